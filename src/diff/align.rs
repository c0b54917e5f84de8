//! Block alignment of two programs, streaming.
//!
//! Two blocks *match* when both carry the same N number (when both have one), or
//! else when both are motion blocks of the same kind (an arc and a straight
//! move count as one kind: a split arc ends in a straight piece) whose end
//! targets agree within the match tolerance, or else when their words (without
//! N and comments) are equal. The aligner walks both programs with a bounded
//! look-ahead window: at each step it pairs matching blocks, or takes the
//! shortest run of insertions (blocks only in B, such as the pieces of a split
//! move) or deletions that restores a match, or else pairs the two blocks as a
//! substitution. Memory is bounded by the window, except while the straight
//! pieces of a split arc are followed along the arc (at most
//! [`MAX_ARC_PIECES`] blocks).
use crate::axes::Axes;
use crate::gcode::Motion;
use crate::gcode::motion::to_plane;
use std::collections::VecDeque;

/// Most straight pieces of one split arc followed beyond the window
/// (`compensate` writes at most 100,000 chords an arc).
pub const MAX_ARC_PIECES: usize = 200_000;

/// What the aligner needs of a block.
#[derive(Clone, Debug, PartialEq)]
pub struct BlockSummary {
    /// Program line, 1-based.
    pub line: usize,
    /// N number, if written.
    pub number: Option<u64>,
    /// Motion kind code (0 = G0, 1 = G1, 2 = G2, 3 = G3) and absolute end target of a
    /// motion block, in mm/degrees.
    pub motion: Option<(u8, Axes)>,
    /// The block's words without N number and comments, normalised (upper case, no spaces).
    pub key: String,
    /// The block's last move (its path: an arc's centre and turns), when it
    /// has one.
    pub path: Option<Motion>,
    /// The line of the original program this block stands for when a writer
    /// said so (`compensate`, `check --flatten`): a canned cycle or a spline
    /// written flat (`(volcomp: G81 of line 5 expanded below)`, `(volcomp: G5
    /// of line 4 written flat below)`), a G5.2 control point; the pieces
    /// follow it.
    pub written_for: Option<usize>,
}

/// One step of the alignment.
// A pair holds both sides by value: the aligner keeps a bounded window of
// these, and boxing would allocate twice per block.
#[allow(clippy::large_enum_variant)]
#[derive(Clone, Debug, PartialEq)]
pub enum Aligned {
    /// Present in both (possibly changed).
    Pair(BlockSummary, BlockSummary),
    /// Only in A.
    Removed(BlockSummary),
    /// Only in B.
    Added(BlockSummary),
}

/// Settings of the alignment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlignOptions {
    /// Motion blocks whose targets differ by less than this (mm, and degrees) match.
    pub match_tolerance: f64,
    /// Largest run of insertions or deletions looked for.
    pub window: usize,
}

impl Default for AlignOptions {
    fn default() -> Self {
        AlignOptions {
            match_tolerance: 0.05,
            window: 1024,
        }
    }
}

/// Do `a` and `b` match (see the module docs)?
pub fn blocks_match(a: &BlockSummary, b: &BlockSummary, tolerance: f64) -> bool {
    if let (Some(na), Some(nb)) = (a.number, b.number) {
        return na == nb;
    }
    match (&a.motion, &b.motion) {
        (Some((ka, ta)), Some((kb, tb))) => {
            same_kind(*ka, *kb)
                && ta
                    .to_array()
                    .iter()
                    .zip(tb.to_array())
                    .all(|(x, y)| (x - y).abs() <= tolerance)
        }
        (None, None) => a.key == b.key,
        _ => false,
    }
}

/// How far apart the ends of two motion blocks are (largest axis
/// difference, mm or degrees); infinite unless both move.
fn end_distance(a: &BlockSummary, b: &BlockSummary) -> f64 {
    match (&a.motion, &b.motion) {
        (Some((_, ta)), Some((_, tb))) => ta
            .to_array()
            .iter()
            .zip(tb.to_array())
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max),
        _ => f64::INFINITY,
    }
}

/// Motion kind codes that pair: equal, or an arc (2, 3) and a straight feed
/// move (1): a split arc's last piece is a `G1`.
fn same_kind(a: u8, b: u8) -> bool {
    a == b || matches!((a, b), (2 | 3, 1) | (1, 2 | 3))
}

/// Does `b`'s end lie on `arc`'s path (its helix), within `tolerance`? A
/// piece of the arc split into straight pieces does.
fn on_arc(arc: &Motion, b: &BlockSummary, tolerance: f64) -> bool {
    let (crate::gcode::MotionKind::Arc { centre, plane, .. }, Some((1, end)), None) =
        (arc.kind, &b.motion, b.number)
    else {
        return false;
    };
    let (p, c) = (to_plane(plane, end.xyz()), to_plane(plane, centre));
    let (s, e) = (
        to_plane(plane, arc.start.xyz()),
        to_plane(plane, arc.end.xyz()),
    );
    let (r0, r1) = (
        (s[0] - c[0]).hypot(s[1] - c[1]),
        (e[0] - c[0]).hypot(e[1] - c[1]),
    );
    let r = (p[0] - c[0]).hypot(p[1] - c[1]);
    r >= r0.min(r1) - tolerance
        && r <= r0.max(r1) + tolerance
        && p[2] >= s[2].min(e[2]) - tolerance
        && p[2] <= s[2].max(e[2]) + tolerance
}

/// Streaming aligner over two block iterators.
pub struct Aligner<A, B>
where
    A: Iterator<Item = BlockSummary>,
    B: Iterator<Item = BlockSummary>,
{
    a: A,
    b: B,
    buf_a: VecDeque<BlockSummary>,
    buf_b: VecDeque<BlockSummary>,
    options: AlignOptions,
    /// Queued output of the last step.
    out: VecDeque<Aligned>,
}

impl<A, B> Aligner<A, B>
where
    A: Iterator<Item = BlockSummary>,
    B: Iterator<Item = BlockSummary>,
{
    /// Pairs the blocks of `a` with those of `b`.
    pub fn new(a: A, b: B, options: AlignOptions) -> Self {
        Aligner {
            a,
            b,
            buf_a: VecDeque::new(),
            buf_b: VecDeque::new(),
            options,
            out: VecDeque::new(),
        }
    }

    fn fill(&mut self) {
        let want = self.options.window + 1;
        while self.buf_a.len() < want {
            match self.a.next() {
                Some(x) => self.buf_a.push_back(x),
                None => break,
            }
        }
        while self.buf_b.len() < want {
            match self.b.next() {
                Some(x) => self.buf_b.push_back(x),
                None => break,
            }
        }
    }

    fn step(&mut self) {
        self.fill();
        let tol = self.options.match_tolerance;
        match (self.buf_a.front(), self.buf_b.front()) {
            (None, None) => {}
            (Some(_), None) => {
                let x = self.buf_a.pop_front().expect("front");
                self.out.push_back(Aligned::Removed(x));
            }
            (None, Some(_)) => {
                let x = self.buf_b.pop_front().expect("front");
                self.out.push_back(Aligned::Added(x));
            }
            (Some(_), Some(_)) => {
                let (fa, fb) = (&self.buf_a[0], &self.buf_b[0]);
                if fb.written_for == Some(fa.line) {
                    // Written flat for this block: it pairs with its last move.
                    let k = if fa.motion.is_some() {
                        self.flat_pieces()
                    } else {
                        0
                    };
                    self.pair_after(k);
                    return;
                }
                if blocks_match(fa, fb, tol) {
                    let k = self.closest_in_run(0);
                    self.pair_after(k);
                    return;
                }
                if let Some(n) = self.arc_pieces() {
                    let k = self.closest_in_run(n);
                    self.pair_after(k);
                    return;
                }
                let (fa, fb) = (&self.buf_a[0], &self.buf_b[0]);
                // Shortest run of insertions in B or deletions from A that restores a match.
                let insert = self
                    .buf_b
                    .iter()
                    .skip(1)
                    .position(|b| blocks_match(fa, b, tol));
                let delete = self
                    .buf_a
                    .iter()
                    .skip(1)
                    .position(|a| blocks_match(a, fb, tol));
                match (insert, delete) {
                    (Some(i), d) if d.is_none_or(|d| i <= d) => {
                        let k = self.closest_in_run(i + 1);
                        self.pair_after(k);
                    }
                    (_, Some(d)) => {
                        for _ in 0..=d {
                            let x = self.buf_a.pop_front().expect("buffered");
                            self.out.push_back(Aligned::Removed(x));
                        }
                    }
                    _ => {
                        let x = self.buf_a.pop_front().expect("front");
                        let y = self.buf_b.pop_front().expect("front");
                        self.out.push_back(Aligned::Pair(x, y));
                    }
                }
            }
        }
    }
}

impl<A, B> Aligner<A, B>
where
    A: Iterator<Item = BlockSummary>,
    B: Iterator<Item = BlockSummary>,
{
    /// B's block `k` matches A's next block: the block of the run of
    /// matching blocks from `k` on that ends closest to it (the short pieces
    /// at the end of a split move all end within the match tolerance of it;
    /// the last one ends where it ends).
    fn closest_in_run(&mut self, mut k: usize) -> usize {
        let tol = self.options.match_tolerance;
        loop {
            if k + 1 >= self.buf_b.len() {
                if self.buf_b.len() >= MAX_ARC_PIECES {
                    return k;
                }
                match self.b.next() {
                    Some(x) => self.buf_b.push_back(x),
                    None => return k,
                }
            }
            let fa = &self.buf_a[0];
            let (here, next) = (&self.buf_b[k], &self.buf_b[k + 1]);
            if blocks_match(fa, next, tol) && end_distance(fa, next) < end_distance(fa, here) {
                k += 1;
            } else {
                return k;
            }
        }
    }

    /// B's next block says it is written flat for A's next: the index of
    /// the piece that ends where A's block ends (the first of the pieces
    /// that follow, moves without N numbers and the dwell, spindle and
    /// distance-mode lines of a flat cycle, that matches it, then the
    /// closest of the run), read beyond the window up to
    /// [`MAX_ARC_PIECES`]; 0 (the comment line itself) when none does.
    fn flat_pieces(&mut self) -> usize {
        let tol = self.options.match_tolerance;
        let mut k = 1;
        loop {
            if k >= self.buf_b.len() {
                if k >= MAX_ARC_PIECES {
                    return 0;
                }
                match self.b.next() {
                    Some(x) => self.buf_b.push_back(x),
                    None => return 0,
                }
            }
            let b = &self.buf_b[k];
            let piece = b.number.is_none() && b.written_for.is_none();
            let step = matches!(
                b.key.as_str(),
                "G90" | "G91" | "M3" | "M4" | "M5" | "M48" | "M49" | "M0"
            ) || b.key.starts_with("G4P");
            if !piece || (b.motion.is_none() && !step) {
                return 0;
            }
            if b.motion.is_some() && blocks_match(&self.buf_a[0], b, tol) {
                return self.closest_in_run(k);
            }
            k += 1;
        }
    }

    /// B's first `k` blocks are added; then A's next and B's next pair.
    fn pair_after(&mut self, k: usize) {
        for _ in 0..k {
            let y = self.buf_b.pop_front().expect("buffered");
            self.out.push_back(Aligned::Added(y));
        }
        let x = self.buf_a.pop_front().expect("front");
        let y = self.buf_b.pop_front().expect("buffered");
        self.out.push_back(Aligned::Pair(x, y));
    }

    /// When A's next block is an arc and B's next blocks are straight pieces
    /// along it: how many come before the one that ends where the arc ends
    /// (read beyond the window, up to [`MAX_ARC_PIECES`]); `None` otherwise.
    fn arc_pieces(&mut self) -> Option<usize> {
        let tol = self.options.match_tolerance;
        let fa = self.buf_a.front()?;
        let arc = fa
            .path
            .filter(|m| matches!(m.kind, crate::gcode::MotionKind::Arc { .. }))?;
        let mut k = 0;
        loop {
            if k >= self.buf_b.len() {
                if k >= MAX_ARC_PIECES {
                    return None;
                }
                self.buf_b.push_back(self.b.next()?);
            }
            let b = &self.buf_b[k];
            if k > 0 && blocks_match(fa, b, tol) {
                return Some(k);
            }
            if !on_arc(&arc, b, tol) {
                return None;
            }
            k += 1;
        }
    }
}

impl<A, B> Iterator for Aligner<A, B>
where
    A: Iterator<Item = BlockSummary>,
    B: Iterator<Item = BlockSummary>,
{
    type Item = Aligned;

    fn next(&mut self) -> Option<Aligned> {
        if self.out.is_empty() {
            self.step();
        }
        self.out.pop_front()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motion(line: usize, x: f64) -> BlockSummary {
        BlockSummary {
            line,
            number: None,
            motion: Some((1, Axes::xyzac(x, 0.0, 0.0, 0.0, 0.0))),
            key: format!("G1X{x}"),
            path: None,
            written_for: None,
        }
    }

    #[test]
    fn split_moves_are_insertions() {
        let a = vec![motion(1, 0.0), motion(2, 10.0), motion(3, 20.0)];
        let b = vec![
            motion(1, 0.0001),
            motion(2, 5.0),
            motion(3, 10.0002),
            motion(4, 20.0),
        ];
        let out: Vec<Aligned> =
            Aligner::new(a.into_iter(), b.into_iter(), AlignOptions::default()).collect();
        let kinds: Vec<&str> = out
            .iter()
            .map(|x| match x {
                Aligned::Pair(..) => "pair",
                Aligned::Added(_) => "added",
                Aligned::Removed(_) => "removed",
            })
            .collect();
        assert_eq!(kinds, vec!["pair", "added", "pair", "pair"]);
    }

    #[test]
    fn n_numbers_decide_when_both_have_them() {
        let mut a = motion(1, 0.0);
        a.number = Some(10);
        let mut b = motion(1, 3.0);
        b.number = Some(10);
        assert!(blocks_match(&a, &b, 0.05));
        b.number = Some(20);
        assert!(!blocks_match(&a, &b, 0.05));
    }
}
