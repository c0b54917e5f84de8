//! Kinematics of any serial five-axis machine (kinematics.md is the contract): the
//! chain ([`chain::MachineChain`]) with its error parameters, nominal forward and
//! inverse kinematics, the volumetric error `e` and the tool-axis error, and
//! Jacobians. `xyzac-trt` and `xyzbc-trt` (LinuxCNC's names) are presets that build
//! a chain ([`Kinematics::xyzac_trt`], [`Kinematics::xyzbc_trt`]).
//!
//! Invariants: no I/O, no allocation on the hot path (the chain is evaluated on
//! fixed-size `transform::Affine` values); every inverse is the exact inverse of
//! the matrix as written (never a first-order `L(−δ, −ε)`); angles in degrees at the
//! API, radians inside; errors in µm/µrad at the API, mm/rad inside; results are
//! in part coordinates. Joint vectors are `(x, y, z, r₁, r₂)` with the machine's two
//! rotary letters in letter order (`a, c` on xyzac-trt). Finite input gives finite
//! output; callers check inputs for NaN at their boundary.
pub(crate) mod chain;
pub(crate) mod error_values;
pub(crate) mod inverse;
pub(crate) mod jacobian;
pub(crate) mod transform;

use crate::axes::{Axes, Axis};
pub use chain::{ChainAxis, ChainConstants, ChainError, MachineChain, Side};
pub use error_values::{
    COMPONENT_NAMES, ErrorValues, LOCATION_NAMES, PARAMETER_COUNT, PARAMETER_NAMES,
    ParameterLayout, SQUARENESS_NAMES, UnknownParameter,
};
pub use inverse::{InverseError, InverseOptions, POLE_SIN};
use serde::{Deserialize, Serialize};
use transform::{Mat3, sub};

/// Nominal geometry (mm) of kinematics.md: `P_C` = rotary points, `P_A` = `P_C` +
/// `(0, y_offset, z_offset)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    /// X of `P_C`, machine coordinates, mm.
    pub x_rot_point: f64,
    /// Y of `P_C`, mm.
    pub y_rot_point: f64,
    /// Z of `P_C`, mm.
    pub z_rot_point: f64,
    /// Y of `P_A − P_C`, mm.
    pub y_offset: f64,
    /// Z of `P_A − P_C`, mm.
    pub z_offset: f64,
}

impl Geometry {
    /// `P_C`, a point on the C axis.
    pub fn c_point(&self) -> [f64; 3] {
        [self.x_rot_point, self.y_rot_point, self.z_rot_point]
    }

    /// `P_A`, a point on the A axis.
    pub fn a_point(&self) -> [f64; 3] {
        [
            self.x_rot_point,
            self.y_rot_point + self.y_offset,
            self.z_rot_point + self.z_offset,
        ]
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.c_point().iter().all(|v| v.is_finite())
            && self.y_offset.is_finite()
            && self.z_offset.is_finite()
    }
}

/// Bed → spindle order of the three linear axes: always a permutation of X Y Z.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct ToolChain([Axis; 3]);

/// A tool chain that is not a permutation of X, Y, Z.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("tool_chain must be a permutation of X, Y, Z (got {0})")]
pub struct BadToolChain(pub String);

impl Default for ToolChain {
    fn default() -> Self {
        ToolChain::XYZ
    }
}

impl ToolChain {
    /// Bed → spindle X, Y, Z.
    pub const XYZ: ToolChain = ToolChain([Axis::X, Axis::Y, Axis::Z]);

    /// The order `order`, refused unless it is a permutation of X, Y, Z.
    pub fn new(order: [Axis; 3]) -> Result<ToolChain, BadToolChain> {
        let mut seen = [false; 3];
        for axis in order {
            match axis {
                Axis::X | Axis::Y | Axis::Z => seen[linear_index(axis)] = true,
                _ => {}
            }
        }
        if seen.iter().all(|s| *s) {
            Ok(ToolChain(order))
        } else {
            Err(BadToolChain(format!("{order:?}")))
        }
    }

    /// From letters such as `["Y", "X", "Z"]` (case-insensitive).
    pub fn from_names<S: AsRef<str>>(names: &[S]) -> Result<ToolChain, BadToolChain> {
        let describe = || {
            let list: Vec<&str> = names.iter().map(|s| s.as_ref()).collect();
            format!("{list:?}")
        };
        if names.len() != 3 {
            return Err(BadToolChain(describe()));
        }
        let mut order = [Axis::X; 3];
        for (slot, name) in order.iter_mut().zip(names) {
            let mut chars = name.as_ref().chars();
            *slot = match (chars.next().and_then(Axis::from_letter), chars.next()) {
                (Some(axis), None) if !axis.is_rotary() => axis,
                _ => return Err(BadToolChain(describe())),
            };
        }
        ToolChain::new(order).map_err(|_| BadToolChain(describe()))
    }

    /// The three linear axes, bed → spindle.
    pub fn order(&self) -> [Axis; 3] {
        self.0
    }
}

/// 0, 1, 2 for X, Y, Z (callers only pass linear axes).
pub(crate) fn linear_index(axis: Axis) -> usize {
    match axis {
        Axis::X => 0,
        Axis::Y => 1,
        _ => 2,
    }
}

/// Nominal geometry (mm) of LinuxCNC's `xyzbc-trt`: `P_C` = rotary points, `P_B` =
/// `P_C` + `(x_offset, 0, z_offset)` (kinematics.md: B in place of A, `y_offset`
/// replaced by `x_offset`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BcGeometry {
    /// X of `P_C`, machine coordinates, mm.
    pub x_rot_point: f64,
    /// Y of `P_C`, mm.
    pub y_rot_point: f64,
    /// Z of `P_C`, mm.
    pub z_rot_point: f64,
    /// X of `P_B − P_C`, mm.
    pub x_offset: f64,
    /// Z of `P_B − P_C`, mm.
    pub z_offset: f64,
}

impl BcGeometry {
    /// `P_C`, a point on the C axis.
    pub fn c_point(&self) -> [f64; 3] {
        [self.x_rot_point, self.y_rot_point, self.z_rot_point]
    }

    /// `P_B`, a point on the B axis.
    pub fn b_point(&self) -> [f64; 3] {
        [
            self.x_rot_point + self.x_offset,
            self.y_rot_point,
            self.z_rot_point + self.z_offset,
        ]
    }

    /// Whether every number is finite.
    pub fn is_finite(&self) -> bool {
        self.c_point().iter().all(|v| v.is_finite())
            && self.x_offset.is_finite()
            && self.z_offset.is_finite()
    }
}

/// The exact nominal map part-frame tip → linear joints at fixed rotary joints
/// ([`Kinematics::tip_to_joints`]): `q = M⁻¹·(tip − r₀)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TipToJoints {
    base: Axes,
    r0: [f64; 3],
    /// `J`: the columns ∂tip/∂x, ∂y, ∂z as rows of a matrix (`J[i][k]`).
    jacobian: Mat3,
    inverse: Mat3,
}

impl TipToJoints {
    /// The nominal tip at linear joints `xyz`: `r₀ + J·xyz`.
    #[inline]
    pub fn tip_of(&self, xyz: [f64; 3]) -> [f64; 3] {
        transform::add(self.r0, transform::mat_vec(&self.jacobian, xyz))
    }

    /// X Y Z (mm) that put the nominal tip at `tip`.
    #[inline]
    pub fn linear_joints(&self, tip: [f64; 3]) -> [f64; 3] {
        transform::mat_vec(&self.inverse, sub(tip, self.r0))
    }

    /// The whole position: X Y Z for `tip`, the rest as given.
    #[inline]
    pub fn joints(&self, tip: [f64; 3]) -> Axes {
        let q = self.linear_joints(tip);
        Axes {
            x: q[0],
            y: q[1],
            z: q[2],
            ..self.base
        }
    }
}

/// The kinematic model of one machine with one tool: its chain and the tool length.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics {
    /// The nominal chain.
    pub chain: MachineChain,
    /// Tool length `L`, mm (gauge point to tip).
    pub tool_length: f64,
}

/// Volumetric error `e` (µm) and tool-axis error (µrad), part coordinates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VolumetricError {
    /// `e = r_act − r_nom`, µm, part coordinates.
    pub e_um: [f64; 3],
    /// Actual minus nominal tool axis, µrad (×1e-6 of a unit vector), part coordinates.
    pub axis_urad: [f64; 3],
}

impl VolumetricError {
    /// `|e|`, µm.
    pub fn magnitude_um(&self) -> f64 {
        transform::norm(self.e_um)
    }
}

/// Tool tip (mm) and tool axis (not re-normalised), part coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TipAndAxis {
    /// Tool tip, mm, part coordinates.
    pub tip: [f64; 3],
    /// Tool axis (tip → spindle), part coordinates, not re-normalised.
    pub axis: [f64; 3],
}

fn linear_axes(tool_chain: ToolChain) -> [ChainAxis; 3] {
    tool_chain.order().map(|a| {
        let mut d = [0.0; 3];
        d[linear_index(a)] = 1.0;
        ChainAxis::linear(a, d)
    })
}

impl Kinematics {
    /// A machine from its chain.
    pub fn from_chain(chain: MachineChain, tool_length: f64) -> Kinematics {
        Kinematics { chain, tool_length }
    }

    /// `xyzac-trt` with the default tool chain and directions.
    pub fn new(geometry: Geometry, tool_length: f64) -> Kinematics {
        Kinematics::xyzac_trt(geometry, ToolChain::XYZ, false, tool_length)
    }

    /// LinuxCNC's `xyzac-trt` (kinematics.md): workpiece side A (about X through
    /// `P_A`) then C (about Z through `P_C`), tool side the linear axes in
    /// `tool_chain` order. `conventional_directions` negates A and C before the
    /// formulas.
    pub fn xyzac_trt(
        geometry: Geometry,
        tool_chain: ToolChain,
        conventional_directions: bool,
        tool_length: f64,
    ) -> Kinematics {
        let work = [
            ChainAxis::rotary(Axis::A, [1.0, 0.0, 0.0], geometry.a_point()),
            ChainAxis::rotary(Axis::C, [0.0, 0.0, 1.0], geometry.c_point()),
        ];
        Kinematics::trt(work, tool_chain, conventional_directions, tool_length)
    }

    /// LinuxCNC's `xyzbc-trt`: as `xyzac-trt` with B (about Y through `P_B`) in
    /// place of A.
    pub fn xyzbc_trt(
        geometry: BcGeometry,
        tool_chain: ToolChain,
        conventional_directions: bool,
        tool_length: f64,
    ) -> Kinematics {
        let work = [
            ChainAxis::rotary(Axis::B, [0.0, 1.0, 0.0], geometry.b_point()),
            ChainAxis::rotary(Axis::C, [0.0, 0.0, 1.0], geometry.c_point()),
        ];
        Kinematics::trt(work, tool_chain, conventional_directions, tool_length)
    }

    fn trt(
        work: [ChainAxis; 2],
        tool_chain: ToolChain,
        conventional_directions: bool,
        tool_length: f64,
    ) -> Kinematics {
        // A table-table machine with orthogonal axes is always a valid chain.
        let chain = MachineChain::new(&work, &linear_axes(tool_chain), [0.0, 0.0, 1.0])
            .unwrap_or_else(|e| unreachable!("a table-table preset is a valid chain: {e}"));
        let chain = if conventional_directions {
            chain.with_negated_rotaries()
        } else {
            chain
        };
        Kinematics { chain, tool_length }
    }

    /// The same machine with a tool of `tool_length` mm (gauge point to tip).
    pub fn with_tool_length(&self, tool_length: f64) -> Kinematics {
        Kinematics {
            tool_length,
            ..*self
        }
    }

    /// The machine's two rotary letters, in letter order (joint slots 3 and 4).
    pub fn rotary(&self) -> [Axis; 2] {
        self.chain.rotary()
    }

    /// The names of this machine's error parameters.
    pub fn layout(&self) -> ParameterLayout {
        self.chain.layout()
    }

    /// The joint vector `(x, y, z, r₁, r₂)` of a position.
    #[inline]
    pub fn joints(&self, q: &Axes) -> [f64; 5] {
        self.chain.joints(q)
    }

    /// `q` with its five joints replaced.
    #[inline]
    pub fn with_joints(&self, q: &Axes, j: [f64; 5]) -> Axes {
        self.chain.with_joints(q, j)
    }

    /// The actual chain at `joints` with `errors`, ready for derivatives.
    #[inline]
    pub fn pose<'a>(&'a self, joints: &'a Axes, errors: &'a ErrorValues) -> chain::ChainPose<'a> {
        chain::ChainPose::new(&self.chain, self.tool_length, joints, errors, false)
    }

    /// The nominal chain at `joints`, ready for derivatives.
    #[inline]
    pub fn nominal_pose<'a>(&'a self, joints: &'a Axes) -> chain::ChainPose<'a> {
        chain::ChainPose::new(
            &self.chain,
            self.tool_length,
            joints,
            &ErrorValues::ZERO,
            true,
        )
    }

    /// Nominal tool tip in part coordinates (mm) for joint position `joints`.
    #[inline]
    pub fn nominal_tip(&self, joints: &Axes) -> [f64; 3] {
        chain::tip_and_axis(
            &self.chain,
            self.tool_length,
            joints,
            &ErrorValues::ZERO,
            true,
        )
        .0
    }

    /// Nominal tool tip (mm) and unit tool axis in part coordinates, one pass.
    #[inline]
    pub fn nominal_tip_and_axis(&self, joints: &Axes) -> ([f64; 3], [f64; 3]) {
        chain::tip_and_axis(
            &self.chain,
            self.tool_length,
            joints,
            &ErrorValues::ZERO,
            true,
        )
    }

    /// Nominal unit tool axis (tip → spindle) in part coordinates.
    pub fn nominal_tool_axis(&self, joints: &Axes) -> [f64; 3] {
        let r = chain::nominal_orientation(&self.chain, joints);
        transform::mat_vec(&r, self.chain.tool_axis())
    }

    /// The nominal rotation part → tool of the rotary joints at `joints`:
    /// `u = R·u₀` (its columns the tool's home axes seen from the part).
    pub fn nominal_orientation(&self, joints: &Axes) -> Mat3 {
        chain::nominal_orientation(&self.chain, joints)
    }

    /// The two rotary letters in Siemens' swivel order: the tool side's
    /// from the bed towards the spindle, then the workpiece side's from the
    /// bed towards the part (rotary axis 2 is carried by rotary axis 1, and
    /// on a mixed machine rotary axis 1 is the head's).
    pub fn swivel_order(&self) -> [Axis; 2] {
        let [(a, sa), (b, sb)] = self.chain.orientation();
        if sa > 0.0 && sb > 0.0 { [a, b] } else { [b, a] }
    }

    /// The nominal rotation of machine (bed) directions into part coordinates at
    /// `joints` (the rotation part of `W⁻¹`).
    pub fn machine_to_part_rotation(&self, joints: &Axes) -> Mat3 {
        self.nominal_pose(joints).machine_to_part().m
    }

    /// A machine-frame vector in part coordinates at `joints` (nominal).
    pub fn machine_to_part(&self, joints: &Axes, v: [f64; 3]) -> [f64; 3] {
        transform::mat_vec(&self.machine_to_part_rotation(joints), v)
    }

    /// The nominal map from a part-frame tool tip to the linear joints at the rotary
    /// joints (and U V W) of `rotaries`: the tip is affine in the linear joints, so
    /// the map is exact ([`TipToJoints`]).
    pub fn tip_to_joints(&self, rotaries: &Axes) -> TipToJoints {
        let (r0, cols) = chain::nominal_linear_map(&self.chain, self.tool_length, rotaries);
        let m = [
            [cols[0][0], cols[1][0], cols[2][0]],
            [cols[0][1], cols[1][1], cols[2][1]],
            [cols[0][2], cols[1][2], cols[2][2]],
        ];
        TipToJoints {
            base: Axes {
                x: 0.0,
                y: 0.0,
                z: 0.0,
                ..*rotaries
            },
            r0,
            jacobian: m,
            inverse: transform::mat_inverse(&m),
        }
    }

    /// The joints that put the nominal tool tip at part point `part` with the rotary
    /// joints (and U V W) of `rotaries`.
    pub fn nominal_joints_for_tip(&self, part: [f64; 3], rotaries: &Axes) -> Axes {
        self.tip_to_joints(rotaries).joints(part)
    }

    /// Nominal machine point (the linear joints) of part point `part` at the rotary
    /// joints of `rotaries`; the exact inverse of [`Kinematics::nominal_tip`] for the
    /// same rotary joints.
    pub fn nominal_machine_point(&self, part: [f64; 3], rotaries: &Axes) -> [f64; 3] {
        self.tip_to_joints(rotaries).linear_joints(part)
    }

    /// The angle (degrees) between the nominal tool axis and the outer rotary axis
    /// (the one a tool axis along it makes free: C on an A/C table, where this is
    /// |A|). Near 0 that joint cannot steer the tool axis (the pole).
    pub fn pole_angle_deg(&self, joints: &Axes) -> f64 {
        let [(outer, _), (inner, sign)] = self.chain.orientation();
        let (e1, a2) = (self.chain.axis(outer).direction, self.chain.axis(inner));
        let theta = (sign * a2.joint_sign * joints.get(inner)).to_radians();
        let (s, c) = chain::sin_cos(theta);
        let v = transform::mat_vec(&chain::rotation(a2.direction, s, c), self.chain.tool_axis());
        transform::dot(v, e1).abs().min(1.0).acos().to_degrees()
    }

    /// The outer rotary letter (see [`Kinematics::pole_angle_deg`]).
    pub fn outer_rotary(&self) -> Axis {
        self.chain.orientation()[0].0
    }

    /// Actual tool tip (mm) and tool axis (not re-normalised), part coordinates.
    #[inline]
    pub fn actual_tip_and_axis(&self, joints: &Axes, errors: &ErrorValues) -> TipAndAxis {
        let (tip, axis) = chain::tip_and_axis(&self.chain, self.tool_length, joints, errors, false);
        TipAndAxis { tip, axis }
    }

    /// [`Kinematics::actual_tip_and_axis`] with the [`ChainConstants`] of the
    /// values' squareness and location computed beforehand: the same numbers.
    #[inline]
    pub fn actual_tip_and_axis_with(
        &self,
        joints: &Axes,
        errors: &ErrorValues,
        constants: &ChainConstants,
    ) -> TipAndAxis {
        let (tip, axis) =
            chain::tip_and_axis_with(&self.chain, self.tool_length, joints, errors, constants);
        TipAndAxis { tip, axis }
    }

    /// Volumetric error `e = r_act − r_nom` (µm) and tool-axis error (µrad), part
    /// coordinates, at `joints` with the parameter values `errors` (µm, µrad).
    pub fn volumetric_error(&self, joints: &Axes, errors: &ErrorValues) -> VolumetricError {
        let [(tip, axis), (tip0, axis0)] =
            chain::actual_and_nominal(&self.chain, self.tool_length, joints, errors);
        let e = sub(tip, tip0);
        let u = sub(axis, axis0);
        VolumetricError {
            e_um: transform::scale(e, 1e3),
            axis_urad: transform::scale(u, 1e6),
        }
    }
}
