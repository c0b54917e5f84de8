//! `volcomp simulate`: synthetic CMM measurements of the part a program cuts on a
//! machine (effects.md): the machine's geometric volumetric error (its tables as
//! the truth), plus the given unmodelled effects, plus Gaussian probing noise.
use super::UsageError;
use crate::diagnose::{Effect, SimulateOptions, simulate};
use crate::inspection::{Plan, profile};
use anyhow::Context;
use std::path::PathBuf;

const AFTER_HELP: &str = "\
Effects (parameters default to 0; thermal_drift needs tau):
  thermal_drift:dx,dy,dz (µm),tau (min)   backlash:bx,by,bz (µm)   servo_lag:k (s²)
  tool_deflection:c (µm)   tool_wear:w (µm/m)   radius_offset:r (µm)
  setup_error:tx,ty,tz (µm),rx,ry,rz (µrad)   squareness:s_xy,s_xz,s_yz (µrad)
  rotary_location:EY0A,EZ0A,EB0A,EC0A,EX0C,EY0C,EA0C,EB0C (µm, µrad)

Examples:
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv -o meas.csv --effect backlash:bx=6,by=0,bz=3
  volcomp simulate machines/ref-trt.toml part.nc plan.csv -o meas.csv --effect thermal_drift:dz=-6,tau=5 --effect tool_wear:w=4 --noise-um 0.5 --seed 7";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    #[command(flatten)]
    pub machine: super::common::MachineArgs,
    /// Program (G-code) that cuts the part.
    pub program: PathBuf,
    #[command(flatten)]
    pub read: super::common::ProgramArgs,
    /// Inspection plan (CSV: id,x,y,z,i,j,k).
    pub plan: PathBuf,
    /// Output measurement (CSV: id,x,y,z,i,j,k,mx,my,mz; `-` for stdout).
    #[arg(short, long)]
    pub output: PathBuf,
    /// An unmodelled effect to inject, `NAME` or `NAME:k=v,...` (repeatable).
    #[arg(long = "effect", value_name = "NAME:k=v,...")]
    pub effects: Vec<String>,
    /// Probing noise along the normal, µm (one standard deviation).
    #[arg(long, default_value_t = 0.3)]
    pub noise_um: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Also write the tool-path context of every plan point (JSON), for checks
    /// and test fixtures.
    #[arg(long, value_name = "FILE")]
    pub dump_contexts: Option<PathBuf>,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    let effects = args
        .effects
        .iter()
        .map(|s| Effect::parse(s).map_err(|e| UsageError(format!("--effect {s}: {e}"))))
        .collect::<Result<Vec<_>, _>>()?;
    if !(args.noise_um.is_finite() && args.noise_um >= 0.0) {
        return Err(UsageError(format!("--noise-um must be ≥ 0, got {}", args.noise_um)).into());
    }
    let plan = Plan::read(&args.plan)?;
    let part =
        super::diagnose::CutPart::new(&args.machine, &args.program, args.read.clone(), plan)?;
    let contexts = part.contexts()?;
    if let Some(path) = &args.dump_contexts {
        crate::io::write_json_atomic(path, &contexts)?;
    }
    let options = SimulateOptions {
        noise_um: args.noise_um,
        seed: args.seed,
    };
    let measurement = simulate(&contexts, &part.truth_um()?, &effects, &options)
        .context("simulating the measurement")?;
    measurement.write(&args.output)?;
    let cut = contexts.iter().filter(|c| c.cut).count();
    let deviations = measurement.deviations_um();
    let p = profile(&deviations);
    if !crate::io::is_stdio(&args.output) {
        crate::outln!(
            "simulated {} points ({cut} cut by the program) with {}; noise {} µm, seed {}",
            deviations.len(),
            if effects.is_empty() {
                "no unmodelled effect".to_string()
            } else {
                effects
                    .iter()
                    .map(Effect::to_spec)
                    .collect::<Vec<_>>()
                    .join(" + ")
            },
            args.noise_um,
            args.seed
        );
        crate::outln!(
            "measured profile {:.2} µm (range {:.2} µm) -> {}",
            p.profile_um,
            p.range_um,
            args.output.display()
        );
    }
    Ok(())
}
