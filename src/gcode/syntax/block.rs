//! The syntax of one block (one line of the program), lossless.
//!
//! Invariants: a [`Block`] is exactly one line of the input; `raw` holds its
//! bytes without the line ending, and `ending` the line ending that followed it,
//! so `raw + ending` over all blocks reproduces the file byte for byte. Every
//! [`Word`] knows its byte range inside `raw`, its letter (upper case), its
//! value (exactly as `str::parse::<f64>` reads the digits with the spaces
//! removed) and the number of decimals written. Nothing here has meaning yet:
//! that is the interpreter's job (`interpret.rs`).
use std::ops::Range;

use crate::gcode::error::GcodeError;

/// The line ending that followed a line in the input.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LineEnding {
    /// `\n`.
    #[default]
    Lf,
    /// `\r\n`.
    CrLf,
    /// The last line of a file without a final newline.
    None,
}

impl LineEnding {
    /// Take the line ending off a line as read (`\n`, `\r\n`, or none at the
    /// end of a file) and say which it was.
    pub fn take_from(raw: &mut Vec<u8>) -> LineEnding {
        if raw.last() != Some(&b'\n') {
            return LineEnding::None;
        }
        raw.pop();
        if raw.last() == Some(&b'\r') {
            raw.pop();
            LineEnding::CrLf
        } else {
            LineEnding::Lf
        }
    }

    /// The bytes that end the line (empty for [`LineEnding::None`]).
    pub fn as_bytes(self) -> &'static [u8] {
        match self {
            LineEnding::Lf => b"\n",
            LineEnding::CrLf => b"\r\n",
            LineEnding::None => b"",
        }
    }
}

/// One word: a letter and a number (`X-0.5`, `g43.4`, `F 159`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Word {
    /// The letter, upper-cased ASCII (`b'X'`).
    pub letter: u8,
    /// The value as written (sign included), never NaN or infinite.
    pub value: f64,
    /// Byte offset of the word's letter inside the line (0-based).
    pub start: usize,
    /// Byte offset just past the word's last digit (exclusive end).
    pub end: usize,
    /// Digits written after the decimal point (`X5.` and `X5` have 0).
    pub decimals: u8,
    /// Whether the number had a decimal point.
    pub point: bool,
    /// The value is computed (a parameter, an expression or a function): the
    /// index of its syntax tree in [`Block::exprs`]. `value` is 0 until the
    /// language layer evaluates it (an executed block has every value set).
    pub expr: Option<u32>,
}

impl Word {
    /// Byte range of the whole word (letter to last digit) inside the line.
    pub fn span(&self) -> Range<usize> {
        self.start..self.end
    }

    /// The G/M code number times ten, when the value has at most one decimal
    /// (`G43.4` → 434, `G1` → 10); `None` for values such as `G1.25`.
    pub fn code10(&self) -> Option<i32> {
        let t = self.value * 10.0;
        let r = round_half_away(t);
        if (t - r).abs() < 1e-6 && r.abs() < 1e9 {
            Some(r as i32)
        } else {
            None
        }
    }
}

/// `t.round()` (halves away from zero) in SSE2 arithmetic, without the
/// library call `round` is on a target without SSE4.1: every block's G and
/// M words come through [`Word::code10`] several times. Adding and taking
/// away 2^52 rounds to the nearest whole number (ties to even); a tie is
/// then moved away from zero. Not inlined: its callers keep their size.
#[inline(never)]
fn round_half_away(t: f64) -> f64 {
    const TWO_52: f64 = 4_503_599_627_370_496.0;
    // Whole already (and NaN, ±∞): as `round`.
    if !(t.abs() < TWO_52) {
        return t;
    }
    let magic = TWO_52.copysign(t);
    let r = (t + magic) - magic;
    let r = if (t - r).abs() == 0.5 {
        t + 0.5f64.copysign(t)
    } else {
        r
    };
    r.copysign(t)
}

/// A parameter assignment `#1=…`, `#<name>=…` (applied after the whole line
/// is read, in order: LinuxCNC's parallel setting).
#[derive(Clone, Debug, PartialEq)]
pub struct Assignment {
    pub target: AssignTarget,
    /// The value: an index into [`Block::exprs`].
    pub value: u32,
    /// Byte range of the whole assignment.
    pub start: usize,
    pub end: usize,
}

/// What an assignment sets.
#[derive(Clone, Debug, PartialEq)]
pub enum AssignTarget {
    /// A numbered parameter; its number is an expression (index into [`Block::exprs`]).
    Numbered(u32),
    /// A named parameter (lower case, spaces removed).
    Named(String),
}

/// The keyword of an O-word line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OKeyword {
    Sub,
    EndSub,
    Call,
    Do,
    While,
    EndWhile,
    If,
    ElseIf,
    Else,
    EndIf,
    Repeat,
    EndRepeat,
    Return,
    Break,
    Continue,
}

impl OKeyword {
    /// Every keyword, longest first where one is a prefix of another
    /// (`endsub` before `end…`, `elseif` before `else`).
    pub const ALL: [(&'static str, OKeyword); 15] = [
        ("endsub", OKeyword::EndSub),
        ("endwhile", OKeyword::EndWhile),
        ("endif", OKeyword::EndIf),
        ("endrepeat", OKeyword::EndRepeat),
        ("elseif", OKeyword::ElseIf),
        ("else", OKeyword::Else),
        ("sub", OKeyword::Sub),
        ("call", OKeyword::Call),
        ("do", OKeyword::Do),
        ("while", OKeyword::While),
        ("if", OKeyword::If),
        ("repeat", OKeyword::Repeat),
        ("return", OKeyword::Return),
        ("break", OKeyword::Break),
        ("continue", OKeyword::Continue),
    ];

    pub fn name(self) -> &'static str {
        OKeyword::ALL
            .iter()
            .find(|(_, k)| *k == self)
            .map(|(n, _)| *n)
            .unwrap_or("?")
    }
}

/// The label of an O-word: `O100` (a number, possibly computed) or `O<name>`.
#[derive(Clone, Debug, PartialEq)]
pub enum OLabel {
    /// The number's expression (index into [`Block::exprs`]).
    Number(u32),
    /// The name, lower case, spaces removed.
    Name(String),
}

/// An O-word control line (`O100 while [#1 LT 10]`, `o<drill> call [1] [2]`).
#[derive(Clone, Debug, PartialEq)]
pub struct OWord {
    pub label: OLabel,
    pub keyword: OKeyword,
    /// Call arguments; the condition of while/if/elseif; the count of repeat;
    /// the optional value of return/endsub (indices into [`Block::exprs`]).
    pub args: Vec<u32>,
    /// Byte range from the `O` to the end of the keyword.
    pub start: usize,
    pub end: usize,
}

/// The letters of a dialect's orientation-vector words (SINUMERIK `A3=`
/// `B3=` `C3=`, the tool direction's X Y Z components in the block's frame):
/// not axis letters, so the machine-state layer passes them over; the rotary
/// joints the front solved from them ride in the same block as zero-width
/// axis words, and the rewriter writes a changed orientation back as a
/// vector (`Rewriter::with_orientation`).
pub const ORIENTATION_VECTOR_LETTERS: [u8; 3] = [b'1', b'2', b'3'];

/// Bare keywords that switch the frame (Siemens ISO mode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Keyword {
    /// `TRAORI`: tool-tip (part-frame) programming on.
    TraOri,
    /// `TRAFOOF`: transformation off (joint frame).
    TraFoof,
}

/// A keyword and its byte range in the line.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KeywordWord {
    /// Which keyword.
    pub keyword: Keyword,
    /// Byte offset of its first character inside the line (0-based).
    pub start: usize,
    /// Byte offset just past its last character (exclusive end).
    pub end: usize,
}

/// One line of the program, parsed but not interpreted.
#[derive(Clone, Debug, Default)]
pub struct Block {
    /// 1-based line number.
    pub line: usize,
    /// Byte offset of the line's first byte in the input.
    pub offset: u64,
    /// The line's bytes without its line ending (may be non-UTF-8 in comments).
    pub raw: Vec<u8>,
    /// The line ending that followed the line.
    pub ending: LineEnding,
    /// A `%` tape-marker line (not interpreted).
    pub percent: bool,
    /// Block delete: the line starts with `/`.
    pub deleted: bool,
    /// The words in the order written (N and O words included).
    pub words: Vec<Word>,
    /// Frame keywords (`TRAORI`, `TRAFOOF`).
    pub keywords: Vec<KeywordWord>,
    /// Parameter assignments, in the order written.
    pub assignments: Vec<Assignment>,
    /// The O-word control of the line, if any (the line then holds nothing else
    /// but comments).
    pub o_word: Option<OWord>,
    /// The syntax trees of computed values (words, assignments, O-word arguments).
    pub exprs: Vec<crate::gcode::syntax::expression::Expr>,
    /// Byte ranges of the comments, `( … )` and `; …`, delimiters included.
    pub comments: Vec<Range<usize>>,
    /// A dialect's non-moving statements passed through untouched (`STOPRE`,
    /// `MSG(…)`, `CYCLE832(…)`, `BLK FORM`…): their byte ranges, each
    /// starting with the statement's name (counted by the summary). Empty
    /// for LinuxCNC programs.
    pub statements: Vec<Range<usize>>,
    /// Lenient reading only: the line could not be parsed; it is kept verbatim,
    /// without words, and this is why.
    pub unparsed: Option<Box<GcodeError>>,
    /// The words the machine-state layer and the summary read when a front
    /// found words in `words` that change nothing ([`Block::machine_words`]:
    /// a SINUMERIK block number, a `G1` under `G1`, an `F` of the feed in
    /// force); they stay in `words`, which writers read. Unused otherwise.
    pub(crate) machine_words: Vec<Word>,
    /// `machine_words` holds the words to read (a front passed over some).
    pub(crate) inert_words: bool,
}

impl Block {
    /// Byte span of the line (without its ending) in the input.
    pub fn span(&self) -> Range<u64> {
        self.offset..self.offset + self.raw.len() as u64
    }

    /// The raw text, lossily decoded (non-UTF-8 bytes become U+FFFD).
    pub fn text(&self) -> std::borrow::Cow<'_, str> {
        String::from_utf8_lossy(&self.raw)
    }

    /// The first word with this (upper-case) letter.
    pub fn word(&self, letter: u8) -> Option<&Word> {
        self.words.iter().find(|w| w.letter == letter)
    }

    /// The N block number, if any.
    pub fn block_number(&self) -> Option<f64> {
        self.word(b'N').map(|w| w.value)
    }

    /// The words the machine-state layer reads: `words` without those a
    /// front found to change nothing (all of `words` unless it found some).
    #[inline]
    pub(crate) fn machine_words(&self) -> &[Word] {
        if self.inert_words {
            &self.machine_words
        } else {
            &self.words
        }
    }

    /// Whether the line has neither words nor keywords, assignments or an
    /// O-word (blank, comment only, `%`).
    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
            && self.keywords.is_empty()
            && self.assignments.is_empty()
            && self.o_word.is_none()
            && self.statements.is_empty()
    }

    /// Whether the line uses the RS274NGC language: a computed word, an
    /// assignment or an O-word (its executed meaning is not its literal text).
    pub fn uses_language(&self) -> bool {
        !self.exprs.is_empty() || !self.assignments.is_empty() || self.o_word.is_some()
    }

    /// Write the line exactly as read, line ending included.
    pub fn write_raw(&self, out: &mut dyn std::io::Write) -> std::io::Result<()> {
        out.write_all(&self.raw)?;
        out.write_all(self.ending.as_bytes())
    }

    pub(crate) fn reset(&mut self, line: usize, offset: u64) {
        self.line = line;
        self.offset = offset;
        self.raw.clear();
        self.ending = LineEnding::Lf;
        self.percent = false;
        self.deleted = false;
        self.words.clear();
        self.keywords.clear();
        self.assignments.clear();
        self.o_word = None;
        self.exprs.clear();
        self.comments.clear();
        self.statements.clear();
        self.unparsed = None;
        self.inert_words = false;
    }
}
