//! LinuxCNC's own compensation (formats.md "Laser positioning runs and
//! reversal"): a `COMP_FILE` per linear joint and the trt kinematics module's
//! pivot parameters.
//!
//! LinuxCNC's loader (`usrmotLoadComp`) reads `nominal forward reverse` with
//! `sscanf("%lf %lf %lf")` and stops at the first line that is not three
//! numbers, so the triplets come first and the provenance after them. Motion
//! (`compute_screw_comp`) adds to the commanded joint position the forward trim
//! while the joint moves up and the reverse trim while it moves down (keeping the
//! last one when it stops), linear between the listed nominals and held beyond
//! the ends; type 0 lists actual positions (trim = nominal − actual), type 1 the
//! trims. At most 256 triplets a joint.
//!
//! The nominals: the table's positions, refined by bisection where linear
//! interpolation departs from the fitted curves by more than the tolerance,
//! until it is met or 256 lines are used (said in the result).
use std::fmt::Write as _;

use super::{ExportError, Positioning};
use crate::axes::Axis;
use crate::machine::{KinematicsType, Machine};

/// LinuxCNC's limit of triplets per joint (`EMCMOT_COMP_SIZE`).
pub const MAX_COMP_LINES: usize = 256;

/// `COMP_FILE_TYPE`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CompType {
    /// 0: nominal, actual moving up, actual moving down.
    Actual,
    /// 1: nominal, trim moving up, trim moving down (trim = nominal − actual).
    Trim,
}

impl CompType {
    pub fn number(self) -> u8 {
        match self {
            CompType::Actual => 0,
            CompType::Trim => 1,
        }
    }
}

/// How the comp files are made.
#[derive(Clone, Copy, Debug)]
pub struct CompSettings {
    pub comp_type: CompType,
    /// Largest departure (µm) of LinuxCNC's linear interpolation from the fitted curves.
    pub tolerance_um: f64,
    /// Most triplets a file may have (≤ [`MAX_COMP_LINES`]).
    pub max_lines: usize,
}

impl Default for CompSettings {
    fn default() -> Self {
        CompSettings {
            comp_type: CompType::Actual,
            tolerance_um: 0.1,
            max_lines: MAX_COMP_LINES,
        }
    }
}

/// One joint's `COMP_FILE`.
#[derive(Clone, Debug)]
pub struct CompFile {
    pub axis: Axis,
    /// LinuxCNC's joint number (the machine's letters in X Y Z A B C U V W order).
    pub joint: usize,
    pub parameter: String,
    pub reversal: bool,
    /// The triplets' nominals (mm).
    pub nominals: Vec<f64>,
    /// The largest departure (µm) of the file read back as LinuxCNC interpolates it
    /// from the fitted forward and reverse curves, over the table's range.
    pub max_error_um: f64,
    /// Whether `max_error_um` is within the tolerance.
    pub met: bool,
    /// The smallest and largest standard uncertainty (µm) of the fitted curve
    /// at the nominals, when the model carries one.
    pub uncertainty_um: Option<(f64, f64)>,
    /// The file.
    pub text: String,
}

/// What was exported and what was not, and why.
#[derive(Clone, Debug)]
pub struct LinuxCncExport {
    pub comp_files: Vec<CompFile>,
    /// How the comp files list their values.
    pub comp_type: CompType,
    /// Axes with a table that get no comp file, and why.
    pub skipped: Vec<(Axis, String)>,
    /// `kinematics.ini`, when the machine is a trt type.
    pub kinematics_ini: Option<String>,
    /// Why there is no `kinematics.ini`.
    pub kinematics_note: Option<String>,
    pub readme: String,
}

/// The most a linear interpolation between `a` and `b` departs from the
/// forward and reverse curves (µm), at `samples` interior points.
fn interval_error(pos: &Positioning<'_>, a: f64, b: f64, samples: usize) -> f64 {
    let (fa, fb, ra, rb) = (
        pos.forward(a),
        pos.forward(b),
        pos.reverse(a),
        pos.reverse(b),
    );
    let mut worst: f64 = 0.0;
    for k in 1..=samples {
        let t = k as f64 / (samples + 1) as f64;
        let p = a + t * (b - a);
        worst = worst
            .max((fa + t * (fb - fa) - pos.forward(p)).abs())
            .max((ra + t * (rb - ra) - pos.reverse(p)).abs());
    }
    worst
}

/// The nominals of a comp file: the table's positions, bisected where needed.
fn nominals(pos: &Positioning<'_>, settings: &CompSettings) -> Vec<f64> {
    let [lo, hi] = pos.range;
    let max = settings.max_lines.clamp(2, MAX_COMP_LINES);
    let mut nodes: Vec<f64> = if pos.positions().len() <= max {
        pos.positions().to_vec()
    } else {
        (0..max)
            .map(|k| lo + (hi - lo) * k as f64 / (max - 1) as f64)
            .collect()
    };
    let mut errors: Vec<f64> = nodes
        .windows(2)
        .map(|w| interval_error(pos, w[0], w[1], 8))
        .collect();
    while nodes.len() < max {
        let Some((k, &worst)) = errors.iter().enumerate().max_by(|a, b| a.1.total_cmp(b.1)) else {
            break;
        };
        if worst <= settings.tolerance_um {
            break;
        }
        let mid = 0.5 * (nodes[k] + nodes[k + 1]);
        nodes.insert(k + 1, mid);
        let left = interval_error(pos, nodes[k], mid, 8);
        let right = interval_error(pos, mid, nodes[k + 2], 8);
        errors[k] = left;
        errors.insert(k + 1, right);
    }
    nodes
}

/// A number as written in the file: shortest form of a value rounded to 1e-9.
pub(crate) fn number(v: f64) -> String {
    let s = format!("{:.9}", v + 0.0);
    let s = s.trim_end_matches('0').trim_end_matches('.');
    if s == "-0" { "0".into() } else { s.to_string() }
}

/// The comp file of one linear axis.
pub fn comp_file(
    pos: &Positioning<'_>,
    joint: usize,
    machine: &Machine,
    settings: &CompSettings,
) -> CompFile {
    let nodes = nominals(pos, settings);
    let mut text = String::new();
    let mm = |um: f64| um * 1e-3;
    for &p in &nodes {
        let (f, r) = (mm(pos.forward(p)), mm(pos.reverse(p)));
        let (a, b) = match settings.comp_type {
            CompType::Actual => (p + f, p + r),
            CompType::Trim => (-f, -r),
        };
        let _ = writeln!(text, "{} {} {}", number(p), number(a), number(b));
    }
    // Read back exactly as LinuxCNC will (the written, rounded numbers).
    let back = read_back(&text, settings.comp_type);
    let mut max_error_um: f64 = 0.0;
    for w in nodes.windows(2) {
        for k in 0..=40 {
            let p = w[0] + (w[1] - w[0]) * k as f64 / 40.0;
            let (tf, tr) = back.trims(p);
            max_error_um = max_error_um
                .max((tf * 1e3 + pos.forward(p)).abs())
                .max((tr * 1e3 + pos.reverse(p)).abs());
        }
    }
    let reversal = pos.has_reversal();
    let _ = writeln!(
        text,
        "\n# volcomp export linuxcnc: machine {}, axis {} (joint {joint}), COMP_FILE_TYPE = {}.",
        machine.name,
        pos.axis.letter(),
        settings.comp_type.number()
    );
    let _ = writeln!(
        text,
        "# LinuxCNC reads the triplets above and stops at the first other line (this one)."
    );
    let _ = writeln!(
        text,
        "# {} lines: nominal mm, then {} moving up (+) and moving down (-), mm;",
        nodes.len(),
        match settings.comp_type {
            CompType::Actual => "the actual position",
            CompType::Trim => "the trim LinuxCNC adds (nominal - actual)",
        }
    );
    let _ = if reversal {
        writeln!(
            text,
            "# actual = nominal + ({p} ± REVERSAL/2)/1000: {p} the fitted curve of the table's {n} positions, REVERSAL {}.",
            if pos.reversal_source() == Some("[reversal]") {
                "the machine file's [reversal] constant"
            } else {
                "linear between them"
            },
            p = pos.parameter,
            n = pos.positions().len()
        )
    } else {
        writeln!(
            text,
            "# actual = nominal + {p}/1000, both directions alike (the table has no REVERSAL): {p} the fitted curve of its {n} positions.",
            p = pos.parameter,
            n = pos.positions().len()
        )
    };
    let _ = writeln!(
        text,
        "# Read back as LinuxCNC interpolates it, within {:.4} µm of those curves (tolerance {} µm).",
        max_error_um, settings.tolerance_um
    );
    let uncertainty = pos.uncertainty_range(&nodes);
    if let Some((lo_u, hi_u)) = uncertainty {
        let _ = writeln!(
            text,
            "# Standard uncertainty of {p} (the fitted curve's, from the table{}): {lo_u:.4} to {hi_u:.4} µm; per nominal (mm µm):",
            if pos.table_has_uncertainty() {
                "'s u_ column"
            } else {
                "'s noise"
            },
            p = pos.parameter
        );
        for &p in &nodes {
            let _ = writeln!(
                text,
                "# u {} {:.4}",
                number(p),
                pos.uncertainty(p).unwrap_or(0.0) + 0.0
            );
        }
    }
    CompFile {
        axis: pos.axis,
        joint,
        parameter: pos.parameter.clone(),
        reversal,
        nominals: nodes,
        met: max_error_um <= settings.tolerance_um,
        max_error_um,
        uncertainty_um: uncertainty,
        text,
    }
}

/// A comp file as LinuxCNC's loader and motion read it.
#[derive(Clone, Debug, Default)]
pub struct CompTable {
    /// (nominal, forward trim, reverse trim), mm.
    pub entries: Vec<(f64, f64, f64)>,
}

/// Read a comp file as `usrmotLoadComp` does: three numbers a line, stop at the
/// first line that is not; type 0 turns actual positions into trims.
pub fn read_back(text: &str, comp_type: CompType) -> CompTable {
    let mut entries = Vec::new();
    for line in text.lines() {
        let mut it = line.split_whitespace().map(str::parse::<f64>);
        let (Some(Ok(n)), Some(Ok(f)), Some(Ok(r))) = (it.next(), it.next(), it.next()) else {
            break;
        };
        entries.push(match comp_type {
            CompType::Actual => (n, n - f, n - r),
            CompType::Trim => (n, f, r),
        });
    }
    CompTable { entries }
}

impl CompTable {
    /// The trims (forward, reverse) at commanded position `p`, as
    /// `compute_screw_comp` interpolates them (linear, ends held).
    pub fn trims(&self, p: f64) -> (f64, f64) {
        let e = &self.entries;
        if e.is_empty() {
            return (0.0, 0.0);
        }
        if p < e[0].0 {
            return (e[0].1, e[0].2);
        }
        let k = e.partition_point(|x| x.0 <= p) - 1;
        if k + 1 >= e.len() {
            return (e[k].1, e[k].2);
        }
        let t = (p - e[k].0) / (e[k + 1].0 - e[k].0);
        (
            e[k].1 + t * (e[k + 1].1 - e[k].1),
            e[k].2 + t * (e[k + 1].2 - e[k].2),
        )
    }
}

/// The location error `name` of `machine` (µm or µrad; 0 when the machine has no such name).
pub(crate) fn location(machine: &Machine, name: &str) -> f64 {
    machine
        .layout()
        .location_names()
        .iter()
        .position(|n| *n == name)
        .map_or(0.0, |k| machine.location[k])
}

/// The trt module's pivot parameters, nominal and corrected by the location
/// offsets the module can express (`kinematics.ini`; the residual machine's
/// `[geometry]`).
#[derive(Clone, Debug)]
pub struct Pivots {
    /// `xyzac-trt-kins` or `xyzbc-trt-kins`.
    pub module: &'static str,
    /// The tilting axis (A or B).
    pub tilt: Axis,
    /// The machine file's `[geometry]` keys, in the order of the values.
    pub names: [&'static str; 5],
    /// The module's pins (`x-rot-point`, …), in the same order.
    pub pins: [&'static str; 5],
    /// The machine file's values (mm).
    pub nominal: [f64; 5],
    /// With the location offsets added (mm).
    pub corrected: [f64; 5],
    /// The location errors the correction expresses (`EX0C`, `EY0C`, `EY0A`,
    /// `EZ0A` on an A/C machine): what a controller with these pivots applies.
    pub expressed: [String; 4],
    /// The formulas, one line (for the comments).
    pub formulas: String,
}

/// The pivots of a trt machine; `None` for a chain machine.
pub fn pivots(machine: &Machine) -> Option<Pivots> {
    let (module, second, offset_name, offset_axis) = match machine.kinematics {
        KinematicsType::XyzacTrt => ("xyzac-trt-kins", Axis::A, "y-offset", 1),
        KinematicsType::XyzbcTrt => ("xyzbc-trt-kins", Axis::B, "x-offset", 0),
        KinematicsType::Chain => return None,
    };
    let c = machine.chain.axis(Axis::C).point;
    let t = machine.chain.axis(second).point;
    let l = second.letter();
    let (off_letter, off_name) = if offset_axis == 1 {
        ('Y', "y_offset")
    } else {
        ('X', "x_offset")
    };
    let nominal = [
        c[0],
        c[1],
        c[2],
        t[offset_axis] - c[offset_axis],
        t[2] - c[2],
    ];
    let um = |name: &str| location(machine, name) * 1e-3;
    let offset_own = format!("E{off_letter}0{l}");
    let offset_c = format!("E{off_letter}0C");
    let z_own = format!("EZ0{l}");
    let corrected = [
        nominal[0] + um("EX0C"),
        nominal[1] + um("EY0C"),
        nominal[2],
        nominal[3] + um(&offset_own) - um(&offset_c),
        nominal[4] + um(&z_own),
    ];
    Some(Pivots {
        module,
        tilt: second,
        names: [
            "x_rot_point",
            "y_rot_point",
            "z_rot_point",
            off_name,
            "z_offset",
        ],
        pins: [
            "x-rot-point",
            "y-rot-point",
            "z-rot-point",
            offset_name,
            "z-offset",
        ],
        nominal,
        corrected,
        expressed: [
            "EX0C".into(),
            "EY0C".into(),
            offset_own.clone(),
            z_own.clone(),
        ],
        formulas: format!(
            "x-rot-point += EX0C; y-rot-point += EY0C; {offset_name} += {offset_own} - {offset_c}; z-offset += {z_own}"
        ),
    })
}

/// `kinematics.ini` for a trt machine: the module's pivot parameters with the
/// location offsets added (µm → mm); the tilts and zero offsets it cannot express
/// listed. `None` for a chain machine.
pub fn kinematics_ini(machine: &Machine) -> Option<String> {
    let p = pivots(machine)?;
    let module = p.module;
    let l = p.tilt.letter();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# volcomp export linuxcnc: machine {} ({}), the pivot parameters of {module}",
        machine.name,
        machine.kinematics.name()
    );
    let _ = writeln!(
        s,
        "# corrected by the identified location errors of the machine file (µm -> mm):"
    );
    let _ = writeln!(s, "#   {}", p.formulas);
    let _ = writeln!(
        s,
        "#   (the C axis line moves by (EX0C, EY0C), the {l} axis line by its two offsets)."
    );
    for (k, name) in p.names.iter().enumerate() {
        let _ = writeln!(
            s,
            "#   {name}: {} -> {}",
            number(p.nominal[k]),
            number(p.corrected[k])
        );
    }
    let layout = machine.layout();
    let inexpressible: Vec<String> = layout
        .location_names()
        .iter()
        .filter(|n| {
            let b = n.as_bytes();
            // Offsets (E X/Y/Z 0 axis) are expressed above; tilts and zero offsets are not.
            !(matches!(b[1], b'X' | b'Y' | b'Z'))
        })
        .map(|n| format!("{n} = {}", location(machine, n)))
        .collect();
    let _ = writeln!(
        s,
        "# Not expressible by {module} (tilts and zero offsets, µrad; left to volcomp compensate):"
    );
    let _ = writeln!(s, "#   {}", inexpressible.join(", "));
    let _ = writeln!(
        s,
        "# Paste into the [HAL] section of the machine's INI (or set the signals these pins are netted to)."
    );
    let _ = writeln!(s, "[HAL]");
    for (k, pin) in p.pins.iter().enumerate() {
        let _ = writeln!(s, "HALCMD = setp {module}.{pin} {}", number(p.corrected[k]));
    }
    Some(s)
}

/// Everything `volcomp export linuxcnc` writes; `comp_dir` is how the README
/// names the folder in the `COMP_FILE` lines.
pub fn export(
    machine: &Machine,
    model: &crate::machine::ErrorModel,
    settings: &CompSettings,
    comp_dir: &str,
) -> Result<LinuxCncExport, ExportError> {
    if !(settings.tolerance_um.is_finite() && settings.tolerance_um > 0.0) {
        return Err(ExportError::Setting(format!(
            "the comp-file tolerance must be a positive number of µm, not {}",
            settings.tolerance_um
        )));
    }
    let letters: Vec<Axis> = machine.letters().iter().collect();
    let mut comp_files = Vec::new();
    let mut skipped = Vec::new();
    for (joint, &axis) in letters.iter().enumerate() {
        if machine.table(axis).is_none() {
            continue;
        }
        if axis.is_rotary() {
            skipped.push((
                axis,
                "rotary: LinuxCNC's comp applies to the joint value; a rotary axis's positioning error stays with volcomp compensate".into(),
            ));
            continue;
        }
        match Positioning::of(machine, model, axis) {
            Some(pos) => comp_files.push(comp_file(&pos, joint, machine, settings)),
            None => skipped.push((
                axis,
                format!(
                    "its table does not measure {}",
                    crate::laser::positioning_parameter(axis)
                ),
            )),
        }
    }
    if comp_files.is_empty() {
        return Err(ExportError::Nothing(format!(
            "{}: no linear axis has a positioning table ({}): nothing to write a COMP_FILE from",
            machine.source.display(),
            letters
                .iter()
                .filter(|a| !a.is_rotary())
                .map(|a| crate::laser::positioning_parameter(*a))
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let kinematics_ini = kinematics_ini(machine);
    let kinematics_note = kinematics_ini.is_none().then(|| {
        "a chain machine: no LinuxCNC trt module takes its parameters (kinematics.ini not written)".to_string()
    });
    let mut readme = String::new();
    let _ = writeln!(
        readme,
        "volcomp export linuxcnc: machine {} ({}), from {}",
        machine.name,
        machine.kinematics.name(),
        machine.source.display()
    );
    let _ = writeln!(readme);
    let _ = writeln!(
        readme,
        "Screw compensation: paste into the machine's INI (joints numbered in the order of the"
    );
    let _ = writeln!(
        readme,
        "coordinates {}; a joint with COMP_FILE ignores BACKLASH, so remove it there).",
        letters.iter().map(|a| a.letter()).collect::<String>()
    );
    for f in &comp_files {
        let _ = writeln!(readme);
        let _ = writeln!(readme, "[JOINT_{}]", f.joint);
        let _ = writeln!(
            readme,
            "COMP_FILE = {}/{}.comp",
            comp_dir.trim_end_matches('/'),
            f.axis.lower()
        );
        let _ = writeln!(readme, "COMP_FILE_TYPE = {}", settings.comp_type.number());
        let _ = writeln!(
            readme,
            "# {} lines from {}{}; read back as LinuxCNC interpolates it: within {:.4} µm of the fitted curves{}",
            f.nominals.len(),
            f.parameter,
            if f.reversal {
                " and REVERSAL"
            } else {
                " (no REVERSAL in the table)"
            },
            f.max_error_um,
            if f.met {
                String::new()
            } else {
                format!(
                    " (tolerance {} µm NOT met with {} lines)",
                    settings.tolerance_um,
                    f.nominals.len()
                )
            }
        );
        if let Some((lo, hi)) = f.uncertainty_um {
            let _ = writeln!(
                readme,
                "# standard uncertainty of {}: {lo:.4} to {hi:.4} µm (per nominal after the triplets)",
                f.parameter
            );
        }
    }
    for (axis, why) in &skipped {
        let _ = writeln!(readme, "\n{}: no COMP_FILE ({why}).", axis.letter());
    }
    let _ = writeln!(readme);
    match &kinematics_ini {
        Some(_) => {
            let _ = writeln!(
                readme,
                "Kinematics: kinematics.ini holds the {} pivot parameters corrected by the location errors.",
                machine.kinematics.name()
            );
        }
        None => {
            let _ = writeln!(
                readme,
                "Kinematics: {}.",
                kinematics_note.as_deref().unwrap_or("")
            );
        }
    }
    let _ = writeln!(
        readme,
        "\nWhat a COMP_FILE and these parameters cannot correct (the other component errors, squareness,\n\
tilts, the tool-axis error) stays with `volcomp compensate`; do not apply a correction twice:\n\
a program compensated by volcomp for a machine whose controller applies these files needs a\n\
machine file whose tables and location errors are what is left after them."
    );
    Ok(LinuxCncExport {
        comp_files,
        comp_type: settings.comp_type,
        skipped,
        kinematics_ini,
        kinematics_note,
        readme,
    })
}
