//! Running a prediction: program + error model (+ plan) → [`PredictReport`].
use super::{BlockError, PredictReport, PredictedPoint};
use crate::gcode::{Execution, GcodeError, Program};
use crate::inspection::{Plan, profile, rms};
use crate::machine::tool_models::kinematics_with;
use crate::machine::{ErrorModel, LookupError, ToolModels};
use crate::stamp::Stamp;
use crate::toolpath::cut::{CutError, CutOptions, match_errors, match_plan};
use crate::toolpath::joints_of;
use crate::vec3::dot;
use serde::{Serialize, Serializer};
use std::cell::{Cell, RefCell};
use std::collections::VecDeque;
use std::time::Instant;

/// Why a prediction failed.
#[derive(Debug, thiserror::Error)]
pub enum PredictError {
    /// The program could not be read.
    #[error(transparent)]
    Gcode(#[from] GcodeError),
    /// Cutting the plan failed (the program, or the model at a plan point's path point).
    #[error(transparent)]
    Cut(#[from] CutError),
    /// The error model cannot be evaluated at a block's joints (e.g. outside a table).
    #[error("{path}:{line}: {source}")]
    Lookup {
        /// The program.
        path: String,
        /// 1-based line of the block.
        line: usize,
        /// Why the lookup failed.
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
        let offset = m.map(|m| m.path_offset_um(p.point, n));
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
/// move; a canned cycle's block gives several rows with its line), collected.
/// [`PathErrors`] gives the same rows one at a time, holding none.
pub fn predict_path(
    program: Program,
    model: &ErrorModel,
    options: &CutOptions,
) -> Result<PredictReport, PredictError> {
    let mut errors = PathErrors::new(program, model, options);
    let mut blocks = Vec::new();
    while let Some(row) = errors.next_row() {
        blocks.push(row?);
    }
    let summary = errors.summary();
    Ok(PredictReport {
        max_error_um: summary.max_error_um,
        rms_error_um: summary.rms_error_um(),
        blocks,
        match_distance_mm: options.max_distance_mm,
        seconds: errors.seconds(),
        ..PredictReport::default()
    })
}

/// The volumetric error at the end of every move of a program, computed as
/// the program runs, one row at a time ([`PathErrors::next_row`]). Only the
/// running summary is kept, so memory does not grow with the program.
pub struct PathErrors<'m> {
    run: Execution,
    models: ToolModels<'m>,
    path: String,
    /// Rows of the current block not handed out yet (a canned cycle's moves).
    pending: VecDeque<BlockError>,
    summary: PathSummary,
    match_distance_mm: f64,
    started: Instant,
    /// An error was returned: no more rows.
    failed: bool,
    /// The direction of each axis with a reversal, as the program moves it.
    directions: crate::machine::DirectionTracker,
}

/// What the rows handed out so far add up to.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PathSummary {
    /// Number of rows handed out.
    pub rows: usize,
    /// Largest `|e|`, µm (0 without rows).
    pub max_error_um: f64,
    /// The line of the last row with the largest `|e|`.
    pub max_line: Option<usize>,
    sum_of_squares: f64,
}

impl PathSummary {
    /// RMS of `|e|` over the rows, µm (0 without rows).
    pub fn rms_error_um(&self) -> f64 {
        if self.rows == 0 {
            0.0
        } else {
            (self.sum_of_squares / self.rows as f64).sqrt()
        }
    }

    fn add(&mut self, row: &BlockError) {
        self.rows += 1;
        self.sum_of_squares += row.norm_um * row.norm_um;
        if self.max_line.is_none() || row.norm_um >= self.max_error_um {
            self.max_line = Some(row.line);
        }
        self.max_error_um = self.max_error_um.max(row.norm_um);
    }
}

impl<'m> PathErrors<'m> {
    /// The errors along `program` run with `options`, looked up in `model` (a copy per tool length).
    pub fn new(program: Program, model: &'m ErrorModel, options: &CutOptions) -> PathErrors<'m> {
        PathErrors {
            path: program.path().display().to_string(),
            run: program.run(options.interpret),
            models: crate::machine::ToolModels::new(model),
            pending: VecDeque::new(),
            summary: PathSummary::default(),
            match_distance_mm: options.max_distance_mm,
            started: Instant::now(),
            failed: false,
            directions: model.direction_tracker(),
        }
    }

    /// The next row, in program order; `None` at the end of the program or
    /// after an error.
    pub fn next_row(&mut self) -> Option<Result<BlockError, PredictError>> {
        loop {
            if let Some(row) = self.pending.pop_front() {
                self.summary.add(&row);
                return Some(Ok(row));
            }
            if self.failed {
                return None;
            }
            if let Err(e) = self.fill()? {
                self.failed = true;
                return Some(Err(e));
            }
        }
    }

    /// Run the program to its next executed block and compute its rows into
    /// `pending`; `None` at the end.
    fn fill(&mut self) -> Option<Result<(), PredictError>> {
        let (_, event, _) = match self.run.next()? {
            Ok(step) => step,
            Err(e) => return Some(Err(e.into())),
        };
        if event.skipped {
            return Some(Ok(()));
        }
        // Every move's end (a canned cycle's or a loop's moves each).
        let model = self.models.get_or_make(&event.tool);
        for m in event.motions() {
            let joints = joints_of(model.kinematics(), &m.end_pose());
            crate::toolpath::walk::advance_directions(
                &mut self.directions,
                model.kinematics(),
                m,
                0.0,
                1.0,
            );
            let v = match model.volumetric_error_toward(&joints, &self.directions.approach()) {
                Ok(v) => v,
                Err(source) => {
                    return Some(Err(PredictError::Lookup {
                        path: self.path.clone(),
                        line: event.line,
                        source,
                    }));
                }
            };
            self.pending.push_back(BlockError {
                line: event.line,
                tool: event.tool.number,
                e_um: v.e_um,
                norm_um: v.magnitude_um(),
                axis_urad: v.axis_urad,
            });
        }
        Some(Ok(()))
    }

    /// The rows handed out so far, summed up.
    pub fn summary(&self) -> PathSummary {
        self.summary
    }

    /// Seconds since the run started.
    pub fn seconds(&self) -> f64 {
        self.started.elapsed().as_secs_f64()
    }
}

/// The `predict --report` JSON without a plan, written while the program runs:
/// the same fields in the same order as [`PredictReport`] of [`predict_path`]
/// (serde's output for it, byte for byte but for `seconds`), each row of
/// `blocks` serialised as soon as it is computed. Serialising it runs the
/// program; a failure of the prediction ends the serialisation, and
/// [`PathReportStream::failure`] gives it.
pub struct PathReportStream<'m> {
    errors: RefCell<PathErrors<'m>>,
    failure: RefCell<Option<PredictError>>,
    compensated: bool,
    stamp: Option<Stamp>,
    seconds: Cell<f64>,
    /// The run's warnings, asked for once the rows are written (the last field).
    warnings: Option<&'m dyn Fn() -> Vec<crate::warnings::WarningGroup>>,
}

impl<'m> PathReportStream<'m> {
    /// `compensated` and `stamp` as in [`PredictReport`].
    pub fn new(errors: PathErrors<'m>, stamp: Option<Stamp>) -> PathReportStream<'m> {
        PathReportStream {
            errors: RefCell::new(errors),
            failure: RefCell::new(None),
            compensated: stamp.is_some(),
            stamp,
            seconds: Cell::new(0.0),
            warnings: None,
        }
    }

    /// The report's `warnings` field: `finish` gives them after the run.
    pub fn with_warnings(
        mut self,
        finish: &'m dyn Fn() -> Vec<crate::warnings::WarningGroup>,
    ) -> PathReportStream<'m> {
        self.warnings = Some(finish);
        self
    }

    /// Run the program without writing anything (the summary only).
    pub fn drain(&self) -> Result<(), PredictError> {
        let mut errors = self.errors.borrow_mut();
        while let Some(row) = errors.next_row() {
            row?;
        }
        self.seconds.set(errors.seconds());
        Ok(())
    }

    /// The prediction's error, when serialising stopped because of it.
    pub fn failure(&self) -> Option<PredictError> {
        self.failure.borrow_mut().take()
    }

    /// The rows written (or drained), summed up.
    pub fn summary(&self) -> PathSummary {
        self.errors.borrow().summary()
    }

    /// The report without its rows (for the summary and the HTML page), after
    /// the run.
    pub fn report(&self) -> PredictReport {
        let errors = self.errors.borrow();
        let summary = errors.summary();
        PredictReport {
            max_error_um: summary.max_error_um,
            rms_error_um: summary.rms_error_um(),
            match_distance_mm: errors.match_distance_mm,
            seconds: self.seconds.get(),
            compensated: self.compensated,
            stamp: self.stamp.clone(),
            ..PredictReport::default()
        }
    }

    /// The next row, or the failure kept for [`PathReportStream::failure`].
    fn next_row<E: serde::ser::Error>(&self) -> Result<Option<BlockError>, E> {
        match self.errors.borrow_mut().next_row() {
            None => Ok(None),
            Some(Ok(row)) => Ok(Some(row)),
            Some(Err(e)) => {
                let message = e.to_string();
                *self.failure.borrow_mut() = Some(e);
                Err(E::custom(message))
            }
        }
    }
}

impl Serialize for PathReportStream<'_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeStruct;
        // The first row decides whether there is a `blocks` field at all (it
        // is left out when empty, as PredictReport's).
        let first = self.next_row()?;
        let match_distance_mm = self.errors.borrow().match_distance_mm;
        let mut s = serializer.serialize_struct("PredictReport", 17)?;
        s.serialize_field("profile_um", &0.0)?;
        s.serialize_field("range_um", &0.0)?;
        s.serialize_field("points", &[] as &[super::PredictedPoint])?;
        s.serialize_field("points_total", &0usize)?;
        s.serialize_field("points_cut", &0usize)?;
        s.serialize_field("profile_with_path_um", &0.0)?;
        s.serialize_field("range_with_path_um", &0.0)?;
        s.serialize_field("max_path_offset_um", &0.0)?;
        s.serialize_field("match_distance_mm", &match_distance_mm)?;
        if let Some(first) = first {
            s.serialize_field(
                "blocks",
                &Rows {
                    first: RefCell::new(Some(first)),
                    stream: self,
                },
            )?;
        }
        let report = {
            self.seconds.set(self.errors.borrow().seconds());
            self.report()
        };
        s.serialize_field("max_error_um", &report.max_error_um)?;
        s.serialize_field("rms_error_um", &report.rms_error_um)?;
        s.serialize_field("seconds", &report.seconds)?;
        s.serialize_field("compensated", &report.compensated)?;
        if let Some(stamp) = &report.stamp {
            s.serialize_field("stamp", stamp)?;
        }
        let warnings = self.warnings.map(|finish| finish()).unwrap_or_default();
        s.serialize_field("warnings", &warnings)?;
        s.end()
    }
}

/// The `blocks` array of a [`PathReportStream`], pulled from the run.
struct Rows<'a, 'm> {
    first: RefCell<Option<BlockError>>,
    stream: &'a PathReportStream<'m>,
}

impl Serialize for Rows<'_, '_> {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        use serde::ser::SerializeSeq;
        let mut seq = serializer.serialize_seq(None)?;
        if let Some(first) = self.first.borrow_mut().take() {
            seq.serialize_element(&first)?;
        }
        while let Some(row) = self.stream.next_row()? {
            seq.serialize_element(&row)?;
        }
        seq.end()
    }
}
