//! The `packet-render` binary that Cargo built for this test run.

use std::process::{Command, Output};

/// Path of the binary (Cargo sets it for integration tests).
pub const BIN: &str = env!("CARGO_BIN_EXE_packet-render");

/// A command for the binary, to add arguments, environment or stdin to.
pub fn bin() -> Command {
    Command::new(BIN)
}

/// Runs the binary with `args` and waits for it.
pub fn run(args: &[&str]) -> Output {
    bin().args(args).output().expect("binary runs")
}
