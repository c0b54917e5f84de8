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
        }
    }
}

/// Length units of the program words (G20/G21). Reported values are always mm.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Units {
    #[default]
    Mm,
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
    #[default]
    Absolute,
    Incremental,
}

/// Cutter radius compensation (G40/G41/G42).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum CutterComp {
    #[default]
    Off,
    Left,
    Right,
}

/// The modal state after a block.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ModalState {
    pub motion: MotionMode,
    pub plane: Plane,
    pub units: Units,
    /// G90/G91 for axis words.
    pub distance: Distance,
    /// G90.1/G91.1 for I J K (incremental by default, as LinuxCNC and Fanuc).
    pub arc_distance: Distance,
    /// G93 active.
    pub inverse_time: bool,
    pub cutter_comp: CutterComp,
    /// G43 (or G43.4/G234) tool length offset active.
    pub tool_length: bool,
    pub frame: Frame,
    /// Last programmed F: mm/min under G94 (converted from in/min), 1/min under G93.
    pub feed: f64,
}

impl ModalState {
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
    /// G43.4 / G234: tool length on and tool-tip (part-frame) programming.
    ToolTip,
    /// G49: tool length off, tool-tip programming off.
    ToolLengthOff,
    /// G53: machine coordinates for this block.
    MachineCoordinates,
    /// G54–G59, G59.1–G59.3, G54.1: work offsets, passed through (offsets unknown).
    WorkOffset,
    /// G28/G30: return to a reference point (reported, not interpolated).
    Home,
    /// G80: cancels the motion mode (canned cycles).
    CancelMotion,
    /// Harmless codes passed through and counted: G4 dwell, G61/G61.1/G64 path
    /// control, G98/G99, G15, G50, G50.1, G69, G43.1 (dynamic TLO), G90/G91-like
    /// cancels.
    PassThrough,
    /// Anything else: assumed to change the geometry (G10, G92, G52, G68, G51,
    /// canned cycles G81–G89, G33, G38.x, G5.x, G7/G8, G16, ...).
    Unsupported,
}

/// Classify a G code by its number times ten.
pub fn classify_g(code10: i32) -> GCode {
    match code10 {
        0 => GCode::Motion(MotionMode::Rapid),
        10 => GCode::Motion(MotionMode::Linear),
        20 => GCode::Motion(MotionMode::ArcCw),
        30 => GCode::Motion(MotionMode::ArcCcw),
        170 => GCode::Plane(Plane::XY),
        180 => GCode::Plane(Plane::ZX),
        190 => GCode::Plane(Plane::YZ),
        200 => GCode::Units(Units::Inch),
        210 => GCode::Units(Units::Mm),
        900 => GCode::Distance(Distance::Absolute),
        910 => GCode::Distance(Distance::Incremental),
        901 => GCode::ArcDistance(Distance::Absolute),
        911 => GCode::ArcDistance(Distance::Incremental),
        930 => GCode::FeedMode(true),
        940 => GCode::FeedMode(false),
        400 => GCode::CutterComp(CutterComp::Off),
        410 | 411 => GCode::CutterComp(CutterComp::Left),
        420 | 421 => GCode::CutterComp(CutterComp::Right),
        430 => GCode::ToolLength,
        434 | 2340 => GCode::ToolTip,
        490 => GCode::ToolLengthOff,
        530 => GCode::MachineCoordinates,
        540 | 541 | 550 | 560 | 570 | 580 | 590 | 591 | 592 | 593 => GCode::WorkOffset,
        280 | 300 => GCode::Home,
        800 => GCode::CancelMotion,
        40 | 431 | 610 | 611 | 640 | 980 | 990 | 150 | 500 | 501 | 690 => GCode::PassThrough,
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
            | b'C'
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
