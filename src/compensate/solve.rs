//! The compensation solve: joints whose modelled ACTUAL tool tip lands on the
//! programmed (nominal) one.
//!
//! With A and C kept as programmed, the actual tip `r_act(x, y, z)` is the nominal
//! tip plus the volumetric error, and the nominal map is an exact rigid motion whose
//! inverse is `Kinematics::nominal_machine_point`. The iteration
//!
//! ```text
//! q_{k+1} = q_k + M(r_target) − M(r_act(q_k))        (M = nominal part → machine map)
//! ```
//!
//! is Newton's method with the nominal Jacobian: it contracts by the slope of the
//! error functions (a few µm per 100 mm, so ~1e-4 per step) and reaches the 1 nm
//! residual in two or three steps. It stops with a typed error when it does not.
//!
//! Rotary errors are not corrected through A and C: the tool-axis error (µrad)
//! remains, as in the seed paper, which moves only X, Y, Z.
use crate::axes::Axes;
use crate::machine::{ErrorModel, LookupError};

/// Residual at which the solve stops, mm (1 nm).
pub const RESIDUAL_MM: f64 = 1e-6;
/// Iterations before giving up.
pub const MAX_ITERATIONS: usize = 30;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error(transparent)]
    Lookup(#[from] LookupError),
    #[error(
        "the compensation did not converge at X{:.4} Y{:.4} Z{:.4} A{:.4} C{:.4}: residual {residual_um:.4} µm after {iterations} iterations",
        joints.x, joints.y, joints.z, joints.a, joints.c
    )]
    NoConvergence {
        joints: Axes,
        residual_um: f64,
        iterations: usize,
    },
    #[error("the target is not finite: {0:?}")]
    NotFinite(Axes),
}

/// A solved target.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Solved {
    /// Compensated joints (A and C as programmed).
    pub joints: Axes,
    /// Final |r_act − r_target|, mm.
    pub residual_mm: f64,
    pub iterations: usize,
}

/// Joints `q` with `r_act(q) = nominal_tip(nominal)`, starting from `nominal`.
pub fn solve_joints(model: &ErrorModel, nominal: &Axes) -> Result<Solved, SolveError> {
    solve_joints_from(model, nominal, [0.0; 3])
}

/// As [`solve_joints`], starting from `nominal + guess` (X Y Z, mm): the previous
/// target's correction is a good guess, since corrections change slowly along a
/// path, and saves an iteration. The result does not depend on the guess beyond
/// the 1 nm residual.
pub fn solve_joints_from(
    model: &ErrorModel,
    nominal: &Axes,
    guess: [f64; 3],
) -> Result<Solved, SolveError> {
    let kinematics = model.kinematics();
    if !nominal.is_finite() {
        return Err(SolveError::NotFinite(*nominal));
    }
    let target = kinematics.nominal_tip(nominal);
    let m_target = kinematics.nominal_machine_point(target, nominal.a, nominal.c);
    let mut q = *nominal;
    if guess.iter().all(|g| g.is_finite() && g.abs() < 1.0) {
        q.x += guess[0];
        q.y += guess[1];
        q.z += guess[2];
    }
    let mut residual = f64::INFINITY;
    for iteration in 0..=MAX_ITERATIONS {
        let errors = model.errors_at(&q)?;
        let actual = kinematics.actual_tip_and_axis(&q, &errors).tip;
        let r = [
            actual[0] - target[0],
            actual[1] - target[1],
            actual[2] - target[2],
        ];
        residual = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
        if residual < RESIDUAL_MM {
            return Ok(Solved {
                joints: q,
                residual_mm: residual,
                iterations: iteration,
            });
        }
        if !residual.is_finite() {
            break;
        }
        let m_actual = kinematics.nominal_machine_point(actual, q.a, q.c);
        q.x += m_target[0] - m_actual[0];
        q.y += m_target[1] - m_actual[1];
        q.z += m_target[2] - m_actual[2];
    }
    Err(SolveError::NoConvergence {
        joints: *nominal,
        residual_um: residual * 1e3,
        iterations: MAX_ITERATIONS,
    })
}

/// First-order compensated joints with one error evaluation: `q − M⁻¹·e(q)`, A and
/// C as given. Its departure from the exact solve is the error's slope times the
/// correction (≈ 1e-4 × tens of µm, a few nm), so it serves to decide whether a
/// move must be split, never as output.
pub fn first_order_joints(model: &ErrorModel, nominal: &Axes) -> Result<Axes, SolveError> {
    if !nominal.is_finite() {
        return Err(SolveError::NotFinite(*nominal));
    }
    let kinematics = model.kinematics();
    let target = kinematics.nominal_tip(nominal);
    let errors = model.errors_at(nominal)?;
    let actual = kinematics.actual_tip_and_axis(nominal, &errors).tip;
    let m_target = kinematics.nominal_machine_point(target, nominal.a, nominal.c);
    let m_actual = kinematics.nominal_machine_point(actual, nominal.a, nominal.c);
    Ok(Axes {
        x: nominal.x + m_target[0] - m_actual[0],
        y: nominal.y + m_target[1] - m_actual[1],
        z: nominal.z + m_target[2] - m_actual[2],
        ..*nominal
    })
}
