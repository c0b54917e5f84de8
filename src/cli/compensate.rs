//! `volcomp compensate`.
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input files.
    pub inputs: Vec<PathBuf>,
}

pub fn run(_args: &Args) -> anyhow::Result<()> {
    Err(super::NotBuilt {
        command: "compensate",
        what: "the G-code / compensation work is not built yet",
    }
    .into())
}
