//! Command-line behaviour common to every command.

use crate::support::volcomp;

#[test]
fn help_lists_commands_and_examples() {
    let out = volcomp().arg("--help").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for cmd in [
        "fit",
        "error",
        "compensate",
        "predict",
        "diff",
        "simulate",
        "diagnose",
    ] {
        assert!(text.contains(cmd), "help lacks {cmd}:\n{text}");
    }
    assert!(text.contains("Examples:"));
}

#[test]
fn unknown_command_is_a_usage_error() {
    let out = volcomp().arg("frobnicate").output().unwrap();
    assert_eq!(out.status.code(), Some(2));
}
