//! Programs with tool changes: the tool table, the tool in the spindle per
//! block, and compensation with each tool's own length.
use crate::compensate::ref_trt;
use crate::support::{assert_success, root, volcomp};
use std::path::{Path, PathBuf};
use volcomp::gcode::{ErrorKind, Program, ProgramSetup, ToolTable, WarningKind};

const TABLE: &str = "T1 P1 Z40.0 D10.0 ;roughing end mill\nT2 P2 Z120.0 D6.0 ;ball-end finisher\n";
const PREAMBLE: &str = "%\nG21 G90 G94\n";

/// A five-axis section: a rapid to its start, then feed moves with A and C
/// moving (so the tool length matters), around `x0`.
fn section(x0: f64, a0: f64) -> String {
    let mut s = format!("G0 X{x0:.4} Y-20.0000 Z5.0000 A{a0:.4} C0.0000\n");
    for i in 0..12 {
        let t = i as f64;
        s.push_str(&format!(
            "G1 X{:.4} Y{:.4} Z{:.4} A{:.4} C{:.4} F800\n",
            x0 + 4.0 * t,
            -20.0 + 3.5 * t,
            -2.0 - 0.25 * t,
            a0 + 2.5 * t,
            15.0 * t
        ));
    }
    s
}

/// Write the fitted reference model and machine files whose `[tool]` is
/// 100 mm (the reference), 40 mm (T1) and 120 mm (T2) into `dir`.
fn setup(dir: &Path) -> (PathBuf, [PathBuf; 3]) {
    let (machine, model) = ref_trt();
    let fit = dir.join("fit.json");
    let file = model.to_model_file(machine).expect("model file");
    std::fs::write(&fit, serde_json::to_string(&file).unwrap()).unwrap();
    let tables = dir.join("ref-trt");
    std::fs::create_dir(&tables).unwrap();
    for axis in ["x", "y", "z", "a", "c"] {
        std::fs::copy(
            root().join(format!("machines/ref-trt/{axis}.csv")),
            tables.join(format!("{axis}.csv")),
        )
        .unwrap();
    }
    let text = std::fs::read_to_string(root().join("machines/ref-trt.toml")).unwrap();
    assert!(text.contains("length = 100.0"));
    // Without its [[tools]]: the tools come from --tools or not at all.
    let text = text.split("\n# The tool table").next().unwrap().to_string();
    assert!(!text.contains("[[tools]]"));
    let machines = ["100.0", "40.0", "120.0"].map(|length| {
        let path = dir.join(format!("machine-{length}.toml"));
        std::fs::write(
            &path,
            text.replace("length = 100.0", &format!("length = {length}")),
        )
        .unwrap();
        path
    });
    (fit, machines)
}

/// `volcomp compensate` of `program` into its text.
fn compensate(dir: &Path, machine: &Path, fit: &Path, program: &str, extra: &[&str]) -> String {
    let input = dir.join("in.nc");
    let output = dir.join("out.nc");
    std::fs::write(&input, program).unwrap();
    let out = volcomp()
        .arg("compensate")
        .arg(machine)
        .arg(&input)
        .arg("-o")
        .arg(&output)
        .arg("--model")
        .arg(fit)
        .args(extra)
        .output()
        .unwrap();
    assert_success(&out);
    std::fs::read_to_string(&output).unwrap()
}

/// The lines that carry an axis word (the motion words), in order.
fn motion_lines(text: &str) -> Vec<String> {
    text.lines()
        .filter(|l| !l.starts_with('(') && l.contains(['X', 'Y', 'Z']))
        .map(str::to_string)
        .collect()
}

/// Compensating a two-tool program with the tool table gives the same motion
/// words, byte for byte, as compensating each tool's part with a machine file
/// whose `[tool]` is that tool; without the table the second tool's part
/// differs (so the comparison can fail).
fn split_equals_whole(frame: &str) {
    let dir = tempfile::tempdir().unwrap();
    let (fit, [m100, m40, m120]) = setup(dir.path());
    std::fs::write(dir.path().join("tool.tbl"), TABLE).unwrap();
    let tools = dir.path().join("tool.tbl");
    let (s1, s2) = (section(-30.0, 10.0), section(5.0, 25.0));
    let whole = format!("{PREAMBLE}T1 M6\nG43 H1\n{s1}T2 M6\nG43 H2\n{s2}M30\n%\n");
    let part1 = format!("{PREAMBLE}{s1}M30\n%\n");
    let part2 = format!("{PREAMBLE}{s2}M30\n%\n");
    let args = ["--frame", frame];
    let mut with_table = args.to_vec();
    with_table.extend(["--tools", tools.to_str().unwrap()]);

    let whole_out = compensate(dir.path(), &m100, &fit, &whole, &with_table);
    let mut parts = motion_lines(&compensate(dir.path(), &m40, &fit, &part1, &args));
    parts.extend(motion_lines(&compensate(
        dir.path(),
        &m120,
        &fit,
        &part2,
        &args,
    )));
    let whole_lines = motion_lines(&whole_out);
    assert_eq!(whole_lines.len(), parts.len(), "{frame}: {whole_out}");
    for (k, (w, p)) in whole_lines.iter().zip(&parts).enumerate() {
        assert_eq!(w, p, "{frame}: motion line {k}");
    }
    // The tool's length matters: without the table both tools are the
    // default 100 mm tool and the motion words differ.
    let default_out = compensate(dir.path(), &m100, &fit, &whole, &args);
    let differing = motion_lines(&default_out)
        .iter()
        .zip(&parts)
        .filter(|(a, b)| a != b)
        .count();
    // (ref-trt's angular errors are small: tens of nm per 10 mm of length,
    // so some lines round alike at 4 decimals.)
    assert!(
        differing >= 8,
        "{frame}: only {differing} lines depend on the tool"
    );
}

#[test]
fn a_two_tool_program_compensates_as_its_parts_with_each_tool_joint_frame() {
    split_equals_whole("joint");
}

#[test]
fn a_two_tool_program_compensates_as_its_parts_with_each_tool_part_frame() {
    split_equals_whole("part");
}

fn setup_with(table: &str) -> ProgramSetup {
    ProgramSetup {
        tools: ToolTable::parse(table, "tool.tbl").unwrap(),
        ..ProgramSetup::default()
    }
}

/// The tool of each move and the warnings, or the error.
fn run(
    text: &str,
    setup: ProgramSetup,
) -> Result<(Vec<(usize, u32, f64)>, Vec<WarningKind>), String> {
    let program = Program::new(
        Box::new(std::io::Cursor::new(text.as_bytes().to_vec())),
        Path::new("p.ngc"),
        setup,
    );
    let mut run = program.run(Default::default());
    let mut moves = Vec::new();
    let mut warnings = Vec::new();
    while let Some(step) = run.next() {
        let (_, event, _) = step.map_err(|e| e.to_string())?;
        warnings.extend(event.warnings.iter().map(|w| w.kind.clone()));
        for _ in event.motions() {
            moves.push((event.line, event.tool.number, event.tool.length_mm));
        }
    }
    Ok((moves, warnings))
}

#[test]
fn the_tool_in_the_spindle_follows_t_m6_m61_and_g10() {
    let text = "G21 G90\nG0 X0 Y0 Z10\nT1 M6 G43\nG1 Z0 F100\nT2\nG1 X1\nM6 G43 H2\nG1 X2\n\
                G10 L1 P2 Z125.5 R4\nG43 H2\nG1 X3\nM61 Q1\nG43\nG1 X4\nT0 M6 G49\nG1 X5\nM2\n";
    let (moves, warnings) = run(text, setup_with(TABLE)).unwrap();
    assert_eq!(
        moves,
        vec![
            (2, 0, 0.0),
            (4, 1, 40.0),
            (6, 1, 40.0), // T2 is only selected
            (8, 2, 120.0),
            (11, 2, 125.5), // G10 L1 changed its length
            (14, 1, 40.0),
            (16, 0, 0.0), // empty spindle: the default tool
        ]
    );
    assert!(warnings.is_empty(), "{warnings:?}");
}

#[test]
fn g10_l10_sets_the_length_that_makes_the_current_point_read_as_given() {
    // At machine Z -80 with T1 (40 mm) applied, G10 L10 P1 Z0 sets T1's length
    // so that Z reads 0 with the offset: -80 + 40 - 0 = -40 mm.
    let text = "G21 G90\nT1 M6 G43\nG0 X0 Y0 Z-80\nG10 L10 P1 Z0\nG43\nG1 X1 F100\nM2\n";
    let (moves, _) = run(text, setup_with(TABLE)).unwrap();
    assert_eq!(moves.last().unwrap(), &(6, 1, -40.0));
}

#[test]
fn a_tool_the_table_lacks_is_a_located_error() {
    for (text, column) in [
        ("G21\nT7 M6\nM2\n", 1),
        ("G21\nM61 Q7\nM2\n", 5),
        ("G21\nT1 M6\nG43 H9\nM2\n", 5),
        ("G21\nG10 L1 P8 Z3\nM2\n", 8),
    ] {
        let err = run(text, setup_with(TABLE)).unwrap_err();
        let wanted = ErrorKind::ToolNotInTable(if text.contains("H9") {
            9
        } else if text.contains("P8") {
            8
        } else {
            7
        })
        .to_string();
        assert!(err.contains(&wanted), "{text}: {err}");
        assert!(
            err.contains(&format!(
                "p.ngc:{}:{column}",
                if text.contains("H9") { 3 } else { 2 }
            )),
            "{text}: {err}"
        );
    }
    // Without a table any tool may be selected; the default tool is used,
    // and the first tool change says so.
    let (moves, warnings) = run("G21\nT7 M6\nG1 X1 F100\nM2\n", ProgramSetup::default()).unwrap();
    assert_eq!(moves, vec![(3, 0, 0.0)]);
    assert_eq!(warnings, vec![WarningKind::NoToolTable(7)]);
}

#[test]
fn cutting_under_an_offset_other_than_the_tools_length_is_warned_once() {
    let text =
        "G21 G90\nT2 M6\nG0 X0 Y0 Z5\nG1 Z0 F100\nG1 X1\nG43 H1\nG1 X2\nG43.1 Z120\nG1 X3\nM2\n";
    let (moves, warnings) = run(text, setup_with(TABLE)).unwrap();
    assert_eq!(
        moves.len(),
        5,
        "G43.1's Z word sets the offset, it does not move"
    );
    assert_eq!(
        warnings,
        vec![
            WarningKind::ToolLengthOffsetMismatch {
                tool: 2,
                length_mm: 120.0,
                offset_mm: 0.0
            },
            WarningKind::ToolLengthOffsetMismatch {
                tool: 2,
                length_mm: 120.0,
                offset_mm: 40.0
            },
        ]
    );
}

#[test]
fn the_machine_file_tools_and_the_error_command_use_them() {
    let dir = tempfile::tempdir().unwrap();
    let (fit, _) = setup(dir.path());
    // ref-trt's [[tools]]: T2 is 60 mm long, [tool] 100 mm.
    let machine = root().join("machines/ref-trt.toml");
    let error_at = |tool: &[&str]| {
        let out = volcomp()
            .arg("error")
            .arg(&machine)
            .args(["--at", "10,20,-30,15,45", "--json", "--model"])
            .arg(&fit)
            .args(tool)
            .output()
            .unwrap();
        assert_success(&out);
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["e_um"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect::<Vec<f64>>()
    };
    let default = error_at(&[]);
    let t2 = error_at(&["--tool", "2"]);
    let t0 = error_at(&["--tool", "0"]);
    assert_eq!(default, t0);
    assert!(
        default.iter().zip(&t2).any(|(a, b)| (a - b).abs() > 1e-3),
        "{default:?} {t2:?}"
    );
    let out = volcomp()
        .arg("error")
        .arg(&machine)
        .args(["--at", "10,20,-30,15,45", "--tool", "5", "--model"])
        .arg(&fit)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--tool 5: not in the tool table"));
}
