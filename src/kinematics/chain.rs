//! The serial chain of any five-axis machine (kinematics.md "Any five-axis machine"):
//! its description ([`MachineChain`]) and its evaluation at a pose, nominal or with
//! error values ([`ChainPose`]).
//!
//! A machine is two chains that meet at the bed: the axes that carry the workpiece
//! (`W = T_w1·T_w2·…`, bed → part) and those that carry the tool (`S = T_t1·T_t2·…`,
//! bed → spindle, the gauge offset `g = L·u₀` inserted after the last tool-side
//! linear axis, within Z's factor when Z is on the tool side). Every axis is
//! described at the home pose in machine coordinates. The tool tip is `S·(−g)`, the
//! tool axis `S·u₀`; in part coordinates `r = W⁻¹·tip`, `u = W⁻¹·(S·u₀)`.
//!
//! Invariants: no I/O, no allocation (fixed arrays); every inverse is the exact
//! inverse of the matrix as written.
use super::error_values::{ErrorValues, ParameterLayout};
use super::transform::{Affine, Mat3, add, cross, dot, mat_mul, mat_vec, norm, scale, sub};
use crate::axes::{Axes, Axis, AxisSet};

/// µm → mm.
const UM: f64 = 1e-3;
/// µrad → rad.
const URAD: f64 = 1e-6;
/// Axes on one side at most (X Y Z U V W and two rotaries).
pub const MAX_SIDE: usize = 8;

/// The side of the bed an axis sits on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Side {
    /// Carries the workpiece (a table): a positive linear joint moves the table by
    /// `−q·d` so that the tool moves `+q·d` relative to the part (ISO 841).
    Workpiece,
    /// Carries the tool (a carriage or a head).
    Tool,
}

/// One axis of the chain at the home pose.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ChainAxis {
    pub axis: Axis,
    /// Nominal unit direction (machine coordinates at home).
    pub direction: [f64; 3],
    /// Rotary only: the reference point on the axis line (workpiece side: machine
    /// coordinates; tool side: relative to the gauge point).
    pub point: [f64; 3],
    /// +1, or −1 where the joint is negated before the formulas (xyzac-trt's
    /// `conventional_directions`: the table is still looked up at the commanded value).
    pub joint_sign: f64,
}

impl ChainAxis {
    pub fn linear(axis: Axis, direction: [f64; 3]) -> ChainAxis {
        ChainAxis {
            axis,
            direction,
            point: [0.0; 3],
            joint_sign: 1.0,
        }
    }

    pub fn rotary(axis: Axis, direction: [f64; 3], point: [f64; 3]) -> ChainAxis {
        ChainAxis {
            axis,
            direction,
            point,
            joint_sign: 1.0,
        }
    }

    pub fn is_rotary(&self) -> bool {
        self.axis.is_rotary()
    }
}

/// Why a chain description is not a five-axis machine.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChainError {
    #[error("axis {0} appears twice")]
    Repeated(char),
    #[error("the machine needs the linear axes X, Y and Z: {0} is missing")]
    MissingLinear(char),
    #[error("the machine needs exactly two rotary axes (of A, B, C), it has {0}")]
    RotaryCount(usize),
    #[error(
        "on the tool side rotary axes come after the linear ones (a head is carried by the carriages): {rotary} comes before {linear}"
    )]
    HeadBeforeCarriage { rotary: char, linear: char },
    #[error("axis {0}: the direction is the zero vector or not finite")]
    BadDirection(char),
    #[error("axis {0}: the point is not finite")]
    BadPoint(char),
    #[error("tool_axis is the zero vector or not finite")]
    BadToolAxis,
    #[error(
        "the rotary axes {0} and {1} are parallel: the machine cannot orient the tool (two rotary axes must not be parallel)"
    )]
    ParallelRotaries(char, char),
    #[error(
        "the tool axis is parallel to rotary axis {0}, the one nearest the tool: that axis cannot orient the tool"
    )]
    ToolAxisAlongRotary(char),
}

/// The nominal description of a serial five-axis machine (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MachineChain {
    workpiece: [ChainAxis; MAX_SIDE],
    workpiece_len: usize,
    tool: [ChainAxis; MAX_SIDE],
    tool_len: usize,
    /// `u₀`, tip → spindle at home (unit).
    tool_axis: [f64; 3],
    /// The machine's two rotary letters in letter order (slots 3 and 4 of the joint
    /// vector and of [`ErrorValues::component`]).
    rotary: [Axis; 2],
    letters: AxisSet,
    /// Index in `tool` after which `Trans(g)` acts when Z is not on the tool side
    /// (0: at the start), `None` when it is within Z's factor.
    gauge_after: Option<usize>,
    /// The two rotations from part to tool, outermost first: `u = R(e₁, φ₁)·R(e₂, φ₂)·u₀`
    /// with `φ = sign·joint_sign·q`; (axis, side sign).
    orientation: [(Axis, f64); 2],
}

const PLACEHOLDER: ChainAxis = ChainAxis {
    axis: Axis::X,
    direction: [1.0, 0.0, 0.0],
    point: [0.0; 3],
    joint_sign: 1.0,
};

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = norm(v);
    (n.is_finite() && n > 1e-12).then(|| scale(v, 1.0 / n))
}

impl MachineChain {
    /// Validates and normalises a chain: X, Y, Z once each, exactly two of A B C,
    /// U V W optional, each letter once; rotary axes on the tool side after its
    /// linear axes; directions non-zero (normalised here); the rotaries not parallel.
    pub fn new(
        workpiece_side: &[ChainAxis],
        tool_side: &[ChainAxis],
        tool_axis: [f64; 3],
    ) -> Result<MachineChain, ChainError> {
        let mut letters = AxisSet::EMPTY;
        let mut rotary = Vec::new();
        for a in workpiece_side.iter().chain(tool_side) {
            if letters.contains(a.axis) {
                return Err(ChainError::Repeated(a.axis.letter()));
            }
            letters = letters.with(a.axis);
            if a.is_rotary() {
                rotary.push(a.axis);
            }
        }
        for l in [Axis::X, Axis::Y, Axis::Z] {
            if !letters.contains(l) {
                return Err(ChainError::MissingLinear(l.letter()));
            }
        }
        if rotary.len() != 2 || workpiece_side.len() > MAX_SIDE || tool_side.len() > MAX_SIDE {
            return Err(ChainError::RotaryCount(rotary.len()));
        }
        rotary.sort();
        if let Some(first_rotary) = tool_side.iter().position(|a| a.is_rotary())
            && let Some(late) = tool_side[first_rotary..].iter().find(|a| !a.is_rotary())
        {
            return Err(ChainError::HeadBeforeCarriage {
                rotary: tool_side[first_rotary].axis.letter(),
                linear: late.axis.letter(),
            });
        }
        let normalise = |a: &ChainAxis| -> Result<ChainAxis, ChainError> {
            let direction = unit(a.direction).ok_or(ChainError::BadDirection(a.axis.letter()))?;
            if !a.point.iter().all(|v| v.is_finite()) {
                return Err(ChainError::BadPoint(a.axis.letter()));
            }
            Ok(ChainAxis { direction, ..*a })
        };
        let mut workpiece = [PLACEHOLDER; MAX_SIDE];
        for (slot, a) in workpiece.iter_mut().zip(workpiece_side) {
            *slot = normalise(a)?;
        }
        let mut tool = [PLACEHOLDER; MAX_SIDE];
        for (slot, a) in tool.iter_mut().zip(tool_side) {
            *slot = normalise(a)?;
        }
        let tool_axis = unit(tool_axis).ok_or(ChainError::BadToolAxis)?;
        let gauge_after = if tool_side.iter().any(|a| a.axis == Axis::Z) {
            None
        } else {
            Some(
                tool_side
                    .iter()
                    .rposition(|a| !a.is_rotary())
                    .map_or(0, |i| i + 1),
            )
        };
        // Rotations from the part to the tool: the workpiece rotaries reversed with
        // negated angles, then the tool rotaries in order.
        let mut orientation = Vec::with_capacity(2);
        for a in workpiece_side.iter().rev().filter(|a| a.is_rotary()) {
            orientation.push((a.axis, -1.0));
        }
        for a in tool_side.iter().filter(|a| a.is_rotary()) {
            orientation.push((a.axis, 1.0));
        }
        let chain = MachineChain {
            workpiece,
            workpiece_len: workpiece_side.len(),
            tool,
            tool_len: tool_side.len(),
            tool_axis,
            rotary: [rotary[0], rotary[1]],
            letters,
            gauge_after,
            orientation: [orientation[0], orientation[1]],
        };
        let (e1, e2) = (
            chain.axis(orientation[0].0).direction,
            chain.axis(orientation[1].0).direction,
        );
        if norm(cross(e1, e2)) < 1e-9 {
            return Err(ChainError::ParallelRotaries(
                orientation[0].0.letter(),
                orientation[1].0.letter(),
            ));
        }
        if norm(cross(e2, tool_axis)) < 1e-9 {
            return Err(ChainError::ToolAxisAlongRotary(orientation[1].0.letter()));
        }
        Ok(chain)
    }

    /// The axes carrying the workpiece, bed → part.
    pub fn workpiece_side(&self) -> &[ChainAxis] {
        &self.workpiece[..self.workpiece_len]
    }

    /// The axes carrying the tool, bed → spindle.
    pub fn tool_side(&self) -> &[ChainAxis] {
        &self.tool[..self.tool_len]
    }

    /// The description of letter `axis` (which must be the machine's).
    pub fn axis(&self, axis: Axis) -> &ChainAxis {
        self.workpiece_side()
            .iter()
            .chain(self.tool_side())
            .find(|a| a.axis == axis)
            .unwrap_or(&PLACEHOLDER)
    }

    /// The side `axis` sits on (`None`: not the machine's).
    pub fn side_of(&self, axis: Axis) -> Option<Side> {
        if self.workpiece_side().iter().any(|a| a.axis == axis) {
            Some(Side::Workpiece)
        } else if self.tool_side().iter().any(|a| a.axis == axis) {
            Some(Side::Tool)
        } else {
            None
        }
    }

    /// `u₀`.
    pub fn tool_axis(&self) -> [f64; 3] {
        self.tool_axis
    }

    /// The two rotary letters, in letter order.
    pub fn rotary(&self) -> [Axis; 2] {
        self.rotary
    }

    /// Every letter of the machine.
    pub fn letters(&self) -> AxisSet {
        self.letters
    }

    /// Names of the error parameters of this machine.
    pub fn layout(&self) -> ParameterLayout {
        ParameterLayout::new(self.rotary)
    }

    /// The rotations from part to tool, outermost first (see the field).
    pub(crate) fn orientation(&self) -> [(Axis, f64); 2] {
        self.orientation
    }

    /// The same machine with every rotary joint negated before the formulas (LinuxCNC's
    /// `conventional-directions = 1`).
    pub fn with_negated_rotaries(mut self) -> MachineChain {
        for a in self.workpiece.iter_mut().chain(self.tool.iter_mut()) {
            if a.is_rotary() {
                a.joint_sign = -a.joint_sign;
            }
        }
        self
    }

    /// The joint vector `(x, y, z, r₁, r₂)` of a position (rotaries in letter order).
    #[inline]
    pub fn joints(&self, q: &Axes) -> [f64; 5] {
        [q.x, q.y, q.z, q.get(self.rotary[0]), q.get(self.rotary[1])]
    }

    /// `q` with its five joints replaced by `j` (U V W kept).
    #[inline]
    pub fn with_joints(&self, q: &Axes, j: [f64; 5]) -> Axes {
        let mut out = *q;
        out.x = j[0];
        out.y = j[1];
        out.z = j[2];
        out.set(self.rotary[0], j[3]);
        out.set(self.rotary[1], j[4]);
        out
    }

    /// Slot of `axis` in the joint vector and in [`ErrorValues::component`].
    #[inline]
    pub fn slot(&self, axis: Axis) -> Option<usize> {
        match axis {
            Axis::X => Some(0),
            Axis::Y => Some(1),
            Axis::Z => Some(2),
            a if a == self.rotary[0] => Some(3),
            a if a == self.rotary[1] => Some(4),
            _ => None,
        }
    }
}

/// The transform `R(d, θ)`, right-handed about the unit `d`, from `sin θ`, `cos θ`.
#[inline]
pub fn rotation(d: [f64; 3], s: f64, c: f64) -> Mat3 {
    let k = 1.0 - c;
    let [x, y, z] = d;
    [
        [c + x * x * k, x * y * k - z * s, x * z * k + y * s],
        [y * x * k + z * s, c + y * y * k, y * z * k - x * s],
        [z * x * k - y * s, z * y * k + x * s, c + z * z * k],
    ]
}

/// The location matrix `L(δ, ε)` of rotary axis `axis` from its five location
/// values (kinematics.md: two offsets, two tilts, zero offset, named by the letter).
fn location_matrix(axis: Axis, v: &[f64]) -> Affine {
    let k = match axis {
        Axis::A => 0,
        Axis::B => 1,
        _ => 2,
    };
    let (i, j) = match k {
        0 => (1, 2),
        1 => (0, 2),
        _ => (0, 1),
    };
    let mut delta = [0.0; 3];
    let mut eps = [0.0; 3];
    delta[i] = v[0] * UM;
    delta[j] = v[1] * UM;
    eps[i] = v[2] * URAD;
    eps[j] = v[3] * URAD;
    Affine::small(delta, eps)
}

fn component(errors: &ErrorValues, slot: usize) -> Affine {
    let c = &errors.component[slot];
    Affine::small(
        [c[0] * UM, c[1] * UM, c[2] * UM],
        [c[3] * URAD, c[4] * URAD, c[5] * URAD],
    )
}

/// One factor `T_K` of a side, with what its derivative needs.
#[derive(Clone, Copy, Debug)]
struct Factor {
    transform: Affine,
    /// Linear: `s·d` (the derivative of the translation per mm). Rotary: unused.
    travel: [f64; 3],
    rotary: Option<RotaryFactor>,
}

#[derive(Clone, Copy, Debug)]
struct RotaryFactor {
    /// `L` (location), `R`, `E·L⁻¹·Trans(−p)` pieces: `T = Trans(p)·L·R·E·L⁻¹·Trans(−p)`.
    location: Affine,
    rotation: Mat3,
    /// `E·L⁻¹·Trans(−p)`.
    inner: Affine,
    direction: [f64; 3],
    /// `joint_sign·π/180`: dθ/dq in rad per degree.
    per_degree: f64,
}

impl Factor {
    /// `∂T/∂q · x` (a vector) at the factor's output point `x` (the point the factor
    /// maps, i.e. expressed in the factor's child frame).
    #[inline]
    fn derivative(&self, x: [f64; 3]) -> [f64; 3] {
        match &self.rotary {
            None => self.travel,
            Some(r) => {
                let y = mat_vec(&r.rotation, r.inner.apply_point(x));
                let dy = cross(r.direction, y);
                scale(r.location.apply_vector(dy), r.per_degree)
            }
        }
    }

    /// `∂(rotation part of T)/∂q · v` for a direction `v` in the child frame.
    #[inline]
    fn derivative_vector(&self, v: [f64; 3]) -> [f64; 3] {
        match &self.rotary {
            None => [0.0; 3],
            Some(r) => {
                let y = mat_vec(&r.rotation, r.inner.apply_vector(v));
                scale(r.location.apply_vector(cross(r.direction, y)), r.per_degree)
            }
        }
    }
}

/// The factors of one side and their prefix products.
#[derive(Clone, Copy, Debug)]
struct SideEval {
    factors: [Factor; MAX_SIDE + 1],
    /// Letter of each factor (`None` for the gauge offset).
    letters: [Option<Axis>; MAX_SIDE + 1],
    len: usize,
    /// `prefix[k]` = product of factors before `k`; `prefix[len]` = the whole side.
    prefix: [Affine; MAX_SIDE + 2],
}

const NO_FACTOR: Factor = Factor {
    transform: Affine::IDENTITY,
    travel: [0.0; 3],
    rotary: None,
};

impl SideEval {
    fn new() -> SideEval {
        SideEval {
            factors: [NO_FACTOR; MAX_SIDE + 1],
            letters: [None; MAX_SIDE + 1],
            len: 0,
            prefix: [Affine::IDENTITY; MAX_SIDE + 2],
        }
    }

    #[inline]
    fn push(&mut self, letter: Option<Axis>, f: Factor) {
        let k = self.len;
        self.factors[k] = f;
        self.letters[k] = letter;
        self.prefix[k + 1] = self.prefix[k].mul(&f.transform);
        self.len += 1;
    }

    #[inline]
    fn total(&self) -> &Affine {
        &self.prefix[self.len]
    }

    fn index_of(&self, axis: Axis) -> Option<usize> {
        self.letters[..self.len].iter().position(|l| *l == Some(axis))
    }

    /// `∂(side · x)/∂q_axis` for a point `x` in the side's end frame: the factor's
    /// derivative at the point it maps, carried through the prefix's rotation.
    fn point_derivative(&self, k: usize, x: [f64; 3]) -> [f64; 3] {
        // The point in factor k's child frame: suffix product applied to x.
        let mut p = x;
        for f in self.factors[k + 1..self.len].iter().rev() {
            p = f.transform.apply_point(p);
        }
        self.prefix[k].apply_vector(self.factors[k].derivative(p))
    }

    /// As [`SideEval::point_derivative`] for a direction.
    fn vector_derivative(&self, k: usize, v: [f64; 3]) -> [f64; 3] {
        let mut p = v;
        for f in self.factors[k + 1..self.len].iter().rev() {
            p = f.transform.apply_vector(p);
        }
        self.prefix[k].apply_vector(self.factors[k].derivative_vector(p))
    }
}

/// The chain evaluated at one pose with one set of error values.
#[derive(Clone, Copy, Debug)]
pub struct ChainPose {
    workpiece: SideEval,
    tool: SideEval,
    /// `W⁻¹`.
    work_inv: Affine,
    /// `−g`, the tip in the spindle frame.
    tip_local: [f64; 3],
    tool_axis: [f64; 3],
    /// Tool tip in machine (bed) coordinates.
    tip_machine: [f64; 3],
}

impl ChainPose {
    /// Evaluates `chain` at `q` with `errors` and a tool of `tool_length` mm.
    pub fn new(
        chain: &MachineChain,
        tool_length: f64,
        q: &Axes,
        errors: &ErrorValues,
    ) -> ChainPose {
        let s = &errors.squareness;
        // Actual travel directions of X Y Z with squareness (kinematics.md).
        let (dx, dy, dz) = (
            chain.axis(Axis::X).direction,
            chain.axis(Axis::Y).direction,
            chain.axis(Axis::Z).direction,
        );
        let d_y = sub(dy, scale(dx, s[0] * URAD));
        let d_z = sub(sub(dz, scale(dx, s[1] * URAD)), scale(dy, s[2] * URAD));
        let direction_of = |a: &ChainAxis| match a.axis {
            Axis::X => dx,
            Axis::Y => d_y,
            Axis::Z => d_z,
            _ => a.direction,
        };
        let g = scale(chain.tool_axis, tool_length);
        let factor = |a: &ChainAxis, side_sign: f64, gauge: [f64; 3]| -> Factor {
            let value = q.get(a.axis);
            let slot = chain.slot(a.axis);
            let e = slot.map_or(Affine::IDENTITY, |k| component(errors, k));
            if a.is_rotary() {
                let offset_index = if a.axis == chain.rotary[0] { 0 } else { 5 };
                let loc = &errors.location[offset_index..offset_index + 5];
                let location = location_matrix(a.axis, loc);
                let location_inv = location.inverse();
                let theta = (a.joint_sign * value).to_radians() + loc[4] * URAD;
                let (sn, cs) = theta.sin_cos();
                let rotation = rotation(a.direction, sn, cs);
                let inner = e
                    .mul(&location_inv)
                    .mul(&Affine::translation(scale(a.point, -1.0)));
                let transform = Affine::translation(a.point)
                    .mul(&location)
                    .mul(&Affine {
                        m: rotation,
                        t: [0.0; 3],
                    })
                    .mul(&inner);
                Factor {
                    transform,
                    travel: [0.0; 3],
                    rotary: Some(RotaryFactor {
                        location,
                        rotation,
                        inner,
                        direction: a.direction,
                        per_degree: a.joint_sign * std::f64::consts::PI / 180.0,
                    }),
                }
            } else {
                let travel = scale(direction_of(a), side_sign);
                // Trans(s·q·d + gauge)·E
                let t = add(scale(travel, value), gauge);
                Factor {
                    transform: Affine {
                        m: e.m,
                        t: add(e.t, t),
                    },
                    travel,
                    rotary: None,
                }
            }
        };
        let mut workpiece = SideEval::new();
        for a in chain.workpiece_side() {
            workpiece.push(Some(a.axis), factor(a, -1.0, [0.0; 3]));
        }
        let mut tool = SideEval::new();
        if chain.gauge_after == Some(0) {
            tool.push(None, gauge_factor(g));
        }
        for (k, a) in chain.tool_side().iter().enumerate() {
            let gauge = if a.axis == Axis::Z { g } else { [0.0; 3] };
            tool.push(Some(a.axis), factor(a, 1.0, gauge));
            if chain.gauge_after == Some(k + 1) {
                tool.push(None, gauge_factor(g));
            }
        }
        let tip_local = scale(g, -1.0);
        let tip_machine = tool.total().apply_point(tip_local);
        ChainPose {
            work_inv: workpiece.total().inverse(),
            workpiece,
            tool,
            tip_local,
            tool_axis: chain.tool_axis,
            tip_machine,
        }
    }

    /// Tool tip in part coordinates, mm.
    #[inline]
    pub fn tip(&self) -> [f64; 3] {
        self.work_inv.apply_point(self.tip_machine)
    }

    /// Tool axis in part coordinates (not re-normalised).
    #[inline]
    pub fn axis(&self) -> [f64; 3] {
        self.work_inv
            .apply_vector(self.tool.total().apply_vector(self.tool_axis))
    }

    /// Tool tip in machine (bed) coordinates, mm.
    pub fn tip_machine(&self) -> [f64; 3] {
        self.tip_machine
    }

    /// `W⁻¹`: machine (bed) coordinates → part coordinates.
    pub fn machine_to_part(&self) -> &Affine {
        &self.work_inv
    }

    /// `∂tip/∂q` (part coordinates, mm per mm or per degree) for the machine's joint
    /// `axis`, error values held fixed.
    pub fn tip_derivative(&self, axis: Axis) -> [f64; 3] {
        if let Some(k) = self.tool.index_of(axis) {
            let d = self.tool.point_derivative(k, self.tip_local);
            self.work_inv.apply_vector(d)
        } else if let Some(k) = self.workpiece.index_of(axis) {
            // ∂(W⁻¹·p) = −W⁻¹·∂W·W⁻¹·p
            let r = self.tip();
            let d = self.workpiece.point_derivative(k, r);
            scale(self.work_inv.apply_vector(d), -1.0)
        } else {
            [0.0; 3]
        }
    }

    /// `∂(tool axis)/∂q` (part coordinates, per degree) for rotary joint `axis`.
    pub fn axis_derivative(&self, axis: Axis) -> [f64; 3] {
        if let Some(k) = self.tool.index_of(axis) {
            let d = self.tool.vector_derivative(k, self.tool_axis);
            self.work_inv.apply_vector(d)
        } else if let Some(k) = self.workpiece.index_of(axis) {
            let u = self.axis();
            let d = self.workpiece.vector_derivative(k, u);
            scale(self.work_inv.apply_vector(d), -1.0)
        } else {
            [0.0; 3]
        }
    }
}

fn gauge_factor(g: [f64; 3]) -> Factor {
    Factor {
        transform: Affine::translation(g),
        travel: [0.0; 3],
        rotary: None,
    }
}

/// The nominal rotation part → tool of the rotary joints alone:
/// `R(e₁, φ₁)·R(e₂, φ₂)` (see [`MachineChain::orientation`]).
pub fn nominal_orientation(chain: &MachineChain, q: &Axes) -> Mat3 {
    let mut m = super::transform::IDENTITY3;
    for (axis, sign) in chain.orientation() {
        let a = chain.axis(axis);
        let theta = (sign * a.joint_sign * q.get(axis)).to_radians();
        let (s, c) = theta.sin_cos();
        m = mat_mul(&m, &rotation(a.direction, s, c));
    }
    m
}

/// Paden–Kahan subproblem 1: the angle (rad) that turns `p` into `q` about the unit
/// `e` (both projected on the plane square to `e`); `None` when `p` or `q` lies on
/// the axis (any angle does).
pub fn angle_about(e: [f64; 3], p: [f64; 3], q: [f64; 3]) -> Option<f64> {
    let pp = sub(p, scale(e, dot(e, p)));
    let qq = sub(q, scale(e, dot(e, q)));
    if norm(pp) < 1e-12 || norm(qq) < 1e-12 {
        return None;
    }
    Some(dot(e, cross(pp, qq)).atan2(dot(pp, qq)))
}

/// The angle between two vectors, radians in [0, π], accurate near 0 and π.
pub fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm(cross(a, b)).atan2(dot(a, b))
}

/// Paden–Kahan subproblem 2, in a form that stays accurate near the singular pose:
/// the angles `φ₂` (radians) with `angle(e₁, R(e₂, φ₂)·p) = angle(e₁, q)`, so that a
/// rotation about `e₁` then takes `R(e₂, φ₂)·p` to `q` (unit vectors; `e₁`, `e₂` not
/// parallel). Zero, one (tangent) or two solutions.
///
/// `e₁·R(e₂, φ)·p = k + R·cos(φ − ψ)` ranges over `[cos θ₁, cos θ₀]` with `θ₀`, `θ₁`
/// the least and largest angle from `e₁` to the cone of `p` about `e₂`; the half
/// angle `h = (φ − ψ)/2` follows from `sin²h = sin((θ + θ₀)/2)·sin((θ − θ₀)/2) / R`,
/// every factor an angle computed by `atan2` (no `1 − cos` cancellation).
pub fn inner_angles(e1: [f64; 3], e2: [f64; 3], p: [f64; 3], q: [f64; 3]) -> Vec<f64> {
    let p_perp = sub(p, scale(e2, dot(e2, p)));
    let (a, b) = (dot(e1, p_perp), dot(e1, cross(e2, p_perp)));
    let r = a.hypot(b);
    if r < 1e-15 {
        return Vec::new();
    }
    let psi = b.atan2(a);
    let beta = angle_between(e1, e2);
    let alpha = angle_between(p, e2);
    let theta = angle_between(e1, q);
    let theta0 = (beta - alpha).abs();
    let s2 = ((theta + theta0) / 2.0).sin() * ((theta - theta0) / 2.0).sin() / r;
    if !(-1e-12..=1.0 + 1e-12).contains(&s2) {
        return Vec::new();
    }
    let h = s2.clamp(0.0, 1.0).sqrt().asin();
    if h < 1e-15 {
        return vec![psi];
    }
    vec![psi + 2.0 * h, psi - 2.0 * h]
}
