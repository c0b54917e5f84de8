//! Where the tool is in the workpiece's own terms, for every dialect
//! (dialects.md "Positions"): each motion end as the tool tip and the unit
//! tool axis in the workpiece frame — the frame of the work offset / preset,
//! before G92, datum shifts, programmable frames and working planes. This is
//! the form in which the three dialects' readings of one tool path compare
//! (`check --frame part --targets`).
//!
//! - The tip: a part-frame (tool-tip) target is the tip already
//!   ([`Origin::xyz_to_workpiece`] of it); a joint-frame target is the tip
//!   only while every rotary axis is at 0 (X Y Z are then the tip, tool
//!   length not applied, as `check --targets` reads them); a joint-frame
//!   target with a rotary axis away from 0 (no tool-tip control) and a
//!   machine-coordinate move (G53, SUPA, M91/M92) have no tip here.
//! - The axis: the machine's nominal tool axis (tip → spindle) at the
//!   target's rotary joints, in part coordinates; without a machine, +Z
//!   where every rotary axis is at 0 and a located error elsewhere.
use crate::axes::{Axes, Axis, AxisSet};
use crate::gcode::{Block, BlockEvent, ErrorKind, Frame, GcodeError, Motion};
use crate::kinematics::Kinematics;

/// A motion end in the workpiece frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkpieceTarget {
    /// The tool tip, mm; `None` where the reading cannot place it (a
    /// machine-coordinate move, a rotary axis away from 0 without tool-tip
    /// control).
    pub tip: Option<[f64; 3]>,
    /// The unit tool axis (tip → spindle).
    pub axis: [f64; 3],
}

/// Turns motion ends into [`WorkpieceTarget`]s: the machine's nominal chain
/// (for the tool axis of rotary positions) and the axis letters read.
#[derive(Clone, Debug)]
pub struct WorkpieceFrame {
    kinematics: Option<Kinematics>,
    letters: AxisSet,
}

/// The tool axis of a machine with every rotary axis at 0 when no machine
/// is given (every bundled machine, and kinematics.md's default `tool_axis`).
const HOME_AXIS: [f64; 3] = [0.0, 0.0, 1.0];

impl WorkpieceFrame {
    /// For `machine` (`None`: rotary positions other than 0 cannot be turned
    /// into an axis), reading the axis letters `letters`.
    pub fn new(machine: Option<&crate::machine::Machine>, letters: AxisSet) -> Self {
        WorkpieceFrame {
            kinematics: machine.map(|m| m.kinematics_model()),
            letters,
        }
    }

    /// Where `motion` (one of `event`'s, from `block`) ends in the workpiece
    /// frame. Errors: a rotary position other than 0 without a machine,
    /// located at the block's first rotary word (else its start).
    pub fn target(
        &self,
        block: &Block,
        event: &BlockEvent,
        motion: &Motion,
    ) -> Result<WorkpieceTarget, GcodeError> {
        let end = &motion.end;
        let rotary_at_zero = [Axis::A, Axis::B, Axis::C]
            .into_iter()
            .filter(|a| self.letters.contains(*a))
            .all(|a| end.get(a) == 0.0);
        let origin = &event.origin;
        let tip = if motion.machine_coordinates {
            None
        } else {
            match motion.frame {
                Frame::Part => Some(origin.xyz_to_workpiece(end.xyz())),
                Frame::Joint if rotary_at_zero => Some(origin.xyz_to_workpiece(end.xyz())),
                Frame::Joint => None,
            }
        };
        let axis = match &self.kinematics {
            Some(k) => k.nominal_tool_axis(&rotary_joints(end)),
            None if rotary_at_zero => HOME_AXIS,
            None => {
                let (start, stop) = block
                    .words
                    .iter()
                    .find(|w| matches!(w.letter, b'A' | b'B' | b'C'))
                    .map_or((0, 1), |w| (w.start, w.end));
                return Err(GcodeError::at(
                    ErrorKind::MachineNeeded(
                        "the tool axis of a rotary position other than 0 (--frame part --targets)",
                    ),
                    block.line,
                    &block.raw,
                    start,
                    stop,
                ));
            }
        };
        Ok(WorkpieceTarget {
            tip,
            axis: origin.vector_to_workpiece(axis),
        })
    }
}

/// The rotary joints of a target (its linear axes do not turn the tool).
fn rotary_joints(end: &Axes) -> Axes {
    Axes {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        ..*end
    }
}
