//! Helpers shared by the end-to-end tests of the `rttest` binary.
#![allow(dead_code)]

use std::path::Path;
use std::process::{Command, Output};

use scenes::ScratchDir;

/// A fresh, empty scratch folder for one test of `suite`, removed when the test passes.
pub fn scratch(suite: &str, name: &str) -> ScratchDir {
    ScratchDir::new(&format!("rttest-{suite}"), name).expect("scratch folder")
}

/// Runs `rttest args` in `dir`.
pub fn rttest(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_rttest")).args(args).current_dir(dir).output().expect("run rttest")
}
