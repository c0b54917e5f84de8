//! `volcomp import-laser`: laser positioning runs in, the axis's error table and
//! the ISO 230-2 report out (formats.md "Laser positioning runs and reversal").
use crate::axes::Axis;
use crate::laser::{ReadSettings, evaluate, is_parameter_of, positioning_parameter, read_file};
use std::path::{Path, PathBuf};

pub const EXAMPLES: &str = "\
  volcomp import-laser tests/data/laser/x-long.csv --axis X -o x.csv --report x-iso230.json
  volcomp import-laser tests/data/laser/x-long.csv tests/data/laser/x-paired.csv --axis X -o x.csv
  volcomp import-laser tests/data/laser/x-long.csv EYX=tests/data/laser/x-straightness-eyx.csv EBX=tests/data/laser/x-pitch-ebx.csv --axis X -o x.csv";

const AFTER_HELP: &str = "\
Each FILE holds bidirectional runs in one of three layouts (docs/extensions.md):
  long    target,run,direction,deviation      one reading a row (direction + - up down fwd rev)
  paired  target,run,+,-                      a target and run a row, both approaches
  wide    target,run 1 +,run 1 -,run 2 +,...  a target a row, a column per run and direction
English or German names (Sollposition, Lauf, Richtung, Abweichung; vorwärts/rückwärts,
hin/rück, ↑/↓). Metadata lines before the header are kept in the report; columns that
are not readings (temperatures, comments) are kept by name. Separators , ; or tab; a
decimal point or comma, one per file; # comments; UTF-8 or Latin-1 text. Units in the
header cell or a units line under it: target [mm] [in] or [deg]; deviations [µm] [um]
[nm] [mm] [in] [mil] [µin] for lengths, [µrad] [urad] [mrad] [arcsec] [mm/m] [µm/m] for
angles (default mm or deg, µm or µrad). Rows may come in any order. A file given twice
(the same file or the same bytes) is an error.

A FILE measures the axis's positioning error (EXX for X, EAA for A) unless it is
given as PARAM=FILE (EYX=..., EBX=...) or its deviation column is named after the
parameter (target,run,direction,EYX [µm]). Several files of one parameter are
pooled (their runs kept apart). The table has position, each parameter's mean
bidirectional deviation (ISO 230-2 x̄_i) and, after the positioning parameter,
REVERSAL (B_i = x̄_i↑ − x̄_i↓). The report gives A, B, E, M, R per parameter and the
statistics of every target.";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// Laser files: FILE, or PARAM=FILE for a straightness or angular run (EYX=x-straight.csv).
    #[arg(required = true, value_name = "FILE")]
    pub files: Vec<String>,
    /// The axis measured (X Y Z A B C U V W).
    #[arg(long, value_parser = parse_axis)]
    pub axis: Axis,
    /// The error table to write (`-`: standard output).
    #[arg(short, long, value_name = "TABLE.csv")]
    pub output: PathBuf,
    /// The ISO 230-2 report (JSON; `-`: standard output).
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
}

fn parse_axis(text: &str) -> Result<Axis, String> {
    let mut chars = text.trim().chars();
    match (chars.next().and_then(Axis::from_letter), chars.next()) {
        (Some(a), None) => Ok(a),
        _ => Err(format!(
            "`{text}` is not an axis letter (X Y Z A B C U V W)"
        )),
    }
}

/// `PARAM=FILE` → (Some(PARAM), FILE); anything else is a path.
fn split_source(arg: &str) -> (Option<String>, PathBuf) {
    if let Some((p, f)) = arg.split_once('=') {
        let upper = p.trim().to_ascii_uppercase();
        let b = upper.as_bytes();
        if b.len() == 3 && b[0] == b'E' && !f.is_empty() {
            return (Some(upper), PathBuf::from(f));
        }
    }
    (None, PathBuf::from(arg))
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let to_stdout = super::common::stdout_output(&[
        ("-o", super::common::is_stdout(Some(&args.output))),
        ("--report", super::common::is_stdout(args.report.as_deref())),
    ])?;
    // Every output against every input (the laser files, through links) and
    // the other output, before anything is read.
    let mut check = super::common::CommandFiles::new();
    for arg in &args.files {
        check = check.input("the laser file", Some(&split_source(arg).1));
    }
    check
        .output("-o", Some(&args.output))
        .output("--report", args.report.as_deref())
        .check()?;
    let mut files = Vec::new();
    for arg in &args.files {
        let (parameter, path) = split_source(arg);
        if let Some(p) = &parameter {
            if !is_parameter_of(p, args.axis) {
                return Err(super::UsageError(format!(
                    "`{arg}`: {p} is not an error parameter of axis {} (E<direction>{}, e.g. {})",
                    args.axis.letter(),
                    args.axis.letter(),
                    positioning_parameter(args.axis)
                ))
                .into());
            }
        }
        let settings = ReadSettings {
            axis: args.axis,
            parameter,
        };
        files.push(read_file(&path, &settings)?);
    }
    let import = evaluate(args.axis, files)?;
    let table = import.table_csv();
    // Both outputs are made before either is written: a failure leaves neither.
    let report = args
        .report
        .as_ref()
        .map(|_| {
            serde_json::to_string_pretty(&import).map(|mut s| {
                s.push('\n');
                s
            })
        })
        .transpose()?;
    // Both or neither: a report that cannot be written leaves -o as it was.
    let outputs = crate::io::OutputSet::begin();
    crate::io::write_file_atomic(&args.output, table.as_bytes())?;
    if let (Some(path), Some(text)) = (&args.report, &report) {
        crate::io::write_file_atomic(path, text.as_bytes())?;
    }
    outputs.commit()?;
    let layouts: Vec<&str> = import.files.iter().map(|f| f.layout.name()).collect();
    let first = &import.parameters[0];
    crate::cli::humanln!(
        to_stdout,
        "axis {}: {} ({}), {} targets from {} to {} {}",
        args.axis.letter(),
        super::common::count(import.files.len() as u64, "file", "files"),
        layouts.join(", "),
        first.targets.len(),
        first.targets[0].target,
        first.targets[first.targets.len() - 1].target,
        args.axis.unit()
    );
    for f in &import.files {
        crate::cli::humanln!(to_stdout, "{}", file_summary(f, args.axis));
    }
    for p in &import.parameters {
        let f = &p.figures;
        let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
        crate::cli::humanln!(
            to_stdout,
            "{} ({}, {} runs +, {} runs -): A {}  B {:.2} (mean {:.2})  E {:.2}  M {:.2}  R {}",
            p.parameter,
            p.unit,
            p.runs_up,
            p.runs_down,
            opt(f.accuracy),
            f.reversal,
            f.mean_reversal,
            f.systematic,
            f.mean_range,
            opt(f.repeatability)
        );
        if f.accuracy.is_none() {
            crate::cli::humanln!(
                to_stdout,
                "note: {}: A and R need at least two runs in each direction at every target",
                p.parameter
            );
        }
    }
    let columns: Vec<&str> = table
        .lines()
        .find(|l| !l.starts_with('#'))
        .map(|h| h.split(',').skip(1).collect())
        .unwrap_or_default();
    if !super::common::is_stdout(Some(&args.output)) {
        crate::cli::humanln!(
            to_stdout,
            "wrote {} ({} positions: {})",
            display(&args.output),
            first.targets.len(),
            columns.join(", ")
        );
    }
    if let Some(path) = args.report.as_deref().filter(|p| !crate::io::is_stdio(p)) {
        crate::cli::humanln!(to_stdout, "wrote {}", display(path));
    }
    Ok(())
}

/// One file as read: its parameter, layout, separator, decimal mark, units,
/// and what it held besides readings.
fn file_summary(f: &crate::laser::FileSummary, axis: Axis) -> String {
    let mut parts = vec![
        format!("{} {}", f.parameter, f.layout.name()),
        format!("separator {}", f.separator),
        f.decimal_mark.describe().to_string(),
    ];
    if f.encoding != "UTF-8" {
        parts.push(format!("{} text", f.encoding));
    }
    let unit = |u: &str, default: &str| {
        if u.is_empty() {
            format!("{default} (no unit given)")
        } else {
            u.to_string()
        }
    };
    let deviation_default = if crate::laser::is_angular(&f.parameter) {
        "µrad"
    } else {
        "µm"
    };
    parts.push(format!(
        "targets {}, deviations {}{}",
        unit(&f.target_unit, axis.unit()),
        unit(&f.deviation_unit, deviation_default),
        f.units_line
            .map_or(String::new(), |l| format!(" (units line {l})"))
    ));
    if !f.preamble.is_empty() {
        parts.push(format!(
            "{} before the header (in the report)",
            super::common::count(f.preamble.len() as u64, "line", "lines")
        ));
    }
    if !f.other_columns.is_empty() {
        let names: Vec<String> = f
            .other_columns
            .iter()
            .map(|c| match c.range {
                Some([lo, hi]) if lo == hi => format!("`{}` {lo}", c.name),
                Some([lo, hi]) => format!("`{}` {lo} to {hi}", c.name),
                None => format!("`{}`", c.name),
            })
            .collect();
        parts.push(format!(
            "not readings (kept in the report): {}",
            names.join(", ")
        ));
    }
    format!("{}: {}", display(&f.path), parts.join("; "))
}

fn display(path: &Path) -> String {
    path.display().to_string()
}
