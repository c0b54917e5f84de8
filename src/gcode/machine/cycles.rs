//! Canned cycles (G73, G74, G81–G89) expanded into elementary moves exactly as
//! LinuxCNC 2.9's interpreter expands them (`interp_cycles.cc`: `convert_cycle`,
//! `convert_cycle_xy`/`_yz`/`_zx`, the `CYCLE_MACRO` of `interp_internal.hh`,
//! `convert_cycle_g73` … `convert_cycle_g89`, `cycle_feed`, `cycle_traverse`;
//! the A/B/C refusal of `check_other_codes` in `interp_check.cc`; the reset of
//! the initial level in `convert_motion`, `interp_convert.cc`).
//!
//! Every expansion here was checked against the canonical calls that LinuxCNC's
//! standalone interpreter `rs274 -g` (2.9) prints for the same program; the unit
//! tests quote the G-code they were checked with.
//!
//! # The model
//!
//! A cycle works in the coordinates of its plane: `a`, `b` in the plane (X Y for
//! G17, Z X for G18, Y Z for G19) and `c` along its normal (Z, Y, X), the
//! drilling axis, which points out of the part (the hole's bottom has the
//! smallest `c`). For each block LinuxCNC
//!
//! 1. takes R (the word, or the sticky R of the previous block of the *same*
//!    cycle; else an error) and the depth word (Z for G17: the word, or sticky);
//! 2. fixes the *initial level*: the current `c` when the first cycle block of
//!    a series runs (kept until a non-cycle motion code or G80);
//! 3. computes, under G90, `r = R`, `bottom = Z`, the hole at the block's
//!    `a b` words (else the current position); under G91, `r = initial level +
//!    R`, `bottom = r + Z`, and the `a b` words are increments added *before
//!    every repeat* (so `L` repeats step along a line);
//! 4. refuses `r < bottom`;
//! 5. if the initial level is below `r`, rapids the drilling axis alone from
//!    the current point up to `r` (the initial level then counts as `r` for
//!    this block);
//! 6. clears to `clear` = `r` under G99, the (raised) initial level under G98;
//! 7. repeats `L` times: rapid in the plane to the hole (at the current `c` if
//!    that is above `r` on the first repeat, else at `clear`), rapid down to
//!    `r` (if not there), then the cycle proper from `r`.
//!
//! The interpreter's position after the block is the hole at `clear` (whatever
//! the last commanded move was: see [`CycleStep::AssumePosition`]).
//!
//! LinuxCNC runs every cycle block in exact-path mode (it switches to G61 for
//! the block if another mode is active and restores it afterwards); that is
//! not emitted as a step.
//!
//! # Units
//!
//! Lengths are mm (the caller converts G20 words), P is seconds. Under G20
//! LinuxCNC computes in inches; the only place where that can change the
//! result beyond rounding is the count of pecks of G73/G83 (a peck that lands
//! exactly on the bottom), so [`CycleBlock::inch`] makes the peck loop run in
//! inches as LinuxCNC's does (recovering the inch values exactly when the
//! caller converted them as `inches * 25.4`). The peck retract of G73 and G83
//! is LinuxCNC 2.9's fixed 0.010 in (0.254 mm) in both unit systems (later
//! versions read it from the INI file and a D word).
//!
//! # What the caller does
//!
//! - calls [`expand`] for every block that executes a canned-cycle motion
//!   (a cycle G code, or axis words while a cycle is the motion mode);
//! - calls [`CycleMemory::leave_cycle`] for every block that executes any
//!   other motion (G0 … G3, G38.x, G80, …), as `convert_motion` does;
//! - checks the word-usage rules of `check_other_codes` that involve other
//!   codes of the block ([`CycleCode::uses`] says which words a cycle uses);
//! - applies work offsets: everything here is in program (work) coordinates.
//!
//! Pure: no I/O, no allocation except pushing onto `out`, no panics (non-finite
//! inputs and results are errors).
use super::motion::Plane;

/// The most steps one block may expand to (volcomp's limit: LinuxCNC would
/// loop for as long as the numbers say, or forever when a peck no longer
/// changes the depth).
pub const MAX_STEPS: usize = 1_000_000;

/// The peck retract of G73 and G83 in LinuxCNC 2.9 (`G83_RAPID_DELTA`, 0.010
/// inch, scaled by 25.4 under G21), in mm.
pub const PECK_RETRACT_MM: f64 = 0.010 * 25.4;

/// A canned cycle (LinuxCNC 2.9's `is_a_cycle`: G73, G74, G81–G89).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CycleCode {
    /// Chip-breaking peck drilling (Q; retract 0.254 mm after each peck).
    G73,
    /// Left-hand tapping (spindle counter-clockwise; optional P dwell).
    G74,
    /// Drilling.
    G81,
    /// Drilling with a dwell (P).
    G82,
    /// Peck drilling (Q; back to R after each peck).
    G83,
    /// Right-hand tapping (spindle clockwise; optional P dwell).
    G84,
    /// Boring, feed out.
    G85,
    /// Boring, spindle stop, rapid out (P).
    G86,
    /// Back boring (I J K).
    G87,
    /// Boring, spindle stop, manual out (P).
    G88,
    /// Boring, dwell, feed out (P).
    G89,
}

impl CycleCode {
    /// The cycle of a G code given as its number × 10 (`810` → G81).
    pub fn from_code10(code10: i32) -> Option<Self> {
        Some(match code10 {
            730 => Self::G73,
            740 => Self::G74,
            810 => Self::G81,
            820 => Self::G82,
            830 => Self::G83,
            840 => Self::G84,
            850 => Self::G85,
            860 => Self::G86,
            870 => Self::G87,
            880 => Self::G88,
            890 => Self::G89,
            _ => return None,
        })
    }

    /// The G code's number × 10 (G81 → `810`).
    #[cfg(test)]
    pub fn code10(self) -> i32 {
        match self {
            Self::G73 => 730,
            Self::G74 => 740,
            Self::G81 => 810,
            Self::G82 => 820,
            Self::G83 => 830,
            Self::G84 => 840,
            Self::G85 => 850,
            Self::G86 => 860,
            Self::G87 => 870,
            Self::G88 => 880,
            Self::G89 => 890,
        }
    }

    /// `"G81"`.
    pub fn name(self) -> &'static str {
        match self {
            Self::G73 => "G73",
            Self::G74 => "G74",
            Self::G81 => "G81",
            Self::G82 => "G82",
            Self::G83 => "G83",
            Self::G84 => "G84",
            Self::G85 => "G85",
            Self::G86 => "G86",
            Self::G87 => "G87",
            Self::G88 => "G88",
            Self::G89 => "G89",
        }
    }

    /// `"g81"`, as LinuxCNC's fixed messages spell it.
    fn lower(self) -> &'static str {
        match self {
            Self::G73 => "g73",
            Self::G74 => "g74",
            Self::G81 => "g81",
            Self::G82 => "g82",
            Self::G83 => "g83",
            Self::G84 => "g84",
            Self::G85 => "g85",
            Self::G86 => "g86",
            Self::G87 => "g87",
            Self::G88 => "g88",
            Self::G89 => "g89",
        }
    }

    /// Whether LinuxCNC's `check_other_codes` lets this cycle use the word
    /// `letter` (upper case): R by all; L by all but G74 (LinuxCNC 2.9 refuses
    /// `L` with G74: "L word with no G10, cutter compensation, canned cycle,
    /// digital/analog input, M98 or NURBS code"); P by G74 G82 G84 G86 G88 G89;
    /// Q by G73 G83; I J K by G87. A P, Q, I, J or K that the cycle does not
    /// use is an error there unless another code of the block uses it.
    #[cfg(test)]
    pub fn uses(self, letter: char) -> bool {
        match letter {
            'R' => true,
            'L' => self != Self::G74,
            'P' => matches!(
                self,
                Self::G74 | Self::G82 | Self::G84 | Self::G86 | Self::G88 | Self::G89
            ),
            'Q' => matches!(self, Self::G73 | Self::G83),
            'I' | 'J' | 'K' => self == Self::G87,
            _ => false,
        }
    }
}

/// G98 / G99. The default is LinuxCNC's initial mode (G99, unless the
/// machine's start-up code says otherwise).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum RetractMode {
    /// G98: clear to the initial level (or R if that is higher).
    OldZ,
    /// G99: clear to R.
    #[default]
    RPlane,
}

/// The spindle's direction when the block starts (LinuxCNC's
/// `spindle_turning` of the active spindle: M3, M4, M5).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SpindleDirection {
    #[default]
    Stopped,
    Clockwise,
    CounterClockwise,
}

/// What LinuxCNC remembers between cycle blocks. [`Default`] is the state of
/// a freshly initialised interpreter.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CycleMemory {
    /// The motion mode when it is a canned cycle (`settings->motion_mode`):
    /// set by a cycle block, cleared by [`leave_cycle`](Self::leave_cycle).
    /// Sticky words are taken only while the block's cycle is this one.
    pub mode: Option<CycleCode>,
    /// The initial level (`cycle_il`, valid while `cycle_il_flag`): the drilling
    /// axis coordinate when the first cycle block of a series ran. G98 clears
    /// to it, G91 measures R from it. Kept across cycle blocks even when the
    /// cycle code or the plane changes.
    pub initial_level: Option<f64>,
    /// The last R word (`cycle_r`), as written (a level, or under G91 an
    /// increment), mm.
    pub r: f64,
    /// The last depth word (`cycle_cc`: Z for G17, Y for G18, X for G19), as
    /// written, mm.
    pub depth: f64,
    /// The last dwell (`cycle_p`), seconds. Shared by G74 G82 G84 G86 G88 G89;
    /// G74 and G84 take it even when the previous block was another cycle or
    /// not a cycle at all.
    pub p: f64,
    /// The last peck (`cycle_q`), mm. Shared by G73 and G83.
    pub q: f64,
    /// The last G87 offsets I J K (`cycle_i`, `cycle_j`, `cycle_k`), mm.
    pub ijk: [f64; 3],
}

impl CycleMemory {
    /// A block executed a motion that is not a canned cycle (G0, G1, G2, G3,
    /// G38.x, G80, …): the motion mode leaves the cycle and the initial level
    /// is forgotten (`convert_motion`). The sticky words stay (LinuxCNC keeps
    /// them; only P is ever read again without the same cycle in force, by
    /// G74/G84).
    pub fn leave_cycle(&mut self) {
        self.mode = None;
        self.initial_level = None;
    }
}

/// One block executed in a canned-cycle motion mode, in mm (units already
/// applied), in work coordinates (program coordinates; offsets are applied by
/// the caller).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CycleBlock {
    pub code: CycleCode,
    pub plane: Plane,
    pub retract: RetractMode,
    /// G91.
    pub incremental: bool,
    /// The interpreter's current x y z (work coordinates, mm).
    pub position: [f64; 3],
    /// The block's X Y Z words (mm), as written (absolute or increments).
    pub xyz: [Option<f64>; 3],
    /// R word (mm; under G91 an increment from the initial level).
    pub r: Option<f64>,
    /// Q word (mm). LinuxCNC reads `Q-1` (in the program's units) as "no Q".
    pub q: Option<f64>,
    /// P word (seconds). LinuxCNC reads `P-1` as "no P".
    pub p: Option<f64>,
    /// L word (repeats), as read; LinuxCNC requires a non-negative integer.
    pub l: Option<f64>,
    /// G87 offsets I J K (mm): always increments from the hole, except the
    /// one along the drilling axis (K for G17, J for G18, I for G19), which is
    /// the level of the top of the back bore: absolute under G90, from the
    /// bottom under G91.
    pub ijk: [Option<f64>; 3],
    /// Polar words `@` radius (mm) and `^` angle (degrees), about the program
    /// origin: in the XY plane (other planes' cycles do not read them, as in
    /// LinuxCNC) they give the hole's X Y (G90), or are added to its radius
    /// and angle in every repeat (G91).
    pub polar: [Option<f64>; 2],
    /// A, B, C words present (refused in a canned cycle).
    pub rotary_words: [bool; 3],
    /// U, V, W words present (refused in a canned cycle in G17/G18/G19).
    pub uvw_words: [bool; 3],
    /// LinuxCNC's feed rate for this block (after its F word); only tested
    /// for zero. G94 and G95 reset it to 0, and an F word read under G93 does
    /// not set it (so `G93 F100` then a cycle fails with the zero-feed error).
    pub feed_rate: f64,
    /// G93 (inverse time) in force.
    pub inverse_time: bool,
    /// Cutter radius compensation (G41/G42) in force.
    pub cutter_comp: bool,
    /// The active spindle's direction (after this block's M3/M4/M5).
    pub spindle: SpindleDirection,
    /// G20 in force: the pecks of G73/G83 are counted in inches, as LinuxCNC
    /// computes them.
    pub inch: bool,
}

/// One elementary step of a cycle, in the order LinuxCNC emits them.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CycleStep {
    /// `STRAIGHT_TRAVERSE` to x y z (work coordinates, mm).
    Rapid([f64; 3]),
    /// `STRAIGHT_FEED` to x y z at the feed rate in force.
    Feed([f64; 3]),
    /// `DWELL(seconds)`.
    Dwell { seconds: f64 },
    /// `STOP_SPINDLE_TURNING`.
    SpindleStop,
    /// `START_SPINDLE_CLOCKWISE` / `START_SPINDLE_COUNTERCLOCKWISE`.
    SpindleStart { clockwise: bool },
    /// `ORIENT_SPINDLE(angle, mode)` (G87): LinuxCNC passes angle 0 and, as
    /// the mode, its spindle-direction code (2 clockwise, 3 counter-clockwise).
    SpindleOrient { angle_deg: f64, mode: i32 },
    /// `PROGRAM_STOP` (G88: the operator retracts by hand).
    ProgramStop,
    /// `DISABLE_FEED_OVERRIDE` + `DISABLE_SPEED_OVERRIDE` (G74/G84).
    OverridesDisabled,
    /// Both overrides back to what they were before `OverridesDisabled`
    /// (`ENABLE_FEED_OVERRIDE`/`ENABLE_SPEED_OVERRIDE` if they were enabled).
    OverridesRestored,
    /// Not a move: from here on the interpreter takes this as the current
    /// position although the machine was last commanded elsewhere. Emitted
    /// last, when LinuxCNC's position after the block (the hole at the clear
    /// level) differs from the last commanded point: after G88 (the operator
    /// was to retract by hand), and after G74/G84 in G18/G19, whose feeds
    /// LinuxCNC 2.9 commands with permuted coordinates (see [`expand`]).
    AssumePosition([f64; 3]),
}

/// A canned-cycle error: LinuxCNC's message text (its spelling and case),
/// except the last four, which are volcomp's limits.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CycleError {
    #[error("Cannot put an a in canned cycle")]
    AWord,
    #[error("Cannot put a b in canned cycle")]
    BWord,
    #[error("Cannot put a c in canned cycle")]
    CWord,
    #[error("Negative l word used")]
    NegativeL,
    #[error("Non integer value for integer")]
    NonIntegerL,
    #[error("Cannot feed with zero feed rate")]
    ZeroFeed,
    #[error("Cannot use inverse time feed with canned cycles")]
    InverseTime,
    #[error("Cannot use canned cycles with cutter compensation on")]
    CutterComp,
    #[error("R clearance plane unspecified in cycle")]
    RMissing,
    #[error("Cannot do zero repeats of cycle")]
    ZeroRepeats,
    /// A U, V or W word; `plane` as LinuxCNC names it ("XY", "XZ", "YZ").
    #[error("Cannot put a {letter} in a canned cycle in the {plane} plane")]
    UvwWord { letter: char, plane: &'static str },
    /// The depth word is missing in the first block of a cycle.
    #[error("{}", depth_missing(*.0))]
    DepthMissing(Plane),
    /// R is below the bottom.
    #[error("{}", r_below(*.0))]
    RBelowBottom(Plane),
    #[error("Dwell time p word missing with {}", .0.lower())]
    PMissing(CycleCode),
    #[error("Q word missing with {}", .0.lower())]
    QMissing(CycleCode),
    #[error("I word missing with g87")]
    IMissing,
    #[error("J word missing with g87")]
    JMissing,
    #[error("K word missing with g87")]
    KMissing,
    #[error("Negative or zero q value used")]
    NonPositiveQ,
    /// G74/G84 with the spindle stopped.
    #[error("Spindle not turning in {}", .0.name())]
    TapSpindleStopped(CycleCode),
    #[error("Spindle turning clockwise in G74")]
    ClockwiseInG74,
    #[error("Spindle turning counterclockwise in G84")]
    CounterClockwiseInG84,
    /// G86, G87, G88 with the spindle stopped.
    #[error("Spindle not turning in {}", .0.lower())]
    SpindleNotTurning(CycleCode),
    /// volcomp: a word (or the feed rate, 'F') is NaN or infinite.
    #[error("{0} value is not a finite number")]
    NonFiniteWord(char),
    /// volcomp: the current position is NaN or infinite.
    #[error("the current position is not finite")]
    NonFinitePosition,
    /// volcomp: a position of the cycle overflows.
    #[error("a canned-cycle position overflows")]
    NonFiniteResult,
    /// volcomp: the block would expand to more than [`MAX_STEPS`] steps.
    #[error("the canned cycle would expand to more than {MAX_STEPS} moves")]
    TooManySteps,
    #[error("Incremental motion with polar coordinates is indeterminate when at the origin")]
    PolarAtOrigin,
}

fn depth_missing(plane: Plane) -> &'static str {
    match plane {
        Plane::XY => "Z value unspecified in xy plane canned cycle",
        Plane::ZX => "Y value unspecified in xz plane canned cycle",
        Plane::YZ => "X value unspecified in yz plane canned cycle",
    }
}

fn r_below(plane: Plane) -> &'static str {
    match plane {
        Plane::XY => "R less than z in cycle in xy plane",
        Plane::ZX => "R less than y in cycle in xz plane",
        Plane::YZ => "R less than x in cycle in yz plane",
    }
}

impl CycleError {
    /// The word letter to point at, if any. It may name a word that is not in
    /// the block (a sticky value); `None` means: point at the cycle's G code
    /// or the block.
    pub fn word(&self) -> Option<char> {
        match self {
            Self::AWord => Some('A'),
            Self::BWord => Some('B'),
            Self::CWord => Some('C'),
            Self::NegativeL | Self::NonIntegerL | Self::ZeroRepeats => Some('L'),
            Self::UvwWord { letter, .. } => Some(*letter),
            Self::RBelowBottom(_) => Some('R'),
            Self::NonPositiveQ => Some('Q'),
            Self::NonFiniteWord(c) => Some(*c),
            Self::ZeroFeed
            | Self::InverseTime
            | Self::CutterComp
            | Self::RMissing
            | Self::DepthMissing(_)
            | Self::PMissing(_)
            | Self::QMissing(_)
            | Self::IMissing
            | Self::JMissing
            | Self::KMissing
            | Self::PolarAtOrigin
            | Self::TapSpindleStopped(_)
            | Self::ClockwiseInG74
            | Self::CounterClockwiseInG84
            | Self::SpindleNotTurning(_)
            | Self::NonFinitePosition
            | Self::NonFiniteResult
            | Self::TooManySteps => None,
        }
    }
}

/// LinuxCNC's name of a plane in its messages (G18 is "XZ").
fn plane_name(plane: Plane) -> &'static str {
    match plane {
        Plane::XY => "XY",
        Plane::ZX => "XZ",
        Plane::YZ => "YZ",
    }
}

/// Indices of the plane's first and second axes and of its normal
/// (LinuxCNC's `aa`, `bb`, `cc`).
fn plane_axes(plane: Plane) -> [usize; 3] {
    match plane {
        Plane::XY => [0, 1, 2],
        Plane::ZX => [2, 0, 1],
        Plane::YZ => [1, 2, 0],
    }
}

/// x y z of the plane coordinates `(e1, e2, e3)`, exactly as `cycle_feed` and
/// `cycle_traverse` map their three arguments.
fn plane_point(plane: Plane, e1: f64, e2: f64, e3: f64) -> [f64; 3] {
    match plane {
        Plane::XY => [e1, e2, e3],
        Plane::YZ => [e3, e1, e2],
        Plane::ZX => [e2, e3, e1],
    }
}

/// Where the steps go: counts them and refuses non-finite positions.
struct Emitter<'a> {
    out: &'a mut Vec<CycleStep>,
    plane: Plane,
    count: usize,
    last: Option<[f64; 3]>,
}

impl Emitter<'_> {
    fn push(&mut self, step: CycleStep) -> Result<(), CycleError> {
        if self.count >= MAX_STEPS {
            return Err(CycleError::TooManySteps);
        }
        self.count += 1;
        self.out.push(step);
        Ok(())
    }

    fn point(&mut self, p: [f64; 3], feed: bool) -> Result<(), CycleError> {
        if !p.iter().all(|v| v.is_finite()) {
            return Err(CycleError::NonFiniteResult);
        }
        self.last = Some(p);
        self.push(if feed {
            CycleStep::Feed(p)
        } else {
            CycleStep::Rapid(p)
        })
    }

    /// `cycle_traverse(plane, e1, e2, e3)`.
    fn rapid(&mut self, e1: f64, e2: f64, e3: f64) -> Result<(), CycleError> {
        self.point(plane_point(self.plane, e1, e2, e3), false)
    }

    /// `cycle_feed(plane, e1, e2, e3)`.
    fn feed(&mut self, e1: f64, e2: f64, e3: f64) -> Result<(), CycleError> {
        self.point(plane_point(self.plane, e1, e2, e3), true)
    }

    fn dwell(&mut self, seconds: f64) -> Result<(), CycleError> {
        self.push(CycleStep::Dwell { seconds })
    }

    fn start(&mut self, clockwise: bool) -> Result<(), CycleError> {
        self.push(CycleStep::SpindleStart { clockwise })
    }
}

/// The levels of one cycle along the drilling axis, mm.
#[derive(Clone, Copy)]
struct Levels {
    r: f64,
    clear: f64,
    bottom: f64,
    /// G87: the top of the back bore.
    middle: f64,
}

/// The peck loop's R and bottom levels, unit (mm per program unit) and
/// retract, in the program's units.
struct Peck {
    r: f64,
    bottom: f64,
    unit: f64,
    retract: f64,
}

/// The inch value a length in mm was converted from (`mm = inches × 25.4`
/// rounded), so that the pecks of a G20 program meet the bottom exactly where
/// LinuxCNC's do: of the f64 nearest to `mm / 25.4` and its two neighbours,
/// those whose product by 25.4 gives `mm` back exactly, the one closest to a
/// number of 6 decimals (a program's words have few decimals); `mm / 25.4`
/// when none does.
fn to_inches(mm: f64) -> f64 {
    let y = mm / 25.4;
    if !y.is_finite() {
        return y;
    }
    // How far c is from the f64 nearest to its rounding to 6 decimals.
    let roughness = |c: f64| (c - (c * 1e6).round() / 1e6).abs();
    let mut best: Option<(f64, f64)> = None;
    for c in [
        y,
        next_toward(y, f64::INFINITY),
        next_toward(y, f64::NEG_INFINITY),
    ] {
        if c * 25.4 == mm && best.is_none_or(|(_, d)| roughness(c) < d) {
            best = Some((c, roughness(c)));
        }
    }
    best.map_or(y, |(c, _)| c)
}

/// The f64 next to finite `y` toward `to` (±infinity).
fn next_toward(y: f64, to: f64) -> f64 {
    if y == 0.0 {
        let tiny = f64::from_bits(1);
        return if to > 0.0 { tiny } else { -tiny };
    }
    let bits = y.to_bits();
    // Away from zero when moving toward the sign of y.
    let away = (y > 0.0) == (to > 0.0);
    f64::from_bits(if away { bits + 1 } else { bits - 1 })
}

/// An L word as LinuxCNC's `read_integer_value` reads it (`None`: no L).
fn repeats(l: Option<f64>) -> Result<Option<f64>, CycleError> {
    let Some(v) = l else { return Ok(None) };
    let mut n = v.floor();
    if v - n > 0.9999 {
        n = v.ceil();
    } else if v - n > 0.0001 {
        return Err(CycleError::NonIntegerL);
    }
    if n < 0.0 {
        return Err(CycleError::NegativeL);
    }
    Ok(Some(n))
}

/// Expand one cycle block: push its steps in order onto `out` and update
/// `memory`. The position of the last `Rapid`, `Feed` or `AssumePosition`
/// step is the interpreter's new current position.
///
/// On error nothing is pushed (`out` is left as it was) and `memory` is
/// unchanged. (LinuxCNC emits the moves that precede a failing check, such as
/// the positioning moves before a spindle check, and then aborts the
/// program.) When several errors apply, the one LinuxCNC reports first is
/// returned.
///
/// Known LinuxCNC 2.9 behaviours reproduced on purpose:
/// - G74/G84 in G18 and G19 command their two feeds with permuted
///   coordinates (`convert_cycle_g74_g84` passes its arguments to
///   `cycle_feed` in another order for those planes): in G19 the feeds go to
///   X = the hole's Z, Y = the depth, Z = the hole's Y; in G18 to X = the
///   depth, Y = the hole's Z, Z = the hole's X. The interpreter then assumes
///   the hole at the clear level ([`CycleStep::AssumePosition`]).
/// - Under G99, a block whose initial level is above its R starts with a
///   single rapid from the current point (possibly below R, after a previous
///   G99 block with a lower R) straight to the new hole at R.
/// - `P-1` and `Q-1` (in the program's units) count as absent words.
pub fn expand(
    block: &CycleBlock,
    memory: &mut CycleMemory,
    out: &mut Vec<CycleStep>,
) -> Result<(), CycleError> {
    let start = out.len();
    let mut mem = *memory;
    match expand_inner(block, &mut mem, out) {
        Ok(()) => {
            *memory = mem;
            Ok(())
        }
        Err(e) => {
            out.truncate(start);
            Err(e)
        }
    }
}

fn check_finite(block: &CycleBlock) -> Result<(), CycleError> {
    let words = [
        ('X', block.xyz[0]),
        ('Y', block.xyz[1]),
        ('Z', block.xyz[2]),
        ('R', block.r),
        ('Q', block.q),
        ('P', block.p),
        ('L', block.l),
        ('I', block.ijk[0]),
        ('J', block.ijk[1]),
        ('K', block.ijk[2]),
        ('F', Some(block.feed_rate)),
    ];
    for (letter, v) in words {
        if v.is_some_and(|v| !v.is_finite()) {
            return Err(CycleError::NonFiniteWord(letter));
        }
    }
    if !block.position.iter().all(|v| v.is_finite()) {
        return Err(CycleError::NonFinitePosition);
    }
    Ok(())
}

/// The per-repeat refusals of the cycle functions (Q > 0, spindle direction).
/// LinuxCNC checks them in every repeat after the positioning moves; they do
/// not change between repeats, so checking once up front gives the same
/// outcome.
fn check_cycle_function(
    code: CycleCode,
    q: f64,
    spindle: SpindleDirection,
) -> Result<(), CycleError> {
    use SpindleDirection::*;
    match code {
        CycleCode::G73 | CycleCode::G83 if q <= 0.0 => Err(CycleError::NonPositiveQ),
        CycleCode::G74 | CycleCode::G84 => match (code, spindle) {
            (_, Stopped) => Err(CycleError::TapSpindleStopped(code)),
            (CycleCode::G74, Clockwise) => Err(CycleError::ClockwiseInG74),
            (CycleCode::G84, CounterClockwise) => Err(CycleError::CounterClockwiseInG84),
            _ => Ok(()),
        },
        CycleCode::G86 | CycleCode::G87 | CycleCode::G88 if spindle == Stopped => {
            Err(CycleError::SpindleNotTurning(code))
        }
        _ => Ok(()),
    }
}

fn expand_inner(
    block: &CycleBlock,
    mem: &mut CycleMemory,
    out: &mut Vec<CycleStep>,
) -> Result<(), CycleError> {
    check_finite(block)?;
    let code = block.code;
    let plane = block.plane;
    let continuing = mem.mode == Some(code);
    let (l, r_word) = convert_cycle(block, mem, continuing)?;
    let mut layout = Layout::new(block, mem, continuing, r_word)?;
    let peck = Peck::of(block, &layout, r_word);
    let (r, cc) = (layout.r, layout.bottom);
    let mut emit = Emitter {
        out,
        plane,
        count: 0,
        last: None,
    };
    let [_, _, ic] = plane_axes(plane);
    let pos = block.position;
    let mut current_cc = pos[ic];
    if layout.old_cc < r {
        // Up to R along the drilling axis alone, from the current point.
        let mut p = pos;
        p[ic] = r;
        emit.point(p, false)?;
        layout.old_cc = r;
        current_cc = r;
    }
    let clear = match block.retract {
        RetractMode::RPlane => r,
        RetractMode::OldZ => layout.old_cc,
    };
    let sticky = Sticky::take(block, mem, continuing, cc)?;
    check_cycle_function(code, sticky.q, block.spindle)?;
    let repeats = bounded_repeats(code, l, r - cc, sticky.q)?;
    let levels = Levels {
        r,
        clear,
        bottom: cc,
        middle: sticky.middle,
    };
    for repeat in 0..repeats {
        let [aa, bb] = layout.next_hole()?;
        if repeat == 0 && current_cc > r {
            emit.rapid(aa, bb, current_cc)?;
            emit.rapid(aa, bb, r)?;
        } else {
            emit.rapid(aa, bb, clear)?;
            if clear > r {
                emit.rapid(aa, bb, r)?;
            }
        }
        let words = (sticky.p, sticky.q);
        cycle_function(
            &mut emit,
            block,
            [aa, bb],
            levels,
            words,
            &peck,
            sticky.offset,
        )?;
    }
    let end = plane_point(plane, layout.aa, layout.bb, clear);
    if !end.iter().all(|v| v.is_finite()) {
        return Err(CycleError::NonFiniteResult);
    }
    if emit.last != Some(end) {
        emit.push(CycleStep::AssumePosition(end))?;
    }
    mem.mode = Some(code);
    mem.r = r_word;
    mem.depth = layout.depth_word;
    Ok(())
}

/// Reading the block (`read_l`), `check_other_codes` and `convert_cycle`:
/// the repeats L (1 when not given) and the R word (the last one when the
/// cycle continues).
fn convert_cycle(
    block: &CycleBlock,
    mem: &CycleMemory,
    continuing: bool,
) -> Result<(f64, f64), CycleError> {
    let l = repeats(block.l)?;
    // check_other_codes.
    for (present, err) in
        block
            .rotary_words
            .iter()
            .zip([CycleError::AWord, CycleError::BWord, CycleError::CWord])
    {
        if *present {
            return Err(err);
        }
    }
    // convert_cycle.
    if block.feed_rate == 0.0 {
        return Err(CycleError::ZeroFeed);
    }
    if block.inverse_time {
        return Err(CycleError::InverseTime);
    }
    if block.cutter_comp {
        return Err(CycleError::CutterComp);
    }
    let r_word = match block.r {
        Some(r) => r,
        None if continuing => mem.r,
        None => return Err(CycleError::RMissing),
    };
    let l = match l {
        None => 1.0,
        Some(0.0) => return Err(CycleError::ZeroRepeats),
        Some(n) => n,
    };
    for (present, letter) in block.uvw_words.iter().zip(['U', 'V', 'W']) {
        if *present {
            return Err(CycleError::UvwWord {
                letter,
                plane: plane_name(block.plane),
            });
        }
    }
    Ok((l, r_word))
}

/// Where a cycle's holes are and its levels along the drilling axis
/// (`convert_cycle_xy` / `_yz` / `_zx`), in plane coordinates: the hole
/// before the first repeat and the increment of each repeat.
struct Layout {
    /// The hole (before [`Layout::next_hole`] moves it by the increments).
    aa: f64,
    bb: f64,
    aa_inc: f64,
    bb_inc: f64,
    /// Polar increments (G91 with `@`, `^`): radius, angle in radians.
    radius_inc: f64,
    theta_inc: f64,
    /// The R level and the bottom.
    r: f64,
    bottom: f64,
    /// The initial level, raised to R when it is below.
    old_cc: f64,
    /// The depth word as written (the last one when the cycle continues).
    depth_word: f64,
}

impl Layout {
    fn new(
        block: &CycleBlock,
        mem: &mut CycleMemory,
        continuing: bool,
        r_word: f64,
    ) -> Result<Layout, CycleError> {
        let plane = block.plane;
        let [ia, ib, ic] = plane_axes(plane);
        let pos = block.position;
        let depth_word = match block.xyz[ic] {
            Some(v) => v,
            None if continuing => mem.depth,
            None => return Err(CycleError::DepthMissing(plane)),
        };
        let old_cc = *mem.initial_level.get_or_insert(pos[ic]);
        // Polar words: XY plane only (`convert_cycle_xy`).
        let polar = if plane == Plane::XY {
            block.polar
        } else {
            [None; 2]
        };
        let layout = if block.incremental {
            let r = r_word + old_cc;
            Layout {
                aa: pos[ia],
                bb: pos[ib],
                aa_inc: block.xyz[ia].unwrap_or(0.0),
                bb_inc: block.xyz[ib].unwrap_or(0.0),
                radius_inc: polar[0].unwrap_or(0.0),
                theta_inc: polar[1].unwrap_or(0.0).to_radians(),
                r,
                bottom: r + depth_word,
                old_cc,
                depth_word,
            }
        } else {
            let [aa, bb] = if polar.iter().any(Option::is_some) {
                let radius = polar[0].unwrap_or(pos[ib].hypot(pos[ia]));
                let theta = polar[1].map_or(pos[ib].atan2(pos[ia]), f64::to_radians);
                [radius * theta.cos(), radius * theta.sin()]
            } else {
                [
                    block.xyz[ia].unwrap_or(pos[ia]),
                    block.xyz[ib].unwrap_or(pos[ib]),
                ]
            };
            Layout {
                aa,
                bb,
                aa_inc: 0.0,
                bb_inc: 0.0,
                radius_inc: 0.0,
                theta_inc: 0.0,
                r: r_word,
                bottom: depth_word,
                old_cc,
                depth_word,
            }
        };
        if !(layout.r.is_finite() && layout.bottom.is_finite()) {
            return Err(CycleError::NonFiniteResult);
        }
        if layout.r < layout.bottom {
            return Err(CycleError::RBelowBottom(plane));
        }
        Ok(layout)
    }

    /// Move to the next repeat's hole (LinuxCNC's `CYCLE_MACRO`: a zero
    /// increment is no increment) and return it.
    fn next_hole(&mut self) -> Result<[f64; 2], CycleError> {
        self.aa += self.aa_inc;
        self.bb += self.bb_inc;
        if self.radius_inc != 0.0 {
            if self.aa == 0.0 && self.bb == 0.0 {
                return Err(CycleError::PolarAtOrigin);
            }
            let (t, rad) = (
                self.bb.atan2(self.aa),
                self.bb.hypot(self.aa) + self.radius_inc,
            );
            (self.aa, self.bb) = (rad * t.cos(), rad * t.sin());
        }
        if self.theta_inc != 0.0 {
            if self.aa == 0.0 && self.bb == 0.0 {
                return Err(CycleError::PolarAtOrigin);
            }
            let (t, rad) = (
                self.bb.atan2(self.aa) + self.theta_inc,
                self.bb.hypot(self.aa),
            );
            (self.aa, self.bb) = (rad * t.cos(), rad * t.sin());
        }
        Ok([self.aa, self.bb])
    }
}

impl Peck {
    /// The peck loop of G73/G83 in the program's units (see `Units`).
    fn of(block: &CycleBlock, layout: &Layout, r_word: f64) -> Peck {
        if !block.inch {
            return Peck {
                r: layout.r,
                bottom: layout.bottom,
                unit: 1.0,
                retract: PECK_RETRACT_MM,
            };
        }
        let r_in = if block.incremental {
            to_inches(r_word) + to_inches(layout.old_cc)
        } else {
            to_inches(r_word)
        };
        let bottom_in = if block.incremental {
            r_in + to_inches(layout.depth_word)
        } else {
            to_inches(layout.depth_word)
        };
        Peck {
            r: r_in,
            bottom: bottom_in,
            unit: 25.4,
            retract: 0.010,
        }
    }
}

/// The sticky words of a cycle (given, or the last ones while the cycle
/// continues): its dwell `p`, peck `q`, and G87's offsets along the plane and
/// the top of its back bore.
struct Sticky {
    p: f64,
    q: f64,
    middle: f64,
    offset: [f64; 2],
}

impl Sticky {
    /// Take the block's sticky words (checked as LinuxCNC checks them before
    /// the repeats) and remember them; `bottom` is the cycle's bottom.
    fn take(
        block: &CycleBlock,
        mem: &mut CycleMemory,
        continuing: bool,
        bottom: f64,
    ) -> Result<Sticky, CycleError> {
        use CycleCode::*;
        let code = block.code;
        // The -1 sentinels of read_p/read_q.
        let unit = if block.inch { 25.4 } else { 1.0 };
        let p_word = block.p.filter(|&p| p != -1.0);
        let q_word = block.q.filter(|&q| q != -unit);
        let mut sticky = Sticky {
            p: 0.0,
            q: 0.0,
            middle: 0.0,
            offset: [0.0; 2],
        };
        match code {
            G82 | G86 | G88 | G89 => {
                if !continuing && p_word.is_none() {
                    return Err(CycleError::PMissing(code));
                }
                sticky.p = p_word.unwrap_or(mem.p);
                mem.p = sticky.p;
            }
            G73 | G83 => {
                if !continuing && q_word.is_none() {
                    return Err(CycleError::QMissing(code));
                }
                sticky.q = q_word.unwrap_or(mem.q);
                mem.q = sticky.q;
            }
            G74 | G84 => {
                sticky.p = p_word.unwrap_or(mem.p);
                mem.p = sticky.p;
            }
            G87 => (sticky.offset, sticky.middle) = back_bore(block, mem, continuing, bottom)?,
            G81 | G85 => {}
        }
        Ok(sticky)
    }
}

/// G87's I J K (given, or the last ones while the cycle continues): the
/// offsets along the plane's two axes and the top of the back bore.
fn back_bore(
    block: &CycleBlock,
    mem: &mut CycleMemory,
    continuing: bool,
    bottom: f64,
) -> Result<([f64; 2], f64), CycleError> {
    let [ia, ib, ic] = plane_axes(block.plane);
    if !continuing {
        let missing = [
            CycleError::IMissing,
            CycleError::JMissing,
            CycleError::KMissing,
        ];
        for (word, err) in block.ijk.iter().zip(missing) {
            if word.is_none() {
                return Err(err);
            }
        }
    }
    let mut ijk = mem.ijk;
    for (v, word) in ijk.iter_mut().zip(block.ijk) {
        if let Some(w) = word {
            *v = w;
        }
    }
    mem.ijk = ijk;
    let middle = if block.incremental {
        bottom + ijk[ic]
    } else {
        ijk[ic]
    };
    Ok(([ijk[ia], ijk[ib]], middle))
}

/// The number of repeats, bounding the work before doing it (the pecks of
/// G73/G83 dominate); `height` is R − bottom.
fn bounded_repeats(code: CycleCode, l: f64, height: f64, q: f64) -> Result<u64, CycleError> {
    let pecks = if matches!(code, CycleCode::G73 | CycleCode::G83) {
        (height / q).ceil()
    } else {
        0.0
    };
    let estimate = l * (3.0 * pecks + 16.0);
    if estimate.is_nan() || estimate > MAX_STEPS as f64 {
        return Err(CycleError::TooManySteps);
    }
    Ok(l as u64)
}

/// One repeat of the cycle proper, from the hole at R (`convert_cycle_g73` …
/// `convert_cycle_g89`), at the hole `[aa, bb]` (plane coordinates), with
/// the block's dwell `p` and peck `q`.
fn cycle_function(
    emit: &mut Emitter<'_>,
    block: &CycleBlock,
    [aa, bb]: [f64; 2],
    levels: Levels,
    (p, q): (f64, f64),
    peck: &Peck,
    offset: [f64; 2],
) -> Result<(), CycleError> {
    use CycleCode::*;
    let Levels {
        r,
        clear,
        bottom,
        middle,
    } = levels;
    let clockwise = block.spindle == SpindleDirection::Clockwise;
    match block.code {
        G81 => {
            emit.feed(aa, bb, bottom)?;
            emit.rapid(aa, bb, clear)?;
        }
        G82 => {
            emit.feed(aa, bb, bottom)?;
            emit.dwell(p)?;
            emit.rapid(aa, bb, clear)?;
        }
        G73 | G83 => {
            // The loop runs in the program's units, as LinuxCNC's does.
            let unit = peck.unit;
            let q_u = if unit == 1.0 { q } else { to_inches(q) };
            let mut depth = peck.r - q_u;
            while depth > peck.bottom {
                emit.feed(aa, bb, depth * unit)?;
                if block.code == G83 {
                    emit.rapid(aa, bb, r)?;
                }
                emit.rapid(aa, bb, (depth + peck.retract) * unit)?;
                depth -= q_u;
            }
            emit.feed(aa, bb, bottom)?;
            emit.rapid(aa, bb, clear)?;
        }
        G74 | G84 => {
            // LinuxCNC 2.9 passes the coordinates to cycle_feed in another
            // order for G18 and G19 (reproduced as is).
            let to = |level: f64| match block.plane {
                Plane::XY => (aa, bb, level),
                Plane::YZ => (level, aa, bb),
                Plane::ZX => (bb, level, aa),
            };
            let right_hand = block.code == G84;
            emit.push(CycleStep::OverridesDisabled)?;
            let (e1, e2, e3) = to(bottom);
            emit.feed(e1, e2, e3)?;
            emit.push(CycleStep::SpindleStop)?;
            emit.start(!right_hand)?;
            emit.dwell(p)?;
            let (e1, e2, e3) = to(clear);
            emit.feed(e1, e2, e3)?;
            emit.push(CycleStep::SpindleStop)?;
            emit.start(right_hand)?;
            emit.push(CycleStep::OverridesRestored)?;
        }
        G85 => {
            emit.feed(aa, bb, bottom)?;
            emit.feed(aa, bb, r)?;
            emit.rapid(aa, bb, clear)?;
        }
        G86 => {
            emit.feed(aa, bb, bottom)?;
            emit.dwell(p)?;
            emit.push(CycleStep::SpindleStop)?;
            emit.rapid(aa, bb, clear)?;
            emit.start(clockwise)?;
        }
        G87 => {
            let [oa, ob] = [aa + offset[0], bb + offset[1]];
            let orient = CycleStep::SpindleOrient {
                angle_deg: 0.0,
                mode: if clockwise { 2 } else { 3 },
            };
            emit.rapid(oa, ob, r)?;
            emit.push(CycleStep::SpindleStop)?;
            emit.push(orient)?;
            emit.rapid(oa, ob, bottom)?;
            emit.rapid(aa, bb, bottom)?;
            emit.start(clockwise)?;
            emit.feed(aa, bb, middle)?;
            emit.feed(aa, bb, bottom)?;
            emit.push(CycleStep::SpindleStop)?;
            emit.push(orient)?;
            emit.rapid(oa, ob, bottom)?;
            emit.rapid(oa, ob, clear)?;
            emit.rapid(aa, bb, clear)?;
            emit.start(clockwise)?;
        }
        G88 => {
            emit.feed(aa, bb, bottom)?;
            emit.dwell(p)?;
            emit.push(CycleStep::SpindleStop)?;
            emit.push(CycleStep::ProgramStop)?;
            emit.start(clockwise)?;
        }
        G89 => {
            emit.feed(aa, bb, bottom)?;
            emit.dwell(p)?;
            emit.feed(aa, bb, clear)?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    //! Every expected list below is what LinuxCNC 2.9's `rs274 -g` printed for
    //! the program quoted above it (STRAIGHT_TRAVERSE → `Rapid`,
    //! STRAIGHT_FEED → `Feed`, DWELL, STOP_SPINDLE_TURNING, START_SPINDLE_*,
    //! ORIENT_SPINDLE, PROGRAM_STOP, DISABLE_/ENABLE_FEED_OVERRIDE; the G20
    //! program's inches × 25.4). Only the steps of the cycle blocks are
    //! compared; `G0` blocks set the position and leave the cycle, as a caller
    //! does.
    use super::CycleStep::*;
    use super::*;
    use proptest::prelude::*;

    fn blk(code: CycleCode) -> CycleBlock {
        CycleBlock {
            code,
            plane: Plane::XY,
            retract: RetractMode::OldZ,
            incremental: false,
            position: [0.0; 3],
            xyz: [None; 3],
            r: None,
            q: None,
            p: None,
            l: None,
            ijk: [None; 3],
            polar: [None; 2],
            rotary_words: [false; 3],
            uvw_words: [false; 3],
            feed_rate: 100.0,
            inverse_time: false,
            cutter_comp: false,
            spindle: SpindleDirection::Clockwise,
            inch: false,
        }
    }

    /// A caller in miniature: the position and the memory between blocks.
    struct Session {
        pos: [f64; 3],
        mem: CycleMemory,
    }

    impl Session {
        fn at(pos: [f64; 3]) -> Self {
            Session {
                pos,
                mem: CycleMemory::default(),
            }
        }

        /// `G0` to `pos`: a non-cycle motion.
        fn g0(&mut self, pos: [f64; 3]) {
            self.pos = pos;
            self.mem.leave_cycle();
        }

        /// `G80`.
        fn g80(&mut self) {
            self.mem.leave_cycle();
        }

        fn run(&mut self, mut block: CycleBlock) -> Result<Vec<CycleStep>, CycleError> {
            block.position = self.pos;
            let mut out = Vec::new();
            expand(&block, &mut self.mem, &mut out)?;
            for s in &out {
                if let Rapid(p) | Feed(p) | AssumePosition(p) = s {
                    self.pos = *p;
                }
            }
            Ok(out)
        }

        fn check(&mut self, block: CycleBlock, expected: &[CycleStep]) {
            let got = self.run(block).unwrap_or_else(|e| panic!("{e}"));
            assert_same(&got, expected);
        }
    }

    fn assert_same(got: &[CycleStep], expected: &[CycleStep]) {
        let close = |a: &[f64; 3], b: &[f64; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-9);
        let same = got.len() == expected.len()
            && got.iter().zip(expected).all(|(g, e)| match (g, e) {
                (Rapid(a), Rapid(b))
                | (Feed(a), Feed(b))
                | (AssumePosition(a), AssumePosition(b)) => close(a, b),
                (Dwell { seconds: a }, Dwell { seconds: b }) => (a - b).abs() < 1e-12,
                _ => g == e,
            });
        assert!(same, "got {got:#?}\nexpected {expected:#?}");
    }

    fn xyz(x: Option<f64>, y: Option<f64>, z: Option<f64>) -> [Option<f64>; 3] {
        [x, y, z]
    }

    // G21 G17 G90 G98 F100 S1000 M3 / G0 X0 Y0 Z10 / G81 X1 Y2 R2 Z-5 / X3 /
    // Y4 R3 Z-1
    #[test]
    fn g81_g98_sticky_r_and_z_and_xy_only_blocks() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G81);
        b.xyz = xyz(Some(1.0), Some(2.0), Some(-5.0));
        b.r = Some(2.0);
        s.check(
            b,
            &[
                Rapid([1.0, 2.0, 10.0]),
                Rapid([1.0, 2.0, 2.0]),
                Feed([1.0, 2.0, -5.0]),
                Rapid([1.0, 2.0, 10.0]),
            ],
        );
        let mut b = blk(CycleCode::G81);
        b.xyz = xyz(Some(3.0), None, None);
        s.check(
            b,
            &[
                Rapid([3.0, 2.0, 10.0]),
                Rapid([3.0, 2.0, 2.0]),
                Feed([3.0, 2.0, -5.0]),
                Rapid([3.0, 2.0, 10.0]),
            ],
        );
        let mut b = blk(CycleCode::G81);
        b.xyz = xyz(None, Some(4.0), Some(-1.0));
        b.r = Some(3.0);
        s.check(
            b,
            &[
                Rapid([3.0, 4.0, 10.0]),
                Rapid([3.0, 4.0, 3.0]),
                Feed([3.0, 4.0, -1.0]),
                Rapid([3.0, 4.0, 10.0]),
            ],
        );
        assert_eq!(s.mem.mode, Some(CycleCode::G81));
        assert_eq!(s.mem.initial_level, Some(10.0));
        assert_eq!((s.mem.r, s.mem.depth), (3.0, -1.0));
    }

    // G21 G17 G90 G98 F100 S1000 M3 / G0 X0 Y0 Z1 / G81 X1 R5 Z-1 / X2
    // (R above the current Z: up to R first; G98 then clears to R)
    #[test]
    fn r_above_the_start_rapids_up_first() {
        let mut s = Session::at([0.0, 0.0, 1.0]);
        let mut b = blk(CycleCode::G81);
        b.xyz = xyz(Some(1.0), None, Some(-1.0));
        b.r = Some(5.0);
        s.check(
            b,
            &[
                Rapid([0.0, 0.0, 5.0]),
                Rapid([1.0, 0.0, 5.0]),
                Feed([1.0, 0.0, -1.0]),
                Rapid([1.0, 0.0, 5.0]),
            ],
        );
        let mut b = blk(CycleCode::G81);
        b.xyz = xyz(Some(2.0), None, None);
        s.check(
            b,
            &[
                Rapid([1.0, 0.0, 5.0]),
                Rapid([2.0, 0.0, 5.0]),
                Feed([2.0, 0.0, -1.0]),
                Rapid([2.0, 0.0, 5.0]),
            ],
        );
    }

    // G21 G17 G90 G99 F100 S1000 M3 / G0 X0 Y0 Z10 / G81 X1 R2 Z-1 / X2 R5 /
    // X3 G98 (G99 below a higher R: one rapid straight to the hole at R; G98
    // later clears to the initial level of the series, 10)
    #[test]
    fn g99_with_a_higher_r_and_g98_to_the_initial_level() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G81);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(1.0), None, Some(-1.0));
        b.r = Some(2.0);
        s.check(
            b,
            &[
                Rapid([1.0, 0.0, 10.0]),
                Rapid([1.0, 0.0, 2.0]),
                Feed([1.0, 0.0, -1.0]),
                Rapid([1.0, 0.0, 2.0]),
            ],
        );
        let mut b = blk(CycleCode::G81);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(2.0), None, None);
        b.r = Some(5.0);
        s.check(
            b,
            &[
                Rapid([2.0, 0.0, 5.0]),
                Feed([2.0, 0.0, -1.0]),
                Rapid([2.0, 0.0, 5.0]),
            ],
        );
        let mut b = blk(CycleCode::G81);
        b.xyz = xyz(Some(3.0), None, None);
        s.check(
            b,
            &[
                Rapid([3.0, 0.0, 10.0]),
                Rapid([3.0, 0.0, 5.0]),
                Feed([3.0, 0.0, -1.0]),
                Rapid([3.0, 0.0, 10.0]),
            ],
        );
    }

    // G21 G17 G90 G98 F100 S1000 M3 / G0 X0 Y0 Z10 / G91 G81 X5 Y1 R-8 Z-3 L3 /
    // X-2 R-9 (G91: R from the initial level, Z from R, X Y added per repeat)
    #[test]
    fn g91_increments_and_l_repeats() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G81);
        b.incremental = true;
        b.xyz = xyz(Some(5.0), Some(1.0), Some(-3.0));
        b.r = Some(-8.0);
        b.l = Some(3.0);
        s.check(
            b,
            &[
                Rapid([5.0, 1.0, 10.0]),
                Rapid([5.0, 1.0, 2.0]),
                Feed([5.0, 1.0, -1.0]),
                Rapid([5.0, 1.0, 10.0]),
                Rapid([10.0, 2.0, 10.0]),
                Rapid([10.0, 2.0, 2.0]),
                Feed([10.0, 2.0, -1.0]),
                Rapid([10.0, 2.0, 10.0]),
                Rapid([15.0, 3.0, 10.0]),
                Rapid([15.0, 3.0, 2.0]),
                Feed([15.0, 3.0, -1.0]),
                Rapid([15.0, 3.0, 10.0]),
            ],
        );
        let mut b = blk(CycleCode::G81);
        b.incremental = true;
        b.xyz = xyz(Some(-2.0), None, None);
        b.r = Some(-9.0);
        s.check(
            b,
            &[
                Rapid([13.0, 3.0, 10.0]),
                Rapid([13.0, 3.0, 1.0]),
                Feed([13.0, 3.0, -2.0]),
                Rapid([13.0, 3.0, 10.0]),
            ],
        );
    }

    // G21 G17 G90 G99 F100 S1000 M3 / G0 X0 Y0 Z10 / G83 X1 R2 Z-1.5 Q1.5 / X2
    // (back to R after each peck, then down to 0.254 mm above the last depth)
    #[test]
    fn g83_pecks_and_sticky_q() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G83);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(1.0), None, Some(-1.5));
        b.r = Some(2.0);
        b.q = Some(1.5);
        s.check(
            b,
            &[
                Rapid([1.0, 0.0, 10.0]),
                Rapid([1.0, 0.0, 2.0]),
                Feed([1.0, 0.0, 0.5]),
                Rapid([1.0, 0.0, 2.0]),
                Rapid([1.0, 0.0, 0.754]),
                Feed([1.0, 0.0, -1.0]),
                Rapid([1.0, 0.0, 2.0]),
                Rapid([1.0, 0.0, -0.746]),
                Feed([1.0, 0.0, -1.5]),
                Rapid([1.0, 0.0, 2.0]),
            ],
        );
        let mut b = blk(CycleCode::G83);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(2.0), None, None);
        s.check(
            b,
            &[
                Rapid([2.0, 0.0, 2.0]),
                Feed([2.0, 0.0, 0.5]),
                Rapid([2.0, 0.0, 2.0]),
                Rapid([2.0, 0.0, 0.754]),
                Feed([2.0, 0.0, -1.0]),
                Rapid([2.0, 0.0, 2.0]),
                Rapid([2.0, 0.0, -0.746]),
                Feed([2.0, 0.0, -1.5]),
                Rapid([2.0, 0.0, 2.0]),
            ],
        );
    }

    // G21 G17 G90 G98 F100 S1000 M3 / G0 X0 Y0 Z10 / G73 X1 R2 Z-1.5 Q1.5
    // (up 0.254 mm after each peck)
    #[test]
    fn g73_chip_breaking() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G73);
        b.xyz = xyz(Some(1.0), None, Some(-1.5));
        b.r = Some(2.0);
        b.q = Some(1.5);
        s.check(
            b,
            &[
                Rapid([1.0, 0.0, 10.0]),
                Rapid([1.0, 0.0, 2.0]),
                Feed([1.0, 0.0, 0.5]),
                Rapid([1.0, 0.0, 0.754]),
                Feed([1.0, 0.0, -1.0]),
                Rapid([1.0, 0.0, -0.746]),
                Feed([1.0, 0.0, -1.5]),
                Rapid([1.0, 0.0, 10.0]),
            ],
        );
    }

    // G20 G17 G90 G98 F10 S1000 M3 / G0 X0 Y0 Z1 / G83 X1 R0.1 Z-0.2 Q0.1 /
    // G73 X2 R8 Z6.8 Q0.3 (inches × 25.4; the peck retract is 0.010 in; in
    // inches 8 − 4 × 0.3 lands just above 6.8, so LinuxCNC pecks to 6.8 twice)
    #[test]
    fn g20_pecks_count_in_inches() {
        let inch = |v: f64| v * 25.4;
        let mut s = Session::at([0.0, 0.0, inch(1.0)]);
        let mut b = blk(CycleCode::G83);
        b.inch = true;
        b.xyz = xyz(Some(inch(1.0)), None, Some(inch(-0.2)));
        b.r = Some(inch(0.1));
        b.q = Some(inch(0.1));
        s.check(
            b,
            &[
                Rapid([25.4, 0.0, 25.4]),
                Rapid([25.4, 0.0, 2.54]),
                Feed([25.4, 0.0, 0.0]),
                Rapid([25.4, 0.0, 2.54]),
                Rapid([25.4, 0.0, 0.254]),
                Feed([25.4, 0.0, -2.54]),
                Rapid([25.4, 0.0, 2.54]),
                Rapid([25.4, 0.0, -2.286]),
                Feed([25.4, 0.0, -5.08]),
                Rapid([25.4, 0.0, 25.4]),
            ],
        );
        let mut b = blk(CycleCode::G73);
        b.inch = true;
        b.xyz = xyz(Some(inch(2.0)), None, Some(inch(6.8)));
        b.r = Some(inch(8.0));
        b.q = Some(inch(0.3));
        s.check(
            b,
            &[
                Rapid([25.4, 0.0, 203.2]),
                Rapid([50.8, 0.0, 203.2]),
                Feed([50.8, 0.0, 195.58]),
                Rapid([50.8, 0.0, 195.834]),
                Feed([50.8, 0.0, 187.96]),
                Rapid([50.8, 0.0, 188.214]),
                Feed([50.8, 0.0, 180.34]),
                Rapid([50.8, 0.0, 180.594]),
                Feed([50.8, 0.0, 172.72]),
                Rapid([50.8, 0.0, 172.974]),
                Feed([50.8, 0.0, 172.72]),
                Rapid([50.8, 0.0, 203.2]),
            ],
        );
    }

    // G21 G90 G98 F100 S1000 M3 / G0 X10 Y10 Z10 / G18 G81 X1 Z2 R5 Y-1 / G80 /
    // G19 G82 Y3 Z4 R12 X1 P0.5
    #[test]
    fn g18_and_g19_drill_along_y_and_x() {
        let mut s = Session::at([10.0, 10.0, 10.0]);
        let mut b = blk(CycleCode::G81);
        b.plane = Plane::ZX;
        b.xyz = xyz(Some(1.0), Some(-1.0), Some(2.0));
        b.r = Some(5.0);
        s.check(
            b,
            &[
                Rapid([1.0, 10.0, 2.0]),
                Rapid([1.0, 5.0, 2.0]),
                Feed([1.0, -1.0, 2.0]),
                Rapid([1.0, 10.0, 2.0]),
            ],
        );
        s.g80();
        let mut b = blk(CycleCode::G82);
        b.plane = Plane::YZ;
        b.xyz = xyz(Some(1.0), Some(3.0), Some(4.0));
        b.r = Some(12.0);
        b.p = Some(0.5);
        s.check(
            b,
            &[
                Rapid([12.0, 10.0, 2.0]),
                Rapid([12.0, 3.0, 4.0]),
                Feed([1.0, 3.0, 4.0]),
                Dwell { seconds: 0.5 },
                Rapid([12.0, 3.0, 4.0]),
            ],
        );
    }

    // G21 G17 G90 G98 F100 S1000 M3 / G0 X0 Y0 Z10 / G84 X5 R2 Z-3 P0.5 /
    // G80 M4 / G74 X6 R2 Z-3 (G74 takes the P of G84 although G80 came between)
    #[test]
    fn g84_and_g74_reverse_the_spindle_and_share_p() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G84);
        b.xyz = xyz(Some(5.0), None, Some(-3.0));
        b.r = Some(2.0);
        b.p = Some(0.5);
        s.check(
            b,
            &[
                Rapid([5.0, 0.0, 10.0]),
                Rapid([5.0, 0.0, 2.0]),
                OverridesDisabled,
                Feed([5.0, 0.0, -3.0]),
                SpindleStop,
                SpindleStart { clockwise: false },
                Dwell { seconds: 0.5 },
                Feed([5.0, 0.0, 10.0]),
                SpindleStop,
                SpindleStart { clockwise: true },
                OverridesRestored,
            ],
        );
        s.g80();
        let mut b = blk(CycleCode::G74);
        b.spindle = SpindleDirection::CounterClockwise;
        b.xyz = xyz(Some(6.0), None, Some(-3.0));
        b.r = Some(2.0);
        s.check(
            b,
            &[
                Rapid([6.0, 0.0, 10.0]),
                Rapid([6.0, 0.0, 2.0]),
                OverridesDisabled,
                Feed([6.0, 0.0, -3.0]),
                SpindleStop,
                SpindleStart { clockwise: true },
                Dwell { seconds: 0.5 },
                Feed([6.0, 0.0, 10.0]),
                SpindleStop,
                SpindleStart { clockwise: false },
                OverridesRestored,
            ],
        );
    }

    // G21 G90 G98 F100 S1000 M3 / G0 X1 Y2 Z3 / G19 G84 X-1 Y5 Z6 R0 P0.5 /
    // G80 / G18 G84 Y-1 X7 Z8 R0 / G80 / G0 X0 → STRAIGHT_TRAVERSE(0, 5, 8)
    // (LinuxCNC 2.9 permutes the tapping feeds in G19 and G18, then assumes
    // the hole at the clear level: the last G0 starts from (7, 5, 8))
    #[test]
    fn g84_in_g19_and_g18_feeds_to_permuted_coordinates() {
        let mut s = Session::at([1.0, 2.0, 3.0]);
        let mut b = blk(CycleCode::G84);
        b.plane = Plane::YZ;
        b.xyz = xyz(Some(-1.0), Some(5.0), Some(6.0));
        b.r = Some(0.0);
        b.p = Some(0.5);
        s.check(
            b,
            &[
                Rapid([1.0, 5.0, 6.0]),
                Rapid([0.0, 5.0, 6.0]),
                OverridesDisabled,
                Feed([6.0, -1.0, 5.0]),
                SpindleStop,
                SpindleStart { clockwise: false },
                Dwell { seconds: 0.5 },
                Feed([6.0, 1.0, 5.0]),
                SpindleStop,
                SpindleStart { clockwise: true },
                OverridesRestored,
                AssumePosition([1.0, 5.0, 6.0]),
            ],
        );
        s.g80();
        let mut b = blk(CycleCode::G84);
        b.plane = Plane::ZX;
        b.xyz = xyz(Some(7.0), Some(-1.0), Some(8.0));
        b.r = Some(0.0);
        s.check(
            b,
            &[
                Rapid([7.0, 5.0, 8.0]),
                Rapid([7.0, 0.0, 8.0]),
                OverridesDisabled,
                Feed([-1.0, 8.0, 7.0]),
                SpindleStop,
                SpindleStart { clockwise: false },
                Dwell { seconds: 0.5 },
                Feed([5.0, 8.0, 7.0]),
                SpindleStop,
                SpindleStart { clockwise: true },
                OverridesRestored,
                AssumePosition([7.0, 5.0, 8.0]),
            ],
        );
        s.g0([0.0, s.pos[1], s.pos[2]]);
        assert_eq!(s.pos, [0.0, 5.0, 8.0]);
    }

    // G21 G17 G90 G99 F100 S1000 M4 / G0 X0 Y0 Z10 / G85 X1 R2 Z-1 /
    // G86 X2 R2 Z-1 P1 / G89 X3 R2 Z-1 P0.25 / X4 L2
    #[test]
    fn g85_g86_g89_boring() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let ccw = SpindleDirection::CounterClockwise;
        let mut b = blk(CycleCode::G85);
        b.retract = RetractMode::RPlane;
        b.spindle = ccw;
        b.xyz = xyz(Some(1.0), None, Some(-1.0));
        b.r = Some(2.0);
        s.check(
            b,
            &[
                Rapid([1.0, 0.0, 10.0]),
                Rapid([1.0, 0.0, 2.0]),
                Feed([1.0, 0.0, -1.0]),
                Feed([1.0, 0.0, 2.0]),
                Rapid([1.0, 0.0, 2.0]),
            ],
        );
        let mut b = blk(CycleCode::G86);
        b.retract = RetractMode::RPlane;
        b.spindle = ccw;
        b.xyz = xyz(Some(2.0), None, Some(-1.0));
        b.r = Some(2.0);
        b.p = Some(1.0);
        s.check(
            b,
            &[
                Rapid([2.0, 0.0, 2.0]),
                Feed([2.0, 0.0, -1.0]),
                Dwell { seconds: 1.0 },
                SpindleStop,
                Rapid([2.0, 0.0, 2.0]),
                SpindleStart { clockwise: false },
            ],
        );
        let mut b = blk(CycleCode::G89);
        b.retract = RetractMode::RPlane;
        b.spindle = ccw;
        b.xyz = xyz(Some(3.0), None, Some(-1.0));
        b.r = Some(2.0);
        b.p = Some(0.25);
        s.check(
            b,
            &[
                Rapid([3.0, 0.0, 2.0]),
                Feed([3.0, 0.0, -1.0]),
                Dwell { seconds: 0.25 },
                Feed([3.0, 0.0, 2.0]),
            ],
        );
        let mut b = blk(CycleCode::G89);
        b.retract = RetractMode::RPlane;
        b.spindle = ccw;
        b.xyz = xyz(Some(4.0), None, None);
        b.l = Some(2.0);
        s.check(
            b,
            &[
                Rapid([4.0, 0.0, 2.0]),
                Feed([4.0, 0.0, -1.0]),
                Dwell { seconds: 0.25 },
                Feed([4.0, 0.0, 2.0]),
                Rapid([4.0, 0.0, 2.0]),
                Feed([4.0, 0.0, -1.0]),
                Dwell { seconds: 0.25 },
                Feed([4.0, 0.0, 2.0]),
            ],
        );
    }

    // G21 G17 G90 G98 F100 S1000 M3 / G0 X0 Y0 Z10 / G87 X7 Y1 R2 Z-3 I1 J2 K-1 /
    // G91 X1 R-7 Z-6 K2 / G90 G80 / G18 G87 Z1 X2 R4 Y-3 I0.5 J-1 K0.25
    #[test]
    fn g87_back_boring() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G87);
        b.xyz = xyz(Some(7.0), Some(1.0), Some(-3.0));
        b.r = Some(2.0);
        b.ijk = [Some(1.0), Some(2.0), Some(-1.0)];
        let orient = SpindleOrient {
            angle_deg: 0.0,
            mode: 2,
        };
        s.check(
            b,
            &[
                Rapid([7.0, 1.0, 10.0]),
                Rapid([7.0, 1.0, 2.0]),
                Rapid([8.0, 3.0, 2.0]),
                SpindleStop,
                orient,
                Rapid([8.0, 3.0, -3.0]),
                Rapid([7.0, 1.0, -3.0]),
                SpindleStart { clockwise: true },
                Feed([7.0, 1.0, -1.0]),
                Feed([7.0, 1.0, -3.0]),
                SpindleStop,
                orient,
                Rapid([8.0, 3.0, -3.0]),
                Rapid([8.0, 3.0, 10.0]),
                Rapid([7.0, 1.0, 10.0]),
                SpindleStart { clockwise: true },
            ],
        );
        // G91: K from the bottom; I and J sticky.
        let mut b = blk(CycleCode::G87);
        b.incremental = true;
        b.xyz = xyz(Some(1.0), None, Some(-6.0));
        b.r = Some(-7.0);
        b.ijk = [None, None, Some(2.0)];
        s.check(
            b,
            &[
                Rapid([8.0, 1.0, 10.0]),
                Rapid([8.0, 1.0, 3.0]),
                Rapid([9.0, 3.0, 3.0]),
                SpindleStop,
                orient,
                Rapid([9.0, 3.0, -3.0]),
                Rapid([8.0, 1.0, -3.0]),
                SpindleStart { clockwise: true },
                Feed([8.0, 1.0, -1.0]),
                Feed([8.0, 1.0, -3.0]),
                SpindleStop,
                orient,
                Rapid([9.0, 3.0, -3.0]),
                Rapid([9.0, 3.0, 10.0]),
                Rapid([8.0, 1.0, 10.0]),
                SpindleStart { clockwise: true },
            ],
        );
        s.g80();
        // G18: K offsets Z, I offsets X, J is the top of the back bore.
        let mut b = blk(CycleCode::G87);
        b.plane = Plane::ZX;
        b.xyz = xyz(Some(2.0), Some(-3.0), Some(1.0));
        b.r = Some(4.0);
        b.ijk = [Some(0.5), Some(-1.0), Some(0.25)];
        s.check(
            b,
            &[
                Rapid([8.0, 4.0, 10.0]),
                Rapid([2.0, 4.0, 1.0]),
                Rapid([2.5, 4.0, 1.25]),
                SpindleStop,
                orient,
                Rapid([2.5, -3.0, 1.25]),
                Rapid([2.0, -3.0, 1.0]),
                SpindleStart { clockwise: true },
                Feed([2.0, -1.0, 1.0]),
                Feed([2.0, -3.0, 1.0]),
                SpindleStop,
                orient,
                Rapid([2.5, -3.0, 1.25]),
                Rapid([2.5, 4.0, 1.25]),
                Rapid([2.0, 4.0, 1.0]),
                SpindleStart { clockwise: true },
            ],
        );
    }

    // G21 G17 G90 G98 F100 S1000 M4 / G0 X0 Y0 Z10 / G88 X8 Y1 R2 Z-3 P0.2 / X9
    // (the operator retracts: the next block starts from the clear level)
    #[test]
    fn g88_stops_and_assumes_the_clear_level() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G88);
        b.spindle = SpindleDirection::CounterClockwise;
        b.xyz = xyz(Some(8.0), Some(1.0), Some(-3.0));
        b.r = Some(2.0);
        b.p = Some(0.2);
        let tail = [
            Dwell { seconds: 0.2 },
            SpindleStop,
            ProgramStop,
            SpindleStart { clockwise: false },
        ];
        let mut expected = vec![
            Rapid([8.0, 1.0, 10.0]),
            Rapid([8.0, 1.0, 2.0]),
            Feed([8.0, 1.0, -3.0]),
        ];
        expected.extend(tail);
        expected.push(AssumePosition([8.0, 1.0, 10.0]));
        s.check(b, &expected);
        let mut b = blk(CycleCode::G88);
        b.spindle = SpindleDirection::CounterClockwise;
        b.xyz = xyz(Some(9.0), None, None);
        let mut expected = vec![
            Rapid([9.0, 1.0, 10.0]),
            Rapid([9.0, 1.0, 2.0]),
            Feed([9.0, 1.0, -3.0]),
        ];
        expected.extend(tail);
        expected.push(AssumePosition([9.0, 1.0, 10.0]));
        s.check(b, &expected);
    }

    // G21 G17 G90 G99 F100 S1000 M3 / G0 X0 Y0 Z10 / G81 X1 R2 Z-1 /
    // G82 X2 R3 Z-1 P1 G98 / G0 Z4 / G81 X3 R2 Z-1 (changing the cycle keeps
    // the initial level; G0 forgets it)
    #[test]
    fn initial_level_spans_cycle_codes_until_another_motion() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G81);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(1.0), None, Some(-1.0));
        b.r = Some(2.0);
        s.check(
            b,
            &[
                Rapid([1.0, 0.0, 10.0]),
                Rapid([1.0, 0.0, 2.0]),
                Feed([1.0, 0.0, -1.0]),
                Rapid([1.0, 0.0, 2.0]),
            ],
        );
        let mut b = blk(CycleCode::G82);
        b.xyz = xyz(Some(2.0), None, Some(-1.0));
        b.r = Some(3.0);
        b.p = Some(1.0);
        s.check(
            b,
            &[
                Rapid([2.0, 0.0, 10.0]),
                Rapid([2.0, 0.0, 3.0]),
                Feed([2.0, 0.0, -1.0]),
                Dwell { seconds: 1.0 },
                Rapid([2.0, 0.0, 10.0]),
            ],
        );
        s.g0([2.0, 0.0, 4.0]);
        let mut b = blk(CycleCode::G81);
        b.xyz = xyz(Some(3.0), None, Some(-1.0));
        b.r = Some(2.0);
        s.check(
            b,
            &[
                Rapid([3.0, 0.0, 4.0]),
                Rapid([3.0, 0.0, 2.0]),
                Feed([3.0, 0.0, -1.0]),
                Rapid([3.0, 0.0, 4.0]),
            ],
        );
    }

    // G21 G17 G90 G99 F100 S1000 M3 / G0 X0 Y0 Z10 / G82 X1 R2 Z-1 P1.5 / G80 /
    // G84 X2 R2 Z-2 / G82 X3 R2 Z-1 P-1 → "Dwell time p word missing with g82"
    // (P-1 is no P; the dwell is shared with G84)
    #[test]
    fn p_is_shared_and_p_minus_one_is_no_p() {
        let mut s = Session::at([0.0, 0.0, 10.0]);
        let mut b = blk(CycleCode::G82);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(1.0), None, Some(-1.0));
        b.r = Some(2.0);
        b.p = Some(1.5);
        s.check(
            b,
            &[
                Rapid([1.0, 0.0, 10.0]),
                Rapid([1.0, 0.0, 2.0]),
                Feed([1.0, 0.0, -1.0]),
                Dwell { seconds: 1.5 },
                Rapid([1.0, 0.0, 2.0]),
            ],
        );
        s.g80();
        let mut b = blk(CycleCode::G84);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(2.0), None, Some(-2.0));
        b.r = Some(2.0);
        s.check(
            b,
            &[
                Rapid([2.0, 0.0, 2.0]),
                OverridesDisabled,
                Feed([2.0, 0.0, -2.0]),
                SpindleStop,
                SpindleStart { clockwise: false },
                Dwell { seconds: 1.5 },
                Feed([2.0, 0.0, 2.0]),
                SpindleStop,
                SpindleStart { clockwise: true },
                OverridesRestored,
            ],
        );
        let mut b = blk(CycleCode::G82);
        b.retract = RetractMode::RPlane;
        b.xyz = xyz(Some(3.0), None, Some(-1.0));
        b.r = Some(2.0);
        b.p = Some(-1.0);
        let before = s.mem;
        assert_eq!(s.run(b), Err(CycleError::PMissing(CycleCode::G82)));
        assert_eq!(s.mem, before, "memory untouched on error");
    }

    // G21 G90 G98 F100 S1000 M3 / G0 X0 Y0 Z10 / G81 X1 R2 Z-1 / G80 / G81 X2 Z-1
    // → "R clearance plane unspecified in cycle"; likewise G81 X1 R2 Z-1 /
    // G82 X2 P1 (another cycle takes no sticky R)
    #[test]
    fn sticky_words_need_the_same_cycle() {
        for change in [false, true] {
            let mut s = Session::at([0.0, 0.0, 10.0]);
            let mut b = blk(CycleCode::G81);
            b.xyz = xyz(Some(1.0), None, Some(-1.0));
            b.r = Some(2.0);
            s.run(b).unwrap();
            let mut b = if change {
                let mut b = blk(CycleCode::G82);
                b.p = Some(1.0);
                b
            } else {
                s.g80();
                let mut b = blk(CycleCode::G81);
                b.xyz[2] = Some(-1.0);
                b
            };
            b.xyz[0] = Some(2.0);
            assert_eq!(s.run(b), Err(CycleError::RMissing));
        }
    }

    /// One block after `G21 G90 G98 F100 S1000 <pre> / G0 X0 Y0 Z10`.
    fn error_of(pre: fn(&mut CycleBlock), code: CycleCode, set: fn(&mut CycleBlock)) -> CycleError {
        let mut b = blk(code);
        b.position = [0.0, 0.0, 10.0];
        pre(&mut b);
        set(&mut b);
        let mut out = vec![Dwell { seconds: 9.0 }];
        let mut mem = CycleMemory::default();
        let e = expand(&b, &mut mem, &mut out).unwrap_err();
        assert_eq!(out, [Dwell { seconds: 9.0 }], "nothing pushed on error");
        assert_eq!(mem, CycleMemory::default(), "memory untouched on error");
        e
    }

    // Each line: the third line of the program `N1 G21 G90 G98 F100 S1000
    // <pre> / N2 G0 X0 Y0 Z10 / N3 <block>`, and the message rs274 printed.
    #[test]
    fn errors_match_linuxcnc() {
        use CycleCode::*;
        let m3: fn(&mut CycleBlock) = |_| {};
        let m4: fn(&mut CycleBlock) = |b| b.spindle = SpindleDirection::CounterClockwise;
        let m5: fn(&mut CycleBlock) = |b| b.spindle = SpindleDirection::Stopped;
        let g18: fn(&mut CycleBlock) = |b| b.plane = Plane::ZX;
        let g19: fn(&mut CycleBlock) = |b| b.plane = Plane::YZ;
        type Set = fn(&mut CycleBlock);
        let cases: Vec<(Set, CycleCode, Set, &str)> = vec![
            // M3 G17 | G81 X1 Z-1
            (
                m3,
                G81,
                |b| b.xyz = [Some(1.0), None, Some(-1.0)],
                "R clearance plane unspecified in cycle",
            ),
            // M3 G17 | G81 X1 R2
            (
                m3,
                G81,
                |b| (b.xyz[0], b.r) = (Some(1.0), Some(2.0)),
                "Z value unspecified in xy plane canned cycle",
            ),
            // M3 G18 | G81 X1 R2
            (
                g18,
                G81,
                |b| (b.xyz[0], b.r) = (Some(1.0), Some(2.0)),
                "Y value unspecified in xz plane canned cycle",
            ),
            // M3 G19 | G81 Y1 R2
            (
                g19,
                G81,
                |b| (b.xyz[1], b.r) = (Some(1.0), Some(2.0)),
                "X value unspecified in yz plane canned cycle",
            ),
            // M3 G17 | G81 X1 R2 Z3
            (
                m3,
                G81,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(3.0)], Some(2.0)),
                "R less than z in cycle in xy plane",
            ),
            // M3 G18 | G81 X1 R2 Y3
            (
                g18,
                G81,
                |b| (b.xyz, b.r) = ([Some(1.0), Some(3.0), None], Some(2.0)),
                "R less than y in cycle in xz plane",
            ),
            // M3 G19 | G81 Y1 R2 X3
            (
                g19,
                G81,
                |b| (b.xyz, b.r) = ([Some(3.0), Some(1.0), None], Some(2.0)),
                "R less than x in cycle in yz plane",
            ),
            // M3 G17 | G81 X1 R2 Z-1 L0
            (
                m3,
                G81,
                |b| (b.xyz, b.r, b.l) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(0.0)),
                "Cannot do zero repeats of cycle",
            ),
            // M3 G17 | G82 X1 R2 Z-1
            (
                m3,
                G82,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Dwell time p word missing with g82",
            ),
            // M3 G17 | G86 X1 R2 Z-1
            (
                m3,
                G86,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Dwell time p word missing with g86",
            ),
            // M3 G17 | G88 X1 R2 Z-1
            (
                m3,
                G88,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Dwell time p word missing with g88",
            ),
            // M3 G17 | G89 X1 R2 Z-1 P-1
            (
                m3,
                G89,
                |b| (b.xyz, b.r, b.p) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(-1.0)),
                "Dwell time p word missing with g89",
            ),
            // M3 G17 | G73 X1 R2 Z-1
            (
                m3,
                G73,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Q word missing with g73",
            ),
            // M3 G17 | G83 X1 R2 Z-1 Q-1
            (
                m3,
                G83,
                |b| (b.xyz, b.r, b.q) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(-1.0)),
                "Q word missing with g83",
            ),
            // M3 G17 | G87 X1 R2 Z-1 J1 K1
            (
                m3,
                G87,
                |b| {
                    (b.xyz, b.r, b.ijk) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        [None, Some(1.0), Some(1.0)],
                    )
                },
                "I word missing with g87",
            ),
            // M3 G17 | G87 X1 R2 Z-1 I1 K1
            (
                m3,
                G87,
                |b| {
                    (b.xyz, b.r, b.ijk) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        [Some(1.0), None, Some(1.0)],
                    )
                },
                "J word missing with g87",
            ),
            // M3 G17 | G87 X1 R2 Z-1 I1 J1
            (
                m3,
                G87,
                |b| {
                    (b.xyz, b.r, b.ijk) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        [Some(1.0), Some(1.0), None],
                    )
                },
                "K word missing with g87",
            ),
            // M3 G17 | G83 X1 R2 Z-1 Q0
            (
                m3,
                G83,
                |b| (b.xyz, b.r, b.q) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(0.0)),
                "Negative or zero q value used",
            ),
            // M3 G17 | G73 X1 R2 Z-1
            (
                m3,
                G73,
                |b| (b.xyz, b.r, b.q) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(-0.5)),
                "Negative or zero q value used",
            ),
            // M4 G17 | G84 X1 R2 Z-1
            (
                m4,
                G84,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Spindle turning counterclockwise in G84",
            ),
            // M5 G17 | G84 X1 R2 Z-1
            (
                m5,
                G84,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Spindle not turning in G84",
            ),
            // M3 G17 | G74 X1 R2 Z-1
            (
                m3,
                G74,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Spindle turning clockwise in G74",
            ),
            // M5 G17 | G74 X1 R2 Z-1
            (
                m5,
                G74,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(-1.0)], Some(2.0)),
                "Spindle not turning in G74",
            ),
            // M5 G17 | G86 X1 R2 Z-1 P1
            (
                m5,
                G86,
                |b| (b.xyz, b.r, b.p) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(1.0)),
                "Spindle not turning in g86",
            ),
            // M5 G17 | G87 X1 R2 Z-1 I1 J1 K1
            (
                m5,
                G87,
                |b| {
                    (b.xyz, b.r, b.ijk) = ([Some(1.0), None, Some(-1.0)], Some(2.0), [Some(1.0); 3])
                },
                "Spindle not turning in g87",
            ),
            // M5 G17 | G88 X1 R2 Z-1 P1
            (
                m5,
                G88,
                |b| (b.xyz, b.r, b.p) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(1.0)),
                "Spindle not turning in g88",
            ),
            // M3 G17 | G81 X1 R2 Z-1 A1 (and B1 C2: the first is reported)
            (
                m3,
                G81,
                |b| {
                    (b.xyz, b.r, b.rotary_words) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        [true, false, false],
                    )
                },
                "Cannot put an a in canned cycle",
            ),
            (
                m3,
                G81,
                |b| {
                    (b.xyz, b.r, b.rotary_words) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        [false, true, true],
                    )
                },
                "Cannot put a b in canned cycle",
            ),
            (
                m3,
                G81,
                |b| {
                    (b.xyz, b.r, b.rotary_words) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        [false, false, true],
                    )
                },
                "Cannot put a c in canned cycle",
            ),
            // M3 G17 | G81 X1 R2 Z-1 L-2
            (
                m3,
                G81,
                |b| (b.xyz, b.r, b.l) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(-2.0)),
                "Negative l word used",
            ),
            // M3 G17 | G81 X1 R2 Z-1 L2.5
            (
                m3,
                G81,
                |b| (b.xyz, b.r, b.l) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(2.5)),
                "Non integer value for integer",
            ),
            // M3 (no F) | G81 X1 R2 Z-1
            (
                m3,
                G81,
                |b| (b.xyz, b.r, b.feed_rate) = ([Some(1.0), None, Some(-1.0)], Some(2.0), 0.0),
                "Cannot feed with zero feed rate",
            ),
            // M3 / G93 | G81 X1 R2 Z-1 (F100 read before G93)
            (
                m3,
                G81,
                |b| (b.xyz, b.r, b.inverse_time) = ([Some(1.0), None, Some(-1.0)], Some(2.0), true),
                "Cannot use inverse time feed with canned cycles",
            ),
            // T1 M6 (tool.tbl of the sample configs) / G0 X-10 Y-10 Z10 /
            // G41 G1 X0 Y0 / G81 X5 R2 Z-1
            (
                m3,
                G81,
                |b| (b.xyz, b.r, b.cutter_comp) = ([Some(5.0), None, Some(-1.0)], Some(2.0), true),
                "Cannot use canned cycles with cutter compensation on",
            ),
            // Which error first: M3 G17 | G82 X1 Z3 R2
            (
                m3,
                G82,
                |b| (b.xyz, b.r) = ([Some(1.0), None, Some(3.0)], Some(2.0)),
                "R less than z in cycle in xy plane",
            ),
            // M3 G17 | G73 X1 Z-1 R2 Q0 L0
            (
                m3,
                G73,
                |b| {
                    (b.xyz, b.r, b.q, b.l) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        Some(0.0),
                        Some(0.0),
                    )
                },
                "Cannot do zero repeats of cycle",
            ),
            // M5 G17 | G84 X1 Z-1 R2 C1
            (
                m5,
                G84,
                |b| {
                    (b.xyz, b.r, b.rotary_words) = (
                        [Some(1.0), None, Some(-1.0)],
                        Some(2.0),
                        [false, false, true],
                    )
                },
                "Cannot put a c in canned cycle",
            ),
            // M3 G17 | G87 X1 R2 Z3 I1 J1
            (
                m3,
                G87,
                |b| {
                    (b.xyz, b.r, b.ijk) = (
                        [Some(1.0), None, Some(3.0)],
                        Some(2.0),
                        [Some(1.0), Some(1.0), None],
                    )
                },
                "R less than z in cycle in xy plane",
            ),
            // M5 G17 | G83 X1 R2 Z-1 Q0
            (
                m5,
                G83,
                |b| (b.xyz, b.r, b.q) = ([Some(1.0), None, Some(-1.0)], Some(2.0), Some(0.0)),
                "Negative or zero q value used",
            ),
        ];
        for (pre, code, set, message) in cases {
            assert_eq!(error_of(pre, code, set).to_string(), message);
        }
    }

    // M3 G17 | G81 X1 R2 Z-1 L1.99995: LinuxCNC reads L2 (two repeats).
    #[test]
    fn l_reads_as_linuxcnc_rounds_it() {
        assert_eq!(repeats(Some(1.99995)), Ok(Some(2.0)));
        assert_eq!(repeats(Some(2.00005)), Ok(Some(2.0)));
        assert_eq!(repeats(Some(2.5)), Err(CycleError::NonIntegerL));
        assert_eq!(repeats(None), Ok(None));
    }

    // Not reachable with rs274 (its machine has no U V W): the messages of
    // convert_cycle.
    #[test]
    fn uvw_words_are_refused_with_the_plane_name() {
        let mut b = blk(CycleCode::G81);
        b.plane = Plane::ZX;
        b.xyz = [Some(1.0), Some(-1.0), None];
        b.r = Some(2.0);
        b.uvw_words = [false, true, true];
        let e = expand(&b, &mut CycleMemory::default(), &mut Vec::new()).unwrap_err();
        assert_eq!(
            e.to_string(),
            "Cannot put a V in a canned cycle in the XZ plane"
        );
        assert_eq!(e.word(), Some('V'));
    }

    #[test]
    fn codes_round_trip_and_words() {
        for c in [730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890] {
            let code = CycleCode::from_code10(c).unwrap();
            assert_eq!(code.code10(), c);
            assert_eq!(code.name(), format!("G{}", c / 10));
        }
        assert_eq!(CycleCode::from_code10(800), None);
        assert_eq!(CycleCode::from_code10(761), None);
        assert!(!CycleCode::G74.uses('L') && CycleCode::G84.uses('L'));
        assert!(CycleCode::G87.uses('J') && !CycleCode::G81.uses('P'));
        assert_eq!(CycleError::RBelowBottom(Plane::XY).word(), Some('R'));
        assert_eq!(CycleError::RMissing.word(), None);
        assert_eq!(RetractMode::default(), RetractMode::RPlane);
    }

    #[test]
    fn non_finite_and_runaway_inputs_are_errors() {
        let mut b = blk(CycleCode::G83);
        b.xyz = [Some(1.0), None, Some(-1.0)];
        b.r = Some(2.0);
        b.q = Some(f64::NAN);
        let mut out = Vec::new();
        let mut mem = CycleMemory::default();
        assert_eq!(
            expand(&b, &mut mem, &mut out),
            Err(CycleError::NonFiniteWord('Q'))
        );
        b.q = Some(1e-12);
        assert_eq!(
            expand(&b, &mut mem, &mut out),
            Err(CycleError::TooManySteps)
        );
        // A peck that no longer changes the depth (LinuxCNC would loop forever).
        b.r = Some(1e17);
        b.xyz[2] = Some(1e17 - 64.0);
        b.q = Some(1.0);
        assert_eq!(
            expand(&b, &mut mem, &mut out),
            Err(CycleError::TooManySteps)
        );
        b.q = Some(2.0);
        b.r = Some(2.0);
        b.xyz = [Some(f64::MAX), None, Some(-1.0)];
        b.incremental = true;
        b.l = Some(3.0);
        assert_eq!(
            expand(&b, &mut mem, &mut out),
            Err(CycleError::NonFiniteResult)
        );
        b.position[1] = f64::INFINITY;
        assert_eq!(
            expand(&b, &mut mem, &mut out),
            Err(CycleError::NonFinitePosition)
        );
        assert!(out.is_empty());
        assert_eq!(mem, CycleMemory::default());
    }

    #[test]
    fn to_inches_recovers_program_values() {
        for v in [0.1, 0.3, 6.8, 8.0, -0.2, 0.0625, 12.3456, 1e-3] {
            assert_eq!(to_inches(v * 25.4), v, "{v}");
        }
    }

    fn opt() -> impl Strategy<Value = Option<f64>> {
        prop_oneof![
            Just(None),
            (-20.0..20.0f64).prop_map(Some),
            prop::sample::select(vec![
                0.0,
                -1.0,
                -25.4,
                0.5,
                1e300,
                -1e300,
                f64::MAX,
                f64::MIN_POSITIVE,
                1e-9,
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY
            ])
            .prop_map(Some),
        ]
    }

    fn arb_block() -> impl Strategy<Value = CycleBlock> {
        let codes =
            prop::sample::select(vec![730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890]);
        let plane = prop::sample::select(vec![Plane::XY, Plane::ZX, Plane::YZ]);
        let spindle = prop::sample::select(vec![
            SpindleDirection::Stopped,
            SpindleDirection::Clockwise,
            SpindleDirection::CounterClockwise,
        ]);
        let l = prop_oneof![Just(None), (0u32..5).prop_map(|l| Some(l as f64)), opt()];
        (
            (codes, plane, any::<[bool; 4]>(), spindle),
            ([opt(), opt(), opt()], [opt(), opt(), opt()]),
            (opt(), opt(), opt(), l, [opt(), opt(), opt()]),
            (
                any::<[bool; 6]>(),
                prop_oneof![Just(100.0), Just(0.0), -1e3..1e3f64],
            ),
        )
            .prop_map(
                |((code, plane, flags, spindle), (pos, xyz), (r, q, p, l, ijk), (words, feed))| {
                    CycleBlock {
                        code: CycleCode::from_code10(code).unwrap(),
                        plane,
                        retract: if flags[0] {
                            RetractMode::OldZ
                        } else {
                            RetractMode::RPlane
                        },
                        incremental: flags[1],
                        position: pos.map(|v| v.unwrap_or(0.0)),
                        xyz,
                        r,
                        q,
                        p,
                        l,
                        ijk,
                        polar: [None; 2],
                        rotary_words: [words[0] && words[1], false, words[2] && words[3]],
                        uvw_words: [words[4] && words[5], false, false],
                        feed_rate: feed,
                        inverse_time: flags[2] && flags[3],
                        cutter_comp: false,
                        spindle,
                        inch: flags[3],
                    }
                },
            )
    }

    /// Mostly well-formed blocks (so that most expand), with some wild values.
    fn good_block() -> impl Strategy<Value = CycleBlock> {
        let codes =
            prop::sample::select(vec![730, 740, 810, 820, 830, 840, 850, 860, 870, 880, 890]);
        let plane = prop::sample::select(vec![Plane::XY, Plane::ZX, Plane::YZ]);
        let word = || prop_oneof![4 => (-20.0..20.0f64).prop_map(Some), 1 => Just(None)];
        (
            (codes, plane, any::<[bool; 3]>()),
            (
                [-50.0..50.0f64, -50.0..50.0f64, -50.0..50.0f64],
                [word(), word()],
            ),
            (
                -10.0..10.0f64,
                0.0..10.0f64,
                0.05..5.0f64,
                0.0..2.0f64,
                1u32..4,
            ),
            [word(), word(), word()],
            (opt(), 0usize..12),
        )
            .prop_map(
                |((code, plane, flags), (position, ab), (r, d, q, p, l), ijk, (wild, at))| {
                    let code = CycleCode::from_code10(code).unwrap();
                    let [ia, ib, ic] = plane_axes(plane);
                    let mut xyz = [None; 3];
                    (xyz[ia], xyz[ib]) = (ab[0], ab[1]);
                    xyz[ic] = Some(if flags[1] { -d } else { r - d });
                    let mut b = CycleBlock {
                        code,
                        plane,
                        retract: if flags[0] {
                            RetractMode::OldZ
                        } else {
                            RetractMode::RPlane
                        },
                        incremental: flags[1],
                        position,
                        xyz,
                        r: Some(r),
                        q: Some(q),
                        p: Some(p),
                        l: Some(l as f64),
                        ijk,
                        polar: [None; 2],
                        rotary_words: [false; 3],
                        uvw_words: [false; 3],
                        feed_rate: 100.0,
                        inverse_time: false,
                        cutter_comp: false,
                        spindle: if code == CycleCode::G74 {
                            SpindleDirection::CounterClockwise
                        } else {
                            SpindleDirection::Clockwise
                        },
                        inch: flags[2],
                    };
                    if !code.uses('Q') {
                        b.q = None;
                    }
                    if !code.uses('P') {
                        b.p = None;
                    }
                    // One wild word now and then.
                    match at {
                        0 => b.xyz[ia] = wild,
                        1 => b.xyz[ic] = wild,
                        2 => b.r = wild,
                        3 => b.q = wild,
                        4 => b.p = wild,
                        5 => b.l = wild,
                        6 => b.ijk[ic] = wild,
                        7 => b.position[ic] = wild.unwrap_or(0.0),
                        _ => {}
                    }
                    b
                },
            )
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// Any sequence of blocks: no panic, only finite positions, nothing
        /// pushed and memory kept on error, at most MAX_STEPS per block.
        #[test]
        fn expand_never_panics_and_emits_finite_positions(
            blocks in prop::collection::vec(prop_oneof![3 => good_block(), 1 => arb_block()], 1..6),
            leave in any::<[bool; 6]>(),
        ) {
            let mut mem = CycleMemory::default();
            let mut out = Vec::new();
            for (i, b) in blocks.iter().enumerate() {
                let before = (mem, out.len());
                match expand(b, &mut mem, &mut out) {
                    Ok(()) => {
                        prop_assert!(out.len() - before.1 <= MAX_STEPS);
                        prop_assert_eq!(mem.mode, Some(b.code));
                    }
                    Err(_) => {
                        prop_assert_eq!(out.len(), before.1);
                        prop_assert_eq!(mem, before.0);
                    }
                }
                for s in &out {
                    if let Rapid(p) | Feed(p) | AssumePosition(p) = s {
                        prop_assert!(p.iter().all(|v| v.is_finite()), "{:?}", s);
                    }
                    if let Dwell { seconds } = s {
                        prop_assert!(seconds.is_finite());
                    }
                }
                if leave[i] {
                    mem.leave_cycle();
                }
            }
        }
    }
}
