//! Axis positions shared by every layer: the nine axis letters of RS274NGC
//! (`X Y Z A B C U V W`, LinuxCNC's `EmcPose`), linear in mm, rotary in degrees.
//!
//! The program layer tracks all nine, as LinuxCNC's interpreter does; a machine
//! has X Y Z, two of A B C and possibly some of U V W (`kinematics::MachineChain`
//! says which), and a word for a letter the machine lacks is refused where the
//! machine is known. `Axes` is a bare set of numbers: a value that *is* a machine
//! joint position is a [`Joints`]; a motion's target says its frame as a
//! `gcode::Pose` (joint commands, or the tool tip in part coordinates plus the
//! rotary joints), and `toolpath::joints_of` / `toolpath::pose_of` are the one
//! conversion between the two.
use serde::{Deserialize, Serialize};

/// A position of all nine axes. Letters a machine lacks stay 0.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Axes {
    /// X, mm.
    pub x: f64,
    /// Y, mm.
    pub y: f64,
    /// Z, mm.
    pub z: f64,
    /// A (rotary about X), degrees.
    pub a: f64,
    /// B (rotary about Y), degrees.
    #[serde(default)]
    pub b: f64,
    /// C (rotary about Z), degrees.
    pub c: f64,
    /// U (linear, parallel to X), mm.
    #[serde(default)]
    pub u: f64,
    /// V (linear, parallel to Y), mm.
    #[serde(default)]
    pub v: f64,
    /// W (linear, parallel to Z), mm.
    #[serde(default)]
    pub w: f64,
}

/// A machine joint position: X Y Z (and U V W) machine coordinates in mm, the
/// rotary joints in degrees, as the axes are commanded. Kinematics evaluates
/// joints; a program's target becomes joints only through
/// `toolpath::joints_of` (a part-frame target needs the kinematics), so a
/// value of this type never holds a part-frame tool tip. It reads as the
/// [`Axes`] it wraps.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(transparent)]
pub struct Joints(Axes);

impl Joints {
    /// The joint position whose values are `axes` (machine coordinates: a
    /// joint-frame or G53 target, a solver's result).
    pub const fn new(axes: Axes) -> Joints {
        Joints(axes)
    }

    /// The values, as bare [`Axes`].
    pub const fn axes(&self) -> Axes {
        self.0
    }
}

impl std::ops::Deref for Joints {
    type Target = Axes;

    fn deref(&self) -> &Axes {
        &self.0
    }
}

/// One of the nine axis letters, in RS274NGC order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Axis {
    /// Linear, mm.
    X,
    /// Linear, mm.
    Y,
    /// Linear, mm.
    Z,
    /// Rotary about X, degrees.
    A,
    /// Rotary about Y, degrees.
    B,
    /// Rotary about Z, degrees.
    C,
    /// Linear, parallel to X, mm.
    U,
    /// Linear, parallel to Y, mm.
    V,
    /// Linear, parallel to Z, mm.
    W,
}

/// Number of axis letters.
pub const AXIS_COUNT: usize = 9;

impl Axis {
    /// Every letter, in RS274NGC order (the index of a letter is `axis as usize`).
    pub const ALL: [Axis; AXIS_COUNT] = [
        Axis::X,
        Axis::Y,
        Axis::Z,
        Axis::A,
        Axis::B,
        Axis::C,
        Axis::U,
        Axis::V,
        Axis::W,
    ];

    /// The upper-case letter, as a G-code word writes it.
    pub fn letter(self) -> char {
        match self {
            Axis::X => 'X',
            Axis::Y => 'Y',
            Axis::Z => 'Z',
            Axis::A => 'A',
            Axis::B => 'B',
            Axis::C => 'C',
            Axis::U => 'U',
            Axis::V => 'V',
            Axis::W => 'W',
        }
    }

    /// The lower-case letter (machine-file keys, CSV columns).
    pub fn lower(self) -> char {
        self.letter().to_ascii_lowercase()
    }

    /// A, B and C turn (degrees); the others travel (mm).
    pub fn is_rotary(self) -> bool {
        matches!(self, Axis::A | Axis::B | Axis::C)
    }

    /// The axis of a letter, either case; `None` for a letter that is not an axis.
    pub fn from_letter(c: char) -> Option<Axis> {
        match c.to_ascii_uppercase() {
            'X' => Some(Axis::X),
            'Y' => Some(Axis::Y),
            'Z' => Some(Axis::Z),
            'A' => Some(Axis::A),
            'B' => Some(Axis::B),
            'C' => Some(Axis::C),
            'U' => Some(Axis::U),
            'V' => Some(Axis::V),
            'W' => Some(Axis::W),
            _ => None,
        }
    }

    /// "mm" or "°".
    pub fn unit(self) -> &'static str {
        if self.is_rotary() { "°" } else { "mm" }
    }
}

/// A set of axis letters (which letters a machine has).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct AxisSet(u16);

impl Default for AxisSet {
    /// Every letter (a program read without a machine, as LinuxCNC's `rs274`).
    fn default() -> Self {
        AxisSet::ALL
    }
}

impl AxisSet {
    /// All nine letters.
    pub const ALL: AxisSet = AxisSet((1 << AXIS_COUNT) - 1);
    /// X Y Z A B C: what LinuxCNC's `rs274` reads without an INI file.
    pub const RS274: AxisSet = AxisSet(0b111111);
    /// No letter.
    pub const EMPTY: AxisSet = AxisSet(0);

    /// The set of `axes`.
    pub fn of(axes: &[Axis]) -> AxisSet {
        axes.iter().fold(AxisSet::EMPTY, |s, a| s.with(*a))
    }

    /// This set with `axis` added.
    pub fn with(self, axis: Axis) -> AxisSet {
        AxisSet(self.0 | (1 << axis as u16))
    }

    /// Whether `axis` is in the set.
    pub fn contains(self, axis: Axis) -> bool {
        self.0 & (1 << axis as u16) != 0
    }

    /// The letters of the set, in RS274NGC order.
    pub fn iter(self) -> impl Iterator<Item = Axis> {
        Axis::ALL.into_iter().filter(move |a| self.contains(*a))
    }

    /// The letters, in order (`"XYZBC"`).
    pub fn letters(self) -> String {
        self.iter().map(Axis::letter).collect()
    }
}

impl Axes {
    /// A position of an A/C machine (`xyzac-trt`); the other letters 0.
    pub const fn xyzac(x: f64, y: f64, z: f64, a: f64, c: f64) -> Self {
        Axes {
            x,
            y,
            z,
            a,
            b: 0.0,
            c,
            u: 0.0,
            v: 0.0,
            w: 0.0,
        }
    }

    /// X Y Z and every rotary letter 0 but `rotary`s.
    pub fn xyz_rotary(xyz: [f64; 3], rotary: [(Axis, f64); 2]) -> Self {
        let mut out = Axes {
            x: xyz[0],
            y: xyz[1],
            z: xyz[2],
            ..Axes::default()
        };
        for (axis, v) in rotary {
            out.set(axis, v);
        }
        out
    }

    /// The value of one letter (mm or degrees).
    pub fn get(&self, axis: Axis) -> f64 {
        match axis {
            Axis::X => self.x,
            Axis::Y => self.y,
            Axis::Z => self.z,
            Axis::A => self.a,
            Axis::B => self.b,
            Axis::C => self.c,
            Axis::U => self.u,
            Axis::V => self.v,
            Axis::W => self.w,
        }
    }

    /// Sets the value of one letter (mm or degrees).
    pub fn set(&mut self, axis: Axis, value: f64) {
        match axis {
            Axis::X => self.x = value,
            Axis::Y => self.y = value,
            Axis::Z => self.z = value,
            Axis::A => self.a = value,
            Axis::B => self.b = value,
            Axis::C => self.c = value,
            Axis::U => self.u = value,
            Axis::V => self.v = value,
            Axis::W => self.w = value,
        }
    }

    /// `[x, y, z]`, mm.
    pub fn xyz(&self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    /// All nine, in [`Axis::ALL`] order.
    pub fn to_array(&self) -> [f64; AXIS_COUNT] {
        [
            self.x, self.y, self.z, self.a, self.b, self.c, self.u, self.v, self.w,
        ]
    }

    /// From all nine, in [`Axis::ALL`] order.
    pub fn from_array(v: [f64; AXIS_COUNT]) -> Self {
        Axes {
            x: v[0],
            y: v[1],
            z: v[2],
            a: v[3],
            b: v[4],
            c: v[5],
            u: v[6],
            v: v[7],
            w: v[8],
        }
    }

    /// `f` applied letter by letter to `self` and `other`. Always inlined:
    /// it is on every block's path (origins, interpolation), and a build
    /// that leaves it out of line reads LinuxCNC programs measurably slower.
    #[inline(always)]
    pub fn zip_with(&self, other: &Axes, f: impl Fn(f64, f64) -> f64) -> Axes {
        let (a, b) = (self.to_array(), other.to_array());
        Axes::from_array(std::array::from_fn(|i| f(a[i], b[i])))
    }

    /// Linear interpolation of every axis (rotary axes taken literally, no shortest path).
    pub fn lerp(&self, other: &Axes, t: f64) -> Axes {
        self.zip_with(other, |a, b| a + (b - a) * t)
    }

    /// Length of the XYZ part of `other - self`, mm.
    pub fn xyz_distance(&self, other: &Axes) -> f64 {
        let dx = other.x - self.x;
        let dy = other.y - self.y;
        let dz = other.z - self.z;
        (dx * dx + dy * dy + dz * dz).sqrt()
    }

    /// `√(Σ Δ²)` over the rotary letters A B C, degrees.
    pub fn rotary_distance(&self, other: &Axes) -> f64 {
        let (da, db, dc) = (other.a - self.a, other.b - self.b, other.c - self.c);
        (da * da + db * db + dc * dc).sqrt()
    }

    /// The largest `|Δ|` over the rotary letters A B C, degrees.
    pub fn rotary_max_step(&self, other: &Axes) -> f64 {
        (other.a - self.a)
            .abs()
            .max((other.b - self.b).abs())
            .max((other.c - self.c).abs())
    }

    /// Length of the U V W part of `other - self`, mm.
    pub fn uvw_distance(&self, other: &Axes) -> f64 {
        let (du, dv, dw) = (other.u - self.u, other.v - self.v, other.w - self.w);
        (du * du + dv * dv + dw * dw).sqrt()
    }

    /// Whether every one of the nine values is finite (no NaN, no infinity).
    pub fn is_finite(&self) -> bool {
        self.to_array().iter().all(|v| v.is_finite())
    }

    /// The axis words of `letters` with `decimals` decimals: `X1.0000 Y2.0000 …`.
    pub fn words(&self, letters: AxisSet, decimals: usize) -> String {
        letters
            .iter()
            .map(|a| format!("{}{:.*}", a.letter(), decimals, self.get(a)))
            .collect::<Vec<_>>()
            .join(" ")
    }
}
