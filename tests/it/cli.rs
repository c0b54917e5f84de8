//! Command-line behaviour common to every command.

use crate::support::{assert_success, root, volcomp};
use std::path::{Path, PathBuf};
use std::process::Output;
use volcomp::stamp::{PREFIX, Stamp};

#[test]
fn help_lists_commands_and_examples() {
    let out = volcomp().arg("--help").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    for cmd in [
        "fit",
        "error",
        "compensate",
        "predict",
        "diff",
        "simulate",
        "diagnose",
    ] {
        assert!(text.contains(cmd), "help lacks {cmd}:\n{text}");
    }
    assert!(text.contains("Examples:"));
}

#[test]
fn unknown_command_is_a_usage_error() {
    let out = volcomp().arg("frobnicate").output().unwrap();
    assert_eq!(out.status.code(), Some(2));
}

// Issue 23: nothing silently wrong.

const MACHINE: &str = "machines/ref-trt.toml";

fn run(args: &[&str]) -> Output {
    volcomp().args(args).current_dir(root()).output().unwrap()
}

fn stdout(out: &Output) -> String {
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The reference machine without its tool table (`[[tools]]`), in `dir`.
fn machine_without_tools(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(root().join(MACHINE)).unwrap();
    let cut = text.find("[[tools]]").expect("ref-trt lists tools");
    let tables = format!("\"{}/machines/ref-trt/", root().display());
    let path = dir.join("no-tools.toml");
    std::fs::write(&path, text[..cut].replace("\"ref-trt/", &tables)).unwrap();
    path
}

/// Issue 23 (3): a warning of the reading (T2 loaded without a tool table:
/// the default tool's length assumed) is shown once, with its line and a
/// count, by every command that reads the program, in every JSON report, and
/// the summary line says that it changes the result.
#[test]
fn every_command_shows_the_warnings_of_the_reading() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let machine = machine_without_tools(d);
    let m = s(&machine);
    let saddle = "samples/saddle.nc";
    let plan = "samples/saddle-plan.csv";
    let warned = |out: &Output, what: &str| {
        let err = stderr(out);
        let line = "warning: samples/saddle.nc:7:1: T2 is loaded but there is no tool table";
        assert_eq!(err.matches(line).count(), 1, "{what}: {err}");
    };
    let in_report = |path: &Path, what: &str| {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap();
        let w = &v["warnings"][0];
        assert_eq!(w["kind"], "no_tool_table", "{what}: {v}");
        assert_eq!(w["count"], 1, "{what}");
        assert_eq!(w["first_line"], 7, "{what}");
        assert_eq!(w["changes_result"], true, "{what}");
    };
    let note = "(warnings change this result: 1× tool length assumed)";

    let report = d.join("comp.json");
    let out = run(&[
        "compensate",
        m,
        saddle,
        "-o",
        s(&d.join("c.nc")),
        "--report",
        s(&report),
    ]);
    assert_success(&out);
    warned(&out, "compensate");
    in_report(&report, "compensate");
    assert!(
        stdout(&out).lines().next().unwrap().ends_with(note),
        "{}",
        stdout(&out)
    );

    let report = d.join("pred.json");
    let out = run(&["predict", m, saddle, "--plan", plan, "--report", s(&report)]);
    assert_success(&out);
    warned(&out, "predict");
    in_report(&report, "predict");
    assert!(
        stdout(&out).lines().next().unwrap().ends_with(note),
        "{}",
        stdout(&out)
    );

    let out = run(&["check", saddle, "--json"]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["warnings"][0]["kind"], "no_tool_table");
    // The human summary went to stderr, with the warning.
    assert!(stderr(&out).contains(note), "{}", stderr(&out));
    assert!(stderr(&out).contains("saddle.nc:7:1: T2 is loaded"));

    let report = d.join("diff.json");
    let out = run(&["diff", saddle, s(&d.join("c.nc")), "--report", s(&report)]);
    assert_success(&out);
    // diff compares the targets as programmed: no tool length enters them,
    // so the tool table's absence is not said, nor counted as changing it.
    assert_eq!(
        stderr(&out).matches("T2 is loaded").count(),
        0,
        "{}",
        stderr(&out)
    );
    assert!(!stdout(&out).contains("warnings change this result"));
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    assert_eq!(v["warnings"].as_array().unwrap().len(), 0);

    let measured = d.join("m.csv");
    let out = run(&[
        "simulate",
        m,
        saddle,
        plan,
        "-o",
        s(&measured),
        "--effect",
        "backlash:bx=6",
    ]);
    assert_success(&out);
    warned(&out, "simulate");
    assert!(
        stdout(&out).lines().next().unwrap().ends_with(note),
        "{}",
        stdout(&out)
    );

    let report = d.join("diag.json");
    let out = run(&["diagnose", m, saddle, s(&measured), "--report", s(&report)]);
    assert_success(&out);
    warned(&out, "diagnose");
    in_report(&report, "diagnose");
    assert!(
        stdout(&out).lines().next().unwrap().ends_with(note),
        "{}",
        stdout(&out)
    );
}

/// Issue 23 (3): lines passed through under --lenient are counted and said
/// to change the result (a Heidenhain program: no motion at all).
#[test]
fn lenient_pass_through_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("heid.h");
    std::fs::write(
        &program,
        "BEGIN PGM TEST MM\nBLK FORM 0.1 Z X+0 Y+0 Z-20\nTOOL CALL 1 Z S5000\nL X+10 Y+10 R0 FMAX\nL Z-5 F200\nEND PGM TEST MM\n",
    )
    .unwrap();
    let out_path = dir.path().join("out.nc");
    let out = run(&[
        "compensate",
        MACHINE,
        s(&program),
        "-o",
        s(&out_path),
        "--lenient",
        // `BEGIN PGM` would read it as Heidenhain (docs/dialects.md): this
        // is LinuxCNC's reader passing unread lines through.
        "--dialect",
        "linuxcnc",
    ]);
    assert_success(&out);
    let first = stdout(&out).lines().next().unwrap().to_string();
    assert!(
        first.ends_with("(warnings change this result: 6× passed through unread (--lenient))"),
        "{first}"
    );
    let err = stderr(&out);
    assert!(
        err.contains("heid.h:1:1: passed through (--lenient): word `B` has no number (6 in all, the first shown)"),
        "{err}"
    );
}

/// Issue 23 (4): predict on a compensated (stamped) program headlines what
/// the part will measure, with the uncompensated figure beside it; so does
/// the HTML.
#[test]
fn predict_headlines_what_a_compensated_part_measures() {
    let dir = tempfile::tempdir().unwrap();
    let comp = dir.path().join("c.nc");
    assert_success(&run(&[
        "compensate",
        MACHINE,
        "samples/saddle.nc",
        "-o",
        s(&comp),
    ]));
    let html = dir.path().join("p.html");
    let out = run(&[
        "predict",
        MACHINE,
        s(&comp),
        "--plan",
        "samples/saddle-plan.csv",
        "--html",
        s(&html),
    ]);
    assert_success(&out);
    let text = stdout(&out);
    let first = text.lines().next().unwrap();
    assert!(
        first.starts_with("the part will measure profile 0.2"),
        "{text}"
    );
    assert!(first.contains("uncompensated it would be 32.4"), "{text}");
    let page = std::fs::read_to_string(&html).unwrap();
    assert!(
        page.contains("the part will measure a profile error of 0.2"),
        "no headline in the HTML"
    );
    assert!(page.contains("Without compensation"));
    // The original program keeps formats.md's headline.
    let out = run(&[
        "predict",
        MACHINE,
        "samples/saddle.nc",
        "--plan",
        "samples/saddle-plan.csv",
    ]);
    assert!(
        stdout(&out).starts_with("predicted profile error 32.4"),
        "{}",
        stdout(&out)
    );
}

/// Issue 23 (5): data on standard output sends the summary to standard
/// error; two outputs on standard output are a usage error.
#[test]
fn data_on_stdout_parses_and_two_outputs_on_it_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = run(&["fit", MACHINE, "--report", "-"]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON alone");
    assert_eq!(v["parameters"].as_array().unwrap().len(), 30);
    assert!(stderr(&out).contains("30 parameters fitted"));

    let comp = dir.path().join("c.nc");
    let out = run(&[
        "compensate",
        MACHINE,
        "samples/saddle.nc",
        "-o",
        s(&comp),
        "--report",
        "-",
    ]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON alone");
    assert_eq!(v["blocks_read"], 3927);
    assert!(stderr(&out).contains("3927 blocks read"));

    for args in [
        &[
            "compensate",
            MACHINE,
            "samples/saddle.nc",
            "-o",
            "-",
            "--report",
            "-",
        ][..],
        &["check", "samples/saddle.nc", "--targets", "-", "--json"],
        &[
            "diff",
            "samples/saddle.nc",
            "samples/saddle.nc",
            "--report",
            "-",
            "--json",
        ],
        &[
            "predict",
            MACHINE,
            "samples/saddle.nc",
            "--report",
            "-",
            "--html",
            "-",
        ],
    ] {
        let out = run(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("write to standard output"),
            "{}",
            stderr(&out)
        );
        assert!(out.stdout.is_empty());
    }

    let out = run(&["check", "samples/saddle.nc", "--json"]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["lines"], 3927);
    assert_eq!(v["tools"][0]["moves"], 3911);
    assert_eq!(v["compensated"], false);

    // diff --json, and --fail-over for CI.
    let out = run(&["diff", "samples/saddle.nc", s(&comp), "--json"]);
    assert_success(&out);
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let max = v["max_xyz_change_um"].as_f64().unwrap();
    assert!(max > 20.0 && max < 40.0, "{max}");
    let out = run(&["diff", "samples/saddle.nc", s(&comp), "--fail-over", "1"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out).contains("more than --fail-over 1 µm"),
        "{}",
        stderr(&out)
    );
    let out = run(&["diff", "samples/saddle.nc", s(&comp), "--fail-over", "100"]);
    assert_success(&out);
}

/// Issue 23 (6): a target at a table's end whose correction crosses the end
/// by less than the correction compensates, the end value held over that
/// sliver, and says so once; a target beyond the table stays an error.
#[test]
fn a_move_to_the_end_of_a_table_compensates() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("end.nc");
    std::fs::write(
        &program,
        "G21 G90 G94\nG1 X0 Y0 Z0 A10 C0 F500\nG1 Y150\nG1 X10\nG1 Y0\nM30\n",
    )
    .unwrap();
    let out_path = dir.path().join("out.nc");
    let report = dir.path().join("r.json");
    // The reference machine's travel ends where its tables do: --no-limits.
    let out = run(&[
        "compensate",
        MACHINE,
        s(&program),
        "-o",
        s(&out_path),
        "--no-limits",
        "--report",
        s(&report),
    ]);
    assert_success(&out);
    let err = stderr(&out);
    assert_eq!(err.matches("warning:").count(), 1, "{err}");
    assert!(
        err.contains("end.nc:3: the target is inside the error tables but its correction crosses a table's end, by up to"),
        "{err}"
    );
    assert!(
        stdout(&out).contains("× table end held over a sliver"),
        "{}",
        stdout(&out)
    );
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&report).unwrap()).unwrap();
    let t = &v["table_ends"];
    assert_eq!(t["moves"], 2, "{v}");
    assert_eq!(t["first_line"], 3);
    let um = t["max_um"].as_f64().unwrap();
    assert!(um > 0.0 && um < 20.0, "{um}");
    // The travel check still refuses what the machine cannot reach.
    let out = run(&["compensate", MACHINE, s(&program), "-o", s(&out_path)]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("outside its travel"),
        "{}",
        stderr(&out)
    );
    // A target beyond the table is no sliver.
    std::fs::write(
        &program,
        "G21 G90 G94\nG1 X0 Y0 Z0 A10 C0 F500\nG1 Y150.01\nM30\n",
    )
    .unwrap();
    let out = run(&[
        "compensate",
        MACHINE,
        s(&program),
        "-o",
        s(&out_path),
        "--no-limits",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        stderr(&out).contains("outside the Y error table"),
        "{}",
        stderr(&out)
    );
}

/// The compensated flank sample's stamp lines, and the program.
fn compensated(dir: &Path) -> (PathBuf, String) {
    let path = dir.join("c.nc");
    assert_success(&run(&[
        "compensate",
        MACHINE,
        "samples/flank.nc",
        "-o",
        s(&path),
    ]));
    let text = std::fs::read_to_string(&path).unwrap();
    (path, text)
}

/// Issue 23 (8): a stamp as a controller or an editor may leave it is still
/// found, and the program is not compensated a second time.
#[test]
fn a_changed_stamp_still_refuses_a_second_compensation() {
    let dir = tempfile::tempdir().unwrap();
    let (_, text) = compensated(dir.path());
    let stamp_lines: Vec<&str> = text.lines().filter(|l| l.starts_with(PREFIX)).collect();
    let rest: Vec<&str> = text.lines().filter(|l| !l.starts_with(PREFIX)).collect();
    let join = |lines: Vec<String>| lines.join("\n") + "\n";
    let variants: Vec<(&str, String)> = vec![
        ("uppercased", text.to_ascii_uppercase()),
        (
            "N-numbered",
            join(
                text.lines()
                    .enumerate()
                    .map(|(i, l)| {
                        if l.starts_with(['%', 'N']) {
                            l.to_string()
                        } else {
                            format!("N{} {l}", 10 * (i + 1))
                        }
                    })
                    .collect(),
            ),
        ),
        (
            "; comments",
            join(
                text.lines()
                    .map(|l| match l.strip_prefix('(') {
                        Some(body) if l.starts_with(PREFIX) => {
                            format!("; {}", body.trim_end_matches(')'))
                        }
                        _ => l.to_string(),
                    })
                    .collect(),
            ),
        ),
        (
            "past line 64",
            join(
                std::iter::once("%".to_string())
                    .chain(std::iter::repeat_n("(a long header)".to_string(), 100))
                    .chain(text.lines().skip(1).map(str::to_string))
                    .collect(),
            ),
        ),
        (
            "without its compensated-by line",
            join(
                text.lines()
                    .filter(|l| !l.contains("compensated-by"))
                    .map(str::to_string)
                    .collect(),
            ),
        ),
        (
            "after the first blocks",
            join(
                rest[..3]
                    .iter()
                    .chain(&stamp_lines)
                    .chain(&rest[3..])
                    .map(|l| l.to_string())
                    .collect(),
            ),
        ),
    ];
    for (what, program) in variants {
        let path = dir.path().join("variant.nc");
        std::fs::write(&path, &program).unwrap();
        let out = run(&[
            "compensate",
            MACHINE,
            s(&path),
            "-o",
            s(&dir.path().join("again.nc")),
        ]);
        assert_eq!(out.status.code(), Some(1), "{what}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("is already compensated"),
            "{what}: {}",
            stderr(&out)
        );
        let out = run(&[
            "compensate",
            MACHINE,
            s(&path),
            "-o",
            s(&dir.path().join("again.nc")),
            "--force",
        ]);
        assert_success(&out);
    }
}

/// Issue 23 (8): blank lines before the opening `%` stay before it, the
/// stamp goes after it, and the output reads back (volcomp and LinuxCNC).
#[test]
fn the_stamp_goes_after_the_percent_behind_blank_lines() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("p.ngc");
    std::fs::write(
        &program,
        "\n  \n%\nG21 G90 G94\nG1 X1 Y1 Z1 A10 C0 F100\nM2\n%\n",
    )
    .unwrap();
    let out_path = dir.path().join("out.ngc");
    assert_success(&run(&[
        "compensate",
        MACHINE,
        s(&program),
        "-o",
        s(&out_path),
    ]));
    let text = std::fs::read_to_string(&out_path).unwrap();
    assert!(
        text.starts_with("\n  \n%\n(volcomp-stamp compensated-by: "),
        "{text}"
    );
    assert_success(&run(&["check", s(&out_path)]));
    let _one_at_a_time = crate::rs274::RS274
        .lock()
        .unwrap_or_else(|e| e.into_inner());
    if let Ok(out) = std::process::Command::new("rs274")
        .arg("-g")
        .arg(&out_path)
        .stdin(std::process::Stdio::null())
        .output()
    {
        let all = stdout(&out) + &stderr(&out);
        assert!(!all.contains("Bad character"), "{all}");
        assert!(all.contains("PROGRAM_END"), "{all}");
    }
}

/// Issue 23 (8): stamp values never reach the terminal raw, and a partial
/// stamp prints no NaN.
#[test]
fn stamp_values_are_shown_safely() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("p.nc");
    std::fs::write(
        &program,
        "(volcomp-stamp machine: evil\u{1b}[2J\u{1b}]0;title\u{7})\nG21 G90\nG1 X1 Y1 Z1 A10 C0 F100\nM2\n",
    )
    .unwrap();
    let out = run(&["check", s(&program)]);
    assert_success(&out);
    let text = stdout(&out);
    assert!(
        !text.contains('\u{1b}') && !text.contains('\u{7}'),
        "{text:?}"
    );
    assert!(text.contains("machine evil\\u{1b}[2J"), "{text}");
    assert!(text.contains("tool length unknown"), "{text}");
    assert!(!text.contains("NaN"), "{text}");
    let out = run(&[
        "compensate",
        MACHINE,
        s(&program),
        "-o",
        s(&dir.path().join("o.nc")),
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(!stderr(&out).contains('\u{1b}'));
}

/// Issue 23 (11): the stamp lists the tools it was compensated with.
#[test]
fn the_stamp_lists_the_tools() {
    let dir = tempfile::tempdir().unwrap();
    let (_, text) = compensated(dir.path());
    let stamp = Stamp::find(&text).unwrap();
    assert_eq!(stamp.tools_mm, "T1=100 T2=60 T3=80");
    assert_eq!(stamp.tool_length_mm, Some(100.0));
}

/// Issue 23 (10): a fractional `#5220` selects the coordinate system LinuxCNC
/// selects: `(int)(#5220 + 0.0001)`, so 1.9 is G54, not G55.
#[test]
fn a_fractional_coordinate_system_number_truncates_as_linuxcnc() {
    let dir = tempfile::tempdir().unwrap();
    let var = dir.path().join("p.var");
    std::fs::write(&var, "5220 1.9\n5221 10\n5241 100\n").unwrap();
    let program = dir.path().join("p.ngc");
    std::fs::write(&program, "G21 G90\nG0 X0 Y0 Z0\nM2\n").unwrap();
    let out = run(&["check", s(&program), "--var", s(&var), "--targets", "-"]);
    assert_success(&out);
    let row = stdout(&out).lines().nth(1).unwrap().to_string();
    assert!(row.starts_with("2,G0,10.000000,"), "{row}");
}

/// Issue 23 (11): small things a user notices.
#[test]
fn plurals_units_and_numbers_read_well() {
    let dir = tempfile::tempdir().unwrap();
    let program = dir.path().join("p.nc");
    std::fs::write(
        &program,
        "G21 G90 G94\nT1 M6\nG1 X1 Y1 Z1 A10 C0 F100\nM2\n",
    )
    .unwrap();
    let out = run(&[
        "compensate",
        MACHINE,
        s(&program),
        "-o",
        s(&dir.path().join("o.nc")),
    ]);
    assert_success(&out);
    let text = stdout(&out);
    assert!(text.contains("lines 3–3: 1 move,"), "{text}");
    assert!(text.contains("(+0 blocks)"), "{text}");
    // The rate: whole blocks per second, thousands separated.
    let rate = text
        .split(" s (")
        .nth(1)
        .and_then(|r| r.split(" blocks/s").next())
        .unwrap_or_else(|| panic!("{text}"));
    assert!(
        rate.chars().all(|c| c.is_ascii_digit() || c == ','),
        "{rate}"
    );
    let out = run(&[
        "check",
        s(&program),
        "--targets",
        s(&dir.path().join("t.csv")),
    ]);
    assert!(
        stdout(&out).contains("targets: 1 row written"),
        "{}",
        stdout(&out)
    );
    // µm in every human output.
    for args in [
        &["error", MACHINE, "--at", "10,20,-30,15,45", "--verbose"][..],
        &[
            "map",
            MACHINE,
            "--plane",
            "xy",
            "--at",
            "z=0",
            "--grid",
            "9",
            "--out",
            s(&dir.path().join("m.svg")),
        ],
        &["fit", MACHINE],
    ] {
        let out = run(args);
        assert_success(&out);
        let text = stdout(&out);
        assert!(text.contains("µm"), "{args:?}: {text}");
        for word in [" um", "(um)", " urad", "e0 "] {
            assert!(!text.contains(word), "{args:?}: `{word}` in {text}");
        }
    }
    let out = run(&["--help"]);
    assert!(stdout(&out).contains("the flank"), "{}", stdout(&out));
}
