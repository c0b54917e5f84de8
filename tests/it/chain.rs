//! Any five-axis machine (kinematics.md "Any five-axis machine"): the independent
//! chain vectors, the equivalence of the presets with their chains, and the
//! identities of the generic engine (FK∘IK, Jacobians) on every public layout.
use proptest::prelude::*;
use proptest::strategy::ValueTree;
use serde::Deserialize;
use std::collections::BTreeMap;
use volcomp::axes::{Axes, Axis, Joints};
use volcomp::gcode::Frame;
use volcomp::kinematics::{
    ChainAxis, ChainConstants, ErrorValues, Geometry, InverseOptions, Kinematics, MachineChain,
    PARAMETER_COUNT, ParameterLayout, ToolChain,
};
use volcomp::toolpath::joints_of;

#[derive(Deserialize)]
struct ChainFile {
    tolerance: Tolerance,
    cases: Vec<ChainCase>,
}

#[derive(Deserialize)]
struct Tolerance {
    e_um: f64,
    axis_urad: f64,
}

#[derive(Deserialize, Clone)]
struct ChainCase {
    name: String,
    machine: String,
    chain: ChainDescription,
    pose: BTreeMap<String, f64>,
    errors: BTreeMap<String, f64>,
    expected: Expected,
}

#[derive(Deserialize, Clone)]
struct ChainDescription {
    workpiece_side: Vec<String>,
    tool_side: Vec<String>,
    tool_axis: [f64; 3],
    axes: BTreeMap<String, AxisDescription>,
    tool_length: f64,
}

#[derive(Deserialize, Clone)]
struct AxisDescription {
    direction: [f64; 3],
    point: Option<[f64; 3]>,
}

#[derive(Deserialize, Clone)]
struct Expected {
    e_um: [f64; 3],
    axis_urad: [f64; 3],
}

fn chain_file() -> ChainFile {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/vectors/chain.json");
    let text = std::fs::read_to_string(path).expect("chain vector file");
    serde_json::from_str(&text).expect("chain vector file parses")
}

fn letter(name: &str) -> Axis {
    Axis::from_letter(name.chars().next().expect("letter")).expect("axis letter")
}

/// The engine's machine of a vector case.
fn kinematics_of(d: &ChainDescription) -> Kinematics {
    let axis = |name: &String| {
        let a = &d.axes[name];
        let l = letter(name);
        match a.point {
            Some(p) => ChainAxis::rotary(l, a.direction, p),
            None => ChainAxis::linear(l, a.direction),
        }
    };
    let work: Vec<ChainAxis> = d.workpiece_side.iter().map(axis).collect();
    let tool: Vec<ChainAxis> = d.tool_side.iter().map(axis).collect();
    let chain = MachineChain::new(&work, &tool, d.tool_axis).expect("valid chain");
    Kinematics::from_chain(chain, d.tool_length)
}

fn pose_of(case: &ChainCase) -> Axes {
    let mut q = Axes::default();
    for (name, v) in &case.pose {
        q.set(letter(name), *v);
    }
    q
}

fn errors_of(kin: &Kinematics, case: &ChainCase) -> ErrorValues {
    let layout = kin.layout();
    let mut e = ErrorValues::ZERO;
    for (name, v) in &case.errors {
        e.set(&layout, name, *v)
            .unwrap_or_else(|err| panic!("{}: {err}", case.name));
    }
    assert_eq!(case.errors.len(), PARAMETER_COUNT, "{}", case.name);
    e
}

#[test]
fn every_chain_vector_matches() {
    let file = chain_file();
    assert_eq!(file.cases.len(), 75);
    assert!(file.tolerance.e_um <= 1e-4 && file.tolerance.axis_urad <= 1e-4);
    let mut failures = Vec::new();
    let mut worst: BTreeMap<String, (f64, f64, usize)> = BTreeMap::new();
    for case in &file.cases {
        let kin = kinematics_of(&case.chain);
        let got = kin.volumetric_error(&pose_of(case), &errors_of(&kin, case));
        let de = (0..3)
            .map(|i| (got.e_um[i] - case.expected.e_um[i]).abs())
            .fold(0.0, f64::max);
        let du = (0..3)
            .map(|i| (got.axis_urad[i] - case.expected.axis_urad[i]).abs())
            .fold(0.0, f64::max);
        let w = worst.entry(case.machine.clone()).or_default();
        *w = (w.0.max(de), w.1.max(du), w.2 + 1);
        if de > file.tolerance.e_um || du > file.tolerance.axis_urad {
            failures.push(format!(
                "{}: e {:?} expected {:?} (|Δ| {de:.3e}); axis {:?} expected {:?} (|Δ| {du:.3e})",
                case.name, got.e_um, case.expected.e_um, got.axis_urad, case.expected.axis_urad
            ));
        }
    }
    for (machine, (de, du, n)) in &worst {
        eprintln!("{machine}: {n} cases, worst |Δe| {de:.2e} µm, |Δaxis| {du:.2e} µrad");
    }
    assert!(
        failures.is_empty(),
        "{} of {} cases fail:\n{}",
        failures.len(),
        file.cases.len(),
        failures.join("\n")
    );
    for (de, du, _) in worst.values() {
        assert!(*de < 1e-6 && *du < 1e-6, "{worst:?}");
    }
}

/// The A/C preset and the chain that describes the same machine give the same
/// numbers (kinematics.md "Equivalence"), and so do B/C.
#[test]
fn presets_equal_their_chains() {
    let g = Geometry {
        x_rot_point: 3.0,
        y_rot_point: -7.0,
        z_rot_point: 12.0,
        y_offset: 15.0,
        z_offset: -22.0,
    };
    let order = ToolChain::from_names(&["Y", "X", "Z"]).unwrap();
    let preset = Kinematics::xyzac_trt(g, order, false, 87.0);
    let linear = |a: Axis, d: [f64; 3]| ChainAxis::linear(a, d);
    let chain = MachineChain::new(
        &[
            ChainAxis::rotary(Axis::A, [1.0, 0.0, 0.0], g.a_point()),
            ChainAxis::rotary(Axis::C, [0.0, 0.0, 1.0], g.c_point()),
        ],
        &[
            linear(Axis::Y, [0.0, 1.0, 0.0]),
            linear(Axis::X, [1.0, 0.0, 0.0]),
            linear(Axis::Z, [0.0, 0.0, 1.0]),
        ],
        [0.0, 0.0, 1.0],
    )
    .unwrap();
    let described = Kinematics::from_chain(chain, 87.0);
    let mut runner = proptest::test_runner::TestRunner::deterministic();
    for _ in 0..200 {
        let (j, e) = (joints_ac(), errors())
            .new_tree(&mut runner)
            .unwrap()
            .current();
        let a = preset.volumetric_error(&j, &e);
        let b = described.volumetric_error(&j, &e);
        for k in 0..3 {
            assert!((a.e_um[k] - b.e_um[k]).abs() < 1e-9, "{a:?} {b:?}");
            assert!(
                (a.axis_urad[k] - b.axis_urad[k]).abs() < 1e-9,
                "{a:?} {b:?}"
            );
        }
    }
}

fn joints_ac() -> impl Strategy<Value = Axes> {
    (
        -300.0..300.0f64,
        -300.0..300.0f64,
        -300.0..300.0f64,
        -120.0..120.0f64,
        -720.0..720.0f64,
    )
        .prop_map(|(x, y, z, a, c)| Axes::xyzac(x, y, z, a, c))
}

fn errors() -> impl Strategy<Value = ErrorValues> {
    prop::collection::vec(-40.0..40.0f64, PARAMETER_COUNT).prop_map(|v| {
        let mut e = ErrorValues::ZERO;
        for (i, x) in v.into_iter().enumerate() {
            if let Some(slot) = e.slot_mut(i) {
                *slot = x;
            }
        }
        e
    })
}

/// The three public layouts of chain.json (one case each).
fn public_machines() -> Vec<(String, Kinematics)> {
    let mut seen = BTreeMap::new();
    for case in chain_file().cases {
        seen.entry(case.machine.clone())
            .or_insert_with(|| kinematics_of(&case.chain));
    }
    seen.into_iter().collect()
}

/// A pose of `kin` with both rotary joints in a working range away from the
/// pole (the outer joint then matters).
fn pose(kin: &Kinematics, v: [f64; 5]) -> Axes {
    kin.with_joints(&Axes::default(), v)
}

fn pose_values() -> impl Strategy<Value = [f64; 5]> {
    (
        -200.0..200.0f64,
        -200.0..200.0f64,
        -200.0..200.0f64,
        -100.0..100.0f64,
        -100.0..100.0f64,
    )
        .prop_map(|(x, y, z, r1, r2)| [x, y, z, r1, r2])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Joints → part-frame target → joints, on every public layout.
    #[test]
    fn fk_ik_identity_part_frame_any_chain(v in pose_values(), which in 0usize..3) {
        let (_, kin) = &public_machines()[which];
        let j = pose(kin, v);
        let part = volcomp::toolpath::pose_of(kin, Frame::Part, &Joints::new(j));
        let back = joints_of(kin, &part);
        for (a, b) in back.to_array().iter().zip(j.to_array()) {
            prop_assert!((a - b).abs() < 1e-9, "{back:?} vs {j:?}");
        }
    }

    /// Joints → (tip, tool axis) → joints: the inverse finds a solution with the
    /// same tip and axis, and the original joints when started near them.
    #[test]
    fn fk_ik_identity_tool_axis_any_chain(v in pose_values(), which in 0usize..3, d in -20.0..20.0f64) {
        let (name, kin) = &public_machines()[which];
        let j = pose(kin, v);
        let tip = kin.nominal_tip(&j);
        let axis = kin.nominal_tool_axis(&j);
        let [r1, r2] = kin.rotary();
        let mut previous = j;
        previous.set(r1, j.get(r1) + d);
        previous.set(r2, j.get(r2) - d);
        let s = kin
            .inverse_tool_axis(tip, axis, &InverseOptions { previous, limits: [None, None] })
            .expect("inverse");
        let back = s.joints;
        let t = kin.nominal_tip(&back);
        let u = kin.nominal_tool_axis(&back);
        for k in 0..3 {
            prop_assert!((t[k] - tip[k]).abs() < 1e-8, "{name}: tip {t:?} vs {tip:?}");
            prop_assert!((u[k] - axis[k]).abs() < 1e-9, "{name}: axis {u:?} vs {axis:?}");
        }
        if kin.pole_angle_deg(&j) > 1.0 {
            // Started within 20° of the original, the nearest solution is it.
            for (a, b) in kin.joints(&back).iter().zip(kin.joints(&j)) {
                prop_assert!((a - b).abs() < 1e-6, "{name}: {back:?} vs {j:?}");
            }
        }
    }

    /// The analytic tip and axis Jacobians against central differences, with
    /// errors, on every public layout.
    #[test]
    fn jacobians_match_differences_any_chain(v in pose_values(), which in 0usize..3, e in errors()) {
        let (name, kin) = &public_machines()[which];
        let j = pose(kin, v);
        let jac = kin.tip_jacobian(&j, &e);
        let (u1, u2) = kin.nominal_axis_jacobian(&j);
        let h = 1e-4;
        for col in 0..5 {
            let mut p = kin.joints(&j);
            let mut m = kin.joints(&j);
            p[col] += h;
            m[col] -= h;
            let (qp, qm) = (kin.with_joints(&j, p), kin.with_joints(&j, m));
            let tp = kin.actual_tip_and_axis(&qp, &e).tip;
            let tm = kin.actual_tip_and_axis(&qm, &e).tip;
            for row in 0..3 {
                let fd = (tp[row] - tm[row]) / (2.0 * h);
                prop_assert!((fd - jac[row][col]).abs() < 1e-6, "{name} col {col} row {row}: {fd} vs {}", jac[row][col]);
            }
            if col >= 3 {
                let ap = kin.nominal_tool_axis(&qp);
                let am = kin.nominal_tool_axis(&qm);
                let want = if col == 3 { u1 } else { u2 };
                for row in 0..3 {
                    let fd = (ap[row] - am[row]) / (2.0 * h);
                    prop_assert!((fd - want[row]).abs() < 1e-8, "{name} axis col {col}: {fd} vs {}", want[row]);
                }
            }
        }
    }

    /// The actual tip and axis with a model's precomputed chain constants are
    /// the general evaluation's numbers, bit for bit (constants made for other
    /// values are not used), on every public layout.
    #[test]
    fn chain_constants_give_the_same_bits_any_chain(v in pose_values(), which in 0usize..3, e in errors(), other in errors()) {
        let (name, kin) = &public_machines()[which];
        let j = pose(kin, v);
        let want = kin.actual_tip_and_axis(&j, &e);
        let bits = |t: &volcomp::kinematics::TipAndAxis| [t.tip, t.axis].map(|v| v.map(f64::to_bits));
        for made_for in [&e, &other] {
            let constants = ChainConstants::new(&kin.chain, made_for);
            let got = kin.actual_tip_and_axis_with(&j, &e, &constants);
            prop_assert_eq!(bits(&got), bits(&want), "{}", name);
        }
    }

    /// e is zero without errors, on every layout.
    #[test]
    fn zero_errors_give_zero_error_any_chain(v in pose_values(), which in 0usize..3) {
        let (_, kin) = &public_machines()[which];
        let e = kin.volumetric_error(&pose(kin, v), &ErrorValues::ZERO);
        prop_assert!(e.magnitude_um() < 1e-9 && e.axis_urad.iter().all(|u| u.abs() < 1e-9));
    }
}

/// The names follow the machine's letters.
#[test]
fn parameter_names_follow_the_rotary_letters() {
    let machines = public_machines();
    let bc = &machines[0].1;
    assert_eq!(bc.rotary(), [Axis::B, Axis::C]);
    let layout = bc.layout();
    assert_eq!(layout.component_names(3)[0], "EXB");
    assert_eq!(
        layout.location_effect_names()[..4],
        ["EX0B", "EZ0B", "EA0B", "EC0B"]
    );
    assert!(layout.index_of("EXA").is_none());
    assert_eq!(ParameterLayout::AC.index_of("EXA"), Some(18));
}
