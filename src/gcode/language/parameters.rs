//! The parameter table of RS274NGC, as LinuxCNC keeps it.
//!
//! - Numbered parameters `#1`–`#5601` (LinuxCNC's `RS274NGC_MAX_PARAMETERS` is
//!   5602); all exist and start at 0 (or the value a `.var` file gives). `#1`–`#30`
//!   are a subroutine's arguments: saved on call, restored on return.
//! - Named parameters: `#<name>` is local to the call level that set it,
//!   `#<_name>` is global. Reading one that was never set is an error.
//! - Predefined read-only names (`#<_x>`, `#<_metric>`, `#<_coord_system>`, …)
//!   are computed from [`SystemState`], which the machine-state layer updates.
//! - The machine-state layer keeps the work origins, G92 offsets and stored
//!   positions here, at LinuxCNC's numbers ([`numbers`]), exactly as LinuxCNC does
//!   (a program may read and write them).
//!
//! Invariant: no value is ever NaN or infinite (assignments are checked by the
//! evaluator; `.var` values by their reader).
use std::collections::HashMap;

use crate::gcode::syntax::expression::{EvalErrorKind, ParamSource};

/// LinuxCNC's `RS274NGC_MAX_PARAMETERS`: numbers run from 1 to this − 1.
pub const MAX_PARAMETERS: usize = 5602;

/// The numbers of LinuxCNC's system parameters (axis order X Y Z A B C U V W).
pub mod numbers {
    /// Where the last probing move (G38.x) stopped, X at 5061 … W at 5069
    /// (program coordinates and units).
    pub const PROBE_POSITION: usize = 5061;
    /// 1 when the last probing move tripped the probe.
    pub const PROBE_TRIPPED: usize = 5070;
    /// G28 stored position, X at 5161 … W at 5169.
    pub const G28_POSITION: usize = 5161;
    /// G30 stored position, 5181 … 5189.
    pub const G30_POSITION: usize = 5181;
    /// 1 when G92 offsets are applied.
    pub const G92_ENABLED: usize = 5210;
    /// G92 offsets, 5211 … 5219.
    pub const G92_OFFSET: usize = 5211;
    /// The active coordinate system, 1 (G54) … 9 (G59.3).
    pub const COORD_SYSTEM: usize = 5220;
    /// Origin of coordinate system `n` (1-based): `COORD_BASE + 20 (n − 1)`, X … W, then R (XY rotation).
    pub const COORD_BASE: usize = 5221;
    /// The tool in the spindle.
    pub const TOOL: usize = 5400;
    /// The current position in the program's coordinate system, 5420 … 5428.
    pub const POSITION: usize = 5420;
    /// Read-only parameters (writing one is an error).
    pub const READ_ONLY: [usize; 32] = [
        5021, 5022, 5023, 5024, 5025, 5026, 5027, 5028, 5029, 5400, 5401, 5402, 5403, 5404, 5405,
        5406, 5407, 5408, 5409, 5410, 5411, 5412, 5413, 5420, 5421, 5422, 5423, 5424, 5425, 5426,
        5427, 5428,
    ];

    /// The parameter of coordinate system `n` (1 = G54 … 9 = G59.3), axis `axis` (0 = X … 8 = W, 9 = R).
    pub fn coord(n: usize, axis: usize) -> usize {
        COORD_BASE + 20 * (n - 1) + axis
    }
}

/// The machine state that predefined named parameters report, updated by the
/// machine-state layer after every block.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SystemState {
    /// Current position, program coordinates (X Y Z A B C U V W), program units.
    pub position: [f64; 9],
    /// Current position, machine coordinates (offsets applied), program units.
    pub absolute: [f64; 9],
    /// The sequence (line) number being executed.
    pub line: f64,
    /// `_motion_mode`: 0, 10, 20, 30, 800, 810 …
    pub motion_mode: f64,
    /// `_plane`: 170, 180, 190.
    pub plane: f64,
    /// `_ccomp`: 400, 410, 420.
    pub cutter_comp: f64,
    pub metric: bool,
    pub incremental: bool,
    pub inverse_time: bool,
    /// `_coord_system`: 540, 550, … 590, 591, 592, 593.
    pub coord_system: f64,
    pub tool_offset: bool,
    /// G99 (retract to R) active.
    pub retract_r_plane: bool,
    pub ijk_absolute: bool,
    pub feed: f64,
    pub rpm: f64,
    pub spindle_on: bool,
    pub spindle_cw: bool,
    pub mist: bool,
    pub flood: bool,
    pub current_tool: f64,
    pub selected_tool: f64,
}

/// The whole table.
#[derive(Clone, Debug)]
pub struct Parameters {
    numbered: Box<[f64]>,
    globals: HashMap<String, f64>,
    /// Named locals, one table per call level (index 0: the main program).
    locals: Vec<HashMap<String, f64>>,
    /// The last value returned by a subroutine (`#<_value>`), and whether one was.
    pub returned: Option<f64>,
    /// The machine state the predefined named parameters (`#<_x>`, …) report,
    /// written by the machine-state layer only, so that it cannot drift from
    /// the interpreter's state (a program reads it through the names).
    system: SystemState,
}

impl Default for Parameters {
    fn default() -> Self {
        Parameters::new()
    }
}

impl Parameters {
    /// LinuxCNC's start: every numbered parameter 0 but #5220 (coordinate
    /// system 1, G54), no named parameter set, the modal state of a fresh
    /// start (G21 G17 G40 G54).
    pub fn new() -> Self {
        let mut p = Parameters {
            numbered: vec![0.0; MAX_PARAMETERS].into_boxed_slice(),
            globals: HashMap::new(),
            locals: vec![HashMap::new()],
            returned: None,
            system: SystemState::default(),
        };
        p.numbered[numbers::COORD_SYSTEM] = 1.0;
        p.system.metric = true;
        p.system.motion_mode = 0.0;
        p.system.plane = 170.0;
        p.system.cutter_comp = 400.0;
        p.system.coord_system = 540.0;
        p.system.selected_tool = 0.0;
        p
    }

    /// Whether `n` is a parameter number (1 … 5601).
    pub fn in_range(n: i64) -> bool {
        n >= 1 && (n as usize) < MAX_PARAMETERS
    }

    /// Numbered parameter `n`, 0 when out of range.
    pub fn get(&self, n: usize) -> f64 {
        self.numbered.get(n).copied().unwrap_or(0.0)
    }

    /// Set numbered parameter `n` (no read-only check: the machine-state layer
    /// writes system values through this).
    pub fn set(&mut self, n: usize, value: f64) {
        if let Some(slot) = self.numbered.get_mut(n) {
            *slot = value;
        }
    }

    /// Set a numbered parameter from the program: range and read-only checked.
    pub fn assign_numbered(&mut self, n: i64, value: f64) -> Result<(), EvalErrorKind> {
        if !Parameters::in_range(n) {
            return Err(EvalErrorKind::ParameterOutOfRange);
        }
        if numbers::READ_ONLY.contains(&(n as usize)) {
            return Err(EvalErrorKind::ReadOnly(n));
        }
        self.numbered[n as usize] = value;
        Ok(())
    }

    /// Set a named parameter from the program (`_name` global, else local to the
    /// current call level). Predefined names are read-only.
    pub fn assign_named(&mut self, name: &str, value: f64) -> Result<(), EvalErrorKind> {
        if name.starts_with('_') {
            if self.predefined(name).is_some() {
                return Err(EvalErrorKind::ReadOnlyNamed(name.to_string()));
            }
            self.globals.insert(name.to_string(), value);
        } else if let Some(level) = self.locals.last_mut() {
            level.insert(name.to_string(), value);
        }
        Ok(())
    }

    /// Enter a subroutine: save `#1`–`#30`, set them from `args` (zeros after),
    /// open a new local scope. Returns the saved values for [`Parameters::leave`].
    pub fn enter(&mut self, args: &[f64]) -> [f64; 30] {
        let mut saved = [0.0; 30];
        saved.copy_from_slice(&self.numbered[1..31]);
        for i in 0..30 {
            self.numbered[1 + i] = args.get(i).copied().unwrap_or(0.0);
        }
        self.locals.push(HashMap::new());
        saved
    }

    /// Leave a subroutine: restore `#1`–`#30`, drop its locals.
    pub fn leave(&mut self, saved: &[f64; 30]) {
        self.numbered[1..31].copy_from_slice(saved);
        if self.locals.len() > 1 {
            self.locals.pop();
        }
    }

    /// The call depth (0 in the main program).
    pub fn call_level(&self) -> usize {
        self.locals.len() - 1
    }

    /// The machine state the predefined named parameters report, for the
    /// machine-state layer to update after every block.
    pub(crate) fn system_mut(&mut self) -> &mut SystemState {
        &mut self.system
    }

    /// Set the line being executed (`#<_line>`, LinuxCNC's sequence number).
    pub(crate) fn set_line(&mut self, line: usize) {
        self.system.line = line as f64;
    }

    /// Write the current position (program coordinates, program units) to
    /// #5420–#5428 and the predefined names.
    pub fn set_position(&mut self, position: [f64; 9], absolute: [f64; 9]) {
        self.numbered[numbers::POSITION..numbers::POSITION + 9].copy_from_slice(&position);
        self.system.position = position;
        self.system.absolute = absolute;
    }

    fn predefined(&self, name: &str) -> Option<f64> {
        let s = &self.system;
        let b = |v: bool| f64::from(v as u8);
        let axis = |n: &str| -> Option<usize> {
            ["x", "y", "z", "a", "b", "c", "u", "v", "w"]
                .iter()
                .position(|a| *a == n)
        };
        Some(match name {
            "_line" => s.line,
            "_motion_mode" => s.motion_mode,
            "_plane" => s.plane,
            "_ccomp" => s.cutter_comp,
            "_metric" => b(s.metric),
            "_imperial" => b(!s.metric),
            "_absolute" => b(!s.incremental),
            "_incremental" => b(s.incremental),
            "_inverse_time" => b(s.inverse_time),
            "_units_per_minute" => b(!s.inverse_time),
            "_units_per_rev" => 0.0,
            "_coord_system" => s.coord_system,
            "_tool_offset" => b(s.tool_offset),
            "_retract_r_plane" => b(s.retract_r_plane),
            "_retract_old_z" => b(!s.retract_r_plane),
            "_spindle_rpm_mode" => 1.0,
            "_spindle_css_mode" => 0.0,
            "_ijk_absolute_mode" => b(s.ijk_absolute),
            "_lathe_diameter_mode" => 0.0,
            "_lathe_radius_mode" => 1.0,
            "_spindle_on" => b(s.spindle_on),
            "_spindle_cw" => b(s.spindle_cw),
            "_mist" => b(s.mist),
            "_flood" => b(s.flood),
            "_speed_override" | "_feed_override" | "_adaptive_feed" | "_feed_hold" => 0.0,
            "_feed" => s.feed,
            "_rpm" => s.rpm,
            "_current_tool" => s.current_tool,
            "_current_pocket" => s.current_tool,
            "_selected_pocket" | "_selected_tool" => s.selected_tool,
            "_value" => self.returned.unwrap_or(0.0),
            "_value_returned" => b(self.returned.is_some()),
            // rs274 runs without the task: 0, as LinuxCNC's standalone interpreter.
            "_task" => 0.0,
            "_call_level" => self.call_level() as f64,
            "_remap_level" => 0.0,
            // LinuxCNC's version, as the reference rs274 (2.9) reports it.
            "_vmajor" => 2.9,
            "_vminor" => 0.0,
            _ => {
                if let Some(a) = name.strip_prefix("_abs_").and_then(axis) {
                    s.absolute[a]
                } else if let Some(a) = name.strip_prefix('_').and_then(axis) {
                    s.position[a]
                } else {
                    return None;
                }
            }
        })
    }
}

impl ParamSource for Parameters {
    fn numbered(&self, n: i64) -> Result<f64, EvalErrorKind> {
        if !Parameters::in_range(n) {
            return Err(EvalErrorKind::ParameterOutOfRange);
        }
        Ok(self.numbered[n as usize])
    }

    fn named(&self, name: &str) -> Option<f64> {
        if name.starts_with('_') {
            self.predefined(name)
                .or_else(|| self.globals.get(name).copied())
        } else {
            self.locals.last().and_then(|l| l.get(name).copied())
        }
    }
}

/// Why a `.var` file could not be read.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum VarFileError {
    #[error("line {line}: expected `NUMBER VALUE` (a LinuxCNC .var line), found `{text}`")]
    Malformed { line: usize, text: String },
    #[error("line {line}: parameter number {number} is outside 1…5601")]
    OutOfRange { line: usize, number: String },
    #[error("line {line}: the value `{text}` is not a finite number")]
    BadValue { line: usize, text: String },
    #[error("line {line}: parameter {number} is given twice (first on line {first})")]
    Duplicate {
        line: usize,
        number: usize,
        first: usize,
    },
}

impl VarFileError {
    pub fn line(&self) -> usize {
        match self {
            VarFileError::Malformed { line, .. }
            | VarFileError::OutOfRange { line, .. }
            | VarFileError::BadValue { line, .. }
            | VarFileError::Duplicate { line, .. } => *line,
        }
    }
}

/// Read a LinuxCNC parameter file (`.var`): one `NUMBER VALUE` pair per line,
/// blank lines allowed, anything after the value ignored (LinuxCNC reads two
/// numbers per line with `sscanf`). Returns the pairs in file order.
pub fn parse_var_file(text: &str) -> Result<Vec<(usize, f64)>, VarFileError> {
    let mut out: Vec<(usize, f64)> = Vec::new();
    let mut first_line: HashMap<usize, usize> = HashMap::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        // What the messages echo is cut (a long line, a long cell).
        let cut = |s: &str| crate::io::echo(s).into_owned();
        if raw.len() > crate::io::MAX_LINE_BYTES {
            return Err(VarFileError::Malformed {
                line,
                text: format!(
                    "{} (longer than {} bytes)",
                    cut(raw),
                    crate::io::MAX_LINE_BYTES
                ),
            });
        }
        let mut fields = raw.split_whitespace();
        let Some(number) = fields.next() else {
            continue;
        };
        let Some(value) = fields.next() else {
            return Err(VarFileError::Malformed {
                line,
                text: cut(raw.trim()),
            });
        };
        let n: usize = match number.parse() {
            Ok(n) if (1..MAX_PARAMETERS).contains(&n) => n,
            Ok(_) => {
                return Err(VarFileError::OutOfRange {
                    line,
                    number: cut(number),
                });
            }
            Err(_) => {
                return Err(VarFileError::Malformed {
                    line,
                    text: cut(raw.trim()),
                });
            }
        };
        let v: f64 = match value.parse() {
            Ok(v) if f64::is_finite(v) => v,
            _ => {
                return Err(VarFileError::BadValue {
                    line,
                    text: cut(value),
                });
            }
        };
        if let Some(first) = first_line.insert(n, line) {
            return Err(VarFileError::Duplicate {
                line,
                number: n,
                first,
            });
        }
        out.push((n, v));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scopes_and_call_arguments() {
        let mut p = Parameters::new();
        p.assign_numbered(1, 5.0).unwrap();
        p.assign_named("depth", 2.0).unwrap();
        p.assign_named("_global", 3.0).unwrap();
        let saved = p.enter(&[7.0, 8.0]);
        assert_eq!(p.numbered(1), Ok(7.0));
        assert_eq!(p.numbered(3), Ok(0.0));
        assert_eq!(p.named("depth"), None);
        assert_eq!(p.named("_global"), Some(3.0));
        assert_eq!(p.named("_call_level"), Some(1.0));
        p.assign_named("depth", 9.0).unwrap();
        p.leave(&saved);
        assert_eq!(p.numbered(1), Ok(5.0));
        assert_eq!(p.named("depth"), Some(2.0));
        assert_eq!(
            p.assign_numbered(5420, 1.0),
            Err(EvalErrorKind::ReadOnly(5420))
        );
        assert!(p.assign_named("_x", 1.0).is_err());
        assert_eq!(p.numbered(5602), Err(EvalErrorKind::ParameterOutOfRange));
    }

    #[test]
    fn var_files() {
        let pairs = parse_var_file("5221\t10.5\n\n5222 -2\n").unwrap();
        assert_eq!(pairs, vec![(5221, 10.5), (5222, -2.0)]);
        assert_eq!(parse_var_file("5221 x").unwrap_err().line(), 1);
        assert!(matches!(
            parse_var_file("1 1\n1 2").unwrap_err(),
            VarFileError::Duplicate { first: 1, .. }
        ));
        assert!(matches!(
            parse_var_file("9999 1").unwrap_err(),
            VarFileError::OutOfRange { .. }
        ));
    }
}
