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
//! (volcomp-stamp tools-mm: T1=150 T2=60)
//! (volcomp-stamp tolerance-um: 0.5)
//! (volcomp-stamp input: saddle.nc)
//! (volcomp-stamp input-fnv1a64: 0123456789abcdef)
//! ```
//!
//! [`Stamp::find`] reads it back from the head of a program, as a controller
//! or an editor may have left it: any case, N-numbered, as `;` comments, with
//! lines missing, after any number of other comment lines. [`is_stamp_line`]
//! recognises one line of it anywhere (`compensate` looks through the whole
//! program). The interpreter sees only comments. [`StampWriter`] inserts it
//! into a stream and passes every other byte through unchanged.
use serde::Serialize;
use std::io::{self, Write};

/// What starts every stamp line.
pub const PREFIX: &str = "(volcomp-stamp ";

/// The word that marks a stamp comment (compared without regard to case).
const MARK: &str = "volcomp-stamp";

/// Most tools the `tools-mm` line lists (then `… N in all`).
pub const LISTED_TOOLS: usize = 16;

/// Who compensated a program, for which machine and model, from which input.
/// Read back, a field the stamp lacks is empty (numbers `None`), and every
/// value is [`sanitise`]d.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Stamp {
    /// `volcomp X.Y.Z`.
    pub compensated_by: String,
    /// The machine file's `name`.
    pub machine: String,
    /// FNV-1a 64 of the error-table files' bytes, in axis order (16 hex digits).
    pub model_fnv1a64: String,
    /// `fit METHOD` or `model FILE` (`--model`).
    pub model_source: String,
    /// The default tool's length (the machine file's `[tool]`): the tool of
    /// the blocks before the first tool change.
    pub tool_length_mm: Option<f64>,
    /// The tool table the program was compensated with, as written
    /// (`T1=100 T2=60`; empty: none, every block used the default tool).
    pub tools_mm: String,
    /// The split tolerance of the compensation (`--tol`), µm: largest departure of a move from the compensated path.
    pub tolerance_um: Option<f64>,
    /// The input program's name (`<stdin>` for standard input).
    pub input: String,
    /// FNV-1a 64 of the input program's bytes (16 hex digits).
    pub input_fnv1a64: String,
    /// The tool axis was corrected too (`--orientation`): a line
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

/// A value read from a program, safe to print on a terminal: control
/// characters (an escape sequence's ESC, a carriage return) and the
/// invisible format characters are written as escapes (`\u{1b}`).
pub fn sanitise(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        let invisible = matches!(c, '\u{200b}'..='\u{200f}' | '\u{202a}'..='\u{202e}' | '\u{2066}'..='\u{2069}' | '\u{feff}');
        if c.is_control() || invisible {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    out
}

/// The `KEY: VALUE` text of a stamp line, if `line` is one: a comment
/// (`( … )`, or `;` to the end of the line) whose text starts with
/// `volcomp-stamp`, in any case, possibly after a block delete `/` and an
/// `N` number.
fn stamp_body(line: &str) -> Option<&str> {
    let mut t = line.trim_start_matches('\u{feff}').trim();
    if let Some(rest) = t.strip_prefix('/') {
        t = rest.trim_start();
    }
    // A Klartext block number (`3 ; volcomp-stamp …`).
    let bare = t.len() - t.trim_start_matches(|c: char| c.is_ascii_digit()).len();
    if bare > 0 && t[bare..].trim_start().starts_with(';') {
        t = t[bare..].trim_start();
    }
    if let Some(rest) = t.strip_prefix(['N', 'n']) {
        let digits = rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
        if digits > 0 {
            t = rest[digits..].trim_start();
        }
    }
    let comment = if let Some(rest) = t.strip_prefix('(') {
        rest.strip_suffix(')').unwrap_or(rest)
    } else if let Some(rest) = t.strip_prefix(';') {
        let rest = rest.trim_start();
        match rest.strip_prefix('(') {
            Some(inner) => inner.strip_suffix(')').unwrap_or(inner),
            None => rest,
        }
    } else {
        return None;
    };
    let comment = comment.trim_start();
    let head = comment.get(..MARK.len())?;
    if !head.eq_ignore_ascii_case(MARK) {
        return None;
    }
    let rest = &comment[MARK.len()..];
    (rest.is_empty() || rest.starts_with(char::is_whitespace)).then(|| rest.trim())
}

/// Is `line` (one line of a program, without its end) a line of a stamp?
/// Bytes that are not UTF-8 are read as U+FFFD.
pub fn is_stamp_line(line: &[u8]) -> bool {
    stamp_body(&String::from_utf8_lossy(line)).is_some()
}

/// Looks for stamp lines in a program fed in pieces (`compensate` feeds it
/// every byte it hashes): [`StampScan::finish`] returns the first line that holds one.
#[derive(Debug, Default)]
pub struct StampScan {
    partial: Vec<u8>,
    line: usize,
    found: Option<usize>,
}

impl StampScan {
    /// Feeds the next bytes of the program.
    pub fn update(&mut self, mut bytes: &[u8]) {
        while let Some(end) = memchr::memchr(b'\n', bytes) {
            self.line += 1;
            if self.found.is_none() {
                let line = if self.partial.is_empty() {
                    &bytes[..end]
                } else {
                    self.partial.extend_from_slice(&bytes[..end]);
                    &self.partial[..]
                };
                if Self::may_hold(line) && is_stamp_line(line) {
                    self.found = Some(self.line);
                }
            }
            self.partial.clear();
            bytes = &bytes[end + 1..];
        }
        // Only a bounded start of a long line is kept: a stamp line is short.
        let room = 4096usize.saturating_sub(self.partial.len());
        self.partial
            .extend_from_slice(&bytes[..bytes.len().min(room)]);
    }

    /// The line (1-based) of the first stamp line, once the input has ended.
    pub fn finish(&mut self) -> Option<usize> {
        if !self.partial.is_empty() {
            self.line += 1;
            if self.found.is_none() && is_stamp_line(&self.partial) {
                self.found = Some(self.line);
            }
            self.partial.clear();
        }
        self.found
    }

    /// A quick test before the full one: the line mentions `stamp` in any case
    /// (only where an `s` starts it: most lines of a program have none).
    fn may_hold(line: &[u8]) -> bool {
        memchr::memchr2_iter(b's', b'S', line).any(|i| {
            line.get(i..i + 5)
                .is_some_and(|w| w.eq_ignore_ascii_case(b"stamp"))
        })
    }
}

impl Stamp {
    /// The stamp lines, each ended by `eol`.
    pub fn render(&self, eol: &str) -> String {
        let number = |v: Option<f64>| v.map_or(String::new(), |v| format!("{v}"));
        let mut fields: Vec<(&str, String)> = vec![
            ("compensated-by", clean(&self.compensated_by)),
            ("machine", clean(&self.machine)),
            ("model-fnv1a64", clean(&self.model_fnv1a64)),
            ("model-source", clean(&self.model_source)),
            ("tool-length-mm", number(self.tool_length_mm)),
        ];
        if !self.tools_mm.is_empty() {
            fields.push(("tools-mm", clean(&self.tools_mm)));
        }
        fields.extend([
            ("tolerance-um", number(self.tolerance_um)),
            ("input", clean(&self.input)),
            ("input-fnv1a64", clean(&self.input_fnv1a64)),
        ]);
        if self.orientation {
            fields.push(("corrected", "tip and tool axis".to_string()));
        }
        let mut s = String::new();
        for (key, value) in fields {
            s.push_str(PREFIX);
            s.push_str(key);
            s.push_str(": ");
            s.push_str(&value);
            s.push(')');
            s.push_str(eol);
        }
        s
    }

    /// The `tools-mm` value for a tool table: `T1=100 T2=60`, the first
    /// [`LISTED_TOOLS`] tools, then how many there are in all.
    pub fn tools_text(tools: &[(u32, f64)]) -> String {
        let mut parts: Vec<String> = tools
            .iter()
            .take(LISTED_TOOLS)
            .map(|(n, l)| format!("T{n}={l}"))
            .collect();
        if tools.len() > LISTED_TOOLS {
            parts.push(format!("... {} in all", tools.len()));
        }
        parts.join(" ")
    }

    /// The stamp in `head` (the start of a program), if any: the first run of
    /// stamp lines (a program compensated twice carries two runs; the first
    /// is the newest). Every line of `head` is looked at. Keys are read in any
    /// case, unknown keys are skipped, missing ones stay empty; a run without
    /// its `compensated-by` line is still a stamp.
    pub fn find(head: &str) -> Option<Stamp> {
        let mut stamp: Option<Stamp> = None;
        for line in head.lines() {
            let Some(body) = stamp_body(line) else {
                if stamp.is_some() {
                    break;
                }
                continue;
            };
            let (key, value) = body.split_once(':').unwrap_or((body, ""));
            let key = key.trim().to_ascii_lowercase();
            let value = sanitise(value.trim());
            if key == "compensated-by"
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
                tool_length_mm: None,
                tools_mm: String::new(),
                tolerance_um: None,
                input: String::new(),
                input_fnv1a64: String::new(),
                orientation: false,
            });
            let number = |v: &str| v.parse::<f64>().ok().filter(|x| x.is_finite());
            match key.as_str() {
                "compensated-by" => s.compensated_by = value,
                "machine" => s.machine = value,
                "model-fnv1a64" => s.model_fnv1a64 = value,
                "model-source" => s.model_source = value,
                "tool-length-mm" => s.tool_length_mm = number(&value),
                "tools-mm" => s.tools_mm = value,
                "tolerance-um" => s.tolerance_um = number(&value),
                "input" => s.input = value,
                "input-fnv1a64" => s.input_fnv1a64 = value,
                "corrected" => s.orientation = value.to_ascii_lowercase().contains("axis"),
                _ => {}
            }
        }
        stamp
    }

    /// One line for people: who, for which machine, from which input. Fields
    /// the stamp lacks read `unknown`.
    pub fn summary(&self) -> String {
        let text = |v: &str| {
            if v.is_empty() {
                "unknown".to_string()
            } else {
                v.to_string()
            }
        };
        let number = |v: Option<f64>| v.map_or("unknown".to_string(), |v| v.to_string());
        format!(
            "compensated by {} for machine {} (model {}, {}; tool length {}{}, tolerance {}{}) from {} (fnv1a64 {})",
            if self.compensated_by.is_empty() {
                "an unknown version".to_string()
            } else {
                self.compensated_by.clone()
            },
            text(&self.machine),
            text(&self.model_fnv1a64),
            text(&self.model_source),
            match self.tool_length_mm {
                Some(l) => format!("{l} mm"),
                None => "unknown".into(),
            },
            if self.tools_mm.is_empty() {
                String::new()
            } else {
                format!(", tools {} mm", self.tools_mm)
            },
            match self.tolerance_um {
                Some(_) => format!("{} µm", number(self.tolerance_um)),
                None => "unknown".into(),
            },
            if self.orientation {
                "; tool axis corrected too"
            } else {
                ""
            },
            text(&self.input),
            text(&self.input_fnv1a64)
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
    /// Feeds the next bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        let mut h = self.0;
        for &b in bytes {
            h ^= b as u64;
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self.0 = h;
    }
    /// The hash of the bytes fed so far.
    pub fn finish(&self) -> u64 {
        self.0
    }
    /// 16 hex digits.
    pub fn hex(&self) -> String {
        format!("{:016x}", self.0)
    }
}

/// `line` without a UTF-8 byte order mark at its start.
fn without_bom(line: &[u8]) -> &[u8] {
    line.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(line)
}

/// Is `line` (without its end) a leading `%` line?
fn is_percent_line(line: &[u8]) -> bool {
    without_bom(line).trim_ascii().first() == Some(&b'%')
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

/// A writer that inserts a stamp after the leading blank lines, `%` line and
/// `O` program number line of what passes through it (LinuxCNC allows only
/// blank lines before the `%`); every byte written comes out.
/// Call [`StampWriter::finish`] at the end (a program of header lines only).
pub struct StampWriter<'a> {
    inner: &'a mut dyn Write,
    stamp: Stamp,
    /// Bytes held until the insertion point is known.
    pending: Vec<u8>,
    /// Header lines passed so far (0: none, 1: `%` seen).
    seen_percent: bool,
    done: bool,
    /// The comment style of the program's dialect (`;` lines for Sinumerik
    /// and Heidenhain).
    dialect: crate::gcode::Dialect,
    /// Heidenhain: the stamp as `;` blocks after `BEGIN PGM`, the blocks
    /// renumbered (everything passes through it).
    klartext: Option<crate::gcode::KlartextStamp>,
}

impl<'a> StampWriter<'a> {
    /// A writer passing everything to `inner`, with `stamp` inserted after the program's header lines.
    pub fn new(inner: &'a mut dyn Write, stamp: Stamp) -> Self {
        StampWriter {
            inner,
            stamp,
            pending: Vec::new(),
            seen_percent: false,
            done: false,
            dialect: crate::gcode::Dialect::LinuxCnc,
            klartext: None,
        }
    }

    /// Write the stamp as comments of `dialect` (`; volcomp-stamp …` lines
    /// for Sinumerik and Heidenhain, whose controls read no `( … )`). A
    /// Heidenhain program gets them as `N ; …` blocks after `BEGIN PGM`, the
    /// blocks after them renumbered (docs/dialects.md).
    pub fn with_dialect(mut self, dialect: crate::gcode::Dialect) -> Self {
        self.dialect = dialect;
        if dialect == crate::gcode::Dialect::Heidenhain {
            self.klartext = Some(crate::gcode::KlartextStamp::new(&self.stamp.render("\n")));
        }
        self
    }

    fn render(&self, eol: &str) -> String {
        let text = self.stamp.render(eol);
        match self.dialect {
            crate::gcode::Dialect::LinuxCnc => text,
            d => text
                .split_inclusive(eol)
                .map(|line| {
                    let body = line.trim_end_matches(eol);
                    let body = body.strip_prefix('(').unwrap_or(body);
                    let body = body.strip_suffix(')').unwrap_or(body);
                    d.comment(body) + eol
                })
                .collect(),
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
            if !self.seen_percent && without_bom(content).trim_ascii().is_empty() {
                // A blank line before the `%` (or before the first block).
                self.inner.write_all(&self.pending[..=end])?;
                self.pending.drain(..=end);
                continue;
            }
            if !self.seen_percent && is_percent_line(content) {
                self.seen_percent = true;
                self.inner.write_all(&self.pending[..=end])?;
                self.pending.drain(..=end);
                continue;
            }
            // Sinumerik's archive header: `%_N_PART_MPF`, then `;$PATH=/_N_MPF_DIR`.
            let path_line = self.seen_percent
                && self.dialect == crate::gcode::Dialect::Sinumerik
                && content.trim_ascii_start().starts_with(b";$PATH");
            if is_program_number(content) || path_line {
                self.inner.write_all(&self.pending[..=end])?;
                self.pending.drain(..=end);
                self.inner.write_all(self.render(eol).as_bytes())?;
            } else {
                self.inner.write_all(self.render(eol).as_bytes())?;
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
        if let Some(k) = &mut self.klartext {
            return k.finish(self.inner);
        }
        if !self.done {
            if !self.pending.is_empty() {
                // A last header line without a line end.
                let last = std::mem::take(&mut self.pending);
                self.inner.write_all(&last)?;
                self.inner.write_all(b"\n")?;
            }
            self.inner.write_all(self.render("\n").as_bytes())?;
            self.done = true;
        }
        self.inner.flush()
    }
}

impl Write for StampWriter<'_> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if let Some(k) = &mut self.klartext {
            k.write(self.inner, buf)?;
            return Ok(buf.len());
        }
        if self.done {
            return self.inner.write(buf);
        }
        self.pending.extend_from_slice(buf);
        self.advance()?;
        Ok(buf.len())
    }

    fn write_all(&mut self, buf: &[u8]) -> io::Result<()> {
        if let Some(k) = &mut self.klartext {
            return k.write(self.inner, buf);
        }
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
            tool_length_mm: Some(150.25),
            tools_mm: String::new(),
            tolerance_um: Some(0.5),
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
        assert_eq!(back.tool_length_mm, Some(150.25));
        assert_eq!(back.tolerance_um, Some(0.5));
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
        assert_eq!(Stamp::find("(volcomp-stamped machine: x)\n"), None);
        assert_eq!(
            Stamp::find("(volcomp stamp: x)\nG1 X1 (volcomp-stamp\n"),
            None
        );
        assert!(!is_stamp_line(b"G1 X1 ; a volcomp-stamp comment"));
    }

    /// Issue 23: a stamp as a controller or an editor may leave it is still
    /// found, so the program is not compensated twice.
    #[test]
    fn a_changed_stamp_is_still_found() {
        let text = stamp().render("\n");
        let upper = text.to_ascii_uppercase();
        let s = Stamp::find(&upper).expect("uppercased");
        assert_eq!(s.machine, "REF [TRT]");
        assert_eq!(s.tool_length_mm, Some(150.25));
        let numbered: String = text
            .lines()
            .enumerate()
            .map(|(i, l)| format!("N{} {l}\n", 10 * (i + 1)))
            .collect();
        assert_eq!(Stamp::find(&numbered).unwrap().machine, "ref [trt]");
        let semicolons: String = text
            .lines()
            .map(|l| format!("; {}\n", &l[1..l.len() - 1]))
            .collect();
        assert_eq!(Stamp::find(&semicolons).unwrap().input, "part.nc");
        let late = "(header)\n".repeat(200) + &text;
        assert!(Stamp::find(&late).is_some());
        // Without its compensated-by line.
        let partial: String = text.lines().skip(1).map(|l| format!("{l}\n")).collect();
        let s = Stamp::find(&partial).expect("a partial stamp");
        assert_eq!(s.compensated_by, "");
        assert!(s.summary().starts_with("compensated by an unknown version"));
        // Only a machine line: nothing reads NaN.
        let s = Stamp::find("(volcomp-stamp machine: m)\n").unwrap();
        let summary = s.summary();
        assert!(!summary.contains("NaN"), "{summary}");
        assert!(summary.contains("tool length unknown"), "{summary}");
    }

    #[test]
    fn values_reach_the_terminal_escaped() {
        let s = Stamp::find("(volcomp-stamp machine: a\u{1b}[2Jb\u{7}\u{202e}c)\n").unwrap();
        assert_eq!(s.machine, "a\\u{1b}[2Jb\\u{7}\\u{202e}c");
        assert!(!s.summary().chars().any(char::is_control));
    }

    #[test]
    fn the_stamp_goes_after_blank_lines_and_a_bom_before_the_percent() {
        let s = stamp().render("\n");
        assert_eq!(
            stamped("\n\n%\nG1 X1\n%\n"),
            format!("\n\n%\n{s}G1 X1\n%\n")
        );
        assert_eq!(
            stamped("\u{feff}%\nO1\nM2\n%\n"),
            format!("\u{feff}%\nO1\n{s}M2\n%\n")
        );
        assert_eq!(
            stamped("  \r\n%\r\nM2\r\n"),
            format!("  \r\n%\r\n{}M2\r\n", stamp().render("\r\n"))
        );
    }

    #[test]
    fn a_scan_finds_a_stamp_line_anywhere() {
        let mut scan = StampScan::default();
        let text = format!(
            "G21\n{}G1 X1\nN5 ;VOLCOMP-STAMP MACHINE: X\n",
            "G1 X2\n".repeat(100)
        );
        for piece in text.as_bytes().chunks(7) {
            scan.update(piece);
        }
        assert_eq!(scan.finish(), Some(103));
        let mut scan = StampScan::default();
        scan.update(b"G1 X1\n(volcomp-stamp input: a)");
        assert_eq!(scan.finish(), Some(2));
        let mut scan = StampScan::default();
        scan.update(b"G1 X1\n(stamp)\n");
        assert_eq!(scan.finish(), None);
    }

    #[test]
    fn incremental_hash_matches_the_one_shot_hash() {
        let mut h = Fnv1a64::default();
        h.update(b"ab");
        h.update(b"c");
        assert_eq!(h.finish(), crate::nurbs::fnv1a64(b"abc"));
    }
}
