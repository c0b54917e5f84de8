//! G-code front end throughput, through the path every command takes
//! (`Program` → `Execution` → `rewrite_stream`):
//!
//! - `gcode_1M_blocks`: parse + interpret + emit unchanged, streaming, over a
//!   seeded flat program of 1,000,000 five-axis blocks written to a file
//!   (`target/gcode-bench-1M.nc`, reused when present). Baselines in the same
//!   run: `wc -l` on the same file, and a plain in-process line count.
//! - `loop_1M_iterations`: a parametric program whose `repeat` loop runs a
//!   move with computed words and an assignment 1,000,000 times, written flat
//!   by volcomp, against LinuxCNC's own interpreter `rs274 -g` on the same
//!   file (when `rs274` is installed; the ratio of the two times is the figure).
//!
//! Run: `cargo bench --bench gcode -- --warm-up-time 1 --measurement-time 3`
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::Command;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use volcomp::gcode::{InterpretOptions, Program, ProgramSetup, RewriteOptions, rewrite_stream};

const BLOCKS: usize = 1_000_000;

/// A seeded five-axis program: header, BLOCKS motion lines, footer.
fn program_path() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("target");
    let path = dir.join("gcode-bench-1M.nc");
    if path.exists() {
        return path;
    }
    std::fs::create_dir_all(&dir).unwrap();
    let tmp = dir.join("gcode-bench-1M.nc.tmp");
    let mut w = BufWriter::new(File::create(&tmp).unwrap());
    let mut rng = ChaCha8Rng::seed_from_u64(2016);
    writeln!(
        w,
        "%\nO1000 (BENCH: 1M FIVE-AXIS BLOCKS)\nN1 G21 G90 G94 G17"
    )
    .unwrap();
    writeln!(w, "N2 G0 X0. Y0. Z20. A0. C0.\nN3 G1 Z0. F800.").unwrap();
    let (mut x, mut y, mut z, mut a, mut c) = (0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64);
    for i in 0..BLOCKS {
        x = (x + rng.random_range(-0.8..0.8)).clamp(-200.0, 200.0);
        y = (y + rng.random_range(-0.8..0.8)).clamp(-200.0, 200.0);
        z = (z + rng.random_range(-0.2..0.2)).clamp(-50.0, 50.0);
        a = (a + rng.random_range(-0.3..0.3)).clamp(-90.0, 90.0);
        c += rng.random_range(-0.2..0.6);
        let n = 10 * (i + 4);
        if i % 1000 == 999 {
            writeln!(
                w,
                "N{n} G93 G1 X{x:.4} Y{y:.4} Z{z:.4} A{a:.4} C{c:.4} F{:.4}",
                rng.random_range(50.0..5000.0)
            )
            .unwrap();
            writeln!(w, "G94 F800.").unwrap();
        } else {
            writeln!(w, "N{n} X{x:.4} Y{y:.4} Z{z:.4} A{a:.4} C{c:.4}").unwrap();
        }
    }
    writeln!(w, "G0 Z50.\nM30\n%").unwrap();
    w.into_inner().unwrap().sync_all().unwrap();
    std::fs::rename(&tmp, &path).unwrap();
    path
}

/// Parse + interpret + emit unchanged, streaming; returns (blocks, bytes out).
fn pipeline(path: &Path) -> (usize, u64) {
    let program = Program::open(path, ProgramSetup::default()).unwrap();
    let mut out = CountingSink(0);
    let stats = rewrite_stream(
        program.run(InterpretOptions::default()),
        &mut out,
        RewriteOptions::default(),
        |_, _, _| None,
    )
    .unwrap();
    (stats.blocks, out.0)
}

const ITERATIONS: usize = 1_000_000;

/// The parametric program: one move with computed words and one assignment
/// per iteration.
fn loop_program_path() -> PathBuf {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("target/gcode-bench-loop.ngc");
    std::fs::write(
        &path,
        format!(
            "G21 G90 G94 F800\n#1 = 0\no1 repeat [{ITERATIONS}]\n  G1 X[#1 MOD 100] Y[#1 * 0.0001] Z0\n  #1 = [#1 + 1]\no1 endrepeat\nM2\n"
        ),
    )
    .unwrap();
    path
}

fn rs274(path: &Path) -> bool {
    Command::new("rs274")
        .arg("-g")
        .arg(path)
        .arg("/dev/null")
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status()
        .map(|s| s.success())
        .unwrap_or(false)
}

struct CountingSink(u64);

impl Write for CountingSink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0 += buf.len() as u64;
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

fn wc_l(path: &Path) -> usize {
    let out = Command::new("wc").arg("-l").arg(path).output().unwrap();
    String::from_utf8_lossy(&out.stdout)
        .split_whitespace()
        .next()
        .and_then(|n| n.parse().ok())
        .unwrap_or(0)
}

fn count_lines(path: &Path) -> usize {
    let mut file = BufReader::with_capacity(1 << 16, File::open(path).unwrap());
    let mut n = 0;
    loop {
        let buf = file.fill_buf().unwrap();
        if buf.is_empty() {
            break;
        }
        n += buf.iter().filter(|&&b| b == b'\n').count();
        let len = buf.len();
        file.consume(len);
    }
    n
}

fn bench(c: &mut Criterion) {
    let path = program_path();
    let lines = wc_l(&path);
    let (blocks, out_bytes) = pipeline(&path);
    let mut input = Vec::new();
    File::open(&path).unwrap().read_to_end(&mut input).unwrap();
    assert_eq!(blocks, lines, "every line is a block");
    assert_eq!(
        out_bytes as usize,
        input.len(),
        "unchanged output has the input's size"
    );
    drop(input);

    let mut group = c.benchmark_group("gcode_1M_blocks");
    group.sample_size(10);
    group.throughput(Throughput::Elements(blocks as u64));
    group.bench_function("parse_interpret_emit_unchanged", |b| {
        b.iter(|| pipeline(&path))
    });
    group.bench_function("baseline_wc_l", |b| b.iter(|| wc_l(&path)));
    group.bench_function("baseline_count_newlines", |b| b.iter(|| count_lines(&path)));
    group.finish();

    let loop_path = loop_program_path();
    let (executed, _) = pipeline(&loop_path);
    assert_eq!(
        executed,
        ITERATIONS + 2,
        "every iteration's move is written"
    );
    let mut group = c.benchmark_group("loop_1M_iterations");
    group.sample_size(10);
    group.throughput(Throughput::Elements(ITERATIONS as u64));
    group.bench_function("volcomp_flatten", |b| b.iter(|| pipeline(&loop_path)));
    if rs274(&loop_path) {
        group.bench_function("rs274_g", |b| b.iter(|| rs274(&loop_path)));
    } else {
        eprintln!("rs274 not found (Debian package linuxcnc-uspace): no reference time");
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
