//! Differential test against LinuxCNC's standalone interpreter `rs274` (2.9).
//!
//! Every program of the corpus — our fixtures `tests/data/rs274/*.ngc` and the
//! example programs of the `linuxcnc-uspace` package — is run through
//! `rs274 -g` and through `volcomp check --targets`, and the two are compared:
//!
//! 1. accept/reject: rs274 rejects with exit status 1 and the message on
//!    stderr; volcomp with a nonzero exit status;
//! 2. when both accept, every motion end point in MACHINE coordinates (mm,
//!    degrees), after removing consecutive duplicate points on both sides,
//!    within [`TOLERANCE`] plus the rounding of the numbers rs274 printed
//!    (4 decimals in the units then current: up to 0.00005 in = 1.27 µm per
//!    number in G20 programs; see [`parse_canon`]). A spline is one motion
//!    on each side whose end is not compared: rs274 prints `NURBS_FEED(n,
//!    ...)` without it; the moves after it show where it ended.
//!
//! rs274 prints canonical calls with positions in the work frame, in the
//! units current at the time; this module turns them into machine
//! coordinates: machine = rot(canon + G92) + G5x, from its `SET_G5X_OFFSET`,
//! `SET_G92_OFFSET`, `SET_XY_ROTATION`, `USE_LENGTH_UNITS` and `SELECT_PLANE`
//! calls. Tool length offsets are not applied on either side (volcomp's
//! targets are tool-tip positions).
//!
//! Standalone rs274's machine units are inches: the `.var` file it gets is
//! the mm fixture with its linear values divided by 25.4. It rewrites its
//! `.var` file on exit and crashes when two copies share files, so every run
//! gets its own temporary folder and runs are serialised.
//!
//! `tests/data/rs274/expected.toml` says, per file, what to expect (`agree`,
//! a documented `differ`, or `skip`); the test fails when a file comes out
//! otherwise. `VOLCOMP_WRITE_RS274_TABLE=1` writes the table to
//! `docs/rs274-differential.md`.
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::Mutex;

use crate::support;

/// Largest allowed difference of a coordinate, mm or degrees.
const TOLERANCE: f64 = 1e-3;

/// Where the package keeps its example programs (the second is a link to the
/// first on Debian; both are read, files are deduplicated by content).
const PACKAGE_ROOTS: [&str; 2] = [
    "/usr/share/linuxcnc/ncfiles",
    "/usr/share/doc/linuxcnc/examples/nc_files",
];

/// rs274 crashes (SIGBUS) when two copies run at once: one at a time.
pub(crate) static RS274: Mutex<()> = Mutex::new(());

/// A point: X Y Z (mm) A B C (degrees), machine coordinates.
pub type Point = [f64; 6];

fn data_dir() -> PathBuf {
    support::root().join("tests/data/rs274")
}

/// One program of the corpus.
struct Case {
    /// Stable name: the fixture's file name, `ncfiles/<path>` for the package's.
    name: String,
    path: PathBuf,
    /// Folders searched for `NAME.ngc` subroutine files, in order.
    subroutine_path: Vec<PathBuf>,
}

/// What one interpreter made of a program.
#[derive(Debug, Default)]
struct Side {
    accepted: bool,
    /// The first line of the error message when rejected.
    message: String,
    /// Motion end points, consecutive duplicates removed.
    points: Vec<Point>,
    /// Per point, how far rs274's rounding of the numbers it printed may
    /// move it (mm/deg); empty for volcomp.
    slack: Vec<f64>,
    /// Per point: a spline (rs274's `NURBS_FEED`, whose end it does not
    /// print: its point is NaN; volcomp's straight pieces of one spline
    /// block, the last piece's end).
    splines: Vec<bool>,
    /// Why the points cannot be compared (rs274 printed a move without its end).
    incomplete: Option<String>,
}

/// What a file is expected to do.
#[derive(Debug, Clone, PartialEq)]
enum Expect {
    Agree,
    Differ {
        reason: String,
        rs274: bool,
        volcomp: bool,
    },
    Skip(String),
}

/// The result of comparing both sides.
#[derive(Debug)]
struct Comparison {
    rs274: Side,
    volcomp: Side,
    /// Motions compared (both accepted: the common length).
    compared: usize,
    /// Largest coordinate difference over the compared motions.
    max_deviation: f64,
    /// First disagreement, in words (None: they agree).
    difference: Option<String>,
}

// ---------------------------------------------------------------- corpus

fn fixture_cases() -> Vec<Case> {
    let dir = data_dir();
    let mut cases: Vec<Case> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("readable folder").path())
        .filter(|p| p.extension().is_some_and(|e| e == "ngc"))
        .map(|path| Case {
            name: path.file_name().unwrap().to_string_lossy().into_owned(),
            path,
            subroutine_path: vec![dir.join("subs")],
        })
        .collect();
    cases.sort_by(|a, b| a.name.cmp(&b.name));
    cases
}

fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let p = e.path();
        if p.is_dir() {
            walk(&p, out);
        } else if p.extension().is_some_and(|e| e == "ngc") {
            out.push(p);
        }
    }
}

/// The package's example programs, one per distinct content.
fn package_cases() -> Vec<Case> {
    let mut seen: BTreeMap<Vec<u8>, ()> = BTreeMap::new();
    let mut cases = Vec::new();
    for root in PACKAGE_ROOTS {
        let root = Path::new(root);
        let mut files = Vec::new();
        walk(root, &mut files);
        files.sort();
        for path in files {
            let bytes = std::fs::read(&path).unwrap_or_default();
            if seen.insert(bytes, ()).is_some() {
                continue;
            }
            let rel = path.strip_prefix(root).unwrap().to_string_lossy();
            let dir = path.parent().unwrap().to_path_buf();
            let mut subroutine_path = vec![dir.clone()];
            if dir != root {
                subroutine_path.push(root.to_path_buf());
            }
            cases.push(Case {
                name: format!("ncfiles/{rel}"),
                path,
                subroutine_path,
            });
        }
    }
    cases.sort_by(|a, b| a.name.cmp(&b.name));
    cases
}

// ---------------------------------------------------------- expectations

fn read_expectations() -> BTreeMap<String, Expect> {
    let path = data_dir().join("expected.toml");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let table: toml::Table = text
        .parse()
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let files = table
        .get("files")
        .and_then(|f| f.as_table())
        .unwrap_or_else(|| panic!("{}: no [files] table", path.display()));
    let side = |t: &toml::Table, key: &str, name: &str| -> bool {
        match t.get(key).and_then(|v| v.as_str()) {
            Some("accept") => true,
            Some("reject") => false,
            _ => panic!(
                "{}: {name}: a differ entry needs {key} = \"accept\" or \"reject\"",
                path.display()
            ),
        }
    };
    files
        .iter()
        .map(|(name, v)| {
            let e = match v {
                toml::Value::String(s) if s == "agree" => Expect::Agree,
                toml::Value::Table(t) => {
                    if let Some(r) = t.get("skip").and_then(|r| r.as_str()) {
                        Expect::Skip(r.to_string())
                    } else if let Some(r) = t.get("differ").and_then(|r| r.as_str()) {
                        Expect::Differ {
                            reason: r.to_string(),
                            rs274: side(t, "rs274", name),
                            volcomp: side(t, "volcomp", name),
                        }
                    } else {
                        panic!("{}: {name}: expected skip or differ", path.display())
                    }
                }
                _ => panic!(
                    "{}: {name}: expected \"agree\", {{ differ = … }} or {{ skip = … }}",
                    path.display()
                ),
            };
            (name.clone(), e)
        })
        .collect()
}

// ------------------------------------------------------------------ setup

/// The mm `.var` fixture as rs274 (machine units: inches) must read it:
/// linear values of the stored positions, G92 and work origins / 25.4.
fn var_in_inches(text: &str) -> String {
    let mut out = String::new();
    for line in text.lines() {
        let mut it = line.split_whitespace();
        let (Some(n), Some(v)) = (it.next(), it.next()) else {
            continue;
        };
        let n: usize = n.parse().expect("parameter number");
        let v: f64 = v.parse().expect("parameter value");
        let linear = matches!(n, 5161..=5163 | 5181..=5183 | 5211..=5213)
            || ((5221..=5403).contains(&n) && (n - 5221) % 20 < 3);
        let v = if linear { v / 25.4 } else { v };
        writeln!(out, "{n}\t{v:.12}").unwrap();
    }
    out
}

fn check_rs274() {
    let out = {
        let _one_at_a_time = RS274.lock().unwrap_or_else(|e| e.into_inner());
        Command::new("rs274").arg("-h").output()
    };
    match out {
        Ok(o) if String::from_utf8_lossy(&o.stderr).contains("Usage: rs274") => {}
        Ok(o) => panic!(
            "`rs274` ran ({}) but is not LinuxCNC's standalone interpreter: {}",
            o.status,
            String::from_utf8_lossy(&o.stderr)
        ),
        Err(e) => panic!(
            "cannot run `rs274` (LinuxCNC 2.9's standalone interpreter, Debian package \
             linuxcnc-uspace; .ci/run installs it): {e}"
        ),
    }
}

// ----------------------------------------------------------------- rs274

/// The rounding bound of a number rs274 printed (4 decimals) in mm.
fn print_rounding(inch: bool) -> f64 {
    if inch { 0.00005 * 25.4 } else { 0.00005 }
}

/// An offset rs274 printed: X Y Z in the current units, A B C in degrees.
/// When it is printed in inches and agrees with the value known before (in
/// mm) to the printed digits, the known value is kept (rs274 prints the same
/// offset again after every coordinate system change): no rounding is added.
struct Offset {
    value: [f64; 6],
    /// Rounding bound of `value`, mm.
    rounding: f64,
}

impl Offset {
    fn update(&mut self, printed: &[f64], inch: bool) {
        // Linear axes (the first three) in the current units, rotary in degrees.
        let unit = |k: usize| if k < 3 && inch { 25.4 } else { 1.0 };
        let same = self
            .value
            .iter()
            .zip(printed)
            .enumerate()
            .all(|(k, (known, p))| (known / unit(k) - p).abs() <= 0.5e-4 + 1e-9);
        if same {
            return;
        }
        for (k, (v, p)) in self.value.iter_mut().zip(printed).enumerate() {
            *v = p * unit(k);
        }
        self.rounding = print_rounding(inch);
    }
}

/// rs274's canonical calls → motion end points in machine coordinates, the
/// rounding bound of each, and which are splines (`NURBS_FEED`: rs274 prints
/// the number of control points only, so the point is NaN; the moves after
/// it, printed absolute, show where it ended).
fn parse_canon(text: &str) -> Result<(Vec<Point>, Vec<f64>, Vec<bool>), String> {
    let mut inch = false;
    let mut plane = 0; // 0 XY, 1 YZ, 2 XZ
    let mut g5x = Offset {
        value: [0.0; 6],
        rounding: 0.0,
    };
    let mut g92 = Offset {
        value: [0.0; 6],
        rounding: 0.0,
    };
    let mut rotation = 0.0f64;
    let mut program = [0.0f64; 6]; // last canon position (program units)
    let mut points = Vec::new();
    let mut slack = Vec::new();
    let mut splines = Vec::new();
    let mut push = |p: &[f64; 6], inch: bool, g5x: &Offset, g92: &Offset, rot: f64| {
        let mut m = *p;
        if inch {
            for v in m.iter_mut().take(3) {
                *v *= 25.4;
            }
        }
        for (v, o) in m.iter_mut().zip(&g92.value) {
            *v += o;
        }
        let (s, c) = rot.to_radians().sin_cos();
        let (x, y) = (m[0], m[1]);
        m[0] = c * x - s * y;
        m[1] = s * x + c * y;
        for (v, o) in m.iter_mut().zip(&g5x.value) {
            *v += o;
        }
        let mix = if rot == 0.0 { 1.0 } else { s.abs() + c.abs() };
        points.push(m);
        slack.push(mix * (print_rounding(inch) + g92.rounding) + g5x.rounding);
        splines.push(m.iter().any(|v| v.is_nan()));
    };
    for line in text.lines() {
        // "   16 N..... NAME(args)"
        let mut rest = line
            .trim_start()
            .trim_start_matches(|c: char| c.is_ascii_digit())
            .trim_start();
        if rest.starts_with('N') {
            rest = rest.split_once(' ').map_or("", |(_, r)| r);
        }
        let Some((name, args)) = rest.split_once('(') else {
            continue;
        };
        let args = args.rsplit_once(')').map_or(args, |(a, _)| a);
        let numbers = || -> Result<Vec<f64>, String> {
            args.split(',')
                .map(|a| {
                    a.trim()
                        .parse::<f64>()
                        .map_err(|e| format!("`{line}`: {e}"))
                })
                .collect()
        };
        match name.trim() {
            "USE_LENGTH_UNITS" => inch = args.contains("INCHES"),
            "SELECT_PLANE" => {
                plane = if args.contains("XY") {
                    0
                } else if args.contains("YZ") {
                    1
                } else {
                    2
                };
            }
            "SET_G5X_OFFSET" => g5x.update(&numbers()?[1..7], inch),
            "SET_G92_OFFSET" => g92.update(&numbers()?[0..6], inch),
            "SET_XY_ROTATION" => rotation = numbers()?[0],
            "STRAIGHT_TRAVERSE" | "STRAIGHT_FEED" | "STRAIGHT_PROBE" => {
                let v = numbers()?;
                program.copy_from_slice(&v[0..6]);
                push(&program, inch, &g5x, &g92, rotation);
            }
            "ARC_FEED" => {
                let v = numbers()?;
                let (first, second, axis) = (v[0], v[1], v[5]);
                let xyz = match plane {
                    0 => [first, second, axis],
                    1 => [axis, first, second],
                    _ => [second, axis, first],
                };
                program = [xyz[0], xyz[1], xyz[2], v[6], v[7], v[8]];
                push(&program, inch, &g5x, &g92, rotation);
            }
            "RIGID_TAP" => {
                // To the bottom and back to the start.
                let v = numbers()?;
                let start = program;
                program[..3].copy_from_slice(&v[0..3]);
                push(&program, inch, &g5x, &g92, rotation);
                program = start;
                push(&program, inch, &g5x, &g92, rotation);
            }
            "NURBS_FEED" => {
                // "NURBS_FEED(4, ...)": the control points' count only.
                push(&[f64::NAN; 6], inch, &g5x, &g92, rotation);
            }
            _ => {}
        }
    }
    Ok((points, slack, splines))
}

fn run_rs274(case: &Case, var_mm: &str, dir: &Path) -> Side {
    let var = dir.join("rs274.var");
    let table = dir.join("sim.tbl");
    let ini = dir.join("rs274.ini");
    let path: Vec<String> = case
        .subroutine_path
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    std::fs::write(
        &ini,
        format!("[RS274NGC]\nSUBROUTINE_PATH = {}\n", path.join(":")),
    )
    .unwrap();
    let out_file = dir.join("canon.txt");
    // rs274 rewrites its .var (and may write its tool table) on exit: fresh
    // copies for every run. A run killed by a signal (rs274 has crashed when
    // another copy ran at the same time) is tried again, twice at most.
    let mut attempts = 0;
    let out = loop {
        std::fs::write(&var, var_in_inches(var_mm)).unwrap();
        std::fs::copy(data_dir().join("sim.tbl"), &table).unwrap();
        let _one_at_a_time = RS274.lock().unwrap_or_else(|e| e.into_inner());
        let out = Command::new("rs274")
            .current_dir(dir)
            .arg("-i")
            .arg(&ini)
            .arg("-v")
            .arg(&var)
            .arg("-t")
            .arg(&table)
            .arg("-g")
            .arg(&case.path)
            .arg(&out_file)
            .output()
            .unwrap_or_else(|e| panic!("cannot run rs274: {e}"));
        attempts += 1;
        if out.status.code().is_some() || attempts == 3 {
            break out;
        }
    };
    let stderr = String::from_utf8_lossy(&out.stderr);
    let message = stderr
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty() && *l != "executing")
        .unwrap_or("")
        .to_string();
    let text = std::fs::read_to_string(&out_file).unwrap_or_default();
    match out.status.code() {
        Some(0) => {}
        Some(1) => {
            return Side {
                accepted: false,
                message,
                ..Side::default()
            };
        }
        _ => panic!(
            "{}: rs274 did not run to its end ({}): {stderr}",
            case.name, out.status
        ),
    }
    match parse_canon(&text) {
        Ok((points, slack, splines)) => {
            let (points, slack, splines) = dedup(points, slack, splines);
            Side {
                accepted: true,
                message,
                points,
                slack,
                splines,
                incomplete: None,
            }
        }
        Err(e) => Side {
            accepted: true,
            message,
            incomplete: Some(e),
            ..Side::default()
        },
    }
}

/// What rs274 makes of the program at `path`, in the corpus's setup
/// (`setup.var`, `sim.tbl`, `subs/` on the subroutine path): its motion end
/// points in machine coordinates (zero-length moves dropped), or its error.
/// For tests that read a written program back.
pub fn rs274_motions(path: &Path) -> Result<Vec<Point>, String> {
    check_rs274();
    let case = Case {
        name: path.display().to_string(),
        path: path.to_path_buf(),
        subroutine_path: vec![data_dir().join("subs")],
    };
    let var_mm = std::fs::read_to_string(data_dir().join("setup.var")).unwrap();
    let dir = tempfile::tempdir().expect("temporary folder");
    let side = run_rs274(&case, &var_mm, dir.path());
    match (side.accepted, side.incomplete) {
        (false, _) => Err(side.message),
        (true, Some(why)) => Err(why),
        (true, None) => Ok(side.points),
    }
}

// --------------------------------------------------------------- volcomp

fn run_volcomp(case: &Case, var_mm: &Path, dir: &Path) -> Side {
    let targets = dir.join("targets.csv");
    let mut cmd = support::volcomp();
    cmd.arg("check")
        .arg(&case.path)
        .arg("--targets")
        .arg(&targets)
        .arg("--var")
        .arg(var_mm);
    for p in &case.subroutine_path {
        cmd.arg("--subroutine-path").arg(p);
    }
    let out = cmd.output().expect("volcomp runs");
    if !out.status.success() {
        let stderr = String::from_utf8_lossy(&out.stderr);
        // "error: no targets were written to DIR/targets.csv: MESSAGE"
        // " --> FILE:LINE:COLUMN"
        let first = stderr.lines().map(str::trim).find(|l| !l.is_empty());
        let first = first.unwrap_or("").trim_start_matches("error: ");
        let mut message = first
            .split_once("targets.csv: ")
            .map_or(first, |(_, m)| m)
            .to_string();
        if let Some(at) = stderr.lines().find_map(|l| l.trim().strip_prefix("--> ")) {
            let mut parts = at.rsplitn(3, ':');
            let (_, line, file) = (parts.next(), parts.next(), parts.next());
            if let (Some(line), Some(file)) = (line, file) {
                let file = Path::new(file).file_name().map(|f| f.to_string_lossy());
                let file = file.unwrap_or_default();
                write!(message, " ({file}:{line})").unwrap();
            }
        }
        return Side {
            accepted: false,
            message,
            ..Side::default()
        };
    }
    let text = std::fs::read_to_string(&targets).expect("targets written");
    let mut points = Vec::new();
    let mut splines: Vec<bool> = Vec::new();
    // The line of the spline whose pieces are being read.
    let mut spline_line: Option<&str> = None;
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let num = |i: usize| -> f64 {
            if f[i].is_empty() {
                0.0
            } else {
                f[i].parse().unwrap_or_else(|e| panic!("`{line}`: {e}"))
            }
        };
        let p = [num(2), num(3), num(4), num(5), num(6), num(7)];
        if f[1].starts_with("G5") {
            // A spline's straight pieces: one entry, at the last one's end.
            if spline_line == Some(f[0]) {
                *points.last_mut().expect("a piece before") = p;
                continue;
            }
            spline_line = Some(f[0]);
            points.push(p);
            splines.push(true);
            continue;
        }
        spline_line = None;
        points.push(p);
        splines.push(false);
    }
    let slack = vec![0.0; points.len()];
    let (points, _, splines) = dedup(points, slack, splines);
    Side {
        accepted: true,
        points,
        splines,
        ..Side::default()
    }
}

/// Drop points within half the tolerance of the previous one (zero-length
/// moves; both start at the machine origin), with their slack. A spline is
/// kept, and so is the point after it (rs274 does not say where it ended).
fn dedup(
    points: Vec<Point>,
    slack: Vec<f64>,
    splines: Vec<bool>,
) -> (Vec<Point>, Vec<f64>, Vec<bool>) {
    let mut out: Vec<Point> = Vec::with_capacity(points.len());
    let mut out_slack = Vec::with_capacity(points.len());
    let mut out_splines: Vec<bool> = Vec::with_capacity(points.len());
    for ((p, s), spline) in points.into_iter().zip(slack).zip(splines) {
        let last = out.last().copied().unwrap_or([0.0; 6]);
        let after_spline = out_splines.last() == Some(&true);
        if !spline && !after_spline && deviation(&last, &p) < TOLERANCE / 2.0 {
            continue;
        }
        out.push(p);
        out_slack.push(s);
        out_splines.push(spline);
    }
    (out, out_slack, out_splines)
}

fn deviation(a: &Point, b: &Point) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

fn fmt_point(p: &Point) -> String {
    format!(
        "X{:.4} Y{:.4} Z{:.4} A{:.4} B{:.4} C{:.4}",
        p[0], p[1], p[2], p[3], p[4], p[5]
    )
}

fn compare(case: &Case, var_mm_text: &str, var_mm: &Path) -> Comparison {
    let dir = tempfile::tempdir().expect("temporary folder");
    let rs274 = run_rs274(case, var_mm_text, dir.path());
    let volcomp = run_volcomp(case, var_mm, dir.path());
    let mut compared = 0;
    let mut max_deviation: f64 = 0.0;
    let difference = match (rs274.accepted, volcomp.accepted) {
        (false, false) => None,
        (true, false) => Some(format!("volcomp rejects: {}", volcomp.message)),
        (false, true) => Some(format!("rs274 rejects: {}", rs274.message)),
        (true, true) if rs274.incomplete.is_some() => Some(format!(
            "positions cannot be compared: {}",
            rs274.incomplete.as_deref().unwrap_or_default()
        )),
        (true, true) => {
            let (a, b) = (&rs274.points, &volcomp.points);
            compared = a.len().min(b.len());
            let mut first = None;
            let mut spline_mismatch = None;
            for i in 0..compared {
                let (sa, sb) = (rs274.splines[i], volcomp.splines[i]);
                if sa || sb {
                    // A spline: rs274 prints no end (the next moves show it).
                    if sa != sb && spline_mismatch.is_none() && first.is_none() {
                        spline_mismatch = Some(i);
                    }
                    continue;
                }
                let d = deviation(&a[i], &b[i]);
                max_deviation = max_deviation.max(d);
                if d > TOLERANCE + rs274.slack[i] && first.is_none() && spline_mismatch.is_none() {
                    first = Some(i);
                }
            }
            if let Some(i) = spline_mismatch {
                let (who, other) = if rs274.splines[i] {
                    ("rs274", "volcomp")
                } else {
                    ("volcomp", "rs274")
                };
                return Comparison {
                    difference: Some(format!(
                        "motion {} of {}/{}: {who} runs a spline where {other} moves straight",
                        i + 1,
                        a.len(),
                        b.len()
                    )),
                    rs274,
                    volcomp,
                    compared,
                    max_deviation,
                };
            }
            match first {
                Some(i) => Some(format!(
                    "motion {} of {}/{} differs by {:.4}: rs274 {} | volcomp {}",
                    i + 1,
                    a.len(),
                    b.len(),
                    deviation(&a[i], &b[i]),
                    fmt_point(&a[i]),
                    fmt_point(&b[i])
                )),
                None if a.len() != b.len() => {
                    let (who, p) = if a.len() > b.len() {
                        ("rs274", &a[compared])
                    } else {
                        ("volcomp", &b[compared])
                    };
                    Some(format!(
                        "rs274 has {} motions, volcomp {}; the first extra ({who}, motion {}): {}",
                        a.len(),
                        b.len(),
                        compared + 1,
                        fmt_point(p)
                    ))
                }
                None => None,
            }
        }
    };
    Comparison {
        rs274,
        volcomp,
        compared,
        max_deviation,
        difference,
    }
}

// ------------------------------------------------------------------ test

/// One row of the table.
struct Row {
    name: String,
    rs274: String,
    volcomp: String,
    compared: String,
    deviation: String,
    verdict: String,
}

fn yes_no(side: &Side) -> String {
    if side.accepted { "accept" } else { "reject" }.into()
}

#[test]
fn rs274_and_volcomp_read_programs_alike() {
    check_rs274();
    let started = std::time::Instant::now();
    let expectations = read_expectations();
    let var_mm = data_dir().join("setup.var");
    let var_mm_text = std::fs::read_to_string(&var_mm).unwrap();
    let fixtures = fixture_cases();
    let package = package_cases();
    assert!(
        package.len() >= 150,
        "only {} example programs of linuxcnc-uspace found under {:?}",
        package.len(),
        PACKAGE_ROOTS
    );
    let only = std::env::var("VOLCOMP_RS274_ONLY").ok();
    let mut rows = Vec::new();
    let mut failures = Vec::new();
    let (mut files, mut skipped, mut accept_agree, mut both_accepted, mut position_agree) =
        (0, 0, 0, 0, 0);
    let mut max_agreeing_deviation: f64 = 0.0;
    let mut total_motions = 0;
    let (mut moving, mut documented) = (0, 0);
    let names: std::collections::BTreeSet<&str> = fixtures
        .iter()
        .chain(&package)
        .map(|c| c.name.as_str())
        .collect();
    for name in expectations.keys() {
        if !names.contains(name.as_str()) {
            failures.push(format!(
                "{name}: listed in expected.toml but not in the corpus"
            ));
        }
    }
    for case in fixtures.iter().chain(&package) {
        if only.as_deref().is_some_and(|o| !case.name.contains(o)) {
            continue;
        }
        let expect = expectations.get(&case.name).cloned();
        if let Some(Expect::Skip(reason)) = &expect {
            skipped += 1;
            rows.push(Row {
                name: case.name.clone(),
                rs274: "-".into(),
                volcomp: "-".into(),
                compared: "-".into(),
                deviation: "-".into(),
                verdict: format!("skip: {reason}"),
            });
            continue;
        }
        files += 1;
        let c = compare(case, &var_mm_text, &var_mm);
        if c.rs274.accepted == c.volcomp.accepted {
            accept_agree += 1;
        }
        if c.rs274.accepted && c.volcomp.accepted {
            both_accepted += 1;
            if c.difference.is_none() {
                position_agree += 1;
            }
        }
        if c.difference.is_none() {
            max_agreeing_deviation = max_agreeing_deviation.max(c.max_deviation);
            total_motions += c.compared;
            if c.compared > 0 {
                moving += 1;
            }
        }
        let is_error_fixture = !case.name.starts_with("ncfiles/") && case.name.starts_with("err_");
        if is_error_fixture && (c.rs274.accepted || c.volcomp.accepted) {
            failures.push(format!(
                "{}: an error fixture must be rejected by both (rs274 {}, volcomp {})",
                case.name,
                yes_no(&c.rs274),
                yes_no(&c.volcomp)
            ));
        }
        let verdict = match (&expect, &c.difference) {
            (Some(Expect::Agree), None) => "agree".to_string(),
            (Some(Expect::Agree), Some(d)) => {
                failures.push(format!("{}: expected to agree, but {d}", case.name));
                format!("FAIL: {d}")
            }
            (Some(Expect::Differ { reason, .. }), None) => {
                failures.push(format!(
                    "{}: expected to differ ({reason}), but now agrees: make it `agree`",
                    case.name
                ));
                "FAIL: agrees now".to_string()
            }
            (
                Some(Expect::Differ {
                    reason,
                    rs274,
                    volcomp,
                }),
                Some(d),
            ) => {
                if (*rs274, *volcomp) != (c.rs274.accepted, c.volcomp.accepted) {
                    failures.push(format!(
                        "{}: expected to differ with rs274 {} and volcomp {}, but {d}",
                        case.name,
                        if *rs274 { "accepting" } else { "rejecting" },
                        if *volcomp { "accepting" } else { "rejecting" },
                    ));
                    format!("FAIL: {d}")
                } else {
                    documented += 1;
                    format!("differ: {reason}")
                }
            }
            (None, d) => {
                failures.push(format!(
                    "{}: not in expected.toml (outcome: {})",
                    case.name,
                    d.as_deref().unwrap_or("agree")
                ));
                format!("NEW: {}", d.as_deref().unwrap_or("agree"))
            }
            (Some(Expect::Skip(_)), _) => unreachable!(),
        };
        let message = |s: &Side| {
            if s.accepted {
                "accept".to_string()
            } else {
                format!("reject ({})", s.message.replace('|', "/"))
            }
        };
        rows.push(Row {
            name: case.name.clone(),
            rs274: message(&c.rs274),
            volcomp: message(&c.volcomp),
            compared: if c.rs274.accepted && c.volcomp.accepted {
                c.compared.to_string()
            } else {
                "-".into()
            },
            deviation: if c.rs274.accepted && c.volcomp.accepted && c.compared > 0 {
                format!("{:.1e}", c.max_deviation)
            } else {
                "-".into()
            },
            verdict,
        });
    }
    let elapsed = started.elapsed();
    let mut table = String::new();
    writeln!(
        table,
        "| file | rs274 | volcomp | motions compared | max deviation | verdict |"
    )
    .unwrap();
    writeln!(table, "|---|---|---|---:|---:|---|").unwrap();
    for r in &rows {
        writeln!(
            table,
            "| `{}` | {} | {} | {} | {} | {} |",
            r.name,
            r.rs274,
            r.volcomp,
            r.compared,
            r.deviation,
            r.verdict.replace('|', "/")
        )
        .unwrap();
    }
    let summary = format!(
        "{} files ({} fixtures, {} distinct package programs): {skipped} skipped, {files} \
         compared. Accept/reject agree on {accept_agree} of {files}. Positions agree \
         on {position_agree} of the {both_accepted} programs both accept ({moving} of them \
         with motions; {total_motions} motions, largest deviation \
         {max_agreeing_deviation:.1e} mm/deg). {documented} documented differences",
        fixtures.len() + package.len(),
        fixtures.len(),
        package.len(),
    );
    println!("{table}\n{summary}\n({:.1} s)", elapsed.as_secs_f64());
    if only.is_none() && std::env::var("VOLCOMP_WRITE_RS274_TABLE").is_ok_and(|v| v == "1") {
        // rs274's messages name files by absolute path: the page names them
        // from the checkout's root, wherever it is.
        let table = table.replace(&format!("{}/", support::root().display()), "");
        let doc = format!(
            "# Differential test against LinuxCNC's rs274\n\n\
             LinuxCNC's standalone interpreter `rs274` (2.9, Debian package `linuxcnc-uspace`) \
             is volcomp's reference for reading RS274NGC programs. The test \
             `tests/it/rs274.rs` runs `rs274 -g` and `volcomp check --targets` on the same \
             programs — the fixtures `tests/data/rs274/*.ngc` (one or more per construct, \
             and programs both must reject) and every example program of the package \
             (`/usr/share/linuxcnc/ncfiles`, deduplicated by content) — and compares\n\n\
             1. accept/reject, and\n\
             2. when both accept, every motion end point in machine coordinates (work \
             offsets, G92, XY rotation and units applied; tool length offsets not), \
             tolerance {TOLERANCE:e} mm/deg plus the rounding of the numbers rs274 prints \
             (4 decimals in the units then current: up to 0.00005 in = 1.27 µm per number \
             in G20 programs), after removing zero-length moves on both sides. A spline \
             (G5, G5.1, G5.2 … G5.3) is one motion on each side: rs274 prints \
             `NURBS_FEED(n, ...)`, the control points' count and not the curve's end, and \
             volcomp writes the curve's straight pieces (collapsed into one motion, \
             `G5`/`G5.1`/`G5.2` in its targets); the sides must agree that a spline runs \
             there, and the moves after it (the fixtures follow every curve with a G91 \
             move, which rs274 prints absolute) show that both end it at the same point.\n\n\
             Both get the same setup: `tests/data/rs274/setup.var` (work origins, G92, \
             G28/G30 positions; rs274 gets it in inches, its machine units), the tool \
             table `tests/data/rs274/sim.tbl`, and the subroutine path (`tests/data/rs274/subs`, \
             or the program's folder and the package's `ncfiles`). What each file is \
             expected to do (agree, a documented difference, or skip) is in \
             `tests/data/rs274/expected.toml`; the test fails on any other outcome.\n\n\
             Regenerate this page with\n\n\
             ```\nVOLCOMP_WRITE_RS274_TABLE=1 cargo test --release --locked rs274\n```\n\n\
             **{summary}.**\n\n{table}"
        );
        std::fs::write(support::root().join("docs/rs274-differential.md"), doc).unwrap();
    }
    assert!(
        failures.is_empty(),
        "{} of the files do not come out as expected.toml says:\n{}",
        failures.len(),
        failures.join("\n")
    );
}

/// Issue 23: polar words and splines are read as LinuxCNC reads them and
/// written flat by `compensate` (a polar block whose target moves says its X
/// Y; a spline becomes straight pieces, each end compensated). LinuxCNC reads
/// each compensated fixture to the positions volcomp reads (`check
/// --targets`), move for move.
#[test]
fn compensated_polar_and_spline_programs_read_back_alike() {
    check_rs274();
    let var_mm = data_dir().join("setup.var");
    let var_mm_text = std::fs::read_to_string(&var_mm).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let mut checked = 0;
    for case in fixture_cases() {
        let name = case.name.as_str();
        if name.starts_with("err_") || !(name.contains("polar") || name.contains("spline")) {
            continue;
        }
        let out = dir.path().join(name);
        let run = support::volcomp()
            .args(["compensate", "machines/ref-trt.toml"])
            .arg(&case.path)
            .arg("--var")
            .arg(&var_mm)
            .args(["--no-limits", "-o"])
            .arg(&out)
            .current_dir(support::root())
            .output()
            .unwrap();
        support::assert_success(&run);
        let text = std::fs::read_to_string(&out).unwrap();
        // The words, without the comments.
        let words: String = text
            .lines()
            .map(|l| {
                let mut depth = 0;
                l.chars()
                    .filter(|c| {
                        match c {
                            '(' => depth += 1,
                            ')' => depth -= 1,
                            _ => return depth == 0,
                        }
                        false
                    })
                    .collect::<String>()
                    + "\n"
            })
            .collect();
        assert!(
            !words.contains('@') && !words.contains('^'),
            "{name}: polar words left\n{text}"
        );
        assert!(
            !words
                .split_whitespace()
                .any(|t| t.eq_ignore_ascii_case("G5") || t.to_ascii_uppercase().starts_with("G5.")),
            "{name}: spline words left\n{text}"
        );
        let written = Case {
            name: format!("{name} compensated"),
            path: out,
            subroutine_path: case.subroutine_path.clone(),
        };
        let c = compare(&written, &var_mm_text, &var_mm);
        assert!(
            c.difference.is_none() && c.compared > 5,
            "{name}: {:?} ({} motions compared)",
            c.difference,
            c.compared
        );
        checked += 1;
    }
    assert_eq!(checked, 6);
}
