//! The command line: clap arguments → validated job → library call → summary.
//!
//! Invariants: only this module prints; library modules return typed errors and
//! values. Each command lives in its own file with its `Args` (stage one, what
//! clap parses) and `run` (stage two: validate into the library's options struct,
//! run, print the summary, write outputs atomically).
//!
//! Exit codes (gcode.md): 0 success, 1 bad input, 2 usage error (clap's own
//! errors and [`UsageError`]). Beyond the contract: 141 when standard output is
//! a pipe closed early (EPIPE: a quiet stop, no message, as a process killed by
//! SIGPIPE), 130/143/129/153 on SIGINT/SIGTERM/SIGHUP/SIGXFSZ (temporary files
//! removed).
//!
//! Standard output is written through [`outln!`] / [`stdout_line`], never
//! `println!` (which panics on a closed pipe): a failed write is an error.
use clap::{Parser, Subcommand};

mod check;
mod common;
mod compensate;
mod diagnose;
mod diff;
mod error;
mod export;
mod fit;
mod import_laser;
mod map;
mod plan_frame;
mod predict;
mod sample;
mod shell;
mod simulate;
mod write_machine;

const EXAMPLES: &str = "\
  volcomp fit machines/ref-trt.toml --report fit.json
  volcomp error machines/ref-trt.toml --at 10,20,-30,15,45 --json
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc --report comp.json
  volcomp predict machines/ref-trt.toml samples/saddle.nc --plan samples/saddle-plan.csv --report pred.json --html pred.html
  volcomp diff samples/saddle.nc saddle-comp.nc
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv -o meas.csv --effect backlash:bx=6
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json --html diag.html
  volcomp -q compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc   # no summary
  volcomp completions bash > volcomp.bash
  volcomp man -o man";

const AFTER_HELP: &str = "\
-q and -v go before the command: -q prints only the data a command was asked for, its \
warnings and errors (no summary, notes or progress bar); -v adds detail: the time the \
command took, and with `error` each parameter's contribution (as `error --verbose`).";

#[derive(Debug, Parser)]
#[command(
    name = "volcomp",
    version,
    about = "Volumetric error compensation for five-axis machine tools (SMEM, He et al. 2016)",
    long_about = "Reads the G-code a CAM system wrote, predicts where the real machine puts the tool \
from its measured error tables (fitted as cubic NURBS curves, the SMEM), and rewrites the program \
so the part comes out right. Files use the formats of the project's docs (machine TOML, error CSV, \
inspection plans, measurements); `-` means standard input or output. Outputs: no option writes over \
an input or another output; a command writes all its outputs or none; a missing folder of an output \
is created (one that cannot be, refused before anything is computed).",
    after_help = AFTER_HELP
)]
pub struct Cli {
    /// Quiet: no summary, notes or progress bar; data, warnings and errors still print.
    #[arg(short, long, conflicts_with = "verbose")]
    pub quiet: bool,
    /// Verbose: more detail (the time taken; `error`: each parameter's contribution).
    #[arg(short, long)]
    pub verbose: bool,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Debug, Subcommand)]
pub enum Command {
    /// Fit the SMEM (cubic NURBS) of every error table of a machine, or of one table.
    Fit(fit::Args),
    /// Volumetric error and tool-axis error at one pose or many.
    Error(error::Args),
    /// Volumetric error map over a plane (SVG heat map, fitted NURBS surface).
    Map(map::Args),
    /// Parse and interpret a program; report its blocks, frames, time and problems.
    Check(check::Args),
    /// Rewrite a program so the modelled tool tip and axis land on the programmed ones.
    Compensate(compensate::Args),
    /// Predicted deviations and profile error of the part a program cuts.
    Predict(predict::Args),
    /// Block-by-block comparison of two programs.
    Diff(diff::Args),
    /// Synthetic CMM measurements: geometric error plus unmodelled effects plus noise.
    Simulate(simulate::Args),
    /// Explain the gap between measured and predicted deviations.
    Diagnose(diagnose::Args),
    /// Laser positioning runs (ISO 230-2, bidirectional) to an axis's error table and report.
    ImportLaser(import_laser::Args),
    /// Controller files out: LinuxCNC COMP_FILEs and kinematics parameters, fitted tables as CSV.
    Export(export::Args),
    /// Write the bundled samples: the saddle (program, plan, tool table) or the flank (program, plan).
    Sample(sample::Args),
    /// Shell completions (bash, zsh, fish, powershell) on standard output.
    Completions(shell::CompletionsArgs),
    /// The manual pages (roff): volcomp.1 on standard output, or every page into a folder.
    Man(shell::ManArgs),
}

/// How much the command prints beyond its data: `-q`, default, `-v`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verbosity {
    /// `-q`: data, warnings and errors only.
    Quiet,
    /// The summary and notes.
    Normal,
    /// `-v`: and more detail.
    Verbose,
}

static VERBOSITY: std::sync::atomic::AtomicU8 = std::sync::atomic::AtomicU8::new(1);

/// The run's verbosity (`-q`, `-v`).
pub fn verbosity() -> Verbosity {
    match VERBOSITY.load(std::sync::atomic::Ordering::Relaxed) {
        0 => Verbosity::Quiet,
        1 => Verbosity::Normal,
        _ => Verbosity::Verbose,
    }
}

fn set_verbosity(v: Verbosity) {
    VERBOSITY.store(v as u8, std::sync::atomic::Ordering::Relaxed);
}

/// Is `-q` in effect?
pub fn quiet() -> bool {
    verbosity() == Verbosity::Quiet
}

/// Print a note on standard error (`note: …`) unless `-q`, and only once per
/// command: a note already printed (the same machine loaded twice) is not
/// repeated.
pub fn note(text: String) {
    static SAID: std::sync::Mutex<Vec<String>> = std::sync::Mutex::new(Vec::new());
    if quiet() {
        return;
    }
    let mut said = SAID.lock().unwrap_or_else(|e| e.into_inner());
    if !said.contains(&text) {
        eprintln!("note: {text}");
        said.push(text);
    }
}

/// [`note`] with `format!` arguments.
macro_rules! noteln {
    ($($arg:tt)*) => {
        $crate::cli::note(format!($($arg)*))
    };
}
pub(crate) use noteln;

/// The examples of every help page, by the page's command path (`""` for
/// `volcomp` itself, `"export linuxcnc"`): printed verbatim at the end of
/// the page, never wrapped, so that each example is one whole command at any
/// terminal width.
fn examples(path: &str) -> Option<&'static str> {
    Some(match path {
        "" => EXAMPLES,
        "fit" => fit::EXAMPLES,
        "error" => error::EXAMPLES,
        "map" => map::EXAMPLES,
        "check" => check::EXAMPLES,
        "compensate" => compensate::EXAMPLES,
        "predict" => predict::EXAMPLES,
        "diff" => diff::EXAMPLES,
        "simulate" => simulate::EXAMPLES,
        "diagnose" => diagnose::EXAMPLES,
        "import-laser" => import_laser::EXAMPLES,
        "export" => export::EXAMPLES,
        "export linuxcnc" => export::LINUXCNC_EXAMPLES,
        "export tables" => export::TABLES_EXAMPLES,
        "sample" => sample::EXAMPLES,
        "completions" => shell::COMPLETIONS_EXAMPLES,
        "man" => shell::MAN_EXAMPLES,
        _ => return None,
    })
}

/// clap's default layout with the examples appended as literal text (clap
/// wraps `after_help` to the terminal's width; a template's own text is
/// printed as it is).
fn help_template(examples: &str) -> String {
    let mut template = String::from(
        "{before-help}{about-with-newline}\n{usage-heading} {usage}\n\n{all-args}{after-help}\n\nExamples:",
    );
    for line in example_lines(examples) {
        template.push_str("\n  ");
        template.push_str(line);
    }
    template
}

/// The examples of a page, one command line each.
pub fn example_lines(examples: &str) -> impl Iterator<Item = &str> {
    examples.lines().map(str::trim).filter(|l| !l.is_empty())
}

fn with_examples(cmd: clap::Command, path: &str) -> clap::Command {
    let cmd = match examples(path) {
        Some(text) => cmd.help_template(help_template(text)),
        None => cmd,
    };
    cmd.mut_subcommands(|sub| {
        let name = sub.get_name().to_string();
        let sub_path = if path.is_empty() {
            name
        } else {
            format!("{path} {name}")
        };
        with_examples(sub, &sub_path)
    })
}

/// The command line's definition, examples included.
pub fn command() -> clap::Command {
    use clap::CommandFactory;
    with_examples(Cli::command(), "")
}

/// A usage error found after clap (conflicting or missing options): exit 2.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct UsageError(pub String);

/// Exit code when standard output was closed early (128 + SIGPIPE).
pub const EXIT_BROKEN_PIPE: i32 = 141;

/// Write one line to standard output; a failed write is an error naming it.
pub fn stdout_line(args: std::fmt::Arguments) -> Result<(), crate::io::OutputError> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    out.write_fmt(args)
        .and_then(|()| out.write_all(b"\n"))
        .map_err(|source| crate::io::OutputError::Write {
            path: "standard output".into(),
            source,
        })
}

/// Write text as is to standard output; a failed write is an error naming it.
pub fn stdout_text(text: &str) -> Result<(), crate::io::OutputError> {
    use std::io::Write;
    std::io::stdout()
        .lock()
        .write_all(text.as_bytes())
        .map_err(|source| crate::io::OutputError::Write {
            path: "standard output".into(),
            source,
        })
}

/// `println!` that returns the failure (`?` in the caller) instead of panicking.
macro_rules! outln {
    ($($arg:tt)*) => {
        $crate::cli::stdout_line(format_args!($($arg)*))?
    };
}

/// A line of the human summary: to standard output, or to standard error
/// when standard output carries the command's data (`--report -`, `-o -`,
/// `--json`), so that the data parses.
macro_rules! humanln {
    ($data_on_stdout:expr, $($arg:tt)*) => {
        if $crate::cli::quiet() {
        } else if $data_on_stdout {
            eprintln!($($arg)*);
        } else {
            $crate::cli::stdout_line(format_args!($($arg)*))?
        }
    };
}
pub(crate) use humanln;
pub(crate) use outln;

/// Is `err` (or a cause) a write into a closed pipe?
pub fn is_broken_pipe(err: &anyhow::Error) -> bool {
    err.chain().any(|cause| {
        cause
            .downcast_ref::<std::io::Error>()
            .is_some_and(|e| e.kind() == std::io::ErrorKind::BrokenPipe)
    })
}

/// Parse the process arguments, run, print errors; returns the exit code.
pub fn main() -> i32 {
    use clap::FromArgMatches;
    let cli = match command()
        .try_get_matches()
        .and_then(|matches| Cli::from_arg_matches(&matches))
    {
        Ok(cli) => cli,
        Err(e) => {
            let code = if e.use_stderr() { 2 } else { 0 };
            let _ = e.print();
            return code;
        }
    };
    if let Err(e) = crate::io::install_signal_cleanup() {
        eprintln!(
            "warning: cannot watch for interrupts ({e}); an interrupted run may leave a .volcomp-*.tmp file"
        );
    }
    let result = run(cli).and_then(|()| {
        use std::io::Write;
        std::io::stdout()
            .flush()
            .map_err(|source| crate::io::OutputError::Write {
                path: "standard output".into(),
                source,
            })
            .map_err(anyhow::Error::from)
    });
    match result {
        Ok(()) => 0,
        Err(err) if is_broken_pipe(&err) => EXIT_BROKEN_PIPE,
        Err(err) => {
            eprintln!("error: {}", error_text(&err));
            if err.downcast_ref::<UsageError>().is_some() {
                2
            } else {
                1
            }
        }
    }
}

/// The error and its causes on one line, each cause said once: library errors
/// often name their cause in their own message already.
pub fn error_text(err: &anyhow::Error) -> String {
    let mut text = err.to_string();
    for cause in err.chain().skip(1) {
        let c = cause.to_string();
        if !text.contains(&c) {
            text.push_str(": ");
            text.push_str(&c);
        }
    }
    text
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    set_verbosity(if cli.quiet {
        Verbosity::Quiet
    } else if cli.verbose {
        Verbosity::Verbose
    } else {
        Verbosity::Normal
    });
    let started = std::time::Instant::now();
    run_command(cli.command)?;
    if verbosity() == Verbosity::Verbose {
        eprintln!("volcomp: done in {:.3} s", started.elapsed().as_secs_f64());
    }
    Ok(())
}

fn run_command(command: Command) -> anyhow::Result<()> {
    match command {
        Command::Fit(args) => fit::run(&args),
        Command::ImportLaser(args) => import_laser::run(&args),
        Command::Export(args) => export::run(&args),
        Command::Error(args) => error::run(&args),
        Command::Map(args) => map::run(&args),
        Command::Check(args) => check::run(&args),
        Command::Compensate(args) => compensate::run(&args),
        Command::Predict(args) => predict::run(&args),
        Command::Diff(args) => diff::run(&args),
        Command::Simulate(args) => simulate::run(&args),
        Command::Diagnose(args) => diagnose::run(&args),
        Command::Sample(args) => sample::run(&args),
        Command::Completions(args) => shell::completions(&args),
        Command::Man(args) => shell::man(&args),
    }
}
