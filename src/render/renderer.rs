//! The renderer: a validated [`Scene`] made ready to render (its medium,
//! camera, technique plan and tables), and its passes over a [`Film`].

use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

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

use super::camera::{direction_from_az_el, Camera, HalfMirror, Mirror, MirrorAxis};
use super::film::Film;
use super::ground_circles::GroundPool;
use super::integrator::Integrator;
use super::lanes::{LaneTable, SolarSource};
use super::medium::{Lanes, Medium, SpectralLanes, LANES};
use super::tables::Tables;
use super::{circles, exact, film, film_layers, film_spectral};
use crate::atmosphere::Atmosphere;
use crate::plan::Conditions;
use crate::plan::{Sampler, TechniquePlan};
use crate::rng::{Rng, SOBOL_POINTS};
use crate::scene::{Scene, SceneError};
use crate::spectrum::{ColourMatching, K_M};
use exact::ExactSum;
use film_layers::SampleSplit;
use film_spectral::SampleLanes;

/// (√5 − 1)/2: the additive recurrence with this step is the most evenly
/// spread 1-D sequence (Weyl; the three-distance theorem).
pub(super) const GOLDEN_RATIO_CONJUGATE: f64 = 0.618_033_988_749_894_8;

/// With adaptive sampling on, the pass whose start fixes each pixel's
/// samples per pass (see [`film`]): after the draft and the first
/// full pass, so the plan reads one full sample per pixel.
pub const ADAPTIVE_FROM_PASS: u32 = 2;

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

/// The pixel parts a film of `scene` reads together ([`film`]) where the
/// sun's vertical plane is off the pixel grid of an equirect image (a real
/// date's sun, most often): [`Camera::half_mirror`], where `[render]
/// mirror_symmetry` is on and no output reads the film's sums otherwise
/// than the image does (the `sky`, `sun` and `ground` layers, a spectral
/// image: those read each pixel alone there; the `variance` layer reads
/// the halves, `VarianceSums::plane`) and the render
/// has three passes or more (the draft and the first full pass draw in
/// the wider part only, [`HalfMirror::in_left`]); `None` otherwise, and
/// where [`mirror_pairs`] has pairs.
pub fn mirror_halves(scene: &Scene) -> Option<HalfMirror> {
    let own_sums = scene.output.spectral_bands.is_some()
        || scene
            .output
            .layers
            .iter()
            .any(|l| super::film_layers::PATH_LAYERS.contains(&l.as_str()));
    if !scene.render.mirror_symmetry
        || own_sums
        || scene.render.spp < 3
        || mirror_pairs(scene).is_some()
    {
        return None;
    }
    Camera::new(&scene.camera, scene.render.width, scene.render.height)
        .half_mirror(scene.sun.azimuth_deg)
}

/// A scene made ready to render.
pub struct Renderer {
    /// The scene as validated.
    pub scene: Scene,
    /// Its atmosphere.
    pub atmosphere: Atmosphere,
    pub(super) medium: Medium,
    pub(super) camera: Camera,
    pub(super) cmf: &'static ColourMatching,
    /// Per-wavelength constants over the colour-matching range.
    pub(super) lane_table: LaneTable,
    pub(super) sun_direction: DVec3,
    pub(super) observer_m: DVec3,
    /// The tables the plan reads, built on first use.
    pub(super) tables: Tables,
    /// The scene's techniques, every choice made ([`TechniquePlan::new`]).
    pub(super) plan: TechniquePlan,
    /// The first pass's techniques ([`TechniquePlan::first_pass`]).
    pub(super) draft_plan: TechniquePlan,
    /// The pixel pairs the film reads together (`mirror_symmetry`).
    pub(super) mirror: Option<Mirror>,
    /// The pixel parts the film reads together where there are no pairs.
    pub(super) halves: Option<HalfMirror>,
}

/// A row's sums and weights of the samples in its pixels' left parts
/// under a [`HalfMirror`].
type LeftRow<'a> = (exact::ExactRow<'a>, &'a mut [f64]);

/// Where a pixel takes its low-discrepancy numbers
/// ([`Renderer::sequence_slot`]): sample k uses point k × `stride` +
/// `offset` of `pixel`'s sequences.
#[derive(Clone, Copy, Debug)]
pub(super) struct SequenceSlot {
    pub(super) pixel: u64,
    pub(super) stride: u64,
    pub(super) offset: u64,
    /// The mirror axis to reflect the position within the pixel across.
    pub(super) reflect: Option<MirrorAxis>,
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
    /// Samples (and splats) discarded as non-finite (or negative where
    /// no estimate may be, `Integrator::signed_estimates`).
    pub discarded: u64,
    /// The splats among `discarded`.
    pub splat_discarded: u64,
}

impl Renderer {
    /// The renderer of `scene`, or why the scene is invalid.
    pub fn new(scene: &Scene) -> Result<Self, SceneError> {
        Ok(Unfinished::new(scene)?.finish())
    }

    /// [`Self::new`] for a caller that shows the sky model first (the
    /// app's preview): the model's tables
    /// ([`super::sky_model::ModelTables::shared_unless`]) made before the
    /// renderer's own, and `Ok(None)` where `cancelled()` returns true
    /// while they are being made — a new atmosphere's tables take
    /// seconds, and a scene replaced meanwhile need not wait for them.
    pub fn with_model_unless(
        scene: &Scene,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Result<Option<Self>, SceneError> {
        let unfinished = Unfinished::new(scene)?;
        let tables = super::sky_model::ModelTables::shared_unless(
            &unfinished.medium,
            &unfinished.lane_table,
            cancelled,
        );
        Ok(tables.map(|_| unfinished.finish()))
    }

    /// The scene's techniques, every choice made.
    pub fn plan(&self) -> &TechniquePlan {
        &self.plan
    }

    /// The approximate sky of [`super::sky_model`]: the preview's first
    /// frame (an approximation, never the reference). Its atmosphere's
    /// tables are kept between renderers of the same atmosphere
    /// ([`super::sky_model::ModelTables::shared`]): with them made, tens
    /// of milliseconds.
    pub fn sky_model_image(&self) -> crate::output::RgbImage {
        let r = &self.scene.render;
        self.sky_model().image(&self.camera, r.width, r.height)
    }

    /// The approximate sky of [`super::sky_model`] for this scene's sun and
    /// observer, to image through any camera (the fast mode images it at
    /// two sizes, [`super::fast`]).
    pub fn sky_model(&self) -> super::sky_model::SkyModel {
        super::sky_model::SkyModel::from_tables(
            super::sky_model::ModelTables::shared(&self.medium, &self.lane_table),
            &self.medium,
            &self.lane_table,
            self.cmf,
            self.sun_direction,
            self.observer_m,
        )
    }

    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// Unit vector toward the sun's centre.
    pub fn sun_direction(&self) -> DVec3 {
        self.sun_direction
    }

    /// The weight of pass `pass` in the film's average: the draft's
    /// ([`TechniquePlan::draft_weight`]) or 1.
    pub(super) fn pass_weight(&self, pass: u32) -> f64 {
        if pass == 0 {
            self.plan.draft_weight
        } else {
            1.0
        }
    }

    /// The integrator for pass `pass`. The first pass traces plain
    /// delta-tracked camera paths (no camera-ray densities to build, no
    /// branches), so the first image of a progressive render — the preview's
    /// first frame — comes fast; every pass is an unbiased estimate, so the
    /// film's average of them stays unbiased.
    pub(super) fn integrator(&self, pass: u32) -> Integrator<'_> {
        let plan = if pass == 0 {
            &self.draft_plan
        } else {
            &self.plan
        };
        self.tables
            .integrator(&self.medium, plan, self.sun_direction)
    }

    /// Wavelengths each path carries (`wavelengths_per_path`, 1–[`LANES`]).
    pub(super) fn lanes_per_path(&self) -> usize {
        self.scene
            .render
            .integrator
            .wavelengths_per_path
            .clamp(1, LANES)
    }

    /// Hero-rotated wavelengths for one path: lane k uses u₀ + k/n (mod 1)
    /// through the importance CDF, so each lane is distributed by the CMF-based
    /// density and the lanes are stratified (Wilkie et al. 2014).
    pub(super) fn sample_lanes(&self, u0: f64) -> (SpectralLanes, Lanes) {
        let n = self.lanes_per_path();
        let mut wavelengths = Lanes::splat(0.0);
        let mut pdfs = Lanes::splat(0.0);
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
    /// Each pixel's samples stay uniform, so its mean stays unbiased
    /// (`BENCHMARKS.md`, mirror pairs).
    pub(super) fn sequence_slot(&self, x: u32, y: u32) -> SequenceSlot {
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
    /// `None` if the estimate was not finite, or negative where no single
    /// estimate may be (`Integrator::signed_estimates`: a control variate
    /// or the sun's corrected table makes them signed). A pixel's
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
        let part = self.halves.map(|h| h.part(sample));
        self.sample_pixel_lanes(integrator, (x, y), sample, false, part, None)
            .map(|(xyz, ..)| xyz)
    }

    /// [`Self::sample_pixel`] with the sample's wavelength lanes, for the
    /// spectral layer ([`film_spectral`]), and what it gives the `sky`,
    /// `sun` and `ground` layers ([`film_layers`]; whether its ray meets
    /// the ground only where `layers`). With the pass's `pool` (where the
    /// ground's splats serve the pixel), a ray that meets the ground adds
    /// the pool's light there ([`GroundPool`]).
    pub(super) fn sample_pixel_lanes(
        &self,
        integrator: &Integrator<'_>,
        (x, y): (u32, u32),
        sample: u64,
        layers: bool,
        part: Option<(bool, u64)>,
        pool: Option<&GroundPool<'_>>,
    ) -> Option<([f64; 3], SampleLanes, SampleSplit)> {
        let width = self.scene.render.width;
        let pixel = u64::from(y) * u64::from(width) + u64::from(x);
        let seed = self.scene.render.seed;
        let rng = Rng::for_sample(seed, sample, pixel);
        let slot = self.sequence_slot(x, y);
        // Samples 1, 2, … take the sequence's points 0, 1, … (so that every
        // 2ᵐ of them are stratified; a mirror pair's, every other point);
        // the draft sample 0 and samples past the sequence's end draw
        // independent numbers. Under a half mirror each part's samples take
        // a sequence of their own, numbered within the part: stratified
        // over the part as a pixel's are over it, and independent of the
        // other part's. (With one sequence for both, each part's samples
        // were stratified against the other's, which anti-correlated the
        // noise of the two neighbours that read them: −0.15 along the rows
        // of an airliner's sky.)
        let (sequence, point) = match part {
            Some((left, index)) => (
                (pixel << 1 | u64::from(left)) | 1 << 63,
                (sample >= 1).then_some(index),
            ),
            None => (
                slot.pixel,
                sample.checked_sub(1).map(|k| k * slot.stride + slot.offset),
            ),
        };
        let point = point.filter(|&point| point < SOBOL_POINTS);
        let mut rng = match (integrator.plan.sampler, point) {
            (Sampler::Sobol, Some(point)) => rng.with_sobol_prefix(seed, sequence, point as u32),
            _ => rng,
        };
        let (u, v) = (rng.uniform(), rng.uniform());
        let px = f64::from(x)
            + match (self.halves.zip(part), slot.reflect) {
                (Some((h, (left, _))), _) => h.position(left, u),
                (None, Some(MirrorAxis::Columns)) => 1.0 - u,
                (None, _) => u,
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
        // A half mirror's parts each follow their own recurrence, as their
        // sequences above (the draft at its step 0, the part's full
        // samples from step 1).
        let start = Rng::new(self.scene.render.seed, sequence).uniform();
        let step = match part {
            Some(_) if sample == 0 => 0,
            Some((_, index)) => index + 1,
            None => sample * slot.stride + slot.offset,
        };
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
        if let Some(pool) = pool {
            pool.add_to(&mut xyz, dir);
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
            film.mirror == self.mirror
                && film.halves == self.halves
                && film.splats() == self.plan.splats(),
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
        // the camera's branches from the air (and bounces off the ground).
        let splatting = (self.plan.splats() && pass > 0).then(|| {
            self.integrator(pass)
                .with_splatting(self.plan.circle_splatting, self.ground_splatter().is_some())
        });
        // The pass's pool, whose light the camera's samples add.
        let pool = splatting
            .as_ref()
            .and_then(|splatting| self.ground_pool(splatting, pass));
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
                Some(l) => l.rows().into_iter().map(|r| Some(r).into()).collect(),
                None => film.row_passes.iter().map(|_| None.into()).collect(),
            };
        let variance_rows: Vec<std::sync::Mutex<Option<film_layers::VarianceRow<'_>>>> =
            match &mut film.variance {
                Some(v) => v.rows(width).into_iter().map(|r| Some(r).into()).collect(),
                None => film.row_passes.iter().map(|_| None.into()).collect(),
            };
        // The sums and weights of the samples in the pixels' left parts
        // under a half mirror, likewise.
        let halves = film.halves;
        let left_rows: Vec<std::sync::Mutex<Option<LeftRow<'_>>>> = if halves.is_some() {
            film.left_sum
                .rows_mut()
                .into_iter()
                .zip(film.left_weight.chunks_mut(width))
                .map(|r| Some(r).into())
                .collect()
        } else {
            film.row_passes.iter().map(|_| None.into()).collect()
        };
        film.xyz_sum
            .rows_mut()
            .into_par_iter()
            .zip(film.row_passes.par_iter_mut())
            .zip(film.row_weights.par_iter_mut())
            .zip(film.row_planned_passes.par_iter_mut())
            .enumerate()
            // Rows differ up to 16× in cost under an adaptive plan (the
            // horizon's glow, the aureole): hand them out one at a time so
            // both threads stay busy to the pass's end.
            .with_max_len(1)
            .for_each(|(y, (((mut row, passes), row_weight), planned_passes))| {
                if cancelled() || *passes != pass {
                    return;
                }
                // Each row's lock is taken by the one thread that renders
                // the row: never contended.
                let mut spectral = spectral_rows[y]
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                let mut left_row = left_rows[y]
                    .lock()
                    .unwrap_or_else(std::sync::PoisonError::into_inner);
                if splats {
                    // As `Film::drop_draft` drops the row's XYZ.
                    if *passes == 1 {
                        spectral.fill(0.0);
                    }
                    if let Some((sums, weights)) = left_row.as_mut().filter(|_| *passes == 1) {
                        sums.clear();
                        weights.fill(0.0);
                    }
                    Film::drop_draft(&mut row, *passes, row_weight);
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
                for x in x0..x1 {
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
                    let (integrator, pool) = match &splatting {
                        Some(s) if self.camera.pixel_density_bounded(x as u32, y as u32) => {
                            (s, pool.as_ref())
                        }
                        _ => (&integrator, None),
                    };
                    let mut sum = [ExactSum::ZERO; 3];
                    let (mut left, mut left_weight) = ([ExactSum::ZERO; 3], 0.0);
                    for sample in first..first + count {
                        // A discarded sample keeps its weight (as a row's
                        // passes do): its part's too.
                        // A part's samples numbered apart (pass × 16 + k)
                        // take their part by a rotation of their number,
                        // which stays in proportion on any such subset.
                        let part = halves.map(|h| {
                            if apart {
                                h.part_apart(sample)
                            } else {
                                h.part(sample)
                            }
                        });
                        let in_left = part.is_some_and(|p| p.0);
                        if in_left {
                            left_weight += weight;
                        }
                        let sampled = self.sample_pixel_lanes(
                            integrator,
                            (x as u32, y as u32),
                            sample,
                            with_layers,
                            part,
                            pool,
                        );
                        match sampled {
                            Some((xyz, lanes, split)) => {
                                let value = xyz.map(|v| ExactSum::from_f64(weight * v));
                                for c in 0..3 {
                                    sum[c] += value[c];
                                }
                                if in_left {
                                    for c in 0..3 {
                                        left[c] += value[c];
                                    }
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
                    row.add(x, sum);
                    if let Some((sums, weights)) = left_row.as_mut() {
                        sums.add(x, left);
                        weights[x] += left_weight;
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

/// A renderer but for its tables: the scene checked, its atmosphere,
/// medium, camera, plan and wavelengths.
struct Unfinished {
    scene: Scene,
    atmosphere: Atmosphere,
    medium: Medium,
    camera: Camera,
    cmf: &'static ColourMatching,
    observer_m: DVec3,
    sun_direction: DVec3,
    plan: TechniquePlan,
    lane_table: LaneTable,
}

impl Unfinished {
    fn new(scene: &Scene) -> Result<Self, SceneError> {
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
        // From above the air (where the scene refuses splatting when asked
        // for) or without circles (the sun at the zenith or nadir), the
        // camera's branches keep every order.
        let in_air = scene.observer.altitude_m < scene.atmosphere.top_altitude_m;
        let circles = in_air && circles::has_circles(observer_m, sun_direction);
        let ground_density = atmosphere.air_number_density_m3(0.0);
        let density_over_ground = if ground_density > 0.0 {
            atmosphere.air_number_density_m3(scene.observer.altitude_m) / ground_density
        } else {
            0.0
        };
        let plan = TechniquePlan::new(
            &scene.render.integrator,
            &Conditions::new(scene.sun.elevation_deg, &scene.atmosphere, circles)
                .with_observer_density(density_over_ground)
                .with_observer_in_air(in_air)
                .with_spectral_image(scene.output.spectral_bands.is_some()),
        );
        let lane_table = LaneTable::new(&medium, cmf.range_nm(), solar_source(scene));
        Ok(Self {
            scene: scene.clone(),
            atmosphere,
            medium,
            camera,
            cmf,
            observer_m,
            sun_direction,
            plan,
            lane_table,
        })
    }

    /// The renderer, its tables made (empty until first used, but for the
    /// model's: [`Tables::new`]).
    fn finish(self) -> Renderer {
        // Fields are initialised in the order written: the borrows first.
        Renderer {
            tables: Tables::new(
                &self.medium,
                &self.plan,
                &self.lane_table,
                self.observer_m,
                self.sun_direction,
            ),
            mirror: mirror_pairs(&self.scene),
            halves: mirror_halves(&self.scene),
            draft_plan: self.plan.first_pass(),
            plan: self.plan,
            observer_m: self.observer_m,
            sun_direction: self.sun_direction,
            cmf: self.cmf,
            lane_table: self.lane_table,
            scene: self.scene,
            atmosphere: self.atmosphere,
            medium: self.medium,
            camera: self.camera,
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
            let plain = crate::render::sunlight::CameraDensities::new(
                &r.medium,
                r.observer_m,
                r.sun_direction,
            );
            let dir = direction_from_az_el(r.scene.sun.azimuth_deg, 10.0);
            let span = r.medium.span(r.observer_m, dir).unwrap();
            let own = r.tables.camera_densities.density(&r.medium, dir, span);
            let plain = plain.density(&r.medium, dir, span);
            let differs = [0.25, 0.5, 0.75].iter().any(|&u| {
                own.sample(crate::render::sunlight::Component::Skylight, u)
                    != plain.sample(crate::render::sunlight::Component::Skylight, u)
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
        // With the sun low (sunset, 2°): the air's and the ground's; high
        // (midday, 45°): the ground's alone, from the first full pass on a
        // quarter bounce per pixel that sees the ground with the pool
        // (the table's count, near the lower half's 64).
        let sunset = Renderer::new(&small("sunset")).unwrap();
        assert!(sunset.plan().circle_splatting && sunset.new_film().splats());
        let midday = Renderer::new(&small("midday")).unwrap();
        assert!(!midday.plan().circle_splatting && midday.plan().ground_splatting);
        let mut film = midday.new_film();
        assert!(film.splats());
        let stats: Vec<PassStats> = (0..3)
            .map(|pass| midday.render_pass(&mut film, pass, &|| false))
            .collect();
        assert_eq!(stats[0].splat_paths, 0);
        for s in &stats[1..] {
            assert!(
                (16 * 8 / 16..16 * 8 * 3 / 16).contains(&s.splat_paths),
                "{s:?}"
            );
        }
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
        scene.render.integrator.ground_splatting = Some(false);
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
