//! Diagnosis time on the saddle (372 points, the contexts fixture): the whole
//! engine, and its parts (single effects only; noise floor only) as baselines.
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use volcomp::diagnose::synthetic::from_fixture;
use volcomp::diagnose::{DiagnoseOptions, Effect, SimulateOptions, diagnose, simulate};

fn bench(c: &mut Criterion) {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/diagnose");
    let json = std::fs::read_to_string(root.join("saddle-contexts.json")).expect("fixture");
    let truth =
        volcomp::inspection::Measurement::read(&root.join("saddle-truth.csv")).expect("fixture");
    let part = from_fixture(&json, &truth).expect("fixture");
    let effect = Effect::parse("backlash:bx=6,by=2,bz=4").expect("effect");
    let m = simulate(
        &part.contexts,
        &part.truth_um,
        &[effect],
        &SimulateOptions::default(),
    )
    .expect("simulate");
    let d = m.deviations_um();
    let mut group = c.benchmark_group("diagnose");
    group.throughput(Throughput::Elements(part.contexts.len() as u64));
    group.bench_function("full (up to two effects)", |b| {
        b.iter(|| diagnose(&part.contexts, &d, &DiagnoseOptions::default()).expect("diagnose"))
    });
    let single = DiagnoseOptions {
        max_selected: 1,
        ..DiagnoseOptions::default()
    };
    group.bench_function("single effects only", |b| {
        b.iter(|| diagnose(&part.contexts, &d, &single).expect("diagnose"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
