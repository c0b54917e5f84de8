//! Differential test of volcomp's SINUMERIK reading against CEAD's
//! `nc-gcode-interpreter` (PyPI, a SINUMERIK interpreter written in Rust
//! with a Python API; issue 34 item 6, dialects.md "Differential reference").
//!
//! One Python process (`tests/data/sinumerik/differential/cead_positions.py`)
//! reads every program: volcomp's SINUMERIK fixtures
//! (`tests/data/sinumerik/*.mpf`) and the 32 example programs of CEAD's own
//! repository (`tests/data/sinumerik/real/cead/`). For each it gives the
//! blocks that program an axis with every axis's position after the block
//! (after frames). volcomp's side is `volcomp check --targets` (machine
//! coordinates; no work offset is given, so they are the positions after
//! frames, and under `TRAORI` the programmed tool tip). Both sides drop
//! zero-length moves; then the moves must be as many, on the same lines, at
//! the same X Y Z A B C within [`TOLERANCE`].
//!
//! Each program's outcome must be the one [`EXPECTED`] gives it, with the
//! reason: a new difference, a difference that went away, or a program
//! without an entry fails the test. The interpreter is installed by
//! `.ci/run` in `target/nc-gcode-interpreter-venv` (or give its Python with
//! `VOLCOMP_NC_GCODE_PYTHON`); when it cannot run, the test fails.
//! `VOLCOMP_WRITE_SINUMERIK_TABLE=1` writes docs/sinumerik-differential.md
//! from the run.
use crate::support::root;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Largest difference of a position, mm or degrees, where both read a
/// program (both compute in double precision from the same decimal text;
/// frames with rotations leave ~1e-13).
const TOLERANCE: f64 = 1e-6;

/// The version `.ci/run` installs (the one this table was made with).
pub const REFERENCE_VERSION: &str = "0.2.8";

/// What a program does in the two interpreters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Outcome {
    /// Both read it: the same moves.
    Agree,
    /// Both read it, the moves differ.
    Differ,
    /// volcomp reads it, the reference refuses it.
    ReferenceRefuses,
    /// The reference reads it, volcomp refuses it.
    VolcompRefuses,
    /// Both refuse it.
    BothRefuse,
}

impl Outcome {
    fn name(self) -> &'static str {
        match self {
            Outcome::Agree => "agree",
            Outcome::Differ => "differ",
            Outcome::ReferenceRefuses => "reference refuses",
            Outcome::VolcompRefuses => "volcomp refuses",
            Outcome::BothRefuse => "both refuse",
        }
    }
}

/// How a program is read by both sides.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Text {
    /// As written.
    AsWritten,
    /// A fragment (no program end, no feed before its first G1: the control
    /// and volcomp refuse it as written): both sides read it with a first
    /// line `F1000` and a last line `M30` added ([`FRAGMENT_HEAD`],
    /// [`FRAGMENT_TAIL`]); lines are then one more than in the file.
    Fragment,
}

/// The line put before a fragment.
const FRAGMENT_HEAD: &str = "F1000 ; volcomp differential: a feed\n";
/// The line put after a fragment.
const FRAGMENT_TAIL: &str = "M30 ; volcomp differential: a program end\n";

use Outcome::*;
use Text::*;

/// Every program (under `tests/data/sinumerik/`), the arguments volcomp
/// reads it with, how both read it, its outcome and why (docs/
/// sinumerik-differential.md shows these reasons).
const EXPECTED: &[(&str, &[&str], Text, Outcome, &str)] = &[
    // volcomp's fixtures.
    (
        "language.mpf",
        &["--subroutine-path", "tests/data/sinumerik/subprograms"],
        AsWritten,
        ReferenceRefuses,
        "the reference refuses `Y.5` (line 11: \"expected the end of the program\"), a number the 840D reads (a leading zero left out, as CAM output writes `.02`); the file also calls subprograms (`L12`, `CORNER(7, -3)`), which the reference does not run",
    ),
    (
        "arcs.mpf",
        &[],
        AsWritten,
        ReferenceRefuses,
        "the reference does not read `CIP … I1= J1=` (line 7: \"expected a comment (;...), or a statement\"), nor the other circles written without a centre (`CT`, `AR=`, `TURN=`); volcomp works each out into the centre form (the fixture's comments check them by hand)",
    ),
    (
        "plane-3plus2.mpf",
        &["--machine", "machines/ref-trt.toml"],
        AsWritten,
        Differ,
        "the reference does not model `CYCLE800` (it passes the call over): its positions are the plane's own X Y Z and no rotary axes; volcomp's are the tool tip in the part frame of the plane swivelled 30° about X (`Rx(30°)·p`), with A30 C−180 where ref-trt reaches it; the test checks, move for move, that volcomp's `check --frame part --targets` tip is `Rx(30°)` of the reference's position",
    ),
    (
        "bspline.mpf",
        &[],
        AsWritten,
        Differ,
        "the reference does not interpolate `BSPLINE`: it moves straight to each control point (15 moves); volcomp follows the rational B spline (`SD=`, `PW=`, `PL=`) as chords within 0.5 µm (417 moves), each section checked by hand in tests/it/sinumerik_splines.rs",
    ),
    (
        "corners.mpf",
        &[],
        AsWritten,
        Differ,
        "a difference by design: the reference reads `RND=`, `RNDM=`, `CHF=`, `CHR=`, `FRC=` but inserts no corner (it moves to each programmed corner: 16 moves); volcomp rounds and chamfers them as *Fundamentals*, \"Chamfer, rounding\" defines (the corner its own move: 24 moves), every tangent point checked by hand in tests/it/sinumerik_corners.rs",
    ),
    (
        "frame-after-split-arc.mpf",
        &[],
        AsWritten,
        Agree,
        "`ROT Y30` and `TRANS Y5` after a circle: both turn and shift the moves after them alike (the fixture guards that compensate writes the frame statements alone in their blocks)",
    ),
    (
        "saddle-traori-ac.mpf",
        &[],
        AsWritten,
        Agree,
        "the reference does not model `TRAORI`; under it X Y Z are the programmed tool tip, which is what both give (volcomp turns them into joints only where a machine needs them)",
    ),
    (
        "saddle-traori-bc.mpf",
        &["--machine", "machines/bc-trt.toml"],
        AsWritten,
        Agree,
        "as saddle-traori-ac.mpf, on a B/C machine",
    ),
    (
        "saddle-traori-vector.mpf",
        &["--machine", "machines/ref-trt.toml"],
        AsWritten,
        ReferenceRefuses,
        "the reference does not read orientation vectors `A3= B3= C3=` (line 10: \"expected a comment (;...), or a statement\"); volcomp turns them into ref-trt's rotary joints on its chain (tests/it/sinumerik.rs checks the closed loop)",
    ),
    (
        "sections-tools-frames.mpf",
        &[
            "--subroutine-path",
            "tests/data/sinumerik/subprograms",
            "--offset",
            "G54=1,2,3",
            "--offset",
            "G505=50,60,70",
            "--offset",
            "G599=-10,-20,-30",
            "--tools",
            "tests/data/sinumerik/named-tools.tbl",
        ],
        AsWritten,
        ReferenceRefuses,
        "the reference does not read section repeats `REPEAT label [label2] P=n` (it takes `REPEAT` for the opener of `REPEAT … UNTIL`: \"REPEAT is never closed\" at line 15), nor runs calls (`STEPDOWN` with `VAR` parameters), tools by name or `G505`–`G599`; volcomp's reading is checked by hand, move for move, in tests/it/sinumerik.rs",
    ),
    (
        "orivect-turn.mpf",
        &["--machine", "machines/ref-trt.toml"],
        AsWritten,
        ReferenceRefuses,
        "the reference does not read orientation vectors `A3= B3= C3=` (line 9); volcomp splits the blocks whose tool turns on a great circle (`ORIVECT`) into pieces on it (tests/it/sinumerik_five_axis.rs checks them by hand)",
    ),
    (
        "tilted-arcs.mpf",
        &[],
        AsWritten,
        ReferenceRefuses,
        "the reference does not read `CIP … I1= J1= K1=` (line 15); before it, under `ROT Y30`, volcomp hands the circles of the tilted plane on as chords in that plane (tests/it/sinumerik_five_axis.rs checks them by hand)",
    ),
    (
        "cycle800-modes.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "read here without `--machine`: volcomp solves `CYCLE800` on the machine's chain and refuses it without one (line 9); the reference passes `CYCLE800` over (as for plane-3plus2.mpf). tests/it/sinumerik_five_axis.rs checks the projection and solid-angle planes by hand",
    ),
    (
        "plane-solid-angle.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "as cycle800-modes.mpf: `CYCLE800` (solid angle) needs the machine (line 8); the reference passes it over. The closed loop is in tests/it/sinumerik_five_axis.rs",
    ),
    (
        "cycle800-more-modes.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "as cycle800-modes.mpf: `CYCLE800` (axis sequences 27 and 39, solid angle with `_C`, projection Zα Xα, direct mode) needs the machine (line 9); the reference passes it over. tests/it/sinumerik_five_axis.rs checks every plane by hand",
    ),
    (
        "plane-direct.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "as cycle800-modes.mpf: `CYCLE800` in direct mode (rotary axis positions) needs the machine (line 8); the reference passes it over. The closed loop is in tests/it/sinumerik_five_axis.rs",
    ),
    (
        "ct-after-space-cip.mpf",
        &[],
        AsWritten,
        ReferenceRefuses,
        "the reference does not read `CIP … I1= J1= K1=` (line 9); volcomp hands the circle in space and the `CT` after it (the circle in space leaving its end tangentially) on as chords (tests/it/sinumerik_five_axis.rs checks them by hand)",
    ),
    (
        "circle-turning-tool.mpf",
        &["--machine", "machines/ref-trt.toml"],
        AsWritten,
        ReferenceRefuses,
        "the reference does not read `TRAORI ORIWKS ORIVECT` on one line (line 10) nor orientation vectors; volcomp hands the circles that turn the tool on as pieces, the tool on the great circle or the rotary axes linear in the path (tests/it/sinumerik_five_axis.rs checks them by hand)",
    ),
    // CEAD's example programs.
    (
        "real/cead/actual_position.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "reads the actual position `$AA_IW[Z]` (a value the control knows only while running): the reference serves it from its own interpolated position, volcomp refuses system variables without an offline value (dialects.md)",
    ),
    (
        "real/cead/arc.mpf",
        &[],
        Fragment,
        VolcompRefuses,
        "`G2 … I0 J-25 K5` under G17: volcomp refuses a K in an XY arc, as it does for LinuxCNC programs; the reference passes the arc's parameters through (it does not interpolate arcs)",
    ),
    (
        "real/cead/arrays.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "`DEF INT FELD[2,3,4] = REP(1,24)`: the `REP()` initialiser is not read by volcomp yet",
    ),
    (
        "real/cead/axis_index_assignment.mpf",
        &[],
        AsWritten,
        BothRefuse,
        "`ACC[E]=50`: the reference needs an axis index map it is not given, volcomp does not read `ACC` (acceleration: no position)",
    ),
    ("real/cead/basic_math.mpf", &[], Fragment, Agree, ""),
    ("real/cead/case.mpf", &[], AsWritten, Agree, ""),
    (
        "real/cead/case_insensitive_variables.mpf",
        &[],
        AsWritten,
        Agree,
        "",
    ),
    (
        "real/cead/custom_vars.mpf",
        &[],
        AsWritten,
        BothRefuse,
        "`X=aa`: a variable never defined, refused by both",
    ),
    (
        "real/cead/def_string.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "assigns a string to a `DEF STRING` variable (`_LOGFILENAME = \"…\"`): volcomp declares string variables but does not assign them yet",
    ),
    (
        "real/cead/defaults.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "`E=0`: E is an axis of the reference's default set (a 3D printer's extruder), not of a milling machine; volcomp, reading X Y Z A B C, refuses it",
    ),
    (
        "real/cead/edge_cases.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "`ELX=3087.02`: an axis named in the reference's example configuration; volcomp reads X Y Z A B C and refuses it",
    ),
    (
        "real/cead/flatten_demo.mpf",
        &[],
        AsWritten,
        Differ,
        "as bspline.mpf: the reference moves straight to each `BSPLINE` control point (7 moves); volcomp follows the B spline (the rational B-spline of *Job planning*, \"Spline interpolation\") as chords within 0.5 µm (258 moves)",
    ),
    ("real/cead/for_loop.mpf", &[], Fragment, Agree, ""),
    ("real/cead/function_calls.mpf", &[], Fragment, Agree, ""),
    ("real/cead/goto.mpf", &[], AsWritten, Agree, ""),
    ("real/cead/if_statement.mpf", &[], Fragment, Agree, ""),
    ("real/cead/increment.mpf", &[], Fragment, Agree, ""),
    (
        "real/cead/logic_operators.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "`R12 = 6 B_AND 3`: the bit operators `B_AND B_OR B_XOR B_NOT` are not read by volcomp yet",
    ),
    ("real/cead/loop.mpf", &[], AsWritten, Agree, ""),
    (
        "real/cead/multiple_m_codes.mpf",
        &[],
        Fragment,
        VolcompRefuses,
        "`X3 M103 M2 M3 M4 M5`: volcomp refuses two M codes of one modal group in a block (M3, M4 and M5 all set the spindle, M2 ends the program), as it does for LinuxCNC programs; the 840D takes five M functions per block but not contradictory spindle commands",
    ),
    ("real/cead/precedence.mpf", &[], Fragment, Agree, ""),
    ("real/cead/r_param.mpf", &[], Fragment, Agree, ""),
    ("real/cead/repeat.mpf", &[], Fragment, Agree, ""),
    (
        "real/cead/simple.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "`G2 X3 Z100` has no centre (no I J K, CR=, AR= or CIP point) and `X1 X=3` writes X twice: the control refuses both; the reference passes them",
    ),
    (
        "real/cead/spline.mpf",
        &[],
        AsWritten,
        VolcompRefuses,
        "`ASPLINE` (Akima spline, line 17): not read by volcomp yet (the `BSPLINE` section before it is read)",
    ),
    (
        "real/cead/tool.mpf",
        &[],
        Fragment,
        Agree,
        "`T=\"BALL_MILL_8MM_SHORT\" M6` and no move (before tools by name were read, volcomp refused it)",
    ),
    ("real/cead/trans.mpf", &[], Fragment, Agree, ""),
    ("real/cead/trans2.mpf", &[], Fragment, Agree, ""),
    ("real/cead/trans_ic.mpf", &[], Fragment, Agree, ""),
    ("real/cead/trans_reset.mpf", &[], Fragment, Agree, ""),
    ("real/cead/trig.mpf", &[], Fragment, Agree, ""),
    ("real/cead/variables.mpf", &[], Fragment, Agree, ""),
];

/// One side's reading: the moves (line, X Y Z A B C), or why it refused.
type Reading = Result<Vec<(usize, [f64; 6])>, String>;

/// The Python that has `nc_gcode_interpreter`, or why there is none.
fn reference_python() -> PathBuf {
    let python = std::env::var_os("VOLCOMP_NC_GCODE_PYTHON")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("target/nc-gcode-interpreter-venv/bin/python"));
    let probe = Command::new(&python)
        .args([
            "-c",
            "import importlib.metadata as m; print(m.version('nc-gcode-interpreter'))",
        ])
        .output();
    match probe {
        Ok(out) if out.status.success() => python,
        other => panic!(
            "CEAD's nc-gcode-interpreter cannot run with {} ({}): `.ci/run` installs it \
             (python3.12 -m venv target/nc-gcode-interpreter-venv && \
             target/nc-gcode-interpreter-venv/bin/pip install nc-gcode-interpreter=={REFERENCE_VERSION}), \
             or set VOLCOMP_NC_GCODE_PYTHON to a Python ≥ 3.12 that has it",
            python.display(),
            match other {
                Ok(out) => String::from_utf8_lossy(&out.stderr).trim().to_string(),
                Err(e) => e.to_string(),
            }
        ),
    }
}

/// The reference's reading of every program, in one Python process.
fn reference_readings(files: &[PathBuf]) -> BTreeMap<PathBuf, Reading> {
    let out = Command::new(reference_python())
        .arg(root().join("tests/data/sinumerik/differential/cead_positions.py"))
        .args(files)
        .current_dir(root())
        .output()
        .expect("the reference runs");
    assert!(
        out.status.success(),
        "the reference's driver failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    let mut readings = BTreeMap::new();
    for line in text.lines() {
        let v: serde_json::Value = serde_json::from_str(line).unwrap();
        let file = PathBuf::from(v["file"].as_str().unwrap());
        let reading = if v["ok"].as_bool().unwrap() {
            Ok(v["moves"]
                .as_array()
                .unwrap()
                .iter()
                .map(|m| {
                    let m = m.as_array().unwrap();
                    let mut p = [0.0; 6];
                    for (k, value) in p.iter_mut().enumerate() {
                        *value = m[2 + k].as_f64().unwrap();
                    }
                    (m[0].as_u64().unwrap() as usize, p)
                })
                .collect())
        } else {
            Err(format!(
                "{} at line {}: {}",
                v["kind"].as_str().unwrap_or("?"),
                v["line"].as_u64().map_or("?".into(), |l| l.to_string()),
                v["message"].as_str().unwrap_or("")
            ))
        };
        readings.insert(file, reading);
    }
    assert_eq!(readings.len(), files.len(), "one reading per program");
    readings
}

/// volcomp's reading: `check --targets -`.
fn volcomp_reading(file: &Path, args: &[&str]) -> Reading {
    let out = crate::support::volcomp()
        .arg("check")
        .arg(file)
        .args(args)
        .args(["--targets", "-"])
        .current_dir(root())
        .output()
        .unwrap();
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        // The message and its location (`--> file:line:column`).
        let message = err
            .lines()
            .next()
            .unwrap_or("")
            .trim_start_matches("error: ");
        let at = err
            .lines()
            .find_map(|l| l.trim().strip_prefix("--> "))
            .unwrap_or("");
        return Err(format!("{message} ({at})"));
    }
    let text = String::from_utf8(out.stdout).unwrap();
    Ok(text
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let mut p = [0.0; 6];
            for (k, value) in p.iter_mut().enumerate() {
                *value = f[2 + k].parse().unwrap_or(0.0);
            }
            (f[0].parse().unwrap(), p)
        })
        .collect())
}

/// The moves without the zero-length ones (from 0, where both start).
fn moving(moves: &[(usize, [f64; 6])]) -> Vec<(usize, [f64; 6])> {
    let mut last = [0.0; 6];
    let mut out = Vec::new();
    for (line, p) in moves {
        if (0..6).any(|k| (p[k] - last[k]).abs() > 1e-9) {
            out.push((*line, *p));
            last = *p;
        }
    }
    out
}

/// A program's comparison.
struct Comparison {
    file: String,
    outcome: Outcome,
    /// Moves compared (both read, the same count).
    moves: usize,
    /// Largest position difference over them.
    max_difference: Option<f64>,
    /// What differs, or why a side refused.
    detail: String,
    reference: String,
    volcomp: String,
}

fn compare(file: &str, reference: &Reading, ours: &Reading) -> Comparison {
    let said = |r: &Reading| match r {
        Ok(m) => match moving(m).len() {
            1 => "reads (1 move)".to_string(),
            n => format!("reads ({n} moves)"),
        },
        Err(e) => format!("refuses: {e}"),
    };
    let mut c = Comparison {
        file: file.to_string(),
        outcome: Outcome::Agree,
        moves: 0,
        max_difference: None,
        detail: String::new(),
        reference: said(reference),
        volcomp: said(ours),
    };
    match (reference, ours) {
        (Err(_), Err(_)) => c.outcome = Outcome::BothRefuse,
        (Err(_), Ok(_)) => c.outcome = Outcome::ReferenceRefuses,
        (Ok(_), Err(_)) => c.outcome = Outcome::VolcompRefuses,
        (Ok(a), Ok(b)) => {
            let (a, b) = (moving(a), moving(b));
            if a.len() != b.len() {
                c.outcome = Outcome::Differ;
                c.detail = format!("{} moves vs {}", a.len(), b.len());
            }
            let mut max: f64 = 0.0;
            for (k, ((la, pa), (lb, pb))) in a.iter().zip(&b).enumerate() {
                let d = (0..6).map(|i| (pa[i] - pb[i]).abs()).fold(0.0, f64::max);
                if (d > TOLERANCE || la != lb) && c.detail.is_empty() {
                    c.outcome = Outcome::Differ;
                    c.detail = format!("move {}: line {la} {pa:?} vs line {lb} {pb:?}", k + 1);
                }
                max = max.max(d);
            }
            c.moves = a.len().min(b.len());
            c.max_difference = (c.moves > 0).then_some(max);
        }
    }
    c
}

/// Every SINUMERIK program of the comparison: the fixtures and the real
/// programs, relative to `tests/data/sinumerik/`.
fn programs() -> Vec<String> {
    let base = root().join("tests/data/sinumerik");
    let mut out = Vec::new();
    for dir in ["", "real/cead"] {
        for entry in std::fs::read_dir(base.join(dir)).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().to_string();
            if name.to_ascii_lowercase().ends_with(".mpf") {
                out.push(if dir.is_empty() {
                    name
                } else {
                    format!("{dir}/{name}")
                });
            }
        }
    }
    out.sort();
    out
}

#[test]
fn volcomp_and_ceads_interpreter_read_sinumerik_programs_alike() {
    let names = programs();
    let expected: BTreeMap<&str, Expectation> = EXPECTED
        .iter()
        .map(|(file, args, text, outcome, why)| (*file, (*args, *text, *outcome, *why)))
        .collect();
    // Fragments are read from amended copies, by both sides.
    let amended = tempfile::tempdir().unwrap();
    let files: Vec<PathBuf> = names
        .iter()
        .map(|name| {
            let file = root().join("tests/data/sinumerik").join(name);
            match expected.get(name.as_str()) {
                Some((_, Fragment, _, _)) => {
                    let copy = amended.path().join(name.replace('/', "_"));
                    let text = std::fs::read_to_string(&file).unwrap();
                    let newline = if text.ends_with('\n') { "" } else { "\n" };
                    std::fs::write(
                        &copy,
                        format!("{FRAGMENT_HEAD}{text}{newline}{FRAGMENT_TAIL}"),
                    )
                    .unwrap();
                    copy
                }
                _ => file,
            }
        })
        .collect();
    let reference = reference_readings(&files);
    let plane = names.iter().position(|n| n == "plane-3plus2.mpf").unwrap();
    let mut comparisons = Vec::new();
    let mut failures = Vec::new();
    for (name, file) in names.iter().zip(&files) {
        let args = expected.get(name.as_str()).map_or(&[][..], |e| e.0);
        // Messages name the program as the table does (not a temporary copy).
        let ours =
            volcomp_reading(file, args).map_err(|e| e.replace(&file.display().to_string(), name));
        let c = compare(name, &reference[file], &ours);
        match expected.get(name.as_str()) {
            None => failures.push(format!(
                "{name}: not in EXPECTED (it came out `{}`: reference {}; volcomp {}; {})",
                c.outcome.name(),
                c.reference,
                c.volcomp,
                c.detail
            )),
            Some((_, _, want, _)) if c.outcome != *want => failures.push(format!(
                "{name}: expected `{}`, came out `{}` (reference {}; volcomp {}; {})",
                want.name(),
                c.outcome.name(),
                c.reference,
                c.volcomp,
                c.detail
            )),
            Some(_) => {}
        }
        comparisons.push(c);
    }
    for name in expected.keys() {
        if !names.iter().any(|n| n == name) {
            failures.push(format!("{name}: in EXPECTED but no such program"));
        }
    }
    if std::env::var("VOLCOMP_WRITE_SINUMERIK_TABLE").is_ok_and(|v| v == "1") {
        write_page(&comparisons, &expected);
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
    // The programs both read agree to the tolerance (the largest difference
    // over them, and how many positions that is).
    let agreeing: Vec<&Comparison> = comparisons.iter().filter(|c| c.outcome == Agree).collect();
    assert!(agreeing.len() >= 20, "{} programs agree", agreeing.len());
    the_cycle800_difference_is_the_swivelled_plane(&reference[&files[plane]]);
}

/// plane-3plus2.mpf's difference is the one its entry gives: the
/// reference's positions are the plane's coordinates `p`, volcomp's tool tip
/// in the workpiece frame (`check --frame part --targets`) is `Rx(30°)·p`,
/// move for move.
fn the_cycle800_difference_is_the_swivelled_plane(reference: &Reading) {
    let reference = moving(
        reference
            .as_ref()
            .expect("the reference reads plane-3plus2.mpf"),
    );
    let out = crate::support::volcomp()
        .args([
            "check",
            "tests/data/sinumerik/plane-3plus2.mpf",
            "--machine",
            "machines/ref-trt.toml",
            "--frame",
            "part",
            "--targets",
            "-",
        ])
        .current_dir(root())
        .output()
        .unwrap();
    crate::support::assert_success(&out);
    let tips: Vec<(usize, [f64; 3])> = String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let n = |k: usize| f[k].parse::<f64>().unwrap();
            (f[0].parse().unwrap(), [n(2), n(3), n(4)])
        })
        .collect();
    assert_eq!(tips.len(), reference.len());
    let (s, c) = 30f64.to_radians().sin_cos();
    for ((line, p), (tip_line, tip)) in reference.iter().zip(&tips) {
        let rotated = [p[0], c * p[1] - s * p[2], s * p[1] + c * p[2]];
        assert_eq!(line, tip_line);
        assert!(
            (0..3).all(|k| (rotated[k] - tip[k]).abs() < TOLERANCE),
            "line {line}: Rx(30°)·{p:?} = {rotated:?}, volcomp's tip {tip:?}"
        );
    }
}

/// A program's entry in [`EXPECTED`]: volcomp's arguments, how both read
/// it, its outcome, why.
type Expectation = (&'static [&'static str], Text, Outcome, &'static str);

/// docs/sinumerik-differential.md from this run.
fn write_page(comparisons: &[Comparison], expected: &BTreeMap<&str, Expectation>) {
    let count = |o: Outcome| comparisons.iter().filter(|c| c.outcome == o).count();
    let both: Vec<&Comparison> = comparisons
        .iter()
        .filter(|c| matches!(c.outcome, Agree | Differ))
        .collect();
    let agreeing = comparisons.iter().filter(|c| c.outcome == Agree);
    let moves: usize = agreeing.clone().map(|c| c.moves).sum();
    let largest = agreeing
        .filter_map(|c| c.max_difference)
        .fold(0.0, f64::max);
    let mut page = format!(
        "# Differential test against CEAD's nc-gcode-interpreter\n\n\
         CEAD's `nc-gcode-interpreter` ({REFERENCE_VERSION}, PyPI; a SINUMERIK interpreter in Rust with a \
         Python API, MIT) is volcomp's reference for reading SINUMERIK programs (dialects.md \
         \"Differential reference\"). The test `tests/it/sinumerik_differential.rs` runs it in one \
         Python process (`tests/data/sinumerik/differential/cead_positions.py`, `nc_to_dataframe` with \
         the source line of each block) over volcomp's SINUMERIK fixtures (`tests/data/sinumerik/*.mpf`) \
         and the 32 example programs of CEAD's repository (`tests/data/sinumerik/real/cead/`), and runs \
         `volcomp check --targets` on the same text. It compares\n\n\
         1. read / refuse, and\n\
         2. where both read a program, every move: the blocks that program an axis, with X Y Z A B C \
         after the block (after frames; no work offset is given, so volcomp's machine coordinates are \
         the same numbers; under `TRAORI` the programmed tool tip), zero-length moves dropped on both \
         sides, on the same source line, within {TOLERANCE:e} mm/deg (volcomp's targets have six \
         decimals).\n\n\
         Two changes to the text, the same for both sides: a `%_N_…_MPF` header line, which the \
         reference refuses, is read as an empty comment; a fragment (CEAD's examples mostly have no \
         program end, several no feed before their first `G1`: the control refuses both, and so does \
         volcomp) is read with a first line `F1000` and a last line `M30` added (its lines are then \
         one more than in the file).\n\n\
         What the reference does not model: `TRAORI` (harmless for the comparison: the programmed \
         tool tip is what both give), `CYCLE800` (it passes the call over: its positions stay in the \
         plane's coordinates), subprogram calls, system variables known only at run time (it serves \
         `$AA_IW` from its own position), spindle and tool data. Where it is stricter than the control: \
         numbers like `.5` and `%_N_` headers. Every difference is an explicit entry, with its \
         reason, in the test's `EXPECTED`; the test fails on any other outcome (a new difference, \
         one that went away, or a new program without an entry).\n\n\
         Regenerate this page with\n\n\
         ```\nVOLCOMP_WRITE_SINUMERIK_TABLE=1 cargo test --release --locked sinumerik_differential\n```\n\n\
         **{} programs ({} fixtures, {} of CEAD's): both read {} ({} agree, {} differ); volcomp \
         refuses {} the reference reads, the reference refuses {} volcomp reads, both refuse {}. \
         Where both read and agree: {} moves, {} positions (X Y Z A B C), largest difference \
         {:.1e} mm/deg.**\n\n\
         | program | read as | reference | volcomp | moves | largest difference | outcome |\n\
         |---|---|---|---|---:|---:|---|\n",
        comparisons.len(),
        comparisons
            .iter()
            .filter(|c| !c.file.starts_with("real/"))
            .count(),
        comparisons
            .iter()
            .filter(|c| c.file.starts_with("real/"))
            .count(),
        both.len(),
        count(Agree),
        count(Differ),
        count(VolcompRefuses),
        count(ReferenceRefuses),
        count(BothRefuse),
        moves,
        6 * moves,
        largest,
    );
    for c in comparisons {
        let (_, text, _, why) = expected[c.file.as_str()];
        let side = |s: &str| s.replace('|', "\\|");
        page.push_str(&format!(
            "| `{}` | {} | {} | {} | {} | {} | {}{} |\n",
            c.file,
            match text {
                AsWritten => "as written",
                Fragment => "fragment",
            },
            side(&c.reference),
            side(&c.volcomp),
            if matches!(c.outcome, Agree | Differ) {
                c.moves.to_string()
            } else {
                "-".into()
            },
            c.max_difference.map_or("-".into(), |d| format!("{d:.1e}")),
            c.outcome.name(),
            if why.is_empty() {
                String::new()
            } else {
                format!(": {}", side(why))
            },
        ));
    }
    std::fs::write(root().join("docs/sinumerik-differential.md"), page).unwrap();
}
