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

const AFTER_HELP: &str = "\
Examples:
  volcomp check samples/saddle.nc
  volcomp check part.ngc --var sim.var --targets targets.csv   # machine positions, G54… from the .var
  volcomp check part.nc --offset G54=250,120,-310 --targets -  # other controllers' origins
  volcomp check part.ngc --tools tool.tbl     # T words checked against LinuxCNC's tool table
  volcomp check part.ngc --subroutine-path subs/              # o<name> call finds subs/name.ngc
  volcomp check part.ngc --flatten -o flat.ngc                # loops, subroutines and cycles written out
  volcomp check part.nc --frame part          # program starts with tool-tip control on
  volcomp check legacy.nc --lenient           # pass constructs it cannot understand through
  cat part.nc | volcomp check -";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// The G-code program (`-` for standard input).
    pub program: PathBuf,
    #[command(flatten)]
    pub read: ProgramArgs,
    /// Rapid rate for G0 durations, mm/min.
    #[arg(long, default_value_t = 10_000.0)]
    pub rapid: f64,
    /// Honour block delete: skip lines starting with `/`.
    #[arg(long)]
    pub skip_deleted: bool,
    /// Write every executed motion end point (loops and cycles expanded):
    /// `line,motion,x,y,z,a,b,c,tool` in machine coordinates, mm and degrees
    /// (work origin, G92 and units applied; tool length offset not applied;
    /// `b` empty on an A/C machine; `tool`: the tool in the spindle, 0 before
    /// the first tool change). `-` for standard output.
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
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if !(args.rapid.is_finite() && args.rapid > 0.0) {
        return Err(super::UsageError(format!(
            "--rapid must be a positive number of mm/min, got {}",
            args.rapid
        ))
        .into());
    }
    let options = InterpretOptions {
        skip_deleted_blocks: args.skip_deleted,
        ..args.read.interpret_options(args.rapid)
    };
    let setup = args.read.setup(None)?;
    let name = if crate::io::is_stdio(&args.program) {
        PathBuf::from("<stdin>")
    } else {
        args.program.clone()
    };
    let (input, stamp) = super::common::open_program_with_stamp(&args.program)?;
    if let (true, Some(output)) = (args.flatten, &args.output) {
        // A flat program holds no O-words: the subroutine definitions the
        // program passes over are left out (their calls come flat).
        let mut setup = setup;
        setup.language.drop_definitions = true;
        let program = crate::gcode::Program::new(input, &name, setup);
        let mut stats = None;
        crate::io::write_atomic(output, |out| -> anyhow::Result<()> {
            stats = Some(crate::gcode::rewrite_stream(
                program.run(options),
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
        let stats = stats.expect("written");
        if let Some(stamp) = &stamp {
            eprintln!("note: {}: {}", args.program.display(), stamp.summary());
        }
        if !crate::io::is_stdio(output) {
            crate::outln!(
                "{}: {} blocks executed ({} single moves), {} written flat (+{} lines for canned cycles), flat program written to {}",
                args.program.display(),
                stats.blocks,
                stats.motions,
                stats.flat,
                stats.pieces,
                output.display()
            );
        }
        return Ok(());
    }
    let to_stdout = super::common::writes_stdout(args.targets.as_ref());
    let summary = match &args.targets {
        None => check_stream(input, &name, options, &setup, None)?,
        Some(path) if to_stdout => {
            let _ = path;
            let stdout = std::io::stdout();
            let mut out = std::io::BufWriter::new(stdout.lock());
            let s = check_stream(
                input,
                &name,
                options,
                &setup,
                Some((&mut out, "standard output")),
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
                )?);
                Ok(())
            })
            .with_context(|| format!("no targets were written to {}", path.display()))?;
            summary.expect("written")
        }
    };
    if to_stdout {
        return Ok(());
    }
    print_summary(&args.program, &summary, options.initial_frame)?;
    if let Some(stamp) = &stamp {
        crate::outln!("  stamp: {}", stamp.summary());
    }
    if let Some(path) = &args.targets {
        crate::outln!(
            "  targets: {} rows written to {}",
            summary.motion.total(),
            path.display()
        );
    }
    Ok(())
}

/// Run `input` through both layers, counting as it goes, and write every
/// motion end point to `targets` when given.
pub fn check_stream(
    input: Box<dyn crate::gcode::ProgramInput>,
    path: &Path,
    options: InterpretOptions,
    setup: &ProgramSetup,
    mut targets: Option<(&mut dyn Write, &str)>,
) -> anyhow::Result<ProgramSummary> {
    let mut run = Execution::new(input, path, options, setup);
    let mut summary = ProgramSummary::default();
    if let Some((out, to)) = targets.as_mut() {
        out.write_all(b"line,motion,x,y,z,a,b,c,tool\n")
            .with_context(|| format!("cannot write the targets to {to}"))?;
    }
    let mut row = String::new();
    while let Some(step) = run.next() {
        let (block, event, executed) = step.map_err(anyhow::Error::new)?;
        summary.add(block, event);
        if let Some((out, to)) = targets.as_mut() {
            for m in event.motions() {
                row.clear();
                let code = motion_code(m, event);
                let e = &m.end;
                use std::fmt::Write as _;
                let _ = writeln!(
                    row,
                    "{},{code},{:.6},{:.6},{:.6},{:.6},,{:.6},{}",
                    executed.line, e.x, e.y, e.z, e.a, e.c, event.tool.number
                );
                out.write_all(row.as_bytes())
                    .with_context(|| format!("cannot write the targets to {to}"))?;
            }
        }
    }
    Ok(summary)
}

/// The G code of a move as the targets file names it.
fn motion_code(m: &crate::gcode::Motion, event: &BlockEvent) -> &'static str {
    match m.kind {
        MotionKind::Rapid => "G0",
        MotionKind::Arc {
            clockwise: true, ..
        } => "G2",
        MotionKind::Arc { .. } => "G3",
        MotionKind::Linear => match (event.motion.is_some(), event.modal.motion, event.spline) {
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

fn print_summary(path: &Path, s: &ProgramSummary, frame: Frame) -> anyhow::Result<()> {
    let m = &s.motion;
    crate::outln!(
        "{}: {} lines executed, {} blocks, {} comments, {} with block delete",
        path.display(),
        s.lines,
        s.blocks,
        s.comments,
        s.deleted_blocks
    );
    crate::outln!(
        "  motion blocks: {} (G0 {}, G1 {}, G2 {}, G3 {}), G53 {}, G28/G30 {}",
        m.total(),
        m.rapid,
        m.linear,
        m.arc_cw,
        m.arc_ccw,
        s.machine_coordinate_motions,
        s.home_blocks
    );
    crate::outln!(
        "  frame: {} at start, {} switches, {} part-frame (tool-tip) moves",
        match frame {
            Frame::Joint => "joint",
            Frame::Part => "part",
        },
        s.frame_switches,
        s.part_frame_motions
    );
    crate::outln!("  G93 inverse-time moves: {}", s.inverse_time_motions);
    crate::outln!("  machining time: {:.3} min", s.time_min);
    crate::outln!(
        "  X {}  Y {}  Z {} mm",
        range(&s.x),
        range(&s.y),
        range(&s.z)
    );
    crate::outln!("  A {}  C {} deg", range(&s.a), range(&s.c));
    crate::outln!("  tools: {}", tool_runs(s));
    let list = |map: &mut dyn Iterator<Item = (String, usize)>| {
        let v: Vec<String> = map.map(|(k, n)| format!("{k}×{n}")).collect();
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(" ")
        }
    };
    crate::outln!(
        "  unknown words: {}",
        list(&mut s.unknown_words.iter().map(|(k, n)| (k.to_string(), *n)))
    );
    crate::outln!(
        "  passed through: {}",
        list(&mut s.passed_through().into_iter())
    );
    crate::outln!("  warnings: {}", s.warnings);
    for w in &s.first_warnings {
        crate::outln!("    {w}");
    }
    if s.warnings > s.first_warnings.len() {
        crate::outln!("    … {} more", s.warnings - s.first_warnings.len());
    }
    Ok(())
}
