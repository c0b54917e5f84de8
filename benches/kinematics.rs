//! Volumetric error per pose: the chain alone (baseline), the 30 table lookups, and
//! both together (what compensate and predict call), on the reference machine; and
//! poses per second over a batch, one thread vs two (rayon). Baselines in the same
//! run: the chain alone, and the exact (Newton-inverted) NURBS lookups.
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use std::hint::black_box;
use std::path::Path;
use volcomp::axes::Axes;
use volcomp::machine::{ErrorModel, Machine, ModelOptions};

/// The reference machine fitted with the default SMEM settings; `exact` selects the
/// exact NURBS lookups instead of the resampled ones.
fn reference_models() -> (ErrorModel, ErrorModel) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("machines/ref-trt.toml");
    let machine = Machine::load(&path).expect("ref-trt loads");
    let fast = ErrorModel::from_machine(&machine, &ModelOptions::default()).expect("fit");
    let file = fast.to_model_file(&machine).expect("model file");
    let dir = tempfile::tempdir().expect("tempdir");
    let model_path = dir.path().join("fit.json");
    std::fs::write(&model_path, serde_json::to_string(&file).expect("json")).expect("write");
    let exact_options = ModelOptions {
        exact_lookups: true,
        ..Default::default()
    };
    let exact = ErrorModel::from_model_file(&machine, &model_path, &exact_options).expect("read");
    (fast, exact)
}

/// Poses inside the reference machine's tables, C over several turns.
fn poses(n: usize) -> Vec<Axes> {
    let mut rng = ChaCha8Rng::seed_from_u64(2016);
    (0..n)
        .map(|_| {
            Axes::xyzac(
                rng.random_range(-200.0..200.0),
                rng.random_range(-150.0..150.0),
                rng.random_range(-200.0..100.0),
                rng.random_range(-110.0..110.0),
                rng.random_range(-1080.0..1080.0),
            )
        })
        .collect()
}

fn per_pose(c: &mut Criterion) {
    let (model, exact) = reference_models();
    let kin = *model.kinematics();
    let set = poses(1024);
    let errors: Vec<_> = set
        .iter()
        .map(|p| model.errors_at(p).expect("inside"))
        .collect();
    let mut group = c.benchmark_group("per_pose");
    group.throughput(Throughput::Elements(set.len() as u64));
    group.bench_function("chain_only", |b| {
        b.iter(|| {
            for (p, e) in set.iter().zip(&errors) {
                black_box(kin.volumetric_error(black_box(p), e));
            }
        })
    });
    group.bench_function("exact_lookups_and_chain", |b| {
        b.iter(|| {
            for p in &set {
                black_box(exact.volumetric_error(black_box(p)).expect("inside"));
            }
        })
    });
    group.bench_function("lookups_only_30", |b| {
        b.iter(|| {
            for p in &set {
                black_box(model.errors_at(black_box(p)).expect("inside"));
            }
        })
    });
    group.bench_function("lookups_and_chain", |b| {
        b.iter(|| {
            for p in &set {
                black_box(model.volumetric_error(black_box(p)).expect("inside"));
            }
        })
    });
    group.finish();
}

fn batch(c: &mut Criterion) {
    let (model, _) = reference_models();
    let set = poses(100_000);
    let mut group = c.benchmark_group("batch_100k");
    group.throughput(Throughput::Elements(set.len() as u64));
    group.sample_size(10);
    for threads in [1usize, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        group.bench_with_input(
            BenchmarkId::new("rayon_threads", threads),
            &threads,
            |b, _| {
                b.iter(|| {
                    pool.install(|| {
                        let worst = set
                            .par_iter()
                            .map(|p| model.volumetric_error(p).expect("inside").magnitude_um())
                            .reduce(|| 0.0, f64::max);
                        black_box(worst)
                    })
                })
            },
        );
    }
    group.finish();
}

criterion_group!(benches, per_pose, batch);
criterion_main!(benches);
