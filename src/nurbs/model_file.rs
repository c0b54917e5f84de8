//! The fitted SMEM as a file (serde JSON): the `volcomp fit --report` format
//! (formats.md: `{"parameters": [{"axis", "parameter", "samples",
//! "control_points", "method", "emax", "erms", "knots", "weights", "seconds"}]}`)
//! plus what is needed to rebuild each curve exactly (degree, control points) and
//! to tie it to its data (the FNV-1a 64 hash of the table file, hex).
use serde::{Deserialize, Serialize};

use super::curve::NurbsCurve;
use super::smem::{FitStats, SmemCurve};

/// The `volcomp fit --report` file: every fitted error parameter of a machine.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SmemModelFile {
    /// One entry per fitted parameter (table column).
    pub parameters: Vec<ParameterFit>,
    /// Parameters of the tables that were not measured (taken as zero).
    #[serde(default)]
    pub not_measured: Vec<String>,
}

/// One fitted error parameter: the fit statistics (flattened: `samples`,
/// `control_points`, `method`, `emax`, `erms`, `tolerance`, `met`, `seconds`, …)
/// and the curve.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParameterFit {
    /// Axis letter of the table ("X", …, "C").
    pub axis: String,
    /// Parameter name, e.g. "EXX".
    pub parameter: String,
    /// "um" or "urad" (the unit of `emax`, `erms`, `tolerance`).
    pub unit: String,
    /// The fit statistics (Emax, Erms, method, control points, …), flattened into this object.
    #[serde(flatten)]
    pub stats: FitStats,
    /// Degree of the curve.
    pub degree: usize,
    /// Clamped knot vector of the curve.
    pub knots: Vec<f64>,
    /// Weight of each control point.
    pub weights: Vec<f64>,
    /// Control points `(position, value)` in table units.
    pub points: Vec<[f64; 2]>,
    /// The table file and the FNV-1a 64 hash of its bytes (16 hex digits).
    pub table: String,
    /// The FNV-1a 64 hash of the table file's bytes, 16 hex digits.
    pub table_hash: String,
    /// `(position, standard uncertainty)` of the curve at the table's positions
    /// (extension; absent in files written before it).
    #[serde(default)]
    pub uncertainty: Vec<[f64; 2]>,
    /// FNV-1a 64 of the table's hash and the curve's numbers (degree, knots,
    /// weights, control points, uncertainty, as f64 bits), 16 hex digits: a
    /// curve edited after the fit does not match it. Empty in files written
    /// before it (their curves are checked against the table only).
    #[serde(default)]
    pub curve_hash: String,
}

impl ParameterFit {
    /// The entry for `curve`, fitted to column `parameter` of the table of axis `axis` (file `table`, whose bytes hash to `table_hash`).
    pub fn new(
        axis: char,
        parameter: &str,
        unit: &str,
        curve: &SmemCurve,
        table: &str,
        table_hash: u64,
    ) -> ParameterFit {
        ParameterFit {
            axis: axis.to_string(),
            parameter: parameter.to_string(),
            unit: unit.to_string(),
            stats: curve.stats().clone(),
            degree: curve.degree(),
            knots: curve.knots().to_vec(),
            weights: curve.weights().to_vec(),
            points: curve.control_points().to_vec(),
            table: table.to_string(),
            table_hash: format!("{table_hash:016x}"),
            uncertainty: curve.uncertainty().to_vec(),
            curve_hash: String::new(),
        }
        .with_curve_hash()
    }

    /// The same with [`ParameterFit::curve_hash`] set to its numbers' hash.
    fn with_curve_hash(mut self) -> ParameterFit {
        self.curve_hash = format!("{:016x}", self.computed_curve_hash());
        self
    }

    /// FNV-1a 64 of `table_hash` and the curve's numbers (what `curve_hash`
    /// must hold).
    pub fn computed_curve_hash(&self) -> u64 {
        let mut bytes = Vec::with_capacity(
            24 + 8 * (self.knots.len() + self.weights.len())
                + 16 * (self.points.len() + self.uncertainty.len()),
        );
        bytes.extend_from_slice(self.table_hash.as_bytes());
        bytes.extend_from_slice(&(self.degree as u64).to_le_bytes());
        let numbers = self
            .knots
            .iter()
            .chain(&self.weights)
            .chain(self.points.iter().flatten())
            .chain(self.uncertainty.iter().flatten());
        for v in numbers {
            bytes.extend_from_slice(&v.to_bits().to_le_bytes());
        }
        fnv1a64(&bytes)
    }

    /// Rebuild the curve (validated; `x(u)` must be increasing).
    pub fn to_curve(&self) -> Result<SmemCurve, String> {
        let curve = NurbsCurve::new(
            self.degree,
            self.knots.clone(),
            self.weights.clone(),
            self.points.clone(),
        )
        .map_err(|e| e.to_string())?;
        let mut curve =
            SmemCurve::from_curve(curve, self.stats.clone()).map_err(|e| e.to_string())?;
        curve.set_uncertainty(self.uncertainty.clone())?;
        Ok(curve)
    }
}

/// FNV-1a, 64 bits.
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Issue 23: an edited curve no longer matches its hash.
    #[test]
    fn the_curve_hash_covers_every_number_of_the_curve() {
        let fit = ParameterFit {
            axis: "X".into(),
            parameter: "EXX".into(),
            unit: "um".into(),
            stats: serde_json::from_str(
                r#"{"samples":4,"control_points":4,"method":"best","emax":0.1,"erms":0.05,"tolerance":0.5,"met":true,"grid_segments":null,"evaluations":1,"seconds":0.0}"#,
            )
            .unwrap(),
            degree: 3,
            knots: vec![0.0, 0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0],
            weights: vec![1.0; 4],
            points: vec![[0.0, 1.0], [1.0, 2.0], [2.0, 2.5], [3.0, 1.0]],
            table: "x.csv".into(),
            table_hash: "0123456789abcdef".into(),
            uncertainty: vec![],
            curve_hash: String::new(),
        }
        .with_curve_hash();
        assert_eq!(
            fit.curve_hash,
            format!("{:016x}", fit.computed_curve_hash())
        );
        let mut edited = fit.clone();
        edited.points[2][1] = 499.0;
        assert_ne!(edited.computed_curve_hash(), fit.computed_curve_hash());
        let mut edited = fit.clone();
        edited.weights[1] = 1.0 + 1e-15;
        assert_ne!(edited.computed_curve_hash(), fit.computed_curve_hash());
        // Through JSON and back, exactly.
        let back: ParameterFit =
            serde_json::from_str(&serde_json::to_string(&fit).unwrap()).unwrap();
        assert_eq!(back.computed_curve_hash(), fit.computed_curve_hash());
    }

    #[test]
    fn fnv_reference_values() {
        assert_eq!(fnv1a64(b""), 0xcbf29ce484222325);
        assert_eq!(fnv1a64(b"a"), 0xaf63dc4c8601ec8c);
    }
}
