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
use super::walk::PathPoint;
use std::collections::HashMap;

/// The path point that cut a plan point, and how far its contact point is from it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanMatch {
    pub point: PathPoint,
    pub distance_mm: f64,
}

/// The plan side of the query for one ball radius: `p + R·n` per plan point,
/// gridded.
#[derive(Debug)]
struct RadiusGrid {
    radius_bits: u64,
    queries: Vec<[f64; 3]>,
    grid: HashMap<[i64; 3], Vec<u32>>,
}

#[derive(Debug)]
pub struct PlanMatcher {
    /// Ball radius of tool 0 (the default tool).
    default_radius: f64,
    max_distance: f64,
    cell: f64,
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
            max_distance: max_distance_mm,
            cell: max_distance_mm.max(1e-6),
            points: points.to_vec(),
            grids: Vec::new(),
            best: vec![None; points.len()],
        }
    }

    /// The grid for ball radius `radius`, made on first use.
    fn grid_for(&mut self, radius: f64) -> usize {
        let bits = radius.to_bits();
        if let Some(k) = self.grids.iter().position(|g| g.radius_bits == bits) {
            return k;
        }
        let queries: Vec<[f64; 3]> = self
            .points
            .iter()
            .map(|(p, n)| {
                [
                    p[0] + radius * n[0],
                    p[1] + radius * n[1],
                    p[2] + radius * n[2],
                ]
            })
            .collect();
        let mut grid: HashMap<[i64; 3], Vec<u32>> = HashMap::new();
        for (i, q) in queries.iter().enumerate() {
            grid.entry(cell_of(*q, self.cell))
                .or_default()
                .push(i as u32);
        }
        self.grids.push(RadiusGrid {
            radius_bits: bits,
            queries,
            grid,
        });
        self.grids.len() - 1
    }

    /// Consider one path point (the first of equally near points wins).
    pub fn offer(&mut self, point: &PathPoint) {
        let radius = if point.tool.number == 0 {
            self.default_radius
        } else {
            point.tool.radius_mm
        };
        let k = self.grid_for(radius);
        let g = &self.grids[k];
        let centre = [
            point.tip[0] + radius * point.axis[0],
            point.tip[1] + radius * point.axis[1],
            point.tip[2] + radius * point.axis[2],
        ];
        let c = cell_of(centre, self.cell);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let key = [c[0] + dx, c[1] + dy, c[2] + dz];
                    let Some(ids) = g.grid.get(&key) else {
                        continue;
                    };
                    for &i in ids {
                        let q = g.queries[i as usize];
                        let d = ((q[0] - centre[0]).powi(2)
                            + (q[1] - centre[1]).powi(2)
                            + (q[2] - centre[2]).powi(2))
                        .sqrt();
                        if d > self.max_distance {
                            continue;
                        }
                        let slot = &mut self.best[i as usize];
                        if slot.is_none_or(|b| d < b.distance_mm) {
                            *slot = Some(PlanMatch {
                                point: *point,
                                distance_mm: d,
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
