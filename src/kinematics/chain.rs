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
use super::transform::{
    Affine, IDENTITY3, Mat3, add, cross, dot, mat_mul, mat_vec, norm, scale, sub,
};
use crate::axes::{Axes, Axis, AxisSet};
use std::cell::Cell;

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
    /// The axis letter.
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
    /// A linear axis moving along unit `direction` (machine coordinates).
    pub fn linear(axis: Axis, direction: [f64; 3]) -> ChainAxis {
        ChainAxis {
            axis,
            direction,
            point: [0.0; 3],
            joint_sign: 1.0,
        }
    }

    /// A rotary axis turning about unit `direction` through `point`.
    pub fn rotary(axis: Axis, direction: [f64; 3], point: [f64; 3]) -> ChainAxis {
        ChainAxis {
            axis,
            direction,
            point,
            joint_sign: 1.0,
        }
    }

    /// Whether the axis is A, B or C.
    pub fn is_rotary(&self) -> bool {
        self.axis.is_rotary()
    }
}

/// Why a chain description is not a five-axis machine.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ChainError {
    /// An axis letter appears twice.
    #[error("axis {0} appears twice")]
    Repeated(char),
    /// One of X, Y and Z is missing.
    #[error("the machine needs the linear axes X, Y and Z: {0} is missing")]
    MissingLinear(char),
    /// Not exactly two rotary axes (the count given).
    #[error("the machine needs exactly two rotary axes (of A, B, C), it has {0}")]
    RotaryCount(usize),
    /// A tool-side rotary axis is listed before a linear one (a head must be carried by the carriages).
    #[error(
        "on the tool side rotary axes come after the linear ones (a head is carried by the carriages): {rotary} comes before {linear}"
    )]
    HeadBeforeCarriage {
        /// The rotary axis.
        rotary: char,
        /// The linear axis listed after it.
        linear: char,
    },
    /// An axis direction is the zero vector or not finite.
    #[error("axis {0}: the direction is the zero vector or not finite")]
    BadDirection(char),
    /// A rotary axis point is not finite.
    #[error("axis {0}: the point is not finite")]
    BadPoint(char),
    /// The tool axis is the zero vector or not finite.
    #[error("tool_axis is the zero vector or not finite")]
    BadToolAxis,
    /// The two rotary axes are parallel.
    #[error(
        "the rotary axes {0} and {1} are parallel: the machine cannot orient the tool (two rotary axes must not be parallel)"
    )]
    ParallelRotaries(char, char),
    /// The tool axis is parallel to the rotary axis nearest the tool.
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
    /// Nominal directions of X, Y, Z (the squareness formulas use them).
    directions: [[f64; 3]; 3],
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
            directions: [[0.0; 3]; 3],
        };
        let mut chain = chain;
        chain.directions = [Axis::X, Axis::Y, Axis::Z].map(|l| chain.axis(l).direction);
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
/// About X, Y or Z (the usual axis) the same formula with `d`'s entries as
/// constants: the compiler drops the products by 1 (exact) and keeps those by 0
/// (their signs of zero), so the numbers are the general formula's, bit for bit.
#[inline]
pub fn rotation(d: [f64; 3], s: f64, c: f64) -> Mat3 {
    const X: [u64; 3] = [1f64.to_bits(), 0, 0];
    const Y: [u64; 3] = [0, 1f64.to_bits(), 0];
    const Z: [u64; 3] = [0, 0, 1f64.to_bits()];
    match d.map(f64::to_bits) {
        X => rotation_formula([1.0, 0.0, 0.0], s, c),
        Y => rotation_formula([0.0, 1.0, 0.0], s, c),
        Z => rotation_formula([0.0, 0.0, 1.0], s, c),
        _ => rotation_formula(d, s, c),
    }
}

/// The formula of [`rotation`] (inlined where `d` is a constant).
#[inline(always)]
fn rotation_formula(d: [f64; 3], s: f64, c: f64) -> Mat3 {
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
#[inline]
fn location_matrix(axis: Axis, v: &[f64]) -> Affine {
    let (i, j) = match axis {
        Axis::A => (1, 2),
        Axis::B => (0, 2),
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

#[inline]
fn component(errors: &ErrorValues, slot: usize) -> Affine {
    let c = &errors.component[slot];
    Affine::small(
        [c[0] * UM, c[1] * UM, c[2] * UM],
        [c[3] * URAD, c[4] * URAD, c[5] * URAD],
    )
}

/// What an evaluation with errors computes from the position-independent error
/// values alone (squareness and location), computed once per model: the actual
/// directions of Y and Z, each rotary axis' location matrix `L` and its inverse,
/// and the sine and cosine of its zero offset. An evaluation given them
/// ([`Kinematics::actual_tip_and_axis_with`](crate::kinematics::Kinematics::actual_tip_and_axis_with)) computes the same numbers as one without, bit for
/// bit, when they were made for its chain and its values (checked: otherwise
/// they are computed afresh).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainConstants {
    /// What they were made from: the chain's rotary letters and X Y Z
    /// directions, and the values' squareness and location (compared bit for bit).
    rotary: [Axis; 2],
    directions: [[f64; 3]; 3],
    squareness: [f64; 3],
    location: [f64; 10],
    d_y: [f64; 3],
    d_z: [f64; 3],
    /// `L` of each rotary (letter order).
    location_matrix: [Affine; 2],
    /// `L⁻¹`, the exact inverse.
    location_inverse: [Affine; 2],
    /// `(sin δ, cos δ)` of each rotary's zero offset `δ`, `None` when it is 0.
    zero_offset: [Option<(f64, f64)>; 2],
}

impl ChainConstants {
    /// The constants of `chain` with the squareness and location of `errors`.
    pub fn new(chain: &MachineChain, errors: &ErrorValues) -> ChainConstants {
        let (d_y, d_z) = actual_directions(chain, &errors.squareness);
        let location_matrix =
            [0, 1].map(|r| location_matrix(chain.rotary[r], &errors.location[5 * r..5 * r + 5]));
        ChainConstants {
            rotary: chain.rotary,
            directions: chain.directions,
            squareness: errors.squareness,
            location: errors.location,
            d_y,
            d_z,
            location_matrix,
            location_inverse: location_matrix.map(|l| l.inverse()),
            zero_offset: [0, 1].map(|r| offset_sin_cos(errors.location[5 * r + 4] * URAD)),
        }
    }

    /// Whether they are those of `chain` and `errors`.
    #[inline]
    fn serve(&self, chain: &MachineChain, errors: &ErrorValues) -> bool {
        /// Bit for bit (a −0 is not a 0).
        #[inline(always)]
        fn same(a: &[f64], b: &[f64]) -> bool {
            a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
        }
        self.rotary == chain.rotary
            && same(&self.location, &errors.location)
            && same(&self.squareness, &errors.squareness)
            && same(
                self.directions.as_flattened(),
                chain.directions.as_flattened(),
            )
    }
}

/// The actual directions of Y and Z with the squareness values `s` (µrad).
#[inline]
fn actual_directions(chain: &MachineChain, s: &[f64; 3]) -> ([f64; 3], [f64; 3]) {
    let (dx, dy, dz) = (
        chain.directions[0],
        chain.directions[1],
        chain.directions[2],
    );
    (
        sub(dy, scale(dx, s[0] * URAD)),
        sub(sub(dz, scale(dx, s[1] * URAD)), scale(dy, s[2] * URAD)),
    )
}

/// The pieces of a rotary factor `T = Trans(p)·L·R·E·L⁻¹·Trans(−p)`.
#[derive(Clone, Copy, Debug)]
struct RotaryParts {
    /// Rotation part of `L`.
    location: Mat3,
    rotation: Mat3,
    /// `E·L⁻¹·Trans(−p)`.
    inner: Affine,
    direction: [f64; 3],
    /// `dθ/dq`, rad per degree (`joint_sign·π/180`).
    per_degree: f64,
}

impl RotaryParts {
    /// `∂T/∂q · x` for the point `x` the factor maps.
    #[inline]
    fn point_derivative(&self, x: [f64; 3]) -> [f64; 3] {
        let y = mat_vec(&self.rotation, self.inner.apply_point(x));
        scale(
            mat_vec(&self.location, cross(self.direction, y)),
            self.per_degree,
        )
    }

    /// `∂(rotation of T)/∂q · v` for a direction `v`.
    #[inline]
    fn vector_derivative(&self, v: [f64; 3]) -> [f64; 3] {
        let y = mat_vec(&self.rotation, self.inner.apply_vector(v));
        scale(
            mat_vec(&self.location, cross(self.direction, y)),
            self.per_degree,
        )
    }
}

/// What every factor of one evaluation shares: the pose, the error values, the
/// actual travel directions and the gauge offset.
#[derive(Clone, Copy)]
struct Evaluation<'a> {
    chain: &'a MachineChain,
    q: &'a Axes,
    errors: &'a ErrorValues,
    /// Error-free: every `E` and `L` is the identity (skipped).
    nominal: bool,
    /// Actual directions of Y and Z with squareness (X's is its own).
    d_y: [f64; 3],
    d_z: [f64; 3],
    /// `g = L·u₀`.
    gauge: [f64; 3],
    /// `(sin, cos)` of each rotary joint's angle `joint_sign·q` (letter order),
    /// before the zero offset.
    trig: [(f64, f64); 2],
    /// The model's constants, when given and made for these values.
    constants: Option<&'a ChainConstants>,
}

/// Arguments [`sin_cos`] remembers, per thread.
const RECENT_ANGLES: usize = 8;

/// The last [`RECENT_ANGLES`] arguments of [`sin_cos`] on this thread (their
/// bits) and their sines and cosines, replaced in turn.
struct RecentSinCos {
    arguments: [Cell<u64>; RECENT_ANGLES],
    values: [Cell<(f64, f64)>; RECENT_ANGLES],
    next: Cell<usize>,
}

thread_local! {
    static RECENT_SIN_COS: RecentSinCos = const {
        RecentSinCos {
            // A NaN's bits, with NaN values: what `sin_cos` gives it.
            arguments: [const { Cell::new(u64::MAX) }; RECENT_ANGLES],
            values: [const { Cell::new((f64::NAN, f64::NAN)) }; RECENT_ANGLES],
            next: Cell::new(0),
        }
    };
}

/// `x.sin_cos()` (`x` in radians), remembered for the last few arguments of
/// the thread: a solve asks for the same pose's angles several times (its
/// residual, its Jacobian, the axis rows, the pole angle; the split test's
/// first-order step at the turned joints of the map it just made). The same
/// bits as `x.sin_cos()`.
#[inline]
pub(crate) fn sin_cos(x: f64) -> (f64, f64) {
    let bits = x.to_bits();
    RECENT_SIN_COS.with(|recent| {
        for (argument, value) in recent.arguments.iter().zip(&recent.values) {
            if argument.get() == bits {
                return value.get();
            }
        }
        let value = x.sin_cos();
        let k = recent.next.get();
        recent.arguments[k].set(bits);
        recent.values[k].set(value);
        recent.next.set((k + 1) % RECENT_ANGLES);
        value
    })
}

/// `(sin, cos)` of each rotary joint angle of `q` (letter order).
#[inline]
fn joint_trig(chain: &MachineChain, q: &Axes) -> [(f64, f64); 2] {
    chain.rotary.map(|r| {
        let a = chain.axis(r);
        sin_cos((a.joint_sign * q.get(r)).to_radians())
    })
}

/// `(sin, cos)` of `θ + δ` from those of `θ` and a zero offset `δ` (rad): the
/// angle-sum formulas, with the Taylor series of `δ` where it is small (µrad
/// offsets: the series is exact in double precision below 1e-3).
#[inline]
fn plus_offset(trig: (f64, f64), delta: f64) -> (f64, f64) {
    plus_offset_sin_cos(trig, offset_sin_cos(delta))
}

/// `(sin δ, cos δ)` of a zero offset `δ` (rad) as [`plus_offset`] takes them,
/// `None` for 0.
#[inline]
fn offset_sin_cos(delta: f64) -> Option<(f64, f64)> {
    if delta == 0.0 {
        return None;
    }
    Some(if delta.abs() < 1e-3 {
        let d2 = delta * delta;
        (
            delta * (1.0 - d2 / 6.0 * (1.0 - d2 / 20.0)),
            1.0 - d2 / 2.0 * (1.0 - d2 / 12.0 * (1.0 - d2 / 30.0)),
        )
    } else {
        delta.sin_cos()
    })
}

/// [`plus_offset`] from the offset's sine and cosine.
#[inline(always)]
fn plus_offset_sin_cos((s, c): (f64, f64), offset: Option<(f64, f64)>) -> (f64, f64) {
    match offset {
        None => (s, c),
        Some((sd, cd)) => (s * cd + c * sd, c * cd - s * sd),
    }
}

impl<'a> Evaluation<'a> {
    #[inline]
    fn new(
        chain: &'a MachineChain,
        tool_length: f64,
        q: &'a Axes,
        errors: &'a ErrorValues,
        nominal: bool,
    ) -> Evaluation<'a> {
        Evaluation::with_trig(chain, tool_length, q, errors, nominal, joint_trig(chain, q))
    }

    /// [`Evaluation::new`] with the joint angles' sines and cosines given.
    #[inline]
    fn with_trig(
        chain: &'a MachineChain,
        tool_length: f64,
        q: &'a Axes,
        errors: &'a ErrorValues,
        nominal: bool,
        trig: [(f64, f64); 2],
    ) -> Evaluation<'a> {
        Evaluation::with_constants(chain, tool_length, q, errors, nominal, trig, None)
    }

    /// [`Evaluation::with_trig`] with the model's constants (used when they
    /// serve these values).
    #[inline(always)]
    fn with_constants(
        chain: &'a MachineChain,
        tool_length: f64,
        q: &'a Axes,
        errors: &'a ErrorValues,
        nominal: bool,
        trig: [(f64, f64); 2],
        constants: Option<&'a ChainConstants>,
    ) -> Evaluation<'a> {
        let constants = constants.filter(|c| !nominal && c.serve(chain, errors));
        let (d_y, d_z) = match constants {
            _ if nominal => (chain.directions[1], chain.directions[2]),
            Some(c) => (c.d_y, c.d_z),
            None => actual_directions(chain, &errors.squareness),
        };
        Evaluation {
            chain,
            q,
            errors,
            nominal,
            d_y,
            d_z,
            gauge: scale(chain.tool_axis, tool_length),
            trig,
            constants,
        }
    }

    /// The actual travel direction of linear axis `a`.
    #[inline]
    fn direction(&self, a: &ChainAxis) -> [f64; 3] {
        match a.axis {
            Axis::Y => self.d_y,
            Axis::Z => self.d_z,
            _ => a.direction,
        }
    }

    /// `s·d`: the derivative of a linear factor's translation per mm.
    #[inline]
    fn travel(&self, a: &ChainAxis, side_sign: f64) -> [f64; 3] {
        scale(self.direction(a), side_sign)
    }

    /// The location values of rotary `a` and its index (0 or 1, letter order).
    #[inline]
    fn location(&self, a: &ChainAxis) -> (&'a [f64], usize) {
        let r = usize::from(a.axis != self.chain.rotary[0]);
        (&self.errors.location[5 * r..5 * r + 5], r)
    }

    /// `R(d, θ + zero offset)` of rotary `a`.
    #[inline(always)]
    fn rotation_of(&self, a: &ChainAxis) -> Mat3 {
        let (loc, r) = self.location(a);
        let (sn, cs) = match self.constants {
            Some(c) => plus_offset_sin_cos(self.trig[r], c.zero_offset[r]),
            None => {
                let offset = if self.nominal { 0.0 } else { loc[4] * URAD };
                plus_offset(self.trig[r], offset)
            }
        };
        rotation(a.direction, sn, cs)
    }

    /// `L` and `L⁻¹` of rotary `a`.
    #[inline(always)]
    fn location_pair(&self, a: &ChainAxis) -> (Affine, Affine) {
        let (loc, r) = self.location(a);
        match self.constants {
            Some(c) => (c.location_matrix[r], c.location_inverse[r]),
            None => {
                let location = location_matrix(a.axis, loc);
                (location, location.inverse())
            }
        }
    }

    /// The transform of rotary factor `a`: `(L·R·E·L⁻¹)` about its point.
    #[inline(always)]
    fn rotary(&self, a: &ChainAxis) -> Affine {
        let rot = Affine {
            m: self.rotation_of(a),
            t: [0.0; 3],
        };
        if self.nominal {
            return rot.about(a.point);
        }
        let (location, inverse) = self.location_pair(a);
        let e = component(self.errors, self.chain.slot(a.axis).unwrap_or(4));
        location.mul(&rot).mul(&e).mul(&inverse).about(a.point)
    }

    /// The pieces of rotary factor `a` for its derivative.
    fn rotary_parts(&self, a: &ChainAxis) -> RotaryParts {
        let rot = self.rotation_of(a);
        let per_degree = a.joint_sign * std::f64::consts::PI / 180.0;
        let back = Affine::translation(scale(a.point, -1.0));
        if self.nominal {
            return RotaryParts {
                location: IDENTITY3,
                rotation: rot,
                inner: back,
                direction: a.direction,
                per_degree,
            };
        }
        let (location, inverse) = self.location_pair(a);
        let e = component(self.errors, self.chain.slot(a.axis).unwrap_or(4));
        RotaryParts {
            location: location.m,
            rotation: rot,
            inner: e.mul(&inverse).mul(&back),
            direction: a.direction,
            per_degree,
        }
    }

    /// The transform of linear axis `a`: `Trans(s·q·d + gauge)·E`.
    #[inline(always)]
    fn linear(&self, a: &ChainAxis, side_sign: f64, gauge: [f64; 3]) -> Affine {
        let t = add(scale(self.travel(a, side_sign), self.q.get(a.axis)), gauge);
        match (self.nominal, self.chain.slot(a.axis)) {
            (false, Some(slot)) => {
                let e = component(self.errors, slot);
                Affine {
                    m: e.m,
                    t: add(e.t, t),
                }
            }
            _ => Affine::translation(t),
        }
    }

    /// The transform `T_K` of axis `a` on the side with sign `side_sign`.
    #[inline(always)]
    fn factor(&self, a: &ChainAxis, side_sign: f64) -> Affine {
        if a.is_rotary() {
            self.rotary(a)
        } else {
            let gauge = if side_sign > 0.0 && a.axis == Axis::Z {
                self.gauge
            } else {
                [0.0; 3]
            };
            self.linear(a, side_sign, gauge)
        }
    }

    /// Calls `visit(letter, factor)` for every factor of the tool side in order,
    /// `Trans(g)` included (letter `None`).
    #[inline(always)]
    fn tool_factors(&self, mut visit: impl FnMut(Option<&ChainAxis>, Affine)) {
        let chain = self.chain;
        if chain.gauge_after == Some(0) {
            visit(None, Affine::translation(self.gauge));
        }
        for (k, a) in chain.tool_side().iter().enumerate() {
            visit(Some(a), self.factor(a, 1.0));
            if chain.gauge_after == Some(k + 1) {
                visit(None, Affine::translation(self.gauge));
            }
        }
    }

    /// `W` and `S`.
    #[inline(always)]
    fn products(&self) -> (Affine, Affine) {
        let mut w = Affine::IDENTITY;
        for a in self.chain.workpiece_side() {
            w = w.mul_fast(&self.factor(a, -1.0));
        }
        let mut s = Affine::IDENTITY;
        self.tool_factors(|_, f| s = s.mul_fast(&f));
        (w, s)
    }
}

/// The tool tip (mm) and tool axis (not re-normalised) in part coordinates, with
/// no storage: the hot path of every lookup.
#[inline]
pub fn tip_and_axis(
    chain: &MachineChain,
    tool_length: f64,
    q: &Axes,
    errors: &ErrorValues,
    nominal: bool,
) -> ([f64; 3], [f64; 3]) {
    let eval = Evaluation::new(chain, tool_length, q, errors, nominal);
    tip_and_axis_of(&eval)
}

/// The actual [`tip_and_axis`] with a model's [`ChainConstants`] (the same
/// numbers; the constants are used when they serve `errors`).
#[inline]
pub fn tip_and_axis_with(
    chain: &MachineChain,
    tool_length: f64,
    q: &Axes,
    errors: &ErrorValues,
    constants: &ChainConstants,
) -> ([f64; 3], [f64; 3]) {
    let trig = joint_trig(chain, q);
    let eval =
        Evaluation::with_constants(chain, tool_length, q, errors, false, trig, Some(constants));
    tip_and_axis_of(&eval)
}

/// The tip and axis of one evaluation.
#[inline(always)]
fn tip_and_axis_of(eval: &Evaluation<'_>) -> ([f64; 3], [f64; 3]) {
    let chain = eval.chain;
    let (w, s) = eval.products();
    let w_inv = w.inverse();
    let tip = w_inv.apply_point(s.apply_point(scale(eval.gauge, -1.0)));
    let axis = w_inv.apply_vector(s.apply_vector(chain.tool_axis));
    (tip, axis)
}

/// The nominal tool tip at zero linear joints and `∂tip/∂(x, y, z)` (columns), at
/// the rotary joints (and U V W) of `rotaries`: the tip is affine in the linear
/// joints, so `tip = r₀ + J·(x, y, z)` exactly. No storage.
pub fn nominal_linear_map(
    chain: &MachineChain,
    tool_length: f64,
    rotaries: &Axes,
) -> ([f64; 3], [[f64; 3]; 3]) {
    let base = Axes {
        x: 0.0,
        y: 0.0,
        z: 0.0,
        ..*rotaries
    };
    let eval = Evaluation::new(chain, tool_length, &base, &ErrorValues::ZERO, true);
    // W with the rotation before each workpiece linear axis; S (nominal tool-side
    // linear factors are translations before any head rotary: ∂ = the direction).
    let mut w = Affine::IDENTITY;
    let mut columns = [[0.0; 3]; 3];
    let mut work_linear: [(usize, Mat3); 3] = [(3, IDENTITY3); 3];
    for a in chain.workpiece_side() {
        if let Some(i) = linear_slot(a.axis) {
            work_linear[i] = (i, w.m);
        }
        w = w.mul(&eval.factor(a, -1.0));
    }
    let mut s = Affine::IDENTITY;
    eval.tool_factors(|_, f| s = s.mul(&f));
    let w_inv = w.inverse();
    for a in chain.tool_side() {
        if let Some(i) = linear_slot(a.axis) {
            columns[i] = w_inv.apply_vector(a.direction);
        }
    }
    for (i, prefix) in work_linear {
        if i < 3 {
            // ∂(W⁻¹·p)/∂q = −W⁻¹·prefix·(−d)
            columns[i] = w_inv.apply_vector(mat_vec(&prefix, chain.directions[i]));
        }
    }
    let tip = w_inv.apply_point(s.apply_point(scale(eval.gauge, -1.0)));
    (tip, columns)
}

/// 0, 1, 2 for X, Y, Z.
#[inline]
fn linear_slot(axis: Axis) -> Option<usize> {
    match axis {
        Axis::X => Some(0),
        Axis::Y => Some(1),
        Axis::Z => Some(2),
        _ => None,
    }
}

/// `∂u/∂q` (per degree) of the nominal tool axis for the two rotary joints in
/// letter order: with `u = R(e₁, φ₁)·R(e₂, φ₂)·u₀`, `∂u/∂φ₁ = e₁ × u` and
/// `∂u/∂φ₂ = R(e₁, φ₁)·(e₂ × R(e₂, φ₂)·u₀)`.
pub fn nominal_axis_derivatives(chain: &MachineChain, q: &Axes) -> [[f64; 3]; 2] {
    let [(o1, s1), (o2, s2)] = chain.orientation();
    let (a1, a2) = (chain.axis(o1), chain.axis(o2));
    let (k1, k2) = (s1 * a1.joint_sign, s2 * a2.joint_sign);
    let (sn2, cs2) = sin_cos((k2 * q.get(o2)).to_radians());
    let (sn1, cs1) = sin_cos((k1 * q.get(o1)).to_radians());
    let r1 = rotation(a1.direction, sn1, cs1);
    let v = mat_vec(&rotation(a2.direction, sn2, cs2), chain.tool_axis);
    let u = mat_vec(&r1, v);
    let per = std::f64::consts::PI / 180.0;
    let d1 = scale(cross(a1.direction, u), k1 * per);
    let d2 = scale(mat_vec(&r1, cross(a2.direction, v)), k2 * per);
    if o1 == chain.rotary[0] {
        [d1, d2]
    } else {
        [d2, d1]
    }
}

/// The actual and the nominal tool tip and axis (part coordinates) at `q` in one
/// pass: the joint angles' sines and cosines are shared.
#[inline]
pub fn actual_and_nominal(
    chain: &MachineChain,
    tool_length: f64,
    q: &Axes,
    errors: &ErrorValues,
) -> [([f64; 3], [f64; 3]); 2] {
    let trig = joint_trig(chain, q);
    [(errors, false), (&ErrorValues::ZERO, true)].map(|(e, nominal)| {
        let eval = Evaluation::with_trig(chain, tool_length, q, e, nominal, trig);
        let (w, s) = eval.products();
        let w_inv = w.inverse();
        (
            w_inv.apply_point(s.apply_point(scale(eval.gauge, -1.0))),
            w_inv.apply_vector(s.apply_vector(chain.tool_axis)),
        )
    })
}

/// The chain evaluated at one pose with one set of error values, with the prefix
/// products the derivatives need.
pub struct ChainPose<'a> {
    eval: Evaluation<'a>,
    /// Prefix products of the workpiece side: `work[k]` = product of the factors
    /// before `k`; `work[len]` = `W`.
    work: [Affine; MAX_SIDE + 1],
    work_factors: [Affine; MAX_SIDE],
    /// The same for the tool side (with `Trans(g)`).
    tool: [Affine; MAX_SIDE + 2],
    tool_factors: [Affine; MAX_SIDE + 1],
    tool_letters: [Option<Axis>; MAX_SIDE + 1],
    tool_len: usize,
    /// `W⁻¹`.
    work_inv: Affine,
    /// Tool tip in machine (bed) coordinates.
    tip_machine: [f64; 3],
}

impl<'a> ChainPose<'a> {
    /// Evaluates `chain` at `q` with `errors` and a tool of `tool_length` mm
    /// (`nominal`: the errors are all zero and are skipped).
    pub fn new(
        chain: &'a MachineChain,
        tool_length: f64,
        q: &'a Axes,
        errors: &'a ErrorValues,
        nominal: bool,
    ) -> ChainPose<'a> {
        ChainPose::of(Evaluation::new(chain, tool_length, q, errors, nominal))
    }

    /// [`ChainPose::new`] with errors and a model's [`ChainConstants`] (the same
    /// numbers; the constants are used when they serve `errors`).
    pub fn with_constants(
        chain: &'a MachineChain,
        tool_length: f64,
        q: &'a Axes,
        errors: &'a ErrorValues,
        constants: &'a ChainConstants,
    ) -> ChainPose<'a> {
        let trig = joint_trig(chain, q);
        ChainPose::of(Evaluation::with_constants(
            chain,
            tool_length,
            q,
            errors,
            false,
            trig,
            Some(constants),
        ))
    }

    /// The pose of one evaluation.
    fn of(eval: Evaluation<'a>) -> ChainPose<'a> {
        let chain = eval.chain;
        let mut work = [Affine::IDENTITY; MAX_SIDE + 1];
        let mut work_factors = [Affine::IDENTITY; MAX_SIDE];
        for (k, a) in chain.workpiece_side().iter().enumerate() {
            work_factors[k] = eval.factor(a, -1.0);
            work[k + 1] = work[k].mul(&work_factors[k]);
        }
        let mut tool = [Affine::IDENTITY; MAX_SIDE + 2];
        let mut tool_factors = [Affine::IDENTITY; MAX_SIDE + 1];
        let mut tool_letters = [None; MAX_SIDE + 1];
        let mut k = 0;
        eval.tool_factors(|a, f| {
            tool_factors[k] = f;
            tool[k + 1] = tool[k].mul(&f);
            tool_letters[k] = a.map(|a| a.axis);
            k += 1;
        });
        let w = &work[chain.workpiece_len];
        let tip_machine = tool[k].apply_point(scale(eval.gauge, -1.0));
        ChainPose {
            work_inv: w.inverse(),
            eval,
            work,
            work_factors,
            tool,
            tool_factors,
            tool_letters,
            tool_len: k,
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
            .apply_vector(self.tool[self.tool_len].apply_vector(self.eval.chain.tool_axis))
    }

    /// Tool tip in machine (bed) coordinates, mm.
    pub fn tip_machine(&self) -> [f64; 3] {
        self.tip_machine
    }

    /// `W⁻¹`: machine (bed) coordinates → part coordinates.
    pub fn machine_to_part(&self) -> &Affine {
        &self.work_inv
    }

    /// The point `x` of side `factors[k + 1..len]`'s end frame carried back to factor
    /// `k`'s output frame: the suffix product applied to `x`.
    fn suffix_point(&self, side: Side, k: usize, x: [f64; 3], vector: bool) -> [f64; 3] {
        let factors = match side {
            Side::Workpiece => &self.work_factors[k + 1..self.eval.chain.workpiece_len],
            Side::Tool => &self.tool_factors[k + 1..self.tool_len],
        };
        factors.iter().rev().fold(x, |p, f| {
            if vector {
                f.apply_vector(p)
            } else {
                f.apply_point(p)
            }
        })
    }

    /// `∂(factor k of side)·x` (a vector) for a linear or rotary axis `a`.
    fn factor_derivative(
        &self,
        a: &ChainAxis,
        side_sign: f64,
        x: [f64; 3],
        vector: bool,
    ) -> [f64; 3] {
        if a.is_rotary() {
            let parts = self.eval.rotary_parts(a);
            if vector {
                parts.vector_derivative(x)
            } else {
                parts.point_derivative(x)
            }
        } else if vector {
            [0.0; 3]
        } else {
            self.eval.travel(a, side_sign)
        }
    }

    /// `∂tip/∂q` (part coordinates, mm per mm or per degree) for the machine's joint
    /// `axis`, error values held fixed.
    pub fn tip_derivative(&self, axis: Axis) -> [f64; 3] {
        let chain = self.eval.chain;
        if let Some(k) = self.tool_letters[..self.tool_len]
            .iter()
            .position(|l| *l == Some(axis))
        {
            let x = self.suffix_point(Side::Tool, k, scale(self.eval.gauge, -1.0), false);
            let d = self.factor_derivative(chain.axis(axis), 1.0, x, false);
            self.work_inv.apply_vector(self.tool[k].apply_vector(d))
        } else if let Some(k) = chain.workpiece_side().iter().position(|a| a.axis == axis) {
            // ∂(W⁻¹·p) = −W⁻¹·∂W·W⁻¹·p
            let x = self.suffix_point(Side::Workpiece, k, self.tip(), false);
            let d = self.factor_derivative(chain.axis(axis), -1.0, x, false);
            scale(
                self.work_inv.apply_vector(self.work[k].apply_vector(d)),
                -1.0,
            )
        } else {
            [0.0; 3]
        }
    }

    /// `∂(tool axis)/∂q` (part coordinates, per degree) for rotary joint `axis`.
    pub fn axis_derivative(&self, axis: Axis) -> [f64; 3] {
        let chain = self.eval.chain;
        if let Some(k) = self.tool_letters[..self.tool_len]
            .iter()
            .position(|l| *l == Some(axis))
        {
            let v = self.suffix_point(Side::Tool, k, chain.tool_axis, true);
            let d = self.factor_derivative(chain.axis(axis), 1.0, v, true);
            self.work_inv.apply_vector(self.tool[k].apply_vector(d))
        } else if let Some(k) = chain.workpiece_side().iter().position(|a| a.axis == axis) {
            let v = self.suffix_point(Side::Workpiece, k, self.axis(), true);
            let d = self.factor_derivative(chain.axis(axis), -1.0, v, true);
            scale(
                self.work_inv.apply_vector(self.work[k].apply_vector(d)),
                -1.0,
            )
        } else {
            [0.0; 3]
        }
    }
}

/// The nominal rotation part → tool of the rotary joints alone:
/// `R(e₁, φ₁)·R(e₂, φ₂)` (see [`MachineChain::orientation`]).
pub fn nominal_orientation(chain: &MachineChain, q: &Axes) -> Mat3 {
    let mut m = super::transform::IDENTITY3;
    for (axis, sign) in chain.orientation() {
        let a = chain.axis(axis);
        let theta = (sign * a.joint_sign * q.get(axis)).to_radians();
        let (s, c) = sin_cos(theta);
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
