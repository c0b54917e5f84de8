//! Where a tool touches the surface it cuts, and the error there.
//!
//! formats.md fixes the ball end of the machine file's `[tool]`: the contact
//! point for surface normal `n` is `t + R·u − R·n` and the predicted deviation is
//! `n·e` with `e` the error of the tool tip. A tool whose machine-file entry
//! names its `shape` (docs/extensions.md) is a body of revolution: a cylinder of
//! radius R whose tip edge is rounded with the corner radius r (flat end r = 0,
//! ball end r = R, bull nose between), cutting up to the flute length L above
//! the tip. Its contact point follows the normal on the corner torus, and for a
//! normal square to the axis (within [`FLANK_COS`]) slides up the side to the
//! plan point's height (flank milling); its deviation adds the tool's tilt
//! acting on the contact's lever: `e + (u × δu) × (c − t)`, the end of a flat
//! or bull-nose tool touching with its lowest point under that tilt
//! ([`error_at_contact`]).
//!
//! Invariant: pure geometry on part coordinates; no I/O, no kinematics.
use crate::gcode::CutterShape;
use crate::vec3::{add, cross, dot, norm, scale, sub};

/// Normals within this cosine of square to the tool axis (≈ 1.15°) are cut by
/// the side of the tool (flank).
pub const FLANK_COS: f64 = 0.02;

/// The contact point's offset from the tool tip, `c − t` (part coordinates,
/// mm), for plan point `point` with unit outward normal `normal`, cut by a tool
/// of `radius` with tip `tip`, unit axis `axis` and `shape` (`None`: formats.md's
/// ball, `R·u − R·n`).
pub fn contact_offset(
    tip: [f64; 3],
    axis: [f64; 3],
    radius: f64,
    shape: Option<CutterShape>,
    point: [f64; 3],
    normal: [f64; 3],
) -> [f64; 3] {
    let Some(shape) = shape else {
        return scale(sub(axis, normal), radius);
    };
    let r = shape.corner_radius_mm;
    // The tool's outward normal at the contact is −n; its part square to the
    // axis points from the axis to the corner torus's circle.
    let m = scale(normal, -1.0);
    let across = sub(m, scale(axis, dot(m, axis)));
    let s = norm(across);
    let v = if s > 1e-12 {
        scale(across, 1.0 / s)
    } else {
        [0.0; 3]
    };
    let up = dot(normal, axis);
    let corner = if up >= 0.0 {
        // On the corner torus (or the end face) where its normal is −n.
        add(add(scale(axis, r), scale(v, radius - r)), scale(m, r))
    } else {
        // A normal facing away from the spindle: the side's lowest line.
        add(scale(axis, r), scale(v, radius))
    };
    if up > FLANK_COS {
        return corner;
    }
    // Flank: up the side to the plan point's height, within the flute.
    let height = dot(sub(sub(point, tip), corner), axis);
    let slide = height.clamp(0.0, (shape.flute_length_mm - r).max(0.0));
    add(corner, scale(axis, slide))
}

/// The farthest a contact point lies from the corner circle's centre `t + r·u`
/// beyond the corner radius, mm: `(R − r) + (L − r)` for a named shape, 0 for
/// formats.md's ball. The plan matcher widens its search by this.
pub fn contact_reach(radius: f64, shape: Option<CutterShape>) -> f64 {
    shape.map_or(0.0, |s| {
        (radius - s.corner_radius_mm).max(0.0) + (s.flute_length_mm - s.corner_radius_mm).max(0.0)
    })
}

/// The error at a contact point (µm, part coordinates): the tip's error
/// `e_um` plus the tilt of the tool (actual − nominal axis, `axis_error_urad`,
/// about the tip) acting on the contact's offset `offset` (mm) from the tip.
///
/// `rim` is the radius `R − r` of the corner circle when the end of a named
/// flat or bull-nose tool cuts (not its side), else 0. The end touches with its
/// lowest point relative to the surface: for a normal `n` close to the axis
/// that point is chosen by the tilt itself, so the rim's share along `n` is
/// `−rim·(|w| − |n⊥|)` with `w = n⊥ − (n·u)·δu⊥` (`n⊥`, `δu⊥`: the parts square
/// to `u`): `−rim·|δu⊥|` on a floor square to the axis (the tilted face digs in
/// with its rim), `−rim·(v·δu)` on a surface clearly tilted from it.
pub fn error_at_contact(
    e_um: [f64; 3],
    axis: [f64; 3],
    axis_error_urad: [f64; 3],
    offset: [f64; 3],
    normal: [f64; 3],
    rim: f64,
) -> [f64; 3] {
    let tilt = cross(axis, axis_error_urad);
    let across = |v: [f64; 3]| sub(v, scale(axis, dot(v, axis)));
    let n_across = across(normal);
    // The offset without its radial (rim) part, when the end cuts.
    let radial = if rim > 0.0 && norm(n_across) > 0.0 {
        scale(n_across, -rim / norm(n_across))
    } else {
        [0.0; 3]
    };
    let e = add(e_um, scale(cross(tilt, sub(offset, radial)), 1e-3));
    if rim <= 0.0 {
        return e;
    }
    let du_across = scale(across(axis_error_urad), 1e-6);
    let w = sub(n_across, scale(du_across, dot(normal, axis)));
    add(e, scale(normal, -rim * (norm(w) - norm(n_across)) * 1e3))
}

#[cfg(test)]
mod tests {
    use super::*;

    const Z: [f64; 3] = [0.0, 0.0, 1.0];

    fn shape(corner: f64, flute: f64) -> Option<CutterShape> {
        Some(CutterShape {
            corner_radius_mm: corner,
            flute_length_mm: flute,
        })
    }

    fn close(a: [f64; 3], b: [f64; 3]) -> bool {
        norm(sub(a, b)) < 1e-12
    }

    #[test]
    fn a_named_ball_touches_where_formats_md_says() {
        let n = [0.6, 0.0, 0.8];
        let unnamed = contact_offset([0.0; 3], Z, 3.0, None, [9.0; 3], n);
        let ball = contact_offset([0.0; 3], Z, 3.0, shape(3.0, 10.0), [9.0; 3], n);
        assert!(close(unnamed, ball), "{unnamed:?} {ball:?}");
        assert!(close(ball, [-1.8, 0.0, 0.6]));
    }

    #[test]
    fn flat_and_bull_ends_touch_on_their_corner_and_face() {
        // Floor (n = u): the centre of a flat end's face.
        assert!(close(
            contact_offset([0.0; 3], Z, 5.0, shape(0.0, 20.0), [0.0; 3], Z),
            [0.0; 3]
        ));
        // A 45° slope facing −x and up: the bull nose's torus (corner 1 of R 5)
        // on its +x side.
        let n = [-(0.5f64.sqrt()), 0.0, 0.5f64.sqrt()];
        let c = contact_offset([0.0; 3], Z, 5.0, shape(1.0, 20.0), [0.0; 3], n);
        let h = 0.5f64.sqrt();
        assert!(close(c, [4.0 + h, 0.0, 1.0 - h]), "{c:?}");
    }

    #[test]
    fn a_wall_is_cut_by_the_side_at_the_plan_points_height() {
        // A wall at x = 5 facing −x (towards the tool), cut by the side of a
        // flat R5 at the origin, flute 20.
        let n = [-1.0, 0.0, 0.0];
        let at = |z: f64| contact_offset([0.0; 3], Z, 5.0, shape(0.0, 20.0), [5.0, 0.0, z], n);
        assert!(close(at(12.0), [5.0, 0.0, 12.0]), "{:?}", at(12.0));
        // Above the flute, and below the tip: clamped.
        assert!(close(at(30.0), [5.0, 0.0, 20.0]));
        assert!(close(at(-3.0), [5.0, 0.0, 0.0]));
    }

    #[test]
    fn the_tilt_acts_on_the_lever_of_the_contact() {
        // Axis z tilted by 50 µrad towards +x: a wall point 20 mm up the side
        // moves 1 µm in x (the side cuts: no rim term).
        let wall = [-1.0, 0.0, 0.0];
        let e = error_at_contact(
            [0.1, 0.2, 0.3],
            Z,
            [50.0, 0.0, 0.0],
            [-5.0, 0.0, 20.0],
            wall,
            0.0,
        );
        assert!((e[0] - 1.1).abs() < 1e-12, "{e:?}");
        assert!((e[1] - 0.2).abs() < 1e-12);
    }

    #[test]
    fn a_tilted_flat_end_digs_into_a_floor_with_its_rim() {
        // A floor square to the axis, a flat R5 tilted by 50 µrad: its rim
        // goes 0.25 µm deeper, whichever way it tilts.
        for tilt in [[50.0, 0.0, 0.0], [0.0, -50.0, 0.0], [30.0, 40.0, 0.0]] {
            let e = error_at_contact([0.0; 3], Z, tilt, [0.0; 3], Z, 5.0);
            assert!((dot(e, Z) + 0.25).abs() < 1e-9, "{tilt:?}: {e:?}");
        }
        // A surface tilted 1 mrad from the axis (≫ the error): the rim point
        // on its low side touches, and the tilt moves it as a lever would.
        let n = crate::vec3::normalise([1e-3, 0.0, 1.0]);
        let v = [-1.0, 0.0, 0.0];
        let o = contact_offset([0.0; 3], Z, 5.0, shape(0.0, 20.0), [0.0; 3], n);
        assert!(close(o, scale(v, 5.0)), "{o:?}");
        let e = error_at_contact([0.0; 3], Z, [50.0, 0.0, 0.0], o, n, 5.0);
        // −rim·(v·δu) = −5 mm · (−50 µrad) = +0.25 µm (that side rises).
        assert!((dot(e, n) - 0.25).abs() < 2e-3, "{e:?}");
        // Without a tilt, nothing.
        let e = error_at_contact([0.0; 3], Z, [0.0; 3], o, n, 5.0);
        assert!(norm(e) < 1e-12);
    }
}
