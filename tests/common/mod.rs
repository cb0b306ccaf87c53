//! What the test files share: running the binary headless and reading
//! its errors, and (`estimate`) the estimator tests' statistics.

// Each test file uses its own share of these.
#![allow(dead_code)]

pub mod estimate;

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

/// Runs `skyrender` with `args` and checks that it succeeded (the
/// failure's message is its standard error).
pub fn skyrender_ok(args: &[&str]) -> Output {
    let out = skyrender(args);
    assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    out
}

/// Renders the scene file `scene` at 8×4 pixels, 1 sample per pixel, to
/// `image`: enough to see whether a scene renders or is refused.
pub fn render_small(scene: &std::path::Path, image: &std::path::Path) -> Output {
    skyrender(&[
        "render",
        "--scene",
        scene.to_str().unwrap(),
        "--width",
        "8",
        "--height",
        "4",
        "--spp",
        "1",
        "-o",
        image.to_str().unwrap(),
    ])
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

/// The luminance (cd/m², Rec.709 weights) of every pixel of an RGB EXR,
/// row-major, and the image's width. Pixels are placed by the position the
/// reader gives: it decodes blocks of rows in parallel and hands pixels
/// over in no fixed order.
pub fn exr_luminance(path: &std::path::Path) -> (usize, Vec<f64>) {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| (size.width(), vec![f64::NAN; size.width() * size.height()]),
        |(width, pixels): &mut (usize, Vec<f64>),
         position: exr::prelude::Vec2<usize>,
         (r, g, b, _): (f32, f32, f32, f32)| {
            pixels[position.y() * *width + position.x()] =
                f64::from(0.2126 * r + 0.7152 * g + 0.0722 * b);
        },
    )
    .expect("read the EXR");
    image.layer_data.channel_data.pixels
}

/// `amount` (an aerosol amount) nudged by 0.1–0.2 % by the clock's
/// nanoseconds: an atmosphere whose sky-model tables no earlier test or
/// run has made, in memory or on disk.
pub fn fresh_haze(amount: f64) -> f64 {
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .unwrap()
        .subsec_nanos();
    amount * (1.001 + 1e-12 * f64::from(nanos))
}
