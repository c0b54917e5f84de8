//! `volcomp` binary: a thin shell around [`volcomp::cli`].
fn main() {
    std::process::exit(volcomp::cli::main());
}
