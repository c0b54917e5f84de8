//! `volcomp sample`: write the bundled sample programs.
use crate::io::write_file_atomic;
use crate::machine::{LoadOptions, Machine};
use crate::sample::saddle::{SaddleOptions, generate};
use anyhow::Context;
use std::path::PathBuf;

const AFTER_HELP: &str = "\
Examples:
  volcomp sample saddle
  volcomp sample saddle --machine machines/ref-trt.toml --out-dir samples

Writes saddle.nc (joint frame: a roughing pass with T2, a ball-end R5 leaving
1 mm, then the finishing pass with T1, the machine's [tool]), saddle-tcp.nc (the
same path with tool-tip control, G43.4 ... G49), saddle-plan.csv (372 inspection
points with normals) and saddle.tbl (the LinuxCNC tool table of T1 and T2) into
--out-dir. The output is deterministic: the same machine gives the same bytes.";

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SampleName {
    /// A saddle-style bicycle seat, like the seed paper's (blank 100 × 80 × 40 mm).
    Saddle,
}

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// Which sample.
    #[arg(value_enum)]
    pub name: SampleName,
    /// Machine whose nominal kinematics the joint program is written for.
    #[arg(long, default_value = "machines/ref-trt.toml")]
    pub machine: PathBuf,
    /// Folder to write into.
    #[arg(long, default_value = "samples")]
    pub out_dir: PathBuf,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let machine = Machine::load_with(
        &args.machine,
        &LoadOptions {
            extrapolation: crate::machine::ExtrapolationPolicy::Hold,
        },
    )?;
    let options = SaddleOptions {
        tool_radius: machine.tool.radius,
        ..SaddleOptions::default()
    };
    let files = generate(
        &machine.kinematics_model(),
        Some(machine.limits.a),
        &options,
    )
    .with_context(|| format!("generating the saddle for {}", args.machine.display()))?;
    std::fs::create_dir_all(&args.out_dir)
        .with_context(|| format!("cannot create {}", args.out_dir.display()))?;
    for (name, text) in [
        ("saddle.nc", &files.joint_program),
        ("saddle-tcp.nc", &files.part_program),
        ("saddle-plan.csv", &files.plan_csv),
        ("saddle.tbl", &files.tool_table),
    ] {
        let path = args.out_dir.join(name);
        write_file_atomic(&path, text.as_bytes())?;
        crate::outln!("wrote {} ({} lines)", path.display(), text.lines().count());
    }
    Ok(())
}
