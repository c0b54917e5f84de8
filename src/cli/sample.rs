//! `volcomp sample`: write the bundled sample programs.
use crate::io::write_file_atomic;
use crate::machine::{LoadOptions, Machine};
use crate::sample::flank::FlankOptions;
use crate::sample::saddle::{SaddleOptions, generate};
use anyhow::Context;
use std::path::PathBuf;

const AFTER_HELP: &str = "\
Examples:
  volcomp sample saddle
  volcomp sample saddle --machine machines/ref-trt.toml --out-dir samples
  volcomp sample flank

Writes saddle.nc (joint frame: a roughing pass with T2, a ball-end R5 leaving
1 mm, then the finishing pass with T1, the machine's [tool]), saddle-tcp.nc (the
same path with tool-tip control, G43.4 ... G49), saddle-plan.csv (372 inspection
points with normals) and saddle.tbl (the LinuxCNC tool table of T1 and T2) into
--out-dir.

The flank sample writes flank.nc (joint frame: the wall of a drafted boss,
R40 at the foot centred at X20 Y-15, 20 mm high, 10 deg draft, cut in one revolution by the side of
T3, which the machine file's [[tools]] must list with a shape and a flute long
enough for the wall) and flank-plan.csv (180 wall points with normals).

The output is deterministic: the same machine gives the same bytes.";

#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SampleName {
    /// A saddle-style bicycle seat, like the seed paper's (blank 100 × 80 × 40 mm).
    Saddle,
    /// The drafted wall of a round boss, flank-milled with the side of a flat end mill.
    Flank,
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

/// The travel of the machine's two rotary axes (letter order).
fn rotary_limits(machine: &Machine) -> [Option<[f64; 2]>; 2] {
    machine.chain.rotary().map(|a| machine.limits.get(a))
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let machine = Machine::load_with(
        &args.machine,
        &LoadOptions {
            extrapolation: crate::machine::ExtrapolationPolicy::Hold,
        },
    )?;
    let files: Vec<(&str, String)> = match args.name {
        SampleName::Saddle => {
            let options = SaddleOptions {
                tool_radius: machine.tool.radius,
                ..SaddleOptions::default()
            };
            let files = generate(
                &machine.kinematics_model(),
                rotary_limits(&machine),
                &options,
            )
            .with_context(|| format!("generating the saddle for {}", args.machine.display()))?;
            vec![
                ("saddle.nc", files.joint_program),
                ("saddle-tcp.nc", files.part_program),
                ("saddle-plan.csv", files.plan_csv),
                ("saddle.tbl", files.tool_table),
            ]
        }
        SampleName::Flank => {
            let options = FlankOptions::default();
            let tool = machine.tools.in_use(options.tool, machine.default_tool());
            let shape = match tool.shape {
                Some(s) if tool.number == options.tool => s,
                _ => anyhow::bail!(
                    "{}: the flank sample cuts with T{}, which [[tools]] must list with its shape and flute_length (docs/extensions.md)",
                    args.machine.display(),
                    options.tool
                ),
            };
            let needed = options.flute_needed_mm();
            if shape.flute_length_mm < needed {
                anyhow::bail!(
                    "{}: T{}'s flute_length {} mm is shorter than the wall it must cut ({needed:.2} mm)",
                    args.machine.display(),
                    options.tool,
                    shape.flute_length_mm
                );
            }
            let options = FlankOptions {
                tool_radius: tool.radius_mm,
                ..options
            };
            let files = crate::sample::flank::generate(
                &machine.kinematics_model(),
                tool.length_mm,
                rotary_limits(&machine),
                &options,
            )
            .with_context(|| {
                format!("generating the flank sample for {}", args.machine.display())
            })?;
            vec![
                ("flank.nc", files.joint_program),
                ("flank-plan.csv", files.plan_csv),
            ]
        }
    };
    let mut command_files = super::common::CommandFiles::new().machine(&machine);
    for (name, _) in &files {
        command_files = command_files.output("the sample file", Some(&args.out_dir.join(name)));
    }
    command_files.check()?;
    let outputs = crate::io::OutputSet::begin();
    for (name, text) in &files {
        write_file_atomic(&args.out_dir.join(name), text.as_bytes())?;
    }
    outputs.commit()?;
    for (name, text) in &files {
        let path = args.out_dir.join(name);
        crate::cli::outln!("wrote {} ({} lines)", path.display(), text.lines().count());
    }
    Ok(())
}
