//! Synthetic point contexts: a zig-zag raster along X over a saddle surface cut on
//! a table-tilting A/C machine, with the contexts a real tool path would give
//! (time from the feed, σ flips at raster reversals, speed, curvature and
//! principal normal of the machine path, tool axis, cut length) and plausible
//! squareness / rotary-location Jacobians from a first-order TRT chain.
//!
//! Used by tests, the confusion-matrix example and the bench, so that the
//! diagnosis can be exercised without the toolpath layer.
//! Invariant: deterministic for a given [`SyntheticOptions`].
use super::effects::{Effect, EffectKind};
use crate::axes::Axes;
use crate::toolpath::PointContext;
use crate::toolpath::context::machine_to_part;
use crate::vec3::{cross, dot, norm, rot_x as rx, rot_z as rz, sub};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// Shape of the synthetic part and path.
#[derive(Clone, Debug, PartialEq)]
pub struct SyntheticOptions {
    /// Raster rows (along X), evenly spaced over y ∈ [−half_y, half_y].
    pub rows: usize,
    /// Half length of the part along X, mm.
    pub half_x_mm: f64,
    /// Half width of the part along Y, mm.
    pub half_y_mm: f64,
    /// Feed, mm/min.
    pub feed_mm_min: f64,
    /// Mean spacing of plan points along a row, mm.
    pub plan_spacing_mm: f64,
    /// Amplitude of the smooth difference between the model's prediction and the
    /// truth (table noise and fit error), µm.
    pub model_error_um: f64,
    /// Seed of the plan points' positions along the rows.
    pub seed: u64,
    /// The surface: a saddle `z = 0.006 (x² − y²)` or a dome `z = −0.006 (x² + y²)`.
    pub dome: bool,
    /// A runs over `a_mid_deg ± a_span_deg` with x, C over `10 ± c_span_deg` with y.
    pub a_mid_deg: f64,
    /// See `a_mid_deg`, degrees.
    pub a_span_deg: f64,
    /// See `a_mid_deg`, degrees.
    pub c_span_deg: f64,
}

impl Default for SyntheticOptions {
    fn default() -> Self {
        SyntheticOptions {
            rows: 15,
            half_x_mm: 45.0,
            half_y_mm: 35.0,
            feed_mm_min: 250.0,
            plan_spacing_mm: 3.5,
            model_error_um: 0.15,
            seed: 7,
            dome: false,
            a_mid_deg: 35.0,
            a_span_deg: 12.0,
            c_span_deg: 25.0,
        }
    }
}

impl SyntheticOptions {
    /// The second part of docs/diagnose.md: a dome cut with A over 15–85° and
    /// C over −50…70° (the saddle raster's A spans 23–47°).
    pub fn dome() -> Self {
        SyntheticOptions {
            dome: true,
            a_mid_deg: 50.0,
            a_span_deg: 35.0,
            c_span_deg: 60.0,
            ..SyntheticOptions::default()
        }
    }
}

/// Contexts and the true volumetric error `e` (µm, part coordinates) of each.
#[derive(Clone, Debug)]
pub struct SyntheticPart {
    /// The plan points' contexts along the path.
    pub contexts: Vec<PointContext>,
    /// The true volumetric error `e` at each context (X Y Z, µm, part coordinates).
    pub truth_um: Vec<[f64; 3]>,
}

const TOOL_RADIUS: f64 = 3.0;
const TOOL_LENGTH: f64 = 100.0;

fn surface(x: f64, y: f64, dome: bool) -> ([f64; 3], [f64; 3]) {
    let s = if dome { -1.0 } else { 1.0 };
    let z = if dome {
        -0.006 * (x * x + y * y) - 5.0
    } else {
        0.006 * (x * x - y * y) - 5.0
    };
    let (fx, fy) = (s * 0.012 * x, -0.012 * y);
    let len = (fx * fx + fy * fy + 1.0).sqrt();
    ([x, y, z], [-fx / len, -fy / len, 1.0 / len])
}

struct PathPoint {
    contact: [f64; 3],
    normal: [f64; 3],
    a_deg: f64,
    c_deg: f64,
    tip: [f64; 3],
    machine: [f64; 3],
    /// Plan point candidate (on a row, not on a step between rows).
    on_row: bool,
}

/// Circle through three points: (curvature, unit principal normal towards the centre).
fn curvature(p0: [f64; 3], p1: [f64; 3], p2: [f64; 3]) -> (f64, [f64; 3]) {
    let (a, b) = (sub(p0, p1), sub(p2, p1));
    let axb = cross(a, b);
    let den = 2.0 * dot(axb, axb);
    if norm(a) < 1e-9 || norm(b) < 1e-9 || den < 1e-18 {
        return (0.0, [0.0; 3]);
    }
    // Centre relative to p1: ((|a|² b − |b|² a) × (a × b)) / (2 |a × b|²).
    let (aa, bb) = (dot(a, a), dot(b, b));
    let w = [
        aa * b[0] - bb * a[0],
        aa * b[1] - bb * a[1],
        aa * b[2] - bb * a[2],
    ];
    let c = cross(w, axb).map(|v| v / den);
    let r = norm(c);
    if !(1e-12..=1e9).contains(&r) {
        return (0.0, [0.0; 3]);
    }
    (1.0 / r, c.map(|v| v / r))
}

/// First-order squareness and rotary-location Jacobians (µm per µrad or per
/// µm, part coordinates) of the synthetic table-tilting A/C chain at the tool
/// tip `tip` (part coordinates, mm) in the pose `a_deg`, `c_deg` with the
/// joints `joints`.
fn chain_jacobians(
    tip: [f64; 3],
    a_deg: f64,
    c_deg: f64,
    joints: &Axes,
) -> ([[f64; 3]; 3], [[f64; 3]; 8]) {
    let (a, c) = (a_deg.to_radians(), c_deg.to_radians());
    let to_part = |v: [f64; 3]| machine_to_part(a_deg, c_deg, v);
    let q = [joints.x, joints.y, joints.z];
    let squareness_jacobian = [
        to_part([q[1] * 1e-3, 0.0, 0.0]),
        to_part([q[2] * 1e-3, 0.0, 0.0]),
        to_part([0.0, q[2] * 1e-3, 0.0]),
    ];
    // First-order rotary location errors of the TRT chain.
    let in_a = rz(c, tip); // point in the A frame
    let offset_a = |d: [f64; 3]| to_part(sub(d, rx(a, d)));
    let tilt_a = |w: [f64; 3]| {
        let lhs = cross(w, rx(a, in_a));
        let rhs = rx(a, cross(w, in_a));
        to_part(sub(lhs, rhs).map(|v| v * 1e-3))
    };
    let offset_c = |d: [f64; 3]| to_part(rx(a, sub(d, rz(c, d))));
    let tilt_c = |w: [f64; 3]| {
        let lhs = cross(w, rz(c, tip));
        let rhs = rz(c, cross(w, tip));
        to_part(rx(a, sub(lhs, rhs).map(|v| v * 1e-3)))
    };
    let location_jacobian = [
        offset_a([0.0, 1.0, 0.0]),
        offset_a([0.0, 0.0, 1.0]),
        tilt_a([0.0, 1.0, 0.0]),
        tilt_a([0.0, 0.0, 1.0]),
        offset_c([1.0, 0.0, 0.0]),
        offset_c([0.0, 1.0, 0.0]),
        tilt_c([1.0, 0.0, 0.0]),
        tilt_c([0.0, 1.0, 0.0]),
    ];
    (squareness_jacobian, location_jacobian)
}

/// Build the synthetic part.
pub fn saddle_raster(options: &SyntheticOptions) -> SyntheticPart {
    let mut rng = ChaCha8Rng::seed_from_u64(options.seed);
    let rows = options.rows.max(2);
    let step = 0.5;
    let (hx, hy) = (options.half_x_mm, options.half_y_mm);
    let nx = (2.0 * hx / step).round().max(2.0) as usize;
    let mut path: Vec<PathPoint> = Vec::new();
    let make = |x: f64, y: f64, on_row: bool| {
        let (contact, normal) = surface(x, y, options.dome);
        let a_deg = options.a_mid_deg + options.a_span_deg * x / hx + 4.0 * (y / hy).powi(2);
        let c_deg = 10.0 + options.c_span_deg * y / hy - 8.0 * x / hx;
        let (a, c) = (a_deg.to_radians(), c_deg.to_radians());
        let u = [a.sin() * c.sin(), a.sin() * c.cos(), a.cos()];
        let tip = [0, 1, 2].map(|k| contact[k] - TOOL_RADIUS * u[k] + TOOL_RADIUS * normal[k]);
        let machine = rx(a, rz(c, tip));
        PathPoint {
            contact,
            normal,
            a_deg,
            c_deg,
            tip,
            machine,
            on_row,
        }
    };
    for j in 0..rows {
        let y = -hy + 2.0 * hy * j as f64 / (rows - 1) as f64;
        if j > 0 {
            let y_prev = -hy + 2.0 * hy * (j - 1) as f64 / (rows - 1) as f64;
            let x_end = if j % 2 == 1 { hx } else { -hx };
            let ny = ((y - y_prev) / step).ceil() as usize;
            for s in 1..ny {
                path.push(make(
                    x_end,
                    y_prev + (y - y_prev) * s as f64 / ny as f64,
                    false,
                ));
            }
        }
        for i in 0..=nx {
            let f = i as f64 / nx as f64;
            let x = if j % 2 == 0 {
                -hx + 2.0 * hx * f
            } else {
                hx - 2.0 * hx * f
            };
            path.push(make(x, y, true));
        }
    }
    // Walk the path: time, σ, speed, cut length.
    let feed = options.feed_mm_min.max(1e-6);
    let mut time = 0.0;
    let mut sigma = [0.0; 3];
    let mut cut = 0.0;
    let mut per_point = Vec::with_capacity(path.len());
    for (i, p) in path.iter().enumerate() {
        if i > 0 {
            let d = sub(p.machine, path[i - 1].machine);
            let len = norm(d);
            time += len / feed;
            cut += len / 1000.0;
            for k in 0..3 {
                if d[k].abs() > 1e-9 {
                    sigma[k] = d[k].signum();
                }
            }
        }
        per_point.push((time, sigma, cut));
    }
    let spacing = (options.plan_spacing_mm / step).round().max(1.0) as usize;
    let mut contexts = Vec::new();
    let mut truth = Vec::new();
    let mut next = rng.random_range(0..spacing);
    for i in 1..path.len().saturating_sub(1) {
        let p = &path[i];
        if !p.on_row {
            continue;
        }
        if next > 0 {
            next -= 1;
            continue;
        }
        next = spacing - 1 + rng.random_range(0..=2) - 1;
        let (time_min, sigma, cut_length_m) = per_point[i];
        let (kappa, n_machine) = curvature(path[i - 1].machine, p.machine, path[i + 1].machine);
        let joints = Axes::xyzac(
            p.machine[0],
            p.machine[1],
            p.machine[2] + TOOL_LENGTH,
            p.a_deg,
            p.c_deg,
        );
        let (squareness_jacobian, location_jacobian) =
            chain_jacobians(p.tip, p.a_deg, p.c_deg, &joints);
        let (a, c) = (p.a_deg.to_radians(), p.c_deg.to_radians());
        let (x, y) = (p.contact[0], p.contact[1]);
        let e = [
            2.0 + 0.03 * x - 0.01 * y,
            -1.0 + 0.02 * y + 0.0005 * x * y,
            3.0 - 0.01 * x + 0.02 * y,
        ];
        // What each "table" contributes (they sum to e): X varies with x, Y
        // with y, the constant part is put on Z.
        let axis_deviation_um = [
            dot(p.normal, [0.03 * x, 0.0, -0.01 * x]),
            dot(p.normal, [-0.01 * y, 0.02 * y + 0.0005 * x * y, 0.02 * y]),
            dot(p.normal, [2.0, -1.0, 3.0]),
            0.0,
            0.0,
        ];
        let model_error = options.model_error_um * (x / 15.0).sin() * (y / 12.0).cos();
        let (sa, ca) = a.sin_cos();
        let tool_axis = [sa * c.sin(), sa * c.cos(), ca];
        contexts.push(PointContext {
            id: (contexts.len() + 1).to_string(),
            point: p.contact,
            normal: p.normal,
            cut: true,
            line: 10 * (i + 2),
            block: i,
            time_min,
            joints,
            sigma,
            speed_mm_s: feed / 60.0,
            curvature_per_mm: kappa,
            principal_normal: n_machine,
            tool_axis,
            cut_length_m,
            predicted_um: dot(p.normal, e) + model_error,
            squareness_jacobian,
            location_jacobian,
            axis_deviation_um,
            // The model error's RMS over the part (the field's amplitude / 2).
            model_u_um: options.model_error_um / 2.0,
            rotary: [crate::axes::Axis::A, crate::axes::Axis::C],
            machine_to_part_rotation: None,
        });
        truth.push(e);
    }
    SyntheticPart {
        contexts,
        truth_um: truth,
    }
}

/// A random effect of `kind` with realistic parameter signs and proportions,
/// scaled so that its `n·Δ` over `contexts` has an RMS drawn from
/// `rms_um` (µm); `tau` of `thermal_drift` is drawn in [0.3, 1.5] × the
/// program's duration.
pub fn random_effect(
    kind: EffectKind,
    contexts: &[PointContext],
    rms_um: (f64, f64),
    rng: &mut impl Rng,
) -> Effect {
    let mut u = |lo: f64, hi: f64| rng.random_range(lo..hi);
    let t_max = crate::toolpath::last_time_min(contexts).max(1e-3);
    let mut values: Vec<f64> = match kind {
        EffectKind::ThermalDrift => vec![
            u(-8.0, 8.0),
            u(-8.0, 8.0),
            u(-8.0, 8.0),
            u(0.3, 1.5) * t_max,
        ],
        EffectKind::Backlash => vec![u(2.0, 10.0), u(2.0, 10.0), u(2.0, 10.0)],
        EffectKind::ServoLag => vec![u(0.5e-3, 3e-3)],
        EffectKind::ToolDeflection => vec![u(2.0, 8.0)],
        EffectKind::ToolWear => vec![u(1.0, 10.0)],
        EffectKind::RadiusOffset => vec![u(2.0, 8.0) * if u(0.0, 1.0) < 0.5 { -1.0 } else { 1.0 }],
        EffectKind::SetupError => vec![
            u(-8.0, 8.0),
            u(-8.0, 8.0),
            u(-8.0, 8.0),
            u(-100.0, 100.0),
            u(-100.0, 100.0),
            u(-100.0, 100.0),
        ],
        EffectKind::Squareness => vec![u(-100.0, 100.0), u(-100.0, 100.0), u(-100.0, 100.0)],
        EffectKind::RotaryLocation => vec![
            u(-10.0, 10.0),
            u(-10.0, 10.0),
            u(-100.0, 100.0),
            u(-100.0, 100.0),
            u(-10.0, 10.0),
            u(-10.0, 10.0),
            u(-100.0, 100.0),
            u(-100.0, 100.0),
        ],
    };
    let target = u(rms_um.0, rms_um.1);
    let effect = Effect {
        kind,
        values: values.clone(),
    };
    let current = {
        let d: Vec<f64> = contexts.iter().map(|c| effect.deviation_um(c)).collect();
        super::noise::rms(&d)
    };
    if current > 1e-12 {
        let s = target / current;
        for v in values.iter_mut().take(kind.linear_count()) {
            *v *= s;
        }
    }
    Effect { kind, values }
}

/// A part from contexts (JSON, as `--dump-contexts` writes them) and a noise-free
/// `simulate` of the same plan (the true volumetric error `e = (m − p)·1000`).
pub fn from_fixture(
    contexts_json: &str,
    truth: &crate::inspection::Measurement,
) -> Option<SyntheticPart> {
    let contexts: Vec<PointContext> = serde_json::from_str(contexts_json).ok()?;
    if contexts.len() != truth.points.len() {
        return None;
    }
    let truth_um = truth
        .points
        .iter()
        .map(|m| [0, 1, 2].map(|k| (m.measured[k] - m.plan.point[k]) * 1000.0))
        .collect();
    Some(SyntheticPart { contexts, truth_um })
}

/// The context of a follow-up probe (docs/diagnose.md "Follow-up") of the cut
/// point `cut` of a [`saddle_raster`] part on its synthetic table-tilting A/C
/// machine: a ball stylus of radius `probe_radius_mm` on the raster's tool
/// length, at the rotary joints `rotary` (A, C in degrees), at `time_min`,
/// approaching along −n (as `toolpath::cut::probe_context` on a real
/// machine). Its squareness and rotary-location Jacobians are the raster's
/// first-order chain at the probe's tip and pose.
///
/// The raster's machine error and its model's prediction are functions of the
/// part point alone (the tables are written in part x, y), so the probe's
/// `predicted_um` and `axis_deviation_um` are the cut's: the model's part of
/// a re-probe, `n·(e(q_cut) − e(q_probe))`, is zero in every pose.
pub fn probe_context(
    cut: &PointContext,
    rotary: [f64; 2],
    time_min: f64,
    probe_radius_mm: f64,
) -> PointContext {
    let [a_deg, c_deg] = rotary;
    let (a, c) = (a_deg.to_radians(), c_deg.to_radians());
    let (sa, ca) = a.sin_cos();
    let tool_axis = [sa * c.sin(), sa * c.cos(), ca];
    let (n, p) = (cut.normal, cut.point);
    let tip = [0, 1, 2].map(|k| p[k] + probe_radius_mm * (n[k] - tool_axis[k]));
    let machine = rx(a, rz(c, tip));
    let joints = Axes::xyzac(
        machine[0],
        machine[1],
        machine[2] + TOOL_LENGTH,
        a_deg,
        c_deg,
    );
    let (squareness_jacobian, location_jacobian) = chain_jacobians(tip, a_deg, c_deg, &joints);
    // The approach −n in the machine frame (part → machine: Rx(a)·Rz(c)).
    let approach = rx(a, rz(c, n.map(|v| -v)));
    let sigma = crate::toolpath::cut::approach_signs(approach);
    // `predicted_um`, `axis_deviation_um` and `rotary` stay the cut's.
    PointContext {
        joints,
        sigma,
        tool_axis,
        squareness_jacobian,
        location_jacobian,
        machine_to_part_rotation: None,
        ..cut.probe_of(time_min)
    }
}
