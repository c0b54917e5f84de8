//! SINUMERIK five-axis motion (issue 34 item 4, docs/dialects.md): blocks
//! whose tool turns on the great circle (`TRAORI`, `ORIWKS` + `ORIVECT`)
//! split so that the joint path follows it; `CYCLE800` in its projection,
//! solid-angle and direct modes; circles in a tilted plane; `CIP` through a
//! circle out of the working plane; `CT` after `CR=`.
use crate::compensate::{closed_loop_on, compensate_on, read, ref_trt};
use crate::support::{assert_success, program_lines, root, volcomp, written_by};
use volcomp::compensate::CompensateOptions;
use volcomp::gcode::Frame;

/// `check --targets` rows: (line, [x, y, z], [a, b, c]) (empty rotary: NaN).
fn joint_rows(args: &[&str]) -> Vec<(usize, [f64; 3], [f64; 3])> {
    let out = volcomp().args(args).current_dir(root()).output().unwrap();
    assert_success(&out);
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let n = |k: usize| f[k].parse::<f64>().unwrap_or(f64::NAN);
            (
                f[0].parse().unwrap(),
                [n(2), n(3), n(4)],
                [n(5), n(6), n(7)],
            )
        })
        .collect()
}

/// ref-trt's nominal tool axis at A, C (kinematics.md).
fn ac_axis(a: f64, c: f64) -> [f64; 3] {
    let (sa, ca) = a.to_radians().sin_cos();
    let (sc, cc) = c.to_radians().sin_cos();
    [sa * sc, sa * cc, ca]
}

fn angle(u: [f64; 3], v: [f64; 3]) -> f64 {
    let d: f64 = (0..3).map(|k| u[k] * v[k]).sum();
    let c = [
        u[1] * v[2] - u[2] * v[1],
        u[2] * v[0] - u[0] * v[2],
        u[0] * v[1] - u[1] * v[0],
    ];
    (c.iter().map(|x| x * x).sum::<f64>()).sqrt().atan2(d)
}

fn slerp(v0: [f64; 3], v1: [f64; 3], t: f64) -> [f64; 3] {
    let th = angle(v0, v1);
    let (a, b) = (((1.0 - t) * th).sin() / th.sin(), (t * th).sin() / th.sin());
    [0, 1, 2].map(|k| a * v0[k] + b * v1[k])
}

/// The hand check (tests/data/sinumerik/orivect-turn.mpf): N60 turns the
/// tool 60° about (0, √3/2, −1/2) while the tip runs from (0, 0, 40) to
/// (40, 20, 40). By hand the tool goes from A 30° C 0 to (√3/2, 1/4, √3/4)
/// = A 64.3411° C 73.8979°, through (1/2, √3/4, 3/4) = A 41.4096° C
/// 49.1066° half way (tip at (20, 10, 40)); linear joints would stand at A
/// 47.17° C 36.95° there, 7.7° off. volcomp splits it: every piece end is
/// on the tip's line and on the great circle at the same fraction, and
/// between piece ends the linear joints stay within 0.1 mrad of the circle.
/// N80 turns back the same way; N100, under `ORIAXES`, is one move.
#[test]
fn orivect_blocks_are_split_onto_the_great_circle() {
    let rows = joint_rows(&[
        "check",
        "--machine",
        "machines/ref-trt.toml",
        "tests/data/sinumerik/orivect-turn.mpf",
        "--targets",
        "-",
    ]);
    let r3 = 3f64.sqrt();
    let (v0, v1) = ([0.0, 0.5, r3 / 2.0], [r3 / 2.0, 0.25, r3 / 4.0]);
    let n60: Vec<_> = rows.iter().filter(|r| r.0 == 12).collect();
    let n80: Vec<_> = rows.iter().filter(|r| r.0 == 14).collect();
    let n100: Vec<_> = rows.iter().filter(|r| r.0 == 16).collect();
    assert!(n60.len() >= 16, "{}", n60.len());
    assert_eq!(n60.len(), n80.len());
    assert_eq!(n100.len(), 1);
    let last = n60.last().unwrap();
    assert!((last.2[0] - 64.3411).abs() < 1e-4 && (last.2[2] - 73.8979).abs() < 1e-4);
    let half = n60.iter().find(|r| (r.1[0] - 20.0).abs() < 1e-9).unwrap();
    assert!((half.2[0] - 41.4096).abs() < 1e-4 && (half.2[2] - 49.1066).abs() < 1e-4);
    let mut before = (0.0, [30.0, f64::NAN, 0.0]);
    // 1e-4 rad, and the 6-decimal print of the joints (1e-8 rad).
    let mut worst: f64 = 0.0;
    for r in &n60 {
        let t = r.1[0] / 40.0;
        assert!((r.1[1] - 20.0 * t).abs() < 1e-6 && (r.1[2] - 40.0).abs() < 1e-6);
        let on = slerp(v0, v1, t);
        assert!(angle(ac_axis(r.2[0], r.2[2]), on) < 1e-6, "{r:?}");
        for s in [0.25, 0.5, 0.75] {
            let (a, c) = (
                before.1[0] + s * (r.2[0] - before.1[0]),
                before.1[2] + s * (r.2[2] - before.1[2]),
            );
            let tt = before.0 + s * (t - before.0);
            worst = worst.max(angle(ac_axis(a, c), slerp(v0, v1, tt)));
        }
        before = (t, r.2);
    }
    assert!(worst <= 1e-4 + 1e-7, "{worst}");
    eprintln!(
        "orivect-turn.mpf N60: {} pieces, largest deviation between piece ends {:.3e} rad",
        n60.len(),
        worst
    );
}

/// Written back: the split pieces are flat blocks in the input's vector
/// form with `; volcomp: line N`, the first keeping the block's number;
/// the output reads back into as many moves; closed loop on two machines
/// (the replay follows the control's great circle too): tip error cut by
/// ≥ 90 %. For contrast, the same program compensated as volcomp did
/// before the split (read under `ORIAXES`, the joints linear) and run with
/// `ORIVECT` as the control runs it.
#[test]
fn orivect_split_closed_loop_on_two_machines() {
    let file = "tests/data/sinumerik/orivect-turn.mpf";
    let original = read(file);
    for rig in [ref_trt(), crate::machines::rig("bc-trt")] {
        let name = &rig.0.name;
        let (text, report) = compensate_on(
            rig,
            &original,
            Frame::Joint,
            CompensateOptions::default().tolerance_um,
            true,
        );
        assert!(report.blocks_changed > 40, "{name}");
        let pieces: Vec<&str> = text
            .lines()
            .filter(|l| l.ends_with("; volcomp: line 12"))
            .collect();
        assert!(pieces.len() >= 16, "{name}: {}", pieces.len());
        assert!(pieces[0].starts_with("N60 X"), "{name}: {}", pieces[0]);
        for p in &pieces {
            assert!(
                p.contains(" A3=") && p.contains(" B3=") && p.contains(" C3="),
                "{name}: {p}"
            );
        }
        let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
        // As before the split: compensated along linear joints, run on the
        // great circle.
        let axes_read = original.replacen("TRAORI ORIWKS ORIVECT", "TRAORI ORIWKS ORIAXES", 1);
        let (old, _) = compensate_on(
            rig,
            &axes_read,
            Frame::Joint,
            CompensateOptions::default().tolerance_um,
            true,
        );
        let old_on_control = old.replacen("TRAORI ORIWKS ORIAXES", "TRAORI ORIWKS ORIVECT", 1);
        let (_, unsplit) = closed_loop_on(rig, &original, &old_on_control, Frame::Joint);
        eprintln!(
            "{name}/orivect-turn.mpf: tip max {:.3} -> {:.4} µm, RMS {:.3} -> {:.4} µm ({} pieces of N60); compensated unsplit and run on the great circle: max {:.4} µm, RMS {:.4} µm",
            before.max_um,
            after.max_um,
            before.rms_um,
            after.rms_um,
            pieces.len(),
            unsplit.max_um,
            unsplit.rms_um
        );
        assert!(before.max_um > 5.0, "{name}");
        assert!(
            after.max_um <= 0.1 * before.max_um,
            "{name}: {} vs {}",
            after.max_um,
            before.max_um
        );
        assert!(after.rms_um < unsplit.rms_um, "{name}");
    }
    // The output reads back.
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("c.mpf");
    let out = volcomp()
        .args(["compensate", "machines/ref-trt.toml", file, "-o"])
        .arg(&out_path)
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&out);
    let out = volcomp()
        .args(["check", "--machine", "machines/ref-trt.toml"])
        .arg(&out_path)
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&out);
}

/// tests/data/sinumerik/tilted-arcs.mpf: under `ROT Y30` a `G3` with a
/// centre, a `G2` with `CR=` and a `CT` after it (whose tangent comes from
/// the `CR=` circle's centre), then a `CIP` through three points in the
/// plane x = z; each is a circle of radius 10 about the workpiece origin.
/// By hand, every row (`--frame part`) lies 10 mm from the origin, in the
/// plane `Ry(30°)·XY` (normal (sin 30°, 0, cos 30°)) or x = z, and the
/// chords stay within 0.5 µm of the circle; the `CT` ends at (0, −10, 0);
/// the space circle passes (7.071068, 0, 7.071068). Written flat (`G1`
/// pieces with `; volcomp: line N`), compensated, and read back.
#[test]
fn circles_in_a_tilted_plane_and_in_space_are_handed_on_as_chords() {
    let rows = joint_rows(&[
        "check",
        "tests/data/sinumerik/tilted-arcs.mpf",
        "--frame",
        "part",
        "--targets",
        "-",
    ]);
    let (s, c) = 30f64.to_radians().sin_cos();
    let tilted = [s, 0.0, c];
    let space = [0.5f64.sqrt(), 0.0, -(0.5f64.sqrt())];
    let norm = |p: [f64; 3]| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
    let dot = |a: [f64; 3], b: [f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    for (line, normal) in [(11, tilted), (12, tilted), (13, tilted), (15, space)] {
        let pts: Vec<[f64; 3]> = rows.iter().filter(|r| r.0 == line).map(|r| r.1).collect();
        assert!(pts.len() > 70, "line {line}: {}", pts.len());
        for w in pts.windows(2) {
            for p in w {
                assert!((norm(*p) - 10.0).abs() < 2e-6, "line {line}: {p:?}");
                assert!(dot(*p, normal).abs() < 2e-6, "line {line}: {p:?}");
            }
            let mid = [0, 1, 2].map(|k| 0.5 * (w[0][k] + w[1][k]));
            assert!(10.0 - norm(mid) <= 0.0005 + 2e-6, "line {line}: sagitta");
        }
    }
    let ct_end = rows.iter().rfind(|r| r.0 == 13).unwrap().1;
    assert!(
        norm([ct_end[0], ct_end[1] + 10.0, ct_end[2]]) < 1e-6,
        "{ct_end:?}"
    );
    assert!(
        rows.iter()
            .any(|r| r.0 == 15 && norm([r.1[0] - 7.071068, r.1[1], r.1[2] - 7.071068]) < 0.15)
    );
    // Flat and compensated, and read back.
    let dir = tempfile::tempdir().unwrap();
    let compensated = dir.path().join("c.mpf");
    let out = volcomp()
        .args([
            "compensate",
            "machines/ref-trt.toml",
            "tests/data/sinumerik/tilted-arcs.mpf",
            "-o",
        ])
        .arg(&compensated)
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&out);
    let text = std::fs::read_to_string(&compensated).unwrap();
    for (n, line) in [
        ("N60 G1 X", 11),
        ("N70 G1 X", 12),
        ("N80 G1 X", 13),
        ("N100 G1 X", 15),
    ] {
        let tag = format!("; volcomp: line {line}");
        assert!(
            text.lines().any(|l| l.starts_with(n) && l.ends_with(&tag)),
            "{n}\n{text}"
        );
        assert!(text.lines().filter(|l| l.ends_with(&tag)).count() > 70);
    }
    for l in program_lines(&text) {
        assert!(
            !l.contains("CR=") && !l.contains("CIP") && !l.contains("CT "),
            "{l}"
        );
    }
    let again = joint_rows(&["check", compensated.to_str().unwrap(), "--targets", "-"]);
    // (compensate may split a long move where its correction bends.)
    assert!(again.len() >= rows.len(), "{} {}", again.len(), rows.len());
}

/// A circle given by `CR=` in a plane whose frame scales it unevenly is
/// refused, located at its line.
#[test]
fn a_circle_under_an_uneven_scale_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("s.mpf");
    std::fs::write(
        &p,
        "G0 X0 Y0 Z5\nSCALE X2 Y1\nG1 X10 F100\nG3 X0 Y10 CR=10\nM30\n",
    )
    .unwrap();
    let out = volcomp().arg("check").arg(&p).output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("unevenly") && err.contains("s.mpf:4:"),
        "{err}"
    );
}

/// tests/data/sinumerik/cycle800-modes.mpf (`check --frame part`): a
/// projection angle alone (`_MODE` 185: Xα, Yα, Zβ) gives the plane of the
/// axis-by-axis rotation about that axis (`_MODE` 57), tip and tool axis;
/// the solid angle α 90° β 30° (`_MODE` 64) is `Rz(90°)·Ry(30°)`: the
/// point (10, 5, 2) of the plane at (−5, 9.660254, −3.267949) by hand, the
/// tool along (0, 1/2, √3/2), on ref-trt.
#[test]
fn cycle800_projection_and_solid_angle_modes() {
    let out = volcomp()
        .args([
            "check",
            "--machine",
            "machines/ref-trt.toml",
            "tests/data/sinumerik/cycle800-modes.mpf",
            "--frame",
            "part",
            "--targets",
            "-",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&out);
    let rows: Vec<Vec<f64>> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').filter_map(|f| f.parse().ok()).collect())
        .collect();
    assert_eq!(rows.len(), 5);
    for (a, b) in [(0, 1), (2, 3)] {
        for k in 1..rows[a].len() {
            assert!((rows[a][k] - rows[b][k]).abs() < 1e-9, "{rows:?}");
        }
    }
    let want = [18.0, -5.0, 9.660254, -3.267949, 0.0, 0.5, 0.866025];
    for (k, w) in want.iter().enumerate() {
        assert!((rows[4][k] - w).abs() < 2e-6, "{:?}", rows[4]);
    }
}

/// Closed loop of a `CYCLE800` 3+2 raster on a plane given by solid angle
/// (tests/data/sinumerik/plane-solid-angle.mpf) on ref-trt: the tip error
/// is cut by ≥ 90 %.
#[test]
fn cycle800_solid_angle_closed_loop() {
    let original = read("tests/data/sinumerik/plane-solid-angle.mpf");
    let rig = ref_trt();
    let (text, report) = compensate_on(
        rig,
        &original,
        Frame::Joint,
        CompensateOptions::default().tolerance_um,
        true,
    );
    assert!(report.blocks_changed >= 25, "{}", report.blocks_changed);
    let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
    eprintln!(
        "ref-trt/plane-solid-angle.mpf: tip max {:.3} -> {:.4} µm, RMS {:.3} -> {:.4} µm",
        before.max_um, after.max_um, before.rms_um, after.rms_um
    );
    assert!(before.max_um > 5.0);
    assert!(after.max_um <= 0.1 * before.max_um);
}

/// tests/data/sinumerik/cycle800-more-modes.mpf on ref-trt (`check
/// --frame part`), each block at the point (10, 5, 2) of its plane, the
/// rotations multiplied out by hand here:
/// - `_MODE` 27 (ZYX), Z 90° then Y 30°: `Rz(90)·Ry(30)·p` = (−5,
///   9.660254, −3.267949), tool (0, 1/2, √3/2);
/// - 39 (ZXY), Z 90° then X −30°: `Rx(−30)·p` = (10, 5.330127,
///   −0.767949), then `Rz(90)`: (−5.330127, 10, −0.767949), tool (−1/2, 0,
///   √3/2);
/// - 64 solid angle α 90° β 30° with `_C` 90°: `Rz(90)·Ry(30)·Rz(90)·p` =
///   (−10, −3.330127, 4.232051), tool (0, 1/2, √3/2);
/// - 128 + 55 projection Zα 20° Xα 35°: the operating manual's rule for
///   the pair ZX (the new Z in the old YZ plane) with the plane's traces
///   `Rz(20)·X` and `Rx(35)·Z`: Z' = Rx(35)·Z, Y' ⟂ both traces, X' = Y' × Z';
/// - 192 direct, A 30° C 90° (rotary axis 1 = A, the table carrying C):
///   the tool (sin A sin C, sin A cos C, cos A) = (1/2, 0, √3/2) and the
///   plane the table's turn, `Rz(−90)·Rx(−30)·p` = (5.330127, −10,
///   −0.767949), the joints A 30 C 90.
#[test]
fn cycle800_axis_orders_solid_angle_c_projection_orders_and_direct_mode() {
    let file = "tests/data/sinumerik/cycle800-more-modes.mpf";
    let args = |frame: bool| {
        let mut a = vec!["check", "--machine", "machines/ref-trt.toml", file];
        if frame {
            a.extend(["--frame", "part"]);
        }
        a.extend(["--targets", "-"]);
        a
    };
    let out = volcomp()
        .args(args(true))
        .current_dir(root())
        .output()
        .unwrap();
    assert_success(&out);
    let rows: Vec<Vec<f64>> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| l.split(',').skip(2).map(|f| f.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), 5);
    let r3 = 3f64.sqrt() / 2.0;
    let cross = |a: [f64; 3], b: [f64; 3]| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let (s20, c20) = 20f64.to_radians().sin_cos();
    let (s35, c35) = 35f64.to_radians().sin_cos();
    let (trace, z) = ([c20, s20, 0.0], [0.0, -s35, c35]);
    let y = cross(z, trace);
    let n = (y[0] * y[0] + y[1] * y[1] + y[2] * y[2]).sqrt();
    let y = y.map(|c| c / n);
    let x = cross(y, z);
    let projected: Vec<f64> = (0..3)
        .map(|k| 10.0 * x[k] + 5.0 * y[k] + 2.0 * z[k])
        .chain(z)
        .collect();
    let want: [Vec<f64>; 5] = [
        vec![-5.0, 9.660254, -3.267949, 0.0, 0.5, r3],
        vec![-5.330127, 10.0, -0.767949, -0.5, 0.0, r3],
        vec![-10.0, -3.330127, 4.232051, 0.0, 0.5, r3],
        projected,
        vec![5.330127, -10.0, -0.767949, 0.5, 0.0, r3],
    ];
    for (row, w) in rows.iter().zip(&want) {
        for k in 0..6 {
            assert!((row[k] - w[k]).abs() < 2e-6, "{row:?} vs {w:?}");
        }
    }
    let joints = joint_rows(&args(false));
    assert!((joints[4].2[0] - 30.0).abs() < 1e-9 && (joints[4].2[2] - 90.0).abs() < 1e-9);
}

/// `_MODE` values the control does not define are refused at the
/// `CYCLE800` line, naming the bits.
#[test]
fn cycle800_modes_the_control_lacks_are_located_refusals() {
    let dir = tempfile::tempdir().unwrap();
    for (mode, angles, says) in [
        (21, "10,10,10", "X comes twice"),
        (133, "10,10,0", "XX name no projection position"),
        (249, "30,90,0", "direct mode, _MODE 249: bits 0–5 = 57"),
        (121, "30,20,0", "solid angle, _MODE 121: bits 0–5 = 57"),
    ] {
        let p = dir.path().join("m.mpf");
        std::fs::write(
            &p,
            format!("G0 X0 Y0 Z50\nCYCLE800(1,\"T\",0,{mode},0,0,0,{angles},0,0,0,1,100,1)\nG1 X1 F100\nM30\n"),
        )
        .unwrap();
        let out = volcomp()
            .args(["check", "--machine", "machines/ref-trt.toml"])
            .arg(&p)
            .current_dir(root())
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(1), "{mode}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(says) && err.contains("m.mpf:2:"),
            "{mode}: {err}"
        );
    }
}

/// Closed loop of a `CYCLE800` 3+2 raster on a plane set by rotary axis
/// positions (direct mode, tests/data/sinumerik/plane-direct.mpf: A 30° C
/// 90°) on ref-trt: the tip error is cut by ≥ 90 %.
#[test]
fn cycle800_direct_mode_closed_loop() {
    let original = read("tests/data/sinumerik/plane-direct.mpf");
    let rig = ref_trt();
    let (text, report) = compensate_on(
        rig,
        &original,
        Frame::Joint,
        CompensateOptions::default().tolerance_um,
        true,
    );
    assert!(report.blocks_changed >= 25, "{}", report.blocks_changed);
    let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
    eprintln!(
        "ref-trt/plane-direct.mpf: tip max {:.3} -> {:.4} µm, RMS {:.3} -> {:.4} µm",
        before.max_um, after.max_um, before.rms_um, after.rms_um
    );
    assert!(before.max_um > 5.0);
    assert!(after.max_um <= 0.1 * before.max_um);
}

/// tests/data/sinumerik/circle-turning-tool.mpf on ref-trt: circles of
/// radius 20 about the origin that also turn the tool, handed on as
/// pieces. By hand:
/// - N60 (`ORIWKS ORIVECT`, a quarter from (20, 0) to (0, 20)): the tool on
///   the great circle from v0 = (0, 1/2, √3/2) to v1 = (1/2, 0, √3/2), the
///   angle proportional to the path: at the tip's polar angle θ the axis
///   is slerp(v0, v1, θ/90°); half way the tip is at (14.142136,
///   14.142136) and the axis (1/2, 1/2, √3)/√3.5 = A 22.2077° C 45°
///   (linear joints would stand at A 30° there); the end A 30° C 90°.
/// - N80 (`ORIAXES`, back from (0, 20) to (20, 0)): the rotary axes linear
///   in the path, C from 90° to 0° with A 30°: C equals θ at every end.
/// - N110 (`ROT Y30`, a rotary axis word `C90`): the tip on `Ry(30°)` of
///   the quarter circle, C = θ (linear), A 30°.
///
/// Then compensated (pieces written with their orientation words or rotary
/// words), read back, and the closed loop cuts the tip error by ≥ 90 %.
#[test]
fn circles_that_turn_the_tool_are_handed_on_as_pieces() {
    let file = "tests/data/sinumerik/circle-turning-tool.mpf";
    let machine = ["check", "--machine", "machines/ref-trt.toml", file];
    let part = joint_rows(&[&machine[..], &["--frame", "part", "--targets", "-"]].concat());
    let joints = joint_rows(&[&machine[..], &["--targets", "-"]].concat());
    assert_eq!(part.len(), joints.len());
    let r3 = 3f64.sqrt();
    let (v0, v1) = ([0.0, 0.5, r3 / 2.0], [0.5, 0.0, r3 / 2.0]);
    let rows = |line: usize| -> Vec<(usize, [f64; 3], [f64; 3], [f64; 3])> {
        part.iter()
            .zip(&joints)
            .filter(|(p, _)| p.0 == line)
            .map(|(p, j)| (p.0, p.1, p.2, j.2))
            .collect()
    };
    // The part rows carry i j k in the "rotary" slots of joint_rows.
    let (n60, n80, n110) = (rows(12), rows(14), rows(17));
    for set in [&n60, &n80, &n110] {
        assert!(set.len() > 100, "{}", set.len());
    }
    for (_, tip, axis, j) in &n60 {
        assert!((tip[0].hypot(tip[1]) - 20.0).abs() < 1e-3 && tip[2].abs() < 1e-9);
        let t = tip[1].atan2(tip[0]) / std::f64::consts::FRAC_PI_2;
        assert!(angle(*axis, slerp(v0, v1, t)) < 2e-6, "{tip:?} {axis:?}");
        assert!(angle(*axis, ac_axis(j[0], j[2])) < 1e-6);
    }
    let half = n60
        .iter()
        .find(|r| (r.1[0] - 14.142136).abs() < 1e-6 && (r.1[1] - 14.142136).abs() < 1e-6)
        .expect("a piece ends half way");
    let s = 3.5f64.sqrt();
    assert!(angle(half.2, [0.5 / s, 0.5 / s, r3 / s]) < 1e-6);
    assert!((half.3[0] - 22.2077).abs() < 1e-4 && (half.3[2] - 45.0).abs() < 1e-6);
    let end = n60.last().unwrap();
    assert!((end.1[1] - 20.0).abs() < 1e-9 && (end.3[0] - 30.0).abs() < 1e-4);
    assert!((end.3[2] - 90.0).abs() < 1e-6);
    for (_, tip, _, j) in &n80 {
        let theta = tip[1].atan2(tip[0]).to_degrees();
        assert!(
            (j[2] - theta).abs() < 1e-5 && (j[0] - 30.0).abs() < 1e-4,
            "{tip:?} {j:?}"
        );
    }
    let (sy, cy) = 30f64.to_radians().sin_cos();
    for (_, tip, _, j) in &n110 {
        // Back through Ry(30°): the point of the quarter circle.
        let flat = [cy * tip[0] - sy * tip[2], tip[1], sy * tip[0] + cy * tip[2]];
        assert!((flat[0].hypot(flat[1]) - 20.0).abs() < 1e-3 && flat[2].abs() < 1e-6);
        let theta = flat[1].atan2(flat[0]).to_degrees();
        assert!(
            (j[2] - theta).abs() < 1e-5 && (j[0] - 30.0).abs() < 1e-4,
            "{flat:?} {j:?}"
        );
    }
    // Compensated, written back and read back; the closed loop.
    let original = read(file);
    let rig = ref_trt();
    let (text, _) = compensate_on(
        rig,
        &original,
        Frame::Joint,
        CompensateOptions::default().tolerance_um,
        true,
    );
    let n60_out: Vec<&str> = text
        .lines()
        .filter(|l| l.ends_with("; volcomp: line 12"))
        .collect();
    assert!(n60_out.len() > 100 && n60_out.iter().all(|l| l.contains(" A3=")));
    assert!(
        text.lines()
            .filter(|l| l.ends_with("; volcomp: line 17"))
            .all(|l| l.contains(" C"))
    );
    let dir = tempfile::tempdir().unwrap();
    let back = dir.path().join("c.mpf");
    std::fs::write(&back, &text).unwrap();
    let again = joint_rows(&[
        "check",
        "--machine",
        "machines/ref-trt.toml",
        back.to_str().unwrap(),
        "--targets",
        "-",
    ]);
    assert!(again.len() >= joints.len());
    let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
    eprintln!(
        "ref-trt/circle-turning-tool.mpf: tip max {:.3} -> {:.4} µm, RMS {:.3} -> {:.4} µm",
        before.max_um, after.max_um, before.rms_um, after.rms_um
    );
    assert!(before.max_um > 5.0);
    assert!(after.max_um <= 0.1 * before.max_um);
}

/// tests/data/sinumerik/ct-after-space-cip.mpf (`check --frame part`): the
/// `CIP` half circle about the origin in y = 0 ends at (−10, 0, 0) running
/// along −Z; the `CT` after it is, by hand, the half circle about (−5, −5,
/// 0) of radius √50 in the plane x + y = −10 leaving along −Z and ending at
/// (0, −10, 0), lowest at z = −√50. Every row lies on it; written flat,
/// compensated and read back.
#[test]
fn ct_after_a_circle_in_space_continues_tangentially() {
    let file = "tests/data/sinumerik/ct-after-space-cip.mpf";
    let rows = joint_rows(&["check", file, "--frame", "part", "--targets", "-"]);
    let ct: Vec<[f64; 3]> = rows.iter().filter(|r| r.0 == 11).map(|r| r.1).collect();
    assert!(ct.len() > 70, "{}", ct.len());
    let r = 50f64.sqrt();
    for p in &ct {
        let d = ((p[0] + 5.0).powi(2) + (p[1] + 5.0).powi(2) + p[2] * p[2]).sqrt();
        assert!(
            (d - r).abs() < 2e-6 && (p[0] + p[1] + 10.0).abs() < 2e-6,
            "{p:?}"
        );
    }
    let first = ct[0];
    let dir = [first[0] + 10.0, first[1], first[2]];
    let len = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    // The first chord leaves within half its own turn of −Z.
    assert!(-dir[2] / len > 0.999, "{dir:?}");
    let last = ct.last().unwrap();
    assert!(last[0].abs() < 1e-9 && (last[1] + 10.0).abs() < 1e-9 && last[2].abs() < 1e-9);
    let lowest = ct.iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
    assert!(lowest < -7.07 && lowest > -r - 1e-6, "{lowest}");
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("c.mpf");
    let text = written_by(
        &["compensate", "machines/ref-trt.toml", file, "-o"],
        &out_path,
    );
    assert!(
        text.lines()
            .any(|l| l.starts_with("N60 G1 X") && l.ends_with("; volcomp: line 11"))
    );
    for l in program_lines(&text) {
        assert!(!l.contains("CT ") && !l.contains("CIP"), "{l}");
    }
    let again = joint_rows(&["check", out_path.to_str().unwrap(), "--targets", "-"]);
    assert!(again.len() >= rows.len());
}
