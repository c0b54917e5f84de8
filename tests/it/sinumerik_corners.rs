//! SINUMERIK contour corners `RND=`, `RNDM=`, `CHF=`, `CHR=`, `FRC=`
//! (docs/dialects.md, "Contour corners"; Siemens, *Fundamentals*,
//! "Chamfer, rounding (CHF, CHR, RND, RNDM, FRC, FRCM)"). The fixture
//! `corners.mpf` holds one corner of each kind; every tangent point and
//! centre below is worked out by hand in the comments.
use crate::compensate::{closed_loop_with_ruler_on, compensate_on, read, ref_trt};
use crate::sinumerik::targets;
use crate::support::{assert_success, program_lines, volcomp, written_by};
use volcomp::compensate::CompensateOptions;
use volcomp::gcode::Frame;

const FIXTURE: &str = "tests/data/sinumerik/corners.mpf";

fn close(a: [f64; 3], b: [f64; 3]) -> bool {
    (0..3).all(|k| (a[k] - b[k]).abs() < 1e-6)
}

/// The move ends, each against the hand-worked point (line, x, y, z).
#[test]
fn corners_are_where_the_manual_puts_them() {
    let got = targets(&["check", FIXTURE, "--targets", "-"]);
    let s140 = 140f64.sqrt();
    let s595 = 59.5f64.sqrt();
    // Arc-arc rounding R3 at (10, 40) (N60 → N70): the first arc is
    // clockwise about (20, 40) radius 10, arriving along +Y; the second
    // clockwise about (10, 50) radius 10, leaving along −X: a left turn,
    // the rounding on the left, outside both circles: its centre M is 13
    // from (20, 40) and 13 from (10, 50). The centres are 10√2 apart,
    // their midpoint (15, 45), the half chord √(13² − 50) = √119 across
    // (±(1, 1)/√2): M = (15 − √59.5, 45 − √59.5), the one near the corner.
    let m = [15.0 - s595, 45.0 - s595];
    let t1 = [
        20.0 + 10.0 / 13.0 * (m[0] - 20.0),
        40.0 + 10.0 / 13.0 * (m[1] - 40.0),
    ];
    let t2 = [
        10.0 + 10.0 / 13.0 * (m[0] - 10.0),
        50.0 + 10.0 / 13.0 * (m[1] - 50.0),
    ];
    let want: Vec<(usize, [f64; 3])> = vec![
        (5, [0.0, 0.0, 5.0]),
        (6, [0.0, 0.0, -1.0]),
        // Line-line R5 at (20, 0), (0,0)→(20,0)→(20,30), a left turn of
        // 90°: the tangent points r·tan 45° = 5 from the corner, (15, 0)
        // and (20, 5); centre (15, 5), counter-clockwise (G3).
        (7, [15.0, 0.0, -1.0]),
        (7, [20.0, 5.0, -1.0]),
        // Line-arc R2 at (20, 30): the line along +Y, the arc clockwise
        // about (20, 40) leaving along −X (a left turn). The line offset 2
        // to the left: x = 18; the circle offset outwards (the arc's
        // centre is on the right): radius 12. (18 − 20)² + (y − 40)² = 144
        // → y = 40 − √140 near the corner: M = (18, 40 − √140). T1 = the
        // foot on the line (20, 40 − √140); T2 = (20, 40) + 10/12·(M −
        // (20, 40)) = (20 − 5/3, 40 − 5/6·√140).
        (8, [20.0, 40.0 - s140, -1.0]),
        (8, [20.0 - 5.0 / 3.0, 40.0 - 5.0 / 6.0 * s140, -1.0]),
        (9, [t1[0], t1[1], -1.0]),
        (9, [t2[0], t2[1], -1.0]),
        (10, [0.0, 50.0, -1.0]),
        // CHF = 3√2 (the chamfer's own length) at (0, 70), a right angle:
        // legs CHF/(2·cos 45°) = 3: (0, 67) and (3, 70).
        (11, [0.0, 67.0, -1.0]),
        (11, [3.0, 70.0, -1.0]),
        // CHR = 2 (the leg) at (20, 70): (18, 70) and (20, 72).
        (12, [18.0, 70.0, -1.0]),
        (12, [20.0, 72.0, -1.0]),
        // RNDM=1 from N100: at (20, 90) (right turn) (20, 89), (21, 90);
        // at (40, 90) past the M8 block (left turn) (39, 90), (40, 91);
        // N120 (RNDM=0) ends at its programmed point.
        (13, [20.0, 89.0, -1.0]),
        (13, [21.0, 90.0, -1.0]),
        (14, [39.0, 90.0, -1.0]),
        (14, [40.0, 91.0, -1.0]),
        (16, [40.0, 110.0, -1.0]),
        (17, [40.0, 110.0, 5.0]),
        (18, [50.0, 110.0, 5.0]),
        // G18 (u = Z, v = X): down −Z to (X50, Z−5), then +X: R2, tangent
        // points 2 from the corner: (X50, Z−3) and (X52, Z−5).
        (19, [50.0, 110.0, -3.0]),
        (19, [52.0, 110.0, -5.0]),
        (20, [60.0, 110.0, -5.0]),
        (21, [60.0, 110.0, 5.0]),
    ];
    assert_eq!(got.len(), want.len(), "{got:?}");
    for (g, w) in got.iter().zip(&want) {
        assert!(g.0 == w.0 && close(g.1, w.1), "{g:?} vs {w:?}");
    }
}

/// Written flat: the corners are their own blocks (`G2`/`G3 … I J`, `G1`)
/// with the element's line, no corner word is left, the `FRC=` feed is
/// the chamfer's and `F` comes back after it, the untouched lines are byte
/// for byte, and the flat program moves as the original.
#[test]
fn corners_are_written_flat_and_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat.mpf");
    let text = written_by(&["check", FIXTURE, "--flatten", "-o"], &flat);
    let body = program_lines(&text).collect::<Vec<_>>().join("\n");
    for word in ["RND", "CHF", "CHR", "FRC"] {
        assert!(!body.contains(word), "{word}: {text}");
    }
    for line in [
        "N40 G1 X15 Y0 ; volcomp: line 7\n",
        "G3 X20 Y5 I0 J5 ; volcomp: line 7\n",
        "G1 X20 Y72 F200 ; volcomp: line 12\n",
        "N100 F500 Y89 X20 ; volcomp: line 13\n",
        "N115 M8\n",
        "N120 G1 Y110 ; volcomp: line 16\n",
        "G2 Z-5 X52 K0 I2 ; volcomp: line 19\n",
        "N30 G1 Z-1 F500\n",
    ] {
        assert!(text.contains(line), "{line}: {text}");
    }
    let a = targets(&["check", FIXTURE, "--targets", "-"]);
    let b = targets(&["check", flat.to_str().unwrap(), "--targets", "-"]);
    assert_eq!(a.len(), b.len());
    for (p, q) in a.iter().zip(&b) {
        assert!(close(p.1, q.1), "{p:?} {q:?}");
    }
    // compensate writes the corners flat too, and its output reads back to
    // the same moves.
    let comp = dir.path().join("comp.mpf");
    let written = written_by(
        &["compensate", "machines/ref-trt.toml", FIXTURE, "-o"],
        &comp,
    );
    assert!(!written.contains("RND=") && written.contains("; volcomp: line 9\nG3 X"));
    let c = targets(&[
        "check",
        "--dialect",
        "sinumerik",
        comp.to_str().unwrap(),
        "--targets",
        "-",
    ]);
    assert_eq!(c.len(), a.len());
    for (p, q) in a.iter().zip(&c) {
        assert!(
            (0..3).all(|k| (p.1[k] - q.1[k]).abs() < 0.05),
            "{p:?} {q:?}"
        );
    }
}

/// Compensated on the A/C and B/C table-table machines and replayed
/// through the same model: the largest tip error and the RMS are cut by
/// ≥ 90 %. Measured against the nominal path in 0.01 mm chords: the
/// roundings have radii of 1 and 2 mm, where 0.1 mm chords depart from
/// the arc by c²/(8r) = 1.25 µm and 0.6 µm, as much as the error left.
#[test]
fn corners_closed_loop_on_two_machines() {
    let original = read(FIXTURE);
    for (name, rig) in [
        ("ref-trt", ref_trt()),
        ("bc-trt", crate::machines::rig("bc-trt")),
    ] {
        let (text, _) = compensate_on(
            rig,
            &original,
            Frame::Joint,
            CompensateOptions::default().tolerance_um,
            true,
        );
        let (before, after) = closed_loop_with_ruler_on(rig, &original, &text, Frame::Joint, 0.01);
        eprintln!("corners.mpf on {name}: {before:?} -> {after:?}");
        assert!(before.max_um > 5.0, "{name}: nothing to compensate?");
        assert!(after.samples > before.samples, "{name}");
        assert!(
            after.rms_um <= 0.1 * before.rms_um,
            "{name}: {after:?} vs {before:?}"
        );
        assert!(
            after.max_um <= 0.1 * before.max_um,
            "{name}: {after:?} vs {before:?}"
        );
    }
}

/// What the manual says the control does, and what volcomp refuses
/// (located, naming it).
#[test]
fn corners_the_control_leaves_out_or_volcomp_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, program: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, program).unwrap();
        volcomp()
            .args(["check", "--dialect", "sinumerik"])
            .arg(&path)
            .args(["--targets", "-"])
            .output()
            .unwrap()
    };
    let rows = |out: &std::process::Output| -> Vec<String> {
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .skip(1)
            .map(|l| l.split(',').take(4).collect::<Vec<_>>().join(","))
            .collect()
    };
    // Three blocks without a move in the plane between: rounded; four:
    // "no chamfer/rounding is inserted" (the corner stays sharp).
    let three = run(
        "three.mpf",
        "G1 X0 Y0 F100\nX10 RND=2\nM8\nM9\nM8\nY10\nM30\n",
    );
    assert_success(&three);
    assert!(rows(&three).contains(&"2,G1,8.000000,0.000000".to_string()));
    let four = run(
        "four.mpf",
        "G1 X0 Y0 F100\nX10 RND=2\nM8\nM9\nM8\nM9\nY10\nM30\n",
    );
    assert_success(&four);
    assert!(
        rows(&four).contains(&"2,G1,10.000000,0.000000".to_string()),
        "{:?}",
        rows(&four)
    );
    // A plane change between: no rounding either.
    let plane = run("plane.mpf", "G1 X0 Y0 F100\nX10 RND=2\nG18 Y10\nM30\n");
    assert_success(&plane);
    assert!(rows(&plane).contains(&"2,G1,10.000000,0.000000".to_string()));
    // Elements meeting tangentially: nothing to round.
    let tangent = run("tangent.mpf", "G1 X0 Y0 F100\nX10 RND=2\nX20\nM30\n");
    assert_success(&tangent);
    assert!(rows(&tangent).contains(&"2,G1,10.000000,0.000000".to_string()));
    let cases = [
        (
            "G1 X0 Y0 F100\nX10 RND=20\nY10\nM30\n",
            "too large for its elements",
            ":2:5",
        ),
        (
            "G1 X0 Y0 F100\nX10 RND=2\nM30\n",
            "last motion block",
            ":2:5",
        ),
        ("G1 X0 Y0 F100\nX10 RND=2\n", "last motion block", ":2:5"),
        (
            "G1 X0 Y0 F100\nX10 RND=2\nZ5\nY10\nM30\n",
            "out of the working plane",
            ":3:1",
        ),
        (
            "G1 X0 Y0 F100\nX10 RND=2\nTRANS X5\nY10\nM30\n",
            "frame, work offset",
            ":3:1",
        ),
        ("G0 X0 Y0\nX10 RND=2\nG1 Y10 F100\nM30\n", "G0", ":2:5"),
        (
            "G1 X0 Y0 F100\nX10 Z5 RND=2\nY10\nM30\n",
            "out of the working plane",
            ":2:5",
        ),
        (
            "G1 X0 Y0 F100\nX10 RND=-2\nY10\nM30\n",
            "RND= is a radius",
            ":2:5",
        ),
    ];
    for (k, (program, says, at)) in cases.iter().enumerate() {
        let name = format!("bad{k}.mpf");
        let out = run(&name, program);
        assert_eq!(out.status.code(), Some(1), "{program}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(says), "{program}: {err}");
        assert!(err.contains(&format!("{name}{at}")), "{program}: {err}");
    }
}
