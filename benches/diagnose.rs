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
    bench_write_machine(c, &part);
}

/// `diagnose --write-machine` per case (issue 26: under 1 s each): seeded
/// cases of the effects that go back into the machine file, each diagnosed
/// and turned into the machine file's edits (the text included).
fn bench_write_machine(c: &mut Criterion, part: &volcomp::diagnose::synthetic::SyntheticPart) {
    use volcomp::diagnose::machine_update;
    use volcomp::machine::edit_machine_text;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine_path = root.join("machines/ref-trt.toml");
    let machine = volcomp::machine::Machine::load(&machine_path).expect("ref-trt");
    let machine_text = std::fs::read_to_string(&machine_path).expect("ref-trt");
    let cases: Vec<Vec<f64>> = [
        vec![
            "rotary_location:EY0A=20,EZ0A=-15,EX0C=12",
            "squareness:s_xy=40,s_xz=-30",
        ],
        vec![
            "rotary_location:EY0A=20,EZ0A=-15,EB0A=30,EX0C=12,EA0C=-25",
            "backlash:bx=15,by=12,bz=8",
        ],
        vec!["squareness:s_xy=40"],
        vec!["backlash:bx=15,by=12,bz=8"],
    ]
    .iter()
    .enumerate()
    .map(|(k, specs)| {
        let effects: Vec<Effect> = specs
            .iter()
            .map(|s| Effect::parse(s).expect("effect"))
            .collect();
        simulate(
            &part.contexts,
            &part.truth_um,
            &effects,
            &SimulateOptions {
                seed: 2016 + k as u64,
                ..SimulateOptions::default()
            },
        )
        .expect("simulate")
        .deviations_um()
    })
    .collect();
    let mut group = c.benchmark_group("diagnose_write_machine");
    group.throughput(Throughput::Elements(cases.len() as u64));
    group.bench_function("4 cases (diagnosis and machine file edits)", |b| {
        b.iter(|| {
            for d in &cases {
                let report =
                    diagnose(&part.contexts, d, &DiagnoseOptions::default()).expect("diagnose");
                let update = machine_update(&report, &machine, &[]);
                edit_machine_text(&machine_text, &machine_path, &update.edits).expect("edit");
            }
        })
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
