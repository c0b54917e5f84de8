//! `volcomp fit`.
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input files.
    pub inputs: Vec<PathBuf>,
}

pub fn run(_args: &Args) -> anyhow::Result<()> {
    Err(super::NotBuilt {
        command: "fit",
        what: "the SMEM fitting is not built yet",
    }
    .into())
}
