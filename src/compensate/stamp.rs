//! The provenance stamp of a compensated program (docs/extensions.md).
//!
//! `volcomp compensate` writes a few parenthesised comment lines at the head of
//! its output, after a leading `%` line and an `O` program-number line, so that
//! LinuxCNC, Fanuc and Siemens (ISO mode) readers still see a valid program:
//!
//! ```text
//! (volcomp-stamp compensated-by: volcomp 0.1.0)
//! (volcomp-stamp machine: ref-trt)
//! (volcomp-stamp model-fnv1a64: 0123456789abcdef)
//! (volcomp-stamp model-source: fit best)
//! (volcomp-stamp tool-length-mm: 150)
//! (volcomp-stamp tolerance-um: 0.5)
//! (volcomp-stamp input: saddle.nc)
//! (volcomp-stamp input-fnv1a64: 0123456789abcdef)
//! ```
//!
//! [`Stamp::find`] reads it back from the first lines of a program; the
//! interpreter sees only comments. [`StampWriter`] inserts it into a stream and
//! passes every other byte through unchanged.
use serde::Serialize;
use std::io::{self, Write};

/// What starts every stamp line.
pub const PREFIX: &str = "(volcomp-stamp ";

/// How many lines from the top [`Stamp::find`] looks at.
pub const SEARCH_LINES: usize = 64;

/// Who compensated a program, for which machine and model, from which input.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stamp {
    /// `volcomp X.Y.Z`.
    pub compensated_by: String,
    pub machine: String,
    /// FNV-1a 64 of the error-table files' bytes, in axis order (16 hex digits).
    pub model_fnv1a64: String,
    /// `fit METHOD` or `model FILE` (`--model`).
    pub model_source: String,
    pub tool_length_mm: f64,
    pub tolerance_um: f64,
    /// The input program's name (`<stdin>` for standard input).
    pub input: String,
    /// FNV-1a 64 of the input program's bytes (16 hex digits).
    pub input_fnv1a64: String,
    /// The tool axis was corrected too (`--orientation`): a ninth line
    /// `corrected: tip and tool axis`, written only then.
    pub orientation: bool,
}

/// Text fit for a comment: no parentheses, printable ASCII only.
fn clean(text: &str) -> String {
    text.chars()
        .map(|c| match c {
            '(' => '[',
            ')' => ']',
            ' '..='~' => c,
            _ => '_',
        })
        .collect()
}

impl Stamp {
    /// The stamp lines, each ended by `eol`.
    pub fn render(&self, eol: &str) -> String {
        let fields: [(&str, String); 8] = [
            ("compensated-by", clean(&self.compensated_by)),
            ("machine", clean(&self.machine)),
            ("model-fnv1a64", clean(&self.model_fnv1a64)),
            ("model-source", clean(&self.model_source)),
            ("tool-length-mm", format!("{}", self.tool_length_mm)),
            ("tolerance-um", format!("{}", self.tolerance_um)),
            ("input", clean(&self.input)),
            ("input-fnv1a64", clean(&self.input_fnv1a64)),
        ];
        let mut s = String::new();
        let corrected = self
            .orientation
            .then(|| ("corrected", "tip and tool axis".to_string()));
        for (key, value) in fields.into_iter().chain(corrected) {
            s.push_str(PREFIX);
            s.push_str(key);
            s.push_str(": ");
            s.push_str(&value);
            s.push(')');
            s.push_str(eol);
        }
        s
    }

    /// The stamp among the first [`SEARCH_LINES`] lines of `head` (the start of a
    /// program), if any: a run of stamp lines with a `compensated-by` field.
    /// Unknown keys are skipped; missing ones are empty (numbers NaN).
    pub fn find(head: &str) -> Option<Stamp> {
        let mut stamp: Option<Stamp> = None;
        for line in head.lines().take(SEARCH_LINES) {
            let line = line.trim();
            let Some(body) = line
                .strip_prefix(PREFIX)
                .and_then(|rest| rest.strip_suffix(')'))
            else {
                if stamp.is_some() {
                    break;
                }
                continue;
            };
            let Some((key, value)) = body.split_once(": ") else {
                continue;
            };
            if key.trim() == "compensated-by"
                && stamp.as_ref().is_some_and(|s| !s.compensated_by.is_empty())
            {
                // A program compensated twice (--force): the newest stamp only.
                break;
            }
            let s = stamp.get_or_insert_with(|| Stamp {
                compensated_by: String::new(),
                machine: String::new(),
                model_fnv1a64: String::new(),
                model_source: String::new(),
                tool_length_mm: f64::NAN,
                tolerance_um: f64::NAN,
                input: String::new(),
                input_fnv1a64: String::new(),
                orientation: false,
            });
            let value = value.trim().to_string();
            match key.trim() {
                "compensated-by" => s.compensated_by = value,
                "machine" => s.machine = value,
                "model-fnv1a64" => s.model_fnv1a64 = value,
                "model-source" => s.model_source = value,
                "tool-length-mm" => s.tool_length_mm = value.parse().unwrap_or(f64::NAN),
                "tolerance-um" => s.tolerance_um = value.parse().unwrap_or(f64::NAN),
                "input" => s.input = value,
                "input-fnv1a64" => s.input_fnv1a64 = value,
                "corrected" => s.orientation = value.contains("axis"),
                _ => {}
            }
        }
        stamp.filter(|s| !s.compensated_by.is_empty())
    }

    /// One line for people: who, for which machine, from which input.
    pub fn summary(&self) -> String {
        format!(
            "compensated by {} for machine {} (model {}, {}; tool length {} mm, tolerance {} µm{}) from {} (fnv1a64 {})",
            self.compensated_by,
            self.machine,
            self.model_fnv1a64,
            self.model_source,
            self.tool_length_mm,
            self.tolerance_um,
            if self.orientation {
                "; tool axis corrected too"
            } else {
                ""
            },
            self.input,
            self.input_fnv1a64
        )
    }
}

/// FNV-1a 64, fed in pieces (the same values as [`crate::nurbs::fnv1a64`]).
#[derive(Clone, Copy, Debug)]
pub struct Fnv1a64(u64);

impl Default for Fnv1a64 {
    fn default() -> Self {
        Fnv1a64(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a64 {
    pub fn update(&mut self, bytes: &[u8]) {
        let mut h = self.0;
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.0 = h;
    }
    pub fn finish(&self) -> u64 {
        self.0
    }
    /// 16 hex digits.
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// Is `line` (without its end) a leading `%` line?
fn is_percent_line(line: &[u8]) -> bool {
    line.trim_ascii().first() == Some(&b'%')
}

/// Is `line` an `O` program number (`O1234`, `O1234 (NAME)`), not an O-word
/// control statement (`o100 sub`, `o<name> call`)?
fn is_program_number(line: &[u8]) -> bool {
    let t = line.trim_ascii();
    if !matches!(t.first(), Some(b'O' | b'o')) {
        return false;
    }
    let digits = t[1..].iter().take_while(|b| b.is_ascii_digit()).count();
    if digits == 0 {
        return false;
    }
    let rest = t[1 + digits..].trim_ascii();
    rest.is_empty() || rest[0] == b'(' || rest[0] == b';'
}

/// A writer that inserts a stamp after the leading `%` line and `O` program
/// number line of what passes through it; every byte written comes out.
/// Call [`StampWriter::finish`] at the end (a program of header lines only).
pub struct StampWriter<'a> {
    inner: &'a mut dyn Write,
    stamp: Stamp,
    /// Bytes held until the insertion point is known.
    pending: Vec<u8>,
    /// Header lines passed so far (0: none, 1: `%` seen).
    seen_percent: bool,
    done: bool,
}

impl<'a> StampWriter<'a> {
    pub fn new(inner: &'a mut dyn Write, stamp: Stamp) -> Self {
        StampWriter {
            inner,
            stamp,
            pending: Vec::new(),
            seen_percent: false,
            done: false,
        }
    }

    /// Look at the complete lines held; write what is decided.
    fn advance(&mut self) -> io::Result<()> {
        while !self.done {
            let Some(end) = self.pending.iter().position(|&b| b == b'\n') else {
                return Ok(());
            };
            let line = &self.pending[..end];
            let eol = if line.last() == Some(&b'\r') {
                "\r\n"
            } else {
                "\n"
            };
            let content = line.strip_suffix(b"\r").unwrap_or(line);
            if !self.seen_percent && is_percent_line(content) {
                self.seen_percent = true;
                self.inner.write_all(&self.pending[..=end])?;
                self.pending.drain(..=end);
                continue;
            }
            if is_program_number(content) {
                self.inner.write_all(&self.pending[..=end])?;
                self.pending.drain(..=end);
                self.inner.write_all(self.stamp.render(eol).as_bytes())?;
            } else {
                self.inner.write_all(self.stamp.render(eol).as_bytes())?;
            }
            self.done = true;
            self.inner.write_all(&self.pending)?;
            self.pending = Vec::new();
        }
        Ok(())
    }

    /// Write what is still held (the stamp at the end of a header-only
    /// program) and flush.
    pub fn finish(&mut self) -> io::Result<()> {
        if !self.done {
            if !self.pending.is_empty() {
                // A last header line without a line end.
                let last = std::mem::take(&mut self.pending);
                self.inner.write_all(&last)?;
                self.inner.write_all(b"\n")?;
            }
            self.inner.write_all(self.stamp.render("\n").as_bytes())?;
            self.done = true;
        }
        self.inner.flush()
    }
}

impl Write for StampWriter<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if self.done {
            return self.inner.write(buf);
        }
        self.pending.extend_from_slice(buf);
        self.advance()?;
        Ok(buf.len())
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        if self.done {
            return self.inner.write_all(buf);
        }
        self.pending.extend_from_slice(buf);
        self.advance()
    }

    fn flush(&mut self) -> io::Result<()> {
        self.inner.flush()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn stamp() -> Stamp {
        Stamp {
            compensated_by: "volcomp 0.1.0".into(),
            machine: "ref (trt)".into(),
            model_fnv1a64: "0123456789abcdef".into(),
            model_source: "fit best".into(),
            tool_length_mm: 150.25,
            tolerance_um: 0.5,
            input: "part.nc".into(),
            input_fnv1a64: "fedcba9876543210".into(),
            orientation: false,
        }
    }

    fn stamped(text: &str) -> String {
        let mut out = Vec::new();
        let mut w = StampWriter::new(&mut out, stamp());
        // Byte by byte: the insertion must not depend on how writes are cut.
        for b in text.as_bytes() {
            w.write_all(&[*b]).unwrap();
        }
        w.finish().unwrap();
        String::from_utf8(out).unwrap()
    }

    #[test]
    fn goes_after_percent_and_program_number_and_keeps_the_rest() {
        let text = "%\nO2016 (SADDLE)\nG21 G90\nG1 X1 F100\nM30\n%\n";
        let out = stamped(text);
        let s = stamp().render("\n");
        assert_eq!(
            out,
            format!("%\nO2016 (SADDLE)\n{s}G21 G90\nG1 X1 F100\nM30\n%\n")
        );
        let back = Stamp::find(&out).unwrap();
        assert_eq!(back.machine, "ref [trt]");
        assert_eq!(back.tool_length_mm, 150.25);
        assert_eq!(back.tolerance_um, 0.5);
        assert_eq!(back.input_fnv1a64, "fedcba9876543210");
        assert!(!back.orientation);
    }

    #[test]
    fn an_orientation_run_says_so_and_reads_back() {
        let s = Stamp {
            orientation: true,
            ..stamp()
        };
        let text = s.render("\n");
        assert!(text.ends_with("(volcomp-stamp corrected: tip and tool axis)\n"));
        let back = Stamp::find(&text).unwrap();
        assert!(back.orientation);
        assert!(back.summary().contains("tool axis corrected too"));
    }

    #[test]
    fn goes_first_without_a_header_and_keeps_crlf() {
        let out = stamped("G21\r\nM2\r\n");
        assert!(out.starts_with("(volcomp-stamp compensated-by: volcomp 0.1.0)\r\n"));
        assert!(out.ends_with(")\r\nG21\r\nM2\r\n"));
        // An O-word statement is not a program number.
        let out = stamped("o100 sub\nM2\n");
        assert!(out.starts_with(PREFIX), "{out}");
        let out = stamped("O1234\nM30\n");
        assert!(out.starts_with("O1234\n(volcomp-stamp"), "{out}");
        assert!(stamped("").starts_with(PREFIX));
    }

    #[test]
    fn a_program_without_a_stamp_has_none() {
        assert_eq!(Stamp::find("%\nO1 (volcomp)\nG1 X1\n"), None);
        assert_eq!(Stamp::find("(volcomp-stamp machine: x)\n"), None);
    }

    #[test]
    fn incremental_hash_matches_the_one_shot_hash() {
        let mut h = Fnv1a64::default();
        h.update(b"ab");
        h.update(b"c");
        assert_eq!(h.finish(), crate::nurbs::fnv1a64(b"abc"));
    }
}
