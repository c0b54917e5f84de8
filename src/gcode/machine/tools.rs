//! Tools: LinuxCNC's tool table and the tool in the spindle.
//!
//! A tool table line is LinuxCNC's (`tooldata_read_entry`): words separated by
//! spaces, `;` starts the comment, `T` is the tool number, `P` the pocket,
//! `Z` the length offset, `D` the diameter; `X Y A B C U V W I J Q` are read
//! and not used (lathe offsets, angles, orientation). volcomp reads the values
//! in mm (as `.var` files), and takes `Z` as the tool's length from the gauge
//! point to the tip, the `L` of kinematics.md that each angular error acts on:
//! a negative `Z` (a table measured against a master tool) is refused.
//!
//! The tool in use follows the program as LinuxCNC runs it: `T` selects
//! (a tool the table lacks is an error, as in LinuxCNC), `M6` loads the
//! selected tool, `M61 Q` sets the loaded tool, G10 L1/L10/L11 change table
//! entries. Tool 0 (an empty spindle, and every block before the first tool
//! change) is the default tool: the machine file's `[tool]`. The controller's
//! tool length offset (`G43 H`, `G43.1`, `G43.2`, `G49`) is tracked to warn when
//! it differs from the loaded tool's length: X Y Z are then not that tool's tip.
use std::collections::BTreeMap;
use std::fmt;

/// One tool of the table, mm.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ToolEntry {
    /// The tool number (the table's `T`).
    pub number: u32,
    /// The pocket (the table's `P`), when given.
    pub pocket: Option<u32>,
    /// The tool's name, for controls that call tools by name (Heidenhain's
    /// `TOOL CALL "NAME"`: the `NAME` column of the TNC's tool table; the
    /// machine file's `[[tools]] name`). LinuxCNC's tables name no tools.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// Gauge point to tip (the table's `Z`), mm.
    pub length_mm: f64,
    /// Cutter diameter (`D`; 0 when the table has none), mm.
    pub diameter_mm: f64,
    /// Its cutting shape, when the machine file names one (LinuxCNC's tables
    /// do not).
    pub shape: Option<CutterShape>,
    /// The line's comment (after `;`, trimmed; empty when none).
    pub comment: String,
    /// Where the entry comes from (`file:line`), for messages.
    #[serde(skip)]
    pub origin: String,
}

/// The cutting shape of a tool (machine file `shape`; docs/extensions.md): a
/// body of revolution about the tool axis, a cylinder of the tool's radius
/// whose tip edge is rounded with `corner_radius_mm` (0: flat end; the radius:
/// ball end; between: bull nose), cutting up to `flute_length_mm` above the tip.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CutterShape {
    /// Radius of the rounded tip edge, mm (0: flat end; the tool's radius:
    /// ball end).
    pub corner_radius_mm: f64,
    /// How far above the tip the tool cuts, mm.
    pub flute_length_mm: f64,
}

/// The tool a block cuts with: its number, length (gauge point to tip) and
/// radius, mm, and its cutting shape when the machine file names one. Tool 0
/// is the default tool, whose length, radius and shape the consumer knows
/// (the machine file's `[tool]`, the error model's length): resolve it with
/// [`ToolInUse::or`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct ToolInUse {
    /// The tool number (0: the default tool).
    pub number: u32,
    /// Gauge point to tip, mm.
    pub length_mm: f64,
    /// Cutter radius, mm.
    pub radius_mm: f64,
    /// Its cutting shape, when the machine file names one.
    pub shape: Option<CutterShape>,
}

impl ToolInUse {
    /// The default tool (number 0), its length and radius not known here.
    pub const DEFAULT: ToolInUse = ToolInUse {
        number: 0,
        length_mm: 0.0,
        radius_mm: 0.0,
        shape: None,
    };

    /// The default tool (number 0) of `length_mm` and `radius_mm`.
    pub fn default_tool(length_mm: f64, radius_mm: f64) -> Self {
        ToolInUse {
            number: 0,
            length_mm,
            radius_mm,
            shape: None,
        }
    }

    /// This tool, or `default` when this is tool 0.
    pub fn or(self, default: ToolInUse) -> ToolInUse {
        if self.number == 0 { default } else { self }
    }
}

impl Default for ToolInUse {
    fn default() -> Self {
        ToolInUse::DEFAULT
    }
}

impl fmt::Display for ToolInUse {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.number == 0 && self.length_mm == 0.0 && self.radius_mm == 0.0 {
            return write!(f, "default tool ([tool] of the machine file)");
        }
        if self.number == 0 {
            write!(f, "default tool")?;
        } else {
            write!(f, "T{}", self.number)?;
        }
        write!(f, " (L {} mm, R {} mm)", self.length_mm, self.radius_mm)
    }
}

/// Most tools a tool table may list (LinuxCNC's `CANON_POCKETS_MAX` 1001,
/// pocket 0 being the spindle).
pub const MAX_TOOLS: usize = 1000;

/// A token as messages quote it: at most 40 characters.
fn short_token(token: &str) -> std::borrow::Cow<'_, str> {
    match token.char_indices().nth(40) {
        Some((k, _)) => format!("{}…", &token[..k]).into(),
        None => token.into(),
    }
}

/// A bad tool table line (or `[[tools]]` entry).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{source_name}:{line}:{column}: {message}")]
pub struct ToolTableError {
    /// The name the table was parsed under ([`ToolTable::parse`]).
    pub source_name: String,
    /// 1-based line.
    pub line: usize,
    /// 1-based byte column of the offending word (1: the whole line).
    pub column: usize,
    /// What is wrong, and how to fix it.
    pub message: String,
}

/// What a tool name finds in a table ([`ToolTable::named`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NamedTool<'a> {
    /// The one tool of that name.
    One(&'a ToolEntry),
    /// Two tools carry the name (their numbers): a name must name one tool.
    Two(u32, u32),
    /// No tool carries it.
    None,
}

/// A tool table: tools by number.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ToolTable {
    entries: BTreeMap<u32, ToolEntry>,
    /// Tool numbers by name (the entries with a name).
    names: BTreeMap<String, u32>,
    /// The file (or machine file) it was read from.
    source: Option<String>,
    /// A LinuxCNC table (`parse`): its comments name its tools.
    comments_are_names: bool,
    /// A table was given (`parse`, `insert`): programs may select only its
    /// tools. Without one any tool may be selected (the default tool is used).
    given: bool,
}

impl ToolTable {
    /// An empty table: programs select tools freely and every block uses the
    /// default tool (`check` warns at the first tool change).
    pub fn new() -> Self {
        ToolTable::default()
    }

    /// Read a LinuxCNC tool table; `name` names it in messages.
    pub fn parse(text: &str, name: &str) -> Result<ToolTable, ToolTableError> {
        let mut table = ToolTable {
            entries: BTreeMap::new(),
            names: BTreeMap::new(),
            source: Some(name.to_string()),
            comments_are_names: true,
            given: true,
        };
        // A UTF-8 byte order mark is not part of the first line.
        let text = text.strip_prefix('\u{feff}').unwrap_or(text);
        for (index, raw) in text.lines().enumerate() {
            let line = index + 1;
            let fail = |column: usize, message: String| ToolTableError {
                source_name: name.to_string(),
                line,
                column,
                message,
            };
            if let Some(message) = crate::io::long_line(raw) {
                return Err(fail(1, message));
            }
            let (body, comment) = match raw.find(';') {
                Some(k) => (&raw[..k], raw[k + 1..].trim()),
                None => (raw, ""),
            };
            if body.trim().is_empty() {
                continue;
            }
            if table.entries.len() >= MAX_TOOLS {
                return Err(fail(
                    1,
                    format!(
                        "more than {MAX_TOOLS} tools: LinuxCNC's tool table holds at most {MAX_TOOLS} (CANON_POCKETS_MAX 1001, pocket 0 being the spindle); is this a tool table?"
                    ),
                ));
            }
            let mut number = None;
            let mut pocket = None;
            let mut length = 0.0;
            let mut diameter = 0.0;
            let mut column = 1;
            // Letters seen on the line, with their column: a repeated word
            // (`Z100 Z200`) is refused rather than one of them picked.
            let mut seen: [Option<usize>; 26] = [None; 26];
            for token in body.split([' ', '\t']) {
                let here = column;
                column += token.len() + 1;
                if token.is_empty() {
                    continue;
                }
                // The first character may be any (a byte order mark, a typo).
                let first = token.chars().next().unwrap_or(' ');
                let letter = if first.is_ascii() {
                    (first as u8).to_ascii_uppercase()
                } else {
                    0
                };
                let value = &token[first.len_utf8()..];
                // Messages quote the token, shortened.
                let token = &*short_token(token);
                if letter.is_ascii_uppercase() {
                    let slot = &mut seen[(letter - b'A') as usize];
                    if let Some(at) = *slot {
                        return Err(fail(
                            here,
                            format!(
                                "`{token}`: {} is given twice on the line (first at column {at}); give each word once",
                                letter as char
                            ),
                        ));
                    }
                    *slot = Some(here);
                }
                let number_of = |what: &str| -> Result<f64, ToolTableError> {
                    match value.parse::<f64>() {
                        Ok(v) if v.is_finite() && v.abs() < 1e9 => Ok(v),
                        _ => Err(fail(
                            here,
                            format!(
                                "`{token}`: {what} must be a finite number (e.g. {}12.5)",
                                letter as char
                            ),
                        )),
                    }
                };
                let integer_of = |what: &str| -> Result<u32, ToolTableError> {
                    value.parse::<u32>().map_err(|_| {
                        fail(
                            here,
                            format!("`{token}`: {what} must be a whole number ≥ 0"),
                        )
                    })
                };
                match letter {
                    b'T' => number = Some((integer_of("the tool number")?, here)),
                    b'P' => pocket = Some(integer_of("the pocket")?),
                    b'Z' => {
                        length = number_of("the tool length Z")?;
                        if length < 0.0 {
                            return Err(fail(
                                here,
                                format!(
                                    "`{token}`: a tool length must be ≥ 0 mm; volcomp reads Z as the tool's length from the gauge point (spindle nose) to the tip, as the machine file's [tool] length: add the master tool's length to a table measured against a master tool"
                                ),
                            ));
                        }
                    }
                    b'D' => {
                        diameter = number_of("the diameter D")?;
                        if diameter < 0.0 {
                            return Err(fail(
                                here,
                                format!("`{token}`: a diameter must be ≥ 0 mm"),
                            ));
                        }
                    }
                    b'X' | b'Y' | b'A' | b'B' | b'C' | b'U' | b'V' | b'W' | b'I' | b'J' => {
                        number_of("the value")?;
                    }
                    b'Q' => {
                        integer_of("the orientation Q")?;
                    }
                    _ => {
                        return Err(fail(
                            here,
                            format!(
                                "`{token}`: not a tool table word (LinuxCNC's format: `T1 P1 Z50.0 D6.0 ;comment`)"
                            ),
                        ));
                    }
                }
            }
            let Some((number, at)) = number else {
                return Err(fail(
                    1,
                    "a tool table line needs its tool number `T…` (LinuxCNC's format: `T1 P1 Z50.0 D6.0 ;comment`)".into(),
                ));
            };
            let entry = ToolEntry {
                number,
                pocket,
                name: None,
                shape: None,
                length_mm: length,
                diameter_mm: diameter,
                comment: comment.to_string(),
                origin: format!("{name}:{line}"),
            };
            table.insert(entry).map_err(|first| {
                fail(
                    at,
                    format!("tool T{number} is listed twice (first at {first})"),
                )
            })?;
        }
        Ok(table)
    }

    /// Add an entry; `Err(origin of the first)` when the number, or the
    /// name, is taken.
    pub fn insert(&mut self, entry: ToolEntry) -> Result<(), String> {
        if let Some(first) = self.entries.get(&entry.number) {
            return Err(first.origin.clone());
        }
        if let Some(name) = &entry.name {
            if let Some(first) = self.names.get(name).and_then(|n| self.entries.get(n)) {
                return Err(first.origin.clone());
            }
            self.names.insert(name.clone(), entry.number);
        }
        self.given = true;
        self.entries.insert(entry.number, entry);
        Ok(())
    }

    /// Name the table's source in messages.
    pub fn set_source(&mut self, source: impl Into<String>) {
        self.source = Some(source.into());
    }

    /// The table's source in messages, when named.
    pub fn source(&self) -> Option<&str> {
        self.source.as_deref()
    }

    /// Whether the table holds no tool.
    pub fn is_empty(&self) -> bool {
        self.entries.is_empty()
    }

    /// Whether a table was given (an empty file is a table with no tools).
    pub fn is_given(&self) -> bool {
        self.given
    }

    /// How many tools the table holds.
    pub fn len(&self) -> usize {
        self.entries.len()
    }

    /// Tool `number`, when the table holds it.
    pub fn get(&self, number: u32) -> Option<&ToolEntry> {
        self.entries.get(&number)
    }

    /// The tool a program calls by name (Heidenhain's `TOOL CALL "NAME"`,
    /// SINUMERIK's `T="NAME"`). A tool's name is the machine file's
    /// `[[tools]] name`; a LinuxCNC tool table has no name column, so there
    /// an entry's comment is its name (`T7 P7 Z95.2 D8.5 ;DRILL 8.5`).
    /// Names are compared exactly (case and inner spaces kept), as the
    /// controls compare them. Both dialects read the answer alike: one tool
    /// is taken; two are a located error; none is a located error when the
    /// table names any tool, and the default tool (said in `check`'s
    /// summary) when it names none.
    pub fn named(&self, name: &str) -> NamedTool<'_> {
        if let Some(e) = self.names.get(name).and_then(|n| self.entries.get(n)) {
            return NamedTool::One(e);
        }
        if !self.comments_are_names {
            return NamedTool::None;
        }
        let mut found = self.entries.values().filter(|e| e.comment == name);
        match (found.next(), found.next()) {
            (Some(e), None) => NamedTool::One(e),
            (Some(a), Some(b)) => NamedTool::Two(a.number, b.number),
            (None, _) => NamedTool::None,
        }
    }

    /// Whether the table names any tool (see [`ToolTable::named`]).
    pub fn names_tools(&self) -> bool {
        !self.names.is_empty()
            || (self.comments_are_names && self.entries.values().any(|e| !e.comment.is_empty()))
    }

    /// The tools, by increasing number.
    pub fn entries(&self) -> impl Iterator<Item = &ToolEntry> {
        self.entries.values()
    }

    /// Whether a program may select `number`: tool 0 always, others when the
    /// table lists them (any tool when no table was given).
    pub fn knows(&self, number: u32) -> bool {
        number == 0 || !self.given || self.entries.contains_key(&number)
    }

    /// G10 L1/L10/L11: set the length and/or radius of a tool (added when
    /// no table was given, so the program can use it).
    pub fn update(
        &mut self,
        number: u32,
        length_mm: Option<f64>,
        radius_mm: Option<f64>,
        origin: String,
    ) {
        let entry = self.entries.entry(number).or_insert_with(|| ToolEntry {
            number,
            pocket: None,
            name: None,
            length_mm: 0.0,
            diameter_mm: 0.0,
            shape: None,
            comment: String::new(),
            origin,
        });
        if let Some(l) = length_mm {
            entry.length_mm = l;
        }
        if let Some(r) = radius_mm {
            entry.diameter_mm = 2.0 * r;
        }
    }

    /// The tool in use when `number` is loaded: its entry, or `default` for
    /// tool 0 and for tools the table does not list.
    pub fn in_use(&self, number: u32, default: ToolInUse) -> ToolInUse {
        match self.entries.get(&number) {
            Some(e) if number != 0 => ToolInUse {
                number,
                length_mm: e.length_mm,
                radius_mm: 0.5 * e.diameter_mm,
                shape: e.shape,
            },
            _ => default,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_linuxcnc_tool_tables() {
        let t = ToolTable::parse(
            "T1 P1 Z0.511 D0.125 ;1/8 end mill \n\n;comment line\nt2 p2 z40 d6 x0 q3\n",
            "sim.tbl",
        )
        .unwrap();
        assert_eq!(t.len(), 2);
        let e = t.get(1).unwrap();
        assert_eq!((e.length_mm, e.diameter_mm), (0.511, 0.125));
        assert_eq!(e.comment, "1/8 end mill");
        assert_eq!(t.get(2).unwrap().length_mm, 40.0);
        let d = ToolInUse::default_tool(100.0, 3.0);
        assert_eq!(t.in_use(2, d).radius_mm, 3.0);
        assert_eq!(t.in_use(0, d), d);
    }

    #[test]
    fn finds_tools_by_name_and_refuses_a_name_twice() {
        let entry = |number: u32, name: &str, origin: &str| ToolEntry {
            number,
            pocket: None,
            name: Some(name.to_string()),
            length_mm: 50.0,
            diameter_mm: 8.0,
            shape: None,
            comment: String::new(),
            origin: origin.to_string(),
        };
        let mut t = ToolTable::new();
        t.insert(entry(7, "SA077", "m.toml:1")).unwrap();
        assert_eq!(t.named("SA077"), NamedTool::One(t.get(7).unwrap()));
        assert_eq!(t.named("sa077"), NamedTool::None);
        assert!(t.names_tools());
        // A machine file's comments describe; they do not name.
        let mut described = ToolTable::new();
        let mut e = entry(3, "x", "m.toml:3");
        e.name = None;
        e.comment = "ball end R3".into();
        described.insert(e).unwrap();
        assert_eq!(described.named("ball end R3"), NamedTool::None);
        assert!(!described.names_tools());
        // A LinuxCNC table's comments are its names; one name, one tool.
        let tbl =
            ToolTable::parse("T1 Z10 ;DRILL 8.5\nT2 Z20 ;MILL\nT3 Z30 ;MILL\n", "t.tbl").unwrap();
        assert_eq!(tbl.named("DRILL 8.5"), NamedTool::One(tbl.get(1).unwrap()));
        assert_eq!(tbl.named("MILL"), NamedTool::Two(2, 3));
        assert_eq!(tbl.named("drill 8.5"), NamedTool::None);
        assert_eq!(
            t.insert(entry(8, "SA077", "m.toml:9")),
            Err("m.toml:1".into())
        );
        assert!(t.get(8).is_none());
    }

    #[test]
    fn refuses_bad_lines_with_their_place() {
        let e = ToolTable::parse("T1 Z10\nT2 Z-5 D6\n", "t.tbl").unwrap_err();
        assert_eq!((e.line, e.column), (2, 4));
        assert!(e.message.contains("≥ 0"), "{e}");
        let e = ToolTable::parse("T1 Z10\nT1 Z12\n", "t.tbl").unwrap_err();
        assert!(
            e.to_string().contains("listed twice (first at t.tbl:1)"),
            "{e}"
        );
        let e = ToolTable::parse("T1 Znan\n", "t.tbl").unwrap_err();
        assert_eq!(e.column, 4);
        let e = ToolTable::parse("P1 Z10\n", "t.tbl").unwrap_err();
        assert!(e.message.contains("tool number"));
        let e = ToolTable::parse("T1 K3\n", "t.tbl").unwrap_err();
        assert!(e.message.contains("not a tool table word"));
        // Found by fuzzing: a multi-byte first character.
        let e = ToolTable::parse("T1 Z1\n\u{feff}T1\n", "t.tbl").unwrap_err();
        assert!(e.message.contains("not a tool table word"), "{e}");
        assert_eq!(
            ToolTable::parse("\u{feff}T1 Z1\n", "t.tbl").unwrap().len(),
            1
        );
    }
}
