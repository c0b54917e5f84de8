//! `volcomp diagnose --write-machine OUT.toml`: the machine file with the
//! diagnosed machine errors applied (docs/diagnose.md "Writing the diagnosis
//! back"). The input machine file is copied with its `[squareness]` and
//! `[location]` updated and a comment block on top; its `[errors]` paths are
//! re-written relative to OUT's folder; an axis with a diagnosed backlash gets
//! a copy of its table with a `REVERSAL` column, `OUT.<axis>.csv` next to OUT.
use crate::axes::Axis;
use crate::diagnose::DiagnoseReport;
use crate::diagnose::machine_file::machine_update;
use crate::machine::Machine;
use crate::machine::update::{add_reversal, edit_machine_text, relative_path, toml_path};
use anyhow::Context;
use std::path::{Path, PathBuf};

/// The copy of `axis`'s table that carries a diagnosed reversal: `OUT.x.csv`.
pub(crate) fn table_copy(out: &Path, axis: Axis) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "machine".into());
    out.with_file_name(format!("{stem}.{}.csv", axis.letter().to_ascii_lowercase()))
}

/// Every file `--write-machine OUT` may write (checked before anything is
/// computed): OUT, and a table copy for each linear axis with a table (only
/// those with a diagnosed backlash are written).
pub(crate) fn planned_outputs(out: &Path, machine: &Machine) -> Vec<(String, PathBuf)> {
    let mut files = vec![("--write-machine".to_string(), out.to_path_buf())];
    for axis in [Axis::X, Axis::Y, Axis::Z] {
        if machine.table(axis).is_some() {
            files.push((
                format!(
                    "the {} table with its reversal (--write-machine)",
                    axis.letter()
                ),
                table_copy(out, axis),
            ));
        }
    }
    files
}

/// What was written.
pub(crate) struct Written {
    pub machine: PathBuf,
    pub tables: Vec<PathBuf>,
    pub changes: Vec<String>,
}

/// Write the machine file (and table copies) for `report`. Called inside the
/// command's output set: nothing is in place until it commits.
pub(crate) fn write(
    out: &Path,
    machine: &Machine,
    report: &DiagnoseReport,
    provenance: &[String],
) -> anyhow::Result<Written> {
    let update = machine_update(report, machine, provenance);
    // OUT's folder, resolved; it may not exist yet (made when OUT is written).
    let folder = crate::io::resolved_path(out)
        .and_then(|p| p.parent().map(Path::to_path_buf))
        .with_context(|| {
            format!(
                "--write-machine {}: its folder cannot be found",
                out.display()
            )
        })?;
    let mut edits = update.edits.clone();
    let mut tables = Vec::new();
    for slot in machine.tables.iter().flatten() {
        let axis = slot.axis;
        let key = axis.letter().to_ascii_lowercase().to_string();
        if let Some(reversal) = update.reversal.iter().find(|r| r.axis == axis) {
            let copy = table_copy(out, axis);
            let text = &slot.text;
            let comment = vec![
                format!(
                    "{}: the {} table {} with REVERSAL {:+.2} µm added by `volcomp diagnose --write-machine` ({}).",
                    copy.file_name().unwrap_or_default().to_string_lossy(),
                    axis.letter(),
                    slot.path.display(),
                    reversal.add_um,
                    reversal.note
                ),
                "REVERSAL (formats.md): the positioning error approaching in the positive direction minus in the negative one.".into(),
            ];
            let edited = add_reversal(text, &slot.path, reversal.add_um, &comment)?;
            crate::io::write_file_atomic(&copy, edited.as_bytes())?;
            let name = copy.file_name().unwrap_or_default().to_string_lossy();
            edits.tables.push((key, name.into_owned()));
            tables.push(copy);
        } else {
            let at = std::fs::canonicalize(&slot.path)
                .with_context(|| format!("locating the error table {}", slot.path.display()))?;
            let path = relative_path(&folder, &at).unwrap_or(at);
            edits.tables.push((key, toml_path(&path)));
        }
    }
    let edited = edit_machine_text(&machine.text, &machine.source, &edits)?;
    crate::io::write_file_atomic(out, edited.as_bytes())?;
    Ok(Written {
        machine: out.to_path_buf(),
        tables,
        changes: update.changes,
    })
}
