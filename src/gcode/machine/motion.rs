//! What the interpreter says about each block: the contract between the G-code
//! front end and everything downstream (toolpath sampling, compensation, diff).
//!
//! All values are absolute, in mm and degrees (G20 input is converted), in the
//! frame the block was programmed in. `gcode` knows nothing about kinematics:
//! a part-frame target is reported as programmed, and the layers that know the
//! machine turn it into joints: a consumer takes a target as a [`Pose`]
//! ([`Motion::end_pose`]), tagged with its frame, and `toolpath::joints_of` is
//! the one conversion.
use crate::axes::{Axes, Joints};
use serde::{Deserialize, Serialize};

/// The frame of a block's `X Y Z` words (gcode.md "Joint programs and tool-tip programs").
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Frame {
    /// Axis commands: X Y Z machine coordinates of the tool tip, A C degrees.
    #[default]
    Joint,
    /// Tool tip in part coordinates (M428, G43.4, G234, TRAORI active); A C degrees.
    Part,
}

/// A target that says its frame: what a motion block commands. A joint-frame
/// (or G53) target is a joint position as it stands; a part-frame target is
/// the tool tip in part coordinates with the rotary joints (and U V W) as
/// given, and becomes joints only through the machine's kinematics
/// (`toolpath::joints_of`, the one conversion; `gcode` knows no kinematics).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Pose {
    /// Machine joints (axis commands).
    Joint(Joints),
    /// Tool tip in part coordinates, rotary joints as given.
    Part(Axes),
}

impl Pose {
    /// The pose of the values `axes` given in `frame`.
    pub fn in_frame(frame: Frame, axes: Axes) -> Pose {
        match frame {
            Frame::Joint => Pose::Joint(Joints::new(axes)),
            Frame::Part => Pose::Part(axes),
        }
    }

    /// Its frame.
    pub fn frame(&self) -> Frame {
        match self {
            Pose::Joint(_) => Frame::Joint,
            Pose::Part(_) => Frame::Part,
        }
    }

    /// Its values in its own frame (the numbers a block writes).
    pub fn axes(&self) -> Axes {
        match self {
            Pose::Joint(j) => j.axes(),
            Pose::Part(p) => *p,
        }
    }
}

/// Arc plane (G17/G18/G19).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum Plane {
    /// G17.
    #[default]
    XY,
    /// G18.
    ZX,
    /// G19.
    YZ,
}

/// The path of a [`Motion`] between its start and end.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum MotionKind {
    /// G0.
    Rapid,
    /// G1.
    Linear,
    /// G2 (clockwise) or G3, about `centre` (absolute, same frame as the targets),
    /// in `plane`; `turns` extra full turns (P word), helical along the plane normal.
    Arc {
        /// G2 (clockwise) rather than G3 (counter-clockwise).
        clockwise: bool,
        /// The centre, X Y Z in mm, absolute, in the frame of the targets.
        centre: [f64; 3],
        /// The arc's plane (G17/G18/G19).
        plane: Plane,
        /// Full turns beyond the first sweep (the P word − 1; 0 without P).
        turns: u32,
    },
}

/// Feed of a motion block.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Feed {
    /// G0 at the machine's rapid rate.
    Rapid,
    /// G94: mm/min (converted from in/min under G20).
    PerMinute(f64),
    /// G93: the block takes 1/F minutes.
    InverseTime(f64),
}

/// One motion block, absolute and resolved.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Motion {
    /// Rapid, linear or arc.
    pub kind: MotionKind,
    /// The frame of `start` and `end` (joint: axis commands; part: tool tip).
    pub frame: Frame,
    /// G53: the targets are machine coordinates for this block only.
    pub machine_coordinates: bool,
    /// Where the move starts: absolute, mm and degrees, in `frame` (the
    /// numbers as programmed; [`Motion::start_pose`] says their frame, G53
    /// included, and is what converts to joints).
    pub start: Axes,
    /// Where the move ends: absolute, mm and degrees, in `frame` (see
    /// [`Motion::end_pose`]).
    pub end: Axes,
    /// The feed it runs at.
    pub feed: Feed,
    /// Duration in minutes from the programmed coordinates (effects.md rules:
    /// XYZ path length / F, or √(Δa²+Δc²)/F when only A/C move, G0 at the rapid
    /// rate, 1/F under G93). For part-frame blocks the toolpath layer recomputes
    /// it from the machine path.
    pub duration_min: f64,
}

impl Motion {
    /// The frame its targets are really in: G53 targets are machine
    /// coordinates (joints) whatever the program's frame.
    pub fn target_frame(&self) -> Frame {
        if self.machine_coordinates {
            Frame::Joint
        } else {
            self.frame
        }
    }

    /// A point of this move (its start, end, [`Motion::point_at`] or
    /// [`Motion::interpolate`]) as the pose it is, in [`Motion::target_frame`].
    pub fn pose(&self, point: Axes) -> Pose {
        Pose::in_frame(self.target_frame(), point)
    }

    /// Where the move starts, tagged with its frame.
    pub fn start_pose(&self) -> Pose {
        self.pose(self.start)
    }

    /// Where the move ends, tagged with its frame.
    pub fn end_pose(&self) -> Pose {
        self.pose(self.end)
    }

    /// Points along the move at most `max_step` apart (XYZ distance in the move's
    /// frame; rotary-only moves are stepped so that no axis moves more than
    /// `max_step` degrees), excluding the start and including the end. Arcs are
    /// interpolated on the circle (helix), A/C linearly in the arc parameter.
    pub fn interpolate(&self, max_step: f64) -> Vec<Axes> {
        let mut out = Vec::new();
        self.interpolate_into(max_step, &mut out);
        out
    }

    /// As [`Motion::interpolate`], appending to `out`.
    pub fn interpolate_into(&self, max_step: f64, out: &mut Vec<Axes>) {
        let step = if max_step.is_finite() && max_step > 0.0 {
            max_step
        } else {
            0.5
        };
        let arc = self.arc_geometry();
        let len = arc.map_or_else(|| self.start.xyz_distance(&self.end), |g| g.length());
        let rot = self.start.rotary_max_step(&self.end);
        let n = ((len.max(rot) / step).ceil() as usize).clamp(1, 1_000_000);
        for i in 1..n {
            out.push(self.point_at(arc.as_ref(), i as f64 / n as f64));
        }
        out.push(self.end);
    }

    /// The circle (helix) of an arc move; `None` for straight moves.
    pub fn arc_geometry(&self) -> Option<ArcGeometry> {
        match self.kind {
            MotionKind::Rapid | MotionKind::Linear => None,
            MotionKind::Arc {
                clockwise,
                centre,
                plane,
                turns,
            } => Some(ArcGeometry::new(
                &self.start,
                &self.end,
                centre,
                plane,
                clockwise,
                turns,
            )),
        }
    }

    /// The point at fraction `t` ∈ [0, 1] of the move: all axes linear in `t`,
    /// except X Y Z on the circle of an arc (`arc` = [`Motion::arc_geometry`],
    /// passed in so that callers evaluating many points build it once).
    pub fn point_at(&self, arc: Option<&ArcGeometry>, t: f64) -> Axes {
        let mut p = self.start.lerp(&self.end, t);
        if let Some(g) = arc {
            let xyz = g.point(t);
            p.x = xyz[0];
            p.y = xyz[1];
            p.z = xyz[2];
        }
        p
    }

    /// XYZ path length in the move's frame (arc length for arcs), mm.
    pub fn xyz_length(&self) -> f64 {
        self.arc_geometry()
            .map_or_else(|| self.start.xyz_distance(&self.end), |g| g.length())
    }
}

/// Circle (helix) geometry of an arc in its plane: in-plane coordinates (u, v),
/// normal coordinate w.
#[derive(Clone, Copy, Debug)]
pub struct ArcGeometry {
    plane: Plane,
    centre_uv: [f64; 2],
    radius_start: f64,
    radius_end: f64,
    angle_start: f64,
    sweep: f64,
    w_start: f64,
    w_end: f64,
}

impl ArcGeometry {
    pub fn new(
        start: &Axes,
        end: &Axes,
        centre: [f64; 3],
        plane: Plane,
        clockwise: bool,
        turns: u32,
    ) -> Self {
        let (s, e, c) = (
            to_plane(plane, start.xyz()),
            to_plane(plane, end.xyz()),
            to_plane(plane, centre),
        );
        let a0 = (s[1] - c[1]).atan2(s[0] - c[0]);
        let a1 = (e[1] - c[1]).atan2(e[0] - c[0]);
        let tau = std::f64::consts::TAU;
        let mut sweep = a1 - a0;
        if clockwise {
            while sweep >= -1e-12 {
                sweep -= tau;
            }
            sweep -= tau * turns as f64;
        } else {
            while sweep <= 1e-12 {
                sweep += tau;
            }
            sweep += tau * turns as f64;
        }
        ArcGeometry {
            plane,
            centre_uv: [c[0], c[1]],
            radius_start: ((s[0] - c[0]).powi(2) + (s[1] - c[1]).powi(2)).sqrt(),
            radius_end: ((e[0] - c[0]).powi(2) + (e[1] - c[1]).powi(2)).sqrt(),
            angle_start: a0,
            sweep,
            w_start: s[2],
            w_end: e[2],
        }
    }

    /// The angle swept, radians (negative clockwise), full turns included.
    pub fn sweep(&self) -> f64 {
        self.sweep
    }

    /// The radius at the start and at the end, mm.
    pub fn radii(&self) -> (f64, f64) {
        (self.radius_start, self.radius_end)
    }

    pub fn length(&self) -> f64 {
        let r = 0.5 * (self.radius_start + self.radius_end);
        let planar = r * self.sweep.abs();
        let dw = self.w_end - self.w_start;
        (planar * planar + dw * dw).sqrt()
    }

    /// Point at fraction `t` ∈ [0, 1] of the arc (XYZ).
    pub fn point(&self, t: f64) -> [f64; 3] {
        let ang = self.angle_start + self.sweep * t;
        let r = self.radius_start + (self.radius_end - self.radius_start) * t;
        let u = self.centre_uv[0] + r * ang.cos();
        let v = self.centre_uv[1] + r * ang.sin();
        let w = self.w_start + (self.w_end - self.w_start) * t;
        from_plane(self.plane, [u, v, w])
    }
}

/// `(x, y, z)` → in-plane `(u, v)` and normal `w` coordinates of `plane`.
pub(crate) fn to_plane(plane: Plane, p: [f64; 3]) -> [f64; 3] {
    match plane {
        Plane::XY => [p[0], p[1], p[2]],
        Plane::ZX => [p[2], p[0], p[1]],
        Plane::YZ => [p[1], p[2], p[0]],
    }
}

/// Inverse of [`to_plane`].
pub(crate) fn from_plane(plane: Plane, q: [f64; 3]) -> [f64; 3] {
    match plane {
        Plane::XY => [q[0], q[1], q[2]],
        Plane::ZX => [q[1], q[2], q[0]],
        Plane::YZ => [q[2], q[0], q[1]],
    }
}
