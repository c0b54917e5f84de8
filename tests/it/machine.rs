//! Machine files (validation, error messages) and the error model's lookup policy.
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use volcomp::axes::{Axes, Axis};
use volcomp::machine::{
    ErrorModel, ExtrapolationPolicy, LoadOptions, LookupError, Machine, ModelOptions,
};
use volcomp::nurbs::FitOptions;

fn project(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// Fit settings for tests (the default, milliseconds per table): the lookup and the
/// chain are under test here, not the SMEM fit (tested in the nurbs module).
fn fast_fit() -> ModelOptions {
    ModelOptions {
        // The default fit (cross-validated) takes milliseconds per table.
        fit: FitOptions::default(),
        ..Default::default()
    }
}

/// The reference machine's model, fitted once for the whole test binary.
fn ref_model() -> &'static (Machine, ErrorModel) {
    static MODEL: OnceLock<(Machine, ErrorModel)> = OnceLock::new();
    MODEL.get_or_init(|| {
        let machine = Machine::load(&project("machines/ref-trt.toml")).expect("ref-trt loads");
        let model = ErrorModel::from_machine(&machine, &fast_fit()).expect("fit");
        (machine, model)
    })
}

/// The reference model written as a fitted-model file (for the CLI's `--model`).
fn ref_model_file(dir: &Path) -> PathBuf {
    let (machine, model) = ref_model();
    let file = model.to_model_file(machine).expect("model file");
    let path = dir.join("fit.json");
    std::fs::write(&path, serde_json::to_string(&file).expect("json")).expect("write");
    path
}

const REF_TEXT: &str = include_str!("../../machines/ref-trt.toml");

/// A scratch directory holding the reference tables and `machine.toml` = `text`.
fn scratch(text: &str) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().expect("tempdir");
    let tables = dir.path().join("ref-trt");
    std::fs::create_dir(&tables).expect("mkdir");
    for axis in ["x", "y", "z", "a", "c"] {
        std::fs::copy(
            project(&format!("machines/ref-trt/{axis}.csv")),
            tables.join(format!("{axis}.csv")),
        )
        .expect("copy table");
    }
    let path = dir.path().join("machine.toml");
    std::fs::write(&path, text).expect("write machine");
    (dir, path)
}

/// The machine of `text` (in a scratch directory with the reference tables).
fn load_text(text: &str) -> Machine {
    let (_dir, path) = scratch(text);
    Machine::load(&path).expect("loads")
}

/// The load error of `text`, with the scratch directory replaced by `<dir>`.
fn load_error(text: &str, options: &LoadOptions) -> String {
    let (dir, path) = scratch(text);
    let err = match Machine::load_with(&path, options) {
        Ok(_) => panic!("expected an error for:\n{text}"),
        Err(e) => e.to_string(),
    };
    err.replace(&dir.path().display().to_string(), "<dir>")
}

#[test]
fn reference_machine_loads() {
    let (m, model) = ref_model();
    assert_eq!(m.name, "ref-trt");
    assert_eq!(m.limits.get(Axis::X), Some([-200.0, 200.0]));
    assert_eq!(m.limits.get(Axis::C), None);
    assert_eq!(m.rapid_mm_per_min, 30000.0);
    assert_eq!(m.squareness, [-39.9, 32.8, 14.5]);
    assert_eq!(m.location[0], 12.7);
    assert!(
        [Axis::X, Axis::Y, Axis::Z, Axis::A, Axis::C]
            .iter()
            .all(|a| m.table(*a).is_some())
    );
    assert_eq!(model.fitted_parameters().len(), 30);
    assert_eq!(m.chain.rotary(), [Axis::A, Axis::C]);
}

#[test]
fn linuxcnc_sim_machine_is_nominal() {
    let m = Machine::load(&project("machines/xyzac-trt.toml")).expect("loads");
    // P_A = P_C + (0, y_offset, z_offset) = (0, 20, 10).
    assert_eq!(m.chain.axis(Axis::A).point, [0.0, 20.0, 10.0]);
    assert_eq!(m.chain.axis(Axis::C).point, [0.0, 0.0, 0.0]);
    assert_eq!(m.limits.get(Axis::C), Some([-36000.0, 36000.0]));
    assert!(Axis::ALL.iter().all(|a| m.table(*a).is_none()));
    let model = ErrorModel::from_machine(&m, &fast_fit()).expect("model");
    let v = model
        .volumetric_error(&Axes::xyzac(10.0, -20.0, 30.0, -45.0, 7200.5))
        .expect("lookup");
    assert!(
        v.e_um.iter().chain(&v.axis_urad).all(|x| x.abs() < 1e-9),
        "{v:?}"
    );
}

#[test]
fn unknown_key_is_named() {
    let text = REF_TEXT.replace("[tool]\n", "[tool]\nlenght = 90.0\n");
    insta::assert_snapshot!(load_error(&text, &LoadOptions::default()));
}

#[test]
fn missing_table_is_named() {
    let text = REF_TEXT.replace("ref-trt/y.csv", "ref-trt/y-missing.csv");
    let msg = load_error(&text, &LoadOptions::default());
    // The OS message differs between systems: keep the part we own.
    let msg = msg
        .rsplit_once(": ")
        .map_or(msg.clone(), |(head, _)| head.to_string());
    insta::assert_snapshot!(msg);
}

#[test]
fn bad_tool_chain_is_named() {
    let text = REF_TEXT.replace(
        r#"tool_chain = ["X", "Y", "Z"]"#,
        r#"tool_chain = ["X", "X", "Z"]"#,
    );
    insta::assert_snapshot!(load_error(&text, &LoadOptions::default()));
}

#[test]
fn other_kinematics_is_refused() {
    let text = REF_TEXT.replace(r#"kinematics = "xyzac-trt""#, r#"kinematics = "xyzbd-trt""#);
    insta::assert_snapshot!(load_error(&text, &LoadOptions::default()));
}

#[test]
fn limits_not_covered_by_a_table() {
    let text = REF_TEXT.replace("x = [-200.0, 200.0]", "x = [-250.0, 200.0]");
    insta::assert_snapshot!(load_error(&text, &LoadOptions::default()));
    // Holding the end values accepts it.
    let (_dir, path) = scratch(&text);
    let hold = LoadOptions {
        extrapolation: ExtrapolationPolicy::Hold,
    };
    assert!(Machine::load_with(&path, &hold).is_ok());
}

#[test]
fn endless_c_needs_a_one_revolution_table() {
    let (dir, path) = scratch(REF_TEXT);
    // Drop the 360° row: the C table no longer spans one revolution.
    let c = dir.path().join("ref-trt/c.csv");
    let text = std::fs::read_to_string(&c).expect("c");
    let kept: Vec<&str> = text.lines().filter(|l| !l.starts_with("360")).collect();
    std::fs::write(&c, kept.join("\n") + "\n").expect("write");
    let err = Machine::load(&path)
        .expect_err("endless C, partial table")
        .to_string();
    insta::assert_snapshot!(err.replace(&dir.path().display().to_string(), "<dir>"));
}

#[test]
fn non_finite_and_reversed_values_are_named() {
    let text = REF_TEXT.replace("length = 100.0", "length = nan");
    insta::assert_snapshot!(
        "tool_length_nan",
        load_error(&text, &LoadOptions::default())
    );
    let text = REF_TEXT.replace("a = [-110.0, 110.0]", "a = [110.0, -110.0]");
    insta::assert_snapshot!(
        "limits_reversed",
        load_error(&text, &LoadOptions::default())
    );
}

#[test]
fn c_lookup_wraps_over_any_number_of_turns() {
    let (_, model) = ref_model();
    let base = Axes::xyzac(10.0, -20.0, -30.0, 15.0, 37.5);
    let e0 = model.errors_at(&base).expect("inside");
    for k in [-7i32, -1, 1, 3, 100] {
        let j = Axes {
            c: base.c + 360.0 * k as f64,
            ..base
        };
        let e = model.errors_at(&j).expect("wraps");
        for i in 0..6 {
            assert!(
                (e.component[4][i] - e0.component[4][i]).abs() < 1e-9,
                "k = {k}, column {i}: {} vs {}",
                e.component[4][i],
                e0.component[4][i]
            );
        }
    }
    // The volumetric error differs (C moves the part), the lookup does not.
    assert!(model.errors_at(&Axes { c: -322.5, ..base }).is_ok());
}

#[test]
fn out_of_range_is_an_error_naming_axis_and_range() {
    let (_, model) = ref_model();
    let err = model
        .errors_at(&Axes::xyzac(250.0, 0.0, 0.0, 0.0, 0.0))
        .expect_err("outside X");
    assert_eq!(
        err,
        LookupError::OutOfRange {
            axis: Axis::X,
            position: 250.0,
            range: [-200.0, 200.0]
        }
    );
    insta::assert_snapshot!(err.to_string());
    assert!(
        model
            .errors_at(&Axes::xyzac(0.0, 0.0, 0.0, 0.0, f64::NAN))
            .is_err()
    );
}

#[test]
fn hold_policy_holds_the_end_value_and_counts() {
    let (_, model) = ref_model();
    let mut model = model.clone();
    model.set_policy(ExtrapolationPolicy::Hold);
    model.reset_held_lookups();
    let end = model
        .errors_at(&Axes::xyzac(200.0, 0.0, 0.0, 0.0, 0.0))
        .expect("end");
    let past = model
        .errors_at(&Axes::xyzac(260.0, 0.0, 0.0, 0.0, 0.0))
        .expect("held");
    assert_eq!(end.component[0], past.component[0]);
    assert_eq!(model.held_lookups(), 1);
    let _ = model
        .errors_at(&Axes::xyzac(0.0, 0.0, 0.0, -130.0, 0.0))
        .expect("held A");
    assert_eq!(model.held_lookups(), 2);
}

#[test]
fn model_reproduces_the_tables_within_the_fit_error() {
    let (m, model) = ref_model();
    for axis in m.layout().slot_axes() {
        let table = m.table(axis).expect("table");
        for column in &table.columns {
            let curve = model.curve(&column.name).expect("fitted");
            let emax = curve.stats().emax;
            for (p, v) in table.positions.iter().zip(&column.values) {
                if table.one_revolution && *p == 360.0 {
                    // One revolution: 360° is looked up as 0° (the seam), so every
                    // turn 360·k + c sees the same value.
                    continue;
                }
                let mut j = Axes::default();
                j.set(axis, *p);
                let got = model
                    .errors_at(&j)
                    .expect("inside")
                    .get(&m.layout(), &column.name)
                    .expect("name");
                assert!(
                    (got - v).abs() <= emax + 2e-6, // + the resampling tolerance
                    "{} at {p}: {got} vs table {v} (emax {emax})",
                    column.name
                );
            }
        }
    }
}

#[test]
fn contributions_sum_to_e_to_first_order() {
    let (_, model) = ref_model();
    let j = Axes::xyzac(120.0, -80.0, -150.0, 60.0, 200.0);
    let v = model.volumetric_error(&j).expect("inside");
    let parts = model.contributions(&j).expect("inside");
    let mut sum = [0.0; 3];
    for c in &parts {
        for (s, e) in sum.iter_mut().zip(c.e_um) {
            *s += e;
        }
    }
    for i in 0..3 {
        assert!((sum[i] - v.e_um[i]).abs() < 0.05, "{sum:?} vs {:?}", v.e_um);
    }
    assert!(
        parts
            .windows(2)
            .all(|w| w[0].magnitude_um() >= w[1].magnitude_um())
    );
}

#[test]
fn resampled_lookups_match_exact_lookups() {
    let (machine, fast) = ref_model();
    let exact = ErrorModel::from_machine(
        machine,
        &ModelOptions {
            exact_lookups: true,
            ..fast_fit()
        },
    )
    .expect("fit");
    let info = fast.lookup_resampling();
    eprintln!("resampling: {info:?}");
    assert_eq!(info.len(), 5);
    for (axis, r) in &info {
        let (intervals, deviation) = r.unwrap_or_else(|| panic!("{axis:?} not resampled"));
        assert!(
            intervals >= 512 && deviation <= 1e-6,
            "{axis:?}: {intervals} {deviation}"
        );
    }
    use proptest::prelude::*;
    let mut runner = proptest::test_runner::TestRunner::new(proptest::test_runner::Config {
        cases: 256,
        ..Default::default()
    });
    let poses = (
        -200.0..200.0f64,
        -150.0..150.0f64,
        -200.0..100.0f64,
        -110.0..110.0f64,
        -2000.0..2000.0f64,
    );
    runner
        .run(&poses, |(x, y, z, a, c)| {
            let j = Axes::xyzac(x, y, z, a, c);
            let (f, e) = (
                fast.errors_at(&j).expect("in"),
                exact.errors_at(&j).expect("in"),
            );
            for i in 0..30 {
                let (p, q) = (f.get_index(i).expect("i"), e.get_index(i).expect("i"));
                prop_assert!(
                    (p - q).abs() <= 1.5e-6,
                    "parameter {i} at {j:?}: {p} vs {q}"
                );
            }
            Ok(())
        })
        .expect("resampled = exact within 1.5e-6");
}

#[test]
fn model_file_round_trip_and_stale_tables() {
    let (machine, model) = ref_model();
    let dir = tempfile::tempdir().expect("tempdir");
    let path = ref_model_file(dir.path());
    let back =
        ErrorModel::from_model_file(machine, &path, &ModelOptions::default()).expect("reads");
    let j = Axes::xyzac(33.0, -44.0, -55.0, 66.0, 777.0);
    let (a, b) = (
        model.errors_at(&j).expect("in"),
        back.errors_at(&j).expect("in"),
    );
    // serde_json's default float parsing may differ from the written value in the
    // last bit; the curves are otherwise identical.
    for i in 0..volcomp::kinematics::PARAMETER_COUNT {
        let (x, y) = (a.get_index(i).expect("i"), b.get_index(i).expect("i"));
        assert!((x - y).abs() < 1e-9, "{i}: {x} vs {y}");
    }
    // A table changed since the fit: refused, naming the parameter.
    let text = REF_TEXT.to_string();
    let (scratch_dir, scratch_path) = scratch(&text);
    let x = scratch_dir.path().join("ref-trt/x.csv");
    let mut table = std::fs::read_to_string(&x).expect("x");
    table.push_str("# edited\n");
    std::fs::write(&x, table).expect("write");
    let edited = Machine::load(&scratch_path).expect("loads");
    let err =
        ErrorModel::from_model_file(&edited, &path, &ModelOptions::default()).expect_err("stale");
    let msg = err.to_string();
    assert!(msg.contains("EXX: was fitted to different data"), "{msg}");
}

/// Issue 25: the fitted model is cached by the tables' content, the fit
/// settings and the build of volcomp: a second command reuses it (the same
/// numbers as fitting again), an edited table is refitted and said so once,
/// a corrupt cache file is ignored, and the cache can be turned off.
mod cache {
    use super::{REF_TEXT, scratch};
    use crate::support::{assert_success, volcomp};
    use std::path::Path;

    /// `volcomp error MACHINE --at … --json` with the cache in `cache`
    /// (`None`: `--no-model-cache`): (stdout, stderr).
    fn error_at(machine: &Path, cache: Option<&Path>) -> (String, String) {
        let mut cmd = volcomp();
        cmd.arg("error")
            .arg(machine)
            .args(["--at", "-10,20,-30,15,405", "--json"]);
        match cache {
            Some(dir) => cmd.env("VOLCOMP_MODEL_CACHE", dir),
            None => cmd.arg("--no-model-cache"),
        };
        let out = cmd.output().expect("runs");
        assert_success(&out);
        (
            String::from_utf8(out.stdout).expect("utf-8"),
            String::from_utf8(out.stderr).expect("utf-8"),
        )
    }

    fn cache_files(dir: &Path) -> Vec<std::path::PathBuf> {
        std::fs::read_dir(dir)
            .map(|d| d.flatten().map(|e| e.path()).collect())
            .unwrap_or_default()
    }

    #[test]
    fn a_cached_model_is_reused_until_a_table_changes() {
        let (dir, machine) = scratch(REF_TEXT);
        let cache = tempfile::tempdir().expect("tempdir");
        let fresh = error_at(&machine, None);
        assert!(cache_files(cache.path()).is_empty());
        // First run: fitted and stored.
        let first = error_at(&machine, Some(cache.path()));
        assert_eq!(first.0, fresh.0);
        assert!(!first.1.contains("cached"), "{}", first.1);
        let files = cache_files(cache.path());
        assert_eq!(files.len(), 1, "{files:?}");
        let stored = std::fs::read(&files[0]).expect("cache file");
        // Second run: the cached model, the same numbers, the file untouched.
        let second = error_at(&machine, Some(cache.path()));
        assert_eq!(second, first);
        assert_eq!(std::fs::read(&files[0]).expect("cache file"), stored);
        // A table changed: refitted, said once, and stored again.
        let x = dir.path().join("ref-trt/x.csv");
        let table = std::fs::read_to_string(&x).expect("x");
        let edited = table.replacen("-15.8661", "-14.8661", 1);
        assert_ne!(edited, table);
        std::fs::write(&x, edited).expect("write");
        let third = error_at(&machine, Some(cache.path()));
        assert_ne!(third.0, first.0, "the edited EXX changes e");
        assert_eq!(third.0, error_at(&machine, None).0);
        assert!(
            third
                .1
                .contains("x.csv changed since its model was cached: refitted"),
            "{}",
            third.1
        );
        let fourth = error_at(&machine, Some(cache.path()));
        assert_eq!(fourth.0, third.0);
        assert!(!fourth.1.contains("cached"), "said once: {}", fourth.1);
        // The same machine through another relative path: the same model.
        let relative = volcomp()
            .current_dir(dir.path().join("ref-trt"))
            .arg("error")
            .arg("../machine.toml")
            .args(["--at", "-10,20,-30,15,405", "--json"])
            .env("VOLCOMP_MODEL_CACHE", cache.path())
            .output()
            .expect("runs");
        assert_success(&relative);
        assert_eq!(String::from_utf8_lossy(&relative.stdout), fourth.0);
        assert!(
            !String::from_utf8_lossy(&relative.stderr).contains("cached"),
            "{}",
            String::from_utf8_lossy(&relative.stderr)
        );
        // A comment changes the bytes but not the table: still the same model.
        std::fs::write(
            &x,
            format!("{}# a comment\n", std::fs::read_to_string(&x).unwrap()),
        )
        .expect("write");
        let fifth = error_at(&machine, Some(cache.path()));
        assert_eq!(fifth, fourth);
    }

    #[test]
    fn a_corrupt_cache_file_is_ignored_and_replaced() {
        let (_dir, machine) = scratch(REF_TEXT);
        let cache = tempfile::tempdir().expect("tempdir");
        let first = error_at(&machine, Some(cache.path()));
        let files = cache_files(cache.path());
        assert_eq!(files.len(), 1);
        for garbage in [
            &b"{\"format\": 1, \"volcomp\""[..],
            b"",
            b"\xff\xfe not json",
        ] {
            std::fs::write(&files[0], garbage).expect("corrupt");
            let again = error_at(&machine, Some(cache.path()));
            assert_eq!(again.0, first.0);
            assert!(!again.1.contains("error"), "{}", again.1);
            let json: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&files[0]).expect("file")).expect("json");
            assert_eq!(json["format"], 1);
        }
        // A cached model of other tables, swapped in by hand, is not used: the
        // tables in it are compared with the machine's.
        let other = tempfile::tempdir().expect("tempdir");
        let (dir2, machine2) = scratch(REF_TEXT);
        let x = dir2.path().join("ref-trt/x.csv");
        let table = std::fs::read_to_string(&x).expect("x");
        std::fs::write(&x, table.replacen("-15.8661", "-10.0", 1)).expect("write");
        error_at(&machine2, Some(other.path()));
        let foreign = std::fs::read_to_string(&cache_files(other.path())[0]).expect("file");
        let foreign = foreign.replace(
            &dir2.path().display().to_string(),
            &_dir.path().display().to_string(),
        );
        std::fs::write(&files[0], foreign).expect("swap");
        let swapped = error_at(&machine, Some(cache.path()));
        assert_eq!(swapped.0, first.0);
        assert!(
            swapped.1.contains("changed since its model was cached"),
            "{}",
            swapped.1
        );
    }

    #[test]
    fn the_cache_can_be_turned_off() {
        let (_dir, machine) = scratch(REF_TEXT);
        let cache = tempfile::tempdir().expect("tempdir");
        let mut cmd = volcomp();
        let out = cmd
            .arg("error")
            .arg(&machine)
            .args(["--at", "0,0,0,0,0"])
            .env("VOLCOMP_MODEL_CACHE", "")
            .env("XDG_CACHE_HOME", cache.path())
            .env("HOME", cache.path())
            .output()
            .expect("runs");
        assert_success(&out);
        let out = volcomp()
            .arg("error")
            .arg(&machine)
            .args(["--at", "0,0,0,0,0", "--no-model-cache"])
            .env("XDG_CACHE_HOME", cache.path())
            .output()
            .expect("runs");
        assert_success(&out);
        assert!(cache_files(cache.path()).is_empty());
        // Without VOLCOMP_MODEL_CACHE, XDG_CACHE_HOME/volcomp.
        let out = volcomp()
            .arg("error")
            .arg(&machine)
            .args(["--at", "0,0,0,0,0"])
            .env_remove("VOLCOMP_MODEL_CACHE")
            .env("XDG_CACHE_HOME", cache.path())
            .output()
            .expect("runs");
        assert_success(&out);
        assert_eq!(cache_files(&cache.path().join("volcomp")).len(), 1);
        // An unwritable cache folder: the command works and says why.
        let file = cache.path().join("a-file");
        std::fs::write(&file, "").expect("write");
        let out = volcomp()
            .arg("error")
            .arg(&machine)
            .args(["--at", "0,0,0,0,0", "--model-cache"])
            .arg(&file)
            .output()
            .expect("runs");
        assert_success(&out);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            stderr.contains("the fitted model was not cached"),
            "{stderr}"
        );
    }
}

mod cli {
    use super::{project, ref_model_file};
    use std::process::Command;

    use crate::support::volcomp;

    /// `volcomp COMMAND machines/ref-trt.toml --model <the test model in dir>`.
    fn on_reference(command: &str, dir: &std::path::Path) -> Command {
        let mut cmd = volcomp();
        cmd.arg(command)
            .arg(project("machines/ref-trt.toml"))
            .arg("--model")
            .arg(ref_model_file(dir));
        cmd
    }

    /// Run, insisting on success; the output.
    fn success(cmd: &mut Command) -> std::process::Output {
        let out = cmd.output().expect("runs");
        crate::support::assert_success(&out);
        out
    }

    #[test]
    fn error_at_one_pose_as_json_matches_the_library() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = success(on_reference("error", dir.path()).args([
            "--at",
            "-10,20,-30,15,405",
            "--json",
        ]));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        let (_, model) = super::ref_model();
        let want = model
            .volumetric_error(&volcomp::axes::Axes::xyzac(-10.0, 20.0, -30.0, 15.0, 405.0))
            .expect("inside");
        for i in 0..3 {
            let got = v["e_um"][i].as_f64().expect("number");
            assert!(
                (got - want.e_um[i]).abs() < 1e-9,
                "{got} vs {}",
                want.e_um[i]
            );
            let got = v["axis_urad"][i].as_f64().expect("number");
            assert!((got - want.axis_urad[i]).abs() < 1e-9);
        }
        // The standard uncertainty per axis, as the library propagates it.
        let u = model
            .uncertainty_at(&volcomp::axes::Axes::xyzac(-10.0, 20.0, -30.0, 15.0, 405.0))
            .expect("inside")
            .per_axis_um();
        for i in 0..3 {
            let got = v["u_um"][i].as_f64().expect("u_um");
            assert!((got - u[i]).abs() < 1e-9, "{got} vs {}", u[i]);
            // Table noise of ~0.2 µm / 0.5 µrad, averaged by the fit: tenths of a µm.
            assert!(got > 0.02 && got < 1.0, "u {got}");
        }
    }

    #[test]
    fn error_poses_file_gives_one_object_per_row_in_order() {
        let dir = tempfile::tempdir().expect("tempdir");
        let poses = dir.path().join("poses.csv");
        std::fs::write(
            &poses,
            "x,y,z,a,c\n# comment\n0,0,0,0,0\n100,-50,-100,45,1000\n-150,120,50,-90,-30\n",
        )
        .expect("write");
        let out = success(
            on_reference("error", dir.path())
                .arg("--poses")
                .arg(&poses)
                .arg("--json"),
        );
        let v: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).expect("json list");
        assert_eq!(v.len(), 3);
        let (_, model) = super::ref_model();
        let second = model
            .volumetric_error(&volcomp::axes::Axes::xyzac(
                100.0, -50.0, -100.0, 45.0, 1000.0,
            ))
            .expect("inside");
        let got = v[1]["e_um"][2].as_f64().expect("number");
        assert!((got - second.e_um[2]).abs() < 1e-9);
        // The same pose given as a part-frame target.
        let kin = model.kinematics();
        let joints = volcomp::axes::Axes::xyzac(100.0, -50.0, -100.0, 45.0, 1000.0);
        let tip = kin.nominal_tip(&joints);
        let at = format!("{},{},{},45,1000", tip[0], tip[1], tip[2]);
        let out = success(
            on_reference("error", dir.path()).args(["--frame", "part", "--at", &at, "--json"]),
        );
        let p: serde_json::Value = serde_json::from_slice(&out.stdout).expect("json");
        let got = p["e_um"][2].as_f64().expect("number");
        assert!(
            (got - second.e_um[2]).abs() < 1e-6,
            "{got} vs {}",
            second.e_um[2]
        );
    }

    #[test]
    fn error_reports_bad_input_with_file_and_line() {
        let dir = tempfile::tempdir().expect("tempdir");
        let poses = dir.path().join("poses.csv");
        std::fs::write(&poses, "x,y,z,a,c\n0,0,0,0,0\n0,zero,0,0,0\n").expect("write");
        let out = volcomp()
            .arg("error")
            .arg(project("machines/ref-trt.toml"))
            .arg("--poses")
            .arg(&poses)
            .output()
            .expect("runs");
        assert_eq!(out.status.code(), Some(1));
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("poses.csv:3: field 2 (`y`)"), "{err}");
        // Outside the table: exit 1, naming the axis.
        let out = on_reference("error", dir.path())
            .args(["--at", "0,0,150,0,0"])
            .output()
            .expect("runs");
        assert_eq!(out.status.code(), Some(1));
        assert!(String::from_utf8_lossy(&out.stderr).contains("Z = 150 is outside"));
        // Usage: a malformed pose is exit 2.
        let out = volcomp()
            .arg("error")
            .arg(project("machines/ref-trt.toml"))
            .args(["--at", "1,2,3"])
            .output()
            .expect("runs");
        assert_eq!(out.status.code(), Some(2));
    }

    #[test]
    fn map_writes_svg_and_report() {
        let dir = tempfile::tempdir().expect("tempdir");
        let svg = dir.path().join("map.svg");
        let report = dir.path().join("map.json");
        success(
            on_reference("map", dir.path())
                .args([
                    "--plane", "xz", "--at", "y=20", "--a", "30", "--c", "-45", "--grid", "9",
                ])
                .arg("--out")
                .arg(&svg)
                .arg("--report")
                .arg(&report),
        );
        let text = std::fs::read_to_string(&svg).expect("svg");
        assert!(text.starts_with("<svg") && text.contains("|e|"));
        let r: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&report).expect("report")).expect("json");
        assert_eq!(r["map"]["points"].as_array().map(Vec::len), Some(81));
        assert_eq!(r["surfaces"].as_array().map(Vec::len), Some(4));
        assert!(r["surfaces"][0]["emax_um"].as_f64().is_some());
        assert!(r["max_um"].as_f64().expect("max") > 0.0);
    }
}

/// `[tool]` and `[[tools]]` may name the cutting shape (docs/extensions.md);
/// a shape missing what it needs, or values without a shape, are located errors.
#[test]
fn tool_shapes_are_read_and_checked() {
    let with = |tool: &str| REF_TEXT.replace("[tool]\nlength = 100.0\nradius = 3.0\n", tool);
    let m = load_text(&with(
        "[tool]\nlength = 100.0\nradius = 3.0\nshape = \"bull\"\ncorner_radius = 1.0\nflute_length = 20.0\n",
    ));
    let s = m.tool.shape.expect("shape");
    assert_eq!((s.corner_radius_mm, s.flute_length_mm), (1.0, 20.0));
    let ball = load_text(&with(
        "[tool]\nlength = 100.0\nradius = 3.0\nshape = \"ball\"\nflute_length = 12.0\n",
    ));
    assert_eq!(ball.tool.shape.expect("ball").corner_radius_mm, 3.0);
    assert_eq!(ball.default_tool().shape, ball.tool.shape);
    let flat = load_text(&REF_TEXT.replace(
        "comment = \"ball end R5 roughing\"",
        "comment = \"flat\"\nshape = \"flat\"\nflute_length = 25.0",
    ));
    let t2 = flat.tools.in_use(2, flat.default_tool());
    assert_eq!(t2.shape.expect("T2 shape").corner_radius_mm, 0.0);
    let errors: Vec<String> = [
        "[tool]\nlength = 100.0\nradius = 3.0\nshape = \"bull\"\nflute_length = 20.0\n",
        "[tool]\nlength = 100.0\nradius = 3.0\nshape = \"bull\"\ncorner_radius = 3.0\nflute_length = 20.0\n",
        "[tool]\nlength = 100.0\nradius = 3.0\nshape = \"flat\"\n",
        "[tool]\nlength = 100.0\nradius = 3.0\nshape = \"cone\"\nflute_length = 20.0\n",
        "[tool]\nlength = 100.0\nradius = 3.0\nflute_length = 20.0\n",
    ]
    .iter()
    .map(|t| load_error(&with(t), &LoadOptions::default()))
    .collect();
    insta::assert_snapshot!(errors.join("\n"));
}
