//! `check --frame part --targets` (dialects.md "Positions"): every motion end
//! as the tool tip and unit tool axis in the workpiece frame, for every
//! dialect. Hand-checked rows of a LinuxCNC A/C program, a SINUMERIK
//! `TRAORI` program, a `CYCLE800` plane, a Klartext `PLANE SPATIAL` and an
//! `M128` program; the same tool path written in the three dialects gives
//! the same rows (the bundled saddle, and generated paths).
//!
//! The axis of ref-trt (`xyzac-trt`, kinematics.md): `Rz(−c)·Rx(−a)·Z` =
//! `(sin a·sin c, sin a·cos c, cos a)`.
use crate::support::{assert_success, root, volcomp};
use proptest::prelude::*;
use std::io::Write as _;

/// A row: line, motion, the tip (`None`: empty), the axis.
type Row = (usize, String, Option<[f64; 3]>, [f64; 3]);

/// Parse `line,motion,x,y,z,i,j,k`.
fn rows(csv: &str) -> Vec<Row> {
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("line,motion,x,y,z,i,j,k"));
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            assert_eq!(f.len(), 8, "{l}");
            let n = |k: usize| f[k].parse::<f64>().unwrap();
            let tip = (!f[2].is_empty()).then(|| [n(2), n(3), n(4)]);
            (
                f[0].parse().unwrap(),
                f[1].to_string(),
                tip,
                [n(5), n(6), n(7)],
            )
        })
        .collect()
}

/// `volcomp check ARGS --frame part --targets -` from the project root
/// (standard input `stdin` when given): its rows.
fn part_targets(args: &[&str], stdin: Option<&str>) -> Vec<Row> {
    let mut command = volcomp();
    command
        .arg("check")
        .args(args)
        .args(["--frame", "part", "--targets", "-"])
        .current_dir(root());
    let out = match stdin {
        None => command.output().unwrap(),
        Some(text) => {
            let mut child = command
                .stdin(std::process::Stdio::piped())
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap();
            child
                .stdin
                .take()
                .unwrap()
                .write_all(text.as_bytes())
                .unwrap();
            child.wait_with_output().unwrap()
        }
    };
    assert_success(&out);
    rows(&String::from_utf8(out.stdout).unwrap())
}

/// `(sin a·sin c, sin a·cos c, cos a)`: ref-trt's tool axis at A `a`, C `c` (degrees).
fn ac_axis(a: f64, c: f64) -> [f64; 3] {
    let (a, c) = (a.to_radians(), c.to_radians());
    [a.sin() * c.sin(), a.sin() * c.cos(), a.cos()]
}

#[track_caller]
fn assert_rows(got: &[Row], expected: &[(usize, &str, Option<[f64; 3]>, [f64; 3])]) {
    assert_eq!(got.len(), expected.len(), "{got:?}");
    for (g, e) in got.iter().zip(expected) {
        assert_eq!((g.0, g.1.as_str()), (e.0, e.1), "{g:?}");
        match (g.2, e.2) {
            (None, None) => {}
            (Some(t), Some(u)) => {
                for k in 0..3 {
                    assert!(
                        (t[k] - u[k]).abs() < 1e-6,
                        "line {}: tip {t:?} != {u:?}",
                        g.0
                    );
                }
            }
            _ => panic!("line {}: tip {:?}, expected {:?}", g.0, g.2, e.2),
        }
        for k in 0..3 {
            assert!(
                (g.3[k] - e.3[k]).abs() < 1e-9,
                "line {}: axis {:?} != {:?}",
                g.0,
                g.3,
                e.3
            );
        }
    }
}

const REF_TRT: &str = "machines/ref-trt.toml";

#[test]
fn a_linuxcnc_ac_program_in_the_workpiece_frame() {
    let got = part_targets(
        &[
            "tests/data/workpiece-targets/linuxcnc-ac.ngc",
            "--machine",
            REF_TRT,
            "--offset",
            "G54=100,50,-200",
        ],
        None,
    );
    assert_rows(
        &got,
        &[
            // G54 G49: joint, rotary axes at 0: X Y Z are the tip, G54 undone.
            (7, "G0", Some([10.0, 20.0, 30.0]), [0.0, 0.0, 1.0]),
            // A joint rotary move: no tip; the axis of A30 C90.
            (8, "G0", None, ac_axis(30.0, 90.0)),
            // G43.4: the tool tip in program coordinates = workpiece.
            (9, "G1", Some([5.0, -5.0, 12.0]), ac_axis(30.0, 90.0)),
            (10, "G1", Some([6.0, -5.0, 12.0]), ac_axis(45.0, 180.0)),
            // G53: machine coordinates, no tip.
            (12, "G0", None, ac_axis(45.0, 180.0)),
        ],
    );
}

#[test]
fn a_sinumerik_traori_program_in_the_workpiece_frame() {
    let got = part_targets(
        &[
            "tests/data/workpiece-targets/sinumerik-traori.mpf",
            "--machine",
            REF_TRT,
            "--offset",
            "G54=100,50,-200",
        ],
        None,
    );
    assert_rows(
        &got,
        &[
            // TRANS X10 Y-5 applies (the workpiece frame is G54's, before frames).
            (9, "G1", Some([15.0, -10.0, 12.0]), ac_axis(30.0, 90.0)),
            (10, "G1", Some([16.0, -10.0, 12.0]), ac_axis(45.0, 180.0)),
            // TRAFOOF: joint, A45 C180: no tip.
            (13, "G0", None, ac_axis(45.0, 180.0)),
            // Rotary axes back at 0: X Y Z are the tip (TRANS reset).
            (14, "G0", Some([1.0, 2.0, 3.0]), [0.0, 0.0, 1.0]),
            // SUPA: machine coordinates.
            (15, "G0", None, [0.0, 0.0, 1.0]),
        ],
    );
}

#[test]
fn a_heidenhain_m128_program_in_the_workpiece_frame() {
    let got = part_targets(
        &[
            "tests/data/workpiece-targets/heidenhain-m128.h",
            "--machine",
            REF_TRT,
            "--offset",
            "PRESET=100,50,-200",
        ],
        None,
    );
    assert_rows(
        &got,
        &[
            // CYCL DEF 7 X+10 Y-5 applies, the preset is undone: the same
            // rows as the SINUMERIK program's.
            // (Rows name file lines: block 8 is line 9.)
            (9, "G1", Some([15.0, -10.0, 12.0]), ac_axis(30.0, 90.0)),
            (10, "G1", Some([16.0, -10.0, 12.0]), ac_axis(45.0, 180.0)),
            // M129: joint, A45 C180: no tip; M91: machine coordinates.
            (12, "G0", None, ac_axis(45.0, 180.0)),
            (13, "G0", None, ac_axis(45.0, 180.0)),
        ],
    );
}

/// `CYCLE800` swivelling 30° about X (`_MODE` 57, A=30): a point `p` of
/// the plane is `Rx(30)·p` in the workpiece, the axis `Rx(30)·Z` =
/// `(0, −0.5, 0.866)` (ref-trt reaches it at A30 C−180).
#[test]
fn a_cycle800_plane_and_its_moves_in_the_workpiece_frame() {
    let got = part_targets(
        &[
            "tests/data/sinumerik/plane-3plus2.mpf",
            "--machine",
            REF_TRT,
        ],
        None,
    );
    let (s, c) = 30f64.to_radians().sin_cos();
    let rx = |p: [f64; 3]| [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]];
    let axis = [0.0, -s, c];
    assert_rows(
        &got[..3],
        &[
            (10, "G0", Some(rx([-30.0, -15.0, 20.0])), axis),
            (11, "G1", Some(rx([-30.0, -15.0, 2.0])), axis),
            (12, "G1", Some(rx([30.0, -15.0, -0.5])), axis),
        ],
    );
    assert_eq!(got.len(), 27);
}

/// `CYCL DEF 7` X+10 Y-5, then `PLANE SPATIAL SPB-45 TURN` on head-table: a
/// point `p` of the plane is `shift + Ry(−45)·p`, the axis `Ry(−45)·Z` =
/// `(−0.7071, 0, 0.7071)`; the TURN leg has no tip.
#[test]
fn a_klartext_plane_spatial_and_its_moves_in_the_workpiece_frame() {
    let got = part_targets(
        &[
            "tests/data/heidenhain/plane-spatial-32.h",
            "--machine",
            "machines/head-table.toml",
        ],
        None,
    );
    let (s, c) = (-45f64).to_radians().sin_cos();
    let ry = |p: [f64; 3]| {
        [
            10.0 + c * p[0] + s * p[2],
            -5.0 + p[1],
            -s * p[0] + c * p[2],
        ]
    };
    let axis = [s, 0.0, c];
    assert_rows(
        &got[..4],
        &[
            (10, "G0", None, axis),
            (11, "G0", Some(ry([-15.0, -15.0, 20.0])), axis),
            (12, "G1", Some(ry([-15.0, -15.0, 0.0])), axis),
            (13, "G1", Some(ry([15.0, -15.0, 0.0])), axis),
        ],
    );
}

/// Without `--machine`, a rotary position other than 0 is an error at its
/// word; a program whose rotary axes stay at 0 needs no machine.
#[test]
fn without_a_machine_a_rotary_position_is_a_located_error() {
    let out = volcomp()
        .args([
            "check",
            "tests/data/workpiece-targets/linuxcnc-ac.ngc",
            "--frame",
            "part",
            "--targets",
            "-",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("needs the machine's kinematics") && err.contains("linuxcnc-ac.ngc:8:4"),
        "{err}"
    );
    assert!(err.contains("--machine"), "{err}");
    let got = part_targets(&["-", "--dialect", "sinumerik"], Some("G0 X1 Y2 Z3\nM30\n"));
    assert_rows(&got, &[(1, "G0", Some([1.0, 2.0, 3.0]), [0.0, 0.0, 1.0])]);
}

/// The tip and axis of each row (line numbers and motion names differ
/// between dialects).
fn geometry(rows: &[Row]) -> Vec<(Option<[f64; 3]>, [f64; 3])> {
    rows.iter().map(|r| (r.2, r.3)).collect()
}

#[track_caller]
fn assert_same_geometry(a: &[Row], b: &[Row], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: row counts");
    for (k, (x, y)) in geometry(a).iter().zip(geometry(b)).enumerate() {
        let tip = match (x.0, y.0) {
            (Some(p), Some(q)) => (0..3).all(|i| (p[i] - q[i]).abs() < 1e-6),
            (None, None) => true,
            _ => false,
        };
        let axis = (0..3).all(|i| (x.1[i] - y.1[i]).abs() < 1e-9);
        assert!(tip && axis, "{what}: row {k}: {x:?} != {y:?}");
    }
}

/// The saddle seat on bc-trt, written in the three dialects (LinuxCNC
/// `G43.4`, SINUMERIK `TRAORI`, Klartext `M128`): the same 3911 rows.
#[test]
fn the_saddle_in_three_dialects_has_the_same_workpiece_targets() {
    let run = |program: &str| part_targets(&[program, "--machine", "machines/bc-trt.toml"], None);
    let linuxcnc = run("samples/bc-trt/saddle-tcp.nc");
    assert_eq!(linuxcnc.len(), 3911);
    assert_same_geometry(
        &linuxcnc,
        &run("tests/data/sinumerik/saddle-traori-bc.mpf"),
        "SINUMERIK",
    );
    assert_same_geometry(
        &linuxcnc,
        &run("tests/data/heidenhain/saddle-tcp-bc.h"),
        "Heidenhain",
    );
}

/// One tool-tip path in the three dialects: a work origin (G54 / PRESET),
/// a shift (in LinuxCNC's numbers / `TRANS` / `CYCL DEF 7`) and points with
/// A C positions.
fn three_dialects(shift: [f64; 2], points: &[[f64; 5]]) -> [String; 3] {
    let mut ngc = String::from("%\nG21 G90 G94 G17\nT1 M6\nG54\nG43.4 H1\n");
    let mut mpf = format!(
        "N10 G71 G90 G94 G17\nN20 T1 M6 D1\nN30 G54\nN40 TRANS X{:.4} Y{:.4}\nN50 TRAORI\n",
        shift[0], shift[1]
    );
    let mut h = format!(
        "0 BEGIN PGM P MM\n1 TOOL CALL 1 Z S8000\n2 CYCL DEF 7.0 DATUM SHIFT\n3 CYCL DEF 7.1 X{:+.4}\n4 CYCL DEF 7.2 Y{:+.4}\n5 M128\n",
        shift[0], shift[1]
    );
    for (k, p) in points.iter().enumerate() {
        ngc.push_str(&format!(
            "G1 X{:.4} Y{:.4} Z{:.4} A{:.4} C{:.4} F1000\n",
            p[0] + shift[0],
            p[1] + shift[1],
            p[2],
            p[3],
            p[4]
        ));
        mpf.push_str(&format!(
            "N{} G1 X{:.4} Y{:.4} Z{:.4} A{:.4} C{:.4} F1000\n",
            60 + 10 * k,
            p[0],
            p[1],
            p[2],
            p[3],
            p[4]
        ));
        h.push_str(&format!(
            "{} L X{:+.4} Y{:+.4} Z{:+.4} A{:+.4} C{:+.4} R0 F1000\n",
            6 + k,
            p[0],
            p[1],
            p[2],
            p[3],
            p[4]
        ));
    }
    ngc.push_str("G49\nM2\n%\n");
    mpf.push_str("N9990 TRAFOOF\nN9999 M30\n");
    h.push_str(&format!(
        "{} M129\n{} END PGM P MM\n",
        6 + points.len(),
        7 + points.len()
    ));
    [ngc, mpf, h]
}

fn point() -> impl Strategy<Value = [f64; 5]> {
    (
        -80.0..80.0f64,
        -80.0..80.0f64,
        -40.0..60.0f64,
        -90.0..90.0f64,
        -360.0..360.0f64,
    )
        .prop_map(|(x, y, z, a, c)| {
            // Four decimals, as each dialect writes them.
            let r = |v: f64| (v * 1e4).round() / 1e4;
            [r(x), r(y), r(z), r(a), r(c)]
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(12))]

    /// The same tool-tip path in LinuxCNC, SINUMERIK and Klartext: the same
    /// tips and axes in the workpiece frame, and those are the path's own
    /// points and ref-trt's axis of their A C.
    #[test]
    fn one_path_in_three_dialects_gives_the_same_workpiece_targets(
        origin in (-200.0..200.0f64, -200.0..200.0f64, -300.0..0.0f64),
        shift in (-20.0..20.0f64, -20.0..20.0f64),
        points in prop::collection::vec(point(), 1..6),
    ) {
        let r = |v: f64| (v * 1e4).round() / 1e4;
        let origin = [r(origin.0), r(origin.1), r(origin.2)];
        let shift = [r(shift.0), r(shift.1)];
        let [ngc, mpf, h] = three_dialects(shift, &points);
        let offset = |name: &str| format!("{name}={},{},{}", origin[0], origin[1], origin[2]);
        let run = |dialect: &str, text: &str, system: &str| {
            let offset = offset(system);
            part_targets(
                &["-", "--dialect", dialect, "--machine", REF_TRT, "--offset", &offset],
                Some(text),
            )
        };
        let linuxcnc = run("linuxcnc", &ngc, "G54");
        prop_assert_eq!(linuxcnc.len(), points.len());
        for (row, p) in linuxcnc.iter().zip(&points) {
            let tip = row.2.unwrap();
            let want = [p[0] + shift[0], p[1] + shift[1], p[2]];
            prop_assert!((0..3).all(|i| (tip[i] - want[i]).abs() < 1e-6), "{:?} != {:?}", tip, want);
            let axis = ac_axis(p[3], p[4]);
            prop_assert!((0..3).all(|i| (row.3[i] - axis[i]).abs() < 1e-9), "{:?} != {:?}", row.3, axis);
        }
        assert_same_geometry(&linuxcnc, &run("sinumerik", &mpf, "G54"), "SINUMERIK");
        assert_same_geometry(&linuxcnc, &run("heidenhain", &h, "PRESET"), "Heidenhain");
    }
}
