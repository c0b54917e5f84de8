//! The follow-up loop, end to end, on the saddle: every catalogue effect × N
//! seeds is simulated and diagnosed blind (as `confusion_matrix -- saddle`);
//! when the selection has aliases, a follow-up is designed
//! (`diagnose::followup::design`), its readings are simulated with the
//! injected effect (`simulate_followup`), and the measurement and the
//! follow-up are diagnosed together. Prints top-1 before and after, and the
//! expected against the achieved separation.
//!
//!     cargo run --release --example followup [-- SEEDS [noise=UM] [probes=N]]
#![allow(clippy::result_large_err)]
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::path::Path;
use std::time::Instant;
use volcomp::diagnose::followup::{self, FollowupOptions, ProbeReading};
use volcomp::diagnose::synthetic::{from_fixture, random_effect};
use volcomp::diagnose::{
    DiagnoseOptions, EffectKind, SimulateOptions, diagnose, diagnose_with_followup, simulate,
    simulate_followup,
};
use volcomp::machine::{ErrorModel, Machine, ModelOptions};
use volcomp::toolpath::{ProbeTool, probe_context};

fn arg_value(args: &[String], name: &str) -> Option<f64> {
    args.iter()
        .find_map(|a| a.strip_prefix(name)?.strip_prefix('='))
        .and_then(|v| v.parse().ok())
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seeds: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(10);
    let noise_um = arg_value(&args, "noise").unwrap_or(0.3);
    let options = FollowupOptions {
        probes: arg_value(&args, "probes").map_or(12, |v| v as usize),
        ..FollowupOptions::default()
    };
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let machine = Machine::load(&root.join("machines/ref-trt.toml")).expect("ref-trt loads");
    let model = ErrorModel::from_machine(&machine, &ModelOptions::default()).expect("fit");
    let data = root.join("tests/data/diagnose");
    let json = std::fs::read_to_string(data.join("saddle-contexts.json")).expect("fixture");
    let truth =
        volcomp::inspection::Measurement::read(&data.join("saddle-truth.csv")).expect("fixture");
    let part = from_fixture(&json, &truth).expect("fixture");
    let contexts = &part.contexts;
    let end = volcomp::toolpath::last_time_min(contexts);
    let probe = ProbeTool {
        length_mm: machine.tool.length,
        radius_mm: 1.0,
    };
    let candidates = followup::candidates(contexts, |cut, rotary| {
        probe_context(&model, &probe, Some(&machine.limits), cut, rotary, end)
    })
    .expect("candidates");
    println!(
        "saddle: {} points, {} candidate probes; noise {noise_um} µm; {} probes per follow-up",
        contexts.len(),
        candidates.len(),
        options.probes
    );
    let start = Instant::now();
    let (mut total, mut before_ok, mut after_ok, mut designed) = (0, 0, 0, 0);
    let mut separations: Vec<(String, f64, f64)> = Vec::new();
    let mut design_ms = Vec::new();
    for (row, kind) in EffectKind::ALL.iter().enumerate() {
        for seed in 0..seeds {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 * row as u64 + seed);
            let effect = random_effect(*kind, contexts, (2.0, 6.0), &mut rng);
            let effects = [effect];
            let sim = SimulateOptions {
                noise_um,
                seed: 77 + seed,
            };
            let measured = simulate(contexts, &part.truth_um, &effects, &sim)
                .expect("simulate")
                .deviations_um();
            let report =
                diagnose(contexts, &measured, &DiagnoseOptions::default()).expect("diagnose");
            let top = |r: &volcomp::diagnose::DiagnoseReport| r.selected.first().cloned();
            let right =
                |r: &volcomp::diagnose::DiagnoseReport| top(r).as_deref() == Some(kind.name());
            total += 1;
            before_ok += usize::from(right(&report));
            let t0 = Instant::now();
            let design = followup::design(contexts, &measured, &report, &candidates, end, &options)
                .expect("design");
            let Some(design) = design else {
                after_ok += usize::from(right(&report));
                continue;
            };
            design_ms.push(t0.elapsed().as_secs_f64() * 1e3);
            designed += 1;
            let probes: Vec<_> = design.probes.iter().map(|p| p.probe.clone()).collect();
            let truth: Vec<f64> = probes
                .iter()
                .map(|p| contexts[p.of].predicted_um - p.context.predicted_um)
                .collect();
            let readings = simulate_followup(
                contexts,
                &probes,
                &truth,
                &effects,
                &SimulateOptions {
                    noise_um,
                    seed: 5000 + seed,
                },
            )
            .expect("simulate follow-up");
            let readings: Vec<ProbeReading> = probes
                .into_iter()
                .zip(readings)
                .map(|(probe, reading_um)| ProbeReading { probe, reading_um })
                .collect();
            let after =
                diagnose_with_followup(contexts, &measured, &readings, &DiagnoseOptions::default())
                    .expect("diagnose with follow-up");
            let outcome =
                followup::outcome(contexts, &measured, &report, &readings).expect("outcome");
            after_ok += usize::from(right(&after));
            // Expected in the direction of the truth, against achieved.
            for s in &outcome.separations {
                let truth_is_selected = s.selected == kind.name();
                let truth_is_rival = s.rival == kind.name();
                if !(truth_is_selected || truth_is_rival) {
                    continue;
                }
                let expected = if truth_is_selected {
                    s.if_selected_sigma
                } else {
                    s.if_rival_sigma
                };
                let achieved = s.achieved_sigma.unwrap_or(0.0);
                let achieved = if truth_is_selected {
                    achieved
                } else {
                    -achieved
                };
                separations.push((format!("{} vs {}", s.selected, s.rival), expected, achieved));
            }
            println!(
                "{:<16} seed {seed}: before {:<16} rivals {:<40} after {:<16} expected {:.1} σ",
                kind.name(),
                top(&report).unwrap_or_else(|| "none".into()),
                design.rivals.join(", "),
                top(&after).unwrap_or_else(|| "none".into()),
                design.expected_separation_sigma
            );
        }
    }
    println!(
        "\ntop-1 before the follow-up {before_ok}/{total}, after {after_ok}/{total}; {designed} follow-ups designed ({:.0} ms each on average); {:.1} s",
        design_ms.iter().sum::<f64>() / design_ms.len().max(1) as f64,
        start.elapsed().as_secs_f64()
    );
    if !separations.is_empty() {
        println!("\nseparation of the truth from its alias (σ): expected → achieved");
        for (pair, e, a) in &separations {
            println!("  {pair:<40} {e:6.1} → {a:6.1}");
        }
        let within = separations
            .iter()
            .filter(|(_, e, a)| (e - a).abs() <= 1.5 + 0.2 * e)
            .count();
        println!(
            "{within}/{} within 1.5 σ + 20 % of the expected",
            separations.len()
        );
    }
}
