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

/// The stdout of a `--json` run: one JSON object per line.
pub fn json_lines(o: &Output) -> Vec<serde_json::Value> {
    String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| serde_json::from_str(l).expect("one JSON object per line"))
        .collect()
}
