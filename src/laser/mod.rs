//! Laser-interferometer measurements in: bidirectional positioning runs (and
//! straightness or angular runs of the same instrument) read from the files
//! laser software writes, evaluated as ISO 230-2 does, and turned into the
//! axis's error table (formats.md "Laser positioning runs and reversal").
//!
//! `read` parses one file into readings in volcomp's units; [`evaluate`] groups
//! the readings of all files by parameter and target, checks that every target
//! has both approaches and every parameter the same targets, and computes the
//! statistics (`iso230`); [`LaserImport::table_csv`] writes the table
//! (`position`, the parameters, and `REVERSAL` for the positioning parameter).
//!
//! Invariants: no I/O beyond reading the named files; nothing printed; every
//! error names a file, line and column.
pub(crate) mod iso230;
pub(crate) mod read;
pub(crate) mod vocabulary;

use std::collections::{HashMap, HashSet};
use std::fmt::Write as _;
use std::path::PathBuf;

use crate::axes::Axis;
pub use iso230::{AxisFigures, TargetStats, axis_figures, target_stats};
pub use read::{
    DecimalMark, FileIdentity, FileReadings, LaserError, Layout, MAX_DEVIATION, MAX_PREAMBLE_LINES,
    MAX_TARGET_DEG, MAX_TARGET_MM, OtherColumn, ReadSettings, Reading, is_angular, is_parameter_of,
    parse, parse_direction, positioning_parameter, read_file,
};

/// What one file contributed.
#[derive(Clone, Debug, serde::Serialize)]
pub struct FileSummary {
    /// The file.
    pub path: PathBuf,
    /// The parameter its deviations measure (`EXX`, …).
    pub parameter: String,
    /// Its header layout.
    pub layout: Layout,
    /// Line of its header.
    pub header_line: usize,
    /// Its field separator (`,`, `;` or `tab`).
    pub separator: String,
    /// The decimal mark it writes (decided by its first number that writes one).
    pub decimal_mark: DecimalMark,
    /// `UTF-8`, or `Latin-1` when a line was not UTF-8.
    pub encoding: &'static str,
    /// The unit of its targets as the file gave it (empty: volcomp's default).
    pub target_unit: String,
    /// The unit of its deviations as the file gave it (empty: volcomp's default).
    pub deviation_unit: String,
    /// The line of its units line, if it had one.
    pub units_line: Option<usize>,
    /// Number of readings read from it.
    pub readings: usize,
    /// The export's metadata lines before the header.
    pub preamble: Vec<String>,
    /// Its columns that hold no reading (temperatures, comments), by name.
    pub other_columns: Vec<OtherColumn>,
}

/// One measured parameter over all its files.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ParameterResult {
    /// The parameter (`EXX`, `EYX`, `EAA`, …).
    pub parameter: String,
    /// `µm` or `µrad`.
    pub unit: &'static str,
    /// Distinct runs approaching in each direction (over all files).
    pub runs_up: usize,
    /// Distinct runs approaching in the negative direction.
    pub runs_down: usize,
    /// The ISO 230-2 figures of the axis.
    pub figures: AxisFigures,
    /// Ascending targets.
    pub targets: Vec<TargetStats>,
}

/// The evaluated import: what the table and the report are written from.
#[derive(Clone, Debug, serde::Serialize)]
pub struct LaserImport {
    /// The measured axis.
    pub axis: Axis,
    /// What each file contributed, in the order given.
    pub files: Vec<FileSummary>,
    /// The axis's positioning parameter first (when measured), then file order.
    pub parameters: Vec<ParameterResult>,
}

/// A fast hash for the small integer keys of [`evaluate`] (a million readings:
/// SipHash was half the import's time). Not for untrusted keys' DoS resistance:
/// the worst case is slower, never wrong.
#[derive(Default)]
struct KeyHasher(u64);

impl std::hash::Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u8(&mut self, i: u8) {
        self.write_u64(u64::from(i));
    }
    fn write_u32(&mut self, i: u32) {
        self.write_u64(u64::from(i));
    }
    fn write_usize(&mut self, i: usize) {
        self.write_u64(i as u64);
    }
    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(26) ^ i).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

type FastMap<K, V> = HashMap<K, V, std::hash::BuildHasherDefault<KeyHasher>>;
type FastSet<K> = HashSet<K, std::hash::BuildHasherDefault<KeyHasher>>;

/// Accumulated deviations of one target.
struct TargetAcc {
    target: f64,
    up: Vec<f64>,
    down: Vec<f64>,
    /// First reading: (file, line).
    first: (usize, u32),
}

/// Group `files` by parameter and target and evaluate them.
pub fn evaluate(axis: Axis, files: Vec<FileReadings>) -> Result<LaserImport, LaserError> {
    distinct_files(&files)?;
    let positioning = positioning_parameter(axis);
    let mut order: Vec<String> = Vec::new();
    for f in &files {
        if !order.contains(&f.parameter) {
            order.push(f.parameter.clone());
        }
    }
    order.sort_by_key(|p| *p != positioning);
    let mut parameters: Vec<ParameterResult> = Vec::new();
    for parameter in &order {
        let grouped = group_targets(&files, parameter)?;
        let stats: Vec<TargetStats> = grouped
            .targets
            .iter()
            .map(|t| iso230::target_stats(t.target, &t.up, &t.down))
            .collect();
        if let Some(first) = parameters.first() {
            same_targets(first, parameter, &stats)?;
        }
        parameters.push(ParameterResult {
            parameter: parameter.clone(),
            unit: if is_angular(parameter) {
                "µrad"
            } else {
                "µm"
            },
            runs_up: grouped.runs_up,
            runs_down: grouped.runs_down,
            figures: iso230::axis_figures(&stats),
            targets: stats,
        });
    }
    let files = files
        .into_iter()
        .map(|f| FileSummary {
            separator: match f.separator {
                '\t' => "tab".into(),
                c => c.to_string(),
            },
            readings: f.readings.len(),
            path: f.path,
            parameter: f.parameter,
            layout: f.layout,
            header_line: f.header_line,
            decimal_mark: f.decimal_mark,
            encoding: f.encoding,
            target_unit: f.target_unit,
            deviation_unit: f.deviation_unit,
            units_line: f.units_line,
            preamble: f.preamble,
            other_columns: f.other_columns,
        })
        .collect();
    Ok(LaserImport {
        axis,
        files,
        parameters,
    })
}

/// One measurement counts once: a file given twice (the same device and
/// inode: the same path, another spelling of it, a link) or two files of the
/// same bytes are an error naming both.
fn distinct_files(files: &[FileReadings]) -> Result<(), LaserError> {
    for (j, b) in files.iter().enumerate() {
        for (i, a) in files[..j].iter().enumerate() {
            let same_file = a.identity.device_inode.is_some()
                && a.identity.device_inode == b.identity.device_inode;
            let same_bytes =
                a.identity.length == b.identity.length && a.identity.fnv1a64 == b.identity.fnv1a64;
            if same_file || same_bytes {
                return Err(LaserError::Data(format!(
                    "{} (file {}) {} {} (file {}): one measurement counts once; give each file once",
                    b.path.display(),
                    j + 1,
                    if same_file {
                        "is the same file as"
                    } else {
                        "has the same bytes as"
                    },
                    a.path.display(),
                    i + 1
                )));
            }
        }
    }
    Ok(())
}

/// One parameter's readings grouped by target (ascending), and its runs.
struct Grouped {
    targets: Vec<TargetAcc>,
    runs_up: usize,
    runs_down: usize,
}

/// `file:line:column` of a reading of `files[file]`.
fn place(files: &[FileReadings], file: usize, line: u32, column: u32) -> String {
    format!("{}:{line}:{column}", files[file].path.display())
}

fn approach_words(up: bool) -> &'static str {
    if up {
        "from below (+)"
    } else {
        "from above (-)"
    }
}

/// Group the readings of `parameter` over `files` by target: a run that
/// approaches a target twice the same way, a target without both approaches,
/// or fewer targets than a table needs are errors.
fn group_targets(files: &[FileReadings], parameter: &str) -> Result<Grouped, LaserError> {
    let mut index: FastMap<u64, usize> = FastMap::default();
    let mut targets: Vec<TargetAcc> = Vec::new();
    let mut seen: FastMap<(u64, usize, u32, bool), (u32, u32)> = FastMap::default();
    let mut runs: FastSet<(usize, u32, bool)> = FastSet::default();
    let mut last_run = None;
    for (fi, f) in files.iter().enumerate() {
        if f.parameter != parameter {
            continue;
        }
        seen.reserve(f.readings.len());
        for r in &f.readings {
            let target = if r.target == 0.0 { 0.0 } else { r.target };
            let key = target.to_bits();
            if let Some((line, column)) = seen.insert((key, fi, r.run, r.up), (r.line, r.column)) {
                return Err(LaserError::Data(format!(
                    "{}: run {} approaches target {target} {} a second time (first at {})",
                    place(files, fi, r.line, r.column),
                    r.run,
                    approach_words(r.up),
                    place(files, fi, line, column)
                )));
            }
            if last_run != Some((fi, r.run, r.up)) {
                runs.insert((fi, r.run, r.up));
                last_run = Some((fi, r.run, r.up));
            }
            let k = *index.entry(key).or_insert_with(|| {
                targets.push(TargetAcc {
                    target,
                    up: Vec::new(),
                    down: Vec::new(),
                    first: (fi, r.line),
                });
                targets.len() - 1
            });
            if r.up {
                targets[k].up.push(r.deviation);
            } else {
                targets[k].down.push(r.deviation);
            }
        }
    }
    drop(seen);
    targets.sort_by(|a, b| a.target.total_cmp(&b.target));
    for t in &targets {
        if t.up.is_empty() || t.down.is_empty() {
            return Err(LaserError::Data(format!(
                "{}: {parameter} at target {} has no reading approached {} (every target needs both approaches, + and -)",
                place(files, t.first.0, t.first.1, 1),
                t.target,
                approach_words(t.up.is_empty())
            )));
        }
    }
    if targets.len() < crate::machine::table::MIN_ROWS_WITH_UNCERTAINTY {
        let fi = files
            .iter()
            .position(|f| f.parameter == parameter)
            .unwrap_or(0);
        return Err(LaserError::Data(format!(
            "{}: {parameter} has {} targets, but an error table needs at least {} to be fitted",
            files[fi].path.display(),
            targets.len(),
            crate::machine::table::MIN_ROWS_WITH_UNCERTAINTY
        )));
    }
    let runs_up = runs.iter().filter(|r| r.2).count();
    Ok(Grouped {
        targets,
        runs_up,
        runs_down: runs.len() - runs_up,
    })
}

/// Every parameter of one table must be measured at the first one's targets.
fn same_targets(
    first: &ParameterResult,
    parameter: &str,
    stats: &[TargetStats],
) -> Result<(), LaserError> {
    let a: Vec<f64> = first.targets.iter().map(|t| t.target).collect();
    let b: Vec<f64> = stats.iter().map(|t| t.target).collect();
    if a == b {
        return Ok(());
    }
    let odd = b
        .iter()
        .find(|t| !a.contains(t))
        .map(|t| format!("target {t} is not among {}'s", first.parameter))
        .or_else(|| {
            a.iter()
                .find(|t| !b.contains(t))
                .map(|t| format!("{}'s target {t} is missing", first.parameter))
        })
        .unwrap_or_default();
    Err(LaserError::Data(format!(
        "{parameter} and {} were measured at different targets ({odd}); one table needs the same positions for every column",
        first.parameter
    )))
}

impl ParameterResult {
    /// Every target has two runs or more in each direction: the table gets
    /// the parameter's `u_` column.
    pub fn has_uncertainty(&self) -> bool {
        self.targets.iter().all(|t| t.uncertainty.is_some())
    }
}

impl LaserImport {
    /// The axis's error table (formats.md "Error table", with `REVERSAL`):
    /// `position`, each parameter's mean bidirectional deviation, and after the
    /// positioning parameter its reversal value B_i.
    pub fn table_csv(&self) -> String {
        let mut out = String::new();
        let positioning = positioning_parameter(self.axis);
        let _ = writeln!(
            out,
            "# volcomp import-laser: axis {}, {} file{}; mean bidirectional deviation per target (ISO 230-2 x̄_i){}{}",
            self.axis.letter(),
            self.files.len(),
            if self.files.len() == 1 { "" } else { "s" },
            if self.parameters.iter().any(|p| p.parameter == positioning) {
                "; REVERSAL = x̄_i↑ − x̄_i↓ (B_i)"
            } else {
                ""
            },
            if self.parameters.iter().any(ParameterResult::has_uncertainty) {
                "; u_<parameter> = ½√(s_i↑²/n↑ + s_i↓²/n↓), the standard uncertainty of x̄_i"
            } else {
                ""
            }
        );
        let mut header = vec!["position".to_string()];
        for p in &self.parameters {
            header.push(p.parameter.clone());
            if p.parameter == positioning {
                header.push("REVERSAL".into());
            }
            if p.has_uncertainty() {
                header.push(format!("u_{}", p.parameter));
            }
        }
        let _ = writeln!(out, "{}", header.join(","));
        let Some(first) = self.parameters.first() else {
            return out;
        };
        for (i, t) in first.targets.iter().enumerate() {
            let _ = write!(out, "{}", t.target);
            for p in &self.parameters {
                let s = &p.targets[i];
                let _ = write!(out, ",{:.4}", s.mean + 0.0);
                if p.parameter == positioning {
                    let _ = write!(out, ",{:.4}", s.reversal + 0.0);
                }
                if let (true, Some(u)) = (p.has_uncertainty(), s.uncertainty) {
                    let _ = write!(out, ",{:.4}", u + 0.0);
                }
            }
            out.push('\n');
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn a_target_without_a_down_run_is_named() {
        let mut text = String::from("target,run,direction,deviation\n");
        for t in 0..8 {
            text.push_str(&format!("{t},1,+,1\n"));
            if t != 5 {
                text.push_str(&format!("{t},1,-,0\n"));
            }
        }
        let settings = ReadSettings {
            axis: Axis::X,
            parameter: None,
        };
        let f = read::parse(&text, Path::new("l.csv"), &settings).unwrap();
        let e = evaluate(Axis::X, vec![f]).unwrap_err().to_string();
        assert!(
            e.starts_with("l.csv:12:1: EXX at target 5 has no reading approached from above (-)"),
            "{e}"
        );
    }
}
