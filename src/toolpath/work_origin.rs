//! The work frame a program cuts in: the origins (work offset, G92, rotation)
//! active during its cutting moves (G1, G2, G3; not G0, not G53), for reading
//! plans and measurements given in work coordinates.
use crate::gcode::{Frame, GcodeError, InterpretOptions, MotionKind, Origin, Program};

/// One origin the program cuts in.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CuttingOrigin {
    pub origin: Origin,
    /// The first line that cuts in it.
    pub first_line: usize,
    /// Cutting moves in it.
    pub moves: usize,
    /// Joint-frame cutting moves (no tool-tip control) with a rotary axis away
    /// from 0 (at either end), and the first line of one: under a work offset
    /// such a move's part is not the plan moved by the offset.
    pub tilted_joint_moves: usize,
    pub first_tilted_line: Option<usize>,
}

/// Every distinct origin of the program's cutting moves, in order of first use.
pub fn cutting_origins(
    program: Program,
    interpret: InterpretOptions,
) -> Result<Vec<CuttingOrigin>, GcodeError> {
    let mut run = program.run(interpret);
    let mut out: Vec<CuttingOrigin> = Vec::new();
    while let Some(step) = run.next() {
        let (_, event, executed) = step?;
        if event.skipped {
            continue;
        }
        for m in event.motions() {
            if m.machine_coordinates
                || !matches!(m.kind, MotionKind::Linear | MotionKind::Arc { .. })
            {
                continue;
            }
            let k = match out.iter().position(|c| c.origin == event.origin) {
                Some(k) => k,
                None => {
                    out.push(CuttingOrigin {
                        origin: event.origin,
                        first_line: executed.line,
                        moves: 0,
                        tilted_joint_moves: 0,
                        first_tilted_line: None,
                    });
                    out.len() - 1
                }
            };
            let c = &mut out[k];
            c.moves += 1;
            let turned = |p: &crate::axes::Axes| {
                [
                    crate::axes::Axis::A,
                    crate::axes::Axis::B,
                    crate::axes::Axis::C,
                ]
                .iter()
                .any(|a| p.get(*a) != 0.0)
            };
            if m.frame == Frame::Joint && (turned(&m.start) || turned(&m.end)) {
                c.tilted_joint_moves += 1;
                c.first_tilted_line.get_or_insert(executed.line);
            }
        }
    }
    Ok(out)
}
