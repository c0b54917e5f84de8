//! `volcomp completions` and `volcomp man`: the shell's completions and the
//! manual pages, made from the command line's own definition.
use anyhow::Context;
use std::path::{Path, PathBuf};

pub const COMPLETIONS_EXAMPLES: &str = "\
  volcomp completions bash > volcomp.bash
  volcomp completions zsh > _volcomp
  volcomp completions fish > volcomp.fish
  volcomp completions powershell > volcomp.ps1";

const COMPLETIONS_HELP: &str = "\
Installed for one user: bash reads ~/.local/share/bash-completion/completions/volcomp, zsh \
a file _volcomp in a folder of $fpath, fish ~/.config/fish/completions/volcomp.fish; \
PowerShell runs volcomp.ps1 from $PROFILE. The README's \"Installing\" section has the \
commands.";

pub const MAN_EXAMPLES: &str = "\
  volcomp man > volcomp.1
  volcomp man -o man   # volcomp.1, volcomp-compensate.1, volcomp-export-linuxcnc.1 …";

const MAN_HELP: &str = "\
With -o DIR, writes volcomp.1 and a page per command (volcomp-compensate.1, \
volcomp-export-linuxcnc.1 …) into DIR, creating it when missing. A folder of MANPATH \
(~/.local/share/man/man1 for one user) makes them `man volcomp-compensate`.";

/// A shell `volcomp completions` writes for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ShellName {
    Bash,
    Zsh,
    Fish,
    Powershell,
}

#[derive(Debug, clap::Args)]
#[command(after_help = COMPLETIONS_HELP)]
pub struct CompletionsArgs {
    /// The shell.
    #[arg(value_enum)]
    pub shell: ShellName,
}

#[derive(Debug, clap::Args)]
#[command(after_help = MAN_HELP)]
pub struct ManArgs {
    /// Write every page into this folder (created when missing) instead of
    /// volcomp.1 on standard output.
    #[arg(short, long, value_name = "DIR")]
    pub output: Option<PathBuf>,
}

pub fn completions(args: &CompletionsArgs) -> anyhow::Result<()> {
    use clap_complete::Shell;
    let shell = match args.shell {
        ShellName::Bash => Shell::Bash,
        ShellName::Zsh => Shell::Zsh,
        ShellName::Fish => Shell::Fish,
        ShellName::Powershell => Shell::PowerShell,
    };
    let mut text = Vec::new();
    clap_complete::generate(shell, &mut super::command(), "volcomp", &mut text);
    super::stdout_text(&String::from_utf8_lossy(&text))?;
    Ok(())
}

pub fn man(args: &ManArgs) -> anyhow::Result<()> {
    let mut cmd = super::command().disable_help_subcommand(true);
    cmd.build();
    let mut pages = Vec::new();
    man_pages(&cmd, "", &mut pages)?;
    match &args.output {
        None => {
            let (_, page) = pages.pop().context("no manual page")?;
            super::stdout_text(&page)?;
        }
        Some(dir) => {
            if crate::io::is_stdio(dir) {
                return Err(super::UsageError(
                    "-o names a folder; `-` cannot hold several pages (leave -o out for volcomp.1 on standard output)".into(),
                )
                .into());
            }
            let mut files = super::common::CommandFiles::new();
            for (name, _) in &pages {
                files = files.output("the manual page", Some(&dir.join(name)));
            }
            files.check()?;
            let outputs = crate::io::OutputSet::begin();
            for (name, page) in &pages {
                crate::io::write_file_atomic(&dir.join(name), page.as_bytes())?;
            }
            outputs.commit()?;
            super::common::say(
                false,
                &format!(
                    "wrote {} manual pages into {}",
                    pages.len(),
                    Path::new(dir).display()
                ),
            )?;
        }
    }
    Ok(())
}

/// The page of `cmd` (at `path`, as [`super::examples`] names it) and of its
/// commands, the page of `cmd` itself last: (file name, roff).
fn man_pages(
    cmd: &clap::Command,
    path: &str,
    pages: &mut Vec<(String, String)>,
) -> anyhow::Result<()> {
    for sub in cmd.get_subcommands().filter(|s| !s.is_hide_set()) {
        let sub_path = if path.is_empty() {
            sub.get_name().to_string()
        } else {
            format!("{path} {}", sub.get_name())
        };
        man_pages(sub, &sub_path, pages)?;
    }
    let man = clap_mangen::Man::new(cmd.clone());
    let mut roff = Vec::new();
    man.render(&mut roff).context("rendering a manual page")?;
    let mut page = String::from_utf8_lossy(&roff).into_owned();
    if let Some(examples) = super::examples(path) {
        page.push_str(".SH EXAMPLES\n.nf\n");
        for line in super::example_lines(examples) {
            page.push_str(&roff_literal(line));
            page.push('\n');
        }
        page.push_str(".fi\n");
    }
    pages.push((man.get_filename(), page));
    Ok(())
}

/// One line of literal text in roff: backslashes and hyphens escaped (a bare
/// `-` prints as a typographic hyphen a shell does not read as a minus), and
/// a leading `.` or `'` kept from being read as a request.
fn roff_literal(line: &str) -> String {
    let mut out = String::with_capacity(line.len() + 8);
    if line.starts_with(['.', '\'']) {
        out.push_str("\\&");
    }
    for c in line.chars() {
        match c {
            '\\' => out.push_str("\\e"),
            '-' => out.push_str("\\-"),
            _ => out.push(c),
        }
    }
    out
}
