//! `volcomp compensate`: the compensated program.
use super::common::{MachineArgs, ProgramArgs, Progress};
use crate::compensate::{
    CompensateOptions, CompensateReport, OrientationReport, PassedDefinition, SplitCap, compensate,
};
use crate::gcode::{ProgramInput, ProgramSetup};
use crate::io::{OutputError, write_atomic, write_json_atomic};
use crate::machine::{ErrorModel, Machine};
use crate::stamp::{Fnv1a64, Stamp, StampWriter};
use anyhow::Context;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc --tol 0.2 --report comp.json
  volcomp compensate machines/ref-trt.toml samples/saddle-tcp.nc -o - > saddle-tcp-comp.nc
  cat samples/saddle.nc | volcomp compensate machines/ref-trt.toml - -o from-stdin.nc
  cp samples/saddle.nc part.nc && volcomp compensate machines/ref-trt.toml part.nc --in-place
  volcomp compensate machines/ref-trt.toml part.nc -o again.nc --force   # compensate twice, knowingly
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o tip-only.nc --position-only
  volcomp compensate machines/bc-trt.toml samples/bc-trt/saddle.nc -o bc-comp.nc --tools samples/bc-trt/saddle.tbl";

const AFTER_HELP: &str = "\
Every motion target is moved so that the modelled actual tool tip (the machine's
measured errors, fitted as SMEM curves) lands on the programmed one, solved to
1 nm, and the modelled tool axis on the programmed axis, to 0.01 µrad, through
X Y Z and both rotary axes together (--position-only: X Y Z only, the rotary axes
as programmed, the tilt errors left in the axis; near the pole moves are
position-only anyway). A cutting move is split where the correction along it
departs from the straight move between its corrected ends by more than --tol.
Blocks that do not move, and every non-motion line, come out byte for byte. The
output is written to a temporary file and renamed: a failed or interrupted run
(SIGINT, SIGTERM) leaves no partial program.

The output starts with a provenance stamp, comment lines after the `%` and `O`
lines (volcomp version, machine, model hash, tool length, tolerance, input
hash). A program that carries one is refused (compensating twice doubles the
corrections) unless --force. -o naming the input itself (also through a link)
is refused unless --in-place. A program whose stamp or header names another
machine is compensated with a warning.

With --report, the summary also gives the expected residual from the model's own
noise: the standard uncertainty of the modelled error (table noise and fit,
propagated) at every move end, RMS and largest. That much remains after
compensation even if the model has every effect right.";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    #[command(flatten)]
    pub machine: MachineArgs,
    /// Program to compensate (`-` for standard input).
    pub program: PathBuf,
    /// Compensated program (`-` for standard output); not the input itself
    /// unless --in-place.
    #[arg(short, long, value_name = "OUT", required_unless_present = "in_place")]
    pub output: Option<PathBuf>,
    /// Replace the input program with the compensated one (through a temporary
    /// file renamed over it); -o may then be left out or name the input.
    #[arg(long)]
    pub in_place: bool,
    /// Compensate a program that carries volcomp's stamp (already compensated):
    /// its corrections are added again.
    #[arg(long)]
    pub force: bool,
    /// Split tolerance, µm: largest departure of a move from the compensated path.
    #[arg(long, value_name = "UM", default_value_t = 0.5)]
    pub tol: f64,
    /// Correct the tool axis too (the default): solve X Y Z A C so that the
    /// modelled actual tip AND tool axis are the programmed ones (A and C words
    /// change where the correction shows at the program's decimals). Near the
    /// A = 0 pole, where C cannot steer the axis, moves stay position-only
    /// (counted and reported).
    #[arg(long, conflicts_with = "position_only")]
    pub orientation: bool,
    /// Correct the tool tip only, A and C as programmed (the seed paper's
    /// compensation): the machine's tilt errors stay in the tool axis.
    #[arg(long)]
    pub position_only: bool,
    /// Write the summary as JSON, with the expected residual from the model's
    /// own noise.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub read: ProgramArgs,
    /// Do not check the compensated joints against the machine's travel limits.
    #[arg(long)]
    pub no_limits: bool,
}

/// A compensation run, validated: its output, where the summary goes, the
/// machine and its model.
struct Job<'a> {
    args: &'a Args,
    output: PathBuf,
    /// The program or the report goes to standard output (the summary to stderr).
    data_on_stdout: bool,
    machine: Machine,
    model: ErrorModel,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let job = Job::new(args)?;
    let outputs = crate::io::OutputSet::begin();
    let (input, setup, stamp) = job.read_input()?;
    let report = job.compensate(input, setup, stamp)?;
    if let Some(path) = &args.report {
        write_json_atomic(path, &report).map_err(|e: OutputError| anyhow::anyhow!(e))?;
    }
    outputs.commit()?;
    super::common::print_warnings(&report.warnings);
    // The summary goes to stderr when the program or the report goes to stdout.
    super::common::say(job.data_on_stdout, &summary_text(&report, &job.model))?;
    Ok(())
}

impl<'a> Job<'a> {
    /// Checks the arguments, loads the machine and its model, and checks the
    /// files (inputs against outputs) before anything is computed.
    fn new(args: &'a Args) -> anyhow::Result<Job<'a>> {
        if !(args.tol.is_finite() && args.tol > 0.0) {
            return Err(super::UsageError(format!(
                "--tol must be a positive number of µm (got {})",
                args.tol
            ))
            .into());
        }
        let output = output_path(args)?;
        let data_on_stdout = super::common::stdout_output(&[
            ("-o -", crate::io::is_stdio(&output)),
            (
                "--report -",
                super::common::is_stdout(args.report.as_deref()),
            ),
        ])?;
        let (machine, model) = args.machine.load()?;
        // With --in-place the program is the output (-o), not an input.
        super::common::CommandFiles::new()
            .input(
                "the program",
                (!args.in_place).then_some(args.program.as_path()),
            )
            .machine(&machine)
            .model(&args.machine.model)
            .program_args(&args.read)
            .output(
                if args.in_place {
                    "the program (--in-place)"
                } else {
                    "-o"
                },
                Some(&output),
            )
            .output("--report", args.report.as_deref())
            .check()?;
        Ok(Job {
            args,
            output,
            data_on_stdout,
            machine,
            model,
        })
    }

    /// Opens the program, refuses one that carries volcomp's stamp (unless
    /// --force), and returns it with its setup and the stamp to write.
    fn read_input(&self) -> anyhow::Result<(Box<dyn ProgramInput>, ProgramSetup, Stamp)> {
        let args = self.args;
        let (mut input, old_stamp) = super::common::open_program_with_stamp(&args.program)?;
        let name =
            crate::io::display_name(&args.program).replace("standard output", "standard input");
        if let (Some(old), false) = (&old_stamp, args.force) {
            anyhow::bail!(
                "{name} is already compensated ({}); compensating it again would add the corrections twice. \
Give the original program, or --force to compensate it anyway",
                old.summary()
            );
        }
        // The whole program is read for its hash: a stamp line anywhere in it
        // (not only at its head) is found too.
        let (input_hash, stamp_line) = super::common::program_hash(input.as_mut())?;
        if let (Some(line), false) = (stamp_line, args.force) {
            anyhow::bail!(
                "{name} is already compensated: line {line} is a line of volcomp's stamp; compensating it again would add the corrections twice. \
Give the original program, or --force to compensate it anyway"
            );
        }
        let setup = args.read.setup(Some(&self.machine))?;
        let head = super::common::program_head(input.as_mut())?;
        super::common::warn_other_machine(
            &setup.warnings,
            &name,
            &head,
            old_stamp.as_ref(),
            &self.machine.name,
        );
        let stamp = self.stamp(&setup, input_hash)?;
        Ok((input, setup, stamp))
    }

    /// The provenance stamp of the compensated program.
    fn stamp(&self, setup: &ProgramSetup, input_hash: Fnv1a64) -> anyhow::Result<Stamp> {
        let (args, machine) = (self.args, &self.machine);
        Ok(Stamp {
            compensated_by: format!("volcomp {}", env!("CARGO_PKG_VERSION")),
            machine: machine.name.clone(),
            model_fnv1a64: model_hash(machine)?.hex(),
            model_source: match &args.machine.model.model {
                Some(file) => format!("model {}", file.display()),
                None => format!("fit {}", args.machine.model.fit_description()),
            },
            tool_length_mm: Some(machine.tool.length),
            tools_mm: Stamp::tools_text(
                &setup
                    .tools
                    .entries()
                    .map(|t| (t.number, t.length_mm))
                    .collect::<Vec<_>>(),
            ),
            tolerance_um: Some(args.tol),
            input: if crate::io::is_stdio(&args.program) {
                "<stdin>".to_string()
            } else {
                args.program.display().to_string()
            },
            input_fnv1a64: input_hash.hex(),
            orientation: !args.position_only,
        })
    }

    /// The compensation's settings.
    fn options(&self) -> CompensateOptions {
        let (args, machine) = (self.args, &self.machine);
        CompensateOptions {
            tolerance_um: args.tol,
            interpret: args
                .read
                .interpret_options(machine.rapid_mm_per_min, machine.letters()),
            limits: (!args.no_limits).then_some(machine.limits),
            // The model's own noise at every move end: with --report only (it
            // doubles the run time).
            expected_residual: args.report.is_some(),
            orientation: !args.position_only,
            ..CompensateOptions::default()
        }
    }

    /// Compensates the program into the output (stamped, written atomically,
    /// with a progress bar) and returns the report with the run's warnings.
    fn compensate(
        &self,
        input: Box<dyn ProgramInput>,
        setup: ProgramSetup,
        stamp: Stamp,
    ) -> anyhow::Result<CompensateReport> {
        let (args, output) = (self.args, self.output.as_path());
        let options = self.options();
        let (input, total, position) = super::common::track(input)?;
        let program = crate::gcode::Program::new(input, &args.program, setup);
        super::common::announce_dialect(&program);
        let dialect = program.dialect().dialect;
        let warnings = program.warnings();
        let bar = Progress::new(&args.program, "compensating", total, position);
        let mut report: Option<CompensateReport> = None;
        write_atomic(output, |out| -> anyhow::Result<()> {
            // `( … )` lines for LinuxCNC, `;` lines for Sinumerik, `N ; …`
            // blocks after BEGIN PGM for Heidenhain (docs/dialects.md).
            let mut out = StampWriter::new(out, stamp).with_dialect(dialect);
            let r = compensate(program, &mut out, &self.model, &options, |n| {
                if let Some(b) = &bar {
                    b.update(n);
                }
            })?;
            out.finish()
                .map_err(|source| crate::io::OutputError::Write {
                    path: output.to_path_buf(),
                    source,
                })?;
            report = Some(r);
            Ok(())
        })
        .inspect_err(|_e| {
            if let Some(b) = &bar {
                b.abandon();
            }
        })
        .with_context(|| {
            format!(
                "the compensated program was not written (whole) to {}",
                crate::io::display_name(output)
            )
        })?;
        if let Some(b) = &bar {
            b.finish();
        }
        let mut report = report.expect("set by the writer");
        super::common::add_held_lookups(&warnings, report.held_lookups);
        if let Some(t) = &report.table_ends {
            add_table_ends(&warnings, &args.program, t);
        }
        report.warnings = warnings.groups();
        Ok(report)
    }
}

/// The human summary of a run: the counts and corrections, then what applies
/// (tool axis, reversal, tools, split cap, subroutine definitions).
fn summary_text(report: &CompensateReport, model: &ErrorModel) -> String {
    let mut msg = format!(
        "{} read, {} motion, {} changed, {} split (+{}){}\n\
max correction {:.3} µm (line {}), RMS {:.3} µm, solver residual ≤ {:.3} nm, tolerance {} µm\n\
{:.2} s ({} blocks/s)",
        super::common::count(report.blocks_read as u64, "block", "blocks"),
        report.motion_blocks,
        report.blocks_changed,
        report.blocks_split,
        super::common::count(report.blocks_added as u64, "block", "blocks"),
        super::common::result_note(&report.warnings),
        report.max_correction_um,
        report.max_correction_line,
        report.rms_correction_um,
        report.max_residual_nm,
        report.tolerance_um,
        report.seconds,
        super::common::thousands(report.blocks_read as f64 / report.seconds.max(1e-9)),
    );
    if let (Some(rms), Some(max)) = (
        report.expected_residual_rms_um,
        report.expected_residual_max_um,
    ) {
        msg.push_str(&format!(
            "\nexpected residual from the model's own noise (1 sigma; table noise and fit, \
unmodelled effects not included): RMS {rms:.3} µm, max {max:.3} µm"
        ));
    }
    if let Some(o) = &report.orientation {
        msg.push_str(&tool_axis_text(o, model));
    }
    msg.push_str(&reversal_text(model));
    msg.push_str(&tools_text(report));
    if let Some(cap) = &report.split_cap {
        msg.push_str(&split_cap_text(cap, report.tolerance_um));
    }
    msg.push_str(&subroutines_text(&report.subroutine_definitions));
    msg
}

/// The first `n` line numbers, joined with ", ".
fn first_lines(lines: &[usize], n: usize) -> String {
    lines
        .iter()
        .take(n)
        .map(|l| l.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// The tool axis's modelled error before and after, and the moves left
/// position-only near the pole.
fn tool_axis_text(o: &OrientationReport, model: &ErrorModel) -> String {
    // Where the outer rotary axis cannot steer the tool axis (A = 0 on an A/C table).
    let pole_axis = model
        .kinematics()
        .outer_rotary()
        .letter()
        .to_ascii_uppercase();
    format!(
        "\ntool axis (modelled, {}): error before max {:.3} RMS {:.3} µrad, after max {:.4} RMS {:.4} µrad; {} position-only near the pole (the tool axis along {pole_axis}, which cannot steer it){}",
        super::common::count(o.moves as u64, "move end", "move ends"),
        o.axis_error_before_max_urad,
        o.axis_error_before_rms_urad,
        o.axis_error_after_max_urad,
        o.axis_error_after_rms_urad,
        o.position_only_moves,
        if o.position_only_lines.is_empty() {
            String::new()
        } else {
            format!(" (lines {})", first_lines(&o.position_only_lines, 10))
        }
    )
}

/// The reversal is part of the correction: which axes carry one.
fn reversal_text(model: &ErrorModel) -> String {
    let reversal = model.reversal_axes();
    if reversal.is_empty() {
        return String::new();
    }
    let axes: Vec<String> = reversal
        .iter()
        .map(|(axis, source)| format!("{} ({source})", axis.letter()))
        .collect();
    format!(
        "\nreversal applied by each axis's approach direction: {}; a straight move that reverses such an axis gets a take-up piece (counted in the splits)",
        axes.join(", ")
    )
}

/// Per tool, when the program changes tools.
fn tools_text(report: &CompensateReport) -> String {
    let mut msg = String::new();
    if !report.tools.iter().any(|t| t.tool != 0) {
        return msg;
    }
    for t in &report.tools {
        let name = if t.tool == 0 {
            "default tool".to_string()
        } else {
            format!("T{}", t.tool)
        };
        msg.push_str(&format!(
            "
  {name} (L {} mm) lines {}–{}: {}, max correction {:.3} µm, RMS {:.3} µm",
            t.length_mm,
            t.first_line,
            t.last_line,
            super::common::count(t.moves as u64, "move", "moves"),
            t.max_correction_um,
            t.rms_correction_um
        ));
    }
    msg
}

/// The warning that moves reached the split cap still out of tolerance.
fn split_cap_text(cap: &SplitCap, tolerance_um: f64) -> String {
    format!(
        "\nwarning: {} move{} reached the split cap of {} pieces with the correction still departing from the pieces by up to {:.3} µm, more than the tolerance {} µm (line{} {}); raise --tol or split {} in the program",
        cap.moves,
        if cap.moves == 1 { "" } else { "s" },
        cap.pieces,
        cap.max_departure_um,
        if tolerance_um >= 1e-3 {
            tolerance_um.to_string()
        } else {
            format!("{tolerance_um:e}")
        },
        if cap.lines.len() == 1 { "" } else { "s" },
        first_lines(&cap.lines, 10) + if cap.moves > 10 { ", …" } else { "" },
        if cap.moves == 1 { "it" } else { "them" },
    )
}

/// The subroutine definitions written as they are (not executed, so not
/// compensated).
fn subroutines_text(definitions: &[PassedDefinition]) -> String {
    if definitions.is_empty() {
        return String::new();
    }
    let list: Vec<String> = definitions
        .iter()
        .take(10)
        .map(|d| format!("{} (lines {}–{})", d.name, d.first_line, d.last_line))
        .collect();
    let more = definitions.len().saturating_sub(10);
    let one = definitions.len() == 1;
    format!(
        "\n{} subroutine definition{} written as {}: not executed where {} (LinuxCNC skips {} there too), so not compensated; the calls this program makes are written flat and compensated: {}{}",
        definitions.len(),
        if one { "" } else { "s" },
        if one { "it is" } else { "they are" },
        if one { "it stands" } else { "they stand" },
        if one { "it" } else { "them" },
        list.join(", "),
        if more > 0 {
            format!(" and {more} more")
        } else {
            String::new()
        }
    )
}

/// Say once that move ends at a table's end were compensated with the end
/// value held over the sliver their corrections cross.
fn add_table_ends(
    warnings: &crate::warnings::Warnings,
    program: &std::path::Path,
    t: &crate::compensate::TableEndReport,
) {
    let file = crate::io::display_name(program).replace("standard output", "<stdin>");
    warnings.add(
        &crate::warnings::Warning {
            kind: "table_end",
            file: (t.moves > 0).then_some(file.as_str()),
            line: (t.moves > 0).then_some(t.first_line),
            column: None,
            effect: "table end held over a sliver",
        },
        t.moves.max(1) as u64,
        || {
            if t.moves == 0 {
                "a split point's correction crosses the end of an error table; the table's end value is held over that sliver".to_string()
            } else {
                format!(
                    "the target is inside the error tables but its correction crosses a table's end, by up to {:.3} µm{}: the table's end value is held over that sliver",
                    t.max_um,
                    if t.max_urad > 0.0 {
                        format!(" / {:.3} µrad", t.max_urad)
                    } else {
                        String::new()
                    }
                )
            }
        },
    );
}

/// Where the compensated program goes: `-o`, refused when it is the input
/// itself (same device and inode, so also through a symlink or a hard link)
/// unless `--in-place`; with `--in-place`, the input's real path.
fn output_path(args: &Args) -> anyhow::Result<PathBuf> {
    let usage = |m: String| -> anyhow::Error { super::UsageError(m).into() };
    let input_is_stdin = crate::io::is_stdio(&args.program);
    if args.in_place {
        if input_is_stdin {
            return Err(usage(
                "--in-place needs a program file, not standard input".into(),
            ));
        }
        if let Some(out) = args
            .output
            .as_ref()
            .filter(|o| !same_file(&args.program, o))
        {
            return Err(usage(format!(
                "--in-place replaces the input {}; -o {} is another file (leave -o out, or drop --in-place)",
                args.program.display(),
                crate::io::display_name(out)
            )));
        }
        // A symlink's target is replaced, not the link.
        return std::fs::canonicalize(&args.program)
            .with_context(|| format!("cannot open {}", args.program.display()));
    }
    let out = args
        .output
        .clone()
        .expect("clap requires -o without --in-place");
    if !input_is_stdin && same_file(&args.program, &out) {
        return Err(usage(format!(
            "-o {} is the input program {} (the same file); writing over it loses the original. \
Name another output, or pass --in-place to replace the program",
            out.display(),
            args.program.display()
        )));
    }
    Ok(out)
}

/// Are `a` and `b` the same file (links followed)?
fn same_file(a: &std::path::Path, b: &std::path::Path) -> bool {
    if crate::io::is_stdio(a) || crate::io::is_stdio(b) {
        return false;
    }
    match (std::fs::metadata(a), std::fs::metadata(b)) {
        #[cfg(unix)]
        (Ok(ma), Ok(mb)) => {
            use std::os::unix::fs::MetadataExt;
            ma.dev() == mb.dev() && ma.ino() == mb.ino()
        }
        #[cfg(not(unix))]
        (Ok(_), Ok(_)) => match (std::fs::canonicalize(a), std::fs::canonicalize(b)) {
            (Ok(x), Ok(y)) => x == y,
            _ => false,
        },
        _ => false,
    }
}

/// FNV-1a 64 over the error-table files' bytes as they were read (the data the
/// model was built from, not the files read again; a `--model` file is
/// checked against the same tables), in axis order,
/// then over the machine file's own error constants: the squareness, the
/// rotary location errors and the `[reversal]` constants (0 where absent), so
/// that two machine files with the same tables but other constants differ.
fn model_hash(machine: &crate::machine::Machine) -> anyhow::Result<Fnv1a64> {
    let mut hash = Fnv1a64::default();
    for table in machine.tables.iter().flatten() {
        hash.update(table.text.as_bytes());
    }
    let constants = machine
        .squareness
        .iter()
        .chain(machine.location.iter())
        .copied()
        .chain(machine.reversal.iter().map(|r| r.unwrap_or(0.0)));
    for v in constants {
        hash.update(&v.to_le_bytes());
    }
    Ok(hash)
}
