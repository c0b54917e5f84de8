//! Laser positioning runs in (`volcomp import-laser`): the fixtures of
//! tests/data/laser/ (made by its make.py from the reference tables, with seeded
//! noise and a known reversal) come back as the reference table and that
//! reversal; the ISO 230-2 figures against a hand-computed example; an imported
//! table is fitted and compensated with.
use crate::support::{assert_success, root, volcomp};
use volcomp::laser::{axis_figures, target_stats};
use volcomp::machine::ErrorTable;

/// Import `files` for `axis` into a table in `dir`; the table read back.
fn import(dir: &std::path::Path, files: &[&str], axis: &str) -> ErrorTable {
    let out_path = dir.join(format!("{axis}-imported.csv"));
    let mut cmd = volcomp();
    cmd.arg("import-laser");
    for f in files {
        match f.split_once('=') {
            Some((p, f)) => cmd.arg(format!(
                "{p}={}",
                root().join("tests/data/laser").join(f).display()
            )),
            None => cmd.arg(root().join("tests/data/laser").join(f)),
        };
    }
    let out = cmd
        .args(["--axis", axis, "-o"])
        .arg(&out_path)
        .args(["--report"])
        .arg(dir.join(format!("{axis}-report.json")))
        .output()
        .unwrap();
    assert_success(&out);
    ErrorTable::read(&out_path, None).unwrap()
}

/// The largest |imported − reference| of `column`.
fn max_gap(table: &ErrorTable, reference: &str, column: &str) -> f64 {
    let r = ErrorTable::read(&root().join(reference), None).unwrap();
    assert_eq!(table.positions, r.positions);
    let a = &table.column(column).unwrap().values;
    let b = &r.column(column).unwrap().values;
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn every_fixture_gives_the_reference_table_and_its_reversal() {
    let dir = tempfile::tempdir().unwrap();
    // X: 5 runs each way, σ = 0.3 µm, B_i = 6 + t/200 µm; three layouts.
    for file in ["x-long.csv", "x-semicolon.csv", "x-paired.csv"] {
        let t = import(dir.path(), &[file], "X");
        let gap = max_gap(&t, "machines/ref-trt/x.csv", "EXX");
        assert!(gap < 0.5, "{file}: EXX off by {gap} µm");
        let rev = t.reversal.as_ref().expect("REVERSAL");
        for (p, b) in t.positions.iter().zip(rev) {
            let known = 6.0 + p / 200.0;
            assert!(
                (b - known).abs() < 0.8,
                "{file}: B at {p} = {b}, made {known}"
            );
        }
    }
    // Y, wide tab export, descending targets, 3 runs, B = 4 µm.
    let t = import(dir.path(), &["y-wide.tsv"], "Y");
    assert!(max_gap(&t, "machines/ref-trt/y.csv", "EYY") < 0.5);
    assert!(t.reversal.unwrap().iter().all(|b| (b - 4.0).abs() < 0.8));
    // A in arcsec, B = 10 µrad.
    let t = import(dir.path(), &["a-long.csv"], "A");
    assert!(max_gap(&t, "machines/ref-trt/a.csv", "EAA") < 1.5);
    assert!(t.reversal.unwrap().iter().all(|b| (b - 10.0).abs() < 2.5));
    // Positioning, straightness (µm) and pitch (arcsec, decimal comma) in one table.
    let t = import(
        dir.path(),
        &[
            "x-long.csv",
            "EYX=x-straightness-eyx.csv",
            "EBX=x-pitch-ebx.csv",
        ],
        "X",
    );
    let names: Vec<&str> = t.columns.iter().map(|c| c.name.as_str()).collect();
    assert_eq!(names, ["EXX", "EYX", "EBX"]);
    assert!(max_gap(&t, "machines/ref-trt/x.csv", "EYX") < 0.4);
    assert!(max_gap(&t, "machines/ref-trt/x.csv", "EBX") < 1.0);
    // The header names the parameter: no EYX= needed.
    let t = import(dir.path(), &["x-straightness-eyx.csv"], "X");
    assert_eq!(t.columns[0].name, "EYX");
    assert!(t.reversal.is_none());
}

/// ISO 230-2 by hand, two targets, three runs each way (µm):
/// target 0: up 1 2 3 (x̄↑ 2, s↑ 1), down −1 −1 −4 (x̄↓ −2, s↓ √3), B 4;
/// target 10: up 5 5 5 (x̄↑ 5, s↑ 0), down 4 6 5 (x̄↓ 5, s↓ 1), B 0.
/// R_0 = max(2 + 2√3 + 4, 4, 4√3) = 6 + 2√3; R_10 = max(0 + 2 + 0, 0, 4) = 4.
/// E = 5 − (−2) = 7; M = 5 − 0 = 5; B = 4, B̄ = 2; R = 6 + 2√3;
/// A = max(2+2, −2+2√3, 5+0, 5+2) − min(2−2, −2−2√3, 5−0, 5−2) = 7 − (−2 − 2√3) = 9 + 2√3;
/// A↑ = max(4, 5) − min(0, 5) = 5; A↓ = 9 + 2√3; E↑ = 3; E↓ = 7; R↑ = 4; R↓ = 4√3.
#[test]
fn iso_230_2_figures_match_a_hand_computed_example() {
    let r3 = 3f64.sqrt();
    let t0 = target_stats(0.0, &[1.0, 2.0, 3.0], &[-1.0, -1.0, -4.0]);
    let t1 = target_stats(10.0, &[5.0, 5.0, 5.0], &[4.0, 6.0, 5.0]);
    let close = |a: f64, b: f64| assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    close(t0.mean_up, 2.0);
    close(t0.mean_down, -2.0);
    close(t0.mean, 0.0);
    close(t0.reversal, 4.0);
    close(t0.s_up.unwrap(), 1.0);
    close(t0.s_down.unwrap(), r3);
    close(t0.repeatability.unwrap(), 6.0 + 2.0 * r3);
    close(t1.repeatability.unwrap(), 4.0);
    let f = axis_figures(&[t0, t1]);
    close(f.systematic, 7.0);
    close(f.mean_range, 5.0);
    close(f.reversal, 4.0);
    close(f.mean_reversal, 2.0);
    close(f.repeatability.unwrap(), 6.0 + 2.0 * r3);
    close(f.accuracy.unwrap(), 9.0 + 2.0 * r3);
    close(f.accuracy_up.unwrap(), 5.0);
    close(f.accuracy_down.unwrap(), 9.0 + 2.0 * r3);
    close(f.systematic_up, 3.0);
    close(f.systematic_down, 7.0);
    close(f.repeatability_up.unwrap(), 4.0);
    close(f.repeatability_down.unwrap(), 4.0 * r3);
}

/// The same example through the command: a long file with six more targets of
/// zero deviation (a table needs eight), the report's figures as above.
#[test]
fn the_report_carries_the_hand_computed_figures() {
    let dir = tempfile::tempdir().unwrap();
    let mut text = String::from("target;run;direction;deviation [mm]\n");
    let rows: [(f64, [f64; 3], [f64; 3]); 2] = [
        (0.0, [1.0, 2.0, 3.0], [-1.0, -1.0, -4.0]),
        (10.0, [5.0, 5.0, 5.0], [4.0, 6.0, 5.0]),
    ];
    for (t, up, down) in rows {
        for j in 0..3 {
            text.push_str(&format!(
                "{t};{};+;{}\n",
                j + 1,
                (up[j] / 1000.0).to_string().replace('.', ",")
            ));
            text.push_str(&format!(
                "{t};{};-;{}\n",
                j + 1,
                (down[j] / 1000.0).to_string().replace('.', ",")
            ));
        }
    }
    for t in 2..8 {
        for j in 1..=3 {
            text.push_str(&format!(
                "{};{j};+;2,5E-3\n{};{j};-;2,5E-3\n",
                t * 10,
                t * 10
            ));
        }
    }
    std::fs::write(dir.path().join("hand.csv"), text).unwrap();
    let out = volcomp()
        .arg("import-laser")
        .arg(dir.path().join("hand.csv"))
        .args(["--axis", "Z", "-o"])
        .arg(dir.path().join("z.csv"))
        .arg("--report")
        .arg(dir.path().join("z.json"))
        .output()
        .unwrap();
    assert_success(&out);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("z.json")).unwrap()).unwrap();
    let f = &report["parameters"][0]["figures"];
    let r3 = 3f64.sqrt();
    let close = |key: &str, v: f64| {
        let got = f[key].as_f64().unwrap();
        assert!((got - v).abs() < 1e-9, "{key}: {got} vs {v}");
    };
    close("A", 9.0 + 2.0 * r3);
    close("B", 4.0);
    close("E", 7.0);
    close("M", 5.0);
    close("R", 6.0 + 2.0 * r3);
    assert_eq!(report["parameters"][0]["parameter"], "EZZ");
    let table = std::fs::read_to_string(dir.path().join("z.csv")).unwrap();
    assert!(
        table.contains(
            "\nposition,EZZ,REVERSAL,u_EZZ\n0,0.0000,4.0000,0.5774\n10,5.0000,0.0000,0.2887\n"
        ),
        "{table}"
    );
}

#[test]
fn an_imported_table_is_fitted_and_compensated_with() {
    let dir = tempfile::tempdir().unwrap();
    let t = import(dir.path(), &["x-long.csv"], "X");
    assert!(t.reversal.is_some());
    let machine = std::fs::read_to_string(root().join("machines/ref-trt.toml"))
        .unwrap()
        .replace(
            "\"ref-trt/x.csv\"",
            &format!("\"{}\"", dir.path().join("X-imported.csv").display()),
        )
        .replace(
            "\"ref-trt/",
            &format!("\"{}/machines/ref-trt/", root().display()),
        );
    std::fs::write(dir.path().join("m.toml"), machine).unwrap();
    std::fs::write(
        dir.path().join("p.nc"),
        "%\nG21 G90 G94\nG0 X0 Y0 Z10 A10 C0\nG1 X50 Y5 Z2 A12 C30 F500\nG1 X-50 Y2 Z1 A15 C60\nM30\n%\n",
    )
    .unwrap();
    let out = volcomp()
        .arg("compensate")
        .arg(dir.path().join("m.toml"))
        .arg(dir.path().join("p.nc"))
        .arg("-o")
        .arg(dir.path().join("out.nc"))
        .output()
        .unwrap();
    assert_success(&out);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("has a REVERSAL column: the error model adds ±REVERSAL/2"),
        "{stderr}"
    );
    assert!(dir.path().join("out.nc").exists());
}

/// One row of the layout table of docs/extensions.md: a fixture as laser
/// software writes it, and what must be read from it.
struct Export {
    file: &'static str,
    axis: &'static str,
    reference: &'static str,
    column: &'static str,
    /// In the summary line of the file.
    read_as: &'static str,
    runs: usize,
    reversal: f64,
}

/// Every export layout of docs/extensions.md gives the reference table (within
/// the fixtures' noise) and its known reversal, and the summary says how the
/// file was read (layout, separator, decimal mark, units, metadata, columns
/// that hold no reading).
#[test]
fn exports_as_laser_software_writes_them_are_read() {
    let rows = [
        Export {
            file: "x-carto-preamble.csv",
            axis: "X",
            reference: "machines/ref-trt/x.csv",
            column: "EXX",
            read_as: "EXX long; separator ,; decimal point; targets mm, deviations µm; 5 lines before the header (in the report); not readings (kept in the report): `Air temp (°C)` 20.1 to 20.26, `Material temp (°C)` 20.4 to 20.52, `Pressure (mbar)` 1011.7 to 1012.5, `Comment`",
            runs: 5,
            reversal: f64::NAN,
        },
        Export {
            file: "z-german-latin1.csv",
            axis: "Z",
            reference: "machines/ref-trt/z.csv",
            column: "EZZ",
            read_as: "EZZ long; separator ;; decimal comma; Latin-1 text; targets mm, deviations µm; 2 lines before the header (in the report); not readings (kept in the report): `Lufttemperatur [°C]` 20.2, `Bemerkung`",
            runs: 4,
            reversal: 3.0,
        },
        Export {
            file: "y-german-wide.tsv",
            axis: "Y",
            reference: "machines/ref-trt/y.csv",
            column: "EYY",
            read_as: "EYY wide; separator tab; decimal comma; targets mm, deviations µm (units line 2)",
            runs: 3,
            reversal: 4.0,
        },
        Export {
            file: "y-inch-paired.csv",
            axis: "Y",
            reference: "machines/ref-trt/y.csv",
            column: "EYY",
            read_as: "EYY paired; separator ,; decimal point; targets in, deviations µin",
            runs: 3,
            reversal: 4.0,
        },
        Export {
            file: "z-units-line-mil.csv",
            axis: "Z",
            reference: "machines/ref-trt/z.csv",
            column: "EZZ",
            read_as: "EZZ long; separator ,; decimal point; targets mm, deviations mil (units line 2)",
            runs: 3,
            reversal: 3.0,
        },
    ];
    let dir = tempfile::tempdir().unwrap();
    for row in rows {
        let out_path = dir.path().join("t.csv");
        let report_path = dir.path().join("r.json");
        let out = volcomp()
            .arg("import-laser")
            .arg(root().join("tests/data/laser").join(row.file))
            .args(["--axis", row.axis, "-o"])
            .arg(&out_path)
            .arg("--report")
            .arg(&report_path)
            .output()
            .unwrap();
        assert_success(&out);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains(&format!("{}: {}\n", row.file, row.read_as)),
            "{}: {stdout}",
            row.file
        );
        let t = ErrorTable::read(&out_path, None).unwrap();
        let r = ErrorTable::read(&root().join(row.reference), None).unwrap();
        assert_eq!(t.positions.len(), r.positions.len(), "{}", row.file);
        let got = &t.column(row.column).unwrap().values;
        let want = &r.column(row.column).unwrap().values;
        for k in 0..t.positions.len() {
            assert!(
                (t.positions[k] - r.positions[k]).abs() < 1e-5,
                "{}: position {} vs {}",
                row.file,
                t.positions[k],
                r.positions[k]
            );
            assert!(
                (got[k] - want[k]).abs() < 0.5,
                "{}: {} at {}: {} vs {}",
                row.file,
                row.column,
                r.positions[k],
                got[k],
                want[k]
            );
        }
        let rev = t.reversal.as_ref().expect("REVERSAL");
        for (p, b) in t.positions.iter().zip(rev) {
            let known = if row.reversal.is_nan() {
                6.0 + p / 200.0
            } else {
                row.reversal
            };
            assert!((b - known).abs() < 0.8, "{}: B at {p} = {b}", row.file);
        }
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report_path).unwrap()).unwrap();
        assert_eq!(report["parameters"][0]["runs_up"], row.runs, "{}", row.file);
        assert_eq!(
            report["parameters"][0]["runs_down"], row.runs,
            "{}",
            row.file
        );
    }
}

/// The CARTO-style export's metadata lines and other columns are in the report.
#[test]
fn the_report_keeps_the_metadata_and_the_other_columns() {
    let dir = tempfile::tempdir().unwrap();
    let out = volcomp()
        .arg("import-laser")
        .arg(root().join("tests/data/laser/x-carto-preamble.csv"))
        .args(["--axis", "X", "-o"])
        .arg(dir.path().join("t.csv"))
        .arg("--report")
        .arg(dir.path().join("r.json"))
        .output()
        .unwrap();
    assert_success(&out);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("r.json")).unwrap()).unwrap();
    let file = &report["files"][0];
    assert_eq!(file["preamble"][0], "Renishaw CARTO Explore export");
    assert_eq!(file["preamble"][2], "Axis,X");
    assert_eq!(file["header_line"], 7);
    assert_eq!(file["decimal_mark"], "point");
    assert_eq!(file["other_columns"][0]["name"], "Air temp (°C)");
    assert_eq!(file["other_columns"][3]["name"], "Comment");
    assert_eq!(file["other_columns"][3]["cells"], 1);
}

/// One measurement counts once: the same file under another spelling, through
/// a symbolic link, as `EXX=FILE`, or a copy of its bytes is an error naming both.
#[test]
fn the_same_measurement_given_twice_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let runs = dir.path().join("runs.csv");
    std::fs::copy(root().join("tests/data/laser/x-long.csv"), &runs).unwrap();
    std::fs::copy(&runs, dir.path().join("copy.csv")).unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink(&runs, dir.path().join("link.csv")).unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["runs.csv", "./runs.csv"],
            "./runs.csv (file 2) is the same file as runs.csv (file 1)",
        ),
        (
            &["runs.csv", "EXX=runs.csv"],
            "runs.csv (file 2) is the same file as runs.csv (file 1)",
        ),
        (
            &["runs.csv", "copy.csv"],
            "copy.csv (file 2) has the same bytes as runs.csv (file 1)",
        ),
        #[cfg(unix)]
        (
            &["runs.csv", "link.csv"],
            "link.csv (file 2) is the same file as runs.csv (file 1)",
        ),
    ];
    for (files, message) in cases {
        let out = volcomp()
            .current_dir(dir.path())
            .arg("import-laser")
            .args(*files)
            .args(["--axis", "X", "-o", "t.csv"])
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{files:?}: {stderr}");
        assert!(
            stderr.contains(message) && stderr.contains("one measurement counts once"),
            "{files:?}: {stderr}"
        );
        assert!(!dir.path().join("t.csv").exists());
    }
}

/// RMS distances from the truth of one sparse-table cell, averaged over seeds.
struct SparseCell {
    weighted: f64,
    unweighted: f64,
    linear: f64,
    /// Largest |fit − mean| / u over the targets and seeds.
    max_over_u: f64,
}

/// Generated machines (machine::synthetic's truths, 10 µm), measured at
/// `targets` positions over ±200 mm by 5 bidirectional runs with `scatter` µm
/// per reading and a reversal of 4 µm: the fit of the means weighted by their
/// uncertainty (`u_EXX`), today's unweighted fit, and linear interpolation of
/// the means, against the truth on a 1 mm grid.
fn sparse_cell(targets: usize, scatter: f64, seeds: u64) -> SparseCell {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    use volcomp::nurbs::{FitOptions, ParameterKind, fit_parameter_with_uncertainty};
    let (lo, hi) = (-200.0, 200.0);
    let step = (hi - lo) / (targets - 1) as f64;
    let positions: Vec<f64> = (0..targets).map(|i| lo + step * i as f64).collect();
    let grid: Vec<f64> = (0..=400).map(|i| lo + i as f64).collect();
    let rms = |f: &dyn Fn(f64) -> f64, truth: &dyn Fn(f64) -> f64| {
        (grid.iter().map(|&x| (f(x) - truth(x)).powi(2)).sum::<f64>() / grid.len() as f64).sqrt()
    };
    let mut cell = SparseCell {
        weighted: 0.0,
        unweighted: 0.0,
        linear: 0.0,
        max_over_u: 0.0,
    };
    for seed in 0..seeds {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1000 + seed);
        // One machine whatever the count of targets: its features are those
        // of a machine tabulated every 10 mm (the bundled machines' spacing).
        let truth = volcomp::machine::synthetic::truth(&mut rng, lo, hi, 10.0, 10.0, false);
        let noise = Normal::new(0.0, scatter).unwrap();
        let stats: Vec<_> = positions
            .iter()
            .map(|&t| {
                let e = truth(t);
                let up: Vec<f64> = (0..5).map(|_| e + 2.0 + noise.sample(&mut rng)).collect();
                let down: Vec<f64> = (0..5).map(|_| e - 2.0 + noise.sample(&mut rng)).collect();
                target_stats(t, &up, &down)
            })
            .collect();
        let means: Vec<f64> = stats.iter().map(|s| s.mean).collect();
        let u: Vec<f64> = stats.iter().map(|s| s.uncertainty.unwrap()).collect();
        let options = FitOptions::default();
        let weighted = fit_parameter_with_uncertainty(
            &positions,
            &means,
            Some(&u),
            ParameterKind::Length,
            &options,
        )
        .unwrap();
        let unweighted = fit_parameter_with_uncertainty(
            &positions,
            &means,
            None,
            ParameterKind::Length,
            &options,
        )
        .unwrap();
        let linear = |x: f64| {
            let k = (((x - lo) / step).floor() as usize).min(targets - 2);
            let w = (x - positions[k]) / step;
            means[k] * (1.0 - w) + means[k + 1] * w
        };
        cell.weighted += rms(&|x| weighted.value_at(x), &truth) / seeds as f64;
        cell.unweighted += rms(&|x| unweighted.value_at(x), &truth) / seeds as f64;
        cell.linear += rms(&linear, &truth) / seeds as f64;
        for (k, &t) in positions.iter().enumerate() {
            cell.max_over_u = cell
                .max_over_u
                .max((weighted.value_at(t) - means[k]).abs() / u[k]);
        }
    }
    cell
}

/// The sparse-table study of docs/fidelity.md (target counts 6/11/21/41 ×
/// scatter 0.1/0.35/1 µm, RMS from the truth over 8 generated machines): the
/// fit of the means with their uncertainty passes every mean within 3.5 of its
/// standard uncertainties; it is nearer the truth than today's unweighted fit
/// at 11 targets (the table) and no farther than linear interpolation
/// of the means in every cell (issue 37: lines where they predict the
/// left-out means better, and under 8 targets).
#[test]
fn a_fit_weighted_by_the_uncertainty_passes_the_means_and_beats_linear_interpolation_on_dense_tables()
 {
    let mut rows = Vec::new();
    let mut farther = Vec::new();
    for targets in [6, 11, 21, 41] {
        for scatter in [0.1, 0.35, 1.0] {
            let c = sparse_cell(targets, scatter, 8);
            let row = format!(
                "| {targets} | {scatter} | {:.3} | {:.3} | {:.3} | {:.1} |",
                c.weighted, c.unweighted, c.linear, c.max_over_u
            );
            assert!(c.max_over_u <= 3.5, "not within 3.5 u of a mean: {row}");
            if targets == 11 {
                assert!(
                    c.weighted < c.unweighted,
                    "not nearer than unweighted: {row}"
                );
            }
            if c.weighted > c.linear * (1.0 + 1e-9) {
                farther.push(row.clone());
            }
            rows.push(row);
        }
    }
    println!("{}", rows.join("\n"));
    assert!(
        farther.is_empty(),
        "farther than linear interpolation:\n{}",
        farther.join("\n")
    );
}

/// Issue 37: a 6-target run (5 to 7 targets: below the seed paper's 8 rows) is
/// imported and fitted: its means, which carry their uncertainty, are joined by
/// straight lines (a curve through every mean, one control point each).
#[test]
fn a_six_target_run_is_imported_and_fitted_as_lines_through_its_means() {
    let dir = tempfile::tempdir().unwrap();
    let mut runs = String::from("target,run,direction,deviation\n");
    for (k, t) in [0.0, 40.0, 80.0, 120.0, 160.0, 200.0].iter().enumerate() {
        for run in 1..=2 {
            let v = 3.0 * (t / 50.0f64).sin() + 0.1 * run as f64 + 0.01 * k as f64;
            runs.push_str(&format!("{t},{run},+,{v}\n{t},{run},-,{}\n", v - 2.0));
        }
    }
    std::fs::write(dir.path().join("six.csv"), runs).unwrap();
    let out = volcomp()
        .current_dir(dir.path())
        .args(["import-laser", "six.csv", "--axis", "X", "-o", "x.csv"])
        .output()
        .unwrap();
    assert_success(&out);
    let out = volcomp()
        .current_dir(dir.path())
        .args(["fit", "x.csv", "--report", "fit.json"])
        .output()
        .unwrap();
    assert_success(&out);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("fit.json")).unwrap())
            .unwrap();
    let exx = &report["parameters"][0];
    assert_eq!(exx["parameter"], "EXX");
    assert_eq!(exx["samples"], 6);
    assert_eq!(exx["control_points"], 6);
    assert!(exx["emax"].as_f64().unwrap() < 1e-9, "{exx}");
}
