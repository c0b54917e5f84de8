//! `volcomp map`: the volumetric error over a plane of the workspace as an SVG heat
//! map (|e|, with arrows of the in-plane error) and a JSON report.
use super::common::{ModelArgs, load_model};
use crate::axes::Axis;
use crate::machine::error_map::{ErrorMap, MapSpec, Plane, SurfaceFit};
use anyhow::Context;
use clap::ValueEnum;
use serde::Serialize;
use std::path::PathBuf;

pub const EXAMPLES: &str = "\
  volcomp map machines/ref-trt.toml --plane xy --at z=0 --out map-xy.svg
  volcomp map machines/ref-trt.toml --plane xz --at y=50 --a 30 --c 90 --grid 31 --out map-xz.svg --report map-xz.json
  volcomp map machines/ref-trt.toml --plane yz --range -100:100,-150:50 --out map-yz.svg";

const AFTER_HELP: &str = "\
The grid is in joint (machine) coordinates; the third linear axis sits at --at and A, C
at --a, --c. The default range is the machine's travel of the two in-plane axes. Colours
show |e| (µm, from a NURBS surface fitted to the grid); arrows show the in-plane part of
e turned into the machine frame.";

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PlaneArg {
    Xy,
    Xz,
    Yz,
}

impl From<PlaneArg> for Plane {
    fn from(p: PlaneArg) -> Plane {
        match p {
            PlaneArg::Xy => Plane::XY,
            PlaneArg::Xz => Plane::XZ,
            PlaneArg::Yz => Plane::YZ,
        }
    }
}

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
pub struct Args {
    /// Machine file (TOML).
    pub machine: PathBuf,
    /// Plane of the map.
    #[arg(long, value_enum, default_value = "xy")]
    pub plane: PlaneArg,
    /// Position of the normal axis, e.g. `z=0` for the XY plane (default 0).
    #[arg(long, value_name = "AXIS=VALUE", allow_hyphen_values = true)]
    pub at: Option<String>,
    /// A angle, degrees (machines with an A axis).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub a: f64,
    /// B angle, degrees (machines with a B axis).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub b: f64,
    /// C angle, degrees (machines with a C axis).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub c: f64,
    /// Ranges of the two in-plane axes, `U0:U1,V0:V1` (mm); default: the travel.
    #[arg(long, value_name = "U0:U1,V0:V1", allow_hyphen_values = true)]
    pub range: Option<String>,
    /// Grid points per side.
    #[arg(long, default_value_t = 21)]
    pub grid: usize,
    /// Control points per direction of the fitted NURBS surfaces (least squares;
    /// default min(grid, 12); equal to --grid interpolates the grid).
    #[arg(long, value_name = "N")]
    pub control: Option<usize>,
    /// SVG output file.
    #[arg(long, short)]
    pub out: PathBuf,
    /// JSON report: grid values and the surface fit error.
    #[arg(long)]
    pub report: Option<PathBuf>,
    #[command(flatten)]
    pub model: ModelArgs,
}

fn usage(msg: String) -> anyhow::Error {
    crate::cli::UsageError(msg).into()
}

/// `z=0` → 0 for the normal axis `normal`.
fn parse_level(text: &str, normal: Axis) -> anyhow::Result<f64> {
    let (name, value) = text.split_once('=').ok_or_else(|| {
        usage(format!(
            "--at expects AXIS=VALUE such as z=0, got \"{text}\""
        ))
    })?;
    let axis = Axis::from_letter(name.trim().chars().next().unwrap_or('?'));
    if axis != Some(normal) || name.trim().len() != 1 {
        return Err(usage(format!(
            "--at names the axis normal to the plane, {} (got \"{text}\")",
            normal.letter().to_ascii_lowercase()
        )));
    }
    value
        .trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| usage(format!("--at: \"{value}\" is not a finite number")))
}

/// `U0:U1,V0:V1`.
fn parse_ranges(text: &str) -> anyhow::Result<[[f64; 2]; 2]> {
    let bad = || {
        usage(format!(
            "--range expects U0:U1,V0:V1 with U0 < U1 and V0 < V1, got \"{text}\""
        ))
    };
    let parts: Vec<&str> = text.split(',').collect();
    if parts.len() != 2 {
        return Err(bad());
    }
    let mut out = [[0.0; 2]; 2];
    for (slot, part) in out.iter_mut().zip(parts) {
        let (a, b) = part.split_once(':').ok_or_else(bad)?;
        let a: f64 = a.trim().parse().map_err(|_| bad())?;
        let b: f64 = b.trim().parse().map_err(|_| bad())?;
        if !(a.is_finite() && b.is_finite() && a < b) {
            return Err(bad());
        }
        *slot = [a, b];
    }
    Ok(out)
}

#[derive(Serialize)]
struct Report<'a> {
    machine: &'a str,
    map: &'a ErrorMap,
    max_um: f64,
    rms_um: f64,
    /// Fit errors of the NURBS surfaces: |e| (drawn), e_x, e_y, e_z.
    surfaces: &'a [SurfaceFit],
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.grid < 2 || args.grid > 401 {
        return Err(usage(format!(
            "--grid must be between 2 and 401 (got {})",
            args.grid
        )));
    }
    if let Some(n) = args.control {
        let min = (args.grid - 1).min(3) + 1;
        if n < min || n > args.grid {
            return Err(usage(format!(
                "--control must be between {min} (degree + 1) and --grid = {} (got {n})",
                args.grid
            )));
        }
    }
    if !(args.a.is_finite() && args.b.is_finite() && args.c.is_finite()) {
        return Err(usage("--a, --b and --c must be finite".into()));
    }
    let data_on_stdout = super::common::stdout_output(&[
        ("--out -", crate::io::is_stdio(&args.out)),
        (
            "--report -",
            super::common::is_stdout(args.report.as_deref()),
        ),
    ])?;
    let plane: Plane = args.plane.into();
    let (ua, va, na) = plane.axes();
    let level = match &args.at {
        Some(text) => parse_level(text, na)?,
        None => 0.0,
    };
    let ranges = args.range.as_deref().map(parse_ranges).transpose()?;
    let (machine, model) = load_model(&args.machine, &args.model)?;
    super::common::CommandFiles::new()
        .machine(&machine)
        .model(&args.model)
        .output("--out", Some(&args.out))
        .output("--report", args.report.as_deref())
        .check()?;
    let outputs = crate::io::OutputSet::begin();
    let mut rotaries = crate::axes::Axes::default();
    for (axis, value) in [(Axis::A, args.a), (Axis::B, args.b), (Axis::C, args.c)] {
        if value != 0.0 && !machine.letters().contains(axis) {
            return Err(usage(format!(
                "--{} {value}: {} has no {} axis (its axes: {})",
                axis.lower(),
                machine.name,
                axis.letter(),
                machine.letters().letters()
            )));
        }
        rotaries.set(axis, value);
    }
    let [r1, r2] = machine.chain.rotary();
    let rotary_text = format!(
        "{}={} {}={}",
        r1.letter(),
        rotaries.get(r1),
        r2.letter(),
        rotaries.get(r2)
    );
    let travel = |axis: Axis| machine.limits.get(axis).unwrap_or([-100.0, 100.0]);
    let [u_range, v_range] = ranges.unwrap_or([travel(ua), travel(va)]);
    let spec = MapSpec {
        plane,
        level,
        rotaries,
        u_range,
        v_range,
        grid: args.grid,
    };
    let map = ErrorMap::compute(&model, &spec)
        .with_context(|| format!("mapping {} over the {:?} plane", machine.name, plane))?;
    let surfaces = map
        .fit_surfaces(args.control)
        .context("fitting the map surfaces")?;
    let title = format!(
        "{}: |e| over {}{} at {}={} mm, {rotary_text}",
        machine.name,
        ua.letter(),
        va.letter(),
        na.letter(),
        level,
    );
    let svg = crate::report::error_map_svg::error_map_svg(&map, &title, &|u, v| {
        surfaces.magnitude.eval(u, v)
    });
    crate::io::write_file_atomic(&args.out, svg.as_bytes())?;
    let mags = map.magnitudes();
    let rms = (mags.iter().map(|m| m * m).sum::<f64>() / mags.len() as f64).sqrt();
    if let Some(path) = &args.report {
        let report = Report {
            machine: &machine.name,
            map: &map,
            max_um: map.max_magnitude(),
            rms_um: rms,
            surfaces: &surfaces.fits,
        };
        crate::io::write_json_atomic(path, &report)?;
    }
    outputs.commit()?;
    crate::cli::humanln!(
        data_on_stdout,
        "{}: {}×{} grid over {} {:?} × {} {:?} mm at {}={level}, {rotary_text}",
        machine.name,
        args.grid,
        args.grid,
        ua.letter(),
        u_range,
        va.letter(),
        v_range,
        na.letter(),
    );
    crate::cli::humanln!(
        data_on_stdout,
        "|e|: max {:.3} µm, RMS {rms:.3} µm",
        map.max_magnitude()
    );
    for fit in &surfaces.fits {
        crate::cli::humanln!(
            data_on_stdout,
            "NURBS surface of {:<3} (degree {}, {}×{} control points): fit error max {} µm, RMS {} µm",
            fit.quantity,
            fit.degree,
            fit.control_points[0],
            fit.control_points[1],
            small_um(fit.emax_um),
            small_um(fit.erms_um)
        );
    }
    crate::cli::humanln!(
        data_on_stdout,
        "wrote {}",
        crate::io::display_name(&args.out)
    );
    if let Some(path) = &args.report {
        crate::cli::humanln!(data_on_stdout, "wrote {}", crate::io::display_name(path));
    }
    let held = model.held_lookups();
    if held > 0 {
        let warnings = crate::warnings::Warnings::new();
        super::common::add_held_lookups(&warnings, held);
        super::common::print_warnings(&warnings.groups());
    }
    Ok(())
}

/// A fit error for people: three decimals, or two significant digits in
/// scientific notation when it is below 0.01 µm (`0.004 µm` would hide it).
fn small_um(v: f64) -> String {
    if v == 0.0 || v.abs() >= 0.01 {
        format!("{v:.3}")
    } else {
        format!("{v:.1e}")
    }
}

#[cfg(test)]
mod tests {
    /// Issue 23: "1.26e0 um" is 1.260 µm.
    #[test]
    fn fit_errors_read_as_numbers() {
        assert_eq!(super::small_um(1.2634), "1.263");
        assert_eq!(super::small_um(0.0), "0.000");
        assert_eq!(super::small_um(3.21e-5), "3.2e-5");
    }
}
