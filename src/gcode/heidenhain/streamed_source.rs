//! A Klartext main program read as it runs (`crate::gcode::streamed_program`):
//! when no block of it has a label (`LBL`), nothing can jump (every jump and
//! call in a program goes to a label), so its blocks are read once, in
//! order. A first pass splits it into logical blocks as
//! [`Source::new`](super::language::Source::new) does and checks each; the
//! run then holds a window of blocks: the one running and the ones the
//! corner look-ahead reads after it.

use std::collections::VecDeque;
use std::io::{self, SeekFrom};

use super::language::BlockRef;
use crate::gcode::language::ProgramInput;
use crate::gcode::streamed_program::scan_lines;
use crate::gcode::syntax::block::LineEnding;

/// Bytes before the window's first block forgotten once they reach this.
const CHUNK: usize = 1 << 16;

/// Logical blocks (a line and its `~` continuation lines) read in order,
/// in chunks: a block's bytes are where the chunks put them (no copy a
/// line), as [`LineStream`](crate::gcode::streamed_program::LineStream)
/// splits them.
struct BlockStream {
    input: Box<dyn ProgramInput>,
    /// Where the program starts in the input.
    start: u64,
    /// The bytes read and kept: `text[0]` is the program's byte `offset`.
    text: Vec<u8>,
    offset: usize,
    /// Where the next line starts in `text`, and its index.
    next: usize,
    next_line: usize,
    /// The input has no byte after `text`.
    eof: bool,
}

impl BlockStream {
    /// Read more of the input (what its buffer holds) into `text`:
    /// `false` at its end.
    fn read_more(&mut self) -> io::Result<bool> {
        if self.eof {
            return Ok(false);
        }
        let n = loop {
            match self.input.fill_buf() {
                Ok(b) => {
                    self.text.extend_from_slice(b);
                    break b.len();
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
                Err(e) => return Err(e),
            }
        };
        self.input.consume(n);
        self.eof = n == 0;
        Ok(n > 0)
    }

    /// The next line: where it starts in `text`, its length without its
    /// ending, and the ending. `None` at the end.
    fn line(&mut self) -> io::Result<Option<(usize, usize, LineEnding)>> {
        let mut searched = self.next;
        loop {
            if let Some(k) = memchr::memchr(b'\n', &self.text[searched..]) {
                let eol = searched + k;
                let start = self.next;
                self.next = eol + 1;
                self.next_line += 1;
                return Ok(Some(if eol > start && self.text[eol - 1] == b'\r' {
                    (start, eol - 1 - start, LineEnding::CrLf)
                } else {
                    (start, eol - start, LineEnding::Lf)
                }));
            }
            searched = self.text.len();
            if !self.read_more()? {
                if self.next == self.text.len() {
                    return Ok(None);
                }
                let start = self.next;
                self.next = self.text.len();
                self.next_line += 1;
                return Ok(Some((start, self.text.len() - start, LineEnding::None)));
            }
        }
    }

    /// Whether no byte follows the lines read.
    fn at_end(&mut self) -> io::Result<bool> {
        Ok(self.next == self.text.len() && !self.read_more()?)
    }

    /// The next block (what `Source::raw` gives: continuation lines with
    /// their endings, the last line without) with its place in the file,
    /// and where its bytes start in `text`. `None` at the end.
    fn read_block(&mut self) -> io::Result<Option<(BlockRef, usize)>> {
        let mut first: Option<(usize, usize)> = None;
        loop {
            let Some((at, len, ending)) = self.line()? else {
                return Ok(None);
            };
            let (start, line) = *first.get_or_insert((at, self.next_line));
            let content_end = at + len;
            // `Source::new`: a line ending in `~` continues, unless no byte follows it.
            let continues = self.text[start..content_end]
                .trim_ascii_end()
                .ends_with(b"~")
                && ending != LineEnding::None
                && !self.at_end()?;
            if !continues {
                let block_start = self.offset + start;
                return Ok(Some((
                    BlockRef {
                        start: block_start,
                        end: block_start + (content_end - start),
                        ending,
                        line,
                    },
                    start,
                )));
            }
        }
    }

    /// Forget the bytes before `keep` (an offset in `text`), moving the rest
    /// to the front; returns how far they moved.
    fn forget_before(&mut self, keep: usize) -> usize {
        self.text.drain(..keep);
        self.offset += keep;
        self.next -= keep;
        keep
    }

    /// Read from the first line again.
    fn restart(&mut self) -> io::Result<()> {
        self.input.seek(SeekFrom::Start(self.start))?;
        self.text.clear();
        self.offset = 0;
        self.next = 0;
        self.next_line = 0;
        self.eof = false;
        Ok(())
    }
}

/// Whether a block has a label (`LBL`, in any case: conservative).
fn has_label(raw: &[u8]) -> bool {
    let flagged = raw.iter().fold(0u8, |f, &b| f | u8::from(b | 0x20 == b'b'));
    flagged != 0 && raw.windows(3).any(|w| w.eq_ignore_ascii_case(b"LBL"))
}

/// The blocks of a streamed main program around the one running.
pub(crate) struct Window {
    blocks: BlockStream,
    /// The program's number of blocks and its last block's line.
    count: usize,
    last_line: Option<usize>,
    /// The index of the first block held.
    first: usize,
    /// The blocks held, each with where its bytes start in the stream's text.
    held: VecDeque<(BlockRef, usize)>,
}

impl Window {
    /// Read `input` (at `start`) once: its blocks, each given to `each`
    /// with its line (the caller's checks: `false` stops). `Err`: a block
    /// has a label, `each` said no, or the input failed: the input back at
    /// `start`, to be read whole.
    pub(crate) fn scan(
        mut input: Box<dyn ProgramInput>,
        start: u64,
        mut each: impl FnMut(&[u8], usize) -> bool,
    ) -> Result<Window, Box<dyn ProgramInput>> {
        let mut count = 0usize;
        let mut last_line = None;
        let mut check = |raw: &[u8], line: usize| {
            if has_label(raw) || !each(raw, line) {
                return false;
            }
            count += 1;
            last_line = Some(line);
            true
        };
        // A block whose line ends in `~` (with its ending: it continues
        // unless no byte follows), gathered here; most blocks are a line,
        // checked where the input's buffer holds it.
        let mut open: Vec<u8> = Vec::new();
        let mut open_ending = 0usize;
        let mut first_line = 0usize;
        let mut line_no = 0usize;
        let scan = scan_lines(&mut input, |line, newline| {
            line_no += 1;
            let content = match line {
                [rest @ .., b'\r'] if newline => rest,
                _ => line,
            };
            let ending: &[u8] = match (newline, content.len() < line.len()) {
                (false, _) => b"",
                (true, true) => b"\r\n",
                (true, false) => b"\n",
            };
            if open_ending > 0 || !open.is_empty() {
                open.extend_from_slice(content);
            } else {
                first_line = line_no;
                if !(newline && content.trim_ascii_end().ends_with(b"~")) {
                    return check(content, first_line);
                }
                open.extend_from_slice(content);
            }
            if newline && open.trim_ascii_end().ends_with(b"~") {
                open.extend_from_slice(ending);
                open_ending = ending.len();
                return true;
            }
            let go_on = check(&open, first_line);
            open.clear();
            open_ending = 0;
            go_on
        });
        let straight = match scan {
            // A block left open: no byte followed its `~` line.
            Ok(Some(_)) if open_ending > 0 => {
                let end = open.len() - open_ending;
                check(&open[..end], first_line)
            }
            Ok(Some(_)) => true,
            _ => false,
        };
        if input.seek(std::io::SeekFrom::Start(start)).is_err() {
            // Not sought back: the held path reads what is left (its error).
            return Err(input);
        }
        if !straight {
            return Err(input);
        }
        Ok(Window {
            blocks: BlockStream {
                input,
                start,
                text: Vec::new(),
                offset: 0,
                next: 0,
                next_line: 0,
                eof: false,
            },
            count,
            last_line,
            first: 0,
            held: VecDeque::new(),
        })
    }

    pub(crate) fn len(&self) -> usize {
        self.count
    }

    pub(crate) fn last_line(&self) -> Option<usize> {
        self.last_line
    }

    /// Block `k`, if held.
    #[inline]
    pub(crate) fn block(&self, k: usize) -> Option<BlockRef> {
        let i = k.checked_sub(self.first)?;
        self.held.get(i).map(|(b, _)| *b)
    }

    /// Block `k`'s bytes (empty when not held).
    #[inline]
    pub(crate) fn raw(&self, k: usize) -> &[u8] {
        let Some(i) = k.checked_sub(self.first) else {
            return b"";
        };
        match self.held.get(i) {
            Some((b, at)) => self
                .blocks
                .text
                .get(*at..*at + (b.end - b.start))
                .unwrap_or_default(),
            None => b"",
        }
    }

    /// Hold blocks `from..to` (those that exist), and none before `from`.
    pub(crate) fn fill(&mut self, from: usize, to: usize) -> io::Result<()> {
        if from < self.first {
            // Back before the window (not for a program without labels):
            // from the start again.
            self.blocks.restart()?;
            self.held.clear();
            self.first = 0;
        }
        while self.first < from {
            if self.held.pop_front().is_none() {
                // Skipped without holding.
                if self.blocks.read_block()?.is_none() {
                    break;
                }
            }
            self.first += 1;
        }
        // The bytes before the first block held (all read, when none is)
        // are forgotten once they pass a chunk.
        let keep = self.held.front().map_or(self.blocks.next, |&(_, at)| at);
        if keep >= CHUNK {
            let moved = self.blocks.forget_before(keep);
            for (_, a) in &mut self.held {
                *a -= moved;
            }
        }
        let to = to.min(self.count);
        while self.first + self.held.len() < to {
            match self.blocks.read_block()? {
                Some(b) => self.held.push_back(b),
                None => break,
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gcode::heidenhain::language::Source;
    use std::io::Read;

    fn window(text: &[u8]) -> Result<Window, Box<dyn ProgramInput>> {
        let input = Box::new(io::BufReader::with_capacity(
            8,
            io::Cursor::new(text.to_vec()),
        ));
        Window::scan(input, 0, |_, _| true)
    }

    #[test]
    fn streamed_blocks_are_the_held_ones() {
        for text in [
            &b"0 BEGIN PGM T MM\r\n1 L X+1 ~\r\n  Y+2 F100\r\n2 L X+3 ~\r\n3 END PGM T MM ~\r\n"[..],
            b"0 BEGIN PGM T MM\n1 L X+1 ~\n\n2 L Y+2\n3 END PGM T MM",
            b"0 BEGIN PGM T MM\n1 L X+1 ~",
            b"",
        ] {
            let held = Source::new("t".into(), None, text.to_vec()).unwrap();
            let mut w = window(text).ok().unwrap();
            assert_eq!(w.len(), held.blocks.len());
            assert_eq!(w.last_line(), held.blocks.last().map(|b| b.line));
            for k in 0..held.blocks.len() {
                w.fill(k, k + 2).unwrap();
                let (a, b) = (w.block(k).unwrap(), held.blocks[k]);
                assert_eq!(
                    (a.start, a.end, a.ending, a.line),
                    (b.start, b.end, b.ending, b.line)
                );
                assert_eq!(w.raw(k), held.raw(k));
            }
            // Back before the window: read from the start again.
            w.fill(0, 1).unwrap();
            if !held.blocks.is_empty() {
                assert_eq!(w.raw(0), held.raw(0));
            }
        }
    }

    #[test]
    fn a_program_with_a_label_or_a_refused_block_is_held() {
        assert!(window(b"0 BEGIN PGM T MM\n1 lbl 1\n2 END PGM T MM\n").is_err());
        let input = Box::new(io::Cursor::new(b"0 BEGIN PGM T MM\n".to_vec()));
        let mut input = match Window::scan(input, 0, |_, _| false) {
            Ok(_) => panic!("a block the caller refused"),
            Err(input) => input,
        };
        let mut all = Vec::new();
        input.read_to_end(&mut all).unwrap();
        assert_eq!(all, b"0 BEGIN PGM T MM\n");
    }
}
