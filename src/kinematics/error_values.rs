//! The values of the 43 error parameters of a five-axis machine at one pose, and
//! their names ([`ParameterLayout`]).
//!
//! Units: lengths µm, angles µrad (as in the tables and machine files); the chain
//! converts to mm and rad. The values are stored by **slot**: the machine's joints
//! X, Y, Z and its two rotary axes in letter order (A/C on xyzac-trt, B/C on
//! xyzbc-trt). Flat index order (used by [`ErrorValues::get_index`] and
//! [`ParameterLayout::names`]): the 30 component errors slot by slot, each
//! `δx δy δz εx εy εz` as in kinematics.md's table; then `s_xy s_xz s_yz`; then the
//! five location errors of each rotary axis in kinematics.md's order (two offsets,
//! two tilts, the zero offset). For an A/C machine these are exactly the 43 names of
//! [`PARAMETER_NAMES`].
use crate::axes::Axis;
use serde::{Deserialize, Serialize};

/// Number of position-dependent component errors (5 axes × 6).
pub const COMPONENT_COUNT: usize = 30;
/// Number of parameters in total (30 + 3 squareness + 10 location).
pub const PARAMETER_COUNT: usize = 43;

/// ISO 230-1 names of the component errors of every letter that can carry a table,
/// `[letter X Y Z A B C][k]`, `k` = δx δy δz εx εy εz.
const NAMES_BY_LETTER: [[&str; 6]; 6] = [
    ["EXX", "EYX", "EZX", "EAX", "EBX", "ECX"],
    ["EXY", "EYY", "EZY", "EAY", "EBY", "ECY"],
    ["EXZ", "EYZ", "EZZ", "EAZ", "EBZ", "ECZ"],
    ["EXA", "EYA", "EZA", "EAA", "EBA", "ECA"],
    ["EXB", "EYB", "EZB", "EAB", "EBB", "ECB"],
    ["EXC", "EYC", "EZC", "EAC", "EBC", "ECC"],
];

/// ISO 230-7 location names of each rotary letter (kinematics.md: the two offsets
/// along the other machine axes, the two tilts about them, the zero offset).
const LOCATION_BY_LETTER: [[&str; 5]; 3] = [
    ["EY0A", "EZ0A", "EB0A", "EC0A", "EA0A"],
    ["EX0B", "EZ0B", "EA0B", "EC0B", "EB0B"],
    ["EX0C", "EY0C", "EA0C", "EB0C", "EC0C"],
];

/// ISO 230-1 names of the component errors of an A/C machine: `COMPONENT_NAMES[slot][k]`.
pub const COMPONENT_NAMES: [[&str; 6]; 5] = [
    NAMES_BY_LETTER[0],
    NAMES_BY_LETTER[1],
    NAMES_BY_LETTER[2],
    NAMES_BY_LETTER[3],
    NAMES_BY_LETTER[5],
];

/// Squareness names, in the order of [`ErrorValues::squareness`].
pub const SQUARENESS_NAMES: [&str; 3] = ["s_xy", "s_xz", "s_yz"];

/// Rotary location names of an A/C machine, in the order of [`ErrorValues::location`].
pub const LOCATION_NAMES: [&str; 10] = [
    "EY0A", "EZ0A", "EB0A", "EC0A", "EA0A", "EX0C", "EY0C", "EA0C", "EB0C", "EC0C",
];

/// All 43 names of an A/C machine in flat index order.
pub const PARAMETER_NAMES: [&str; PARAMETER_COUNT] = ParameterLayout::AC.names();

/// A name that is none of the machine's parameters.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "unknown error parameter `{0}` (expected an ISO 230-1 name of this machine's axes such as EXX, EBX, s_xy, or a location error of its rotary axes such as {1})"
)]
pub struct UnknownParameter(pub String, pub &'static str);

/// The names of a machine's 43 parameters: they follow from its two rotary letters.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize)]
pub struct ParameterLayout {
    rotary: [Axis; 2],
}

const fn letter_index(axis: Axis) -> usize {
    match axis {
        Axis::X => 0,
        Axis::Y => 1,
        Axis::Z => 2,
        Axis::A => 3,
        Axis::B => 4,
        _ => 5,
    }
}

impl ParameterLayout {
    /// The A/C machine (`xyzac-trt`).
    pub const AC: ParameterLayout = ParameterLayout {
        rotary: [Axis::A, Axis::C],
    };

    /// The layout of a machine whose rotary letters are `rotary` (two of A B C, any
    /// order: slots follow letter order).
    pub const fn new(rotary: [Axis; 2]) -> ParameterLayout {
        if letter_index(rotary[0]) <= letter_index(rotary[1]) {
            ParameterLayout { rotary }
        } else {
            ParameterLayout {
                rotary: [rotary[1], rotary[0]],
            }
        }
    }

    /// The rotary letters, slots 3 and 4.
    pub const fn rotary(&self) -> [Axis; 2] {
        self.rotary
    }

    /// The letter of each slot: X Y Z and the two rotaries.
    pub const fn slot_axes(&self) -> [Axis; 5] {
        [Axis::X, Axis::Y, Axis::Z, self.rotary[0], self.rotary[1]]
    }

    /// The slot of `axis` (`None`: the machine has no table slot for it).
    pub fn slot_of(&self, axis: Axis) -> Option<usize> {
        self.slot_axes().iter().position(|a| *a == axis)
    }

    /// The six component names of `slot`.
    pub const fn component_names(&self, slot: usize) -> [&'static str; 6] {
        NAMES_BY_LETTER[letter_index(self.slot_axes()[slot])]
    }

    /// The five location names of rotary slot `r` (0 or 1).
    pub const fn rotary_location_names(&self, r: usize) -> [&'static str; 5] {
        LOCATION_BY_LETTER[letter_index(self.rotary[r]) - 3]
    }

    /// The ten location names in [`ErrorValues::location`] order.
    pub const fn location_names(&self) -> [&'static str; 10] {
        let a = self.rotary_location_names(0);
        let b = self.rotary_location_names(1);
        [a[0], a[1], a[2], a[3], a[4], b[0], b[1], b[2], b[3], b[4]]
    }

    /// The eight offsets and tilts (the `rotary_location` effect's parameters: the
    /// location errors without the zero offsets), in [`ErrorValues::location`] order.
    pub const fn location_effect_names(&self) -> [&'static str; 8] {
        let a = self.rotary_location_names(0);
        let b = self.rotary_location_names(1);
        [a[0], a[1], a[2], a[3], b[0], b[1], b[2], b[3]]
    }

    /// Flat indices of [`ParameterLayout::location_effect_names`].
    pub const LOCATION_EFFECT_INDICES: [usize; 8] = {
        let base = COMPONENT_COUNT + 3;
        [
            base,
            base + 1,
            base + 2,
            base + 3,
            base + 5,
            base + 6,
            base + 7,
            base + 8,
        ]
    };

    /// All 43 names in flat index order.
    pub const fn names(&self) -> [&'static str; PARAMETER_COUNT] {
        let mut out = [""; PARAMETER_COUNT];
        let mut i = 0;
        while i < 5 {
            let names = self.component_names(i);
            let mut k = 0;
            while k < 6 {
                out[i * 6 + k] = names[k];
                k += 1;
            }
            i += 1;
        }
        let mut s = 0;
        while s < 3 {
            out[COMPONENT_COUNT + s] = SQUARENESS_NAMES[s];
            s += 1;
        }
        let loc = self.location_names();
        let mut l = 0;
        while l < 10 {
            out[COMPONENT_COUNT + 3 + l] = loc[l];
            l += 1;
        }
        out
    }

    /// Name of flat index `index` (`""` past 43).
    pub fn name(&self, index: usize) -> &'static str {
        self.names().get(index).copied().unwrap_or("")
    }

    /// Flat index of a parameter name (exact, case-sensitive as in kinematics.md).
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.names().iter().position(|n| *n == name)
    }

    fn unknown(&self, name: &str) -> UnknownParameter {
        UnknownParameter(name.to_string(), self.rotary_location_names(0)[0])
    }
}

/// Values of every error parameter at one pose (µm and µrad). Zero is "no error".
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ErrorValues {
    /// `component[axis][k]`, axis by its slot
    /// ([`MachineChain::slot`](crate::kinematics::MachineChain::slot): X Y Z,
    /// then the two rotaries in letter order), `k` = δx δy δz (µm),
    /// εx εy εz (µrad).
    pub component: [[f64; 6]; 5],
    /// `s_xy, s_xz, s_yz`, µrad.
    pub squareness: [f64; 3],
    /// [`LOCATION_NAMES`] order; µm for EY0A EZ0A EX0C EY0C, µrad for the rest.
    pub location: [f64; 10],
}

impl ErrorValues {
    /// Every error zero (the nominal machine).
    pub const ZERO: ErrorValues = ErrorValues {
        component: [[0.0; 6]; 5],
        squareness: [0.0; 3],
        location: [0.0; 10],
    };

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

    /// Value by name (`"EXX"`, `"s_xy"`, `"EY0A"`, ...) in `layout`'s names.
    pub fn get(&self, layout: &ParameterLayout, name: &str) -> Option<f64> {
        layout.index_of(name).and_then(|i| self.get_index(i))
    }

    /// Set a value by name in `layout`'s names.
    pub fn set(
        &mut self,
        layout: &ParameterLayout,
        name: &str,
        value: f64,
    ) -> Result<(), UnknownParameter> {
        let slot = layout
            .index_of(name)
            .and_then(|i| self.slot_mut(i))
            .ok_or_else(|| layout.unknown(name))?;
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
        let ac = ParameterLayout::AC;
        let mut v = ErrorValues::ZERO;
        for (i, name) in PARAMETER_NAMES.iter().enumerate() {
            v.set(&ac, name, i as f64 + 1.0).unwrap();
        }
        assert_eq!(v.get(&ac, "EXX"), Some(1.0));
        assert_eq!(v.component[3][4], v.get(&ac, "EBA").unwrap());
        assert_eq!(v.squareness[2], v.get(&ac, "s_yz").unwrap());
        assert_eq!(
            v.location[LOCATION_NAMES.iter().position(|n| *n == "EA0C").unwrap()],
            v.get(&ac, "EA0C").unwrap()
        );
        assert_eq!(v.get(&ac, "ECC"), Some(30.0));
        assert!(v.set(&ac, "EQX", 1.0).is_err());
        assert!(v.set(&ac, "EXB", 1.0).is_err());
        // B/C: the B slot takes A's place, B's location names A's.
        let bc = ParameterLayout::new([Axis::C, Axis::B]);
        assert_eq!(bc.rotary(), [Axis::B, Axis::C]);
        assert_eq!(bc.index_of("EXB"), Some(18));
        assert_eq!(bc.index_of("EB0B"), Some(37));
        assert_eq!(bc.location_effect_names()[0], "EX0B");
        assert_eq!(ParameterLayout::AC.names(), PARAMETER_NAMES);
        assert_eq!(v.only(5).get_index(5), Some(6.0));
        assert_eq!(v.only(5).get_index(4), Some(0.0));
    }
}
