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
