//! Running a prediction: program + error model (+ plan) → [`PredictReport`].
use super::{BlockError, PredictReport, PredictedPoint};
use crate::gcode::{GcodeError, Program};
use crate::inspection::{Plan, profile, rms};
use crate::machine::tool_models::kinematics_with;
use crate::machine::{ErrorModel, LookupError};
use crate::toolpath::cut::{CutError, CutOptions, match_errors, match_plan};
use crate::toolpath::{effective_frame, joints_of};
use crate::vec3::dot;
use std::time::Instant;

#[derive(Debug, thiserror::Error)]
pub enum PredictError {
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    #[error(transparent)]
    Cut(#[from] CutError),
    #[error("{path}:{line}: {source}")]
    Lookup {
        path: String,
        line: usize,
        source: LookupError,
    },
}

/// Predicted deviation of every plan point and the profile error of the part.
pub fn predict_plan(
    program: Program,
    model: &ErrorModel,
    plan: &Plan,
    options: &CutOptions,
) -> Result<PredictReport, PredictError> {
    let started = Instant::now();
    let (matches, _) = match_plan(program, model, &plan.points, options)?;
    let errors = match_errors(model, &plan.points, &matches)?;
    let uncertain = model.has_uncertainty();
    let mut points = Vec::with_capacity(plan.points.len());
    let mut deviations = Vec::new();
    let mut with_path = Vec::new();
    let mut max_offset = 0.0f64;
    for ((p, m), e) in plan.points.iter().zip(&matches).zip(&errors) {
        let n = p.normal;
        let deviation = e.map(|e| dot(n, e.deviation));
        // What the part measures: the error where the tool touches.
        let at_contact = e.map(|e| dot(n, e.contact));
        // Nominal contact point of the cutting path point, relative to the plan point.
        let offset = m.map(|m| {
            let t = m.point.tip;
            let c = m.contact_offset;
            (0..3)
                .map(|k| (t[k] + c[k] - p.point[k]) * n[k])
                .sum::<f64>()
                * 1e3
        });
        let deviation_with_path = match (at_contact, offset) {
            (Some(d), Some(o)) => {
                max_offset = max_offset.max(o.abs());
                with_path.push(d + o);
                Some(d + o)
            }
            _ => None,
        };
        if let Some(d) = deviation {
            deviations.push(d);
        }
        let deviation_u = match m {
            Some(m) if uncertain => Some(
                model
                    .uncertainty_with(&kinematics_with(model, &m.point.tool), &m.point.joints)
                    .map_err(|source| CutError::Lookup {
                        id: p.id.clone(),
                        source,
                    })?
                    .along_um(n),
            ),
            _ => None,
        };
        points.push(PredictedPoint {
            id: p.id.clone(),
            deviation_um: deviation,
            cut: m.is_some(),
            line: m.map(|m| m.point.line),
            tool: m.map(|m| m.point.tool.number),
            point: p.point,
            normal: p.normal,
            e_um: e.map(|e| e.deviation),
            distance_mm: m.map(|m| m.distance_mm),
            deviation_with_path_um: deviation_with_path,
            deviation_u_um: deviation_u,
        });
    }
    let prof = profile(&deviations);
    // The profile is set by the largest |deviation|: its uncertainty, doubled.
    let profile_u = points
        .iter()
        .filter_map(|p| Some((p.deviation_um?.abs(), p.deviation_u_um?)))
        .max_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, u)| 2.0 * u);
    let us: Vec<f64> = points.iter().filter_map(|p| p.deviation_u_um).collect();
    let rms_u = (!us.is_empty()).then(|| rms(&us));
    let prof_path = profile(&with_path);
    let magnitudes: Vec<f64> = errors
        .iter()
        .flatten()
        .map(|e| crate::vec3::norm(e.deviation))
        .collect();
    Ok(PredictReport {
        profile_um: prof.profile_um,
        range_um: prof.range_um,
        profile_u_um: profile_u,
        rms_deviation_u_um: rms_u,
        points_total: points.len(),
        points_cut: deviations.len(),
        profile_with_path_um: prof_path.profile_um,
        range_with_path_um: prof_path.range_um,
        max_path_offset_um: max_offset,
        points,
        match_distance_mm: options.max_distance_mm,
        blocks: Vec::new(),
        max_error_um: magnitudes.iter().copied().fold(0.0, f64::max),
        rms_error_um: rms(&magnitudes),
        seconds: started.elapsed().as_secs_f64(),
        compensated: false,
        stamp: None,
        warnings: Vec::new(),
    })
}

/// Without a plan: the volumetric error at the end of every move (one row per
/// move; a canned cycle's block gives several rows with its line).
pub fn predict_path(
    program: Program,
    model: &ErrorModel,
    options: &CutOptions,
) -> Result<PredictReport, PredictError> {
    let started = Instant::now();
    let path = program.path().display().to_string();
    let mut run = program.run(options.interpret);
    let mut models = crate::machine::ToolModels::new(model);
    let mut blocks = Vec::new();
    while let Some(step) = run.next() {
        let (_, event, _) = step?;
        if event.skipped {
            continue;
        }
        // Every move's end (a canned cycle's or a loop's moves each).
        let model = models.get_or_make(&event.tool);
        for m in event.motions() {
            let joints = joints_of(model.kinematics(), effective_frame(m), &m.end);
            let v = model
                .volumetric_error(&joints)
                .map_err(|source| PredictError::Lookup {
                    path: path.clone(),
                    line: event.line,
                    source,
                })?;
            blocks.push(BlockError {
                line: event.line,
                tool: event.tool.number,
                e_um: v.e_um,
                norm_um: v.magnitude_um(),
                axis_urad: v.axis_urad,
            });
        }
    }
    let norms: Vec<f64> = blocks.iter().map(|b| b.norm_um).collect();
    Ok(PredictReport {
        max_error_um: norms.iter().copied().fold(0.0, f64::max),
        rms_error_um: rms(&norms),
        blocks,
        match_distance_mm: options.max_distance_mm,
        seconds: started.elapsed().as_secs_f64(),
        ..PredictReport::default()
    })
}
