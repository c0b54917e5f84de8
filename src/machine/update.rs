//! A machine file with corrections applied (`volcomp diagnose --write-machine`):
//! new `[squareness]` and `[location]` values, `[errors]` paths re-pointed (to
//! tables that stay where they are, from the new file's folder, or to copies
//! that carry a `REVERSAL` column), and a leading comment block. Everything else
//! in the file is kept as written (keys, comments, order: the text is edited,
//! not re-serialised).
//!
//! Invariant: pure text in, text out; no I/O.
use std::path::{Component, Path, PathBuf};

/// The edits of one machine file.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MachineEdits {
    /// Lines of the leading comment block (without `# `).
    pub header: Vec<String>,
    /// `[squareness]` keys and their new values, with a note for the line.
    pub squareness: Vec<ValueEdit>,
    /// `[location]` keys and their new values, with a note for the line.
    pub location: Vec<ValueEdit>,
    /// `[errors]` keys (axis letters, lower case) and the path to write.
    pub tables: Vec<(String, String)>,
    /// `[geometry]` keys (mm) and their new values, written to 1e-9 mm
    /// (`export linuxcnc --residual-machine`: the pivots LinuxCNC's module uses).
    pub geometry: Vec<ValueEdit>,
    /// Keys removed: (section, key), e.g. `("reversal", "X")` (matched
    /// without regard to case).
    pub removed: Vec<(String, String)>,
}

/// One value of a table of the machine file.
#[derive(Clone, Debug, PartialEq)]
pub struct ValueEdit {
    pub key: String,
    pub value: f64,
    /// Written as a comment after the value.
    pub note: String,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum UpdateError {
    #[error("{path}: {message}")]
    Machine { path: PathBuf, message: String },
    #[error("{path}: line {line}: {message}")]
    Table {
        path: PathBuf,
        line: usize,
        message: String,
    },
}

/// Values are written to 0.01 µm / µrad (far below any measurement's
/// uncertainty; the file stays readable).
pub fn rounded(v: f64) -> f64 {
    let r = (v * 100.0).round() / 100.0;
    if r == 0.0 { 0.0 } else { r }
}

/// A length as written in `[geometry]`: rounded to 1e-9 mm, no `-0`.
pub fn rounded_mm(v: f64) -> f64 {
    let r = (v * 1e9).round() / 1e9;
    if r == 0.0 { 0.0 } else { r }
}

/// `text` (the machine file read from `path`) with `edits` applied.
pub fn edit_machine_text(
    text: &str,
    path: &Path,
    edits: &MachineEdits,
) -> Result<String, UpdateError> {
    let fail = |message: String| UpdateError::Machine {
        path: path.to_path_buf(),
        message,
    };
    let mut doc: toml_edit::DocumentMut = text
        .parse()
        .map_err(|e: toml_edit::TomlError| fail(e.to_string()))?;
    for (section, values, round) in [
        ("squareness", &edits.squareness, rounded as fn(f64) -> f64),
        ("location", &edits.location, rounded),
        ("geometry", &edits.geometry, rounded_mm),
    ] {
        if values.is_empty() {
            continue;
        }
        let table = doc
            .entry(section)
            .or_insert_with(|| toml_edit::Item::Table(toml_edit::Table::new()));
        let table = table
            .as_table_like_mut()
            .ok_or_else(|| fail(format!("`{section}` is not a table")))?;
        for edit in values {
            let mut value = toml_edit::Value::from(round(edit.value));
            let suffix = if edit.note.is_empty() {
                String::new()
            } else {
                format!("  # {}", edit.note)
            };
            match table.get_mut(&edit.key).and_then(|i| i.as_value_mut()) {
                Some(old) => {
                    let prefix = old
                        .decor()
                        .prefix()
                        .and_then(|p| p.as_str())
                        .unwrap_or(" ")
                        .to_string();
                    value.decor_mut().set_prefix(prefix);
                    if !suffix.is_empty() {
                        value.decor_mut().set_suffix(suffix);
                    } else if let Some(s) = old.decor().suffix().and_then(|s| s.as_str()) {
                        value.decor_mut().set_suffix(s.to_string());
                    }
                    *old = value;
                }
                None => {
                    value.decor_mut().set_prefix(" ");
                    value.decor_mut().set_suffix(suffix);
                    table.insert(&edit.key, toml_edit::Item::Value(value));
                }
            }
        }
    }
    for (section, key) in &edits.removed {
        if let Some(table) = doc.get_mut(section).and_then(|i| i.as_table_like_mut()) {
            let found = table
                .iter()
                .map(|(k, _)| k.to_string())
                .find(|k| k.eq_ignore_ascii_case(key));
            if let Some(k) = found {
                table.remove(&k);
            }
        }
    }
    if !edits.tables.is_empty() {
        let errors = doc
            .get_mut("errors")
            .and_then(|i| i.as_table_like_mut())
            .ok_or_else(|| fail("has no `[errors]` table to re-point".into()))?;
        for (key, new_path) in &edits.tables {
            let key = errors
                .iter()
                .map(|(k, _)| k.to_string())
                .find(|k| k.eq_ignore_ascii_case(key))
                .unwrap_or_else(|| key.clone());
            let old = errors
                .get_mut(&key)
                .and_then(|i| i.as_value_mut())
                .ok_or_else(|| fail(format!("`errors.{key}` is missing")))?;
            let mut value = toml_edit::Value::from(new_path.as_str());
            *value.decor_mut() = old.decor().clone();
            *old = value;
        }
    }
    let mut out = String::new();
    for line in &edits.header {
        if line.is_empty() {
            out.push_str("#\n");
        } else {
            out.push_str("# ");
            out.push_str(line);
            out.push('\n');
        }
    }
    if !edits.header.is_empty() {
        out.push('\n');
    }
    out.push_str(&doc.to_string());
    Ok(out)
}

/// An error table's text with `add` (µm or µrad) added to its `REVERSAL`
/// column at every position (the column is appended, zero before, when the
/// table has none), and `comment` lines (without `# `) put first. Comments,
/// columns and the line ending are kept.
pub fn add_reversal(
    text: &str,
    path: &Path,
    add: f64,
    comment: &[String],
) -> Result<String, UpdateError> {
    let eol = if text.contains("\r\n") { "\r\n" } else { "\n" };
    let mut out = String::new();
    for line in comment {
        out.push_str("# ");
        out.push_str(line);
        out.push_str(eol);
    }
    let mut column: Option<usize> = None;
    let mut appended = false;
    for (k, raw) in text.lines().enumerate() {
        let line = raw.trim_end_matches('\r');
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed.starts_with('#') {
            out.push_str(line);
            out.push_str(eol);
            continue;
        }
        match column {
            None => {
                let names: Vec<&str> = trimmed.split(',').map(str::trim).collect();
                match names
                    .iter()
                    .position(|n| n.eq_ignore_ascii_case("REVERSAL"))
                {
                    Some(i) => {
                        column = Some(i);
                        out.push_str(line);
                    }
                    None => {
                        column = Some(names.len());
                        appended = true;
                        out.push_str(trimmed);
                        out.push_str(",REVERSAL");
                    }
                }
            }
            Some(i) => {
                let mut fields: Vec<String> =
                    trimmed.split(',').map(|s| s.trim().to_string()).collect();
                let old = if appended {
                    fields.push(String::new());
                    0.0
                } else {
                    let field = fields.get(i).ok_or_else(|| UpdateError::Table {
                        path: path.to_path_buf(),
                        line: k + 1,
                        message: format!("no REVERSAL value (column {})", i + 1),
                    })?;
                    field.parse::<f64>().map_err(|_| UpdateError::Table {
                        path: path.to_path_buf(),
                        line: k + 1,
                        message: format!("REVERSAL `{field}` is not a number"),
                    })?
                };
                fields[i] = format!("{:.4}", old + add);
                out.push_str(&fields.join(","));
            }
        }
        out.push_str(eol);
    }
    if column.is_none() {
        return Err(UpdateError::Table {
            path: path.to_path_buf(),
            line: 1,
            message: "empty table: no header".into(),
        });
    }
    Ok(out)
}

/// `target` written relative to the folder `from` (both absolute, as
/// `canonicalize` gives them): `../ref-trt/x.csv`. `None` when they share no
/// folder below the root (then the absolute path is the one to write).
pub fn relative_path(from: &Path, target: &Path) -> Option<PathBuf> {
    let a: Vec<Component> = from.components().collect();
    let b: Vec<Component> = target.components().collect();
    if a.first() != b.first() {
        return None;
    }
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    // Sharing only the root (or a drive): the absolute path says it better.
    if common <= 1 && from.has_root() {
        return None;
    }
    let mut out = PathBuf::new();
    for _ in common..a.len() {
        out.push("..");
    }
    for c in &b[common..] {
        out.push(c.as_os_str());
    }
    Some(out)
}

/// A path as written in a machine file (forward slashes).
pub fn toml_path(path: &Path) -> String {
    path.to_string_lossy().replace('\\', "/")
}

#[cfg(test)]
mod tests {
    use super::*;

    const MACHINE: &str = "name = \"m\" # the name\n\n[errors]\nx = \"t/x.csv\"\n\n[location]\nEY0A = 12.7 # measured 2026\nEZ0A = -3.0\n";

    #[test]
    fn values_are_replaced_added_and_the_rest_kept() {
        let edits = MachineEdits {
            header: vec!["written by a test".into(), String::new()],
            squareness: vec![ValueEdit {
                key: "s_xy".into(),
                value: 40.123,
                note: "diagnosed".into(),
            }],
            location: vec![ValueEdit {
                key: "EY0A".into(),
                value: 32.6049,
                note: "was 12.7".into(),
            }],
            tables: vec![("x".into(), "../t/x.csv".into())],
            geometry: vec![ValueEdit {
                key: "y_offset".into(),
                value: 0.0048000000004,
                note: "moved".into(),
            }],
            removed: vec![("location".into(), "ez0a".into())],
        };
        let out = edit_machine_text(MACHINE, Path::new("m.toml"), &edits).unwrap();
        assert!(out.starts_with("# written by a test\n#\n\nname = \"m\" # the name\n"));
        assert!(out.contains("EY0A = 32.6  # was 12.7\n"), "{out}");
        assert!(!out.contains("EZ0A"), "{out}");
        assert!(
            out.contains("[geometry]\ny_offset = 0.0048  # moved\n"),
            "{out}"
        );
        assert!(out.contains("x = \"../t/x.csv\"\n"), "{out}");
        assert!(
            out.contains("[squareness]\ns_xy = 40.12  # diagnosed\n"),
            "{out}"
        );
        let v: toml::Value = toml::from_str(&out).unwrap();
        assert_eq!(v["location"]["EY0A"].as_float(), Some(32.6));
    }

    #[test]
    fn a_reversal_column_is_appended_or_added_to() {
        let table = "# measured\nposition,EXX\r\n0,1.5\r\n10,2.0\r\n";
        let out = add_reversal(table, Path::new("x.csv"), 6.25, &["note".into()]).unwrap();
        assert_eq!(
            out,
            "# note\r\n# measured\r\nposition,EXX,REVERSAL\r\n0,1.5,6.2500\r\n10,2.0,6.2500\r\n"
        );
        let again = add_reversal(&out, Path::new("x.csv"), -1.0, &[]).unwrap();
        assert!(again.contains("0,1.5,5.2500\r\n"), "{again}");
        assert!(matches!(
            add_reversal("position,REVERSAL\n0,a\n", Path::new("x.csv"), 1.0, &[]),
            Err(UpdateError::Table { line: 2, .. })
        ));
    }

    #[test]
    fn relative_paths_climb_to_the_common_folder() {
        let r = relative_path(Path::new("/w/out/sub"), Path::new("/w/machines/t/x.csv"));
        assert_eq!(r, Some(PathBuf::from("../../machines/t/x.csv")));
        let r = relative_path(Path::new("/w/machines"), Path::new("/w/machines/t/x.csv"));
        assert_eq!(r, Some(PathBuf::from("t/x.csv")));
        assert_eq!(
            relative_path(Path::new("/tmp/o"), Path::new("/w/t/x.csv")),
            None
        );
    }
}
