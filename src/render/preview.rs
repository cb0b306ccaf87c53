//! What the app's preview shows as a render goes on, step by step: the
//! approximate sky model first ([`super::sky_model`], tens of
//! milliseconds), then the model corrected by a coarse Monte Carlo render
//! (the fast mode's image, [`super::fast`], at a quarter of the width and
//! height: each coarse pass costs a sixteenth of a full one; its
//! correction denoised by what the passes' two halves bear out,
//! `render::denoise`; shown once four full coarse passes are in), then the
//! full-size passes, blended with the corrected model until their noise
//! falls below its error ([`model_weight_with`]). The finished image is
//! the passes alone: only the preview ever shows the model.
//!
//! A full pass at sunset takes seconds on two cores; the model alone is
//! 1–5 % off; corrected, two seconds after a change, about 0.3 % at
//! midday, 0.9–1.3 % from orbit and on Mars at noon, 0.8–1.6 % at sunset
//! and twilight, and 4–5 % on Mars at sunset, where the model's own error
//! is left (`BENCHMARKS.md`).

use std::time::{Duration, Instant};

use super::sky_model::SkyModel;
use super::{fast, noise_estimate, Film, Renderer};
use crate::output::RgbImage;
use crate::spectrum::rec709_luminance;

/// The sky model's typical RMS error over a whole image, relative to its
/// mean luminance: 1–11 % over the bench's scenes (`BENCHMARKS.md`, "The
/// sky model's first frame"); the blend's weight takes the larger.
pub const MODEL_ERROR: f64 = 0.1;

/// See [`model_weight`]: a pixel of the passes this many times the model's
/// is the sun's disc (10⁵–10⁶ times the sky) or a rare bright sample, not
/// the spread that sets the blend.
pub const OUTLIER_RATIO: f64 = 100.0;

/// The approximate sky model's share in a preview frame, from the passes'
/// image so far (`passes`) and the model's (`model`). With independent
/// errors, the model's bias m and the passes' noise σ, the blend
/// (1 − w) passes + w model has the least mean squared error at
/// w = σ²/(σ² + m²). The squared RMS difference between the two images,
/// relative to the mean, D² ≈ m² + σ², gives σ² ≈ D² − m²; with m =
/// [`MODEL_ERROR`], w = 1 − m²/D² (0 where D ≤ m): the noisier the
/// passes, the more of the frame the model keeps, until enough passes are
/// in. Pixels where the passes exceed the model [`OUTLIER_RATIO`]-fold are
/// left out of D: the sun's disc, which the model lacks, would otherwise
/// hold the weight at 1 whenever the sun is in view. Only the app's
/// preview blends: renders and exports are the passes alone.
pub fn model_weight(passes: &RgbImage, model: &RgbImage) -> f64 {
    model_weight_with(passes, model, MODEL_ERROR)
}

/// [`model_weight`] for a model of typical relative RMS error `error`
/// (the corrected model's, [`CORRECTED_ERROR`]).
pub fn model_weight_with(passes: &RgbImage, model: &RgbImage, error: f64) -> f64 {
    let y = |p: &[f32; 3]| crate::spectrum::rec709_luminance(p.map(f64::from));
    let (mut diff2, mut sum, mut n) = (0.0, 0.0, 0.0);
    for (p, m) in passes.pixels.iter().zip(&model.pixels) {
        let (a, b) = (y(p), y(m));
        if a.is_finite() && b.is_finite() && a <= OUTLIER_RATIO * b.max(0.0) {
            diff2 += (a - b) * (a - b);
            sum += b;
            n += 1.0;
        }
    }
    if n == 0.0 || sum <= 0.0 {
        return 0.0;
    }
    let relative2 = diff2 / n / (sum / n).powi(2);
    if relative2 <= error * error {
        0.0
    } else {
        1.0 - error * error / relative2
    }
}

/// The coarse render's width and height are the preview's over this.
pub const PREVIEW_SCALE: u32 = 4;
/// Coarse passes before the full-size ones: the work of four full passes
/// at [`PREVIEW_SCALE`] (16 coarse passes cost about one full one), by
/// when the corrected model's noise is below its bias.
pub const PREVIEW_COARSE_PASSES: u32 = 64;
/// Coarse passes before the first corrected model: the draft and four full
/// passes, two in each half (`Film::variance_halves`) by which the
/// correction is told from its noise (`render::denoise`). Shown as it was,
/// the draft's correction took twilight's preview 700–900 % off for a
/// quarter of a second, one full pass's 15–30 %; from one full pass in
/// each half (the third coarse pass) the halves' check let frames up to
/// 2.8 % off through at twilight and 2.3 % at sunset, where the model is
/// 1.6 % and 1.9 % off.
pub const FIRST_COMPOSED_PASS: u32 = 5;
/// The corrected model's typical RMS error over a whole image, relative to
/// its mean luminance, after [`PREVIEW_COARSE_PASSES`]: bias and the
/// coarse passes' noise, 1–4 % over the bench's scenes (`BENCHMARKS.md`).
pub const CORRECTED_ERROR: f64 = 0.03;

/// One image the preview shows.
#[derive(Clone, Debug)]
pub struct Shown {
    /// Linear Rec.709, Y in cd m⁻², at the scene's size.
    pub image: RgbImage,
    /// Full-size passes in `image`.
    pub spp: u32,
    /// Coarse passes behind the correction of the model in `image`.
    pub coarse_passes: u32,
    /// The model's share (corrected or not) in `image`, 0–1.
    pub model_weight: f64,
    /// The full-size passes are all done.
    pub finished: bool,
    /// The full-size passes' estimated relative noise (0.01: 1 %; what the
    /// finished image will have had at this pass count), from
    /// [`noise_estimate::MIN_PASSES`] passes on; `None` before.
    pub noise: Option<f64>,
}

/// The coarse render behind the corrected model.
struct CoarsePhase {
    renderer: Renderer,
    model: RgbImage,
    /// Where each of the preview's pixels takes its correction.
    places: Vec<Option<fast::Place>>,
    film: Film,
    passes: u32,
    /// How long the last composition took.
    compose_time: Duration,
}

/// A preview of one renderer's scene, advanced one step at a time.
pub struct Preview<'a> {
    renderer: &'a Renderer,
    /// The scene's approximate sky, imaged at the preview's size and, for
    /// the correction, at the coarse one.
    sky: SkyModel,
    model: RgbImage,
    coarse: Option<CoarsePhase>,
    /// The coarse phase is over (done, not wanted, or not possible).
    coarse_done: bool,
    corrected: Option<RgbImage>,
    film: Film,
    /// The pixels the passes' noise is estimated over
    /// ([`noise_estimate::outside_sun_cone`]); empty where the film keeps
    /// no variance sums.
    noise_mask: Vec<bool>,
    pass: u32,
    coarse_passes: u32,
    /// Camera paths traced, coarse and full-size.
    pub paths: u64,
}

impl<'a> Preview<'a> {
    /// The preview of `renderer`'s scene: its first image is the model's.
    pub fn new(renderer: &'a Renderer) -> Self {
        let r = &renderer.scene.render;
        // A one-pass draft, or an image too small to have a coarser one,
        // goes straight to its passes.
        let coarse_wanted =
            r.spp > 1 && r.width >= 4 * PREVIEW_SCALE && r.height >= 2 * PREVIEW_SCALE;
        let sky = renderer.sky_model();
        // The variance layer's sums (five numbers a pixel), for the noise
        // the status bar shows; a preview without them where they do not fit.
        let (film, noise_mask) = match renderer.new_film().try_with_variance() {
            Ok(film) => {
                let mask = noise_estimate::outside_sun_cone(
                    renderer.camera(),
                    r.width,
                    r.height,
                    renderer.sun_direction(),
                    |_, _| true,
                );
                (film, mask)
            }
            Err(_) => (renderer.new_film(), Vec::new()),
        };
        Self {
            renderer,
            model: sky.image(renderer.camera(), r.width, r.height),
            sky,
            coarse: None,
            coarse_done: !coarse_wanted,
            corrected: None,
            film,
            noise_mask,
            pass: 0,
            coarse_passes: 0,
            paths: 0,
        }
    }

    /// The model's image: the first frame.
    pub fn model(&self) -> &RgbImage {
        &self.model
    }

    /// The film of the full-size passes.
    pub fn film(&self) -> &Film {
        &self.film
    }

    /// Renders the next step — a coarse pass while the correction is being
    /// made, else a full-size pass — and returns the image to show, or
    /// `None` once every pass is done or `stale` stopped the step.
    pub fn step(&mut self, stale: &(dyn Fn() -> bool + Sync)) -> Option<Shown> {
        let target = self.renderer.scene.render.spp;
        if self.pass >= target {
            return None;
        }
        if !self.coarse_done {
            if let Some(shown) = self.coarse_step(stale) {
                return Some(shown);
            }
            if stale() {
                return None;
            }
        }
        let stats = self.renderer.render_pass(&mut self.film, self.pass, stale);
        self.paths += stats.paths;
        if !stats.completed {
            return None;
        }
        self.pass += 1;
        let mut image = self.film.to_rgb();
        let noise = self.noise(&image);
        let finished = self.pass >= target;
        let (model, error) = match &self.corrected {
            Some(corrected) => (corrected, CORRECTED_ERROR),
            None => (&self.model, MODEL_ERROR),
        };
        let w = if finished {
            0.0
        } else {
            model_weight_with(&image, model, error)
        };
        if w > 0.0 {
            for (p, m) in image.pixels.iter_mut().zip(&model.pixels) {
                *p = std::array::from_fn(|c| {
                    ((1.0 - w) * f64::from(p[c]) + w * f64::from(m[c])) as f32
                });
            }
        }
        Some(Shown {
            image,
            spp: self.pass,
            coarse_passes: self.coarse_passes,
            model_weight: w,
            finished,
            noise,
        })
    }

    /// The full passes' estimated noise, from their `image` (before any
    /// blend) and the film's variance, once [`noise_estimate::MIN_PASSES`]
    /// are in.
    fn noise(&self, image: &RgbImage) -> Option<f64> {
        if self.pass < noise_estimate::MIN_PASSES || self.noise_mask.is_empty() {
            return None;
        }
        let variance = self.film.variance_plane()?;
        let luminance: Vec<f64> = image
            .pixels
            .iter()
            .map(|p| rec709_luminance(p.map(f64::from)))
            .collect();
        noise_estimate::relative_noise_of(&variance, &luminance, &self.noise_mask)
    }

    /// Coarse passes (as many as took as long as the last composition) and
    /// the model corrected by the passes so far; `None`
    /// where the phase ends (its last pass done, or no coarse render to be
    /// had) or `stale` stopped the pass.
    fn coarse_step(&mut self, stale: &(dyn Fn() -> bool + Sync)) -> Option<Shown> {
        if self.coarse.is_none() {
            let mut scene = self.renderer.scene.clone();
            scene.render.fast_scale = PREVIEW_SCALE;
            // The coarse scene is the valid scene at a smaller size: should
            // it still be refused, the preview goes on without it.
            let mut coarse_scene = fast::coarse_scene(&scene);
            // The passes' halves, by which the correction is denoised
            // (render::denoise).
            coarse_scene.output.layers.push("variance".into());
            let Ok(renderer) = Renderer::new(&coarse_scene) else {
                self.coarse_done = true;
                return None;
            };
            let c = &renderer.scene.render;
            let mut film = renderer.new_film();
            if film.try_keep_variance_halves().is_err() {
                self.coarse_done = true;
                return None;
            }
            self.coarse = Some(CoarsePhase {
                model: self.sky.image(renderer.camera(), c.width, c.height),
                places: fast::places(self.renderer.camera(), &renderer),
                film,
                renderer,
                passes: 0,
                compose_time: Duration::ZERO,
            });
        }
        let phase = self.coarse.as_mut()?;
        // Composing the image costs about a coarse pass at midday, a
        // fifth of one at sunset: passes go on until they have taken as
        // long as the last composition did.
        let started = Instant::now();
        loop {
            let stats = phase
                .renderer
                .render_pass(&mut phase.film, phase.passes, stale);
            self.paths += stats.paths;
            if !stats.completed {
                return None;
            }
            phase.passes += 1;
            let composable = phase.passes >= FIRST_COMPOSED_PASS;
            if composable
                && (started.elapsed() >= phase.compose_time
                    || phase.passes >= PREVIEW_COARSE_PASSES)
            {
                break;
            }
        }
        let composing = Instant::now();
        self.coarse_passes = phase.passes;
        self.coarse_done = phase.passes >= PREVIEW_COARSE_PASSES;
        let corrected = fast::correct(
            &self.renderer.scene,
            self.renderer.camera(),
            self.model.clone(),
            &phase.renderer,
            &phase.model,
            &phase.film,
            Some(&phase.places),
        );
        if self.coarse_done {
            // The full-size passes need the memory more.
            self.coarse = None;
        }
        let Ok(corrected) = corrected else {
            self.coarse_done = true;
            return None;
        };
        let mut image = corrected;
        if let Some(phase) = self.coarse.as_mut() {
            phase.compose_time = composing.elapsed();
        }
        // The coarse passes' noise can take a dark pixel below zero; the
        // preview shows it black (the export of the fast mode keeps it).
        for p in &mut image.pixels {
            if rec709_luminance(p.map(f64::from)) < 0.0 {
                *p = [0.0; 3];
            }
        }
        self.corrected = Some(image.clone());
        Some(Shown {
            image,
            spp: 0,
            coarse_passes: self.coarse_passes,
            model_weight: 1.0,
            finished: false,
            noise: None,
        })
    }
}
