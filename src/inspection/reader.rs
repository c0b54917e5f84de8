//! A small CSV record reader for plans and measurements: header with named
//! columns (any order, extra columns ignored), `#` comment lines and blank lines
//! skipped, a leading byte order mark ignored, every error naming file, line and
//! column.
//!
//! Invariant: a returned record holds exactly the requested columns, parsed as
//! finite `f64` (except the `id` column, kept as text).
use super::InspectionError;
use std::path::Path;

/// One data row: its 1-based line number, the id text and the numeric fields in
/// the order of the requested numeric columns.
#[derive(Clone, Debug)]
pub struct Record {
    pub line: usize,
    pub id: String,
    pub values: Vec<f64>,
}

/// Parse `text` (the content of `path`) requiring column `id` and the numeric
/// `columns`.
pub fn read_records(
    path: &Path,
    text: &str,
    columns: &[&str],
) -> Result<Vec<Record>, InspectionError> {
    let mut header: Option<(usize, Vec<usize>)> = None;
    let mut records = Vec::new();
    // A byte order mark (spreadsheets write one) is not part of the header.
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        if let Some(message) = crate::io::long_line(raw) {
            return Err(InspectionError::Field {
                path: path.to_path_buf(),
                line,
                column: "(the whole line)".into(),
                message,
            });
        }
        let trimmed = raw.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = trimmed.split(',').map(str::trim).collect();
        match &header {
            None => {
                let find = |name: &str| {
                    fields
                        .iter()
                        .position(|f| f.eq_ignore_ascii_case(name))
                        .ok_or_else(|| InspectionError::Header {
                            path: path.to_path_buf(),
                            line,
                            missing: name.to_string(),
                            expected: std::iter::once("id")
                                .chain(columns.iter().copied())
                                .collect::<Vec<_>>()
                                .join(","),
                        })
                };
                let mut positions = vec![find("id")?];
                for c in columns {
                    positions.push(find(c)?);
                }
                header = Some((fields.len(), positions));
            }
            Some((_, positions)) => {
                let get = |k: usize| -> Result<&str, InspectionError> {
                    let col = positions[k];
                    let name = if k == 0 { "id" } else { columns[k - 1] };
                    fields
                        .get(col)
                        .copied()
                        .ok_or_else(|| InspectionError::Field {
                            path: path.to_path_buf(),
                            line,
                            column: name.to_string(),
                            message: format!(
                                "the row has {} fields, column `{name}` is field {}",
                                fields.len(),
                                col + 1
                            ),
                        })
                };
                let id = get(0)?.to_string();
                if id.is_empty() {
                    return Err(InspectionError::Field {
                        path: path.to_path_buf(),
                        line,
                        column: "id".into(),
                        message: "expected a non-empty point id".into(),
                    });
                }
                let mut values = Vec::with_capacity(columns.len());
                for (k, name) in columns.iter().enumerate() {
                    let text = get(k + 1)?;
                    let v: f64 = text.parse().map_err(|_| InspectionError::Field {
                        path: path.to_path_buf(),
                        line,
                        column: name.to_string(),
                        message: format!("expected a number, found `{}`", crate::io::echo(text)),
                    })?;
                    if !v.is_finite() {
                        return Err(InspectionError::Field {
                            path: path.to_path_buf(),
                            line,
                            column: name.to_string(),
                            message: format!(
                                "expected a finite number, found `{}`",
                                crate::io::echo(text)
                            ),
                        });
                    }
                    values.push(v);
                }
                records.push(Record { line, id, values });
            }
        }
    }
    if header.is_none() {
        return Err(InspectionError::Header {
            path: path.to_path_buf(),
            line: 1,
            missing: "id".into(),
            expected: std::iter::once("id")
                .chain(columns.iter().copied())
                .collect::<Vec<_>>()
                .join(","),
        });
    }
    Ok(records)
}
