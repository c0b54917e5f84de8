//! `volcomp compensate`: the compensated program.
use super::common::{MachineArgs, ProgramArgs, Progress};
use crate::compensate::{CompensateOptions, CompensateReport, compensate};
use crate::io::{OutputError, write_atomic, write_json_atomic};
use crate::stamp::{Fnv1a64, Stamp, StampWriter};
use anyhow::Context;
use std::path::PathBuf;

const AFTER_HELP: &str = "\
Examples:
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc --tol 0.2 --report comp.json
  volcomp compensate machines/ref-trt.toml samples/saddle-tcp.nc -o - --frame joint > out.nc
  cat big.nc | volcomp compensate machines/ref-trt.toml - -o big-comp.nc
  volcomp compensate machines/ref-trt.toml part.nc --in-place          # replace part.nc
  volcomp compensate machines/ref-trt.toml part-comp.nc -o again.nc --force   # compensate twice, knowingly
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o tip-only.nc --position-only

Every motion target is moved so that the modelled actual tool tip (the machine's
measured errors, fitted as SMEM curves) lands on the programmed one, solved to
1 nm, and the modelled tool axis on the programmed axis, to 0.01 µrad, through
X Y Z A C together (--position-only: X Y Z only, A and C as programmed, the tilt
errors left in the axis; near the A = 0 pole moves are position-only anyway).
A cutting move is split where the correction along it departs from the
straight move between its corrected ends by more than --tol. Blocks that do not
move, and every non-motion line, come out byte for byte. The output is written to a temporary file and renamed: a failed or
interrupted run (SIGINT, SIGTERM) leaves no partial program.

The output starts with a provenance stamp, comment lines after the `%` and `O`
lines (volcomp version, machine, model hash, tool length, tolerance, input
hash). A program that carries one is refused (compensating twice doubles the
corrections) unless --force. -o naming the input itself (also through a link)
is refused unless --in-place.

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

pub fn run(args: &Args) -> anyhow::Result<()> {
    if !(args.tol.is_finite() && args.tol > 0.0) {
        return Err(super::UsageError(format!(
            "--tol must be a positive number of µm (got {})",
            args.tol
        ))
        .into());
    }
    let output = output_path(args)?;
    let output = output.as_path();
    let data_on_stdout = super::common::stdout_output(&[
        ("-o -", crate::io::is_stdio(output)),
        (
            "--report -",
            super::common::is_stdout(args.report.as_deref()),
        ),
    ])?;
    let (machine, model) = args.machine.load()?;
    // Where the outer rotary axis cannot steer the tool axis (A = 0 on an A/C table).
    let pole_axis = model
        .kinematics()
        .outer_rotary()
        .letter()
        .to_ascii_uppercase();
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
            Some(output),
        )
        .output("--report", args.report.as_deref())
        .check()?;
    let outputs = crate::io::OutputSet::begin();
    let options = CompensateOptions {
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
    };
    let (mut input, old_stamp) = super::common::open_program_with_stamp(&args.program)?;
    let name = crate::io::display_name(&args.program).replace("standard output", "standard input");
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
    let setup = args.read.setup(Some(&machine))?;
    let stamp = Stamp {
        compensated_by: format!("volcomp {}", env!("CARGO_PKG_VERSION")),
        machine: machine.name.clone(),
        model_fnv1a64: model_hash(&machine)?.hex(),
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
    };
    let (input, total, position) = super::common::track(input)?;
    let program = crate::gcode::Program::new(input, &args.program, setup);
    let warnings = program.warnings();
    let bar = Progress::new(&args.program, "compensating", total, position);
    let mut report: Option<CompensateReport> = None;
    write_atomic(output, |out| -> anyhow::Result<()> {
        let mut out = StampWriter::new(out, stamp);
        let r = compensate(program, &mut out, &model, &options, |n| {
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
    if let Some(path) = &args.report {
        write_json_atomic(path, &report).map_err(|e: OutputError| anyhow::anyhow!(e))?;
    }
    outputs.commit()?;
    super::common::print_warnings(&report.warnings);
    let msg = format!(
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
    ) + &match (
        report.expected_residual_rms_um,
        report.expected_residual_max_um,
    ) {
        (Some(rms), Some(max)) => format!(
            "\nexpected residual from the model's own noise (1 sigma; table noise and fit, \
unmodelled effects not included): RMS {rms:.3} µm, max {max:.3} µm"
        ),
        _ => String::new(),
    };
    let msg = match &report.orientation {
        Some(o) => format!(
            "{msg}\ntool axis (modelled, {}): error before max {:.3} RMS {:.3} µrad, after max {:.4} RMS {:.4} µrad; {} position-only near the pole (the tool axis along {pole_axis}, which cannot steer it){}",
            super::common::count(o.moves as u64, "move end", "move ends"),
            o.axis_error_before_max_urad,
            o.axis_error_before_rms_urad,
            o.axis_error_after_max_urad,
            o.axis_error_after_rms_urad,
            o.position_only_moves,
            if o.position_only_lines.is_empty() {
                String::new()
            } else {
                format!(
                    " (lines {})",
                    o.position_only_lines
                        .iter()
                        .take(10)
                        .map(|l| l.to_string())
                        .collect::<Vec<_>>()
                        .join(", ")
                )
            }
        ),
        None => msg,
    };
    // The reversal is part of the correction: say which axes carry one.
    let reversal = model.reversal_axes();
    let msg = if reversal.is_empty() {
        msg
    } else {
        let axes: Vec<String> = reversal
            .iter()
            .map(|(axis, source)| format!("{} ({source})", axis.letter()))
            .collect();
        format!(
            "{msg}\nreversal applied by each axis's approach direction: {}; a straight move that reverses such an axis gets a take-up piece (counted in the splits)",
            axes.join(", ")
        )
    };
    // Per tool, when the program changes tools.
    let msg = if report.tools.iter().any(|t| t.tool != 0) {
        let mut msg = msg;
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
    } else {
        msg
    };
    let msg = match &report.split_cap {
        Some(cap) => format!(
            "{msg}\nwarning: {} move{} reached the split cap of {} pieces with the correction still departing from the pieces by up to {:.3} µm, more than the tolerance {} µm (line{} {}); raise --tol or split {} in the program",
            cap.moves,
            if cap.moves == 1 { "" } else { "s" },
            cap.pieces,
            cap.max_departure_um,
            if report.tolerance_um >= 1e-3 {
                report.tolerance_um.to_string()
            } else {
                format!("{:e}", report.tolerance_um)
            },
            if cap.lines.len() == 1 { "" } else { "s" },
            cap.lines
                .iter()
                .take(10)
                .map(|l| l.to_string())
                .collect::<Vec<_>>()
                .join(", ")
                + if cap.moves > 10 { ", …" } else { "" },
            if cap.moves == 1 { "it" } else { "them" },
        ),
        None => msg,
    };
    let msg = if report.subroutine_definitions.is_empty() {
        msg
    } else {
        let list: Vec<String> = report
            .subroutine_definitions
            .iter()
            .take(10)
            .map(|d| format!("{} (lines {}–{})", d.name, d.first_line, d.last_line))
            .collect();
        let more = report.subroutine_definitions.len().saturating_sub(10);
        format!(
            "{msg}\n{} subroutine definition{} written as {}: not executed where {} (LinuxCNC skips {} there too), so not compensated; the calls this program makes are written flat and compensated: {}{}",
            report.subroutine_definitions.len(),
            if report.subroutine_definitions.len() == 1 {
                ""
            } else {
                "s"
            },
            if report.subroutine_definitions.len() == 1 {
                "it is"
            } else {
                "they are"
            },
            if report.subroutine_definitions.len() == 1 {
                "it stands"
            } else {
                "they stand"
            },
            if report.subroutine_definitions.len() == 1 {
                "it"
            } else {
                "them"
            },
            list.join(", "),
            if more > 0 {
                format!(" and {more} more")
            } else {
                String::new()
            }
        )
    };
    // The summary goes to stderr when the program or the report goes to stdout.
    super::common::say(data_on_stdout, &msg)?;
    Ok(())
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

/// FNV-1a 64 over the error-table files' bytes, in axis order (the data the
/// model was fitted to; a `--model` file is checked against the same tables),
/// then over the machine file's own error constants: the squareness, the
/// rotary location errors and the `[reversal]` constants (0 where absent), so
/// that two machine files with the same tables but other constants differ.
fn model_hash(machine: &crate::machine::Machine) -> anyhow::Result<Fnv1a64> {
    let mut hash = Fnv1a64::default();
    for table in machine.tables.iter().flatten() {
        let bytes = std::fs::read(&table.path)
            .with_context(|| format!("cannot read {}", table.path.display()))?;
        hash.update(&bytes);
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
