//! The rotary joints a control holds under a swivelled working plane
//! (dialects.md "Writing back": under a tilted plane the tip is corrected,
//! and the tool axis where the program commands the rotary axes itself).
//!
//! After `PLANE … STAY` (or `CYCL DEF 19` without a feed) a Klartext
//! program turns the rotary axes itself (`L B+Q121 C+Q122 FMAX`): that
//! block is not held ([`crate::gcode::Origin::holds_rotary`] is false for
//! it), so it is compensated in tip and tool axis and its corrected rotary
//! words are written. The blocks after it, which the plane holds, then run
//! at those *written* rotary positions, not at the nominal ones: each held
//! move whose programmed rotary joints are still those of the last
//! compensated move is solved (tip only) at that move's corrected rotary
//! joints, so that its tip lands where the model says at the axes the
//! control really holds, and its tool axis is the corrected one.
//!
//! Invariants: only held moves are changed, and only their rotary joints
//! (start and end, to the same values: a held move does not turn the
//! axes); an uncompensated motion (a `PLANE … TURN` leg, `M91`) or a held
//! move at other rotary joints ends the hold; the correction of a source
//! move is solved once, here, and reused by the parallel pass.
use std::collections::HashMap;

use super::{
    Chunk, CompensateOptions, Compensated, WarmStart, compensate_target, compensated_moves,
};
use crate::axes::Axes;
use crate::gcode::{Motion, Moves};
use crate::machine::{Approach, ToolModels};

/// The rotary joints the control holds: the programmed (nominal) ones of
/// the move that wrote them, and the corrected ones it wrote.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct HeldRotary {
    nominal: [f64; 3],
    corrected: [f64; 3],
}

/// Where the held rotary joints come from, scanning a chunk in order.
#[derive(Clone, Copy, Debug)]
enum Source {
    /// Nothing held (or nothing corrected).
    None,
    /// From a move of an earlier chunk.
    Carried(HeldRotary),
    /// From this chunk's compensated move with this flat index, at these
    /// nominal rotary joints.
    Move(usize, [f64; 3]),
}

/// What [`hold_corrected_rotary`] leaves for the rest of the chunk's solve.
#[derive(Debug, Default)]
pub(super) struct HeldSolves {
    /// The solved correction of each source move (flat index over the
    /// chunk's compensated moves), to be used as it is.
    pub presolved: HashMap<usize, Compensated>,
    /// The source the next chunk carries, when it is a move of this chunk
    /// (its flat index and nominal rotary joints): [`HeldSolves::carry`]
    /// turns it into a [`HeldRotary`] once its correction is known.
    pending: Option<(usize, [f64; 3])>,
    /// The held rotary joints carried on when the chunk ends on no move of its own.
    carried: Option<HeldRotary>,
}

impl HeldSolves {
    /// The flat index of this chunk's move whose corrected rotary joints
    /// the next chunk holds, if any.
    pub fn pending_move(&self) -> Option<usize> {
        self.pending.map(|(k, _)| k)
    }

    /// The held rotary joints the next chunk starts with, given the
    /// compensated end of [`HeldSolves::pending_move`].
    pub fn carry(&self, pending_end: Option<Axes>) -> Option<HeldRotary> {
        match self.pending {
            Some((_, nominal)) => pending_end.map(|c| HeldRotary {
                nominal,
                corrected: rotary(&c),
            }),
            None => self.carried,
        }
    }
}

fn rotary(a: &Axes) -> [f64; 3] {
    [a.a, a.b, a.c]
}

fn set_rotary(a: &mut Axes, r: [f64; 3]) {
    a.a = r[0];
    a.b = r[1];
    a.c = r[2];
}

fn moves_mut(moves: &mut Moves) -> &mut [Motion] {
    match moves {
        Moves::Move(m) => std::slice::from_mut(m),
        Moves::Cycle { moves, .. } | Moves::Spline(moves) | Moves::Home(moves) => moves,
        Moves::None => &mut [],
    }
}

/// Hold the rotary joints of the chunk's held moves at the corrected ones
/// of the compensated move that last wrote them (module doc), starting from
/// `carried`; solves those source moves (`approaches`: each compensated
/// move's approach, flat). A source whose solve fails is left to the
/// parallel pass, which reports the failure; its dependants stay nominal.
pub(super) fn hold_corrected_rotary(
    chunk: &mut Chunk,
    carried: Option<HeldRotary>,
    models: &ToolModels,
    options: &CompensateOptions,
    approaches: &[Approach],
) -> HeldSolves {
    let mut solves = HeldSolves::default();
    if !options.orientation {
        return solves;
    }
    // 1. Which held moves depend on which source.
    let mut source = carried.map_or(Source::None, Source::Carried);
    let mut dependants: Vec<(usize, usize, Source)> = Vec::new(); // (block, move in block, source)
    let mut k = 0usize;
    for (b, (_, event)) in chunk.iter().enumerate() {
        if event.skipped {
            continue;
        }
        let compensated = compensated_moves(event);
        if compensated.is_empty() {
            if event.motions().next().is_some() {
                source = Source::None;
            }
            continue;
        }
        let held = event.origin.holds_rotary();
        for (i, m) in compensated.iter().enumerate() {
            let nominal = rotary(&m.end);
            if !held {
                source = Source::Move(k, nominal);
            } else {
                match source {
                    Source::Carried(h) if h.nominal == nominal && rotary(&m.start) == nominal => {
                        dependants.push((b, i, source));
                    }
                    Source::Move(_, n) if n == nominal && rotary(&m.start) == nominal => {
                        dependants.push((b, i, source));
                    }
                    _ => source = Source::None,
                }
            }
            k += 1;
        }
    }
    solves.pending = match source {
        Source::Move(k, n) => Some((k, n)),
        _ => None,
    };
    solves.carried = match source {
        Source::Carried(h) => Some(h),
        _ => None,
    };
    if dependants.is_empty() {
        return solves;
    }
    // 2. The sources' corrections, in order (each from a cold start).
    let mut wanted: Vec<usize> = dependants
        .iter()
        .filter_map(|(_, _, s)| match s {
            Source::Move(k, _) => Some(*k),
            _ => None,
        })
        .collect();
    wanted.dedup();
    let mut k = 0usize;
    let mut next = wanted.iter().peekable();
    'blocks: for (_, event) in chunk.iter() {
        for m in compensated_moves(event) {
            if next.peek() == Some(&&k) {
                next.next();
                let solved = compensate_target(
                    models.get(&event.tool),
                    &m.end_pose(),
                    options.limits.as_ref(),
                    &mut WarmStart::default(),
                    true,
                    &approaches[k],
                );
                if let Ok(c) = solved {
                    solves.presolved.insert(k, c);
                }
            }
            k += 1;
            if next.peek().is_none() {
                break 'blocks;
            }
        }
    }
    // 3. The dependants at the held, corrected rotary joints.
    for (b, i, s) in dependants {
        let corrected = match s {
            Source::Carried(h) => h.corrected,
            Source::Move(k, _) => match solves.presolved.get(&k) {
                Some(c) => rotary(&c.target.axes()),
                None => continue,
            },
            Source::None => continue,
        };
        let m = &mut moves_mut(&mut chunk[b].1.moves)[i];
        set_rotary(&mut m.start, corrected);
        set_rotary(&mut m.end, corrected);
    }
    solves
}
