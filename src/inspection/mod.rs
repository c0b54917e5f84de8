//! Inspection plans and measurements (formats.md): points on the nominal part
//! surface with their unit outward normals, the measured points a CMM reports,
//! deviations along the normal and the profile error.
//!
//! Invariants: every plan point has finite coordinates and a unit normal (a zero
//! normal is rejected at read time); ids are unique within a plan; deviations are
//! in µm, positive where material was left.
use crate::io::{OutputError, read_to_string, write_atomic};
use serde::{Deserialize, Serialize};
use std::collections::HashSet;
use std::path::{Path, PathBuf};

pub(crate) mod reader;
pub(crate) mod work_frame;

pub use work_frame::WorkFrame;

/// Why an inspection plan or measurement could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum InspectionError {
    /// The file could not be read.
    #[error(transparent)]
    Read(#[from] crate::io::InputError),
    /// The file could not be written.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// The header lacks a required column.
    #[error("{}:{line}: header lacks column `{missing}` (expected columns {expected}, any order)", path.display())]
    Header {
        /// The file.
        path: PathBuf,
        /// 1-based line of the header.
        line: usize,
        /// The missing column.
        missing: String,
        /// The expected columns, comma-separated.
        expected: String,
    },
    /// A field is not acceptable (not a number, not finite, a zero normal, a repeated id, …).
    #[error("{}:{line}: column `{column}`: {message}", path.display())]
    Field {
        /// The file.
        path: PathBuf,
        /// 1-based line.
        line: usize,
        /// The column of the field.
        column: String,
        /// What is wrong.
        message: String,
    },
    /// The file has no data rows.
    #[error("{}: no data rows (expected at least one point after the header)", path.display())]
    Empty {
        /// The file.
        path: PathBuf,
    },
}

/// One point of an inspection plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanPoint {
    /// The point's id, unique within a plan.
    pub id: String,
    /// Nominal point, part coordinates, mm.
    pub point: [f64; 3],
    /// Unit outward surface normal (out of the material, towards the tool).
    pub normal: [f64; 3],
}

/// An inspection plan: the points in file order.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Plan {
    /// The points, in file order.
    pub points: Vec<PlanPoint>,
}

/// A plan point with the measured point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MeasuredPoint {
    /// The plan point.
    pub plan: PlanPoint,
    /// Measured point, part coordinates, mm.
    pub measured: [f64; 3],
}

impl MeasuredPoint {
    /// Deviation `d = (m − p)·n`, µm.
    pub fn deviation_um(&self) -> f64 {
        let p = &self.plan;
        (0..3)
            .map(|k| (self.measured[k] - p.point[k]) * p.normal[k])
            .sum::<f64>()
            * 1000.0
    }
}

/// A measurement: the plan with measured points, in file order.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Measurement {
    /// The measured points, in file order.
    pub points: Vec<MeasuredPoint>,
}

impl Measurement {
    /// The plan the measurement was taken on.
    pub fn plan(&self) -> Plan {
        Plan {
            points: self.points.iter().map(|m| m.plan.clone()).collect(),
        }
    }

    /// Deviations in µm, in point order.
    pub fn deviations_um(&self) -> Vec<f64> {
        self.points
            .iter()
            .map(MeasuredPoint::deviation_um)
            .collect()
    }
}

/// Profile error of a set of deviations (formats.md "Profile error").
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Profile {
    /// 2·max|d|, µm.
    pub profile_um: f64,
    /// max d − min d, µm.
    pub range_um: f64,
}

/// Root mean square (0 for an empty slice).
pub fn rms(v: &[f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    (v.iter().map(|x| x * x).sum::<f64>() / v.len() as f64).sqrt()
}

/// Profile of deviations (0 for an empty set).
pub fn profile(deviations_um: &[f64]) -> Profile {
    if deviations_um.is_empty() {
        return Profile {
            profile_um: 0.0,
            range_um: 0.0,
        };
    }
    let max_abs = deviations_um.iter().fold(0.0f64, |m, d| m.max(d.abs()));
    let hi = deviations_um
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let lo = deviations_um.iter().copied().fold(f64::INFINITY, f64::min);
    Profile {
        profile_um: 2.0 * max_abs,
        range_um: hi - lo,
    }
}

const PLAN_COLUMNS: [&str; 6] = ["x", "y", "z", "i", "j", "k"];
const MEASUREMENT_COLUMNS: [&str; 9] = ["x", "y", "z", "i", "j", "k", "mx", "my", "mz"];

fn plan_point(
    path: &Path,
    record: &reader::Record,
    seen: &mut HashSet<String>,
) -> Result<PlanPoint, InspectionError> {
    let v = &record.values;
    let norm = (v[3] * v[3] + v[4] * v[4] + v[5] * v[5]).sqrt();
    if !(norm.is_finite() && norm >= 1e-9) {
        // Zero, or so large that its length overflows: no direction to
        // divide out (a unit normal is expected).
        return Err(InspectionError::Field {
            path: path.to_path_buf(),
            line: record.line,
            column: "i,j,k".into(),
            message: if norm.is_finite() {
                format!(
                    "expected a non-zero surface normal, found ({}, {}, {})",
                    v[3], v[4], v[5]
                )
            } else {
                format!(
                    "expected a unit surface normal, found ({:e}, {:e}, {:e}), whose length overflows",
                    v[3], v[4], v[5]
                )
            },
        });
    }
    if !seen.insert(record.id.clone()) {
        return Err(InspectionError::Field {
            path: path.to_path_buf(),
            line: record.line,
            column: "id".into(),
            message: format!("expected unique ids, `{}` appears again", record.id),
        });
    }
    Ok(PlanPoint {
        id: record.id.clone(),
        point: [v[0], v[1], v[2]],
        normal: [v[3] / norm, v[4] / norm, v[5] / norm],
    })
}

/// Parse the records of `columns` (the plan columns first) into points.
fn parse_points<T>(
    path: &Path,
    text: &str,
    columns: &[&str],
    make: impl Fn(&reader::Record, PlanPoint) -> Result<T, InspectionError>,
) -> Result<Vec<T>, InspectionError> {
    let records = reader::read_records(path, text, columns)?;
    if records.is_empty() {
        return Err(InspectionError::Empty {
            path: path.to_path_buf(),
        });
    }
    let mut seen = HashSet::new();
    records
        .iter()
        .map(|r| make(r, plan_point(path, r, &mut seen)?))
        .collect()
}

/// Write `header` and one `id,values…` row per item atomically (6 decimals).
fn write_rows<'a>(
    path: &Path,
    header: &str,
    rows: impl Iterator<Item = (&'a str, Vec<f64>)>,
) -> Result<(), InspectionError> {
    write_atomic(path, |w| {
        let io = |source| OutputError::Write {
            path: path.to_path_buf(),
            source,
        };
        writeln!(w, "{header}").map_err(io)?;
        for (id, values) in rows {
            writeln!(w, "{id},{}", fmt6(&values)).map_err(io)?;
        }
        Ok::<(), InspectionError>(())
    })
}

impl Plan {
    /// Parse a plan CSV (`id,x,y,z,i,j,k`); `path` names the file in errors.
    pub fn parse(path: &Path, text: &str) -> Result<Plan, InspectionError> {
        let points = parse_points(path, text, &PLAN_COLUMNS, |_, p| Ok(p))?;
        Ok(Plan { points })
    }

    /// Read a plan CSV file (`id,x,y,z,i,j,k`).
    pub fn read(path: &Path) -> Result<Plan, InspectionError> {
        Plan::parse(path, &read_to_string(path)?)
    }

    /// Write the plan atomically (6 decimals).
    pub fn write(&self, path: &Path) -> Result<(), InspectionError> {
        let rows = self
            .points
            .iter()
            .map(|p| (p.id.as_str(), [p.point, p.normal].concat()));
        write_rows(path, "id,x,y,z,i,j,k", rows)
    }
}

impl Measurement {
    /// Parse a measurement CSV (`id,x,y,z,i,j,k,mx,my,mz`).
    pub fn parse(path: &Path, text: &str) -> Result<Measurement, InspectionError> {
        let points = parse_points(path, text, &MEASUREMENT_COLUMNS, |r, plan| {
            Ok(MeasuredPoint {
                plan,
                measured: [r.values[6], r.values[7], r.values[8]],
            })
        })?;
        Ok(Measurement { points })
    }

    /// Read a measurement CSV file (`id,x,y,z,i,j,k,mx,my,mz`).
    pub fn read(path: &Path) -> Result<Measurement, InspectionError> {
        Measurement::parse(path, &read_to_string(path)?)
    }

    /// Write the measurement atomically (6 decimals, as the blind examples).
    pub fn write(&self, path: &Path) -> Result<(), InspectionError> {
        let rows = self.points.iter().map(|m| {
            let p = &m.plan;
            (p.id.as_str(), [p.point, p.normal, m.measured].concat())
        });
        write_rows(path, "id,x,y,z,i,j,k,mx,my,mz", rows)
    }
}

/// A plan point probed again on the machine (a follow-up probe,
/// docs/diagnose.md "Follow-up"): at rotary angles `a`, `c` (degrees), at
/// `t_min` (minutes since the program's start); `id` is the probe's, the
/// point and normal are the plan point's.
#[derive(Clone, Debug, PartialEq)]
pub struct FollowupPoint {
    /// The plan point (id, point, normal).
    pub plan: PlanPoint,
    /// First rotary angle (in letter order, e.g. A on an A/C machine), degrees.
    pub a_deg: f64,
    /// Second rotary angle (e.g. C), degrees.
    pub c_deg: f64,
    /// When it is probed: minutes since the program's start.
    pub time_min: f64,
    /// The probed point (part coordinates, mm), in a follow-up measurement.
    pub measured: Option<[f64; 3]>,
}

impl FollowupPoint {
    /// The reading `(m − p)·n` in µm (0 without a measured point).
    pub fn reading_um(&self) -> f64 {
        self.measured.map_or(0.0, |m| {
            let p = &self.plan;
            (0..3)
                .map(|k| (m[k] - p.point[k]) * p.normal[k])
                .sum::<f64>()
                * 1000.0
        })
    }
}

/// A follow-up plan (`id,x,y,z,i,j,k,a,c,t_min`) or measurement (with
/// `mx,my,mz`): an extension of formats.md (docs/extensions.md). The two
/// angle columns are named by the machine's rotary letters (`a,c` on an A/C
/// machine, `b,c` on a B/C one); `a_deg`/`c_deg` hold the first and the
/// second of them in letter order.
#[derive(Clone, Debug, PartialEq)]
pub struct Followup {
    /// The points, in file order.
    pub points: Vec<FollowupPoint>,
    /// The machine's rotary axes, in letter order: the angle columns' names.
    pub rotary: [crate::axes::Axis; 2],
}

impl Default for Followup {
    fn default() -> Self {
        Followup {
            points: Vec::new(),
            rotary: [crate::axes::Axis::A, crate::axes::Axis::C],
        }
    }
}

/// Farthest a follow-up's probed point may lie from its plan point, mm: a
/// reading is the machine's error there (µm), not a different point.
pub const MAX_PROBE_OFFSET_MM: f64 = 1.0;

/// The columns of a follow-up plan or measurement after `id`, the angle
/// columns named by `rotary`.
fn followup_columns(rotary: [crate::axes::Axis; 2], measured: bool) -> Vec<String> {
    let mut columns: Vec<String> = ["x", "y", "z", "i", "j", "k"].map(String::from).to_vec();
    columns.extend(rotary.map(|a| a.letter().to_ascii_lowercase().to_string()));
    columns.push("t_min".into());
    if measured {
        columns.extend(["mx", "my", "mz"].map(String::from));
    }
    columns
}

impl Followup {
    fn parse_with(
        path: &Path,
        text: &str,
        measured: bool,
        rotary: [crate::axes::Axis; 2],
    ) -> Result<Followup, InspectionError> {
        let names = followup_columns(rotary, measured);
        let columns: Vec<&str> = names.iter().map(String::as_str).collect();
        let points = parse_points(path, text, &columns, |r, plan| {
            let f = FollowupPoint {
                plan,
                a_deg: r.values[6],
                c_deg: r.values[7],
                time_min: r.values[8],
                measured: measured.then(|| [r.values[9], r.values[10], r.values[11]]),
            };
            // What one field cannot show: a probe taken before the part
            // program started, a probed point that is not the plan point.
            let field = |column: &str, message: String| InspectionError::Field {
                path: path.to_path_buf(),
                line: r.line,
                column: column.into(),
                message,
            };
            if f.time_min < 0.0 {
                return Err(field(
                    "t_min",
                    format!(
                        "expected minutes since the part program's start (≥ 0), found {}",
                        f.time_min
                    ),
                ));
            }
            if let Some(m) = f.measured {
                let off = crate::vec3::dist(m, f.plan.point);
                if off > MAX_PROBE_OFFSET_MM {
                    return Err(field(
                        "mx,my,mz",
                        format!(
                            "the probed point ({}, {}, {}) is {off:.4} mm from the plan point; a follow-up probes the plan point again (within {MAX_PROBE_OFFSET_MM} mm)",
                            m[0], m[1], m[2]
                        ),
                    ));
                }
            }
            Ok(f)
        })?;
        Ok(Followup { points, rotary })
    }

    /// Parse a follow-up plan CSV (`id,x,y,z,i,j,k,a,c,t_min`; the angle
    /// columns named by the machine's `rotary` letters).
    pub fn parse_plan(
        path: &Path,
        text: &str,
        rotary: [crate::axes::Axis; 2],
    ) -> Result<Followup, InspectionError> {
        Followup::parse_with(path, text, false, rotary)
    }

    /// Parse a follow-up measurement CSV (the plan's columns and `mx,my,mz`).
    pub fn parse_measurement(
        path: &Path,
        text: &str,
        rotary: [crate::axes::Axis; 2],
    ) -> Result<Followup, InspectionError> {
        Followup::parse_with(path, text, true, rotary)
    }

    /// Read a follow-up plan file (`id,x,y,z,i,j,k,<r1>,<r2>,t_min`, angle columns named by `rotary`).
    pub fn read_plan(
        path: &Path,
        rotary: [crate::axes::Axis; 2],
    ) -> Result<Followup, InspectionError> {
        Followup::parse_plan(path, &read_to_string(path)?, rotary)
    }

    /// Read a follow-up measurement file (a follow-up plan with `mx,my,mz`).
    pub fn read_measurement(
        path: &Path,
        rotary: [crate::axes::Axis; 2],
    ) -> Result<Followup, InspectionError> {
        Followup::parse_measurement(path, &read_to_string(path)?, rotary)
    }

    /// Write the plan, or the measurement when every point has its measured
    /// point, atomically (6 decimals).
    pub fn write(&self, path: &Path) -> Result<(), InspectionError> {
        let measured = !self.points.is_empty() && self.points.iter().all(|p| p.measured.is_some());
        let rows = self.points.iter().map(|f| {
            let p = &f.plan;
            let mut v = [p.point, p.normal].concat();
            v.extend([f.a_deg, f.c_deg, f.time_min]);
            if let (true, Some(m)) = (measured, f.measured) {
                v.extend(m);
            }
            (p.id.as_str(), v)
        });
        let header = format!("id,{}", followup_columns(self.rotary, measured).join(","));
        write_rows(path, &header, rows)
    }
}

/// Comma-separated values with 6 decimals (never `-0.000000`).
fn fmt6(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| {
            let s = format!("{v:.6}");
            if s == "-0.000000" {
                "0.000000".into()
            } else {
                s
            }
        })
        .collect::<Vec<_>>()
        .join(",")
}
