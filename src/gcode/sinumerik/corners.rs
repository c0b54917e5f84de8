//! Contour corners: `RND=`, `RNDM=`, `CHF=`, `CHR=` (and their feeds
//! `FRC=`, `FRCM=`), as Siemens' *Programming Manual Fundamentals* defines
//! them ("Chamfer, rounding (CHF, CHR, RND, RNDM, FRC, FRCM)": 840D/840Di sl
//! 11/2006 §4.22 pp. 193–194, 828D 07/2010 §9.15 p. 282, 840D sl 12/2019
//! p. 245, which the contour-definition pages pp. 218–220 point to):
//!
//! - the word is "written in the block with axis movements leading to the
//!   corner"; the control inserts the rounding (an arc tangent to both
//!   elements) or the chamfer (a straight line) after that block, between
//!   straight lines and circles "in any combination", in the working plane
//!   of `G17`–`G19`; `RNDM=` rounds every following corner until
//!   `RNDM=0`; `CHF=` is the chamfer's own length, `CHR=` its width "in the
//!   original direction of motion" (the figure: CHF = 2·cos α·CHR); with a
//!   radius and a chamfer in one block, only the radius is inserted;
//! - "no chamfer/rounding is inserted if more than three blocks in the
//!   connection are programmed that do not contain any information for
//!   traversing in the plane, or a plane change is carried out": volcomp
//!   holds the element and up to three blocks after it, and hands them on
//!   unchanged at the fourth or at a plane change;
//! - `FRC=` (this corner) and `FRCM=` (modal, `0` off) are the corner's
//!   feed; without them the corner runs at the feed of the block before it
//!   (the technology of the previous block: machine data 20201 bit 0 = 1,
//!   the 828D manual's recommended setting), and F comes back after it.
//!
//! The geometry is the Klartext corners' ([`crate::gcode::contour_corners`]).
//! The element with the word is handed on ending at the first tangent
//! point, written flat without the corner words; the corner follows as its
//! own flat block (`G2`/`G3 … I J` or `G1`), `; volcomp: line N`; the next
//! element starts at the second tangent point (its centre words, its
//! increments, a motion code or feed the corner changed are written flat).
//! So the output reads back to the same path and holds no corner words.
//!
//! What the manual leaves open is refused at a located line, naming it:
//! a value too large for the elements (the control "automatically reduces"
//! it, by a rule the manual does not give), a corner on the last motion
//! block, a rounding traversed in `G0`, elements that move out of the
//! plane or turn the tool, `CIP`/`CT`/`AR=`/`TURN=` circles, circles handed
//! on as chords, frames, offsets or `TRAORI` changed between the elements,
//! inch programs, `BSPLINE` sections.
//!
//! The look-ahead holds at most four blocks: the element is held (not yet
//! handed on); the blocks after it run on the interpreter from a copy of
//! its state taken before the element (so the next line reads as the
//! control reads it), and the copy is put back when the held blocks are
//! handed on in their final form.
use crate::gcode::contour_corners::{
    Chamfer, CornerError, Element, Inserted, chamfer_elements, round_elements,
};
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::language::Executed;
use crate::gcode::machine::interpret::Interpreter;
use crate::gcode::machine::modal::{MotionMode, Units};
use crate::gcode::syntax::block::{Block, LineEnding};

use super::{LastKind, LineRun, Out, SinumerikFront, word};

/// Blocks without a move in the plane that may come between two elements
/// (*Fundamentals*: "more than three blocks … no chamfer/rounding").
const MAX_BLOCKS_BETWEEN: usize = 3;

/// The corner words of one block (value, text span).
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct CornerWords {
    round: Option<(f64, (usize, usize))>,
    modal_round: Option<(f64, (usize, usize))>,
    chamfer: Option<(Chamfer, (usize, usize))>,
    feed: Option<(f64, (usize, usize))>,
    modal_feed: Option<(f64, (usize, usize))>,
}

impl CornerWords {
    /// Take the word `name` (`RND`, `RNDM`, `CHF`, `CHR`, `FRC`, `FRCM`).
    pub(super) fn set(&mut self, name: u8, value: f64, at: (usize, usize)) {
        match name {
            b'R' => self.round = Some((value, at)),
            b'M' => self.modal_round = Some((value, at)),
            b'F' => self.chamfer = Some((Chamfer::Length(value), at)),
            b'C' => self.chamfer = Some((Chamfer::Leg(value), at)),
            b'f' => self.feed = Some((value, at)),
            _ => self.modal_feed = Some((value, at)),
        }
    }

    pub(super) fn any(&self) -> bool {
        self.round.is_some()
            || self.modal_round.is_some()
            || self.chamfer.is_some()
            || self.feed.is_some()
            || self.modal_feed.is_some()
    }
}

/// What the block being read does to the corner machinery (set by
/// [`SinumerikFront::corner_block`], done by [`SinumerikFront::after_corner_block`]).
#[derive(Default)]
enum Disposition {
    /// Nothing: handed on as usual.
    #[default]
    Pass,
    /// Blocks were queued that come before it: it goes after them.
    After,
    /// It is an element with a corner at its end: held.
    Arm(Box<Pending>),
    /// A block between two elements: held.
    Between,
}

/// The SINUMERIK corner state.
#[derive(Default)]
pub(super) struct Corners {
    /// `RNDM=`: the modal radius.
    modal_radius: Option<f64>,
    /// `FRCM=`: the modal corner feed.
    modal_feed: Option<f64>,
    /// The element waiting for the next one.
    pending: Option<Box<Pending>>,
    disposition: Disposition,
}

impl Corners {
    /// Whether a block must pass through [`SinumerikFront::corner_block`].
    #[inline]
    pub(super) fn active(&self) -> bool {
        self.pending.is_some() || self.modal_radius.is_some()
    }

    /// Whether the block just handed on is the corner machinery's.
    #[inline]
    pub(super) fn busy(&self) -> bool {
        !matches!(self.disposition, Disposition::Pass)
    }

    /// Whether an element waits for the next one.
    #[inline]
    pub(super) fn waiting(&self) -> bool {
        self.pending.is_some()
    }
}

/// The corner asked at an element's end.
#[derive(Clone, Copy, Debug)]
enum Request {
    Round(f64),
    Chamfer(Chamfer),
}

/// One contour element in program coordinates.
#[derive(Clone, Copy, Debug)]
struct Ends {
    start: [f64; 3],
    end: [f64; 3],
    /// A circle's centre and sense (clockwise).
    arc: Option<([f64; 3], bool)>,
    /// The plane's axes (u, v, the normal), as `arc_context` gives them.
    idx: [usize; 3],
    incremental: bool,
    /// Its motion code, 0–3.
    motion: f64,
}

impl Ends {
    fn uv(&self, p: [f64; 3]) -> [f64; 2] {
        [p[self.idx[0]], p[self.idx[1]]]
    }

    /// As the element before the corner (`before`) or after it.
    fn element(&self, before: bool) -> Element {
        let other = self.uv(if before { self.start } else { self.end });
        match self.arc {
            Some((centre, clockwise)) => Element::Arc {
                centre: self.uv(centre),
                clockwise,
                other,
            },
            None => Element::Line { other },
        }
    }

    /// `p` with the plane coordinates `uv`.
    fn at(&self, uv: [f64; 2], p: [f64; 3]) -> [f64; 3] {
        let mut q = p;
        q[self.idx[0]] = uv[0];
        q[self.idx[1]] = uv[1];
        q
    }
}

/// An element held until the next one is read.
struct Pending {
    request: Request,
    /// The corner word's span in the element's line.
    at: (usize, usize),
    feed: Option<f64>,
    out: Out,
    raw: Vec<u8>,
    line: usize,
    file: usize,
    ends: Ends,
    /// The element as it was handed on.
    block: Option<(Block, Executed)>,
    /// Blocks after it without a move in the plane.
    between: Vec<(Block, Executed)>,
    /// The interpreter before the element (set when it is run ahead).
    before: Option<Interpreter>,
}

/// What [`SinumerikFront::corner_block`] needs to know of the block.
pub(super) struct BlockFacts {
    /// It has axis words or circle words.
    pub moves: bool,
    /// Its circle came from `CIP`, `CT`, `AR=` or `TURN=`.
    pub arc_words: bool,
    /// It changes frames, work offsets, `SUPA` or `TRAORI`.
    pub framed: bool,
    /// It turns the tool (orientation words).
    pub turned: bool,
    /// Where the block starts (program coordinates).
    pub start: [f64; 3],
}

impl SinumerikFront {
    fn corner_error(&self, p: &Pending, message: String) -> GcodeError {
        GcodeError::at(
            ErrorKind::DialectRefused(message),
            p.line,
            &p.raw,
            p.at.0,
            p.at.1,
        )
    }

    fn corner_feature(&self, line: &LineRun, what: String, at: (usize, usize)) -> GcodeError {
        self.feature(line, &what, at.0, at.1.max(at.0 + 1).min(line.raw.len()))
    }

    /// The corner words and state of the block being read (after its
    /// circle was worked out, before it is handed on): ends a waiting
    /// corner (the next element, a block between, a plane change) and arms
    /// a new one.
    #[inline(never)]
    #[cold]
    pub(super) fn corner_block(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        words: &CornerWords,
        facts: &BlockFacts,
        interpreter: &mut Interpreter,
    ) -> Result<(), GcodeError> {
        let mut values: Vec<(f64, (usize, usize), &str)> = Vec::new();
        if let Some((v, at)) = words.round {
            values.push((v, at, "RND= is a radius"));
        }
        if let Some((v, at)) = words.modal_round {
            values.push((v, at, "RNDM= is a radius"));
        }
        if let Some((v, at)) = words.modal_feed {
            values.push((v, at, "FRCM= is a feed"));
        }
        if let Some((c, at)) = words.chamfer {
            values.push(match c {
                Chamfer::Leg(v) => (v, at, "CHR= is a length"),
                Chamfer::Length(v) => (v, at, "CHF= is a length"),
            });
        }
        for (v, at, what) in values {
            if !(v >= 0.0) {
                return Err(self.refused(line, format!("{what} ≥ 0, not {v}"), at.0, at.1));
            }
        }
        if let Some((v, at)) = words.feed
            && !(v > 0.0)
        {
            return Err(self.refused(line, format!("FRC= is a feed > 0, not {v}"), at.0, at.1));
        }
        if let Some((v, _)) = words.modal_round {
            self.corners.modal_radius = (v > 0.0).then_some(v);
        }
        if let Some((v, _)) = words.modal_feed {
            self.corners.modal_feed = (v > 0.0).then_some(v);
        }
        // The corner words are never written back (the corners are).
        if words.any() {
            out.flat = true;
        }
        let (idx, plane, sense, incremental) = self.arc_context(out, interpreter);
        let plane_changed = plane != interpreter.modal().plane;
        let motion = out
            .words
            .iter()
            .rev()
            .find(|w| w.letter == b'G' && matches!(w.value as i64, 0..=3) && w.value.fract() == 0.0)
            .map(|w| w.value)
            .unwrap_or(match interpreter.modal().motion {
                MotionMode::Rapid => 0.0,
                MotionMode::ArcCw => 2.0,
                MotionMode::ArcCcw => 3.0,
                _ => 1.0,
            });
        let end = super::circles::block_end(out, facts.start, incremental);
        let moved = |k: usize| (end[k] - facts.start[k]).abs() > 1e-9;
        let in_plane = facts.moves && (sense.is_some() || moved(idx[0]) || moved(idx[1]));
        let mut start = facts.start;
        // This block as an element (worked out before a corner before it
        // changes its words).
        let mut element = None;
        if let Some(pending) = self.corners.pending.take() {
            if facts.framed {
                return Err(self.corner_feature(
                    line,
                    format!(
                        "a frame, work offset, SUPA or TRAORI change between the two elements of the corner at line {}",
                        pending.line
                    ),
                    (0, line.raw.len()),
                ));
            }
            if plane_changed {
                // "No chamfer/rounding is inserted if … a plane change".
                self.corner_unchanged(pending, interpreter);
            } else if !in_plane {
                if facts.moves {
                    let w = out.words.iter().find(|w| super::is_axis(w.letter)).copied();
                    let at = w.map_or((0, line.raw.len()), |w| (w.start, w.end));
                    return Err(self.corner_feature(
                        line,
                        format!(
                            "a move out of the working plane between the two elements of the corner at line {}",
                            pending.line
                        ),
                        at,
                    ));
                }
                let ends_program = out
                    .words
                    .iter()
                    .any(|w| w.letter == b'M' && matches!(w.value as i64, 2 | 30))
                    || self.returned;
                if ends_program {
                    return Err(self.corner_error(&pending, last_block_message(&pending)));
                }
                if words.round.is_some() || words.chamfer.is_some() {
                    let at = words.round.map(|w| w.1).or(words.chamfer.map(|w| w.1));
                    return Err(self.refused(
                        line,
                        "RND=/CHF=/CHR= belong to a block that moves to the corner".into(),
                        at.map_or(0, |a| a.0),
                        at.map_or(line.raw.len(), |a| a.1),
                    ));
                }
                self.corners.pending = Some(pending);
                self.corners.disposition = Disposition::Between;
                return Ok(());
            } else {
                let ends = self.corner_element(line, out, interpreter, facts, motion, end)?;
                start = self.corner_between(line, pending, out, ends, interpreter)?;
                element = Some(ends);
            }
        }
        // A corner at this block's end.
        let request = match (words.round, self.corners.modal_radius, words.chamfer) {
            (Some((r, _)), ..) if r > 0.0 => Some(Request::Round(r)),
            (Some(_), ..) => None,
            (None, Some(r), _) => Some(Request::Round(r)),
            (None, None, Some((c, _))) => match c {
                Chamfer::Leg(v) | Chamfer::Length(v) if v > 0.0 => Some(Request::Chamfer(c)),
                _ => None,
            },
            _ => None,
        };
        let (Some(request), true) = (request, in_plane) else {
            let asked = words
                .round
                .filter(|w| w.0 > 0.0)
                .map(|w| w.1)
                .or(words.chamfer.map(|w| w.1));
            if let Some(at) = asked
                && !in_plane
            {
                return Err(self.refused(
                    line,
                    "RND=/CHF=/CHR= belong to a block that moves to the corner in the working plane"
                        .into(),
                    at.0,
                    at.1,
                ));
            }
            return Ok(());
        };
        let at = words
            .round
            .map(|w| w.1)
            .or(words.chamfer.map(|w| w.1))
            .or(words.modal_round.map(|w| w.1))
            .unwrap_or((0, line.raw.len()));
        if facts.framed {
            return Err(self.corner_feature(
                line,
                "a corner (RND=/CHF=) in a block that changes a frame, offset, SUPA or TRAORI"
                    .into(),
                at,
            ));
        }
        let mut ends = match element {
            Some(e) => e,
            None => self.corner_element(line, out, interpreter, facts, motion, end)?,
        };
        ends.start = start;
        if self.returned
            || out
                .words
                .iter()
                .any(|w| w.letter == b'M' && matches!(w.value as i64, 2 | 30))
        {
            return Err(self.refused(
                line,
                "a corner (RND=/RNDM=/CHF=/CHR=) on the last motion block: no element follows it"
                    .into(),
                at.0,
                at.1,
            ));
        }
        if matches!(request, Request::Round(_)) && ends.motion == 0.0 {
            return Err(self.corner_feature(line, "a rounding traversed in G0".into(), at));
        }
        let feed = words.feed.map(|w| w.0).or(self.corners.modal_feed);
        let pending = Pending {
            request,
            at,
            feed,
            out: out.clone(),
            raw: line.raw.to_vec(),
            line: line.line,
            file: line.file,
            ends,
            block: None,
            between: Vec::new(),
            before: None,
        };
        // The element is written back flat, without its corner words.
        out.flat = true;
        self.corners.disposition = Disposition::Arm(Box::new(pending));
        Ok(())
    }

    /// This block as a corner element (a line or a circle in the plane),
    /// or a located error naming what is not read.
    fn corner_element(
        &self,
        line: &LineRun,
        out: &Out,
        interpreter: &Interpreter,
        facts: &BlockFacts,
        motion: f64,
        end: [f64; 3],
    ) -> Result<Ends, GcodeError> {
        let whole = (0, line.raw.len());
        if facts.arc_words {
            return Err(self.corner_feature(
                line,
                "a corner (RND=/CHF=) next to a CIP, CT, AR= or TURN= circle".into(),
                whole,
            ));
        }
        if facts.turned || self.chorded || !self.pending.is_empty() {
            return Err(self.corner_feature(
                line,
                "a corner (RND=/CHF=) next to a move that turns the tool or is handed on in pieces"
                    .into(),
                whole,
            ));
        }
        if let Some(w) = out.words.iter().find(|w| {
            crate::axes::Axis::from_letter(w.letter as char).is_some_and(|a| a.is_rotary())
                || super::orientation::word_name(w.letter).is_some()
        }) {
            return Err(self.corner_feature(
                line,
                format!(
                    "rotary axis or orientation word {} in an element of a corner (RND=/CHF=)",
                    String::from_utf8_lossy(&line.raw[w.start..w.end.max(w.start)])
                ),
                (w.start, w.end),
            ));
        }
        if interpreter.modal().units != Units::Mm || interpreter.modal().inverse_time {
            return Err(self.corner_feature(
                line,
                "a corner (RND=/CHF=) in inch (G70/G700) or inverse-time (G93) programs".into(),
                whole,
            ));
        }
        let (idx, _, sense, incremental) = self.arc_context(out, interpreter);
        if (end[idx[2]] - facts.start[idx[2]]).abs() > 1e-9 {
            let letter = b"XYZ"[idx[2]];
            let w = out.words.iter().rev().find(|w| w.letter == letter);
            return Err(self.corner_feature(
                line,
                format!(
                    "an element of a corner (RND=/CHF=) that moves {} out of the working plane",
                    letter as char
                ),
                w.map_or(whole, |w| (w.start, w.end)),
            ));
        }
        let arc = match sense {
            None => None,
            Some(_) => match self.move_of(out, interpreter, facts.start).map(|m| m.kind) {
                Some(LastKind::Arc { centre, cw, .. }) => Some((centre, cw)),
                _ => {
                    return Err(self.refused(
                        line,
                        "CR=: no circle of that radius joins the start and the end".into(),
                        0,
                        line.raw.len(),
                    ));
                }
            },
        };
        Ok(Ends {
            start: facts.start,
            end,
            arc,
            idx,
            incremental,
            motion,
        })
    }

    /// The next element `b` (this block) arrived: the corner between the
    /// held element and it, the held blocks queued in their final form,
    /// this block changed to start at the corner's end. Returns where this
    /// block now starts.
    fn corner_between(
        &mut self,
        line: &LineRun,
        mut pending: Box<Pending>,
        out: &mut Out,
        b: Ends,
        interpreter: &mut Interpreter,
    ) -> Result<[f64; 3], GcodeError> {
        let a = pending.ends;
        let corner = a.uv(a.end);
        let (first, second) = (a.element(true), b.element(false));
        let inserted = match pending.request {
            Request::Round(r) => {
                if b.motion == 0.0 {
                    return Err(self.corner_feature(
                        line,
                        "a rounding traversed in G0".into(),
                        (0, line.raw.len()),
                    ));
                }
                round_elements(first, corner, second, r)
            }
            Request::Chamfer(c) => chamfer_elements(first, corner, second, c),
        };
        let inserted: Inserted = match inserted {
            Ok(i) => i,
            Err(CornerError::Straight) if tangent(&first, corner, &second) => {
                // Elements meeting tangentially: nothing to round.
                self.corner_unchanged(pending, interpreter);
                return Ok(a.end);
            }
            Err(CornerError::Straight) | Err(CornerError::ZeroLength) => {
                return Err(self.corner_error(
                    &pending,
                    format!(
                        "the corner at line {}: the elements turn back on themselves or have no length (no corner to round or chamfer)",
                        pending.line
                    ),
                ));
            }
            Err(CornerError::TooLarge { needed, available }) => {
                return Err(GcodeError::at(
                    ErrorKind::DialectFeature(
                        "Sinumerik",
                        format!(
                            "a corner too large for its elements (it needs {needed:.4} mm, {available:.4} mm are there; the control reduces it by a rule the manual does not give)"
                        ),
                    ),
                    pending.line,
                    &pending.raw,
                    pending.at.0,
                    pending.at.1,
                ));
            }
        };
        let t1 = a.at(inserted.from, a.end);
        let t2 = a.at(inserted.to, a.end);
        // The element before: to the first tangent point.
        let mut a_out = std::mem::replace(&mut pending.out, Out::new(0));
        set_end(&mut a_out, &a, t1);
        if let Some((centre, _)) = a.arc {
            set_centre(&mut a_out, &a, centre, a.start, false);
        }
        a_out.flat = true;
        let a_line = LineRun {
            raw: &pending.raw,
            line: pending.line,
            file: pending.file,
            first_reading: false,
        };
        let mut queued = Vec::new();
        a_out.sort_words();
        if self.hand_on(&a_line, &mut a_out, &pending.raw, false)? {
            queued.push(std::mem::take(&mut self.block));
        }
        // The corner.
        let mut c_out = Out::new(0);
        let code = match inserted.arc {
            Some((_, true)) => 2.0,
            Some((_, false)) => 3.0,
            None if a.motion == 0.0 => 0.0,
            None => 1.0,
        };
        let push = |out: &mut Out, letter: u8, v: f64| {
            out.synthetic.push(out.words.len());
            out.words.push(word(letter, v, 0, 0, 6, true, true));
        };
        push(&mut c_out, b'G', code);
        for k in [a.idx[0], a.idx[1]] {
            let v = if a.incremental { t2[k] - t1[k] } else { t2[k] };
            push(&mut c_out, b"XYZ"[k], v);
        }
        if let Some((m, _)) = inserted.arc {
            let m = a.at(m, a.end);
            for k in [a.idx[0], a.idx[1]] {
                push(&mut c_out, b"IJK"[k], m[k] - t1[k]);
            }
        }
        let feed = pending.feed.filter(|_| code != 0.0);
        if let Some(f) = feed {
            push(&mut c_out, b'F', f);
        }
        c_out.flat = true;
        if self.hand_on(&a_line, &mut c_out, &pending.raw, false)? {
            queued.push(std::mem::take(&mut self.block));
        }
        // The next element: from the second tangent point.
        let mut changed = false;
        if let Some((centre, _)) = b.arc {
            set_centre(out, &b, centre, t2, true);
            changed = true;
        }
        if b.incremental {
            set_end(out, &Ends { start: t2, ..b }, b.end);
            changed = true;
        }
        let has = |out: &Out, letter: u8, motion: bool| {
            out.words
                .iter()
                .any(|w| w.letter == letter && (!motion || matches!(w.value as i64, 0..=3)))
        };
        if code != b.motion && !has(out, b'G', true) {
            out.synthetic.push(out.words.len());
            out.words.push(word(b'G', b.motion, 0, 0, 0, false, false));
            changed = true;
        }
        if feed.is_some() && !has(out, b'F', false) {
            // The block's feed (`interpreter` has run the held blocks).
            out.synthetic.push(out.words.len());
            out.words
                .push(word(b'F', interpreter.modal().feed, 0, 0, 4, true, true));
            changed = true;
        }
        if changed {
            out.flat = true;
        }
        let executed = Executed::made_from(pending.file, pending.line);
        for mut block in queued {
            block.line = pending.line;
            block.ending = LineEnding::Lf;
            self.spline_out.push_back((block, executed.clone()));
        }
        self.spline_out.extend(pending.between.drain(..));
        if let Some(before) = pending.before.take() {
            *interpreter = before;
        }
        self.corners.disposition = Disposition::After;
        Ok(t2)
    }

    /// No corner after all: the held element and the blocks after it go on
    /// as they were read.
    fn corner_unchanged(&mut self, mut pending: Box<Pending>, interpreter: &mut Interpreter) {
        if let Some(block) = pending.block.take() {
            self.spline_out.push_back(block);
        }
        self.spline_out.extend(pending.between.drain(..));
        if let Some(before) = pending.before.take() {
            *interpreter = before;
        }
        self.corners.disposition = Disposition::After;
    }

    /// After the block was handed on (`self.block`): hold it, or queue it
    /// after the blocks the corner queued. Returns whether it was taken.
    #[inline(never)]
    #[cold]
    pub(super) fn after_corner_block(
        &mut self,
        interpreter: &mut Interpreter,
        handed: bool,
    ) -> Result<bool, GcodeError> {
        fn take(front: &mut SinumerikFront) -> Vec<(Block, Executed)> {
            let executed = front.executed.clone();
            let block = std::mem::take(&mut front.block);
            let (line, offset) = (block.line, block.offset);
            let mut all = vec![(block, executed.clone())];
            while let Some(mut piece) = front.pending.pop_front() {
                piece.line = line;
                piece.offset = offset;
                piece.ending = LineEnding::Lf;
                all.push((
                    piece,
                    Executed {
                        literal: false,
                        ..executed.clone()
                    },
                ));
            }
            all
        }
        if !handed {
            // Nothing handed on (an empty flat line): nothing to hold.
            if let Disposition::Arm(p) = std::mem::take(&mut self.corners.disposition) {
                self.corners.pending = Some(p);
            }
            return Ok(false);
        }
        match std::mem::take(&mut self.corners.disposition) {
            Disposition::Pass => Ok(false),
            Disposition::After => {
                let blocks = take(self);
                self.spline_out.extend(blocks);
                Ok(true)
            }
            Disposition::Arm(mut pending) => {
                let mut blocks = take(self);
                pending.block = Some(blocks.remove(0));
                self.corners.pending = Some(pending);
                Ok(true)
            }
            Disposition::Between => {
                let blocks = take(self);
                let mut pending = self.corners.pending.take().expect("a held element");
                for (block, _) in &blocks {
                    run_ahead(interpreter, block)?;
                }
                pending.between.extend(blocks);
                if pending.between.len() > MAX_BLOCKS_BETWEEN {
                    // "More than three blocks … no chamfer/rounding".
                    self.corner_unchanged(pending, interpreter);
                    self.corners.disposition = Disposition::Pass;
                } else {
                    self.corners.pending = Some(pending);
                }
                Ok(true)
            }
        }
    }

    /// Before the next line is read: run the held element on the
    /// interpreter (from a copy of its state), so that the line reads as
    /// the control reads it.
    #[inline(never)]
    #[cold]
    pub(super) fn run_held_element(
        &mut self,
        interpreter: &mut Interpreter,
    ) -> Result<(), GcodeError> {
        if let Some(p) = self.corners.pending.as_mut()
            && p.before.is_none()
            && let Some((block, _)) = &p.block
        {
            p.before = Some(interpreter.clone());
            run_ahead(interpreter, block)?;
        }
        Ok(())
    }

    /// The program ended with an element waiting for its corner.
    pub(super) fn corner_at_the_end(&mut self) -> Option<GcodeError> {
        let p = self.corners.pending.take()?;
        Some(self.corner_error(&p, last_block_message(&p)))
    }
}

/// Run a held block on the interpreter (its event is not handed on).
#[inline(never)]
#[cold]
fn run_ahead(interpreter: &mut Interpreter, block: &Block) -> Result<(), GcodeError> {
    let mut event = crate::gcode::BlockEvent::default();
    interpreter.interpret_into(block, &mut event)
}

fn last_block_message(p: &Pending) -> String {
    format!(
        "a corner (RND=/RNDM=/CHF=/CHR=) on the last motion block (line {}): no element follows it",
        p.line
    )
}

/// Whether the elements meet tangentially (going on in one direction).
fn tangent(first: &Element, corner: [f64; 2], second: &Element) -> bool {
    crate::gcode::contour_corners::directions_at(first, corner, second)
        .is_ok_and(|(u, v)| u[0] * v[0] + u[1] * v[1] > 0.0)
}

/// Set the block's end in the plane to `target` (its words in its mode;
/// a missing word added).
fn set_end(out: &mut Out, e: &Ends, target: [f64; 3]) {
    for k in [e.idx[0], e.idx[1]] {
        let v = if e.incremental {
            target[k] - e.start[k]
        } else {
            target[k]
        };
        set_word(out, b"XYZ"[k], v, 6);
    }
}

/// Give the circle its centre as `I J K` increments from `from` (a `CR=`
/// radius replaced); `always`: also when the block gives them.
fn set_centre(out: &mut Out, e: &Ends, centre: [f64; 3], from: [f64; 3], always: bool) {
    let radius = out.words.iter().any(|w| w.letter == b'R');
    if !radius && !always {
        return;
    }
    if radius {
        super::circles::retain_words(out, |w| w.letter != b'R');
    }
    for k in [e.idx[0], e.idx[1]] {
        set_word(out, b"IJK"[k], centre[k] - from[k], 6);
    }
}

/// Set the last word of `letter` to `v` (written as a number), or add it.
fn set_word(out: &mut Out, letter: u8, v: f64, decimals: u8) {
    match out.words.iter().rposition(|w| w.letter == letter) {
        Some(k) => {
            out.words[k].value = v;
            if !out.substituted.contains(&k) && !out.synthetic.contains(&k) {
                out.substituted.push(k);
            }
        }
        None => {
            // After the block's words (a synthetic word has no text).
            let at = out.words.iter().map(|w| w.end).max().unwrap_or(0);
            out.synthetic.push(out.words.len());
            out.words
                .push(word(letter, v, at, at, decimals, true, true));
        }
    }
}
