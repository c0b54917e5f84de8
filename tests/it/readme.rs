//! The README and the help pages as a new user meets them: every shell block
//! of README.md, taken from the file, runs in order in a copy of the bundled
//! files; every example of every `--help` page runs as written.
//!
//! Both run in a temporary folder holding a copy of the bundled `machines/`,
//! `samples/` and `tests/data/laser/` (what a fresh clone has), with the
//! `volcomp` built for these tests first on the `PATH`.
use crate::support::{model_cache, root};
use std::path::{Path, PathBuf};
use std::process::Command;

/// A temporary copy of the bundled files a fresh clone has.
fn fresh_clone() -> tempfile::TempDir {
    let dir = tempfile::tempdir().expect("a temporary folder");
    for bundled in ["machines", "samples", "tests/data/laser"] {
        copy_tree(&root().join(bundled), &dir.path().join(bundled));
    }
    dir
}

fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_tree(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// The folder of the `volcomp` built for these tests.
fn binary_dir() -> PathBuf {
    Path::new(env!("CARGO_BIN_EXE_volcomp"))
        .parent()
        .unwrap()
        .to_path_buf()
}

/// `PATH` with `first` before the system's.
fn path_with(first: &[&Path]) -> std::ffi::OsString {
    let mut dirs: Vec<PathBuf> = first.iter().map(|p| p.to_path_buf()).collect();
    dirs.extend(std::env::split_paths(
        &std::env::var_os("PATH").unwrap_or_default(),
    ));
    std::env::join_paths(dirs).unwrap()
}

/// The shell blocks (```sh) of a Markdown text, each as its lines.
fn shell_blocks(markdown: &str) -> Vec<Vec<String>> {
    let mut blocks = Vec::new();
    let mut current: Option<Vec<String>> = None;
    for line in markdown.lines() {
        match (&mut current, line.trim_start().starts_with("```")) {
            (None, true) if line.trim() == "```sh" => current = Some(Vec::new()),
            (Some(_), true) => blocks.extend(current.take()),
            (Some(block), false) => block.push(line.to_string()),
            _ => {}
        }
    }
    blocks
}

/// `cargo` for the README's own `cargo` lines: `cargo run --release -- ARGS`
/// runs the `volcomp` these tests were built with (the same sources and
/// profile: building it again in the copy would take minutes), `cargo install
/// --locked --path .` puts that binary in `~/.cargo/bin`; anything else fails.
const CARGO_STAND_IN: &str = r#"#!/bin/sh
case "$1 $2 $3" in
  "run --release --") shift 3; exec "$VOLCOMP" "$@";;
  "install --locked --path") mkdir -p "$HOME/.cargo/bin" && cp "$VOLCOMP" "$HOME/.cargo/bin/volcomp";;
  *) echo "the README test's cargo does not run: cargo $*" >&2; exit 2;;
esac
"#;

/// Every shell block of README.md, in order, as a fresh clone runs it
/// (`.ci/run` excepted: it runs this test). A block's comment lines are the
/// output it shows: each must be in what the block printed.
#[test]
fn every_shell_block_of_the_readme_runs_in_order() {
    let readme = std::fs::read_to_string(root().join("README.md")).unwrap();
    let blocks = shell_blocks(&readme);
    assert!(
        blocks.len() >= 5,
        "README.md has {} shell blocks",
        blocks.len()
    );
    let clone = fresh_clone();
    let home = clone.path().join("home");
    let stand_in = clone.path().join("stand-in");
    std::fs::create_dir_all(&home).unwrap();
    std::fs::create_dir_all(&stand_in).unwrap();
    let cargo = stand_in.join("cargo");
    std::fs::write(&cargo, CARGO_STAND_IN).unwrap();
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&cargo, std::fs::Permissions::from_mode(0o755)).unwrap();
    }
    // Not the tests' binary folder: `volcomp` is what `cargo install` put
    // in ~/.cargo/bin.
    let path = path_with(&[&stand_in, &home.join(".cargo/bin")]);
    let mut ran = 0;
    for (i, block) in blocks.iter().enumerate() {
        let script: Vec<&str> = block
            .iter()
            .map(String::as_str)
            .filter(|l| l.trim() != ".ci/run")
            .collect();
        let out = Command::new("bash")
            .args(["-euo", "pipefail", "-c", &script.join("\n")])
            .current_dir(clone.path())
            .env("HOME", &home)
            .env("PATH", &path)
            .env("VOLCOMP", env!("CARGO_BIN_EXE_volcomp"))
            .env("VOLCOMP_MODEL_CACHE", model_cache())
            .output()
            .unwrap();
        let printed = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            out.status.success(),
            "README shell block {} failed ({}):\n{}\n--- printed:\n{printed}",
            i + 1,
            out.status,
            script.join("\n")
        );
        for shown in script.iter().filter_map(|l| l.trim().strip_prefix('#')) {
            let shown = shown.trim();
            assert!(
                printed.contains(shown),
                "README shell block {} shows `{shown}`, which it did not print:\n{printed}",
                i + 1
            );
        }
        ran += script.iter().filter(|l| !l.trim().is_empty()).count();
    }
    // What the walk-through leaves: the installed binary, its completions and
    // manual pages, the diagnosed machine file and the second part.
    for made in [
        "home/.cargo/bin/volcomp",
        "home/.local/share/bash-completion/completions/volcomp",
        "home/.local/share/man/man1/volcomp.1",
        "home/.local/share/man/man1/volcomp-compensate.1",
        "diag/ref-trt-diag.toml",
        "m2.csv",
    ] {
        assert!(clone.path().join(made).is_file(), "{made} was not made");
    }
    assert!(ran > 15, "only {ran} README lines ran");
}

/// `volcomp [PAGE…] --help` at `columns` columns.
fn help_page(page: &[String], columns: usize) -> String {
    let out = crate::support::volcomp()
        .args(page)
        .arg("--help")
        .env("COLUMNS", columns.to_string())
        .output()
        .unwrap();
    assert!(out.status.success(), "{page:?} --help failed");
    String::from_utf8(out.stdout).unwrap()
}

/// The commands a help page lists (its `Commands:` section, `help` aside).
fn commands_of(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| *l != "Commands:")
        .skip(1)
        .take_while(|l| !l.is_empty())
        .filter(|l| l.starts_with("  ") && !l.starts_with("   "))
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(str::to_string)
        .collect()
}

/// Every help page: `volcomp` and its commands, and theirs.
fn help_pages() -> Vec<Vec<String>> {
    let mut pages = vec![Vec::new()];
    let mut i = 0;
    while i < pages.len() {
        let page = pages[i].clone();
        for command in commands_of(&help_page(&page, 1000)) {
            let mut sub = page.clone();
            sub.push(command);
            pages.push(sub);
        }
        i += 1;
    }
    pages
}

/// The lines of a help page's `Examples:` section (its end).
fn examples_of(help: &str) -> Vec<String> {
    help.lines()
        .skip_while(|l| *l != "Examples:")
        .skip(1)
        .map(|l| l.trim().to_string())
        .filter(|l| !l.is_empty())
        .collect()
}

/// Each example is one whole command line whatever the width: the same at 20
/// columns as at 1000, each line a command (none broken in the middle).
#[test]
fn help_examples_print_whole_at_any_width() {
    let pages = help_pages();
    assert!(pages.len() >= 16, "{} help pages", pages.len());
    for page in &pages {
        let wide = examples_of(&help_page(page, 1000));
        assert!(!wide.is_empty(), "volcomp {page:?} --help has no examples");
        for columns in [20, 60, 80] {
            let narrow = examples_of(&help_page(page, columns));
            assert_eq!(narrow, wide, "volcomp {page:?} --help at {columns} columns");
        }
        for line in &wide {
            let first = line.split_whitespace().next().unwrap_or_default();
            assert!(
                ["volcomp", "cat", "cp", "printf"].contains(&first),
                "volcomp {page:?} --help: `{line}` is not a command"
            );
        }
    }
}

/// Every example of every help page runs as written, in order, in a fresh
/// copy of the bundled files (one per page), and succeeds.
#[test]
fn help_examples_run_as_written_on_the_bundled_files() {
    let path = path_with(&[&binary_dir()]);
    let mut ran = 0;
    for page in help_pages() {
        let clone = fresh_clone();
        for example in examples_of(&help_page(&page, 1000)) {
            let out = Command::new("bash")
                .args(["-euo", "pipefail", "-c", &example])
                .current_dir(clone.path())
                .env("PATH", &path)
                .env("VOLCOMP_MODEL_CACHE", model_cache())
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "volcomp {page:?} --help: `{example}` failed ({}):\n{}",
                out.status,
                String::from_utf8_lossy(&out.stderr)
            );
            ran += 1;
        }
    }
    assert!(ran >= 60, "{ran} examples ran");
}

/// `volcomp completions SHELL` and `volcomp man` give what the shells and
/// man read.
#[test]
fn completions_and_manual_pages() {
    for (shell, mark) in [
        ("bash", "complete -F"),
        ("zsh", "#compdef volcomp"),
        ("fish", "complete -c volcomp"),
        ("powershell", "Register-ArgumentCompleter"),
    ] {
        let out = crate::support::volcomp()
            .args(["completions", shell])
            .output()
            .unwrap();
        crate::support::assert_success(&out);
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(text.contains(mark), "{shell}: no `{mark}`");
        assert!(text.contains("compensate") && text.contains("position-only"));
    }
    let dir = tempfile::tempdir().unwrap();
    let out = crate::support::volcomp()
        .args(["man", "-o"])
        .arg(dir.path().join("man1"))
        .output()
        .unwrap();
    crate::support::assert_success(&out);
    let page = std::fs::read_to_string(dir.path().join("man1/volcomp-compensate.1")).unwrap();
    assert!(page.starts_with(".ie") || page.contains(".TH"), "{page}");
    // The examples verbatim, hyphens as minus signs (copyable).
    assert!(page.contains(".SH EXAMPLES\n.nf\n"));
    assert!(page.contains(
        "volcomp compensate machines/ref\\-trt.toml samples/saddle.nc \\-o saddle\\-comp.nc\n"
    ));
    assert!(dir.path().join("man1/volcomp-export-linuxcnc.1").is_file());
}

/// `-q` leaves the data and the warnings; `-v` adds the time.
#[test]
fn quiet_and_verbose() {
    let dir = tempfile::tempdir().unwrap();
    let out_nc = dir.path().join("c.nc");
    let run = |flag: &str| {
        let out = crate::support::volcomp()
            .args([
                flag,
                "compensate",
                "machines/head-table.toml",
                "samples/bc-trt/saddle.nc",
                "-o",
            ])
            .arg(&out_nc)
            .current_dir(root())
            .output()
            .unwrap();
        crate::support::assert_success(&out);
        (
            String::from_utf8_lossy(&out.stdout).into_owned(),
            String::from_utf8_lossy(&out.stderr).into_owned(),
        )
    };
    let (stdout, stderr) = run("-q");
    assert_eq!(stdout, "");
    assert!(
        stderr.starts_with(
            "warning: samples/bc-trt/saddle.nc: its header says it was written for machine BC-TRT"
        ),
        "{stderr}"
    );
    let (stdout, stderr) = run("-v");
    assert!(stdout.contains("max correction"), "{stdout}");
    assert!(stderr.contains("volcomp: done in"), "{stderr}");
}
