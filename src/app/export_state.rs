//! The Export section's state: the panorama's size and samples, the
//! timelapse settings, and the progress of an export under way.

use std::path::PathBuf;
use std::time::Duration;

/// Largest export sample count.
pub const MAX_EXPORT_SPP: u32 = 1 << 16;
/// Widest panorama export: 16384 × 8192, the most pixels a scene may have
/// ([`crate::scene::MAX_PIXELS`]).
pub const MAX_EXPORT_WIDTH: u32 = 16_384;
/// Export panorama sizes offered (width; the height is half of it).
pub const EXPORT_WIDTHS: [u32; 5] = [512, 1024, 2048, 4096, 8192];
/// The noise target an export offers first, percent: the level at which
/// `BENCHMARKS.md` gives a 4096×2048 export's time.
pub const DEFAULT_EXPORT_NOISE_PERCENT: f64 = 1.0;
/// Longest timelapse the app offers, minutes (a week).
pub const MAX_TIMELAPSE_MINUTES: u32 = 7 * 24 * 60;

/// Size and sample count of an exported panorama.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportSettings {
    /// Width in pixels; the height is half of it (equirectangular, 2:1).
    pub width: u32,
    /// Samples per pixel: the most, where a noise target may stop the
    /// export sooner.
    pub spp: u32,
    /// Stop once the estimated noise is at most this many percent
    /// (`render --noise`); `None`: `spp` passes.
    pub noise_percent: Option<f64>,
    /// A sequence of panoramas over time instead of one.
    pub timelapse: TimelapseSettings,
    /// Write every compositing layer beside the image (`render --layers`).
    pub layers: bool,
    /// The fast mode (`render --mode fast`): the sky model corrected by a
    /// Monte Carlo render at an eighth of the size; no layers.
    pub fast: bool,
}

impl Default for ExportSettings {
    fn default() -> Self {
        Self {
            width: 4096,
            spp: 64,
            noise_percent: None,
            timelapse: TimelapseSettings::default(),
            layers: false,
            fast: false,
        }
    }
}

/// A timelapse export: panoramas at evenly spaced times from the Sun
/// panel's date and time on (offered where the Sun is placed by date).
#[derive(Clone, Debug, PartialEq)]
pub struct TimelapseSettings {
    /// Export the sequence rather than one panorama.
    pub enabled: bool,
    /// Time from the first frame to the last, minutes.
    pub duration_min: u32,
    /// Frames in the sequence, first and last included.
    pub frames: u32,
    /// The frames' file name, a run of `#` standing for the frame number
    /// (`sky_####.exr` → `sky_0001.exr`, …).
    pub file_name: String,
    /// Leave frames whose file exists alone (to resume a sequence).
    pub skip_existing: bool,
}

impl Default for TimelapseSettings {
    fn default() -> Self {
        Self {
            enabled: false,
            duration_min: 12 * 60,
            frames: 25,
            file_name: "sky_####.exr".into(),
            skip_existing: false,
        }
    }
}

impl ExportSettings {
    /// Height in pixels (half the width, at least 1).
    pub fn height(&self) -> u32 {
        (self.width / 2).max(1)
    }
}

/// Where a timelapse export stands in its sequence.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct SequenceStatus {
    /// The frame being rendered (the last one looked at once it ended), from 1.
    pub frame: u32,
    /// Frames in the sequence.
    pub frames: u32,
    /// Frames written so far.
    pub written: u32,
    /// Frames skipped because their file existed.
    pub skipped: u32,
}

/// Where the HDR panorama export stands.
#[derive(Clone, Debug, PartialEq, Default)]
pub enum ExportStatus {
    /// No export has been started.
    #[default]
    Idle,
    /// Rendering `done` of `total` passes into `path`.
    Running {
        /// Target file (a timelapse: the file name pattern).
        path: PathBuf,
        /// Completed passes (a timelapse: of all its frames).
        done: u32,
        /// Passes in all (the export spp; a timelapse: times its frames).
        total: u32,
        /// A timelapse's frames.
        sequence: Option<SequenceStatus>,
    },
    /// The file (a timelapse: every frame) was written.
    Finished {
        /// The file written (a timelapse: the file name pattern).
        path: PathBuf,
        /// Wall-clock time of the export.
        elapsed: Duration,
        /// A timelapse's frames.
        sequence: Option<SequenceStatus>,
    },
    /// Cancelled by the user; nothing was written (a timelapse: no
    /// partial frame; the frames finished before are kept).
    Cancelled {
        /// A timelapse's frames.
        sequence: Option<SequenceStatus>,
    },
    /// The export failed; nothing was written (a timelapse: the frames
    /// finished before are kept; the message says how many).
    Failed(String),
}

impl ExportStatus {
    /// An export is in progress.
    pub fn is_running(&self) -> bool {
        matches!(self, Self::Running { .. })
    }
}
