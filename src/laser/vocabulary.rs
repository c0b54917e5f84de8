//! The words laser software writes in its exports: column names (English and
//! German), directions of approach, units of targets and deviations, and the
//! run columns of the wide layout. Pure functions of a cell's text; the reader
//! (`read`) decides what a file is from them.
use crate::axes::Axis;

/// What a header cell is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Role {
    Target,
    Run,
    Direction,
    /// The deviation of the long layout.
    Deviation,
    /// A paired layout's deviation of one approach.
    Approach(bool),
    /// A wide layout's run and approach.
    RunApproach(u32, bool),
    /// Not a reading (environment, comments, actual position, …): kept by name.
    Other,
}

impl Role {
    /// What the role holds, for messages.
    pub(crate) fn describe(self) -> String {
        match self {
            Role::Target => "target".into(),
            Role::Run => "run".into(),
            Role::Direction => "direction".into(),
            Role::Deviation => "deviation".into(),
            Role::Approach(up) => format!("deviation approached {}", sign(up)),
            Role::RunApproach(run, up) => format!("run {run} {}", sign(up)),
            Role::Other => "other".into(),
        }
    }
}

fn sign(up: bool) -> &'static str {
    if up { "+" } else { "-" }
}

/// Lowercase, with `µ`/`μ` as `u` (Unicode lowercase: `RÜCK` → `rück`).
fn fold(text: &str) -> String {
    text.trim().to_lowercase().replace(['μ', 'µ'], "u")
}

/// A direction of approach, as laser software writes it: `+ -`, `up down`,
/// `fwd rev`, `forward reverse`, `↑ ↓`, German `vorwärts rückwärts`,
/// `hin rück`, `auf ab`.
pub fn parse_direction(text: &str) -> Option<bool> {
    match text {
        "+" => return Some(true),
        "-" => return Some(false),
        _ => {}
    }
    match fold(text).as_str() {
        "+" | "up" | "fwd" | "forward" | "pos" | "positive" | "↑" | "vorwärts" | "vorwaerts"
        | "vorw" | "vorw." | "hin" | "hinlauf" | "hinweg" | "auf" | "aufwärts" | "aufwaerts"
        | "positiv" => Some(true),
        "-" | "−" | "down" | "rev" | "reverse" | "bwd" | "backward" | "neg" | "negative" | "↓"
        | "rückwärts" | "rueckwaerts" | "rückw" | "rückw." | "rück" | "rueck" | "zurück"
        | "zurueck" | "rücklauf" | "ruecklauf" | "rückweg" | "ab" | "abwärts" | "abwaerts"
        | "negativ" => Some(false),
        _ => None,
    }
}

/// A deviation unit's factor to volcomp's unit (µm, µrad), and whether it
/// measures an angle.
pub(crate) fn deviation_unit(unit: &str) -> Option<(f64, bool)> {
    let arcsec = std::f64::consts::PI / (180.0 * 3600.0) * 1e6;
    Some(match fold(unit).as_str() {
        "um" | "micron" | "microns" => (1.0, false),
        "mm" => (1000.0, false),
        "nm" => (1e-3, false),
        "in" | "inch" | "inches" => (25_400.0, false),
        "mil" | "mils" | "thou" => (25.4, false),
        "uin" | "microinch" | "microinches" => (0.0254, false),
        "urad" => (1.0, true),
        "mrad" => (1000.0, true),
        "arcsec" | "\"" | "″" | "sec" => (arcsec, true),
        "mm/m" => (1000.0, true),
        "um/m" => (1.0, true),
        _ => return None,
    })
}

/// A target unit's factor to mm (linear) or degrees (rotary).
pub(crate) fn target_unit(unit: &str, rotary: bool) -> Option<f64> {
    match (fold(unit).as_str(), rotary) {
        ("mm", false) => Some(1.0),
        ("in" | "inch" | "inches", false) => Some(25.4),
        ("deg" | "°" | "degree" | "degrees" | "grad", true) => Some(1.0),
        _ => None,
    }
}

/// Is `unit` a unit of a target or a deviation volcomp reads?
pub(crate) fn is_known_unit(unit: &str) -> bool {
    deviation_unit(unit).is_some()
        || target_unit(unit, false)
            .or(target_unit(unit, true))
            .is_some()
}

/// A unit cell of a units line: `mm`, `[µm]`, `(in)` → the unit.
pub(crate) fn strip_brackets(cell: &str) -> &str {
    let t = cell.trim();
    for (open, close) in [('[', ']'), ('(', ')')] {
        if let Some(inner) = t.strip_prefix(open).and_then(|r| r.strip_suffix(close)) {
            return inner.trim();
        }
    }
    t
}

/// `name [unit]` or `name (unit)` → (name, unit); no unit → "".
pub(crate) fn split_unit(cell: &str) -> (String, String) {
    let cell = cell.trim();
    for (open, close) in [('[', ']'), ('(', ')')] {
        if cell.ends_with(close) {
            if let Some(k) = cell.rfind(open) {
                let unit = cell[k + open.len_utf8()..cell.len() - close.len_utf8()].trim();
                let name = cell[..k].trim();
                if name.is_empty() || unit.is_empty() {
                    continue;
                }
                if is_known_unit(unit)
                    || (!unit.chars().any(|c| c.is_ascii_digit())
                        && parse_direction(unit).is_none())
                {
                    // An unknown unit is kept: refused with its column when it
                    // is a target's or a deviation's.
                    return (name.to_string(), unit.to_string());
                }
            }
        }
    }
    (cell.to_string(), String::new())
}

/// The words that start a wide layout's run column (`Run 1 +`, `Lauf 2 rück`).
const RUN_WORDS: [&str; 8] = [
    "run",
    "messlauf",
    "durchlauf",
    "lauf",
    "cycle",
    "zyklus",
    "r",
    "#",
];

/// A wide layout's run column: a run number and a direction, e.g. `run 1 +`,
/// `Run 2 (down)`, `R3 fwd`, `1+`, `+4`, `Lauf 1 hin`, `Run 1 ↑`.
pub(crate) fn parse_run_column(name: &str) -> Option<(u32, bool)> {
    let (run, before, after) = run_and_rest(name)?;
    match (before.is_empty(), after.is_empty()) {
        (true, false) => parse_direction(&after).map(|d| (run, d)),
        (false, true) => parse_direction(&before).map(|d| (run, d)),
        _ => None,
    }
}

/// A run column that says no direction (`Run 1`, `Lauf 3`): the wide layout
/// cannot tell which approach it holds.
pub(crate) fn is_run_without_direction(name: &str) -> bool {
    matches!(run_and_rest(name), Some((_, b, a)) if b.is_empty() && a.is_empty())
        && fold(name).starts_with(|c: char| c.is_alphabetic())
}

/// The run number of a run column and the words before and after it.
fn run_and_rest(name: &str) -> Option<(u32, String, String)> {
    let lower = fold(name);
    let mut rest = lower.as_str();
    for prefix in RUN_WORDS {
        if let Some(r) = rest.strip_prefix(prefix) {
            if r.starts_with(|c: char| {
                c.is_ascii_digit() || c == ' ' || c == '_' || c == '.' || c == '#'
            }) {
                rest = r.trim_start_matches([' ', '_', '.', '#']);
                let rest = rest.strip_prefix("nr").unwrap_or(rest);
                let rest = rest.trim_start_matches([' ', '_', '.', '#']);
                return split_run(rest);
            }
        }
    }
    split_run(rest)
}

fn split_run(rest: &str) -> Option<(u32, String, String)> {
    let digits_start = rest.find(|c: char| c.is_ascii_digit())?;
    let digits_end = digits_start
        + rest[digits_start..]
            .find(|c: char| !c.is_ascii_digit())
            .unwrap_or(rest.len() - digits_start);
    let run: u32 = rest[digits_start..digits_end].parse().ok()?;
    if run == 0 {
        return None;
    }
    let clean = |s: &str| {
        s.trim_matches(|c: char| c == ' ' || c == '_' || c == '(' || c == ')' || c == '.')
            .to_string()
    };
    Some((
        run,
        clean(&rest[..digits_start]),
        clean(&rest[digits_end..]),
    ))
}

/// The role of a header cell named `name` (its unit split off). A name that is
/// no reading's is [`Role::Other`].
pub(crate) fn classify(name: &str) -> Role {
    let lower = fold(name);
    match lower.as_str() {
        "target" | "position" | "target position" | "target pos" | "target_position"
        | "nominal" | "nominal position" | "setpoint" | "commanded" | "sollposition"
        | "soll-position" | "soll position" | "soll" | "sollwert" | "zielposition"
        | "nennposition" | "nennmaß" | "nennmass" => Role::Target,
        "run" | "run no" | "run no." | "run number" | "run #" | "run nr" | "cycle" | "lauf"
        | "lauf nr" | "lauf nr." | "laufnummer" | "durchlauf" | "messlauf" | "zyklus" => Role::Run,
        "direction" | "dir" | "approach" | "approach direction" | "richtung" | "anfahrrichtung"
        | "fahrtrichtung" => Role::Direction,
        "deviation"
        | "error"
        | "dev"
        | "positional deviation"
        | "position error"
        | "positioning error"
        | "abweichung"
        | "fehler"
        | "positionsabweichung"
        | "positionierabweichung" => Role::Deviation,
        _ => {
            if let Some(up) = parse_direction(&lower) {
                return Role::Approach(up);
            }
            for word in [
                "deviation",
                "error",
                "dev",
                "abweichung",
                "fehler",
                "positionsabweichung",
            ] {
                if let Some(rest) = lower.strip_prefix(word) {
                    if let Some(up) = parse_direction(rest.trim_matches([' ', '_', '(', ')'])) {
                        return Role::Approach(up);
                    }
                }
            }
            if is_parameter_name(&name.trim().to_ascii_uppercase()) {
                return Role::Deviation;
            }
            match parse_run_column(name) {
                Some((run, up)) => Role::RunApproach(run, up),
                None => Role::Other,
            }
        }
    }
}

/// `E` + direction + axis letter (any axis).
pub(crate) fn is_parameter_name(name: &str) -> bool {
    let b = name.as_bytes();
    b.len() == 3
        && b[0] == b'E'
        && crate::machine::table::DIRECTIONS.contains(&(b[1] as char))
        && Axis::from_letter(b[2] as char).is_some()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn run_columns_are_read() {
        assert_eq!(parse_run_column("run 1 +"), Some((1, true)));
        assert_eq!(parse_run_column("run 12 (down)"), Some((12, false)));
        assert_eq!(parse_run_column("r3 fwd"), Some((3, true)));
        assert_eq!(parse_run_column("2-"), Some((2, false)));
        assert_eq!(parse_run_column("+4"), Some((4, true)));
        assert_eq!(parse_run_column("Lauf 2 Rück"), Some((2, false)));
        assert_eq!(parse_run_column("Lauf Nr. 3 vorwärts"), Some((3, true)));
        assert_eq!(parse_run_column("Run 1 (↑)"), Some((1, true)));
        assert_eq!(parse_run_column("run 1"), None);
        assert!(is_run_without_direction("Run 1"));
        assert!(!is_run_without_direction("Run 1 +"));
        assert_eq!(parse_run_column("temperature"), None);
    }

    #[test]
    fn german_and_english_headers_are_classified() {
        assert_eq!(classify("Sollposition"), Role::Target);
        assert_eq!(classify("Lauf"), Role::Run);
        assert_eq!(classify("Richtung"), Role::Direction);
        assert_eq!(classify("Abweichung"), Role::Deviation);
        assert_eq!(classify("Abweichung hin"), Role::Approach(true));
        assert_eq!(classify("RÜCKWÄRTS"), Role::Approach(false));
        assert_eq!(classify("Air temp"), Role::Other);
        assert_eq!(classify("EYX"), Role::Deviation);
    }

    #[test]
    fn units_are_split_from_names() {
        assert_eq!(split_unit("target [mm]"), ("target".into(), "mm".into()));
        assert_eq!(
            split_unit("deviation (µm)"),
            ("deviation".into(), "µm".into())
        );
        assert_eq!(split_unit("run 1 (+)"), ("run 1 (+)".into(), "".into()));
        assert_eq!(
            split_unit("Air temp (°C)"),
            ("Air temp".into(), "°C".into())
        );
        assert_eq!(deviation_unit("µin"), Some((0.0254, false)));
        assert_eq!(target_unit("in", false), Some(25.4));
        assert_eq!(target_unit("in", true), None);
    }
}
