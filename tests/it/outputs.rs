//! Issue 25 items 1–3: no output overwrites an input or another output, all
//! the outputs of a command or none, symbolic links written through, read-only
//! outputs refused, a file size limit (SIGXFSZ) handled like SIGTERM.
use crate::support::{assert_success, root, volcomp};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Output;

/// A folder holding a copy of the reference machine (`m.toml`, `ref-trt/`),
/// the saddle program (`part.nc`, and `part2.nc`), its plan (`plan.csv`), a
/// tool table (`tools.tbl`), a fitted model (`model.json`) and a simulated
/// measurement (`meas.csv`): the inputs every command's outputs are tried
/// against.
struct Workshop {
    dir: tempfile::TempDir,
}

impl Workshop {
    fn new() -> Workshop {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::copy(root().join("machines/ref-trt.toml"), d.join("m.toml")).unwrap();
        std::fs::create_dir(d.join("ref-trt")).unwrap();
        for axis in ["x", "y", "z", "a", "c"] {
            let name = format!("ref-trt/{axis}.csv");
            std::fs::copy(root().join("machines").join(&name), d.join(&name)).unwrap();
        }
        std::fs::copy(root().join("samples/saddle.nc"), d.join("part.nc")).unwrap();
        std::fs::copy(root().join("samples/saddle.nc"), d.join("part2.nc")).unwrap();
        std::fs::copy(root().join("samples/saddle-plan.csv"), d.join("plan.csv")).unwrap();
        std::fs::copy(root().join("samples/saddle.tbl"), d.join("tools.tbl")).unwrap();
        std::fs::hard_link(d.join("part.nc"), d.join("hard.nc")).unwrap();
        std::fs::copy(d.join("m.toml"), d.join("saddle.tbl")).unwrap();
        std::fs::create_dir(d.join("plots")).unwrap();
        let w = Workshop { dir };
        assert_success(&w.run(&["fit", "m.toml", "--report", "model.json"]));
        assert_success(&w.run(&[
            "simulate", "m.toml", "part.nc", "plan.csv", "-o", "meas.csv",
        ]));
        w
    }

    fn path(&self) -> &Path {
        self.dir.path()
    }

    fn run(&self, args: &[&str]) -> Output {
        volcomp()
            .args(args)
            .current_dir(self.path())
            .output()
            .unwrap()
    }

    /// Every file below the folder and its bytes.
    fn files(&self) -> BTreeMap<PathBuf, Vec<u8>> {
        fn walk(dir: &Path, into: &mut BTreeMap<PathBuf, Vec<u8>>) {
            for entry in std::fs::read_dir(dir).unwrap() {
                let path = entry.unwrap().path();
                if path.is_dir() {
                    walk(&path, into);
                } else {
                    into.insert(path.clone(), std::fs::read(&path).unwrap_or_default());
                }
            }
        }
        let mut files = BTreeMap::new();
        walk(self.path(), &mut files);
        files
    }
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Every command's output options, against its inputs and against each
/// other: each run is a usage error (exit 2) naming both files, and nothing in
/// the folder changes (no file written, replaced or left behind).
#[test]
fn every_output_option_is_checked_against_inputs_and_other_outputs() {
    let w = Workshop::new();
    // (command line, the two names the message must give)
    let cases: &[(&[&str], [&str; 2])] = &[
        // compensate
        (
            &[
                "compensate",
                "m.toml",
                "part.nc",
                "-o",
                "out.nc",
                "--report",
                "out.nc",
            ],
            ["-o out.nc", "--report out.nc"],
        ),
        (
            &[
                "compensate",
                "m.toml",
                "part.nc",
                "-o",
                "out.nc",
                "--report",
                "part.nc",
            ],
            ["--report part.nc", "the program part.nc"],
        ),
        (
            &[
                "compensate",
                "m.toml",
                "part.nc",
                "-o",
                "out.nc",
                "--report",
                "hard.nc",
            ],
            ["--report hard.nc", "the program part.nc"],
        ),
        (
            &[
                "compensate",
                "m.toml",
                "part.nc",
                "--in-place",
                "--report",
                "part.nc",
            ],
            ["(--in-place)", "--report part.nc"],
        ),
        (
            &[
                "compensate",
                "m.toml",
                "part.nc",
                "-o",
                "out.nc",
                "--report",
                "ref-trt/x.csv",
            ],
            ["--report ref-trt/x.csv", "the error table ref-trt/x.csv"],
        ),
        (
            &["compensate", "m.toml", "part.nc", "-o", "m.toml"],
            ["-o m.toml", "the machine file m.toml"],
        ),
        (
            &[
                "compensate",
                "m.toml",
                "part.nc",
                "-o",
                "tools.tbl",
                "--tools",
                "tools.tbl",
            ],
            ["-o tools.tbl", "the tool table (--tools) tools.tbl"],
        ),
        (
            &[
                "compensate",
                "m.toml",
                "part.nc",
                "--model",
                "model.json",
                "-o",
                "out.nc",
                "--report",
                "model.json",
            ],
            ["--report model.json", "the model (--model) model.json"],
        ),
        // check
        (
            &["check", "part.nc", "--targets", "part.nc"],
            ["--targets part.nc", "the program part.nc"],
        ),
        (
            &["check", "part.nc", "--flatten", "-o", "part.nc"],
            ["-o part.nc", "the program part.nc"],
        ),
        (
            &[
                "check",
                "part.nc",
                "--machine",
                "m.toml",
                "--targets",
                "ref-trt/z.csv",
            ],
            ["--targets ref-trt/z.csv", "the error table ref-trt/z.csv"],
        ),
        // predict
        (
            &[
                "predict", "m.toml", "part.nc", "--plan", "plan.csv", "--report", "plan.csv",
            ],
            ["--report plan.csv", "the plan plan.csv"],
        ),
        (
            &[
                "predict", "m.toml", "part.nc", "--report", "p.json", "--html", "p.json",
            ],
            ["--report p.json", "--html p.json"],
        ),
        (
            &["predict", "m.toml", "part.nc", "--html", "part.nc"],
            ["--html part.nc", "the program part.nc"],
        ),
        // simulate
        (
            &["simulate", "m.toml", "part.nc", "plan.csv", "-o", "part.nc"],
            ["-o part.nc", "the program part.nc"],
        ),
        (
            &[
                "simulate", "m.toml", "part.nc", "plan.csv", "-o", "plan.csv",
            ],
            ["-o plan.csv", "the plan plan.csv"],
        ),
        (
            &[
                "simulate",
                "m.toml",
                "part.nc",
                "plan.csv",
                "-o",
                "m2.csv",
                "--dump-contexts",
                "m2.csv",
            ],
            ["-o m2.csv", "--dump-contexts m2.csv"],
        ),
        // diagnose
        (
            &[
                "diagnose", "m.toml", "part.nc", "meas.csv", "--report", "meas.csv",
            ],
            ["--report meas.csv", "the measurement meas.csv"],
        ),
        (
            &[
                "diagnose",
                "m.toml",
                "part.nc",
                "meas.csv",
                "--report",
                "d.json",
                "--followup-program",
                "meas.nc",
            ],
            [
                "(--followup-program, .csv) meas.csv",
                "the measurement meas.csv",
            ],
        ),
        (
            &[
                "diagnose",
                "m.toml",
                "part.nc",
                "meas.csv",
                "--report",
                "d.json",
                "--followup-program",
                "part.nc",
            ],
            ["--followup-program part.nc", "the program part.nc"],
        ),
        (
            &[
                "diagnose",
                "m.toml",
                "part.nc",
                "meas.csv",
                "--report",
                "d.json",
                "--followup-program",
                "f.nc",
                "--html",
                "f.csv",
            ],
            ["--html f.csv", "(--followup-program, .csv) f.csv"],
        ),
        (
            &[
                "diagnose", "m.toml", "part.nc", "meas.csv", "--report", "d.json", "--html",
                "d.json",
            ],
            ["--report d.json", "--html d.json"],
        ),
        (
            &[
                "diagnose",
                "m.toml",
                "part.nc",
                "meas.csv",
                "--report",
                "d.json",
                "--dump-contexts",
                "meas.csv",
            ],
            ["--dump-contexts meas.csv", "the measurement meas.csv"],
        ),
        // fit
        (
            &["fit", "m.toml", "--report", "ref-trt/y.csv"],
            ["--report ref-trt/y.csv", "the error table ref-trt/y.csv"],
        ),
        (
            &[
                "fit",
                "ref-trt/x.csv",
                "--axis",
                "X",
                "--report",
                "ref-trt/x.csv",
            ],
            ["--report ref-trt/x.csv", "the input ref-trt/x.csv"],
        ),
        (
            &[
                "fit",
                "m.toml",
                "--plot",
                "plots",
                "--report",
                "plots/EXX.svg",
            ],
            ["--report plots/EXX.svg", "(--plot) plots/EXX.svg"],
        ),
        // map
        (
            &["map", "m.toml", "--out", "r.svg", "--report", "r.svg"],
            ["--out r.svg", "--report r.svg"],
        ),
        (
            &["map", "m.toml", "--out", "ref-trt/c.csv"],
            ["--out ref-trt/c.csv", "the error table ref-trt/c.csv"],
        ),
        // diff
        (
            &["diff", "part.nc", "part2.nc", "--report", "part2.nc"],
            ["--report part2.nc", "program B part2.nc"],
        ),
        (
            &[
                "diff",
                "part.nc",
                "part2.nc",
                "--report",
                "tools.tbl",
                "--tools",
                "tools.tbl",
            ],
            ["--report tools.tbl", "(--tools) tools.tbl"],
        ),
        // sample: a machine file that has a sample's name, in the out folder
        (
            &[
                "sample",
                "saddle",
                "--machine",
                "saddle.tbl",
                "--out-dir",
                ".",
            ],
            [
                "the sample file ./saddle.tbl",
                "the machine file saddle.tbl",
            ],
        ),
    ];
    let before = w.files();
    let mut failures = Vec::new();
    for (args, [first, second]) in cases {
        let out = w.run(args);
        let err = stderr(&out);
        let named = err.contains(first) && err.contains(second);
        if out.status.code() != Some(2) || !named {
            failures.push(format!(
                "volcomp {}: exit {:?}, expected 2 naming `{first}` and `{second}`: {err}",
                args.join(" "),
                out.status.code()
            ));
        }
        let after = w.files();
        if after != before {
            let changed: Vec<_> = after
                .iter()
                .filter(|(p, b)| before.get(*p) != Some(b))
                .map(|(p, _)| p.display().to_string())
                .collect();
            failures.push(format!(
                "volcomp {}: the folder changed: {changed:?}",
                args.join(" ")
            ));
            return assert!(failures.is_empty(), "{}", failures.join("\n"));
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
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

/// A second output that fails (a folder that is missing; a device that is
/// full, found only while writing, after the program was written to its
/// temporary file) leaves the first output as it was: all outputs or none.
#[cfg(unix)]
#[test]
fn outputs_are_written_all_or_none() {
    let w = Workshop::new();
    std::fs::write(w.path().join("out.nc"), "old program\n").unwrap();
    // A folder that cannot be made (a file in its way) is refused before
    // anything is computed; a device that is full fails while writing.
    for report in ["part.nc/comp.json", "/dev/full"] {
        let out = w.run(&[
            "compensate",
            "m.toml",
            "part.nc",
            "-o",
            "out.nc",
            "--report",
            report,
        ]);
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        assert!(stderr(&out).contains(report), "{}", stderr(&out));
        assert_eq!(
            std::fs::read_to_string(w.path().join("out.nc")).unwrap(),
            "old program\n",
            "--report {report}"
        );
        assert!(temp_files(w.path()).is_empty());
    }
    // diagnose: the follow-up program, its plan and the report; the HTML
    // report fails last (a full device).
    let out = w.run(&[
        "diagnose",
        "m.toml",
        "part.nc",
        "meas.csv",
        "--report",
        "d.json",
        "--followup-program",
        "f.nc",
        "--html",
        "/dev/full",
    ]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    for name in ["d.json", "f.nc", "f.csv"] {
        assert!(!w.path().join(name).exists(), "{name} was written");
    }
    assert!(temp_files(w.path()).is_empty());
    // And when everything can be written, everything is.
    let out = w.run(&[
        "compensate",
        "m.toml",
        "part.nc",
        "-o",
        "out.nc",
        "--report",
        "comp.json",
    ]);
    assert_success(&out);
    assert!(
        std::fs::read_to_string(w.path().join("out.nc"))
            .unwrap()
            .contains("volcomp-stamp")
    );
    assert!(w.path().join("comp.json").exists());
}

/// `-o link` writes through the link: its target is replaced, the link stays
/// a link. A link to nothing is refused (as `cp` does).
#[cfg(unix)]
#[test]
fn a_symbolic_link_output_is_written_through() {
    let w = Workshop::new();
    std::fs::create_dir(w.path().join("real")).unwrap();
    std::fs::write(w.path().join("real/out.nc"), "old\n").unwrap();
    std::os::unix::fs::symlink("real/out.nc", w.path().join("link.nc")).unwrap();
    let out = w.run(&["compensate", "m.toml", "part.nc", "-o", "link.nc"]);
    assert_success(&out);
    let link = w.path().join("link.nc");
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    let written = std::fs::read_to_string(w.path().join("real/out.nc")).unwrap();
    assert!(written.contains("volcomp-stamp"), "{written}");
    assert!(temp_files(w.path()).is_empty());
    assert!(temp_files(&w.path().join("real")).is_empty());
    // A dangling link.
    std::os::unix::fs::symlink("nowhere/x.nc", w.path().join("dangling.nc")).unwrap();
    let out = w.run(&["check", "part.nc", "--targets", "dangling.nc"]);
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(
        stderr(&out)
            .contains("dangling.nc is a symbolic link to nowhere/x.nc, which does not exist"),
        "{}",
        stderr(&out)
    );
    assert!(!w.path().join("nowhere").exists());
}

/// A read-only output (mode 0444) is refused before anything is computed,
/// by its mode bits: also when the tests run as root (who could write it).
#[cfg(unix)]
#[test]
fn a_read_only_output_is_refused() {
    use std::os::unix::fs::PermissionsExt;
    let w = Workshop::new();
    let protected = w.path().join("protected.json");
    std::fs::write(&protected, "keep\n").unwrap();
    std::fs::set_permissions(&protected, std::fs::Permissions::from_mode(0o444)).unwrap();
    for args in [
        &[
            "compensate",
            "m.toml",
            "part.nc",
            "-o",
            "out.nc",
            "--report",
            "protected.json",
        ][..],
        &["fit", "m.toml", "--report", "protected.json"][..],
        &["check", "part.nc", "--targets", "protected.json"][..],
    ] {
        let out = w.run(args);
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        assert!(
            stderr(&out).contains("protected.json is read-only (mode 0444)"),
            "{}",
            stderr(&out)
        );
        assert_eq!(std::fs::read_to_string(&protected).unwrap(), "keep\n");
        assert!(!w.path().join("out.nc").exists());
    }
}

/// A file size limit (`ulimit -f`): the write is stopped by SIGXFSZ, handled
/// like SIGTERM: the temporary file is removed, the exit is not 0, the old
/// output stays.
#[cfg(unix)]
#[test]
fn a_file_size_limit_leaves_no_temporary_file() {
    let w = Workshop::new();
    std::fs::write(w.path().join("out.nc"), "old\n").unwrap();
    // 64 blocks of 512 bytes: far less than the 210 kB program.
    let out = std::process::Command::new("sh")
        .arg("-c")
        .arg("ulimit -f 64 && exec \"$0\" compensate m.toml part.nc -o out.nc")
        .arg(env!("CARGO_BIN_EXE_volcomp"))
        .env("VOLCOMP_MODEL_CACHE", crate::support::model_cache())
        .current_dir(w.path())
        .output()
        .unwrap();
    assert!(!out.status.success(), "{}", stderr(&out));
    assert!(
        temp_files(w.path()).is_empty(),
        "{:?}",
        temp_files(w.path())
    );
    assert_eq!(
        std::fs::read_to_string(w.path().join("out.nc")).unwrap(),
        "old\n"
    );
}

/// Every option of every command that names a file or folder, from clap's
/// command tree: (command path, option id). Paths are `PathBuf` options and
/// positionals, and any option whose name says it writes (`out`, `output`,
/// `report`, `html`, `plot`, `write`, `dump`, `program`, `targets`).
fn path_options() -> Vec<(String, String)> {
    fn walk(cmd: &clap::Command, path: &str, into: &mut Vec<(String, String)>) {
        for arg in cmd.get_arguments() {
            let id = arg.get_id().as_str();
            let is_path = arg.get_value_parser().type_id()
                == clap::builder::ValueParser::path_buf().type_id();
            let long = arg.get_long().unwrap_or_default();
            let writes_by_name = [
                "out", "output", "report", "html", "plot", "write", "dump", "program", "targets",
            ]
            .iter()
            .any(|w| long.contains(w));
            if (is_path || writes_by_name) && arg.get_num_args().is_none_or(|n| n.takes_values()) {
                into.push((path.to_string(), id.to_string()));
            }
        }
        for sub in cmd.get_subcommands() {
            let name = if path.is_empty() {
                sub.get_name().to_string()
            } else {
                format!("{path} {}", sub.get_name())
            };
            walk(sub, &name, into);
        }
    }
    let mut all = Vec::new();
    walk(&volcomp::command_line(), "", &mut all);
    all
}

/// One option that writes a file: its command, its option id (clap's), a
/// command line that names an input (or an existing file it must not replace)
/// as that output, and the two names the refusal must give.
struct Writer {
    command: &'static str,
    option: &'static str,
    args: &'static [&'static str],
    names: [&'static str; 2],
}

/// Every option that writes a file, with a run that points it at an input:
/// each must be refused before anything is computed (exit 2) with the folder
/// untouched. A new writing option that is not listed here fails
/// [`every_path_option_is_classified`].
const WRITING_OPTIONS: &[Writer] = &[
    Writer {
        command: "fit",
        option: "report",
        args: &["fit", "m.toml", "--report", "ref-trt/y.csv"],
        names: ["--report ref-trt/y.csv", "the error table ref-trt/y.csv"],
    },
    Writer {
        command: "fit",
        option: "plot",
        args: &["fit", "EXX.svg", "--axis", "X", "--plot", "."],
        names: ["(--plot) ./EXX.svg", "the input EXX.svg"],
    },
    Writer {
        command: "map",
        option: "out",
        args: &["map", "m.toml", "--out", "ref-trt/c.csv"],
        names: ["--out ref-trt/c.csv", "the error table ref-trt/c.csv"],
    },
    Writer {
        command: "map",
        option: "report",
        args: &["map", "m.toml", "--out", "r.svg", "--report", "m.toml"],
        names: ["--report m.toml", "the machine file m.toml"],
    },
    Writer {
        command: "check",
        option: "targets",
        args: &["check", "part.nc", "--targets", "part.nc"],
        names: ["--targets part.nc", "the program part.nc"],
    },
    Writer {
        command: "check",
        option: "output",
        args: &["check", "part.nc", "--flatten", "-o", "hard.nc"],
        names: ["-o hard.nc", "the program part.nc"],
    },
    Writer {
        command: "compensate",
        option: "output",
        args: &[
            "compensate",
            "m.toml",
            "part.nc",
            "-o",
            "tools.tbl",
            "--tools",
            "tools.tbl",
        ],
        names: ["-o tools.tbl", "the tool table (--tools) tools.tbl"],
    },
    Writer {
        command: "compensate",
        option: "report",
        args: &[
            "compensate",
            "m.toml",
            "part.nc",
            "-o",
            "o.nc",
            "--report",
            "part.nc",
        ],
        names: ["--report part.nc", "the program part.nc"],
    },
    Writer {
        command: "predict",
        option: "report",
        args: &[
            "predict", "m.toml", "part.nc", "--plan", "plan.csv", "--report", "plan.csv",
        ],
        names: ["--report plan.csv", "the plan plan.csv"],
    },
    Writer {
        command: "predict",
        option: "html",
        args: &["predict", "m.toml", "part.nc", "--html", "part.nc"],
        names: ["--html part.nc", "the program part.nc"],
    },
    Writer {
        command: "predict",
        option: "csv",
        args: &[
            "predict", "m.toml", "part.nc", "--plan", "plan.csv", "--csv", "plan.csv",
        ],
        names: ["--csv plan.csv", "the plan plan.csv"],
    },
    Writer {
        command: "diff",
        option: "report",
        args: &["diff", "part.nc", "part2.nc", "--report", "part2.nc"],
        names: ["--report part2.nc", "program B part2.nc"],
    },
    Writer {
        command: "simulate",
        option: "output",
        args: &[
            "simulate", "m.toml", "part.nc", "plan.csv", "-o", "plan.csv",
        ],
        names: ["-o plan.csv", "the plan plan.csv"],
    },
    Writer {
        command: "simulate",
        option: "dump_contexts",
        args: &[
            "simulate",
            "m.toml",
            "part.nc",
            "plan.csv",
            "-o",
            "s.csv",
            "--dump-contexts",
            "part.nc",
        ],
        names: ["--dump-contexts part.nc", "the program part.nc"],
    },
    Writer {
        command: "diagnose",
        option: "report",
        args: &[
            "diagnose", "m.toml", "part.nc", "meas.csv", "--report", "meas.csv",
        ],
        names: ["--report meas.csv", "the measurement meas.csv"],
    },
    Writer {
        command: "diagnose",
        option: "html",
        args: &[
            "diagnose", "m.toml", "part.nc", "meas.csv", "--report", "d.json", "--html", "m.toml",
        ],
        names: ["--html m.toml", "the machine file m.toml"],
    },
    Writer {
        command: "diagnose",
        option: "dump_contexts",
        args: &[
            "diagnose",
            "m.toml",
            "part.nc",
            "meas.csv",
            "--report",
            "d.json",
            "--dump-contexts",
            "meas.csv",
        ],
        names: ["--dump-contexts meas.csv", "the measurement meas.csv"],
    },
    Writer {
        command: "diagnose",
        option: "followup_program",
        args: &[
            "diagnose",
            "m.toml",
            "part.nc",
            "meas.csv",
            "--report",
            "d.json",
            "--followup-program",
            "part.nc",
        ],
        names: ["--followup-program part.nc", "the program part.nc"],
    },
    Writer {
        command: "diagnose",
        option: "write_machine",
        args: &[
            "diagnose",
            "m.toml",
            "part.nc",
            "meas.csv",
            "--report",
            "d.json",
            "--write-machine",
            "m.toml",
        ],
        names: ["--write-machine m.toml", "the machine file m.toml"],
    },
    Writer {
        command: "import-laser",
        option: "output",
        args: &["import-laser", "runs.csv", "--axis", "X", "-o", "runs.csv"],
        names: ["-o runs.csv", "the laser file runs.csv"],
    },
    Writer {
        command: "import-laser",
        option: "report",
        args: &[
            "import-laser",
            "runs.csv",
            "--axis",
            "X",
            "-o",
            "x.csv",
            "--report",
            "runs-link.csv",
        ],
        names: ["--report runs-link.csv", "the laser file runs.csv"],
    },
    Writer {
        command: "export linuxcnc",
        option: "output",
        args: &["export", "linuxcnc", "m.toml", "-o", "existing"],
        names: ["existing/README.txt", "--force"],
    },
    Writer {
        command: "export linuxcnc",
        option: "residual_machine",
        args: &[
            "export",
            "linuxcnc",
            "m.toml",
            "-o",
            "new",
            "--residual-machine",
            "m.toml",
        ],
        names: ["(-o) m.toml", "the machine file m.toml"],
    },
    Writer {
        command: "export tables",
        option: "output",
        args: &["export", "tables", "m.toml", "-o", "ref-trt"],
        names: ["ref-trt/x.csv", "the error table ref-trt/x.csv"],
    },
    Writer {
        command: "sample",
        option: "out_dir",
        args: &[
            "sample",
            "saddle",
            "--machine",
            "saddle.tbl",
            "--out-dir",
            ".",
        ],
        names: [
            "the sample file ./saddle.tbl",
            "the machine file saddle.tbl",
        ],
    },
];

/// The options that name files read (never written).
const READING_OPTIONS: &[(&str, &str)] = &[
    ("fit", "input"),
    ("error", "machine"),
    ("error", "poses"),
    ("map", "machine"),
    ("check", "machine"),
    ("predict", "plan"),
    ("diff", "a"),
    ("diff", "b"),
    ("simulate", "plan"),
    ("simulate", "followup"),
    ("diagnose", "measured"),
    ("diagnose", "followup"),
    ("sample", "machine"),
];

/// Writing options of commands that read no file (`man -o DIR` writes the
/// manual pages): no input they could replace, so [`WRITING_OPTIONS`]'s test
/// has nothing to point them at; they still go through the output check.
const WRITING_WITHOUT_INPUTS: &[(&str, &str)] = &[("man", "output")];

/// The options every command that reads a machine, a program or both shares:
/// all read.
const SHARED_READING: &[&str] = &[
    "machine_file",
    "model",
    "model_cache",
    "program",
    "var",
    "subroutine_path",
    "tools",
];

/// Every writing option of [`WRITING_OPTIONS`], pointed at an input (or an
/// existing file of an export folder): refused before anything is computed,
/// exit 2, both files named, nothing in the folder changed.
#[test]
fn every_writing_option_refuses_an_input() {
    let w = Workshop::new();
    std::fs::copy(
        root().join("tests/data/laser/x-long.csv"),
        w.path().join("runs.csv"),
    )
    .unwrap();
    #[cfg(unix)]
    std::os::unix::fs::symlink("runs.csv", w.path().join("runs-link.csv")).unwrap();
    // A table whose name is the plot `fit --plot .` writes of it.
    std::fs::copy(w.path().join("ref-trt/x.csv"), w.path().join("EXX.svg")).unwrap();
    std::fs::create_dir(w.path().join("existing")).unwrap();
    std::fs::write(w.path().join("existing/README.txt"), "mine\n").unwrap();
    let before = w.files();
    let mut failures = Vec::new();
    for writer in WRITING_OPTIONS {
        let out = w.run(writer.args);
        let err = stderr(&out);
        let [first, second] = writer.names;
        if out.status.code() != Some(2) || !(err.contains(first) && err.contains(second)) {
            failures.push(format!(
                "{} {}: volcomp {}: exit {:?}, expected 2 naming `{first}` and `{second}`: {err}",
                writer.command,
                writer.option,
                writer.args.join(" "),
                out.status.code()
            ));
        }
        if w.files() != before {
            failures.push(format!(
                "volcomp {}: the folder changed",
                writer.args.join(" ")
            ));
            break;
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

/// Every option naming a path is either a writing option (listed, and tried
/// against the inputs) or a reading one: a new one cannot be added without
/// saying which.
#[test]
fn every_path_option_is_classified() {
    let unlisted: Vec<String> = path_options()
        .into_iter()
        .filter(|(c, o)| {
            let writes = WRITING_OPTIONS
                .iter()
                .any(|w| w.command == c && w.option == o);
            let reads = READING_OPTIONS.iter().any(|(rc, ro)| rc == c && ro == o)
                || SHARED_READING.contains(&o.as_str());
            let writes_alone = WRITING_WITHOUT_INPUTS
                .iter()
                .any(|(wc, wo)| wc == c && wo == o);
            !writes && !reads && !writes_alone
        })
        .map(|(c, o)| format!("(\"{c}\", \"{o}\"),"))
        .collect();
    assert!(
        unlisted.is_empty(),
        "options naming a path in neither WRITING_OPTIONS nor READING_OPTIONS:\n{}",
        unlisted.join("\n")
    );
}

/// One rule for output folders (issue 39): a missing folder is made when the
/// outputs are written (`diagnose --write-machine diag/x.toml`, `import-laser
/// --report nodir/r.json`), and removed again when the command fails before
/// its outputs are in place; a folder that cannot be made (a file in its way)
/// is refused before anything is computed, leaving every other output as it
/// was.
#[cfg(unix)]
#[test]
fn missing_output_folders_are_made_and_removed_on_failure() {
    let w = Workshop::new();
    std::fs::copy(
        root().join("tests/data/laser/x-long.csv"),
        w.path().join("runs.csv"),
    )
    .unwrap();
    // Made.
    let out = w.run(&[
        "diagnose",
        "m.toml",
        "part.nc",
        "meas.csv",
        "--report",
        "diag/d.json",
        "--write-machine",
        "diag/deeper/m-diag.toml",
    ]);
    assert_success(&out);
    assert!(w.path().join("diag/deeper/m-diag.toml").is_file());
    // The written machine names its tables from its own folder.
    assert_success(&w.run(&["fit", "diag/deeper/m-diag.toml"]));
    std::fs::write(w.path().join("table.csv"), "old\n").unwrap();
    let out = w.run(&[
        "import-laser",
        "runs.csv",
        "--axis",
        "X",
        "-o",
        "table.csv",
        "--report",
        "nodir/r.json",
    ]);
    assert_success(&out);
    assert!(w.path().join("nodir/r.json").is_file());
    // A report that cannot be written: -o untouched, no folder left.
    std::fs::write(w.path().join("table.csv"), "old\n").unwrap();
    for report in ["m.toml/r.json", "/dev/full"] {
        let out = w.run(&[
            "import-laser",
            "runs.csv",
            "--axis",
            "X",
            "-o",
            "new/table.csv",
            "--report",
            report,
        ]);
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        assert!(!w.path().join("new").exists(), "--report {report}");
        let out = w.run(&[
            "import-laser",
            "runs.csv",
            "--axis",
            "X",
            "-o",
            "table.csv",
            "--report",
            report,
        ]);
        assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
        assert_eq!(
            std::fs::read_to_string(w.path().join("table.csv")).unwrap(),
            "old\n"
        );
    }
    assert!(
        stderr(&w.run(&["fit", "m.toml", "--report", "m.toml/r.json"]))
            .contains("m.toml is not a folder")
    );
    assert!(temp_files(w.path()).is_empty());
}

/// `export` writes into a folder: an existing file there is not replaced
/// without `--force`; with it, or into a new folder, the export is written.
#[test]
fn export_does_not_replace_files_without_force() {
    let w = Workshop::new();
    std::fs::create_dir(w.path().join("lcnc")).unwrap();
    std::fs::write(w.path().join("lcnc/README.txt"), "my notes\n").unwrap();
    let out = w.run(&["export", "linuxcnc", "m.toml", "-o", "lcnc"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
    assert!(stderr(&out).contains("lcnc/README.txt"), "{}", stderr(&out));
    assert_eq!(
        w.files()
            .keys()
            .filter(|p| p.starts_with(w.path().join("lcnc")))
            .count(),
        1
    );
    assert_success(&w.run(&["export", "linuxcnc", "m.toml", "-o", "lcnc", "--force"]));
    assert_ne!(
        std::fs::read_to_string(w.path().join("lcnc/README.txt")).unwrap(),
        "my notes\n"
    );
    assert_success(&w.run(&["export", "tables", "m.toml", "-o", "fitted/new"]));
    assert!(w.path().join("fitted/new/x.csv").is_file());
    let out = w.run(&["export", "tables", "m.toml", "-o", "fitted/new"]);
    assert_eq!(out.status.code(), Some(2), "{}", stderr(&out));
}

/// The model cache opens only regular files: a cache file that is a link
/// (to a file, to `/dev/zero`) or a named pipe is a miss, never followed nor
/// waited on; the model is stored under a new name and renamed over it, so a
/// link's target is never written.
#[cfg(unix)]
#[test]
fn the_model_cache_opens_only_regular_files() {
    let w = Workshop::new();
    let run = || {
        let out = w.run(&[
            "compensate",
            "m.toml",
            "part.nc",
            "-o",
            "o.nc",
            "--model-cache",
            "cache",
        ]);
        assert_success(&out);
    };
    run();
    let cached: Vec<PathBuf> = std::fs::read_dir(w.path().join("cache"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    assert_eq!(cached.len(), 1, "{cached:?}");
    let file = &cached[0];
    std::fs::write(w.path().join("victim.txt"), "keep\n").unwrap();
    let replace = |make: &dyn Fn(&Path)| {
        std::fs::remove_file(file).unwrap();
        make(file);
    };
    // A link to another file: not written through.
    replace(&|f| std::os::unix::fs::symlink(w.path().join("victim.txt"), f).unwrap());
    run();
    assert_eq!(
        std::fs::read_to_string(w.path().join("victim.txt")).unwrap(),
        "keep\n"
    );
    assert!(
        std::fs::symlink_metadata(file)
            .unwrap()
            .file_type()
            .is_file()
    );
    // A link to an endless device, then a named pipe: neither read nor waited on.
    replace(&|f| std::os::unix::fs::symlink("/dev/zero", f).unwrap());
    run();
    assert!(
        std::fs::symlink_metadata(file)
            .unwrap()
            .file_type()
            .is_file()
    );
    replace(&|f| {
        let status = std::process::Command::new("mkfifo")
            .arg(f)
            .status()
            .unwrap();
        assert!(status.success());
    });
    run();
    assert!(
        std::fs::symlink_metadata(file)
            .unwrap()
            .file_type()
            .is_file()
    );
    // And the stored model is used.
    run();
}
