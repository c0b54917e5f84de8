//! Prediction, end to end: the saddle plan, the compensated saddle, the path
//! report, and agreement with the blind examples' independent predictions.
use crate::compensate::{compensate_text, interpret_options, read, ref_trt};
use crate::support::root;
use volcomp::gcode::Frame;
use volcomp::inspection::Plan;
use volcomp::predict::{PredictReport, predict_path, predict_plan};
use volcomp::toolpath::CutOptions;

/// Round every float of a JSON value to 3 decimals and drop the timing, so the
/// snapshot is deterministic.
pub fn rounded(mut value: serde_json::Value) -> serde_json::Value {
    fn walk(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Number(n) => {
                if let Some(f) = n.as_f64().filter(|_| !n.is_i64() && !n.is_u64()) {
                    let r = (f * 1000.0).round() / 1000.0;
                    // -0.0 and 0.0 snapshot the same.
                    *v = serde_json::json!(if r == 0.0 { 0.0 } else { r });
                }
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(walk),
            serde_json::Value::Object(o) => {
                o.remove("seconds");
                o.values_mut().for_each(walk);
            }
            _ => {}
        }
    }
    walk(&mut value);
    value
}

fn options() -> CutOptions {
    CutOptions::for_machine(&ref_trt().0, Frame::Joint)
}

fn predict_text(text: &str, plan: &Plan) -> PredictReport {
    predict_plan(
        volcomp::gcode::Program::from_text(text, "program.nc"),
        &ref_trt().1,
        plan,
        &options(),
    )
    .expect("predicts")
}

fn saddle_plan() -> Plan {
    Plan::read(&root().join("samples/saddle-plan.csv")).expect("plan")
}

#[test]
fn saddle_prediction_snapshot_and_profile() {
    let report = predict_text(&read("samples/saddle.nc"), &saddle_plan());
    assert_eq!(report.points_total, 372);
    assert_eq!(report.points_cut, 372);
    assert!(report.points.iter().all(|p| p.cut && p.line.is_some()));
    let max = report
        .points
        .iter()
        .filter_map(|p| p.deviation_um)
        .fold(0.0f64, |m, d| m.max(d.abs()));
    approx::assert_relative_eq!(report.profile_um, 2.0 * max, max_relative = 1e-12);
    assert!(report.profile_um > 10.0);
    insta::assert_json_snapshot!(
        "saddle_predict_report",
        rounded(serde_json::to_value(&report).unwrap())
    );
}

#[test]
fn compensated_saddle_profile_with_path_is_under_five_percent() {
    let plan = saddle_plan();
    let original = read("samples/saddle.nc");
    let before = predict_text(&original, &plan);
    let (compensated, _) = compensate_text(&original, Frame::Joint);
    let after = predict_text(&compensated, &plan);
    eprintln!(
        "saddle profile_with_path: original {:.3} µm, compensated {:.4} µm ({:.2}%); profile (n·e only) {:.3} -> {:.3} µm",
        before.profile_with_path_um,
        after.profile_with_path_um,
        100.0 * after.profile_with_path_um / before.profile_with_path_um,
        before.profile_um,
        after.profile_um
    );
    assert_eq!(after.points_cut, 372);
    assert!(after.profile_with_path_um < 0.05 * before.profile_with_path_um);
}

/// What the part measures is taken where the ball touches, so the tool's tilt
/// acts on the ball's radius (`R·δu`): compensating the tool axis too (the
/// default) leaves less than the tip alone, which leaves that tilt.
#[test]
fn correcting_the_tool_axis_leaves_less_on_the_saddle_than_the_tip_alone() {
    let plan = saddle_plan();
    let original = read("samples/saddle.nc");
    let (tip_only, _) = compensate_text(&original, Frame::Joint);
    let (full, _) = crate::compensate::compensate_with(&original, Frame::Joint, 0.5, true);
    let tip_only = predict_text(&tip_only, &plan);
    let full = predict_text(&full, &plan);
    eprintln!(
        "saddle profile_with_path: tip only {:.3} µm, tip and axis {:.3} µm",
        tip_only.profile_with_path_um, full.profile_with_path_um
    );
    assert!(
        full.profile_with_path_um < 0.3,
        "{}",
        full.profile_with_path_um
    );
    assert!(
        tip_only.profile_with_path_um > 0.6,
        "{}",
        tip_only.profile_with_path_um
    );
}

#[test]
fn prediction_without_plan_lists_every_motion_block() {
    let text = read("tests/data/compensate/linuxcnc-demo.ngc");
    let report = predict_path(
        volcomp::gcode::Program::from_text(&text, "demo.ngc"),
        &ref_trt().1,
        &options(),
    )
    .expect("predicts");
    // The motion lines of the demo, from the interpreter.
    let mut reader = volcomp::gcode::BlockReader::new(text.as_bytes(), Default::default());
    let mut interpreter = volcomp::gcode::Interpreter::new(interpret_options(Frame::Joint));
    let mut lines = Vec::new();
    while let Some(block) = reader.next_block() {
        let event = interpreter.interpret(block.unwrap()).unwrap();
        if event.motion().is_some() {
            lines.push(event.line);
        }
    }
    let reported: Vec<usize> = report.blocks.iter().map(|b| b.line).collect();
    assert_eq!(reported, lines);
    assert!(report.blocks.iter().all(|b| b.norm_um.is_finite()));
    let max = report.blocks.iter().fold(0.0f64, |m, b| m.max(b.norm_um));
    approx::assert_relative_eq!(report.max_error_um, max, max_relative = 1e-12);
}

/// `seconds` differs from run to run: fixed for comparisons.
fn without_seconds(json: &str) -> String {
    json.lines()
        .map(|l| {
            if l.trim_start().starts_with("\"seconds\":") {
                "  \"seconds\": 0.0,"
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n")
}

/// Issue 25: without a plan the report is written while the program runs
/// (memory flat with program length), and it is the same JSON as serialising
/// the whole report: the same fields in the same order, byte for byte, with
/// rows, without any (no `blocks` field), and with a compensated program's
/// stamp.
#[test]
fn the_streamed_path_report_is_the_collected_one() {
    use volcomp::predict::{PathErrors, PathReportStream};
    let model = &ref_trt().1;
    let demo = read("tests/data/compensate/linuxcnc-demo.ngc");
    let (compensated, _) = compensate_text(&demo, Frame::Joint);
    // What `volcomp compensate` would have stamped it with.
    let stamp = Some(volcomp::stamp::Stamp {
        compensated_by: "volcomp 0.1.0".into(),
        machine: "ref-trt".into(),
        model_fnv1a64: "0123456789abcdef".into(),
        model_source: "fit cv".into(),
        tool_length_mm: Some(100.0),
        tools_mm: String::new(),
        tolerance_um: Some(0.5),
        input: "demo.ngc".into(),
        input_fnv1a64: "fedcba9876543210".into(),
        orientation: true,
    });
    let no_motion = "G21 G90\nM30\n".to_string();
    for (text, stamp) in [(&demo, None), (&compensated, stamp), (&no_motion, None)] {
        let program = || volcomp::gcode::Program::from_text(text, "demo.ngc");
        let mut whole = predict_path(program(), model, &options()).expect("predicts");
        whole.compensated = stamp.is_some();
        whole.stamp = stamp.clone();
        let stream = PathReportStream::new(PathErrors::new(program(), model, &options()), stamp);
        let streamed = serde_json::to_string_pretty(&stream).expect("streams");
        assert!(stream.failure().is_none());
        assert_eq!(
            without_seconds(&streamed),
            without_seconds(&serde_json::to_string_pretty(&whole).unwrap())
        );
        assert_eq!(stream.summary().rows, whole.blocks.len());
        assert_eq!(streamed.contains("\"blocks\""), !whole.blocks.is_empty());
        let report = stream.report();
        assert_eq!(report.max_error_um, whole.max_error_um);
        assert_eq!(report.rms_error_um, whole.rms_error_um);
    }
}

/// A prediction that fails half way (a move outside a table) writes no
/// report: the streamed file is a temporary one until the end.
#[test]
fn a_failing_streamed_report_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("out.nc");
    std::fs::write(
        &program,
        "G21 G90 G94\nG1 X0 Y0 Z0 A0 C0 F500\nG1 X10\nG1 X900\nM30\n",
    )
    .unwrap();
    let report = dir.path().join("report.json");
    let out = crate::support::volcomp()
        .arg("predict")
        .arg(root().join("machines/ref-trt.toml"))
        .arg(&program)
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("out.nc:4") && stderr.contains("outside"),
        "{stderr}"
    );
    assert!(!report.exists());
    let left: Vec<_> = std::fs::read_dir(dir.path()).unwrap().flatten().collect();
    assert_eq!(left.len(), 1, "only the program remains: {left:?}");
}

/// Our deviations (tables fitted as SMEM curves) against the blind examples'
/// `expected_predicted.csv` (an independent implementation with the TRUE error
/// functions): they differ by the table noise and the fit error only.
#[test]
fn blind_examples_agree_with_the_independent_prediction() {
    let mut all = Vec::new();
    for case in ["01-backlash", "02-thermal_drift", "03-none"] {
        let dir = root().join("tests/data/blind").join(case);
        let plan = Plan::read(&dir.join("plan.csv")).unwrap();
        let report = predict_text(
            &std::fs::read_to_string(dir.join("program.nc")).unwrap(),
            &plan,
        );
        let expected = std::fs::read_to_string(dir.join("expected_predicted.csv")).unwrap();
        let mut diffs = Vec::new();
        let (mut within_one_u, mut within_two_u) = (0usize, 0usize);
        for (line, point) in expected.lines().skip(1).zip(&report.points) {
            let (id, value) = line.split_once(',').unwrap();
            assert_eq!(id, point.id);
            let want: f64 = value.parse().unwrap();
            let got = point.deviation_um.expect("cut");
            diffs.push(got - want);
            let u = point
                .deviation_u_um
                .expect("the fitted model carries uncertainties");
            within_one_u += usize::from((got - want).abs() <= u);
            within_two_u += usize::from((got - want).abs() <= 2.0 * u);
        }
        // The reported uncertainty is calibrated: about 68 % of the true
        // deviations lie within one standard uncertainty (measured 66–70 %).
        let share = within_one_u as f64 / diffs.len() as f64;
        assert!((0.55..0.85).contains(&share), "{case}: {share} within 1 u");
        assert_eq!(diffs.len(), 372);
        let rms = (diffs.iter().map(|d| d * d).sum::<f64>() / diffs.len() as f64).sqrt();
        let max = diffs.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        eprintln!(
            "blind {case}: RMS difference {rms:.4} µm, max {max:.4} µm; within 1 u {:.0} %, within 2 u {:.0} %",
            100.0 * share,
            100.0 * within_two_u as f64 / diffs.len() as f64
        );
        all.extend(diffs);
    }
    let rms = (all.iter().map(|d| d * d).sum::<f64>() / all.len() as f64).sqrt();
    let max = all.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    eprintln!("blind all: RMS difference {rms:.4} µm, max {max:.4} µm");
    // Measured with the default (cross-validated) model: RMS 0.276 µm, max
    // 0.651 µm over the 3 × 372 points (--fit-select emax: 0.265 / 0.741).
    assert!(rms < 0.3, "RMS {rms}");
    assert!(max < 0.75, "max {max}");
}
