//! `compensate`: rewrite a program so that the modelled actual tool tip lands on
//! the programmed one.
//!
//! For every motion target the joints are solved (`solve`) so that the actual
//! tool tip of the error model equals the nominal tip of the programmed target;
//! part-frame (tool-tip control) targets are moved in part coordinates, through
//! the nominal kinematics the control itself uses. A cutting move whose correction
//! varies along it by more than the tolerance (the compensated straight move would
//! miss the compensated path in between) is split at its midpoint, recursively.
//! Rapids are compensated at their ends and never split.
//!
//! Streaming: three stages run at once, each a chunk or two ahead of the next
//! (bounded channels, so memory does not grow with the program): reading and
//! interpreting; solving and planning, in parallel within a chunk (rayon); and
//! writing in order through `gcode::rewrite`. Nothing is printed here.
mod held_rotary;
pub(crate) mod solve;
pub use solve::{RESIDUAL_MM, RESIDUAL_URAD, WarmStart, solve_joints, solve_pose_from};

use crate::axes::{Axes, Joints};
use crate::gcode::ToolInUse;
use crate::gcode::{
    Block, BlockEvent, Frame, GcodeError, InterpretOptions, Motion, MotionKind, Moves, Pose,
    Program, RewriteError, RewriteOptions, Rewriter, Target, motion::ArcGeometry,
};
use crate::machine::{
    Approach, Direction, DirectionTracker, ErrorModel, ExtrapolationPolicy, Limits, LookupError,
    ToolModels,
};
use crate::toolpath::{joints_of, pose_of};
use rayon::prelude::*;
use serde::Serialize;
use solve::{
    SolveError, first_order_joints, first_order_joints_at, solve_joints_toward, solve_pose_toward,
};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Consecutive blocks solved in order by one thread (warm-started solves).
const WARM_START_RUN: usize = 256;

/// Settings of a compensation run.
#[derive(Clone, Debug)]
pub struct CompensateOptions {
    /// A cutting move is split where the correction along it departs from the
    /// straight interpolation of its end corrections by more than this, µm.
    pub tolerance_um: f64,
    /// Deepest recursive halving of one move (2^depth pieces at most). A
    /// move that still departs from its pieces by more than the tolerance is
    /// counted ([`CompensateReport::split_cap`]).
    pub max_split_depth: u32,
    /// Most straight pieces a split arc becomes; an arc that needs more to
    /// stay within the tolerance is refused (a located error).
    pub max_arc_chords: usize,
    /// How the program is read (start frame and position, rapid rate, leniency, axis letters, spline tolerance).
    pub interpret: InterpretOptions,
    /// How the compensated blocks are written (decimals of the rewritten values).
    pub rewrite: RewriteOptions,
    /// Blocks per chunk (memory and parallel grain).
    pub chunk_blocks: usize,
    /// Generated moves per chunk: a chunk ends at the block that brings it to
    /// this many (canned cycles, splines, blocks run again by loops), so that
    /// memory stays a few chunks whatever the program generates (as `check`).
    pub chunk_moves: usize,
    /// Travel limits the compensated joints must respect (`None`: unchecked).
    pub limits: Option<Limits>,
    /// Compute [`CompensateReport::expected_residual_rms_um`] (the model's
    /// standard uncertainty at every move end: about as long as the
    /// compensation itself again).
    pub expected_residual: bool,
    /// Correct the tool axis too: solve X Y Z A C so that the modelled actual
    /// tip and tool axis are the programmed ones (the default; `false` is
    /// `compensate --position-only`, the seed paper's X Y Z correction).
    pub orientation: bool,
}

impl Default for CompensateOptions {
    fn default() -> Self {
        CompensateOptions {
            tolerance_um: 0.5,
            max_split_depth: 8,
            max_arc_chords: 100_000,
            interpret: InterpretOptions::default(),
            rewrite: RewriteOptions::default(),
            chunk_blocks: 4096,
            chunk_moves: 16_384,
            limits: None,
            expected_residual: false,
            orientation: true,
        }
    }
}

/// The summary (`--report` JSON: formats.md fields first).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct CompensateReport {
    /// Blocks read from the program.
    pub blocks_read: usize,
    /// Blocks written differently from how they were read.
    pub blocks_changed: usize,
    /// Moves split into straight pieces because the correction varies along them.
    pub blocks_split: usize,
    /// Largest and RMS |Δ(X, Y, Z)| of the motion targets, µm (block frame).
    pub max_correction_um: f64,
    /// RMS of the same, µm.
    pub rms_correction_um: f64,
    /// Wall-clock time of the run, seconds.
    pub seconds: f64,
    /// Motion blocks and the new blocks the splits added.
    pub motion_blocks: usize,
    /// Blocks the splits (and flattened cycles) added.
    pub blocks_added: usize,
    /// Largest solver residual, nm.
    pub max_residual_nm: f64,
    /// Line of the largest correction.
    pub max_correction_line: usize,
    /// Lookups that held a table's end value (`--extrapolate hold`).
    pub held_lookups: u64,
    /// The split tolerance of the run ([`CompensateOptions::tolerance_um`]), µm.
    pub tolerance_um: f64,
    /// The corrections per run of blocks cut with one tool, in program order.
    pub tools: Vec<ToolCorrections>,
    /// The expected residual after compensation from the model's own noise:
    /// the standard uncertainty of e (table noise and fit, propagated; RMS
    /// length) at each compensated move end, RMS and largest over the moves,
    /// µm. Unmodelled effects are not in it. Absent when the model carries no
    /// uncertainties (extension: docs/extensions.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub expected_residual_rms_um: Option<f64>,
    /// The largest such standard uncertainty over the moves, µm (absent as above).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub expected_residual_max_um: Option<f64>,
    /// With `--orientation`: the modelled tool-axis error at the move ends
    /// before and after compensation (max and RMS, µrad), and the moves left to
    /// the position-only solve near the A = 0 pole, with their first lines.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub orientation: Option<OrientationReport>,
    /// Move ends inside the tables whose corrections cross a table's end:
    /// the end value was held over that sliver (absent when none).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub table_ends: Option<TableEndReport>,
    /// The warnings of the run (`crate::warnings`; the command fills it).
    pub warnings: Vec<crate::warnings::WarningGroup>,
    /// Moves that reached the split cap (2^`max_split_depth` pieces) with the
    /// correction still departing from a piece by more than the tolerance
    /// (extension: docs/extensions.md).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub split_cap: Option<SplitCap>,
    /// Subroutine definitions written as they are: the program passes over
    /// them (LinuxCNC skips a definition where it stands), so they are not
    /// compensated there; the calls the program makes are written flat and
    /// compensated (extension: docs/extensions.md).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub subroutine_definitions: Vec<PassedDefinition>,
    #[serde(skip)]
    residual_sum_sq: f64,
    #[serde(skip)]
    residual_moves: usize,
}

/// Targets at a table's end whose corrections cross it (issue 23): the
/// table's end value is held over the sliver beyond it, as long as it is
/// shorter than the correction itself.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TableEndReport {
    /// Move ends so compensated.
    pub moves: usize,
    /// Line of the first such move end.
    pub first_line: usize,
    /// How far beyond a table's end, at most: X Y Z µm, A µrad.
    pub max_um: f64,
    /// The same for the rotary axes, µrad.
    pub max_urad: f64,
    /// Lookups held over such slivers (move ends and split points).
    pub lookups: u64,
}

/// The moves that reached the split cap (see [`CompensateReport::split_cap`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SplitCap {
    /// Most pieces a move is split into.
    pub pieces: usize,
    /// Moves that reached the cap.
    pub moves: usize,
    /// Their lines (the first 50).
    pub lines: Vec<usize>,
    /// The largest departure of the correction from the pieces written, µm
    /// (at the points the split test samples).
    pub max_departure_um: f64,
}

/// A subroutine definition written as it is (see
/// [`CompensateReport::subroutine_definitions`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct PassedDefinition {
    /// Its label as written (`o<probe>`, `O100`).
    pub name: String,
    /// Lines of its `sub` and `endsub`.
    pub first_line: usize,
    /// Line of its `endsub`.
    pub last_line: usize,
}

/// The tool-axis side of `compensate --orientation`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct OrientationReport {
    /// Compensated move ends counted here.
    pub moves: usize,
    /// Largest modelled tool-axis error before compensation, µrad.
    pub axis_error_before_max_urad: f64,
    /// RMS of the modelled tool-axis error before compensation, µrad.
    pub axis_error_before_rms_urad: f64,
    /// Largest modelled tool-axis error left after compensation, µrad.
    pub axis_error_after_max_urad: f64,
    /// RMS of the modelled tool-axis error left after compensation, µrad.
    pub axis_error_after_rms_urad: f64,
    /// Moves too close to the A = 0 pole for C to steer the axis: position only.
    pub position_only_moves: usize,
    /// Their lines (the first 50).
    pub position_only_lines: Vec<usize>,
    #[serde(skip)]
    before_sum_sq: f64,
    #[serde(skip)]
    after_sum_sq: f64,
}

/// Correction statistics of a run of blocks cut with one tool.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ToolCorrections {
    /// Tool number (0: the default tool, the machine file's `[tool]`).
    pub tool: u32,
    /// Its length (gauge point to tip), the lever of the angular errors, mm.
    pub length_mm: f64,
    /// Lines of the run's first and last compensated move.
    pub first_line: usize,
    /// Line of the run's last compensated move.
    pub last_line: usize,
    /// Compensated moves in the run.
    pub moves: usize,
    /// Largest |Δ(X, Y, Z)| of the run's motion targets, µm.
    pub max_correction_um: f64,
    /// RMS |Δ(X, Y, Z)| of the run's motion targets, µm.
    pub rms_correction_um: f64,
    #[serde(skip)]
    sum_sq: f64,
}

impl CompensateReport {
    /// Count one compensated move of `um` at `line`, cut with `tool`.
    fn record(&mut self, line: usize, tool: &ToolInUse, length_mm: f64, um: f64) {
        self.motion_blocks += 1;
        if um > self.max_correction_um {
            self.max_correction_um = um;
            self.max_correction_line = line;
        }
        let same = self
            .tools
            .last()
            .is_some_and(|t| t.tool == tool.number && t.length_mm == length_mm);
        if !same {
            self.tools.push(ToolCorrections {
                tool: tool.number,
                length_mm,
                first_line: line,
                ..ToolCorrections::default()
            });
        }
        if let Some(t) = self.tools.last_mut() {
            t.last_line = line;
            t.moves += 1;
            t.max_correction_um = t.max_correction_um.max(um);
            t.sum_sq += um * um;
        }
    }

    /// Count the tool axis of one compensated move end (`--orientation`).
    fn record_axis(&mut self, line: usize, a: AxisCorrection) {
        let o = self
            .orientation
            .get_or_insert_with(OrientationReport::default);
        o.moves += 1;
        o.axis_error_before_max_urad = o.axis_error_before_max_urad.max(a.before_urad);
        o.axis_error_after_max_urad = o.axis_error_after_max_urad.max(a.after_urad);
        o.before_sum_sq += a.before_urad * a.before_urad;
        o.after_sum_sq += a.after_urad * a.after_urad;
        if a.position_only {
            o.position_only_moves += 1;
            if o.position_only_lines.len() < 50 && o.position_only_lines.last() != Some(&line) {
                o.position_only_lines.push(line);
            }
        }
    }

    /// Count a move end whose correction crosses a table's end.
    fn record_table_end(&mut self, line: usize, end: TableEnd) {
        let t = self.table_ends.get_or_insert_with(|| TableEndReport {
            first_line: line,
            ..TableEndReport::default()
        });
        t.moves += 1;
        t.max_um = t.max_um.max(end.um);
        t.max_urad = t.max_urad.max(end.urad);
    }

    /// Count the model's standard uncertainty `um` at one compensated move end.
    fn record_uncertainty(&mut self, um: f64) {
        self.residual_sum_sq += um * um;
        self.residual_moves += 1;
        self.expected_residual_max_um = Some(self.expected_residual_max_um.unwrap_or(0.0).max(um));
    }

    /// Count a move that reached the split cap with `gap_um` left.
    fn record_cap(&mut self, line: usize, gap_um: f64) {
        let cap = self.split_cap.get_or_insert_with(SplitCap::default);
        cap.moves += 1;
        if cap.lines.len() < 50 {
            cap.lines.push(line);
        }
        cap.max_departure_um = cap.max_departure_um.max(gap_um);
    }

    /// Note a line that is written as it is, not executed: the lines of a
    /// subroutine definition the program passes over are counted by
    /// definition.
    fn record_passed(&mut self, block: &Block) {
        use crate::gcode::block::OKeyword;
        let Some(o) = &block.o_word else {
            return;
        };
        match o.keyword {
            OKeyword::Sub => {
                let text = String::from_utf8_lossy(block.raw.get(o.start..o.end).unwrap_or(&[]));
                // The label: the text before the keyword `sub`.
                let label = text
                    .trim_end()
                    .get(..text.trim_end().len().saturating_sub(3))
                    .unwrap_or("")
                    .trim_end()
                    .to_string();
                self.subroutine_definitions.push(PassedDefinition {
                    name: label,
                    first_line: block.line,
                    last_line: block.line,
                });
            }
            OKeyword::EndSub => {
                if let Some(d) = self.subroutine_definitions.last_mut() {
                    d.last_line = block.line;
                }
            }
            _ => {}
        }
    }

    /// The RMS values, once every move is recorded.
    fn finish(&mut self, options: &CompensateOptions) {
        if let Some(cap) = self.split_cap.as_mut() {
            cap.pieces = 1usize << options.max_split_depth.min(63);
        }
        if let Some(o) = self.orientation.as_mut()
            && o.moves > 0
        {
            o.axis_error_before_rms_urad = (o.before_sum_sq / o.moves as f64).sqrt();
            o.axis_error_after_rms_urad = (o.after_sum_sq / o.moves as f64).sqrt();
        }
        if self.residual_moves > 0 {
            self.expected_residual_rms_um =
                Some((self.residual_sum_sq / self.residual_moves as f64).sqrt());
        }
        let rms = |sum_sq: f64, n: usize| {
            if n > 0 {
                (sum_sq / n as f64).sqrt()
            } else {
                0.0
            }
        };
        for t in &mut self.tools {
            t.rms_correction_um = rms(t.sum_sq, t.moves);
        }
        let (sum_sq, n) = self
            .tools
            .iter()
            .fold((0.0, 0), |(s, n), t| (s + t.sum_sq, n + t.moves));
        self.rms_correction_um = rms(sum_sq, n);
    }
}

/// Why a compensation run stopped; every variant but `Gcode` names the program file and line.
#[derive(Debug, thiserror::Error)]
pub enum CompensateError {
    /// The program could not be read or interpreted.
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    /// Solving the joints of a block's compensated target failed (a table lookup, a non-finite target, no convergence).
    #[error("{path}:{line}: {source}")]
    Solve {
        /// The program file.
        path: PathBuf,
        /// Line of the block.
        line: usize,
        /// Why the solve failed.
        source: SolveError,
    },
    /// A compensated target falls outside the travel limits of the machine file.
    #[error(
        "{path}:{line}: the compensated target puts {axis:?} at {value:.4}, outside its travel [{}, {}]; \
the machine cannot cut this block as compensated (move the part or relax the limits in the machine file)",
        range[0], range[1]
    )]
    OutsideTravel {
        /// The program file.
        path: PathBuf,
        /// Line of the block.
        line: usize,
        /// The joint out of travel.
        axis: crate::axes::Axis,
        /// Its compensated position (mm, or degrees for a rotary axis).
        value: f64,
        /// Its travel limits `[min, max]`, same units.
        range: [f64; 2],
    },
    /// An arc would need more straight pieces than [`CompensateOptions::max_arc_chords`].
    #[error(
        "{path}:{line}: the correction varies along this arc, which must be written as straight pieces: \
{needed:.0} are needed to stay within a tenth of the tolerance of the arc, more than the {cap} volcomp writes for one arc; \
raise --tol, or split the arc in the program"
    )]
    TooManyChords {
        /// The program file.
        path: PathBuf,
        /// Line of the arc.
        line: usize,
        /// Pieces the arc would need.
        needed: f64,
        /// The most pieces allowed for one arc.
        cap: usize,
    },
    /// Writing a compensated block failed (output I/O or a block that cannot be rewritten).
    #[error("{path}:{line}: {source}")]
    Rewrite {
        /// The program file.
        path: PathBuf,
        /// Line of the block.
        line: usize,
        /// Why the rewrite failed.
        source: RewriteError,
    },
}

/// What to do with one motion block, computed in parallel.
#[derive(Clone, Debug, Default)]
struct Plan {
    end: Option<Axes>,
    via: Vec<Axes>,
    /// The split cap was reached: the largest departure left, µm.
    capped_gap_um: Option<f64>,
    correction_um: f64,
    /// Length of the tool cutting it, mm.
    length_mm: f64,
    /// The model's standard uncertainty of e at the nominal end, µm.
    uncertainty_um: Option<f64>,
}

/// A compensated target: in the block's frame, and the solve residual (mm).
#[derive(Clone, Copy, Debug)]
struct Compensated {
    target: Pose,
    residual_mm: f64,
    /// With `--orientation`: the tool-axis error before and after (µrad), and
    /// whether the pose was left to the position-only solve (A = 0 pole).
    orientation: Option<AxisCorrection>,
    /// The target is inside the tables and its correction crosses a table's
    /// end: how far (the end value was held over that sliver).
    beyond_table: Option<TableEnd>,
}

/// How far a compensated target lies beyond a table's end: X Y Z µm, A µrad.
#[derive(Clone, Copy, Debug)]
struct TableEnd {
    um: f64,
    urad: f64,
}

#[derive(Clone, Copy, Debug)]
struct AxisCorrection {
    before_urad: f64,
    after_urad: f64,
    position_only: bool,
}

/// Angle between the modelled actual tool axis at `joints` and the nominal one
/// at `nominal`, µrad.
fn axis_error_urad(
    model: &ErrorModel,
    joints: &Joints,
    nominal: &Joints,
    approach: &Approach,
) -> Result<f64, PointError> {
    let kin = model.kinematics();
    let errors = model
        .errors_toward(joints, approach)
        .map_err(|e| PointError::Solve(SolveError::Lookup(e)))?;
    let actual = crate::vec3::normalise(model.actual_tip_and_axis(joints, &errors).axis);
    let programmed = kin.nominal_tool_axis(nominal);
    Ok(1e6 * crate::vec3::norm(crate::vec3::cross(actual, programmed)))
}

/// The compensated target of `target` (in its frame), the solve starting from
/// `warm` (updated when it succeeds); A and C corrected too when `orientation`;
/// the pose approached as `approach` says (the reversal terms).
fn compensate_target(
    model: &ErrorModel,
    target: &Pose,
    limits: Option<&Limits>,
    warm: &mut WarmStart,
    orientation: bool,
    approach: &Approach,
) -> Result<Compensated, PointError> {
    let kin = model.kinematics();
    let nominal = joints_of(kin, target);
    let (joints, residual_mm, axis, beyond) =
        match solve_target(model, &nominal, warm, orientation, approach) {
            Err(PointError::Solve(SolveError::Lookup(e @ LookupError::OutOfRange { .. })))
                if model.policy() == ExtrapolationPolicy::Error
                    && model.errors_at(&nominal).is_ok() =>
            {
                // The target is inside every table but its correction crosses a
                // table's end: hold the end value over that sliver when it is
                // shorter than the correction itself (issue 23), else the
                // lookup error stands.
                let held = model.holding_ends();
                let (joints, residual_mm, axis) =
                    solve_target(held, &nominal, warm, orientation, approach)?;
                let beyond = model.beyond_tables(&joints);
                let within = crate::axes::Axis::ALL.into_iter().all(|a| {
                    let b = beyond.get(a);
                    b == 0.0 || b <= (joints.get(a) - nominal.get(a)).abs()
                });
                if !within {
                    return Err(PointError::Solve(SolveError::Lookup(e)));
                }
                (joints, residual_mm, axis, Some(beyond))
            }
            other => {
                let (joints, residual_mm, axis) = other?;
                (joints, residual_mm, axis, None)
            }
        };
    if let Some(l) = limits
        && let Some((axis, value, range)) = l.violated(&joints)
    {
        return Err(PointError::Travel { axis, value, range });
    }
    let (jq, jn) = (kin.joints(&joints), kin.joints(&nominal));
    warm.correction = std::array::from_fn(|i| jq[i] - jn[i]);
    Ok(Compensated {
        target: pose_of(kin, target.frame(), &joints),
        residual_mm,
        orientation: axis,
        beyond_table: beyond.map(|b| TableEnd {
            um: 1e3 * b.x.max(b.y).max(b.z),
            urad: b.a.max(b.b).max(b.c).to_radians() * 1e6,
        }),
    })
}

/// The joints of [`compensate_target`] (no travel check), their residual and
/// tool-axis correction.
fn solve_target(
    model: &ErrorModel,
    nominal: &Joints,
    warm: &mut WarmStart,
    orientation: bool,
    approach: &Approach,
) -> Result<(Joints, f64, Option<AxisCorrection>), PointError> {
    let nominal = *nominal;
    let guess = warm.correction;
    let (joints, residual_mm, axis) = if orientation {
        match solve_pose_toward(model, &nominal, approach, warm).map_err(PointError::Solve)? {
            Some(pose) => (
                pose.joints,
                pose.residual_mm,
                Some(AxisCorrection {
                    before_urad: pose.before_urad,
                    after_urad: pose.residual_urad,
                    position_only: false,
                }),
            ),
            None => {
                let before = axis_error_urad(model, &nominal, &nominal, approach)?;
                let xyz = [guess[0], guess[1], guess[2]];
                let solved = solve_joints_toward(model, &nominal, approach, xyz)
                    .map_err(PointError::Solve)?;
                let after = axis_error_urad(model, &solved.joints, &nominal, approach)?;
                (
                    solved.joints,
                    solved.residual_mm,
                    Some(AxisCorrection {
                        before_urad: before,
                        after_urad: after,
                        position_only: true,
                    }),
                )
            }
        }
    } else {
        let xyz = [guess[0], guess[1], guess[2]];
        let solved =
            solve_joints_toward(model, &nominal, approach, xyz).map_err(PointError::Solve)?;
        (solved.joints, solved.residual_mm, None)
    };
    Ok((joints, residual_mm, axis))
}

/// First-order estimate of [`compensate_target`] for the split decision (one
/// error evaluation, no limits): X Y Z such that the actual tip lands on the
/// programmed one, at the programmed rotary joints or at `rotary` (degrees, slot
/// order).
fn estimate_target(
    model: &ErrorModel,
    target: &Pose,
    rotary: Option<[f64; 2]>,
    approach: &Approach,
) -> Result<Pose, PointError> {
    let kin = model.kinematics();
    let nominal = joints_of(kin, target);
    let estimate = |model: &ErrorModel| match rotary {
        Some(r) => first_order_joints_at(model, &nominal, r, approach),
        None => first_order_joints(model, &nominal, approach),
    };
    let q = match estimate(model) {
        // Corrected angles just beyond a table's end: held over the sliver,
        // as `compensate_target` does.
        Err(SolveError::Lookup(LookupError::OutOfRange { .. }))
            if model.policy() == ExtrapolationPolicy::Error
                && model.errors_at(&nominal).is_ok() =>
        {
            estimate(model.holding_ends())
        }
        other => other,
    }
    .map_err(PointError::Solve)?;
    Ok(pose_of(kin, target.frame(), &q))
}

#[derive(Debug)]
enum PointError {
    Solve(SolveError),
    Travel {
        axis: crate::axes::Axis,
        value: f64,
        range: [f64; 2],
    },
    TooManyChords {
        needed: f64,
        cap: usize,
    },
}

fn xyz_gap(a: &Axes, b: &Axes) -> f64 {
    a.xyz_distance(b)
}

/// The split points of one motion block, and whether the split cap was
/// reached.
#[derive(Clone, Debug, Default)]
struct Split {
    via: Vec<Axes>,
    /// The piece cap ([`CompensateOptions::max_split_depth`]) was reached with
    /// the correction still departing from a piece by this much, µm.
    capped_gap_um: Option<f64>,
}

/// Turns a move sweeps: the arc's sweep, or A's or C's travel, whichever is
/// most, in turns.
fn turns_swept(motion: &Motion, arc: Option<&ArcGeometry>) -> f64 {
    let sweep = arc.map_or(0.0, |g| g.sweep().abs() / std::f64::consts::TAU);
    let a = (motion.end.a - motion.start.a).abs() / 360.0;
    let c = (motion.end.c - motion.start.c).abs() / 360.0;
    sweep.max(a).max(c)
}

/// Where the split test samples a piece `[t0, t1]` of a move that sweeps
/// `turns` in all: its midpoint, and where the piece sweeps more than a
/// quarter turn, `k` evenly spaced points at most a quarter turn apart
/// (`j / (k + 1)`, never a whole turn from the ends: a full circle of even
/// `P` or `G1 C720` has its midpoint at the pose of its ends).
fn sample_fractions(turns: f64, t0: f64, t1: f64) -> impl Iterator<Item = f64> {
    let k = (4.0 * turns * (t1 - t0)).ceil();
    // Bounded: a move of 2^31 turns is refused before (too many chords).
    let k = if k.is_finite() && k > 1.0 {
        k.min(1e7) as usize
    } else {
        1
    };
    (1..=k).map(move |j| j as f64 / (k + 1) as f64)
}

/// The directions of the axes with a reversal at fraction `t` of `motion`,
/// from `incoming` (before the move; `None`: the machine has no reversal): a
/// straight joint move's are its end's (`end`) past its start.
fn approach_at(
    model: &ErrorModel,
    motion: &Motion,
    incoming: Option<&DirectionTracker>,
    end: &Approach,
    t: f64,
) -> Approach {
    let Some(incoming) = incoming else {
        return Approach::NONE;
    };
    if motion.target_frame() == Frame::Joint && motion.arc_geometry().is_none() {
        return *end;
    }
    let mut tracker = incoming.clone();
    crate::toolpath::walk::advance_directions(&mut tracker, model.kinematics(), motion, 0.0, t);
    tracker.approach()
}

/// How a motion was approached: the directions before it (`None`: the machine
/// has no reversal) and at its end.
#[derive(Clone, Copy)]
struct Directions<'a> {
    incoming: Option<&'a DirectionTracker>,
    end: &'a Approach,
}

/// Plan one motion block: its compensated end (already solved), and split points.
fn plan_motion(
    model: &ErrorModel,
    motion: &Motion,
    start_comp: Option<Axes>,
    end_comp: Axes,
    options: &CompensateOptions,
    directions: Directions<'_>,
) -> Result<Split, PointError> {
    let splittable = !matches!(motion.kind, MotionKind::Rapid);
    let Some(mut start_comp) = start_comp.filter(|_| splittable) else {
        return Ok(Split::default());
    };
    let arc = motion.arc_geometry();
    let at = |t: f64| approach_at(model, motion, directions.incoming, directions.end, t);
    // A move that reverses an axis with a reversal (its direction before the
    // move is not its direction at the end): the written start was compensated
    // for the old direction. A straight move gets a take-up piece: its first
    // point, where the programmed motion of each reversing axis has gone far
    // enough to reverse it (below), is compensated in the new direction, so the
    // reversal is taken up within that piece, and the split test runs from
    // there. An arc, or a move too short for it, takes the reversal up over
    // its length (docs/extensions.md "Reversal errors").
    let mut t_start = 0.0;
    let mut take_up = None;
    if let Some(incoming) = directions.incoming
        && incoming.approach() != *directions.end
    {
        let before = incoming.approach();
        let kin = model.kinematics();
        let (q0, q1) = (
            joints_of(kin, &motion.start_pose()),
            joints_of(kin, &motion.end_pose()),
        );
        let mut t_s = 0.0f64;
        for axis in crate::axes::Axis::ALL {
            let (b, e) = (before.get(axis), directions.end.get(axis));
            if b == e || e == Direction::Unknown {
                continue;
            }
            let Some(r) = model.reversal_at(axis, q0.get(axis)) else {
                continue;
            };
            let play = if axis.is_rotary() {
                (r.abs() * 1e-6).to_degrees()
            } else {
                r.abs() * 1e-3
            };
            // The piece's compensated motion along the axis is the programmed
            // δ minus REVERSAL (in the new direction): it must exceed the play
            // for the axis to have reversed at its end (δ > 2·REVERSAL when
            // REVERSAL > 0; any δ when it is negative, a lost motion).
            let k = if r > 0.0 { 2.5 } else { 0.5 };
            let d = (q1.get(axis) - q0.get(axis)).abs();
            t_s = t_s.max(if d > 0.0 { k * play / d } else { f64::INFINITY });
        }
        let at_new = |t: f64| {
            compensate_target(
                model,
                &motion.pose(motion.point_at(arc.as_ref(), t)),
                options.limits.as_ref(),
                &mut WarmStart::default(),
                options.orientation,
                directions.end,
            )
            .map(|c| c.target.axes())
        };
        if arc.is_none() && t_s > 0.0 && t_s < 0.9 {
            let c = at_new(t_s)?;
            take_up = Some(c);
            t_start = t_s;
            start_comp = c;
        } else {
            start_comp = at_new(0.0)?;
        }
    }
    let turns = turns_swept(motion, arc.as_ref());
    let tol_mm = options.tolerance_um * 1e-3;
    let limits = options.limits.as_ref();
    // Recursive halving on [t0, t1] with compensated ends c0, c1.
    let mut split = Split::default();
    split.via.extend(take_up);
    // Depth-first, left first, so `via` comes out in order: the left half is
    // taken next, the right half waits on the stack (which a move that is not
    // split never allocates).
    let mut stack = Vec::new();
    let mut next = Some((t_start, 1.0f64, start_comp, end_comp, 0u32));
    while let Some((t0, t1, c0, c1, depth)) = next.take().or_else(|| stack.pop()) {
        let n0 = motion.point_at(arc.as_ref(), t0);
        let n1 = motion.point_at(arc.as_ref(), t1);
        let (a, b, na, nb) = (c0.to_array(), c1.to_array(), n0.to_array(), n1.to_array());
        // The largest departure of the exact correction from the straight
        // interpolation of the corrections at the ends (what the control
        // would do), over the samples.
        let mut gap = 0.0f64;
        for f in sample_fractions(turns, t0, t1) {
            let nominal = motion.point_at(arc.as_ref(), t0 + f * (t1 - t0));
            let nm = nominal.to_array();
            let straight = Axes::from_array(std::array::from_fn(|i| {
                nm[i] + (1.0 - f) * (a[i] - na[i]) + f * (b[i] - nb[i])
            }));
            // With `--orientation` the control turns the rotary axes to the interpolated
            // corrected angles: the X Y Z the tip needs there, to first order.
            let [r1, r2] = model.kinematics().rotary();
            let rotary = options
                .orientation
                .then_some([straight.get(r1), straight.get(r2)]);
            let approach = at(t0 + f * (t1 - t0));
            let estimate = estimate_target(model, &motion.pose(nominal), rotary, &approach)?;
            gap = gap.max(xyz_gap(&estimate.axes(), &straight));
            if gap > tol_mm && depth < options.max_split_depth {
                break;
            }
        }
        if gap > tol_mm
            && let Some(arc) = arc.as_ref()
        {
            // A split arc becomes straight pieces on the compensated arc.
            return Ok(Split {
                via: densify_arc(model, motion, arc, options, directions.incoming)?,
                capped_gap_um: None,
            });
        }
        if gap > tol_mm && depth < options.max_split_depth {
            let tm = 0.5 * (t0 + t1);
            let cm = compensate_target(
                model,
                &motion.pose(motion.point_at(arc.as_ref(), tm)),
                limits,
                &mut WarmStart::default(),
                options.orientation,
                &at(tm),
            )?
            .target
            .axes();
            stack.push((tm, t1, cm, c1, depth + 1));
            next = Some((t0, tm, c0, cm, depth + 1));
            continue;
        }
        if gap > tol_mm {
            let um = gap * 1e3;
            split.capped_gap_um = Some(split.capped_gap_um.map_or(um, |g| g.max(um)));
        }
        if t1 < 1.0 {
            split.via.push(c1);
        }
    }
    Ok(split)
}

/// Straight pieces along a compensated arc, each within a tenth of the
/// tolerance of the arc (at most [`CompensateOptions::max_arc_chords`]).
fn densify_arc(
    model: &ErrorModel,
    motion: &Motion,
    arc: &ArcGeometry,
    options: &CompensateOptions,
    incoming: Option<&DirectionTracker>,
) -> Result<Vec<Axes>, PointError> {
    let n = arc_chords(arc, options.tolerance_um * 1e-4);
    if n > options.max_arc_chords as f64 {
        return Err(PointError::TooManyChords {
            needed: n,
            cap: options.max_arc_chords,
        });
    }
    let n = n as usize;
    let mut via = Vec::with_capacity(n - 1);
    let mut warm = WarmStart::default();
    // The directions along the arc, advanced chord by chord.
    let mut tracker = incoming.cloned();
    for i in 1..n {
        let t = i as f64 / n as f64;
        let p = motion.point_at(Some(arc), t);
        let approach = match tracker.as_mut() {
            Some(tr) => {
                crate::toolpath::walk::advance_directions(
                    tr,
                    model.kinematics(),
                    motion,
                    (i - 1) as f64 / n as f64,
                    t,
                );
                tr.approach()
            }
            None => Approach::NONE,
        };
        via.push(
            compensate_target(
                model,
                &motion.pose(p),
                options.limits.as_ref(),
                &mut warm,
                options.orientation,
                &approach,
            )?
            .target
            .axes(),
        );
    }
    Ok(via)
}

/// Chords of equal angle that keep an arc (a helix: its chords depart from
/// it as its circle's do) within `sag_mm` of each chord: at least 2.
fn arc_chords(arc: &ArcGeometry, sag_mm: f64) -> f64 {
    let (r0, r1) = arc.radii();
    let r = r0.max(r1).max(1e-9);
    let sag = sag_mm.max(1e-7);
    // A chord of angle θ departs from its circle by r (1 − cos θ/2).
    let angle = if sag >= r {
        std::f64::consts::PI
    } else {
        2.0 * (1.0 - sag / r).acos()
    };
    (arc.sweep().abs() / angle.max(1e-12)).ceil().max(2.0)
}

/// Compensate `program` into `output`. `progress` is called after each chunk
/// with the number of blocks done. Blocks flattened by the language layer and
/// canned cycles are written flat (each executed move explicit, compensated).
pub fn compensate(
    program: Program,
    output: &mut dyn Write,
    model: &ErrorModel,
    options: &CompensateOptions,
    mut progress: impl FnMut(usize),
) -> Result<CompensateReport, CompensateError> {
    let started = Instant::now();
    let path = program.path().to_path_buf();
    let path = path.as_path();
    let held_before = model.held_lookups();
    let sliver_before = model.table_end_lookups();
    let mut models = ToolModels::new(model);
    let (sender, chunks) = std::sync::mpsc::sync_channel::<Result<Chunk, GcodeError>>(2);
    let (solved_sender, solved) = std::sync::mpsc::sync_channel::<Solved>(2);
    // Splines become straight pieces within a tenth of the tolerance of the
    // curve, as split arcs do; each piece's end is compensated.
    let interpret = InterpretOptions {
        spline_tolerance_mm: options.tolerance_um * 1e-4,
        ..options.interpret
    };
    let size = ChunkSize {
        blocks: options.chunk_blocks.max(1),
        moves: options.chunk_moves.max(1),
    };
    let options = &CompensateOptions {
        rewrite: crate::gcode::RewriteOptions {
            dialect: program.dialect().dialect,
            ..options.rewrite
        },
        ..options.clone()
    };
    let models_ref = &mut models;
    // The chain's orientation, for the tool vectors a writer writes (A3= B3= C3=, LN).
    let orientation = program.setup().orientation.clone();
    std::thread::scope(|scope| {
        // Three stages, each a chunk or two ahead of the next (bounded channels:
        // memory stays bounded): reading and interpreting; solving and planning
        // (rayon); writing in order, here. A stage that stops (end, error, or a
        // later stage gone) drops its sender, which ends the next one.
        scope.spawn(move || read_chunks(program, interpret, size, sender));
        let solver =
            scope.spawn(move || solve_chunks(chunks, path, models_ref, options, solved_sender));
        let written = write_chunks(solved, path, output, options, orientation, &mut progress);
        let axes = match solver.join() {
            Ok(axes) => axes,
            Err(panic) => std::panic::resume_unwind(panic),
        };
        written.map(|mut report| {
            report.max_residual_nm = axes.max_residual_nm;
            report.orientation = axes.orientation;
            report.table_ends = axes.table_ends;
            report.finish(options);
            report
        })
    })
    .map(|mut report| {
        report.held_lookups = models.held_lookups().saturating_sub(held_before);
        let sliver = models.table_end_lookups().saturating_sub(sliver_before);
        if sliver > 0 {
            report
                .table_ends
                .get_or_insert_with(TableEndReport::default)
                .lookups = sliver;
        }
        report.seconds = started.elapsed().as_secs_f64();
        report
    })
}

/// A run of parsed blocks with their interpretation.
type Chunk = Vec<(Block, BlockEvent)>;

/// Where a chunk ends: at this many blocks, or at the block that brings its
/// moves to this many.
#[derive(Clone, Copy)]
struct ChunkSize {
    blocks: usize,
    moves: usize,
}

/// The reader thread: run the program into chunks; stop at the end, at the
/// first error (sent on), or when the receiver has gone.
fn read_chunks(
    program: Program,
    interpret: InterpretOptions,
    size: ChunkSize,
    sender: std::sync::mpsc::SyncSender<Result<Chunk, GcodeError>>,
) {
    let mut run = program.run(interpret);
    loop {
        let mut chunk = Vec::with_capacity(size.blocks.min(4096));
        let mut moves = 0usize;
        let mut done = false;
        while chunk.len() < size.blocks && moves < size.moves {
            match run.next() {
                None => {
                    done = true;
                    break;
                }
                Some(Ok((block, event, _))) => {
                    moves += event.expanded().len().max(1);
                    chunk.push((block.clone(), event.clone()));
                }
                Some(Err(e)) => {
                    let _ = sender.send(Err(e));
                    return;
                }
            }
        }
        if (!chunk.is_empty() && sender.send(Ok(chunk)).is_err()) || done {
            return;
        }
    }
}

/// The moves of a block that are compensated: its one move, or the moves of a
/// canned cycle or the straight pieces of a spline (written flat). G28/G30
/// legs go to stored positions and are not compensated.
fn compensated_moves(event: &BlockEvent) -> &[Motion] {
    if event.skipped {
        return &[];
    }
    match &event.moves {
        Moves::Move(m) => std::slice::from_ref(m),
        Moves::Cycle { moves, .. } | Moves::Spline(moves) => moves,
        Moves::Home(moves) if event.spline.is_some() => moves,
        Moves::Home(_) | Moves::None => &[],
    }
}

/// What the solving stage hands the writing stage, in program order: a solved
/// chunk, or the error that stopped the solving.
type Solved = Result<SolvedChunk, CompensateError>;

/// A chunk with its compensated targets and split points.
struct SolvedChunk {
    chunk: Chunk,
    /// Per block (an error is the first failure, reported in program order).
    plans: Vec<Result<Plan, PointError>>,
    /// Per block: its canned cycle's compensated move ends, if it is one.
    cycles: Vec<Option<SolvedCycle>>,
}

/// The compensated moves of a canned cycle (written flat).
struct SolvedCycle {
    ends: Vec<Axes>,
    /// |Δ(X, Y, Z)| of each end, µm.
    corrections_um: Vec<f64>,
    /// Length of the tool cutting it, mm.
    length_mm: f64,
}

/// |Δ(X, Y, Z)| between a compensated and a programmed target, µm.
fn xyz_correction_um(compensated: &Axes, programmed: &Axes) -> f64 {
    compensated.xyz_distance(programmed) * 1e3
}

/// The solving stage: chunks in, compensated targets and split points out
/// (rayon within a chunk). Returns what it recorded of the solves themselves
/// (largest residual, tool-axis errors); it stops at the first error, which it
/// sends on, or when the writing stage has gone.
fn solve_chunks(
    chunks: std::sync::mpsc::Receiver<Result<Chunk, GcodeError>>,
    path: &Path,
    models: &mut ToolModels,
    options: &CompensateOptions,
    solved: std::sync::mpsc::SyncSender<Solved>,
) -> CompensateReport {
    let mut axes = CompensateReport::default();
    // Compensated end of the previous motion (the numbers written).
    let mut previous: Option<Axes> = None;
    // The directions of the axes with a reversal (empty without one).
    let mut directions = models.get(&ToolInUse::DEFAULT).direction_tracker();
    let tracking = !directions.is_empty();
    // The rotary joints held under a swivelled plane, from an earlier chunk.
    let mut held: Option<held_rotary::HeldRotary> = None;
    for chunk in chunks {
        let mut chunk = match chunk {
            Ok(chunk) => chunk,
            Err(e) => {
                let _ = solved.send(Err(e.into()));
                return axes;
            }
        };
        models.prepare(chunk.iter().map(|(_, event)| &event.tool));
        let models = &*models;
        let uncertain =
            options.expected_residual && models.get(&ToolInUse::DEFAULT).has_uncertainty();
        // 0. The direction of each axis with a reversal at the end of every
        //    compensated move: the last motion of the axis in the programmed
        //    (nominal) joints, every move of the program in order (G28/G30 legs
        //    too); before a move, the directions it starts with.
        let mut approaches: Vec<Approach> = Vec::new();
        let mut offsets: Vec<usize> = Vec::with_capacity(chunk.len() + 1);
        let mut incoming: Vec<Option<DirectionTracker>> = Vec::with_capacity(chunk.len());
        for (_, event) in chunk.iter() {
            offsets.push(approaches.len());
            if event.skipped {
                incoming.push(None);
                continue;
            }
            incoming.push((tracking && event.motion().is_some()).then(|| directions.clone()));
            let kin = models.get(&event.tool).kinematics();
            let compensated = compensated_moves(event);
            for m in event.motions() {
                crate::toolpath::walk::advance_directions(&mut directions, kin, m, 0.0, 1.0);
                if compensated.iter().any(|c| std::ptr::eq(c, m)) {
                    approaches.push(directions.approach());
                }
            }
        }
        offsets.push(approaches.len());
        // 0b. Held moves at the corrected rotary joints the program wrote.
        let held_solves =
            held_rotary::hold_corrected_rotary(&mut chunk, held, models, options, &approaches);
        let presolved = &held_solves.presolved;
        // 1. Compensated end of every motion, in parallel over pieces of the chunk;
        //    within a piece each solve starts from the previous correction.
        //    Flat over the chunk's moves, in order.
        let ends: Vec<Result<Compensated, PointError>> = chunk
            .par_chunks(WARM_START_RUN)
            .enumerate()
            .flat_map_iter(|(index, piece)| {
                let mut warm = WarmStart::default();
                let mut k = offsets[index * WARM_START_RUN];
                let approaches = &approaches;
                piece
                    .iter()
                    .flat_map(|(_, event)| {
                        let model = models.get(&event.tool);
                        let held = event.origin.holds_rotary();
                        compensated_moves(event)
                            .iter()
                            .map(move |m| (model, m, held))
                    })
                    .map(|(model, m, held)| {
                        let approach = approaches[k];
                        k += 1;
                        if let Some(c) = presolved.get(&(k - 1)) {
                            return Ok(*c);
                        }
                        compensate_target(
                            model,
                            &m.end_pose(),
                            options.limits.as_ref(),
                            &mut warm,
                            options.orientation && !held,
                            &approach,
                        )
                    })
                    .collect::<Vec<_>>()
            })
            .collect();
        // Per block: its single move's end, or its cycle's ends (`cycle_ends`).
        let mut resolved: Vec<Option<(Axes, f64)>> = Vec::with_capacity(chunk.len());
        let mut cycles: Vec<Option<SolvedCycle>> = Vec::with_capacity(chunk.len());
        let mut ends = ends.into_iter();
        let (mut flat, mut held_end) = (0usize, None);
        for (block, event) in chunk.iter() {
            let moves = compensated_moves(event);
            // A motion's end, or a cycle's ends (only a cycle allocates).
            let single = event.motion().is_some();
            let mut first = None;
            let mut mine = Vec::new();
            for _ in moves {
                flat += 1;
                match ends.next() {
                    Some(Ok(c)) => {
                        if held_solves.pending_move() == Some(flat - 1) {
                            held_end = Some(c.target.axes());
                        }
                        axes.max_residual_nm = axes.max_residual_nm.max(c.residual_mm * 1e6);
                        if let Some(a) = c.orientation {
                            axes.record_axis(block.line, a);
                        }
                        if let Some(end) = c.beyond_table {
                            axes.record_table_end(block.line, end);
                        }
                        let end = (c.target.axes(), c.residual_mm);
                        first = first.or(Some(end));
                        if !single {
                            mine.push(end);
                        }
                    }
                    Some(Err(e)) => {
                        let _ = solved.send(Err(point_error(path, block.line, e)));
                        return axes;
                    }
                    None => unreachable!("one end per move"),
                }
            }
            if single {
                resolved.push(first);
                cycles.push(None);
            } else {
                resolved.push(None);
                cycles.push((!moves.is_empty()).then(|| {
                    SolvedCycle {
                        ends: mine.iter().map(|e| e.0).collect(),
                        corrections_um: mine
                            .iter()
                            .zip(moves)
                            .map(|((end, _), m)| xyz_correction_um(end, &m.end))
                            .collect(),
                        length_mm: models.length_mm(&event.tool),
                    }
                }));
            }
        }
        held = held_solves.carry(held_end);
        // 2. Compensated start of every motion: the previous motion's compensated end.
        let mut starts: Vec<Option<Axes>> = Vec::with_capacity(chunk.len());
        for (((_, event), end), cycle) in chunk.iter().zip(&resolved).zip(&cycles) {
            match (event.motion(), end) {
                (Some(_), Some((e, _))) if !event.skipped => {
                    // Across a frame switch too: the interpreter (and so the
                    // control model of `toolpath`) starts the move from the last
                    // written numbers, which are the compensated ones.
                    starts.push(previous);
                    previous = Some(*e);
                }
                _ => {
                    starts.push(None);
                    if let Some(cycle) = cycle {
                        previous = cycle.ends.last().copied().or(previous);
                    }
                }
            }
        }
        // 3. Split points, in parallel.
        let plans: Vec<Result<Plan, PointError>> = chunk
            .par_iter()
            .zip(resolved.par_iter())
            .zip(starts.par_iter())
            .zip(incoming.par_iter())
            .enumerate()
            .map(|(i, ((((_, event), end), start), before))| {
                let (Some(m), Some((end, _))) = (event.motion(), end) else {
                    return Ok(Plan::default());
                };
                let model = models.get(&event.tool);
                let end_approach = approaches.get(offsets[i]).copied().unwrap_or_default();
                let directions = Directions {
                    incoming: before.as_ref(),
                    end: &end_approach,
                };
                // Under a swivelled plane the control holds the rotary axes:
                // the tip only.
                let tip_only;
                let options = if event.origin.holds_rotary() {
                    tip_only = CompensateOptions {
                        orientation: false,
                        ..options.clone()
                    };
                    &tip_only
                } else {
                    options
                };
                let split = plan_motion(model, m, *start, *end, options, directions)?;
                let uncertainty_um = if uncertain {
                    let joints = joints_of(model.kinematics(), &m.end_pose());
                    Some(
                        model
                            .uncertainty_at(&joints)
                            .map_err(|e| PointError::Solve(SolveError::Lookup(e)))?
                            .magnitude_um(),
                    )
                } else {
                    None
                };
                Ok(Plan {
                    end: Some(*end),
                    via: split.via,
                    capped_gap_um: split.capped_gap_um,
                    correction_um: xyz_correction_um(end, &m.end),
                    length_mm: models.length_mm(&event.tool),
                    uncertainty_um,
                })
            })
            .collect();
        let failed = plans.iter().any(|p| p.is_err());
        let solved_chunk = SolvedChunk {
            chunk,
            plans,
            cycles,
        };
        if solved.send(Ok(solved_chunk)).is_err() || failed {
            return axes;
        }
    }
    axes
}

/// The writing stage: solved chunks in, the compensated program out, in order.
fn write_chunks(
    solved: std::sync::mpsc::Receiver<Solved>,
    path: &Path,
    output: &mut dyn Write,
    options: &CompensateOptions,
    orientation: Option<std::sync::Arc<dyn crate::gcode::OrientationSolver>>,
    progress: &mut dyn FnMut(usize),
) -> Result<CompensateReport, CompensateError> {
    let rewrite = RewriteOptions {
        axes: options.interpret.axes,
        ..options.rewrite
    };
    let mut rewriter =
        Rewriter::new(rewrite, options.interpret.initial_position).with_orientation(orientation);
    let mut report = CompensateReport {
        tolerance_um: options.tolerance_um,
        ..CompensateReport::default()
    };
    let mut emitted = Vec::with_capacity(256);
    for solved in solved {
        // 4. Emit in order.
        let SolvedChunk {
            chunk,
            plans,
            cycles,
        } = solved?;
        for (((block, event), plan), cycle) in chunk.iter().zip(plans).zip(&cycles) {
            let plan = plan.map_err(|e| point_error(path, block.line, e))?;
            report.blocks_read += 1;
            if event.skipped {
                report.record_passed(block);
            }
            if let Some(cycle) = cycle {
                for &um in &cycle.corrections_um {
                    report.record(block.line, &event.tool, cycle.length_mm, um);
                }
                emitted.clear();
                let e = rewriter
                    .emit_flat(block, event, &cycle.ends, &mut emitted)
                    .map_err(|source| CompensateError::Rewrite {
                        path: path.to_path_buf(),
                        line: block.line,
                        source,
                    })?;
                report.blocks_changed += 1;
                report.blocks_added += e.pieces;
                output
                    .write_all(&emitted)
                    .map_err(|source| CompensateError::Rewrite {
                        path: path.to_path_buf(),
                        line: block.line,
                        source: RewriteError::Io(source),
                    })?;
                continue;
            }
            let target = match plan.end {
                None => Target::Same,
                Some(end) => {
                    report.record(block.line, &event.tool, plan.length_mm, plan.correction_um);
                    if let Some(u) = plan.uncertainty_um {
                        report.record_uncertainty(u);
                    }
                    if let Some(gap) = plan.capped_gap_um {
                        report.record_cap(block.line, gap);
                    }
                    if plan.via.is_empty() {
                        Target::Move(end)
                    } else {
                        report.blocks_split += 1;
                        report.blocks_added += plan.via.len();
                        Target::Split {
                            via: &plan.via,
                            end,
                        }
                    }
                }
            };
            emitted.clear();
            rewriter
                .emit(block, event, target, &mut emitted)
                .map_err(|source| CompensateError::Rewrite {
                    path: path.to_path_buf(),
                    line: block.line,
                    source,
                })?;
            if !same_bytes(block, &emitted) {
                report.blocks_changed += 1;
            }
            output
                .write_all(&emitted)
                .map_err(|source| CompensateError::Rewrite {
                    path: path.to_path_buf(),
                    line: block.line,
                    source: RewriteError::Io(source),
                })?;
        }
        progress(report.blocks_read);
    }
    Ok(report)
}

/// Whether the emitted bytes are the block's original line.
fn same_bytes(block: &Block, emitted: &[u8]) -> bool {
    let ending = block.ending.as_bytes();
    emitted.len() == block.raw.len() + ending.len()
        && emitted.starts_with(&block.raw)
        && emitted.ends_with(ending)
}

fn point_error(path: &Path, line: usize, e: PointError) -> CompensateError {
    match e {
        PointError::Solve(source) => CompensateError::Solve {
            path: path.to_path_buf(),
            line,
            source,
        },
        PointError::Travel { axis, value, range } => CompensateError::OutsideTravel {
            path: path.to_path_buf(),
            line,
            axis,
            value,
            range,
        },
        PointError::TooManyChords { needed, cap } => CompensateError::TooManyChords {
            path: path.to_path_buf(),
            line,
            needed,
            cap,
        },
    }
}
