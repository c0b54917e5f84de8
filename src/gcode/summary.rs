//! What `volcomp check` reports about a program, accumulated block by block
//! (streaming: constant memory). Its warnings are collected by the run
//! (`crate::warnings`, through [`super::ProgramSetup::warnings`]).
use std::collections::BTreeMap;

use serde::Serialize;

use crate::gcode::machine::interpret::BlockEvent;
use crate::gcode::machine::modal::{
    GCode, MCode, classify_g, classify_m, code_text, is_known_letter,
};
use crate::gcode::machine::motion::{Feed, Frame, MotionKind};
use crate::gcode::syntax::block::Block;

/// How many tool runs a summary keeps (all are counted).
pub const KEPT_TOOL_RUNS: usize = 256;

/// A run of moves cut with one tool.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ToolRun {
    pub tool: crate::gcode::machine::tools::ToolInUse,
    pub first_line: usize,
    pub last_line: usize,
    pub moves: usize,
}

/// Motion blocks by kind.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct MotionCounts {
    pub rapid: usize,
    pub linear: usize,
    pub arc_cw: usize,
    pub arc_ccw: usize,
}

impl MotionCounts {
    pub fn total(&self) -> usize {
        self.rapid + self.linear + self.arc_cw + self.arc_ccw
    }
}

/// Closed range of values seen (`None` before the first).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct Range {
    pub min: f64,
    pub max: f64,
}

fn widen(r: &mut Option<Range>, v: f64) {
    match r {
        Some(r) => {
            r.min = r.min.min(v);
            r.max = r.max.max(v);
        }
        None => *r = Some(Range { min: v, max: v }),
    }
}

/// What `volcomp check` reports about a program: counts, machining time and
/// the ranges of the move targets, accumulated block by block
/// ([`ProgramSummary::add`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ProgramSummary {
    /// Lines executed (every line is a block; a line in a loop or a
    /// subroutine counts each time it runs).
    pub lines: usize,
    /// Lines with words or keywords.
    pub blocks: usize,
    /// Comments (a line may hold several).
    pub comments: usize,
    /// Lines with block delete `/`.
    pub deleted_blocks: usize,
    /// Moves by kind (rapid, linear, arc; a canned cycle or a spline
    /// counts each of its moves).
    pub motion: MotionCounts,
    /// Blocks that switch between the joint and the part frame.
    pub frame_switches: usize,
    /// Motion blocks in the part frame (tool-tip programming).
    pub part_frame_motions: usize,
    /// Motion blocks under G93.
    pub inverse_time_motions: usize,
    /// G53 moves.
    pub machine_coordinate_motions: usize,
    /// G28/G30 blocks.
    pub home_blocks: usize,
    /// Machining time, min (effects.md rules; from the first move's target).
    pub time_min: f64,
    /// Ranges of the programmed move targets (mm, degrees), over all frames:
    /// X, mm (`None` before the first move).
    pub x: Option<Range>,
    /// Range of the Y targets, mm.
    pub y: Option<Range>,
    /// Range of the Z targets, mm.
    pub z: Option<Range>,
    /// Range of the A targets, degrees.
    pub a: Option<Range>,
    /// Range of the B targets, degrees.
    pub b: Option<Range>,
    /// Range of the C targets, degrees.
    pub c: Option<Range>,
    /// Range of the U targets, mm.
    pub u: Option<Range>,
    /// Range of the V targets, mm.
    pub v: Option<Range>,
    /// Range of the W targets, mm.
    pub w: Option<Range>,
    /// Words with a letter the interpreter does not know, by letter.
    pub unknown_words: BTreeMap<char, usize>,
    /// The moves per tool, run by run in program order (the first
    /// `KEPT_TOOL_RUNS`; `tool_runs` counts them all).
    pub tools: Vec<ToolRun>,
    /// How many tool runs the program has (`tools` keeps at most the first
    /// 256, `KEPT_TOOL_RUNS`).
    pub tool_runs: usize,
    /// The dialect the program was read in and why (`read as Sinumerik
    /// (extension .MPF)`), for programs not read as LinuxCNC's (whose
    /// summaries stay as they were).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub dialect: Option<String>,
    /// The dialect the program was read in (the summary's words follow it).
    #[serde(skip)]
    pub read_in: crate::gcode::Dialect,
    /// Passed-through codes by (letter, code × 10); see [`ProgramSummary::passed_through`].
    #[serde(skip)]
    passed: BTreeMap<(u8, i32), usize>,
    /// A dialect's statements passed through, by name (`Block::statements`).
    #[serde(skip)]
    statements: BTreeMap<String, usize>,
}

impl ProgramSummary {
    /// Count one block and its event.
    pub fn add(&mut self, block: &Block, event: &BlockEvent) {
        self.lines += 1;
        self.comments += block.comments.len();
        if !block.is_empty() {
            self.blocks += 1;
        }
        if block.deleted {
            self.deleted_blocks += 1;
        }
        if event.frame_switch.is_some() {
            self.frame_switches += 1;
        }
        if event.is_home() {
            self.home_blocks += 1;
        }
        self.time_min = event.time_min;
        if !event.skipped {
            // A word a dialect front solved (zero width: no text, e.g. the
            // rotary joints of a SINUMERIK orientation vector) or an
            // orientation component (a digit letter) is not a word written
            // as such: not counted. (Only G and M words are counted by
            // their code.)
            // (The words a front found to change nothing, `N`, `F` and
            // motion codes, would not be counted: `Block::machine_words`.)
            for w in block
                .machine_words()
                .iter()
                .filter(|w| w.start < w.end && !w.letter.is_ascii_digit())
            {
                let code10 = if matches!(w.letter, b'G' | b'M') {
                    w.code10()
                } else {
                    None
                };
                self.count_word(w.letter, code10);
            }
            for s in &block.statements {
                self.count_statement(&block.raw[s.clone()]);
            }
        }
        for m in event.motions() {
            self.add_tool_move(event);
            match m.kind {
                MotionKind::Rapid => self.motion.rapid += 1,
                MotionKind::Linear => self.motion.linear += 1,
                MotionKind::Arc {
                    clockwise: true, ..
                } => self.motion.arc_cw += 1,
                MotionKind::Arc { .. } => self.motion.arc_ccw += 1,
            }
            if m.frame == Frame::Part {
                self.part_frame_motions += 1;
            }
            if matches!(m.feed, Feed::InverseTime(_)) {
                self.inverse_time_motions += 1;
            }
            if m.machine_coordinates {
                self.machine_coordinate_motions += 1;
            }
            let p = &m.end;
            widen(&mut self.x, p.x);
            widen(&mut self.y, p.y);
            widen(&mut self.z, p.z);
            widen(&mut self.a, p.a);
            widen(&mut self.b, p.b);
            widen(&mut self.c, p.c);
            widen(&mut self.u, p.u);
            widen(&mut self.v, p.v);
            widen(&mut self.w, p.w);
        }
    }

    fn add_tool_move(&mut self, event: &BlockEvent) {
        // The last kept run is the current one while every run is kept.
        let current = self.tool_runs == self.tools.len();
        match self.tools.last_mut().filter(|_| current) {
            Some(r) if r.tool == event.tool => {
                r.last_line = event.line;
                r.moves += 1;
            }
            _ => {
                self.tool_runs += 1;
                if self.tools.len() < KEPT_TOOL_RUNS {
                    self.tools.push(ToolRun {
                        tool: event.tool,
                        first_line: event.line,
                        last_line: event.line,
                        moves: 1,
                    });
                }
            }
        }
    }

    fn count_word(&mut self, letter: u8, code10: Option<i32>) {
        let key = match letter {
            b'G' => match code10.map(classify_g) {
                Some(
                    GCode::CoordSystem(_)
                    | GCode::PassThrough
                    | GCode::ToolLength
                    | GCode::ToolLengthDynamic
                    | GCode::ToolLengthAdd
                    | GCode::Unsupported
                    | GCode::SetData
                    | GCode::AxisOffset(_)
                    | GCode::RetractMode(_)
                    | GCode::Dwell
                    | GCode::StoreHome(_),
                ) => (b'G', code10.unwrap_or(0)),
                _ => return,
            },
            b'M' => match code10.map(classify_m) {
                Some(MCode::PassThrough | MCode::Subroutine) | None => (b'M', code10.unwrap_or(-1)),
                _ => return,
            },
            b'S' | b'T' | b'D' | b'H' | b'Q' | b'L' | b'E' => (letter, i32::MIN),
            _ => {
                if !is_known_letter(letter) {
                    *self.unknown_words.entry(letter as char).or_default() += 1;
                }
                return;
            }
        };
        *self.passed.entry(key).or_default() += 1;
    }

    fn count_statement(&mut self, text: &[u8]) {
        let name: String = text
            .iter()
            .take_while(|b| b.is_ascii_alphanumeric() || **b == b'_' || **b == b'$')
            .map(|b| b.to_ascii_uppercase() as char)
            .collect();
        if let Some(n) = self.statements.get_mut(&name) {
            *n += 1;
        } else {
            self.statements.insert(name, 1);
        }
    }

    /// Codes and words passed through untouched (`G54`, `M3`, `S`, `T`, ...),
    /// with their counts.
    pub fn passed_through(&self) -> BTreeMap<String, usize> {
        self.passed
            .iter()
            .map(|(&(letter, code), &n)| {
                let name = if code == i32::MIN {
                    (letter as char).to_string()
                } else {
                    code_text(letter as char, code)
                };
                (name, n)
            })
            .chain(self.statements.iter().map(|(k, &n)| (k.clone(), n)))
            .collect()
    }
}
