//! Kinematics of the `xyzac-trt` machine (kinematics.md is the contract): nominal
//! forward and inverse kinematics, the actual chain with the 43 error parameters,
//! the volumetric error `e` and the tool-axis error, and Jacobians.
//!
//! Invariants: no I/O, no allocation on the hot path (`volumetric_error` works on
//! fixed-size [`transform::Affine`] values); every inverse is the exact inverse of
//! the matrix as written (never a first-order `L(−δ, −ε)`); angles in degrees at the
//! API, radians inside; errors in µm/µrad at the API, mm/rad inside; results are
//! in part coordinates. Finite input gives finite output (no matrix of the chain
//! can be singular, see [`transform::Affine::inverse`]); callers check inputs for
//! NaN at their boundary.
pub mod error_values;
pub mod inverse;
pub mod jacobian;
pub mod transform;

use crate::axes::{Axes, Axis};
pub use error_values::{
    COMPONENT_NAMES, ErrorValues, LOCATION_NAMES, PARAMETER_COUNT, PARAMETER_NAMES,
    SQUARENESS_NAMES, UnknownParameter,
};
pub use inverse::{InverseError, InverseOptions};
use serde::{Deserialize, Serialize};
use transform::{Affine, add, sub};

/// µm → mm.
const UM: f64 = 1e-3;
/// µrad → rad.
const URAD: f64 = 1e-6;

/// Nominal geometry (mm) of kinematics.md: `P_C` = rotary points, `P_A` = `P_C` +
/// `(0, y_offset, z_offset)`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Geometry {
    pub x_rot_point: f64,
    pub y_rot_point: f64,
    pub z_rot_point: f64,
    pub y_offset: f64,
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
    pub const XYZ: ToolChain = ToolChain([Axis::X, Axis::Y, Axis::Z]);

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

/// The kinematic model of one `xyzac-trt` machine.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kinematics {
    pub geometry: Geometry,
    /// Tool length `L`, mm (gauge point to tip).
    pub tool_length: f64,
    pub tool_chain: ToolChain,
    /// LinuxCNC's `conventional-directions = 1`: A and C are negated before the
    /// formulas of kinematics.md (the tables are still looked up at the commanded A, C).
    pub conventional_directions: bool,
}

/// Volumetric error `e` (µm) and tool-axis error (µrad), part coordinates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VolumetricError {
    pub e_um: [f64; 3],
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
    pub tip: [f64; 3],
    pub axis: [f64; 3],
}

/// Sines and cosines of the effective rotary angles (after the direction convention).
#[derive(Clone, Copy, Debug)]
struct Rotations {
    sa: f64,
    ca: f64,
    sc: f64,
    cc: f64,
}

/// The actual chain at one pose, with the pieces the Jacobians need.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Chain {
    /// `T·E` pairs in tool-chain order, product `tool`.
    pub(crate) tool: Affine,
    /// Rotation part of the product of the pairs before each linear axis (X, Y, Z index).
    pub(crate) prefix: [transform::Mat3; 3],
    /// Actual travel directions `d_X, d_Y, d_Z`.
    pub(crate) directions: [[f64; 3]; 3],
    pub(crate) location_a: Affine,
    pub(crate) location_a_inv: Affine,
    pub(crate) error_a: Affine,
    pub(crate) angle_a: f64,
    pub(crate) location_c: Affine,
    pub(crate) location_c_inv: Affine,
    pub(crate) error_c: Affine,
    pub(crate) angle_c: f64,
    pub(crate) table_a: Affine,
    pub(crate) table_c: Affine,
    /// `(T_A·T_C)⁻¹`.
    pub(crate) work_inv: Affine,
}

impl Chain {
    /// Actual tool tip (mm) in part coordinates.
    pub(crate) fn tip(&self, tool_length: f64) -> [f64; 3] {
        let p_tool = self.tool.apply_point([0.0, 0.0, -tool_length]);
        self.work_inv.apply_point(p_tool)
    }

    /// Actual tool axis in part coordinates (third column of the rotation part).
    pub(crate) fn axis(&self) -> [f64; 3] {
        let m = &self.tool.m;
        self.work_inv.apply_vector([m[0][2], m[1][2], m[2][2]])
    }
}

fn component(errors: &ErrorValues, axis: usize) -> Affine {
    let c = &errors.component[axis];
    Affine::small(
        [c[0] * UM, c[1] * UM, c[2] * UM],
        [c[3] * URAD, c[4] * URAD, c[5] * URAD],
    )
}

impl Kinematics {
    /// Nominal kinematics with the default tool chain and directions.
    /// The same machine with a tool of `tool_length` mm (gauge point to tip).
    pub fn with_tool_length(&self, tool_length: f64) -> Kinematics {
        Kinematics {
            tool_length,
            ..*self
        }
    }

    pub fn new(geometry: Geometry, tool_length: f64) -> Kinematics {
        Kinematics {
            geometry,
            tool_length,
            tool_chain: ToolChain::XYZ,
            conventional_directions: false,
        }
    }

    /// +1, or −1 with conventional directions.
    pub(crate) fn direction_sign(&self) -> f64 {
        if self.conventional_directions {
            -1.0
        } else {
            1.0
        }
    }

    /// Effective rotary angles in radians (A, C), after the direction convention.
    fn angles(&self, a_deg: f64, c_deg: f64) -> (f64, f64) {
        let s = self.direction_sign();
        ((s * a_deg).to_radians(), (s * c_deg).to_radians())
    }

    fn rotations(&self, a_deg: f64, c_deg: f64) -> Rotations {
        let (a, c) = self.angles(a_deg, c_deg);
        let (sa, ca) = a.sin_cos();
        let (sc, cc) = c.sin_cos();
        Rotations { sa, ca, sc, cc }
    }

    fn nominal_tip_with(&self, rot: &Rotations, q: [f64; 3]) -> [f64; 3] {
        let pa = self.geometry.a_point();
        let pc = self.geometry.c_point();
        // w = Rx(−a)·(q − P_A)
        let v = sub(q, pa);
        let w = [
            v[0],
            rot.ca * v[1] + rot.sa * v[2],
            -rot.sa * v[1] + rot.ca * v[2],
        ];
        // r = P_C + Rz(−c)·(P_A + w − P_C)
        let u = sub(add(pa, w), pc);
        add(
            pc,
            [
                rot.cc * u[0] + rot.sc * u[1],
                -rot.sc * u[0] + rot.cc * u[1],
                u[2],
            ],
        )
    }

    fn nominal_axis_with(rot: &Rotations) -> [f64; 3] {
        [rot.sa * rot.sc, rot.sa * rot.cc, rot.ca]
    }

    /// Nominal tool tip in part coordinates (mm) for joint position `joints`:
    /// `r = P_C + Rz(−c)·(P_A + Rx(−a)·(q − P_A) − P_C)`.
    pub fn nominal_tip(&self, joints: &Axes) -> [f64; 3] {
        let rot = self.rotations(joints.a, joints.c);
        self.nominal_tip_with(&rot, joints.xyz())
    }

    /// Nominal unit tool axis (tip → spindle) in part coordinates:
    /// `(sin a sin c, sin a cos c, cos a)` (with the direction convention applied).
    pub fn nominal_tool_axis(&self, joints: &Axes) -> [f64; 3] {
        Self::nominal_axis_with(&self.rotations(joints.a, joints.c))
    }

    /// Nominal machine point of part point `part` at rotary angles `a`, `c` (degrees):
    /// `m = P_A + Rx(a)·(P_C + Rz(c)·(r − P_C) − P_A)`; the exact inverse of
    /// [`Kinematics::nominal_tip`] for the same A, C.
    pub fn nominal_machine_point(&self, part: [f64; 3], a_deg: f64, c_deg: f64) -> [f64; 3] {
        let rot = self.rotations(a_deg, c_deg);
        let pa = self.geometry.a_point();
        let pc = self.geometry.c_point();
        let u = sub(part, pc);
        let v = add(
            pc,
            [
                rot.cc * u[0] - rot.sc * u[1],
                rot.sc * u[0] + rot.cc * u[1],
                u[2],
            ],
        );
        let w = sub(v, pa);
        add(
            pa,
            [
                w[0],
                rot.ca * w[1] - rot.sa * w[2],
                rot.sa * w[1] + rot.ca * w[2],
            ],
        )
    }

    /// Joints of a part-frame target: `part.x, part.y, part.z` the tool tip in part
    /// coordinates, `part.a, part.c` the rotary angles (taken as given).
    pub fn joints_from_part(&self, part: &Axes) -> Axes {
        let m = self.nominal_machine_point(part.xyz(), part.a, part.c);
        Axes::new(m[0], m[1], m[2], part.a, part.c)
    }

    /// Part-frame target of a joint position: the nominal tool tip in part
    /// coordinates with the same A and C (inverse of [`Kinematics::joints_from_part`]).
    pub fn part_from_joints(&self, joints: &Axes) -> Axes {
        let r = self.nominal_tip(joints);
        Axes::new(r[0], r[1], r[2], joints.a, joints.c)
    }

    /// The actual chain of kinematics.md at `joints` with `errors`.
    pub(crate) fn chain(&self, joints: &Axes, errors: &ErrorValues) -> Chain {
        self.chain_with(&self.rotations(joints.a, joints.c), joints, errors)
    }

    /// [`Kinematics::chain`] with the nominal rotations already computed: the rotary
    /// zero offsets are added by the angle-sum formulas (one trigonometric call on a
    /// large angle per axis instead of two).
    fn chain_with(&self, rot: &Rotations, joints: &Axes, errors: &ErrorValues) -> Chain {
        let s = &errors.squareness;
        let directions = [
            [1.0, 0.0, 0.0],
            [-s[0] * URAD, 1.0, 0.0],
            [-s[1] * URAD, -s[2] * URAD, 1.0],
        ];
        let q = joints.xyz();
        let mut tool = Affine::IDENTITY;
        let mut prefix = [transform::IDENTITY3; 3];
        for axis in self.tool_chain.order() {
            let i = linear_index(axis);
            prefix[i] = tool.m;
            let e = component(errors, i);
            let mut t = transform::scale(directions[i], q[i]);
            if i == 2 {
                t[2] += self.tool_length;
            }
            // Trans(t)·E = [E.m, E.t + t]
            let pair = Affine {
                m: e.m,
                t: add(e.t, t),
            };
            tool = tool.mul(&pair);
        }

        let loc = &errors.location;
        use error_values::location as l;
        let location_a = Affine::small(
            [0.0, loc[l::EY0A] * UM, loc[l::EZ0A] * UM],
            [0.0, loc[l::EB0A] * URAD, loc[l::EC0A] * URAD],
        );
        let location_c = Affine::small(
            [loc[l::EX0C] * UM, loc[l::EY0C] * UM, 0.0],
            [loc[l::EA0C] * URAD, loc[l::EB0C] * URAD, 0.0],
        );
        let location_a_inv = location_a.inverse();
        let location_c_inv = location_c.inverse();
        let (a, c) = self.angles(joints.a, joints.c);
        let (offset_a, offset_c) = (loc[l::EA0A] * URAD, loc[l::EC0C] * URAD);
        let angle_a = a + offset_a;
        let angle_c = c + offset_c;
        // sin(θ + δ) = sin θ cos δ + cos θ sin δ, cos(θ + δ) = cos θ cos δ − sin θ sin δ.
        let (so, co) = offset_a.sin_cos();
        let rx = Affine::rot_x_sin_cos(rot.sa * co + rot.ca * so, rot.ca * co - rot.sa * so);
        let (so, co) = offset_c.sin_cos();
        let rz = Affine::rot_z_sin_cos(rot.sc * co + rot.cc * so, rot.cc * co - rot.sc * so);
        let error_a = component(errors, 3);
        let error_c = component(errors, 4);
        let table_a = location_a
            .mul(&rx)
            .mul(&error_a)
            .mul(&location_a_inv)
            .about(self.geometry.a_point());
        let table_c = location_c
            .mul(&rz)
            .mul(&error_c)
            .mul(&location_c_inv)
            .about(self.geometry.c_point());
        let work_inv = table_a.mul(&table_c).inverse();
        Chain {
            tool,
            prefix,
            directions,
            location_a,
            location_a_inv,
            error_a,
            angle_a,
            location_c,
            location_c_inv,
            error_c,
            angle_c,
            table_a,
            table_c,
            work_inv,
        }
    }

    /// Actual tool tip (mm) and tool axis (not re-normalised), part coordinates.
    pub fn actual_tip_and_axis(&self, joints: &Axes, errors: &ErrorValues) -> TipAndAxis {
        let chain = self.chain(joints, errors);
        TipAndAxis {
            tip: chain.tip(self.tool_length),
            axis: chain.axis(),
        }
    }

    /// Volumetric error `e = r_act − r_nom` (µm) and tool-axis error (µrad), part
    /// coordinates, at `joints` with the parameter values `errors` (µm, µrad).
    pub fn volumetric_error(&self, joints: &Axes, errors: &ErrorValues) -> VolumetricError {
        let rot = self.rotations(joints.a, joints.c);
        let chain = self.chain_with(&rot, joints, errors);
        let actual = TipAndAxis {
            tip: chain.tip(self.tool_length),
            axis: chain.axis(),
        };
        let tip = self.nominal_tip_with(&rot, joints.xyz());
        let axis = Self::nominal_axis_with(&rot);
        let e = sub(actual.tip, tip);
        let u = sub(actual.axis, axis);
        VolumetricError {
            e_um: transform::scale(e, 1e3),
            axis_urad: transform::scale(u, 1e6),
        }
    }
}
