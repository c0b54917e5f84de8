//! The machine file (formats.md "Machine file"): TOML read with serde, unknown keys
//! rejected, every value validated, error tables read through [`ErrorTable::read`].
//!
//! Invariants of a loaded [`Machine`]: every number is finite; limits are
//! `min < max`; the tool chain is a permutation of X Y Z; every table exists, has
//! the right columns (checked by the table reader) and covers the travel of its
//! axis unless the load options hold end values (a C table over one revolution
//! covers any C). Errors name the machine file with line and column of the key, or
//! (for a table) the CSV file and line.
use super::table::{ErrorTable, TableError};
use crate::axes::{Axes, Axis};
use crate::kinematics::error_values::{LOCATION_NAMES, SQUARENESS_NAMES};
use crate::kinematics::{ErrorValues, Geometry, Kinematics, ToolChain};
use serde::Deserialize;
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
}

impl KinematicsType {
    pub fn name(self) -> &'static str {
        match self {
            KinematicsType::XyzacTrt => "xyzac-trt",
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

/// Travel limits: `[min, max]`, mm or degrees; `c = None` is endless.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Limits {
    pub x: [f64; 2],
    pub y: [f64; 2],
    pub z: [f64; 2],
    pub a: [f64; 2],
    pub c: Option<[f64; 2]>,
}

impl Limits {
    pub fn get(&self, axis: Axis) -> Option<[f64; 2]> {
        match axis {
            Axis::X => Some(self.x),
            Axis::Y => Some(self.y),
            Axis::Z => Some(self.z),
            Axis::A => Some(self.a),
            Axis::C => self.c,
        }
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
    pub length: f64,
    pub radius: f64,
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
    pub name: String,
    pub kinematics: KinematicsType,
    pub tool_chain: ToolChain,
    pub geometry: Geometry,
    pub tool: Tool,
    /// `[[tools]]`: the machine's tool table (empty when the file has none).
    pub tools: crate::gcode::ToolTable,
    pub limits: Limits,
    /// G0 rate, mm/min ([`DEFAULT_RAPID_MM_PER_MIN`] when the file has none).
    pub rapid_mm_per_min: f64,
    /// Whether `rapid_mm_per_min` is the default rather than the file's value.
    pub rapid_is_default: bool,
    /// Measured tables per axis, in `Axis::ALL` order (X Y Z A C); `None` = not measured.
    pub tables: [Option<ErrorTable>; 5],
    /// `s_xy, s_xz, s_yz`, µrad.
    pub squareness: [f64; 3],
    /// Rotary location errors in `kinematics::LOCATION_NAMES` order (µm, µrad).
    pub location: [f64; 10],
    /// LinuxCNC's `conventional-directions` (kinematics.md).
    pub conventional_directions: bool,
    /// The machine file this was read from.
    pub source: PathBuf,
}

#[derive(Debug, thiserror::Error)]
pub enum MachineError {
    #[error(transparent)]
    Read(#[from] crate::io::InputError),
    /// Syntax, type, missing or unknown key (what serde and toml report).
    #[error("{}:{line}:{column}: {message}", path.display())]
    Parse {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    /// A value that parses but is not acceptable.
    #[error("{}:{line}:{column}: `{key}`: {message}", path.display())]
    Invalid {
        path: PathBuf,
        line: usize,
        column: usize,
        key: String,
        message: String,
    },
    /// An error table named by the machine file could not be read.
    #[error("{}:{line}:{column}: `{key}`: {source}", path.display())]
    Table {
        path: PathBuf,
        line: usize,
        column: usize,
        key: String,
        source: Box<TableError>,
    },
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMachine {
    name: String,
    kinematics: Spanned<String>,
    tool_chain: Option<Spanned<Vec<String>>>,
    #[serde(default)]
    conventional_directions: bool,
    geometry: Spanned<Geometry>,
    tool: RawTool,
    #[serde(default)]
    tools: Vec<Spanned<RawToolEntry>>,
    limits: Spanned<RawLimits>,
    rates: Option<RawRates>,
    errors: Option<RawErrors>,
    squareness: Option<Spanned<RawSquareness>>,
    location: Option<Spanned<RawLocation>>,
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
    shape: Option<String>,
    corner_radius: Option<f64>,
    flute_length: Option<f64>,
    #[serde(default)]
    comment: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawLimits {
    x: Spanned<[f64; 2]>,
    y: Spanned<[f64; 2]>,
    z: Spanned<[f64; 2]>,
    a: Spanned<[f64; 2]>,
    c: Option<Spanned<[f64; 2]>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRates {
    rapid: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawErrors {
    x: Option<Spanned<String>>,
    y: Option<Spanned<String>>,
    z: Option<Spanned<String>>,
    a: Option<Spanned<String>>,
    c: Option<Spanned<String>>,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
struct RawSquareness {
    s_xy: f64,
    s_xz: f64,
    s_yz: f64,
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields, default)]
#[allow(non_snake_case)]
struct RawLocation {
    EY0A: f64,
    EZ0A: f64,
    EB0A: f64,
    EC0A: f64,
    EA0A: f64,
    EX0C: f64,
    EY0C: f64,
    EA0C: f64,
    EB0C: f64,
    EC0C: f64,
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

    fn range(&self, key: &str, value: &Spanned<[f64; 2]>) -> Result<[f64; 2], MachineError> {
        let v = *value.get_ref();
        self.finite(value.span(), key, &v)?;
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
                message: e.message().trim_end().to_string(),
            }
        })?;

        let kinematics = match raw.kinematics.get_ref().as_str() {
            "xyzac-trt" => KinematicsType::XyzacTrt,
            other => {
                return Err(src.invalid(
                    raw.kinematics.span(),
                    "kinematics",
                    format!("unsupported kinematics \"{other}\" (expected \"xyzac-trt\")"),
                ));
            }
        };
        let tool_chain = match &raw.tool_chain {
            None => ToolChain::XYZ,
            Some(chain) => ToolChain::from_names(chain.get_ref())
                .map_err(|e| src.invalid(chain.span(), "tool_chain", e.to_string()))?,
        };
        let geometry = *raw.geometry.get_ref();
        if !geometry.is_finite() {
            return Err(src.invalid(
                raw.geometry.span(),
                "geometry",
                "every value must be a finite number",
            ));
        }
        let (length, radius) = (*raw.tool.length.get_ref(), *raw.tool.radius.get_ref());
        src.finite(raw.tool.length.span(), "tool.length", &[length])?;
        src.finite(raw.tool.radius.span(), "tool.radius", &[radius])?;
        if length < 0.0 {
            return Err(src.invalid(raw.tool.length.span(), "tool.length", "must be ≥ 0 mm"));
        }
        if radius < 0.0 {
            return Err(src.invalid(raw.tool.radius.span(), "tool.radius", "must be ≥ 0 mm"));
        }
        let shape = cutter_shape(
            raw.tool.shape.as_ref().map(|s| s.get_ref().as_str()),
            radius,
            raw.tool.corner_radius,
            raw.tool.flute_length,
        )
        .map_err(|message| {
            let span = raw
                .tool
                .shape
                .as_ref()
                .map_or(raw.tool.radius.span(), |s| s.span());
            src.invalid(span, "tool.shape", message)
        })?;
        let tool = Tool {
            length,
            radius,
            shape,
        };
        let mut tools = crate::gcode::ToolTable::new();
        tools.set_source(format!("{} [[tools]]", path.display()));
        for entry in &raw.tools {
            let span = entry.span();
            let e = entry.get_ref();
            let key = format!("tools (T{})", e.number);
            src.finite(span.clone(), &key, &[e.length, e.radius])?;
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
            let (line, _) = line_column(text, span.start);
            tools
                .insert(crate::gcode::ToolEntry {
                    number: e.number,
                    pocket: e.pocket,
                    length_mm: e.length,
                    diameter_mm: 2.0 * e.radius,
                    shape,
                    comment: e.comment.clone(),
                    origin: format!("{}:{line}", path.display()),
                })
                .map_err(|first| {
                    src.invalid(
                        span,
                        &key,
                        format!("tool {} is listed twice (first at {first})", e.number),
                    )
                })?;
        }
        let limits_span = raw.limits.span();
        let raw_limits = raw.limits.get_ref();
        let limits = Limits {
            x: src.range("limits.x", &raw_limits.x)?,
            y: src.range("limits.y", &raw_limits.y)?,
            z: src.range("limits.z", &raw_limits.z)?,
            a: src.range("limits.a", &raw_limits.a)?,
            c: match &raw_limits.c {
                Some(c) => Some(src.range("limits.c", c)?),
                None => None,
            },
        };
        let (rapid_mm_per_min, rapid_is_default) =
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
                    (v, false)
                }
                None => (DEFAULT_RAPID_MM_PER_MIN, true),
            };
        let squareness = match &raw.squareness {
            Some(s) => {
                let r = s.get_ref();
                let v = [r.s_xy, r.s_xz, r.s_yz];
                src.finite(s.span(), "squareness", &v)?;
                v
            }
            None => [0.0; 3],
        };
        let location = match &raw.location {
            Some(l) => {
                let r = l.get_ref();
                let v = [
                    r.EY0A, r.EZ0A, r.EB0A, r.EC0A, r.EA0A, r.EX0C, r.EY0C, r.EA0C, r.EB0C, r.EC0C,
                ];
                src.finite(l.span(), "location", &v)?;
                v
            }
            None => [0.0; 10],
        };

        let base = path.parent().unwrap_or(Path::new(""));
        let mut tables: [Option<ErrorTable>; 5] = Default::default();
        if let Some(errors) = &raw.errors {
            let entries = [
                (Axis::X, &errors.x),
                (Axis::Y, &errors.y),
                (Axis::Z, &errors.z),
                (Axis::A, &errors.a),
                (Axis::C, &errors.c),
            ];
            for (slot, (axis, entry)) in tables.iter_mut().zip(entries) {
                let Some(entry) = entry else { continue };
                let key = format!("errors.{}", axis.letter().to_ascii_lowercase());
                let table_path = base.join(entry.get_ref());
                let table = ErrorTable::read(&table_path, Some(axis)).map_err(|source| {
                    let (line, column) = line_column(text, entry.span().start);
                    MachineError::Table {
                        path: path.to_path_buf(),
                        line,
                        column,
                        key: key.clone(),
                        source: Box::new(source),
                    }
                })?;
                if options.extrapolation == ExtrapolationPolicy::Error {
                    check_coverage(&src, raw_limits, limits_span.clone(), axis, &table, &key)?;
                }
                *slot = Some(table);
            }
        }

        Ok(Machine {
            name: raw.name,
            kinematics,
            tool_chain,
            geometry,
            tool,
            tools,
            limits,
            rapid_mm_per_min,
            rapid_is_default,
            tables,
            squareness,
            location,
            conventional_directions: raw.conventional_directions,
            source: path.to_path_buf(),
        })
    }

    /// The kinematic model of this machine.
    pub fn kinematics_model(&self) -> Kinematics {
        Kinematics {
            geometry: self.geometry,
            tool_length: self.tool.length,
            tool_chain: self.tool_chain,
            conventional_directions: self.conventional_directions,
        }
    }

    /// The default tool (tool 0): `[tool]`.
    pub fn default_tool(&self) -> crate::gcode::ToolInUse {
        crate::gcode::ToolInUse {
            shape: self.tool.shape,
            ..crate::gcode::ToolInUse::default_tool(self.tool.length, self.tool.radius)
        }
    }

    /// The kinematic model of this machine with `tool` in the spindle.
    pub fn kinematics_for(&self, tool: &crate::gcode::ToolInUse) -> Kinematics {
        self.kinematics_model().with_tool_length(tool.length_mm)
    }

    /// The table of `axis`, if measured.
    pub fn table(&self, axis: Axis) -> Option<&ErrorTable> {
        self.tables[axis_slot(axis)].as_ref()
    }

    /// The position-independent parameters (squareness, location) with every
    /// component error zero.
    pub fn scalar_errors(&self) -> ErrorValues {
        let mut values = ErrorValues::ZERO;
        values.squareness = self.squareness;
        values.location = self.location;
        debug_assert_eq!(SQUARENESS_NAMES.len(), 3);
        debug_assert_eq!(LOCATION_NAMES.len(), 10);
        values
    }
}

/// Index of `axis` in `Axis::ALL` (the order of [`Machine::tables`]).
pub(crate) fn axis_slot(axis: Axis) -> usize {
    match axis {
        Axis::X => 0,
        Axis::Y => 1,
        Axis::Z => 2,
        Axis::A => 3,
        Axis::C => 4,
    }
}

/// The travel of `axis` must lie inside the table's positions (a C table over one
/// revolution covers everything).
fn check_coverage(
    src: &Source<'_>,
    limits: &RawLimits,
    limits_span: Range<usize>,
    axis: Axis,
    table: &ErrorTable,
    table_key: &str,
) -> Result<(), MachineError> {
    if axis == Axis::C && table.one_revolution {
        return Ok(());
    }
    let (Some(first), Some(last)) = (table.positions.first(), table.positions.last()) else {
        return Ok(());
    };
    let spanned = match axis {
        Axis::X => Some(&limits.x),
        Axis::Y => Some(&limits.y),
        Axis::Z => Some(&limits.z),
        Axis::A => Some(&limits.a),
        Axis::C => limits.c.as_ref(),
    };
    let unit = if axis.is_rotary() { "°" } else { " mm" };
    let key = format!("limits.{}", axis.letter().to_ascii_lowercase());
    let hint = "a lookup inside the travel would fall outside the table; extend the table, \
narrow the limits, or hold the end values (--extrapolate hold)";
    match spanned {
        None => Err(src.invalid(
            limits_span,
            &key,
            format!(
                "C is endless (no limits.c) but the {} table covers only {first}{unit} to {last}{unit} \
and is not one revolution (0 to 360°); {hint}",
                table_key
            ),
        )),
        Some(limit) => {
            let [lo, hi] = *limit.get_ref();
            let tol = 1e-9 * (1.0 + lo.abs().max(hi.abs()));
            if lo < first - tol || hi > last + tol {
                Err(src.invalid(
                    limit.span(),
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
