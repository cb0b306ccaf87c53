//! The splats of a pass ([`super::circles`]): the paths the circles of
//! symmetry share between pixels, run in chunks whose splats the film
//! adds in the chunks' order, so that the image does not depend on the
//! thread count.

use rayon::prelude::*;

use super::circles::CircleSplatter;
use super::film_spectral::Splat;
use super::ground_circles::{GroundPool, GroundSplatter};
use super::medium::{Lanes, SpectralLanes, LANES};
use super::{Film, Integrator, Renderer, Sampler};
use crate::rng::{mix64, Rng, SOBOL_POINTS};
use crate::spectrum::K_M;

/// The stream of [`Renderer::splat_pass`]'s paths (past any pixel's).
pub(crate) const SPLAT_STREAM: u64 = u64::MAX - 0x5b1a;
/// The stream of the ground's bounces ([`super::ground_circles`]).
const GROUND_STREAM: u64 = u64::MAX - 0x96d0;
/// The stream of the pool's bounces at the observer's foot
/// ([`GroundSplatter::walk`]).
const POOL_STREAM: u64 = u64::MAX - 0x9001;
/// The pool's bounces per pixel that sees the ground
/// ([`GroundSplatter::ground_pixels`]): its noise is shared by every ground
/// pixel of the pass, a small part of the ground's, and it is drawn from
/// its own Sobol points (a tenth to twice as many measured alike:
/// `BENCHMARKS.md`, the ground pool's row).
const POOL_PER_GROUND_PIXEL: f64 = 0.25;
/// The least share of bounces traced with their twins
/// ([`GroundSplatter::walk`]).
const PAIR_SHARE: f64 = 1.0 / 16.0;
/// The least bounces in a pool.
const MIN_POOL: u64 = 256;
/// The most: the pool's noise is shared by every ground pixel, and a
/// pass's noise in each pixel does not fall with the image's size, so a
/// larger image needs no larger pool (a 256×128 map takes about 4 000).
const MAX_POOL: u64 = 16_384;
/// Ground bounces per path splatted in the air, each splatting
/// [`GROUND_SPLATS`] positions: more positions per bounce pay better than
/// more bounces (`BENCHMARKS.md`).
const GROUND_WALKS_PER_WALK: u64 = 1;
/// Ground bounces per pixel that sees the ground
/// ([`GroundSplatter::ground_pixels`]) in a pass where the ground's
/// skylight is splatted without the air's (by day): at midday a bounce
/// with its positions costs about two thirds of a camera sample, nearly
/// all of it the positions (their landing and transmittance; the
/// bounce's own path a tenth of a camera sample). From 2 m, where the
/// ground fills half the image, half a bounce per pixel of the image
/// measured best, and the ground's noise is flat about it in the bounces
/// and positions (`BENCHMARKS.md`, ground splatting).
const GROUND_WALKS_PER_GROUND_PIXEL: f64 = 1.0;
/// The same with the pool: the walks then carry only the pairs'
/// differences, and most of those are left out by roulette; fewer walks
/// leave the camera's samples more of the pass (`BENCHMARKS.md`, the
/// ground pool's row).
const POOLED_GROUND_WALKS_PER_GROUND_PIXEL: f64 = 0.25;
/// Points splatted per pixel in each pass after the first ([`circles`];
/// each with its directions and paths): with more, the camera's own
/// samples (single scattering, the ground) get too few passes; 2 and 3
/// measured alike, and 2 makes shorter passes (`BENCHMARKS.md`).
const SPLAT_PATHS_PER_PIXEL: u64 = 2;
/// Points per pixel of the first splatting pass (pass 1), the only one that
/// draws them from the prior alone ([`circles::LearnedPoints`]): half as
/// many, so the learned density takes over sooner (`BENCHMARKS.md`,
/// learned splat density).
const FIRST_SPLAT_PATHS_PER_PIXEL: u64 = 1;

/// Ground bounces per pixel that sees the ground where the air's light is
/// not splatted, with the pool or without.
fn ground_walks_per_ground_pixel(pool: bool) -> f64 {
    if pool {
        POOLED_GROUND_WALKS_PER_GROUND_PIXEL
    } else {
        GROUND_WALKS_PER_GROUND_PIXEL
    }
}

/// Points splatted per pixel in pass `pass` (≥ 1).
fn splat_paths_per_pixel(pass: u32) -> u64 {
    if pass == 1 {
        FIRST_SPLAT_PATHS_PER_PIXEL
    } else {
        SPLAT_PATHS_PER_PIXEL
    }
}

/// What one chunk of [`Renderer::splat_pass`]'s walks left: their splats,
/// discarded splats, number, and terms of the learned density's moments.
struct ChunkSplats {
    splats: Vec<Splat>,
    discarded: u64,
    walks: u64,
    moments: Vec<(usize, f64)>,
}

impl Renderer {
    /// The splats of pass `pass` ([`circles`]): [`splat_paths_per_pixel`]
    /// paths per pixel, each with its ground bounces, or where only the
    /// ground's light is splatted [`ground_walks_per_ground_pixel`]
    /// bounces per pixel that sees the ground, in
    /// chunks whose splats are added in the chunks' order, so the image
    /// does not depend on the thread count. With the plan's `ground_pool`
    /// (the pass's [`Self::ground_pool`]) the ground's bounces go with
    /// their twins.
    /// Stops between batches of chunks once `cancelled()` returns true; the
    /// film divides by the paths actually splatted. Returns the paths and
    /// the discarded splats.
    pub(crate) fn splat_pass(
        &self,
        film: &mut Film,
        pass: u32,
        integrator: &Integrator<'_>,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> (u64, u64) {
        const CHUNK: u64 = 256;
        // Chunks run in parallel between checks for cancellation; their
        // number does not change the image (splats are added in order).
        // Capped: each holds up to CHUNK × (SPLATS_PER_WALK +
        // GROUND_WALKS_PER_WALK × GROUND_SPLATS) splats until added.
        let chunks_per_batch = (8 * rayon::current_num_threads() as u64).min(64);
        let splatter = if self.plan.circle_splatting {
            let splatter = self.tables.splatter(
                &self.medium,
                || self.integrator(1),
                &self.camera,
                self.observer_m,
            );
            if splatter.is_none() {
                return (0, 0);
            }
            splatter
        } else {
            None
        };
        let ground = self.ground_splatter();
        let pool = self.plan.ground_pool;
        let pixels = u64::from(film.width) * u64::from(film.height);
        // A walk is a path splatted in the air with its ground bounces, or
        // without the air's splats a single ground bounce.
        let paths_total = match (splatter, ground) {
            (Some(_), _) => pixels * splat_paths_per_pixel(pass),
            // At least one: a ground the table finds no mass for can still
            // be seen (its uniform share), and must not go without light.
            (None, Some(g)) => (g.ground_pixels() * ground_walks_per_ground_pixel(pool))
                .ceil()
                .max(1.0) as u64,
            (None, None) => return (0, 0),
        };
        let ground_walks_per_walk = if splatter.is_some() {
            GROUND_WALKS_PER_WALK
        } else {
            1
        };
        let pair_share = pool.then_some(PAIR_SHARE);
        let chunks = paths_total.div_ceil(CHUNK);
        let n = self.lanes_per_path();
        let (mut paths, mut discarded) = (0, 0);
        // The points' density is the one learned from earlier passes, fixed
        // for this pass; this pass's walks then refine it for the next.
        let mut learned = std::mem::take(&mut film.learned_points);
        // Each batch's splats go to the film (in order) while the next
        // batch runs: adding them is serial, and would leave the other
        // threads idle. The moments wait for the pass's end, since the
        // walks read `learned` (whose density this pass does not change).
        let mut moments = Vec::new();
        let mut add = |batch: Vec<ChunkSplats>| {
            for c in batch {
                moments.extend(c.moments);
                film.add_splats(&c.splats, c.walks);
                paths += c.walks;
                discarded += c.discarded;
            }
        };
        let mut pending: Option<Vec<ChunkSplats>> = None;
        let mut chunk = 0;
        while chunk < chunks && !cancelled() {
            let end = (chunk + chunks_per_batch).min(chunks);
            let run = || -> Vec<ChunkSplats> {
                (chunk..end)
                    .into_par_iter()
                    .map(|c| {
                        let walks = c * CHUNK..((c + 1) * CHUNK).min(paths_total);
                        let per_walk = splatter.map_or(0, CircleSplatter::splats_per_walk)
                            + ground.as_ref().map_or(0, |g| {
                                ground_walks_per_walk as usize * g.splats_per_bounce()
                            });
                        let mut splats = Vec::with_capacity(CHUNK as usize * per_walk);
                        let mut moments = Vec::with_capacity(CHUNK as usize);
                        let mut discarded = 0;
                        for walk in walks.clone() {
                            if let Some(splatter) = splatter {
                                let (mut rng, lanes, pdfs) =
                                    self.splat_walk_start(integrator, pass, SPLAT_STREAM, walk);
                                let weights = self.xyz_weights(&lanes, pdfs);
                                let before = splats.len();
                                let walked = splatter.walk(
                                    integrator,
                                    &self.camera,
                                    &lanes,
                                    &weights,
                                    &learned,
                                    &mut rng,
                                    &mut splats,
                                );
                                over_densities(&mut splats[before..], pdfs, n);
                                discarded += walked.discarded;
                                moments.extend(walked.moment);
                            }
                            // The ground's bounces, each a share of the walk's
                            // unit (the film divides by walks), with their own
                            // generators and wavelengths.
                            if let Some(ground) = ground {
                                for g in 0..ground_walks_per_walk {
                                    let index = walk * ground_walks_per_walk + g;
                                    let (mut rng, lanes, pdfs) = self.splat_walk_start(
                                        integrator,
                                        pass,
                                        GROUND_STREAM,
                                        index,
                                    );
                                    let weights = self.xyz_weights(&lanes, pdfs);
                                    let before = splats.len();
                                    discarded += ground.walk(
                                        integrator,
                                        &self.camera,
                                        &lanes,
                                        &weights,
                                        1.0 / ground_walks_per_walk as f64,
                                        pair_share,
                                        &mut rng,
                                        &mut splats,
                                    );
                                    over_densities(&mut splats[before..], pdfs, n);
                                }
                            }
                        }
                        ChunkSplats {
                            splats,
                            discarded,
                            walks: walks.end - walks.start,
                            moments,
                        }
                    })
                    .collect()
            };
            let batch = match pending.take() {
                Some(previous) => rayon::join(|| add(previous), run).1,
                None => run(),
            };
            pending = Some(batch);
            chunk = end;
        }
        if let Some(previous) = pending {
            add(previous);
        }
        learned.add_moments(moments);
        if let Some(splatter) = splatter {
            splatter.learn(&mut learned);
        }
        film.learned_points = learned;
        (paths, discarded)
    }

    /// The pool of pass `pass` where the plan has one (and the ground is
    /// splatted): the mean of its bounces from the observer's foot, each
    /// with generator and wavelengths of its own, in XYZ
    /// ([`GroundSplatter::walk`]), [`POOL_PER_GROUND_PIXEL`] per pixel that
    /// sees the ground (at least [`MIN_POOL`], at most [`MAX_POOL`]);
    /// summed in index order, so the image does not depend on the thread
    /// count.
    pub(crate) fn ground_pool(
        &self,
        integrator: &Integrator<'_>,
        pass: u32,
    ) -> Option<GroundPool<'_>> {
        let ground = self.ground_splatter().filter(|_| self.plan.ground_pool)?;
        let count = ((ground.ground_pixels() * POOL_PER_GROUND_PIXEL).ceil() as u64)
            .clamp(MIN_POOL, MAX_POOL);
        let terms: Vec<[f64; 3]> = (0..count)
            .into_par_iter()
            .map(|index| self.pool_term(ground, integrator, pass, index))
            .collect();
        let sum = terms
            .iter()
            .fold([0.0; 3], |a, t| [a[0] + t[0], a[1] + t[1], a[2] + t[2]]);
        Some(GroundPool::new(
            ground,
            &self.medium,
            sum.map(|v| v / count as f64),
        ))
    }

    /// The pool's bounce `index` of pass `pass`, in XYZ.
    fn pool_term(
        &self,
        ground: &GroundSplatter,
        integrator: &Integrator<'_>,
        pass: u32,
        index: u64,
    ) -> [f64; 3] {
        let (mut rng, lanes, pdfs) = self.splat_walk_start(integrator, pass, POOL_STREAM, index);
        let weights = self.xyz_weights(&lanes, pdfs);
        let light = ground.foot_light(integrator, &lanes, &mut rng);
        let mut xyz = [0.0; 3];
        for (l, w) in light[..lanes.active].iter().zip(weights) {
            for (value, bar) in xyz.iter_mut().zip(w) {
                *value += l * bar;
            }
        }
        // A term that is not finite is left out as a discarded splat is
        // (the pool's mean then reads it as zero).
        if xyz.iter().all(|v| v.is_finite()) {
            xyz
        } else {
            [0.0; 3]
        }
    }

    /// The splatter of the ground's skylight where the plan splats it and
    /// there is ground to splat on (`None` for an observer on the ground
    /// or a black one: the camera's rays then keep their bounces).
    pub(crate) fn ground_splatter(&self) -> Option<&GroundSplatter> {
        self.plan
            .ground_splatting
            .then(|| {
                self.tables.ground_splatter(
                    &self.medium,
                    || self.integrator(1),
                    &self.camera,
                    self.observer_m,
                )
            })
            .flatten()
    }

    /// A splatted path's generator — a key of its own per path, `index` of
    /// `stream` in pass `pass` (the pixels' streams share one per sample:
    /// fine for one sample per pixel, but paths splatted into one pixel must
    /// not be related), its first numbers from the pass's Sobol points, one
    /// sequence scrambled per pass and block of `SOBOL_POINTS` (the paths'
    /// wavelengths, points and first directions are stratified across the
    /// pass) — and its wavelengths with their densities.
    fn splat_walk_start(
        &self,
        integrator: &Integrator<'_>,
        pass: u32,
        stream: u64,
        index: u64,
    ) -> (Rng, SpectralLanes, Lanes) {
        let seed = self.scene.render.seed;
        let rng = Rng::for_sample(seed, (u64::from(pass) << 40) ^ index, stream);
        let mut rng = match integrator.plan.sampler {
            Sampler::Sobol => rng.with_sobol_prefix(
                seed ^ mix64(u64::from(pass)),
                stream ^ (index / SOBOL_POINTS),
                (index % SOBOL_POINTS) as u32,
            ),
            Sampler::Independent => rng,
        };
        let (lanes, pdfs) = self.sample_lanes(rng.uniform());
        (rng, lanes, pdfs)
    }

    /// What turns lane j's radiance into XYZ: K_m x̄ȳz̄(λ) over its density
    /// and the lanes.
    fn xyz_weights(&self, lanes: &SpectralLanes, pdfs: Lanes) -> [[f64; 3]; LANES] {
        let n = self.lanes_per_path();
        std::array::from_fn(|j| {
            let bar = self.cmf.xyz_bar(lanes.wavelengths_nm[j]);
            bar.map(|b| K_M * b / (pdfs[j] * n as f64))
        })
    }
}

/// The splats' lanes over their densities, as the XYZ weights divide (for
/// the spectral layer).
fn over_densities(splats: &mut [Splat], pdfs: Lanes, n: usize) {
    for s in splats {
        for (v, p) in s.lanes.values.iter_mut().zip(pdfs).take(n) {
            *v = (f64::from(*v) / (p * n as f64)) as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;

    /// Mean and variance of `values`.
    fn stats(values: &[f64]) -> (f64, f64) {
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, var)
    }

    /// Each of `walks` ground walks' splats summed over the image
    /// (luminance Y), with the pool's pairs (`pair_share`) or without.
    fn walk_totals(renderer: &Renderer, pair_share: Option<f64>, walks: u64) -> Vec<f64> {
        let integrator = renderer.integrator(2);
        let ground = renderer.ground_splatter().unwrap();
        let mut out = Vec::new();
        (0..walks)
            .map(|walk| {
                let (mut rng, lanes, pdfs) =
                    renderer.splat_walk_start(&integrator, 2, GROUND_STREAM, walk);
                let weights = renderer.xyz_weights(&lanes, pdfs);
                out.clear();
                ground.walk(
                    &integrator,
                    &renderer.camera,
                    &lanes,
                    &weights,
                    1.0,
                    pair_share,
                    &mut rng,
                    &mut out,
                );
                out.iter().map(|s| s.xyz[1]).sum()
            })
            .collect()
    }

    /// Σ over the pixels the ground's splats serve of ∫ J c dω, c the
    /// pool's weight where the pixel's rays meet the ground: what the
    /// camera's samples add per unit of the pool, by a 16 × 16 midpoint
    /// rule in each pixel.
    fn pool_coverage(renderer: &Renderer) -> f64 {
        let ground = renderer.ground_splatter().unwrap();
        let (width, height) = renderer.camera.size();
        let n = 16;
        let mut total = 0.0;
        for y in 0..height as u32 {
            for x in 0..width as u32 {
                if !renderer.camera.pixel_density_bounded(x, y) {
                    continue;
                }
                for k in 0..n * n {
                    let px = f64::from(x) + (f64::from(k % n) + 0.5) / f64::from(n);
                    let py = f64::from(y) + (f64::from(k / n) + 0.5) / f64::from(n);
                    let Some(dir) = renderer.camera.direction(px, py) else {
                        continue;
                    };
                    let Some(span) = renderer
                        .medium
                        .span(renderer.observer_m, dir)
                        .filter(|s| s.hits_ground)
                    else {
                        continue;
                    };
                    total += ground.pool_weight(dir, span.t_exit) / f64::from(n * n);
                }
            }
        }
        total
    }

    #[test]
    fn an_air_walks_directions_follow_their_density() {
        // The air's splat walk draws its direction from a mixture (the
        // guide's table, the sun lobe, the phase function about each of its
        // anchors) and returns the mixture's density. At twilight, from
        // points 0.5, 3 and 12 km above the observer with 32 anchors spread
        // over half a turn of azimuth and 10-41 degrees of elevation, the
        // mean of 1/pdf over 40 000 draws is the sphere's 4π within 4
        // standard errors (each under 2 % of it): a density that did not
        // match the draws, such as lobes about other anchors than those
        // drawn about, would miss it. The draws' picks of the mixture's
        // part are stratified in thirds, as a walk's are: the mean holds
        // only if the pick maps every third's uniforms onto the mixture's
        // parts in their shares.
        let mut scene = Scene::preset("twilight").unwrap();
        scene.render.width = 32;
        scene.render.height = 16;
        let renderer = Renderer::new(&scene).unwrap();
        let integrator = renderer.integrator(2);
        let anchors: Vec<glam::DVec3> = (0..32)
            .map(|k| {
                let k = f64::from(k);
                super::super::direction_from_az_el(90.0 + 5.625 * k, 10.0 + k)
            })
            .collect();
        let up = renderer.observer_m.normalize();
        let sphere = 4.0 * std::f64::consts::PI;
        for height_m in [500.0, 3e3, 12e3] {
            let x = renderer.observer_m + up * height_m;
            let inverse: Vec<f64> = (0..40_000u64)
                .map(|i| {
                    let (mut rng, lanes, _) =
                        renderer.splat_walk_start(&integrator, 2, SPLAT_STREAM, i);
                    let c = integrator.medium.coefficients(x.length(), &lanes);
                    let select = ((i % 3) as f64 + rng.uniform()) / 3.0;
                    let (_, pdf, _) = integrator
                        .splat_walk(x, &anchors, &c, &lanes, select, &mut rng)
                        .unwrap();
                    1.0 / pdf
                })
                .collect();
            let (mean, var) = stats(&inverse);
            let se = (var / inverse.len() as f64).sqrt();
            assert!(se < 0.02 * sphere, "{height_m} m: standard error {se}");
            assert!(
                (mean - sphere).abs() < 4.0 * se,
                "{height_m} m: mean 1/pdf {mean} against 4π ± {se}"
            );
        }
    }

    #[test]
    fn a_spectral_image_keeps_each_bounces_own_estimate() {
        // The pool's light is XYZ; a spectral film's lanes need each
        // bounce's own.
        let mut scene = Scene::preset("sunset").unwrap();
        assert!(Renderer::new(&scene).unwrap().plan().ground_pool);
        scene.output.spectral_bands = Some(47);
        assert!(!Renderer::new(&scene).unwrap().plan().ground_pool);
    }

    #[test]
    fn the_pool_keeps_the_grounds_mean_and_takes_out_its_bounces_noise() {
        // The ground's reflected skylight over the whole image, per walk:
        // the plain walks' splats against the pooled walks' (each bounce
        // less its twin, most pairs left out by roulette) plus the pool's
        // share, which the camera's samples add (the pool's estimate of
        // the foot's light times its weight over the ground pixels, by
        // quadrature). They agree within 4 standard errors (the walks' and
        // the pool's own); a bias above ~3 % of the ground fails. The
        // pooled walks carry a small part of the plain walks' variance.
        for preset in ["midday", "sunset", "twilight", "airliner"] {
            let mut scene = Scene::preset(preset).unwrap();
            scene.render.width = 64;
            scene.render.height = 32;
            let renderer = Renderer::new(&scene).unwrap();
            let integrator = renderer.integrator(2);
            let ground = renderer.ground_splatter().unwrap();
            let pool: Vec<f64> = (0..20_000)
                .map(|i| renderer.pool_term(ground, &integrator, 2, i)[1])
                .collect();
            let (pool_y, pool_var) = stats(&pool);
            let pool_se = (pool_var / pool.len() as f64).sqrt();
            let coverage = pool_coverage(&renderer);
            let walks = 20_000;
            let (plain, plain_var) = stats(&walk_totals(&renderer, None, walks));
            let (pairs, pairs_var) = stats(&walk_totals(&renderer, Some(PAIR_SHARE), walks));
            let pooled = pairs + coverage * pool_y;
            let se = ((plain_var + pairs_var) / walks as f64 + (coverage * pool_se).powi(2)).sqrt();
            println!(
                "{preset}: {pooled} ({pairs} pairs) vs {plain} se {se}; var ratio {}",
                pairs_var / plain_var
            );
            assert!(
                (pooled - plain).abs() < 4.0 * se,
                "{preset}: {pooled} pooled ({pairs} the pairs) against {plain} ± {se}"
            );
            // 10⁻⁶–10⁻⁵ of it near the ground, 0.013 from the airliner.
            let ratio = pairs_var / plain_var;
            assert!(ratio < 0.1, "{preset}: variance ratio {ratio}");
        }
    }

    #[test]
    fn the_camera_branches_over_a_splatted_ground_keep_their_mean() {
        // Where the ground's skylight is splatted, a camera ray that meets
        // the ground lets its branches into the air in front go on only
        // with a probability (their share of the pixel's light). At midday
        // (rays toward the ground 1°, 3° and 6° below the horizon) and from
        // an airliner (5°, 20°, 60°): the camera's light (the ground's sunlight,
        // the air's once-scattered light and the branches' paths; lanes'
        // sum, 20 000 paths) agrees within 4 standard errors with that of
        // a plan without Russian roulette (whose camera branches go on with
        // the scattered fraction alone, another probability, and whose
        // paths are never rouletted) — and both exceed, by more than 8
        // standard errors, the light without any branch, so a wrong weight
        // of the branches' light would show.
        for (preset, elevations_deg) in [
            ("midday", [-1.0, -3.0, -6.0]),
            ("airliner", [-5.0, -20.0, -60.0]),
        ] {
            let renderer = |roulette: bool| {
                let mut scene = Scene::preset(preset).unwrap();
                scene.render.width = 32;
                scene.render.height = 16;
                scene.render.integrator.russian_roulette = roulette;
                Renderer::new(&scene).unwrap()
            };
            let (rouletted, always) = (renderer(true), renderer(false));
            for elevation_deg in elevations_deg {
                let dir = super::super::direction_from_az_el(30.0, elevation_deg);
                let light = |r: &Renderer, branches: bool| -> (f64, f64) {
                    let integrator = r.integrator(2).with_splatting(!branches, true);
                    let values: Vec<f64> = (0..20_000u64)
                        .map(|i| {
                            let mut rng = crate::rng::Rng::for_sample(7, i, 0);
                            let (lanes, _) = r.sample_lanes(rng.uniform());
                            let l = integrator.light(r.observer_m, dir, &lanes, &mut rng);
                            l.total[..lanes.active].iter().sum()
                        })
                        .collect();
                    let (mean, var) = stats(&values);
                    (mean, var / values.len() as f64)
                };
                let (a, a_var) = light(&rouletted, true);
                let (b, b_var) = light(&always, true);
                let (c, c_var) = light(&rouletted, false);
                let se = (a_var + b_var).sqrt();
                println!("{preset} {elevation_deg}°: {a} vs {b} ± {se}; without branches {c}");
                assert!(
                    (a - b).abs() < 4.0 * se,
                    "{preset} {elevation_deg}°: {a} against {b} ± {se}"
                );
                for (x, x_var) in [(a, a_var), (b, b_var)] {
                    let se = (x_var + c_var).sqrt();
                    assert!(
                        x - c > 8.0 * se,
                        "{preset} {elevation_deg}°: {x} against {c} ± {se}"
                    );
                }
            }
        }
    }
}
