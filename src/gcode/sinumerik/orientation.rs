//! The control's orientation interpolation under `TRAORI` (*Job planning*,
//! "Three, four and five axis transformation (TRAORI)": "Orientation axis
//! reference (ORIWKS, ORIMKS)" and the G group 51, `ORIAXES`/`ORIVECT`):
//! with an orientation given in the workpiece frame (a vector `A3 B3 C3` or
//! angles `A2 B2 C2`) under `ORIWKS` and `ORIVECT` (the reset settings) the
//! tool direction turns on the great circle from the block's start
//! orientation to its end one, the angle proportional to the path, while the
//! tip moves on its straight line. volcomp's machine-state layer moves the
//! rotary joints linearly between block ends (the control's `ORIAXES` /
//! `ORIMKS` path), so such a block is split where the two part: its pieces'
//! ends lie on the great circle (each solved on the machine's chain, the
//! nearest branch from the piece before), and between them the linear joints
//! stay within [`ORIENTATION_TOLERANCE_RAD`] of it.
//!
//! Pure functions over the [`OrientationSolver`]; the front hands the pieces
//! on as blocks.
use crate::axes::{Axes, Axis};
use crate::gcode::error::GcodeError;
use crate::gcode::machine::interpret::Interpreter;
use crate::gcode::{Branch, OrientationSolver};

use super::{LineRun, ORIENTATION_ANGLE_LETTERS, ORIENTATION_RPY_LETTERS, Out, SinumerikFront};

/// Largest angle (rad) between the tool axis of the joints volcomp
/// interpolates linearly inside a piece and the great circle the control
/// turns on, at the quarter points of every piece: 0.1 mrad (0.0057°). At
/// the tip nothing differs (both paths move it on the programmed line); the
/// linear joints differ by at most this angle times the tip's distance from
/// the rotary axes (20 µm at 200 mm), where error tables change by far less
/// than a nanometre.
pub(crate) const ORIENTATION_TOLERANCE_RAD: f64 = 1e-4;

/// The pole: where the tool axis lies within this angle (rad, 1°) of a
/// rotary axis' own line, that axis hardly steers it and the great circle
/// may ask it to turn by any amount at once. The control interpolates the
/// rotary axes there rather than the vector (the pole handling its machine
/// data `$MC_TRAFO5_POLE_LIMIT` sets; the machine maker's value is not
/// known offline: volcomp's reading is 1°): a piece that starts or ends
/// there is not split further, the joints move linearly across it.
pub(crate) const POLE_LIMIT_RAD: f64 = 0.017_453_292_519_943_295;

/// Halvings of one block at most: 2^10 = 1024 pieces (a block that needs
/// more turns its tool by a joint move near a singular pose; the last
/// halving is taken as it is and counted by the caller).
const MAX_DEPTH: u32 = 10;

/// The angle (rad) between two directions (any length, not zero).
pub(crate) fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    let c = cross(a, b);
    norm(c).atan2(dot(a, b))
}

/// The direction a fraction `t` of the way from `v0` to `v1` along their
/// great circle (both unit; not opposite).
pub(crate) fn great_circle(v0: [f64; 3], v1: [f64; 3], t: f64) -> [f64; 3] {
    let theta = angle_between(v0, v1);
    if theta < 1e-12 {
        return v0;
    }
    let s = theta.sin();
    let (a, b) = (((1.0 - t) * theta).sin() / s, (t * theta).sin() / s);
    let v = [0, 1, 2].map(|k| a * v0[k] + b * v1[k]);
    let n = norm(v);
    v.map(|c| c / n)
}

/// One end of a piece: its fraction of the block and its joints.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct PieceEnd {
    /// Fraction of the block (0 at its start, 1 at its end).
    pub t: f64,
    /// The machine's joints there (only the rotary ones differ from the
    /// start's; machine coordinates).
    pub joints: Axes,
}

/// The pieces of a block whose tool turns on the great circle from `v0`
/// (the tool axis at `start`, unit, workpiece frame) to `v1` (unit): their
/// ends in order, the last at `t = 1`, each solved on `solver` on the branch
/// nearest the end before. One piece (ending at `end`, the joints the block
/// was solved to) when the linear joints from `start` to `end` stay within
/// `tolerance` (rad) of the great circle. `None` when a direction on the way
/// cannot be reached within the rotary travel. The second value says whether
/// a piece was left at the halving limit.
pub(crate) fn great_circle_pieces(
    solver: &dyn OrientationSolver,
    rotary: &[Axis],
    start: &Axes,
    end: &Axes,
    v: [[f64; 3]; 2],
    tolerance: f64,
) -> Option<(Vec<PieceEnd>, bool)> {
    let [v0, v1] = v;
    let end = *end;
    let mut out = Vec::new();
    let mut capped = false;
    let first = PieceEnd {
        t: 0.0,
        joints: *start,
    };
    let last = PieceEnd {
        t: 1.0,
        joints: end,
    };
    let geometry = Geometry {
        solver,
        rotary,
        v0,
        v1,
        tolerance,
    };
    geometry.refine(first, last, 0, &mut out, &mut capped)?;
    Some((out, capped))
}

/// The tool axis at `joints` is within [`POLE_LIMIT_RAD`] of a rotary
/// axis' line (turning that axis half a turn moves it by twice the angle
/// or less).
pub(crate) fn near_pole(solver: &dyn OrientationSolver, rotary: &[Axis], joints: &Axes) -> bool {
    let axis = solver.axis_of(joints);
    rotary.iter().any(|&r| {
        let mut turned = *joints;
        turned.set(r, joints.get(r) + 180.0);
        angle_between(axis, solver.axis_of(&turned)) <= 2.0 * POLE_LIMIT_RAD
    })
}

struct Geometry<'a> {
    solver: &'a dyn OrientationSolver,
    rotary: &'a [Axis],
    v0: [f64; 3],
    v1: [f64; 3],
    tolerance: f64,
}

impl Geometry<'_> {
    /// The joints a fraction `s` of the way from `a` to `b` (rotary joints
    /// linear, as the machine-state layer moves them).
    fn between(&self, a: &Axes, b: &Axes, s: f64) -> Axes {
        let mut j = *a;
        for &r in self.rotary {
            j.set(r, a.get(r) + s * (b.get(r) - a.get(r)));
        }
        j
    }

    /// The largest angle between the linear joints' tool axis and the
    /// great circle inside the piece `a → b` (at its quarter points).
    fn deviation(&self, a: &PieceEnd, b: &PieceEnd) -> f64 {
        [0.25, 0.5, 0.75]
            .into_iter()
            .map(|s| {
                let axis = self.solver.axis_of(&self.between(&a.joints, &b.joints, s));
                let t = a.t + s * (b.t - a.t);
                angle_between(axis, great_circle(self.v0, self.v1, t))
            })
            .fold(0.0, f64::max)
    }

    /// Push the ends of the pieces from `a` to `b` (not `a`, `b` last;
    /// `b`'s joints solved again from the piece before, so that the pieces
    /// follow one branch as the control does).
    fn refine(
        &self,
        a: PieceEnd,
        b: PieceEnd,
        depth: u32,
        out: &mut Vec<PieceEnd>,
        capped: &mut bool,
    ) -> Option<()> {
        let b = if depth == 0 {
            b
        } else {
            PieceEnd {
                t: b.t,
                joints: self.solver.joints_for_axis(
                    great_circle(self.v0, self.v1, b.t),
                    Branch::Nearest,
                    &a.joints,
                )?,
            }
        };
        if near_pole(self.solver, self.rotary, &a.joints)
            || near_pole(self.solver, self.rotary, &b.joints)
            || self.deviation(&a, &b) <= self.tolerance
        {
            out.push(b);
            return Some(());
        }
        if depth >= MAX_DEPTH {
            *capped = true;
            out.push(b);
            return Some(());
        }
        let t = 0.5 * (a.t + b.t);
        let mid = PieceEnd {
            t,
            joints: self.solver.joints_for_axis(
                great_circle(self.v0, self.v1, t),
                Branch::Nearest,
                &a.joints,
            )?,
        };
        self.refine(a, mid, depth + 1, out, capped)?;
        let from = *out.last()?;
        self.refine(from, b, depth + 1, out, capped)
    }
}

/// The name a handed-on orientation word is written with (`A3=`, `B2=`…),
/// for the letters [`crate::gcode::ORIENTATION_VECTOR_LETTERS`],
/// [`ORIENTATION_ANGLE_LETTERS`] and [`ORIENTATION_RPY_LETTERS`].
pub(crate) fn word_name(letter: u8) -> Option<&'static str> {
    if let Some(k) = crate::gcode::ORIENTATION_VECTOR_LETTERS
        .iter()
        .position(|&l| l == letter)
    {
        return Some(["A3=", "B3=", "C3="][k]);
    }
    ORIENTATION_ANGLE_LETTERS
        .iter()
        .chain(&ORIENTATION_RPY_LETTERS)
        .position(|&l| l == letter)
        .map(|k| ["A2=", "B2=", "C2="][k % 3])
}

/// Where an orientation block ends: the rotary joints it was solved to
/// (machine coordinates) and the tool axis (unit, workpiece frame).
#[derive(Clone, Copy, Debug)]
pub(super) struct OrientationEnd {
    pub joints: Axes,
    pub axis: [f64; 3],
    /// The orientation words' span in the line.
    pub at: (usize, usize),
}

impl SinumerikFront {
    /// The control turns this block's tool on the great circle (`TRAORI`
    /// with `ORIWKS` and `ORIVECT`, the reset settings; under `ORIMKS` or
    /// `ORIAXES` it moves the rotary axes linearly, as volcomp does).
    pub(super) fn great_circle_mode(&self) -> bool {
        self.traori && !self.ori.machine && !self.ori.axes
    }

    /// Split a straight orientation block (`out`, from `start`, program
    /// coordinates, to its words' end) whose tool turns on the great circle
    /// where volcomp's linear joints would leave it by more than
    /// [`ORIENTATION_TOLERANCE_RAD`]: the block itself becomes the first
    /// piece (its other words with it), flat; the others are queued as flat
    /// blocks `X… Y… Z… A3=… B3=… C3=… ; volcomp: line N` (angles `A2= B2=`
    /// for a block given in angles), each with its joints on the machine's
    /// chain ([`Self::hand_on_pieces`]). A block that needs no split is left
    /// as it is.
    #[inline(never)]
    pub(super) fn split_on_great_circle(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        interpreter: &Interpreter,
        start: [f64; 3],
        end: OrientationEnd,
    ) -> Result<(), GcodeError> {
        let Some(solver) = self.orientation.clone() else {
            return Ok(());
        };
        let j0 = interpreter.position();
        let v0 = unit(solver.axis_of(&j0));
        let v1 = end.axis;
        let turn = angle_between(v0, v1);
        if turn < 1e-9 {
            return Ok(());
        }
        self.refuse_half_turn(line, turn, end.at)?;
        let rotary = rotary_axes(interpreter);
        let Some((pieces, _capped)) = great_circle_pieces(
            solver.as_ref(),
            &rotary,
            &j0,
            &end.joints,
            [v0, v1],
            ORIENTATION_TOLERANCE_RAD,
        ) else {
            return Err(self.unreachable_circle(line, end.at));
        };
        if pieces.len() < 2 {
            return Ok(());
        }
        // The block's end in program coordinates (mm).
        let incremental = out.incremental(self.incremental);
        let inch = out
            .words
            .iter()
            .rev()
            .find(|w| w.letter == b'G' && (w.value == 20.0 || w.value == 21.0))
            .map_or(
                interpreter.modal().units == crate::gcode::machine::modal::Units::Inch,
                |w| w.value == 20.0,
            );
        let unit_mm = if inch { 25.4 } else { 1.0 };
        let mut p1 = start;
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            if let Some(w) = out.words.iter().rev().find(|w| w.letter == letter) {
                p1[k] = if incremental {
                    start[k] + w.value * unit_mm
                } else {
                    w.value * unit_mm
                };
            }
        }
        let origin = interpreter.origin();
        let ends: Vec<HandedEnd> = pieces
            .iter()
            .map(|p| HandedEnd {
                tip: [0, 1, 2].map(|k| start[k] + p.t * (p1[k] - start[k])),
                joints: origin.to_program(&p.joints),
                axis: great_circle(v0, v1, p.t),
            })
            .collect();
        let form = self.orientation_form(out, end.at);
        self.hand_on_pieces(
            line,
            out,
            interpreter,
            Pieces {
                start,
                ends: &ends,
                form: form.as_ref(),
                unit_mm,
            },
        )
    }

    /// A turn of 180° in one block has no great circle.
    pub(super) fn refuse_half_turn(
        &self,
        line: &LineRun,
        turn: f64,
        at: (usize, usize),
    ) -> Result<(), GcodeError> {
        if turn > std::f64::consts::PI - 1e-6 {
            return Err(self.refused(
                line,
                "the tool turns by 180° in one block: under ORIVECT the great circle it turns on is not defined".into(),
                at.0,
                at.1,
            ));
        }
        Ok(())
    }

    /// The great circle passes a direction the machine cannot reach.
    pub(super) fn unreachable_circle(&self, line: &LineRun, at: (usize, usize)) -> GcodeError {
        self.refused(
            line,
            "the tool turns on a great circle through a direction the machine cannot reach within its rotary travel".into(),
            at.0,
            at.1,
        )
    }

    /// The orientation words of the block (a vector `A3= B3= C3=`, or angles
    /// `A2= B2= C2=` as `ORIEULER`/`ORIRPY` read them) at `at`; `None` when
    /// it has none (the tool turned by rotary axis words).
    pub(super) fn orientation_form(
        &self,
        out: &Out,
        at: (usize, usize),
    ) -> Option<OrientationForm> {
        let has = |letters: [u8; 3]| out.words.iter().any(|w| letters.contains(&w.letter));
        let (letters, angles) = if has(crate::gcode::ORIENTATION_VECTOR_LETTERS) {
            (crate::gcode::ORIENTATION_VECTOR_LETTERS, None)
        } else if has(ORIENTATION_RPY_LETTERS) || has(ORIENTATION_ANGLE_LETTERS) {
            if self.ori.rpy {
                (ORIENTATION_RPY_LETTERS, Some(true))
            } else {
                (ORIENTATION_ANGLE_LETTERS, Some(false))
            }
        } else {
            return None;
        };
        let c2 = out
            .words
            .iter()
            .find(|w| w.letter == letters[2])
            .map_or(0.0, |w| w.value);
        Some(OrientationForm {
            letters,
            angles,
            c2,
            at,
        })
    }

    /// Hand a block on as straight pieces through `ends` (the last the
    /// block's end; tips in program coordinates, mm, the block's start
    /// `start`): the block itself ends at the first (its axis, rotary and
    /// orientation words say it, flat); the others are queued as flat
    /// blocks `X… Y… Z… [A3=… B3=… C3=…] A… C… ; volcomp: line N`, in the
    /// block's `G90`/`G91` and units (`unit_mm` mm per program unit). The
    /// rotary joints are written for every rotary axis that moves or that
    /// the block names; orientation words (`form`) are the tool axis back
    /// through the block's frame.
    pub(super) fn hand_on_pieces(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        interpreter: &Interpreter,
        pieces: Pieces<'_>,
    ) -> Result<(), GcodeError> {
        let Pieces {
            start,
            ends,
            form,
            unit_mm,
        } = pieces;
        let Some(first) = ends.first() else {
            return Ok(());
        };
        let incremental = out.incremental(self.incremental);
        let j_base = interpreter.origin().to_program(&interpreter.position());
        let rotary: Vec<Axis> = rotary_axes(interpreter)
            .into_iter()
            .filter(|&r| {
                out.words.iter().any(|w| w.letter == r.letter() as u8)
                    || ends
                        .iter()
                        .any(|e| (e.joints.get(r) - j_base.get(r)).abs() > 1e-12)
            })
            .collect();
        let frame = self.combined_frame();
        let words_of = |axis: [f64; 3]| -> [f64; 3] {
            let Some(form) = form else {
                return [0.0; 3];
            };
            let m = &frame.inverse;
            let v = unit([0, 1, 2].map(|i| dot(m[i], axis)));
            match form.angles {
                Some(rpy) => super::direction_angles(rpy, v, form.c2),
                None => v,
            }
        };
        let skip_c2 = |k: usize| form.is_some_and(|f| f.angles.is_some() && k == 2 && f.c2 == 0.0);
        let moved: Vec<bool> = (0..3)
            .map(|k| ends.iter().any(|e| (e.tip[k] - start[k]).abs() > 1e-12))
            .collect();
        let delta = |now: f64, before: f64| if incremental { now - before } else { now };
        let mut previous = (first.tip, first.joints);
        for e in &ends[1..] {
            let mut piece = Out::new(0);
            piece.flat = true;
            for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
                if moved[k] {
                    piece.synthetic.push(piece.words.len());
                    piece.words.push(super::word(
                        letter,
                        delta(e.tip[k], previous.0[k]) / unit_mm,
                        0,
                        0,
                        4,
                        true,
                        false,
                    ));
                }
            }
            if let Some(form) = form {
                let v = words_of(e.axis);
                for (k, &letter) in form.letters.iter().enumerate() {
                    if skip_c2(k) {
                        continue;
                    }
                    piece.synthetic.push(piece.words.len());
                    piece
                        .words
                        .push(super::word(letter, v[k], 0, 0, 7, true, false));
                }
            }
            for &r in &rotary {
                // Machine-axis words are the piece's own text; with an
                // orientation the writer says the joints in its words.
                if form.is_none() {
                    piece.synthetic.push(piece.words.len());
                }
                piece.words.push(super::word(
                    r.letter() as u8,
                    delta(e.joints.get(r), previous.1.get(r)),
                    0,
                    0,
                    4,
                    true,
                    false,
                ));
            }
            previous = (e.tip, e.joints);
            if self.hand_on(line, &mut piece, line.raw, false)? {
                self.pending.push_back(std::mem::take(&mut self.block));
            }
        }
        // The block itself is the first piece: its axis, rotary and
        // orientation words say the first end.
        let anchor = out.words.iter().map(|w| w.end).max().unwrap_or(0);
        let at = form.map_or((anchor, anchor), |f| f.at);
        let mut added = Vec::new();
        for (k, letter) in [b'X', b'Y', b'Z'].into_iter().enumerate() {
            let value = delta(first.tip[k], start[k]) / unit_mm;
            match out.words.iter().rposition(|w| w.letter == letter) {
                Some(i) => {
                    out.words[i].value = value;
                    out.substituted.push(i);
                }
                None if moved[k] => {
                    added.push(super::word(letter, value, at.0, at.0, 4, true, false))
                }
                None => {}
            }
        }
        if let Some(form) = form {
            let v = words_of(first.axis);
            for (k, &letter) in form.letters.iter().enumerate() {
                match out.words.iter().position(|w| w.letter == letter) {
                    Some(i) => {
                        out.words[i].value = v[k];
                        out.substituted.push(i);
                    }
                    None if !skip_c2(k) => {
                        added.push(super::word(letter, v[k], at.1, at.1, 7, true, false))
                    }
                    None => {}
                }
            }
        }
        for &r in &rotary {
            let value = delta(first.joints.get(r), j_base.get(r));
            match out.words.iter().position(|w| w.letter == r.letter() as u8) {
                Some(i) => {
                    out.words[i].value = value;
                    if out.words[i].start != out.words[i].end {
                        out.substituted.push(i);
                    }
                }
                None => added.push(super::word(
                    r.letter() as u8,
                    value,
                    at.1,
                    at.1,
                    4,
                    true,
                    false,
                )),
            }
        }
        for w in added {
            out.synthetic.push(out.words.len());
            out.words.push(w);
        }
        out.flat = true;
        Ok(())
    }
}

/// A block's pieces for [`SinumerikFront::hand_on_pieces`]: the block's
/// start (program coordinates, mm), the piece ends (the last the block's
/// end), the orientation words they carry, mm per program unit.
#[derive(Clone, Copy, Debug)]
pub(super) struct Pieces<'a> {
    pub start: [f64; 3],
    pub ends: &'a [HandedEnd],
    pub form: Option<&'a OrientationForm>,
    pub unit_mm: f64,
}

/// One end of a piece handed on: the tool tip (program coordinates, mm),
/// the joints (program values) and the tool axis (unit, workpiece frame).
#[derive(Clone, Copy, Debug)]
pub(super) struct HandedEnd {
    pub tip: [f64; 3],
    pub joints: Axes,
    pub axis: [f64; 3],
}

/// How a block gives its orientation: the words its pieces carry.
#[derive(Clone, Copy, Debug)]
pub(super) struct OrientationForm {
    /// `A3 B3 C3`, or the angle letters (`A2 B2 C2`).
    letters: [u8; 3],
    /// Angles: `Some(true)` under `ORIRPY`, `Some(false)` Euler; `None` a vector.
    angles: Option<bool>,
    /// The block's `C2` (kept: it turns about the tool).
    c2: f64,
    /// The orientation words' span in the line.
    at: (usize, usize),
}

/// The interpreter's rotary axes.
pub(super) fn rotary_axes(interpreter: &Interpreter) -> Vec<Axis> {
    interpreter
        .options()
        .axes
        .iter()
        .filter(|a| a.is_rotary())
        .collect()
}

fn unit(v: [f64; 3]) -> [f64; 3] {
    let n = norm(v);
    v.map(|c| c / n)
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn norm(a: [f64; 3]) -> f64 {
    dot(a, a).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An A/C table-table: the tool axis (sin a sin c, sin a cos c, cos a).
    #[derive(Debug)]
    struct TiltTurn;

    impl OrientationSolver for TiltTurn {
        fn joints_for_axis(&self, axis: [f64; 3], _: Branch, previous: &Axes) -> Option<Axes> {
            let a = axis[2].clamp(-1.0, 1.0).acos().to_degrees();
            let c = if a.abs() < 1e-9 {
                previous.c
            } else {
                let c = axis[0].atan2(axis[1]).to_degrees();
                c + 360.0 * ((previous.c - c) / 360.0).round()
            };
            Some(Axes { a, c, ..*previous })
        }

        fn axis_of(&self, j: &Axes) -> [f64; 3] {
            let (sa, ca) = j.a.to_radians().sin_cos();
            let (sc, cc) = j.c.to_radians().sin_cos();
            [sa * sc, sa * cc, ca]
        }

        /// `Rz(−C)·Rx(−A)` (the table turns the part the other way).
        fn frame_of(&self, j: &Axes) -> [[f64; 3]; 3] {
            let (sa, ca) = j.a.to_radians().sin_cos();
            let (sc, cc) = j.c.to_radians().sin_cos();
            [
                [cc, sc * ca, sc * sa],
                [-sc, cc * ca, cc * sa],
                [0.0, -sa, ca],
            ]
        }

        fn swivel_order(&self) -> [Axis; 2] {
            [Axis::A, Axis::C]
        }
    }

    #[test]
    fn the_great_circle_turns_evenly() {
        let v = great_circle([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 1.0 / 3.0);
        let s = 30f64.to_radians();
        assert!((v[0] - s.cos()).abs() < 1e-12 && (v[1] - s.sin()).abs() < 1e-12);
        assert!(
            (angle_between([1.0, 0.0, 0.0], [1.0, 1.0, 0.0]) - 45f64.to_radians()).abs() < 1e-12
        );
    }

    /// A block turning the tool 60° about the non-principal axis
    /// (0, √3/2, −1/2) from A 30° C 0, i.e. from (0, 1/2, √3/2) to
    /// (√3/2, 1/4, √3/4) = A 64.3411° C 73.8979°; half way the great circle
    /// is at (1/2, √3/4, 3/4) = A 41.4096° C 49.1066° where the linear
    /// joints stand at A 47.17° C 36.95° (by hand: 7.7° off). The block is
    /// split; every piece end is on the circle and the pieces follow it
    /// within the tolerance.
    #[test]
    fn a_sixty_degree_turn_about_a_skew_axis_is_split_onto_the_great_circle() {
        let r3 = 3f64.sqrt();
        let v0 = [0.0, 0.5, r3 / 2.0];
        let v1 = [r3 / 2.0, 0.25, r3 / 4.0];
        assert!((angle_between(v0, v1) - 60f64.to_radians()).abs() < 1e-12);
        let mid = great_circle(v0, v1, 0.5);
        for (got, want) in mid.iter().zip([0.5, r3 / 4.0, 0.75]) {
            assert!((got - want).abs() < 1e-12, "{mid:?}");
        }
        let j = TiltTurn
            .joints_for_axis(mid, Branch::Nearest, &Axes::default())
            .unwrap();
        assert!(
            (j.a - 41.4096).abs() < 1e-4 && (j.c - 49.1066).abs() < 1e-4,
            "{j:?}"
        );
        let start = Axes {
            a: 30.0,
            ..Axes::default()
        };
        let rotary = [Axis::A, Axis::C];
        let end = TiltTurn
            .joints_for_axis(v1, Branch::Nearest, &start)
            .unwrap();
        let (pieces, capped) = great_circle_pieces(
            &TiltTurn,
            &rotary,
            &start,
            &end,
            [v0, v1],
            ORIENTATION_TOLERANCE_RAD,
        )
        .unwrap();
        assert!(!capped);
        assert!(pieces.len() > 4, "{}", pieces.len());
        assert_eq!(pieces.last().unwrap().t, 1.0);
        let g = Geometry {
            solver: &TiltTurn,
            rotary: &rotary,
            v0,
            v1,
            tolerance: ORIENTATION_TOLERANCE_RAD,
        };
        let mut a = PieceEnd {
            t: 0.0,
            joints: start,
        };
        for p in &pieces {
            let on = great_circle(v0, v1, p.t);
            assert!(angle_between(TiltTurn.axis_of(&p.joints), on) < 1e-9);
            assert!(g.deviation(&a, p) <= ORIENTATION_TOLERANCE_RAD);
            a = *p;
        }
        // Unsplit, the linear joints would leave the circle by far more.
        let whole = PieceEnd {
            t: 1.0,
            joints: TiltTurn
                .joints_for_axis(v1, Branch::Nearest, &start)
                .unwrap(),
        };
        let unsplit = g.deviation(
            &PieceEnd {
                t: 0.0,
                joints: start,
            },
            &whole,
        );
        assert!(unsplit > 50.0 * ORIENTATION_TOLERANCE_RAD, "{unsplit}");
    }

    /// From the pole (A 0: the table C does not steer the tool) the control
    /// moves the rotary axes, so the block is one piece.
    #[test]
    fn a_turn_from_the_pole_is_one_piece() {
        let r3 = 3f64.sqrt();
        let start = Axes::default();
        let v1 = [r3 / 2.0, 0.25, r3 / 4.0];
        let end = TiltTurn
            .joints_for_axis(v1, Branch::Nearest, &start)
            .unwrap();
        let rotary = [Axis::A, Axis::C];
        assert!(near_pole(&TiltTurn, &rotary, &start));
        assert!(!near_pole(&TiltTurn, &rotary, &end));
        let (pieces, capped) = great_circle_pieces(
            &TiltTurn,
            &rotary,
            &start,
            &end,
            [[0.0, 0.0, 1.0], v1],
            ORIENTATION_TOLERANCE_RAD,
        )
        .unwrap();
        assert_eq!((pieces.len(), capped), (1, false));
    }
}
