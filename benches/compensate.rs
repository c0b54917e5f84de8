//! Compensation throughput, end to end (read, interpret, solve, split check,
//! rewrite, write) over a seeded, smooth five-axis program inside the ref-trt
//! travel (x ∈ [−150, 150], y ∈ [−100, 100], z ∈ [−150, 50], a ∈ [−60, 60],
//! c multi-turn), tip and tool axis (X Y Z A C solved, the default) and
//! `--position-only`,
//! against the G-code pass-through (`rewrite_stream` with
//! unchanged targets) on the same file in the same run; and `predict` of the
//! saddle's 372 plan points, with and without loading (fitting) the machine.
//!
//! Run: `cargo bench --bench compensate -- --warm-up-time 1 --measurement-time 3`
//!
//! The 1,000,000-block figure is measured once outside criterion:
//! `VOLCOMP_BENCH_PROGRAM=/tmp/p1m.nc cargo bench --bench compensate` writes the
//! program and exits, then
//! `/usr/bin/time -v target/release/volcomp compensate machines/ref-trt.toml /tmp/p1m.nc -o /tmp/p1m-c.nc [--position-only]`.
use criterion::{Criterion, Throughput};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use volcomp::compensate::{CompensateOptions, compensate};
use volcomp::gcode::{InterpretOptions, Program, ProgramSetup, RewriteOptions, rewrite_stream};
use volcomp::inspection::Plan;
use volcomp::machine::{ErrorModel, Machine};
use volcomp::predict::predict_plan;
use volcomp::toolpath::CutOptions;

/// Blocks of the program measured inside criterion.
const CRITERION_BLOCKS: usize = 100_000;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Write a seeded program of `blocks` motion blocks (plus a short header and
/// footer): a smooth Lissajous path sampled about every 0.5 mm, with a small
/// seeded jitter, G94 feed.
fn write_program(path: &Path, blocks: usize) -> std::io::Result<()> {
    let mut w = BufWriter::new(File::create(path)?);
    let mut rng = ChaCha8Rng::seed_from_u64(2016);
    writeln!(
        w,
        "%\nO2000 (BENCH: SEEDED FIVE-AXIS PATH)\nN1 G21 G90 G94 G17"
    )?;
    writeln!(w, "N2 G0 X0. Y0. Z0. A0. C0.\nN3 G1 F2000.")?;
    let dt = 0.002;
    for i in 0..blocks {
        let t = i as f64 * dt;
        let j = |rng: &mut ChaCha8Rng| rng.random_range(-0.01..0.01);
        let x = 150.0 * (1.0 * t).sin() * 0.99 + j(&mut rng);
        let y = 100.0 * (1.3 * t + 0.5).sin() * 0.99 + j(&mut rng);
        let z = -50.0 + 99.0 * (0.7 * t).sin() + j(&mut rng);
        let a = 59.0 * (0.37 * t).sin();
        let c = 3.0 * t;
        writeln!(
            w,
            "N{} X{x:.4} Y{y:.4} Z{z:.4} A{a:.4} C{c:.4}",
            10 * (i + 4)
        )?;
    }
    writeln!(w, "G0 Z50.\nM30\n%")?;
    w.into_inner().map_err(|e| e.into_error())?.sync_all()
}

fn load() -> (Machine, ErrorModel) {
    let machine = Machine::load(&root().join("machines/ref-trt.toml")).expect("ref-trt loads");
    let model = ErrorModel::from_machine(&machine, &volcomp::machine::ModelOptions::default())
        .expect("ref-trt's tables fit");
    (machine, model)
}

fn bench_compensate(c: &mut Criterion, machine: &Machine, model: &ErrorModel) {
    let dir = tempfile::tempdir().expect("temp dir");
    let program = dir.path().join("program.nc");
    write_program(&program, CRITERION_BLOCKS).expect("program written");
    let output = dir.path().join("out.nc");
    let blocks = CRITERION_BLOCKS as u64 + 7;
    let interpret = InterpretOptions {
        rapid_mm_per_min: machine.rapid_mm_per_min,
        ..InterpretOptions::default()
    };
    let options = CompensateOptions {
        interpret,
        limits: Some(machine.limits),
        ..CompensateOptions::default()
    };
    let mut group = c.benchmark_group("compensate_100k_blocks");
    group.sample_size(10);
    group.throughput(Throughput::Elements(blocks));
    group.bench_function("passthrough_rewrite_stream", |b| {
        b.iter(|| {
            let input = Program::open(&program, ProgramSetup::default()).unwrap();
            let mut out = BufWriter::with_capacity(1 << 16, File::create(&output).unwrap());
            let stats = rewrite_stream(
                input.run(interpret),
                &mut out,
                RewriteOptions::default(),
                |_, event, _| event.motion().map(|m| m.end),
            )
            .unwrap();
            out.flush().unwrap();
            stats.blocks
        })
    });
    let position_only = CompensateOptions {
        orientation: false,
        ..options.clone()
    };
    for (name, options) in [
        ("compensate_position_only", &position_only),
        ("compensate", &options),
    ] {
        group.bench_function(name, |b| {
            b.iter(|| {
                let input = Program::open(&program, ProgramSetup::default()).unwrap();
                let mut out = BufWriter::with_capacity(1 << 16, File::create(&output).unwrap());
                let report = compensate(input, &mut out, model, options, |_| {}).unwrap();
                out.flush().unwrap();
                report.blocks_read
            })
        });
    }
    group.finish();
}

fn bench_predict(c: &mut Criterion, machine: &Machine, model: &ErrorModel) {
    let program = root().join("samples/saddle.nc");
    let plan = Plan::read(&root().join("samples/saddle-plan.csv")).expect("plan");
    let options = CutOptions::for_machine(machine, volcomp::gcode::Frame::Joint);
    let mut group = c.benchmark_group("predict_saddle_372_points");
    group.sample_size(10);
    group.throughput(Throughput::Elements(plan.points.len() as u64));
    group.bench_function("model_loaded", |b| {
        b.iter(|| {
            let input = Program::open(&program, ProgramSetup::default()).unwrap();
            predict_plan(input, model, &plan, &options)
                .unwrap()
                .profile_um
        })
    });
    group.bench_function("including_machine_load_and_fit", |b| {
        b.iter(|| {
            let (machine, model) = load();
            let options = CutOptions::for_machine(&machine, volcomp::gcode::Frame::Joint);
            let input = Program::open(&program, ProgramSetup::default()).unwrap();
            predict_plan(input, &model, &plan, &options)
                .unwrap()
                .profile_um
        })
    });
    group.finish();
}

/// Where compensation time goes: one error lookup (30 curves) and one solve.
fn bench_pose(c: &mut Criterion, model: &ErrorModel) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let poses: Vec<volcomp::axes::Joints> = (0..1000)
        .map(|_| {
            volcomp::axes::Joints::new(volcomp::axes::Axes::xyzac(
                rng.random_range(-150.0..150.0),
                rng.random_range(-100.0..100.0),
                rng.random_range(-150.0..50.0),
                rng.random_range(-60.0..60.0),
                rng.random_range(0.0..720.0),
            ))
        })
        .collect();
    let mut group = c.benchmark_group("per_pose_1000");
    group.throughput(Throughput::Elements(poses.len() as u64));
    group.bench_function("errors_at", |b| {
        b.iter(|| {
            poses
                .iter()
                .map(|p| model.errors_at(p).unwrap().component[0][0])
                .sum::<f64>()
        })
    });
    group.bench_function("solve_joints", |b| {
        b.iter(|| {
            poses
                .iter()
                .map(|p| {
                    volcomp::compensate::solve_joints(model, p)
                        .unwrap()
                        .residual_mm
                })
                .sum::<f64>()
        })
    });
    group.finish();
}

fn main() {
    if let Ok(path) = std::env::var("VOLCOMP_BENCH_PROGRAM") {
        let blocks = std::env::var("VOLCOMP_BENCH_BLOCKS")
            .ok()
            .and_then(|b| b.parse().ok())
            .unwrap_or(1_000_000);
        write_program(Path::new(&path), blocks).expect("program written");
        eprintln!("wrote {blocks} motion blocks to {path}");
        return;
    }
    let (machine, model) = load();
    let mut c = Criterion::default().configure_from_args();
    bench_compensate(&mut c, &machine, &model);
    bench_predict(&mut c, &machine, &model);
    bench_pose(&mut c, &model);
    c.final_summary();
}
