//! Heidenhain TNC Klartext programs (issue 35): hand-checked positions of
//! the semantics that decide them, each citing the TNC user's manual; the
//! closed loop of a tool-tip (M128) program and a 3+2 (PLANE SPATIAL)
//! program on two bundled machines; the written program's form.
use crate::compensate::{
    Rig, closed_loop_on, closed_loop_with_ruler_on, compensate_on, interpret_options_on,
    replayed_axis_error_on,
};
use crate::support::root;
use approx::assert_abs_diff_eq;
use std::sync::{Arc, OnceLock};
use volcomp::axes::Axes;
use volcomp::compensate::CompensateOptions;
use volcomp::gcode::{
    Frame, InterpretOptions, Motion, MotionKind, OrientationSolver, Program, ProgramSetup,
};
use volcomp::machine::{ErrorModel, Machine, ModelOptions};
use volcomp::toolpath::ChainOrientation;

fn rig(name: &str) -> &'static Rig {
    static RIGS: [OnceLock<Rig>; 3] = [OnceLock::new(), OnceLock::new(), OnceLock::new()];
    let names = ["bc-trt", "head-table", "ref-trt"];
    let i = names.iter().position(|n| *n == name).expect("a machine");
    RIGS[i].get_or_init(|| {
        let machine = Machine::load(&root().join(format!("machines/{name}.toml"))).unwrap();
        let model = ErrorModel::from_machine(&machine, &ModelOptions::default()).unwrap();
        (machine, model)
    })
}

/// `text` as a Klartext program on `machine` (its tools and chain), or on
/// no machine.
fn program(text: &str, machine: Option<&Machine>) -> Program {
    let mut setup = ProgramSetup::default();
    if let Some(m) = machine {
        setup.tools = m.tools.clone();
        setup.orientation = Some(Arc::new(ChainOrientation::of(m)));
    }
    Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        std::path::Path::new("t.h"),
        setup,
    )
}

/// Every motion of `text` with its source line, or the first error.
fn motions(text: &str, machine: Option<&Machine>) -> Result<Vec<(usize, Motion)>, String> {
    let options = machine.map_or_else(InterpretOptions::default, |m| {
        interpret_options_on(m, Frame::Joint)
    });
    let mut run = program(text, machine).run(options);
    let mut out = Vec::new();
    while let Some(step) = run.next() {
        let (_, event, executed) = step.map_err(|e| e.to_string())?;
        out.extend(event.motions().map(|m| (executed.line, *m)));
    }
    Ok(out)
}

fn xyz(a: &Axes) -> [f64; 3] {
    [a.x, a.y, a.z]
}

fn assert_point(got: [f64; 3], want: [f64; 3]) {
    assert_near(got, want, 1e-9);
}

fn assert_near(got: [f64; 3], want: [f64; 3], epsilon: f64) {
    for k in 0..3 {
        assert_abs_diff_eq!(got[k], want[k], epsilon = epsilon);
    }
}

/// TNC 640 user's manual (Klartext), "Path contours – Cartesian coordinates
/// › Circular path C around circle center CC": the tool moves from its
/// position to the end point about the pole CC, DR+ counter-clockwise, DR-
/// clockwise (iTNC 530 user's manual 340 422, section 6.4).
#[test]
fn circle_about_cc_turns_by_dr() {
    let program = |dr: &str| {
        format!(
            "0 BEGIN PGM C MM\n1 TOOL CALL 1 Z S1000\n2 L X+10 Y+0 Z+0 R0 F500\n3 CC X+0 Y+0\n4 C X+0 Y+10 DR{dr}\n5 END PGM C MM\n"
        )
    };
    for (dr, mid) in [
        ("+", [7.0710678118654755, 7.0710678118654755]),
        ("-", [-7.0710678118654755, -7.0710678118654755]),
    ] {
        let m = motions(&program(dr), None).unwrap();
        let (line, arc) = m.last().unwrap();
        assert_eq!(*line, 5);
        let MotionKind::Arc {
            clockwise, centre, ..
        } = arc.kind
        else {
            panic!("an arc")
        };
        assert_eq!(clockwise, dr == "-");
        assert_point(centre, [0.0, 0.0, 0.0]);
        let g = arc.arc_geometry().unwrap();
        let p = g.point(0.5);
        assert_point(p, [mid[0], mid[1], 0.0]);
        // A quarter turn one way, three quarters the other.
        let quarter = std::f64::consts::FRAC_PI_2;
        assert_abs_diff_eq!(
            g.sweep().abs(),
            if dr == "+" { quarter } else { 3.0 * quarter },
            epsilon = 1e-12
        );
    }
}

/// TNC 640 user's manual, "Path contours – Polar coordinates › Helical
/// interpolation": `CP IPA±… IZ… DR±` about the pole; IPA may exceed 360°
/// (here two turns, 4 mm down; iTNC 530 user's manual 340 422, 6.5).
#[test]
fn cp_helix_turns_twice_down_the_axis() {
    let text = "0 BEGIN PGM H MM\n1 TOOL CALL 1 Z S1000\n2 L X+10 Y+0 Z+0 R0 F500\n3 CC X+0 Y+0\n4 CP IPA+720 IZ-4 DR+ F200\n5 END PGM H MM\n";
    let m = motions(text, None).unwrap();
    let (_, helix) = m.last().unwrap();
    assert_point(xyz(&helix.end), [10.0, 0.0, -4.0]);
    let g = helix.arc_geometry().unwrap();
    assert_abs_diff_eq!(g.sweep(), 4.0 * std::f64::consts::PI, epsilon = 1e-12);
    // A quarter of the way: half a turn round, 1 mm down.
    assert_point(g.point(0.25), [-10.0, 0.0, -1.0]);
    // The sign of IPA must agree with DR (the control refuses the block).
    let bad = text.replace("IPA+720", "IPA-720");
    let e = motions(&bad, None).unwrap_err();
    assert!(e.contains("IPA"), "{e}");
}

/// CYCL DEF 7 (datum shift, TNC 640 user's manual "Cycles: coordinate
/// transformations › DATUM SHIFT (Cycle 7)") then `PLANE SPATIAL SPA+0
/// SPB-45 SPC+0 TURN` (iTNC 530 user's manual 340 422, p. 460: rotations
/// about the machine-fixed axes, first A, then B, then C) and a move: the
/// tip in the workpiece frame is shift + Ry(−45°)·p, the B head at −45°.
#[test]
fn datum_shift_then_plane_spatial_spb_minus_45_then_a_move() {
    let text = "0 BEGIN PGM P MM\n1 TOOL CALL 1 Z S1000\n2 CYCL DEF 7.0 DATUM SHIFT\n3 CYCL DEF 7.1 X+10\n4 CYCL DEF 7.2 Y-5\n5 CYCL DEF 7.3 Z+0\n6 PLANE SPATIAL SPA+0 SPB-45 SPC+0 TURN FMAX SEQ- TABLE ROT\n7 L X-15 Y-15 Z+0 R0 F300\n8 END PGM P MM\n";
    let (machine, _) = rig("head-table");
    let m = motions(text, Some(machine)).unwrap();
    let (line, mv) = m.last().unwrap();
    assert_eq!(*line, 8);
    assert_eq!(mv.frame, Frame::Part);
    let h = 0.5f64.sqrt();
    // Ry(−45°)·(−15, −15, 0) = (−15·cos45, −15, −15·sin45), plus the shift (10, −5, 0).
    assert_point(xyz(&mv.end), [10.0 - 15.0 * h, -20.0, -15.0 * h]);
    assert_abs_diff_eq!(mv.end.b, -45.0, epsilon = 1e-9);
    // The rotary positioning of TURN came first: B to −45°, not compensated
    // (a machine-datum-like leg).
    let (_, turn) = &m[0];
    assert!(turn.end.b + 45.0 < 1e-9);
    // Without the machine, the plane cannot be solved: a located error.
    let e = motions(text, None).unwrap_err();
    assert!(e.contains("--machine") && e.contains("t.h:7:"), "{e}");
}

/// FN 12 (TNC 640 user's manual, "Q parameters › If-then decisions": FN 12
/// IF … LT … GOTO LBL) loops back while the condition holds; the first pass
/// is the program's own block, the others its flat copies.
#[test]
fn fn12_loop_runs_three_times() {
    let text = "0 BEGIN PGM Q MM\n1 TOOL CALL 1 Z\n2 L X+0 Y+0 Z+0 R0 F100\n3 Q1 = 0\n4 LBL 5\n5 Q1 = Q1 + 1\n6 L X+Q1\n7 FN 12: IF +Q1 LT +3 GOTO LBL 5\n8 END PGM Q MM\n";
    let m = motions(text, None).unwrap();
    let xs: Vec<f64> = m.iter().skip(1).map(|(_, m)| m.end.x).collect();
    assert_eq!(xs, vec![1.0, 2.0, 3.0]);
}

/// CALL LBL 1 REP 3 (TNC 640 user's manual, "Subprograms and program
/// section repeats › Program section repeats": the section runs once, then
/// is repeated REP times) runs the section four times.
#[test]
fn call_lbl_rep_3_runs_the_section_four_times() {
    let text = "0 BEGIN PGM R MM\n1 TOOL CALL 1 Z\n2 L X+0 Y+0 Z+0 R0 F100\n3 LBL 1\n4 L IX+1\n5 CALL LBL 1 REP 3\n6 END PGM R MM\n";
    let m = motions(text, None).unwrap();
    let xs: Vec<f64> = m.iter().skip(1).map(|(_, m)| m.end.x).collect();
    assert_eq!(xs, vec![1.0, 2.0, 3.0, 4.0]);
}

/// M128 (TNC 640 user's manual, "Multiple-axis machining › Compensating
/// the tool orientation: M128"): X Y Z are the tool tip in the workpiece
/// frame, A C the machine's axes; with LN and a tool vector TX TY TZ the
/// control solves the rotary axes itself ("Three-dimensional tool
/// compensation › LN blocks").
#[test]
fn m128_with_a_c_and_with_ln() {
    let (machine, _) = rig("ref-trt");
    let text = "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z\n2 M128\n3 L X+10 Y+20 Z+5 A+15 C+90 R0 F500\n4 LN X+11 Y+20 Z+5 TX+0 TY-0.5 TZ+0.8660254 F500\n5 M129\n6 END PGM T MM\n";
    let m = motions(text, Some(machine)).unwrap();
    let (_, first) = m[0];
    assert_eq!(first.frame, Frame::Part);
    assert_point(xyz(&first.end), [10.0, 20.0, 5.0]);
    assert_eq!((first.end.a, first.end.c), (15.0, 90.0));
    let (_, ln) = m[1];
    assert_point(xyz(&ln.end), [11.0, 20.0, 5.0]);
    // The solved joints point the tool along the vector.
    let axis = ChainOrientation::of(machine).axis_of(&ln.end);
    // (The vector is written to 7 decimals.)
    assert_near(axis, [0.0, -0.5, 0.8660254037844386], 1e-7);
    // A zero vector is refused at its block.
    let bad = text.replace("TX+0 TY-0.5 TZ+0.8660254", "TX+0 TY+0 TZ+0");
    let e = motions(&bad, Some(machine)).unwrap_err();
    assert!(
        e.contains("zero tool vector") && e.contains("t.h:5:"),
        "{e}"
    );
}

/// The closed loop of each (machine, file): compensated in Klartext,
/// renumbered consecutively, replayed through the same model; the tip
/// error cut by ≥ 90 %. One summary line each.
fn closed_loop_rows(cases: &[(&str, &str)]) -> String {
    let mut summary = String::new();
    for &(machine, file) in cases {
        let rig = rig(machine);
        let original = std::fs::read_to_string(root().join(file)).unwrap();
        let (text, report) = compensate_on(
            rig,
            &original,
            Frame::Joint,
            CompensateOptions::default().tolerance_um,
            true,
        );
        assert!(text.starts_with("0 BEGIN PGM"), "{file}");
        for (k, line) in text.lines().enumerate() {
            assert!(line.starts_with(&format!("{k} ")), "{file}: {line}");
        }
        let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
        assert!(before.max_um > 5.0, "{file}: nothing to compensate?");
        assert!(
            after.max_um <= 0.1 * before.max_um && after.rms_um <= 0.1 * before.rms_um,
            "{machine} {file}: {before:?} -> {after:?}"
        );
        summary += &format!(
            "{machine} {file}: blocks changed {}, tip max {:.2} -> {:.3} µm ({:.2} %), rms {:.2} -> {:.3} µm\n",
            report.blocks_changed,
            before.max_um,
            after.max_um,
            100.0 * after.max_um / before.max_um,
            before.rms_um,
            after.rms_um,
        );
    }
    summary
}

/// The closed loop (issue 35 "Show"): a five-axis M128 program on bc-trt
/// and a PLANE SPATIAL 3+2 program on head-table, compensated in Klartext
/// and replayed through the same model: the tip error is cut by ≥ 90 %
/// (the program's four decimals leave far less).
#[test]
fn closed_loop_m128_and_plane_spatial() {
    let summary = closed_loop_rows(&[
        ("bc-trt", "tests/data/heidenhain/saddle-tcp-bc.h"),
        ("head-table", "tests/data/heidenhain/plane-spatial-32.h"),
    ]);
    insta::assert_snapshot!("heidenhain_closed_loop", summary);
}

/// What `compensate` writes: an untouched block byte for byte; a changed
/// block differs only in the values of its axis words (the input's sign,
/// at least four decimals), an added word after the last axis word; every
/// line keeps its comment.
#[test]
fn written_blocks_change_only_their_words() {
    let rig = rig("bc-trt");
    let original =
        std::fs::read_to_string(root().join("tests/data/heidenhain/saddle-tcp-bc.h")).unwrap();
    let (text, _) = compensate_on(rig, &original, Frame::Joint, 0.5, true);
    let words = |l: &str| -> Vec<String> {
        l.split(';')
            .next()
            .unwrap()
            .split_whitespace()
            .map(|w| {
                w.trim_start_matches(|c: char| c.is_ascii_alphabetic())
                    .to_string()
            })
            .collect()
    };
    let mut changed = 0;
    for (a, b) in original.lines().zip(text.lines()) {
        if a == b {
            continue;
        }
        changed += 1;
        // Same comment, same words in the same order (an added word at the end of the axes).
        assert_eq!(
            a.split_once(';').map(|c| c.1),
            b.split_once(';').map(|c| c.1)
        );
        let (wa, wb) = (words(a), words(b));
        assert!(
            wb.len() >= wa.len() && wb.len() <= wa.len() + 2,
            "{a} -> {b}"
        );
        let code = b.split(';').next().unwrap();
        for w in code
            .split_whitespace()
            .filter(|w| w.len() > 1 && "XYZBC".contains(&w[..1]))
        {
            let v = &w[1..];
            assert!(v.starts_with('+') || v.starts_with('-'), "{b}");
            assert!(v.split('.').nth(1).is_some_and(|d| d.len() == 4), "{b}");
        }
    }
    assert!(changed > 3000);
}

/// The motions of a fixture in `tests/data/heidenhain/`.
fn fixture_motions(file: &str, machine: Option<&Machine>) -> Vec<(usize, Motion)> {
    let text = std::fs::read_to_string(root().join("tests/data/heidenhain").join(file)).unwrap();
    motions(&text, machine).unwrap()
}

/// The motions of one program line, in order.
fn motions_of_line(m: &[(usize, Motion)], line: usize) -> Vec<Motion> {
    m.iter()
        .filter(|(l, _)| *l == line)
        .map(|(_, m)| *m)
        .collect()
}

/// The last motion of source line `line`.
fn last_of(m: &[(usize, Motion)], line: usize) -> Motion {
    m.iter()
        .rev()
        .find(|(l, _)| *l == line)
        .map(|(_, m)| *m)
        .unwrap_or_else(|| panic!("no motion on line {line}"))
}

/// `RND R5` and `CHF 4` between straight lines (TNC 620 Klartext user's
/// manual 01/2022, "Corner rounding RND" p. 157, "Chamfer CHF" p. 156):
/// the line before ends where the rounding or chamfer begins, the arc is
/// tangent to both lines (chords within 0.5 µm), the chamfer side length is
/// measured from the corner; a rounding too large for its corner and one
/// between an arc and the line going on tangentially from it are located
/// errors.
#[test]
fn rnd_and_chf_between_straight_lines() {
    let m = fixture_motions("rnd-chf-corners.h", None);
    assert_point(xyz(&last_of(&m, 8).end), [15.0, 0.0, 0.0]);
    let arc: Vec<&Motion> = m.iter().filter(|(l, _)| *l == 10).map(|(_, m)| m).collect();
    assert!(arc.len() > 10, "{}", arc.len());
    for mv in &arc {
        let p = xyz(&mv.end);
        assert_abs_diff_eq!((p[0] - 15.0).hypot(p[1] - 5.0), 5.0, epsilon = 1e-9);
        assert!(p[0] >= 15.0 - 1e-9 && p[1] <= 5.0 + 1e-9, "{p:?}");
    }
    assert_point(xyz(&arc.last().unwrap().end), [20.0, 5.0, 0.0]);
    assert_point(xyz(&last_of(&m, 12).start), [20.0, 5.0, 0.0]);
    assert_point(xyz(&last_of(&m, 12).end), [20.0, 16.0, 0.0]);
    assert_point(xyz(&last_of(&m, 14).end), [16.0, 20.0, 0.0]);
    assert_point(xyz(&last_of(&m, 15).start), [16.0, 20.0, 0.0]);
    assert_point(xyz(&last_of(&m, 15).end), [0.0, 20.0, 0.0]);
    let head = "0 BEGIN PGM R MM\n1 TOOL CALL 1 Z\n2 L X+0 Y+0 Z+0 R0 F500\n";
    let e = motions(
        &format!("{head}3 L X+20\n4 RND R25\n5 L Y+20\n6 END PGM R MM\n"),
        None,
    )
    .unwrap_err();
    assert!(e.contains("t.h:5:") && e.contains("too large"), "{e}");
    // After an arc that the line goes on from tangentially: no corner.
    let e = motions(
        &format!("{head}3 CC X+10 Y+0\n4 C X+20 Y+0 DR+\n5 RND R2\n6 L Y+20\n7 END PGM R MM\n"),
        None,
    )
    .unwrap_err();
    assert!(e.contains("t.h:6:") && e.contains("no corner"), "{e}");
}

/// `RND` next to arcs (`rnd-next-to-arcs.h`; TNC 620 Klartext user's
/// manual 01/2022 p. 157: "a circular arc with tangential connection to the
/// preceding and subsequent contour elements"), worked by hand (the same
/// construction as `geometry::tests::round_line_and_arc_and_two_arcs`):
/// - the line along +X to the corner X+10 Y+0, then `C X+30 Y+0 DR+`
///   about CC X+20 Y+0 (leaving the corner along -Y: a right turn),
///   `RND R2`: its centre m₁ is 2 below the line and 10 + 2 from the
///   pole: m₁ = (20 − √140, −2); the line ends at (20 − √140, 0); the
///   arc starts at (20, 0) + 10·(m₁ − (20, 0))/12;
/// - the arc arrives at X+30 Y+0 along +Y, the line to X+40 Y+10 leaves
///   along (1, 1)/√2 (a right turn), `RND R1`: m₂ is 1 to the right of
///   that line, p = (30, 0) + (1, −1)/√2 + t·d, and 10 + 1 from the pole:
///   t² + 2t(d·w) + |w|² − 121 = 0 with w = p₀ − (20, 0), the root
///   nearest the corner; the arc ends at (20, 0) + 10·(m₂ − (20, 0))/11,
///   the line starts at (30, 0) + t·d.
///
/// The arc before a rounding is handed on as chords (written back flat,
/// as the line before one); `CHF` next to an arc is the control's refusal
/// (a chamfer only between two straight lines, p. 154).
#[test]
fn rnd_next_to_arcs_by_hand() {
    let m = fixture_motions("rnd-next-to-arcs.h", None);
    let of = |line: usize| motions_of_line(&m, line);
    let r140 = 140f64.sqrt();
    let m1 = [20.0 - r140, -2.0];
    assert_point(xyz(&last_of(&m, 7).end), [20.0 - r140, 0.0, 0.0]);
    let round1 = of(8);
    for x in &round1 {
        assert_abs_diff_eq!(
            (x.end.x - m1[0]).hypot(x.end.y - m1[1]),
            2.0,
            epsilon = 1e-9
        );
    }
    let t2 = [
        20.0 + 10.0 * (m1[0] - 20.0) / 12.0,
        10.0 * m1[1] / 12.0,
        0.0,
    ];
    assert_point(xyz(&round1.last().unwrap().end), t2);
    // The arc: from the rounding's end, on the circle about the pole.
    let arc = of(9);
    assert_point(xyz(&arc[0].start), t2);
    for x in &arc {
        assert_abs_diff_eq!((x.end.x - 20.0).hypot(x.end.y), 10.0, epsilon = 1e-9);
        assert!(x.end.y <= 1e-9, "{:?}", x.end);
    }
    let d = [0.5f64.sqrt(), 0.5f64.sqrt()];
    let p0 = [30.0 + d[0], -d[1]];
    let w = [p0[0] - 20.0, p0[1]];
    let b = d[0] * w[0] + d[1] * w[1];
    let t = -b + (b * b - (w[0] * w[0] + w[1] * w[1] - 121.0)).sqrt();
    let m2 = [p0[0] + t * d[0], p0[1] + t * d[1]];
    let t1 = [
        20.0 + 10.0 * (m2[0] - 20.0) / 11.0,
        10.0 * m2[1] / 11.0,
        0.0,
    ];
    assert_point(xyz(&arc.last().unwrap().end), t1);
    let round2 = of(10);
    for x in &round2 {
        assert_abs_diff_eq!(
            (x.end.x - m2[0]).hypot(x.end.y - m2[1]),
            1.0,
            epsilon = 1e-9
        );
    }
    let start = [30.0 + t * d[0], t * d[1], 0.0];
    assert_point(xyz(&round2.last().unwrap().end), start);
    assert_point(xyz(&last_of(&m, 11).start), start);
    assert_point(xyz(&last_of(&m, 11).end), [40.0, 10.0, 0.0]);
    let text =
        std::fs::read_to_string(root().join("tests/data/heidenhain/rnd-next-to-arcs.h")).unwrap();
    let e = motions(&text.replace("9 RND R1", "9 CHF 1"), None).unwrap_err();
    assert!(
        e.contains("t.h:10:") && e.contains("two straight lines"),
        "{e}"
    );
    // R20 at the first corner: its tangent point on the line would be at
    // x = 20 − √(30² − 20²) = −2.36, before the line's start.
    let e = motions(&text.replace("7 RND R2", "7 RND R20"), None).unwrap_err();
    assert!(e.contains("t.h:8:") && e.contains("too large"), "{e}");
    // Compensated on head-table: it reads back and the tip error is cut.
    let rig = rig("head-table");
    let (out, _) = compensate_on(rig, &text, Frame::Joint, 0.5, true);
    motions(&out, Some(&rig.0)).unwrap();
    let (before, after) = closed_loop_on(rig, &text, &out, Frame::Joint);
    assert!(
        after.max_um <= 0.1 * before.max_um,
        "{before:?} -> {after:?}"
    );
    println!(
        "rnd-next-to-arcs head-table: tip max {:.2} -> {:.3} µm",
        before.max_um, after.max_um
    );
}

/// PLANE PROJECTED, EULER, POINTS and RELATIVE (TNC 640 user's manual,
/// "The PLANE function") defining one plane, solved on head-table's chain:
/// the same joints and the same tip (worked in the fixture's comments).
#[test]
fn plane_forms_projected_euler_points_relative() {
    let (machine, _) = rig("head-table");
    let m = fixture_motions("plane-forms-head-table.h", Some(machine));
    let s = 30f64.to_radians().sin_cos();
    for line in [12, 15, 18, 22] {
        let mv = last_of(&m, line);
        assert_eq!(mv.frame, Frame::Part, "line {line}");
        assert_near(xyz(&mv.end), [10.0 * s.1, 0.0, -10.0 * s.0], 1e-6);
        assert_abs_diff_eq!(mv.end.b, 30.0, epsilon = 1e-6);
        assert_abs_diff_eq!(mv.end.c, 0.0, epsilon = 1e-6);
    }
}

/// MOVE DIST (about the point DIST below the tip), STAY with SEQ- and the
/// Q120–Q122 it leaves, CYCL DEF 19 with spatial angles (TNC 640 user's
/// manual, "Specifying the positioning behavior of the PLANE function",
/// "Cycle 19 WORKING PLANE"; worked in the fixture's comments).
#[test]
fn plane_move_stay_and_cycl_def_19_position_the_axes() {
    let (machine, _) = rig("head-table");
    let m = fixture_motions("plane-move-stay-cycl19.h", Some(machine));
    let (s, c) = 30f64.to_radians().sin_cos();
    let turn = last_of(&m, 10);
    assert_eq!(turn.frame, Frame::Part);
    assert_point(xyz(&turn.start), [0.0, 0.0, 50.0]);
    assert_near(xyz(&turn.end), [25.0, 0.0, 50.0 * c], 1e-9);
    assert_abs_diff_eq!(turn.end.b, 30.0, epsilon = 1e-6);
    assert_near(xyz(&last_of(&m, 12).end), [10.0 * s, 0.0, 10.0 * c], 1e-6);
    // STAY: no motion on line 15; the program's own rotary block turns them.
    assert!(m.iter().all(|(l, _)| *l != 15));
    let stay = last_of(&m, 16);
    assert_abs_diff_eq!(stay.end.b, -30.0, epsilon = 1e-6);
    assert_abs_diff_eq!(stay.end.c.abs(), 180.0, epsilon = 1e-6);
    let after = last_of(&m, 18);
    assert_near(xyz(&after.end), [10.0 * c, 0.0, -10.0 * s], 1e-6);
    assert_abs_diff_eq!(after.end.b, -30.0, epsilon = 1e-6);
    // CYCL DEF 19: no motion of its own, B+30 through Q121.
    assert!(m.iter().all(|(l, _)| *l != 22));
    assert_abs_diff_eq!(last_of(&m, 23).end.b, 30.0, epsilon = 1e-6);
    let cut = last_of(&m, 25);
    assert_near(xyz(&cut.end), [10.0 * c, 0.0, -10.0 * s], 1e-6);
    let back = last_of(&m, 28);
    assert_abs_diff_eq!(back.end.b, 0.0, epsilon = 1e-9);
    assert_abs_diff_eq!(back.end.c, 0.0, epsilon = 1e-9);
    // Without the machine, CYCL DEF 19 cannot be solved: a located error.
    let text =
        std::fs::read_to_string(root().join("tests/data/heidenhain/plane-move-stay-cycl19.h"))
            .unwrap();
    let e = motions(&text, None).unwrap_err();
    assert!(e.contains("--machine") && e.contains("t.h:10:"), "{e}");
}

/// `PLANE … MB` (TNC 620 conversational user's manual 10/2017 p. 556: the
/// retraction MB "is effective incrementally from the current tool position
/// in the active tool axis direction that the control approaches before
/// tilting"), worked by hand on head-table. From X+0 Y+0 Z+10 with no plane
/// active, `MB+40` first lifts the tool along Z to Z+50 (a leg of the
/// control, like the turn: in the block's `Home` legs, not compensated),
/// then `MOVE DIST+50` tilts about the point 50 below that tip: tip
/// = (0, 0, 50) + 50·((sin 30°, 0, cos 30°) − (0, 0, 1)) = X+25 Z+43.3013.
/// After `L Z+10` (the tip at Ry(30°)·(0, 0, 10) = X+5 Z+8.6603),
/// `PLANE RESET TURN MB+20` retracts along the tilted tool axis: X+15
/// Z+25.9808, before the axes turn back. `MB MAX` (to the software limit
/// switch: no travel limits are read) and `MB` with `STAY` are refused.
#[test]
fn plane_mb_retracts_before_tilting() {
    let (machine, _) = rig("head-table");
    let head = "0 BEGIN PGM MB MM\n1 TOOL CALL 1 Z S1000\n2 L X+0 Y+0 Z+10 R0 FMAX\n";
    let text = format!(
        "{head}3 PLANE SPATIAL SPA+0 SPB+30 SPC+0 MOVE DIST+50 MB+40 F2000\n4 L Z+10 F500\n5 PLANE RESET TURN MB+20 FMAX\n6 END PGM MB MM\n"
    );
    let program = program(&text, Some(machine));
    let mut run = program.run(interpret_options_on(machine, Frame::Joint));
    let mut legs = Vec::new();
    while let Some(step) = run.next() {
        let (_, event, executed) = step.unwrap();
        if matches!(executed.line, 4 | 6) {
            match &event.moves {
                volcomp::gcode::Moves::Home(m) => legs.push(m.clone()),
                other => panic!("line {}: {other:?}", executed.line),
            }
        }
    }
    let (s, c) = 30f64.to_radians().sin_cos();
    let [first, second] = &legs[..] else {
        panic!("{legs:?}")
    };
    assert_eq!(first.len(), 2);
    assert_eq!(first[0].frame, Frame::Joint);
    assert_point(xyz(&first[0].start), [0.0, 0.0, 10.0]);
    assert_point(xyz(&first[0].end), [0.0, 0.0, 50.0]);
    assert_abs_diff_eq!(first[0].end.b, 0.0, epsilon = 1e-12);
    assert_near(xyz(&first[1].end), [25.0, 0.0, 50.0 * c], 1e-9);
    assert_abs_diff_eq!(first[1].end.b, 30.0, epsilon = 1e-6);
    assert_eq!(second[0].frame, Frame::Part);
    assert_near(xyz(&second[0].start), [10.0 * s, 0.0, 10.0 * c], 1e-6);
    assert_near(xyz(&second[0].end), [30.0 * s, 0.0, 30.0 * c], 1e-6);
    assert_abs_diff_eq!(second[1].end.b, 0.0, epsilon = 1e-9);
    let e = motions(&text.replace("MB+20", "MB MAX"), Some(machine)).unwrap_err();
    assert!(e.contains("t.h:6:") && e.contains("MB MAX"), "{e}");
    let e = motions(&text.replace("MOVE DIST+50", "STAY"), Some(machine)).unwrap_err();
    assert!(e.contains("t.h:4:") && e.contains("STAY with MB"), "{e}");
}

/// A plane the machine cannot reach (head-table's B travels ±100°; SPA+120
/// needs 120°), TABLE ROT where the table would take the rotation about
/// the tool axis (refused, naming it), COORD ROT (the table stays, the
/// coordinates turn: TNC 640 user's manual, "Transformation type").
#[test]
fn plane_refusals_and_coord_rot() {
    let (machine, _) = rig("head-table");
    let head = "0 BEGIN PGM P MM\n1 TOOL CALL 1 Z S1000\n";
    let e = motions(
        &format!("{head}2 PLANE SPATIAL SPA+120 SPB+0 SPC+0 TURN FMAX\n3 END PGM P MM\n"),
        Some(machine),
    )
    .unwrap_err();
    assert!(e.contains("t.h:3:") && e.contains("cannot reach"), "{e}");
    let e = motions(
        &format!("{head}2 PLANE SPATIAL SPA+0 SPB+0 SPC+30 TURN FMAX TABLE ROT\n3 END PGM P MM\n"),
        Some(machine),
    )
    .unwrap_err();
    assert!(e.contains("t.h:3:") && e.contains("TABLE ROT"), "{e}");
    let m = motions(
        &format!("{head}2 PLANE SPATIAL SPA+0 SPB+0 SPC+30 TURN FMAX COORD ROT\n3 L X+10 Y+0 Z+0 R0 F500\n4 END PGM P MM\n"),
        Some(machine),
    )
    .unwrap();
    let (s, c) = 30f64.to_radians().sin_cos();
    let mv = last_of(&m, 4);
    assert_near(xyz(&mv.end), [10.0 * c, 10.0 * s, 0.0], 1e-9);
    assert_abs_diff_eq!(mv.end.c, 0.0, epsilon = 1e-9);
}

/// A circle in a tilted working plane (TNC 640 user's manual, "Tilting the
/// working plane": contours are programmed in the tilted plane): `CC` and
/// `C` after `PLANE SPATIAL SPB+30`, the arc in the tilted plane, handed
/// on as chords within 0.5 µm, each end on the circle of radius 10 about
/// the pole, in the plane whose normal is (sin 30°, 0, cos 30°).
#[test]
fn circle_in_a_tilted_plane_lies_in_it() {
    let (machine, _) = rig("head-table");
    let text = "0 BEGIN PGM A MM\n1 TOOL CALL 1 Z S1000\n2 PLANE SPATIAL SPA+0 SPB+30 SPC+0 TURN FMAX\n3 L X+10 Y+0 Z+0 R0 F500\n4 CC X+0 Y+0\n5 C X+0 Y+10 DR+\n6 END PGM A MM\n";
    let m = motions(text, Some(machine)).unwrap();
    let (s, c) = 30f64.to_radians().sin_cos();
    let chords: Vec<&Motion> = m.iter().filter(|(l, _)| *l == 6).map(|(_, m)| m).collect();
    assert!(chords.len() > 20);
    for mv in &chords {
        let p = xyz(&mv.end);
        assert_abs_diff_eq!(p[0] * s + p[2] * c, 0.0, epsilon = 1e-9);
        assert_abs_diff_eq!(
            (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt(),
            10.0,
            epsilon = 1e-9
        );
        assert_eq!(mv.frame, Frame::Part);
    }
    assert_near(xyz(&chords.last().unwrap().end), [0.0, 10.0, 0.0], 1e-9);
    // The middle of the arc: R·(10 cos 45°, 10 sin 45°, 0).
    let h = 0.5f64.sqrt();
    let mid = chords
        .iter()
        .map(|mv| xyz(&mv.end))
        .min_by(|a, b| {
            let d = |p: &[f64; 3]| (p[1] - 10.0 * h).abs();
            d(a).total_cmp(&d(b))
        })
        .unwrap();
    assert_near(mid, [10.0 * h * c, 10.0 * h, -10.0 * h * s], 0.2);
}

/// The closed loop of 3+2 programs with the working plane tilted by `PLANE
/// SPATIAL … TURN` and by `CYCL DEF 19` (arcs, a rounding, in the tilted
/// plane) on two bundled machines each: the tip error cut by ≥ 90 %, the
/// output read back.
#[test]
fn closed_loop_plane_turn_and_cycl19_arcs_on_two_machines() {
    let summary = closed_loop_rows(&[
        ("bc-trt", "tests/data/heidenhain/plane-spatial-32.h"),
        (
            "head-table",
            "tests/data/heidenhain/tilted-arcs-cycl19-32.h",
        ),
        ("bc-trt", "tests/data/heidenhain/tilted-arcs-cycl19-32.h"),
    ]);
    insta::assert_snapshot!("heidenhain_closed_loop_tilted", summary);
}

/// Rotary-axis correction in 3+2 (issue 35; dialects.md "Writing back":
/// under a tilted plane the tip is corrected, and the tool axis where the
/// program commands the rotary axes itself): after `PLANE … STAY` and
/// `CYCL DEF 19` the program turns the axes with `L B+Q121 C+Q122`; that
/// block is corrected in tip and tool axis (its `Q` words written as
/// numbers), and the blocks the plane then holds run at those corrected
/// axes. On two machines the replayed tip error and the tool-axis error at
/// the cutting block ends are cut by ≥ 90 %.
#[test]
fn closed_loop_stay_rotary_block_corrects_the_tool_axis() {
    let file = "tests/data/heidenhain/plane-stay-rotary-block.h";
    let mut summary = closed_loop_rows(&[("head-table", file), ("bc-trt", file)]);
    let original = std::fs::read_to_string(root().join(file)).unwrap();
    for machine in ["head-table", "bc-trt"] {
        let rig = rig(machine);
        // Block ends only (no split pieces), so that blocks pair by line.
        let (text, _) = compensate_on(rig, &original, Frame::Joint, 1e3, true);
        assert_eq!(text.lines().count(), original.lines().count());
        let rotary_block = text.lines().nth(11).unwrap();
        assert!(
            rotary_block.starts_with("11 L X") && rotary_block.contains(" B-39.99"),
            "{rotary_block}"
        );
        assert!(!rotary_block.contains('Q'), "{rotary_block}");
        let (axis_before, _, n) = replayed_axis_error_on(rig, &original, &original, Frame::Joint);
        let (axis_after, axis_rms_after, m) =
            replayed_axis_error_on(rig, &original, &text, Frame::Joint);
        assert_eq!(n, m);
        assert!(axis_before > 10.0, "{machine}: {axis_before}");
        // The axes are held over the whole plane, so the part of the axis
        // error that varies with X Y Z over the cut (the linear axes'
        // angular errors: 32–45 µrad before along the first plane's passes
        // on head-table) stays; the rotary block takes out the rest.
        assert!(
            axis_after <= 0.25 * axis_before,
            "{machine}: tool axis {axis_before} -> {axis_after} µrad"
        );
        summary += &format!(
            "{machine}: tool axis max {axis_before:.1} -> {axis_after:.2} µrad (rms after {axis_rms_after:.2}), {n} cutting block ends\n"
        );
    }
    insta::assert_snapshot!("heidenhain_closed_loop_stay_rotary", summary);
}

/// `compensate` of polar blocks whose ends move (docs/dialects.md
/// "Writing back", polar blocks): an `LP` is written as the straight line
/// `L X Y Z` to its corrected end after a `; volcomp:` note; a `CP` keeps
/// its form, its pole moved for it (`CC` before, the program's pole again
/// after) so that its corrected start and end are equidistant from it, its
/// angle and `IZ` rewritten, a helix of more than 270° first turning its
/// half turns (each about the pole moved by the correction at its middle). The output reads back, and
/// on two machines the replayed tip error is cut by ≥ 90 %.
///
/// The ruler: the nominal path is a polyline, whose chords of `s` mm lie
/// `s² / (8 r)` inside an arc of radius `r`. The fixture's smallest arc is
/// the helix about `CC X+22 Y+21` from X+23.5 Y+20, `r = √(1.5² + 1²)` =
/// 1.80 mm: the default 0.1 mm chords lie 0.69 µm inside it, more than the
/// compensator's 0.5 µm tolerance, and an actual tip on the helix read as
/// 0.69 µm off (head-table measured 1.133 µm, 11 %, with them; the worst
/// sample 0.47 µm from the exact helix). At 0.01 mm the ruler's own error is
/// 0.007 µm.
#[test]
fn closed_loop_polar_lp_and_cp_written_back() {
    let file = "tests/data/heidenhain/polar-lp-cp.h";
    let original = std::fs::read_to_string(root().join(file)).unwrap();
    let smallest_radius_mm = 1.5f64.hypot(1.0);
    let ruler_step_mm = 0.01;
    assert!(ruler_step_mm * ruler_step_mm / (8.0 * smallest_radius_mm) < 1e-5);
    let mut summary = String::new();
    for machine in ["head-table", "bc-trt"] {
        let rig = rig(machine);
        let (text, report) = compensate_on(rig, &original, Frame::Joint, 0.5, true);
        for (k, line) in text.lines().enumerate() {
            assert!(line.starts_with(&format!("{k} ")), "{line}");
        }
        let (before, after) =
            closed_loop_with_ruler_on(rig, &original, &text, Frame::Joint, ruler_step_mm);
        assert!(before.max_um > 5.0, "{machine}: nothing to compensate?");
        assert!(
            after.max_um <= 0.1 * before.max_um && after.rms_um <= 0.1 * before.rms_um,
            "{machine}: {before:?} -> {after:?}"
        );
        summary += &format!(
            "{machine} {file}: blocks changed {}, tip max {:.2} -> {:.3} µm ({:.2} %), rms {:.2} -> {:.3} µm\n",
            report.blocks_changed,
            before.max_um,
            after.max_um,
            100.0 * after.max_um / before.max_um,
            before.rms_um,
            after.rms_um,
        );
    }
    let (text, _) = compensate_on(rig("bc-trt"), &original, Frame::Joint, 0.5, true);
    let lines: Vec<&str> = text.lines().collect();
    let find = |needle: &str| {
        lines
            .iter()
            .position(|l| l.contains(needle))
            .unwrap_or_else(|| panic!("{needle}:\n{text}"))
    };
    // LP → L, after its note.
    let k = find("volcomp: line 10 written as L (its corrected end): LP PR+3 PA+90");
    assert!(
        lines[k + 1].split_whitespace().nth(1) == Some("L"),
        "{}",
        lines[k + 1]
    );
    assert!(lines[k + 1].contains(" X+20.00") && lines[k + 1].contains(" Y+23.00"));
    // CP IPA-450: two half turns, each about the pole moved by the
    // correction at its middle, then the rest about the equidistant pole,
    // then the program's pole again.
    let k = find("volcomp: line 13 written to its corrected end");
    let end = find("CC X+20 Y+20 ; volcomp: the pole of line 13 again");
    let pieces = &lines[k + 1..end];
    let halves = pieces
        .iter()
        .filter(|l| l.contains(" CP IPA-179.9") && l.contains(" IZ-0."))
        .count();
    assert_eq!(halves, 2, "{pieces:?}");
    assert!(pieces.iter().any(|l| l.contains(" CC X+")), "{pieces:?}");
    let last = pieces.last().unwrap();
    assert!(
        last.contains(" CP IPA-90.") && last.contains(" F700"),
        "{last}"
    );
    insta::assert_snapshot!("heidenhain_closed_loop_polar", summary);
}

/// The bundled nutating-head machine (`machines/nutating-head-table.toml`,
/// a model of the DMU duoBLOCK's layout: B about `[0, 0.7071, 0.7071]`, C
/// table) and the A/C table in ISO 841 senses (`ac-trt-iso.toml`), worked
/// by hand. `PLANE SPATIAL SPA+90 SPB+0 SPC+90` puts the tool along the
/// workpiece's +X (`Rz(90°)·Rx(90°)·Z`); the head's B180 turns the spindle
/// to +Y (`2(n·Z)n − Z` for `n = (0, 1, 1)/√2`), and the table's C then
/// brings the part's +X there: `Rz(C)·Y = X` at C = −90°, hyperMILL's
/// `; B180 C270`. On the A/C table, `SPA-90` puts the tool along +Y:
/// `Rx(A)·Z = Y` at A = −90°, C = 0 (hyperMILL's `; A-90 C0`), where
/// LinuxCNC's senses (`xyzac-trt`) give C = 180° (TNC 640 user's manual,
/// "PLANE SPATIAL"; dialects.md "Rotary senses").
#[test]
fn nutating_head_and_iso_table_solve_planes_as_the_cam_comments_say() {
    let run = |machine: &str, plane: &str, rotary: &str| {
        let seq = if rotary.starts_with('A') {
            "SEQ-"
        } else {
            "SEQ+"
        };
        let m = Machine::load(&root().join(format!("machines/{machine}.toml"))).unwrap();
        let text = format!(
            "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z S1000\n2 {plane} STAY {seq}\n3 L {rotary} R0 FMAX\n4 END PGM T MM\n"
        );
        let moves = motions(&text, Some(&m)).unwrap();
        moves.last().unwrap().1.end
    };
    let end = run(
        "nutating-head-table",
        "PLANE SPATIAL SPA+90 SPB+0 SPC+90",
        "B+Q121 C+Q122",
    );
    assert_abs_diff_eq!(end.b, 180.0, epsilon = 1e-5);
    assert_abs_diff_eq!(end.c.rem_euclid(360.0), 270.0, epsilon = 1e-5);
    let end = run(
        "nutating-head-table",
        "PLANE SPATIAL SPA+0 SPB+0 SPC+0",
        "B+Q121 C+Q122",
    );
    assert_abs_diff_eq!(end.b, 0.0, epsilon = 1e-9);
    let end = run(
        "ac-trt-iso",
        "PLANE SPATIAL SPA-90 SPB+0 SPC+0",
        "A+Q120 C+Q122",
    );
    assert_abs_diff_eq!(end.a, -90.0, epsilon = 1e-5);
    assert_abs_diff_eq!(end.c, 0.0, epsilon = 1e-5);
    let end = run(
        "xyzac-trt",
        "PLANE SPATIAL SPA-90 SPB+0 SPC+0",
        "A+Q120 C+Q122",
    );
    assert_abs_diff_eq!(end.a, -90.0, epsilon = 1e-5);
    assert_abs_diff_eq!(end.c.abs(), 180.0, epsilon = 1e-5);
}

/// `APPR LT` and `DEP LT` with `R0` (TNC 640 user's manual, "Approaching
/// and departing a contour": with R0 the control computes the path for a
/// tool of radius 0): the approach reaches the first contour point X+10
/// Y+0 from the auxiliary point LEN 5 before it on the first element's
/// line (X+5 Y+0); the departure goes on LEN 4 along the last element
/// (from X+30 Y+0 to X+34 Y+0). `APPR PLT` with no pole programmed is
/// refused at its block (the polar forms: `appr_dep_polar_by_hand`); `RL`
/// as on any move.
#[test]
fn appr_and_dep_lt() {
    let text = "0 BEGIN PGM A MM\n1 TOOL CALL 1 Z\n2 L X-10 Y+20 Z+0 R0 FMAX\n3 APPR LT X+10 Y+0 LEN5 R0 F300\n4 L X+30\n5 DEP LT LEN4 F600\n6 END PGM A MM\n";
    let m = motions(text, None).unwrap();
    let approach: Vec<&Motion> = m.iter().filter(|(l, _)| *l == 4).map(|(_, m)| m).collect();
    assert_eq!(approach.len(), 2);
    assert_point(xyz(&approach[0].start), [-10.0, 20.0, 0.0]);
    assert_point(xyz(&approach[0].end), [5.0, 0.0, 0.0]);
    assert_point(xyz(&approach[1].end), [10.0, 0.0, 0.0]);
    assert_point(xyz(&last_of(&m, 6).start), [30.0, 0.0, 0.0]);
    assert_point(xyz(&last_of(&m, 6).end), [34.0, 0.0, 0.0]);
    let e = motions(
        &text.replace("APPR LT X+10 Y+0", "APPR PLT PR+10 PA+0"),
        None,
    )
    .unwrap_err();
    assert!(
        e.contains("t.h:4:") && e.contains("APPR PLT without a pole"),
        "{e}"
    );
    let e = motions(&text.replace("LEN5 R0", "LEN5 RL"), None).unwrap_err();
    assert!(e.contains("t.h:4:") && e.contains("RL"), "{e}");
}

/// `APPR`/`DEP` `LN`, `CT`, `LCT` with `R0` (`appr-dep-ln-ct-lct.h`; TNC7
/// user's manual 81762x-16/-18, "Approach function APPR LN | CT | LCT";
/// TNC 640 DIN/ISO user's manual 1/2015 pp. 213 ff.), worked by hand. Every
/// contour runs along +X with the start below it (-Y): the tool is on the
/// right, so the arcs turn clockwise.
/// - `APPR LN X+10 Y+0 Z-2 LEN5`: from X+0 Y-20 (rapid: the block before
///   is FMAX) to PH = PA + 5·(0, -1) = X+10 Y-5 Z-2, then to PA.
/// - `DEP CT CCA90 R+4` at X+40 Y+30 going +Y: centre 4 to the right,
///   X+44 Y+30; a clockwise quarter from the west point ends at the north
///   point X+44 Y+34.
/// - `APPR CT X+50 Y+0 CCA90 R+4`: centre X+50 Y-4, PH 90° back (clockwise
///   arc) at the west point X+46 Y-4.
/// - `DEP LN LEN5` at X+80 Y+0: to X+80 Y-5.
/// - `APPR LCT X+100 Y+0 R4` from X+100 Y-16: centre C = X+100 Y-4; the
///   tangent point H from P satisfies (H−C)·(P−C) = R², |H−C| = R: with
///   P−C = (0, −12), (H−C)_y = −16/12 = −4/3 and (H−C)_x = −√(16 − 16/9)
///   = −4√8/3 (the clockwise arc must pass the west point to arrive
///   moving +X): H = X+96.228764 Y-5.333333; the line at F300 (the APPR
///   block's feed for LCT).
/// - `DEP LCT X+140 Y-10 Z+5 R4` at X+130 Y+0: centre X+130 Y-4, N−C =
///   (10, −6): 10x − 6y = 16, x² + y² = 16 → 1.36y² + 1.92y − 13.44 = 0,
///   y = (−1.92 + √76.8)/2.72 (the clockwise arc from the north point
///   goes to the east side): H = C + (1.6 + 0.6y, y); then the line to
///   X+140 Y-10 at Z-2, then up to Z+5.
#[test]
fn appr_dep_ln_ct_lct_by_hand() {
    let m = fixture_motions("appr-dep-ln-ct-lct.h", None);
    let of = |line: usize| motions_of_line(&m, line);
    let on_circle = |mv: &[Motion], c: [f64; 2]| {
        for x in mv {
            assert_abs_diff_eq!((x.end.x - c[0]).hypot(x.end.y - c[1]), 4.0, epsilon = 1e-9);
        }
    };
    let a = of(6);
    assert_eq!(a.len(), 2);
    assert_eq!(a[0].kind, MotionKind::Rapid);
    assert_point(xyz(&a[0].end), [10.0, -5.0, -2.0]);
    assert_point(xyz(&a[1].end), [10.0, 0.0, -2.0]);
    let d = of(9);
    assert!(d.len() > 10);
    on_circle(&d, [44.0, 30.0]);
    assert_point(xyz(&d[0].start), [40.0, 30.0, -2.0]);
    assert_point(xyz(&d.last().unwrap().end), [44.0, 34.0, -2.0]);
    assert!(
        d.iter()
            .all(|x| x.end.x <= 44.0 + 1e-9 && x.end.y >= 30.0 - 1e-9)
    );
    let a = of(12);
    assert_point(xyz(&a[0].end), [46.0, -4.0, -2.0]);
    on_circle(&a[1..], [50.0, -4.0]);
    assert!(
        a[1..]
            .iter()
            .all(|x| x.end.x <= 50.0 + 1e-9 && x.end.y >= -4.0 - 1e-9)
    );
    assert_point(xyz(&a.last().unwrap().end), [50.0, 0.0, -2.0]);
    assert_point(xyz(&last_of(&m, 14).end), [80.0, -5.0, -2.0]);
    let a = of(17);
    let h = [100.0 - 4.0 * 8f64.sqrt() / 3.0, -4.0 - 4.0 / 3.0, -2.0];
    assert_point(xyz(&a[0].start), [100.0, -16.0, 5.0]);
    assert_point(xyz(&a[0].end), h);
    assert_eq!(a[0].feed, volcomp::gcode::Feed::PerMinute(300.0));
    on_circle(&a[1..], [100.0, -4.0]);
    assert_point(xyz(&a.last().unwrap().end), [100.0, 0.0, -2.0]);
    let d = of(19);
    let y = (-1.92 + 76.8f64.sqrt()) / 2.72;
    let h = [130.0 + 1.6 + 0.6 * y, -4.0 + y, -2.0];
    let n = d.len();
    on_circle(&d[..n - 2], [130.0, -4.0]);
    assert_point(xyz(&d[n - 3].end), h);
    assert_point(xyz(&d[n - 2].end), [140.0, -10.0, -2.0]);
    assert_point(xyz(&d[n - 1].end), [140.0, -10.0, 5.0]);
    // The side comes from the start: one on the contour's line gives none.
    let text =
        std::fs::read_to_string(root().join("tests/data/heidenhain/appr-dep-ln-ct-lct.h")).unwrap();
    let e = motions(&text.replace("4 L X+0 Y-20", "4 L X+0 Y+0"), None).unwrap_err();
    assert!(e.contains("t.h:6:") && e.contains("no side"), "{e}");
    // A departure with no approach before it has no side.
    let e = motions(
        "0 BEGIN PGM D MM\n1 L X+0 Y+0 Z+0 R0 F100\n2 L X+10\n3 DEP LN LEN5\n4 END PGM D MM\n",
        None,
    )
    .unwrap_err();
    assert!(e.contains("t.h:4:") && e.contains("no side"), "{e}");
    let e = motions(&text.replace("R4 R0 F300", "R4 RR F300"), None).unwrap_err();
    assert!(e.contains("t.h:17:") && e.contains("RR"), "{e}");
}

/// The approach and departure program compensated on head-table and
/// bc-trt: every block reads back, the tip error is cut by at least 90 %.
#[test]
fn closed_loop_appr_dep() {
    let original =
        std::fs::read_to_string(root().join("tests/data/heidenhain/appr-dep-ln-ct-lct.h")).unwrap();
    let mut summary = String::new();
    for machine in ["head-table", "bc-trt"] {
        let rig = rig(machine);
        let (text, _) = compensate_on(rig, &original, Frame::Joint, 0.5, true);
        motions(&text, Some(&rig.0)).unwrap();
        let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
        assert!(before.max_um > 3.0, "{machine}: nothing to compensate?");
        assert!(
            after.max_um <= 0.1 * before.max_um,
            "{machine}: {before:?} -> {after:?}"
        );
        summary += &format!(
            "{machine}: tip max {:.2} -> {:.3} µm, rms {:.2} -> {:.3} µm\n",
            before.max_um, after.max_um, before.rms_um, after.rms_um
        );
    }
    println!("{summary}");
}

/// The polar approach and departure forms `APPR PLT`, `PLN`, `PCT`, `PLCT`
/// and `DEP PLCT` with `R0` (`appr-dep-polar.h`; TNC7 user's manual
/// 81762x-16, "Overview of path shapes" and "Approach functions APPR CT and
/// APPR PCT": the same paths with the contour point in polar coordinates
/// about a pole CC programmed before; TNC 620 Klartext user's manual
/// 01/2022 p. 147 for PS, PH, PA, PE, PN), worked by hand. Every contour
/// runs along +X with the start below it (the tool on the right, arcs
/// clockwise), as in `appr-dep-ln-ct-lct.h`:
/// - `CC X+20 Y+0`, `APPR PLT PR+10 PA+180 Z-2 LEN5`: PA = (20 − 10, 0) =
///   X+10 Y+0; PH = PA − 5·(1, 0) = X+5 Y+0 Z-2, rapid (the block before is
///   FMAX), then PA at F300.
/// - `CC X+40 Y+0`, `APPR PLN PR+10 PA+0 Z-2 LEN5` from X+60 Y-20: PA = X+50
///   Y+0, PH = PA + 5·(0, −1) = X+50 Y-5.
/// - `CC X+90 Y+0`, `APPR PCT PR+10 PA+0 Z-2 CCA90 R+4`: PA = X+100 Y+0, the
///   centre 4 to the right, X+100 Y-4, PH 90° back on the clockwise arc, at
///   its west point X+96 Y-4. `DEP CT CCA90 R+4` at X+130 Y+0 (the side
///   from the `APPR PCT`): centre X+130 Y-4, a clockwise quarter from its
///   north point to its east point X+134 Y-4.
/// - `CC X+190 Y+0`, `APPR PLCT PR+40 PA+180 Z-2 R4` from X+150 Y-16: PA =
///   X+150 Y+0, centre C = X+150 Y-4; the tangent point H from P with
///   (H−C)·(P−C) = R²: H = X+(150 − 4√8/3) Y-16/3, the line at F300.
/// - `DEP PLCT PR+10 PA-90 Z+5 R4` at X+180 Y+0: PN = X+190 Y-10; centre
///   X+180 Y-4, N − C = (10, −6): H = C + (1.6 + 0.6y, y), y = (−1.92 +
///   √76.8)/2.72; the line to PN at Z-2, then up to Z+5.
///
/// Each polar block runs as the Cartesian block to the same point does.
/// Refused, located: `DEP PLT` (the control's polar departure is `DEP
/// PLCT` only), a polar form with no pole, an `APPR` before anything but
/// `L`, `RND` after a helix.
#[test]
fn appr_dep_polar_by_hand() {
    let m = fixture_motions("appr-dep-polar.h", None);
    let of = |line: usize| motions_of_line(&m, line);
    let on_circle = |mv: &[Motion], c: [f64; 2]| {
        for x in mv {
            assert_abs_diff_eq!((x.end.x - c[0]).hypot(x.end.y - c[1]), 4.0, epsilon = 1e-9);
        }
    };
    let a = of(7);
    assert_eq!(a.len(), 2);
    assert_eq!(a[0].kind, MotionKind::Rapid);
    assert_point(xyz(&a[0].end), [5.0, 0.0, -2.0]);
    assert_point(xyz(&a[1].end), [10.0, 0.0, -2.0]);
    assert_eq!(a[1].feed, volcomp::gcode::Feed::PerMinute(300.0));
    let a = of(13);
    assert_eq!(a.len(), 2);
    assert_point(xyz(&a[0].end), [50.0, -5.0, -2.0]);
    assert_point(xyz(&a[1].end), [50.0, 0.0, -2.0]);
    let a = of(19);
    assert_point(xyz(&a[0].end), [96.0, -4.0, -2.0]);
    on_circle(&a[1..], [100.0, -4.0]);
    assert!(
        a[1..]
            .iter()
            .all(|x| x.end.x <= 100.0 + 1e-9 && x.end.y >= -4.0 - 1e-9)
    );
    assert_point(xyz(&a.last().unwrap().end), [100.0, 0.0, -2.0]);
    let d = of(21);
    on_circle(&d, [130.0, -4.0]);
    assert_point(xyz(&d[0].start), [130.0, 0.0, -2.0]);
    assert_point(xyz(&d.last().unwrap().end), [134.0, -4.0, -2.0]);
    let a = of(25);
    let h = [150.0 - 4.0 * 8f64.sqrt() / 3.0, -16.0 / 3.0, -2.0];
    assert_point(xyz(&a[0].start), [150.0, -16.0, 5.0]);
    assert_point(xyz(&a[0].end), h);
    assert_eq!(a[0].feed, volcomp::gcode::Feed::PerMinute(300.0));
    on_circle(&a[1..], [150.0, -4.0]);
    assert_point(xyz(&a.last().unwrap().end), [150.0, 0.0, -2.0]);
    let d = of(27);
    let y = (-1.92 + 76.8f64.sqrt()) / 2.72;
    let h = [180.0 + 1.6 + 0.6 * y, -4.0 + y, -2.0];
    let n = d.len();
    on_circle(&d[..n - 2], [180.0, -4.0]);
    assert_point(xyz(&d[n - 3].end), h);
    assert_point(xyz(&d[n - 2].end), [190.0, -10.0, -2.0]);
    assert_point(xyz(&d[n - 1].end), [190.0, -10.0, 5.0]);
    // Each polar form runs as its Cartesian form to the same point.
    let text =
        std::fs::read_to_string(root().join("tests/data/heidenhain/appr-dep-polar.h")).unwrap();
    let cartesian = text
        .replace("APPR PLT PR+10 PA+180", "APPR LT X+10 Y+0")
        .replace("APPR PLN PR+10 PA+0", "APPR LN X+50 Y+0")
        .replace("APPR PCT PR+10 PA+0", "APPR CT X+100 Y+0")
        .replace("APPR PLCT PR+40 PA+180", "APPR LCT X+150 Y+0")
        .replace("DEP PLCT PR+10 PA-90", "DEP LCT X+190 Y-10");
    assert!(!cartesian.contains(" PR+"));
    let c = motions(&cartesian, None).unwrap();
    assert_eq!(c.len(), m.len());
    for ((l, p), (k, q)) in m.iter().zip(&c) {
        assert_eq!(l, k);
        assert_near(xyz(&p.end), xyz(&q.end), 1e-9);
        assert_eq!(p.feed, q.feed, "line {l}");
    }
    // Incremental polar words from the current position, as LP's: from
    // X+0 Y-20 about X+20 Y+0 the angle is 225°; IPA+45 turns it to 270°
    // and PR+10 sets the radius: PA = X+20 Y-10, PH 5 before it on +X.
    let inc = motions(
        &text.replace("APPR PLT PR+10 PA+180", "APPR PLT PR+10 IPA+45"),
        None,
    )
    .unwrap();
    let a: Vec<&Motion> = inc
        .iter()
        .filter(|(l, _)| *l == 7)
        .map(|(_, m)| m)
        .collect();
    assert_point(xyz(&a[0].end), [15.0, -10.0, -2.0]);
    assert_point(xyz(&a[1].end), [20.0, -10.0, -2.0]);
    // The refusals, each located.
    let e = motions(&text.replace("DEP PLCT PR+10 PA-90", "DEP PLT LEN5"), None).unwrap_err();
    assert!(e.contains("t.h:27:") && e.contains("DEP PLCT only"), "{e}");
    let e = motions(&text.replace("5 CC X+20 Y+0", "5 ; no pole"), None).unwrap_err();
    assert!(e.contains("t.h:7:") && e.contains("without a pole"), "{e}");
    let e = motions(&text.replace("7 L X+40", "7 C X+40 Y+0 DR-"), None).unwrap_err();
    assert!(
        e.contains("t.h:7:") && e.contains("APPR PLT before anything but a straight line"),
        "{e}"
    );
    let helix = "0 BEGIN PGM R MM\n1 TOOL CALL 1 Z\n2 L X+10 Y+0 Z+0 R0 F100\n3 CC X+0 Y+0\n4 CP IPA+90 IZ-2 DR+\n5 RND R2\n6 L X+20\n7 END PGM R MM\n";
    let e = motions(helix, None).unwrap_err();
    assert!(
        e.contains("t.h:6:")
            && e.contains("`RND after a helix or a full turn` is not read by volcomp yet"),
        "{e}"
    );
}

/// The polar approach and departure program compensated on head-table and
/// bc-trt: written flat (`L` blocks after a `; volcomp: … written flat`
/// note for each polar block), read back, the tip error cut by ≥ 90 %.
#[test]
fn closed_loop_appr_dep_polar() {
    let original =
        std::fs::read_to_string(root().join("tests/data/heidenhain/appr-dep-polar.h")).unwrap();
    let mut summary = String::new();
    for machine in ["head-table", "bc-trt"] {
        let rig = rig(machine);
        let (text, _) = compensate_on(rig, &original, Frame::Joint, 0.5, true);
        for form in ["APPR PLT", "APPR PLN", "APPR PCT", "APPR PLCT", "DEP PLCT"] {
            assert!(
                text.lines()
                    .any(|l| l.contains("written flat: ") && l.contains(form)),
                "{machine}: {form}\n{text}"
            );
        }
        for (k, line) in text.lines().enumerate() {
            assert!(line.starts_with(&format!("{k} ")), "{line}");
            let word = line.split_whitespace().nth(1);
            assert!(word != Some("APPR") && word != Some("DEP"), "{line}");
        }
        motions(&text, Some(&rig.0)).unwrap();
        let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
        assert!(before.max_um > 3.0, "{machine}: nothing to compensate?");
        assert!(
            after.max_um <= 0.1 * before.max_um && after.rms_um <= 0.1 * before.rms_um,
            "{machine}: {before:?} -> {after:?}"
        );
        summary += &format!(
            "{machine}: tip max {:.2} -> {:.3} µm ({:.2} %), rms {:.2} -> {:.3} µm\n",
            before.max_um,
            after.max_um,
            100.0 * after.max_um / before.max_um,
            before.rms_um,
            after.rms_um
        );
    }
    insta::assert_snapshot!("heidenhain_closed_loop_appr_dep_polar", summary);
}

/// What `compensate` writes for the new forms (dialects.md "Writing back"):
/// every block of the input is in the output renumbered, either as it was
/// (byte for byte after its number), with only its words' values changed,
/// or written flat (`; volcomp: line N written flat: …` and `L` blocks: an
/// `RND`, the line before it, an arc in the tilted plane, `APPR`/`DEP`);
/// the output reads back.
#[test]
fn tilted_plane_corner_and_approach_write_back() {
    let code = |l: &str| l.split_once(' ').map_or("", |x| x.1).to_string();
    // The addresses of a block's words, in order.
    let letters = |l: &str| -> Vec<String> {
        l.split(';')
            .next()
            .unwrap()
            .split_whitespace()
            .map(|w| w.chars().take_while(|c| c.is_ascii_alphabetic()).collect())
            .collect()
    };
    // `a` within `b` in order (a changed block may gain axis words).
    let within = |a: &[String], b: &[String]| {
        let mut it = b.iter();
        a.iter().all(|x| it.any(|y| y == x))
    };
    for (machine, file) in [
        (
            "head-table",
            "tests/data/heidenhain/tilted-arcs-cycl19-32.h",
        ),
        ("head-table", "tests/data/heidenhain/rnd-chf-corners.h"),
    ] {
        let rig = rig(machine);
        let original = std::fs::read_to_string(root().join(file)).unwrap();
        let original = original.replace("14 L X+0\n", "14 L X+0\n15 DEP LT LEN5 F500\n");
        let original = original.replace("15 END PGM CORNERS", "16 END PGM CORNERS");
        let (text, _) = compensate_on(rig, &original, Frame::Joint, 0.5, true);
        let out: Vec<String> = text.lines().map(code).collect();
        for line in original.lines().skip(1) {
            let c = code(line);
            let flat = out
                .iter()
                .any(|o| o.contains(&format!("written flat: {}", c.trim())));
            let same = out.contains(&c);
            let changed = out.iter().any(|o| within(&letters(&c), &letters(o)));
            assert!(same || flat || changed, "{file}: {line}");
        }
        for (k, line) in text.lines().enumerate() {
            assert!(line.starts_with(&format!("{k} ")), "{file}: {line}");
        }
        motions(&text, Some(&rig.0)).unwrap();
    }
}

/// The tool-axis coordinates of the moves of line `line` (rounded to 1e-9).
fn z_of(m: &[(usize, Motion)], line: usize) -> Vec<f64> {
    m.iter()
        .filter(|(l, _)| *l == line)
        .map(|(_, m)| (m.end.z * 1e9).round() / 1e9)
        .collect()
}

/// Machining cycles (TNC 640 Cycle Programming; TNC 320 Cycle Programming
/// 340 55x-04, chapter 3): cycle 203 UNIVERSAL DRILLING (3.6: plunges of
/// Q202 less the decrement Q212, not under Q205; a chip break of Q256
/// before each of Q213 retractions), called by `CYCL CALL`, at each point
/// of a `PATTERN DEF` by `CYCL CALL PAT` (between points the clearance
/// height: the greater of the call's Z and Q204 above the surface; a
/// point's Z shifts the surface), by `CYCL CALL POS` and by `M99`; `M89`
/// calls it after every positioning block until `M99`; the old cycle 1
/// PECKING (advanced stop 0.6 mm); a cycle volcomp does not expand is
/// refused at its call, naming it.
#[test]
fn cycles_expand_at_their_calls() {
    let text = "0 BEGIN PGM C MM\n1 TOOL CALL 1 Z S1000\n2 L Z+100 R0 FMAX\n3 L X+10 Y+10 FMAX\n4 CYCL DEF 203 UNIVERSAL DRILLING ~\n  Q200=+2 ;SET-UP CLEARANCE ~\n  Q201=-10 ;DEPTH ~\n  Q206=+150 ~\n  Q202=+4 ~\n  Q210=+0 ~\n  Q203=+0 ~\n  Q204=+50 ~\n  Q212=+1 ~\n  Q213=+1 ~\n  Q205=+3 ~\n  Q211=+0 ~\n  Q208=+500 ~\n  Q256=+0.5\n5 CYCL CALL\n6 PATTERN DEF ~\n  POS1 (X+30 Y+10 Z+0) ~\n  ROW1 (X+0 Y+40 D+10 NUM2 ROT+0 Z-2)\n7 CYCL CALL PAT FMAX\n8 CYCL CALL POS X+5 Y+5 Z+0 FMAX\n9 L X+50 FMAX M99\n10 L X+60 FMAX M89\n11 L X+70 FMAX\n12 L X+80 FMAX M99\n13 L X+90 FMAX\n14 CYCL DEF 1.0 PECKING\n15 CYCL DEF 1.1 SET UP -2\n16 CYCL DEF 1.2 DEPTH -8\n17 CYCL DEF 1.3 PECKG -5\n18 CYCL DEF 1.4 DWELL 0\n19 CYCL DEF 1.5 F80\n20 L Z+2 FMAX\n21 CYCL CALL\n22 END PGM C MM\n";
    let m = motions(text, None).unwrap();
    let drilled = vec![2.0, -4.0, -3.5, -7.0, 2.0, -5.0, -10.0, 2.0, 50.0];
    assert_eq!(z_of(&m, 19), drilled);
    // The pattern: up to the clearance height (here the call's Z+50), over,
    // then the cycle on a surface 2 lower for the row.
    let pat = z_of(&m, 23);
    assert_eq!(&pat[..10], &[[50.0].as_slice(), &drilled].concat()[..]);
    assert_eq!(&pat[10..13], &[50.0, 0.0, -6.0]);
    let ends: Vec<[f64; 3]> = m
        .iter()
        .filter(|(l, _)| *l == 23)
        .map(|(_, m)| xyz(&m.end))
        .collect();
    assert_point(ends[10], [0.0, 40.0, 50.0]);
    assert_point(*ends.last().unwrap(), [10.0, 40.0, 48.0]);
    // CYCL CALL POS: over the point at the tool's height, down to its Z, the cycle.
    let pos = z_of(&m, 24);
    assert_eq!(&pos[..3], &[48.0, 0.0, 2.0]);
    assert_point(
        xyz(&m.iter().find(|(l, _)| *l == 24).unwrap().1.end),
        [5.0, 5.0, 48.0],
    );
    // M99 on a positioning block: the move, then the cycle; M89 on 26, 27, 28 (M99 ends it).
    assert_eq!(z_of(&m, 25).len(), 1 + drilled.len());
    for line in [26, 27, 28] {
        assert_eq!(z_of(&m, line).len(), 1 + drilled.len(), "line {line}");
    }
    assert_eq!(z_of(&m, 29), vec![50.0]);
    // Cycle 1 from Z+2: to -3 (5 from the start), back, to 0.6 above, to -8, back.
    assert_eq!(z_of(&m, 37), vec![-3.0, 2.0, -2.4, -8.0, 2.0]);
    // A cycle volcomp does not expand: refused at its call, named.
    let bad = text
        .replace(
            "21 CYCL CALL\n",
            "21 CYCL DEF 262 THREAD MILLING Q335=+10\n22 CYCL CALL\n",
        )
        .replace("22 END PGM", "23 END PGM");
    let e = motions(&bad, None).unwrap_err();
    assert!(e.contains("CYCL DEF 262") && e.contains("t.h:38:"), "{e}");
    // A rotation cycle is refused where it is defined.
    let rot = text.replace("20 L Z+2 FMAX", "20 CYCL DEF 10.0 ROTATION");
    let e = motions(&rot, None).unwrap_err();
    assert!(
        e.contains("CYCL DEF 10 ROTATION") && e.contains("t.h:36:"),
        "{e}"
    );
}

/// `FN 14: ERROR = n` stops with the number (TNC 640 User's Manual,
/// "Q parameters › FN 14: ERROR"); `FN 16: F-PRINT` and `FN 20: WAIT FOR`
/// do not move: passed through; `FN 23: CIRCLE DATA` gives the circle
/// through three points; `FN 18: SYSREAD` is refused at its block.
#[test]
fn fn_functions_stop_pass_or_compute() {
    let text = "0 BEGIN PGM F MM\n1 Q30 = 10\n2 Q31 = 0\n3 Q32 = 0\n4 Q33 = 10\n5 Q34 = -10\n6 Q35 = 0\n7 FN 23: CIRCLE DATA Q20 = CDATA Q30\n8 FN 16: F-PRINT TNC:\\MASK.A / TNC:\\OUT.TXT\n9 FN 20: WAIT FOR SYNC\n10 L X+Q20 Y+Q21 Z+Q22 R0 F100\n11 FN 14: ERROR = 254\n12 END PGM F MM\n";
    let e = motions(text, None).unwrap_err();
    assert!(
        e.contains("error number 254") && e.contains("t.h:12:"),
        "{e}"
    );
    let ok = text.replace("11 FN 14: ERROR = 254\n", "");
    let m = motions(&ok, None).unwrap();
    assert_point(xyz(&m[0].1.end), [0.0, 0.0, 10.0]);
    let read = text.replace("9 FN 20: WAIT FOR SYNC", "9 FN 18: SYSREAD Q1 = ID20 NR1");
    let e = motions(&read, None).unwrap_err();
    assert!(e.contains("FN 18") && e.contains("t.h:10:"), "{e}");
}

/// `LN` blocks under M128 (TNC 640 User's Manual, "3D tool compensation ›
/// LN blocks"): compensate writes the tool vector of the corrected joints
/// back as `TX TY TZ` (no rotary words added), in the input's sign style;
/// on two machines (B/C and A/C tables) the replayed tip error and tool
/// axis error are cut by ≥ 90 %.
#[test]
fn closed_loop_ln_vectors() {
    let original = std::fs::read_to_string(root().join("tests/data/heidenhain/ln-tcp.h")).unwrap();
    let mut summary = String::new();
    for machine in ["bc-trt", "ref-trt"] {
        let rig = rig(machine);
        let (text, report) = compensate_on(rig, &original, Frame::Joint, 0.5, true);
        let mut vectors = 0;
        for (a, b) in original.lines().zip(text.lines()) {
            if a == b {
                continue;
            }
            let names = |l: &str| -> Vec<String> {
                l.split_whitespace()
                    .map(|w| w.chars().take_while(|c| c.is_ascii_alphabetic()).collect())
                    .collect()
            };
            assert_eq!(names(a), names(b), "{a} -> {b}");
            vectors +=
                usize::from(a.contains(" TX") && a.split(" T").nth(1) != b.split(" T").nth(1));
        }
        assert!(vectors > 100, "{machine}: {vectors} vectors rewritten");
        let (before, after) = closed_loop_on(rig, &original, &text, Frame::Joint);
        let (axis_before, _, n) = replayed_axis_error_on(rig, &original, &original, Frame::Joint);
        let (axis_after, axis_rms_after, m) =
            replayed_axis_error_on(rig, &original, &text, Frame::Joint);
        assert_eq!(n, m);
        assert!(
            before.max_um > 5.0 && axis_before > 10.0,
            "{machine}: {before:?} {axis_before}"
        );
        assert!(
            after.max_um <= 0.1 * before.max_um,
            "{machine}: {before:?} -> {after:?}"
        );
        assert!(
            axis_after <= 0.1 * axis_before,
            "{machine}: {axis_before} -> {axis_after}"
        );
        summary += &format!(
            "{machine}: blocks changed {}, tip max {:.2} -> {:.3} µm, rms {:.2} -> {:.3} µm; tool axis max {:.1} -> {:.2} µrad (rms after {:.2}), {n} block ends\n",
            report.blocks_changed,
            before.max_um,
            after.max_um,
            before.rms_um,
            after.rms_um,
            axis_before,
            axis_after,
            axis_rms_after,
        );
    }
    insta::assert_snapshot!("heidenhain_closed_loop_ln", summary);
}

/// Forms real hyperMILL output uses (the BRK_CNC_CORE programs of
/// docs/dialects.md "Heidenhain: real programs"): a feed from a parameter
/// written `FQ2`, the block-skip `/` before the block number (the block is
/// run, as with block delete off), `CYCL DEF9.0` with the number written on.
#[test]
fn hypermill_forms_are_read() {
    let text = "1 BEGIN PGM H MM\n2 FN 0:Q2=250 ; Z FEED RATE\n3 CYCL DEF9.0 VARAKOZASI IDO\n4 CYCL DEF9.1 V.IDO5\n5 L X+10 Y+0 Z+5 R0 F MAX\n6 L Z-1 FQ2\n/7 M30\n8 L Z+50 R0 F MAX\n9 END PGM H MM\n";
    let m = motions(text, None).unwrap();
    assert_eq!(m.len(), 2);
    assert_eq!(m[1].1.feed, volcomp::gcode::Feed::PerMinute(250.0));
    assert_point(xyz(&m[1].1.end), [10.0, 0.0, -1.0]);
}

/// hyperMILL's `PLANE SPATIAL SPA0 SPB0 SPC0|SPC180 STAY SEQ+ TABLE ROT`
/// on a table C axis (free there: the tool is along it): the table takes
/// the plane's rotation about the tool axis (TNC 640 user's manual,
/// "Specifying the positioning behavior of the PLANE function", TABLE ROT),
/// so `Q122` is 0 or 180 and the program's `L B+Q121 C+Q122` turns it
/// there; `CP … DR+F2777` (the feed written on the sign) is `DR+ F2777`.
#[test]
fn table_rot_free_axis_and_dr_with_feed() {
    let (machine, _) = rig("bc-trt");
    let text = "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z S1000\n2 L X+0 Y+0 Z+50 B+0 C+30 R0 FMAX\n3 PLANE SPATIAL SPA0 SPB0 SPC180 STAY SEQ+ TABLE ROT\n4 L B+Q121 C+Q122 R0 FMAX\n5 PLANE SPATIAL SPA0 SPB0 SPC0 STAY SEQ+ TABLE ROT\n6 L B+Q121 C+Q122 R0 FMAX\n7 PLANE RESET STAY\n8 L X+10 Y+0 Z+0 R0 FMAX\n9 CC X+0 Y+0\n10 CP IPA+90 IZ-2 DR+F2777\n11 END PGM T MM\n";
    let m = motions(text, Some(machine)).unwrap();
    let turned = last_of(&m, 5);
    assert_abs_diff_eq!(turned.end.c.abs(), 180.0, epsilon = 1e-9);
    assert_abs_diff_eq!(turned.end.b, 0.0, epsilon = 1e-9);
    assert_abs_diff_eq!(last_of(&m, 7).end.c, 0.0, epsilon = 1e-9);
    let helix = last_of(&m, 11);
    assert_eq!(helix.feed, volcomp::gcode::Feed::PerMinute(2777.0));
    assert_near(xyz(&helix.end), [0.0, 10.0, -2.0], 1e-6);
    // Another rotation about the tool axis stays refused (its sense).
    let e = motions(
        "0 BEGIN PGM T MM\n1 TOOL CALL 1 Z S1000\n2 PLANE SPATIAL SPA0 SPB0 SPC90 STAY SEQ+ TABLE ROT\n3 END PGM T MM\n",
        Some(machine),
    )
    .unwrap_err();
    assert!(e.contains("t.h:3:") && e.contains("TABLE ROT"), "{e}");
}
