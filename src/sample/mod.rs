//! Bundled sample parts: deterministic generators of programs and inspection plans.
pub(crate) mod flank;
pub(crate) mod saddle;

/// How a generated program's header comment ends, naming the machine it is
/// written for (its joints are that machine's): `… FOR MACHINE REF-TRT)`.
pub fn machine_suffix(machine: &str) -> String {
    format!(" FOR MACHINE {})", machine.to_uppercase())
}

/// The machine a program's header names ([`machine_suffix`]), as written
/// (upper case): searched in the comment lines at its head.
pub fn header_machine(head: &str) -> Option<String> {
    head.lines()
        .map(str::trim)
        .take_while(|l| l.starts_with(['(', '%', 'O', 'o', ';']) || l.is_empty())
        .find_map(|l| {
            let name = l.strip_suffix(')')?.rsplit_once(" FOR MACHINE ")?.1;
            (!name.is_empty() && !name.contains(['(', ')', ' '])).then(|| name.to_string())
        })
}

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

/// The linear words (`X… Y… Z…`, 4 decimals) of `to` that differ from `from` as
/// written: the words of a plunge or a retract.
pub(crate) fn moved_words(from: &crate::axes::Axes, to: &crate::axes::Axes) -> String {
    use crate::axes::{Axis, AxisSet};
    let xyz = AxisSet::of(&[Axis::X, Axis::Y, Axis::Z]);
    let (before, after) = (from.words(xyz, 4), to.words(xyz, 4));
    before
        .split(' ')
        .zip(after.split(' '))
        .filter(|(b, a)| b != a)
        .map(|(_, a)| a)
        .collect::<Vec<_>>()
        .join(" ")
}

/// The joints `by` mm above `j` along the tool axis, and their tool tip (part
/// coordinates). On a table-tilting machine the tool axis is machine Z and only Z
/// moves.
pub(crate) fn lifted(
    kinematics: &crate::kinematics::Kinematics,
    j: &crate::axes::Axes,
    by: f64,
) -> (crate::axes::Axes, [f64; 3]) {
    let chain = &kinematics.chain;
    let head = chain.tool_side().iter().any(|a| a.is_rotary());
    if !head && chain.tool_axis() == [0.0, 0.0, 1.0] {
        let up = crate::axes::Axes { z: j.z + by, ..*j };
        return (up, kinematics.nominal_tip(&up));
    }
    let axis = kinematics.nominal_tool_axis(j);
    let tip = kinematics.nominal_tip(j);
    let up_tip: [f64; 3] = std::array::from_fn(|k| tip[k] + by * axis[k]);
    (kinematics.nominal_joints_for_tip(up_tip, j), up_tip)
}
