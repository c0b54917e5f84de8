//! Plans and measurements in work coordinates (the program's coordinate
//! system, where a CMM report aligned to the part datum usually is): a rigid
//! placement `r = Rz(θ)·w + t` of the work frame in part coordinates.
use super::{MeasuredPoint, Measurement, Plan, PlanPoint};

/// Where a work frame lies in part coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WorkFrame {
    /// The work origin in part coordinates, mm.
    pub translation: [f64; 3],
    /// Rotation of the work frame about Z (G10 L2 R), degrees counter-clockwise.
    pub rotation_deg: f64,
}

impl WorkFrame {
    fn rotate(&self, v: [f64; 3], sign: f64) -> [f64; 3] {
        if self.rotation_deg == 0.0 {
            return v;
        }
        let (s, c) = (sign * self.rotation_deg).to_radians().sin_cos();
        [c * v[0] - s * v[1], s * v[0] + c * v[1], v[2]]
    }

    /// A point in work coordinates → part coordinates.
    pub fn to_part_point(&self, w: [f64; 3]) -> [f64; 3] {
        let r = self.rotate(w, 1.0);
        [
            r[0] + self.translation[0],
            r[1] + self.translation[1],
            r[2] + self.translation[2],
        ]
    }

    /// A direction in work coordinates → part coordinates.
    pub fn to_part_vector(&self, v: [f64; 3]) -> [f64; 3] {
        self.rotate(v, 1.0)
    }

    /// A point in part coordinates → work coordinates.
    pub fn to_work_point(&self, r: [f64; 3]) -> [f64; 3] {
        let d = [
            r[0] - self.translation[0],
            r[1] - self.translation[1],
            r[2] - self.translation[2],
        ];
        self.rotate(d, -1.0)
    }

    /// A direction in part coordinates → work coordinates.
    pub fn to_work_vector(&self, v: [f64; 3]) -> [f64; 3] {
        self.rotate(v, -1.0)
    }

    fn map_point(&self, p: &PlanPoint, to_part: bool) -> PlanPoint {
        PlanPoint {
            id: p.id.clone(),
            point: if to_part {
                self.to_part_point(p.point)
            } else {
                self.to_work_point(p.point)
            },
            normal: if to_part {
                self.to_part_vector(p.normal)
            } else {
                self.to_work_vector(p.normal)
            },
        }
    }

    /// A plan in work coordinates → part coordinates.
    pub fn plan_to_part(&self, plan: &Plan) -> Plan {
        Plan {
            points: plan
                .points
                .iter()
                .map(|p| self.map_point(p, true))
                .collect(),
        }
    }

    /// A measurement in work coordinates → part coordinates.
    pub fn measurement_to_part(&self, m: &Measurement) -> Measurement {
        self.map_measurement(m, true)
    }

    /// A measurement in part coordinates → work coordinates.
    pub fn measurement_to_work(&self, m: &Measurement) -> Measurement {
        self.map_measurement(m, false)
    }

    fn map_measurement(&self, m: &Measurement, to_part: bool) -> Measurement {
        Measurement {
            points: m
                .points
                .iter()
                .map(|p| MeasuredPoint {
                    plan: self.map_point(&p.plan, to_part),
                    measured: if to_part {
                        self.to_part_point(p.measured)
                    } else {
                        self.to_work_point(p.measured)
                    },
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn work_and_part_are_inverse() {
        let f = WorkFrame {
            translation: [10.0, -5.0, 2.0],
            rotation_deg: 30.0,
        };
        let w = [1.0, 2.0, 3.0];
        let r = f.to_part_point(w);
        let back = f.to_work_point(r);
        for k in 0..3 {
            assert!((back[k] - w[k]).abs() < 1e-12);
        }
        let n = f.to_part_vector([1.0, 0.0, 0.0]);
        assert!((n[0] - 30f64.to_radians().cos()).abs() < 1e-12);
    }
}
