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
//! - G28/G30 move at rapid rate to the intermediate point their axis words
//!   give, then to the stored position (#5161…, #5181…) of the given axes
//!   (of all when none is given); both legs are in [`BlockEvent::expanded`]
//!   (the second in machine coordinates) and [`BlockEvent::home`] is set.
//! - Axis words are read in the active origin: the work origin of the
//!   selected system (G54–G59.3, from the parameters: a `.var` file,
//!   `--offset`, G10 L2/L20), the G92/G52 offset and the XY rotation
//!   ([`Origin`]: machine = rot(program + G92) + work origin). G53 moves are
//!   reported with `machine_coordinates` set: their words are machine
//!   coordinates, absolute.
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

use super::cycles::{
    CycleBlock, CycleCode, CycleMemory, CycleStep, RetractMode, SpindleDirection, expand,
};
use super::modal::{
    CutterComp, Distance, GCode, MCode, ModalState, MotionMode, Units, classify_g, classify_m,
    code_text, g_group, is_known_letter, m_group,
};
use super::motion::{Feed, Frame, Motion, MotionKind, Plane, from_plane, to_plane};
use super::origin::Origin;
use super::tools::{ToolInUse, ToolTable};
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::language::parameters::{Parameters, numbers};
use crate::gcode::syntax::block::{Block, Word};
use crate::gcode::syntax::expression::to_integer;

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
    /// The axis letters the machine has: a word for another is LinuxCNC's "Bad
    /// character" (default: X Y Z A B C, what `rs274` reads without an INI file).
    pub axes: crate::axes::AxisSet,
    /// Splines (G5, G5.1, G5.2 … G5.3) become straight pieces within this
    /// distance of the curve, mm (`compensate`: a tenth of `--tol`).
    pub spline_tolerance_mm: f64,
}

/// Most straight pieces one spline becomes; a spline that needs more to stay
/// within [`InterpretOptions::spline_tolerance_mm`] is refused (located).
pub const MAX_SPLINE_PIECES: usize = 100_000;

impl Default for InterpretOptions {
    fn default() -> Self {
        InterpretOptions {
            initial_frame: Frame::Joint,
            rapid_mm_per_min: 10_000.0,
            lenient: false,
            initial_position: Axes::default(),
            skip_deleted_blocks: false,
            axes: crate::axes::AxisSet::RS274,
            spline_tolerance_mm: 5e-5,
        }
    }
}

/// A harmless problem, or an error passed through under `lenient`.
#[derive(Clone, Debug, PartialEq)]
pub struct Warning {
    /// 1-based line of the block it is about.
    pub line: usize,
    /// 1-based byte column (1 when about the whole line).
    pub column: usize,
    /// What it is about.
    pub kind: WarningKind,
}

/// What a [`Warning`] is about.
#[derive(Clone, Debug, PartialEq)]
pub enum WarningKind {
    /// A letter the interpreter does not know (reported once per letter).
    UnknownLetter(char),
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
    /// A tool change with no tool table: the default tool is used.
    NoToolTable(u32),
    /// A cutting move whose tool length offset (G43 H, G43.1, G43.2, G49)
    /// differs from the loaded tool's length, mm (reported once per tool
    /// and offset).
    ToolLengthOffsetMismatch {
        /// The loaded tool's number.
        tool: u32,
        /// The loaded tool's length (mm).
        length_mm: f64,
        /// The tool length offset in effect (mm).
        offset_mm: f64,
    },
    /// A spline word or state LinuxCNC reads in a way a reader may not expect
    /// (what it does, in words).
    Spline(String),
}

impl WarningKind {
    /// Its kind, for grouping (`crate::warnings`).
    pub fn key(&self) -> &'static str {
        match self {
            WarningKind::UnknownLetter(_) => "unknown_word",
            WarningKind::MissingInverseTimeFeed => "inverse_time_feed",
            WarningKind::ZeroFeed => "zero_feed",
            WarningKind::ArcRadiusMismatch(_) => "arc_radius",
            WarningKind::AfterProgramEnd => "after_program_end",
            WarningKind::Lenient(_) => "lenient",
            WarningKind::NoToolTable(_) => "no_tool_table",
            WarningKind::ToolLengthOffsetMismatch { .. } => "tool_length_offset",
            WarningKind::Spline(_) => "spline",
        }
    }

    /// What it changes in a command's result (empty: nothing but time or
    /// the report): a tool length assumed, words or lines ignored.
    pub fn effect(&self) -> &'static str {
        match self {
            WarningKind::UnknownLetter(_) => "unknown words ignored",
            WarningKind::Lenient(_) => "passed through unread (--lenient)",
            WarningKind::NoToolTable(_) => "tool length assumed",
            WarningKind::ToolLengthOffsetMismatch { .. } => {
                "tool length offset differs from the tool"
            }
            _ => "",
        }
    }
}

impl Warning {
    /// The message without its place.
    pub fn message(&self) -> String {
        let text = self.to_string();
        let prefix = format!("line {}:{}: ", self.line, self.column);
        text.strip_prefix(&prefix).unwrap_or(&text).to_string()
    }
}

impl fmt::Display for Warning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "line {}:{}: ", self.line, self.column)?;
        match &self.kind {
            WarningKind::UnknownLetter(c) => {
                write!(f, "unknown word letter `{c}` kept verbatim (reported once)")
            }
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
            WarningKind::NoToolTable(t) => write!(
                f,
                "T{t} is loaded but there is no tool table (--tools FILE, or [[tools]] in the machine file): every block uses the default tool"
            ),
            WarningKind::Spline(what) => write!(f, "{what}"),
            WarningKind::ToolLengthOffsetMismatch {
                tool,
                length_mm,
                offset_mm,
            } => write!(
                f,
                "cutting with T{tool} (length {length_mm} mm) under a tool length offset of {offset_mm} mm (G43 H…/G43.1/G43.2/G49): volcomp takes X Y Z as T{tool}'s tip, but the controller puts that tip {:.4} mm {} the programmed point along the tool axis",
                (offset_mm - length_mm).abs(),
                if offset_mm < length_mm {
                    "below"
                } else {
                    "above"
                }
            ),
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
    /// What the block moves.
    pub moves: Moves,
    /// The origin the block's axis words were read in (identity under G53).
    pub origin: Origin,
    /// Modal state after the block.
    pub modal: ModalState,
    /// The tool in the spindle for the block's moves (after its M6/M61).
    pub tool: ToolInUse,
    /// Position before the block (machine coordinates: origin applied, mm/deg).
    pub start: Axes,
    /// Position after the block.
    pub position: Axes,
    /// Machining time at the end of the block, min since program start (the
    /// first move's target is time 0).
    pub time_min: f64,
    /// The frame changed in this block (to this frame).
    pub frame_switch: Option<Frame>,
    /// M2/M30 in this block.
    pub program_end: bool,
    /// Not interpreted: deleted (when skipping), unparsed (lenient) or after the end.
    pub skipped: bool,
    /// A spline block: G5 or G5.1, or the G5.3 that runs a G5.2 NURBS (its
    /// curve's straight pieces are `expanded`), or a G5.2 control-point block.
    pub spline: Option<SplineStep>,
    /// The block's warnings, in the order they were found.
    pub warnings: Vec<Warning>,
}

/// What a block moves.
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Moves {
    /// Nothing.
    #[default]
    None,
    /// One ordinary move (G0–G3, G38, G53).
    Move(Motion),
    /// G28/G30: at rapid rate to the intermediate point, then to the stored
    /// position (machine coordinates).
    Home(Vec<Motion>),
    /// A canned cycle: its moves, and its steps (program coordinates, mm) in
    /// order, each `Rapid`/`Feed` step the next of `moves`. Flat writers emit
    /// the dwells and spindle steps too.
    Cycle {
        /// The cycle's moves, in order.
        moves: Vec<Motion>,
        /// The cycle's steps (moves, dwells, spindle), in order.
        steps: Vec<CycleStep>,
    },
    /// The straight pieces of a spline (G5, G5.1, the G5.3 that runs a G5.2
    /// NURBS; [`BlockEvent::spline`] says which).
    Spline(Vec<Motion>),
}

/// Which kind of [`Moves`] a block expands into (see [`Moves::expanded_mut`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Expansion {
    Home,
    Spline,
}

impl Moves {
    /// Every move, in order (the one move, or the expanded ones).
    pub fn all(&self) -> &[Motion] {
        match self {
            Moves::None => &[],
            Moves::Move(m) => std::slice::from_ref(m),
            Moves::Home(moves) | Moves::Cycle { moves, .. } | Moves::Spline(moves) => moves,
        }
    }

    /// The one ordinary move.
    pub fn motion(&self) -> Option<&Motion> {
        match self {
            Moves::Move(m) => Some(m),
            _ => None,
        }
    }

    /// The moves of a block that expands into several (G28/G30, a canned
    /// cycle, a spline); empty for others.
    pub fn expanded(&self) -> &[Motion] {
        match self {
            Moves::None | Moves::Move(_) => &[],
            Moves::Home(moves) | Moves::Cycle { moves, .. } | Moves::Spline(moves) => moves,
        }
    }

    /// The steps of a canned cycle; empty for other blocks.
    pub fn cycle_steps(&self) -> &[CycleStep] {
        match self {
            Moves::Cycle { steps, .. } => steps,
            _ => &[],
        }
    }

    /// The list the block's expanded moves go to: a block that moves nothing
    /// yet becomes `kind`; one that expands already keeps its kind (under
    /// `lenient` a G28 and a G5.3 may share a block).
    fn expanded_mut(&mut self, kind: Expansion) -> &mut Vec<Motion> {
        if matches!(self, Moves::None | Moves::Move(_)) {
            *self = match kind {
                Expansion::Home => Moves::Home(Vec::new()),
                Expansion::Spline => Moves::Spline(Vec::new()),
            };
        }
        match self {
            Moves::Home(moves) | Moves::Cycle { moves, .. } | Moves::Spline(moves) => moves,
            Moves::None | Moves::Move(_) => unreachable!("made a list above"),
        }
    }

    /// A canned cycle's moves and steps (the block's earlier expanded moves
    /// kept in front).
    fn cycle_mut(&mut self) -> (&mut Vec<Motion>, &mut Vec<CycleStep>) {
        if !matches!(self, Moves::Cycle { .. }) {
            let moves = match std::mem::take(self) {
                Moves::Home(moves) | Moves::Spline(moves) => moves,
                _ => Vec::new(),
            };
            *self = Moves::Cycle {
                moves,
                steps: Vec::new(),
            };
        }
        match self {
            Moves::Cycle { moves, steps } => (moves, steps),
            _ => unreachable!("made a cycle above"),
        }
    }
}

impl BlockEvent {
    /// The move, if the block is one ordinary move (G0–G3, G38, G53).
    pub fn motion(&self) -> Option<&Motion> {
        self.moves.motion()
    }

    /// The moves of a block that expands into several (G28/G30 through their
    /// intermediate point, canned cycles, splines), in order.
    pub fn expanded(&self) -> &[Motion] {
        self.moves.expanded()
    }

    /// The steps of a canned-cycle block (empty for other blocks).
    pub fn cycle_steps(&self) -> &[CycleStep] {
        self.moves.cycle_steps()
    }

    /// G28/G30 in this block.
    pub fn is_home(&self) -> bool {
        matches!(self.moves, Moves::Home(_))
    }

    /// Every move of the block, in order (the ordinary move, or the expanded ones).
    pub fn motions(&self) -> impl Iterator<Item = &Motion> {
        self.moves.all().iter()
    }
}

/// What a spline block does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplineStep {
    /// A curve runs (G5: 50, G5.1: 51, the NURBS of G5.2 run by G5.3: 53):
    /// `expanded` holds its straight pieces, within
    /// [`InterpretOptions::spline_tolerance_mm`] of it.
    Curve {
        code: u16,
        /// LinuxCNC's `NURBS_FEED` count: the control points, the start
        /// included.
        control_points: usize,
    },
    /// A G5.2 block: control points (or the first weight) are added; nothing
    /// moves until G5.3.
    NurbsPoint,
}

impl Default for BlockEvent {
    /// An empty event (for [`Interpreter::interpret_into`]).
    fn default() -> Self {
        BlockEvent {
            index: 0,
            line: 0,
            moves: Moves::None,
            origin: Origin::MACHINE,
            modal: ModalState::new(Frame::Joint),
            tool: ToolInUse::default(),
            start: Axes::default(),
            position: Axes::default(),
            time_min: 0.0,
            frame_switch: None,
            program_end: false,
            skipped: false,
            spline: None,
            warnings: Vec::new(),
        }
    }
}

/// The modal interpreter. Feed it blocks in order.
#[derive(Clone, Debug)]
pub struct Interpreter {
    options: InterpretOptions,
    modal: ModalState,
    /// Current position, machine coordinates (origin applied), mm/deg.
    position: Axes,
    /// The active work origin and G92 offset.
    origin: Origin,
    params: Parameters,
    time_min: f64,
    moved: bool,
    ended: bool,
    unknown_letters_seen: u32,
    /// The spindle's direction (M3/M4/M5; canned cycles check it).
    spindle: SpindleDirection,
    /// Spindle speed (S), mist (M7) and flood (M8) coolant, the selected
    /// (T) and the loaded (M6) tool: what `#<_rpm>`, `#<_mist>`, `#<_flood>`,
    /// `#<_selected_tool>`, `#<_current_tool>` and #5400 report.
    rpm: f64,
    mist: bool,
    flood: bool,
    selected_tool: f64,
    current_tool: f64,
    /// The tool table (G10 L1/L10/L11 change this copy).
    tools: ToolTable,
    /// The controller's tool length offset along Z, mm (`None`: not known,
    /// a G43 of a tool that an empty table does not list).
    tool_length_offset: Option<f64>,
    /// The offset mismatch was reported for the present tool and offset.
    offset_warned: bool,
    no_table_warned: bool,
    /// What LinuxCNC remembers between canned-cycle blocks.
    cycle_memory: CycleMemory,
    /// LinuxCNC's one list of spline control points (program coordinates,
    /// mm): filled by G5.2 blocks until G5.3 runs them, and by G5/G5.1 for
    /// their own curve (LinuxCNC shares it: points a G5.2 block left pending
    /// become part of the next G5/G5.1 curve).
    nurbs: Vec<super::spline::ControlPoint>,
    /// The order of the pending NURBS (`L`, 3 unless more).
    nurbs_order: usize,
}

/// The tool state a block leaves (see [`Interpreter::tool_words`]).
#[derive(Clone, Copy, Debug)]
struct ToolStep {
    selected: f64,
    current: f64,
    offset: Option<f64>,
    /// G10 L1/L10/L11: tool, new length, new radius (mm).
    update: Option<(u32, Option<f64>, Option<f64>)>,
}

impl ToolStep {
    fn current_number(&self) -> u32 {
        if self.current.is_finite() && self.current >= 0.0 {
            self.current.round().min(u32::MAX as f64) as u32
        } else {
            0
        }
    }
}

/// Per-block word values, fixed size (no allocation). Linear values are mm.
#[derive(Default)]
struct Words {
    axes: [Option<(f64, usize)>; crate::axes::AXIS_COUNT],
    ijk: [Option<f64>; 3],
    r: Option<f64>,
    p: Option<f64>,
    q: Option<f64>,
    l: Option<f64>,
    s: Option<f64>,
    t: Option<f64>,
    f: Option<f64>,
    /// Byte ranges of the F and first axis word (for error carets).
    f_span: Option<(usize, usize)>,
    /// Polar words (LinuxCNC: the last of each wins): `@` radius (mm) and
    /// `^` angle (degrees), and the first one's span.
    radius: Option<f64>,
    theta: Option<f64>,
    polar_span: Option<(usize, usize)>,
}

impl Words {
    fn has_axes(&self) -> bool {
        self.axes.iter().any(Option::is_some)
    }

    fn polar(&self) -> bool {
        self.radius.is_some() || self.theta.is_some()
    }

    fn first_axis(&self) -> usize {
        self.axes.iter().flatten().map(|a| a.1).min().unwrap_or(0)
    }
}

/// A byte range of the block's text (a word's, for error carets).
type Span = (usize, usize);

/// A block read into LinuxCNC's block structure ([`Interpreter::read`]): its
/// words' values and the codes it holds, each with its word's span. Nothing
/// is converted yet.
#[derive(Default)]
struct Decoded {
    words: Words,
    units: Option<Units>,
    /// The motion code (G80 too, unless the block holds another).
    motion: Option<MotionMode>,
    motion_word: Option<Span>,
    cancel_motion: bool,
    plane: Option<Plane>,
    distance: Option<Distance>,
    arc_distance: Option<Distance>,
    inverse_time: Option<bool>,
    /// G94/G95: the feed rate is set to 0.
    feed_reset: bool,
    cutter_comp: Option<CutterComp>,
    tool_length: Option<bool>,
    /// TRAORI/TRAFOOF, M428/M429, G43.4/G234/G49: the last one's frame.
    frame: Option<Frame>,
    retract_r_plane: Option<bool>,
    /// G43/G43.1/G43.2/G49 (code × 10) and its span.
    offset_code: Option<(i32, usize, usize)>,
    /// G53's span.
    g53: Option<Span>,
    coord_select: Option<u8>,
    /// The group-0 code that takes the axis words: (code, start, end).
    axis_user: Option<(GCode, usize, usize)>,
    store_home: Option<u8>,
    axis_offset: Option<u16>,
    dwell: bool,
    /// G5.3's span.
    nurbs_end: Option<Span>,
    /// A G code volcomp does not know (under `lenient`).
    unsupported: bool,
    /// M2/M30.
    end: bool,
    spindle: Option<SpindleDirection>,
    /// M6.
    tool_change: bool,
    /// M61's span.
    m61: Option<Span>,
    mist: Option<bool>,
    flood: Option<bool>,
    /// Unknown letters first seen in this block (a warning each).
    unknown_letters: u32,
    /// The upper-case letters the block holds, one bit each (bit 0: `A`).
    letters: u32,
}

impl Decoded {
    /// The modal state the block's codes set, from `before`; the feed rate
    /// too (a change of feed mode forgets the old F).
    fn modes(&self, before: &ModalState) -> ModalState {
        let mut m = *before;
        if let Some(u) = self.units {
            m.units = u;
        }
        if let Some(x) = self.motion {
            m.motion = x;
        }
        if let Some(p) = self.plane {
            m.plane = p;
        }
        if let Some(x) = self.distance {
            m.distance = x;
        }
        if let Some(x) = self.arc_distance {
            m.arc_distance = x;
        }
        if let Some(x) = self.inverse_time {
            m.inverse_time = x;
        }
        if let Some(x) = self.cutter_comp {
            m.cutter_comp = x;
        }
        if let Some(x) = self.tool_length {
            m.tool_length = x;
        }
        if let Some(x) = self.frame {
            m.frame = x;
        }
        if let Some(x) = self.retract_r_plane {
            m.retract_r_plane = x;
        }
        if m.inverse_time != before.inverse_time || self.feed_reset {
            m.feed = 0.0;
        }
        if let Some(f) = self.words.f {
            m.feed = if m.inverse_time {
                f
            } else {
                f * m.units.scale()
            };
        }
        m
    }
}

/// What a block changes: a copy of the interpreter's state that the
/// conversions work on, committed ([`Interpreter::commit`]) only when the
/// block succeeds. A failing block drops it: the one way a block is rolled
/// back.
struct BlockState {
    modal: ModalState,
    /// The origin the block sets (G54…, G10 L2/L20, G52, G92…), `None` while
    /// it keeps the interpreter's: the origin, with a dialect's frame 328
    /// bytes, is copied only by the blocks that change it.
    origin: Option<Origin>,
    /// The position after the block (machine coordinates).
    position: Axes,
    spindle: SpindleDirection,
    cycle_memory: CycleMemory,
    mist: bool,
    flood: bool,
    /// Dwell time of the block (G4, cycles), min.
    dwell_min: f64,
    tool: ToolStep,
    /// Parameters the block sets, in order.
    store: Vec<(usize, f64)>,
    nurbs: Vec<super::spline::ControlPoint>,
    nurbs_order: usize,
    /// The block's one ordinary move.
    motion: Option<Motion>,
    /// M2/M30.
    ended: bool,
}

impl BlockState {
    /// The block's origin: the one it sets, or `current` (the interpreter's).
    fn origin<'a>(&'a self, current: &'a Origin) -> &'a Origin {
        self.origin.as_ref().unwrap_or(current)
    }

    /// The block's origin to change, from `current` (the interpreter's) on
    /// the first change.
    fn origin_mut(&mut self, current: &Origin) -> &mut Origin {
        self.origin.get_or_insert(*current)
    }

    /// G92/G52 applied: #5210 and the offsets #5211….
    fn store_g92(&mut self, current: &Origin) {
        let g92 = self.origin(current).g92;
        self.store.push((numbers::G92_ENABLED, 1.0));
        for (k, axis) in Axis::ALL.into_iter().enumerate() {
            self.store.push((numbers::G92_OFFSET + k, g92.get(axis)));
        }
    }
}

/// A block being converted: its text and words, its event (warnings and
/// moves go there) and the state it builds.
struct Convert<'a> {
    block: &'a Block,
    words: &'a Words,
    event: &'a mut BlockEvent,
    next: &'a mut BlockState,
}

impl Interpreter {
    /// An interpreter with a fresh parameter table ([`Parameters::new`]: G54,
    /// every origin zero) and no tool table.
    pub fn new(options: InterpretOptions) -> Self {
        Interpreter::with_parameters(options, Parameters::new())
    }

    /// An interpreter starting from a parameter table (a `.var` file's work
    /// origins and stored positions, `--offset`), with coordinate system
    /// `#5220` active, as LinuxCNC starts.
    pub fn with_parameters(options: InterpretOptions, params: Parameters) -> Self {
        let mut i = Interpreter {
            options,
            modal: ModalState::new(options.initial_frame),
            position: options.initial_position,
            origin: Origin::MACHINE,
            params,
            time_min: 0.0,
            moved: false,
            ended: false,
            unknown_letters_seen: 0,
            spindle: SpindleDirection::Stopped,
            rpm: 0.0,
            mist: false,
            flood: false,
            selected_tool: 0.0,
            current_tool: 0.0,
            tools: ToolTable::new(),
            tool_length_offset: Some(0.0),
            offset_warned: false,
            no_table_warned: false,
            cycle_memory: CycleMemory::default(),
            nurbs: Vec::new(),
            nurbs_order: 3,
        };
        // LinuxCNC's `init`: `(int)(pars[5220] + 0.0001)`, truncated (1.9 is
        // G54), and 1 (with #5220 reset to 1) when out of 1 … 9.
        let system = (i.params.get(numbers::COORD_SYSTEM) + 0.0001).trunc();
        i.modal.coord_system = if (1.0..=9.0).contains(&system) {
            system as u8
        } else {
            i.params.set(numbers::COORD_SYSTEM, 1.0);
            1
        };
        i.origin.work = i.stored_origin(i.modal.coord_system);
        i.origin.rotation_deg = i
            .params
            .get(numbers::coord(i.modal.coord_system as usize, 9));
        if i.params.get(numbers::G92_ENABLED) != 0.0 {
            i.origin.g92 = i.stored_axes(numbers::G92_OFFSET);
        }
        i.current_tool = i.params.get(numbers::TOOL);
        i.update_parameters();
        i
    }

    /// The tool table the program runs with.
    pub fn set_tools(&mut self, tools: ToolTable) {
        self.tools = tools;
        self.update_parameters();
    }

    /// The tool in the spindle.
    pub fn tool_in_use(&self) -> ToolInUse {
        let number = if self.current_tool.is_finite() && self.current_tool >= 0.0 {
            self.current_tool.round().min(u32::MAX as f64) as u32
        } else {
            0
        };
        self.tools.in_use(number, ToolInUse::DEFAULT)
    }

    /// The tool table as the program has left it (G10 L1/L10/L11).
    pub fn tools(&self) -> &ToolTable {
        &self.tools
    }

    /// The options it runs with.
    pub fn options(&self) -> &InterpretOptions {
        &self.options
    }

    /// Modal state now (after the last block).
    pub fn modal(&self) -> &ModalState {
        &self.modal
    }

    /// Position now (after the last block), machine coordinates.
    pub fn position(&self) -> Axes {
        self.position
    }

    /// The active origin (work offset, G92, rotation).
    pub fn origin(&self) -> Origin {
        self.origin
    }

    /// The active origin, borrowed: a dialect front that reads it on every
    /// block does not copy it (its frame with it).
    pub fn origin_ref(&self) -> &Origin {
        &self.origin
    }

    /// Set a dialect's programmable frame (Sinumerik `TRANS`/`ROT`/…, a
    /// swivelled plane), applied to the X Y Z words of the next blocks
    /// before the work origin ([`Origin::frame`]); `None` clears it.
    /// LinuxCNC programs never set one.
    pub fn set_frame(&mut self, frame: Option<super::origin::FrameTransform>) {
        self.origin.frame = frame;
    }

    /// Set the work origin (and clear its XY rotation): a dialect whose
    /// control starts without a settable frame (Sinumerik's `G500`) or
    /// switches it off.
    pub fn set_work_origin(&mut self, work: Axes) {
        self.origin.work = work;
        self.origin.rotation_deg = 0.0;
    }

    /// Set the position (machine coordinates) without a move: a dialect's
    /// step that moves axes the program does not write as words (a
    /// swivelled plane turning the rotary axes), reported by the front.
    pub fn set_position(&mut self, position: Axes) {
        self.position = position;
    }

    /// The parameter table (the language layer reads and writes it).
    pub fn parameters_mut(&mut self) -> &mut Parameters {
        &mut self.params
    }

    /// The parameter table (work origins, G92 offsets, named parameters).
    pub fn parameters(&self) -> &Parameters {
        &self.params
    }

    /// Interpret one block into a new event.
    pub fn interpret(&mut self, block: &Block) -> Result<BlockEvent, GcodeError> {
        let mut event = BlockEvent::default();
        self.interpret_into(block, &mut event)?;
        Ok(event)
    }

    /// Interpret one block, reusing `event` (its vectors keep their capacity).
    /// On error the interpreter's state is unchanged.
    pub fn interpret_into(
        &mut self,
        block: &Block,
        event: &mut BlockEvent,
    ) -> Result<(), GcodeError> {
        event.index = block.line.saturating_sub(1);
        event.line = block.line;
        event.moves = Moves::None;
        event.start = self.position;
        event.origin = self.origin;
        event.frame_switch = None;
        event.program_end = false;
        event.skipped = false;
        event.spline = None;
        event.warnings.clear();
        let result = self.apply(block, event);
        event.modal = self.modal;
        event.tool = self.tool_in_use();
        event.position = self.position;
        event.time_min = self.time_min;
        result
    }

    /// Fill `event` for a line that is not executed (after the program end):
    /// no motion, state unchanged, `skipped` set.
    pub fn pass_over(&self, block: &Block, event: &mut BlockEvent) {
        event.index = block.line.saturating_sub(1);
        event.line = block.line;
        event.moves = Moves::None;
        event.start = self.position;
        event.position = self.position;
        event.origin = self.origin;
        event.modal = self.modal;
        event.tool = self.tool_in_use();
        event.time_min = self.time_min;
        event.frame_switch = None;
        event.program_end = false;
        event.skipped = true;
        event.spline = None;
        event.warnings.clear();
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

    /// Origin of coordinate system `n` (1 … 9) from the parameters, mm/deg.
    fn stored_origin(&self, n: u8) -> Axes {
        self.stored_axes(numbers::coord(n as usize, 0))
    }

    /// The nine axes stored at `base` (X) … in LinuxCNC's parameter order.
    fn stored_axes(&self, base: usize) -> Axes {
        let mut a = Axes::default();
        for (k, axis) in Axis::ALL.into_iter().enumerate() {
            a.set(axis, self.params.get(base + k));
        }
        a
    }

    /// Write the position, modal state and tool to the parameter table.
    fn update_parameters(&mut self) {
        let scale = self.modal.units.scale();
        let program = self.origin.to_program(&self.position);
        let unit = |axis: Axis, v: f64| if axis.is_rotary() { v } else { v / scale };
        let mut pos = [0.0; 9];
        let mut abs = [0.0; 9];
        for (k, axis) in Axis::ALL.into_iter().enumerate() {
            pos[k] = unit(axis, program.get(axis));
            abs[k] = unit(axis, self.position.get(axis));
        }
        self.params.set_position(pos, abs);
        let m = &self.modal;
        let s = self.params.system_mut();
        s.motion_mode = m.motion.code10();
        s.plane = match m.plane {
            Plane::XY => 170.0,
            Plane::ZX => 180.0,
            Plane::YZ => 190.0,
        };
        s.cutter_comp = match m.cutter_comp {
            CutterComp::Off => 400.0,
            CutterComp::Left => 410.0,
            CutterComp::Right => 420.0,
        };
        s.metric = m.units == Units::Mm;
        s.incremental = m.distance == Distance::Incremental;
        s.ijk_absolute = m.arc_distance == Distance::Absolute;
        s.inverse_time = m.inverse_time;
        s.coord_system = match m.coord_system {
            n @ 1..=6 => 530.0 + 10.0 * n as f64,
            n => 584.0 + n as f64,
        };
        s.tool_offset = m.tool_length;
        s.retract_r_plane = m.retract_r_plane;
        s.rpm = self.rpm;
        s.spindle_on = self.spindle != SpindleDirection::Stopped;
        s.spindle_cw = self.spindle == SpindleDirection::Clockwise;
        s.mist = self.mist;
        s.flood = self.flood;
        s.selected_tool = self.selected_tool;
        s.current_tool = self.current_tool;
        s.feed = if m.inverse_time {
            m.feed
        } else {
            m.feed / scale
        };
        self.params.set(numbers::TOOL, self.current_tool);
    }

    /// One block: LinuxCNC's `read_items` (+ `enhance_block`), `check_items`,
    /// then `execute_block`'s conversions in its order. The conversions work
    /// on a [`BlockState`]; it is committed only when the block succeeds.
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
        if block.uses_language() {
            // Parameters, expressions and O-words are run by the language
            // layer (`Execution`); a block read by the bare reader still holds them.
            let at = block
                .exprs
                .first()
                .map(|e| (e.start, e.end))
                .or_else(|| block.o_word.as_ref().map(|o| (o.start, o.end)))
                .unwrap_or((0, block.raw.len()));
            return self.fail(block, event, ErrorKind::NeedsLanguage, at.0, at.1);
        }
        self.params.set_line(block.line);
        // Filled in place (`read`) and borrowed (`commit`): these block-sized
        // values are not moved between frames.
        let mut decoded = Decoded::default();
        self.read(block, event, &mut decoded)?;
        let mut next = BlockState {
            modal: decoded.modes(&self.modal),
            origin: None,
            position: self.position,
            spindle: self.spindle,
            cycle_memory: self.cycle_memory,
            mist: self.mist,
            flood: self.flood,
            dwell_min: 0.0,
            tool: ToolStep {
                selected: self.selected_tool,
                current: self.current_tool,
                offset: self.tool_length_offset,
                update: None,
            },
            store: Vec::new(),
            nurbs: self.nurbs.clone(),
            nurbs_order: self.nurbs_order,
            motion: None,
            ended: false,
        };
        self.check(block, event, &mut decoded, &next.modal)?;
        let mut c = Convert {
            block,
            words: &decoded.words,
            event,
            next: &mut next,
        };
        self.convert_tools(&mut c, &decoded)?;
        self.convert_spindle_and_coolant(&mut c, &decoded);
        self.convert_dwell(&mut c, &decoded);
        self.convert_coord_system(&mut c, &decoded);
        self.convert_modal_0(&mut c, &decoded)?;
        let nurbs_ran = self.convert_nurbs_end(&mut c, &decoded)?;
        self.convert_motion(&mut c, &decoded, nurbs_ran)?;
        self.convert_stop(&mut c, &decoded);
        self.commit(block, event, &decoded, &mut next);
        Ok(())
    }

    /// LinuxCNC's `read_items` and `enhance_block`: the block's words into a
    /// [`Decoded`] block. Refuses repeated words, two codes of one modal
    /// group, unknown G codes, M98/M99 and axes the machine lacks.
    fn read(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        d: &mut Decoded,
    ) -> Result<(), GcodeError> {
        for kw in &block.keywords {
            d.frame = Some(match kw.keyword {
                crate::gcode::syntax::block::Keyword::TraOri => Frame::Part,
                crate::gcode::syntax::block::Keyword::TraFoof => Frame::Joint,
            });
        }
        // (The words a front found to change nothing are passed over:
        // `Block::machine_words`.)
        let words = block.machine_words();
        // Units first (found with the conflicts): every number of the block
        // is in the block's units.
        let other_motion = self.read_conflicts(block, words, event, d)?;
        let scale = d.units.unwrap_or(self.modal.units).scale();
        for w in words {
            match w.letter {
                b'G' => self.read_g(block, event, w, d, other_motion)?,
                b'M' => self.read_m(block, event, w, d)?,
                b'X' | b'Y' | b'Z' | b'A' | b'B' | b'C' | b'U' | b'V' | b'W' => {
                    self.read_axis(block, event, w, &mut d.words, scale)?
                }
                _ => self.read_other(block, event, w, d, scale),
            }
        }
        // G43.1's axis words set the offset and do not move (LinuxCNC's
        // `enhance_block`), unless the block has its own motion code.
        if let Some((431, s, e)) = d.offset_code
            && d.motion_word.is_none()
            && d.axis_user.is_none()
        {
            d.axis_user = Some((GCode::ToolLengthDynamic, s, e));
        }
        Ok(())
    }

    /// Repeated words and modal-group conflicts (LinuxCNC refuses both);
    /// whether the block holds a motion code other than G80. Sets `d`'s
    /// units (the block's last G20/G21) and the letters it holds.
    fn read_conflicts(
        &self,
        block: &Block,
        words: &[Word],
        event: &mut BlockEvent,
        d: &mut Decoded,
    ) -> Result<bool, GcodeError> {
        let mut g_groups = [false; 16];
        let mut m_groups = [false; 11];
        let mut seen_letters = 0u32;
        // G and M: their bits in `Decoded::letters`.
        let mut codes = 0u32;
        for w in words {
            // The error is built only for a conflict (most blocks have none).
            let (conflict, kind): (bool, fn(char) -> ErrorKind) = match w.letter {
                b'G' => {
                    codes |= 1 << (b'G' - b'A');
                    let Some(g) = w.code10().and_then(|code| {
                        let g = classify_g(code);
                        if let GCode::Units(u) = g {
                            d.units = Some(u);
                        }
                        // G80 with another motion code is no conflict: the
                        // other code wins (LinuxCNC's `read_g`).
                        g_group(g).filter(|_| code != 800)
                    }) else {
                        continue;
                    };
                    let seen = std::mem::replace(&mut g_groups[g as usize], true);
                    (seen, ErrorKind::ModalGroupConflict)
                }
                b'M' => {
                    codes |= 1 << (b'M' - b'A');
                    // LinuxCNC 2.9 allows no two codes of a group, M7 and
                    // M8 included (`read_m`).
                    let Some(g) = w.code10().and_then(m_group) else {
                        continue;
                    };
                    let seen = std::mem::replace(&mut m_groups[g as usize], true);
                    (seen, ErrorKind::ModalGroupConflict)
                }
                letter if letter.is_ascii_uppercase() => {
                    let bit = 1u32 << (letter - b'A');
                    let seen = seen_letters & bit != 0;
                    seen_letters |= bit;
                    (seen, ErrorKind::RepeatedWord)
                }
                _ => continue,
            };
            if conflict {
                let kind = kind(w.letter as char);
                self.fail(block, event, kind, w.start, w.end)?;
            }
        }
        d.letters = seen_letters | codes;
        Ok(g_groups[1])
    }

    /// A G word (LinuxCNC's `read_g`); `other_motion`: the block holds a
    /// motion code other than G80.
    fn read_g(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        w: &Word,
        d: &mut Decoded,
        other_motion: bool,
    ) -> Result<(), GcodeError> {
        let Some(code) = w.code10() else {
            d.unsupported = true;
            let kind = ErrorKind::UnsupportedGCode(format!("G{}", w.value));
            return self.fail(block, event, kind, w.start, w.end);
        };
        let g = classify_g(code);
        let span = (w.start, w.end);
        match g {
            GCode::Motion(m) => {
                d.motion = Some(m);
                d.motion_word = Some(span);
            }
            GCode::Plane(p) => d.plane = Some(p),
            GCode::Units(_) => {}
            GCode::Distance(x) => d.distance = Some(x),
            GCode::ArcDistance(x) => d.arc_distance = Some(x),
            GCode::FeedMode(inv) => {
                d.inverse_time = Some(inv);
                // LinuxCNC: G94 and G95 set the feed rate to 0.
                if !inv {
                    d.feed_reset = true;
                }
            }
            GCode::CutterComp(x) => d.cutter_comp = Some(x),
            GCode::ToolLength | GCode::ToolLengthDynamic | GCode::ToolLengthAdd => {
                d.tool_length = Some(true);
                d.offset_code = Some((code, w.start, w.end));
            }
            GCode::ToolTip => {
                d.tool_length = Some(true);
                d.frame = Some(Frame::Part);
                d.offset_code = Some((430, w.start, w.end));
            }
            GCode::ToolLengthOff => {
                d.tool_length = Some(false);
                d.frame = Some(Frame::Joint);
                d.offset_code = Some((490, w.start, w.end));
            }
            GCode::MachineCoordinates => d.g53 = Some(span),
            GCode::CoordSystem(n) => d.coord_select = Some(n),
            GCode::RetractMode(r) => d.retract_r_plane = Some(r),
            GCode::Home(_) | GCode::SetData => d.axis_user = Some((g, w.start, w.end)),
            GCode::StoreHome(n) => d.store_home = Some(n),
            GCode::AxisOffset(c) => {
                d.axis_offset = Some(c);
                if c == 920 || c == 520 {
                    d.axis_user = Some((g, w.start, w.end));
                }
            }
            GCode::Dwell => d.dwell = true,
            GCode::NurbsEnd => d.nurbs_end = Some(span),
            GCode::PassThrough => {}
            GCode::CancelMotion => {
                // Ignored when the block holds another motion code.
                if !other_motion {
                    d.motion = Some(MotionMode::None);
                    d.cancel_motion = true;
                }
            }
            GCode::Unsupported => {
                d.unsupported = true;
                let kind = ErrorKind::UnsupportedGCode(code_text('G', code));
                self.fail(block, event, kind, w.start, w.end)?
            }
        }
        Ok(())
    }

    /// An M word (LinuxCNC's `read_m`).
    fn read_m(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        w: &Word,
        d: &mut Decoded,
    ) -> Result<(), GcodeError> {
        match w.code10().map(classify_m) {
            Some(MCode::End) => d.end = true,
            Some(MCode::Subroutine) => {
                let kind = ErrorKind::SubroutineCall(code_text('M', w.code10().unwrap_or(0)));
                self.fail(block, event, kind, w.start, w.end)?
            }
            Some(MCode::ToolTipOn) => d.frame = Some(Frame::Part),
            Some(MCode::ToolTipOff) => d.frame = Some(Frame::Joint),
            Some(MCode::PassThrough) | None => match w.code10() {
                Some(30) => d.spindle = Some(SpindleDirection::Clockwise),
                Some(40) => d.spindle = Some(SpindleDirection::CounterClockwise),
                Some(50) => d.spindle = Some(SpindleDirection::Stopped),
                Some(60) => d.tool_change = true,
                Some(610) => d.m61 = Some((w.start, w.end)),
                Some(70) => d.mist = Some(true),
                Some(80) => d.flood = Some(true),
                Some(90) => (d.mist, d.flood) = (Some(false), Some(false)),
                _ => {}
            },
        }
        Ok(())
    }

    /// An axis word, in mm (linear) or degrees; `scale`: mm per program unit.
    fn read_axis(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        w: &Word,
        words: &mut Words,
        scale: f64,
    ) -> Result<(), GcodeError> {
        let Some(axis) = Axis::from_letter(w.letter as char) else {
            return Ok(());
        };
        if !self.options.axes.contains(axis) {
            // LinuxCNC: "Bad character 'b' used" for an axis its
            // configuration lacks; under --lenient the word is
            // ignored and reported.
            let kind = ErrorKind::AxisNotOnMachine {
                letter: axis.letter(),
                axes: self.options.axes.letters(),
            };
            return self.fail(block, event, kind, w.start, w.end);
        }
        let v = if axis.is_rotary() {
            w.value
        } else {
            w.value * scale
        };
        words.axes[axis as usize] = Some((v, w.start));
        Ok(())
    }

    /// The other words: numbers the conversions read, and a warning for a
    /// letter that is not known (once a letter).
    fn read_other(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        w: &Word,
        d: &mut Decoded,
        scale: f64,
    ) {
        let words = &mut d.words;
        match w.letter {
            b'I' => words.ijk[0] = Some(w.value * scale),
            b'J' => words.ijk[1] = Some(w.value * scale),
            b'K' => words.ijk[2] = Some(w.value * scale),
            b'R' => words.r = Some(w.value),
            b'P' => words.p = Some(w.value),
            b'Q' => words.q = Some(w.value),
            b'L' => words.l = Some(w.value),
            b'S' => words.s = Some(w.value),
            b'T' => words.t = Some(w.value),
            b'F' => {
                words.f = Some(w.value);
                words.f_span = Some((w.start, w.end));
            }
            b'@' => {
                words.radius = Some(w.value * scale);
                words.polar_span.get_or_insert((w.start, w.end));
            }
            b'^' => {
                words.theta = Some(w.value);
                words.polar_span.get_or_insert((w.start, w.end));
            }
            other => {
                if !is_known_letter(other) && other.is_ascii_uppercase() {
                    let bit = 1u32 << (other - b'A');
                    if (self.unknown_letters_seen | d.unknown_letters) & bit == 0 {
                        d.unknown_letters |= bit;
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

    /// LinuxCNC's `check_items`: what the block asks that no conversion can
    /// do, refused with LinuxCNC's messages. `modal` is the modal state the
    /// block's codes set. Under `lenient` a refused polar word is dropped.
    fn check(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        d: &mut Decoded,
        modal: &ModalState,
    ) -> Result<(), GcodeError> {
        if d.dwell && !matches!(d.words.p, Some(p) if p.is_finite()) {
            self.fail(block, event, ErrorKind::DwellWithoutP, 0, block.raw.len())?;
        }
        // Polar words (LinuxCNC's `enhance_block`): in the plane in force
        // before the block, G17, in place of X and Y, in motion blocks only.
        if d.words.polar() {
            let (s, e) = d.words.polar_span.unwrap_or((0, block.raw.len()));
            let refused = if self.modal.plane != Plane::XY {
                Some("Cannot use polar coordinate except in G17 plane")
            } else if d.words.axes[0].is_some() {
                Some("Cannot specify both polar coordinate and X word")
            } else if d.words.axes[1].is_some() {
                Some("Cannot specify both polar coordinate and Y word")
            } else if d.axis_user.is_some() {
                Some("Polar coordinates can only be used for motion")
            } else {
                None
            };
            if let Some(what) = refused {
                self.fail(block, event, ErrorKind::Polar(what), s, e)?;
                d.words.radius = None;
                d.words.theta = None;
            }
        }
        // G5.3 with a motion code other than G5.2 (`check_g_codes`).
        if d.nurbs_end.is_some()
            && let Some((ms, me)) = d.motion_word
            && modal.motion != MotionMode::Spline(52)
        {
            self.fail(
                block,
                event,
                ErrorKind::Spline(
                    "Between G5.2 and G5.3 codes, only additional G5.2 codes are allowed.".into(),
                ),
                ms,
                me,
            )?;
        }
        // A motion code (G80 aside) beside a modal-group-0 code that takes the
        // axis words (G10, G28, G30, G52, G92; LinuxCNC's `enhance_block`),
        // whether or not the block has axis words.
        if let Some((g, _, _)) = d.axis_user
            && g != GCode::ToolLengthDynamic
            && let Some((ms, me)) = d.motion_word
            && d.motion != Some(MotionMode::None)
        {
            self.fail(block, event, ErrorKind::TwoAxisUsers, ms, me)?;
        }
        // A code volcomp does not know may use any word.
        if !d.unsupported {
            self.check_words(block, event, &d.words, d.letters, d.axis_user.is_some())?;
        }
        // G53 moves straight, in absolute coordinates (LinuxCNC's
        // `check_g_codes`; the block's own G90/G91 counts).
        if let Some((s, e)) = d.g53 {
            if !matches!(modal.motion, MotionMode::Rapid | MotionMode::Linear) {
                self.fail(block, event, ErrorKind::G53Motion, s, e)?;
            } else if modal.distance == Distance::Incremental {
                self.fail(block, event, ErrorKind::G53Incremental, s, e)?;
            }
        }
        Ok(())
    }

    /// T, M6/M61, then G43/G43.1/G43.2/G49 (LinuxCNC's `convert_tool_select`,
    /// `convert_m`'s tool change, `convert_tool_length_offset`; nothing
    /// between them in LinuxCNC's order reads or refuses anything).
    fn convert_tools(&self, c: &mut Convert<'_>, d: &Decoded) -> Result<(), GcodeError> {
        c.next.tool = self.tool_words(c.block, c.event, d)?;
        Ok(())
    }

    /// M3/M4/M5, then M7/M8/M9 (`convert_m`); S is kept at the commit.
    fn convert_spindle_and_coolant(&self, c: &mut Convert<'_>, d: &Decoded) {
        if let Some(s) = d.spindle {
            c.next.spindle = s;
        }
        if let Some(m) = d.mist {
            c.next.mist = m;
        }
        if let Some(f) = d.flood {
            c.next.flood = f;
        }
    }

    /// G4 (`convert_dwell`; a missing P was refused by the check).
    fn convert_dwell(&self, c: &mut Convert<'_>, d: &Decoded) {
        if d.dwell
            && let Some(p) = d.words.p
            && p.is_finite()
        {
            c.next.dwell_min += p.max(0.0) / 60.0;
        }
    }

    /// G54–G59.3 (`convert_coordinate_system`).
    fn convert_coord_system(&self, c: &mut Convert<'_>, d: &Decoded) {
        if let Some(n) = d.coord_select {
            c.next.modal.coord_system = n;
            let origin = c.next.origin_mut(&self.origin);
            origin.work = self.stored_origin(n);
            origin.rotation_deg = self.params.get(numbers::coord(n as usize, 9));
        }
    }

    /// The group-0 codes that take the axis words (G10, G28/G30, G52, G92,
    /// and the G43.1 of `enhance_block`), then G28.1/G30.1 and
    /// G92.1/G92.2/G92.3 (`convert_modal_0`).
    fn convert_modal_0(&self, c: &mut Convert<'_>, d: &Decoded) -> Result<(), GcodeError> {
        let (block, words) = (c.block, c.words);
        // Program coordinates of the current position in the block's origin.
        let program_now = |c: &Convert<'_>| c.next.origin(&self.origin).to_program(&self.position);
        match d.axis_user {
            Some((GCode::SetData, s, e)) => self.set_data(c, (s, e))?,
            Some((GCode::AxisOffset(520), ..)) => {
                // G52: the words are the offsets (LinuxCNC keeps them where
                // G92 keeps its own).
                if !words.has_axes() {
                    self.fail(
                        block,
                        c.event,
                        ErrorKind::G52WithoutAxes,
                        0,
                        block.raw.len(),
                    )?;
                }
                let origin = c.next.origin_mut(&self.origin);
                for axis in Axis::ALL {
                    if let Some((v, _)) = words.axes[axis as usize] {
                        origin.g92.set(axis, v);
                    }
                }
                c.next.store_g92(&self.origin);
            }
            Some((GCode::AxisOffset(_), ..)) => {
                // G92: offsets so that the current position reads as the words.
                if !words.has_axes() {
                    self.fail(
                        block,
                        c.event,
                        ErrorKind::G92WithoutAxes,
                        0,
                        block.raw.len(),
                    )?;
                }
                let q = program_now(c).zip_with(&c.next.origin(&self.origin).g92, |p, g| p + g);
                let origin = c.next.origin_mut(&self.origin);
                for axis in Axis::ALL {
                    if let Some((v, _)) = words.axes[axis as usize] {
                        origin.g92.set(axis, q.get(axis) - v);
                    }
                }
                c.next.store_g92(&self.origin);
            }
            Some((GCode::Home(n), ..)) => {
                let now = program_now(c);
                self.convert_home(c, n, &now)
            }
            _ => {}
        }
        if let Some(n) = d.store_home {
            let base = if n == 28 {
                numbers::G28_POSITION
            } else {
                numbers::G30_POSITION
            };
            for (k, axis) in Axis::ALL.into_iter().enumerate() {
                c.next.store.push((base + k, self.position.get(axis)));
            }
        }
        match d.axis_offset {
            Some(921) | Some(922) => {
                c.next.origin_mut(&self.origin).g92 = Axes::default();
                c.next.store.push((numbers::G92_ENABLED, 0.0));
                if d.axis_offset == Some(921) {
                    for k in 0..9 {
                        c.next.store.push((numbers::G92_OFFSET + k, 0.0));
                    }
                }
            }
            Some(923) => {
                c.next.origin_mut(&self.origin).g92 = self.stored_axes(numbers::G92_OFFSET);
                c.next.store.push((numbers::G92_ENABLED, 1.0));
            }
            _ => {}
        }
        Ok(())
    }

    /// G28/G30 (`convert_home`): to the intermediate point (program
    /// coordinates), then to the stored position of the given axes (all when
    /// none is given).
    fn convert_home(&self, c: &mut Convert<'_>, n: u8, program_now: &Axes) {
        let words = c.words;
        let origin = *c.next.origin(&self.origin);
        let mut mid = *program_now;
        let mut given = [false; crate::axes::AXIS_COUNT];
        for (i, a) in words.axes.iter().enumerate() {
            given[i] = a.is_some();
        }
        for axis in Axis::ALL {
            if let Some((v, _)) = words.axes[axis as usize] {
                let base = if c.next.modal.distance == Distance::Incremental {
                    program_now.get(axis)
                } else {
                    0.0
                };
                mid.set(axis, base + v);
            }
        }
        let mid_program = mid;
        let mid = origin.to_machine(&mid_program);
        let base = if n == 28 {
            numbers::G28_POSITION
        } else {
            numbers::G30_POSITION
        };
        // LinuxCNC's `convert_home` mixes in program coordinates: the stored
        // position of the given axes, the intermediate point's others (under
        // an XY rotation one axis word moves both X and Y).
        let stored = origin.to_program(&self.stored_axes(base));
        let mut home = mid_program;
        let all = !given.iter().any(|x| *x);
        for axis in Axis::ALL {
            if all || given[axis as usize] {
                home.set(axis, stored.get(axis));
            }
        }
        let home = if all {
            self.stored_axes(base)
        } else {
            origin.to_machine(&home)
        };
        for (from, to, g53) in [(self.position, mid, false), (mid, home, true)] {
            let mut m = Motion {
                kind: MotionKind::Rapid,
                frame: Frame::Joint,
                machine_coordinates: g53,
                start: from,
                end: to,
                feed: Feed::Rapid,
                duration_min: 0.0,
            };
            m.duration_min = duration_min(&m, self.options.rapid_mm_per_min);
            c.event.moves.expanded_mut(Expansion::Home).push(m);
        }
        c.next.position = home;
    }

    /// G5.3 runs the NURBS of the G5.2 blocks before it (a group-0 code:
    /// before the block's motion; LinuxCNC's motion mode is then none).
    /// Returns whether the curve ran.
    fn convert_nurbs_end(&self, c: &mut Convert<'_>, d: &Decoded) -> Result<bool, GcodeError> {
        let Some((s, e)) = d.nurbs_end else {
            return Ok(false);
        };
        let block = c.block;
        let mut ran = false;
        if self.modal.motion != MotionMode::Spline(52) {
            self.fail(
                block,
                c.event,
                ErrorKind::Spline("Cannot use G5.3 without G5.2 first".into()),
                s,
                e,
            )?;
        } else if c.next.nurbs.len() < c.next.nurbs_order {
            self.fail(
                block,
                c.event,
                ErrorKind::Spline(format!(
                    "You must specify a number of control points at least equal to the order L = {}",
                    c.next.nurbs_order
                )),
                s,
                e,
            )?;
        } else {
            let curve = super::spline::Nurbs {
                points: std::mem::take(&mut c.next.nurbs),
                order: c.next.nurbs_order,
            };
            c.next.position = self.run_curve(c, self.position, &curve, 53, (s, e))?;
            ran = true;
        }
        if d.motion_word.is_none() && !c.words.has_axes() {
            c.next.modal.motion = MotionMode::None;
        }
        Ok(ran)
    }

    /// The block's motion (`convert_motion`): a canned cycle, a spline, a
    /// straight move, an arc or a probing move, to the axis words' target.
    fn convert_motion(
        &self,
        c: &mut Convert<'_>,
        d: &Decoded,
        nurbs_ran: bool,
    ) -> Result<(), GcodeError> {
        let (block, words) = (c.block, c.words);
        let machine_coordinates = d.g53.is_some();
        let nurbs_block = c.next.modal.motion == MotionMode::Spline(52) && d.motion_word.is_some();
        if d.axis_user.is_some()
            || !(words.has_axes() || words.polar() || nurbs_block)
            || d.unsupported
        {
            // (Lenient: an unsupported code's axis words are ignored.)
            return Ok(());
        }
        if c.next.modal.motion == MotionMode::None {
            let at = words
                .polar_span
                .map_or(words.first_axis(), |p| p.0.min(words.first_axis()));
            self.fail(block, c.event, ErrorKind::NoMotionMode, at, at + 1)?;
            c.next.modal.motion = MotionMode::Linear;
        }
        if c.next.modal.cutter_comp != CutterComp::Off {
            let (s, e) = d
                .motion_word
                .unwrap_or((words.first_axis(), words.first_axis() + 1));
            let name = if c.next.modal.cutter_comp == CutterComp::Left {
                "G41"
            } else {
                "G42"
            };
            self.fail(
                block,
                c.event,
                ErrorKind::CutterCompensation(name.into()),
                s,
                e,
            )?;
        }
        if let MotionMode::Cycle(code) = c.next.modal.motion {
            c.next.position = self.cycle(c, code)?;
            return Ok(());
        }
        let modal = c.next.modal;
        let incremental = modal.distance == Distance::Incremental && !machine_coordinates;
        // The target in the block's coordinates (machine for G53).
        let mut target = if machine_coordinates {
            self.position
        } else {
            c.next.origin(&self.origin).to_program(&self.position)
        };
        for axis in Axis::ALL {
            if let Some((v, _)) = words.axes[axis as usize] {
                let base = if incremental { target.get(axis) } else { 0.0 };
                target.set(axis, base + v);
            }
        }
        // Polar words (LinuxCNC's `find_ends`); a G5.2 control point
        // takes X and Y only.
        if words.polar() && modal.motion != MotionMode::Spline(52) {
            let (s, e) = words.polar_span.unwrap_or((0, block.raw.len()));
            if machine_coordinates {
                self.fail(
                    block,
                    c.event,
                    ErrorKind::Polar("Cannot use polar coordinates with G53"),
                    s,
                    e,
                )?;
            } else {
                self.polar_target(block, c.event, words, &mut target, incremental, (s, e))?;
            }
        }
        // (Borrowed from the interpreter while the block keeps its origin:
        // `c` is lent to the move below.)
        let set_origin = match &c.next.origin {
            Some(o) if !machine_coordinates => Some(*o),
            _ => None,
        };
        let block_origin = if machine_coordinates {
            &Origin::MACHINE
        } else {
            set_origin.as_ref().unwrap_or(&self.origin)
        };
        let end_machine = block_origin.to_machine(&target);
        if let MotionMode::Spline(code) = modal.motion
            && !machine_coordinates
        {
            let now = if nurbs_ran {
                c.next.position
            } else {
                self.position
            };
            let span = d.motion_word.unwrap_or((0, block.raw.len()));
            if code == 52 {
                self.nurbs_point(c, now, &target, nurbs_ran, span)?;
            } else {
                c.next.position = self.spline(c, now, &target, code, span)?;
            }
        } else if end_machine.is_finite() {
            let m = self.motion(c, block_origin, end_machine, machine_coordinates)?;
            c.next.position = m.end;
            c.next.motion = Some(m);
        } else {
            self.fail(block, c.event, ErrorKind::NonFinite, 0, block.raw.len())?;
        }
        Ok(())
    }

    /// M2/M30 (`convert_stop`), and the end of a series of canned-cycle
    /// blocks: a motion other than a cycle ends it (`convert_motion`).
    fn convert_stop(&self, c: &mut Convert<'_>, d: &Decoded) {
        if d.end {
            c.event.program_end = true;
            c.next.ended = true;
        }
        let runs_motion = d.cancel_motion
            || d.motion_word.is_some()
            || (c.words.has_axes() && d.axis_user.is_none());
        if runs_motion && !matches!(c.next.modal.motion, MotionMode::Cycle(_)) {
            c.next.cycle_memory.leave_cycle();
        }
    }

    /// Make a block that succeeded current: its state, its parameters
    /// (LinuxCNC's `set_probe_data` for a probing move), the time, the tools.
    fn commit(
        &mut self,
        block: &Block,
        event: &mut BlockEvent,
        d: &Decoded,
        next: &mut BlockState,
    ) {
        let modal = next.modal;
        let position = next.position;
        let (spindle, cycle_memory) = (next.spindle, next.cycle_memory);
        let (mist, flood, dwell_min, tool) = (next.mist, next.flood, next.dwell_min, next.tool);
        let store = std::mem::take(&mut next.store);
        let nurbs = std::mem::take(&mut next.nurbs);
        let (nurbs_order, motion, ended) = (next.nurbs_order, next.motion.take(), next.ended);
        if modal.frame != self.modal.frame {
            event.frame_switch = Some(modal.frame);
        }
        self.modal = modal;
        // `event.origin` holds the origin the block started with
        // (`interpret_into`): it changes only with the block's own.
        if let Some(origin) = &next.origin {
            self.origin = *origin;
            event.origin = *origin;
        }
        self.spindle = spindle;
        self.cycle_memory = cycle_memory;
        self.nurbs = nurbs;
        self.nurbs_order = nurbs_order;
        self.ended |= ended;
        self.unknown_letters_seen |= d.unknown_letters;
        if d.g53.is_some() {
            event.origin = Origin::MACHINE;
        }
        for (n, v) in store {
            self.params.set(n, v);
        }
        self.params
            .set(numbers::COORD_SYSTEM, modal.coord_system as f64);
        self.position = position;
        if let (Some(m), MotionMode::Probe(_)) = (&motion, modal.motion) {
            // LinuxCNC's `set_probe_data`. The probe is taken to run to its
            // end point without tripping (what rs274's simulation reports):
            // #5061–#5069 hold the end point in program coordinates and
            // units, #5070 is 0.
            let scale = modal.units.scale();
            let p = self.origin.to_program(&m.end);
            let mut values = [0.0; 9];
            for (k, axis) in Axis::ALL.into_iter().enumerate() {
                let v = p.get(axis);
                values[k] = if axis.is_rotary() { v } else { v / scale };
            }
            for (k, v) in values.into_iter().enumerate() {
                self.params.set(numbers::PROBE_POSITION + k, v);
            }
            self.params.set(numbers::PROBE_TRIPPED, 0.0);
        }
        if let Some(m) = motion {
            // (Under `lenient`, a G5.3 and a move may share a block: the
            // move follows the curve's pieces.)
            match &mut event.moves {
                Moves::None => event.moves = Moves::Move(m),
                moves => moves.expanded_mut(Expansion::Spline).push(m),
            }
        }
        for m in event.moves.all() {
            if self.moved {
                self.time_min += m.duration_min;
            }
            self.moved = true;
        }
        if self.moved {
            self.time_min += dwell_min;
        }
        self.mist = mist;
        self.flood = flood;
        if let Some(s) = d.words.s {
            self.rpm = s.abs();
        }
        self.commit_tools(block, event, tool);
        self.update_parameters();
    }

    /// The block's T, M6, M61 and tool length offset words: the tool state
    /// after them (committed by [`Self::commit_tools`] when the block succeeds).
    fn tool_words(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        d: &Decoded,
    ) -> Result<ToolStep, GcodeError> {
        let words = &d.words;
        let (tool_change, m61, offset_code) = (d.tool_change, d.m61, d.offset_code);
        let mut step = ToolStep {
            selected: self.selected_tool,
            current: self.current_tool,
            offset: self.tool_length_offset,
            update: None,
        };
        let span_of = |letter: u8| {
            block
                .word(letter)
                .map_or((0, block.raw.len()), |w| (w.start, w.end))
        };
        // A tool number word: a whole number ≥ 0 that the table knows.
        let tool_number = |this: &Self, event: &mut BlockEvent, value: f64, letter: u8| {
            let at = span_of(letter);
            match to_integer(value).filter(|n| (0..=u32::MAX as i64).contains(n)) {
                None => this
                    .fail(
                        block,
                        event,
                        ErrorKind::ToolNumber(letter as char),
                        at.0,
                        at.1,
                    )
                    .map(|_| None),
                Some(n) if !this.tools.knows(n as u32) => this
                    .fail(
                        block,
                        event,
                        ErrorKind::ToolNotInTable(n as u32),
                        at.0,
                        at.1,
                    )
                    .map(|_| None),
                Some(n) => Ok(Some(n as u32)),
            }
        };
        if let Some(t) = words.t
            && let Some(n) = tool_number(self, event, t, b'T')?
        {
            step.selected = n as f64;
        }
        if tool_change {
            step.current = step.selected;
        }
        if let Some((s, e)) = m61 {
            match words.q {
                Some(q) => {
                    if let Some(n) = tool_number(self, event, q, b'Q')? {
                        step.current = n as f64;
                    }
                }
                None => self.fail(block, event, ErrorKind::ToolNumber('Q'), s, e)?,
            }
        }
        let length_of = |n: u32| -> Option<f64> {
            match n {
                0 => None,
                n => self.tools.get(n).map(|t| t.length_mm),
            }
        };
        let h = match block.word(b'H') {
            Some(w) => tool_number(self, event, w.value, b'H')?,
            None => None,
        };
        let z_word = words.axes[Axis::Z as usize].map(|(v, _)| v);
        match offset_code {
            Some((430, ..)) => {
                // H0 and no H: the loaded tool (LinuxCNC's index 0).
                let n = h.filter(|n| *n != 0).unwrap_or(step.current_number());
                step.offset = length_of(n);
            }
            Some((431, ..)) => {
                if let Some(z) = z_word {
                    step.offset = Some(z);
                }
            }
            Some((432, s, e)) => {
                let given_axes = words.has_axes();
                match (block.word(b'H').is_some(), given_axes) {
                    (true, true) => self.fail(
                        block,
                        event,
                        ErrorKind::ToolOffsetAdd("Can not have both H and axis words"),
                        s,
                        e,
                    )?,
                    (false, false) => self.fail(
                        block,
                        event,
                        ErrorKind::ToolOffsetAdd("No axes specified and H word missing"),
                        s,
                        e,
                    )?,
                    (true, false) => {
                        let n = h.unwrap_or(0);
                        let n = if n == 0 { step.current_number() } else { n };
                        step.offset = step.offset.zip(length_of(n)).map(|(a, b)| a + b);
                    }
                    (false, true) => {
                        step.offset = step.offset.map(|a| a + z_word.unwrap_or(0.0));
                    }
                }
            }
            Some((490, ..)) => step.offset = Some(0.0),
            _ => {}
        }
        Ok(step)
    }

    /// Make the block's tool state current; warn about a tool change with no
    /// table and about cutting moves whose offset is not the tool's length.
    fn commit_tools(&mut self, block: &Block, event: &mut BlockEvent, step: ToolStep) {
        if let Some((n, length, radius)) = step.update {
            self.tools
                .update(n, length, radius, format!("G10 on line {}", block.line));
            self.offset_warned = false;
        }
        if step.current != self.current_tool || step.offset != self.tool_length_offset {
            self.offset_warned = false;
        }
        let loaded = step.current != self.current_tool;
        self.selected_tool = step.selected;
        self.current_tool = step.current;
        self.tool_length_offset = step.offset;
        let tool = self.tool_in_use();
        if loaded
            && !self.tools.is_given()
            && tool.number == 0
            && step.current_number() != 0
            && !self.no_table_warned
        {
            self.no_table_warned = true;
            event.warnings.push(Warning {
                line: block.line,
                column: 1,
                kind: WarningKind::NoToolTable(step.current_number()),
            });
        }
        let cuts = event
            .motions()
            .any(|m| m.kind != MotionKind::Rapid && !m.machine_coordinates);
        if cuts
            && tool.number != 0
            && !self.offset_warned
            && let Some(offset) = self.tool_length_offset
            && (offset - tool.length_mm).abs() > 1e-4
        {
            self.offset_warned = true;
            event.warnings.push(Warning {
                line: block.line,
                column: 1,
                kind: WarningKind::ToolLengthOffsetMismatch {
                    tool: tool.number,
                    length_mm: tool.length_mm,
                    offset_mm: offset,
                },
            });
        }
    }

    /// LinuxCNC's `check_other_codes` (and the motion checks of
    /// `enhance_block`): a D, H, I, J, K, L, P, Q or R word that no code of the
    /// block uses is an error, and so is a motion code other than G0–G3
    /// without axis words.
    fn check_words(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        words: &Words,
        present: u32,
        axis_user: bool,
    ) -> Result<(), GcodeError> {
        let machine_words = block.machine_words();
        let codes = |letter: u8| {
            machine_words
                .iter()
                .filter(move |w| w.letter == letter)
                .filter_map(|w| w.code10())
        };
        // The letters the block holds (`present`, one bit each): most blocks
        // hold no G or M word and none of the words checked below, and skip
        // the scans of their codes.
        let bit = |letter: u8| 1u32 << (letter - b'A');
        let has = |letter: u8| present & bit(letter) != 0;
        // User M codes (M100–M199) take any word; M98/M99 (refused on
        // their own) their P and L.
        if has(b'M') && codes(b'M').any(|m| (1000..=1990).contains(&m) || m == 980 || m == 990) {
            return Ok(());
        }
        let g = |list: &[i32]| codes(b'G').any(|c| list.contains(&c));
        let m = |list: &[i32]| codes(b'M').any(|c| list.contains(&c));
        // The motion the block runs (`motion_to_be`), as code × 10.
        let block_motion = if has(b'G') {
            codes(b'G')
                .rfind(|c| matches!(classify_g(*c), GCode::Motion(_)))
                .or_else(|| g(&[800]).then_some(800))
        } else {
            None
        };
        let ijk = words.ijk.iter().any(Option::is_some);
        let modal = self.modal.motion.code10() as i32;
        let motion = match block_motion {
            Some(c) => Some(c),
            None if axis_user => None,
            None if words.has_axes() || words.polar() => Some(modal),
            None if ijk && matches!(self.modal.motion, MotionMode::ArcCw | MotionMode::ArcCcw) => {
                Some(modal)
            }
            None => None,
        };
        if let Some(c) = block_motion
            && !matches!(c, 0 | 10 | 20 | 30 | 52 | 800)
            && !words.has_axes()
            && !words.polar()
            && !axis_user
        {
            let at = block
                .words
                .iter()
                .find(|w| w.letter == b'G' && w.code10() == Some(c))
                .map_or((0, block.raw.len()), |w| (w.start, w.end));
            self.fail(block, event, ErrorKind::MotionWithoutAxes, at.0, at.1)?;
        }
        let is = |list: &[i32]| motion.is_some_and(|c| list.contains(&c));
        let cycle = |c: i32| (810..=890).contains(&c) || c == 730;
        let arc = is(&[20, 30]);
        if !b"DEHIJKLPQR".iter().any(|l| has(*l)) {
            return Ok(());
        }
        let g10 = g(&[100]);
        let comp = g(&[410, 411, 420, 421]);
        let unused = [
            (b'D', !(comp || g(&[960]))),
            // LinuxCNC: "E word with no G70, G76, M66, M67 or M68 to use it"
            // (X1e400 is X1 and E400).
            (b'E', !m(&[660, 670, 680])),
            // G43.4 and G234: tool-tip control of other controllers (Fanuc).
            (b'H', !g(&[430, 432, 434, 2340])),
            (b'I', !(arc || is(&[870, 50, 51]) || g10)),
            (b'J', !(arc || is(&[870, 50, 51]) || g10)),
            (b'K', !(arc || is(&[870]))),
            (
                b'L',
                !(motion.is_some_and(cycle) || g10 || comp || m(&[660]) || is(&[52])),
            ),
            (
                b'P',
                !(g(&[100, 40, 640])
                    || is(&[820, 860, 880, 890, 20, 30, 740, 840, 50, 52])
                    || m(&[500, 510, 520, 530, 620, 630, 640, 650, 660, 190])),
            ),
            (
                b'Q',
                !(is(&[830, 730, 50]) || m(&[660, 670, 680, 610, 190]) || g10 || g(&[640])),
            ),
            (
                b'R',
                !(arc
                    || motion.is_some_and(cycle)
                    || is(&[740])
                    || g(&[411, 421])
                    || g10
                    || m(&[190])),
            ),
        ];
        for (letter, refused) in unused {
            if let Some(w) = block.word(letter)
                && refused
            {
                self.fail(
                    block,
                    event,
                    ErrorKind::UnusedWord(letter as char),
                    w.start,
                    w.end,
                )?;
            }
        }
        if arc && let Some(p) = words.p {
            let at = block.word(b'P').map_or((0, 0), |w| (w.start, w.end));
            // LinuxCNC's `round_to_int`: (int) nearbyint(P); beyond an int
            // the conversion gives INT_MIN, which is then "not an integer".
            let turns = arc_turns(p).map_or(i32::MIN as f64, |n| n as f64);
            if (turns - p).abs() > 0.001 {
                self.fail(block, event, ErrorKind::ArcTurnsNotInteger, at.0, at.1)?;
            } else if turns < 1.0 {
                self.fail(block, event, ErrorKind::ArcTurnsBelowOne, at.0, at.1)?;
            }
        }
        Ok(())
    }

    /// G10: L2/L20 set a work origin, L1/L10/L11 the tool table (accepted; tool
    /// offsets are not applied).
    fn set_data(&self, c: &mut Convert<'_>, span: Span) -> Result<(), GcodeError> {
        let (block, words, event) = (c.block, c.words, &mut *c.event);
        let BlockState {
            modal,
            origin,
            store,
            tool,
            ..
        } = &mut *c.next;
        let l = words.l.and_then(to_integer);
        let p = words.p.and_then(to_integer);
        match l {
            Some(2) | Some(20) => {
                let Some(p) = p.filter(|p| (0..=9).contains(p)) else {
                    return self.fail(block, event, ErrorKind::G10Pnumber, span.0, span.1);
                };
                let n = if p == 0 { modal.coord_system } else { p as u8 };
                if l == Some(20) && words.r.is_some() {
                    let at = block.word(b'R').map(|w| (w.start, w.end)).unwrap_or(span);
                    return self.fail(block, event, ErrorKind::G10L20Rotation, at.0, at.1);
                }
                let mut o = self.stored_origin(n);
                if l == Some(2) {
                    for axis in Axis::ALL {
                        if let Some((v, _)) = words.axes[axis as usize] {
                            o.set(axis, v);
                        }
                    }
                } else {
                    // L20 (LinuxCNC's `convert_setup`): the current point,
                    // read in system `n` (its origin, its XY rotation and the
                    // G92 offset when applied), reads as the words. X and Y
                    // are rotated together: one of them changes both.
                    let g92 = if self.params.get(numbers::G92_ENABLED) != 0.0 {
                        self.stored_axes(numbers::G92_OFFSET)
                    } else {
                        Axes::default()
                    };
                    let system = Origin {
                        work: o,
                        g92,
                        rotation_deg: self.params.get(numbers::coord(n as usize, 9)),
                        frame: None,
                    };
                    let mut wanted = system.to_program(&self.position);
                    for axis in Axis::ALL {
                        if let Some((v, _)) = words.axes[axis as usize] {
                            wanted.set(axis, v);
                        }
                    }
                    let unshifted = Origin {
                        work: Axes::default(),
                        ..system
                    }
                    .to_machine(&wanted);
                    let xy = words.axes[0].is_some() || words.axes[1].is_some();
                    for axis in Axis::ALL {
                        let given = words.axes[axis as usize].is_some()
                            || (xy && matches!(axis, Axis::X | Axis::Y));
                        if given {
                            o.set(axis, self.position.get(axis) - unshifted.get(axis));
                        }
                    }
                }
                for (k, axis) in Axis::ALL.into_iter().enumerate() {
                    store.push((numbers::coord(n as usize, k), o.get(axis)));
                }
                let mut rotation = self.params.get(numbers::coord(n as usize, 9));
                if let Some(r) = words.r {
                    rotation = r;
                    store.push((numbers::coord(n as usize, 9), r));
                }
                if n == modal.coord_system {
                    let origin = origin.get_or_insert(self.origin);
                    origin.work = o;
                    origin.rotation_deg = rotation;
                }
                Ok(())
            }
            Some(l @ (1 | 10 | 11)) => {
                let Some(n) = p.filter(|p| (1..=u32::MAX as i64).contains(p)) else {
                    return self.fail(block, event, ErrorKind::G10Pnumber, span.0, span.1);
                };
                let n = n as u32;
                if !self.tools.knows(n) {
                    let at = block.word(b'P').map_or(span, |w| (w.start, w.end));
                    return self.fail(block, event, ErrorKind::ToolNotInTable(n), at.0, at.1);
                }
                // LinuxCNC's `convert_setup_tool`: L1 sets the offset, L10
                // and L11 so that the current point (in the current system,
                // or G59.3 without G92) reads as the words with it applied.
                let z = words.axes[Axis::Z as usize].map(|(v, _)| v);
                let length = match l {
                    1 => z,
                    _ => z.map(|z| {
                        let system = if l == 10 {
                            origin
                                .as_ref()
                                .unwrap_or(&self.origin)
                                .to_program(&self.position)
                        } else {
                            Origin {
                                work: self.stored_origin(9),
                                g92: Axes::default(),
                                rotation_deg: self.params.get(numbers::coord(9, 9)),
                                frame: None,
                            }
                            .to_program(&self.position)
                        };
                        system.z + tool.offset.unwrap_or(0.0) - z
                    }),
                };
                let radius = words.r.map(|r| r * modal.units.scale());
                tool.update = Some((n, length, radius));
                Ok(())
            }
            _ => self.fail(block, event, ErrorKind::G10Lnumber, span.0, span.1),
        }
    }

    /// The X Y of a target given in polar words (LinuxCNC's `find_ends`):
    /// about the program origin, `@` the radius and `^` the angle in degrees
    /// (absolute), or added to the current point's (G91); the one not given
    /// is the current point's.
    fn polar_target(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        words: &Words,
        target: &mut Axes,
        incremental: bool,
        span: (usize, usize),
    ) -> Result<(), GcodeError> {
        let (x, y) = (target.x, target.y);
        let at_origin = x == 0.0 && y == 0.0;
        let refuse = |this: &Self, event: &mut BlockEvent, what: &'static str| {
            this.fail(block, event, ErrorKind::Polar(what), span.0, span.1)
        };
        let (mut px, mut py) = (x, y);
        if !incremental {
            match (words.radius, words.theta) {
                (Some(r), Some(t)) => {
                    let t = t.to_radians();
                    (px, py) = (r * t.cos(), r * t.sin());
                }
                (Some(r), None) => {
                    if at_origin {
                        return refuse(
                            self,
                            event,
                            "Must specify angle in polar coordinate if at the origin",
                        );
                    }
                    let t = y.atan2(x);
                    (px, py) = (r * t.cos(), r * t.sin());
                }
                (None, Some(t)) => {
                    let r = y.hypot(x);
                    let t = t.to_radians();
                    (px, py) = (r * t.cos(), r * t.sin());
                }
                (None, None) => {}
            }
        } else {
            if let Some(dr) = words.radius {
                if px == 0.0 && py == 0.0 {
                    return refuse(
                        self,
                        event,
                        "Incremental motion with polar coordinates is indeterminate when at the origin",
                    );
                }
                let t = py.atan2(px);
                let r = py.hypot(px) + dr;
                (px, py) = (r * t.cos(), r * t.sin());
            }
            if let Some(dt) = words.theta {
                if px == 0.0 && py == 0.0 {
                    return refuse(
                        self,
                        event,
                        "G91 motion with polar coordinates is indeterminate when at the origin",
                    );
                }
                let t = py.atan2(px) + dt.to_radians();
                let r = py.hypot(px);
                (px, py) = (r * t.cos(), r * t.sin());
            }
        }
        target.x = px;
        target.y = py;
        Ok(())
    }

    /// A G5 (cubic) or G5.1 (quadratic) spline block from `now` (machine
    /// coordinates) to `target` (program coordinates), LinuxCNC's checks
    /// (`convert_spline`). Returns the position after the block.
    fn spline(
        &self,
        c: &mut Convert<'_>,
        now: Axes,
        target: &Axes,
        code: u16,
        span: Span,
    ) -> Result<Axes, GcodeError> {
        let (block, words) = (c.block, c.words);
        let (modal, origin) = (c.next.modal, *c.next.origin(&self.origin));
        let (modal, origin) = (&modal, &origin);
        let event = &mut *c.event;
        let scale = modal.units.scale();
        let refuse = |this: &Self, event: &mut BlockEvent, what: &str| {
            this.fail(block, event, ErrorKind::Spline(what.into()), span.0, span.1)
        };
        let mut ok = true;
        if !modal.inverse_time && modal.feed == 0.0 {
            self.fail(block, event, ErrorKind::ZeroFeed("spline"), span.0, span.1)?;
            ok = false;
        } else if modal.inverse_time && words.f.is_none() {
            let at = (0, block.raw.len());
            self.fail(
                block,
                event,
                ErrorKind::InverseTimeFeedMissing("spline"),
                at.0,
                at.1,
            )?;
            ok = false;
        }
        let ij = (words.ijk[0], words.ijk[1]);
        if ok && modal.plane != Plane::XY {
            refuse(self, event, "Splines must be in the XY plane")?;
            ok = false;
        } else if ok
            && [Axis::Z, Axis::A, Axis::C]
                .iter()
                .any(|a| words.axes[*a as usize].is_some())
        {
            refuse(self, event, "Splines may not have motion in Z, A, B, or C")?;
            ok = false;
        } else if ok && code == 51 && (ij.0.is_none() || ij.1.is_none()) {
            refuse(self, event, "Must specify both I and J with G5.1")?;
            ok = false;
        } else if ok && code == 50 && ij.0.is_some() != ij.1.is_some() {
            refuse(self, event, "Must specify both I and J, or neither")?;
            ok = false;
        } else if ok && code == 50 && (words.p.is_none() || words.q.is_none()) {
            refuse(self, event, "Must specify both P and Q with G5")?;
            ok = false;
        }
        let start = origin.to_program(&now);
        if !ok {
            // Lenient: a straight move to the end.
            let mut end = start;
            (end.x, end.y) = (target.x, target.y);
            let end = origin.to_machine(&end);
            let mut m = Motion {
                kind: MotionKind::Linear,
                frame: modal.frame,
                machine_coordinates: false,
                start: now,
                end,
                feed: if modal.inverse_time {
                    Feed::InverseTime(modal.feed)
                } else {
                    Feed::PerMinute(modal.feed)
                },
                duration_min: 0.0,
            };
            m.duration_min = duration_min(&m, self.options.rapid_mm_per_min);
            event.moves.expanded_mut(Expansion::Spline).push(m);
            event.spline = Some(SplineStep::Curve {
                code,
                control_points: 0,
            });
            return Ok(end);
        }
        use super::spline::ControlPoint;
        let cp = |x: f64, y: f64| ControlPoint { x, y, w: 1.0 };
        if !c.next.nurbs.is_empty() {
            event.warnings.push(Warning {
                line: block.line,
                column: span.0 + 1,
                kind: WarningKind::Spline(format!(
                    "{} control points of a G5.2 block never ended by G5.3 become part of this {} curve, as LinuxCNC takes them",
                    c.next.nurbs.len(),
                    MotionMode::Spline(code).word()
                )),
            });
        }
        let (x0, y0) = (start.x, start.y);
        let (x3, y3) = (target.x, target.y);
        let order = if code == 51 {
            let (i, j) = (ij.0.unwrap_or(0.0), ij.1.unwrap_or(0.0));
            c.next
                .nurbs
                .extend([cp(x0, y0), cp(x0 + i, y0 + j), cp(x3, y3)]);
            3
        } else {
            // Without I and J: the last G5's −P −Q (LinuxCNC's `cycle_i`,
            // `cycle_j`, which G87 shares), for a tangent continuation.
            let (i, j) = match ij {
                (Some(i), Some(j)) => (i, j),
                _ => (c.next.cycle_memory.ijk[0], c.next.cycle_memory.ijk[1]),
            };
            let (p, q) = (
                words.p.unwrap_or(0.0) * scale,
                words.q.unwrap_or(0.0) * scale,
            );
            c.next.nurbs.extend([
                cp(x0, y0),
                cp(x0 + i, y0 + j),
                cp(x3 + p, y3 + q),
                cp(x3, y3),
            ]);
            c.next.cycle_memory.ijk[0] = -p;
            c.next.cycle_memory.ijk[1] = -q;
            4
        };
        let curve = super::spline::Nurbs {
            points: std::mem::take(&mut c.next.nurbs),
            order,
        };
        self.run_curve(c, now, &curve, code, span)
    }

    /// A G5.2 block (LinuxCNC's `convert_nurbs`): control points for the
    /// NURBS that G5.3 runs; nothing moves. `now` is the current position
    /// (machine coordinates), `target` the block's X Y (program
    /// coordinates); `restart`: a G5.3 of the same block ended the last one.
    fn nurbs_point(
        &self,
        c: &mut Convert<'_>,
        now: Axes,
        target: &Axes,
        restart: bool,
        span: Span,
    ) -> Result<(), GcodeError> {
        let (block, words) = (c.block, c.words);
        let (modal, origin) = (c.next.modal, *c.next.origin(&self.origin));
        let (modal, origin) = (&modal, &origin);
        let event = &mut *c.event;
        use super::spline::ControlPoint;
        let refuse = |this: &Self, event: &mut BlockEvent, what: String| {
            this.fail(block, event, ErrorKind::Spline(what), span.0, span.1)
        };
        // (A G5.3 of the same block ran a curve: that is what the block says.)
        event.spline.get_or_insert(SplineStep::NurbsPoint);
        let (x, y) = (words.axes[0].is_some(), words.axes[1].is_some());
        // LinuxCNC reads a missing P as -1.
        let p = words.p.unwrap_or(-1.0);
        if x != y {
            return refuse(
                self,
                event,
                "You must specify both X and Y coordinates for Control Points".into(),
            );
        }
        if !x && p > 0.0 && !c.next.nurbs.is_empty() {
            return refuse(
                self,
                event,
                "Can specify P without X and Y only for the first control point".into(),
            );
        }
        if p <= 0.0 && !c.next.nurbs.is_empty() {
            return refuse(
                self,
                event,
                "Must specify positive weight P for every Control Point".into(),
            );
        }
        if !modal.inverse_time && modal.feed == 0.0 {
            return refuse(self, event, "Cannot make a NURBS with 0 feedrate".into());
        }
        let l = match words.l {
            None => None,
            Some(l) => match to_integer(l) {
                Some(n) if n >= 0 => Some(n as usize),
                Some(_) => return refuse(self, event, "Negative L word used".into()),
                None => return refuse(self, event, "Non-integer value for integer".into()),
            },
        };
        if self.modal.motion != MotionMode::Spline(52) || restart {
            c.next.nurbs.clear();
        }
        if c.next.nurbs.is_empty() {
            let start = origin.to_program(&now);
            c.next.nurbs.push(ControlPoint {
                x: start.x,
                y: start.y,
                w: if !x && p > 0.0 { p } else { 1.0 },
            });
            c.next.nurbs_order = 3;
        }
        if let Some(l) = l.filter(|l| *l > 3) {
            c.next.nurbs_order = l;
        }
        if x {
            c.next.nurbs.push(ControlPoint {
                x: target.x,
                y: target.y,
                w: p,
            });
        }
        if [Axis::Z, Axis::A, Axis::C]
            .iter()
            .any(|a| words.axes[*a as usize].is_some())
        {
            event.warnings.push(Warning {
                line: block.line,
                column: span.0 + 1,
                kind: WarningKind::Spline(
                    "Z, A and C words of a G5.2 block do not move (LinuxCNC takes X Y and P only)"
                        .into(),
                ),
            });
        }
        Ok(())
    }

    /// The straight pieces of `curve` (program coordinates) from `now`
    /// (machine coordinates; Z, A and C stay) into the block's [`Moves::Spline`].
    /// Returns the position after the curve.
    fn run_curve(
        &self,
        c: &mut Convert<'_>,
        now: Axes,
        curve: &super::spline::Nurbs,
        code: u16,
        span: Span,
    ) -> Result<Axes, GcodeError> {
        let block = c.block;
        let (modal, origin) = (c.next.modal, *c.next.origin(&self.origin));
        let (modal, origin) = (&modal, &origin);
        let event = &mut *c.event;
        let pieces =
            match super::spline::chords(curve, self.options.spline_tolerance_mm, MAX_SPLINE_PIECES)
            {
                Ok(p) => p,
                Err(e) => {
                    self.fail(
                        block,
                        event,
                        ErrorKind::Spline(e.to_string()),
                        span.0,
                        span.1,
                    )?;
                    return Ok(now);
                }
            };
        let start = origin.to_program(&now);
        let mut from = start;
        let mut ends = Vec::with_capacity(pieces.len());
        let mut total = 0.0;
        for p in &pieces {
            let mut to = start;
            (to.x, to.y) = (p[0], p[1]);
            total += from.xyz_distance(&to);
            ends.push(to);
            from = to;
        }
        let mut at = now;
        let mut from = start;
        for to in ends {
            let end = origin.to_machine(&to);
            let fraction = if total > 0.0 {
                from.xyz_distance(&to) / total
            } else {
                1.0
            };
            let mut m = Motion {
                kind: MotionKind::Linear,
                frame: modal.frame,
                machine_coordinates: false,
                start: at,
                end,
                feed: if modal.inverse_time {
                    // The curve takes 1/F: each piece its share.
                    Feed::InverseTime(modal.feed / fraction.max(1e-12))
                } else {
                    Feed::PerMinute(modal.feed)
                },
                duration_min: 0.0,
            };
            m.duration_min = duration_min(&m, self.options.rapid_mm_per_min);
            event.moves.expanded_mut(Expansion::Spline).push(m);
            at = end;
            from = to;
        }
        event.spline = Some(SplineStep::Curve {
            code,
            control_points: curve.points.len(),
        });
        Ok(at)
    }

    /// A canned-cycle block: its moves, expanded by [`super::cycles`], in
    /// machine coordinates. Returns the position after the block.
    fn cycle(&self, c: &mut Convert<'_>, code: u16) -> Result<Axes, GcodeError> {
        let (block, words) = (c.block, c.words);
        let (modal, origin) = (c.next.modal, *c.next.origin(&self.origin));
        let (modal, origin) = (&modal, &origin);
        let event = &mut *c.event;
        let Some(cycle) = CycleCode::from_code10(code as i32) else {
            self.fail(
                block,
                event,
                ErrorKind::UnsupportedGCode(code_text('G', code as i32)),
                0,
                block.raw.len(),
            )?;
            return Ok(self.position);
        };
        let scale = modal.units.scale();
        let program_now = origin.to_program(&self.position);
        let input = CycleBlock {
            code: cycle,
            plane: modal.plane,
            retract: if modal.retract_r_plane {
                RetractMode::RPlane
            } else {
                RetractMode::OldZ
            },
            incremental: modal.distance == Distance::Incremental,
            position: [program_now.x, program_now.y, program_now.z],
            xyz: [
                words.axes[0].map(|a| a.0),
                words.axes[1].map(|a| a.0),
                words.axes[2].map(|a| a.0),
            ],
            r: words.r.map(|r| r * scale),
            q: words.q.map(|q| q * scale),
            p: words.p,
            l: words.l,
            ijk: words.ijk,
            polar: [words.radius, words.theta],
            rotary_words: [3, 4, 5].map(|i| words.axes[i].is_some()),
            uvw_words: [6, 7, 8].map(|i| words.axes[i].is_some()),
            feed_rate: if modal.inverse_time { 0.0 } else { modal.feed },
            inverse_time: modal.inverse_time,
            cutter_comp: modal.cutter_comp != CutterComp::Off,
            spindle: c.next.spindle,
            inch: modal.units == Units::Inch,
        };
        let mut steps = Vec::new();
        if let Err(e) = expand(&input, &mut c.next.cycle_memory, &mut steps) {
            let at = e
                .word()
                .and_then(|c| block.words.iter().find(|w| w.letter == c as u8))
                .map(|w| (w.start, w.end))
                .unwrap_or((0, block.raw.len()));
            self.fail(block, event, ErrorKind::Cycle(e.to_string()), at.0, at.1)?;
            return Ok(self.position);
        }
        if steps.is_empty() {
            return Ok(self.position);
        }
        let (moves, cycle_steps) = event.moves.cycle_mut();
        *cycle_steps = steps;
        let mut at = self.position;
        for step in cycle_steps.iter() {
            let (xyz, kind) = match *step {
                CycleStep::Rapid(p) => (p, Some(MotionKind::Rapid)),
                CycleStep::Feed(p) => (p, Some(MotionKind::Linear)),
                CycleStep::AssumePosition(p) => (p, None),
                CycleStep::Dwell { seconds } => {
                    c.next.dwell_min += seconds.max(0.0) / 60.0;
                    continue;
                }
                CycleStep::SpindleStop => {
                    c.next.spindle = SpindleDirection::Stopped;
                    continue;
                }
                CycleStep::SpindleStart { clockwise } => {
                    c.next.spindle = if clockwise {
                        SpindleDirection::Clockwise
                    } else {
                        SpindleDirection::CounterClockwise
                    };
                    continue;
                }
                CycleStep::SpindleOrient { .. }
                | CycleStep::ProgramStop
                | CycleStep::OverridesDisabled
                | CycleStep::OverridesRestored => continue,
            };
            let mut program = origin.to_program(&at);
            program.x = xyz[0];
            program.y = xyz[1];
            program.z = xyz[2];
            let end = origin.to_machine(&program);
            if let Some(kind) = kind {
                let rapid = kind == MotionKind::Rapid;
                let mut m = Motion {
                    kind,
                    frame: modal.frame,
                    machine_coordinates: false,
                    start: at,
                    end,
                    feed: if rapid {
                        Feed::Rapid
                    } else {
                        Feed::PerMinute(modal.feed)
                    },
                    duration_min: 0.0,
                };
                m.duration_min = duration_min(&m, self.options.rapid_mm_per_min);
                moves.push(m);
            }
            at = end;
        }
        Ok(at)
    }

    /// A straight move, arc or probing move from the current position to
    /// `end` (machine coordinates); `origin` is the block's (identity for G53).
    fn motion(
        &self,
        c: &mut Convert<'_>,
        origin: &Origin,
        end: Axes,
        machine_coordinates: bool,
    ) -> Result<Motion, GcodeError> {
        let (block, words) = (c.block, c.words);
        let modal = c.next.modal;
        let modal = &modal;
        let event = &mut *c.event;
        let start = self.position;
        let feed_span = words.f_span.unwrap_or((0, block.raw.len()));
        let mut kind = match modal.motion {
            MotionMode::Rapid => MotionKind::Rapid,
            MotionMode::Linear
            | MotionMode::None
            | MotionMode::Probe(_)
            | MotionMode::Cycle(_)
            | MotionMode::Spline(_) => MotionKind::Linear,
            MotionMode::ArcCw | MotionMode::ArcCcw => {
                let clockwise = modal.motion == MotionMode::ArcCw;
                if origin.rotation_deg != 0.0 && modal.plane != Plane::XY {
                    self.fail(block, event, ErrorKind::RotatedArcPlane, 0, block.raw.len())?;
                }
                let s = origin.to_program(&start);
                let e = origin.to_program(&end);
                match self.arc_centre(block, event, modal, words, (&s, &e), clockwise)? {
                    Some(centre) => {
                        // P full circles (LinuxCNC runs every one of them).
                        let turns = match words.p.and_then(arc_turns) {
                            Some(n) if n >= 1 => (n - 1) as u32,
                            _ => 0,
                        };
                        MotionKind::Arc {
                            clockwise,
                            centre: origin.xyz_to_machine(centre),
                            plane: modal.plane,
                            turns,
                        }
                    }
                    None => MotionKind::Linear,
                }
            }
        };
        if let MotionKind::Arc { centre, .. } = kind
            && !centre.iter().all(|v| v.is_finite())
        {
            kind = MotionKind::Linear;
        }
        let feeding = modal.motion != MotionMode::Rapid;
        let arc = matches!(modal.motion, MotionMode::ArcCw | MotionMode::ArcCcw);
        if let MotionMode::Probe(_) = modal.motion {
            if modal.inverse_time {
                self.fail(
                    block,
                    event,
                    ErrorKind::ProbeInverseTime,
                    feed_span.0,
                    feed_span.1,
                )?;
            } else if modal.feed <= 0.0 {
                self.fail(
                    block,
                    event,
                    ErrorKind::ZeroFeed("probe"),
                    0,
                    block.raw.len(),
                )?;
            }
            // G38.3 and G38.5 (no error when the probe does not trip) may
            // start at their end point (LinuxCNC's `convert_probe`).
            if start == end && matches!(modal.motion, MotionMode::Probe(382 | 384)) {
                self.fail(block, event, ErrorKind::ProbeTooClose, 0, block.raw.len())?;
            }
        } else if feeding && modal.inverse_time && words.f.is_none() {
            let what = if arc { "arc" } else { "G1" };
            self.fail(
                block,
                event,
                ErrorKind::InverseTimeFeedMissing(what),
                0,
                block.raw.len(),
            )?;
        } else if feeding && !modal.inverse_time && modal.feed <= 0.0 {
            let what = if arc { "arc" } else { "G1" };
            self.fail(block, event, ErrorKind::ZeroFeed(what), 0, block.raw.len())?;
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

    /// Centre of an arc in program coordinates (mm), LinuxCNC's checks and
    /// tolerances (`arc_data_ijk`, `arc_data_r`); `None` when it falls back to a
    /// straight move (lenient).
    fn arc_centre(
        &self,
        block: &Block,
        event: &mut BlockEvent,
        modal: &ModalState,
        words: &Words,
        (start, end): (&Axes, &Axes),
        clockwise: bool,
    ) -> Result<Option<[f64; 3]>, GcodeError> {
        let word_span = |letter: u8| {
            block
                .word(letter)
                .map(|w| (w.start, w.end))
                .unwrap_or((0, block.raw.len()))
        };
        let scale = modal.units.scale();
        let inch = modal.units == Units::Inch;
        // LinuxCNC: RADIUS_TOLERANCE_INCH 0.00005 in; CENTER_ARC_RADIUS_TOLERANCE
        // 2·0.001·√2 in / 2·0.01·√2 mm; SPIRAL_RELATIVE_TOLERANCE 0.001.
        let radius_tolerance = 0.00005 * 25.4;
        let spiral_abs = if inch {
            2.0 * 0.001 * std::f64::consts::SQRT_2 * 25.4
        } else {
            2.0 * 0.01 * std::f64::consts::SQRT_2
        };
        let s = to_plane(modal.plane, start.xyz());
        let e = to_plane(modal.plane, end.xyz());
        // LinuxCNC's `convert_arc`: R or centre words, not both; no centre
        // word along the plane's normal; both centre words under G90.1.
        if words.r.is_some() && words.ijk.iter().any(Option::is_some) {
            let (a, b) = word_span(b'R');
            self.fail(block, event, ErrorKind::ArcMixedFormat, a, b)?;
            return Ok(None);
        }
        let (normal, plane_name, in_plane) = match modal.plane {
            Plane::XY => (2, "XY", [0, 1]),
            Plane::ZX => (1, "XZ", [2, 0]),
            Plane::YZ => (0, "YZ", [1, 2]),
        };
        const IJK: [u8; 3] = [b'I', b'J', b'K'];
        if words.ijk[normal].is_some() {
            let (a, b) = word_span(IJK[normal]);
            let kind = ErrorKind::ArcCentreWordOffPlane(IJK[normal] as char, plane_name);
            self.fail(block, event, kind, a, b)?;
            return Ok(None);
        }
        if modal.arc_distance == Distance::Absolute
            && words.ijk[in_plane[0]].is_some() != words.ijk[in_plane[1]].is_some()
        {
            let missing = in_plane[usize::from(words.ijk[in_plane[0]].is_some())];
            let kind = ErrorKind::ArcAbsoluteCentreMissing(IJK[missing] as char);
            self.fail(block, event, kind, 0, block.raw.len())?;
            return Ok(None);
        }
        if let Some(r_words) = words.r {
            let r = r_words * scale;
            let (dx, dy) = (e[0] - s[0], e[1] - s[1]);
            let d = dx.hypot(dy);
            let (a, b) = word_span(b'R');
            if d == 0.0 {
                self.fail(block, event, ErrorKind::ArcSamePoint, a, b)?;
                return Ok(None);
            }
            let radius = r.abs();
            if d / 2.0 - radius > radius_tolerance {
                self.fail(block, event, ErrorKind::ArcUnreachable(r_words), a, b)?;
                return Ok(None);
            }
            let half = (d / 2.0).min(radius);
            let h = (radius * radius - half * half).max(0.0).sqrt();
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
        let cp = to_plane(modal.plane, c);
        let r1 = (s[0] - cp[0]).hypot(s[1] - cp[1]);
        let r2 = (e[0] - cp[0]).hypot(e[1] - cp[1]);
        if r1 < radius_tolerance || r2 < radius_tolerance {
            self.fail(block, event, ErrorKind::ArcZeroRadius, 0, block.raw.len())?;
            return Ok(None);
        }
        let abs_err = (r1 - r2).abs();
        let rel_err = abs_err / r1.max(r2);
        if abs_err > spiral_abs * 100.0 || (rel_err > 0.001 && abs_err > spiral_abs) {
            self.fail(
                block,
                event,
                ErrorKind::ArcRadiusMismatch { r1, r2 },
                0,
                block.raw.len(),
            )?;
            return Ok(None);
        }
        if abs_err > 0.005 && abs_err > 1e-3 * r1.max(r2) {
            event.warnings.push(Warning {
                line: block.line,
                column: 1,
                kind: WarningKind::ArcRadiusMismatch(abs_err),
            });
        }
        Ok(Some(c))
    }

    /// Machining time so far, min.
    pub fn time_min(&self) -> f64 {
        self.time_min
    }
}

/// An arc's P as LinuxCNC's `round_to_int` reads it: the nearest integer
/// (ties to even), `None` when it does not fit an `int`.
fn arc_turns(p: f64) -> Option<i32> {
    let n = p.round_ties_even();
    (n >= i32::MIN as f64 && n <= i32::MAX as f64).then_some(n as i32)
}

/// Duration of a move by the effects.md rules, minutes, from its programmed
/// coordinates (see [`duration_from_lengths`]).
pub fn duration_min(m: &Motion, rapid_mm_per_min: f64) -> f64 {
    let rotary = m.start.rotary_distance(&m.end);
    // LinuxCNC's feed rule: the XYZ length, else the UVW length, else the rotary.
    let linear = match m.xyz_length() {
        0.0 => m.start.uvw_distance(&m.end),
        l => l,
    };
    duration_from_lengths(&m.feed, linear, rotary, rapid_mm_per_min)
}

/// Duration (minutes) of a move with XYZ path length `xyz_mm` and rotary length
/// `rotary_deg` = √(Δa² + Δb² + Δc²): the XYZ length over F, the rotary length over
/// F when only the rotary axes move, the rapid rate for G0, 1/F under G93; 0 when the feed gives
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
) -> Result<Vec<(crate::gcode::syntax::block::Block, BlockEvent)>, GcodeError> {
    let mut reader = crate::gcode::syntax::reader::BlockReader::new(
        text,
        crate::gcode::syntax::reader::ReadOptions {
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
