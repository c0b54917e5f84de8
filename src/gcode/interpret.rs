//! The interpreter: blocks (syntax) → block events (meaning), one at a time.
//!
//! Decisions (gcode.md leaves them open):
//! - The position before the first move is [`InterpretOptions::initial_position`]
//!   (all zero by default). The first motion's [`Motion::duration_min`] is
//!   computed as for any block, but machining time starts at the first motion's
//!   target (effects.md), so [`BlockEvent::time_min`] does not include it.
//! - Every line is a block: block index = line − 1, blank and comment lines
//!   included, so indices and lines stay aligned with the file.
//! - G20 input is converted to mm (linear axes, I J K R, and F under G94);
//!   A and C are degrees, taken literally (no shortest path, multi-turn allowed).
//! - A frame switch (M428/M429, G43.4/G234/G49, TRAORI/TRAFOOF) takes effect in
//!   its own block, before that block's move. Unwritten axes keep their last
//!   programmed *numbers* across a switch (the interpreter knows no
//!   kinematics); [`BlockEvent::frame_switch`] tells the layers that do.
//! - G28/G30 are reported (a warning, [`BlockEvent::home`]) and not
//!   interpolated: their axis words are intermediate points, and the tracked
//!   position is left unchanged, so the next move starts from the last
//!   programmed position.
//! - G53 moves are reported with `machine_coordinates` set; work offsets
//!   (G54–G59) are unknown, so the values are taken as they are, absolute.
//! - Under G93 a move without F reuses the last F with a warning; a move at zero
//!   feed lasts 0 min with a warning.
//! - After M2/M30 the remaining lines are not interpreted (events are `skipped`).
//! - Block delete `/`: the block is executed unless
//!   [`InterpretOptions::skip_deleted_blocks`].
//! - Errors (unless `lenient`, which turns them into warnings and ignores the
//!   offending word's effect): M98/M99, cutter compensation G41/G42 active during
//!   a move, unknown G codes (assumed to change the geometry; under `lenient`
//!   the block's axis words are then ignored: no move), axis words without
//!   a motion mode (lenient: G1), arcs without centre or with an unreachable R
//!   (lenient: straight move), non-finite targets.
use std::fmt;

use crate::axes::{Axes, Axis};

use super::block::Block;
use super::error::{ErrorKind, GcodeError};
use super::modal::{
    CutterComp, Distance, GCode, MCode, ModalState, MotionMode, classify_g, classify_m, code_text,
    is_known_letter,
};
use super::motion::{Feed, Frame, Motion, MotionKind, Plane, from_plane, to_plane};

/// Interpreter settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InterpretOptions {
    /// Frame at program start (`--frame`).
    pub initial_frame: Frame,
    /// Rapid rate for G0 durations, mm/min.
    pub rapid_mm_per_min: f64,
    /// Turn errors into warnings and pass the offending construct through.
    pub lenient: bool,
    /// Position before the first move.
    pub initial_position: Axes,
    /// Honour block delete: skip lines that start with `/`.
    pub skip_deleted_blocks: bool,
}

impl Default for InterpretOptions {
    fn default() -> Self {
        InterpretOptions {
            initial_frame: Frame::Joint,
            rapid_mm_per_min: 10_000.0,
            lenient: false,
            initial_position: Axes::default(),
            skip_deleted_blocks: false,
        }
    }
}

/// A harmless problem, or an error passed through under `lenient`.
#[derive(Clone, Debug, PartialEq)]
pub struct Warning {
    pub line: usize,
    /// 1-based byte column (1 when about the whole line).
    pub column: usize,
    pub kind: WarningKind,
}

#[derive(Clone, Debug, PartialEq)]
pub enum WarningKind {
    /// A letter the interpreter does not know (reported once per letter).
    UnknownLetter(char),
    /// G28/G30: not interpolated.
    Home(String),
    /// G93 move without F: the last F is used.
    MissingInverseTimeFeed,
    /// A move at zero feed: duration 0.
    ZeroFeed,
    /// Start and end radius of an arc differ (mm).
    ArcRadiusMismatch(f64),
    /// Words after M2/M30 (not interpreted).
    AfterProgramEnd,
    /// An error passed through because of `lenient`.
    Lenient(ErrorKind),
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}:{}: ", self.line, self.column)?;
        match &self.kind {
            WarningKind::UnknownLetter(c) => {
                write!(f, "unknown word letter `{c}` kept verbatim (reported once)")
            }
            WarningKind::Home(code) => write!(
                f,
                "{code} returns to a reference point; not interpolated, the next move starts from the last programmed position"
            ),
            WarningKind::MissingInverseTimeFeed => {
                write!(f, "G93 move without F; the last F is used")
            }
            WarningKind::ZeroFeed => write!(f, "move at zero feed; its duration is taken as 0"),
            WarningKind::ArcRadiusMismatch(d) => {
                write!(f, "arc start and end radius differ by {d:.4} mm")
            }
            WarningKind::AfterProgramEnd => {
                write!(
                    f,
                    "words after the program end (M2/M30) are not interpreted"
                )
            }
            WarningKind::Lenient(kind) => write!(f, "passed through (--lenient): {kind}"),
        }
    }
}

/// What the interpreter says about one block (one line).
#[derive(Clone, Debug, PartialEq)]
pub struct BlockEvent {
    /// 0-based block index (= line − 1).
    pub index: usize,
    /// 1-based line.
    pub line: usize,
    /// The move, if the block moves.
    pub motion: Option<Motion>,
    /// Modal state after the block.
    pub modal: ModalState,
    /// Position before the block (absolute, mm/deg, programmed numbers).
    pub start: Axes,
    /// Position after the block.
    pub position: Axes,
    /// Machining time at the end of the block, min since program start (the
    /// first move's target is time 0).
    pub time_min: f64,
    /// The frame changed in this block (to this frame).
    pub frame_switch: Option<Frame>,
    /// G28/G30 in this block.
    pub home: bool,
    /// M2/M30 in this block.
    pub program_end: bool,
    /// Not interpreted: deleted (when skipping), unparsed (lenient) or after the end.
    pub skipped: bool,
    pub warnings: Vec<Warning>,
}

impl Default for BlockEvent {
    /// An empty event (for [`Interpreter::interpret_into`]).
    fn default() -> Self {
        BlockEvent {
            index: 0,
            line: 0,
            motion: None,
            modal: ModalState::new(Frame::Joint),
            start: Axes::default(),
            position: Axes::default(),
            time_min: 0.0,
            frame_switch: None,
            home: false,
            program_end: false,
            skipped: false,
            warnings: Vec::new(),
        }
    }
}

/// The modal interpreter. Feed it blocks in order.
#[derive(Clone, Debug)]
pub struct Interpreter {
    options: InterpretOptions,
    modal: ModalState,
    position: Axes,
    time_min: f64,
    moved: bool,
    ended: bool,
    unknown_letters_seen: u32,
}

/// Per-block word values, fixed size (no allocation).
#[derive(Default)]
struct Words {
    axes: [Option<(f64, usize)>; 5],
    ijk: [Option<f64>; 3],
    r: Option<f64>,
    p: Option<f64>,
    f: Option<f64>,
}

impl Interpreter {
    pub fn new(options: InterpretOptions) -> Self {
        Interpreter {
            options,
            modal: ModalState::new(options.initial_frame),
            position: options.initial_position,
            time_min: 0.0,
            moved: false,
            ended: false,
            unknown_letters_seen: 0,
        }
    }

    pub fn options(&self) -> &InterpretOptions {
        &self.options
    }

    /// Modal state now (after the last block).
    pub fn modal(&self) -> &ModalState {
        &self.modal
    }

    /// Position now (after the last block).
    pub fn position(&self) -> Axes {
        self.position
    }

    /// Interpret one block into a new event.
    pub fn interpret(&mut self, block: &Block) -> Result<BlockEvent, GcodeError> {
        let mut event = BlockEvent::default();
        self.interpret_into(block, &mut event)?;
        Ok(event)
    }

    /// Interpret one block, reusing `event` (its warning vector keeps its
    /// capacity). On error the interpreter's state is unchanged.
    pub fn interpret_into(
        &mut self,
        block: &Block,
        event: &mut BlockEvent,
    ) -> Result<(), GcodeError> {
        event.index = block.line.saturating_sub(1);
        event.line = block.line;
        event.motion = None;
        event.start = self.position;
        event.frame_switch = None;
        event.home = false;
        event.program_end = false;
        event.skipped = false;
        event.warnings.clear();
        let result = self.apply(block, event);
        event.modal = self.modal;
        event.position = self.position;
        event.time_min = self.time_min;
        result
    }

    fn error(&self, block: &Block, kind: ErrorKind, start: usize, end: usize) -> GcodeError {
        GcodeError::at(kind, block.line, &block.raw, start, end)
    }

    /// An error, or under `lenient` a warning (then `Ok`).
    fn fail(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        kind: ErrorKind,
        start: usize,
        end: usize,
    ) -> Result<(), GcodeError> {
        if self.options.lenient {
            event.warnings.push(Warning {
                line: block.line,
                column: start + 1,
                kind: WarningKind::Lenient(kind),
            });
            Ok(())
        } else {
            Err(self.error(block, kind, start, end))
        }
    }

    fn apply(&mut self, block: &Block, event: &mut BlockEvent) -> Result<(), GcodeError> {
        if let Some(err) = &block.unparsed {
            event.skipped = true;
            event.warnings.push(Warning {
                line: block.line,
                column: err.column,
                kind: WarningKind::Lenient(err.kind.clone()),
            });
            return Ok(());
        }
        if self.ended || (block.deleted && self.options.skip_deleted_blocks) {
            event.skipped = true;
            if self.ended && !block.is_empty() {
                event.warnings.push(Warning {
                    line: block.line,
                    column: 1,
                    kind: WarningKind::AfterProgramEnd,
                });
            }
            return Ok(());
        }
        if block.is_empty() {
            return Ok(());
        }
        // Work on a copy of the modal state: nothing changes when the block fails.
        let mut modal = self.modal;
        let old_frame = modal.frame;
        let old_inverse = modal.inverse_time;
        let mut words = Words::default();
        let mut machine_coordinates = false;
        let mut home: Option<(i32, usize, usize)> = None;
        let mut motion_word: Option<(usize, usize)> = None;
        let mut end = false;
        let mut unsupported = false;

        for kw in &block.keywords {
            modal.frame = match kw.keyword {
                super::block::Keyword::TraOri => Frame::Part,
                super::block::Keyword::TraFoof => Frame::Joint,
            };
        }
        // Units first: every number of the block is in the block's units.
        for w in block.words.iter().filter(|w| w.letter == b'G') {
            if let Some(GCode::Units(u)) = w.code10().map(classify_g) {
                modal.units = u;
            }
        }
        let scale = modal.units.scale();
        for w in &block.words {
            match w.letter {
                b'G' => {
                    let Some(code) = w.code10() else {
                        unsupported = true;
                        self.fail(
                            block,
                            event,
                            ErrorKind::UnsupportedGCode(format!("G{}", w.value)),
                            w.start,
                            w.end,
                        )?;
                        continue;
                    };
                    match classify_g(code) {
                        GCode::Motion(m) => {
                            modal.motion = m;
                            motion_word = Some((w.start, w.end));
                        }
                        GCode::Plane(p) => modal.plane = p,
                        GCode::Units(_) => {}
                        GCode::Distance(d) => modal.distance = d,
                        GCode::ArcDistance(d) => modal.arc_distance = d,
                        GCode::FeedMode(inv) => modal.inverse_time = inv,
                        GCode::CutterComp(c) => modal.cutter_comp = c,
                        GCode::ToolLength => modal.tool_length = true,
                        GCode::ToolTip => {
                            modal.tool_length = true;
                            modal.frame = Frame::Part;
                        }
                        GCode::ToolLengthOff => {
                            modal.tool_length = false;
                            modal.frame = Frame::Joint;
                        }
                        GCode::MachineCoordinates => machine_coordinates = true,
                        GCode::WorkOffset | GCode::PassThrough => {}
                        GCode::Home => home = Some((code, w.start, w.end)),
                        GCode::CancelMotion => modal.motion = MotionMode::None,
                        GCode::Unsupported => {
                            unsupported = true;
                            self.fail(
                                block,
                                event,
                                ErrorKind::UnsupportedGCode(code_text('G', code)),
                                w.start,
                                w.end,
                            )?
                        }
                    }
                }
                b'M' => match w.code10().map(classify_m) {
                    Some(MCode::End) => end = true,
                    Some(MCode::Subroutine) => self.fail(
                        block,
                        event,
                        ErrorKind::SubroutineCall(code_text('M', w.code10().unwrap_or(0))),
                        w.start,
                        w.end,
                    )?,
                    Some(MCode::ToolTipOn) => modal.frame = Frame::Part,
                    Some(MCode::ToolTipOff) => modal.frame = Frame::Joint,
                    Some(MCode::PassThrough) | None => {}
                },
                b'X' | b'Y' | b'Z' | b'A' | b'C' => {
                    if let Some(axis) = Axis::from_letter(w.letter as char) {
                        let i = axis as usize;
                        let v = if axis.is_rotary() {
                            w.value
                        } else {
                            w.value * scale
                        };
                        words.axes[i] = Some((v, w.start));
                    }
                }
                b'I' => words.ijk[0] = Some(w.value * scale),
                b'J' => words.ijk[1] = Some(w.value * scale),
                b'K' => words.ijk[2] = Some(w.value * scale),
                b'R' => words.r = Some(w.value * scale),
                b'P' => words.p = Some(w.value),
                b'F' => words.f = Some(w.value),
                other => {
                    if !is_known_letter(other) && other.is_ascii_uppercase() {
                        let bit = 1u32 << (other - b'A');
                        if self.unknown_letters_seen & bit == 0 {
                            self.unknown_letters_seen |= bit;
                            event.warnings.push(Warning {
                                line: block.line,
                                column: w.start + 1,
                                kind: WarningKind::UnknownLetter(other as char),
                            });
                        }
                    }
                }
            }
        }
        // Feed: a change of feed mode forgets the old F.
        if modal.inverse_time != old_inverse {
            modal.feed = 0.0;
        }
        if let Some(f) = words.f {
            modal.feed = if modal.inverse_time { f } else { f * scale };
        }

        let has_axes = words.axes.iter().any(Option::is_some);
        let mut new_position = self.position;
        let mut motion = None;
        if let Some((code, start, _)) = home {
            event.home = true;
            event.warnings.push(Warning {
                line: block.line,
                column: start + 1,
                kind: WarningKind::Home(code_text('G', code)),
            });
        } else if has_axes && !unsupported {
            if modal.motion == MotionMode::None {
                let at = words.axes.iter().flatten().map(|a| a.1).next().unwrap_or(0);
                self.fail(block, event, ErrorKind::NoMotionMode, at, at + 1)?;
                modal.motion = MotionMode::Linear;
            }
            if modal.cutter_comp != CutterComp::Off {
                let (s, e) = motion_word
                    .or_else(|| words.axes.iter().flatten().map(|a| (a.1, a.1 + 1)).next())
                    .unwrap_or((0, 1));
                let name = if modal.cutter_comp == CutterComp::Left {
                    "G41"
                } else {
                    "G42"
                };
                self.fail(
                    block,
                    event,
                    ErrorKind::CutterCompensation(name.into()),
                    s,
                    e,
                )?;
            }
            for axis in Axis::ALL {
                if let Some((v, _)) = words.axes[axis as usize] {
                    let incremental =
                        modal.distance == Distance::Incremental && !machine_coordinates;
                    let base = if incremental {
                        self.position.get(axis)
                    } else {
                        0.0
                    };
                    new_position.set(axis, base + v);
                }
            }
            if new_position.is_finite() {
                let m = self.motion(
                    block,
                    event,
                    &modal,
                    &words,
                    new_position,
                    machine_coordinates,
                )?;
                motion = Some(m);
            } else {
                self.fail(block, event, ErrorKind::NonFinite, 0, block.raw.len())?;
                new_position = self.position;
            }
        }
        if end {
            event.program_end = true;
            self.ended = true;
        }
        // Commit.
        if modal.frame != old_frame {
            event.frame_switch = Some(modal.frame);
        }
        self.modal = modal;
        self.position = new_position;
        if let Some(m) = motion {
            if self.moved {
                self.time_min += m.duration_min;
            }
            self.moved = true;
            event.motion = Some(m);
        }
        Ok(())
    }

    fn motion(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        modal: &ModalState,
        words: &Words,
        end: Axes,
        machine_coordinates: bool,
    ) -> Result<Motion, GcodeError> {
        let start = self.position;
        let mut kind = match modal.motion {
            MotionMode::Rapid => MotionKind::Rapid,
            MotionMode::Linear | MotionMode::None => MotionKind::Linear,
            MotionMode::ArcCw | MotionMode::ArcCcw => {
                let clockwise = modal.motion == MotionMode::ArcCw;
                match self.arc_centre(block, event, modal, words, &start, &end, clockwise)? {
                    Some(centre) => {
                        let turns = match words.p {
                            Some(p) if (1.0..1e6).contains(&p) => {
                                (p.round() as u32).saturating_sub(1)
                            }
                            _ => 0,
                        };
                        MotionKind::Arc {
                            clockwise,
                            centre,
                            plane: modal.plane,
                            turns,
                        }
                    }
                    None => MotionKind::Linear,
                }
            }
        };
        if let MotionKind::Arc { centre, plane, .. } = kind {
            let (s, e, c) = (
                to_plane(plane, start.xyz()),
                to_plane(plane, end.xyz()),
                to_plane(plane, centre),
            );
            let rs = (s[0] - c[0]).hypot(s[1] - c[1]);
            let re = (e[0] - c[0]).hypot(e[1] - c[1]);
            let d = (rs - re).abs();
            if d > 0.005 && d > 1e-3 * rs.max(re) {
                event.warnings.push(Warning {
                    line: block.line,
                    column: 1,
                    kind: WarningKind::ArcRadiusMismatch(d),
                });
            }
            if !centre.iter().all(|v| v.is_finite()) {
                kind = MotionKind::Linear;
            }
        }
        let feed = if modal.motion == MotionMode::Rapid {
            Feed::Rapid
        } else if modal.inverse_time {
            if words.f.is_none() {
                event.warnings.push(Warning {
                    line: block.line,
                    column: 1,
                    kind: WarningKind::MissingInverseTimeFeed,
                });
            }
            Feed::InverseTime(modal.feed)
        } else {
            Feed::PerMinute(modal.feed)
        };
        let mut m = Motion {
            kind,
            frame: modal.frame,
            machine_coordinates,
            start,
            end,
            feed,
            duration_min: 0.0,
        };
        m.duration_min = duration_min(&m, self.options.rapid_mm_per_min);
        let zero_feed = match feed {
            Feed::Rapid => false,
            Feed::PerMinute(f) | Feed::InverseTime(f) => f <= 0.0,
        };
        if zero_feed && (start != end) {
            event.warnings.push(Warning {
                line: block.line,
                column: 1,
                kind: WarningKind::ZeroFeed,
            });
        }
        Ok(m)
    }

    /// Absolute centre of an arc, `None` when it falls back to a straight move (lenient).
    #[allow(clippy::too_many_arguments)]
    fn arc_centre(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        modal: &ModalState,
        words: &Words,
        start: &Axes,
        end: &Axes,
        clockwise: bool,
    ) -> Result<Option<[f64; 3]>, GcodeError> {
        let word_span = |letter: u8| {
            block
                .word(letter)
                .map(|w| (w.start, w.end))
                .unwrap_or((0, block.raw.len()))
        };
        if let Some(r) = words.r {
            let s = to_plane(modal.plane, start.xyz());
            let e = to_plane(modal.plane, end.xyz());
            let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
            let d = dx.hypot(dy);
            let radius = r.abs();
            if d <= 1e-12 || d > 2.0 * radius * (1.0 + 1e-9) + 1e-9 {
                let (a, b) = word_span(b'R');
                self.fail(block, event, ErrorKind::ArcUnreachable(r), a, b)?;
                return Ok(None);
            }
            let h = (radius * radius - d * d / 4.0).max(0.0).sqrt();
            let (tx, ty) = (dx / d, dy / d);
            let (nx, ny) = (-ty, tx);
            // CCW with a minor arc (R > 0): centre to the left of the chord.
            let mut sign = if clockwise { -1.0 } else { 1.0 };
            if r < 0.0 {
                sign = -sign;
            }
            let c = [
                (s[0] + e[0]) / 2.0 + sign * h * nx,
                (s[1] + e[1]) / 2.0 + sign * h * ny,
                s[2],
            ];
            return Ok(Some(from_plane(modal.plane, c)));
        }
        let [i, j, k] = words.ijk;
        let needed = match modal.plane {
            Plane::XY => i.is_some() || j.is_some(),
            Plane::ZX => i.is_some() || k.is_some(),
            Plane::YZ => j.is_some() || k.is_some(),
        };
        if !needed {
            let (a, b) = (0, block.raw.len());
            self.fail(block, event, ErrorKind::ArcWithoutCentre, a, b)?;
            return Ok(None);
        }
        let offsets = [i.unwrap_or(0.0), j.unwrap_or(0.0), k.unwrap_or(0.0)];
        let mut c = start.xyz();
        for n in 0..3 {
            let given = words.ijk[n].is_some();
            if modal.arc_distance == Distance::Absolute {
                if given {
                    c[n] = offsets[n];
                }
            } else {
                c[n] += offsets[n];
            }
        }
        Ok(Some(c))
    }

    /// Machining time so far, min.
    pub fn time_min(&self) -> f64 {
        self.time_min
    }
}

/// Duration of a move by the effects.md rules, minutes, from its programmed
/// coordinates (see [`duration_from_lengths`]).
pub fn duration_min(m: &Motion, rapid_mm_per_min: f64) -> f64 {
    let rotary = (m.end.a - m.start.a).hypot(m.end.c - m.start.c);
    duration_from_lengths(&m.feed, m.xyz_length(), rotary, rapid_mm_per_min)
}

/// Duration (minutes) of a move with XYZ path length `xyz_mm` and rotary length
/// `rotary_deg` = √(Δa² + Δc²): the XYZ length over F, the rotary length over F
/// when only A/C move, the rapid rate for G0, 1/F under G93; 0 when the feed gives
/// no time (F0).
pub fn duration_from_lengths(
    feed: &Feed,
    xyz_mm: f64,
    rotary_deg: f64,
    rapid_mm_per_min: f64,
) -> f64 {
    let path = if xyz_mm > 1e-9 { xyz_mm } else { rotary_deg };
    let t = match *feed {
        Feed::Rapid => path / rapid_mm_per_min,
        Feed::PerMinute(f) => path / f,
        Feed::InverseTime(f) => 1.0 / f,
    };
    if t.is_finite() && t >= 0.0 { t } else { 0.0 }
}

/// Read and interpret a whole program held in memory (strict unless
/// `options.lenient`): blocks and their events, in order.
pub fn interpret_program(
    text: &[u8],
    options: InterpretOptions,
) -> Result<Vec<(super::block::Block, BlockEvent)>, GcodeError> {
    let mut reader = super::reader::BlockReader::new(
        text,
        super::reader::ReadOptions {
            lenient: options.lenient,
        },
    );
    let mut interpreter = Interpreter::new(options);
    let mut out = Vec::new();
    while let Some(block) = reader.next_block() {
        let block = block?;
        let event = interpreter.interpret(block)?;
        out.push((block.clone(), event));
    }
    Ok(out)
}
