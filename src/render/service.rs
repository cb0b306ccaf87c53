//! A progressive render service: one background thread owns the rayon work,
//! renders sample passes of the current scene into a film, and publishes the
//! image after each completed pass. Starting a new scene bumps an epoch
//! counter; the running pass notices between rows and stops, and a frame is
//! published only if its epoch is still current, so a stale image never
//! appears after a restart.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::noise_estimate::{Stop, StopRules};
use super::parts::{PassRange, Tile};
use super::preview::Preview;
use super::{Film, OutOfMemory, Renderer};
use crate::output::RgbImage;
use crate::scene::{CameraKind, Scene};

/// Pixels in a preview at scale 1 (320 × 160 for the equirectangular view).
pub const PREVIEW_BASE_PIXELS: f64 = 320.0 * 160.0;

/// Samples per pixel after which a preview stops refining, by default.
pub const PREVIEW_TARGET_SPP: u32 = 1024;

/// Width and height of a preview of `scene` at linear `scale`: 2:1 for the
/// equirectangular map, square for the fisheye, the scene's own aspect
/// ratio for the perspective camera; about [`PREVIEW_BASE_PIXELS`] × scale²
/// pixels in each case.
pub fn preview_size(scene: &Scene, scale: f64) -> (u32, u32) {
    let pixels = PREVIEW_BASE_PIXELS * scale * scale;
    let aspect = match scene.camera.kind {
        CameraKind::Equirect => 2.0,
        CameraKind::Fisheye => 1.0,
        CameraKind::Perspective => {
            let r = &scene.render;
            (f64::from(r.width) / f64::from(r.height)).clamp(0.5, 3.0)
        }
    };
    let width = (pixels * aspect).sqrt().round().max(1.0);
    let height = (width / aspect).round().max(1.0);
    (width as u32, height as u32)
}

/// The scene a preview renders: `scene` at the preview size for `scale`,
/// refining to `spp` samples per pixel.
pub fn preview_scene(scene: &Scene, scale: f64, spp: u32) -> Scene {
    let mut preview = scene.clone();
    let (width, height) = preview_size(scene, scale);
    preview.render.width = width;
    preview.render.height = height;
    preview.render.spp = spp;
    preview
}

/// The app's first preview: the `midday` preset at scale 1.
pub fn default_preview_scene() -> Scene {
    let midday = Scene::preset("midday").unwrap_or_default();
    preview_scene(&midday, 1.0, PREVIEW_TARGET_SPP)
}

/// An image published by the service.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The scene generation this frame belongs to.
    pub epoch: u64,
    /// Linear Rec.709, Y in cd m⁻².
    pub image: RgbImage,
    /// Passes in `image` (the least samples a pixel has).
    pub spp: u32,
    /// Camera paths in `image` (more than `spp` per pixel under adaptive
    /// sampling).
    pub paths: u64,
    /// Time since the scene started rendering.
    pub elapsed: Duration,
    /// Samples discarded as not finite.
    pub discarded: u64,
    /// The target sample count was reached.
    pub finished: bool,
    /// The share of the approximate sky model ([`super::sky_model`]) in
    /// `image`, 0–1 ([`model_weight`]): 1 for the first frame, before any
    /// pass; 0 once the passes are done.
    pub model_weight: f64,
    /// Coarse passes behind the model's correction in `image`
    /// ([`super::preview`]).
    pub coarse_passes: u32,
    /// The passes' estimated relative noise (0.01: 1 %), from
    /// [`super::noise_estimate::MIN_PASSES`] passes on
    /// ([`super::preview::Shown::noise`]).
    pub noise: Option<f64>,
}

pub use super::preview::{model_weight, model_weight_with, MODEL_ERROR, OUTLIER_RATIO};

impl Frame {
    /// Camera paths per second of wall time so far.
    pub fn paths_per_second(&self) -> f64 {
        self.paths as f64 / self.elapsed.as_secs_f64().max(1e-9)
    }
}

#[derive(Default)]
struct State {
    scene: Option<(u64, Scene)>,
    paused: bool,
    shutdown: bool,
    frame: Option<Arc<Frame>>,
    error: Option<(u64, String)>,
    /// The epoch whose sky-model tables are being made or looked up.
    preparing: Option<u64>,
}

struct Shared {
    state: Mutex<State>,
    wake: Condvar,
    epoch: AtomicU64,
}

/// Renders the latest scene progressively on a background thread.
pub struct RenderService {
    shared: Arc<Shared>,
    worker: Option<JoinHandle<()>>,
}

impl Default for RenderService {
    fn default() -> Self {
        Self::new()
    }
}

impl RenderService {
    /// A service with its render thread started.
    pub fn new() -> Self {
        let shared = Arc::new(Shared {
            state: Mutex::new(State::default()),
            wake: Condvar::new(),
            epoch: AtomicU64::new(0),
        });
        let worker_shared = Arc::clone(&shared);
        let worker = std::thread::Builder::new()
            .name("skyrender-service".into())
            .spawn(move || worker_loop(&worker_shared))
            .expect("spawn render thread");
        Self {
            shared,
            worker: Some(worker),
        }
    }

    /// Render `scene` (up to `scene.render.spp` samples per pixel), replacing
    /// whatever was being rendered. Returns the new epoch.
    pub fn start(&self, scene: Scene) -> u64 {
        let mut state = self.shared.state.lock().unwrap();
        let epoch = self.shared.epoch.fetch_add(1, Ordering::SeqCst) + 1;
        state.scene = Some((epoch, scene));
        state.error = None;
        drop(state);
        self.shared.wake.notify_all();
        epoch
    }

    /// Stop rendering (the last frame stays available).
    pub fn cancel(&self) {
        let mut state = self.shared.state.lock().unwrap();
        self.shared.epoch.fetch_add(1, Ordering::SeqCst);
        state.scene = None;
    }

    /// Pauses or resumes rendering (the accumulated image stays).
    pub fn set_paused(&self, paused: bool) {
        self.shared.state.lock().unwrap().paused = paused;
        self.shared.wake.notify_all();
    }

    /// The current epoch (the latest `start` or `cancel`).
    pub fn epoch(&self) -> u64 {
        self.shared.epoch.load(Ordering::SeqCst)
    }

    /// The latest published frame of any epoch.
    pub fn latest(&self) -> Option<Arc<Frame>> {
        self.shared.state.lock().unwrap().frame.clone()
    }

    /// Whether the current scene's sky-model tables are being made (or
    /// looked up: tables kept take a millisecond, a new atmosphere's a few
    /// seconds, and its first frame waits on them).
    pub fn is_preparing(&self) -> bool {
        let state = self.shared.state.lock().unwrap();
        state.preparing == Some(self.epoch())
    }

    /// An error from building the current scene, if any.
    pub fn error(&self) -> Option<String> {
        let state = self.shared.state.lock().unwrap();
        state
            .error
            .as_ref()
            .filter(|(e, _)| *e == self.epoch())
            .map(|(_, m)| m.clone())
    }
}

impl Drop for RenderService {
    fn drop(&mut self) {
        self.shared.state.lock().unwrap().shutdown = true;
        self.shared.epoch.fetch_add(1, Ordering::SeqCst);
        self.shared.wake.notify_all();
        if let Some(worker) = self.worker.take() {
            let _ = worker.join();
        }
    }
}

fn worker_loop(shared: &Shared) {
    loop {
        let (epoch, scene) = {
            let mut state = shared.state.lock().unwrap();
            loop {
                if state.shutdown {
                    return;
                }
                if !state.paused {
                    if let Some(job) = state.scene.take() {
                        break job;
                    }
                }
                state = shared.wake.wait(state).unwrap();
            }
        };
        let stale = || shared.epoch.load(Ordering::SeqCst) != epoch;
        // A new atmosphere's model tables take seconds: a scene replaced
        // meanwhile (a slider dragged) gives them up for the next one.
        shared.state.lock().unwrap().preparing = Some(epoch);
        let made = Renderer::with_model_unless(&scene, &stale);
        shared.state.lock().unwrap().preparing = None;
        let renderer = match made {
            Ok(Some(r)) => r,
            Ok(None) => continue,
            Err(e) => {
                shared.state.lock().unwrap().error = Some((epoch, e.to_string()));
                continue;
            }
        };
        let start = Instant::now();
        // The first frame: the approximate model, in tens of milliseconds.
        let mut preview = Preview::new(&renderer);
        if stale() {
            continue;
        }
        publish_image(
            shared,
            epoch,
            Frame {
                epoch,
                image: preview.model().clone(),
                spp: 0,
                paths: 0,
                elapsed: start.elapsed(),
                discarded: 0,
                finished: false,
                model_weight: 1.0,
                coarse_passes: 0,
                noise: None,
            },
        );
        loop {
            // Pausing keeps the films; resume continues where it stopped.
            {
                let mut state = shared.state.lock().unwrap();
                while state.paused && !stale() && !state.shutdown {
                    state = shared.wake.wait(state).unwrap();
                }
            }
            if stale() {
                break;
            }
            let Some(shown) = preview.step(&stale) else {
                break;
            };
            let finished = shown.finished;
            publish_image(
                shared,
                epoch,
                Frame {
                    epoch,
                    image: shown.image,
                    spp: shown.spp,
                    paths: preview.paths,
                    elapsed: start.elapsed(),
                    discarded: preview.film().discarded,
                    finished,
                    model_weight: shown.model_weight,
                    coarse_passes: shown.coarse_passes,
                    noise: shown.noise,
                },
            );
            if finished {
                break;
            }
        }
    }
}

fn publish_image(shared: &Shared, epoch: u64, frame: Frame) {
    let mut state = shared.state.lock().unwrap();
    // Checked under the lock that `start` takes: no stale frame after a restart.
    if shared.epoch.load(Ordering::SeqCst) != epoch {
        return;
    }
    state.frame = Some(Arc::new(frame));
}

/// A render done by [`render_blocking`].
pub struct Rendered {
    /// The film of every pass rendered.
    pub film: Film,
    /// Camera paths traced.
    pub paths: u64,
    /// Passes rendered (the least samples a pixel has).
    pub passes: u32,
    /// The image's estimated relative noise (0.01: 1 %), where its film
    /// keeps the variance layer ([`super::noise_estimate`]).
    pub noise: Option<f64>,
    /// Why it stopped.
    pub stop: Stop,
}

/// Render a scene on the calling thread's rayon pool until its stopping
/// rules say (`spp` passes, a noise target, a time limit:
/// [`StopRules`]), reporting progress after each pass; returns `None` if
/// `cancel` was set, and an error before any work where the render's
/// memory is not there ([`Renderer::check_memory`]).
pub fn render_blocking(
    renderer: &Renderer,
    cancel: &AtomicBool,
    mut on_pass: impl FnMut(u32, &Film),
) -> Result<Option<Rendered>, OutOfMemory> {
    renderer.check_memory()?;
    let mut film = renderer.try_new_film()?;
    let rules = StopRules::new(renderer);
    let is_cancelled = || cancel.load(Ordering::Relaxed);
    let start = Instant::now();
    let (mut paths, mut passes, mut last_end) = (0, 0, Duration::ZERO);
    loop {
        let stats = renderer.render_pass(&mut film, passes, &is_cancelled);
        paths += stats.paths;
        if !stats.completed {
            return Ok(None);
        }
        passes += 1;
        on_pass(passes, &film);
        let elapsed = start.elapsed();
        // Estimated each pass only for a target; else once, at the end.
        let noise = rules.noise_target().and_then(|_| rules.noise(&film));
        if let Some(stop) =
            rules.stop_after(passes, noise, elapsed, elapsed.saturating_sub(last_end))
        {
            let noise = noise.or_else(|| rules.noise(&film));
            return Ok(Some(Rendered {
                film,
                paths,
                passes,
                noise,
                stop,
            }));
        }
        last_end = elapsed;
    }
}

/// [`render_blocking`] for one part of a split render: passes `passes` of
/// the pixels in `tile` ([`super::parts`]); `on_pass` receives the passes
/// done in the part.
pub fn render_part_blocking(
    renderer: &Renderer,
    passes: PassRange,
    tile: Tile,
    cancel: &AtomicBool,
    mut on_pass: impl FnMut(u32, &Film),
) -> Result<Option<(Film, u64)>, OutOfMemory> {
    renderer.check_memory()?;
    let mut film = renderer.try_new_film()?.for_part(passes, tile);
    let mut paths = 0;
    let is_cancelled = || cancel.load(Ordering::Relaxed);
    for pass in passes.start..passes.end {
        let stats = renderer.render_pass(&mut film, pass, &is_cancelled);
        paths += stats.paths;
        if !stats.completed {
            return Ok(None);
        }
        on_pass(pass + 1 - passes.start, &film);
    }
    Ok(Some((film, paths)))
}
