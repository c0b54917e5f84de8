//! Modal state and the meaning of G and M codes (gcode.md "modal state").
//!
//! Invariant: [`ModalState`] is small and `Copy`; it is the state *after* a
//! block, reported with every block event so that the rewriter knows the units,
//! distance mode, feed mode and frame the block's words were written in.
use serde::{Deserialize, Serialize};

use super::motion::{Frame, Plane};

/// Motion mode (modal group 1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum MotionMode {
    /// None yet, or cancelled by G80.
    #[default]
    None,
    /// G0.
    Rapid,
    /// G1.
    Linear,
    /// G2.
    ArcCw,
    /// G3.
    ArcCcw,
    /// G38.2–G38.5 (the code × 10: 382 … 385): a straight probing move.
    Probe(u16),
    /// A canned cycle, G73 or G81–G89 (the code × 10: 730, 810 … 890).
    Cycle(u16),
    /// A spline (the code × 10): G5 cubic (50), G5.1 quadratic (51), G5.2
    /// NURBS control points (52, executed by G5.3).
    Spline(u16),
}

impl MotionMode {
    /// The G word that selects the mode (`"G1"`), empty for `None`.
    pub fn word(self) -> &'static str {
        match self {
            MotionMode::None => "",
            MotionMode::Rapid => "G0",
            MotionMode::Linear => "G1",
            MotionMode::ArcCw => "G2",
            MotionMode::ArcCcw => "G3",
            MotionMode::Probe(382) => "G38.2",
            MotionMode::Probe(383) => "G38.3",
            MotionMode::Probe(384) => "G38.4",
            MotionMode::Probe(_) => "G38.5",
            MotionMode::Cycle(730) => "G73",
            MotionMode::Cycle(740) => "G74",
            MotionMode::Cycle(810) => "G81",
            MotionMode::Cycle(820) => "G82",
            MotionMode::Cycle(830) => "G83",
            MotionMode::Cycle(840) => "G84",
            MotionMode::Cycle(850) => "G85",
            MotionMode::Cycle(860) => "G86",
            MotionMode::Cycle(870) => "G87",
            MotionMode::Cycle(880) => "G88",
            MotionMode::Cycle(_) => "G89",
            MotionMode::Spline(50) => "G5",
            MotionMode::Spline(51) => "G5.1",
            MotionMode::Spline(_) => "G5.2",
        }
    }

    /// LinuxCNC's `_motion_mode` value (code × 10; 800 when cancelled).
    pub fn code10(self) -> f64 {
        match self {
            MotionMode::None => 800.0,
            MotionMode::Rapid => 0.0,
            MotionMode::Linear => 10.0,
            MotionMode::ArcCw => 20.0,
            MotionMode::ArcCcw => 30.0,
            MotionMode::Probe(c) | MotionMode::Cycle(c) | MotionMode::Spline(c) => c as f64,
        }
    }
}

/// Length units of the program words (G20/G21). Reported values are always mm.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Units {
    /// G21: millimetres.
    #[default]
    Mm,
    /// G20: inches (25.4 mm).
    Inch,
}

impl Units {
    /// mm per program unit.
    pub fn scale(self) -> f64 {
        match self {
            Units::Mm => 1.0,
            Units::Inch => 25.4,
        }
    }
}

/// Absolute (G90, G90.1) or incremental (G91, G91.1).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Distance {
    /// G90 (G90.1 for I J K): words are positions.
    #[default]
    Absolute,
    /// G91 (G91.1 for I J K): words are offsets from the current point.
    Incremental,
}

/// Cutter radius compensation (G40/G41/G42).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum CutterComp {
    /// G40: off.
    #[default]
    Off,
    /// G41: the tool left of the path.
    Left,
    /// G42: the tool right of the path.
    Right,
}

/// The modal state after a block.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModalState {
    /// The active motion mode (G0, G1, G2, G3, G38.x, a canned cycle, a
    /// spline), or none.
    pub motion: MotionMode,
    /// The arc plane (G17/G18/G19).
    pub plane: Plane,
    /// The units of the program words (G20/G21).
    pub units: Units,
    /// G90/G91 for axis words.
    pub distance: Distance,
    /// G90.1/G91.1 for I J K (incremental by default, as LinuxCNC and Fanuc).
    pub arc_distance: Distance,
    /// G93 active.
    pub inverse_time: bool,
    /// Cutter radius compensation (G40/G41/G42).
    pub cutter_comp: CutterComp,
    /// G43 (or G43.4/G234) tool length offset active.
    pub tool_length: bool,
    /// The frame of the `X Y Z` words: joint (axis commands) or part
    /// (tool tip, M428/G43.4/G234/TRAORI).
    pub frame: Frame,
    /// Last programmed F: mm/min under G94 (converted from in/min), 1/min under G93.
    pub feed: f64,
    /// Active work coordinate system: 1 (G54) … 9 (G59.3).
    pub coord_system: u8,
    /// G99 (canned cycles retract to R, LinuxCNC's initial mode) rather than G98 (to the old Z).
    pub retract_r_plane: bool,
}

impl ModalState {
    /// The modal state at the program's start (no motion mode, G17 G21 G90 G91.1
    /// G94 G40 G49 G54 G99, F0), with `frame` as the starting frame.
    pub fn new(frame: Frame) -> Self {
        ModalState {
            motion: MotionMode::None,
            plane: Plane::XY,
            units: Units::Mm,
            distance: Distance::Absolute,
            arc_distance: Distance::Incremental,
            inverse_time: false,
            cutter_comp: CutterComp::Off,
            tool_length: false,
            frame,
            feed: 0.0,
            coord_system: 1,
            retract_r_plane: true,
        }
    }
}

/// What a G code does, by its number times ten (`G43.4` → 434).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GCode {
    Motion(MotionMode),
    Plane(Plane),
    Units(Units),
    Distance(Distance),
    ArcDistance(Distance),
    /// G93 (`true`) / G94 (`false`).
    FeedMode(bool),
    CutterComp(CutterComp),
    /// G43 (tool length on, frame unchanged).
    ToolLength,
    /// G43.1: tool length offset from the block's axis words (which do not move).
    ToolLengthDynamic,
    /// G43.2: add a tool's offset (H) or the axis words to the current one.
    ToolLengthAdd,
    /// G43.4 / G234: tool length on and tool-tip (part-frame) programming.
    ToolTip,
    /// G49: tool length off, tool-tip programming off.
    ToolLengthOff,
    /// G53: machine coordinates for this block.
    MachineCoordinates,
    /// G54–G59, G59.1–G59.3: select work coordinate system 1 … 9.
    CoordSystem(u8),
    /// G28 / G30: go to a stored position (through the words' intermediate point).
    Home(u8),
    /// G28.1 / G30.1: store the current position.
    StoreHome(u8),
    /// G10 (L1, L2, L10, L11, L20).
    SetData,
    /// G92, G92.1, G92.2, G92.3 (the code × 10).
    AxisOffset(u16),
    /// G98 (`false`) / G99 (`true`).
    RetractMode(bool),
    /// G4 dwell.
    Dwell,
    /// G5.3: the end of a G5.2 NURBS block, which then runs.
    NurbsEnd,
    /// G80: cancels the motion mode (canned cycles).
    CancelMotion,
    /// Harmless codes passed through and counted: G61/G61.1/G64 path control,
    /// G96/G97, G7/G8, G15, G50, G50.1, G69.
    PassThrough,
    /// Anything else, assumed to change the geometry (G33, G76, G70–G72,
    /// G41.1/G42.1, G52, G68, G51, G16, …).
    Unsupported,
}

/// LinuxCNC's modal group of a G code (group 0 holds the non-modal codes).
pub fn g_group(code: GCode) -> Option<u8> {
    Some(match code {
        GCode::Motion(_) | GCode::CancelMotion => 1,
        GCode::Plane(_) => 2,
        GCode::Distance(_) => 3,
        GCode::ArcDistance(_) => 4,
        GCode::FeedMode(_) => 5,
        GCode::Units(_) => 6,
        GCode::CutterComp(_) => 7,
        GCode::ToolLength
        | GCode::ToolLengthDynamic
        | GCode::ToolLengthAdd
        | GCode::ToolTip
        | GCode::ToolLengthOff => 8,
        GCode::RetractMode(_) => 10,
        GCode::CoordSystem(_) => 12,
        GCode::MachineCoordinates
        | GCode::Home(_)
        | GCode::StoreHome(_)
        | GCode::SetData
        | GCode::AxisOffset(_)
        | GCode::Dwell
        | GCode::NurbsEnd => 0,
        GCode::PassThrough | GCode::Unsupported => return None,
    })
}

/// Classify a G code by its number times ten.
pub fn classify_g(code10: i32) -> GCode {
    match code10 {
        0 => GCode::Motion(MotionMode::Rapid),
        10 => GCode::Motion(MotionMode::Linear),
        20 => GCode::Motion(MotionMode::ArcCw),
        30 => GCode::Motion(MotionMode::ArcCcw),
        382..=385 => GCode::Motion(MotionMode::Probe(code10 as u16)),
        730 | 740 | 810 | 820 | 830 | 840 | 850 | 860 | 870 | 880 | 890 => {
            GCode::Motion(MotionMode::Cycle(code10 as u16))
        }
        50..=52 => GCode::Motion(MotionMode::Spline(code10 as u16)),
        53 => GCode::NurbsEnd,
        40 => GCode::Dwell,
        100 => GCode::SetData,
        170 => GCode::Plane(Plane::XY),
        180 => GCode::Plane(Plane::ZX),
        190 => GCode::Plane(Plane::YZ),
        200 => GCode::Units(Units::Inch),
        210 => GCode::Units(Units::Mm),
        280 => GCode::Home(28),
        281 => GCode::StoreHome(28),
        300 => GCode::Home(30),
        301 => GCode::StoreHome(30),
        900 => GCode::Distance(Distance::Absolute),
        910 => GCode::Distance(Distance::Incremental),
        901 => GCode::ArcDistance(Distance::Absolute),
        911 => GCode::ArcDistance(Distance::Incremental),
        520 | 920..=923 => GCode::AxisOffset(code10 as u16),
        930 => GCode::FeedMode(true),
        940 => GCode::FeedMode(false),
        400 => GCode::CutterComp(CutterComp::Off),
        410 => GCode::CutterComp(CutterComp::Left),
        420 => GCode::CutterComp(CutterComp::Right),
        430 => GCode::ToolLength,
        431 => GCode::ToolLengthDynamic,
        432 => GCode::ToolLengthAdd,
        434 | 2340 => GCode::ToolTip,
        490 => GCode::ToolLengthOff,
        530 => GCode::MachineCoordinates,
        540 => GCode::CoordSystem(1),
        550 => GCode::CoordSystem(2),
        560 => GCode::CoordSystem(3),
        570 => GCode::CoordSystem(4),
        580 => GCode::CoordSystem(5),
        590 => GCode::CoordSystem(6),
        591 => GCode::CoordSystem(7),
        592 => GCode::CoordSystem(8),
        593 => GCode::CoordSystem(9),
        800 => GCode::CancelMotion,
        980 => GCode::RetractMode(false),
        990 => GCode::RetractMode(true),
        // Not G7 (lathe diameter mode: X words would be diameters).
        610 | 611 | 640 | 960 | 970 | 80 | 150 | 500 | 501 | 690 => GCode::PassThrough,
        _ => GCode::Unsupported,
    }
}

/// What an M code does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MCode {
    /// M2 / M30.
    End,
    /// M98 / M99 (subroutine call / return): not supported.
    Subroutine,
    /// M428: tool-tip (part-frame) programming on (LinuxCNC).
    ToolTipOn,
    /// M429: off.
    ToolTipOff,
    /// Anything else (spindle, coolant, tool change, stops): passed through.
    PassThrough,
}

/// LinuxCNC's modal group of an M code (4 stopping, 6 tool change, 7
/// spindle, 8 coolant, 9 overrides, 10 user).
pub fn m_group(code10: i32) -> Option<u8> {
    Some(match code10 {
        0 | 10 | 20 | 300 | 600 => 4,
        60 | 610 => 6,
        30 | 40 | 50 => 7,
        70 | 80 | 90 => 8,
        480 | 490 | 500 | 510 | 520 | 530 => 9,
        1000..=1990 => 10,
        _ => return None,
    })
}

/// Classify an M code by its number times ten.
pub fn classify_m(code10: i32) -> MCode {
    match code10 {
        20 | 300 => MCode::End,
        980 | 990 => MCode::Subroutine,
        4280 => MCode::ToolTipOn,
        4290 => MCode::ToolTipOff,
        _ => MCode::PassThrough,
    }
}

/// The letters the interpreter understands; others are kept and warned about.
pub fn is_known_letter(letter: u8) -> bool {
    matches!(
        letter,
        b'G' | b'M'
            | b'X'
            | b'Y'
            | b'Z'
            | b'A'
            | b'B'
            | b'C'
            | b'U'
            | b'V'
            | b'W'
            | b'F'
            | b'S'
            | b'T'
            | b'H'
            | b'D'
            | b'I'
            | b'J'
            | b'K'
            | b'R'
            | b'P'
            | b'Q'
            | b'L'
            | b'E'
            | b'N'
            | b'O'
            | b'@'
            | b'^'
    )
}

/// `G43.4`-style text of a code number times ten.
pub fn code_text(letter: char, code10: i32) -> String {
    if code10 % 10 == 0 {
        format!("{letter}{}", code10 / 10)
    } else {
        format!("{letter}{}.{}", code10 / 10, (code10 % 10).abs())
    }
}
