//! The machine's orientation kinematics as a dialect front needs it
//! ([`crate::gcode::OrientationSolver`]): the rotary joints that point the
//! tool along an axis (a working plane's normal, an `LN` tool vector), on the
//! branch the control picks, within the machine's travel; and back.
use crate::axes::{Axes, Axis};
use crate::gcode::{Branch, OrientationSolver};
use crate::kinematics::Kinematics;
use crate::machine::{Limits, Machine};

/// A machine's chain and rotary travel, as an [`OrientationSolver`].
#[derive(Clone, Debug)]
pub struct ChainOrientation {
    kinematics: Kinematics,
    limits: Limits,
}

impl ChainOrientation {
    /// The solver of `machine`'s chain and limits.
    pub fn of(machine: &Machine) -> Self {
        ChainOrientation {
            kinematics: machine.kinematics_model(),
            limits: machine.limits,
        }
    }

    /// `a + k·360` nearest `previous` inside `axis`'s travel.
    fn near(&self, axis: Axis, a: f64, previous: f64) -> Option<f64> {
        let k = ((previous - a) / 360.0).round();
        let near = a + 360.0 * k;
        let Some([lo, hi]) = self.limits.get(axis) else {
            return Some(near);
        };
        [near, near - 360.0, near + 360.0]
            .into_iter()
            .filter(|v| *v >= lo - 1e-9 && *v <= hi + 1e-9)
            .min_by(|x, y| (x - previous).abs().total_cmp(&(y - previous).abs()))
    }
}

impl OrientationSolver for ChainOrientation {
    /// `SEQ+`/`SEQ-` (Heidenhain TNC 640 user's manual, "PLANE: positioning
    /// behaviour", SEQ) pick the solution whose first rotary axis (letter
    /// order) is positive / negative; without one, the solution nearest
    /// `previous` (the sum of the two joints' travels).
    fn joints_for_axis(&self, axis: [f64; 3], branch: Branch, previous: &Axes) -> Option<Axes> {
        let rotary = self.kinematics.rotary();
        let mut best: Option<(f64, Axes)> = None;
        for [r0, r1] in self.kinematics.orientation_solutions(axis) {
            let keep = match branch {
                Branch::Nearest => true,
                Branch::Plus => r0 >= -1e-9,
                Branch::Minus => r0 <= 1e-9,
            };
            if !keep {
                continue;
            }
            let (Some(j0), Some(j1)) = (
                self.near(rotary[0], r0, previous.get(rotary[0])),
                self.near(rotary[1], r1, previous.get(rotary[1])),
            ) else {
                continue;
            };
            let cost = (j0 - previous.get(rotary[0])).abs() + (j1 - previous.get(rotary[1])).abs();
            if best.as_ref().is_none_or(|(c, _)| cost < *c - 1e-9) {
                let mut joints = *previous;
                joints.set(rotary[0], j0);
                joints.set(rotary[1], j1);
                best = Some((cost, joints));
            }
        }
        best.map(|(_, j)| j)
    }

    fn axis_of(&self, joints: &Axes) -> [f64; 3] {
        self.kinematics.nominal_tool_axis(joints)
    }

    fn workpiece_rotation(&self, joints: &Axes) -> [[f64; 3]; 3] {
        // The tool's orientation in the workpiece frame is r; a workpiece
        // vector is then at rᵀ·v as the machine sees it.
        let r = crate::kinematics::chain::nominal_orientation(&self.kinematics.chain, joints);
        std::array::from_fn(|i| std::array::from_fn(|j| r[j][i]))
    }
}
