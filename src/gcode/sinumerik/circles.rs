//! Circles the seam cannot carry as one arc (*Fundamentals*, "Circular
//! interpolation"; "Frames"): a circle in the working plane of a frame that
//! tilts it out of G17/G18/G19 (`ROT`/`AROT` about an axis in the plane, a
//! `CYCLE800` plane, a `MIRROR`), which the control runs in that plane, and
//! a `CIP` circle through three points that are not in a plane parallel to
//! the working plane (a circle in space). The machine-state layer's arcs lie
//! in its G17/G18/G19 planes, so these are handed on as chords within
//! [`CHORD_TOLERANCE_MM`] (0.5 µm, the Heidenhain front's tolerance for its
//! tilted-plane arcs, with its chord code
//! [`crate::gcode::heidenhain::geometry::arc_chords`]), as flat `G1` pieces
//! in program coordinates: the block itself becomes the first (its other
//! words with it), the others follow it, `; volcomp: line N` each.
use crate::axes::Axis;
use crate::gcode::error::GcodeError;
use crate::gcode::heidenhain::geometry::{arc_chords, cross, dot};
use crate::gcode::heidenhain::machine::{CHORD_TOLERANCE_MM, radius_centre};
use crate::gcode::machine::interpret::Interpreter;

use super::orientation::{
    HandedEnd, ORIENTATION_TOLERANCE_RAD, Pieces, angle_between, great_circle, great_circle_pieces,
    rotary_axes,
};
use super::{LineRun, Out, SinumerikFront, word};
use crate::gcode::Branch;

impl SinumerikFront {
    /// The circle of this block (centre form after `arc`: `G2`/`G3` with
    /// `I J K` increments from `start` or `CR=`, `P` for `TURN=`), in the
    /// working plane of the program coordinates, as chords.
    #[inline(never)]
    pub(super) fn circle_as_chords(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        interpreter: &Interpreter,
        start: [f64; 3],
    ) -> Result<(), GcodeError> {
        let ([iu, iv, iw], _, sense, incremental) = self.arc_context(out, interpreter);
        let Some(cw) = sense else {
            return Ok(());
        };
        let end = block_end(out, start, incremental);
        let find = |letter: u8| out.words.iter().rev().find(|w| w.letter == letter);
        let s = [start[iu], start[iv], start[iw]];
        let e = [end[iu], end[iv], end[iw]];
        let centre = match find(b'R') {
            Some(r) => radius_centre(s, e, r.value, cw).ok_or_else(|| {
                self.refused(
                    line,
                    format!(
                        "CR={}: no circle of that radius joins the start and the end",
                        r.value
                    ),
                    r.start,
                    r.end,
                )
            })?,
            None => {
                let c = |k: usize| find(b"IJK"[k]).map_or(0.0, |w| w.value);
                [s[0] + c(iu), s[1] + c(iv)]
            }
        };
        let turns = find(b'P').map_or(0, |w| (w.value - 1.0).max(0.0) as u32);
        let points: Vec<[f64; 3]> = arc_chords(centre, s, e, cw, turns, CHORD_TOLERANCE_MM)
            .into_iter()
            .map(|p| {
                let mut q = [0.0; 3];
                q[iu] = p[0];
                q[iv] = p[1];
                q[iw] = p[2];
                q
            })
            .collect();
        self.hand_on_chords(line, out, interpreter, start, &points, incremental)
    }

    /// `CIP` through `start`, `inter` and `end` (program coordinates) not in
    /// a plane parallel to the working plane: the circle through the three
    /// points, from the start through the intermediate point to the end,
    /// as chords. `None` when the points lie on one line.
    pub(super) fn space_circle_as_chords(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        interpreter: &Interpreter,
        [start, inter, end]: [[f64; 3]; 3],
        incremental: bool,
    ) -> Result<Option<()>, GcodeError> {
        let Some((centre, normal)) = space_circle(start, inter, end) else {
            return Ok(None);
        };
        // A right-handed frame (e1, e2, normal) about the centre: the
        // circle runs counter-clockwise in it.
        let e1 = unit(sub(start, centre));
        let e2 = cross(normal, e1);
        let local = |p: [f64; 3]| {
            let d = sub(p, centre);
            [dot(d, e1), dot(d, e2), dot(d, normal)]
        };
        let points: Vec<[f64; 3]> = arc_chords(
            [0.0, 0.0],
            local(start),
            local(end),
            false,
            0,
            CHORD_TOLERANCE_MM,
        )
        .into_iter()
        .map(|p| [0, 1, 2].map(|k| centre[k] + p[0] * e1[k] + p[1] * e2[k] + p[2] * normal[k]))
        .collect();
        self.hand_on_chords(line, out, interpreter, start, &points, incremental)?;
        self.space_arc = Some((centre, normal));
        Ok(Some(()))
    }

    /// Hand the block on as straight pieces through `points` (program
    /// coordinates, the last the block's end, evenly spaced along the
    /// path): the block itself, its circle words dropped and `G1` in place
    /// of its circle, ends at the first; the others are queued flat
    /// ([`Self::hand_on_pieces`]). A circle that also turns the tool
    /// (under `TRAORI`) turns it as the control does
    /// ([`Self::circle_turn`]). A circle given by `G2`/`G3` stays the modal
    /// motion for the blocks after it (the next motion block without a
    /// motion word gets it back, flat).
    pub(super) fn hand_on_chords(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        interpreter: &Interpreter,
        start: [f64; 3],
        points: &[[f64; 3]],
        incremental: bool,
    ) -> Result<(), GcodeError> {
        let ends = self.circle_turn(line, out, interpreter, start, points, incremental)?;
        // The orientation is handed on with the pieces (not split again).
        let form = self
            .turn_end
            .take()
            .and_then(|e| self.orientation_form(out, e.at));
        // The block: its circle's words go, G1 to the first point.
        let modal_arc = matches!(
            interpreter.modal().motion,
            crate::gcode::machine::modal::MotionMode::ArcCw
                | crate::gcode::machine::modal::MotionMode::ArcCcw
        );
        let mut arc_code = modal_arc.then(|| {
            if interpreter.modal().motion == crate::gcode::machine::modal::MotionMode::ArcCw {
                2.0
            } else {
                3.0
            }
        });
        let mut has_motion = false;
        for (i, w) in out.words.iter_mut().enumerate() {
            if w.letter == b'G' && matches!(w.value as i64, 2 | 3) && w.value.fract() == 0.0 {
                if !out.synthetic.contains(&i) {
                    arc_code = Some(w.value);
                }
                w.value = 1.0;
                out.substituted.push(i);
                has_motion = true;
            } else if w.letter == b'G' && matches!(w.value as i64, 0 | 1) {
                has_motion = true;
            }
        }
        retain_words(out, |w| {
            !matches!(w.letter, b'I' | b'J' | b'K' | b'R' | b'P')
        });
        if !has_motion {
            out.synthetic.push(out.words.len());
            out.words.push(word(b'G', 1.0, 0, 0, 0, false, false));
        }
        // The control's modal motion after the block is still the circle
        // (`CIP`/`CT` stay modal in the front itself).
        self.restore_arc = if self.arc_form.is_none() {
            arc_code
        } else {
            None
        };
        self.hand_on_pieces(
            line,
            out,
            interpreter,
            Pieces {
                start,
                ends: &ends,
                form: form.as_ref(),
                unit_mm: 1.0,
            },
        )
    }

    /// The piece ends of a circle through `points` (evenly spaced along
    /// the path, the last its end) and how its tool turns: not at all (the
    /// joints stay); under `TRAORI` with rotary axis words, or with an
    /// orientation under `ORIMKS`/`ORIAXES`, the rotary axes linearly in the
    /// path; with an orientation under `ORIWKS` + `ORIVECT` on the great
    /// circle from the start's tool axis to the end's, the angle
    /// proportional to the path (*Job planning*, "Orientation axis
    /// reference (ORIWKS, ORIMKS)", as for straight blocks), each chord
    /// split further where the linear joints would leave the great circle
    /// ([`super::orientation::great_circle_pieces`]; a piece end inside a
    /// chord lies on the chord). A circle that turns the tool without
    /// `TRAORI` is refused (its rotary words would be machine joints).
    fn circle_turn(
        &self,
        line: &LineRun,
        out: &Out,
        interpreter: &Interpreter,
        start: [f64; 3],
        points: &[[f64; 3]],
        incremental: bool,
    ) -> Result<Vec<HandedEnd>, GcodeError> {
        let origin = interpreter.origin();
        let j0 = interpreter.position();
        let rotary = rotary_axes(interpreter);
        let mut tool_words: Vec<_> = out
            .words
            .iter()
            .filter(|w| {
                super::orientation::word_name(w.letter).is_some()
                    || Axis::from_letter(w.letter as char).is_some_and(|a| a.is_rotary())
            })
            .collect();
        tool_words.sort_by_key(|w| w.start);
        let still = |points: &[[f64; 3]]| {
            let joints = origin.to_program(&j0);
            points
                .iter()
                .map(|&tip| HandedEnd {
                    tip,
                    joints,
                    axis: [0.0, 0.0, 1.0],
                })
                .collect()
        };
        let Some(w) = tool_words.first() else {
            return Ok(still(points));
        };
        let at = (w.start, w.end.max(w.start + 1).min(line.raw.len()));
        if !self.traori {
            return Err(self.feature(
                line,
                "a circle in a tilted plane or in space that also turns the tool without TRAORI",
                at.0,
                at.1,
            ));
        }
        let Some(solver) = self.orientation.clone() else {
            return Err(self.feature(
                line,
                "a circle that also turns the tool without the machine (give --machine: the orientation comes from its chain)",
                at.0,
                at.1,
            ));
        };
        let n = points.len();
        let chord = |k: usize| if k == 0 { start } else { points[k - 1] };
        match self.turn_end {
            Some(end) if self.great_circle_mode() => {
                let v0 = unit(solver.axis_of(&j0));
                let v1 = end.axis;
                self.refuse_half_turn(line, angle_between(v0, v1), end.at)?;
                let mut ends = Vec::new();
                let mut ja = j0;
                for k in 0..n {
                    let (ta, tb) = (k as f64 / n as f64, (k + 1) as f64 / n as f64);
                    let (va, vb) = (great_circle(v0, v1, ta), great_circle(v0, v1, tb));
                    let (a, b) = (chord(k), points[k]);
                    let jb = solver
                        .joints_for_axis(vb, Branch::Nearest, &ja)
                        .ok_or_else(|| self.unreachable_circle(line, end.at))?;
                    let (pieces, _capped) = great_circle_pieces(
                        solver.as_ref(),
                        &rotary,
                        &ja,
                        &jb,
                        [va, vb],
                        ORIENTATION_TOLERANCE_RAD,
                    )
                    .ok_or_else(|| self.unreachable_circle(line, end.at))?;
                    for p in &pieces {
                        ends.push(HandedEnd {
                            tip: [0, 1, 2].map(|i| a[i] + p.t * (b[i] - a[i])),
                            joints: origin.to_program(&p.joints),
                            axis: great_circle(v0, v1, ta + p.t * (tb - ta)),
                        });
                    }
                    ja = pieces.last().map_or(jb, |p| p.joints);
                }
                Ok(ends)
            }
            _ => {
                // The rotary axes linearly in the path.
                let j1 = match self.turn_end {
                    Some(end) => end.joints,
                    None => {
                        let mut program = origin.to_program(&j0);
                        for w in &tool_words {
                            if let Some(r) = Axis::from_letter(w.letter as char) {
                                let before = program.get(r);
                                program.set(
                                    r,
                                    if incremental {
                                        before + w.value
                                    } else {
                                        w.value
                                    },
                                );
                            }
                        }
                        origin.to_machine(&program)
                    }
                };
                Ok((0..n)
                    .map(|k| {
                        let t = (k + 1) as f64 / n as f64;
                        let mut j = j0;
                        for &r in &rotary {
                            j.set(r, j0.get(r) + t * (j1.get(r) - j0.get(r)));
                        }
                        HandedEnd {
                            tip: points[k],
                            joints: origin.to_program(&j),
                            axis: solver.axis_of(&j),
                        }
                    })
                    .collect())
            }
        }
    }
}

/// The block's end in program coordinates: its X Y Z words (absolute, or
/// increments from `start`), `start` where it has none.
pub(super) fn block_end(out: &Out, start: [f64; 3], incremental: bool) -> [f64; 3] {
    let mut end = start;
    for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
        if let Some(w) = out.words.iter().rev().find(|w| w.letter == letter) {
            end[k] = if incremental {
                start[k] + w.value
            } else {
                w.value
            };
        }
    }
    end
}

/// Keep the words `keep` says, the index lists following them.
pub(super) fn retain_words(
    out: &mut Out,
    keep: impl Fn(&crate::gcode::syntax::block::Word) -> bool,
) {
    let mut at = vec![None; out.words.len()];
    let mut n = 0;
    for (i, w) in out.words.iter().enumerate() {
        if keep(w) {
            at[i] = Some(n);
            n += 1;
        }
    }
    out.words.retain(|w| keep(w));
    for list in [
        &mut out.absolute,
        &mut out.relative,
        &mut out.substituted,
        &mut out.synthetic,
    ] {
        *list = list.iter().filter_map(|&i| at[i]).collect();
    }
}

/// The centre of the circle through `a`, `b`, `c` and its unit normal, the
/// circle running counter-clockwise about it from `a` through `b` to `c`;
/// `None` when the points lie on one line.
pub(crate) fn space_circle(a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> Option<([f64; 3], [f64; 3])> {
    let (ab, ac) = (sub(b, a), sub(c, a));
    let n = cross(ab, ac);
    let nn = dot(n, n);
    let size = dot(ab, ab).max(dot(ac, ac));
    if !(nn > 1e-18 * size * size) || size < 1e-18 {
        return None;
    }
    // a + (|ac|² (n × ab) + |ab|² (ac × n)) / (2 |n|²)
    let (u, v) = (cross(n, ab), cross(ac, n));
    let (lab, lac) = (dot(ab, ab), dot(ac, ac));
    let centre = [0, 1, 2].map(|k| a[k] + (lac * u[k] + lab * v[k]) / (2.0 * nn));
    Some((centre, unit(n)))
}

/// The unit tangent at `p` of the circle about `centre` running
/// counter-clockwise about the unit `normal`: `normal × (p − centre)`.
pub(super) fn space_tangent(centre: [f64; 3], normal: [f64; 3], p: [f64; 3]) -> [f64; 3] {
    unit(cross(normal, sub(p, centre)))
}

/// `CT` in space: the point half way along the circle that leaves `p`
/// along the unit `tangent` and reaches `e` (it lies in the plane of the
/// tangent and the chord; its centre is `p + s·u`, `u` the unit square to
/// the tangent towards `e`, `s = |e − p|² / (2 (e − p)·u)`); `None` when
/// `e` lies on the tangent's line.
pub(super) fn tangent_circle_midpoint(
    p: [f64; 3],
    tangent: [f64; 3],
    e: [f64; 3],
) -> Option<[f64; 3]> {
    let d = sub(e, p);
    let dd = dot(d, d);
    let n = cross(tangent, d);
    if !(dot(n, n).sqrt() > 1e-9 * dd.sqrt().max(1e-9)) {
        return None;
    }
    let n = unit(n);
    let u = cross(n, tangent);
    let s = dd / (2.0 * dot(d, u));
    let c = [0, 1, 2].map(|k| p[k] + s * u[k]);
    // Counter-clockwise about n from p to e: the angle, then half of it.
    let (rp, re) = (sub(p, c), sub(e, c));
    let mut sweep = dot(n, cross(rp, re)).atan2(dot(rp, re));
    if sweep <= 0.0 {
        sweep += std::f64::consts::TAU;
    }
    let (sh, ch) = (0.5 * sweep).sin_cos();
    let w = cross(n, rp);
    Some([0, 1, 2].map(|k| c[k] + ch * rp[k] + sh * w[k]))
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = dot(v, v).sqrt();
    v.map(|c| c / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Three points (at 0°, 90° and 200°) of a circle of radius 10 about
    /// (1, 2, 3) in a tilted plane: its centre and normal are found again;
    /// the points the other way round flip the normal.
    #[test]
    fn the_circle_through_three_points_in_space() {
        let c = [1.0, 2.0, 3.0];
        let r2 = 0.5f64.sqrt();
        let (e1, e2) = ([r2, -r2, 0.0], [0.5, 0.5, r2]);
        let at = |deg: f64| {
            let (s, co) = deg.to_radians().sin_cos();
            [0, 1, 2].map(|k| c[k] + 10.0 * (co * e1[k] + s * e2[k]))
        };
        let (centre, n) = space_circle(at(0.0), at(90.0), at(200.0)).unwrap();
        let want_n = cross(e1, e2);
        for k in 0..3 {
            assert!((centre[k] - c[k]).abs() < 1e-9, "{centre:?}");
            assert!((n[k] - want_n[k]).abs() < 1e-9, "{n:?}");
        }
        // The other way round: the normal flips.
        let (_, back) = space_circle(at(200.0), at(90.0), at(0.0)).unwrap();
        assert!((back[2] + want_n[2]).abs() < 1e-9);
        assert!(space_circle(at(0.0), at(0.0), at(90.0)).is_none());
    }

    /// `CT` in space: leaving (10, 0, 0) along +Y towards (0, 10, 0) is
    /// the quarter circle about the origin in z = 0 (half way at 45°);
    /// leaving it along +Z towards (0, 0, 10)... towards (−10, 0, 0) along
    /// +Z is the half circle about the origin in y = 0, through (0, 0, 10).
    #[test]
    fn a_tangent_circle_in_space() {
        let m =
            tangent_circle_midpoint([10.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 10.0, 0.0]).unwrap();
        let h = 10.0 * 0.5f64.sqrt();
        assert!((m[0] - h).abs() < 1e-12 && (m[1] - h).abs() < 1e-12 && m[2].abs() < 1e-12);
        let m =
            tangent_circle_midpoint([10.0, 0.0, 0.0], [0.0, 0.0, 1.0], [-10.0, 0.0, 0.0]).unwrap();
        assert!(
            m[0].abs() < 1e-9 && m[1].abs() < 1e-12 && (m[2] - 10.0).abs() < 1e-9,
            "{m:?}"
        );
        assert!(tangent_circle_midpoint([0.0; 3], [1.0, 0.0, 0.0], [5.0, 0.0, 0.0]).is_none());
        // The tangent of a circle about Z at (10, 0, 0) is +Y.
        let t = space_tangent([0.0; 3], [0.0, 0.0, 1.0], [10.0, 0.0, 0.0]);
        assert!((t[1] - 1.0).abs() < 1e-12);
    }
}
