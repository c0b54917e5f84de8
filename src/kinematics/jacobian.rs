//! Jacobians of the actual tool tip (part coordinates).
//!
//! * [`Kinematics::tip_jacobian`]: with respect to the joints, analytic, with the
//!   error values held fixed (the tables' own slope, of the order of 1 µm per 100 mm,
//!   changes the result by about 1e-5 relative, which compensation iterations absorb).
//! * [`Kinematics::squareness_jacobian`] and [`Kinematics::location_jacobian`]: with
//!   respect to the position-independent parameters, by central differences (see
//!   [`PARAMETER_STEP`] for the step).
use super::Kinematics;
use super::chain::ChainConstants;
use super::error_values::{COMPONENT_COUNT, ErrorValues, ParameterLayout, SQUARENESS_NAMES};
use super::transform::{scale, sub};
use crate::axes::{Axes, Axis};

/// Names of the squareness parameters, in the order of
/// [`Kinematics::squareness_jacobian`](super::Kinematics::squareness_jacobian)'s rows.
pub const SQUARENESS_PARAMETERS: [&str; 3] = SQUARENESS_NAMES;
/// Names of the rotary location parameters of an A/C machine (the
/// `rotary_location` effect), in the order of the location Jacobian's rows; a
/// machine's own are [`ParameterLayout::location_effect_names`].
pub const LOCATION_PARAMETERS: [&str; 8] = ParameterLayout::AC.location_effect_names();

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
    /// `∂(actual tool tip, part, mm) / ∂(x, y, z mm; r₁, r₂ degrees)` at `joints` with
    /// the error values `errors` held fixed: `J[row = tip x y z][column = joint slot]`.
    /// Pass [`ErrorValues::ZERO`] for the nominal Jacobian.
    pub fn tip_jacobian(&self, joints: &Axes, errors: &ErrorValues) -> [[f64; 5]; 3] {
        self.tip_jacobian_of(&self.pose(joints, errors))
    }

    /// [`Kinematics::tip_jacobian`] with the [`ChainConstants`] of the values'
    /// squareness and location computed beforehand: the same numbers.
    pub fn tip_jacobian_with(
        &self,
        joints: &Axes,
        errors: &ErrorValues,
        constants: &ChainConstants,
    ) -> [[f64; 5]; 3] {
        let pose = super::chain::ChainPose::with_constants(
            &self.chain,
            self.tool_length,
            joints,
            errors,
            constants,
        );
        self.tip_jacobian_of(&pose)
    }

    /// The tip Jacobian of an evaluated pose.
    fn tip_jacobian_of(&self, pose: &super::chain::ChainPose<'_>) -> [[f64; 5]; 3] {
        let [r1, r2] = self.rotary();
        let columns = [Axis::X, Axis::Y, Axis::Z, r1, r2].map(|a| pose.tip_derivative(a));
        let mut out = [[0.0; 5]; 3];
        for (j, col) in columns.iter().enumerate() {
            for (i, row) in out.iter_mut().enumerate() {
                row[j] = col[i];
            }
        }
        out
    }

    /// `∂(nominal tool axis)/∂r₁` and `∂/∂r₂` (per degree) at `joints`.
    pub fn nominal_axis_jacobian(&self, joints: &Axes) -> ([f64; 3], [f64; 3]) {
        let [d1, d2] = super::chain::nominal_axis_derivatives(&self.chain, joints);
        (d1, d2)
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
        let tp = self.actual_tip_and_axis(joints, &plus).tip;
        let tm = self.actual_tip_and_axis(joints, &minus).tip;
        scale(sub(tp, tm), 1e3 / (2.0 * PARAMETER_STEP))
    }

    /// `∂(actual tip, part, µm)/∂(s_xy, s_xz, s_yz µrad)` at `joints` around `errors`:
    /// one row per parameter (the layout of `PointContext::squareness_jacobian`).
    pub fn squareness_jacobian(&self, joints: &Axes, errors: &ErrorValues) -> [[f64; 3]; 3] {
        let mut out = [[0.0; 3]; 3];
        for (s, row) in out.iter_mut().enumerate() {
            *row = self.parameter_derivative(joints, errors, COMPONENT_COUNT + s);
        }
        out
    }

    /// `∂(actual tip, part, µm)/∂(location parameter, µm or µrad)` at `joints` around
    /// `errors`, rows in the order of the machine's
    /// [`ParameterLayout::location_effect_names`].
    pub fn location_jacobian(&self, joints: &Axes, errors: &ErrorValues) -> [[f64; 3]; 8] {
        let mut out = [[0.0; 3]; 8];
        for (row, index) in out.iter_mut().zip(ParameterLayout::LOCATION_EFFECT_INDICES) {
            *row = self.parameter_derivative(joints, errors, index);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::{Geometry, PARAMETER_COUNT, ToolChain};

    fn machine(conventional: bool) -> Kinematics {
        Kinematics::xyzac_trt(
            Geometry {
                x_rot_point: -5.0,
                y_rot_point: 10.0,
                z_rot_point: 30.0,
                y_offset: 7.5,
                z_offset: -20.0,
            },
            ToolChain::from_names(&["Y", "X", "Z"]).unwrap(),
            conventional,
            90.0,
        )
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
            let j0 = Axes::xyzac(12.0, -40.0, 25.0, -37.0, 123.0);
            let jac = k.tip_jacobian(&j0, &e);
            for col in 0..5 {
                let h = 1e-4;
                let mut p = k.joints(&j0);
                let mut m = k.joints(&j0);
                p[col] += h;
                m[col] -= h;
                let tp = k.actual_tip_and_axis(&k.with_joints(&j0, p), &e).tip;
                let tm = k.actual_tip_and_axis(&k.with_joints(&j0, m), &e).tip;
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
            let q = Axes::xyzac(12.0, -40.0, 25.0, -37.0, 123.0);
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
                diff(Axes::xyzac(0.0, 0.0, 0.0, h, 0.0)),
                diff(Axes::xyzac(0.0, 0.0, 0.0, 0.0, h)),
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
        let j = Axes::xyzac(10.0, 50.0, -20.0, 0.0, 0.0);
        let d = k.squareness_jacobian(&j, &ErrorValues::ZERO);
        assert!((d[0][0] - (-50.0 * 1e-3)).abs() < 1e-9, "{:?}", d[0]);
        let loc = k.location_jacobian(&j, &ErrorValues::ZERO);
        // EX0C offset of the C axis line moves nothing at C = 0 (the offset and its
        // inverse cancel) and EY0A likewise at A = 0.
        assert!(loc[4].iter().all(|v| v.abs() < 1e-9), "{:?}", loc[4]);
        assert!(loc[0].iter().all(|v| v.abs() < 1e-9), "{:?}", loc[0]);
    }
}
