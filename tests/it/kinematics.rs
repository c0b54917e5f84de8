//! Kinematics: the independent test vectors, and identities (proptest).
use proptest::prelude::*;
use serde::Deserialize;
use std::collections::BTreeMap;
use volcomp::axes::{Axes, Joints};
use volcomp::gcode::Frame;
use volcomp::kinematics::{
    ErrorValues, Geometry, InverseOptions, Kinematics, PARAMETER_COUNT, PARAMETER_NAMES,
    ParameterLayout, ToolChain,
};
use volcomp::toolpath::{joints_of, pose_of};

#[derive(Deserialize)]
struct VectorFile {
    tolerance: Tolerance,
    cases: Vec<Case>,
}

#[derive(Deserialize)]
struct Tolerance {
    e_um: f64,
    axis_urad: f64,
}

#[derive(Deserialize)]
struct Case {
    name: String,
    geometry: Geometry,
    tool_length: f64,
    tool_chain: Vec<String>,
    pose: Axes,
    errors: BTreeMap<String, f64>,
    expected: Expected,
}

#[derive(Deserialize)]
struct Expected {
    e_um: [f64; 3],
    axis_urad: [f64; 3],
}

fn vectors() -> VectorFile {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/vectors/kinematics.json"
    );
    let text = std::fs::read_to_string(path).expect("vector file");
    serde_json::from_str(&text).expect("vector file parses")
}

#[test]
fn every_vector_case_matches() {
    let file = vectors();
    assert_eq!(file.cases.len(), 60);
    assert!(file.tolerance.e_um <= 1e-4 && file.tolerance.axis_urad <= 1e-4);
    let mut failures = Vec::new();
    let mut worst = (0.0f64, 0.0f64);
    for case in &file.cases {
        let kin = Kinematics::xyzac_trt(
            case.geometry,
            ToolChain::from_names(&case.tool_chain).expect("tool chain"),
            false,
            case.tool_length,
        );
        let mut errors = ErrorValues::ZERO;
        for (name, value) in &case.errors {
            errors
                .set(&ParameterLayout::AC, name, *value)
                .expect("known parameter");
        }
        assert_eq!(case.errors.len(), PARAMETER_COUNT, "{}", case.name);
        let got = kin.volumetric_error(&case.pose, &errors);
        let de = (0..3)
            .map(|i| (got.e_um[i] - case.expected.e_um[i]).abs())
            .fold(0.0, f64::max);
        let du = (0..3)
            .map(|i| (got.axis_urad[i] - case.expected.axis_urad[i]).abs())
            .fold(0.0, f64::max);
        worst = (worst.0.max(de), worst.1.max(du));
        if de > file.tolerance.e_um || du > file.tolerance.axis_urad {
            failures.push(format!(
                "{}: e {:?} expected {:?} (|Δ| {de:.3e}); axis {:?} expected {:?} (|Δ| {du:.3e})",
                case.name, got.e_um, case.expected.e_um, got.axis_urad, case.expected.axis_urad
            ));
        }
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases fail:\n{}",
        failures.len(),
        file.cases.len(),
        failures.join("\n")
    );
    eprintln!(
        "worst deviation over all cases: e {:.2e} µm, axis {:.2e} µrad",
        worst.0, worst.1
    );
    // The match is far inside the tolerance, not just inside it.
    assert!(worst.0 < 1e-6 && worst.1 < 1e-6, "worst {worst:?}");
}

fn geometry() -> impl Strategy<Value = Geometry> {
    (
        -50.0..50.0f64,
        -50.0..50.0f64,
        -50.0..50.0f64,
        -40.0..40.0f64,
        -40.0..40.0f64,
    )
        .prop_map(|(x, y, z, yo, zo)| Geometry {
            x_rot_point: x,
            y_rot_point: y,
            z_rot_point: z,
            y_offset: yo,
            z_offset: zo,
        })
}

fn kinematics() -> impl Strategy<Value = Kinematics> {
    (geometry(), 0.0..200.0f64, 0usize..6, any::<bool>()).prop_map(|(g, l, chain, conv)| {
        let orders = [
            ["X", "Y", "Z"],
            ["X", "Z", "Y"],
            ["Y", "X", "Z"],
            ["Y", "Z", "X"],
            ["Z", "X", "Y"],
            ["Z", "Y", "X"],
        ];
        Kinematics::xyzac_trt(
            g,
            ToolChain::from_names(&orders[chain]).expect("permutation"),
            conv,
            l,
        )
    })
}

/// A angles with extra weight near the pole A = 0.
fn a_angle() -> impl Strategy<Value = f64> {
    prop_oneof![-120.0..120.0f64, -1e-6..1e-6f64, Just(0.0)]
}

fn joints() -> impl Strategy<Value = Axes> {
    (
        -300.0..300.0f64,
        -300.0..300.0f64,
        -300.0..300.0f64,
        a_angle(),
        -5000.0..5000.0f64,
    )
        .prop_map(|(x, y, z, a, c)| Axes::xyzac(x, y, z, a, c))
}

fn random_errors() -> impl Strategy<Value = ErrorValues> {
    prop::array::uniform32(-40.0..40.0f64).prop_flat_map(|head| {
        prop::array::uniform16(-40.0..40.0f64).prop_map(move |tail| {
            let mut e = ErrorValues::ZERO;
            for i in 0..PARAMETER_COUNT {
                let v = if i < 32 { head[i] } else { tail[i - 32] };
                e.set(&ParameterLayout::AC, PARAMETER_NAMES[i], v)
                    .expect("known name");
            }
            e
        })
    })
}

fn close(a: [f64; 3], b: [f64; 3], tol: f64) -> bool {
    (0..3).all(|i| (a[i] - b[i]).abs() <= tol)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    /// Part frame → joints → part frame is the identity, and back.
    #[test]
    fn fk_ik_identity_part_frame(kin in kinematics(), j in joints()) {
        let part = pose_of(&kin, Frame::Part, &Joints::new(j));
        prop_assert_eq!(part.frame(), Frame::Part);
        let back = joints_of(&kin, &part);
        prop_assert!(close(back.xyz(), j.xyz(), 1e-9), "{back:?} vs {j:?}");
        prop_assert_eq!((back.a, back.c), (j.a, j.c));
    }

    /// Joints → (tip, tool axis) → joints recovers the joints, choosing the C turn
    /// nearest the previous C; at the pole the pose (not C) is recovered and C is kept.
    #[test]
    fn fk_ik_identity_tool_axis(kin in kinematics(), j in joints(), dc in -89.0..89.0f64) {
        let tip = kin.nominal_tip(&j);
        let axis = kin.nominal_tool_axis(&j);
        let previous = Axes::xyzac(0.0, 0.0, 0.0, j.a, j.c + dc);
        let opts = InverseOptions { previous, limits: [None, None] };
        let back = kin.inverse_tool_axis(tip, axis, &opts).expect("inverse").joints;
        prop_assert!(close(kin.nominal_tip(&back), tip, 1e-9));
        let pole = j.a.to_radians().sin().abs() < volcomp::kinematics::POLE_SIN;
        // At the pole A snaps to 0: the axis moves by at most POLE_SIN.
        let axis_tol = if pole { 2e-9 } else { 1e-12 };
        prop_assert!(close(kin.nominal_tool_axis(&back), axis, axis_tol));
        if pole {
            prop_assert_eq!(back.c, previous.c);
            prop_assert!(back.a.abs() < 1e-6);
        } else {
            prop_assert!((back.a - j.a).abs() < 1e-8, "{back:?} vs {j:?}");
            prop_assert!((back.c - j.c).abs() < 1e-6, "{back:?} vs {j:?}");
            prop_assert!(close(back.xyz(), j.xyz(), 1e-8));
        }
    }

    /// Multi-turn C: the same errors at c and c + 360·k give the same e.
    #[test]
    fn multi_turn_c_is_periodic(kin in kinematics(), j in joints(), e in random_errors(), k in -100i32..100) {
        let turned = Axes { c: j.c + 360.0 * f64::from(k), ..j };
        let a = kin.volumetric_error(&j, &e);
        let b = kin.volumetric_error(&turned, &e);
        prop_assert!(close(a.e_um, b.e_um, 1e-6), "{a:?} vs {b:?}");
        prop_assert!(close(a.axis_urad, b.axis_urad, 1e-6));
    }

    #[test]
    fn zero_errors_give_zero_error(kin in kinematics(), j in joints()) {
        let v = kin.volumetric_error(&j, &ErrorValues::ZERO);
        prop_assert!(close(v.e_um, [0.0; 3], 1e-9), "{v:?}");
        prop_assert!(close(v.axis_urad, [0.0; 3], 1e-9), "{v:?}");
    }

    /// e(αE) ≈ α·e(E) for small α: the model is first order in the errors. The
    /// remainder `e(αE) − α·e(E) = (α² − α)·Q + …` is second order: relative to the
    /// first-order term it is of the order of the angular errors (≤ ~1e-3 here).
    #[test]
    fn first_order_linearity(kin in kinematics(), j in joints(), e in random_errors(), alpha in 0.01..0.2f64) {
        let full = kin.volumetric_error(&j, &e);
        let part = kin.volumetric_error(&j, &e.scaled(alpha));
        let mag = full.magnitude_um().max(10.0);
        let axis_mag = full.axis_urad.iter().map(|v| v.abs()).fold(10.0, f64::max);
        for i in 0..3 {
            prop_assert!((part.e_um[i] - alpha * full.e_um[i]).abs() < 2e-3 * alpha * mag,
                "{i}: {} vs {}", part.e_um[i], alpha * full.e_um[i]);
            prop_assert!((part.axis_urad[i] - alpha * full.axis_urad[i]).abs() < 2e-3 * alpha * axis_mag,
                "{i}: {} vs {}", part.axis_urad[i], alpha * full.axis_urad[i]);
        }
    }
}
