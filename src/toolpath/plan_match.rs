//! Which tool-path point cut each plan point (formats.md "Predicted deviation of a
//! plan point"): the path point whose ball-end contact point for the plan normal is
//! nearest the plan point, within `max_distance_mm`.
//!
//! The contact point of a path point with tip `t` and axis `u` for normal `n` is
//! `t + R·u − R·n`, so its distance to plan point `p` is the distance between the
//! ball centre `t + R·u` and `p + R·n`: a nearest-neighbour query between two point
//! sets, answered with a uniform grid over the plan side (one per tool radius:
//! each path point carries its tool). Streaming: path points are offered one by
//! one and only the best candidate per plan point is kept.
//!
//! A tool whose shape is named (`contact`, docs/extensions.md) touches at
//! `t + r·u + (R − r)·v − r·n`, slid up its side for a flank cut: the grid is
//! kept on `p + r·n` (r the corner radius) and widened by the contact's reach
//! beyond it, and each candidate's contact point is computed exactly.
use super::contact::{contact_offset, contact_reach};
use super::walk::PathPoint;
use crate::gcode::{CutterShape, ToolInUse};
use std::collections::HashMap;

/// The path point that cut a plan point, and how far its contact point is from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanMatch {
    /// The path point.
    pub point: PathPoint,
    /// Distance of its contact point from the plan point, mm.
    pub distance_mm: f64,
    /// The tool that cut it, tool 0 resolved to the machine file's `[tool]`.
    pub tool: ToolInUse,
    /// The contact point's offset from the nominal tip, `c − t` (part, mm).
    pub contact_offset: [f64; 3],
}

impl PlanMatch {
    /// How far the path's own nominal contact point lies from the plan point
    /// `point` along its unit normal `normal`, µm (`n·(t + c − p)`): about zero
    /// for the program the CAM system wrote, minus the correction for a
    /// compensated one. The part measures the machine's error at the contact
    /// plus this.
    pub fn path_offset_um(&self, point: [f64; 3], normal: [f64; 3]) -> f64 {
        let (t, c) = (self.point.tip, self.contact_offset);
        (0..3)
            .map(|k| (t[k] + c[k] - point[k]) * normal[k])
            .sum::<f64>()
            * 1e3
    }
}

/// The plan side of the query for one tool radius and shape: `p + r·n` per plan
/// point (r: the corner radius, the ball's radius when no shape is named),
/// gridded with cells as wide as the match distance plus the contact's reach.
#[derive(Debug)]
struct RadiusGrid {
    radius_bits: u64,
    shape: Option<CutterShape>,
    corner: f64,
    cell: f64,
    queries: Vec<[f64; 3]>,
    grid: HashMap<[i64; 3], Vec<u32>>,
}

/// Finds, for every plan point, the path point whose contact point is nearest it (within the match distance), fed path point by path point.
#[derive(Debug)]
pub struct PlanMatcher {
    /// Radius and shape of tool 0 (the default tool).
    default_radius: f64,
    default_shape: Option<CutterShape>,
    max_distance: f64,
    /// (point, unit normal) per plan point, part coordinates.
    points: Vec<([f64; 3], [f64; 3])>,
    /// One grid per tool radius seen (programs change tools).
    grids: Vec<RadiusGrid>,
    best: Vec<Option<PlanMatch>>,
}

impl PlanMatcher {
    /// `points`: (point, unit normal) per plan point, part coordinates. Each
    /// path point is matched with the ball radius of its own tool;
    /// `default_radius` is tool 0's (the machine file's `[tool]`).
    pub fn new(points: &[([f64; 3], [f64; 3])], default_radius: f64, max_distance_mm: f64) -> Self {
        PlanMatcher {
            default_radius,
            default_shape: None,
            max_distance: max_distance_mm,
            points: points.to_vec(),
            grids: Vec::new(),
            best: vec![None; points.len()],
        }
    }

    /// Tool 0's cutting shape (the machine file's `[tool] shape`).
    pub fn with_default_shape(mut self, shape: Option<CutterShape>) -> Self {
        self.default_shape = shape;
        self
    }

    /// The grid for a tool of `radius` and `shape`, made on first use.
    fn grid_for(&mut self, radius: f64, shape: Option<CutterShape>) -> usize {
        let bits = radius.to_bits();
        if let Some(k) = self
            .grids
            .iter()
            .position(|g| g.radius_bits == bits && g.shape == shape)
        {
            return k;
        }
        let corner = shape.map_or(radius, |s| s.corner_radius_mm);
        let cell = (self.max_distance + contact_reach(radius, shape)).max(1e-6);
        let queries: Vec<[f64; 3]> = self
            .points
            .iter()
            .map(|(p, n)| {
                [
                    p[0] + corner * n[0],
                    p[1] + corner * n[1],
                    p[2] + corner * n[2],
                ]
            })
            .collect();
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (i, q) in queries.iter().enumerate() {
            grid.entry(cell_of(*q, cell)).or_default().push(i as u32);
        }
        self.grids.push(RadiusGrid {
            radius_bits: bits,
            shape,
            corner,
            cell,
            queries,
            grid,
        });
        self.grids.len() - 1
    }

    /// Consider one path point (the first of equally near points wins).
    pub fn offer(&mut self, point: &PathPoint) {
        let tool = if point.tool.number == 0 {
            ToolInUse {
                radius_mm: self.default_radius,
                shape: self.default_shape,
                ..point.tool
            }
        } else {
            point.tool
        };
        let radius = tool.radius_mm;
        let k = self.grid_for(radius, tool.shape);
        let g = &self.grids[k];
        let centre = [
            point.tip[0] + g.corner * point.axis[0],
            point.tip[1] + g.corner * point.axis[1],
            point.tip[2] + g.corner * point.axis[2],
        ];
        let c = cell_of(centre, g.cell);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                    let Some(ids) = g.grid.get(&key) else {
                        continue;
                    };
                    for &i in ids {
                        let (p, n) = self.points[i as usize];
                        let offset = contact_offset(point.tip, point.axis, radius, g.shape, p, n);
                        let d = match g.shape {
                            // formats.md's ball: |(t + R·u) − (p + R·n)|.
                            None => crate::vec3::dist(g.queries[i as usize], centre),
                            Some(_) => crate::vec3::dist(crate::vec3::add(point.tip, offset), p),
                        };
                        if d > self.max_distance {
                            continue;
                        }
                        let slot = &mut self.best[i as usize];
                        if slot.is_none_or(|b| d < b.distance_mm) {
                            *slot = Some(PlanMatch {
                                point: *point,
                                distance_mm: d,
                                tool,
                                contact_offset: offset,
                            });
                        }
                    }
                }
            }
        }
    }

    /// The match of every plan point, in plan order (`None`: not cut).
    pub fn into_matches(self) -> Vec<Option<PlanMatch>> {
        self.best
    }
}

fn cell_of(p: [f64; 3], cell: f64) -> [i64; 3] {
    [
        (p[0] / cell).floor() as i64,
        (p[1] / cell).floor() as i64,
        (p[2] / cell).floor() as i64,
    ]
}
