//! What the tests of the `backlash` binary share: running it as a user does, and reading what
//! it writes.

use std::process::{Command, Output};

/// The `backlash` binary run with `args`: its status and what it wrote.
pub fn backlash(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_backlash"))
        .args(args)
        .output()
        .expect("the backlash binary runs")
}

/// Output bytes as text (the binary writes UTF-8).
pub fn text(bytes: &[u8]) -> &str {
    std::str::from_utf8(bytes).expect("UTF-8 output")
}
