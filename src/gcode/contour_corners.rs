//! Contour corners as pure geometry (no state), shared by the dialects
//! whose controls insert them: the rounding arc and the chamfer a control
//! puts between two contour elements (straight lines and circular arcs in
//! the working plane, coordinates u, v).
//!
//! - Klartext `RND`/`CHF` (TNC 620 Klartext user's manual 01/2022
//!   pp. 154–157, "Corner rounding RND", "Chamfer CHF"): [`Corner`] between
//!   two lines, [`round_elements`] when an arc is involved.
//! - SINUMERIK `RND=`/`RNDM=`/`CHF=`/`CHR=` (*Fundamentals*, "Chamfer,
//!   rounding (CHF, CHR, RND, RNDM, FRC, FRCM)"): the same rounding, and
//!   [`chamfer_elements`], a chamfer between lines and arcs "in any
//!   combination", given by its leg (`CHR=`) or its own length (`CHF=`).
//!
//! A rounding's centre is where both elements, offset by the radius to the
//! inside of the turn, intersect (the intersection nearest the corner);
//! its tangent points are where it touches them.

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

/// The unit directions of travel into the corner (`first`'s at its end)
/// and out of it (`second`'s at its start); an element of no length there
/// is [`CornerError::ZeroLength`].
pub(crate) fn directions_at(
    first: &Element,
    corner: [f64; 2],
    second: &Element,
) -> Result<([f64; 2], [f64; 2]), CornerError> {
    match (
        first.direction_at(corner, true),
        second.direction_at(corner, false),
    ) {
        (Some(u), Some(v)) => Ok((u, v)),
        _ => Err(CornerError::ZeroLength),
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
    let (u, v) = directions_at(&first, corner, &second)?;
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

/// How a chamfer is given (SINUMERIK *Fundamentals*, "Chamfer, rounding":
/// `CHR=` "the width of the chamfer in the direction of motion", `CHF=`
/// "the length of the chamfer"; the manual's figure: CHF = 2·cos α·CHR,
/// α half the change of direction, the chamfer at right angles to the
/// corner's bisector).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Chamfer {
    /// `CHR=`: the distance from the corner to each end of the chamfer.
    Leg(f64),
    /// `CHF=`: the length of the chamfer itself.
    Length(f64),
}

impl Element {
    /// The point of the element whose straight distance from the corner is
    /// `d` (along a line; the chord on an arc), on the side the element
    /// runs (`before`: back from the corner). `None` beyond a diameter.
    fn at_distance(&self, corner: [f64; 2], before: bool, d: f64) -> Option<[f64; 2]> {
        match *self {
            Element::Line { other } => {
                let t = [other[0] - corner[0], other[1] - corner[1]];
                let n = t[0].hypot(t[1]);
                (n > 1e-12).then(|| [corner[0] + t[0] / n * d, corner[1] + t[1] / n * d])
            }
            Element::Arc {
                centre, clockwise, ..
            } => {
                let rho = (corner[0] - centre[0]).hypot(corner[1] - centre[1]);
                if rho < 1e-12 || d > 2.0 * rho {
                    return None;
                }
                // The chord d subtends 2·asin(d / 2ρ); travel turns
                // counter-clockwise unless `clockwise`, and back from the
                // corner the other way.
                let theta = 2.0 * (d / (2.0 * rho)).asin();
                let forward = if clockwise { -theta } else { theta };
                let a = if before { -forward } else { forward };
                let (s, c) = a.sin_cos();
                let r = [corner[0] - centre[0], corner[1] - centre[1]];
                Some([
                    centre[0] + c * r[0] - s * r[1],
                    centre[1] + s * r[0] + c * r[1],
                ])
            }
        }
    }
}

/// A chamfer between two contour elements, lines or arcs in any
/// combination: its ends lie on the elements at the same straight
/// distance from the corner (the leg; for `CHF=` the leg whose chamfer has
/// the length given, found by bisection). Both ends must lie on the
/// elements (else [`CornerError::TooLarge`]); elements that go on in one
/// direction make no corner ([`CornerError::Straight`]).
pub fn chamfer_elements(
    first: Element,
    corner: [f64; 2],
    second: Element,
    size: Chamfer,
) -> Result<Inserted, CornerError> {
    let (u, v) = directions_at(&first, corner, &second)?;
    let turn = u[0] * v[1] - u[1] * v[0];
    if turn.abs() < 1e-9 && u[0] * v[0] + u[1] * v[1] > 0.0 {
        return Err(CornerError::Straight);
    }
    let distance = |p: [f64; 2]| (p[0] - corner[0]).hypot(p[1] - corner[1]);
    let size_of = |e: &Element| match *e {
        Element::Line { other } | Element::Arc { other, .. } => distance(other),
    };
    let ends = |d: f64| -> Option<([f64; 2], [f64; 2])> {
        let a = first.at_distance(corner, true, d)?;
        let b = second.at_distance(corner, false, d)?;
        (first.holds(corner, a, true) && second.holds(corner, b, false)).then_some((a, b))
    };
    let leg = match size {
        Chamfer::Leg(d) => d.abs(),
        Chamfer::Length(l) => {
            let l = l.abs();
            let length = |d: f64| ends(d).map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1]));
            // The longest leg both elements allow (within a diameter of an arc).
            let mut most = size_of(&first).min(size_of(&second));
            for e in [&first, &second] {
                if let Element::Arc { centre, .. } = *e {
                    most = most.min(2.0 * distance(centre));
                }
            }
            match length(most) {
                Some(m) if m + 1e-9 >= l => {}
                _ => {
                    return Err(CornerError::TooLarge {
                        needed: l,
                        available: length(most).unwrap_or(0.0),
                    });
                }
            }
            let (mut lo, mut hi) = (0.0, most);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                match length(mid) {
                    Some(m) if m < l => lo = mid,
                    _ => hi = mid,
                }
            }
            0.5 * (lo + hi)
        }
    };
    match ends(leg) {
        Some((from, to)) => Ok(Inserted {
            from,
            to,
            arc: None,
        }),
        None => Err(CornerError::TooLarge {
            needed: leg,
            available: size_of(&first).min(size_of(&second)),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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

    /// Chamfers worked by hand. Two lines at a right angle, (0,0)→(10,0)→(10,10):
    /// CHR=2 ends 2 from the corner on each, (8,0) and (10,2); CHF=2 is the
    /// chamfer's own length: legs 2/(2·cos 45°) = √2, ends (10-√2, 0) and
    /// (10, √2). A line into an arc: (0,0)→(10,0), then counter-clockwise
    /// about (10,10) radius 10 leaving (10,0) along +X is tangent (no
    /// corner); clockwise about (10,-10) it leaves along +X too; about
    /// (20,0) counter-clockwise it leaves along -Y: CHR=2 puts the second
    /// end on that circle 2 from the corner: the chord 2 subtends
    /// 2·asin(0.1) about (20,0), turned clockwise back from the corner's
    /// angle π (travel is counter-clockwise, leaving downwards):
    /// (20 - 10·cos θ, -10·sin θ), θ = 2·asin(0.1).
    #[test]
    fn chamfers_between_lines_and_arcs() {
        let close =
            |a: [f64; 2], b: [f64; 2]| (a[0] - b[0]).abs() < 1e-9 && (a[1] - b[1]).abs() < 1e-9;
        let first = Element::Line { other: [0.0, 0.0] };
        let second = Element::Line {
            other: [10.0, 10.0],
        };
        let k = chamfer_elements(first, [10.0, 0.0], second, Chamfer::Leg(2.0)).unwrap();
        assert!(
            close(k.from, [8.0, 0.0]) && close(k.to, [10.0, 2.0]),
            "{k:?}"
        );
        let h = 2f64.sqrt();
        let k = chamfer_elements(first, [10.0, 0.0], second, Chamfer::Length(2.0)).unwrap();
        assert!(
            close(k.from, [10.0 - h, 0.0]) && close(k.to, [10.0, h]),
            "{k:?}"
        );
        let arc = Element::Arc {
            centre: [20.0, 0.0],
            clockwise: false,
            other: [30.0, 0.0],
        };
        let k = chamfer_elements(first, [10.0, 0.0], arc, Chamfer::Leg(2.0)).unwrap();
        let theta = 2.0 * 0.1f64.asin();
        assert!(close(k.from, [8.0, 0.0]), "{k:?}");
        assert!(
            close(k.to, [20.0 - 10.0 * theta.cos(), -10.0 * theta.sin()]),
            "{k:?}"
        );
        // The chamfer's length: CHF gives back the leg.
        let l = (k.from[0] - k.to[0]).hypot(k.from[1] - k.to[1]);
        let back = chamfer_elements(first, [10.0, 0.0], arc, Chamfer::Length(l)).unwrap();
        assert!(close(back.to, k.to), "{back:?}");
        assert!(matches!(
            chamfer_elements(first, [10.0, 0.0], second, Chamfer::Leg(11.0)),
            Err(CornerError::TooLarge { .. })
        ));
        let straight = Element::Line { other: [20.0, 0.0] };
        assert_eq!(
            chamfer_elements(first, [10.0, 0.0], straight, Chamfer::Leg(1.0)),
            Err(CornerError::Straight)
        );
    }
}
