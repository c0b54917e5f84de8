//! `volcomp export`: the fitted error model as controllers read it.
use super::common::MachineArgs;
use crate::export::linuxcnc::{CompSettings, CompType, MAX_COMP_LINES};
use crate::export::tables::GridSettings;
use anyhow::Context;
use std::path::{Path, PathBuf};

const AFTER_HELP: &str = "\
Examples:
  volcomp export linuxcnc machines/ref-trt.toml -o linuxcnc-ref-trt
  volcomp export linuxcnc machine.toml -o comp --comp-type 1 --tol-um 0.05
  volcomp export tables machines/ref-trt.toml -o fitted --step 5 --step-deg 1";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    #[command(subcommand)]
    pub target: Target,
}

#[derive(Debug, clap::Subcommand)]
pub enum Target {
    /// LinuxCNC: a COMP_FILE per linear joint, the trt module's corrected pivot parameters, README.txt.
    Linuxcnc(LinuxcncArgs),
    /// Every error table as fitted, on a grid you choose: DIR/<axis>.csv in volcomp's table format.
    Tables(TablesArgs),
}

const LINUXCNC_HELP: &str = "\
Examples:
  volcomp export linuxcnc machines/ref-trt.toml -o linuxcnc-ref-trt
  volcomp export linuxcnc machine.toml -o comp --comp-type 1

Writes into DIR:
  <axis>.comp      for each linear axis whose table measures its positioning error (EXX, EYY,
                   EZZ): LinuxCNC's COMP_FILE triplets `nominal forward reverse` (mm), ascending,
                   at most 256, nothing before them (LinuxCNC stops reading at the first line that
                   is not three numbers); forward/reverse = the fitted curve ± REVERSAL/2 when the
                   table has REVERSAL (volcomp import-laser); provenance after the triplets.
  kinematics.ini   xyzac-trt / xyzbc-trt: the module's pivot parameters corrected by the machine
                   file's location errors, as [HAL] HALCMD = setp lines.
  README.txt       the [JOINT_n] COMP_FILE and COMP_FILE_TYPE lines to paste.
Nominals are the table's positions, bisected until LinuxCNC's linear interpolation is within
--tol-um of the fitted curves (or --max-lines is reached: the summary says so).";

#[derive(Debug, clap::Args)]
#[command(after_help = LINUXCNC_HELP)]
pub struct LinuxcncArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Folder to write into (made if missing).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// COMP_FILE_TYPE: 0 lists actual positions, 1 the trims LinuxCNC adds (nominal − actual).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=1))]
    pub comp_type: u8,
    /// Largest departure (µm) of LinuxCNC's linear interpolation from the fitted curves.
    #[arg(long, default_value_t = 0.1, value_name = "UM")]
    pub tol_um: f64,
    /// Most triplets a file may have (2 to 256, LinuxCNC's limit).
    #[arg(long, default_value_t = MAX_COMP_LINES)]
    pub max_lines: usize,
}

const TABLES_HELP: &str = "\
Examples:
  volcomp export tables machines/ref-trt.toml -o fitted --step 5 --step-deg 1

Writes DIR/<axis>.csv for each measured axis: `position` on the grid (the table's first
position, then every --step mm or --step-deg degrees, and its last position), each fitted
parameter's value (µm, µrad; error = actual − nominal) and REVERSAL when the table has it
(linear between the measured positions). The files are volcomp error tables: a machine file
can name them.";

#[derive(Debug, clap::Args)]
#[command(after_help = TABLES_HELP)]
pub struct TablesArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Folder to write into (made if missing).
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Grid spacing on linear axes, mm.
    #[arg(long, default_value_t = 1.0, value_name = "MM")]
    pub step: f64,
    /// Grid spacing on rotary axes, degrees.
    #[arg(long, default_value_t = 1.0, value_name = "DEG")]
    pub step_deg: f64,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    match &args.target {
        Target::Linuxcnc(a) => linuxcnc(a),
        Target::Tables(a) => tables(a),
    }
}

fn make_dir(dir: &Path) -> anyhow::Result<()> {
    if crate::io::is_stdio(dir) {
        return Err(
            super::UsageError("-o names a folder; `-` cannot hold several files".into()).into(),
        );
    }
    std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))
}

fn linuxcnc(args: &LinuxcncArgs) -> anyhow::Result<()> {
    if !(2..=MAX_COMP_LINES).contains(&args.max_lines) {
        return Err(super::UsageError(format!(
            "--max-lines {}: LinuxCNC takes 2 to {MAX_COMP_LINES} lines a joint",
            args.max_lines
        ))
        .into());
    }
    if !(args.tol_um.is_finite() && args.tol_um > 0.0) {
        return Err(super::UsageError(format!(
            "--tol-um {}: must be a positive number",
            args.tol_um
        ))
        .into());
    }
    let (machine, model) = args.machine.load()?;
    let settings = CompSettings {
        comp_type: if args.comp_type == 1 {
            CompType::Trim
        } else {
            CompType::Actual
        },
        tolerance_um: args.tol_um,
        max_lines: args.max_lines,
    };
    // Made before the folder, so a machine without tables leaves nothing behind.
    let name_for_readme = std::path::absolute(&args.output).unwrap_or_else(|_| args.output.clone());
    let export = crate::export::linuxcnc::export(
        &machine,
        &model,
        &settings,
        &name_for_readme.display().to_string(),
    )?;
    make_dir(&args.output)?;
    for f in &export.comp_files {
        let path = args.output.join(format!("{}.comp", f.axis.lower()));
        crate::io::write_file_atomic(&path, f.text.as_bytes())?;
        crate::cli::outln!(
            "{} (joint {}): {} lines, within {:.4} µm of the fitted {}{} -> {}",
            f.axis.letter(),
            f.joint,
            f.nominals.len(),
            f.max_error_um,
            f.parameter,
            if f.reversal {
                " ± REVERSAL/2"
            } else {
                " (no REVERSAL)"
            },
            path.display()
        );
        if !f.met {
            eprintln!(
                "warning: {}: {} lines do not meet --tol-um {} (within {:.4} µm); {}",
                f.axis.letter(),
                f.nominals.len(),
                args.tol_um,
                f.max_error_um,
                unmet_tolerance_advice(args.max_lines, f.max_error_um)
            );
        }
    }
    for (axis, why) in &export.skipped {
        crate::cli::outln!("{}: no COMP_FILE ({why})", axis.letter());
    }
    match &export.kinematics_ini {
        Some(text) => {
            let path = args.output.join("kinematics.ini");
            crate::io::write_file_atomic(&path, text.as_bytes())?;
            crate::cli::outln!(
                "{} pivot parameters corrected by the location errors -> {}",
                machine.kinematics.name(),
                path.display()
            );
        }
        None => crate::cli::outln!("{}", export.kinematics_note.as_deref().unwrap_or_default()),
    }
    let path = args.output.join("README.txt");
    crate::io::write_file_atomic(&path, export.readme.as_bytes())?;
    crate::cli::outln!("[JOINT_n] lines to paste -> {}", path.display());
    Ok(())
}

/// What to do when a COMP_FILE of `max_lines` lines stays `reached_um` from
/// the fitted curve: raise --max-lines while it is below LinuxCNC's limit;
/// at the limit, say so, and that only a larger tolerance (or a smoother fit,
/// which needs fewer lines) remains.
fn unmet_tolerance_advice(max_lines: usize, reached_um: f64) -> String {
    if max_lines < MAX_COMP_LINES {
        format!(
            "raise --max-lines (now {max_lines}, LinuxCNC takes up to {MAX_COMP_LINES}) or --tol-um"
        )
    } else {
        format!(
            "--max-lines is at LinuxCNC's limit of {MAX_COMP_LINES} lines a joint: give --tol-um {:.4} or more, \
or fit a smoother curve (fit --select cv, the default) that fewer lines follow",
            (reached_um * 1e4).ceil() / 1e4
        )
    }
}

fn tables(args: &TablesArgs) -> anyhow::Result<()> {
    let (machine, model) = args.machine.load()?;
    let settings = GridSettings {
        step_mm: args.step,
        step_deg: args.step_deg,
    };
    let tables = crate::export::tables::fitted_tables(&machine, &model, &settings)?;
    make_dir(&args.output)?;
    for t in &tables {
        let path = args.output.join(format!("{}.csv", t.axis.lower()));
        crate::io::write_file_atomic(&path, t.text.as_bytes())?;
        crate::cli::outln!(
            "{}: {} rows ({}) -> {}",
            t.axis.letter(),
            t.rows,
            t.columns.join(", "),
            path.display()
        );
    }
    Ok(())
}
