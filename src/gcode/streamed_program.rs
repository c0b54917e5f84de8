//! A dialect's main program read as it runs, not held in memory.
//!
//! The SINUMERIK and Klartext fronts hold a program's text when its flow
//! may go back (labels, loops, structures: their lines are read again). A
//! program without any of these (a CAM program of moves) is read twice
//! instead: once through [`scan_lines`] (the line count, and whether a line
//! may move the run elsewhere, which sends the program to the held path),
//! then line by line through a [`LineStream`] as the front runs it. Memory
//! is then the input's buffer and one line, whatever the program's length.

use std::io::{self, BufRead, SeekFrom};

use crate::gcode::language::ProgramInput;
use crate::gcode::syntax::block::LineEnding;

/// Read `input` from its position to its end, a line at a time (without
/// its `\n`; a `\r` before it kept), calling `each` on every line and
/// whether a `\n` ended it: the
/// number of lines (as the held fronts split a text: a last line without
/// `\n` counts), or `None` as soon as `each` returns `false`.
pub(crate) fn scan_lines(
    input: &mut dyn BufRead,
    each: impl FnMut(&[u8], bool) -> bool,
) -> io::Result<Option<usize>> {
    scan_lines_skipping(input, |_| false, each)
}

/// [`scan_lines`], where the caller knows of a run of whole lines at once
/// that `each` would return `true` on every one of them (`skip` on the run,
/// `\n`s included): such a run is only counted. Each input buffer's whole
/// lines are offered to `skip` as one run (the lines of a CAM program's
/// moves, looked at with vector compares instead of line by line).
pub(crate) fn scan_lines_skipping(
    input: &mut dyn BufRead,
    skip: impl Fn(&[u8]) -> bool,
    mut each: impl FnMut(&[u8], bool) -> bool,
) -> io::Result<Option<usize>> {
    let mut count = 0usize;
    // A line that runs over the input's buffer, gathered here.
    let mut partial: Vec<u8> = Vec::new();
    loop {
        let buf = match input.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        if buf.is_empty() {
            if !partial.is_empty() {
                count += 1;
                if !each(&partial, false) {
                    return Ok(None);
                }
            }
            return Ok(Some(count));
        }
        let n = buf.len();
        let mut at = 0;
        // The line that completes `partial` first; then the buffer's other
        // whole lines as one run, when `skip` takes them.
        let mut run_offered = false;
        loop {
            if partial.is_empty() && !run_offered {
                run_offered = true;
                if let Some(last) = memchr::memrchr(b'\n', &buf[at..])
                    && skip(&buf[at..=at + last])
                {
                    count += memchr::memchr_iter(b'\n', &buf[at..=at + last]).count();
                    at += last + 1;
                }
            }
            let Some(k) = memchr::memchr(b'\n', &buf[at..]) else {
                break;
            };
            let line = &buf[at..at + k];
            count += 1;
            let go_on = if partial.is_empty() {
                each(line, true)
            } else {
                partial.extend_from_slice(line);
                let go_on = each(&partial, true);
                partial.clear();
                go_on
            };
            if !go_on {
                return Ok(None);
            }
            at += k + 1;
        }
        partial.extend_from_slice(&buf[at..]);
        input.consume(n);
    }
}

/// The lines of a program read in order from its input (after
/// [`scan_lines`] has read it once).
pub(crate) struct LineStream {
    input: Box<dyn ProgramInput>,
    /// Where the program starts in the input.
    start: u64,
    /// The byte offset (from `start`) and index of the next line.
    next_offset: u64,
    next_index: usize,
}

/// A line read by [`LineStream::read_line`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct StreamedLine {
    /// Its index (0 is the first line).
    pub index: usize,
    /// Its first byte's offset in the program.
    pub offset: u64,
    /// Its length without its ending.
    pub len: usize,
    pub ending: LineEnding,
}

impl LineStream {
    /// The lines of `input`, which is at `start` (its position when
    /// [`scan_lines`] began, sought back).
    pub(crate) fn new(input: Box<dyn ProgramInput>, start: u64) -> LineStream {
        LineStream {
            input,
            start,
            next_offset: 0,
            next_index: 0,
        }
    }

    /// Read from the first line again.
    pub(crate) fn restart(&mut self) -> io::Result<()> {
        self.input.seek(SeekFrom::Start(self.start))?;
        self.next_offset = 0;
        self.next_index = 0;
        Ok(())
    }

    /// Line `index` into `buf` (replacing it; its ending included): the
    /// next line in order, or, for any other line, read again from the
    /// start. `None` past the end.
    pub(crate) fn read_line(
        &mut self,
        index: usize,
        buf: &mut Vec<u8>,
    ) -> io::Result<Option<StreamedLine>> {
        buf.clear();
        self.append_line(index, buf)
    }

    /// [`LineStream::read_line`], the line appended to `buf` (its
    /// [`StreamedLine::len`] counted from where it starts there).
    pub(crate) fn append_line(
        &mut self,
        index: usize,
        buf: &mut Vec<u8>,
    ) -> io::Result<Option<StreamedLine>> {
        if index < self.next_index {
            self.restart()?;
        }
        let at = buf.len();
        loop {
            buf.truncate(at);
            let n = read_until_newline(&mut *self.input, buf)?;
            if n == 0 {
                return Ok(None);
            }
            let line = StreamedLine {
                index: self.next_index,
                offset: self.next_offset,
                len: 0,
                ending: LineEnding::None,
            };
            self.next_offset += n as u64;
            self.next_index += 1;
            if line.index < index {
                continue;
            }
            let line_bytes = &buf[at..];
            let (len, ending) = if line_bytes.last() == Some(&b'\n') {
                let eol = line_bytes.len() - 1;
                if eol > 0 && line_bytes[eol - 1] == b'\r' {
                    (eol - 1, LineEnding::CrLf)
                } else {
                    (eol, LineEnding::Lf)
                }
            } else {
                (line_bytes.len(), LineEnding::None)
            };
            return Ok(Some(StreamedLine {
                len,
                ending,
                ..line
            }));
        }
    }
}

/// `BufRead::read_until(b'\n', buf)`, its search vectorised.
fn read_until_newline(input: &mut dyn BufRead, buf: &mut Vec<u8>) -> io::Result<usize> {
    let mut read = 0;
    loop {
        let available = match input.fill_buf() {
            Ok(b) => b,
            Err(e) if e.kind() == io::ErrorKind::Interrupted => continue,
            Err(e) => return Err(e),
        };
        let (done, used) = match memchr::memchr(b'\n', available) {
            Some(k) => {
                buf.extend_from_slice(&available[..=k]);
                (true, k + 1)
            }
            None => {
                buf.extend_from_slice(available);
                (available.is_empty(), available.len())
            }
        };
        input.consume(used);
        read += used;
        if done {
            return Ok(read);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lines(text: &[u8]) -> Vec<Vec<u8>> {
        let mut out = Vec::new();
        let mut input = io::BufReader::with_capacity(4, text);
        let count = scan_lines(&mut input, |l, _| {
            out.push(l.to_vec());
            true
        })
        .unwrap();
        assert_eq!(count, Some(out.len()));
        out
    }

    #[test]
    fn lines_across_the_buffer_are_whole() {
        assert_eq!(
            lines(b"G1 X1\r\nG1 X22\n\nX3"),
            vec![
                b"G1 X1\r".to_vec(),
                b"G1 X22".to_vec(),
                b"".to_vec(),
                b"X3".to_vec()
            ]
        );
        assert_eq!(lines(b""), Vec::<Vec<u8>>::new());
        assert_eq!(lines(b"a\n"), vec![b"a".to_vec()]);
    }

    #[test]
    fn skipped_runs_are_counted_as_their_lines() {
        for capacity in [1, 3, 4, 7, 64] {
            for text in [&b"G1 X1\r\nG1 X22\n\nX3"[..], b"a\n", b"", b"\n\n\nb\nc\n"] {
                let mut seen = 0;
                let mut input = io::BufReader::with_capacity(capacity, text);
                let skipped = scan_lines_skipping(
                    &mut input,
                    |run| !run.contains(&b'2'),
                    |_, _| {
                        seen += 1;
                        true
                    },
                )
                .unwrap();
                let all = scan_lines(&mut io::BufReader::with_capacity(capacity, text), |_, _| {
                    true
                })
                .unwrap();
                assert_eq!(skipped, all, "{capacity} {text:?}");
                // A run skipped is not seen line by line.
                assert!(seen <= all.unwrap_or(0));
            }
        }
    }

    #[test]
    fn a_stream_reads_in_order_and_again() {
        let text = b"%\nG1 X1\r\nX2";
        let input = Box::new(io::Cursor::new(text.to_vec()));
        let mut s = LineStream::new(input, 0);
        let mut buf = Vec::new();
        let l = s.read_line(0, &mut buf).unwrap().unwrap();
        assert_eq!((l.offset, l.len, l.ending), (0, 1, LineEnding::Lf));
        let l = s.read_line(1, &mut buf).unwrap().unwrap();
        assert_eq!((l.offset, l.len, l.ending), (2, 5, LineEnding::CrLf));
        assert_eq!(&buf[..l.len], b"G1 X1");
        let l = s.read_line(2, &mut buf).unwrap().unwrap();
        assert_eq!((l.offset, l.len, l.ending), (9, 2, LineEnding::None));
        assert!(s.read_line(3, &mut buf).unwrap().is_none());
        // Back to a line read before: from the start again.
        let l = s.read_line(1, &mut buf).unwrap().unwrap();
        assert_eq!((l.index, l.offset), (1, 2));
    }
}
