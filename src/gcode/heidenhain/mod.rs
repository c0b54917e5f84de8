//! Heidenhain TNC Klartext programs (dialects.md "Heidenhain TNC
//! (Klartext)"): their syntax, language and machine state, feeding the same
//! seam as LinuxCNC's programs ([`crate::gcode::Execution`]).
//!
//! - `syntax`: a logical block (a line and its `~` continuation lines) →
//!   tokens with byte ranges, Q formulas;
//! - `language`: Q parameters, `FN` functions and jumps, labels, `CALL LBL`
//!   repeats and subprograms, `CALL PGM` → executed blocks in order;
//! - `geometry`: the rotation of each `PLANE` form, `RND`/`CHF` corners,
//!   `APPR`/`DEP` paths, arcs as chords (pure functions);
//! - `machine`: the TNC's state (pole, feeds, datum shift, working plane,
//!   tool-tip control, tools, the defined cycle) → [`BlockEvent`]s;
//! - `cycles`: machining cycles (`CYCL DEF 200 …`, `PATTERN DEF`) expanded
//!   into the moves the control makes;
//! - `write`: Klartext written back (renumbered, numbers in the input's
//!   style).
//!
//! The front ([`KlartextFront`]) reads the whole program into memory (a
//! Klartext program's jumps and labels go both ways; one without labels
//! is read as it runs: `streamed_source`) and hands on one
//! block at a time: the main program's blocks read once in sequence as
//! written (`literal`), blocks run again or from a call as flat copies
//! (`; volcomp: line N`), a taken jump or call as a `; volcomp:` comment
//! block, and blocks never run as `passed`, so that a writer loses no byte.
pub(crate) mod cycles;
pub(crate) mod geometry;
pub(crate) mod language;
pub(crate) mod machine;
pub(crate) mod streamed_source;
pub(crate) mod syntax;
pub(crate) mod write;

use std::path::{Path, PathBuf};

use language::{Flow, Language, Reach, Source};
use machine::{KlMachine, KlartextSetup};
use syntax::{KlBlock, Value, parse_block, parse_block_into};

use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::language::{Executed, LanguageOptions, ProgramInput};
use crate::gcode::machine::interpret::{BlockEvent, InterpretOptions};
use crate::gcode::syntax::block::{Block, LineEnding, Word};

/// The blocks after a straight line that [`KlartextFront::corner_ahead`]
/// may read (two searches of 16), and the block itself.
const CORNER_AHEAD: usize = 33;

/// The Klartext front of a run.
pub(crate) struct KlartextFront {
    language: Language,
    machine: KlMachine,
    block: Block,
    parsed: KlBlock,
    executed: Executed,
    /// The main program has ended (M2, M30, its END PGM).
    ended: bool,
    /// This block ends the main program.
    ends_here: bool,
    /// A read error to hand on first.
    failed: Option<GcodeError>,
    /// The file and block index of the block handed on.
    current: (usize, usize),
    done: bool,
    path: PathBuf,
    lenient: bool,
    /// Honour block skip `/` ([`InterpretOptions::skip_deleted_blocks`]).
    skip_deleted: bool,
}

impl KlartextFront {
    /// Read `input` (named `path`) whole and prepare the run.
    pub(crate) fn new(
        input: Box<dyn ProgramInput>,
        path: &Path,
        language: &LanguageOptions,
        options: &InterpretOptions,
        setup: &crate::gcode::ProgramSetup,
    ) -> Self {
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let (source, failed) = match streamed_main(&name, path, input) {
            Ok(source) => (source, None),
            Err(input) => held_main(name, path, input),
        };
        let preset = {
            let p = &setup.parameters;
            let get = |k| p.get(crate::gcode::language::parameters::numbers::coord(1, k));
            crate::axes::Axes {
                x: get(0),
                y: get(1),
                z: get(2),
                a: get(3),
                b: get(4),
                c: get(5),
                ..crate::axes::Axes::default()
            }
        };
        let max = language
            .max_executed_lines
            .unwrap_or(crate::gcode::language::DEFAULT_MAX_EXECUTED_LINES);
        KlartextFront {
            language: Language::new(source, language.subroutine_path.clone(), max),
            machine: KlMachine::new(KlartextSetup {
                preset,
                tools: setup.tools.clone(),
                orientation: setup.orientation.clone(),
                rapid_mm_per_min: options.rapid_mm_per_min,
                axes: options.axes,
            }),
            block: Block::default(),
            parsed: KlBlock::default(),
            executed: Executed {
                file: 0,
                line: 1,
                literal: true,
                passed: false,
            },
            ended: false,
            ends_here: false,
            failed,
            current: (0, 0),
            done: false,
            path: path.to_path_buf(),
            lenient: options.lenient,
            skip_deleted: options.skip_deleted_blocks,
        }
    }

    /// The next executed block, `None` after the program's end.
    pub(crate) fn next_block(&mut self) -> Option<Result<(), GcodeError>> {
        if let Some(e) = self.failed.take() {
            self.done = true;
            return Some(Err(e));
        }
        if self.done || self.ended {
            return None;
        }
        let result = self.step();
        if result.is_err() {
            self.done = true;
        }
        Some(result)
    }

    fn step(&mut self) -> Result<(), GcodeError> {
        let lang = &mut self.language;
        let (file, pc) = (lang.file, lang.pc);
        // A streamed program: this block, the ones passed over before it,
        // and the corner look-ahead's (`corner_ahead`: up to 32 after).
        let from = if file == 0 {
            pc.min(lang.next_literal)
        } else {
            pc
        };
        lang.files[file].fill(from, pc + CORNER_AHEAD)?;
        let count = lang.files[file].len();
        if pc >= count {
            let source = &lang.files[file];
            let line = source.last_line().unwrap_or(1);
            return Err(GcodeError::at(
                ErrorKind::DialectRefused(format!(
                    "the program {} ends without END PGM",
                    source.name
                )),
                line,
                b"",
                0,
                0,
            )
            .with_path(source.path.clone().unwrap_or_else(|| self.path.clone())));
        }
        // Main-program blocks a jump passed over: handed on as written.
        if file == 0 && !lang.in_call() && pc > lang.next_literal {
            let k = lang.next_literal;
            lang.next_literal += 1;
            self.emit_passed(k);
            return Ok(());
        }
        let reach = lang.reach();
        if reach == Reach::Literal {
            lang.next_literal = pc + 1;
        }
        lang.count(file, pc)?;
        let r = lang.files[file].block(pc);
        let raw = lang.files[file].raw(pc);
        // The block handed on starts as written (its bytes copied once).
        self.block.reset(r.line, r.start as u64);
        self.block.raw.extend_from_slice(raw);
        parse_block_into(raw, &mut self.parsed);
        if self.parsed.deleted && self.skip_deleted {
            // Block skip on: not read yet (the block's language effects
            // would have to be skipped too).
            return Err(GcodeError::at(
                ErrorKind::DialectFeature(
                    "Heidenhain",
                    "`/` block skip with block delete on".into(),
                ),
                r.line,
                raw,
                0,
                1,
            ));
        }
        let flat = substituted(&self.parsed, raw, &lang.q);
        let ends_program = self.parsed.starts_with(&["END", "PGM"]);
        let stops =
            self.parsed.tokens.iter().any(|t| {
                t.address == "M" && matches!(t.number(), Some(v) if v == 2.0 || v == 30.0)
            });
        let flow = if ends_program || stops {
            self.ends_here = stops || lang.end_program();
            if self.ends_here {
                self.ended = true;
            }
            Flow::Next
        } else {
            self.ends_here = false;
            lang.step(&self.parsed)
                .map_err(|e| self.with_file(e, file))?
        };
        let control = matches!(flow, Flow::Jumped)
            || (reach == Reach::Flat
                && (self.parsed.starts_with(&["LBL"])
                    || self.parsed.starts_with(&["BEGIN", "PGM"])
                    || ends_program));
        // The origin comment is written by flat and control blocks only.
        let origin = if !control && reach != Reach::Flat {
            String::new()
        } else if file == 0 {
            format!("line {}", r.line)
        } else {
            format!("{}:{}", self.language.files[file].name, r.line)
        };
        self.current = (file, pc);
        self.block.ending = r.ending;
        self.block.deleted = self.parsed.deleted;
        if control {
            // What the flat copies already did: a comment.
            let number = self.parsed.number.as_ref().map(|n| format!("{} ", n.0));
            let code = self.parsed.code.trim().to_string();
            self.block.raw =
                format!("{}; volcomp: {origin}: {code}", number.unwrap_or_default()).into_bytes();
        } else if reach == Reach::Flat {
            if let Some(flat) = flat {
                self.block.raw = flat;
            }
            let at = self.block.raw.len();
            self.block
                .raw
                .extend_from_slice(format!(" ; volcomp: {origin}").as_bytes());
            self.block.comments.push(at + 1..self.block.raw.len());
        } else {
            self.block
                .comments
                .extend(self.parsed.comments.iter().cloned());
        }
        if self.block.ending == LineEnding::None && (reach == Reach::Flat || control) {
            self.block.ending = LineEnding::Lf;
        }
        if let Some((n, span)) = &self.parsed.number {
            self.block.words.push(number_word(*n, span.clone()));
        }
        self.executed = Executed {
            file,
            line: r.line,
            literal: reach == Reach::Literal && !control,
            passed: false,
        };
        Ok(())
    }

    fn with_file(&self, e: GcodeError, file: usize) -> GcodeError {
        if file == 0 {
            e
        } else {
            let path = self.language.files[file].path.clone();
            match path {
                Some(p) => e.with_path(p),
                None => e,
            }
        }
    }

    /// Hand on main-program block `k` as written, not run.
    fn emit_passed(&mut self, k: usize) {
        self.current = (0, k);
        let source = &self.language.files[0];
        let r = source.block(k);
        self.block.reset(r.line, r.start as u64);
        self.block.raw.extend_from_slice(source.raw(k));
        self.block.ending = r.ending;
        let parsed = parse_block(&self.block.raw);
        self.block.comments.extend(parsed.comments.iter().cloned());
        if let Some((n, span)) = &parsed.number {
            self.block.words.push(number_word(*n, span.clone()));
        }
        self.parsed = parsed;
        self.executed = Executed {
            file: 0,
            line: r.line,
            literal: true,
            passed: true,
        };
    }

    /// Interpret the block just handed on.
    pub(crate) fn interpret(&mut self, event: &mut BlockEvent) -> Result<(), GcodeError> {
        let (file, index) = self.current;
        self.machine.set_lookahead(self.corner_ahead(file, index));
        let raw = self.language.files[file].raw(index);
        let result = self.machine.interpret(
            &self.parsed,
            raw,
            self.executed.line,
            &self.language.q,
            event,
        );
        match result {
            Ok(_) => {
                event.program_end = self.ends_here;
                for (n, v) in self.machine.take_assigned() {
                    let p = syntax::Param {
                        kind: syntax::ParamKind::Q,
                        number: n,
                    };
                    self.language.q.set(p, v);
                }
                Ok(())
            }
            Err(e) if self.lenient && !matches!(e.kind, ErrorKind::DialectRefused(_)) => {
                self.machine.pass_over(self.executed.line, event);
                event.warnings.push(crate::gcode::Warning {
                    line: self.executed.line,
                    column: e.column,
                    kind: crate::gcode::WarningKind::Lenient(e.kind),
                });
                Ok(())
            }
            Err(e) => Err(self.with_file(e, file)),
        }
    }

    /// After a straight line `L` or an arc at `index`: the `RND`/`CHF`
    /// block right after it and the block after that (the corner the
    /// control inserts needs both elements).
    fn corner_ahead(&self, file: usize, index: usize) -> Option<(KlBlock, KlBlock)> {
        let first = self.parsed.address(0);
        if !matches!(first, "L" | "APPR" | "C" | "CR" | "CT" | "CP") {
            return None;
        }
        let source = &self.language.files[file];
        // The next block with code (comment lines between are skipped),
        // found on its bytes: most lines are not followed by a corner.
        let code = |k: usize| {
            let raw = source.raw(k);
            let at = raw
                .iter()
                .position(|b| !b.is_ascii_digit() && !b.is_ascii_whitespace())
                .unwrap_or(raw.len());
            &raw[at..]
        };
        // The block and its code.
        let after = |from: usize| {
            (from..source.len().min(from + 16)).find_map(|k| {
                let c = code(k);
                (!c.is_empty() && c[0] != b';').then_some((k, c))
            })
        };
        if first == "APPR" {
            // The first contour element after an approach.
            let (k, _) = after(index + 1)?;
            return Some((self.parsed.clone(), parse_block(source.raw(k))));
        }
        let (k, corner) = after(index + 1)?;
        if !(corner.starts_with(b"RND") || corner.starts_with(b"CHF")) {
            return None;
        }
        let (next, _) = after(k + 1)?;
        Some((parse_block(source.raw(k)), parse_block(source.raw(next))))
    }

    /// The event of a block not run.
    pub(crate) fn pass_over(&self, event: &mut BlockEvent) {
        self.machine.pass_over(self.executed.line, event);
    }

    /// After the end: the main program's blocks not handed on yet.
    pub(crate) fn next_tail_line(&mut self) -> Option<Result<(), GcodeError>> {
        let k = self.language.next_literal;
        if let Err(e) = self.language.files[0].fill(k, k + 1) {
            return Some(Err(e));
        }
        if k >= self.language.files[0].len() {
            return None;
        }
        self.language.next_literal += 1;
        self.emit_passed(k);
        Some(Ok(()))
    }

    pub(crate) fn block(&self) -> &Block {
        &self.block
    }

    pub(crate) fn executed(&self) -> &Executed {
        &self.executed
    }

    pub(crate) fn file_name(&self, index: usize) -> &str {
        self.language
            .files
            .get(index)
            .map_or("?", |f| f.name.as_str())
    }

    pub(crate) fn end_program(&mut self) {
        self.ended = true;
    }

    pub(crate) fn lines_read(&self) -> usize {
        self.language.files[0].last_line().unwrap_or(0)
    }

    pub(crate) fn in_call(&self) -> bool {
        self.language.in_call()
    }
}

/// The main program read as it runs, when no block has a label and every
/// block passes [`NumberCheck`] (a first pass: [`streamed_source`]); `Err`:
/// the input back at its start, to be read whole.
fn streamed_main(
    name: &str,
    path: &Path,
    mut input: Box<dyn ProgramInput>,
) -> Result<Source, Box<dyn ProgramInput>> {
    let Ok(start) = std::io::Seek::stream_position(&mut input) else {
        return Err(input);
    };
    let mut numbers = NumberCheck::default();
    let window =
        streamed_source::Window::scan(input, start, |raw, line| numbers.block(raw, line).is_ok())?;
    Ok(Source {
        name: name.to_string(),
        path: Some(path.to_path_buf()),
        text: Vec::new(),
        blocks: Vec::new(),
        labels: Default::default(),
        window: Some(Box::new(window)),
    })
}

/// The main program read whole, and the error to hand on first.
fn held_main(
    name: String,
    path: &Path,
    mut input: Box<dyn ProgramInput>,
) -> (Source, Option<GcodeError>) {
    let mut text = Vec::new();
    let read = std::io::Read::read_to_end(&mut input, &mut text);
    let (source, mut failed) = match read {
        Err(e) => (
            None,
            Some(GcodeError::at(ErrorKind::Io(e.to_string()), 1, b"", 0, 0)),
        ),
        Ok(_) => match Source::new(name.clone(), Some(path.to_path_buf()), text) {
            Ok(s) => (Some(s), None),
            Err(e) => (None, Some(e)),
        },
    };
    let source = source.unwrap_or_else(|| {
        Source::new(name, None, Vec::new()).unwrap_or_else(|_| unreachable_source())
    });
    if failed.is_none() {
        failed = check_numbers(&source).err();
    }
    (source, failed)
}

fn unreachable_source() -> Source {
    Source {
        name: String::new(),
        path: None,
        text: Vec::new(),
        blocks: Vec::new(),
        labels: Default::default(),
        window: None,
    }
}

fn number_word(n: u64, span: std::ops::Range<usize>) -> Word {
    Word {
        letter: b'N',
        value: n as f64,
        start: span.start,
        end: span.end,
        decimals: 0,
        point: false,
        expr: None,
    }
}

/// Block numbers must ascend (the TNC numbers a program's blocks 0, 1, 2 …;
/// older controls' files have gaps, which are kept), and either every block
/// has one or none does (a file written by hand, numbered by the control on
/// loading).
fn check_numbers(source: &Source) -> Result<(), GcodeError> {
    let mut numbers = NumberCheck::default();
    for k in 0..source.len() {
        numbers.block(source.raw(k), source.block(k).line)?;
    }
    Ok(())
}

/// [`check_numbers`] a block at a time.
#[derive(Default)]
struct NumberCheck {
    previous: Option<u64>,
    numbered: Option<bool>,
}

impl NumberCheck {
    /// The next block, `raw` at `line`.
    fn block(&mut self, raw: &[u8], line: usize) -> Result<(), GcodeError> {
        let Some(mut lead) = raw.iter().position(|b| !b.is_ascii_whitespace()) else {
            return Ok(());
        };
        // A block-skip `/` before the number (`/81 M30`).
        if raw.get(lead) == Some(&b'/') {
            lead += 1;
        }
        // The digits counted and converted in one pass (at most 19 cannot
        // overflow; more are converted as `str::parse` would).
        let mut value = 0u64;
        let mut digits = 0;
        for &b in &raw[lead..] {
            let d = b.wrapping_sub(b'0');
            if d > 9 {
                break;
            }
            value = value.wrapping_mul(10).wrapping_add(u64::from(d));
            digits += 1;
        }
        let has = digits > 0;
        if *self.numbered.get_or_insert(has) != has {
            return Err(GcodeError::at(
                ErrorKind::DialectRefused(
                    "a block without its block number among numbered blocks".into(),
                ),
                line,
                raw,
                lead,
                lead + 1,
            ));
        }
        let n = if digits <= 19 {
            has.then_some(value)
        } else {
            syntax::digits_u64(&raw[lead..lead + digits])
        };
        let Some(n) = n else { return Ok(()) };
        if let Some(p) = self.previous
            && n <= p
        {
            return Err(GcodeError::at(
                ErrorKind::DialectRefused(format!(
                    "block number {n} out of order: after block {p} (block numbers ascend)"
                )),
                line,
                raw,
                lead,
                lead + digits,
            ));
        }
        self.previous = Some(n);
        Ok(())
    }
}

/// The block with its parameter values written as numbers (a flat copy),
/// `None` when it has none.
fn substituted(block: &KlBlock, raw: &[u8], q: &language::QParameters) -> Option<Vec<u8>> {
    let substituted =
        |t: &&syntax::Token| !(t.address.starts_with('Q') && t.value_span.start == t.span.start);
    // Most blocks have no parameter value: no list is built.
    if !block
        .tokens
        .iter()
        .any(|t| matches!(t.value, Some(Value::Param { .. })))
    {
        return None;
    }
    let params: Vec<_> = block
        .tokens
        .iter()
        .filter(|t| matches!(t.value, Some(Value::Param { .. })))
        .filter(substituted)
        .collect();
    if params.is_empty() || block.starts_with(&["FN"]) {
        return None;
    }
    // Q assignments keep their formula (they run again in order).
    if block.assigned().is_some() {
        return None;
    }
    let mut out = Vec::with_capacity(raw.len() + 8);
    let mut at = 0;
    for t in params {
        let Some(v) = &t.value else { continue };
        let span = t.value_span.clone();
        if span.start < at || span.end > raw.len() {
            continue;
        }
        out.extend_from_slice(&raw[at..span.start]);
        out.extend_from_slice(write::signed_number(q.value(v), 4).as_bytes());
        at = span.end;
    }
    out.extend_from_slice(&raw[at..]);
    Some(out)
}
