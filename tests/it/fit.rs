//! `volcomp fit` and the error-table reader.
use crate::support::root;
use std::path::Path;

use volcomp::axes::Axis;
use volcomp::machine::ErrorTable;

use crate::support::volcomp;

/// The default fit (`--select cv`) of the reference machine: the printed table
/// (timing removed, rounded) is stable, C curves are periodic, and the report
/// carries each parameter's noise, dof, cross-validated error and uncertainty.
#[test]
fn reference_machine_fits_by_cross_validation() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("fit.json");
    let out = volcomp()
        .arg("fit")
        .arg(root().join("machines/ref-trt.toml"))
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(out.status.success(), "{stdout}");
    let rows: Vec<String> = stdout
        .lines()
        .filter(|l| l.split_whitespace().count() == 11 && !l.starts_with("axis"))
        .map(|line| {
            let f: Vec<&str> = line.split_whitespace().collect();
            let round = |s: &str, d: usize| format!("{:.*}", d, s.parse::<f64>().unwrap());
            format!(
                "{} {} samples={} ctrl={} dof={} noise={} cv={} emax={} {} periodic={}",
                f[0],
                f[1],
                f[2],
                f[3],
                round(f[4], 1),
                round(f[5], 2),
                round(f[6], 2),
                round(f[7], 2),
                f[8],
                f[9]
            )
        })
        .collect();
    assert_eq!(rows.len(), 30, "{stdout}");
    for r in &rows {
        assert_eq!(r.starts_with("C "), r.ends_with("periodic=yes"), "{r}");
    }
    insta::assert_snapshot!(rows.join("\n"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    for p in json["parameters"].as_array().unwrap() {
        let stats = |k: &str| p[k].as_f64().unwrap_or_else(|| panic!("report lacks {k}"));
        assert_eq!(p["select"], "cv");
        let (noise, dof, cv) = (stats("noise"), stats("dof"), stats("cv_error"));
        assert!(noise > 0.0 && cv > 0.0 && dof >= 3.0, "{p}");
        let u = p["uncertainty"].as_array().unwrap();
        assert_eq!(u.len() as f64, stats("samples"));
        // A smoother averages: the curve is surer than one measurement.
        let one = cv.max(noise);
        for pair in u {
            let v = pair[1].as_f64().unwrap();
            assert!(
                v > 0.0 && v < one,
                "{} uncertainty {v} vs {one}",
                p["parameter"]
            );
        }
        let fit: volcomp::nurbs::ParameterFit = serde_json::from_value(p.clone()).unwrap();
        fit.to_curve().unwrap();
    }
}

/// The paper's selection (`--select emax`): every parameter of the reference
/// machine is fitted within tolerance; the printed table (timing column removed,
/// errors rounded to 0.01) is stable.
#[test]
fn reference_machine_fits_within_tolerance() {
    let dir = tempfile::tempdir().unwrap();
    let report = dir.path().join("fit.json");
    let out = volcomp()
        .arg("fit")
        .arg(root().join("machines/ref-trt.toml"))
        .args(["--select", "emax"])
        .arg("--report")
        .arg(&report)
        .output()
        .unwrap();
    let stdout = String::from_utf8(out.stdout).unwrap();
    assert!(
        out.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut rows = Vec::new();
    for line in stdout
        .lines()
        .filter(|l| l.split_whitespace().count() == 10)
    {
        let f: Vec<&str> = line.split_whitespace().collect();
        if f[0] == "axis" {
            continue;
        }
        let round = |s: &str| format!("{:.2}", s.parse::<f64>().unwrap());
        rows.push(format!(
            "{} {} samples={} ctrl={} emax={} erms={} tol={} {} met={}",
            f[0],
            f[1],
            f[2],
            f[3],
            round(f[4]),
            round(f[5]),
            f[6],
            f[7],
            f[8]
        ));
    }
    assert_eq!(rows.len(), 30);
    assert!(rows.iter().all(|r| r.ends_with("met=yes")));
    insta::assert_snapshot!(rows.join("\n"));
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let params = json["parameters"].as_array().unwrap();
    assert_eq!(params.len(), 30);
    for p in params {
        for key in [
            "axis",
            "parameter",
            "samples",
            "control_points",
            "method",
            "emax",
            "erms",
            "knots",
            "weights",
            "seconds",
        ] {
            assert!(p.get(key).is_some(), "report lacks {key}");
        }
        assert!(p["emax"].as_f64().unwrap() <= p["tolerance"].as_f64().unwrap());
        assert_eq!(p["table_hash"].as_str().unwrap().len(), 16);
        // The report rebuilds the curve.
        let fit: volcomp::nurbs::ParameterFit = serde_json::from_value(p.clone()).unwrap();
        fit.to_curve().unwrap();
    }
}

#[test]
fn one_table_with_a_method_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let plots = dir.path().join("plots");
    let out = volcomp()
        .arg("fit")
        .arg(root().join("machines/ref-trt/z.csv"))
        .args([
            "--select",
            "emax",
            "--method",
            "ga",
            "--seed",
            "7",
            "--tol",
            "0.8",
            "--tol-angle",
            "1.5",
            "--plot",
        ])
        .arg(&plots)
        .output()
        .unwrap();
    crate::support::assert_success(&out);
    let svgs = std::fs::read_dir(&plots).unwrap().count();
    assert_eq!(svgs, 6);
    let svg = std::fs::read_to_string(plots.join("EXZ.svg")).unwrap();
    assert!(svg.starts_with("<svg") && svg.contains("knots"));
}

#[test]
fn missed_tolerance_fails_clearly() {
    let out = volcomp()
        .arg("fit")
        .arg(root().join("machines/ref-trt/y.csv"))
        .args([
            "--select",
            "emax",
            "--tol",
            "0.001",
            "--control-points",
            "5",
            "--method",
            "lam",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("6 parameter(s) miss their tolerance"),
        "{stderr}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains(" NO "));
}

#[test]
fn tables_read_with_any_column_order_comments_and_missing_columns() {
    let mut text = String::from("# laser run 3\nEYX,position,EXX\n");
    for i in 0..9 {
        text.push_str(&format!(
            "{},{},{}\n",
            i as f64 * 0.1,
            -100.0 + 25.0 * i as f64,
            i as f64
        ));
    }
    let t = ErrorTable::parse(&text, Path::new("t.csv"), None).unwrap();
    assert_eq!(t.axis, Axis::X);
    assert_eq!(
        t.columns
            .iter()
            .map(|c| c.name.as_str())
            .collect::<Vec<_>>(),
        ["EYX", "EXX"]
    );
    assert_eq!(t.missing, ["EZX", "EAX", "EBX", "ECX"]);
    assert_eq!(t.positions[8], 100.0);
    assert!(!t.one_revolution);
    let c = ErrorTable::read(&root().join("machines/ref-trt/c.csv"), Some(Axis::C)).unwrap();
    assert!(c.one_revolution && c.missing.is_empty());
}

#[test]
fn bad_tables_name_file_line_and_column() {
    let rows = |n: usize| {
        (0..n)
            .map(|i| format!("{},0.1,0.2\n", 10 * i))
            .collect::<String>()
    };
    let cases = [
        ("too_few.csv", format!("position,EXX,EYX\n{}", rows(7))),
        (
            "not_increasing.csv",
            format!("position,EXX,EYX\n{}10,0,0\n", rows(9)),
        ),
        (
            "nan.csv",
            format!("position,EXX,EYX\n{}100,NaN,0\n", rows(9)),
        ),
        (
            "garbage.csv",
            format!("position,EXX,EYX\n{}100,0,1.2.3\n", rows(9)),
        ),
        ("no_header.csv", rows(9)),
        (
            "unknown_column.csv",
            format!("position,EXX,TEMP\n{}", rows(9)),
        ),
        ("mixed_axes.csv", format!("position,EXX,EYZ\n{}", rows(9))),
        (
            "short_row.csv",
            format!("position,EXX,EYX\n{}100,0\n", rows(9)),
        ),
        ("empty.csv", "# nothing\n".to_string()),
    ];
    let messages: Vec<String> = cases
        .iter()
        .map(|(name, text)| {
            ErrorTable::parse(text, Path::new(name), None)
                .unwrap_err()
                .to_string()
        })
        .collect();
    let wrong_axis = ErrorTable::parse(
        &format!("position,EXX,EYX\n{}", rows(9)),
        Path::new("y.csv"),
        Some(Axis::Y),
    )
    .unwrap_err();
    insta::assert_snapshot!(format!("{}\n{wrong_axis}", messages.join("\n")));
    // The CLI reports them with exit 1.
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.csv");
    std::fs::write(&bad, &cases[2].1).unwrap();
    let out = volcomp().arg("fit").arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("line 11, column 2 (EXX)"));
}

/// The paper's settings without `--select emax` are refused, not ignored.
#[test]
fn tolerance_without_emax_selection_is_a_usage_error() {
    let out = volcomp()
        .arg("fit")
        .arg(root().join("machines/ref-trt.toml"))
        .args(["--tol", "0.3", "--method", "ga"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("--tol, --method belong(s) to the paper's selection: add --select emax"),
        "{stderr}"
    );
}

/// Long work draws a bar (percentage and time left) only on a terminal: with
/// the bar's delay at 0 ms, the fit piped writes no bar (no `%`, no escape
/// codes) to either stream; the same run on a pseudo-terminal (`script`, when
/// the system has it) draws one.
#[test]
fn progress_bar_only_on_a_terminal() {
    let out = volcomp()
        .env("VOLCOMP_PROGRESS_AFTER_MS", "0")
        .arg("fit")
        .arg(root().join("machines/ref-trt.toml"))
        .output()
        .unwrap();
    crate::support::assert_success(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    let stdout = String::from_utf8_lossy(&out.stdout);
    for text in [&stderr, &stdout] {
        assert!(!text.contains("% ["), "a bar when piped: {text}");
        assert!(!text.contains('\u{1b}'), "escape codes when piped: {text}");
    }
    if Path::new("/usr/bin/script").exists() {
        let command = format!(
            "{} fit {}",
            env!("CARGO_BIN_EXE_volcomp"),
            root().join("machines/ref-trt.toml").display()
        );
        let tty = std::process::Command::new("/usr/bin/script")
            .env("VOLCOMP_PROGRESS_AFTER_MS", "0")
            .args(["-qec", &command, "/dev/null"])
            .output()
            .unwrap();
        let shown = String::from_utf8_lossy(&tty.stdout);
        assert!(
            shown.contains("fitting ") && shown.contains("% ["),
            "no bar on a terminal: {shown}"
        );
    }
}
