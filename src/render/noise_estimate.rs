//! A render's noise estimated from its own passes, and the rules that stop
//! a render early: at a noise target or a time limit (`[render]
//! noise_percent`, `time_limit_s`; `render --noise`, `--time-limit`).
//!
//! **The estimate.** The film's variance layer ([`Film::variance_plane`])
//! gives, per pixel, the variance of its mean luminance from the spread of
//! its passes. The image's relative noise is the RMS of that noise over its
//! mean: √(Σᵢ Var(Ȳᵢ)/n) / (Σᵢ Ȳᵢ/n), over every pixel with a ray and light
//! (n of them), those within [`SUN_CONE_DEG`] of the sun's centre left
//! out — the figure `skyrender bench` measures from two independent
//! renders as its whole image's noise (`BENCHMARKS.md`, "What the user
//! sees"), here from one render. Against that two-render figure the
//! estimate reads low while a few heavy-tailed passes are all it has (the
//! draft pass, another estimator, is not in its spread; on Mars at sunset
//! 0.62× after 3 passes, 0.83× after 5) and slightly high later (the
//! passes' low-discrepancy points and wavelengths are stratified against
//! each other, which it takes for independent: 1.07–1.10× after 8 passes
//! from orbit and at midday, 1.03× with independent points; the decisions
//! table of `BENCHMARKS.md`): a noise target stops a render no sooner
//! than [`MIN_PASSES`].
//! `tests/noise_target.rs` checks it against two renders.
//!
//! A render stopped by its own noise is, strictly, no longer a fixed-count
//! average, but the rule reads one number for the whole image after whole
//! passes, so a pixel's mean cannot steer it.

use std::time::Duration;

use glam::DVec3;

use super::camera::Camera;
use super::{Film, Renderer};

/// Half-angle of the cone about the sun's centre left out of the noise,
/// degrees: the disc (0.27°) and its aureole's steepest part, whose
/// pixels' variance says more about the pixel grid than the render.
pub const SUN_CONE_DEG: f64 = 2.0;

/// The fewest passes (the draft included) after which a noise target may
/// stop a render: after 8 the estimate was within 0.99–1.10× of the noise
/// two renders measure at every bench scene (midday, sunset, twilight,
/// from orbit, Mars at sunset; 256×128, seeds 11 and 12), after 5 as low
/// as 0.83×.
pub const MIN_PASSES: u32 = 8;

/// The pixels (row-major) whose centre's ray is farther than
/// [`SUN_CONE_DEG`] from `sun` and for which `keep(index, direction)`
/// holds.
pub fn outside_sun_cone(
    camera: &Camera,
    width: u32,
    height: u32,
    sun: DVec3,
    keep: impl Fn(usize, DVec3) -> bool,
) -> Vec<bool> {
    let cos_cone = SUN_CONE_DEG.to_radians().cos();
    (0..height)
        .flat_map(|y| (0..width).map(move |x| (x, y)))
        .enumerate()
        .map(|(i, (x, y))| {
            camera
                .direction(f64::from(x) + 0.5, f64::from(y) + 0.5)
                .is_some_and(|dir| dir.normalize().dot(sun) < cos_cone && keep(i, dir))
        })
        .collect()
}

/// The relative noise of `film`'s image (see the module documentation) over
/// `mask`'s pixels with light; `None` before the film's variance layer has
/// two passes (or where it keeps none) or where no masked pixel has light.
pub fn relative_noise(film: &Film, mask: &[bool]) -> Option<f64> {
    let variance = film.variance_plane()?;
    let w = film.width as usize;
    let luminance: Vec<f64> = (0..variance.len())
        .map(|i| film.xyz((i % w) as u32, (i / w) as u32)[1])
        .collect();
    relative_noise_of(&variance, &luminance, mask)
}

/// [`relative_noise`] from each pixel's `variance` of its mean luminance
/// and that mean, `luminance` (row-major, cd m⁻²), over `mask`.
pub fn relative_noise_of(variance: &[f32], luminance: &[f64], mask: &[bool]) -> Option<f64> {
    let (mut n, mut variance_sum, mut luminance_sum) = (0usize, 0.0, 0.0);
    for ((&keep, &v), &y) in mask.iter().zip(variance).zip(luminance) {
        if keep && y > 0.0 && y.is_finite() {
            n += 1;
            variance_sum += f64::from(v);
            luminance_sum += y;
        }
    }
    (n > 0 && luminance_sum > 0.0)
        .then(|| (variance_sum / n as f64).sqrt() / (luminance_sum / n as f64))
}

/// Why a render stopped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// It rendered every pass it was asked for (`spp`).
    Passes,
    /// Its estimated noise reached the target.
    NoiseTarget,
    /// The next pass would have ended past the time limit.
    TimeLimit,
}

impl Stop {
    /// The reason in words (the EXR header's `skyrender:stopped_by`).
    pub fn describe(self) -> &'static str {
        match self {
            Self::Passes => "passes",
            Self::NoiseTarget => "noise target",
            Self::TimeLimit => "time limit",
        }
    }
}

/// The stopping rules of one render ([`crate::scene::RenderParams`]'s
/// `spp`, `noise_percent` and `time_limit_s`).
pub struct StopRules {
    passes: u32,
    /// Passes a time limit lets run whatever the time: 1, or 3 where the
    /// output has the variance layer (the spread of the passes after the
    /// first).
    least_passes: u32,
    noise_target: Option<f64>,
    time_limit: Option<Duration>,
    /// The pixels the noise is estimated over; empty where the film keeps
    /// no variance layer.
    mask: Vec<bool>,
}

impl StopRules {
    /// The rules of `renderer`'s scene; the noise is estimated wherever its
    /// films keep the variance layer (a noise target, or the layer asked
    /// for).
    pub fn new(renderer: &Renderer) -> Self {
        let r = &renderer.scene.render;
        let mask = if renderer.variance_sums() {
            outside_sun_cone(
                renderer.camera(),
                r.width,
                r.height,
                renderer.sun_direction(),
                |_, _| true,
            )
        } else {
            Vec::new()
        };
        Self {
            passes: r.spp,
            least_passes: if renderer.variance_layer() { 3 } else { 1 },
            noise_target: r.noise_percent.map(|p| p / 100.0),
            time_limit: r.time_limit_s.map(Duration::from_secs_f64),
            mask,
        }
    }

    /// The passes asked for: at most this many are rendered.
    pub fn max_passes(&self) -> u32 {
        self.passes
    }

    /// The noise target, relative (0.01: 1 %), if any.
    pub fn noise_target(&self) -> Option<f64> {
        self.noise_target
    }

    /// The relative noise of `film` over the rules' pixels, where it can be
    /// estimated.
    pub fn noise(&self, film: &Film) -> Option<f64> {
        (!self.mask.is_empty())
            .then(|| relative_noise(film, &self.mask))
            .flatten()
    }

    /// Whether to stop after `done` passes (`done` ≥ 1) whose relative
    /// noise is `noise`,
    /// `elapsed` after the start, the last pass having taken `last_pass`;
    /// `None`: render the next pass.
    pub fn stop_after(
        &self,
        done: u32,
        noise: Option<f64>,
        elapsed: Duration,
        last_pass: Duration,
    ) -> Option<Stop> {
        if done >= self.passes {
            return Some(Stop::Passes);
        }
        if let (Some(target), Some(noise)) = (self.noise_target, noise) {
            if done >= MIN_PASSES && noise <= target {
                return Some(Stop::NoiseTarget);
            }
        }
        self.time_limit
            .filter(|&limit| done >= self.least_passes && elapsed + last_pass > limit)
            .map(|_| Stop::TimeLimit)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rules(passes: u32, noise_percent: Option<f64>, limit_s: Option<f64>) -> StopRules {
        StopRules {
            passes,
            least_passes: 1,
            noise_target: noise_percent.map(|p| p / 100.0),
            time_limit: limit_s.map(Duration::from_secs_f64),
            mask: vec![true],
        }
    }

    const S: fn(f64) -> Duration = Duration::from_secs_f64;

    /// Each rule stops the render, and only when it says: the passes
    /// asked for at most; a noise target once met and no sooner than
    /// [`MIN_PASSES`]; a time limit before a pass that would end past it.
    #[test]
    fn each_rule_stops_when_it_says() {
        let plain = rules(10, None, None);
        assert_eq!(plain.stop_after(9, Some(0.0), S(1e6), S(1.0)), None);
        assert_eq!(
            plain.stop_after(10, None, S(0.0), S(0.0)),
            Some(Stop::Passes)
        );
        let noise = rules(100, Some(1.0), None);
        assert_eq!(
            noise.stop_after(MIN_PASSES, Some(0.0101), S(1.0), S(1.0)),
            None
        );
        assert_eq!(
            noise.stop_after(MIN_PASSES - 1, Some(0.001), S(1.0), S(1.0)),
            None
        );
        assert_eq!(
            noise.stop_after(MIN_PASSES, Some(0.01), S(1.0), S(1.0)),
            Some(Stop::NoiseTarget)
        );
        assert_eq!(noise.stop_after(MIN_PASSES, None, S(1.0), S(1.0)), None);
        let limit = rules(100, None, Some(10.0));
        assert_eq!(limit.stop_after(3, None, S(7.0), S(2.9)), None);
        assert_eq!(
            limit.stop_after(3, None, S(7.0), S(3.1)),
            Some(Stop::TimeLimit)
        );
        // With the variance layer, three passes at least.
        let layer = StopRules {
            least_passes: 3,
            ..rules(100, None, Some(1.0))
        };
        assert_eq!(layer.stop_after(2, None, S(9.0), S(1.0)), None);
        assert_eq!(
            layer.stop_after(3, None, S(9.0), S(1.0)),
            Some(Stop::TimeLimit)
        );
        // The passes asked for come first, then the noise.
        let both = rules(MIN_PASSES, Some(5.0), Some(1.0));
        assert_eq!(
            both.stop_after(MIN_PASSES, Some(0.01), S(9.0), S(1.0)),
            Some(Stop::Passes)
        );
    }
}
