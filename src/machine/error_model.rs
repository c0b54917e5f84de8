//! The machine's error model: a fitted SMEM curve (cubic NURBS, `crate::nurbs`) for
//! every measured table column, plus the position-independent scalars, and the
//! lookup `joints → ErrorValues → VolumetricError`.
//!
//! Lookup policy (formats.md): linear axes are looked up by position (mm), rotary
//! axes by angle (degrees); a rotary table over one revolution wraps (the angle
//! reduced modulo 360 into the table's range, for any number of turns); outside a table's range a lookup is
//! [`LookupError::OutOfRange`] unless the policy is [`ExtrapolationPolicy::Hold`],
//! which holds the end value and counts it ([`ErrorModel::held_lookups`]).
//! Unmeasured axes and columns contribute zero.
//!
//! Invariants: built once, then read-only and `Sync` (the hold counter is atomic):
//! compensate and predict call [`ErrorModel::volumetric_error`] from many threads;
//! the lookup allocates nothing; every returned value is finite (inputs are checked).
use super::definition::{ExtrapolationPolicy, Machine};
use super::resampled::ResampledAxis;
use super::reversal::{Approach, AxisPlay, DirectionTracker};
use super::table::ErrorTable;
use crate::axes::{Axes, Axis};
use crate::kinematics::error_values::PARAMETER_COUNT;
use crate::kinematics::{ChainConstants, ErrorValues, Kinematics, TipAndAxis, VolumetricError};
use crate::nurbs::{
    FitError, FitOptions, ParameterFit, ParameterKind, SmemCurve, SmemModelFile, fnv1a64,
};
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

/// How the model is built.
#[derive(Clone, Debug, Default)]
pub struct ModelOptions {
    /// How each table column is fitted.
    pub fit: FitOptions,
    /// What a lookup outside a table's range does.
    pub extrapolation: ExtrapolationPolicy,
    /// Look every value up on the NURBS itself (Newton inversion per call) instead of
    /// the verified resampling of `machine::resampled` (within 1e-6 µm/µrad of it,
    /// several times faster).
    pub exact_lookups: bool,
    /// Counts a step per fitted column (the fit's progress), if given.
    pub progress: Option<Arc<crate::progress::WorkCounter>>,
}

/// Why an error model could not be built or read.
#[derive(Debug, thiserror::Error)]
pub enum ModelError {
    /// Fitting a table column failed.
    #[error("{}: cannot fit {parameter}: {source}", table.display())]
    Fit {
        /// The error table file.
        table: PathBuf,
        /// The parameter (column), e.g. `EXX`.
        parameter: String,
        /// Why the fit failed.
        source: FitError,
    },
    /// A file could not be read.
    #[error(transparent)]
    Read(#[from] crate::io::InputError),
    /// A fitted-model file is not valid JSON of the `volcomp fit --report` format.
    #[error("{}:{line}:{column}: not a fitted-model file (volcomp fit --report): {message}", path.display())]
    Parse {
        /// The fitted-model file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What the JSON reader reports.
        message: String,
    },
    /// A fitted-model file does not match the machine: a measured parameter is
    /// missing, was fitted to other table data, its curve was changed after the
    /// fit or does not reproduce its recorded fit, or the curve is invalid.
    #[error("{}: {parameter}: {message}", path.display())]
    Model {
        /// The fitted-model file.
        path: PathBuf,
        /// The parameter of the entry.
        parameter: String,
        /// What is wrong.
        message: String,
    },
}

/// Why the model could not be evaluated at a pose.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LookupError {
    /// A joint position is NaN or infinite.
    #[error("joint position is not finite: {0:?}")]
    NotFinite(Axes),
    /// A joint position lies outside its axis's error table (with the `Error` extrapolation policy).
    #[error(
        "{axis:?} = {position} is outside the {axis:?} error table ({} to {}); \
the model is not defined there (use --extrapolate hold to hold the end values)",
        range[0], range[1]
    )]
    OutOfRange {
        /// The axis.
        axis: Axis,
        /// Its position, mm or degrees.
        position: f64,
        /// The table's first and last positions.
        range: [f64; 2],
    },
}

/// FNV-1a 64 of a table file's bytes as they were read (what fitted-model
/// files record).
fn table_hash(table: &ErrorTable) -> Result<u64, ModelError> {
    Ok(fnv1a64(table.text.as_bytes()))
}

/// Curves of one measured axis.
#[derive(Clone, Debug)]
struct AxisCurves {
    axis: Axis,
    /// First and last table position.
    range: [f64; 2],
    /// C over one revolution: positions wrap modulo 360 into `range`.
    wrap: bool,
    /// One curve per component (δx δy δz εx εy εz), `None` = not measured.
    curves: [Option<SmemCurve>; 6],
    /// The fast stand-in for `curves` (`None`: exact lookups).
    resampled: Option<ResampledAxis>,
}

/// The reversal of one joint slot: its axis, the component it adds to (the
/// axis's positioning parameter: δx of X, εz of C, …) and its values.
#[derive(Clone, Debug)]
struct SlotReversal {
    component: usize,
    play: AxisPlay,
}

/// The effect of one parameter alone at a pose (first order).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Contribution {
    /// kinematics.md name (`EXX`, `s_xy`, `EY0A`, ...).
    pub parameter: &'static str,
    /// The parameter's value at the pose, µm or µrad.
    pub value: f64,
    /// e with only this parameter non-zero, µm.
    pub e_um: [f64; 3],
    /// Tool-axis error with only this parameter non-zero, µrad.
    pub axis_urad: [f64; 3],
}

impl Contribution {
    /// Length of `e_um`, µm.
    pub fn magnitude_um(&self) -> f64 {
        crate::kinematics::transform::norm(self.e_um)
    }
}

/// How sure the fitted model is of its own e at a pose: each measured
/// parameter's standard uncertainty (its curve's, from the table noise and the
/// fit) propagated to first order, parameters independent. Unmodelled effects
/// are not in it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelUncertainty {
    /// e of each of the 30 component parameters at one standard uncertainty
    /// (zero where unmeasured or carrying no uncertainty), µm.
    pub by_parameter: [[f64; 3]; 30],
}

impl ModelUncertainty {
    /// Standard uncertainty of e along X, Y and Z, µm.
    pub fn per_axis_um(&self) -> [f64; 3] {
        let mut s = [0.0; 3];
        for v in &self.by_parameter {
            for k in 0..3 {
                s[k] += v[k] * v[k];
            }
        }
        s.map(f64::sqrt)
    }

    /// `√(u_x² + u_y² + u_z²)`: the RMS length of e's error, µm.
    pub fn magnitude_um(&self) -> f64 {
        let [x, y, z] = self.per_axis_um();
        (x * x + y * y + z * z).sqrt()
    }

    /// Standard uncertainty of e's component along the unit vector `n`, µm.
    pub fn along_um(&self, n: [f64; 3]) -> f64 {
        self.by_parameter
            .iter()
            .map(|v| (v[0] * n[0] + v[1] * n[1] + v[2] * n[2]).powi(2))
            .sum::<f64>()
            .sqrt()
    }
}

/// See the module documentation.
#[derive(Debug)]
pub struct ErrorModel {
    kinematics: Kinematics,
    axes: [Option<AxisCurves>; 5],
    scalars: ErrorValues,
    /// What the chain computes from the scalars alone, once
    /// ([`ErrorModel::actual_tip_and_axis`]).
    constants: ChainConstants,
    /// Per joint slot, its reversal ([`super::reversal`]); all `None` on a
    /// machine without one, whose lookups are then exactly the direction-free ones.
    reversal: [Option<SlotReversal>; 5],
    policy: ExtrapolationPolicy,
    /// Lookups that held an end value; shared with the models of other tool
    /// lengths made from this one ([`ErrorModel::with_tool_length`]).
    held: Arc<AtomicU64>,
    /// [`ErrorModel::holding_ends`], made on first use.
    holding: OnceLock<Box<ErrorModel>>,
}

impl Clone for ErrorModel {
    /// An independent copy (its own count of held lookups, from the current one).
    fn clone(&self) -> Self {
        ErrorModel {
            kinematics: self.kinematics,
            axes: self.axes.clone(),
            scalars: self.scalars,
            constants: self.constants,
            reversal: self.reversal.clone(),
            policy: self.policy,
            held: Arc::new(AtomicU64::new(self.held.load(Ordering::Relaxed))),
            holding: OnceLock::new(),
        }
    }
}

impl ErrorModel {
    /// Fit every measured column of `machine`'s tables (in parallel) and collect its
    /// scalars. A column with fewer rows than the fit needs is an error naming it.
    pub fn from_machine(
        machine: &Machine,
        options: &ModelOptions,
    ) -> Result<ErrorModel, ModelError> {
        let mut jobs = Vec::new();
        let layout = machine.layout();
        for (slot, axis) in layout.slot_axes().into_iter().enumerate() {
            let Some(table) = machine.table(axis) else {
                continue;
            };
            for (k, name) in layout.component_names(slot).iter().enumerate() {
                if let Some(column) = table.columns.iter().find(|c| c.name == *name) {
                    jobs.push((slot, k, *name, table, column));
                }
            }
        }
        if let Some(c) = &options.progress {
            c.add_total(jobs.len() as u64);
        }
        let fitted: Vec<(usize, usize, SmemCurve)> = jobs
            .par_iter()
            .map(|(slot, k, name, table, column)| {
                let kind = if *k < 3 {
                    ParameterKind::Length
                } else {
                    ParameterKind::Angle
                };
                let fit = crate::nurbs::FitOptions {
                    periodic: table.one_revolution,
                    ..options.fit.clone()
                };
                crate::nurbs::fit_parameter_with_uncertainty(
                    &table.positions,
                    &column.values,
                    column.uncertainty.as_deref(),
                    kind,
                    &fit,
                )
                .inspect(|_| crate::progress::step(options.progress.as_ref()))
                .map(|curve| (*slot, *k, curve))
                .map_err(|source| ModelError::Fit {
                    table: table.path.clone(),
                    parameter: name.to_string(),
                    source,
                })
            })
            .collect::<Result<_, _>>()?;
        let mut axes = Self::empty_axes(machine);
        for (slot, k, curve) in fitted {
            if let Some(ac) = axes[slot].as_mut() {
                ac.curves[k] = Some(curve);
            }
        }
        Ok(Self::assemble(machine, axes, options))
    }

    /// Use the curves of a fitted-model file (`volcomp fit --report FILE`) instead of
    /// fitting: every measured column of `machine` must be in the file, fitted to the
    /// same table bytes (FNV-1a hash), else an error naming the parameter.
    pub fn from_model_file(
        machine: &Machine,
        path: &std::path::Path,
        options: &ModelOptions,
    ) -> Result<ErrorModel, ModelError> {
        let text = crate::io::read_to_string(path)?;
        let file: SmemModelFile = serde_json::from_str(&text).map_err(|e| ModelError::Parse {
            path: path.to_path_buf(),
            line: e.line(),
            column: e.column(),
            message: e.to_string(),
        })?;
        Self::from_fitted(machine, &file, path, true, options)
    }

    /// The model of `machine` from fitted curves already read (`path` names
    /// their source in errors). With `check_hashes`, each curve must have been
    /// fitted to its table's current bytes (see [`ErrorModel::from_model_file`]);
    /// without, the caller has checked that the curves belong to these tables.
    pub fn from_fitted(
        machine: &Machine,
        file: &SmemModelFile,
        path: &std::path::Path,
        check_hashes: bool,
        options: &ModelOptions,
    ) -> Result<ErrorModel, ModelError> {
        let model_error = |parameter: &str, message: String| ModelError::Model {
            path: path.to_path_buf(),
            parameter: parameter.to_string(),
            message,
        };
        let mut axes = Self::empty_axes(machine);
        let layout = machine.layout();
        for (slot, axis) in layout.slot_axes().into_iter().enumerate() {
            let Some(table) = machine.table(axis) else {
                continue;
            };
            let hash = if check_hashes {
                format!("{:016x}", table_hash(table)?)
            } else {
                String::new()
            };
            for (k, name) in layout.component_names(slot).iter().enumerate() {
                if table.column(name).is_none() {
                    continue;
                }
                let entry = file
                    .parameters
                    .iter()
                    .find(|p| p.parameter == *name)
                    .ok_or_else(|| {
                        model_error(
                            name,
                            format!(
                                "not in the file (the machine's {} table measures it)",
                                axis.letter()
                            ),
                        )
                    })?;
                if check_hashes && entry.table_hash != hash {
                    return Err(model_error(
                        name,
                        format!(
                            "was fitted to different data ({} with hash {}) than {} (hash {hash}); refit with volcomp fit",
                            entry.table,
                            entry.table_hash,
                            table.path.display()
                        ),
                    ));
                }
                if !entry.curve_hash.is_empty()
                    && entry.curve_hash != format!("{:016x}", entry.computed_curve_hash())
                {
                    return Err(model_error(
                        name,
                        format!(
                            "its curve was changed after the fit (its numbers no longer match the recorded hash {}); refit with volcomp fit",
                            entry.curve_hash
                        ),
                    ));
                }
                let curve = entry.to_curve().map_err(|m| model_error(name, m))?;
                // The curve must reproduce its recorded fit at the table's
                // points (files written before `curve_hash` are checked so too).
                if let Some(column) = table.column(name) {
                    let recomputed = table
                        .positions
                        .iter()
                        .zip(&column.values)
                        .fold(0.0f64, |m, (x, y)| m.max((curve.value_at(*x) - y).abs()));
                    let recorded = entry.stats.emax;
                    if !(recomputed.is_finite()
                        && (recomputed - recorded).abs() <= 1e-6 * (1.0 + recorded.abs()))
                    {
                        return Err(model_error(
                            name,
                            format!(
                                "its curve departs from the table by up to {recomputed:.6} {unit} at the table's points, but the file records {recorded:.6} {unit} for its fit: the file was edited; refit with volcomp fit",
                                unit = if entry.unit == "urad" { "µrad" } else { "µm" }
                            ),
                        ));
                    }
                }
                if let Some(ac) = axes[slot].as_mut() {
                    ac.curves[k] = Some(curve);
                }
            }
        }
        Ok(Self::assemble(machine, axes, options))
    }

    /// The fitted curves as a fitted-model file (the `volcomp fit --report` format),
    /// tied to `machine`'s table bytes; [`ErrorModel::from_model_file`] reads it back.
    pub fn to_model_file(&self, machine: &Machine) -> Result<SmemModelFile, ModelError> {
        let mut file = SmemModelFile {
            parameters: Vec::new(),
            not_measured: Vec::new(),
        };
        let layout = machine.layout();
        for (slot, axis) in layout.slot_axes().into_iter().enumerate() {
            let Some(table) = machine.table(axis) else {
                continue;
            };
            let hash = table_hash(table)?;
            for (k, name) in layout.component_names(slot).iter().enumerate() {
                let curve = self.axes[slot]
                    .as_ref()
                    .and_then(|ac| ac.curves[k].as_ref());
                match curve {
                    Some(curve) => {
                        let kind = if k < 3 {
                            ParameterKind::Length
                        } else {
                            ParameterKind::Angle
                        };
                        file.parameters.push(ParameterFit::new(
                            axis.letter(),
                            name,
                            kind.unit(),
                            curve,
                            &table.path.display().to_string(),
                            hash,
                        ));
                    }
                    None => file.not_measured.push(name.to_string()),
                }
            }
        }
        Ok(file)
    }

    /// The model of `machine` with the fitted `axes`: resampled (in parallel) unless
    /// exact lookups are asked for, plus the machine's scalars.
    fn assemble(
        machine: &Machine,
        mut axes: [Option<AxisCurves>; 5],
        options: &ModelOptions,
    ) -> ErrorModel {
        if !options.exact_lookups {
            axes.par_iter_mut().flatten().for_each(|ac| {
                ac.resampled = ResampledAxis::build(&ac.curves, ac.range[0], ac.range[1]);
            });
        }
        let reversal = Self::reversals(machine);
        let kinematics = machine.kinematics_model();
        let scalars = machine.scalar_errors();
        ErrorModel {
            constants: ChainConstants::new(&kinematics.chain, &scalars),
            kinematics,
            axes,
            scalars,
            reversal,
            policy: options.extrapolation,
            held: Arc::new(AtomicU64::new(0)),
            holding: OnceLock::new(),
        }
    }

    /// The reversal of every slot of `machine` that has one.
    fn reversals(machine: &Machine) -> [Option<SlotReversal>; 5] {
        let layout = machine.layout();
        let mut out: [Option<SlotReversal>; 5] = Default::default();
        for (slot, axis) in layout.slot_axes().into_iter().enumerate() {
            let Some(reversal) = machine.reversal(axis) else {
                continue;
            };
            let parameter = crate::laser::positioning_parameter(axis);
            let Some(component) = layout
                .component_names(slot)
                .iter()
                .position(|n| *n == parameter)
            else {
                continue;
            };
            let (range, wrap) = match machine.table(axis) {
                Some(t) => (
                    [
                        t.positions.first().copied().unwrap_or(0.0),
                        t.positions.last().copied().unwrap_or(0.0),
                    ],
                    t.one_revolution,
                ),
                None => ([f64::NEG_INFINITY, f64::INFINITY], false),
            };
            out[slot] = Some(SlotReversal {
                component,
                play: AxisPlay {
                    axis,
                    reversal,
                    range,
                    wrap,
                },
            });
        }
        out
    }

    /// Whether any axis has a reversal (a table's `REVERSAL` or `[reversal]`).
    pub fn has_reversal(&self) -> bool {
        self.reversal.iter().any(Option::is_some)
    }

    /// The axes with a reversal, in slot order, with where each comes from.
    pub fn reversal_axes(&self) -> Vec<(Axis, &'static str)> {
        self.reversal
            .iter()
            .flatten()
            .map(|r| (r.play.axis, r.play.reversal.source()))
            .collect()
    }

    /// A tracker of the directions of the axes with a reversal
    /// ([`DirectionTracker`]; empty on a machine without one).
    pub fn direction_tracker(&self) -> DirectionTracker {
        DirectionTracker::new(
            self.reversal
                .iter()
                .flatten()
                .map(|r| r.play.clone())
                .collect(),
        )
    }

    /// REVERSAL of `axis` at joint value `joint` (µm or µrad; the table's
    /// position wrapped and clamped as the curves' lookups are, no count);
    /// `None` when the axis has none.
    pub fn reversal_at(&self, axis: Axis, joint: f64) -> Option<f64> {
        let r = self.reversal[self.kinematics.chain.slot(axis)?].as_ref()?;
        Some(r.play.at_joint(joint))
    }

    /// Per measured axis: intervals of the resampled lookup and its largest deviation
    /// from the exact lookup (µm or µrad); `None` where lookups are exact.
    pub fn lookup_resampling(&self) -> Vec<(Axis, Option<(usize, f64)>)> {
        self.axes
            .iter()
            .flatten()
            .map(|ac| {
                (
                    ac.axis,
                    ac.resampled
                        .as_ref()
                        .map(|r| (r.intervals(), r.max_deviation())),
                )
            })
            .collect()
    }

    /// One entry per measured axis with its range and no curves yet.
    fn empty_axes(machine: &Machine) -> [Option<AxisCurves>; 5] {
        let mut axes: [Option<AxisCurves>; 5] = Default::default();
        for (slot, axis) in machine.layout().slot_axes().into_iter().enumerate() {
            if let Some(table) = machine.table(axis) {
                let (Some(first), Some(last)) = (table.positions.first(), table.positions.last())
                else {
                    continue;
                };
                axes[slot] = Some(AxisCurves {
                    axis,
                    range: [*first, *last],
                    wrap: table.one_revolution,
                    curves: Default::default(),
                    resampled: None,
                });
            }
        }
        axes
    }

    /// A model with no measured tables: only the scalars of `scalars` (component
    /// errors ignored). For nominal machines and tests.
    pub fn scalars_only(kinematics: Kinematics, scalars: ErrorValues) -> ErrorModel {
        let mut values = ErrorValues::ZERO;
        values.squareness = scalars.squareness;
        values.location = scalars.location;
        ErrorModel {
            constants: ChainConstants::new(&kinematics.chain, &values),
            kinematics,
            axes: Default::default(),
            scalars: values,
            reversal: Default::default(),
            policy: ExtrapolationPolicy::Error,
            held: Arc::new(AtomicU64::new(0)),
            holding: OnceLock::new(),
        }
    }

    /// The kinematics (nominal chain and tool) the model evaluates.
    pub fn kinematics(&self) -> &Kinematics {
        &self.kinematics
    }

    /// The same model with a tool of `length_mm` in the spindle; its held
    /// lookups are counted in this model's count (so the base model of
    /// [`super::ToolModels`] counts every tool's). See [`super::ToolModels`].
    pub fn with_tool_length(&self, length_mm: f64) -> ErrorModel {
        let mut model = self.clone();
        model.kinematics = model.kinematics.with_tool_length(length_mm);
        model.held = Arc::clone(&self.held);
        model
    }

    /// The same model, but a lookup beyond a table's end holds the end value
    /// (with its own count of held lookups): what the compensation uses over
    /// the sliver between a table's end and a corrected target just beyond it
    /// (`compensate`). Made once, on first use.
    pub fn holding_ends(&self) -> &ErrorModel {
        self.holding.get_or_init(|| {
            let mut model = self.clone();
            model.policy = ExtrapolationPolicy::Hold;
            model.held = Arc::new(AtomicU64::new(0));
            Box::new(model)
        })
    }

    /// Lookups that held an end value in [`ErrorModel::holding_ends`].
    pub fn table_end_lookups(&self) -> u64 {
        self.holding.get().map_or(0, |m| m.held_lookups())
    }

    /// How far `joints` lie beyond the ends of the tables, per axis (X Y Z
    /// mm, A C degrees; 0 inside a table, for an unmeasured axis, and for a C
    /// table that wraps).
    pub fn beyond_tables(&self, joints: &Axes) -> Axes {
        let mut beyond = Axes::default();
        for ac in self.axes.iter().flatten() {
            if ac.wrap {
                continue;
            }
            let v = joints.get(ac.axis);
            let [lo, hi] = ac.range;
            beyond.set(ac.axis, (lo - v).max(v - hi).max(0.0));
        }
        beyond
    }

    /// What a lookup outside a table's range does.
    pub fn policy(&self) -> ExtrapolationPolicy {
        self.policy
    }

    /// Change the out-of-range policy.
    pub fn set_policy(&mut self, policy: ExtrapolationPolicy) {
        self.policy = policy;
    }

    /// How many single-axis lookups held an end value since the model was built (or
    /// since [`ErrorModel::reset_held_lookups`]).
    pub fn held_lookups(&self) -> u64 {
        self.held.load(Ordering::Relaxed)
    }

    /// Sets the count of [`ErrorModel::held_lookups`] back to 0.
    pub fn reset_held_lookups(&self) {
        self.held.store(0, Ordering::Relaxed);
    }

    /// The fitted curve of a parameter (`"EXX"`...), if measured.
    pub fn curve(&self, parameter: &str) -> Option<&SmemCurve> {
        let index = self.kinematics.layout().index_of(parameter)?;
        if index >= 30 {
            return None;
        }
        self.axes[index / 6].as_ref()?.curves[index % 6].as_ref()
    }

    /// Names of the fitted parameters, in kinematics.md order.
    pub fn fitted_parameters(&self) -> Vec<&'static str> {
        (0..30)
            .filter(|i| {
                self.axes[i / 6]
                    .as_ref()
                    .is_some_and(|ac| ac.curves[i % 6].is_some())
            })
            .map(|i| self.kinematics.layout().name(i))
            .collect()
    }

    /// The position at which `ac` is looked up for joint value `joint`.
    #[inline]
    fn table_position(&self, ac: &AxisCurves, joint: f64) -> Result<f64, LookupError> {
        self.table_position_counted(ac, joint, true)
    }

    /// [`Self::table_position`], counting a held end value only if `count`.
    #[inline]
    fn table_position_counted(
        &self,
        ac: &AxisCurves,
        joint: f64,
        count: bool,
    ) -> Result<f64, LookupError> {
        let [lo, hi] = ac.range;
        let p = if ac.wrap {
            lo + (joint - lo).rem_euclid(360.0)
        } else {
            joint
        };
        let tol = 1e-9 * (1.0 + p.abs());
        if p < lo - tol || p > hi + tol {
            match self.policy {
                ExtrapolationPolicy::Error => {
                    return Err(LookupError::OutOfRange {
                        axis: ac.axis,
                        position: joint,
                        range: ac.range,
                    });
                }
                ExtrapolationPolicy::Hold => {
                    if count {
                        self.held.fetch_add(1, Ordering::Relaxed);
                    }
                }
            }
        }
        Ok(p.clamp(lo, hi))
    }

    /// Values of all 43 parameters at `joints` (mm, degrees).
    pub fn errors_at(&self, joints: &Axes) -> Result<ErrorValues, LookupError> {
        let mut values = ErrorValues::ZERO;
        self.errors_at_into(joints, &mut values)?;
        Ok(values)
    }

    /// [`Self::errors_at`] written into `values` (every parameter set: the hot
    /// path of the solves fills one buffer instead of moving 344-byte values).
    #[inline]
    pub fn errors_at_into(
        &self,
        joints: &Axes,
        values: &mut ErrorValues,
    ) -> Result<(), LookupError> {
        if !joints.is_finite() {
            return Err(LookupError::NotFinite(*joints));
        }
        *values = self.scalars;
        for (slot, ac) in self.axes.iter().enumerate() {
            let Some(ac) = ac else { continue };
            let p = self.table_position(ac, joints.get(ac.axis))?;
            match &ac.resampled {
                Some(fast) => fast.eval_into(p, &mut values.component[slot]),
                None => {
                    for (out, curve) in values.component[slot].iter_mut().zip(&ac.curves) {
                        if let Some(curve) = curve {
                            *out = curve.value_at(p);
                        }
                    }
                }
            }
        }
        Ok(())
    }

    /// The actual tool tip and axis at `joints` with `errors` (values of this
    /// model's lookups): [`Kinematics::actual_tip_and_axis`], the same numbers,
    /// with the chain's constants of the model's scalars computed once.
    #[inline]
    pub fn actual_tip_and_axis(&self, joints: &Axes, errors: &ErrorValues) -> TipAndAxis {
        self.kinematics
            .actual_tip_and_axis_with(joints, errors, &self.constants)
    }

    /// [`Kinematics::tip_jacobian`] with this model's chain constants (the same
    /// numbers).
    pub fn tip_jacobian(&self, joints: &Axes, errors: &ErrorValues) -> [[f64; 5]; 3] {
        self.kinematics
            .tip_jacobian_with(joints, errors, &self.constants)
    }

    /// [`Self::errors_at`] for a pose approached as `approach` says: each axis
    /// with a reversal and a known direction adds ±REVERSAL/2 to its
    /// positioning parameter (formats.md "Laser positioning runs and
    /// reversal"); an unknown direction adds nothing (the mean error).
    pub fn errors_toward(
        &self,
        joints: &Axes,
        approach: &Approach,
    ) -> Result<ErrorValues, LookupError> {
        let mut values = ErrorValues::ZERO;
        self.errors_toward_into(joints, approach, &mut values)?;
        Ok(values)
    }

    /// [`Self::errors_toward`] written into `values`.
    #[inline]
    pub fn errors_toward_into(
        &self,
        joints: &Axes,
        approach: &Approach,
        values: &mut ErrorValues,
    ) -> Result<(), LookupError> {
        self.errors_at_into(joints, values)?;
        self.add_reversal(values, joints, approach);
        Ok(())
    }

    /// Add the reversal terms of `approach` at `joints` to `values`.
    #[inline]
    pub fn add_reversal(&self, values: &mut ErrorValues, joints: &Axes, approach: &Approach) {
        if approach.is_none() {
            return;
        }
        for (slot, r) in self.reversal.iter().enumerate() {
            let Some(r) = r else { continue };
            let sign = approach.get(r.play.axis).sign();
            if sign != 0.0 {
                values.component[slot][r.component] +=
                    0.5 * sign * r.play.at_joint(joints.get(r.play.axis));
            }
        }
    }

    /// [`Self::volumetric_error`] for a pose approached as `approach` says.
    #[inline]
    pub fn volumetric_error_toward(
        &self,
        joints: &Axes,
        approach: &Approach,
    ) -> Result<VolumetricError, LookupError> {
        let errors = self.errors_toward(joints, approach)?;
        Ok(self.kinematics.volumetric_error(joints, &errors))
    }

    /// Volumetric and tool-axis error at `joints`: the lookup plus the chain.
    #[inline]
    pub fn volumetric_error(&self, joints: &Axes) -> Result<VolumetricError, LookupError> {
        let errors = self.errors_at(joints)?;
        Ok(self.kinematics.volumetric_error(joints, &errors))
    }

    /// Whether any fitted curve carries an uncertainty (model files written
    /// before uncertainties were reported carry none).
    pub fn has_uncertainty(&self) -> bool {
        self.axes
            .iter()
            .flatten()
            .flat_map(|ac| ac.curves.iter().flatten())
            .any(|c| !c.uncertainty().is_empty())
    }

    /// The standard uncertainty of the model's e at `joints` (see
    /// [`ModelUncertainty`]); the same lookup policy as [`Self::errors_at`].
    pub fn uncertainty_at(&self, joints: &Axes) -> Result<ModelUncertainty, LookupError> {
        self.uncertainty_with(&self.kinematics, joints)
    }

    /// [`Self::uncertainty_at`] through the chain `kinematics` (another tool).
    pub fn uncertainty_with(
        &self,
        kinematics: &Kinematics,
        joints: &Axes,
    ) -> Result<ModelUncertainty, LookupError> {
        if !joints.is_finite() {
            return Err(LookupError::NotFinite(*joints));
        }
        let mut out = ModelUncertainty {
            by_parameter: [[0.0; 3]; 30],
        };
        for (slot, ac) in self.axes.iter().enumerate() {
            let Some(ac) = ac else { continue };
            // Not counted: the same pose's value lookup counts it.
            let p = self.table_position_counted(ac, joints.get(ac.axis), false)?;
            for (k, curve) in ac.curves.iter().enumerate() {
                let Some(u) = curve.as_ref().and_then(|c| c.uncertainty_at(p)) else {
                    continue;
                };
                if u == 0.0 {
                    continue;
                }
                let mut one = ErrorValues::ZERO;
                one.component[slot][k] = u;
                out.by_parameter[slot * 6 + k] = kinematics.volumetric_error(joints, &one).e_um;
            }
        }
        Ok(out)
    }

    /// The e of each parameter alone at `joints` (first order: every other parameter
    /// zero), largest |e| first; parameters that are zero there are left out.
    pub fn contributions(&self, joints: &Axes) -> Result<Vec<Contribution>, LookupError> {
        self.contributions_toward(joints, &Approach::NONE)
    }

    /// [`Self::contributions`] for a pose approached as `approach` says (the
    /// positioning parameters carry their ±REVERSAL/2).
    pub fn contributions_toward(
        &self,
        joints: &Axes,
        approach: &Approach,
    ) -> Result<Vec<Contribution>, LookupError> {
        let errors = self.errors_toward(joints, approach)?;
        let names = self.kinematics.layout().names();
        let mut out: Vec<Contribution> = (0..PARAMETER_COUNT)
            .filter_map(|i| {
                let value = errors.get_index(i)?;
                if value == 0.0 {
                    return None;
                }
                let v = self.kinematics.volumetric_error(joints, &errors.only(i));
                Some(Contribution {
                    parameter: names[i],
                    value,
                    e_um: v.e_um,
                    axis_urad: v.axis_urad,
                })
            })
            .collect();
        out.sort_by(|a, b| b.magnitude_um().total_cmp(&a.magnitude_um()));
        Ok(out)
    }
}
