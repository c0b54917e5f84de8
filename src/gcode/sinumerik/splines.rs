//! `BSPLINE` written flat (Siemens, *Job planning*, "Spline interpolation
//! (ASPLINE, BSPLINE, CSPLINE, BAUTO, BNAT, BTAN, EAUTO, ENAT, ETAN, PW, SD,
//! PL)"). The B spline is a non-uniform rational B-spline (NURBS): the
//! programmed positions are its control points, not points it passes
//! through; it starts at the position before the section and ends at the
//! last programmed point, tangential to the control polygon at both ends
//! (the manual's note: the start and end conditions `BAUTO/BNAT/BTAN`,
//! `EAUTO/ENAT/ETAN` have no influence on the B spline). `SD=` is its
//! degree (3 by default, "a second degree polygon can also be used by
//! programming SD=2"; volcomp also takes `SD=1`, the control polygon), `PW=`
//! a point's weight (`0 < n ≤ 3`; > 1 pulls the curve towards the point,
//! < 1 less; the start point's weight is 1), `PL=` the block's parameter
//! interval length. `BSPLINE` is modal in the motion group: the section
//! ends at `G0`–`G3`, `CIP`, `CT`, `ASPLINE`, `CSPLINE`, `POLY` or the
//! program's end.
//!
//! What the manual leaves to the control ("the distances between nodes
//! are suitably calculated internally"), volcomp fixes and documents
//! (docs/dialects.md): a block's parameter interval is its `PL=`, else the
//! distance from the control point before to its own (chord length); the
//! knots are clamped (degree + 1 equal knots at each end) and the inner
//! ones are averages of `degree` consecutive parameters (de Boor's
//! averaging, Piegl and Tiller, *The NURBS Book*, eq. 9.8), so that
//! `SD=1` is the polygon. Block k owns the curve between the parameters of
//! control points k − 1 and k: it is handed on as straight chords within
//! [`CHORD_TOLERANCE_MM`] (0.5 µm, the tolerance of the circles handed on
//! as chords, and their code [`SinumerikFront::hand_on_chords`]), the
//! block itself the first chord (its other words with it), `; volcomp:
//! line N` on each. The evaluation and the chords are the LinuxCNC
//! spline's ([`crate::gcode::machine::spline`]).
//!
//! A section's curve depends on the points after each block, so its blocks
//! are held until it ends, then handed on in order with the blocks between
//! them. Inside a section, orientation or rotary axis words, `AC()`/`IC()`
//! and frame or work-offset changes are located errors (not read yet).
use std::collections::VecDeque;

use crate::gcode::error::GcodeError;
use crate::gcode::heidenhain::machine::CHORD_TOLERANCE_MM;
use crate::gcode::language::Executed;
use crate::gcode::machine::interpret::Interpreter;
use crate::gcode::machine::spline::{RationalCurve, chords_over};
use crate::gcode::syntax::block::{Block, LineEnding};

use super::syntax::{Tok, Token};
use super::{LineRun, Out, SinumerikFront};

/// The spline words of one block: `SD=`, `PL=`, `PW=` (value, text span).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct SplineWords {
    pub degree: Option<(f64, (usize, usize))>,
    pub interval: Option<(f64, (usize, usize))>,
    pub weight: Option<(f64, (usize, usize))>,
}

impl SplineWords {
    fn any(&self) -> bool {
        self.degree.is_some() || self.interval.is_some() || self.weight.is_some()
    }
}

/// A `BSPLINE` section being read: its start, control points and the
/// blocks held until it ends.
pub(super) struct SplineSection {
    /// Program coordinates where the curve starts (the position before it).
    start: [f64; 3],
    points: Vec<ControlBlock>,
    held: Vec<Held>,
}

/// A control point and the block that programmed it.
struct ControlBlock {
    end: [f64; 3],
    weight: f64,
    /// `PL=`, else the distance from the point before.
    interval: Option<f64>,
    out: Out,
    raw: Vec<u8>,
    line: usize,
    file: usize,
    incremental: bool,
}

enum Held {
    /// A block handed on in the section (no motion), in its order.
    Block(Box<(Block, Executed)>),
    /// The control point of that index.
    Point(usize),
}

/// Whether a line ends a `BSPLINE` section (before it runs): another motion
/// of the group (`G0`–`G3`, `CIP`, `CT`, `ASPLINE`, `CSPLINE`, `POLY`) or a
/// program end (`M2`, `M30`, `M17`, `RET`).
pub(super) fn ends_section(tokens: &[Token]) -> bool {
    tokens.iter().enumerate().any(|(i, t)| {
        let Tok::Name(name) = &t.tok else {
            return false;
        };
        let number = match tokens.get(i + 1) {
            Some(Token {
                tok: Tok::Num(v, ..),
                start,
                ..
            }) if *start == t.end => Some(*v),
            _ => None,
        };
        match name.as_ref() {
            "G" => number.is_some_and(|v| matches!(v, 0.0 | 1.0 | 2.0 | 3.0)),
            "M" => number.is_some_and(|v| matches!(v, 2.0 | 30.0 | 17.0)),
            "CIP" | "CT" | "ASPLINE" | "CSPLINE" | "POLY" | "RET" => true,
            _ => false,
        }
    })
}

impl SinumerikFront {
    /// A block in `BSPLINE` mode (`bspline`: the keyword's span when the
    /// block says it): its spline words are taken, and a block with axis
    /// words becomes a control point, held (`Some(false)`: nothing handed
    /// on now). `None`: the block goes on as any other (written flat when
    /// it carried spline words).
    #[allow(clippy::too_many_arguments)]
    #[inline(never)]
    pub(super) fn spline_block(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        bspline: Option<(usize, usize)>,
        words: &SplineWords,
        axis_words: bool,
        interpreter: &Interpreter,
    ) -> Result<Option<bool>, GcodeError> {
        if bspline.is_none() && self.spline.is_none() {
            return Ok(None);
        }
        if let Some((d, (s, e))) = words.degree {
            if !(d.fract() == 0.0 && (1.0..=3.0).contains(&d)) {
                return Err(self.refused(
                    line,
                    format!("SD={d}: a B spline's degree is 1, 2 or 3"),
                    s,
                    e,
                ));
            }
            let started = self.spline.as_ref().is_some_and(|s| !s.points.is_empty());
            if started && d as usize != self.spline_degree {
                return Err(self.feature(line, "a change of SD= inside a BSPLINE section", s, e));
            }
            self.spline_degree = d as usize;
        }
        if self.spline.is_none() {
            let start = interpreter
                .origin()
                .to_program(&interpreter.position())
                .xyz();
            self.spline = Some(SplineSection {
                start,
                points: Vec::new(),
                held: Vec::new(),
            });
        }
        // The spline's words are not written (the flat pieces are G1).
        out.flat |= bspline.is_some() || words.any();
        if !axis_words {
            if let Some((_, (s, e))) = words.weight.or(words.interval) {
                return Err(self.refused(
                    line,
                    "PW= and PL= belong to a block with a control point".into(),
                    s,
                    e,
                ));
            }
            return Ok(None);
        }
        let turns = out.words.iter().find(|w| {
            super::orientation::word_name(w.letter).is_some()
                || crate::axes::Axis::from_letter(w.letter as char).is_some_and(|a| a.is_rotary())
        });
        if let Some(w) = turns {
            return Err(self.feature(
                line,
                "orientation or rotary axes in a BSPLINE block",
                w.start,
                w.end.max(w.start + 1).min(line.raw.len()),
            ));
        }
        if let Some(&k) = out.absolute.first().or(out.relative.first()) {
            let w = out.words[k];
            return Err(self.feature(line, "AC()/IC() in a BSPLINE block", w.start, w.end));
        }
        let weight = match words.weight {
            Some((w, (s, e))) if !(w > 0.0 && w <= 3.0) => {
                return Err(self.refused(
                    line,
                    format!("PW={w}: a point weight is more than 0 and at most 3"),
                    s,
                    e,
                ));
            }
            Some((w, _)) => w,
            None => 1.0,
        };
        let interval = match words.interval {
            Some((l, (s, e))) if !(l > 0.0) => {
                return Err(self.refused(
                    line,
                    format!("PL={l}: a parameter interval length is more than 0"),
                    s,
                    e,
                ));
            }
            l => l.map(|l| l.0),
        };
        let incremental = out.incremental(self.incremental);
        let section = self.spline.as_mut().expect("opened above");
        let before = section.points.last().map_or(section.start, |p| p.end);
        let end = super::circles::block_end(out, before, incremental);
        if interval.is_none() && end == before {
            return Err(self.refused(
                line,
                "a B spline control point equal to the one before needs PL= (its parameter interval)"
                    .into(),
                0,
                line.raw.len(),
            ));
        }
        section.held.push(Held::Point(section.points.len()));
        section.points.push(ControlBlock {
            end,
            weight,
            interval,
            out: std::mem::replace(out, Out::new(0)),
            raw: line.raw.to_vec(),
            line: line.line,
            file: line.file,
            incremental,
        });
        let level = self.levels.len() - 1;
        self.levels[level].moved = true;
        Ok(Some(false))
    }

    /// Hold the block just handed on (`self.block`, with the pieces queued
    /// after it) while a section is open. Returns whether it was held.
    pub(super) fn hold_in_spline(&mut self) -> bool {
        let Some(section) = self.spline.as_mut() else {
            return false;
        };
        let executed = self.executed.clone();
        let block = std::mem::take(&mut self.block);
        let (line, offset) = (block.line, block.offset);
        section
            .held
            .push(Held::Block(Box::new((block, executed.clone()))));
        while let Some(mut piece) = self.pending.pop_front() {
            piece.line = line;
            piece.offset = offset;
            piece.ending = LineEnding::Lf;
            section.held.push(Held::Block(Box::new((
                piece,
                Executed {
                    literal: false,
                    ..executed.clone()
                },
            ))));
        }
        true
    }

    /// End the open section: its curve as chords, with the blocks held in
    /// it, queued in order ([`Self::next_spline_block`]).
    #[inline(never)]
    pub(super) fn close_spline(&mut self, interpreter: &Interpreter) -> Result<(), GcodeError> {
        let Some(section) = self.spline.take() else {
            return Ok(());
        };
        let n = section.points.len();
        let mut points = Vec::with_capacity(n + 1);
        let mut weights = Vec::with_capacity(n + 1);
        let mut params = Vec::with_capacity(n + 1);
        points.push(section.start);
        weights.push(1.0);
        params.push(0.0);
        for p in &section.points {
            let before = *points.last().expect("the start");
            let d = p.interval.unwrap_or_else(|| distance(before, p.end));
            params.push(params.last().expect("the start") + d);
            points.push(p.end);
            weights.push(p.weight);
        }
        let degree = self.spline_degree.min(n);
        let knots = averaged_knots(&params, degree);
        let curve = RationalCurve {
            points,
            weights,
            degree,
            knots,
        };
        let at = |u: f64| curve.point(u);
        let max = self
            .options
            .max_generated_moves
            .unwrap_or(crate::gcode::language::DEFAULT_MAX_GENERATED_MOVES)
            .min(usize::MAX as u64) as usize;
        let mut controls: Vec<Option<ControlBlock>> =
            section.points.into_iter().map(Some).collect();
        for held in section.held {
            let k = match held {
                Held::Block(held) => {
                    self.spline_out.push_back(*held);
                    continue;
                }
                Held::Point(k) => k,
            };
            let Some(mut c) = controls[k].take() else {
                continue;
            };
            let line = LineRun {
                raw: &c.raw,
                line: c.line,
                file: c.file,
                first_reading: false,
            };
            let chords = chords_over(&at, (params[k], params[k + 1]), 1, CHORD_TOLERANCE_MM, max)
                .map_err(|e| {
                self.refused(&line, format!("the B spline: {e}"), 0, c.raw.len())
            })?;
            let from = if k == 0 {
                curve.points[0]
            } else {
                curve.point(params[k])
            };
            self.hand_on_chords(&line, &mut c.out, interpreter, from, &chords, c.incremental)?;
            self.restore_arc = None;
            let executed = Executed::made_from(c.file, c.line);
            let mut pieces = VecDeque::new();
            if self.hand_on(
                &line,
                &mut std::mem::replace(&mut c.out, Out::new(0)),
                &c.raw,
                false,
            )? {
                pieces.push_back(std::mem::take(&mut self.block));
            }
            pieces.extend(self.pending.drain(..));
            for mut piece in pieces {
                piece.line = c.line;
                piece.ending = LineEnding::Lf;
                self.spline_out.push_back((piece, executed.clone()));
            }
        }
        // A `CT` after the spline has no tangent here.
        self.last_move = None;
        Ok(())
    }

    /// The next block of a closed section, into [`Self::block`]; whether
    /// there was one.
    pub(super) fn next_spline_block(&mut self) -> bool {
        match self.spline_out.pop_front() {
            Some((block, executed)) => {
                self.block = block;
                self.executed = executed;
                true
            }
            None => false,
        }
    }
}

/// The clamped knot vector over the parameters `params` (one per control
/// point, increasing from 0) for `degree`: `degree + 1` zeros, the inner
/// knots as averages of `degree` consecutive parameters, `degree + 1`
/// times the last parameter (*The NURBS Book*, eq. 9.8).
pub(crate) fn averaged_knots(params: &[f64], degree: usize) -> Vec<f64> {
    let n = params.len() - 1;
    let p = degree.max(1);
    let last = params[n];
    let mut knots = vec![0.0; p + 1];
    for j in 1..=n.saturating_sub(p) {
        knots.push(params[j..j + p].iter().sum::<f64>() / p as f64);
    }
    knots.extend(std::iter::repeat_n(last, p + 1));
    knots
}

fn distance(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal parameter steps: the cubic's inner knots are 2, 3, …, n − 2
    /// (the averages of three consecutive steps), the linear one's the
    /// parameters themselves.
    #[test]
    fn knots_are_averages_of_the_parameters() {
        let params = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        assert_eq!(
            averaged_knots(&params, 3),
            vec![0.0, 0.0, 0.0, 0.0, 2.0, 3.0, 5.0, 5.0, 5.0, 5.0]
        );
        assert_eq!(
            averaged_knots(&params, 1),
            vec![0.0, 0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 5.0]
        );
        // Three points, degree 2: a Bézier curve (no inner knot).
        assert_eq!(
            averaged_knots(&[0.0, 1.0, 3.0], 2),
            vec![0.0, 0.0, 0.0, 3.0, 3.0, 3.0]
        );
    }
}
