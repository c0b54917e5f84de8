//! `--plan-frame`: plans and measurements in part coordinates (the contract)
//! or in the program's work coordinates (`work`: the work offset, G92 and
//! rotation the program cuts in applied), shared by predict, simulate and diagnose.
use super::common::ProgramArgs;
use crate::inspection::WorkFrame;
use crate::machine::Machine;
use std::path::Path;

/// The frame of a plan's or measurement's points.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum PlanFrame {
    /// Part coordinates: the rotary plate's frame (formats.md).
    #[default]
    Part,
    /// The program's work coordinates (program zero of the work offset it cuts in).
    Work,
}

/// [`work_frame`] for a command that loads `machine` itself later: the
/// machine file is read (no fit) for the program's run. `followup`: the
/// message refusing a follow-up file with `--plan-frame work`, when one is
/// given (follow-ups are in part coordinates).
pub fn work_frame_of_command(
    frame: PlanFrame,
    machine: &super::common::MachineArgs,
    read: &ProgramArgs,
    program: &Path,
    followup: Option<&str>,
) -> anyhow::Result<Option<WorkFrame>> {
    if frame == PlanFrame::Part {
        return Ok(None);
    }
    if let Some(message) = followup {
        return Err(
            super::UsageError(format!("--plan-frame work with --followup: {message}")).into(),
        );
    }
    let machine = Machine::load_with(
        &machine.machine_file,
        &crate::machine::LoadOptions {
            extrapolation: machine.model.extrapolate.into(),
        },
    )?;
    work_frame(frame, read, program, &machine)
}

/// The work frame of `program` in part coordinates, when `frame` is `work`:
/// the one origin its cutting moves use (several, none, or one with a rotary
/// offset is an error: never a guess).
pub fn work_frame(
    frame: PlanFrame,
    read: &ProgramArgs,
    program: &Path,
    machine: &Machine,
) -> anyhow::Result<Option<WorkFrame>> {
    if frame == PlanFrame::Part {
        return Ok(None);
    }
    if crate::io::is_stdio(program) {
        return Err(super::UsageError(
            "--plan-frame work reads the program twice (its work offset first): give it as a file, not `-`".into(),
        )
        .into());
    }
    let name = crate::io::display_name(program);
    let options = read.cut_options(machine).interpret;
    let origins = crate::toolpath::work_origin::cutting_origins(
        read.program(program, Some(machine))?,
        options,
    )
    .map_err(anyhow::Error::new)?;
    let cutting = match origins.as_slice() {
        [] => anyhow::bail!(
            "{name}: --plan-frame work: the program has no cutting move (G1, G2, G3), so no work offset to place the plan with"
        ),
        [one] => *one,
        many => {
            let list: Vec<String> = many
                .iter()
                .map(|c| {
                    format!(
                        "line {} (work origin {:.4},{:.4},{:.4}, G92 {:.4},{:.4},{:.4}, {} moves)",
                        c.first_line,
                        c.origin.work.x,
                        c.origin.work.y,
                        c.origin.work.z,
                        c.origin.g92.x,
                        c.origin.g92.y,
                        c.origin.g92.z,
                        c.moves
                    )
                })
                .collect();
            anyhow::bail!(
                "{name}: --plan-frame work is ambiguous: the program cuts in {} work frames: {}; give the plan in part coordinates",
                many.len(),
                list.join("; ")
            )
        }
    };
    let origin = cutting.origin;
    let shifted = [origin.work, origin.g92]
        .iter()
        .any(|o| o.x != 0.0 || o.y != 0.0 || o.z != 0.0)
        || origin.rotation_deg != 0.0;
    if let (true, Some(line)) = (shifted, cutting.first_tilted_line) {
        anyhow::bail!(
            "{name}: --plan-frame work: the program cuts in joint coordinates (no tool-tip control) with a rotary axis turned \
(first at line {line}, {} moves) under a work offset: the part it cuts is not the plan moved by the offset, so there is no one \
work frame to place the plan with; give the plan in part coordinates (a tool-tip-control program, G43.4, has one)",
            cutting.tilted_joint_moves
        );
    }
    let rotary = [
        crate::axes::Axis::A,
        crate::axes::Axis::B,
        crate::axes::Axis::C,
    ];
    if let Some(axis) = rotary
        .iter()
        .find(|a| origin.work.get(**a) != 0.0 || origin.g92.get(**a) != 0.0)
    {
        anyhow::bail!(
            "{name}: --plan-frame work: the program's work offset turns {} ({}°): a plan in that frame is not supported; give it in part coordinates",
            axis.letter(),
            origin.work.get(*axis) + origin.g92.get(*axis)
        );
    }
    // machine = Rz(θ)·(program + G92) + work; at A = C = 0 machine = part.
    let (s, c) = origin.rotation_deg.to_radians().sin_cos();
    let g = origin.g92;
    Ok(Some(WorkFrame {
        translation: [
            c * g.x - s * g.y + origin.work.x,
            s * g.x + c * g.y + origin.work.y,
            g.z + origin.work.z,
        ],
        rotation_deg: origin.rotation_deg,
    }))
}
