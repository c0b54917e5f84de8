//! Measured component-error tables (formats.md "Error table"), one CSV per axis:
//! a header `position,EXX,EYX,…` (columns in any order), then one row per measured
//! position, positions strictly increasing; `#` lines and blank lines are ignored.
//! A `REVERSAL` column (formats.md "Laser positioning runs and reversal", written by
//! `volcomp import-laser`) is kept in [`ErrorTable::reversal`].
//!
//! Invariants of a read [`ErrorTable`]: at least [`MIN_ROWS`] rows
//! ([`MIN_ROWS_WITH_UNCERTAINTY`] when every column has its `u_`), positions
//! finite and strictly increasing, every value finite; each column is one of the six
//! parameters `E{X,Y,Z,A,B,C}{axis}` of the table's axis, at most once; the
//! parameters not in the file are listed in `missing` (not measured: zero).
//! Every error names the file, the line and (where it applies) the column.
use std::path::{Path, PathBuf};

use super::physical_ranges::{
    MAX_LENGTH_MM, MAX_REVERSAL_UM, MAX_REVERSAL_URAD, check_magnitude, error_bound,
};
use crate::axes::Axis;

/// Fewest rows a column needs to be fitted (the seed paper's minimum).
pub const MIN_ROWS: usize = 8;

/// Fewest rows of a table whose every column carries its uncertainty (`u_`,
/// a laser run through `import-laser`): ISO 230-2's five targets a metre; a
/// sparse table of means is joined by straight lines where that predicts the
/// means better than a spline (docs/fidelity.md "Sparse laser tables").
pub const MIN_ROWS_WITH_UNCERTAINTY: usize = 5;

/// The error directions of a table's columns, in the conventional order.
pub const DIRECTIONS: [char; 6] = ['X', 'Y', 'Z', 'A', 'B', 'C'];

/// One measured error parameter.
#[derive(Clone, Debug, PartialEq)]
pub struct TableColumn {
    /// Parameter name, e.g. `EXX` (error in X of the X axis), `EAC`.
    pub name: String,
    /// One value per position: µm for E{X,Y,Z}*, µrad for E{A,B,C}*.
    pub values: Vec<f64>,
    /// The standard uncertainty of every value, when the table has its
    /// `u_<name>` column (`import-laser` writes it from the runs' scatter):
    /// the fit weights by it and takes it as the noise. Same units.
    pub uncertainty: Option<Vec<f64>>,
}

impl TableColumn {
    /// Is this an angular parameter (`EA?`, `EB?`, `EC?`), in µrad?
    pub fn is_angular(&self) -> bool {
        matches!(self.name.as_bytes().get(1), Some(b'A' | b'B' | b'C'))
    }
}

/// A measured error table of one axis (a CSV file named by the machine file).
/// Two tables are equal when their data are (not their text: a comment does
/// not change a table).
#[derive(Clone, Debug)]
pub struct ErrorTable {
    /// The CSV file.
    pub path: PathBuf,
    /// The axis it measures.
    pub axis: Axis,
    /// mm (linear axes) or degrees (rotary), strictly increasing.
    pub positions: Vec<f64>,
    /// In file order.
    pub columns: Vec<TableColumn>,
    /// Parameters of the axis the file does not carry (not measured, zero).
    pub missing: Vec<String>,
    /// A rotary table covering 0..360 degrees: lookups wrap (c mod 360).
    pub one_revolution: bool,
    /// `REVERSAL` (formats.md "Laser positioning runs and reversal"): the
    /// positioning error approaching from below minus from above, µm or µrad,
    /// one value per position; `None` when the file has no such column.
    pub reversal: Option<Vec<f64>>,
    /// The file's text as it was read and parsed: what hashes and copies of
    /// the table are made from (the file may change after it was read).
    pub text: std::sync::Arc<str>,
}

impl PartialEq for ErrorTable {
    fn eq(&self, other: &Self) -> bool {
        self.path == other.path
            && self.axis == other.axis
            && self.positions == other.positions
            && self.columns == other.columns
            && self.missing == other.missing
            && self.one_revolution == other.one_revolution
            && self.reversal == other.reversal
    }
}

#[derive(Debug, thiserror::Error)]
pub enum TableError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    #[error("{}: line {line}{}: {message}", path.display(), column.as_ref().map(|c| format!(", column {c}")).unwrap_or_default())]
    Invalid {
        path: PathBuf,
        line: usize,
        column: Option<String>,
        message: String,
    },
}

/// What lets a short table be fitted.
static UNCERTAINTY_HINT: std::sync::LazyLock<String> = std::sync::LazyLock::new(|| {
    format!(
        " ({MIN_ROWS_WITH_UNCERTAINTY} suffice when every column has its u_ column, as import-laser writes)"
    )
});

/// The parameter name of direction `d` on `axis`, e.g. `EXZ`.
pub fn parameter_name(direction: char, axis: Axis) -> String {
    format!("E{direction}{}", axis.letter())
}

impl ErrorTable {
    /// Read and validate a table; `axis` None = infer it from the column names.
    pub fn read(path: &Path, axis: Option<Axis>) -> Result<ErrorTable, TableError> {
        let text = crate::io::read_to_string(path).map_err(|e| TableError::Read {
            path: path.to_path_buf(),
            source: e.source,
        })?;
        ErrorTable::parse(&text, path, axis)
    }

    /// Parse `text` as the table `path` (named in errors).
    pub fn parse(text: &str, path: &Path, axis: Option<Axis>) -> Result<ErrorTable, TableError> {
        let at = TableSource { path };
        let source_text: std::sync::Arc<str> = std::sync::Arc::from(text);
        // A byte order mark (spreadsheets write one) is not part of the header.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        // Lines longer than the readers' limit are refused, not echoed.
        if let Some((i, l)) = text
            .lines()
            .enumerate()
            .find(|(_, l)| l.len() > crate::io::MAX_LINE_BYTES)
        {
            let message = crate::io::long_line(l).unwrap_or_default();
            return Err(at.invalid(i + 1, None, message));
        }
        let mut lines = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((header_line, header_text)) = lines.next() else {
            return Err(at.invalid(
                1,
                None,
                "empty table: expected a header `position,EXX,...`".into(),
            ));
        };
        let header = TableHeader::read(header_text, header_line, axis, &at)?;
        let axis = header.axis;
        let mut positions: Vec<f64> = Vec::new();
        let mut values: Vec<Vec<f64>> = vec![Vec::new(); header.params.len()];
        let mut reversal: Vec<f64> = Vec::new();
        let mut uncertainty: Vec<Option<Vec<f64>>> = vec![None; header.params.len()];
        for &(_, slot) in &header.uncertainties {
            uncertainty[slot] = Some(Vec::new());
        }
        let mut last_line = header_line;
        for (line, row) in lines {
            last_line = line;
            let fields: Vec<&str> = row.split(',').map(str::trim).collect();
            if fields.len() != header.width {
                return Err(at.invalid(
                    line,
                    None,
                    format!(
                        "{} fields, but the header has {} columns",
                        fields.len(),
                        header.width
                    ),
                ));
            }
            let number = |i: usize| -> Result<f64, TableError> {
                match fields[i].parse::<f64>() {
                    Ok(v) if v.is_finite() => Ok(v),
                    _ => Err(at.invalid(
                        line,
                        Some(header.label(i)),
                        format!("`{}` is not a finite number", crate::io::echo(fields[i])),
                    )),
                }
            };
            // Within what a machine tool can have (physical_ranges).
            let bounded = |i: usize, name: &str, max: f64, unit: &str| {
                let v = number(i)?;
                check_magnitude(name, unit, v, max)
                    .map_err(|m| at.invalid(line, Some(header.label(i)), m))
            };
            let x = bounded(header.position, "position", MAX_LENGTH_MM, "mm or °")?;
            if let Some(&prev) = positions.last() {
                if x <= prev {
                    return Err(at.invalid(
                        line,
                        Some(header.label(header.position)),
                        format!(
                            "position {x} does not increase (previous row: {prev}); positions must be strictly increasing"
                        ),
                    ));
                }
            }
            positions.push(x);
            for (slot, (i, name)) in header.params.iter().enumerate() {
                let (max, unit) = error_bound(name);
                values[slot].push(bounded(*i, name, max, unit)?);
            }
            if let Some(i) = header.reversal {
                let (max, unit) = if axis.is_rotary() {
                    (MAX_REVERSAL_URAD, "µrad")
                } else {
                    (MAX_REVERSAL_UM, "µm")
                };
                reversal.push(bounded(i, "REVERSAL", max, unit)?);
            }
            for &(i, slot) in &header.uncertainties {
                let u = number(i)?;
                if u < 0.0 {
                    return Err(at.invalid(
                        line,
                        Some(header.label(i)),
                        format!("uncertainty {u} is negative: a standard uncertainty is >= 0"),
                    ));
                }
                if let Some(column) = &mut uncertainty[slot] {
                    column.push(u);
                }
            }
        }
        let measured = !uncertainty.is_empty() && uncertainty.iter().all(Option::is_some);
        let need = if measured {
            MIN_ROWS_WITH_UNCERTAINTY
        } else {
            MIN_ROWS
        };
        if positions.len() < need {
            return Err(at.invalid(
                last_line,
                None,
                format!(
                    "{} rows, but at least {need} are needed to fit a column{}",
                    positions.len(),
                    if measured {
                        " (with its uncertainty)"
                    } else if positions.len() >= MIN_ROWS_WITH_UNCERTAINTY {
                        &*UNCERTAINTY_HINT
                    } else {
                        ""
                    }
                ),
            ));
        }
        let present: Vec<&String> = header.params.iter().map(|(_, n)| n).collect();
        let missing = DIRECTIONS
            .iter()
            .map(|&d| parameter_name(d, axis))
            .filter(|n| !present.contains(&n))
            .collect();
        let first = positions[0];
        let last = positions[positions.len() - 1];
        let one_revolution = axis.is_rotary() && first == 0.0 && (last - 360.0).abs() < 1e-9;
        let columns = header
            .params
            .into_iter()
            .zip(values)
            .zip(uncertainty)
            .map(|(((_, name), values), uncertainty)| TableColumn {
                name,
                values,
                uncertainty,
            })
            .collect();
        Ok(ErrorTable {
            path: path.to_path_buf(),
            axis,
            positions,
            columns,
            missing,
            one_revolution,
            reversal: header.reversal.map(|_| reversal),
            text: source_text,
        })
    }

    /// The column of a parameter (e.g. "EXX"), if measured.
    pub fn column(&self, name: &str) -> Option<&TableColumn> {
        self.columns
            .iter()
            .find(|c| c.name.eq_ignore_ascii_case(name))
    }
}

/// Column `i` as errors name it: its number and its name as written in the file.
fn column_label(raw_names: &[String], i: usize) -> String {
    format!(
        "{} ({})",
        i + 1,
        crate::io::echo(raw_names.get(i).map_or("?", String::as_str))
    )
}

/// Where a table's errors are reported.
struct TableSource<'p> {
    path: &'p Path,
}

impl TableSource<'_> {
    fn invalid(&self, line: usize, column: Option<String>, message: String) -> TableError {
        TableError::Invalid {
            path: self.path.to_path_buf(),
            line,
            column,
            message,
        }
    }
}

/// A table's header: which column is the position, which are parameters (and
/// of which axis), which is the reversal.
struct TableHeader {
    /// The columns as written in the file.
    raw_names: Vec<String>,
    width: usize,
    position: usize,
    /// (column, upper-case parameter name), in file order.
    params: Vec<(usize, String)>,
    /// (column, the parameter's slot in `params`) of each `u_<parameter>`.
    uncertainties: Vec<(usize, usize)>,
    reversal: Option<usize>,
    axis: Axis,
}

impl TableHeader {
    /// Read the header line `text` (line `line`); `axis` None = infer it from
    /// the parameter columns (the last letter shared by every one).
    fn read(
        text: &str,
        line: usize,
        axis: Option<Axis>,
        at: &TableSource,
    ) -> Result<Self, TableError> {
        let names: Vec<String> = text
            .split(',')
            .map(|s| s.trim().to_ascii_uppercase())
            .collect();
        let raw_names: Vec<String> = text.split(',').map(|s| s.trim().to_string()).collect();
        let label = |i: usize| column_label(&raw_names, i);
        let Some(position) = names.iter().position(|n| n == "POSITION") else {
            return Err(at.invalid(
                line,
                None,
                format!(
                    "missing header: expected a `position` column followed by error parameters like EXX, found `{}`",
                    crate::io::echo(text)
                ),
            ));
        };
        let mut inferred: Option<Axis> = axis;
        let mut params: Vec<(usize, String)> = Vec::new();
        let mut reversal: Option<usize> = None;
        let mut u_columns: Vec<(usize, String)> = Vec::new();
        for (i, name) in names.iter().enumerate() {
            if i == position {
                continue;
            }
            if let Some(parameter) = name.strip_prefix("U_") {
                if u_columns.iter().any(|(_, p)| p == parameter) {
                    return Err(at.invalid(
                        line,
                        Some(label(i)),
                        format!("column `{}` appears twice", raw_names[i]),
                    ));
                }
                u_columns.push((i, parameter.to_string()));
                continue;
            }
            if name == "REVERSAL" {
                if reversal.is_some() {
                    return Err(at.invalid(
                        line,
                        Some(label(i)),
                        "column `REVERSAL` appears twice".into(),
                    ));
                }
                reversal = Some(i);
                continue;
            }
            let b = name.as_bytes();
            let valid = b.len() == 3
                && b[0] == b'E'
                && DIRECTIONS.contains(&(b[1] as char))
                && Axis::from_letter(b[2] as char).is_some();
            if !valid {
                return Err(at.invalid(
                    line,
                    Some(label(i)),
                    format!(
                        "unknown column `{}`: expected `position`, E<direction><axis> such as EXX, EAC, or REVERSAL",
                        crate::io::echo(name)
                    ),
                ));
            }
            let col_axis = Axis::from_letter(b[2] as char).unwrap_or(Axis::X);
            match inferred {
                None => inferred = Some(col_axis),
                Some(a) if a != col_axis => {
                    return Err(at.invalid(
                        line,
                        Some(label(i)),
                        format!(
                            "column `{name}` belongs to axis {}, but this is the table of axis {}",
                            col_axis.letter(),
                            a.letter()
                        ),
                    ));
                }
                _ => {}
            }
            if params.iter().any(|(_, n)| n == name) {
                return Err(at.invalid(
                    line,
                    Some(label(i)),
                    format!("column `{name}` appears twice"),
                ));
            }
            params.push((i, name.clone()));
        }
        let Some(axis) = inferred else {
            return Err(at.invalid(line, None, "no error columns: cannot tell the axis (name the columns like EXX or give the axis)".into()));
        };
        let mut uncertainties = Vec::new();
        for (i, parameter) in u_columns {
            let Some(slot) = params.iter().position(|(_, n)| *n == parameter) else {
                return Err(at.invalid(
                    line,
                    Some(label(i)),
                    format!(
                        "column `{}` is the uncertainty of {parameter}, but the table has no {parameter} column",
                        raw_names[i]
                    ),
                ));
            };
            uncertainties.push((i, slot));
        }
        Ok(TableHeader {
            width: names.len(),
            raw_names,
            position,
            params,
            uncertainties,
            reversal,
            axis,
        })
    }

    /// Column `i` as errors name it.
    fn label(&self, i: usize) -> String {
        column_label(&self.raw_names, i)
    }
}
