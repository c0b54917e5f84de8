//! `volcomp predict`: predicted deviations and profile error of the part a program cuts.
use super::common::{MachineArgs, ProgramArgs};
use crate::gcode::Program;
use crate::inspection::{Plan, WorkFrame};
use crate::io::{OutputError, write_atomic, write_file_atomic, write_json_atomic};
use crate::machine::{ErrorModel, Machine};
use crate::predict::{PathErrors, PathReportStream, PathSummary, PredictReport, predict_plan};
use crate::stamp::Stamp;
use crate::toolpath::CutOptions;
use crate::warnings::WarningGroup;
use std::path::{Path, PathBuf};

pub const EXAMPLES: &str = "\
  volcomp predict machines/ref-trt.toml samples/saddle.nc --plan samples/saddle-plan.csv --report pred.json --html pred.html
  volcomp predict machines/ref-trt.toml samples/saddle.nc --plan samples/saddle-plan.csv --report pred.json --csv pred.csv
  volcomp predict machines/ref-trt.toml samples/saddle.nc --report path-errors.json
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc
  volcomp predict machines/ref-trt.toml saddle-comp.nc --plan samples/saddle-plan.csv --report pred-comp.json --html pred-comp.html";

const AFTER_HELP: &str = "\
With --plan, each plan point is assigned the tool-path point that cut it (the
ball-end contact point t + R·u − R·n nearest the plan point, path sampled at
0.5 mm in part coordinates); its predicted deviation is n·e, the volumetric error
of that path point along the surface normal (µm, positive: material left), with
its standard uncertainty (±, from the tables' noise). The profile error is
2·max|d| (and the range max d − min d). Without --plan the report lists the
volumetric error at the end of every motion block, with its line. For a
compensated (stamped) program, the figures are what the part will measure, with
the uncompensated ones beside them.";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Program (`-` for standard input).
    pub program: PathBuf,
    /// Inspection plan (CSV `id,x,y,z,i,j,k`, part coordinates unless --plan-frame work).
    #[arg(long, value_name = "PLAN.csv")]
    pub plan: Option<PathBuf>,
    /// Frame of the plan's points: part (the rotary plate's) or work (the program's
    /// coordinates: the work offset, G92 and rotation it cuts in are applied).
    #[arg(long, value_enum, default_value = "part", value_name = "part|work")]
    pub plan_frame: super::plan_frame::PlanFrame,
    /// Every plan point's prediction as CSV for inspection software:
    /// id,x,y,z,i,j,k,deviation_um,u_um,line,tool (points in the plan's frame).
    #[arg(long, value_name = "FILE.csv")]
    pub csv: Option<PathBuf>,
    /// Report (JSON).
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Self-contained HTML report with pictures.
    #[arg(long, value_name = "FILE.html")]
    pub html: Option<PathBuf>,
    #[command(flatten)]
    pub read: ProgramArgs,
}

/// A prediction run, validated: the machine, its model, the plan's frame and
/// where the summary goes.
struct Job<'a> {
    args: &'a Args,
    /// The report, the page or the table goes to standard output (the summary
    /// to stderr).
    data_on_stdout: bool,
    machine: Machine,
    model: ErrorModel,
    /// The program's work frame, for a plan given in work coordinates.
    work: Option<WorkFrame>,
}

/// The warnings of a run, finished once (with the lookups it held).
type FinishWarnings<'a> = &'a dyn Fn() -> Vec<WarningGroup>;

pub fn run(args: &Args) -> anyhow::Result<()> {
    let job = Job::new(args)?;
    let outputs = crate::io::OutputSet::begin();
    let (machine, model) = (&job.machine, &job.model);
    let options = args.read.cut_options(machine);
    let (program, stamp) = args.read.program_and_stamp(&args.program, Some(machine))?;
    let warnings = program.warnings();
    let held_before = model.held_lookups();
    // The run's warnings with the lookups it held (added once, after the run).
    let added = std::cell::Cell::new(false);
    let finish_warnings = || {
        if !added.replace(true) {
            super::common::add_held_lookups(&warnings, model.held_lookups() - held_before);
        }
        warnings.groups()
    };
    let (mut report, summary) = match &args.plan {
        Some(plan_path) => {
            let report = job.predict_plan(plan_path, program, stamp, &options, &finish_warnings)?;
            (report, PathSummary::default())
        }
        None => job.predict_path(program, stamp, &options, &finish_warnings)?,
    };
    report.warnings = finish_warnings();
    job.write_html(&report)?;
    outputs.commit()?;
    super::common::print_warnings(&report.warnings);
    let note = super::common::result_note(&report.warnings);
    let text = if args.plan.is_some() {
        plan_summary(&report, &note)
    } else {
        path_summary(&report, &summary, &note)
    };
    let text = text + &tools_line(&report);
    let text = match &report.stamp {
        Some(stamp) => format!(
            "{text}\nnote: {} is already compensated: {}",
            args.program.display(),
            stamp.summary()
        ),
        None => text,
    };
    super::common::say(job.data_on_stdout, &text)?;
    Ok(())
}

impl<'a> Job<'a> {
    /// Checks the arguments, loads the machine and its model, and checks the
    /// files (inputs against outputs) before anything is computed.
    fn new(args: &'a Args) -> anyhow::Result<Job<'a>> {
        let data_on_stdout = super::common::stdout_output(&[
            (
                "--report -",
                super::common::is_stdout(args.report.as_deref()),
            ),
            ("--html -", super::common::is_stdout(args.html.as_deref())),
            ("--csv -", super::common::is_stdout(args.csv.as_deref())),
        ])?;
        if args.plan.is_none() {
            for (given, what) in [
                (args.csv.is_some(), "--csv"),
                (
                    args.plan_frame != super::plan_frame::PlanFrame::Part,
                    "--plan-frame work",
                ),
            ] {
                if given {
                    return Err(super::UsageError(format!("{what} needs --plan")).into());
                }
            }
        }
        if args.report.is_none() && args.html.is_none() && args.csv.is_none() {
            super::noteln!("no --report or --html given; printing the summary only");
        }
        let (machine, model) = args.machine.load()?;
        let work =
            super::plan_frame::work_frame(args.plan_frame, &args.read, &args.program, &machine)?;
        super::common::CommandFiles::new()
            .input("the program", Some(&args.program))
            .input("the plan", args.plan.as_deref())
            .machine(&machine)
            .model(&args.machine.model)
            .program_args(&args.read)
            .output("--report", args.report.as_deref())
            .output("--html", args.html.as_deref())
            .output("--csv", args.csv.as_deref())
            .check()?;
        Ok(Job {
            args,
            data_on_stdout,
            machine,
            model,
            work,
        })
    }

    /// The prediction of every plan point, written as `--report` and `--csv`;
    /// refused when the program cuts none of them.
    fn predict_plan(
        &self,
        plan_path: &Path,
        program: Program,
        stamp: Option<Stamp>,
        options: &CutOptions,
        finish_warnings: FinishWarnings<'_>,
    ) -> anyhow::Result<PredictReport> {
        let args = self.args;
        let warnings = program.warnings();
        let given = Plan::read(plan_path)?;
        let plan = match &self.work {
            Some(frame) => frame.plan_to_part(&given),
            None => given.clone(),
        };
        let mut report = predict_plan(program, &self.model, &plan, options)?;
        if report.points_cut == 0 {
            super::common::print_warnings(&warnings.groups());
            anyhow::bail!(
                "{}: none of its {} plan points is cut by {}: no tool-path point comes within {} mm of any (another part's plan, or the program's work offset or frame differs from the plan's: --var, --offset, --frame)",
                plan_path.display(),
                report.points_total,
                crate::io::display_name(&args.program),
                report.match_distance_mm
            );
        }
        report.warnings = finish_warnings();
        report.compensated = stamp.is_some();
        report.stamp = stamp;
        if let Some(path) = &args.report {
            write_json_atomic(path, &report)?;
        }
        if let Some(path) = &args.csv {
            write_file_atomic(path, prediction_csv(&given, &report).as_bytes())?;
        }
        Ok(report)
    }

    /// Without a plan, every move end is a row: written as it is computed,
    /// never held (memory does not grow with the program); the warnings come
    /// last, once the run is over.
    fn predict_path(
        &self,
        program: Program,
        stamp: Option<Stamp>,
        options: &CutOptions,
        finish_warnings: FinishWarnings<'_>,
    ) -> anyhow::Result<(PredictReport, PathSummary)> {
        let stream = PathReportStream::new(PathErrors::new(program, &self.model, options), stamp)
            .with_warnings(finish_warnings);
        match &self.args.report {
            Some(path) => write_atomic(path, |w| -> anyhow::Result<()> {
                let written = serde_json::to_writer_pretty(&mut *w, &stream)
                    .map_err(std::io::Error::from)
                    .and_then(|()| w.write_all(b"\n"));
                match (stream.failure(), written) {
                    (Some(failure), _) => Err(failure.into()),
                    (None, Ok(())) => Ok(()),
                    (None, Err(source)) => Err(OutputError::Write {
                        path: path.clone(),
                        source,
                    }
                    .into()),
                }
            })?,
            None => stream.drain()?,
        }
        Ok((stream.report(), stream.summary()))
    }

    /// `--html`: the page of the report.
    fn write_html(&self, report: &PredictReport) -> anyhow::Result<()> {
        if let Some(path) = &self.args.html {
            let title = format!(
                "volcomp predict: {} on {}",
                self.args.program.display(),
                self.machine.name
            );
            write_file_atomic(
                path,
                crate::report::predict_html::render(report, &title).as_bytes(),
            )?;
        }
        Ok(())
    }
}

/// The summary of a prediction over a plan: the profile (what the part will
/// measure, for a compensated program), the error, the largest deviation, the
/// model's noise, and the path's own offset where it shows.
fn plan_summary(report: &PredictReport, note: &str) -> String {
    let not_cut = report.points_total - report.points_cut;
    let c = report.compensated;
    let worst = report
        .points
        .iter()
        .filter_map(|p| p.shown_um(c).map(|d| (p, d)))
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()));
    let over = format!(
        "over {} of {} plan points{}",
        report.points_cut,
        report.points_total,
        if not_cut > 0 {
            format!(" ({not_cut} not cut)")
        } else {
            String::new()
        }
    );
    let uncertainty = report
        .profile_u_um
        .map_or(String::new(), |u| format!(" ± {u:.2}"));
    let headline = if c {
        // A compensated program: what the part will measure, with the
        // uncompensated figure beside it.
        format!(
            "the part will measure profile {:.2} µm (range {:.2} µm) {over}{note}; uncompensated it would be {:.2}{uncertainty} µm (n·e)",
            report.profile_with_path_um, report.range_with_path_um, report.profile_um
        )
    } else {
        format!(
            "predicted profile error {:.2}{uncertainty} µm (range {:.2} µm) {over}{note}",
            report.profile_um, report.range_um
        )
    };
    format!(
        "{headline}\n\
volumetric error at the cutting points: max {:.2} µm, RMS {:.2} µm{}{}\n{:.3} s",
        report.max_error_um,
        report.rms_error_um,
        worst.map_or(String::new(), |(p, d)| format!(
            "\nlargest deviation {d:.3} µm at plan point {} (line {})",
            p.id,
            p.line.unwrap_or(0)
        )),
        match report.rms_deviation_u_um {
            Some(u) => format!(
                "\nmodel noise (1 sigma, from the table noise and the fit; unmodelled effects not included): \
{u:.3} µm RMS over the points, ± is one standard uncertainty"
            ),
            None => {
                "\nmodel noise unknown (the model file carries no uncertainties; refit)".to_string()
            }
        },
        report.seconds
    ) + &if report.max_path_offset_um > 0.5 && !c {
        format!(
            "\nthe program's own path departs from the plan points by up to {:.2} µm along the normals \
(a compensated program without its stamp?): with it, the part would measure profile {:.2} µm (range {:.2} µm)",
            report.max_path_offset_um, report.profile_with_path_um, report.range_with_path_um
        )
    } else {
        String::new()
    }
}

/// The summary of a prediction along the path (no plan).
fn path_summary(report: &PredictReport, summary: &PathSummary, note: &str) -> String {
    format!(
        "{}: volumetric error max {:.2} µm{}, RMS {:.2} µm{note}\n{:.3} s",
        super::common::count(summary.rows as u64, "motion block", "motion blocks"),
        report.max_error_um,
        summary
            .max_line
            .map_or(String::new(), |line| format!(" (line {line})")),
        report.rms_error_um,
        report.seconds
    )
}

/// Which tool cut the plan points, when the program changes tools (a line
/// of its own), else nothing.
fn tools_line(report: &PredictReport) -> String {
    let mut by_tool: std::collections::BTreeMap<u32, usize> = Default::default();
    for p in &report.points {
        if let Some(t) = p.tool {
            *by_tool.entry(t).or_default() += 1;
        }
    }
    if !by_tool.keys().any(|t| *t != 0) {
        return String::new();
    }
    let list: Vec<String> = by_tool
        .iter()
        .map(|(t, n)| match t {
            0 => format!("default tool {n}"),
            t => format!("T{t} {n}"),
        })
        .collect();
    format!("\nplan points cut per tool: {}", list.join(", "))
}

/// `id,x,y,z,i,j,k,deviation_um,u_um,line,tool`: each plan point as given (its
/// own frame and digits) with its prediction; a point not cut has the last four
/// cells empty, as has `u_um` when the model carries no uncertainty.
fn prediction_csv(plan: &Plan, report: &PredictReport) -> String {
    use std::fmt::Write as _;
    let mut out = String::from("id,x,y,z,i,j,k,deviation_um,u_um,line,tool\n");
    for (p, r) in plan.points.iter().zip(&report.points) {
        debug_assert_eq!(p.id, r.id);
        let opt = |v: Option<f64>| v.map_or(String::new(), |v| format!("{:.4}", v + 0.0));
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{},{}",
            csv_field(&p.id),
            p.point[0],
            p.point[1],
            p.point[2],
            p.normal[0],
            p.normal[1],
            p.normal[2],
            opt(r.deviation_um),
            opt(r.deviation_u_um),
            r.line.map_or(String::new(), |l| l.to_string()),
            r.tool.map_or(String::new(), |t| t.to_string()),
        );
    }
    out
}

/// An id as a CSV field (quoted when it holds a comma or a quote).
fn csv_field(id: &str) -> String {
    if id.contains([',', '"', '\n']) {
        format!("\"{}\"", id.replace('"', "\"\""))
    } else {
        id.to_string()
    }
}
