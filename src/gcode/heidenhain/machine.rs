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
use crate::gcode::machine::tools::{ToolInUse, ToolTable};
use crate::gcode::motion::{Feed, Frame, Motion, MotionKind, Plane, from_plane, to_plane};

/// A 3×3 rotation, rows.
pub type Mat3 = [[f64; 3]; 3];

const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

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
    /// Direction of the last path element's end (program coordinates), for `CT`.
    tangent: Option<[f64; 3]>,
    /// The event frame position after the last block.
    position: Axes,
    time_min: f64,
    begun: bool,
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
}

/// What a block says the language should do at the program level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Statement {
    /// Anything else.
    Other,
    /// `END PGM`, `M2`, `M30`: the program ends.
    End,
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn mat_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

fn mat_t_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// The rotation about X, Y or Z (0, 1, 2) by `deg` degrees, right-handed.
pub fn rotation(axis: usize, deg: f64) -> Mat3 {
    let (s, c) = deg.to_radians().sin_cos();
    match axis {
        0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
    }
}

/// `PLANE SPATIAL SPA SPB SPC`: the working plane turned about the
/// workpiece's X by SPA, then its Y by SPB, then its Z by SPC, all about
/// fixed axes (TNC 640 user's manual, "PLANE SPATIAL"): R = Rz·Ry·Rx.
pub fn spatial(spa: f64, spb: f64, spc: f64) -> Mat3 {
    mat_mul(
        &rotation(2, spc),
        &mat_mul(&rotation(1, spb), &rotation(0, spa)),
    )
}

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
                tangent: None,
                position: setup.preset,
                time_min: 0.0,
                begun: false,
            },
            setup,
        }
    }

    /// The event of a block not run (passed over).
    pub fn pass_over(&self, line: usize, event: &mut BlockEvent) {
        self.fill(event, line);
        event.start = self.state.position;
        event.skipped = true;
    }

    fn fill(&self, event: &mut BlockEvent, line: usize) {
        let s = &self.state;
        event.index = line.saturating_sub(1);
        event.line = line;
        event.moves = Moves::None;
        event.origin = self.origin();
        event.modal = self.modal();
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
        let frame = (s.tilt.is_some() || shift != [0.0; 3])
            .then(|| FrameTransform::new(r, shift))
            .flatten();
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
        self.fill(event, line);
        let mut s = self.state.clone();
        let ctx = Ctx {
            block,
            raw,
            line,
            q,
        };
        let statement = self.statement(&ctx, &mut s, event)?;
        for m in event.moves.all() {
            s.time_min += m.duration_min;
        }
        if let Some(m) = event.moves.all().last() {
            s.position = m.end;
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
            "RND" | "CHF" => Err(c.unread(first, Some(0))),
            // `CYCL DEF 200`, and the number written on (`CYCL DEF9.0`, `CYCL DEF9 .0`).
            "CYCL" if b.address(1) == "DEF" => {
                self.cycle_def(c, s)?;
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
        let mut tool = match number {
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
            match t.address.as_str() {
                "FMAX" => rapid = true,
                "FAUTO" => s.feed = s.tool_feed,
                "F" if t.value.is_none() => match b.address(k + 1) {
                    "MAX" => rapid = true,
                    "AUTO" => s.feed = s.tool_feed,
                    _ => return Err(c.error("F without a value", Some(k))),
                },
                "F" => s.feed = self.feed_value(c, s, k)?,
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
            match (t.address.as_str(), t.number()) {
                ("R", Some(v)) if v == 0.0 && t.value_span.len() == 1 => s.comp = CutterComp::Off,
                ("RL", None) => s.comp = CutterComp::Left,
                ("RR", None) => s.comp = CutterComp::Right,
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
        s.pos = target;
        s.rot = rot;
        self.push_motion(c, s, event, kind, start, end, feed)?;
        self.m_codes(c, s, event, Some(1))
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
        let scale = if s.inch { 25.4 } else { 1.0 };
        let cur = to_plane(s.plane, s.pos);
        let (mut r, mut a) = polar_of(pole, cur);
        let mut w = cur[2];
        for (k, t) in c.block.tokens.iter().enumerate().skip(1) {
            match t.address.as_str() {
                "PR" => r = c.value(k)? * scale,
                "IPR" => r += c.value(k)? * scale,
                "PA" => a = c.value(k)?,
                "IPA" => a += c.value(k)?,
                name if plane_normal_letter(s.plane) == name => w = c.value(k)? * scale,
                name if format!("I{}", plane_normal_letter(s.plane)) == name => {
                    w += c.value(k)? * scale
                }
                _ => {}
            }
        }
        let (sa, ca) = a.to_radians().sin_cos();
        let target = from_plane(s.plane, [pole[0] + r * ca, pole[1] + r * sa, w]);
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
        if s.tilt.is_some_and(|r| {
            let n = from_plane(s.plane, [0.0, 0.0, 1.0]);
            let rn = mat_vec(&r, n);
            (dot(rn, n) - 1.0).abs() > 1e-9
        }) {
            return Err(c.unread("circle in a tilted working plane", Some(0)));
        }
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
    fn cycle_def(&self, c: &Ctx<'_>, s: &mut State) -> Result<(), GcodeError> {
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
                    let (inc, slot) = match t.address.as_str() {
                        "X" => (false, 0),
                        "Y" => (false, 1),
                        "Z" => (false, 2),
                        "IX" => (true, 0),
                        "IY" => (true, 1),
                        "IZ" => (true, 2),
                        _ => continue,
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
            moves.push(self.straight(s.frame(), false, start, end, feed));
            done.push(if feed == Feed::Rapid {
                CycleStep::Rapid(p)
            } else {
                CycleStep::Feed(p)
            });
            start = end;
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

    /// `PLANE …`: the working plane.
    fn plane(&self, c: &Ctx<'_>, s: &mut State, event: &mut BlockEvent) -> Result<(), GcodeError> {
        let b = c.block;
        let kind = b.address(1).to_string();
        let named = |name: &str| -> Result<Option<f64>, GcodeError> {
            match b.tokens.iter().position(|t| t.address == name) {
                Some(k) => Ok(Some(c.value(k)?)),
                None => Ok(None),
            }
        };
        let (rotation, axes): (Option<Mat3>, Option<[Option<f64>; 3]>) = match kind.as_str() {
            "RESET" => (None, None),
            "SPATIAL" => {
                let spa = named("SPA")?.unwrap_or(0.0);
                let spb = named("SPB")?.unwrap_or(0.0);
                let spc = named("SPC")?.unwrap_or(0.0);
                (Some(spatial(spa, spb, spc)), None)
            }
            "VECTOR" => {
                let v = |n: &str| named(n).map(|x| x.unwrap_or(0.0));
                let base = [v("BX")?, v("BY")?, v("BZ")?];
                let normal = [v("NX")?, v("NY")?, v("NZ")?];
                (Some(vector_frame(base, normal).ok_or_else(|| {
                    c.error(
                        "PLANE VECTOR: the base and normal vectors must be non-zero and not parallel",
                        Some(1),
                    )
                })?), None)
            }
            "AXIAL" => {
                let a = [named("A")?, named("B")?, named("C")?];
                (None, Some(a))
            }
            "PROJECTED" | "EULER" | "POINTS" | "RELATIVE" => {
                return Err(c.unread(&format!("PLANE {kind}"), Some(1)));
            }
            _ => return Err(c.error("PLANE: expected SPATIAL, PROJECTED, EULER, VECTOR, POINTS, RELATIVE, AXIAL or RESET", Some(1))),
        };
        let mode = ["MOVE", "TURN", "STAY"]
            .into_iter()
            .find(|m| b.tokens.iter().any(|t| t.address == *m));
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
        if b.tokens.iter().any(|t| t.address == "COORD") {
            return Err(c.unread("PLANE … COORD ROT", Some(1)));
        }
        let pre = self.setup.preset;
        // The rotary position the plane asks for.
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
            (Some(r), _) => {
                let axis = mat_vec(&r, [0.0, 0.0, 1.0]);
                let solver = self.solver(c)?;
                let j = solver.joints_for_axis(axis, seq, &s.position).ok_or_else(|| {
                    c.error(
                        "the machine cannot reach this working plane (its rotary axes cannot point the tool along the plane's normal)",
                        Some(1),
                    )
                })?;
                (Some(r), Some(j))
            }
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
        let tilt = tilt.filter(|r| *r != IDENTITY);
        // The position in the new frame: where the tool is.
        let here = s.position;
        s.tilt = tilt;
        if tilt.is_none() {
            s.shift_tilted = [0.0; 3];
        }
        if let Some(j) = joints
            && mode != Some("STAY")
        {
            let moves_rotary = (j.a - here.a).abs() > 1e-12
                || (j.b - here.b).abs() > 1e-12
                || (j.c - here.c).abs() > 1e-12;
            if moves_rotary {
                if mode == Some("MOVE") {
                    return Err(c.unread("PLANE … MOVE", Some(1)));
                }
                let end = Axes {
                    a: j.a,
                    b: j.b,
                    c: j.c,
                    ..here
                };
                let feed = if b.tokens.iter().any(|t| t.address == "FMAX") {
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
                let m = self.straight(Frame::Joint, false, here, end, feed);
                event.moves = Moves::Home(vec![m]);
                s.rot = [j.a - pre.a, j.b - pre.b, j.c - pre.c];
            }
        } else if mode == Some("STAY")
            && let Some(j) = joints
        {
            // Q120–Q122: the axis values STAY leaves for the program's own
            // rotary block (the language keeps Q parameters; noted here).
            let _ = j;
        }
        // The program position in the new frame (the tool has not moved).
        let tip = here.xyz();
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
        Ok(())
    }

    fn frame_of(&self, s: &State) -> Frame {
        if s.tcpm || s.tilt.is_some() {
            Frame::Part
        } else {
            Frame::Joint
        }
    }
}

/// The frame whose Z is `normal` and whose X is `base` made perpendicular to
/// it (PLANE VECTOR), as rows of the rotation program → workpiece.
pub fn vector_frame(base: [f64; 3], normal: [f64; 3]) -> Option<Mat3> {
    let nn = dot(normal, normal).sqrt();
    if nn < 1e-12 {
        return None;
    }
    let z = normal.map(|v| v / nn);
    let bz = dot(base, z);
    let x = [
        base[0] - bz * z[0],
        base[1] - bz * z[1],
        base[2] - bz * z[2],
    ];
    let nx = dot(x, x).sqrt();
    if nx < 1e-9 {
        return None;
    }
    let x = x.map(|v| v / nx);
    let y = [
        z[1] * x[2] - z[2] * x[1],
        z[2] * x[0] - z[0] * x[2],
        z[0] * x[1] - z[1] * x[0],
    ];
    // Columns are the frame's axes in workpiece coordinates.
    Some([[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]])
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
fn radius_centre(s: [f64; 3], e: [f64; 3], r: f64, clockwise: bool) -> Option<[f64; 2]> {
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
