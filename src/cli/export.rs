//! `volcomp export`: the fitted error model as controllers read it.
use super::common::MachineArgs;
use crate::export::linuxcnc::{CompSettings, CompType, MAX_COMP_LINES};
use crate::export::tables::GridSettings;
use std::path::{Path, PathBuf};

pub const EXAMPLES: &str = "\
  volcomp export linuxcnc machines/ref-trt.toml -o linuxcnc-ref-trt
  volcomp export linuxcnc machines/bc-trt.toml -o comp --comp-type 1 --tol-um 0.05
  volcomp export tables machines/ref-trt.toml -o fitted --step 5 --step-deg 1";

#[derive(Debug, clap::Args)]
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

pub const LINUXCNC_EXAMPLES: &str = "\
  volcomp export linuxcnc machines/ref-trt.toml -o linuxcnc-ref-trt
  volcomp export linuxcnc machines/bc-trt.toml -o comp --comp-type 1
  volcomp export linuxcnc machines/ref-trt.toml -o lcnc --residual-machine lcnc/residual.toml";

const LINUXCNC_HELP: &str = "\
Writes into DIR:
  <axis>.comp      for each linear axis whose table measures its positioning error (EXX, EYY,
                   EZZ): LinuxCNC's COMP_FILE triplets `nominal forward reverse` (mm), ascending,
                   at most 256, nothing before them (LinuxCNC stops reading at the first line that
                   is not three numbers); forward/reverse = the fitted curve ± REVERSAL/2 when the
                   table has REVERSAL (volcomp import-laser); provenance after the triplets.
  kinematics.ini   xyzac-trt / xyzbc-trt: the module's pivot parameters corrected by the machine
                   file's location errors, as [HAL] HALCMD = setp lines.
  README.txt       the [JOINT_n] COMP_FILE and COMP_FILE_TYPE lines to paste.
With --residual-machine OUT.toml, also the machine file to compensate with on that LinuxCNC
(no double correction): each exported axis's table as OUT.<axis>.csv with its positioning
column and REVERSAL replaced by what the COMP_FILE leaves, the location offsets kinematics.ini
expresses moved into [geometry]; a comment on top says what was removed.
Nominals are the table's positions, bisected until LinuxCNC's linear interpolation is within
--tol-um of the fitted curves (or --max-lines is reached: the summary says so).";

#[derive(Debug, clap::Args)]
#[command(after_help = LINUXCNC_HELP)]
pub struct LinuxcncArgs {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Folder to write into (made if missing). A file there that the export
    /// would replace is refused unless --force.
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Replace files of DIR that the export writes (x.comp, kinematics.ini,
    /// README.txt) when they exist already.
    #[arg(long)]
    pub force: bool,
    /// COMP_FILE_TYPE: 0 lists actual positions, 1 the trims LinuxCNC adds (nominal − actual).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u8).range(0..=1))]
    pub comp_type: u8,
    /// Largest departure (µm) of LinuxCNC's linear interpolation from the fitted curves.
    #[arg(long, default_value_t = 0.1, value_name = "UM")]
    pub tol_um: f64,
    /// Most triplets a file may have (2 to 256, LinuxCNC's limit).
    #[arg(long, default_value_t = MAX_COMP_LINES)]
    pub max_lines: usize,
    /// Also write the machine file for `volcomp compensate` on a LinuxCNC that
    /// applies this export: the exported positioning errors (and REVERSAL)
    /// replaced by what is left after the COMP_FILEs, the location offsets
    /// moved into [geometry] as in kinematics.ini, the rest kept; its changed
    /// tables beside it (OUT.x.csv, ...).
    #[arg(long, value_name = "OUT.toml")]
    pub residual_machine: Option<PathBuf>,
}

pub const TABLES_EXAMPLES: &str = "\
  volcomp export tables machines/ref-trt.toml -o fitted --step 5 --step-deg 1";

const TABLES_HELP: &str = "\
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
    /// Folder to write into (made if missing). A file there that the export
    /// would replace is refused unless --force.
    #[arg(short, long, value_name = "DIR")]
    pub output: PathBuf,
    /// Replace files of DIR that the export writes (<axis>.csv) when they
    /// exist already.
    #[arg(long)]
    pub force: bool,
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

/// The files an export writes into its folder, checked before anything is
/// fitted: none is an input (the machine file, a table: `-o` naming the
/// tables' own folder), none exists already unless `--force` (a folder holds
/// other files than the export's: they are not replaced without notice). The
/// folder is made, when missing, as the files are written. Then the model
/// is fitted (or loaded): the machine and its model.
fn checked_model(
    dir: &Path,
    machine: crate::machine::Machine,
    args: &MachineArgs,
    files: &[PathBuf],
    force: bool,
) -> anyhow::Result<(crate::machine::Machine, crate::machine::ErrorModel)> {
    if crate::io::is_stdio(dir) {
        return Err(
            super::UsageError("-o names a folder; `-` cannot hold several files".into()).into(),
        );
    }
    if dir.exists() && !dir.is_dir() {
        return Err(super::UsageError(format!(
            "-o {} is a file; it names the folder to write into",
            dir.display()
        ))
        .into());
    }
    let mut check = super::common::CommandFiles::new()
        .machine(&machine)
        .model(&args.model);
    for file in files {
        check = check.output("(-o)", Some(file));
    }
    check.check()?;
    let existing: Vec<String> = files
        .iter()
        .filter(|f| std::fs::symlink_metadata(f).is_ok())
        .map(|f| f.display().to_string())
        .collect();
    if !force && !existing.is_empty() {
        return Err(super::UsageError(format!(
            "{} already exist{}: the export does not replace files without notice (pass --force to replace them, or name a new folder)",
            existing.join(", "),
            if existing.len() == 1 { "s" } else { "" }
        ))
        .into());
    }
    super::common::fit_model(machine, &args.machine_file, &args.model)
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
    let machine = super::common::load_machine(&args.machine.machine_file, &args.machine.model)?;
    let mut files: Vec<PathBuf> = machine
        .letters()
        .iter()
        .filter(|a| !a.is_rotary())
        .filter(|a| {
            let parameter = crate::laser::positioning_parameter(*a);
            machine
                .table(*a)
                .is_some_and(|t| t.columns.iter().any(|c| c.name == parameter))
        })
        .map(|a| args.output.join(format!("{}.comp", a.lower())))
        .collect();
    if crate::export::linuxcnc::kinematics_ini(&machine).is_some() {
        files.push(args.output.join("kinematics.ini"));
    }
    files.push(args.output.join("README.txt"));
    if let Some(out) = &args.residual_machine {
        files.push(out.clone());
        files.extend(
            machine
                .letters()
                .iter()
                .filter(|a| !a.is_rotary() && machine.table(*a).is_some())
                .map(|a| super::write_machine::table_copy(out, a)),
        );
    }
    let (machine, model) = checked_model(&args.output, machine, &args.machine, &files, args.force)?;
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
    let outputs = crate::io::OutputSet::begin();
    let mut lines = Vec::new();
    for f in &export.comp_files {
        let path = args.output.join(format!("{}.comp", f.axis.lower()));
        crate::io::write_file_atomic(&path, f.text.as_bytes())?;
        lines.push(format!(
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
        ));
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
        lines.push(format!("{}: no COMP_FILE ({why})", axis.letter()));
    }
    match &export.kinematics_ini {
        Some(text) => {
            let path = args.output.join("kinematics.ini");
            crate::io::write_file_atomic(&path, text.as_bytes())?;
            lines.push(format!(
                "{} pivot parameters corrected by the location errors -> {}",
                machine.kinematics.name(),
                path.display()
            ));
        }
        None => lines.push(
            export
                .kinematics_note
                .as_deref()
                .unwrap_or_default()
                .to_string(),
        ),
    }
    let path = args.output.join("README.txt");
    crate::io::write_file_atomic(&path, export.readme.as_bytes())?;
    lines.push(format!("[JOINT_n] lines to paste -> {}", path.display()));
    if let Some(out) = &args.residual_machine {
        lines.extend(write_residual_machine(
            out,
            &machine,
            &model,
            &export,
            &name_for_readme.display().to_string(),
        )?);
    }
    outputs.commit()?;
    for line in lines {
        crate::cli::outln!("{line}");
    }
    Ok(())
}

/// Writes `--residual-machine OUT` (inside the command's output set): the
/// machine file edited, the exported axes' tables beside it, the other tables
/// re-pointed from OUT's folder. Returns the summary lines.
fn write_residual_machine(
    out: &Path,
    machine: &crate::machine::Machine,
    model: &crate::machine::ErrorModel,
    export: &crate::export::linuxcnc::LinuxCncExport,
    comp_dir: &str,
) -> anyhow::Result<Vec<String>> {
    use crate::machine::update::{edit_machine_text, relative_path, toml_path};
    use anyhow::Context as _;
    let residual = crate::export::residual::residual_machine(machine, model, export, comp_dir)?;
    let folder = crate::io::resolved_path(out)
        .and_then(|p| p.parent().map(Path::to_path_buf))
        .with_context(|| {
            format!(
                "--residual-machine {}: its folder cannot be found",
                out.display()
            )
        })?;
    let mut edits = residual.edits.clone();
    let mut lines = Vec::new();
    for slot in machine.tables.iter().flatten() {
        let key = slot.axis.lower().to_string();
        if let Some(t) = residual.tables.iter().find(|t| t.axis == slot.axis) {
            let copy = super::write_machine::table_copy(out, slot.axis);
            crate::io::write_file_atomic(&copy, t.text.as_bytes())?;
            let name = copy.file_name().unwrap_or_default().to_string_lossy();
            edits.tables.push((key, name.into_owned()));
            lines.push(format!(
                "{}: table with what the COMP_FILE leaves -> {}",
                slot.axis.letter(),
                copy.display()
            ));
        } else {
            let at = std::fs::canonicalize(&slot.path)
                .with_context(|| format!("locating the error table {}", slot.path.display()))?;
            let path = relative_path(&folder, &at).unwrap_or(at);
            edits.tables.push((key, toml_path(&path)));
        }
    }
    let text = edit_machine_text(&machine.text, &machine.source, &edits)?;
    crate::io::write_file_atomic(out, text.as_bytes())?;
    lines.push(format!(
        "residual machine (compensate with it on that LinuxCNC) -> {}",
        out.display()
    ));
    lines.extend(residual.removed.iter().map(|r| format!("  removed {r}")));
    Ok(lines)
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
    use crate::machine::physical_ranges::{MAX_STEP_DEG, MAX_STEP_MM, check_range};
    check_range("--step", "mm", args.step, (0.0, MAX_STEP_MM), true).map_err(super::UsageError)?;
    check_range("--step-deg", "°", args.step_deg, (0.0, MAX_STEP_DEG), true)
        .map_err(super::UsageError)?;
    let machine = super::common::load_machine(&args.machine.machine_file, &args.machine.model)?;
    let files: Vec<PathBuf> = machine
        .letters()
        .iter()
        .filter(|a| machine.table(*a).is_some())
        .map(|a| args.output.join(format!("{}.csv", a.lower())))
        .collect();
    let (machine, model) = checked_model(&args.output, machine, &args.machine, &files, args.force)?;
    let settings = GridSettings {
        step_mm: args.step,
        step_deg: args.step_deg,
    };
    let tables = crate::export::tables::fitted_tables(&machine, &model, &settings)?;
    let outputs = crate::io::OutputSet::begin();
    for t in &tables {
        let path = args.output.join(format!("{}.csv", t.axis.lower()));
        crate::io::write_file_atomic(&path, t.text.as_bytes())?;
    }
    outputs.commit()?;
    for t in &tables {
        let path = args.output.join(format!("{}.csv", t.axis.lower()));
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
