//! What every area's tests share: the project root, the built binary, and a
//! success check that shows the command's stderr when it fails.
use std::path::PathBuf;
use std::process::{Command, Output};

/// The project's root folder.
pub fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The `volcomp` binary built for these tests.
pub fn volcomp() -> Command {
    Command::new(env!("CARGO_BIN_EXE_volcomp"))
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
