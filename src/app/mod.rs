//! The interactive preview app (egui/eframe on wgpu).
//!
//! * [`state`]: [`AppState`], the scene and the display/render/export
//!   settings as a plain struct, testable without a window.
//! * [`io`]: the file work (HDR export, saving the view, scene TOML,
//!   screenshots) as plain functions taking a path.
//! * [`ui`]: [`SkyApp`], the window, and [`run_app`], its entry point.
//!
//! Rendering runs on a [`crate::render::service::RenderService`]: every
//! scene change restarts it (a new epoch), and the UI uploads each newly
//! published pass as a texture.

pub mod io;
pub mod state;
pub mod ui;

pub use state::{
    AppState, DisplaySettings, ExportSettings, ExportStatus, RenderSettings, ToneCurve,
};
pub use ui::{run_app, LatencyStats, SkyApp, NO_DISPLAY_MESSAGE, WINDOW_SIZE};
