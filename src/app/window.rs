//! Opening the preview window: [`run_app`] checks its arguments, finds the
//! display and runs [`SkyApp`] in an `eframe` window; without a display it
//! says what to do instead, in one line.

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::ui::SkyApp;
use crate::scene::Scene;

/// What to do without a window, ending each message about the display.
const HEADLESS_HINT: &str =
    "on a headless machine use `skyrender render --preset midday -o sky.exr`";

/// The line printed when there is no display to open a window on.
pub const NO_DISPLAY_MESSAGE: &str =
    "no display found: the preview app needs a window; on a headless machine use \
     `skyrender render --preset midday -o sky.exr`";

/// The preview window's default size, points.
pub const WINDOW_SIZE: [f32; 2] = [1240.0, 760.0];

/// The display the window goes to, as the environment names it.
fn display_name() -> String {
    ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .filter_map(std::env::var_os)
        .find(|s| !s.is_empty())
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default()
}

/// One short line from the windowing library's error text. winit's OS
/// errors read `os error at <its source file>:<line>: <reason>` (behind
/// eframe's "winit EventLoopError: "): a path into the dependency's source
/// means nothing to a user, so only the reason after it is kept.
fn window_error_reason(text: &str) -> String {
    let line = text.lines().next().unwrap_or_default().trim();
    let reason = match line.rfind(".rs:") {
        Some(i) => line[i + ".rs:".len()..]
            .trim_start_matches(|c: char| c.is_ascii_digit() || c == ':')
            .trim(),
        None => line,
    };
    let mut chars = reason.chars();
    match (chars.next(), chars.next()) {
        // "Failed to open…" reads as a clause after a colon; "X11…" keeps its case.
        (Some(first), Some(second)) if first.is_uppercase() && second.is_lowercase() => {
            first.to_lowercase().chain(reason.chars().skip(1)).collect()
        }
        (Some(_), _) => reason.to_owned(),
        (None, _) => "unknown error".to_owned(),
    }
}

/// The error for a window that could not be opened.
fn window_error(text: &str) -> String {
    format!(
        "cannot open the preview window on display '{}': {}; {HEADLESS_HINT}",
        display_name(),
        window_error_reason(text)
    )
}

/// Whether a window can be opened (on Linux and the BSDs: `DISPLAY` or
/// `WAYLAND_DISPLAY` is set).
fn has_display() -> bool {
    if cfg!(all(unix, not(target_os = "macos"))) {
        ["DISPLAY", "WAYLAND_DISPLAY"]
            .iter()
            .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()))
    } else {
        true
    }
}

/// Open the preview window (wgpu renderer), starting from `preset` or the
/// scene file `scene_file` (default: the `midday` preset). With
/// `screenshot`, save a PNG of the window after `screenshot_after_s` seconds
/// of refining and exit. Every argument is checked before a window opens, so
/// a mistake fails fast with one line, also on a machine without a display.
pub fn run_app(
    preset: Option<&str>,
    scene_file: Option<&Path>,
    screenshot: Option<&Path>,
    screenshot_after_s: f64,
) -> Result<(), String> {
    // `Scene::load` validates, as `skyrender render --scene` does: the same
    // file gives the same message in both.
    let scene = match (preset, scene_file) {
        (Some(_), Some(_)) => {
            return Err("a preset and a scene file cannot be used together".into())
        }
        (None, Some(path)) => Scene::load(path),
        (preset, None) => Scene::preset(preset.unwrap_or("midday")),
    }
    .map_err(|e| e.to_string())?;
    if !(screenshot_after_s.is_finite() && (0.0..=86_400.0).contains(&screenshot_after_s)) {
        return Err(format!(
            "invalid screenshot delay: {screenshot_after_s} is outside the valid range 0 to 86400 s"
        ));
    }
    if let Some(path) = screenshot {
        if !path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("png"))
        {
            return Err(format!(
                "invalid screenshot path '{}': it must end in .png",
                path.display()
            ));
        }
        crate::output::check_writable(path).map_err(|e| format!("invalid screenshot path: {e}"))?;
    }
    if !has_display() {
        return Err(NO_DISPLAY_MESSAGE.into());
    }
    let result = Arc::new(Mutex::new(None));
    let options = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title("skyrender")
            .with_inner_size(WINDOW_SIZE)
            .with_min_inner_size([640.0, 400.0]),
        renderer: eframe::Renderer::Wgpu,
        ..Default::default()
    };
    let plan = screenshot.map(|p| {
        (
            p.to_path_buf(),
            Duration::from_secs_f64(screenshot_after_s),
            Arc::clone(&result),
        )
    });
    eframe::run_native(
        "skyrender",
        options,
        Box::new(move |_cc| {
            let mut app = SkyApp::new(scene);
            if let Some((path, after, result)) = plan {
                app = app.with_screenshot(path, after, result);
            }
            Ok(Box::new(app))
        }),
    )
    .map_err(|e| window_error(&e.to_string()))?;
    if screenshot.is_some() {
        let outcome = result
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .take();
        return outcome
            .unwrap_or_else(|| Err("the window closed before the screenshot was taken".into()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn window_errors_lose_the_dependency_source_path() {
        let winit = "winit EventLoopError: os error at /home/u/.cargo/registry/src/\
                     index.crates.io-1949cf8c6b5b557f/winit-0.30.13/src/platform_impl/\
                     linux/mod.rs:767:30: Failed to open connection to X server";
        assert_eq!(
            window_error_reason(winit),
            "failed to open connection to X server"
        );
        assert_eq!(
            window_error_reason("WGPU error: no suitable adapter\nmore detail"),
            "WGPU error: no suitable adapter"
        );
        assert_eq!(window_error_reason("X11 said no"), "X11 said no");
        assert_eq!(window_error_reason(""), "unknown error");
        let message = window_error(winit);
        assert!(message.starts_with("cannot open the preview window on display '"));
        assert!(message.ends_with(HEADLESS_HINT), "{message}");
        assert!(NO_DISPLAY_MESSAGE.ends_with(HEADLESS_HINT));
    }
}
