//! What the command-line test files share: running the binary headless
//! and reading its errors.

// Each test file uses its own share of these.
#![allow(dead_code)]

use std::process::{Command, Output};

/// Runs `skyrender` with `args`, without a display.
pub fn skyrender(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skyrender"))
        .args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run skyrender")
}

/// The run's standard error as text.
pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// Checks a failing run: exit code 2 and one line on standard error that
/// contains every one of `needles` (case-insensitive); returns the line.
pub fn assert_one_line_error(out: &Output, needles: &[&str]) -> String {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
    for needle in needles {
        assert!(
            err.to_lowercase().contains(&needle.to_lowercase()),
            "'{err}' lacks '{needle}'"
        );
    }
    err
}
