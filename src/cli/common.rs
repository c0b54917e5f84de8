//! Arguments and helpers shared by the commands: the machine and its fitted error
//! model, the program frame, input files and progress display.
use crate::gcode::Frame;
use crate::machine::{ErrorModel, ExtrapolationPolicy, Machine};
use crate::nurbs::KnotMethod;
use anyhow::Context;
use clap::ValueEnum;
use indicatif::{ProgressBar, ProgressStyle};
use std::io::{BufReader, IsTerminal};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

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
    /// How the SMEM fit of the tables chooses each curve: cv (cross-validation,
    /// the default) or emax (the paper's tolerance; see `volcomp fit`).
    #[arg(
        long,
        default_value = "cv",
        value_name = "cv|emax",
        conflicts_with = "model"
    )]
    pub fit_select: crate::nurbs::Selection,
    /// Knot placement of the --fit-select emax fit: ukm, epm, lam, ga, exhaustive
    /// or best (the default).
    #[arg(long, value_name = "METHOD", conflicts_with = "model")]
    pub fit_method: Option<KnotMethod>,
    /// Use the curves of a fitted-model file (`volcomp fit MACHINE --report FILE`)
    /// instead of fitting the tables again (faster; checked against the tables).
    #[arg(long, value_name = "FILE.json")]
    pub model: Option<PathBuf>,
    /// Evaluate the NURBS exactly at every lookup instead of the verified resampling
    /// (which stays within 1e-6 µm/µrad of it and is several times faster).
    #[arg(long)]
    pub exact_lookups: bool,
    /// Folder of the fitted-model cache: a machine's tables are fitted once and
    /// the model reused until a table, the fit settings or volcomp change
    /// (default: $VOLCOMP_MODEL_CACHE, else $XDG_CACHE_HOME/volcomp, else
    /// ~/.cache/volcomp; an empty VOLCOMP_MODEL_CACHE turns the cache off).
    #[arg(long, value_name = "DIR", conflicts_with_all = ["model", "no_model_cache"])]
    pub model_cache: Option<PathBuf>,
    /// Fit the tables without the model cache (it is neither read nor written).
    #[arg(long, conflicts_with = "model")]
    pub no_model_cache: bool,
}

impl Default for ModelArgs {
    /// The command line's defaults: cv selection, lookups outside a table are
    /// errors; but no model cache, so that library callers (benches, examples)
    /// never read or write the user's.
    fn default() -> Self {
        Self {
            extrapolate: Extrapolate::Error,
            fit_select: crate::nurbs::Selection::Cv,
            fit_method: None,
            model: None,
            exact_lookups: false,
            model_cache: None,
            no_model_cache: true,
        }
    }
}

impl ModelArgs {
    /// The model cache to use, if any: `--model-cache`, else
    /// `$VOLCOMP_MODEL_CACHE` (empty: none), else `$XDG_CACHE_HOME/volcomp`
    /// (an absolute path), else `$HOME/.cache/volcomp`; none with
    /// `--no-model-cache` or `--model`.
    pub fn cache(&self) -> Option<crate::machine::ModelCache> {
        if self.no_model_cache || self.model.is_some() {
            return None;
        }
        if let Some(dir) = &self.model_cache {
            return Some(crate::machine::ModelCache::new(dir));
        }
        let env = |name: &str| std::env::var_os(name);
        let dir = match env("VOLCOMP_MODEL_CACHE") {
            Some(dir) if dir.is_empty() => return None,
            Some(dir) => PathBuf::from(dir),
            None => match env("XDG_CACHE_HOME").map(PathBuf::from) {
                Some(dir) if dir.is_absolute() => dir.join("volcomp"),
                _ => PathBuf::from(env("HOME").filter(|h| !h.is_empty())?)
                    .join(".cache")
                    .join("volcomp"),
            },
        };
        Some(crate::machine::ModelCache::new(dir))
    }

    /// How the model is fitted, for stamps and reports: `cv`, or `emax METHOD`.
    pub fn fit_description(&self) -> String {
        match self.fit_select {
            crate::nurbs::Selection::Cv => "cv".to_string(),
            crate::nurbs::Selection::Emax => {
                format!("emax {}", self.fit_method.unwrap_or_default())
            }
        }
    }
}

/// Load a machine and fit its error model, printing what was not measured to stderr.
pub fn load_model(path: &Path, args: &ModelArgs) -> anyhow::Result<(Machine, ErrorModel)> {
    let machine = load_machine(path, args)?;
    fit_model(machine, path, args)
}

/// The machine file and its tables, read as `args` says (no model yet).
pub fn load_machine(path: &Path, args: &ModelArgs) -> anyhow::Result<Machine> {
    if args.fit_select == crate::nurbs::Selection::Cv && args.fit_method.is_some() {
        return Err(super::UsageError(
            "--fit-method belongs to the paper's selection: add --fit-select emax".into(),
        )
        .into());
    }
    let options = crate::machine::LoadOptions {
        extrapolation: args.extrapolate.into(),
    };
    Ok(Machine::load_with(path, &options)?)
}

/// The error model of a loaded machine (fitted, from the cache or from
/// `--model`), printing what was not measured to stderr; a progress bar while
/// it fits on a terminal.
pub fn fit_model(
    machine: Machine,
    path: &Path,
    args: &ModelArgs,
) -> anyhow::Result<(Machine, ErrorModel)> {
    let policy: ExtrapolationPolicy = args.extrapolate.into();
    let counter = Arc::new(crate::progress::WorkCounter::new());
    let model_options = crate::machine::ModelOptions {
        extrapolation: policy,
        fit: crate::nurbs::FitOptions {
            select: args.fit_select,
            method: args.fit_method.unwrap_or_default(),
            ..Default::default()
        },
        exact_lookups: args.exact_lookups,
        progress: Some(Arc::clone(&counter)),
    };
    let what = format!("fitting {}", crate::io::display_name(path));
    let model = with_progress(&what, &counter, || -> anyhow::Result<ErrorModel> {
        Ok(match (&args.model, args.cache()) {
            (Some(file), _) => ErrorModel::from_model_file(&machine, file, &model_options)?,
            (None, Some(cache)) => {
                let (model, report) = cache
                    .load_or_fit(&machine, path, &model_options)
                    .with_context(|| format!("fitting the error tables of {}", path.display()))?;
                if let crate::machine::CacheOutcome::TablesChanged(tables) = &report.outcome {
                    let names: Vec<String> =
                        tables.iter().map(|t| t.display().to_string()).collect();
                    super::noteln!(
                        "{}: {} changed since its model was cached: refitted",
                        machine.name,
                        names.join(", ")
                    );
                }
                if let Some(e) = &report.store_error {
                    super::noteln!(
                        "the fitted model was not cached in {}: {e}",
                        cache.dir().display()
                    );
                }
                model
            }
            (None, None) => ErrorModel::from_machine(&machine, &model_options)
                .with_context(|| format!("fitting the error tables of {}", path.display()))?,
        })
    })?;
    for note in model_notes(&machine) {
        super::noteln!("{note}");
    }
    Ok((machine, model))
}

/// What a machine's tables leave out or add, one note per kind (a note that
/// names several tables names them together): axes without a table, tables
/// with a `REVERSAL` column, tables missing parameters.
pub fn model_notes(machine: &Machine) -> Vec<String> {
    let mut notes = Vec::new();
    let unmeasured: Vec<String> = machine
        .layout()
        .slot_axes()
        .into_iter()
        .filter(|axis| machine.table(*axis).is_none())
        .map(|axis| axis.letter().to_string())
        .collect();
    if !unmeasured.is_empty() {
        notes.push(format!(
            "{}: no error table for {} (those errors are taken as zero)",
            machine.name,
            unmeasured.join(", ")
        ));
    }
    let tables: Vec<_> = machine.tables.iter().flatten().collect();
    let reversal: Vec<String> = tables
        .iter()
        .filter(|t| t.reversal.is_some())
        .map(|t| t.path.display().to_string())
        .collect();
    if !reversal.is_empty() {
        let (has, column) = if reversal.len() == 1 {
            ("has a", "column")
        } else {
            ("have", "columns")
        };
        notes.push(format!(
            "{}: {} {has} REVERSAL {column}: the error model adds ±REVERSAL/2 by the direction of the axis's last motion (unknown before the axis first moves: the mean)",
            machine.name,
            reversal.join(", ")
        ));
    }
    for table in tables.iter().filter(|t| !t.missing.is_empty()) {
        notes.push(format!(
            "{}: {} does not measure {} (taken as zero)",
            machine.name,
            table.path.display(),
            table.missing.join(", ")
        ));
    }
    notes
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

/// How a program is read: its start frame, how strictly, and the setup it runs
/// in (work origins, stored positions, subroutine files).
#[derive(Debug, Clone, clap::Args)]
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
    /// LinuxCNC parameter file (`.var`) holding the setup's work origins
    /// (G54–G59.3), G92 offsets and G28/G30 positions, in mm.
    #[arg(long, value_name = "FILE.var")]
    pub var: Option<PathBuf>,
    /// A work origin for other controllers, mm and degrees, e.g.
    /// `--offset G54=100,50,-200` or `--offset G55=0,0,0,0,90` (X,Y,Z[,A,C]);
    /// repeatable; overrides `--var` for that system. SINUMERIK programs:
    /// G54–G57 and the settable frames G505–G599; Heidenhain: PRESET.
    #[arg(long, value_name = "G54=X,Y,Z[,A,C]")]
    pub offset: Vec<String>,
    /// Folder searched for `NAME.ngc` when the program calls `o<NAME>` without
    /// defining it (LinuxCNC's SUBROUTINE_PATH); repeatable, searched in order.
    #[arg(long, value_name = "DIR")]
    pub subroutine_path: Vec<PathBuf>,
    /// LinuxCNC tool table (`T1 P1 Z120.0 D6.0 ;comment`, lengths in mm from
    /// the gauge point to the tip); replaces the machine file's [[tools]]. The
    /// program's T/M6/M61 choose the tool of each block; blocks before the
    /// first tool change use the machine file's [tool].
    #[arg(long, value_name = "FILE.tbl")]
    pub tools: Option<PathBuf>,
    /// Most lines read inside loop bodies and subroutine calls before the run
    /// stops as an endless or runaway loop (the program's own lines, read
    /// once, do not count).
    #[arg(long, value_name = "N", default_value_t = crate::gcode::language::DEFAULT_MAX_LOOP_LINES)]
    pub max_loop_lines: u64,
    /// Most moves the program generates beyond its own lines (moves in loops
    /// and calls, canned-cycle and spline expansions) before the run stops.
    #[arg(long, value_name = "N", default_value_t = crate::gcode::language::DEFAULT_MAX_GENERATED_MOVES)]
    pub max_moves: u64,
    /// The program's language: linuxcnc, sinumerik or heidenhain (default:
    /// from the program, docs/dialects.md: `.mpf`/`.spf` or a `%_N_…_MPF`
    /// first line is Sinumerik, `BEGIN PGM` on the first block Heidenhain,
    /// anything else LinuxCNC).
    #[arg(long, value_name = "linuxcnc|sinumerik|heidenhain", value_parser = parse_dialect)]
    pub dialect: Option<crate::gcode::Dialect>,
    /// The value of a SINUMERIK system variable the program reads and that
    /// cannot be known offline, e.g. `--sysvar '$AA_IW[X]=12.5'` or
    /// `--sysvar '$P_UIFR[1,X,TR]=100'` (the name as the program writes
    /// it, indices included; case and spaces do not matter); repeatable.
    /// `$P_TOOLNO` and `$P_TOOL` come from the program's own `T`/`M6`/`D`
    /// once it has set them (docs/dialects.md).
    #[arg(long, value_name = "$NAME=VALUE", value_parser = parse_sysvar)]
    pub sysvar: Vec<(String, f64)>,
}

/// A `--sysvar` value: `$NAME[indices]=number`.
fn parse_sysvar(text: &str) -> Result<(String, f64), String> {
    let Some((name, value)) = text.split_once('=') else {
        return Err(format!(
            "`{text}`: expected $NAME=VALUE, e.g. --sysvar '$AA_IW[X]=12.5'"
        ));
    };
    let key = crate::gcode::normalise_system_variable(name);
    if !key.starts_with('$') || key.len() < 2 {
        return Err(format!(
            "`{text}`: a system variable's name starts with `$` (e.g. $P_UIFR[1,X,TR])"
        ));
    }
    let v = value
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("`{text}`: `{}` is not a finite number", value.trim()))?;
    Ok((key, v))
}

/// A `--dialect` value.
fn parse_dialect(text: &str) -> Result<crate::gcode::Dialect, String> {
    crate::gcode::Dialect::from_key(text).ok_or_else(|| {
        format!("`{text}` is not a dialect volcomp reads: give linuxcnc, sinumerik or heidenhain")
    })
}

/// What a summary says about the dialect: `read as Sinumerik (extension
/// .MPF)`; nothing for a program read as LinuxCNC's (its outputs stay as
/// they were before dialects).
pub fn dialect_note(choice: &crate::gcode::DialectChoice) -> Option<String> {
    (choice.dialect != crate::gcode::Dialect::LinuxCnc).then(|| choice.describe())
}

/// Say (on standard error, as the other notes) which dialect `program` is
/// read in and why, when it is not LinuxCNC's.
pub fn announce_dialect(program: &crate::gcode::Program) {
    if let Some(note) = dialect_note(program.dialect()) {
        eprintln!("note: {}: {note}", program.path().display());
    }
}

/// A LinuxCNC tool table file.
pub fn read_tool_table(path: &Path) -> anyhow::Result<crate::gcode::ToolTable> {
    let text = crate::io::read_to_string(path)?;
    Ok(crate::gcode::ToolTable::parse(
        &text,
        &path.display().to_string(),
    )?)
}

/// The tool `number` of `--tools` (or of `machine`'s `[[tools]]`); the
/// machine's default tool when no number is given.
pub fn select_tool(
    machine: &crate::machine::Machine,
    number: Option<u32>,
    tools: Option<&Path>,
) -> anyhow::Result<crate::gcode::ToolInUse> {
    let table = match tools {
        Some(path) => read_tool_table(path)?,
        None => machine.tools.clone(),
    };
    match number {
        None | Some(0) => Ok(machine.default_tool()),
        Some(n) => match table.get(n) {
            Some(_) => Ok(table.in_use(n, machine.default_tool())),
            None => Err(super::UsageError(format!(
                "--tool {n}: not in the tool table ({}); give --tools FILE.tbl or add [[tools]] to the machine file",
                table.source().unwrap_or("none given")
            ))
            .into()),
        },
    }
}

/// Parse `G54=X,Y,Z[,R1,R2]` (plain numbers: X Y Z and then the machine's two
/// rotary axes in letter order, `rotary`) or `G54=X100,Y50,B10` (letter-prefixed
/// values, any letters) into (system number 1 … 9, or 505 … 599 for the
/// SINUMERIK settable frames `G505` … `G599`, origin). A letter given twice,
/// or a letter the machine lacks (`letters`), is an error.
pub fn parse_offset(
    text: &str,
    rotary: [crate::axes::Axis; 2],
    letters: crate::axes::AxisSet,
) -> Result<(usize, crate::axes::Axes), String> {
    use crate::axes::{Axes, Axis};
    const SYSTEMS: [&str; 9] = [
        "G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3",
    ];
    let plain = format!("X,Y,Z[,{},{}]", rotary[0].letter(), rotary[1].letter());
    let Some((name, values)) = text.split_once('=') else {
        return Err(format!(
            "--offset `{text}`: expected G54={plain} (e.g. G54=100,50,-200) or G54=X100,Y50,Z-200"
        ));
    };
    let name = name.trim().to_ascii_uppercase();
    // `PRESET` (Heidenhain: the preset in use) is the first work system.
    let key = if name == "PRESET" {
        "G54"
    } else {
        name.as_str()
    };
    // `G505` … `G599`: the SINUMERIK settable frames beyond G54–G57.
    let sinumerik_frame = key
        .strip_prefix('G')
        .and_then(|n| n.parse::<usize>().ok())
        .filter(|n| (505..=599).contains(n) && key.len() == 4);
    let Some(n) = SYSTEMS
        .iter()
        .position(|s| *s == key)
        .map(|k| k + 1)
        .or(sinumerik_frame)
    else {
        return Err(format!(
            "--offset `{text}`: `{name}` is not a work coordinate system (G54 … G59, G59.1 … G59.3, G505 … G599 for SINUMERIK programs, or PRESET for Heidenhain programs)"
        ));
    };
    let fields: Vec<&str> = values.split(',').map(str::trim).collect();
    let lettered = fields
        .iter()
        .any(|f| f.chars().next().is_some_and(|c| c.is_ascii_alphabetic()));
    let mut origin = Axes::default();
    if lettered {
        let mut seen = crate::axes::AxisSet::EMPTY;
        for field in &fields {
            let mut chars = field.chars();
            let axis = chars.next().and_then(Axis::from_letter);
            let value = chars
                .as_str()
                .trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite());
            match (axis, value) {
                (Some(axis), Some(v)) if !seen.contains(axis) && letters.contains(axis) => {
                    seen = seen.with(axis);
                    origin.set(axis, v);
                }
                (Some(axis), Some(_)) if seen.contains(axis) => {
                    return Err(format!(
                        "--offset `{text}`: {} is given twice",
                        axis.letter()
                    ));
                }
                (Some(axis), Some(_)) => {
                    return Err(format!(
                        "--offset `{text}`: the machine has no {} axis (its axes: {})",
                        axis.letter(),
                        letters.letters()
                    ));
                }
                _ => {
                    return Err(format!(
                        "--offset `{text}`: `{field}` is not a letter and a finite number (e.g. X100, B-5.5)"
                    ));
                }
            }
        }
        return Ok((n, origin));
    }
    let numbers: Result<Vec<f64>, _> = fields.iter().map(|v| v.parse::<f64>()).collect();
    let numbers = match numbers {
        Ok(v) if (v.len() == 3 || v.len() == 5) && v.iter().all(|x| x.is_finite()) => v,
        _ => {
            return Err(format!(
                "--offset `{text}`: give 3 or 5 finite numbers {plain} in mm and degrees, or letter-prefixed values such as X100,Y50,Z-200,{}10",
                rotary[0].letter()
            ));
        }
    };
    origin.x = numbers[0];
    origin.y = numbers[1];
    origin.z = numbers[2];
    if numbers.len() == 5 {
        origin.set(rotary[0], numbers[3]);
        origin.set(rotary[1], numbers[4]);
    }
    Ok((n, origin))
}

impl ProgramArgs {
    /// The setup the program runs in: `--var`, `--offset`, `--subroutine-path`,
    /// and the tools: `--tools` or `machine`'s `[[tools]]`, `machine`'s `[tool]`
    /// as the default tool. Programs must end with M2/M30 or `%`, as LinuxCNC
    /// requires.
    pub fn setup(
        &self,
        machine: Option<&crate::machine::Machine>,
    ) -> anyhow::Result<crate::gcode::ProgramSetup> {
        let mut setup = crate::gcode::ProgramSetup {
            require_program_end: true,
            ..Default::default()
        };
        if let Some(m) = machine {
            setup.tools = m.tools.clone();
            setup.orientation = Some(std::sync::Arc::new(crate::toolpath::ChainOrientation::of(
                m,
            )));
        }
        if let Some(path) = &self.tools {
            setup.tools = read_tool_table(path)?;
        }
        if let Some(path) = &self.var {
            let text = crate::io::read_to_string(path)?;
            let pairs = crate::gcode::parameters::parse_var_file(&text)
                .map_err(|e| anyhow::anyhow!("{}:{}: {e}", path.display(), e.line()))?;
            for (n, v) in pairs {
                setup.parameters.set(n, v);
            }
        }
        let (rotary, letters) = match machine {
            Some(m) => (m.chain.rotary(), m.letters()),
            None => (
                [crate::axes::Axis::A, crate::axes::Axis::C],
                crate::axes::AxisSet::RS274,
            ),
        };
        let mut given: std::collections::BTreeMap<usize, &str> = Default::default();
        for text in &self.offset {
            let (n, origin) = parse_offset(text, rotary, letters).map_err(super::UsageError)?;
            if let Some(first) = given.get(&n) {
                return Err(super::UsageError(format!(
                    "--offset `{text}`: that work coordinate system is already given (--offset `{first}`); give each system once"
                ))
                .into());
            }
            given.insert(n, text);
            setup.set_origin(n, &origin);
        }
        for dir in &self.subroutine_path {
            if !dir.is_dir() {
                return Err(super::UsageError(format!(
                    "--subroutine-path {}: not a folder",
                    dir.display()
                ))
                .into());
            }
        }
        setup.language.subroutine_path = self.subroutine_path.clone();
        setup.dialect = self.dialect;
        for (key, v) in &self.sysvar {
            if setup.system_variables.insert(key.clone(), *v).is_some() {
                return Err(super::UsageError(format!(
                    "--sysvar `{key}` is given twice; give each system variable once"
                ))
                .into());
            }
        }
        setup.language.max_loop_lines = Some(self.max_loop_lines);
        setup.language.max_generated_moves = Some(self.max_moves);
        Ok(setup)
    }

    /// [`Self::program`] and the program's provenance stamp, if it carries one.
    pub fn program_and_stamp(
        &self,
        path: &Path,
        machine: Option<&crate::machine::Machine>,
    ) -> anyhow::Result<(crate::gcode::Program, Option<crate::stamp::Stamp>)> {
        let (input, stamp) = open_program_with_stamp(path)?;
        let program = crate::gcode::Program::new(input, path, self.setup(machine)?);
        announce_dialect(&program);
        Ok((program, stamp))
    }

    /// The program at `path` (`-`: standard input) in the setup of [`Self::setup`].
    pub fn program(
        &self,
        path: &Path,
        machine: Option<&crate::machine::Machine>,
    ) -> anyhow::Result<crate::gcode::Program> {
        let program = crate::gcode::Program::new(open_program(path)?, path, self.setup(machine)?);
        announce_dialect(&program);
        Ok(program)
    }

    /// Interpreter settings for a machine whose G0 rate is `rapid_mm_per_min` and
    /// whose axis letters are `axes`.
    pub fn interpret_options(
        &self,
        rapid_mm_per_min: f64,
        axes: crate::axes::AxisSet,
    ) -> crate::gcode::InterpretOptions {
        crate::gcode::InterpretOptions {
            initial_frame: self.frame.into(),
            rapid_mm_per_min,
            lenient: self.lenient,
            axes,
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

/// Open a program (or `-`, standard input) for the language layer, which
/// seeks (loops, calls): standard input is first copied to a temporary file.
pub fn open_program(path: &Path) -> anyhow::Result<Box<dyn crate::gcode::ProgramInput>> {
    if crate::io::is_stdio(path) {
        let mut spool =
            tempfile::tempfile().context("cannot create a temporary file for standard input")?;
        std::io::copy(&mut std::io::stdin().lock(), &mut spool)
            .context("cannot read standard input")?;
        use std::io::Seek;
        spool.rewind().context("cannot read standard input back")?;
        return Ok(Box::new(BufReader::with_capacity(1 << 16, spool)));
    }
    let file =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    Ok(Box::new(BufReader::with_capacity(1 << 16, file)))
}

/// How much of a program's head is searched for its stamp.
const HEAD_BYTES: u64 = 256 * 1024;

/// The first bytes of a program (what [`crate::stamp::Stamp::find`]
/// reads); the input is rewound.
pub fn program_head(input: &mut dyn crate::gcode::ProgramInput) -> anyhow::Result<String> {
    use std::io::Read;
    let mut head = Vec::new();
    input
        .take(HEAD_BYTES)
        .read_to_end(&mut head)
        .context("cannot read the program")?;
    input.rewind().context("cannot read the program")?;
    Ok(String::from_utf8_lossy(&head).into_owned())
}

/// FNV-1a 64 of a program's bytes, and the line of the first stamp line
/// anywhere in it; the input is rewound.
pub fn program_hash(
    input: &mut dyn crate::gcode::ProgramInput,
) -> anyhow::Result<(crate::stamp::Fnv1a64, Option<usize>)> {
    let mut hash = crate::stamp::Fnv1a64::default();
    let mut scan = crate::stamp::StampScan::default();
    loop {
        let buf = input.fill_buf().context("cannot read the program")?;
        if buf.is_empty() {
            break;
        }
        hash.update(buf);
        scan.update(buf);
        let n = buf.len();
        input.consume(n);
    }
    input.rewind().context("cannot read the program")?;
    Ok((hash, scan.finish()))
}

/// The stamp of an already compensated program (`-`: standard input), with the
/// program opened.
pub fn open_program_with_stamp(
    path: &Path,
) -> anyhow::Result<(
    Box<dyn crate::gcode::ProgramInput>,
    Option<crate::stamp::Stamp>,
)> {
    let mut input = open_program(path)?;
    let head = program_head(input.as_mut())
        .with_context(|| format!("reading {}", crate::io::display_name(path)))?;
    Ok((input, crate::stamp::Stamp::find(&head)))
}

/// A progress bar on stderr for long runs (none when stderr is not a
/// terminal): the share of the program's bytes read, with the time left, and
/// the blocks done.
pub struct Progress {
    bar: ProgressBar,
    /// The farthest byte of the program read so far ([`track`]).
    position: Arc<AtomicU64>,
    started: std::time::Instant,
}

impl Progress {
    /// A bar over `total` bytes read at `position`, named `what path`.
    pub fn new(path: &Path, what: &str, total: u64, position: Arc<AtomicU64>) -> Option<Progress> {
        if !std::io::stderr().is_terminal() || crate::cli::quiet() {
            return None;
        }
        let bar = ProgressBar::new(total.max(1));
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix}: {percent:>3}% [{bar:30}] {msg} ({elapsed}, about {eta} left)",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        bar.set_prefix(format!("{what} {}", crate::io::display_name(path)));
        Some(Progress {
            bar,
            position,
            started: std::time::Instant::now(),
        })
    }

    /// `blocks` are done.
    pub fn update(&self, blocks: usize) {
        self.bar.set_position(self.position.load(Ordering::Relaxed));
        let seconds = self.started.elapsed().as_secs_f64().max(1e-3);
        self.bar.set_message(format!(
            "{} blocks, {} blocks/s",
            thousands(blocks as f64),
            thousands(blocks as f64 / seconds)
        ));
    }

    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }

    pub fn abandon(&self) {
        self.bar.abandon();
    }
}

/// How long work runs before [`with_progress`] shows its bar (the
/// environment's `VOLCOMP_PROGRESS_AFTER_MS` overrides it, for tests).
const PROGRESS_AFTER: std::time::Duration = std::time::Duration::from_secs(2);

/// Runs `work`, which counts its steps on `counter`; once it has run
/// [`PROGRESS_AFTER`] and standard error is a terminal, a bar with the
/// percentage and the time left is drawn on it (cleared at the end), named
/// `what`. Piped, nothing is drawn.
pub fn with_progress<T>(
    what: &str,
    counter: &Arc<crate::progress::WorkCounter>,
    work: impl FnOnce() -> T,
) -> T {
    let after = std::env::var("VOLCOMP_PROGRESS_AFTER_MS")
        .ok()
        .and_then(|v| v.parse::<u64>().ok())
        .map_or(PROGRESS_AFTER, std::time::Duration::from_millis);
    let finished = std::sync::atomic::AtomicBool::new(false);
    std::thread::scope(|scope| {
        scope.spawn(|| draw_progress(what, counter, after, &finished));
        let out = work();
        finished.store(true, Ordering::Relaxed);
        out
    })
}

/// The bar of [`with_progress`], updated every 100 ms until `finished`.
fn draw_progress(
    what: &str,
    counter: &crate::progress::WorkCounter,
    after: std::time::Duration,
    finished: &std::sync::atomic::AtomicBool,
) {
    let tick = std::time::Duration::from_millis(50);
    let started = std::time::Instant::now();
    let mut bar: Option<ProgressBar> = None;
    while !finished.load(Ordering::Relaxed) {
        std::thread::sleep(tick);
        if bar.is_none() && started.elapsed() >= after && std::io::stderr().is_terminal() {
            let b = ProgressBar::new(counter.total().max(1));
            b.set_style(
                ProgressStyle::with_template(
                    "{prefix}: {percent:>3}% [{bar:30}] {pos}/{len} ({elapsed}, about {eta} left)",
                )
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
            );
            b.set_prefix(what.to_string());
            bar = Some(b);
        }
        if let Some(b) = &bar {
            b.set_length(counter.total().max(1));
            b.set_position(counter.done());
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
}

/// A program input that records the farthest byte read (loops seek back;
/// the farthest point is the progress through the file).
struct Tracked<R> {
    inner: R,
    at: u64,
    farthest: Arc<AtomicU64>,
}

impl<R: std::io::Read> std::io::Read for Tracked<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.advance(n as u64);
        Ok(n)
    }
}

impl<R: std::io::BufRead> std::io::BufRead for Tracked<R> {
    fn fill_buf(&mut self) -> std::io::Result<&[u8]> {
        self.inner.fill_buf()
    }
    fn consume(&mut self, n: usize) {
        self.inner.consume(n);
        self.advance(n as u64);
    }
}

impl<R: std::io::Seek> std::io::Seek for Tracked<R> {
    fn seek(&mut self, to: std::io::SeekFrom) -> std::io::Result<u64> {
        self.at = self.inner.seek(to)?;
        Ok(self.at)
    }
}

impl<R> Tracked<R> {
    fn advance(&mut self, n: u64) {
        self.at += n;
        self.farthest.fetch_max(self.at, Ordering::Relaxed);
    }
}

/// `input` recording the farthest byte read into the returned counter, and
/// its length in bytes (the input is rewound).
pub fn track(
    mut input: Box<dyn crate::gcode::ProgramInput>,
) -> anyhow::Result<(Box<dyn crate::gcode::ProgramInput>, u64, Arc<AtomicU64>)> {
    use std::io::Seek;
    let total = input
        .seek(std::io::SeekFrom::End(0))
        .context("cannot read the program")?;
    input.rewind().context("cannot read the program")?;
    let farthest = Arc::new(AtomicU64::new(0));
    let tracked = Tracked {
        inner: input,
        at: 0,
        farthest: Arc::clone(&farthest),
    };
    Ok((Box::new(tracked), total, farthest))
}

/// Which of a command's outputs go to standard output (`-`, or `--json`):
/// `Ok(true)` when one does (the human summary then goes to standard error),
/// a usage error when two do (their bytes would mix on one stream).
pub fn stdout_output(outputs: &[(&str, bool)]) -> anyhow::Result<bool> {
    let on_stdout: Vec<&str> = outputs
        .iter()
        .filter(|(_, yes)| *yes)
        .map(|(name, _)| *name)
        .collect();
    if on_stdout.len() > 1 {
        return Err(super::UsageError(format!(
            "{} would {} write to standard output; give all but one of them a file",
            on_stdout.join(" and "),
            if on_stdout.len() == 2 { "both" } else { "all" }
        ))
        .into());
    }
    Ok(!on_stdout.is_empty())
}

/// Whether `path` is given and is `-` (standard output).
pub fn is_stdout(path: Option<&Path>) -> bool {
    path.is_some_and(crate::io::is_stdio)
}

/// A unit for people: `µm` and `µrad` for the files' `um` and `urad`.
pub fn unit_symbol(unit: &str) -> &str {
    match unit {
        "um" => "µm",
        "urad" => "µrad",
        other => other,
    }
}

/// `n word`, the word in the plural unless `n` is 1 (`1 move`, `3 moves`).
pub fn count(n: u64, singular: &str, plural: &str) -> String {
    if n == 1 {
        format!("{n} {singular}")
    } else {
        format!("{n} {plural}")
    }
}

/// A rate or count for people: whole, with thousands separated by commas
/// (`203,088`).
pub fn thousands(v: f64) -> String {
    if !v.is_finite() {
        return v.to_string();
    }
    let digits = format!("{:.0}", v.abs());
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    if v < 0.0 && digits != "0" {
        out.insert(0, '-');
    }
    out
}

/// The warnings of a run as lines, once per kind: the first one's place and
/// message, and how many there were in all.
pub fn warning_lines(groups: &[crate::warnings::WarningGroup]) -> Vec<String> {
    groups
        .iter()
        .map(|g| {
            let place = match (&g.file, g.first_line, g.first_column) {
                (Some(f), Some(l), Some(c)) => format!("{f}:{l}:{c}: "),
                (Some(f), Some(l), None) => format!("{f}:{l}: "),
                (None, Some(l), _) => format!("line {l}: "),
                (Some(f), None, _) => format!("{f}: "),
                (None, None, _) => String::new(),
            };
            let more = match g.count {
                1 => String::new(),
                n => format!(" ({n} in all, the first shown)"),
            };
            format!("{place}{}{more}", g.message)
        })
        .collect()
}

/// Print the warnings of a run to standard error (`warning: …`), once per kind.
pub fn print_warnings(groups: &[crate::warnings::WarningGroup]) {
    for line in warning_lines(groups) {
        eprintln!("warning: {line}");
    }
}

/// What to append to a summary's first line when warnings change the
/// result: ` (warnings change this result: 1× tool length assumed)`.
pub fn result_note(groups: &[crate::warnings::WarningGroup]) -> String {
    // One part per effect: two programs' warnings of one kind (diff) add up.
    let mut parts: Vec<(u64, &str)> = Vec::new();
    for g in groups.iter().filter(|g| g.changes_result) {
        match parts.iter_mut().find(|(_, effect)| *effect == g.effect) {
            Some((count, _)) => *count += g.count,
            None => parts.push((g.count, &g.effect)),
        }
    }
    if parts.is_empty() {
        String::new()
    } else {
        let parts: Vec<String> = parts
            .iter()
            .map(|(count, effect)| format!("{count}× {effect}"))
            .collect();
        format!(" (warnings change this result: {})", parts.join(", "))
    }
}

/// Warn (kind `other_machine`) when a program's stamp or header
/// ([`crate::sample::machine_suffix`]) names a machine other than `machine`:
/// its joints were written for that machine's kinematics.
pub fn warn_other_machine(
    warnings: &crate::warnings::Warnings,
    program: &str,
    head: &str,
    stamp: Option<&crate::stamp::Stamp>,
    machine: &str,
) {
    let named = stamp
        .map(|s| (s.machine.clone(), "its stamp"))
        .or_else(|| crate::sample::header_machine(head).map(|m| (m, "its header")));
    let Some((other, source)) = named else {
        return;
    };
    if other.eq_ignore_ascii_case(machine) {
        return;
    }
    warnings.add(
        &crate::warnings::Warning {
            kind: "other_machine",
            file: Some(program),
            line: None,
            column: None,
            effect: "",
        },
        1,
        || {
            format!(
                "{source} says it was written for machine {other}, not {machine}: its axis words are that machine's joints (generate or post the program for {machine})"
            )
        },
    );
}

/// Add the model's held lookups (`--extrapolate hold`) to a run's warnings.
pub fn add_held_lookups(warnings: &crate::warnings::Warnings, held: u64) {
    warnings.add(
        &crate::warnings::Warning {
            kind: "held_lookups",
            file: None,
            line: None,
            column: None,
            effect: "table end held (--extrapolate hold)",
        },
        held,
        || "a lookup outside an error table held the table's end value (--extrapolate hold)".into(),
    );
}

/// Print to stdout, or to stderr when stdout carries the command's output;
/// nothing under `-q`.
pub fn say(stdout_is_output: bool, text: &str) -> anyhow::Result<()> {
    if crate::cli::quiet() {
    } else if stdout_is_output {
        eprintln!("{text}");
    } else {
        crate::cli::outln!("{text}");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Wrapper {
        #[command(flatten)]
        model: ModelArgs,
    }

    #[test]
    fn rates_are_whole_with_thousands_separated() {
        assert_eq!(thousands(203_087.988_5), "203,088");
        assert_eq!(thousands(999.4), "999");
        assert_eq!(thousands(1_000.0), "1,000");
        assert_eq!(thousands(-1234567.0), "-1,234,567");
        assert_eq!(thousands(0.2), "0");
    }

    /// The progress bar's position: the farthest byte read, across seeks back.
    #[test]
    fn a_tracked_input_records_the_farthest_byte_read() {
        use std::io::{BufRead, Read, Seek};
        let data = b"G1 X1\nG1 X2\nG1 X3\n".to_vec();
        let (mut input, total, farthest) = track(Box::new(std::io::Cursor::new(data))).unwrap();
        assert_eq!(total, 18);
        let mut line = String::new();
        input.read_line(&mut line).unwrap();
        input.read_line(&mut line).unwrap();
        assert_eq!(farthest.load(Ordering::Relaxed), 12);
        input.rewind().unwrap();
        let mut first = [0u8; 3];
        input.read_exact(&mut first).unwrap();
        assert_eq!(farthest.load(Ordering::Relaxed), 12);
        let mut rest = Vec::new();
        input.read_to_end(&mut rest).unwrap();
        assert_eq!(farthest.load(Ordering::Relaxed), 18);
    }

    /// `ModelArgs::default()` (benches, examples) is what the command line gives
    /// when no model option is passed.
    #[test]
    fn default_model_args_are_the_command_line_defaults() {
        let parsed = Wrapper::parse_from(["volcomp"]).model;
        let default = ModelArgs::default();
        assert_eq!(parsed.extrapolate, default.extrapolate);
        assert_eq!(parsed.fit_select, default.fit_select);
        assert_eq!(parsed.fit_method, default.fit_method);
        assert_eq!(parsed.model, default.model);
        assert_eq!(parsed.exact_lookups, default.exact_lookups);
        assert_eq!(parsed.fit_description(), "cv");
        // The one difference: library callers fit without the user's cache.
        assert!(!parsed.no_model_cache && default.no_model_cache);
        assert!(default.cache().is_none());
    }
}

/// The files a command reads and the files it writes. [`CommandFiles::check`]
/// runs before anything is computed: an output that is an input or another
/// output is a usage error (exit 2) naming both; an output that cannot be
/// replaced (read-only, a dangling link, a folder that cannot be created) is
/// an error. A missing folder is not: it is created when the outputs are
/// written (`crate::io`'s one rule for output folders).
#[derive(Debug, Default)]
pub struct CommandFiles {
    inputs: Vec<crate::io::NamedPath>,
    outputs: Vec<crate::io::NamedPath>,
}

impl CommandFiles {
    pub fn new() -> CommandFiles {
        CommandFiles::default()
    }

    pub fn input(mut self, role: &str, path: Option<&Path>) -> CommandFiles {
        if let Some(path) = path {
            self.inputs.push(crate::io::NamedPath::new(role, path));
        }
        self
    }

    pub fn output(mut self, role: &str, path: Option<&Path>) -> CommandFiles {
        if let Some(path) = path {
            self.outputs.push(crate::io::NamedPath::new(role, path));
        }
        self
    }

    /// The machine file and its error tables.
    pub fn machine(mut self, machine: &Machine) -> CommandFiles {
        self = self.input("the machine file", Some(&machine.source));
        for table in machine.tables.iter().flatten() {
            self = self.input("the error table", Some(&table.path));
        }
        self
    }

    /// `--model`.
    pub fn model(self, args: &ModelArgs) -> CommandFiles {
        self.input("the model (--model)", args.model.as_deref())
    }

    /// `--var` and `--tools`.
    pub fn program_args(self, args: &ProgramArgs) -> CommandFiles {
        self.input("the parameter file (--var)", args.var.as_deref())
            .input("the tool table (--tools)", args.tools.as_deref())
    }

    pub fn check(&self) -> anyhow::Result<()> {
        crate::io::check_outputs(&self.inputs, &self.outputs)
            .map_err(|e| super::UsageError(e.to_string()))?;
        for output in &self.outputs {
            if !crate::io::is_stdio(&output.path) {
                crate::io::check_writable(&output.path)?;
            }
        }
        Ok(())
    }
}
