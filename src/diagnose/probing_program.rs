//! The probing program of a follow-up design (docs/diagnose.md "Follow-up"):
//! G-code in the dialect we read (gcode.md; joint frame, G38.2 probing moves),
//! one block group per probe: retract to a safe Z, rotate, position above the
//! clearance point, approach along −n with G38.2 (2 mm before the surface to
//! 1 mm beyond it), retract along n.
//!
//! Invariant: pure text; the joints come from the probes' contexts (built by
//! the toolpath layer with the probe's length and stylus radius), and the
//! clearance points are offsets along the normal turned into the machine frame
//! (`Rx(a)·Rz(c)`, the linear part of the nominal kinematics).
use super::followup::FollowupDesign;

/// Settings of the probing program.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbingOptions {
    /// Machine Z (mm) to retract to before each rotation.
    pub safe_z_mm: f64,
    /// Probing feed, mm/min.
    pub feed_mm_min: f64,
    /// Start of the approach, mm before the surface along n.
    pub clearance_mm: f64,
    /// End of the approach, mm beyond the surface (the probe must trip before).
    pub overtravel_mm: f64,
    /// Stylus radius and probe length, for the header.
    pub stylus_radius_mm: f64,
    pub probe_length_mm: f64,
    /// Lines of provenance for the header (program, measurement).
    pub provenance: Vec<String>,
}

/// A comment line `(text)`: printable ASCII, no nested parentheses.
fn comment(s: &str) -> String {
    let inner: String = s
        .chars()
        .map(|c| match c {
            '(' => '[',
            ')' => ']',
            '°' => 'd',
            'σ' => 's',
            'µ' => 'u',
            '→' => '>',
            c if c.is_ascii_graphic() || c == ' ' => c,
            _ => '?',
        })
        .collect();
    format!("({inner})")
}

/// A part-frame vector in the machine frame at `ctx`'s pose (the transpose of
/// its machine → part rotation; `Rx(a)·Rz(c)·v` on an A/C table).
fn part_to_machine(ctx: &crate::toolpath::PointContext, v: [f64; 3]) -> [f64; 3] {
    // The rotation is orthonormal: its inverse is its transpose, read off the
    // images of the machine axes.
    let cols = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]].map(|e| ctx.machine_to_part(e));
    std::array::from_fn(|i| crate::vec3::dot(cols[i], v))
}

fn xyz(p: [f64; 3]) -> String {
    format!("X{:.4} Y{:.4} Z{:.4}", p[0], p[1], p[2])
}

/// The probing program of `design`.
pub fn probing_program(design: &FollowupDesign, options: &ProbingOptions) -> String {
    let mut s = String::new();
    let mut line = |text: String| {
        s.push_str(&text);
        s.push('\n');
    };
    line("%".into());
    line(comment(&format!(
        "volcomp follow-up probing program: {} probes to tell {} from {}",
        design.probes.len(),
        design.selected,
        design.rivals.join(", ")
    )));
    for p in &options.provenance {
        line(comment(p));
    }
    line(comment(&format!(
        "expected separation {:.1} sigma at a probing noise of {:.2} um",
        design.expected_separation_sigma, design.noise_um
    )));
    line(comment(&format!(
        "run right after the part program with the part still clamped; probe of length {} mm to the stylus tip, ball radius {} mm, as the machine file's tool",
        options.probe_length_mm, options.stylus_radius_mm
    )));
    line(
        "(record each probe's trigger point [part frame] and time in the follow-up plan's columns mx,my,mz and t_min)"
            .into(),
    );
    line("(check the moves and clearances in a simulation of this machine before running)".into());
    line("G21 G90 G94 G17".into());
    for p in &design.probes {
        let ctx = &p.probe.context;
        let j = ctx.joints;
        let along = |d: f64| {
            let off = part_to_machine(
                ctx,
                [ctx.normal[0] * d, ctx.normal[1] * d, ctx.normal[2] * d],
            );
            [j.x + off[0], j.y + off[1], j.z + off[2]]
        };
        let start = along(options.clearance_mm);
        let end = along(-options.overtravel_mm);
        let expects = p
            .expected_um
            .iter()
            .map(|(h, v)| format!("{h} {v:+.2} um"))
            .collect::<Vec<_>>()
            .join(", ");
        line(comment(&format!(
            "{}: plan point {}, {}, at t = {:.2} min; expects {}",
            p.id, p.point_id, p.pose, p.time_min, expects
        )));
        line(format!("G0 Z{:.4}", options.safe_z_mm));
        let [r1, r2] = ctx.rotary;
        line(format!(
            "G0 {}{:.4} {}{:.4}",
            r1.letter(),
            j.get(r1),
            r2.letter(),
            j.get(r2)
        ));
        line(format!("G0 X{:.4} Y{:.4}", start[0], start[1]));
        line(format!("G0 Z{:.4}", start[2]));
        line(format!("G38.2 {} F{}", xyz(end), options.feed_mm_min));
        line(format!("G0 {}", xyz(start)));
    }
    line(format!("G0 Z{:.4}", options.safe_z_mm));
    line("M2".into());
    line("%".into());
    s
}
