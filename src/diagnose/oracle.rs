//! The oracle cases (issue 36): measurements made by an independent
//! implementation of effects.md and kinematics.md, not by volcomp's own
//! generator, read from their folder and scored exactly as their README says.
//!
//! A folder holds `index.json` (case, part, machine, noise, effects), one
//! sub-folder per case (`measured.csv`, the plan with the measured points),
//! the parts (`parts/*.nc`) and the wrong model (`machines/x1.4.toml`) of the
//! `w*` cases; the right machine (ref-trt) is given by the caller.
//!
//! Scores (README "what a good diagnosis says"):
//! - `s*` (one effect): that effect first (`selected[0]`);
//! - `l*` (servo lag, strong at few points): `servo_lag` selected;
//! - `n*` (no effect): nothing selected and no model verdict;
//! - `p*` (two effects): both selected;
//! - `w*` (a wrong model, with an effect or none): the model verdict, and the
//!   effect beside it (selected, or named as an alias of a selected effect:
//!   the pair the data cannot tell apart); with no effect, the verdict alone.
//!
//! Only the tests, benches and examples use it (`testkit`).
use super::effects::{Effect, EffectKind};
use super::{DiagnoseOptions, DiagnoseReport, diagnose};
use crate::machine::{ErrorModel, Machine, ModelOptions};
use crate::toolpath::PointContext;
use std::path::{Path, PathBuf};

/// The kind of an oracle case (its name's first letter).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum OracleGroup {
    /// `s*`: one effect, 4–7 µm peak.
    Single,
    /// `l*`: servo lag, a few µm where the path turns.
    ServoLag,
    /// `n*`: no effect.
    NoEffect,
    /// `p*`: two effects.
    Pair,
    /// `w*`: a wrong model (tables 1.4 × the truth), with an effect or none.
    WrongModel,
}

/// One case of `index.json`.
#[derive(Clone, Debug)]
pub struct OracleCase {
    /// Its name (and folder).
    pub name: String,
    /// Its group.
    pub group: OracleGroup,
    /// The program that cut the part (`parts/…`, relative to the folder).
    pub part: String,
    /// The injected probing noise, µm.
    pub noise_um: f64,
    /// The injected effects (catalogue names).
    pub effects: Vec<String>,
}

/// The outcome of one case.
#[derive(Clone, Debug)]
pub struct OracleScore {
    /// The diagnosis says what the README asks of the case.
    pub pass: bool,
    /// What it said, in a few words (selection, verdict, aliases).
    pub said: String,
}

/// Why a folder of oracle cases cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum OracleError {
    /// A file cannot be read or parsed.
    #[error("{path}: {message}")]
    File {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
}

fn file_error(path: &Path, message: impl ToString) -> OracleError {
    OracleError::File {
        path: path.to_path_buf(),
        message: message.to_string(),
    }
}

/// The cases of `root/index.json`, in file order.
pub fn read_index(root: &Path) -> Result<Vec<OracleCase>, OracleError> {
    let path = root.join("index.json");
    let text = std::fs::read_to_string(&path).map_err(|e| file_error(&path, e))?;
    let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| file_error(&path, e))?;
    let list = value
        .as_array()
        .ok_or_else(|| file_error(&path, "expected a list of cases"))?;
    list.iter()
        .map(|c| {
            let text_of = |key: &str| {
                c[key]
                    .as_str()
                    .map(str::to_string)
                    .ok_or_else(|| file_error(&path, format!("a case without `{key}`")))
            };
            let name = text_of("case")?;
            let group = match name.chars().next() {
                Some('s') => OracleGroup::Single,
                Some('l') => OracleGroup::ServoLag,
                Some('n') => OracleGroup::NoEffect,
                Some('p') => OracleGroup::Pair,
                Some('w') => OracleGroup::WrongModel,
                _ => return Err(file_error(&path, format!("case `{name}`: unknown group"))),
            };
            let effects = c["effects"]
                .as_array()
                .map(|a| {
                    a.iter()
                        .filter_map(|e| e.as_str().map(str::to_string))
                        .collect()
                })
                .unwrap_or_default();
            Ok(OracleCase {
                group,
                part: text_of("part")?,
                noise_um: c["noise_um"].as_f64().unwrap_or(f64::NAN),
                effects,
                name,
            })
        })
        .collect()
}

/// The effects a case injected, with their values (`truth.json` of the
/// case's folder).
pub fn truth_effects(case_dir: &Path) -> Result<Vec<Effect>, OracleError> {
    let path = case_dir.join("truth.json");
    let text = std::fs::read_to_string(&path).map_err(|e| file_error(&path, e))?;
    let value: serde_json::Value = serde_json::from_str(&text).map_err(|e| file_error(&path, e))?;
    let list = value["effects"]
        .as_array()
        .ok_or_else(|| file_error(&path, "expected a list `effects`"))?;
    list.iter()
        .map(|e| {
            let name = e["name"]
                .as_str()
                .ok_or_else(|| file_error(&path, "an effect without `name`"))?;
            let kind = EffectKind::from_name(name)
                .ok_or_else(|| file_error(&path, format!("`{name}` is not in the catalogue")))?;
            let params = e["params"]
                .as_object()
                .ok_or_else(|| file_error(&path, format!("`{name}` without `params`")))?;
            let pairs: Vec<(&str, f64)> = params
                .iter()
                .map(|(k, v)| {
                    v.as_f64()
                        .map(|v| (k.as_str(), v))
                        .ok_or_else(|| file_error(&path, format!("`{name}.{k}` is not a number")))
                })
                .collect::<Result<_, _>>()?;
            Effect::from_pairs(kind, &pairs).map_err(|e| file_error(&path, e))
        })
        .collect()
}

/// RMS over the cut points of what `truth`, as volcomp's catalogue computes
/// it, leaves of a measurement beyond the contexts' prediction, µm: the noise,
/// when the two generators agree.
pub fn truth_residual_rms(contexts: &[PointContext], measured_um: &[f64], truth: &[Effect]) -> f64 {
    let left: Vec<f64> = contexts
        .iter()
        .zip(measured_um)
        .filter(|(c, _)| c.cut)
        .map(|(c, m)| m - c.predicted_um - truth.iter().map(|e| e.deviation_um(c)).sum::<f64>())
        .collect();
    crate::diagnose::noise::rms(&left)
}

/// A machine and its error model, fitted once for many cases.
pub struct OracleMachine {
    /// The machine file.
    pub machine: Machine,
    /// Its error model.
    pub model: ErrorModel,
}

impl OracleMachine {
    /// Load the machine file at `path` and fit its tables.
    pub fn load(path: &Path) -> Result<OracleMachine, OracleError> {
        let machine = Machine::load(path).map_err(|e| file_error(path, e))?;
        let model = ErrorModel::from_machine(&machine, &ModelOptions::default())
            .map_err(|e| file_error(path, e))?;
        Ok(OracleMachine { machine, model })
    }

    /// The contexts of a case's plan (as `diagnose` builds them on this
    /// machine) and its measured deviations, µm.
    pub fn case_inputs(
        &self,
        root: &Path,
        case: &OracleCase,
    ) -> Result<(Vec<PointContext>, Vec<f64>), OracleError> {
        let measured_path = root.join(&case.name).join("measured.csv");
        let measurement = crate::inspection::Measurement::read(&measured_path)
            .map_err(|e| file_error(&measured_path, e))?;
        let program_path = root.join(&case.part);
        let file = std::fs::File::open(&program_path).map_err(|e| file_error(&program_path, e))?;
        let setup = crate::gcode::ProgramSetup {
            require_program_end: true,
            tools: self.machine.tools.clone(),
            ..Default::default()
        };
        let program = crate::gcode::Program::new(
            Box::new(std::io::BufReader::new(file)),
            &program_path,
            setup,
        );
        let options =
            crate::toolpath::CutOptions::for_machine(&self.machine, crate::gcode::Frame::Joint);
        let plan = measurement.plan();
        let (matches, _) =
            crate::toolpath::cut::match_plan(program, &self.model, &plan.points, &options)
                .map_err(|e| file_error(&program_path, e))?;
        let contexts = crate::toolpath::cut::contexts(&self.model, &plan.points, &matches)
            .map_err(|e| file_error(&program_path, e))?;
        Ok((contexts, measurement.deviations_um()))
    }
}

/// Diagnose a case with the default options.
pub fn diagnose_case(
    machine: &OracleMachine,
    root: &Path,
    case: &OracleCase,
) -> Result<DiagnoseReport, OracleError> {
    let (contexts, measured) = machine.case_inputs(root, case)?;
    diagnose(&contexts, &measured, &DiagnoseOptions::default())
        .map_err(|e| file_error(&root.join(&case.name), e))
}

/// Score a case's diagnosis as the README says (module doc).
pub fn score(case: &OracleCase, report: &DiagnoseReport) -> OracleScore {
    let selected = &report.selected;
    let verdict = report.model_check.mismatch;
    let has = |name: &str| selected.iter().any(|s| s == name);
    // An effect named as an alias of a selected effect: the pair the data
    // cannot tell apart.
    let named_as_alias = |name: &str| {
        report
            .effects
            .iter()
            .filter(|e| has(&e.name))
            .any(|e| e.aliases.iter().any(|a| a == name))
    };
    let pass = match case.group {
        OracleGroup::Single => selected.first() == case.effects.first(),
        OracleGroup::ServoLag => has("servo_lag"),
        OracleGroup::NoEffect => selected.is_empty() && !verdict,
        OracleGroup::Pair => case.effects.iter().all(|e| has(e)),
        OracleGroup::WrongModel => {
            verdict
                && match case.effects.first() {
                    None => selected.is_empty(),
                    Some(e) => has(e) || named_as_alias(e),
                }
        }
    };
    let aliases: Vec<String> = report
        .effects
        .iter()
        .filter(|e| has(&e.name) && !e.aliases.is_empty())
        .map(|e| format!("{}~{}", e.name, e.aliases.join("~")))
        .collect();
    let said = format!(
        "{}{}{}",
        if selected.is_empty() {
            "nothing".to_string()
        } else {
            selected.join(" + ")
        },
        if verdict { " + model verdict" } else { "" },
        if aliases.is_empty() {
            String::new()
        } else {
            format!(" (aliases {})", aliases.join(", "))
        }
    );
    OracleScore { pass, said }
}
