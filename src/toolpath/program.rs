//! Walking a whole program: reader → interpreter → [`PathWalker`], streaming.
use super::walk::{PathPoint, PathWalker, WalkOptions};
use crate::gcode::{BlockReader, GcodeError, InterpretOptions, Interpreter, ReadOptions};
use crate::kinematics::Kinematics;
use std::io::BufRead;
use std::path::Path;

/// What a walk saw.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WalkSummary {
    pub blocks: usize,
    pub motion_blocks: usize,
    pub path_points: usize,
    /// Total machining time, minutes.
    pub time_min: f64,
}

/// Walk every motion of the program read from `input` (named `path` in errors),
/// calling `visit` for every path point in order.
pub fn walk_program(
    input: impl BufRead,
    path: &Path,
    kinematics: &Kinematics,
    interpret: InterpretOptions,
    walk: WalkOptions,
    mut visit: impl FnMut(&PathPoint),
) -> Result<WalkSummary, GcodeError> {
    let mut reader = BlockReader::new(
        input,
        ReadOptions {
            lenient: interpret.lenient,
        },
    );
    let mut interpreter = Interpreter::new(interpret);
    let mut walker = PathWalker::new(kinematics, walk);
    let mut summary = WalkSummary::default();
    let mut count = |p: &PathPoint| {
        summary.path_points += 1;
        visit(p);
    };
    while let Some(block) = reader.next_block() {
        let block = block.map_err(|e| e.with_path(path))?;
        let event = interpreter
            .interpret(block)
            .map_err(|e| e.with_path(path))?;
        summary.blocks += 1;
        if let Some(motion) = &event.motion {
            summary.motion_blocks += 1;
            walker.push(event.index, event.line, motion, &mut count);
        }
    }
    walker.finish(&mut count);
    summary.time_min = walker.time_min();
    Ok(summary)
}
