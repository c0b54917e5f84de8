//! Programs as the controller reads them, through every command: work offsets
//! change where the errors are looked up (and nothing else), offset settings
//! survive compensation, parametric programs and canned cycles are written
//! flat, and no line after the program end is lost.
use crate::compensate::{interpret_options, ref_trt};
use approx::assert_abs_diff_eq;
use volcomp::axes::Axes;
use volcomp::compensate::{CompensateOptions, CompensateReport, compensate};
use volcomp::gcode::{Frame, Program, ProgramSetup, RewriteOptions, rewrite_stream};

/// Compensate `text` on ref-trt in `setup`.
fn compensate_in(text: &str, setup: &ProgramSetup) -> (String, CompensateReport) {
    compensate_tol(text, setup, CompensateOptions::default().tolerance_um)
}

/// … with split tolerance `tolerance_um` (a large one: no splits).
fn compensate_tol(
    text: &str,
    setup: &ProgramSetup,
    tolerance_um: f64,
) -> (String, CompensateReport) {
    let (machine, model) = ref_trt();
    let options = CompensateOptions {
        tolerance_um,
        interpret: interpret_options(Frame::Joint),
        limits: Some(machine.limits),
        ..CompensateOptions::default()
    };
    let program = Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        std::path::Path::new("part.ngc"),
        setup.clone(),
    );
    let mut out = Vec::new();
    let report = compensate(program, &mut out, model, &options, |_| {}).expect("compensates");
    (String::from_utf8(out).expect("utf-8"), report)
}

/// Every motion end of `text` run in `setup`, machine coordinates.
fn machine_targets(text: &str, setup: &ProgramSetup) -> Vec<Axes> {
    let program = Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        std::path::Path::new("part.ngc"),
        setup.clone(),
    );
    let mut run = program.run(interpret_options(Frame::Joint));
    let mut ends = Vec::new();
    while let Some(step) = run.next() {
        let (_, event, _) = step.expect("runs");
        ends.extend(event.motions().map(|m| m.end));
    }
    ends
}

fn with_g54(origin: Axes) -> ProgramSetup {
    let mut setup = ProgramSetup::default();
    setup.set_origin(1, &origin);
    setup
}

/// A five-axis part: moves, an arc, rotary moves (machine coordinates when
/// `o` is zero; work coordinates of origin `o` otherwise).
fn part(o: [f64; 3]) -> String {
    let p = |x: f64, y: f64, z: f64| format!("X{:.4} Y{:.4} Z{:.4}", x - o[0], y - o[1], z - o[2]);
    [
        "G21 G90 G17 G94".to_string(),
        format!("G0 {} A0 C0", p(120.0, -40.0, 20.0)),
        format!("G1 {} F800", p(120.0, -40.0, -30.0)),
        format!("G1 {} A15 C30", p(150.5, -10.25, -35.0)),
        format!("G2 {} I10 J5", p(170.5, -10.25, -35.0)),
        format!("G1 {} A-20 C120", p(90.0, 60.0, -60.0)),
        format!("G0 {}", p(90.0, 60.0, 40.0)),
        "M2".to_string(),
    ]
    .join("\n")
        + "\n"
}

#[test]
fn a_part_in_g54_compensates_to_the_same_machine_positions_as_in_machine_coordinates() {
    let origin = Axes::xyzac(35.5, 12.25, -30.125, 0.0, 0.0);
    let machine_setup = ProgramSetup::default();
    let work_setup = with_g54(origin);
    let in_machine = part([0.0; 3]);
    let in_work = part([origin.x, origin.y, origin.z]);
    // The nominal programs say the same thing.
    let nominal_m = machine_targets(&in_machine, &machine_setup);
    let nominal_w = machine_targets(&in_work, &work_setup);
    assert_eq!(nominal_m.len(), nominal_w.len());
    for (a, b) in nominal_m.iter().zip(&nominal_w) {
        assert_abs_diff_eq!(a.xyz_distance(b), 0.0, epsilon = 1e-9);
    }
    let (comp_m, report_m) = compensate_in(&in_machine, &machine_setup);
    let (comp_w, report_w) = compensate_in(&in_work, &work_setup);
    assert!(report_m.max_correction_um > 1.0, "the part is corrected");
    assert_abs_diff_eq!(
        report_m.max_correction_um,
        report_w.max_correction_um,
        epsilon = 1e-6
    );
    let ends_m = machine_targets(&comp_m, &machine_setup);
    let ends_w = machine_targets(&comp_w, &work_setup);
    assert_eq!(ends_m.len(), ends_w.len());
    let mut moved = 0.0f64;
    for ((a, b), n) in ends_m.iter().zip(&ends_w).zip(&nominal_m) {
        for (u, v) in a.to_array().iter().zip(b.to_array()) {
            assert_abs_diff_eq!(*u, v, epsilon = 1e-9);
        }
        moved = moved.max(a.xyz_distance(n));
    }
    assert!(moved > 1e-3, "compensation moved the targets ({moved} mm)");
    // Ignoring the origin would look the errors up 49 mm away: different numbers.
    let (comp_ignored, _) = compensate_in(&in_work, &machine_setup);
    assert_ne!(comp_ignored, comp_w);
}

#[test]
fn g92_and_g10_l20_set_the_same_offsets_in_the_compensated_program() {
    let text = "G21 G90 G94\nG0 X120 Y-40 Z20 A30 C45\nG1 X150 Y-20 Z-40 F500\n\
G92 X0 Y0 Z0\nG1 X10 Y5 Z-2\nG10 L20 P2 X1 Y2 Z3\nG55\nG1 X4 Y4 Z4\nG92.1\nG54\nG1 X100 Y30 Z-50\nM2\n";
    let setup = ProgramSetup::default();
    // No splits: one compensated target per original move.
    let (compensated, _) = compensate_tol(text, &setup, 1e4);
    // The offset blocks were rewritten by the drift at that point.
    let g92 = compensated
        .lines()
        .find(|l| l.starts_with("G92 X"))
        .expect("G92 kept");
    assert!(g92.starts_with("G92 X") && g92 != "G92 X0 Y0 Z0", "{g92}");
    // Replaying: every target after the offsets lands where the
    // compensation put it (the G92/G10 drift does not add to it).
    let nominal = machine_targets(text, &setup);
    let replayed = machine_targets(&compensated, &setup);
    assert_eq!(nominal.len(), replayed.len());
    for (n, r) in nominal.iter().zip(&replayed) {
        // Corrections of ref-trt are tens of µm; a double correction would be
        // twice that.
        assert!(n.xyz_distance(r) < 0.2, "{n:?} vs {r:?}");
    }
    // Offsets: the same to the printed precision.
    let offsets = |t: &str| {
        let program = Program::from_text(t, "p.ngc");
        let mut run = program.run(interpret_options(Frame::Joint));
        let mut seen = Vec::new();
        while let Some(step) = run.next() {
            let (_, event, _) = step.unwrap();
            seen.push(event.origin);
        }
        seen
    };
    for (a, b) in offsets(text).iter().zip(offsets(&compensated)) {
        assert_abs_diff_eq!(a.g92.x, b.g92.x, epsilon = 1e-4);
        assert_abs_diff_eq!(a.g92.y, b.g92.y, epsilon = 1e-4);
        assert_abs_diff_eq!(a.g92.z, b.g92.z, epsilon = 1e-4);
        assert_abs_diff_eq!(a.work.x, b.work.x, epsilon = 1e-4);
        assert_abs_diff_eq!(a.work.z, b.work.z, epsilon = 1e-4);
    }
}

/// `check --flatten` as a library call: the flat program and its stats.
fn flatten(text: &str) -> (String, volcomp::gcode::RewriteStats) {
    let mut setup = ProgramSetup::default();
    setup.language.drop_definitions = true;
    let program = Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        std::path::Path::new("p.ngc"),
        setup,
    );
    let mut out = Vec::new();
    let stats = rewrite_stream(
        program.run(interpret_options(Frame::Joint)),
        &mut out,
        RewriteOptions::default(),
        |_, _, _| None,
    )
    .expect("flattens");
    (String::from_utf8(out).unwrap(), stats)
}

const PARAMETRIC: &str = "\
G21 G90 G17 G94 F300
#<_depth> = -2
o10 sub
  G1 X[#1] Y[#2] Z#<_depth>
o10 endsub
#1 = 0
o20 repeat [3]
  o10 call [#1 * 5] [#1]
  #1 = [#1 + 1]
o20 endrepeat
G0 Z5
M3 S1000
G98 G81 X10 Y10 Z-3 R1
G91 X5 L2
G90 G80
G4 P0.5
M2
(after the end)
";

#[test]
fn parametric_programs_and_cycles_are_written_flat_and_read_back_the_same() {
    let (flat, stats) = flatten(PARAMETRIC);
    insta::assert_snapshot!("flat_parametric", flat);
    assert_eq!(stats.flat, 5, "3 calls' moves + 2 cycle blocks");
    // The flat program holds no language and no cycle…
    assert!(!flat.contains('#') && !flat.to_ascii_lowercase().contains("o10"));
    assert!(!flat.contains("G81 X") && !flat.contains("X5 L2"));
    // …and moves the machine exactly as the original does.
    let setup = ProgramSetup::default();
    let original = machine_targets(PARAMETRIC, &setup);
    let again = machine_targets(&flat, &setup);
    assert_eq!(original.len(), again.len());
    for (a, b) in original.iter().zip(&again) {
        assert_abs_diff_eq!(a.xyz_distance(b), 0.0, epsilon = 1e-9);
    }
    // The lines after M2 are kept.
    assert!(flat.ends_with("M2\n(after the end)\n"), "{flat}");
}

#[test]
fn a_flat_program_stays_byte_for_byte() {
    let text = "%\nG21 G90\r\nN10 G0 X1 Y2 Z3 (c)\n\nG1 x4 F100\nM30\n%\ntrailing words\n";
    let (flat, stats) = flatten(text);
    assert_eq!(flat, text);
    assert_eq!(stats.flat, 0);
}

#[test]
fn canned_cycles_are_compensated_move_by_move() {
    let text = "G21 G90 G17 G94 F200\nG0 X100 Y-50 Z30 A0 C0\nG99 G83 X120 Y-40 Z-20 R5 Q8\nX140\nG80\nG0 Z30\nM2\n(kept)\n";
    let (compensated, report) = compensate_in(text, &ProgramSetup::default());
    assert!(!compensated.contains("G83 X"), "{compensated}");
    assert!(compensated.contains("(volcomp: G83 of line 3 expanded below)"));
    assert!(compensated.ends_with("M2\n(kept)\n"));
    // One compensated target per executed move, in order.
    let nominal = machine_targets(text, &ProgramSetup::default());
    let replayed = machine_targets(&compensated, &ProgramSetup::default());
    assert_eq!(
        nominal.len(),
        replayed.len(),
        "{nominal:?}\n{replayed:?}\n{compensated}"
    );
    let mut largest = 0.0f64;
    for (n, r) in nominal.iter().zip(&replayed) {
        largest = largest.max(n.xyz_distance(r));
    }
    assert!(largest > 1e-3 && largest < 0.2, "{largest}");
    assert!(report.motion_blocks >= nominal.len() - 1);
}

#[test]
fn a_cycle_a_flat_program_cannot_say_is_refused_with_its_line() {
    let text = "G21 G90 G17 F100\nM3 S500\nG0 X0 Y0 Z10\nG88 X1 Y1 Z-2 R1 P1\nG80\nM2\n";
    let mut out = Vec::new();
    let e = rewrite_stream(
        Program::from_text(text, "p.ngc").run(interpret_options(Frame::Joint)),
        &mut out,
        RewriteOptions::default(),
        |_, _, _| None,
    )
    .unwrap_err();
    let message = e.to_string();
    assert!(message.contains("line 4"), "{message}");
    assert!(
        message.contains("expand this canned cycle by hand"),
        "{message}"
    );
}

/// Found by fuzzing: an endless `do … while` ran for ever (and a writer would
/// fill the disk). A run stops with a located error after its line budget.
#[test]
fn an_endless_loop_is_an_error_not_a_hang() {
    let text = "G21 G90 F250\n#1 = 3\no1 do\n  G1 X#1\n  #1 = [#1 - 0]\no1 while [#1 GT 0]\nM2\n";
    let program = Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        std::path::Path::new("loop.ngc"),
        ProgramSetup {
            language: volcomp::gcode::LanguageOptions {
                max_executed_lines: Some(10_000),
                ..Default::default()
            },
            ..ProgramSetup::default()
        },
    );
    let mut run = program.run(interpret_options(Frame::Joint));
    let mut steps = 0;
    let err = loop {
        match run.next() {
            Some(Ok(_)) => steps += 1,
            Some(Err(e)) => break e,
            None => panic!("the endless loop ended"),
        }
    };
    // The loop's lines, O-word lines included, count.
    assert!(steps > 1000, "{steps}");
    assert!(
        matches!(err.kind, volcomp::gcode::ErrorKind::EndlessProgram(10_000)),
        "{err}"
    );
    assert!(err.to_string().contains("loop.ngc:"), "{err}");
}

/// Found by fuzzing: an endless loop with an empty body executes no block,
/// only O-word lines; they count too.
#[test]
fn an_endless_empty_loop_is_an_error_not_a_hang() {
    let text = "#1 = 0\no1 while [#1 LT 1]\no1 endwhile\nM2\n";
    let program = Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        std::path::Path::new("loop.ngc"),
        ProgramSetup {
            language: volcomp::gcode::LanguageOptions {
                max_executed_lines: Some(10_000),
                ..Default::default()
            },
            ..ProgramSetup::default()
        },
    );
    let mut run = program.run(interpret_options(Frame::Joint));
    let err = loop {
        match run.next() {
            Some(Ok(_)) => {}
            Some(Err(e)) => break e,
            None => panic!("the endless loop ended"),
        }
    };
    assert!(
        matches!(err.kind, volcomp::gcode::ErrorKind::EndlessProgram(10_000)),
        "{err}"
    );
}

/// A block with polar words (`@`, `^`) whose move does not change is written
/// as it is: its polar words give its X Y (found on LinuxCNC's `spiral.ngc`:
/// X Y were added beside them, which LinuxCNC refuses).
#[test]
fn polar_blocks_that_do_not_move_stay_byte_for_byte() {
    for name in ["polar_absolute.ngc", "polar_incremental.ngc"] {
        let text =
            std::fs::read_to_string(crate::support::root().join("tests/data/rs274").join(name))
                .unwrap();
        let (flat, stats) = flatten(&text);
        assert_eq!(flat, text, "{name}");
        assert_eq!(stats.rewritten, 0, "{name}");
    }
}
