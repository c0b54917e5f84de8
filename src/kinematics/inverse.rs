//! Nominal inverse kinematics from a tool tip and a tool-axis direction (part frame),
//! for any chain.
//!
//! The tool axis depends on the rotary joints alone: `u = R(e₁, φ₁)·R(e₂, φ₂)·u₀`
//! (the chain's rotations from part to tool, outermost first; see
//! `MachineChain::orientation`). Paden–Kahan's subproblem 2 gives up to two
//! `(φ₁, φ₂)` for a reachable `u` — for an A/C table `(a, c)` and `(−a, c + 180°)` —
//! whatever the directions (nutating heads included). Each joint is taken at the
//! turn nearest the previous block's joint (inside its travel where it has limits),
//! and of the solutions inside the travel the one nearest the previous joints
//! (Euclidean over the two rotary joints) wins, as kinematics.md asks; ties go to the
//! larger first rotary joint (A ≥ 0 on an A/C table). At a singular pose (`u` along
//! `e₁`, e.g. A = 0 on an A/C table) `φ₁` is free and the previous joint is kept.
//! The linear joints then follow exactly (the tip is affine in them).
use super::Kinematics;
use super::chain::{angle_about, inner_angles, rotation};
use super::transform::{cross, mat_vec, norm};
use crate::axes::Axes;

/// `|sin|` of the angle between the tool axis and the outer rotary axis below which
/// the pose is singular (about 6e-8°): the outer joint is then the previous one.
pub const POLE_SIN: f64 = 1e-9;

/// A jump of a rotary joint between consecutive solutions beyond which the move is
/// reported as a flip (kinematics.md).
pub const FLIP_DEG: f64 = 90.0;

/// Where the inverse starts from and what it may choose.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct InverseOptions {
    /// The previous joint position: each rotary joint is chosen nearest it.
    pub previous: Axes,
    /// Travel `[min, max]` (degrees) of the two rotary joints in letter order;
    /// `None`: endless.
    pub limits: [Option<[f64; 2]>; 2],
}

/// The joints of one pose and what the choice met.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverseSolution {
    pub joints: Axes,
    /// The tool axis lies on the outer rotary axis: its joint was kept.
    pub singular: bool,
    /// The largest change of a rotary joint from the previous position, degrees
    /// (a flip when above [`FLIP_DEG`]).
    pub jump_deg: f64,
}

impl InverseSolution {
    /// Whether reaching this solution from the previous joints is a flip (a
    /// rotary jump of more than [`FLIP_DEG`]; kinematics.md).
    pub fn is_flip(&self) -> bool {
        self.jump_deg > FLIP_DEG
    }
}

/// Why no joints reach a tool tip and tool axis.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InverseError {
    /// The tool-axis target is not finite or has zero length.
    #[error("the tool-axis target is not finite or has zero length: {axis:?}")]
    BadAxis {
        /// The tool-axis target (part frame).
        axis: [f64; 3],
    },
    /// The tool-tip target is not finite.
    #[error("the tool tip target is not finite: {tip:?}")]
    BadTip {
        /// The tool-tip target, part frame, mm.
        tip: [f64; 3],
    },
    /// No rotary joints turn the tool to this axis (outside the machine's cone of reach).
    #[error(
        "the machine's rotary axes cannot turn the tool to {axis:?} (outside its cone of reach)"
    )]
    Unreachable {
        /// The tool-axis target (part frame).
        axis: [f64; 3],
    },
    /// Every rotary solution for this axis is outside the travel of the rotary axes.
    #[error("tool axis {axis:?} needs {first} or {second}, outside the travel of the rotary axes")]
    OutsideLimits {
        /// The tool-axis target (part frame).
        axis: [f64; 3],
        /// The first rotary solution, e.g. `A30.000000° C90.000000°`.
        first: String,
        /// The second rotary solution, or `nothing else`.
        second: String,
    },
}

/// `c` plus the whole number of turns that brings it nearest `previous`.
pub fn nearest_turn(c: f64, previous: f64) -> f64 {
    c + 360.0 * ((previous - c) / 360.0).round()
}

/// The value of `q` (mod 360) nearest `previous` inside `limits` (any turn when
/// `None`); `None` when no turn of it is inside.
pub(crate) fn joint_near(q: f64, previous: f64, limits: Option<[f64; 2]>) -> Option<f64> {
    let near = nearest_turn(q, previous);
    let Some([lo, hi]) = limits else {
        return Some(near);
    };
    let inside = |v: f64| v >= lo - 1e-9 && v <= hi + 1e-9;
    [near, near - 360.0, near + 360.0, near - 720.0, near + 720.0]
        .into_iter()
        .filter(|v| inside(*v))
        .min_by(|a, b| (a - previous).abs().total_cmp(&(b - previous).abs()))
}

/// The raw solutions of the orientation: joint values of the two orientation axes
/// (outer first, degrees, any turn) and whether the pose is singular.
struct Orientations {
    joints: Vec<(f64, f64)>,
    singular: bool,
}

impl Kinematics {
    /// Paden–Kahan on the unit tool axis `u`; `previous_outer` is the outer joint kept
    /// at a singular pose.
    fn orientations(&self, u: [f64; 3], previous_outer: f64) -> Option<Orientations> {
        let chain = &self.chain;
        let [(o1, s1), (o2, s2)] = chain.orientation();
        let (a1, a2) = (chain.axis(o1), chain.axis(o2));
        let (e1, e2) = (a1.direction, a2.direction);
        let u0 = chain.tool_axis();
        // φ (rad) of an orientation rotation → joint (degrees) of its axis.
        let to_joint =
            |phi: f64, sign: f64, joint_sign: f64| phi.to_degrees() / (sign * joint_sign);
        if norm(cross(e1, u)) < POLE_SIN {
            let phi1 = (s1 * a1.joint_sign * previous_outer).to_radians();
            let (s, c) = (-phi1).sin_cos();
            let z = mat_vec(&rotation(e1, s, c), u);
            let phi2 = angle_about(e2, u0, z)?;
            return Some(Orientations {
                joints: vec![(previous_outer, to_joint(phi2, s2, a2.joint_sign))],
                singular: true,
            });
        }
        let phi1_previous = (s1 * a1.joint_sign * previous_outer).to_radians();
        let mut singular = false;
        let joints: Vec<(f64, f64)> = inner_angles(e1, e2, u0, u)
            .into_iter()
            .map(|phi2| {
                let (s, c) = phi2.sin_cos();
                let v = mat_vec(&rotation(e2, s, c), u0);
                // Numerically on the outer axis: the outer joint is free.
                let phi1 = angle_about(e1, v, u).unwrap_or_else(|| {
                    singular = true;
                    phi1_previous
                });
                (
                    to_joint(phi1, s1, a1.joint_sign),
                    to_joint(phi2, s2, a2.joint_sign),
                )
            })
            .collect();
        (!joints.is_empty()).then_some(Orientations { joints, singular })
    }

    /// The rotary joints (degrees, letter order, each in (−180°, 180°]) of every
    /// solution for tool axis `axis` (part coordinates, any positive length); at a
    /// singular pose the outer joint is 0. Empty when no orientation of the machine
    /// gives `axis`.
    pub fn orientation_solutions(&self, axis: [f64; 3]) -> Vec<[f64; 2]> {
        let n = norm(axis);
        if !n.is_finite() || n < 1e-12 {
            return Vec::new();
        }
        let u = [axis[0] / n, axis[1] / n, axis[2] / n];
        let Some(found) = self.orientations(u, 0.0) else {
            return Vec::new();
        };
        let wrap = |v: f64| -> f64 {
            let w = v.rem_euclid(360.0);
            if w > 180.0 { w - 360.0 } else { w }
        };
        let outer_first = self.chain.orientation()[0].0 == self.rotary()[0];
        found
            .joints
            .into_iter()
            .map(|(q1, q2)| {
                let (a, b) = if outer_first { (q1, q2) } else { (q2, q1) };
                [wrap(a), wrap(b)]
            })
            .collect()
    }

    /// Joints that put the nominal tool tip at `tip` (part coordinates, mm) with the
    /// tool axis along `axis` (part coordinates, any positive length); U V W are
    /// `options.previous`'s.
    pub fn inverse_tool_axis(
        &self,
        tip: [f64; 3],
        axis: [f64; 3],
        options: &InverseOptions,
    ) -> Result<InverseSolution, InverseError> {
        if !tip.iter().all(|v| v.is_finite()) {
            return Err(InverseError::BadTip { tip });
        }
        let n = norm(axis);
        if !n.is_finite() || n < 1e-12 {
            return Err(InverseError::BadAxis { axis });
        }
        let u = [axis[0] / n, axis[1] / n, axis[2] / n];
        let [(o1, _), (o2, _)] = self.chain.orientation();
        let prev = options.previous;
        let found = self
            .orientations(u, prev.get(o1))
            .ok_or(InverseError::Unreachable { axis })?;
        let rotary = self.rotary();
        let limit_of = |a| {
            if a == rotary[0] {
                options.limits[0]
            } else {
                options.limits[1]
            }
        };
        let mut best: Option<(f64, Axes)> = None;
        for (q1, q2) in &found.joints {
            let (Some(j1), Some(j2)) = (
                joint_near(*q1, prev.get(o1), limit_of(o1)),
                joint_near(*q2, prev.get(o2), limit_of(o2)),
            ) else {
                continue;
            };
            let mut joints = prev;
            joints.set(o1, j1);
            joints.set(o2, j2);
            let d = ((j1 - prev.get(o1)).powi(2) + (j2 - prev.get(o2)).powi(2)).sqrt();
            let better = match &best {
                None => true,
                Some((bd, bj)) => {
                    d < bd - 1e-9
                        || ((d - bd).abs() <= 1e-9
                            && joints.get(rotary[0]) > bj.get(rotary[0]) + 1e-12)
                }
            };
            if better {
                best = Some((d, joints));
            }
        }
        let Some((_, rotaries)) = best else {
            let describe =
                |(q1, q2): (f64, f64)| format!("{}{q1:.6}° {}{q2:.6}°", o1.letter(), o2.letter());
            return Err(InverseError::OutsideLimits {
                axis,
                first: describe(found.joints[0]),
                second: found
                    .joints
                    .get(1)
                    .map_or_else(|| "nothing else".to_string(), |r| describe(*r)),
            });
        };
        let joints = self.nominal_joints_for_tip(tip, &rotaries);
        let jump_deg = (joints.get(o1) - prev.get(o1))
            .abs()
            .max((joints.get(o2) - prev.get(o2)).abs());
        Ok(InverseSolution {
            joints,
            singular: found.singular,
            jump_deg,
        })
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
            previous: Axes::xyzac(0.0, 0.0, 0.0, 5.0, 1234.5),
            limits: [Some([-110.0, 110.0]), None],
        };
        let s = k
            .inverse_tool_axis([1.0, 2.0, 3.0], [0.0, 0.0, 2.0], &opts)
            .unwrap();
        assert!(s.singular);
        assert_eq!(s.joints.c, 1234.5);
        assert!(s.joints.a.abs() < 1e-12);
    }

    #[test]
    fn limits_pick_the_other_branch() {
        let k = Kinematics::new(Geometry::default(), 100.0);
        let axis = k.nominal_tool_axis(&Axes::xyzac(0.0, 0.0, 0.0, 30.0, 40.0));
        let opts = InverseOptions {
            previous: Axes::default(),
            limits: [Some([-100.0, 0.0]), None],
        };
        let j = k.inverse_tool_axis([0.0; 3], axis, &opts).unwrap().joints;
        assert!((j.a + 30.0).abs() < 1e-9, "{j:?}");
        assert!((j.c - (-140.0)).abs() < 1e-9, "{j:?}");
        let none = InverseOptions {
            previous: Axes::default(),
            limits: [Some([50.0, 60.0]), None],
        };
        assert!(k.inverse_tool_axis([0.0; 3], axis, &none).is_err());
    }
}
