//! Number formatting of the writers: fixed decimals, exactly as `format!`
//! prints them (a fast path where it provably agrees), no `-0`, and the
//! value as printed.
/// Largest scaled value of the fast path (see [`push_fixed`]): 2³².
const FAST_LIMIT: f64 = 4_294_967_296.0;

/// The fast path of [`push_number`]: integer arithmetic on `value·10^decimals`,
/// taken only where it prints exactly what `format!("{:.*}")` prints. That is when
/// the scaled value is below 2³² (so its rounding error, at most half an ulp,
/// 2⁻²² < 2.4e-7, cannot move it across a half) and not within 1e-6 of a half
/// (where the exact decimal expansion of the double decides, which `format!` does
/// and this does not). A wrong floor needs the exact product within 2.4e-7 of an
/// integer, where both sides round to that integer. The printed value `n / 10^d`
/// (`n` < 2³², exact) is the correctly rounded double of the printed decimal, as
/// parsing it would give. (Below 1e8 only, rotary words past 10,000° took the
/// slow path: a long program's C words.)
pub(super) fn push_fixed(out: &mut String, value: f64, decimals: u8) -> Option<f64> {
    const POW10: [u64; 10] = [
        1,
        10,
        100,
        1_000,
        10_000,
        100_000,
        1_000_000,
        10_000_000,
        100_000_000,
        1_000_000_000,
    ];
    let p = *POW10.get(decimals as usize)?;
    let scaled = value.abs() * p as f64;
    if !(scaled < FAST_LIMIT) {
        return None;
    }
    let floor = scaled.floor();
    let frac = scaled - floor;
    if (frac - 0.5).abs() < 1e-6 {
        return None;
    }
    let n = floor as u64 + u64::from(frac > 0.5);
    let negative = value < 0.0 && n != 0;
    if negative {
        out.push('-');
    }
    let (int, fraction) = (n / p, n % p);
    let mut digits = [0u8; 20];
    let mut i = digits.len();
    let mut v = int;
    loop {
        i -= 1;
        digits[i] = b'0' + (v % 10) as u8;
        v /= 10;
        if v == 0 {
            break;
        }
    }
    out.push_str(std::str::from_utf8(&digits[i..]).ok()?);
    if decimals > 0 {
        out.push('.');
        let mut f = [b'0'; 10];
        let mut v = fraction;
        for k in (0..decimals as usize).rev() {
            f[k] = b'0' + (v % 10) as u8;
            v /= 10;
        }
        out.push_str(std::str::from_utf8(&f[..decimals as usize]).ok()?);
    }
    let printed = n as f64 / p as f64;
    Some(if negative { -printed } else { printed })
}

/// Half a unit of the last of `decimals` decimals (a hair less).
pub(crate) fn half_ulp(decimals: u8) -> f64 {
    0.5 * 10f64.powi(-(decimals as i32)) * (1.0 - 1e-9)
}

/// `v` rounded to `decimals` decimals, no `-0`.
pub(crate) fn round_to(v: f64, decimals: u8) -> f64 {
    let p = 10f64.powi(decimals as i32);
    let r = (v * p).round() / p;
    if r == 0.0 { 0.0 } else { r }
}

/// Append `value` with `decimals` decimals (no `-0`); returns the printed value.
pub(crate) fn push_number(out: &mut String, value: f64, decimals: u8) -> f64 {
    use std::fmt::Write as _;
    if let Some(printed) = push_fixed(out, value, decimals) {
        return printed;
    }
    let start = out.len();
    let _ = write!(out, "{:.*}", decimals as usize, value);
    if out[start..].starts_with('-') && out[start + 1..].bytes().all(|b| b == b'0' || b == b'.') {
        out.remove(start);
    }
    out[start..].parse::<f64>().unwrap_or(value)
}

#[cfg(test)]
mod fixed_tests {
    use super::{push_fixed, push_number};
    use proptest::prelude::*;

    fn std_number(value: f64, decimals: u8) -> String {
        let mut s = format!("{:.*}", decimals as usize, value);
        if s.starts_with('-') && s[1..].bytes().all(|b| b == b'0' || b == b'.') {
            s.remove(0);
        }
        s
    }

    proptest! {
        #[test]
        fn fast_path_prints_what_format_prints(
            value in -20_000.0f64..20_000.0,
            decimals in 0u8..8,
        ) {
            let value = value * if decimals <= 4 { 20.0 } else { 1.0 };
            let mut fast = String::new();
            let printed = push_number(&mut fast, value, decimals);
            let expected = std_number(value, decimals);
            prop_assert_eq!(&fast, &expected);
            prop_assert_eq!(printed, expected.parse::<f64>().unwrap());
        }
    }

    #[test]
    fn ties_and_signs() {
        for (v, d) in [
            (0.125, 2),
            (-0.00004, 4),
            (2.5, 0),
            (1.00005, 4),
            (-3.14158, 3),
            (0.0, 4),
            (200_129.123_45, 4),
            (-200_129.5, 0),
            (429_496.729_55, 4),
        ] {
            let mut fast = String::new();
            push_number(&mut fast, v, d);
            assert_eq!(fast, std_number(v, d), "{v} with {d} decimals");
        }
        let mut s = String::new();
        assert!(
            push_fixed(&mut s, 0.125, 2).is_none(),
            "an exact tie goes to format!"
        );
    }
}
