//! File work of the preview app, as plain functions taking a path (the UI
//! only asks a dialog for the path and runs these off the UI thread):
//! the HDR panorama and timelapse exports, saving the view, saving and loading scenes, and
//! writing the window screenshot. Every file is written atomically (a
//! temporary file in the target directory, renamed into place), so a
//! failure or a cancel never leaves a half-written file behind.

use std::io::Write as _;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::readout::FalseColourScale;
use super::state::{DisplaySettings, SequenceStatus, ToneCurve};
use crate::export::{FramePattern, Timelapse};
use crate::output::{self, check_writable, replace_file, OutputFormat};
use crate::render::service::Frame;
use crate::scene::Scene;

/// Check that `path` can take an HDR export before rendering: it must end in
/// `.exr`, must not be a directory, and its directory must exist and be
/// writable.
pub fn check_export_path(path: &Path) -> Result<(), String> {
    match OutputFormat::from_path(path) {
        Ok(OutputFormat::Exr) => {}
        Ok(OutputFormat::Png) => {
            return Err(format!(
                "cannot export to '{}': the HDR panorama is an OpenEXR file (.exr)",
                path.display()
            ))
        }
        Err(e) => return Err(e.to_string()),
    }
    check_writable(path)
}

/// How far an export has got, shared with its thread.
#[derive(Debug, Default)]
pub struct ExportProgress {
    /// Completed passes (a timelapse: of all its frames so far, a skipped
    /// frame counting as all of its passes).
    pub passes: AtomicU32,
    /// The frame being rendered or looked at, from 1 (0 for one panorama).
    pub frame: AtomicU32,
    /// Frames written.
    pub written: AtomicU32,
    /// Frames skipped because their file existed.
    pub skipped: AtomicU32,
}

/// Render `scene` (already set to an equirectangular camera, the export size
/// and spp; see [`super::AppState::export_scene`]) into the EXR at `path`,
/// exactly as `skyrender render` does ([`crate::export::render_to_file`]).
/// Blocks; `progress` receives the completed passes, `cancel` stops between
/// rows. Returns the wall-clock time.
pub fn export_panorama(
    scene: &Scene,
    path: &Path,
    cancel: &AtomicBool,
    progress: &AtomicU32,
) -> Result<Duration, String> {
    let start = Instant::now();
    check_export_path(path)?;
    crate::export::render_to_file(scene, path, cancel, |pass, _| {
        progress.store(pass, Ordering::Relaxed);
    })
    .map_err(|e| e.to_string())?;
    Ok(start.elapsed())
}

/// Render the frames of `timelapse` from `base` (an export scene, see
/// [`super::AppState::export_scene`]) one after another into the files
/// `pattern` names (`sky_####.exr`). With `skip_existing`, frames whose file exists are left alone, so
/// an interrupted sequence can be resumed. Each file is written whole or
/// not at all, so a cancel or an error leaves the finished frames and no
/// partial one. Blocks; returns the wall-clock time.
pub fn export_timelapse(
    timelapse: &Timelapse,
    base: &Scene,
    pattern: &Path,
    skip_existing: bool,
    cancel: &AtomicBool,
    progress: &ExportProgress,
) -> Result<Duration, String> {
    let start = Instant::now();
    let files = FramePattern::parse(pattern).ok_or_else(|| {
        format!(
            "invalid timelapse file name '{}': it needs a run of # for the frame number",
            pattern.display()
        )
    })?;
    // Every frame goes to the same folder with the same extension.
    check_export_path(&files.path_for(1))?;
    let frames = timelapse.frames();
    let spp = base.render.spp;
    for frame in 1..=frames {
        if cancel.load(Ordering::Relaxed) {
            return Err(crate::export::ExportError::Cancelled.to_string());
        }
        progress.frame.store(frame, Ordering::Relaxed);
        let done_before = (frame - 1).saturating_mul(spp);
        progress.passes.store(done_before, Ordering::Relaxed);
        let path = files.path_for(frame);
        let fail = |e: &dyn std::fmt::Display| {
            format!("frame {frame} of {frames} ('{}'): {e}", path.display())
        };
        if skip_existing && path.is_file() {
            progress.skipped.fetch_add(1, Ordering::Relaxed);
            continue;
        }
        let scene = timelapse.scene_for(base, frame).map_err(|e| fail(&e))?;
        check_export_path(&path).map_err(|e| fail(&e))?;
        crate::export::render_to_file(&scene, &path, cancel, |pass, _| {
            progress
                .passes
                .store(done_before.saturating_add(pass), Ordering::Relaxed);
        })
        .map_err(|e| fail(&e))?;
        progress.written.fetch_add(1, Ordering::Relaxed);
    }
    progress
        .passes
        .store(frames.saturating_mul(spp), Ordering::Relaxed);
    Ok(start.elapsed())
}

/// A running export (one panorama or a timelapse) on its own thread.
pub struct ExportJob {
    /// Target file (a timelapse: the file name pattern).
    pub path: PathBuf,
    /// Passes in all (a timelapse: of all its frames).
    pub total: u32,
    /// Frames of a timelapse; `None` for one panorama.
    pub frames: Option<u32>,
    progress: Arc<ExportProgress>,
    cancel: Arc<AtomicBool>,
    handle: Option<JoinHandle<Result<Duration, String>>>,
}

impl ExportJob {
    /// Start exporting `scene` to `path` in the background; `on_done` runs
    /// on the export thread when it ends (e.g. to wake the UI).
    pub fn start(
        scene: Scene,
        path: PathBuf,
        on_done: impl FnOnce() + Send + 'static,
    ) -> Result<Self, String> {
        let total = scene.render.spp;
        let thread_path = path.clone();
        Self::spawn(path, total, None, on_done, move |cancel, progress| {
            export_panorama(&scene, &thread_path, cancel, &progress.passes)
        })
    }

    /// Start exporting the frames of `timelapse` from `base` into the files
    /// `pattern` names in the background ([`export_timelapse`]); `on_done`
    /// runs on the export thread when it ends.
    pub fn start_timelapse(
        timelapse: Timelapse,
        base: Scene,
        pattern: PathBuf,
        skip_existing: bool,
        on_done: impl FnOnce() + Send + 'static,
    ) -> Result<Self, String> {
        let frames = timelapse.frames();
        let total = frames.saturating_mul(base.render.spp);
        let thread_pattern = pattern.clone();
        Self::spawn(
            pattern,
            total,
            Some(frames),
            on_done,
            move |cancel, progress| {
                export_timelapse(
                    &timelapse,
                    &base,
                    &thread_pattern,
                    skip_existing,
                    cancel,
                    progress,
                )
            },
        )
    }

    fn spawn(
        path: PathBuf,
        total: u32,
        frames: Option<u32>,
        on_done: impl FnOnce() + Send + 'static,
        work: impl FnOnce(&AtomicBool, &ExportProgress) -> Result<Duration, String> + Send + 'static,
    ) -> Result<Self, String> {
        let progress = Arc::new(ExportProgress::default());
        let cancel = Arc::new(AtomicBool::new(false));
        let (thread_progress, thread_cancel) = (Arc::clone(&progress), Arc::clone(&cancel));
        let handle = std::thread::Builder::new()
            .name("skyrender-export".into())
            .spawn(move || {
                let result = work(&thread_cancel, &thread_progress);
                on_done();
                result
            })
            .map_err(|e| format!("cannot start the export: {e}"))?;
        Ok(Self {
            path,
            total,
            frames,
            progress,
            cancel,
            handle: Some(handle),
        })
    }

    /// Completed passes.
    pub fn done(&self) -> u32 {
        self.progress.passes.load(Ordering::Relaxed)
    }

    /// Where a timelapse stands in its sequence; `None` for one panorama.
    pub fn sequence(&self) -> Option<SequenceStatus> {
        let frames = self.frames?;
        let p = &self.progress;
        Some(SequenceStatus {
            frame: p.frame.load(Ordering::Relaxed),
            frames,
            written: p.written.load(Ordering::Relaxed),
            skipped: p.skipped.load(Ordering::Relaxed),
        })
    }

    /// Ask the export to stop (it ends within one row of rendering).
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// Whether [`Self::cancel`] was called.
    pub fn is_cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// The result once the thread has ended (never blocks): the elapsed time
    /// or the error. `None` while it runs or after the result was taken.
    pub fn try_finish(&mut self) -> Option<Result<Duration, String>> {
        if !self.handle.as_ref()?.is_finished() {
            return None;
        }
        let handle = self.handle.take()?;
        Some(
            handle
                .join()
                .unwrap_or_else(|_| Err("the export thread panicked".into())),
        )
    }
}

impl Drop for ExportJob {
    fn drop(&mut self) {
        // An app closing mid-export stops it; the detached thread then ends
        // without writing anything more.
        self.cancel();
    }
}

/// Tone-map `image` for display: 8-bit sRGB, row-major, 3 bytes a pixel
/// (with `false_colour`, its log luminance in false colour on
/// [`FalseColourScale::of`] the image instead).
pub fn tonemap_rgb8(image: &output::RgbImage, display: &DisplaySettings) -> Vec<u8> {
    if display.false_colour {
        return FalseColourScale::of(image).map(image);
    }
    let scale = display.exposure_ev.exp2();
    let curve: ToneCurve = display.tone_curve;
    image
        .pixels
        .iter()
        .flat_map(|&rgb| curve.map(rgb, scale))
        .collect()
}

/// Save the displayed frame: `.exr` writes the linear HDR image with the same
/// header metadata as the CLI (for `scene`, the preview scene); `.png` writes
/// exactly what is on screen (exposure and tone curve applied).
pub fn save_view(
    path: &Path,
    frame: &Frame,
    scene: &Scene,
    display: &DisplaySettings,
) -> Result<(), String> {
    match OutputFormat::from_path(path).map_err(|e| e.to_string())? {
        OutputFormat::Exr => {
            let metadata = crate::export::image_metadata(
                scene,
                &frame.image,
                frame.spp,
                frame.paths,
                frame.discarded,
            );
            output::write_image(path, &frame.image, &metadata, None).map_err(|e| e.to_string())
        }
        OutputFormat::Png => {
            let rgb = tonemap_rgb8(&frame.image, display);
            let text = [
                ("skyrender:scene".to_owned(), scene.to_toml()),
                (
                    "skyrender:exposure_ev".to_owned(),
                    format!("{:.4}", display.exposure_ev),
                ),
                (
                    "skyrender:tone_curve".to_owned(),
                    format!("{:?}", display.tone_curve),
                ),
            ];
            write_png_bytes(
                path,
                frame.image.width,
                frame.image.height,
                &rgb,
                png::ColorType::Rgb,
                &text,
            )
        }
    }
}

/// Write 8-bit pixels (`Rgb8` or `Rgba8`) as a PNG, atomically.
pub fn write_png_atomic(
    path: &Path,
    width: u32,
    height: u32,
    bytes: &[u8],
    color: image::ExtendedColorType,
) -> Result<(), String> {
    let color = match color {
        image::ExtendedColorType::Rgba8 => png::ColorType::Rgba,
        _ => png::ColorType::Rgb,
    };
    write_png_bytes(path, width, height, bytes, color, &[])
}

/// Write 8-bit sRGB pixels as a PNG with `text` chunks, atomically
/// ([`output::encode_png`]).
fn write_png_bytes(
    path: &Path,
    width: u32,
    height: u32,
    bytes: &[u8],
    color: png::ColorType,
    text: &[(String, String)],
) -> Result<(), String> {
    let fail = |e: &dyn std::fmt::Display| format!("cannot write '{}': {e}", path.display());
    if path.is_dir() {
        return Err(fail(&"it is a directory"));
    }
    replace_file(
        path,
        |e| fail(&e),
        |writer| {
            output::encode_png(writer, width, height, bytes, color, text).map_err(|e| fail(&e))
        },
    )
}

/// Write `scene` as TOML, atomically.
pub fn save_scene(path: &Path, scene: &Scene) -> Result<(), String> {
    let fail = |e: &dyn std::fmt::Display| format!("cannot save scene '{}': {e}", path.display());
    if path.is_dir() {
        return Err(fail(&"it is a directory"));
    }
    replace_file(
        path,
        |e| fail(&e),
        |writer| {
            writer
                .write_all(scene.to_toml().as_bytes())
                .map_err(|e| fail(&e))
        },
    )
}

/// Read and validate a scene TOML.
pub fn load_scene(path: &Path) -> Result<Scene, String> {
    Scene::load(path).map_err(|e| e.to_string())
}

/// `path` with `extension` appended if it has none (dialogs may return a
/// bare name).
pub fn with_default_extension(path: PathBuf, extension: &str) -> PathBuf {
    if path.extension().is_some() {
        path
    } else {
        path.with_extension(extension)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::output::RgbImage;

    fn tiny_frame() -> Frame {
        Frame {
            epoch: 1,
            image: RgbImage {
                width: 2,
                height: 1,
                pixels: vec![[1.0, 2.0, 3.0], [1e4, 1e4, 1e4]],
            },
            spp: 1,
            paths: 2,
            elapsed: Duration::ZERO,
            discarded: 0,
            finished: true,
            model_weight: 0.0,
            coarse_passes: 0,
            noise: None,
        }
    }

    #[test]
    fn export_path_checks() {
        let dir = tempfile::tempdir().unwrap();
        assert!(check_export_path(&dir.path().join("a.exr")).is_ok());
        assert!(check_export_path(&dir.path().join("a.EXR")).is_ok());
        assert!(check_export_path(&dir.path().join("a.png"))
            .unwrap_err()
            .contains(".exr"));
        assert!(check_export_path(&dir.path().join("a")).is_err());
        assert!(check_export_path(&dir.path().join("missing/a.exr")).is_err());
        let as_dir = dir.path().join("d.exr");
        std::fs::create_dir(&as_dir).unwrap();
        assert!(check_export_path(&as_dir)
            .unwrap_err()
            .contains("directory"));
    }

    #[test]
    fn save_view_png_and_exr_and_scene_round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let frame = tiny_frame();
        let scene = Scene::default();
        let display = DisplaySettings::default();
        let png = dir.path().join("v.png");
        save_view(&png, &frame, &scene, &display).unwrap();
        let decoded = image::open(&png).unwrap().to_rgb8();
        assert_eq!(decoded.dimensions(), (2, 1));
        assert_eq!(
            decoded.get_pixel(1, 0).0.to_vec(),
            tonemap_rgb8(&frame.image, &display)[3..]
        );
        let exr = dir.path().join("v.exr");
        save_view(&exr, &frame, &scene, &display).unwrap();
        assert!(std::fs::metadata(&exr).unwrap().len() > 0);
        assert!(save_view(&dir.path().join("v.tif"), &frame, &scene, &display).is_err());
        // A missing folder is named plainly, not through the temporary file.
        for missing in ["no/v.png", "no/v.exr"] {
            let e = save_view(&dir.path().join(missing), &frame, &scene, &display).unwrap_err();
            assert!(!e.contains(".skyrender-"), "{e}");
        }
        let e = save_scene(&dir.path().join("no/s.toml"), &Scene::default()).unwrap_err();
        assert!(e.contains("s.toml") && !e.contains(".skyrender-"), "{e}");

        let toml = dir.path().join("s.toml");
        let mut custom = Scene::default();
        custom.sun.elevation_deg = 12.5;
        save_scene(&toml, &custom).unwrap();
        assert_eq!(load_scene(&toml).unwrap(), custom);
        // Saving over a file keeps its permissions.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt as _;
            let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
            std::fs::set_permissions(&toml, std::fs::Permissions::from_mode(0o744)).unwrap();
            save_scene(&toml, &custom).unwrap();
            std::fs::set_permissions(&png, std::fs::Permissions::from_mode(0o744)).unwrap();
            save_view(&png, &frame, &scene, &display).unwrap();
            assert_eq!((mode(&toml), mode(&png)), (0o744, 0o744));
        }
        assert!(load_scene(&dir.path().join("none.toml")).is_err());
        assert!(save_scene(dir.path(), &custom).is_err());
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names.len(), 3, "no temporary files left: {names:?}");
    }

    #[test]
    fn default_extension() {
        assert_eq!(
            with_default_extension("a".into(), "exr"),
            PathBuf::from("a.exr")
        );
        assert_eq!(
            with_default_extension("a.png".into(), "exr"),
            PathBuf::from("a.png")
        );
    }
}
