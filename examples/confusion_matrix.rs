//! Confusion matrix of the blind diagnosis: every catalogue effect × N seeds,
//! simulated on the synthetic saddle raster at 0.3 µm noise, diagnosed without
//! being told. Prints the matrix (rows: injected, columns: selected[0] or
//! "none") and the top-1 accuracy.
//!
//!     cargo run --release --example confusion_matrix [-- SEEDS [pairs] [saddle] [noise=UM] [peak=K]]
//!
//! `saddle` uses the contexts our toolpath layer builds for the bundled saddle
//! (samples/saddle.nc on ref-trt, fixture in tests/data/diagnose) instead of the
//! synthetic raster; `pairs` also runs every pair of effects once; `noise=UM`
//! sets the probing noise (default 0.3 µm); `peak=K` scales every injected
//! effect so that its largest deviation on the part is K × the noise (default:
//! an RMS drawn in 2–6 µm); `dome` runs a second synthetic part, a dome cut
//! with A over 15–85° and C over −50…70° (the raster's A spans 23–47°).
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use std::time::Instant;
use volcomp::diagnose::synthetic::SyntheticPart;
use volcomp::diagnose::synthetic::{SyntheticOptions, from_fixture, random_effect, saddle_raster};
use volcomp::diagnose::{
    DiagnoseOptions, DiagnoseReport, Effect, EffectKind, SimulateOptions, diagnose, simulate,
};

/// Simulate `effects` at `noise_um` and diagnose without telling.
fn blind_run(part: &SyntheticPart, effects: &[Effect], noise_um: f64, seed: u64) -> DiagnoseReport {
    let options = SimulateOptions { noise_um, seed };
    let m = simulate(&part.contexts, &part.truth_um, effects, &options).expect("simulate");
    diagnose(
        &part.contexts,
        &m.deviations_um(),
        &DiagnoseOptions::default(),
    )
    .expect("diagnose")
}

/// A value given as `name=VALUE` on the command line.
fn arg_value(args: &[String], name: &str) -> Option<f64> {
    args.iter()
        .find_map(|a| a.strip_prefix(name)?.strip_prefix('='))
        .map(|v| {
            v.parse()
                .unwrap_or_else(|_| panic!("{name}= needs a number, got {v}"))
        })
}

/// `effect` scaled so that its largest |deviation| over `part` is `peak_um`
/// (every parameter but `thermal_drift`'s `tau`, all of them linear).
fn scaled_to_peak(effect: Effect, part: &SyntheticPart, peak_um: f64) -> Effect {
    let current = part
        .contexts
        .iter()
        .map(|c| effect.deviation_um(c).abs())
        .fold(0.0f64, f64::max);
    if current == 0.0 {
        return effect;
    }
    let k = peak_um / current;
    let mut values = effect.values.clone();
    let linear = if effect.kind == EffectKind::ThermalDrift {
        3
    } else {
        values.len()
    };
    for v in &mut values[..linear] {
        *v *= k;
    }
    Effect {
        kind: effect.kind,
        values,
    }
}

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(10);
    let args: Vec<String> = std::env::args().collect();
    let part = if args.iter().any(|a| a == "saddle") {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/diagnose");
        let json = std::fs::read_to_string(root.join("saddle-contexts.json")).expect("fixture");
        let truth = volcomp::inspection::Measurement::read(&root.join("saddle-truth.csv"))
            .expect("fixture");
        let part = from_fixture(&json, &truth).expect("fixture");
        println!(
            "saddle (samples/saddle.nc on ref-trt): {} points",
            part.contexts.len()
        );
        part
    } else if args.iter().any(|a| a == "dome") {
        let part = saddle_raster(&SyntheticOptions::dome());
        println!(
            "synthetic dome, A 15–85°, C −50…70°: {} points",
            part.contexts.len()
        );
        part
    } else {
        let part = saddle_raster(&SyntheticOptions::default());
        println!("synthetic saddle raster: {} points", part.contexts.len());
        part
    };
    let noise_um = arg_value(&args, "noise").unwrap_or(0.3);
    let peak = arg_value(&args, "peak");
    println!(
        "noise {noise_um} µm; effects {}",
        peak.map_or("of RMS 2–6 µm".to_string(), |k| format!(
            "scaled to a peak of {k} × the noise"
        ))
    );
    let draw = |kind: EffectKind, rng: &mut ChaCha8Rng| {
        let e = random_effect(kind, &part.contexts, (2.0, 6.0), rng);
        match peak {
            Some(k) => scaled_to_peak(e, &part, k * noise_um),
            None => e,
        }
    };
    let mut names: Vec<&str> = EffectKind::ALL.iter().map(|k| k.name()).collect();
    names.push("none");
    let mut matrix = vec![vec![0usize; names.len()]; names.len()];
    let mut correct = 0;
    let mut total = 0;
    // The model is right in every run: a "model does not match" verdict is a false alarm.
    let mut false_mismatch = 0;
    let mut worst_ratio = 0.0f64;
    let start = Instant::now();
    for (row, kind) in EffectKind::ALL.iter().map(Some).chain([None]).enumerate() {
        for seed in 0..seeds {
            let mut rng = ChaCha8Rng::seed_from_u64(1000 * row as u64 + seed);
            let effects: Vec<_> = kind.map(|k| draw(*k, &mut rng)).into_iter().collect();
            let report = blind_run(&part, &effects, noise_um, 77 + seed);
            if report.model_check.mismatch {
                false_mismatch += 1;
                println!(
                    "model verdict on a right model: injected {} (seed {seed}): {:?}",
                    names[row], report.model_check
                );
            }
            let got = report
                .selected
                .first()
                .map(String::as_str)
                .unwrap_or("none");
            let col = names
                .iter()
                .position(|n| *n == got)
                .unwrap_or(names.len() - 1);
            matrix[row][col] += 1;
            total += 1;
            if col == row {
                correct += 1;
                let ratio = report.after.heldout_rms_um / report.gap.noise_floor_um;
                worst_ratio = worst_ratio.max(ratio);
                if ratio > 1.3 {
                    println!(
                        "high: {} seed {seed}: held-out after {:.3} / floor {:.3} = {ratio:.2}; selected {:?}",
                        names[row],
                        report.after.heldout_rms_um,
                        report.gap.noise_floor_um,
                        report.selected
                    );
                }
            } else {
                println!(
                    "miss: injected {} (seed {seed}) -> {:?}; top effects {:?}; aliases {:?}",
                    names[row],
                    report.selected,
                    report
                        .effects
                        .iter()
                        .take(3)
                        .map(|e| (
                            e.name.as_str(),
                            (e.heldout_rms_after_um * 1000.0).round() / 1000.0,
                            e.bic.round()
                        ))
                        .collect::<Vec<_>>(),
                    report
                        .effects
                        .iter()
                        .find(|e| e.name == names[row])
                        .map(|e| e.aliases.clone())
                );
            }
        }
    }
    let elapsed = start.elapsed().as_secs_f64();
    if args.iter().any(|a| a == "pairs") {
        let mut found = 0;
        let mut count = 0;
        for (i, a) in EffectKind::ALL.iter().enumerate() {
            for b in &EffectKind::ALL[i + 1..] {
                let mut rng = ChaCha8Rng::seed_from_u64(5000 + count);
                let effects = vec![draw(*a, &mut rng), draw(*b, &mut rng)];
                let report = blind_run(&part, &effects, noise_um, count);
                let ok = report.selected.len() == 2
                    && report.selected.iter().any(|s| s == a.name())
                    && report.selected.iter().any(|s| s == b.name());
                found += usize::from(ok);
                count += 1;
                println!(
                    "pair {} + {}: selected {:?}{}",
                    a.name(),
                    b.name(),
                    report.selected,
                    if ok { "" } else { "  <-- miss" }
                );
            }
        }
        println!("pairs found: {found}/{count}");
    }
    print!("{:>16}", "injected \\ got");
    for n in &names {
        print!(" {:>5}", &n[..n.len().min(5)]);
    }
    println!();
    for (r, row) in matrix.iter().enumerate() {
        print!("{:>16}", names[r]);
        for c in row {
            print!(" {c:>5}");
        }
        println!();
    }
    println!(
        "\"error model does not match\" verdicts (false alarms: the model is right): {false_mismatch}/{total}"
    );
    println!(
        "top-1 accuracy: {correct}/{total} = {:.1}%; worst held-out RMS after / noise floor among correct: {worst_ratio:.2}; {:.1} ms per diagnosis",
        100.0 * correct as f64 / total as f64,
        1000.0 * elapsed / total as f64
    );
}
