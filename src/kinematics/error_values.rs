//! The values of all 43 error parameters of kinematics.md at one pose.
//!
//! Units: lengths µm, angles µrad (as in the tables and machine files); the chain
//! converts to mm and rad. Flat index order (used by [`ErrorValues::get_index`] and
//! [`PARAMETER_NAMES`]): the 30 component errors axis by axis (X, Y, Z, A, C), each
//! `δx δy δz εx εy εz` as in kinematics.md's table; then `s_xy s_xz s_yz`; then the ten
//! location errors in formats.md's order.
use crate::axes::Axis;
use serde::{Deserialize, Serialize};

/// Number of position-dependent component errors (5 axes × 6).
pub const COMPONENT_COUNT: usize = 30;
/// Number of parameters in total (30 + 3 squareness + 10 location).
pub const PARAMETER_COUNT: usize = 43;

/// Axes that carry component-error tables, in the order of [`ErrorValues::component`].
pub const COMPONENT_AXES: [Axis; 5] = [Axis::X, Axis::Y, Axis::Z, Axis::A, Axis::C];

/// ISO 230-1 names of the component errors: `COMPONENT_NAMES[axis][k]`, `k` =
/// δx δy δz εx εy εz.
pub const COMPONENT_NAMES: [[&str; 6]; 5] = [
    ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"],
    ["EXY", "EYY", "EZY", "EAY", "EBY", "ECY"],
    ["EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ"],
    ["EXA", "EYA", "EZA", "EAA", "EBA", "ECA"],
    ["EXC", "EYC", "EZC", "EAC", "EBC", "ECC"],
];

/// Squareness names, in the order of [`ErrorValues::squareness`].
pub const SQUARENESS_NAMES: [&str; 3] = ["s_xy", "s_xz", "s_yz"];

/// Rotary location names (ISO 230-7), in the order of [`ErrorValues::location`].
pub const LOCATION_NAMES: [&str; 10] = [
    "EY0A", "EZ0A", "EB0A", "EC0A", "EA0A", "EX0C", "EY0C", "EA0C", "EB0C", "EC0C",
];

/// Indices into [`ErrorValues::location`].
pub mod location {
    pub const EY0A: usize = 0;
    pub const EZ0A: usize = 1;
    pub const EB0A: usize = 2;
    pub const EC0A: usize = 3;
    pub const EA0A: usize = 4;
    pub const EX0C: usize = 5;
    pub const EY0C: usize = 6;
    pub const EA0C: usize = 7;
    pub const EB0C: usize = 8;
    pub const EC0C: usize = 9;
}

/// All 43 names in flat index order.
pub const PARAMETER_NAMES: [&str; PARAMETER_COUNT] = {
    let mut out = [""; PARAMETER_COUNT];
    let mut i = 0;
    while i < 5 {
        let mut k = 0;
        while k < 6 {
            out[i * 6 + k] = COMPONENT_NAMES[i][k];
            k += 1;
        }
        i += 1;
    }
    let mut s = 0;
    while s < 3 {
        out[COMPONENT_COUNT + s] = SQUARENESS_NAMES[s];
        s += 1;
    }
    let mut l = 0;
    while l < 10 {
        out[COMPONENT_COUNT + 3 + l] = LOCATION_NAMES[l];
        l += 1;
    }
    out
};

/// A name that is none of the 43 parameters.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown error parameter `{0}` (expected an ISO 230-1 name such as EXX, EBA, s_xy or EY0A)"
)]
pub struct UnknownParameter(pub String);

/// Values of every error parameter at one pose (µm and µrad). Zero is "no error".
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ErrorValues {
    /// `component[axis][k]`, axis in [`COMPONENT_AXES`] order, `k` = δx δy δz (µm),
    /// εx εy εz (µrad).
    pub component: [[f64; 6]; 5],
    /// `s_xy, s_xz, s_yz`, µrad.
    pub squareness: [f64; 3],
    /// [`LOCATION_NAMES`] order; µm for EY0A EZ0A EX0C EY0C, µrad for the rest.
    pub location: [f64; 10],
}

impl ErrorValues {
    pub const ZERO: ErrorValues = ErrorValues {
        component: [[0.0; 6]; 5],
        squareness: [0.0; 3],
        location: [0.0; 10],
    };

    /// Flat index of a parameter name (exact, case-sensitive as in kinematics.md).
    pub fn index_of(name: &str) -> Option<usize> {
        PARAMETER_NAMES.iter().position(|n| *n == name)
    }

    /// Value by flat index (`None` past 43).
    pub fn get_index(&self, index: usize) -> Option<f64> {
        match index {
            i if i < COMPONENT_COUNT => Some(self.component[i / 6][i % 6]),
            i if i < COMPONENT_COUNT + 3 => Some(self.squareness[i - COMPONENT_COUNT]),
            i if i < PARAMETER_COUNT => Some(self.location[i - COMPONENT_COUNT - 3]),
            _ => None,
        }
    }

    /// Mutable slot by flat index (`None` past 43).
    pub fn slot_mut(&mut self, index: usize) -> Option<&mut f64> {
        match index {
            i if i < COMPONENT_COUNT => Some(&mut self.component[i / 6][i % 6]),
            i if i < COMPONENT_COUNT + 3 => Some(&mut self.squareness[i - COMPONENT_COUNT]),
            i if i < PARAMETER_COUNT => Some(&mut self.location[i - COMPONENT_COUNT - 3]),
            _ => None,
        }
    }

    /// Value by name (`"EXX"`, `"s_xy"`, `"EY0A"`, ...).
    pub fn get(&self, name: &str) -> Option<f64> {
        Self::index_of(name).and_then(|i| self.get_index(i))
    }

    /// Set a value by name.
    pub fn set(&mut self, name: &str, value: f64) -> Result<(), UnknownParameter> {
        let slot = Self::index_of(name)
            .and_then(|i| self.slot_mut(i))
            .ok_or_else(|| UnknownParameter(name.to_string()))?;
        *slot = value;
        Ok(())
    }

    /// The same values with only parameter `index` kept (all others zero).
    pub fn only(&self, index: usize) -> ErrorValues {
        let mut out = ErrorValues::ZERO;
        if let (Some(v), Some(slot)) = (self.get_index(index), out.slot_mut(index)) {
            *slot = v;
        }
        out
    }

    /// Every value multiplied by `k`.
    pub fn scaled(&self, k: f64) -> ErrorValues {
        let mut out = *self;
        for i in 0..PARAMETER_COUNT {
            if let Some(slot) = out.slot_mut(i) {
                *slot *= k;
            }
        }
        out
    }

    /// Whether every value is finite.
    pub fn is_finite(&self) -> bool {
        (0..PARAMETER_COUNT).all(|i| self.get_index(i).is_some_and(f64::is_finite))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip() {
        let mut v = ErrorValues::ZERO;
        for (i, name) in PARAMETER_NAMES.iter().enumerate() {
            v.set(name, i as f64 + 1.0).unwrap();
        }
        assert_eq!(v.get("EXX"), Some(1.0));
        assert_eq!(v.component[3][4], v.get("EBA").unwrap());
        assert_eq!(v.squareness[2], v.get("s_yz").unwrap());
        assert_eq!(v.location[location::EA0C], v.get("EA0C").unwrap());
        assert_eq!(v.get("ECC"), Some(30.0));
        assert!(v.set("EQX", 1.0).is_err());
        assert_eq!(v.only(5).get_index(5), Some(6.0));
        assert_eq!(v.only(5).get_index(4), Some(0.0));
    }
}
