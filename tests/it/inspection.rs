//! Plans and measurements: readers (columns by name, comments, errors that name
//! file, line and column), deviations, profile, atomic writers.
use std::path::Path;
use volcomp::inspection::{InspectionError, Measurement, Plan, profile};

#[test]
fn plan_columns_in_any_order_with_comments_and_extras() {
    let text =
        "# a plan\nk,id,extra,x,y,z,i,j\n\n0,p1,foo,1,2,3,2,0\n# comment\n2,p2,bar,4,5,6,0,0\n";
    let plan = Plan::parse(Path::new("p.csv"), text).unwrap();
    assert_eq!(plan.points.len(), 2);
    assert_eq!(plan.points[0].id, "p1");
    assert_eq!(plan.points[0].normal, [1.0, 0.0, 0.0]);
    assert_eq!(plan.points[1].point, [4.0, 5.0, 6.0]);
    assert_eq!(
        plan.points[1].normal,
        [0.0, 0.0, 1.0],
        "normal is normalised"
    );
}

fn err(text: &str) -> String {
    Plan::parse(Path::new("plan.csv"), text)
        .unwrap_err()
        .to_string()
}

#[test]
fn plan_errors_name_file_line_and_column() {
    let e = err("id,x,y,z,i,j\n1,0,0,0,0,0\n");
    assert!(e.contains("plan.csv:1") && e.contains("`k`"), "{e}");
    let e = err("id,x,y,z,i,j,k\n1,0,0,0,0,0,1\n2,0,abc,0,0,0,1\n");
    assert!(
        e.contains("plan.csv:3") && e.contains("`y`") && e.contains("abc"),
        "{e}"
    );
    let e = err("id,x,y,z,i,j,k\n1,0,0,0,0,0,0\n");
    assert!(e.contains("plan.csv:2") && e.contains("normal"), "{e}");
    let e = err("id,x,y,z,i,j,k\n1,0,0,0,0,0,1\n1,1,0,0,0,0,1\n");
    assert!(e.contains("plan.csv:3") && e.contains("unique"), "{e}");
    let e = err("id,x,y,z,i,j,k\n1,0,0\n");
    assert!(e.contains("plan.csv:2") && e.contains("`z`"), "{e}");
    let e = err("id,x,y,z,i,j,k\n1,0,0,NaN,0,0,1\n");
    assert!(e.contains("finite"), "{e}");
    assert!(matches!(
        Plan::parse(Path::new("plan.csv"), "id,x,y,z,i,j,k\n"),
        Err(InspectionError::Empty { .. })
    ));
    assert!(err("").contains("plan.csv"));
}

#[test]
fn measurement_deviation_and_profile() {
    let text = "id,x,y,z,i,j,k,mx,my,mz\na,0,0,0,0,0,1,0.5,0,0.002\nb,1,0,0,1,0,0,0.999,7,0\n";
    let m = Measurement::parse(Path::new("m.csv"), text).unwrap();
    let d = m.deviations_um();
    approx::assert_abs_diff_eq!(d[0], 2.0, epsilon = 1e-9);
    approx::assert_abs_diff_eq!(d[1], -1.0, epsilon = 1e-9);
    let p = profile(&d);
    approx::assert_abs_diff_eq!(p.profile_um, 4.0, epsilon = 1e-9);
    approx::assert_abs_diff_eq!(p.range_um, 3.0, epsilon = 1e-9);
    assert_eq!(profile(&[]).profile_um, 0.0);
}

#[test]
fn blind_measurements_read_and_round_trip() {
    for case in ["01-backlash", "02-thermal_drift", "03-none"] {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/blind")
            .join(case);
        let m = Measurement::read(&dir.join("measured.csv")).unwrap();
        let plan = Plan::read(&dir.join("plan.csv")).unwrap();
        assert_eq!(m.points.len(), 372);
        assert_eq!(m.plan().points.len(), plan.points.len());
        for (a, b) in m.plan().points.iter().zip(&plan.points) {
            assert_eq!(a.id, b.id);
            for k in 0..3 {
                approx::assert_abs_diff_eq!(a.point[k], b.point[k], epsilon = 1e-12);
                approx::assert_abs_diff_eq!(a.normal[k], b.normal[k], epsilon = 1e-5);
            }
        }
        let d = m.deviations_um();
        assert!(d.iter().all(|v| v.is_finite() && v.abs() < 100.0));
        // Written with 6 decimals and read back: the same deviations (to 1e-3 µm·|n|).
        let tmp = tempfile::tempdir().unwrap();
        let out = tmp.path().join("m.csv");
        m.write(&out).unwrap();
        let back = Measurement::read(&out).unwrap();
        for (x, y) in d.iter().zip(back.deviations_um()) {
            approx::assert_abs_diff_eq!(*x, y, epsilon = 2e-3);
        }
        let plan_out = tmp.path().join("p.csv");
        plan.write(&plan_out).unwrap();
        assert_eq!(Plan::read(&plan_out).unwrap().points.len(), 372);
    }
}

#[test]
fn unreadable_file_is_named() {
    let e = Plan::read(Path::new("/nonexistent/plan.csv"))
        .unwrap_err()
        .to_string();
    assert!(e.contains("/nonexistent/plan.csv"), "{e}");
}
