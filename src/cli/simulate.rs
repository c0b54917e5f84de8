//! `volcomp simulate`: synthetic CMM measurements of the part a program cuts on a
//! machine (effects.md): the machine's geometric volumetric error (its tables as
//! the truth), plus the given unmodelled effects, plus Gaussian probing noise.
use super::UsageError;
use crate::diagnose::{Effect, SimulateOptions, simulate, simulate_followup};
use crate::inspection::{Followup, Plan, profile};
use anyhow::Context;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv -o meas.csv --effect backlash:bx=6,by=0,bz=3
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv -o meas.csv --effect thermal_drift:dz=-6,tau=5 --effect tool_wear:w=4 --noise-um 0.5 --seed 7
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv -o meas.csv --effect rotary_location:EY0A=20,EX0C=12
  volcomp simulate machines/bc-trt.toml samples/bc-trt/saddle.nc samples/bc-trt/saddle-plan.csv -o bc-meas.csv --effect rotary_location:EX0B=20,EZ0B=-15
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv -o meas.csv --effect thermal_drift:dz=-6,tau=5
  volcomp diagnose machines/ref-trt.toml samples/saddle.nc meas.csv --report diag.json --followup-program followup.nc
  volcomp simulate machines/ref-trt.toml samples/saddle.nc samples/saddle-plan.csv --followup followup.csv -o meas2.csv --effect thermal_drift:dz=-6,tau=5";

const AFTER_HELP: &str = "\
Effects (parameters default to 0; thermal_drift needs tau):
  thermal_drift:dx,dy,dz (µm),tau (min)   backlash:bx,by,bz (µm)   servo_lag:k (s²)
  tool_deflection:c (µm)   tool_wear:w (µm/m)   radius_offset:r (µm)
  setup_error:tx,ty,tz (µm),rx,ry,rz (µrad)   squareness:s_xy,s_xz,s_yz (µrad)
  rotary_location: the location errors of the machine's rotary axes (µm, µrad), named as \
in the machine file's [location]: EY0A,EZ0A,EB0A,EC0A,EX0C,EY0C,EA0C,EB0C on an A/C machine, \
EX0B,EZ0B,EA0B,EC0B,EX0C,EY0C,EA0C,EB0C on a B/C one (an unknown name is refused with the \
machine's list)";

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
    /// Frame of the plan's (measurement's) points: part (the rotary plate's) or work
    /// (the program's coordinates: the work offset, G92 and rotation it cuts in applied).
    #[arg(long, value_enum, default_value = "part", value_name = "part|work")]
    pub plan_frame: super::plan_frame::PlanFrame,
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
    /// Simulate the follow-up probing of this plan (from `diagnose
    /// --followup-program`; CSV id,x,y,z,i,j,k,a,c,t_min) instead: OUTPUT
    /// receives its readings (id,…,t_min,mx,my,mz), with the same effects.
    #[arg(long, value_name = "FOLLOWUP.csv")]
    pub followup: Option<PathBuf>,
    #[command(flatten)]
    pub probe: super::diagnose::ProbeArgs,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    // Checked before the (slower) machine load with A/C names; parsed again
    // below with the machine's own (rotary_location names its axes).
    let check_syntax = |rotary| {
        args.effects
            .iter()
            .map(|s| {
                Effect::parse_for(s, rotary).map_err(|e| UsageError(format!("--effect {s}: {e}")))
            })
            .collect::<Result<Vec<_>, _>>()
    };
    let is_location = |s: &String| s.trim_start().starts_with("rotary_location");
    if !args.effects.iter().any(is_location) {
        check_syntax([crate::axes::Axis::A, crate::axes::Axis::C])?;
    }
    if !(args.noise_um.is_finite() && args.noise_um >= 0.0) {
        return Err(UsageError(format!("--noise-um must be ≥ 0, got {}", args.noise_um)).into());
    }
    args.probe.check()?;
    let data_on_stdout = super::common::stdout_output(&[
        ("-o -", crate::io::is_stdio(&args.output)),
        (
            "--dump-contexts -",
            super::common::is_stdout(args.dump_contexts.as_deref()),
        ),
    ])?;
    let given = Plan::read(&args.plan)?;
    let work = work_frame_of(args)?;
    let plan = match &work {
        Some(frame) => frame.plan_to_part(&given),
        None => given,
    };
    let part =
        super::diagnose::CutPart::new(&args.machine, &args.program, args.read.clone(), plan)?;
    super::common::CommandFiles::new()
        .input("the program", Some(&args.program))
        .input("the plan", Some(&args.plan))
        .input("the follow-up plan (--followup)", args.followup.as_deref())
        .machine(&part.machine)
        .model(&args.machine.model)
        .program_args(&args.read)
        .output("-o", Some(&args.output))
        .output("--dump-contexts", args.dump_contexts.as_deref())
        .check()?;
    let outputs = crate::io::OutputSet::begin();
    let rotary = part.machine.chain.rotary();
    let followup_plan = args
        .followup
        .as_ref()
        .map(|p| Followup::read_plan(p, rotary))
        .transpose()?;
    let effects = check_syntax(rotary)?;
    let contexts = part.contexts()?;
    if let Some(path) = &args.dump_contexts {
        crate::io::write_json_atomic(path, &contexts)?;
    }
    let options = SimulateOptions {
        noise_um: args.noise_um,
        seed: args.seed,
    };
    if let (Some(mut followup), Some(path)) = (followup_plan, &args.followup) {
        let probes = part.followup_probes(&contexts, &followup, &args.probe, path)?;
        // The machine's own tables are the truth, as for the measurement.
        let truth: Vec<f64> = probes
            .iter()
            .map(|p| contexts[p.of].predicted_um - p.context.predicted_um)
            .collect();
        let readings = simulate_followup(&contexts, &probes, &truth, &effects, &options)
            .context("simulating the follow-up")?;
        for (f, r) in followup.points.iter_mut().zip(&readings) {
            let (p, n) = (f.plan.point, f.plan.normal);
            f.measured = Some([0, 1, 2].map(|k| p[k] + r * n[k] / 1000.0));
        }
        followup.write(&args.output)?;
        outputs.commit()?;
        let warnings = part.warnings();
        super::common::print_warnings(&warnings);
        crate::cli::humanln!(
            data_on_stdout,
            "simulated {} with {}; noise {} µm, seed {}; readings {:.2} µm RMS -> {}{}",
            super::common::count(readings.len() as u64, "follow-up probe", "follow-up probes"),
            effects_text(&effects, rotary),
            args.noise_um,
            args.seed,
            crate::inspection::rms(&readings),
            crate::io::display_name(&args.output),
            super::common::result_note(&warnings)
        );
        return Ok(());
    }
    let measurement = simulate(&contexts, &part.truth_um()?, &effects, &options)
        .context("simulating the measurement")?;
    let measurement = match &work {
        // Written in the frame the plan came in.
        Some(frame) => frame.measurement_to_work(&measurement),
        None => measurement,
    };
    measurement.write(&args.output)?;
    outputs.commit()?;
    let cut = contexts.iter().filter(|c| c.cut).count();
    let deviations = measurement.deviations_um();
    let p = profile(&deviations);
    let warnings = part.warnings();
    super::common::print_warnings(&warnings);
    crate::cli::humanln!(
        data_on_stdout,
        "simulated {} ({cut} cut by the program) with {}; noise {} µm, seed {}{}",
        super::common::count(deviations.len() as u64, "point", "points"),
        effects_text(&effects, rotary),
        args.noise_um,
        args.seed,
        super::common::result_note(&warnings)
    );
    if cut < deviations.len() {
        crate::cli::humanln!(
            data_on_stdout,
            "{} of the plan not cut by the program: measured as the part's nominal surface moved by the error there",
            super::common::count((deviations.len() - cut) as u64, "point", "points")
        );
    }
    crate::cli::humanln!(
        data_on_stdout,
        "measured profile {:.2} µm (range {:.2} µm) -> {}",
        p.profile_um,
        p.range_um,
        crate::io::display_name(&args.output)
    );
    Ok(())
}

fn effects_text(effects: &[Effect], rotary: [crate::axes::Axis; 2]) -> String {
    if effects.is_empty() {
        "no unmodelled effect".to_string()
    } else {
        effects
            .iter()
            .map(|e| e.to_spec_for(rotary))
            .collect::<Vec<_>>()
            .join(" + ")
    }
}

/// The work frame of `--plan-frame work` (None for part coordinates).
fn work_frame_of(args: &Args) -> anyhow::Result<Option<crate::inspection::WorkFrame>> {
    super::plan_frame::work_frame_of_command(
        args.plan_frame,
        &args.machine,
        &args.read,
        &args.program,
        args.followup
            .is_some()
            .then_some("a follow-up plan is in part coordinates; simulate it separately"),
    )
}
