//! The preview app's window: controls on the left, the progressively
//! path-traced sky in the middle, a status bar at the bottom.
//!
//! [`SkyApp::show`] draws everything into a [`egui::Ui`]; `eframe` calls it
//! through [`eframe::App::ui`] and the UI tests through `egui_kittest`. The
//! UI thread never waits: rendering runs on the [`RenderService`]'s thread,
//! exports, saves, loads and file dialogs on threads of their own that
//! report back through a channel.

use std::path::{Path, PathBuf};
use std::sync::mpsc::{channel, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use egui::{Color32, RichText, Sense, Slider};

use super::io::{self, ExportJob};
use super::state::{
    altitude_to_slider, format_altitude, parse_altitude, slider_to_altitude, AppState,
    DisplaySettings, ExportStatus, ToneCurve, AEROSOL_AMOUNT_RANGE, EXPORT_WIDTHS, EXPOSURE_RANGE,
    FISHEYE_FOV_RANGE, GROUND_ALTITUDE_M, MAX_APP_ALTITUDE_M, MAX_EXPORT_SPP, MAX_TARGET_SPP,
    OZONE_DU_RANGE, PERSPECTIVE_FOV_RANGE, PREVIEW_SCALE_RANGE, SUN_ELEVATION_RANGE,
};
use crate::render::service::{Frame, RenderService};
use crate::render::{direction_from_az_el, Camera};
use crate::scene::{CameraKind, Scene, PRESETS};

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
/// Radius of the ring marking the sun, points.
const SUN_RING_RADIUS: f32 = 12.0;
/// How often the UI refreshes while an export or a file task runs.
const TASK_POLL: Duration = Duration::from_millis(100);
/// The camera mode buttons: mode, label, tooltip.
const CAMERA_MODES: [(CameraKind, &str, &str); 3] = [
    (
        CameraKind::Fisheye,
        "Fisheye",
        "All-sky view looking straight up, north at the top",
    ),
    (
        CameraKind::Equirect,
        "Equirect",
        "Whole sphere as a 2:1 latitude–longitude map, north in the middle",
    ),
    (
        CameraKind::Perspective,
        "Perspective",
        "Ordinary camera; drag the view or use the arrow keys to look around",
    ),
];
/// Arrow-key step of the view direction, degrees (shift: a fifth of it).
const ARROW_STEP_DEG: f64 = 5.0;

/// A file dialog the app can open.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Dialog {
    Export,
    SaveView,
    SaveScene,
    LoadScene,
}

/// Results that background threads send to the UI.
enum TaskResult {
    /// A dialog closed with this path (`None`: cancelled).
    Picked(Dialog, Option<PathBuf>),
    /// A scene file was read.
    SceneLoaded(PathBuf, Result<Box<Scene>, String>),
    /// A file (view, scene, screenshot) was written, or not.
    Saved(&'static str, PathBuf, Result<(), String>),
}

/// Time from a scene change to its first frame on screen.
#[derive(Clone, Copy, Debug, Default)]
pub struct LatencyStats {
    /// The latest measurement.
    pub last: Option<Duration>,
    /// Number of measurements.
    pub count: u32,
    /// Sum of all measurements.
    pub total: Duration,
    /// Largest measurement.
    pub max: Duration,
}

impl LatencyStats {
    fn record(&mut self, latency: Duration) {
        self.last = Some(latency);
        self.count += 1;
        self.total += latency;
        self.max = self.max.max(latency);
    }

    /// Mean of all measurements.
    pub fn mean(&self) -> Option<Duration> {
        (self.count > 0).then(|| self.total / self.count)
    }
}

/// Render time of the image on screen: wall time since the latest scene
/// change, draft included, pauses not counted, stopped when the target is
/// reached (or the render failed). The service's own `Frame::elapsed` starts
/// again at the full-size render after a draft and counts pauses, so it
/// understates a fresh render and overstates a paused one.
#[derive(Clone, Copy, Debug, Default)]
struct RenderClock {
    /// Time counted before `running_since`.
    banked: Duration,
    /// Counting since then; `None` while paused or stopped.
    running_since: Option<Instant>,
    /// The render is over; only a scene change starts the clock again.
    stopped: bool,
}

impl RenderClock {
    /// A scene change at `now`: count from zero (from the resume if paused).
    fn restart(&mut self, now: Instant, paused: bool) {
        *self = Self {
            banked: Duration::ZERO,
            running_since: (!paused).then_some(now),
            stopped: false,
        };
    }

    fn pause(&mut self, now: Instant) {
        if let Some(since) = self.running_since.take() {
            self.banked += now.saturating_duration_since(since);
        }
    }

    fn resume(&mut self, now: Instant) {
        if !self.stopped && self.running_since.is_none() {
            self.running_since = Some(now);
        }
    }

    /// The render finished (or failed) at `now`.
    fn stop(&mut self, now: Instant) {
        self.pause(now);
        self.stopped = true;
    }

    fn read(&self, now: Instant) -> Duration {
        self.banked
            + self
                .running_since
                .map_or(Duration::ZERO, |since| now.saturating_duration_since(since))
    }
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
        }
    }

    /// Take a screenshot of the window into `path` (PNG) `after` the first
    /// frame, then close the window; `result` receives the outcome.
    fn with_screenshot(
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
        let total = scene.render.spp;
        match ExportJob::start(scene, path.clone(), self.wake()) {
            Ok(job) => {
                self.export_job = Some(job);
                self.state.export_status = ExportStatus::Running {
                    path,
                    done: 0,
                    total,
                };
            }
            Err(e) => self.fail_export(e),
        }
    }

    /// Stop a running export; nothing is written.
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
                TaskResult::Picked(dialog, path) => {
                    self.dialog_open = false;
                    let Some(path) = path else { continue };
                    match dialog {
                        Dialog::Export => self.start_export(path),
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
            let done = job.done();
            if let ExportStatus::Running { done: shown, .. } = &mut self.state.export_status {
                *shown = done;
            }
            if let Some(result) = job.try_finish() {
                let cancelled = job.is_cancelled();
                let path = job.path.clone();
                self.export_job = None;
                match result {
                    Ok(elapsed) => {
                        self.state.message = Some(format!("exported '{}'", path.display()));
                        self.state.export_status = ExportStatus::Finished { path, elapsed };
                    }
                    Err(_) if cancelled => self.state.export_status = ExportStatus::Cancelled,
                    Err(e) => self.fail_export(e),
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

    /// Draw the whole app into `ui` (the window's root).
    pub fn show(&mut self, ui: &mut egui::Ui) {
        let ctx = ui.ctx().clone();
        if self.ctx.is_none() {
            self.ctx = Some(ctx.clone());
        }
        self.poll_tasks();
        self.poll_render(&ctx);
        self.poll_screenshot(&ctx);

        egui::Panel::bottom("status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::left("controls")
            .resizable(true)
            .default_size(300.0)
            .show(ui, |ui| {
                // The export and save buttons are where a user ends up:
                // pinned under the settings, they stay in reach however many
                // sections are open, and the settings scroll above them.
                egui::Panel::bottom("export")
                    .frame(egui::Frame::NONE.inner_margin(egui::Margin::symmetric(0, 4)))
                    .show(ui, |ui| self.export_group(ui));
                egui::ScrollArea::vertical().show(ui, |ui| self.controls(ui));
            });
        egui::CentralPanel::default().show(ui, |ui| self.view(ui));
        // Apply changes made this frame right away (no frame's delay).
        self.poll_render(&ctx);
    }

    fn status_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal_wrapped(|ui| {
            let (w, h) = self.state.preview_size();
            let state = if self.state.render().paused {
                "paused"
            } else if self.is_rendering() {
                "rendering"
            } else {
                "done"
            };
            ui.label(RichText::new(state).strong());
            match &self.frame {
                Some(f) => {
                    let spp = if self.frame_is_draft {
                        format!("draft {}×{}", f.image.width, f.image.height)
                    } else {
                        format!("{} / {} spp", f.spp, self.state.render().target_spp)
                    };
                    ui.label(spp).on_hover_text(
                        "Samples per pixel accumulated / target (a draft is a quick \
                         low-resolution first look after a change)",
                    );
                    ui.label(format!(
                        "{:.2} M camera paths/s",
                        f.paths_per_second() / 1e6
                    ))
                    .on_hover_text("Camera paths traced per second");
                    ui.label(format!("{:.1} s", self.render_time().as_secs_f64()))
                        .on_hover_text(
                            "Render time since the latest change (draft included, \
                             pauses not counted)",
                        );
                    if let Some(pass) = self.pass_time {
                        let seconds = pass.as_secs_f64();
                        let text = if seconds < 1.0 {
                            format!("{:.0} ms/pass", seconds * 1e3)
                        } else {
                            format!("{seconds:.1} s/pass")
                        };
                        ui.label(text)
                            .on_hover_text("How long the latest sample pass took");
                    }
                    ui.label(format!("{} discarded", f.discarded))
                        .on_hover_text("Samples dropped as non-finite or negative");
                }
                None => {
                    ui.label("no frame yet");
                }
            }
            ui.label(format!("{w}×{h} px"))
                .on_hover_text("Preview resolution");
            if let (Some(first), Some(full)) = (self.latency.last, self.full_latency.last) {
                ui.label(format!(
                    "first frame {:.0} ms, full size {:.0} ms",
                    first.as_secs_f64() * 1e3,
                    full.as_secs_f64() * 1e3
                ))
                .on_hover_text(
                    "Time from the latest change to its first frame on screen \
                     (draft, then full size)",
                );
            }
            if let Some(error) = self.state.last_error.clone() {
                ui.separator();
                ui.colored_label(Color32::from_rgb(255, 110, 100), format!("Error: {error}"));
                if ui
                    .small_button("Dismiss")
                    .on_hover_text("Clear this error")
                    .clicked()
                {
                    self.state.last_error = None;
                }
            } else if let Some(message) = &self.state.message {
                ui.separator();
                ui.weak(message);
            }
        });
    }

    fn controls(&mut self, ui: &mut egui::Ui) {
        ui.heading("skyrender");
        self.presets_group(ui);
        self.sun_group(ui);
        self.observer_group(ui);
        self.atmosphere_group(ui);
        self.camera_group(ui);
        self.display_group(ui);
        self.render_group(ui);
    }

    fn presets_group(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Presets")
            .default_open(true)
            .show(ui, |ui| {
                ui.horizontal_wrapped(|ui| {
                    for (name, text) in PRESETS {
                        let summary = text
                            .lines()
                            .next()
                            .unwrap_or("")
                            .trim_start_matches('#')
                            .trim();
                        if ui.button(name).on_hover_text(summary).clicked() {
                            self.state.load_preset(name);
                        }
                    }
                });
                ui.horizontal(|ui| {
                    let enabled = !self.dialog_open;
                    if ui
                        .add_enabled(enabled, egui::Button::new("Save scene…"))
                        .on_hover_text(
                            "Save the scene as TOML (usable with `skyrender render --scene`)",
                        )
                        .clicked()
                    {
                        self.open_dialog(Dialog::SaveScene);
                    }
                    if ui
                        .add_enabled(enabled, egui::Button::new("Load scene…"))
                        .on_hover_text("Load a scene TOML")
                        .clicked()
                    {
                        self.open_dialog(Dialog::LoadScene);
                    }
                });
            });
    }

    fn sun_group(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Sun")
            .default_open(true)
            .show(ui, |ui| {
                let sun = self.state.scene().sun.clone();
                if let Some(v) = slider(
                    ui,
                    sun.elevation_deg,
                    SUN_ELEVATION_RANGE,
                    "Elevation",
                    "°",
                    "Sun elevation above the astronomical horizon, degrees (negative: below it)",
                ) {
                    self.state.set_sun_elevation(v);
                }
                if let Some(v) = slider(
                    ui,
                    sun.azimuth_deg,
                    (0.0, 360.0),
                    "Azimuth",
                    "°",
                    "Sun azimuth, degrees clockwise from north (90 east, 180 south, 270 west)",
                ) {
                    self.state.set_sun_azimuth(v);
                }
            });
    }

    fn observer_group(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Observer")
            .default_open(true)
            .show(ui, |ui| {
                let altitude = self.state.scene().observer.altitude_m;
                let mut position = altitude_to_slider(altitude);
                let response = ui
                    .add(
                        Slider::new(&mut position, 0.0..=altitude_to_slider(MAX_APP_ALTITUDE_M))
                            .text("Altitude")
                            .custom_formatter(|p, _| format_altitude(slider_to_altitude(p)))
                            .custom_parser(|s| parse_altitude(s).map(altitude_to_slider)),
                    )
                    .on_hover_text(
                        "Height of the eye above the ground (logarithmic scale, 0 m to 1000 km); \
                     type e.g. \"10 km\"",
                    );
                if response.changed() {
                    self.state.set_altitude_m(slider_to_altitude(position));
                }
                ui.horizontal(|ui| {
                    for (label, m, tip) in [
                        (
                            "Ground",
                            GROUND_ALTITUDE_M,
                            "Standing on the ground (eye height 2 m)",
                        ),
                        (
                            "Airliner 10 km",
                            10_000.0,
                            "Cruising altitude of an airliner",
                        ),
                        ("Orbit 400 km", 400_000.0, "Low Earth orbit, like the ISS"),
                    ] {
                        if ui
                            .selectable_label(altitude == m, label)
                            .on_hover_text(tip)
                            .clicked()
                        {
                            self.state.set_altitude_m(m);
                        }
                    }
                });
            });
    }

    fn atmosphere_group(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Atmosphere")
            .default_open(true)
            .show(ui, |ui| {
                let a = self.state.atmosphere().clone();
                let mut aerosols = a.aerosols;
                if ui
                    .checkbox(&mut aerosols, "Aerosols")
                    .on_hover_text(
                        "Haze particles (Elterman's profile): whiter sky near the horizon, \
                     glow around the sun",
                    )
                    .changed()
                {
                    self.state.set_aerosols(aerosols);
                }
                ui.add_enabled_ui(aerosols, |ui| {
                    if let Some(v) = slider(
                        ui,
                        a.aerosol_amount,
                        AEROSOL_AMOUNT_RANGE,
                        "Aerosol amount",
                        "×",
                        "Multiple of the standard aerosol profile (1 = clear standard day)",
                    ) {
                        self.state.set_aerosol_amount(v);
                    }
                });
                let mut ozone = a.ozone;
                if ui
                    .checkbox(&mut ozone, "Ozone")
                    .on_hover_text(
                        "Ozone absorption (Chappuis band): keeps the twilight zenith blue",
                    )
                    .changed()
                {
                    self.state.set_ozone(ozone);
                }
                ui.add_enabled_ui(ozone, |ui| {
                    ui.horizontal(|ui| {
                        if let Some(v) = slider(
                            ui,
                            self.state.ozone_column_du(),
                            OZONE_DU_RANGE,
                            "Ozone column",
                            " DU",
                            "Total ozone column in Dobson units (about 300 is typical)",
                        ) {
                            self.state.set_ozone_du(Some(v));
                        }
                        if ui
                            .add_enabled(a.ozone_du.is_some(), egui::Button::new("Profile").small())
                            .on_hover_text("Use the model profile's own column")
                            .clicked()
                        {
                            self.state.set_ozone_du(None);
                        }
                    });
                });
                if let Some(v) = slider(
                    ui,
                    a.ground_albedo,
                    (0.0, 1.0),
                    "Ground albedo",
                    "",
                    "Fraction of light the (Lambertian) ground reflects: \
                 0.1 forest or sea, 0.3 average, 0.8 snow",
                ) {
                    self.state.set_ground_albedo(v);
                }
            });
    }

    fn camera_group(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Camera")
            .default_open(true)
            .show(ui, |ui| {
                let camera = self.state.scene().camera.clone();
                ui.horizontal(|ui| {
                    for (kind, label, tip) in CAMERA_MODES {
                        if ui
                            .selectable_label(camera.kind == kind, label)
                            .on_hover_text(tip)
                            .clicked()
                        {
                            self.state.set_camera_kind(kind);
                        }
                    }
                });
                match camera.kind {
                    CameraKind::Perspective => {
                        if let Some(v) = slider(
                            ui,
                            camera.fov_deg,
                            PERSPECTIVE_FOV_RANGE,
                            "Field of view",
                            "°",
                            "Horizontal field of view, degrees",
                        ) {
                            self.state.set_fov(v);
                        }
                        if let Some(v) = slider(
                            ui,
                            camera.yaw_deg,
                            (-180.0, 180.0),
                            "Yaw",
                            "°",
                            "View direction, degrees clockwise from north",
                        ) {
                            self.state.set_view(v, camera.pitch_deg);
                        }
                        if let Some(v) = slider(
                            ui,
                            camera.pitch_deg,
                            (-90.0, 90.0),
                            "Pitch",
                            "°",
                            "View elevation above the horizon, degrees",
                        ) {
                            self.state.set_view(camera.yaw_deg, v);
                        }
                        ui.weak("Drag the view or use the arrow keys to look around.");
                    }
                    CameraKind::Fisheye => {
                        if let Some(v) = slider(
                            ui,
                            camera.fov_deg,
                            FISHEYE_FOV_RANGE,
                            "Field of view",
                            "°",
                            "Full field of view of the fisheye circle, degrees \
                         (180 = down to the horizon)",
                        ) {
                            self.state.set_fov(v);
                        }
                        if let Some(v) = slider(
                            ui,
                            camera.yaw_deg,
                            (-180.0, 180.0),
                            "Rotation",
                            "°",
                            "Turns the all-sky image, degrees",
                        ) {
                            self.state.set_view(v, camera.pitch_deg);
                        }
                    }
                    CameraKind::Equirect => {
                        ui.weak("The map is geographic: north in the middle, east to the right.");
                    }
                }
            });
    }

    fn display_group(&mut self, ui: &mut egui::Ui) {
        // Closed at first: auto exposure and the default tone curve suit
        // most scenes, and the settings above it then fit the default
        // window without scrolling.
        egui::CollapsingHeader::new("Display")
            .default_open(false)
            .show(ui, |ui| {
                let display = &mut self.state.display;
                ui.checkbox(&mut display.auto_exposure, "Auto exposure")
                    .on_hover_text("Map the image's log-average luminance to middle grey");
                let (lo, hi) = EXPOSURE_RANGE;
                ui.add_enabled(
                    !display.auto_exposure,
                    Slider::new(&mut display.exposure_ev, lo..=hi)
                        .text("Exposure")
                        .suffix(" EV")
                        .custom_formatter(|v, _| format!("{v:.1}")),
                )
                .on_hover_text("Display value = luminance (cd/m²) × 2^EV, then the tone curve")
                .on_disabled_hover_text("Set automatically; untick Auto exposure to adjust");
                egui::ComboBox::from_label("Tone curve")
                    .selected_text(display.tone_curve.label())
                    .show_ui(ui, |ui| {
                        for curve in ToneCurve::ALL {
                            ui.selectable_value(&mut display.tone_curve, curve, curve.label());
                        }
                    })
                    .response
                    .on_hover_text("How linear radiance becomes screen brightness");
                ui.checkbox(&mut display.mark_sun, "Mark the sun")
                    .on_hover_text("Draw a ring where the sun is");
            });
    }

    fn render_group(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Render")
            .default_open(true)
            .show(ui, |ui| {
                let render = self.state.render().clone();
                let mut scale = render.preview_scale;
                let (lo, hi) = PREVIEW_SCALE_RANGE;
                let (w, h) = self.state.preview_size();
                if ui
                    .add(
                        Slider::new(&mut scale, lo..=hi)
                            .text("Preview scale")
                            .suffix("×")
                            .custom_formatter(|v, _| format!("{v:.2}")),
                    )
                    .on_hover_text(format!(
                        "Preview resolution relative to 320×160 (now {w}×{h} px); lower is faster"
                    ))
                    .changed()
                {
                    self.state.set_preview_scale(scale);
                }
                let mut spp = render.target_spp;
                if ui
                    .add(
                        Slider::new(&mut spp, 1..=MAX_TARGET_SPP)
                            .logarithmic(true)
                            .text("Target spp"),
                    )
                    .on_hover_text("Samples per pixel after which the preview stops refining")
                    .changed()
                {
                    self.state.set_target_spp(spp);
                }
                let label = if render.paused { "Resume" } else { "Pause" };
                if ui
                    .button(label)
                    .on_hover_text("Pause or resume refining (the image is kept)")
                    .clicked()
                {
                    self.state.set_paused(!render.paused);
                }
            });
    }

    fn export_group(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Export")
            .default_open(true)
            .show(ui, |ui| self.export_controls(ui));
    }

    fn export_controls(&mut self, ui: &mut egui::Ui) {
        let export = self.state.export.clone();
        egui::ComboBox::from_label("Panorama size")
            .selected_text(format!("{} × {}", export.width, export.height()))
            .show_ui(ui, |ui| {
                for width in EXPORT_WIDTHS {
                    let text = format!("{width} × {}", width / 2);
                    if ui.selectable_label(export.width == width, text).clicked() {
                        self.state.set_export_width(width);
                    }
                }
            })
            .response
            .on_hover_text("Size of the equirectangular EXR panorama");
        let mut spp = export.spp;
        let spp_slider = Slider::new(&mut spp, 1..=MAX_EXPORT_SPP)
            .logarithmic(true)
            .text("Export spp");
        if ui
            .add(spp_slider)
            .on_hover_text("Samples per pixel of the exported panorama")
            .changed()
        {
            self.state.set_export_spp(spp);
        }
        let can_export = self.export_job.is_none() && !self.dialog_open;
        let export_button = egui::Button::new("Export HDR panorama…");
        if ui
            .add_enabled(can_export, export_button)
            .on_hover_text(
                "Render the scene as an equirectangular OpenEXR in the background: \
                 the same file as `skyrender render --camera equirect` writes",
            )
            .clicked()
        {
            self.open_dialog(Dialog::Export);
        }
        let error_colour = Color32::from_rgb(255, 110, 100);
        match self.state.export_status.clone() {
            ExportStatus::Running { done, total, .. } => {
                ui.horizontal(|ui| {
                    let fraction = done as f32 / total.max(1) as f32;
                    let bar = egui::ProgressBar::new(fraction)
                        .text(format!("{done} / {total} spp"))
                        .desired_width(160.0);
                    ui.add(bar);
                    let cancel = ui
                        .button("Cancel")
                        .on_hover_text("Stop the export; nothing is written");
                    if cancel.clicked() {
                        self.cancel_export();
                    }
                });
            }
            ExportStatus::Finished { path, elapsed } => {
                let seconds = elapsed.as_secs_f64();
                ui.weak(format!("Exported {} in {seconds:.1} s", path.display()));
            }
            ExportStatus::Cancelled => {
                ui.weak("Export cancelled; nothing written.");
            }
            ExportStatus::Failed(e) => {
                ui.colored_label(error_colour, format!("Export failed: {e}"));
            }
            ExportStatus::Idle => {}
        }
        let can_save = self.frame.is_some() && !self.dialog_open;
        if ui
            .add_enabled(can_save, egui::Button::new("Save view as PNG/EXR…"))
            .on_hover_text("Save the image on screen: PNG as shown, EXR as linear HDR")
            .clicked()
        {
            self.open_dialog(Dialog::SaveView);
        }
    }

    /// The central image, with dragging and arrow keys to turn the view.
    fn view(&mut self, ui: &mut egui::Ui) {
        let available = ui.available_rect_before_wrap();
        let Some((texture, frame)) = self.texture.as_ref().zip(self.frame.as_ref()) else {
            ui.centered_and_justified(|ui| {
                ui.horizontal_centered(|ui| {
                    ui.spinner();
                    ui.label("rendering the first pass…");
                });
            });
            return;
        };
        let (w, h) = (frame.image.width as f32, frame.image.height as f32);
        let scale = (available.width() / w).min(available.height() / h).max(0.0);
        let rect =
            egui::Rect::from_center_size(available.center(), egui::vec2(w * scale, h * scale));
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, "Sky view"));
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        ui.painter().image(texture.id(), rect, uv, Color32::WHITE);

        if self.state.display.mark_sun {
            let scene = &self.frame_scene;
            let camera = Camera::new(&scene.camera, scene.render.width, scene.render.height);
            let sun = direction_from_az_el(scene.sun.azimuth_deg, scene.sun.elevation_deg);
            if let Some((px, py)) = camera.project(sun) {
                let centre = rect.min
                    + egui::vec2(px as f32 / w * rect.width(), py as f32 / h * rect.height());
                // The equirectangular map wraps around: a sun on its edge
                // shows on both sides.
                let copies: &[f32] = if scene.camera.kind == CameraKind::Equirect {
                    &[-1.0, 0.0, 1.0]
                } else {
                    &[0.0]
                };
                let painter = ui.painter().with_clip_rect(rect);
                for shift in copies {
                    let c = centre + egui::vec2(shift * rect.width(), 0.0);
                    if rect.expand(SUN_RING_RADIUS).contains(c) {
                        // A dark ring around a light one reads on any background.
                        let dark = egui::Stroke::new(3.0, Color32::from_black_alpha(160));
                        let light = egui::Stroke::new(1.5, Color32::from_rgb(255, 220, 90));
                        painter.circle_stroke(c, SUN_RING_RADIUS, dark);
                        painter.circle_stroke(c, SUN_RING_RADIUS, light);
                    }
                }
            }
        }

        let kind = self.state.scene().camera.kind;
        if response.dragged() && kind != CameraKind::Equirect {
            let delta = response.drag_delta();
            let fov = self.state.scene().camera.fov_deg;
            let per_point = fov / f64::from(rect.width().max(1.0));
            match kind {
                CameraKind::Perspective => {
                    self.state.rotate_view(
                        -f64::from(delta.x) * per_point,
                        f64::from(delta.y) * per_point,
                    );
                }
                _ => self.state.rotate_view(f64::from(delta.x) * per_point, 0.0),
            }
        }
        let nothing_focused = ui.memory(|m| m.focused().is_none());
        if nothing_focused && kind != CameraKind::Equirect {
            let (d_yaw, d_pitch) = ui.input(|i| {
                let step = if i.modifiers.shift {
                    ARROW_STEP_DEG / 5.0
                } else {
                    ARROW_STEP_DEG
                };
                let key = |k| if i.key_pressed(k) { step } else { 0.0 };
                (
                    key(egui::Key::ArrowRight) - key(egui::Key::ArrowLeft),
                    key(egui::Key::ArrowUp) - key(egui::Key::ArrowDown),
                )
            });
            if d_yaw != 0.0 || d_pitch != 0.0 {
                let d_pitch = if kind == CameraKind::Perspective {
                    d_pitch
                } else {
                    0.0
                };
                self.state.rotate_view(d_yaw, d_pitch);
            }
        }
    }
}

/// A labelled slider with units and a tooltip over `value` (one decimal for
/// wide ranges such as degrees, two otherwise); the new value if the user
/// changed it.
fn slider(
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
/// errors read "os error at <its source file>:<line>: <reason>" (behind
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

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn render_clock_counts_from_the_change_without_pauses_and_stops_when_done() {
        let t0 = Instant::now();
        let mut clock = RenderClock::default();
        assert_eq!(clock.read(t0), Duration::ZERO);
        clock.restart(t0, false);
        assert_eq!(clock.read(t0 + 300 * MS), 300 * MS);
        clock.pause(t0 + 500 * MS);
        assert_eq!(clock.read(t0 + 9000 * MS), 500 * MS);
        clock.resume(t0 + 10_000 * MS);
        assert_eq!(clock.read(t0 + 10_250 * MS), 750 * MS);
        clock.stop(t0 + 11_000 * MS);
        assert_eq!(clock.read(t0 + 60_000 * MS), 1500 * MS);
        // Pausing and resuming a finished render leaves it finished.
        clock.pause(t0 + 61_000 * MS);
        clock.resume(t0 + 62_000 * MS);
        assert_eq!(clock.read(t0 + 63_000 * MS), 1500 * MS);
        // A change made while paused starts counting at the resume.
        clock.restart(t0 + 70_000 * MS, true);
        assert_eq!(clock.read(t0 + 71_000 * MS), Duration::ZERO);
        clock.resume(t0 + 72_000 * MS);
        assert_eq!(clock.read(t0 + 72_100 * MS), 100 * MS);
    }

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
