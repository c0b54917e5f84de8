//! A fast, verified stand-in for the exact SMEM lookups of one axis: the six fitted
//! curves resampled on a uniform grid of positions as cubic Hermite pieces (value
//! and exact slope `y'(u)/x'(u)` at every node, from the exact lookups).
//!
//! Why: the exact lookup inverts `x(u) = position` by Newton's method on every call
//! (~0.2 µs each, 30 per pose); the resampled axis needs one index computation and
//! four basis weights shared by its six curves.
//!
//! Invariant (checked when built): at three interior points of every interval (¼, ½,
//! ¾) the resampled value differs from the exact lookup by at most
//! [`RESAMPLE_TOLERANCE`] (table units, µm or µrad) for every curve; the grid is
//! refined by doubling until that holds, and [`ResampledAxis::build`] returns `None`
//! (callers keep the exact lookup) if it does not hold at [`MAX_INTERVALS`].
use crate::nurbs::SmemCurve;

/// Largest accepted difference from the exact lookup, µm or µrad (1 pm / 1 prad:
/// nine orders below the tables' own noise).
pub const RESAMPLE_TOLERANCE: f64 = 1e-6;
/// First grid tried (intervals over the table's range).
pub const MIN_INTERVALS: usize = 512;
/// Finest grid tried.
pub const MAX_INTERVALS: usize = 1 << 16;

/// Six curves of one axis resampled (see the module doc). Unmeasured curves are 0.
#[derive(Clone, Debug)]
pub struct ResampledAxis {
    lo: f64,
    hi: f64,
    /// Intervals per unit position.
    inv_h: f64,
    intervals: usize,
    /// Per node: six values, then six slopes multiplied by the interval length.
    nodes: Vec<[f64; 12]>,
    /// Largest difference from the exact lookup seen in the check.
    max_deviation: f64,
}

impl ResampledAxis {
    /// Resample `curves` over `[lo, hi]`, refining until the check passes.
    pub fn build(curves: &[Option<SmemCurve>; 6], lo: f64, hi: f64) -> Option<ResampledAxis> {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return None;
        }
        let mut intervals = MIN_INTERVALS;
        while intervals <= MAX_INTERVALS {
            let table = Self::sample(curves, lo, hi, intervals);
            if let Some(deviation) = table.check(curves) {
                return Some(ResampledAxis {
                    max_deviation: deviation,
                    ..table
                });
            }
            intervals *= 2;
        }
        None
    }

    fn sample(
        curves: &[Option<SmemCurve>; 6],
        lo: f64,
        hi: f64,
        intervals: usize,
    ) -> ResampledAxis {
        let h = (hi - lo) / intervals as f64;
        let nodes = (0..=intervals)
            .map(|i| {
                let x = if i == intervals {
                    hi
                } else {
                    lo + i as f64 * h
                };
                let mut node = [0.0; 12];
                for (k, curve) in curves.iter().enumerate() {
                    if let Some(curve) = curve {
                        node[k] = curve.value_at(x);
                        node[6 + k] = curve.slope_at(x) * h;
                    }
                }
                node
            })
            .collect();
        ResampledAxis {
            lo,
            hi,
            inv_h: intervals as f64 / (hi - lo),
            intervals,
            nodes,
            max_deviation: 0.0,
        }
    }

    /// Largest deviation at the check points, or `None` above the tolerance.
    fn check(&self, curves: &[Option<SmemCurve>; 6]) -> Option<f64> {
        let h = (self.hi - self.lo) / self.intervals as f64;
        let mut worst = 0.0f64;
        for i in 0..self.intervals {
            for t in [0.25, 0.5, 0.75] {
                let x = self.lo + (i as f64 + t) * h;
                let got = self.eval(x);
                for (k, curve) in curves.iter().enumerate() {
                    if let Some(curve) = curve {
                        let d = (got[k] - curve.value_at(x)).abs();
                        if d.is_nan() || d > RESAMPLE_TOLERANCE {
                            return None;
                        }
                        worst = worst.max(d);
                    }
                }
            }
        }
        Some(worst)
    }

    /// The six values at `position` (clamped to the range).
    #[inline]
    pub fn eval(&self, position: f64) -> [f64; 6] {
        let mut out = [0.0; 6];
        self.eval_into(position, &mut out);
        out
    }

    /// [`Self::eval`] written into `out`.
    #[inline]
    pub fn eval_into(&self, position: f64, out: &mut [f64; 6]) {
        let s = ((position - self.lo) * self.inv_h).clamp(0.0, self.intervals as f64);
        let i = (s as usize).min(self.intervals - 1);
        let t = s - i as f64;
        let t2 = t * t;
        let t3 = t2 * t;
        let h00 = 2.0 * t3 - 3.0 * t2 + 1.0;
        let h10 = t3 - 2.0 * t2 + t;
        let h01 = -2.0 * t3 + 3.0 * t2;
        let h11 = t3 - t2;
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        for (k, o) in out.iter_mut().enumerate() {
            *o = h00 * a[k] + h10 * a[6 + k] + h01 * b[k] + h11 * b[6 + k];
        }
    }

    /// Intervals of the accepted grid.
    pub fn intervals(&self) -> usize {
        self.intervals
    }

    /// Largest difference from the exact lookup found by the check (µm or µrad).
    pub fn max_deviation(&self) -> f64 {
        self.max_deviation
    }
}
