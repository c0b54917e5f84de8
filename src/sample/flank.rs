//! The flank sample: a drafted round boss whose wall is cut in one revolution
//! by the side of a flat end mill, the tool axis lying along the wall's ruling
//! (five-axis flank milling), and its inspection plan over the wall's height.
//!
//! Everything here is deterministic: the same options give the same bytes.
//!
//! Geometry (part coordinates, mm): a truncated cone about the vertical through
//! [`FlankOptions::centre`] (off the C axis, so X Y Z move as C turns), radius
//! [`FlankOptions::base_radius`] at z = 0 narrowing with the draft angle δ up to
//! z = [`FlankOptions::height`]. At azimuth φ its wall point at height z is
//! `centre + (ρ(z) cos φ, ρ(z) sin φ, z)` with
//! `ρ(z) = ρ₀ − z tan δ`, its outward normal `n = (cos δ cos φ, cos δ sin φ,
//! sin δ)` and its ruling `w = (−sin δ cos φ, −sin δ sin φ, cos δ)`.
//!
//! Tool path: the tool axis is the ruling, `u = w`, so A stays at ±δ while C
//! turns a full revolution with φ; the tool's side touches the whole ruling, so
//! its tip is the wall's foot point plus `R·n`, lowered by
//! [`FlankOptions::below_foot`] along the axis. A wall point at height z is
//! cut `below_foot + z / cos δ` up the flute: the machine's tilt errors act on
//! that lever, which is what the sample is for (issue 13).
//!
//! Plan: azimuths every 10° (36) × heights 2, 6, 10, 14, 18 mm (5) = 180 wall
//! points with their normals.
use crate::axes::Axes;
use crate::kinematics::{InverseOptions, Kinematics};
use std::fmt::Write as _;

/// Settings of the flank sample.
#[derive(Clone, Copy, Debug)]
pub struct FlankOptions {
    /// Tool number (the machine file's `[[tools]]` entry that flank-mills).
    pub tool: u32,
    /// Cutter radius, mm.
    pub tool_radius: f64,
    /// Centre of the boss's foot on the part (x, y), mm: off the C axis, so
    /// X Y Z move as C turns.
    pub centre: [f64; 2],
    /// Radius of the boss at its foot (z = 0), mm.
    pub base_radius: f64,
    /// Height of the wall, mm.
    pub height: f64,
    /// Draft angle of the wall from the vertical, degrees.
    pub draft_degrees: f64,
    /// How far the tool tip runs below the wall's foot, along the axis, mm.
    pub below_foot: f64,
    /// Azimuth step of the path, degrees.
    pub step_degrees: f64,
    /// Feed, mm/min.
    pub feed: f64,
    /// Safe distance above the part for rapids (machine Z), mm.
    pub clearance: f64,
}

impl Default for FlankOptions {
    fn default() -> Self {
        FlankOptions {
            tool: 3,
            tool_radius: 5.0,
            centre: [20.0, -15.0],
            base_radius: 40.0,
            height: 20.0,
            draft_degrees: 10.0,
            below_foot: 1.0,
            step_degrees: 1.0,
            feed: 800.0,
            clearance: 40.0,
        }
    }
}

/// The generated files.
#[derive(Clone, Debug, PartialEq)]
pub struct FlankFiles {
    pub joint_program: String,
    pub plan_csv: String,
}

#[derive(Debug, thiserror::Error)]
pub enum FlankError {
    #[error("the flank tool path needs an orientation the machine cannot reach: {0}")]
    Inverse(#[from] crate::kinematics::InverseError),
    #[error(
        "the flank tool path would flip the rotary axes by {jump_deg:.1}° at azimuth {azimuth_deg}° (kinematics.md: more than 90°)"
    )]
    Flip { azimuth_deg: f64, jump_deg: f64 },
}

impl FlankOptions {
    /// The wall point at azimuth `phi_deg` and height `z`, and its unit outward normal.
    pub fn wall(&self, phi_deg: f64, z: f64) -> ([f64; 3], [f64; 3]) {
        let (sp, cp) = phi_deg.to_radians().sin_cos();
        let (sd, cd) = self.draft_degrees.to_radians().sin_cos();
        let rho = self.base_radius - z * sd / cd;
        let [x0, y0] = self.centre;
        ([x0 + rho * cp, y0 + rho * sp, z], [cd * cp, cd * sp, sd])
    }

    /// The wall's ruling (foot to top, unit) at azimuth `phi_deg`: the tool axis.
    pub fn ruling(&self, phi_deg: f64) -> [f64; 3] {
        let (sp, cp) = phi_deg.to_radians().sin_cos();
        let (sd, cd) = self.draft_degrees.to_radians().sin_cos();
        [-sd * cp, -sd * sp, cd]
    }

    /// Tool tip at azimuth `phi_deg` (part coordinates).
    pub fn tip(&self, phi_deg: f64) -> [f64; 3] {
        let (foot, n) = self.wall(phi_deg, 0.0);
        let u = self.ruling(phi_deg);
        std::array::from_fn(|k| foot[k] + self.tool_radius * n[k] - self.below_foot * u[k])
    }

    /// The flute length the wall needs: from the tip, below the foot, up the
    /// ruling to the top of the wall, mm.
    pub fn flute_needed_mm(&self) -> f64 {
        self.below_foot + self.height / self.draft_degrees.to_radians().cos()
    }

    /// The plan: (point, normal) over azimuths every 10° and five heights.
    pub fn plan_points(&self) -> Vec<([f64; 3], [f64; 3])> {
        let mut points = Vec::new();
        for k in 0..36 {
            for z in [2.0f64, 6.0, 10.0, 14.0, 18.0] {
                points.push(self.wall(10.0 * k as f64, z.min(self.height)));
            }
        }
        points
    }
}

/// Generate the flank sample for a machine's nominal kinematics with the flank
/// tool (of `tool_length` mm) in the spindle; the program's header names `machine`.
pub fn generate(
    kinematics: &Kinematics,
    tool_length: f64,
    limits: [Option<[f64; 2]>; 2],
    options: &FlankOptions,
    machine: &str,
) -> Result<FlankFiles, FlankError> {
    use crate::axes::{Axis, AxisSet};
    let kin = kinematics.with_tool_length(tool_length);
    let [r1, r2] = kin.rotary();
    let letters = AxisSet::of(&[Axis::X, Axis::Y, Axis::Z, r1, r2]);
    let fmt = |a: &Axes| a.words(letters, 4);
    let lifted = |j: &Axes, by: f64| super::lifted(&kin, j, by).0;
    let mut out = String::new();
    let mut n = 10;
    let mut block = |out: &mut String, text: &str| {
        let _ = writeln!(out, "N{n} {text}");
        n += 10;
    };
    let _ = writeln!(out, "%");
    let _ = writeln!(
        out,
        "O2017 (DRAFTED BOSS - FIVE-AXIS FLANK MILLING OF THE WALL - JOINT FRAME)"
    );
    let _ = writeln!(
        out,
        "(BOSS R{} AT X{} Y{}, {} MM HIGH, {} DEG DRAFT; T{} FLAT END R{} CUTS WITH ITS SIDE, AXIS ALONG THE RULING)",
        options.base_radius,
        options.centre[0],
        options.centre[1],
        options.height,
        options.draft_degrees,
        options.tool,
        options.tool_radius
    );
    let _ = writeln!(
        out,
        "(GENERATED BY VOLCOMP SAMPLE FLANK{}",
        super::machine_suffix(machine)
    );
    block(&mut out, "G21 G90 G94 G17");
    block(
        &mut out,
        &format!(
            "T{t} M6 (FLAT END R{})",
            options.tool_radius,
            t = options.tool
        ),
    );
    block(&mut out, &format!("G43 H{}", options.tool));
    block(&mut out, "S10000 M3");
    // Start from the solution for the draft lean towards +Y whose first rotary
    // joint is positive (A = draft, C = 0 on an A/C table).
    let lean = options.draft_degrees.to_radians();
    let lean_axis = [0.0, lean.sin(), lean.cos()];
    let start = kin
        .orientation_solutions(lean_axis)
        .into_iter()
        .find(|s| s[0] > 0.0)
        .unwrap_or([0.0, 0.0]);
    let mut inverse = InverseOptions {
        previous: Axes::xyz_rotary([0.0; 3], [(r1, start[0]), (r2, start[1])]),
        limits,
    };
    let steps = (360.0 / options.step_degrees).round() as usize;
    let mut last = Axes::default();
    for i in 0..=steps {
        let phi = i as f64 * options.step_degrees;
        let solution = kin.inverse_tool_axis(options.tip(phi), options.ruling(phi), &inverse)?;
        if i > 0 && solution.is_flip() {
            return Err(FlankError::Flip {
                azimuth_deg: phi,
                jump_deg: solution.jump_deg,
            });
        }
        let joints = solution.joints;
        inverse.previous = joints;
        if i == 0 {
            let above = lifted(&joints, options.clearance);
            block(&mut out, &format!("G0 {}", fmt(&above)));
            block(
                &mut out,
                &format!("G1 {} F400. (PLUNGE)", super::moved_words(&above, &joints)),
            );
        } else {
            let feed = if i == 1 {
                format!(" F{:.0}.", options.feed)
            } else {
                String::new()
            };
            block(&mut out, &format!("{}{feed}", fmt(&joints)));
        }
        last = joints;
    }
    let retract = lifted(&last, options.clearance);
    block(
        &mut out,
        &format!("G0 {}", super::moved_words(&last, &retract)),
    );
    block(&mut out, "M5");
    block(&mut out, "M30");
    out.push_str("%\n");

    let plan = super::plan_csv(&options.plan_points());
    Ok(FlankFiles {
        joint_program: out,
        plan_csv: plan,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vec3::{dot, norm, sub};

    #[test]
    fn the_ruling_lies_in_the_wall_and_the_tool_side_touches_it() {
        let o = FlankOptions::default();
        for phi in [0.0, 37.0, 181.0, 300.0] {
            let u = o.ruling(phi);
            let (foot, n) = o.wall(phi, 0.0);
            let (top, _) = o.wall(phi, 20.0);
            assert!(dot(u, n).abs() < 1e-15);
            let along = sub(top, foot);
            assert!((dot(along, u) - norm(along)).abs() < 1e-12);
            // Every wall point of the ruling is R from the tool axis line.
            let t = o.tip(phi);
            for z in [0.0, 7.0, 20.0] {
                let (p, _) = o.wall(phi, z);
                let d = sub(p, t);
                let across = sub(d, crate::vec3::scale(u, dot(d, u)));
                assert!((norm(across) - o.tool_radius).abs() < 1e-12);
            }
        }
        assert_eq!(o.plan_points().len(), 180);
    }
}
