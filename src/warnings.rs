//! The warnings of a run, collected once for every command.
//!
//! Reading a program produces warnings (a tool change without a tool table, a
//! line passed through under `--lenient`, an unknown word), and so do the
//! lookups of the error model (a table's end value held). Every command shows
//! them the same way: once per kind, with the first place and a count, and in
//! its JSON report under `warnings` (`cli::common` renders them). Some change
//! the result (a tool length assumed, words ignored, a table end held): the
//! command's summary line then says so.
//!
//! [`Warnings`] is a shared handle: the program's setup carries one
//! ([`crate::gcode::ProgramSetup::warnings`]), the reader adds to it while the
//! program runs (on any thread), and the command reads it at the end. Memory is
//! one entry per kind, whatever the program's length.
use serde::{Deserialize, Serialize};
use std::sync::{Arc, Mutex};

/// One kind of warning of a run: how often, where first, and what it said.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WarningGroup {
    /// What kind (`no_tool_table`, `lenient`, `held_lookups`, …).
    pub kind: String,
    /// How many times it was raised.
    pub count: u64,
    /// The file of the first one, when it is about a program's line.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub file: Option<String>,
    /// The line (and column) of the first one.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_line: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first_column: Option<usize>,
    /// The first one's message.
    pub message: String,
    /// The result (corrections, predictions) would differ without it.
    pub changes_result: bool,
    /// What it changes, in a few words, for the summary line (`tool length
    /// assumed`); empty when it changes nothing.
    pub effect: String,
}

/// One warning to add: see [`Warnings::add`].
#[derive(Clone, Debug, PartialEq)]
pub struct Warning<'a> {
    pub kind: &'a str,
    pub file: Option<&'a str>,
    pub line: Option<usize>,
    pub column: Option<usize>,
    /// Its effect on the result (empty: none).
    pub effect: &'a str,
}

/// The warnings of one run, grouped by kind in the order first raised.
/// Cloning shares the collection.
#[derive(Clone, Debug, Default)]
pub struct Warnings(Arc<Mutex<Vec<WarningGroup>>>);

impl Warnings {
    pub fn new() -> Self {
        Warnings::default()
    }

    /// Count `count` warnings of `w.kind`; the message (made only for the
    /// first of a kind) and place are kept from the first.
    pub fn add(&self, w: &Warning<'_>, count: u64, message: impl FnOnce() -> String) {
        if count == 0 {
            return;
        }
        let mut groups = self.0.lock().unwrap_or_else(|e| e.into_inner());
        match groups.iter_mut().find(|g| g.kind == w.kind) {
            Some(g) => g.count += count,
            None => groups.push(WarningGroup {
                kind: w.kind.to_string(),
                count,
                file: w.file.map(str::to_string),
                first_line: w.line,
                first_column: w.column,
                message: message(),
                changes_result: !w.effect.is_empty(),
                effect: w.effect.to_string(),
            }),
        }
    }

    /// The groups so far, in the order first raised.
    pub fn groups(&self) -> Vec<WarningGroup> {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).clone()
    }

    /// Whether no warning was raised.
    pub fn is_empty(&self) -> bool {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w<'a>(kind: &'a str, line: usize, effect: &'a str) -> Warning<'a> {
        Warning {
            kind,
            file: Some("p.nc"),
            line: Some(line),
            column: Some(1),
            effect,
        }
    }

    #[test]
    fn one_group_per_kind_keeps_the_first_and_counts_all() {
        let log = Warnings::new();
        let shared = log.clone();
        shared.add(&w("lenient", 3, "lines passed through unread"), 1, || {
            "a".into()
        });
        shared.add(&w("home", 5, ""), 1, || "b".into());
        shared.add(&w("lenient", 9, "lines passed through unread"), 2, || {
            "c".into()
        });
        log.add(&w("none", 1, ""), 0, || unreachable!());
        let g = log.groups();
        assert_eq!(g.len(), 2);
        assert_eq!(
            (g[0].count, g[0].first_line, g[0].message.as_str()),
            (3, Some(3), "a")
        );
        assert!(g[0].changes_result && !g[1].changes_result);
        assert_eq!(g[0].effect, "lines passed through unread");
    }
}
