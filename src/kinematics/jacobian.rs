//! Jacobians of the actual tool tip (part coordinates).
//!
//! * [`Kinematics::tip_jacobian`]: with respect to the joints, analytic, with the
//!   error values held fixed (the tables' own slope, of the order of 1 µm per 100 mm,
//!   changes the result by about 1e-5 relative, which compensation iterations absorb).
//! * [`Kinematics::squareness_jacobian`] and [`Kinematics::location_jacobian`]: with
//!   respect to the position-independent parameters, by central differences (see
//!   [`PARAMETER_STEP`] for the step).
use super::error_values::{ErrorValues, SQUARENESS_NAMES};
use super::transform::{mat_vec, scale, sub};
use super::{Kinematics, linear_index};
use crate::axes::{Axes, Axis};

/// Names of the squareness parameters, in the order of
/// [`Kinematics::squareness_jacobian`](super::Kinematics::squareness_jacobian)'s rows.
pub const SQUARENESS_PARAMETERS: [&str; 3] = SQUARENESS_NAMES;
/// Names of the rotary location parameters (the `rotary_location` effect), in
/// the order of the location Jacobian's rows.
pub const LOCATION_PARAMETERS: [&str; 8] = [
    "EY0A", "EZ0A", "EB0A", "EC0A", "EX0C", "EY0C", "EA0C", "EB0C",
];

/// Step of the central differences over squareness and location parameters: 1 µrad
/// (or 1 µm).
///
/// Why 1: the tip depends on each such parameter through the entries of the
/// first-order matrices (linear) and their exact inverses (rational with the
/// denominator `1 + |ε|²`), so its third derivative is of the order of
/// `|r|·(1e-6 rad)³` per µrad³ and the truncation error `h²·f'''/6` is far below
/// 1e-12 µm per µrad; the central difference cancels the second-order term exactly.
/// Rounding: the tip (|r| ≤ ~1000 mm) carries about 1e-13 mm = 1e-10 µm of rounding,
/// divided by `2h` = 2 that is 5e-11 µm per µrad. A smaller step only adds rounding;
/// a much larger one (1000 µrad) would still be accurate to ~1e-9 but models no real
/// machine.
pub const PARAMETER_STEP: f64 = 1.0;

impl Kinematics {
    /// `∂(actual tool tip, part, mm) / ∂(x, y, z mm; a, c degrees)` at `joints` with
    /// the error values `errors` held fixed: `J[row = tip x y z][column = x y z a c]`.
    /// Pass [`ErrorValues::ZERO`] for the nominal Jacobian.
    pub fn tip_jacobian(&self, joints: &Axes, errors: &ErrorValues) -> [[f64; 5]; 3] {
        let chain = self.chain(joints, errors);
        let r = chain.tip(self.tool_length);
        let minv = &chain.work_inv.m;
        let mut columns = [[0.0; 3]; 5];
        // r = M⁻¹·p: ∂r/∂q_k = M⁻¹·(prefix_k · d_k), the translation T_k(q_k) = Trans(q_k·d_k).
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let i = linear_index(axis);
            columns[i] = mat_vec(minv, mat_vec(&chain.prefix[i], chain.directions[i]));
        }
        let per_degree = self.direction_sign() * std::f64::consts::PI / 180.0;
        // ∂r/∂θ = −M⁻¹·(∂M/∂θ)·r, M = T_A·T_C.
        // A: ∂T_A/∂a·v = L_A·Rx'(a)·E_A·L_A⁻¹·(v − P_A), applied to v = T_C·r.
        {
            let v = chain.table_c.apply_point(r);
            let w = chain
                .location_a_inv
                .apply_point(sub(v, self.geometry.a_point()));
            let u = chain.error_a.apply_point(w);
            let (s, c) = chain.angle_a.sin_cos();
            let d = [0.0, -s * u[1] - c * u[2], c * u[1] - s * u[2]];
            let dm = chain.location_a.apply_vector(d);
            columns[3] = scale(mat_vec(minv, dm), -per_degree);
        }
        // C: T_A·∂T_C/∂c·r = T_A·L_C·Rz'(c)·E_C·L_C⁻¹·(r − P_C).
        {
            let w = chain
                .location_c_inv
                .apply_point(sub(r, self.geometry.c_point()));
            let u = chain.error_c.apply_point(w);
            let (s, c) = chain.angle_c.sin_cos();
            let d = [-s * u[0] - c * u[1], c * u[0] - s * u[1], 0.0];
            let dm = chain.table_a.apply_vector(chain.location_c.apply_vector(d));
            columns[4] = scale(mat_vec(minv, dm), -per_degree);
        }
        let mut out = [[0.0; 5]; 3];
        for (j, col) in columns.iter().enumerate() {
            for (i, row) in out.iter_mut().enumerate() {
                row[j] = col[i];
            }
        }
        out
    }

    /// `∂(nominal tool axis)/∂a` and `∂/∂c` (per degree) at `joints`: the
    /// derivatives of `(sin a sin c, sin a cos c, cos a)` (direction convention
    /// applied), one trigonometric evaluation.
    pub fn nominal_axis_jacobian(&self, joints: &Axes) -> ([f64; 3], [f64; 3]) {
        let rot = self.rotations(joints.a, joints.c);
        let k = self.direction_sign() * std::f64::consts::PI / 180.0;
        (
            [k * rot.ca * rot.sc, k * rot.ca * rot.cc, -k * rot.sa],
            [k * rot.sa * rot.cc, -k * rot.sa * rot.sc, 0.0],
        )
    }

    /// Central difference of the actual tip (µm) in parameter `index` (flat
    /// [`ErrorValues`] index) around `errors`.
    fn parameter_derivative(&self, joints: &Axes, errors: &ErrorValues, index: usize) -> [f64; 3] {
        let mut plus = *errors;
        let mut minus = *errors;
        if let (Some(p), Some(m)) = (plus.slot_mut(index), minus.slot_mut(index)) {
            *p += PARAMETER_STEP;
            *m -= PARAMETER_STEP;
        }
        let tp = self.chain(joints, &plus).tip(self.tool_length);
        let tm = self.chain(joints, &minus).tip(self.tool_length);
        scale(sub(tp, tm), 1e3 / (2.0 * PARAMETER_STEP))
    }

    /// `∂(actual tip, part, µm)/∂(s_xy, s_xz, s_yz µrad)` at `joints` around `errors`:
    /// one row per parameter (the layout of `PointContext::squareness_jacobian`).
    pub fn squareness_jacobian(&self, joints: &Axes, errors: &ErrorValues) -> [[f64; 3]; 3] {
        let mut out = [[0.0; 3]; 3];
        for (row, name) in out.iter_mut().zip(SQUARENESS_NAMES) {
            if let Some(index) = ErrorValues::index_of(name) {
                *row = self.parameter_derivative(joints, errors, index);
            }
        }
        out
    }

    /// `∂(actual tip, part, µm)/∂(location parameter, µm or µrad)` at `joints` around
    /// `errors`, rows in the order of [`LOCATION_PARAMETERS`].
    pub fn location_jacobian(&self, joints: &Axes, errors: &ErrorValues) -> [[f64; 3]; 8] {
        let mut out = [[0.0; 3]; 8];
        for (row, name) in out.iter_mut().zip(LOCATION_PARAMETERS) {
            if let Some(index) = ErrorValues::index_of(name) {
                *row = self.parameter_derivative(joints, errors, index);
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{Geometry, PARAMETER_COUNT, ToolChain};

    fn machine(conventional: bool) -> Kinematics {
        Kinematics {
            geometry: Geometry {
                x_rot_point: -5.0,
                y_rot_point: 10.0,
                z_rot_point: 30.0,
                y_offset: 7.5,
                z_offset: -20.0,
            },
            tool_length: 90.0,
            tool_chain: ToolChain::from_names(&["Y", "X", "Z"]).unwrap(),
            conventional_directions: conventional,
        }
    }

    fn errors() -> ErrorValues {
        let mut e = ErrorValues::ZERO;
        for i in 0..PARAMETER_COUNT {
            if let Some(slot) = e.slot_mut(i) {
                *slot = 200.0 * (((i * 7919) % 13) as f64 - 6.0);
            }
        }
        e
    }

    #[test]
    fn joint_jacobian_matches_central_differences() {
        for conventional in [false, true] {
            let k = machine(conventional);
            let e = errors();
            let j0 = Axes::new(12.0, -40.0, 25.0, -37.0, 123.0);
            let jac = k.tip_jacobian(&j0, &e);
            for col in 0..5 {
                let h = 1e-4;
                let mut p = j0.to_array();
                let mut m = j0.to_array();
                p[col] += h;
                m[col] -= h;
                let tp = k.actual_tip_and_axis(&Axes::from_array(p), &e).tip;
                let tm = k.actual_tip_and_axis(&Axes::from_array(m), &e).tip;
                for row in 0..3 {
                    let fd = (tp[row] - tm[row]) / (2.0 * h);
                    assert!(
                        (fd - jac[row][col]).abs() < 1e-7,
                        "col {col} row {row}: fd {fd} analytic {}",
                        jac[row][col]
                    );
                }
            }
        }
    }

    #[test]
    fn nominal_axis_jacobian_matches_central_differences() {
        for conventional in [false, true] {
            let k = machine(conventional);
            let q = Axes::new(12.0, -40.0, 25.0, -37.0, 123.0);
            let (da, dc) = k.nominal_axis_jacobian(&q);
            let h = 1e-4;
            let diff = |dq: Axes| {
                let plus = k.nominal_tool_axis(&Axes::from_array(std::array::from_fn(|i| {
                    q.to_array()[i] + dq.to_array()[i]
                })));
                let minus = k.nominal_tool_axis(&Axes::from_array(std::array::from_fn(|i| {
                    q.to_array()[i] - dq.to_array()[i]
                })));
                scale(sub(plus, minus), 0.5 / h)
            };
            let (fa, fc) = (
                diff(Axes::new(0.0, 0.0, 0.0, h, 0.0)),
                diff(Axes::new(0.0, 0.0, 0.0, 0.0, h)),
            );
            for i in 0..3 {
                assert!((fa[i] - da[i]).abs() < 1e-10, "a {i}: {fa:?} {da:?}");
                assert!((fc[i] - dc[i]).abs() < 1e-10, "c {i}: {fc:?} {dc:?}");
            }
        }
    }

    #[test]
    fn squareness_derivative_is_first_order_lever() {
        // Only s_xy: the tip moves by −y·s_xy along X in the machine frame (A = C = 0).
        let k = Kinematics::new(Geometry::default(), 100.0);
        let j = Axes::new(10.0, 50.0, -20.0, 0.0, 0.0);
        let d = k.squareness_jacobian(&j, &ErrorValues::ZERO);
        assert!((d[0][0] - (-50.0 * 1e-3)).abs() < 1e-9, "{:?}", d[0]);
        let loc = k.location_jacobian(&j, &ErrorValues::ZERO);
        // EX0C offset of the C axis line moves nothing at C = 0 (the offset and its
        // inverse cancel) and EY0A likewise at A = 0.
        assert!(loc[4].iter().all(|v| v.abs() < 1e-9), "{:?}", loc[4]);
        assert!(loc[0].iter().all(|v| v.abs() < 1e-9), "{:?}", loc[0]);
    }
}
