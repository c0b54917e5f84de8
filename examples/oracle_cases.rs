//! The oracle table of docs/diagnose.md (issue 36): `diagnose` on every case
//! of a folder of oracle cases (measurements made by an independent
//! implementation of the spec), scored as the folder's README says; prints
//! one line per case, then the table's row and the time per diagnosis.
//!
//!     cargo run --release --example oracle_cases -- [ORACLE_DIR [REF_TRT.toml]] [verbose] [only=PREFIX]
//!
//! `only=PREFIX` runs the cases whose name starts with PREFIX (the table's
//! row then counts those only).
//!
//! Defaults: `../shared/data/oracle-cases` (from the crate's root, or
//! `../../shared/…` from a worktree one level down) and the crate's `machines/ref-trt.toml` (the
//! same tables as the folder's `../ref-trt.toml`).
use std::path::PathBuf;
use std::time::Instant;
use volcomp::diagnose::ideal_observer::separation;
use volcomp::diagnose::oracle::{OracleGroup, OracleMachine, read_index, score};
use volcomp::diagnose::oracle::{truth_effects, truth_residual_rms};
use volcomp::diagnose::{DiagnoseOptions, diagnose};

fn main() {
    let root_dir = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "verbose" && !a.starts_with("only="))
        .collect();
    let only: Option<String> =
        std::env::args().find_map(|a| a.strip_prefix("only=").map(String::from));
    let verbose = std::env::args().any(|a| a == "verbose");
    // The checkout's sibling `shared/` (`../shared`), or its parent's for a
    // worktree one level further down (`../../shared`).
    let dir = args.first().map_or_else(
        || {
            [
                "../shared/data/oracle-cases",
                "../../shared/data/oracle-cases",
            ]
            .iter()
            .map(|d| root_dir.join(d))
            .find(|d| d.join("index.json").is_file())
            .unwrap_or_else(|| root_dir.join("../shared/data/oracle-cases"))
        },
        PathBuf::from,
    );
    let machine_path = args
        .get(1)
        .map_or_else(|| root_dir.join("machines/ref-trt.toml"), PathBuf::from);
    let cases = read_index(&dir).expect("index.json");
    let right = OracleMachine::load(&machine_path).expect("ref-trt");
    let wrong = OracleMachine::load(&dir.join("machines/x1.4.toml")).expect("x1.4");
    let mut rows: Vec<(OracleGroup, f64, bool)> = Vec::new();
    let mut total = 0.0;
    // Pairs the ideal observer separates, and of those the pairs passed.
    let (mut separable, mut separable_passed) = (0usize, 0usize);
    for case in cases
        .iter()
        .filter(|c| only.as_ref().is_none_or(|o| c.name.starts_with(o.as_str())))
    {
        let machine = if case.group == OracleGroup::WrongModel {
            &wrong
        } else {
            &right
        };
        let (contexts, measured) = machine.case_inputs(&dir, case).expect("case inputs");
        let started = Instant::now();
        let report = diagnose(&contexts, &measured, &DiagnoseOptions::default()).expect("diagnose");
        total += started.elapsed().as_secs_f64();
        let s = score(case, &report);
        let ideal = (case.group == OracleGroup::Pair).then(|| {
            let truth = truth_effects(&dir.join(&case.name)).expect("truth.json");
            let left = truth_residual_rms(&contexts, &measured, &truth);
            let sep = separation(
                &contexts,
                &truth,
                case.noise_um,
                &DiagnoseOptions::default(),
            )
            .expect("ideal observer");
            (sep, left)
        });
        if let Some((id, _)) = &ideal {
            separable += usize::from(id.separable());
            separable_passed += usize::from(id.separable() && s.pass);
        }
        println!(
            "{:<32} {:<4} truth {:<34} said {}",
            case.name,
            if s.pass { "ok" } else { "MISS" },
            if case.effects.is_empty() {
                "nothing".to_string()
            } else {
                case.effects.join(" + ")
            },
            s.said
        );
        if let Some((id, left)) = ideal.as_ref().filter(|_| verbose) {
            println!(
                "    ideal observer: {id}; the truth leaves {left:.3} µm RMS of the measurement (noise {} µm)",
                case.noise_um
            );
        }
        if verbose {
            for note in &report.selection_notes {
                println!("    {note}");
            }
        }
        rows.push((case.group, case.noise_um, s.pass));
    }
    let count = |f: &dyn Fn(&(OracleGroup, f64, bool)) -> bool| {
        let all: Vec<_> = rows.iter().filter(|r| f(r)).collect();
        (all.iter().filter(|r| r.2).count(), all.len())
    };
    let single = |noise: f64| {
        count(&|r: &(OracleGroup, f64, bool)| {
            r.0 == OracleGroup::Single && (r.1 - noise).abs() < 1e-9
        })
    };
    let group = |g: OracleGroup| count(&|r: &(OracleGroup, f64, bool)| r.0 == g);
    let (s3, n3) = single(0.3);
    let (s1, n1) = single(1.0);
    let (l, nl) = group(OracleGroup::ServoLag);
    let (p, np) = group(OracleGroup::Pair);
    let (w, nw) = group(OracleGroup::WrongModel);
    let (q, nq) = group(OracleGroup::NoEffect);
    println!();
    println!(
        "| top-1, noise 0.3 and 1.0 µm | servo lag strong at few points | pairs both named | wrong model named beside its effect | quiet on no-effect cases |"
    );
    println!("|---|---|---|---|---|");
    println!(
        "| {}/{} ({s3}/{n3} + {s1}/{n1}) | {l}/{nl} | {p}/{np} | {w}/{nw} | {q}/{nq} |",
        s3 + s1,
        n3 + n1
    );
    println!(
        "pairs this part separates (ideal observer, expected margin ≥ the threshold): {separable}/{np}; both named of those: {separable_passed}/{separable}"
    );
    println!(
        "{} cases, {:.1} ms per diagnosis (diagnose only; machines fitted once)",
        rows.len(),
        1000.0 * total / rows.len().max(1) as f64
    );
}
