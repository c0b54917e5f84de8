//! The context of a plan point: everything about the tool-path point that cut it
//! (effects.md "Context of a plan point"). Built by the toolpath layer from the
//! interpreted program and the machine; consumed by `predict`, `simulate` and
//! `diagnose`, which need nothing else from the program or the kinematics.
use crate::axes::{Axes, Axis};
use serde::{Deserialize, Serialize};

/// The parameter names of the Jacobians a context carries (defined by
/// `kinematics`, which computes them).
pub use crate::kinematics::jacobian::{LOCATION_PARAMETERS, SQUARENESS_PARAMETERS};

/// Everything about the tool-path point that cut one plan point (effects.md "Context of a plan point").
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointContext {
    /// Plan point id (as in the CSV).
    pub id: String,
    /// Nominal plan point, part coordinates, mm.
    pub point: [f64; 3],
    /// Unit outward surface normal, part coordinates.
    pub normal: [f64; 3],
    /// Whether a path point lies within 0.5 mm of the contact point (formats.md).
    pub cut: bool,
    /// Program line (1-based) of the block that cut it.
    pub line: usize,
    /// Index of that block among the program's blocks (0-based).
    pub block: usize,
    /// Machining time in minutes since program start (end of the block reaching the point).
    pub time_min: f64,
    /// Joint position of the path point (mm, degrees).
    pub joints: Axes,
    /// Sign (−1, 0, +1) of each linear axis's most recent non-zero motion.
    pub sigma: [f64; 3],
    /// XYZ machine-path speed of the block arriving at the point, mm/s.
    pub speed_mm_s: f64,
    /// Curvature of the machine XYZ path at the point, 1/mm (0 where undefined).
    pub curvature_per_mm: f64,
    /// Unit principal normal (towards the centre of curvature), machine frame.
    pub principal_normal: [f64; 3],
    /// Nominal unit tool axis (tip towards spindle), part coordinates.
    pub tool_axis: [f64; 3],
    /// Cumulative G1/G2/G3 XYZ machine length up to the point, m.
    pub cut_length_m: f64,
    /// Predicted deviation n·e of the geometric model, µm.
    pub predicted_um: f64,
    /// ∂(tool tip, part coordinates, µm)/∂(s_xy, s_xz, s_yz in µrad): one row per parameter.
    pub squareness_jacobian: [[f64; 3]; 3],
    /// ∂(tool tip, part coordinates, µm)/∂(location parameter, µm or µrad), rows in
    /// the order of `LOCATION_PARAMETERS`.
    pub location_jacobian: [[f64; 3]; 8],
    /// `n·e` of each joint slot's measured errors alone (X Y Z and the two
    /// rotary tables, first order), µm: what the model attributes to each table
    /// at this point. Zero in contexts written before this field.
    #[serde(default)]
    pub axis_deviation_um: [f64; 5],
    /// Standard uncertainty of `predicted_um` from the model's own fit (table
    /// noise and fit error, along `n`), µm; 0 when the model carries none and
    /// in contexts written before this field.
    #[serde(default)]
    pub model_u_um: f64,
    /// The machine's two rotary letters in letter order (slots 3 and 4; A and C
    /// in contexts written before this field).
    #[serde(default = "ac")]
    pub rotary: [Axis; 2],
    /// The nominal rotation from machine (bed) directions to part coordinates at
    /// the point's joints (the rotation of `W⁻¹`); `None` in contexts written
    /// before this field, which are A/C tables: `Rz(−c)·Rx(−a)`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub machine_to_part_rotation: Option<[[f64; 3]; 3]>,
}

fn ac() -> [Axis; 2] {
    [Axis::A, Axis::C]
}

impl PointContext {
    /// Rotate a machine-frame vector into part coordinates (effects.md "machine
    /// frame → part"; `Rz(−c)·Rx(−a)·v` on an A/C table).
    pub fn machine_to_part(&self, v: [f64; 3]) -> [f64; 3] {
        match &self.machine_to_part_rotation {
            Some(m) => crate::kinematics::transform::mat_vec(m, v),
            None => machine_to_part(self.joints.a, self.joints.c, v),
        }
    }

    /// This cut point probed again on the machine at `time_min` (a follow-up
    /// probe): the same id, point and normal, with a probe's motion (no
    /// speed, curvature or cut length) and no table uncertainty. The
    /// pose-dependent fields are still the cut's: the caller sets the probe's.
    pub fn probe_of(&self, time_min: f64) -> PointContext {
        PointContext {
            cut: true,
            line: 0,
            block: 0,
            time_min,
            speed_mm_s: 0.0,
            curvature_per_mm: 0.0,
            principal_normal: [0.0; 3],
            cut_length_m: 0.0,
            model_u_um: 0.0,
            ..self.clone()
        }
    }

    /// The letter of each joint slot: X Y Z and the two rotary axes.
    pub fn slot_letters(&self) -> [Axis; 5] {
        [Axis::X, Axis::Y, Axis::Z, self.rotary[0], self.rotary[1]]
    }
}

/// The time of the last of `points` (minutes since the program's first
/// target): the duration of the program up to them; 0 for none.
pub fn last_time_min<'a>(points: impl IntoIterator<Item = &'a PointContext>) -> f64 {
    points
        .into_iter()
        .map(|c| c.time_min)
        .fold(0.0f64, f64::max)
}

/// `Rz(−c)·Rx(−a)·v`, `a` and `c` in degrees.
pub fn machine_to_part(a_deg: f64, c_deg: f64, v: [f64; 3]) -> [f64; 3] {
    use crate::vec3::{rot_x, rot_z};
    rot_z(-c_deg.to_radians(), rot_x(-a_deg.to_radians(), v))
}
