//! The sky's light on the ground splatted along the scene's circles of
//! symmetry.
//!
//! The ground is Lambertian and the scene is unchanged by any rotation R
//! about the sun's axis through the Earth's centre ([`super::circles`]), so
//! the radiance the ground reflects, ρ(x) = (a/π) E(x) with E the skylight
//! irradiance, is the same at x and at R x, toward every direction. A
//! pixel's reflected skylight is an integral over the visible ground,
//!
//! V = ∫ J(ω) T(O, x) cos_x / t² ρ(x) dA, dA = R_g² sin θ dθ dψ,
//!
//! ω = (x − O)/t the camera direction, cos_x = x̂·(−ω), J =
//! [`Camera::pixels_per_sr`] where ω falls in the pixel. The camera's own
//! paths estimate ρ at each ground point they meet by one bounce; near the
//! observer all the ground it sees has one irradiance, and a bounce's
//! noise (its path's, at sunset and twilight most of the ground's) stays
//! in one pixel. Here one bounce serves many pixels: an angle θ is drawn,
//! a bounce path at x₀ = (R_g, θ, 0) estimates ρ(x₀) — also an unbiased
//! estimate of ρ at every x_k = R_k x₀ — and K positions ψ_k
//! ([`GROUND_SPLATS`] at 256×128, more at finer images)
//! along the circle each add J T cos_x R_g² sin θ ρ̂ / (t² p(θ) q(ψ_k)) to
//! the pixel that sees x_k, q the positions' combined density (balance
//! heuristic over their three kinds, multi-sample MIS). Each pixel's
//! expected sum of splats is its V exactly; the bounce's noise is spread
//! over the pixels along the circle.
//!
//! * **Angles** θ through the distance u = R_g (θ − θ₀) along the ground
//!   toward the sun from the observer's foot, from a table over u of the
//!   positions' own integral, ∫ J T cos_x / t² dψ (times the guide's light
//!   at the ground point, where there is a guide): near the foot, seen from
//!   a height h, a line of ground at distance u fills ∝ h / (u² + h²) of a
//!   view, and of an equirect map, whose pixels shrink as cos el toward
//!   the nadir, ∝ ln(h/|u|) more; the table's bins are log-spaced in |u|,
//!   each weighted by the most of the integral at its edges and centre
//!   (a bin the image's edge cuts keeps the mass of its visible part). A
//!   share uniform over the visible ground keeps the density positive
//!   wherever a circle can be seen.
//! * **Positions** ψ on the visible arc, stratified, of three kinds
//!   combined by the balance heuristic: from a Cauchy density about the
//!   point nearest the observer (following 1/t², as for the air), from a
//!   Cauchy density as narrow as the circle passes the observer's foot
//!   (the equirect map's 1/cos el), and uniform.
//!
//! * **The pool** (`ground_pool`): each bounce less its twin at the
//!   observer's foot, and the camera's samples add one estimate of the
//!   foot's light per pass where they meet the ground
//!   ([`GroundSplatter::walk`], [`GroundPool`]). ρ depends on x only
//!   through the sun's zenith angle there, which over the ground seen
//!   from near it changes by less than the horizon's dip, so the pair
//!   nearly cancels (most pairs are left out by roulette) and the ground's
//!   light takes the pool's noise, shared by every pixel, in place of the
//!   bounces' and of where their positions land.
//!
//! The ground's direct sunlight stays with the camera paths (one
//! next-event estimate, little variance). Splats into pixels whose density
//! J varies too much within them ([`Camera::pixel_density_bounded`]) are
//! dropped; those pixels' camera paths keep their own bounces.

use std::f64::consts::PI;

use glam::DVec3;
use rayon::prelude::*;

use super::camera::Camera;
use super::circle_geometry::{cauchy_scale, Arc, SunAxis};
use super::film_spectral::{Splat, SplatLanes};
use super::guide::SkyGuide;
use super::integrator::Integrator;
use super::medium::{Lanes, Medium, SpectralLanes, LANES};
use super::observer_depths::ObserverRays;
use crate::rng::Rng;

/// Positions along a circle per bounce: a position costs a transmittance
/// look-up and a projection, a bounce a whole path. The reflected
/// skylight is nearly the same over the visible ground, so the ground's
/// noise follows how many pixels each bounce's estimate is spread over
/// more than how many bounces there are: one bounce of many positions
/// beats several of few (`BENCHMARKS.md`, the ground splatting row).
/// This many at the bench's 256×128 map, half the air's positions at any
/// size ([`super::circle_geometry::splats_per_walk`]).
pub const GROUND_SPLATS: usize = 48;
/// The most positions per bounce.
pub const MAX_GROUND_SPLATS: usize = super::circle_geometry::MAX_SPLATS_PER_WALK / 2;
/// Of them, 3/8 from the Cauchy density about the observer's nearest
/// point and 3/8 from the narrow one about the foot's (the rest uniform).
const CAUCHY_GROUND_EIGHTHS: usize = 3;
const NARROW_GROUND_EIGHTHS: usize = 3;
/// With the pool, the distance from the foot (m) at and past which a
/// bounce and its twin are always traced; nearer, with probability
/// √(u / it), at least the caller's share.
pub const PAIR_FULL_DISTANCE_M: f64 = 4000.0;
/// The pool's weight is whole within this distance (m) of the foot toward
/// the sun ([`GroundSplatter::pool_weight`]): with the sun low, a bounce
/// and its twin this far apart no longer take the same path most of the
/// time, and their difference's variance nears a bounce's own.
pub const POOL_FULL_M: f64 = 10_000.0;
/// ... and 0 from this distance (m) on, where the bounce goes alone.
pub const POOL_NONE_M: f64 = 50_000.0;
/// Share of the angles drawn uniformly over the visible ground.
const UNIFORM_SHARE: f64 = 0.05;
/// Share of the table's mass from the positions' integral alone (the rest
/// weighted by the guide's light at the ground point): the guide's light
/// is once-scattered only, and the ground in the night reflects more.
const GEOMETRIC_SHARE: f64 = 0.2;
/// The table's bins per side of the foot, log-spaced in |u| from
/// [`FIRST_EDGE`] × the height (one bin below it) to the horizon.
const SIDE_BINS: usize = 64;
const FIRST_EDGE: f64 = 1e-3;
/// Stratified sets of positions per point of a bin for its integral (at
/// the strata's centres).
const TABLE_NODES: usize = 16;
/// Seed of the table's transmittance estimates.
const TABLE_SEED: u64 = 0x6_0c1e;
/// The table's wavelength, nm.
const TABLE_WAVELENGTH_NM: f64 = 550.0;
/// The least height (m) the densities take as the observer's (an observer
/// on the ground would give them no width).
const MIN_HEIGHT_M: f64 = 0.01;
/// The splat's transmittance stops this fraction of the way short of the
/// ground point, so that rounding in the ray's ground hit never reads it as
/// hidden (a millionth of the path's transmittance: far below any noise).
const SHORT_OF_GROUND: f64 = 1e-6;

/// Where one position of a circle lands: its pixel, camera direction,
/// distance and J cos_x R_g² sin θ / (t² q(ψ)) (before the angle's
/// density).
struct Landing {
    pixel: u32,
    column_offset: f32,
    dir: DVec3,
    t_m: f64,
    weight: f64,
}

/// The circle at one angle: its visible arc and the positions' densities.
struct GroundArc {
    theta: f64,
    /// sin θ and cos θ.
    sines: (f64, f64),
    half: f64,
    near: Arc,
    narrow: Arc,
    /// Positions per kind: Cauchy about the nearest point, narrow Cauchy,
    /// uniform.
    counts: [usize; 3],
}

impl GroundArc {
    /// ψ of stratum position `k` (of the arc's positions) at offset `v`.
    fn position(&self, k: usize, v: f64) -> f64 {
        let [cauchy, narrow, uniform] = self.counts;
        if k < cauchy {
            self.near.cauchy((k as f64 + v) / cauchy as f64)
        } else if k < cauchy + narrow {
            let k = k - cauchy;
            self.narrow.cauchy((k as f64 + v) / narrow as f64)
        } else {
            let k = k - cauchy - narrow;
            self.half * (2.0 * (k as f64 + v) / uniform as f64 - 1.0)
        }
    }

    /// The positions' combined density at `psi` (balance heuristic,
    /// multi-sample MIS: a sum over positions divides each term by it).
    fn density(&self, psi: f64) -> f64 {
        let [cauchy, narrow, uniform] = self.counts;
        cauchy as f64 * self.near.cauchy_density(psi)
            + narrow as f64 * self.narrow.cauchy_density(psi)
            + uniform as f64 / (2.0 * self.half)
    }
}

/// Positions per kind for `splats` positions a bounce.
fn kind_counts(splats: usize) -> [usize; 3] {
    let cauchy = splats * CAUCHY_GROUND_EIGHTHS / 8;
    let narrow = splats * NARROW_GROUND_EIGHTHS / 8;
    [cauchy, narrow, splats - cauchy - narrow]
}

/// The probability that a bounce and its twin are traced, at `u_m` from
/// the foot toward the sun: their difference is small near the foot
/// and grows with the distance, √(|u| / [`PAIR_FULL_DISTANCE_M`]),
/// at least `share`.
fn pair_probability(u_m: f64, share: f64) -> f64 {
    (u_m.abs() / PAIR_FULL_DISTANCE_M)
        .sqrt()
        .clamp(share.min(1.0), 1.0)
}

/// Splats the skylight the ground reflects, for one scene and camera.
pub struct GroundSplatter {
    axis: SunAxis,
    /// The observer's height above the ground (m, floored).
    height_m: f64,
    /// The visible ground's half-width |u| ≤ it (m).
    limit_m: f64,
    /// Bin edges in u (m), ascending from −`limit_m` to `limit_m`.
    edges: Vec<f64>,
    /// Probability of each bin and their running sum; empty where nothing
    /// in view had weight (then the uniform density alone).
    bins: Vec<f64>,
    cdf: Vec<f64>,
    /// The look-ups of the rays from the observer.
    observer: ObserverRays,
    /// The lanes at [`TABLE_WAVELENGTH_NM`]: the pool's share of a
    /// position is weighted by the table's transmittance there.
    table_lanes: SpectralLanes,
    /// The unit normal at the observer's foot, where a bounce's twin and
    /// the pool's bounces leave ([`Self::walk`]).
    foot_normal: DVec3,
    /// Positions per bounce: half the air's per point
    /// ([`super::circle_geometry::splats_per_walk`]).
    splats: usize,
    /// About how many pixels the visible ground fills: the table's
    /// integral of the positions' weights, ∫ J T dω over the ground, each
    /// bin at its most (18 146 at the bench's 256×128 midday, where 16 384
    /// see the ground; 55 of 64 at 16×8).
    ground_pixels: f64,
}

impl GroundSplatter {
    /// The splatter for `camera` at `observer_m`, its table built with
    /// `integrator`'s transmittance estimates and `guide`'s light; `None`
    /// where the scene has no circles (the sun at the zenith or nadir),
    /// the observer is not above the ground, or the ground is black.
    pub fn new(
        medium: &Medium,
        integrator: &Integrator<'_>,
        guide: Option<&SkyGuide>,
        camera: &Camera,
        observer_m: DVec3,
    ) -> Option<Self> {
        let ground_m = medium.planet_radius_m;
        let axis = SunAxis::new(
            observer_m,
            integrator.sun_direction,
            ground_m,
            medium.top_radius_m,
        )?;
        if axis.r0_m <= ground_m || medium.ground_albedo_max <= 0.0 {
            return None;
        }
        let height_m = (axis.r0_m - ground_m).max(MIN_HEIGHT_M);
        let limit_m = ground_m * axis.horizon_angle(ground_m);
        let first = (FIRST_EDGE * height_m).min(0.5 * limit_m);
        let side: Vec<f64> = std::iter::once(0.0)
            .chain(
                (0..SIDE_BINS)
                    .map(|i| first * (limit_m / first).powf(i as f64 / (SIDE_BINS - 1) as f64)),
            )
            .collect();
        let edges: Vec<f64> = side
            .iter()
            .rev()
            .map(|u| -u)
            .chain(side.iter().skip(1).copied())
            .collect();
        let foot_normal = axis.point(1.0, axis.theta0, 0.0);
        let mut splatter = Self {
            axis,
            height_m,
            limit_m,
            edges,
            bins: Vec::new(),
            cdf: Vec::new(),
            observer: ObserverRays::new(medium, observer_m),
            table_lanes: SpectralLanes::new(
                Lanes::from([TABLE_WAVELENGTH_NM; LANES]),
                1,
                medium,
                true,
            ),
            foot_normal,
            splats: super::circle_geometry::splats_per_walk(camera) / 2,
            ground_pixels: 0.0,
        };
        let lanes = splatter.table_lanes.clone();
        // Per bin: the positions' integral (and with the guide's light) at
        // the most of its edges and centre, times its width. At the most:
        // a bin that the image's edge cuts has a visible edge, and its mass
        // must not hang on whether its centre's circle is seen (a bin of
        // no mass leaves its pixels to the uniform share: fireflies).
        let masses: Vec<(f64, f64)> = (0..splatter.edges.len() - 1)
            .into_par_iter()
            .map(|bin| {
                let (lo, hi) = (splatter.edges[bin], splatter.edges[bin + 1]);
                let mut rng = Rng::new(TABLE_SEED, bin as u64);
                [lo, 0.5 * (lo + hi), hi]
                    .into_iter()
                    .map(|u| {
                        let Some(arc) = splatter.arc(u) else {
                            return (0.0, 0.0);
                        };
                        let mut integral = 0.0;
                        for node in 0..TABLE_NODES {
                            // Each node one full stratified set of positions.
                            let v = (node as f64 + 0.5) / TABLE_NODES as f64;
                            for k in 0..splatter.splats {
                                let Some(landing) = splatter.land(&arc, arc.position(k, v), camera)
                                else {
                                    continue;
                                };
                                let Some(tr) = integrator.transmittance_from(
                                    splatter.observer.start(),
                                    landing.dir,
                                    landing.t_m * (1.0 - SHORT_OF_GROUND),
                                    &lanes,
                                    &mut rng,
                                ) else {
                                    continue;
                                };
                                integral += tr[0] * landing.weight / TABLE_NODES as f64;
                            }
                        }
                        let light = guide.map_or(1.0, |g| {
                            g.skylight(medium, splatter.axis.point(ground_m, arc.theta, 0.0))
                        });
                        // Per dθ → per du.
                        let geometric = integral / ground_m * (hi - lo);
                        (geometric, geometric * light)
                    })
                    .fold((0.0_f64, 0.0_f64), |a, b| (a.0.max(b.0), a.1.max(b.1)))
            })
            .collect();
        let (geometric, lit): (f64, f64) = masses
            .iter()
            .fold((0.0, 0.0), |(g, l), m| (g + m.0, l + m.1));
        if geometric > 0.0 && geometric.is_finite() {
            splatter.ground_pixels = geometric;
            let lit_share = if lit > 0.0 && lit.is_finite() {
                1.0 - GEOMETRIC_SHARE
            } else {
                0.0
            };
            splatter.bins = masses
                .iter()
                .map(|(g, l)| {
                    (1.0 - lit_share) * g / geometric
                        + if lit_share > 0.0 {
                            lit_share * l / lit
                        } else {
                            0.0
                        }
                })
                .collect();
            let mut sum = 0.0;
            splatter.cdf = splatter
                .bins
                .iter()
                .map(|p| {
                    sum += p;
                    sum
                })
                .collect();
        }
        Some(splatter)
    }

    /// The circle at distance `u` from the foot, or `None` where none of
    /// it is visible.
    fn arc(&self, u: f64) -> Option<GroundArc> {
        let axis = &self.axis;
        let ground_m = axis.ground_m;
        let theta = axis.theta0 + u / ground_m;
        if !(0.0..=PI).contains(&theta) {
            return None;
        }
        let half = axis.half_arc(ground_m, theta);
        if half <= 0.0 {
            return None;
        }
        let scale = cauchy_scale(axis, ground_m, theta);
        // The nearest point's distance over its horizontal distance from
        // the foot: the narrow density's scale is the latter's.
        let foot = u.abs() / u.hypot(self.height_m);
        Some(GroundArc {
            theta,
            sines: (theta.sin(), theta.cos()),
            half,
            near: Arc::new(half, scale),
            narrow: Arc::new(half, scale * foot.max(1e-6)),
            counts: kind_counts(self.splats),
        })
    }

    /// Where position `psi` of `arc` lands in `camera`, or `None` where it
    /// is not seen (or in a pixel that takes no splats).
    fn land(&self, arc: &GroundArc, psi: f64, camera: &Camera) -> Option<Landing> {
        let axis = &self.axis;
        let ground_m = axis.ground_m;
        let x = axis.circle_at(ground_m, arc.sines).point(psi.sin_cos());
        let to = x - axis.observer_m;
        let t_m = to.length();
        let dir = to / t_m;
        // Facing the observer: the sphere hides no point that faces it.
        let cos_x = -dir.dot(x / ground_m);
        if cos_x <= 0.0 {
            return None;
        }
        let per_sr = camera.pixels_per_sr(dir);
        if per_sr <= 0.0 {
            return None;
        }
        let (px, py) = camera.splat_position(dir)?;
        let (width, _) = camera.size();
        let weight =
            per_sr * cos_x * ground_m * ground_m * arc.sines.0 / (t_m * t_m * arc.density(psi));
        Some(Landing {
            pixel: (py as u32) * width as u32 + px as u32,
            column_offset: px.fract() as f32,
            dir,
            t_m,
            weight,
        })
    }

    /// Density of u (per metre).
    fn u_density(&self, u: f64) -> f64 {
        if u.abs() > self.limit_m {
            return 0.0;
        }
        let uniform = 1.0 / (2.0 * self.limit_m);
        if self.bins.is_empty() {
            return uniform;
        }
        let i = self
            .edges
            .partition_point(|&e| e <= u)
            .clamp(1, self.bins.len())
            - 1;
        let width = self.edges[i + 1] - self.edges[i];
        UNIFORM_SHARE * uniform + (1.0 - UNIFORM_SHARE) * self.bins[i] / width
    }

    fn sample_u(&self, choice: f64, v: f64, w: f64) -> f64 {
        if self.bins.is_empty() || choice < UNIFORM_SHARE {
            return self.limit_m * (2.0 * v - 1.0);
        }
        let i = self
            .cdf
            .partition_point(|&c| c <= w)
            .min(self.cdf.len() - 1);
        self.edges[i] + v * (self.edges[i + 1] - self.edges[i])
    }

    /// A circle drawn for one bounce: its arc, the angle's density (per
    /// radian) and where its positions land in `camera` — `None` where
    /// none does (the bounce would serve no pixel: no path is traced).
    /// With `pair_share` (the pool's), the bounce is kept by Russian
    /// roulette with probability q ([`pair_probability`]), returned
    /// too (1 without), and `None` where it is not.
    #[allow(clippy::type_complexity)]
    fn circle(
        &self,
        camera: &Camera,
        pair_share: Option<f64>,
        rng: &mut Rng,
    ) -> Option<(GroundArc, f64, f64, [Option<Landing>; MAX_GROUND_SPLATS])> {
        let (choice, v, w) = (rng.uniform(), rng.uniform(), rng.uniform());
        let u = self.sample_u(choice, v, w);
        let u_density = self.u_density(u);
        let arc = self.arc(u).filter(|_| u_density > 0.0)?;
        let q = pair_share.map_or(1.0, |share| pair_probability(u, share));
        if pair_share.is_some() && rng.uniform() >= q {
            return None;
        }
        let offset = rng.uniform();
        let landings: [Option<Landing>; MAX_GROUND_SPLATS] = std::array::from_fn(|k| {
            (k < self.splats)
                .then(|| self.land(&arc, arc.position(k, offset), camera))
                .flatten()
        });
        // Per dθ: per du × R_g.
        let theta_density = u_density * self.axis.ground_m;
        landings
            .iter()
            .any(Option::is_some)
            .then_some((arc, theta_density, q, landings))
    }

    /// The weight c(x) of the pool's light at the ground point x at
    /// distance `t_m` along the unit direction `dir` from the observer: the
    /// observer's table's transmittance to it at 550 nm times κ(u), which
    /// is 1 within [`POOL_FULL_M`] of the foot toward the sun and falls to
    /// 0 at [`POOL_NONE_M`], where a bounce and its twin are no longer
    /// alike ([`Self::walk`]). A function of x alone: the camera's samples
    /// add c P̂ where their rays meet the ground, and each splat takes c ρ̂⁰
    /// out.
    pub fn pool_weight(&self, dir: DVec3, t_m: f64) -> f64 {
        let axis = &self.axis;
        let x = axis.observer_m + dir * t_m;
        let theta = x.cross(axis.sun).length().atan2(x.dot(axis.sun));
        let u_m = ((theta - axis.theta0) * axis.ground_m).abs();
        let kappa = ((POOL_NONE_M - u_m) / (POOL_NONE_M - POOL_FULL_M)).clamp(0.0, 1.0);
        if kappa == 0.0 {
            return 0.0;
        }
        let t_short = t_m * (1.0 - SHORT_OF_GROUND);
        kappa
            * self
                .observer
                .table_transmittance(dir, t_short, &self.table_lanes)
                .map_or(0.0, |tr| tr[0])
    }

    /// Positions per bounce: splats a bounce makes at most.
    pub fn splats_per_bounce(&self) -> usize {
        self.splats
    }

    /// About how many of the image's pixels see the ground (0 where none
    /// does): what a pass's bounces are spread over.
    pub fn ground_pixels(&self) -> f64 {
        self.ground_pixels
    }

    /// The skylight reflected at the observer's foot, by one bounce: what a
    /// bounce's twin estimates, and the pool's bounces
    /// ([`Self::walk`]).
    pub fn foot_light(
        &self,
        integrator: &Integrator<'_>,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Lanes {
        integrator.ground_light(self.foot_normal, lanes, rng)
    }

    /// One bounce and its splats (at most [`Self::splats_per_bounce`])
    /// into `out`, each weighted by `scale` (the share of the walk's unit
    /// the bounce is); `wavelength_weights[j]` turns lane j's radiance into
    /// XYZ as in [`super::circles::CircleSplatter::walk`]. Returns the
    /// splats discarded as not finite.
    ///
    /// With the pool (`pair_share`), each position's XYZ is the bounce
    /// less its twin,
    ///
    /// w Σ_j x̄_j (T_j ρ̂_j − c ρ̂⁰_j) / q,
    ///
    /// ρ̂ the bounce, ρ̂⁰ its twin (the same bounce, random numbers and
    /// lanes from the foot), T_j the position's transmittance, c its
    /// [`Self::pool_weight`] and w its weight, the pair kept with
    /// probability q. The camera's samples add c P̂ where they meet the
    /// ground, P̂ the pass's pool (independent bounces from the foot): with
    /// E[P̂] = E[ρ̂⁰], the sum's mean is the plain estimate's. By the
    /// scene's symmetry about the Earth's centre ρ(x) depends on x only
    /// through the sun's zenith angle there, which over the ground seen
    /// from near it changes by less than the horizon's dip: a bounce and
    /// its twin take nearly the same path and their difference is small
    /// (`BENCHMARKS.md`, the ground pool's row), so most pairs are left
    /// out, and the ground's light takes the pool's noise, shared by every
    /// pixel, in place of each bounce's.
    #[allow(clippy::too_many_arguments)]
    pub fn walk(
        &self,
        integrator: &Integrator<'_>,
        camera: &Camera,
        lanes: &SpectralLanes,
        wavelength_weights: &[[f64; 3]; LANES],
        scale: f64,
        pair_share: Option<f64>,
        rng: &mut Rng,
        out: &mut Vec<Splat>,
    ) -> u64 {
        let Some((arc, theta_density, q, landings)) = self.circle(camera, pair_share, rng) else {
            return 0;
        };
        let normal = self.axis.point(1.0, arc.theta, 0.0);
        let mut twin_rng = pair_share.map(|_| rng.clone());
        let reflected = integrator.ground_light(normal, lanes, rng) / q;
        let twin = twin_rng
            .as_mut()
            .map(|twin_rng| self.foot_light(integrator, lanes, twin_rng) / q);
        if twin.is_none() && reflected[..lanes.active].iter().all(|&l| l == 0.0) {
            return 0;
        }
        let mut discarded = 0;
        for landing in landings.into_iter().flatten() {
            let t_short = landing.t_m * (1.0 - SHORT_OF_GROUND);
            // `None`: hidden. The plain estimate then leaves the position
            // out; the twin's term stays, as the camera's c P̂ does.
            let tr = self
                .observer
                .transmittance(integrator, landing.dir, t_short, lanes, rng);
            if twin.is_none() && tr.is_none() {
                continue;
            }
            let weight = scale * landing.weight / theta_density;
            let c = twin.map_or(0.0, |_| self.pool_weight(landing.dir, landing.t_m));
            let mut xyz = [0.0; 3];
            let mut spectral = SplatLanes::default();
            for j in 0..lanes.active {
                let l = tr.map_or(0.0, |tr| tr[j] * reflected[j] * weight);
                let controlled = twin.map_or(l, |twin| l - c * twin[j] * weight);
                for (value, bar) in xyz.iter_mut().zip(wavelength_weights[j]) {
                    *value += controlled * bar;
                }
                spectral.wavelengths_nm[j] = lanes.wavelengths_nm[j] as f32;
                spectral.values[j] = l as f32;
            }
            if xyz.iter().all(|v| v.is_finite()) {
                out.push(Splat {
                    pixel: landing.pixel,
                    column_offset: landing.column_offset,
                    xyz,
                    lanes: spectral,
                });
            } else {
                discarded += 1;
            }
        }
        discarded
    }
}

/// A pass's pool: its estimate P̂ (XYZ) of the skylight reflected at the
/// observer's foot, which a camera sample adds where its ray meets the
/// ground, weighted by [`GroundSplatter::pool_weight`] there.
pub struct GroundPool<'a> {
    splatter: &'a GroundSplatter,
    medium: &'a Medium,
    xyz: [f64; 3],
}

impl<'a> GroundPool<'a> {
    /// The pool P̂ = `xyz` of `splatter`'s scene in `medium`.
    pub fn new(splatter: &'a GroundSplatter, medium: &'a Medium, xyz: [f64; 3]) -> Self {
        Self {
            splatter,
            medium,
            xyz,
        }
    }

    /// Adds the pool's light to a camera sample's `xyz` (Y in cd m⁻²)
    /// along the unit `dir` from the observer, where the ray meets the
    /// ground.
    pub fn add_to(&self, xyz: &mut [f64; 3], dir: DVec3) {
        let Some(span) = self
            .medium
            .span(self.splatter.axis.observer_m, dir)
            .filter(|s| s.hits_ground)
        else {
            return;
        };
        let c = self.splatter.pool_weight(dir, span.t_exit);
        for (value, p) in xyz.iter_mut().zip(self.xyz) {
            *value += c * p;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::render::direction_from_az_el;
    use crate::scene::{CameraKind, CameraParams};

    /// A sunset splatter for `camera_params` at `width` × `height` seen from
    /// `altitude_m`, and its camera.
    fn sunset_splatter(
        camera_params: &CameraParams,
        width: u32,
        height: u32,
        altitude_m: f64,
    ) -> (GroundSplatter, Camera) {
        let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
        let sun = direction_from_az_el(270.0, 2.0);
        let plan = crate::plan::TechniquePlan::new(
            &crate::plan::IntegratorOptions::default(),
            &crate::plan::Conditions::new(2.0, &AtmosphereParams::default(), true),
        );
        let guide = SkyGuide::new(&medium, sun);
        let integrator = Integrator::new(&medium, &plan, sun).with_sky_guide(&guide);
        let camera = Camera::new(camera_params, width, height);
        let observer = DVec3::new(0.0, 0.0, medium.planet_radius_m + altitude_m);
        let splatter =
            GroundSplatter::new(&medium, &integrator, Some(&guide), &camera, observer).unwrap();
        (splatter, camera)
    }

    /// Each pixel's mean over `walks` circles of Σ J cos_x dA / (t² p):
    /// the estimate of ∫ J dω over the ground the pixel sees, with its
    /// standard error; the same per row (its pixels' mean, the error over
    /// walks: one walk's positions fall in several pixels of a row, so
    /// the row's error is not its pixels' taken as independent); and the
    /// largest weight one walk brought a pixel.
    fn coverage(
        splatter: &GroundSplatter,
        camera: &Camera,
        walks: u64,
    ) -> (Coverage, Coverage, f64) {
        let (width, height) = camera.size();
        let mut largest: f64 = 0.0;
        let pixels = (width * height) as usize;
        let (mut sums, mut squares) = (vec![0.0; pixels], vec![0.0; pixels]);
        let rows = height as usize;
        let (mut row_sums, mut row_squares) = (vec![0.0; rows], vec![0.0; rows]);
        let mut walk_rows = vec![0.0; rows];
        let mut walk_sums = vec![0.0; pixels];
        for walk in 0..walks {
            let mut rng = Rng::new(7, walk);
            let Some((_, theta_density, _, landings)) = splatter.circle(camera, None, &mut rng)
            else {
                continue;
            };
            let mut touched = Vec::new();
            for landing in landings.into_iter().flatten() {
                let p = landing.pixel as usize;
                if walk_sums[p] == 0.0 {
                    touched.push(p);
                }
                walk_sums[p] += landing.weight / theta_density;
            }
            for p in touched {
                largest = largest.max(walk_sums[p]);
                sums[p] += walk_sums[p];
                squares[p] += walk_sums[p] * walk_sums[p];
                walk_rows[p / width as usize] += walk_sums[p] / width;
                walk_sums[p] = 0.0;
            }
            for (y, v) in walk_rows.iter_mut().enumerate() {
                row_sums[y] += *v;
                row_squares[y] += *v * *v;
                *v = 0.0;
            }
        }
        let n = walks as f64;
        let stats = |sums: &[f64], squares: &[f64]| -> Coverage {
            let means: Vec<f64> = sums.iter().map(|s| s / n).collect();
            let errors = squares
                .iter()
                .zip(&means)
                .map(|(q, m)| ((q / n - m * m).max(0.0) / n).sqrt())
                .collect();
            (means, errors)
        };
        (
            stats(&sums, &squares),
            stats(&row_sums, &row_squares),
            largest,
        )
    }

    /// Means and their standard errors.
    type Coverage = (Vec<f64>, Vec<f64>);

    #[test]
    fn the_angles_density_is_normalised() {
        let (splatter, _) = sunset_splatter(&CameraParams::default(), 32, 16, 2.0);
        assert!(!splatter.bins.is_empty());
        // ∫ p(u) du by the midpoint rule within each bin (p is constant
        // there) and over the uniform share.
        let total: f64 = splatter
            .edges
            .windows(2)
            .map(|e| splatter.u_density(0.5 * (e[0] + e[1])) * (e[1] - e[0]))
            .sum();
        assert!((total - 1.0).abs() < 1e-9, "{total}");
        assert_eq!(splatter.u_density(1.01 * splatter.limit_m), 0.0);
    }

    #[test]
    fn splats_cover_every_ground_pixel_once() {
        // With unit light and no air, a pixel's splats estimate ∫ J dω over
        // the ground it sees: 1 where it sees only ground. Rows of an
        // equirect map from just below the horizon's to the last but one
        // (the bottom row, the pole's, takes no splats), the horizon's row
        // at the share of it below the horizon's dip (arccos R/(R + h)),
        // from 2 m and from 10 km, and every pixel of a view looking down: each row's (pixel's) mean within
        // 4 standard errors of it, which lie below 2 %. A Jacobian or a
        // density wrong by a factor anywhere in θ or ψ fails, and so does
        // a density that leaves some visible ground to its uniform share.
        let (width, height) = (32, 16);
        // From the ground and from an airliner (the table's scales follow
        // the height; the horizon dips 3.2° at 10 km).
        for altitude_m in [2.0, 10e3] {
            let (splatter, camera) =
                sunset_splatter(&CameraParams::default(), width, height, altitude_m);
            let (_, (means, errors), largest) = coverage(&splatter, &camera, 200_000);
            // No walk brings a pixel more than a few hundred times its
            // share (a bin of the angles' table left empty brought 10⁶:
            // fireflies).
            assert!(largest < 1e3, "{altitude_m} m: {largest}");
            let r = splatter.axis.ground_m;
            let dip_deg = (r / (r + altitude_m)).acos().to_degrees();
            let row_deg = 180.0 / f64::from(height);
            for y in height / 2..height - 1 {
                let (mean, error) = (means[y as usize], errors[y as usize]);
                let expected = if y == height / 2 {
                    1.0 - dip_deg / row_deg
                } else {
                    1.0
                };
                assert!(
                    error < 0.02,
                    "{altitude_m} m, row {y}: standard error {error}"
                );
                assert!(
                    (mean - expected).abs() < 4.0 * error,
                    "{altitude_m} m, row {y}: {mean} ± {error}, expected {expected}"
                );
            }
            assert_eq!(means[(height - 1) as usize], 0.0);
        }
        let down = CameraParams {
            kind: CameraKind::Perspective,
            pitch_deg: -60.0,
            fov_deg: 60.0,
            ..CameraParams::default()
        };
        let (splatter, camera) = sunset_splatter(&down, 8, 8, 2.0);
        let ((means, errors), _, largest) = coverage(&splatter, &camera, 400_000);
        assert!(largest < 1e3, "{largest}");
        for (p, (mean, error)) in means.iter().zip(&errors).enumerate() {
            assert!(*error < 0.02, "pixel {p}: standard error {error}");
            assert!(
                (mean - 1.0).abs() < 4.0 * error,
                "pixel {p}: {mean} ± {error}"
            );
        }
    }
}
