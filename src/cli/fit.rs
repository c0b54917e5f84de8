//! `volcomp fit`: the SMEM of every error table of a machine, or of one table.
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use rayon::prelude::*;

use crate::axes::Axis;
use crate::machine::table::ErrorTable;
use crate::nurbs::{
    FitOptions, KnotMethod, ParameterFit, ParameterKind, Selection, SmemModelFile, fnv1a64,
};
use crate::report::fit_plot::{PlotLabels, plot_fit};

pub const EXAMPLES: &str = "\
  volcomp fit machines/ref-trt.toml
  volcomp fit machines/ref-trt.toml --report fit.json --plot fit-plots
  volcomp fit machines/ref-trt/x.csv --select emax --method ga --seed 7
  volcomp fit machines/ref-trt/a.csv --select emax --tol 0.5 --tol-angle 1.0 --method ukm";

const AFTER_HELP: &str = "\
Each measured column is fitted with a cubic NURBS. By default (--select cv) the curve
follows the machine, not the measurement noise: a penalised cubic B-spline whose number
of control points and smoothness minimise generalised cross-validation, smoothing less
where the curve bends (a locally adaptive penalty), periodic over a full C turn. The
table shows each parameter's estimated noise (from the data alone), the effective
number of parameters (dof) and the cross-validated error (cv: the expected RMS error at
a new measurement of that table).

--select emax is the paper's (He et al. 2016): knots by --method, weights optimised,
control points added until the largest error at the measured points is within tolerance
(default 0.5 µm for lengths, 1.0 µrad for angles). A parameter that misses its tolerance
is reported and makes the command fail (exit 1) after the report is written.";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// A machine file (TOML, its [errors] tables are fitted) or one error table (CSV).
    pub input: PathBuf,
    /// How each curve's complexity is chosen: cv (cross-validation, noise-aware)
    /// or emax (the paper's tolerance on the largest error).
    #[arg(long, default_value = "cv", value_name = "cv|emax")]
    pub select: Selection,
    /// Tolerance on the largest error at the measured points, in table units
    /// (µm for lengths; also µrad for angles unless --tol-angle is given).
    /// With --select emax.
    #[arg(long, value_name = "UM")]
    pub tol: Option<f64>,
    /// Tolerance for angular parameters, urad. With --select emax.
    #[arg(long, value_name = "URAD")]
    pub tol_angle: Option<f64>,
    /// Knot placement: ukm, epm, lam, ga, exhaustive or best (the default).
    /// With --select emax.
    #[arg(long)]
    pub method: Option<KnotMethod>,
    /// Fixed number of control points (no adaptive growth).
    #[arg(long, value_name = "N")]
    pub control_points: Option<usize>,
    /// Segments M of the candidate-knot grid (ga, exhaustive, best).
    /// With --select emax.
    #[arg(long, value_name = "M")]
    pub grid: Option<usize>,
    /// Keep all weights at 1 (plain B-spline fits). With --select emax.
    #[arg(long)]
    pub no_weights: bool,
    /// Seed of the genetic algorithm and the optimiser's random restarts
    /// (default 2016). With --select emax.
    #[arg(long)]
    pub seed: Option<u64>,
    /// Axis of a CSV table (default: inferred from the column names).
    #[arg(long, value_name = "AXIS", value_parser = parse_axis)]
    pub axis: Option<Axis>,
    /// Write the fit report (JSON) here.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Write one SVG per parameter (points, curve, knots) into this directory.
    #[arg(long, value_name = "DIR")]
    pub plot: Option<PathBuf>,
}

fn parse_axis(s: &str) -> Result<Axis, String> {
    let mut chars = s.chars();
    match (chars.next().and_then(Axis::from_letter), chars.next()) {
        (Some(a), None) => Ok(a),
        _ => Err(format!("`{s}` is not an axis (X, Y, Z, A or C)")),
    }
}

/// The tables to fit: from a machine file or a single CSV.
fn load_tables(args: &Args) -> anyhow::Result<Vec<ErrorTable>> {
    let is_toml = args
        .input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
    if is_toml {
        if args.axis.is_some() {
            return Err(super::UsageError(
                "--axis applies to a CSV table, not a machine file".into(),
            )
            .into());
        }
        let machine = crate::machine::Machine::load(&args.input)?;
        Ok(machine.tables.into_iter().flatten().collect())
    } else {
        Ok(vec![ErrorTable::read(&args.input, args.axis)?])
    }
}

/// The fit of one column of a table.
struct Job<'a> {
    table: &'a ErrorTable,
    column: usize,
    kind: ParameterKind,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let started = Instant::now();
    check_arguments(args)?;
    // The human table goes to standard error when the report goes to
    // standard output.
    let data_on_stdout = super::common::is_stdout(args.report.as_deref());
    let tables = load_tables(args)?;
    let base = fit_options(args);
    let jobs = column_jobs(&tables);
    check_files(args, &tables, &jobs)?;
    let outputs = crate::io::OutputSet::begin();
    let hashes = table_hashes(&tables)?;
    let counter = std::sync::Arc::new(crate::progress::WorkCounter::new());
    counter.add_total(jobs.len() as u64);
    let what = format!("fitting {}", crate::io::display_name(&args.input));
    let fits = super::common::with_progress(&what, &counter, || {
        fit_columns(args, &base, &jobs, &counter)
    })?;
    let cv = args.select == Selection::Cv;
    let report = report_fits(data_on_stdout, cv, &tables, &jobs, &fits, &hashes)?;
    let missed: Vec<&str> = report
        .parameters
        .iter()
        .filter(|p| !cv && !p.stats.met)
        .map(|p| p.parameter.as_str())
        .collect();
    let seconds = started.elapsed().as_secs_f64();
    if cv {
        crate::cli::humanln!(
            data_on_stdout,
            "{} parameters fitted by cross-validation in {seconds:.2} s",
            report.parameters.len(),
        );
    } else {
        crate::cli::humanln!(
            data_on_stdout,
            "{} parameters fitted with method {} in {seconds:.2} s; {} within tolerance",
            report.parameters.len(),
            base.method,
            report.parameters.len() - missed.len()
        );
    }
    if let Some(path) = &args.report {
        crate::io::write_json_atomic(path, &report)?;
        crate::cli::humanln!(data_on_stdout, "report: {}", path.display());
    }
    if let Some(dir) = &args.plot {
        write_plots(dir, &jobs, &fits)?;
        crate::cli::humanln!(data_on_stdout, "plots: {}", dir.display());
    }
    outputs.commit()?;
    if !missed.is_empty() {
        anyhow::bail!(
            "{} parameter(s) miss their tolerance: {} (raise --tol or the control-point cap)",
            missed.len(),
            missed.join(", ")
        );
    }
    Ok(())
}

/// The usage errors: tolerances that are not positive, and the paper's
/// options without `--select emax`.
fn check_arguments(args: &Args) -> anyhow::Result<()> {
    for (name, v) in [("--tol", args.tol), ("--tol-angle", args.tol_angle)] {
        if let Some(t) = v {
            if !(t.is_finite() && t > 0.0) {
                return Err(super::UsageError(format!(
                    "{name} must be a positive number, got {t}"
                ))
                .into());
            }
        }
    }
    if args.select == Selection::Cv {
        let emax_only = [
            ("--tol", args.tol.is_some()),
            ("--tol-angle", args.tol_angle.is_some()),
            ("--method", args.method.is_some()),
            ("--grid", args.grid.is_some()),
            ("--no-weights", args.no_weights),
            ("--seed", args.seed.is_some()),
        ];
        let given: Vec<&str> = emax_only
            .iter()
            .filter(|(_, g)| *g)
            .map(|(n, _)| *n)
            .collect();
        if !given.is_empty() {
            return Err(super::UsageError(format!(
                "{} belong(s) to the paper's selection: add --select emax (the default, \
--select cv, chooses each curve by cross-validation and has no tolerance, knot method or seed)",
                given.join(", ")
            ))
            .into());
        }
    }
    Ok(())
}

/// The fit settings every column shares (its tolerance and periodicity aside).
fn fit_options(args: &Args) -> FitOptions {
    let defaults = FitOptions::default();
    FitOptions {
        select: args.select,
        method: args.method.unwrap_or(defaults.method),
        control_points: args.control_points,
        grid_segments: args.grid,
        optimise_weights: !args.no_weights,
        seed: args.seed.unwrap_or(defaults.seed),
        ..defaults
    }
}

/// One fit for every column of every table, in table order.
fn column_jobs(tables: &[ErrorTable]) -> Vec<Job<'_>> {
    tables
        .iter()
        .flat_map(|t| {
            t.columns.iter().enumerate().map(move |(i, c)| Job {
                table: t,
                column: i,
                kind: if c.is_angular() {
                    ParameterKind::Angle
                } else {
                    ParameterKind::Length
                },
            })
        })
        .collect()
}

/// Inputs against outputs (the report, every plot), before anything is fitted.
fn check_files(args: &Args, tables: &[ErrorTable], jobs: &[Job<'_>]) -> anyhow::Result<()> {
    let mut files = super::common::CommandFiles::new()
        .input("the input", Some(&args.input))
        .output("--report", args.report.as_deref());
    for table in tables {
        files = files.input("the error table", Some(&table.path));
    }
    if let Some(dir) = &args.plot {
        for job in jobs {
            let name = format!("{}.svg", job.table.columns[job.column].name);
            files = files.output("(--plot)", Some(&dir.join(name)));
        }
    }
    files.check()?;
    Ok(())
}

/// FNV-1a 64 of every table file's bytes as they were read and fitted (the
/// report names what it fitted).
fn table_hashes(tables: &[ErrorTable]) -> anyhow::Result<Vec<u64>> {
    Ok(tables.iter().map(|t| fnv1a64(t.text.as_bytes())).collect())
}

/// Fits every column, in parallel.
fn fit_columns(
    args: &Args,
    base: &FitOptions,
    jobs: &[Job<'_>],
    counter: &crate::progress::WorkCounter,
) -> anyhow::Result<Vec<crate::nurbs::SmemCurve>> {
    jobs.par_iter()
        .map(|job| {
            let column = &job.table.columns[job.column];
            let tolerance = match job.kind {
                ParameterKind::Length => args.tol,
                ParameterKind::Angle => args.tol_angle.or(args.tol),
            };
            let options = FitOptions {
                tolerance,
                periodic: job.table.one_revolution,
                ..base.clone()
            };
            crate::nurbs::fit_parameter_with_uncertainty(
                &job.table.positions,
                &column.values,
                column.uncertainty.as_deref(),
                job.kind,
                &options,
            )
            .inspect(|_| counter.step())
            .with_context(|| format!("{}: cannot fit {}", job.table.path.display(), column.name))
        })
        .collect()
}

/// The fits as the model file, printed as a table (a row a fit, then each
/// table's rows that are not fits).
fn report_fits(
    data_on_stdout: bool,
    cv: bool,
    tables: &[ErrorTable],
    jobs: &[Job<'_>],
    fits: &[crate::nurbs::SmemCurve],
    hashes: &[u64],
) -> anyhow::Result<SmemModelFile> {
    let mut report = SmemModelFile {
        parameters: Vec::new(),
        not_measured: Vec::new(),
    };
    print_header(data_on_stdout, cv)?;
    for (job, curve) in jobs.iter().zip(fits) {
        let table_index = tables
            .iter()
            .position(|t| std::ptr::eq(t, job.table))
            .unwrap_or(0);
        let entry = ParameterFit::new(
            job.table.axis.letter(),
            &job.table.columns[job.column].name,
            job.kind.unit(),
            curve,
            &job.table.path.display().to_string(),
            hashes[table_index],
        );
        print_row(data_on_stdout, cv, &entry)?;
        report.parameters.push(entry);
    }
    for t in tables {
        print_not_fitted(data_on_stdout, t)?;
        report.not_measured.extend(t.missing.iter().cloned());
    }
    Ok(report)
}

/// The header of the table of fits.
fn print_header(data_on_stdout: bool, cv: bool) -> anyhow::Result<()> {
    if cv {
        crate::cli::humanln!(
            data_on_stdout,
            "axis  parameter  samples  ctrl  dof    noise     cv        emax      unit  periodic  seconds"
        );
    } else {
        crate::cli::humanln!(
            data_on_stdout,
            "axis  parameter  samples  ctrl  emax      erms      tol      unit  met  seconds"
        );
    }
    Ok(())
}

/// One fitted parameter's row.
fn print_row(data_on_stdout: bool, cv: bool, entry: &ParameterFit) -> anyhow::Result<()> {
    let s = &entry.stats;
    let unit = super::common::unit_symbol(&entry.unit);
    if cv {
        crate::cli::humanln!(
            data_on_stdout,
            "{:<4}  {:<9}  {:>7}  {:>4}  {:>5.1}  {:>8.4}  {:>8.4}  {:>8.4}  {:<4}  {:<8}  {:>7.3}",
            entry.axis,
            entry.parameter,
            s.samples,
            s.control_points,
            s.dof,
            s.noise,
            s.cv_error,
            s.emax,
            unit,
            if s.periodic { "yes" } else { "no" },
            s.seconds
        );
    } else {
        crate::cli::humanln!(
            data_on_stdout,
            "{:<4}  {:<9}  {:>7}  {:>4}  {:>8.4}  {:>8.4}  {:>7.3}  {:<4}  {:<3}  {:>7.3}",
            entry.axis,
            entry.parameter,
            s.samples,
            s.control_points,
            s.emax,
            s.erms,
            s.tolerance,
            unit,
            if s.met { "yes" } else { "NO" },
            s.seconds
        );
    }
    Ok(())
}

/// A table's rows that are not fits: its REVERSAL column, its parameters not measured.
fn print_not_fitted(data_on_stdout: bool, t: &ErrorTable) -> anyhow::Result<()> {
    if t.reversal.is_some() {
        crate::cli::humanln!(
            data_on_stdout,
            "{:<4}  REVERSAL   read, not fitted: linear between the positions, ±REVERSAL/2 by the direction of motion",
            t.axis.letter()
        );
    }
    for m in &t.missing {
        crate::cli::humanln!(
            data_on_stdout,
            "{:<4}  {:<9}  not measured (taken as zero)",
            t.axis.letter(),
            m
        );
    }
    Ok(())
}

fn write_plots(
    dir: &Path,
    jobs: &[Job<'_>],
    fits: &[crate::nurbs::SmemCurve],
) -> anyhow::Result<()> {
    for (job, curve) in jobs.iter().zip(fits) {
        let column = &job.table.columns[job.column];
        let s = curve.stats();
        let title = match s.select {
            Selection::Cv => format!(
                "{}: {} control points, cross-validated (dof {:.1}, noise {:.3} {})",
                column.name,
                s.control_points,
                s.dof,
                s.noise,
                super::common::unit_symbol(job.kind.unit())
            ),
            Selection::Emax => format!(
                "{}: {} control points, {} knots, Emax {:.3} {}",
                column.name,
                s.control_points,
                s.method,
                s.emax,
                super::common::unit_symbol(job.kind.unit())
            ),
        };
        let x_label = if job.table.axis.is_rotary() {
            "Axis position (deg)"
        } else {
            "Axis position (mm)"
        };
        let y_label = format!("Error ({})", super::common::unit_symbol(job.kind.unit()));
        let svg = plot_fit(
            &job.table.positions,
            &column.values,
            curve,
            &PlotLabels {
                title: &title,
                x_label,
                y_label: &y_label,
            },
        );
        crate::io::write_file_atomic(&dir.join(format!("{}.svg", column.name)), svg.as_bytes())?;
    }
    Ok(())
}
