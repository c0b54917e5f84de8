//! The tool path: sampling, plan matching and point context.
use std::path::Path;
use volcomp::gcode::InterpretOptions;
use volcomp::kinematics::{Geometry, Kinematics};
use volcomp::toolpath::{PlanMatcher, WalkOptions, walk_program};

fn read_plan(path: &Path) -> Vec<(String, [f64; 3], [f64; 3])> {
    let text = std::fs::read_to_string(path).unwrap();
    text.lines()
        .skip(1)
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v: Vec<f64> = f[1..7].iter().map(|s| s.parse().unwrap()).collect();
            (f[0].to_string(), [v[0], v[1], v[2]], [v[3], v[4], v[5]])
        })
        .collect()
}

/// The blind examples' plans are contact points of path points of their programs
/// (an independent implementation): every one must be matched at ~0 distance.
#[test]
fn blind_example_plan_points_are_contact_points_of_our_path() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/blind/01-backlash");
    let plan = read_plan(&dir.join("plan.csv"));
    let pts: Vec<([f64; 3], [f64; 3])> = plan.iter().map(|(_, p, n)| (*p, *n)).collect();
    let kin = Kinematics::new(Geometry::default(), 100.0);
    let mut matcher = PlanMatcher::new(&pts, 3.0, 0.5);
    let program = volcomp::gcode::Program::open(
        &dir.join("program.nc"),
        volcomp::gcode::ProgramSetup::default(),
    )
    .unwrap();
    let summary = walk_program(
        program,
        &kin,
        InterpretOptions::default(),
        WalkOptions {
            step_mm: 0.5,
            rapid_mm_per_min: 30000.0,
        },
        |p| matcher.offer(p),
    )
    .unwrap();
    assert!(summary.motion_blocks > 3000);
    let matches = matcher.into_matches();
    let worst = matches
        .iter()
        .map(|m| m.map_or(f64::INFINITY, |m| m.distance_mm))
        .fold(0.0f64, f64::max);
    let ends = matches
        .iter()
        .filter(|m| m.is_some_and(|m| m.point.block_end))
        .count();
    eprintln!("worst {worst:e} block ends {ends}");
    assert!(worst < 1e-3, "worst contact distance {worst} mm");
}
