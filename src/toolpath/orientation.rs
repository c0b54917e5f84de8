//! The [`OrientationSolver`] of a machine: tool axis ↔ rotary joints from its
//! chain, handed to the G-code front through `ProgramSetup::orientation` for
//! the dialect blocks that need it (Sinumerik `CYCLE800` swivelled planes;
//! orientation vectors). `gcode` knows no kinematics; this is where it asks.
use crate::axes::{Axes, Axis};
use crate::gcode::{Branch, OrientationSolver};
use crate::kinematics::Kinematics;

/// A machine's nominal chain as an [`OrientationSolver`].
#[derive(Clone, Debug)]
pub struct ChainOrientation {
    kinematics: Kinematics,
    rotary: [Axis; 2],
}

impl ChainOrientation {
    /// The solver of `machine` (its nominal chain; the tool length does not
    /// matter for directions).
    pub fn of(machine: &crate::machine::Machine) -> Self {
        let kinematics = machine.kinematics_model();
        ChainOrientation {
            rotary: kinematics.rotary(),
            kinematics,
        }
    }
}

impl OrientationSolver for ChainOrientation {
    /// Among the chain's solutions (each rotary joint in (−180°, 180°],
    /// then the turn nearest `previous`): on [`Branch::Plus`] / `Minus` the
    /// one whose first rotary axis (letter order) is ≥ 0 / < 0 (Siemens
    /// `CYCLE800` `_DIR`, Heidenhain `SEQ`), else the one nearest
    /// `previous`.
    fn joints_for_axis(&self, axis: [f64; 3], branch: Branch, previous: &Axes) -> Option<Axes> {
        let solutions = self.kinematics.orientation_solutions(axis);
        let [r1, r2] = self.rotary;
        let candidates = solutions.into_iter().map(|[a, b]| {
            let mut j = *previous;
            j.set(
                r1,
                crate::kinematics::inverse::nearest_turn(a, previous.get(r1)),
            );
            j.set(
                r2,
                crate::kinematics::inverse::nearest_turn(b, previous.get(r2)),
            );
            (a, j)
        });
        let distance =
            |j: &Axes| (j.get(r1) - previous.get(r1)).abs() + (j.get(r2) - previous.get(r2)).abs();
        let filtered: Vec<(f64, Axes)> = candidates
            .filter(|(a, _)| match branch {
                Branch::Nearest => true,
                Branch::Plus => *a >= -1e-9,
                Branch::Minus => *a <= 1e-9,
            })
            .collect();
        filtered
            .into_iter()
            .map(|(_, j)| j)
            .min_by(|a, b| distance(a).total_cmp(&distance(b)))
    }

    fn axis_of(&self, joints: &Axes) -> [f64; 3] {
        self.kinematics.nominal_tool_axis(joints)
    }
}
