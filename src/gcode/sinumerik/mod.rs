//! The SINUMERIK 840D sl front: its syntax ([`syntax`]), its language
//! (variables [`values`], program flow and subprograms: this file) and its
//! machine-state steps (settable and programmable frames, `TRAORI`), feeding
//! LinuxCNC's machine-state layer through the `Execution` seam
//! (`gcode::front`).
//!
//! Semantics follow Siemens' SINUMERIK 840D sl programming manuals
//! (*Fundamentals*; *Job planning*), cited where a rule is decided. Each
//! executed line becomes a [`Block`] holding the words the machine-state
//! layer reads (`G` codes in LinuxCNC's numbering, axis words as absolute
//! or incremental numbers, `I J K`, `R` for `CR=`, `F`, `S`, `T`, `M`),
//! each with its byte range in the line, so that writers change only the
//! words they must (a word written `X=R1+2` is written back `X=12.5`).
//!
//! - **Literal and flat lines.** A line of the main program read once, in
//!   sequence, is handed on as written; once the program has run any flow
//!   (a jump, a loop, a call, `IF`), a line whose values come from
//!   variables is handed on flat: its values as numbers, its assignments
//!   and definitions dropped, `; volcomp: line N` appended (so the control,
//!   running the written program, needs none of the variables the flow
//!   changed). Lines run again (loops, backward jumps) and subprogram lines
//!   are always flat. Flow statements (`IF`, `WHILE`, `GOTOF`, calls…) are
//!   not written: the blocks they run are.
//! - **Frames** (*Fundamentals*, "Coordinate transformations (frames)"):
//!   the settable frame `G54`–`G57` (its shift from `--offset`; `G500`
//!   none) then the programmable frame. An absolute statement (`TRANS`,
//!   `ROT`, `SCALE`, `MIRROR`) replaces the whole programmable frame; an
//!   additive one (`ATRANS`, `AROT`, `ASCALE`, `AMIRROR`) acts in the frame
//!   as it stands. `ROT`'s angles turn about Z, then the new Y, then the new
//!   X (the control's default RPY order). `SUPA`, `G53`, `G153` suppress the
//!   frames for their block.
//! - **Five-axis**: `TRAORI` … `TRAFOOF` switch the part frame (tool-tip
//!   programs with orientation by machine axes, by vector `A3= B3= C3=` or
//!   by angles `A2= B2= C2=`, solved on the machine's chain);
//!   `CYCLE800` swivelled planes axis by axis. The features listed in
//!   `docs/dialects.md` as not read are located errors naming the feature.
//! - **Circles** without a centre (`CIP`, `CT`, `AR=`, `TURN=`) are worked
//!   out into the centre form and handed on flat.
pub(crate) mod circles;
pub(crate) mod corners;
pub(crate) mod cycle800;
pub(crate) mod orientation;
pub(crate) mod splines;
pub(crate) mod syntax;
pub(crate) mod values;

use std::collections::HashMap;
use std::io::Seek;
use std::path::{Path, PathBuf};

use crate::gcode::NamedTool;
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::language::{Executed, LanguageOptions, ProgramInput};
use crate::gcode::machine::interpret::Interpreter;
use crate::gcode::machine::origin::FrameTransform;
use crate::gcode::syntax::block::{Block, Keyword, KeywordWord, LineEnding, Word};
use syntax::{Cursor, Expr, Tok, Token};
use values::{R_COUNT, Scope, VarType, Variable};

/// Most program levels (main program and subprograms) open at once (the
/// 840D sl's 16 levels).
const MAX_LEVELS: usize = 16;

/// A program file held in memory, split into lines.
struct SourceFile {
    /// Its name in messages.
    name: String,
    /// The name a subprogram was called by (empty for the main program).
    called_as: String,
    /// The file's bytes.
    text: Vec<u8>,
    /// Where each line starts (its end and ending are read from the text
    /// at the next line's start: [`SourceFile::line`]).
    lines: Vec<usize>,
    /// The partner line of each structured statement (IF → ELSE/ENDIF,
    /// ELSE → ENDIF, WHILE ↔ ENDWHILE, FOR ↔ ENDFOR, REPEAT ↔ UNTIL,
    /// LOOP ↔ ENDLOOP), by line (only those lines: a program of moves
    /// has none).
    partner: HashMap<usize, usize>,
    /// Labels (`NAME:`) by name, upper-cased → line index.
    labels: HashMap<String, usize>,
    /// A main program read as it runs ([`SourceFile::streamed`]): `text`
    /// then holds the line read last, `lines` nothing.
    stream: Option<Box<MainStream>>,
}

/// The reading of a streamed main program.
struct MainStream {
    lines: crate::gcode::streamed_program::LineStream,
    /// Its number of lines.
    count: usize,
    /// The line in `text`.
    loaded: Option<crate::gcode::streamed_program::StreamedLine>,
}

/// Whether a line may move the run to another line of its file, or need
/// the whole file's structure: a label or main block number (`:`), a
/// structured statement, a jump, `CASE`, a section repeat (any of their
/// names anywhere in the line's code, in any case: a line this cannot tell
/// is taken as one).
fn may_leave_the_sequence(raw: &[u8]) -> bool {
    if !flagged(raw) {
        return false;
    }
    let code = match memchr::memchr(b';', raw) {
        Some(c) if !raw[..c].contains(&b'"') => &raw[..c],
        _ => raw,
    };
    if memchr::memchr(b':', code).is_some() {
        return true;
    }
    const NAMES: [&[u8]; 9] = [
        b"GOTO", b"CASE", b"REPEAT", b"IF", b"ELSE", b"WHILE", b"FOR", b"UNTIL", b"LOOP",
    ];
    (0..code.len()).any(|i| {
        matches!(
            code[i].to_ascii_uppercase(),
            b'G' | b'C' | b'R' | b'I' | b'E' | b'W' | b'F' | b'U' | b'L'
        ) && NAMES
            .iter()
            .any(|n| code.len() - i >= n.len() && code[i..i + n.len()].eq_ignore_ascii_case(n))
    })
}

/// Whether `bytes` (a line, or a run of lines) has a byte that may start
/// what [`may_leave_the_sequence`] looks for: each of its names has an O,
/// I, S or P; a label a `:`; a string a `"`. Most lines of moves have none
/// (one pass over the bytes, no early exit, so that it runs as vector
/// compares).
fn flagged(bytes: &[u8]) -> bool {
    let flag = |b: u8| {
        let l = b | 0x20;
        u8::from(l == b'o')
            | u8::from(l == b'i')
            | u8::from(l == b's')
            | u8::from(l == b'p')
            | u8::from(b == b':')
            | u8::from(b == b'"')
    };
    // Whole 32-byte chunks only: the tail is the line's last 32 bytes
    // (read twice where they overlap a chunk), a line shorter than 32
    // bytes is padded with spaces (which no flag sees).
    let fold32 = |chunk: &[u8; 32]| chunk.iter().fold(0u8, |f, &b| f | flag(b));
    let mut flagged = 0u8;
    if bytes.len() >= 32 {
        let mut chunks = bytes.chunks_exact(32);
        for chunk in &mut chunks {
            flagged |= chunk.iter().fold(0u8, |f, &b| f | flag(b));
        }
        if let Some(tail) = bytes
            .last_chunk::<32>()
            .filter(|_| !chunks.remainder().is_empty())
        {
            flagged |= fold32(tail);
        }
    } else {
        let mut padded = [b' '; 32];
        padded[..bytes.len()].copy_from_slice(bytes);
        flagged = fold32(&padded);
    }
    flagged != 0
}

/// The kind of a structured statement (the line's first name).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Structure {
    If,
    Else,
    EndIf,
    While,
    EndWhile,
    For,
    EndFor,
    Repeat,
    Until,
    Loop,
    EndLoop,
}

impl Structure {
    fn of(name: &str) -> Option<Structure> {
        Some(match name {
            "IF" => Structure::If,
            "ELSE" => Structure::Else,
            "ENDIF" => Structure::EndIf,
            "WHILE" => Structure::While,
            "ENDWHILE" => Structure::EndWhile,
            "FOR" => Structure::For,
            "ENDFOR" => Structure::EndFor,
            "REPEAT" => Structure::Repeat,
            "UNTIL" => Structure::Until,
            "LOOP" => Structure::Loop,
            "ENDLOOP" => Structure::EndLoop,
            _ => return None,
        })
    }

    fn opener(self) -> Option<Structure> {
        Some(match self {
            Structure::EndIf | Structure::Else => Structure::If,
            Structure::EndWhile => Structure::While,
            Structure::EndFor => Structure::For,
            Structure::Until => Structure::Repeat,
            Structure::EndLoop => Structure::Loop,
            _ => return None,
        })
    }

    fn closer_name(self) -> &'static str {
        match self {
            Structure::If | Structure::Else => "ENDIF",
            Structure::While => "ENDWHILE",
            Structure::For => "ENDFOR",
            Structure::Repeat => "UNTIL",
            Structure::Loop => "ENDLOOP",
            _ => "",
        }
    }
}

/// The start of a line as the structure scan reads it: where the
/// statements begin (after `/`, the block number and a label), the label,
/// and the first name.
struct LineHead<'a> {
    label: Option<String>,
    first: Option<&'a [u8]>,
    rest: &'a [u8],
}

fn line_head(raw: &[u8]) -> LineHead<'_> {
    let mut i = 0;
    let skip_ws = |i: &mut usize| {
        while *i < raw.len() && matches!(raw[*i], b' ' | b'\t') {
            *i += 1;
        }
    };
    skip_ws(&mut i);
    if raw.get(i) == Some(&b'/') {
        i += 1;
        while i < raw.len() && raw[i].is_ascii_digit() {
            i += 1;
        }
        skip_ws(&mut i);
    }
    if raw
        .get(i)
        .is_some_and(|b| b.eq_ignore_ascii_case(&b'N') || *b == b':')
        && raw.get(i + 1).is_some_and(u8::is_ascii_digit)
    {
        i += 1;
        while i < raw.len() && raw[i].is_ascii_digit() {
            i += 1;
        }
        skip_ws(&mut i);
    }
    let name_at = |i: usize| {
        let mut j = i;
        while j < raw.len() && (raw[j].is_ascii_alphanumeric() || raw[j] == b'_') {
            j += 1;
        }
        j
    };
    let mut label = None;
    if raw
        .get(i)
        .is_some_and(|b| b.is_ascii_alphabetic() || *b == b'_')
    {
        let j = name_at(i);
        if raw.get(j) == Some(&b':') && j - i >= 2 {
            label = Some(String::from_utf8_lossy(&raw[i..j]).to_ascii_uppercase());
            i = j + 1;
            skip_ws(&mut i);
        }
    }
    let first = if raw.get(i).is_some_and(|b| b.is_ascii_alphabetic()) {
        let j = name_at(i);
        Some(&raw[i..j])
    } else {
        None
    };
    LineHead {
        label,
        first,
        rest: &raw[i..],
    }
}

impl SourceFile {
    /// Split `text` into lines and match its structured statements.
    fn new(name: String, text: Vec<u8>) -> Result<SourceFile, GcodeError> {
        let mut lines = Vec::with_capacity(memchr::memchr_iter(b'\n', &text).count() + 1);
        let mut start = 0;
        while start < text.len() {
            lines.push(start);
            start = memchr::memchr(b'\n', &text[start..]).map_or(text.len(), |k| start + k + 1);
        }
        let mut f = SourceFile {
            name,
            called_as: String::new(),
            partner: HashMap::new(),
            lines,
            text,
            labels: HashMap::new(),
            stream: None,
        };
        f.scan()?;
        Ok(f)
    }

    /// The main program read from `input` as it runs, when no line of it
    /// may leave the sequence ([`may_leave_the_sequence`]: no labels, no
    /// structures, so nothing to match): what [`SourceFile::new`] would
    /// give, line by line. `Err`: the input, back where it was, to be read
    /// whole.
    fn streamed(
        name: &str,
        mut input: Box<dyn ProgramInput>,
    ) -> Result<SourceFile, Box<dyn ProgramInput>> {
        let Ok(start) = input.stream_position() else {
            return Err(input);
        };
        // A run of lines without a flagged byte has no line that may leave
        // the sequence: counted at once.
        let scan = crate::gcode::streamed_program::scan_lines_skipping(
            &mut input,
            |run| !flagged(run),
            |raw, _| !may_leave_the_sequence(raw),
        );
        // Back to the start: read again as it runs, or whole (where an
        // error of the input is the held path's).
        let back = input.seek(std::io::SeekFrom::Start(start));
        let (Ok(Some(count)), Ok(_)) = (scan, back) else {
            return Err(input);
        };
        let lines = crate::gcode::streamed_program::LineStream::new(input, start);
        Ok(SourceFile {
            name: name.to_string(),
            called_as: String::new(),
            text: Vec::new(),
            lines: Vec::new(),
            partner: HashMap::new(),
            labels: HashMap::new(),
            stream: Some(Box::new(MainStream {
                lines,
                count,
                loaded: None,
            })),
        })
    }

    /// Its number of lines.
    fn count(&self) -> usize {
        match &self.stream {
            Some(s) => s.count,
            None => self.lines.len(),
        }
    }

    /// Make line `k` readable ([`SourceFile::line`]): a streamed file reads
    /// it (the next line, or from the start again).
    fn load(&mut self, k: usize) -> Result<(), GcodeError> {
        let Some(s) = &mut self.stream else {
            return Ok(());
        };
        if s.loaded.is_some_and(|l| l.index == k) {
            return Ok(());
        }
        s.loaded = None;
        match s.lines.read_line(k, &mut self.text) {
            Ok(line) => {
                s.loaded = line;
                Ok(())
            }
            Err(e) => Err(GcodeError::at(
                ErrorKind::Io(e.to_string()),
                k + 1,
                b"",
                0,
                0,
            )),
        }
    }

    /// Where line `k` starts in the file.
    fn offset(&self, k: usize) -> u64 {
        match &self.stream {
            Some(s) => s.loaded.map_or(0, |l| l.offset),
            None => self.lines[k] as u64,
        }
    }

    /// Line `k`: its start, its end (without its ending) and its ending
    /// in `text` (a streamed file: the line [`SourceFile::load`] read, empty
    /// for any other).
    fn line(&self, k: usize) -> (usize, usize, LineEnding) {
        if let Some(s) = &self.stream {
            return match s.loaded {
                Some(l) if l.index == k => (0, l.len, l.ending),
                _ => (0, 0, LineEnding::None),
            };
        }
        let start = self.lines[k];
        let next = self.lines.get(k + 1).copied().unwrap_or(self.text.len());
        if next > start && self.text[next - 1] == b'\n' {
            let eol = next - 1;
            if eol > start && self.text[eol - 1] == b'\r' {
                (start, eol - 1, LineEnding::CrLf)
            } else {
                (start, eol, LineEnding::Lf)
            }
        } else {
            (start, next, LineEnding::None)
        }
    }

    fn raw(&self, k: usize) -> &[u8] {
        let (s, e, _) = self.line(k);
        &self.text[s..e]
    }

    /// Match IF/ELSE/ENDIF, WHILE/ENDWHILE, FOR/ENDFOR, REPEAT/UNTIL,
    /// LOOP/ENDLOOP; collect labels. An opener without its closer (or a
    /// closer without its opener) is a located error (*Job planning*,
    /// "Program sequence control": the control checks the nesting when it
    /// reads the program).
    fn scan(&mut self) -> Result<(), GcodeError> {
        let mut open: Vec<(Structure, usize)> = Vec::new();
        let mut labels = std::mem::take(&mut self.labels);
        let result = self.scan_lines(&mut open, &mut labels);
        self.labels = labels;
        result?;
        if let Some(&(s, at)) = open.last() {
            return Err(self.structure_error(
                at,
                format!(
                    "{} is never closed: no {} follows in {}",
                    opener_name(s),
                    s.closer_name(),
                    self.name
                ),
            ));
        }
        Ok(())
    }

    fn scan_lines(
        &mut self,
        open: &mut Vec<(Structure, usize)>,
        labels: &mut HashMap<String, usize>,
    ) -> Result<(), GcodeError> {
        for k in 0..self.lines.len() {
            let (ls, le, _) = self.line(k);
            let raw = &self.text[ls..le];
            let head = line_head(raw);
            if let Some(label) = head.label.clone() {
                labels.entry(label).or_insert(k);
            }
            let Some(first) = head.first else { continue };
            // The longest structure name is 8 letters: a longer first name (or
            // a motion word such as `G1`) is none, without allocating.
            let mut buf = [0u8; 8];
            let Some(upper_first) = buf.get_mut(..first.len()) else {
                continue;
            };
            for (u, b) in upper_first.iter_mut().zip(first) {
                *u = b.to_ascii_uppercase();
            }
            let Some(s) = Structure::of(std::str::from_utf8(upper_first).unwrap_or("")) else {
                continue;
            };
            let name = first.to_ascii_uppercase();
            let upper = head.rest.to_ascii_uppercase();
            let code = match upper.iter().position(|&b| b == b';') {
                Some(c) => &upper[..c],
                None => &upper[..],
            };
            // `IF cond GOTOF label` jumps; `REPEAT label P=n` repeats a section.
            if s == Structure::If && code.windows(4).any(|w| w == b"GOTO") {
                continue;
            }
            if s == Structure::Repeat
                && code[first.len()..]
                    .iter()
                    .any(|b| b.is_ascii_alphanumeric())
            {
                continue;
            }
            match s.opener() {
                None => open.push((s, k)),
                Some(opener) => {
                    let Some(&(o, at)) = open.last() else {
                        return Err(self.structure_error(
                            k,
                            format!(
                                "{} without its {}",
                                String::from_utf8_lossy(&name),
                                opener_name(opener)
                            ),
                        ));
                    };
                    if o != opener && !(s == Structure::EndIf && o == Structure::Else) {
                        return Err(self.structure_error(
                            k,
                            format!(
                                "{} closes the {} of line {}",
                                String::from_utf8_lossy(&name),
                                opener_name(o),
                                at + 1
                            ),
                        ));
                    }
                    open.pop();
                    self.partner.insert(at, k);
                    if s == Structure::Else {
                        open.push((Structure::Else, k));
                    } else {
                        self.partner.insert(k, at);
                    }
                }
            }
        }
        Ok(())
    }

    fn structure_error(&self, k: usize, message: String) -> GcodeError {
        let raw = self.raw(k);
        GcodeError::at(ErrorKind::DialectRefused(message), k + 1, raw, 0, raw.len())
    }
}

fn opener_name(s: Structure) -> &'static str {
    match s {
        Structure::If => "IF",
        Structure::Else => "ELSE",
        Structure::While => "WHILE",
        Structure::For => "FOR",
        Structure::Repeat => "REPEAT",
        Structure::Loop => "LOOP",
        _ => "?",
    }
}

#[cfg(test)]
mod streaming_tests {
    #[test]
    fn lines_that_may_leave_the_sequence_are_found() {
        use super::may_leave_the_sequence as leaves;
        for line in [
            "N10 G1 X1 Y2 Z3 A0 C0 F800",
            "G0 X0 Y0 Z20 ; a comment",
            "T1 M6 S1000 M3",
            "R1=R1+1",
        ] {
            assert!(!leaves(line.as_bytes()), "{line}");
        }
        for line in [
            "N10 gotob start",
            "START: G1 X1",
            "IF R1>2",
            "endwhile",
            "N20 REPEATB A P=2",
            "CASE R1 OF 1 GOTOF A DEFAULT GOTOF B",
            "LOOP",
            "MSG(\"a;\") GOTOF A",
        ] {
            assert!(leaves(line.as_bytes()), "{line}");
        }
    }
}

/// One program level: a file being run, where, its variables, its repeats.
struct Level {
    file: usize,
    /// The next line to read.
    next: usize,
    scope: Scope,
    /// Repetitions left after this run (`P=n`).
    repeats_left: u64,
    /// The name it was called by (recursion check, messages).
    name: String,
    /// A FOR line being re-entered from its ENDFOR (no re-initialisation).
    for_continue: Option<usize>,
    /// A motion block has run at this level (DEF must come before).
    moved: bool,
    /// Program sections being repeated (`REPEAT`, `REPEATB`), innermost last.
    sections: Vec<Section>,
    /// `VAR` parameters (by reference): the parameter and the caller's
    /// variable it stands for, written back when the level returns.
    by_ref: Vec<(String, Target)>,
}

/// A subprogram call of a block: the program's name, the arguments (each
/// with the variable it names, for `VAR` parameters), the call's span.
type Call = (String, Vec<(f64, Option<Target>)>, (usize, usize));

/// A caller's variable a `VAR` parameter refers to: an `R` parameter, or
/// an element (flat index; 0 for a scalar) of a variable of the caller.
#[derive(Clone, Debug)]
enum Target {
    R(usize),
    Var(String, usize),
    /// A whole array of the caller (a `VAR` array parameter).
    Array(String),
}

/// A program section `REPEAT label [label2] P=n` / `REPEATB label P=n` runs
/// (*Job planning*, "Program section repetition (REPEAT, REPEATB, ENDLABEL,
/// P)"): lines `start..=end` of the level's file, `left` more runs, then on
/// at `resume` (the line after the `REPEAT`).
#[derive(Clone, Copy, Debug)]
struct Section {
    start: usize,
    end: usize,
    left: u64,
    resume: usize,
}

/// The swivelled plane (`CYCLE800`) and the programmable frame.
#[derive(Clone, Copy, Debug)]
struct Frames {
    swivel: Option<FrameTransform>,
    programmable: FrameTransform,
}

/// The SINUMERIK front: reads the program into memory, runs its language,
/// hands on executed blocks.
pub(crate) struct SinumerikFront {
    files: Vec<SourceFile>,
    load_error: Option<GcodeError>,
    levels: Vec<Level>,
    r: Vec<f64>,
    block: Block,
    executed: Executed,
    options: LanguageOptions,
    main_dir: Option<PathBuf>,
    /// Lines of the main file read in sequence so far (index of the next).
    frontier: usize,
    /// Flow has run: values from variables are written flat from here on.
    flowed: bool,
    ended: bool,
    returned: bool,
    tail: usize,
    finished: bool,
    /// Lines read in loops, again, or in subprograms (bounded).
    loop_lines: u64,
    max_loop_lines: u64,
    frames: Frames,
    /// The origins of the settable frames `G505`–`G599` (`--offset`).
    settable_frames: std::collections::BTreeMap<u16, crate::axes::Axes>,
    /// Tool axis ↔ rotary joints from the machine (`CYCLE800`).
    orientation: Option<std::sync::Arc<dyn crate::gcode::OrientationSolver>>,
    /// The program switched `TRAORI` on itself.
    traori: bool,
    /// How orientations are given and interpolated (`ORIEULER`/`ORIRPY`,
    /// `ORIWKS`/`ORIMKS`, `ORIVECT`/`ORIAXES`).
    ori: OriModes,
    /// The modal `CIP` or `CT` (motion group 1 with G0–G3).
    arc_form: Option<ArcForm>,
    /// The last move's start and, for an arc whose centre is known, its
    /// centre and sense (`CT` continues tangentially from it).
    last_move: Option<LastMove>,
    incremental: bool,
    skip_deleted: bool,
    motion_set: bool,
    /// The letters of the machine's axes, one bit each (bit 0: `A`): set
    /// with the reset state before the first block.
    machine_axis_letters: u32,
    /// The frames changed: set them on the interpreter before the block.
    flush_frame_later: bool,
    tokens: Vec<Token>,
    text: String,
    /// The line being run (reused).
    line_buf: Vec<u8>,
    /// The words buffer of the block handed on before (reused by the next line).
    spare_words: Vec<Word>,
    /// The words of a plain line (reused).
    plain: Vec<syntax::PlainWord>,
    /// Flat pieces of the line just handed on, handed on next (a block
    /// split on the great circle, `orientation`).
    pending: std::collections::VecDeque<Block>,
    /// A circle handed on as chords left the control in `G2`/`G3`: the
    /// next motion block without a motion word gets it back (`circles`).
    restore_arc: Option<f64>,
    /// This line's circle was handed on as chords.
    chorded: bool,
    /// System variables given a value (`--sysvar`), by their normalised text.
    system_variables: std::collections::BTreeMap<String, f64>,
    /// The active tool's number once the program changed tools (`$P_TOOLNO`).
    state_tool: Option<f64>,
    /// The active cutting edge once the program chose one (`$P_TOOL`).
    state_edge: Option<f64>,
    /// The tool the last `T` preselected (made active by `M6`).
    preselected_tool: Option<f64>,
    /// The open `BSPLINE` section (`splines`).
    spline: Option<splines::SplineSection>,
    /// The B spline's degree (`SD=`, 3 at reset).
    spline_degree: usize,
    /// The blocks of a closed section, handed on next.
    spline_out: std::collections::VecDeque<(Block, Executed)>,
    /// The circle in space this line handed on: its centre and normal.
    space_arc: Option<([f64; 3], [f64; 3])>,
    /// Where this line's orientation words turn the tool (`circles` hands a
    /// circle that turns it on in pieces).
    turn_end: Option<orientation::OrientationEnd>,
    /// Contour corners `RND=`/`CHF=` (`corners`): the element held for
    /// its corner, `RNDM=`, `FRCM=`.
    corners: corners::Corners,
}

impl SinumerikFront {
    /// The front for the main program read from `input`.
    pub(crate) fn new(
        input: Box<dyn ProgramInput>,
        path: &Path,
        language: LanguageOptions,
        setup: &crate::gcode::ProgramSetup,
    ) -> SinumerikFront {
        let name = path.display().to_string();
        let mut load_error = None;
        let main = match SourceFile::streamed(&name, input) {
            Ok(f) => f,
            Err(mut input) => {
                let mut text = Vec::new();
                if let Err(e) = input.read_to_end(&mut text) {
                    load_error = Some(GcodeError::at(ErrorKind::Io(e.to_string()), 1, b"", 0, 0));
                }
                match SourceFile::new(name.clone(), text) {
                    Ok(f) => f,
                    Err(e) => {
                        load_error.get_or_insert(e);
                        SourceFile {
                            name,
                            called_as: String::new(),
                            text: Vec::new(),
                            lines: Vec::new(),
                            partner: HashMap::new(),
                            labels: HashMap::new(),
                            stream: None,
                        }
                    }
                }
            }
        };
        SinumerikFront {
            files: vec![main],
            load_error,
            levels: vec![Level {
                file: 0,
                next: 0,
                scope: Scope {
                    vars: HashMap::new(),
                },
                repeats_left: 0,
                name: String::new(),
                for_continue: None,
                moved: false,
                sections: Vec::new(),
                by_ref: Vec::new(),
            }],
            r: vec![0.0; R_COUNT],
            block: Block::default(),
            executed: Executed {
                file: 0,
                line: 0,
                literal: true,
                passed: false,
            },
            max_loop_lines: language
                .max_loop_lines
                .unwrap_or(crate::gcode::language::DEFAULT_MAX_LOOP_LINES),
            main_dir: path.parent().map(Path::to_path_buf),
            options: language,
            frontier: 0,
            flowed: false,
            ended: false,
            returned: false,
            tail: 0,
            finished: false,
            loop_lines: 0,
            frames: Frames {
                swivel: None,
                programmable: FrameTransform::IDENTITY,
            },
            orientation: setup.orientation.clone(),
            settable_frames: setup.settable_frames.clone(),
            traori: false,
            ori: OriModes::default(),
            arc_form: None,
            last_move: None,
            incremental: false,
            skip_deleted: false,
            motion_set: false,
            machine_axis_letters: 0,
            flush_frame_later: false,
            tokens: Vec::new(),
            text: String::new(),
            line_buf: Vec::new(),
            spare_words: Vec::new(),
            plain: Vec::new(),
            pending: std::collections::VecDeque::new(),
            restore_arc: None,
            chorded: false,
            system_variables: setup.system_variables.clone(),
            state_tool: None,
            state_edge: None,
            preselected_tool: None,
            spline: None,
            spline_degree: 3,
            spline_out: std::collections::VecDeque::new(),
            space_arc: None,
            turn_end: None,
            corners: corners::Corners::default(),
        }
    }

    pub(crate) fn block(&self) -> &Block {
        &self.block
    }

    pub(crate) fn executed(&self) -> &Executed {
        &self.executed
    }

    pub(crate) fn file_name(&self, index: usize) -> &str {
        self.files.get(index).map_or("?", |f| f.name.as_str())
    }

    pub(crate) fn end_program(&mut self) {
        self.ended = true;
        let level = &self.levels[0];
        self.tail = if self.levels.len() == 1 {
            level.next
        } else {
            usize::MAX
        };
    }

    /// The program ended by `RET`/`M17` in the main program (as a closing
    /// `%` ends a LinuxCNC program).
    pub(crate) fn percent_ended(&self) -> bool {
        self.returned
    }

    pub(crate) fn lines_read(&self) -> usize {
        self.frontier
    }

    pub(crate) fn innermost_loop(&self) -> Option<String> {
        self.levels
            .last()
            .filter(|_| self.levels.len() > 1)
            .map(|l| format!("the call of `{}`", l.name))
    }

    /// After the end: the main file's next line, as written.
    pub(crate) fn next_tail_line(&mut self) -> Option<Result<(), GcodeError>> {
        if self.tail >= self.files[0].count() {
            return None;
        }
        let k = self.tail;
        self.tail += 1;
        if let Err(e) = self.files[0].load(k) {
            return Some(Err(e));
        }
        let main = &self.files[0];
        let (s, e, ending) = main.line(k);
        self.block.reset(k + 1, main.offset(k));
        self.block.raw.extend_from_slice(&main.text[s..e]);
        self.block.ending = ending;
        self.executed = Executed {
            file: 0,
            line: k + 1,
            literal: true,
            passed: false,
        };
        Some(Ok(()))
    }

    /// The next executed block (then [`Self::block`]), `None` at the end.
    pub(crate) fn next_block(
        &mut self,
        interpreter: &mut Interpreter,
    ) -> Option<Result<(), GcodeError>> {
        if let Some(e) = self.load_error.take() {
            self.finished = true;
            return Some(Err(e));
        }
        if self.next_spline_block() {
            return Some(Ok(()));
        }
        if self.finished || self.ended || self.returned {
            if !self.finished && self.corners.waiting() {
                self.finished = true;
                return self.corner_at_the_end().map(Err);
            }
            return None;
        }
        if let Some(mut piece) = self.pending.pop_front() {
            // The next piece of the line just handed on (same line, flat).
            piece.line = self.block.line;
            piece.offset = self.block.offset;
            piece.ending = match self.block.ending {
                LineEnding::None => LineEnding::Lf,
                e => e,
            };
            self.block = piece;
            self.executed.literal = false;
            return Some(Ok(()));
        }
        if !self.motion_set {
            // The 840D sl starts in G0 (its reset G codes: G0 G17 G90 G94 G71).
            self.motion_set = true;
            let axes = interpreter.options().axes;
            self.machine_axis_letters = crate::axes::Axis::ALL
                .into_iter()
                .filter(|&axis| axes.contains(axis))
                .fold(0, |bits, axis| bits | 1 << (axis.letter() as u8 - b'A'));
            let mut start = Block::default();
            start.words.push(Word {
                letter: b'G',
                value: 0.0,
                start: 0,
                end: 0,
                decimals: 0,
                point: false,
                expr: None,
            });
            let _ = interpreter.interpret(&start);
            // And without a settable frame (G500) until G54–G57.
            interpreter.set_work_origin(crate::axes::Axes::default());
        }
        self.skip_deleted = interpreter.options().skip_deleted_blocks;
        loop {
            match self.step(interpreter) {
                Ok(Some(true)) => return Some(Ok(())),
                Ok(Some(false)) if self.next_spline_block() => return Some(Ok(())),
                Ok(Some(false)) => continue,
                Ok(None) if self.corners.waiting() => {
                    self.finished = true;
                    return self.corner_at_the_end().map(Err);
                }
                Ok(None) if self.spline.is_some() => {
                    // The program ends in a BSPLINE section.
                    if let Err(e) = self.close_spline(interpreter) {
                        self.finished = true;
                        return Some(Err(e));
                    }
                    if self.next_spline_block() {
                        return Some(Ok(()));
                    }
                    self.finished = true;
                    return None;
                }
                Ok(None) => {
                    self.finished = true;
                    return None;
                }
                Err(e) => {
                    self.finished = true;
                    let level = self.levels.last().map_or(0, |l| l.file);
                    return Some(Err(if level > 0 {
                        e.with_path(&self.files[level].name)
                    } else {
                        e
                    }));
                }
            }
        }
    }

    /// Read and run one line: `Some(true)` when a block is handed on,
    /// `Some(false)` when the line is not (flow, empty flat), `None` at the
    /// end of the main program.
    fn step(&mut self, interpreter: &mut Interpreter) -> Result<Option<bool>, GcodeError> {
        if self.corners.waiting() {
            self.run_held_element(interpreter)?;
        }
        let depth = self.levels.len() - 1;
        // The end of a repeated section: again from its start, or on after
        // its `REPEAT`.
        {
            let l = &mut self.levels[depth];
            if let Some(sec) = l.sections.last_mut()
                && l.next == sec.end + 1
            {
                if sec.left > 1 {
                    sec.left -= 1;
                    l.next = sec.start;
                } else {
                    l.next = sec.resume;
                    l.sections.pop();
                }
                l.for_continue = None;
            }
        }
        let (file, k) = {
            let l = &self.levels[depth];
            (l.file, l.next)
        };
        if k >= self.files[file].count() {
            if depth == 0 {
                return Ok(None);
            }
            self.return_from_level(None)?;
            return Ok(Some(false));
        }
        self.levels[depth].next = k + 1;
        self.files[file].load(k)?;
        let first_reading = file == 0 && depth == 0 && k >= self.frontier;
        if first_reading {
            self.frontier = k + 1;
        } else {
            self.loop_lines += 1;
            if self.loop_lines > self.max_loop_lines {
                let raw = self.files[file].raw(k).to_vec();
                return Err(GcodeError::at(
                    ErrorKind::LoopLimit {
                        limit: self.max_loop_lines,
                        what: "lines read in loops, jumps and subprogram calls",
                        option: "--max-loop-lines",
                        within: self.innermost_loop().unwrap_or_default(),
                    },
                    k + 1,
                    &raw,
                    0,
                    raw.len(),
                ));
            }
        }
        let (s, e, ending) = self.files[file].line(k);
        if self.spline.is_some() && self.line_ends_spline(file, s, e) {
            // Close the section first; the line runs again after it.
            self.levels[depth].next = k;
            if first_reading {
                self.frontier = k;
            } else {
                self.loop_lines -= 1;
            }
            self.close_spline(interpreter)?;
            return Ok(Some(false));
        }
        let offset = self.files[file].offset(k);
        let mut raw = std::mem::take(&mut self.line_buf);
        raw.clear();
        let streamed = self.files[file].stream.is_some();
        if streamed {
            // The line read is the file's text: run it there, no copy.
            std::mem::swap(&mut raw, &mut self.files[file].text);
            raw.truncate(e);
        } else {
            raw.extend_from_slice(&self.files[file].text[s..e]);
        }
        let mut line = LineRun {
            raw: &raw,
            line: k + 1,
            file,
            first_reading,
        };
        let handed = self.run_line(&mut line, interpreter);
        if streamed {
            // Back (without its ending, which `line` no longer reads).
            std::mem::swap(&mut raw, &mut self.files[file].text);
        }
        self.line_buf = raw;
        let handed = handed?;
        if handed {
            self.block.line = k + 1;
            self.block.offset = offset;
            self.block.ending = if first_reading && self.pending.is_empty() {
                ending
            } else if ending == LineEnding::None {
                LineEnding::Lf
            } else {
                ending
            };
            self.executed = Executed {
                file,
                line: k + 1,
                literal: self.executed.literal,
                passed: false,
            };
            if self.corners.busy() && self.after_corner_block(interpreter, true)? {
                return Ok(Some(false));
            }
            if self.hold_in_spline() {
                return Ok(Some(false));
            }
        } else if self.corners.busy() {
            self.after_corner_block(interpreter, false)?;
        }
        Ok(Some(handed))
    }

    /// Whether the line at `s..e` of `file` ends the open `BSPLINE`
    /// section ([`splines::ends_section`]).
    #[inline(never)]
    fn line_ends_spline(&mut self, file: usize, s: usize, e: usize) -> bool {
        let mut tokens = std::mem::take(&mut self.tokens);
        let ends = syntax::tokenize(&self.files[file].text[s..e], &mut tokens).is_ok()
            && splines::ends_section(&tokens);
        self.tokens = tokens;
        ends
    }

    #[cold]
    fn error(&self, line: &LineRun, kind: ErrorKind, start: usize, end: usize) -> GcodeError {
        GcodeError::at(kind, line.line, line.raw, start, end)
    }

    #[cold]
    fn feature(&self, line: &LineRun, what: &str, start: usize, end: usize) -> GcodeError {
        self.error(
            line,
            ErrorKind::DialectFeature("Sinumerik", what.to_string()),
            start,
            end,
        )
    }

    #[cold]
    fn refused(&self, line: &LineRun, message: String, start: usize, end: usize) -> GcodeError {
        self.error(line, ErrorKind::DialectRefused(message), start, end)
    }

    fn eval(&self, line: &LineRun, e: &Expr, at: (usize, usize)) -> Result<f64, GcodeError> {
        let scope = &self.levels.last().expect("a level").scope;
        let system = |name: &str, at: std::ops::Range<usize>| self.system_value(line, name, at);
        values::eval(e, &self.r, scope, &system).map_err(|err| {
            let (s, t) = err.at.map_or(at, |r| (r.start, r.end));
            let kind = if err.unknown_system {
                ErrorKind::SystemVariableUnknown(err.message)
            } else {
                ErrorKind::DialectRefused(err.message)
            };
            self.error(line, kind, s, t.max(s + 1))
        })
    }

    /// The value of the system variable `name` written at `at` in the line:
    /// the execution state's where the program itself set it (`$P_TOOLNO`
    /// after a tool change, `$P_TOOL` after `D` or `M6`), else the value
    /// `--sysvar` gives its text (indices included), else an error saying
    /// how to give it.
    fn system_value(
        &self,
        line: &LineRun,
        name: &str,
        at: std::ops::Range<usize>,
    ) -> Result<f64, String> {
        let state = match name {
            "$P_TOOLNO" => self.state_tool,
            "$P_TOOL" => self.state_edge,
            _ => None,
        };
        let text = line
            .raw
            .get(at)
            .map(String::from_utf8_lossy)
            .unwrap_or_default();
        let key = crate::gcode::normalise_system_variable(&text);
        if let Some(v) = state.filter(|_| key == name) {
            return Ok(v);
        }
        self.system_variables.get(&key).copied().ok_or_else(|| {
            format!(
                "system variable `{key}` has no value offline (the control knows it at run time); give it one with --sysvar '{key}=VALUE'"
            )
        })
    }

    /// Tokenise and run one line; build the handed-on block. Returns whether
    /// a block is handed on.
    fn run_line(
        &mut self,
        line: &mut LineRun,
        interpreter: &mut Interpreter,
    ) -> Result<bool, GcodeError> {
        let raw = line.raw;
        if let Some(handed) = self.run_plain_line(line, interpreter)? {
            return Ok(handed);
        }
        let mut tokens = std::mem::take(&mut self.tokens);
        let comment = match syntax::tokenize(raw, &mut tokens) {
            Ok(c) => c,
            Err(e) => {
                self.tokens = tokens;
                return Err(self.refused(line, e.message, e.start, e.end));
            }
        };
        let result = self.run_tokens(line, &tokens, comment, interpreter);
        self.tokens = tokens;
        result
    }

    /// A plain line ([`syntax::plain_words`]: address words only, most
    /// lines of a CAM program) read without tokens: its words are what the
    /// statement layer's address path makes of them (the same [`word`]s, G
    /// codes through [`Self::g_code`]), then the statement layer finishes the
    /// block. `None`: not a plain line (or a G code that asks more of the
    /// front than a word), to be tokenised.
    fn run_plain_line(
        &mut self,
        line: &mut LineRun,
        interpreter: &mut Interpreter,
    ) -> Result<Option<bool>, GcodeError> {
        let raw = line.raw;
        let mut plain = std::mem::take(&mut self.plain);
        let comment = match syntax::plain_words(raw, &mut plain) {
            // A lone block number is handed on by the line layer, not the statements.
            Some(c) if plain.iter().any(|w| w.letter != b'N') => c,
            _ => {
                self.plain = plain;
                return Ok(None);
            }
        };
        let mut out = Out::new(raw.len());
        out.words = std::mem::take(&mut self.spare_words);
        if let Some(c) = comment {
            out.comments.push(c);
        }
        let mut letters = PlainLetters::default();
        for w in &plain {
            // (Plain letters are A–Z.)
            let bit = 1 << (w.letter - b'A');
            letters.repeated |= letters.all & bit;
            letters.all |= bit;
            let code = if w.letter == b'G' && w.value == 1.0 {
                // What `g_code` makes of `G1` (most G codes of a CAM program).
                letters.g1 = true;
                1.0
            } else if w.letter == b'G' {
                letters.other_g = true;
                let mut flags = GFlags::default();
                let code = self.g_code(line, w.value, (w.start, w.end), &mut out, &mut flags);
                match code {
                    Ok(Some(code)) if flags == GFlags::default() => code,
                    Ok(_) | Err(_) => {
                        // Read by the statement layer (dwell, frames, errors).
                        out.words.clear();
                        self.spare_words = out.words;
                        self.plain = plain;
                        return Ok(None);
                    }
                }
            } else {
                w.value
            };
            let (decimals, point) = match w.letter {
                b'N' | b'G' => (0, false),
                _ => (w.decimals, w.point),
            };
            out.words
                .push(word(w.letter, code, w.start, w.end, decimals, point, false));
        }
        self.plain = plain;
        let axis_words = letters.all & AXIS_LETTERS != 0;
        if self.quiet(line, interpreter) {
            return self
                .end_quiet_block(line, &mut out, letters, interpreter)
                .map(Some);
        }
        let mut said = Said::words_only(axis_words);
        self.end_block(line, &mut out, &mut said, interpreter)
            .map(Some)
    }

    /// Whether a plain line read now would find none of the state
    /// [`Self::end_block`] acts on beyond its words (no open `BSPLINE`
    /// section, no frame to set or to check arcs against, no modal `CIP`/
    /// `CT`, no circle to restore, no `TRAORI`), and is handed on as
    /// written: then [`Self::end_quiet_block`] ends it, doing what
    /// `end_block` does for such a line. A state `end_block` learns to act
    /// on is added here.
    fn quiet(&self, line: &LineRun, interpreter: &Interpreter) -> bool {
        line.first_reading
            && self.spline.is_none()
            && !self.flush_frame_later
            && self.arc_form.is_none()
            && self.restore_arc.is_none()
            && !self.traori
            && !self.corners.active()
            && !self.corners.busy()
            && interpreter.origin_ref().frame.is_none()
    }

    /// [`Self::end_block`] for a plain line in a quiet state
    /// ([`Self::quiet`]): its plain words (no `T`, `M`, no `=` value, G
    /// codes that set no flag) are in the line's order and need no mode
    /// resolved; a move notes where it started (`CT` after it).
    fn end_quiet_block(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        letters: PlainLetters,
        interpreter: &Interpreter,
    ) -> Result<bool, GcodeError> {
        let axis_words = letters.all & AXIS_LETTERS != 0;
        self.chorded = false;
        self.turn_end = None;
        let modal = interpreter.modal();
        if axis_words {
            let level = self.levels.len() - 1;
            self.levels[level].moved = true;
            let start = interpreter
                .origin_ref()
                .xyz_to_program_of(&interpreter.position());
            // A straight move (its last G0–G3 `G1`, or none under G0/G1):
            // what `move_of` makes of it, without reading its words again.
            use crate::gcode::machine::modal::MotionMode;
            let straight = !letters.other_g
                && (letters.g1 || !matches!(modal.motion, MotionMode::ArcCw | MotionMode::ArcCcw));
            self.last_move = if straight {
                Some(LastMove {
                    start,
                    kind: LastKind::Straight,
                })
            } else {
                self.move_of(out, interpreter, start)
            };
        }
        if letters.other_g {
            self.note_distance_mode(out);
        }
        let inert = if axis_words && letters.all & NGF_LETTERS != 0 {
            inert_letters(letters, &out.words, self.machine_axis_letters, modal)
        } else {
            0
        };
        let handed = self.hand_on(line, out, line.raw, false)?;
        if inert != 0 && handed && self.executed.literal {
            let Block {
                words,
                machine_words,
                inert_words,
                ..
            } = &mut self.block;
            machine_words.clear();
            for w in words.iter() {
                if inert & 1 << (w.letter - b'A') == 0 {
                    machine_words.push(*w);
                }
            }
            *inert_words = true;
        }
        Ok(handed)
    }

    #[inline(never)]
    fn run_tokens(
        &mut self,
        line: &mut LineRun,
        tokens: &[Token],
        comment: Option<std::ops::Range<usize>>,
        interpreter: &mut Interpreter,
    ) -> Result<bool, GcodeError> {
        let raw = line.raw;
        let mut out = Out::new(raw.len());
        out.words = std::mem::take(&mut self.spare_words);
        if let Some(c) = &comment {
            out.comments.push(c.clone());
        }
        let mut cur = Cursor::new(tokens, raw.len());
        // `%_N_PART_MPF` header lines: no statements.
        if matches!(
            cur.peek(),
            Some(Token {
                tok: Tok::Sym("%"),
                ..
            })
        ) {
            return self.hand_on(line, &mut out, raw, true);
        }
        // `/` block skip (*Fundamentals*, "Skip blocks").
        if cur.eat_sym("/") {
            if let Some(Token {
                tok: Tok::Num(..), ..
            }) = cur.peek()
            {
                cur.pos += 1;
            }
            out.deleted = true;
            if self.skip_deleted {
                return self.hand_on(line, &mut out, raw, true);
            }
        }
        // Block number `N10` or main block `:10`.
        if let (
            Some(Token {
                tok: Tok::Name(n),
                start,
                ..
            }),
            Some(Token {
                tok: Tok::Num(v, ..),
                end,
                ..
            }),
        ) = (cur.peek(), cur.peek_at(1))
            && n == "N"
        {
            out.words
                .push(word(b'N', *v, *start, *end, 0, false, false));
            cur.pos += 2;
        } else if cur.eat_sym(":")
            && let Some(Token {
                tok: Tok::Num(..), ..
            }) = cur.peek()
        {
            cur.pos += 1;
        }
        // A label `NAME:`.
        if let (
            Some(Token {
                tok: Tok::Name(_), ..
            }),
            Some(Token {
                tok: Tok::Sym(":"), ..
            }),
        ) = (cur.peek(), cur.peek_at(1))
        {
            cur.pos += 2;
        }
        let Some(first) = cur.peek() else {
            return self.hand_on(line, &mut out, raw, true);
        };
        if let Tok::Name(name) = &first.tok {
            let name = name.clone();
            if let Some(s) = Structure::of(&name) {
                return self.structured(line, &mut cur, s, (first.start, first.end));
            }
            match name.as_ref() {
                "DEF" => return self.define(line, &mut cur, out, raw),
                "PROC" => {
                    // The definition line of a program (its parameters are
                    // bound by the call).
                    return if line.file == 0 && self.levels.len() == 1 {
                        self.hand_on(line, &mut out, raw, true)
                    } else {
                        Ok(false)
                    };
                }
                "EXTERN" => return self.hand_on(line, &mut out, raw, true),
                "RET" => {
                    self.return_from_level(Some(line))?;
                    return Ok(false);
                }
                "CASE" => return self.case(line, &mut cur),
                "REPEATB" => {
                    cur.pos += 1;
                    self.flowed = true;
                    return self.repeat_section(line, &mut cur, true, (first.start, first.end));
                }
                "GOTOF" | "GOTOB" | "GOTO" | "GOTOC" => {
                    cur.pos += 1;
                    return self.goto(line, &mut cur, &name, (first.start, first.end));
                }
                _ => {}
            }
        }
        self.statements(line, &mut cur, out, interpreter)
    }

    /// Hand the block on: literal (as written) or flat.
    fn hand_on(
        &mut self,
        line: &LineRun,
        out: &mut Out,
        raw: &[u8],
        _plain: bool,
    ) -> Result<bool, GcodeError> {
        let literal = line.first_reading && !(self.flowed && out.computed) && !out.flat;
        self.block.reset(line.line, 0);
        self.block.deleted = out.deleted;
        if literal {
            self.block.raw.extend_from_slice(raw);
            // The previous block's words buffer (cleared by reset) serves the next line.
            self.spare_words =
                std::mem::replace(&mut self.block.words, std::mem::take(&mut out.words));
            self.block.keywords = std::mem::take(&mut out.keywords);
            self.block.comments = std::mem::take(&mut out.comments);
            self.block.statements = std::mem::take(&mut out.statements);
            self.executed.literal = true;
            return Ok(true);
        }
        // Flat: the kept pieces in order, computed values as numbers.
        self.executed.literal = false;
        let mut pieces: Vec<(usize, usize, Piece)> = Vec::new();
        for (k, w) in out.words.iter().enumerate() {
            pieces.push((w.start, w.end, Piece::Word(k)));
        }
        for (k, kw) in out.keywords.iter().enumerate() {
            // `CYCLE800(…)` switches the frame: its text is the statement's.
            if !out.statements.contains(&(kw.start..kw.end)) {
                pieces.push((kw.start, kw.end, Piece::Keyword(k)));
            }
        }
        for s in &out.statements {
            pieces.push((s.start, s.end, Piece::Statement));
        }
        for c in &out.comments {
            pieces.push((c.start, c.end, Piece::Comment));
        }
        pieces.sort_by_key(|p| p.0);
        let b = &mut self.block;
        for (start, end, piece) in pieces {
            if let Piece::Word(k) = piece
                && start == end
                && !out.synthetic.contains(&k)
            {
                // A word the front solved (the rotary joints of an
                // orientation vector): it has no text.
                let at = b.raw.len();
                b.words.push(Word {
                    start: at,
                    end: at,
                    expr: None,
                    ..out.words[k]
                });
                continue;
            }
            if !b.raw.is_empty() {
                b.raw.push(b' ');
            }
            let at = b.raw.len();
            match piece {
                Piece::Word(k) => {
                    let w = out.words[k];
                    if out.synthetic.contains(&k) {
                        // A word the front worked out (a CIP/CT/AR= arc's
                        // G code, centre or end; a split piece's
                        // orientation): written as LETTERvalue.
                        match orientation::word_name(w.letter) {
                            Some(name) => b.raw.extend_from_slice(name.as_bytes()),
                            None => b.raw.push(w.letter),
                        }
                        if w.letter == b'G' {
                            b.raw.extend_from_slice(format!("{}", w.value).as_bytes());
                        } else {
                            self.text.clear();
                            crate::gcode::language::push_value(&mut self.text, w.value);
                            b.raw.extend_from_slice(self.text.as_bytes());
                        }
                    } else if w.expr.is_some() || out.substituted.contains(&k) {
                        let text = &raw[w.start..w.end];
                        match text.iter().position(|&c| c == b'=') {
                            Some(eq) => b.raw.extend_from_slice(&text[..=eq]),
                            None => b.raw.push(text[0].to_ascii_uppercase()),
                        }
                        self.text.clear();
                        crate::gcode::language::push_value(&mut self.text, w.value);
                        b.raw.extend_from_slice(self.text.as_bytes());
                    } else {
                        b.raw.extend_from_slice(&raw[start..end]);
                    }
                    b.words.push(Word {
                        start: at,
                        end: b.raw.len(),
                        expr: None,
                        ..w
                    });
                }
                Piece::Keyword(k) => {
                    b.raw.extend_from_slice(&raw[start..end]);
                    b.keywords.push(KeywordWord {
                        start: at,
                        end: b.raw.len(),
                        ..out.keywords[k]
                    });
                }
                Piece::Statement => {
                    b.raw.extend_from_slice(&raw[start..end]);
                    b.statements.push(at..b.raw.len());
                }
                Piece::Comment => {
                    b.raw.extend_from_slice(&raw[start..end]);
                    b.comments.push(at..b.raw.len());
                }
            }
        }
        if b.is_empty() && b.comments.is_empty() {
            return Ok(false);
        }
        let origin = if line.file == 0 {
            format!("line {}", line.line)
        } else {
            let name = &self.files[line.file].name;
            let short = Path::new(name)
                .file_name()
                .map_or(name.clone(), |n| n.to_string_lossy().into_owned());
            format!("{short}:{}", line.line)
        };
        if !b.raw.is_empty() {
            b.raw.push(b' ');
        }
        let at = b.raw.len();
        b.raw
            .extend_from_slice(format!("; volcomp: {origin}").as_bytes());
        b.comments.push(at..b.raw.len());
        Ok(true)
    }

    /// IF/ELSE/ENDIF, WHILE, FOR, REPEAT/UNTIL, LOOP (*Job planning*,
    /// "Program sequence control").
    fn structured(
        &mut self,
        line: &LineRun,
        cur: &mut Cursor,
        s: Structure,
        at: (usize, usize),
    ) -> Result<bool, GcodeError> {
        cur.pos += 1;
        self.flowed = true;
        let k = line.line - 1;
        let partner = self.files[line.file]
            .partner
            .get(&k)
            .copied()
            .unwrap_or(usize::MAX);
        let level = self.levels.len() - 1;
        match s {
            Structure::If if partner == usize::MAX => {
                // `IF cond GOTOF label`.
                let e = cur
                    .expr()
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                let c = self.eval(line, &e, at)?;
                let Some((g, start, end)) = cur.next_name() else {
                    return Err(self.refused(
                        line,
                        "GOTOF, GOTOB, GOTO or GOTOC expected after the IF condition".into(),
                        at.0,
                        at.1,
                    ));
                };
                if c != 0.0 {
                    let g = g.to_string();
                    return self.goto(line, cur, &g, (start, end));
                }
                Ok(false)
            }
            Structure::If | Structure::While => {
                let e = cur
                    .expr()
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                let c = self.eval(line, &e, at)?;
                if c == 0.0 {
                    self.levels[level].next = partner + 1;
                }
                Ok(false)
            }
            Structure::Else => {
                // Reached from the IF branch: skip to after ENDIF.
                self.levels[level].next = partner + 1;
                Ok(false)
            }
            Structure::Repeat if partner == usize::MAX => self.repeat_section(line, cur, false, at),
            Structure::EndIf | Structure::Repeat | Structure::Loop => Ok(false),
            Structure::EndWhile | Structure::EndLoop => {
                self.levels[level].next = if s == Structure::EndWhile {
                    partner
                } else {
                    partner + 1
                };
                Ok(false)
            }
            Structure::Until => {
                let e = cur
                    .expr()
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                if self.eval(line, &e, at)? == 0.0 {
                    self.levels[level].next = partner + 1;
                }
                Ok(false)
            }
            Structure::For => {
                // FOR var = start TO end.
                let Some((var, vs, ve)) = cur.next_name() else {
                    return Err(self.refused(
                        line,
                        "FOR needs a variable: FOR I = 1 TO 10".into(),
                        at.0,
                        at.1,
                    ));
                };
                let var = var.to_string();
                let (vs, ve) = (vs, ve);
                cur.expect_sym("=")
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                let from = cur
                    .expr()
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                if !cur.eat_name("TO") {
                    let h = cur.here();
                    return Err(self.refused(
                        line,
                        "TO expected: FOR I = 1 TO 10".into(),
                        h,
                        h + 1,
                    ));
                }
                let to = cur
                    .expr()
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                let to = self.eval(line, &to, at)?;
                let value = if self.levels[level].for_continue == Some(k) {
                    self.levels[level].for_continue = None;
                    self.get_var(line, &var, (vs, ve))?
                } else {
                    let v = self.eval(line, &from, at)?;
                    self.set_var(line, &var, v, (vs, ve))?;
                    v
                };
                if value > to {
                    self.levels[level].next = partner + 1;
                }
                Ok(false)
            }
            Structure::EndFor => {
                // Count up and test again at the FOR line.
                let for_line = partner;
                let raw = self.files[line.file].raw(for_line).to_vec();
                let head = line_head(&raw);
                let rest = head.rest;
                let var: String = rest[3.min(rest.len())..]
                    .iter()
                    .skip_while(|b| **b == b' ')
                    .take_while(|b| b.is_ascii_alphanumeric() || **b == b'_')
                    .map(|b| b.to_ascii_uppercase() as char)
                    .collect();
                let v = self.get_var(line, &var, at)?;
                self.set_var(line, &var, v + 1.0, at)?;
                self.levels[level].for_continue = Some(for_line);
                self.levels[level].next = for_line;
                Ok(false)
            }
        }
    }

    fn var_value(&self, name: &str) -> Option<f64> {
        if let Some(n) = r_number(name) {
            return self.r.get(n).copied();
        }
        let v = self.levels.last()?.scope.vars.get(name)?;
        (v.dims.is_empty()).then(|| v.values[0])
    }

    fn get_var(&self, line: &LineRun, name: &str, at: (usize, usize)) -> Result<f64, GcodeError> {
        self.var_value(name).ok_or_else(|| {
            self.refused(
                line,
                format!("`{name}` is not a defined variable"),
                at.0,
                at.1,
            )
        })
    }

    fn set_var(
        &mut self,
        line: &LineRun,
        name: &str,
        v: f64,
        at: (usize, usize),
    ) -> Result<(), GcodeError> {
        if let Some(n) = r_number(name) {
            if n < R_COUNT {
                self.r[n] = v;
                return Ok(());
            }
        }
        let level = self.levels.len() - 1;
        match self.levels[level].scope.vars.get_mut(name) {
            Some(var) if var.dims.is_empty() => {
                var.values[0] = var.ty.store(v);
                Ok(())
            }
            _ => Err(self.refused(
                line,
                format!("`{name}` is not a defined variable"),
                at.0,
                at.1,
            )),
        }
    }

    /// `GOTOF`/`GOTOB`/`GOTO`/`GOTOC` label or block number (*Job
    /// planning*, "Program jumps to jump markers": GOTOF searches forward,
    /// GOTOB backward, GOTO forward then backward, GOTOC as GOTO without
    /// an alarm when the label is missing).
    fn goto(
        &mut self,
        line: &LineRun,
        cur: &mut Cursor,
        kind: &str,
        at: (usize, usize),
    ) -> Result<bool, GcodeError> {
        self.flowed = true;
        let (target, tend) = match (cur.next(), cur.peek()) {
            (
                Some(Token {
                    tok: Tok::Name(n),
                    end,
                    ..
                }),
                Some(Token {
                    tok: Tok::Num(v, ..),
                    end: e2,
                    ..
                }),
            ) if n == "N" => {
                let (v, e2) = (*v, *e2);
                let _ = end;
                cur.pos += 1;
                (format!("N{}", v), e2)
            }
            (
                Some(Token {
                    tok: Tok::Name(n),
                    end,
                    ..
                }),
                _,
            ) => (n.to_string(), *end),
            // `GOTOF 90`: a block number without its N.
            (
                Some(Token {
                    tok: Tok::Num(v, ..),
                    end,
                    ..
                }),
                _,
            ) => (format!("N{v}"), *end),
            _ => {
                return Err(self.refused(
                    line,
                    format!("{kind} needs a label or a block number"),
                    at.0,
                    at.1,
                ));
            }
        };
        let file = &self.files[line.file];
        let here = line.line - 1;
        let find = |forward: bool| -> Option<usize> {
            let matches = |k: usize| -> bool {
                if let Some(n) = target
                    .strip_prefix('N')
                    .filter(|n| n.parse::<f64>().is_ok())
                {
                    let raw = file.raw(k);
                    let head = raw.trim_ascii_start();
                    head.len() > n.len()
                        && head[0].eq_ignore_ascii_case(&b'N')
                        && head[1..].starts_with(n.as_bytes())
                        && !head.get(1 + n.len()).is_some_and(u8::is_ascii_digit)
                } else {
                    file.labels.get(&target) == Some(&k)
                }
            };
            if forward {
                (here + 1..file.count()).find(|&k| matches(k))
            } else {
                (0..here).rev().find(|&k| matches(k))
            }
        };
        let found = match kind {
            "GOTOF" => find(true),
            "GOTOB" => find(false),
            _ => find(true).or_else(|| find(false)),
        };
        match found {
            Some(k) => {
                let level = self.levels.len() - 1;
                self.levels[level].next = k;
                self.levels[level].for_continue = None;
                Ok(false)
            }
            None if kind == "GOTOC" => Ok(false),
            None => Err(self.refused(
                line,
                format!(
                    "jump destination `{target}` not found ({kind} searches {})",
                    match kind {
                        "GOTOF" => "forward",
                        "GOTOB" => "backward",
                        _ => "forward, then backward",
                    }
                ),
                at.0,
                tend,
            )),
        }
    }

    /// `REPEAT label P=n`, `REPEAT label label2 P=n`, `REPEATB label P=n`
    /// (*Job planning*, "Program section repetition (REPEAT, REPEATB,
    /// ENDLABEL, P)"): the statement runs a section of the program `n` times
    /// (`P` omitted: once), then the program goes on after the statement.
    /// The section: `REPEATB` the block with the label; one label the
    /// blocks from the label to the next block labelled `ENDLABEL`, or,
    /// without one before the statement, to the block before the `REPEAT`;
    /// two labels the blocks from the first to the second, both included.
    /// A label is looked for backward from the statement, then forward; a
    /// label that is missing, a second label before the first, or a
    /// section that would contain its own `REPEAT` is a located error.
    fn repeat_section(
        &mut self,
        line: &LineRun,
        cur: &mut Cursor,
        single: bool,
        at: (usize, usize),
    ) -> Result<bool, GcodeError> {
        let what = if single { "REPEATB" } else { "REPEAT" };
        let mut names: Vec<(String, usize, usize)> = Vec::new();
        while let Some(Token {
            tok: Tok::Name(n),
            start,
            end,
        }) = cur.peek()
        {
            if n == "P"
                && cur
                    .peek_at(1)
                    .is_some_and(|t| matches!(t.tok, Tok::Sym("=") | Tok::Num(..)))
            {
                break;
            }
            names.push((n.to_string(), *start, *end));
            cur.pos += 1;
        }
        let mut runs = 1.0;
        if cur.eat_name("P") {
            cur.eat_sym("=");
            let h = cur.here();
            let e = cur
                .expr()
                .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
            runs = self.eval(line, &e, (h, cur.last_end()))?;
            if !(runs >= 1.0 && runs.fract() == 0.0) {
                return Err(self.refused(
                    line,
                    format!("P={runs}: the number of runs is a whole number ≥ 1"),
                    h,
                    cur.last_end().max(h + 1),
                ));
            }
        }
        if let Some(t) = cur.peek() {
            return Err(self.refused(
                line,
                format!("unexpected after {what} label P=n"),
                t.start,
                t.end,
            ));
        }
        let most = if single { 1 } else { 2 };
        if names.is_empty() || names.len() > most {
            return Err(self.refused(
                line,
                format!(
                    "{what} needs {}, then P=n",
                    if single { "a label" } else { "a label or two" }
                ),
                at.0,
                at.1,
            ));
        }
        let here = line.line - 1;
        let file = &self.files[line.file];
        let label_line = |name: &str, from: usize| -> Option<usize> {
            // Backward from `from`, then forward.
            let matches = |k: usize| line_head(file.raw(k)).label.as_deref() == Some(name);
            (0..from)
                .rev()
                .find(|&k| matches(k))
                .or_else(|| (from + 1..file.count()).find(|&k| matches(k)))
        };
        let missing = |name: &str, s: usize, e: usize| {
            self.refused(
                line,
                format!("{what}: the label `{name}` is not in {}", file.name),
                s,
                e,
            )
        };
        let (first, fs, fe) = &names[0];
        let start = label_line(first, here).ok_or_else(|| missing(first, *fs, *fe))?;
        let end = if single {
            start
        } else if let Some((second, ss, se)) = names.get(1) {
            (start..file.count())
                .find(|&k| line_head(file.raw(k)).label.as_deref() == Some(second.as_str()))
                .ok_or_else(|| {
                    self.refused(
                        line,
                        format!("{what}: no label `{second}` after the label `{first}`"),
                        *ss,
                        *se,
                    )
                })?
        } else {
            let endlabel = (start..file.count())
                .find(|&k| line_head(file.raw(k)).label.as_deref() == Some("ENDLABEL"));
            match endlabel {
                Some(e) if start > here || e < here => e,
                _ if start < here => here - 1,
                _ => {
                    return Err(self.refused(
                        line,
                        format!(
                            "{what} {first}: the label follows the statement, and no ENDLABEL closes the section"
                        ),
                        *fs,
                        *fe,
                    ));
                }
            }
        };
        if (start..=end).contains(&here) {
            return Err(self.refused(
                line,
                format!(
                    "{what}: the section (lines {}–{}) contains the statement itself",
                    start + 1,
                    end + 1
                ),
                at.0,
                at.1,
            ));
        }
        self.flowed = true;
        let level = self.levels.len() - 1;
        let l = &mut self.levels[level];
        l.sections.push(Section {
            start,
            end,
            left: runs as u64,
            resume: here + 1,
        });
        l.next = start;
        l.for_continue = None;
        Ok(false)
    }

    /// `CASE (expr) OF c1 GOTOF L1 … DEFAULT GOTOF Ln`.
    fn case(&mut self, line: &LineRun, cur: &mut Cursor) -> Result<bool, GcodeError> {
        let at = (cur.here(), cur.here() + 4);
        cur.pos += 1;
        let e = cur
            .expr()
            .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
        let v = self.eval(line, &e, at)?;
        if !cur.eat_name("OF") {
            let h = cur.here();
            return Err(self.refused(
                line,
                "OF expected: CASE (R1) OF 1 GOTOF A 2 GOTOF B DEFAULT GOTOF C".into(),
                h,
                h + 1,
            ));
        }
        loop {
            let Some(t) = cur.next() else {
                return Ok(false);
            };
            let hit = match &t.tok {
                Tok::Name(n) if n == "DEFAULT" => true,
                Tok::Num(c, ..) => *c == v,
                Tok::Sym("-") => {
                    matches!(cur.next(), Some(Token { tok: Tok::Num(c, ..), .. }) if -*c == v)
                }
                _ => {
                    return Err(self.refused(
                        line,
                        "a constant or DEFAULT expected in CASE".into(),
                        t.start,
                        t.end,
                    ));
                }
            };
            let Some((g, start, end)) = cur.next_name() else {
                return Err(self.refused(
                    line,
                    "GOTOF/GOTOB expected in CASE".into(),
                    t.start,
                    t.end,
                ));
            };
            let g = g.to_string();
            let gat = (start, end);
            if hit {
                return self.goto(line, cur, &g, gat);
            }
            cur.pos += 1; // the label
        }
    }

    /// `DEF type name[dims] = init, …` (*Job planning*, "Definition of user
    /// variables (DEF)": definitions come at the start of the program,
    /// before its first motion block).
    fn define(
        &mut self,
        line: &LineRun,
        cur: &mut Cursor,
        out: Out,
        raw: &[u8],
    ) -> Result<bool, GcodeError> {
        let at = (cur.here(), cur.here() + 3);
        let level = self.levels.len() - 1;
        if self.levels[level].moved {
            return Err(self.refused(
                line,
                "DEF after the first motion block: definitions come at the start of the program (Job planning, \"Definition of user variables\")".into(),
                at.0,
                at.1,
            ));
        }
        cur.pos += 1;
        let Some((ty_name, start, end)) = cur.next_name() else {
            return Err(self.refused(
                line,
                "DEF needs a type: INT, REAL, BOOL, CHAR, STRING, AXIS or FRAME".into(),
                at.0,
                at.1,
            ));
        };
        let Some(ty) = VarType::from_name(ty_name) else {
            return Err(self.refused(line, format!("`{ty_name}` is not a type DEF takes (INT, REAL, BOOL, CHAR, STRING, AXIS, FRAME)"), start, end));
        };
        if ty_name == "STRING" && cur.eat_sym("[") {
            while let Some(t) = cur.next() {
                if t.tok == Tok::Sym("]") {
                    break;
                }
            }
        }
        loop {
            let Some((name, start, end)) = cur.next_name() else {
                let h = cur.here();
                return Err(self.refused(line, "a variable name expected".into(), h, h + 1));
            };
            let (name, nat) = (name.to_string(), (start, end));
            let mut dims = Vec::new();
            if cur.eat_sym("[") {
                loop {
                    let e = cur
                        .expr()
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                    let d = self.eval(line, &e, nat)?;
                    if !(d >= 1.0 && d.fract() == 0.0 && d <= 1e6) {
                        return Err(self.refused(
                            line,
                            format!("array dimension {d} of `{name}` is not a whole number ≥ 1"),
                            nat.0,
                            nat.1,
                        ));
                    }
                    dims.push(d as usize);
                    if cur.eat_sym("]") {
                        break;
                    }
                    cur.expect_sym(",")
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                }
            }
            let mut var = Variable::new(ty, dims);
            if cur.eat_sym("=") {
                let mut init = Vec::new();
                let set = cur.eat_name("SET");
                let open = cur.at_sym("(");
                if set && !open {
                    cur.expect_sym("(")
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                }
                if set || open {
                    // An empty place (`SET(0,,,9)`) leaves its element 0.
                    init = argument_list(cur)
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?
                        .0;
                } else if ty != VarType::Other {
                    init.push(
                        cur.expr()
                            .map_err(|e| self.refused(line, e.message, e.start, e.end))?,
                    );
                } else {
                    // A string or frame initialiser: kept as written.
                    while cur.peek().is_some_and(|t| t.tok != Tok::Sym(",")) {
                        cur.pos += 1;
                    }
                }
                if init.len() > var.values.len() {
                    return Err(self.refused(
                        line,
                        format!(
                            "{} initial values for `{name}` of {} elements",
                            init.len(),
                            var.values.len()
                        ),
                        nat.0,
                        nat.1,
                    ));
                }
                for (k, e) in init.iter().enumerate() {
                    let v = self.eval(line, e, nat)?;
                    var.values[k] = ty.store(v);
                }
            }
            self.levels[level].scope.vars.insert(name, var);
            if !cur.eat_sym(",") {
                break;
            }
        }
        if let Some(t) = cur.peek() {
            return Err(self.refused(
                line,
                "unexpected after the definition".into(),
                t.start,
                t.end,
            ));
        }
        let mut out = out;
        out.computed = true;
        // A definition is written where it stands, read in sequence; flat, dropped.
        if line.first_reading && !self.flowed {
            self.hand_on(line, &mut out, raw, true)
        } else {
            Ok(false)
        }
    }

    /// Return from a subprogram (`RET`, `M17`, its end); in the main program
    /// the program ends.
    fn return_from_level(&mut self, _line: Option<&LineRun>) -> Result<(), GcodeError> {
        let depth = self.levels.len() - 1;
        if depth == 0 {
            self.returned = true;
            self.levels[0].next = self.files[0].count();
            return Ok(());
        }
        let level = &mut self.levels[depth];
        if level.repeats_left > 0 {
            level.repeats_left -= 1;
            level.next = 0;
            return Ok(());
        }
        let done = self.levels.pop().expect("a subprogram level");
        // `VAR` parameters: the caller's variables take their last values.
        for (param, target) in &done.by_ref {
            let Some(var) = done.scope.vars.get(param) else {
                continue;
            };
            let v = var.values[0];
            match target {
                Target::Array(name) => {
                    let caller = self.levels.last_mut().expect("the caller's level");
                    if let Some(into) = caller.scope.vars.get_mut(name) {
                        for (to, from) in into.values.iter_mut().zip(&var.values) {
                            *to = into.ty.store(*from);
                        }
                    }
                }
                Target::R(k) => self.r[*k] = v,
                Target::Var(name, k) => {
                    let caller = self.levels.last_mut().expect("the caller's level");
                    if let Some(var) = caller.scope.vars.get_mut(name) {
                        var.values[*k] = var.ty.store(v);
                    }
                }
            }
        }
        Ok(())
    }

    /// A `VAR` array parameter (`VAR REAL A[3]`, `VAR REAL M[,4]`: an
    /// empty first dimension takes the caller's; *Job planning*, "Subprograms
    /// with parameter transfer (PROC, VAR)": arrays are passed by
    /// reference only) bound to the caller's whole array `arg`: a copy of
    /// it, written back on return. The number of dimensions and each given
    /// size must be the caller's.
    #[allow(clippy::too_many_arguments)]
    fn bind_array(
        &self,
        line: &LineRun,
        name: &str,
        param: &str,
        ty: VarType,
        dims: &[Option<usize>],
        arg: Option<&(f64, Option<Target>)>,
        at: (usize, usize),
    ) -> Result<Variable, GcodeError> {
        let Some((_, Some(Target::Array(array)))) = arg else {
            return Err(self.refused(
                line,
                format!(
                    "`{param}` of {name} is a VAR array parameter: the call must pass an array (its name)"
                ),
                at.0,
                at.1,
            ));
        };
        let scope = &self.levels.last().expect("a level").scope;
        let caller = &scope.vars[array];
        let fits = caller.dims.len() == dims.len()
            && dims
                .iter()
                .zip(&caller.dims)
                .all(|(d, c)| d.is_none_or(|d| d == *c));
        if !fits {
            let given: Vec<String> = dims
                .iter()
                .map(|d| d.map_or(String::new(), |d| d.to_string()))
                .collect();
            return Err(self.refused(
                line,
                format!(
                    "`{array}` has dimensions {:?}; `{param}` of {name} takes [{}]",
                    caller.dims,
                    given.join(",")
                ),
                at.0,
                at.1,
            ));
        }
        let mut var = Variable::new(ty, caller.dims.clone());
        for (to, from) in var.values.iter_mut().zip(&caller.values) {
            *to = ty.store(*from);
        }
        Ok(var)
    }

    /// Call a subprogram by name: its file on the search path, its `PROC`
    /// parameters bound to `args` (*Job planning*, "Subprogram technique").
    #[inline(never)]
    fn call(
        &mut self,
        line: &LineRun,
        name: &str,
        args: Vec<(f64, Option<Target>)>,
        repeats: u64,
        at: (usize, usize),
    ) -> Result<(), GcodeError> {
        self.flowed = true;
        if self.levels.iter().skip(1).any(|l| l.name == name) {
            return Err(self.refused(
                line,
                format!("recursive call of `{name}`: it is already running (volcomp does not run recursive subprograms)"),
                at.0,
                at.1,
            ));
        }
        if self.levels.len() >= MAX_LEVELS {
            return Err(self.refused(
                line,
                format!("more than {MAX_LEVELS} program levels"),
                at.0,
                at.1,
            ));
        }
        let file = match self
            .files
            .iter()
            .position(|f| f.name.ends_with(&format!("#{name}")))
        {
            Some(k) => k,
            None => {
                let path = self.find_subprogram(name).ok_or_else(|| {
                    self.refused(
                        line,
                        format!(
                            "`{name}` is neither a statement volcomp knows nor a subprogram found as {name}.SPF in --subroutine-path or the program's folder"
                        ),
                        at.0,
                        at.1,
                    )
                })?;
                let text = std::fs::read(&path).map_err(|e| {
                    self.error(
                        line,
                        ErrorKind::Io(format!("{}: {e}", path.display())),
                        at.0,
                        at.1,
                    )
                })?;
                let mut f = SourceFile::new(path.display().to_string(), text)
                    .map_err(|e| e.with_path(&path))?;
                f.called_as = name.to_string();
                self.files.push(f);
                self.files.len() - 1
            }
        };
        // Bind the PROC parameters.
        let mut scope = Scope {
            vars: HashMap::new(),
        };
        let mut start = 0;
        let mut by_ref = Vec::new();
        for k in 0..self.files[file].count() {
            let raw = self.files[file].raw(k).to_vec();
            let head = line_head(&raw);
            let Some(first) = head.first else { continue };
            if first.eq_ignore_ascii_case(b"PROC") {
                start = k + 1;
                let params = proc_params(head.rest);
                for (i, param) in params.into_iter().enumerate() {
                    let arg = args.get(i);
                    if param.by_ref {
                        // *Job planning*, "Subprograms with parameter
                        // transfer (PROC, VAR)": the call passes a variable,
                        // whose value the subprogram's writes change.
                        if let Some(dims) = &param.array {
                            let var =
                                self.bind_array(line, name, &param.name, param.ty, dims, arg, at)?;
                            if let Some((_, Some(target))) = arg {
                                by_ref.push((param.name.clone(), target.clone()));
                            }
                            scope.vars.insert(param.name, var);
                            continue;
                        }
                        let Some((_, Some(target))) = arg else {
                            return Err(self.refused(
                                line,
                                format!(
                                    "`{}` of {name} is a VAR parameter: the call must pass a variable (an R parameter or a DEF variable), not a value",
                                    param.name
                                ),
                                at.0,
                                at.1,
                            ));
                        };
                        if matches!(target, Target::Array(_)) {
                            return Err(self.refused(
                                line,
                                format!(
                                    "`{}` of {name} is not an array: pass one element (`A[i]`)",
                                    param.name
                                ),
                                at.0,
                                at.1,
                            ));
                        }
                        by_ref.push((param.name.clone(), target.clone()));
                    } else if param.array.is_some() {
                        return Err(self.refused(
                            line,
                            format!(
                                "array parameter `{}` of {name} without VAR: an array is passed by reference only (VAR)",
                                param.name
                            ),
                            at.0,
                            at.1,
                        ));
                    }
                    let mut var = Variable::new(param.ty, Vec::new());
                    var.values[0] = param.ty.store(arg.map_or(0.0, |a| a.0));
                    scope.vars.insert(param.name, var);
                }
                break;
            }
            if !raw.trim_ascii().starts_with(b"%")
                && !raw.trim_ascii().starts_with(b";")
                && !raw.trim_ascii().is_empty()
            {
                break;
            }
        }
        self.levels.push(Level {
            file,
            next: start,
            scope,
            repeats_left: repeats.saturating_sub(1),
            name: name.to_string(),
            for_continue: None,
            // A subprogram's definitions come at its own start (Job
            // planning, "Definition of user variables": in each program).
            moved: false,
            sections: Vec::new(),
            by_ref,
        });
        Ok(())
    }

    /// The arguments of a call: each one's value and the variable it names
    /// ([`Self::target_of`]); a whole array (for a `VAR` array parameter)
    /// has no value of its own (0).
    fn call_arguments(
        &self,
        line: &LineRun,
        args: &[Expr],
        at: (usize, usize),
    ) -> Result<Vec<(f64, Option<Target>)>, GcodeError> {
        let mut values = Vec::with_capacity(args.len());
        for a in args {
            let target = self.target_of(line, a, at)?;
            let v = match target {
                Some(Target::Array(_)) => 0.0,
                _ => self.eval(line, a, at)?,
            };
            values.push((v, target));
        }
        Ok(values)
    }

    /// The variable an argument names (for a `VAR` parameter): `R12`,
    /// `R[expr]`, `NAME`, `NAME[i, j]`; `None` for any other expression.
    fn target_of(
        &self,
        line: &LineRun,
        e: &Expr,
        at: (usize, usize),
    ) -> Result<Option<Target>, GcodeError> {
        Ok(match e {
            Expr::R(i) => {
                let k = values::round_half_away(self.eval(line, i, at)?);
                (0.0..R_COUNT as f64)
                    .contains(&k)
                    .then_some(Target::R(k as usize))
            }
            Expr::Var(name, index, _) => {
                let scope = &self.levels.last().expect("a level").scope;
                let Some(var) = scope.vars.get(name) else {
                    return Ok(None);
                };
                if index.is_empty() && !var.dims.is_empty() {
                    return Ok(Some(Target::Array(name.clone())));
                }
                let mut idx = Vec::with_capacity(index.len());
                for i in index {
                    idx.push(self.eval(line, i, at)?);
                }
                var.flat(&idx).map(|k| Target::Var(name.clone(), k))
            }
            _ => None,
        })
    }

    fn find_subprogram(&self, name: &str) -> Option<PathBuf> {
        let dirs = self
            .options
            .subroutine_path
            .iter()
            .chain(self.main_dir.iter());
        for dir in dirs {
            for ext in ["SPF", "spf", "MPF", "mpf"] {
                for n in [name.to_string(), name.to_ascii_lowercase()] {
                    let p = dir.join(format!("{n}.{ext}"));
                    if p.is_file() {
                        return Some(p);
                    }
                }
            }
        }
        None
    }

    /// The statements of an ordinary block: words, assignments, frame and
    /// five-axis statements, calls, statements passed through.
    fn statements(
        &mut self,
        line: &mut LineRun,
        cur: &mut Cursor,
        mut out: Out,
        interpreter: &mut Interpreter,
    ) -> Result<bool, GcodeError> {
        let raw = line.raw;
        let mut frame_op: Option<(String, (usize, usize))> = None;
        let mut rpl: Option<f64> = None;
        let mut flags = GFlags::default();
        let mut call: Option<Call> = None;
        let mut repeats: u64 = 1;

        // The words before the statements (the block number).
        let mut axis_words = out.words.iter().any(|w| is_axis(w.letter));
        let mut centre_abs: Vec<(usize, f64)> = Vec::new();
        let mut orientation = Orientation::default();
        let mut tool_edge: Option<(f64, usize)> = None;
        let mut arc = ArcWords::default();
        let mut spline_words = splines::SplineWords::default();
        let mut bspline = None;
        let mut corner_words: Option<Box<corners::CornerWords>> = None;
        while let Some(t) = cur.next() {
            let (ts, te) = (t.start, t.end);
            let Tok::Name(name) = &t.tok else {
                return Err(self.refused(
                    line,
                    "a statement or an address expected".into(),
                    ts,
                    te,
                ));
            };
            let name = name.clone();
            // `ADDR=expr`, `VAR=expr`, `R1=expr`.
            if cur.eat_sym("=") {
                let vstart = cur.here();
                if name == "T" && self.named_tool_word(line, cur, interpreter, ts, &mut out)? {
                    continue;
                }
                let (e, mode) =
                    value_expr(cur).map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                let vend = cur.last_end();
                let v = self.eval(line, &e, (vstart, vend))?;
                match address(&name) {
                    Some(Address::Word(letter)) => {
                        axis_words |= is_axis(letter);
                        let k = out.words.len();
                        out.words.push(word(letter, v, ts, vend, 4, true, true));
                        out.computed = true;
                        match mode {
                            Mode::Ac if is_axis(letter) => out.absolute.push(k),
                            Mode::Ic if is_axis(letter) => out.relative.push(k),
                            Mode::Ac if matches!(letter, b'I' | b'J' | b'K') => {
                                centre_abs.push((k, v))
                            }
                            _ => {}
                        }
                    }
                    Some(Address::Radius) => {
                        out.words.push(word(b'R', v, ts, vend, 4, true, true));
                        out.computed = true;
                    }
                    Some(Address::Pass) => {
                        out.statements.push(ts..vend);
                    }
                    Some(Address::Repeat) => {
                        if !(v >= 1.0 && v.fract() == 0.0) {
                            return Err(self.refused(
                                line,
                                format!("P={v}: the number of runs is a whole number ≥ 1"),
                                ts,
                                vend,
                            ));
                        }
                        repeats = v as u64;
                    }
                    Some(Address::RotPlane) => rpl = Some(v),
                    Some(Address::Spline(b'D')) => spline_words.degree = Some((v, (ts, vend))),
                    Some(Address::Spline(b'L')) => spline_words.interval = Some((v, (ts, vend))),
                    Some(Address::Spline(_)) => spline_words.weight = Some((v, (ts, vend))),
                    Some(Address::Vector(k)) => {
                        orientation.vector[k] = Some((v, ts, vend));
                        out.computed = true;
                    }
                    Some(Address::Angle(k)) => {
                        orientation.angles[k] = Some((v, ts, vend));
                        out.computed = true;
                    }
                    Some(Address::ArcAngle) => arc.angle = Some((v, ts, vend)),
                    Some(Address::Turns) => arc.turns = Some((v, ts, vend)),
                    Some(Address::Intermediate(k)) => arc.inter[k] = Some((v, mode)),
                    Some(Address::Corner(c)) => {
                        corner_words.get_or_insert_default().set(c, v, (ts, vend))
                    }
                    None => {
                        // An assignment (R parameter or variable).
                        self.assign(line, &name, &[], v, (ts, vend))?;
                        out.computed = true;
                        out.assignments.push(ts..vend);
                    }
                }
                continue;
            }
            // `ACC[X]=50`, `FGREF[C]=…`: axis settings without motion.
            if matches!(
                name.as_ref(),
                "ACC" | "FGREF" | "OVRA" | "VELOLIM" | "JERKLIM" | "FL" | "POLF"
            ) && matches!(
                cur.peek(),
                Some(Token {
                    tok: Tok::Sym("["),
                    ..
                })
            ) {
                while cur.peek().is_some_and(|t| !matches!(t.tok, Tok::Sym("="))) {
                    cur.pos += 1;
                }
                cur.pos += 1;
                cur.expr()
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                out.statements.push(ts..cur.last_end());
                continue;
            }
            // `NAME[i]=expr` (an array element).
            if matches!(
                cur.peek(),
                Some(Token {
                    tok: Tok::Sym("["),
                    ..
                })
            ) && !name.starts_with('$')
            {
                cur.pos += 1;
                let mut idx = Vec::new();
                loop {
                    let e = cur
                        .expr()
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                    idx.push(self.eval(line, &e, (ts, te))?);
                    if cur.eat_sym("]") {
                        break;
                    }
                    cur.expect_sym(",")
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                }
                cur.expect_sym("=")
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                let e = cur
                    .expr()
                    .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                let v = self.eval(line, &e, (ts, cur.last_end()))?;
                let r_index = if name == "R" {
                    idx.first().copied()
                } else {
                    None
                };
                match r_index {
                    Some(n) => self.assign(
                        line,
                        &format!("R{}", n.round()),
                        &[],
                        v,
                        (ts, cur.last_end()),
                    )?,
                    None => self.assign(line, &name, &idx, v, (ts, cur.last_end()))?,
                }
                out.computed = true;
                out.assignments.push(ts..cur.last_end());
                continue;
            }
            // A single address letter and its number: `X10`, `G0`, `X-5`.
            if name.len() == 1 {
                let letter = name.as_bytes()[0];
                let neg = if cur.eat_sym("-") {
                    true
                } else {
                    cur.eat_sym("+");
                    false
                };
                let Some(Token {
                    tok: Tok::Num(v, dec, point),
                    end,
                    ..
                }) = cur.peek()
                else {
                    if letter == b'T'
                        && self.named_tool_word(line, cur, interpreter, ts, &mut out)?
                    {
                        continue;
                    }
                    return Err(self.refused(
                        line,
                        format!("address `{}` without a value", letter as char),
                        ts,
                        te,
                    ));
                };
                let (v, dec, point, end) = (if neg { -*v } else { *v }, *dec, *point, *end);
                cur.pos += 1;
                match letter {
                    b'G' => {
                        if let Some(code) = self.g_code(line, v, (ts, end), &mut out, &mut flags)? {
                            out.words.push(word(b'G', code, ts, end, 0, false, false));
                        }
                    }
                    b'M' => match v as i64 {
                        _ if v.fract() != 0.0 => out.statements.push(ts..end),
                        0 | 1 | 2 | 30 | 3 | 4 | 5 | 6 | 7 | 8 | 9 => {
                            out.words.push(word(b'M', v, ts, end, 0, false, false));
                        }
                        17 => {
                            // The return is flow: a flat copy must not end
                            // the main program.
                            self.return_from_level(Some(line))?;
                            self.flowed = true;
                        }
                        _ => out.statements.push(ts..end),
                    },
                    b'X' | b'Y' | b'Z' | b'A' | b'B' | b'C' | b'U' | b'V' | b'W' | b'I' | b'J'
                    | b'K' | b'F' | b'S' | b'T' => {
                        axis_words |= is_axis(letter);
                        out.words.push(word(letter, v, ts, end, dec, point, false));
                    }
                    b'D' => {
                        tool_edge = Some((v, end));
                        out.statements.push(ts..end);
                    }
                    b'H' | b'E' => out.statements.push(ts..end),
                    b'L' => {
                        // `L123`, and `L123(args)`: a program named L123
                        // whose PROC takes parameters (*Job planning*,
                        // "Subprogram call": the name is L and a number).
                        let n = &raw[ts + 1..end];
                        let open = cur.at_sym("(");
                        let (list, last) = argument_list(cur)
                            .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                        let call_end = if open { last } else { end };
                        let args = self.call_arguments(line, &list, (ts, end))?;
                        call = Some((
                            format!("L{}", String::from_utf8_lossy(n)),
                            args,
                            (ts, call_end),
                        ));
                    }
                    b'P' => {
                        if !(v >= 1.0 && v.fract() == 0.0) {
                            return Err(self.refused(
                                line,
                                format!("P{v}: the number of runs is a whole number ≥ 1"),
                                ts,
                                end,
                            ));
                        }
                        repeats = v as u64;
                    }
                    b'N' => out.words.push(word(b'N', v, ts, end, 0, false, false)),
                    b'R' => {
                        return Err(self.refused(
                            line,
                            "an R parameter is set with `=` (R1=5)".into(),
                            ts,
                            end,
                        ));
                    }
                    _ => {
                        return Err(self.feature(
                            line,
                            &format!("address {}", letter as char),
                            ts,
                            end,
                        ));
                    }
                }
                continue;
            }
            // Named statements.
            match name.as_ref() {
                "TRANS" | "ATRANS" | "ROT" | "AROT" | "SCALE" | "ASCALE" | "MIRROR" | "AMIRROR" => {
                    frame_op = Some((name.to_string(), (ts, te)));
                    out.statements.push(ts..te);
                }
                "TRAORI" => {
                    let (_, end) = argument_list(cur)
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                    self.traori = true;
                    out.keywords.push(KeywordWord {
                        keyword: Keyword::TraOri,
                        start: ts,
                        end,
                    });
                }
                "TRAFOOF" => {
                    self.traori = false;
                    out.keywords.push(KeywordWord {
                        keyword: Keyword::TraFoof,
                        start: ts,
                        end: te,
                    });
                }
                "SUPA" => {
                    flags.suppress = true;
                    out.words.push(word(b'G', 53.0, ts, te, 0, false, false));
                }
                "CYCLE800" => {
                    let (args, end) = argument_list(cur)
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                    self.cycle800(line, &args, (ts, end), interpreter, &mut out)?;
                }
                "BSPLINE" => bspline = Some((ts, te)),
                "CIP" | "CT" => {
                    arc.form = Some(if name == "CIP" {
                        ArcForm::Intermediate
                    } else {
                        ArcForm::Tangential
                    });
                    arc.at = (ts, te);
                }
                "ASPLINE" | "CSPLINE" | "POLY" | "G33" | "OFFN" | "COMPON" | "ORICONCW"
                | "ORICONCCW" | "ORICURVE" | "TRANSMIT" | "TRACYL" | "TRAANG" | "PRESETON"
                | "CFINE" | "MCALL"
                    if name != "MCALL"
                        || matches!(
                            cur.peek(),
                            Some(Token {
                                tok: Tok::Name(_),
                                ..
                            })
                        ) =>
                {
                    let end = cur.peek().map_or(te, |t| t.end);
                    return Err(self.feature(line, &name, ts, te.max(end.min(te))));
                }
                "ORIWKS" | "ORIMKS" | "ORIAXES" | "ORIVECT" | "ORIPLANE" | "ORIEULER"
                | "ORIRPY" => {
                    self.ori.set(&name);
                    out.statements.push(ts..te);
                }
                "ORIVIRT1" | "ORIVIRT2" | "ORIAXPOS" | "ORIRPY2" | "ORIPATH" | "ORIPATHS"
                | "ORICONIO" | "ORICONTO" => {
                    return Err(self.feature(line, &name, ts, te));
                }
                "MSG" | "STOPRE" | "SOFT" | "BRISK" | "DRIVE" | "FFWON" | "FFWOF" | "COMPCAD"
                | "COMPOF" | "COMPCURV" | "COMPSURF" | "CYCLE832" | "WAITM" | "WAITS" | "WAITE"
                | "SETMS" | "SPOS" | "SPOSA" | "FNORM" | "UPATH" | "SPATH" | "CFC" | "CFTCP"
                | "CFIN" | "ORIROTA" | "ORIROTR" | "ORIROTT" | "CUT2D" | "CUT2DF" | "CUT3DC"
                | "CUT3DF" | "CUTCONON" | "CUTCONOF" | "NORM" | "KONT" | "KONTC" | "KONTT"
                | "DIAMON" | "DIAMOF" | "FGROUP" | "FGREF" | "SETAL" | "MCALL" | "DISPLON"
                | "DISPLOF" | "SAVE" | "SBLOF" | "SBLON" | "ACC" | "OVR" | "TRAFOON" | "G4"
                | "STOPFIFO" | "STARTFIFO" | "FIFOCTRL" | "WRTPR" | "CPROT" | "WALIMON"
                | "WALIMOF" | "LIMS" | "TOFFON" | "TOFFOF" | "TCARR" | "TCOABS" | "TCOFR"
                | "PAROT" | "PAROTOF" | "TOROT" | "TOROTOF" | "TOFRAME" | "EXTCALL" | "G64"
                | "G642" | "G645" => {
                    let (_, end) = argument_list(cur)
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                    if matches!(
                        name.as_ref(),
                        "PAROT" | "TOROT" | "TOFRAME" | "TCARR" | "TCOFR" | "TCOABS" | "EXTCALL"
                    ) {
                        return Err(self.feature(line, &name, ts, end));
                    }
                    out.statements.push(ts..end);
                }
                _ if name.starts_with("CYCLE")
                    || name.starts_with("POCKET")
                    || name.starts_with("SLOT")
                    || name.starts_with("HOLES")
                    || name.starts_with("LONGHOLE") =>
                {
                    let (_, end) = argument_list(cur)
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                    return Err(self.feature(line, &format!("machining cycle {name}"), ts, end));
                }
                _ if name.starts_with('$') => {
                    return Err(self.refused(
                        line,
                        format!("system variable `{name}` has no value offline"),
                        ts,
                        te,
                    ));
                }
                _ => {
                    // A subprogram call by name, with arguments.
                    let (args, end) = argument_list(cur)
                        .map_err(|e| self.refused(line, e.message, e.start, e.end))?;
                    let values = self.call_arguments(line, &args, (ts, end))?;
                    call = Some((name.to_string(), values, (ts, end)));
                }
            }
        }
        let mut said = Said {
            frame_op,
            rpl,
            flags,
            call,
            repeats,
            axis_words,
            centre_abs,
            orientation,
            tool_edge,
            arc,
            spline_words,
            bspline,
            corner_words,
        };
        self.end_block(line, &mut out, &mut said, interpreter)
    }

    /// The end of an ordinary block, after its statements (`statements`;
    /// a plain line's words come straight from `run_plain_line`): frames,
    /// calls, tools, orientation, splines, circles, the modes; then the
    /// block is handed on.
    fn end_block(
        &mut self,
        line: &mut LineRun,
        out: &mut Out,
        said: &mut Said,
        interpreter: &mut Interpreter,
    ) -> Result<bool, GcodeError> {
        let raw = line.raw;
        let Said {
            frame_op,
            rpl,
            flags,
            call,
            repeats,
            axis_words,
            centre_abs,
            orientation,
            tool_edge,
            arc,
            spline_words,
            bspline,
            corner_words,
        } = said;
        let (rpl, repeats, tool_edge, bspline) = (*rpl, *repeats, *tool_edge, *bspline);
        let mut axis_words = *axis_words;
        let mut frame_values: Vec<(u8, f64, (usize, usize))> = Vec::new();
        let mut turned = None;
        if self.spline.is_some() {
            let offsets = flags.suppress
                || flags.settable_off
                || flags.settable.is_some()
                || self.flush_frame_later;
            let framed = frame_op
                .as_ref()
                .map(|f| f.1)
                .or(offsets.then_some((0, raw.len())));
            if let Some((s, e)) = framed {
                return Err(self.feature(
                    line,
                    "a frame, work offset or SUPA inside a BSPLINE section",
                    s,
                    e,
                ));
            }
        }
        if let Some((name, args, at)) = call.take() {
            if out.words.iter().any(|w| is_axis(w.letter)) {
                return Err(self.feature(
                    line,
                    "a subprogram call in a block with axis words",
                    at.0,
                    at.1,
                ));
            }
            self.call(line, &name, args, repeats, at)?;
            return Ok(false);
        }
        // Frame statements take the block's axis words as their values.
        if let Some((op, at)) = frame_op {
            let mut kept = Vec::new();
            for w in out.words.drain(..) {
                if is_axis(w.letter) {
                    frame_values.push((w.letter, w.value, (w.start, w.end)));
                    // The frame statement's text runs over its values.
                    if let Some(st) = out.statements.iter_mut().find(|s| s.start == at.0) {
                        st.end = st.end.max(w.end);
                    }
                } else {
                    kept.push(w);
                }
            }
            out.words = kept;
            // The values move nothing: the block is not a move (the control
            // wants a frame statement alone in its block).
            axis_words = false;
            self.frame_statement(line, op, &frame_values, rpl, *at, interpreter)?;
        } else if rpl.is_some() {
            return Err(self.refused(line, "RPL= belongs to ROT or AROT".into(), 0, raw.len()));
        }
        if flags.dwell {
            // `G4 F…` (seconds) / `G4 S…` (revolutions): not a feed.
            let mut kept = Vec::new();
            for w in out.words.drain(..) {
                if matches!(w.letter, b'F' | b'S') {
                    out.statements.push(w.start..w.end);
                } else {
                    kept.push(w);
                }
            }
            out.words = kept;
        }
        let frame_flushed = self.flush_frame_later;
        if self.flush_frame_later {
            self.flush_frame_later = false;
            let combined = self.combined_frame();
            interpreter.set_frame((combined != FrameTransform::IDENTITY).then_some(combined));
        }
        if flags.settable_off {
            interpreter.set_work_origin(crate::axes::Axes::default());
        }
        if let Some(origin) = flags.settable {
            interpreter.set_work_origin(origin);
        }
        self.tool_state(out, tool_edge);
        self.tool_length(out, tool_edge);
        if orientation.given() {
            turned = Some(self.orientation_words(line, orientation, out, interpreter)?);
            axis_words = true;
        }
        if bspline.is_some()
            && let Some(w) = out
                .words
                .iter()
                .find(|w| w.letter == b'G' && matches!(w.value as i64, 0..=3))
        {
            return Err(self.refused(
                line,
                "BSPLINE and G0–G3 in one block (one motion group)".into(),
                w.start,
                w.end,
            ));
        }
        if (bspline.is_some() || self.spline.is_some())
            && (corner_words.is_some() || self.corners.active())
        {
            return Err(self.feature(
                line,
                "a contour corner (RND=/RNDM=/CHF=/CHR=) next to a BSPLINE section",
                bspline.map_or(0, |b| b.0),
                bspline.map_or(raw.len(), |b| b.1),
            ));
        }
        match self.spline_block(line, out, bspline, spline_words, axis_words, interpreter)? {
            Some(handed) => return Ok(handed),
            None if self.spline.is_none() => {
                // SD=, PL=, PW= outside a spline: passed through, as before.
                for (_, (s, e)) in [
                    spline_words.degree,
                    spline_words.interval,
                    spline_words.weight,
                ]
                .into_iter()
                .flatten()
                {
                    out.statements.push(s..e);
                }
            }
            None => {}
        }
        // The modal CIP / CT: a block with G0–G3 ends it.
        if out
            .words
            .iter()
            .any(|w| w.letter == b'G' && matches!(w.value as i64, 0..=3))
        {
            self.arc_form = None;
        }
        if arc.form.is_some() {
            self.arc_form = arc.form;
        } else if axis_words {
            arc.form = self.arc_form;
        }
        let arc_words = arc.form.is_some() || arc.angle.is_some() || arc.turns.is_some();
        if let Some(g) = self.restore_arc
            && (axis_words || arc_words || out.words.iter().any(|w| w.letter == b'G'))
        {
            // The circle before was handed on as chords (G1): the control
            // still runs G2/G3 here.
            self.restore_arc = None;
            let motion = out
                .words
                .iter()
                .any(|w| w.letter == b'G' && matches!(w.value as i64, 0..=3));
            if !motion && arc.form.is_none() && axis_words {
                out.synthetic.push(out.words.len());
                out.words.push(word(b'G', g, 0, 0, 0, false, false));
                out.flat = true;
            }
        }
        self.chorded = false;
        self.turn_end = turned;
        if axis_words || arc_words {
            let level = self.levels.len() - 1;
            self.levels[level].moved = true;
            self.resolve_modes(out, interpreter, flags.suppress, centre_abs);
            let start = interpreter
                .origin_ref()
                .to_program(&interpreter.position())
                .xyz();
            if arc_words {
                self.arc(line, arc, out, interpreter, start)?;
            }
            // After `arc`: a CIP/CT circle has its G2/G3 now.
            let chords = !self.chorded && self.check_arc_frame(line, out, interpreter)?;
            self.last_move = self.move_of(out, interpreter, start);
            if self.chorded {
                // A circle in space (CIP, or CT after one): CT goes on from
                // its tangent (`circles::space_tangent`).
                self.last_move =
                    Some(LastMove {
                        start,
                        kind: self.space_arc.take().map_or(
                            LastKind::Unknown,
                            |(centre, normal)| LastKind::Space { centre, normal },
                        ),
                    });
            } else if chords
                || (self.traori
                    && self.arc_context(out, interpreter).2.is_some()
                    && (turned.is_some()
                        || out.words.iter().any(|w| {
                            crate::axes::Axis::from_letter(w.letter as char)
                                .is_some_and(|a| a.is_rotary())
                        })))
            {
                // A circle in a tilted plane, or one that turns the tool
                // under TRAORI: pieces.
                self.circle_as_chords(line, out, interpreter, start)?;
            }
            if let Some(end) = self.turn_end
                && !arc_words
                && self.great_circle_mode()
                && self.arc_context(out, interpreter).2.is_none()
            {
                self.split_on_great_circle(line, out, interpreter, start, end)?;
            }
        }
        if corner_words.is_some() || self.corners.active() {
            let framed = frame_flushed
                || flags.suppress
                || flags.settable_off
                || flags.settable.is_some()
                || !out.keywords.is_empty();
            let words = corner_words.take().map(|w| *w).unwrap_or_default();
            let facts = corners::BlockFacts {
                moves: axis_words || arc_words,
                arc_words,
                framed,
                turned: turned.is_some(),
                start: interpreter
                    .origin_ref()
                    .to_program(&interpreter.position())
                    .xyz(),
            };
            self.corner_block(line, out, &words, &facts, interpreter)?;
        }
        self.note_distance_mode(out);
        out.sort_words();
        self.hand_on(line, out, raw, false)
    }

    /// Keep the block's G90/G91 for AC/IC.
    fn note_distance_mode(&mut self, out: &Out) {
        for w in &out.words {
            if w.letter == b'G' {
                if w.value == 90.0 {
                    self.incremental = false;
                } else if w.value == 91.0 {
                    self.incremental = true;
                }
            }
        }
    }

    /// `A3= B3= C3=` (the tool direction as a vector) or `A2= B2= C2=`
    /// (Euler angles under `ORIEULER`, the control's default, or RPY angles
    /// under `ORIRPY`) under `TRAORI` (*Job planning*, "Three, four and five
    /// axis transformation (TRAORI)": orientation programming in the
    /// workpiece coordinate system). The direction is in the workpiece frame
    /// as the active frames leave it (it turns with `ROT`/`AROT` and a
    /// `CYCLE800` plane); unwritten vector components are 0 and the
    /// vector's length does not matter. The rotary joints come from the
    /// machine's chain ([`crate::gcode::OrientationSolver`]), on the branch
    /// nearest the previous joints (dialects.md "Tool-tip programs": the
    /// control's branch rule); they ride in the block as zero-width axis
    /// words, the orientation words under
    /// [`crate::gcode::ORIENTATION_VECTOR_LETTERS`] (vector) and
    /// [`ORIENTATION_ANGLE_LETTERS`] (angles) for the rewriter.
    #[inline(never)]
    fn orientation_words(
        &mut self,
        line: &LineRun,
        o: &Orientation,
        out: &mut Out,
        interpreter: &mut Interpreter,
    ) -> Result<orientation::OrientationEnd, GcodeError> {
        let (start, end) = o.span();
        let by_vector = o.vector.iter().any(Option::is_some);
        if by_vector && o.angles.iter().any(Option::is_some) {
            return Err(self.refused(
                line,
                "the orientation is given twice: a vector A3 B3 C3 and angles A2 B2 C2".into(),
                start,
                end,
            ));
        }
        if !self.traori {
            return Err(self.refused(
                line,
                "an orientation by vector (A3 B3 C3) or angles (A2 B2 C2) needs TRAORI: without the transformation the control has no tool direction to turn".into(),
                start,
                end,
            ));
        }
        let rotary: Vec<crate::axes::Axis> = interpreter
            .options()
            .axes
            .iter()
            .filter(|a| a.is_rotary())
            .collect();
        if let Some(w) = out.words.iter().find(|w| {
            crate::axes::Axis::from_letter(w.letter as char).is_some_and(|a| a.is_rotary())
        }) {
            return Err(self.refused(
                line,
                "the orientation is given twice: rotary axis words and A3 B3 C3 / A2 B2 C2".into(),
                w.start,
                w.end,
            ));
        }
        let v = if by_vector {
            let v = o.vector.map(|c| c.map_or(0.0, |c| c.0));
            if v.iter().map(|c| c * c).sum::<f64>() < 1e-18 {
                return Err(self.refused(
                    line,
                    "orientation vector A3 B3 C3 of length 0: it gives no tool direction".into(),
                    start,
                    end,
                ));
            }
            v
        } else {
            let [a, b, c] = o.angles.map(|c| c.map_or(0.0, |c| c.0));
            angles_direction(self.ori.rpy, a, b, c)
        };
        let Some(solver) = self.orientation.clone() else {
            return Err(self.feature(
                line,
                "an orientation by vector or angles without the machine (give --machine: the rotary joints come from its chain)",
                start,
                end,
            ));
        };
        let frame = self.combined_frame();
        let mut axis = frame.apply_vector(v);
        let norm = axis.iter().map(|c| c * c).sum::<f64>().sqrt();
        axis = axis.map(|c| c / norm);
        let previous = interpreter.position();
        let Some(joints) = solver.joints_for_axis(axis, crate::gcode::Branch::Nearest, &previous)
        else {
            return Err(self.refused(
                line,
                format!(
                    "the machine cannot point the tool along [{:.4}, {:.4}, {:.4}] within its rotary travel",
                    axis[0], axis[1], axis[2]
                ),
                start,
                end,
            ));
        };
        let program = interpreter.origin().to_program(&joints);
        for a in rotary {
            out.absolute.push(out.words.len());
            out.words.push(word(
                a.letter() as u8,
                program.get(a),
                end,
                end,
                4,
                true,
                true,
            ));
        }
        let letters = if by_vector {
            crate::gcode::ORIENTATION_VECTOR_LETTERS
        } else if self.ori.rpy {
            ORIENTATION_RPY_LETTERS
        } else {
            ORIENTATION_ANGLE_LETTERS
        };
        let given = if by_vector { &o.vector } else { &o.angles };
        for (k, c) in given.iter().enumerate() {
            if let Some((value, s, e)) = *c {
                out.words.push(word(letters[k], value, s, e, 4, true, true));
            }
        }
        Ok(orientation::OrientationEnd {
            joints,
            axis,
            at: (start, end),
        })
    }

    /// `T="name"` / `T"name"` at the cursor (after `T=` or `T`): the `T`
    /// word of the tool of that name ([`Self::tool_by_name`]) handed on,
    /// the string consumed; `false` (nothing consumed) when no string
    /// follows.
    fn named_tool_word(
        &self,
        line: &LineRun,
        cur: &mut Cursor<'_>,
        interpreter: &Interpreter,
        start: usize,
        out: &mut Out,
    ) -> Result<bool, GcodeError> {
        let Some(Token {
            tok: Tok::Str(tool),
            end,
            ..
        }) = cur.peek()
        else {
            return Ok(false);
        };
        cur.pos += 1;
        let number = self.tool_by_name(line, tool, interpreter, (start, *end))?;
        out.words
            .push(word(b'T', number, start, *end, 0, false, false));
        Ok(true)
    }

    /// `T="name"`: the tool managed by name (*Fundamentals*, "Tool change",
    /// with tool management the tool is selected by its name), found as
    /// [`crate::gcode::ToolTable::named`] says (the machine file's
    /// `[[tools]] name`, or a LinuxCNC table's comment, `T7 P7 Z95.2 D8.5
    /// ;DRILL 8.5`). A table that names no tool gives the default tool (the
    /// machine file's `[tool]`, said in the summary); a name that table
    /// names twice or not at all is a located error, as a number the table
    /// lacks is. The number rides in the block as the `T` word's value (its
    /// text stays `T="name"`).
    fn tool_by_name(
        &self,
        line: &LineRun,
        tool: &str,
        interpreter: &Interpreter,
        at: (usize, usize),
    ) -> Result<f64, GcodeError> {
        let table = interpreter.tools();
        match table.named(tool) {
            NamedTool::One(e) => Ok(f64::from(e.number)),
            NamedTool::None if !table.names_tools() => Ok(0.0),
            NamedTool::Two(a, b) => Err(self.refused(
                line,
                format!(
                    "tool \"{tool}\" names two tools of the tool table (T{a} and T{b}): a name must name one tool"
                ),
                at.0,
                at.1,
            )),
            NamedTool::None => Err(self.refused(
                line,
                format!(
                    "tool \"{tool}\" is not in the tool table: a tool is named by the machine file's [[tools]] name, or a tool table entry's comment (T1 P1 Z100 D8 ;{tool})"
                ),
                at.0,
                at.1,
            )),
        }
    }

    /// The execution state `$P_TOOLNO` and `$P_TOOL` read after this block:
    /// `T` preselects, `M6` makes the preselected tool active with its first
    /// edge (`D1`), `D` chooses the edge (*Fundamentals*, "Tool offsets", as
    /// [`Self::tool_length`] reads them).
    fn tool_state(&mut self, out: &Out, edge: Option<(f64, usize)>) {
        if let Some(t) = out.words.iter().rev().find(|w| w.letter == b'T') {
            self.preselected_tool = Some(t.value);
        }
        if out.words.iter().any(|w| w.letter == b'M' && w.value == 6.0) {
            self.state_tool = self.preselected_tool;
            self.state_edge = Some(1.0);
        }
        if let Some((d, _)) = edge {
            self.state_edge = Some(d);
        }
    }

    /// The tool length compensation: on the 840D sl a tool change (`M6`)
    /// activates the new tool's first cutting edge (`D1`, the reset setting
    /// of `$MC_CUTTING_EDGE_DEFAULT`), and `D1`…`D9` select an edge of the
    /// active tool, each with its length; `D0` switches the compensation off
    /// (*Fundamentals*, "Tool offsets"). For the machine-state layer that is
    /// LinuxCNC's `G43` (the loaded tool's length) or `G49`, handed on as a
    /// zero-width word (the block's text does not change), so that its
    /// tool-length check sees what the control does.
    fn tool_length(&self, out: &mut Out, edge: Option<(f64, usize)>) {
        let m6 = out
            .words
            .iter()
            .find(|w| w.letter == b'M' && w.value == 6.0)
            .map(|w| w.end);
        let (code, at) = match (edge, m6) {
            (Some((d, at)), _) => (if d == 0.0 { 49.0 } else { 43.0 }, at),
            (None, Some(at)) => (43.0, at),
            (None, None) => return,
        };
        out.words.push(word(b'G', code, at, at, 0, false, false));
    }

    /// The plane's coordinate indices (u, v, normal) as LinuxCNC's arcs
    /// read them (G17: X Y Z, G18: Z X Y, G19: Y Z X), the block's sense
    /// (`Some(true)` G2, `Some(false)` G3, `None` no circle) and whether its
    /// axis words are increments.
    fn arc_context(
        &self,
        out: &Out,
        interpreter: &Interpreter,
    ) -> ([usize; 3], crate::gcode::Plane, Option<bool>, bool) {
        use crate::gcode::machine::modal::MotionMode;
        let mut plane = interpreter.modal().plane;
        let mut sense = match interpreter.modal().motion {
            MotionMode::ArcCw => Some(true),
            MotionMode::ArcCcw => Some(false),
            _ => None,
        };
        let mut incremental = self.incremental;
        for w in out.words.iter().filter(|w| w.letter == b'G') {
            match w.value as i64 {
                0 | 1 => sense = None,
                2 => sense = Some(true),
                3 => sense = Some(false),
                17 => plane = crate::gcode::Plane::XY,
                18 => plane = crate::gcode::Plane::ZX,
                19 => plane = crate::gcode::Plane::YZ,
                90 => incremental = false,
                91 => incremental = true,
                _ => {}
            }
        }
        let idx = match plane {
            crate::gcode::Plane::XY => [0, 1, 2],
            crate::gcode::Plane::ZX => [2, 0, 1],
            crate::gcode::Plane::YZ => [1, 2, 0],
        };
        (idx, plane, sense, incremental)
    }

    /// Circles the machine-state layer does not take as written, turned
    /// into its centre form (*Fundamentals*, "Circular interpolation"):
    /// `CIP` through the intermediate point `I1= J1= K1=` (absolute or
    /// incremental as the axes, `AC`/`IC` allowed), `CT` tangential to the
    /// previous move, `AR=` with a centre (the end worked out) or with an
    /// end (the centre worked out: the shorter side for `AR` < 180°),
    /// `TURN=` full turns of a helix (LinuxCNC's `P` = turns + 1). The block
    /// is written flat: `G2`/`G3` with `I J K` (incremental, as both
    /// dialects read them) and, where the end was worked out, its axis
    /// words; `TURN=` stays.
    #[inline(never)]
    fn arc(
        &mut self,
        line: &LineRun,
        arc: &ArcWords,
        out: &mut Out,
        interpreter: &Interpreter,
        start: [f64; 3],
    ) -> Result<(), GcodeError> {
        let ([iu, iv, iw], plane, sense, incremental) = self.arc_context(out, interpreter);
        let at = if arc.at.1 > 0 {
            arc.at
        } else if let Some((_, s, e)) = arc.angle.or(arc.turns) {
            (s, e)
        } else {
            (0, line.raw.len())
        };
        let find = |out: &Out, letter: u8| out.words.iter().rposition(|w| w.letter == letter);
        let mut end = start;
        for k in 0..3 {
            if let Some(i) = find(out, b"XYZ"[k]) {
                let v = out.words[i].value;
                end[k] = if incremental { start[k] + v } else { v };
            }
        }
        let has_end = [iu, iv].iter().any(|&k| find(out, b"XYZ"[k]).is_some());
        let has_centre = [iu, iv].iter().any(|&k| find(out, b"IJK"[k]).is_some());
        let has_radius = find(out, b'R').is_some();
        let turns = match arc.turns {
            None => None,
            Some((n, s, e)) => {
                if !(n >= 0.0 && n.fract() == 0.0 && n <= 1e6) {
                    return Err(self.refused(
                        line,
                        format!("TURN={n}: the number of full turns is a whole number ≥ 0"),
                        s,
                        e,
                    ));
                }
                if arc.form.is_some() || sense.is_none() {
                    return Err(self.refused(
                        line,
                        "TURN= belongs to a circle programmed with G2/G3".into(),
                        s,
                        e,
                    ));
                }
                Some((n, s, e))
            }
        };
        let u = |p: [f64; 3]| [p[iu], p[iv]];
        let (s2, e2) = (u(start), u(end));
        let (cw, centre) = match arc.form {
            Some(ArcForm::Intermediate) => {
                let mut inter = start;
                for k in 0..3 {
                    inter[k] = match arc.inter[k] {
                        Some((v, Mode::Ac)) => v,
                        Some((v, Mode::Ic)) => start[k] + v,
                        Some((v, Mode::Plain)) if incremental => start[k] + v,
                        Some((v, Mode::Plain)) => v,
                        None if k == iw => 0.5 * (start[k] + end[k]),
                        None => start[k],
                    };
                }
                if (end[iw] - start[iw]).abs() > 1e-6 || (inter[iw] - start[iw]).abs() > 1e-6 {
                    // A circle in space: chords (`circles`).
                    if has_radius || has_centre {
                        return Err(self.refused(
                            line,
                            "CIP/CT/AR= with I J K or CR=: the circle is over-determined".into(),
                            at.0,
                            at.1,
                        ));
                    }
                    let done = self.space_circle_as_chords(
                        line,
                        out,
                        interpreter,
                        [start, inter, end],
                        incremental,
                    )?;
                    if done.is_none() {
                        return Err(self.refused(
                            line,
                            "CIP: the start, the intermediate point (I1 J1 K1) and the end lie on one line: no circle passes through them".into(),
                            at.0,
                            at.1,
                        ));
                    }
                    self.chorded = true;
                    return Ok(());
                }
                let m2 = u(inter);
                let Some(c) = circumcentre(s2, m2, e2) else {
                    return Err(self.refused(
                        line,
                        "CIP: the start, the intermediate point (I1 J1 K1) and the end lie on one line: no circle passes through them".into(),
                        at.0,
                        at.1,
                    ));
                };
                let cross = (m2[0] - s2[0]) * (e2[1] - m2[1]) - (m2[1] - s2[1]) * (e2[0] - m2[0]);
                (cross < 0.0, c)
            }
            Some(ArcForm::Tangential) => {
                if let Some(LastMove {
                    kind: LastKind::Space { centre, normal },
                    ..
                }) = self.last_move
                {
                    // After a circle in space: the circle in space leaving
                    // its end tangentially to it (`circles`).
                    if has_radius || has_centre {
                        return Err(self.refused(
                            line,
                            "CIP/CT/AR= with I J K or CR=: the circle is over-determined".into(),
                            at.0,
                            at.1,
                        ));
                    }
                    let tangent = circles::space_tangent(centre, normal, start);
                    let Some(inter) = circles::tangent_circle_midpoint(start, tangent, end) else {
                        return Err(self.refused(
                            line,
                            "CT: the end lies on the tangent of the circle before (or is the start): no circle leaves tangentially to it".into(),
                            at.0,
                            at.1,
                        ));
                    };
                    if self
                        .space_circle_as_chords(
                            line,
                            out,
                            interpreter,
                            [start, inter, end],
                            incremental,
                        )?
                        .is_none()
                    {
                        return Err(self.refused(
                            line,
                            "CT: no circle leaves tangentially to the circle before and reaches the end".into(),
                            at.0,
                            at.1,
                        ));
                    }
                    self.chorded = true;
                    return Ok(());
                }
                let Some(t) = self.tangent(line, plane, start, at)? else {
                    return Err(self.refused(
                        line,
                        "CT: the move before has no direction to continue tangentially".into(),
                        at.0,
                        at.1,
                    ));
                };
                let d = [e2[0] - s2[0], e2[1] - s2[1]];
                let n = [-t[1], t[0]];
                let nd = n[0] * d[0] + n[1] * d[1];
                let dd = d[0] * d[0] + d[1] * d[1];
                if nd.abs() <= 1e-9 * dd.sqrt().max(1e-9) {
                    return Err(self.refused(
                        line,
                        "CT: the end lies on the tangent of the move before (or is the start): no circle leaves tangentially to it".into(),
                        at.0,
                        at.1,
                    ));
                }
                let r = dd / (2.0 * nd);
                (nd < 0.0, [s2[0] + n[0] * r, s2[1] + n[1] * r])
            }
            None => {
                let Some((ar, s, e)) = arc.angle else {
                    // TURN= alone: the circle as written, its turns added.
                    self.push_turns(out, turns);
                    out.flat = true;
                    return Ok(());
                };
                let Some(cw) = sense else {
                    return Err(self.refused(
                        line,
                        "AR= belongs to a circle programmed with G2/G3".into(),
                        s,
                        e,
                    ));
                };
                if !(ar > 0.0 && ar <= 360.0) {
                    return Err(self.refused(
                        line,
                        format!(
                            "AR={ar}: a circle's opening angle is more than 0° and at most 360°"
                        ),
                        s,
                        e,
                    ));
                }
                if has_radius || (has_centre && has_end) {
                    return Err(self.refused(
                        line,
                        "AR= with CR= or with both a centre (I J K) and an end: the circle is over-determined".into(),
                        s,
                        e,
                    ));
                }
                if has_centre {
                    let ci = |k: usize| find(out, b"IJK"[k]).map_or(0.0, |i| out.words[i].value);
                    let c = [s2[0] + ci(iu), s2[1] + ci(iv)];
                    let a = if cw { -ar } else { ar }.to_radians();
                    let (sa, ca) = a.sin_cos();
                    let r = [s2[0] - c[0], s2[1] - c[1]];
                    end[iu] = c[0] + ca * r[0] - sa * r[1];
                    end[iv] = c[1] + sa * r[0] + ca * r[1];
                    self.push_end(out, [iu, iv], end, start, incremental, at);
                    self.push_turns(out, turns);
                    out.flat = true;
                    return Ok(());
                }
                if !has_end {
                    return Err(self.refused(
                        line,
                        "AR= needs the circle's centre (I J K) or its end".into(),
                        s,
                        e,
                    ));
                }
                let d = [e2[0] - s2[0], e2[1] - s2[1]];
                let chord = (d[0] * d[0] + d[1] * d[1]).sqrt();
                let half = (0.5 * ar).to_radians();
                if chord < 1e-9 || half.sin() < 1e-12 {
                    return Err(self.refused(
                        line,
                        format!("AR={ar} with an end {chord:.4} mm from the start: no circle of that opening angle joins them"),
                        s,
                        e,
                    ));
                }
                let r = chord / (2.0 * half.sin());
                let h = r * half.cos() * if cw { -1.0 } else { 1.0 };
                let n = [-d[1] / chord, d[0] / chord];
                (
                    cw,
                    [
                        0.5 * (s2[0] + e2[0]) + n[0] * h,
                        0.5 * (s2[1] + e2[1]) + n[1] * h,
                    ],
                )
            }
        };
        if has_radius || has_centre {
            return Err(self.refused(
                line,
                "CIP/CT/AR= with I J K or CR=: the circle is over-determined".into(),
                at.0,
                at.1,
            ));
        }
        let anchor = out
            .words
            .iter()
            .map(|w| w.end)
            .max()
            .unwrap_or(at.1)
            .max(at.1);
        if arc.form.is_some() {
            out.synthetic.push(out.words.len());
            out.words.push(word(
                b'G',
                if cw { 2.0 } else { 3.0 },
                at.0,
                at.0,
                0,
                false,
                false,
            ));
        }
        for (k, c) in [(iu, centre[0]), (iv, centre[1])] {
            out.synthetic.push(out.words.len());
            out.words
                .push(word(b"IJK"[k], c - start[k], anchor, anchor, 4, true, true));
        }
        self.push_turns(out, turns);
        out.flat = true;
        Ok(())
    }

    /// The end words of a circle whose end was worked out (`AR=` with a
    /// centre), replacing none: the block had none in the plane.
    fn push_end(
        &self,
        out: &mut Out,
        axes: [usize; 2],
        end: [f64; 3],
        start: [f64; 3],
        incremental: bool,
        at: (usize, usize),
    ) {
        for k in axes {
            out.synthetic.push(out.words.len());
            let v = if incremental {
                end[k] - start[k]
            } else {
                end[k]
            };
            out.words
                .push(word(b"XYZ"[k], v, at.0, at.0, 4, true, true));
        }
    }

    /// `TURN=n`: LinuxCNC's `P` = n + 1 for the machine-state layer, over
    /// the `TURN=` text (written as it is; a straightened circle loses it
    /// with its other circle words).
    fn push_turns(&self, out: &mut Out, turns: Option<(f64, usize, usize)>) {
        if let Some((n, s, e)) = turns {
            out.words.push(word(b'P', n + 1.0, s, e, 0, false, false));
        }
    }

    /// The unit tangent (in the plane's u v) at the end of the last move,
    /// for `CT`; `None` when it has no direction.
    fn tangent(
        &self,
        line: &LineRun,
        plane: crate::gcode::Plane,
        end: [f64; 3],
        at: (usize, usize),
    ) -> Result<Option<[f64; 2]>, GcodeError> {
        let Some(last) = self.last_move else {
            return Ok(None);
        };
        let idx = match plane {
            crate::gcode::Plane::XY => [0, 1],
            crate::gcode::Plane::ZX => [2, 0],
            crate::gcode::Plane::YZ => [1, 2],
        };
        let t = match last.kind {
            LastKind::Straight => [
                end[idx[0]] - last.start[idx[0]],
                end[idx[1]] - last.start[idx[1]],
            ],
            LastKind::Arc {
                centre,
                cw,
                plane: p,
            } if p == plane => {
                let r = [end[idx[0]] - centre[idx[0]], end[idx[1]] - centre[idx[1]]];
                if cw { [r[1], -r[0]] } else { [-r[1], r[0]] }
            }
            _ => {
                return Err(self.feature(
                    line,
                    "CT after a circle in another working plane (G17/G18/G19 changed between them)",
                    at.0,
                    at.1,
                ));
            }
        };
        let n = (t[0] * t[0] + t[1] * t[1]).sqrt();
        Ok((n > 1e-12).then(|| [t[0] / n, t[1] / n]))
    }

    /// What `CT` needs of this block's move: its start and, for a circle
    /// whose centre the block gives (I J K) or the front worked out, the
    /// centre, sense and plane.
    fn move_of(&self, out: &Out, interpreter: &Interpreter, start: [f64; 3]) -> Option<LastMove> {
        let ([iu, iv, _], plane, sense, incremental) = self.arc_context(out, interpreter);
        let kind = match sense {
            None => LastKind::Straight,
            Some(cw) if let Some(r) = out.words.iter().rev().find(|w| w.letter == b'R') => {
                // `CR=`: the centre on the side its sign and the sense give
                // (*Fundamentals*, "Circular interpolation with radius").
                let end = circles::block_end(out, start, incremental);
                let p = |q: [f64; 3]| [q[iu], q[iv], 0.0];
                match crate::gcode::heidenhain::machine::radius_centre(
                    p(start),
                    p(end),
                    r.value,
                    cw,
                ) {
                    Some(c) => {
                        let mut centre = start;
                        centre[iu] = c[0];
                        centre[iv] = c[1];
                        LastKind::Arc { centre, cw, plane }
                    }
                    None => LastKind::Unknown,
                }
            }
            Some(cw) => {
                let mut centre = start;
                for k in [iu, iv] {
                    if let Some(w) = out.words.iter().rev().find(|w| w.letter == b"IJK"[k]) {
                        centre[k] += w.value;
                    }
                }
                LastKind::Arc { centre, cw, plane }
            }
        };
        Some(LastMove { start, kind })
    }

    /// The settable-plane and programmable frames as one (`CYCLE800`'s
    /// plane after the programmable frame).
    fn combined_frame(&self) -> FrameTransform {
        let p = self.frames.programmable;
        match &self.frames.swivel {
            Some(s) => s.after(&p),
            None => p,
        }
    }

    /// An arc under a frame that does not keep its plane (a rotation out
    /// of the plane, a mirror, an uneven scale) is not read: the machine
    /// layer's arcs lie in G17/G18/G19.
    fn check_arc_frame(
        &self,
        line: &LineRun,
        out: &Out,
        interpreter: &Interpreter,
    ) -> Result<bool, GcodeError> {
        use crate::gcode::machine::modal::MotionMode;
        let Some(f) = &interpreter.origin_ref().frame else {
            return Ok(false);
        };
        let mut arc = matches!(
            interpreter.modal().motion,
            MotionMode::ArcCw | MotionMode::ArcCcw
        );
        let mut plane = interpreter.modal().plane;
        for w in &out.words {
            if w.letter == b'G' {
                match w.value as i64 {
                    0 | 1 => arc = false,
                    2 | 3 => arc = true,
                    17 => plane = crate::gcode::Plane::XY,
                    18 => plane = crate::gcode::Plane::ZX,
                    19 => plane = crate::gcode::Plane::YZ,
                    _ => {}
                }
            }
        }
        if !arc {
            return Ok(false);
        }
        let n = match plane {
            crate::gcode::Plane::XY => [0.0, 0.0, 1.0],
            crate::gcode::Plane::ZX => [0.0, 1.0, 0.0],
            crate::gcode::Plane::YZ => [1.0, 0.0, 0.0],
        };
        let m = f.matrix;
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        let scale = det.cbrt();
        let mut similar = true;
        for i in 0..3 {
            for j in 0..3 {
                let dot: f64 = (0..3).map(|k| m[k][i] * m[k][j]).sum::<f64>() / (scale * scale);
                similar &= (dot - f64::from(u8::from(i == j))).abs() < 1e-9;
            }
        }
        let mn = f.apply_vector(n);
        let kept = det > 0.0 && (0..3).all(|k| (mn[k] / scale - n[k]).abs() < 1e-9);
        if similar && kept {
            Ok(false)
        } else if similar {
            // The circle lies in the frame's plane: chords (`circles`).
            Ok(true)
        } else {
            Err(self.feature(
                line,
                "G2/G3 under a frame that scales the arc's plane unevenly",
                0,
                line.raw.len(),
            ))
        }
    }

    /// Set a variable, an array element or an R parameter.
    fn assign(
        &mut self,
        line: &LineRun,
        name: &str,
        index: &[f64],
        v: f64,
        at: (usize, usize),
    ) -> Result<(), GcodeError> {
        if index.is_empty() {
            return self.set_var(line, name, v, at);
        }
        let level = self.levels.len() - 1;
        let Some(var) = self.levels[level].scope.vars.get_mut(name) else {
            return Err(self.refused(
                line,
                format!("`{name}` is not a defined variable"),
                at.0,
                at.1,
            ));
        };
        match var.flat(index) {
            Some(k) => {
                var.values[k] = var.ty.store(v);
                Ok(())
            }
            None => {
                let dims = var.dims.clone();
                Err(self.refused(
                    line,
                    format!("index {index:?} of `{name}` out of its dimensions {dims:?}"),
                    at.0,
                    at.1,
                ))
            }
        }
    }

    /// `TRANS`/`ATRANS`, `ROT`/`AROT` (with `RPL=`), `SCALE`/`ASCALE`,
    /// `MIRROR`/`AMIRROR` (*Fundamentals*, "Coordinate transformations
    /// (frames)"): an absolute statement replaces the programmable frame,
    /// an additive one acts in the frame as it stands.
    #[inline(never)]
    fn frame_statement(
        &mut self,
        line: &LineRun,
        op: &str,
        values: &[(u8, f64, (usize, usize))],
        rpl: Option<f64>,
        at: (usize, usize),
        interpreter: &Interpreter,
    ) -> Result<(), GcodeError> {
        let get = |l: u8, default: f64| values.iter().find(|v| v.0 == l).map_or(default, |v| v.1);
        for &(l, _, (s, e)) in values {
            if !matches!(l, b'X' | b'Y' | b'Z') {
                return Err(self.feature(line, &format!("{op} of the {} axis", l as char), s, e));
            }
        }
        let piece = match op.trim_start_matches('A') {
            "TRANS" => FrameTransform::new(
                FrameTransform::IDENTITY.matrix,
                [get(b'X', 0.0), get(b'Y', 0.0), get(b'Z', 0.0)],
            ),
            "ROT" => {
                let (rx, ry, rz) = match rpl {
                    Some(a) => match interpreter.modal().plane {
                        crate::gcode::Plane::XY => (0.0, 0.0, a),
                        crate::gcode::Plane::ZX => (0.0, a, 0.0),
                        crate::gcode::Plane::YZ => (a, 0.0, 0.0),
                    },
                    None => (get(b'X', 0.0), get(b'Y', 0.0), get(b'Z', 0.0)),
                };
                FrameTransform::new(rpy(rx, ry, rz), [0.0; 3])
            }
            "SCALE" => FrameTransform::new(
                [
                    [get(b'X', 1.0), 0.0, 0.0],
                    [0.0, get(b'Y', 1.0), 0.0],
                    [0.0, 0.0, get(b'Z', 1.0)],
                ],
                [0.0; 3],
            ),
            "MIRROR" => {
                let sign = |l: u8| {
                    if values.iter().any(|v| v.0 == l) {
                        -1.0
                    } else {
                        1.0
                    }
                };
                FrameTransform::new(
                    [
                        [sign(b'X'), 0.0, 0.0],
                        [0.0, sign(b'Y'), 0.0],
                        [0.0, 0.0, sign(b'Z')],
                    ],
                    [0.0; 3],
                )
            }
            _ => None,
        };
        let Some(piece) = piece else {
            return Err(self.refused(
                line,
                format!("{op}: the frame is singular (a scale of 0)"),
                at.0,
                at.1,
            ));
        };
        self.frames.programmable = if op.starts_with('A') {
            self.frames.programmable.after(&piece)
        } else {
            piece
        };
        self.flush_frame_later = true;
        Ok(())
    }

    /// `AC()`/`IC()` values: an axis word written `=IC(…)` under G90 becomes
    /// the absolute target, `=AC(…)` under G91 the increment (*Fundamentals*,
    /// "Absolute and incremental dimensions: AC, IC"); `I=AC(…)` centres
    /// become increments from the start.
    fn resolve_modes(
        &mut self,
        out: &mut Out,
        interpreter: &Interpreter,
        suppress: bool,
        centre_abs: &[(usize, f64)],
    ) {
        if out.absolute.is_empty() && out.relative.is_empty() && centre_abs.is_empty() {
            return;
        }
        let origin = if suppress {
            crate::gcode::Origin::MACHINE
        } else {
            interpreter.origin()
        };
        let here = origin.to_program(&interpreter.position());
        let incremental = out.incremental(self.incremental);
        let current = |letter: u8| -> f64 {
            crate::axes::Axis::from_letter(letter as char).map_or(0.0, |a| here.get(a))
        };
        for &k in &out.relative {
            if !incremental {
                let w = &mut out.words[k];
                w.value += current(w.letter);
                out.substituted.push(k);
            }
        }
        for &k in &out.absolute {
            if incremental {
                let w = &mut out.words[k];
                w.value -= current(w.letter);
                out.substituted.push(k);
            }
        }
        for &(k, v) in centre_abs {
            let w = &mut out.words[k];
            let axis = match w.letter {
                b'I' => b'X',
                b'J' => b'Y',
                _ => b'Z',
            };
            w.value = v - current(axis);
            out.substituted.push(k);
        }
    }

    /// A G code: its LinuxCNC number for the machine-state layer, or `None`
    /// when the front handles it (frames, dwell, modes with no geometry).
    fn g_code(
        &mut self,
        line: &LineRun,
        v: f64,
        at: (usize, usize),
        out: &mut Out,
        flags: &mut GFlags,
    ) -> Result<Option<f64>, GcodeError> {
        if v.fract() != 0.0 {
            return Err(self.feature(line, &format!("G{v}"), at.0, at.1));
        }
        let code = v as i64;
        Ok(match code {
            0..=3 | 17..=19 | 90 | 91 | 93 | 94 | 95 | 40..=42 => Some(v),
            70 | 700 => Some(20.0),
            71 | 710 => Some(21.0),
            53 | 153 => {
                flags.suppress = true;
                Some(53.0)
            }
            // G54–G57 are LinuxCNC's systems 1–4 (origins from --offset).
            54..=57 => Some(v),
            500 => {
                flags.settable_off = true;
                out.statements.push(at.0..at.1);
                None
            }
            // The settable frames beyond G54–G57 (*Fundamentals*, "Settable
            // zero offset (G54 to G57, G505 to G599)"): their origins from
            // `--offset G505=…`; one not given is zero, as G54's is.
            505..=599 => {
                let origin = self
                    .settable_frames
                    .get(&(code as u16))
                    .copied()
                    .unwrap_or_default();
                flags.settable = Some(origin);
                out.statements.push(at.0..at.1);
                None
            }
            4 => {
                flags.dwell = true;
                out.statements.push(at.0..at.1);
                None
            }
            9 | 60 | 64 | 601 | 602 | 603 | 641 | 642 | 643 | 644 | 645 | 25 | 26 | 450 | 451
            | 460 | 461 | 462 => {
                out.statements.push(at.0..at.1);
                None
            }
            _ => return Err(self.feature(line, &format!("G{code}"), at.0, at.1)),
        })
    }
}

/// `CIP` or `CT` (modal, motion group 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum ArcForm {
    Intermediate,
    Tangential,
}

/// A block's circle words the machine-state layer does not read.
#[derive(Default)]
struct ArcWords {
    form: Option<ArcForm>,
    /// The `CIP`/`CT` name's span (0, 0: not in this block).
    at: (usize, usize),
    angle: Option<(f64, usize, usize)>,
    turns: Option<(f64, usize, usize)>,
    inter: [Option<(f64, Mode)>; 3],
}

/// The last move as `CT` continues it.
#[derive(Clone, Copy, Debug)]
struct LastMove {
    start: [f64; 3],
    kind: LastKind,
}

#[derive(Clone, Copy, Debug)]
enum LastKind {
    Straight,
    Arc {
        centre: [f64; 3],
        cw: bool,
        plane: crate::gcode::Plane,
    },
    /// A circle by `CR=`: its centre is the machine-state layer's.
    Unknown,
    /// A circle in space (`CIP` out of the working plane, or a `CT` after
    /// one): its centre and the unit normal it runs counter-clockwise about.
    Space {
        centre: [f64; 3],
        normal: [f64; 3],
    },
}

/// The centre of the circle through `a`, `b`, `c` (2-D); `None` when they
/// lie on one line (or two coincide).
fn circumcentre(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<[f64; 2]> {
    let d = 2.0 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]));
    let size = [b[0] - a[0], b[1] - a[1], c[0] - a[0], c[1] - a[1]]
        .iter()
        .map(|v| v.abs())
        .fold(0.0f64, f64::max);
    if !(d.abs() > 1e-9 * size * size) || size < 1e-9 {
        return None;
    }
    let (aa, bb, cc) = (
        a[0] * a[0] + a[1] * a[1],
        b[0] * b[0] + b[1] * b[1],
        c[0] * c[0] + c[1] * c[1],
    );
    Some([
        (aa * (b[1] - c[1]) + bb * (c[1] - a[1]) + cc * (a[1] - b[1])) / d,
        (aa * (c[0] - b[0]) + bb * (a[0] - c[0]) + cc * (b[0] - a[0])) / d,
    ])
}

/// Letters of the Euler angle words `A2= B2= C2=` under `ORIEULER` in a
/// handed-on block (not axis letters; the rewriter reads them).
pub(crate) const ORIENTATION_ANGLE_LETTERS: [u8; 3] = [b'4', b'5', b'6'];
/// Letters of the RPY angle words `A2= B2= C2=` under `ORIRPY`.
pub(crate) const ORIENTATION_RPY_LETTERS: [u8; 3] = [b'7', b'8', b'9'];

/// The orientation words of a block: each component's value and span.
#[derive(Default)]
struct Orientation {
    vector: [Option<(f64, usize, usize)>; 3],
    angles: [Option<(f64, usize, usize)>; 3],
}

impl Orientation {
    fn given(&self) -> bool {
        self.vector.iter().chain(&self.angles).any(Option::is_some)
    }

    /// From the first orientation word's start to the last one's end.
    fn span(&self) -> (usize, usize) {
        self.vector
            .iter()
            .chain(&self.angles)
            .flatten()
            .fold((usize::MAX, 0), |(s, e), c| (s.min(c.1), e.max(c.2)))
    }
}

/// The orientation modes of the control (*Job planning*, "Orientation
/// programming"; the G groups 50 and 51 and `ORIWKS`/`ORIMKS`).
#[derive(Clone, Copy, Debug, Default)]
struct OriModes {
    /// `ORIRPY` (else `ORIEULER`, the reset setting): how `A2 B2 C2` read.
    rpy: bool,
    /// `ORIMKS` (else `ORIWKS`, the basic setting): the orientation turns
    /// in the machine's coordinate system, the rotary axes interpolated
    /// linearly.
    machine: bool,
    /// `ORIAXES` (else `ORIVECT`/`ORIPLANE`, the reset setting): the rotary
    /// axes interpolated linearly.
    axes: bool,
}

impl OriModes {
    fn set(&mut self, name: &str) {
        match name {
            "ORIEULER" => self.rpy = false,
            "ORIRPY" => self.rpy = true,
            "ORIWKS" => self.machine = false,
            "ORIMKS" => self.machine = true,
            "ORIAXES" => self.axes = true,
            "ORIVECT" | "ORIPLANE" => self.axes = false,
            _ => {}
        }
    }
}

/// The tool direction of orientation angles: Euler (`ORIEULER`, Z–X–Z:
/// `Rz(A2)·Rx(B2)·Rz(C2)·Z`, C2 turning about the tool itself) or RPY
/// (`ORIRPY`, `Rz(C2)·Ry(B2)·Rx(A2)·Z`, the order of `ROT`).
pub(crate) fn angles_direction(rpy_angles: bool, a: f64, b: f64, c: f64) -> [f64; 3] {
    let m = if rpy_angles {
        rpy(a, b, c)
    } else {
        let (sa, ca) = a.to_radians().sin_cos();
        let (sb, cb) = b.to_radians().sin_cos();
        return [sa * sb, -ca * sb, cb];
    };
    [m[0][2], m[1][2], m[2][2]]
}

/// The angles of direction `v` as `angles_direction` reads them, the third
/// angle `c` kept (Euler: C2 does not turn the direction; RPY: A2 and B2
/// for the given C2).
pub(crate) fn direction_angles(rpy_angles: bool, v: [f64; 3], c: f64) -> [f64; 3] {
    if rpy_angles {
        let (sc, cc) = c.to_radians().sin_cos();
        // u = Rz(−c)·v = (cos a sin b, −sin a, cos a cos b).
        let u = [cc * v[0] + sc * v[1], -sc * v[0] + cc * v[1], v[2]];
        let a = (-u[1]).atan2((u[0] * u[0] + u[2] * u[2]).sqrt());
        let b = u[0].atan2(u[2]);
        [a.to_degrees(), b.to_degrees(), c]
    } else {
        let b = v[2].clamp(-1.0, 1.0).acos();
        let a = if (v[0] * v[0] + v[1] * v[1]).sqrt() < 1e-12 {
            0.0
        } else {
            v[0].atan2(-v[1])
        };
        [a.to_degrees(), b.to_degrees(), c]
    }
}

/// What a block's G codes ask of the front.
#[derive(Default, PartialEq)]
struct GFlags {
    /// `G4`: F and S are the dwell.
    dwell: bool,
    /// `SUPA`/`G53`/`G153`: the frames are suppressed for the block.
    suppress: bool,
    /// `G500`: no settable frame.
    settable_off: bool,
    /// `G505`–`G599`: this settable frame's origin.
    settable: Option<crate::axes::Axes>,
}

/// What a line's statements said besides its words ([`SinumerikFront::statements`]),
/// read at the block's end ([`SinumerikFront::end_block`]).
struct Said {
    /// A frame statement (`TRANS`, `AROT`…) and where it is.
    frame_op: Option<(String, (usize, usize))>,
    /// `RPL=`.
    rpl: Option<f64>,
    flags: GFlags,
    call: Option<Call>,
    /// `P`: runs of the call.
    repeats: u64,
    /// The block has axis words.
    axis_words: bool,
    /// `I J K` given `AC(…)`: word index and value.
    centre_abs: Vec<(usize, f64)>,
    orientation: Orientation,
    /// `D`: the cutting edge and its word's end.
    tool_edge: Option<(f64, usize)>,
    arc: ArcWords,
    spline_words: splines::SplineWords,
    /// `BSPLINE` and where it is.
    bspline: Option<(usize, usize)>,
    /// `RND=`, `RNDM=`, `CHF=`, `CHR=`, `FRC=`, `FRCM=` ([`corners`]).
    corner_words: Option<Box<corners::CornerWords>>,
}

impl Said {
    /// A plain line's: its words only.
    fn words_only(axis_words: bool) -> Said {
        Said {
            frame_op: None,
            rpl: None,
            flags: GFlags::default(),
            call: None,
            repeats: 1,
            axis_words,
            centre_abs: Vec::new(),
            orientation: Orientation::default(),
            tool_edge: None,
            arc: ArcWords::default(),
            spline_words: splines::SplineWords::default(),
            bspline: None,
            corner_words: None,
        }
    }
}

/// Where a line being run comes from.
struct LineRun<'a> {
    raw: &'a [u8],
    line: usize,
    file: usize,
    first_reading: bool,
}

/// What a line hands on, in the source line's byte ranges.
#[derive(Clone)]
struct Out {
    words: Vec<Word>,
    keywords: Vec<KeywordWord>,
    statements: Vec<std::ops::Range<usize>>,
    comments: Vec<std::ops::Range<usize>>,
    assignments: Vec<std::ops::Range<usize>>,
    deleted: bool,
    /// A value comes from a variable or an expression.
    computed: bool,
    absolute: Vec<usize>,
    relative: Vec<usize>,
    /// Words whose value differs from their text (written as numbers when flat).
    substituted: Vec<usize>,
    /// Words the front worked out, with no text in the line (zero width at
    /// their place): written `LETTERvalue` in the flat block.
    synthetic: Vec<usize>,
    /// The block is written flat even when read once in sequence (its text
    /// says what the machine-state layer cannot read: `CIP`, `CT`, `AR=`).
    flat: bool,
}

impl Out {
    /// Whether the block's axis words are increments: its own last `G90`/
    /// `G91`, else the modal setting `modal`.
    fn incremental(&self, modal: bool) -> bool {
        self.words
            .iter()
            .rev()
            .find(|w| w.letter == b'G' && (w.value == 90.0 || w.value == 91.0))
            .map_or(modal, |w| w.value == 91.0)
    }

    /// The words in the order of the line (the ones the front worked out
    /// at their place), the index lists following them.
    fn sort_words(&mut self) {
        // Most lines: already in order (no allocation).
        if self.words.is_sorted_by_key(|w| w.start) {
            return;
        }
        let mut order: Vec<usize> = (0..self.words.len()).collect();
        order.sort_by_key(|&i| self.words[i].start);
        if order.iter().enumerate().all(|(k, &i)| k == i) {
            return;
        }
        let mut at = vec![0; order.len()];
        for (k, &i) in order.iter().enumerate() {
            at[i] = k;
        }
        self.words = order.iter().map(|&i| self.words[i]).collect();
        for list in [
            &mut self.absolute,
            &mut self.relative,
            &mut self.substituted,
            &mut self.synthetic,
        ] {
            for i in list.iter_mut() {
                *i = at[*i];
            }
        }
    }

    fn new(_len: usize) -> Out {
        Out {
            words: Vec::new(),
            keywords: Vec::new(),
            statements: Vec::new(),
            comments: Vec::new(),
            assignments: Vec::new(),
            deleted: false,
            computed: false,
            absolute: Vec::new(),
            relative: Vec::new(),
            substituted: Vec::new(),
            synthetic: Vec::new(),
            flat: false,
        }
    }
}

enum Piece {
    Word(usize),
    Keyword(usize),
    Statement,
    Comment,
}

fn word(
    letter: u8,
    value: f64,
    start: usize,
    end: usize,
    decimals: u8,
    point: bool,
    computed: bool,
) -> Word {
    Word {
        letter,
        value,
        start,
        end,
        decimals,
        point,
        expr: computed.then_some(0),
    }
}

/// The axis letters of [`is_axis`], one bit each (bit 0: `A`).
const AXIS_LETTERS: u32 = letter_bits(b"XYZABCUVW");

/// `N`, `G` and `F`, one bit each: the letters of [`inert_letters`].
const NGF_LETTERS: u32 = letter_bits(b"NGF");

/// Upper-case letters as bits (bit 0: `A`).
const fn letter_bits(letters: &[u8]) -> u32 {
    let mut bits = 0;
    let mut k = 0;
    while k < letters.len() {
        bits |= 1 << (letters[k] - b'A');
        k += 1;
    }
    bits
}

/// What a plain line's letters are (one bit each, bit 0: `A`).
#[derive(Clone, Copy, Default)]
struct PlainLetters {
    /// The letters written.
    all: u32,
    /// The letters written more than once.
    repeated: u32,
    /// A `G1` is written.
    g1: bool,
    /// A G code other than `G1` is written.
    other_g: bool,
}

/// The letters of the words of a plain line in a quiet state that change
/// nothing in LinuxCNC's machine-state layer, one bit each, which it then
/// passes over ([`Block::machine_words`]): the block number (the line's one
/// `N`: the layer reads none), `G1` under `G1` without cutter compensation
/// (the line's one G code: its axis words run the same move), `F` at the
/// feed in force (the line's one `F`, no G code but such a `G1`, not
/// inverse time, under `G0`/`G1`). None unless the line has a word of an
/// axis the machine has (`machine_axes`, its letters): then the move runs
/// with or without them, and no error, warning or state differs.
fn inert_letters(
    letters: PlainLetters,
    words: &[Word],
    machine_axes: u32,
    modal: &crate::gcode::ModalState,
) -> u32 {
    use crate::gcode::machine::modal::{CutterComp, MotionMode};
    const N: u32 = letter_bits(b"N");
    const G: u32 = letter_bits(b"G");
    const F: u32 = letter_bits(b"F");
    if letters.all & machine_axes == 0 {
        return 0;
    }
    let once = letters.all & !letters.repeated;
    let mut inert = once & N;
    let g1 = once & G != 0
        && letters.g1
        && modal.motion == MotionMode::Linear
        && modal.cutter_comp == CutterComp::Off;
    if g1 {
        inert |= G;
    }
    if once & F != 0
        && (letters.all & G == 0 || g1)
        && !modal.inverse_time
        && matches!(modal.motion, MotionMode::Rapid | MotionMode::Linear)
        && words
            .iter()
            .find(|w| w.letter == b'F')
            .is_some_and(|f| f.value * modal.units.scale() == modal.feed)
    {
        inert |= F;
    }
    inert
}

fn is_axis(letter: u8) -> bool {
    matches!(
        letter,
        b'X' | b'Y' | b'Z' | b'A' | b'B' | b'C' | b'U' | b'V' | b'W'
    )
}

fn r_number(name: &str) -> Option<usize> {
    let rest = name.strip_prefix('R')?;
    (!rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit())).then(|| rest.parse().ok())?
}

/// What an address written with `=` is.
enum Address {
    /// A word the machine-state layer reads (its letter).
    Word(u8),
    /// `CR=`: the arc radius (LinuxCNC's `R`).
    Radius,
    /// Passed through (`SPOS=`, `S1=`…).
    Pass,
    /// `P=`: runs of a subprogram.
    Repeat,
    /// `SD=` (`b'D'`), `PL=` (`b'L'`), `PW=` (`b'W'`): a B spline's degree,
    /// parameter interval and point weight (`splines`).
    Spline(u8),
    /// `RPL=`: rotation in the plane.
    RotPlane,
    /// A component of the orientation vector `A3= B3= C3=`.
    Vector(usize),
    /// An orientation angle `A2= B2= C2=` (Euler or RPY, `ORIEULER`/`ORIRPY`).
    Angle(usize),
    /// `AR=`: an arc's opening angle.
    ArcAngle,
    /// `TURN=`: a helix's full turns beyond the first.
    Turns,
    /// `I1= J1= K1=`: `CIP`'s intermediate point.
    Intermediate(usize),
    /// A contour corner's word (`corners`): `RND=` (`b'R'`), `RNDM=`
    /// (`b'M'`), `CHF=` (`b'F'`), `CHR=` (`b'C'`), `FRC=` (`b'f'`), `FRCM=`
    /// (`b'm'`).
    Corner(u8),
}

fn address(name: &str) -> Option<Address> {
    Some(match name {
        "X" | "Y" | "Z" | "A" | "B" | "C" | "U" | "V" | "W" | "I" | "J" | "K" | "F" | "S" | "T" => {
            Address::Word(name.as_bytes()[0])
        }
        "CR" => Address::Radius,
        "P" => Address::Repeat,
        "RPL" => Address::RotPlane,
        "AR" => Address::ArcAngle,
        "I1" => Address::Intermediate(0),
        "J1" => Address::Intermediate(1),
        "K1" => Address::Intermediate(2),
        "A3" => Address::Vector(0),
        "B3" => Address::Vector(1),
        "C3" => Address::Vector(2),
        "A2" => Address::Angle(0),
        "B2" => Address::Angle(1),
        "C2" => Address::Angle(2),
        "RND" => Address::Corner(b'R'),
        "RNDM" => Address::Corner(b'M'),
        "CHF" => Address::Corner(b'F'),
        "CHR" => Address::Corner(b'C'),
        "FRC" => Address::Corner(b'f'),
        "FRCM" => Address::Corner(b'm'),
        "TURN" => Address::Turns,
        "SD" => Address::Spline(b'D'),
        "PL" => Address::Spline(b'L'),
        "PW" => Address::Spline(b'W'),
        "D" | "H" | "M" | "SPOS" | "SPOSA" | "S1" | "S2" | "M1" | "M2" | "FA" | "ACC" | "OVR"
        | "OFFN" | "ADIS" | "ADISPOS" | "CTOL" | "OTOL" | "STOLF" | "FFWON" | "G" => Address::Pass,
        _ if name.len() == 2 && name.as_bytes()[1].is_ascii_digit() && !name.starts_with('R') => {
            Address::Pass
        }
        _ => return None,
    })
}

/// How an `=` value is written: plain, `AC(…)`, `IC(…)` (also `DC`,
/// `ACP`, `ACN` for rotary axes: absolute, the direction left to the
/// control's path).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Mode {
    Plain,
    Ac,
    Ic,
}

/// An argument list `(a, b, …)` at the cursor, when one follows (none:
/// no arguments), and the end of the last token read. An empty place
/// (`CYCLE800(1,,0)`, `SET(0,,,9)`) is 0.
fn argument_list(cur: &mut Cursor) -> Result<(Vec<Expr>, usize), syntax::SyntaxError> {
    let mut args = Vec::new();
    if cur.eat_sym("(") && !cur.eat_sym(")") {
        loop {
            if matches!(
                cur.peek(),
                Some(Token {
                    tok: Tok::Sym("," | ")"),
                    ..
                })
            ) {
                args.push(Expr::Num(0.0));
            } else {
                args.push(cur.expr()?);
            }
            if cur.eat_sym(")") {
                break;
            }
            cur.expect_sym(",")?;
        }
    }
    Ok((args, cur.last_end()))
}

fn value_expr(cur: &mut Cursor) -> Result<(Expr, Mode), syntax::SyntaxError> {
    if let (
        Some(Token {
            tok: Tok::Name(n), ..
        }),
        Some(Token {
            tok: Tok::Sym("("), ..
        }),
    ) = (cur.peek(), cur.peek_at(1))
    {
        let mode = match n.as_ref() {
            "AC" | "DC" | "ACP" | "ACN" => Some(Mode::Ac),
            "IC" => Some(Mode::Ic),
            _ => None,
        };
        if let Some(mode) = mode {
            cur.pos += 2;
            let e = cur.expr()?;
            cur.expect_sym(")")?;
            return Ok((e, mode));
        }
    }
    Ok((cur.expr()?, Mode::Plain))
}

/// The parameters of a `PROC` line: `PROC NAME(REAL X, VAR INT N)`.
/// One formal parameter of a `PROC` line.
struct ProcParam {
    ty: VarType,
    name: String,
    /// `VAR`: by reference.
    by_ref: bool,
    /// An array (`VAR REAL A[3, 4]`): its dimensions, `None` where left
    /// open (`A[,4]`).
    array: Option<Vec<Option<usize>>>,
}

fn proc_params(rest: &[u8]) -> Vec<ProcParam> {
    let text = String::from_utf8_lossy(rest).to_ascii_uppercase();
    let Some(open) = text.find('(') else {
        return Vec::new();
    };
    let close = text[open..].find(')').map_or(text.len(), |c| open + c);
    // Split at the commas outside brackets (`VAR REAL A[3, 4], INT N`).
    let mut params = Vec::new();
    let (mut depth, mut from) = (0usize, open + 1);
    for (i, c) in text[open + 1..close].char_indices() {
        match c {
            '[' => depth += 1,
            ']' => depth = depth.saturating_sub(1),
            ',' if depth == 0 => {
                params.push(&text[from..open + 1 + i]);
                from = open + 2 + i;
            }
            _ => {}
        }
    }
    params.push(&text[from..close]);
    params
        .into_iter()
        .filter_map(|p| {
            let by_ref = p.split_whitespace().next() == Some("VAR");
            let mut parts = p.split_whitespace().filter(|w| *w != "VAR");
            let ty = VarType::from_name(parts.next()?.split('[').next()?)?;
            let word = parts.next()?;
            let name = word.split('[').next()?.to_string();
            let array = p.find('[').map(|b| {
                let e = p[b..].find(']').map_or(p.len(), |e| b + e);
                p[b + 1..e]
                    .split(',')
                    .map(|d| d.trim().parse::<usize>().ok())
                    .collect()
            });
            Some(ProcParam {
                ty,
                name,
                by_ref,
                array,
            })
        })
        .collect()
}

/// The rotation of `ROT X a Y b Z c`: about Z by c, then about the new Y by
/// b, then about the new X by a (degrees; `R = Rz·Ry·Rx`).
fn rpy(a: f64, b: f64, c: f64) -> [[f64; 3]; 3] {
    let (sa, ca) = a.to_radians().sin_cos();
    let (sb, cb) = b.to_radians().sin_cos();
    let (sc, cc) = c.to_radians().sin_cos();
    let rx = [[1.0, 0.0, 0.0], [0.0, ca, -sa], [0.0, sa, ca]];
    let ry = [[cb, 0.0, sb], [0.0, 1.0, 0.0], [-sb, 0.0, cb]];
    let rz = [[cc, -sc, 0.0], [sc, cc, 0.0], [0.0, 0.0, 1.0]];
    let mul = |p: [[f64; 3]; 3], q: [[f64; 3]; 3]| {
        let mut m = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = (0..3).map(|k| p[i][k] * q[k][j]).sum();
            }
        }
        m
    };
    mul(mul(rz, ry), rx)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::axes::Axes;
    use crate::gcode::{Branch, InterpretOptions, OrientationSolver, Program, ProgramSetup};

    /// A head that tilts the tool by A from Z, then turns it about Z by C:
    /// axis = (sin A sin C, −sin A cos C, cos A).
    #[derive(Debug)]
    struct TiltTurn;

    impl OrientationSolver for TiltTurn {
        fn joints_for_axis(&self, axis: [f64; 3], _: Branch, previous: &Axes) -> Option<Axes> {
            let mut j = *previous;
            j.a = axis[2].clamp(-1.0, 1.0).acos().to_degrees();
            j.c = axis[0].atan2(-axis[1]).to_degrees();
            Some(j)
        }
        fn axis_of(&self, j: &Axes) -> [f64; 3] {
            let (sa, ca) = j.a.to_radians().sin_cos();
            let (sc, cc) = j.c.to_radians().sin_cos();
            [sa * sc, -sa * cc, ca]
        }
        /// `Rz(C)·Rx(A)`.
        fn frame_of(&self, j: &Axes) -> [[f64; 3]; 3] {
            let (sa, ca) = j.a.to_radians().sin_cos();
            let (sc, cc) = j.c.to_radians().sin_cos();
            [
                [cc, -sc * ca, sc * sa],
                [sc, cc * ca, -cc * sa],
                [0.0, sa, ca],
            ]
        }
        fn swivel_order(&self) -> [crate::axes::Axis; 2] {
            [crate::axes::Axis::C, crate::axes::Axis::A]
        }
    }

    /// `text` as a program named `t.mpf`, read with `setup`.
    fn program_of(text: &str, setup: ProgramSetup) -> Program {
        Program::new(
            Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
            Path::new("t.mpf"),
            setup,
        )
    }

    /// The move ends of `text` read with the [`TiltTurn`] head.
    fn ends(text: &str) -> Result<Vec<Axes>, GcodeError> {
        let setup = ProgramSetup {
            dialect: Some(crate::gcode::Dialect::Sinumerik),
            orientation: Some(std::sync::Arc::new(TiltTurn)),
            ..Default::default()
        };
        let mut run = program_of(text, setup).run(InterpretOptions::default());
        let mut out = Vec::new();
        while let Some(step) = run.next() {
            let (_, event, _) = step?;
            out.extend(event.motions().map(|m| m.end));
        }
        Ok(out)
    }

    /// Each block's words the machine-state layer passes over (their
    /// letters) and each run's moves (end and feed), read in `dialect`.
    fn inert_and_moves(
        text: &str,
        dialect: crate::gcode::Dialect,
    ) -> (Vec<String>, Vec<crate::gcode::Motion>) {
        let setup = ProgramSetup {
            dialect: Some(dialect),
            ..Default::default()
        };
        let mut run = program_of(text, setup).run(InterpretOptions::default());
        let (mut inert, mut moves) = (Vec::new(), Vec::new());
        while let Some(step) = run.next() {
            let (block, event, _) = step.expect("the program runs");
            let read = block.machine_words();
            inert.push(
                block
                    .words
                    .iter()
                    .filter(|w| !read.contains(w))
                    .map(|w| w.letter as char)
                    .collect(),
            );
            moves.extend(event.motions().copied());
        }
        (inert, moves)
    }

    #[test]
    fn words_that_change_nothing_are_passed_over_and_the_moves_stay() {
        let text = "G0 X0 Y0 Z0\n\
                    N10 G1 X1 F800\n\
                    N20 G1 X2 F800\n\
                    N30 X3 F900\n\
                    N40 X4 Y1 F900\n\
                    N50 G0 X5 F900\n\
                    N60 X6 F900\n\
                    N70 G1 F900\n\
                    N80 G93 G1 X9 F2\n\
                    N90 G1 X10 F2\n\
                    N100 G94 G1 X11 F900\n\
                    N110 G1 X12 F900\n\
                    M30\n";
        let (inert, moves) = inert_and_moves(text, crate::gcode::Dialect::Sinumerik);
        let expected = [
            "", "N", "NGF", "N", "NF", "N", "NF", "", "N", "NG", "N", "NGF", "",
        ];
        assert_eq!(inert, expected);
        // LinuxCNC's reading of the same lines reads every word.
        let (all_read, linuxcnc) = inert_and_moves(text, crate::gcode::Dialect::LinuxCnc);
        assert!(all_read.iter().all(String::is_empty));
        assert_eq!(moves.len(), 11);
        assert_eq!(moves, linuxcnc);
    }

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() < 1e-9
    }

    #[test]
    fn a_vector_turns_the_rotary_joints_through_the_chain() {
        let s = 0.5f64.sqrt();
        let e = ends(&format!(
            "TRAORI\nG1 X1 Y2 Z3 A3={s} B3=0 C3={s} F100\nG1 X2 B3=-1 C3=1\nM30\n"
        ))
        .unwrap();
        // (s, 0, s): tilted 45° towards +X → A 45, C 90.
        assert!(close(e[0].a, 45.0) && close(e[0].c, 90.0), "{:?}", e[0]);
        assert_eq!([e[0].x, e[0].y, e[0].z], [1.0, 2.0, 3.0]);
        // A3 unwritten is 0; the length does not matter: (0, −1, 1) → A 45, C 0.
        assert!(close(e[1].a, 45.0) && close(e[1].c, 0.0), "{:?}", e[1]);
    }

    #[test]
    fn a_vector_turns_with_the_frame() {
        // ROT Z90: the frame's X is the part's Y; (1, 0, 1) → (0, 1, 1).
        let e = ends("TRAORI\nROT Z90\nG1 X0 Y0 Z0 A3=1 C3=1 F100\nM30\n").unwrap();
        assert!(close(e[0].a, 45.0) && close(e[0].c, 180.0), "{:?}", e[0]);
    }

    #[test]
    fn euler_and_rpy_angles_give_the_vector_they_stand_for() {
        // ORIEULER (the reset setting): A2 about Z, B2 tilting about the new X.
        let e = ends("TRAORI\nG1 X0 Y0 Z0 A2=90 B2=30 C2=77 F100\nM30\n").unwrap();
        let v = TiltTurn.axis_of(&e[0]);
        let want = [0.5, 0.0, 0.75f64.sqrt()];
        assert!((0..3).all(|k| close(v[k], want[k])), "{v:?}");
        // ORIRPY: Rz(C2)·Ry(B2)·Rx(A2)·Z; B2 = 30 alone tilts towards +X.
        let e = ends("TRAORI ORIRPY\nG1 X0 Y0 Z0 B2=30 F100\nM30\n").unwrap();
        let v = TiltTurn.axis_of(&e[0]);
        assert!((0..3).all(|k| close(v[k], want[k])), "{v:?}");
        for rpy_angles in [false, true] {
            for (a, b, c) in [(10.0, 20.0, 30.0), (-40.0, 65.0, 5.0), (0.0, 0.0, 0.0)] {
                let v = angles_direction(rpy_angles, a, b, c);
                let back = direction_angles(rpy_angles, v, c);
                let w = angles_direction(rpy_angles, back[0], back[1], back[2]);
                assert!((0..3).all(|k| (v[k] - w[k]).abs() < 1e-12), "{v:?} {w:?}");
            }
        }
    }

    #[test]
    fn an_additive_cycle800_swivels_on_from_the_active_plane() {
        // 30° about X, then 30° more (additive, _ST 1) = one 60° plane; the
        // direction 0 leaves the rotary axes (no chain needed).
        let two = ends(
            "CYCLE800(1,\"T\",0,57,0,0,0,30,0,0,0,0,0,0)\nCYCLE800(1,\"T\",1,57,0,0,0,30,0,0,0,0,0,0)\nG1 X1 Y2 Z3 F100\nM30\n",
        )
        .unwrap();
        let one =
            ends("CYCLE800(1,\"T\",0,57,0,0,0,60,0,0,0,0,0,0)\nG1 X1 Y2 Z3 F100\nM30\n").unwrap();
        let (a, b) = (two[0].xyz(), one[0].xyz());
        assert!((0..3).all(|k| close(a[k], b[k])), "{a:?} vs {b:?}");
        // Not the same as a fresh 30° plane.
        let fresh =
            ends("CYCLE800(1,\"T\",0,57,0,0,0,30,0,0,0,0,0,0)\nG1 X1 Y2 Z3 F100\nM30\n").unwrap();
        assert!(!close(fresh[0].y, b[1]));
    }

    #[test]
    fn orientation_words_the_control_refuses_are_located() {
        let err = |t: &str| ends(t).unwrap_err().to_string();
        assert!(err("G1 X0 A3=1 F100\nM30\n").contains("needs TRAORI"));
        let e = err("TRAORI\nG1 X0 A10 A3=1 F100\nM30\n");
        assert!(e.contains("given twice") && e.contains(":2:"), "{e}");
        let e = err("TRAORI\nG1 X0 A3=1 B2=4 F100\nM30\n");
        assert!(e.contains("given twice"), "{e}");
        let e = err("TRAORI\nG1 X0 A3=0 F100\nM30\n");
        assert!(e.contains("length 0"), "{e}");
    }
}
