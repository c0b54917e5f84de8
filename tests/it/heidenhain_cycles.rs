//! Klartext machining cycles expanded at their call (issue 35 item 4):
//! 262 THREAD MILLING (a helix of the pitch Q239 on the circle of Q335/2 −
//! the tool radius, its working direction from the hand and Q351), 204
//! BACK BORING (down through the hole displaced by Q251 in the direction
//! Q214, counterbored upwards from the underside), 208 BORE MILLING (a helix on the circle of Q335/2 − the tool radius, the
//! tool called by name from the machine file's `[[tools]] name`), 241
//! SINGLE-LIP DEEP-HOLE DRILLING, 209 TAPPING WITH CHIP BREAKING and 206
//! TAPPING, each path worked out by hand from the cycle run of the TNC 640
//! cycle programming manual as `src/gcode/heidenhain/cycles.rs` reads it
//! (the readings made without the manual's text are listed in
//! docs/dialects.md); the cycles volcomp does not expand are refused at the
//! call naming the missing detail; `compensate` writes the expanded moves
//! flat and the output reads back.
use crate::compensate::{Rig, compensate_on, interpret_options_on, program_on};
use crate::support::root;
use approx::assert_abs_diff_eq;
use std::sync::OnceLock;
use volcomp::gcode::{Feed, Frame, Motion, MotionKind};
use volcomp::machine::{ErrorModel, LoadOptions, Machine, ModelOptions};

const FIXTURE: &str = "tests/data/heidenhain/cycles-bore-tap-deep.h";
const THREADS: &str = "tests/data/heidenhain/cycles-thread-backbore.h";

/// bc-trt with the fixture's tools by name (the TNC tool table's NAME
/// column as the machine file's `[[tools]] name`).
fn rig() -> &'static Rig {
    static RIG: OnceLock<Rig> = OnceLock::new();
    RIG.get_or_init(|| {
        let path = root().join("machines/bc-trt.toml");
        let mut text = std::fs::read_to_string(&path).unwrap();
        for (number, name, length, radius) in [
            (11, "MILL_D8", 80.0, 4.0),
            (12, "DEEP_D6", 150.0, 3.0),
            (13, "TAP_M10", 90.0, 5.0),
            (14, "THREAD_M24", 70.0, 8.0),
            (15, "BACKBORE", 120.0, 2.0),
        ] {
            text.push_str(&format!(
                "\n[[tools]]\nnumber = {number}\nname = \"{name}\"\nlength = {length}\nradius = {radius}\n"
            ));
        }
        let machine = Machine::parse(&text, &path, &LoadOptions::default()).unwrap();
        let model = ErrorModel::from_machine(&machine, &ModelOptions::default()).unwrap();
        (machine, model)
    })
}

/// Every motion of `text` on `machine` (or none: no tool table) with its
/// source line, or the first error.
fn motions(text: &str, machine: Option<&Machine>) -> Result<Vec<(usize, Motion)>, String> {
    let plain;
    let m = match machine {
        Some(m) => m,
        None => {
            plain = Machine::load(&root().join("machines/bc-trt.toml")).unwrap();
            &plain
        }
    };
    let mut program = program_on(m, text, "t.h");
    if machine.is_none() {
        program = volcomp::gcode::Program::new(
            Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
            std::path::Path::new("t.h"),
            volcomp::gcode::ProgramSetup::default(),
        );
    }
    let mut run = program.run(interpret_options_on(m, Frame::Joint));
    let mut out = Vec::new();
    while let Some(step) = run.next() {
        let (_, event, executed) = step.map_err(|e| e.to_string())?;
        out.extend(event.motions().map(|m| (executed.line, *m)));
    }
    Ok(out)
}

fn fixture() -> String {
    std::fs::read_to_string(root().join(FIXTURE)).unwrap()
}

/// The motions of source line `line`.
fn of(m: &[(usize, Motion)], line: usize) -> Vec<Motion> {
    m.iter()
        .filter(|(l, _)| *l == line)
        .map(|(_, m)| *m)
        .collect()
}

fn end(m: &Motion) -> [f64; 3] {
    [m.end.x, m.end.y, m.end.z]
}

fn assert_at(got: [f64; 3], want: [f64; 3]) {
    for k in 0..3 {
        assert_abs_diff_eq!(got[k], want[k], epsilon = 1e-9);
    }
}

/// The tool-axis coordinates of the ends of `moves`, rounded to 1e-9.
fn zs(moves: &[Motion]) -> Vec<f64> {
    moves
        .iter()
        .map(|m| (m.end.z * 1e9).round() / 1e9)
        .collect()
}

fn feed(m: &Motion) -> Option<f64> {
    match m.feed {
        Feed::PerMinute(f) => Some(f),
        _ => None,
    }
}

/// Cycle 208 with the tool "MILL_D8" (R 4) and Q335 = 12: the helix runs
/// on a circle of radius 6 − 4 = 2 about the call position (10, 20). From
/// Z+100: FMAX to the set-up clearance Z+2; the approach semicircle (radius
/// 1 about (11, 20), counter-clockwise for Q351 = +1, through y < 20) to
/// (12, 20, 2); the helix counter-clockwise, 2 mm per turn, from Z+2 to the
/// depth Z-3: 2.5 turns, through (12, 20, 0) and (12, 20, -2), ending at
/// (8, 20, -3); a full circle there; back to the centre (10, 20, -3); FMAX
/// to Z+2 and to the 2nd set-up clearance Z+50. Every cutting move at Q206
/// (150 mm/min), every chord within 0.5 µm of the arc.
#[test]
fn bore_milling_208_is_a_helix_on_the_tool_radius() {
    let rig = rig();
    let m = motions(&fixture(), Some(&rig.0)).unwrap();
    let call = of(&m, 18);
    assert_eq!(call[0].kind, MotionKind::Rapid);
    assert_at(end(&call[0]), [10.0, 20.0, 2.0]);
    let n = call.len();
    assert_at(end(&call[n - 3]), [10.0, 20.0, -3.0]);
    assert_at(end(&call[n - 2]), [10.0, 20.0, 2.0]);
    assert_at(end(&call[n - 1]), [10.0, 20.0, 50.0]);
    assert_eq!(call[n - 2].kind, MotionKind::Rapid);
    assert_eq!(call[n - 1].kind, MotionKind::Rapid);
    let cutting = &call[1..n - 2];
    assert!(cutting.iter().all(|c| feed(c) == Some(150.0)));
    // The approach: on the circle of radius 1 about (11, 20) at Z+2.
    let approach = cutting
        .iter()
        .position(|c| (end(c)[0] - 12.0).abs() < 1e-9 && (end(c)[1] - 20.0).abs() < 1e-9)
        .expect("the helix start");
    for c in &cutting[..=approach] {
        let p = end(c);
        assert_abs_diff_eq!((p[0] - 11.0).hypot(p[1] - 20.0), 1.0, epsilon = 1e-9);
        assert_abs_diff_eq!(p[2], 2.0, epsilon = 1e-12);
    }
    assert!(end(&cutting[0])[1] < 20.0, "counter-clockwise: through -Y");
    // The helix and the circle at the depth: radius 2 about (10, 20), Z
    // falling 2 mm per turn of the unwrapped angle, down to -3.
    let helix = &cutting[approach + 1..cutting.len() - 1];
    let mut angle = 0.0f64;
    let mut last: [f64; 3] = [12.0, 20.0, 2.0];
    let mut turn_ends = Vec::new();
    for c in helix {
        let p = end(c);
        assert_abs_diff_eq!((p[0] - 10.0).hypot(p[1] - 20.0), 2.0, epsilon = 1e-9);
        let step = ((p[1] - 20.0).atan2(p[0] - 10.0) - (last[1] - 20.0).atan2(last[0] - 10.0))
            .rem_euclid(std::f64::consts::TAU);
        // Chord: sagitta r(1 - cos(step/2)) ≤ 0.5 µm, counter-clockwise.
        assert!(step > 0.0 && 2.0 * (1.0 - (step / 2.0).cos()) <= 0.5e-3 + 1e-12);
        angle += step;
        let want = (2.0 - 2.0 * angle / std::f64::consts::TAU).max(-3.0);
        assert_abs_diff_eq!(p[2], want, epsilon = 1e-9);
        if (p[0] - 12.0).abs() < 1e-9 && p[2] > -3.0 + 1e-9 {
            turn_ends.push((p[2] * 1e9).round() / 1e9);
        }
        last = p;
    }
    assert_eq!(turn_ends, vec![0.0, -2.0]);
    // 2.5 turns down, one full circle at the depth.
    assert_abs_diff_eq!(angle, 3.5 * std::f64::consts::TAU, epsilon = 1e-9);
    assert_at(last, [8.0, 20.0, -3.0]);
    // M99 on a positioning block: the move to (-20, -20) at Z+50, then the
    // same cycle about it.
    let at99 = of(&m, 19);
    assert_at(end(&at99[0]), [-20.0, -20.0, 50.0]);
    assert_at(end(&at99[1]), [-20.0, -20.0, 2.0]);
    assert_eq!(at99.len(), n + 1);
    assert_at(end(&at99[n - 2]), [-20.0, -20.0, -3.0]);
}

/// The other readings of cycle 208: up-cut (Q351 = -1) turns clockwise
/// (the approach through y > 20, the same half-turn end (8, 20, -3)); the
/// tool call's DR widens the tool (R 4 - 0.5: radius 2.5, end (7.5, 20,
/// -3)); a nominal diameter equal to the tool's goes straight down; a tool
/// the table does not give (an unknown name, or no table) is refused at the
/// call, naming the tool radius; a hole narrower than the tool is refused.
#[test]
fn bore_milling_208_senses_radii_and_refusals() {
    let rig = rig();
    let text = fixture();
    let upcut = text.replace("Q351=+1", "Q351=-1");
    let m = motions(&upcut, Some(&rig.0)).unwrap();
    let call = of(&m, 18);
    assert!(end(&call[1])[1] > 20.0, "clockwise: through +Y");
    let n = call.len();
    assert_at(end(&call[n - 4]), [8.0, 20.0, -3.0]);
    let dr = text.replace("S2000 DL+0 DR+0", "S2000 DL+0 DR-0.5");
    let call = of(&motions(&dr, Some(&rig.0)).unwrap(), 18);
    let n = call.len();
    assert_at(end(&call[n - 4]), [7.5, 20.0, -3.0]);
    let plunge = text.replace("Q335=+12", "Q335=+8");
    let call = of(&motions(&plunge, Some(&rig.0)).unwrap(), 18);
    assert_eq!(zs(&call), vec![2.0, -3.0, 2.0, 50.0]);
    assert_eq!(feed(&call[1]), Some(150.0));
    // A table that names tools: a name it lacks is refused at the call.
    let e = motions(&text.replace("\"MILL_D8\"", "\"OTHER\""), Some(&rig.0)).unwrap_err();
    assert!(
        e.contains("tool \"OTHER\" is not in the tool table") && e.contains("TOOL CALL"),
        "{e}"
    );
    // No table: the default tool, whose radius 208 cannot know.
    let e = motions(&text, None).unwrap_err();
    assert!(
        e.contains("CYCL DEF 208") && e.contains("tool radius") && e.contains("t.h:18:"),
        "{e}"
    );
    let e = motions(&text.replace("Q335=+12", "Q335=+6"), Some(&rig.0)).unwrap_err();
    assert!(e.contains("smaller than the tool"), "{e}");
}

/// Cycle 241 from Z+50 over (30, 0): FMAX to the set-up clearance 3 above
/// the surface Z+1 (Z+4); at Q253 (50) to the set-up clearance above the
/// deepened starting point 10 (1 - 10 + 3 = -6); at Q206 (25) to the depth
/// 1 - 40 = -39; dwell; back at Q208 (300) to Z+4; FMAX to 1 + 29 = 30.
/// Cycle 209 (S500, pitch 1.5: F 750; Q403 = 2: out at 1500): Z+2; infeeds
/// of Q257 = 4 with a retraction of Q256 × pitch = 1.5 after each (-4,
/// -2.5, -8, -6.5), the depth -10, back to Z+2, FMAX to Z+20; with Q256 = 0
/// the retractions go to the set-up clearance. Cycle 206: Z+2, Q206 to
/// -12, dwell, back at Q206, FMAX to Z+30. A dwell depth Q435 is refused,
/// at the call.
#[test]
fn deep_hole_241_and_tapping_209_206() {
    let rig = rig();
    let text = fixture();
    let m = motions(&text, Some(&rig.0)).unwrap();
    let deep = of(&m, 38);
    assert_eq!(zs(&deep), vec![50.0, 4.0, -6.0, -39.0, 4.0, 30.0]);
    let feeds: Vec<Option<f64>> = deep.iter().map(feed).collect();
    assert_eq!(
        feeds,
        vec![None, None, Some(50.0), Some(25.0), Some(300.0), None]
    );
    assert_at(end(&deep[5]), [30.0, 0.0, 30.0]);
    // The dwell Q211 = 0.5 s is counted in the machining time of the call.
    let tap = of(&m, 50);
    assert_eq!(
        zs(&tap),
        vec![30.0, 2.0, -4.0, -2.5, -8.0, -6.5, -10.0, 2.0, 20.0]
    );
    let feeds: Vec<Option<f64>> = tap.iter().map(feed).collect();
    assert_eq!(
        feeds,
        vec![
            None,
            None,
            Some(750.0),
            Some(1500.0),
            Some(750.0),
            Some(1500.0),
            Some(750.0),
            Some(1500.0),
            None
        ]
    );
    let full = text.replace("Q256=+1 ;", "Q256=+0 ;");
    let tap = of(&motions(&full, Some(&rig.0)).unwrap(), 50);
    assert_eq!(
        zs(&tap),
        vec![30.0, 2.0, -4.0, 2.0, -8.0, 2.0, -10.0, 2.0, 20.0]
    );
    let floating = of(&m, 58);
    assert_eq!(zs(&floating), vec![20.0, 2.0, -12.0, 2.0, 30.0]);
    assert!(floating[2..4].iter().all(|c| feed(c) == Some(150.0)));
    let e = motions(&text.replace("Q435=+0", "Q435=+5"), Some(&rig.0)).unwrap_err();
    assert!(
        e.contains("CYCL DEF 241") && e.contains("Q435") && e.contains("t.h:38:"),
        "{e}"
    );
}

/// The cycles whose path the manual's text (as read here) does not give
/// exactly are refused at their call, naming the cycle, the line of its
/// definition and the missing detail: the 25x pockets, slots and studs,
/// 263–267 thread milling with countersinking, drilling or outside.
#[test]
fn unexpanded_cycles_name_the_missing_detail() {
    for (cycle, detail) in [
        ("251 RECTANGULAR POCKET", "stepovers of at most Q370"),
        ("252 CIRCULAR POCKET", "plunge of Q366"),
        ("256 RECTANGULAR STUD", "finishing passes"),
        ("263 THREAD MILLING/CNTSNKG", "path of the countersinking"),
        ("265 HEL. THREAD DRLG/MLG", "path of the countersinking"),
        ("267 OUTSIDE THREAD MILLING", "outside approach"),
    ] {
        let text = format!(
            "0 BEGIN PGM R MM\n1 TOOL CALL 1 Z S1000\n2 L X+0 Y+0 Z+50 R0 FMAX\n3 CYCL DEF {cycle} ~\n  Q200=+2 ~\n  Q201=-10 ~\n  Q203=+0 ~\n  Q204=+50\n4 L X+10 R0 FMAX M99\n5 END PGM R MM\n"
        );
        let e = motions(&text, Some(&rig().0)).unwrap_err();
        let number = &cycle[..3];
        assert!(
            e.contains(&format!("CYCL DEF {number} (defined on line 4)"))
                && e.contains(detail)
                && e.contains("t.h:9:"),
            "{e}"
        );
    }
}

/// `compensate` of the fixture on bc-trt: each call is written flat (`;
/// volcomp: line N written flat: …` then `L` blocks each with `; volcomp:
/// line N`), the blocks are numbered consecutively, and the output reads
/// back (with no tool table: the cycles are no longer called) to the same
/// number of moves, each within the correction (≤ 50 µm) of the input's.
#[test]
fn compensate_writes_expanded_cycles_flat() {
    let rig = rig();
    let text = fixture();
    let (out, _) = compensate_on(rig, &text, Frame::Joint, 0.5, true);
    for (line, call) in [
        (18, "CYCL CALL"),
        (19, "L X-20 Y-20 R0 FMAX M99"),
        (38, "L X+30 Y+0 R0 FMAX M99"),
        (50, "L X+30 Y+30 R0 FMAX M99"),
        (58, "L X-30 Y+30 R0 FMAX M99"),
    ] {
        assert!(
            out.contains(&format!("; volcomp: line {line} written flat: {call}\n")),
            "{line}"
        );
    }
    // Blocks numbered consecutively (`~` continuation lines carry none).
    for (k, l) in out.lines().filter(|l| !l.starts_with(' ')).enumerate() {
        assert!(l.starts_with(&format!("{k} ")), "{l}");
    }
    let flat = out
        .lines()
        .filter(|l| l.contains(" L ") && l.ends_with("; volcomp: line 18"))
        .count();
    let before = motions(&text, Some(&rig.0)).unwrap();
    assert_eq!(flat, of(&before, 18).len());
    let after = motions(&out, None).unwrap();
    assert_eq!(after.len(), before.len());
    for ((_, a), (_, b)) in before.iter().zip(&after) {
        let (p, q) = (end(a), end(b));
        let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
        assert!(d < 0.05, "{p:?} -> {q:?}");
    }
}

fn threads() -> String {
    std::fs::read_to_string(root().join(THREADS)).unwrap()
}

/// Checks that `moves`, from `from`, run on the circle of `radius` about
/// `centre` (x, y) in the sense `ccw`, as chords within 0.5 µm, with Z
/// linear in the swept angle (`rise` mm per radian); returns the angle
/// swept (radians, positive).
fn on_helix(
    moves: &[Motion],
    from: [f64; 3],
    centre: [f64; 2],
    radius: f64,
    ccw: bool,
    rise: f64,
) -> f64 {
    let angle_of = |p: [f64; 3]| (p[1] - centre[1]).atan2(p[0] - centre[0]);
    let mut last = from;
    let mut swept = 0.0;
    for c in moves {
        let p = end(c);
        assert_abs_diff_eq!(
            (p[0] - centre[0]).hypot(p[1] - centre[1]),
            radius,
            epsilon = 1e-9
        );
        let mut step = (angle_of(p) - angle_of(last)).rem_euclid(std::f64::consts::TAU);
        if !ccw {
            step = std::f64::consts::TAU - step;
        }
        assert!(step > 0.0 && radius * (1.0 - (step / 2.0).cos()) <= 0.5e-3 + 1e-12);
        swept += step;
        assert_abs_diff_eq!(p[2], from[2] + rise * swept, epsilon = 1e-9);
        last = p;
    }
    swept
}

/// Cycle 262 with "THREAD_M24" (R 8), an M24 × 2 right-hand thread 8 deep
/// (Q335 = 24, Q239 = +2, Q201 = -8), climb (Q351 = +1), Q355 = 1, called
/// at (10, 20) from Z+100. By hand: the helix radius is 12 − 8 = 4; right
/// hand and climb work out of the hole (the fundamentals' Z+), so the
/// starting plane is the depth: FMAX to Z+2, at Q253 (500) to Z-8, the
/// compensating move a quarter pitch (0.5) lower to Z-8.5; the approach
/// semicircle about (12, 20), radius 2, counter-clockwise (through y = 18),
/// rising 0.5 to (14, 20, -8); the helix counter-clockwise about (10, 20),
/// 2 per turn, 8 / 2 = 4 turns to (14, 20, 0); the departure semicircle
/// about (12, 20) (through y = 22) rising 0.5 to the centre (10, 20, +0.5);
/// FMAX to Z+2 and Z+50. Milling at Q207 at the tool centre: 300 × 4 / 12
/// = 100 mm/min.
#[test]
fn thread_milling_262_climbs_a_right_hand_thread_out_of_the_hole() {
    let rig = rig();
    let m = motions(&threads(), Some(&rig.0)).unwrap();
    let call = of(&m, 19);
    let n = call.len();
    assert_eq!(zs(&call[..3]), vec![2.0, -8.0, -8.5]);
    assert_eq!(call[0].kind, MotionKind::Rapid);
    assert_at(end(&call[2]), [10.0, 20.0, -8.5]);
    assert_eq!(feed(&call[1]), Some(500.0));
    assert_eq!(feed(&call[2]), Some(500.0));
    assert_eq!(zs(&call[n - 2..]), vec![2.0, 50.0]);
    assert!(call[n - 2..].iter().all(|c| c.kind == MotionKind::Rapid));
    assert_at(end(&call[n - 1]), [10.0, 20.0, 50.0]);
    let cutting = &call[3..n - 2];
    assert!(cutting.iter().all(|c| feed(c) == Some(100.0)));
    let at = |p: [f64; 3]| {
        cutting
            .iter()
            .position(|c| {
                let q = end(c);
                (0..3).all(|k| (q[k] - p[k]).abs() < 1e-9)
            })
            .unwrap()
    };
    let (a, h) = (at([14.0, 20.0, -8.0]), at([14.0, 20.0, 0.0]));
    let pi = std::f64::consts::PI;
    // The approach: half a turn about (12, 20), through y = 18.
    let swept = on_helix(
        &cutting[..=a],
        [10.0, 20.0, -8.5],
        [12.0, 20.0],
        2.0,
        true,
        0.5 / pi,
    );
    assert_abs_diff_eq!(swept, pi, epsilon = 1e-9);
    assert!(cutting[..a].iter().any(|c| end(c)[1] < 18.01));
    // The helix: 4 turns about (10, 20), 2 mm per turn.
    let swept = on_helix(
        &cutting[a + 1..=h],
        [14.0, 20.0, -8.0],
        [10.0, 20.0],
        4.0,
        true,
        2.0 / (2.0 * pi),
    );
    assert_abs_diff_eq!(swept, 4.0 * 2.0 * pi, epsilon = 1e-9);
    // The departure: half a turn about (12, 20) to the centre, through y = 22.
    let swept = on_helix(
        &cutting[h + 1..],
        [14.0, 20.0, 0.0],
        [12.0, 20.0],
        2.0,
        true,
        0.5 / pi,
    );
    assert_abs_diff_eq!(swept, pi, epsilon = 1e-9);
    assert!(cutting[h + 1..].iter().any(|c| end(c)[1] > 21.99));
    assert_at(end(cutting.last().unwrap()), [10.0, 20.0, 0.5]);
}

/// The other readings of cycle 262, by hand. Left hand (Q239 = -2) and
/// climb works into the hole: from the surface (Z0; compensating move to
/// Z+0.5) counter-clockwise down 4 turns to (14, 20, -8), departure to
/// (10, 20, -8.5). Up-cut (Q351 = -1) with the right hand also works into
/// the hole, clockwise (the approach through y = 22). Q355 = 0: one turn,
/// Z-8 to Z-6 (departure to -5.5). Q355 = 3 (offset 3 × 2 = 6): helices of
/// one turn from Z-8 and from Z-2 (ceil(8 / 6) = 2), each after its own
/// pre-positioning at Q253 (Z-8, -8.5; Z-2, -2.5). Refused at the call:
/// no tool radius, a tool as wide as the thread.
#[test]
fn thread_milling_262_senses_steps_and_refusals() {
    let rig = rig();
    let text = threads();
    let left = of(
        &motions(&text.replace("Q239=+2", "Q239=-2"), Some(&rig.0)).unwrap(),
        19,
    );
    assert_eq!(zs(&left[..3]), vec![2.0, 0.0, 0.5]);
    let n = left.len();
    assert_at(end(&left[n - 3]), [10.0, 20.0, -8.5]);
    let find = |z: f64| {
        left.iter()
            .position(|c| {
                let p = end(c);
                (p[0] - 14.0).abs() < 1e-9 && (p[1] - 20.0).abs() < 1e-9 && (p[2] - z).abs() < 1e-9
            })
            .expect("the helix start and end")
    };
    let (top, bottom) = (find(0.0), find(-8.0));
    let swept = on_helix(
        &left[top + 1..=bottom],
        [14.0, 20.0, 0.0],
        [10.0, 20.0],
        4.0,
        true,
        -1.0 / std::f64::consts::PI,
    );
    assert_abs_diff_eq!(swept, 8.0 * std::f64::consts::PI, epsilon = 1e-9);
    let upcut = of(
        &motions(&text.replace("Q351=+1", "Q351=-1"), Some(&rig.0)).unwrap(),
        19,
    );
    assert_eq!(zs(&upcut[..3]), vec![2.0, 0.0, 0.5]);
    assert!(end(&upcut[3])[1] > 20.0, "clockwise: through +Y");
    let one = of(
        &motions(&text.replace("Q355=+1", "Q355=+0"), Some(&rig.0)).unwrap(),
        19,
    );
    let n = one.len();
    assert_eq!(zs(&one[..3]), vec![2.0, -8.0, -8.5]);
    assert_at(end(&one[n - 3]), [10.0, 20.0, -5.5]);
    let z_one: Vec<f64> = zs(&one);
    assert!(z_one.iter().all(|z| (-8.5..=50.0).contains(z)));
    assert!(z_one[3..n - 3].iter().all(|z| *z <= -5.5 + 1e-9));
    let three = of(
        &motions(&text.replace("Q355=+1", "Q355=+3"), Some(&rig.0)).unwrap(),
        19,
    );
    let pre: Vec<f64> = three
        .iter()
        .filter(|c| feed(c) == Some(500.0))
        .map(|c| (end(c)[2] * 1e9).round() / 1e9)
        .collect();
    assert_eq!(pre, vec![-8.0, -8.5, -2.0, -2.5]);
    let n = three.len();
    assert_at(end(&three[n - 3]), [10.0, 20.0, 0.5]);
    let e = motions(&text, None).unwrap_err();
    assert!(
        e.contains("CYCL DEF 262") && e.contains("tool radius") && e.contains("t.h:19:"),
        "{e}"
    );
    let e = motions(&text.replace("Q335=+24", "Q335=+16"), Some(&rig.0)).unwrap_err();
    assert!(e.contains("not smaller than the nominal diameter"), "{e}");
}

/// Cycle 204 called by M99 at (30, 0) from (0, 0, 50), by hand: surface
/// Z0, material 20 thick (underside Z-20), boring bar 3.5 off centre,
/// tooth 15 above the tool's tip, counterbore 5 deep, Q214 = 1 (−X):
/// FMAX to Z+2; FMAX aside to X26.5; at Q253 (400) down until the tooth is
/// the set-up clearance below the underside (tooth Z-22, tip Z-37); at
/// Q253 back over the centre (30, 0, -37); at Q254 (100) up until the
/// tooth is 5 above the underside (tooth Z-15, tip Z-30); dwell; at Q253
/// back down to Z-37; FMAX aside, up to Z+2 and Z+50, back over the
/// centre. Q214 = 4 displaces to +Y; Q249 < 0 is refused.
#[test]
fn back_boring_204_goes_through_the_hole_off_centre() {
    let rig = rig();
    let text = threads();
    let m = motions(&text, Some(&rig.0)).unwrap();
    let call = of(&m, 35);
    let want = [
        ([30.0, 0.0, 50.0], None),
        ([30.0, 0.0, 2.0], None),
        ([26.5, 0.0, 2.0], None),
        ([26.5, 0.0, -37.0], Some(400.0)),
        ([30.0, 0.0, -37.0], Some(400.0)),
        ([30.0, 0.0, -30.0], Some(100.0)),
        ([30.0, 0.0, -37.0], Some(400.0)),
        ([26.5, 0.0, -37.0], None),
        ([26.5, 0.0, 2.0], None),
        ([26.5, 0.0, 50.0], None),
        ([30.0, 0.0, 50.0], None),
    ];
    assert_eq!(call.len(), want.len());
    for (c, (p, f)) in call.iter().zip(want) {
        assert_at(end(c), p);
        assert_eq!(feed(c), f, "{p:?}");
    }
    let plus_y = of(
        &motions(&text.replace("Q214=+1", "Q214=+4"), Some(&rig.0)).unwrap(),
        35,
    );
    assert_at(end(&plus_y[2]), [30.0, 3.5, 2.0]);
    let e = motions(&text.replace("Q249=+5", "Q249=-5"), Some(&rig.0)).unwrap_err();
    assert!(
        e.contains("CYCL DEF 204") && e.contains("Q249") && e.contains("t.h:35:"),
        "{e}"
    );
}

/// `compensate` of the thread and back boring fixture on bc-trt: both
/// calls written flat, the output reads back (no tool table: the cycles
/// are no longer called) to the same moves within the correction.
#[test]
fn compensate_writes_thread_and_back_boring_flat() {
    let rig = rig();
    let text = threads();
    let (out, _) = compensate_on(rig, &text, Frame::Joint, 0.5, true);
    for (line, call) in [(19, "CYCL CALL"), (35, "L X+30 Y+0 R0 FMAX M99")] {
        assert!(
            out.contains(&format!("; volcomp: line {line} written flat: {call}\n")),
            "{line}"
        );
    }
    let before = motions(&text, Some(&rig.0)).unwrap();
    let after = motions(&out, None).unwrap();
    assert_eq!(after.len(), before.len());
    for ((_, a), (_, b)) in before.iter().zip(&after) {
        let (p, q) = (end(a), end(b));
        let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
        assert!(d < 0.05, "{p:?} -> {q:?}");
    }
}
