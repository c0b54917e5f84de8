//! The machine state of a TNC running Klartext: units, the pole, feeds,
//! radius compensation, the datum shift (`CYCL DEF 7`), the working plane
//! (`PLANE …`), tool-tip control (`M128`, `FUNCTION TCPM`), tools and the
//! drilling cycle, each block → a [`BlockEvent`] with its motions.
//!
//! Positions (dialects.md "Positions"): without a working plane and without
//! tool-tip control a block's `X Y Z A B C` are joint positions: the preset
//! (`--offset PRESET=…`) and the datum shift are added
//! ([`Origin`]: `work` = preset, `g92` = datum shift). With a working plane
//! or tool-tip control the motion is in the part frame: the tip is
//! `preset + shift + R·(program + tilted shift)`, `R` the plane's rotation
//! ([`BlockEvent::tilt`]), and the rotary joints are the plane's solution
//! (or the programmed ones under `M128`).
//!
//! Invariants: knows no kinematics (the plane's rotary solution comes from an
//! [`OrientationSolver`] handed in); a block that fails leaves the state as
//! it was (the state is copied, changed and committed).
use std::sync::Arc;

use crate::gcode::dialect::{Branch, OrientationSolver};
use crate::gcode::machine::origin::FrameTransform;

use super::cycles::{self, CycleDef, CycleError};
use super::language::QParameters;
use super::syntax::{KlBlock, Token};
use crate::axes::{Axes, Axis};
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::machine::cycles::CycleStep;
use crate::gcode::machine::interpret::{BlockEvent, Moves, duration_min};
use crate::gcode::machine::modal::{CutterComp, ModalState, MotionMode, Units};
use crate::gcode::machine::origin::Origin;
use crate::gcode::machine::tools::{NamedTool, ToolInUse, ToolTable};
use crate::gcode::motion::{Feed, Frame, Motion, MotionKind, Plane, from_plane, to_plane};

use super::geometry;
use super::geometry::{
    Corner, CornerError, IDENTITY, Mat3, arc_chords, dot, mat_mul, mat_t_vec, mat_vec, rotation,
};

/// Settings of the machine layer.
#[derive(Clone, Debug, Default)]
pub struct KlartextSetup {
    /// The preset in use (`--offset PRESET=…`), machine coordinates.
    pub preset: Axes,
    /// The tool table.
    pub tools: ToolTable,
    /// The machine's orientation kinematics (`--machine`), for `PLANE` and
    /// `LN` vectors.
    pub orientation: Option<Arc<dyn OrientationSolver>>,
    /// Rapid rate for durations, mm/min.
    pub rapid_mm_per_min: f64,
    /// The machine's axes (a word for another axis is refused).
    pub axes: crate::axes::AxisSet,
}

/// The state a block changes (copied, changed, committed).
#[derive(Clone, Debug)]
struct State {
    inch: bool,
    /// Last programmed X Y Z, program coordinates (mm).
    pos: [f64; 3],
    /// Last programmed A B C, degrees.
    rot: [f64; 3],
    feed: f64,
    tool_feed: f64,
    comp: CutterComp,
    pole: Option<[f64; 2]>,
    plane: Plane,
    /// Datum shift in the untilted frame, and in the tilted frame.
    shift: [f64; 3],
    shift_tilted: [f64; 3],
    tilt: Option<Mat3>,
    tcpm: bool,
    shortest: bool,
    tool: ToolInUse,
    cycle: Option<CycleDef>,
    /// The points of the last `PATTERN DEF` (`CYCL CALL PAT`).
    pattern: Option<Arc<cycles::Pattern>>,
    /// `M89`: the cycle is called after every positioning block.
    modal_call: bool,
    /// The spindle speed of the last `TOOL CALL … S` (rpm).
    spindle: Option<f64>,
    /// The radius of the tool in the spindle (with `DR`) when the tool
    /// table gives it (a tool called by a number or name it lists), for the
    /// cycles that mill about a centre (208 …).
    tool_radius: Option<f64>,
    /// Direction of the last path element's end (program coordinates), for `CT`.
    tangent: Option<[f64; 3]>,
    /// The event frame position after the last block.
    position: Axes,
    /// Q parameters this block sets (`Q120`–`Q122` after `STAY`).
    assigned: Vec<(u32, f64)>,
    /// A `RND`/`CHF` next: what the control inserts there, or why it
    /// cannot (reported at the `RND`/`CHF` block).
    corner: Option<Result<PendingCorner, CornerRefusal>>,
    time_min: f64,
    begun: bool,
    /// This block programs a rotary axis itself (`L B+Q121 C+Q122` after
    /// `PLANE … STAY`): a tilted plane does not hold the axes for it.
    commands_rotary: bool,
    /// The last block that moved ended with a rapid move (`APPR`'s way to
    /// its auxiliary point).
    last_rapid: bool,
    /// The side of the contour the last `APPR` came from (left of the
    /// travel direction: `true`), for `DEP LN | CT | LCT` with `R0`.
    contour_left: Option<bool>,
}

impl State {
    /// The frame of the X Y Z a move programs: the tool tip in the part
    /// under `M128`/`FUNCTION TCPM` or a working plane, else the joints.
    fn frame(&self) -> Frame {
        if self.tcpm || self.tilt.is_some() {
            Frame::Part
        } else {
            Frame::Joint
        }
    }
}

/// The machine layer.
pub(crate) struct KlMachine {
    setup: KlartextSetup,
    state: State,
    /// The `RND`/`CHF` block after the next block and the block after it.
    ahead: Option<(KlBlock, KlBlock)>,
}

/// A rounding or chamfer the control inserts at the end of a straight line:
/// its points (program coordinates, the last where the next line starts),
/// and the next line's direction.
#[derive(Clone, Debug)]
struct PendingCorner {
    points: Vec<[f64; 3]>,
    tangent: [f64; 3],
}

/// Why no rounding or chamfer can be inserted after an element (reported
/// at the `RND`/`CHF` block).
#[derive(Clone, Debug)]
enum CornerRefusal {
    /// What the control refuses, in its words.
    Control(String),
    /// What volcomp does not read yet (names the feature).
    Unread(String),
}

impl From<String> for CornerRefusal {
    fn from(why: String) -> Self {
        CornerRefusal::Control(why)
    }
}

impl From<&str> for CornerRefusal {
    fn from(why: &str) -> Self {
        CornerRefusal::Control(why.to_string())
    }
}

/// What a block says the language should do at the program level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Statement {
    /// Anything else.
    Other,
    /// `END PGM`, `M2`, `M30`: the program ends.
    End,
}

pub use super::geometry::{spatial, vector_frame};

impl KlMachine {
    /// A straight move (rapid at `F MAX`, else linear) with its duration.
    fn straight(
        &self,
        frame: Frame,
        machine_coordinates: bool,
        start: Axes,
        end: Axes,
        feed: Feed,
    ) -> Motion {
        let mut m = Motion {
            kind: if feed == Feed::Rapid {
                MotionKind::Rapid
            } else {
                MotionKind::Linear
            },
            frame,
            machine_coordinates,
            start,
            end,
            feed,
            duration_min: 0.0,
        };
        m.duration_min = duration_min(&m, self.setup.rapid_mm_per_min);
        m
    }
    pub fn new(setup: KlartextSetup) -> Self {
        let tool = ToolInUse::DEFAULT;
        KlMachine {
            state: State {
                inch: false,
                pos: [0.0; 3],
                rot: [0.0; 3],
                feed: 0.0,
                tool_feed: 0.0,
                comp: CutterComp::Off,
                pole: None,
                plane: Plane::XY,
                shift: [0.0; 3],
                shift_tilted: [0.0; 3],
                tilt: None,
                tcpm: false,
                shortest: false,
                tool,
                cycle: None,
                pattern: None,
                modal_call: false,
                spindle: None,
                tool_radius: None,
                tangent: None,
                position: setup.preset,
                assigned: Vec::new(),
                corner: None,
                time_min: 0.0,
                begun: false,
                commands_rotary: false,
                last_rapid: false,
                contour_left: None,
            },
            setup,
            ahead: None,
        }
    }

    /// The two blocks after the next one to interpret, when the first of
    /// them is `RND`/`CHF` (the corner the next straight line ends in).
    pub fn set_lookahead(&mut self, ahead: Option<(KlBlock, KlBlock)>) {
        // Most blocks have none, before and after: nothing to move.
        if ahead.is_some() || self.ahead.is_some() {
            self.ahead = ahead;
        }
    }

    /// The Q parameters the last block set (`Q120`–`Q122` after `PLANE …
    /// STAY` or `CYCL DEF 19`), for the language's table.
    pub fn take_assigned(&mut self) -> Vec<(u32, f64)> {
        std::mem::take(&mut self.state.assigned)
    }

    /// The event of a block not run (passed over).
    pub fn pass_over(&self, line: usize, event: &mut BlockEvent) {
        self.fill(event, line);
        event.start = self.state.position;
        event.skipped = true;
    }

    fn fill(&self, event: &mut BlockEvent, line: usize) {
        self.fill_but_frames(event, line);
        event.origin = self.origin();
        event.modal = self.modal();
    }

    /// [`KlMachine::fill`] but the origin and modal state (which
    /// [`KlMachine::interpret`] sets after the block).
    fn fill_but_frames(&self, event: &mut BlockEvent, line: usize) {
        let s = &self.state;
        event.index = line.saturating_sub(1);
        event.line = line;
        event.moves = Moves::None;
        event.tool = s.tool;
        event.start = s.position;
        event.position = s.position;
        event.time_min = s.time_min;
        event.frame_switch = None;
        event.program_end = false;
        event.skipped = false;
        event.spline = None;
        event.warnings.clear();
    }

    /// The origin of the block's words: the preset, and the datum shift
    /// and working plane as a frame (`part = preset + shift + R·(p + s₁)`).
    fn origin(&self) -> Origin {
        let s = &self.state;
        let r = s.tilt.unwrap_or(IDENTITY);
        let turned = mat_vec(&r, s.shift_tilted);
        let shift = [
            s.shift[0] + turned[0],
            s.shift[1] + turned[1],
            s.shift[2] + turned[2],
        ];
        // Under a tilted plane without tool-tip control the control holds
        // the rotary axes where the plane (or the program's own rotary
        // block) put them and places the tip through the plane's nominal
        // transform: a compensator corrects the tip only (dialects.md
        // "Writing back"), as under Sinumerik's CYCLE800.
        let frame = (s.tilt.is_some() || shift != [0.0; 3])
            .then(|| FrameTransform::new(r, shift))
            .flatten()
            .map(|mut f| {
                f.holds_rotary = s.tilt.is_some() && !s.tcpm;
                f
            });
        Origin {
            work: self.setup.preset,
            g92: Axes::default(),
            rotation_deg: 0.0,
            frame,
        }
    }

    fn modal(&self) -> ModalState {
        let s = &self.state;
        let mut m = ModalState::new(self.frame());
        m.units = if s.inch { Units::Inch } else { Units::Mm };
        m.plane = s.plane;
        m.cutter_comp = s.comp;
        m.feed = s.feed;
        m.tool_length = true;
        m.motion = MotionMode::Linear;
        m
    }

    fn frame(&self) -> Frame {
        if self.state.tcpm || self.state.tilt.is_some() {
            Frame::Part
        } else {
            Frame::Joint
        }
    }

    /// Program X Y Z (and A B C) → the event frame's values.
    fn to_frame(&self, s: &State, p: [f64; 3], rot: [f64; 3]) -> Axes {
        let pre = &self.setup.preset;
        let q = match &s.tilt {
            Some(r) => {
                let local = [
                    p[0] + s.shift_tilted[0],
                    p[1] + s.shift_tilted[1],
                    p[2] + s.shift_tilted[2],
                ];
                mat_vec(r, local)
            }
            None => p,
        };
        Axes {
            x: pre.x + s.shift[0] + q[0],
            y: pre.y + s.shift[1] + q[1],
            z: pre.z + s.shift[2] + q[2],
            a: pre.a + rot[0],
            b: pre.b + rot[1],
            c: pre.c + rot[2],
            ..*pre
        }
    }

    /// Interpret one block (its values read through `q`).
    pub fn interpret(
        &mut self,
        block: &KlBlock,
        raw: &[u8],
        line: usize,
        q: &QParameters,
        event: &mut BlockEvent,
    ) -> Result<Statement, GcodeError> {
        self.fill_but_frames(event, line);
        let mut s = self.state.clone();
        s.assigned.clear();
        s.commands_rotary = false;
        if !block.tokens.is_empty() && !matches!(block.address(0), "RND" | "CHF") {
            s.corner = None;
        }
        let ctx = Ctx {
            block,
            raw,
            line,
            q,
        };
        let statement = match self.statement(&ctx, &mut s, event) {
            Ok(statement) => statement,
            Err(e) => {
                // The event as `fill` leaves it.
                event.origin = self.origin();
                event.modal = self.modal();
                return Err(e);
            }
        };
        for m in event.moves.all() {
            s.time_min += m.duration_min;
        }
        if let Some(m) = event.moves.all().last() {
            s.position = m.end;
            s.last_rapid = m.kind == MotionKind::Rapid;
        }
        event.position = s.position;
        event.time_min = s.time_min;
        let before = self.frame();
        self.state = s;
        if self.frame() != before {
            event.frame_switch = Some(self.frame());
        }
        event.modal = self.modal();
        event.origin = self.origin();
        if self.state.commands_rotary
            && let Some(f) = &mut event.origin.frame
        {
            // The program turns the rotary axes itself: its words are
            // corrected (tool axis too), dialects.md "Writing back".
            f.holds_rotary = false;
        }
        event.tool = self.state.tool;
        event.program_end = statement == Statement::End;
        Ok(statement)
    }

    fn statement(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
    ) -> Result<Statement, GcodeError> {
        let b = c.block;
        if b.section || b.tokens.is_empty() {
            return Ok(Statement::Other);
        }
        let first = b.address(0);
        if !s.begun && !b.starts_with(&["BEGIN", "PGM"]) {
            return Err(c.error("the program must start with BEGIN PGM", None));
        }
        match first {
            "BEGIN" if b.starts_with(&["BEGIN", "PGM"]) => {
                let units = b.tokens.get(3).map(|t| t.address.as_str());
                s.inch = match units {
                    Some("MM") => false,
                    Some("INCH") => true,
                    _ => return Err(c.error("BEGIN PGM name MM|INCH: the units are missing", None)),
                };
                s.begun = true;
                Ok(Statement::Other)
            }
            "END" if b.starts_with(&["END", "PGM"]) => Ok(Statement::End),
            "BLK" | "TOOL" if first == "BLK" || b.starts_with(&["TOOL", "DEF"]) => {
                Ok(Statement::Other)
            }
            "TOOL" if b.starts_with(&["TOOL", "CALL"]) => {
                self.tool_call(c, s, event)?;
                Ok(Statement::Other)
            }
            "L" => self.linear(c, s, event),
            "LN" => self.linear(c, s, event),
            "LP" => self.polar_line(c, s, event),
            "CC" => {
                self.pole(c, s)?;
                Ok(Statement::Other)
            }
            "C" | "CR" | "CT" | "CP" => self.circle(c, s, event),
            "RND" | "CHF" => self.corner(c, s, event),
            "APPR" | "DEP" => self.approach_departure(c, s, event),
            // `CYCL DEF 200`, and the number written on (`CYCL DEF9.0`, `CYCL DEF9 .0`).
            "CYCL" if b.address(1) == "DEF" => {
                self.cycle_def(c, s, event)?;
                Ok(Statement::Other)
            }
            "CYCL" if b.starts_with(&["CYCL", "CALL"]) => {
                self.cycle_call(c, s, event, cycle_call_kind(b))?;
                self.m_codes(c, s, event, Some(2))
            }
            "PATTERN" if b.starts_with(&["PATTERN", "DEF"]) => {
                self.pattern_def(c, s)?;
                Ok(Statement::Other)
            }
            "PLANE" => {
                self.plane(c, s, event)?;
                Ok(Statement::Other)
            }
            "FUNCTION" if b.starts_with(&["FUNCTION", "TCPM"]) => {
                s.tcpm = true;
                Ok(Statement::Other)
            }
            "FUNCTION" if b.starts_with(&["FUNCTION", "RESET", "TCPM"]) => {
                s.tcpm = false;
                Ok(Statement::Other)
            }
            "M" => {
                let end = self.m_codes(c, s, event, None)?;
                Ok(end)
            }
            "STOP" => {
                let end = self.m_codes(c, s, event, None)?;
                Ok(end)
            }
            // Language statements (the language layer ran them).
            "FN" | "LBL" | "CALL" => Ok(Statement::Other),
            _ if b.assigned().is_some() => Ok(Statement::Other),
            // Statements that do not move (passed through, counted).
            "FUNCTION" | "SEL" | "DECLARE" | "SPEC" | "SYSCALL" => Ok(Statement::Other),
            _ => Err(c.unread(first, Some(0))),
        }
    }

    /// `TOOL CALL n|"name" axis S… F… DL… DR…`.
    fn tool_call(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        _event: &mut BlockEvent,
    ) -> Result<(), GcodeError> {
        let b = c.block;
        let mut i = 2;
        let mut number = None;
        if let Some(t) = b.tokens.get(2)
            && t.address.is_empty()
        {
            if let Some(v) = t.number() {
                if v < 0.0 || v.fract() != 0.0 || v > 1e9 {
                    return Err(c.error("the tool number must be a whole number", Some(2)));
                }
                number = Some(v as u32);
            }
            i = 3;
        }
        let mut dl = 0.0;
        let mut dr = 0.0;
        for (k, t) in b.tokens.iter().enumerate().skip(i) {
            match t.address.as_str() {
                "X" | "Y" | "Z" if t.value.is_none() => {
                    s.plane = match t.address.as_str() {
                        "X" => Plane::YZ,
                        "Y" => Plane::ZX,
                        _ => Plane::XY,
                    };
                }
                "F" => s.tool_feed = self.feed_value(c, s, k)?,
                "DL" => dl = c.value(k)?,
                "DR" => dr = c.value(k)?,
                "S" if t.value.is_some() => s.spindle = Some(c.value(k)?),
                _ => {}
            }
        }
        let default = ToolInUse::DEFAULT;
        // `TOOL CALL "NAME"`: the entry of that name, found as
        // `ToolTable::named` says for every dialect (a table that names no
        // tool keeps the default tool, said in the summary).
        let named = match b.tokens.get(2) {
            Some(t) if number.is_none() && t.address.is_empty() => {
                match super::language::token_text(b, t).map(|x| x.trim().trim_matches('"')) {
                    Some(name) => match self.setup.tools.named(name) {
                        NamedTool::One(e) => Some(e),
                        NamedTool::None if !self.setup.tools.names_tools() => None,
                        NamedTool::Two(x, y) => {
                            return Err(c.error(
                                &format!(
                                    "tool \"{name}\" names two tools of the tool table ({x} and {y}): a name must name one tool"
                                ),
                                Some(2),
                            ));
                        }
                        NamedTool::None => {
                            return Err(c.error(
                                &format!(
                                    "tool \"{name}\" is not in the tool table: a tool is named by the machine file's [[tools]] name"
                                ),
                                Some(2),
                            ));
                        }
                    },
                    None => None,
                }
            }
            _ => None,
        };
        let known = match number {
            Some(n) => self.setup.tools.get(n).is_some(),
            None if b.tokens.get(2).is_some_and(|t| t.address.is_empty()) => named.is_some(),
            None => s.tool_radius.is_some(),
        };
        let mut tool = match number {
            None if named.is_some() => {
                named.map_or(default, |e| self.setup.tools.in_use(e.number, default))
            }
            Some(n) if n != 0 => {
                if self.setup.tools.is_given() && !self.setup.tools.knows(n) {
                    return Err(GcodeError::at(
                        ErrorKind::ToolNotInTable(n),
                        c.line,
                        c.raw,
                        b.tokens[2].span.start,
                        b.tokens[2].span.end,
                    ));
                }
                self.setup.tools.in_use(
                    n,
                    ToolInUse {
                        number: n,
                        ..default
                    },
                )
            }
            Some(_) => default,
            // Tool by name, or TOOL CALL with the axis only: the tool stays.
            None if b.tokens.get(2).is_some_and(|t| t.address.is_empty()) => default,
            None => s.tool,
        };
        tool.length_mm += dl;
        tool.radius_mm += dr;
        s.tool = tool;
        s.tool_radius = known.then_some(tool.radius_mm);
        Ok(())
    }

    /// The value of a feed token (`F+200`, `F200`, `FQ5`): mm/min.
    fn feed_value(&self, c: &Ctx<'_>, s: &State, k: usize) -> Result<f64, GcodeError> {
        let f = c.value(k)?;
        if f < 0.0 {
            return Err(c.error("a negative feed rate", Some(k)));
        }
        // INCH programs give F in 1/10 inch/min.
        Ok(if s.inch { f * 2.54 } else { f })
    }

    /// The feed of a motion block: `FMAX`/`F MAX` (this block only), `FAUTO`,
    /// `F…` (modal).
    fn block_feed(&self, c: &Ctx<'_>, s: &mut State, from: usize) -> Result<Feed, GcodeError> {
        let b = c.block;
        let mut rapid = false;
        for (k, t) in b.tokens.iter().enumerate().skip(from) {
            match t.address.as_bytes() {
                b"FMAX" => rapid = true,
                b"FAUTO" => s.feed = s.tool_feed,
                b"F" if t.value.is_none() => match b.address(k + 1) {
                    "MAX" => rapid = true,
                    "AUTO" => s.feed = s.tool_feed,
                    _ => return Err(c.error("F without a value", Some(k))),
                },
                b"F" => s.feed = self.feed_value(c, s, k)?,
                _ => {}
            }
        }
        Ok(if rapid {
            Feed::Rapid
        } else {
            Feed::PerMinute(s.feed)
        })
    }

    /// Radius compensation words (`R0`, `RL`, `RR`).
    fn compensation(&self, c: &Ctx<'_>, s: &mut State) {
        for t in &c.block.tokens {
            match (t.address.as_bytes(), t.number()) {
                (b"R", Some(v)) if v == 0.0 && t.value_span.len() == 1 => s.comp = CutterComp::Off,
                (b"RL", None) => s.comp = CutterComp::Left,
                (b"RR", None) => s.comp = CutterComp::Right,
                _ => {}
            }
        }
    }

    fn refuse_compensation(&self, c: &Ctx<'_>, s: &State) -> Result<(), GcodeError> {
        let name = match s.comp {
            CutterComp::Off => return Ok(()),
            CutterComp::Left => "RL",
            _ => "RR",
        };
        let k = c
            .block
            .tokens
            .iter()
            .position(|t| t.address == name)
            .unwrap_or(0);
        let t = &c.block.tokens[k.min(c.block.tokens.len().saturating_sub(1))];
        Err(GcodeError::at(
            ErrorKind::CutterCompensation(name.to_string()),
            c.line,
            c.raw,
            t.span.start,
            t.span.end,
        ))
    }

    /// `L`/`LN`: a straight move to the axis words.
    fn linear(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
    ) -> Result<Statement, GcodeError> {
        let b = c.block;
        let ln = b.address(0) == "LN";
        let scale = if s.inch { 25.4 } else { 1.0 };
        let mut target = s.pos;
        let mut rot = s.rot;
        let mut given = false;
        let mut n = [None::<f64>; 3];
        let mut t_vec = [None::<f64>; 3];
        for (k, t) in b.tokens.iter().enumerate().skip(1) {
            let (inc, letter) = match t.address.as_bytes() {
                [b'I', l] => (true, *l),
                [l] => (false, *l),
                [b'N', l @ (b'X' | b'Y' | b'Z')] if ln => {
                    n[(l - b'X') as usize] = Some(c.value(k)?);
                    continue;
                }
                [b'T', l @ (b'X' | b'Y' | b'Z')] if ln => {
                    t_vec[(l - b'X') as usize] = Some(c.value(k)?);
                    continue;
                }
                _ => continue,
            };
            if t.value.is_none() {
                continue;
            }
            let (slot, rotary) = match letter {
                b'X' => (0, false),
                b'Y' => (1, false),
                b'Z' => (2, false),
                b'A' => (0, true),
                b'B' => (1, true),
                b'C' => (2, true),
                _ => continue,
            };
            let v = c.value(k)?;
            given = true;
            let axis = [[Axis::X, Axis::Y, Axis::Z], [Axis::A, Axis::B, Axis::C]]
                [usize::from(rotary)][slot];
            if !self.setup.axes.contains(axis) {
                return Err(GcodeError::at(
                    ErrorKind::AxisNotOnMachine {
                        letter: axis.letter(),
                        axes: self.setup.axes.letters(),
                    },
                    c.line,
                    c.raw,
                    t.span.start,
                    t.span.end,
                ));
            }
            if rotary {
                s.commands_rotary = true;
                let base = if inc { rot[slot] } else { 0.0 };
                rot[slot] = if !inc && s.shortest {
                    nearest_turn(v, rot[slot])
                } else {
                    base + v
                };
            } else {
                let base = if inc { target[slot] } else { 0.0 };
                target[slot] = base + v * scale;
            }
        }
        self.compensation(c, s);
        let feed = self.block_feed(c, s, 1)?;
        let machine_datum = b
            .tokens
            .iter()
            .any(|t| t.address == "M" && matches!(t.number(), Some(v) if v == 91.0 || v == 92.0));
        if ln {
            let norm = |v: [Option<f64>; 3]| {
                let v = v.map(|x| x.unwrap_or(0.0));
                dot(v, v).sqrt()
            };
            if n.iter().any(Option::is_some) && norm(n) < 1e-9 {
                return Err(c.error("LN with a zero normal vector (NX NY NZ)", Some(0)));
            }
            if t_vec.iter().any(Option::is_some) {
                if norm(t_vec) < 1e-9 {
                    return Err(c.error("LN with a zero tool vector (TX TY TZ)", Some(0)));
                }
                if !s.tcpm {
                    return Err(c.error(
                        "LN with a tool vector (TX TY TZ) needs M128 or FUNCTION TCPM",
                        Some(0),
                    ));
                }
                let solver = self.solver(c)?;
                let l = norm(t_vec);
                let axis_prog = t_vec.map(|x| x.unwrap_or(0.0) / l);
                let axis = match &s.tilt {
                    Some(r) => mat_vec(r, axis_prog),
                    None => axis_prog,
                };
                let previous = self.to_frame(s, target, rot);
                let j = solver
                    .joints_for_axis(axis, Branch::Nearest, &previous)
                    .ok_or_else(|| {
                        c.error(
                            "the machine cannot point the tool along this LN vector",
                            Some(0),
                        )
                    })?;
                let pre = &self.setup.preset;
                rot = [j.a - pre.a, j.b - pre.b, j.c - pre.c];
                given = true;
            }
        }
        if !given {
            // `L R0 FMAX` and the like: no move.
            self.m_codes(c, s, event, Some(1))?;
            return Ok(Statement::Other);
        }
        if machine_datum {
            return self.machine_datum_move(c, s, event, feed);
        }
        self.refuse_compensation(c, s)?;
        let start = s.position;
        let end = self.to_frame(s, target, rot);
        let kind = if feed == Feed::Rapid {
            MotionKind::Rapid
        } else {
            MotionKind::Linear
        };
        let d = [
            target[0] - s.pos[0],
            target[1] - s.pos[1],
            target[2] - s.pos[2],
        ];
        if dot(d, d) > 0.0 {
            s.tangent = Some(d);
        }
        let from = s.pos;
        let turned = rot != s.rot;
        s.pos = target;
        s.rot = rot;
        self.push_motion(c, s, event, kind, start, end, feed)?;
        if let Some((corner, next)) = &self.ahead
            && !ln
        {
            let a = to_plane(s.plane, from);
            let line = geometry::Element::Line {
                other: [a[0], a[1]],
            };
            let planned = self.plan_corner(c, s, corner, next, line, a[2], turned);
            if let Ok((t1, _)) = &planned {
                // The line ends where the rounding or chamfer begins.
                let end = self.to_frame(s, *t1, rot);
                let m = self.straight(s.frame(), false, start, end, feed);
                let step = if feed == Feed::Rapid {
                    CycleStep::Rapid(*t1)
                } else {
                    CycleStep::Feed(*t1)
                };
                event.moves = Moves::Cycle {
                    moves: vec![m],
                    steps: vec![step],
                };
            }
            s.corner = Some(planned.map(|(_, p)| p));
        }
        self.m_codes(c, s, event, Some(1))
    }

    /// The corner at the end of the element `first` (a straight line or an
    /// arc ending at `s.pos`, starting at the tool-axis coordinate
    /// `first_w`) that the `RND`/`CHF` block `corner` asks for, with the
    /// element `next` after it: where `first` now ends, and what follows
    /// (TNC 620 Klartext user's manual 01/2022, "Corner rounding RND"
    /// p. 157: an arc tangent to the element before and after; "Chamfer
    /// CHF" p. 156 and the overview p. 154: a chamfer between two straight
    /// lines, its side length from the corner). `RND` is read between
    /// straight lines `L` and arcs `C`, `CR`, `CT`, `CP` before it, `L`,
    /// `C`, `CR` after it (a `CT` after it would be tangent to the
    /// element before the corner: no corner); all in the working plane.
    #[allow(clippy::too_many_arguments)]
    fn plan_corner(
        &self,
        c: &Ctx<'_>,
        s: &State,
        corner: &KlBlock,
        next: &KlBlock,
        first: geometry::Element,
        first_w: f64,
        turned: bool,
    ) -> Result<([f64; 3], PendingCorner), CornerRefusal> {
        let what = corner.address(0).to_string();
        let unread = CornerRefusal::Unread(format!(
            "{what} next to anything but straight lines (L) and arcs (C, CR, CT, CP before it; C, CR after it) in the working plane"
        ));
        let kind = next.address(0);
        if turned || !matches!(kind, "L" | "C" | "CR") {
            return Err(unread);
        }
        let scale = if s.inch { 25.4 } else { 1.0 };
        let ctx = Ctx {
            block: next,
            raw: c.raw,
            line: c.line,
            q: c.q,
        };
        let rotary = next.tokens.iter().any(|t| {
            t.value.is_some() && matches!(t.address.as_str(), "A" | "B" | "C" | "IA" | "IB" | "IC")
        });
        if rotary {
            return Err(unread);
        }
        let end = xyz_words(&ctx, s.pos, scale, 1).map_err(|e| e.to_string())?;
        let (p, e) = (to_plane(s.plane, s.pos), to_plane(s.plane, end));
        if (first_w - p[2]).abs() > 1e-9 || (e[2] - p[2]).abs() > 1e-9 {
            return Err(unread);
        }
        let value = |name: &str| {
            next.tokens
                .iter()
                .position(|t| t.address == name && t.value.is_some())
                .map(|k| ctx.value(k).map_err(|e| e.to_string()))
                .transpose()
        };
        let dr = || -> Result<bool, String> {
            value("DR")?
                .map(|d| d < 0.0)
                .ok_or_else(|| format!("{kind} needs its direction DR+ or DR-"))
        };
        let second = match kind {
            "L" => geometry::Element::Line {
                other: [e[0], e[1]],
            },
            "C" => geometry::Element::Arc {
                centre: s
                    .pole
                    .ok_or("no circle centre: program CC before C, CP or LP")?,
                clockwise: dr()?,
                other: [e[0], e[1]],
            },
            _ => {
                let r = value("R")?.ok_or("CR needs its radius R")? * scale;
                let clockwise = dr()?;
                let centre = radius_centre(p, e, r, clockwise)
                    .ok_or("CR: the end point is farther than the diameter from the start")?;
                geometry::Element::Arc {
                    centre,
                    clockwise,
                    other: [e[0], e[1]],
                }
            }
        };
        let lines = matches!(first, geometry::Element::Line { .. })
            && matches!(second, geometry::Element::Line { .. });
        if what == "CHF" && !lines {
            return Err(
                "CHF: the control chamfers only between two straight lines (TNC 620 Klartext user's manual 01/2022 p. 154)"
                    .into(),
            );
        }
        let size = corner
            .tokens
            .iter()
            .enumerate()
            .find(|(k, t)| {
                (what == "RND" && t.address == "R")
                    || (what == "CHF" && *k == 0 && t.value.is_some())
                    || (what == "CHF" && *k == 1 && t.address.is_empty())
            })
            .map(|(k, _)| {
                Ctx {
                    block: corner,
                    ..ctx
                }
                .value(k)
                .map_err(|e| e.to_string())
            })
            .transpose()?
            .ok_or_else(|| {
                if what == "RND" {
                    "RND without its radius R".to_string()
                } else {
                    "CHF without its side length".to_string()
                }
            })?
            * scale;
        let corner_uv = [p[0], p[1]];
        let inserted = match (what.as_str(), first, second) {
            ("RND", geometry::Element::Line { other: a }, geometry::Element::Line { other: b }) => {
                Corner { start: a, corner: corner_uv, end: b }.round(size)
            }
            ("RND", _, _) => geometry::round_elements(first, corner_uv, second, size),
            (_, geometry::Element::Line { other: a }, geometry::Element::Line { other: b }) => {
                Corner { start: a, corner: corner_uv, end: b }.chamfer(size)
            }
            _ => Err(CornerError::Straight),
        }
        .map_err(|e| match e {
            CornerError::ZeroLength => format!("{what}: a contour element of zero length meets the corner"),
            CornerError::Straight => format!("{what}: the two elements make no corner (they meet tangentially)"),
            CornerError::TooLarge { needed, available } if lines => format!(
                "{what} {size}: too large for the corner (it needs {needed:.4} mm along each line; the shorter line is {available:.4} mm)"
            ),
            CornerError::TooLarge { needed, available } => format!(
                "{what} {size}: too large for the corner (it needs {needed:.4} mm from the corner; the element is {available:.4} mm)"
            ),
        })?;
        let at = |uv: [f64; 2]| from_plane(s.plane, [uv[0], uv[1], p[2]]);
        let t1 = at(inserted.from);
        let t2 = at(inserted.to);
        if let (
            "CR",
            geometry::Element::Arc {
                centre, clockwise, ..
            },
        ) = (kind, second)
        {
            // Written back, the CR starts where the rounding ends; the
            // control computes its centre from there: it must be the same.
            let again = radius_centre(
                to_plane(s.plane, t2),
                e,
                value("R")?.unwrap_or(0.0) * scale,
                clockwise,
            );
            if again.is_none_or(|q| (q[0] - centre[0]).hypot(q[1] - centre[1]) > 1e-6) {
                return Err(format!(
                    "{what} before CR: from the rounding's end the CR's radius R picks another centre (its sign decides the arc's side of 180°)"
                )
                .into());
            }
        }
        let points = match inserted.arc {
            Some((centre, clockwise)) => {
                let (f, t) = (to_plane(s.plane, t1), to_plane(s.plane, t2));
                geometry::arc_chords(centre, f, t, clockwise, 0, CHORD_TOLERANCE_MM)
                    .into_iter()
                    .map(|q| from_plane(s.plane, q))
                    .collect()
            }
            None => vec![t2],
        };
        let tangent = match second {
            geometry::Element::Line { .. } => {
                [end[0] - s.pos[0], end[1] - s.pos[1], end[2] - s.pos[2]]
            }
            geometry::Element::Arc {
                centre, clockwise, ..
            } => {
                let r = [inserted.to[0] - centre[0], inserted.to[1] - centre[1]];
                let t = if clockwise {
                    [r[1], -r[0], 0.0]
                } else {
                    [-r[1], r[0], 0.0]
                };
                from_plane(s.plane, t)
            }
        };
        Ok((t1, PendingCorner { points, tangent }))
    }

    /// `APPR`/`DEP` `LT`, `LN`, `CT`, `LCT` with `R0` (the control's
    /// "Approaching and departing a contour": TNC 640 DIN/ISO user's manual
    /// 1/2015 pp. 213 ff. for the positions PS, PH, PA, PE, PN and the
    /// feeds; TNC7 user's manual 81762x-16/-18, "Approach function APPR
    /// LN | CT | LCT", for each path; iTNC 530 user's manual 340 49x-03
    /// p. 230):
    /// - `APPR LT X Y LEN`: a straight line to the auxiliary point `PH`,
    ///   `LEN` before the first contour point `PA` on the line of the first
    ///   contour element, then to `PA`; `DEP LT LEN`: `LEN` on along the
    ///   last element.
    /// - `APPR LN X Y LEN`: `PH` is `LEN` from `PA` on the perpendicular to
    ///   the first element; `DEP LN LEN`: to the point `LEN` from the last
    ///   contour point `PE` on the perpendicular.
    /// - `APPR CT X Y CCA R`: to `PH`, then on the arc of radius `R` and
    ///   centre angle `CCA` tangent to the first element at `PA`; a negative
    ///   `R` puts the arc on the other side; `DEP CT CCA R` likewise from
    ///   `PE`, tangent to the last element.
    /// - `APPR LCT X Y R`: a straight line tangent to the arc of radius `R`
    ///   that is tangent to the first element at `PA`, then that arc;
    ///   `DEP LCT X Y R`: the arc tangent to the last element, then the
    ///   straight line tangent to it to the end point `PN`.
    ///
    /// The side of the contour (which the manual takes from `RL`/`RR`, and
    /// with it the arcs' sense) is, with `R0`, volcomp's reading: for an
    /// approach the side the starting point `PS` lies on (relative to the
    /// first element's line; on the line: an error), for a departure the
    /// side of the last approach (`RL`/`RR`, which would give it, also move
    /// the path by the tool radius: refused as on every move). The TNC 640
    /// and TNC7 stop `APPR CT` with `R0` with an error; the iTNC 530 runs
    /// it: volcomp reads it as the iTNC 530. `PS` → `PH` runs at the feed
    /// last programmed (at `FMAX` when the block before was rapid) for
    /// `LT`, `LN`, `CT`, at the block's feed for `LCT` (iTNC 530 p. 230);
    /// the rest at the block's feed. A tool-axis word in `APPR` is reached
    /// on the way to `PH` (TNC7 "APPR LCT": "simultaneously in three axes";
    /// the TNC 640 1/2015 text moves in the plane first: not followed,
    /// kept as `APPR LT` read it before); `DEP LCT`'s tool-axis word is
    /// reached after `PN` in the plane (TNC 640 1/2015 p. 213). The first
    /// contour element after an `APPR` must be a straight line `L`. The
    /// polar forms `APPR PLT`, `PLN`, `PCT`, `PLCT` and `DEP PLCT` are the
    /// same paths with the contour point (`DEP PLCT`: the end point `PN`)
    /// given as `PR`/`IPR` `PA`/`IPA` about the pole `CC`, which must be
    /// programmed before (TNC7 user's manual 81762x-16, "Approach
    /// functions APPR CT and APPR PCT": "you must first define a pole CC");
    /// the control has no polar `DEP LT`, `LN`, `CT` (they take no point).
    fn approach_departure(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
    ) -> Result<Statement, GcodeError> {
        let b = c.block;
        let approach = b.address(0) == "APPR";
        let what = format!("{} {}", b.address(0), b.address(1));
        // The polar forms: the contour point (`DEP PLCT`: the end point)
        // in polar coordinates about the pole (TNC7 user's manual
        // 81762x-16, "Overview of path shapes": APPR PLT, PLN, PCT, PLCT;
        // DEP PLCT only).
        let (form, polar) = match b.address(1) {
            f @ ("LT" | "LN" | "CT" | "LCT") => (f, false),
            "PLT" if approach => ("LT", true),
            "PLN" if approach => ("LN", true),
            "PCT" if approach => ("CT", true),
            "PLCT" => ("LCT", true),
            "PLT" | "PLN" | "PCT" => {
                return Err(c.error(
                    &format!(
                        "{what}: the control departs in polar coordinates with DEP PLCT only (DEP LT, LN, CT take no end point)"
                    ),
                    Some(1),
                ));
            }
            _ => return Err(c.unread(&what, Some(1))),
        };
        // The point the block programs: X Y Z, or PR PA (and the tool-axis
        // word) about the pole.
        let programmed = |s: &State| -> Result<[f64; 3], GcodeError> {
            if polar {
                let pole = s.pole.ok_or_else(|| {
                    c.error(
                        &format!("{what} without a pole: program CC before it"),
                        Some(0),
                    )
                })?;
                polar_words(c, s, pole, 2)
            } else {
                xyz_words(c, s.pos, if s.inch { 25.4 } else { 1.0 }, 2)
            }
        };
        // The feed and rapid of the block before (PS → PH).
        let (feed_before, rapid_before) = (s.feed, s.last_rapid);
        self.compensation(c, s);
        let feed = self.block_feed(c, s, 2)?;
        self.refuse_compensation(c, s)?;
        let scale = if s.inch { 25.4 } else { 1.0 };
        let word = |name: &str| {
            b.tokens
                .iter()
                .position(|t| t.address == name && t.value.is_some())
                .map(|k| c.value(k))
                .transpose()
        };
        let needed = |name: &str, v: Option<f64>| {
            v.ok_or_else(|| c.error(&format!("{what} without its {name}"), Some(0)))
        };
        // `CCA`, the centre angle of a CT arc: above 0, at most 360.
        let centre_angle = || {
            let cca = needed("centre angle CCA", word("CCA")?)?;
            if cca > 0.0 && cca <= 360.0 {
                Ok(cca)
            } else {
                Err(c.error(
                    &format!("{what}: the centre angle CCA must be above 0 and at most 360"),
                    Some(0),
                ))
            }
        };
        // `R…` the radius (not the `R0` of the compensation).
        let radius = b
            .tokens
            .iter()
            .enumerate()
            .find(|(_, t)| {
                t.address == "R"
                    && t.value.is_some()
                    && !(t.number() == Some(0.0) && t.value_span.len() == 1)
            })
            .map(|(k, _)| c.value(k))
            .transpose()?
            .map(|r| r * scale);
        let len = match form {
            "LT" | "LN" => Some(needed("length LEN", word("LEN")?)?.abs() * scale),
            _ => None,
        };
        let unit2 = |d: [f64; 3]| {
            let n = d[0].hypot(d[1]);
            (n > 1e-12).then(|| [d[0] / n, d[1] / n])
        };
        let plane = s.plane;
        let at = |uv: [f64; 2], w: f64| from_plane(plane, [uv[0], uv[1], w]);
        let block_feed = feed;
        let before = if rapid_before {
            Feed::Rapid
        } else {
            Feed::PerMinute(feed_before)
        };
        // (point, feed) in program coordinates, in order.
        let mut path: Vec<([f64; 3], Feed)> = Vec::new();
        let arc_points =
            |centre: [f64; 2], from: [f64; 2], to: [f64; 2], clockwise: bool, w: f64| {
                arc_chords(
                    centre,
                    [from[0], from[1], w],
                    [to[0], to[1], w],
                    clockwise,
                    0,
                    CHORD_TOLERANCE_MM,
                )
                .into_iter()
                .map(|q| from_plane(plane, q))
                .collect::<Vec<_>>()
            };
        if approach {
            let first = programmed(s)?;
            // The first contour element: a straight line after the APPR block.
            let end = self
                .ahead
                .as_ref()
                .filter(|(_, next)| next.address(0) == "L")
                .and_then(|(_, next)| xyz_words(&Ctx { block: next, ..*c }, first, scale, 1).ok());
            let pa = to_plane(plane, first);
            let direction = end
                .map(|e| to_plane(plane, e))
                .and_then(|e| unit2([e[0] - pa[0], e[1] - pa[1], 0.0]))
                .ok_or_else(|| {
                    c.unread(
                        &format!(
                            "{what} before anything but a straight line (L) in the working plane"
                        ),
                        Some(0),
                    )
                })?;
            let ps = to_plane(plane, s.pos);
            let side = geometry::ContourContact::side_of([pa[0], pa[1]], direction, [ps[0], ps[1]]);
            let contact = |left: bool| geometry::ContourContact {
                point: [pa[0], pa[1]],
                direction,
                left,
            };
            let side_needed = || {
                side.ok_or_else(|| {
                    c.error(
                        &format!(
                            "{what} with R0: the starting point lies on the first contour element's line, so it gives no side of the contour"
                        ),
                        Some(0),
                    )
                })
            };
            match form {
                "LT" => {
                    let len = len.unwrap_or(0.0);
                    let h = [pa[0] - len * direction[0], pa[1] - len * direction[1]];
                    path.push((at(h, pa[2]), before));
                    path.push((first, block_feed));
                    s.contour_left = side;
                }
                "LN" => {
                    let left = side_needed()?;
                    let h = contact(left).perpendicular(len.unwrap_or(0.0));
                    path.push((at(h, pa[2]), before));
                    path.push((first, block_feed));
                    s.contour_left = Some(left);
                }
                "CT" => {
                    let left = side_needed()?;
                    let r = needed("radius R", radius)?;
                    let cca = centre_angle()?;
                    // A negative R: the arc on the other side.
                    let arc = contact(left != (r < 0.0)).tangent_arc(r, cca, true);
                    path.push((at(arc.away, pa[2]), before));
                    for p in arc_points(arc.centre, arc.away, [pa[0], pa[1]], arc.clockwise, pa[2])
                    {
                        path.push((p, block_feed));
                    }
                    s.contour_left = Some(left);
                }
                _ => {
                    let left = side_needed()?;
                    let r = needed("radius R", radius)?;
                    let arc = contact(left)
                        .line_and_arc(r, [ps[0], ps[1]], true)
                        .ok_or_else(|| {
                            c.error(&format!("{what}: the starting point lies within the arc's circle (no tangent line)"), Some(0))
                        })?;
                    path.push((at(arc.away, pa[2]), block_feed));
                    for p in arc_points(arc.centre, arc.away, [pa[0], pa[1]], arc.clockwise, pa[2])
                    {
                        path.push((p, block_feed));
                    }
                    s.contour_left = Some(left);
                }
            }
            s.tangent = Some(at(direction, 0.0));
        } else {
            let direction = s
                .tangent
                .map(|t| to_plane(plane, t))
                .and_then(unit2)
                .ok_or_else(|| {
                    c.error(
                        &format!("{what} needs a contour element before it (its direction)"),
                        Some(0),
                    )
                })?;
            let pe = to_plane(plane, s.pos);
            let left = || {
                s.contour_left.ok_or_else(|| {
                    c.error(
                        &format!(
                            "{what} with R0: no side of the contour (volcomp takes it from an APPR LN, CT or LCT before; RL/RR would give it)"
                        ),
                        Some(0),
                    )
                })
            };
            let contact = |left: bool| geometry::ContourContact {
                point: [pe[0], pe[1]],
                direction,
                left,
            };
            match form {
                "LT" => {
                    let len = len.unwrap_or(0.0);
                    path.push((
                        at(
                            [pe[0] + len * direction[0], pe[1] + len * direction[1]],
                            pe[2],
                        ),
                        block_feed,
                    ));
                }
                "LN" => {
                    let n = contact(left()?).perpendicular(len.unwrap_or(0.0));
                    path.push((at(n, pe[2]), block_feed));
                }
                "CT" => {
                    let r = needed("radius R", radius)?;
                    let cca = centre_angle()?;
                    let arc = contact(left()? != (r < 0.0)).tangent_arc(r, cca, false);
                    for p in arc_points(arc.centre, [pe[0], pe[1]], arc.away, arc.clockwise, pe[2])
                    {
                        path.push((p, block_feed));
                    }
                }
                _ => {
                    let r = needed("radius R", radius)?;
                    let pn = to_plane(plane, programmed(s)?);
                    let arc = contact(left()?)
                        .line_and_arc(r, [pn[0], pn[1]], false)
                        .ok_or_else(|| {
                            c.error(&format!("{what}: the end point lies within the arc's circle (no tangent line)"), Some(0))
                        })?;
                    for p in arc_points(arc.centre, [pe[0], pe[1]], arc.away, arc.clockwise, pe[2])
                    {
                        path.push((p, block_feed));
                    }
                    path.push((at([pn[0], pn[1]], pe[2]), block_feed));
                    if (pn[2] - pe[2]).abs() > 0.0 {
                        path.push((at([pn[0], pn[1]], pn[2]), block_feed));
                    }
                }
            }
            if let [.., a, b] = path.as_slice() {
                let d = [b.0[0] - a.0[0], b.0[1] - a.0[1], b.0[2] - a.0[2]];
                if dot(d, d) > 0.0 {
                    s.tangent = Some(d);
                }
            } else if let Some((p, _)) = path.first() {
                let d = [p[0] - s.pos[0], p[1] - s.pos[1], p[2] - s.pos[2]];
                if dot(d, d) > 0.0 {
                    s.tangent = Some(d);
                }
            }
        }
        let mut moves = Vec::with_capacity(path.len());
        let mut steps = Vec::with_capacity(path.len());
        let mut start = s.position;
        for (p, f) in &path {
            if let Feed::PerMinute(v) = f
                && *v <= 0.0
            {
                return Err(c.error("a feed move without a feed rate (F)", Some(0)));
            }
            let (motion, step) = self.piece(c, s, start, *p, *f)?;
            start = motion.end;
            moves.push(motion);
            steps.push(step);
        }
        event.moves = Moves::Cycle { moves, steps };
        if let Some((p, _)) = path.last() {
            s.pos = *p;
        }
        self.m_codes(c, s, event, Some(2))
    }

    /// Straight moves through `points` (program coordinates) from `start`,
    /// the pieces of one block that the seam cannot carry as one move
    /// (`Moves::Cycle`, written back flat as `L` blocks).
    fn pieces(
        &self,
        c: &Ctx<'_>,
        s: &State,
        start: Axes,
        points: &[[f64; 3]],
        feed: Feed,
    ) -> Result<Moves, GcodeError> {
        if let Feed::PerMinute(f) = feed
            && f <= 0.0
        {
            return Err(c.error("a feed move without a feed rate (F)", Some(0)));
        }
        let mut start = start;
        let mut moves = Vec::with_capacity(points.len());
        let mut steps = Vec::with_capacity(points.len());
        for p in points {
            let (motion, step) = self.piece(c, s, start, *p, feed)?;
            start = motion.end;
            moves.push(motion);
            steps.push(step);
        }
        Ok(Moves::Cycle { moves, steps })
    }

    /// One straight piece from `start` to `p` (program coordinates) at
    /// `feed`, and the step a writer writes it as.
    fn piece(
        &self,
        c: &Ctx<'_>,
        s: &State,
        start: Axes,
        p: [f64; 3],
        feed: Feed,
    ) -> Result<(Motion, CycleStep), GcodeError> {
        let end = self.to_frame(s, p, s.rot);
        if !end.is_finite() {
            return Err(GcodeError::at(
                ErrorKind::NonFinite,
                c.line,
                c.raw,
                0,
                c.raw.len(),
            ));
        }
        let step = if feed == Feed::Rapid {
            CycleStep::Rapid(p)
        } else {
            CycleStep::Feed(p)
        };
        Ok((self.straight(s.frame(), false, start, end, feed), step))
    }

    /// `RND R…` / `CHF …`: the rounding arc (as chords within
    /// [`CHORD_TOLERANCE_MM`]) or the chamfer planned at the line before.
    fn corner(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
    ) -> Result<Statement, GcodeError> {
        let what = c.block.address(0);
        let pending = match s.corner.take() {
            Some(Ok(p)) => p,
            Some(Err(CornerRefusal::Control(why))) => return Err(c.error(&why, Some(0))),
            Some(Err(CornerRefusal::Unread(what))) => return Err(c.unread(&what, Some(0))),
            None => {
                return Err(c.error(
                    &format!(
                        "{what} must follow a straight line (L) or an arc in the working plane"
                    ),
                    Some(0),
                ));
            }
        };
        // `F` here is for the rounding only (then the feed before it again).
        let mut feed = s.feed;
        for (k, t) in c.block.tokens.iter().enumerate().skip(1) {
            if t.address == "F" && t.value.is_some() {
                feed = self.feed_value(c, s, k)?;
            }
        }
        if feed <= 0.0 {
            return Err(c.error("a feed move without a feed rate (F)", Some(0)));
        }
        self.refuse_compensation(c, s)?;
        event.moves = self.pieces(c, s, s.position, &pending.points, Feed::PerMinute(feed))?;
        s.tangent = Some(pending.tangent);
        Ok(Statement::Other)
    }

    /// M91/M92: the words are machine coordinates (not compensated; reported).
    fn machine_datum_move(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
        feed: Feed,
    ) -> Result<Statement, GcodeError> {
        let scale = if s.inch { 25.4 } else { 1.0 };
        let mut end = if self.frame() == Frame::Joint && s.tilt.is_none() {
            s.position
        } else {
            return Err(c.unread("M91/M92 under PLANE or M128", Some(0)));
        };
        for (k, t) in c.block.tokens.iter().enumerate() {
            let axis = match t.address.as_str() {
                "X" => Axis::X,
                "Y" => Axis::Y,
                "Z" => Axis::Z,
                "A" => Axis::A,
                "B" => Axis::B,
                "C" => Axis::C,
                "IX" | "IY" | "IZ" | "IA" | "IB" | "IC" => {
                    return Err(c.unread("M91/M92 with incremental words", Some(k)));
                }
                _ => continue,
            };
            let v = c.value(k)?;
            end.set(axis, if axis.is_rotary() { v } else { v * scale });
        }
        // The program position becomes the machine position seen in the program frame.
        let o = self.origin();
        let p = o.to_program(&end);
        s.pos = [p.x, p.y, p.z];
        s.rot = [
            end.a - self.setup.preset.a,
            end.b - self.setup.preset.b,
            end.c - self.setup.preset.c,
        ];
        let start = s.position;
        let m = self.straight(Frame::Joint, true, start, end, feed);
        event.moves = Moves::Home(vec![m]);
        s.tangent = None;
        self.m_codes(c, s, event, Some(1))
    }

    fn solver(&self, c: &Ctx<'_>) -> Result<&Arc<dyn OrientationSolver>, GcodeError> {
        self.setup.orientation.as_ref().ok_or_else(|| {
            c.error(
                "this block needs the machine's kinematics to solve the rotary axes: give --machine",
                Some(0),
            )
        })
    }

    #[allow(clippy::too_many_arguments)]
    fn push_motion(
        &self,
        c: &Ctx<'_>,
        s: &State,
        event: &mut BlockEvent,
        kind: MotionKind,
        start: Axes,
        end: Axes,
        feed: Feed,
    ) -> Result<(), GcodeError> {
        if !end.is_finite() {
            return Err(GcodeError::at(
                ErrorKind::NonFinite,
                c.line,
                c.raw,
                0,
                c.raw.len(),
            ));
        }
        if let Feed::PerMinute(f) = feed
            && f <= 0.0
        {
            return Err(c.error("a feed move without a feed rate (F)", Some(0)));
        }
        let mut m = Motion {
            kind,
            frame: s.frame(),
            machine_coordinates: false,
            start,
            end,
            feed,
            duration_min: 0.0,
        };
        m.duration_min = duration_min(&m, self.setup.rapid_mm_per_min);
        event.moves = Moves::Move(m);
        Ok(())
    }

    /// M functions of a block (from token `from`); `None`: an M-only block.
    fn m_codes(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
        from: Option<usize>,
    ) -> Result<Statement, GcodeError> {
        let mut end = Statement::Other;
        let mut called = false;
        for (k, t) in c.block.tokens.iter().enumerate().skip(from.unwrap_or(0)) {
            if t.address != "M" {
                continue;
            }
            let Some(v) = t.number() else { continue };
            match v as i64 {
                2 | 30 => end = Statement::End,
                126 => s.shortest = true,
                127 => s.shortest = false,
                128 => s.tcpm = true,
                129 => s.tcpm = false,
                99 if c.block.address(0) != "CYCL" => {
                    self.cycle_call(c, s, event, CallKind::Here)?;
                    s.modal_call = false;
                    called = true;
                }
                89 => s.modal_call = true,
                140 => {
                    return Err(c.unread("M140", Some(k)));
                }
                _ => {}
            }
        }
        // M89 (modal cycle call, iTNC 530 User's Manual "Miscellaneous
        // functions"): the cycle runs after every positioning block.
        if s.modal_call && !called && matches!(event.moves, Moves::Move(_)) {
            self.cycle_call(c, s, event, CallKind::Here)?;
        }
        Ok(end)
    }

    /// `CC`: the pole (absolute, incremental, or the last position).
    fn pole(&self, c: &Ctx<'_>, s: &mut State) -> Result<(), GcodeError> {
        let scale = if s.inch { 25.4 } else { 1.0 };
        let cur = to_plane(s.plane, s.pos);
        let mut pole = [cur[0], cur[1]];
        let mut any = false;
        for (k, t) in c.block.tokens.iter().enumerate().skip(1) {
            let (inc, letter) = match t.address.as_bytes() {
                [b'I', l] => (true, *l),
                [l] => (false, *l),
                _ => continue,
            };
            let Some(slot) = plane_slot(s.plane, letter) else {
                if matches!(letter, b'X' | b'Y' | b'Z') {
                    return Err(c.error(
                        "CC: the pole's coordinate is not in the working plane",
                        Some(k),
                    ));
                }
                continue;
            };
            let v = c.value(k)? * scale;
            pole[slot] = if inc { cur[slot] + v } else { v };
            any = true;
        }
        let _ = any;
        s.pole = Some(pole);
        Ok(())
    }

    fn require_pole(&self, c: &Ctx<'_>, s: &State) -> Result<[f64; 2], GcodeError> {
        s.pole
            .ok_or_else(|| c.error("no circle centre: program CC before C, CP or LP", Some(0)))
    }

    /// `LP PR PA`: a straight move to polar coordinates about the pole.
    fn polar_line(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
    ) -> Result<Statement, GcodeError> {
        let pole = self.require_pole(c, s)?;
        let target = polar_words(c, s, pole, 1)?;
        self.compensation(c, s);
        let feed = self.block_feed(c, s, 1)?;
        self.refuse_compensation(c, s)?;
        let start = s.position;
        let end = self.to_frame(s, target, s.rot);
        let d = [
            target[0] - s.pos[0],
            target[1] - s.pos[1],
            target[2] - s.pos[2],
        ];
        if dot(d, d) > 0.0 {
            s.tangent = Some(d);
        }
        s.pos = target;
        let kind = if feed == Feed::Rapid {
            MotionKind::Rapid
        } else {
            MotionKind::Linear
        };
        self.push_motion(c, s, event, kind, start, end, feed)?;
        self.m_codes(c, s, event, Some(1))
    }

    /// `C`, `CR`, `CT`, `CP`: circles and helices in the working plane.
    fn circle(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
    ) -> Result<Statement, GcodeError> {
        let b = c.block;
        let kind = b.address(0).to_string();
        let scale = if s.inch { 25.4 } else { 1.0 };
        let cur = to_plane(s.plane, s.pos);
        let mut end = cur;
        let mut dr: Option<f64> = None;
        let mut radius: Option<f64> = None;
        let mut pa: Option<(bool, f64)> = None;
        for (k, t) in b.tokens.iter().enumerate().skip(1) {
            let name = t.address.as_str();
            match name {
                "DR" => dr = Some(c.value(k)?),
                "R" if kind == "CR" => radius = Some(c.value(k)? * scale),
                "PA" => pa = Some((false, c.value(k)?)),
                "IPA" => pa = Some((true, c.value(k)?)),
                _ => {
                    let (inc, letter) = match t.address.as_bytes() {
                        [b'I', l] => (true, *l),
                        [l] => (false, *l),
                        _ => continue,
                    };
                    let slot = match (s.plane, letter) {
                        (_, b'X' | b'Y' | b'Z') => to_plane_index(s.plane, letter),
                        _ => continue,
                    };
                    if t.value.is_none() {
                        continue;
                    }
                    let v = c.value(k)? * scale;
                    end[slot] = if inc { cur[slot] + v } else { v };
                }
            }
        }
        let (centre, clockwise, turns) = match kind.as_str() {
            "C" => {
                let pole = self.require_pole(c, s)?;
                let Some(dr) = dr else {
                    return Err(c.error("C needs its direction DR+ or DR-", Some(0)));
                };
                (pole, dr < 0.0, 0)
            }
            "CR" => {
                let Some(r) = radius else {
                    return Err(c.error("CR needs its radius R", Some(0)));
                };
                let Some(dr) = dr else {
                    return Err(c.error("CR needs its direction DR+ or DR-", Some(0)));
                };
                let centre = radius_centre(cur, end, r, dr < 0.0).ok_or_else(|| {
                    c.error(
                        "CR: the end point is farther than the diameter from the start",
                        Some(0),
                    )
                })?;
                (centre, dr < 0.0, 0)
            }
            "CT" => {
                let t = s.tangent.map(|t| to_plane(s.plane, t)).ok_or_else(|| {
                    c.error(
                        "CT needs a contour element before it (its tangent)",
                        Some(0),
                    )
                })?;
                let (centre, clockwise) =
                    tangent_centre(cur, end, [t[0], t[1]]).ok_or_else(|| {
                        c.error("CT: the end point lies on the tangent (no arc)", Some(0))
                    })?;
                (centre, clockwise, 0)
            }
            _ => {
                // CP: polar arc (helix with IZ) about the pole.
                let pole = self.require_pole(c, s)?;
                let Some(dr) = dr else {
                    return Err(c.error("CP needs its direction DR+ or DR-", Some(0)));
                };
                let Some((inc, angle)) = pa else {
                    return Err(c.error("CP needs its angle PA or IPA", Some(0)));
                };
                let (r, a0) = polar_of(pole, cur);
                let clockwise = dr < 0.0;
                let (a1, turns) = if inc {
                    if (angle < 0.0) != clockwise && angle != 0.0 {
                        return Err(c.error(
                            "CP: the sign of IPA must agree with the direction DR",
                            Some(0),
                        ));
                    }
                    let full = (angle.abs() / 360.0 - 1e-9).floor().max(0.0);
                    (a0 + angle, full as u32)
                } else {
                    (angle, 0)
                };
                let (sa, ca) = a1.to_radians().sin_cos();
                end[0] = pole[0] + r * ca;
                end[1] = pole[1] + r * sa;
                (pole, clockwise, turns)
            }
        };
        // In a tilted working plane whose normal is not the workpiece's,
        // the arc lies in the tilted plane: handed on as chords.
        let tilted = s.tilt.is_some_and(|r| {
            let n = from_plane(s.plane, [0.0, 0.0, 1.0]);
            let rn = mat_vec(&r, n);
            (dot(rn, n) - 1.0).abs() > 1e-9
        });
        self.compensation(c, s);
        let feed = self.block_feed(c, s, 1)?;
        self.refuse_compensation(c, s)?;
        let target = from_plane(s.plane, end);
        let centre_prog = from_plane(s.plane, [centre[0], centre[1], cur[2]]);
        let start = s.position;
        let end_axes = self.to_frame(s, target, s.rot);
        let centre_frame = self.to_frame(s, centre_prog, s.rot).xyz();
        // The tangent at the end: perpendicular to the radius, in the sense of travel.
        let re = [end[0] - centre[0], end[1] - centre[1]];
        let tan = if clockwise {
            [re[1], -re[0], 0.0]
        } else {
            [-re[1], re[0], 0.0]
        };
        s.tangent = Some(from_plane(s.plane, tan));
        s.pos = target;
        // A rounding next (`RND`, read after an arc of less than a full
        // turn in the working plane): the arc ends at its tangent point.
        let planned = match &self.ahead {
            Some((corner, next)) if matches!(corner.address(0), "RND" | "CHF") => {
                Some(if turns > 0 || (end[2] - cur[2]).abs() > 1e-9 {
                    Err(CornerRefusal::Unread(format!(
                        "{} after a helix or a full turn",
                        corner.address(0)
                    )))
                } else {
                    let first = geometry::Element::Arc {
                        centre,
                        clockwise,
                        other: [cur[0], cur[1]],
                    };
                    self.plan_corner(c, s, corner, next, first, cur[2], false)
                })
            }
            _ => None,
        };
        let arc_end = planned
            .as_ref()
            .and_then(|p| p.as_ref().ok())
            .map(|(t1, _)| to_plane(s.plane, *t1));
        if let Some(p) = planned {
            s.corner = Some(p.map(|(_, q)| q));
        }
        if tilted || arc_end.is_some() {
            // As chords (in a tilted plane the arc lies in it; an arc ended
            // early is written back flat, as the line before a rounding).
            let _ = end_axes;
            let feed = if feed == Feed::Rapid {
                Feed::PerMinute(self.setup.rapid_mm_per_min)
            } else {
                feed
            };
            let points: Vec<[f64; 3]> = arc_chords(
                centre,
                cur,
                arc_end.unwrap_or(end),
                clockwise,
                turns,
                CHORD_TOLERANCE_MM,
            )
            .into_iter()
            .map(|q| from_plane(s.plane, q))
            .collect();
            event.moves = self.pieces(c, s, start, &points, feed)?;
            return self.m_codes(c, s, event, Some(1));
        }
        let kind = MotionKind::Arc {
            clockwise,
            centre: centre_frame,
            plane: s.plane,
            turns,
        };
        let feed = if feed == Feed::Rapid {
            Feed::PerMinute(self.setup.rapid_mm_per_min)
        } else {
            feed
        };
        self.push_motion(c, s, event, kind, start, end_axes, feed)?;
        self.m_codes(c, s, event, Some(1))
    }

    /// `CYCL DEF n …`: a datum shift, a cycle that does not move (passed
    /// through), a transformation volcomp does not read (refused here), or
    /// a machining cycle (defined; expanded or refused at its call).
    fn cycle_def(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
    ) -> Result<(), GcodeError> {
        let b = c.block;
        let n = match b.tokens.get(1).and_then(|t| t.number()) {
            // `DEF9.0`, `DEF9 .0`.
            Some(v) => {
                let fraction = b
                    .tokens
                    .get(2)
                    .filter(|t| t.address.is_empty() && c.raw.get(t.span.start) == Some(&b'.'))
                    .and_then(|t| t.number())
                    .unwrap_or(0.0);
                v + fraction
            }
            None => {
                let Some(t) = b.tokens.get(2) else {
                    return Err(c.error("CYCL DEF without its number", Some(0)));
                };
                let Some(n) = t.number() else {
                    return Err(c.error("CYCL DEF without its number", Some(2)));
                };
                n
            }
        };
        let major = n.trunc() as u32;
        let minor = ((n - n.trunc()) * 10.0).round() as u32;
        match major {
            7 => self.datum_shift(c, s, minor),
            // 19.0 WORKING PLANE, 19.1 its angles.
            19 if minor <= 1 => self.working_plane_cycle(c, s, event, minor),
            19 => Err(c.unread("CYCL DEF 19", Some(2))),
            9 => {
                // 9.1 DWELL v: effective at its definition (seconds).
                if minor == 1
                    && let Some(k) = (3..b.tokens.len())
                        .rev()
                        .find(|&k| b.tokens[k].value.is_some())
                {
                    s.time_min += c.value(k)?.max(0.0) / 60.0;
                }
                Ok(())
            }
            n if cycles::transforms(n).is_some() => {
                Err(c.unread(cycles::transforms(n).unwrap_or("CYCL DEF"), Some(2)))
            }
            n if cycles::passes_through(n) => Ok(()),
            _ => {
                let value = |k: usize| b.tokens[k].value.as_ref().map_or(0.0, |v| c.q.value(v));
                let def = cycles::define(b, major, minor, c.line, s.cycle.as_ref(), &value)
                    .map_err(|m| c.error(&m, Some(2)))?;
                s.cycle = Some(def);
                Ok(())
            }
        }
    }

    /// `PATTERN DEF …`: the points of `CYCL CALL PAT`.
    fn pattern_def(&self, c: &Ctx<'_>, s: &mut State) -> Result<(), GcodeError> {
        let p = cycles::pattern(c.block, c.line, s.plane, s.inch, &|v| c.q.value(v))
            .map_err(|e| c.cycle_error(e, Some(0)))?;
        s.pattern = Some(p);
        Ok(())
    }

    /// `CYCL DEF 7.0 DATUM SHIFT`, `7.1 X…`, `7.2 Y…`, `7.3 Z…`.
    fn datum_shift(&self, c: &Ctx<'_>, s: &mut State, minor: u32) -> Result<(), GcodeError> {
        if minor == 0 {
            if c.block.tokens.iter().any(|t| t.address == "#") || c.block.code.contains('#') {
                return Err(c.unread("CYCL DEF 7 from the datum table (#)", Some(0)));
            }
            return Ok(());
        }
        let scale = if s.inch { 25.4 } else { 1.0 };
        for (k, t) in c.block.tokens.iter().enumerate().skip(3) {
            let (inc, letter) = match t.address.as_bytes() {
                [b'I', l] => (true, *l),
                [l] => (false, *l),
                _ => continue,
            };
            let slot = match letter {
                b'X' => 0,
                b'Y' => 1,
                b'Z' => 2,
                _ => continue,
            };
            if t.value.is_none() {
                continue;
            }
            let v = c.value(k)? * scale;
            let shift = if s.tilt.is_some() {
                &mut s.shift_tilted
            } else {
                &mut s.shift
            };
            shift[slot] = if inc { shift[slot] + v } else { v };
        }
        Ok(())
    }

    /// `CYCL CALL`, `M99`, `CYCL CALL POS`, `CYCL CALL PAT`: run the
    /// defined cycle ([`cycles::expand`]) here, at a position, or at each
    /// point of the pattern.
    fn cycle_call(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
        kind: CallKind,
    ) -> Result<(), GcodeError> {
        let Some(cycle) = s.cycle.clone() else {
            return Err(c.error("a cycle call without a cycle defined (CYCL DEF)", Some(0)));
        };
        self.refuse_compensation(c, s)?;
        let base = cycles::Call {
            start: s.pos,
            plane: s.plane,
            inch: s.inch,
            spindle_rpm: s.spindle,
            tool_radius: s.tool_radius,
            surface_shift: 0.0,
        };
        let axis = tool_axis_index(s.plane);
        let feed = |s: &mut State| -> Result<Option<f64>, GcodeError> {
            let given = c
                .block
                .tokens
                .iter()
                .any(|t| matches!(t.address.as_str(), "F" | "FMAX" | "FAUTO"));
            Ok(match self.block_feed(c, s, 2)? {
                Feed::PerMinute(f) if given => Some(f),
                _ => None,
            })
        };
        let mut steps: Vec<cycles::Step> = Vec::new();
        let expand = |call: &cycles::Call| {
            cycles::expand(&cycle, call).map_err(|e| c.cycle_error(e, Some(0)))
        };
        let to = |p: [f64; 3], f: Option<f64>| match f {
            Some(f) => cycles::Step::Feed(p, f),
            None => cycles::Step::Rapid(p),
        };
        match kind {
            CallKind::Here => steps = expand(&base)?,
            CallKind::Position => {
                // CYCL CALL POS X Y Z: the three coordinates, the tool-axis one
                // an additional shift of the surface (TNC 640 Cycle
                // Programming, "Calling a cycle with CYCL CALL POS").
                let scale = if s.inch { 25.4 } else { 1.0 };
                let mut target = [None::<f64>; 3];
                for (k, t) in c.block.tokens.iter().enumerate().skip(3) {
                    let Some((inc, slot)) = xyz_address(t.address.as_str()) else {
                        continue;
                    };
                    let v = c.value(k)? * scale;
                    target[slot] = Some(if inc { s.pos[slot] + v } else { v });
                }
                let [Some(x), Some(y), Some(z)] = target else {
                    return Err(c.error("CYCL CALL POS needs all three coordinates X Y Z", Some(2)));
                };
                let target = [x, y, z];
                let f = feed(s)?;
                let call = cycles::Call {
                    start: target,
                    surface_shift: target[axis],
                    ..base
                };
                let Some((surface, height, up)) = cycles::levels(&cycle, &call) else {
                    return Err(c.unread(
                        &format!(
                            "CYCL CALL POS with CYCL DEF {} (no surface Q203)",
                            cycle.number
                        ),
                        Some(2),
                    ));
                };
                let mut at = s.pos;
                if (at[axis] - surface) * up < 0.0 {
                    // Below the surface: first up to the clearance height.
                    at[axis] = height;
                    steps.push(to(at, f));
                }
                let mut over = target;
                over[axis] = at[axis];
                steps.push(to(over, f));
                steps.push(to(target, f));
                steps.extend(expand(&call)?);
            }
            CallKind::Pattern => {
                let Some(pattern) = s.pattern.clone() else {
                    return Err(c.error("CYCL CALL PAT without a PATTERN DEF before it", Some(2)));
                };
                let f = feed(s)?;
                let mut at = s.pos;
                for p in &pattern.points {
                    let plane_point = from_plane(s.plane, [p[0], p[1], 0.0]);
                    let call = cycles::Call {
                        surface_shift: p[2],
                        ..base
                    };
                    let Some(height) = cycles::clearance_height(&cycle, &call, s.pos[axis]) else {
                        return Err(c.unread(
                            &format!(
                                "CYCL CALL PAT with CYCL DEF {} (no surface Q203)",
                                cycle.number
                            ),
                            Some(2),
                        ));
                    };
                    if (at[axis] - height).abs() > 1e-12 {
                        at[axis] = height;
                        steps.push(cycles::Step::Rapid(at));
                    }
                    let mut next = plane_point;
                    next[axis] = height;
                    steps.push(to(next, f));
                    let call = cycles::Call {
                        start: next,
                        ..call
                    };
                    let more = expand(&call)?;
                    for st in &more {
                        if let cycles::Step::Rapid(q) | cycles::Step::Feed(q, _) = st {
                            at = *q;
                        }
                    }
                    at = if more.is_empty() { next } else { at };
                    steps.extend(more);
                }
            }
        }
        let mut moves = Vec::new();
        let mut done = Vec::new();
        let mut start = s.position;
        let mut last = s.pos;
        for st in &steps {
            let (p, feed) = match *st {
                cycles::Step::Rapid(p) => (p, Feed::Rapid),
                cycles::Step::Feed(p, f) => (p, Feed::PerMinute(f)),
                cycles::Step::Dwell(seconds) => {
                    s.time_min += seconds / 60.0;
                    done.push(CycleStep::Dwell { seconds });
                    continue;
                }
            };
            let (motion, step) = self.piece(c, s, start, p, feed)?;
            start = motion.end;
            moves.push(motion);
            done.push(step);
            last = p;
        }
        // A cycle called with M99 on a positioning block: that move first.
        if let Moves::Move(m) = &event.moves {
            moves.insert(0, *m);
            done.insert(
                0,
                if m.kind == MotionKind::Rapid {
                    CycleStep::Rapid(s.pos)
                } else {
                    CycleStep::Feed(s.pos)
                },
            );
        }
        s.pos = last;
        s.tangent = None;
        event.moves = Moves::Cycle { moves, steps: done };
        Ok(())
    }

    /// `PLANE …`: the working plane (TNC 640 user's manual, "Multiple-axis
    /// machining › The PLANE function": SPATIAL, PROJECTED, EULER, VECTOR,
    /// POINTS, RELATIVE, AXIAL, RESET; "Specifying the positioning behavior
    /// of the PLANE function": MOVE, TURN, STAY, SEQ, COORD ROT / TABLE ROT).
    fn plane(&self, c: &Ctx<'_>, s: &mut State, event: &mut BlockEvent) -> Result<(), GcodeError> {
        let b = c.block;
        let kind = b.address(1).to_string();
        let named = |name: &str| -> Result<Option<f64>, GcodeError> {
            match b.tokens.iter().position(|t| t.address == name) {
                Some(k) => Ok(Some(c.value(k)?)),
                None => Ok(None),
            }
        };
        let v = |n: &str| named(n).map(|x| x.unwrap_or(0.0));
        let scale = if s.inch { 25.4 } else { 1.0 };
        let (rotation, axes): (Option<Mat3>, Option<[Option<f64>; 3]>) = match kind.as_str() {
            "RESET" => (None, None),
            "SPATIAL" => (Some(spatial(v("SPA")?, v("SPB")?, v("SPC")?)), None),
            "PROJECTED" => {
                let rot = match named("PROROT")? {
                    Some(r) => r,
                    None => v("ROT")?,
                };
                let r = geometry::projected(v("PROPR")?, v("PROMIN")?, rot).ok_or_else(|| {
                    c.error(
                        "PLANE PROJECTED: a projection angle of ±90° or more defines no plane",
                        Some(1),
                    )
                })?;
                (Some(r), None)
            }
            "EULER" => (
                Some(geometry::euler(v("EULPR")?, v("EULNU")?, v("EULROT")?)),
                None,
            ),
            "VECTOR" => {
                let base = [v("BX")?, v("BY")?, v("BZ")?];
                let normal = [v("NX")?, v("NY")?, v("NZ")?];
                (Some(vector_frame(base, normal).ok_or_else(|| {
                    c.error(
                        "PLANE VECTOR: the base and normal vectors must be non-zero and not parallel",
                        Some(1),
                    )
                })?), None)
            }
            "POINTS" => {
                let p = |k: u8| -> Result<[f64; 3], GcodeError> {
                    Ok([
                        v(&format!("P{k}X"))? * scale,
                        v(&format!("P{k}Y"))? * scale,
                        v(&format!("P{k}Z"))? * scale,
                    ])
                };
                let r = geometry::points(p(1)?, p(2)?, p(3)?).ok_or_else(|| {
                    c.error("PLANE POINTS: the three points lie on one line", Some(1))
                })?;
                (Some(r), None)
            }
            "RELATIVE" => {
                // One incremental spatial angle about an axis of the active
                // (tilted) frame: R = R_active · R_axis.
                let given: Vec<(usize, f64)> = [("SPA", 0), ("SPB", 1), ("SPC", 2)]
                    .into_iter()
                    .filter_map(|(n, k)| named(n).transpose().map(|x| x.map(|x| (k, x))))
                    .collect::<Result<_, _>>()?;
                let [(axis, angle)] = given[..] else {
                    return Err(c.error(
                        "PLANE RELATIVE: exactly one incremental angle (SPA, SPB or SPC)",
                        Some(1),
                    ));
                };
                let active = s.tilt.unwrap_or(IDENTITY);
                (Some(mat_mul(&active, &rotation(axis, angle))), None)
            }
            "AXIAL" => (None, Some([named("A")?, named("B")?, named("C")?])),
            _ => return Err(c.error("PLANE: expected SPATIAL, PROJECTED, EULER, VECTOR, POINTS, RELATIVE, AXIAL or RESET", Some(1))),
        };
        let positioning = self.positioning(c, s, axes.is_some())?;
        let pre = self.setup.preset;
        let (tilt, joints): (Option<Mat3>, Option<Axes>) = match (rotation, axes) {
            (None, None) => (
                None,
                Some(Axes {
                    a: pre.a,
                    b: pre.b,
                    c: pre.c,
                    ..s.position
                }),
            ),
            (Some(r), _) => (Some(r), Some(self.solve_plane(c, s, &r, &positioning)?)),
            (None, Some(a)) => {
                let mut j = s.position;
                for (v, axis) in a.iter().zip([Axis::A, Axis::B, Axis::C]) {
                    if let Some(v) = v {
                        j.set(axis, pre.get(axis) + v);
                    }
                }
                let solver = self.solver(c)?;
                let axis = solver.axis_of(&j);
                // The plane of machine-axis angles: the tool axis they give,
                // the X axis kept as near the workpiece's as the axis allows.
                (
                    vector_frame([1.0, 0.0, 0.0], axis)
                        .or_else(|| vector_frame([0.0, 1.0, 0.0], axis)),
                    Some(j),
                )
            }
        };
        self.tilt_to(c, s, event, tilt, joints, &positioning)
    }

    /// The positioning words of a `PLANE` block (or `CYCL DEF 19`): `MOVE
    /// [DIST]`, `TURN`, `STAY`, `SEQ±`, `COORD ROT`/`TABLE ROT`, `F`/`FMAX`.
    fn positioning(&self, c: &Ctx<'_>, s: &State, axial: bool) -> Result<Positioning, GcodeError> {
        let b = c.block;
        let has = |name: &str| b.tokens.iter().position(|t| t.address == name);
        let scale = if s.inch { 25.4 } else { 1.0 };
        let mode = if has("STAY").is_some() {
            PlaneMode::Stay
        } else if let Some(k) = has("MOVE") {
            // `MOVE DIST+50` (the distance may follow as its own word).
            let dist = match has("DIST") {
                Some(d) => c.value(d)? * scale,
                None => b.tokens[k].number().unwrap_or(0.0) * scale,
            };
            PlaneMode::Move { dist }
        } else {
            PlaneMode::Turn
        };
        // `MB`: the retraction before tilting (TNC 620 conversational
        // user's manual 10/2017 p. 556: "effective incrementally from the
        // current tool position in the active tool axis direction that the
        // control approaches before tilting"; asked for with MOVE and TURN).
        let mut retract = None;
        if let Some(k) = has("MB") {
            if b.address(k + 1) == "MAX" {
                return Err(c.unread(
                    "PLANE … MB MAX (a retraction to just before the software limit switch: the machine's travel limits are not read for Klartext)",
                    Some(k),
                ));
            }
            let d = c.value(k)? * scale;
            if d != 0.0 {
                if mode == PlaneMode::Stay {
                    return Err(c.unread(
                        "PLANE … STAY with MB (the retraction belongs to MOVE or TURN positioning)",
                        Some(k),
                    ));
                }
                retract = Some(d);
            }
        }
        let seq = match b
            .tokens
            .iter()
            .find(|t| t.address == "SEQ")
            .and_then(|t| t.number())
        {
            Some(v) if v > 0.0 => Branch::Plus,
            Some(_) => Branch::Minus,
            None => Branch::Nearest,
        };
        let table_rot = b
            .tokens
            .iter()
            .enumerate()
            .any(|(k, t)| t.address == "TABLE" && b.address(k + 1) == "ROT");
        let feed = if has("FMAX").is_some() {
            Feed::Rapid
        } else {
            match b
                .tokens
                .iter()
                .position(|t| t.address == "F" && t.value.is_some())
            {
                Some(k) => Feed::PerMinute(self.feed_value(c, s, k)?),
                None => Feed::Rapid,
            }
        };
        let _ = axial;
        Ok(Positioning {
            mode,
            retract,
            seq,
            table_rot: table_rot.then(|| has("TABLE").unwrap_or(0)),
            feed,
        })
    }

    /// The rotary joints that put the tool along `r`'s tool axis, on the
    /// machine's chain, `SEQ`'s branch; a free rotary axis (one parallel
    /// to the tool axis there, which does not tilt the tool) stays where it
    /// is (`COORD ROT`: the rotation about the tool axis is the coordinate
    /// system's), or, with `TABLE ROT` and the tool vertical, goes to the
    /// plane's rotation about the tool axis when that is 0° or 180°.
    fn solve_plane(
        &self,
        c: &Ctx<'_>,
        s: &State,
        r: &Mat3,
        how: &Positioning,
    ) -> Result<Axes, GcodeError> {
        let axis = mat_vec(r, [0.0, 0.0, 1.0]);
        let solver = self.solver(c)?;
        let mut j = solver
            .joints_for_axis(axis, how.seq, &s.position)
            .ok_or_else(|| {
                c.error(
                    "the machine cannot reach this working plane (its rotary axes cannot point the tool along the plane's normal within their travel)",
                    Some(1),
                )
            })?;
        for letter in [Axis::A, Axis::B, Axis::C] {
            if !self.setup.axes.contains(letter) {
                continue;
            }
            let mut turned = j;
            turned.set(letter, j.get(letter) + 1.0);
            let moved = solver.axis_of(&turned);
            let d = [moved[0] - axis[0], moved[1] - axis[1], moved[2] - axis[2]];
            if dot(d, d).sqrt() < 1e-9 {
                if let Some(k) = how.table_rot {
                    // TABLE ROT: the table takes the plane's rotation about
                    // the tool axis (TNC 640 user's manual, "Specifying the
                    // positioning behavior of the PLANE function", COORD
                    // ROT / TABLE ROT). Read where that rotation is 0° or
                    // 180° (the same table angle in either sense); another
                    // angle needs the table's sense, not confirmed here.
                    let x = mat_vec(r, [1.0, 0.0, 0.0]);
                    let gamma = x[1].atan2(x[0]).to_degrees();
                    let vertical = (axis[2] - 1.0).abs() < 1e-9;
                    let turn = if vertical && gamma.abs() < 1e-9 {
                        0.0
                    } else if vertical && (gamma.abs() - 180.0).abs() < 1e-9 {
                        180.0
                    } else {
                        return Err(c.unread(
                            &format!(
                                "PLANE … TABLE ROT with the free rotary axis {} turning the table by an angle other than 0° or 180° (its sense is not confirmed)",
                                letter.letter()
                            ),
                            Some(k),
                        ));
                    };
                    j.set(letter, self.setup.preset.get(letter) + turn);
                    continue;
                }
                j.set(letter, s.position.get(letter));
            }
        }
        Ok(j)
    }

    /// Tilt to `tilt` with the rotary axes at `joints`, positioned as `how`
    /// says: `TURN` turns them (the tip moves with the head or table),
    /// `MOVE` turns them about a point `DIST` below the tip (the tool keeps
    /// its distance from it), `STAY` leaves them to the program and sets
    /// `Q120`–`Q122` (A, B, C) to their values.
    fn tilt_to(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
        tilt: Option<Mat3>,
        joints: Option<Axes>,
        how: &Positioning,
    ) -> Result<(), GcodeError> {
        let pre = self.setup.preset;
        let tilt = tilt.filter(|r| *r != IDENTITY);
        let mut here = s.position;
        // `MB`: the control first retracts along the tool axis active
        // before tilting (the tilted plane's, else the TOOL CALL's axis: for
        // a head turned without a plane this is the machine's axis, not the
        // spindle's). A positioning leg of the control, as `TURN`'s: not
        // compensated, reported with it (dialects.md, Heidenhain "Positions").
        let mut legs = Vec::new();
        if let Some(d) = how.retract {
            let n = from_plane(s.plane, [0.0, 0.0, 1.0]);
            let axis = s.tilt.map_or(n, |r| mat_vec(&r, n));
            let end = Axes {
                x: here.x + d * axis[0],
                y: here.y + d * axis[1],
                z: here.z + d * axis[2],
                ..here
            };
            legs.push(self.straight(self.frame_of(s), false, here, end, how.feed));
            here = end;
        }
        let mut tip = here.xyz();
        s.tilt = tilt;
        if tilt.is_none() {
            s.shift_tilted = [0.0; 3];
        }
        if let Some(j) = joints {
            let moves_rotary = (j.a - here.a).abs() > 1e-12
                || (j.b - here.b).abs() > 1e-12
                || (j.c - here.c).abs() > 1e-12;
            match how.mode {
                PlaneMode::Stay => {
                    for (q, axis) in [(120, Axis::A), (121, Axis::B), (122, Axis::C)] {
                        if self.setup.axes.contains(axis) {
                            s.assigned.push((q, j.get(axis) - pre.get(axis)));
                        }
                    }
                }
                PlaneMode::Turn | PlaneMode::Move { .. } if moves_rotary => {
                    // TURN: a joint-frame leg (the tip moves with the axes).
                    // MOVE: about the point DIST below the tip along the tool
                    // axis, tip' = tip + DIST·(axis' − axis), a part-frame leg.
                    let frame = match how.mode {
                        PlaneMode::Move { dist } => {
                            let solver = self.solver(c)?;
                            let (a0, a1) = (solver.axis_of(&here), solver.axis_of(&j));
                            for k in 0..3 {
                                tip[k] += dist * (a1[k] - a0[k]);
                            }
                            Frame::Part
                        }
                        _ => Frame::Joint,
                    };
                    let end = Axes {
                        x: tip[0],
                        y: tip[1],
                        z: tip[2],
                        a: j.a,
                        b: j.b,
                        c: j.c,
                        ..here
                    };
                    legs.push(self.straight(frame, false, here, end, how.feed));
                    s.rot = [j.a - pre.a, j.b - pre.b, j.c - pre.c];
                }
                _ => {}
            }
        }
        if !legs.is_empty() {
            event.moves = Moves::Home(legs);
        }
        // The program position in the new frame: where the tip is.
        let base = [
            tip[0] - pre.x - s.shift[0],
            tip[1] - pre.y - s.shift[1],
            tip[2] - pre.z - s.shift[2],
        ];
        if self.frame_of(s) == Frame::Joint {
            s.pos = base;
        } else {
            let local = match &s.tilt {
                Some(r) => mat_t_vec(r, base),
                None => base,
            };
            s.pos = [
                local[0] - s.shift_tilted[0],
                local[1] - s.shift_tilted[1],
                local[2] - s.shift_tilted[2],
            ];
        }
        s.tangent = None;
        s.corner = None;
        Ok(())
    }

    /// `CYCL DEF 19.0 WORKING PLANE`, `CYCL DEF 19.1 A… B… C… [F…]`: the
    /// working plane by spatial angles, as `PLANE SPATIAL` (TNC 640 user's
    /// manual, "Cycle 19 WORKING PLANE": rotations about the machine-fixed
    /// axes A, then B, then C; all angles 0 resets it). The control leaves
    /// the rotary positions in `Q120`–`Q122` for the program's own rotary
    /// block; with a feed rate `F` in 19.1 (automatic positioning) it turns
    /// the axes itself, as `TURN`.
    fn working_plane_cycle(
        &self,
        c: &Ctx<'_>,
        s: &mut State,
        event: &mut BlockEvent,
        minor: u32,
    ) -> Result<(), GcodeError> {
        if minor == 0 {
            return Ok(());
        }
        let b = c.block;
        let mut angle = [0.0; 3];
        let mut feed = None;
        for (k, t) in b.tokens.iter().enumerate().skip(3) {
            match t.address.as_str() {
                "A" => angle[0] = c.value(k)?,
                "B" => angle[1] = c.value(k)?,
                "C" => angle[2] = c.value(k)?,
                "F" if t.value.is_some() => feed = Some(Feed::PerMinute(self.feed_value(c, s, k)?)),
                "FMAX" => feed = Some(Feed::Rapid),
                _ => {}
            }
        }
        let how = Positioning {
            retract: None,
            mode: if feed.is_some() {
                PlaneMode::Turn
            } else {
                PlaneMode::Stay
            },
            seq: Branch::Nearest,
            table_rot: None,
            feed: feed.unwrap_or(Feed::Rapid),
        };
        let pre = self.setup.preset;
        let r = spatial(angle[0], angle[1], angle[2]);
        let joints = if r == IDENTITY || angle == [0.0; 3] {
            self.solver(c)?;
            Axes {
                a: pre.a,
                b: pre.b,
                c: pre.c,
                ..s.position
            }
        } else {
            self.solve_plane(c, s, &r, &how)?
        };
        let tilt = (angle != [0.0; 3]).then_some(r);
        self.tilt_to(c, s, event, tilt, Some(joints), &how)
    }

    fn frame_of(&self, s: &State) -> Frame {
        if s.tcpm || s.tilt.is_some() {
            Frame::Part
        } else {
            Frame::Joint
        }
    }
}

/// The largest distance of a chord from the arc it stands for, mm: arcs
/// the seam cannot carry as arcs (in a tilted working plane, `RND`) are
/// handed on as chords this close.
pub const CHORD_TOLERANCE_MM: f64 = 0.0005;

/// How a `PLANE` (or `CYCL DEF 19`) positions the rotary axes.
#[derive(Clone, Copy, Debug, PartialEq)]
enum PlaneMode {
    /// `TURN`: the axes turn; the tip moves with them.
    Turn,
    /// `MOVE`: the axes turn about the point `dist` below the tip.
    Move { dist: f64 },
    /// `STAY`: the program turns them (Q120–Q122).
    Stay,
}

/// The positioning words of a working-plane block.
#[derive(Clone, Copy, Debug)]
struct Positioning {
    mode: PlaneMode,
    /// `MB`: the retraction along the active tool axis before tilting, mm.
    retract: Option<f64>,
    seq: Branch,
    /// `TABLE ROT` given: its token.
    table_rot: Option<usize>,
    feed: Feed,
}

/// The angle of `a` nearest `previous` among `a + k·360` (M126).
fn nearest_turn(a: f64, previous: f64) -> f64 {
    let k = ((previous - a) / 360.0).round();
    a + 360.0 * k
}

/// Radius and angle (degrees) of `p` about `pole` (in-plane coordinates).
fn polar_of(pole: [f64; 2], p: [f64; 3]) -> (f64, f64) {
    let (du, dv) = (p[0] - pole[0], p[1] - pole[1]);
    (du.hypot(dv), dv.atan2(du).to_degrees())
}

/// The in-plane slot (0, 1) of an axis letter, if it lies in the plane.
fn plane_slot(plane: Plane, letter: u8) -> Option<usize> {
    match to_plane_index(plane, letter) {
        2 => None,
        k => Some(k),
    }
}

/// The index of `letter`'s coordinate in [`to_plane`]'s (u, v, w).
fn to_plane_index(plane: Plane, letter: u8) -> usize {
    let xyz = match letter {
        b'X' => 0,
        b'Y' => 1,
        _ => 2,
    };
    let mut e = [0.0; 3];
    e[xyz] = 1.0;
    let q = to_plane(plane, e);
    q.iter().position(|&v| v == 1.0).unwrap_or(2)
}

fn plane_normal_letter(plane: Plane) -> &'static str {
    match plane {
        Plane::XY => "Z",
        Plane::ZX => "Y",
        Plane::YZ => "X",
    }
}

/// The centre of a `CR` arc: radius `r` (R+ the short way, R− the long
/// way, TNC 640 "Circular path CR"), `clockwise` for DR−.
pub(crate) fn radius_centre(s: [f64; 3], e: [f64; 3], r: f64, clockwise: bool) -> Option<[f64; 2]> {
    let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
    let chord = dx.hypot(dy);
    let ra = r.abs();
    if chord < 1e-12 || chord > 2.0 * ra + 1e-9 {
        return None;
    }
    let h = (ra * ra - chord * chord / 4.0).max(0.0).sqrt();
    let (mx, my) = (s[0] + dx / 2.0, s[1] + dy / 2.0);
    // Unit normal to the chord, to the left of travel.
    let (nx, ny) = (-dy / chord, dx / chord);
    // A counter-clockwise arc under 180° has its centre on the left.
    let left = clockwise != (r > 0.0);
    let sign = if left { 1.0 } else { -1.0 };
    Some([mx + sign * h * nx, my + sign * h * ny])
}

/// The centre and sense of the arc from `s` to `e` tangent to `t` at `s`.
fn tangent_centre(s: [f64; 3], e: [f64; 3], t: [f64; 2]) -> Option<([f64; 2], bool)> {
    let tl = t[0].hypot(t[1]);
    if tl < 1e-12 {
        return None;
    }
    let n = [-t[1] / tl, t[0] / tl];
    let d = [e[0] - s[0], e[1] - s[1]];
    let dn = d[0] * n[0] + d[1] * n[1];
    if dn.abs() < 1e-12 {
        return None;
    }
    let k = (d[0] * d[0] + d[1] * d[1]) / (2.0 * dn);
    Some(([s[0] + k * n[0], s[1] + k * n[1]], k < 0.0))
}

/// A straight move's coordinate address: (incremental, 0 X / 1 Y / 2 Z).
fn xyz_address(address: &str) -> Option<(bool, usize)> {
    match address {
        "X" => Some((false, 0)),
        "Y" => Some((false, 1)),
        "Z" => Some((false, 2)),
        "IX" => Some((true, 0)),
        "IY" => Some((true, 1)),
        "IZ" => Some((true, 2)),
        _ => None,
    }
}

/// Where the `X Y Z` / `IX IY IZ` words of `c`'s block (from token
/// `skip`) put a straight move that starts at `from` (mm, `scale` for the
/// program's units).
fn xyz_words(c: &Ctx<'_>, from: [f64; 3], scale: f64, skip: usize) -> Result<[f64; 3], GcodeError> {
    let mut end = from;
    for (k, t) in c.block.tokens.iter().enumerate().skip(skip) {
        let Some((inc, slot)) = xyz_address(t.address.as_str()) else {
            continue;
        };
        if t.value.is_none() {
            continue;
        }
        let v = c.value(k)? * scale;
        end[slot] = if inc { from[slot] + v } else { v };
    }
    Ok(end)
}

/// The point a block's polar words give (`PR`/`IPR`, `PA`/`IPA` about
/// `pole`, the tool-axis word absolute or incremental), from the current
/// position: what a word leaves out stays the current position's (its
/// polar radius and angle about the pole). The block's words from `skip`.
fn polar_words(
    c: &Ctx<'_>,
    s: &State,
    pole: [f64; 2],
    skip: usize,
) -> Result<[f64; 3], GcodeError> {
    let scale = if s.inch { 25.4 } else { 1.0 };
    let cur = to_plane(s.plane, s.pos);
    let (mut r, mut a) = polar_of(pole, cur);
    let mut w = cur[2];
    let normal = plane_normal_letter(s.plane);
    for (k, t) in c.block.tokens.iter().enumerate().skip(skip) {
        let name = t.address.as_str();
        match name {
            "PR" => r = c.value(k)? * scale,
            "IPR" => r += c.value(k)? * scale,
            "PA" => a = c.value(k)?,
            "IPA" => a += c.value(k)?,
            _ if name == normal => w = c.value(k)? * scale,
            _ if name.strip_prefix('I') == Some(normal) => w += c.value(k)? * scale,
            _ => {}
        }
    }
    let (sa, ca) = a.to_radians().sin_cos();
    Ok(from_plane(s.plane, [pole[0] + r * ca, pole[1] + r * sa, w]))
}

/// Where a cycle call runs the cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum CallKind {
    /// `CYCL CALL`, `M99`, `M89`: at the tool's position.
    Here,
    /// `CYCL CALL POS X Y Z`.
    Position,
    /// `CYCL CALL PAT`: at each point of the `PATTERN DEF`.
    Pattern,
}

fn cycle_call_kind(b: &KlBlock) -> CallKind {
    match b.address(2) {
        "POS" => CallKind::Position,
        "PAT" => CallKind::Pattern,
        _ => CallKind::Here,
    }
}

/// The index (0 X, 1 Y, 2 Z) of the tool axis of `plane`.
fn tool_axis_index(plane: Plane) -> usize {
    match plane {
        Plane::XY => 2,
        Plane::ZX => 1,
        Plane::YZ => 0,
    }
}

/// A block and what locates its errors.
#[derive(Clone, Copy)]
struct Ctx<'a> {
    block: &'a KlBlock,
    raw: &'a [u8],
    line: usize,
    q: &'a QParameters,
}

impl Ctx<'_> {
    /// A located error at token `at` (or the whole block): what the control
    /// refuses, in its words.
    fn error(&self, message: &str, at: Option<usize>) -> GcodeError {
        self.located(ErrorKind::DialectRefused(message.to_string()), at)
    }

    /// A located error naming a feature volcomp does not read yet.
    fn unread(&self, feature: &str, at: Option<usize>) -> GcodeError {
        self.located(
            ErrorKind::DialectFeature("Heidenhain", feature.to_string()),
            at,
        )
    }

    /// A cycle's error, located: refused in the control's words, or not read.
    fn cycle_error(&self, e: CycleError, at: Option<usize>) -> GcodeError {
        match e {
            CycleError::Refused(m) => self.error(&m, at),
            CycleError::Unread(m) => self.unread(&m, at),
        }
    }

    fn located(&self, kind: ErrorKind, at: Option<usize>) -> GcodeError {
        let (start, end) = match at.and_then(|k| self.block.tokens.get(k)) {
            Some(t) => (t.span.start, t.span.end),
            None => (0, self.raw.len()),
        };
        GcodeError::at(kind, self.line, self.raw, start, end)
    }

    /// The value of token `k` (a number or a parameter's).
    fn value(&self, k: usize) -> Result<f64, GcodeError> {
        let t: &Token = &self.block.tokens[k];
        match &t.value {
            Some(v) => Ok(self.q.value(v)),
            None => Err(self.error(&format!("`{}` without a value", t.address), Some(k))),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spatial_turns_the_tool_axis() {
        // SPB-45: the tool axis turns about Y by −45°: (−sin45, 0, cos45).
        let r = spatial(0.0, -45.0, 0.0);
        let z = mat_vec(&r, [0.0, 0.0, 1.0]);
        let h = 0.5f64.sqrt();
        assert!((z[0] + h).abs() < 1e-12 && z[1].abs() < 1e-12 && (z[2] - h).abs() < 1e-12);
    }

    #[test]
    fn radius_arcs() {
        // Quarter circle from (10,0) to (0,10), radius 10, counter-clockwise:
        // the short way has the centre at the origin.
        let c = radius_centre([10.0, 0.0, 0.0], [0.0, 10.0, 0.0], 10.0, false).unwrap();
        assert!(c[0].abs() < 1e-9 && c[1].abs() < 1e-9);
        let c = radius_centre([10.0, 0.0, 0.0], [0.0, 10.0, 0.0], -10.0, false).unwrap();
        assert!((c[0] - 10.0).abs() < 1e-9 && (c[1] - 10.0).abs() < 1e-9);
        // Tangent arc: moving +X at (0,0), to (10,10): centre (0,10), counter-clockwise.
        let (c, cw) = tangent_centre([0.0, 0.0, 0.0], [10.0, 10.0, 0.0], [1.0, 0.0]).unwrap();
        assert!(c[0].abs() < 1e-9 && (c[1] - 10.0).abs() < 1e-9 && !cw);
    }

    #[test]
    fn vector_frame_is_a_rotation() {
        let r = vector_frame([1.0, 0.0, 0.0], [0.0, -1.0, 1.0]).unwrap();
        let z = mat_vec(&r, [0.0, 0.0, 1.0]);
        let h = 0.5f64.sqrt();
        assert!(z[0].abs() < 1e-12 && (z[1] + h).abs() < 1e-12 && (z[2] - h).abs() < 1e-12);
        assert!(vector_frame([0.0, 0.0, 1.0], [0.0, 0.0, 2.0]).is_none());
    }
}
