//! Errors of the G-code front end: typed, located (file, line, column) and
//! rendered like rustc diagnostics — the offending line, a caret under the spot,
//! and a hint.
//!
//! Invariant: every [`GcodeError`] carries the 1-based line and 1-based byte
//! column it is about and a copy of that line (lossily decoded, tabs kept), so
//! it can be shown without the file.
use std::fmt;
use std::path::PathBuf;

/// What went wrong.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ErrorKind {
    #[error("unclosed comment: `(` is never closed on this line")]
    UnclosedComment,
    #[error("word `{0}` has no number")]
    MissingNumber(char),
    #[error("malformed number in word `{0}`")]
    MalformedNumber(char),
    #[error("number out of range in word `{0}`")]
    NumberOutOfRange(char),
    #[error("{0}")]
    Syntax(crate::gcode::syntax::expression::SyntaxErrorKind),
    #[error("{0}")]
    Eval(crate::gcode::syntax::expression::EvalErrorKind),
    #[error("{0}")]
    OWord(String),
    #[error("EOF seeking {0}")]
    EndOfFileInSubroutine(String),
    #[error("Equal sign missing in parameter setting")]
    MissingEquals,
    #[error("Unexpected character after O-word")]
    UnexpectedAfterOWord,
    #[error(
        "Unknown O-word keyword: expected sub, endsub, call, do, while, endwhile, if, elseif, else, endif, repeat, endrepeat, return, break or continue"
    )]
    UnknownOWordKeyword,
    #[error("Left bracket missing after '{0}'")]
    BracketAfterOKeyword(&'static str),
    #[error("unexpected character `{0}`")]
    UnexpectedCharacter(String),
    #[error(
        "Bad character '{}' used: the machine has no {letter} axis (its axes: {axes})",
        letter.to_ascii_lowercase()
    )]
    AxisNotOnMachine { letter: char, axes: String },
    #[error("subroutine call `{0}` is not supported")]
    SubroutineCall(String),
    #[error("cutter radius compensation {0} is active during a move")]
    CutterCompensation(String),
    #[error("`{0}` changes the geometry and is not understood")]
    UnsupportedGCode(String),
    #[error(
        "parameters, expressions and O-words are not run by this command yet (`volcomp check` runs them)"
    )]
    NeedsLanguage,
    #[error("File ended with no percent sign or program end")]
    NoProgramEnd,
    #[error("Multiple {0} words on one line")]
    RepeatedWord(char),
    #[error("Two {0} codes used from same modal group")]
    ModalGroupConflict(char),
    #[error("Cannot use two G codes that both use axis values")]
    TwoAxisUsers,
    #[error("G92 needs at least one axis word")]
    G92WithoutAxes,
    #[error("G52 needs at least one axis word")]
    G52WithoutAxes,
    #[error("G10 with a missing or invalid P number")]
    G10Pnumber,
    #[error("G10 with a missing or unsupported L number (L1, L2, L10, L11, L20)")]
    G10Lnumber,
    #[error("Must use G0 or G1 with G53")]
    G53Motion,
    #[error("Cannot use G53 incremental")]
    G53Incremental,
    #[error("R not allowed in G10 L20")]
    G10L20Rotation,
    #[error("Dwell time P word missing with G4")]
    DwellWithoutP,
    #[error("Cannot use inverse time feed with canned cycles")]
    CycleInverseTime,
    #[error("{0}")]
    Cycle(String),
    #[error("Cannot probe in inverse time feed mode")]
    ProbeInverseTime,
    #[error("Start point too close to probe point")]
    ProbeTooClose,
    #[error("Cannot do {0} with zero feed rate")]
    ZeroFeed(&'static str),
    #[error("F word missing with inverse time {0} move")]
    InverseTimeFeedMissing(&'static str),
    #[error("Current point same as end point of arc")]
    ArcSamePoint,
    #[error("Zero-radius arc")]
    ArcZeroRadius,
    #[error("Radius to end of arc differs from radius to start: r1={r1:.4} r2={r2:.4} mm")]
    ArcRadiusMismatch { r1: f64, r2: f64 },
    #[error("arcs in the G18/G19 planes under an XY rotation (G10 L2 R) are not supported")]
    RotatedArcPlane,
    #[error("axis words without a motion mode (G0, G1, G2 or G3)")]
    NoMotionMode,
    #[error("{0} word with no G or M code that uses it")]
    UnusedWord(char),
    #[error("All axes missing with motion code")]
    MotionWithoutAxes,
    #[error("P value not an integer with G2 or G3")]
    ArcTurnsNotInteger,
    #[error("P value should be 1 or greater with G2 or G3")]
    ArcTurnsBelowOne,
    #[error("Mixed radius ijk format for arc")]
    ArcMixedFormat,
    #[error("{0} word given for arc in {1} plane")]
    ArcCentreWordOffPlane(char, &'static str),
    #[error("{0} word missing in absolute center arc")]
    ArcAbsoluteCentreMissing(char),
    #[error("arc without a centre: give I/J/K or R")]
    ArcWithoutCentre,
    #[error("arc radius R{0} cannot reach the end point")]
    ArcUnreachable(f64),
    #[error("the target is not finite")]
    NonFinite,
    #[error("the program executed {0} lines without ending: an endless loop?")]
    EndlessProgram(u64),
    /// volcomp's limit on a line's length ([`crate::gcode::syntax::reader::MAX_LINE_BYTES`]).
    #[error(
        "line of {bytes} bytes, longer than volcomp's limit of {limit} bytes (LinuxCNC reads at most 254 characters: \"Command too long\")"
    )]
    LineTooLong { bytes: usize, limit: usize },
    /// volcomp's limit on repeated work ([`super::LanguageOptions::max_loop_lines`],
    /// [`super::LanguageOptions::max_generated_moves`]).
    #[error("more than {limit} {what}{}: an endless or runaway loop? ({option} N raises the limit)", if within.is_empty() { String::new() } else { format!(", in {within}") })]
    LoopLimit {
        limit: u64,
        what: &'static str,
        option: &'static str,
        within: String,
    },
    /// The up-front estimate of a canned cycle in `repeat` loops.
    #[error("this block would generate about {estimate:.3e} moves ({per_block} per execution × {trips:.0} executions{}), more than the limit of {limit} ({option} N raises it)", if within.is_empty() { String::new() } else { format!(" of {within}") })]
    MovesEstimate {
        estimate: f64,
        per_block: usize,
        trips: f64,
        limit: u64,
        option: &'static str,
        within: String,
    },
    #[error("carriage return inside the line: the file has CR-only (classic Mac) line ends")]
    BareCarriageReturn,
    #[error("Bad character '\\357' used: the file starts with a UTF-8 byte order mark (EF BB BF)")]
    ByteOrderMark,
    #[error("Requested tool {0} not found in the tool table")]
    ToolNotInTable(u32),
    #[error("{0} word: a tool number must be a whole number ≥ 0")]
    ToolNumber(char),
    #[error("G43.2: {0}")]
    ToolOffsetAdd(&'static str),
    #[error("cannot read the input: {0}")]
    Io(String),
    /// Polar coordinates (`@` radius, `^` angle) used where LinuxCNC
    /// refuses them (its message).
    #[error("{0}")]
    Polar(&'static str),
    /// A spline (G5, G5.1, G5.2 … G5.3) LinuxCNC refuses (its message), or
    /// one volcomp cannot follow.
    #[error("{0}")]
    Spline(String),
}

impl ErrorKind {
    /// How to fix it, shown under the caret.
    pub fn hint(&self) -> &'static str {
        match self {
            ErrorKind::UnclosedComment => {
                "close the comment with `)` on the same line, or pass --lenient to pass the line through untouched"
            }
            ErrorKind::MissingNumber(_) => {
                "write a number after the letter (e.g. `X0`), or pass --lenient to pass the line through untouched"
            }
            ErrorKind::MalformedNumber(_) | ErrorKind::NumberOutOfRange(_) => {
                "write a plain decimal number (e.g. `X-12.5`), or pass --lenient to pass the line through untouched"
            }
            ErrorKind::Syntax(_) | ErrorKind::MissingEquals => {
                "check the expression (RS274NGC: `[` … `]` with + - * / ** MOD EQ NE GT GE LT LE AND OR XOR, #n or #<name> parameters, functions such as SIN[…])"
            }
            ErrorKind::Eval(_) => {
                "check the parameters and the expression at the caret (named parameters must be set before they are read), or pass --lenient to pass the line through untouched"
            }
            ErrorKind::OWord(_) | ErrorKind::EndOfFileInSubroutine(_) => {
                "check the O-word labels: every sub/while/if/repeat needs its matching end; subroutine files are found on --subroutine-path as NAME.ngc"
            }
            ErrorKind::UnexpectedAfterOWord
            | ErrorKind::UnknownOWordKeyword
            | ErrorKind::BracketAfterOKeyword(_) => {
                "an O-word line holds only the O-word, its keyword, its bracketed arguments and comments"
            }
            ErrorKind::AxisNotOnMachine { .. } => {
                "the program is for another machine (check the machine file's axes), or pass --lenient to ignore the word (reported)"
            }
            ErrorKind::SubroutineCall(_) => {
                "expand subroutines in the CAM post-processor, or pass --lenient to pass the line through untouched (its geometry is then ignored)"
            }
            ErrorKind::UnexpectedCharacter(_) => {
                "remove the character or put it in a comment, or pass --lenient to pass the line through untouched"
            }
            ErrorKind::CutterCompensation(_) => {
                "post-process with cutter compensation in the CAM system (G40), or pass --lenient to interpret the moves as programmed"
            }
            ErrorKind::UnsupportedGCode(_) => {
                "remove the code or expand it in the post-processor, or pass --lenient to pass it through (its effect on geometry is then ignored)"
            }
            ErrorKind::NoMotionMode => {
                "program G0 or G1 before the first move, or pass --lenient to treat the move as G1"
            }
            ErrorKind::ArcWithoutCentre
            | ErrorKind::ArcUnreachable(_)
            | ErrorKind::ArcMixedFormat
            | ErrorKind::ArcCentreWordOffPlane(..)
            | ErrorKind::ArcAbsoluteCentreMissing(_)
            | ErrorKind::ArcTurnsNotInteger
            | ErrorKind::ArcTurnsBelowOne => {
                "check the arc words, or pass --lenient to treat the arc as a straight move"
            }
            ErrorKind::NonFinite => "check the numbers of the block",
            ErrorKind::LineTooLong { .. } => {
                "split the line (a long comment into several comment lines); is this a G-code program?"
            }
            ErrorKind::LoopLimit { .. } | ErrorKind::MovesEstimate { .. } => {
                "check the loop's condition and counts (the line shown is where it stopped); the limits are far above what a real program's loops run"
            }
            ErrorKind::EndlessProgram(_) => {
                "check the loop's condition (the line shown is where it stopped): volcomp stops a program after a billion executed lines"
            }
            ErrorKind::ByteOrderMark => {
                "LinuxCNC refuses it (as rs274 says: Bad character '\\357' used): save the program without the byte order mark (as UTF-8 without BOM, or ASCII)"
            }
            ErrorKind::BareCarriageReturn => {
                "convert the line ends to LF or CR LF (e.g. `tr '\\r' '\\n'`); LinuxCNC would read the whole file as one block"
            }
            ErrorKind::ToolNotInTable(_) => {
                "add the tool to the tool table (--tools FILE, LinuxCNC's `T2 P2 Z120.0 D6.0`, or [[tools]] in the machine file), or correct the tool number"
            }
            ErrorKind::ToolNumber(_) => {
                "write the tool number as a whole number: `T2 M6`, `M61 Q2`, `G43 H2`"
            }
            ErrorKind::ToolOffsetAdd(_) => {
                "G43.2 adds one tool's offset (`G43.2 H3`) or the axis words (`G43.2 Z0.5`)"
            }
            ErrorKind::UnusedWord(_) => {
                "remove the word, or give the code that uses it (LinuxCNC refuses words no code of the block uses)"
            }
            ErrorKind::MotionWithoutAxes => "give the move's axis words",
            ErrorKind::DwellWithoutP => "give the dwell time in seconds: `G4 P0.5`",
            ErrorKind::RepeatedWord(_)
            | ErrorKind::ModalGroupConflict(_)
            | ErrorKind::TwoAxisUsers => {
                "LinuxCNC refuses this block; split it into two blocks, or pass --lenient to let the last word win"
            }
            ErrorKind::NeedsLanguage => {
                "flatten the program first (`volcomp check --targets` shows its executed moves), or pass --lenient to pass the line through untouched"
            }
            ErrorKind::NoProgramEnd => "end the program with M2 or M30 (or enclose it in % lines)",
            ErrorKind::G92WithoutAxes
            | ErrorKind::G52WithoutAxes
            | ErrorKind::G10Pnumber
            | ErrorKind::G10Lnumber
            | ErrorKind::G10L20Rotation => {
                "check the G10/G92 words (G10 L2 P1 X… sets the G54 origin)"
            }
            ErrorKind::CycleInverseTime | ErrorKind::Cycle(_) => "check the canned cycle's words",
            ErrorKind::ProbeInverseTime | ErrorKind::ProbeTooClose => "check the probing move",
            ErrorKind::ZeroFeed(_) | ErrorKind::InverseTimeFeedMissing(_) => {
                "program an F word before (G94) or on (G93) the feed move"
            }
            ErrorKind::ArcSamePoint
            | ErrorKind::ArcZeroRadius
            | ErrorKind::ArcRadiusMismatch { .. } => {
                "check the arc's end point and centre words (LinuxCNC's tolerance: 0.028 mm, or 0.1 % of the radius above 0.028 mm)"
            }
            ErrorKind::RotatedArcPlane => "program the arc in G17, or without the rotation",
            ErrorKind::G53Motion | ErrorKind::G53Incremental => {
                "G53 moves with G0 or G1 to absolute machine coordinates (G90)"
            }
            ErrorKind::Io(_) => "check that the file exists and is readable",
            ErrorKind::Polar(_) => {
                "polar words (`@` radius, `^` angle, about the program origin in the XY plane) replace X and Y in G17 motion blocks"
            }
            ErrorKind::Spline(_) => {
                "G5: X Y, I J (or neither) and P Q; G5.1: X Y, I J; G5.2 X Y P [L] lines, then G5.3 (XY plane, no Z A C words)"
            }
        }
    }
}

/// An error located in the program.
#[derive(Clone, Debug, PartialEq)]
pub struct GcodeError {
    pub kind: ErrorKind,
    /// File, when known (set by [`GcodeError::with_path`]).
    pub path: Option<PathBuf>,
    /// 1-based line.
    pub line: usize,
    /// 1-based byte column.
    pub column: usize,
    /// Number of bytes the caret underlines (at least 1).
    pub width: usize,
    /// The line's text (lossily decoded); of a long line, an excerpt of at
    /// most [`EXCERPT_BYTES`] around the column.
    pub source_line: String,
    /// Where the excerpt starts in the line (bytes; 0: at its start).
    pub excerpt_from: usize,
    /// The excerpt stops before the end of the line.
    pub excerpt_cut: bool,
}

/// The most bytes of a line an error keeps and shows: a message stays short
/// however long the line.
pub const EXCERPT_BYTES: usize = 160;

impl std::error::Error for GcodeError {}

impl GcodeError {
    /// An error at byte `start..end` (0-based) of line `line` whose bytes are `raw`.
    pub fn at(kind: ErrorKind, line: usize, raw: &[u8], start: usize, end: usize) -> Self {
        let start = start.min(raw.len());
        let end = end.clamp(start, raw.len());
        // A window of the line around the column (60 bytes before it).
        let from = if raw.len() <= EXCERPT_BYTES {
            0
        } else {
            start.saturating_sub(60).min(raw.len() - EXCERPT_BYTES)
        };
        let to = (from + EXCERPT_BYTES).min(raw.len());
        GcodeError {
            kind,
            path: None,
            line,
            column: start + 1,
            width: (end - start).max(1),
            source_line: String::from_utf8_lossy(&raw[from..to]).into_owned(),
            excerpt_from: from,
            excerpt_cut: to < raw.len(),
        }
    }

    /// Name the file in the rendering.
    pub fn with_path(mut self, path: impl Into<PathBuf>) -> Self {
        self.path = Some(path.into());
        self
    }
}

impl fmt::Display for GcodeError {
    /// Renders like rustc:
    ///
    /// ```text
    /// unclosed comment: `(` is never closed on this line
    ///   --> part.nc:12:8
    ///    |
    /// 12 | N10 G1 (oops X1
    ///    |        ^
    ///    = hint: close the comment ...
    /// ```
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let file = self
            .path
            .as_ref()
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| "<input>".to_string());
        let num = self.line.to_string();
        let pad = " ".repeat(num.len());
        writeln!(f, "{}", self.kind)?;
        writeln!(f, "{pad}--> {file}:{}:{}", self.line, self.column)?;
        writeln!(f, "{pad} |")?;
        // Show the line (its excerpt) up to a sane length, with control
        // characters made visible; `…` where the excerpt cuts the line.
        let lead = if self.excerpt_from > 0 { "…" } else { "" };
        let shown: String = lead
            .chars()
            .chain(self.source_line.chars())
            .chain(if self.excerpt_cut { "…" } else { "" }.chars())
            .take(200)
            .map(|c| {
                if c.is_control() && c != '\t' {
                    '�'
                } else {
                    c
                }
            })
            .collect();
        writeln!(f, "{num} | {shown}")?;
        // The caret goes under the byte column; tabs in the prefix stay tabs.
        let before = self
            .column
            .saturating_sub(1)
            .saturating_sub(self.excerpt_from);
        let prefix: String = self
            .source_line
            .bytes()
            .take(before)
            .map(|b| if b == b'\t' { '\t' } else { ' ' })
            .collect();
        // Count characters, not bytes, for the prefix when the line is UTF-8.
        let prefix = match self.source_line.get(..before) {
            Some(p) => p
                .chars()
                .map(|c| if c == '\t' { '\t' } else { ' ' })
                .collect(),
            None => prefix,
        };
        let prefix = if self.excerpt_from > 0 {
            format!(" {prefix}")
        } else {
            prefix
        };
        let carets = "^".repeat(self.width.min(80));
        writeln!(f, "{pad} | {prefix}{carets}")?;
        write!(f, "{pad} = hint: {}", self.kind.hint())
    }
}
