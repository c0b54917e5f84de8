//! `volcomp sample saddle` is deterministic: it reproduces the committed samples.
use crate::support::root;

#[test]
fn sample_saddle_reproduces_the_committed_files_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let out = crate::support::volcomp()
        .args(["sample", "saddle", "--out-dir"])
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
    for name in ["saddle.nc", "saddle-tcp.nc", "saddle-plan.csv"] {
        let made = std::fs::read(dir.path().join(name)).unwrap();
        let committed = std::fs::read(root().join("samples").join(name)).unwrap();
        assert!(made == committed, "{name} differs from samples/{name}");
    }
}
