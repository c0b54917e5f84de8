//! The language layer: runs a program's RS274NGC language — parameters,
//! expressions, O-word control flow and subroutines — and yields EXECUTED
//! blocks, every word a number, in execution order.
//!
//! It follows LinuxCNC's interpreter (`interp_o_word.cc`) in its model, so that
//! its edge cases agree:
//! - O-word labels: `sub`/`endsub`/`call`/`return` labels are global; the others
//!   are local to the subroutine that holds them.
//! - Control flow moves by *skipping* forward to the next O-line with a given
//!   label and by *seeking back* to a recorded O-line (loops, calls to a
//!   subroutine defined earlier). A call to a subroutine not seen yet opens
//!   `NAME.ngc` on the subroutine search path, else searches forward in the
//!   current file.
//! - Parameter assignments on a line take effect after the whole line is read
//!   (parallel setting); words use the old values.
//!
//! An executed block is the source line itself when the line is plain G-code
//! read once in sequence from the main file ([`Executed::literal`]). Otherwise
//! it is the line *flattened*: computed words replaced by their values
//! (6 decimals, trailing zeros dropped), assignments removed, and a comment
//! naming the source appended: `(volcomp: line 12)`, `(volcomp: drill.ngc:3)`.
//! Writers copy executed blocks, so a program with loops comes out flat.
//! A subroutine definition in the main file is handed on as written where the
//! program passes over it ([`Executed::passed`]; LinuxCNC skips it there too),
//! so that a written program keeps it; its calls come flat.
//!
//! Streaming: memory is bounded by the call stack, the parameter table, the
//! O-word table and a cache of parsed lines inside loops and subroutines (at
//! most [`LINE_CACHE_LIMIT`] lines, then lines are re-read) — never by the
//! number of executed blocks. Invariant: the language knows no kinematics and
//! no machine state beyond what the parameter table holds.
use std::collections::HashMap;
use std::io::{BufRead, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::parameters::Parameters;
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::syntax::block::{AssignTarget, Block, LineEnding, OKeyword, OLabel, OWord};
use crate::gcode::syntax::expression::{EvalError, EvalErrorKind, Expr, to_integer};
use crate::gcode::syntax::parser::parse_line;

/// Lines of loop and subroutine bodies kept parsed (then re-read from the file).
pub const LINE_CACHE_LIMIT: usize = 1 << 20;

/// LinuxCNC's `INTERP_SUB_ROUTINE_LEVELS`: call levels, the main program's
/// included (so at most 9 calls are nested).
pub const MAX_CALL_DEPTH: usize = 10;

/// LinuxCNC's `INTERP_SUB_PARAMS`: arguments of a call.
pub const MAX_CALL_ARGUMENTS: usize = 30;

/// A program input: readable line by line and seekable (loops and calls seek).
pub trait ProgramInput: BufRead + Seek + Send {}
impl<T: BufRead + Seek + Send> ProgramInput for T {}

/// Settings of the language layer.
#[derive(Clone, Debug, Default)]
pub struct LanguageOptions {
    /// Folders searched, in order, for `NAME.ngc` when `o<NAME> call` names a
    /// subroutine the program does not define (LinuxCNC's `SUBROUTINE_PATH`).
    pub subroutine_path: Vec<PathBuf>,
    /// Lenient reading: a line that cannot be parsed is passed through verbatim.
    pub lenient: bool,
    /// Honour block delete (`/`): such lines are not executed.
    pub skip_deleted_blocks: bool,
    /// Most lines a run reads (loops and calls counted each time, O-word lines
    /// included) before it is refused as an endless loop (`None`:
    /// `DEFAULT_MAX_EXECUTED_LINES`).
    pub max_executed_lines: Option<u64>,
    /// Most lines read inside loop bodies and subroutine calls (the lines a
    /// program reads more than once, or from another file), checked as they
    /// are read: an endless or runaway loop stops with an error naming it
    /// (`None`: `DEFAULT_MAX_LOOP_LINES`). The program's own lines read once
    /// in sequence do not count: a flat program of any length runs.
    pub max_loop_lines: Option<u64>,
    /// Most moves that no line of the main program spells out one by one:
    /// moves of blocks executed in loops and calls, canned-cycle and spline
    /// expansions (`None`: `DEFAULT_MAX_GENERATED_MOVES`). Checked by
    /// [`crate::gcode::Execution`] as they grow, and up front for a canned cycle in
    /// `repeat` loops (its moves × the loops' counts).
    pub max_generated_moves: Option<u64>,
    /// Drop the subroutine definitions the main program passes over
    /// (`check --flatten`: a program with no O-words). By default they are
    /// handed on as written, not executed ([`Executed::passed`]), so that
    /// writers keep every byte of them.
    pub drop_definitions: bool,
}

/// Lines a run may read: a billion, a thousand times the largest real
/// programs (about 25 GB written flat). LinuxCNC would run an endless loop
/// for ever, and a writer would fill the disk.
pub const DEFAULT_MAX_EXECUTED_LINES: u64 = 1_000_000_000;

/// Lines a run may read inside loops and calls: 10 million (`while [1]` with
/// two moves in its body is stopped after about 6 s of `check`); a real
/// program's loops (a pattern repeated, a probing macro) stay far below.
pub const DEFAULT_MAX_LOOP_LINES: u64 = 10_000_000;

/// Moves a run may generate (loops, calls, canned cycles, splines): 50 million.
pub const DEFAULT_MAX_GENERATED_MOVES: u64 = 50_000_000;

/// A loop being run, for messages and for the estimate of a `repeat`.
#[derive(Clone, Debug)]
struct OpenLoop {
    label: String,
    kind: LabelKind,
    file: usize,
    line: usize,
    /// Calls in progress when it was entered (a return drops the loops of
    /// the call it leaves).
    depth: usize,
    /// A `repeat`'s count.
    count: Option<f64>,
}

/// Where an executed block comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Executed {
    /// Index of the file in `Executor::file_name` (0: the main program).
    pub file: usize,
    /// 1-based line in that file.
    pub line: usize,
    /// The block is the source line as written, executed once in sequence
    /// from the main program: writers may copy or edit it in place.
    pub literal: bool,
    /// The line is not executed: a line of a subroutine definition that the
    /// main program passes over (`o<name> sub` … `endsub`, read in sequence
    /// from the main file, outside calls), handed on as written (`literal`)
    /// so that writers lose none of it. LinuxCNC skips it the same way.
    pub passed: bool,
}

impl Executed {
    /// A block volcomp made from line `line` of file `file` (a rounding, a
    /// chamfer, a spline's chord): executed, not the line as written.
    pub fn made_from(file: usize, line: usize) -> Executed {
        Executed {
            file,
            line,
            literal: false,
            passed: false,
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum LabelKind {
    Sub,
    Do,
    While,
    Repeat,
    If,
}

/// A recorded O-line: where it is, what it opened.
#[derive(Clone, Debug)]
struct LabelEntry {
    file: usize,
    offset: u64,
    line: usize,
    kind: LabelKind,
    repeat_left: Option<i64>,
}

/// What the executor does with the lines it reads. LinuxCNC keeps it in
/// several flags (`skipping_o`, `skipping_to_sub`, `defining_sub`) of which
/// only these combinations occur.
#[derive(Clone, Debug, PartialEq, Eq)]
enum Mode {
    /// Lines are executed.
    Run,
    /// Skipping forward to the next O-line with this (resolved) label: an
    /// `if` branch not taken, a loop left, a `break` or a `continue`.
    Skip(String),
    /// Looking for the `sub` line of the subroutine being called: the first
    /// one of a subroutine file just opened (`None`), or the one with this
    /// label, forward in the main program.
    FindSub(Option<String>),
    /// Passing over the definition of subroutine `name` in the main program,
    /// up to its `endsub`; `passing`: its lines are handed on as written
    /// ([`Executed::passed`]).
    Define { name: String, passing: bool },
}

impl Mode {
    /// The label of the O-line that ends the skip (`None`: running, or any
    /// `sub` line ends it).
    fn awaited(&self) -> Option<&str> {
        match self {
            Mode::Run | Mode::FindSub(None) => None,
            Mode::Skip(label) | Mode::FindSub(Some(label)) | Mode::Define { name: label, .. } => {
                Some(label)
            }
        }
    }
}

/// LinuxCNC's flags that outlive the line that sets them (`executed_if`,
/// `doing_break`, `doing_continue` of its interpreter state), kept as it
/// keeps them: where they leak is visible (after a `break` out of a `while`
/// the next do-while runs its body once).
#[derive(Clone, Copy, Debug, Default)]
struct Latches {
    /// The last `if`, `elseif` or `else` test passed.
    executed_if: bool,
    /// A `break` was read (cleared only at the end of a do-while).
    breaking: bool,
    /// A `continue` was read (cleared at the end of the loop it skips to).
    continuing: bool,
}

/// An O-line being executed: its block, its O-word and its resolved label.
struct OLine<'a> {
    block: &'a Block,
    o: &'a OWord,
    label: String,
}

impl OLine<'_> {
    /// An error located at the O-word.
    fn error(&self, message: String) -> GcodeError {
        located(
            ErrorKind::OWord(message),
            self.block,
            self.o.start,
            self.o.end,
        )
    }

    /// The value of the line's expression `index`.
    fn eval(&self, index: u32, params: &Parameters) -> Result<f64, GcodeError> {
        expr(self.block, index)
            .eval(params)
            .map_err(|e| eval_error(e, self.block))
    }
}

/// A subroutine call in progress.
#[derive(Clone, Debug)]
struct Frame {
    name: String,
    return_file: usize,
    return_offset: u64,
    return_line: usize,
    saved: [f64; 30],
    /// Loops and ifs opened inside this call (for the `literal` rule).
    loops: usize,
}

struct SourceFile {
    name: String,
    path: Option<PathBuf>,
    input: Box<dyn ProgramInput>,
    /// Offset and line of the next line to read.
    offset: u64,
    line: usize,
    /// Whether the input sits at `offset` (false after a seek was requested).
    positioned: bool,
}

/// A parsed source line, cached inside loops and subroutines.
struct CachedLine {
    block: Arc<Block>,
    next_offset: u64,
}

/// A source line as [`Executor::read_line`] hands it on: read just now and
/// owned (when it is executed as written it becomes the executed block, and
/// the executed block's buffers are kept for the next read: no copy, no
/// allocation per line), or shared with the line cache.
enum SourceLine {
    /// (Boxed: handing it on moves a pointer, not the block.)
    Read(Box<Block>),
    Cached(Arc<Block>),
}

impl std::ops::Deref for SourceLine {
    type Target = Block;

    fn deref(&self) -> &Block {
        match self {
            SourceLine::Read(block) => block,
            SourceLine::Cached(block) => block,
        }
    }
}

/// The language layer. Call [`Executor::next_block`] until it returns `None`.
pub struct Executor {
    options: LanguageOptions,
    /// Lines read so far (the budget of `options.max_executed_lines`).
    lines_stepped: u64,
    files: Vec<SourceFile>,
    current: usize,
    labels: HashMap<String, LabelEntry>,
    frames: Vec<Frame>,
    /// What the lines read now are for (run, skipped, searched for a `sub`,
    /// a definition passed over).
    mode: Mode,
    /// LinuxCNC's flags that outlive the line that sets them.
    latches: Latches,
    /// Offsets of the definitions handed on (a definition inside a loop of
    /// the main program is read once per iteration, written once).
    passed_definitions: std::collections::HashSet<u64>,
    /// Loops entered in the main program (not inside a call).
    main_loops: usize,
    /// The loops being run, innermost last.
    open_loops: Vec<OpenLoop>,
    /// Lines read inside loops and calls (the budget of
    /// `options.max_loop_lines`).
    loop_lines: u64,
    cache: HashMap<(usize, u64), CachedLine>,
    /// The source line being read (reused), and the executed block handed out.
    /// The buffers of the next line to read (`None` while they are lent).
    source: Option<Box<Block>>,
    out: Box<Block>,
    executed: Executed,
    percent_seen: bool,
    /// A line of the main file that is not blank was read.
    content_seen: bool,
    finished: bool,
    ended: bool,
    text: String,
}

fn located(kind: ErrorKind, block: &Block, start: usize, end: usize) -> GcodeError {
    GcodeError::at(kind, block.line, &block.raw, start, end)
}

fn eval_error(e: EvalError, block: &Block) -> GcodeError {
    located(ErrorKind::Eval(e.kind), block, e.start, e.end)
}

impl Executor {
    /// Run the program read from `input`, named `name` in messages (its path,
    /// when it is a file, anchors nothing: subroutine files come only from
    /// [`LanguageOptions::subroutine_path`]).
    pub fn new(input: Box<dyn ProgramInput>, name: &Path, options: LanguageOptions) -> Self {
        Executor {
            options,
            lines_stepped: 0,
            files: vec![SourceFile {
                name: name.display().to_string(),
                path: None,
                input,
                offset: 0,
                line: 0,
                positioned: true,
            }],
            current: 0,
            labels: HashMap::new(),
            frames: Vec::new(),
            mode: Mode::Run,
            latches: Latches::default(),
            passed_definitions: std::collections::HashSet::new(),
            main_loops: 0,
            open_loops: Vec::new(),
            loop_lines: 0,
            cache: HashMap::new(),
            source: None,
            out: Box::default(),
            executed: Executed {
                file: 0,
                line: 0,
                literal: true,
                passed: false,
            },
            percent_seen: false,
            content_seen: false,
            finished: false,
            ended: false,
            text: String::new(),
        }
    }

    /// The name of file `index` (0: the main program) as messages show it.
    pub fn file_name(&self, index: usize) -> &str {
        self.files.get(index).map_or("?", |f| f.name.as_str())
    }

    /// The program ended at a closing `%`.
    pub fn percent_ended(&self) -> bool {
        self.ended && self.percent_seen
    }

    /// Lines read from the main program so far.
    pub fn lines_read(&self) -> usize {
        self.files[0].line
    }

    /// The last executed block.
    pub fn block(&self) -> &Block {
        &self.out
    }

    /// Where the last executed block came from.
    pub fn executed(&self) -> &Executed {
        &self.executed
    }

    /// The program has ended (M2/M30 seen by the machine-state layer): lines
    /// after it are not executed. Call when the block that ended it is done.
    pub fn end_program(&mut self) {
        self.ended = true;
    }

    /// After the end of the program: the next line of the main file after the
    /// block that ended it, as written (not executed; `None` at the end of the
    /// file). Writers copy these lines so that no byte of the file is lost.
    /// Only when the program ended in the main file outside loops and calls
    /// (after an end inside them the output is flat and the rest is dropped).
    pub fn next_tail_line(&mut self) -> Option<Result<(), GcodeError>> {
        if !self.ended
            || self.current != 0
            || !self.frames.is_empty()
            || self.main_loops != 0
            || self.mode.awaited().is_some()
        {
            return None;
        }
        match self.read_line() {
            Ok(Some(block)) => {
                self.emit_source(block);
                Some(Ok(()))
            }
            Ok(None) => None,
            Err(e) => Some(Err(e)),
        }
    }

    /// The next executed block, `None` at the end of the program. Errors are
    /// located in the file that holds the line (the path is set for subroutine
    /// files; the caller names the main file).
    /// The block is then [`Executor::block`].
    pub fn next_block(&mut self, params: &mut Parameters) -> Option<Result<(), GcodeError>> {
        if self.finished || self.ended {
            return None;
        }
        match self.step(params) {
            Ok(true) => Some(Ok(())),
            Ok(false) => {
                self.finished = true;
                None
            }
            Err(e) => {
                self.finished = true;
                let e = if self.current > 0 {
                    let file = &self.files[self.current];
                    e.with_path(
                        file.path
                            .clone()
                            .unwrap_or_else(|| file.name.clone().into()),
                    )
                } else {
                    e
                };
                Some(Err(e))
            }
        }
    }

    /// Read lines until one executes; `false` at the end of the program.
    fn step(&mut self, params: &mut Parameters) -> Result<bool, GcodeError> {
        let budget = self
            .options
            .max_executed_lines
            .unwrap_or(DEFAULT_MAX_EXECUTED_LINES);
        loop {
            let Some(block) = self.read_line()? else {
                return self.end_of_file();
            };
            self.lines_stepped += 1;
            if self.lines_stepped > budget {
                return Err(GcodeError::at(
                    ErrorKind::EndlessProgram(budget),
                    block.line,
                    &block.raw,
                    0,
                    block.raw.len(),
                ));
            }
            if !self.frames.is_empty() || self.main_loops > 0 {
                self.loop_lines += 1;
                let limit = self
                    .options
                    .max_loop_lines
                    .unwrap_or(DEFAULT_MAX_LOOP_LINES);
                if self.loop_lines > limit {
                    return Err(GcodeError::at(
                        ErrorKind::LoopLimit {
                            limit,
                            what: "lines in loops and calls",
                            option: "--max-loop-lines",
                            within: self.innermost_loop().unwrap_or_default(),
                        },
                        block.line,
                        &block.raw,
                        0,
                        block.raw.len(),
                    ));
                }
            }
            if let Mode::Define { passing: true, .. } = self.mode {
                // A subroutine definition the main program passes over: its
                // lines go on as written; only its end matters.
                if block.unparsed.is_none()
                    && let Some(o) = &block.o_word
                {
                    self.control(&block, o, params)?;
                }
                self.emit_passed(block);
                return Ok(true);
            }
            let skipping = self.mode != Mode::Run;
            if let Some(err) = &block.unparsed {
                if skipping {
                    self.recycle(block);
                    continue;
                }
                if !self.options.lenient {
                    return Err((**err).clone());
                }
                // Lenient: pass the line through verbatim (the machine-state
                // layer warns about it).
                self.emit_source(block);
                return Ok(true);
            }
            // LinuxCNC: the first line that is not blank may be a lone `%`
            // (the program then ends at the next lone `%`).
            let opening = self.current == 0 && !self.content_seen;
            let text = block
                .raw
                .strip_prefix(b"\xEF\xBB\xBF")
                .unwrap_or(&block.raw);
            if opening && !text.iter().all(|b| b.is_ascii_whitespace()) {
                self.content_seen = true;
            }
            if block.percent {
                if skipping {
                    self.recycle(block);
                    continue;
                }
                if self.current == 0 {
                    // Spaces aside, the line is `%` (a comment makes it an error).
                    let lone = text.iter().filter(|b| !b.is_ascii_whitespace()).eq(b"%");
                    if self.percent_seen && lone {
                        // The closing `%` ends the program (LinuxCNC).
                        self.emit_source(block);
                        self.ended = true;
                        return Ok(true);
                    }
                    if opening && lone {
                        self.percent_seen = true;
                    } else if !self.options.lenient {
                        let at = block.raw.iter().position(|b| *b == b'%').unwrap_or(0);
                        return Err(located(
                            ErrorKind::UnexpectedCharacter("%".into()),
                            &block,
                            at,
                            at + 1,
                        ));
                    }
                }
                self.emit_source(block);
                return Ok(true);
            }
            if let Some(o) = &block.o_word {
                self.control(&block, o, params)?;
                if let Mode::Define { passing: true, .. } = self.mode {
                    // The `sub` line of a definition passed over.
                    self.emit_passed(block);
                    return Ok(true);
                }
                self.recycle(block);
                continue;
            }
            if skipping || (block.deleted && self.options.skip_deleted_blocks) {
                self.recycle(block);
                continue;
            }
            // An ordinary line: evaluate, then assign.
            let literal = !block.uses_language()
                && self.current == 0
                && self.frames.is_empty()
                && self.main_loops == 0;
            if literal {
                self.emit_source(block);
            } else {
                if let Err(e) = self.flatten(&block, params) {
                    if !self.options.lenient {
                        return Err(e);
                    }
                    // Lenient: the line is passed through verbatim, with a warning.
                    let mut verbatim = (*block).clone();
                    verbatim.words.clear();
                    verbatim.assignments.clear();
                    verbatim.exprs.clear();
                    verbatim.unparsed = Some(Box::new(e));
                    self.emit_source(SourceLine::Read(Box::new(verbatim)));
                    return Ok(true);
                }
                self.recycle(block);
                if self.out.is_empty() && self.out.comments.is_empty() {
                    // An assignment-only line: nothing to write.
                    continue;
                }
            }
            return Ok(true);
        }
    }

    /// Hand on a line of a definition passed over, as written.
    fn emit_passed(&mut self, block: SourceLine) {
        self.take_as_out(block);
        self.executed = Executed {
            file: self.current,
            line: self.out.line,
            literal: true,
            passed: true,
        };
    }

    /// Make a source line the executed block as it is written: a line just
    /// read is moved there, and the buffers of the block it replaces become
    /// the next read's.
    fn take_as_out(&mut self, block: SourceLine) {
        match block {
            SourceLine::Read(block) => self.source = Some(std::mem::replace(&mut self.out, block)),
            SourceLine::Cached(block) => (*self.out).clone_from(&block),
        }
    }

    /// Keep the buffers of a line read and not executed as written for the
    /// next read.
    fn recycle(&mut self, block: SourceLine) {
        if let SourceLine::Read(block) = block {
            self.source = Some(block);
        }
    }

    fn emit_source(&mut self, block: SourceLine) {
        self.take_as_out(block);
        self.executed = Executed {
            file: self.current,
            line: self.out.line,
            literal: self.current == 0 && self.frames.is_empty() && self.main_loops == 0,
            passed: false,
        };
        if !self.executed.literal {
            self.append_origin_comment();
        }
    }

    /// The line with its values substituted, assignments applied.
    fn flatten(&mut self, block: &Block, params: &mut Parameters) -> Result<(), GcodeError> {
        // `#<_line>` reads the line being executed (LinuxCNC's sequence number).
        params.set_line(block.line);
        // 1. Evaluate everything with the parameters as they were.
        let mut values: Vec<f64> = Vec::with_capacity(block.words.len());
        for w in &block.words {
            values.push(match w.expr {
                Some(i) => expr(block, i)
                    .eval(params)
                    .map_err(|e| eval_error(e, block))?,
                None => w.value,
            });
        }
        let mut numbered: Vec<(i64, f64, usize, usize)> = Vec::new();
        let mut named: Vec<(String, f64)> = Vec::new();
        for a in &block.assignments {
            let v = expr(block, a.value)
                .eval(params)
                .map_err(|e| eval_error(e, block))?;
            match &a.target {
                AssignTarget::Numbered(i) => {
                    let index = expr(block, *i);
                    let n = index.eval(params).map_err(|e| eval_error(e, block))?;
                    let n = to_integer(n).ok_or_else(|| {
                        located(
                            ErrorKind::Eval(EvalErrorKind::NonInteger),
                            block,
                            index.start,
                            index.end,
                        )
                    })?;
                    numbered.push((n, v, a.start, a.end));
                }
                AssignTarget::Named(name) => named.push((name.clone(), v)),
            }
        }
        // 2. Assign, in order (the last setting of a parameter wins).
        for (n, v, start, end) in numbered {
            params
                .assign_numbered(n, v)
                .map_err(|k| located(ErrorKind::Eval(k), block, start, end))?;
        }
        for (name, v) in named {
            params.assign_named(&name, v).map_err(|k| {
                let a = block.assignments.first();
                located(
                    ErrorKind::Eval(k),
                    block,
                    a.map_or(0, |a| a.start),
                    a.map_or(1, |a| a.end),
                )
            })?;
        }
        // 3. The flat text: words with numbers, no assignments.
        let mut raw: Vec<u8> = Vec::with_capacity(block.raw.len() + 24);
        let mut pos = 0;
        let mut edits: Vec<(usize, usize, Option<usize>)> = Vec::new();
        for (k, w) in block.words.iter().enumerate() {
            if w.expr.is_some() {
                edits.push((w.start, w.end, Some(k)));
            }
        }
        for a in &block.assignments {
            edits.push((a.start, a.end, None));
        }
        edits.sort_by_key(|e| e.0);
        for (start, end, word) in edits {
            raw.extend_from_slice(&block.raw[pos..start]);
            if let Some(k) = word {
                let letter = block.raw[start];
                raw.push(letter);
                self.text.clear();
                push_value(&mut self.text, values[k]);
                raw.extend_from_slice(self.text.as_bytes());
            } else {
                // Drop the assignment and the space before it.
                while raw.last().is_some_and(|b| *b == b' ' || *b == b'\t') {
                    raw.pop();
                }
            }
            pos = end;
        }
        raw.extend_from_slice(&block.raw[pos..]);
        let trimmed_start = raw
            .iter()
            .position(|b| !matches!(b, b' ' | b'\t'))
            .unwrap_or(raw.len());
        raw.drain(..trimmed_start);
        self.out.reset(block.line, block.offset);
        self.out.raw = raw;
        self.out.ending = match block.ending {
            LineEnding::None => LineEnding::Lf,
            e => e,
        };
        parse_line(&mut self.out)?;
        self.executed = Executed {
            file: self.current,
            line: block.line,
            literal: false,
            passed: false,
        };
        if !self.out.is_empty() || !self.out.comments.is_empty() {
            self.append_origin_comment();
        }
        Ok(())
    }

    /// Append `(volcomp: line N)` (or `(volcomp: file.ngc:N)` in a subroutine
    /// file) to `out`.
    fn append_origin_comment(&mut self) {
        let origin = if self.current == 0 {
            format!("line {}", self.executed.line)
        } else {
            let f = &self.files[self.current];
            let name = f
                .path
                .as_ref()
                .and_then(|p| p.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| f.name.clone())
                .replace(['(', ')'], "");
            format!("{name}:{}", self.executed.line)
        };
        let raw = &mut self.out.raw;
        let start = if raw.is_empty() {
            0
        } else {
            raw.push(b' ');
            raw.len()
        };
        raw.extend_from_slice(format!("(volcomp: {origin})").as_bytes());
        let end = raw.len();
        self.out.comments.push(start..end);
        if self.out.ending == LineEnding::None {
            self.out.ending = LineEnding::Lf;
        }
    }

    /// End of the current file.
    fn end_of_file(&mut self) -> Result<bool, GcodeError> {
        if self.current != 0 || !self.frames.is_empty() {
            let name = self.files[self.current].name.clone();
            let what = if let Some(label) = self.mode.awaited() {
                format!("o-word o{label} (searched from a call or a control line)")
            } else {
                "the end of the subroutine".to_string()
            };
            return Err(GcodeError::at(
                ErrorKind::EndOfFileInSubroutine(format!("{what} in {name}")),
                self.files[self.current].line,
                b"",
                0,
                0,
            ));
        }
        if let Some(label) = self.mode.awaited() {
            return Err(GcodeError::at(
                ErrorKind::EndOfFileInSubroutine(format!("o-word o{label}")),
                self.files[0].line,
                b"",
                0,
                0,
            ));
        }
        Ok(false)
    }

    /// Read the next source line of the current file (from the cache when it
    /// was parsed before), `None` at its end.
    fn read_line(&mut self) -> Result<Option<SourceLine>, GcodeError> {
        let file = &mut self.files[self.current];
        let key = (self.current, file.offset);
        if let Some(c) = self.cache.get(&key) {
            let block = c.block.clone();
            file.offset = c.next_offset;
            file.line = block.line;
            file.positioned = false;
            return Ok(Some(SourceLine::Cached(block)));
        }
        if !file.positioned {
            file.input
                .seek(SeekFrom::Start(file.offset))
                .map_err(|e| GcodeError::at(ErrorKind::Io(e.to_string()), file.line, b"", 0, 0))?;
            file.positioned = true;
        }
        file.line += 1;
        let mut block = self.source.take().unwrap_or_default();
        block.reset(file.line, file.offset);
        let (n, too_long) =
            crate::gcode::syntax::reader::read_line_bounded(&mut file.input, &mut block.raw)
                .map_err(|e| GcodeError::at(ErrorKind::Io(e.to_string()), file.line, b"", 0, 0))?;
        if let Some(length) = too_long {
            return Err(crate::gcode::syntax::reader::line_too_long(
                file.line, &block.raw, length,
            ));
        }
        if n == 0 {
            file.line -= 1;
            self.source = Some(block);
            return Ok(None);
        }
        file.offset += n as u64;
        block.ending = LineEnding::take_from(&mut block.raw);
        if let Err(e) = parse_line(&mut block) {
            block.words.clear();
            block.keywords.clear();
            block.comments.clear();
            block.assignments.clear();
            block.o_word = None;
            block.exprs.clear();
            block.unparsed = Some(Box::new(e));
        }
        let in_body = !self.frames.is_empty() || self.main_loops > 0 || block.o_word.is_some();
        if in_body && self.cache.len() < LINE_CACHE_LIMIT {
            let block = Arc::new(*block);
            self.cache.insert(
                key,
                CachedLine {
                    block: block.clone(),
                    next_offset: self.files[self.current].offset,
                },
            );
            return Ok(Some(SourceLine::Cached(block)));
        }
        Ok(Some(SourceLine::Read(block)))
    }

    /// The resolved label of an O-line: global for sub/endsub/call/return,
    /// else local to the subroutine being executed or defined.
    fn label_of(
        &self,
        block: &Block,
        o: &OWord,
        params: &Parameters,
    ) -> Result<String, GcodeError> {
        let base = match &o.label {
            OLabel::Name(n) => n.clone(),
            OLabel::Number(i) => {
                let e = expr(block, *i);
                let v = e.eval(params).map_err(|e| eval_error(e, block))?;
                let n = to_integer(v).ok_or_else(|| {
                    located(
                        ErrorKind::Eval(EvalErrorKind::NonInteger),
                        block,
                        e.start,
                        e.end,
                    )
                })?;
                n.to_string()
            }
        };
        Ok(match o.keyword {
            OKeyword::Sub | OKeyword::EndSub | OKeyword::Call | OKeyword::Return => base,
            _ => {
                let scope = self
                    .frames
                    .last()
                    .map(|f| f.name.as_str())
                    .or(match &self.mode {
                        Mode::Define { name, .. } => Some(name.as_str()),
                        _ => None,
                    })
                    .unwrap_or("");
                format!("{scope}#{base}")
            }
        })
    }

    fn record(&mut self, label: &str, block: &Block, kind: LabelKind) -> Result<(), GcodeError> {
        if let Some(e) = self.labels.get(label) {
            if kind == LabelKind::Sub && (e.file != self.current || e.offset != block.offset) {
                return Err(located(
                    ErrorKind::OWord(format!(
                        "redefining sub o{label}: already defined at line {}",
                        e.line
                    )),
                    block,
                    0,
                    block.raw.len(),
                ));
            }
            return Ok(());
        }
        self.labels.insert(
            label.to_string(),
            LabelEntry {
                file: self.current,
                offset: block.offset,
                line: block.line,
                kind,
                repeat_left: None,
            },
        );
        Ok(())
    }

    fn condition(&self, block: &Block, o: &OWord, params: &Parameters) -> Result<f64, GcodeError> {
        match o.args.first() {
            Some(&i) => expr(block, i)
                .eval(params)
                .map_err(|e| eval_error(e, block)),
            None => Ok(0.0),
        }
    }

    /// Jump to a recorded O-line (the line is read again next).
    fn seek_to(&mut self, entry: &LabelEntry) {
        self.current = entry.file;
        let f = &mut self.files[entry.file];
        f.offset = entry.offset;
        f.line = entry.line - 1;
        f.positioned = false;
    }

    /// Execute an O-line, or look at it while skipping: one function per
    /// O-word kind, each changing [`Mode`] as LinuxCNC's `convert_control_functions`
    /// changes its flags.
    fn control(
        &mut self,
        block: &Block,
        o: &OWord,
        params: &mut Parameters,
    ) -> Result<(), GcodeError> {
        let Some(line) = self.awaited_line(block, o, params)? else {
            return Ok(());
        };
        match o.keyword {
            OKeyword::Sub => self.o_sub(line),
            OKeyword::EndSub | OKeyword::Return => self.o_end_sub(line, params),
            OKeyword::Call => self.o_call(line, params),
            OKeyword::Do => self.o_do(line),
            OKeyword::Repeat => self.o_repeat(line, params),
            OKeyword::While => self.o_while(line, params),
            OKeyword::EndWhile | OKeyword::EndRepeat => self.o_end_loop(line),
            OKeyword::If => self.o_if(line, params),
            OKeyword::ElseIf => self.o_else_if(line, params),
            OKeyword::Else => self.o_else(line),
            OKeyword::EndIf => self.o_end_if(line),
            OKeyword::Break | OKeyword::Continue => self.o_break(line),
        }
    }

    /// The O-line with its resolved label, `None` when the mode passes it by:
    /// while skipping only the awaited label (or a `sub` line when searching
    /// for a subroutine) is looked at, and a label that cannot be resolved is
    /// an error only when running.
    fn awaited_line<'a>(
        &self,
        block: &'a Block,
        o: &'a OWord,
        params: &mut Parameters,
    ) -> Result<Option<OLine<'a>>, GcodeError> {
        let running = self.mode == Mode::Run;
        if running {
            params.set_line(block.line);
        }
        let label = match self.label_of(block, o, params) {
            Ok(l) => l,
            Err(_) if !running => return Ok(None),
            Err(e) => return Err(e),
        };
        if self.mode.awaited().is_some_and(|a| a != label)
            || matches!(self.mode, Mode::FindSub(_)) && o.keyword != OKeyword::Sub
        {
            return Ok(None);
        }
        Ok(Some(OLine { block, o, label }))
    }

    /// `sub`: the target of a call (its body is executed) or a definition in
    /// the main program (passed over).
    fn o_sub(&mut self, line: OLine) -> Result<(), GcodeError> {
        match self.mode {
            Mode::Run => {}
            Mode::Define { .. } => {
                self.record(&line.label, line.block, LabelKind::Sub)?;
                return Err(line.error("Nested subroutine definition".into()));
            }
            Mode::Skip(_) | Mode::FindSub(_) => {
                // Found by a forward search: record it; it is the call's target.
                self.record(&line.label, line.block, LabelKind::Sub)?;
                self.mode = Mode::Run;
                if self.frames.last().is_some_and(|f| f.name == line.label) {
                    return Ok(()); // execute the body
                }
            }
        }
        if let Some(frame) = self.frames.last() {
            if frame.name != line.label {
                return Err(line.error(format!(
                    "Nested subroutine definition: 'O{} sub' found inside called subroutine 'O{}'",
                    line.label, frame.name
                )));
            }
            return Ok(()); // arriving at the called sub: execute its body
        }
        // A definition in the main program: record and skip over it
        // (handing its lines on as written, once).
        self.record(&line.label, line.block, LabelKind::Sub)?;
        let passing = self.current == 0
            && !self.options.drop_definitions
            && self.passed_definitions.insert(line.block.offset);
        self.mode = Mode::Define {
            name: line.label,
            passing,
        };
        Ok(())
    }

    /// `endsub` or `return`: the end of a definition passed over, or the
    /// return from a call.
    fn o_end_sub(&mut self, line: OLine, params: &mut Parameters) -> Result<(), GcodeError> {
        if self.frames.is_empty() {
            if !matches!(self.mode, Mode::Define { .. }) {
                return Err(line.error(format!(
                    "not in a subroutine definition: 'o{} {}'",
                    line.label,
                    line.o.keyword.name()
                )));
            }
            if line.o.keyword == OKeyword::EndSub {
                self.mode = Mode::Run;
            }
            return Ok(());
        }
        // Return from the call. The value is evaluated only now: a
        // definition passed over evaluates nothing (LinuxCNC).
        let value = match line.o.args.first() {
            Some(&i) => Some(line.eval(i, params)?),
            None => None,
        };
        params.returned = value;
        let frame = self.frames.pop().expect("checked");
        let depth = self.frames.len();
        self.open_loops.retain(|l| l.depth <= depth);
        params.leave(&frame.saved);
        self.mode = Mode::Run;
        self.current = frame.return_file;
        let f = &mut self.files[frame.return_file];
        f.offset = frame.return_offset;
        f.line = frame.return_line;
        f.positioned = false;
        Ok(())
    }

    /// `call`: enter a new call level, then go to the subroutine: recorded,
    /// in a file on the subroutine path, or searched forward in the main
    /// program.
    fn o_call(&mut self, line: OLine, params: &mut Parameters) -> Result<(), GcodeError> {
        if self.mode != Mode::Run {
            return Ok(());
        }
        // LinuxCNC counts the main program as level 0 and refuses
        // level INTERP_SUB_ROUTINE_LEVELS: at most 9 nested calls.
        if self.frames.len() + 1 >= MAX_CALL_DEPTH {
            return Err(line.error("Too many subroutine levels".into()));
        }
        let mut args = Vec::with_capacity(line.o.args.len());
        for &i in &line.o.args {
            if args.len() >= MAX_CALL_ARGUMENTS {
                return Err(line.error("Too many subroutine parameters".into()));
            }
            args.push(line.eval(i, params)?);
        }
        let f = &self.files[self.current];
        let frame = Frame {
            name: line.label.clone(),
            return_file: self.current,
            return_offset: f.offset,
            return_line: f.line,
            saved: params.enter(&args),
            loops: 0,
        };
        self.frames.push(frame);
        params.returned = None;
        self.go_to_sub(line)
    }

    /// Go to the `sub` line of the subroutine a call names.
    fn go_to_sub(&mut self, line: OLine) -> Result<(), GcodeError> {
        let label = line.label.as_str();
        if let Some(entry) = self.labels.get(label).cloned() {
            self.seek_to(&entry);
        } else if let Some(path) = self.find_file(label) {
            let input = std::fs::File::open(&path)
                .map_err(|e| line.error(format!("cannot open {}: {e}", path.display())))?;
            self.files.push(SourceFile {
                name: path.display().to_string(),
                path: Some(path),
                input: Box::new(std::io::BufReader::new(input)),
                offset: 0,
                line: 0,
                positioned: true,
            });
            self.current = self.files.len() - 1;
            self.mode = Mode::FindSub(None);
        } else {
            if self.current != 0 {
                return Err(line.error(format!(
                    "Subroutine 'O{label}' not found -- not in offset table and no file '{label}.ngc' found"
                )));
            }
            // Search forward in the main program.
            self.mode = Mode::FindSub(Some(line.label));
        }
        Ok(())
    }

    /// `do`: the start of a do-while loop (its end is the `while` line).
    fn o_do(&mut self, line: OLine) -> Result<(), GcodeError> {
        self.mode = Mode::Run;
        if !self.labels.contains_key(&line.label) {
            self.record(&line.label, line.block, LabelKind::Do)?;
            self.enter_loop(&line.label, line.block, LabelKind::Do, None);
        }
        Ok(())
    }

    /// `repeat`: count down the loop's trips, skip to its end after the last.
    fn o_repeat(&mut self, line: OLine, params: &mut Parameters) -> Result<(), GcodeError> {
        let label = line.label.as_str();
        self.check_duplicate(label, line.block, LabelKind::Repeat)?;
        self.record(label, line.block, LabelKind::Repeat)?;
        self.mode = Mode::Run;
        let count = self.condition(line.block, line.o, params)?;
        let entry = self.labels.get_mut(label).expect("recorded");
        if entry.repeat_left.is_none() {
            // LinuxCNC's `round_to_int`: to the nearest, ties to even.
            entry.repeat_left = Some(count.round_ties_even() as i64);
            let trips = Some(count.round_ties_even());
            self.enter_loop(label, line.block, LabelKind::Repeat, trips);
        }
        let entry = self.labels.get_mut(label).expect("recorded");
        if entry.repeat_left.unwrap_or(0) > 0 {
            entry.repeat_left = entry.repeat_left.map(|n| n - 1);
        } else {
            entry.repeat_left = None;
            self.mode = Mode::Skip(line.label);
        }
        Ok(())
    }

    /// `while`: the test at the start of a while loop, or at the end of a
    /// do-while loop.
    fn o_while(&mut self, line: OLine, params: &mut Parameters) -> Result<(), GcodeError> {
        let existing = self.labels.get(&line.label).cloned();
        if let Some(e) = &existing
            && e.kind != LabelKind::Do
            && (e.file != self.current || e.offset != line.block.offset)
        {
            return Err(line.error(format!(
                "duplicate O-word label: '{}' - defined in line {}",
                line.label, e.line
            )));
        }
        self.mode = Mode::Run;
        let test = self.condition(line.block, line.o, params)?;
        match existing {
            Some(e) if e.kind == LabelKind::Do => {
                // The end of a do-while loop.
                if test != 0.0 && !self.latches.breaking {
                    self.seek_to(&e);
                } else {
                    self.latches.breaking = false;
                    self.leave_loop(&line.label);
                }
            }
            _ => {
                if existing.is_none() {
                    self.record(&line.label, line.block, LabelKind::While)?;
                    self.enter_loop(&line.label, line.block, LabelKind::While, None);
                }
                if test == 0.0 {
                    self.mode = Mode::Skip(line.label);
                }
            }
        }
        Ok(())
    }

    /// `endwhile` or `endrepeat`: back to the loop's start, or out of the
    /// loop when skipping to it.
    fn o_end_loop(&mut self, line: OLine) -> Result<(), GcodeError> {
        let label = line.label.as_str();
        let Some(e) = self.labels.get(label).cloned() else {
            return Err(line.error(format!("undefined O-word label: '{label}'")));
        };
        let want = if line.o.keyword == OKeyword::EndWhile {
            LabelKind::While
        } else {
            LabelKind::Repeat
        };
        if e.kind != want {
            return Err(line.error(format!(
                "no matching label: '{label}' (found {:?} in line {})",
                e.kind, e.line
            )));
        }
        if self.mode.awaited() != Some(label) {
            self.seek_to(&e);
        } else if self.latches.continuing {
            self.mode = Mode::Run;
            self.latches.continuing = false;
            self.seek_to(&e);
        } else {
            // The loop is over (condition false or break). A break's latch
            // stays set, as in LinuxCNC 2.9 (only the end of a do-while
            // clears it): the next do-while then runs its body once.
            self.mode = Mode::Run;
            if let Some(entry) = self.labels.get_mut(label) {
                entry.repeat_left = None;
            }
            self.leave_loop(label);
        }
        Ok(())
    }

    /// `if`: run its body or skip to its next branch.
    fn o_if(&mut self, line: OLine, params: &mut Parameters) -> Result<(), GcodeError> {
        self.check_duplicate(&line.label, line.block, LabelKind::If)?;
        self.record(&line.label, line.block, LabelKind::If)?;
        let taken = self.condition(line.block, line.o, params)? != 0.0;
        self.latches.executed_if = taken;
        self.mode = if taken {
            Mode::Run
        } else {
            Mode::Skip(line.label)
        };
        Ok(())
    }

    /// `elseif`: skip to the end after a branch taken, else test.
    fn o_else_if(&mut self, line: OLine, params: &mut Parameters) -> Result<(), GcodeError> {
        self.expect_if(&line.label, line.block, line.o)?;
        if self.latches.executed_if {
            self.mode = Mode::Skip(line.label);
            return Ok(());
        }
        if self.condition(line.block, line.o, params)? != 0.0 {
            self.mode = Mode::Run;
            self.latches.executed_if = true;
        }
        Ok(())
    }

    /// `else`: skip to the end after a branch taken, else run its body.
    fn o_else(&mut self, line: OLine) -> Result<(), GcodeError> {
        self.expect_if(&line.label, line.block, line.o)?;
        if self.latches.executed_if {
            self.mode = Mode::Skip(line.label);
            return Ok(());
        }
        if self.mode.awaited() == Some(line.label.as_str()) {
            self.latches.executed_if = true;
            self.mode = Mode::Run;
        }
        Ok(())
    }

    /// `endif`: run on.
    fn o_end_if(&mut self, line: OLine) -> Result<(), GcodeError> {
        self.expect_if(&line.label, line.block, line.o)?;
        self.mode = Mode::Run;
        self.latches.executed_if = true;
        Ok(())
    }

    /// `break` or `continue`: skip to the loop's end, latching which.
    fn o_break(&mut self, line: OLine) -> Result<(), GcodeError> {
        let label = line.label.as_str();
        let Some(e) = self.labels.get(label) else {
            return Err(line.error(format!("undefined O-word label: '{label}'")));
        };
        if e.kind != LabelKind::While && e.kind != LabelKind::Do {
            return Err(line.error(format!(
                "no matching while/do label: '{label}' (found {:?} in line {})",
                e.kind, e.line
            )));
        }
        if self.mode.awaited() == Some(label) {
            return Ok(());
        }
        if line.o.keyword == OKeyword::Break {
            self.latches.breaking = true;
        } else {
            self.latches.continuing = true;
        }
        self.mode = Mode::Skip(line.label);
        Ok(())
    }

    fn check_duplicate(
        &self,
        label: &str,
        block: &Block,
        kind: LabelKind,
    ) -> Result<(), GcodeError> {
        if let Some(e) = self.labels.get(label)
            && (e.kind != kind || e.file != self.current || e.offset != block.offset)
        {
            return Err(located(
                ErrorKind::OWord(format!(
                    "duplicate O-word label: '{label}' - defined in line {}",
                    e.line
                )),
                block,
                0,
                block.raw.len(),
            ));
        }
        Ok(())
    }

    fn expect_if(&self, label: &str, block: &Block, o: &OWord) -> Result<(), GcodeError> {
        match self.labels.get(label) {
            None => Err(located(
                ErrorKind::OWord(format!("undefined O-word label: '{label}'")),
                block,
                o.start,
                o.end,
            )),
            Some(e) if e.kind != LabelKind::If => Err(located(
                ErrorKind::OWord(format!(
                    "no matching 'if' label: '{label}' (found {:?} in line {})",
                    e.kind, e.line
                )),
                block,
                o.start,
                o.end,
            )),
            Some(_) => Ok(()),
        }
    }

    fn enter_loop(&mut self, label: &str, block: &Block, kind: LabelKind, count: Option<f64>) {
        self.open_loops.push(OpenLoop {
            label: label.to_string(),
            kind,
            file: self.current,
            line: block.line,
            depth: self.frames.len(),
            count,
        });
        match self.frames.last_mut() {
            Some(f) => f.loops += 1,
            None => self.main_loops += 1,
        }
    }

    /// The innermost loop being run, as messages name it:
    /// `` `o1 while` (line 3) `` (and the file when it is a subroutine file).
    pub fn innermost_loop(&self) -> Option<String> {
        let l = self.open_loops.last()?;
        let keyword = match l.kind {
            LabelKind::Do => "do",
            LabelKind::While => "while",
            LabelKind::Repeat => "repeat",
            LabelKind::If => "if",
            LabelKind::Sub => "sub",
        };
        // Stored as `scope#label` (the label inside a subroutine is its own).
        let base = l.label.rsplit('#').next().unwrap_or(&l.label);
        let label = if base.parse::<u64>().is_ok() {
            base.to_string()
        } else {
            format!("<{base}>")
        };
        Some(if l.file == 0 {
            format!("`o{label} {keyword}` (line {})", l.line)
        } else {
            format!(
                "`o{label} {keyword}` ({} line {})",
                self.file_name(l.file),
                l.line
            )
        })
    }

    /// How many times the `repeat` loops being run execute their bodies in
    /// all (the product of their counts; 1 outside them, `while` and `do`
    /// loops left out: their counts are not known).
    pub fn repeat_trips(&self) -> f64 {
        self.open_loops
            .iter()
            .filter_map(|l| l.count)
            .map(|c| c.max(1.0))
            .product()
    }

    fn leave_loop(&mut self, label: &str) {
        if let Some(k) = self.open_loops.iter().rposition(|l| l.label == label) {
            self.open_loops.truncate(k);
        }
        match self.frames.last_mut() {
            Some(f) => f.loops = f.loops.saturating_sub(1),
            None => {
                // Blocks after the last loop of the main program are literal
                // again only when no loop is open.
                self.main_loops = self.main_loops.saturating_sub(1);
            }
        }
    }

    fn find_file(&self, label: &str) -> Option<PathBuf> {
        let file = format!("{label}.ngc");
        self.options
            .subroutine_path
            .iter()
            .map(|dir| dir.join(&file))
            .find(|p| p.is_file())
    }
}

fn expr(block: &Block, index: u32) -> &Expr {
    &block.exprs[index as usize]
}

/// A computed value as a G-code number: 6 decimals, trailing zeros and a
/// trailing point dropped, no `-0`.
pub fn push_value(out: &mut String, v: f64) {
    use std::fmt::Write;
    let mut s = format!("{v:.6}");
    if s.contains('.') {
        while s.ends_with('0') {
            s.pop();
        }
        if s.ends_with('.') {
            s.pop();
        }
    }
    if s == "-0" {
        s = "0".into();
    }
    let _ = write!(out, "{s}");
}
