//! `volcomp sample` is deterministic: it reproduces the committed samples.
use crate::support::root;

#[test]
fn sample_saddle_reproduces_the_committed_files_byte_for_byte() {
    reproduces("saddle", &["saddle.nc", "saddle-tcp.nc", "saddle-plan.csv"]);
}

#[test]
fn sample_flank_reproduces_the_committed_files_byte_for_byte() {
    reproduces("flank", &["flank.nc", "flank-plan.csv"]);
}

/// A machine without a shaped T3 cannot have the flank sample: said, not guessed.
#[test]
fn sample_flank_needs_a_shaped_tool() {
    let out = crate::support::volcomp()
        .args([
            "sample",
            "flank",
            "--machine",
            "machines/xyzac-trt.toml",
            "--out-dir",
        ])
        .arg(tempfile::tempdir().unwrap().path())
        .current_dir(root())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("T3") && err.contains("shape"), "{err}");
}

fn reproduces(sample: &str, names: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = crate::support::volcomp()
        .args(["sample", sample, "--out-dir"])
        .arg(dir.path())
        .current_dir(root())
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for name in names {
        let made = std::fs::read(dir.path().join(name)).unwrap();
        let committed = std::fs::read(root().join("samples").join(name)).unwrap();
        assert!(made == committed, "{name} differs from samples/{name}");
    }
}

/// Another machine's saddle goes to samples/<machine>/ and names its machine;
/// a file holding other bytes is refused (nothing written) unless --force;
/// compensating it for another machine warns.
#[test]
fn sample_never_replaces_another_machines_files() {
    let dir = tempfile::tempdir().unwrap();
    let machines = dir.path().join("machines");
    std::fs::create_dir_all(&machines).unwrap();
    for name in ["bc-trt.toml", "head-table.toml", "ref-trt.toml"] {
        std::fs::copy(root().join("machines").join(name), machines.join(name)).unwrap();
    }
    for table in ["bc-trt", "head-table", "ref-trt"] {
        let to = machines.join(table);
        std::fs::create_dir_all(&to).unwrap();
        for entry in std::fs::read_dir(root().join("machines").join(table)).unwrap() {
            let entry = entry.unwrap();
            std::fs::copy(entry.path(), to.join(entry.file_name())).unwrap();
        }
    }
    let run = |args: &[&str]| {
        crate::support::volcomp()
            .args(args)
            .current_dir(dir.path())
            .output()
            .unwrap()
    };
    let out = run(&["sample", "saddle", "--machine", "machines/bc-trt.toml"]);
    crate::support::assert_success(&out);
    let bc = std::fs::read_to_string(dir.path().join("samples/bc-trt/saddle.nc")).unwrap();
    assert!(
        bc.lines()
            .take(6)
            .any(|l| l.ends_with(" FOR MACHINE BC-TRT)"))
    );
    assert_eq!(
        bc,
        std::fs::read_to_string(root().join("samples/bc-trt/saddle.nc")).unwrap()
    );
    assert!(!dir.path().join("samples/saddle.nc").exists());
    // The reference machine's saddle beside it, then a clash refused.
    crate::support::assert_success(&run(&["sample", "saddle"]));
    let reference = std::fs::read(dir.path().join("samples/saddle.nc")).unwrap();
    let out = run(&[
        "sample",
        "saddle",
        "--machine",
        "machines/bc-trt.toml",
        "--out-dir",
        "samples",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("samples/saddle.nc") && err.contains("--force"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(dir.path().join("samples/saddle.nc")).unwrap(),
        reference
    );
    // Again: the same bytes, said so.
    let out = run(&["sample", "saddle"]);
    crate::support::assert_success(&out);
    assert!(String::from_utf8_lossy(&out.stdout).contains("samples/saddle.nc unchanged"));
    // bc-trt's program compensated for head-table (same letters): a warning.
    let out = run(&[
        "compensate",
        "machines/head-table.toml",
        "samples/bc-trt/saddle.nc",
        "-o",
        "c.nc",
    ]);
    crate::support::assert_success(&out);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("written for machine BC-TRT, not head-table"),
        "{err}"
    );
    // For its own machine: none.
    let out = run(&[
        "compensate",
        "machines/bc-trt.toml",
        "samples/bc-trt/saddle.nc",
        "-o",
        "c.nc",
    ]);
    crate::support::assert_success(&out);
    assert!(!String::from_utf8_lossy(&out.stderr).contains("written for machine"));
}
