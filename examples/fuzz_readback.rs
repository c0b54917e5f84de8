//! The compensated read-back of mutated programs (docs/fuzzing.md, issue 23):
//! every mutant that LinuxCNC's rs274 accepts is compensated by `volcomp
//! compensate` (the command line, stamp included) and the output must read
//! back, through `volcomp check` and through rs274.
//!
//!     cargo build --release && cargo run --release --example fuzz_readback [-- MUTANTS [SEED]]
//!
//! `VOLCOMP_BIN=PATH` runs another build of the command (an older one).
//!
//! Seeds: the programs of `tests/data/rs274`, `tests/data/gcode`,
//! `tests/data/compensate` and the two samples. Each mutant applies one to
//! three edits to a seed, drawn with ChaCha8 from `SEED` (default 23): a byte
//! changed, inserted or deleted, a line deleted, duplicated, swapped or
//! inserted (blank lines, `%`, a byte order mark, G-code fragments), at any
//! place, the head included. Both sides read with the same tool table
//! (`tests/data/rs274/sim.tbl`) and subroutine folder; the machine has only
//! position-independent errors (squareness and location), so no table range
//! refuses a mutant. A run that takes longer than 10 s (an endless loop) is
//! stopped and counted as neither. Failing programs are kept in
//! `target/fuzz-readback/` for inspection.
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Fragments inserted as lines.
const LINES: &[&str] = &[
    "",
    "   ",
    "%",
    "\u{feff}%",
    "(comment)",
    "; comment",
    "G91",
    "G20",
    "G90 G21",
    "G0 X1 Y2 Z3",
    "G1 X10 F100",
    "G2 X1 Y1 I1 J0",
    "M2",
    "M30",
    "O1234",
    "o100 sub",
    "o100 endsub",
    "N10 G1 X5",
    "#1 = 2",
    "T1 M6",
    "G43 H1",
    "G54",
    "/G1 X3",
];

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let count: usize = args.first().map_or(2000, |s| s.parse().expect("a count"));
    let seed: u64 = args.get(1).map_or(23, |s| s.parse().expect("a seed"));
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    // VOLCOMP_BIN=path runs another build (an older one, to see what it missed).
    let volcomp = std::env::var_os("VOLCOMP_BIN")
        .map(PathBuf::from)
        .unwrap_or_else(|| root.join("target/release/volcomp"));
    assert!(
        volcomp.exists(),
        "build the command first: cargo build --release"
    );
    let seeds = seed_programs(&root);
    let work = tempfile::tempdir().expect("a scratch folder");
    let dir = work.path();
    let keep = root.join("target/fuzz-readback");
    std::fs::create_dir_all(&keep).expect("target/fuzz-readback");
    // The machine: LinuxCNC's xyzac-trt with position-independent errors.
    let machine = dir.join("machine.toml");
    let text = std::fs::read_to_string(root.join("machines/xyzac-trt.toml")).unwrap();
    std::fs::write(
        &machine,
        text + "\n[squareness]\ns_xy = 20.0\ns_xz = -15.0\ns_yz = 10.0\n\n[location]\nEY0A = 5.0\nEX0C = -4.0\n",
    )
    .unwrap();
    let table = root.join("tests/data/rs274/sim.tbl");
    let subs = root.join("tests/data/rs274/subs");
    let ini = dir.join("rs274.ini");
    std::fs::write(
        &ini,
        format!("[RS274NGC]\nSUBROUTINE_PATH = {}\n", subs.display()),
    )
    .unwrap();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let started = Instant::now();
    let mut n = Counts::default();
    for k in 0..count {
        let (name, base) = &seeds[rng.random_range(0..seeds.len())];
        let mutant = mutate(base, &mut rng);
        let program = dir.join("mutant.ngc");
        std::fs::write(&program, &mutant).unwrap();
        n.mutants += 1;
        match rs274(&program, &ini, &table, dir) {
            Outcome::Accepted => n.linuxcnc_accepts += 1,
            Outcome::Rejected => continue,
            Outcome::TimedOut | Outcome::Crashed => {
                n.timed_out += 1;
                continue;
            }
        }
        let out = dir.join("compensated.ngc");
        let _ = std::fs::remove_file(&out);
        let compensate = run(Command::new(&volcomp)
            .arg("compensate")
            .arg(&machine)
            .arg(&program)
            .arg("-o")
            .arg(&out)
            .arg("--tools")
            .arg(&table)
            .arg("--subroutine-path")
            .arg(&subs)
            .arg("--no-limits"));
        match compensate {
            Outcome::Accepted => n.compensated += 1,
            Outcome::Rejected | Outcome::Crashed => {
                n.volcomp_refuses += 1;
                continue;
            }
            Outcome::TimedOut => {
                n.timed_out += 1;
                continue;
            }
        }
        let check = run(Command::new(&volcomp)
            .arg("check")
            .arg(&out)
            .arg("--tools")
            .arg(&table)
            .arg("--subroutine-path")
            .arg(&subs));
        let linuxcnc = rs274(&out, &ini, &table, dir);
        let volcomp_ok = matches!(check, Outcome::Accepted);
        let linuxcnc_ok = matches!(linuxcnc, Outcome::Accepted);
        if !volcomp_ok {
            n.volcomp_readback_failures += 1;
        }
        if !linuxcnc_ok {
            n.linuxcnc_readback_failures += 1;
        }
        if !(volcomp_ok && linuxcnc_ok) {
            let stem = format!("{k:05}-{}", name.replace(['/', '.'], "_"));
            std::fs::copy(&program, keep.join(format!("{stem}.ngc"))).unwrap();
            std::fs::copy(&out, keep.join(format!("{stem}-compensated.ngc"))).unwrap();
        }
        if (k + 1) % 250 == 0 {
            eprintln!(
                "{} mutants, {:.0} s: {n:?}",
                k + 1,
                started.elapsed().as_secs_f64()
            );
        }
    }
    println!(
        "{} mutants (seed {seed}) of {} programs in {:.0} s",
        n.mutants,
        seeds.len(),
        started.elapsed().as_secs_f64()
    );
    println!("LinuxCNC (rs274) accepts {}", n.linuxcnc_accepts);
    println!(
        "of those, volcomp compensates {} and refuses {} ({} runs stopped after 10 s or crashed, in all)",
        n.compensated, n.volcomp_refuses, n.timed_out
    );
    println!(
        "compensated outputs that do not read back: {} through volcomp check, {} through rs274",
        n.volcomp_readback_failures, n.linuxcnc_readback_failures
    );
    if n.volcomp_readback_failures + n.linuxcnc_readback_failures > 0 {
        println!("kept in {}", keep.display());
        std::process::exit(1);
    }
}

#[derive(Debug, Default)]
struct Counts {
    mutants: usize,
    linuxcnc_accepts: usize,
    compensated: usize,
    volcomp_refuses: usize,
    timed_out: usize,
    volcomp_readback_failures: usize,
    linuxcnc_readback_failures: usize,
}

/// The seed programs, by name.
fn seed_programs(root: &Path) -> Vec<(String, Vec<u8>)> {
    let mut seeds = Vec::new();
    for folder in [
        "tests/data/rs274",
        "tests/data/gcode",
        "tests/data/compensate",
    ] {
        let mut paths: Vec<PathBuf> = std::fs::read_dir(root.join(folder))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| p.extension().is_some_and(|e| e == "ngc" || e == "nc"))
            .collect();
        paths.sort();
        for p in paths {
            let name = format!("{folder}/{}", p.file_name().unwrap().to_string_lossy());
            seeds.push((name, std::fs::read(&p).unwrap()));
        }
    }
    for sample in ["samples/saddle.nc", "samples/flank.nc"] {
        seeds.push((
            sample.to_string(),
            std::fs::read(root.join(sample)).unwrap(),
        ));
    }
    seeds
}

/// One to three edits of `base`.
fn mutate(base: &[u8], rng: &mut ChaCha8Rng) -> Vec<u8> {
    let mut bytes = base.to_vec();
    for _ in 0..rng.random_range(1..=3) {
        let mut lines: Vec<Vec<u8>> = bytes.split(|&b| b == b'\n').map(<[u8]>::to_vec).collect();
        // Edits near the head are the interesting ones for the stamp: half of
        // the line edits fall in the first five lines.
        let line = if rng.random_bool(0.5) {
            rng.random_range(0..lines.len().min(5))
        } else {
            rng.random_range(0..lines.len())
        };
        match rng.random_range(0..8) {
            0 if !bytes.is_empty() => {
                let at = rng.random_range(0..bytes.len());
                bytes[at] = rng.random();
                continue;
            }
            1 => {
                let at = rng.random_range(0..=bytes.len());
                let b = *b" \t\r\n%();#[]0123456789.-+GXYZACFNMOT"
                    .get(rng.random_range(0..36))
                    .unwrap_or(&b' ');
                bytes.insert(at, b);
                continue;
            }
            2 if !bytes.is_empty() => {
                let at = rng.random_range(0..bytes.len());
                let len = rng.random_range(1..=8).min(bytes.len() - at);
                bytes.drain(at..at + len);
                continue;
            }
            3 if lines.len() > 1 => {
                lines.remove(line);
            }
            4 => {
                let copy = lines[line].clone();
                lines.insert(line, copy);
            }
            5 => {
                let other = rng.random_range(0..lines.len());
                lines.swap(line, other);
            }
            _ => {
                let text = LINES[rng.random_range(0..LINES.len())];
                lines.insert(line, text.as_bytes().to_vec());
            }
        }
        bytes = lines.join(&b'\n');
    }
    bytes
}

enum Outcome {
    Accepted,
    Rejected,
    TimedOut,
    /// Killed by a signal (rs274 has crashed when another copy ran at once).
    Crashed,
}

/// Run to its end (10 s at most): exit 0 is accepted.
fn run(cmd: &mut Command) -> Outcome {
    let mut child = cmd
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .expect("the command runs");
    let started = Instant::now();
    loop {
        if let Some(status) = child.try_wait().expect("waits") {
            return match status.code() {
                Some(0) => Outcome::Accepted,
                Some(_) => Outcome::Rejected,
                None => Outcome::Crashed,
            };
        }
        if started.elapsed() > Duration::from_secs(10) {
            let _ = child.kill();
            let _ = child.wait();
            return Outcome::TimedOut;
        }
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// LinuxCNC's verdict on `program` (a fresh copy of the tool table: rs274
/// may write it).
/// A crashed run is tried again, twice at most.
fn rs274(program: &Path, ini: &Path, table: &Path, dir: &Path) -> Outcome {
    let fresh = dir.join("sim.tbl");
    let var = dir.join("rs274.var");
    for _ in 0..3 {
        std::fs::copy(table, &fresh).unwrap();
        std::fs::write(&var, "").unwrap();
        let outcome = run(Command::new("rs274")
            .current_dir(dir)
            .arg("-i")
            .arg(ini)
            .arg("-v")
            .arg(&var)
            .arg("-t")
            .arg(&fresh)
            .arg("-g")
            .arg(program)
            .arg(dir.join("canon.txt")));
        if !matches!(outcome, Outcome::Crashed) {
            return outcome;
        }
    }
    Outcome::Crashed
}
