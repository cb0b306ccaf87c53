//! The interactive preview app (egui/eframe on wgpu).
//!
//! * [`state`]: [`AppState`], the scene and the display/render/export
//!   settings as a plain struct, testable without a window; the export's
//!   own settings and progress in `export_state`.
//! * [`sun_place`]: the Sun panel's date, time and place inputs and how
//!   they become the scene's `sun.date_time`, latitude and longitude.
//! * [`readout`]: what the sky view reads off the frame (a pixel's
//!   direction, luminance and colour; the false-colour luminance map).
//! * [`io`]: the file work (HDR panorama and timelapse exports, saving the
//!   view, scene TOML, screenshots) as plain functions taking a path.
//! * [`ui`]: [`SkyApp`], the window's layout and its background work; the
//!   side panel's sections are in `panels` (one file each), the sky image
//!   in `view`, the timing in `timing`, and opening the window
//!   ([`run_app`]) in `window`.
//!
//! Rendering runs on a [`crate::render::service::RenderService`]: every
//! scene change restarts it (a new epoch), and the UI uploads each newly
//! published pass as a texture.

mod export_state;
pub mod io;
mod panels;
pub mod readout;
pub mod state;
pub mod sun_place;
mod timing;
pub mod ui;
mod view;
mod window;

pub use state::{
    AppState, DisplaySettings, ExportSettings, ExportStatus, RenderSettings, SequenceStatus,
    TimelapseSettings, ToneCurve,
};
pub use sun_place::{DatePlace, SunMode};
pub use timing::LatencyStats;
pub use ui::{SkyApp, SpectrumProbe, DEFAULT_PROBE_SAMPLES, SPECTRUM_TITLE};
pub use view::COLOUR_BAR_LABEL;
pub use window::{run_app, NO_DISPLAY_MESSAGE, WINDOW_SIZE};
