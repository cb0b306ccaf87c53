//! The side panel's sections, one per file, in the order they appear:
//! [`PresetsPanel`], [`SunPanel`], [`ObserverPanel`], [`AtmospherePanel`],
//! [`CameraPanel`], [`DisplayPanel`], [`RenderPanel`] and, pinned under
//! them, [`ExportPanel`]; and the window's [`StatusBar`].
//!
//! Each is a small struct borrowing what it shows (mostly the
//! [`AppState`](super::AppState)) with a `ui(&mut self, ui)` that draws it
//! and applies the user's changes through the state's setters. What a
//! section cannot do itself (open a file dialog, cancel the export) it
//! returns as a [`Request`] for the app.

mod atmosphere;
mod camera;
mod display;
mod export;
mod observer;
mod presets;
mod render;
pub mod spectrum;
mod status;
mod sun;

pub use atmosphere::AtmospherePanel;
pub use camera::CameraPanel;
pub use display::DisplayPanel;
pub use export::ExportPanel;
pub use observer::ObserverPanel;
pub use presets::PresetsPanel;
pub use render::RenderPanel;
pub use status::StatusBar;
pub use sun::SunPanel;

use egui::{Color32, Slider};

/// A file dialog the app can open.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dialog {
    /// Where to export the HDR panorama.
    Export,
    /// The folder a timelapse's frames go to.
    TimelapseFolder,
    /// Where to save the view (PNG or EXR).
    SaveView,
    /// Where to save the scene (TOML).
    SaveScene,
    /// A scene to load (TOML).
    LoadScene,
}

/// Something a section asks of the app.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Request {
    /// Open this file dialog.
    Open(Dialog),
    /// Stop the running export.
    CancelExport,
}

/// The colour of error messages.
pub const ERROR_COLOUR: Color32 = Color32::from_rgb(255, 110, 100);

/// A labelled slider with units and a tooltip over `value` (one decimal for
/// wide ranges such as degrees, two otherwise); the new value if the user
/// changed it.
pub fn slider(
    ui: &mut egui::Ui,
    value: f64,
    (lo, hi): (f64, f64),
    text: &str,
    suffix: &str,
    tooltip: &str,
) -> Option<f64> {
    // Only the text is rounded: egui's `max_decimals` would round the value
    // itself, changing the scene just by showing it.
    let decimals = if hi - lo >= 100.0 { 1 } else { 2 };
    let mut v = value;
    let response = ui
        .add(
            Slider::new(&mut v, lo..=hi)
                .text(text)
                .suffix(suffix)
                .custom_formatter(move |v, _| format!("{v:.decimals$}")),
        )
        .on_hover_text(tooltip);
    (response.changed() && v != value).then_some(v)
}
