//! The [`OrientationSolver`] of a machine: tool axis ↔ rotary joints from its
//! chain, handed to the G-code front through `ProgramSetup::orientation` for
//! the dialect blocks that need it (Sinumerik `CYCLE800` swivelled planes,
//! Heidenhain `PLANE` working planes and `LN` tool vectors): the rotary joints
//! that point the tool along an axis, on the branch the control picks, within
//! the machine's rotary travel; and back. `gcode` knows no kinematics; this is
//! where it asks.
use crate::axes::{Axes, Axis};
use crate::gcode::{Branch, OrientationSolver};
use crate::kinematics::Kinematics;
use crate::machine::{Limits, Machine};

/// A machine's nominal chain and rotary travel as an [`OrientationSolver`].
#[derive(Clone, Debug)]
pub struct ChainOrientation {
    kinematics: Kinematics,
    rotary: [Axis; 2],
    limits: Limits,
}

impl ChainOrientation {
    /// The solver of `machine` (its nominal chain, the tool length does not
    /// matter for directions; its rotary travel limits).
    pub fn of(machine: &Machine) -> Self {
        let kinematics = machine.kinematics_model();
        ChainOrientation {
            rotary: kinematics.rotary(),
            kinematics,
            limits: machine.limits,
        }
    }
}

impl OrientationSolver for ChainOrientation {
    /// Among the chain's solutions (each rotary joint at its turn nearest
    /// `previous` inside the machine's travel; a solution with a joint no
    /// turn of which is inside is dropped): on [`Branch::Plus`] / `Minus`
    /// the one whose first rotary axis (letter order) is ≥ 0 / ≤ 0 (Siemens
    /// `CYCLE800` `_DIR`; Heidenhain TNC 640 user's manual, "PLANE:
    /// positioning behaviour", `SEQ+`/`SEQ-`), else the one nearest
    /// `previous` (the sum of the two joints' travels).
    fn joints_for_axis(&self, axis: [f64; 3], branch: Branch, previous: &Axes) -> Option<Axes> {
        let [r1, r2] = self.rotary;
        let distance =
            |j: &Axes| (j.get(r1) - previous.get(r1)).abs() + (j.get(r2) - previous.get(r2)).abs();
        self.kinematics
            .orientation_solutions(axis)
            .into_iter()
            .filter(|[a, _]| match branch {
                Branch::Nearest => true,
                Branch::Plus => *a >= -1e-9,
                Branch::Minus => *a <= 1e-9,
            })
            .filter_map(|[a, b]| {
                let near = |axis: Axis, q: f64| {
                    crate::kinematics::inverse::joint_near(
                        q,
                        previous.get(axis),
                        self.limits.get(axis),
                    )
                };
                let mut j = *previous;
                j.set(r1, near(r1, a)?);
                j.set(r2, near(r2, b)?);
                Some(j)
            })
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))
    }

    fn axis_of(&self, joints: &Axes) -> [f64; 3] {
        self.kinematics.nominal_tool_axis(joints)
    }

    fn frame_of(&self, joints: &Axes) -> [[f64; 3]; 3] {
        self.kinematics.nominal_orientation(joints)
    }

    fn swivel_order(&self) -> [Axis; 2] {
        self.kinematics.swivel_order()
    }
}
