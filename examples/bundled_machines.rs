//! Writes the synthetic error tables of the bundled machines that are not the
//! reference machine (`machines/bc-trt/`, `machines/head-table/`,
//! `machines/head-head/`) from `volcomp::machine::synthetic::BUNDLED_MACHINES`.
//!
//!     cargo run --release --example bundled_machines [-- MACHINES_DIR]
//!
//! The test `machine::bundled_machine_tables_are_the_generators` checks that the
//! committed tables are what this writes.
use std::path::PathBuf;
use volcomp::machine::synthetic::BUNDLED_MACHINES;

fn main() -> std::io::Result<()> {
    let dir = std::env::args_os()
        .nth(1)
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("machines"));
    for machine in &BUNDLED_MACHINES {
        let folder = dir.join(machine.name);
        std::fs::create_dir_all(&folder)?;
        for (name, text) in machine.table_files() {
            let path = folder.join(name);
            std::fs::write(&path, text)?;
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}
