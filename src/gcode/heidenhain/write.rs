//! Klartext written back (dialects.md "Writing back"): an untouched block
//! byte for byte; a changed block keeps its words and comment and changes
//! only its changed axis words, in the input's style (`X+12.5` →
//! `X+12.5001`: the sign written when the input wrote it, at least the
//! rewriter's decimals); a changed parameter word (`X+Q1`) as a number;
//! split pieces and canned-cycle moves as `L` blocks; blocks numbered
//! consecutively from the first (`0 BEGIN PGM`), so that a program with
//! pieces added still reads on the control. Blocks a taken jump passed
//! over become `; volcomp:` comments (the output is the run, flat), blocks
//! after the program's end stay as written.
use std::io::Write;

use super::syntax::{KlBlock, parse_block};
use crate::axes::Axes;
use crate::gcode::machine::interpret::{BlockEvent, Moves};
use crate::gcode::machine::modal::Units;
use crate::gcode::machine::motion::{Feed, MotionKind, to_plane};
use crate::gcode::syntax::block::Block;
use crate::gcode::write::format::{half_ulp, push_number};
use crate::gcode::write::rewrite::{Emitted, RewriteError, RewriteOptions, Target};

/// `v` with an explicit sign and `decimals` decimals (`+12.5000`).
pub fn signed_number(v: f64, decimals: u8) -> String {
    let mut s = String::new();
    let printed = push_number(&mut s, v, decimals);
    if printed >= 0.0 && !s.starts_with('-') {
        s.insert(0, '+');
    }
    s
}

/// The Klartext writer: block numbers and the emitted position.
#[derive(Clone, Debug, Default)]
pub struct KlartextWriter {
    /// The last block number written; whether the program numbers its
    /// blocks (known from its first block).
    last_number: Option<u64>,
    numbered: Option<bool>,
    /// The program has ended: passed blocks are written as they are.
    ended: bool,
    /// The last target written (event frame), for incremental words.
    emitted: Option<Axes>,
    line: Vec<u8>,
    /// The machine's orientation kinematics: the tool axis of corrected
    /// joints, written as an `LN` block's `TX TY TZ`.
    pub(crate) orientation: Option<std::sync::Arc<dyn crate::gcode::OrientationSolver>>,
}

/// Least decimals of a rewritten `LN` vector component (1e-7 rad).
const VECTOR_DECIMALS: u8 = 7;

const LETTERS: [(&str, usize); 6] = [("X", 0), ("Y", 1), ("Z", 2), ("A", 3), ("B", 4), ("C", 5)];

fn slot_value(a: &Axes, slot: usize) -> f64 {
    match slot {
        0 => a.x,
        1 => a.y,
        2 => a.z,
        3 => a.a,
        4 => a.b,
        _ => a.c,
    }
}

impl KlartextWriter {
    /// Emit one block (the contract of [`crate::gcode::Rewriter::emit`]).
    pub fn emit(
        &mut self,
        options: &RewriteOptions,
        block: &Block,
        event: &BlockEvent,
        target: Target<'_>,
        out: &mut dyn Write,
    ) -> Result<Emitted, RewriteError> {
        let parsed = parse_block(&block.raw);
        if event.skipped {
            if target != Target::Same {
                return Err(RewriteError::NotAMotion { line: block.line });
            }
            if self.ended || parsed.tokens.is_empty() && !parsed.section {
                self.write_numbered(block, &parsed, None, out)?;
            } else {
                // Passed over by a jump the flat output no longer takes.
                let code = parsed.code.trim();
                let text = format!(" ; volcomp: not run (line {}): {code}", block.line);
                self.write_fresh(&text, block, out)?;
            }
            return Ok(Emitted::default());
        }
        let mut emitted = Emitted::default();
        if matches!(event.moves, Moves::Cycle { .. }) && target == Target::Same {
            let ends: Vec<Axes> = event.expanded().iter().map(|m| m.end).collect();
            return self.emit_flat(options, block, event, &ends, out);
        }
        match (target, event.motion()) {
            (Target::Same, _) | (_, None) => {
                if target != Target::Same {
                    return Err(RewriteError::NotAMotion { line: block.line });
                }
                self.write_numbered(block, &parsed, None, out)?;
                if let Some(m) = event.motions().last() {
                    self.emitted = Some(m.end);
                }
            }
            (Target::Move(end), Some(m)) if self.polar_moved(options, &parsed, event, m, &end) => {
                let start = self.emitted.unwrap_or(m.start);
                emitted.rewritten = true;
                emitted.pieces +=
                    self.emit_polar(options, block, &parsed, event, m, start, &end, out)?;
                self.emitted = Some(end);
            }
            (Target::Move(end), Some(m)) => {
                let edits = self.edits(options, block, &parsed, event, &end)?;
                emitted.rewritten = !edits.is_empty();
                self.write_numbered(block, &parsed, Some(&edits), out)?;
                let _ = m;
                self.emitted = Some(end);
            }
            (Target::Split { via, end }, Some(m)) => {
                let feed = m.feed;
                for p in via {
                    if !p.is_finite() {
                        return Err(RewriteError::NonFinite { line: block.line });
                    }
                    let text = self.linear_text(options, event, p, feed, block.line);
                    self.write_fresh(&text, block, out)?;
                    emitted.pieces += 1;
                    self.emitted = Some(*p);
                }
                if matches!(m.kind, MotionKind::Arc { .. }) {
                    // The arc's last chord: a straight block, the arc as a comment.
                    let text = self.linear_text(options, event, &end, feed, block.line);
                    self.write_fresh(&text, block, out)?;
                    let code = parsed.code.trim();
                    self.write_fresh(
                        &format!(" ; volcomp: line {} as chords: {code}", block.line),
                        block,
                        out,
                    )?;
                } else if parsed.address(0) == "LP" {
                    let start = self.emitted.unwrap_or(m.start);
                    emitted.pieces +=
                        self.emit_polar(options, block, &parsed, event, m, start, &end, out)?;
                } else {
                    let edits = self.edits(options, block, &parsed, event, &end)?;
                    self.write_numbered(block, &parsed, Some(&edits), out)?;
                }
                emitted.rewritten = true;
                self.emitted = Some(end);
            }
        }
        if event.program_end {
            self.ended = true;
        }
        Ok(emitted)
    }

    /// A canned cycle written flat: the calling block as a comment, then its
    /// moves as `L` blocks at `ends` (event frame).
    pub fn emit_flat(
        &mut self,
        options: &RewriteOptions,
        block: &Block,
        event: &BlockEvent,
        ends: &[Axes],
        out: &mut dyn Write,
    ) -> Result<Emitted, RewriteError> {
        let parsed = parse_block(&block.raw);
        let code = parsed.code.trim().to_string();
        self.write_fresh(
            &format!(" ; volcomp: line {} written flat: {code}", block.line),
            block,
            out,
        )?;
        let mut emitted = Emitted {
            rewritten: true,
            pieces: 0,
        };
        for (m, end) in event.expanded().iter().zip(ends) {
            if !end.is_finite() {
                return Err(RewriteError::NonFinite { line: block.line });
            }
            let text = self.linear_text(options, event, end, m.feed, block.line);
            self.write_fresh(&text, block, out)?;
            emitted.pieces += 1;
            self.emitted = Some(*end);
        }
        Ok(emitted)
    }

    /// ` L X… Y… Z… [A… B… C…] FMAX|F…` for a target in the event's frame.
    fn linear_text(
        &self,
        options: &RewriteOptions,
        event: &BlockEvent,
        p: &Axes,
        feed: Feed,
        line: usize,
    ) -> String {
        let prog = event.origin.to_program(p);
        let inch = event.modal.units == Units::Inch;
        let d = if inch {
            options.min_decimals_inch
        } else {
            options.min_decimals_mm
        };
        let mut s = String::from(" L");
        for (letter, slot) in LETTERS {
            let v = slot_value(&prog, slot);
            let v = if slot < 3 && inch { v / 25.4 } else { v };
            if slot >= 3 && v == 0.0 && slot_value(&event.start, slot) == 0.0 {
                continue;
            }
            s.push(' ');
            s.push_str(letter);
            s.push_str(&signed_number(v, d));
        }
        match feed {
            Feed::Rapid => s.push_str(" FMAX"),
            Feed::PerMinute(f) | Feed::InverseTime(f) => {
                let f = if inch { f / 2.54 } else { f };
                s.push_str(&format!(" F{}", trim_number(f)));
            }
        }
        s.push_str(&format!(" ; volcomp: line {line}"));
        s
    }

    /// Whether a polar block (`LP`, `CP`) must be written anew: its end
    /// moved, or its start did (a `CP` keeps the radius of its start, an
    /// incremental `IPR`/`IPA` is counted from it).
    fn polar_moved(
        &self,
        options: &RewriteOptions,
        parsed: &KlBlock,
        event: &BlockEvent,
        m: &crate::gcode::Motion,
        end: &Axes,
    ) -> bool {
        if !matches!(parsed.address(0), "LP" | "CP") {
            return false;
        }
        let d = if event.modal.units == Units::Inch {
            options.min_decimals_inch
        } else {
            options.min_decimals_mm
        };
        let limit = half_ulp(d);
        let start = self.emitted.unwrap_or(m.start);
        (0..3).any(|k| {
            (slot_value(end, k) - slot_value(&m.end, k)).abs() >= limit
                || (slot_value(&start, k) - slot_value(&m.start, k)).abs() > 1e-9
        })
    }

    /// A polar block whose start or end the correction moved, written so
    /// that the control lands on the corrected end from the corrected
    /// start (docs/dialects.md "Writing back", polar blocks):
    /// - `LP` becomes the straight line `L X… Y… Z…` to the corrected end
    ///   (its other words kept), after a `; volcomp:` note naming the
    ///   original: the polar form has no word for the tool-axis coordinate.
    /// - `CP` keeps its form: a `CP` keeps the radius of its start about the
    ///   pole, so the pole is moved for it (`CC` before, the program's pole
    ///   restored by a `CC` after) to the point nearest the program's pole
    ///   equidistant from the corrected start and end; its `PA`/`IPA` and
    ///   `IZ`/`Z` are rewritten. A helix of more than 270° first turns its
    ///   half turns (`CP IPA±180 IZ…` pieces, each about the pole moved by
    ///   the correction at its middle, the tool-axis travel in proportion),
    ///   so that the equidistant pole is taken on an arc of 90°–270°, where
    ///   it is well defined.
    ///
    /// Returns the blocks added.
    #[allow(clippy::too_many_arguments)]
    fn emit_polar(
        &mut self,
        options: &RewriteOptions,
        block: &Block,
        parsed: &KlBlock,
        event: &BlockEvent,
        m: &crate::gcode::Motion,
        start: Axes,
        end: &Axes,
        out: &mut dyn Write,
    ) -> Result<usize, RewriteError> {
        if !end.is_finite() || !start.is_finite() {
            return Err(RewriteError::NonFinite { line: block.line });
        }
        let inch = event.modal.units == Units::Inch;
        let d = if inch {
            options.min_decimals_inch
        } else {
            options.min_decimals_mm
        };
        let unit = if inch { 25.4 } else { 1.0 };
        let prog = |a: &Axes| event.origin.to_program(a).xyz().map(|v| v / unit);
        let code = parsed.code.trim().to_string();
        let (new_end, new_start) = (prog(end), prog(&start));
        let MotionKind::Arc {
            clockwise,
            centre,
            plane,
            turns,
        } = m.kind
        else {
            // LP → L X Y Z.
            self.write_fresh(
                &format!(
                    " ; volcomp: line {} written as L (its corrected end): {code}",
                    block.line
                ),
                block,
                out,
            )?;
            let mut edits = Vec::new();
            let first = &parsed.tokens[0];
            edits.push((first.span.clone(), "L".to_string()));
            let mut xyz = String::new();
            for (k, letter) in ["X", "Y", "Z"].into_iter().enumerate() {
                xyz.push(' ');
                xyz.push_str(letter);
                xyz.push_str(&signed_number(new_end[k], d));
            }
            edits.push((first.span.end..first.span.end, xyz));
            let polar_words = ["PR", "IPR", "PA", "IPA", "X", "Y", "Z", "IX", "IY", "IZ"];
            edits.extend(removals(block, parsed, &polar_words));
            edits.sort_by_key(|e| e.0.start);
            self.write_numbered(block, parsed, Some(&edits), out)?;
            return Ok(1);
        };
        // CP, in the plane's coordinates (program frame, program units).
        let plane_of = |p: [f64; 3]| to_plane(plane, p);
        let c_prog = prog(&Axes {
            x: centre[0],
            y: centre[1],
            z: centre[2],
            ..m.end
        });
        let c = plane_of(c_prog);
        let (s0, e0) = (plane_of(prog(&m.start)), plane_of(prog(&m.end)));
        let (s1, e1) = (plane_of(new_start), plane_of(new_end));
        let angle = |p: [f64; 3], o: [f64; 3]| (p[1] - o[1]).atan2(p[0] - o[0]).to_degrees();
        let sigma = if clockwise { -1.0 } else { 1.0 };
        let wrap = |a: f64| (a + 180.0).rem_euclid(360.0) - 180.0;
        let mut directed = (sigma * (angle(e0, c) - angle(s0, c))).rem_euclid(360.0);
        if directed < 1e-7 {
            directed = 360.0;
        }
        let sweep0 = directed + 360.0 * f64::from(turns);
        let sweep =
            sweep0 + sigma * wrap((angle(e1, c) - angle(e0, c)) - (angle(s1, c) - angle(s0, c)));
        // The last part, 90°–270° (or the whole arc when shorter).
        let r = sweep.rem_euclid(360.0);
        let mut last = if r < 90.0 {
            r + 180.0
        } else if r > 270.0 {
            r - 180.0
        } else {
            r
        };
        if last > sweep {
            last = sweep;
        }
        let before = sweep - last;
        let letters = plane_letters(plane);
        let feed = parsed
            .tokens
            .iter()
            .find(|t| t.address == "F" || t.address == "FMAX")
            .map(|t| String::from_utf8_lossy(&block.raw[t.span.clone()]).into_owned());
        let dr = if clockwise { "DR-" } else { "DR+" };
        let mut added = 0;
        self.write_fresh(
            &format!(
                " ; volcomp: line {} written to its corrected end (the pole moved for it): {code}",
                block.line
            ),
            block,
            out,
        )?;
        added += 1;
        // The corrections of the start and the end, in the plane: the
        // compensated circle is the program's translated by them (the
        // errors vary little over an arc the compensator did not split).
        let ds = [s1[0] - s0[0], s1[1] - s0[1]];
        let de = [e1[0] - e0[0], e1[1] - e0[1]];
        let rounded = |v: f64| signed_short(v).parse::<f64>().unwrap_or(v);
        let mut current = [c[0], c[1]];
        let mut moved = false;
        let mut set_pole = |w: &mut Self, p: [f64; 2], out: &mut dyn Write| {
            let p = [rounded(p[0]), rounded(p[1])];
            if p == current {
                return Ok::<_, RewriteError>((p, 0));
            }
            current = p;
            moved = true;
            let text = pole_block(letters, &p, &format!("line {}", block.line));
            w.write_fresh(&text, block, out)?;
            Ok((p, 1))
        };
        // The correction at the fraction `t` of the arc (the compensator's
        // straight interpolation of the end corrections).
        let at = |t: f64| [ds[0] + t * (de[0] - ds[0]), ds[1] + t * (de[1] - ds[1])];
        let mut from = s1;
        let mut done = 0.0;
        let (r0, a0) = ((s0[0] - c[0]).hypot(s0[1] - c[1]), angle(s0, c));
        // The compensated path at the fraction `t` of the arc, in the plane:
        // the program's point there moved by the interpolated correction
        // (what the compensator checked against its tolerance).
        let model_at = |t: f64| {
            let a = (a0 + sigma * t * sweep0).to_radians();
            let corr = at(t);
            [
                c[0] + r0 * a.cos() + corr[0],
                c[1] + r0 * a.sin() + corr[1],
                0.0,
            ]
        };
        while before - done > 1e-9 {
            // Half turns first, each on the circle through where the last
            // one ended and its own corrected end (the program's point
            // there plus the interpolated correction), about the pole on
            // their bisector nearest the program's pole moved by the
            // correction at its middle.
            let step = (before - done).min(180.0);
            let t = (done + step) / sweep;
            let mid = at((done + step / 2.0) / sweep);
            let a = (a0 + sigma * (done + step) * sweep0 / sweep).to_radians();
            let corr = at(t);
            let target = [
                c[0] + r0 * a.cos() + corr[0],
                c[1] + r0 * a.sin() + corr[1],
                s1[2] + (e1[2] - s1[2]) * t,
            ];
            let guess = [c[0] + mid[0], c[1] + mid[1], 0.0];
            let (p, n) = set_pole(
                self,
                pole_through(guess, from, model_at((done + step / 2.0) / sweep), target),
                out,
            )?;
            added += n;
            let p3 = [p[0], p[1], 0.0];
            let mut turn = (sigma * (angle(target, p3) - angle(from, p3))).rem_euclid(360.0);
            turn += 360.0 * ((step - turn) / 360.0).round();
            let written: f64 = signed_number(sigma * turn, d)
                .parse()
                .unwrap_or(sigma * turn);
            let dz: f64 = signed_number(target[2] - from[2], d)
                .parse()
                .unwrap_or(target[2] - from[2]);
            let mut text = format!(
                " CP IPA{} I{}{} {dr}",
                signed_number(written, d),
                letters[2],
                signed_number(dz, d)
            );
            if let Some(f) = &feed {
                text.push(' ');
                text.push_str(f);
            }
            text.push_str(&format!(" ; volcomp: line {}", block.line));
            self.write_fresh(&text, block, out)?;
            added += 1;
            // Where the control ends it: the start's radius, the written angle.
            let radius = (from[0] - p[0]).hypot(from[1] - p[1]);
            let a = (angle(from, p3) + written).to_radians();
            from = [
                p[0] + radius * a.cos(),
                p[1] + radius * a.sin(),
                from[2] + dz,
            ];
            done += step;
        }
        let ds = at(done / sweep);
        // The pole for the rest: on the circle through its start, the
        // compensated path's point at its middle and the end.
        let guess = [
            c[0] + (ds[0] + de[0]) / 2.0,
            c[1] + (ds[1] + de[1]) / 2.0,
            0.0,
        ];
        let (p, n) = set_pole(
            self,
            pole_through(guess, from, model_at((done + last / 2.0) / sweep), e1),
            out,
        )?;
        added += n;
        let pole = [p[0], p[1], 0.0];
        let mut rest = (sigma * (angle(e1, pole) - angle(from, pole))).rem_euclid(360.0);
        rest += 360.0 * ((last - rest) / 360.0).round();
        let mut edits = Vec::new();
        let mut after_angle = parsed.tokens[0].span.end;
        let mut axis_written = false;
        for t in &parsed.tokens[1..] {
            let value = match t.address.as_str() {
                "PA" => {
                    after_angle = t.span.end;
                    Some(signed_number(angle(e1, pole), d.max(t.decimals)))
                }
                "IPA" => {
                    after_angle = t.span.end;
                    Some(signed_number(sigma * rest, d.max(t.decimals)))
                }
                a if a == letters[2] => {
                    axis_written = true;
                    Some(signed_number(e1[2], d.max(t.decimals)))
                }
                a if a.len() == 2 && a.starts_with('I') && &a[1..] == letters[2] => {
                    axis_written = true;
                    Some(signed_number(e1[2] - from[2], d.max(t.decimals)))
                }
                _ => None,
            };
            if let Some(mut v) = value
                && !t.value_span.is_empty()
            {
                if !t.signed && !v.starts_with('-') {
                    v.remove(0);
                }
                edits.push((t.value_span.clone(), v));
            }
        }
        if !axis_written && (e1[2] - from[2]).abs() >= half_ulp(d) {
            edits.push((
                after_angle..after_angle,
                format!(" I{}{}", letters[2], signed_number(e1[2] - from[2], d)),
            ));
        }
        edits.sort_by_key(|e| e.0.start);
        self.write_numbered(block, parsed, Some(&edits), out)?;
        if moved {
            let text = pole_block(
                letters,
                &c,
                &format!("the pole of line {} again", block.line),
            );
            self.write_fresh(&text, block, out)?;
            added += 1;
        }
        Ok(added)
    }

    /// The word edits that move `block` to `end` (event frame).
    fn edits(
        &self,
        options: &RewriteOptions,
        block: &Block,
        parsed: &KlBlock,
        event: &BlockEvent,
        end: &Axes,
    ) -> Result<Vec<(std::ops::Range<usize>, String)>, RewriteError> {
        if !end.is_finite() {
            return Err(RewriteError::NonFinite { line: block.line });
        }
        let Some(m) = event.motion() else {
            return Err(RewriteError::NotAMotion { line: block.line });
        };
        let inch = event.modal.units == Units::Inch;
        let base_d = if inch {
            options.min_decimals_inch
        } else {
            options.min_decimals_mm
        };
        let new = event.origin.to_program(end);
        let old = event.origin.to_program(&m.end);
        let before = event.origin.to_program(&self.emitted.unwrap_or(m.start));
        let unit = |slot: usize, v: f64| if slot < 3 && inch { v / 25.4 } else { v };
        let mut edits = Vec::new();
        let mut last_axis_end = parsed.tokens.first().map_or(0, |t| t.span.end);
        let polar = parsed.address(0) == "CP" || parsed.address(0) == "LP";
        // An LN block with a tool vector: its orientation is the vector, not
        // rotary words (written below).
        let vector = parsed.address(0) == "LN"
            && parsed
                .tokens
                .iter()
                .any(|t| matches!(t.address.as_str(), "TX" | "TY" | "TZ"));
        for (letter, slot) in LETTERS {
            if vector && slot >= 3 {
                continue;
            }
            let (n, o) = (
                unit(slot, slot_value(&new, slot)),
                unit(slot, slot_value(&old, slot)),
            );
            let token = parsed.tokens.iter().find(|t| {
                t.address == letter
                    || (t.address.len() == 2
                        && t.address.starts_with('I')
                        && &t.address[1..] == letter)
            });
            let changed = (n - o).abs() >= half_ulp(base_d);
            match token {
                Some(t) => {
                    last_axis_end = last_axis_end.max(t.span.end);
                    if !changed && !self.emitted_moved(slot, &before, event, m) {
                        continue;
                    }
                    let incremental = t.address.starts_with('I');
                    let v = if incremental {
                        n - unit(slot, slot_value(&before, slot))
                    } else {
                        n
                    };
                    let d = t.decimals.max(base_d);
                    let mut text = signed_number(v, d);
                    if !t.signed && !text.starts_with('-') {
                        text.remove(0);
                    }
                    if t.value_span.is_empty() {
                        continue;
                    }
                    let old_text = &block.raw[t.value_span.clone()];
                    if old_text != text.as_bytes() && (changed || incremental) {
                        edits.push((t.value_span.clone(), text));
                    }
                }
                None if changed => {
                    if polar {
                        return Err(RewriteError::CannotFlatten {
                            line: block.line,
                            what: "a corrected end of a polar block (LP, CP)",
                        });
                    }
                    edits.push((
                        last_axis_end..last_axis_end,
                        format!(" {letter}{}", signed_number(n, base_d)),
                    ));
                }
                None => {}
            }
        }
        if vector {
            self.vector_edits(block, parsed, event, m, end, &mut edits)?;
        }
        edits.sort_by_key(|e| e.0.start);
        Ok(edits)
    }

    /// The `TX TY TZ` of an `LN` block moved to the tool axis of the
    /// corrected joints (dialects.md "Writing back": a vector program keeps
    /// its form, the vector being the nominal tool axis of the solved
    /// joints), in the program's frame: each component that changes is
    /// written in the input's sign style with at least 7 decimals (1e-7 rad);
    /// the others stay as written.
    fn vector_edits(
        &self,
        block: &Block,
        parsed: &KlBlock,
        event: &BlockEvent,
        m: &crate::gcode::Motion,
        end: &Axes,
        edits: &mut Vec<(std::ops::Range<usize>, String)>,
    ) -> Result<(), RewriteError> {
        let turned = (end.a - m.end.a).abs() > 1e-12
            || (end.b - m.end.b).abs() > 1e-12
            || (end.c - m.end.c).abs() > 1e-12;
        if !turned {
            return Ok(());
        }
        let Some(solver) = &self.orientation else {
            return Err(RewriteError::CannotFlatten {
                line: block.line,
                what: "a corrected LN tool vector without the machine's kinematics",
            });
        };
        let program = |v: [f64; 3]| match &event.origin.frame {
            Some(f) => {
                let (o, w) = (f.unapply([0.0; 3]), f.unapply(v));
                [w[0] - o[0], w[1] - o[1], w[2] - o[2]]
            }
            None => v,
        };
        let new = program(solver.axis_of(end));
        let old = program(solver.axis_of(&m.end));
        if !new.iter().all(|v| v.is_finite()) {
            return Err(RewriteError::NonFinite { line: block.line });
        }
        let mut last = 0;
        for (k, name) in ["TX", "TY", "TZ"].into_iter().enumerate() {
            let token = parsed.tokens.iter().find(|t| t.address == name);
            let d = token.map_or(VECTOR_DECIMALS, |t| t.decimals.max(VECTOR_DECIMALS));
            let changed = (new[k] - old[k]).abs() >= half_ulp(d);
            match token {
                Some(t) => {
                    last = last.max(t.span.end);
                    if !changed || t.value_span.is_empty() {
                        continue;
                    }
                    let mut text = signed_number(new[k], d);
                    if !t.signed && !text.starts_with('-') {
                        text.remove(0);
                    }
                    edits.push((t.value_span.clone(), text));
                }
                None if changed => {
                    let at = parsed
                        .tokens
                        .iter()
                        .filter(|t| matches!(t.address.as_str(), "TX" | "TY" | "TZ"))
                        .map(|t| t.span.end)
                        .max()
                        .unwrap_or(last);
                    edits.push((at..at, format!(" {name}{}", signed_number(new[k], d))));
                }
                None => {}
            }
        }
        Ok(())
    }

    /// Whether the emitted start of this move differs from its programmed
    /// start on `slot` (an incremental word must then be rewritten).
    fn emitted_moved(
        &self,
        slot: usize,
        before: &Axes,
        event: &BlockEvent,
        m: &crate::gcode::Motion,
    ) -> bool {
        let start = event.origin.to_program(&m.start);
        (slot_value(before, slot) - slot_value(&start, slot)).abs() > 1e-9
    }

    /// Write `block` renumbered, with `edits` applied.
    fn write_numbered(
        &mut self,
        block: &Block,
        parsed: &KlBlock,
        edits: Option<&Vec<(std::ops::Range<usize>, String)>>,
        out: &mut dyn Write,
    ) -> Result<(), RewriteError> {
        self.line.clear();
        let mut all: Vec<(std::ops::Range<usize>, String)> = Vec::new();
        if let Some((n, span)) = &parsed.number {
            self.numbered.get_or_insert(true);
            // Ascending: the block's own number unless a piece or a flat
            // copy came before it (then the next one).
            let want = self.last_number.map_or(*n, |l| (*n).max(l + 1));
            self.last_number = Some(want);
            if want != *n {
                all.push((span.clone(), want.to_string()));
            }
        } else if !parsed.tokens.is_empty() || parsed.section {
            self.numbered.get_or_insert(false);
        }
        if let Some(e) = edits {
            all.extend(e.iter().cloned());
        }
        all.sort_by_key(|e| e.0.start);
        let mut at = 0;
        for (range, text) in &all {
            if range.start < at || range.end > block.raw.len() {
                continue;
            }
            self.line.extend_from_slice(&block.raw[at..range.start]);
            self.line.extend_from_slice(text.as_bytes());
            at = range.end;
        }
        self.line.extend_from_slice(&block.raw[at..]);
        self.line.extend_from_slice(block.ending.as_bytes());
        out.write_all(&self.line)?;
        Ok(())
    }

    /// Write a new block: the next number, then `text` (which starts with a
    /// space), with `block`'s line ending (a new line when it has none).
    fn write_fresh(
        &mut self,
        text: &str,
        block: &Block,
        out: &mut dyn Write,
    ) -> Result<(), RewriteError> {
        if self.numbered != Some(false) {
            let n = self.last_number.map_or(0, |l| l + 1);
            self.last_number = Some(n);
            out.write_all(n.to_string().as_bytes())?;
        }
        let ending = match block.ending {
            crate::gcode::LineEnding::None => b"\n".as_slice(),
            e => e.as_bytes(),
        };
        let text = if self.numbered == Some(false) {
            text.trim_start()
        } else {
            text
        };
        out.write_all(text.as_bytes())?;
        out.write_all(ending)?;
        Ok(())
    }
}

/// Decimals of a pole written for a rewritten `CP` (and of the program's
/// pole restored after it): 1e-6 mm.
const POLE_DECIMALS: u8 = 6;

/// `v` signed, with at most [`POLE_DECIMALS`] decimals and no trailing zeros.
fn signed_short(v: f64) -> String {
    let s = signed_number(v, POLE_DECIMALS);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    s.to_string()
}

/// A `CC` block setting the pole at `p` in the plane's letters, with a
/// `; volcomp: …` note.
fn pole_block(letters: [&str; 3], p: &[f64], note: &str) -> String {
    format!(
        " CC {}{} {}{} ; volcomp: {note}",
        letters[0],
        signed_short(p[0]),
        letters[1],
        signed_short(p[1]),
    )
}

/// The letters of the plane's first and second axes and its normal.
fn plane_letters(plane: crate::gcode::motion::Plane) -> [&'static str; 3] {
    match plane {
        crate::gcode::motion::Plane::XY => ["X", "Y", "Z"],
        crate::gcode::motion::Plane::ZX => ["Z", "X", "Y"],
        crate::gcode::motion::Plane::YZ => ["Y", "Z", "X"],
    }
}

/// The point nearest `c` (plane coordinates) equidistant from `s` and `e`:
/// on their bisector (`c` when they coincide).
fn equidistant_pole(c: [f64; 3], s: [f64; 3], e: [f64; 3]) -> [f64; 2] {
    on_bisector(s, e)
        .map(|(m, n)| {
            let t = (c[0] - m[0]) * n[0] + (c[1] - m[1]) * n[1];
            [m[0] + t * n[0], m[1] + t * n[1]]
        })
        .unwrap_or([c[0], c[1]])
}

/// The midpoint of `s`–`e` and the unit normal of their bisector, in the
/// plane; `None` when they coincide.
fn on_bisector(s: [f64; 3], e: [f64; 3]) -> Option<([f64; 2], [f64; 2])> {
    let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
    let len = dx.hypot(dy);
    (len >= 1e-9).then(|| {
        (
            [(s[0] + e[0]) / 2.0, (s[1] + e[1]) / 2.0],
            [-dy / len, dx / len],
        )
    })
}

/// The centre of the circle through `s`, `m` and `e` (in the plane): the
/// pole of a `CP` piece that passes through the compensated path's point
/// `m` at its middle as well as through its corrected ends, so that the
/// written arc follows the compensator's interpolated correction (a circle
/// through the ends about the pole moved by the mean correction departs
/// from it in radius by half the difference of the end corrections). Where
/// the three points give no circle, the point equidistant from `s` and
/// `e` nearest `guess`.
fn pole_through(guess: [f64; 3], s: [f64; 3], m: [f64; 3], e: [f64; 3]) -> [f64; 2] {
    let Some((mid, n)) = on_bisector(s, e) else {
        return [guess[0], guess[1]];
    };
    // On the bisector, q = mid + t·n with |q − s| = |q − m|.
    let dm = [m[0] - s[0], m[1] - s[1]];
    let denominator = 2.0 * (n[0] * dm[0] + n[1] * dm[1]);
    let to = |p: [f64; 3]| (mid[0] - p[0]).powi(2) + (mid[1] - p[1]).powi(2);
    let t = (to(m) - to(s)) / denominator;
    let q = [mid[0] + t * n[0], mid[1] + t * n[1]];
    // A pole farther from the guess than the chord is long would be a
    // near-collinear fit: keep the equidistant point there.
    let chord = (e[0] - s[0]).hypot(e[1] - s[1]);
    if t.is_finite() && (q[0] - guess[0]).hypot(q[1] - guess[1]) <= chord {
        q
    } else {
        equidistant_pole(guess, s, e)
    }
}

/// Edits removing the tokens named `names` (after the first), each with
/// the blanks before it (only the token where a comment or `~` lies between).
fn removals(
    block: &Block,
    parsed: &KlBlock,
    names: &[&str],
) -> Vec<(std::ops::Range<usize>, String)> {
    let mut out = Vec::new();
    for (k, t) in parsed.tokens.iter().enumerate().skip(1) {
        if !names.contains(&t.address.as_str()) {
            continue;
        }
        let from = parsed.tokens[k - 1].span.end;
        let gap = &block.raw[from..t.span.start];
        let range = if gap.iter().all(|b| b.is_ascii_whitespace()) {
            from..t.span.end
        } else {
            t.span.clone()
        };
        out.push((range, String::new()));
    }
    out
}

/// A feed as the shortest decimal that reads back the same (at most 4 decimals).
fn trim_number(v: f64) -> String {
    let s = format!("{v:.4}");
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s.is_empty() || s == "-" {
        "0".into()
    } else {
        s.to_string()
    }
}

/// The stamp of a compensated Klartext program, inserted as `;` blocks
/// after the `BEGIN PGM` block, the blocks after it renumbered so that the
/// numbers stay consecutive: the Heidenhain mode of
/// [`crate::stamp::StampWriter`] (`with_dialect`), which hands it the
/// bytes and its writer.
pub(crate) struct KlartextStamp {
    stamp: Vec<String>,
    pending: Vec<u8>,
    /// Blocks inserted so far (added to every later block number).
    inserted: u64,
    done: bool,
}

impl KlartextStamp {
    /// The lines of `stamp_text` (one stamp line each, LinuxCNC's `( … )`
    /// form) to be written as `N ; …` blocks after `BEGIN PGM`.
    pub(crate) fn new(stamp_text: &str) -> Self {
        let stamp = stamp_text
            .lines()
            .map(|l| {
                let l = l.trim();
                let l = l.strip_prefix('(').unwrap_or(l);
                let l = l.strip_suffix(')').unwrap_or(l);
                l.to_string()
            })
            .filter(|l| !l.is_empty())
            .collect();
        KlartextStamp {
            stamp,
            pending: Vec::new(),
            inserted: 0,
            done: false,
        }
    }

    fn line(&mut self, inner: &mut dyn Write, line: &[u8]) -> std::io::Result<()> {
        let digits = line.iter().take_while(|b| b.is_ascii_digit()).count();
        let number = std::str::from_utf8(&line[..digits])
            .ok()
            .and_then(|s| s.parse::<u64>().ok());
        match number {
            Some(n) if self.inserted > 0 => {
                inner.write_all((n + self.inserted).to_string().as_bytes())?;
                inner.write_all(&line[digits..])?;
            }
            _ => inner.write_all(line)?,
        }
        let rest = String::from_utf8_lossy(&line[digits..]);
        if !self.done
            && rest
                .trim_start()
                .to_ascii_uppercase()
                .starts_with("BEGIN PGM")
        {
            self.done = true;
            let eol = if line.ends_with(b"\r\n") {
                "\r\n"
            } else {
                "\n"
            };
            let stamp = std::mem::take(&mut self.stamp);
            for (k, s) in stamp.iter().enumerate() {
                match number {
                    Some(n) => write!(inner, "{} ; {s}{eol}", n + 1 + k as u64)?,
                    None => write!(inner, "; {s}{eol}")?,
                }
            }
            if number.is_some() {
                self.inserted = stamp.len() as u64;
            }
        }
        Ok(())
    }

    /// Pass `buf` on to `inner`, its complete lines renumbered.
    pub(crate) fn write(&mut self, inner: &mut dyn Write, buf: &[u8]) -> std::io::Result<()> {
        self.pending.extend_from_slice(buf);
        while let Some(k) = self.pending.iter().position(|&b| b == b'\n') {
            let line: Vec<u8> = self.pending.drain(..=k).collect();
            self.line(inner, &line)?;
        }
        Ok(())
    }

    /// Write what is held and flush.
    pub(crate) fn finish(&mut self, inner: &mut dyn Write) -> std::io::Result<()> {
        let rest = std::mem::take(&mut self.pending);
        if !rest.is_empty() {
            self.line(inner, &rest)?;
        }
        inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signed_numbers() {
        assert_eq!(signed_number(12.50006, 4), "+12.5001");
        assert_eq!(signed_number(-3.0, 0), "-3");
        assert_eq!(signed_number(-0.00001, 4), "+0.0000");
    }

    #[test]
    fn stamp_after_begin_pgm_renumbers() {
        let mut out = Vec::new();
        {
            let mut w = KlartextStamp::new("(volcomp-stamp a: 1)\n(volcomp-stamp b: 2)\n");
            w.write(
                &mut out,
                b"0 BEGIN PGM T MM\n1 L X+1 FMAX\n2 END PGM T MM\n",
            )
            .unwrap();
            w.finish(&mut out).unwrap();
        }
        assert_eq!(
            String::from_utf8(out).unwrap(),
            "0 BEGIN PGM T MM\n1 ; volcomp-stamp a: 1\n2 ; volcomp-stamp b: 2\n3 L X+1 FMAX\n4 END PGM T MM\n"
        );
    }
}
