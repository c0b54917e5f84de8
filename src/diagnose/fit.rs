//! Fitting effects to residuals: signature columns over the used points, linear
//! least squares (SVD on unit-RMS columns, minimum-norm where a combination of
//! parameters is not identifiable), `tau` of `thermal_drift` profiled (log grid +
//! golden section), and cross-validation with folds by region and by time.
//!
//! Invariant: every held-out prediction comes from a fit that did not see the
//! point; no intercept is fitted (a constant offset along `n` is the
//! `radius_offset` effect, so it must compete like any other effect).
use super::effects::EffectKind;
use crate::toolpath::PointContext;
use nalgebra::{DMatrix, DVector};

/// One observation: a cut point measured after the part left the machine (a
/// CMM reading, `probe: None`), or a cut point probed again on the machine
/// (a follow-up reading, `n·(Δ_cut − Δ_probe)`; see [`super::followup`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Row<'a> {
    pub cut: &'a PointContext,
    pub probe: Option<&'a PointContext>,
}

impl Row<'_> {
    /// Signature of `kind` at `tau` (appended to `out`): the cut's, less the
    /// probe's for effects that move the probe too.
    pub fn signature(&self, kind: EffectKind, tau: f64, out: &mut Vec<f64>) {
        let start = out.len();
        kind.signature(self.cut, tau, out);
        if let Some(probe) = self.probe.filter(|_| kind.acts_on_probe()) {
            let mut p = Vec::with_capacity(8);
            kind.signature(probe, tau, &mut p);
            for (o, v) in out[start..].iter_mut().zip(p) {
                *o -= v;
            }
        }
    }

    /// The geometric model's prediction of the reading, µm.
    pub fn predicted_um(&self) -> f64 {
        self.cut.predicted_um - self.probe.map_or(0.0, |p| p.predicted_um)
    }

    /// What the model attributes to axis `k`'s tables in the reading, µm.
    pub fn axis_deviation_um(&self, k: usize) -> f64 {
        self.cut.axis_deviation_um[k] - self.probe.map_or(0.0, |p| p.axis_deviation_um[k])
    }
}

/// Signature columns of every effect over the used rows.
pub(crate) struct Signatures {
    n: usize,
    linear: Vec<(EffectKind, Vec<Vec<f64>>)>,
    /// `n·(machine → part of e_k)` for thermal drift, k = x, y, z, at the cut.
    thermal_direction: [Vec<f64>; 3],
    time: Vec<f64>,
    /// The same at the probe of a follow-up row (zero and unused otherwise).
    probe_direction: [Vec<f64>; 3],
    probe_time: Vec<Option<f64>>,
    /// Range searched for `tau`, minutes.
    pub tau_range: (f64, f64),
    /// The error model's own columns (one per measured axis's tables, and the
    /// machine file's position-independent errors): the "model" term of the
    /// selection (a table `k` that is `(1 + β_k)` × the machine's).
    pub model: Vec<Vec<f64>>,
    /// Per effect, the RMS over the rows of each linear column at the
    /// parameter's largest plausible value (`plausible_reach`): the most
    /// that parameter can move the readings on this part, µm.
    reach: Vec<(EffectKind, Vec<f64>)>,
}

impl Signatures {
    pub fn new(rows: &[Row]) -> Signatures {
        let n = rows.len();
        let mut linear = Vec::new();
        let reach = EffectKind::ALL
            .iter()
            .map(|&kind| (kind, plausible_reach(rows, kind)))
            .collect();
        for kind in EffectKind::ALL {
            if kind.is_nonlinear() {
                continue;
            }
            let mut cols = vec![Vec::with_capacity(n); kind.linear_count()];
            let mut values = Vec::with_capacity(8);
            for row in rows {
                values.clear();
                row.signature(kind, 1.0, &mut values);
                for (c, v) in cols.iter_mut().zip(&values) {
                    c.push(*v);
                }
            }
            linear.push((kind, cols));
        }
        let direction = |ctx: &PointContext, k: usize| {
            let mut e = [0.0; 3];
            e[k] = 1.0;
            crate::vec3::dot(ctx.normal, ctx.machine_to_part(e))
        };
        let thermal_direction =
            [0, 1, 2].map(|k| rows.iter().map(|r| direction(r.cut, k)).collect());
        let probe_direction = [0, 1, 2].map(|k| {
            rows.iter()
                .map(|r| r.probe.map_or(0.0, |p| direction(p, k)))
                .collect()
        });
        let time: Vec<f64> = rows.iter().map(|r| r.cut.time_min).collect();
        let probe_time: Vec<Option<f64>> =
            rows.iter().map(|r| r.probe.map(|p| p.time_min)).collect();
        // τ is searched from the cutting times (a follow-up does not widen it).
        let t_max = rows
            .iter()
            .filter(|r| r.probe.is_none())
            .map(|r| r.cut.time_min)
            .fold(0.0f64, f64::max)
            .max(1e-3);
        Signatures {
            n,
            linear,
            thermal_direction,
            time,
            probe_direction,
            probe_time,
            tau_range: ((t_max / 200.0).max(1e-3), 20.0 * t_max),
            model: Vec::new(),
            reach,
        }
    }

    /// Fix at 0 every linear parameter that the part cannot see: one whose
    /// largest plausible effect on the readings could not pay for itself in
    /// the likelihood ratio, `n·reach² / σ² < ln n` (`reach` the RMS of its
    /// column at the parameter's largest plausible value, `σ` the noise
    /// floor). Such a column (a rotation about the axis of a surface of
    /// revolution: zero up to the plan's rounding) would otherwise be scaled
    /// to unit RMS and fitted, giving its effect a free column of noise. Its
    /// column is zeroed (the fit leaves it at 0). The penalty still counts
    /// it (`SetFit::parameter_count`): the price of a hypothesis is what the
    /// catalogue lets it vary, so that it does not jump by `ln n` with the
    /// side of the cut a column falls on. Returns the parameters dropped.
    pub fn drop_invisible(&mut self, noise_um: f64) -> Vec<(EffectKind, usize)> {
        let n = self.n as f64;
        let price = n.max(1.0).ln();
        let mut dropped = Vec::new();
        for (kind, reach) in &self.reach {
            for (j, r) in reach.iter().enumerate() {
                if n * r * r < price * noise_um * noise_um {
                    dropped.push((*kind, j));
                }
            }
        }
        for &(kind, j) in &dropped {
            if kind.is_nonlinear() {
                self.thermal_direction[j].iter_mut().for_each(|v| *v = 0.0);
                self.probe_direction[j].iter_mut().for_each(|v| *v = 0.0);
            } else if let Some((_, cols)) = self.linear.iter_mut().find(|(k, _)| *k == kind) {
                cols[j].iter_mut().for_each(|v| *v = 0.0);
            }
        }
        dropped
    }

    pub fn len(&self) -> usize {
        self.n
    }

    /// Columns of `kind` (for `thermal_drift` at `tau`).
    pub fn columns(&self, kind: EffectKind, tau: f64) -> Vec<Vec<f64>> {
        if kind.is_nonlinear() {
            let growth = |t: f64| 1.0 - (-t / tau).exp();
            let f: Vec<f64> = self.time.iter().map(|t| growth(*t)).collect();
            let fp: Vec<f64> = self
                .probe_time
                .iter()
                .map(|t| t.map_or(0.0, growth))
                .collect();
            (0..3)
                .map(|k| {
                    (0..self.n)
                        .map(|i| {
                            self.thermal_direction[k][i] * f[i] - self.probe_direction[k][i] * fp[i]
                        })
                        .collect()
                })
                .collect()
        } else {
            self.linear
                .iter()
                .find(|(k, _)| *k == kind)
                .map(|(_, c)| c.clone())
                .unwrap_or_default()
        }
    }

    fn design(&self, kinds: &[EffectKind], tau: f64) -> Vec<Vec<f64>> {
        kinds.iter().flat_map(|k| self.columns(*k, tau)).collect()
    }

    /// The design of `kinds`, followed by the model's columns when `model`.
    pub fn design_with(&self, kinds: &[EffectKind], model: bool, tau: f64) -> Vec<Vec<f64>> {
        let mut cols = self.design(kinds, tau);
        if model {
            cols.extend(self.model.iter().cloned());
        }
        cols
    }
}

/// Result of a linear least-squares fit.
#[derive(Clone, Debug)]
pub(crate) struct LinearFit {
    pub coefs: Vec<f64>,
    /// Diagonal of (XᵀX)⁺ in the original units (for standard errors).
    pub inverse_diagonal: Vec<f64>,
    pub sse: f64,
    /// Numerical rank of the design on the fitted rows.
    pub rank: usize,
}

/// Least squares of `y[rows]` on `cols[·][rows]` (minimum norm, relative
/// singular-value cutoff 1e-5 on unit-RMS columns).
pub(crate) fn least_squares(cols: &[Vec<f64>], rows: &[usize], y: &[f64]) -> LinearFit {
    let p = cols.len();
    let m = rows.len();
    let scales: Vec<f64> = cols
        .iter()
        .map(|c| {
            let ss: f64 = rows.iter().map(|&i| c[i] * c[i]).sum();
            (ss / m.max(1) as f64).sqrt()
        })
        .collect();
    let active: Vec<usize> = (0..p).filter(|&j| scales[j] > 1e-12).collect();
    let mut coefs = vec![0.0; p];
    let mut inverse_diagonal = vec![0.0; p];
    let sse_of = |coefs: &[f64]| {
        rows.iter()
            .map(|&i| {
                let f: f64 = (0..p).map(|j| coefs[j] * cols[j][i]).sum();
                (y[i] - f).powi(2)
            })
            .sum::<f64>()
    };
    if active.is_empty() || m == 0 {
        let sse = sse_of(&coefs);
        return LinearFit {
            coefs,
            inverse_diagonal,
            sse,
            rank: 0,
        };
    }
    // Normal equations of the unit-RMS columns, solved through the symmetric
    // eigendecomposition (V Λ Vᵀ): x = V Λ⁺ Vᵀ Xᵀy with λ ≤ (cutoff·√λ_max)²
    // dropped, which is the truncated-SVD solution without forming U.
    let q = active.len();
    let scaled: Vec<Vec<f64>> = active
        .iter()
        .map(|&j| rows.iter().map(|&i| cols[j][i] / scales[j]).collect())
        .collect();
    let yv: Vec<f64> = rows.iter().map(|&i| y[i]).collect();
    let mut ata = DMatrix::zeros(q, q);
    let mut aty = DVector::zeros(q);
    for a in 0..q {
        aty[a] = scaled[a].iter().zip(&yv).map(|(u, v)| u * v).sum();
        for b in a..q {
            let v: f64 = scaled[a].iter().zip(&scaled[b]).map(|(u, v)| u * v).sum();
            ata[(a, b)] = v;
            ata[(b, a)] = v;
        }
    }
    let eig = ata.symmetric_eigen();
    let l_max = eig.eigenvalues.max().max(0.0);
    let cutoff = l_max * 1e-10; // singular values below 1e-5 × the largest
    let rank = eig.eigenvalues.iter().filter(|l| **l > cutoff).count();
    let v = &eig.eigenvectors;
    let vty = v.transpose() * &aty;
    for (c, &j) in active.iter().enumerate() {
        let mut x = 0.0;
        let mut d = 0.0;
        for (k, l) in eig.eigenvalues.iter().enumerate() {
            if *l > cutoff {
                x += v[(c, k)] * vty[k] / l;
                d += v[(c, k)] * v[(c, k)] / l;
            }
        }
        coefs[j] = x / scales[j];
        inverse_diagonal[j] = d / (scales[j] * scales[j]);
    }
    let sse = sse_of(&coefs);
    LinearFit {
        coefs,
        inverse_diagonal,
        sse,
        rank,
    }
}

/// A fitted set of effects.
#[derive(Clone, Debug)]
pub(crate) struct SetFit {
    pub kinds: Vec<EffectKind>,
    /// The model's columns are fitted too (their factors follow the effects'
    /// coefficients in `linear`).
    pub model: bool,
    /// `tau` when the set holds `thermal_drift`.
    pub tau: Option<f64>,
    pub linear: LinearFit,
}

impl SetFit {
    /// Contribution (µm) of the whole set at every used point.
    pub fn contribution(&self, sig: &Signatures) -> Vec<f64> {
        let cols = sig.design_with(&self.kinds, self.model, self.tau.unwrap_or(1.0));
        (0..sig.len())
            .map(|i| {
                cols.iter()
                    .zip(&self.linear.coefs)
                    .map(|(c, b)| c[i] * b)
                    .sum()
            })
            .collect()
    }

    /// Number of free parameters (linear + `tau`).
    pub fn parameter_count(&self) -> usize {
        self.kinds.iter().map(|k| k.parameters().len()).sum()
    }
}

/// Fit a set of effects on `rows` (profiling `tau` when needed).
pub(crate) fn fit_set(sig: &Signatures, kinds: &[EffectKind], rows: &[usize], y: &[f64]) -> SetFit {
    fit_terms(sig, kinds, false, rows, y)
}

/// Fit a set of effects, and the model's columns when `model`, on `rows`.
pub(crate) fn fit_terms(
    sig: &Signatures,
    kinds: &[EffectKind],
    model: bool,
    rows: &[usize],
    y: &[f64],
) -> SetFit {
    let has_tau = kinds.iter().any(|k| k.is_nonlinear());
    if !has_tau {
        return SetFit {
            kinds: kinds.to_vec(),
            model,
            tau: None,
            linear: least_squares(&sig.design_with(kinds, model, 1.0), rows, y),
        };
    }
    let eval = |log_tau: f64| least_squares(&sig.design_with(kinds, model, log_tau.exp()), rows, y);
    let (lo, hi) = (sig.tau_range.0.ln(), sig.tau_range.1.ln());
    const GRID: usize = 16;
    let grid: Vec<f64> = (0..GRID)
        .map(|g| lo + (hi - lo) * g as f64 / (GRID - 1) as f64)
        .collect();
    let sses: Vec<f64> = grid.iter().map(|&g| eval(g).sse).collect();
    let best = (0..GRID)
        .min_by(|&a, &b| sses[a].total_cmp(&sses[b]))
        .unwrap_or(0);
    // Golden section between the grid neighbours of the best grid point.
    let (mut a, mut b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(GRID - 1)]);
    let ratio = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - ratio * (b - a);
    let mut d = a + ratio * (b - a);
    let (mut fc, mut fd) = (eval(c).sse, eval(d).sse);
    for _ in 0..20 {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - ratio * (b - a);
            fc = eval(c).sse;
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + ratio * (b - a);
            fd = eval(d).sse;
        }
    }
    let mut log_tau = 0.5 * (a + b);
    let mut linear = eval(log_tau);
    if sses[best] < linear.sse {
        log_tau = grid[best];
        linear = eval(log_tau);
    }
    SetFit {
        kinds: kinds.to_vec(),
        model,
        tau: Some(log_tau.exp()),
        linear,
    }
}

/// Cross-validation folds: each scheme partitions the used points.
#[derive(Clone, Debug)]
pub(crate) struct Folds {
    /// (scheme name, folds as lists of held-out rows).
    pub schemes: Vec<(&'static str, Vec<Vec<usize>>)>,
}

impl Folds {
    /// Region folds (a 3 × 3 grid of the plan by x and y terciles) and time
    /// folds (`k` contiguous bands of equal point count, in cutting order).
    pub fn new(contexts: &[&PointContext], k: usize) -> Folds {
        // (A follow-up row is passed as its cut point: it falls in that
        // point's folds, so a point and its re-probe are held out together.)
        let n = contexts.len();
        let terciles = |axis: usize| {
            let mut v: Vec<f64> = contexts.iter().map(|c| c.point[axis]).collect();
            v.sort_by(f64::total_cmp);
            let at = |f: f64| {
                v.get(((n as f64 * f) as usize).min(n.saturating_sub(1)))
                    .copied()
                    .unwrap_or(0.0)
            };
            [at(1.0 / 3.0), at(2.0 / 3.0)]
        };
        let (tx, ty) = (terciles(0), terciles(1));
        let band = |v: f64, t: [f64; 2]| usize::from(v >= t[0]) + usize::from(v >= t[1]);
        let mut region = vec![Vec::new(); 9];
        for (i, c) in contexts.iter().enumerate() {
            region[band(c.point[0], tx) + 3 * band(c.point[1], ty)].push(i);
        }
        region.retain(|f| !f.is_empty());
        let mut order: Vec<usize> = (0..n).collect();
        order.sort_by(|&a, &b| {
            contexts[a]
                .time_min
                .total_cmp(&contexts[b].time_min)
                .then(a.cmp(&b))
        });
        let k = k.max(2);
        let mut time = vec![Vec::new(); k];
        for (rank, &i) in order.iter().enumerate() {
            time[(rank * k / n.max(1)).min(k - 1)].push(i);
        }
        time.retain(|f| !f.is_empty());
        Folds {
            schemes: vec![("region", region), ("time", time)],
        }
    }
}

/// Held-out mean squared error over all schemes: each point is predicted once
/// per scheme by `predict(train)`, a predictor fitted without it. A fold whose
/// complement is empty is predicted as zero.
fn heldout_mse<P: Fn(usize) -> f64>(
    folds: &Folds,
    n: usize,
    y: &[f64],
    fit: impl Fn(&[usize]) -> P,
) -> f64 {
    let mut sse = 0.0;
    let mut count = 0usize;
    for (_, scheme) in &folds.schemes {
        let mut held = vec![false; n];
        for fold in scheme {
            for &i in fold {
                held[i] = true;
            }
            let train: Vec<usize> = (0..n).filter(|&i| !held[i]).collect();
            for &i in fold {
                held[i] = false;
            }
            if train.is_empty() {
                sse += fold.iter().map(|&i| y[i] * y[i]).sum::<f64>();
                count += fold.len();
                continue;
            }
            let predict = fit(&train);
            for &i in fold {
                sse += (y[i] - predict(i)).powi(2);
                count += 1;
            }
        }
    }
    sse / count.max(1) as f64
}

/// Held-out mean squared error of a set of effects over all schemes (each point
/// is predicted once per scheme by a fit that did not see it).
pub(crate) fn cross_validate(
    sig: &Signatures,
    folds: &Folds,
    kinds: &[EffectKind],
    y: &[f64],
) -> f64 {
    cross_validate_terms(sig, folds, kinds, false, y)
}

/// [`cross_validate`] of a set of effects and, when `model`, the model's columns.
pub(crate) fn cross_validate_terms(
    sig: &Signatures,
    folds: &Folds,
    kinds: &[EffectKind],
    model: bool,
    y: &[f64],
) -> f64 {
    heldout_mse(folds, sig.len(), y, |train| {
        let fit = fit_terms(sig, kinds, model, train, y);
        let cols = sig.design_with(kinds, model, fit.tau.unwrap_or(1.0));
        move |i| {
            cols.iter()
                .zip(&fit.linear.coefs)
                .map(|(c, b)| c[i] * b)
                .sum()
        }
    })
}

/// How much of each column stands apart from the others: the RMS of column
/// `j` outside the span of the other columns, over its own RMS (0: a
/// rank-deficient direction, one that the rows cannot identify).
pub(crate) fn column_independence(cols: &[Vec<f64>]) -> Vec<f64> {
    let n = cols.first().map_or(0, |c| c.len());
    let rows: Vec<usize> = (0..n).collect();
    (0..cols.len())
        .map(|j| {
            let own: f64 = cols[j].iter().map(|v| v * v).sum();
            // A column that vanishes on the rows (as least_squares drops it).
            if (own / n.max(1) as f64).sqrt() <= 1e-12 {
                return 0.0;
            }
            let others: Vec<Vec<f64>> = cols
                .iter()
                .enumerate()
                .filter(|(k, _)| *k != j)
                .map(|(_, c)| c.clone())
                .collect();
            if others.is_empty() {
                return 1.0;
            }
            let fit = least_squares(&others, &rows, &cols[j]);
            (fit.sse.max(0.0) / own).sqrt()
        })
        .collect()
}

/// The RMS over `rows` of each linear column of `kind` at its parameter's
/// largest plausible value (µm): an angle at `MAX_ANGLE_URAD`, an offset at
/// `MAX_OFFSET_UM` (`plausibility`); a parameter of another unit (servo lag's
/// `k`, wear's `w`) at the value whose displacement reaches `MAX_OFFSET_UM`
/// at some point of the part. For `thermal_drift`, the drift directions at
/// full growth (`tau` → 0).
fn plausible_reach(rows: &[Row], kind: EffectKind) -> Vec<f64> {
    use super::plausibility::{MAX_ANGLE_URAD, MAX_OFFSET_UM};
    let count = kind.linear_count();
    let mut sum2 = vec![0.0; count];
    let mut largest = vec![0.0f64; count];
    let (mut basis, mut values) = (Vec::with_capacity(8), Vec::with_capacity(8));
    for row in rows {
        basis.clear();
        values.clear();
        // τ → 0: the drift at full growth (1 − e^(−t/τ) = 1 for t > 0).
        let tau = 1e-9;
        kind.basis(row.cut, tau, &mut basis);
        row.signature(kind, tau, &mut values);
        for j in 0..count {
            let b = basis.get(j).copied().unwrap_or([0.0; 3]);
            largest[j] = largest[j].max(crate::vec3::dot(b, b).sqrt());
            let v = values.get(j).copied().unwrap_or(0.0);
            sum2[j] += v * v;
        }
    }
    let n = rows.len().max(1) as f64;
    let units = kind.units();
    (0..count)
        .map(|j| {
            let bound = match units.get(j).copied() {
                Some("µrad") => MAX_ANGLE_URAD,
                Some("µm") => MAX_OFFSET_UM,
                _ if largest[j] > 0.0 => MAX_OFFSET_UM / largest[j],
                _ => 0.0,
            };
            bound * (sum2[j] / n).sqrt()
        })
        .collect()
}
