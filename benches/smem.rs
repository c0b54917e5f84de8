//! SMEM benchmarks: the shape of the paper's Tables 3 and 4 on a seeded 40-point
//! curve like its Fig. 3 (p = 3, 10 control points), and the lookup speed.
//!
//! Run: `cargo bench --bench smem -- --warm-up-time 1 --measurement-time 3`
//! The tables are measured once per run (wall-clock, single fits) and printed as
//! markdown before criterion's lookup and fit timings. `SMEM_BENCH_MAX_M=25` skips
//! the exhaustive searches of larger grids.
//!
//! The default fit's cost against the table length (issue 25) is measured on
//! tables of 1 000, 10 000 and 100 000 rows like a laser run (trend, ripple
//! and bump, N(0, 0.3 µm) noise; `benches/long_table.py` writes the same shape
//! for `/usr/bin/time -v volcomp fit`): once each for the printed table
//! (`SMEM_BENCH_MAX_ROWS=10000` skips the largest; `cargo test` fits the
//! smallest only), then by criterion at 1 000 and 10 000 rows.
use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput};
use volcomp::nurbs::combinations;
use volcomp::nurbs::synthetic::paper_like_curve;
use volcomp::nurbs::{FitOptions, KnotMethod, ParameterKind, Selection, SmemCurve, fit_parameter};

const SEED: u64 = 3;
const CONTROL_POINTS: usize = 10;

fn fit(method: KnotMethod, grid: Option<usize>, weights: bool) -> (SmemCurve, f64) {
    let (x, y) = paper_like_curve(SEED);
    let options = FitOptions {
        method,
        control_points: Some(CONTROL_POINTS),
        grid_segments: grid,
        optimise_weights: weights,
        tolerance: Some(0.0),
        exhaustive_limit: u64::MAX,
        select: Selection::Emax,
        ..FitOptions::default()
    };
    let t = Instant::now();
    let curve = fit_parameter(&x, &y, ParameterKind::Length, &options).expect("fit");
    (curve, t.elapsed().as_secs_f64())
}

fn table3() {
    println!(
        "\n### Table 3 shape: knot methods, 40 points, p = 3, 10 control points (unit weights; ga/best on M = 13)\n"
    );
    println!("| method | Emax (um) | Erms (um) | time (s) |");
    println!("|---|---|---|---|");
    for method in KnotMethod::ALL {
        let grid = matches!(
            method,
            KnotMethod::Ga | KnotMethod::Exhaustive | KnotMethod::Best
        )
        .then_some(13);
        let (c, t) = fit(method, grid, false);
        println!(
            "| {} | {:.3} | {:.3} | {:.4} |",
            method,
            c.stats().emax,
            c.stats().erms,
            t
        );
    }
    println!("\nWith weight optimisation (ga: weight GA; best: compass search on ln w):\n");
    println!("| method | Emax (um) | Erms (um) | time (s) |");
    println!("|---|---|---|---|");
    for method in [KnotMethod::Ga, KnotMethod::Best] {
        let (c, t) = fit(method, Some(13), true);
        println!(
            "| {} + weights | {:.3} | {:.3} | {:.4} |",
            method,
            c.stats().emax,
            c.stats().erms,
            t
        );
    }
}

fn table4() {
    let max_m: usize = std::env::var("SMEM_BENCH_MAX_M")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(33);
    println!(
        "\n### Table 4 shape: exhaustive vs GA vs best on the grid M (10 control points, unit weights)\n"
    );
    println!(
        "| M | C(M-1,6) | exhaustive Emax | t (s) | GA Emax | t (s) | GA - exh. | best Emax | t (s) | best - exh. |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for m in [13usize, 20, 25, 33] {
        let count = combinations(m - 1, CONTROL_POINTS - 4);
        let (ga, tga) = fit(KnotMethod::Ga, Some(m), false);
        let (best, tb) = fit(KnotMethod::Best, Some(m), false);
        if m > max_m {
            println!(
                "| {m} | {count} | (skipped) | | {:.3} | {:.3} | | {:.3} | {:.4} | |",
                ga.stats().emax,
                tga,
                best.stats().emax,
                tb
            );
            continue;
        }
        let (ex, tex) = fit(KnotMethod::Exhaustive, Some(m), false);
        let e = ex.stats().emax;
        println!(
            "| {m} | {count} | {:.3} | {:.3} | {:.3} | {:.3} | {:+.3} | {:.3} | {:.4} | {:+.3} |",
            e,
            tex,
            ga.stats().emax,
            tga,
            ga.stats().emax - e,
            best.stats().emax,
            tb,
            best.stats().emax - e
        );
    }
}

/// A laser run of `rows` points over −200…200 mm (seeded; the shape of
/// `benches/long_table.py`).
fn long_table(rows: usize) -> (Vec<f64>, Vec<f64>) {
    use rand::SeedableRng;
    use rand_distr::{Distribution, Normal};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(25);
    let noise = Normal::new(0.0, 0.3).expect("valid normal");
    let x: Vec<f64> = (0..rows)
        .map(|i| -200.0 + 400.0 * i as f64 / (rows - 1) as f64)
        .collect();
    let y = x
        .iter()
        .map(|&x| {
            0.02 * x - 2e-5 * x * x
                + 3.0 * (x / 40.0).sin()
                + 4.0 * (-((x - 35.0) / 20.0).powi(2)).exp()
                + noise.sample(&mut rng)
        })
        .collect();
    (x, y)
}

fn scaling() {
    // `cargo test` runs this bench once as a test: the smallest table only.
    let benching = std::env::args().any(|a| a == "--bench");
    let max_rows: usize = std::env::var("SMEM_BENCH_MAX_ROWS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(if benching { 100_000 } else { 1_000 });
    println!("\n### The default fit (--select cv) against the table length\n");
    println!("| rows | time (s) | control points | dof | noise (um) | cv (um) |");
    println!("|---|---|---|---|---|---|");
    for rows in [1_000usize, 10_000, 100_000] {
        if rows > max_rows {
            continue;
        }
        let (x, y) = long_table(rows);
        let t = Instant::now();
        let c = fit_parameter(&x, &y, ParameterKind::Length, &FitOptions::default()).expect("fit");
        let s = c.stats();
        println!(
            "| {rows} | {:.3} | {} | {:.1} | {:.3} | {:.3} |",
            t.elapsed().as_secs_f64(),
            s.control_points,
            s.dof,
            s.noise,
            s.cv_error
        );
    }
}

fn criterion_benches(c: &mut Criterion) {
    let (curve, _) = fit(KnotMethod::Best, None, true);
    let (x0, x1) = curve.domain();
    let queries: Vec<f64> = (0..1024)
        .map(|i| x0 + (x1 - x0) * ((i * 7919) % 1024) as f64 / 1023.0)
        .collect();
    let mut group = c.benchmark_group("lookup");
    group.throughput(Throughput::Elements(queries.len() as u64));
    group.bench_function("value_at x1024", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for &q in &queries {
                s += curve.value_at(black_box(q));
            }
            s
        })
    });
    // The default fit (--select cv): a penalised B-spline, x(u) linear.
    let (cx, cy) = paper_like_curve(SEED);
    let cv = fit_parameter(&cx, &cy, ParameterKind::Length, &FitOptions::default()).expect("fit");
    group.bench_function("value_at x1024, default cv fit", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for &q in &queries {
                s += cv.value_at(black_box(q));
            }
            s
        })
    });
    // Baseline in the same run: the paper's binary search on u (bisection to 1e-12).
    let nurbs = curve.curve().clone();
    group.bench_function("bisection x1024 (baseline)", |b| {
        b.iter(|| {
            let mut s = 0.0;
            for &q in &queries {
                let (mut lo, mut hi) = (0.0, 1.0);
                while hi - lo > 1e-12 {
                    let mid = 0.5 * (lo + hi);
                    if nurbs.eval(mid)[0] < black_box(q) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                s += nurbs.eval(0.5 * (lo + hi))[1];
            }
            s
        })
    });
    group.finish();
    let (x, y) = paper_like_curve(SEED);
    let problem =
        volcomp::nurbs::FitProblem::new(&x, &y, 3, volcomp::nurbs::Parameterization::Centripetal);
    let interior = volcomp::nurbs::uniform(9, 3);
    c.bench_function("evaluate one knot vector (LS + lookup + errors)", |b| {
        b.iter(|| problem.emax(black_box(&interior), &[1.0; 10]))
    });
    let mut group = c.benchmark_group("fit 40 points, 10 control points");
    group.sample_size(10);
    for method in [KnotMethod::Ukm, KnotMethod::Ga, KnotMethod::Best] {
        group.bench_function(method.name(), |b| b.iter(|| fit(method, Some(13), false)));
    }
    group.bench_function("cv (default, count and smoothness chosen)", |b| {
        b.iter(|| fit_parameter(&cx, &cy, ParameterKind::Length, &FitOptions::default()))
    });
    group.finish();
    let mut group = c.benchmark_group("cv fit of a long table");
    group.sample_size(10);
    for rows in [1_000usize, 10_000] {
        let (x, y) = long_table(rows);
        group.throughput(Throughput::Elements(rows as u64));
        group.bench_function(format!("{rows} rows"), |b| {
            b.iter(|| fit_parameter(&x, &y, ParameterKind::Length, &FitOptions::default()))
        });
    }
    group.finish();
}

fn main() {
    scaling();
    table3();
    table4();
    let mut c = Criterion::default().configure_from_args();
    criterion_benches(&mut c);
    c.final_summary();
}
