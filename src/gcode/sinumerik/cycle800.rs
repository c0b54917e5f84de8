//! `CYCLE800(_FR, _TC, _ST, _MODE, _X0, _Y0, _Z0, _A, _B, _C, _X1, _Y1,
//! _Z1, _DIR, …)`: a swivelled working plane (Siemens, *SINUMERIK 840D sl
//! Operating Manual Milling* / *Turning*, "Further cycles and functions ›
//! Swivel plane (CYCLE800)"; *Commissioning Manual SINUMERIK Operate*,
//! "Swiveling"). The `_MODE` bit field: bits 6–7 the swivel mode (00 axis
//! by axis, 01 solid angle, 10 projection angle, 11 direct: "position rotary
//! axes directly"); bits 0–1, 2–3, 4–5 the axis of the angle `_A`, `_B`,
//! `_C` (01 X, 10 Y, 11 Z), which is how CAM posts write the six axis
//! sequences (57 XYZ, 45 XZY, 54 YXZ, 30 YZX, 39 ZXY, 27 ZYX) and 192 for
//! direct mode. The plane's frame is `p ↦ X0 + R·(X1 + p)`; what each mode
//! makes of `R` is [`swivel_rotation`]'s.
use crate::axes::Axis;
use crate::gcode::Branch;
use crate::gcode::error::GcodeError;
use crate::gcode::heidenhain::geometry::projected;
use crate::gcode::machine::interpret::Interpreter;
use crate::gcode::machine::origin::FrameTransform;
use crate::gcode::syntax::block::{Keyword, KeywordWord};

use super::syntax::Expr;
use super::{LineRun, Out, SinumerikFront, rpy};

/// A 3×3 rotation, row-major.
type Mat = [[f64; 3]; 3];

/// How `_MODE` and the angles turn the plane: a rotation, or (direct mode)
/// the rotary axis positions `_A` (rotary axis 1) and `_B` (rotary axis 2)
/// whose frame the machine's chain gives.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Swivel {
    /// The plane's rotation `R` (workpiece frame).
    Rotation(Mat),
    /// Direct mode: the positions of the machine's rotary axes 1 and 2.
    Direct([f64; 2]),
}

/// The axis letter of a 2-bit axis field (01 X, 10 Y, 11 Z).
fn axis_name(field: i64) -> char {
    ['-', 'X', 'Y', 'Z'][field as usize & 3]
}

/// The rotation about X, Y or Z (field 1, 2, 3) by `deg` degrees.
fn about(field: i64, deg: f64) -> Mat {
    match field {
        1 => rpy(deg, 0.0, 0.0),
        2 => rpy(0.0, deg, 0.0),
        _ => rpy(0.0, 0.0, deg),
    }
}

fn mul(p: &Mat, q: &Mat) -> Mat {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, c) in row.iter_mut().enumerate() {
            *c = (0..3).map(|k| p[i][k] * q[k][j]).sum();
        }
    }
    m
}

fn transpose(m: &Mat) -> Mat {
    [0, 1, 2].map(|i| [0, 1, 2].map(|j| m[j][i]))
}

/// The plane of `CYCLE800`'s `_MODE` (`mode`) and angles `_A _B _C`:
/// - **axis by axis** (bits 6–7 = 00): the rotations about the axes that
///   bits 0–5 name, `_A` first, each about the axis as the rotations before
///   left it: `R = R₁(_A)·R₂(_B)·R₃(_C)` (the HMI's "axis sequence" XYZ …
///   ZYX). A field 00 takes no rotation (its angle must be 0), an axis may
///   come once.
/// - **solid angle** (01, bits 0–5 = 0): about Z by α (`_A`, in the XY
///   plane), about the turned Y by β (`_B`), then about the new tool axis
///   by `_C` (the HMI's "angle of rotation in the plane"): `R =
///   Rz(α)·Ry(β)·Rz(γ)`; the tool along (sin β cos α, sin β sin α, cos β).
/// - **projection angle** (10): bits 0–3 the two projected axes, one of the
///   pairs XY, YZ, ZX in either order (the HMI's "projection position" Xα Yα,
///   Yα Zα, Zα Xα; the operating manual: for XY and YX the new X lies in
///   the old ZX plane, for YZ and ZY the new Y in the old XY plane, for XZ
///   and ZX the new Z in the old YZ plane: one rule turned X→Y→Z→X), each
///   angle the angle of the plane's trace on the coordinate plane square to
///   its axis (Klartext's `PLANE PROJECTED`, [`projected`], for XY); bits
///   4–5 the axis of the third rotation by `_C` (Zβ under G17), about the
///   new axis. `None` of the traces exists at ±90°.
/// - **direct** (11, bits 0–5 = 0): `_A`, `_B` are the positions of rotary
///   axes 1 and 2; `_C` must be 0.
pub(crate) fn swivel_rotation(mode: f64, [a, b, c]: [f64; 3]) -> Result<Swivel, String> {
    if !(0.0..=255.0).contains(&mode) || mode.fract() != 0.0 {
        return Err(format!(
            "CYCLE800 _MODE {mode}: the swivel mode is a bit field 0–255 (bits 6–7 the mode, bits 0–5 the axes)"
        ));
    }
    let bits = mode as i64;
    let field = |k: usize| (bits >> (2 * k)) & 3;
    let angles = [a, b, c];
    let names = ["_A", "_B", "_C"];
    match bits >> 6 {
        0 => {
            let mut r = rpy(0.0, 0.0, 0.0);
            let mut seen = [false; 4];
            for k in 0..3 {
                let f = field(k);
                if f == 0 {
                    if angles[k] != 0.0 {
                        return Err(format!(
                            "CYCLE800 axis by axis, _MODE {bits}: {} = {} has no axis (bits {}–{} = 00)",
                            names[k],
                            angles[k],
                            2 * k,
                            2 * k + 1
                        ));
                    }
                    continue;
                }
                if seen[f as usize] {
                    return Err(format!(
                        "CYCLE800 axis by axis, _MODE {bits}: the axis {} comes twice in bits 0–5 (the sequences are XYZ XZY YXZ YZX ZXY ZYX)",
                        axis_name(f)
                    ));
                }
                seen[f as usize] = true;
                r = mul(&r, &about(f, angles[k]));
            }
            Ok(Swivel::Rotation(r))
        }
        1 => {
            if bits & 0x3F != 0 {
                return Err(format!(
                    "CYCLE800 solid angle, _MODE {bits}: bits 0–5 = {} (the solid angle takes no axis sequence: _MODE 64)",
                    bits & 0x3F
                ));
            }
            let r = mul(&mul(&about(3, a), &about(2, b)), &about(3, c));
            Ok(Swivel::Rotation(r))
        }
        2 => {
            let (f0, f1, f2) = (field(0), field(1), field(2));
            // The cyclic turn that maps the pair onto XY, and which of the
            // two angles is about the pair's first axis in X→Y→Z→X order.
            let (turns, first_angle, second_angle) = match (f0, f1) {
                (1, 2) => (0, a, b),
                (2, 1) => (0, b, a),
                (2, 3) => (1, a, b),
                (3, 2) => (1, b, a),
                (3, 1) => (2, a, b),
                (1, 3) => (2, b, a),
                _ => {
                    return Err(format!(
                        "CYCLE800 projection angle, _MODE {bits}: bits 0–3 = {}{} name no projection position (Xα Yα, Yα Zα or Zα Xα, either order)",
                        axis_name(f0),
                        axis_name(f1)
                    ));
                }
            };
            if f2 == 0 && c != 0.0 {
                return Err(format!(
                    "CYCLE800 projection angle, _MODE {bits}: _C = {c} has no axis (bits 4–5 = 00)"
                ));
            }
            let Some(xy) = projected(second_angle, first_angle, 0.0) else {
                return Err(format!(
                    "CYCLE800 projection angles of ±90° (_MODE {bits}): the plane's traces are not defined"
                ));
            };
            // P maps X→Y, Y→Z, Z→X; the pair YZ is P·(XY)·Pᵀ, ZX P²·(XY)·P²ᵀ.
            let p: Mat = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
            let mut r = xy;
            for _ in 0..turns {
                r = mul(&mul(&p, &r), &transpose(&p));
            }
            if f2 != 0 {
                r = mul(&r, &about(f2, c));
            }
            Ok(Swivel::Rotation(r))
        }
        _ => {
            if bits & 0x3F != 0 {
                return Err(format!(
                    "CYCLE800 direct mode, _MODE {bits}: bits 0–5 = {} (direct mode takes no axis sequence: _MODE 192)",
                    bits & 0x3F
                ));
            }
            if c != 0.0 {
                return Err(format!(
                    "CYCLE800 direct mode (_MODE {bits}): _C = {c} would be a third rotary axis; _A and _B are rotary axes 1 and 2"
                ));
            }
            Ok(Swivel::Direct([a, b]))
        }
    }
}

impl SinumerikFront {
    /// `CYCLE800(…)`: a new plane (`_ST` units digit 0) or an additive one
    /// (1: the new swivel acts in the plane already active), its rotation
    /// from `_MODE` ([`swivel_rotation`]). The tool is turned along `R·Z`
    /// by the machine's chain (`ProgramSetup::orientation`): `_DIR` +1/−1
    /// picks the solution whose first rotary axis (letter order) is ≥ 0 /
    /// ≤ 0 ("plus: higher rotary axis value"), 0 leaves the rotary axes
    /// where they are. In direct mode the rotary axes go to `_A`/`_B`
    /// (program values, as `A=`/`C=` words) whatever `_DIR` says (the HMI
    /// offers no direction there) and the plane is the frame they turn
    /// ([`crate::gcode::OrientationSolver::frame_of`]: moving X in the plane
    /// moves the machine's X, as the operating manual says one finds the
    /// plane's X and Y "by traversing the axes"). Positions are then tool-tip
    /// positions in the part frame, as under `TRAORI`. The swivel itself is
    /// no executed move (the joints are set), so `_ST`'s other digits
    /// (tracking the tool tip while swivelling or not) change no position
    /// volcomp hands on. `CYCLE800()` removes the plane (the rotary axes
    /// stay).
    pub(super) fn cycle800(
        &mut self,
        line: &LineRun,
        args: &[Expr],
        at: (usize, usize),
        interpreter: &mut Interpreter,
        out: &mut Out,
    ) -> Result<(), GcodeError> {
        out.statements.push(at.0..at.1);
        self.flush_frame_later = true;
        if args.is_empty() {
            if self.frames.swivel.take().is_some() && !self.traori {
                out.keywords.push(KeywordWord {
                    keyword: Keyword::TraFoof,
                    start: at.0,
                    end: at.1,
                });
            }
            return Ok(());
        }
        let mut v = [0.0f64; 16];
        for (k, a) in args.iter().enumerate().take(16) {
            v[k] = match a {
                Expr::Str(_) => 0.0,
                e => self.eval(line, e, at)?,
            };
        }
        let additive = (v[2] as i64) % 10 == 1;
        let swivel = swivel_rotation(v[3], [v[7], v[8], v[9]])
            .map_err(|m| self.refused(line, m, at.0, at.1))?;
        let solver = || {
            self.orientation.clone().ok_or_else(|| {
                self.feature(
                    line,
                    "CYCLE800 without the machine (give --machine: the plane is solved with its chain)",
                    at.0,
                    at.1,
                )
            })
        };
        let mut position = interpreter.position();
        let (m, direct) = match swivel {
            Swivel::Rotation(m) => (m, false),
            Swivel::Direct([a1, a2]) => {
                let solver = solver()?;
                if additive {
                    return Err(self.refused(
                        line,
                        "CYCLE800 direct mode (_MODE 192) with an additive plane (_ST units digit 1): rotary axis positions are absolute".into(),
                        at.0,
                        at.1,
                    ));
                }
                let origin = interpreter.origin();
                let mut program = origin.to_program(&position);
                let [r1, r2] = solver.swivel_order();
                program.set(r1, a1);
                program.set(r2, a2);
                let machine = origin.to_machine(&program);
                for r in [r1, r2] {
                    position.set(r, machine.get(r));
                }
                let frame = solver.frame_of(&position);
                let z = [frame[0][2], frame[1][2], frame[2][2]];
                let axis = solver.axis_of(&position);
                let off = (0..3).map(|k| (z[k] - axis[k]).abs()).fold(0.0, f64::max);
                if off > 1e-9 {
                    return Err(self.refused(
                        line,
                        "CYCLE800 direct mode on a machine whose tool axis at home is not Z: the plane's Z would not be the tool".into(),
                        at.0,
                        at.1,
                    ));
                }
                (frame, true)
            }
        };
        let Some(mut r) = FrameTransform::new(m, [0.0; 3]) else {
            return Err(self.refused(
                line,
                "CYCLE800: the plane's rotation is singular".into(),
                at.0,
                at.1,
            ));
        };
        let shift = |t: [f64; 3]| FrameTransform {
            shift: t,
            ..FrameTransform::IDENTITY
        };
        let mut plane = shift([v[4], v[5], v[6]])
            .after(&r)
            .after(&shift([v[10], v[11], v[12]]));
        if additive && let Some(old) = self.frames.swivel {
            plane = old.after(&plane);
            r = FrameTransform {
                shift: [0.0; 3],
                ..old
            }
            .after(&r);
        }
        plane.holds_rotary = true;
        let dir = v[13];
        if direct {
            interpreter.set_position(position);
        } else if dir != 0.0 {
            let solver = solver()?;
            let axis = r.apply_vector([0.0, 0.0, 1.0]);
            let branch = if dir > 0.0 {
                Branch::Plus
            } else {
                Branch::Minus
            };
            let Some(joints) = solver.joints_for_axis(axis, branch, &position) else {
                return Err(self.refused(
                    line,
                    format!(
                        "the machine cannot turn the tool along the plane's normal [{:.4}, {:.4}, {:.4}] on the {} branch",
                        axis[0],
                        axis[1],
                        axis[2],
                        if dir > 0.0 { "+" } else { "-" }
                    ),
                    at.0,
                    at.1,
                ));
            };
            for a in [Axis::A, Axis::B, Axis::C] {
                position.set(a, joints.get(a));
            }
            interpreter.set_position(position);
        }
        if self.frames.swivel.is_none() && !self.traori {
            out.keywords.push(KeywordWord {
                keyword: Keyword::TraOri,
                start: at.0,
                end: at.1,
            });
        }
        self.frames.swivel = Some(plane);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rot(s: Swivel) -> Mat {
        match s {
            Swivel::Rotation(m) => m,
            Swivel::Direct(_) => panic!("not a rotation"),
        }
    }

    fn close(a: &Mat, b: &Mat) -> bool {
        (0..3).all(|i| (0..3).all(|j| (a[i][j] - b[i][j]).abs() < 1e-12))
    }

    /// The axis sequences as CAM posts name them (57 XYZ, 27 ZYX): 90°
    /// about the first axis, then 90° about the turned second one
    /// (matrices multiplied out by hand); sequences the control lacks are
    /// refused naming the bits.
    #[test]
    fn axis_by_axis_sequences_follow_the_bits() {
        // Rx(90)·Ry(90) multiplied out by hand.
        let xyz = rot(swivel_rotation(57.0, [90.0, 90.0, 0.0]).unwrap());
        let want = [[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        assert!(close(&xyz, &want), "{xyz:?}");
        // ZYX (27): 90° about Z, then about the new Y (the old −X) by 90°.
        let zyx = rot(swivel_rotation(27.0, [90.0, 90.0, 0.0]).unwrap());
        let want = [[0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [-1.0, 0.0, 0.0]];
        assert!(close(&zyx, &want), "{zyx:?}");
        assert!(matches!(
            swivel_rotation(21.0, [10.0, 10.0, 10.0]),
            Err(m) if m.contains("X comes twice")
        ));
        assert!(matches!(
            swivel_rotation(9.0, [0.0, 0.0, 5.0]),
            Err(m) if m.contains("bits 4–5 = 00")
        ));
        assert!(swivel_rotation(300.0, [0.0; 3]).is_err());
    }

    /// Projection positions turned X→Y→Z→X: Yα Zα (62) alone about Y is
    /// the axis-by-axis rotation about Y; the pair XY read in the order YX
    /// (54 + 128) swaps the angles.
    #[test]
    fn projection_orders_are_one_rule_turned() {
        let yz = rot(swivel_rotation(128.0 + 62.0, [30.0, 0.0, 0.0]).unwrap());
        let about_y = rot(swivel_rotation(2.0, [30.0, 0.0, 0.0]).unwrap());
        assert!(close(&yz, &about_y), "{yz:?}");
        let xy = rot(swivel_rotation(128.0 + 57.0, [20.0, 35.0, 10.0]).unwrap());
        let yx = rot(swivel_rotation(128.0 + 54.0, [35.0, 20.0, 10.0]).unwrap());
        assert!(close(&xy, &yx));
        assert!(matches!(
            swivel_rotation(128.0 + 5.0, [1.0, 1.0, 0.0]),
            Err(m) if m.contains("XX")
        ));
    }

    #[test]
    fn direct_and_solid_angle_modes() {
        assert_eq!(
            swivel_rotation(192.0, [30.0, -45.0, 0.0]),
            Ok(Swivel::Direct([30.0, -45.0]))
        );
        assert!(swivel_rotation(192.0, [30.0, -45.0, 5.0]).is_err());
        assert!(swivel_rotation(192.0 + 57.0, [30.0, -45.0, 0.0]).is_err());
        // Rz(90)·Ry(30)·Rz(90): the tool along (0, 1/2, √3/2).
        let m = rot(swivel_rotation(64.0, [90.0, 30.0, 90.0]).unwrap());
        let (s, c) = (0.5, 3f64.sqrt() / 2.0);
        assert!(
            (m[0][2]).abs() < 1e-12 && (m[1][2] - s).abs() < 1e-12 && (m[2][2] - c).abs() < 1e-12
        );
        assert!(swivel_rotation(64.0 + 57.0, [1.0, 1.0, 0.0]).is_err());
    }
}
