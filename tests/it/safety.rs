//! Issue 11: a compensated program is a part about to be cut. The provenance
//! stamp, in-place writing only when asked, checked writes, and interrupted runs
//! that leave nothing behind.
use crate::support::{assert_success, root, volcomp};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use volcomp::stamp::{PREFIX, Stamp};

const MACHINE: &str = "machines/ref-trt.toml";

fn run(cmd: &mut Command) -> Output {
    cmd.current_dir(root()).output().unwrap()
}

fn compensate(input: &Path, extra: &[&str]) -> Output {
    run(volcomp()
        .args(["compensate", MACHINE])
        .arg(input)
        .args(extra))
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Files in `dir` whose name looks like a temporary output.
fn temp_files(dir: &Path) -> Vec<PathBuf> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            p.file_name()
                .is_some_and(|n| n.to_string_lossy().starts_with(".volcomp-"))
        })
        .collect()
}

fn saddle_copy(dir: &Path) -> PathBuf {
    let path = dir.join("part.nc");
    std::fs::copy(root().join("samples/saddle.nc"), &path).unwrap();
    path
}

#[test]
fn compensated_program_is_stamped_and_refused_a_second_time() {
    let dir = tempfile::tempdir().unwrap();
    let input = saddle_copy(dir.path());
    let original = std::fs::read_to_string(&input).unwrap();
    let out_path = dir.path().join("part-comp.nc");
    let out = compensate(&input, &["-o", out_path.to_str().unwrap(), "--tol", "0.4"]);
    assert_success(&out);
    let text = std::fs::read_to_string(&out_path).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    // After the `%` and `O` lines, ten comment lines (the tools of the
    // machine file's table; the last: the tool axis was corrected too, the
    // default), then the program.
    assert_eq!(lines[0], "%");
    assert!(lines[1].starts_with("O2016 "));
    assert!(
        lines[2..12]
            .iter()
            .all(|l| l.starts_with(PREFIX) && l.ends_with(')'))
    );
    assert_eq!(lines[7], "(volcomp-stamp tools-mm: T1=100 T2=60 T3=80)");
    assert_eq!(lines[11], "(volcomp-stamp corrected: tip and tool axis)");
    assert!(!lines[12].starts_with(PREFIX));
    let original_lines: Vec<&str> = original.lines().collect();
    assert_eq!(lines[12], original_lines[2]);
    // Ten stamp lines, plus the blocks the tolerance split off.
    let stdout = String::from_utf8_lossy(&out.stdout);
    let added: usize = stdout
        .split("(+")
        .nth(1)
        .and_then(|t| t.split_whitespace().next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no split count in {stdout}"));
    assert_eq!(lines.len(), original_lines.len() + 10 + added);
    assert!(stamp_of(&text).orientation);
    let stamp = stamp_of(&text);
    assert_eq!(
        stamp.compensated_by,
        format!("volcomp {}", env!("CARGO_PKG_VERSION"))
    );
    assert_eq!(stamp.machine, "ref-trt");
    assert_eq!(stamp.tolerance_um, Some(0.4));
    assert_eq!(stamp.tool_length_mm, Some(100.0));
    assert_eq!(stamp.model_source, "fit cv");
    assert_eq!(stamp.model_fnv1a64.len(), 16);
    assert_eq!(
        stamp.input_fnv1a64,
        format!("{:016x}", volcomp::nurbs::fnv1a64(original.as_bytes()))
    );
    assert!(stamp.input.ends_with("part.nc"));
    assert_eq!(Stamp::find(&original), None);

    // Again: refused, naming the file, the machine and the version.
    let again = dir.path().join("again.nc");
    let out = compensate(&out_path, &["-o", again.to_str().unwrap()]);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(err.contains("part-comp.nc is already compensated"), "{err}");
    assert!(
        err.contains("ref-trt") && err.contains("volcomp 0."),
        "{err}"
    );
    assert!(err.contains("--force"), "{err}");
    assert!(!again.exists());
    // Through standard input too.
    let out = run(volcomp()
        .args(["compensate", MACHINE, "-", "-o", "-"])
        .stdin(std::fs::File::open(&out_path).unwrap()));
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(out.stdout.is_empty());
    // --force: compensated again, the new stamp first.
    let out = compensate(&out_path, &["-o", again.to_str().unwrap(), "--force"]);
    assert_success(&out);
    let twice = std::fs::read_to_string(&again).unwrap();
    assert_eq!(twice.matches("(volcomp-stamp compensated-by").count(), 2);
    assert!(Stamp::find(&twice).unwrap().input.ends_with("part-comp.nc"));

    // check, diff and predict say so.
    let out = run(volcomp().arg("check").arg(&out_path));
    assert_success(&out);
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(
        s.contains("stamp: compensated by volcomp") && s.contains("ref-trt"),
        "{s}"
    );
    let out = run(volcomp().arg("diff").arg(&input).arg(&out_path));
    assert_success(&out);
    let s = String::from_utf8_lossy(&out.stdout);
    assert!(
        s.contains("B (") && s.contains("compensated by volcomp"),
        "{s}"
    );
    assert!(!s.contains("A ("), "{s}");
    for (program, compensated) in [(&out_path, true), (&input, false)] {
        let out = run(volcomp()
            .args(["predict", MACHINE])
            .arg(program)
            .args(["--report", "-"]));
        assert_success(&out);
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(report["compensated"], compensated);
        assert_eq!(report.get("stamp").is_some(), compensated);
        assert!(report["max_error_um"].is_number());
        assert_eq!(
            stderr(&out).contains("is already compensated"),
            compensated,
            "{}",
            stderr(&out)
        );
    }
}

#[cfg(unix)]
#[test]
fn output_over_the_input_needs_in_place() {
    let dir = tempfile::tempdir().unwrap();
    let input = saddle_copy(dir.path());
    let original = std::fs::read(&input).unwrap();
    let link = dir.path().join("link.nc");
    std::os::unix::fs::symlink(&input, &link).unwrap();
    let hard = dir.path().join("hard.nc");
    std::fs::hard_link(&input, &hard).unwrap();
    for target in [&input, &link, &hard] {
        let out = compensate(&input, &["-o", target.to_str().unwrap()]);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{err}");
        assert!(err.contains("is the input program"), "{err}");
        assert!(err.contains("--in-place"), "{err}");
        assert_eq!(std::fs::read(&input).unwrap(), original);
    }
    // --in-place with another output is a usage error too.
    let other = dir.path().join("other.nc");
    let out = compensate(&input, &["--in-place", "-o", other.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(!other.exists());
    // Through the symlink: the real file is replaced, the link stays a link.
    let out = compensate(&link, &["--in-place"]);
    assert_success(&out);
    let replaced = std::fs::read_to_string(&input).unwrap();
    assert!(Stamp::find(&replaced).is_some());
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(temp_files(dir.path()).is_empty());
    // And a second in-place run is refused: it is compensated now.
    let out = compensate(&input, &["--in-place"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert_eq!(std::fs::read_to_string(&input).unwrap(), replaced);
}

fn dev_full() -> Stdio {
    Stdio::from(
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap(),
    )
}

#[cfg(target_os = "linux")]
#[test]
fn a_full_output_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("fit.json");
    // `fit` itself: a table on standard output.
    let out = run(volcomp()
        .args(["fit", MACHINE, "--report"])
        .arg(&model)
        .stdout(dev_full()));
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("standard output"), "{}", stderr(&out));
    assert_success(&run(volcomp()
        .args(["fit", MACHINE, "--report"])
        .arg(&model)));
    let model = model.to_str().unwrap();
    let saddle = "samples/saddle.nc";
    let plan = "samples/saddle-plan.csv";
    // (arguments, output named in the message, stdout to /dev/full)
    let cases: Vec<(Vec<&str>, &str, bool)> = vec![
        (
            vec![
                "compensate",
                MACHINE,
                "--model",
                model,
                saddle,
                "-o",
                "/dev/full",
            ],
            "/dev/full",
            false,
        ),
        (
            vec!["compensate", MACHINE, "--model", model, saddle, "-o", "-"],
            "standard output",
            true,
        ),
        (
            vec!["check", saddle, "--targets", "/dev/full"],
            "/dev/full",
            false,
        ),
        (
            vec!["check", saddle, "--targets", "-"],
            "standard output",
            true,
        ),
        (
            vec!["check", saddle, "--flatten", "-o", "/dev/full"],
            "/dev/full",
            false,
        ),
        (vec!["check", saddle], "standard output", true),
        (
            vec![
                "predict",
                MACHINE,
                "--model",
                model,
                saddle,
                "--report",
                "/dev/full",
            ],
            "/dev/full",
            false,
        ),
        (
            vec!["predict", MACHINE, "--model", model, saddle, "--plan", plan],
            "standard output",
            true,
        ),
        (vec!["diff", saddle, saddle], "standard output", true),
        (
            vec!["diff", saddle, saddle, "--report", "/dev/full"],
            "/dev/full",
            false,
        ),
        (
            vec!["error", MACHINE, "--model", model, "--at", "10,20,30,10,20"],
            "standard output",
            true,
        ),
        (
            vec![
                "simulate",
                MACHINE,
                "--model",
                model,
                saddle,
                plan,
                "-o",
                "/dev/full",
            ],
            "/dev/full",
            false,
        ),
    ];
    for (args, named, stdout_full) in cases {
        let mut cmd = volcomp();
        cmd.args(&args);
        if stdout_full {
            cmd.stdout(dev_full());
        }
        let out = run(&mut cmd);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(named), "{args:?}: {err}");
        assert!(err.contains("No space left"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    let meta = std::fs::metadata("/dev/full").unwrap();
    assert!(!meta.is_file(), "/dev/full is still a device");
}

#[cfg(unix)]
#[test]
fn a_pipe_closed_early_is_a_quiet_stop() {
    use std::io::{BufRead, BufReader};
    for args in [
        vec!["check", "--targets", "-", "samples/saddle.nc"],
        vec![
            "compensate",
            MACHINE,
            "tests/data/compensate/linuxcnc-demo.ngc",
            "-o",
            "-",
        ],
        vec!["check", "--flatten", "-o", "-", "samples/saddle.nc"],
    ] {
        let mut child = volcomp()
            .args(&args)
            .current_dir(root())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let mut first = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut first)
            .unwrap();
        assert!(!first.is_empty());
        // The reader is gone: the next writes meet a closed pipe.
        let out = child.wait_with_output().unwrap();
        let err = stderr(&out);
        // The demo program is small: it may fit in the pipe before it closes.
        if out.status.code() == Some(0) {
            assert!(args[0] == "compensate", "{args:?}: {err}");
            continue;
        }
        assert_eq!(out.status.code(), Some(141), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(!err.contains("error"), "{args:?}: {err}");
    }
}

/// A seeded five-axis program of `blocks` moves (as benches/compensate.rs).
fn write_big_program(path: &Path, blocks: usize) {
    use std::fmt::Write as _;
    let mut s = String::with_capacity(blocks * 48);
    s.push_str(
        "%\nO2000 (SIGNAL TEST)\nN1 G21 G90 G94 G17\nN2 G0 X0. Y0. Z0. A0. C0.\nN3 G1 F2000.\n",
    );
    for i in 0..blocks {
        let t = i as f64 * 0.002;
        let x = 150.0 * t.sin() * 0.99;
        let y = 100.0 * (1.3 * t + 0.5).sin() * 0.99;
        let z = -50.0 + 99.0 * (0.7 * t).sin();
        let a = 59.0 * (0.37 * t).sin();
        let c = 3.0 * t;
        let _ = writeln!(s, "X{x:.4} Y{y:.4} Z{z:.4} A{a:.4} C{c:.4}");
    }
    s.push_str("G0 Z50.\nM30\n%\n");
    std::fs::write(path, s).unwrap();
}

#[cfg(unix)]
#[test]
fn an_interrupted_run_leaves_no_temporary_file() {
    let dir = tempfile::tempdir().unwrap();
    let model = dir.path().join("fit.json");
    assert_success(&run(volcomp()
        .args(["fit", MACHINE, "--report"])
        .arg(&model)));
    let program = dir.path().join("big.nc");
    // Long enough that the run is still writing when the signal comes, even
    // on a loaded machine (with 400 000 blocks the exit code once differed
    // from the signal's under the full suite's load; the status is now in
    // the message).
    write_big_program(&program, 1_500_000);
    for (signal, code) in [("TERM", 143), ("INT", 130)] {
        let out_dir = dir.path().join(signal);
        std::fs::create_dir(&out_dir).unwrap();
        let output = out_dir.join("big-comp.nc");
        let mut child = volcomp()
            .args(["compensate", MACHINE, "--model"])
            .arg(&model)
            .arg(&program)
            .arg("-o")
            .arg(&output)
            .current_dir(root())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let started = Instant::now();
        while temp_files(&out_dir).is_empty() {
            assert!(
                started.elapsed() < Duration::from_secs(10),
                "no temporary file appeared"
            );
            assert!(child.try_wait().unwrap().is_none(), "finished too early");
            std::thread::sleep(Duration::from_millis(2));
        }
        let status = Command::new("kill")
            .arg(format!("-{signal}"))
            .arg(child.id().to_string())
            .status()
            .unwrap();
        assert!(status.success());
        let out = child.wait_with_output().unwrap();
        assert_eq!(
            out.status.code(),
            Some(code),
            "{signal}: {:?}, {}",
            out.status,
            stderr(&out)
        );
        assert!(
            temp_files(&out_dir).is_empty(),
            "{:?}",
            temp_files(&out_dir)
        );
        assert!(!output.exists());
    }
}

fn stamp_of(text: &str) -> Stamp {
    Stamp::find(text).expect("the output carries a stamp")
}

/// `--position-only` corrects the tip alone (the seed paper's compensation):
/// A and C stay as programmed, and the stamp has no ninth line.
#[test]
fn position_only_keeps_a_and_c_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let input = saddle_copy(dir.path());
    let out_path = dir.path().join("tip.nc");
    let out = compensate(
        &input,
        &["-o", out_path.to_str().unwrap(), "--position-only"],
    );
    assert_success(&out);
    let text = std::fs::read_to_string(&out_path).unwrap();
    assert!(!stamp_of(&text).orientation);
    assert!(!text.contains("corrected: tip and tool axis"));
    let original = std::fs::read_to_string(&input).unwrap();
    let rotary = |t: &str| -> Vec<String> {
        t.lines()
            .filter(|l| !l.starts_with(PREFIX))
            .flat_map(|l| l.split_whitespace().map(str::to_string).collect::<Vec<_>>())
            .filter(|w| w.starts_with('A') || w.starts_with('C'))
            .collect()
    };
    assert_eq!(rotary(&text), rotary(&original));
    let both = compensate(&input, &["-o", "-", "--position-only", "--orientation"]);
    assert_eq!(both.status.code(), Some(2));
}
