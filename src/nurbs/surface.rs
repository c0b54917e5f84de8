//! Tensor-product NURBS surfaces (the paper's eq. 4) and their least-squares fit
//! to gridded data by two passes of curve fitting (§2.2): first along `v` for every
//! grid row, giving intermediate control values `C_j(ū_k)`, then along `u` through
//! those, giving the control net `P_ij`.
//!
//! The surfaces here are explicit (height fields): a scalar value over the plane
//! of the grid coordinates, e.g. an error map `e(x, y)` in µm over mm. The grid
//! coordinates are mapped affinely to the parameters (`u = (x − x_0)/(x_n − x_0)`),
//! which is the chord-length parameterisation of a grid line, so `eval(x, y)` needs
//! no inversion. Knots by EPM (eq. 14) on those parameters; with unit weights the
//! two passes give exactly the tensor-product least-squares solution with the four
//! boundary curves' end points interpolated.
//!
//! Invariants: knot vectors valid and clamped, `weights.len() == values.len() ==
//! count_u * count_v` (index `i * count_v + j`), weights positive, all finite.
use serde::{Deserialize, Serialize};

use super::basis::{MAX_DEGREE, basis_funs, find_span};
use super::knot_placement;
use super::knot_vector;
use super::least_squares::{LeastSquaresError, fit_control_points};

/// A tensor-product NURBS height field: a scalar value over a rectangle of grid coordinates (e.g. an error map in µm over mm).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NurbsSurface {
    /// Degree along `u`.
    pub degree_u: usize,
    /// Degree along `v`.
    pub degree_v: usize,
    /// Clamped knot vector along `u`.
    pub knots_u: Vec<f64>,
    /// Clamped knot vector along `v`.
    pub knots_v: Vec<f64>,
    /// Number of control values along `u`.
    pub count_u: usize,
    /// Number of control values along `v`.
    pub count_v: usize,
    /// Weight of each control value, `i * count_v + j`, positive.
    pub weights: Vec<f64>,
    /// Control values, `i * count_v + j`.
    pub values: Vec<f64>,
    /// First and last grid coordinates along `u`, mapped to `u ∈ [0, 1]`.
    pub range_u: (f64, f64),
    /// First and last grid coordinates along `v`, mapped to `v ∈ [0, 1]`.
    pub range_v: (f64, f64),
}

/// Settings of [`fit_surface`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SurfaceFitOptions {
    /// Degree along `u` (3).
    pub degree_u: usize,
    /// Degree along `v` (3).
    pub degree_v: usize,
    /// Control points along each direction; `None` = `min(grid points, 12)`.
    pub control_u: Option<usize>,
    /// Control points along `v`; `None` = `min(grid points, 12)`.
    pub control_v: Option<usize>,
}

impl Default for SurfaceFitOptions {
    fn default() -> Self {
        SurfaceFitOptions {
            degree_u: 3,
            degree_v: 3,
            control_u: None,
            control_v: None,
        }
    }
}

/// Why a surface fit failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    /// Fewer grid coordinates along a direction than degree + 1.
    #[error("the grid needs at least {need} coordinates along {direction} (degree + 1), got {got}")]
    TooFewGrid {
        /// `'u'` or `'v'`.
        direction: char,
        /// Number of coordinates given.
        got: usize,
        /// Least number needed (degree + 1).
        need: usize,
    },
    /// Grid coordinates along a direction are not finite or not strictly increasing.
    #[error(
        "grid coordinates along {direction} must be finite and strictly increasing (index {index})"
    )]
    Grid {
        /// `'u'` or `'v'`.
        direction: char,
        /// Index of the first offending coordinate.
        index: usize,
    },
    /// The values are not `rows` rows of `cols` finite numbers.
    #[error("values must be {rows} rows of {cols} finite numbers (row {row})")]
    Values {
        /// Number of rows expected (grid coordinates along `u`).
        rows: usize,
        /// Number of columns expected (grid coordinates along `v`).
        cols: usize,
        /// The first row that is missing, of the wrong length or not finite.
        row: usize,
    },
    /// The number of control points asked for along a direction is outside degree + 1 ..= grid points.
    #[error("{count} control points along {direction}: need between degree + 1 = {min} and {max}")]
    ControlCount {
        /// `'u'` or `'v'`.
        direction: char,
        /// Number asked for.
        count: usize,
        /// Least allowed (degree + 1).
        min: usize,
        /// Most allowed (grid coordinates along that direction).
        max: usize,
    },
    /// A degree is outside 1..=`MAX_DEGREE`.
    #[error("degree {0} is outside 1..={MAX_DEGREE}")]
    Degree(usize),
    /// A least-squares curve fit of one pass failed.
    #[error(transparent)]
    LeastSquares(#[from] LeastSquaresError),
}

fn check_grid(g: &[f64], direction: char, degree: usize) -> Result<(), SurfaceError> {
    if degree == 0 || degree > MAX_DEGREE {
        return Err(SurfaceError::Degree(degree));
    }
    if g.len() < degree + 1 {
        return Err(SurfaceError::TooFewGrid {
            direction,
            got: g.len(),
            need: degree + 1,
        });
    }
    for (index, &x) in g.iter().enumerate() {
        if !x.is_finite() || (index > 0 && x <= g[index - 1]) {
            return Err(SurfaceError::Grid { direction, index });
        }
    }
    Ok(())
}

fn params(g: &[f64]) -> Vec<f64> {
    let (a, b) = (g[0], g[g.len() - 1]);
    let mut p: Vec<f64> = g.iter().map(|x| (x - a) / (b - a)).collect();
    let last = p.len() - 1;
    p[last] = 1.0;
    p
}

fn knots_for(
    p: &[f64],
    count: usize,
    degree: usize,
    direction: char,
) -> Result<Vec<f64>, SurfaceError> {
    if count < degree + 1 || count > p.len() {
        return Err(SurfaceError::ControlCount {
            direction,
            count,
            min: degree + 1,
            max: p.len(),
        });
    }
    let interior = knot_placement::equal_partition(p, count - 1, degree);
    Ok(knot_vector::clamped(degree, &interior, 0.0, 1.0))
}

/// Fit `values[i][j]` given at `(grid_u[i], grid_v[j])` (see the module doc).
pub fn fit_surface(
    grid_u: &[f64],
    grid_v: &[f64],
    values: &[Vec<f64>],
    options: &SurfaceFitOptions,
) -> Result<NurbsSurface, SurfaceError> {
    let (pu, pv) = (options.degree_u, options.degree_v);
    check_grid(grid_u, 'u', pu)?;
    check_grid(grid_v, 'v', pv)?;
    if values.len() != grid_u.len() {
        return Err(SurfaceError::Values {
            rows: grid_u.len(),
            cols: grid_v.len(),
            row: values.len().min(grid_u.len()),
        });
    }
    for (row, r) in values.iter().enumerate() {
        if r.len() != grid_v.len() || r.iter().any(|v| !v.is_finite()) {
            return Err(SurfaceError::Values {
                rows: grid_u.len(),
                cols: grid_v.len(),
                row,
            });
        }
    }
    let (par_u, par_v) = (params(grid_u), params(grid_v));
    let nu = options.control_u.unwrap_or(grid_u.len().min(12));
    let nv = options.control_v.unwrap_or(grid_v.len().min(12));
    let knots_u = knots_for(&par_u, nu, pu, 'u')?;
    let knots_v = knots_for(&par_v, nv, pv, 'v')?;
    let (wu, wv) = (vec![1.0; nu], vec![1.0; nv]);
    // Pass 1: along v for every grid row -> intermediate[k][j].
    let mut intermediate = Vec::with_capacity(grid_u.len());
    for row in values {
        intermediate.push(fit_control_points(&par_v, row, 1, pv, &knots_v, &wv)?);
    }
    // Pass 2: along u for every intermediate column -> P[i][j].
    let mut net = vec![0.0; nu * nv];
    for j in 0..nv {
        let column: Vec<f64> = intermediate.iter().map(|r| r[j]).collect();
        let ctrl = fit_control_points(&par_u, &column, 1, pu, &knots_u, &wu)?;
        for i in 0..nu {
            net[i * nv + j] = ctrl[i];
        }
    }
    Ok(NurbsSurface {
        degree_u: pu,
        degree_v: pv,
        knots_u,
        knots_v,
        count_u: nu,
        count_v: nv,
        weights: vec![1.0; nu * nv],
        values: net,
        range_u: (grid_u[0], grid_u[grid_u.len() - 1]),
        range_v: (grid_v[0], grid_v[grid_v.len() - 1]),
    })
}

impl NurbsSurface {
    /// The surface value at grid coordinates `(x, y)` (clamped to the grid's range).
    pub fn eval(&self, x: f64, y: f64) -> f64 {
        let u = ((x - self.range_u.0) / (self.range_u.1 - self.range_u.0)).clamp(0.0, 1.0);
        let v = ((y - self.range_v.0) / (self.range_v.1 - self.range_v.0)).clamp(0.0, 1.0);
        self.eval_parameter(u, v)
    }

    /// The surface value at parameters `(u, v)` in `[0, 1]²` (eq. 4).
    pub fn eval_parameter(&self, u: f64, v: f64) -> f64 {
        let (pu, pv) = (self.degree_u, self.degree_v);
        let su = find_span(self.count_u - 1, pu, u, &self.knots_u);
        let sv = find_span(self.count_v - 1, pv, v, &self.knots_v);
        let mut bu = [0.0; MAX_DEGREE + 1];
        let mut bv = [0.0; MAX_DEGREE + 1];
        basis_funs(su, u, pu, &self.knots_u, &mut bu);
        basis_funs(sv, v, pv, &self.knots_v, &mut bv);
        let (mut num, mut den) = (0.0, 0.0);
        for a in 0..=pu {
            let i = su - pu + a;
            for b in 0..=pv {
                let j = sv - pv + b;
                let k = i * self.count_v + j;
                let bw = bu[a] * bv[b] * self.weights[k];
                num += bw * self.values[k];
                den += bw;
            }
        }
        num / den
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_bad_grids() {
        let g = [0.0, 1.0, 2.0, 3.0];
        let bad = [0.0, 1.0, 1.0, 3.0];
        let vals = vec![vec![0.0; 4]; 4];
        assert!(matches!(
            fit_surface(&bad, &g, &vals, &SurfaceFitOptions::default()),
            Err(SurfaceError::Grid {
                direction: 'u',
                index: 2
            })
        ));
        let nan = vec![vec![0.0, f64::NAN, 0.0, 0.0]; 4];
        assert!(matches!(
            fit_surface(&g, &g, &nan, &SurfaceFitOptions::default()),
            Err(SurfaceError::Values { row: 0, .. })
        ));
    }
}
