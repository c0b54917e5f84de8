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

use super::error::GcodeError;

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
    /// Byte range of the whole word (letter to last digit) inside the line.
    pub start: usize,
    pub end: usize,
    /// Digits written after the decimal point (`X5.` and `X5` have 0).
    pub decimals: u8,
    /// Whether the number had a decimal point.
    pub point: bool,
}

impl Word {
    pub fn span(&self) -> Range<usize> {
        self.start..self.end
    }

    /// The G/M code number times ten, when the value has at most one decimal
    /// (`G43.4` → 434, `G1` → 10); `None` for values such as `G1.25`.
    pub fn code10(&self) -> Option<i32> {
        let t = self.value * 10.0;
        let r = t.round();
        if (t - r).abs() < 1e-6 && r.abs() < 1e9 {
            Some(r as i32)
        } else {
            None
        }
    }
}

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
    pub keyword: Keyword,
    pub start: usize,
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
    /// Byte ranges of the comments, `( … )` and `; …`, delimiters included.
    pub comments: Vec<Range<usize>>,
    /// Lenient reading only: the line could not be parsed; it is kept verbatim,
    /// without words, and this is why.
    pub unparsed: Option<Box<GcodeError>>,
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

    /// Whether the line has neither words nor keywords (blank, comment only, `%`).
    pub fn is_empty(&self) -> bool {
        self.words.is_empty() && self.keywords.is_empty()
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
        self.comments.clear();
        self.unparsed = None;
    }
}
