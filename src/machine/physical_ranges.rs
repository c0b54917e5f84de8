//! What a machine tool can have: the ranges every number a user gives (a
//! machine file, an error table, a command-line setting) is checked against,
//! so that a typing slip (`1e6` for `1e-6`, a value in the wrong unit) is
//! refused with the range in the message instead of giving corrections of
//! half a metre "within tolerance". Generous: the largest machine tools
//! (100 m of travel, 5 m tools) and errors a hundred times those of a worn
//! machine still pass.
//!
//! Invariant: a value that passes is finite.

/// A coordinate, point, offset or travel limit, mm (or degrees of a rotary
/// axis's travel): the largest machine tools travel some tens of metres.
pub const MAX_LENGTH_MM: f64 = 100_000.0;
/// A tool's length from the gauge point to its tip, or its radius, mm.
pub const MAX_TOOL_MM: f64 = 5_000.0;
/// A linear geometric error (a table value, a location offset), µm: 10 mm.
pub const MAX_ERROR_UM: f64 = 10_000.0;
/// An angular geometric error (a table value, a tilt, a squareness), µrad:
/// 10 mrad, 0.57°.
pub const MAX_ERROR_URAD: f64 = 10_000.0;
/// A reversal (backlash) of a linear axis, µm: 1 mm.
pub const MAX_REVERSAL_UM: f64 = 1_000.0;
/// A reversal of a rotary axis, µrad: 10 mrad.
pub const MAX_REVERSAL_URAD: f64 = 10_000.0;
/// A grid step of `export tables` on a linear axis, mm.
pub const MAX_STEP_MM: f64 = MAX_LENGTH_MM;
/// A grid step of `export tables` on a rotary axis, degrees.
pub const MAX_STEP_DEG: f64 = 360.0;

/// `value` if it is finite and within `[lo, hi]` (`(lo, hi]` when
/// `lo_excluded`), else the message naming `name`, the value and the range.
pub fn check_range(
    name: &str,
    unit: &str,
    value: f64,
    (lo, hi): (f64, f64),
    lo_excluded: bool,
) -> Result<f64, String> {
    let above_lo = if lo_excluded { value > lo } else { value >= lo };
    if value.is_finite() && above_lo && value <= hi {
        return Ok(value);
    }
    let range = if lo_excluded {
        format!("more than {lo} and at most {hi} {unit}")
    } else {
        format!("{lo} to {hi} {unit}")
    };
    Err(if value.is_finite() {
        // 1e300 as written, not as 301 digits.
        let shown = if value.abs() >= 1e6 {
            format!("{value:e}")
        } else {
            format!("{value}")
        };
        format!(
            "{name} = {shown} {unit} is beyond what a machine tool can have: the range is {range}"
        )
    } else {
        format!("{name} = {value} is not a finite number: the range is {range}")
    })
}

/// [`check_range`] over `±max`.
pub fn check_magnitude(name: &str, unit: &str, value: f64, max: f64) -> Result<f64, String> {
    check_range(name, unit, value, (-max, max), false)
}

/// The largest error a parameter named `E<direction>…` can have, and its
/// unit: µm for a linear direction (X Y Z), µrad for an angular one.
pub fn error_bound(parameter: &str) -> (f64, &'static str) {
    match parameter.as_bytes().get(1) {
        Some(b'A' | b'B' | b'C') => (MAX_ERROR_URAD, "µrad"),
        _ => (MAX_ERROR_UM, "µm"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_refuse_beyond_and_non_finite_with_the_range() {
        assert_eq!(check_magnitude("x", "µm", 5.0, 10.0), Ok(5.0));
        let e = check_magnitude("[reversal] X", "µm", 1e6, MAX_REVERSAL_UM).unwrap_err();
        assert!(
            e.contains("= 1e6 µm") && e.contains("-1000 to 1000 µm"),
            "{e}"
        );
        let e = check_range("--step", "mm", 0.0, (0.0, 5.0), true).unwrap_err();
        assert!(e.contains("more than 0 and at most 5 mm"), "{e}");
        assert!(check_magnitude("x", "mm", f64::NAN, 1.0).is_err());
        assert!(check_magnitude("x", "mm", f64::INFINITY, 1.0).is_err());
        assert_eq!(error_bound("EAX"), (MAX_ERROR_URAD, "µrad"));
        assert_eq!(error_bound("EYX"), (MAX_ERROR_UM, "µm"));
    }
}
