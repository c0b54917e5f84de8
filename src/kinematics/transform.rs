//! Affine 4×4 homogeneous transforms `[M t; 0 0 0 1]`, hand-rolled and `Copy` so the
//! hot path allocates nothing.
//!
//! Every matrix of kinematics.md (translations, rotations, the first-order `E(δ, ε)`
//! and `L(δ, ε)`) has the last row `0 0 0 1`, so storing the 3×3 block `m` and the
//! translation `t` loses nothing, and the exact inverse of the 4×4 matrix is
//! `[M⁻¹  −M⁻¹·t; 0 1]` with `M⁻¹` the exact 3×3 inverse (adjugate over determinant).
//! No re-orthonormalisation happens anywhere: a first-order `E` stays as written.

/// A 3×3 matrix, row-major: `m[row][column]`.
pub type Mat3 = [[f64; 3]; 3];

/// The 3×3 identity.
pub const IDENTITY3: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// Homogeneous transform with last row `0 0 0 1`: `p ↦ m·p + t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Affine {
    pub m: Mat3,
    pub t: [f64; 3],
}

impl Affine {
    pub const IDENTITY: Affine = Affine {
        m: IDENTITY3,
        t: [0.0; 3],
    };

    /// `Trans(v)`.
    pub const fn translation(v: [f64; 3]) -> Affine {
        Affine { m: IDENTITY3, t: v }
    }

    /// Right-handed rotation about X by `angle` radians.
    pub fn rot_x(angle: f64) -> Affine {
        let (s, c) = angle.sin_cos();
        Affine::rot_x_sin_cos(s, c)
    }

    /// Rotation about X from the sine and cosine of its angle.
    pub const fn rot_x_sin_cos(s: f64, c: f64) -> Affine {
        Affine {
            m: [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
            t: [0.0; 3],
        }
    }

    /// Right-handed rotation about Z by `angle` radians.
    pub fn rot_z(angle: f64) -> Affine {
        let (s, c) = angle.sin_cos();
        Affine::rot_z_sin_cos(s, c)
    }

    /// Rotation about Z from the sine and cosine of its angle.
    pub const fn rot_z_sin_cos(s: f64, c: f64) -> Affine {
        Affine {
            m: [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
            t: [0.0; 3],
        }
    }

    /// The first-order small-displacement matrix `E(δ, ε)` of kinematics.md, exactly as
    /// written (δ in mm, ε in rad).
    pub const fn small(delta: [f64; 3], eps: [f64; 3]) -> Affine {
        let [ex, ey, ez] = eps;
        Affine {
            m: [[1.0, -ez, ey], [ez, 1.0, -ex], [-ey, ex, 1.0]],
            t: delta,
        }
    }

    /// `self · other`.
    #[inline]
    pub fn mul(&self, other: &Affine) -> Affine {
        Affine {
            m: mat_mul(&self.m, &other.m),
            t: add(mat_vec(&self.m, other.t), self.t),
        }
    }

    /// `self · other`, cheaper when one of them is a pure translation (the
    /// nominal linear factors of a chain): the same numbers as [`Affine::mul`].
    #[inline]
    pub fn mul_fast(&self, other: &Affine) -> Affine {
        if other.m == IDENTITY3 {
            Affine {
                m: self.m,
                t: add(mat_vec(&self.m, other.t), self.t),
            }
        } else if self.m == IDENTITY3 {
            Affine {
                m: other.m,
                t: add(other.t, self.t),
            }
        } else {
            self.mul(other)
        }
    }

    /// `self · (p, 1)`.
    #[inline]
    pub fn apply_point(&self, p: [f64; 3]) -> [f64; 3] {
        add(mat_vec(&self.m, p), self.t)
    }

    /// `self · (v, 0)`.
    #[inline]
    pub fn apply_vector(&self, v: [f64; 3]) -> [f64; 3] {
        mat_vec(&self.m, v)
    }

    /// `Trans(p) · self · Trans(−p)`: the same motion about the point `p`.
    #[inline]
    pub fn about(&self, p: [f64; 3]) -> Affine {
        Affine {
            m: self.m,
            t: add(self.t, sub(p, mat_vec(&self.m, p))),
        }
    }

    /// The exact inverse of the 4×4 matrix.
    ///
    /// Never singular for the transforms of kinematics.md with finite values: rotations
    /// have determinant 1, `det(I + [ε]×) = 1 + |ε|² ≥ 1`, and products multiply
    /// determinants. Non-finite input gives non-finite output (checked at the boundary).
    #[inline]
    pub fn inverse(&self) -> Affine {
        let mi = mat_inverse(&self.m);
        let t = mat_vec(&mi, self.t);
        Affine {
            m: mi,
            t: [-t[0], -t[1], -t[2]],
        }
    }
}

pub use crate::vec3::{add, cross, dot, norm, scale, sub};

#[inline]
pub fn mat_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[0][1] * v[1] + m[0][2] * v[2],
        m[1][0] * v[0] + m[1][1] * v[1] + m[1][2] * v[2],
        m[2][0] * v[0] + m[2][1] * v[1] + m[2][2] * v[2],
    ]
}

#[inline]
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut out = [[0.0; 3]; 3];
    for (i, row) in out.iter_mut().enumerate() {
        for (j, cell) in row.iter_mut().enumerate() {
            *cell = a[i][0] * b[0][j] + a[i][1] * b[1][j] + a[i][2] * b[2][j];
        }
    }
    out
}

/// Exact inverse of a 3×3 matrix by the adjugate over the determinant (the caller
/// guarantees a non-singular matrix; a singular one gives non-finite entries).
#[inline]
pub fn mat_inverse(m: &Mat3) -> Mat3 {
    let c00 = m[1][1] * m[2][2] - m[1][2] * m[2][1];
    let c01 = m[1][2] * m[2][0] - m[1][0] * m[2][2];
    let c02 = m[1][0] * m[2][1] - m[1][1] * m[2][0];
    let det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    let k = 1.0 / det;
    [
        [
            c00 * k,
            (m[0][2] * m[2][1] - m[0][1] * m[2][2]) * k,
            (m[0][1] * m[1][2] - m[0][2] * m[1][1]) * k,
        ],
        [
            c01 * k,
            (m[0][0] * m[2][2] - m[0][2] * m[2][0]) * k,
            (m[0][2] * m[1][0] - m[0][0] * m[1][2]) * k,
        ],
        [
            c02 * k,
            (m[0][1] * m[2][0] - m[0][0] * m[2][1]) * k,
            (m[0][0] * m[1][1] - m[0][1] * m[1][0]) * k,
        ],
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_of_first_order_matrix_is_exact() {
        let e = Affine::small([0.01, -0.02, 0.03], [1e-3, -2e-3, 3e-3]);
        let p = e.mul(&e.inverse());
        for i in 0..3 {
            for j in 0..3 {
                let want = if i == j { 1.0 } else { 0.0 };
                assert!((p.m[i][j] - want).abs() < 1e-15);
            }
            assert!(p.t[i].abs() < 1e-15);
        }
        // Not the first-order inverse: E(−δ, −ε) differs in the second order.
        let naive = Affine::small([-0.01, 0.02, -0.03], [-1e-3, 2e-3, -3e-3]);
        let q = e.mul(&naive);
        assert!((q.m[0][0] - 1.0).abs() > 1e-6);
    }

    #[test]
    fn about_point_matches_conjugation() {
        let r = Affine::rot_z(0.7).mul(&Affine::rot_x(-0.3));
        let p = [1.0, -2.0, 3.0];
        let a = Affine::translation(p)
            .mul(&r)
            .mul(&Affine::translation([-1.0, 2.0, -3.0]));
        let b = r.about(p);
        for i in 0..3 {
            assert!((a.t[i] - b.t[i]).abs() < 1e-14);
        }
    }
}
