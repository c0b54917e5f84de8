//! Synthetic error tables of a machine whose true errors are known: the
//! generator of the bundled machines other than the reference machine
//! (`machines/bc-trt`, `machines/head-table`, `machines/head-head`) and of the
//! fidelity bench (`examples/fidelity.rs`).
//!
//! Every error parameter of an axis is a smooth truth (a cubic trend, a ripple
//! of 1.5–4 waves over the range, and a bump a few table steps wide; an
//! endless rotary axis measured over 0…360° gets harmonics 1–3 instead, so its
//! curve closes) with amplitude 2–15 µm for lengths and 5–30 µrad for angles,
//! tabulated at the axis' spacing with measurement noise N(0, σ), σ drawn per
//! table in 0.1–0.5 µm / µrad, as an interferometer or autocollimator run would
//! give. Everything is drawn from one seeded ChaCha8 stream, in a fixed order:
//! the same seed and axes give the same tables on every platform.
//!
//! Invariant: no I/O; [`AxisTable::to_csv`] returns the text a caller writes.
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::PI;
use std::fmt::Write as _;

/// A smooth function of one position: an error parameter's truth.
pub type Truth = Box<dyn Fn(f64) -> f64 + Send + Sync>;

/// Positions `lo, lo + step, …, hi`.
pub fn grid(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let n = ((hi - lo) / step).round() as usize;
    (0..=n).map(|i| lo + step * i as f64).collect()
}

/// A smooth truth like a real error parameter on `[lo, hi]`, amplitude `amp`;
/// periodic over a turn when `periodic` (positions in degrees).
pub fn truth(rng: &mut ChaCha8Rng, lo: f64, hi: f64, step: f64, amp: f64, periodic: bool) -> Truth {
    if periodic {
        let h: Vec<(f64, f64)> = (1..=3)
            .map(|k| {
                (
                    amp * rng.random_range(-1.0..1.0) / k as f64,
                    rng.random_range(0.0..2.0 * PI),
                )
            })
            .collect();
        let offset = amp * rng.random_range(-0.5..0.5);
        return Box::new(move |c: f64| {
            let t = c.to_radians();
            offset
                + h.iter()
                    .enumerate()
                    .map(|(k, (a, ph))| a * ((k + 1) as f64 * t + ph).sin())
                    .sum::<f64>()
        });
    }
    let (c1, c2, c3) = (
        amp * rng.random_range(-1.0..1.0),
        amp * rng.random_range(-0.6..0.6),
        amp * rng.random_range(-0.4..0.4),
    );
    let ripple_a = amp * rng.random_range(0.05..0.3);
    let ripple_w = rng.random_range(1.5..4.0) * 2.0 * PI / (hi - lo);
    let ripple_ph = rng.random_range(0.0..2.0 * PI);
    let bump_a = amp * rng.random_range(-0.4..0.4);
    let bump_c = rng.random_range(lo + 0.2 * (hi - lo)..hi - 0.2 * (hi - lo));
    let bump_w = step * rng.random_range(1.0..2.5);
    Box::new(move |x: f64| {
        let t = 2.0 * (x - lo) / (hi - lo) - 1.0;
        c1 * t
            + c2 * t * t
            + c3 * t * t * t
            + ripple_a * (ripple_w * x + ripple_ph).sin()
            + bump_a * (-((x - bump_c) / bump_w).powi(2)).exp()
    })
}

/// How one axis is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AxisSpec {
    /// The axis letter (upper case).
    pub letter: char,
    /// First measured position, mm or degrees.
    pub lo: f64,
    /// Last measured position, mm or degrees.
    pub hi: f64,
    /// Spacing of the measured positions, mm or degrees.
    pub step: f64,
    /// An endless rotary axis measured over one turn (0…360°): the truths
    /// close, and 0° and 360° are one point, measured once.
    pub periodic: bool,
}

/// One parameter of an axis: its truth and its noisy table column.
pub struct Parameter {
    /// `EXX`, `EAC`, …
    pub name: String,
    /// Lengths (µm) for the first three, angles (µrad) for the last three.
    pub is_angle: bool,
    /// Standard deviation σ of the measurement noise, µm or µrad.
    pub noise_sigma: f64,
    /// The table column: the truth at each position plus noise.
    pub noisy: Vec<f64>,
    /// The error function the column was drawn from.
    pub truth: Truth,
}

/// The six parameters of one axis, tabulated.
pub struct AxisTable {
    /// How the axis is measured.
    pub spec: AxisSpec,
    /// The measured positions, `lo` to `hi` by `step`.
    pub positions: Vec<f64>,
    /// The six parameters, `EX?`, `EY?`, `EZ?`, `EA?`, `EB?`, `EC?` in that order.
    pub parameters: Vec<Parameter>,
}

impl AxisTable {
    /// The table as volcomp reads it (formats.md "Error table"), four decimals,
    /// with `header` as leading `#` comment lines.
    pub fn to_csv(&self, header: &str) -> String {
        let mut out = String::new();
        for line in header.lines() {
            let _ = writeln!(out, "# {line}");
        }
        out.push_str("position");
        for p in &self.parameters {
            let _ = write!(out, ",{}", p.name);
        }
        out.push('\n');
        for (i, x) in self.positions.iter().enumerate() {
            let _ = write!(out, "{x:.3}");
            for p in &self.parameters {
                let _ = write!(out, ",{:.4}", p.noisy[i]);
            }
            out.push('\n');
        }
        out
    }
}

/// The six error parameters of every axis in `axes`, drawn in that order from
/// one stream seeded with `seed`.
pub fn machine_tables(seed: u64, axes: &[AxisSpec]) -> Vec<AxisTable> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    axes.iter()
        .map(|&spec| {
            let positions = grid(spec.lo, spec.hi, spec.step);
            let parameters = ["EX", "EY", "EZ", "EA", "EB", "EC"]
                .iter()
                .enumerate()
                .map(|(k, prefix)| {
                    let is_angle = k >= 3;
                    let amp = if is_angle {
                        rng.random_range(5.0..30.0)
                    } else {
                        rng.random_range(2.0..15.0)
                    };
                    let truth = truth(&mut rng, spec.lo, spec.hi, spec.step, amp, spec.periodic);
                    let noise_sigma = rng.random_range(0.1..0.5);
                    let noise = Normal::new(0.0, noise_sigma).expect("sigma > 0");
                    let mut noisy: Vec<f64> = positions
                        .iter()
                        .map(|&x| truth(x) + noise.sample(&mut rng))
                        .collect();
                    if spec.periodic {
                        let last = noisy.len() - 1;
                        noisy[last] = noisy[0];
                    }
                    Parameter {
                        name: format!("{prefix}{}", spec.letter),
                        is_angle,
                        noise_sigma,
                        noisy,
                        truth,
                    }
                })
                .collect();
            AxisTable {
                spec,
                positions,
                parameters,
            }
        })
        .collect()
}

/// A bundled machine made by this generator: its folder under `machines/`,
/// its seed and how each axis is measured (the machine file's limits; an
/// endless C over one turn).
pub struct BundledMachine {
    /// Its folder under `machines/`.
    pub name: &'static str,
    /// The seed of its tables.
    pub seed: u64,
    /// How its five axes are measured (X, Y, Z, then its two rotaries).
    pub axes: [AxisSpec; 5],
}

const fn axis(letter: char, lo: f64, hi: f64, step: f64, periodic: bool) -> AxisSpec {
    AxisSpec {
        letter,
        lo,
        hi,
        step,
        periodic,
    }
}

/// `machines/bc-trt`, `machines/head-table`, `machines/head-head`
/// (`examples/bundled_machines.rs` writes them; a test checks that the
/// committed tables are what it writes).
pub const BUNDLED_MACHINES: [BundledMachine; 3] = [
    BundledMachine {
        name: "bc-trt",
        seed: 24_001,
        axes: [
            axis('X', -200.0, 200.0, 10.0, false),
            axis('Y', -150.0, 150.0, 10.0, false),
            axis('Z', -200.0, 100.0, 10.0, false),
            axis('B', -110.0, 110.0, 5.0, false),
            axis('C', 0.0, 360.0, 10.0, true),
        ],
    },
    BundledMachine {
        name: "head-table",
        seed: 24_002,
        axes: [
            axis('X', -300.0, 300.0, 10.0, false),
            axis('Y', -200.0, 200.0, 10.0, false),
            axis('Z', -250.0, 150.0, 10.0, false),
            axis('B', -100.0, 100.0, 5.0, false),
            axis('C', 0.0, 360.0, 10.0, true),
        ],
    },
    BundledMachine {
        name: "head-head",
        seed: 24_003,
        axes: [
            axis('X', -300.0, 300.0, 10.0, false),
            axis('Y', -200.0, 200.0, 10.0, false),
            axis('Z', -250.0, 150.0, 10.0, false),
            axis('B', -100.0, 100.0, 5.0, false),
            axis('C', -270.0, 270.0, 10.0, false),
        ],
    },
];

impl BundledMachine {
    /// Its tables, with the comment that says where they come from, as
    /// `(file name, text)`: `x.csv`, `y.csv`, …
    pub fn table_files(&self) -> Vec<(String, String)> {
        machine_tables(self.seed, &self.axes)
            .into_iter()
            .map(|t| {
                let header = format!(
                    "Synthetic {} table of machine {}: seed {}, {}..{} every {} (src/machine/synthetic.rs).\n\
                     Regenerate with: cargo run --release --example bundled_machines\n\
                     Noise sigma per column: {}",
                    t.spec.letter,
                    self.name,
                    self.seed,
                    t.spec.lo,
                    t.spec.hi,
                    t.spec.step,
                    t.parameters
                        .iter()
                        .map(|p| format!("{} {:.3}", p.name, p.noise_sigma))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
                (
                    format!("{}.csv", t.spec.letter.to_ascii_lowercase()),
                    t.to_csv(&header),
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_same_seed_gives_the_same_tables_and_periodic_ones_close() {
        let axes = [
            AxisSpec {
                letter: 'X',
                lo: -100.0,
                hi: 100.0,
                step: 10.0,
                periodic: false,
            },
            AxisSpec {
                letter: 'C',
                lo: 0.0,
                hi: 360.0,
                step: 10.0,
                periodic: true,
            },
        ];
        let a = machine_tables(7, &axes);
        let b = machine_tables(7, &axes);
        assert_eq!(a[0].to_csv(""), b[0].to_csv(""));
        assert_eq!(a[1].positions.len(), 37);
        for p in &a[1].parameters {
            assert_eq!(p.noisy[0], p.noisy[36]);
            assert!(((p.truth)(0.0) - (p.truth)(360.0)).abs() < 1e-9);
        }
        assert!(
            a[0].to_csv("")
                .starts_with("position,EXX,EYX,EZX,EAX,EBX,ECX\n-100.000,")
        );
        assert_ne!(machine_tables(8, &axes)[0].to_csv(""), a[0].to_csv(""));
    }
}
