//! Arguments and helpers shared by the commands: the machine and its fitted error
//! model, the program frame, input files and progress display.
use crate::gcode::Frame;
use crate::machine::{ErrorModel, ExtrapolationPolicy, LoadOptions, Machine, ModelOptions};
use anyhow::Context;
use clap::ValueEnum;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::{BufRead, BufReader, IsTerminal};
use std::path::{Path, PathBuf};

/// Out-of-table lookups.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, ValueEnum)]
pub enum Extrapolate {
    /// A position outside a table is an error (default).
    #[default]
    Error,
    /// Hold the table's end value (and say how often it happened).
    Hold,
}

impl From<Extrapolate> for ExtrapolationPolicy {
    fn from(e: Extrapolate) -> Self {
        match e {
            Extrapolate::Error => ExtrapolationPolicy::Error,
            Extrapolate::Hold => ExtrapolationPolicy::Hold,
        }
    }
}

/// The machine file and how its error model is built.
#[derive(Debug, Clone, clap::Args)]
pub struct MachineArgs {
    /// Machine file (TOML) with its error tables.
    #[arg(value_name = "MACHINE")]
    pub machine_file: PathBuf,
    /// What a lookup outside an error table does.
    #[arg(long, value_enum, default_value = "error")]
    pub extrapolate: Extrapolate,
}

impl MachineArgs {
    /// Load the machine and fit its error model.
    pub fn load(&self) -> anyhow::Result<(Machine, ErrorModel)> {
        load_model(&self.machine_file, self.extrapolate.into())
    }
}

/// Load a machine and fit its error model, printing what was not measured to stderr.
pub fn load_model(
    path: &Path,
    policy: ExtrapolationPolicy,
) -> anyhow::Result<(Machine, ErrorModel)> {
    let options = LoadOptions {
        extrapolation: policy,
    };
    let machine = Machine::load_with(path, &options)?;
    let model_options = ModelOptions {
        extrapolation: policy,
        ..Default::default()
    };
    let model = ErrorModel::from_machine(&machine, &model_options)
        .with_context(|| format!("fitting the error tables of {}", path.display()))?;
    for axis in crate::axes::Axis::ALL {
        match machine.table(axis) {
            None => eprintln!(
                "note: {}: no error table for axis {} (its errors are taken as zero)",
                machine.name,
                axis.letter()
            ),
            Some(table) if !table.missing.is_empty() => eprintln!(
                "note: {}: {} does not measure {} (taken as zero)",
                machine.name,
                table.path.display(),
                table.missing.join(", ")
            ),
            Some(_) => {}
        }
    }
    Ok((machine, model))
}

/// Frame of a program's X Y Z at its start.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum FrameArg {
    /// Axis commands (machine coordinates of the tool tip).
    Joint,
    /// Tool tip in part coordinates (tool-tip control active).
    Part,
}

impl From<FrameArg> for Frame {
    fn from(f: FrameArg) -> Self {
        match f {
            FrameArg::Joint => Frame::Joint,
            FrameArg::Part => Frame::Part,
        }
    }
}

/// Open a program (or `-`, standard input) for buffered reading.
pub fn open_input(path: &Path) -> anyhow::Result<Box<dyn BufRead>> {
    if crate::io::is_stdio(path) {
        return Ok(Box::new(BufReader::with_capacity(
            1 << 16,
            std::io::stdin(),
        )));
    }
    let file =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    Ok(Box::new(BufReader::with_capacity(1 << 16, file)))
}

/// A block counter on stderr for long runs (none when stderr is not a terminal).
pub fn progress_bar(path: &Path, what: &str) -> Option<ProgressBar> {
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = ProgressBar::new_spinner();
    bar.set_style(
        ProgressStyle::with_template("{spinner} {msg}: {pos} blocks ({per_sec}, {elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_spinner()),
    );
    bar.set_message(format!("{what} {}", path.display()));
    Some(bar)
}

/// Print to stdout, or to stderr when stdout carries the command's output.
pub fn say(stdout_is_output: bool, text: &str) {
    if stdout_is_output {
        eprintln!("{text}");
    } else {
        println!("{text}");
    }
}

/// Output path given as an `Option`: helper to check `-` collisions.
pub fn writes_stdout(path: Option<&PathBuf>) -> bool {
    path.is_some_and(|p| crate::io::is_stdio(p))
}
