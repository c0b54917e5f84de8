//! `volcomp diff`: what changed between two programs, block by block.
use super::common::ProgramArgs;
use crate::diff::{AlignOptions, DiffOptions, diff_programs};
use crate::gcode::InterpretOptions;
use crate::io::write_json_atomic;
use std::fmt::Write as _;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
  volcomp compensate machines/ref-trt.toml samples/saddle.nc -o saddle-comp.nc
  volcomp diff samples/saddle.nc saddle-comp.nc
  volcomp diff samples/saddle.nc saddle-comp.nc --report diff.json --top 20
  volcomp diff samples/saddle.nc saddle-comp.nc --match-tol 0.2 --fail-over 100   # exit 1 past 100 µm";

const AFTER_HELP: &str = "\
Blocks are paired by N number when both programs number them, otherwise by a
sequence alignment: motion blocks of the same kind whose targets agree within
--match-tol pair up (a split arc's last straight piece with the arc), the
extra pieces of a split move count as added blocks, and the summary says how
many pieces each split block became.
Changes are B − A of the interpreted end targets as programmed (absolute, mm and
degrees; no tool length enters them); X Y Z changes are shown in µm, rotary axes in
millidegrees.";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// The original program (`-` for standard input).
    pub a: PathBuf,
    /// The changed program, e.g. the compensated one.
    pub b: PathBuf,
    /// Write the report as JSON.
    #[arg(long, value_name = "FILE.json")]
    pub report: Option<PathBuf>,
    /// Motion blocks whose targets differ by at most this (mm, degrees) are the same block.
    #[arg(long, value_name = "MM", default_value_t = 0.05)]
    pub match_tol: f64,
    /// How many of the largest changes to list.
    #[arg(long, value_name = "N", default_value_t = 10)]
    pub top: usize,
    /// Print the report as JSON on standard output (the human summary then
    /// goes to standard error).
    #[arg(long)]
    pub json: bool,
    /// Exit 1 when a paired motion block's |Δ(X,Y,Z)| exceeds this many µm
    /// (for CI: a program changed more than expected).
    #[arg(long, value_name = "UM")]
    pub fail_over: Option<f64>,
    /// How both programs are read.
    #[command(flatten)]
    pub read: ProgramArgs,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if !(args.match_tol.is_finite() && args.match_tol >= 0.0) {
        return Err(super::UsageError(format!(
            "--match-tol must be a non-negative number of mm (got {})",
            args.match_tol
        ))
        .into());
    }
    if crate::io::is_stdio(&args.a) && crate::io::is_stdio(&args.b) {
        return Err(super::UsageError("only one of A and B can be `-`".into()).into());
    }
    if let Some(um) = args.fail_over
        && !(um.is_finite() && um >= 0.0)
    {
        return Err(super::UsageError(format!(
            "--fail-over must be a non-negative number of µm (got {um})"
        ))
        .into());
    }
    let data_on_stdout = super::common::stdout_output(&[
        (
            "--report -",
            super::common::is_stdout(args.report.as_deref()),
        ),
        ("--json", args.json),
    ])?;
    let options = DiffOptions {
        align: AlignOptions {
            match_tolerance: args.match_tol,
            ..AlignOptions::default()
        },
        // Durations do not matter to a diff: the default rapid rate will do.
        interpret: args.read.interpret_options(
            InterpretOptions::default().rapid_mm_per_min,
            crate::axes::AxisSet::ALL,
        ),
        top: args.top,
    };
    super::common::CommandFiles::new()
        .input("program A", Some(&args.a))
        .input("program B", Some(&args.b))
        .program_args(&args.read)
        .output("--report", args.report.as_deref())
        .check()?;
    let outputs = crate::io::OutputSet::begin();
    let (a, stamp_a) = args.read.program_and_stamp(&args.a, None)?;
    let (b, stamp_b) = args.read.program_and_stamp(&args.b, None)?;
    let (warnings_a, warnings_b) = (a.warnings(), b.warnings());
    let mut report = diff_programs(a, b, &options)?;
    // The diff compares the targets as programmed: no tool length enters
    // them, so what the reader says about tools (no tool table, an offset
    // other than the tool's length) changes nothing here and is not said.
    report.warnings = warnings_a
        .groups()
        .into_iter()
        .chain(warnings_b.groups())
        .filter(|w| !matches!(w.kind.as_str(), "no_tool_table" | "tool_length_offset"))
        .collect();
    if let Some(path) = &args.report {
        write_json_atomic(path, &report)?;
    }
    outputs.commit()?;
    if args.json {
        super::stdout_text(&(serde_json::to_string_pretty(&report)? + "\n"))?;
    }
    super::common::print_warnings(&report.warnings);
    let mut text = String::new();
    for (name, path, stamp) in [("A", &args.a, &stamp_a), ("B", &args.b, &stamp_b)] {
        if let Some(stamp) = stamp {
            let _ = writeln!(text, "{name} ({}): {}", path.display(), stamp.summary());
        }
    }
    text.push_str(&summary_text(&report));
    super::common::say(data_on_stdout, &text)?;
    if let Some(limit) = args.fail_over
        && report.max_xyz_change_um > limit
    {
        let at = report.largest.first().map_or(String::new(), |c| {
            format!(" (line {} → line {})", c.line_a, c.line_b)
        });
        anyhow::bail!(
            "a paired motion block changed by {:.3} µm{at}, more than --fail-over {limit} µm",
            report.max_xyz_change_um
        );
    }
    Ok(())
}

/// The human summary: counts, a per-axis table and the largest changes.
pub fn summary_text(r: &crate::diff::DiffReport) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "A: {}, B: {}; {} paired ({} unchanged, {} changed), {} added, {} removed{}",
        super::common::count(r.blocks_a as u64, "block", "blocks"),
        super::common::count(r.blocks_b as u64, "block", "blocks"),
        r.paired,
        r.unchanged,
        r.changed,
        r.added,
        r.removed,
        super::common::result_note(&r.warnings)
    );
    if r.is_identical() {
        let _ = write!(s, "no change");
        return s;
    }
    let _ = writeln!(
        s,
        "{} paired motion blocks: |Δ(X,Y,Z)| max {:.3} µm, RMS {:.3} µm",
        r.motion_pairs, r.max_xyz_change_um, r.rms_xyz_change_um
    );
    let _ = writeln!(s, "axis  unit  max Δ (signed)     mean |Δ|          RMS");
    for a in &r.axes {
        // lengths in µm, angles in millidegrees: both are the value × 1000.
        let unit = if matches!(a.axis, 'A' | 'B' | 'C') {
            "mdeg"
        } else {
            "µm  "
        };
        let k = 1e3;
        let _ = writeln!(
            s,
            "{:<4}  {unit} {:>15.3} {:>12.3} {:>12.3}",
            a.axis,
            a.max_signed * k,
            a.mean_abs * k,
            a.rms * k
        );
    }
    if !r.largest.is_empty() {
        let _ = writeln!(s, "largest changes (line A → line B: |Δxyz| µm):");
        for c in &r.largest {
            let pieces = if c.pieces > 1 {
                format!("  (split into {} pieces; B's last)", c.pieces)
            } else {
                String::new()
            };
            let _ = writeln!(
                s,
                "  {:>7} → {:<7} {:>10.3}{pieces}",
                c.line_a, c.line_b, c.xyz_change_um
            );
        }
    }
    if r.split_blocks > 0 {
        let list: Vec<String> = r
            .splits
            .iter()
            .take(5)
            .map(|p| {
                format!(
                    "line {} → lines {}–{} ({} pieces)",
                    p.line_a, p.first_line_b, p.last_line_b, p.pieces
                )
            })
            .collect();
        let _ = writeln!(
            s,
            "{} block{} of A became {} blocks of B (split moves, flat cycles; each paired with its last piece): {}{}",
            r.split_blocks,
            if r.split_blocks == 1 { "" } else { "s" },
            r.split_pieces,
            list.join(", "),
            if r.split_blocks > list.len() {
                ", …"
            } else {
                ""
            }
        );
    }
    if !r.added_lines.is_empty() {
        let _ = writeln!(s, "first added lines (B): {:?}", r.added_lines);
    }
    if !r.removed_lines.is_empty() {
        let _ = writeln!(s, "first removed lines (A): {:?}", r.removed_lines);
    }
    s.trim_end().to_string()
}
