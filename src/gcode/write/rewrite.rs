//! The rewriter: blocks + their events + new targets → program text.
//!
//! # Use (the compensator's loop)
//!
//! ```
//! use volcomp::gcode::{BlockReader, Interpreter, InterpretOptions, ReadOptions,
//!                      RewriteOptions, Rewriter, Target};
//! let program = "G21 G90 G94\nG0 X0 Y0 Z5 A0 C0\nN10 G1 X10.000 F500 (cut)\n";
//! let options = InterpretOptions::default();
//! let mut reader = BlockReader::new(program.as_bytes(), ReadOptions::default());
//! let mut interpreter = Interpreter::new(options);
//! let mut rewriter = Rewriter::new(RewriteOptions::default(), options.initial_position);
//! let mut out = Vec::new();
//! while let Some(block) = reader.next_block() {
//!     let block = block.unwrap();
//!     let event = interpreter.interpret(block).unwrap();
//!     let target = match event.motion() {
//!         // compute the compensated absolute end (same frame as `motion.end`)
//!         Some(m) if block.line == 3 => Target::Move(volcomp::axes::Axes { x: m.end.x + 0.0123, ..m.end }),
//!         _ => Target::Same,
//!     };
//!     rewriter.emit(block, &event, target, &mut out).unwrap();
//! }
//! assert_eq!(String::from_utf8(out).unwrap(),
//!            "G21 G90 G94\nG0 X0 Y0 Z5 A0 C0\nN10 G1 X10.0123 F500 (cut)\n");
//! ```
//!
//! [`rewrite_stream`] runs that loop over a whole `BufRead` with a closure
//! `(block, event, via_buffer) -> Option<new_end>` and counts what changed
//! ([`RewriteStats`]); [`Rewriter::emit`] is the block-level API underneath and
//! reports per block ([`Emitted`]: line rewritten, pieces added).
//!
//! Feed every block to [`Rewriter::emit`] in order with its [`BlockEvent`] and a
//! [`Target`]: [`Target::Same`] (keep the programmed target), [`Target::Move`]
//! (a new absolute end) or [`Target::Split`] (intermediate absolute targets,
//! then the end). Targets are absolute, in mm and degrees, in the block's own
//! frame (the frame of `event.motion()`), exactly like the interpreter's output.
//!
//! # Contract
//! - A block is written byte for byte (raw text + its own line ending) when
//!   nothing it must say changes: its target is the same, the program emitted so
//!   far stands where the original stood (this matters under G91 and for arcs
//!   whose centre is given relative to the start) and the emitted motion mode is
//!   the original's.
//! - Otherwise only the words that must change are rewritten; the N number,
//!   comments, word order, letter case and every other word stay. A rewritten
//!   axis word keeps its decimal count, at least [`RewriteOptions::min_decimals_mm`]
//!   (mm and degrees) or [`RewriteOptions::min_decimals_inch`] (G20). A word that
//!   would print the same number is kept as written. An axis that must move but has
//!   no word gets one after the block's last axis word (X Y Z A C order among the
//!   added ones).
//! - G91: every emitted value is the difference to the previously *emitted*
//!   target (the printed, rounded one, so rounding never accumulates). G20:
//!   values are converted back to inches. G53: machine coordinates, absolute.
//! - Arcs: when an arc's start (the previous emitted target) or end moves, its
//!   centre is moved to the nearest point that is equidistant from the new start
//!   and end (so the radius stays consistent) and its I/J/K (or R, same sign)
//!   words are rewritten. A split arc becomes straight pieces and its last part
//!   a `G1` (the I J K R P words are removed); pass points along the arc
//!   (`Motion::interpolate`) as `via`.
//! - Split: each intermediate target becomes a new line `G1 X… Y… Z… A… C…`
//!   (`G0` for a rapid; only the axes that move, `G53` repeated when the block
//!   has it), without an N number, with the block's line ending (`\n` when the
//!   block is the unterminated last line), written *before* the rewritten block,
//!   which then moves from the last intermediate target to the end. The first
//!   piece repeats the block's modal words (units, distance, feed mode, plane,
//!   work offset, tool length / tool-tip words with their H, M428/M429,
//!   TRAORI/TRAFOOF) so that the pieces run in the block's state, and under G94
//!   the block's F word. Under G93 every piece and the rewritten block get
//!   `F = F_block / fraction`, the fraction of the XYZ length (rotary length
//!   when the XYZ length is zero) the piece covers, so the pieces take the
//!   block's time.
//! - When the emitted motion mode differs from the block's (after a split or a
//!   straightened arc) and the block has no motion word, the block's mode word
//!   (`G2`…) is inserted after its N word.
use std::io::Write;

use crate::axes::{Axes, Axis};

use super::format::{half_ulp, push_number, round_to};
use crate::gcode::machine::interpret::{BlockEvent, Moves};
use crate::gcode::machine::modal::{
    Distance, GCode, MCode, MotionMode, Units, classify_g, classify_m,
};
use crate::gcode::machine::motion::{Feed, Motion, MotionKind};
use crate::gcode::machine::motion::{from_plane, to_plane};
use crate::gcode::syntax::block::{Block, Word};

/// Rewriter settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RewriteOptions {
    /// Least decimals of a rewritten mm (or degree) value.
    pub min_decimals_mm: u8,
    /// Least decimals of a rewritten inch value.
    pub min_decimals_inch: u8,
    /// Least decimals of a recomputed G93 F.
    pub min_decimals_feed: u8,
    /// Least significant digits of a recomputed G93 F (time is 1/F, so its
    /// relative precision is F's).
    pub min_significant_feed: u8,
    /// The dialect written (the input's: [`crate::gcode::Program::dialect`]).
    pub dialect: crate::gcode::Dialect,
    /// The machine's axis letters: only their words are rewritten or added. A
    /// word of another letter (passed through under `--lenient`) is written
    /// as it was, byte for byte. Default: every letter.
    pub axes: crate::axes::AxisSet,
}

impl Default for RewriteOptions {
    fn default() -> Self {
        RewriteOptions {
            min_decimals_mm: 4,
            min_decimals_inch: 5,
            min_decimals_feed: 4,
            min_significant_feed: 7,
            dialect: crate::gcode::Dialect::LinuxCnc,
            axes: crate::axes::AxisSet::ALL,
        }
    }
}

/// What to emit for a block.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Target<'a> {
    /// The block's programmed target.
    Same,
    /// A new absolute end target (block's frame, mm and degrees).
    Move(Axes),
    /// Intermediate absolute targets, then the end.
    Split {
        /// The intermediate targets, in order (block's frame, mm and degrees).
        via: &'a [Axes],
        /// The end target (block's frame, mm and degrees).
        end: Axes,
    },
}

/// What [`Rewriter::emit`] wrote for a block.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Emitted {
    /// The block's line differs from the input.
    pub rewritten: bool,
    /// New lines written before it (split pieces).
    pub pieces: usize,
}

/// Why a program could not be rewritten.
#[derive(Debug, thiserror::Error)]
pub enum RewriteError {
    /// A new target was given for a block that does not move.
    #[error("line {line}: only a motion block can be given a new target")]
    NotAMotion {
        /// 1-based line of the block.
        line: usize,
    },
    /// A new target (or an intermediate one) is not finite.
    #[error("line {line}: the new target is not finite")]
    NonFinite {
        /// 1-based line of the block.
        line: usize,
    },
    /// A step of a canned cycle or spline that a flat program cannot say
    /// (e.g. G87's spindle orientation).
    #[error("line {line}: a flat program cannot say {what}; expand this canned cycle by hand")]
    CannotFlatten {
        /// 1-based line of the block.
        line: usize,
        /// What cannot be said, in words.
        what: &'static str,
    },
    /// Writing the output failed.
    #[error("cannot write the program: {0}")]
    Io(#[from] std::io::Error),
    /// Reading or interpreting the input program failed.
    #[error(transparent)]
    Input(#[from] crate::gcode::error::GcodeError),
}

/// Totals of a [`rewrite_stream`] run.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RewriteStats {
    /// Lines read.
    pub blocks: usize,
    /// Motion blocks.
    pub motions: usize,
    /// Blocks whose line changed.
    pub rewritten: usize,
    /// New lines added by splits (and the moves of canned cycles).
    pub pieces: usize,
    /// Blocks written flat: produced by parameters, loops or subroutines
    /// (values substituted) or canned cycles (expanded).
    pub flat: usize,
}

/// Run and rewrite a whole program, streaming. For every motion block `plan`
/// gets the block, its event and an empty via buffer; it returns the new
/// absolute end (machine coordinates; `None`: keep the programmed target) and
/// may push intermediate targets into the buffer (a split). Blocks that the
/// language layer flattened are written flat (their values substituted), canned
/// cycles as their moves ([`Rewriter::emit_cycle`], at their programmed
/// targets). Input errors are located (file, line, column).
pub fn rewrite_stream(
    run: crate::gcode::execution::Execution,
    out: &mut dyn Write,
    options: RewriteOptions,
    mut plan: impl FnMut(&Block, &BlockEvent, &mut Vec<Axes>) -> Option<Axes>,
) -> Result<RewriteStats, RewriteError> {
    let mut run = run;
    let interpret = run.interpreter().options();
    let options = RewriteOptions {
        dialect: run.dialect().dialect,
        axes: interpret.axes,
        ..options
    };
    let mut rewriter = Rewriter::new(options, interpret.initial_position);
    let mut via = Vec::new();
    let mut stats = RewriteStats::default();
    while let Some(step) = run.next() {
        let (block, event, executed) = step?;
        stats.blocks += 1;
        if !executed.literal || (written_flat(event) && !event.skipped) {
            stats.flat += 1;
        }
        via.clear();
        let target = match event.motion().filter(|_| !event.skipped) {
            Some(_) => {
                stats.motions += 1;
                match plan(block, event, &mut via) {
                    None => Target::Same,
                    Some(end) if via.is_empty() => Target::Move(end),
                    Some(end) => Target::Split { via: &via, end },
                }
            }
            None => Target::Same,
        };
        let emitted = rewriter.emit(block, event, target, out)?;
        stats.rewritten += emitted.rewritten as usize;
        stats.pieces += emitted.pieces;
    }
    Ok(stats)
}

/// Canned cycles and splines are written flat, move by move.
fn written_flat(event: &BlockEvent) -> bool {
    matches!(event.moves, Moves::Cycle { .. }) || event.spline.is_some()
}

/// One replacement in the raw line: `raw[start..end]` → `text[from..to]`.
#[derive(Clone, Copy, Debug)]
struct Edit {
    start: usize,
    end: usize,
    from: usize,
    to: usize,
}

/// Emits blocks; keeps the position and motion mode of the program written so far.
#[derive(Clone, Debug)]
pub struct Rewriter {
    pub(super) options: RewriteOptions,
    pub(super) emitted: Axes,
    pub(super) emitted_motion: MotionMode,
    /// Motion mode of the original program after the last block.
    pub(super) original_motion: MotionMode,
    pub(super) decimals: [u8; crate::axes::AXIS_COUNT],
    edits: Vec<Edit>,
    pub(super) text: String,
    line: Vec<u8>,
    /// Scratch: split targets in program coordinates.
    via_program: Vec<Axes>,
    /// The writer of Heidenhain programs (`options.dialect`).
    pub(super) klartext: crate::gcode::heidenhain::write::KlartextWriter,
    /// Tool axis ↔ rotary joints: writes a changed orientation vector back
    /// as a vector ([`Rewriter::with_orientation`]).
    orientation: Option<std::sync::Arc<dyn crate::gcode::OrientationSolver>>,
}

impl Rewriter {
    /// `initial_position` must be the interpreter's (`InterpretOptions::initial_position`).
    pub fn new(options: RewriteOptions, initial_position: Axes) -> Self {
        Rewriter {
            options,
            emitted: initial_position,
            emitted_motion: MotionMode::None,
            original_motion: MotionMode::None,
            decimals: [0; crate::axes::AXIS_COUNT],
            edits: Vec::new(),
            text: String::new(),
            line: Vec::new(),
            via_program: Vec::new(),
            klartext: Default::default(),
            orientation: None,
        }
    }

    /// The machine's tool axis ↔ rotary joints (the program's
    /// `ProgramSetup::orientation`): a block whose orientation is a vector
    /// (SINUMERIK `A3= B3= C3=`, Klartext `LN … TX TY TZ`) and whose rotary
    /// joints change is written with the nominal tool axis of its new
    /// joints as its vector.
    pub fn with_orientation(
        mut self,
        orientation: Option<std::sync::Arc<dyn crate::gcode::OrientationSolver>>,
    ) -> Self {
        self.klartext.orientation.clone_from(&orientation);
        self.orientation = orientation;
        self
    }

    /// Emit one block (see the module docs for the contract); says what was written.
    pub fn emit(
        &mut self,
        block: &Block,
        event: &BlockEvent,
        target: Target<'_>,
        out: &mut dyn Write,
    ) -> Result<Emitted, RewriteError> {
        if self.options.dialect == crate::gcode::Dialect::Heidenhain {
            return self.klartext.emit(&self.options, block, event, target, out);
        }
        if event.skipped {
            // Not executed (a subroutine definition passed over, a line after
            // the end, a deleted or unparsed line): as written, and the
            // emitted program's state is unchanged.
            if target != Target::Same {
                return Err(RewriteError::NotAMotion { line: block.line });
            }
            block.write_raw(out)?;
            return Ok(Emitted::default());
        }
        self.note_decimals(block);
        if written_flat(event) && target == Target::Same {
            // Canned cycles and splines are always written flat (see
            // `emit_flat`).
            let ends: Vec<Axes> = event.expanded().iter().map(|m| m.end).collect();
            return self.emit_flat(block, event, &ends, out);
        }
        let Some(motion) = event.motion().filter(|_| !event.skipped) else {
            if target != Target::Same {
                return Err(RewriteError::NotAMotion { line: block.line });
            }
            if has_motion_word(block) {
                self.emitted_motion = event.modal.motion;
            }
            // G28/G30 (written unchanged) end at stored positions: the axes
            // they moved stand where the original program's stand.
            if let Moves::Home(_) = event.moves {
                let named: Vec<Axis> = Axis::ALL
                    .into_iter()
                    .filter(|a| block.word(a.letter() as u8).is_some())
                    .collect();
                for axis in Axis::ALL {
                    if named.is_empty() || named.contains(&axis) {
                        self.emitted.set(axis, event.position.get(axis));
                    }
                }
            }
            self.original_motion = event.modal.motion;
            if offset_setting(block) {
                // G92 / G10 L20 make the current position read as the words:
                // where the emitted program stands elsewhere than the
                // original, shift the words by that drift so that the offset
                // set is the original's (else every later move would carry
                // this block's correction on top of its own).
                self.edits.clear();
                self.text.clear();
                let o = &event.origin;
                let (emitted, nominal) = (o.to_program(&self.emitted), o.to_program(&event.start));
                let ctx = Context::new(block, event);
                for axis in self.options.axes.iter() {
                    let Some(w) = block
                        .words
                        .iter()
                        .rev()
                        .find(|w| w.letter == axis.letter() as u8)
                    else {
                        continue;
                    };
                    let drift = (emitted.get(axis) - nominal.get(axis)) / ctx.unit(axis);
                    let dec = ctx.decimals(axis, w.decimals, &self.options);
                    if drift.abs() > half_ulp(dec) {
                        self.replace_number(block, w, w.value + drift, dec);
                    }
                }
                let rewritten = self.write_edited(block, out)?;
                return Ok(Emitted {
                    rewritten,
                    pieces: 0,
                });
            }
            block.write_raw(out)?;
            return Ok(Emitted::default());
        };
        let (via, end): (&[Axes], Axes) = match target {
            Target::Same => (&[], motion.end),
            Target::Move(e) => (&[], e),
            Target::Split { via, end } => (via, end),
        };
        if !end.is_finite() || !via.iter().all(Axes::is_finite) {
            return Err(RewriteError::NonFinite { line: block.line });
        }
        // Everything below works in the block's program coordinates (its
        // words' coordinates): targets and positions come in machine
        // coordinates and go back at the end.
        let origin = &event.origin;
        let mut via_program = std::mem::take(&mut self.via_program);
        via_program.clear();
        via_program.extend(via.iter().map(|v| origin.to_program(v)));
        let result = self.emit_motion(
            block,
            event,
            motion,
            &via_program,
            origin.to_program(&end),
            out,
        );
        self.via_program = via_program;
        result
    }

    /// [`Rewriter::emit`] of a motion block, in the block's program coordinates.
    fn emit_motion(
        &mut self,
        block: &Block,
        event: &BlockEvent,
        motion: &Motion,
        via: &[Axes],
        end: Axes,
        out: &mut dyn Write,
    ) -> Result<Emitted, RewriteError> {
        let origin = &event.origin;
        let motion = &Motion {
            start: origin.to_program(&motion.start),
            end: origin.to_program(&motion.end),
            kind: match motion.kind {
                MotionKind::Arc {
                    clockwise,
                    centre,
                    plane,
                    turns,
                } => MotionKind::Arc {
                    clockwise,
                    centre: origin.xyz_to_program(centre),
                    plane,
                    turns,
                },
                k => k,
            },
            ..*motion
        };
        self.emitted = origin.to_program(&self.emitted);
        let ctx = Context::new(block, event);
        self.edits.clear();
        self.text.clear();

        // Split pieces, written before the block.
        let mut feed_scale = 1.0;
        let mut pieces = 0;
        if !via.is_empty() {
            let fractions = fractions(self.emitted, via, end);
            for (k, v) in via.iter().enumerate() {
                if self.piece(block, &ctx, pieces == 0, *v, fractions[k], out)? {
                    pieces += 1;
                }
            }
            feed_scale = 1.0 / fractions[via.len()].max(1e-9);
        }

        let start_moved = !same_point(&self.emitted, &motion.start, &ctx);
        let end_moved = !same_point(&end, &motion.end, &ctx);
        let straighten = matches!(motion.kind, MotionKind::Arc { .. }) && !via.is_empty();
        let mut new_emitted = self.emitted;
        // Polar words (`@`, `^`) give X Y from the current point: a block
        // whose start or end moves says its X Y instead; one that does not
        // move keeps them (its X Y are the programmed ones).
        let polar = block.words.iter().any(|w| matches!(w.letter, b'@' | b'^'));
        let cartesian = (start_moved || end_moved) && polar;
        if cartesian {
            for w in block
                .words
                .iter()
                .filter(|w| matches!(w.letter, b'@' | b'^'))
            {
                self.remove_word(block, w);
            }
        }

        // An orientation given as a vector: the rotary joints are said by
        // its words (see `orientation_vector`).
        let vector = self.orientation_vector(block, event, end);

        // Axis words.
        let mut last_axis_end = None;
        let mut appended: [Option<f64>; crate::axes::AXIS_COUNT] = [None; crate::axes::AXIS_COUNT];
        for axis in self.options.axes.iter() {
            let i = axis as usize;
            if vector && axis.is_rotary() {
                new_emitted.set(axis, end.get(axis));
                continue;
            }
            let unit = ctx.unit(axis);
            let base = if ctx.incremental {
                self.emitted.get(axis)
            } else {
                0.0
            };
            let needed = (end.get(axis) - base) / unit;
            let word = block
                .words
                .iter()
                .rev()
                .find(|w| w.letter == axis.letter() as u8);
            match word {
                Some(w) => {
                    last_axis_end = Some(last_axis_end.unwrap_or(0).max(w.end));
                    let dec = ctx.decimals(axis, w.decimals, &self.options);
                    if (needed - w.value).abs() <= half_ulp(dec) {
                        new_emitted.set(axis, base + w.value * unit);
                    } else {
                        let printed = self.replace_number(block, w, needed, dec);
                        new_emitted.set(axis, base + printed * unit);
                    }
                }
                None => {
                    let implied = if ctx.incremental {
                        0.0
                    } else {
                        self.emitted.get(axis) / unit
                    };
                    let dec = ctx.decimals(axis, self.decimals[i], &self.options);
                    let polar_axis = polar && matches!(axis, Axis::X | Axis::Y);
                    if polar_axis && !cartesian {
                        new_emitted.set(axis, end.get(axis));
                    } else if (needed - implied).abs() > half_ulp(dec) || polar_axis {
                        let printed = round_to(needed, dec);
                        appended[i] = Some(printed);
                        new_emitted.set(axis, base + printed * unit);
                    }
                }
            }
        }
        if appended.iter().any(Option::is_some) {
            let at = last_axis_end
                .or_else(|| block.words.last().map(|w| w.end))
                .unwrap_or(block.raw.len());
            let lower = ctx.lowercase;
            let from = self.text.len();
            for axis in Axis::ALL {
                if let Some(v) = appended[axis as usize] {
                    let letter = if lower {
                        axis.letter().to_ascii_lowercase()
                    } else {
                        axis.letter()
                    };
                    let dec = ctx.decimals(axis, self.decimals[axis as usize], &self.options);
                    self.text.push(' ');
                    self.text.push(letter);
                    push_number(&mut self.text, v, dec);
                }
            }
            self.record(from, at, at);
        }

        // Arc words.
        if let MotionKind::Arc { centre, plane, .. } = motion.kind {
            if straighten {
                self.straighten(block, &ctx);
            } else if start_moved || end_moved {
                let nominal = [motion.start.xyz(), motion.end.xyz()];
                self.move_arc_centre(block, &ctx, new_emitted, centre, nominal, plane);
            }
        }

        // G93 feed of the block's last part.
        if feed_scale != 1.0 {
            if let Feed::InverseTime(f) = motion.feed {
                let new_f = f * feed_scale;
                match block.words.iter().rev().find(|w| w.letter == b'F') {
                    Some(w) => {
                        let dec = feed_decimals(new_f, w.decimals, &self.options);
                        self.replace_number(block, w, new_f, dec);
                    }
                    None => {
                        let at = block.words.last().map(|w| w.end).unwrap_or(0);
                        let from = self.text.len();
                        self.text.push_str(if ctx.lowercase { " f" } else { " F" });
                        let dec = feed_decimals(new_f, 0, &self.options);
                        push_number(&mut self.text, new_f, dec);
                        self.record(from, at, at);
                    }
                }
            }
        }

        // Motion mode of the emitted program.
        let mode = if straighten {
            MotionMode::Linear
        } else {
            event.modal.motion
        };
        if !has_motion_word(block) && self.emitted_motion != self.original_motion && !straighten {
            let at = block
                .words
                .first()
                .filter(|w| w.letter == b'N')
                .map(|w| w.end)
                .unwrap_or_else(|| block.words.first().map(|w| w.start).unwrap_or(0));
            let from = self.text.len();
            let word = event.modal.motion.word();
            if at == 0 || block.words.first().is_some_and(|w| w.start == at) {
                self.text.push_str(word);
                self.text.push(' ');
            } else {
                self.text.push(' ');
                self.text.push_str(word);
            }
            if ctx.lowercase {
                self.text[from..].make_ascii_lowercase();
            }
            self.record(from, at, at);
        }
        self.emitted_motion = mode;
        self.original_motion = event.modal.motion;
        self.emitted = origin.to_machine(&new_emitted);
        let rewritten = self.write_edited(block, out)?;
        Ok(Emitted { rewritten, pieces })
    }

    /// A block whose orientation is a vector (SINUMERIK `A3= B3= C3=`,
    /// [`crate::gcode::ORIENTATION_VECTOR_LETTERS`]; angles `A2= B2=` are
    /// rewritten likewise, `C2` kept): when the target's
    /// rotary joints differ from the programmed ones, the vector words are
    /// rewritten to the nominal tool axis of the target's joints (the
    /// machine's chain, [`Rewriter::with_orientation`]), in the block's frame,
    /// at least 7 decimals; a component the block does not write is added
    /// after its last vector word. Returns whether the block is such a block
    /// (its rotary joints are then said by the vector, not by axis words).
    /// Without a solver the vector stays as written.
    fn orientation_vector(&mut self, block: &Block, event: &BlockEvent, end: Axes) -> bool {
        use crate::gcode::sinumerik::{ORIENTATION_ANGLE_LETTERS, ORIENTATION_RPY_LETTERS};
        // Only a SINUMERIK block has orientation words (LinuxCNC's path
        // pays one comparison).
        if self.options.dialect != crate::gcode::Dialect::Sinumerik {
            return false;
        }
        // The vector's components; Euler angles; RPY angles.
        let sets = [
            (crate::gcode::ORIENTATION_VECTOR_LETTERS, None),
            (ORIENTATION_ANGLE_LETTERS, Some(false)),
            (ORIENTATION_RPY_LETTERS, Some(true)),
        ];
        let Some((words, angles)) = sets.iter().find_map(|(letters, angles)| {
            let words = letters.map(|l| block.words.iter().find(|w| w.letter == l));
            words
                .iter()
                .any(Option::is_some)
                .then_some((words, *angles))
        }) else {
            return false;
        };
        let Some(solver) = self.orientation.clone() else {
            return true;
        };
        let changed = self.options.axes.iter().filter(|a| a.is_rotary()).any(|a| {
            block
                .words
                .iter()
                .rev()
                .find(|w| w.letter == a.letter() as u8)
                .is_some_and(|w| (w.value - end.get(a)).abs() > half_ulp(4))
        });
        if !changed {
            return true;
        }
        let origin = &event.origin;
        let axis = solver.axis_of(&origin.to_machine(&end));
        let mut v = match &origin.frame {
            Some(f) => {
                let m = &f.inverse;
                [0, 1, 2].map(|i| (0..3).map(|k| m[i][k] * axis[k]).sum::<f64>())
            }
            None => axis,
        };
        let norm = v.iter().map(|c| c * c).sum::<f64>().sqrt();
        if norm > 0.0 && norm.is_finite() {
            v = v.map(|c| c / norm);
        }
        let (values, names, least) = match angles {
            None => (v, [" A3=", " B3=", " C3="], 7),
            Some(rpy) => {
                let c = words[2].map_or(0.0, |w| w.value);
                (
                    crate::gcode::sinumerik::direction_angles(rpy, v, c),
                    [" A2=", " B2=", " C2="],
                    6,
                )
            }
        };
        let last = words.iter().flatten().map(|w| w.end).max().unwrap_or(0);
        let mut added = String::new();
        for (k, w) in words.iter().enumerate() {
            // An angle C2 is kept: it does not turn the direction
            // (Euler) or it is the one the others were solved for (RPY).
            if angles.is_some() && k == 2 {
                continue;
            }
            match w {
                Some(w) => {
                    let dec = w.decimals.max(least);
                    if (values[k] - w.value).abs() > half_ulp(dec) {
                        self.replace_number(block, w, values[k], dec);
                    }
                }
                None if values[k].abs() > half_ulp(least) => {
                    added.push_str(names[k]);
                    push_number(&mut added, values[k], least);
                }
                None => {}
            }
        }
        if !added.is_empty() {
            let from = self.text.len();
            self.text.push_str(&added);
            self.record(from, last, last);
        }
        true
    }

    /// Record that `raw[start..end]` becomes the text written since `from`.
    pub(super) fn record(&mut self, from: usize, start: usize, end: usize) {
        let to = self.text.len();
        self.edits.push(Edit {
            start,
            end,
            from,
            to,
        });
    }

    /// Replace a word's number; returns the printed value.
    fn replace_number(&mut self, block: &Block, w: &Word, value: f64, dec: u8) -> f64 {
        let from = self.text.len();
        match address_with_equals(block, w) {
            // A dialect's `X=R1+2`, `CR=5`: the address as written, then the number.
            Some(prefix) => self.text.push_str(prefix),
            None => {
                let letter = block.raw.get(w.start).copied().unwrap_or(w.letter) as char;
                self.text.push(letter);
            }
        }
        let printed = push_number(&mut self.text, value, dec);
        self.record(from, w.start, w.end);
        printed
    }

    /// Remove a word and the white space before it.
    /// Every axis letter's largest number of decimals written so far.
    pub(super) fn note_decimals(&mut self, block: &Block) {
        for w in &block.words {
            if let Some(axis) = Axis::from_letter(w.letter as char) {
                let i = axis as usize;
                self.decimals[i] = self.decimals[i].max(w.decimals);
            }
        }
    }

    /// Start a new edit of `block` with the words `strip` selects removed.
    pub(super) fn strip_words(&mut self, block: &Block, strip: impl Fn(&Word) -> bool) {
        self.edits.clear();
        self.text.clear();
        for w in &block.words {
            if strip(w) {
                self.remove_word(block, w);
            }
        }
    }

    fn remove_word(&mut self, block: &Block, w: &Word) {
        let mut start = w.start;
        while start > 0 && matches!(block.raw[start - 1], b' ' | b'\t') {
            start -= 1;
        }
        let at = self.text.len();
        self.record(at, start, w.end);
    }

    /// A split arc's last part becomes a G1: G2/G3 → G1, I J K R P removed.
    fn straighten(&mut self, block: &Block, ctx: &Context) {
        let mut has_word = false;
        for w in &block.words {
            match w.letter {
                b'G' if matches!(
                    w.code10().map(classify_g),
                    Some(GCode::Motion(MotionMode::ArcCw | MotionMode::ArcCcw))
                ) =>
                {
                    has_word = true;
                    let from = self.text.len();
                    self.text.push_str(if ctx.lowercase { "g1" } else { "G1" });
                    self.record(from, w.start, w.end);
                }
                b'I' | b'J' | b'K' | b'R' | b'P' => self.remove_word(block, w),
                _ => {}
            }
        }
        if !has_word {
            let at = block
                .words
                .first()
                .filter(|w| w.letter == b'N')
                .map(|w| w.end);
            let from = self.text.len();
            match at {
                Some(_) => self.text.push_str(" G1"),
                None => self.text.push_str("G1 "),
            }
            if ctx.lowercase {
                self.text[from..].make_ascii_lowercase();
            }
            let at = at.unwrap_or_else(|| block.words.first().map(|w| w.start).unwrap_or(0));
            self.record(from, at, at);
        }
    }

    /// Keep an arc valid after its start or end moved: the centre moved by
    /// the mean of the two ends' corrections (a correction that is the same
    /// at both ends moves the whole circle), then to the nearest point
    /// equidistant from both ends; rewrite I/J/K or R. The centre projected
    /// without the move would leave the arc's middle off by the corrections'
    /// component across the chord times 1 − cos(sweep/2): 0.8 µm on a
    /// quarter circle whose ends move 2.8 µm across its chord, whatever its
    /// radius (docs/extensions.md, "Arc centres").
    fn move_arc_centre(
        &mut self,
        block: &Block,
        ctx: &Context,
        new_end: Axes,
        centre: [f64; 3],
        nominal: [[f64; 3]; 2],
        plane: crate::gcode::machine::motion::Plane,
    ) {
        let s = to_plane(plane, self.emitted.xyz());
        let e = to_plane(plane, new_end.xyz());
        let (s0, e0) = (to_plane(plane, nominal[0]), to_plane(plane, nominal[1]));
        let c = to_plane(plane, centre);
        let c = [
            c[0] + 0.5 * ((s[0] - s0[0]) + (e[0] - e0[0])),
            c[1] + 0.5 * ((s[1] - s0[1]) + (e[1] - e0[1])),
            c[2],
        ];
        let (mx, my) = ((s[0] + e[0]) / 2.0, (s[1] + e[1]) / 2.0);
        let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
        let d = dx.hypot(dy);
        let projected = if d > 1e-12 {
            let (nx, ny) = (-dy / d, dx / d);
            let t = (c[0] - mx) * nx + (c[1] - my) * ny;
            [mx + t * nx, my + t * ny, c[2]]
        } else {
            c
        };
        // A (nearly) full circle: start and end are the same point up to the
        // corrections, the chord's direction is noise and the projection could
        // move the centre by up to the radius (found by fuzzing: `G3 X10 Y0 Z-5
        // I-5 J0 P2` came out with its centre 3.5 mm away). Keep the centre:
        // the radii then differ by at most the chord, µm, far inside LinuxCNC's
        // arc tolerance.
        let shift = (projected[0] - c[0]).hypot(projected[1] - c[1]);
        let new_c = if shift > d.max(1e-3) { c } else { projected };
        let unit = ctx.scale;
        if let Some(w) = block.words.iter().rev().find(|w| w.letter == b'R') {
            let r = (s[0] - new_c[0]).hypot(s[1] - new_c[1]) * w.value.signum() / unit;
            let dec = w.decimals.max(ctx.min_linear(&self.options));
            if (r - w.value).abs() > half_ulp(dec) {
                self.replace_number(block, w, r, dec);
            }
            return;
        }
        let abs_c = from_plane(plane, new_c);
        let start = self.emitted.xyz();
        let letters: [(u8, usize); 2] = match plane {
            crate::gcode::machine::motion::Plane::XY => [(b'I', 0), (b'J', 1)],
            crate::gcode::machine::motion::Plane::ZX => [(b'I', 0), (b'K', 2)],
            crate::gcode::machine::motion::Plane::YZ => [(b'J', 1), (b'K', 2)],
        };
        let mut missing = String::new();
        for (letter, n) in letters {
            let value = if ctx.arc_absolute {
                abs_c[n] / unit
            } else {
                (abs_c[n] - start[n]) / unit
            };
            match block.words.iter().rev().find(|w| w.letter == letter) {
                Some(w) => {
                    let dec = w.decimals.max(ctx.min_linear(&self.options));
                    if (value - w.value).abs() > half_ulp(dec) {
                        self.replace_number(block, w, value, dec);
                    }
                }
                None => {
                    let dec = ctx.min_linear(&self.options);
                    if value.abs() > half_ulp(dec) {
                        missing.push(' ');
                        missing.push(if ctx.lowercase {
                            letter.to_ascii_lowercase() as char
                        } else {
                            letter as char
                        });
                        push_number(&mut missing, value, dec);
                    }
                }
            }
        }
        if !missing.is_empty() {
            let at = block
                .words
                .iter()
                .filter(|w| {
                    matches!(w.letter, b'I' | b'J' | b'K')
                        || Axis::from_letter(w.letter as char).is_some()
                })
                .map(|w| w.end)
                .max()
                .or_else(|| block.words.last().map(|w| w.end))
                .unwrap_or(0);
            let from = self.text.len();
            self.text.push_str(&missing);
            self.record(from, at, at);
        }
    }

    /// Write one split piece; `false` when it has zero length (not written).
    fn piece(
        &mut self,
        block: &Block,
        ctx: &Context,
        first: bool,
        target: Axes,
        fraction: f64,
        out: &mut dyn Write,
    ) -> Result<bool, RewriteError> {
        let mut line = String::new();
        if first {
            for span in modal_word_spans(block) {
                line.push_str(&String::from_utf8_lossy(&block.raw[span.0..span.1]));
                line.push(' ');
            }
        }
        let mode = if ctx.rapid {
            MotionMode::Rapid
        } else {
            MotionMode::Linear
        };
        line.push_str(mode.word());
        if ctx.g53 {
            line.push_str(" G53");
        }
        let mut moved = false;
        let mut new_emitted = self.emitted;
        for axis in self.options.axes.iter() {
            let unit = ctx.unit(axis);
            let base = if ctx.incremental {
                self.emitted.get(axis)
            } else {
                0.0
            };
            let dec = ctx.decimals(axis, self.decimals[axis as usize], &self.options);
            let needed = (target.get(axis) - base) / unit;
            let implied = if ctx.incremental {
                0.0
            } else {
                self.emitted.get(axis) / unit
            };
            if (needed - implied).abs() > half_ulp(dec) {
                line.push(' ');
                line.push(axis.letter());
                let printed = push_number(&mut line, needed, dec);
                new_emitted.set(axis, base + printed * unit);
                moved = true;
            }
        }
        if !moved {
            return Ok(false);
        }
        if ctx.inverse_time {
            if let Some(f) = ctx.feed {
                line.push_str(" F");
                let f = f / fraction.max(1e-12);
                push_number(
                    &mut line,
                    f,
                    feed_decimals(f, ctx.feed_decimals, &self.options),
                );
            }
        } else if first {
            if let Some(w) = block.words.iter().rev().find(|w| w.letter == b'F') {
                line.push(' ');
                line.push_str(&String::from_utf8_lossy(&block.raw[w.start..w.end]));
            }
        }
        if ctx.lowercase {
            line.make_ascii_lowercase();
        }
        out.write_all(line.as_bytes())?;
        out.write_all(match block.ending {
            crate::gcode::syntax::block::LineEnding::CrLf => b"\r\n",
            _ => b"\n",
        })?;
        self.emitted = new_emitted;
        self.emitted_motion = mode;
        Ok(true)
    }

    /// Write the block with its edits; `true` when it differs from the input.
    pub(super) fn write_edited(
        &mut self,
        block: &Block,
        out: &mut dyn Write,
    ) -> Result<bool, RewriteError> {
        if self.edits.is_empty() {
            block.write_raw(out)?;
            return Ok(false);
        }
        self.edits.sort_by_key(|e| (e.start, e.end));
        self.line.clear();
        let mut pos = 0;
        for e in &self.edits {
            if e.start < pos {
                continue;
            }
            self.line.extend_from_slice(&block.raw[pos..e.start]);
            self.line
                .extend_from_slice(&self.text.as_bytes()[e.from..e.to]);
            pos = e.end;
        }
        self.line.extend_from_slice(&block.raw[pos..]);
        // A line that started with a word that was removed (`@5 ^10` written
        // as X Y) starts where its first kept word does.
        if !block.raw.first().is_some_and(|b| b.is_ascii_whitespace()) {
            let blank = self
                .line
                .iter()
                .take_while(|b| matches!(b, b' ' | b'\t'))
                .count();
            self.line.drain(..blank);
        }
        self.line.extend_from_slice(block.ending.as_bytes());
        out.write_all(&self.line)?;
        let body = &self.line[..self.line.len() - block.ending.as_bytes().len()];
        Ok(body != &block.raw[..])
    }
}

/// What the rewriter needs to know about a motion block.
pub(super) struct Context {
    scale: f64,
    inch: bool,
    pub(super) incremental: bool,
    arc_absolute: bool,
    g53: bool,
    rapid: bool,
    inverse_time: bool,
    /// The block's F under G93 (1/min).
    feed: Option<f64>,
    pub(super) feed_decimals: u8,
    pub(super) lowercase: bool,
}

impl Context {
    pub(super) fn new(block: &Block, event: &BlockEvent) -> Self {
        let motion = event.motion();
        let g53 = motion.is_some_and(|m| m.machine_coordinates);
        let (rapid, inverse_time, feed) = match motion.map(|m| m.feed) {
            Some(Feed::Rapid) => (true, false, None),
            Some(Feed::InverseTime(f)) => (false, true, Some(f)),
            _ => (false, false, None),
        };
        let lowercase = block
            .words
            .iter()
            .find(|w| w.letter != b'N')
            .and_then(|w| block.raw.get(w.start))
            .is_some_and(|b| b.is_ascii_lowercase());
        Context {
            scale: event.modal.units.scale(),
            inch: event.modal.units == Units::Inch,
            incremental: event.modal.distance == Distance::Incremental && !g53,
            arc_absolute: event.modal.arc_distance == Distance::Absolute,
            g53,
            rapid,
            inverse_time,
            feed,
            feed_decimals: block
                .words
                .iter()
                .rev()
                .find(|w| w.letter == b'F')
                .map(|w| w.decimals)
                .unwrap_or(0),
            lowercase,
        }
    }

    pub(super) fn unit(&self, axis: Axis) -> f64 {
        if axis.is_rotary() { 1.0 } else { self.scale }
    }

    fn min_linear(&self, o: &RewriteOptions) -> u8 {
        if self.inch {
            o.min_decimals_inch
        } else {
            o.min_decimals_mm
        }
    }

    pub(super) fn decimals(&self, axis: Axis, written: u8, o: &RewriteOptions) -> u8 {
        let min = if axis.is_rotary() {
            o.min_decimals_mm
        } else {
            self.min_linear(o)
        };
        written.max(min).min(12)
    }
}

/// Whether two points print the same at the rewriter's resolution (mm/deg).
/// The line ending `block` was written with.
pub(super) fn line_ending(block: &Block) -> &'static [u8] {
    match block.ending {
        crate::gcode::syntax::block::LineEnding::CrLf => b"\r\n",
        _ => b"\n",
    }
}

fn same_point(a: &Axes, b: &Axes, ctx: &Context) -> bool {
    let tol = if ctx.inch { 0.5e-5 * 25.4 } else { 0.5e-4 };
    Axis::ALL
        .iter()
        .all(|&ax| (a.get(ax) - b.get(ax)).abs() <= tol)
}

/// Fraction of the total length each segment of start → via… → end covers
/// (XYZ length, rotary length when the XYZ length is zero, equal parts when both are).
fn fractions(start: Axes, via: &[Axes], end: Axes) -> Vec<f64> {
    let mut points = Vec::with_capacity(via.len() + 2);
    points.push(start);
    points.extend_from_slice(via);
    points.push(end);
    let xyz: Vec<f64> = points
        .windows(2)
        .map(|p| p[0].xyz_distance(&p[1]))
        .collect();
    let rot: Vec<f64> = points
        .windows(2)
        .map(|p| p[0].rotary_distance(&p[1]))
        .collect();
    let total_xyz: f64 = xyz.iter().sum();
    let total_rot: f64 = rot.iter().sum();
    let n = xyz.len() as f64;
    if total_xyz > 1e-9 {
        xyz.iter().map(|l| l / total_xyz).collect()
    } else if total_rot > 1e-9 {
        rot.iter().map(|l| l / total_rot).collect()
    } else {
        vec![1.0 / n; xyz.len()]
    }
}

/// G92 or G10 L20: a block that sets an offset from the current position.
fn offset_setting(block: &Block) -> bool {
    let mut g92 = false;
    let mut g10 = false;
    let mut l20 = false;
    for w in &block.words {
        match (w.letter, w.code10()) {
            (b'G', Some(920)) => g92 = true,
            (b'G', Some(100)) => g10 = true,
            (b'L', Some(200)) => l20 = true,
            _ => {}
        }
    }
    g92 || (g10 && l20)
}

fn has_motion_word(block: &Block) -> bool {
    block.words.iter().any(|w| {
        w.letter == b'G'
            && matches!(
                w.code10().map(classify_g),
                Some(GCode::Motion(_) | GCode::CancelMotion)
            )
    })
}

/// Byte spans of the block's modal words a split piece must repeat.
fn modal_word_spans(block: &Block) -> Vec<(usize, usize)> {
    let mut spans = Vec::new();
    let mut tool_length = false;
    for w in &block.words {
        match w.letter {
            b'G' => match w.code10().map(classify_g) {
                Some(
                    GCode::Plane(_)
                    | GCode::Units(_)
                    | GCode::Distance(_)
                    | GCode::ArcDistance(_)
                    | GCode::FeedMode(_)
                    | GCode::CoordSystem(_)
                    | GCode::ToolLengthOff,
                ) => spans.push((w.start, w.end)),
                Some(GCode::ToolLength | GCode::ToolTip) => {
                    tool_length = true;
                    spans.push((w.start, w.end));
                }
                _ => {}
            },
            b'M' => {
                if matches!(
                    w.code10().map(classify_m),
                    Some(MCode::ToolTipOn | MCode::ToolTipOff)
                ) {
                    spans.push((w.start, w.end));
                }
            }
            _ => {}
        }
    }
    if tool_length {
        if let Some(h) = block.word(b'H') {
            spans.push((h.start, h.end));
        }
    }
    for k in &block.keywords {
        spans.push((k.start, k.end));
    }
    spans.sort_unstable();
    spans
}

/// Decimals of a recomputed F: the word's, at least `min_decimals_feed`, and
/// enough for `min_significant_feed` significant digits.
pub(super) fn feed_decimals(f: f64, written: u8, o: &RewriteOptions) -> u8 {
    let int_digits = if f.abs() >= 1.0 {
        f.abs().log10().floor() as i32 + 1
    } else {
        0
    };
    let for_significance = (o.min_significant_feed as i32 - int_digits).clamp(0, 12) as u8;
    written
        .max(o.min_decimals_feed)
        .max(for_significance)
        .min(12)
}

/// The address of a dialect's word written with `=` (`X=IC(5)`, `CR=R1`):
/// its text up to and including the `=`; `None` for a letter and a number
/// (every LinuxCNC word, whose computed values are bracketed).
fn address_with_equals<'a>(block: &'a Block, w: &Word) -> Option<&'a str> {
    let text = block.raw.get(w.start..w.end)?;
    let k = text.iter().position(|&b| b == b'=')?;
    text[..k]
        .iter()
        .all(|b| b.is_ascii_alphanumeric() || *b == b' ')
        .then(|| std::str::from_utf8(&text[..=k]).ok())
        .flatten()
}
