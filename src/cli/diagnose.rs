//! `volcomp diagnose`: explain the gap between a measured part and the geometric
//! model's prediction (effects.md): where it lies, which unmodelled effect causes
//! it, and how far it shrinks once that effect is added.
use super::UsageError;
use crate::diagnose::followup::{self, FollowupOptions, Probe, ProbeReading};
use crate::diagnose::probing_program::{ProbingOptions, probing_program};
use crate::diagnose::{DiagnoseOptions, DiagnoseReport, diagnose, diagnose_with_followup};
use crate::inspection::{Followup, FollowupPoint, Measurement, Plan};
use crate::toolpath::PointContext;
use anyhow::Context;
use std::path::{Path, PathBuf};

pub const EXAMPLES: &str = "\
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv -o meas.csv --effect setup_error:tx=8,ty=-5 --seed 7
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json --html diag.html --noise-um 0.3
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json --followup-program followup.nc
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv --followup followup.csv -o meas2.csv --effect setup_error:tx=8,ty=-5 --seed 7
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag2.json --followup meas2.csv
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json --write-machine ref-trt-diag.toml
  volcomp compensate ref-trt-diag.toml samples/saddle.nc -o saddle-comp.nc";

const AFTER_HELP: &str = "\
The report (JSON) holds the gap (measured and predicted profile, residual RMS, noise floor),
its localisation (worst points and blocks, by time, region, rotary angles and direction of
travel), every catalogue effect fitted and cross-validated (folds by region and by time),
the selected effects (none, one or more) and the model after adding them.

When the selected effect has aliases on the part, --followup-program writes a probing
program (G38.2) that separates them and its plan (.csv); measure it (or simulate it)
and give the result with --followup to re-rank the effects on both measurements.

--write-machine OUT.toml writes the machine file with the diagnosed machine errors
applied: rotary location and squareness added to [location] and [squareness], a
backlash as a REVERSAL column in copies of the axis tables (OUT.x.csv …, next to
OUT.toml), the set-up as a work-offset suggestion in the comment block that says
what changed and why. The rest of the file is kept; table paths are re-written to
resolve from OUT's folder. Compensate with it to cut the next part.";

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
    /// Frame of the measurement's points: part (the rotary plate's) or work
    /// (the program's coordinates: the work offset, G92 and rotation it cuts in applied).
    #[arg(long, value_enum, default_value = "part", value_name = "part|work")]
    pub plan_frame: super::plan_frame::PlanFrame,
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
    /// When the selected effect has aliases, write the probing program that
    /// separates them (G38.2, this machine's joints) to OUT.nc and its plan to
    /// OUT.csv (same name, .csv).
    #[arg(long, value_name = "OUT.nc", conflicts_with = "followup")]
    pub followup_program: Option<PathBuf>,
    /// Probes in the designed follow-up.
    #[arg(long, default_value_t = 12, value_name = "N")]
    pub followup_probes: usize,
    /// A follow-up measurement (CSV: id,x,y,z,i,j,k,a,c,t_min,mx,my,mz): fitted
    /// together with MEASURED, re-ranking the effects.
    #[arg(long, value_name = "MEASURED2.csv")]
    pub followup: Option<PathBuf>,
    #[command(flatten)]
    pub probe: ProbeArgs,
    /// Write the machine file with the diagnosed machine errors applied
    /// (location, squareness, backlash as REVERSAL; a comment block says what
    /// changed and why), for `compensate`.
    #[arg(long, value_name = "OUT.toml")]
    pub write_machine: Option<PathBuf>,
}

/// The probe of a follow-up (give the same values to design it, to simulate
/// it and to read it back).
#[derive(Debug, Clone, clap::Args)]
pub struct ProbeArgs {
    /// Probe length, gauge line to the stylus tip, mm [default: the machine file's tool length].
    #[arg(long, value_name = "MM")]
    pub probe_length: Option<f64>,
    /// Stylus ball radius, mm.
    #[arg(long, default_value_t = 1.0, value_name = "MM")]
    pub probe_radius: f64,
}

impl ProbeArgs {
    pub(crate) fn check(&self) -> Result<(), UsageError> {
        if let Some(l) = self.probe_length {
            if !(l.is_finite() && l > 0.0) {
                return Err(UsageError(format!(
                    "--probe-length must be > 0 mm, got {l}"
                )));
            }
        }
        if !(self.probe_radius.is_finite() && self.probe_radius >= 0.0) {
            return Err(UsageError(format!(
                "--probe-radius must be ≥ 0 mm, got {}",
                self.probe_radius
            )));
        }
        Ok(())
    }
}

/// A plan matched against the program that cut it, on a machine's error model:
/// what `diagnose` and `simulate` start from.
pub(crate) struct CutPart {
    pub machine: crate::machine::Machine,
    pub model: crate::machine::ErrorModel,
    pub plan: Plan,
    pub matches: Vec<Option<crate::toolpath::PlanMatch>>,
    /// The program's machining time, minutes (its end).
    pub end_min: f64,
    /// The program carries volcomp's stamp: its path is offset from the
    /// nominal surface by the correction, so the part is that offset plus the
    /// machine's error (as `predict` shows a compensated program).
    pub compensated: bool,
    /// The warnings of reading the program (and of the model's lookups:
    /// [`CutPart::warnings`]).
    warnings: crate::warnings::Warnings,
    held_before: u64,
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
        let (program, stamp) = read.program_and_stamp(program, Some(&machine_def))?;
        let warnings = program.warnings();
        let held_before = model.held_lookups();
        let (matches, summary) =
            crate::toolpath::cut::match_plan(program, &model, &plan.points, &options)?;
        Ok(CutPart {
            machine: machine_def,
            model,
            plan,
            matches,
            end_min: summary.time_min,
            compensated: stamp.is_some(),
            warnings,
            held_before,
        })
    }

    /// The warnings of the run so far: the program's, and the lookups that
    /// held a table's end value (`--extrapolate hold`).
    pub(crate) fn warnings(&self) -> Vec<crate::warnings::WarningGroup> {
        let log = self.warnings.clone();
        let mut groups = log.groups();
        let held = self.model.held_lookups().saturating_sub(self.held_before);
        if held > 0 {
            let extra = crate::warnings::Warnings::new();
            super::common::add_held_lookups(&extra, held);
            groups.extend(extra.groups());
        }
        groups
    }

    /// The context of every plan point.
    pub(crate) fn contexts(&self) -> anyhow::Result<Vec<PointContext>> {
        let mut contexts =
            crate::toolpath::cut::contexts(&self.model, &self.plan.points, &self.matches)?;
        if self.compensated {
            for (c, e) in contexts.iter_mut().zip(self.truth_um()?) {
                if c.cut {
                    c.predicted_um = crate::vec3::dot(c.normal, e);
                }
            }
        }
        Ok(contexts)
    }

    /// The probe of the follow-up options (its length defaults to the machine
    /// file's tool).
    pub(crate) fn probe_tool(&self, probe: &ProbeArgs) -> crate::toolpath::cut::ProbeTool {
        crate::toolpath::cut::ProbeTool {
            length_mm: probe.probe_length.unwrap_or(self.machine.tool.length),
            radius_mm: probe.probe_radius,
        }
    }

    /// The probes of a follow-up plan or measurement: each row's plan point
    /// (found by position and normal among the cut points), its pose and time.
    pub(crate) fn followup_probes(
        &self,
        contexts: &[PointContext],
        followup: &Followup,
        probe: &ProbeArgs,
        path: &Path,
    ) -> anyhow::Result<Vec<Probe>> {
        let tool = self.probe_tool(probe);
        followup
            .points
            .iter()
            .map(|f| {
                let p = &f.plan;
                let of = contexts
                    .iter()
                    .position(|c| {
                        c.cut
                            && crate::vec3::dist(c.point, p.point) < 1e-3
                            && crate::vec3::dot(c.normal, p.normal) > 0.9999
                    })
                    .with_context(|| {
                        format!(
                            "{}: probe {}: no cut point of the measurement at ({:.4}, {:.4}, {:.4}) with that normal (a follow-up probes the measurement's points again)",
                            path.display(), p.id, p.point[0], p.point[1], p.point[2]
                        )
                    })?;
                let context = crate::toolpath::cut::probe_context(
                    &self.model,
                    &tool,
                    None,
                    &contexts[of],
                    [f.a_deg, f.c_deg],
                    f.time_min,
                )?
                .context("a probe without travel limits is always placed")?;
                Ok(Probe {
                    id: p.id.clone(),
                    of,
                    context,
                })
            })
            .collect()
    }

    /// The volumetric error (µm, part frame) of the machine's own tables at every
    /// plan point (`predict`'s deviation), or for a compensated program the
    /// error at the contact plus the path's offset along the normal (what the
    /// part measures, `predict`'s headline): `simulate`'s truth (zero where not cut).
    pub(crate) fn truth_um(&self) -> anyhow::Result<Vec<[f64; 3]>> {
        let errors =
            crate::toolpath::cut::match_errors(&self.model, &self.plan.points, &self.matches)?;
        Ok(errors
            .into_iter()
            .zip(self.plan.points.iter().zip(&self.matches))
            .map(|(e, (p, m))| match (e, m) {
                // As `predict` shows a compensated program: the error where
                // the tool touches, plus the path's own offset.
                (Some(e), Some(m)) if self.compensated => {
                    let o = m.path_offset_um(p.point, p.normal);
                    [0, 1, 2].map(|k| e.contact[k] + o * p.normal[k])
                }
                (Some(e), _) => e.deviation,
                (None, _) => [0.0; 3],
            })
            .collect())
    }
}

/// Fewest cut points `diagnose` works on.
const MIN_DIAGNOSED_POINTS: usize = 20;

pub fn run(args: &Args) -> anyhow::Result<()> {
    check_arguments(args)?;
    let data_on_stdout = super::common::stdout_output(&[
        ("--report -", crate::io::is_stdio(&args.report)),
        ("--html -", super::common::is_stdout(args.html.as_deref())),
        (
            "--dump-contexts -",
            super::common::is_stdout(args.dump_contexts.as_deref()),
        ),
    ])?;
    let (measurement, part) = read_inputs(args)?;
    check_files(args, &part)?;
    let outputs = crate::io::OutputSet::begin();
    let followup_measured = args
        .followup
        .as_ref()
        .map(|p| Followup::read_measurement(p, part.machine.chain.rotary()))
        .transpose()?;
    let contexts = cut_contexts(args, &part)?;
    if let Some(path) = &args.dump_contexts {
        crate::io::write_json_atomic(path, &contexts)?;
    }
    let counter = std::sync::Arc::new(crate::progress::WorkCounter::new());
    let options = DiagnoseOptions {
        noise_um: args.noise_um,
        progress: Some(std::sync::Arc::clone(&counter)),
        ..DiagnoseOptions::default()
    };
    let measured = measurement.deviations_um();
    let mut report = super::common::with_progress("diagnosing (selection)", &counter, || {
        diagnose(&contexts, &measured, &options)
    })
    .context("diagnosing the measurement")?;
    let mut program_written = None;
    if let (Some(followup), Some(path)) = (&followup_measured, &args.followup) {
        let diagnosis = Diagnosis {
            contexts: &contexts,
            measured: &measured,
            options: &options,
        };
        report = diagnosis.with_followup(&part, args, followup, path, &report)?;
    } else if let Some(out) = &args.followup_program {
        program_written = design_followup(args, &part, &contexts, &measured, &mut report, out)?;
    }
    report.warnings = part.warnings();
    let machine_written = match &args.write_machine {
        Some(out) => Some(write_machine_file(args, &part, &report, out)?),
        None => None,
    };
    write_report(args, &report)?;
    outputs.commit()?;
    super::common::print_warnings(&report.warnings);
    let text = outcome_text(&report, program_written, machine_written);
    super::common::say(data_on_stdout, text.trim_end())
}

/// The measurement (in part coordinates) and the part: its plan matched
/// against the program on the machine's model.
fn read_inputs(args: &Args) -> anyhow::Result<(Measurement, CutPart)> {
    let measurement = Measurement::read(&args.measured)?;
    let measurement = match work_frame_of(args)? {
        Some(frame) => frame.measurement_to_part(&measurement),
        None => measurement,
    };
    let part = CutPart::new(
        &args.machine,
        &args.program,
        args.read.clone(),
        measurement.plan(),
    )?;
    Ok((measurement, part))
}

/// `--report` and `--html`.
fn write_report(args: &Args, report: &DiagnoseReport) -> anyhow::Result<()> {
    crate::io::write_json_atomic(&args.report, report)?;
    if let Some(path) = &args.html {
        crate::io::write_file_atomic(
            path,
            crate::report::diagnose_html::render(report).as_bytes(),
        )?;
    }
    Ok(())
}

/// The usage errors of the options, before any file is read.
fn check_arguments(args: &Args) -> anyhow::Result<()> {
    if let Some(s) = args.noise_um {
        if !(s.is_finite() && s > 0.0) {
            return Err(UsageError(format!("--noise-um must be > 0, got {s}")).into());
        }
    }
    args.probe.check()?;
    if args.followup_probes == 0 {
        return Err(UsageError("--followup-probes must be ≥ 1".into()).into());
    }
    if let Some(out) = &args.followup_program {
        if out
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
            || crate::io::is_stdio(out)
        {
            return Err(UsageError(format!(
                "--followup-program {}: give the program's file name (e.g. followup.nc); its plan is written next to it as .csv",
                out.display()
            ))
            .into());
        }
    }
    if let Some(out) = &args.write_machine {
        if crate::io::is_stdio(out) {
            return Err(UsageError(
                "--write-machine -: give a file name (its error tables are found from its folder)"
                    .into(),
            )
            .into());
        }
    }
    Ok(())
}

/// Inputs against outputs (and the machine's), before anything is computed.
fn check_files(args: &Args, part: &CutPart) -> anyhow::Result<()> {
    let followup_plan = args
        .followup_program
        .as_ref()
        .map(|out| out.with_extension("csv"));
    let machine_outputs = args
        .write_machine
        .as_deref()
        .map(|out| super::write_machine::planned_outputs(out, &part.machine))
        .unwrap_or_default();
    let mut files = super::common::CommandFiles::new();
    for (role, path) in &machine_outputs {
        files = files.output(role, Some(path));
    }
    files
        .input("the program", Some(&args.program))
        .input("the measurement", Some(&args.measured))
        .input(
            "the follow-up measurement (--followup)",
            args.followup.as_deref(),
        )
        .machine(&part.machine)
        .model(&args.machine.model)
        .program_args(&args.read)
        .output("--report", Some(&args.report))
        .output("--html", args.html.as_deref())
        .output("--dump-contexts", args.dump_contexts.as_deref())
        .output("--followup-program", args.followup_program.as_deref())
        .output(
            "the follow-up plan (--followup-program, .csv)",
            followup_plan.as_deref(),
        )
        .check()?;
    Ok(())
}

/// The context of every measured point, refused when too few were cut.
fn cut_contexts(args: &Args, part: &CutPart) -> anyhow::Result<Vec<PointContext>> {
    let contexts = part.contexts()?;
    // Held-out judging (a 3 × 3 grid of regions and time bands) needs points
    // in every fold and more points than the largest effect has parameters.
    let cut = contexts.iter().filter(|c| c.cut).count();
    if cut < MIN_DIAGNOSED_POINTS {
        anyhow::bail!(
            "{}: {} cut by the program; a diagnosis needs at least {MIN_DIAGNOSED_POINTS} (points are held out by region and by time to judge each effect)",
            args.measured.display(),
            if cut == 1 {
                "1 measured point was".to_string()
            } else {
                format!("{cut} measured points were")
            }
        );
    }
    Ok(contexts)
}

/// What a diagnosis is computed from: the points' contexts, the measured
/// deviations and the settings.
struct Diagnosis<'a> {
    contexts: &'a [PointContext],
    measured: &'a [f64],
    options: &'a DiagnoseOptions,
}

impl Diagnosis<'_> {
    /// The diagnosis again with the follow-up's readings, and what the
    /// follow-up achieved (in its summary and its `followup`).
    fn with_followup(
        &self,
        part: &CutPart,
        args: &Args,
        followup: &Followup,
        path: &Path,
        first: &DiagnoseReport,
    ) -> anyhow::Result<DiagnoseReport> {
        let (contexts, measured) = (self.contexts, self.measured);
        let probes = part.followup_probes(contexts, followup, &args.probe, path)?;
        let readings: Vec<ProbeReading> = probes
            .into_iter()
            .zip(&followup.points)
            .map(|(probe, f)| ProbeReading {
                probe,
                reading_um: f.reading_um(),
            })
            .collect();
        let outcome = followup::outcome(contexts, measured, first, &readings)
            .context("judging the follow-up")?;
        let counter = std::sync::Arc::new(crate::progress::WorkCounter::new());
        let options = DiagnoseOptions {
            progress: Some(std::sync::Arc::clone(&counter)),
            ..self.options.clone()
        };
        let mut report = super::common::with_progress(
            "diagnosing with the follow-up (selection)",
            &counter,
            || diagnose_with_followup(contexts, measured, &readings, &options),
        )
        .context("diagnosing the measurement with its follow-up")?;
        report.summary.push(followup_sentence(
            &first.selected,
            &report.selected,
            &outcome,
        ));
        report.followup = Some(outcome);
        Ok(report)
    }
}

/// Designs the follow-up that tells the selected effects from their aliases,
/// writes its probing program `out` and plan (`out` as .csv), and says why
/// in the summary when none is designed. Returns the two paths written.
fn design_followup(
    args: &Args,
    part: &CutPart,
    contexts: &[PointContext],
    measured: &[f64],
    report: &mut DiagnoseReport,
    out: &Path,
) -> anyhow::Result<Option<(PathBuf, PathBuf)>> {
    let tool = part.probe_tool(&args.probe);
    let candidates = followup::candidates(contexts, |cut, rotary| {
        crate::toolpath::cut::probe_context(
            &part.model,
            &tool,
            Some(&part.machine.limits),
            cut,
            rotary,
            part.end_min,
        )
    })?;
    let design = followup::design(
        contexts,
        measured,
        report,
        &candidates,
        part.end_min,
        &FollowupOptions {
            probes: args.followup_probes,
            ..FollowupOptions::default()
        },
    )
    .context("designing the follow-up")?;
    let Some(design) = design else {
        report.summary.push(no_followup_sentence(report, out));
        return Ok(None);
    };
    let plan_path = out.with_extension("csv");
    let text = probing_program(
        &design,
        &ProbingOptions {
            safe_z_mm: part.machine.limits.linear(crate::axes::Axis::Z)[1],
            feed_mm_min: 100.0,
            clearance_mm: 2.0,
            overtravel_mm: 1.0,
            stylus_radius_mm: tool.radius_mm,
            probe_length_mm: tool.length_mm,
            provenance: vec![
                format!("part program: {}", args.program.display()),
                format!("measurement: {}", args.measured.display()),
                format!("plan of the probes: {}", plan_path.display()),
            ],
        },
    );
    let plan = Followup {
        points: design
            .probes
            .iter()
            .map(|p| FollowupPoint {
                plan: crate::inspection::PlanPoint {
                    id: p.id.clone(),
                    point: p.probe.context.point,
                    normal: p.probe.context.normal,
                },
                a_deg: p.a_deg,
                c_deg: p.c_deg,
                time_min: p.time_min,
                measured: None,
            })
            .collect(),
        rotary: part.machine.chain.rotary(),
    };
    plan.write(&plan_path)?;
    crate::io::write_file_atomic(out, text.as_bytes())?;
    report.summary.extend(design.explanation.iter().cloned());
    report.followup_design = Some(design);
    Ok(Some((out.to_path_buf(), plan_path)))
}

/// Why no follow-up is designed (the model does not match, or no alias).
fn no_followup_sentence(report: &DiagnoseReport, out: &Path) -> String {
    if report.model_check.mismatch {
        return format!(
            "No follow-up is designed: the error model itself does not match this machine, so the effects cannot be told apart from its error; fix the model first ({} not written).",
            out.display()
        );
    }
    format!(
        "No follow-up is needed: {} (no alias on this part); {} not written.",
        if report.selected.is_empty() {
            "no effect is selected".to_string()
        } else {
            format!(
                "{} is told apart from every other effect",
                report.selected.join(" + ")
            )
        },
        out.display()
    )
}

/// `--write-machine`: the machine file updated by the diagnosis, with its provenance.
fn write_machine_file(
    args: &Args,
    part: &CutPart,
    report: &DiagnoseReport,
    out: &Path,
) -> anyhow::Result<super::write_machine::Written> {
    super::write_machine::write(
        out,
        &part.machine,
        report,
        &[
            format!("machine file: {}", part.machine.source.display()),
            format!("program: {}", args.program.display()),
            format!(
                "measurement: {} ({} points, {} used)",
                args.measured.display(),
                report.points,
                report.points_used
            ),
        ],
    )
}

/// The summary, then the files of the follow-up and of the machine written.
fn outcome_text(
    report: &DiagnoseReport,
    program_written: Option<(PathBuf, PathBuf)>,
    machine_written: Option<super::write_machine::Written>,
) -> String {
    let mut text = summary_text(report);
    if let Some((program, plan)) = program_written {
        text.push_str(&format!(
            "follow-up: probing program {} and its plan {}\n",
            program.display(),
            plan.display()
        ));
    }
    if let Some(w) = machine_written {
        text.push_str(&format!("machine file written: {}", w.machine.display()));
        if !w.tables.is_empty() {
            let names: Vec<String> = w.tables.iter().map(|t| t.display().to_string()).collect();
            text.push_str(&format!(" (with {})", names.join(", ")));
        }
        text.push('\n');
        for c in &w.changes {
            text.push_str(&format!("  {c}\n"));
        }
    }
    text
}

/// The summary sentence of a measured follow-up.
fn followup_sentence(
    before: &[String],
    after: &[String],
    outcome: &followup::FollowupOutcome,
) -> String {
    let name = |v: &[String]| {
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(" + ")
        }
    };
    let pairs = outcome
        .separations
        .iter()
        .map(|s| {
            format!(
                "{} vs {}: {:+.1} σ achieved (expected {:.1} σ if {}, {:.1} σ if {})",
                s.selected,
                s.rival,
                s.achieved_sigma.unwrap_or(0.0),
                s.if_selected_sigma,
                s.selected,
                s.if_rival_sigma,
                s.rival
            )
        })
        .collect::<Vec<_>>()
        .join("; ");
    format!(
        "Follow-up ({}, readings {:.2} µm RMS beyond the model): selected {} before it, {} with it{}{}.",
        super::common::count(outcome.probes as u64, "probe", "probes"),
        outcome.reading_rms_um,
        name(before),
        name(after),
        if pairs.is_empty() { "" } else { "; " },
        pairs
    )
}

/// The human summary printed by the command.
pub fn summary_text(report: &DiagnoseReport) -> String {
    let g = &report.gap;
    let mut out = format!(
        "{} ({} used): measured profile {:.2} µm, predicted {:.2} µm; residual RMS {:.2} µm, noise floor {:.2} µm ({}){}\n",
        super::common::count(report.points as u64, "point", "points"),
        report.points_used,
        g.measured_profile_um,
        g.predicted_profile_um,
        g.residual_rms_um,
        g.noise_floor_um,
        g.noise_floor_source,
        super::common::result_note(&report.warnings)
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
    for (effect, checks) in &report.after.checks {
        let z = report
            .after
            .significance
            .get(effect)
            .copied()
            .unwrap_or(0.0);
        let params: Vec<String> = checks
            .iter()
            .map(|c| {
                let flag = match (c.identifiable, c.plausible) {
                    (true, true) => "",
                    (false, _) => " (not identifiable)",
                    (true, false) => " (implausible)",
                };
                format!("{}{flag}", c.display())
            })
            .collect();
        out.push_str(&format!("  {effect} (z = {z:.0}): {}\n", params.join(", ")));
    }
    out.push_str(&format!(
        "after: predicted profile {:.2} µm, residual RMS {:.2} µm\n",
        report.after.predicted_profile_um, report.after.residual_rms_um
    ));
    for a in &report.local_anomalies {
        out.push_str(&format!(
            "local anomaly: {} points around ({:.1}, {:.1}, {:.1}) mm, peak {:+.2} µm, {:.0} σ, lines {}\n",
            a.points,
            a.centre[0],
            a.centre[1],
            a.centre[2],
            a.peak_um,
            a.sigma,
            a.lines
                .iter()
                .map(|l| l.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    for s in &report.summary {
        out.push_str(s);
        out.push('\n');
    }
    out
}

/// The work frame of `--plan-frame work` (None for part coordinates).
fn work_frame_of(args: &Args) -> anyhow::Result<Option<crate::inspection::WorkFrame>> {
    super::plan_frame::work_frame_of_command(
        args.plan_frame,
        &args.machine,
        &args.read,
        &args.program,
        args.followup
            .is_some()
            .then_some("a follow-up measurement is in part coordinates"),
    )
}
