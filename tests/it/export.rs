//! Controller files out (`volcomp export`): a LinuxCNC COMP_FILE read back as
//! LinuxCNC reads and interpolates it reproduces the fitted positioning curves
//! (forward and reverse) within the stated tolerance; the trt pivot parameters;
//! the fitted tables on a grid.
use crate::support::{assert_success, root, volcomp};
use std::path::{Path, PathBuf};
use volcomp::axes::Axis;
use volcomp::export::Positioning;
use volcomp::machine::ErrorTable;
use volcomp::machine::{ErrorModel, Machine, ModelOptions};

/// ref-trt with its X table replaced by the import of tests/data/laser/x-long.csv
/// (EXX and a REVERSAL of 5 to 7 µm); the machine file's path.
pub(crate) fn machine_with_reversal(dir: &Path) -> PathBuf {
    let table = dir.join("x-laser.csv");
    let out = volcomp()
        .arg("import-laser")
        .arg(root().join("tests/data/laser/x-long.csv"))
        .args(["--axis", "X", "-o"])
        .arg(&table)
        .output()
        .unwrap();
    assert_success(&out);
    let text = std::fs::read_to_string(root().join("machines/ref-trt.toml"))
        .unwrap()
        .replace("\"ref-trt/x.csv\"", &format!("\"{}\"", table.display()))
        .replace(
            "\"ref-trt/",
            &format!("\"{}/machines/ref-trt/", root().display()),
        );
    let path = dir.join("m.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// A COMP_FILE as LinuxCNC's `usrmotLoadComp` reads it: `%lf %lf %lf` a line,
/// stopping at the first line that is not three numbers; type 0 turns actual
/// positions into trims (nominal − actual). (nominal, forward trim, reverse trim).
pub(crate) fn linuxcnc_load(text: &str, comp_type: u8) -> Vec<(f64, f64, f64)> {
    let mut out = Vec::new();
    for line in text.lines() {
        let v: Vec<f64> = line
            .split_whitespace()
            .take(3)
            .map_while(|w| w.parse().ok())
            .collect();
        if v.len() != 3 {
            break;
        }
        out.push(if comp_type == 0 {
            (v[0], v[0] - v[1], v[0] - v[2])
        } else {
            (v[0], v[1], v[2])
        });
    }
    out
}

/// `compute_screw_comp`: the trim at commanded `p` moving up (or down), linear
/// between entries, the end entries' trims held beyond them.
pub(crate) fn linuxcnc_trim(table: &[(f64, f64, f64)], p: f64, up: bool) -> f64 {
    let pick = |e: &(f64, f64, f64)| if up { e.1 } else { e.2 };
    if p < table[0].0 {
        return pick(&table[0]);
    }
    let k = table.iter().rposition(|e| e.0 <= p).unwrap();
    if k + 1 == table.len() {
        return pick(&table[k]);
    }
    let t = (p - table[k].0) / (table[k + 1].0 - table[k].0);
    pick(&table[k]) + t * (pick(&table[k + 1]) - pick(&table[k]))
}

#[test]
fn a_comp_file_read_back_as_linuxcnc_does_reproduces_the_fitted_curves() {
    let dir = tempfile::tempdir().unwrap();
    let machine_path = machine_with_reversal(dir.path());
    let machine = Machine::load(&machine_path).unwrap();
    let model = ErrorModel::from_machine(&machine, &ModelOptions::default()).unwrap();
    let tol_um = 0.1;
    for comp_type in [0u8, 1] {
        let out_dir = dir.path().join(format!("lcnc{comp_type}"));
        let out = volcomp()
            .args(["export", "linuxcnc"])
            .arg(&machine_path)
            .arg("-o")
            .arg(&out_dir)
            .args(["--comp-type", &comp_type.to_string()])
            .output()
            .unwrap();
        assert_success(&out);
        for axis in [Axis::X, Axis::Y, Axis::Z] {
            let text =
                std::fs::read_to_string(out_dir.join(format!("{}.comp", axis.lower()))).unwrap();
            // Nothing before the triplets: the first line is three numbers.
            let first: Vec<&str> = text.lines().next().unwrap().split_whitespace().collect();
            assert_eq!(first.len(), 3, "{text}");
            assert!(first.iter().all(|w| w.parse::<f64>().is_ok()), "{text}");
            let table = linuxcnc_load(&text, comp_type);
            assert!(table.len() <= 256 && table.len() >= 8, "{}", table.len());
            assert!(table.windows(2).all(|w| w[0].0 < w[1].0), "nominals ascend");
            // The provenance follows the triplets.
            assert!(text.contains("# volcomp export linuxcnc: machine ref-trt"));
            let pos = Positioning::of(&machine, &model, axis).unwrap();
            assert_eq!(pos.has_reversal(), axis == Axis::X);
            let [lo, hi] = pos.range;
            assert_eq!((table[0].0, table[table.len() - 1].0), (lo, hi));
            let mut worst: f64 = 0.0;
            for k in 0..=4000 {
                let p = lo + (hi - lo) * k as f64 / 4000.0;
                for up in [true, false] {
                    let trim_um = linuxcnc_trim(&table, p, up) * 1e3;
                    let fitted = if up { pos.forward(p) } else { pos.reverse(p) };
                    worst = worst.max((trim_um + fitted).abs());
                    // The joint lands where it was commanded: motor at p + trim,
                    // the machine there off by its error for that approach.
                    let motor = p + trim_um * 1e-3;
                    if (lo..=hi).contains(&motor) {
                        let err = if up {
                            pos.forward(motor)
                        } else {
                            pos.reverse(motor)
                        };
                        let landed_um = (motor - p) * 1e3 + err;
                        assert!(
                            landed_um.abs() < tol_um + 0.02,
                            "{axis:?} {p} up={up}: {landed_um} µm"
                        );
                    }
                }
            }
            assert!(
                worst <= tol_um + 1e-3,
                "{axis:?} type {comp_type}: {worst} µm"
            );
        }
        // X moving up and down differ by the reversal (5 to 7 µm).
        let x = linuxcnc_load(
            &std::fs::read_to_string(out_dir.join("x.comp")).unwrap(),
            comp_type,
        );
        let gap_um = (linuxcnc_trim(&x, 0.0, false) - linuxcnc_trim(&x, 0.0, true)) * 1e3;
        assert!((gap_um - 6.0).abs() < 1.0, "{gap_um}");
        let readme = std::fs::read_to_string(out_dir.join("README.txt")).unwrap();
        assert!(readme.contains("[JOINT_0]\nCOMP_FILE = "), "{readme}");
        assert!(readme.contains(&format!("COMP_FILE_TYPE = {comp_type}")));
        assert!(readme.contains("A: no COMP_FILE (rotary"), "{readme}");
    }
}

#[test]
fn the_trt_pivot_parameters_carry_the_location_offsets() {
    let dir = tempfile::tempdir().unwrap();
    let out = volcomp()
        .args(["export", "linuxcnc"])
        .arg(root().join("machines/ref-trt.toml"))
        .arg("-o")
        .arg(dir.path())
        .output()
        .unwrap();
    assert_success(&out);
    let ini = std::fs::read_to_string(dir.path().join("kinematics.ini")).unwrap();
    // ref-trt: pivots at 0; EX0C 5.6, EY0C 7.9, EY0A 12.7, EZ0A −3.0 µm.
    for line in [
        "HALCMD = setp xyzac-trt-kins.x-rot-point 0.0056\n",
        "HALCMD = setp xyzac-trt-kins.y-rot-point 0.0079\n",
        "HALCMD = setp xyzac-trt-kins.z-rot-point 0\n",
        "HALCMD = setp xyzac-trt-kins.y-offset 0.0048\n",
        "HALCMD = setp xyzac-trt-kins.z-offset -0.003\n",
    ] {
        assert!(ini.contains(line), "{line}{ini}");
    }
    assert!(ini.contains("EB0A = 22.7"), "{ini}");
    // No REVERSAL in ref-trt's tables: both directions alike.
    let x = std::fs::read_to_string(dir.path().join("x.comp")).unwrap();
    let t = linuxcnc_load(&x, 0);
    assert!(t.iter().all(|e| e.1 == e.2));
}

#[test]
fn fitted_tables_come_out_on_the_chosen_grid_and_read_back() {
    let dir = tempfile::tempdir().unwrap();
    let out = volcomp()
        .args(["export", "tables"])
        .arg(root().join("machines/ref-trt.toml"))
        .arg("-o")
        .arg(dir.path())
        .args(["--step", "5", "--step-deg", "7"])
        .output()
        .unwrap();
    assert_success(&out);
    let (machine, model) = crate::compensate::ref_trt();
    let x = ErrorTable::read(&dir.path().join("x.csv"), None).unwrap();
    assert_eq!(x.positions.len(), 81);
    assert_eq!(x.columns.len(), 6);
    for c in &x.columns {
        let curve = model.curve(&c.name).unwrap();
        for (p, v) in x.positions.iter().zip(&c.values) {
            assert!((curve.value_at(*p) - v).abs() <= 5e-5, "{} at {p}", c.name);
        }
    }
    // A: -110..110 every 7 degrees, and the end.
    let a = ErrorTable::read(&dir.path().join("a.csv"), None).unwrap();
    assert_eq!(a.positions.first(), Some(&-110.0));
    assert_eq!(a.positions.last(), Some(&110.0));
    assert_eq!(a.positions.len(), 33);
    assert!(machine.table(Axis::C).is_some());
    assert!(dir.path().join("c.csv").exists());
}

/// A tolerance the lines cannot meet: below LinuxCNC's 256 lines the warning
/// says to raise --max-lines; at 256 it says the limit is reached and which
/// tolerance the lines do meet (not "raise --max-lines").
#[test]
fn an_unmet_tolerance_says_which_limit_and_what_to_do() {
    let dir = tempfile::tempdir().unwrap();
    let run = |max_lines: &str, out: &str| {
        let out = volcomp()
            .args(["export", "linuxcnc"])
            .arg(root().join("machines/ref-trt.toml"))
            .arg("-o")
            .arg(dir.path().join(out))
            .args(["--max-lines", max_lines, "--tol-um", "0.000001"])
            .output()
            .unwrap();
        assert_success(&out);
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    let few = run("8", "a");
    assert!(
        few.contains("raise --max-lines (now 8, LinuxCNC takes up to 256) or --tol-um"),
        "{few}"
    );
    let most = run("256", "b");
    assert!(
        most.contains("--max-lines is at LinuxCNC's limit of 256 lines a joint: give --tol-um "),
        "{most}"
    );
    assert!(!most.contains("raise --max-lines"), "{most}");
}

/// The physical joints LinuxCNC drives for commanded `joints`: each linear
/// joint with a COMP_FILE moved by its trim for the direction it moved in
/// (`compute_screw_comp`), `None` where that direction is not known yet.
fn linuxcnc_applied(
    joints: &volcomp::axes::Axes,
    approach: &volcomp::machine::Approach,
    comp: &[(Axis, Vec<(f64, f64, f64)>)],
) -> Option<volcomp::axes::Axes> {
    use volcomp::machine::Direction;
    let mut out = *joints;
    for (axis, table) in comp {
        let up = match approach.get(*axis) {
            Direction::Positive => true,
            Direction::Negative => false,
            // No reversal: both directions alike.
            Direction::Unknown if table.iter().all(|e| e.1 == e.2) => true,
            Direction::Unknown => return None,
        };
        let p = joints.get(*axis);
        out.set(*axis, p + linuxcnc_trim(table, p, up));
    }
    Some(out)
}

/// Block ends of `text` compensated on `rig` (6 decimals), walked on
/// `rig`'s own kinematics (what the controller inverts with): (line,
/// joints, approach, tool).
fn compensated_block_ends(
    rig: &crate::compensate::Rig,
    text: &str,
) -> Vec<(
    usize,
    volcomp::axes::Axes,
    volcomp::machine::Approach,
    volcomp::gcode::ToolInUse,
)> {
    use volcomp::compensate::{CompensateOptions, compensate};
    use volcomp::gcode::Frame;
    let (machine, model) = rig;
    let mut options = CompensateOptions {
        tolerance_um: 0.5,
        interpret: crate::compensate::interpret_options_on(machine, Frame::Joint),
        limits: Some(machine.limits),
        orientation: true,
        ..CompensateOptions::default()
    };
    options.rewrite.min_decimals_mm = 6;
    let mut out = Vec::new();
    compensate(
        crate::compensate::program_on(machine, text, "program.nc"),
        &mut out,
        model,
        &options,
        |_| {},
    )
    .expect("compensates");
    let compensated = String::from_utf8(out).unwrap();
    let mut ends = Vec::new();
    // Each axis's direction of motion, followed along the path.
    let mut directions = model.direction_tracker();
    volcomp::toolpath::walk_program(
        crate::compensate::program_on(machine, &compensated, "compensated.nc"),
        model.kinematics(),
        crate::compensate::interpret_options_on(machine, Frame::Joint),
        volcomp::toolpath::WalkOptions {
            step_mm: 0.5,
            rapid_mm_per_min: machine.rapid_mm_per_min,
        },
        |p| {
            directions.update(&p.joints);
            if p.block_end && p.cutting {
                ends.push((p.line, p.joints.axes(), directions.approach(), p.tool));
            }
        },
    )
    .expect("walks");
    ends
}

/// Issue 37 item 3: `--residual-machine` on ref-trt with a laser X table
/// (REVERSAL 5 to 7 µm). The tool-tip-control saddle compensated with the
/// residual machine and run on a LinuxCNC that applies the export (its
/// kinematics with the corrected pivots inverts the program, each COMP_FILE
/// moves its joint by the trim for the direction it last moved in) puts the
/// physical tip (the full machine's model at the joints LinuxCNC drives) on
/// the programmed path, as the program compensated with the full machine
/// alone does on a LinuxCNC without them: at every block end (take-up pieces
/// and splits differ, so the two are compared through the programmed path),
/// within the COMP_FILEs' interpolation tolerance (their linear interpolation
/// departs from the fitted curves by up to 0.1 µm per axis between their
/// lines: √3 · 0.1 µm over three axes) plus 5 nm of solver, rounding and
/// path sampling. The full machine on top of the export corrects twice
/// (asserted: micrometres off).
#[test]
fn the_residual_machine_on_linuxcnc_equals_the_full_machine_alone() {
    let dir = tempfile::tempdir().unwrap();
    let machine_path = machine_with_reversal(dir.path());
    let out_dir = dir.path().join("lcnc");
    let residual_path = out_dir.join("residual.toml");
    let out = volcomp()
        .args(["export", "linuxcnc"])
        .arg(&machine_path)
        .arg("-o")
        .arg(&out_dir)
        .arg("--residual-machine")
        .arg(&residual_path)
        .output()
        .unwrap();
    assert_success(&out);
    let text = std::fs::read_to_string(&residual_path).unwrap();
    for line in [
        "#   X: EXX and REVERSAL -> x.comp; left at the table's positions at most ",
        "#   [location] EX0C 5.6, EY0C 7.9, EY0A 12.7, EZ0A -3 µm -> kinematics.ini's pivots",
        "EX0C = 0.0  # was 5.6: in kinematics.ini's pivots",
        "y_offset = 0.0048  # was 0: kinematics.ini",
        "x = \"residual.x.csv\"",
    ] {
        assert!(text.contains(line), "{line}\n{text}");
    }
    let full = Machine::load(&machine_path).unwrap();
    let full_model = ErrorModel::from_machine(&full, &ModelOptions::default()).unwrap();
    let residual = Machine::load(&residual_path).unwrap();
    let residual_model = ErrorModel::from_machine(&residual, &ModelOptions::default()).unwrap();
    // The residual's location offsets are its chain's points: A and C moved.
    let moved = residual.chain.axis(Axis::C).point;
    assert!((moved[0] - 0.0056).abs() < 1e-12 && (moved[1] - 0.0079).abs() < 1e-12);
    let comp: Vec<(Axis, Vec<(f64, f64, f64)>)> = [Axis::X, Axis::Y, Axis::Z]
        .into_iter()
        .map(|a| {
            let t = std::fs::read_to_string(out_dir.join(format!("{}.comp", a.lower()))).unwrap();
            (a, linuxcnc_load(&t, 0))
        })
        .collect();
    let program = crate::compensate::read("samples/saddle-tcp.nc");
    let full_rig = (full, full_model);
    let residual_rig = (residual, residual_model);
    // The programmed path, sampled every 10 µm (its chords depart from the
    // saddle's curves by < 1e-3 µm).
    let nominal = crate::compensate::NominalPath::of_program_on(
        &full_rig,
        &program,
        volcomp::gcode::Frame::Joint,
        0.01,
    );
    let tip = |joints: &volcomp::axes::Axes,
               approach: &volcomp::machine::Approach,
               tool: &volcomp::gcode::ToolInUse| {
        let (_, model) = &full_rig;
        let errors = model.errors_toward(joints, approach).expect("inside");
        volcomp::machine::kinematics_with(model, tool)
            .actual_tip_and_axis(joints, &errors)
            .tip
    };
    // Where the physical tip lands at every block end (µm from the programmed
    // path): the program compensated on `rig`, run on a LinuxCNC that
    // applies the export (`comp`) or not.
    let landed = |rig: &crate::compensate::Rig, with_export: bool| {
        let (mut worst, mut n) = (0.0f64, 0usize);
        for (_, joints, approach, tool) in compensated_block_ends(rig, &program) {
            let physical = if with_export {
                match linuxcnc_applied(&joints, &approach, &comp) {
                    Some(p) => p,
                    None => continue,
                }
            } else {
                joints
            };
            let d = nominal.distance(tip(&physical, &approach, &tool)) * 1e3;
            worst = worst.max(d);
            n += 1;
        }
        (worst, n)
    };
    let (alone_um, alone_n) = landed(&full_rig, false);
    let (residual_um, residual_n) = landed(&residual_rig, true);
    let (twice_um, _) = landed(&full_rig, true);
    eprintln!(
        "saddle-tcp block ends, physical tip from the programmed path: the full machine alone {alone_um:.4} µm ({alone_n} ends); \
the residual machine on LinuxCNC with the export {residual_um:.4} µm ({residual_n} ends); the full machine on that LinuxCNC {twice_um:.2} µm"
    );
    assert!(
        alone_n > 1000 && residual_n > 1000,
        "{alone_n} {residual_n}"
    );
    assert!(alone_um <= 0.005, "{alone_um} µm");
    assert!(residual_um <= 3f64.sqrt() * 0.1 + 0.005, "{residual_um} µm");
    assert!(twice_um > 2.0, "{twice_um} µm");
}

/// A LinuxCNC-style round trip of one axis: X targets over the travel, each
/// approached from below and from above, compensated with the residual
/// machine's X curve (solved as `compensate` does for one axis), driven by
/// LinuxCNC with x.comp (motor = commanded + trim for that direction), land
/// where the full machine's curve puts them: the commanded target, within the
/// COMP_FILE's tolerance.
#[test]
fn one_axis_round_trips_through_the_comp_file_and_the_residual_machine() {
    let dir = tempfile::tempdir().unwrap();
    let machine_path = machine_with_reversal(dir.path());
    let out_dir = dir.path().join("lcnc");
    let residual_path = out_dir.join("r.toml");
    let out = volcomp()
        .args(["export", "linuxcnc"])
        .arg(&machine_path)
        .arg("-o")
        .arg(&out_dir)
        .args(["--comp-type", "1", "--tol-um", "0.02", "--residual-machine"])
        .arg(&residual_path)
        .output()
        .unwrap();
    assert_success(&out);
    let full = Machine::load(&machine_path).unwrap();
    let full_model = ErrorModel::from_machine(&full, &ModelOptions::default()).unwrap();
    let residual = Machine::load(&residual_path).unwrap();
    let residual_model = ErrorModel::from_machine(&residual, &ModelOptions::default()).unwrap();
    let truth = Positioning::of(&full, &full_model, Axis::X).unwrap();
    let left = Positioning::of(&residual, &residual_model, Axis::X).unwrap();
    let x = linuxcnc_load(&std::fs::read_to_string(out_dir.join("x.comp")).unwrap(), 1);
    let [lo, hi] = truth.range;
    let mut worst: f64 = 0.0;
    let mut left_worst: f64 = 0.0;
    for k in 0..=400 {
        let target = lo + 1.0 + (hi - lo - 2.0) * k as f64 / 400.0;
        for up in [true, false] {
            let error = |pos: &Positioning<'_>, p: f64| {
                if up { pos.forward(p) } else { pos.reverse(p) }
            };
            // Commanded so that the residual model's actual is the target.
            let mut cmd = target;
            for _ in 0..20 {
                cmd = target - error(&left, cmd) * 1e-3;
            }
            let motor = cmd + linuxcnc_trim(&x, cmd, up);
            let actual = motor + error(&truth, motor) * 1e-3;
            worst = worst.max((actual - target).abs() * 1e3);
            left_worst = left_worst.max(error(&left, target).abs());
        }
    }
    eprintln!(
        "X round trip through x.comp (type 1, --tol-um 0.02) and the residual machine: within {worst:.4} µm of the target; the residual curve at most {left_worst:.4} µm"
    );
    assert!(worst <= 0.02 + 0.002, "{worst} µm");
    // Without the residual machine's share the full curve would be applied twice.
    assert!(left_worst < 0.02, "{left_worst}");
}

/// The uncertainty travels into the exports (issue 37): from a laser import
/// with `u_EXX` (the runs' scatter), `export tables` writes `u_EXX` beside
/// `EXX`, equal to the fitted curve's standard uncertainty at each grid
/// position (to its 4 written decimals), and `export linuxcnc` writes after
/// the triplets one `# u NOMINAL µm` line per triplet with the same values,
/// which LinuxCNC's reader never reaches (it stops at the first line that is
/// not three numbers). Tables without `u_` columns get none (the bundled
/// ref-trt in `fitted_tables_come_out_on_the_chosen_grid_and_read_back`).
#[test]
fn the_uncertainty_of_a_laser_table_reaches_both_exports() {
    let dir = tempfile::tempdir().unwrap();
    let machine_path = machine_with_reversal(dir.path());
    let machine = Machine::load(&machine_path).unwrap();
    let model = ErrorModel::from_machine(&machine, &ModelOptions::default()).unwrap();
    let curve = model.curve("EXX").unwrap();
    assert!(!curve.uncertainty().is_empty(), "the import gives u_EXX");

    let tables = dir.path().join("tables");
    let out = volcomp()
        .args(["export", "tables"])
        .arg(&machine_path)
        .arg("-o")
        .arg(&tables)
        .args(["--step", "10"])
        .output()
        .unwrap();
    assert_success(&out);
    let x = ErrorTable::read(&tables.join("x.csv"), None).unwrap();
    let exx = x.column("EXX").unwrap();
    let u = exx.uncertainty.as_ref().expect("u_EXX written beside EXX");
    assert_eq!(u.len(), x.positions.len());
    for (p, u) in x.positions.iter().zip(u) {
        let want = curve.uncertainty_at(*p).unwrap();
        assert!(want > 0.0 && want.is_finite(), "{p}: {want}");
        assert!((u - want).abs() <= 5e-5 + 1e-12, "{p}: {u} vs {want}");
    }

    let lcnc = dir.path().join("lcnc");
    let out = volcomp()
        .args(["export", "linuxcnc"])
        .arg(&machine_path)
        .arg("-o")
        .arg(&lcnc)
        .output()
        .unwrap();
    assert_success(&out);
    let text = std::fs::read_to_string(lcnc.join("x.comp")).unwrap();
    let triplets = linuxcnc_load(&text, 0);
    assert!(
        text.contains(
            "# Standard uncertainty of EXX (the fitted curve's, from the table's u_ column)"
        ),
        "{text}"
    );
    let lines: Vec<(f64, f64)> = text
        .lines()
        .filter_map(|l| l.strip_prefix("# u "))
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|w| w.parse().unwrap()).collect();
            (v[0], v[1])
        })
        .collect();
    assert_eq!(lines.len(), triplets.len(), "one # u line per triplet");
    for ((nominal, u), t) in lines.iter().zip(&triplets) {
        assert_eq!(*nominal, t.0);
        let want = curve.uncertainty_at(*nominal).unwrap();
        assert!((u - want).abs() <= 5e-5 + 1e-12, "{nominal}: {u} vs {want}");
    }
}
