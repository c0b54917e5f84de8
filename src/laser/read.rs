//! Reading laser-interferometer positioning runs (formats.md "Laser positioning
//! runs and reversal"; the accepted layouts are listed in docs/extensions.md).
//!
//! Three layouts, told apart by the header:
//! - **long**: `target,run,direction,deviation` (the contract), one reading a row;
//! - **paired**: `target,run,+,-` (also `up,down`, `fwd,rev`, `forward,reverse`),
//!   one target and run a row, both approaches;
//! - **wide**: `target,run 1 +,run 1 -,run 2 +,…` (the spreadsheet export of
//!   laser software), one target a row, a column per run and direction.
//!
//! Separators `,` `;` or tab (the header's decides); with `;` or tab a decimal
//! comma is accepted (`1,25`); fields may be quoted. A header cell may carry its
//! unit in brackets or parentheses (`target [mm]`, `deviation (µm)`). Rows may
//! come in any order (runs measured from the far end, descending targets).
//!
//! Invariants: every value of a [`FileReadings`] is finite and in volcomp's units
//! (targets mm or degrees, deviations µm or µrad); every error names the file, the
//! line and the column (1-based characters) of the cell.
use std::path::{Path, PathBuf};

use crate::axes::Axis;

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

/// The readings of one file, in volcomp's units.
#[derive(Clone, Debug)]
pub struct FileReadings {
    /// The file.
    pub path: PathBuf,
    /// The error parameter the deviations measure (`EXX`, `EYX`, `EAA`…).
    pub parameter: String,
    /// Its header layout.
    pub layout: Layout,
    /// Its field separator (`,`, `;` or tab).
    pub separator: char,
    /// Whether it writes a decimal comma.
    pub decimal_comma: bool,
    /// The units the file gave (empty: volcomp's default).
    pub target_unit: String,
    /// The unit of its deviations as the file gave it (empty: volcomp's default).
    pub deviation_unit: String,
    /// The readings, in file order.
    pub readings: Vec<Reading>,
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

/// What a header cell is.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Role {
    Target,
    Run,
    Direction,
    /// The deviation of the long layout.
    Deviation,
    /// A paired layout's deviation of one approach.
    Approach(bool),
    /// A wide layout's run and approach.
    RunApproach(u32, bool),
}

/// A header cell: its role, its unit (as written) and its 1-based column.
#[derive(Clone, Debug)]
struct HeaderCell {
    role: Role,
    name: String,
    unit: String,
    column: usize,
}

/// A unit's factor to volcomp's unit, and whether it measures an angle.
fn deviation_unit(unit: &str) -> Option<(f64, bool)> {
    let u = unit.trim().replace(['μ', 'µ'], "u").to_ascii_lowercase();
    let arcsec = std::f64::consts::PI / (180.0 * 3600.0) * 1e6;
    Some(match u.as_str() {
        "um" | "micron" | "microns" => (1.0, false),
        "mm" => (1000.0, false),
        "nm" => (1e-3, false),
        "urad" => (1.0, true),
        "mrad" => (1000.0, true),
        "arcsec" | "\"" | "″" | "sec" => (arcsec, true),
        "mm/m" => (1000.0, true),
        "um/m" => (1.0, true),
        _ => return None,
    })
}

/// A target unit's factor to mm (linear) or degrees (rotary).
fn target_unit(unit: &str, rotary: bool) -> Option<f64> {
    let u = unit.trim().to_ascii_lowercase();
    match (u.as_str(), rotary) {
        ("mm", false) => Some(1.0),
        ("deg" | "°" | "degree" | "degrees", true) => Some(1.0),
        _ => None,
    }
}

/// `name [unit]` or `name (unit)` → (name, unit); no unit → "".
fn split_unit(cell: &str) -> (String, String) {
    let cell = cell.trim();
    for (open, close) in [('[', ']'), ('(', ')')] {
        if cell.ends_with(close) {
            if let Some(k) = cell.rfind(open) {
                let unit = cell[k + open.len_utf8()..cell.len() - close.len_utf8()].trim();
                let name = cell[..k].trim();
                if !name.is_empty()
                    && (deviation_unit(unit).is_some()
                        || target_unit(unit, false)
                            .or(target_unit(unit, true))
                            .is_some())
                {
                    return (name.to_string(), unit.to_string());
                }
                if !name.is_empty()
                    && !unit.is_empty()
                    && !unit.chars().any(|c| c.is_ascii_digit())
                    && !is_direction_word(unit)
                {
                    // An unknown unit: kept, refused with its column later.
                    return (name.to_string(), unit.to_string());
                }
            }
        }
    }
    (cell.to_string(), String::new())
}

/// A direction as the contract writes it (and the usual words).
pub fn parse_direction(text: &str) -> Option<bool> {
    match text {
        "+" => return Some(true),
        "-" => return Some(false),
        _ => {}
    }
    match text.trim().to_ascii_lowercase().as_str() {
        "+" | "up" | "fwd" | "forward" | "pos" | "positive" | "↑" => Some(true),
        "-" | "−" | "down" | "rev" | "reverse" | "bwd" | "backward" | "neg" | "negative" | "↓" => {
            Some(false)
        }
        _ => None,
    }
}

fn is_direction_word(text: &str) -> bool {
    parse_direction(text).is_some()
}

/// A wide layout's run column: a run number and a direction, e.g. `run 1 +`,
/// `Run 2 (down)`, `R3 fwd`, `1+`, `+1`.
fn parse_run_column(name: &str) -> Option<(u32, bool)> {
    let lower = name.to_ascii_lowercase();
    let mut rest = lower.trim();
    for prefix in ["run", "r", "#"] {
        if let Some(r) = rest.strip_prefix(prefix) {
            if r.starts_with(|c: char| {
                c.is_ascii_digit() || c == ' ' || c == '_' || c == '.' || c == '#'
            }) {
                rest = r.trim_start_matches([' ', '_', '.', '#']);
                break;
            }
        }
    }
    let digits_start = rest.find(|c: char| c.is_ascii_digit())?;
    let digits_end = digits_start
        + rest[digits_start..]
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(rest.len() - digits_start);
    let run: u32 = rest[digits_start..digits_end].parse().ok()?;
    if run == 0 {
        return None;
    }
    let clean = |s: &str| {
        s.trim_matches(|c: char| c == ' ' || c == '_' || c == '(' || c == ')' || c == '.')
            .to_string()
    };
    let before = clean(&rest[..digits_start]);
    let after = clean(&rest[digits_end..]);
    match (before.is_empty(), after.is_empty()) {
        (true, false) => parse_direction(&after).map(|d| (run, d)),
        (false, true) => parse_direction(&before).map(|d| (run, d)),
        _ => None,
    }
}

fn classify(name: &str, column: usize) -> Option<Role> {
    let lower = name.trim().to_ascii_lowercase();
    let role = match lower.as_str() {
        "target" | "position" | "target position" | "nominal" | "target_position" => Role::Target,
        "run" | "run no" | "run no." | "run number" | "cycle" => Role::Run,
        "direction" | "dir" | "approach" => Role::Direction,
        "deviation" | "error" | "dev" => Role::Deviation,
        _ => {
            if let Some(up) = parse_direction(&lower) {
                Role::Approach(up)
            } else if let Some(rest) = lower
                .strip_prefix("deviation")
                .or_else(|| lower.strip_prefix("error"))
            {
                Role::Approach(parse_direction(rest)?)
            } else if is_parameter_name(&name.trim().to_ascii_uppercase()) {
                Role::Deviation
            } else {
                let (run, up) = parse_run_column(&lower)?;
                Role::RunApproach(run, up)
            }
        }
    };
    let _ = column;
    Some(role)
}

/// `E` + direction + axis letter (any axis).
fn is_parameter_name(name: &str) -> bool {
    let b = name.as_bytes();
    b.len() == 3
        && b[0] == b'E'
        && crate::machine::table::DIRECTIONS.contains(&(b[1] as char))
        && Axis::from_letter(b[2] as char).is_some()
}

/// The fields of a line: (start byte, text), unquoted and trimmed.
fn split_fields<'a>(line: &'a str, sep: char, out: &mut Vec<(usize, std::borrow::Cow<'a, str>)>) {
    out.clear();
    if !line.contains('"') {
        let mut start = 0;
        for field in line.split(sep) {
            let lead = field.len() - field.trim_start().len();
            out.push((start + lead, std::borrow::Cow::Borrowed(field.trim())));
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
            out.push((start, std::borrow::Cow::Owned(field.trim().to_string())));
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
    out.push((start, std::borrow::Cow::Owned(field.trim().to_string())));
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

/// A number, with a decimal point or a decimal comma (a field holds a comma
/// only with `;` or tab separators, or quoted).
fn parse_number(text: &str) -> Option<f64> {
    let v = if text.contains(',') {
        if text.contains('.') || text.matches(',').count() > 1 {
            return None;
        }
        text.replace(',', ".").parse::<f64>().ok()?
    } else {
        let t = text.strip_prefix('+').unwrap_or(text);
        t.parse::<f64>().ok()?
    };
    v.is_finite().then_some(v)
}

/// Read one laser file (`settings` say which axis and parameter).
pub fn read_file(path: &Path, settings: &ReadSettings) -> Result<FileReadings, LaserError> {
    let text = crate::io::read_to_string(path)?;
    parse(&text, path, settings)
}

/// Parse `text` as the laser file `path` (named in errors).
pub fn parse(text: &str, path: &Path, settings: &ReadSettings) -> Result<FileReadings, LaserError> {
    let at = Locator { path };
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text
        .split('\n')
        .enumerate()
        .map(|(i, l)| (i + 1, l.strip_suffix('\r').unwrap_or(l)))
        .filter(|(_, l)| {
            let t = l.trim();
            !t.is_empty() && !t.starts_with('#')
        });
    let Some((header_line, header_text)) = lines.next() else {
        return Err(at.invalid(
            1,
            1,
            "empty file: expected a header such as `target,run,direction,deviation`".into(),
        ));
    };
    let header = Header::read(header_text, header_line, &at)?;
    let units = Units::read(&header, settings, &at)?;
    let mut readings: Vec<Reading> = Vec::new();
    let mut decimal_comma = false;
    let mut fields = Vec::new();
    for (line_no, line) in lines {
        split_fields(line, header.separator, &mut fields);
        let row = Row {
            header: &header,
            at: &at,
            line_no,
            line,
            fields: &fields,
        };
        row.check_width()?;
        decimal_comma |= fields.iter().any(|(_, f)| f.contains(','));
        row.read(&units, &mut readings)?;
    }
    if readings.is_empty() {
        return Err(at.invalid(header_line, 1, "no data rows after the header".into()));
    }
    Ok(FileReadings {
        path: path.to_path_buf(),
        parameter: units.parameter,
        layout: header.layout,
        separator: header.separator,
        decimal_comma,
        target_unit: header.cells[header.target].unit.clone(),
        deviation_unit: units.deviation_units.join(", "),
        readings,
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
    /// Read the header line `text` (line `line` of the file).
    fn read(text: &str, line: usize, at: &Locator) -> Result<Self, LaserError> {
        let separator = if text.contains('\t') {
            '\t'
        } else if text.contains(';') {
            ';'
        } else {
            ','
        };
        let cells = Self::cells(text, line, separator, at)?;
        let find = |role: Role| cells.iter().position(|c| c.role == role);
        let target = find(Role::Target).ok_or_else(|| {
            at.invalid(
                line,
                1,
                format!(
                    "no target column: expected `target` (or `position`) in the header `{text}`"
                ),
            )
        })?;
        let run = find(Role::Run);
        let direction = find(Role::Direction);
        let deviation = find(Role::Deviation);
        let approach: Vec<usize> = (0..cells.len())
            .filter(|&i| matches!(cells[i].role, Role::Approach(_)))
            .collect();
        let wide: Vec<usize> = (0..cells.len())
            .filter(|&i| matches!(cells[i].role, Role::RunApproach(..)))
            .collect();
        let layout = match (run, direction, deviation, approach.len(), wide.len()) {
            (Some(_), Some(_), Some(_), 0, 0) => Layout::Long,
            (Some(_), None, None, 2, 0) => Layout::Paired,
            (None, None, None, 0, n) if n > 0 => Layout::Wide,
            _ => {
                return Err(at.invalid(
                    line,
                    1,
                    format!(
                        "cannot tell the layout of the header `{text}`: expected `target,run,direction,deviation` \
(long), `target,run,+,-` (paired) or `target,run 1 +,run 1 -,…` (wide), without mixing them"
                    ),
                ));
            }
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

    /// The header's cells, each classified; an unknown or repeated role is an error.
    fn cells(
        text: &str,
        line: usize,
        separator: char,
        at: &Locator,
    ) -> Result<Vec<HeaderCell>, LaserError> {
        let mut fields = Vec::new();
        split_fields(text, separator, &mut fields);
        let mut cells: Vec<HeaderCell> = Vec::new();
        for (start, raw) in &fields {
            let column = char_column(text, *start);
            let (name, unit) = split_unit(raw);
            let Some(role) = classify(&name, column) else {
                return Err(at.invalid(
                    line,
                    column,
                    format!(
                        "unknown column `{raw}`: expected target, run, direction, deviation (long layout), \
+ and - deviations (paired) or run columns like `run 1 +` (wide; docs/extensions.md)"
                    ),
                ));
            };
            if let Some(prev) = cells.iter().find(|c| c.role == role) {
                return Err(at.invalid(
                    line,
                    column,
                    format!(
                        "column `{raw}` repeats column {} (`{}`)",
                        prev.column, prev.name
                    ),
                ));
            }
            cells.push(HeaderCell {
                role,
                name: raw.to_string(),
                unit,
                column,
            });
        }
        Ok(cells)
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

/// What the header says of the values: the parameter measured and the factors
/// that bring targets and deviations to volcomp's units.
struct Units {
    parameter: String,
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
                    header.line,
                    tcell.column,
                    format!(
                        "target unit `{}`: axis {} takes {}",
                        tcell.unit,
                        settings.axis.letter(),
                        if rotary { "degrees (`deg`)" } else { "mm" }
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
                        header.line,
                        cell.column,
                        format!(
                            "deviation unit `{}`: {parameter} is {}",
                            cell.unit,
                            if angular {
                                "an angle: µrad, urad, mrad, arcsec, mm/m or µm/m"
                            } else {
                                "a length: µm, um, nm or mm"
                            }
                        ),
                    ));
                }
            }
        }
        Ok(Units {
            parameter,
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

/// One data row, split into its fields.
struct Row<'a> {
    header: &'a Header,
    at: &'a Locator<'a>,
    line_no: usize,
    line: &'a str,
    fields: &'a [(usize, std::borrow::Cow<'a, str>)],
}

impl Row<'_> {
    /// As many fields as the header has columns.
    fn check_width(&self) -> Result<(), LaserError> {
        let width = self.header.cells.len();
        let found = self.fields.len();
        if found == width {
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

    fn number(&self, k: usize) -> Result<(f64, usize), LaserError> {
        let (text, column) = self.cell(k)?;
        parse_number(text).map(|v| (v, column)).ok_or_else(|| {
            self.at.invalid(
                self.line_no,
                column,
                format!(
                    "`{text}` in column `{}` is not a finite number",
                    self.header.cells[k].name
                ),
            )
        })
    }

    fn run(&self, k: usize) -> Result<u32, LaserError> {
        let (text, column) = self.cell(k)?;
        match text.parse::<u32>() {
            Ok(r) if r >= 1 => Ok(r),
            _ => Err(self.at.invalid(
                self.line_no,
                column,
                format!("run `{text}` is not a whole number from 1"),
            )),
        }
    }

    /// The row's readings, appended to `out` in column order.
    fn read(&self, units: &Units, out: &mut Vec<Reading>) -> Result<(), LaserError> {
        let header = self.header;
        let target = self.number(header.target)?.0 * units.target_factor;
        let reading = |k: usize, run: u32, up: bool| -> Result<Reading, LaserError> {
            let (v, column) = self.number(k)?;
            Ok(Reading {
                target,
                run,
                up,
                deviation: v * units.factors[k],
                line: self.line_no as u32,
                column: column as u32,
            })
        };
        match header.layout {
            Layout::Long => {
                let run = self.run(header.run.unwrap_or(0))?;
                let (dtext, dcol) = self.cell(header.direction.unwrap_or(0))?;
                let up = parse_direction(dtext).ok_or_else(|| {
                    self.at.invalid(
                        self.line_no,
                        dcol,
                        format!("direction `{dtext}`: expected + or - (also up/down, fwd/rev)"),
                    )
                })?;
                out.push(reading(header.deviation.unwrap_or(0), run, up)?);
            }
            Layout::Paired => {
                let run = self.run(header.run.unwrap_or(0))?;
                for &k in &header.approach {
                    if let Role::Approach(up) = header.cells[k].role {
                        out.push(reading(k, run, up)?);
                    }
                }
            }
            Layout::Wide => {
                for &k in &header.wide {
                    if let Role::RunApproach(run, up) = header.cells[k].role {
                        out.push(reading(k, run, up)?);
                    }
                }
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
    fn run_columns_are_read() {
        assert_eq!(parse_run_column("run 1 +"), Some((1, true)));
        assert_eq!(parse_run_column("run 12 (down)"), Some((12, false)));
        assert_eq!(parse_run_column("r3 fwd"), Some((3, true)));
        assert_eq!(parse_run_column("2-"), Some((2, false)));
        assert_eq!(parse_run_column("+4"), Some((4, true)));
        assert_eq!(parse_run_column("run 1"), None);
        assert_eq!(parse_run_column("temperature"), None);
    }

    #[test]
    fn units_are_split_from_names() {
        assert_eq!(split_unit("target [mm]"), ("target".into(), "mm".into()));
        assert_eq!(
            split_unit("deviation (µm)"),
            ("deviation".into(), "µm".into())
        );
        assert_eq!(split_unit("run 1 (+)"), ("run 1 (+)".into(), "".into()));
    }

    #[test]
    fn semicolon_and_decimal_comma() {
        let text = "target [mm];run;direction;deviation [mm]\n0;1;+;0,0012\n0;1;-;-0,0008\n";
        let r = parse(text, Path::new("t.csv"), &settings()).unwrap();
        assert_eq!(r.layout, Layout::Long);
        assert!((r.readings[0].deviation - 1.2).abs() < 1e-12);
        assert!((r.readings[1].deviation + 0.8).abs() < 1e-12);
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
