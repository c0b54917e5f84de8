//! `volcomp simulate`.
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input files.
    pub inputs: Vec<PathBuf>,
}

pub fn run(_args: &Args) -> anyhow::Result<()> {
    Err(super::NotBuilt {
        command: "simulate",
        what: "the sim-to-real diagnosis is not built yet",
    }
    .into())
}
