//! `volcomp check`: read and interpret a whole program (streaming), print what
//! it holds, exit 1 with a located error on bad input.
use super::common::ProgramArgs;
use std::fs::File;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use crate::gcode::{
    BlockEvent, BlockReader, Frame, InterpretOptions, Interpreter, ProgramSummary, ReadOptions,
    summary::Range,
};

const AFTER_HELP: &str = "\
Examples:
  volcomp check samples/saddle.nc
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
    let summary = if crate::io::is_stdio(&args.program) {
        let stdin = std::io::stdin();
        check_stream(stdin.lock(), Path::new("<stdin>"), options)?
    } else {
        let file = File::open(&args.program)
            .with_context(|| format!("cannot read {}", args.program.display()))?;
        check_stream(
            BufReader::with_capacity(1 << 16, file),
            &args.program,
            options,
        )?
    };
    print_summary(&args.program, &summary, options.initial_frame);
    Ok(())
}

/// Read and interpret `input`, counting as it goes.
pub fn check_stream(
    input: impl BufRead,
    path: &Path,
    options: InterpretOptions,
) -> anyhow::Result<ProgramSummary> {
    let mut reader = BlockReader::new(
        input,
        ReadOptions {
            lenient: options.lenient,
        },
    );
    let mut interpreter = Interpreter::new(options);
    let mut event = BlockEvent::default();
    let mut summary = ProgramSummary::default();
    while let Some(block) = reader.next_block() {
        let block = block.map_err(|e| anyhow::Error::new(e.with_path(path)))?;
        interpreter
            .interpret_into(block, &mut event)
            .map_err(|e| anyhow::Error::new(e.with_path(path)))?;
        summary.add(block, &event);
    }
    Ok(summary)
}

fn range(r: &Option<Range>) -> String {
    match r {
        Some(r) => format!("[{:.4}, {:.4}]", r.min, r.max),
        None => "-".into(),
    }
}

fn print_summary(path: &Path, s: &ProgramSummary, frame: Frame) {
    let m = &s.motion;
    println!(
        "{}: {} lines, {} blocks, {} comments, {} with block delete",
        path.display(),
        s.lines,
        s.blocks,
        s.comments,
        s.deleted_blocks
    );
    println!(
        "  motion blocks: {} (G0 {}, G1 {}, G2 {}, G3 {}), G53 {}, G28/G30 {}",
        m.total(),
        m.rapid,
        m.linear,
        m.arc_cw,
        m.arc_ccw,
        s.machine_coordinate_motions,
        s.home_blocks
    );
    println!(
        "  frame: {} at start, {} switches, {} part-frame (tool-tip) moves",
        match frame {
            Frame::Joint => "joint",
            Frame::Part => "part",
        },
        s.frame_switches,
        s.part_frame_motions
    );
    println!("  G93 inverse-time moves: {}", s.inverse_time_motions);
    println!("  machining time: {:.3} min", s.time_min);
    println!(
        "  X {}  Y {}  Z {} mm",
        range(&s.x),
        range(&s.y),
        range(&s.z)
    );
    println!("  A {}  C {} deg", range(&s.a), range(&s.c));
    let list = |map: &mut dyn Iterator<Item = (String, usize)>| {
        let v: Vec<String> = map.map(|(k, n)| format!("{k}×{n}")).collect();
        if v.is_empty() {
            "none".to_string()
        } else {
            v.join(" ")
        }
    };
    println!(
        "  unknown words: {}",
        list(&mut s.unknown_words.iter().map(|(k, n)| (k.to_string(), *n)))
    );
    println!(
        "  passed through: {}",
        list(&mut s.passed_through().into_iter())
    );
    println!("  warnings: {}", s.warnings);
    for w in &s.first_warnings {
        println!("    {w}");
    }
    if s.warnings > s.first_warnings.len() {
        println!("    … {} more", s.warnings - s.first_warnings.len());
    }
}
