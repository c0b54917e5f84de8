//! `volcomp error`: the volumetric error and tool-axis error at one pose or many.
use super::common::{FrameArg, ModelArgs, load_model};
use crate::axes::{Axes, Joints};
use crate::gcode::{Pose, ToolInUse};
use crate::kinematics::VolumetricError;
use crate::machine::{Approach, ErrorModel, Machine};
use crate::toolpath::joints_of;
use anyhow::{Context, anyhow};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

pub const EXAMPLES: &str = "\
  volcomp error machines/ref-trt.toml --at 10,20,-30,15,45
  volcomp error machines/ref-trt.toml --at 10,20,-30,15,45 --json
  volcomp error machines/ref-trt.toml --at 0,0,-50,30,725 --verbose
  volcomp error machines/ref-trt.toml --at 5,5,5,30,45 --frame part
  volcomp error machines/ref-trt.toml --at 10,20,-30,15,45 --tools samples/saddle.tbl --tool 2
  printf 'x,y,z,a,c\\n10,20,-30,15,45\\n0,0,-50,30,90\\n' > poses.csv
  volcomp error machines/ref-trt.toml --poses poses.csv --json > errors.json
  volcomp fit machines/ref-trt.toml --report fit.json
  volcomp error machines/ref-trt.toml --model fit.json --at 10,20,-30,15,45
  volcomp error machines/ref-trt.toml --at 50,20,-30,15,45 --direction X+,Y-
  volcomp error machines/bc-trt.toml --at 10,20,-30,15,45   # X,Y,Z,B,C on a B/C machine";

const AFTER_HELP: &str = "\
The pose is X,Y,Z (mm) and the machine's two rotary axes in letter order (degrees):
X,Y,Z,A,C on an A/C machine, X,Y,Z,B,C on a B/C machine. With --frame joint (default) X Y Z are the
machine coordinates of the tool tip; with --frame part they are the tool tip in part
coordinates (converted with the nominal kinematics). e is actual minus nominal tool
tip in part coordinates (µm); the tool-axis error is in µrad.

--direction says how the pose was approached: each axis's last motion, + or -
(`X+,Y-,C+`). An axis with a reversal (its table's REVERSAL column or the machine
file's [reversal]) then has positioning error E + REVERSAL/2 moving +, E - REVERSAL/2
moving -; an axis not named (and every axis without --direction) has the mean E.";

#[derive(Debug, clap::Args)]
#[command(after_help = AFTER_HELP)]
#[command(group = clap::ArgGroup::new("pose_source").required(true).args(["at", "poses"]))]
pub struct Args {
    /// Machine file (TOML).
    pub machine: PathBuf,
    /// One pose: X,Y,Z and the two rotary axes in letter order (mm, degrees).
    #[arg(long, value_name = "X,Y,Z,A,C", allow_hyphen_values = true)]
    pub at: Option<String>,
    /// Many poses: a CSV file with the header `x,y,z` and the machine's rotary
    /// letters (`x,y,z,a,c`; `x,y,z,b,c` on a B/C machine), in any order.
    #[arg(long, value_name = "FILE.csv")]
    pub poses: Option<PathBuf>,
    /// Frame of X Y Z.
    #[arg(long, value_enum, default_value = "joint")]
    pub frame: FrameArg,
    /// Print JSON (`{"e_um": [..], "axis_urad": [..]}`, a list of them with --poses).
    #[arg(long)]
    pub json: bool,
    /// How the pose was approached: the direction of each axis's last motion,
    /// e.g. `X+,Y-` (axes not named: unknown, the mean error). Adds ±REVERSAL/2
    /// on the axes with a reversal.
    #[arg(
        long,
        value_name = "X+,Y-,…",
        alias = "approach",
        allow_hyphen_values = true
    )]
    pub direction: Option<String>,
    /// Also print each parameter's contribution to e, largest first (single pose).
    #[arg(long, short)]
    pub verbose: bool,
    /// The tool in the spindle: its length (gauge point to tip) is the lever
    /// of every angular error. From `--tools` or the machine file's [[tools]];
    /// default: the machine file's [tool].
    #[arg(long, value_name = "N")]
    pub tool: Option<u32>,
    /// LinuxCNC tool table for `--tool` (replaces the machine file's [[tools]]).
    #[arg(long, value_name = "FILE.tbl", requires = "tool")]
    pub tools: Option<PathBuf>,
    #[command(flatten)]
    pub model: ModelArgs,
}

/// The machine's five joint letters: X Y Z and its rotaries in letter order.
fn joint_letters(kin: &crate::kinematics::Kinematics) -> [crate::axes::Axis; 5] {
    use crate::axes::Axis;
    let [r1, r2] = kin.rotary();
    [Axis::X, Axis::Y, Axis::Z, r1, r2]
}

/// Parse `--direction X+,Y-`: every letter one of the machine's joints (X Y Z
/// and its rotary axes); an error names the column.
pub(crate) fn parse_direction(
    text: &str,
    kin: &crate::kinematics::Kinematics,
) -> anyhow::Result<crate::machine::Approach> {
    let approach = crate::machine::Approach::parse(text)
        .map_err(|e| crate::cli::UsageError(format!("--direction \"{text}\": {e}")))?;
    let letters = joint_letters(kin);
    for (column, c) in text.chars().enumerate() {
        if let Some(axis) = crate::axes::Axis::from_letter(c)
            && !letters.contains(&axis)
        {
            return Err(crate::cli::UsageError(format!(
                "--direction \"{text}\": column {}: the machine has no joint {} (its joints: {})",
                column + 1,
                axis.letter(),
                letters.map(|a| a.letter().to_string()).join(" ")
            ))
            .into());
        }
    }
    Ok(approach)
}

/// Parse `X,Y,Z,R1,R2` (the machine's rotary letters in letter order).
pub(crate) fn parse_pose(text: &str, kin: &crate::kinematics::Kinematics) -> anyhow::Result<Axes> {
    let letters = joint_letters(kin);
    let names = letters.map(|a| a.letter().to_string());
    let fields: Vec<&str> = text.split(',').map(str::trim).collect();
    if fields.len() != 5 {
        return Err(crate::cli::UsageError(format!(
            "--at expects five comma-separated numbers {}, got \"{text}\"",
            names.join(",")
        ))
        .into());
    }
    let mut v = [0.0; 5];
    for (slot, (field, name)) in v.iter_mut().zip(fields.iter().zip(&names)) {
        *slot = field
            .parse::<f64>()
            .ok()
            .filter(|x| x.is_finite())
            .ok_or_else(|| {
                crate::cli::UsageError(format!("--at: {name} = \"{field}\" is not a finite number"))
            })?;
    }
    Ok(kin.with_joints(&Axes::default(), v))
}

/// Read a pose CSV (`x,y,z` and the machine's rotary letters, any column order, `#`
/// comments). Returns the poses with their 1-based line numbers.
pub(crate) fn read_poses(
    path: &Path,
    kin: &crate::kinematics::Kinematics,
) -> anyhow::Result<Vec<(usize, Axes)>> {
    let letters = joint_letters(kin);
    let wanted = letters.map(|a| a.lower().to_string());
    let expected = wanted.join(",");
    let text = crate::io::read_to_string(path)?;
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
    let (header_line, header) = lines.next().ok_or_else(|| {
        anyhow!(
            "{}: empty file (expected the header {expected})",
            path.display()
        )
    })?;
    let names: Vec<String> = header
        .split(',')
        .map(|s| s.trim().to_ascii_lowercase())
        .collect();
    let mut index = [usize::MAX; 5];
    for (slot, want) in index.iter_mut().zip(&wanted) {
        *slot = names.iter().position(|n| n == want).ok_or_else(|| {
            anyhow!(
                "{}:{header_line}: header lacks column `{want}` (expected {expected}, got \"{header}\")",
                path.display()
            )
        })?;
    }
    if let Some(extra) = names.iter().find(|n| {
        !wanted.contains(n)
            && n.len() == 1
            && n.chars()
                .next()
                .and_then(crate::axes::Axis::from_letter)
                .is_some()
    }) {
        return Err(anyhow!(
            "{}:{header_line}: column `{extra}` is an axis this machine lacks (its joints: {expected})",
            path.display()
        ));
    }
    let mut out = Vec::new();
    for (line, row) in lines {
        let fields: Vec<&str> = row.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(anyhow!(
                "{}:{line}: expected {} fields, got {}",
                path.display(),
                names.len(),
                fields.len()
            ));
        }
        let mut v = [0.0; 5];
        for (k, (slot, col)) in v.iter_mut().zip(index).enumerate() {
            *slot = fields[col]
                .parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| {
                    anyhow!(
                        "{}:{line}: field {} (`{}`) = \"{}\" is not a finite number",
                        path.display(),
                        col + 1,
                        wanted[k],
                        fields[col]
                    )
                })?;
        }
        out.push((line, kin.with_joints(&Axes::default(), v)));
    }
    Ok(out)
}

/// The JSON object of one pose (formats.md).
#[derive(Serialize)]
struct PoseJson<'a> {
    e_um: [f64; 3],
    axis_urad: [f64; 3],
    /// Standard uncertainty of e per axis from the model's own noise (extension).
    #[serde(skip_serializing_if = "Option::is_none")]
    u_um: Option<[f64; 3]>,
    #[serde(skip_serializing_if = "Option::is_none")]
    contributions: Option<&'a [crate::machine::Contribution]>,
    /// The approach the error is for, as `--direction` takes it (`X+,Y-`),
    /// when `--direction` was given (extension).
    #[serde(skip_serializing_if = "Option::is_none")]
    approach: Option<String>,
}

fn fmt3(v: [f64; 3], decimals: usize) -> String {
    format!(
        "({:>10.*}, {:>10.*}, {:>10.*})",
        decimals, v[0], decimals, v[1], decimals, v[2]
    )
}

/// An `error` run, validated: the machine, the model for the tool in the
/// spindle, and the approach direction of each axis.
struct Job<'a> {
    args: &'a Args,
    machine: Machine,
    tool: ToolInUse,
    model: ErrorModel,
    approach: Approach,
}

pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.poses.is_some() && args.verbose {
        return Err(
            crate::cli::UsageError("--verbose applies to a single pose (--at)".into()).into(),
        );
    }
    let (machine, model) = load_model(&args.machine, &args.model)?;
    let single = args
        .at
        .as_deref()
        .map(|t| parse_pose(t, model.kinematics()))
        .transpose()?;
    let many = args
        .poses
        .as_deref()
        .map(|p| read_poses(p, model.kinematics()))
        .transpose()?;
    let approach = match args.direction.as_deref() {
        Some(text) => parse_direction(text, model.kinematics())?,
        None => Approach::NONE,
    };
    let tool = super::common::select_tool(&machine, args.tool, args.tools.as_deref())?;
    let model = model.with_tool_length(tool.length_mm);
    let job = Job {
        args,
        machine,
        tool,
        model,
        approach,
    };
    if let Some(pose) = single {
        job.print_pose(&pose)?;
    } else if let (Some(path), Some(poses)) = (&args.poses, many) {
        job.print_poses(path, &poses)?;
    }
    let held = job.model.held_lookups();
    if held > 0 {
        let warnings = crate::warnings::Warnings::new();
        super::common::add_held_lookups(&warnings, held);
        super::common::print_warnings(&warnings.groups());
    }
    Ok(())
}

impl Job<'_> {
    /// The joints of a pose given in the `--frame`.
    fn joints(&self, pose: &Axes) -> Joints {
        joints_of(
            self.model.kinematics(),
            &Pose::in_frame(self.args.frame.into(), *pose),
        )
    }

    /// The approach for the JSON output: `X+,Y-` when `--direction` was given.
    fn approach_json(&self) -> Option<String> {
        self.args
            .direction
            .is_some()
            .then(|| self.approach.describe().replace(' ', ","))
    }

    /// The standard uncertainty of e per axis, where the model carries one.
    fn uncertainty(&self, joints: &Joints) -> anyhow::Result<Option<[f64; 3]>> {
        Ok(if self.model.has_uncertainty() {
            Some(self.model.uncertainty_at(joints)?.per_axis_um())
        } else {
            None
        })
    }

    /// `--at`: the error at one pose, as JSON or as text.
    fn print_pose(&self, pose: &Axes) -> anyhow::Result<()> {
        let (model, approach) = (&self.model, &self.approach);
        let joints = self.joints(pose);
        let v = model.volumetric_error_toward(&joints, approach)?;
        let u = self.uncertainty(&joints)?;
        let contributions = if self.args.verbose {
            Some(model.contributions_toward(&joints, approach)?)
        } else {
            None
        };
        if self.args.json {
            let obj = PoseJson {
                e_um: v.e_um,
                axis_urad: v.axis_urad,
                u_um: u,
                contributions: contributions.as_deref(),
                approach: self.approach_json(),
            };
            crate::cli::outln!("{}", serde_json::to_string_pretty(&obj)?);
            return Ok(());
        }
        self.print_where(&joints)?;
        let tip = model.kinematics().nominal_tip(&joints);
        crate::cli::outln!("tip (part) {} mm", fmt3(tip, 4));
        crate::cli::outln!(
            "e         {} µm   |e| = {:.4} µm",
            fmt3(v.e_um, 4),
            v.magnitude_um()
        );
        match u {
            Some(u) => crate::cli::outln!(
                "u(e)      {} µm   (1 sigma: table noise and fit; unmodelled effects not included)",
                fmt3(u, 4)
            ),
            None => crate::cli::outln!(
                "u(e)      unknown (the model file carries no uncertainties; refit)"
            ),
        }
        crate::cli::outln!("tool axis {} µrad", fmt3(v.axis_urad, 4));
        if let Some(list) = &contributions {
            print_contributions(list)?;
        }
        Ok(())
    }

    /// The machine, the tool, the joints and (where it matters) the approach
    /// with each axis's reversal.
    fn print_where(&self, joints: &Axes) -> anyhow::Result<()> {
        let (machine, model, approach) = (&self.machine, &self.model, &self.approach);
        let kin = model.kinematics();
        crate::cli::outln!("machine {} ({})", machine.name, machine.source.display());
        crate::cli::outln!("tool    {}", self.tool);
        let j = kin.joints(joints);
        let [r1, r2] = kin.rotary();
        crate::cli::outln!(
            "joints  X {:.4} Y {:.4} Z {:.4} mm  {} {:.4} {} {:.4} deg",
            j[0],
            j[1],
            j[2],
            r1.letter(),
            j[3],
            r2.letter(),
            j[4]
        );
        if self.args.direction.is_none() && !model.has_reversal() {
            return Ok(());
        }
        let reversal: Vec<String> = model
            .reversal_axes()
            .iter()
            .map(|(axis, source)| {
                format!(
                    "{} {:.4} {} ({source})",
                    axis.letter(),
                    model.reversal_at(*axis, joints.get(*axis)).unwrap_or(0.0),
                    if axis.is_rotary() { "µrad" } else { "µm" }
                )
            })
            .collect();
        crate::cli::outln!(
            "approach  {}   reversal: {}",
            if approach.is_none() {
                "unknown (mean error)".to_string()
            } else {
                approach.describe()
            },
            if reversal.is_empty() {
                "none on this machine".to_string()
            } else {
                reversal.join(", ")
            }
        );
        Ok(())
    }

    /// `--poses`: the error at every pose of the file (in parallel), as JSON
    /// or as a table with the largest and the RMS |e|.
    fn print_poses(&self, path: &Path, poses: &[(usize, Axes)]) -> anyhow::Result<()> {
        let results: Vec<(VolumetricError, Option<[f64; 3]>)> = poses
            .par_iter()
            .map(|(line, pose)| {
                let joints = self.joints(pose);
                let at = || format!("{}:{line}", path.display());
                let v = self
                    .model
                    .volumetric_error_toward(&joints, &self.approach)
                    .with_context(at)?;
                Ok((v, self.uncertainty(&joints).with_context(at)?))
            })
            .collect::<anyhow::Result<_>>()?;
        if self.args.json {
            let list: Vec<PoseJson> = results
                .iter()
                .map(|(v, u)| PoseJson {
                    e_um: v.e_um,
                    axis_urad: v.axis_urad,
                    u_um: *u,
                    contributions: None,
                    approach: self.approach_json(),
                })
                .collect();
            crate::cli::outln!("{}", serde_json::to_string(&list)?);
            return Ok(());
        }
        crate::cli::outln!(
            "machine {} ({}), {} from {}",
            self.machine.name,
            self.machine.source.display(),
            super::common::count(results.len() as u64, "pose", "poses"),
            path.display()
        );
        crate::cli::outln!(
            "{:>6}  {:>34}  {:>9}  {:>9}",
            "line",
            "e (µm)",
            "|e| µm",
            "u(e) µm"
        );
        for ((line, _), (v, u)) in poses.iter().zip(&results) {
            let u = u.map_or("unknown".to_string(), |u| {
                format!("{:.4}", (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt())
            });
            crate::cli::outln!(
                "{line:>6}  {}  {:>9.4}  {u:>9}",
                fmt3(v.e_um, 4),
                v.magnitude_um()
            );
        }
        let mags: Vec<f64> = results.iter().map(|(v, _)| v.magnitude_um()).collect();
        let max = mags.iter().copied().fold(0.0, f64::max);
        let rms = if mags.is_empty() {
            0.0
        } else {
            (mags.iter().map(|m| m * m).sum::<f64>() / mags.len() as f64).sqrt()
        };
        crate::cli::outln!("max |e| = {max:.4} µm, RMS |e| = {rms:.4} µm");
        Ok(())
    }
}

/// `--verbose`: each parameter's contribution alone, largest |e| first.
fn print_contributions(list: &[crate::machine::Contribution]) -> anyhow::Result<()> {
    crate::cli::outln!("contributions (each parameter alone, largest |e| first):");
    crate::cli::outln!(
        "  {:<6} {:>12}  {:>34}  {:>9}",
        "param",
        "value",
        "e (µm)",
        "|e| µm"
    );
    for c in list {
        let unit = if is_length(c.parameter) {
            "µm"
        } else {
            "µrad"
        };
        crate::cli::outln!(
            "  {:<6} {:>8.4} {:<4} {}  {:>9.4}",
            c.parameter,
            c.value,
            unit,
            fmt3(c.e_um, 4),
            c.magnitude_um()
        );
    }
    Ok(())
}

/// Whether a parameter is a length (µm) rather than an angle (µrad).
fn is_length(name: &str) -> bool {
    matches!(
        name.as_bytes(),
        [b'E', b'X' | b'Y' | b'Z', _] | [b'E', b'X' | b'Y' | b'Z', b'0', _]
    )
}
