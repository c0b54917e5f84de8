//! Walking a whole program: [`Program`] run → [`PathWalker`], streaming.
use super::walk::{PathPoint, PathWalker, WalkOptions};
use crate::gcode::{GcodeError, InterpretOptions, Program};
use crate::kinematics::Kinematics;

/// What a walk saw.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct WalkSummary {
    /// Blocks read (skipped ones included).
    pub blocks: usize,
    /// Blocks that moved the tool.
    pub motion_blocks: usize,
    /// Path points visited.
    pub path_points: usize,
    /// Total machining time, minutes.
    pub time_min: f64,
}

/// Walk every motion of `program` (canned cycles and loops expanded),
/// calling `visit` for every path point in order.
pub fn walk_program(
    program: Program,
    kinematics: &Kinematics,
    interpret: InterpretOptions,
    walk: WalkOptions,
    visit: impl FnMut(&PathPoint),
) -> Result<WalkSummary, GcodeError> {
    walk_program_tracking(program, kinematics, interpret, walk, None, visit)
}

/// [`walk_program`], each point with the directions `directions` tracks
/// (the axes with a reversal; `PathPoint::approach`).
pub fn walk_program_tracking(
    program: Program,
    kinematics: &Kinematics,
    interpret: InterpretOptions,
    walk: WalkOptions,
    directions: Option<crate::machine::DirectionTracker>,
    mut visit: impl FnMut(&PathPoint),
) -> Result<WalkSummary, GcodeError> {
    let mut run = program.run(interpret);
    let mut walker = PathWalker::new(kinematics, walk);
    if let Some(t) = directions {
        walker.track_directions(t);
    }
    let mut summary = WalkSummary::default();
    let mut count = |p: &PathPoint| {
        summary.path_points += 1;
        visit(p);
    };
    while let Some(step) = run.next() {
        let (_, event, _) = step?;
        summary.blocks += 1;
        if event.skipped {
            continue;
        }
        let mut moved = false;
        for motion in event.motions() {
            moved = true;
            walker.push(event.index, event.line, event.tool, motion, &mut count);
        }
        summary.motion_blocks += moved as usize;
    }
    walker.finish(&mut count);
    summary.time_min = walker.time_min();
    Ok(summary)
}
