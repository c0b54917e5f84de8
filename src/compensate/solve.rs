//! The compensation solve: joints whose modelled ACTUAL tool tip lands on the
//! programmed (nominal) one.
//!
//! With the rotary joints kept as programmed, the actual tip `r_act(x, y, z)` is the
//! nominal tip plus the volumetric error, and the nominal map is an exact affine map
//! whose inverse is `Kinematics::tip_to_joints`. The iteration
//!
//! ```text
//! q_{k+1} = q_k + M(r_target) − M(r_act(q_k))        (M = nominal part → machine map)
//! ```
//!
//! is Newton's method with the nominal Jacobian: it contracts by the slope of the
//! error functions (a few µm per 100 mm, so ~1e-4 per step) and reaches the 1 nm
//! residual in two or three steps. It stops with a typed error when it does not.
//!
//! With `--position-only` rotary errors are not corrected through the rotary
//! joints: the tool-axis error (µrad) remains, as in the seed paper, which moves
//! only X, Y, Z.
//!
//! [`solve_pose_from`] (the default) solves X Y Z and the two rotary joints
//! together so that the actual tip AND the actual tool axis equal the programmed
//! ones: five equations (the tip, and the axis's two components normal to the
//! programmed axis; a rotation about the axis does not matter). Newton with the
//! analytic tip Jacobian and the nominal axis derivatives (the errors' own
//! dependence on the joints is ~1e-5 of them), to 1 nm and 0.01 µrad. Near the
//! pole (the tool axis along the outer rotary axis: A = 0 on an A/C table) the
//! outer joint cannot steer the axis: when a step would turn it by more than
//! [`MAX_C_CORRECTION_DEG`] (or the iteration stalls there), the block is left
//! to the position-only solve, and counted. Joint vectors are `(x, y, z, r₁, r₂)`
//! with the machine's rotary letters in letter order.
use crate::axes::{Axes, Joints};
use crate::kinematics::{ErrorValues, Kinematics};
use crate::machine::{Approach, ErrorModel, LookupError};

/// Residual at which the solve stops, mm (1 nm).
pub const RESIDUAL_MM: f64 = 1e-6;
/// Iterations before giving up.
pub const MAX_ITERATIONS: usize = 30;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error(transparent)]
    Lookup(#[from] LookupError),
    #[error(
        "the compensation did not converge at {joints}: residual {residual_um:.4} µm after {iterations} iterations"
    )]
    NoConvergence {
        /// The programmed joints, as `X… Y… Z… B… C…`.
        joints: String,
        residual_um: f64,
        iterations: usize,
    },
    #[error("the target is not finite: {0:?}")]
    NotFinite(Axes),
}

/// Tool-axis residual at which the orientation solve stops, µrad.
pub const RESIDUAL_URAD: f64 = 0.01;
/// Largest correction of the outer rotary joint in the orientation solve,
/// degrees: beyond it the pose is too close to the pole for that joint to steer
/// the axis (on an A/C table a 50 µrad tilt needs 0.05° of C at sin a ≈ 0.06,
/// a = 3.3°).
pub const MAX_C_CORRECTION_DEG: f64 = 0.05;

/// A solved pose of the orientation solve.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolvedPose {
    /// Compensated joints, the rotary joints included.
    pub joints: Joints,
    /// Final |r_act − r_target|, mm.
    pub residual_mm: f64,
    /// Final angle between the actual and the programmed tool axis, µrad.
    pub residual_urad: f64,
    /// The same angle at the programmed joints (before compensation), µrad,
    /// from the first iterate to first order.
    pub before_urad: f64,
    pub iterations: usize,
}

/// Farthest a kept Jacobian is used from the pose it was taken at: degrees of
/// a rotary joint, and mm of X, Y or Z. Within it the Jacobian differs by ≲ 1e-2
/// relative, so Newton with it still gains two decimals per step.
const JACOBIAN_REACH_DEG: f64 = 1.0;
const JACOBIAN_REACH_MM: f64 = 10.0;
/// Steps taken with a kept Jacobian before it is taken afresh.
const KEPT_JACOBIAN_STEPS: usize = 3;

type Lu5 = nalgebra::LU<f64, nalgebra::U5, nalgebra::U5>;

/// What one solve passes to the next along a path: the joint correction
/// (X Y Z mm, rotary joints degrees, slot order) of the last pose, a good start since corrections
/// change slowly, and the orientation solve's Jacobian with the joints it was
/// taken at, kept while the path stays near them. The result does not depend on
/// it beyond the residuals (1 nm, 0.01 µrad).
#[derive(Clone, Debug, Default)]
pub struct WarmStart {
    /// Joint correction of the last pose (X Y Z mm, rotary joints degrees, slot order).
    pub correction: [f64; 5],
    jacobian: Option<KeptJacobian>,
}

#[derive(Clone, Debug)]
struct KeptJacobian {
    lu: Lu5,
    /// Joints it was taken at.
    at: [f64; 5],
    /// The pole angle there (degrees, [`Kinematics::pole_angle_deg`]).
    pole_deg: f64,
}

impl KeptJacobian {
    /// Whether it serves at joints `q`. Near the pole the axis rows scale with the
    /// sine of the pole angle, so the reach of the rotary joints shrinks to a tenth
    /// of that angle there.
    fn reaches(&self, q: &[f64; 5]) -> bool {
        let degrees = JACOBIAN_REACH_DEG.min(0.1 * self.pole_deg);
        (0..3).all(|i| (self.at[i] - q[i]).abs() <= JACOBIAN_REACH_MM)
            && (3..5).all(|i| (self.at[i] - q[i]).abs() <= degrees)
    }
}

/// `X… Y… Z… B… C…` of the machine's joints (messages).
pub(crate) fn describe_joints(kin: &Kinematics, q: &Axes) -> String {
    let j = kin.joints(q);
    let [r1, r2] = kin.rotary();
    format!(
        "X{:.4} Y{:.4} Z{:.4} {}{:.4} {}{:.4}",
        j[0],
        j[1],
        j[2],
        r1.letter(),
        j[3],
        r2.letter(),
        j[4]
    )
}

/// Joints whose actual tip and tool axis are the programmed ones, starting from
/// `nominal + warm.correction` (X Y Z mm, A C degrees) with the Jacobian `warm`
/// keeps, if it is near. `Ok(None)`: the pose is too close to the A = 0 pole
/// for C to steer the axis (a step with a fresh Jacobian would turn C by more
/// than `MAX_C_CORRECTION_DEG`, the system is singular, or the iteration does
/// not reach the residuals in `MAX_ITERATIONS` steps); the caller solves
/// position only. A Jacobian serves several steps and poses (the errors' slope
/// makes it differ by ~1e-5, a nearby pose by ≲ 1e-2); a kept one that does not
/// converge in `KEPT_JACOBIAN_STEPS` is taken afresh. `warm` is updated.
pub fn solve_pose_from(
    model: &ErrorModel,
    nominal: &Joints,
    warm: &mut WarmStart,
) -> Result<Option<SolvedPose>, SolveError> {
    solve_pose_toward(model, nominal, &Approach::NONE, warm)
}

/// [`solve_pose_from`] for a pose approached as `approach` says (the reversal
/// terms of the axes with a known direction: `ErrorModel::errors_toward`).
pub fn solve_pose_toward(
    model: &ErrorModel,
    nominal: &Joints,
    approach: &Approach,
    warm: &mut WarmStart,
) -> Result<Option<SolvedPose>, SolveError> {
    let target = PoseTarget::of(model, nominal)?;
    let kin = model.kinematics();
    let mut q = nominal.axes();
    let guess = warm.correction;
    if guess.iter().all(|g| g.is_finite() && g.abs() < 1.0) {
        let j = kin.joints(&q);
        q = kin.with_joints(&q, std::array::from_fn(|i| j[i] + guess[i]));
    }
    if !warm
        .jacobian
        .as_ref()
        .is_some_and(|j| j.reaches(&kin.joints(&q)))
    {
        warm.jacobian = None;
    }
    let mut fresh = false;
    let mut steps = 0;
    let mut before_urad = f64::NAN;
    let mut errors = ErrorValues::ZERO;
    for iteration in 0..=MAX_ITERATIONS {
        let r = target.residual(model, approach, &q, &mut errors)?;
        let residual_mm = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        let residual_urad = 1e6 * (r[3] * r[3] + r[4] * r[4]).sqrt();
        let kept = match warm.jacobian.take() {
            Some(kept) => kept,
            None => {
                let matrix = target.jacobian(model, &q, &errors);
                fresh = true;
                steps = 0;
                KeptJacobian {
                    lu: matrix.lu(),
                    at: kin.joints(&q),
                    pole_deg: kin.pole_angle_deg(&q),
                }
            }
        };
        if iteration == 0 {
            // The axis residual at the programmed joints, to first order (the
            // axis rows taken here: near the pole they change fast with A).
            let rows = target.axis_rows(model, &q);
            let (jq, jn) = (kin.joints(&q), kin.joints(nominal));
            let (da, dc) = (jq[3] - jn[3], jq[4] - jn[4]);
            let at_nominal = |row: usize| r[3 + row] - rows[row][0] * da - rows[row][1] * dc;
            before_urad = 1e6 * at_nominal(0).hypot(at_nominal(1));
        }
        if residual_mm < RESIDUAL_MM && residual_urad < RESIDUAL_URAD {
            warm.jacobian = Some(kept);
            return Ok(Some(SolvedPose {
                joints: Joints::new(q),
                residual_mm,
                residual_urad,
                before_urad,
                iterations: iteration,
            }));
        }
        match target.next(kin, &kept.lu, &q, &r) {
            Some(next) if fresh || steps < KEPT_JACOBIAN_STEPS => {
                q = next;
                steps += 1;
                warm.jacobian = Some(kept);
            }
            // A kept Jacobian that does not serve: take it afresh here.
            _ if !fresh => {}
            // Near the pole, or singular: the caller solves position only.
            _ => return Ok(None),
        }
    }
    // Not converged: ill-conditioned (close to the pole); the caller falls back
    // to the position-only solve and counts the move.
    Ok(None)
}

/// The programmed tip and tool axis, and two unit vectors normal to the axis.
struct PoseTarget {
    /// The programmed value of the outer rotary joint and its slot (3 or 4).
    outer: (f64, usize),
    tip: [f64; 3],
    axis: [f64; 3],
    normals: [[f64; 3]; 2],
}

impl PoseTarget {
    fn of(model: &ErrorModel, nominal: &Axes) -> Result<PoseTarget, SolveError> {
        if !nominal.is_finite() {
            return Err(SolveError::NotFinite(*nominal));
        }
        let kin = model.kinematics();
        let (tip, axis) = kin.nominal_tip_and_axis(nominal);
        let (e1, e2) = normal_basis(axis);
        let outer = kin.outer_rotary();
        Ok(PoseTarget {
            outer: (nominal.get(outer), kin.chain.slot(outer).unwrap_or(4)),
            tip,
            axis,
            normals: [e1, e2],
        })
    }

    /// Tip residual (mm) and axis residual along the two normals (rad) at `q`;
    /// the error values there are left in `errors`.
    fn residual(
        &self,
        model: &ErrorModel,
        approach: &Approach,
        q: &Axes,
        errors: &mut ErrorValues,
    ) -> Result<[f64; 5], SolveError> {
        model.errors_toward_into(q, approach, errors)?;
        let actual = model.actual_tip_and_axis(q, errors);
        let du = crate::vec3::sub(crate::vec3::normalise(actual.axis), self.axis);
        let [e1, e2] = self.normals;
        Ok([
            actual.tip[0] - self.tip[0],
            actual.tip[1] - self.tip[1],
            actual.tip[2] - self.tip[2],
            crate::vec3::dot(du, e1),
            crate::vec3::dot(du, e2),
        ])
    }

    /// ∂(residual)/∂(x, y, z mm; r₁, r₂ degrees): the analytic tip Jacobian and
    /// the analytic nominal axis derivatives (the errors' share is ~1e-5 of them).
    fn jacobian(
        &self,
        model: &ErrorModel,
        q: &Axes,
        errors: &ErrorValues,
    ) -> nalgebra::Matrix5<f64> {
        let jt = model.tip_jacobian(q, errors);
        let axis = self.axis_rows(model, q);
        let mut j = nalgebra::Matrix5::<f64>::zeros();
        for row in 0..3 {
            for col in 0..5 {
                j[(row, col)] = jt[row][col];
            }
        }
        for (row, values) in axis.iter().enumerate() {
            j[(3 + row, 3)] = values[0];
            j[(3 + row, 4)] = values[1];
        }
        j
    }

    /// ∂(axis residual along the two normals)/∂(r₁, r₂ degrees) at `q`, nominal.
    fn axis_rows(&self, model: &ErrorModel, q: &Axes) -> [[f64; 2]; 2] {
        let (ua, uc) = model.kinematics().nominal_axis_jacobian(q);
        self.normals
            .map(|e| [crate::vec3::dot(ua, e), crate::vec3::dot(uc, e)])
    }

    /// The next iterate, `None` when the system is singular or the outer rotary
    /// joint would turn by more than [`MAX_C_CORRECTION_DEG`] (the pole).
    fn next(
        &self,
        kin: &Kinematics,
        lu: &nalgebra::LU<f64, nalgebra::U5, nalgebra::U5>,
        q: &Axes,
        r: &[f64; 5],
    ) -> Option<Axes> {
        let step = lu.solve(&nalgebra::Vector5::from_column_slice(r))?;
        let j = kin.joints(q);
        let next: [f64; 5] = std::array::from_fn(|i| j[i] - step[i]);
        let (outer, slot) = self.outer;
        (next.iter().all(|v| v.is_finite()) && (next[slot] - outer).abs() <= MAX_C_CORRECTION_DEG)
            .then(|| kin.with_joints(q, next))
    }
}

/// Two unit vectors normal to the unit vector `u` and to each other.
fn normal_basis(u: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let helper = if u[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let e1 = crate::vec3::normalise(crate::vec3::cross(u, helper));
    let e2 = crate::vec3::cross(u, e1);
    (e1, e2)
}

/// A solved target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solved {
    /// Compensated joints (rotary joints as programmed).
    pub joints: Joints,
    /// Final |r_act − r_target|, mm.
    pub residual_mm: f64,
    pub iterations: usize,
}

/// Joints `q` with `r_act(q) = nominal_tip(nominal)`, starting from `nominal`.
pub fn solve_joints(model: &ErrorModel, nominal: &Joints) -> Result<Solved, SolveError> {
    solve_joints_from(model, nominal, [0.0; 3])
}

/// As [`solve_joints`], starting from `nominal + guess` (X Y Z, mm): the previous
/// target's correction is a good guess, since corrections change slowly along a
/// path, and saves an iteration. The result does not depend on the guess beyond
/// the 1 nm residual.
pub fn solve_joints_from(
    model: &ErrorModel,
    nominal: &Joints,
    guess: [f64; 3],
) -> Result<Solved, SolveError> {
    solve_joints_toward(model, nominal, &Approach::NONE, guess)
}

/// [`solve_joints_from`] for a pose approached as `approach` says.
pub fn solve_joints_toward(
    model: &ErrorModel,
    nominal: &Joints,
    approach: &Approach,
    guess: [f64; 3],
) -> Result<Solved, SolveError> {
    let target = Target::of(model, nominal)?;
    let mut q = nominal.axes();
    if guess.iter().all(|g| g.is_finite() && g.abs() < 1.0) {
        q.x += guess[0];
        q.y += guess[1];
        q.z += guess[2];
    }
    let mut residual = f64::INFINITY;
    let mut errors = ErrorValues::ZERO;
    for iteration in 0..=MAX_ITERATIONS {
        let (next, r) = target.newton_step(model, approach, &q, &mut errors)?;
        residual = r;
        if residual < RESIDUAL_MM {
            return Ok(Solved {
                joints: Joints::new(q),
                residual_mm: residual,
                iterations: iteration,
            });
        }
        if !residual.is_finite() {
            break;
        }
        q = next;
    }
    Err(SolveError::NoConvergence {
        joints: describe_joints(model.kinematics(), nominal),
        residual_um: residual * 1e3,
        iterations: MAX_ITERATIONS,
    })
}

/// First-order compensated joints with one error evaluation: `q − M⁻¹·e(q)`, the
/// rotary joints as given (the first step of [`solve_joints`]). Its departure from the exact
/// solve is the error's slope times the correction (≈ 1e-4 × tens of µm, a few
/// nm), so it serves to decide whether a move must be split, never as output.
pub fn first_order_joints(
    model: &ErrorModel,
    nominal: &Joints,
    approach: &Approach,
) -> Result<Joints, SolveError> {
    let mut errors = ErrorValues::ZERO;
    let (next, _) =
        Target::of(model, nominal)?.newton_step(model, approach, nominal, &mut errors)?;
    Ok(Joints::new(next))
}

/// First-order X Y Z at the rotary joints `rotary` (degrees, slot order) such that
/// the actual tip lands on the nominal tip of `nominal`: one error evaluation (the
/// split decision of the orientation solve, where the control turns the rotary
/// axes to the interpolated corrected angles between two compensated ends).
pub fn first_order_joints_at(
    model: &ErrorModel,
    nominal: &Joints,
    rotary: [f64; 2],
    approach: &Approach,
) -> Result<Joints, SolveError> {
    if !nominal.is_finite() {
        return Err(SolveError::NotFinite(nominal.axes()));
    }
    let kin = model.kinematics();
    let mut turned = nominal.axes();
    let [r1, r2] = kin.rotary();
    turned.set(r1, rotary[0]);
    turned.set(r2, rotary[1]);
    let tip = kin.nominal_tip(nominal);
    let map = kin.tip_to_joints(&turned);
    let start = map.joints(tip);
    let target = Target {
        tip,
        machine: start.xyz(),
        map,
    };
    let mut errors = ErrorValues::ZERO;
    let (next, _) = target.newton_step(model, approach, &start, &mut errors)?;
    Ok(Joints::new(next))
}

/// The nominal tool tip to land on, and its machine point at the programmed
/// rotary joints.
struct Target {
    tip: [f64; 3],
    machine: [f64; 3],
    /// The nominal part → machine map at those rotary joints.
    map: crate::kinematics::TipToJoints,
}

impl Target {
    fn of(model: &ErrorModel, nominal: &Axes) -> Result<Target, SolveError> {
        if !nominal.is_finite() {
            return Err(SolveError::NotFinite(*nominal));
        }
        let map = model.kinematics().tip_to_joints(nominal);
        // The nominal tip from the same (exact, affine) map: r₀ + J·(x, y, z).
        let tip = map.tip_of(nominal.xyz());
        Ok(Target {
            tip,
            machine: nominal.xyz(),
            map,
        })
    }

    /// One step from `q`: the next joints and the current residual |r_act(q) − tip|
    /// (mm); `errors` is the buffer of the lookup.
    fn newton_step(
        &self,
        model: &ErrorModel,
        approach: &Approach,
        q: &Axes,
        errors: &mut ErrorValues,
    ) -> Result<(Axes, f64), SolveError> {
        model.errors_toward_into(q, approach, errors)?;
        let actual = model.actual_tip_and_axis(q, errors).tip;
        let residual = crate::vec3::dist(actual, self.tip);
        let m_actual = self.map.linear_joints(actual);
        let next = Axes {
            x: q.x + self.machine[0] - m_actual[0],
            y: q.y + self.machine[1] - m_actual[1],
            z: q.z + self.machine[2] - m_actual[2],
            ..*q
        };
        Ok((next, residual))
    }
}
