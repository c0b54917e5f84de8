//! The language of Klartext programs: Q parameters (`Q`, `QL`, `QR`), the
//! `FN 0–8` functions and Q formulas, the `FN 9–12` jumps, labels (`LBL`,
//! `LBL 0`), `CALL LBL n [REP m]` and `CALL PGM` (TNC 640 user's manual,
//! "Subprograms and program section repeats" and "Q parameters").
//!
//! The semantics followed:
//! - `CALL LBL n REP m` (a program-section repeat) jumps back to `LBL n`
//!   `m` times, each time it is reached; the section runs `m + 1` times;
//! - `CALL LBL n` (no `REP`) calls the subprogram at `LBL n`: it runs until
//!   `LBL 0` and returns after the call;
//! - `FN 9` (`EQU`), `FN 10` (`NE`), `FN 11` (`GT`), `FN 12` (`LT`): `IF a
//!   op b GOTO LBL n` jumps when the comparison holds;
//! - `CALL PGM name` runs the program `name` (its `BEGIN PGM` … `END PGM`),
//!   found beside the caller or on the subroutine path, and returns.
//!
//! What it hands on: every executed block, `literal` when it is the main
//! program's block read once in sequence, otherwise a flat copy (parameter
//! words as numbers, `; volcomp: line N` appended); a taken jump or call and
//! a label in a flat copy become a `; volcomp:` comment block, since the
//! flat copies already say what they did; main-program blocks never run
//! (jumped over, or after the program's end) come as `passed`.
use std::collections::HashMap;
use std::path::{Path, PathBuf};

use super::syntax::{Formula, KlBlock, Param, ParamKind, Value, parse_block, read_param};
use crate::gcode::error::{ErrorKind, GcodeError};
use crate::gcode::syntax::block::LineEnding;

/// Nested `CALL LBL` / `CALL PGM` levels (the TNC allows 19 levels).
pub const MAX_CALL_DEPTH: usize = 19;

/// A label: a number or a name.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Label {
    /// `LBL 12`.
    Number(u32),
    /// `LBL "NAME"` (upper-cased).
    Name(String),
}

impl std::fmt::Display for Label {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Label::Number(n) => write!(f, "LBL {n}"),
            Label::Name(s) => write!(f, "LBL \"{s}\""),
        }
    }
}

/// The label named by the token at `i` of `block` (a number or a quoted
/// name).
pub fn label_at(block: &KlBlock, i: usize) -> Option<Label> {
    let t = block.tokens.get(i)?;
    if t.address.is_empty()
        && let Some(Value::Number(v)) = t.value
        && v >= 0.0
        && v.fract() == 0.0
        && v < 1e9
    {
        return Some(Label::Number(v as u32));
    }
    let text = token_text(block, t)?;
    let name = text.trim().trim_matches('"');
    if name.is_empty() {
        return None;
    }
    Some(Label::Name(name.to_ascii_uppercase()))
}

/// The code text of token `t` of `block`.
pub fn token_text<'a>(
    block: &'a KlBlock,
    t: &crate::gcode::heidenhain::syntax::Token,
) -> Option<&'a str> {
    block.code.get(t.text.clone())
}

/// One logical block of a source: where its bytes are.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BlockRef {
    pub start: usize,
    pub end: usize,
    pub ending: LineEnding,
    pub line: usize,
}

/// A program file held in memory, split into logical blocks, with its labels.
pub(crate) struct Source {
    pub name: String,
    pub path: Option<PathBuf>,
    pub text: Vec<u8>,
    pub blocks: Vec<BlockRef>,
    pub labels: HashMap<Label, usize>,
    /// A main program without labels read as it runs
    /// ([`super::streamed_source`]): `text` and `blocks` are then empty
    /// and this holds the blocks around the one running.
    pub window: Option<Box<super::streamed_source::Window>>,
}

impl Source {
    /// Split `text` into logical blocks (a line ending in `~` continues) and
    /// find its labels.
    pub fn new(name: String, path: Option<PathBuf>, text: Vec<u8>) -> Result<Source, GcodeError> {
        // At most one block a line (a table sized once, not grown).
        let mut blocks = Vec::with_capacity(memchr::memchr_iter(b'\n', &text).count() + 1);
        let mut labels = HashMap::new();
        let mut at = 0;
        let mut line = 0;
        while at < text.len() {
            let start = at;
            let first_line = line + 1;
            let (end, ending) = loop {
                line += 1;
                let line_start = at;
                let eol = memchr::memchr(b'\n', &text[at..]).map_or(text.len(), |k| at + k);
                let (content_end, ending) = if eol == text.len() {
                    (eol, LineEnding::None)
                } else if eol > line_start && text[eol - 1] == b'\r' {
                    (eol - 1, LineEnding::CrLf)
                } else {
                    (eol, LineEnding::Lf)
                };
                at = if eol < text.len() {
                    eol + 1
                } else {
                    text.len()
                };
                let continues =
                    text[start..content_end].trim_ascii_end().ends_with(b"~") && at < text.len();
                if !continues {
                    break (content_end, ending);
                }
            };
            let index = blocks.len();
            blocks.push(BlockRef {
                start,
                end,
                ending,
                line: first_line,
            });
            // Labels: `N LBL …` (cheap test before parsing).
            let raw = &text[start..end];
            if memchr::memmem::find(&raw[..raw.len().min(19)], b"LBL ").is_some() {
                let b = parse_block(raw);
                if b.starts_with(&["LBL"])
                    && let Some(label) = label_at(&b, 1)
                    && label != Label::Number(0)
                    && labels.insert(label.clone(), index).is_some()
                {
                    return Err(GcodeError::at(
                        ErrorKind::DialectRefused(format!("{label} is defined twice")),
                        first_line,
                        raw,
                        0,
                        raw.len(),
                    ));
                }
            }
        }
        Ok(Source {
            name,
            path,
            text,
            blocks,
            labels,
            window: None,
        })
    }

    #[inline]
    pub fn raw(&self, index: usize) -> &[u8] {
        if let Some(w) = &self.window {
            return w.raw(index);
        }
        let b = &self.blocks[index];
        &self.text[b.start..b.end]
    }

    /// Its number of blocks.
    pub fn len(&self) -> usize {
        match &self.window {
            Some(w) => w.len(),
            None => self.blocks.len(),
        }
    }

    /// Block `index` (of a streamed program: one held, else an empty one).
    pub fn block(&self, index: usize) -> BlockRef {
        match &self.window {
            Some(w) => w.block(index).unwrap_or(BlockRef {
                start: 0,
                end: 0,
                ending: LineEnding::None,
                line: 0,
            }),
            None => self.blocks[index],
        }
    }

    /// The line of its last block.
    pub fn last_line(&self) -> Option<usize> {
        match &self.window {
            Some(w) => w.last_line(),
            None => self.blocks.last().map(|b| b.line),
        }
    }

    /// Make blocks `from..to` readable (a streamed program reads them).
    pub fn fill(&mut self, from: usize, to: usize) -> Result<(), GcodeError> {
        match &mut self.window {
            Some(w) => w.fill(from, to).map_err(|e| {
                GcodeError::at(
                    ErrorKind::Io(e.to_string()),
                    w.last_line().unwrap_or(1),
                    b"",
                    0,
                    0,
                )
            }),
            None => Ok(()),
        }
    }
}

/// The parameter tables (Q, QL, QR): unset parameters read 0, as on the
/// control after a reset.
#[derive(Clone, Debug, Default)]
pub struct QParameters {
    values: HashMap<Param, f64>,
}

impl QParameters {
    /// The value of `p` (0 when never set).
    pub fn get(&self, p: Param) -> f64 {
        self.values.get(&p).copied().unwrap_or(0.0)
    }

    /// Set `p`.
    pub fn set(&mut self, p: Param, v: f64) {
        self.values.insert(p, v);
    }

    /// The value of a word's value (a number or a signed parameter).
    pub fn value(&self, v: &Value) -> f64 {
        match *v {
            Value::Number(x) | Value::Sign(x) => x,
            Value::Param { param, negate } => {
                let x = self.get(param);
                if negate { -x } else { x }
            }
        }
    }
}

/// How a block reached the machine layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Reach {
    /// Read once in sequence from the main program.
    Literal,
    /// Run again or from a call: a flat copy.
    Flat,
}

/// A call in progress.
#[derive(Clone, Debug)]
struct CallFrame {
    file: usize,
    return_to: usize,
    /// The QL parameters of the caller (a called program has its own).
    locals: Option<Vec<(Param, f64)>>,
}

/// What the language does after a block.
pub(crate) enum Flow {
    /// Go on with the next block.
    Next,
    /// The block jumped or called: it is written as a comment.
    Jumped,
}

/// The flow of a run: where it is, the calls and repeats in progress.
pub(crate) struct Language {
    pub files: Vec<Source>,
    pub file: usize,
    pub pc: usize,
    stack: Vec<CallFrame>,
    /// Repeats left of each `CALL LBL … REP` block in progress (file, block).
    repeats: HashMap<(usize, usize), u32>,
    /// The next main-program block not handed on yet.
    pub next_literal: usize,
    pub q: QParameters,
    search_path: Vec<PathBuf>,
    /// Blocks run (for the endless-loop limit) and its limit.
    executed: u64,
    max_executed: u64,
}

impl Language {
    pub fn new(main: Source, search_path: Vec<PathBuf>, max_executed: u64) -> Self {
        Language {
            files: vec![main],
            file: 0,
            pc: 0,
            stack: Vec::new(),
            repeats: HashMap::new(),
            next_literal: 0,
            q: QParameters::default(),
            search_path,
            executed: 0,
            max_executed,
        }
    }

    /// In a call (a subprogram or another program).
    pub fn in_call(&self) -> bool {
        !self.stack.is_empty()
    }

    /// How the block at `pc` of the current file is reached now.
    pub fn reach(&self) -> Reach {
        if self.file == 0 && self.stack.is_empty() && self.pc >= self.next_literal {
            Reach::Literal
        } else {
            Reach::Flat
        }
    }

    /// Count one executed block (block `pc` of `file`); an error past the limit.
    pub fn count(&mut self, file: usize, pc: usize) -> Result<(), GcodeError> {
        self.executed += 1;
        if self.executed > self.max_executed {
            let source = &self.files[file];
            let raw = source.raw(pc);
            return Err(GcodeError::at(
                ErrorKind::EndlessProgram(self.max_executed),
                source.block(pc).line,
                raw,
                0,
                raw.len(),
            ));
        }
        Ok(())
    }

    /// A located error naming a feature volcomp does not read yet.
    fn unread(&self, feature: String, block: &KlBlock) -> GcodeError {
        let e = self.error(String::new(), block);
        GcodeError {
            kind: ErrorKind::DialectFeature("Heidenhain", feature),
            ..e
        }
    }

    fn error(&self, message: String, block: &KlBlock) -> GcodeError {
        let source = &self.files[self.file];
        let r = source.block(self.pc);
        let raw = source.raw(self.pc);
        let span = block
            .tokens
            .first()
            .map_or(0..raw.len(), |t| t.span.clone());
        let end = block.tokens.last().map_or(span.end, |t| t.span.end);
        GcodeError::at(
            ErrorKind::DialectRefused(message),
            r.line,
            raw,
            span.start,
            end,
        )
    }

    /// Run the language statements of `block` (at `pc`): assignments,
    /// jumps, calls, returns. Sets `pc` to the next block to run.
    pub fn step(&mut self, block: &KlBlock) -> Result<Flow, GcodeError> {
        let next = self.pc + 1;
        let first = block.address(0);
        // Q formulas: `Q1 = …`, `QL2 = …`.
        if let Some(p) = block.assigned() {
            let rhs = self.right_hand_side(block)?;
            let v = self.formula(&rhs, block)?;
            self.q.set(p, v);
            self.pc = next;
            return Ok(Flow::Next);
        }
        if first == "FN" {
            return self.function(block);
        }
        if block.starts_with(&["CALL", "LBL"]) {
            let label = label_at(block, 2)
                .ok_or_else(|| self.error("CALL LBL without a label".into(), block))?;
            let rep = block.find("REP", 3).map(|t| rep_count(block, t));
            return match rep {
                Some(Some(n)) => self.repeat(label, n, block),
                Some(None) => Err(self.error("REP without a count".into(), block)),
                None => self.call_label(label, block),
            };
        }
        if block.starts_with(&["CALL", "PGM"]) {
            return self.call_program(block);
        }
        if block.starts_with(&["LBL"]) {
            if label_at(block, 1) == Some(Label::Number(0))
                && let Some(frame) = self.stack.last()
                && frame.locals.is_none()
            {
                // The end of a subprogram: return after the call.
                let frame = self.stack.pop().unwrap_or(CallFrame {
                    file: 0,
                    return_to: next,
                    locals: None,
                });
                self.file = frame.file;
                self.pc = frame.return_to;
                return Ok(Flow::Next);
            }
            self.pc = next;
            return Ok(Flow::Next);
        }
        self.pc = next;
        Ok(Flow::Next)
    }

    /// End of the current program (`END PGM`, `M2`, `M30`): return from a
    /// called program; `true` when the main program ends.
    pub fn end_program(&mut self) -> bool {
        while let Some(frame) = self.stack.pop() {
            if let Some(locals) = frame.locals {
                self.file = frame.file;
                self.pc = frame.return_to;
                self.q.values.retain(|p, _| p.kind != ParamKind::Ql);
                for (p, v) in locals {
                    self.q.set(p, v);
                }
                return false;
            }
        }
        true
    }

    /// The text after the `=` of an assignment.
    fn right_hand_side(&self, block: &KlBlock) -> Result<String, GcodeError> {
        match block.code.find('=') {
            Some(k) => Ok(block.code[k + 1..].to_string()),
            None => Err(self.error("a Q parameter without `=`".into(), block)),
        }
    }

    fn formula(&self, text: &str, block: &KlBlock) -> Result<f64, GcodeError> {
        let f = Formula::parse(text.trim())
            .map_err(|e| self.error(format!("{e} in `{}`", text.trim()), block))?;
        f.eval(&|p| self.q.get(p))
            .map_err(|e| self.error(format!("{e} in `{}`", text.trim()), block))
    }

    /// `FN n: …`.
    fn function(&mut self, block: &KlBlock) -> Result<Flow, GcodeError> {
        let after = block.code.trim_start().get(2..).unwrap_or("").trim_start();
        let digits: String = after.chars().take_while(|c| c.is_ascii_digit()).collect();
        let n: u32 = digits
            .parse()
            .map_err(|_| self.error("FN without its number".into(), block))?;
        let colon = block.code.find(':').map_or(block.code.len(), |k| k + 1);
        let body = block.code.get(colon..).unwrap_or("").trim().to_string();
        match n {
            0..=8 | 13 => {
                let Some(eq) = body.find('=') else {
                    return Err(self.error(format!("FN {n} without `=`"), block));
                };
                let target = read_param(body[..eq].trim()).ok_or_else(|| {
                    self.error(format!("FN {n}: no Q parameter before `=`"), block)
                })?;
                let v = self.formula(&body[eq + 1..], block)?;
                self.q.set(target, v);
                self.pc += 1;
                Ok(Flow::Next)
            }
            9..=12 => self.conditional_jump(n, &body, block),
            // TNC 640 User's Manual (Klartext), "Q parameters › Additional
            // functions": FN 14 stops the program with an error number.
            14 => {
                let Some((_, number)) = body.split_once('=') else {
                    return Err(self.error("FN 14: ERROR without `= number`".into(), block));
                };
                let v = self.formula(number, block)?;
                let e = self.error(String::new(), block);
                Err(GcodeError {
                    kind: ErrorKind::ProgramErrorStop(v.round() as i64),
                    ..e
                })
            }
            // No motion, nothing a later block reads: FN 15 PRINT, FN 16
            // F-PRINT (formatted output), FN 19 PLC (values to the PLC), FN 20
            // WAIT FOR (a wait), FN 26/27 TABOPEN/TABWRITE, FN 29 PLC, FN 38
            // SEND: passed through.
            15 | 16 | 19 | 20 | 26 | 27 | 29 | 38 => {
                self.pc += 1;
                Ok(Flow::Next)
            }
            23 => self.circle_data(&body, block),
            // FN 17 SYSWRITE and FN 25 PRESET change the control's data, FN 18
            // SYSREAD, FN 28 TABREAD and FN 37 EXPORT give values known only on
            // the machine: not read.
            17 => Err(self.unread("FN 17: SYSWRITE (writes the control's data)".into(), block)),
            18 => Err(self.unread(
                "FN 18: SYSREAD (a value known only on the machine)".into(),
                block,
            )),
            _ => Err(self.unread(format!("FN {n}"), block)),
        }
    }

    /// `FN 23: CIRCLE DATA Qa = CDATA Qb`: the circle through the three
    /// points Qb…Qb+5 (X1 Y1 X2 Y2 X3 Y3): its centre in Qa, Qa+1 and its
    /// radius in Qa+2 (TNC 640 User's Manual (Klartext), "Q parameters ›
    /// Calculating the circle from three points").
    fn circle_data(&mut self, body: &str, block: &KlBlock) -> Result<Flow, GcodeError> {
        let bad = || self.error("FN 23: expected `CIRCLE DATA Qa = CDATA Qb`".into(), block);
        let (lhs, rhs) = body.split_once('=').ok_or_else(bad)?;
        let target = lhs
            .split_whitespace()
            .last()
            .and_then(read_param)
            .ok_or_else(bad)?;
        let source = rhs
            .split_whitespace()
            .last()
            .and_then(read_param)
            .ok_or_else(bad)?;
        let at = |k: u32| {
            self.q.get(crate::gcode::heidenhain::syntax::Param {
                number: source.number + k,
                ..source
            })
        };
        let (x1, y1, x2, y2, x3, y3) = (at(0), at(1), at(2), at(3), at(4), at(5));
        let d = 2.0 * (x1 * (y2 - y3) + x2 * (y3 - y1) + x3 * (y1 - y2));
        if d.abs() < 1e-12 {
            return Err(self.error(
                "FN 23: the three points lie on a line (no circle)".into(),
                block,
            ));
        }
        let s1 = x1 * x1 + y1 * y1;
        let s2 = x2 * x2 + y2 * y2;
        let s3 = x3 * x3 + y3 * y3;
        let cx = (s1 * (y2 - y3) + s2 * (y3 - y1) + s3 * (y1 - y2)) / d;
        let cy = (s1 * (x3 - x2) + s2 * (x1 - x3) + s3 * (x2 - x1)) / d;
        let r = (x1 - cx).hypot(y1 - cy);
        for (k, v) in [cx, cy, r].into_iter().enumerate() {
            self.q.set(
                crate::gcode::heidenhain::syntax::Param {
                    number: target.number + k as u32,
                    ..target
                },
                v,
            );
        }
        self.pc += 1;
        Ok(Flow::Next)
    }

    /// `IF a op b GOTO LBL n`.
    fn conditional_jump(
        &mut self,
        n: u32,
        body: &str,
        block: &KlBlock,
    ) -> Result<Flow, GcodeError> {
        let upper = body.to_ascii_uppercase();
        let op = match n {
            9 => "EQU",
            10 => "NE",
            11 => "GT",
            _ => "LT",
        };
        let parse = || -> Option<(String, String, String)> {
            let rest = upper.trim().strip_prefix("IF")?;
            let goto = rest.find("GOTO")?;
            let cond = &rest[..goto];
            let target = rest[goto + 4..]
                .trim()
                .strip_prefix("LBL")?
                .trim()
                .to_string();
            let k = cond.find(&format!(" {op} "))?;
            Some((
                cond[..k].to_string(),
                cond[k + op.len() + 2..].to_string(),
                target,
            ))
        };
        let Some((a, b, target)) = parse() else {
            return Err(self.error(format!("FN {n}: expected `IF a {op} b GOTO LBL n`"), block));
        };
        let (a, b) = (self.formula(&a, block)?, self.formula(&b, block)?);
        let holds = match n {
            9 => a == b,
            10 => a != b,
            11 => a > b,
            _ => a < b,
        };
        if !holds {
            self.pc += 1;
            return Ok(Flow::Next);
        }
        let label = target_label(&target, &self.q)
            .ok_or_else(|| self.error(format!("FN {n}: the jump names no label"), block))?;
        let Some(&to) = self.files[self.file].labels.get(&label) else {
            return Err(self.error(
                format!("jump to {label}, which the program does not define"),
                block,
            ));
        };
        self.pc = to;
        Ok(Flow::Jumped)
    }

    /// `CALL LBL n REP m` reached: jump back `m` times.
    fn repeat(&mut self, label: Label, n: u32, block: &KlBlock) -> Result<Flow, GcodeError> {
        let key = (self.file, self.pc);
        let left = *self.repeats.entry(key).or_insert(n);
        if left == 0 {
            self.repeats.remove(&key);
            self.pc += 1;
            return Ok(Flow::Next);
        }
        let Some(&to) = self.files[self.file].labels.get(&label) else {
            return Err(self.error(
                format!("CALL {label}: the program does not define it"),
                block,
            ));
        };
        self.repeats.insert(key, left - 1);
        self.pc = to;
        Ok(Flow::Jumped)
    }

    /// `CALL LBL n`: run the subprogram to its `LBL 0`.
    fn call_label(&mut self, label: Label, block: &KlBlock) -> Result<Flow, GcodeError> {
        let Some(&to) = self.files[self.file].labels.get(&label) else {
            return Err(self.error(
                format!("CALL {label}: the program does not define it"),
                block,
            ));
        };
        if self.stack.len() >= MAX_CALL_DEPTH {
            return Err(self.error(format!("more than {MAX_CALL_DEPTH} nested calls"), block));
        }
        self.stack.push(CallFrame {
            file: self.file,
            return_to: self.pc + 1,
            locals: None,
        });
        self.pc = to;
        Ok(Flow::Jumped)
    }

    /// `CALL PGM name`: find it beside the caller or on the search path.
    fn call_program(&mut self, block: &KlBlock) -> Result<Flow, GcodeError> {
        let name = block
            .code
            .trim()
            .get(4..)
            .and_then(|s| s.trim_start().get(3..))
            .map(|s| s.trim().trim_matches('"').to_string())
            .unwrap_or_default();
        if name.is_empty() {
            return Err(self.error("CALL PGM without a program name".into(), block));
        }
        if self.stack.len() >= MAX_CALL_DEPTH {
            return Err(self.error(format!("more than {MAX_CALL_DEPTH} nested calls"), block));
        }
        let index = match self
            .files
            .iter()
            .position(|f| f.name.eq_ignore_ascii_case(&name))
        {
            Some(i) if i > 0 => i,
            _ => {
                let path = self.find_program(&name).ok_or_else(|| {
                    self.error(
                        format!(
                            "CALL PGM {name}: no such program beside the caller or on --subroutine-path"
                        ),
                        block,
                    )
                })?;
                let text = std::fs::read(&path)
                    .map_err(|e| self.error(format!("CALL PGM {name}: {e}"), block))?;
                self.files
                    .push(Source::new(name.clone(), Some(path), text)?);
                self.files.len() - 1
            }
        };
        let locals: Vec<(Param, f64)> = self
            .q
            .values
            .iter()
            .filter(|(p, _)| p.kind == ParamKind::Ql)
            .map(|(p, v)| (*p, *v))
            .collect();
        self.q.values.retain(|p, _| p.kind != ParamKind::Ql);
        self.stack.push(CallFrame {
            file: self.file,
            return_to: self.pc + 1,
            locals: Some(locals),
        });
        self.file = index;
        self.pc = 0;
        Ok(Flow::Jumped)
    }

    fn find_program(&self, name: &str) -> Option<PathBuf> {
        let mut folders: Vec<PathBuf> = Vec::new();
        if let Some(dir) = self.files[self.file].path.as_deref().and_then(Path::parent) {
            folders.push(dir.to_path_buf());
        }
        folders.extend(self.search_path.iter().cloned());
        let candidates = [name.to_string(), format!("{name}.h"), format!("{name}.H")];
        for folder in &folders {
            for c in &candidates {
                let p = folder.join(c);
                if p.is_file() {
                    return Some(p);
                }
            }
        }
        None
    }
}

/// The count of `REP m` (or `REP m/m`, as the control shows it).
fn rep_count(block: &KlBlock, rep: &crate::gcode::heidenhain::syntax::Token) -> Option<u32> {
    let v = rep.number().or_else(|| {
        // `REP 2/2` (the control shows the repeats left after the slash).
        let i = block.tokens.iter().position(|t| std::ptr::eq(t, rep))?;
        let text = token_text(block, block.tokens.get(i + 1)?)?;
        let digits: String = text.chars().take_while(|c| c.is_ascii_digit()).collect();
        digits.parse::<f64>().ok()
    })?;
    (v >= 0.0 && v.fract() == 0.0 && v < 1e6).then_some(v as u32)
}

/// The label after `GOTO LBL`: a number, a name, or a parameter's value.
fn target_label(text: &str, q: &QParameters) -> Option<Label> {
    let t = text.trim();
    if let Some(p) = read_param(t) {
        let v = q.get(p);
        return (v >= 0.0 && v.fract() == 0.0 && v < 1e9).then_some(Label::Number(v as u32));
    }
    if let Ok(n) = t.parse::<u32>() {
        return Some(Label::Number(n));
    }
    let name = t.trim_matches('"');
    (!name.is_empty()).then(|| Label::Name(name.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(text: &str) -> Vec<(usize, bool)> {
        let source = Source::new("t".into(), None, text.as_bytes().to_vec()).unwrap();
        let mut lang = Language::new(source, Vec::new(), 10_000);
        let mut out = Vec::new();
        while lang.pc < lang.files[lang.file].blocks.len() {
            let raw = lang.files[lang.file].raw(lang.pc).to_vec();
            let line = lang.files[lang.file].blocks[lang.pc].line;
            let literal = lang.reach() == Reach::Literal;
            if literal {
                lang.next_literal = lang.pc + 1;
            }
            let b = parse_block(&raw);
            out.push((line, literal));
            if b.starts_with(&["END", "PGM"]) && lang.end_program() {
                break;
            }
            lang.step(&b).unwrap();
        }
        out
    }

    #[test]
    fn repeat_runs_the_section_rep_plus_one_times() {
        let lines = run("0 BEGIN PGM T MM\n1 LBL 1\n2 L X+1\n3 CALL LBL 1 REP 2\n4 END PGM T MM\n");
        let twos: Vec<bool> = lines.iter().filter(|l| l.0 == 2).map(|l| l.1).collect();
        assert_eq!(twos, vec![true, false, false]);
    }

    #[test]
    fn fn12_loop_and_subprogram() {
        let text = "0 BEGIN PGM T MM\n1 Q1 = 0\n2 LBL 5\n3 Q1 = Q1 + 1\n4 FN 12: IF +Q1 LT +3 GOTO LBL 5\n5 CALL LBL 9\n6 M30\n7 LBL 9\n8 L X+Q1\n9 LBL 0\n10 END PGM T MM\n";
        let lines = run(text);
        assert_eq!(lines.iter().filter(|l| l.0 == 3).count(), 3);
        assert!(lines.iter().any(|l| l.0 == 8 && !l.1));
    }

    #[test]
    fn jump_to_no_label_is_an_error() {
        let source = Source::new(
            "t".into(),
            None,
            b"0 BEGIN PGM T MM\n1 FN 9: IF +0 EQU +0 GOTO LBL 7\n".to_vec(),
        )
        .unwrap();
        let mut lang = Language::new(source, Vec::new(), 100);
        lang.pc = 1;
        let b = parse_block(lang.files[0].raw(1));
        let e = lang.step(&b).err().unwrap();
        assert!(e.to_string().contains("LBL 7"), "{e}");
    }
}
