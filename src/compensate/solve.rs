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
    let target = Target::of(model, nominal)?;
    let mut q = *nominal;
    if guess.iter().all(|g| g.is_finite() && g.abs() < 1.0) {
        q.x += guess[0];
        q.y += guess[1];
        q.z += guess[2];
    }
    let mut residual = f64::INFINITY;
    for iteration in 0..=MAX_ITERATIONS {
        let (next, r) = target.newton_step(model, &q)?;
        residual = r;
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
        q = next;
    }
    Err(SolveError::NoConvergence {
        joints: *nominal,
        residual_um: residual * 1e3,
        iterations: MAX_ITERATIONS,
    })
}

/// First-order compensated joints with one error evaluation: `q − M⁻¹·e(q)`, A and
/// C as given (the first step of [`solve_joints`]). Its departure from the exact
/// solve is the error's slope times the correction (≈ 1e-4 × tens of µm, a few
/// nm), so it serves to decide whether a move must be split, never as output.
pub fn first_order_joints(model: &ErrorModel, nominal: &Axes) -> Result<Axes, SolveError> {
    Ok(Target::of(model, nominal)?.newton_step(model, nominal)?.0)
}

/// The nominal tool tip to land on, and its machine point at the programmed A, C.
struct Target {
    tip: [f64; 3],
    machine: [f64; 3],
}

impl Target {
    fn of(model: &ErrorModel, nominal: &Axes) -> Result<Target, SolveError> {
        if !nominal.is_finite() {
            return Err(SolveError::NotFinite(*nominal));
        }
        let kinematics = model.kinematics();
        let tip = kinematics.nominal_tip(nominal);
        Ok(Target {
            tip,
            machine: kinematics.nominal_machine_point(tip, nominal.a, nominal.c),
        })
    }

    /// One step from `q`: the next joints and the current residual |r_act(q) − tip| (mm).
    fn newton_step(&self, model: &ErrorModel, q: &Axes) -> Result<(Axes, f64), SolveError> {
        let kinematics = model.kinematics();
        let errors = model.errors_at(q)?;
        let actual = kinematics.actual_tip_and_axis(q, &errors).tip;
        let residual = crate::vec3::dist(actual, self.tip);
        let m_actual = kinematics.nominal_machine_point(actual, q.a, q.c);
        let next = Axes {
            x: q.x + self.machine[0] - m_actual[0],
            y: q.y + self.machine[1] - m_actual[1],
            z: q.z + self.machine[2] - m_actual[2],
            ..*q
        };
        Ok((next, residual))
    }
}
