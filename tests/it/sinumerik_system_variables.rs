//! SINUMERIK system variables a program reads (docs/dialects.md, "System
//! variables"): a located error naming `--sysvar` when no value can be
//! known offline; the value `--sysvar` gives (its text, indices included,
//! case and spaces aside); `$P_TOOLNO` and `$P_TOOL` from the program's own
//! `T`/`M6`/`D` once it has set them.
use crate::sinumerik::targets;
use crate::support::volcomp;

const PROGRAM: &str = "G0 X0 Y0 Z5\nR1=$AA_IW[X]\nR2=$P_TOOLNO\nG1 X=R1 Y=R2 F100\nT3\nM6\nG1 Y=$P_TOOLNO D2\nG1 Z=$P_TOOL\nM30\n";

#[test]
fn a_system_variable_is_given_with_sysvar_or_comes_from_the_tool_state() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("sysvar.mpf");
    std::fs::write(&program, PROGRAM).unwrap();
    let path = program.to_str().unwrap();

    // Not given: located at the variable, saying how to give it.
    let out = volcomp()
        .args(["check", path, "--targets", "-"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--sysvar '$AA_IW[X]=VALUE'"), "{err}");
    assert!(err.contains("sysvar.mpf:2:4"), "{err}");

    // Given (other case and spaces): $AA_IW[X] = 7; $P_TOOLNO is the given
    // 9 before the program's own tool change, 3 after `T3 M6`; `$P_TOOL`
    // is the edge `D2` chose.
    let got = targets(&[
        "check",
        path,
        "--targets",
        "-",
        "--sysvar",
        "$aa_iw[ x ]=7",
        "--sysvar",
        "$P_TOOLNO=9",
    ]);
    let want = [
        (1, [0.0, 0.0, 5.0]),
        (4, [7.0, 9.0, 5.0]),
        (7, [7.0, 3.0, 5.0]),
        (8, [7.0, 3.0, 2.0]),
    ];
    assert_eq!(got.len(), want.len(), "{got:?}");
    for (g, w) in got.iter().zip(&want) {
        assert_eq!(g.0, w.0, "{got:?}");
        assert!((0..3).all(|k| (g.1[k] - w.1[k]).abs() < 1e-9), "{got:?}");
    }

    // Given twice: a usage error.
    let out = volcomp()
        .args(["check", path, "--sysvar", "$A=1", "--sysvar", "$a=2"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("given twice"));
}
