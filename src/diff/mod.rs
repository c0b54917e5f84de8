//! `diff`: block-by-block comparison of two programs.
//!
//! Alignment (`align`) pairs the blocks of A and B; this module accumulates what
//! changed: per-axis statistics of the end-target changes of paired motion blocks,
//! counts of added, removed, changed and unchanged blocks, and the largest changes
//! with their line numbers. Streaming: memory is bounded by the alignment window
//! and the number of largest changes kept.
pub(crate) mod align;
pub(crate) mod program;

pub use align::{AlignOptions, Aligned, Aligner, BlockSummary};
pub use program::{BlockSummaries, DiffOptions, diff_programs};

use crate::axes::{AXIS_COUNT, Axis, AxisSet};
use serde::Serialize;

/// Statistics of the change of one axis over paired motion blocks (B − A), in mm
/// (X Y Z U V W) or degrees (A B C).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct AxisChange {
    /// The axis letter.
    pub axis: char,
    /// Largest `|Δ|`.
    pub max_abs: f64,
    /// Mean `|Δ|` over the paired motion blocks.
    pub mean_abs: f64,
    /// RMS of `Δ` over the paired motion blocks.
    pub rms: f64,
    /// Signed change at `max_abs`.
    pub max_signed: f64,
}

/// One of the largest changes.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LargeChange {
    /// Line of the block in A.
    pub line_a: usize,
    /// Line of the (last) block in B.
    pub line_b: usize,
    /// |Δ(X, Y, Z)|, µm.
    pub xyz_change_um: f64,
    /// Δ per axis of the report's `axes`, in their order (mm axes in µm, rotary
    /// axes in millidegrees).
    pub delta: Vec<f64>,
    /// How many blocks of B the block of A became (1, or the pieces of a
    /// split move: B's `line_b` is the last).
    pub pieces: usize,
}

/// A block of A that became several blocks of B (a split move, or a canned
/// cycle written flat): the last of them is paired with it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SplitBlock {
    /// Line of the block in A.
    pub line_a: usize,
    /// Lines of B's first and last piece.
    pub first_line_b: usize,
    /// Line of B's last piece (the one paired with the block of A).
    pub last_line_b: usize,
    /// Number of blocks of B it became.
    pub pieces: usize,
}

/// The diff report (`--report` JSON).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct DiffReport {
    /// Blocks read from A.
    pub blocks_a: usize,
    /// Blocks read from B.
    pub blocks_b: usize,
    /// Blocks of A paired with a block of B.
    pub paired: usize,
    /// Paired blocks that are the same.
    pub unchanged: usize,
    /// Paired blocks that differ.
    pub changed: usize,
    /// Blocks only in B.
    pub added: usize,
    /// Blocks only in A.
    pub removed: usize,
    /// Paired motion blocks whose targets were compared.
    pub motion_pairs: usize,
    /// X Y Z, and every other letter a paired target of either program moves.
    pub axes: Vec<AxisChange>,
    /// |Δ(X, Y, Z)| over paired motion blocks, µm.
    pub max_xyz_change_um: f64,
    /// RMS of `|Δ(X, Y, Z)|` over paired motion blocks, µm.
    pub rms_xyz_change_um: f64,
    /// The largest changes by `|Δ(X, Y, Z)|`, largest first.
    pub largest: Vec<LargeChange>,
    /// Lines of the first added blocks (up to `largest` many).
    pub added_lines: Vec<usize>,
    /// Lines of the first removed blocks (up to `largest` many).
    pub removed_lines: Vec<usize>,
    /// The warnings of reading A, then B (`crate::warnings`; each names its
    /// file; the command fills it).
    pub warnings: Vec<crate::warnings::WarningGroup>,
    /// Blocks of A that became several blocks of B, and how many blocks of B
    /// they became in all (the pieces are counted in `added` too, but the
    /// last, which is paired).
    pub split_blocks: usize,
    /// Blocks of B those became in all.
    pub split_pieces: usize,
    /// The first of them (up to `largest` many).
    pub splits: Vec<SplitBlock>,
}

impl DiffReport {
    /// Whether A and B have the same blocks (nothing changed, added or removed).
    pub fn is_identical(&self) -> bool {
        self.changed == 0 && self.added == 0 && self.removed == 0
    }
}

/// Accumulates a [`DiffReport`] from aligned blocks.
#[derive(Debug)]
pub struct DiffAccumulator {
    report: DiffReport,
    changes: [AxisChange; AXIS_COUNT],
    sum_abs: [f64; AXIS_COUNT],
    sum_sq: [f64; AXIS_COUNT],
    sum_sq_xyz: f64,
    /// Letters a paired target reaches (X Y Z always).
    used: AxisSet,
    /// The largest changes with Δ of all nine letters (projected on finish).
    largest: Vec<(LargeChange, [f64; AXIS_COUNT])>,
    keep: usize,
    /// Motion blocks only in B just before the next pair: its pieces (count,
    /// first line).
    pending_pieces: usize,
    pending_first: usize,
}

impl DiffAccumulator {
    /// `keep`: how many of the largest changes (and added/removed lines) to keep.
    pub fn new(keep: usize) -> Self {
        DiffAccumulator {
            report: DiffReport::default(),
            changes: Axis::ALL.map(|a| AxisChange {
                axis: a.letter(),
                ..AxisChange::default()
            }),
            sum_abs: [0.0; AXIS_COUNT],
            sum_sq: [0.0; AXIS_COUNT],
            sum_sq_xyz: 0.0,
            used: AxisSet::of(&[Axis::X, Axis::Y, Axis::Z]),
            largest: Vec::new(),
            keep,
            pending_pieces: 0,
            pending_first: 0,
        }
    }

    /// Counts one aligned item (a pair, an added or a removed block).
    pub fn push(&mut self, item: &Aligned) {
        let r = &mut self.report;
        match item {
            Aligned::Added(b) => {
                r.blocks_b += 1;
                r.added += 1;
                if r.added_lines.len() < self.keep {
                    r.added_lines.push(b.line);
                }
                // Moves only in B before the next pair are its pieces (the
                // comment, dwell and mode lines of a flat block are not).
                if b.motion.is_some() {
                    if self.pending_pieces == 0 {
                        self.pending_first = b.line;
                    }
                    self.pending_pieces += 1;
                }
            }
            Aligned::Removed(a) => {
                self.pending_pieces = 0;
                r.blocks_a += 1;
                r.removed += 1;
                if r.removed_lines.len() < self.keep {
                    r.removed_lines.push(a.line);
                }
            }
            Aligned::Pair(a, b) => {
                r.blocks_a += 1;
                r.blocks_b += 1;
                r.paired += 1;
                let same = same_block(a, b);
                if same {
                    r.unchanged += 1;
                } else {
                    r.changed += 1;
                }
                let pieces = std::mem::take(&mut self.pending_pieces) + 1;
                if let (Some((_, ta)), Some((_, tb))) = (&a.motion, &b.motion) {
                    r.motion_pairs += 1;
                    if pieces > 1 {
                        r.split_blocks += 1;
                        r.split_pieces += pieces;
                        if r.splits.len() < self.keep {
                            r.splits.push(SplitBlock {
                                line_a: a.line,
                                first_line_b: self.pending_first,
                                last_line_b: b.line,
                                pieces,
                            });
                        }
                    }
                    let (va, vb) = (ta.to_array(), tb.to_array());
                    let mut delta = [0.0; AXIS_COUNT];
                    for i in 0..AXIS_COUNT {
                        if va[i] != 0.0 || vb[i] != 0.0 {
                            self.used = self.used.with(Axis::ALL[i]);
                        }
                        let d = vb[i] - va[i];
                        delta[i] = d;
                        self.sum_abs[i] += d.abs();
                        self.sum_sq[i] += d * d;
                        let ax = &mut self.changes[i];
                        if d.abs() > ax.max_abs {
                            ax.max_abs = d.abs();
                            ax.max_signed = d;
                        }
                    }
                    let xyz_um =
                        (delta[0].powi(2) + delta[1].powi(2) + delta[2].powi(2)).sqrt() * 1e3;
                    self.sum_sq_xyz += xyz_um * xyz_um;
                    r.max_xyz_change_um = r.max_xyz_change_um.max(xyz_um);
                    if delta.iter().any(|d| *d != 0.0) {
                        let change = LargeChange {
                            line_a: a.line,
                            line_b: b.line,
                            xyz_change_um: xyz_um,
                            delta: Vec::new(),
                            pieces,
                        };
                        insert_largest(&mut self.largest, (change, delta), self.keep);
                    }
                }
            }
        }
    }

    /// The report of everything pushed.
    pub fn finish(mut self) -> DiffReport {
        let n = self.report.motion_pairs.max(1) as f64;
        let used: Vec<usize> = self.used.iter().map(|a| a as usize).collect();
        for &i in &used {
            let mut change = self.changes[i].clone();
            change.mean_abs = self.sum_abs[i] / n;
            change.rms = (self.sum_sq[i] / n).sqrt();
            self.report.axes.push(change);
        }
        self.report.largest = self
            .largest
            .into_iter()
            .map(|(mut change, delta)| {
                change.delta = used.iter().map(|&i| delta[i] * 1e3).collect();
                change
            })
            .collect();
        self.report.rms_xyz_change_um = (self.sum_sq_xyz / n).sqrt();
        self.report
    }
}

/// Do two paired blocks say the same thing (same words, same targets)?
fn same_block(a: &BlockSummary, b: &BlockSummary) -> bool {
    a.key == b.key && a.motion == b.motion && a.number == b.number
}

fn insert_largest<T>(list: &mut Vec<(LargeChange, T)>, change: (LargeChange, T), keep: usize) {
    if keep == 0 {
        return;
    }
    if list.len() == keep
        && list
            .last()
            .is_some_and(|last| last.0.xyz_change_um >= change.0.xyz_change_um)
    {
        return;
    }
    let pos = list
        .iter()
        .position(|c| c.0.xyz_change_um < change.0.xyz_change_um)
        .unwrap_or(list.len());
    list.insert(pos, change);
    list.truncate(keep);
}
