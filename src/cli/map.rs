//! `volcomp map`.
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input files.
    pub inputs: Vec<PathBuf>,
}

pub fn run(_args: &Args) -> anyhow::Result<()> {
    Err(super::NotBuilt {
        command: "map",
        what: "the machine model is not built yet",
    }
    .into())
}
