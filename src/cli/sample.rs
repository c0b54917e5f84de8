//! `volcomp sample`: write the bundled sample programs.
use crate::io::write_file_atomic;
use crate::machine::{LoadOptions, Machine};
use crate::sample::flank::FlankOptions;
use crate::sample::saddle::{SaddleOptions, generate};
use anyhow::Context;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
  volcomp sample saddle
  volcomp sample saddle --machine machines/bc-trt.toml   # writes samples/bc-trt/
  volcomp sample saddle --machine machines/head-table.toml --out-dir my-samples
  volcomp sample flank";

const AFTER_HELP: &str = "\
Writes saddle.nc (joint frame: a roughing pass with T2, a ball-end R5 leaving
1 mm, then the finishing pass with T1, the machine's [tool]), saddle-tcp.nc (the
same path with tool-tip control, G43.4 ... G49), saddle-plan.csv (372 inspection
points with normals) and saddle.tbl (the LinuxCNC tool table of T1 and T2) into
--out-dir: by default samples/ for the reference machine (ref-trt) and
samples/<machine>/ for any other, so that one machine's saddle never replaces
another's. Each program names its machine in its header.

The flank sample writes flank.nc (joint frame: the wall of a drafted boss,
R40 at the foot centred at X20 Y-15, 20 mm high, 10 deg draft, cut in one revolution by the side of
T3, which the machine file's [[tools]] must list with a shape and a flute long
enough for the wall) and flank-plan.csv (180 wall points with normals).

The output is deterministic: the same machine gives the same bytes. A file that
already holds those bytes is left as it is; a file that differs is refused unless
--force (the message names it).";

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
    /// Folder to write into (created when missing) [default: samples/ for
    /// ref-trt, samples/<machine>/ for any other machine].
    #[arg(long, value_name = "DIR")]
    pub out_dir: Option<PathBuf>,
    /// Replace files that hold something else (without it, such a file is
    /// refused, and nothing is written).
    #[arg(long)]
    pub force: bool,
}

/// The machine whose samples are `samples/` itself.
const REFERENCE_MACHINE: &str = "ref-trt";

/// Where a machine's samples go by default: `samples/` for the reference
/// machine, `samples/<machine>/` for any other (one machine's saddle never
/// replaces another's).
fn default_out_dir(machine: &Machine) -> PathBuf {
    let samples = PathBuf::from("samples");
    if machine.name == REFERENCE_MACHINE {
        samples
    } else {
        samples.join(&machine.name)
    }
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
    let out_dir = args
        .out_dir
        .clone()
        .unwrap_or_else(|| default_out_dir(&machine));
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
                &machine.name,
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
                &machine.name,
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
        command_files = command_files.output("the sample file", Some(&out_dir.join(name)));
    }
    command_files.check()?;
    // A file that holds other bytes is replaced only with --force; one that
    // holds these bytes already is left as it is.
    let mut changed = Vec::new();
    let mut unchanged = Vec::new();
    for (name, text) in &files {
        let path = out_dir.join(name);
        match std::fs::read(&path) {
            Ok(old) if old == text.as_bytes() => unchanged.push(path),
            Ok(_) => changed.push((path, text, true)),
            Err(_) => changed.push((path, text, false)),
        }
    }
    let differing: Vec<String> = changed
        .iter()
        .filter(|(_, _, exists)| *exists)
        .map(|(path, _, _)| path.display().to_string())
        .collect();
    if !differing.is_empty() && !args.force {
        anyhow::bail!(
            "{} already {} something else; nothing written (--force replaces {}, --out-dir writes elsewhere)",
            differing.join(", "),
            if differing.len() == 1 {
                "holds"
            } else {
                "hold"
            },
            if differing.len() == 1 { "it" } else { "them" },
        );
    }
    if !changed.is_empty() {
        std::fs::create_dir_all(&out_dir)
            .with_context(|| format!("cannot create {}", out_dir.display()))?;
    }
    let outputs = crate::io::OutputSet::begin();
    for (path, text, _) in &changed {
        write_file_atomic(path, text.as_bytes())?;
    }
    outputs.commit()?;
    let mut summary = Vec::new();
    for (path, text, existed) in &changed {
        summary.push(format!(
            "{} {} ({} lines)",
            if *existed { "replaced" } else { "wrote" },
            path.display(),
            text.lines().count()
        ));
    }
    for path in &unchanged {
        summary.push(format!(
            "{} unchanged (already these bytes)",
            path.display()
        ));
    }
    super::common::say(false, &summary.join("\n"))?;
    Ok(())
}
