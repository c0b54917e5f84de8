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
    /// A `(` comment is not closed by `)` on the same line.
    #[error("unclosed comment: `(` is never closed on this line")]
    UnclosedComment,
    /// A word's letter is not followed by a number (the letter).
    #[error("word `{0}` has no number")]
    MissingNumber(char),
    /// A word's number cannot be read as a decimal number (the letter).
    #[error("malformed number in word `{0}`")]
    MalformedNumber(char),
    /// A word's number does not fit an f64 (the letter).
    #[error("number out of range in word `{0}`")]
    NumberOutOfRange(char),
    /// An expression, parameter reference or assignment is malformed.
    #[error("{0}")]
    Syntax(crate::gcode::syntax::expression::SyntaxErrorKind),
    /// Evaluating an expression failed (e.g. an unset named parameter, a
    /// division by zero, a function's argument out of its domain).
    #[error("{0}")]
    Eval(crate::gcode::syntax::expression::EvalErrorKind),
    /// An O-word control-flow error (an unmatched label, a misplaced
    /// keyword, an undefined subroutine…), with LinuxCNC's message.
    #[error("{0}")]
    OWord(String),
    /// The file ended inside a subroutine, or while an O-word label was
    /// sought (what was sought, and where).
    #[error("EOF seeking {0}")]
    EndOfFileInSubroutine(String),
    /// A parameter setting (`#1 …`) without its `=`.
    #[error("Equal sign missing in parameter setting")]
    MissingEquals,
    /// Something other than a keyword follows an O-word's label.
    #[error("Unexpected character after O-word")]
    UnexpectedAfterOWord,
    /// An O-word's keyword is none of LinuxCNC's.
    #[error(
        "Unknown O-word keyword: expected sub, endsub, call, do, while, endwhile, if, elseif, else, endif, repeat, endrepeat, return, break or continue"
    )]
    UnknownOWordKeyword,
    /// An O-word keyword that takes a bracketed argument (the keyword, e.g.
    /// `while`) is not followed by `[`.
    #[error("Left bracket missing after '{0}'")]
    BracketAfterOKeyword(&'static str),
    /// A character that starts no word, comment or expression (shown as
    /// written).
    #[error("unexpected character `{0}`")]
    UnexpectedCharacter(String),
    /// An axis word for an axis the machine does not have.
    #[error(
        "Bad character '{}' used: the machine has no {letter} axis (its axes: {axes})",
        letter.to_ascii_lowercase()
    )]
    AxisNotOnMachine {
        /// The axis word's letter.
        letter: char,
        /// The machine's axis letters.
        axes: String,
    },
    /// An M98 or M99 subroutine call (the code), which volcomp does not run.
    #[error("subroutine call `{0}` is not supported")]
    SubroutineCall(String),
    /// A move while cutter radius compensation (the code: G41 or G42) is
    /// active; volcomp cannot offset the path.
    #[error("cutter radius compensation {0} is active during a move")]
    CutterCompensation(String),
    /// A G-code (as written) volcomp does not understand and that would
    /// change the geometry.
    #[error("`{0}` changes the geometry and is not understood")]
    UnsupportedGCode(String),
    /// A block with parameters, expressions or an O-word reached the machine
    /// layer directly (read without the language layer, [`super::Execution`]).
    #[error(
        "parameters, expressions and O-words are not run by this command yet (`volcomp check` runs them)"
    )]
    NeedsLanguage,
    /// The file ended without `%` or a program end (M2, M30) where one is
    /// required.
    #[error("File ended with no percent sign or program end")]
    NoProgramEnd,
    /// The same word letter twice in one block (the letter), which LinuxCNC
    /// refuses.
    #[error("Multiple {0} words on one line")]
    RepeatedWord(char),
    /// Two codes of the same modal group in one block (the code's letter, G
    /// or M).
    #[error("Two {0} codes used from same modal group")]
    ModalGroupConflict(char),
    /// A motion code beside a code that takes the axis words (G10, G28, G30,
    /// G52, G92), e.g. `G1 G92 X1`.
    #[error("Cannot use two G codes that both use axis values")]
    TwoAxisUsers,
    /// G92 without any axis word.
    #[error("G92 needs at least one axis word")]
    G92WithoutAxes,
    /// G52 without any axis word.
    #[error("G52 needs at least one axis word")]
    G52WithoutAxes,
    /// G10 with a missing or invalid P number (coordinate system or tool).
    #[error("G10 with a missing or invalid P number")]
    G10Pnumber,
    /// G10 with a missing L number or one volcomp does not support.
    #[error("G10 with a missing or unsupported L number (L1, L2, L10, L11, L20)")]
    G10Lnumber,
    /// G53 with a motion mode other than G0 or G1.
    #[error("Must use G0 or G1 with G53")]
    G53Motion,
    /// G53 in incremental distance mode (G91).
    #[error("Cannot use G53 incremental")]
    G53Incremental,
    /// An R (rotation) word with G10 L20.
    #[error("R not allowed in G10 L20")]
    G10L20Rotation,
    /// G4 without its P word (the dwell time).
    #[error("Dwell time P word missing with G4")]
    DwellWithoutP,
    /// A canned cycle in inverse time feed mode (G93).
    #[error("Cannot use inverse time feed with canned cycles")]
    CycleInverseTime,
    /// A canned cycle's words are wrong (LinuxCNC's message).
    #[error("{0}")]
    Cycle(String),
    /// A probing move (G38.x) in inverse time feed mode (G93).
    #[error("Cannot probe in inverse time feed mode")]
    ProbeInverseTime,
    /// A probing move whose end is too close to its start.
    #[error("Start point too close to probe point")]
    ProbeTooClose,
    /// A feed move (what: e.g. `probe`, `spline`) with a zero feed rate.
    #[error("Cannot do {0} with zero feed rate")]
    ZeroFeed(&'static str),
    /// A feed move (what kind) in inverse time mode (G93) without its F word.
    #[error("F word missing with inverse time {0} move")]
    InverseTimeFeedMissing(&'static str),
    /// An arc whose end point is its start point (with an R centre).
    #[error("Current point same as end point of arc")]
    ArcSamePoint,
    /// An arc of zero radius.
    #[error("Zero-radius arc")]
    ArcZeroRadius,
    /// An arc's centre is not at the same distance from its start and end
    /// (beyond LinuxCNC's tolerance).
    #[error("Radius to end of arc differs from radius to start: r1={r1:.4} r2={r2:.4} mm")]
    ArcRadiusMismatch {
        /// Distance from the centre to the start (mm).
        r1: f64,
        /// Distance from the centre to the end (mm).
        r2: f64,
    },
    /// An arc in the G18 or G19 plane while the coordinate system is rotated
    /// about Z (G10 L2 R).
    #[error("arcs in the G18/G19 planes under an XY rotation (G10 L2 R) are not supported")]
    RotatedArcPlane,
    /// Axis words in a block while no motion mode (G0, G1, G2, G3) is active.
    #[error("axis words without a motion mode (G0, G1, G2 or G3)")]
    NoMotionMode,
    /// A word (the letter) that no G- or M-code of its block uses.
    #[error("{0} word with no G or M code that uses it")]
    UnusedWord(char),
    /// A motion code other than G0, G1, G2, G3, G5.2 and G80 (e.g. a canned
    /// cycle, a probe) without any axis word.
    #[error("All axes missing with motion code")]
    MotionWithoutAxes,
    /// The P word (turns) of G2/G3 is not a whole number.
    #[error("P value not an integer with G2 or G3")]
    ArcTurnsNotInteger,
    /// The P word (turns) of G2/G3 is less than 1.
    #[error("P value should be 1 or greater with G2 or G3")]
    ArcTurnsBelowOne,
    /// An arc with both R and I/J/K centre words.
    #[error("Mixed radius ijk format for arc")]
    ArcMixedFormat,
    /// A centre word (the letter) not in the arc's plane (the plane's name).
    #[error("{0} word given for arc in {1} plane")]
    ArcCentreWordOffPlane(char, &'static str),
    /// A centre word (the letter) missing in an arc with absolute centre
    /// (G90.1).
    #[error("{0} word missing in absolute center arc")]
    ArcAbsoluteCentreMissing(char),
    /// An arc with neither I/J/K nor R.
    #[error("arc without a centre: give I/J/K or R")]
    ArcWithoutCentre,
    /// An R arc whose radius (the R value, mm) is too small to reach the end
    /// point.
    #[error("arc radius R{0} cannot reach the end point")]
    ArcUnreachable(f64),
    /// A move's target is not finite (an infinite or NaN coordinate).
    #[error("the target is not finite")]
    NonFinite,
    /// A construct of a controller dialect volcomp does not read yet (the
    /// dialect's name, the feature as written): never passed over, since it
    /// may move an axis.
    #[error("{0} `{1}` is not read by volcomp yet")]
    DialectFeature(&'static str, String),
    /// What the control itself refuses (in its words, as its manual gives
    /// them).
    #[error("{0}")]
    DialectRefused(String),
    /// A system variable the program reads whose value cannot be known
    /// offline and was not given (`--sysvar`).
    #[error("{0}")]
    SystemVariableUnknown(String),
    /// A block whose reading needs the machine's kinematics, read without
    /// `--machine` (what it needs it for).
    #[error("{0} needs the machine's kinematics")]
    MachineNeeded(&'static str),
    /// The program stopped itself with an error number (Klartext `FN 14:
    /// ERROR = n`: the control shows its error text n and stops).
    #[error("the program stops with its own error number {0} (FN 14: ERROR)")]
    ProgramErrorStop(i64),
    /// The program executed more lines than the limit (the limit) without
    /// ending.
    #[error("the program executed {0} lines without ending: an endless loop?")]
    EndlessProgram(u64),
    /// volcomp's limit on a line's length (`MAX_LINE_BYTES`).
    #[error(
        "line of {bytes} bytes, longer than volcomp's limit of {limit} bytes (LinuxCNC reads at most 254 characters: \"Command too long\")"
    )]
    LineTooLong {
        /// The line's length (bytes).
        bytes: usize,
        /// The limit (bytes).
        limit: usize,
    },
    /// volcomp's limit on repeated work ([`super::LanguageOptions::max_loop_lines`],
    /// [`super::LanguageOptions::max_generated_moves`]).
    #[error("more than {limit} {what}{}: an endless or runaway loop? ({option} N raises the limit)", if within.is_empty() { String::new() } else { format!(", in {within}") })]
    LoopLimit {
        /// The limit passed.
        limit: u64,
        /// What was counted (lines in loops and calls, generated moves).
        what: &'static str,
        /// The command-line option that raises the limit.
        option: &'static str,
        /// The innermost loop running (e.g. `` `o1 while` (line 3) ``), or empty.
        within: String,
    },
    /// The up-front estimate of a canned cycle in `repeat` loops.
    #[error("this block would generate about {estimate:.3e} moves ({per_block} per execution × {trips:.0} executions{}), more than the limit of {limit} ({option} N raises it)", if within.is_empty() { String::new() } else { format!(" of {within}") })]
    MovesEstimate {
        /// The estimated number of moves (`per_block` × `trips`).
        estimate: f64,
        /// The moves one execution of the block generates.
        per_block: usize,
        /// How many times the enclosing `repeat` loops run the block.
        trips: f64,
        /// The limit on generated moves.
        limit: u64,
        /// The command-line option that raises the limit.
        option: &'static str,
        /// The innermost loop running (e.g. `` `o1 while` (line 3) ``), or empty.
        within: String,
    },
    /// A carriage return inside a line (the file's line ends are CR only).
    #[error("carriage return inside the line: the file has CR-only (classic Mac) line ends")]
    BareCarriageReturn,
    /// The file starts with a UTF-8 byte order mark, which LinuxCNC refuses.
    #[error("Bad character '\\357' used: the file starts with a UTF-8 byte order mark (EF BB BF)")]
    ByteOrderMark,
    /// A tool number (the number) the tool table does not hold.
    #[error("Requested tool {0} not found in the tool table")]
    ToolNotInTable(u32),
    /// A tool word (the letter: T, H, Q…) whose value is not a whole number
    /// ≥ 0.
    #[error("{0} word: a tool number must be a whole number ≥ 0")]
    ToolNumber(char),
    /// G43.2 with both H and axis words, or with neither (LinuxCNC's
    /// message).
    #[error("G43.2: {0}")]
    ToolOffsetAdd(&'static str),
    /// The program or a subroutine file cannot be read (the I/O error).
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
            ErrorKind::DialectFeature(..) => {
                "docs/dialects.md lists what volcomp reads of each control's language; rewrite the block without the feature (or post-process it flat)"
            }
            ErrorKind::DialectRefused(_) => {
                "the control refuses this too (docs/dialects.md cites its manual); correct the program"
            }
            ErrorKind::SystemVariableUnknown(_) => {
                "give the value the control would have with --sysvar '$NAME=VALUE' (repeatable; docs/dialects.md, \"System variables\")"
            }
            ErrorKind::MachineNeeded(_) => "give the machine file with --machine MACHINE.toml",
            ErrorKind::ProgramErrorStop(_) => {
                "the program raised its own error here (a check of its Q parameters before it failed); its error texts say what the number means"
            }
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
    /// What went wrong.
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
    /// most `EXCERPT_BYTES` around the column.
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
