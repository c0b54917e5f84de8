//! What every area's tests share: the project root, the built binary, and a
//! success check that shows the command's stderr when it fails.
use std::path::PathBuf;
use std::process::{Command, Output};

/// The project's root folder.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The `volcomp` binary built for these tests. Its model cache is a folder of
/// this test run's own under cargo's `CARGO_TARGET_TMPDIR` (`target/tmp`,
/// removed with the build by `cargo clean`; never the user's
/// `~/.cache/volcomp`, nor the system's temporary folder, where a folder held
/// by a static is never deleted), shared by the tests: a model one test fitted
/// is what another one loads, as for a user running several commands.
pub fn volcomp() -> Command {
    let mut command = Command::new(env!("CARGO_BIN_EXE_volcomp"));
    command.env("VOLCOMP_MODEL_CACHE", model_cache());
    command
}

/// The model cache of this test run (see [`volcomp`]).
pub fn model_cache() -> &'static std::path::Path {
    static DIR: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    DIR.get_or_init(|| {
        tempfile::Builder::new()
            .prefix("volcomp-test-cache-")
            .tempdir_in(env!("CARGO_TARGET_TMPDIR"))
            .expect("a temporary folder under CARGO_TARGET_TMPDIR")
    })
    .path()
}

/// Assert that a command succeeded, showing its stderr otherwise.
#[track_caller]
pub fn assert_success(out: &Output) {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// Run `volcomp ARGS OUT` from the project root (`args` ends with the
/// output option, `-o`), assert that it succeeded, and return what it wrote
/// to `out`.
#[track_caller]
pub fn written_by(args: &[&str], out: &std::path::Path) -> String {
    let run = volcomp()
        .args(args)
        .arg(out)
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&run);
    std::fs::read_to_string(out).unwrap()
}

/// A written program's lines without its comment lines (`;`) and `%` lines.
pub fn program_lines(text: &str) -> impl Iterator<Item = &str> {
    text.lines()
        .filter(|l| !l.starts_with(';') && !l.starts_with('%'))
}
