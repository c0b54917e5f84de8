//! Bundled sample parts: deterministic generators of programs and inspection plans.
pub mod flank;
pub mod saddle;

/// A plan CSV (`id,x,y,z,i,j,k`, ids from 1, six decimals) of (point, normal) pairs.
pub fn plan_csv(points: &[([f64; 3], [f64; 3])]) -> String {
    use std::fmt::Write as _;
    let mut plan = String::from("id,x,y,z,i,j,k\n");
    for (id, (p, n)) in points.iter().enumerate() {
        let _ = writeln!(
            plan,
            "{},{:.6},{:.6},{:.6},{:.6},{:.6},{:.6}",
            id + 1,
            p[0],
            p[1],
            p[2],
            n[0],
            n[1],
            n[2]
        );
    }
    plan
}
