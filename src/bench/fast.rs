//! The fast mode ([`crate::render::fast`]) against the reference: its bias
//! and its noise per scene, and what a 4096 × 2048 export of it costs.
//!
//! Two fast images A′, B′ (seeds + 3 and + 4, the coarse Monte Carlo run
//! for half the budget each) give the fast mode's own noise n_f as A and B
//! give the reference's n_r ([`super::noise::relative_noise`]); the RMS
//! difference e between their mean and the reference's, relative to the
//! reference's mean over the whole image, then holds the bias b and both
//! noises: e² = b² + n_f² + n_r², so b = √(e² − n_f² − n_r²).

use std::time::Instant;

use serde::Serialize;

use super::noise::{relative_noise, render_for, time_to_noise, NoiseRun};
use crate::render::{fast, Renderer};
use crate::scene::{RenderMode, Scene};
use crate::spectrum::rec709_luminance;

/// The scales the bench measures (at its 256 × 128 images, coarse renders
/// of 128 × 64 and 64 × 32: 2.8° and 5.6° a pixel).
pub(super) const BENCH_SCALES: [u32; 2] = [2, 4];

/// The export the fast mode's cost is extrapolated to, pixels, and its
/// scale (the default, [`crate::scene::DEFAULT_FAST_SCALE`]).
const EXPORT: (u32, u32) = (4096, 2048);

/// One fast-mode measurement.
#[derive(Clone, Debug, Serialize)]
pub struct FastResult {
    /// The scene's name.
    pub scene: String,
    /// `fast_scale`.
    pub fast_scale: u32,
    /// The coarse render's width and height, pixels.
    pub coarse_size: (u32, u32),
    /// RMS relative luminance error of the fast mode's mean against the
    /// reference over the whole image (sun cone excluded), both images'
    /// noise taken out in quadrature: the bias.
    pub bias: f64,
    /// Relative noise of the fast mode's mean image over the whole image.
    pub noise_whole: f64,
    /// Mean luminance over the whole image, fast mode over reference.
    pub mean_ratio: f64,
    /// Render time of A′ and B′ (the coarse passes), s.
    pub seconds: f64,
    /// Time to compose one image (the model at full size and at the
    /// coarse one, the correction), s.
    pub compose_s: f64,
    /// Passes of A′ and B′.
    pub passes: [u32; 2],
    /// Time to 1 % whole-image noise of a 4096 × 2048 export at the
    /// default scale 8 (a 512 × 256 coarse render), extrapolated: the
    /// coarse render's time to that noise scaled by its pixels (noise
    /// ∝ 1/√time, time ∝ coarse pixels), plus composing scaled by the
    /// export's pixels.
    pub time_to_1pct_4k_s: f64,
}

/// Measures the fast mode of `scene` at `scale` against the reference of
/// `run` (the same scene's [`super::noise::measure_noise`]).
pub(super) fn measure_fast(
    name: &str,
    scene: &Scene,
    run: &NoiseRun,
    scale: u32,
    budget_s: f64,
    seed: u64,
) -> Result<FastResult, String> {
    let mut fast_scene = scene.clone();
    fast_scene.render.mode = RenderMode::Fast;
    fast_scene.render.fast_scale = scale;
    let mut images = Vec::new();
    let (mut seconds, mut passes, mut compose_s) = (0.0, [0; 2], 0.0);
    for (k, offset) in [3, 4].into_iter().enumerate() {
        let s = super::noise::with_seed(&fast_scene, seed, offset, "the fast mode")?;
        let coarse = Renderer::new(&fast::coarse_scene(&s)).map_err(|e| e.to_string())?;
        let r = render_for(&coarse, budget_s / 2.0);
        seconds += r.seconds;
        passes[k] = r.passes;
        let start = Instant::now();
        let image = fast::compose(&s, &coarse, &r.film).map_err(|e| e.to_string())?;
        compose_s = start.elapsed().as_secs_f64();
        images.push(
            image
                .pixels
                .iter()
                .map(|p| rec709_luminance(p.map(f64::from)))
                .collect::<Vec<f64>>(),
        );
    }
    let mask = &run.whole_mask;
    let noise_whole = relative_noise(&images[0], &images[1], mask);
    let mean: Vec<f64> = images[0]
        .iter()
        .zip(&images[1])
        .map(|(a, b)| 0.5 * (a + b))
        .collect();
    let error = relative_noise(&mean, &run.reference, mask) * 2.0;
    let bias = super::noise::without_noise(error, &[noise_whole, run.reference_noise]);
    let masked_sum = |image: &[f64]| -> f64 {
        image
            .iter()
            .zip(mask)
            .filter(|(_, &m)| m)
            .map(|(v, _)| v)
            .sum()
    };
    let coarse_size = fast::coarse_size(scene.render.width, scene.render.height, scale);
    let export_coarse = fast::coarse_size(EXPORT.0, EXPORT.1, crate::scene::DEFAULT_FAST_SCALE);
    let pixels = |(w, h): (u32, u32)| f64::from(w) * f64::from(h);
    let time_to_1pct_4k_s = time_to_noise(noise_whole, seconds, 0.01) * pixels(export_coarse)
        / pixels(coarse_size)
        + compose_s * pixels(EXPORT) / pixels((scene.render.width, scene.render.height));
    Ok(FastResult {
        scene: name.to_owned(),
        fast_scale: scale,
        coarse_size,
        bias,
        noise_whole,
        mean_ratio: masked_sum(&mean) / masked_sum(&run.reference),
        seconds,
        compose_s,
        passes,
        time_to_1pct_4k_s,
    })
}
