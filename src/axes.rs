//! Five-axis positions shared by every layer: `X Y Z` in mm, `A C` in degrees.
//!
//! The same type carries joint commands (machine coordinates, as a joint-frame
//! program writes them) and part-frame targets (tool tip in part coordinates plus
//! A and C); which one a value is depends on where it came from (see `gcode::Frame`).
use serde::{Deserialize, Serialize};

#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Axes {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub a: f64,
    pub c: f64,
}

/// One of the five axes, in program order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Axis {
    X,
    Y,
    Z,
    A,
    C,
}

impl Axis {
    pub const ALL: [Axis; 5] = [Axis::X, Axis::Y, Axis::Z, Axis::A, Axis::C];

    pub fn letter(self) -> char {
        match self {
            Axis::X => 'X',
            Axis::Y => 'Y',
            Axis::Z => 'Z',
            Axis::A => 'A',
            Axis::C => 'C',
        }
    }

    pub fn is_rotary(self) -> bool {
        matches!(self, Axis::A | Axis::C)
    }

    pub fn from_letter(c: char) -> Option<Axis> {
        match c.to_ascii_uppercase() {
            'X' => Some(Axis::X),
            'Y' => Some(Axis::Y),
            'Z' => Some(Axis::Z),
            'A' => Some(Axis::A),
            'C' => Some(Axis::C),
            _ => None,
        }
    }
}

impl Axes {
    pub const fn new(x: f64, y: f64, z: f64, a: f64, c: f64) -> Self {
        Axes { x, y, z, a, c }
    }

    pub fn get(&self, axis: Axis) -> f64 {
        match axis {
            Axis::X => self.x,
            Axis::Y => self.y,
            Axis::Z => self.z,
            Axis::A => self.a,
            Axis::C => self.c,
        }
    }

    pub fn set(&mut self, axis: Axis, value: f64) {
        match axis {
            Axis::X => self.x = value,
            Axis::Y => self.y = value,
            Axis::Z => self.z = value,
            Axis::A => self.a = value,
            Axis::C => self.c = value,
        }
    }

    pub fn xyz(&self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    pub fn to_array(&self) -> [f64; 5] {
        [self.x, self.y, self.z, self.a, self.c]
    }

    pub fn from_array(v: [f64; 5]) -> Self {
        Axes::new(v[0], v[1], v[2], v[3], v[4])
    }

    /// Linear interpolation of every axis (A and C taken literally, no shortest path).
    pub fn lerp(&self, other: &Axes, t: f64) -> Axes {
        let a = self.to_array();
        let b = other.to_array();
        let mut out = [0.0; 5];
        for i in 0..5 {
            out[i] = a[i] + (b[i] - a[i]) * t;
        }
        Axes::from_array(out)
    }

    /// Length of the XYZ part of `other - self`, mm.
    pub fn xyz_distance(&self, other: &Axes) -> f64 {
        let dx = other.x - self.x;
        let dy = other.y - self.y;
        let dz = other.z - self.z;
        (dx * dx + dy * dy + dz * dz).sqrt()
    }

    pub fn is_finite(&self) -> bool {
        self.to_array().iter().all(|v| v.is_finite())
    }
}
