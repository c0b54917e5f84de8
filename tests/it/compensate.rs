//! Compensation, end to end: snapshots of the saddle, the closed loop (the
//! compensated program replayed through the same error model lands on the
//! original nominal path, measured densely along the path), a LinuxCNC-style
//! program, and the edge cases of the command.
use crate::support::root;
use std::collections::HashMap;
use std::sync::OnceLock;
use volcomp::compensate::{CompensateOptions, CompensateReport, compensate};
use volcomp::diff::{AlignOptions, Aligner, BlockSummaries};
use volcomp::diff::{Aligned, BlockSummary};
use volcomp::gcode::{
    BlockReader, Feed, Frame, InterpretOptions, Interpreter, ReadOptions, parse_block,
};
use volcomp::machine::{ErrorModel, Machine, ModelOptions};
use volcomp::toolpath::{WalkOptions, walk_program};

/// ref-trt and its fitted model, loaded once for the whole test binary.
pub fn ref_trt() -> &'static (Machine, ErrorModel) {
    static MODEL: OnceLock<(Machine, ErrorModel)> = OnceLock::new();
    MODEL.get_or_init(|| {
        let machine = Machine::load(&root().join("machines/ref-trt.toml")).expect("ref-trt loads");
        let model =
            ErrorModel::from_machine(&machine, &ModelOptions::default()).expect("ref-trt fits");
        (machine, model)
    })
}

/// A machine and its fitted model (ref-trt, or a bundled machine).
pub type Rig = (Machine, ErrorModel);

pub fn interpret_options(frame: Frame) -> InterpretOptions {
    interpret_options_on(&ref_trt().0, frame)
}

/// How `machine` reads a program: its rapid rate, its axis letters.
pub fn interpret_options_on(machine: &Machine, frame: Frame) -> InterpretOptions {
    InterpretOptions {
        initial_frame: frame,
        rapid_mm_per_min: machine.rapid_mm_per_min,
        axes: machine.letters(),
        ..InterpretOptions::default()
    }
}

/// Compensate `text` as the command does (limits checked, default tolerance).
pub fn compensate_text(text: &str, frame: Frame) -> (String, CompensateReport) {
    compensate_with_tolerance(text, frame, CompensateOptions::default().tolerance_um)
}

/// `text` run on ref-trt: its tool table (`[[tools]]`) selects each block's tool.
pub fn ref_program(text: &str, name: &str) -> volcomp::gcode::Program {
    program_on(&ref_trt().0, text, name)
}

/// `text` run on `machine`, with its tool table.
pub fn program_on(machine: &Machine, text: &str, name: &str) -> volcomp::gcode::Program {
    volcomp::gcode::Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        std::path::Path::new(name),
        volcomp::gcode::ProgramSetup {
            tools: machine.tools.clone(),
            // A dialect's working planes and tool vectors are solved on the
            // machine's chain (LinuxCNC programs never ask).
            orientation: Some(std::sync::Arc::new(
                volcomp::toolpath::ChainOrientation::of(machine),
            )),
            ..Default::default()
        },
    )
}

/// [`compensate_text`] with split tolerance `tolerance_um`.
pub fn compensate_with_tolerance(
    text: &str,
    frame: Frame,
    tolerance_um: f64,
) -> (String, CompensateReport) {
    compensate_with(text, frame, tolerance_um, false)
}

/// [`compensate_with_tolerance`], the tool axis corrected too when `orientation`.
pub fn compensate_with(
    text: &str,
    frame: Frame,
    tolerance_um: f64,
    orientation: bool,
) -> (String, CompensateReport) {
    compensate_on(ref_trt(), text, frame, tolerance_um, orientation)
}

/// [`compensate_with`] on any machine.
pub fn compensate_on(
    rig: &Rig,
    text: &str,
    frame: Frame,
    tolerance_um: f64,
    orientation: bool,
) -> (String, CompensateReport) {
    let (machine, model) = rig;
    let options = CompensateOptions {
        tolerance_um,
        interpret: interpret_options_on(machine, frame),
        limits: Some(machine.limits),
        orientation,
        ..CompensateOptions::default()
    };
    let mut out = Vec::new();
    let report = compensate(
        program_on(machine, text, "program.nc"),
        &mut out,
        model,
        &options,
        |_| {},
    )
    .expect("compensates");
    (String::from_utf8(out).expect("utf-8"), report)
}

/// The nominal tool-tip path of a program (part coordinates) as a polyline of
/// cutting samples, bucketed in a 1 mm grid for nearest-segment queries.
pub struct NominalPath {
    points: Vec<[f64; 3]>,
    cells: HashMap<[i64; 3], Vec<u32>>,
}

const CELL_MM: f64 = 1.0;

fn cell(p: [f64; 3]) -> [i64; 3] {
    p.map(|v| (v / CELL_MM).floor() as i64)
}

fn distance_to_segment(p: [f64; 3], a: [f64; 3], b: [f64; 3]) -> f64 {
    let ab = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let ap = [p[0] - a[0], p[1] - a[1], p[2] - a[2]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1] + ab[2] * ab[2];
    let t = if len2 > 0.0 {
        ((ap[0] * ab[0] + ap[1] * ab[1] + ap[2] * ab[2]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let d = [ap[0] - t * ab[0], ap[1] - t * ab[1], ap[2] - t * ab[2]];
    (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt()
}

impl NominalPath {
    /// Walk `text` at `step_mm` and keep the nominal tips of consecutive cutting samples.
    pub fn of_program(text: &str, frame: Frame, step_mm: f64) -> NominalPath {
        Self::of_program_on(ref_trt(), text, frame, step_mm)
    }

    /// [`NominalPath::of_program`] on any machine.
    pub fn of_program_on(rig: &Rig, text: &str, frame: Frame, step_mm: f64) -> NominalPath {
        let (machine, model) = rig;
        let mut points = Vec::new();
        let mut segments = Vec::new();
        let mut previous_cutting = false;
        walk_program(
            program_on(machine, text, "original.nc"),
            model.kinematics(),
            interpret_options_on(machine, frame),
            WalkOptions {
                step_mm,
                rapid_mm_per_min: machine.rapid_mm_per_min,
            },
            |p| {
                // A segment joins a cutting sample to the sample before it.
                if p.cutting && !points.is_empty() {
                    segments.push(points.len() as u32 - 1);
                }
                previous_cutting = p.cutting;
                points.push(p.tip);
            },
        )
        .expect("walks");
        let mut cells: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for &s in &segments {
            let (a, b) = (points[s as usize], points[s as usize + 1]);
            let (lo, hi) = (
                cell([a[0].min(b[0]), a[1].min(b[1]), a[2].min(b[2])]),
                cell([a[0].max(b[0]), a[1].max(b[1]), a[2].max(b[2])]),
            );
            for i in lo[0]..=hi[0] {
                for j in lo[1]..=hi[1] {
                    for k in lo[2]..=hi[2] {
                        cells.entry([i, j, k]).or_default().push(s);
                    }
                }
            }
        }
        let _ = previous_cutting;
        NominalPath { points, cells }
    }

    /// Distance (mm) from `p` to the nearest cutting segment within one cell.
    pub fn distance(&self, p: [f64; 3]) -> f64 {
        let c = cell(p);
        let mut best = f64::INFINITY;
        for i in -1..=1 {
            for j in -1..=1 {
                for k in -1..=1 {
                    if let Some(list) = self.cells.get(&[c[0] + i, c[1] + j, c[2] + k]) {
                        for &s in list {
                            let d = distance_to_segment(
                                p,
                                self.points[s as usize],
                                self.points[s as usize + 1],
                            );
                            best = best.min(d);
                        }
                    }
                }
            }
        }
        best
    }
}

/// Max and RMS (µm) of the distance of the ACTUAL tool tip to a nominal path,
/// over every cutting sample of `text` (walked at `step_mm`).
#[derive(Clone, Copy, Debug)]
pub struct PathError {
    pub max_um: f64,
    pub rms_um: f64,
    pub samples: usize,
    /// Line of the worst sample.
    pub worst_line: usize,
}

pub fn actual_path_error(
    text: &str,
    frame: Frame,
    nominal: &NominalPath,
    step_mm: f64,
) -> PathError {
    actual_path_error_on(ref_trt(), text, frame, nominal, step_mm)
}

/// [`actual_path_error`] on any machine.
pub fn actual_path_error_on(
    rig: &Rig,
    text: &str,
    frame: Frame,
    nominal: &NominalPath,
    step_mm: f64,
) -> PathError {
    let (machine, model) = rig;
    let kin = model.kinematics();
    let (mut max, mut sum_sq, mut n, mut worst_line) = (0.0f64, 0.0, 0usize, 0);
    walk_program(
        program_on(machine, text, "replayed.nc"),
        kin,
        interpret_options_on(machine, frame),
        WalkOptions {
            step_mm,
            rapid_mm_per_min: machine.rapid_mm_per_min,
        },
        |p| {
            if !p.cutting {
                return;
            }
            let errors = model.errors_at(&p.joints).expect("inside the tables");
            // The tool that cuts: its length is the lever of the angular errors.
            let kin = volcomp::machine::kinematics_with(model, &p.tool);
            let actual = kin.actual_tip_and_axis(&p.joints, &errors).tip;
            let d = nominal.distance(actual) * 1e3;
            if d > max {
                max = d;
                worst_line = p.line;
            }
            sum_sq += d * d;
            n += 1;
        },
    )
    .expect("walks");
    PathError {
        max_um: max,
        rms_um: (sum_sq / n.max(1) as f64).sqrt(),
        samples: n,
        worst_line,
    }
}

/// Replay both programs through the model; returns (uncompensated, compensated).
pub fn closed_loop(original: &str, compensated: &str, frame: Frame) -> (PathError, PathError) {
    closed_loop_on(ref_trt(), original, compensated, frame)
}

/// [`closed_loop`] on any machine.
pub fn closed_loop_on(
    rig: &Rig,
    original: &str,
    compensated: &str,
    frame: Frame,
) -> (PathError, PathError) {
    closed_loop_with_ruler_on(rig, original, compensated, frame, 0.1)
}

/// [`closed_loop_on`] against the nominal path walked in chords of
/// `ruler_mm`: a chord of length c departs from an arc of radius r by
/// c²/(8r), 1.25 µm for the 0.1 mm chords on r = 1 mm; small arcs need a
/// finer ruler.
pub fn closed_loop_with_ruler_on(
    rig: &Rig,
    original: &str,
    compensated: &str,
    frame: Frame,
    ruler_mm: f64,
) -> (PathError, PathError) {
    let nominal = NominalPath::of_program_on(rig, original, frame, ruler_mm);
    let before = actual_path_error_on(rig, original, frame, &nominal, 0.5);
    let after = actual_path_error_on(rig, compensated, frame, &nominal, 0.25);
    (before, after)
}

pub fn assert_closed_loop(name: &str, before: PathError, after: PathError) {
    eprintln!(
        "{name}: uncompensated max {:.3} µm (line {}) RMS {:.3} µm ({} samples); compensated max {:.4} µm (line {}) RMS {:.4} µm ({} samples); ratio max {:.3}% RMS {:.3}%",
        before.max_um,
        before.worst_line,
        before.rms_um,
        before.samples,
        after.max_um,
        after.worst_line,
        after.rms_um,
        after.samples,
        100.0 * after.max_um / before.max_um,
        100.0 * after.rms_um / before.rms_um
    );
    assert!(before.max_um > 5.0, "{name}: nothing to compensate?");
    assert!(
        after.samples > before.samples,
        "{name}: replay sampled densely"
    );
    assert!(
        after.max_um < 0.02 * before.max_um,
        "{name}: compensated max {} µm vs {} µm",
        after.max_um,
        before.max_um
    );
    assert!(
        after.rms_um < 0.02 * before.rms_um,
        "{name}: compensated RMS {} µm vs {} µm",
        after.rms_um,
        before.rms_um
    );
}

pub fn read(path: &str) -> String {
    std::fs::read_to_string(root().join(path)).expect("fixture")
}

/// The saddle, compensated: the whole program (deterministic), and the summary.
#[test]
fn saddle_compensated_program_snapshot() {
    let (text, report) = compensate_text(&read("samples/saddle.nc"), Frame::Joint);
    insta::assert_snapshot!("saddle_compensated", text);
    assert_eq!(report.blocks_read, 3927);
    // Roughing with T2 (60 mm), finishing with T1 (100 mm).
    let tools: Vec<(u32, f64)> = report.tools.iter().map(|t| (t.tool, t.length_mm)).collect();
    assert_eq!(tools, vec![(2, 60.0), (1, 100.0)]);
    assert!(report.max_residual_nm <= 1.0 + 1e-9);
}

#[test]
fn saddle_closed_loop_is_within_two_percent() {
    let original = read("samples/saddle.nc");
    let (compensated, _) = compensate_text(&original, Frame::Joint);
    let (before, after) = closed_loop(&original, &compensated, Frame::Joint);
    assert_closed_loop("saddle.nc", before, after);
}

/// The tool-tip-control saddle (G43.4 switches to the part frame).
#[test]
fn saddle_tcp_closed_loop_is_within_two_percent() {
    let original = read("samples/saddle-tcp.nc");
    let (compensated, report) = compensate_text(&original, Frame::Joint);
    assert!(report.blocks_changed > 3000);
    let (before, after) = closed_loop(&original, &compensated, Frame::Joint);
    assert_closed_loop("saddle-tcp.nc", before, after);
}

/// Word letters of a line, in order.
fn letters(line: &str) -> Vec<u8> {
    parse_block(line)
        .expect("parses")
        .words
        .iter()
        .map(|w| w.letter)
        .collect()
}

fn comments(line: &str) -> Vec<String> {
    let b = parse_block(line).expect("parses");
    b.comments
        .iter()
        .map(|c| line[c.clone()].to_string())
        .collect()
}

/// Total G93 time (minutes) of a program: Σ 1/F over inverse-time moves.
fn inverse_time_minutes(text: &str) -> f64 {
    let mut reader = BlockReader::new(text.as_bytes(), ReadOptions::default());
    let mut interpreter = Interpreter::new(interpret_options(Frame::Joint));
    let mut total = 0.0;
    while let Some(block) = reader.next_block() {
        let event = interpreter
            .interpret(block.expect("reads"))
            .expect("interprets");
        if let Some(m) = event.motion()
            && let Feed::InverseTime(f) = m.feed
        {
            total += 1.0 / f;
        }
    }
    total
}

#[test]
fn linuxcnc_demo_keeps_lines_words_and_inverse_time() {
    let original = read("tests/data/compensate/linuxcnc-demo.ngc");
    // Its error is smaller than the saddle's (max ≈ 20 µm): 2% of it is below the
    // default 0.5 µm split tolerance, so split at 0.2 µm.
    let (compensated, report) = compensate_with_tolerance(&original, Frame::Joint, 0.2);
    assert!(report.blocks_split > 0, "the long moves are split");
    let lines: Vec<&str> = original.lines().collect();
    let out: Vec<&str> = compensated.lines().collect();
    let summaries = |text: &str| -> Vec<BlockSummary> {
        BlockSummaries::new(ref_program(text, "p.nc"), interpret_options(Frame::Joint))
            .map(|s| s.expect("reads"))
            .collect()
    };
    let (mut pairs, mut added) = (0, 0);
    let aligned = Aligner::new(
        summaries(&original).into_iter(),
        summaries(&compensated).into_iter(),
        AlignOptions::default(),
    );
    for item in aligned {
        match item {
            Aligned::Pair(a, b) => {
                pairs += 1;
                let (line, new) = (lines[a.line - 1], out[b.line - 1]);
                if a.motion.is_none() {
                    assert_eq!(new, line, "non-motion line {} byte for byte", a.line);
                    continue;
                }
                assert_eq!(comments(new), comments(line), "line {}", a.line);
                assert_eq!(a.number, b.number, "line {}", a.line);
                let got = letters(new);
                // A split arc becomes straight pieces: its centre words go.
                let want: Vec<u8> = letters(line)
                    .into_iter()
                    .filter(|c| !b"IJKR".contains(c) || got.contains(c))
                    .collect();
                // The original words keep their order; words may be added after them.
                let kept: Vec<u8> = got.iter().copied().filter(|c| want.contains(c)).collect();
                assert_eq!(kept, want, "line {}: {line:?} -> {new:?}", a.line);
            }
            Aligned::Added(b) => {
                added += 1;
                let piece = out[b.line - 1];
                assert!(b.motion.is_some(), "added line {}: {piece}", b.line);
                assert!(comments(piece).is_empty() && b.number.is_none(), "{piece}");
                assert!(
                    letters(piece).iter().all(|c| b"GXYZACF".contains(c)),
                    "{piece}"
                );
            }
            Aligned::Removed(a) => panic!("line {} removed", a.line),
        }
    }
    assert_eq!(pairs, lines.len());
    assert_eq!(added, report.blocks_added);
    let (t0, t1) = (
        inverse_time_minutes(&original),
        inverse_time_minutes(&compensated),
    );
    assert!(t0 > 0.2);
    assert!(
        ((t1 - t0) / t0).abs() < 1e-6,
        "G93 time {t0} min -> {t1} min"
    );
    let (before, after) = closed_loop(&original, &compensated, Frame::Joint);
    assert_closed_loop("linuxcnc-demo.ngc", before, after);
}

/// A long move over a region where the error changes is split, and each piece
/// lands on the nominal path within the tolerance (checked at the piece midpoints
/// and densely along every piece).
#[test]
fn long_move_is_split_and_every_piece_is_within_tolerance() {
    let original = "G21 G90 G94\nG0 X-180 Y0 Z0 A60 C200\nG1 X180 F1000\nM2\n";
    let (compensated, report) = compensate_text(original, Frame::Joint);
    assert_eq!(report.blocks_split, 1, "{compensated}");
    assert!(report.blocks_added >= 3, "{compensated}");
    let nominal = NominalPath::of_program(original, Frame::Joint, 0.05);
    let (_, model) = ref_trt();
    let kin = model.kinematics();
    // Piece midpoints, from the emitted joint targets.
    let mut reader = BlockReader::new(compensated.as_bytes(), ReadOptions::default());
    let mut interpreter = Interpreter::new(interpret_options(Frame::Joint));
    let mut pieces = 0;
    let mut worst = 0.0f64;
    while let Some(block) = reader.next_block() {
        let event = interpreter.interpret(block.unwrap()).unwrap();
        let Some(&m) = event.motion() else { continue };
        if !matches!(m.kind, volcomp::gcode::MotionKind::Linear) {
            continue;
        }
        pieces += 1;
        let mid = m.start.lerp(&m.end, 0.5);
        let e = model.errors_at(&mid).unwrap();
        let d = nominal.distance(kin.actual_tip_and_axis(&mid, &e).tip) * 1e3;
        worst = worst.max(d);
    }
    assert_eq!(pieces, report.blocks_added + 1);
    let tol = CompensateOptions::default().tolerance_um;
    assert!(worst < tol, "piece midpoint {worst} µm off the path");
    let along = actual_path_error(&compensated, Frame::Joint, &nominal, 0.1);
    eprintln!(
        "split move: {pieces} pieces, midpoints ≤ {worst:.4} µm, along the path max {:.4} µm",
        along.max_um
    );
    assert!(along.max_um < tol);
}

use crate::support::volcomp;

#[test]
fn cli_refuses_a_target_outside_the_travel_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("edge.nc");
    // X200 is the end of the travel; the compensated target goes beyond it.
    std::fs::write(
        &program,
        "G21 G90\nG1 X199.9999 Y149.9999 Z99.9999 A60 C200 F1000\nM2\n",
    )
    .unwrap();
    let out_path = dir.path().join("out.nc");
    let out = volcomp()
        // The tables end at the travel limits: hold their end values so that the
        // travel check, not the table lookup, refuses the block.
        .args([
            "compensate",
            "machines/ref-trt.toml",
            "--extrapolate",
            "hold",
        ])
        .arg(&program)
        .arg("-o")
        .arg(&out_path)
        .current_dir(root())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("edge.nc:2"), "{stderr}");
    assert!(stderr.contains("outside its travel"), "{stderr}");
    assert!(!out_path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temp file left"
    );
}

#[test]
fn cli_locates_an_unreadable_program() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("bad.nc");
    std::fs::write(&program, "G21 G90\nG1 X10 Y(oops\n").unwrap();
    let out = volcomp()
        .args(["compensate", "machines/ref-trt.toml"])
        .arg(&program)
        .arg("-o")
        .arg(dir.path().join("out.nc"))
        .current_dir(root())
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("bad.nc:2:"), "{stderr}");
    assert!(!dir.path().join("out.nc").exists());
}

#[test]
fn cli_writes_the_program_to_stdout_and_the_summary_to_stderr() {
    let out = volcomp()
        .args([
            "compensate",
            "machines/ref-trt.toml",
            "tests/data/compensate/linuxcnc-demo.ngc",
            "-o",
            "-",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    let stdout = String::from_utf8(out.stdout).unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    // The provenance stamp comes first (no `%` or `O` line here), then the
    // program as the library writes it.
    assert!(
        stdout.starts_with("(volcomp-stamp compensated-by: volcomp "),
        "{stdout}"
    );
    let stamp = volcomp::stamp::Stamp::find(&stdout).expect("stamped");
    assert_eq!(stamp.machine, "ref-trt");
    let stdout: String = stdout
        .split_inclusive('\n')
        .skip_while(|l| l.starts_with(volcomp::stamp::PREFIX))
        .collect();
    assert!(stdout.starts_with("( xyzac-trt demo"), "{stdout}");
    assert!(stdout.contains("\nM429\n"));
    assert!(!stdout.contains("blocks read"));
    assert!(stderr.contains("blocks read"), "{stderr}");
    // The command's default: tip and tool axis.
    let (library, _) = compensate_with(
        &read("tests/data/compensate/linuxcnc-demo.ngc"),
        Frame::Joint,
        0.5,
        true,
    );
    assert_eq!(stdout, library);
}

/// Found by fuzzing: a full-circle helix (start = end, `P2`) kept its centre
/// only up to the radius (the projection of the centre on the bisector of a
/// µm chord is noise). Its centre now moves by µm, and the program reads back.
#[test]
fn a_full_circle_helix_keeps_its_centre() {
    let text = "%\nG21 G90 G94 G17 F400\nG0 X0 Y0 Z0 A10 C0\nG1 X10\n\
                G3 X10 Y0 Z-5 I-5 J0 P2\nG2 X0 Y0 R5\nM30\n%\n";
    // A tolerance the correction's variation round the helix stays within:
    // it is not split (at 0.5 µm it is, into straight pieces).
    let (compensated, _) = compensate_with_tolerance(text, Frame::Joint, 10.0);
    let helix = compensated
        .lines()
        .find(|l| l.starts_with("G3") && l.contains("P2"))
        .expect("the helix stays one block");
    let word = |letter: char| -> f64 {
        helix
            .split_whitespace()
            .find_map(|w| w.strip_prefix(letter))
            .unwrap()
            .parse()
            .unwrap()
    };
    assert!((word('I') + 5.0).abs() < 0.01, "{helix}");
    assert!(word('J').abs() < 0.01, "{helix}");
    let program = volcomp::gcode::Program::from_text(&compensated, "c.nc");
    let mut run = program.run(interpret_options(Frame::Joint));
    while let Some(step) = run.next() {
        step.expect("the compensated program reads back");
    }
}

/// `compensate --report` carries the expected residual from the model's own
/// noise; without `--report` it is not computed (it doubles the run time).
#[test]
fn the_report_gives_the_expected_residual_from_the_model_noise() {
    let dir = tempfile::tempdir().unwrap();
    let run = |name: &str, extra: &[&std::path::Path]| {
        let mut cmd = crate::support::volcomp();
        cmd.current_dir(root())
            .args([
                "compensate",
                "machines/ref-trt.toml",
                "samples/saddle.nc",
                "-o",
            ])
            .arg(dir.path().join(name));
        if let Some(report) = extra.first() {
            cmd.arg("--report").arg(report);
        }
        let out = cmd.output().unwrap();
        crate::support::assert_success(&out);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let report = dir.path().join("comp.json");
    let stdout = run("out.nc", &[&report]);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let rms = v["expected_residual_rms_um"].as_f64().unwrap();
    let max = v["expected_residual_max_um"].as_f64().unwrap();
    // Measured: 0.442 / 0.452 µm (tables with ~0.2 µm and ~0.5 µrad of noise).
    assert!(rms > 0.1 && rms < 1.0 && max >= rms, "{rms} {max}");
    assert!(stdout.contains("expected residual"));
    assert!(!run("out2.nc", &[]).contains("expected residual"));
}

/// The modelled actual tool axis at every cutting block end of `text`, against
/// the nominal axis of the same line of `original`: (max, RMS) angle, µrad.
fn replayed_axis_error(original: &str, text: &str, frame: Frame) -> (f64, f64, usize) {
    replayed_axis_error_on(ref_trt(), original, text, frame)
}

/// [`replayed_axis_error`] on any machine.
pub fn replayed_axis_error_on(
    rig: &Rig,
    original: &str,
    text: &str,
    frame: Frame,
) -> (f64, f64, usize) {
    let (machine, model) = rig;
    // Blocks pair by their N number (a split move's extra pieces have none,
    // and the stamp moves every line), else by line.
    let ends = |t: &str| {
        let labels: Vec<Option<&str>> = t
            .lines()
            .map(|l| l.split_whitespace().next().filter(|w| w.starts_with('N')))
            .collect();
        let mut out: HashMap<String, (volcomp::axes::Axes, volcomp::gcode::ToolInUse)> =
            HashMap::new();
        walk_program(
            program_on(machine, t, "replayed.nc"),
            model.kinematics(),
            interpret_options_on(machine, frame),
            WalkOptions {
                step_mm: 1e6,
                rapid_mm_per_min: machine.rapid_mm_per_min,
            },
            |p| {
                if p.cutting && p.block_end {
                    let key = labels[p.line - 1]
                        .map_or_else(|| format!("line {}", p.line), str::to_string);
                    out.insert(key, (p.joints.axes(), p.tool));
                }
            },
        )
        .expect("walks");
        out
    };
    let (nominal, actual) = (ends(original), ends(text));
    let (mut max, mut sum_sq, mut n) = (0.0f64, 0.0, 0usize);
    for (line, (q0, _)) in &nominal {
        let Some((q, tool)) = actual.get(line) else {
            continue;
        };
        let kin = volcomp::machine::kinematics_with(model, tool);
        let errors = model.errors_at(q).expect("inside the tables");
        let a = kin.actual_tip_and_axis(q, &errors).axis;
        let norm = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
        let u = kin.nominal_tool_axis(q0);
        let c = [
            a[1] * u[2] - a[2] * u[1],
            a[2] * u[0] - a[0] * u[2],
            a[0] * u[1] - a[1] * u[0],
        ];
        let angle = 1e6 * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt() / norm;
        max = max.max(angle);
        sum_sq += angle * angle;
        n += 1;
    }
    (max, (sum_sq / n.max(1) as f64).sqrt(), n)
}

/// `--orientation` on the saddle (joint and tool-tip frames): the solver puts
/// the modelled tool axis on the programmed one to ≤ 0.01 µrad with the tip to
/// ≤ 1 nm; replayed from the written program (A and C at the program's four
/// decimals, 0.0001° = 1.7 µrad) the axis error falls from ~150 µrad to the
/// rounding, and the tip path stays within 2 % as without it.
#[test]
fn orientation_compensation_corrects_the_tool_axis_too() {
    for (file, frame) in [
        ("samples/saddle.nc", Frame::Joint),
        ("samples/saddle-tcp.nc", Frame::Part),
    ] {
        let original = read(file);
        let (text, report) = compensate_with(&original, frame, 0.5, true);
        let o = report.orientation.as_ref().expect("orientation report");
        assert_eq!(
            o.position_only_moves, 0,
            "{file}: the saddle stays away from A = 0"
        );
        assert!(o.axis_error_before_rms_urad > 100.0, "{file}: {o:?}");
        assert!(o.axis_error_after_max_urad <= 0.01, "{file}: {o:?}");
        assert!(
            report.max_residual_nm <= 1.0,
            "{file}: {}",
            report.max_residual_nm
        );
        let (before_max, before_rms, n) = replayed_axis_error(&original, &original, frame);
        let (after_max, after_rms, m) = replayed_axis_error(&original, &text, frame);
        eprintln!(
            "{file}: replayed tool-axis error {n} block ends: before max {before_max:.2} RMS {before_rms:.2} µrad; after ({m}) max {after_max:.3} RMS {after_rms:.3} µrad"
        );
        assert!(before_rms > 100.0 && n > 3000, "{file}");
        assert!(
            after_max < 3.0 && after_rms < 1.5,
            "{file}: {after_max} {after_rms}"
        );
        let (before, after) = closed_loop(&original, &text, frame);
        assert_closed_loop(file, before, after);
    }
}

/// Near the A = 0 pole C cannot steer the tool axis: those moves stay
/// position-only, counted and located by line; the others are corrected.
#[test]
fn orientation_falls_back_to_position_only_at_the_pole() {
    let program = "%\nO1\nG21 G90 G94 G17\nG1 F1000 X0 Y0 Z0 A0 C0\nX10 C30\nX20 A0.5 C60\nX30 A20 C90\nX40 A25 C120\nM30\n%\n";
    let (_, report) = compensate_with(program, Frame::Joint, 0.5, true);
    let o = report.orientation.expect("orientation report");
    assert_eq!(o.moves, 5, "{o:?}");
    assert_eq!(o.position_only_moves, 3, "{o:?}");
    assert_eq!(o.position_only_lines, vec![4, 5, 6]);
    assert!(report.max_residual_nm <= 1.0);
}

/// The orientation solve keeps its Jacobian from pose to pose along a path
/// (`WarmStart`): on a path that sweeps A down to the pole and back, every pose
/// solves as it does from a cold start (the same fall-backs to position only,
/// the same joints within the residuals), and a kept Jacobian never lets a
/// pose through that a fresh one would refuse.
#[test]
fn a_kept_jacobian_solves_as_a_fresh_one() {
    use volcomp::axes::{Axes, Joints};
    use volcomp::compensate::{RESIDUAL_MM, RESIDUAL_URAD, WarmStart, solve_pose_from};
    let (_, model) = ref_trt();
    let mut warm = WarmStart::default();
    let (mut kept_fallbacks, mut poses) = (0, 0);
    for i in 0..=400 {
        let t = i as f64 / 400.0;
        let nominal = Joints::new(Axes::xyzac(
            -80.0 + 160.0 * t,
            40.0 * (6.0 * t).sin(),
            -30.0 + 20.0 * t,
            30.0 * (2.0 * std::f64::consts::PI * t).cos().abs() + 0.05,
            720.0 * t,
        ));
        let kept = solve_pose_from(model, &nominal, &mut warm).expect("solves");
        let fresh = solve_pose_from(model, &nominal, &mut WarmStart::default()).expect("solves");
        poses += 1;
        match (kept, fresh) {
            (Some(k), Some(f)) => {
                assert!(k.residual_mm < RESIDUAL_MM && k.residual_urad < RESIDUAL_URAD);
                assert!(
                    k.joints.xyz_distance(&f.joints) < 1e-5,
                    "{nominal:?}: {k:?} {f:?}"
                );
                assert!((k.before_urad - f.before_urad).abs() < 1e-3 * f.before_urad.max(1.0));
                // As `compensate` does: the next pose starts from this correction.
                warm.correction =
                    std::array::from_fn(|i| k.joints.to_array()[i] - nominal.to_array()[i]);
            }
            (None, None) => kept_fallbacks += 1,
            (k, f) => panic!("{nominal:?}: kept {k:?}, fresh {f:?}"),
        }
    }
    assert!(
        kept_fallbacks > 0 && kept_fallbacks < poses / 4,
        "{kept_fallbacks} of {poses}"
    );
}

/// The flank sample (a drafted wall cut by the side of a flat end mill, T3
/// with a 25 mm flute, docs/extensions.md tool shapes): `predict` takes each
/// wall point's deviation where the side touches it, up to 21 mm up the
/// flute, so the tool's tilt shows in the part. Position-only compensation puts
/// the tip right and leaves the tilt acting on that lever; `--orientation`
/// removes both. Measured as the part would come out: `profile_with_path_um`.
#[test]
fn flank_milling_needs_the_tool_axis_corrected() {
    use volcomp::inspection::Plan;
    use volcomp::predict::predict_plan;
    use volcomp::toolpath::CutOptions;
    let (machine, model) = ref_trt();
    let original = read("samples/flank.nc");
    let plan = Plan::read(&root().join("samples/flank-plan.csv")).expect("plan");
    let options = CutOptions::for_machine(machine, Frame::Joint);
    let predict = |text: &str| {
        predict_plan(ref_program(text, "flank.nc"), model, &plan, &options).expect("predicts")
    };
    let before = predict(&original);
    let (position_only, _) = compensate_with(&original, Frame::Joint, 0.5, false);
    let (full, report) = compensate_with(&original, Frame::Joint, 0.5, true);
    let position_only = predict(&position_only);
    let full = predict(&full);
    let o = report.orientation.expect("orientation report");
    eprintln!(
        "flank: profile before {:.2} µm; position-only {:.2} µm; full {:.2} µm; tool axis before {:.1} µrad RMS",
        before.profile_with_path_um,
        position_only.profile_with_path_um,
        full.profile_with_path_um,
        o.axis_error_before_rms_urad
    );
    for r in [&before, &position_only, &full] {
        assert_eq!(r.points_cut, 180);
    }
    assert!(before.profile_with_path_um > 20.0);
    assert!(
        position_only.profile_with_path_um > 3.0,
        "the tilt on the flute's lever remains"
    );
    assert!(full.profile_with_path_um < 0.5);
    assert!(full.profile_with_path_um < 0.1 * position_only.profile_with_path_um);
    // The tilt's share grows up the flute: position-only leaves more at the top.
    let residual = |r: &volcomp::predict::PredictReport, z: f64| {
        let d: Vec<f64> = r
            .points
            .iter()
            .filter(|p| (p.point[2] - z).abs() < 1e-9)
            .filter_map(|p| p.deviation_with_path_um)
            .collect();
        (d.iter().map(|v| v * v).sum::<f64>() / d.len() as f64).sqrt()
    };
    assert!(residual(&position_only, 18.0) > 3.0 * residual(&position_only, 2.0));
}

/// The program without volcomp's stamp lines.
fn unstamped(text: &str) -> String {
    text.split_inclusive('\n')
        .filter(|l| !l.starts_with(volcomp::stamp::PREFIX))
        .collect()
}

/// Compensate `text` with the command (ref-trt, `args` added), with a report:
/// the output, the summary and the report.
fn compensate_cli(text: &str, args: &[&str]) -> (String, String, serde_json::Value) {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("part.ngc");
    std::fs::write(&program, text).unwrap();
    let (out_path, report) = (dir.path().join("out.ngc"), dir.path().join("r.json"));
    let out = volcomp()
        .args(["compensate", "machines/ref-trt.toml"])
        .arg(&program)
        .arg("-o")
        .arg(&out_path)
        .arg("--report")
        .arg(&report)
        .args(args)
        .current_dir(root())
        .output()
        .unwrap();
    crate::support::assert_success(&out);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    (
        std::fs::read_to_string(&out_path).unwrap(),
        String::from_utf8(out.stdout).unwrap(),
        report,
    )
}

/// Issue 23: a file that only defines subroutines came out empty, and
/// `o<sq> sub … endsub` then `M2` came out as `M2`. Definitions the program
/// passes over are written as they are (LinuxCNC skips them there too), and
/// the summary and the report say they are not compensated.
#[test]
fn subroutine_definitions_are_written_as_they_are() {
    let library = "(probing library)\no<probe> sub\n  G38.2 Z-10 F100\n  o<probe> if [#5070 EQ 0]\n    (abort, not found)\n  o<probe> endif\n  G0 Z#1 (retract)\no<probe> endsub\n\nO200 sub\n  G1 X#1 Y#2 F300\nO200 endsub\nM2\n";
    let (out, summary, report) = compensate_cli(library, &[]);
    assert_eq!(unstamped(&out), library);
    assert!(
        summary.contains("2 subroutine definitions written as they are")
            && summary.contains("o<probe> (lines 2–8), O200 (lines 10–12)"),
        "{summary}"
    );
    let defs = &report["subroutine_definitions"];
    assert_eq!(defs[0]["name"], "o<probe>");
    assert_eq!(
        (
            defs[1]["first_line"].as_u64(),
            defs[1]["last_line"].as_u64()
        ),
        (Some(10), Some(12))
    );
    let sq = "o<sq> sub\n  G1 X#1 F100\no<sq> endsub\nM2\n";
    assert_eq!(unstamped(&compensate_cli(sq, &[]).0), sq);
}

/// A called subroutine: its definition stays as written, its calls come flat
/// and compensated, and LinuxCNC reads the written program to the same
/// positions (within the corrections, µm).
#[test]
fn called_subroutines_are_written_flat_beside_their_definition() {
    let text = "G21 G90 G17 G94 F300\nG0 X10 Y10 Z5 A0 C0\no<sq> sub\n  G1 X[10+#1] Y10 Z0\n  G1 Y[10+#1]\no<sq> endsub\no<sq> call [5]\no<later> call [2]\no<sq> call [7]\nG0 Z5\nM2\no<later> sub\n  G1 X#1\no<later> endsub\n";
    let (out, _, report) = compensate_cli(text, &[]);
    let out = unstamped(&out);
    assert!(
        out.contains("o<sq> sub\n  G1 X[10+#1] Y10 Z0\n  G1 Y[10+#1]\no<sq> endsub\n"),
        "{out}"
    );
    assert!(
        out.ends_with("M2\no<later> sub\n  G1 X#1\no<later> endsub\n"),
        "{out}"
    );
    assert!(!out.contains("call"), "{out}");
    assert_eq!(report["motion_blocks"], 7);
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.ngc"), dir.path().join("b.ngc"));
    std::fs::write(&a, text).unwrap();
    std::fs::write(&b, &out).unwrap();
    let original = crate::rs274::rs274_motions(&a).expect("rs274 reads the original");
    let written = crate::rs274::rs274_motions(&b).expect("rs274 reads the written program");
    assert_eq!(original.len(), written.len(), "{original:?}\n{written:?}");
    for (p, q) in original.iter().zip(&written) {
        let d = p
            .iter()
            .zip(q)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max);
        assert!(d < 0.05, "{p:?} vs {q:?}");
    }
}

/// Issue 23: a full circle of even `P` (its midpoint is its start) and `G1
/// C720` (its midpoint is the pose of its ends) were never split, though the
/// correction varies along them. The split test samples a move where its pose
/// differs, at most a quarter turn apart.
#[test]
fn moves_whose_midpoint_is_the_pose_of_their_ends_are_split() {
    for (name, text) in [
        (
            "full circle P2",
            "G21 G90 G17 G94 F500\nG0 X-50 Y0 Z10 A0 C0\nG1 X-40 Y0 Z0\nG2 X-40 Y0 I40 J0 P2\nG1 X-50\nM2\n",
        ),
        (
            "G1 C720",
            "G21 G90 G94 F500\nG0 X50 Y30 Z10 A30 C0\nG1 X51\nG1 C720\nM2\n",
        ),
    ] {
        // Unsplit (a tolerance it cannot exceed), the compensated move leaves
        // the path by more than the default tolerance…
        let (unsplit, report) = compensate_with_tolerance(text, Frame::Joint, 1e3);
        assert_eq!(report.blocks_split, 0, "{name}");
        let (before, unsplit) = closed_loop(text, &unsplit, Frame::Joint);
        // …split, it stays within it.
        let (compensated, report) = compensate_text(text, Frame::Joint);
        let (_, after) = closed_loop(text, &compensated, Frame::Joint);
        eprintln!(
            "{name}: uncompensated max {:.3} µm; compensated unsplit max {:.3} µm, split ({} pieces) max {:.4} µm",
            before.max_um,
            unsplit.max_um,
            report.blocks_added + 1,
            after.max_um
        );
        assert!(unsplit.max_um > 1.0, "{name}: {unsplit:?}");
        assert_eq!(report.blocks_split, 1, "{name}");
        assert!(report.split_cap.is_none(), "{name}");
        assert!(after.max_um < 0.5, "{name}: {after:?}");
    }
}

/// Issue 23: an arc's `P` of a million turns or more was read as one turn
/// (LinuxCNC runs them all), and `P100001` became 100,000 straight pieces of
/// a turn each (the circle collapsed). Every turn is read; an arc that needs
/// more straight pieces than volcomp writes is a located error.
#[test]
fn arcs_of_many_turns_are_read_whole_or_refused() {
    let arc = |p: &str| {
        format!(
            "G21 G90 G17 G94 F500\nG0 X-50 Y0 Z10 A0 C0\nG1 X-40 Y0 Z0\nG2 X-40 Y0 I40 J0 P{p}\nM2\n"
        )
    };
    let events = volcomp::gcode::interpret_program(
        arc("1000001").as_bytes(),
        interpret_options(Frame::Joint),
    )
    .expect("reads");
    let m = events[3].1.motion().copied().expect("the arc");
    let turns = m.arc_geometry().unwrap().sweep().abs() / std::f64::consts::TAU;
    assert!((turns - 1_000_001.0).abs() < 1e-6, "{turns}");
    let (machine, model) = ref_trt();
    let options = CompensateOptions {
        interpret: interpret_options(Frame::Joint),
        limits: Some(machine.limits),
        ..CompensateOptions::default()
    };
    let e = compensate(
        ref_program(&arc("100001"), "many.nc"),
        &mut Vec::new(),
        model,
        &options,
        |_| {},
    )
    .expect_err("too many pieces");
    let message = e.to_string();
    assert!(
        message.starts_with("many.nc:4: the correction varies along this arc")
            && message.contains("more than the 100000 volcomp writes"),
        "{message}"
    );
}

/// Issue 23: the split cap (256 pieces a move) was reached silently
/// (`--tol 1e-300` on the flank: every move 256 pieces, exit 0). It is a
/// counted warning, in the summary and the report.
#[test]
fn the_split_cap_reached_is_counted_and_said() {
    let (_, summary, report) = compensate_cli(&read("samples/flank.nc"), &["--tol", "1e-300"]);
    let cap = &report["split_cap"];
    assert_eq!(cap["pieces"], 256);
    let moves = cap["moves"].as_u64().unwrap();
    assert!(moves > 300, "{cap}");
    assert!(cap["max_departure_um"].as_f64().unwrap() > 0.0);
    assert!(
        summary.contains(&format!(
            "warning: {moves} moves reached the split cap of 256 pieces"
        )) && summary.contains("more than the tolerance 1e-300 µm"),
        "{summary}"
    );
    // At the default tolerance no move reaches it, and the report says nothing.
    let (_, summary, report) = compensate_cli(&read("samples/flank.nc"), &[]);
    assert!(report.get("split_cap").is_none(), "{report}");
    assert!(!summary.contains("split cap"), "{summary}");
}

/// Issue 23: splines (G5, G5.1, G5.2 … G5.3) are written flat by
/// `compensate`: straight pieces within a tenth of the tolerance of the
/// curve, each end compensated like any move. Replayed through the model,
/// the written program follows the programmed curve within the tolerance.
#[test]
fn splines_are_written_as_compensated_straight_pieces() {
    let text = "G21 G90 G17 G94 F600\nG0 X-40 Y-20 Z0 A0 C0\nG1 X-30\n\
                G5 I10 J0 P-10 Q0 X10 Y10\nG5 P-5 Q-5 X40 Y-10\n\
                G5.1 I5 J20 X60 Y-10\nG5.2 X60 Y20 P1 L4\nX30 Y40 P2\nX0 Y20 P1\nX-30 Y30 P1\nG5.3\n\
                G1 X-40\nM2\n";
    let (compensated, report) = compensate_text(text, Frame::Joint);
    let (before, after) = closed_loop(text, &compensated, Frame::Joint);
    eprintln!(
        "splines: {} moves, uncompensated max {:.3} µm, compensated max {:.4} µm RMS {:.4} µm",
        report.motion_blocks, before.max_um, after.max_um, after.rms_um
    );
    // Every piece's end is a compensated move; no spline word is left.
    assert!(report.motion_blocks > 500, "{report:?}");
    assert!(
        !compensated.lines().any(|l| l
            .split('(')
            .next()
            .unwrap_or("")
            .split_whitespace()
            .any(|w| w == "G5" || w.starts_with("G5."))),
        "{compensated}"
    );
    assert!(compensated.contains("(volcomp: G5 of line 4 written flat below)"));
    assert!(compensated.contains("(volcomp: the G5.2 NURBS run by line 11 written flat below)"));
    assert!(before.max_um > 2.0, "{before:?}");
    assert!(after.max_um < 0.5, "{after:?}");
}

/// A G5.3 that also starts another NURBS (its X Y are that NURBS's first
/// control point) cannot be written flat: a located error, not a lost point.
#[test]
fn a_g5_3_that_starts_another_nurbs_is_refused() {
    let text = "G21 G90 G17 G94 F600\nG0 X0 Y0 Z0 A0 C0\nG5.2 X0 Y10 P1\nX10 Y10 P1\nX10 Y0 P1\nG5.3 X20 Y0 P1\nX30 Y10 P1\nX40 Y0 P1\nG5.3\nM2\n";
    let (machine, model) = ref_trt();
    let options = CompensateOptions {
        interpret: interpret_options(Frame::Joint),
        limits: Some(machine.limits),
        ..CompensateOptions::default()
    };
    let e = compensate(
        ref_program(text, "n.ngc"),
        &mut Vec::new(),
        model,
        &options,
        |_| {},
    )
    .expect_err("refused");
    assert!(
        e.to_string().starts_with("n.ngc:6: ") && e.to_string().contains("another NURBS"),
        "{e}"
    );
}
