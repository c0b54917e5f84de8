//! The machine file (formats.md "Machine file"): TOML read with serde, unknown keys
//! rejected, every value validated, error tables read through [`ErrorTable::read`].
//!
//! Three kinds (formats.md): `xyzac-trt` (`[geometry]` with `y_offset`),
//! `xyzbc-trt` (LinuxCNC's names: `x_offset` instead of `y_offset`) and `chain`
//! (any serial five-axis machine: `workpiece_side`, `tool_side`, `tool_axis`,
//! `[axes.K]`). All three become one [`MachineChain`].
//!
//! Invariants of a loaded [`Machine`]: every number is finite; limits are
//! `min < max`; the chain is a valid five-axis machine (X Y Z once each, two
//! rotaries, heads after carriages, directions non-zero); limits, tables and
//! location errors name only the machine's own letters; every table exists, has
//! the right columns (checked by the table reader) and covers the travel of its
//! axis unless the load options hold end values (a rotary table over one
//! revolution covers any angle). Errors name the machine file with line and
//! column of the key, or (for a table) the CSV file and line.
use super::physical_ranges::{
    MAX_ERROR_URAD, MAX_LENGTH_MM, MAX_REVERSAL_UM, MAX_REVERSAL_URAD, MAX_TOOL_MM,
    check_magnitude, error_bound,
};
use super::table::{ErrorTable, TableError};
use crate::axes::{Axes, Axis, AxisSet};
use crate::kinematics::error_values::{ParameterLayout, SQUARENESS_NAMES};
use crate::kinematics::{
    BcGeometry, ChainAxis, ErrorValues, Geometry, Kinematics, MachineChain, ToolChain,
};
use serde::Deserialize;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// Rapid rate (mm/min) used when the machine file has no `[rates] rapid`.
pub const DEFAULT_RAPID_MM_PER_MIN: f64 = 10_000.0;

/// Kinematic types a machine file may name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum KinematicsType {
    /// `xyzac-trt`: tilting rotary table, A about X carrying C about Z (kinematics.md).
    XyzacTrt,
    /// `xyzbc-trt`: tilting rotary table, B about Y carrying C about Z (LinuxCNC's).
    XyzbcTrt,
    /// `chain`: any serial five-axis machine described axis by axis.
    Chain,
}

impl KinematicsType {
    /// The name a machine file writes (`kinematics = "xyzac-trt"`, …).
    pub fn name(self) -> &'static str {
        match self {
            KinematicsType::XyzacTrt => "xyzac-trt",
            KinematicsType::XyzbcTrt => "xyzbc-trt",
            KinematicsType::Chain => "chain",
        }
    }
}

/// What to do with a lookup outside a table's range.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub enum ExtrapolationPolicy {
    /// An error naming the axis, the position and the table's range (formats.md default).
    #[default]
    Error,
    /// Hold the end value (counted, so callers can report it).
    Hold,
}

/// Options of [`Machine::load_with`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// With `Hold`, tables narrower than the travel are accepted.
    pub extrapolation: ExtrapolationPolicy,
}

/// Travel limits per letter: `[min, max]`, mm or degrees; `None` is endless (a
/// rotary axis without limits) or a letter the machine lacks.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct Limits {
    ranges: [Option<[f64; 2]>; crate::axes::AXIS_COUNT],
}

impl Limits {
    /// Limits from `(letter, [min, max])` pairs.
    pub fn from_pairs(pairs: &[(Axis, [f64; 2])]) -> Limits {
        let mut out = Limits::default();
        for (axis, r) in pairs {
            out.ranges[*axis as usize] = Some(*r);
        }
        out
    }

    /// The `[min, max]` travel of `axis` (mm or degrees); `None` when endless or absent.
    pub fn get(&self, axis: Axis) -> Option<[f64; 2]> {
        self.ranges[axis as usize]
    }

    /// Sets the travel of `axis` (`None`: endless or absent).
    pub fn set(&mut self, axis: Axis, range: Option<[f64; 2]>) {
        self.ranges[axis as usize] = range;
    }

    /// The travel of linear `axis`, `[0, 0]` when it has none (callers pass the
    /// machine's linear letters, which always have limits).
    pub fn linear(&self, axis: Axis) -> [f64; 2] {
        self.get(axis).unwrap_or([0.0; 2])
    }

    /// The first axis whose limit `joints` exceeds (by more than 1e-9).
    pub fn violated(&self, joints: &Axes) -> Option<(Axis, f64, [f64; 2])> {
        Axis::ALL.into_iter().find_map(|axis| {
            let [lo, hi] = self.get(axis)?;
            let v = joints.get(axis);
            (v < lo - 1e-9 || v > hi + 1e-9).then_some((axis, v, [lo, hi]))
        })
    }
}

/// The tool: length (gauge point to tip) and radius, mm, and its cutting shape
/// when the file names one (`shape`, docs/extensions.md).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Tool {
    /// Gauge point to tip, mm.
    pub length: f64,
    /// Radius, mm.
    pub radius: f64,
    /// The cutting shape (`None`: deviations taken at the tool tip).
    pub shape: Option<crate::gcode::CutterShape>,
}

/// The cutting shape a `[tool]` or `[[tools]]` entry names: `shape` ("ball",
/// "flat" or "bull"), `corner_radius` (bull nose: required, between 0 and the
/// radius; ball and flat: implied) and `flute_length` (required with a shape,
/// at least the corner radius). Without `shape` the others must be absent: the
/// deviations are then taken at the tool tip, as formats.md says.
fn cutter_shape(
    shape: Option<&str>,
    radius: f64,
    corner_radius: Option<f64>,
    flute_length: Option<f64>,
) -> Result<Option<crate::gcode::CutterShape>, String> {
    let Some(shape) = shape else {
        if corner_radius.is_some() || flute_length.is_some() {
            return Err("corner_radius and flute_length describe a `shape` (\"ball\", \"flat\" or \"bull\"); name it".into());
        }
        return Ok(None);
    };
    let corner = match (shape, corner_radius) {
        ("ball", None) => radius,
        ("ball", Some(r)) if r == radius => radius,
        ("ball", Some(_)) => {
            return Err("a ball end's corner radius is its radius: leave corner_radius out".into());
        }
        ("flat", None | Some(0.0)) => 0.0,
        ("flat", Some(_)) => {
            return Err(
                "a flat end has no corner radius: leave corner_radius out, or use shape = \"bull\""
                    .into(),
            );
        }
        ("bull", Some(r)) if r.is_finite() && r > 0.0 && r < radius => r,
        ("bull", Some(r)) => {
            return Err(format!(
                "a bull nose's corner_radius must lie between 0 and the radius {radius} mm (exclusive), not {r}"
            ));
        }
        ("bull", None) => return Err("a bull nose needs its corner_radius (mm)".into()),
        (other, _) => {
            return Err(format!(
                "shape `{other}`: expected \"ball\", \"flat\" or \"bull\""
            ));
        }
    };
    let Some(flute) = flute_length else {
        return Err(format!(
            "a `{shape}` tool needs its flute_length (mm of cutting side above the tip)"
        ));
    };
    if !flute.is_finite() || flute < corner {
        return Err(format!(
            "flute_length must be a number of mm at least the corner radius {corner}, not {flute}"
        ));
    }
    Ok(Some(crate::gcode::CutterShape {
        corner_radius_mm: corner,
        flute_length_mm: flute,
    }))
}

/// A validated machine file.
#[derive(Clone, Debug)]
pub struct Machine {
    /// The machine's `name`.
    pub name: String,
    /// Its kinematic type.
    pub kinematics: KinematicsType,
    /// The nominal chain (presets built from their `[geometry]`).
    pub chain: MachineChain,
    /// The `[tool]` used when a program names none.
    pub tool: Tool,
    /// `[[tools]]`: the machine's tool table (empty when the file has none).
    pub tools: crate::gcode::ToolTable,
    /// Travel limits per letter (joint coordinates).
    pub limits: Limits,
    /// G0 rate, mm/min ([`DEFAULT_RAPID_MM_PER_MIN`] when the file has none).
    pub rapid_mm_per_min: f64,
    /// Whether `rapid_mm_per_min` is the default rather than the file's value.
    pub rapid_is_default: bool,
    /// Measured tables per joint slot (X Y Z and the two rotaries in letter order,
    /// `MachineChain::slot`); `None` = not measured.
    pub tables: [Option<ErrorTable>; 5],
    /// `s_xy, s_xz, s_yz`, µrad.
    pub squareness: [f64; 3],
    /// Rotary location errors in `ParameterLayout::location_names` order (µm, µrad).
    pub location: [f64; 10],
    /// `[reversal]`: a constant reversal per joint slot (µm linear, µrad rotary;
    /// docs/extensions.md); `None` = none given (a table's `REVERSAL` may give one).
    pub reversal: [Option<f64>; 5],
    /// The machine file this was read from.
    pub source: PathBuf,
    /// Its text as it was read (what `--write-machine` edits: the file may
    /// change after it was read).
    pub text: std::sync::Arc<str>,
}

/// Why a machine file could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum MachineError {
    /// The file could not be read.
    #[error(transparent)]
    Read(#[from] crate::io::InputError),
    /// Syntax, type, missing or unknown key (what serde and toml report).
    #[error("{}:{line}:{column}: {message}", path.display())]
    Parse {
        /// The machine file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// What is wrong.
        message: String,
    },
    /// A value that parses but is not acceptable.
    #[error("{}:{line}:{column}: `{key}`: {message}", path.display())]
    Invalid {
        /// The machine file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The key whose value is refused.
        key: String,
        /// Why it is refused.
        message: String,
    },
    /// An error table named by the machine file could not be read.
    #[error("{}:{line}:{column}: `{key}`: {source}", path.display())]
    Table {
        /// The machine file.
        path: PathBuf,
        /// 1-based line of the key naming the table.
        line: usize,
        /// 1-based column.
        column: usize,
        /// The key naming the table.
        key: String,
        /// Why the table could not be read.
        source: Box<TableError>,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMachine {
    name: String,
    kinematics: Spanned<String>,
    tool_chain: Option<Spanned<Vec<String>>>,
    conventional_directions: Option<Spanned<bool>>,
    geometry: Option<Spanned<RawGeometry>>,
    workpiece_side: Option<Spanned<Vec<String>>>,
    tool_side: Option<Spanned<Vec<String>>>,
    tool_axis: Option<Spanned<[f64; 3]>>,
    axes: Option<Spanned<BTreeMap<String, Spanned<RawAxis>>>>,
    tool: RawTool,
    #[serde(default)]
    tools: Vec<Spanned<RawToolEntry>>,
    limits: Spanned<BTreeMap<String, Spanned<[f64; 2]>>>,
    rates: Option<RawRates>,
    errors: Option<Spanned<BTreeMap<String, Spanned<String>>>>,
    squareness: Option<Spanned<RawSquareness>>,
    location: Option<Spanned<BTreeMap<String, Spanned<f64>>>>,
    reversal: Option<Spanned<BTreeMap<String, Spanned<f64>>>>,
}

/// `[geometry]` of the two presets (which keys each takes is checked in
/// [`preset_chain`]).
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawGeometry {
    x_rot_point: Option<Spanned<f64>>,
    y_rot_point: Option<Spanned<f64>>,
    z_rot_point: Option<Spanned<f64>>,
    x_offset: Option<Spanned<f64>>,
    y_offset: Option<Spanned<f64>>,
    z_offset: Option<Spanned<f64>>,
}

/// `[axes.K]` of a chain machine.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawAxis {
    direction: Option<Spanned<Vec<f64>>>,
    point: Option<Spanned<Vec<f64>>>,
}

/// A `direction` or `point` array: exactly three finite numbers.
fn three(src: &Source<'_>, key: &str, v: &Spanned<Vec<f64>>) -> Result<[f64; 3], MachineError> {
    match v.get_ref().as_slice() {
        &[x, y, z] => {
            src.finite(v.span(), key, &[x, y, z])?;
            Ok([x, y, z])
        }
        other => Err(src.invalid(
            v.span(),
            key,
            format!("expected 3 numbers [x, y, z], got {}", other.len()),
        )),
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTool {
    length: Spanned<f64>,
    radius: Spanned<f64>,
    shape: Option<Spanned<String>>,
    corner_radius: Option<f64>,
    flute_length: Option<f64>,
}

/// A `[[tools]]` entry (extensions.md): a tool table for controllers other
/// than LinuxCNC.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawToolEntry {
    number: u32,
    length: f64,
    radius: f64,
    pocket: Option<u32>,
    name: Option<String>,
    shape: Option<String>,
    corner_radius: Option<f64>,
    flute_length: Option<f64>,
    #[serde(default)]
    comment: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRates {
    rapid: Option<Spanned<f64>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct RawSquareness {
    s_xy: f64,
    s_xz: f64,
    s_yz: f64,
}

/// 1-based line and column of byte `offset` in `text`.
fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let offset = offset.min(text.len());
    let before = text.get(..offset).unwrap_or(text);
    let line = before.matches('\n').count() + 1;
    let column = before
        .rfind('\n')
        .map_or(before.chars().count(), |i| before[i + 1..].chars().count())
        + 1;
    (line, column)
}

/// Builds errors that point into one machine file.
struct Source<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Source<'_> {
    fn invalid(&self, span: Range<usize>, key: &str, message: impl Into<String>) -> MachineError {
        let (line, column) = line_column(self.text, span.start);
        MachineError::Invalid {
            path: self.path.to_path_buf(),
            line,
            column,
            key: key.to_string(),
            message: message.into(),
        }
    }

    fn finite(&self, span: Range<usize>, key: &str, values: &[f64]) -> Result<(), MachineError> {
        if values.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(self.invalid(span, key, "must be a finite number"))
        }
    }

    /// A value within `±max` (a physical range, [`physical_ranges`]).
    fn within(
        &self,
        span: Range<usize>,
        key: &str,
        unit: &str,
        value: f64,
        max: f64,
    ) -> Result<f64, MachineError> {
        self.finite(span.clone(), key, &[value])?;
        check_magnitude(key, unit, value, max).map_err(|m| {
            // The key is named before the message already.
            let m = m.strip_prefix(&format!("{key} = ")).unwrap_or(&m);
            self.invalid(span, key, m)
        })
    }

    fn range(&self, key: &str, value: &Spanned<[f64; 2]>) -> Result<[f64; 2], MachineError> {
        let v = *value.get_ref();
        self.finite(value.span(), key, &v)?;
        for x in v {
            self.within(value.span(), key, "mm or °", x, MAX_LENGTH_MM)?;
        }
        if v[0] >= v[1] {
            return Err(self.invalid(
                value.span(),
                key,
                format!(
                    "expected [min, max] with min < max, got [{}, {}]",
                    v[0], v[1]
                ),
            ));
        }
        Ok(v)
    }

    /// The axis letter of a key (`"b"`, `"B"`), or a located error.
    fn letter(&self, span: Range<usize>, key: &str, name: &str) -> Result<Axis, MachineError> {
        let mut chars = name.chars();
        match (chars.next().and_then(Axis::from_letter), chars.next()) {
            (Some(axis), None) => Ok(axis),
            _ => Err(self.invalid(
                span,
                key,
                format!("`{name}` is not an axis letter (expected one of X Y Z A B C U V W)"),
            )),
        }
    }

    /// Axis letters of a side list, each once.
    fn side(
        &self,
        key: &str,
        list: &Spanned<Vec<String>>,
        seen: &mut AxisSet,
    ) -> Result<Vec<Axis>, MachineError> {
        let mut out = Vec::new();
        for name in list.get_ref() {
            let axis = self.letter(list.span(), key, name)?;
            if seen.contains(axis) {
                return Err(self.invalid(
                    list.span(),
                    key,
                    format!(
                        "axis {} appears twice (each letter once, on one side)",
                        axis.letter()
                    ),
                ));
            }
            *seen = seen.with(axis);
            out.push(axis);
        }
        Ok(out)
    }
}

/// The natural direction of a letter (ISO 841): X/A/U along X, Y/B/V along Y, Z/C/W
/// along Z.
fn natural_direction(axis: Axis) -> [f64; 3] {
    match axis {
        Axis::X | Axis::A | Axis::U => [1.0, 0.0, 0.0],
        Axis::Y | Axis::B | Axis::V => [0.0, 1.0, 0.0],
        Axis::Z | Axis::C | Axis::W => [0.0, 0.0, 1.0],
    }
}

/// The chain of a `xyzac-trt` or `xyzbc-trt` file from its `[geometry]`,
/// `tool_chain` and `conventional_directions`.
fn preset_chain(
    src: &Source<'_>,
    raw: &RawMachine,
    kind: KinematicsType,
) -> Result<MachineChain, MachineError> {
    for (present, key) in [
        (
            raw.workpiece_side.as_ref().map(|s| s.span()),
            "workpiece_side",
        ),
        (raw.tool_side.as_ref().map(|s| s.span()), "tool_side"),
        (raw.tool_axis.as_ref().map(|s| s.span()), "tool_axis"),
        (raw.axes.as_ref().map(|s| s.span()), "axes"),
    ] {
        if let Some(span) = present {
            return Err(src.invalid(
                span,
                key,
                format!(
                    "`{key}` describes a `kinematics = \"chain\"` machine; a {} machine is given by [geometry]",
                    kind.name()
                ),
            ));
        }
    }
    let tool_chain = match &raw.tool_chain {
        None => ToolChain::XYZ,
        Some(chain) => ToolChain::from_names(chain.get_ref())
            .map_err(|e| src.invalid(chain.span(), "tool_chain", e.to_string()))?,
    };
    let conventional = raw
        .conventional_directions
        .as_ref()
        .is_some_and(|c| *c.get_ref());
    let Some(geometry) = &raw.geometry else {
        return Err(src.invalid(
            raw.kinematics.span(),
            "geometry",
            format!(
                "a {} machine needs its [geometry] (rotary points and offsets, mm)",
                kind.name()
            ),
        ));
    };
    let g = geometry.get_ref();
    let (wrong, wrong_name, needed) = match kind {
        KinematicsType::XyzacTrt => (&g.x_offset, "x_offset", "y_offset"),
        _ => (&g.y_offset, "y_offset", "x_offset"),
    };
    if let Some(wrong) = wrong {
        return Err(src.invalid(
            wrong.span(),
            &format!("geometry.{wrong_name}"),
            format!(
                "{} takes `{needed}`, not `{wrong_name}` (LinuxCNC's {}-kins ignores {wrong_name})",
                kind.name(),
                kind.name()
            ),
        ));
    }
    let get = |value: &Option<Spanned<f64>>, name: &str| -> Result<f64, MachineError> {
        let v = value.as_ref().ok_or_else(|| {
            src.invalid(
                geometry.span(),
                &format!("geometry.{name}"),
                format!("missing `{name}` (mm)"),
            )
        })?;
        src.within(
            v.span(),
            &format!("geometry.{name}"),
            "mm",
            *v.get_ref(),
            MAX_LENGTH_MM,
        )
    };
    let (x, y, z) = (
        get(&g.x_rot_point, "x_rot_point")?,
        get(&g.y_rot_point, "y_rot_point")?,
        get(&g.z_rot_point, "z_rot_point")?,
    );
    let z_offset = get(&g.z_offset, "z_offset")?;
    let kin = match kind {
        KinematicsType::XyzacTrt => Kinematics::xyzac_trt(
            Geometry {
                x_rot_point: x,
                y_rot_point: y,
                z_rot_point: z,
                y_offset: get(&g.y_offset, "y_offset")?,
                z_offset,
            },
            tool_chain,
            conventional,
            0.0,
        ),
        _ => Kinematics::xyzbc_trt(
            BcGeometry {
                x_rot_point: x,
                y_rot_point: y,
                z_rot_point: z,
                x_offset: get(&g.x_offset, "x_offset")?,
                z_offset,
            },
            tool_chain,
            conventional,
            0.0,
        ),
    };
    Ok(kin.chain)
}

/// The chain of a `kinematics = "chain"` file (formats.md "Machine file for any
/// five-axis machine").
fn described_chain(src: &Source<'_>, raw: &RawMachine) -> Result<MachineChain, MachineError> {
    for (present, key) in [
        (raw.geometry.as_ref().map(|s| s.span()), "geometry"),
        (raw.tool_chain.as_ref().map(|s| s.span()), "tool_chain"),
        (
            raw.conventional_directions.as_ref().map(|s| s.span()),
            "conventional_directions",
        ),
    ] {
        if let Some(span) = present {
            let hint = match key {
                "geometry" => "describe the axes in [axes.K] (direction, point)",
                "tool_chain" => "list the tool's axes in tool_side",
                _ => "give a rotary axis a negative direction to reverse it",
            };
            return Err(src.invalid(
                span,
                key,
                format!("`{key}` belongs to the xyzac-trt/xyzbc-trt presets; a chain machine does not take it: {hint}"),
            ));
        }
    }
    let mut seen = AxisSet::EMPTY;
    let need = |side: &Option<Spanned<Vec<String>>>, key: &str| -> Result<(), MachineError> {
        if side.is_none() {
            return Err(src.invalid(
                raw.kinematics.span(),
                key,
                format!("a chain machine needs `{key}` (a list of axis letters, bed outwards; may be empty)"),
            ));
        }
        Ok(())
    };
    need(&raw.workpiece_side, "workpiece_side")?;
    need(&raw.tool_side, "tool_side")?;
    let empty = Spanned::new(0..0, Vec::new());
    let work_raw = raw.workpiece_side.as_ref().unwrap_or(&empty);
    let tool_raw = raw.tool_side.as_ref().unwrap_or(&empty);
    let work = src.side("workpiece_side", work_raw, &mut seen)?;
    let tool = src.side("tool_side", tool_raw, &mut seen)?;
    let mut described: BTreeMap<Axis, (&Spanned<RawAxis>, Range<usize>)> = BTreeMap::new();
    if let Some(axes) = &raw.axes {
        for (name, entry) in axes.get_ref() {
            let key = format!("axes.{name}");
            let axis = src.letter(entry.span(), &key, name)?;
            if !seen.contains(axis) {
                return Err(src.invalid(
                    entry.span(),
                    &key,
                    format!(
                        "axis {} is described but is in neither workpiece_side nor tool_side (the machine's axes: {})",
                        axis.letter(),
                        seen.letters()
                    ),
                ));
            }
            if described.insert(axis, (entry, entry.span())).is_some() {
                return Err(src.invalid(
                    entry.span(),
                    &key,
                    format!("axis {} is described twice", axis.letter()),
                ));
            }
        }
    }
    let build = |axis: Axis| -> Result<ChainAxis, MachineError> {
        let key = format!("axes.{}", axis.letter());
        let entry = described.get(&axis);
        let span = entry.map_or(raw.kinematics.span(), |e| e.1.clone());
        let raw_axis = entry.map(|e| e.0.get_ref());
        let direction_key = format!("{key}.direction");
        let point_key = format!("{key}.point");
        let direction = match raw_axis.and_then(|a| a.direction.as_ref()) {
            Some(d) => three(src, &direction_key, d)?,
            None => natural_direction(axis),
        };
        let point = match raw_axis.and_then(|a| a.point.as_ref()) {
            Some(p) => {
                let v = three(src, &point_key, p)?;
                for c in v {
                    src.within(p.span(), &point_key, "mm", c, MAX_LENGTH_MM)?;
                }
                Some(v)
            }
            None => None,
        };
        let norm = crate::vec3::norm(direction);
        if !(norm.is_finite() && norm >= 1e-9) {
            return Err(src.invalid(
                span,
                &direction_key,
                "the direction is the zero vector or too large to normalise: give the axis's unit direction at home",
            ));
        }
        if axis.is_rotary() {
            let Some(point) = point else {
                return Err(src.invalid(
                    span,
                    &key,
                    format!(
                        "rotary axis {} needs `point`, a point on its line at home (mm; workpiece side: machine coordinates, tool side: relative to the gauge point)",
                        axis.letter()
                    ),
                ));
            };
            Ok(ChainAxis::rotary(axis, direction, point))
        } else {
            if point.is_some() {
                return Err(src.invalid(
                    span,
                    &format!("{key}.point"),
                    format!(
                        "linear axis {} takes a direction only, not a point",
                        axis.letter()
                    ),
                ));
            }
            Ok(ChainAxis::linear(axis, direction))
        }
    };
    let work: Vec<ChainAxis> = work.into_iter().map(build).collect::<Result<_, _>>()?;
    let tool: Vec<ChainAxis> = tool.into_iter().map(build).collect::<Result<_, _>>()?;
    let tool_axis = match &raw.tool_axis {
        Some(t) => {
            src.finite(t.span(), "tool_axis", t.get_ref())?;
            *t.get_ref()
        }
        None => [0.0, 0.0, 1.0],
    };
    let span = raw
        .tool_side
        .as_ref()
        .map_or(raw.kinematics.span(), |s| s.span());
    MachineChain::new(&work, &tool, tool_axis).map_err(|e| {
        let key = match e {
            crate::kinematics::ChainError::BadToolAxis
            | crate::kinematics::ChainError::ToolAxisAlongRotary(_) => "tool_axis",
            _ => "tool_side",
        };
        src.invalid(span, key, e.to_string())
    })
}

impl Machine {
    /// Read and validate a machine file (tables outside the travel are an error).
    pub fn load(path: &Path) -> Result<Machine, MachineError> {
        Machine::load_with(path, &LoadOptions::default())
    }

    /// Read and validate a machine file with `options`.
    pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Machine, MachineError> {
        let text = crate::io::read_to_string(path)?;
        Machine::parse(&text, path, options)
    }

    /// Parse machine-file `text` as if read from `path` (tables are resolved relative
    /// to `path`'s directory).
    pub fn parse(text: &str, path: &Path, options: &LoadOptions) -> Result<Machine, MachineError> {
        let src = Source { path, text };
        let raw: RawMachine = toml::from_str(text).map_err(|e| {
            let (line, column) = e
                .span()
                .map_or((1, 1), |span| line_column(text, span.start));
            MachineError::Parse {
                path: path.to_path_buf(),
                line,
                column,
                message: crate::io::echo(e.message().trim_end()).into_owned(),
            }
        })?;

        let kinematics = kinematics_type(&src, &raw)?;
        let chain = match kinematics {
            KinematicsType::Chain => described_chain(&src, &raw)?,
            preset => preset_chain(&src, &raw, preset)?,
        };
        let tool = default_tool(&src, &raw.tool)?;
        let tools = tool_table(&src, &raw.tools)?;
        let limits = travel_limits(&src, &raw, &chain, kinematics)?;
        let (rapid_mm_per_min, rapid_is_default) = rapid_rate(&src, &raw)?;
        let squareness = match &raw.squareness {
            Some(s) => {
                let r = s.get_ref();
                let v = [r.s_xy, r.s_xz, r.s_yz];
                for (name, x) in ["s_xy", "s_xz", "s_yz"].iter().zip(v) {
                    let key = format!("squareness.{name}");
                    src.within(s.span(), &key, "µrad", x, MAX_ERROR_URAD)?;
                }
                v
            }
            None => [0.0; 3],
        };
        let location = location_errors(&src, &raw, &chain)?;
        let tables = error_tables(&src, &raw, &chain, &limits, options)?;
        let reversal = reversal_constants(&src, &raw, &chain, &tables)?;

        Ok(Machine {
            name: raw.name,
            kinematics,
            chain,
            tool,
            tools,
            limits,
            rapid_mm_per_min,
            rapid_is_default,
            tables,
            squareness,
            location,
            reversal,
            source: path.to_path_buf(),
            text: std::sync::Arc::from(text),
        })
    }

    /// The kinematic model of this machine.
    pub fn kinematics_model(&self) -> Kinematics {
        Kinematics::from_chain(self.chain, self.tool.length)
    }

    /// The default tool (tool 0): `[tool]`.
    pub fn default_tool(&self) -> crate::gcode::ToolInUse {
        crate::gcode::ToolInUse {
            shape: self.tool.shape,
            ..crate::gcode::ToolInUse::default_tool(self.tool.length, self.tool.radius)
        }
    }

    /// The machine's axis letters.
    pub fn letters(&self) -> AxisSet {
        self.chain.letters()
    }

    /// The names of the machine's error parameters.
    pub fn layout(&self) -> ParameterLayout {
        self.chain.layout()
    }

    /// The table of `axis`, if measured.
    pub fn table(&self, axis: Axis) -> Option<&ErrorTable> {
        self.chain.slot(axis).and_then(|s| self.tables[s].as_ref())
    }

    /// The reversal of `axis`: its table's `REVERSAL` column or the `[reversal]`
    /// constant (never both: refused on load); `None` without either.
    pub fn reversal(&self, axis: Axis) -> Option<super::AxisReversal> {
        let slot = self.chain.slot(axis)?;
        if let Some(v) = self.reversal[slot] {
            return Some(super::AxisReversal::Constant(v));
        }
        let table = self.tables[slot].as_ref()?;
        table
            .reversal
            .as_ref()
            .map(|values| super::AxisReversal::Table {
                positions: table.positions.clone(),
                values: values.clone(),
            })
    }

    /// The position-independent parameters (squareness, location) with every
    /// component error zero.
    pub fn scalar_errors(&self) -> ErrorValues {
        let mut values = ErrorValues::ZERO;
        values.squareness = self.squareness;
        values.location = self.location;
        debug_assert_eq!(SQUARENESS_NAMES.len(), 3);
        values
    }
}

/// The `kinematics` key.
fn kinematics_type(src: &Source<'_>, raw: &RawMachine) -> Result<KinematicsType, MachineError> {
    match raw.kinematics.get_ref().as_str() {
        "xyzac-trt" => Ok(KinematicsType::XyzacTrt),
        "xyzbc-trt" => Ok(KinematicsType::XyzbcTrt),
        "chain" => Ok(KinematicsType::Chain),
        other => Err(src.invalid(
            raw.kinematics.span(),
            "kinematics",
            format!(
                "unsupported kinematics \"{other}\" (expected \"xyzac-trt\", \"xyzbc-trt\" or \"chain\")"
            ),
        )),
    }
}

/// `[tool]`: the default tool.
fn default_tool(src: &Source<'_>, raw: &RawTool) -> Result<Tool, MachineError> {
    let (length, radius) = (*raw.length.get_ref(), *raw.radius.get_ref());
    src.within(raw.length.span(), "tool.length", "mm", length, MAX_TOOL_MM)?;
    src.within(raw.radius.span(), "tool.radius", "mm", radius, MAX_TOOL_MM)?;
    if length < 0.0 {
        return Err(src.invalid(raw.length.span(), "tool.length", "must be ≥ 0 mm"));
    }
    if radius < 0.0 {
        return Err(src.invalid(raw.radius.span(), "tool.radius", "must be ≥ 0 mm"));
    }
    let shape = cutter_shape(
        raw.shape.as_ref().map(|s| s.get_ref().as_str()),
        radius,
        raw.corner_radius,
        raw.flute_length,
    )
    .map_err(|message| {
        let span = raw.shape.as_ref().map_or(raw.radius.span(), |s| s.span());
        src.invalid(span, "tool.shape", message)
    })?;
    Ok(Tool {
        length,
        radius,
        shape,
    })
}

/// `[[tools]]`: the tool table (each entry located in the machine file).
fn tool_table(
    src: &Source<'_>,
    entries: &[Spanned<RawToolEntry>],
) -> Result<crate::gcode::ToolTable, MachineError> {
    let path = src.path;
    let mut tools = crate::gcode::ToolTable::new();
    tools.set_source(format!("{} [[tools]]", path.display()));
    for entry in entries {
        let span = entry.span();
        let e = entry.get_ref();
        let key = format!("tools (T{})", e.number);
        src.within(span.clone(), &key, "mm (length)", e.length, MAX_TOOL_MM)?;
        src.within(span.clone(), &key, "mm (radius)", e.radius, MAX_TOOL_MM)?;
        if e.number == 0 {
            return Err(src.invalid(
                span,
                &key,
                "tool 0 is the empty spindle ([tool] is the default tool): number tools from 1",
            ));
        }
        if e.length < 0.0 || e.radius < 0.0 {
            return Err(src.invalid(
                span,
                &key,
                "length (gauge point to tip) and radius must be ≥ 0 mm",
            ));
        }
        let shape = cutter_shape(
            e.shape.as_deref(),
            e.radius,
            e.corner_radius,
            e.flute_length,
        )
        .map_err(|message| src.invalid(span.clone(), &key, message))?;
        let (line, _) = line_column(src.text, span.start);
        tools
            .insert(crate::gcode::ToolEntry {
                number: e.number,
                pocket: e.pocket,
                name: e.name.clone(),
                length_mm: e.length,
                diameter_mm: 2.0 * e.radius,
                shape,
                comment: e.comment.clone(),
                origin: format!("{}:{line}", path.display()),
            })
            .map_err(|first| {
                let what = match &e.name {
                    Some(name) if tools.get(e.number).is_none() => {
                        format!("the tool name \"{name}\" is listed twice (first at {first})")
                    }
                    _ => format!("tool {} is listed twice (first at {first})", e.number),
                };
                src.invalid(span, &key, what)
            })?;
    }
    Ok(tools)
}

/// `[limits]`: every linear axis of the machine; a rotary axis may be omitted
/// (endless), but the tilting axis of the presets is required (formats.md).
fn travel_limits(
    src: &Source<'_>,
    raw: &RawMachine,
    chain: &MachineChain,
    kinematics: KinematicsType,
) -> Result<Limits, MachineError> {
    let letters = chain.letters();
    let limits_span = raw.limits.span();
    let mut limits = Limits::default();
    for (name, value) in raw.limits.get_ref() {
        let key = format!("limits.{name}");
        let axis = src.letter(value.span(), &key, name)?;
        if !letters.contains(axis) {
            return Err(src.invalid(
                value.span(),
                &key,
                format!(
                    "the machine has no axis {} (its axes: {})",
                    axis.letter(),
                    letters.letters()
                ),
            ));
        }
        if limits.get(axis).is_some() {
            return Err(src.invalid(
                value.span(),
                &key,
                format!("limits of {} given twice", axis.letter()),
            ));
        }
        limits.set(axis, Some(src.range(&key, value)?));
    }
    let tilting = match kinematics {
        KinematicsType::XyzacTrt => Some(Axis::A),
        KinematicsType::XyzbcTrt => Some(Axis::B),
        KinematicsType::Chain => None,
    };
    for axis in letters.iter() {
        if limits.get(axis).is_none() && (!axis.is_rotary() || Some(axis) == tilting) {
            return Err(src.invalid(
                limits_span.clone(),
                &format!("limits.{}", axis.lower()),
                format!(
                    "missing the travel of {} ([min, max], {})",
                    axis.letter(),
                    axis.unit()
                ),
            ));
        }
    }
    Ok(limits)
}

/// `[rates] rapid`, mm/min, and whether it is the default.
fn rapid_rate(src: &Source<'_>, raw: &RawMachine) -> Result<(f64, bool), MachineError> {
    match raw.rates.as_ref().and_then(|r| r.rapid.as_ref()) {
        Some(rapid) => {
            let v = *rapid.get_ref();
            if !(v.is_finite() && v > 0.0) {
                return Err(src.invalid(
                    rapid.span(),
                    "rates.rapid",
                    "must be a positive number (mm/min)",
                ));
            }
            Ok((v, false))
        }
        None => Ok((DEFAULT_RAPID_MM_PER_MIN, true)),
    }
}

/// `[location]`: the rotary axes' location errors, by the layout's names.
fn location_errors(
    src: &Source<'_>,
    raw: &RawMachine,
    chain: &MachineChain,
) -> Result<[f64; 10], MachineError> {
    let mut location = [0.0; 10];
    let Some(l) = &raw.location else {
        return Ok(location);
    };
    let layout = chain.layout();
    let names = layout.location_names();
    for (name, value) in l.get_ref() {
        let key = format!("location.{name}");
        let Some(i) = names.iter().position(|n| n == name) else {
            return Err(src.invalid(
                value.span(),
                &key,
                format!(
                    "unknown location error `{name}`: this machine's rotary axes {} and {} take {}",
                    layout.rotary()[0].letter(),
                    layout.rotary()[1].letter(),
                    names.join(", ")
                ),
            ));
        };
        let (max, unit) = error_bound(name);
        location[i] = src.within(value.span(), &key, unit, *value.get_ref(), max)?;
    }
    Ok(location)
}

/// `[errors]`: each axis's error table, read relative to the machine file's
/// folder (coverage of the travel checked as `options` say).
fn error_tables(
    src: &Source<'_>,
    raw: &RawMachine,
    chain: &MachineChain,
    limits: &Limits,
    options: &LoadOptions,
) -> Result<[Option<ErrorTable>; 5], MachineError> {
    let path = src.path;
    let base = path.parent().unwrap_or(Path::new(""));
    let mut tables: [Option<ErrorTable>; 5] = Default::default();
    let Some(errors) = &raw.errors else {
        return Ok(tables);
    };
    for (name, entry) in errors.get_ref() {
        let key = format!("errors.{name}");
        let axis = src.letter(entry.span(), &key, name)?;
        let slot = modelled_slot(chain, axis, "error tables")
            .map_err(|why| src.invalid(entry.span(), &key, why))?;
        if tables[slot].is_some() {
            return Err(src.invalid(
                entry.span(),
                &key,
                format!("the table of {} is given twice", axis.letter()),
            ));
        }
        let table_path = base.join(entry.get_ref());
        let table = ErrorTable::read(&table_path, Some(axis)).map_err(|source| {
            let (line, column) = line_column(src.text, entry.span().start);
            MachineError::Table {
                path: path.to_path_buf(),
                line,
                column,
                key: key.clone(),
                source: Box::new(source),
            }
        })?;
        if options.extrapolation == ExtrapolationPolicy::Error {
            check_coverage(src, raw, limits, axis, &table, &key)?;
        }
        tables[slot] = Some(table);
    }
    Ok(tables)
}

/// `[reversal]` (docs/extensions.md): `X = 8.0` (µm; µrad for a rotary axis)
/// per axis of the machine with error tables (X Y Z and its two rotary axes),
/// finite, each axis once, and not for an axis whose table has a `REVERSAL`
/// column (which of the two would hold is ambiguous).
/// The error-model slot of `axis` on `chain`, or why it has none: an axis
/// the machine lacks, or U V W (which carry no `carries`).
fn modelled_slot(chain: &MachineChain, axis: Axis, carries: &str) -> Result<usize, String> {
    let letters = chain.letters();
    chain.slot(axis).ok_or_else(|| {
        if letters.contains(axis) {
            format!("U, V and W carry no {carries} (volcomp models their position only)")
        } else {
            format!(
                "the machine has no axis {} (its axes: {})",
                axis.letter(),
                letters.letters()
            )
        }
    })
}

fn reversal_constants(
    src: &Source<'_>,
    raw: &RawMachine,
    chain: &MachineChain,
    tables: &[Option<ErrorTable>; 5],
) -> Result<[Option<f64>; 5], MachineError> {
    let mut out = [None; 5];
    let Some(section) = &raw.reversal else {
        return Ok(out);
    };
    for (name, value) in section.get_ref() {
        let key = format!("reversal.{name}");
        let axis = src.letter(value.span(), &key, name)?;
        let slot = modelled_slot(chain, axis, "error model")
            .map_err(|why| src.invalid(value.span(), &key, why))?;
        if out[slot].is_some() {
            return Err(src.invalid(
                value.span(),
                &key,
                format!("the reversal of {} is given twice", axis.letter()),
            ));
        }
        let (max, unit) = if axis.is_rotary() {
            (MAX_REVERSAL_URAD, "µrad")
        } else {
            (MAX_REVERSAL_UM, "µm")
        };
        let v = src.within(value.span(), &key, unit, *value.get_ref(), max)?;
        if let Some(table) = &tables[slot]
            && table.reversal.is_some()
        {
            return Err(src.invalid(
                value.span(),
                &key,
                format!(
                    "{} already has a REVERSAL column in {}: give the reversal of {} in one place only",
                    axis.letter(),
                    table.path.display(),
                    axis.letter()
                ),
            ));
        }
        out[slot] = Some(v);
    }
    Ok(out)
}

/// The travel of `axis` must lie inside the table's positions (a rotary table over
/// one revolution covers everything).
fn check_coverage(
    src: &Source<'_>,
    raw: &RawMachine,
    limits: &Limits,
    axis: Axis,
    table: &ErrorTable,
    table_key: &str,
) -> Result<(), MachineError> {
    if table.one_revolution {
        return Ok(());
    }
    let (Some(first), Some(last)) = (table.positions.first(), table.positions.last()) else {
        return Ok(());
    };
    let unit = if axis.is_rotary() { "°" } else { " mm" };
    let key = format!("limits.{}", axis.lower());
    let hint = "a lookup inside the travel would fall outside the table; extend the table, \
narrow the limits, or hold the end values (--extrapolate hold)";
    let span = raw
        .limits
        .get_ref()
        .iter()
        .find(|(k, _)| k.eq_ignore_ascii_case(&axis.lower().to_string()))
        .map_or(raw.limits.span(), |(_, v)| v.span());
    match limits.get(axis) {
        None => Err(src.invalid(
            span,
            &key,
            format!(
                "{} is endless (no {key}) but the {} table covers only {first}{unit} to {last}{unit} \
and is not one revolution (0 to 360°); {hint}",
                axis.letter(),
                table_key
            ),
        )),
        Some([lo, hi]) => {
            let tol = 1e-9 * (1.0 + lo.abs().max(hi.abs()));
            if lo < first - tol || hi > last + tol {
                Err(src.invalid(
                    span,
                    &key,
                    format!(
                        "travel [{lo}, {hi}]{unit} is not covered by the table of `{table_key}` \
({first}{unit} to {last}{unit}); {hint}"
                    ),
                ))
            } else {
                Ok(())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn line_and_column_are_one_based() {
        let text = "a = 1\nbb = 2\n";
        assert_eq!(line_column(text, 0), (1, 1));
        assert_eq!(line_column(text, 6), (2, 1));
        assert_eq!(line_column(text, 9), (2, 4));
    }
}
