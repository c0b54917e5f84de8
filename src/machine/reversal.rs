//! Reversal errors (formats.md "Laser positioning runs and reversal"): an axis
//! whose last motion was in the positive direction has positioning error
//! `E + REVERSAL/2`, in the negative direction `E − REVERSAL/2`; with no
//! known direction the model keeps the mean `E`.
//!
//! `REVERSAL` comes from the axis table's column of that name (`volcomp
//! import-laser` writes it; linear between the table's positions: a measured
//! value per position, not smoothed) or from the machine file's `[reversal]`
//! constant (docs/extensions.md), never both. Units: µm for a linear axis, µrad
//! for a rotary one. [`Approach`] says, per axis, how a pose was approached.
//!
//! Invariants: pure arithmetic, no I/O.
use crate::axes::{AXIS_COUNT, Axis};

/// Linear interpolation of `values` over `positions` at `p` (ends held).
pub fn interpolate(positions: &[f64], values: &[f64], p: f64) -> f64 {
    let n = positions.len().min(values.len());
    if n == 0 {
        return 0.0;
    }
    if p <= positions[0] {
        return values[0];
    }
    if p >= positions[n - 1] {
        return values[n - 1];
    }
    let k = positions[..n].partition_point(|x| *x <= p).clamp(1, n - 1);
    let (x0, x1) = (positions[k - 1], positions[k]);
    let t = (p - x0) / (x1 - x0);
    values[k - 1] + t * (values[k] - values[k - 1])
}

/// The direction of an axis's last motion.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub enum Direction {
    /// Not known (nothing moved the axis yet, or not asked): the mean error, no
    /// reversal term.
    #[default]
    Unknown,
    /// The axis's last motion was towards larger values (error `E + REVERSAL/2`).
    Positive,
    /// The axis's last motion was towards smaller values (error `E − REVERSAL/2`).
    Negative,
}

impl Direction {
    /// +1, −1, or 0 for unknown.
    pub fn sign(self) -> f64 {
        match self {
            Direction::Unknown => 0.0,
            Direction::Positive => 1.0,
            Direction::Negative => -1.0,
        }
    }

    /// The direction of a change `delta`, `None` when `|delta| ≤ dead`.
    pub fn of_change(delta: f64, dead: f64) -> Option<Direction> {
        if delta > dead {
            Some(Direction::Positive)
        } else if delta < -dead {
            Some(Direction::Negative)
        } else {
            None
        }
    }

    fn symbol(self) -> &'static str {
        match self {
            Direction::Unknown => "?",
            Direction::Positive => "+",
            Direction::Negative => "-",
        }
    }
}

/// How a pose was approached: the direction of each axis's last motion
/// (indexed by letter). [`Approach::NONE`]: no direction known anywhere (the
/// mean error, what every direction-free lookup gives).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Approach([Direction; AXIS_COUNT]);

/// Why a `--direction` text cannot be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("column {column}: {message}")]
pub struct ApproachParseError {
    /// 1-based character column in the text.
    pub column: usize,
    pub message: String,
}

impl Approach {
    /// No axis with a known direction: every reversal term is zero.
    pub const NONE: Approach = Approach([Direction::Unknown; AXIS_COUNT]);

    /// The direction of `axis`.
    pub fn get(&self, axis: Axis) -> Direction {
        self.0[axis as usize]
    }

    /// Set the direction of `axis`.
    pub fn set(&mut self, axis: Axis, direction: Direction) {
        self.0[axis as usize] = direction;
    }

    /// Whether no axis has a known direction.
    pub fn is_none(&self) -> bool {
        self.0.iter().all(|d| *d == Direction::Unknown)
    }

    /// `X+ Y-` (known directions only; empty when none).
    pub fn describe(&self) -> String {
        Axis::ALL
            .iter()
            .filter(|a| self.get(**a) != Direction::Unknown)
            .map(|a| format!("{}{}", a.letter(), self.get(*a).symbol()))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// Read `X+,Y-,C+` (letters in any case, `,` or spaces between entries; each
    /// entry a letter and `+` or `-`). An unknown letter, a missing or other
    /// sign, or a letter given twice is an error at its column. Whether the
    /// machine has the letter is the caller's check.
    pub fn parse(text: &str) -> Result<Approach, ApproachParseError> {
        let mut approach = Approach::NONE;
        let mut given = [false; AXIS_COUNT];
        let chars: Vec<(usize, char)> = text.chars().enumerate().collect();
        let mut i = 0;
        let err = |column: usize, message: String| ApproachParseError {
            column: column + 1,
            message,
        };
        let mut entries = 0;
        while i < chars.len() {
            let (col, c) = chars[i];
            if c == ',' || c.is_whitespace() {
                i += 1;
                continue;
            }
            let Some(axis) = Axis::from_letter(c) else {
                return Err(err(
                    col,
                    format!("`{c}` is not an axis letter (X Y Z A B C U V W)"),
                ));
            };
            let direction = match chars.get(i + 1).map(|x| x.1) {
                Some('+') => Direction::Positive,
                Some('-') | Some('−') => Direction::Negative,
                Some(other) => {
                    return Err(err(
                        col + 1,
                        format!(
                            "`{}` must be followed by + or - (its direction), not `{other}`",
                            axis.letter()
                        ),
                    ));
                }
                None => {
                    return Err(err(
                        col + 1,
                        format!(
                            "`{}` must be followed by + or - (its direction)",
                            axis.letter()
                        ),
                    ));
                }
            };
            if given[axis as usize] {
                return Err(err(
                    col,
                    format!("the direction of {} is given twice", axis.letter()),
                ));
            }
            given[axis as usize] = true;
            approach.set(axis, direction);
            entries += 1;
            i += 2;
        }
        if entries == 0 {
            return Err(err(
                0,
                "no direction given (expected entries such as X+,Y-)".into(),
            ));
        }
        Ok(approach)
    }
}

/// The reversal of one axis: its table's `REVERSAL` column or the machine
/// file's constant.
#[derive(Clone, Debug, PartialEq)]
pub enum AxisReversal {
    /// `[reversal]` in the machine file: the same value everywhere.
    Constant(f64),
    /// The table's `REVERSAL`, linear between its positions (ends held).
    Table {
        /// The table's positions (mm, or degrees for a rotary axis), ascending.
        positions: Vec<f64>,
        /// `REVERSAL` at each position (µm, or µrad for a rotary axis).
        values: Vec<f64>,
    },
}

impl AxisReversal {
    /// REVERSAL at table position `p` (µm or µrad).
    pub fn at(&self, p: f64) -> f64 {
        match self {
            AxisReversal::Constant(v) => *v,
            AxisReversal::Table { positions, values } => interpolate(positions, values, p),
        }
    }

    /// Where it comes from (messages).
    pub fn source(&self) -> &'static str {
        match self {
            AxisReversal::Constant(_) => "[reversal]",
            AxisReversal::Table { .. } => "REVERSAL column",
        }
    }
}

/// The reversal of one axis as lookups apply it: table positions wrap (a C
/// table over one revolution) and are clamped to the table's ends.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisPlay {
    pub axis: Axis,
    pub reversal: AxisReversal,
    /// The table's first and last position (±∞ for a constant).
    pub range: [f64; 2],
    pub wrap: bool,
}

impl AxisPlay {
    /// REVERSAL at joint value `joint` (µm or µrad).
    pub fn at_joint(&self, joint: f64) -> f64 {
        let [lo, hi] = self.range;
        let p = if self.wrap {
            lo + (joint - lo).rem_euclid(360.0)
        } else {
            joint
        };
        self.reversal.at(p.clamp(lo, hi))
    }

    /// |REVERSAL| at `joint` in the joint's own unit (mm, or degrees for a
    /// rotary axis): the play a motion must exceed to reverse the axis.
    fn play(&self, joint: f64) -> f64 {
        let r = self.at_joint(joint).abs();
        let play = if self.axis.is_rotary() {
            (r * 1e-6).to_degrees()
        } else {
            r * 1e-3
        };
        play.max(DEAD_BAND)
    }
}

/// Smallest change that counts as motion (mm or degrees): below the noise of
/// the part ↔ joint transforms, far below the programs' decimals.
pub const DEAD_BAND: f64 = 1e-9;

/// One axis's state in a [`DirectionTracker`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Track {
    direction: Direction,
    /// Where the last direction began its latest extreme (the turning point
    /// so far); before any direction, the first position seen.
    reference: Option<f64>,
}

/// The direction of each axis's last motion along a sequence of joint values
/// (docs/extensions.md "Reversal errors"). A motion against the current
/// direction reverses it only once it exceeds the axis's play |REVERSAL| from
/// the turning point (within the play the axis has not reversed: a
/// compensation's few-µm drift of an axis the program does not move leaves
/// its direction); before any motion larger than the play the direction is
/// unknown (the mean error). Only axes with a reversal are tracked.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DirectionTracker {
    axes: Vec<(AxisPlay, Track)>,
}

impl DirectionTracker {
    /// A tracker of the axes with a play, every direction unknown at first.
    pub fn new(plays: Vec<AxisPlay>) -> DirectionTracker {
        DirectionTracker {
            axes: plays.into_iter().map(|p| (p, Track::default())).collect(),
        }
    }

    /// Whether it tracks nothing (no axis has a reversal).
    pub fn is_empty(&self) -> bool {
        self.axes.is_empty()
    }

    /// Move to `joints` (a straight, monotone motion from the last joints).
    pub fn update(&mut self, joints: &crate::axes::Joints) {
        for (play, track) in &mut self.axes {
            let q = joints.get(play.axis);
            if !q.is_finite() {
                continue;
            }
            let Some(r) = track.reference else {
                track.reference = Some(q);
                continue;
            };
            let h = play.play(q);
            match track.direction {
                Direction::Unknown => {
                    if let Some(d) = Direction::of_change(q - r, h) {
                        track.direction = d;
                        track.reference = Some(q);
                    }
                }
                Direction::Positive => {
                    if q > r {
                        track.reference = Some(q);
                    } else if q < r - h {
                        track.direction = Direction::Negative;
                        track.reference = Some(q);
                    }
                }
                Direction::Negative => {
                    if q < r {
                        track.reference = Some(q);
                    } else if q > r + h {
                        track.direction = Direction::Positive;
                        track.reference = Some(q);
                    }
                }
            }
        }
    }

    /// The directions now.
    pub fn approach(&self) -> Approach {
        let mut a = Approach::NONE;
        for (play, track) in &self.axes {
            a.set(play.axis, track.direction);
        }
        a
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_directions_and_refuses_what_it_cannot_read() {
        let a = Approach::parse("X+,y- C+").unwrap();
        assert_eq!(a.get(Axis::X), Direction::Positive);
        assert_eq!(a.get(Axis::Y), Direction::Negative);
        assert_eq!(a.get(Axis::C), Direction::Positive);
        assert_eq!(a.get(Axis::Z), Direction::Unknown);
        assert_eq!(a.describe(), "X+ Y- C+");
        let e = Approach::parse("X+,Q-").unwrap_err();
        assert_eq!(e.column, 4);
        assert!(e.message.contains("`Q`"), "{e}");
        let e = Approach::parse("X+,Y").unwrap_err();
        assert_eq!(e.column, 5);
        let e = Approach::parse("X+,Y*").unwrap_err();
        assert_eq!((e.column, e.message.contains("`*`")), (5, true));
        let e = Approach::parse("X+,x-").unwrap_err();
        assert!(e.message.contains("twice"), "{e}");
        assert!(Approach::parse(" , ").is_err());
    }

    #[test]
    fn interpolates_linearly_and_holds_the_ends() {
        let r = AxisReversal::Table {
            positions: vec![0.0, 10.0, 20.0],
            values: vec![2.0, 4.0, 0.0],
        };
        assert_eq!(r.at(-5.0), 2.0);
        assert_eq!(r.at(5.0), 3.0);
        assert_eq!(r.at(15.0), 2.0);
        assert_eq!(r.at(25.0), 0.0);
        assert_eq!(AxisReversal::Constant(8.0).at(1e3), 8.0);
    }

    #[test]
    fn a_motion_within_the_play_does_not_reverse_the_axis() {
        let play = AxisPlay {
            axis: Axis::X,
            reversal: AxisReversal::Constant(8.0),
            range: [f64::NEG_INFINITY, f64::INFINITY],
            wrap: false,
        };
        let mut t = DirectionTracker::new(vec![play]);
        let at = |x: f64| {
            crate::axes::Joints::new(crate::axes::Axes {
                x,
                ..Default::default()
            })
        };
        let dir = |t: &DirectionTracker| t.approach().get(Axis::X);
        t.update(&at(0.0));
        assert_eq!(dir(&t), Direction::Unknown);
        t.update(&at(0.005));
        assert_eq!(dir(&t), Direction::Unknown, "5 µm is within the 8 µm play");
        t.update(&at(50.0));
        assert_eq!(dir(&t), Direction::Positive);
        t.update(&at(49.995));
        assert_eq!(dir(&t), Direction::Positive, "back 5 µm: still +");
        t.update(&at(49.991));
        assert_eq!(dir(&t), Direction::Negative, "back 9 µm: −");
        t.update(&at(49.995));
        assert_eq!(dir(&t), Direction::Negative);
        t.update(&at(60.0));
        assert_eq!(dir(&t), Direction::Positive);
        assert_eq!(t.approach().get(Axis::Y), Direction::Unknown);
    }
}
