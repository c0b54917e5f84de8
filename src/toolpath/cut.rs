//! Which path point cut each plan point, and its context: the one place where a
//! program, a plan and the error model meet. `predict`, `simulate` and `diagnose`
//! all start here.
use super::context::PointContext;
use super::plan_match::{PlanMatch, PlanMatcher};
use super::program::WalkSummary;
use super::walk::WalkOptions;
use crate::gcode::{GcodeError, InterpretOptions, Program};
use crate::inspection::PlanPoint;
use crate::machine::tool_models::kinematics_with;
use crate::machine::{ErrorModel, LookupError};
use crate::vec3::dot;

/// Settings of the cut analysis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutOptions {
    /// How the program is interpreted.
    pub interpret: InterpretOptions,
    /// How the path is sampled.
    pub walk: WalkOptions,
    /// Ball-end radius of the default tool (tool 0: the machine file's
    /// `[tool]`), mm; other tools bring their own.
    pub tool_radius: f64,
    /// The default tool's cutting shape, when the machine file names one
    /// (`contact`): deviations are then taken at the contact point.
    pub tool_shape: Option<crate::gcode::CutterShape>,
    /// A plan point whose contact point is farther than this from every path
    /// point is not cut (formats.md: 0.5 mm).
    pub max_distance_mm: f64,
}

/// Why cutting a plan failed.
#[derive(Debug, thiserror::Error)]
pub enum CutError {
    /// The program could not be read.
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    /// The error model cannot be evaluated at a plan point's path point.
    #[error("plan point {id}: {source}")]
    Lookup {
        /// The plan point's id.
        id: String,
        /// Why the lookup failed.
        source: LookupError,
    },
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
                axes: machine.letters(),
                ..InterpretOptions::default()
            },
            walk: WalkOptions {
                step_mm: 0.5,
                rapid_mm_per_min: machine.rapid_mm_per_min,
            },
            tool_radius: machine.tool.radius,
            tool_shape: machine.tool.shape,
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
    let mut matcher = PlanMatcher::new(&points, options.tool_radius, options.max_distance_mm)
        .with_default_shape(options.tool_shape);
    // The direction of each axis with a reversal, as the program moves it.
    let summary = super::program::walk_program_tracking(
        program,
        model.kinematics(),
        options.interpret,
        options.walk,
        Some(model.direction_tracker()),
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
    let uncertain = model.has_uncertainty();
    plan.iter()
        .zip(matches)
        .map(|(p, m)| {
            let Some(m) = m else {
                return Ok(not_cut(p, model.kinematics().rotary()));
            };
            let pp = &m.point;
            // The chain with the tool that cut the point.
            let kin = kinematics_with(model, &pp.tool);
            let errors = model
                .errors_toward(&pp.joints, &pp.approach)
                .map_err(|source| CutError::Lookup {
                    id: p.id.clone(),
                    source,
                })?;
            let e = errors_at_match(model, m, p.normal, &errors).deviation;
            let axis_deviation_um = std::array::from_fn(|slot| {
                let mut only = crate::kinematics::ErrorValues::ZERO;
                only.component[slot] = errors.component[slot];
                dot(p.normal, kin.volumetric_error(&pp.joints, &only).e_um)
            });
            // The model's own standard uncertainty along n (0 without one).
            let model_u_um = if uncertain {
                model
                    .uncertainty_with(&kin, &pp.joints)
                    .map_err(|source| CutError::Lookup {
                        id: p.id.clone(),
                        source,
                    })?
                    .along_um(p.normal)
            } else {
                0.0
            };
            Ok(PointContext {
                id: p.id.clone(),
                point: p.point,
                normal: p.normal,
                cut: true,
                line: pp.line,
                block: pp.block,
                time_min: pp.time_min,
                joints: pp.joints.axes(),
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
                model_u_um,
                rotary: kin.rotary(),
                machine_to_part_rotation: Some(kin.machine_to_part_rotation(&pp.joints)),
            })
        })
        .collect()
}

/// The volumetric error (µm, part coordinates) of a matched plan point, taken
/// two ways from one lookup.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MatchErrors {
    /// As the predicted deviation takes it: at the tip (formats.md), or at the
    /// contact point of a tool whose shape is named.
    pub deviation: [f64; 3],
    /// At the contact point for every tool: a tool without a named shape is
    /// formats.md's ball, whose error there is its centre's, the tip's plus
    /// `R·δu`. This is what the part measures (`deviation_with_path_um`): after
    /// a compensation that corrects the tool axis, the tip rule alone would
    /// miss the axis correction's effect on the ball.
    pub contact: [f64; 3],
}

/// [`MatchErrors`] of every matched point (`None`: not cut).
pub fn match_errors(
    model: &ErrorModel,
    plan: &[PlanPoint],
    matches: &[Option<PlanMatch>],
) -> Result<Vec<Option<MatchErrors>>, CutError> {
    plan.iter()
        .zip(matches)
        .map(|(p, m)| match m {
            None => Ok(None),
            Some(m) => model
                .errors_toward(&m.point.joints, &m.point.approach)
                .map(|errors| Some(errors_at_match(model, m, p.normal, &errors)))
                .map_err(|source| CutError::Lookup {
                    id: p.id.clone(),
                    source,
                }),
        })
        .collect()
}

/// The volumetric error where the matched path point's tool touched
/// ([`MatchErrors`]; `contact::error_at_contact`).
fn errors_at_match(
    model: &ErrorModel,
    m: &PlanMatch,
    normal: [f64; 3],
    errors: &crate::kinematics::ErrorValues,
) -> MatchErrors {
    let kin = kinematics_with(model, &m.point.tool);
    let v = kin.volumetric_error(&m.point.joints, errors);
    // The end (not the side) of a named flat or bull-nose tool cuts: its rim
    // radius, for the lowest point (a ball has none).
    let end_cuts = dot(normal, m.point.axis) > super::contact::FLANK_COS;
    let rim = match m.tool.shape {
        Some(shape) if end_cuts => (m.tool.radius_mm - shape.corner_radius_mm).max(0.0),
        _ => 0.0,
    };
    let contact = super::contact::error_at_contact(
        v.e_um,
        m.point.axis,
        v.axis_urad,
        m.contact_offset,
        normal,
        rim,
    );
    MatchErrors {
        deviation: if m.tool.shape.is_some() {
            contact
        } else {
            v.e_um
        },
        contact,
    }
}

fn not_cut(p: &PlanPoint, rotary: [crate::axes::Axis; 2]) -> PointContext {
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
        model_u_um: 0.0,
        rotary,
        machine_to_part_rotation: None,
    }
}

/// Stylus and timing of a follow-up probe on the machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeTool {
    /// Gauge line to the stylus tip, mm.
    pub length_mm: f64,
    /// Stylus ball radius, mm.
    pub radius_mm: f64,
}

/// The context of probing the cut point `cut` again on the machine (a
/// follow-up probe, docs/diagnose.md "Follow-up"): the stylus ball touches the
/// plan point at the rotary joints `rotary` (degrees, the machine's two rotary
/// axes in letter order: A and C on an A/C table), approaching along −n, at
/// `time_min`. Its joints put the stylus tip at `p + R·(n − u)` (the ball's
/// centre at `p + R·n`); `sigma` is the sign of each linear axis's approach
/// (0 for an axis that does not move in it); speed, curvature and cut length
/// are 0; `predicted_um`, the Jacobians and `axis_deviation_um` are the
/// model's at the probe pose. `None` when the pose is outside `limits`.
pub fn probe_context(
    model: &ErrorModel,
    probe: &ProbeTool,
    limits: Option<&crate::machine::Limits>,
    cut: &PointContext,
    rotary: [f64; 2],
    time_min: f64,
) -> Result<Option<PointContext>, CutError> {
    use crate::axes::Axes;
    let kin = model.kinematics().with_tool_length(probe.length_mm);
    let (n, p) = (cut.normal, cut.point);
    let [r1, r2] = kin.rotary();
    let at = Axes::xyz_rotary([0.0; 3], [(r1, rotary[0]), (r2, rotary[1])]);
    let u = kin.nominal_tool_axis(&at);
    let tip = [0, 1, 2].map(|k| p[k] + probe.radius_mm * (n[k] - u[k]));
    let joints = super::pose::joints_of(
        &kin,
        &crate::gcode::Pose::Part(Axes {
            x: tip[0],
            y: tip[1],
            z: tip[2],
            ..at
        }),
    );
    if limits.is_some_and(|l| l.violated(&joints).is_some()) {
        return Ok(None);
    }
    let errors = model
        .errors_at(&joints)
        .map_err(|source| CutError::Lookup {
            id: cut.id.clone(),
            source,
        })?;
    let e = kin.volumetric_error(&joints, &errors).e_um;
    let axis_deviation_um = std::array::from_fn(|slot| {
        let mut only = crate::kinematics::ErrorValues::ZERO;
        only.component[slot] = errors.component[slot];
        dot(n, kin.volumetric_error(&joints, &only).e_um)
    });
    // Approach along −n, turned into the machine frame (the transpose of the
    // machine → part rotation; Rx(a)·Rz(c)·(−n) on an A/C table).
    let to_part = kin.machine_to_part_rotation(&joints);
    let approach = std::array::from_fn(|i| -(0..3).map(|k| to_part[k][i] * n[k]).sum::<f64>());
    let sigma = approach_signs(approach);
    Ok(Some(PointContext {
        joints: joints.axes(),
        sigma,
        tool_axis: u,
        predicted_um: dot(n, e),
        squareness_jacobian: kin.squareness_jacobian(&joints, &errors),
        location_jacobian: kin.location_jacobian(&joints, &errors),
        axis_deviation_um,
        rotary: kin.rotary(),
        machine_to_part_rotation: Some(to_part),
        ..cut.probe_of(time_min)
    }))
}

/// The direction each machine axis moves in along a probe's approach (one
/// per axis: +1, −1, or 0 for an axis the approach leaves still): the
/// reversal state `σ` of a probe's context.
pub(crate) fn approach_signs(approach: [f64; 3]) -> [f64; 3] {
    approach.map(|v| if v.abs() < 1e-6 { 0.0 } else { v.signum() })
}
