//! `volcomp compensate`: the compensated program.
use super::common::{MachineArgs, ProgramArgs, progress_bar};
use crate::compensate::{CompensateOptions, CompensateReport, compensate};
use crate::io::{OutputError, write_atomic, write_json_atomic};
use anyhow::Context;
use std::path::PathBuf;

const AFTER_HELP: &str = "\
Examples:
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc --tol 0.2 --report comp.json
  volcomp compensate machines/ref-trt.toml samples/saddle-tcp.nc -o - --frame joint > out.nc
  cat big.nc | volcomp compensate machines/ref-trt.toml - -o big-comp.nc

Every motion target is moved so that the modelled actual tool tip (the machine's
measured errors, fitted as SMEM curves) lands on the programmed one, solved to
1 nm; A and C stay as programmed. A cutting move is split where the correction
along it departs from the straight move between its corrected ends by more than
--tol. Blocks that do not move, and every non-motion line, come out byte for
byte. The output is written to a temporary file and renamed: a failed run leaves
no partial program.";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Program to compensate (`-` for standard input).
    pub program: PathBuf,
    /// Compensated program (`-` for standard output).
    #[arg(short, long, value_name = "OUT")]
    pub output: PathBuf,
    /// Split tolerance, µm: largest departure of a move from the compensated path.
    #[arg(long, value_name = "UM", default_value_t = 0.5)]
    pub tol: f64,
    /// Write the summary as JSON.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub read: ProgramArgs,
    /// Do not check the compensated joints against the machine's travel limits.
    #[arg(long)]
    pub no_limits: bool,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if !(args.tol.is_finite() && args.tol > 0.0) {
        return Err(super::UsageError(format!(
            "--tol must be a positive number of µm (got {})",
            args.tol
        ))
        .into());
    }
    let (machine, model) = args.machine.load()?;
    let options = CompensateOptions {
        tolerance_um: args.tol,
        interpret: args.read.interpret_options(machine.rapid_mm_per_min),
        limits: (!args.no_limits).then(|| machine.limits.clone()),
        ..CompensateOptions::default()
    };
    let program = args.read.program(&args.program)?;
    let bar = progress_bar(&args.program, "compensating");
    let mut report: Option<CompensateReport> = None;
    write_atomic(&args.output, |out| -> anyhow::Result<()> {
        let r = compensate(program, out, &model, &options, |n| {
            if let Some(b) = &bar {
                b.set_position(n as u64);
            }
        })?;
        report = Some(r);
        Ok(())
    })
    .map_err(|e| {
        if let Some(b) = &bar {
            b.abandon();
        }
        e
    })
    .with_context(|| format!("no output was written to {}", args.output.display()))?;
    if let Some(b) = &bar {
        b.finish_and_clear();
    }
    let report = report.expect("set by the writer");
    if let Some(path) = &args.report {
        write_json_atomic(path, &report).map_err(|e: OutputError| anyhow::anyhow!(e))?;
    }
    let msg = format!(
        "{} blocks read, {} motion, {} changed, {} split (+{} blocks)\n\
max correction {:.3} µm (line {}), RMS {:.3} µm, solver residual ≤ {:.3} nm, tolerance {} µm\n\
{:.2} s ({:.0} blocks/s){}",
        report.blocks_read,
        report.motion_blocks,
        report.blocks_changed,
        report.blocks_split,
        report.blocks_added,
        report.max_correction_um,
        report.max_correction_line,
        report.rms_correction_um,
        report.max_residual_nm,
        report.tolerance_um,
        report.seconds,
        report.blocks_read as f64 / report.seconds.max(1e-9),
        if report.held_lookups > 0 {
            format!(
                "\n{} lookups outside the error tables held the end value (--extrapolate hold)",
                report.held_lookups
            )
        } else {
            String::new()
        }
    );
    // The summary goes to stderr when the program itself goes to stdout.
    super::common::say(crate::io::is_stdio(&args.output), &msg);
    Ok(())
}
