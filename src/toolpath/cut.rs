//! Which path point cut each plan point, and its context: the one place where a
//! program, a plan and the error model meet. `predict`, `simulate` and `diagnose`
//! all start here.
use super::context::PointContext;
use super::plan_match::{PlanMatch, PlanMatcher};
use super::program::{WalkSummary, walk_program};
use super::walk::WalkOptions;
use crate::gcode::{GcodeError, InterpretOptions, Program};
use crate::inspection::PlanPoint;
use crate::machine::tool_models::kinematics_with;
use crate::machine::{ErrorModel, LookupError};
use crate::vec3::dot;

/// Settings of the cut analysis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutOptions {
    pub interpret: InterpretOptions,
    pub walk: WalkOptions,
    /// Ball-end radius of the default tool (tool 0: the machine file's
    /// `[tool]`), mm; other tools bring their own.
    pub tool_radius: f64,
    /// A plan point whose contact point is farther than this from every path
    /// point is not cut (formats.md: 0.5 mm).
    pub max_distance_mm: f64,
}

#[derive(Debug, thiserror::Error)]
pub enum CutError {
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    #[error("plan point {id}: {source}")]
    Lookup { id: String, source: LookupError },
}

impl CutOptions {
    /// The usual settings for a machine: its rapid rate and ball radius, 0.5 mm
    /// sampling and matching distance (formats.md), the given start frame.
    pub fn for_machine(
        machine: &crate::machine::Machine,
        initial_frame: crate::gcode::Frame,
    ) -> Self {
        CutOptions {
            interpret: InterpretOptions {
                initial_frame,
                rapid_mm_per_min: machine.rapid_mm_per_min,
                ..InterpretOptions::default()
            },
            walk: WalkOptions {
                step_mm: 0.5,
                rapid_mm_per_min: machine.rapid_mm_per_min,
            },
            tool_radius: machine.tool.radius,
            max_distance_mm: 0.5,
        }
    }
}

/// Walk the program and match every plan point to the path point that cut it.
pub fn match_plan(
    program: Program,
    model: &ErrorModel,
    plan: &[PlanPoint],
    options: &CutOptions,
) -> Result<(Vec<Option<PlanMatch>>, WalkSummary), GcodeError> {
    let points: Vec<([f64; 3], [f64; 3])> = plan.iter().map(|p| (p.point, p.normal)).collect();
    let mut matcher = PlanMatcher::new(&points, options.tool_radius, options.max_distance_mm);
    let summary = walk_program(
        program,
        model.kinematics(),
        options.interpret,
        options.walk,
        |p| matcher.offer(p),
    )?;
    Ok((matcher.into_matches(), summary))
}

/// The context of every plan point (in plan order) from its match. Points that
/// were not cut get `cut: false` and zeros.
pub fn contexts(
    model: &ErrorModel,
    plan: &[PlanPoint],
    matches: &[Option<PlanMatch>],
) -> Result<Vec<PointContext>, CutError> {
    plan.iter()
        .zip(matches)
        .map(|(p, m)| {
            let Some(m) = m else {
                return Ok(not_cut(p));
            };
            let pp = &m.point;
            // The chain with the tool that cut the point.
            let kin = kinematics_with(model, &pp.tool);
            let errors = model
                .errors_at(&pp.joints)
                .map_err(|source| CutError::Lookup {
                    id: p.id.clone(),
                    source,
                })?;
            let e = kin.volumetric_error(&pp.joints, &errors).e_um;
            let axis_deviation_um = std::array::from_fn(|slot| {
                let mut only = crate::kinematics::ErrorValues::ZERO;
                only.component[slot] = errors.component[slot];
                dot(p.normal, kin.volumetric_error(&pp.joints, &only).e_um)
            });
            Ok(PointContext {
                id: p.id.clone(),
                point: p.point,
                normal: p.normal,
                cut: true,
                line: pp.line,
                block: pp.block,
                time_min: pp.time_min,
                joints: pp.joints,
                sigma: pp.sigma,
                speed_mm_s: pp.speed_mm_s,
                curvature_per_mm: pp.curvature_per_mm,
                principal_normal: pp.principal_normal,
                tool_axis: pp.axis,
                cut_length_m: pp.cut_length_m,
                predicted_um: dot(p.normal, e),
                squareness_jacobian: kin.squareness_jacobian(&pp.joints, &errors),
                location_jacobian: kin.location_jacobian(&pp.joints, &errors),
                axis_deviation_um,
            })
        })
        .collect()
}

/// Volumetric error (µm, part coordinates) at every matched point (`None`: not cut).
pub fn volumetric_errors(
    model: &ErrorModel,
    plan: &[PlanPoint],
    matches: &[Option<PlanMatch>],
) -> Result<Vec<Option<[f64; 3]>>, CutError> {
    plan.iter()
        .zip(matches)
        .map(|(p, m)| match m {
            None => Ok(None),
            Some(m) => model
                .errors_at(&m.point.joints)
                .map(|errors| {
                    let kin = kinematics_with(model, &m.point.tool);
                    Some(kin.volumetric_error(&m.point.joints, &errors).e_um)
                })
                .map_err(|source| CutError::Lookup {
                    id: p.id.clone(),
                    source,
                }),
        })
        .collect()
}

fn not_cut(p: &PlanPoint) -> PointContext {
    PointContext {
        id: p.id.clone(),
        point: p.point,
        normal: p.normal,
        cut: false,
        line: 0,
        block: 0,
        time_min: 0.0,
        joints: Default::default(),
        sigma: [0.0; 3],
        speed_mm_s: 0.0,
        curvature_per_mm: 0.0,
        principal_normal: [0.0; 3],
        tool_axis: [0.0, 0.0, 1.0],
        cut_length_m: 0.0,
        predicted_um: 0.0,
        squareness_jacobian: [[0.0; 3]; 3],
        location_jacobian: [[0.0; 3]; 8],
        axis_deviation_um: [0.0; 5],
    }
}
