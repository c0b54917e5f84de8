//! Nominal inverse kinematics from a tool tip and a tool-axis direction (part frame).
//!
//! The tool axis `u = (sin a sin c, sin a cos c, cos a)` (effective angles, after the
//! direction convention) has two solutions away from the poles: `(a, c)` and
//! `(−a, c + 180°)`. Each is unwrapped to the C nearest the previous C (any number
//! of turns), solutions outside the A limits are dropped, and the one with the
//! smallest joint motion `|Δa| + |Δc|` wins (ties: `a ≥ 0` in the effective angle).
//! At the poles (`sin a` below [`POLE_SIN`]) C is undetermined and the previous C is
//! kept.
use super::Kinematics;
use super::transform::norm;
use crate::axes::Axes;

/// `|sin a|` below which the tool axis is taken as lying on the C axis (A = 0° or
/// 180°, within about 6e-8°): C is then the previous C.
pub const POLE_SIN: f64 = 1e-9;

/// Where the inverse starts from and what it may choose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InverseOptions {
    /// The previous joint position: C is chosen nearest `previous.c`, A nearest
    /// `previous.a` between the two branches.
    pub previous: Axes,
    /// A travel `[min, max]` in degrees; `None` means any A.
    pub a_limits: Option<[f64; 2]>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InverseError {
    #[error("the tool-axis target is not finite or has zero length: {axis:?}")]
    BadAxis { axis: [f64; 3] },
    #[error("the tool tip target is not finite: {tip:?}")]
    BadTip { tip: [f64; 3] },
    #[error(
        "tool axis {axis:?} needs A = {a_first:.6}° or {a_second:.6}°, both outside the A limits [{}, {}]",
        limits[0], limits[1]
    )]
    OutsideALimits {
        axis: [f64; 3],
        a_first: f64,
        a_second: f64,
        limits: [f64; 2],
    },
}

/// `c` plus the whole number of turns that brings it nearest `previous`.
pub fn nearest_turn(c: f64, previous: f64) -> f64 {
    c + 360.0 * ((previous - c) / 360.0).round()
}

impl Kinematics {
    /// Joints that put the nominal tool tip at `tip` (part coordinates, mm) with the
    /// tool axis along `axis` (part coordinates, any positive length).
    pub fn inverse_tool_axis(
        &self,
        tip: [f64; 3],
        axis: [f64; 3],
        options: &InverseOptions,
    ) -> Result<Axes, InverseError> {
        if !tip.iter().all(|v| v.is_finite()) {
            return Err(InverseError::BadTip { tip });
        }
        let n = norm(axis);
        if !n.is_finite() || n < 1e-12 {
            return Err(InverseError::BadAxis { axis });
        }
        let u = [axis[0] / n, axis[1] / n, axis[2] / n];
        let s = if self.conventional_directions {
            -1.0
        } else {
            1.0
        };
        let rho = u[0].hypot(u[1]);
        // Effective A in [0°, 180°], well conditioned everywhere (unlike acos near ±1).
        let a_eff = rho.atan2(u[2]).to_degrees();
        let prev = options.previous;
        let candidates: [(f64, f64); 2] = if rho < POLE_SIN {
            [(s * a_eff, prev.c), (-s * a_eff, prev.c)]
        } else {
            let c_eff = u[0].atan2(u[1]).to_degrees();
            [
                (s * a_eff, nearest_turn(s * c_eff, prev.c)),
                (-s * a_eff, nearest_turn(s * (c_eff + 180.0), prev.c)),
            ]
        };
        let inside = |a: f64| match options.a_limits {
            Some([lo, hi]) => a >= lo - 1e-9 && a <= hi + 1e-9,
            None => true,
        };
        let cost = |(a, c): (f64, f64)| (a - prev.a).abs() + (c - prev.c).abs();
        let mut best: Option<(f64, f64)> = None;
        for cand in candidates {
            if !inside(cand.0) {
                continue;
            }
            best = match best {
                Some(b) if cost(b) <= cost(cand) => Some(b),
                _ => Some(cand),
            };
        }
        let (a, c) = best.ok_or(InverseError::OutsideALimits {
            axis,
            a_first: candidates[0].0,
            a_second: candidates[1].0,
            limits: options.a_limits.unwrap_or([f64::NAN; 2]),
        })?;
        let m = self.nominal_machine_point(tip, a, c);
        Ok(Axes::new(m[0], m[1], m[2], a, c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::Geometry;

    #[test]
    fn nearest_turn_handles_many_turns() {
        assert!((nearest_turn(10.0, 3605.0) - 3610.0).abs() < 1e-9);
        assert!((nearest_turn(350.0, -1.0) - (-10.0)).abs() < 1e-9);
    }

    #[test]
    fn pole_keeps_previous_c() {
        let k = Kinematics::new(Geometry::default(), 100.0);
        let opts = InverseOptions {
            previous: Axes::new(0.0, 0.0, 0.0, 5.0, 1234.5),
            a_limits: Some([-110.0, 110.0]),
        };
        let j = k
            .inverse_tool_axis([1.0, 2.0, 3.0], [0.0, 0.0, 2.0], &opts)
            .unwrap();
        assert_eq!(j.c, 1234.5);
        assert!(j.a.abs() < 1e-12);
    }

    #[test]
    fn limits_pick_the_other_branch() {
        let k = Kinematics::new(Geometry::default(), 100.0);
        let axis = k.nominal_tool_axis(&Axes::new(0.0, 0.0, 0.0, 30.0, 40.0));
        let opts = InverseOptions {
            previous: Axes::default(),
            a_limits: Some([-100.0, 0.0]),
        };
        let j = k.inverse_tool_axis([0.0; 3], axis, &opts).unwrap();
        assert!((j.a + 30.0).abs() < 1e-9);
        assert!((j.c - (-140.0)).abs() < 1e-9);
        let none = InverseOptions {
            previous: Axes::default(),
            a_limits: Some([50.0, 60.0]),
        };
        assert!(k.inverse_tool_axis([0.0; 3], axis, &none).is_err());
    }
}
