//! Reading laser-interferometer positioning runs as laser software exports them
//! (formats.md "Laser positioning runs and reversal"; the accepted layouts and
//! the fixture of each are listed in docs/extensions.md).
//!
//! Three layouts, told apart by the header:
//! - **long**: `target,run,direction,deviation` (the contract), one reading a row;
//! - **paired**: `target,run,+,-` (also `up,down`, `fwd,rev`, `forward,reverse`),
//!   one target and run a row, both approaches;
//! - **wide**: `target,run 1 +,run 1 -,run 2 +,…` (the spreadsheet export of
//!   laser software), one target a row, a column per run and direction.
//!
//! Column names and directions in English or German (`vocabulary`). The header
//! is the first line naming a target column and a reading column; the lines
//! before it are the export's metadata (its *preamble*, kept). Columns that are
//! not readings (air and material temperature, comments, the actual position)
//! are kept by name with the range of their numbers. Units come in the header
//! cell (`target [mm]`, `deviation (µm)`) or in a units line right under the
//! header (`mm;;;µm`). Separators `,` `;` or tab: the one that splits the header
//! into a layout (two that both do are an error); the decimal mark is decided
//! by the file's first number that writes one, and a later number writing the
//! other is an error. Text is UTF-8, or Latin-1 where a line is not UTF-8 (as
//! Windows laser software writes `µm` and `rückwärts`). Rows may come in any
//! order (runs measured from the far end, descending targets).
//!
//! Invariants: every value of a [`FileReadings`] is finite, in volcomp's units
//! (targets mm or degrees, deviations µm or µrad) and within the physical ranges
//! ([`MAX_DEVIATION`], [`MAX_TARGET_MM`], [`MAX_TARGET_DEG`]); every error names
//! the file, the line and the column (1-based characters) of the cell, and echoes
//! at most 160 bytes (`EXCERPT_BYTES`) of it; a line is read with at most
//! 64 KiB (`MAX_LINE_BYTES`) of it in memory.
use std::borrow::Cow;
use std::io::BufRead;
use std::path::{Path, PathBuf};

pub use super::vocabulary::parse_direction;
use super::vocabulary::{
    Role, classify, deviation_unit, is_known_unit, is_parameter_name, is_run_without_direction,
    split_unit, strip_brackets, target_unit,
};
use crate::axes::Axis;
use crate::gcode::error::EXCERPT_BYTES;
use crate::gcode::syntax::reader::MAX_LINE_BYTES;

/// The largest |deviation| read: µm of a length parameter (100 mm), µrad of
/// an angle (0.1 rad). A positioning error beyond it is no machine tool's.
pub const MAX_DEVIATION: f64 = 100_000.0;
/// The largest |target| of a linear axis, mm (100 m).
pub const MAX_TARGET_MM: f64 = 100_000.0;
/// The largest |target| of a rotary axis, degrees (100 turns).
pub const MAX_TARGET_DEG: f64 = 36_000.0;
/// The most metadata lines before the header.
pub const MAX_PREAMBLE_LINES: usize = 200;

/// A malformed laser file.
#[derive(Debug, thiserror::Error)]
pub enum LaserError {
    /// The file could not be read.
    #[error(transparent)]
    Read(#[from] crate::io::InputError),
    /// A cell, a header or a row that cannot be read: file:line:column.
    #[error("{}:{line}:{column}: {message}", path.display())]
    Invalid {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column (characters) of the cell.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// Inconsistent data across rows or files (no location of its own).
    #[error("{0}")]
    Data(String),
}

/// The layout of a file's header (module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Layout {
    /// `target,run,direction,deviation`: one reading a row.
    Long,
    /// `target,run,+,-`: one target and run a row, both approaches.
    Paired,
    /// `target,run 1 +,run 1 -,…`: one target a row, a column per run and direction.
    Wide,
}

impl Layout {
    /// The name reports write (`"long"`, `"paired"`, `"wide"`).
    pub fn name(self) -> &'static str {
        match self {
            Layout::Long => "long",
            Layout::Paired => "paired",
            Layout::Wide => "wide",
        }
    }
}

/// The decimal mark a file writes, decided by its first number that writes one.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum DecimalMark {
    /// No number of the file has a fraction.
    None,
    /// `1.25`.
    Point,
    /// `1,25`.
    Comma,
}

impl DecimalMark {
    /// `"decimal point"`, `"decimal comma"`, `"no decimal mark"`.
    pub fn describe(self) -> &'static str {
        match self {
            DecimalMark::None => "no decimal mark",
            DecimalMark::Point => "decimal point",
            DecimalMark::Comma => "decimal comma",
        }
    }

    fn of(text: &str) -> DecimalMark {
        if text.contains(',') {
            DecimalMark::Comma
        } else if text.contains('.') {
            DecimalMark::Point
        } else {
            DecimalMark::None
        }
    }
}

/// One deviation: the axis at `target`, approached moving `up` (positive
/// direction) or down, in run `run`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reading {
    /// mm (linear axis) or degrees (rotary).
    pub target: f64,
    /// The run number.
    pub run: u32,
    /// Whether the target was approached in the positive direction.
    pub up: bool,
    /// Actual − target: µm (a length parameter) or µrad (an angle).
    pub deviation: f64,
    /// Where it was read (1-based).
    pub line: u32,
    /// 1-based column (characters) of the deviation.
    pub column: u32,
}

/// A column that holds no reading (air temperature, a comment): its name and
/// what it held.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct OtherColumn {
    /// The header cell as written (cut to 160 bytes (`EXCERPT_BYTES`)).
    pub name: String,
    /// Its unit (header or units line; empty: none given).
    pub unit: String,
    /// 1-based column (characters) of the header cell.
    pub column: usize,
    /// Cells that were not empty.
    pub cells: usize,
    /// The smallest and largest number of its cells (`None`: no cell is a number).
    pub range: Option<[f64; 2]>,
}

/// Which bytes a file was: for telling that one measurement was given twice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FileIdentity {
    /// Device and inode (`None` where the platform has none, or for text given in memory).
    pub device_inode: Option<(u64, u64)>,
    /// Bytes read.
    pub length: u64,
    /// FNV-1a 64 of the bytes read.
    pub fnv1a64: u64,
}

/// The readings of one file, in volcomp's units.
#[derive(Clone, Debug)]
pub struct FileReadings {
    /// The file.
    pub path: PathBuf,
    /// The error parameter the deviations measure (`EXX`, `EYX`, `EAA`…).
    pub parameter: String,
    /// Its header layout.
    pub layout: Layout,
    /// Line of the header.
    pub header_line: usize,
    /// Its field separator (`,`, `;` or tab).
    pub separator: char,
    /// The decimal mark it writes.
    pub decimal_mark: DecimalMark,
    /// `UTF-8`, or `Latin-1` when a line was not UTF-8.
    pub encoding: &'static str,
    /// The units the file gave (empty: volcomp's default).
    pub target_unit: String,
    /// The unit of its deviations as the file gave it (empty: volcomp's default).
    pub deviation_unit: String,
    /// The line of a units line under the header, if it had one.
    pub units_line: Option<usize>,
    /// The metadata lines before the header (blank lines left out; each cut to
    /// 160 bytes (`EXCERPT_BYTES`)).
    pub preamble: Vec<String>,
    /// The columns that hold no reading, in header order.
    pub other_columns: Vec<OtherColumn>,
    /// The readings, in file order.
    pub readings: Vec<Reading>,
    /// Which bytes it was.
    pub identity: FileIdentity,
}

/// What a file is read as.
#[derive(Clone, Debug)]
pub struct ReadSettings {
    /// The axis measured.
    pub axis: Axis,
    /// The parameter its deviations measure when the header does not name one
    /// (`None`: the axis's positioning parameter).
    pub parameter: Option<String>,
}

/// The positioning parameter of an axis: `EXX` for X, `EAA` for A.
pub fn positioning_parameter(axis: Axis) -> String {
    let d = match axis {
        Axis::U => 'X',
        Axis::V => 'Y',
        Axis::W => 'Z',
        other => other.letter(),
    };
    format!("E{d}{}", axis.letter())
}

/// Is `name` an error parameter of `axis` (`E` + direction + the axis letter)?
pub fn is_parameter_of(name: &str, axis: Axis) -> bool {
    let b = name.as_bytes();
    b.len() == 3
        && b[0] == b'E'
        && crate::machine::table::DIRECTIONS.contains(&(b[1] as char))
        && b[2] as char == axis.letter()
}

/// Is the parameter an angle (µrad) rather than a length (µm)?
pub fn is_angular(parameter: &str) -> bool {
    matches!(parameter.as_bytes().get(1), Some(b'A' | b'B' | b'C'))
}

/// At most 160 bytes (`EXCERPT_BYTES`) of `text` (cut at a character), for messages.
pub(crate) fn excerpt(text: &str) -> Cow<'_, str> {
    if text.len() <= EXCERPT_BYTES {
        return Cow::Borrowed(text);
    }
    let mut end = EXCERPT_BYTES;
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    Cow::Owned(format!("{}… ({} bytes)", &text[..end], text.len()))
}

/// A header cell: its role, its name and unit (as written) and its 1-based
/// column; `unit_at` is where the unit was given (line, column).
#[derive(Clone, Debug)]
struct HeaderCell {
    role: Role,
    name: String,
    unit: String,
    column: usize,
    unit_at: (usize, usize),
}

/// The fields of a line: (start byte, text), unquoted and trimmed.
fn split_fields<'a>(line: &'a str, sep: char, out: &mut Vec<(usize, Cow<'a, str>)>) {
    out.clear();
    if !line.contains('"') {
        let mut start = 0;
        for field in line.split(sep) {
            let lead = field.len() - field.trim_start().len();
            out.push((start + lead, Cow::Borrowed(field.trim())));
            start += field.len() + sep.len_utf8();
        }
        return;
    }
    // Quoted fields ("1,5"; "" is a quote).
    let mut field = String::new();
    let mut start = 0;
    let mut in_quotes = false;
    let mut chars = line.char_indices().peekable();
    while let Some((i, c)) = chars.next() {
        if in_quotes {
            if c == '"' {
                if chars.peek().is_some_and(|(_, n)| *n == '"') {
                    field.push('"');
                    chars.next();
                } else {
                    in_quotes = false;
                }
            } else {
                field.push(c);
            }
        } else if c == '"' {
            in_quotes = true;
        } else if c == sep {
            out.push((start, Cow::Owned(field.trim().to_string())));
            field.clear();
            start = i + sep.len_utf8();
        } else {
            if field.is_empty() && c == ' ' {
                start = i + 1;
                continue;
            }
            field.push(c);
        }
    }
    out.push((start, Cow::Owned(field.trim().to_string())));
}

/// The 1-based character column of byte `at` of `line`.
fn char_column(line: &str, at: usize) -> usize {
    line.get(..at.min(line.len())).map_or(at, |s| {
        if s.is_ascii() {
            s.len()
        } else {
            s.chars().count()
        }
    }) + 1
}

/// A number with at most one decimal mark (`.` or `,`), finite.
fn parse_number(text: &str) -> Option<f64> {
    let t = text.strip_prefix('+').unwrap_or(text);
    let v = if t.contains(',') {
        if t.contains('.') || t.matches(',').count() > 1 {
            return None;
        }
        t.replace(',', ".").parse::<f64>().ok()?
    } else {
        t.parse::<f64>().ok()?
    };
    v.is_finite().then_some(v)
}

/// `v` (written as `text`) times `factor`, rounded to the decimals the
/// product has exactly: inch targets with d decimals times 25.4 have d + 1
/// (`5.9055118` in → 149.99999972 mm, not 149.99999971999999).
fn converted(v: f64, factor: f64, text: &str) -> f64 {
    if factor == 1.0 || text.contains(['e', 'E']) {
        return v * factor;
    }
    let decimals = text.find(['.', ',']).map_or(0, |k| text.len() - k - 1) as i32;
    let factor_decimals = (0..6)
        .find(|&d| {
            let scaled = factor * 10f64.powi(d);
            (scaled - scaled.round()).abs() < 1e-9
        })
        .unwrap_or(6);
    let places = 10f64.powi((decimals + factor_decimals).min(15));
    let product = v * factor;
    let rounded = (product * places).round() / places;
    if rounded.is_finite() {
        rounded
    } else {
        product
    }
}

/// Read one laser file (`settings` say which axis and parameter). Only a
/// regular file is read (a FIFO or a device is refused before reading).
pub fn read_file(path: &Path, settings: &ReadSettings) -> Result<FileReadings, LaserError> {
    let input_error = |source| crate::io::InputError {
        path: path.to_path_buf(),
        source,
    };
    let file = std::fs::File::open(path).map_err(input_error)?;
    let meta = file.metadata().map_err(input_error)?;
    if !meta.is_file() {
        return Err(input_error(std::io::Error::new(
            std::io::ErrorKind::InvalidInput,
            "not a regular file (a laser export is a file)",
        ))
        .into());
    }
    let mut readings = parse_from(&mut std::io::BufReader::new(file), path, settings)?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        readings.identity.device_inode = Some((meta.dev(), meta.ino()));
    }
    Ok(readings)
}

/// Parse `text` as the laser file `path` (named in errors).
pub fn parse(text: &str, path: &Path, settings: &ReadSettings) -> Result<FileReadings, LaserError> {
    parse_from(&mut text.as_bytes(), path, settings)
}

/// The lines of a file, read bounded and decoded, its bytes hashed.
struct Lines<'i, R: BufRead + ?Sized> {
    input: &'i mut R,
    at: &'i Locator<'i>,
    buf: Vec<u8>,
    number: usize,
    hash: crate::stamp::Fnv1a64,
    length: u64,
    latin1: bool,
}

impl<R: BufRead + ?Sized> Lines<'_, R> {
    /// The next line (number, text without its line end), `None` at the end.
    fn next_line(&mut self) -> Result<Option<(usize, String)>, LaserError> {
        self.buf.clear();
        let (consumed, too_long) =
            crate::gcode::syntax::reader::read_line_bounded(self.input, &mut self.buf).map_err(
                |source| crate::io::InputError {
                    path: self.at.path.to_path_buf(),
                    source,
                },
            )?;
        if consumed == 0 {
            return Ok(None);
        }
        self.number += 1;
        self.length += consumed as u64;
        self.hash.update(&self.buf);
        if let Some(length) = too_long {
            return Err(self.at.invalid(
                self.number,
                MAX_LINE_BYTES + 1,
                format!(
                    "line of {length} bytes: volcomp reads laser lines of at most {MAX_LINE_BYTES} bytes \
(a laser export has a row per target or reading)"
                ),
            ));
        }
        let mut bytes: &[u8] = &self.buf;
        bytes = bytes.strip_suffix(b"\n").unwrap_or(bytes);
        bytes = bytes.strip_suffix(b"\r").unwrap_or(bytes);
        if self.number == 1 {
            if bytes.starts_with(&[0xFF, 0xFE]) || bytes.starts_with(&[0xFE, 0xFF]) {
                return Err(self.at.invalid(
                    1,
                    1,
                    "UTF-16 text: save the export as UTF-8 (or ANSI) text".into(),
                ));
            }
            bytes = bytes.strip_prefix(&[0xEF, 0xBB, 0xBF]).unwrap_or(bytes);
        }
        if let Some(k) = bytes
            .iter()
            .position(|&b| (b < 0x20 && b != b'\t' && b != b'\r') || b == 0x7F)
        {
            return Err(self.at.invalid(
                self.number,
                k + 1,
                format!(
                    "byte 0x{:02x} is not text: a laser export is text (UTF-8 or Latin-1)",
                    bytes[k]
                ),
            ));
        }
        let text = match std::str::from_utf8(bytes) {
            Ok(t) => t.to_string(),
            Err(_) => {
                self.latin1 = true;
                bytes.iter().map(|&b| char::from(b)).collect()
            }
        };
        Ok(Some((self.number, text)))
    }

    /// The next line that is not blank and not a `#` comment; the comments
    /// and blank lines passed over are handed to `skipped`.
    fn next_content(
        &mut self,
        skipped: &mut dyn FnMut(&str),
    ) -> Result<Option<(usize, String)>, LaserError> {
        while let Some((n, line)) = self.next_line()? {
            let t = line.trim();
            if t.is_empty() || t.starts_with('#') {
                skipped(t);
                continue;
            }
            return Ok(Some((n, line)));
        }
        Ok(None)
    }
}

/// Does a line before any header look like a data row (two numbers first)?
fn looks_like_data(line: &str) -> bool {
    let sep = ['\t', ';', ','].into_iter().find(|s| line.contains(*s));
    let Some(sep) = sep else {
        return false;
    };
    let mut fields = Vec::new();
    split_fields(line, sep, &mut fields);
    fields.len() >= 2
        && parse_number(&fields[0].1).is_some()
        && parse_number(&fields[1].1).is_some()
}

fn parse_from<R: BufRead + ?Sized>(
    input: &mut R,
    path: &Path,
    settings: &ReadSettings,
) -> Result<FileReadings, LaserError> {
    let at = Locator { path };
    let mut lines = Lines {
        input,
        at: &at,
        buf: Vec::new(),
        number: 0,
        hash: crate::stamp::Fnv1a64::default(),
        length: 0,
        latin1: false,
    };
    let mut preamble: Vec<String> = Vec::new();
    let mut header = loop {
        let mut comments = Vec::new();
        let next = lines.next_content(&mut |t| {
            if !t.is_empty() {
                comments.push(excerpt(t).into_owned());
            }
        })?;
        preamble.extend(comments);
        let Some((n, line)) = next else {
            return Err(match preamble.last() {
                None => at.invalid(
                    1,
                    1,
                    "empty file: expected a header such as `target,run,direction,deviation`".into(),
                ),
                Some(_) => at.invalid(
                    1,
                    1,
                    format!(
                        "no header: none of the {} lines names a target column (target, position, \
Sollposition) and the readings (run, direction, deviation; or run columns like `Run 1 +`)",
                        lines.number
                    ),
                ),
            });
        };
        if let Some(h) = Header::detect(&line, n, &at)? {
            break h;
        }
        if looks_like_data(&line) {
            return Err(at.invalid(
                n,
                1,
                format!(
                    "a data row before any header (`{}`): expected a header naming the target column \
(target, position, Sollposition) and the readings (run, direction, deviation; or run columns like `Run 1 +`){}",
                    excerpt(line.trim()),
                    match preamble.last() {
                        Some(p) => format!("; the line before was read as metadata: `{p}`"),
                        None => String::new(),
                    }
                ),
            ));
        }
        if preamble.len() >= MAX_PREAMBLE_LINES {
            return Err(at.invalid(
                n,
                1,
                format!(
                    "no header in the first {MAX_PREAMBLE_LINES} lines: expected a header such as \
`target,run,direction,deviation` after the export's metadata"
                ),
            ));
        }
        preamble.push(excerpt(line.trim()).into_owned());
    };
    let mut first = lines.next_content(&mut |_| {})?;
    let mut units_line = None;
    if let Some((n, line)) = &first {
        if header.apply_units_line(line, *n, &at)? {
            units_line = Some(*n);
            first = lines.next_content(&mut |_| {})?;
        }
    }
    let units = Units::read(&header, settings, &at)?;
    let mut state = RowState {
        mark: None,
        others: header
            .cells
            .iter()
            .enumerate()
            .filter(|(_, c)| c.role == Role::Other)
            .map(|(k, c)| {
                (
                    k,
                    OtherColumn {
                        name: c.name.clone(),
                        unit: c.unit.clone(),
                        column: c.column,
                        cells: 0,
                        range: None,
                    },
                )
            })
            .collect(),
    };
    let mut readings: Vec<Reading> = Vec::new();
    let mut next = first;
    while let Some((line_no, line)) = next {
        let mut fields = Vec::new();
        split_fields(&line, header.separator, &mut fields);
        let row = Row {
            header: &header,
            at: &at,
            line_no,
            line: &line,
            fields: &fields,
        };
        row.check_width()?;
        row.read(&units, &mut state, &mut readings)?;
        next = lines.next_content(&mut |_| {})?;
    }
    if readings.is_empty() {
        return Err(at.invalid(header.line, 1, "no data rows after the header".into()));
    }
    let identity = FileIdentity {
        device_inode: None,
        length: lines.length,
        fnv1a64: lines.hash.finish(),
    };
    let encoding = if lines.latin1 { "Latin-1" } else { "UTF-8" };
    Ok(FileReadings {
        path: path.to_path_buf(),
        parameter: units.parameter,
        layout: header.layout,
        header_line: header.line,
        separator: header.separator,
        decimal_mark: state.mark.map_or(DecimalMark::None, |m| m.mark),
        encoding,
        target_unit: std::mem::take(&mut header.cells[header.target].unit),
        deviation_unit: units.deviation_units.join(", "),
        units_line,
        preamble,
        other_columns: state.others.into_iter().map(|(_, c)| c).collect(),
        readings,
        identity,
    })
}

/// Where a file's errors are reported.
struct Locator<'p> {
    path: &'p Path,
}

impl Locator<'_> {
    fn invalid(&self, line: usize, column: usize, message: String) -> LaserError {
        LaserError::Invalid {
            path: self.path.to_path_buf(),
            line,
            column,
            message,
        }
    }
}

/// A file's header: its separator, its columns and the layout they make.
struct Header {
    line: usize,
    separator: char,
    cells: Vec<HeaderCell>,
    layout: Layout,
    /// Column indices of the roles.
    target: usize,
    run: Option<usize>,
    direction: Option<usize>,
    deviation: Option<usize>,
    /// The paired layout's `+` and `-` columns.
    approach: Vec<usize>,
    /// The wide layout's `run N ±` columns.
    wide: Vec<usize>,
}

impl Header {
    /// The header of a file, if `text` (line `line`) is one: a line whose
    /// cells, split at one of tab `;` `,`, name a target and a reading
    /// column. A line that names them but makes no layout is an error; one
    /// that makes a layout split at two separators is ambiguous.
    fn detect(text: &str, line: usize, at: &Locator) -> Result<Option<Self>, LaserError> {
        let mut separators: Vec<char> = ['\t', ';', ',']
            .into_iter()
            .filter(|s| text.contains(*s))
            .collect();
        if separators.is_empty() {
            separators.push(',');
        }
        let mut built: Vec<Header> = Vec::new();
        let mut failed = None;
        for separator in separators {
            let cells = Self::cells(text, line, separator);
            let has_target = cells.iter().any(|c| c.role == Role::Target);
            let has_reading = cells.iter().any(|c| {
                !matches!(c.role, Role::Target | Role::Other) || is_run_without_direction(&c.name)
            });
            if !(has_target && has_reading) {
                continue;
            }
            match Self::build(text, line, separator, cells, at) {
                Ok(h) => built.push(h),
                Err(e) => {
                    failed.get_or_insert(e);
                }
            }
        }
        match built.len() {
            0 => failed.map_or(Ok(None), Err),
            1 => Ok(built.pop()),
            _ => Err(at.invalid(
                line,
                1,
                format!(
                    "cannot decide the separator of the header `{}`: split at {} it reads as {} columns, \
split at {} as {} columns (quote the cells that hold the other)",
                    excerpt(text),
                    separator_name(built[0].separator),
                    built[0].cells.len(),
                    separator_name(built[1].separator),
                    built[1].cells.len()
                ),
            )),
        }
    }

    /// The header's cells, each classified.
    fn cells(text: &str, line: usize, separator: char) -> Vec<HeaderCell> {
        let mut fields = Vec::new();
        split_fields(text, separator, &mut fields);
        fields
            .iter()
            .map(|(start, raw)| {
                let column = char_column(text, *start);
                let (name, unit) = split_unit(raw);
                HeaderCell {
                    role: classify(&name),
                    name: excerpt(raw).into_owned(),
                    unit: excerpt(&unit).into_owned(),
                    column,
                    unit_at: (line, column),
                }
            })
            .collect()
    }

    /// The layout of classified cells; a role given twice, a mix of layouts or
    /// run columns without a direction are errors saying what is undecided.
    fn build(
        text: &str,
        line: usize,
        separator: char,
        cells: Vec<HeaderCell>,
        at: &Locator,
    ) -> Result<Self, LaserError> {
        for (k, cell) in cells.iter().enumerate() {
            if cell.role == Role::Other {
                continue;
            }
            if let Some(prev) = cells[..k].iter().find(|c| c.role == cell.role) {
                return Err(at.invalid(
                    line,
                    cell.column,
                    format!(
                        "columns `{}` (column {}) and `{}` both hold the {}: cannot decide which one to read",
                        prev.name,
                        prev.column,
                        cell.name,
                        cell.role.describe()
                    ),
                ));
            }
        }
        let find = |role: Role| cells.iter().position(|c| c.role == role);
        let target = find(Role::Target).unwrap_or(0);
        let run = find(Role::Run);
        let direction = find(Role::Direction);
        let deviation = find(Role::Deviation);
        let approach: Vec<usize> = (0..cells.len())
            .filter(|&i| matches!(cells[i].role, Role::Approach(_)))
            .collect();
        let wide: Vec<usize> = (0..cells.len())
            .filter(|&i| matches!(cells[i].role, Role::RunApproach(..)))
            .collect();
        let undirected: Vec<&str> = cells
            .iter()
            .filter(|c| c.role == Role::Other && is_run_without_direction(&c.name))
            .map(|c| c.name.as_str())
            .collect();
        let layout = match (run, direction, deviation, approach.len(), wide.len()) {
            _ if !undirected.is_empty() => None,
            (Some(_), Some(_), Some(_), 0, 0) => Some(Layout::Long),
            (Some(_), None, None, 2, 0) => Some(Layout::Paired),
            (None, None, None, 0, n) if n > 0 => Some(Layout::Wide),
            _ => None,
        };
        let Some(layout) = layout else {
            let read: Vec<String> = cells
                .iter()
                .filter(|c| c.role != Role::Other)
                .map(|c| format!("`{}` {}", c.name, c.role.describe()))
                .collect();
            let why = if !undirected.is_empty() {
                format!(
                    "`{}` name{} a run but no direction (+/-, up/down, hin/rück, ↑/↓): cannot decide which approach {} hold{}",
                    undirected.join("`, `"),
                    if undirected.len() == 1 { "s" } else { "" },
                    if undirected.len() == 1 { "it" } else { "they" },
                    if undirected.len() == 1 { "s" } else { "" },
                )
            } else if run.is_none() && (direction.is_some() || approach.len() == 2) {
                "no run column: cannot decide which run each reading belongs to".into()
            } else {
                "expected `target,run,direction,deviation` (long), `target,run,+,-` (paired) or \
`target,run 1 +,run 1 -,…` (wide), without mixing them"
                    .into()
            };
            return Err(at.invalid(
                line,
                1,
                format!(
                    "cannot tell the layout of the header `{}` (read as: {}): {why}",
                    excerpt(text),
                    read.join(", ")
                ),
            ));
        };
        Ok(Header {
            line,
            separator,
            cells,
            layout,
            target,
            run,
            direction,
            deviation,
            approach,
            wide,
        })
    }

    /// When `text` (line `line`, right under the header) is a units line
    /// (`mm;;;µm`: no number, a known unit), its units go to the header's
    /// cells and this returns true. A unit that contradicts the header's is
    /// an error.
    fn apply_units_line(
        &mut self,
        text: &str,
        line: usize,
        at: &Locator,
    ) -> Result<bool, LaserError> {
        let mut fields = Vec::new();
        split_fields(text, self.separator, &mut fields);
        let is_units = fields.iter().all(|(_, f)| parse_number(f).is_none())
            && fields
                .iter()
                .any(|(_, f)| !f.is_empty() && is_known_unit(strip_brackets(f)));
        if !is_units {
            return Ok(false);
        }
        for (k, (start, field)) in fields.iter().enumerate() {
            let unit = strip_brackets(field);
            let Some(cell) = self.cells.get_mut(k) else {
                break;
            };
            if unit.is_empty() {
                continue;
            }
            let column = char_column(text, *start);
            if !cell.unit.is_empty() && cell.unit != unit {
                return Err(at.invalid(
                    line,
                    column,
                    format!(
                        "unit `{}` of column `{}` contradicts `{}` in its header (line {}): cannot decide which applies",
                        excerpt(unit),
                        cell.name,
                        cell.unit,
                        self.line
                    ),
                ));
            }
            cell.unit = excerpt(unit).into_owned();
            cell.unit_at = (line, column);
        }
        Ok(true)
    }

    /// The columns that hold deviations.
    fn value_columns(&self) -> Vec<usize> {
        match self.layout {
            Layout::Long => vec![self.deviation.unwrap_or(0)],
            Layout::Paired => self.approach.clone(),
            Layout::Wide => self.wide.clone(),
        }
    }
}

fn separator_name(separator: char) -> &'static str {
    match separator {
        '\t' => "tabs",
        ';' => "`;`",
        _ => "`,`",
    }
}

/// What the header says of the values: the parameter measured and the factors
/// that bring targets and deviations to volcomp's units.
struct Units {
    parameter: String,
    angular: bool,
    rotary: bool,
    target_factor: f64,
    /// Per column (1 where the column gives no unit).
    factors: Vec<f64>,
    /// The deviation units the file gave, each once, in column order.
    deviation_units: Vec<String>,
}

impl Units {
    fn read(header: &Header, settings: &ReadSettings, at: &Locator) -> Result<Self, LaserError> {
        let cells = &header.cells;
        let rotary = settings.axis.is_rotary();
        let tcell = &cells[header.target];
        let target_factor = if tcell.unit.is_empty() {
            1.0
        } else {
            target_unit(&tcell.unit, rotary).ok_or_else(|| {
                at.invalid(
                    tcell.unit_at.0,
                    tcell.unit_at.1,
                    format!(
                        "target unit `{}`: axis {} takes {}",
                        tcell.unit,
                        settings.axis.letter(),
                        if rotary {
                            "degrees (`deg`)"
                        } else {
                            "mm or inch (`in`)"
                        }
                    ),
                )
            })?
        };
        let parameter = Self::parameter(header, settings, at)?;
        let angular = is_angular(&parameter);
        let mut factors = vec![1.0; cells.len()];
        let mut deviation_units: Vec<String> = Vec::new();
        for k in header.value_columns() {
            let cell = &cells[k];
            if cell.unit.is_empty() {
                continue;
            }
            match deviation_unit(&cell.unit) {
                Some((f, is_angle)) if is_angle == angular => {
                    factors[k] = f;
                    if !deviation_units.contains(&cell.unit) {
                        deviation_units.push(cell.unit.clone());
                    }
                }
                _ => {
                    return Err(at.invalid(
                        cell.unit_at.0,
                        cell.unit_at.1,
                        format!(
                            "deviation unit `{}`: {parameter} is {}",
                            cell.unit,
                            if angular {
                                "an angle: µrad, urad, mrad, arcsec, mm/m or µm/m"
                            } else {
                                "a length: µm, um, nm, mm, in, mil or µin"
                            }
                        ),
                    ));
                }
            }
        }
        Ok(Units {
            parameter,
            angular,
            rotary,
            target_factor,
            factors,
            deviation_units,
        })
    }

    /// The parameter measured: the deviation column's name when it is one
    /// (and agrees with the settings), else the settings', else the axis's
    /// positioning parameter; it must belong to the axis.
    fn parameter(
        header: &Header,
        settings: &ReadSettings,
        at: &Locator,
    ) -> Result<String, LaserError> {
        let cells = &header.cells;
        let mut parameter = settings
            .parameter
            .clone()
            .unwrap_or_else(|| positioning_parameter(settings.axis));
        if let Some(d) = header.deviation {
            let (name, _) = split_unit(cells[d].name.trim());
            let name = name.to_ascii_uppercase();
            if is_parameter_name(&name) {
                if let Some(given) = &settings.parameter {
                    if *given != name {
                        return Err(at.invalid(
                            header.line,
                            cells[d].column,
                            format!(
                                "the column measures {name}, but the file was given as {given}"
                            ),
                        ));
                    }
                }
                parameter = name;
            }
        }
        if !is_parameter_of(&parameter, settings.axis) {
            let column = header.deviation.map_or(1, |d| cells[d].column);
            return Err(at.invalid(
                header.line,
                column,
                format!(
                    "{parameter} is not an error parameter of axis {} (E<direction>{}, e.g. {})",
                    settings.axis.letter(),
                    settings.axis.letter(),
                    positioning_parameter(settings.axis)
                ),
            ));
        }
        Ok(parameter)
    }
}

/// The first number of a file that wrote a decimal mark: where and which.
struct FirstMark {
    mark: DecimalMark,
    line: usize,
    column: usize,
    text: String,
}

/// What reading the rows keeps across them.
struct RowState {
    mark: Option<FirstMark>,
    /// The columns that hold no reading, by header index.
    others: Vec<(usize, OtherColumn)>,
}

/// One data row, split into its fields.
struct Row<'a> {
    header: &'a Header,
    at: &'a Locator<'a>,
    line_no: usize,
    line: &'a str,
    fields: &'a [(usize, Cow<'a, str>)],
}

impl Row<'_> {
    /// As many fields as the header has columns: a row may leave out the
    /// cells of trailing columns that hold no reading, and end in empty fields
    /// (a separator at the end of the line).
    fn check_width(&self) -> Result<(), LaserError> {
        let width = self.header.cells.len();
        let found = self.fields.len();
        if found == width
            || (found < width
                && self.header.cells[found..]
                    .iter()
                    .all(|c| c.role == Role::Other))
            || (found > width && self.fields[width..].iter().all(|(_, f)| f.is_empty()))
        {
            return Ok(());
        }
        let column = if found > width {
            char_column(self.line, self.fields[width].0)
        } else {
            self.line.chars().count() + 1
        };
        Err(self.at.invalid(
            self.line_no,
            column,
            format!(
                "{found} fields, but the header (line {}) has {width} columns{}",
                self.header.line,
                if found < width {
                    format!(
                        "; the cell of `{}` is missing",
                        self.header.cells[found].name
                    )
                } else {
                    String::new()
                }
            ),
        ))
    }

    /// The text of column `k` and its column; empty cells are errors.
    fn cell(&self, k: usize) -> Result<(&str, usize), LaserError> {
        let (start, text) = &self.fields[k];
        let column = char_column(self.line, *start);
        if text.is_empty() {
            return Err(self.at.invalid(
                self.line_no,
                column,
                format!(
                    "empty cell in column `{}`: every cell needs a value",
                    self.header.cells[k].name
                ),
            ));
        }
        Ok((text.as_ref(), column))
    }

    /// The number of column `k`; its decimal mark must be the file's.
    fn number(&self, k: usize, state: &mut RowState) -> Result<(f64, usize), LaserError> {
        let (text, column) = self.cell(k)?;
        let v = parse_number(text).ok_or_else(|| {
            self.at.invalid(
                self.line_no,
                column,
                format!(
                    "`{}` in column `{}` is not a finite number{}",
                    excerpt(text),
                    self.header.cells[k].name,
                    if text.contains('.') && text.contains(',') {
                        " (it writes both a decimal point and a comma: a thousands separator cannot be told from a decimal mark)"
                    } else {
                        ""
                    }
                ),
            )
        })?;
        let mark = DecimalMark::of(text);
        if mark != DecimalMark::None {
            match &state.mark {
                None => {
                    state.mark = Some(FirstMark {
                        mark,
                        line: self.line_no,
                        column,
                        text: excerpt(text).into_owned(),
                    });
                }
                Some(first) if first.mark != mark => {
                    return Err(self.at.invalid(
                        self.line_no,
                        column,
                        format!(
                            "`{}` writes a {}, but this file writes a {} (first `{}` at line {}, column {}): \
cannot decide which is the decimal mark; one file, one mark",
                            excerpt(text),
                            mark.describe(),
                            first.mark.describe(),
                            first.text,
                            first.line,
                            first.column
                        ),
                    ));
                }
                Some(_) => {}
            }
        }
        Ok((v, column))
    }

    fn run(&self, k: usize) -> Result<u32, LaserError> {
        let (text, column) = self.cell(k)?;
        match text.parse::<u32>() {
            Ok(r) if r >= 1 => Ok(r),
            _ => Err(self.at.invalid(
                self.line_no,
                column,
                format!("run `{}` is not a whole number from 1", excerpt(text)),
            )),
        }
    }

    /// The row's target in mm or degrees, within the axis's range.
    fn target(&self, units: &Units, state: &mut RowState) -> Result<f64, LaserError> {
        let k = self.header.target;
        let (v, column) = self.number(k, state)?;
        let target = converted(v, units.target_factor, self.fields[k].1.as_ref());
        let limit = if units.rotary {
            MAX_TARGET_DEG
        } else {
            MAX_TARGET_MM
        };
        if !(target.abs() <= limit) {
            return Err(self.at.invalid(
                self.line_no,
                column,
                format!(
                    "target `{}` is beyond what a machine axis travels (|target| ≤ {MAX_TARGET_MM} mm on a linear axis, {MAX_TARGET_DEG}° on a rotary one)",
                    excerpt(self.fields[k].1.as_ref())
                ),
            ));
        }
        Ok(target)
    }

    /// The row's readings, appended to `out` in column order.
    fn read(
        &self,
        units: &Units,
        state: &mut RowState,
        out: &mut Vec<Reading>,
    ) -> Result<(), LaserError> {
        let header = self.header;
        let target = self.target(units, state)?;
        let mut reading = |k: usize, run: u32, up: bool, state: &mut RowState| {
            let (v, column) = self.number(k, state)?;
            let deviation = v * units.factors[k];
            if !(deviation.abs() <= MAX_DEVIATION) {
                return Err(self.at.invalid(
                    self.line_no,
                    column,
                    format!(
                        "deviation `{}` in column `{}` is beyond a machine tool's positioning error (|deviation| ≤ {}",
                        excerpt(self.fields[k].1.as_ref()),
                        header.cells[k].name,
                        if units.angular {
                            format!("{MAX_DEVIATION} µrad = 0.1 rad)")
                        } else {
                            format!("{MAX_DEVIATION} µm = 100 mm)")
                        }
                    ),
                ));
            }
            out.push(Reading {
                target,
                run,
                up,
                deviation,
                line: self.line_no as u32,
                column: column as u32,
            });
            Ok(())
        };
        match header.layout {
            Layout::Long => {
                let run = self.run(header.run.unwrap_or(0))?;
                let (dtext, dcol) = self.cell(header.direction.unwrap_or(0))?;
                let up = parse_direction(dtext).ok_or_else(|| {
                    self.at.invalid(
                        self.line_no,
                        dcol,
                        format!(
                            "direction `{}`: expected + or - (also up/down, fwd/rev, ↑/↓, vorwärts/rückwärts, hin/rück)",
                            excerpt(dtext)
                        ),
                    )
                })?;
                reading(header.deviation.unwrap_or(0), run, up, state)?;
            }
            Layout::Paired => {
                let run = self.run(header.run.unwrap_or(0))?;
                for &k in &header.approach {
                    if let Role::Approach(up) = header.cells[k].role {
                        reading(k, run, up, state)?;
                    }
                }
            }
            Layout::Wide => {
                for &k in &header.wide {
                    if let Role::RunApproach(run, up) = header.cells[k].role {
                        reading(k, run, up, state)?;
                    }
                }
            }
        }
        for (k, other) in &mut state.others {
            let Some((_, text)) = self.fields.get(*k) else {
                continue;
            };
            if text.is_empty() {
                continue;
            }
            other.cells += 1;
            if let Some(v) = parse_number(text) {
                other.range = Some(match other.range {
                    None => [v, v],
                    Some([lo, hi]) => [lo.min(v), hi.max(v)],
                });
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> ReadSettings {
        ReadSettings {
            axis: Axis::X,
            parameter: None,
        }
    }

    #[test]
    fn semicolon_and_decimal_comma() {
        let text = "target [mm];run;direction;deviation [mm]\n0;1;+;0,0012\n0;1;-;-0,0008\n";
        let r = parse(text, Path::new("t.csv"), &settings()).unwrap();
        assert_eq!(r.layout, Layout::Long);
        assert_eq!(r.decimal_mark, DecimalMark::Comma);
        assert!((r.readings[0].deviation - 1.2).abs() < 1e-12);
        assert!((r.readings[1].deviation + 0.8).abs() < 1e-12);
    }

    #[test]
    fn mixed_decimal_marks_name_the_first_cell_that_disagrees() {
        let text = "target;run;direction;deviation\n0;1;+;0,0012\n10;1;+;1.030\n";
        let e = parse(text, Path::new("t.csv"), &settings())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:3:8: `1.030` writes a decimal point, but this file writes a decimal comma (first `0,0012` at line 2, column 7)"),
            "{e}"
        );
    }

    #[test]
    fn an_empty_cell_is_named_by_line_and_column() {
        let text = "target,run 1 +,run 1 -\n0,1.0,\n";
        let e = parse(text, Path::new("t.csv"), &settings())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2:7: empty cell in column `run 1 -`"),
            "{e}"
        );
    }

    #[test]
    fn a_long_cell_is_echoed_cut() {
        let big = "9".repeat(5000) + "x";
        let text = format!("target,run,direction,deviation\n0,1,+,{big}\n");
        let e = parse(&text, Path::new("t.csv"), &settings())
            .unwrap_err()
            .to_string();
        assert!(e.len() < 400, "{} bytes", e.len());
        assert!(e.contains("… (5001 bytes)"), "{e}");
    }

    #[test]
    fn a_long_line_is_refused_without_keeping_it() {
        let text = format!("target,run,direction,deviation\n{}\n", "1".repeat(200_000));
        let e = parse(&text, Path::new("t.csv"), &settings())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2:65537: line of 200000 bytes: volcomp reads laser lines of at most 65536 bytes"),
            "{e}"
        );
    }

    #[test]
    fn deviations_beyond_the_physical_range_are_refused() {
        let text = "target,run,direction,deviation [mm]\n0,1,+,1e308\n";
        let e = parse(text, Path::new("t.csv"), &settings())
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2:7: deviation `1e308` in column `deviation [mm]` is beyond a machine tool's positioning error (|deviation| ≤ 100000 µm = 100 mm)"),
            "{e}"
        );
    }

    #[test]
    fn a_preamble_and_other_columns_are_kept() {
        let text = "Renishaw CARTO Explore export\nMachine,DMU 50\n\nTarget (mm),Run,Direction,Error (µm),Air temp (°C),Comment\n\
0,1,+,1.5,20.1,\n0,1,-,-1.5,20.3,warm\n";
        let r = parse(text, Path::new("t.csv"), &settings()).unwrap();
        assert_eq!(
            r.preamble,
            ["Renishaw CARTO Explore export", "Machine,DMU 50"]
        );
        assert_eq!(r.header_line, 4);
        assert_eq!(r.other_columns.len(), 2);
        assert_eq!(r.other_columns[0].name, "Air temp (°C)");
        assert_eq!(r.other_columns[0].range, Some([20.1, 20.3]));
        assert_eq!(r.other_columns[1].cells, 1);
    }

    #[test]
    fn a_units_line_and_latin1_german() {
        let mut bytes = b"Sollposition;Lauf;Richtung;Abweichung\nin;;;\xb5in\n".to_vec();
        bytes.extend_from_slice(b"1;1;vorw\xe4rts;100\n1;1;r\xfcckw\xe4rts;-100\n");
        let r = parse_from(&mut bytes.as_slice(), Path::new("t.csv"), &settings()).unwrap();
        assert_eq!(r.encoding, "Latin-1");
        assert_eq!(r.units_line, Some(2));
        assert_eq!(r.target_unit, "in");
        assert!((r.readings[0].target - 25.4).abs() < 1e-12);
        assert!((r.readings[0].deviation - 2.54).abs() < 1e-12);
        assert!(!r.readings[1].up);
    }

    #[test]
    fn ambiguous_headers_say_what_they_could_not_decide() {
        let e = |text: &str| {
            parse(text, Path::new("t.csv"), &settings())
                .unwrap_err()
                .to_string()
        };
        let m = e("target,Run 1,Run 2\n0,1,2\n");
        assert!(
            m.contains("`Run 1`, `Run 2` name a run but no direction"),
            "{m}"
        );
        let m = e("target,run,direction,error,Abweichung\n0,1,+,1,1\n");
        assert!(
            m.contains("columns `error` (column 22) and `Abweichung` both hold the deviation"),
            "{m}"
        );
        let m = e("target,direction,deviation\n0,+,1\n");
        assert!(m.contains("no run column"), "{m}");
    }

    #[test]
    fn angle_units_convert_to_microradians() {
        let s = ReadSettings {
            axis: Axis::X,
            parameter: Some("EAX".into()),
        };
        let text = "target\trun\tdirection\tdeviation [arcsec]\n0\t1\t+\t1\n";
        let r = parse(text, Path::new("t.csv"), &s).unwrap();
        assert!((r.readings[0].deviation - 4.84813681109536).abs() < 1e-9);
        let text = "target,run,direction,deviation [mm/m]\n0,1,+,0.01\n";
        let r = parse(text, Path::new("t.csv"), &s).unwrap();
        assert!((r.readings[0].deviation - 10.0).abs() < 1e-12);
        let text = "target,run,direction,deviation [um]\n0,1,+,0.01\n";
        let e = parse(text, Path::new("t.csv"), &s).unwrap_err().to_string();
        assert!(
            e.contains("t.csv:1:22: deviation unit `um`: EAX is an angle"),
            "{e}"
        );
    }
}
