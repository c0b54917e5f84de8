//! The saddle sample: a five-axis ball-end finishing program for a saddle-style
//! bicycle seat like the seed paper's (§4.3, Fig. 14; blank 100 × 80 × 40 mm) and
//! its 372-point inspection plan (the paper measured 372 points).
//!
//! Everything here is deterministic: the same options give the same bytes.
//!
//! Geometry (part coordinates, mm; origin at the centre of the blank's bottom face):
//! `z(x, y) = 28 + 0.0036 x² − 0.0075 y² − 0.00002 x³` over x ∈ [−50, 50],
//! y ∈ [−40, 40]: high along the centre line, falling off to both sides, rising
//! towards the back, a little lower at the nose. Its heights stay within the blank
//! (16.0 mm … 39.5 mm).
//!
//! Tool path: zig-zag raster of lines y = const (stepover 1.5 mm) with points every
//! 1.5 mm in x; at every point the ball centre is `p + R n` and the tool axis `u`
//! leans from the vertical by `θ = 30° + 5° cos(π x / 100) cos(π y / 80)` towards
//! the azimuth `−90° + 25° x / 50`, so its angle to the surface normal varies over
//! the part and A and C move throughout, away from the A = 0 pole. The tool tip is
//! `p + R n − R u`, so the contact point of every path point is exactly the
//! surface point `p`.
//!
//! Plan: x = −45 … 45 step 3 (31) × y = −33 … 33 step 6 (12) = 372 points, all
//! of them path points.

use crate::vec3::normalise;

/// Height of the saddle surface at (x, y), mm.
pub fn height(x: f64, y: f64) -> f64 {
    28.0 + 0.0036 * x * x - 0.0075 * y * y - 0.00002 * x * x * x
}

/// Unit outward normal (towards the tool) of the saddle surface at (x, y).
pub fn normal(x: f64, y: f64) -> [f64; 3] {
    let dzdx = 2.0 * 0.0036 * x - 3.0 * 0.00002 * x * x;
    let dzdy = -2.0 * 0.0075 * y;
    normalise([-dzdx, -dzdy, 1.0])
}

/// Tilt of the tool axis from the vertical (part Z), degrees: 30° … 35° over the raster.
pub fn tilt_degrees(x: f64, y: f64) -> f64 {
    use std::f64::consts::PI;
    30.0 + 5.0 * (PI * x / 100.0).cos() * (PI * y / 80.0).cos()
}

/// Direction of the lean in the XY plane, degrees from +X: towards −Y, turning
/// by ±25° across the part.
pub fn lean_azimuth_degrees(x: f64) -> f64 {
    -90.0 + 25.0 * x / 50.0
}

/// Unit tool axis (tip towards spindle) at surface point (x, y): leaning by
/// [`tilt_degrees`] from the vertical towards [`lean_azimuth_degrees`]. Its angle
/// to the surface normal varies over the part (about 0° … 60°), and it never comes
/// near the vertical, where an A/C table's C axis is undetermined (the pole).
pub fn tool_axis(x: f64, y: f64) -> [f64; 3] {
    let t = tilt_degrees(x, y).to_radians();
    let phi = lean_azimuth_degrees(x).to_radians();
    [t.sin() * phi.cos(), t.sin() * phi.sin(), t.cos()]
}

/// Raster settings of the sample program.
#[derive(Clone, Copy, Debug)]
pub struct SaddleOptions {
    /// Ball-end radius, mm.
    pub tool_radius: f64,
    /// Distance between raster lines, mm.
    pub stepover: f64,
    /// Distance between points along a line, mm.
    pub point_spacing: f64,
    /// Half extents of the raster in x and y, mm.
    pub x_extent: f64,
    pub y_extent: f64,
    /// Feed, mm/min.
    pub feed: f64,
    /// Safe height above the part for rapids (part z, mm).
    pub clearance: f64,
    /// A roughing pass with a second tool before the finishing pass.
    pub roughing: Option<RoughingOptions>,
}

/// The roughing pass: a larger ball-end tool (T2) on a coarser raster,
/// leaving `stock` mm on the surface (so its contact points are never
/// matched to plan points, 0.5 mm at most).
#[derive(Clone, Copy, Debug)]
pub struct RoughingOptions {
    /// Gauge point to tip, mm (for the tool table).
    pub tool_length: f64,
    pub tool_radius: f64,
    pub stock: f64,
    pub stepover: f64,
    pub point_spacing: f64,
    pub feed: f64,
}

impl Default for RoughingOptions {
    fn default() -> Self {
        RoughingOptions {
            tool_length: 60.0,
            tool_radius: 5.0,
            stock: 1.0,
            stepover: 6.0,
            point_spacing: 3.0,
            feed: 2000.0,
        }
    }
}

impl Default for SaddleOptions {
    fn default() -> Self {
        SaddleOptions {
            tool_radius: 3.0,
            stepover: 1.5,
            point_spacing: 1.5,
            x_extent: 48.0,
            y_extent: 39.0,
            feed: 1200.0,
            clearance: 30.0,
            roughing: Some(RoughingOptions::default()),
        }
    }
}

/// One cutter location: the tool tip and axis in part coordinates, and the surface
/// point it cuts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutterLocation {
    pub surface: [f64; 3],
    pub normal: [f64; 3],
    pub tip: [f64; 3],
    pub axis: [f64; 3],
}

/// [`cutter_location`] on the surface offset by `stock` mm along its normal.
pub fn cutter_location_with_stock(x: f64, y: f64, radius: f64, stock: f64) -> CutterLocation {
    let n = normal(x, y);
    let p = [
        x + stock * n[0],
        y + stock * n[1],
        height(x, y) + stock * n[2],
    ];
    let u = tool_axis(x, y);
    let tip = [
        p[0] + radius * (n[0] - u[0]),
        p[1] + radius * (n[1] - u[1]),
        p[2] + radius * (n[2] - u[2]),
    ];
    CutterLocation {
        surface: p,
        normal: n,
        tip,
        axis: u,
    }
}

/// The finishing raster, line by line (zig-zag: odd lines run in −x).
pub fn raster(options: &SaddleOptions) -> Vec<Vec<CutterLocation>> {
    raster_of(
        options,
        options.stepover,
        options.point_spacing,
        options.tool_radius,
        0.0,
    )
}

/// A zig-zag raster over the blank with `radius` leaving `stock`.
fn raster_of(
    options: &SaddleOptions,
    stepover: f64,
    spacing: f64,
    radius: f64,
    stock: f64,
) -> Vec<Vec<CutterLocation>> {
    let lines = grid(-options.y_extent, options.y_extent, stepover);
    let xs = grid(-options.x_extent, options.x_extent, spacing);
    lines
        .iter()
        .enumerate()
        .map(|(i, &y)| {
            let mut row: Vec<CutterLocation> = xs
                .iter()
                .map(|&x| cutter_location_with_stock(x, y, radius, stock))
                .collect();
            if i % 2 == 1 {
                row.reverse();
            }
            row
        })
        .collect()
}

/// The 372 inspection points `(x, y, z, normal)`, ids 1…372 row by row.
pub fn plan_points() -> Vec<([f64; 3], [f64; 3])> {
    let mut out = Vec::with_capacity(372);
    for y in grid(-33.0, 33.0, 6.0) {
        for x in grid(-45.0, 45.0, 3.0) {
            out.push(([x, y, height(x, y)], normal(x, y)));
        }
    }
    out
}

/// `lo, lo + step, …, hi` computed without accumulating rounding error.
fn grid(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let n = ((hi - lo) / step).round() as usize;
    (0..=n).map(|i| lo + step * i as f64).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::vec3::dot;

    #[test]
    fn plan_has_372_points_on_raster_lines() {
        let plan = plan_points();
        assert_eq!(plan.len(), 372);
        let o = SaddleOptions::default();
        for (p, _) in &plan {
            let line = (p[1] + o.y_extent) / o.stepover;
            assert!((line - line.round()).abs() < 1e-9);
            let col = (p[0] + o.x_extent) / o.point_spacing;
            assert!((col - col.round()).abs() < 1e-9);
        }
    }

    #[test]
    fn surface_stays_inside_blank() {
        for x in grid(-50.0, 50.0, 1.0) {
            for y in grid(-40.0, 40.0, 1.0) {
                let z = height(x, y);
                assert!((0.0..=40.0).contains(&z), "z({x},{y}) = {z}");
            }
        }
    }

    #[test]
    fn tool_axis_leans_by_theta_and_stays_on_the_tool_side() {
        for x in grid(-50.0, 50.0, 5.0) {
            for y in grid(-40.0, 40.0, 5.0) {
                let u = tool_axis(x, y);
                let from_vertical = u[2].clamp(-1.0, 1.0).acos().to_degrees();
                assert!((from_vertical - tilt_degrees(x, y)).abs() < 1e-9);
                assert!(from_vertical >= 29.0, "near the pole at ({x}, {y})");
                let to_normal = dot(normal(x, y), u).acos().to_degrees();
                assert!(
                    to_normal < 75.0,
                    "axis {to_normal}° from the normal at ({x}, {y})"
                );
            }
        }
    }

    #[test]
    fn contact_point_of_cutter_location_is_the_surface_point() {
        let cl = cutter_location_with_stock(12.0, -7.5, 3.0, 0.0);
        for i in 0..3 {
            let contact = cl.tip[i] + 3.0 * cl.axis[i] - 3.0 * cl.normal[i];
            assert!((contact - cl.surface[i]).abs() < 1e-12);
        }
    }
}

/// The program texts and the plan of the saddle sample.
#[derive(Clone, Debug, PartialEq)]
pub struct SaddleFiles {
    /// Joint-frame program (axis commands).
    pub joint_program: String,
    /// The same tool path as a part-frame (tool-tip control, `G43.4`) program.
    pub part_program: String,
    /// Inspection plan CSV (`id,x,y,z,i,j,k`).
    pub plan_csv: String,
    /// LinuxCNC tool table of the program's tools (T1 the finishing tool of
    /// `finishing_length`, T2 the roughing tool).
    pub tool_table: String,
}

#[derive(Debug, thiserror::Error)]
pub enum SampleError {
    #[error("the saddle tool path needs an orientation the machine cannot reach: {0}")]
    Inverse(#[from] crate::kinematics::InverseError),
    #[error(
        "the saddle tool path would flip the rotary axes by {jump_deg:.1}° within a cut (the {pass} pass, row {row}, point {point}; kinematics.md: more than 90°)"
    )]
    Flip {
        pass: String,
        row: usize,
        point: usize,
        jump_deg: f64,
    },
}

/// The joints every pass starts its orientations from: the solution for the
/// typical lean (20° from the vertical towards −Y) whose first rotary joint (in
/// letter order) is positive, each joint in (−180°, 180°] (A20 C180 on an A/C
/// table).
pub fn start_joints(
    kinematics: &crate::kinematics::Kinematics,
) -> Result<crate::axes::Axes, SampleError> {
    let lean = 20f64.to_radians();
    let axis = [0.0, -lean.sin(), lean.cos()];
    let solutions = kinematics.orientation_solutions(axis);
    let chosen = solutions
        .iter()
        .find(|s| s[0] > 0.0)
        .or(solutions.first())
        .ok_or(crate::kinematics::InverseError::Unreachable { axis })?;
    let [r1, r2] = kinematics.rotary();
    Ok(crate::axes::Axes::xyz_rotary(
        [0.0; 3],
        [(r1, chosen[0]), (r2, chosen[1])],
    ))
}

/// Generate the saddle sample for a machine's nominal kinematics; `limits` is the
/// travel of its two rotary axes (letter order, `None` endless); the programs'
/// header names `machine`.
pub fn generate(
    kinematics: &crate::kinematics::Kinematics,
    limits: [Option<[f64; 2]>; 2],
    options: &SaddleOptions,
    machine: &str,
) -> Result<SaddleFiles, SampleError> {
    use crate::kinematics::InverseOptions;
    use std::fmt::Write as _;

    let mut joint = String::new();
    let mut part = String::new();
    let header = |out: &mut String, frame: &str| {
        let _ = writeln!(out, "%");
        let _ = writeln!(
            out,
            "O2016 (SADDLE SEAT - FIVE-AXIS BALL-END ROUGHING AND FINISHING - {frame})"
        );
        if let Some(r) = &options.roughing {
            let _ = writeln!(
                out,
                "(T2 BALL END R{} ROUGHING - STEPOVER {} MM - {} MM STOCK; TOOL TABLE SADDLE.TBL)",
                r.tool_radius, r.stepover, r.stock
            );
        }
        let _ = writeln!(
            out,
            "(BLANK 100 X 80 X 40 MM - T1 BALL END R{} FINISHING - ZIG-ZAG RASTER ALONG X - STEPOVER {} MM)",
            options.tool_radius, options.stepover
        );
        let _ = writeln!(
            out,
            "(TOOL AXIS LEANING 30-35 DEG FROM VERTICAL TOWARDS -Y +-25 DEG; GENERATED BY VOLCOMP SAMPLE SADDLE{}",
            super::machine_suffix(machine)
        );
    };
    header(&mut joint, "JOINT FRAME");
    header(&mut part, "TOOL-TIP CONTROL G43.4");
    let mut w = Writer { joint, part, n: 10 };
    w.block("G21 G90 G94 G17", "G21 G90 G94 G17");
    let start = start_joints(kinematics)?;
    let finishing = Pass {
        tool: 1,
        label: format!("BALL END R{}", options.tool_radius),
        spindle: "S12000 M3",
        feed: options.feed,
        raster: raster(options),
    };
    let passes = options
        .roughing
        .map(|r| {
            let pass = Pass {
                tool: 2,
                label: format!("BALL END R{} ROUGHING, {} MM STOCK", r.tool_radius, r.stock),
                spindle: "S9000 M3",
                feed: r.feed,
                raster: raster_of(options, r.stepover, r.point_spacing, r.tool_radius, r.stock),
            };
            (pass, r.tool_length)
        })
        .into_iter()
        .chain([(finishing, kinematics.tool_length)]);
    for (k, (pass, tool_length)) in passes.enumerate() {
        if k > 0 {
            // Tool-tip control off for the tool change.
            w.block("M5", "G49 M5");
        }
        w.block(
            &format!("T{t} M6 ({})", pass.label, t = pass.tool),
            &format!("T{t} M6 ({})", pass.label, t = pass.tool),
        );
        // Joint programs apply the tool's length offset; part programs with G43.4.
        w.block(
            &format!("G43 H{}", pass.tool),
            &format!("(TOOL T{})", pass.tool),
        );
        w.block(pass.spindle, pass.spindle);
        // Every pass starts its orientations from the same joints, so the
        // finishing pass is the same with or without roughing.
        let inverse = InverseOptions {
            previous: start,
            limits,
        };
        // The pass's own tool: with a rotary axis on the tool side its length
        // moves the joints that put the tip on the cutter location.
        let tool_kinematics = kinematics.with_tool_length(tool_length);
        w.pass(&tool_kinematics, &pass, inverse, options.clearance)?;
    }
    w.block("M5", "G49 M5");
    w.block("M30", "M30");
    let Writer {
        mut joint,
        mut part,
        ..
    } = w;
    joint.push_str("%\n");
    part.push_str("%\n");

    let plan = super::plan_csv(&plan_points());
    let mut tool_table = format!(
        "T1 P1 Z{:.3} D{:.3} ;ball end R{} finishing\n",
        kinematics.tool_length,
        2.0 * options.tool_radius,
        options.tool_radius
    );
    if let Some(r) = &options.roughing {
        let _ = writeln!(
            tool_table,
            "T2 P2 Z{:.3} D{:.3} ;ball end R{} roughing",
            r.tool_length,
            2.0 * r.tool_radius,
            r.tool_radius
        );
    }
    Ok(SaddleFiles {
        joint_program: joint,
        part_program: part,
        plan_csv: plan,
        tool_table,
    })
}

/// One pass of the sample: its tool, spindle, feed and raster.
struct Pass {
    tool: u32,
    label: String,
    spindle: &'static str,
    feed: f64,
    raster: Vec<Vec<CutterLocation>>,
}

/// The joint and part programs written side by side, with their N numbers.
struct Writer {
    joint: String,
    part: String,
    n: u32,
}

impl Writer {
    fn block(&mut self, j: &str, p: &str) {
        use std::fmt::Write as _;
        let _ = writeln!(self.joint, "N{} {j}", self.n);
        let _ = writeln!(self.part, "N{} {p}", self.n);
        self.n += 10;
    }

    /// Approach, plunge, the raster, and the retract of one pass.
    fn pass(
        &mut self,
        kinematics: &crate::kinematics::Kinematics,
        pass: &Pass,
        mut inverse: crate::kinematics::InverseOptions,
        clearance: f64,
    ) -> Result<(), SampleError> {
        use crate::axes::{Axes, Axis, AxisSet};
        let [r1, r2] = kinematics.rotary();
        let letters = AxisSet::of(&[Axis::X, Axis::Y, Axis::Z, r1, r2]);
        let fmt_axes = |a: &Axes| a.words(letters, 4);
        let fmt_part = |t: [f64; 3], a: &Axes| {
            Axes {
                x: t[0],
                y: t[1],
                z: t[2],
                ..*a
            }
            .words(letters, 4)
        };
        let moved = super::moved_words;
        let lifted = |j: &Axes| super::lifted(kinematics, j, clearance);
        let mut first = true;
        let mut last = Axes::default();
        for (i, line) in pass.raster.iter().enumerate() {
            for (k, cl) in line.iter().enumerate() {
                let solution = kinematics.inverse_tool_axis(cl.tip, cl.axis, &inverse)?;
                if !first && solution.is_flip() {
                    return Err(SampleError::Flip {
                        pass: pass.label.clone(),
                        row: i,
                        point: k,
                        jump_deg: solution.jump_deg,
                    });
                }
                let joints = solution.joints;
                inverse.previous = joints;
                if first {
                    // Approach: rapid above the first point, then plunge.
                    let (above, above_tip) = lifted(&joints);
                    self.block(
                        &format!("G0 {}", fmt_axes(&above)),
                        &format!("G43.4 H{} G0 {}", pass.tool, fmt_part(above_tip, &above)),
                    );
                    self.block(
                        &format!("G1 {} F400. (PLUNGE)", moved(&above, &joints)),
                        &format!(
                            "G1 X{:.4} Y{:.4} Z{:.4} F400. (PLUNGE)",
                            cl.tip[0], cl.tip[1], cl.tip[2]
                        ),
                    );
                    first = false;
                } else {
                    let comment = if k == 0 {
                        format!(" (LINE {} Y{:.1})", i + 1, cl.surface[1])
                    } else {
                        String::new()
                    };
                    // The first move after the plunge sets the pass's feed.
                    let feed = if i == 0 && k == 1 {
                        format!(" F{:.0}.", pass.feed)
                    } else {
                        String::new()
                    };
                    self.block(
                        &format!("{}{feed}{comment}", fmt_axes(&joints)),
                        &format!("{}{feed}{comment}", fmt_part(cl.tip, &joints)),
                    );
                }
                last = joints;
            }
        }
        let (retract, retract_tip) = lifted(&last);
        self.block(
            &format!("G0 {}", moved(&last, &retract)),
            &format!(
                "G0 X{:.4} Y{:.4} Z{:.4}",
                retract_tip[0], retract_tip[1], retract_tip[2]
            ),
        );
        Ok(())
    }
}
