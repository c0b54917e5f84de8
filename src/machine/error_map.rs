//! Volumetric error maps over a plane of the machine's workspace (the seed paper's
//! Fig. 12): `e` on a regular grid of joint positions with the third linear axis
//! and A, C fixed (drawn as an SVG heat map by the crate's `report` module).
//!
//! Invariants: the grid is `grid × grid` points including the range ends; values
//! are stored row by row (`v` outer, `u` inner); arrows show `e` turned into the
//! machine frame (`Rx(a)·Rz(c)·e`, the nominal rotation), so they lie in the plotted
//! plane whatever A and C are; the report keeps `e` in part coordinates as
//! everywhere else.
use super::error_model::{ErrorModel, LookupError};
use crate::axes::{Axes, Axis};
use crate::kinematics::VolumetricError;
use crate::nurbs::{NurbsSurface, SurfaceFitOptions, fit_surface};
use rayon::prelude::*;
use serde::Serialize;

/// The plane of a map: its two in-plane axes and the normal axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum Plane {
    XY,
    XZ,
    YZ,
}

impl Plane {
    /// `(u, v, normal)`.
    pub fn axes(self) -> (Axis, Axis, Axis) {
        match self {
            Plane::XY => (Axis::X, Axis::Y, Axis::Z),
            Plane::XZ => (Axis::X, Axis::Z, Axis::Y),
            Plane::YZ => (Axis::Y, Axis::Z, Axis::X),
        }
    }

    /// The index of a linear axis in an `[x, y, z]` vector.
    pub(crate) fn index(axis: Axis) -> usize {
        match axis {
            Axis::X => 0,
            Axis::Y => 1,
            _ => 2,
        }
    }
}

/// What to map.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MapSpec {
    pub plane: Plane,
    /// Joint position of the normal axis, mm.
    pub level: f64,
    /// The rotary joints (degrees) of the map; its linear letters are ignored.
    pub rotaries: Axes,
    /// Ranges of the in-plane axes (joint mm), `min < max`.
    pub u_range: [f64; 2],
    pub v_range: [f64; 2],
    /// Points per side (≥ 2).
    pub grid: usize,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    #[error("the map grid needs at least 2 points per side (got {0})")]
    Grid(usize),
    #[error("map range {0:?} must be finite with min < max")]
    Range([f64; 2]),
    #[error("map level and angles must be finite")]
    NotFinite,
    #[error(transparent)]
    Lookup(#[from] LookupError),
    #[error("cannot fit a surface to the map: {0}")]
    Surface(String),
}

/// How well a fitted NURBS surface represents the grid values.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SurfaceFit {
    /// What was fitted: `"|e|"`, `"e_x"`, `"e_y"`, `"e_z"` (µm, part coordinates).
    pub quantity: String,
    pub degree: usize,
    pub control_points: [usize; 2],
    /// Largest and RMS |surface − value| over the grid points, µm.
    pub emax_um: f64,
    pub erms_um: f64,
}

/// The fitted surface of a map, |e| (drawn), and the fits of |e| and of the
/// three components of e.
#[derive(Clone, Debug)]
pub struct MapSurfaces {
    pub magnitude: NurbsSurface,
    /// Fit errors, in the order |e|, e_x, e_y, e_z.
    pub fits: Vec<SurfaceFit>,
}

/// One grid point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct MapPoint {
    pub joints: Axes,
    /// e (µm) and tool-axis error (µrad), part coordinates.
    #[serde(flatten)]
    pub error: VolumetricError,
    /// e in the machine frame (µm), what the arrows show.
    pub e_machine_um: [f64; 3],
    pub magnitude_um: f64,
}

/// A computed map.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ErrorMap {
    pub spec: MapSpec,
    /// Grid coordinates along u and v (joint mm).
    pub u: Vec<f64>,
    pub v: Vec<f64>,
    /// `points[j * u.len() + i]` at `(u[i], v[j])`.
    pub points: Vec<MapPoint>,
}

fn linspace(range: [f64; 2], n: usize) -> Vec<f64> {
    (0..n)
        .map(|i| range[0] + (range[1] - range[0]) * i as f64 / (n - 1) as f64)
        .collect()
}

/// A part-frame vector `v` in machine directions at the rotary joints of `rotaries`.
fn part_to_machine(kin: &crate::kinematics::Kinematics, rotaries: &Axes, v: [f64; 3]) -> [f64; 3] {
    // The nominal tip map is affine: read its linear part off the machine points of
    // two part points (keeps the chain's conventions in one place).
    let map = kin.tip_to_joints(rotaries);
    let o = map.linear_joints([0.0; 3]);
    let p = map.linear_joints(v);
    [p[0] - o[0], p[1] - o[1], p[2] - o[2]]
}

impl ErrorMap {
    /// Evaluate `model` over the grid of `spec` (in parallel).
    pub fn compute(model: &ErrorModel, spec: &MapSpec) -> Result<ErrorMap, MapError> {
        if spec.grid < 2 {
            return Err(MapError::Grid(spec.grid));
        }
        for r in [spec.u_range, spec.v_range] {
            if !(r[0].is_finite() && r[1].is_finite() && r[0] < r[1]) {
                return Err(MapError::Range(r));
            }
        }
        if !(spec.level.is_finite() && spec.rotaries.is_finite()) {
            return Err(MapError::NotFinite);
        }
        let (ua, va, na) = spec.plane.axes();
        let u = linspace(spec.u_range, spec.grid);
        let v = linspace(spec.v_range, spec.grid);
        let kin = *model.kinematics();
        let points = (0..spec.grid * spec.grid)
            .into_par_iter()
            .map(|k| {
                let mut joints = spec.rotaries;
                joints.set(ua, u[k % spec.grid]);
                joints.set(va, v[k / spec.grid]);
                joints.set(na, spec.level);
                let error = model.volumetric_error(&joints)?;
                Ok(MapPoint {
                    joints,
                    error,
                    e_machine_um: part_to_machine(&kin, &spec.rotaries, error.e_um),
                    magnitude_um: error.magnitude_um(),
                })
            })
            .collect::<Result<Vec<_>, LookupError>>()?;
        Ok(ErrorMap {
            spec: *spec,
            u,
            v,
            points,
        })
    }

    /// Fit tensor-product NURBS surfaces (cubic, or of degree grid − 1 for coarser
    /// grids; `crate::nurbs::fit_surface`, least squares) to |e| and to each component
    /// of e, with `control` control points per direction (`None`: the nurbs default,
    /// min(grid, 12); `grid` interpolates the grid values).
    pub fn fit_surfaces(&self, control: Option<usize>) -> Result<MapSurfaces, MapError> {
        let degree = (self.spec.grid - 1).min(3);
        let options = SurfaceFitOptions {
            degree_u: degree,
            degree_v: degree,
            control_u: control,
            control_v: control,
        };
        let nu = self.u.len();
        let grid_of = |f: &dyn Fn(&MapPoint) -> f64| -> Vec<Vec<f64>> {
            (0..nu)
                .map(|i| {
                    (0..self.v.len())
                        .map(|j| f(&self.points[j * nu + i]))
                        .collect()
                })
                .collect()
        };
        let quantities: [(&str, Vec<Vec<f64>>); 4] = [
            ("|e|", grid_of(&|p| p.magnitude_um)),
            ("e_x", grid_of(&|p| p.error.e_um[0])),
            ("e_y", grid_of(&|p| p.error.e_um[1])),
            ("e_z", grid_of(&|p| p.error.e_um[2])),
        ];
        let mut surfaces = Vec::with_capacity(4);
        let mut fits = Vec::with_capacity(4);
        for (name, values) in &quantities {
            let surface = fit_surface(&self.u, &self.v, values, &options)
                .map_err(|e| MapError::Surface(e.to_string()))?;
            let (mut emax, mut sum) = (0.0f64, 0.0);
            for (i, row) in values.iter().enumerate() {
                for (j, value) in row.iter().enumerate() {
                    let d = surface.eval(self.u[i], self.v[j]) - value;
                    emax = emax.max(d.abs());
                    sum += d * d;
                }
            }
            fits.push(SurfaceFit {
                quantity: name.to_string(),
                degree,
                control_points: [surface.count_u, surface.count_v],
                emax_um: emax,
                erms_um: (sum / (nu * self.v.len()) as f64).sqrt(),
            });
            surfaces.push(surface);
        }
        match surfaces.into_iter().next() {
            Some(magnitude) => Ok(MapSurfaces { magnitude, fits }),
            None => Err(MapError::Surface("internal: four surfaces expected".into())),
        }
    }

    /// |e| on the grid, row by row.
    pub fn magnitudes(&self) -> Vec<f64> {
        self.points.iter().map(|p| p.magnitude_um).collect()
    }

    /// Largest |e| over the grid, µm.
    pub fn max_magnitude(&self) -> f64 {
        self.points
            .iter()
            .map(|p| p.magnitude_um)
            .fold(0.0, f64::max)
    }
}
