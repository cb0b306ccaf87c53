//! The preview app's window: controls on the left, the progressively
//! path-traced sky in the middle, a status bar at the bottom.
//!
//! [`SkyApp::show`] lays out the window from the side panel's sections
//! (`panels`), the sky view (`view`) and the status bar; `eframe` calls
//! it through [`eframe::App::ui`] and the UI tests through `egui_kittest`.
//! The UI thread never waits: rendering runs on the [`RenderService`]'s
//! thread, exports, saves, loads, file dialogs and spectrum probes on
//! threads of their own that report back through a channel.

use std::path::PathBuf;
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use super::io::{self, ExportJob};
use super::panels::spectrum::{probe_wavelengths_nm, SpectrumPanel};
pub use super::panels::spectrum::{SpectrumProbe, DEFAULT_PROBE_SAMPLES, SPECTRUM_TITLE};
use super::panels::{
    AtmospherePanel, CameraPanel, Dialog, DisplayPanel, ExportPanel, ObserverPanel, PresetsPanel,
    RenderPanel, Request, StatusBar, SunPanel,
};
use super::readout::FalseColourScale;
use super::state::{AppState, DisplaySettings, ExportStatus, EXPOSURE_RANGE};
use super::timing::{LatencyStats, RenderClock};
use super::view::SkyView;
use crate::render::service::{Frame, RenderService};
use crate::render::{Renderer, SpectralEstimate};
use crate::scene::Scene;

/// While the latest restart has not produced its first frame (usually a
/// draft) yet, further scene changes wait up to this long before restarting
/// again, so that dragging a slider shows a new image at the rate drafts
/// complete instead of cancelling every one before it finishes.
const RESTART_COALESCE: Duration = Duration::from_millis(150);
/// A scene change first renders a one-sample draft at a reduced size when a
/// full-size pass would take longer than this at the measured speed.
const DRAFT_SECONDS: f64 = 0.04;
/// The draft has at least this many pixels.
const MIN_DRAFT_PIXELS: f64 = 1024.0;
/// Speed assumed before the first frame is measured, paths per second.
const INITIAL_PATHS_PER_SECOND: f64 = 150_000.0;
/// How often the UI polls the render service while a first frame is due
/// (and at most how often while refining).
const RENDER_POLL: Duration = Duration::from_millis(15);
/// At least how often the UI polls while refining; in between it polls a few
/// times per pass, so that redrawing the window (which is not free on a
/// software renderer) leaves the CPU to the path tracer.
const REFINE_POLL_MAX: Duration = Duration::from_millis(100);
/// The status bar says that a new atmosphere's sky-model tables are being
/// made once the first frame has waited this long on them: tables kept
/// take a millisecond to look up, and a notice for that would flicker.
const TABLES_NOTICE_AFTER: Duration = Duration::from_millis(250);
/// How often the UI refreshes while an export or a file task runs.
const TASK_POLL: Duration = Duration::from_millis(100);
/// Results that background threads send to the UI.
enum TaskResult {
    /// A dialog closed with this path (`None`: cancelled).
    Picked(Dialog, Option<PathBuf>),
    /// A scene file was read.
    SceneLoaded(PathBuf, Result<Box<Scene>, String>),
    /// A file (view, scene, screenshot) was written, or not.
    Saved(&'static str, PathBuf, Result<(), String>),
    /// The spectrum probe number `.0` finished.
    Spectrum(u64, Result<Vec<SpectralEstimate>, String>),
}

/// `--screenshot`: save the window after a delay and close it.
struct ScreenshotPlan {
    path: PathBuf,
    after: Duration,
    started: Option<Instant>,
    requested: bool,
    result: Arc<Mutex<Option<Result<(), String>>>>,
}

/// The preview app.
pub struct SkyApp {
    state: AppState,
    service: RenderService,
    /// The epoch of the latest `start`, and the scene it renders.
    started_epoch: u64,
    started_scene: Scene,
    /// When the current epoch started, until its first frame is shown.
    pending_since: Option<Instant>,
    /// When the latest change happened, until its first full-size frame is shown.
    full_pending_since: Option<Instant>,
    /// The full-size scene to render once the draft on its way is shown.
    queued_full: Option<Scene>,
    /// Measured rendering speed (smoothed), paths per second.
    paths_per_second: f64,
    latency: LatencyStats,
    full_latency: LatencyStats,
    clock: RenderClock,
    /// The latest full-size frame's epoch, spp and elapsed time, to time
    /// the next pass against; `None` after a pause or resume, whose pass
    /// would include the wait.
    pass_start: Option<(u64, u32, Duration)>,
    /// How long the latest full-size sample pass took.
    pass_time: Option<Duration>,
    applied_paused: bool,
    /// The epoch whose render error was last reported (each is shown once).
    reported_error_epoch: u64,
    /// The frame on screen and the preview scene it was rendered from.
    frame: Option<Arc<Frame>>,
    frame_is_draft: bool,
    frame_scene: Scene,
    texture: Option<egui::TextureHandle>,
    /// Display settings the texture was made with; `None` forces an upload.
    uploaded: Option<DisplaySettings>,
    export_job: Option<ExportJob>,
    tasks_tx: Sender<TaskResult>,
    tasks_rx: Receiver<TaskResult>,
    dialog_open: bool,
    tasks_running: usize,
    ctx: Option<egui::Context>,
    screenshot: Option<ScreenshotPlan>,
    /// The scale of the false-colour texture, when the texture is one.
    false_scale: Option<FalseColourScale>,
    /// The latest spectrum probe, shown in a panel right of the view.
    spectrum: Option<SpectrumProbe>,
    probe_samples: u32,
    probes_started: u64,
}

impl SkyApp {
    /// An app previewing `scene`; rendering starts with the first frame drawn.
    pub fn new(scene: Scene) -> Self {
        Self::with_state(AppState::new(scene))
    }

    /// An app with the given state (e.g. custom render settings for tests).
    pub fn with_state(mut state: AppState) -> Self {
        state.mark_dirty();
        let (tasks_tx, tasks_rx) = channel();
        let started_scene = state.preview_scene();
        Self {
            state,
            service: RenderService::new(),
            started_epoch: 0,
            frame_scene: started_scene.clone(),
            started_scene,
            pending_since: None,
            full_pending_since: None,
            queued_full: None,
            paths_per_second: INITIAL_PATHS_PER_SECOND,
            latency: LatencyStats::default(),
            full_latency: LatencyStats::default(),
            clock: RenderClock::default(),
            pass_start: None,
            pass_time: None,
            applied_paused: false,
            reported_error_epoch: 0,
            frame: None,
            frame_is_draft: false,
            texture: None,
            uploaded: None,
            export_job: None,
            tasks_tx,
            tasks_rx,
            dialog_open: false,
            tasks_running: 0,
            ctx: None,
            screenshot: None,
            false_scale: None,
            spectrum: None,
            probe_samples: DEFAULT_PROBE_SAMPLES,
            probes_started: 0,
        }
    }

    /// Samples per wavelength of the spectrum probes (at least 2, for a
    /// standard error).
    pub fn set_probe_samples(&mut self, samples: u32) {
        self.probe_samples = samples.max(2);
    }

    /// The latest spectrum probe.
    pub fn spectrum(&self) -> Option<&SpectrumProbe> {
        self.spectrum.as_ref()
    }

    /// The spectrum probe was computed for another scene than the current one.
    pub fn spectrum_is_stale(&self) -> bool {
        self.spectrum
            .as_ref()
            .is_some_and(|p| &p.scene != self.state.scene())
    }

    /// Compute the spectral radiance of the current scene towards
    /// (`azimuth_deg`, `elevation_deg`) in the background; it replaces the
    /// spectrum shown.
    pub fn probe_spectrum(&mut self, azimuth_deg: f64, elevation_deg: f64) {
        let scene = self.state.scene().clone();
        self.probes_started += 1;
        let id = self.probes_started;
        self.spectrum = Some(SpectrumProbe {
            azimuth_deg,
            elevation_deg,
            scene: scene.clone(),
            id,
            result: None,
        });
        let samples = self.probe_samples;
        self.spawn_task(move || {
            let wavelengths = probe_wavelengths_nm();
            let result = Renderer::new(&scene)
                .map(|r| r.probe_radiance(90.0 - elevation_deg, azimuth_deg, &wavelengths, samples))
                .map_err(|e| e.to_string());
            TaskResult::Spectrum(id, result)
        });
    }

    /// Take a screenshot of the window into `path` (PNG) `after` the first
    /// frame, then close the window; `result` receives the outcome.
    pub(crate) fn with_screenshot(
        mut self,
        path: PathBuf,
        after: Duration,
        result: Arc<Mutex<Option<Result<(), String>>>>,
    ) -> Self {
        self.screenshot = Some(ScreenshotPlan {
            path,
            after,
            started: None,
            requested: false,
            result,
        });
        self
    }

    /// The app state.
    pub fn state(&self) -> &AppState {
        &self.state
    }

    /// The app state, to change settings as the controls do.
    pub fn state_mut(&mut self) -> &mut AppState {
        &mut self.state
    }

    /// The render service's current epoch (it grows on every restart).
    pub fn service_epoch(&self) -> u64 {
        self.service.epoch()
    }

    /// The frame on screen.
    pub fn frame(&self) -> Option<&Arc<Frame>> {
        self.frame.as_ref()
    }

    /// Time from each scene change to its first frame on screen (a quick
    /// draft where the full size would be slow).
    pub fn latency(&self) -> LatencyStats {
        self.latency
    }

    /// Time from each scene change to its first full-size frame on screen.
    pub fn full_latency(&self) -> LatencyStats {
        self.full_latency
    }

    /// Render time of the image on screen: since the latest scene change,
    /// draft included, pauses not counted, up to the last pass.
    pub fn render_time(&self) -> Duration {
        self.clock.read(Instant::now())
    }

    /// An export, save, load or dialog is still running.
    pub fn busy(&self) -> bool {
        self.export_job.is_some() || self.tasks_running > 0 || self.dialog_open
    }

    fn wake(&self) -> impl Fn() + Send + 'static {
        let ctx = self.ctx.clone();
        move || {
            if let Some(ctx) = &ctx {
                ctx.request_repaint();
            }
        }
    }

    /// Run `work` on a thread of its own; its result comes back through the
    /// task channel.
    fn spawn_task(&mut self, work: impl FnOnce() -> TaskResult + Send + 'static) {
        let tx = self.tasks_tx.clone();
        let wake = self.wake();
        let spawned = std::thread::Builder::new()
            .name("skyrender-task".into())
            .spawn(move || {
                // The receiver lives as long as the app; a closed app drops the result.
                let _ = tx.send(work());
                wake();
            });
        match spawned {
            Ok(_) => self.tasks_running += 1,
            Err(e) => self.state.last_error = Some(format!("cannot start a background task: {e}")),
        }
    }

    /// Open a file dialog off the UI thread; the path comes back as a task result.
    fn open_dialog(&mut self, dialog: Dialog) {
        if self.dialog_open {
            return;
        }
        self.dialog_open = true;
        self.spawn_task(move || {
            let picked = match dialog {
                Dialog::Export => rfd::FileDialog::new()
                    .set_title("Export HDR panorama")
                    .add_filter("OpenEXR", &["exr"])
                    .set_file_name("sky.exr")
                    .save_file()
                    .map(|p| io::with_default_extension(p, "exr")),
                Dialog::TimelapseFolder => rfd::FileDialog::new()
                    .set_title("Export timelapse into folder")
                    .pick_folder(),
                Dialog::SaveView => rfd::FileDialog::new()
                    .set_title("Save view")
                    .add_filter("PNG (as shown)", &["png"])
                    .add_filter("OpenEXR (linear HDR)", &["exr"])
                    .set_file_name("view.png")
                    .save_file()
                    .map(|p| io::with_default_extension(p, "png")),
                Dialog::SaveScene => rfd::FileDialog::new()
                    .set_title("Save scene")
                    .add_filter("Scene (TOML)", &["toml"])
                    .set_file_name("scene.toml")
                    .save_file()
                    .map(|p| io::with_default_extension(p, "toml")),
                Dialog::LoadScene => rfd::FileDialog::new()
                    .set_title("Load scene")
                    .add_filter("Scene (TOML)", &["toml"])
                    .pick_file(),
            };
            TaskResult::Picked(dialog, picked)
        });
    }

    /// Export the HDR panorama of the current scene to `path` in the
    /// background (what the export dialog leads to). Errors, including an
    /// unusable path, end up in the state's `export_status` and `last_error`.
    pub fn start_export(&mut self, path: PathBuf) {
        if self.export_job.is_some() {
            self.state.last_error = Some("an export is already running".into());
            return;
        }
        let scene = self.state.export_scene();
        let job = ExportJob::start(scene, path, self.wake());
        self.run_export(job);
    }

    /// Export the timelapse the export settings describe (see
    /// [`AppState::timelapse`]) into the files `pattern` names
    /// (`…/sky_####.exr`) in the background, frame after frame, skipping
    /// frames whose file exists if the settings say so. Errors end up in
    /// the state's `export_status` and `last_error`.
    pub fn start_timelapse(&mut self, pattern: PathBuf) {
        if self.export_job.is_some() {
            self.state.last_error = Some("an export is already running".into());
            return;
        }
        let timelapse = match self.state.timelapse() {
            Ok(timelapse) => timelapse,
            Err(e) => return self.fail_export(e),
        };
        let base = self.state.export_scene();
        let skip_existing = self.state.export.timelapse.skip_existing;
        let job = ExportJob::start_timelapse(timelapse, base, pattern, skip_existing, self.wake());
        self.run_export(job);
    }

    /// Keep a started export job, or report why it did not start.
    fn run_export(&mut self, job: Result<ExportJob, String>) {
        match job {
            Ok(job) => {
                self.state.export_status = ExportStatus::Running {
                    path: job.path.clone(),
                    done: 0,
                    total: job.total,
                    sequence: job.sequence(),
                };
                self.export_job = Some(job);
            }
            Err(e) => self.fail_export(e),
        }
    }

    /// Stop a running export; nothing more is written (a timelapse keeps
    /// the frames it finished, and no partial one).
    pub fn cancel_export(&self) {
        if let Some(job) = &self.export_job {
            job.cancel();
        }
    }

    fn fail_export(&mut self, message: String) {
        self.state.last_error = Some(message.clone());
        self.state.export_status = ExportStatus::Failed(message);
    }

    /// Save the frame on screen to `path` (`.png` as shown, `.exr` linear) in the background.
    pub fn save_view_to(&mut self, path: PathBuf) {
        let Some(frame) = self.frame.clone() else {
            self.state.last_error = Some("nothing to save yet: no frame has been rendered".into());
            return;
        };
        let scene = self.frame_scene.clone();
        let display = self.state.display.clone();
        self.spawn_task(move || {
            let result = io::save_view(&path, &frame, &scene, &display);
            TaskResult::Saved("view", path, result)
        });
    }

    /// Save the scene as TOML to `path` in the background.
    pub fn save_scene_to(&mut self, path: PathBuf) {
        let scene = self.state.scene().clone();
        self.spawn_task(move || {
            let result = io::save_scene(&path, &scene);
            TaskResult::Saved("scene", path, result)
        });
    }

    /// Load a scene TOML from `path` in the background; it replaces the
    /// current scene if it is valid.
    pub fn load_scene_from(&mut self, path: PathBuf) {
        self.spawn_task(move || {
            let result = io::load_scene(&path).map(Box::new);
            TaskResult::SceneLoaded(path, result)
        });
    }

    /// Handle what background threads reported.
    fn poll_tasks(&mut self) {
        while let Ok(result) = self.tasks_rx.try_recv() {
            self.tasks_running = self.tasks_running.saturating_sub(1);
            match result {
                TaskResult::Spectrum(id, result) => {
                    if let Some(probe) = self.spectrum.as_mut().filter(|p| p.id == id) {
                        probe.result = Some(result);
                    }
                }
                TaskResult::Picked(dialog, path) => {
                    self.dialog_open = false;
                    let Some(path) = path else { continue };
                    match dialog {
                        Dialog::Export => self.start_export(path),
                        Dialog::TimelapseFolder => {
                            let name = self.state.export.timelapse.file_name.trim().to_owned();
                            self.start_timelapse(path.join(name));
                        }
                        Dialog::SaveView => self.save_view_to(path),
                        Dialog::SaveScene => self.save_scene_to(path),
                        Dialog::LoadScene => self.load_scene_from(path),
                    }
                }
                TaskResult::SceneLoaded(path, Ok(scene)) => {
                    if self.state.set_scene(*scene) {
                        self.state.message = Some(format!("loaded '{}'", path.display()));
                    }
                }
                TaskResult::SceneLoaded(_, Err(e)) => {
                    self.state.last_error = Some(e);
                }
                TaskResult::Saved(what, path, result) => {
                    match result {
                        Ok(()) => {
                            self.state.message =
                                Some(format!("saved {what} to '{}'", path.display()));
                        }
                        Err(e) => self.state.last_error = Some(e),
                    }
                    // `--screenshot` ends the run either way: `run_app`
                    // reports the outcome and sets the exit status.
                    if what == "screenshot" {
                        if let Some(ctx) = &self.ctx {
                            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
                        }
                    }
                }
            }
        }
        if let Some(job) = &mut self.export_job {
            if let ExportStatus::Running { done, sequence, .. } = &mut self.state.export_status {
                *done = job.done();
                *sequence = job.sequence();
            }
            if let Some(result) = job.try_finish() {
                let cancelled = job.is_cancelled();
                let path = job.path.clone();
                let sequence = job.sequence();
                self.export_job = None;
                match result {
                    Ok(elapsed) => {
                        self.state.message = Some(match sequence {
                            Some(s) => format!(
                                "exported {} frames to '{}' ({} skipped)",
                                s.written,
                                path.display(),
                                s.skipped
                            ),
                            None => format!("exported '{}'", path.display()),
                        });
                        self.state.export_status = ExportStatus::Finished {
                            path,
                            elapsed,
                            sequence,
                        };
                    }
                    Err(_) if cancelled => {
                        self.state.export_status = ExportStatus::Cancelled { sequence };
                    }
                    Err(e) => match sequence {
                        Some(s) if s.written > 0 => self.fail_export(format!(
                            "{e}; the {} frames written before are kept",
                            s.written
                        )),
                        _ => self.fail_export(e),
                    },
                }
            }
        }
    }

    /// Restart the render service if the scene changed, apply pause/resume,
    /// and take a new frame if one was published.
    fn poll_render(&mut self, ctx: &egui::Context) {
        let now = Instant::now();
        let paused = self.state.render().paused;
        if paused != self.applied_paused {
            self.service.set_paused(paused);
            self.applied_paused = paused;
            self.pass_start = None;
            if paused {
                self.clock.pause(now);
            } else {
                self.clock.resume(now);
            }
        }
        let waiting = self
            .pending_since
            .is_some_and(|since| now.duration_since(since) < RESTART_COALESCE);
        if self.state.is_dirty() && (!waiting || paused || self.frame.is_none()) {
            self.state.take_dirty();
            self.start_render(now);
        }
        if self.reported_error_epoch != self.started_epoch {
            if let Some(error) = self.service.error() {
                self.state.last_error = Some(error);
                self.reported_error_epoch = self.started_epoch;
                self.clock.stop(now);
            }
        }
        if let Some(frame) = self.service.latest() {
            let is_new = frame.epoch == self.started_epoch
                && self
                    .frame
                    .as_ref()
                    .is_none_or(|f| f.epoch != frame.epoch || f.spp != frame.spp);
            if is_new {
                self.take_frame(frame, now);
            }
        }
        if let Some(frame) = &self.frame {
            if self.uploaded.as_ref() != Some(&self.state.display) {
                let bytes = io::tonemap_rgb8(&frame.image, &self.state.display);
                let size = [frame.image.width as usize, frame.image.height as usize];
                let image = egui::ColorImage::from_rgb(size, &bytes);
                match &mut self.texture {
                    Some(texture) => texture.set(image, egui::TextureOptions::LINEAR),
                    None => {
                        self.texture = Some(ctx.load_texture(
                            "sky-preview",
                            image,
                            egui::TextureOptions::LINEAR,
                        ));
                    }
                }
                self.uploaded = Some(self.state.display.clone());
                // The same scale `tonemap_rgb8` used, for the colour bar.
                self.false_scale = self
                    .state
                    .display
                    .false_colour
                    .then(|| FalseColourScale::of(&frame.image));
            }
        }
        if self.is_rendering() {
            ctx.request_repaint_after(self.poll_interval());
        }
        if self.busy() {
            ctx.request_repaint_after(TASK_POLL);
        }
    }

    /// Start rendering the current preview scene. If one pass of it would
    /// take longer than [`DRAFT_SECONDS`] at the measured speed, a quick
    /// one-sample draft at a reduced size goes first, and the full-size
    /// render starts as soon as the draft is on screen.
    fn start_render(&mut self, now: Instant) {
        let full = self.state.preview_scene();
        let (width, height) = (f64::from(full.render.width), f64::from(full.render.height));
        let budget = (self.paths_per_second * DRAFT_SECONDS).max(MIN_DRAFT_PIXELS);
        let scene = if self.state.render().paused || width * height <= budget {
            self.queued_full = None;
            full
        } else {
            let divisor = (width * height / budget).sqrt().max(2.0);
            let mut draft = full.clone();
            draft.render.width = (width / divisor).round().max(1.0) as u32;
            draft.render.height = (height / divisor).round().max(1.0) as u32;
            draft.render.spp = 1;
            self.queued_full = Some(full);
            draft
        };
        self.started_epoch = self.service.start(scene.clone());
        self.started_scene = scene;
        self.pending_since = Some(now);
        self.full_pending_since = Some(now);
        self.clock.restart(now, self.state.render().paused);
        self.pass_start = None;
        self.pass_time = None;
    }

    /// Show a newly published frame of the current epoch; after a draft,
    /// start the full-size render.
    fn take_frame(&mut self, frame: Arc<Frame>, now: Instant) {
        if let Some(since) = self.pending_since.take() {
            self.latency.record(now.duration_since(since));
        }
        let is_draft = self.queued_full.is_some();
        if !is_draft {
            if let Some(since) = self.full_pending_since.take() {
                self.full_latency.record(now.duration_since(since));
            }
            if let Some((epoch, spp, elapsed)) = self.pass_start {
                if epoch == frame.epoch && frame.spp > spp {
                    self.pass_time =
                        Some(frame.elapsed.saturating_sub(elapsed) / (frame.spp - spp));
                }
            }
            self.pass_start = Some((frame.epoch, frame.spp, frame.elapsed));
            if frame.finished {
                self.clock.stop(now);
            }
        }
        if frame.paths_per_second().is_finite() && frame.paths_per_second() > 0.0 {
            self.paths_per_second = 0.5 * (self.paths_per_second + frame.paths_per_second());
        }
        if self.state.display.auto_exposure {
            let (lo, hi) = EXPOSURE_RANGE;
            self.state.display.exposure_ev =
                crate::output::auto_exposure_ev(&frame.image).clamp(lo, hi);
        }
        self.frame = Some(frame);
        self.frame_is_draft = is_draft;
        self.frame_scene = self.started_scene.clone();
        self.uploaded = None;
        if let Some(full) = self.queued_full.take() {
            self.started_epoch = self.service.start(full.clone());
            self.started_scene = full;
        }
    }

    /// How soon to look for the next frame: quickly while a first frame is
    /// due, about four times per pass while refining.
    fn poll_interval(&self) -> Duration {
        match &self.frame {
            Some(f) if self.pending_since.is_none() && f.spp > 0 => {
                (f.elapsed / f.spp / 4).clamp(RENDER_POLL, REFINE_POLL_MAX)
            }
            _ => RENDER_POLL,
        }
    }

    /// The preview is still refining (or waiting for a pending restart).
    fn is_rendering(&self) -> bool {
        if self.state.render().paused {
            return false;
        }
        self.state.is_dirty()
            || self.pending_since.is_some()
            || self.queued_full.is_some()
            || self
                .frame
                .as_ref()
                .is_none_or(|f| f.epoch != self.started_epoch || !f.finished)
    }

    /// `--screenshot`: request it when due, once a frame is on screen.
    fn poll_screenshot(&mut self, ctx: &egui::Context) {
        let Some(plan) = &mut self.screenshot else {
            return;
        };
        let started = *plan.started.get_or_insert_with(Instant::now);
        if plan.requested {
            return;
        }
        let elapsed = started.elapsed();
        // Wait for a first frame, but not forever.
        let due = elapsed >= plan.after
            && (self.frame.is_some() || elapsed >= plan.after + Duration::from_mins(1));
        if !due {
            ctx.request_repaint_after(Duration::from_millis(50));
            return;
        }
        plan.requested = true;
        let path = plan.path.clone();
        let shared = Arc::clone(&plan.result);
        let tx = self.tasks_tx.clone();
        let wake = self.wake();
        eprintln!(
            "skyrender: {}",
            screenshot_report(
                elapsed,
                self.frame.as_deref(),
                self.frame_is_draft,
                &self.frame_scene,
                self.latency.last,
                self.full_latency.last,
            )
        );
        self.tasks_running += 1;
        ctx.request_screenshot(move |image| {
            // Encode off the thread that delivers the image.
            std::thread::spawn(move || {
                let [w, h] = image.size;
                let rgb: Vec<u8> = image
                    .pixels
                    .iter()
                    .flat_map(|c| [c.r(), c.g(), c.b()])
                    .collect();
                let result = io::write_png_atomic(
                    &path,
                    w as u32,
                    h as u32,
                    &rgb,
                    image::ExtendedColorType::Rgb8,
                );
                *shared
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner) = Some(result.clone());
                let _ = tx.send(TaskResult::Saved("screenshot", path, result));
                wake();
            });
        });
    }

    /// Whether the current scene's first frame has waited a quarter of a
    /// second or more on the render service's making of a new
    /// atmosphere's sky-model tables.
    pub fn making_tables(&self) -> bool {
        self.pending_since
            .is_some_and(|since| since.elapsed() >= TABLES_NOTICE_AFTER)
            && self.service.is_preparing()
    }

    /// Draw the whole app into `ui` (the window's root).
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        if self.ctx.is_none() {
            self.ctx = Some(ctx.clone());
        }
        self.poll_tasks();
        self.poll_render(&ctx);
        self.poll_screenshot(&ctx);

        let rendering = self.is_rendering();
        let making_tables = self.making_tables();
        let render_time = self.render_time();
        egui::Panel::bottom("status").show(ui, |ui| {
            StatusBar {
                state: &mut self.state,
                frame: self.frame.as_deref(),
                frame_is_draft: self.frame_is_draft,
                rendering,
                making_tables,
                render_time,
                pass_time: self.pass_time,
                latency: (self.latency.last, self.full_latency.last),
            }
            .ui(ui);
        });
        let mut requests = Vec::new();
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(300.0)
            .show(ui, |ui| {
                // The export and save buttons are where a user ends up:
                // pinned under the settings, they stay in reach however many
                // sections are open, and the settings scroll above them.
                egui::Panel::bottom("export")
                    .frame(egui::Frame::NONE.inner_margin(egui::Margin::symmetric(0, 4)))
                    .show(ui, |ui| {
                        let mut panel = ExportPanel {
                            state: &mut self.state,
                            exporting: self.export_job.is_some(),
                            dialogs_enabled: !self.dialog_open,
                            can_save_view: self.frame.is_some(),
                        };
                        requests.extend(panel.ui(ui));
                    });
                egui::ScrollArea::vertical().show(ui, |ui| {
                    requests.extend(self.controls(ui));
                });
            });
        if self.spectrum.is_some() {
            let stale = self.spectrum_is_stale();
            let mut close = false;
            egui::Panel::right("spectrum")
                .resizable(true)
                .default_size(360.0)
                .show(ui, |ui| {
                    if let Some(probe) = &self.spectrum {
                        close = SpectrumPanel { probe, stale }.ui(ui);
                    }
                });
            if close {
                self.spectrum = None;
            }
        }
        let clicked = egui::CentralPanel::default()
            .show(ui, |ui| {
                SkyView {
                    state: &mut self.state,
                    image: self.texture.as_ref().zip(self.frame.as_deref()),
                    frame_scene: &self.frame_scene,
                    false_colour: self.false_scale,
                }
                .ui(ui)
            })
            .inner;
        if let Some((azimuth, elevation)) = clicked {
            self.probe_spectrum(azimuth, elevation);
        }
        for request in requests {
            match request {
                Request::Open(dialog) => self.open_dialog(dialog),
                Request::CancelExport => self.cancel_export(),
            }
        }
        // Apply changes made this frame right away (no frame's delay).
        self.poll_render(&ctx);
    }

    /// The settings sections, top to bottom; what they ask of the app.
    fn controls(&mut self, ui: &mut egui::Ui) -> Option<Request> {
        ui.heading("skyrender");
        let state = &mut self.state;
        let request = PresetsPanel {
            state,
            dialogs_enabled: !self.dialog_open,
        }
        .ui(ui);
        SunPanel { state }.ui(ui);
        ObserverPanel { state }.ui(ui);
        AtmospherePanel { state }.ui(ui);
        CameraPanel { state }.ui(ui);
        DisplayPanel { state }.ui(ui);
        RenderPanel { state }.ui(ui);
        request
    }
}

/// The line `--screenshot` prints when it takes the screenshot: what is on
/// screen and how long the first frames took. A frame not shown yet (a
/// screenshot taken before the first full-size pass, e.g. with
/// `--screenshot-after 0`) is said so in words.
fn screenshot_report(
    elapsed: Duration,
    frame: Option<&Frame>,
    draft: bool,
    scene: &Scene,
    first: Option<Duration>,
    full: Option<Duration>,
) -> String {
    let ms = |d: Duration| format!("{:.0} ms", d.as_secs_f64() * 1e3);
    let shown = match frame {
        Some(f) => format!(
            "{} spp at {}x{}{}",
            f.spp,
            scene.render.width,
            scene.render.height,
            if draft { " (a draft)" } else { "" }
        ),
        None => "no frame on screen".to_owned(),
    };
    let latency = match (first, full) {
        (Some(first), Some(full)) => format!(
            "first frame {}, first full-size frame {} after start",
            ms(first),
            ms(full)
        ),
        (Some(first), None) => {
            format!(
                "first frame {} after start, no full-size frame yet",
                ms(first)
            )
        }
        (None, _) => "no frame yet".to_owned(),
    };
    format!(
        "screenshot at {:.1} s: {shown}; {latency}",
        elapsed.as_secs_f64()
    )
}

impl eframe::App for SkyApp {
    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        self.show(ui);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);
    #[test]
    fn screenshot_report_never_prints_nan() {
        let scene = Scene::preset("midday").unwrap();
        let frame = Frame {
            epoch: 1,
            image: crate::output::RgbImage {
                width: 4,
                height: 2,
                pixels: vec![[0.0; 3]; 8],
            },
            spp: 3,
            paths: 24,
            elapsed: 20 * MS,
            discarded: 0,
            finished: false,
            model_weight: 0.4,
            coarse_passes: 0,
            noise: None,
        };
        let at = 1500 * MS;
        let both = screenshot_report(
            at,
            Some(&frame),
            false,
            &scene,
            Some(40 * MS),
            Some(90 * MS),
        );
        assert!(both.ends_with("first frame 40 ms, first full-size frame 90 ms after start"));
        assert!(both.starts_with("screenshot at 1.5 s: 3 spp at "), "{both}");
        let draft = screenshot_report(at, Some(&frame), true, &scene, Some(40 * MS), None);
        assert!(
            draft.ends_with("(a draft); first frame 40 ms after start, no full-size frame yet"),
            "{draft}"
        );
        let none = screenshot_report(Duration::ZERO, None, false, &scene, None, None);
        assert_eq!(
            none,
            "screenshot at 0.0 s: no frame on screen; no frame yet"
        );
        for line in [both, draft, none] {
            assert!(!line.to_lowercase().contains("nan"), "{line}");
        }
    }
}
