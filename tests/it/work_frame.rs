//! Plans and measurements in work coordinates (`--plan-frame work`): the
//! saddle (tool-tip control, G43.4) cut under a G54 offset, its plan given in the program's coordinates,
//! predicts and simulates exactly as the same plan moved into part coordinates;
//! `predict --csv` writes the plan's own coordinates with the predictions.
use crate::support::{assert_success, root, volcomp};
use std::path::Path;

const OFFSET: [f64; 3] = [10.0, 20.0, -5.0];

/// The saddle plan moved by the work offset (part coordinates of the same points).
fn shifted_plan(dir: &Path) -> std::path::PathBuf {
    let text = std::fs::read_to_string(root().join("samples/saddle-plan.csv")).unwrap();
    let mut out = String::from("id,x,y,z,i,j,k\n");
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let v = |k: usize| f[k].parse::<f64>().unwrap();
        out.push_str(&format!(
            "{},{},{},{},{},{},{}\n",
            f[0],
            v(1) + OFFSET[0],
            v(2) + OFFSET[1],
            v(3) + OFFSET[2],
            f[4],
            f[5],
            f[6]
        ));
    }
    let path = dir.join("shifted-plan.csv");
    std::fs::write(&path, out).unwrap();
    path
}

fn predict(dir: &Path, plan: &Path, work: bool, name: &str) -> serde_json::Value {
    let mut cmd = volcomp();
    cmd.arg("predict")
        .arg(root().join("machines/ref-trt.toml"))
        .arg(root().join("samples/saddle-tcp.nc"))
        .arg("--plan")
        .arg(plan)
        .args(["--offset", "G54=10,20,-5", "--tools"])
        .arg(root().join("samples/saddle.tbl"))
        .arg("--report")
        .arg(dir.join(format!("{name}.json")))
        .arg("--csv")
        .arg(dir.join(format!("{name}.csv")));
    if work {
        cmd.args(["--plan-frame", "work"]);
    }
    let out = cmd.output().unwrap();
    assert_success(&out);
    serde_json::from_str(&std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap())
        .unwrap()
}

#[test]
fn a_plan_in_work_coordinates_predicts_as_in_part_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let plan = root().join("samples/saddle-plan.csv");
    let work = predict(dir.path(), &plan, true, "work");
    let part = predict(dir.path(), &shifted_plan(dir.path()), false, "part");
    let (a, b) = (
        work["points"].as_array().unwrap(),
        part["points"].as_array().unwrap(),
    );
    assert_eq!(a.len(), 372);
    assert!(work["points_cut"].as_u64().unwrap() > 300);
    for (p, q) in a.iter().zip(b) {
        assert_eq!(p["id"], q["id"]);
        assert_eq!(p["cut"], q["cut"]);
        if let (Some(x), Some(y)) = (p["deviation_um"].as_f64(), q["deviation_um"].as_f64()) {
            assert!((x - y).abs() < 1e-9, "{}: {x} vs {y}", p["id"]);
        }
    }
    // The CSV: the plan's own coordinates, then the prediction.
    let csv = std::fs::read_to_string(dir.path().join("work.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("id,x,y,z,i,j,k,deviation_um,u_um,line,tool")
    );
    let first: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(first.len(), 11);
    assert_eq!(&first[..4], ["1", "-45", "-33", "28.945"]);
    let d: f64 = first[7].parse().unwrap();
    assert!((d - a[0]["deviation_um"].as_f64().unwrap()).abs() < 1e-4);
    assert!(first[9].parse::<usize>().is_ok(), "line: {}", first[9]);
    assert_eq!(first[10], "1");
}

#[test]
fn simulate_writes_a_work_plan_back_in_work_coordinates() {
    let dir = tempfile::tempdir().unwrap();
    let run = |plan: &Path, work: bool, out: &str| {
        let mut cmd = volcomp();
        cmd.arg("simulate")
            .arg(root().join("machines/ref-trt.toml"))
            .arg(root().join("samples/saddle-tcp.nc"))
            .arg(plan)
            .arg("-o")
            .arg(dir.path().join(out))
            .args(["--offset", "G54=10,20,-5", "--seed", "3", "--tools"])
            .arg(root().join("samples/saddle.tbl"));
        if work {
            cmd.args(["--plan-frame", "work"]);
        }
        assert_success(&cmd.output().unwrap());
        volcomp::inspection::Measurement::read(&dir.path().join(out)).unwrap()
    };
    let work = run(&root().join("samples/saddle-plan.csv"), true, "work.csv");
    let part = run(&shifted_plan(dir.path()), false, "part.csv");
    let plan = volcomp::inspection::Plan::read(&root().join("samples/saddle-plan.csv")).unwrap();
    for ((w, p), given) in work.points.iter().zip(&part.points).zip(&plan.points) {
        assert!((w.deviation_um() - p.deviation_um()).abs() < 1e-6);
        for (k, offset) in OFFSET.iter().enumerate() {
            assert!((w.plan.point[k] - given.point[k]).abs() < 1e-9);
            assert!((w.measured[k] + offset - p.measured[k]).abs() < 1e-9);
        }
    }
    // diagnose reads the work-frame measurement back.
    let out = volcomp()
        .arg("diagnose")
        .arg(root().join("machines/ref-trt.toml"))
        .arg(root().join("samples/saddle-tcp.nc"))
        .arg(dir.path().join("work.csv"))
        .args([
            "--offset",
            "G54=10,20,-5",
            "--plan-frame",
            "work",
            "--tools",
        ])
        .arg(root().join("samples/saddle.tbl"))
        .arg("--report")
        .arg(dir.path().join("diag.json"))
        .output()
        .unwrap();
    assert_success(&out);
}
