//! `volcomp` binary: a thin shell around [`volcomp::run_command_line`].
fn main() {
    std::process::exit(volcomp::run_command_line());
}
