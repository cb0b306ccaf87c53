//! Rendering: a [`Renderer`] turns a validated [`Scene`] into samples on a
//! [`Film`], one pass at a time, in parallel over rows with rayon.
//!
//! Determinism: every pixel sample draws from its own generator seeded by
//! (scene seed, the pixel's sample number, pixel), each pixel sums its
//! samples in order, and the adaptive plan is a function of the image, so
//! the image does not depend on the number of threads. The splatted paths
//! ([`circles`]) each draw from a generator of their own, and their splats
//! are added in the paths' order.

pub mod camera;
pub mod circles;
pub mod columns;
pub mod control;
pub mod directions;
pub mod exact;
pub mod film;
pub mod film_layers;
pub mod film_spectral;
pub mod guide;
pub mod integrator;
pub mod layers;
pub mod medium;
pub mod memory;
pub mod parts;
pub mod probe;
pub mod service;
pub mod splatting;
pub mod sunlight;
pub mod trig;

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, OnceLock};

use glam::DVec3;
use rayon::prelude::*;

pub use camera::{direction_from_az_el, Camera};
pub use film::{Film, Mirror, MirrorAxis};
pub use integrator::{Integrator, IntegratorOptions, Sampler};
pub use medium::{
    LaneTable, Lanes, Medium, SolarSource, SpectralLanes, TransmittanceEstimator, LANES,
};
pub use memory::OutOfMemory;
pub use probe::SpectralEstimate;

/// The sun for `scene`: unit, or the measured spectrum (the built-in
/// table or `[sun] spectrum`) at the scene's Earth–Sun distance
/// ([`Scene::sun_distance_au`]), with its disc limb-darkened or uniform
/// (`[sun] limb_darkening`).
pub fn solar_source(scene: &Scene) -> SolarSource {
    let file = scene
        .sun_spectrum()
        .expect("a validated scene's sun spectrum (Scene::validate reads it)");
    SolarSource::at_distance(scene.render.unit_sun, scene.sun_distance_au())
        .with_spectrum(file.as_deref())
        .with_limb_darkening(scene.sun.limb_darkening)
}

use crate::atmosphere::Atmosphere;
use crate::rng::{Rng, SOBOL_POINTS};
use crate::scene::{Scene, SceneError};
use crate::spectrum::{ColourMatching, K_M};
use circles::CircleSplatter;
use exact::ExactSum;
use film_layers::SampleSplit;
use film_spectral::SampleLanes;
use sunlight::CameraDensities;

/// (√5 − 1)/2: the additive recurrence with this step is the most evenly
/// spread 1-D sequence (Weyl; the three-distance theorem).
const GOLDEN_RATIO_CONJUGATE: f64 = 0.618_033_988_749_894_8;

/// With adaptive sampling on, the pass whose start fixes each pixel's
/// samples per pass (see [`film`]): after the draft and the first
/// full pass, so the plan reads one full sample per pixel.
pub const ADAPTIVE_FROM_PASS: u32 = 2;

/// The draft pass's weight in the film's average for the sun at
/// `sun_elevation_deg` above the observer's horizon; every later sample
/// weighs 1. Weights ∝ 1/variance minimise the mean's, and the draft's
/// delta-tracked camera paths (see `Renderer::integrator`) have, per
/// path, 6–16× the variance of a full pass's by day (sun 45°), 23–49× with
/// the sun at 2° and 58–147× at −4°, where a rare collision in the sunlit
/// air high above carries the light (four views at elevations 7–74°,
/// `BENCHMARKS.md`). Any fixed weight keeps the mean unbiased;
/// a positive one lets the draft alone show a first image. By day 1/8 (at 1
/// the draft doubled the upper sky's variance in a 24-pass midday render);
/// at twilight 1/8 nearly doubled the single-scattered light's
/// variance over 8 passes (absolute noise 0.296 against 0.216 with 1/100).
pub fn draft_weight(sun_elevation_deg: f64) -> f64 {
    if sun_elevation_deg < 0.0 {
        1.0 / 128.0
    } else if sun_elevation_deg < integrator::LOW_SUN_ELEVATION_DEG {
        1.0 / 32.0
    } else {
        1.0 / 8.0
    }
}

/// The pixel pairs a film of `scene` reads together ([`film`]): its camera's
/// image of the reflection in the sun's vertical plane ([`Camera::mirror`]),
/// where `[render] mirror_symmetry` is on and that reflection takes pixels
/// onto pixels; `None` otherwise.
pub fn mirror_pairs(scene: &Scene) -> Option<Mirror> {
    let camera = Camera::new(&scene.camera, scene.render.width, scene.render.height);
    scene
        .render
        .mirror_symmetry
        .then(|| camera.mirror(scene.sun.azimuth_deg))
        .flatten()
}

/// A scene made ready to render.
pub struct Renderer {
    pub scene: Scene,
    pub atmosphere: Atmosphere,
    medium: Medium,
    camera: Camera,
    cmf: &'static ColourMatching,
    /// Per-wavelength constants over the colour-matching range.
    lane_table: LaneTable,
    sun_direction: DVec3,
    observer_m: DVec3,
    /// Expected-sunlight densities of camera rays, built per view direction
    /// on first use.
    camera_densities: CameraDensities,
    /// Incoming once-scattered light by direction at scattering points,
    /// built per (altitude, solar zenith) cell on first use; only for the
    /// options that use it (`sky_guide`, `shadow_samples`,
    /// `sunlight_samples`, `camera_importance`); shared with the camera
    /// densities, which read its skylight as their importance.
    sky_guide: Option<Arc<guide::SkyGuide>>,
    /// The once-scattered light's table for the control variate, where the
    /// scene's options turn it on (`control_variate`).
    control: Option<control::RadianceTable>,
    /// The scene's integrator options, every unset choice made for the scene
    /// ([`IntegratorOptions::resolved`]).
    options: IntegratorOptions,
    /// The scene's integrator options with plain delta-tracked camera rays
    /// and shadow rays through the shells, for the first pass (see
    /// [`Self::integrator`]).
    draft_options: IntegratorOptions,
    /// The draft pass's weight in the film's average ([`draft_weight`]).
    draft_weight: f64,
    /// The pixel pairs the film reads together (`mirror_symmetry`).
    mirror: Option<Mirror>,
    /// Whether the light scattered more than once in the air is splatted
    /// along the scene's circles of symmetry (`circle_splatting`).
    splatting: bool,
    /// The splatter, built on first use (after the draft pass).
    circles: OnceLock<Option<CircleSplatter>>,
}

/// Where a pixel takes its low-discrepancy numbers
/// ([`Renderer::sequence_slot`]): sample k uses point k × `stride` +
/// `offset` of `pixel`'s sequences.
#[derive(Clone, Copy, Debug)]
struct SequenceSlot {
    pixel: u64,
    stride: u64,
    offset: u64,
    /// The mirror axis to reflect the position within the pixel across.
    reflect: Option<MirrorAxis>,
}

/// Result of one pass.
#[derive(Clone, Copy, Debug, Default)]
pub struct PassStats {
    /// Whether every row was rendered (false if cancelled).
    pub completed: bool,
    /// Camera paths traced.
    pub paths: u64,
    /// Paths splatted along the circles of symmetry ([`circles`]).
    pub splat_paths: u64,
    /// Samples (and splats) discarded as non-finite (or negative without
    /// the control variate).
    pub discarded: u64,
    /// The splats among `discarded`.
    pub splat_discarded: u64,
}

impl Renderer {
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        scene.validate()?;
        let atmosphere = Atmosphere::new(scene.atmosphere.clone());
        let medium = Medium::new(&atmosphere);
        let camera = Camera::new(&scene.camera, scene.render.width, scene.render.height);
        let cmf = ColourMatching::get(scene.render.observer);
        let observer_m = DVec3::new(
            0.0,
            0.0,
            scene.atmosphere.planet_radius_m + scene.observer.altitude_m,
        );
        let sun_direction = direction_from_az_el(scene.sun.azimuth_deg, scene.sun.elevation_deg);
        let mut options = scene
            .render
            .integrator
            .resolved(scene.sun.elevation_deg, &scene.atmosphere);
        // Without circles (the sun at the zenith or nadir), or from above
        // the air (where the scene refuses it when asked for), the camera's
        // branches keep every order.
        let splatting = options.circle_splatting == Some(true)
            && options.camera_samples() > 0
            && options.next_event_estimation
            && scene.observer.altitude_m < scene.atmosphere.top_altitude_m
            && circles::has_circles(observer_m, sun_direction);
        options.camera_samples = Some(options.camera_samples.unwrap_or(if splatting {
            integrator::SPLAT_CAMERA_SAMPLES
        } else {
            integrator::CAMERA_SAMPLES
        }));
        // Camera branches drawn partly by the light the guide expects them
        // to find ([`IntegratorOptions::camera_importance`]), where camera
        // rays use their densities at all.
        let camera_importance = Some(options.camera_importance())
            .filter(|&share| share > 0.0 && options.camera_samples() > 0);
        let sky_guide = {
            let i = &options;
            (i.sky_guide() > 0.0
                || i.shadow_samples > 0
                || i.sunlight_samples() > 0
                || camera_importance.is_some())
            .then(|| Arc::new(guide::SkyGuide::new(&medium, sun_direction)))
        };
        let camera_densities = CameraDensities::new(&medium, observer_m, sun_direction);
        let camera_densities = match (&sky_guide, camera_importance) {
            (Some(guide), Some(share)) => {
                let guide = Arc::clone(guide);
                camera_densities.with_importance(
                    share,
                    Arc::new(move |medium: &Medium, x: DVec3| guide.skylight(medium, x)),
                )
            }
            _ => camera_densities,
        };
        Ok(Self {
            camera_densities,
            sky_guide,
            control: (options.control_variate == Some(true)).then(|| {
                control::RadianceTable::new(
                    medium.planet_radius_m,
                    medium.top_radius_m,
                    sun_direction,
                    cmf.range_nm(),
                )
            }),
            draft_weight: draft_weight(scene.sun.elevation_deg),
            mirror: mirror_pairs(scene),
            splatting,
            circles: OnceLock::new(),
            draft_options: IntegratorOptions {
                camera_samples: Some(0),
                control_variate: Some(false),
                sky_guide: Some(0.0),
                sunlight_samples: Some(0),
                shadow_samples: 0,
                // The Sobol prefix costs ~4 % of a full path and the draft's
                // single pass gains nothing from stratification across passes.
                sampler: Sampler::Independent,
                // The column table takes ~20 ms to build: not in the first frame.
                shadow_transmittance: match options.shadow_transmittance {
                    TransmittanceEstimator::ResidualRatioTracking => {
                        TransmittanceEstimator::ChordResidualRatioTracking
                    }
                    other => other,
                },
                ..options.clone()
            },
            options,
            observer_m,
            sun_direction,
            cmf,
            lane_table: LaneTable::new(&medium, cmf.range_nm(), solar_source(scene)),
            scene: scene.clone(),
            atmosphere,
            medium,
            camera,
        })
    }

    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    pub fn sun_direction(&self) -> DVec3 {
        self.sun_direction
    }

    /// The weight of pass `pass` in the film's average: the draft's
    /// ([`draft_weight`]) or 1.
    fn pass_weight(&self, pass: u32) -> f64 {
        if pass == 0 {
            self.draft_weight
        } else {
            1.0
        }
    }

    /// The integrator for pass `pass`. The first pass traces plain
    /// delta-tracked camera paths (no camera-ray densities to build, no
    /// branches), so the first image of a progressive render — the preview's
    /// first frame — comes fast; every pass is an unbiased estimate, so the
    /// film's average of them stays unbiased.
    fn integrator(&self, pass: u32) -> Integrator<'_> {
        let options = if pass == 0 {
            &self.draft_options
        } else {
            &self.options
        };
        let integrator = Integrator::new(&self.medium, options, self.sun_direction)
            .with_camera_densities(&self.camera_densities);
        let integrator = match &self.sky_guide {
            Some(guide) => integrator.with_sky_guide(guide),
            None => integrator,
        };
        match &self.control {
            Some(table) => integrator.with_control(table),
            None => integrator,
        }
    }

    /// Wavelengths each path carries (`wavelengths_per_path`, 1–[`LANES`]).
    fn lanes_per_path(&self) -> usize {
        self.scene
            .render
            .integrator
            .wavelengths_per_path
            .clamp(1, LANES)
    }

    /// Hero-rotated wavelengths for one path: lane k uses u₀ + k/n (mod 1)
    /// through the importance CDF, so each lane is distributed by the CMF-based
    /// density and the lanes are stratified (Wilkie et al. 2014).
    fn sample_lanes(&self, u0: f64) -> (SpectralLanes, Lanes) {
        let n = self.lanes_per_path();
        let mut wavelengths = [0.0; LANES];
        let mut pdfs = [0.0; LANES];
        for k in 0..LANES {
            let (w, p) = self
                .cmf
                .sample_wavelength((u0 + (k % n) as f64 / n as f64).fract());
            wavelengths[k] = w;
            pdfs[k] = p;
        }
        (self.lane_table.lanes(wavelengths, n, &self.medium), pdfs)
    }

    /// Where pixel (`x`, `y`) takes its low-discrepancy numbers: a pixel
    /// and its mirror image are read as one ([`film`]), so they share one
    /// pixel's sequences — the lower index's, the lower pixel taking the
    /// even points, its partner the odd ones — and a pair's samples are one
    /// stratified set rather than two. The partner's position in its pixel
    /// is reflected across the mirror's axis, which makes its points the
    /// physical reflection of the ones it would have had in the lower pixel
    /// (so the pixel-position coordinates stay stratified over the pair).
    /// Each pixel's samples stay uniform, so its mean stays unbiased. At
    /// fixed passes over four seed pairs, 0.96× the variance at sunset,
    /// 0.93× at midday, 0.99× at twilight (`BENCHMARKS.md`).
    fn sequence_slot(&self, x: u32, y: u32) -> SequenceSlot {
        let (width, height) = (self.scene.render.width, self.scene.render.height);
        let pixel = u64::from(y) * u64::from(width) + u64::from(x);
        let alone = SequenceSlot {
            pixel,
            stride: 1,
            offset: 0,
            reflect: None,
        };
        let Some(mirror) = self.mirror else {
            return alone;
        };
        let partner =
            mirror.partner(x as usize, y as usize, width as usize, height as usize) as u64;
        if partner == pixel {
            return alone;
        }
        let upper = pixel > partner;
        SequenceSlot {
            pixel: pixel.min(partner),
            stride: 2,
            offset: u64::from(upper),
            reflect: upper.then_some(mirror.axis),
        }
    }

    /// The `sample`-th XYZ sample (Y in cd m⁻²) through pixel (x, y), or
    /// `None` if the estimate was not finite, or negative without the
    /// control variate (with it, single estimates may be). A pixel's
    /// samples are numbered across passes: 0 is the draft pass's, 1 the first
    /// full pass's, then consecutively through each pass's samples (one per
    /// pass without a plan, so the number is the pass; see [`Self::render_pass`]).
    pub fn sample_pixel(
        &self,
        integrator: &Integrator<'_>,
        x: u32,
        y: u32,
        sample: u64,
    ) -> Option<[f64; 3]> {
        self.sample_pixel_lanes(integrator, x, y, sample, false)
            .map(|(xyz, ..)| xyz)
    }

    /// [`Self::sample_pixel`] with the sample's wavelength lanes, for the
    /// spectral layer ([`film_spectral`]), and what it gives the `sky`,
    /// `sun` and `ground` layers ([`film_layers`]; whether its ray meets
    /// the ground only where `layers`).
    fn sample_pixel_lanes(
        &self,
        integrator: &Integrator<'_>,
        x: u32,
        y: u32,
        sample: u64,
        layers: bool,
    ) -> Option<([f64; 3], SampleLanes, SampleSplit)> {
        let width = self.scene.render.width;
        let pixel = u64::from(y) * u64::from(width) + u64::from(x);
        let seed = self.scene.render.seed;
        let rng = Rng::for_sample(seed, sample, pixel);
        let slot = self.sequence_slot(x, y);
        // Samples 1, 2, … take the sequence's points 0, 1, … (so that every
        // 2ᵐ of them are stratified; a mirror pair's, every other point);
        // the draft sample 0 and samples past the sequence's end draw
        // independent numbers.
        let point = sample
            .checked_sub(1)
            .map(|k| k * slot.stride + slot.offset)
            .filter(|&point| point < SOBOL_POINTS);
        let mut rng = match (integrator.options.sampler, point) {
            (Sampler::Sobol, Some(point)) => rng.with_sobol_prefix(seed, slot.pixel, point as u32),
            _ => rng,
        };
        let (u, v) = (rng.uniform(), rng.uniform());
        let px = f64::from(x)
            + if slot.reflect == Some(MirrorAxis::Columns) {
                1.0 - u
            } else {
                u
            };
        let py = f64::from(y)
            + if slot.reflect == Some(MirrorAxis::Rows) {
                1.0 - v
            } else {
                v
            };
        let Some(dir) = self.camera.direction(px, py) else {
            return Some(([0.0; 3], SampleLanes::default(), SampleSplit::default()));
        };
        // Across the passes of one pixel, u₀ follows the golden-ratio additive
        // recurrence from a random per-pixel start (a Cranley–Patterson rotated
        // low-discrepancy sequence): every sample is still uniform, so the
        // pixel mean stays unbiased, but the spectrum is covered evenly and
        // colour noise falls faster than with independent wavelengths.
        let start = Rng::new(self.scene.render.seed, slot.pixel).uniform();
        let step = sample * slot.stride + slot.offset;
        let u0 = (start + step as f64 * GOLDEN_RATIO_CONJUGATE).fract();
        let (lanes, pdfs) = self.sample_lanes(u0);
        let light = integrator.light(self.observer_m, dir, &lanes, &mut rng);
        let radiance = light.total;
        let n = lanes.active;
        let mut xyz = [0.0; 3];
        let mut split = SampleSplit {
            ground: layers
                && self
                    .medium
                    .span(self.observer_m, dir)
                    .is_some_and(|s| s.hits_ground),
            ..SampleSplit::default()
        };
        let mut spectral = SampleLanes {
            active: n,
            ..SampleLanes::default()
        };
        for j in 0..n {
            let bar = self.cmf.xyz_bar(lanes.wavelengths_nm[j]);
            let w = K_M * radiance[j] / (pdfs[j] * n as f64);
            let w_disc = K_M * light.disc[j] / (pdfs[j] * n as f64);
            for c in 0..3 {
                xyz[c] += w * bar[c];
                split.sun_xyz[c] += w_disc * bar[c];
            }
            spectral.wavelengths_nm[j] = lanes.wavelengths_nm[j];
            spectral.values[j] = radiance[j] / (pdfs[j] * n as f64);
        }
        let signed = integrator.signed_estimates();
        xyz.iter()
            .all(|v| v.is_finite() && (signed || *v >= 0.0))
            .then_some((xyz, spectral, split))
    }

    /// Add pass number `pass` to `film`: one sample per pixel, or, once the
    /// film is planned, each pixel's planned number of samples. With
    /// adaptive sampling on, the plan is made from the image when pass
    /// [`ADAPTIVE_FROM_PASS`] starts (see [`film`]). Stops
    /// between rows once `cancelled()` returns true. `film` must come from
    /// [`Self::new_film`]: mirror partners share their sequences, which only
    /// a film that reads them as pairs (and plans them so) averages without
    /// bias.
    pub fn render_pass(
        &self,
        film: &mut Film,
        pass: u32,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> PassStats {
        assert!(
            film.mirror == self.mirror && film.splats() == self.splatting,
            "render_pass: a film from Renderer::new_film (its mirror pairs, its splat layer) is needed"
        );
        // A part that starts later plans after its own first pass.
        if self.scene.render.adaptive_sampling
            && pass == ADAPTIVE_FROM_PASS.max(film.first_pass + 1)
            && !film.is_planned()
            && film.complete_passes() == pass
        {
            film.plan_samples();
        }
        // The variance layer's batch is this pass, where every row starts it.
        let variance_batch = film.variance.is_some() && film.row_passes.iter().all(|&p| p == pass);
        if variance_batch {
            film.start_variance_pass();
        }
        let integrator = self.integrator(pass);
        // Pixels the splats leave out (Camera::pixel_density_bounded) keep
        // the camera's branches from the air.
        let splatting =
            (self.splatting && pass > 0).then(|| self.integrator(pass).with_circle_splatting());
        let (mut splat_paths, mut splat_discarded) = (0, 0);
        if let Some(splatting) = &splatting {
            (splat_paths, splat_discarded) = self.splat_pass(film, pass, splatting, cancelled);
        }
        let width = film.width as usize;
        let discarded = AtomicU64::new(splat_discarded);
        let paths = AtomicU64::new(0);
        let weight = self.pass_weight(pass);
        let planned = film.is_planned();
        let splats = film.splats();
        // The film weighs each planned sample 1 (`Film::xyz`).
        debug_assert!(!planned || weight == 1.0);
        let plan = &film.plan;
        let region = film.region;
        // Sample numbers: a single render numbers each pixel's samples
        // consecutively. A part of a split render that starts at a later
        // pass with adaptive sampling numbers them pass × 16 + k instead:
        // the earlier passes of a render that starts at 0 take numbers
        // below 16 × its end, so parts never share a sample's random
        // numbers. Without adaptive sampling every pass takes the number
        // of the pass, as in a single render.
        let apart = film.first_pass > 0 && self.scene.render.adaptive_sampling;
        let per_pass = u64::from(film::MAX_SAMPLES_PER_PASS);
        // The spectral layer's rows (empty without one), one lock each so
        // the rows' closure below keeps its shape.
        let bands = film.spectral.as_ref().map_or(0, |s| s.bands);
        let spectral_rows: Vec<std::sync::Mutex<&mut [f32]>> = match &mut film.spectral {
            Some(s) => s
                .rows
                .iter_mut()
                .map(|r| std::sync::Mutex::new(r.as_mut_slice()))
                .collect(),
            None => film
                .row_passes
                .iter()
                .map(|_| std::sync::Mutex::new(&mut [][..]))
                .collect(),
        };
        // The sky/sun/ground layers' rows, likewise (`None` without them).
        let with_layers = film.layers.is_some();
        let layer_rows: Vec<std::sync::Mutex<Option<film_layers::LayerRow<'_>>>> =
            match &mut film.layers {
                Some(l) => l.rows(width).into_iter().map(|r| Some(r).into()).collect(),
                None => film.row_passes.iter().map(|_| None.into()).collect(),
            };
        let variance_rows: Vec<std::sync::Mutex<Option<film_layers::VarianceRow<'_>>>> =
            match &mut film.variance {
                Some(v) => v.rows(width).into_iter().map(|r| Some(r).into()).collect(),
                None => film.row_passes.iter().map(|_| None.into()).collect(),
            };
        film.xyz_sum
            .par_chunks_mut(width)
            .zip(film.row_passes.par_iter_mut())
            .zip(film.row_weights.par_iter_mut())
            .zip(film.row_planned_passes.par_iter_mut())
            .enumerate()
            // Rows differ up to 16× in cost under an adaptive plan (the
            // horizon's glow, the aureole): hand them out one at a time so
            // both threads stay busy to the pass's end.
            .with_max_len(1)
            .for_each(|(y, (((row, passes), row_weight), planned_passes))| {
                if cancelled() || *passes != pass {
                    return;
                }
                // Each row's lock is taken by the one thread that renders
                // the row: never contended.
                let mut spectral = spectral_rows[y]
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                if splats {
                    // As `Film::drop_draft` drops the row's XYZ.
                    if *passes == 1 {
                        spectral.fill(0.0);
                    }
                    Film::drop_draft(row, *passes, row_weight);
                }
                let mut layer_row = layer_rows[y]
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                if let Some(layer_row) = layer_row.as_mut().filter(|_| splats && *passes == 1) {
                    layer_row.clear();
                }
                let mut variance_row = variance_rows[y]
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                let mut row_paths = 0;
                // Outside a part's tile, the row's pass counts as done with
                // no samples: the merge takes those pixels from other parts.
                let (x0, x1) = match region {
                    Some(t) if !t.contains_row(y as u32) => (0, 0),
                    Some(t) => (t.x as usize, (t.x + t.width) as usize),
                    None => (0, width),
                };
                for (x, sum) in row.iter_mut().enumerate().take(x1).skip(x0) {
                    // Planned samples are numbered on from the unplanned
                    // passes' (one each), consecutively per pixel.
                    let (first, count) = match (planned, apart) {
                        (true, false) => {
                            let m = u64::from(plan[y * width + x]);
                            let before = u64::from(*passes - *planned_passes);
                            (before + u64::from(*planned_passes) * m, m)
                        }
                        (true, true) => {
                            (u64::from(pass) * per_pass, u64::from(plan[y * width + x]))
                        }
                        (false, true) => (u64::from(pass) * per_pass, 1),
                        (false, false) => (u64::from(pass), 1),
                    };
                    let integrator = match &splatting {
                        Some(s) if self.camera.pixel_density_bounded(x as u32, y as u32) => s,
                        _ => &integrator,
                    };
                    for sample in first..first + count {
                        let sampled = self.sample_pixel_lanes(
                            integrator,
                            x as u32,
                            y as u32,
                            sample,
                            with_layers,
                        );
                        match sampled {
                            Some((xyz, lanes, split)) => {
                                for c in 0..3 {
                                    sum[c] += ExactSum::from_f64(weight * xyz[c]);
                                }
                                if let Some(layer_row) = layer_row.as_mut() {
                                    layer_row.add(x, weight, xyz, &split);
                                }
                                if let Some(variance_row) = variance_row.as_mut() {
                                    variance_row.add(x, weight, xyz[1]);
                                }
                                if bands > 0 {
                                    lanes.add_to(&mut spectral[x * bands..(x + 1) * bands], weight);
                                }
                            }
                            None => {
                                discarded.fetch_add(1, Ordering::Relaxed);
                            }
                        }
                    }
                    row_paths += count;
                }
                *passes += 1;
                *row_weight += ExactSum::from_f64(weight);
                if planned {
                    *planned_passes += 1;
                }
                paths.fetch_add(row_paths, Ordering::Relaxed);
            });
        let discarded = discarded.into_inner();
        film.discarded += discarded;
        film.splat_discarded += splat_discarded;
        let completed = film.row_passes.iter().all(|&p| p > pass);
        if variance_batch && completed {
            film.end_variance_pass(pass, splat_paths);
        }
        PassStats {
            completed,
            paths: paths.into_inner(),
            splat_paths,
            discarded,
            splat_discarded,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn camera_branches_follow_the_guides_importance_with_the_sun_low() {
        // Below 3° the renderer builds its camera densities with the guide's
        // skylight as importance (`camera_importance`), so their skylight
        // component — where camera paths branch — differs from the plain
        // one; by day it is the plain one.
        for (preset, weighted) in [("twilight", true), ("sunset", true), ("midday", false)] {
            let r = Renderer::new(&Scene::preset(preset).unwrap()).unwrap();
            let plain = CameraDensities::new(&r.medium, r.observer_m, r.sun_direction);
            let dir = direction_from_az_el(r.scene.sun.azimuth_deg, 10.0);
            let span = r.medium.span(r.observer_m, dir).unwrap();
            let own = r.camera_densities.density(&r.medium, dir, span);
            let plain = plain.density(&r.medium, dir, span);
            let differs = [0.25, 0.5, 0.75].iter().any(|&u| {
                own.sample(sunlight::Component::Skylight, u)
                    != plain.sample(sunlight::Component::Skylight, u)
            });
            assert_eq!(differs, weighted, "{preset}");
        }
    }

    #[test]
    fn mirror_partners_share_one_sequence() {
        // The sunset preset's sun is at azimuth 270°: on a 26-column equirect
        // map, column x mirrors 12 − x (mod 26), and columns 6 and 19 are on
        // the mirror line.
        let mut scene = Scene::preset("sunset").unwrap();
        scene.render.width = 26;
        scene.render.height = 12;
        let r = Renderer::new(&scene).unwrap();
        for y in [0, 7] {
            for x in 0..26 {
                let (own, other) = (r.sequence_slot(x, y), r.sequence_slot((38 - x) % 26, y));
                if x == 6 || x == 19 {
                    assert_eq!((own.stride, own.offset, own.reflect), (1, 0, None));
                    assert_eq!(own.pixel, u64::from(y * 26 + x));
                    continue;
                }
                assert_eq!(own.pixel, other.pixel);
                assert_eq!((own.stride, other.stride), (2, 2));
                assert_eq!(own.offset + other.offset, 1);
                let lower = own.offset == 0;
                assert_eq!(own.reflect, (!lower).then_some(MirrorAxis::Columns));
                let column = if lower { x } else { (38 - x) % 26 };
                assert_eq!(own.pixel, u64::from(y * 26 + column));
            }
        }
        scene.render.mirror_symmetry = false;
        let alone = Renderer::new(&scene).unwrap().sequence_slot(3, 2);
        assert_eq!(
            (alone.pixel, alone.stride, alone.offset),
            (2 * 26 + 3, 1, 0)
        );
    }

    #[test]
    fn splatting_where_the_scene_has_circles_and_the_observer_is_in_the_air() {
        let small = |preset: &str| {
            let mut scene = Scene::preset(preset).unwrap();
            scene.render.width = 16;
            scene.render.height = 8;
            scene
        };
        // Twilight: the draft pass splats nothing, the first full pass
        // one point per pixel (from the prior), the later ones two.
        let twilight = Renderer::new(&small("twilight")).unwrap();
        let mut film = twilight.new_film();
        assert!(film.splats());
        let stats: Vec<PassStats> = (0..4)
            .map(|pass| twilight.render_pass(&mut film, pass, &|| false))
            .collect();
        assert_eq!(stats[0].splat_paths, 0);
        assert_eq!(stats[1].splat_paths, 16 * 8);
        for s in &stats[2..] {
            assert_eq!(s.splat_paths, 16 * 8 * 2);
        }
        assert_eq!(film.splat_paths, 5 * 16 * 8);
        // The sun below the horizon but the observer above the air, or the
        // sun at the nadir: unset means off.
        let mut space = small("space");
        space.sun.elevation_deg = -4.0;
        assert!(!Renderer::new(&space).unwrap().new_film().splats());
        let mut nadir = small("twilight");
        nadir.sun.elevation_deg = -90.0;
        assert!(!Renderer::new(&nadir).unwrap().new_film().splats());
        // With the sun low (sunset, 2°): on; high (midday, 45°): off.
        assert!(Renderer::new(&small("sunset")).unwrap().new_film().splats());
        assert!(!Renderer::new(&small("midday")).unwrap().new_film().splats());
    }

    /// The memory estimate covers what a render holds: the film's buffers
    /// after its plan, and the RGB image beside them.
    #[test]
    fn the_memory_estimate_covers_the_film_and_the_image() {
        for name in ["sunset", "midday"] {
            let mut scene = Scene::preset(name).unwrap();
            scene.render.width = 16;
            scene.render.height = 8;
            let renderer = Renderer::new(&scene).unwrap();
            renderer.check_memory().unwrap();
            let mut film = renderer.try_new_film().unwrap();
            for pass in 0..3 {
                renderer.render_pass(&mut film, pass, &|| false);
            }
            assert!(film.is_planned());
            let image = film.try_to_rgb().unwrap();
            let held = film.buffer_bytes() + std::mem::size_of_val(image.pixels.as_slice());
            let needed = renderer.memory_needed_bytes() as usize;
            assert!(
                held <= needed && needed < 4 * held,
                "{name}: {held} held, {needed} estimated"
            );
        }
    }

    /// The sunset preset at 24×12, with adaptive sampling on or off, each
    /// pixel read alone (no mirror pairs) from its camera samples alone (no
    /// splats).
    fn small_sunset(adaptive_sampling: bool) -> Renderer {
        let mut scene = Scene::preset("sunset").unwrap();
        scene.render.width = 24;
        scene.render.height = 12;
        scene.render.adaptive_sampling = adaptive_sampling;
        scene.render.mirror_symmetry = false;
        scene.render.integrator.circle_splatting = Some(false);
        Renderer::new(&scene).unwrap()
    }

    #[test]
    fn the_film_weights_every_sample_by_its_pass() {
        // The film's pixel = Σ w·sample / Σ w over the pixel's samples: the
        // draft (pass 0) weighted by `draft_weight`, every later sample 1 — with adaptive
        // sampling the m samples a planned pixel takes per pass from pass 2
        // on, numbered consecutively (exact sums: f64 rounding only).
        let renderer = small_sunset(true);
        let mut film = renderer.new_film();
        for pass in 0..4 {
            renderer.render_pass(&mut film, pass, &|| false);
        }
        assert!(film.is_planned());
        let mut planned = Vec::new();
        for y in 0..12 {
            for x in 0..24 {
                let m = film.samples_per_pass((y * 24 + x) as usize);
                planned.push(m);
                if (x + y) % 5 != 0 {
                    continue;
                }
                let mut sum = [0.0; 3];
                let mut weights = 0.0;
                let mut add = |pass: u32, sample: u64| {
                    let integrator = renderer.integrator(pass);
                    let xyz = renderer.sample_pixel(&integrator, x, y, sample).unwrap();
                    let w = renderer.pass_weight(pass);
                    weights += w;
                    for c in 0..3 {
                        sum[c] += w * xyz[c];
                    }
                };
                add(0, 0);
                add(1, 1);
                for sample in 2..2 + 2 * u64::from(m) {
                    add(2 + ((sample - 2) / u64::from(m)) as u32, sample);
                }
                let draft = renderer.pass_weight(0);
                assert!((weights - (draft + 1.0 + 2.0 * f64::from(m))).abs() < 1e-12);
                let got = film.xyz(x, y);
                for c in 0..3 {
                    let expected = sum[c] / weights;
                    assert!(
                        (got[c] - expected).abs() <= 1e-12 * expected.abs() + 1e-18,
                        "pixel ({x}, {y}) channel {c}: {} vs {expected}",
                        got[c]
                    );
                }
            }
        }
        // The sunset glow plans more samples than the clear sky above it.
        assert!(planned.iter().any(|&m| m > 1) && planned.contains(&1));
    }

    #[test]
    fn without_adaptive_sampling_every_pass_takes_one_sample() {
        let renderer = small_sunset(false);
        let mut film = renderer.new_film();
        for pass in 0..4 {
            let stats = renderer.render_pass(&mut film, pass, &|| false);
            assert_eq!(stats.paths, 24 * 12);
        }
        assert!(!film.is_planned());
    }
}
