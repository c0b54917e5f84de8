//! Which controller's language a program is written in (dialects.md "Which
//! dialect"), why it was read so, how its comments are written back, and the
//! one service a dialect front may need from the machine: turning a tool
//! axis into rotary joints ([`OrientationSolver`]).
//!
//! A dialect is a syntax and a language feeding the same motion seam
//! ([`super::Execution`]): every command reads `(Block, BlockEvent,
//! Executed)` whatever the dialect, so no command has per-dialect code.
use std::path::Path;

use crate::axes::Axes;

/// A controller language volcomp reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize)]
pub enum Dialect {
    /// LinuxCNC's RS274NGC (gcode.md): the default.
    #[default]
    LinuxCnc,
    /// Siemens SINUMERIK 840D sl, the native language (ISO mode off).
    Sinumerik,
    /// Heidenhain TNC Klartext.
    Heidenhain,
}

impl Dialect {
    /// Every dialect, in `--dialect` order.
    pub const ALL: [Dialect; 3] = [Dialect::LinuxCnc, Dialect::Sinumerik, Dialect::Heidenhain];

    /// Its name in messages ("LinuxCNC", "Sinumerik", "Heidenhain").
    pub fn name(self) -> &'static str {
        match self {
            Dialect::LinuxCnc => "LinuxCNC",
            Dialect::Sinumerik => "Sinumerik",
            Dialect::Heidenhain => "Heidenhain",
        }
    }

    /// Its `--dialect` value (`linuxcnc`, `sinumerik`, `heidenhain`).
    pub fn key(self) -> &'static str {
        match self {
            Dialect::LinuxCnc => "linuxcnc",
            Dialect::Sinumerik => "sinumerik",
            Dialect::Heidenhain => "heidenhain",
        }
    }

    /// The dialect of a `--dialect` value (any case).
    pub fn from_key(key: &str) -> Option<Dialect> {
        Dialect::ALL
            .into_iter()
            .find(|d| d.key().eq_ignore_ascii_case(key.trim()))
    }

    /// `text` as a whole-line or trailing comment of this dialect: `(text)`
    /// for LinuxCNC (parentheses in `text` become brackets), `; text` for
    /// Sinumerik and Heidenhain (whose comments run to the end of the line).
    pub fn comment(self, text: &str) -> String {
        match self {
            Dialect::LinuxCnc => format!("({})", text.replace('(', "[").replace(')', "]")),
            Dialect::Sinumerik | Dialect::Heidenhain => format!("; {text}"),
        }
    }
}

/// The dialect a program is read in and why (the summaries say both).
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct DialectChoice {
    /// The dialect.
    pub dialect: Dialect,
    /// Why, in words: `--dialect sinumerik`, `extension .MPF`, `first line
    /// %_N_PART_MPF`, `BEGIN PGM on the first block`, `default`.
    pub reason: String,
}

impl DialectChoice {
    /// `read as Sinumerik (extension .MPF)`.
    pub fn describe(&self) -> String {
        format!("read as {} ({})", self.dialect.name(), self.reason)
    }

    /// The choice `--dialect` made.
    pub fn given(dialect: Dialect) -> Self {
        DialectChoice {
            dialect,
            reason: format!("--dialect {}", dialect.key()),
        }
    }
}

impl Default for DialectChoice {
    fn default() -> Self {
        DialectChoice {
            dialect: Dialect::LinuxCnc,
            reason: "default".to_string(),
        }
    }
}

/// The dialect of a program named `path` whose text starts with `head`
/// (dialects.md "Which dialect"): `BEGIN PGM` on the first block (after an
/// optional block number) is Heidenhain; the extension `.mpf`/`.spf` (any
/// case) or a first line `%_N_…_MPF`/`…_SPF` is Sinumerik; anything else is
/// LinuxCNC. The first block is the first line that is not blank.
pub fn detect(path: &Path, head: &[u8]) -> DialectChoice {
    let first = head
        .split(|&b| b == b'\n')
        .map(|l| l.strip_suffix(b"\r").unwrap_or(l))
        .map(|l| l.trim_ascii())
        .find(|l| !l.is_empty())
        .unwrap_or(b"");
    let after_number = first
        .iter()
        .position(|b| !b.is_ascii_digit())
        .map_or(&first[first.len()..], |k| &first[k..])
        .trim_ascii_start();
    if after_number.len() >= 9 && after_number[..9].eq_ignore_ascii_case(b"BEGIN PGM") {
        return DialectChoice {
            dialect: Dialect::Heidenhain,
            reason: "BEGIN PGM on the first block".to_string(),
        };
    }
    if let Some(ext) = path.extension().and_then(|e| e.to_str())
        && (ext.eq_ignore_ascii_case("mpf") || ext.eq_ignore_ascii_case("spf"))
    {
        return DialectChoice {
            dialect: Dialect::Sinumerik,
            reason: format!("extension .{ext}"),
        };
    }
    let upper = first.to_ascii_uppercase();
    if upper.starts_with(b"%_N_") && (upper.ends_with(b"_MPF") || upper.ends_with(b"_SPF")) {
        return DialectChoice {
            dialect: Dialect::Sinumerik,
            reason: format!("first line {}", String::from_utf8_lossy(first)),
        };
    }
    DialectChoice::default()
}

/// Which of the (usually two) rotary solutions for one tool axis a control
/// takes (Sinumerik `CYCLE800`'s direction parameter, Heidenhain `SEQ+`/`SEQ-`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Branch {
    /// The solution nearest the previous joints (the control's default).
    #[default]
    Nearest,
    /// The solution whose first rotary axis (in the machine's letter order)
    /// is positive / the `+` direction.
    Plus,
    /// The solution whose first rotary axis is negative / the `-` direction.
    Minus,
}

/// Tool axis ↔ rotary joints, from the machine's chain: what a dialect front
/// needs for orientation vectors (`A3 B3 C3`, `LN … NX NY NZ`) and swivelled
/// planes (`CYCLE800`, `PLANE`). `gcode` knows no kinematics: the command
/// line builds one from the machine file and hands it in through
/// [`super::ProgramSetup::orientation`]; without one, a block that needs it
/// is a located error.
pub trait OrientationSolver: Send + Sync + std::fmt::Debug {
    /// The rotary joints (only the machine's rotary letters are set; the
    /// others are copied from `previous`) that point the tool along `axis`
    /// (a unit vector in the workpiece frame), on `branch`, nearest
    /// `previous` among equivalent turns; `None` when no joint position
    /// reaches that axis.
    fn joints_for_axis(&self, axis: [f64; 3], branch: Branch, previous: &Axes) -> Option<Axes>;

    /// The tool axis (unit, workpiece frame) at `joints`' rotary positions.
    fn axis_of(&self, joints: &Axes) -> [f64; 3];

    /// The rotation (row-major, workpiece frame) that the rotary joints at
    /// `joints` put between the workpiece and the tool: its columns are the
    /// machine's X, Y, Z directions as the tool carries them, seen from
    /// the workpiece (at home, the identity). A plane set by rotary axis
    /// positions (Sinumerik `CYCLE800` direct mode) is this frame.
    fn frame_of(&self, joints: &Axes) -> [[f64; 3]; 3];

    /// The machine's rotary axes in Siemens' swivel order (*SINUMERIK
    /// Operate commissioning*, CYCLE800 checklist: "rotary axis 2 is based
    /// on rotary axis 1; with mixed kinematics, rotary axis 1 is always
    /// the axis for the tool orientation"): the head's axes from the bed
    /// towards the spindle, then the table's from the bed towards the part.
    fn swivel_order(&self) -> [crate::axes::Axis; 2];
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn detection_follows_the_contract() {
        let d = |name: &str, text: &str| detect(Path::new(name), text.as_bytes());
        assert_eq!(d("a.MPF", "G1 X1").dialect, Dialect::Sinumerik);
        assert_eq!(
            d("a.MPF", "G1 X1").describe(),
            "read as Sinumerik (extension .MPF)"
        );
        assert_eq!(d("a.spf", "").dialect, Dialect::Sinumerik);
        assert_eq!(
            d("a.nc", "\n%_N_PART_MPF\r\nG1").dialect,
            Dialect::Sinumerik
        );
        assert_eq!(d("a.h", "0 BEGIN PGM X MM").dialect, Dialect::Heidenhain);
        assert_eq!(d("a.mpf", "BEGIN PGM X MM").dialect, Dialect::Heidenhain);
        assert_eq!(d("a.ngc", "G1 X1").dialect, Dialect::LinuxCnc);
        assert_eq!(d("a.ngc", "G1 X1").reason, "default");
        assert_eq!(Dialect::from_key("SINUMERIK"), Some(Dialect::Sinumerik));
        assert_eq!(
            Dialect::Sinumerik.comment("volcomp: line 3"),
            "; volcomp: line 3"
        );
        assert_eq!(Dialect::LinuxCnc.comment("a (b)"), "(a [b])");
    }
}
