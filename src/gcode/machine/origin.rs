//! Where program coordinates sit in machine coordinates: the active work
//! origin (G54–G59.3, with its XY rotation) and the G92 offset, as LinuxCNC's
//! canon applies them: `machine = rot(program + g92) + g5x`, the rotation
//! about Z acting on X and Y only. Tool length offset is not part of it (the
//! error model is looked up at the spindle nose position plus the tool of the
//! machine file).
use crate::axes::Axes;
use serde::{Deserialize, Serialize};

/// The transform of one block's axis words (mm and degrees).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Origin {
    /// The work origin (G54–G59.3), machine coordinates.
    pub work: Axes,
    /// The G92 offset.
    pub g92: Axes,
    /// XY rotation of the work system (G10 L2 R), degrees counter-clockwise.
    pub rotation_deg: f64,
}

impl Origin {
    /// The identity (machine coordinates, as G53 uses).
    pub const MACHINE: Origin = Origin {
        work: Axes::xyzac(0.0, 0.0, 0.0, 0.0, 0.0),
        g92: Axes::xyzac(0.0, 0.0, 0.0, 0.0, 0.0),
        rotation_deg: 0.0,
    };

    /// Program coordinates → machine coordinates.
    pub fn to_machine(&self, p: &Axes) -> Axes {
        let (x, y) = rotate(p.x + self.g92.x, p.y + self.g92.y, self.rotation_deg);
        let shifted = p.zip_with(&self.g92, |v, g| v + g);
        Axes {
            x: x + self.work.x,
            y: y + self.work.y,
            ..shifted.zip_with(&self.work, |v, w| v + w)
        }
    }

    /// Machine coordinates → program coordinates (inverse of [`Origin::to_machine`]).
    pub fn to_program(&self, m: &Axes) -> Axes {
        let (x, y) = rotate(m.x - self.work.x, m.y - self.work.y, -self.rotation_deg);
        let shifted = m.zip_with(&self.work, |v, w| v - w);
        Axes {
            x: x - self.g92.x,
            y: y - self.g92.y,
            ..shifted.zip_with(&self.g92, |v, g| v - g)
        }
    }

    /// A point given by its X Y Z only (an arc centre) → machine XYZ.
    pub fn xyz_to_machine(&self, p: [f64; 3]) -> [f64; 3] {
        self.to_machine(&Axes::xyzac(p[0], p[1], p[2], 0.0, 0.0))
            .xyz()
    }

    /// Machine XYZ → program XYZ.
    pub fn xyz_to_program(&self, m: [f64; 3]) -> [f64; 3] {
        self.to_program(&Axes {
            x: m[0],
            y: m[1],
            z: m[2],
            ..self.work
        })
        .xyz()
    }
}

fn rotate(x: f64, y: f64, deg: f64) -> (f64, f64) {
    if deg == 0.0 {
        return (x, y);
    }
    let (s, c) = deg.to_radians().sin_cos();
    (x * c - y * s, x * s + y * c)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_with_rotation() {
        let o = Origin {
            work: Axes::xyzac(10.0, 20.0, 5.0, 1.0, 90.0),
            g92: Axes::xyzac(1.0, -2.0, 0.5, 0.0, 3.0),
            rotation_deg: 30.0,
        };
        let p = Axes::xyzac(3.0, 4.0, -1.0, 15.0, 200.0);
        let back = o.to_program(&o.to_machine(&p));
        for (a, b) in back.to_array().iter().zip(p.to_array()) {
            assert!((a - b).abs() < 1e-12);
        }
        let m = Origin {
            rotation_deg: 90.0,
            ..Origin::MACHINE
        }
        .to_machine(&Axes::xyzac(1.0, 0.0, 0.0, 0.0, 0.0));
        assert!((m.x).abs() < 1e-12 && (m.y - 1.0).abs() < 1e-12);
    }
}
