//! `volcomp diagnose`: explain the gap between a measured part and the geometric
//! model's prediction (effects.md): where it lies, which unmodelled effect causes
//! it, and how far it shrinks once that effect is added.
use super::UsageError;
use crate::diagnose::{DiagnoseOptions, DiagnoseReport, diagnose, html};
use crate::inspection::{Measurement, Plan};
use crate::toolpath::PointContext;
use anyhow::Context;
use std::path::{Path, PathBuf};

const AFTER_HELP: &str = "\
The report (JSON) holds the gap (measured and predicted profile, residual RMS, noise floor),
its localisation (worst points and blocks, by time, region, A/C and direction of travel),
every catalogue effect fitted and cross-validated (folds by region and by time), the
selected effects (none, one or two) and the model after adding them. See docs/diagnose.md.

Examples:
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json --html diag.html --noise-um 0.3";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    #[command(flatten)]
    pub machine: super::common::MachineArgs,
    /// Program (G-code) that cut the part.
    pub program: PathBuf,
    #[command(flatten)]
    pub read: super::common::ProgramArgs,
    /// Measurement (CSV: id,x,y,z,i,j,k,mx,my,mz).
    pub measured: PathBuf,
    /// Report file (JSON; `-` for stdout).
    #[arg(long)]
    pub report: PathBuf,
    /// Also write a self-contained HTML report with residual maps and charts.
    #[arg(long)]
    pub html: Option<PathBuf>,
    /// Probing noise (µm, one σ) when known; estimated from the data otherwise.
    #[arg(long)]
    pub noise_um: Option<f64>,
    /// Also write the tool-path context of every plan point (JSON), for checks
    /// and test fixtures.
    #[arg(long, value_name = "FILE")]
    pub dump_contexts: Option<PathBuf>,
}

/// A plan matched against the program that cut it, on a machine's error model:
/// what `diagnose` and `simulate` start from.
pub(crate) struct CutPart {
    pub model: crate::machine::ErrorModel,
    pub plan: Plan,
    pub matches: Vec<Option<crate::toolpath::PlanMatch>>,
}

impl CutPart {
    /// Match `plan` against the path of `program` on `machine`.
    pub(crate) fn new(
        machine: &super::common::MachineArgs,
        program: &Path,
        read: super::common::ProgramArgs,
        plan: Plan,
    ) -> anyhow::Result<CutPart> {
        let (machine_def, model) = machine.load()?;
        let options = read.cut_options(&machine_def);
        let program = read.program(program, Some(&machine_def))?;
        let (matches, _) =
            crate::toolpath::cut::match_plan(program, &model, &plan.points, &options)?;
        Ok(CutPart {
            model,
            plan,
            matches,
        })
    }

    /// The context of every plan point.
    pub(crate) fn contexts(&self) -> anyhow::Result<Vec<PointContext>> {
        Ok(crate::toolpath::cut::contexts(
            &self.model,
            &self.plan.points,
            &self.matches,
        )?)
    }

    /// The volumetric error (µm, part frame) of the machine's own tables at every
    /// plan point: `simulate`'s truth (zero where not cut).
    pub(crate) fn truth_um(&self) -> anyhow::Result<Vec<[f64; 3]>> {
        Ok(
            crate::toolpath::cut::volumetric_errors(&self.model, &self.plan.points, &self.matches)?
                .into_iter()
                .map(|e| e.unwrap_or([0.0; 3]))
                .collect(),
        )
    }
}

/// Fewest cut points `diagnose` works on.
const MIN_DIAGNOSED_POINTS: usize = 20;

pub fn run(args: &Args) -> anyhow::Result<()> {
    if let Some(s) = args.noise_um {
        if !(s.is_finite() && s > 0.0) {
            return Err(UsageError(format!("--noise-um must be > 0, got {s}")).into());
        }
    }
    let measurement = Measurement::read(&args.measured)?;
    let contexts = CutPart::new(
        &args.machine,
        &args.program,
        args.read.clone(),
        measurement.plan(),
    )?
    .contexts()?;
    // Held-out judging (a 3 × 3 grid of regions and time bands) needs points
    // in every fold and more points than the largest effect has parameters.
    let cut = contexts.iter().filter(|c| c.cut).count();
    if cut < MIN_DIAGNOSED_POINTS {
        anyhow::bail!(
            "{}: {cut} measured points were cut by the program; a diagnosis needs at least {MIN_DIAGNOSED_POINTS} (points are held out by region and by time to judge each effect)",
            args.measured.display()
        );
    }
    if let Some(path) = &args.dump_contexts {
        crate::io::write_json_atomic(path, &contexts)?;
    }
    let options = DiagnoseOptions {
        noise_um: args.noise_um,
        ..DiagnoseOptions::default()
    };
    let report = diagnose(&contexts, &measurement.deviations_um(), &options)
        .context("diagnosing the measurement")?;
    crate::io::write_json_atomic(&args.report, &report)?;
    if let Some(path) = &args.html {
        crate::io::write_file_atomic(path, html::render(&report).as_bytes())?;
    }
    if !crate::io::is_stdio(&args.report) {
        super::stdout_text(&summary_text(&report))?;
    }
    Ok(())
}

/// The human summary printed by the command.
pub fn summary_text(report: &DiagnoseReport) -> String {
    let g = &report.gap;
    let mut out = format!(
        "{} points ({} used): measured profile {:.2} µm, predicted {:.2} µm; residual RMS {:.2} µm, noise floor {:.2} µm ({})\n",
        report.points,
        report.points_used,
        g.measured_profile_um,
        g.predicted_profile_um,
        g.residual_rms_um,
        g.noise_floor_um,
        g.noise_floor_source
    );
    out.push_str(&format!(
        "selected: {}\n",
        if report.selected.is_empty() {
            "none".to_string()
        } else {
            report.selected.join(", ")
        }
    ));
    for e in report.effects.iter().take(3) {
        out.push_str(&format!(
            "  {:<16} held-out RMS {:.3} -> {:.3} µm ({:+.1} %)\n",
            e.name, e.heldout_rms_before_um, e.heldout_rms_after_um, -e.shrink_pct
        ));
    }
    out.push_str(&format!(
        "after: predicted profile {:.2} µm, residual RMS {:.2} µm\n",
        report.after.predicted_profile_um, report.after.residual_rms_um
    ));
    for s in &report.summary {
        out.push_str(s);
        out.push('\n');
    }
    out
}
