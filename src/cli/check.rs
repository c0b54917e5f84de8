//! `volcomp check`: read and interpret a whole program (streaming), print what
//! it holds, exit 1 with a located error on bad input.
use super::common::ProgramArgs;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use crate::gcode::{
    BlockEvent, Execution, Frame, InterpretOptions, MotionKind, MotionMode, ProgramSetup,
    ProgramSummary, summary::Range,
};
use std::io::Write;

pub const EXAMPLES: &str = "\
  volcomp check samples/saddle.nc
  volcomp check samples/saddle.nc --tools samples/saddle.tbl --targets targets.csv   # T words against the tool table
  volcomp check samples/saddle.nc --offset G54=250,120,-310 --targets -   # other controllers' origins
  volcomp check samples/saddle-tcp.nc --flatten -o flat.ngc   # loops, subroutines and cycles written out
  volcomp check samples/bc-trt/saddle.nc --machine machines/bc-trt.toml   # B/C program: the machine's letters
  volcomp check samples/bc-trt/saddle-tcp.nc --machine machines/bc-trt.toml --frame part --targets tip.csv   # tool tip and axis in the workpiece frame
  printf 'TRAORI\\nG1 X5 Y-5 Z12 A30 C90 F500\\nM30\\n' | volcomp check - --dialect sinumerik --machine machines/ref-trt.toml --frame part --targets -   # any dialect
  volcomp check samples/saddle.nc --lenient --json   # pass constructs it cannot understand through
  cat samples/saddle.nc | volcomp check -";

const AFTER_HELP: &str = "\
A LinuxCNC machine's setup (work origins G54…, G92, G28/G30 positions) comes from its \
parameter file with --var FILE.var; other controllers' origins with --offset. \
--subroutine-path DIR finds o<name> call in DIR/name.ngc. --frame part reads a program \
that starts with tool-tip control already on; with --targets it writes \
`line,motion,x,y,z,i,j,k` instead: every motion end as the tool tip (mm) and the unit tool \
axis in the workpiece frame (the work offset's / preset's frame, before G92, datum shifts, \
frames and working planes), for every dialect. --machine turns rotary positions into the \
axis (without it a rotary position other than 0 is an error at its block); x,y,z stay empty \
where the reading cannot place the tip (G53/SUPA/M91/M92 moves, a rotary axis away from 0 \
without tool-tip control).";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// The G-code program (`-` for standard input).
    pub program: PathBuf,
    #[command(flatten)]
    pub read: ProgramArgs,
    /// Rapid rate for G0 durations, mm/min (default: the machine's, else 10000).
    #[arg(long)]
    pub rapid: Option<f64>,
    /// The machine the program is for: its axis letters (a word for an axis it
    /// lacks is an error, as LinuxCNC's "Bad character"), the columns of
    /// --targets, its tool table and rapid rate. Without it X Y Z A B C are read,
    /// as LinuxCNC's rs274 does without an INI file.
    #[arg(long, value_name = "MACHINE.toml")]
    pub machine: Option<PathBuf>,
    /// Honour block delete: skip lines starting with `/`.
    #[arg(long)]
    pub skip_deleted: bool,
    /// Write every executed motion end point (loops and cycles expanded):
    /// `line,motion,x,y,z,a,b,c,tool` in machine coordinates, mm and degrees
    /// (work origin, G92 and units applied; tool length offset not applied;
    /// the columns of rotary axes the machine lacks empty, `u,v,w` added for a
    /// machine that has them; `tool`: the tool in the spindle, 0 before the
    /// first tool change). With `--frame part`: `line,motion,x,y,z,i,j,k`,
    /// the tool tip and tool axis in the workpiece frame (below). `-` for
    /// standard output.
    #[arg(long, value_name = "FILE.csv", conflicts_with = "flatten")]
    pub targets: Option<PathBuf>,
    /// Write the program flat to `-o`, without compensating: every block that
    /// parameters, loops, subroutines or a canned cycle produced becomes
    /// explicit blocks with a `(volcomp: line N)` comment; other lines are
    /// copied byte for byte.
    #[arg(long, requires = "output")]
    pub flatten: bool,
    /// Output of `--flatten` (`-` for standard output).
    #[arg(short, long, value_name = "OUT", requires = "flatten")]
    pub output: Option<PathBuf>,
    /// Print the summary as JSON on standard output (the human summary then
    /// goes to standard error): counts, ranges, tools, warnings, stamp.
    #[arg(long)]
    pub json: bool,
}

/// A `check` run, validated: the machine (if any), how the program is read,
/// and whether standard output carries data.
struct Job<'a> {
    args: &'a Args,
    machine: Option<crate::machine::Machine>,
    options: InterpretOptions,
    data_on_stdout: bool,
    /// `--frame part --targets`: the targets in the workpiece frame.
    workpiece: Option<crate::toolpath::WorkpieceFrame>,
}

/// The program to read: its input, the name it is reported under, the
/// reading set-up, and the stamp of a compensated program.
struct Input {
    input: Box<dyn crate::gcode::ProgramInput>,
    name: PathBuf,
    setup: ProgramSetup,
    stamp: Option<crate::stamp::Stamp>,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let job = Job::new(args)?;
    let outputs = crate::io::OutputSet::begin();
    let input = job.open()?;
    if let (true, Some(output)) = (args.flatten, &args.output) {
        return job.flatten(input, output, outputs);
    }
    job.check(input, outputs)
}

impl<'a> Job<'a> {
    /// Load the machine, check the options and that no output overwrites an input.
    fn new(args: &'a Args) -> anyhow::Result<Self> {
        let machine = args
            .machine
            .as_deref()
            .map(|path| {
                crate::machine::Machine::load_with(
                    path,
                    &crate::machine::LoadOptions {
                        extrapolation: crate::machine::ExtrapolationPolicy::Hold,
                    },
                )
            })
            .transpose()?;
        let rapid = args
            .rapid
            .unwrap_or(machine.as_ref().map_or(10_000.0, |m| m.rapid_mm_per_min));
        if !(rapid.is_finite() && rapid > 0.0) {
            return Err(super::UsageError(format!(
                "--rapid must be a positive number of mm/min, got {rapid}"
            ))
            .into());
        }
        let letters = machine
            .as_ref()
            .map_or(crate::axes::AxisSet::RS274, |m| m.letters());
        let data_on_stdout = super::common::stdout_output(&[
            (
                "--targets -",
                super::common::is_stdout(args.targets.as_deref()),
            ),
            ("-o -", super::common::is_stdout(args.output.as_deref())),
            ("--json", args.json),
        ])?;
        let options = InterpretOptions {
            skip_deleted_blocks: args.skip_deleted,
            ..args.read.interpret_options(rapid, letters)
        };
        let files = super::common::CommandFiles::new()
            .input("the program", Some(&args.program))
            .input("the machine file", args.machine.as_deref());
        let files = match &machine {
            Some(m) => files.machine(m),
            None => files,
        };
        files
            .program_args(&args.read)
            .output("--targets", args.targets.as_deref())
            .output("-o", args.output.as_deref())
            .check()?;
        let workpiece = (options.initial_frame == Frame::Part && args.targets.is_some())
            .then(|| crate::toolpath::WorkpieceFrame::new(machine.as_ref(), letters));
        Ok(Job {
            args,
            machine,
            options,
            data_on_stdout,
            workpiece,
        })
    }

    /// The reading set-up and the program.
    fn open(&self) -> anyhow::Result<Input> {
        let args = self.args;
        let setup = args.read.setup(self.machine.as_ref())?;
        let name = if crate::io::is_stdio(&args.program) {
            PathBuf::from("<stdin>")
        } else {
            args.program.clone()
        };
        let (input, stamp) = super::common::open_program_with_stamp(&args.program)?;
        Ok(Input {
            input,
            name,
            setup,
            stamp,
        })
    }

    /// `--flatten -o OUT`: the program written flat, then its summary.
    fn flatten(
        &self,
        input: Input,
        output: &Path,
        outputs: crate::io::OutputSet,
    ) -> anyhow::Result<()> {
        let args = self.args;
        let warnings = input.setup.warnings.clone();
        let (name, stamp) = (&input.name, &input.stamp);
        // A flat program holds no O-words: the subroutine definitions the
        // program passes over are left out (their calls come flat).
        let mut setup = input.setup;
        setup.language.drop_definitions = true;
        let program = crate::gcode::Program::new(input.input, name, setup);
        super::common::announce_dialect(&program);
        let mut stats = None;
        crate::io::write_atomic(output, |out| -> anyhow::Result<()> {
            stats = Some(crate::gcode::rewrite_stream(
                program.run(self.options),
                out,
                crate::gcode::RewriteOptions::default(),
                |_, _, _| None,
            )?);
            Ok(())
        })
        .with_context(|| {
            format!(
                "the flat program was not written (whole) to {}",
                crate::io::display_name(output)
            )
        })?;
        outputs.commit()?;
        let stats = stats.expect("written");
        let groups = warnings.groups();
        if args.json {
            let report = FlattenReport {
                program: name.display().to_string(),
                blocks: stats.blocks,
                motions: stats.motions,
                flat: stats.flat,
                pieces: stats.pieces,
                output: output.display().to_string(),
                compensated: stamp.is_some(),
                stamp: stamp.as_ref(),
                warnings: &groups,
            };
            super::stdout_text(&(serde_json::to_string_pretty(&report)? + "\n"))?;
        }
        super::common::print_warnings(&groups);
        if let Some(stamp) = stamp {
            super::noteln!("{}: {}", args.program.display(), stamp.summary());
        }
        crate::cli::humanln!(
            self.data_on_stdout,
            "{}: {} executed ({}), {} written flat (+{} for canned cycles), flat program written to {}{}",
            args.program.display(),
            super::common::count(stats.blocks as u64, "block", "blocks"),
            super::common::count(stats.motions as u64, "single move", "single moves"),
            stats.flat,
            super::common::count(stats.pieces as u64, "line", "lines"),
            crate::io::display_name(output),
            super::common::result_note(&groups)
        );
        Ok(())
    }

    /// Read the program through (writing `--targets` where asked), then its summary.
    fn check(&self, input: Input, outputs: crate::io::OutputSet) -> anyhow::Result<()> {
        let args = self.args;
        let options = self.options;
        let Input {
            input,
            name,
            setup,
            stamp,
        } = input;
        let warnings = setup.warnings.clone();
        let summary = match &args.targets {
            None => check_stream(input, &name, options, &setup, None, None)?,
            Some(path) if crate::io::is_stdio(path) => {
                let stdout = std::io::stdout();
                let mut out = std::io::BufWriter::new(stdout.lock());
                let s = check_stream(
                    input,
                    &name,
                    options,
                    &setup,
                    Some((&mut out, "standard output")),
                    self.workpiece.as_ref(),
                )?;
                out.flush()
                    .context("cannot write the targets to standard output")?;
                s
            }
            Some(path) => {
                let mut summary = None;
                crate::io::write_atomic(path, |out| -> anyhow::Result<()> {
                    summary = Some(check_stream(
                        input,
                        &name,
                        options,
                        &setup,
                        Some((out, "the file")),
                        self.workpiece.as_ref(),
                    )?);
                    Ok(())
                })
                .with_context(|| format!("no targets were written to {}", path.display()))?;
                summary.expect("written")
            }
        };
        outputs.commit()?;
        let groups = warnings.groups();
        if args.json {
            let report = CheckReport {
                program: name.display().to_string(),
                frame: match options.initial_frame {
                    Frame::Joint => "joint",
                    Frame::Part => "part",
                },
                summary: &summary,
                passed_through: summary.passed_through(),
                targets: args.targets.as_ref().map(|p| p.display().to_string()),
                compensated: stamp.is_some(),
                stamp: stamp.as_ref(),
                warnings: &groups,
            };
            super::stdout_text(&(serde_json::to_string_pretty(&report)? + "\n"))?;
        }
        let mut text = summary_text(&args.program, &summary, options.initial_frame, &groups);
        if let Some(dialect) = &summary.dialect {
            text.push_str(&format!("\n  dialect: {dialect}"));
        }
        if let Some(stamp) = &stamp {
            text.push_str(&format!("\n  stamp: {}", stamp.summary()));
        }
        if let Some(path) = &args.targets {
            text.push_str(&format!(
                "\n  targets: {} written to {}",
                super::common::count(summary.motion.total() as u64, "row", "rows"),
                crate::io::display_name(path)
            ));
        }
        super::common::say(self.data_on_stdout, &text)
    }
}

/// `check --json`.
#[derive(serde::Serialize)]
struct CheckReport<'a> {
    program: String,
    frame: &'static str,
    #[serde(flatten)]
    summary: &'a ProgramSummary,
    passed_through: std::collections::BTreeMap<String, usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    targets: Option<String>,
    compensated: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    stamp: Option<&'a crate::stamp::Stamp>,
    warnings: &'a [crate::warnings::WarningGroup],
}

/// `check --flatten --json`.
#[derive(serde::Serialize)]
struct FlattenReport<'a> {
    program: String,
    blocks: usize,
    motions: usize,
    flat: usize,
    pieces: usize,
    output: String,
    compensated: bool,
    #[serde(skip_serializing_if = "Option::is_none")]
    stamp: Option<&'a crate::stamp::Stamp>,
    warnings: &'a [crate::warnings::WarningGroup],
}

/// Run `input` through both layers, counting as it goes, and write every
/// motion end point to `targets` when given: in machine coordinates, or in
/// the workpiece frame when `workpiece` is given (`--frame part`).
pub fn check_stream(
    input: Box<dyn crate::gcode::ProgramInput>,
    path: &Path,
    options: InterpretOptions,
    setup: &ProgramSetup,
    mut targets: Option<(&mut dyn Write, &str)>,
    workpiece: Option<&crate::toolpath::WorkpieceFrame>,
) -> anyhow::Result<ProgramSummary> {
    let mut run = Execution::new(input, path, options, setup);
    let mut summary = ProgramSummary::default();
    summary.dialect = super::common::dialect_note(run.dialect());
    summary.read_in = run.dialect().dialect;
    use crate::axes::Axis;
    let letters = options.axes;
    // The contract's columns, plus u v w for a machine that has them.
    let mut columns = vec![Axis::X, Axis::Y, Axis::Z, Axis::A, Axis::B, Axis::C];
    columns.extend(
        [Axis::U, Axis::V, Axis::W]
            .into_iter()
            .filter(|a| letters.contains(*a)),
    );
    if let Some((out, to)) = targets.as_mut() {
        let header = match workpiece {
            Some(_) => "line,motion,x,y,z,i,j,k\n".to_string(),
            None => {
                let names: Vec<String> = columns.iter().map(|a| a.lower().to_string()).collect();
                format!("line,motion,{},tool\n", names.join(","))
            }
        };
        out.write_all(header.as_bytes())
            .with_context(|| format!("cannot write the targets to {to}"))?;
    }
    let mut row = String::new();
    // A block `--frame part` cannot turn into a row, and its file.
    let mut unplaced = None;
    'blocks: while let Some(step) = run.next() {
        let (block, event, executed) = step.map_err(anyhow::Error::new)?;
        summary.add(block, event);
        if let (Some((out, to)), Some(frame)) = (targets.as_mut(), workpiece) {
            for m in event.motions() {
                let target = match frame.target(block, event, m) {
                    Ok(target) => target,
                    Err(e) => {
                        unplaced = Some((e, executed.file));
                        break 'blocks;
                    }
                };
                row.clear();
                workpiece_row(&mut row, executed.line, motion_code(m, event), &target);
                out.write_all(row.as_bytes())
                    .with_context(|| format!("cannot write the targets to {to}"))?;
            }
        } else if let Some((out, to)) = targets.as_mut() {
            for m in event.motions() {
                row.clear();
                let code = motion_code(m, event);
                let e = &m.end;
                use std::fmt::Write as _;
                let _ = write!(row, "{},{code}", executed.line);
                for axis in &columns {
                    if letters.contains(*axis) {
                        let _ = write!(row, ",{:.6}", e.get(*axis));
                    } else {
                        row.push(',');
                    }
                }
                let _ = writeln!(row, ",{}", event.tool.number);
                out.write_all(row.as_bytes())
                    .with_context(|| format!("cannot write the targets to {to}"))?;
            }
        }
    }
    if let Some((e, file)) = unplaced {
        let file = match file {
            0 => path.to_path_buf(),
            n => PathBuf::from(run.file_name(n)),
        };
        return Err(anyhow::Error::new(e.with_path(file)));
    }
    Ok(summary)
}

/// A row of `--frame part --targets`: `line,motion,x,y,z,i,j,k` (x y z
/// empty where the tip is not placed), no negative zeros.
fn workpiece_row(
    row: &mut String,
    line: usize,
    code: &str,
    target: &crate::toolpath::WorkpieceTarget,
) {
    use std::fmt::Write as _;
    let _ = write!(row, "{line},{code}");
    match target.tip {
        Some(tip) => {
            for v in tip {
                let _ = write!(row, ",{}", fixed(v, 6));
            }
        }
        None => row.push_str(",,,"),
    }
    for v in target.axis {
        let _ = write!(row, ",{}", fixed(v, 9));
    }
    row.push('\n');
}

/// `v` with `decimals` decimals, `-0.000` written `0.000`.
fn fixed(v: f64, decimals: usize) -> String {
    let text = format!("{v:.decimals$}");
    if text.starts_with('-') && text.bytes().all(|b| matches!(b, b'-' | b'0' | b'.')) {
        text[1..].to_string()
    } else {
        text
    }
}

/// The G code of a move as the targets file names it.
fn motion_code(m: &crate::gcode::Motion, event: &BlockEvent) -> &'static str {
    match m.kind {
        MotionKind::Rapid => "G0",
        MotionKind::Arc {
            clockwise: true, ..
        } => "G2",
        MotionKind::Arc { .. } => "G3",
        MotionKind::Linear => match (event.motion().is_some(), event.modal.motion, event.spline) {
            (true, MotionMode::Probe(_), _) => event.modal.motion.word(),
            // The straight pieces of a spline: named by its code.
            (false, _, Some(crate::gcode::interpret::SplineStep::Curve { code, .. })) => match code
            {
                50 => "G5",
                51 => "G5.1",
                _ => "G5.2",
            },
            _ => "G1",
        },
    }
}

fn range(r: &Option<Range>) -> String {
    match r {
        Some(r) => format!("[{:.4}, {:.4}]", r.min, r.max),
        None => "-".into(),
    }
}

/// `T1 (L 40 mm, R 5 mm) lines 3–40 (12 moves); …`.
pub(crate) fn tool_runs(s: &ProgramSummary) -> String {
    if s.tools.is_empty() {
        return "no moves".into();
    }
    let mut parts: Vec<String> = s
        .tools
        .iter()
        .map(|r| {
            let tool = r.tool;
            let moves = if r.moves == 1 { "move" } else { "moves" };
            format!(
                "{tool} lines {}–{} ({} {moves})",
                r.first_line, r.last_line, r.moves
            )
        })
        .collect();
    if s.tool_runs > s.tools.len() {
        parts.push(format!("… {} more runs", s.tool_runs - s.tools.len()));
    }
    parts.join("; ")
}

/// The ranges of the rotary axes (and U V W) the program moves.
fn rotary_ranges(s: &ProgramSummary) -> String {
    let moved = |list: [(&str, &Option<Range>); 3]| -> Vec<String> {
        list.iter()
            .filter(|(_, r)| r.as_ref().is_some_and(|r| r.min != 0.0 || r.max != 0.0))
            .map(|(l, r)| format!("{l} {}", range(r)))
            .collect()
    };
    let rotary = moved([("A", &s.a), ("B", &s.b), ("C", &s.c)]);
    let uvw = moved([("U", &s.u), ("V", &s.v), ("W", &s.w)]);
    let mut text = if rotary.is_empty() {
        "  rotary axes: not moved".to_string()
    } else {
        format!("  {} deg", rotary.join("  "))
    };
    if !uvw.is_empty() {
        text.push_str(&format!("; {} mm", uvw.join("  ")));
    }
    text
}

/// The summary's count of moves, in the words of the program's dialect:
/// LinuxCNC's G0 G1 G2 G3, G53 and G28/G30; SINUMERIK's G0 … G3, SUPA/G53
/// (machine coordinates) and G74/G75 (to the reference / fixed point);
/// Klartext's `L … FMAX`, `L`, `C DR-`/`C DR+`, `M91`/`M92` and the rotary
/// legs of `PLANE … TURN`.
fn motion_line(s: &ProgramSummary) -> String {
    let m = &s.motion;
    let (machine, home) = match s.read_in {
        crate::gcode::Dialect::LinuxCnc => ("G53", "G28/G30"),
        crate::gcode::Dialect::Sinumerik => ("SUPA/G53", "G74/G75"),
        crate::gcode::Dialect::Heidenhain => {
            return format!(
                "  moves: {} (L … FMAX {}, L {}, C DR- {}, C DR+ {}), M91/M92 {}, PLANE … TURN {}",
                m.total(),
                m.rapid,
                m.linear,
                m.arc_cw,
                m.arc_ccw,
                s.machine_coordinate_motions,
                s.home_blocks.saturating_sub(s.machine_coordinate_motions)
            );
        }
    };
    format!(
        "  motion blocks: {} (G0 {}, G1 {}, G2 {}, G3 {}), {machine} {}, {home} {}",
        m.total(),
        m.rapid,
        m.linear,
        m.arc_cw,
        m.arc_ccw,
        s.machine_coordinate_motions,
        s.home_blocks
    )
}

/// The summary's inverse-time line: G93 in LinuxCNC's and SINUMERIK's
/// words; none for Klartext, which has no inverse-time feed (empty).
fn inverse_time_line(s: &ProgramSummary) -> String {
    match s.read_in {
        crate::gcode::Dialect::Heidenhain => String::new(),
        _ => format!("  G93 inverse-time moves: {}", s.inverse_time_motions),
    }
}

/// The human summary: one line about the program, then indented details.
fn summary_text(
    path: &Path,
    s: &ProgramSummary,
    frame: Frame,
    warnings: &[crate::warnings::WarningGroup],
) -> String {
    let list = |map: &mut dyn Iterator<Item = (String, usize)>| {
        let v: Vec<String> = map.map(|(k, n)| format!("{k}×{n}")).collect();
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(" ")
        }
    };
    let mut lines = vec![
        format!(
            "{}: {} executed, {}, {}, {} with block delete{}",
            path.display(),
            super::common::count(s.lines as u64, "line", "lines"),
            super::common::count(s.blocks as u64, "block", "blocks"),
            super::common::count(s.comments as u64, "comment", "comments"),
            s.deleted_blocks,
            super::common::result_note(warnings)
        ),
        motion_line(s),
        format!(
            "  frame: {} at start, {} switches, {} part-frame (tool-tip) moves",
            match frame {
                Frame::Joint => "joint",
                Frame::Part => "part",
            },
            s.frame_switches,
            s.part_frame_motions
        ),
        inverse_time_line(s),
        format!("  machining time: {:.3} min", s.time_min),
        format!(
            "  X {}  Y {}  Z {} mm",
            range(&s.x),
            range(&s.y),
            range(&s.z)
        ),
        rotary_ranges(s),
        format!("  tools: {}", tool_runs(s)),
        format!(
            "  unknown words: {}",
            list(&mut s.unknown_words.iter().map(|(k, n)| (k.to_string(), *n)))
        ),
        format!(
            "  passed through: {}",
            list(&mut s.passed_through().into_iter())
        ),
    ];
    lines.retain(|l| !l.is_empty());
    let total: u64 = warnings.iter().map(|g| g.count).sum();
    lines.push(format!(
        "  warnings: {}",
        if warnings.len() > 1 {
            format!("{total} of {} kinds", warnings.len())
        } else {
            total.to_string()
        }
    ));
    for w in super::common::warning_lines(warnings) {
        lines.push(format!("    {w}"));
    }
    lines.join("\n")
}
