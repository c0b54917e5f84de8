//! Streaming: one block per line from any `BufRead`, with memory that does not
//! grow with the program (the line buffer and the block's word vectors are
//! reused).
//!
//! ```
//! use volcomp::gcode::{BlockReader, ReadOptions};
//! let text = "%\nN10 G0 X1 Y2\r\nN20 G1 Z-1 F100";
//! let mut reader = BlockReader::new(text.as_bytes(), ReadOptions::default());
//! let mut n = 0;
//! while let Some(block) = reader.next_block() {
//!     let block = block.unwrap();
//!     n += block.words.len();
//! }
//! assert_eq!(n, 8);
//! ```
use std::io::BufRead;

use super::block::{Block, LineEnding};
use super::parser::parse_line;
use crate::gcode::error::{ErrorKind, GcodeError};

/// The longest line read, bytes (its line end not counted). LinuxCNC reads
/// at most 254 characters ("Command too long"); volcomp reads longer lines
/// (long comments) but not without bound: a longer line is an error, and
/// reading it keeps at most this much of it in memory.
pub const MAX_LINE_BYTES: usize = 65_536;

/// Read one line through its `\n` into `buf` (empty on entry), keeping at
/// most [`MAX_LINE_BYTES`] + 2 bytes of it. Returns the bytes consumed (the
/// whole line, 0 at the end of the input) and, for a line longer than the
/// limit, its length without the `\n` (then `buf` holds its beginning).
pub fn read_line_bounded(
    input: &mut (impl BufRead + ?Sized),
    buf: &mut Vec<u8>,
) -> std::io::Result<(usize, Option<usize>)> {
    let keep = MAX_LINE_BYTES + 2; // the line, and CR LF
    let mut consumed = 0;
    let mut newline = false;
    loop {
        let available = match input.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if available.is_empty() {
            break;
        }
        let (take, done) = match memchr::memchr(b'\n', available) {
            Some(k) => (k + 1, true),
            None => (available.len(), false),
        };
        let room = keep.saturating_sub(buf.len());
        buf.extend_from_slice(&available[..take.min(room)]);
        input.consume(take);
        consumed += take;
        if done {
            newline = true;
            break;
        }
    }
    let length = consumed - usize::from(newline);
    let whole = consumed == buf.len();
    let content = if whole && buf[..length].ends_with(b"\r") {
        length - 1
    } else {
        length
    };
    Ok((consumed, (content > MAX_LINE_BYTES).then_some(length)))
}

/// The error of a line longer than [`MAX_LINE_BYTES`]: located at the
/// first byte past the limit, showing the line's beginning.
pub fn line_too_long(line: usize, kept: &[u8], length: usize) -> GcodeError {
    GcodeError::at(
        ErrorKind::LineTooLong {
            bytes: length,
            limit: MAX_LINE_BYTES,
        },
        line,
        &kept[..kept.len().min(MAX_LINE_BYTES)],
        0,
        1,
    )
}

/// How to read.
#[derive(Clone, Copy, Debug, Default)]
pub struct ReadOptions {
    /// A line that cannot be parsed is returned as a block with no words and
    /// `unparsed` set (kept verbatim) instead of an error.
    pub lenient: bool,
}

/// Reads blocks one by one. [`BlockReader::next_block`] lends the reused block;
/// the `Iterator` implementation clones it (convenient, allocates per block).
pub struct BlockReader<R> {
    input: R,
    options: ReadOptions,
    block: Block,
    line: usize,
    offset: u64,
    done: bool,
}

impl<R: BufRead> BlockReader<R> {
    /// A reader of the blocks of `input`, from its first line.
    pub fn new(input: R, options: ReadOptions) -> Self {
        BlockReader {
            input,
            options,
            block: Block::default(),
            line: 0,
            offset: 0,
            done: false,
        }
    }

    /// The next line as a block, `None` at the end of the input. After an error
    /// of one line the reader goes on with the next; after an I/O error it stops.
    pub fn next_block(&mut self) -> Option<Result<&Block, GcodeError>> {
        if self.done {
            return None;
        }
        self.line += 1;
        self.block.reset(self.line, self.offset);
        let n = match read_line_bounded(&mut self.input, &mut self.block.raw) {
            Ok((n, Some(length))) => {
                self.offset += n as u64;
                return Some(Err(line_too_long(self.line, &self.block.raw, length)));
            }
            Ok((n, None)) => n,
            Err(e) => {
                self.done = true;
                return Some(Err(GcodeError::at(
                    ErrorKind::Io(e.to_string()),
                    self.line,
                    b"",
                    0,
                    0,
                )));
            }
        };
        if n == 0 {
            self.done = true;
            return None;
        }
        self.offset += n as u64;
        self.block.ending = LineEnding::take_from(&mut self.block.raw);
        match parse_line(&mut self.block) {
            Ok(()) => Some(Ok(&self.block)),
            Err(e) => {
                if self.options.lenient {
                    self.block.words.clear();
                    self.block.keywords.clear();
                    self.block.comments.clear();
                    self.block.unparsed = Some(Box::new(e));
                    Some(Ok(&self.block))
                } else {
                    Some(Err(e))
                }
            }
        }
    }

    /// Lines read so far.
    pub fn lines_read(&self) -> usize {
        self.line
    }
}

impl<R: BufRead> Iterator for BlockReader<R> {
    type Item = Result<Block, GcodeError>;

    fn next(&mut self) -> Option<Self::Item> {
        self.next_block().map(|r| r.cloned())
    }
}

/// Parse a whole program held in memory (strict: the first bad line is an error).
pub fn parse_program(text: &str) -> Result<Vec<Block>, GcodeError> {
    parse_program_bytes(text.as_bytes(), ReadOptions::default())
}

/// Parse a whole program from bytes with the given options.
pub fn parse_program_bytes(bytes: &[u8], options: ReadOptions) -> Result<Vec<Block>, GcodeError> {
    BlockReader::new(bytes, options).collect()
}

/// Write blocks back exactly as read.
pub fn print_program(blocks: &[Block]) -> Vec<u8> {
    let mut out = Vec::new();
    for b in blocks {
        out.extend_from_slice(&b.raw);
        out.extend_from_slice(b.ending.as_bytes());
    }
    out
}
