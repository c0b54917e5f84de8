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
    /// A dialect's programmable frame (Sinumerik `TRANS`/`ROT`/`SCALE`/
    /// `MIRROR`, a swivelled plane; Heidenhain datum shifts and tilted
    /// planes), applied to X Y Z first: `machine = rot(frame(program) + g92)
    /// + work`. `None` (LinuxCNC programs) is the identity.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame: Option<FrameTransform>,
}

/// An affine map of X Y Z: `p ↦ M·p + t` (rotations, mirrors, scales and a
/// shift), with its inverse kept so both directions cost the same.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameTransform {
    /// The linear part, row-major.
    pub matrix: [[f64; 3]; 3],
    /// The shift, mm.
    pub shift: [f64; 3],
    /// The inverse of `matrix`.
    pub inverse: [[f64; 3]; 3],
    /// A swivelled working plane (Sinumerik `CYCLE800`, Heidenhain `PLANE`)
    /// is part of it: the control holds the rotary axes where the plane put
    /// them, so a compensator corrects the tip only (dialects.md "Writing
    /// back": the tool axis is corrected where the program commands the
    /// rotary axes itself).
    #[serde(default)]
    pub holds_rotary: bool,
}

impl FrameTransform {
    /// The identity.
    pub const IDENTITY: FrameTransform = FrameTransform {
        matrix: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        shift: [0.0; 3],
        inverse: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        holds_rotary: false,
    };

    /// The map `p ↦ matrix·p + shift`; `None` when `matrix` is singular or
    /// not finite.
    pub fn new(matrix: [[f64; 3]; 3], shift: [f64; 3]) -> Option<FrameTransform> {
        let inverse = invert3(&matrix)?;
        Some(FrameTransform {
            matrix,
            shift,
            inverse,
            holds_rotary: false,
        })
    }

    /// `M·p + t`.
    pub fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let q = mul3(&self.matrix, p);
        [
            q[0] + self.shift[0],
            q[1] + self.shift[1],
            q[2] + self.shift[2],
        ]
    }

    /// `M⁻¹·(q − t)`.
    pub fn unapply(&self, q: [f64; 3]) -> [f64; 3] {
        mul3(
            &self.inverse,
            [
                q[0] - self.shift[0],
                q[1] - self.shift[1],
                q[2] - self.shift[2],
            ],
        )
    }

    /// `M·v` (a direction: no shift).
    pub fn apply_vector(&self, v: [f64; 3]) -> [f64; 3] {
        mul3(&self.matrix, v)
    }

    /// `self ∘ inner`: first `inner`, then `self`.
    pub fn after(&self, inner: &FrameTransform) -> FrameTransform {
        let mut m = [[0.0; 3]; 3];
        let mut inv = [[0.0; 3]; 3];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] = (0..3).map(|k| self.matrix[i][k] * inner.matrix[k][j]).sum();
                inv[i][j] = (0..3)
                    .map(|k| inner.inverse[i][k] * self.inverse[k][j])
                    .sum();
            }
        }
        FrameTransform {
            matrix: m,
            shift: self.apply(inner.shift),
            inverse: inv,
            holds_rotary: self.holds_rotary || inner.holds_rotary,
        }
    }
}

fn mul3(m: &[[f64; 3]; 3], p: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * p[0] + m[0][1] * p[1] + m[0][2] * p[2],
        m[1][0] * p[0] + m[1][1] * p[1] + m[1][2] * p[2],
        m[2][0] * p[0] + m[2][1] * p[1] + m[2][2] * p[2],
    ]
}

fn invert3(m: &[[f64; 3]; 3]) -> Option<[[f64; 3]; 3]> {
    let c =
        |r0: usize, r1: usize, c0: usize, c1: usize| m[r0][c0] * m[r1][c1] - m[r0][c1] * m[r1][c0];
    let det = m[0][0] * c(1, 2, 1, 2) - m[0][1] * c(1, 2, 0, 2) + m[0][2] * c(1, 2, 0, 1);
    if !det.is_finite() || det.abs() < 1e-12 {
        return None;
    }
    let adj = [
        [c(1, 2, 1, 2), -c(0, 2, 1, 2), c(0, 1, 1, 2)],
        [-c(1, 2, 0, 2), c(0, 2, 0, 2), -c(0, 1, 0, 2)],
        [c(1, 2, 0, 1), -c(0, 2, 0, 1), c(0, 1, 0, 1)],
    ];
    Some(adj.map(|row| row.map(|v| v / det)))
}

impl Origin {
    /// The identity (machine coordinates, as G53 uses).
    pub const MACHINE: Origin = Origin {
        work: Axes::xyzac(0.0, 0.0, 0.0, 0.0, 0.0),
        g92: Axes::xyzac(0.0, 0.0, 0.0, 0.0, 0.0),
        rotation_deg: 0.0,
        frame: None,
    };

    /// The control holds the rotary axes (a swivelled plane is active):
    /// the tip is corrected, the tool axis is not.
    pub fn holds_rotary(&self) -> bool {
        self.frame.is_some_and(|f| f.holds_rotary)
    }

    /// Program coordinates → machine coordinates.
    pub fn to_machine(&self, p: &Axes) -> Axes {
        let framed;
        let p = match &self.frame {
            None => p,
            Some(f) => {
                let [x, y, z] = f.apply(p.xyz());
                framed = Axes { x, y, z, ..*p };
                &framed
            }
        };
        let (x, y) = rotate(p.x + self.g92.x, p.y + self.g92.y, self.rotation_deg);
        let shifted = p.zip_with(&self.g92, |v, g| v + g);
        Axes {
            x: x + self.work.x,
            y: y + self.work.y,
            ..shifted.zip_with(&self.work, |v, w| v + w)
        }
    }

    /// Machine coordinates → program coordinates (inverse of [`Origin::to_machine`]).
    #[inline]
    pub fn to_program(&self, m: &Axes) -> Axes {
        let (x, y) = rotate(m.x - self.work.x, m.y - self.work.y, -self.rotation_deg);
        let shifted = m.zip_with(&self.work, |v, w| v - w);
        let p = Axes {
            x: x - self.g92.x,
            y: y - self.g92.y,
            ..shifted.zip_with(&self.g92, |v, g| v - g)
        };
        match &self.frame {
            None => p,
            Some(f) => {
                let [x, y, z] = f.unapply(p.xyz());
                Axes { x, y, z, ..p }
            }
        }
    }

    /// [`Origin::to_program`]'s X Y Z of `m` (the other axes not worked out).
    #[inline]
    pub fn xyz_to_program_of(&self, m: &Axes) -> [f64; 3] {
        let (x, y) = rotate(m.x - self.work.x, m.y - self.work.y, -self.rotation_deg);
        let p = [
            x - self.g92.x,
            y - self.g92.y,
            m.z - self.work.z - self.g92.z,
        ];
        match &self.frame {
            None => p,
            Some(f) => f.unapply(p),
        }
    }

    /// Machine (part-table) XYZ → the workpiece frame: the frame of the work
    /// origin itself (its shift and its XY rotation), before G92, datum
    /// shifts, programmable frames and working planes (dialects.md
    /// "Positions": where `check --frame part --targets` writes the tip).
    pub fn xyz_to_workpiece(&self, m: [f64; 3]) -> [f64; 3] {
        let (x, y) = rotate(m[0] - self.work.x, m[1] - self.work.y, -self.rotation_deg);
        [x, y, m[2] - self.work.z]
    }

    /// A machine (part-table) direction → the workpiece frame (the work
    /// origin's XY rotation undone; a direction has no shift).
    pub fn vector_to_workpiece(&self, v: [f64; 3]) -> [f64; 3] {
        let (x, y) = rotate(v[0], v[1], -self.rotation_deg);
        [x, y, v[2]]
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
            frame: FrameTransform::new(
                [[0.0, -2.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, -1.0]],
                [1.0, 2.0, 3.0],
            ),
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
