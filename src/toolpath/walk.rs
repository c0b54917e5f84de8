//! Streaming walk along a program's tool path: every motion block is sampled at
//! ≤ `step_mm` in part coordinates, and each sample carries what effects.md's
//! context needs (time, σ, speed, cut length, curvature from neighbouring block
//! endpoints).
//!
//! Memory is bounded: a block's samples are held back only until the next block
//! endpoint that is distinct in machine XYZ is known (for the curvature of its
//! end point); rotary-only blocks in a row are the only thing that lengthens the
//! window.
use super::pose::joints_of;
use crate::axes::Joints;
use crate::gcode::{Frame, Motion, MotionKind, ToolInUse, duration_from_lengths};
use crate::kinematics::Kinematics;
use crate::vec3::{cross, dist, dot, norm, scale, sub};
use std::collections::VecDeque;

/// Settings of the walk.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WalkOptions {
    /// Largest distance between samples, part coordinates, mm (formats.md: 0.5).
    pub step_mm: f64,
    /// G0 rate, mm/min.
    pub rapid_mm_per_min: f64,
}

impl Default for WalkOptions {
    fn default() -> Self {
        WalkOptions {
            step_mm: 0.5,
            rapid_mm_per_min: 10_000.0,
        }
    }
}

/// One sampled point of the tool path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathPoint {
    /// Joint position (machine XYZ mm, A C degrees).
    pub joints: Joints,
    /// Nominal tool tip, part coordinates, mm.
    pub tip: [f64; 3],
    /// Nominal unit tool axis, part coordinates.
    pub axis: [f64; 3],
    /// Index of the block among all the program's blocks (0-based).
    pub block: usize,
    /// Program line (1-based) of the block.
    pub line: usize,
    /// The tool in the spindle.
    pub tool: ToolInUse,
    /// Whether this is the block's end point.
    pub block_end: bool,
    /// G1/G2/G3 (false for G0).
    pub cutting: bool,
    /// Time at the end of the block reaching the point, minutes since the first target.
    pub time_min: f64,
    /// Sign of each linear axis's most recent non-zero motion.
    pub sigma: [f64; 3],
    /// XYZ machine-path speed of the block, mm/s.
    pub speed_mm_s: f64,
    /// Cumulative G1/G2/G3 XYZ machine length up to this point, m.
    pub cut_length_m: f64,
    /// Curvature of the machine XYZ path at the point, 1/mm.
    pub curvature_per_mm: f64,
    /// Unit principal normal towards the centre of curvature (machine frame), or zero.
    pub principal_normal: [f64; 3],
    /// The direction of each axis's last motion, for the axes with a reversal
    /// when the walk tracks them ([`PathWalker::track_directions`]; else none).
    pub approach: crate::machine::Approach,
}

/// A sample waiting for its curvature.
#[derive(Clone, Copy, Debug)]
struct Pending {
    point: PathPoint,
    /// Nearest distinct block endpoint before the point (machine XYZ).
    previous: Option<[f64; 3]>,
    /// Nearest distinct block endpoint after it, once known.
    next: Option<[f64; 3]>,
}

/// The walker. Feed it motion blocks in program order with [`PathWalker::push`];
/// finished points come out through the visitor, in order; call
/// [`PathWalker::finish`] at the end.
#[derive(Debug)]
pub struct PathWalker<'k> {
    kinematics: &'k Kinematics,
    options: WalkOptions,
    started: bool,
    time_min: f64,
    cut_length_mm: f64,
    sigma: [f64; 3],
    /// The last block endpoint (machine XYZ) and the last one distinct from its predecessor.
    last_endpoint: Option<[f64; 3]>,
    previous_distinct: Option<[f64; 3]>,
    pending: VecDeque<Pending>,
    /// Reused sample buffer.
    samples: Vec<Joints>,
    /// Reused buffer of a move's points in its own frame.
    points: Vec<crate::axes::Axes>,
    /// Directions of the axes with a reversal (`None`: not tracked).
    directions: Option<crate::machine::DirectionTracker>,
}

/// Endpoints closer than this (mm) are the same point for the curvature rule.
const SAME_POINT_MM: f64 = 1e-9;

impl<'k> PathWalker<'k> {
    /// A walker at the start of a program, sampling as `options` says.
    pub fn new(kinematics: &'k Kinematics, options: WalkOptions) -> Self {
        PathWalker {
            kinematics,
            options,
            started: false,
            time_min: 0.0,
            cut_length_mm: 0.0,
            sigma: [0.0; 3],
            last_endpoint: None,
            previous_distinct: None,
            pending: VecDeque::new(),
            samples: Vec::new(),
            points: Vec::new(),
            directions: None,
        }
    }

    /// Track the directions of the axes `tracker` follows (the error model's
    /// axes with a reversal) along the path: every point gets its approach.
    pub fn track_directions(&mut self, tracker: crate::machine::DirectionTracker) {
        self.directions = (!tracker.is_empty()).then_some(tracker);
    }

    /// Total time so far, minutes.
    pub fn time_min(&self) -> f64 {
        self.time_min
    }

    /// Walk one motion block.
    pub fn push(
        &mut self,
        block: usize,
        line: usize,
        tool: ToolInUse,
        motion: &Motion,
        visit: &mut impl FnMut(&PathPoint),
    ) {
        // The tool in the spindle: on a machine with a rotary axis on the
        // tool side its length moves the nominal tip (and the joints of a
        // tool-tip target).
        let kin = crate::machine::tool_models::kinematics_for_tool(self.kinematics, &tool);
        let start_joints = joints_of(&kin, &motion.start_pose());
        let end_joints = joints_of(&kin, &motion.end_pose());
        if !self.started {
            // Time starts at the first block's target: the first motion only positions.
            self.started = true;
            self.last_endpoint = Some(start_joints.xyz());
            self.previous_distinct = Some(start_joints.xyz());
        }
        if let Some(t) = self.directions.as_mut() {
            t.update(&start_joints);
        }
        self.sample(&kin, motion, &start_joints, &end_joints);

        // Machine XYZ length and rotary sweep of the block.
        let mut machine_len = 0.0;
        let mut prev = start_joints;
        for s in &self.samples {
            machine_len += prev.xyz_distance(s);
            prev = *s;
        }
        let rotary = start_joints.rotary_distance(&end_joints);
        let duration = duration_from_lengths(
            &motion.feed,
            machine_len,
            rotary,
            self.options.rapid_mm_per_min,
        );
        self.time_min += duration;
        let speed = if machine_len <= SAME_POINT_MM || duration <= 0.0 {
            0.0
        } else {
            machine_len / duration / 60.0
        };
        let cutting = !matches!(motion.kind, MotionKind::Rapid);

        let block_start_xyz = start_joints.xyz();
        let block_end_xyz = end_joints.xyz();
        // The previous distinct endpoint for the end point of this block.
        let prev_for_end = if dist(block_start_xyz, block_end_xyz) > SAME_POINT_MM {
            Some(block_start_xyz)
        } else {
            self.previous_distinct
        };
        let n = self.samples.len();
        let mut prev = start_joints;
        let mut along = 0.0;
        for i in 0..n {
            let joints = self.samples[i];
            let d = [joints.x - prev.x, joints.y - prev.y, joints.z - prev.z];
            for k in 0..3 {
                if d[k].abs() > 1e-12 {
                    self.sigma[k] = d[k].signum();
                }
            }
            along += prev.xyz_distance(&joints);
            prev = joints;
            let approach = match self.directions.as_mut() {
                Some(t) => {
                    t.update(&joints);
                    t.approach()
                }
                None => crate::machine::Approach::NONE,
            };
            let block_end = i + 1 == n;
            let cut_mm = if cutting {
                self.cut_length_mm + along
            } else {
                self.cut_length_mm
            };
            let point = PathPoint {
                joints,
                tip: kin.nominal_tip(&joints),
                axis: kin.nominal_tool_axis(&joints),
                block,
                line,
                tool,
                block_end,
                cutting,
                time_min: self.time_min,
                sigma: self.sigma,
                speed_mm_s: speed,
                cut_length_m: cut_mm * 1e-3,
                curvature_per_mm: 0.0,
                principal_normal: [0.0; 3],
                approach,
            };
            let (previous, next) = if block_end {
                (prev_for_end, None)
            } else {
                // Interior points: the neighbouring endpoints are the block's own.
                (Some(block_start_xyz), Some(block_end_xyz))
            };
            self.pending.push_back(Pending {
                point,
                previous,
                next,
            });
        }
        if cutting {
            self.cut_length_mm += machine_len;
        }

        // This block's end is the "next distinct endpoint" of earlier end points.
        for p in self.pending.iter_mut() {
            if p.point.block_end
                && p.next.is_none()
                && p.point.block != block
                && dist(p.point.joints.xyz(), block_end_xyz) > SAME_POINT_MM
            {
                p.next = Some(block_end_xyz);
            }
        }
        if let Some(last) = self.last_endpoint
            && dist(last, block_end_xyz) > SAME_POINT_MM
        {
            self.previous_distinct = Some(last);
        }
        self.last_endpoint = Some(block_end_xyz);
        self.release(visit, false);
    }

    /// Flush the points still waiting (end of program: no next endpoint).
    pub fn finish(&mut self, visit: &mut impl FnMut(&PathPoint)) {
        self.release(visit, true);
    }

    fn release(&mut self, visit: &mut impl FnMut(&PathPoint), all: bool) {
        while let Some(front) = self.pending.front() {
            let ready = !front.point.block_end || front.next.is_some() || all;
            if !ready {
                break;
            }
            let mut p = self.pending.pop_front().expect("front exists");
            if let (Some(a), Some(b)) = (p.previous, p.next) {
                let (k, n) = circle_curvature(a, p.point.joints.xyz(), b);
                p.point.curvature_per_mm = k;
                p.point.principal_normal = n;
            }
            visit(&p.point);
        }
    }

    /// Fill `self.samples` with the joints of the points along `motion`, excluding
    /// its start, at most `step_mm` apart in part coordinates.
    fn sample(
        &mut self,
        kin: &Kinematics,
        motion: &Motion,
        start_joints: &Joints,
        end_joints: &Joints,
    ) {
        self.samples.clear();
        self.points.clear();
        let step = self.options.step_mm;
        match motion.target_frame() {
            Frame::Part => {
                // A tool-tip control interpolates the tip in part coordinates.
                motion.interpolate_into(step, &mut self.points);
            }
            Frame::Joint => {
                // Joint interpolation: bound the part-coordinate chord by the XYZ
                // length plus the rotary sweep times the lever arm.
                let tip0 = kin.nominal_tip(start_joints);
                let tip1 = kin.nominal_tip(end_joints);
                let lever = norm(tip0).max(norm(tip1)) + motion.start.xyz_distance(&motion.end);
                let sweep = ((end_joints.a - start_joints.a).abs()
                    + (end_joints.b - start_joints.b).abs()
                    + (end_joints.c - start_joints.c).abs())
                .to_radians();
                let bound = motion.xyz_length().max(dist(tip0, tip1)) + sweep * lever;
                let scaled = if bound > 0.0 {
                    // interpolate() steps by XYZ (and degrees for rotary-only moves);
                    // ask for enough points that the part chord stays below `step`.
                    let n = (bound / step).ceil().max(1.0);
                    let ref_len = motion
                        .xyz_length()
                        .max(start_joints.rotary_max_step(end_joints));
                    if ref_len > 0.0 { ref_len / n } else { step }
                } else {
                    step
                };
                motion.interpolate_into(scaled.max(1e-6), &mut self.points);
            }
        }
        self.samples
            .extend(self.points.iter().map(|p| joints_of(kin, &motion.pose(*p))));
        if let Some(last) = self.samples.last_mut() {
            *last = *end_joints;
        } else {
            self.samples.push(*end_joints);
        }
    }
}

/// Curvature (1/mm) and unit principal normal (towards the centre) of the circle
/// through `a`, `p`, `b`, at `p`; zero where they are collinear.
pub fn circle_curvature(a: [f64; 3], p: [f64; 3], b: [f64; 3]) -> (f64, [f64; 3]) {
    let u = sub(a, p);
    let v = sub(b, p);
    let w = cross(u, v);
    let ww = dot(w, w);
    let (uu, vv) = (dot(u, u), dot(v, v));
    if uu <= 0.0 || vv <= 0.0 || ww <= 1e-18 * uu * vv {
        return (0.0, [0.0; 3]);
    }
    // Centre relative to p: ((|u|² v − |v|² u) × w) / (2 |w|²).
    let t = sub(scale(v, uu), scale(u, vv));
    let c = scale(cross(t, w), 0.5 / ww);
    let r = norm(c);
    if r <= 0.0 || !r.is_finite() {
        return (0.0, [0.0; 3]);
    }
    (1.0 / r, scale(c, 1.0 / r))
}

/// Advance `tracker` (the directions of the axes with a reversal) along
/// `motion` from its fraction `t0` to `t1`, in the joints of `kinematics`: a
/// straight joint move at its end alone (its joints move monotonically),
/// anything else (arcs, tool-tip moves, whose joints need not be monotone)
/// at samples ≤ 0.5 mm and ≤ 1/16 turn apart, as the walk samples a path.
pub fn advance_directions(
    tracker: &mut crate::machine::DirectionTracker,
    kinematics: &Kinematics,
    motion: &Motion,
    t0: f64,
    t1: f64,
) {
    if tracker.is_empty() {
        return;
    }
    let arc = motion.arc_geometry();
    let joints_at = |t: f64| joints_of(kinematics, &motion.pose(motion.point_at(arc.as_ref(), t)));
    // The start (the last end: no change, but it places the first move).
    tracker.update(&joints_at(t0));
    if motion.target_frame() == Frame::Joint && arc.is_none() {
        tracker.update(&joints_at(t1));
        return;
    }
    let len = arc
        .as_ref()
        .map_or_else(|| motion.start.xyz_distance(&motion.end), |g| g.length());
    let turns = arc
        .as_ref()
        .map_or(0.0, |g| g.sweep().abs() / std::f64::consts::TAU)
        + motion.start.rotary_max_step(&motion.end) / 360.0;
    let n = ((t1 - t0) * (len / 0.5).max(16.0 * turns)).ceil();
    let n = if n.is_finite() {
        n.clamp(1.0, 10_000.0) as usize
    } else {
        1
    };
    for j in 1..=n {
        let t = t0 + (t1 - t0) * j as f64 / n as f64;
        tracker.update(&joints_at(t));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn circle_through_three_points_of_a_unit_circle() {
        let (k, n) = circle_curvature([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]);
        assert!((k - 1.0).abs() < 1e-12);
        assert!((n[1] + 1.0).abs() < 1e-12);
    }

    #[test]
    fn collinear_points_have_no_curvature() {
        let (k, n) = circle_curvature([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], [2.0, 2.0, 2.0]);
        assert_eq!(k, 0.0);
        assert_eq!(n, [0.0; 3]);
    }
}
