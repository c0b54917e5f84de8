//! The flat writer: a canned cycle or a spline written move by move.
//!
//! A block written flat becomes its own line without the words of the cycle
//! or curve (its other words and comments keep their effect) and a comment
//! that names what was expanded, then one explicit line a step, in absolute
//! coordinates (`G90` … `G91` around them under G91). Cycles and splines share
//! this; they differ in the words they strip, the comment, and how a move is
//! written ([`MoveStyle`]).
use std::io::Write;

use super::format::push_number;
use super::rewrite::{Context, Emitted, RewriteError, Rewriter, feed_decimals, line_ending};
use crate::axes::{Axes, Axis};
use crate::gcode::machine::cycles::{CycleCode, CycleStep};
use crate::gcode::machine::interpret::{BlockEvent, SplineStep};
use crate::gcode::machine::modal::{GCode, MotionMode, classify_g};
use crate::gcode::machine::motion::{Feed, Motion, MotionKind};
use crate::gcode::syntax::block::{Block, Word};

/// How a flat block writes one move.
#[derive(Clone, Copy, Debug)]
struct MoveStyle {
    /// The axes written on every move (the others where they move).
    always: &'static [Axis],
    /// A rapid is written `G0` (else every move is `G1`).
    rapid_as_g0: bool,
    /// An inverse-time move gets its `F`.
    inverse_time_feed: bool,
}

/// A spline's pieces: `G1 X… Y…`, under G93 with the piece's `F`.
const SPLINE_MOVES: MoveStyle = MoveStyle {
    always: &[Axis::X, Axis::Y],
    rapid_as_g0: false,
    inverse_time_feed: true,
};

/// A cycle's moves: `G0`/`G1 X… Y… Z…` (a cycle move names them).
const CYCLE_MOVES: MoveStyle = MoveStyle {
    always: &[Axis::X, Axis::Y, Axis::Z],
    rapid_as_g0: true,
    inverse_time_feed: false,
};

impl Rewriter {
    /// Emit a block that is written flat, a canned cycle
    /// ([`Rewriter::emit_cycle`]) or a spline ([`Rewriter::emit_spline`]),
    /// with `ends[k]` the absolute target of `event.expanded[k]` (machine
    /// coordinates).
    pub fn emit_flat(
        &mut self,
        block: &Block,
        event: &BlockEvent,
        ends: &[Axes],
        out: &mut dyn Write,
    ) -> Result<Emitted, RewriteError> {
        if self.options.dialect == crate::gcode::Dialect::Heidenhain {
            let options = self.options;
            return self.klartext.emit_flat(&options, block, event, ends, out);
        }
        if event.spline.is_some() {
            self.emit_spline(block, event, ends, out)
        } else {
            self.emit_cycle(block, event, ends, out)
        }
    }

    /// Emit a spline block flat. A curve (G5, G5.1, or the G5.3 that runs a
    /// G5.2 NURBS): the block without its spline words (its other words and
    /// comments keep their effect) and a comment, then every straight piece
    /// (`ends[k]` the absolute target of `event.expanded[k]`, machine
    /// coordinates) as `G1 X… Y…` in absolute coordinates, under G93 with
    /// its `F` (the piece's share of the curve's time). A G5.2 control-point
    /// block: the block without its G5.2 X Y P L words, and a comment (its
    /// curve is written at its G5.3).
    pub fn emit_spline(
        &mut self,
        block: &Block,
        event: &BlockEvent,
        ends: &[Axes],
        out: &mut dyn Write,
    ) -> Result<Emitted, RewriteError> {
        check_ends(block, event, ends)?;
        let curve = match event.spline {
            Some(SplineStep::Curve { code, .. }) => Some(code),
            _ => None,
        };
        if curve == Some(53) && event.modal.motion == MotionMode::Spline(52) {
            return Err(RewriteError::CannotFlatten {
                line: block.line,
                what: "a G5.3 block whose axis words start another NURBS",
            });
        }
        // 1. The block without its spline words.
        let n = block.line;
        let comment = match curve {
            Some(53) => format!(" (volcomp: the G5.2 NURBS run by line {n} written flat below)"),
            Some(code) => format!(
                " (volcomp: {} of line {n} written flat below)",
                MotionMode::Spline(code).word()
            ),
            None => format!(
                " (volcomp: G5.2 control point of line {n}, the curve is written flat at its G5.3)"
            ),
        };
        let ctx = self.write_flat_header(block, event, spline_word, &comment, out)?;
        if curve.is_none() {
            self.original_motion = event.modal.motion;
            return Ok(Emitted {
                rewritten: true,
                pieces: 0,
            });
        }
        // 2. The pieces.
        let mut lines = Vec::new();
        for (end, motion) in ends.iter().zip(event.expanded()) {
            let mut line = String::new();
            self.push_move(&mut line, &ctx, event, end, motion, SPLINE_MOVES);
            lines.push(line);
        }
        let pieces = write_flat_lines(&ctx, line_ending(block), &lines, out)?;
        if !event.expanded().is_empty() {
            self.emitted_motion = MotionMode::Linear;
        }
        self.original_motion = event.modal.motion;
        Ok(Emitted {
            rewritten: true,
            pieces,
        })
    }

    /// Emit a canned-cycle block flat: the block without its cycle words (its
    /// other words and comments keep their effect), then every step as an
    /// explicit line: each move (`ends[k]` is the absolute target of
    /// `event.expanded[k]`, machine coordinates, as for [`Rewriter::emit`])
    /// as `G0`/`G1 X… Y… Z…` in absolute coordinates, dwells as `G4 P…`,
    /// spindle stops and starts as `M5`/`M3`/`M4`, override switches as
    /// `M49`/`M48`. Steps LinuxCNC runs that a flat program cannot say (the
    /// spindle orientation of G87, the assumed position after G88's stop and
    /// after G74/G84 in G18/G19) are refused ([`RewriteError::CannotFlatten`]).
    pub fn emit_cycle(
        &mut self,
        block: &Block,
        event: &BlockEvent,
        ends: &[Axes],
        out: &mut dyn Write,
    ) -> Result<Emitted, RewriteError> {
        check_ends(block, event, ends)?;
        if let Some(what) = event.cycle_steps().iter().find_map(unsayable) {
            return Err(RewriteError::CannotFlatten {
                line: block.line,
                what,
            });
        }
        // 1. The block without the cycle's words.
        let name = match event.modal.motion {
            MotionMode::Cycle(c) => {
                CycleCode::from_code10(c as i32).map_or("canned cycle", |c| c.name())
            }
            _ => "canned cycle",
        };
        let comment = format!(" (volcomp: {name} of line {} expanded below)", block.line);
        let ctx = self.write_flat_header(block, event, cycle_word, &comment, out)?;
        // 2. The steps.
        let mut lines = Vec::new();
        let mut moves = ends.iter().zip(event.expanded());
        for step in event.cycle_steps() {
            let mut line = String::new();
            match *step {
                CycleStep::Rapid(_) | CycleStep::Feed(_) => {
                    let Some((end, motion)) = moves.next() else {
                        return Err(RewriteError::NotAMotion { line: block.line });
                    };
                    self.push_move(&mut line, &ctx, event, end, motion, CYCLE_MOVES);
                }
                CycleStep::Dwell { seconds } => {
                    line.push_str("G4 P");
                    push_number(&mut line, seconds, 4);
                }
                CycleStep::SpindleStop => line.push_str("M5"),
                CycleStep::SpindleStart { clockwise } => {
                    line.push_str(if clockwise { "M3" } else { "M4" })
                }
                CycleStep::OverridesDisabled => line.push_str("M49"),
                CycleStep::OverridesRestored => line.push_str("M48"),
                CycleStep::ProgramStop => line.push_str("M0"),
                CycleStep::SpindleOrient { .. } | CycleStep::AssumePosition(_) => continue,
            }
            lines.push(line);
        }
        let pieces = write_flat_lines(&ctx, line_ending(block), &lines, out)?;
        self.emitted_motion = match event.expanded().last().map(|m| m.kind) {
            Some(MotionKind::Rapid) => MotionMode::Rapid,
            Some(_) => MotionMode::Linear,
            None => self.emitted_motion,
        };
        self.original_motion = event.modal.motion;
        Ok(Emitted {
            rewritten: true,
            pieces,
        })
    }

    /// Write the block without the words `strip` selects and with `comment`
    /// at its end (white space at the start dropped); the block's context.
    fn write_flat_header(
        &mut self,
        block: &Block,
        event: &BlockEvent,
        strip: fn(&Word) -> bool,
        comment: &str,
        out: &mut dyn Write,
    ) -> Result<Context, RewriteError> {
        self.note_decimals(block);
        let ctx = Context::new(block, event);
        self.strip_words(block, strip);
        let from = self.text.len();
        self.text.push_str(comment);
        self.record(from, block.raw.len(), block.raw.len());
        let mut header = Vec::with_capacity(block.raw.len() + 64);
        self.write_edited(block, &mut header)?;
        // Without its cycle or spline words the line may start with white space.
        out.write_all(header.trim_ascii_start())?;
        Ok(ctx)
    }

    /// Append one move to `line` (`end` in machine coordinates) and take it
    /// as emitted.
    fn push_move(
        &mut self,
        line: &mut String,
        ctx: &Context,
        event: &BlockEvent,
        end: &Axes,
        motion: &Motion,
        style: MoveStyle,
    ) {
        let program = event.origin.to_program(end);
        let rapid = style.rapid_as_g0 && motion.kind == MotionKind::Rapid;
        line.push_str(if rapid { "G0" } else { "G1" });
        for axis in self.options.axes.iter() {
            let moved = (end.get(axis) - self.emitted.get(axis)).abs() > 1e-12;
            if !moved && !style.always.contains(&axis) {
                continue;
            }
            let dec = ctx.decimals(axis, self.decimals[axis as usize], &self.options);
            line.push(' ');
            line.push(axis.letter());
            push_number(line, program.get(axis) / ctx.unit(axis), dec);
        }
        if style.inverse_time_feed
            && let Feed::InverseTime(f) = motion.feed
        {
            line.push_str(" F");
            let dec = feed_decimals(f, ctx.feed_decimals, &self.options);
            push_number(line, f, dec);
        }
        self.emitted = *end;
    }
}

/// One target for every expanded move, all finite.
fn check_ends(block: &Block, event: &BlockEvent, ends: &[Axes]) -> Result<(), RewriteError> {
    if ends.len() != event.expanded().len() {
        return Err(RewriteError::NotAMotion { line: block.line });
    }
    if !ends.iter().all(Axes::is_finite) {
        return Err(RewriteError::NonFinite { line: block.line });
    }
    Ok(())
}

/// A step LinuxCNC runs that a flat program cannot say.
fn unsayable(step: &CycleStep) -> Option<&'static str> {
    match step {
        CycleStep::SpindleOrient { .. } => Some("the spindle orientation of G87"),
        CycleStep::AssumePosition(_) => Some(
            "a position LinuxCNC assumes without moving there (G88's hand retract, G74/G84 outside G17)",
        ),
        _ => None,
    }
}

/// The words of a spline: its G code, its parameters and its axis words.
fn spline_word(w: &Word) -> bool {
    match w.letter {
        b'G' => matches!(
            w.code10().map(classify_g),
            Some(GCode::Motion(MotionMode::Spline(_)) | GCode::NurbsEnd)
        ),
        b'I' | b'J' | b'P' | b'Q' | b'L' | b'@' | b'^' => true,
        letter => Axis::from_letter(letter as char).is_some(),
    }
}

/// The words of a canned cycle: its G code, its parameters and its axis words.
fn cycle_word(w: &Word) -> bool {
    match w.letter {
        b'G' => matches!(
            w.code10().map(classify_g),
            Some(GCode::Motion(MotionMode::Cycle(_)))
        ),
        b'R' | b'Q' | b'P' | b'L' | b'I' | b'J' | b'K' | b'@' | b'^' => true,
        letter => Axis::from_letter(letter as char).is_some(),
    }
}

/// Write the lines of a flat block, between `G90` and `G91` when the block
/// runs under G91, in the block's letter case; how many lines were written.
fn write_flat_lines(
    ctx: &Context,
    ending: &[u8],
    lines: &[String],
    out: &mut dyn Write,
) -> Result<usize, RewriteError> {
    let mut put = |l: &str| -> std::io::Result<()> {
        if ctx.lowercase {
            out.write_all(l.to_ascii_lowercase().as_bytes())?;
        } else {
            out.write_all(l.as_bytes())?;
        }
        out.write_all(ending)
    };
    if ctx.incremental {
        put("G90")?;
    }
    for l in lines {
        put(l)?;
    }
    if ctx.incremental {
        put("G91")?;
    }
    Ok(lines.len() + if ctx.incremental { 2 } else { 0 })
}
