//! Symmetric matrices that are banded but for a few dense trailing rows (a band
//! with a border), their `LDLᵀ` factorisation, solves, and the elements of the
//! inverse on the factor's pattern (Takahashi et al. 1973; for a band alone,
//! Hutchinson & de Hoog 1985).
//!
//! These are the normal equations of a penalised B-spline fit (`smoothing`):
//! every table point touches `p + 1` consecutive coefficients and the penalty
//! couples coefficients at most `p` apart, so `BᵀB + λP` is banded with
//! half-width `p`. A periodic curve adds a border: its first coefficients are
//! tied to its last ones. Eliminating the band first, the border rows fill in
//! (they are stored dense) and the band does not, so every operation costs
//! `O(n (w + r)²)` for `n` unknowns, half-width `w` and `r` border rows.
//!
//! Layout: rows `0..main` are band rows, holding `A[i][i − d]` for
//! `d = 0..=w`; rows `main..n` are border rows, holding `A[b][j]` for every
//! `j ≤ b`. Only the lower triangle is stored; entries outside the pattern are
//! zero by construction (the caller adds band-row entries within the band).
//!
//! Invariants: no I/O, no panics for any input of a valid shape; a factor
//! exists only when every pivot exceeds the caller's tolerance, so every
//! solve and inverse is finite.

/// A symmetric band-with-border matrix (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct BandBorder {
    n: usize,
    main: usize,
    w: usize,
    /// `main × (w + 1)`: `band[i (w + 1) + d] = A[i][i − d]`.
    band: Vec<f64>,
    /// `(n − main) × n`: `border[t n + j] = A[main + t][j]`, `j ≤ main + t`.
    border: Vec<f64>,
}

impl BandBorder {
    /// The zero matrix of `n` rows: `main` band rows of half-width `w`, then
    /// `n − main` border rows.
    pub fn zeros(n: usize, main: usize, w: usize) -> BandBorder {
        let main = main.min(n);
        BandBorder {
            n,
            main,
            w,
            band: vec![0.0; main * (w + 1)],
            border: vec![0.0; (n - main) * n],
        }
    }

    /// The zero matrix of the same shape.
    pub fn zeros_like(&self) -> BandBorder {
        BandBorder::zeros(self.n, self.main, self.w)
    }

    /// `A[i][j]` (either order; zero outside the pattern).
    #[inline]
    pub fn get(&self, i: usize, j: usize) -> f64 {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        if i >= self.main {
            self.border[(i - self.main) * self.n + j]
        } else if i - j <= self.w {
            self.band[i * (self.w + 1) + i - j]
        } else {
            0.0
        }
    }

    #[inline]
    fn slot(&mut self, i: usize, j: usize) -> &mut f64 {
        let (i, j) = if i >= j { (i, j) } else { (j, i) };
        if i >= self.main {
            &mut self.border[(i - self.main) * self.n + j]
        } else {
            debug_assert!(i - j <= self.w, "({i}, {j}) outside the band");
            &mut self.band[i * (self.w + 1) + i - j]
        }
    }

    /// `A += s · v vᵀ` for the sparse vector `v` (`(index, value)` pairs; an
    /// index may repeat). Two indices below `main` must lie within the band.
    pub fn add_outer(&mut self, v: &[(usize, f64)], s: f64) {
        for &(i, a) in v {
            for &(j, b) in v {
                if i >= j {
                    *self.slot(i, j) += s * a * b;
                }
            }
        }
    }

    /// `self + s · other` (same shape).
    #[cfg(test)]
    pub fn plus_scaled(&self, other: &BandBorder, s: f64) -> BandBorder {
        let mut out = self.clone();
        out.add_scaled(other, s);
        out
    }

    /// `self += s · other` (same shape).
    #[cfg(test)]
    pub fn add_scaled(&mut self, other: &BandBorder, s: f64) {
        debug_assert!(self.n == other.n && self.main == other.main && self.w == other.w);
        for (a, b) in self.band.iter_mut().zip(&other.band) {
            *a += s * b;
        }
        for (a, b) in self.border.iter_mut().zip(&other.border) {
            *a += s * b;
        }
    }

    /// Overwrite with `a + s · b` (all three of one shape), without allocating.
    pub fn assign_sum(&mut self, a: &BandBorder, b: &BandBorder, s: f64) {
        for ((o, x), y) in self.band.iter_mut().zip(&a.band).zip(&b.band) {
            *o = x + s * y;
        }
        for ((o, x), y) in self.border.iter_mut().zip(&a.border).zip(&b.border) {
            *o = x + s * y;
        }
    }

    /// Largest diagonal element.
    pub fn max_diagonal(&self) -> f64 {
        (0..self.n).map(|i| self.get(i, i)).fold(0.0, f64::max)
    }

    /// `A x`.
    pub fn mul_vec(&self, x: &[f64]) -> Vec<f64> {
        let (n, main, w) = (self.n, self.main, self.w);
        let s = w + 1;
        let mut y = vec![0.0; n];
        for i in 0..main {
            let row = &self.band[i * s..(i + 1) * s];
            y[i] += row[0] * x[i];
            for d in 1..=w.min(i) {
                y[i] += row[d] * x[i - d];
                y[i - d] += row[d] * x[i];
            }
        }
        for t in 0..n - main {
            let b = main + t;
            let row = &self.border[t * n..(t + 1) * n];
            y[b] += row[b] * x[b];
            for j in 0..b {
                y[b] += row[j] * x[j];
                y[j] += row[j] * x[b];
            }
        }
        y
    }

    /// `xᵀ A x`.
    pub fn quadratic_form(&self, x: &[f64]) -> f64 {
        let (n, main, w) = (self.n, self.main, self.w);
        let s = w + 1;
        let (mut diagonal, mut off) = (0.0, 0.0);
        for i in 0..main {
            let row = &self.band[i * s..(i + 1) * s];
            diagonal += row[0] * x[i] * x[i];
            let mut acc = 0.0;
            for d in 1..=w.min(i) {
                acc += row[d] * x[i - d];
            }
            off += acc * x[i];
        }
        for t in 0..n - main {
            let b = main + t;
            let row = &self.border[t * n..(t + 1) * n];
            diagonal += row[b] * x[b] * x[b];
            let acc: f64 = row[..b].iter().zip(&x[..b]).map(|(a, v)| a * v).sum();
            off += acc * x[b];
        }
        diagonal + 2.0 * off
    }

    /// `Σᵢⱼ A_ij B_ij` over the pattern, which is `tr(A B)` for symmetric `A`
    /// and `B` whose product's diagonal only involves pattern entries (as for
    /// `B` = a matrix of this shape and `A` its inverse on the pattern).
    pub fn trace_product(&self, other: &BandBorder) -> f64 {
        let (n, main, w) = (self.n, self.main, self.w);
        let s = w + 1;
        let mut diagonal = 0.0;
        let mut off = 0.0;
        for i in 0..main {
            diagonal += self.band[i * s] * other.band[i * s];
            for d in 1..=w.min(i) {
                off += self.band[i * s + d] * other.band[i * s + d];
            }
        }
        for t in 0..n - main {
            let b = main + t;
            diagonal += self.border[t * n + b] * other.border[t * n + b];
            for j in 0..b {
                off += self.border[t * n + j] * other.border[t * n + j];
            }
        }
        diagonal + 2.0 * off
    }

    /// `A = L D Lᵀ` (`L` unit lower triangular, on `A`'s pattern), or `None`
    /// when a pivot `D_i` is not above `tolerance` (or not finite).
    pub fn factor(&self, tolerance: f64) -> Option<Ldl> {
        let mut ldl = Ldl::buffer(self);
        ldl.m.clone_from(self);
        ldl.factor_in_place(tolerance).then_some(ldl)
    }

    /// [`BandBorder::factor`] into `self` (no allocation); `false` when a pivot
    /// fails (then `self` holds a partial factor).
    fn factor_in_place(&mut self, tolerance: f64) -> bool {
        let (n, main, w) = (self.n, self.main, self.w);
        let s = w + 1;
        let ok = |d: f64| d > tolerance && d.is_finite();
        for i in 0..main {
            let lo = i.saturating_sub(w);
            for j in lo..i {
                let mut acc = self.band[i * s + i - j];
                for l in lo..j {
                    acc -= self.band[i * s + i - l] * self.band[j * s + j - l] * self.band[l * s];
                }
                self.band[i * s + i - j] = acc / self.band[j * s];
            }
            let mut d = self.band[i * s];
            for l in lo..i {
                let v = self.band[i * s + i - l];
                d -= v * v * self.band[l * s];
            }
            if !ok(d) {
                return false;
            }
            self.band[i * s] = d;
        }
        for t in 0..n - main {
            let b = main + t;
            for j in 0..b {
                let mut acc = self.border[t * n + j];
                if j < main {
                    for l in j.saturating_sub(w)..j {
                        acc -= self.border[t * n + l] * self.band[j * s + j - l] * self.diagonal(l);
                    }
                } else {
                    let u = j - main;
                    for l in 0..j {
                        acc -= self.border[t * n + l] * self.border[u * n + l] * self.diagonal(l);
                    }
                }
                self.border[t * n + j] = acc / self.diagonal(j);
            }
            let mut d = self.border[t * n + b];
            for l in 0..b {
                let v = self.border[t * n + l];
                d -= v * v * self.diagonal(l);
            }
            if !ok(d) {
                return false;
            }
            self.border[t * n + b] = d;
        }
        true
    }

    #[inline]
    fn diagonal(&self, i: usize) -> f64 {
        if i < self.main {
            self.band[i * (self.w + 1)]
        } else {
            self.border[(i - self.main) * self.n + i]
        }
    }
}

/// `A = L D Lᵀ` on the band-with-border pattern: `L` below the diagonal, `D` on it.
#[derive(Clone, Debug)]
pub struct Ldl {
    m: BandBorder,
    /// `1 / D_i` (filled by the half-width-3 band path, else empty).
    inv: Vec<f64>,
}

impl Ldl {
    /// Storage for factors of matrices shaped like `shape` (no factor yet:
    /// use [`Ldl::refactor`] before anything else).
    pub fn buffer(shape: &BandBorder) -> Ldl {
        Ldl {
            m: shape.zeros_like(),
            inv: vec![0.0; shape.n],
        }
    }

    /// Factor `a + s · b` (both of this buffer's shape) in place, without
    /// allocating; `false` when a pivot is not above `tolerance` (then the
    /// buffer holds no usable factor).
    pub fn refactor(&mut self, a: &BandBorder, b: &BandBorder, s: f64, tolerance: f64) -> bool {
        self.m.assign_sum(a, b, s);
        self.factor_in_place(tolerance)
    }

    fn factor_in_place(&mut self, tolerance: f64) -> bool {
        if self.m.w == 3 && self.m.main == self.m.n {
            return cubic::factor(&mut self.m.band, &mut self.inv, tolerance);
        }
        self.m.factor_in_place(tolerance)
    }

    /// `x` with `A x = b`.
    pub fn solve(&self, b: &[f64]) -> Vec<f64> {
        let mut x = b.to_vec();
        self.solve_in_place(&mut x);
        x
    }

    /// [`Ldl::solve`] in place: `x` holds `b` on entry, the solution on exit.
    pub fn solve_in_place(&self, x: &mut [f64]) {
        let m = &self.m;
        let (n, main, w) = (m.n, m.main, m.w);
        let s = w + 1;
        if w == 3 && main == n {
            cubic::solve(&m.band, &self.inv, x);
            return;
        }
        for i in 0..main {
            let mut acc = x[i];
            for l in i.saturating_sub(w)..i {
                acc -= m.band[i * s + i - l] * x[l];
            }
            x[i] = acc;
        }
        for t in 0..n - main {
            let b = main + t;
            let acc: f64 = m.border[t * n..t * n + b]
                .iter()
                .zip(&x[..b])
                .map(|(a, v)| a * v)
                .sum();
            x[b] -= acc;
        }
        for (i, v) in x.iter_mut().enumerate() {
            *v /= m.diagonal(i);
        }
        for i in (0..n).rev() {
            let mut acc = x[i];
            for t in 0..n - main {
                let l = main + t;
                if l > i {
                    acc -= m.border[t * n + i] * x[l];
                }
            }
            if i < main {
                for l in i + 1..=(i + w).min(main - 1) {
                    acc -= m.band[l * s + l - i] * x[l];
                }
            }
            x[i] = acc;
        }
    }

    /// The elements of `A⁻¹` on `A`'s pattern (Takahashi's recurrence
    /// `Σ = D⁻¹ L⁻¹ + (I − Lᵀ) Σ`, from the last row up), in `out` (same
    /// shape; overwritten).
    pub fn inverse_on_pattern_into(&self, out: &mut BandBorder) {
        let m = &self.m;
        let (n, main, w) = (m.n, m.main, m.w);
        let s = w + 1;
        let r = n - main;
        if w == 3 && main == n {
            cubic::inverse(&m.band, &self.inv, &mut out.band);
            return;
        }
        // Border columns: column i of L is non-zero in every row below it.
        for i in (main..n).rev() {
            let ti = i - main;
            for j in i + 1..n {
                let tj = j - main;
                let mut acc = 0.0;
                for l in i + 1..n {
                    let sigma = if l >= j {
                        out.border[(l - main) * n + j]
                    } else {
                        out.border[tj * n + l]
                    };
                    acc -= m.border[(l - main) * n + i] * sigma;
                }
                out.border[tj * n + i] = acc;
            }
            let mut d = 1.0 / m.border[ti * n + i];
            for l in i + 1..n {
                d -= m.border[(l - main) * n + i] * out.border[(l - main) * n + i];
            }
            out.border[ti * n + i] = d;
        }
        // Band columns: non-zero in the next w band rows and the border rows.
        for i in (0..main).rev() {
            let hi = (i + w).min(main - 1);
            for j in i + 1..=hi {
                let mut acc = 0.0;
                for l in i + 1..=hi {
                    let sigma = if l >= j {
                        out.band[l * s + l - j]
                    } else {
                        out.band[j * s + j - l]
                    };
                    acc -= m.band[l * s + l - i] * sigma;
                }
                for t in 0..r {
                    acc -= m.border[t * n + i] * out.border[t * n + j];
                }
                out.band[j * s + j - i] = acc;
            }
            for tb in 0..r {
                let b = main + tb;
                let mut acc = 0.0;
                for l in i + 1..=hi {
                    acc -= m.band[l * s + l - i] * out.border[tb * n + l];
                }
                for t in 0..r {
                    let l = main + t;
                    let sigma = if l >= b {
                        out.border[t * n + b]
                    } else {
                        out.border[tb * n + l]
                    };
                    acc -= m.border[t * n + i] * sigma;
                }
                out.border[tb * n + i] = acc;
            }
            let mut d = 1.0 / m.band[i * s];
            for l in i + 1..=hi {
                d -= m.band[l * s + l - i] * out.band[l * s + l - i];
            }
            for t in 0..r {
                d -= m.border[t * n + i] * out.border[t * n + i];
            }
            out.band[i * s] = d;
        }
    }

    /// The elements of `A⁻¹` on `A`'s pattern.
    #[cfg(test)]
    pub fn inverse_on_pattern(&self) -> BandBorder {
        let mut out = self.m.zeros_like();
        self.inverse_on_pattern_into(&mut out);
        out
    }
}

/// The band alone with half-width 3 (cubic splines, not periodic), unrolled:
/// the same recurrences as the general code, with the row's entries in
/// registers and the pivots' reciprocals kept (`inv`), so that one division
/// per row remains. Rows are `[D_i, L_i,i−1, L_i,i−2, L_i,i−3]`.
mod cubic {
    const S: usize = 4;

    pub(super) fn factor(band: &mut [f64], inv: &mut [f64], tolerance: f64) -> bool {
        let n = band.len() / S;
        let ok = |d: f64| d > tolerance && d.is_finite();
        for i in 0..n.min(3) {
            // The first rows have fewer neighbours.
            for j in 0..i {
                let mut acc = band[i * S + i - j];
                for l in 0..j {
                    acc -= band[i * S + i - l] * band[j * S + j - l] * band[l * S];
                }
                band[i * S + i - j] = acc * inv[j];
            }
            let mut d = band[i * S];
            for l in 0..i {
                d -= band[i * S + i - l] * band[i * S + i - l] * band[l * S];
            }
            if !ok(d) {
                return false;
            }
            band[i * S] = d;
            inv[i] = 1.0 / d;
        }
        for i in 3..n {
            let (done, rest) = band.split_at_mut(i * S);
            let a: &mut [f64; S] = (&mut rest[..S]).try_into().expect("a row");
            let r: &[f64; 3 * S] = (&done[(i - 3) * S..]).try_into().expect("three rows");
            let (d3, d2, d1) = (r[0], r[S], r[2 * S]);
            let l3 = a[3] * inv[i - 3];
            let l2 = (a[2] - l3 * r[S + 1] * d3) * inv[i - 2];
            let l1 = (a[1] - l3 * r[2 * S + 2] * d3 - l2 * r[2 * S + 1] * d2) * inv[i - 1];
            let d = a[0] - l3 * l3 * d3 - l2 * l2 * d2 - l1 * l1 * d1;
            if !ok(d) {
                return false;
            }
            *a = [d, l1, l2, l3];
            inv[i] = 1.0 / d;
        }
        true
    }

    pub(super) fn solve(band: &[f64], inv: &[f64], x: &mut [f64]) {
        let n = x.len();
        for i in 1..n.min(3) {
            for d in 1..=i {
                x[i] -= band[i * S + d] * x[i - d];
            }
        }
        for i in 3..n {
            let row = &band[i * S..(i + 1) * S];
            x[i] -= row[1] * x[i - 1] + row[2] * x[i - 2] + row[3] * x[i - 3];
        }
        for (v, r) in x.iter_mut().zip(inv) {
            *v *= r;
        }
        for i in (n.saturating_sub(3)..n).rev() {
            for d in 1..n - i {
                x[i] -= band[(i + d) * S + d] * x[i + d];
            }
        }
        for i in (0..n.saturating_sub(3)).rev() {
            x[i] -= band[(i + 1) * S + 1] * x[i + 1]
                + band[(i + 2) * S + 2] * x[i + 2]
                + band[(i + 3) * S + 3] * x[i + 3];
        }
    }

    pub(super) fn inverse(band: &[f64], inv: &[f64], out: &mut [f64]) {
        let n = band.len() / S;
        for i in (n.saturating_sub(3)..n).rev() {
            let hi = n - 1;
            for j in i + 1..=hi {
                let mut acc = 0.0;
                for l in i + 1..=hi {
                    let sigma = if l >= j {
                        out[l * S + l - j]
                    } else {
                        out[j * S + j - l]
                    };
                    acc -= band[l * S + l - i] * sigma;
                }
                out[j * S + j - i] = acc;
            }
            let mut d = inv[i];
            for l in i + 1..=hi {
                d -= band[l * S + l - i] * out[l * S + l - i];
            }
            out[i * S] = d;
        }
        for i in (0..n.saturating_sub(3)).rev() {
            let (c1, c2, c3) = (
                band[(i + 1) * S + 1],
                band[(i + 2) * S + 2],
                band[(i + 3) * S + 3],
            );
            let (head, tail) = out.split_at_mut((i + 1) * S);
            let t: &mut [f64; 3 * S] = (&mut tail[..3 * S]).try_into().expect("three rows");
            let (s11, s22, s33) = (t[0], t[S], t[2 * S]);
            let (s21, s32, s31) = (t[S + 1], t[2 * S + 1], t[2 * S + 2]);
            let e1 = -(c1 * s11 + c2 * s21 + c3 * s31);
            let e2 = -(c1 * s21 + c2 * s22 + c3 * s32);
            let e3 = -(c1 * s31 + c2 * s32 + c3 * s33);
            t[1] = e1;
            t[S + 2] = e2;
            t[2 * S + 3] = e3;
            head[i * S] = inv[i] - (c1 * e1 + c2 * e2 + c3 * e3);
        }
    }
}

/// Several shifted systems `A_l = G + s_l P` at once (`L` lanes), for a band of
/// half-width 3 without a border (cubic splines, not periodic): for each lane
/// whether `A_l` is positive definite, and with `c_l = A_l⁻¹ r` and a given
/// `c₀`, the numbers `(c_l − c₀)ᵀ G (c_l − c₀)` and `tr(A_l⁻¹ G)`. The lanes are independent
/// chains of the same recurrences as [`Ldl`] (unrolled as in its half-width-3
/// path), interleaved so that the processor overlaps them.
pub struct Shifted<const L: usize> {
    band: Vec<[f64; L]>,
    inv: Vec<[f64; L]>,
    x: Vec<[f64; L]>,
    sigma: Vec<[f64; L]>,
}

/// `((c − c₀)ᵀ G (c − c₀), tr(A⁻¹ G))` of one lane of [`Shifted`].
pub type ShiftedLane = (f64, f64);

impl<const L: usize> Shifted<L> {
    /// Whether `g` (and a penalty of its shape) has the layout this handles.
    pub fn supports(g: &BandBorder) -> bool {
        g.w == 3 && g.main == g.n
    }

    /// Work space for matrices shaped like `g` ([`Shifted::supports`]).
    pub fn new(g: &BandBorder) -> Shifted<L> {
        let n = g.n;
        Shifted {
            band: vec![[0.0; L]; 4 * n],
            inv: vec![[0.0; L]; n],
            x: vec![[0.0; L]; n],
            sigma: vec![[0.0; L]; 4 * n],
        }
    }

    /// See the type's doc; `None` for a lane whose `A` is not positive definite.
    pub fn evaluate(
        &mut self,
        g: &BandBorder,
        p: &BandBorder,
        shifts: [f64; L],
        r: &[f64],
        c0: &[f64],
    ) -> [Option<ShiftedLane>; L] {
        const S: usize = 4;
        let n = g.n;
        let (band, inv, x, sigma) = (&mut self.band, &mut self.inv, &mut self.x, &mut self.sigma);
        let mut ok = [true; L];
        // LDLᵀ.
        for i in 0..n {
            let mut a = [[0.0; L]; S];
            for d in 0..S {
                for l in 0..L {
                    a[d][l] = g.band[i * S + d] + shifts[l] * p.band[i * S + d];
                }
            }
            if i < 3 {
                for l in 0..L {
                    for j in 0..i {
                        let mut acc = a[i - j][l];
                        for k in 0..j {
                            acc -= a[i - k][l] * band[j * S + j - k][l] * band[k * S][l];
                        }
                        a[i - j][l] = acc * inv[j][l];
                    }
                    let mut d = a[0][l];
                    for k in 0..i {
                        d -= a[i - k][l] * a[i - k][l] * band[k * S][l];
                    }
                    ok[l] &= d > 0.0 && d.is_finite();
                    a[0][l] = d;
                    inv[i][l] = 1.0 / d;
                }
            } else {
                for l in 0..L {
                    let (d3, d2, d1) = (
                        band[(i - 3) * S][l],
                        band[(i - 2) * S][l],
                        band[(i - 1) * S][l],
                    );
                    let l3 = a[3][l] * inv[i - 3][l];
                    let l2 = (a[2][l] - l3 * band[(i - 2) * S + 1][l] * d3) * inv[i - 2][l];
                    let l1 = (a[1][l]
                        - l3 * band[(i - 1) * S + 2][l] * d3
                        - l2 * band[(i - 1) * S + 1][l] * d2)
                        * inv[i - 1][l];
                    let d = a[0][l] - l3 * l3 * d3 - l2 * l2 * d2 - l1 * l1 * d1;
                    ok[l] &= d > 0.0 && d.is_finite();
                    a[0][l] = d;
                    a[1][l] = l1;
                    a[2][l] = l2;
                    a[3][l] = l3;
                    inv[i][l] = 1.0 / d;
                }
            }
            band[i * S..(i + 1) * S].copy_from_slice(&a);
        }
        // c = A⁻¹ r.
        for i in 0..n {
            let mut v = [r[i]; L];
            if i >= 3 {
                let row = &band[i * S..(i + 1) * S];
                for l in 0..L {
                    v[l] -=
                        row[1][l] * x[i - 1][l] + row[2][l] * x[i - 2][l] + row[3][l] * x[i - 3][l];
                }
            } else {
                for d in 1..=i {
                    for l in 0..L {
                        v[l] -= band[i * S + d][l] * x[i - d][l];
                    }
                }
            }
            x[i] = v;
        }
        for (v, q) in x.iter_mut().zip(inv.iter()) {
            for l in 0..L {
                v[l] *= q[l];
            }
        }
        for i in (0..n).rev() {
            let mut v = x[i];
            if i + 3 < n {
                for l in 0..L {
                    v[l] -= band[(i + 1) * S + 1][l] * x[i + 1][l]
                        + band[(i + 2) * S + 2][l] * x[i + 2][l]
                        + band[(i + 3) * S + 3][l] * x[i + 3][l];
                }
            } else {
                for d in 1..n - i {
                    for l in 0..L {
                        v[l] -= band[(i + d) * S + d][l] * x[i + d][l];
                    }
                }
            }
            x[i] = v;
        }
        // A⁻¹ on the band.
        for i in (0..n).rev() {
            if i + 3 < n {
                let mut e = [[0.0; L]; 3];
                let mut diagonal = [0.0; L];
                for l in 0..L {
                    let (c1, c2, c3) = (
                        band[(i + 1) * S + 1][l],
                        band[(i + 2) * S + 2][l],
                        band[(i + 3) * S + 3][l],
                    );
                    let (s11, s22, s33) = (
                        sigma[(i + 1) * S][l],
                        sigma[(i + 2) * S][l],
                        sigma[(i + 3) * S][l],
                    );
                    let (s21, s32, s31) = (
                        sigma[(i + 2) * S + 1][l],
                        sigma[(i + 3) * S + 1][l],
                        sigma[(i + 3) * S + 2][l],
                    );
                    e[0][l] = -(c1 * s11 + c2 * s21 + c3 * s31);
                    e[1][l] = -(c1 * s21 + c2 * s22 + c3 * s32);
                    e[2][l] = -(c1 * s31 + c2 * s32 + c3 * s33);
                    diagonal[l] = inv[i][l] - (c1 * e[0][l] + c2 * e[1][l] + c3 * e[2][l]);
                }
                sigma[(i + 1) * S + 1] = e[0];
                sigma[(i + 2) * S + 2] = e[1];
                sigma[(i + 3) * S + 3] = e[2];
                sigma[i * S] = diagonal;
                continue;
            }
            let hi = n - 1;
            let mut e = [[0.0; L]; S];
            for j in i + 1..=hi {
                for l in 0..L {
                    let mut acc = 0.0;
                    for k in i + 1..=hi {
                        let s = if k >= j {
                            sigma[k * S + k - j][l]
                        } else {
                            sigma[j * S + j - k][l]
                        };
                        acc -= band[k * S + k - i][l] * s;
                    }
                    e[j - i][l] = acc;
                }
            }
            for j in i + 1..=hi {
                sigma[j * S + j - i] = e[j - i];
            }
            for l in 0..L {
                let mut d = inv[i][l];
                for k in i + 1..=hi {
                    d -= band[k * S + k - i][l] * e[k - i][l];
                }
                sigma[i * S][l] = d;
            }
        }
        // (c − c₀)ᵀ G (c − c₀) and tr(A⁻¹G).
        for (v, b) in x.iter_mut().zip(c0) {
            for l in 0..L {
                v[l] -= b;
            }
        }
        let mut dgd = [0.0; L];
        let mut trace = [0.0; L];
        for i in 0..n {
            let row = &g.band[i * S..(i + 1) * S];
            let sig = &sigma[i * S..(i + 1) * S];
            for l in 0..L {
                let (off, t) = if i >= 3 {
                    (
                        row[1] * x[i - 1][l] + row[2] * x[i - 2][l] + row[3] * x[i - 3][l],
                        row[1] * sig[1][l] + row[2] * sig[2][l] + row[3] * sig[3][l],
                    )
                } else {
                    let (mut off, mut t) = (0.0, 0.0);
                    for d in 1..=i {
                        off += row[d] * x[i - d][l];
                        t += row[d] * sig[d][l];
                    }
                    (off, t)
                };
                dgd[l] += x[i][l] * (row[0] * x[i][l] + 2.0 * off);
                trace[l] += row[0] * sig[0][l] + 2.0 * t;
            }
        }
        let mut out = [None; L];
        for l in 0..L {
            if ok[l] {
                out[l] = Some((dgd[l], trace[l]));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    /// A random symmetric positive-definite matrix of the given shape, and
    /// its dense copy.
    fn random(n: usize, main: usize, w: usize, seed: u64) -> (BandBorder, DMatrix<f64>) {
        let mut state = seed;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5
        };
        let mut a = BandBorder::zeros(n, main, w);
        // Sums of outer products of vectors with the allowed pattern: a band
        // window, plus entries in the border.
        for start in 0..main.max(1) {
            let mut v: Vec<(usize, f64)> = (start..(start + w + 1).min(main))
                .map(|i| (i, next()))
                .collect();
            for b in main..n {
                v.push((b, next()));
            }
            a.add_outer(&v, 1.0);
        }
        for i in 0..n {
            a.add_outer(&[(i, 1.0)], 0.1);
        }
        let dense = DMatrix::from_fn(n, n, |i, j| a.get(i, j));
        (a, dense)
    }

    #[test]
    fn factor_solve_and_inverse_agree_with_dense_algebra() {
        for (n, main, w) in [
            (12, 12, 3),
            (40, 40, 3),
            (3, 3, 3),
            (12, 9, 3),
            (7, 0, 3),
            (30, 27, 2),
            (5, 4, 1),
            (1, 1, 3),
        ] {
            let (a, dense) = random(n, main, w, n as u64 * 31 + main as u64);
            let ldl = a.factor(0.0).expect("positive definite");
            let inverse = dense.clone().try_inverse().unwrap();
            let b: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
            let x = ldl.solve(&b);
            let expected = &inverse * nalgebra::DVector::from_vec(b.clone());
            for i in 0..n {
                assert!((x[i] - expected[i]).abs() < 1e-9 * (1.0 + expected[i].abs()));
            }
            let sigma = ldl.inverse_on_pattern();
            for i in 0..n {
                for j in 0..=i {
                    let on = i >= main || i - j <= w;
                    if on {
                        let e = inverse[(i, j)];
                        assert!(
                            (sigma.get(i, j) - e).abs() < 1e-9 * (1.0 + e.abs()),
                            "({i}, {j}) of n={n} main={main} w={w}: {} vs {e}",
                            sigma.get(i, j)
                        );
                    }
                }
            }
            // tr(A⁻¹ A) = n.
            assert!((sigma.trace_product(&a) - n as f64).abs() < 1e-9 * n as f64);
            let y = a.mul_vec(&b);
            let dy = &dense * nalgebra::DVector::from_vec(b.clone());
            for i in 0..n {
                assert!((y[i] - dy[i]).abs() < 1e-12 * (1.0 + dy[i].abs()));
            }
        }
    }

    #[test]
    fn a_singular_matrix_has_no_factor() {
        let mut a = BandBorder::zeros(4, 4, 3);
        a.add_outer(&[(0, 1.0), (1, 1.0)], 1.0);
        a.add_outer(&[(2, 1.0), (3, 1.0)], 1.0);
        assert!(a.factor(1e-12).is_none());
    }

    #[test]
    fn shifted_lanes_agree_with_one_system_at_a_time() {
        let (g, _) = random(40, 40, 3, 7);
        let (p, _) = random(40, 40, 3, 8);
        let r: Vec<f64> = (0..40).map(|i| (i as f64 * 0.3).cos()).collect();
        let shifts = [0.0, 1e-3, 0.7, 40.0];
        let mut lanes = Shifted::<4>::new(&g);
        let c0 = g.factor(0.0).unwrap().solve(&r);
        let got = lanes.evaluate(&g, &p, shifts, &r, &c0);
        for (s, lane) in shifts.iter().zip(got) {
            let (dgd, trace) = lane.expect("positive definite");
            let a = g.plus_scaled(&p, *s);
            let ldl = a.factor(0.0).unwrap();
            let c = ldl.solve(&r);
            let delta: Vec<f64> = c.iter().zip(&c0).map(|(a, b)| a - b).collect();
            let want = g.quadratic_form(&delta);
            let want_trace = ldl.inverse_on_pattern().trace_product(&g);
            assert!(
                (dgd - want).abs() < 1e-10 * want.abs().max(1.0),
                "{dgd} vs {want}"
            );
            assert!((trace - want_trace).abs() < 1e-10 * want_trace.abs().max(1.0));
        }
        // A lane that is not positive definite fails alone.
        let got = lanes.evaluate(&g, &p, [0.5, -1e6, 0.5, 0.5], &r, &c0);
        assert!(got[0].is_some() && got[1].is_none() && got[3].is_some());
    }
}
