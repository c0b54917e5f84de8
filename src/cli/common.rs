//! Arguments and helpers shared by the commands: the machine and its fitted error
//! model, the program frame, input files and progress display.
use crate::gcode::Frame;
use crate::machine::{ErrorModel, ExtrapolationPolicy, Machine};
use crate::nurbs::KnotMethod;
use anyhow::Context;
use clap::ValueEnum;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::{BufRead, BufReader, IsTerminal};
use std::path::{Path, PathBuf};

/// Out-of-table lookups.
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum Extrapolate {
    /// A position outside a table is an error (default).
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

/// The machine file and how its error model is obtained.
#[derive(Debug, Clone, clap::Args)]
pub struct MachineArgs {
    /// Machine file (TOML) with its error tables.
    #[arg(value_name = "MACHINE")]
    pub machine_file: PathBuf,
    #[command(flatten)]
    pub model: ModelArgs,
}

impl MachineArgs {
    /// Load the machine and its error model (fitted, or from `--model`).
    pub fn load(&self) -> anyhow::Result<(Machine, ErrorModel)> {
        load_model(&self.machine_file, &self.model)
    }
}

/// How the error model is obtained (shared by every command that loads a machine).
#[derive(Debug, Clone, clap::Args)]
pub struct ModelArgs {
    /// What a lookup outside an error table does.
    #[arg(long, value_enum, default_value = "error")]
    pub extrapolate: Extrapolate,
    /// Knot placement of the SMEM fit of the tables: ukm, epm, lam, ga, exhaustive
    /// or best (the default; see `volcomp fit`).
    #[arg(
        long,
        default_value = "best",
        value_name = "METHOD",
        conflicts_with = "model"
    )]
    pub fit_method: KnotMethod,
    /// Use the curves of a fitted-model file (`volcomp fit MACHINE --report FILE`)
    /// instead of fitting the tables again (faster; checked against the tables).
    #[arg(long, value_name = "FILE.json")]
    pub model: Option<PathBuf>,
    /// Evaluate the NURBS exactly at every lookup instead of the verified resampling
    /// (which stays within 1e-6 µm/µrad of it and is several times faster).
    #[arg(long)]
    pub exact_lookups: bool,
}

/// Load a machine and fit its error model, printing what was not measured to stderr.
pub fn load_model(path: &Path, args: &ModelArgs) -> anyhow::Result<(Machine, ErrorModel)> {
    let policy: ExtrapolationPolicy = args.extrapolate.into();
    let options = crate::machine::LoadOptions {
        extrapolation: policy,
    };
    let machine = Machine::load_with(path, &options)?;
    let model_options = crate::machine::ModelOptions {
        extrapolation: policy,
        fit: crate::nurbs::FitOptions {
            method: args.fit_method,
            ..Default::default()
        },
        exact_lookups: args.exact_lookups,
    };
    let model = match &args.model {
        Some(file) => ErrorModel::from_model_file(&machine, file, &model_options)?,
        None => ErrorModel::from_machine(&machine, &model_options)
            .with_context(|| format!("fitting the error tables of {}", path.display()))?,
    };
    let unmeasured: Vec<String> = crate::axes::Axis::ALL
        .into_iter()
        .filter(|axis| machine.table(*axis).is_none())
        .map(|axis| axis.letter().to_string())
        .collect();
    if !unmeasured.is_empty() {
        eprintln!(
            "note: {}: no error table for {} (those errors are taken as zero)",
            machine.name,
            unmeasured.join(", ")
        );
    }
    for table in machine.tables.iter().flatten() {
        if !table.missing.is_empty() {
            eprintln!(
                "note: {}: {} does not measure {} (taken as zero)",
                machine.name,
                table.path.display(),
                table.missing.join(", ")
            );
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

/// How a program is read: its start frame and how strictly.
#[derive(Debug, Clone, Copy, clap::Args)]
pub struct ProgramArgs {
    /// Frame of the X Y Z words at program start (M428/M429, G43.4/G234/G49 and
    /// TRAORI/TRAFOOF switch it later).
    #[arg(long, value_enum, default_value = "joint")]
    pub frame: FrameArg,
    /// Pass constructs that cannot be understood (parameters, subroutines, unknown
    /// G codes, cutter compensation during moves) through with a warning instead
    /// of failing.
    #[arg(long)]
    pub lenient: bool,
}

impl ProgramArgs {
    /// Interpreter settings for a machine whose G0 rate is `rapid_mm_per_min`.
    pub fn interpret_options(&self, rapid_mm_per_min: f64) -> crate::gcode::InterpretOptions {
        crate::gcode::InterpretOptions {
            initial_frame: self.frame.into(),
            rapid_mm_per_min,
            lenient: self.lenient,
            ..crate::gcode::InterpretOptions::default()
        }
    }

    /// Tool-path settings for `machine` (its rapid rate and ball radius).
    pub fn cut_options(&self, machine: &Machine) -> crate::toolpath::CutOptions {
        let mut options = crate::toolpath::CutOptions::for_machine(machine, self.frame.into());
        options.interpret.lenient = self.lenient;
        options
    }
}

/// Open a program (or `-`, standard input) for buffered reading.
pub fn open_input(path: &Path) -> anyhow::Result<Box<dyn BufRead + Send>> {
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
