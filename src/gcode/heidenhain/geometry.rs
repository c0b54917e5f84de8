//! The geometry of Klartext working planes, as pure functions (no state):
//! the rotation each `PLANE` form defines (TNC 640 user's manual,
//! "Multiple-axis machining › The PLANE function"), and the paths of
//! `APPR`/`DEP` `LN`, `CT`, `LCT` ([`ContourContact`]). The contour corners
//! `RND`/`CHF` are shared with SINUMERIK's `RND=`/`CHF=`:
//! [`crate::gcode::contour_corners`], re-exported here.
//!
//! Rotations are 3×3 matrices, rows, mapping the tilted (program) frame's
//! coordinates to the workpiece frame's: their columns are the tilted X, Y
//! and Z axes in workpiece coordinates.

pub use crate::gcode::contour_corners::{Corner, CornerError, Element, round_elements};

/// A 3×3 rotation, rows.
pub type Mat3 = [[f64; 3]; 3];

/// The identity.
pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

/// `a · b`.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `a × b`.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn unit(v: [f64; 3]) -> Option<[f64; 3]> {
    let n = dot(v, v).sqrt();
    (n > 1e-12 && n.is_finite()).then(|| v.map(|x| x / n))
}

/// `m · v`.
pub fn mat_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

/// `mᵀ · v`.
pub fn mat_t_vec(m: &Mat3, v: [f64; 3]) -> [f64; 3] {
    [
        m[0][0] * v[0] + m[1][0] * v[1] + m[2][0] * v[2],
        m[0][1] * v[0] + m[1][1] * v[1] + m[2][1] * v[2],
        m[0][2] * v[0] + m[1][2] * v[1] + m[2][2] * v[2],
    ]
}

/// `a · b`.
pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = (0..3).map(|k| a[i][k] * b[k][j]).sum();
        }
    }
    m
}

/// The rotation whose columns are `x`, `y`, `z`.
fn from_columns(x: [f64; 3], y: [f64; 3], z: [f64; 3]) -> Mat3 {
    [[x[0], y[0], z[0]], [x[1], y[1], z[1]], [x[2], y[2], z[2]]]
}

/// The rotation about X, Y or Z (0, 1, 2) by `deg` degrees, right-handed.
pub fn rotation(axis: usize, deg: f64) -> Mat3 {
    let (s, c) = deg.to_radians().sin_cos();
    match axis {
        0 => [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]],
        1 => [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]],
        _ => [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
    }
}

/// `PLANE SPATIAL SPA SPB SPC` (and `CYCL DEF 19` with spatial angles):
/// the working plane turned about the workpiece's X by SPA, then its Y by
/// SPB, then its Z by SPC, all about fixed axes (iTNC 530 user's manual
/// 340 422, p. 460): `R = Rz·Ry·Rx`.
pub fn spatial(spa: f64, spb: f64, spc: f64) -> Mat3 {
    mat_mul(
        &rotation(2, spc),
        &mat_mul(&rotation(1, spb), &rotation(0, spa)),
    )
}

/// `PLANE PROJECTED PROPR PROMIN ROT`: the tilted plane's trace on the
/// workpiece's ZX plane makes the angle PROPR with X (turned about Y, as
/// SPB), its trace on the YZ plane the angle PROMIN with Y (turned about X,
/// as SPA); the tilted X axis lies along the first trace, and `ROT` turns
/// the tilted frame about its tool axis (TNC 640 user's manual, "PLANE
/// PROJECTED": "projection angle on the 1st / 2nd coordinate plane",
/// "ROT: rotation of the tilted coordinate system about the tilted tool
/// axis"). `None` when an angle is ±90° or more (the traces are then
/// undefined).
pub fn projected(propr: f64, promin: f64, rot: f64) -> Option<Mat3> {
    if propr.abs() >= 90.0 - 1e-9 || promin.abs() >= 90.0 - 1e-9 {
        return None;
    }
    // The traces: (1, 0, −tan PROPR) in ZX (Ry(PROPR)·X ∥ it), (0, 1, tan PROMIN) in YZ.
    let u = unit([1.0, 0.0, -propr.to_radians().tan()])?;
    let v = [0.0, 1.0, promin.to_radians().tan()];
    let z = unit(cross(u, v))?;
    let y = cross(z, u);
    Some(mat_mul(&from_columns(u, y, z), &rotation(2, rot)))
}

/// `PLANE EULER EULPR EULNU EULROT`: precession about the workpiece's Z,
/// then nutation about the turned X, then rotation about the turned Z
/// (TNC 640 user's manual, "PLANE EULER"): `R = Rz(PR)·Rx(NU)·Rz(ROT)`.
pub fn euler(precession: f64, nutation: f64, rot: f64) -> Mat3 {
    mat_mul(
        &rotation(2, precession),
        &mat_mul(&rotation(0, nutation), &rotation(2, rot)),
    )
}

/// `PLANE POINTS P1 P2 P3`: the tilted X axis from P1 to P2, the tilted
/// tool axis by the right-hand rule with P3 on the side of the tilted Y
/// (TNC 640 user's manual, "PLANE POINTS"; iTNC 530 user's manual 340 422,
/// p. 464). `None` when the points are on one line.
pub fn points(p1: [f64; 3], p2: [f64; 3], p3: [f64; 3]) -> Option<Mat3> {
    let d = |a: [f64; 3], b: [f64; 3]| [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let x = unit(d(p1, p2))?;
    let z = unit(cross(d(p1, p2), d(p1, p3)))?;
    let y = cross(z, x);
    Some(from_columns(x, y, z))
}

/// The frame whose Z is `normal` and whose X is `base` made perpendicular to
/// it (PLANE VECTOR).
pub fn vector_frame(base: [f64; 3], normal: [f64; 3]) -> Option<Mat3> {
    let z = unit(normal)?;
    let bz = dot(base, z);
    let x = [
        base[0] - bz * z[0],
        base[1] - bz * z[1],
        base[2] - bz * z[2],
    ];
    if dot(x, x).sqrt() < 1e-9 {
        return None;
    }
    let x = unit(x)?;
    Some(from_columns(x, cross(z, x), z))
}

/// `v` turned by `deg` degrees (counter-clockwise for positive) in the plane.
fn turned(v: [f64; 2], deg: f64) -> [f64; 2] {
    let (s, c) = deg.to_radians().sin_cos();
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

/// Where the tool meets or leaves a contour in `APPR`/`DEP` (working-plane
/// coordinates): the contour point, the unit direction of travel along the
/// contour there, and the side of the contour the tool is on (left of the
/// travel direction, as `RL`, or right, as `RR`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContourContact {
    /// The first contour point `PA` (approach) or the last `PE` (departure).
    pub point: [f64; 2],
    /// The unit direction of travel along the contour at `point`.
    pub direction: [f64; 2],
    /// The tool is on the left of the contour (looking along `direction`).
    pub left: bool,
}

/// An arc of the approach or departure: its centre, its sense, and its end
/// away from the contour (`PH` of `APPR CT`/`LCT`, `PN` of `DEP CT`, the
/// tangent point of `DEP LCT`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ContactArc {
    /// The arc's centre.
    pub centre: [f64; 2],
    /// The arc turns clockwise (in the direction of travel).
    pub clockwise: bool,
    /// The arc's end away from the contour point.
    pub away: [f64; 2],
}

impl ContourContact {
    /// The unit normal pointing to the tool's side.
    fn normal(&self) -> [f64; 2] {
        let [u, v] = self.direction;
        if self.left { [-v, u] } else { [v, -u] }
    }

    /// The side of the contour's line through `point` that `p` lies on:
    /// `Some(true)` left, `Some(false)` right, `None` on the line.
    pub fn side_of(point: [f64; 2], direction: [f64; 2], p: [f64; 2]) -> Option<bool> {
        let cross = direction[0] * (p[1] - point[1]) - direction[1] * (p[0] - point[0]);
        (cross.abs() > 1e-9).then_some(cross > 0.0)
    }

    /// `APPR LN` / `DEP LN`: the point `len` from the contour point on the
    /// perpendicular to the contour, on the tool's side.
    pub fn perpendicular(&self, len: f64) -> [f64; 2] {
        let n = self.normal();
        [self.point[0] + len * n[0], self.point[1] + len * n[1]]
    }

    /// `APPR CT` / `DEP CT`: the arc of radius `r` and centre angle
    /// `cca_deg` tangent to the contour at its point, its centre on the
    /// tool's side (so that the whole arc is there), turning with the
    /// contour; `arriving`: it ends at the contour point (approach), else
    /// it starts there (departure).
    pub fn tangent_arc(&self, r: f64, cca_deg: f64, arriving: bool) -> ContactArc {
        let n = self.normal();
        let r = r.abs();
        let centre = [self.point[0] + r * n[0], self.point[1] + r * n[1]];
        // Centre on the left of travel: counter-clockwise.
        let clockwise = !self.left;
        let sense = if clockwise { -1.0 } else { 1.0 };
        let back = if arriving { -1.0 } else { 1.0 };
        let radius = [self.point[0] - centre[0], self.point[1] - centre[1]];
        let q = turned(radius, sense * back * cca_deg);
        ContactArc {
            centre,
            clockwise,
            away: [centre[0] + q[0], centre[1] + q[1]],
        }
    }

    /// `APPR LCT` / `DEP LCT`: the arc of radius `r` tangent to the contour
    /// at its point (centre on the tool's side) and the straight line from
    /// `other` (the start `PS` when `arriving`, else the end `PN`) tangent
    /// to it; `away` is where line and arc meet. `None` when `other` lies
    /// within the arc's circle (no tangent).
    pub fn line_and_arc(&self, r: f64, other: [f64; 2], arriving: bool) -> Option<ContactArc> {
        let arc = self.tangent_arc(r, 0.0, arriving);
        let r = r.abs();
        let to = [other[0] - arc.centre[0], other[1] - arc.centre[1]];
        let d = to[0].hypot(to[1]);
        if d <= r + 1e-9 {
            return None;
        }
        let beta = (r / d).acos().to_degrees();
        // Arriving on a counter-clockwise arc, the line touches it ahead of
        // the direction to `other` (β further round); leaving, behind it.
        let ccw = !arc.clockwise;
        let turn = if ccw == arriving { beta } else { -beta };
        let u = turned([to[0] / d * r, to[1] / d * r], turn);
        Some(ContactArc {
            away: [arc.centre[0] + u[0], arc.centre[1] + u[1]],
            ..arc
        })
    }
}

/// Points along the arc about `centre` from `from` to `to` (in-plane),
/// `clockwise` or not, `turns` extra full turns, the third coordinate going
/// linearly from `w0` to `w1`: chords whose sagitta is at most `tolerance`
/// mm, excluding the start, including the end.
pub fn arc_chords(
    centre: [f64; 2],
    from: [f64; 3],
    to: [f64; 3],
    clockwise: bool,
    turns: u32,
    tolerance: f64,
) -> Vec<[f64; 3]> {
    let tau = std::f64::consts::TAU;
    let r0 = (from[0] - centre[0]).hypot(from[1] - centre[1]);
    let r1 = (to[0] - centre[0]).hypot(to[1] - centre[1]);
    let a0 = (from[1] - centre[1]).atan2(from[0] - centre[0]);
    let a1 = (to[1] - centre[1]).atan2(to[0] - centre[0]);
    let mut sweep = a1 - a0;
    if clockwise {
        while sweep >= -1e-12 {
            sweep -= tau;
        }
        sweep -= tau * f64::from(turns);
    } else {
        while sweep <= 1e-12 {
            sweep += tau;
        }
        sweep += tau * f64::from(turns);
    }
    let r = r0.max(r1);
    let step = if r > tolerance {
        2.0 * (1.0 - tolerance / r).acos()
    } else {
        tau / 4.0
    };
    let n = ((sweep.abs() / step).ceil() as usize).clamp(1, 100_000);
    (1..=n)
        .map(|i| {
            if i == n {
                return to;
            }
            let t = i as f64 / n as f64;
            let a = a0 + sweep * t;
            let rr = r0 + (r1 - r0) * t;
            [
                centre[0] + rr * a.cos(),
                centre[1] + rr * a.sin(),
                from[2] + (to[2] - from[2]) * t,
            ]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn near(a: [f64; 3], b: [f64; 3]) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 1e-9)
    }

    fn column(m: &Mat3, k: usize) -> [f64; 3] {
        [m[0][k], m[1][k], m[2][k]]
    }

    /// Approach and departure worked by hand: the contour along +X from
    /// (10, 0), the tool on its right (below it, -Y).
    #[test]
    fn approach_and_departure_paths() {
        let c = ContourContact {
            point: [10.0, 0.0],
            direction: [1.0, 0.0],
            left: false,
        };
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9;
        assert_eq!(
            ContourContact::side_of([10.0, 0.0], [1.0, 0.0], [0.0, -3.0]),
            Some(false)
        );
        assert_eq!(
            ContourContact::side_of([10.0, 0.0], [1.0, 0.0], [0.0, 0.0]),
            None
        );
        assert!(close(c.perpendicular(5.0), [10.0, -5.0]));
        // A quarter arc of radius 4 arriving at (10, 0) moving +X: centre
        // (10, -4), clockwise, from (6, -4).
        let a = c.tangent_arc(4.0, 90.0, true);
        assert!(
            a.clockwise && close(a.centre, [10.0, -4.0]) && close(a.away, [6.0, -4.0]),
            "{a:?}"
        );
        // Leaving (10, 0) by a half turn: to (10, -8).
        let d = c.tangent_arc(4.0, 180.0, false);
        assert!(close(d.away, [10.0, -8.0]), "{d:?}");
        // From (6, -12) straight up to the circle about (10, -4), r 4: it
        // touches at (6, -4), then the clockwise quarter to (10, 0).
        let l = c.line_and_arc(4.0, [6.0, -12.0], true).unwrap();
        assert!(close(l.away, [6.0, -4.0]), "{l:?}");
        // Leaving: the clockwise quarter to (14, -4), then down to (14, -12).
        let l = c.line_and_arc(4.0, [14.0, -12.0], false).unwrap();
        assert!(close(l.away, [14.0, -4.0]), "{l:?}");
        assert!(c.line_and_arc(4.0, [10.0, -5.0], true).is_none());
    }

    #[test]
    fn projected_single_angles_are_spatial_ones() {
        // One projection angle alone: the plane turned about Y (PROPR) or X (PROMIN).
        let p = projected(30.0, 0.0, 0.0).unwrap();
        let s = spatial(0.0, 30.0, 0.0);
        for k in 0..3 {
            assert!(near(column(&p, k), column(&s, k)), "{p:?} {s:?}");
        }
        let p = projected(0.0, 20.0, 0.0).unwrap();
        let s = spatial(20.0, 0.0, 0.0);
        for k in 0..3 {
            assert!(near(column(&p, k), column(&s, k)), "{p:?} {s:?}");
        }
        assert!(projected(90.0, 0.0, 0.0).is_none());
    }

    #[test]
    fn projected_traces_have_their_angles() {
        // PROPR+24 PROMIN+24 (the manual's example): the tilted X lies in
        // ZX at −24° (Ry(24)·X), a vector of the plane lies in YZ at +24°.
        let r = projected(24.0, 24.0, 0.0).unwrap();
        let x = column(&r, 0);
        assert!(x[1].abs() < 1e-12);
        assert!((x[2].atan2(x[0]).to_degrees() + 24.0).abs() < 1e-9);
        let z = column(&r, 2);
        // The YZ trace (0, cos, sin)·24° is perpendicular to the normal.
        let t = [0.0, 24f64.to_radians().cos(), 24f64.to_radians().sin()];
        assert!(dot(z, t).abs() < 1e-12);
    }

    #[test]
    fn euler_and_points() {
        // EULPR+90 EULNU+45: Z turned 45° about the turned X (which is Y).
        let r = euler(90.0, 45.0, 0.0);
        let h = 0.5f64.sqrt();
        assert!(near(column(&r, 2), [h, 0.0, h]));
        assert!(near(column(&r, 0), [0.0, 1.0, 0.0]));
        // Three points in the plane z = x: X along +X tilted, Z = (−1, 0, 1)/√2.
        let p = points([0.0, 0.0, 0.0], [1.0, 0.0, 1.0], [0.0, 1.0, 0.0]).unwrap();
        assert!(near(column(&p, 0), [h, 0.0, h]));
        assert!(near(column(&p, 2), [-h, 0.0, h]));
        assert!(points([0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]).is_none());
    }

    #[test]
    fn chords_stay_within_the_tolerance() {
        let pts = arc_chords(
            [0.0, 0.0],
            [10.0, 0.0, 0.0],
            [0.0, 10.0, -1.0],
            false,
            0,
            1e-3,
        );
        let last = *pts.last().unwrap();
        assert_eq!(last, [0.0, 10.0, -1.0]);
        // sagitta = r(1 − cos(θ/2)) ≤ 1 µm.
        let theta = std::f64::consts::FRAC_PI_2 / pts.len() as f64;
        assert!(10.0 * (1.0 - (theta / 2.0).cos()) <= 1e-3);
        for p in &pts {
            assert!((p[0].hypot(p[1]) - 10.0).abs() < 1e-9);
        }
    }
}
