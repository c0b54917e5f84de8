//! The geometry of Klartext working planes and contour corners, as pure
//! functions (no state): the rotation each `PLANE` form defines (TNC 640
//! user's manual, "Multiple-axis machining › The PLANE function"), and the
//! rounding arc `RND` the control inserts between straight lines and arcs
//! and the chamfer `CHF` between two straight lines ("Path contours –
//! Cartesian coordinates › Corner rounding RND", "› Chamfer CHF"; TNC 620
//! Klartext user's manual 01/2022 pp. 154–157), and the paths of
//! `APPR`/`DEP` `LN`, `CT`, `LCT` ([`ContourContact`]).
//!
//! Rotations are 3×3 matrices, rows, mapping the tilted (program) frame's
//! coordinates to the workpiece frame's: their columns are the tilted X, Y
//! and Z axes in workpiece coordinates.

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

/// A corner the control rounds or chamfers: the two straight lines
/// `start → corner → end` (in-plane coordinates u, v).
#[derive(Clone, Copy, Debug)]
pub struct Corner {
    /// Where the first line starts.
    pub start: [f64; 2],
    /// Where the two lines meet (the programmed end of the first).
    pub corner: [f64; 2],
    /// Where the second line ends.
    pub end: [f64; 2],
}

/// What the control inserts at a corner: the points where the first line
/// now ends and the second begins, and for a rounding its centre and sense.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Inserted {
    /// The first line's new end.
    pub from: [f64; 2],
    /// The second line's new start.
    pub to: [f64; 2],
    /// `RND`: the arc's centre and whether it turns clockwise.
    pub arc: Option<([f64; 2], bool)>,
}

/// Why a corner cannot be rounded or chamfered (the control's refusal).
#[derive(Clone, Debug, PartialEq)]
pub enum CornerError {
    /// A line of zero length.
    ZeroLength,
    /// The two lines go on in one direction (no corner) or turn back.
    Straight,
    /// The rounding or chamfer does not fit on the lines: the distance it
    /// needs from the corner, and the shorter line's length.
    TooLarge {
        /// Distance needed along each line from the corner, mm.
        needed: f64,
        /// The shorter line's length, mm.
        available: f64,
    },
}

impl Corner {
    fn legs(&self) -> Result<([f64; 2], [f64; 2], f64, f64), CornerError> {
        let a = [
            self.corner[0] - self.start[0],
            self.corner[1] - self.start[1],
        ];
        let b = [self.end[0] - self.corner[0], self.end[1] - self.corner[1]];
        let (la, lb) = (a[0].hypot(a[1]), b[0].hypot(b[1]));
        if la < 1e-9 || lb < 1e-9 {
            return Err(CornerError::ZeroLength);
        }
        Ok(([a[0] / la, a[1] / la], [b[0] / lb, b[1] / lb], la, lb))
    }

    fn at(&self, u: [f64; 2], d: f64) -> [f64; 2] {
        [self.corner[0] + u[0] * d, self.corner[1] + u[1] * d]
    }

    /// `RND R`: the arc of radius `r` tangent to both lines; its tangent
    /// points lie `r·tan(φ/2)` from the corner, φ the change of direction.
    pub fn round(&self, r: f64) -> Result<Inserted, CornerError> {
        let (u, v, la, lb) = self.legs()?;
        let turn = u[0] * v[1] - u[1] * v[0];
        let along = u[0] * v[0] + u[1] * v[1];
        let phi = turn.atan2(along);
        if turn.abs() < 1e-12 || phi.abs() > std::f64::consts::PI - 1e-9 {
            return Err(CornerError::Straight);
        }
        let r = r.abs();
        let d = r * (phi.abs() / 2.0).tan();
        if d > la.min(lb) + 1e-9 {
            return Err(CornerError::TooLarge {
                needed: d,
                available: la.min(lb),
            });
        }
        let from = self.at(u, -d);
        let to = self.at(v, d);
        // The centre: r to the inside of the turn from the first tangent point.
        let side = if turn > 0.0 { 1.0 } else { -1.0 };
        let normal = [-u[1] * side, u[0] * side];
        let centre = [from[0] + normal[0] * r, from[1] + normal[1] * r];
        Ok(Inserted {
            from,
            to,
            arc: Some((centre, turn < 0.0)),
        })
    }

    /// `CHF L`: a straight line cutting the corner `l` from it along each
    /// line ("chamfer side length").
    pub fn chamfer(&self, l: f64) -> Result<Inserted, CornerError> {
        let (u, v, la, lb) = self.legs()?;
        let turn = u[0] * v[1] - u[1] * v[0];
        if turn.abs() < 1e-12 && u[0] * v[0] + u[1] * v[1] > 0.0 {
            return Err(CornerError::Straight);
        }
        let l = l.abs();
        if l > la.min(lb) + 1e-9 {
            return Err(CornerError::TooLarge {
                needed: l,
                available: la.min(lb),
            });
        }
        Ok(Inserted {
            from: self.at(u, -l),
            to: self.at(v, l),
            arc: None,
        })
    }
}

/// A contour element meeting a corner (working-plane coordinates): a
/// straight line or a circular arc, and its other end (where the element
/// before the corner starts, or where the one after it ends).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Element {
    /// A straight line.
    Line {
        /// Its end away from the corner.
        other: [f64; 2],
    },
    /// A circular arc.
    Arc {
        /// Its centre.
        centre: [f64; 2],
        /// It turns clockwise (in the direction of travel).
        clockwise: bool,
        /// Its end away from the corner.
        other: [f64; 2],
    },
}

impl Element {
    /// The unit direction of travel at the corner; `before`: the element
    /// ends there, else it starts there.
    fn direction_at(&self, corner: [f64; 2], before: bool) -> Option<[f64; 2]> {
        let d = match *self {
            Element::Line { other } if before => [corner[0] - other[0], corner[1] - other[1]],
            Element::Line { other } => [other[0] - corner[0], other[1] - corner[1]],
            Element::Arc {
                centre, clockwise, ..
            } => {
                let r = [corner[0] - centre[0], corner[1] - centre[1]];
                if clockwise {
                    [r[1], -r[0]]
                } else {
                    [-r[1], r[0]]
                }
            }
        };
        let n = d[0].hypot(d[1]);
        (n > 1e-9).then(|| [d[0] / n, d[1] / n])
    }

    /// Where the element touches the circle about `m` of radius `r`
    /// that is tangent to it: the foot of `m` on the line, or the point of
    /// the arc's circle towards `m`.
    fn touch(&self, corner: [f64; 2], direction: [f64; 2], m: [f64; 2]) -> [f64; 2] {
        match *self {
            Element::Line { .. } => {
                let t = (m[0] - corner[0]) * direction[0] + (m[1] - corner[1]) * direction[1];
                [corner[0] + t * direction[0], corner[1] + t * direction[1]]
            }
            Element::Arc { centre, .. } => {
                let rho = (corner[0] - centre[0]).hypot(corner[1] - centre[1]);
                let d = [m[0] - centre[0], m[1] - centre[1]];
                let n = d[0].hypot(d[1]).max(1e-300);
                [centre[0] + rho * d[0] / n, centre[1] + rho * d[1] / n]
            }
        }
    }

    /// `p` lies on the part of the element between the corner and its
    /// other end (`before`: the element runs from `other` to the corner).
    fn holds(&self, corner: [f64; 2], p: [f64; 2], before: bool) -> bool {
        let (from, to) = match *self {
            Element::Line { other } | Element::Arc { other, .. } if before => (other, corner),
            Element::Line { other } | Element::Arc { other, .. } => (corner, other),
        };
        match *self {
            Element::Line { .. } => {
                let d = [to[0] - from[0], to[1] - from[1]];
                let l2 = d[0] * d[0] + d[1] * d[1];
                let t = ((p[0] - from[0]) * d[0] + (p[1] - from[1]) * d[1]) / l2.max(1e-300);
                (-1e-9..=1.0 + 1e-9).contains(&t)
            }
            Element::Arc {
                centre, clockwise, ..
            } => {
                let angle = |q: [f64; 2]| (q[1] - centre[1]).atan2(q[0] - centre[0]);
                let sweep = |a: f64, b: f64| {
                    let d = if clockwise { a - b } else { b - a };
                    d.rem_euclid(std::f64::consts::TAU)
                };
                let whole = sweep(angle(from), angle(to));
                let whole = if whole < 1e-12 {
                    std::f64::consts::TAU
                } else {
                    whole
                };
                sweep(angle(from), angle(p)) <= whole + 1e-9
            }
        }
    }
}

/// `RND R` between two contour elements of which at least one is an arc
/// (TNC 620 Klartext user's manual 01/2022, "Corner rounding RND" p. 157:
/// "a circular arc with tangential connection to the preceding and
/// subsequent contour elements"): the centre of the rounding lies `r` from
/// both elements on the inside of the turn (the elements offset by `r`,
/// intersected: the intersection nearest the corner), its tangent points
/// are where it touches them. Both tangent points must lie on the
/// elements (else too large); elements meeting tangentially make no corner.
pub fn round_elements(
    first: Element,
    corner: [f64; 2],
    second: Element,
    r: f64,
) -> Result<Inserted, CornerError> {
    let r = r.abs();
    let (Some(u), Some(v)) = (
        first.direction_at(corner, true),
        second.direction_at(corner, false),
    ) else {
        return Err(CornerError::ZeroLength);
    };
    let turn = u[0] * v[1] - u[1] * v[0];
    let along = u[0] * v[0] + u[1] * v[1];
    if turn.abs() < 1e-9 || turn.atan2(along).abs() > std::f64::consts::PI - 1e-9 {
        return Err(CornerError::Straight);
    }
    let left = turn > 0.0;
    // Each element offset by r towards the inside of the turn: a line
    // (point, direction) or a circle (centre, radius).
    enum Offset {
        Line([f64; 2], [f64; 2]),
        Circle([f64; 2], f64),
    }
    let offset = |e: &Element, d: [f64; 2]| -> Result<Offset, CornerError> {
        let side = if left { 1.0 } else { -1.0 };
        match *e {
            Element::Line { .. } => Ok(Offset::Line(
                [corner[0] - side * r * d[1], corner[1] + side * r * d[0]],
                d,
            )),
            Element::Arc {
                centre, clockwise, ..
            } => {
                let rho = (corner[0] - centre[0]).hypot(corner[1] - centre[1]);
                // The centre is on the left of travel when counter-clockwise.
                let inner = clockwise != left;
                let rr = if inner { rho - r } else { rho + r };
                if rr <= 1e-9 {
                    return Err(CornerError::TooLarge {
                        needed: r,
                        available: rho,
                    });
                }
                Ok(Offset::Circle(centre, rr))
            }
        }
    };
    let (a, b) = (offset(&first, u)?, offset(&second, v)?);
    let line_circle = |p: [f64; 2], d: [f64; 2], o: [f64; 2], rr: f64| -> Vec<[f64; 2]> {
        let w = [p[0] - o[0], p[1] - o[1]];
        let bq = d[0] * w[0] + d[1] * w[1];
        let cq = w[0] * w[0] + w[1] * w[1] - rr * rr;
        let disc = bq * bq - cq;
        if disc < 0.0 {
            return Vec::new();
        }
        let sq = disc.sqrt();
        [-bq - sq, -bq + sq]
            .iter()
            .map(|t| [p[0] + t * d[0], p[1] + t * d[1]])
            .collect()
    };
    let candidates: Vec<[f64; 2]> = match (&a, &b) {
        (Offset::Line(p, d), Offset::Circle(o, rr))
        | (Offset::Circle(o, rr), Offset::Line(p, d)) => line_circle(*p, *d, *o, *rr),
        (Offset::Circle(o1, r1), Offset::Circle(o2, r2)) => {
            let d = [o2[0] - o1[0], o2[1] - o1[1]];
            let l = d[0].hypot(d[1]);
            if l < 1e-12 {
                Vec::new()
            } else {
                let x = (l * l + r1 * r1 - r2 * r2) / (2.0 * l);
                let h2 = r1 * r1 - x * x;
                if h2 < 0.0 {
                    Vec::new()
                } else {
                    let h = h2.sqrt();
                    let (e, n) = ([d[0] / l, d[1] / l], [-d[1] / l, d[0] / l]);
                    [h, -h]
                        .iter()
                        .map(|s| [o1[0] + x * e[0] + s * n[0], o1[1] + x * e[1] + s * n[1]])
                        .collect()
                }
            }
        }
        (Offset::Line(..), Offset::Line(..)) => {
            // Two straight lines: `Corner::round`.
            return Corner {
                start: match first {
                    Element::Line { other } => other,
                    Element::Arc { other, .. } => other,
                },
                corner,
                end: match second {
                    Element::Line { other } => other,
                    Element::Arc { other, .. } => other,
                },
            }
            .round(r);
        }
    };
    let distance = |p: [f64; 2]| (p[0] - corner[0]).hypot(p[1] - corner[1]);
    let m = candidates
        .into_iter()
        .min_by(|p, q| distance(*p).total_cmp(&distance(*q)))
        .ok_or(CornerError::TooLarge {
            needed: r,
            available: 0.0,
        })?;
    let from = first.touch(corner, u, m);
    let to = second.touch(corner, v, m);
    let size = |e: &Element| match *e {
        Element::Line { other } | Element::Arc { other, .. } => distance(other),
    };
    if !first.holds(corner, from, true) {
        return Err(CornerError::TooLarge {
            needed: distance(from),
            available: size(&first),
        });
    }
    if !second.holds(corner, to, false) {
        return Err(CornerError::TooLarge {
            needed: distance(to),
            available: size(&second),
        });
    }
    Ok(Inserted {
        from,
        to,
        arc: Some((m, !left)),
    })
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

    /// A rounding between a line and an arc and between two arcs, worked by
    /// hand. The line along +X to (10, 0); an arc about (10, 10) leaving
    /// (10, 0) counter-clockwise goes on along +X (tangent: no corner). The
    /// arc about (20, 0), counter-clockwise from (10, 0), leaves along -Y:
    /// a right turn, the rounding on the right. R2: its centre is 2 below
    /// the line (y = -2) and 10 + 2 = 12 from (20, 0) (outside that
    /// circle), nearest the corner: x = 20 - √(144 - 4); the tangent points
    /// (x, 0) and (20, 0) + 10·(m - (20, 0))/12; it turns clockwise.
    /// Two arcs: clockwise about (0, -10) arriving at (0, 0) along +X, then
    /// counter-clockwise about (10, 0) leaving along -Y (a right turn): the
    /// rounding's centre is 10 - 1 from (0, -10) (inside the first circle)
    /// and 10 + 1 from (10, 0) (outside the second), near the corner.
    #[test]
    fn round_line_and_arc_and_two_arcs() {
        let first = Element::Line { other: [0.0, 0.0] };
        let second = Element::Arc {
            centre: [20.0, 0.0],
            clockwise: false,
            other: [30.0, 0.0],
        };
        assert_eq!(
            round_elements(
                first,
                [10.0, 0.0],
                Element::Arc {
                    centre: [10.0, 10.0],
                    clockwise: false,
                    other: [20.0, 10.0]
                },
                2.0
            ),
            Err(CornerError::Straight)
        );
        let got = round_elements(first, [10.0, 0.0], second, 2.0).unwrap();
        let x = 20.0 - 140f64.sqrt();
        let m = [x, -2.0];
        let (centre, clockwise) = got.arc.unwrap();
        assert!(clockwise);
        assert!(
            (centre[0] - m[0]).abs() < 1e-9 && (centre[1] - m[1]).abs() < 1e-9,
            "{got:?}"
        );
        assert!(
            (got.from[0] - x).abs() < 1e-9 && got.from[1].abs() < 1e-9,
            "{got:?}"
        );
        let to = [20.0 + 10.0 * (m[0] - 20.0) / 12.0, 10.0 * m[1] / 12.0];
        assert!(
            (got.to[0] - to[0]).abs() < 1e-9 && (got.to[1] - to[1]).abs() < 1e-9,
            "{got:?}"
        );
        let a = Element::Arc {
            centre: [0.0, -10.0],
            clockwise: true,
            other: [-10.0, -10.0],
        };
        let b = Element::Arc {
            centre: [10.0, 0.0],
            clockwise: false,
            other: [10.0, -10.0],
        };
        let got = round_elements(a, [0.0, 0.0], b, 1.0).unwrap();
        let (m, _) = got.arc.unwrap();
        assert!(((m[0] - 0.0).hypot(m[1] + 10.0) - 9.0).abs() < 1e-9);
        assert!(((m[0] - 10.0).hypot(m[1]) - 11.0).abs() < 1e-9);
        assert!(m[0].hypot(m[1]) < 2.0, "{m:?}");
        // Too large for the arc after it.
        assert!(matches!(
            round_elements(first, [10.0, 0.0], second, 40.0),
            Err(CornerError::TooLarge { .. })
        ));
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
    fn rounding_and_chamfer_at_a_right_angle() {
        let c = Corner {
            start: [0.0, 0.0],
            corner: [10.0, 0.0],
            end: [10.0, 10.0],
        };
        let r = c.round(3.0).unwrap();
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-12 && (a[1] - b[1]).abs() < 1e-12;
        assert!(
            close(r.from, [7.0, 0.0]) && close(r.to, [10.0, 3.0]),
            "{r:?}"
        );
        let (centre, cw) = r.arc.unwrap();
        assert!((centre[0] - 7.0).abs() < 1e-12 && (centre[1] - 3.0).abs() < 1e-12 && !cw);
        let k = c.chamfer(2.0).unwrap();
        assert!(
            close(k.from, [8.0, 0.0]) && close(k.to, [10.0, 2.0]),
            "{k:?}"
        );
        assert!(matches!(c.round(11.0), Err(CornerError::TooLarge { .. })));
        let straight = Corner {
            end: [20.0, 0.0],
            ..c
        };
        assert_eq!(straight.round(1.0), Err(CornerError::Straight));
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
