//! The spectral path tracer: one camera path per call, several wavelengths
//! per path.
//!
//! **Camera rays** (with a [`CameraDensities`] table and `camera_samples` >
//! 0, the default): the segment from the observer is estimated through
//! in-scattering points drawn from the expected sunlight along it, tabulated
//! once per render by view direction. Each point gets a next-event estimate
//! toward the sun (single scattering: rel. std 0.2–1 per path where delta
//! tracking's is 1–20, `BENCHMARKS.md`), and the path then *branches*:
//! `camera_branches` continuations, each from its own point drawn from the
//! skylight part of the density (or from the ground), weighted 1/N. Every
//! camera path thus carries the multiply scattered light, which holds most
//! of the variance, and the camera segment's cost is shared by N estimates
//! of it. Scattering there is forced, not sampled, so a branch starts with
//! the weight ≈ the chance that light scatters at all; roulette plays on the
//! weight relative to that start.
//!
//! **Estimator.** Along every other segment a majorant process proposes
//! tentative collisions (delta tracking over shell-wise majorants; see
//! [`super::medium`]). At each tentative collision at distance t the
//! null-collision form of the radiative transfer equation,
//! L(x) = ∫ T̄(t) [σ_s L_s + σ_n L] dt + T̄ L_background (Galtier et al. 2013),
//! is estimated by
//! * next-event estimation toward the solar disc, weighted by σ_s/σ̄, at
//!   *every* tentative collision (the collision estimator for direct light),
//! * then a random choice between a real scattering event (probability P_s)
//!   and a null collision (1 − P_s), each weighted by its coefficient over
//!   σ̄ and its probability.
//!
//! Absorption never terminates a path; it only weights it. Russian roulette
//! ends paths without bias. On the branches of camera paths the first
//! tentative collision is forced into the segment where the ray would
//! otherwise leave the atmosphere ([`crate::plan::IntegratorOptions::forced_collision_depth`]):
//! an escaping path adds nothing there, so conditioning on not escaping and
//! weighting by its probability turns a rare large contribution into a
//! frequent small one.
//!
//! **Scattering directions** mix the phase function about the path's
//! direction with the phase function about the sun's (`sun_lobe`; see
//! `Integrator::sample_scatter_direction`).
//!
//! Which of the techniques below are on, and how strongly, is the
//! [`TechniquePlan`]'s choice ([`crate::plan`], by the sun's regime); the
//! integrator reads the plan as it is.
//!
//! **Segment estimates at low sun.** With the sun low, `sunlight_samples`
//! estimates every segment like the camera ray's, from the [`SkyGuide`]'s
//! cached densities of rays from points of the same altitude and solar
//! zenith (without a guide, from a density built per segment,
//! [`super::sunlight`]), the path going on from its first real scattering:
//! at sunset and twilight most light reaches a path from thin sunlit
//! stretches of long rays, which chance collisions rarely hit. Higher up
//! the sun, delta tracking wins at equal time.
//!
//! **In the planet's shadow** a share of the scattering directions
//! (`sky_guide`) come from the table
//! of incoming once-scattered light ([`super::guide`]): there the light
//! comes from the sunlit air above the horizon, which no phase function
//! about a fixed axis finds. With the sun low, sunlit points are guided
//! too (`sky_guide_sunlit`).
//!
//! **Roulette and splitting by importance** (`splitting`, at twilight): at a real scattering of a low-sun
//! path, the path's expected light is its weight times the guide's mean
//! once-scattered radiance at the point ([`SkyGuide::skylight`]); relative
//! to that at the path's start it decides roulette (below a quarter) or how
//! many copies go on (at most 4 at a vertex, 256 from one start), each with
//! its own direction (Vorba and Křivánek 2016, adjoint-driven Russian
//! roulette and splitting, with the guide's table as the adjoint).
//! At twilight most of the variance lies in orders ≥ 3 (90 % of it for 32 %
//! of the light, `BENCHMARKS.md`): paths wandering in the shadow that rarely
//! reach the brighter air high up or toward the sun, and there carry large
//! weights.
//!
//! **The once-scattered light as a control variate** (`control_variate`, at
//! sunset, unless the haze is too thick or too peaked for its table,
//! [`crate::plan::control_table_holds`]): at
//! every real scattering the exact phase-function integral of a tabulated
//! approximation A of the once-scattered light arriving there is added,
//! and the path going on estimates only L − A ([`super::control`]). At
//! sunset the aureole, cut by the bright horizon, gives the light a point
//! sees a sharp structure that the sampled directions find unevenly; taken
//! out, it leaves 0.67× the variance (`BENCHMARKS.md`).
//!
//! **Multiply scattered light splatted along circles of symmetry**
//! (`circle_splatting`, with the sun low): the camera's
//! paths keep only their next-event points (more per ray than without:
//! single scattering's variance is per point) and ground branches, and the
//! film gets the light scattered again in the air from paths started
//! anywhere in the visible air, each added to the pixels along its point's
//! circle about the sun's axis ([`super::circles`],
//! `Integrator::splat_walk`).
//!
//! **Alternative kept as an option** (not faster at equal time on the
//! benchmark scenes; see `BENCHMARKS.md`): `shadow_samples` estimates only
//! the segments that start in the planet's shadow through points drawn
//! from their expected sunlight.
//!
//! **Wavelengths.** Lanes carry hero-rotated wavelengths (Wilkie et al. 2014).
//! Every random decision (real vs. null, phase-function component and angle)
//! samples the *average* of the lanes' distributions, and each lane is
//! weighted by its own density over that average (a one-sample mixture / MIS
//! with the balance heuristic per decision), so every lane stays unbiased and
//! weights are bounded by the lane count.

use std::f64::consts::PI;

use glam::DVec3;

use super::columns::FixedStart;
use super::control::{CellCoefficients, Frame, Picked, RadianceTable, COEFFICIENTS, L_MAX, NODES};
use super::directions::orthonormal_basis;
use super::guide::{GuideAt, SkyGuide};
use super::medium::Span;
use super::medium::{Bounds, Lanes, Medium, SpectralLanes, LANES};
use super::sunlight::{CachedRayDensity, CameraDensities, Component, InScatterDistribution};
use super::trig::sin_cos_turns;
use crate::physics::{rayleigh, sun};
use crate::plan::{TechniquePlan, MAX_BRANCHES, MAX_FORCED_COLLISION_DEPTH, MAX_SUNLIGHT_SAMPLES};
use crate::rng::Rng;

/// σ_s,R P_R + σ_s,A P_A of lane `j` at cosine `mu`, given the aerosol's
/// phase function there (the same for every lane).
fn lane_scattering_phase(
    c: &super::medium::Coefficients,
    lanes: &SpectralLanes,
    j: usize,
    mu: f64,
    aerosol_phase: f64,
) -> f64 {
    c.rayleigh[j] * rayleigh::phase(mu, lanes.rayleigh_gamma[j])
        + c.aerosol_scattering[j] * aerosol_phase
}

/// Uniforms a scattering direction draws ([`Integrator::sample_scatter_direction`]
/// without a guide: the lobe, the lane, the component, μ and φ).
const DIRECTION_UNIFORMS: usize = 5;

/// Radiance estimate per lane (W m⁻² sr⁻¹ nm⁻¹, or per unit irradiance).
pub type Radiance = Lanes;

/// A path's light per lane as it is gathered: the total, and the part of
/// it that is the sun's disc seen straight along the camera ray (the `sun`
/// layer, [`super::film_layers`]). Reads and writes as its total.
#[derive(Clone, Copy, Debug, Default)]
pub struct Light {
    /// All the light.
    pub total: Radiance,
    /// The sun's disc through the air along the camera ray, not scattered.
    pub disc: Radiance,
}

impl std::ops::Deref for Light {
    type Target = Radiance;

    fn deref(&self) -> &Radiance {
        &self.total
    }
}

impl std::ops::DerefMut for Light {
    fn deref_mut(&mut self) -> &mut Radiance {
        &mut self.total
    }
}

/// Scattering vertices become paths longer than this only through Russian
/// roulette with survival ≤ 0.9, so paths end with probability one.
const ROULETTE_CAP_DEPTH: u32 = MAX_FORCED_COLLISION_DEPTH;
/// Russian roulette leaves a path alone until its weight, relative to where
/// it started, falls below this; survivors carry this weight. At 1 (roulette
/// on any loss), a ground bounce of albedo 0.3 killed 70 % of the paths and
/// tripled the weight of the rest: per path relative std from orbit 0.65 vs
/// 0.52 here, at midday 0.43 vs 0.36; bench at equal time, alternated runs:
/// 0.86–0.95× the noise in every scene (BENCHMARKS.md).
const ROULETTE_WEIGHT: f64 = 0.25;
/// Paths expected to bring more than this, relative to their start, split.
const SPLIT_WEIGHT: f64 = 2.0;
/// Most copies of one path at one vertex.
const MAX_SPLIT: usize = 4;
/// Most copies one path start may become through splitting (the product of
/// the copies made along any copy's line). Without it, a thick haze below
/// the sunlit air, whose importance grows by orders of magnitude from the
/// ground up, split each start into ~20 000 copies (aerosol amount 100 at
/// −4°: up to 60 000 vertices per camera path against 13 in the preset);
/// in the twilight preset it binds for about 1 camera path in 100, and the
/// noise is unchanged (`BENCHMARKS.md`).
const MAX_COPIES: usize = 256;

/// Zenith × azimuth strata of the directions a control cell is projected
/// from.
const CONTROL_DIRECTIONS: (usize, usize) = (32, 16);
/// Seed of the control cells' own random numbers.
const CONTROL_SEED: u64 = 0xc047_a01e;

/// Where a path stands in roulette and splitting by importance
/// ([`Integrator::weight_window`]).
#[derive(Clone, Copy, Debug)]
struct Window {
    /// Expected light at the path's start (or where a cap last lifted it),
    /// per unit weight.
    reference: f64,
    /// The product of the copy counts along this path's line since its
    /// start — the inverse of its share of the start's weight — at most
    /// [`MAX_COPIES`].
    copies: usize,
}

/// Where a path starts: position, direction, scatterings so far, and the
/// scale of its weight for roulette (see [`survives_roulette`]).
type Start = (DVec3, DVec3, u32, f64);
/// Where a path goes on: position, direction, weight.
type Vertex = (DVec3, DVec3, Lanes);
/// Where a path goes on from a segment.
#[derive(Clone, Copy)]
enum Next<'t> {
    /// A vertex with its new direction chosen.
    Vertex(Vertex),
    /// A real scattering at a point of a path along a direction, weighted
    /// up to the choice of its new direction ([`Integrator::scatter`]).
    /// With the control variate on, its expansions at the point.
    Scatter(DVec3, DVec3, Lanes, Option<ControlAt<'t>>),
}
/// The vertices a segment branches into.
type Branches = [Option<Vertex>; MAX_BRANCHES];
/// Ground vertices sit this far above the surface, m.
const SURFACE_OFFSET_M: f64 = 1e-3;

/// Everything the integrator needs about one scene.
pub struct Integrator<'a> {
    pub medium: &'a Medium,
    pub plan: &'a TechniquePlan,
    pub sun_direction: DVec3,
    cos_sun_radius: f64,
    sun_solid_angle_sr: f64,
    sun_frame: (DVec3, DVec3),
    bounds: Bounds,
    camera: Option<&'a CameraDensities>,
    guide: Option<&'a SkyGuide>,
    control: Option<&'a RadianceTable>,
    /// Camera rays branch only from the ground: the light scattered more
    /// than once in the air reaches the film through [`super::circles`].
    splatting: bool,
    /// The aerosol phase function's Legendre moments k_0..k_L.
    aerosol_moments: [f64; L_MAX + 1],
}

/// The control variate at one scattering point: the point's frame and the
/// expansions drawn for its lanes ([`RadianceTable::pick`]).
#[derive(Clone, Copy)]
struct ControlAt<'t> {
    frame: Frame,
    picked: Picked<'t, LANES>,
}

impl ControlAt<'_> {
    /// Subtracts beta × A(dir): the path going on along `dir` from this
    /// point with weight `beta` now estimates L − A.
    fn subtract(&self, lanes: &SpectralLanes, dir: DVec3, beta: &Lanes, radiance: &mut Lanes) {
        let a = self.picked.evaluate(&self.frame.basis(dir));
        for j in 0..LANES {
            radiance[j] -= beta[j] * lanes.sun_irradiance[j] * a[j];
        }
    }
}

/// A density of in-scattering distances along one path segment.
trait SegmentDensity {
    /// A distance from `component` for the uniform variate `u` ∈ [0, 1) and
    /// its density, m⁻¹.
    fn sample(&self, component: Component, u: f64) -> (f64, f64);
    /// Expected shares of the light found by going on from the medium and
    /// from the ground (only their ratio matters).
    fn shares(&self, ground_albedo: f64) -> (f64, f64);
}

impl SegmentDensity for InScatterDistribution {
    fn sample(&self, component: Component, u: f64) -> (f64, f64) {
        InScatterDistribution::sample(self, component, u)
    }
    fn shares(&self, ground_albedo: f64) -> (f64, f64) {
        InScatterDistribution::shares(self, ground_albedo)
    }
}

impl SegmentDensity for CachedRayDensity<'_> {
    fn sample(&self, component: Component, u: f64) -> (f64, f64) {
        CachedRayDensity::sample(self, component, u)
    }
    fn shares(&self, ground_albedo: f64) -> (f64, f64) {
        CachedRayDensity::shares(self, ground_albedo)
    }
}

impl<'a> Integrator<'a> {
    pub fn new(medium: &'a Medium, plan: &'a TechniquePlan, sun_direction: DVec3) -> Self {
        Self {
            medium,
            plan,
            sun_direction,
            cos_sun_radius: sun::ANGULAR_RADIUS_DEG.to_radians().cos(),
            sun_solid_angle_sr: sun::solid_angle_sr(),
            sun_frame: orthonormal_basis(sun_direction),
            bounds: if plan.segments.tight_majorants {
                Bounds::Tight
            } else {
                Bounds::Global
            },
            camera: None,
            guide: None,
            control: None,
            splatting: false,
            aerosol_moments: medium.aerosol_phase.legendre_moments(),
        }
    }

    /// Uses `table` as the diffuse light's control variate where the
    /// options turn it on ([`crate::plan::IntegratorOptions::control_variate`]; never
    /// with `max_scattering_order`, whose orders it would mix).
    #[must_use]
    pub fn with_control(mut self, table: &'a RadianceTable) -> Self {
        if self.plan.control_variate {
            self.control = Some(table);
        }
        self
    }

    /// Whether single estimates may be negative (with the control variate
    /// on: its mean is not); otherwise a negative one is a defect.
    pub fn signed_estimates(&self) -> bool {
        self.control.is_some()
    }

    /// The control variate at a scattering point `x` for `lanes`, if on.
    fn control_at(&self, x: DVec3, lanes: &SpectralLanes, rng: &mut Rng) -> Option<ControlAt<'a>> {
        let table = self.control?;
        let u = (rng.uniform(), rng.uniform());
        let picked = table.pick(x, &lanes.wavelengths_nm, u, |i, k| {
            self.project_cell(table, i, k)
        });
        Some(ControlAt {
            frame: table.frame(x),
            picked,
        })
    }

    /// Adds beta × ∫ σ_s p(dir·ω') A(ω') dω' for a path along `dir` that
    /// scatters at the point of `at` (coefficients `c`) with weight `beta`
    /// before its direction's factor: Σ_l (σ_R k_l^R + σ_A k_l^A) Σ_m a_lm
    /// Y_lm(dir), exact by the Funk–Hecke theorem.
    fn control_in(
        &self,
        at: &ControlAt<'_>,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        dir: DVec3,
        beta: &Lanes,
        radiance: &mut Light,
    ) {
        let y = at.frame.basis(dir);
        let degrees = at.picked.degrees(&y);
        for j in 0..LANES {
            let rayleigh_k2 = rayleigh::phase_legendre_2(lanes.rayleigh_gamma[j]);
            let aerosol: f64 = self
                .aerosol_moments
                .iter()
                .zip(&degrees)
                .map(|(k, d)| k * d[j])
                .sum();
            let sum = c.rayleigh[j] * (degrees[0][j] + rayleigh_k2 * degrees[2][j])
                + c.aerosol_scattering[j] * aerosol;
            radiance[j] += beta[j] * lanes.sun_irradiance[j] * sum;
        }
    }

    /// The control's expansions for the table's cell (altitude `i`, solar
    /// zenith `k`): the once-scattered light (and the ground's direct
    /// reflection) arriving at the cell's central point, per unit
    /// irradiance at the table's wavelength nodes, projected on the basis
    /// from next-event estimates along [`CONTROL_DIRECTIONS`] stratified
    /// directions. Single scattering holds the sharp part of the light a
    /// point sees (the aureole, the horizon), which is what the control
    /// takes out of the paths (`BENCHMARKS.md`); the random
    /// numbers are the cell's own, so the table does not depend on the
    /// render's.
    fn project_cell(&self, table: &RadianceTable, i: usize, k: usize) -> CellCoefficients {
        let plan = self.plan.for_control_table();
        let mut single = Integrator::new(self.medium, &plan, self.sun_direction);
        single.guide = self.guide;
        let origin = table.cell_point(i, k);
        let frame = table.frame(origin);
        let (nt, np) = CONTROL_DIRECTIONS;
        let weight = 4.0 * PI / (nt * np) as f64;
        let mut rng = Rng::new(CONTROL_SEED, (i * 1000 + k) as u64);
        let sets: Vec<SpectralLanes> = (0..NODES.div_ceil(LANES))
            .map(|set| {
                let nm = std::array::from_fn(|j| table.node_nm((set * LANES + j).min(NODES - 1)));
                SpectralLanes::new(nm, LANES, self.medium, true)
            })
            .collect();
        let mut coefficients = [[0.0; COEFFICIENTS]; NODES];
        for it in 0..nt {
            for ip in 0..np {
                let cos_theta = -1.0 + 2.0 * (it as f64 + rng.uniform()) / nt as f64;
                let phi = PI * (ip as f64 + rng.uniform()) / np as f64;
                let dir = frame.direction(cos_theta, phi);
                let y = frame.basis(dir);
                for (set, lanes) in sets.iter().enumerate() {
                    let mut radiance = Light::default();
                    let from = (origin, dir, 1, 1.0);
                    if plan.segments.sunlight_samples > 0 && single.guide.is_some() {
                        single.trace_sunlit(from, [1.0; LANES], lanes, &mut radiance, &mut rng);
                    } else {
                        single.trace(from, [1.0; LANES], lanes, &mut radiance, &mut rng);
                    }
                    for (j, l) in radiance.total.iter().enumerate() {
                        let n = set * LANES + j;
                        if n < NODES && l.is_finite() {
                            for (c, y) in coefficients[n].iter_mut().zip(&y) {
                                *c += weight * l * y;
                            }
                        }
                    }
                }
            }
        }
        coefficients
    }

    /// Camera rays no longer branch from the air (only from the ground):
    /// the film gets that light from [`super::circles`] instead.
    #[must_use]
    pub(crate) fn with_circle_splatting(mut self) -> Self {
        self.splatting = true;
        self
    }

    /// Uses `guide` for scattering directions (see
    /// [`crate::plan::IntegratorOptions::sky_guide`]) and for the distance densities of
    /// `Self::trace_sunlit`'s segments.
    #[must_use]
    pub fn with_sky_guide(mut self, guide: &'a SkyGuide) -> Self {
        self.guide = Some(guide);
        self
    }

    /// Uses `camera` for rays that start at its observer (see
    /// [`crate::plan::IntegratorOptions::camera_samples`]).
    #[must_use]
    pub fn with_camera_densities(mut self, camera: &'a CameraDensities) -> Self {
        self.camera = Some(camera);
        self
    }

    /// Uniform direction within the solar disc's cone. Unit without
    /// normalising: the frame is orthonormal and sin² + cos² = 1 to within
    /// 1e-15 (a square root and a division saved on every next-event
    /// estimate).
    fn sample_sun_direction(&self, rng: &mut Rng) -> DVec3 {
        let cos_theta = 1.0 - rng.uniform() * (1.0 - self.cos_sun_radius);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let (sin_phi, cos_phi) = sin_cos_turns(rng.uniform());
        let (t, b) = self.sun_frame;
        t * (sin_theta * cos_phi) + b * (sin_theta * sin_phi) + self.sun_direction * cos_theta
    }

    /// The solar irradiance per lane that a next-event estimate along
    /// `to_sun`, drawn uniformly in the disc's cone
    /// ([`Self::sample_sun_direction`]), carries: E × L(μ)/L̄, the disc's
    /// radiance there over its mean ([`sun::radiance_over_mean`]). Its mean
    /// over the cone is E, so the estimate of a limb-darkened disc stays
    /// unbiased; for a uniform disc the factor is exactly 1.
    fn sun_irradiance_toward(&self, to_sun: DVec3, lanes: &SpectralLanes) -> Lanes {
        let mu = sun::disc_mu(to_sun.dot(self.sun_direction), self.cos_sun_radius);
        std::array::from_fn(|j| lanes.sun_irradiance[j] * sun::polynomial(&lanes.limb[j], mu))
    }

    /// Solar radiance per lane along `dir`, a direction within the disc:
    /// E / Ω × L(μ)/L̄ (E / Ω for a uniform disc).
    fn sun_radiance(&self, dir: DVec3, lanes: &SpectralLanes) -> Lanes {
        self.sun_irradiance_toward(dir, lanes)
            .map(|e| e / self.sun_solid_angle_sr)
    }

    fn shadow(&self, origin: DVec3, dir: DVec3, lanes: &SpectralLanes, rng: &mut Rng) -> Lanes {
        self.medium.transmittance(
            origin,
            dir,
            lanes,
            self.plan.segments.shadow_transmittance,
            self.bounds,
            rng,
        )
    }

    /// Phase function of lane `j` times σ_s (i.e. σ_s,R P_R + σ_s,A P_A), per sr.
    pub(crate) fn scattering_phase(
        &self,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        j: usize,
        mu: f64,
    ) -> f64 {
        let aerosol = self.medium.aerosol_phase.eval(mu);
        lane_scattering_phase(c, lanes, j, mu, aerosol)
    }

    /// [`Self::scattering_phase`] of every lane (the aerosol's phase
    /// function, the same for all, evaluated once); inactive lanes 0.
    pub(crate) fn scattering_phases(
        &self,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        mu: f64,
    ) -> Lanes {
        let aerosol = self.medium.aerosol_phase.eval(mu);
        std::array::from_fn(|j| {
            if j < lanes.active {
                lane_scattering_phase(c, lanes, j, mu, aerosol)
            } else {
                0.0
            }
        })
    }

    /// Radiance arriving at `origin` from direction `-dir` (i.e. looking along `dir`).
    pub fn radiance(
        &self,
        origin: DVec3,
        dir: DVec3,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Radiance {
        self.light(origin, dir, lanes, rng).total
    }

    /// [`Self::radiance`] with the part of it that is the sun's disc seen
    /// straight along `dir` (through the air, not scattered), from the
    /// same path.
    pub fn light(&self, origin: DVec3, dir: DVec3, lanes: &SpectralLanes, rng: &mut Rng) -> Light {
        let mut radiance = Light::default();
        let opts = self.plan;
        let camera = self
            .camera
            .filter(|c| opts.camera.samples > 0 && c.origin_m() == origin);
        match camera {
            Some(camera) if opts.segments.next_event_estimation => {
                let branches = self.camera_segment(camera, dir, lanes, &mut radiance, rng);
                // A branch's weight is the chance that light scattered there
                // at all (forced, not sampled) over the branch count, which
                // roulette must not read as a dim path: it plays on the
                // weight relative to the branch's start.
                for (x, new_dir, beta) in branches.into_iter().flatten() {
                    let start = beta[..lanes.active].iter().copied().fold(0.0, f64::max);
                    let scale = if start > 0.0 { 1.0 / start } else { 1.0 };
                    let from = (x, new_dir, 1, scale);
                    if opts.segments.sunlight_samples > 0 {
                        self.trace_sunlit(from, beta, lanes, &mut radiance, rng);
                    } else {
                        self.trace(from, beta, lanes, &mut radiance, rng);
                    }
                }
            }
            _ if opts.segments.sunlight_samples > 0 && opts.segments.next_event_estimation => {
                let from = (origin, dir, 0, 1.0);
                self.trace_sunlit(from, [1.0; LANES], lanes, &mut radiance, rng);
            }
            _ => self.trace(
                (origin, dir, 0, 1.0),
                [1.0; LANES],
                lanes,
                &mut radiance,
                rng,
            ),
        }
        radiance
    }

    /// One walk of [`super::circles`]: the light arriving at `x` along a
    /// direction drawn here, estimated by a path that starts at `x` after
    /// one scattering (so the sun's disc itself is never added). The
    /// direction's density mixes the guide's table and the sun lobe, as at
    /// any scattering, with the phase function about *each* of
    /// `camera_dirs` in equal shares instead of about one incoming
    /// direction: the walk serves a camera ray along every one of them.
    /// Returns the direction, its density (sr⁻¹) and the radiance estimate,
    /// or `None` for an empty `camera_dirs`.
    pub(crate) fn splat_walk(
        &self,
        x: DVec3,
        camera_dirs: &[DVec3],
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<(DVec3, f64, Radiance)> {
        if camera_dirs.is_empty() {
            return None;
        }
        let opts = self.plan;
        let at = self.direction_guide(x);
        let guides = at.as_ref().is_some_and(GuideAt::guides);
        let g = if guides {
            opts.directions.sky_guide
        } else {
            0.0
        };
        let alpha = opts.directions.sun_lobe;
        let dir = match at.as_ref() {
            Some(guide) if guides && rng.uniform() < g => guide.sample(rng).0,
            _ if rng.uniform() < alpha => {
                self.sample_phase_direction(self.sun_direction, c, lanes, rng)
            }
            _ => {
                let n = camera_dirs.len();
                let k = ((rng.uniform() * n as f64) as usize).min(n - 1);
                self.sample_phase_direction(camera_dirs[k], c, lanes, rng)
            }
        };
        let lobes = camera_dirs
            .iter()
            .map(|d| self.phase_mixture_pdf(c, lanes, d.dot(dir)))
            .sum::<f64>()
            / camera_dirs.len() as f64;
        let pdf = self.direction_mixture_pdf(c, lanes, dir, lobes, at.as_ref().filter(|_| guides));
        let mut radiance = Light::default();
        let start = (x, dir, 1, 1.0);
        if opts.segments.sunlight_samples > 0 {
            self.trace_sunlit(start, [1.0; LANES], lanes, &mut radiance, rng);
        } else {
            self.trace(start, [1.0; LANES], lanes, &mut radiance, rng);
        }
        Some((dir, pdf, radiance.total))
    }

    /// [`Self::transmittance_to`] from a fixed start (the observer) along
    /// the unit direction `dir`, through the start's cached look-ups
    /// ([`FixedStart`]) where the rays' estimator is the table's (residual
    /// ratio tracking, tight bounds) and the ray does not start downward.
    pub(crate) fn transmittance_from(
        &self,
        start: &FixedStart,
        dir: DVec3,
        t_m: f64,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<Lanes> {
        let table = self.medium.transmittance_from(
            start,
            dir,
            t_m,
            lanes,
            self.plan.segments.shadow_transmittance,
            self.bounds,
            rng,
        );
        table.or_else(|| self.transmittance_to(start.position_m(), dir, t_m, lanes, rng))
    }

    /// Transmittance from `origin` along `dir` to distance `t_m`, or `None`
    /// where the ground hides that point.
    pub(crate) fn transmittance_to(
        &self,
        origin: DVec3,
        dir: DVec3,
        t_m: f64,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<Lanes> {
        let span = self.medium.span(origin, dir)?;
        if span.hits_ground && span.t_exit < t_m {
            return None;
        }
        let mut points = [(t_m.clamp(span.t_enter, span.t_exit), [0.0; LANES])];
        self.medium.transmittance_along(
            origin,
            dir,
            span,
            lanes,
            self.plan.segments.shadow_transmittance,
            self.bounds,
            &mut points,
            false,
            rng,
        );
        Some(points[0].1)
    }

    /// The camera ray's segment, estimated through in-scattering points from
    /// the cached expected-sunlight density ([`CameraDensities`]) like one
    /// segment of [`Self::trace_sunlit`]; returns the vertices the path
    /// branches into.
    fn camera_segment(
        &self,
        camera: &CameraDensities,
        dir: DVec3,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Branches {
        let origin = camera.origin_m();
        let beta = [1.0; LANES];
        let Some(span) = self.medium.span(origin, dir) else {
            self.add_sun_disc(dir, 0, &beta, lanes, radiance);
            return [None; MAX_BRANCHES];
        };
        let density = camera.density(self.medium, dir, span);
        let n = (self.plan.camera.samples as usize).min(MAX_SUNLIGHT_SAMPLES);
        let segment = Segment {
            origin,
            dir,
            span,
            depth: 0,
        };
        let branches = (self.plan.camera.branches as usize).clamp(1, MAX_BRANCHES);
        self.estimate_segment(
            &segment,
            &beta,
            Some(&density),
            (n, branches),
            lanes,
            radiance,
            rng,
        )
    }

    /// A path whose every segment is estimated through in-scattering points
    /// drawn from [`InScatterDistribution`] (the expected sunlight along the
    /// segment) instead of delta-tracked collisions. For a segment from x
    /// along ω,
    ///
    /// L(x, ω) = ∫ T(0,t) σ_s(t) ∫ p L_in dω' dt + T(0,t_end) L_end.
    ///
    /// Every point gets a next-event estimate toward the sun, weighted by the
    /// point's density and an unbiased transmittance estimate T̂(0,t); one
    /// point, picked uniformly (so its marginal density is the density
    /// itself), may continue the path into the diffuse light. The end of the
    /// segment adds the ground's direct light or, on camera rays, the sun's
    /// disc, weighted by T̂(0,t_end). Where the segment meets the ground the
    /// path continues either from the medium point or from the ground, chosen
    /// by their expected shares (weights divided by the choice's probability).
    /// Every transmittance on the segment comes from one tracking pass.
    fn trace_sunlit(
        &self,
        (origin, dir, depth, split): Start,
        beta: Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        let window = self.importance(origin).map(|reference| Window {
            reference,
            copies: 1,
        });
        self.walk_sunlit(
            Next::Vertex((origin, dir, beta)),
            (depth, split, window),
            lanes,
            radiance,
            rng,
        );
    }

    /// Expected light a path finds going on from `x`, per unit weight, up
    /// to a constant: the guide's mean once-scattered radiance there.
    fn importance(&self, x: DVec3) -> Option<f64> {
        self.guide
            .filter(|_| self.plan.termination.russian_roulette && self.plan.termination.splitting)
            .map(|g| g.skylight(self.medium, x))
            .filter(|&s| s > 0.0 && s.is_finite())
    }

    /// [`Self::trace_sunlit`] from `next` after `depth` scatterings.
    fn walk_sunlit(
        &self,
        next: Next<'a>,
        (depth, split, window): (u32, f64, Option<Window>),
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        let mut next = Some(next);
        let mut depth = depth;
        let mut window = window;
        while let Some(n) = next {
            // The guide at the vertex, where choosing its direction looked it up.
            let ((origin, dir, beta), at) = match n {
                Next::Vertex(vertex) => (vertex, None),
                Next::Scatter(x, dir_in, mut beta, control) => {
                    let c = self.medium.coefficients(x.length(), lanes);
                    let copies = window.and_then(|window| {
                        self.weight_window(x, &c, &mut beta, (depth, split, window), lanes, rng)
                    });
                    match copies {
                        Some((0, _)) => break,
                        Some((copies, copies_window)) => {
                            // This path goes on as the last copy.
                            window = Some(copies_window);
                            let from = (x, dir_in, &c, control.as_ref());
                            let walk = (depth, split, window);
                            self.copies(from, beta, copies, walk, lanes, radiance, rng)
                        }
                        None => {
                            // Without the guide's importance: roulette as
                            // for any other vertex.
                            let (new_dir, at) = self.scatter(x, dir_in, &c, &mut beta, lanes, rng);
                            if self.plan.termination.russian_roulette
                                && depth >= 2
                                && !survives_roulette(&mut beta, lanes.active, depth, split, rng)
                            {
                                break;
                            }
                            if let Some(control) = &control {
                                control.subtract(lanes, new_dir, &beta, radiance);
                            }
                            ((x, new_dir, beta), at)
                        }
                    }
                }
            };
            let segment = (origin, dir, depth, at);
            next = self.sunlit_segment(segment, &beta, lanes, radiance, rng);
            depth += 1;
            self.roulette_vertex(&mut next, depth, split, lanes, rng);
        }
    }

    /// `copies` copies of a path scattered at `x` along `dir_in`
    /// (coefficients `c`, weight `beta` before the direction's factor),
    /// sharing its weight, each with its own direction: all but one walk on
    /// here; the last is returned.
    #[allow(clippy::too_many_arguments)]
    fn copies(
        &self,
        (x, dir_in, c, control): (
            DVec3,
            DVec3,
            &super::medium::Coefficients,
            Option<&ControlAt<'a>>,
        ),
        beta: Lanes,
        copies: usize,
        walk: (u32, f64, Option<Window>),
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> (Vertex, Option<GuideAt<'a>>) {
        let share = 1.0 / copies as f64;
        let beta = beta.map(|b| b * share);
        for _ in 1..copies {
            let mut copy = beta;
            let (new_dir, _) = self.scatter(x, dir_in, c, &mut copy, lanes, rng);
            if let Some(control) = control {
                control.subtract(lanes, new_dir, &copy, radiance);
            }
            self.walk_sunlit(Next::Vertex((x, new_dir, copy)), walk, lanes, radiance, rng);
        }
        let mut last = beta;
        let (new_dir, at) = self.scatter(x, dir_in, c, &mut last, lanes, rng);
        if let Some(control) = control {
            control.subtract(lanes, new_dir, &last, radiance);
        }
        ((x, new_dir, last), at)
    }

    /// Russian roulette on `next` if it is a vertex with its direction
    /// chosen, after `depth` scatterings (real scatterings play it in
    /// [`Self::walk_sunlit`]); ends the path (`None`) if it loses.
    fn roulette_vertex(
        &self,
        next: &mut Option<Next<'a>>,
        depth: u32,
        split: f64,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) {
        if let Some(Next::Vertex((_, _, beta))) = next {
            if self.plan.termination.russian_roulette
                && depth >= 2
                && !survives_roulette(beta, lanes.active, depth, split, rng)
            {
                *next = None;
            }
        }
    }

    /// Adjoint-driven roulette and splitting at a real scattering at `x`
    /// (coefficients `c`, weight `beta` before the direction's factor):
    /// the path's expected light relative to its window's reference (its
    /// start's) picks how many copies go on (0 = ended; survivors' weights
    /// are divided by their chance, copies share the weight), returned with
    /// the copies' window. Where a cap ([`MAX_SPLIT`] per vertex,
    /// [`MAX_COPIES`] per start) leaves each copy at or above the splitting
    /// threshold, their reference rises to their expected light, so a start
    /// with next to no light (where the guide's table fades to zero, or
    /// deep in a thick haze) cannot make every later vertex split again.
    fn weight_window(
        &self,
        x: DVec3,
        c: &super::medium::Coefficients,
        beta: &mut Lanes,
        (depth, split, window): (u32, f64, Window),
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<(usize, Window)> {
        let Window { reference, copies } = window;
        let here = self.importance(x)?;
        let weight = (0..lanes.active)
            .map(|j| beta[j] * c.scattering(j))
            .fold(0.0, f64::max);
        let expected = split * weight * here / reference;
        if expected < ROULETTE_WEIGHT || depth >= ROULETTE_CAP_DEPTH {
            let mut survive = (expected / ROULETTE_WEIGHT).min(1.0);
            if depth >= ROULETTE_CAP_DEPTH {
                survive = survive.min(0.9);
            }
            if rng.uniform() >= survive {
                return Some((0, window));
            }
            for b in beta.iter_mut() {
                *b /= survive;
            }
            return Some((1, window));
        }
        if expected >= SPLIT_WEIGHT {
            let room = (MAX_COPIES / copies).max(1);
            let split_into = (expected.floor() as usize).min(MAX_SPLIT).min(room);
            let each = expected / split_into as f64;
            let lifted = if each >= SPLIT_WEIGHT {
                reference * each
            } else {
                reference
            };
            let window = Window {
                reference: lifted,
                copies: copies * split_into,
            };
            return Some((split_into, window));
        }
        Some((1, window))
    }

    /// One segment of [`Self::trace_sunlit`] from `origin` along `dir` after
    /// `depth` scatterings with weight `beta` (`at`: the guide at `origin`,
    /// if already looked up); returns the next vertex (position, direction,
    /// weight).
    fn sunlit_segment(
        &self,
        (origin, dir, depth, at): (DVec3, DVec3, u32, Option<GuideAt<'a>>),
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        let segment = self.segment(origin, dir, depth, beta, lanes, radiance)?;
        if let Some(guide) = self.guide {
            let at = at.unwrap_or_else(|| guide.at(self.medium, origin));
            return self.guided_segment(&at, &segment, beta, lanes, radiance, rng);
        }
        let opts = self.plan;
        let max_order = opts.termination.max_scattering_order;
        let span = segment.span;
        let n = (opts.segments.sunlight_samples as usize).min(MAX_SUNLIGHT_SAMPLES);
        if depth >= max_order {
            return self.estimate_segment(&segment, beta, None, (0, 1), lanes, radiance, rng)[0]
                .map(Next::Vertex);
        }
        let mu_sun = dir.dot(self.sun_direction);
        let phase_rayleigh: Lanes =
            std::array::from_fn(|j| rayleigh::phase(mu_sun, lanes.rayleigh_gamma[j]));
        let phase_aerosol = self.medium.aerosol_phase.eval(mu_sun);
        let distribution = InScatterDistribution::new(
            self.medium,
            Some(self.medium.sun_columns()),
            lanes,
            origin,
            dir,
            span,
            self.sun_direction,
            &phase_rayleigh,
            phase_aerosol,
            None,
        );
        let n = if distribution.is_some() { n } else { 0 };
        let distribution = distribution.as_ref().map(|d| d as &dyn SegmentDensity);
        self.estimate_segment(&segment, beta, distribution, (n, 1), lanes, radiance, rng)[0]
            .map(Next::Vertex)
    }

    /// The light along `segment` (reached with weight `beta`) through `n`
    /// in-scattering points drawn from `distribution`, each with a next-event
    /// estimate, plus what lies at the segment's end; returns the vertices
    /// the path goes on from, one per branch of `(n, branches)`, each
    /// weighted 1/branches (see [`Self::trace_sunlit`]).
    #[allow(clippy::too_many_arguments)]
    fn estimate_segment(
        &self,
        segment: &Segment,
        beta: &Lanes,
        distribution: Option<&dyn SegmentDensity>,
        (n, branches): (usize, usize),
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Branches {
        let opts = self.plan;
        let max_order = opts.termination.max_scattering_order;
        let &Segment {
            origin,
            dir,
            span,
            depth,
        } = segment;
        let n = if distribution.is_some() && depth < max_order {
            n
        } else {
            0
        };
        // Where the path goes on: from the medium, from the ground, or not.
        let goes_on = depth + 1 < max_order;
        let ground_goes_on = goes_on && span.hits_ground && self.medium.ground_albedo_max > 0.0;
        let p_medium = match (distribution, goes_on) {
            // The camera ray's light scattered again in the air is splatted.
            _ if depth == 0 && self.splatting => 0.0,
            (Some(d), true) if ground_goes_on => {
                // The largest albedo over wavelength: a density, not a value.
                let (medium, ground) = d.shares(self.medium.ground_albedo_max);
                (medium / (medium + ground)).clamp(0.05, 0.95)
            }
            // Without Russian roulette the path must still end: go on with
            // the expected scattered fraction, as an analog path would.
            (Some(d), true) if !opts.termination.russian_roulette => {
                d.shares(0.0).0.clamp(0.05, 1.0)
            }
            (Some(_), true) => 1.0,
            _ => 0.0,
        };
        let mut from_medium = [false; MAX_BRANCHES];
        for f in &mut from_medium[..branches] {
            *f = rng.uniform() < p_medium;
        }
        // n next-event points stratified in the whole density's cumulative
        // probability, and the points the branches go on from, stratified in
        // the skylight part's; sorted for the transmittance pass. A point
        // outside the span (only through rounding) keeps density 0 and is
        // skipped.
        let mut samples = [(0.0, 0.0, None); MAX_SUNLIGHT_SAMPLES + MAX_BRANCHES];
        let mut m = 0;
        if let Some(d) = distribution {
            for k in 0..n {
                let (t, pdf) = d.sample(Component::Mixture, (k as f64 + rng.uniform()) / n as f64);
                samples[m] = (t, pdf, None);
                m += 1;
            }
            for b in (0..branches).filter(|&b| from_medium[b]) {
                let u = (b as f64 + rng.uniform()) / branches as f64;
                let (t, pdf) = d.sample(Component::Skylight, u);
                samples[m] = (t, pdf, Some(b));
                m += 1;
            }
        }
        for sample in &mut samples[..m] {
            if !(span.t_enter..=span.t_exit).contains(&sample.0) {
                *sample = (span.t_exit, 0.0, sample.2);
            }
        }
        // The branches' direction uniforms, drawn before the transmittance
        // pass (whose number of draws varies) so that a pixel sample's
        // first scatterings take them from its low-discrepancy prefix.
        let mut direction_u = [[0.0; DIRECTION_UNIFORMS]; MAX_BRANCHES];
        for u in direction_u[..branches].iter_mut().flatten() {
            *u = rng.uniform();
        }
        samples[..m].sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut points = [(0.0, [0.0; LANES]); MAX_SUNLIGHT_SAMPLES + MAX_BRANCHES];
        for (point, sample) in points.iter_mut().zip(&samples[..m]) {
            point.0 = sample.0;
        }
        // The transmittance to the end is needed at a ground hit and on a
        // camera ray toward the sun's disc; elsewhere the pass stops at the
        // last point.
        let to_end =
            span.hits_ground || (depth == 0 && dir.dot(self.sun_direction) >= self.cos_sun_radius);
        let tr_end = self.medium.transmittance_along(
            origin,
            dir,
            span,
            lanes,
            opts.segments.shadow_transmittance,
            self.bounds,
            &mut points[..m],
            to_end,
            rng,
        );
        let mut next = [None; MAX_BRANCHES];
        let share = 1.0 / branches.max(1) as f64;
        for (&(t, tr_view), &(_, density, branch)) in points.iter().zip(&samples[..m]) {
            if density <= 0.0 {
                continue;
            }
            let x = origin + dir * t;
            let c = self.medium.coefficients(x.length(), lanes);
            if let Some(b) = branch {
                let (new_dir, pdf, _) = rng.replaying(&direction_u[b], |rng| {
                    self.sample_scatter_direction(x, dir, &c, lanes, rng)
                });
                let mu = dir.dot(new_dir);
                let new_beta = std::array::from_fn(|j| {
                    share * beta[j] * tr_view[j] * self.scattering_phase(&c, lanes, j, mu)
                        / (density * pdf * p_medium)
                });
                if let Some(at) = self.control_at(x, lanes, rng) {
                    let scale: Lanes = std::array::from_fn(|j| {
                        share * beta[j] * tr_view[j] / (density * p_medium)
                    });
                    self.control_in(&at, &c, lanes, dir, &scale, radiance);
                    at.subtract(lanes, new_dir, &new_beta, radiance);
                }
                next[b] = Some((x, new_dir, new_beta));
                continue;
            }
            let to_sun = self.sample_sun_direction(rng);
            let mu = dir.dot(to_sun);
            let tr_sun = self.shadow(x, to_sun, lanes, rng);
            let weight = 1.0 / (n as f64 * density);
            let e_sun = self.sun_irradiance_toward(to_sun, lanes);
            for j in 0..LANES {
                radiance[j] += beta[j]
                    * tr_view[j]
                    * weight
                    * self.scattering_phase(&c, lanes, j, mu)
                    * e_sun[j]
                    * tr_sun[j];
            }
        }
        // What lies at the end (only where the pass went there).
        let Some(tr_end) = tr_end else {
            return next;
        };
        let through: Lanes = std::array::from_fn(|j| beta[j] * tr_end[j]);
        if span.hits_ground {
            let normal = (origin + dir * span.t_exit).normalize();
            self.ground_direct(normal, depth, &through, lanes, radiance, rng);
            if ground_goes_on {
                // Each ground branch bounces on its own (see `ground_vertex`).
                let x = ground_point(self.medium, normal);
                let weight: Lanes = std::array::from_fn(|j| {
                    through[j] * lanes.ground_albedo[j] * share / (1.0 - p_medium)
                });
                for ((slot, _), u) in next[..branches]
                    .iter_mut()
                    .zip(&from_medium)
                    .zip(&direction_u)
                    .filter(|((_, &f), _)| !f)
                {
                    let bounce = rng.replaying(u, |rng| cosine_sample_hemisphere(normal, rng));
                    *slot = Some((x, bounce, weight));
                }
            }
        } else if depth == 0 {
            self.add_sun_disc(dir, 0, &through, lanes, radiance);
        }
        next
    }

    /// The segment from `origin` along `dir` after `depth` scatterings, or
    /// `None` where the ray misses the atmosphere (a camera ray, reached with
    /// weight `beta`, then sees the sun's disc if it looks at it).
    fn segment(
        &self,
        origin: DVec3,
        dir: DVec3,
        depth: u32,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
    ) -> Option<Segment> {
        let Some(span) = self.medium.span(origin, dir) else {
            if depth == 0 {
                self.add_sun_disc(dir, 0, beta, lanes, radiance);
            }
            return None;
        };
        Some(Segment {
            origin,
            dir,
            span,
            depth,
        })
    }

    /// One path segment reached with weight `beta`: next-event points from
    /// the cached density of the ray of the guide `at` the segment's origin
    /// ([`GuideAt::density`]), the path going on from its first real
    /// scattering ([`Self::track_continuation`]).
    fn guided_segment(
        &self,
        at: &GuideAt<'_>,
        segment: &Segment,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        let density = at.density(self.medium, segment.dir, segment.span);
        let n = (self
            .plan
            .segments
            .sunlight_samples
            .max(self.plan.segments.shadow_samples) as usize)
            .min(MAX_SUNLIGHT_SAMPLES);
        self.estimate_segment(segment, beta, Some(&density), (n, 0), lanes, radiance, rng);
        self.track_continuation(segment, beta, lanes, radiance, rng)
    }

    /// Where a path goes on from `segment`, whose light a segment estimate
    /// already counted: its first real scattering by delta tracking (so the
    /// weight changes by about the single-scattering albedo, whatever the
    /// ray), or else the ground's bounce; `None` if the path ends.
    fn track_continuation(
        &self,
        segment: &Segment,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        let &Segment {
            origin,
            dir,
            span,
            depth,
        } = segment;
        let max_order = self.plan.termination.max_scattering_order;
        if depth + 1 >= max_order {
            return None;
        }
        let mut beta = *beta;
        let mut tracker = self.medium.tracker(origin, dir, span, lanes, self.bounds);
        while let Some(collision) = tracker.next(rng) {
            let x = origin + dir * collision.t;
            let c = self.medium.coefficients(x.length(), lanes);
            if real_scattering(&c, collision.majorant, &mut beta, lanes, rng) {
                let control = self.control_at(x, lanes, rng);
                if let Some(at) = &control {
                    self.control_in(at, &c, lanes, dir, &beta, radiance);
                }
                return Some(Next::Scatter(x, dir, beta, control));
            }
        }
        if !span.hits_ground || self.medium.ground_albedo_max <= 0.0 {
            return None;
        }
        // Cosine-weighted bounce: the Lambertian BRDF·cos/pdf = albedo.
        let normal = (origin + dir * span.t_exit).normalize();
        Some(Next::Vertex((
            ground_point(self.medium, normal),
            cosine_sample_hemisphere(normal, rng),
            std::array::from_fn(|j| beta[j] * lanes.ground_albedo[j]),
        )))
    }

    /// `next` with its direction chosen (one copy, no splitting).
    fn resolve(
        &self,
        next: Next<'a>,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> (Vertex, Option<ControlAt<'a>>) {
        match next {
            Next::Vertex(vertex) => (vertex, None),
            Next::Scatter(x, dir, mut beta, control) => {
                let c = self.medium.coefficients(x.length(), lanes);
                let (new_dir, _) = self.scatter(x, dir, &c, &mut beta, lanes, rng);
                ((x, new_dir, beta), control)
            }
        }
    }

    /// Forced collision: on a segment that leaves the atmosphere after
    /// `depth` ≤ [`crate::plan::IntegratorOptions::forced_collision_depth`] scatterings,
    /// conditions `tracker`'s first tentative collision on lying within the
    /// segment and weights `beta` by the chance that it would, 1 − exp(−τ̄).
    /// Unbiased where a path that escapes adds nothing: next-event estimates
    /// have already counted the sun (not on camera rays, depth 0, which may
    /// see its disc), and space is black. An upward ray at midday has τ̄ ≈
    /// 0.1: without forcing, 9 paths in 10 leave with nothing further and
    /// the tenth carries all the higher orders.
    fn force_collision(
        &self,
        tracker: &mut super::tracker::Tracker<'_>,
        span: Span,
        depth: u32,
        beta: &mut Lanes,
        rng: &mut Rng,
    ) {
        if depth == 0 || depth > self.plan.segments.forced_collision_depth || span.hits_ground {
            return;
        }
        let p = tracker.force_collision(rng);
        for b in beta {
            *b *= p;
        }
    }

    /// A new direction for a path along `dir` scattered at `x`
    /// (coefficients `c`), weighting `beta` by σ_s p/pdf; with the guide at
    /// `x` if the choice looked it up.
    fn scatter(
        &self,
        x: DVec3,
        dir: DVec3,
        c: &super::medium::Coefficients,
        beta: &mut Lanes,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> (DVec3, Option<GuideAt<'a>>) {
        let (new_dir, pdf, at) = self.sample_scatter_direction(x, dir, c, lanes, rng);
        let mu = dir.dot(new_dir);
        for (j, b) in beta.iter_mut().enumerate() {
            *b *= self.scattering_phase(c, lanes, j, mu) / pdf;
        }
        (new_dir, at)
    }

    /// The sun's disc seen along `dir` through transmittance `beta` after
    /// `depth` scatterings (at depth 0, straight along the camera ray:
    /// [`Light::disc`] too).
    fn add_sun_disc(
        &self,
        dir: DVec3,
        depth: u32,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
    ) {
        if dir.dot(self.sun_direction) >= self.cos_sun_radius {
            let l_sun = self.sun_radiance(dir, lanes);
            for j in 0..LANES {
                radiance.total[j] += beta[j] * l_sun[j];
                if depth == 0 {
                    radiance.disc[j] += beta[j] * l_sun[j];
                }
            }
        }
    }

    /// A Lambertian ground vertex with normal `normal`, reached after `depth`
    /// scatterings with weight `beta`: adds the sun's direct light and
    /// returns the bounce (vertex, direction, weight) if the path goes on.
    fn ground_vertex(
        &self,
        normal: DVec3,
        depth: u32,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Vertex> {
        self.ground_direct(normal, depth, beta, lanes, radiance, rng);
        let max_order = self.plan.termination.max_scattering_order;
        if depth + 1 >= max_order || self.medium.ground_albedo_max <= 0.0 {
            return None;
        }
        // Cosine-weighted bounce: the Lambertian BRDF·cos/pdf = albedo.
        Some((
            ground_point(self.medium, normal),
            cosine_sample_hemisphere(normal, rng),
            std::array::from_fn(|j| beta[j] * lanes.ground_albedo[j]),
        ))
    }

    /// The sun's direct light reflected at a ground vertex with normal
    /// `normal`, reached after `depth` scatterings with weight `beta`.
    fn ground_direct(
        &self,
        normal: DVec3,
        depth: u32,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        let opts = self.plan;
        let max_order = opts.termination.max_scattering_order;
        let x = ground_point(self.medium, normal);
        if opts.segments.next_event_estimation && depth < max_order {
            let to_sun = self.sample_sun_direction(rng);
            let cos = normal.dot(to_sun);
            if cos > 0.0 {
                let tr = self.shadow(x, to_sun, lanes, rng);
                let e_sun = self.sun_irradiance_toward(to_sun, lanes);
                for j in 0..LANES {
                    radiance[j] += beta[j] * lanes.ground_albedo[j] / PI * cos * e_sun[j] * tr[j];
                }
            }
        }
    }

    /// The guide at `x` where it draws scattering directions there
    /// ([`crate::plan::IntegratorOptions::sky_guide`], at sunlit points only with
    /// [`crate::plan::IntegratorOptions::sky_guide_sunlit`]).
    fn direction_guide(&self, x: DVec3) -> Option<GuideAt<'a>> {
        let opts = self.plan;
        self.guide
            .filter(|g| {
                opts.directions.sky_guide > 0.0
                    && (opts.directions.sky_guide_sunlit || g.shadowed(x))
            })
            .map(|g| g.at(self.medium, x))
    }

    /// Density (sr⁻¹) of `dir` under the scattering directions' mixture:
    /// `phase` (the phase-function part's density, already evaluated),
    /// mixed with the lobe about the sun ([`crate::plan::IntegratorOptions::sun_lobe`])
    /// and, where `guide` is given, the guide's table
    /// ([`crate::plan::IntegratorOptions::sky_guide`]).
    fn direction_mixture_pdf(
        &self,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        dir: DVec3,
        phase: f64,
        guide: Option<&GuideAt<'_>>,
    ) -> f64 {
        let alpha = self.plan.directions.sun_lobe;
        let pdf = if alpha > 0.0 {
            let lobe = self.phase_mixture_pdf(c, lanes, self.sun_direction.dot(dir));
            (1.0 - alpha) * phase + alpha * lobe
        } else {
            phase
        };
        match guide {
            Some(guide) => {
                let g = self.plan.directions.sky_guide;
                (1.0 - g) * pdf + g * guide.pdf(dir)
            }
            None => pdf,
        }
    }

    /// A scattering direction and its density (per sr): with probability
    /// `sun_lobe`, from the phase function about the *sun's* direction, else
    /// about `dir`; the density is the mixture's (one-sample MIS, balance
    /// heuristic), and the guide at `x` where it was looked up (the segment
    /// from `x` reads its densities). Skylight arriving along ω is mostly sunlight scattered
    /// once somewhere along ω, always through the angle between ω and the
    /// sun, so its angular shape is that phase function P(ω·ω_sun) — the
    /// aureole by day, the glow over the hidden sun at twilight. The phase
    /// function of the point itself stands in for the unknown ones along ω.
    fn sample_scatter_direction(
        &self,
        x: DVec3,
        dir: DVec3,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> (DVec3, f64, Option<GuideAt<'a>>) {
        let mut at = self.direction_guide(x);
        let guides = at.as_ref().is_some_and(GuideAt::guides);
        let g = if guides {
            self.plan.directions.sky_guide
        } else {
            0.0
        };
        let alpha = self.plan.directions.sun_lobe;
        let (new_dir, cell) = match at.as_ref() {
            Some(guide) if guides && rng.uniform() < g => {
                let (new_dir, cell) = guide.sample(rng);
                (new_dir, Some(cell))
            }
            _ if rng.uniform() < alpha => (
                self.sample_phase_direction(self.sun_direction, c, lanes, rng),
                None,
            ),
            _ => (self.sample_phase_direction(dir, c, lanes, rng), None),
        };
        if let Some(at) = at.as_mut() {
            at.choose(new_dir, cell);
        }
        let phase = self.phase_mixture_pdf(c, lanes, dir.dot(new_dir));
        let pdf =
            self.direction_mixture_pdf(c, lanes, new_dir, phase, at.as_ref().filter(|_| guides));
        (new_dir, pdf, at)
    }

    /// Density of [`Self::sample_phase_direction`] at cosine `mu`, per sr.
    pub(crate) fn phase_mixture_pdf(
        &self,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        mu: f64,
    ) -> f64 {
        let phases = self.scattering_phases(c, lanes, mu);
        (0..lanes.active)
            .map(|k| phases[k] / c.scattering(k))
            .sum::<f64>()
            / lanes.active as f64
    }

    /// Continue a path from `origin` along `dir` after `depth` scatterings
    /// (one of `split` branches) with weight `beta`, adding what it finds to
    /// `radiance`.
    fn trace(
        &self,
        (origin, dir, depth, split): Start,
        beta: Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        let active = lanes.active;
        let opts = self.plan;
        let mut beta = beta;
        let mut origin = origin;
        let mut dir = dir;
        let mut depth = depth;
        let max_order = opts.termination.max_scattering_order;

        loop {
            let mut scattered = false;
            // The control variate's expansions where the path scattered.
            let mut control = None;
            let shadowed = self
                .guide
                .filter(|g| opts.segments.shadow_samples > 0 && depth > 0 && g.shadowed(origin));
            if let (Some(guide), true) = (shadowed, opts.segments.next_event_estimation) {
                // A segment from the planet's shadow: its sunlit stretch is
                // found by the guide's density, not by chance collisions.
                let next = self
                    .segment(origin, dir, depth, &beta, lanes, radiance)
                    .and_then(|segment| {
                        let at = guide.at(self.medium, origin);
                        self.guided_segment(&at, &segment, &beta, lanes, radiance, rng)
                    });
                let Some(next) = next else { break };
                let vertex;
                (vertex, control) = self.resolve(next, lanes, rng);
                (origin, dir, beta) = vertex;
                depth += 1;
                scattered = true;
            } else if let Some(span) = self.medium.span(origin, dir) {
                let mut tracker = self.medium.tracker(origin, dir, span, lanes, self.bounds);
                if depth > 0 && opts.segments.next_event_estimation {
                    self.force_collision(&mut tracker, span, depth, &mut beta, rng);
                }
                while let Some(collision) = tracker.next(rng) {
                    let x = origin + dir * collision.t;
                    let c = self.medium.coefficients(x.length(), lanes);
                    let majorant = collision.majorant;
                    // A next-event estimate at a vertex after `depth` real
                    // scatterings adds scattering order depth + 1.
                    if opts.segments.next_event_estimation && depth < max_order {
                        let to_sun = self.sample_sun_direction(rng);
                        let mu = dir.dot(to_sun);
                        let tr = self.shadow(x, to_sun, lanes, rng);
                        let e_sun = self.sun_irradiance_toward(to_sun, lanes);
                        for j in 0..LANES {
                            radiance[j] += beta[j] * self.scattering_phase(&c, lanes, j, mu)
                                / majorant
                                * e_sun[j]
                                * tr[j];
                        }
                    }
                    if depth + 1 >= max_order {
                        // Only lower orders wanted: continue as if null.
                        for (j, b) in beta.iter_mut().enumerate() {
                            *b *= 1.0 - c.extinction(j) / majorant;
                        }
                        continue;
                    }
                    if real_scattering(&c, majorant, &mut beta, lanes, rng) {
                        control = self.control_at(x, lanes, rng);
                        if let Some(at) = &control {
                            self.control_in(at, &c, lanes, dir, &beta, radiance);
                        }
                        (dir, _) = self.scatter(x, dir, &c, &mut beta, lanes, rng);
                        origin = x;
                        depth += 1;
                        scattered = true;
                        break;
                    }
                }
                if !scattered && span.hits_ground {
                    let normal = (origin + dir * span.t_exit).normalize();
                    let next = self.ground_vertex(normal, depth, &beta, lanes, radiance, rng);
                    let Some(vertex) = next else { break };
                    (origin, dir, beta) = vertex;
                    depth += 1;
                    scattered = true;
                }
            }
            if !scattered {
                // Escaped to space. The disc is counted here only where no
                // next-event estimate already accounted for it.
                if depth == 0 || !opts.segments.next_event_estimation {
                    self.add_sun_disc(dir, depth, &beta, lanes, radiance);
                }
                break;
            }
            // Russian roulette on the largest lane weight.
            if opts.termination.russian_roulette && depth >= 2 {
                if !survives_roulette(&mut beta, active, depth, split, rng) {
                    break;
                }
            } else if beta[..active].iter().all(|&b| b == 0.0) {
                break;
            }
            if let Some(at) = &control {
                at.subtract(lanes, dir, &beta, radiance);
            }
        }
    }

    /// Sample a new direction from the lane-averaged phase function.
    fn sample_phase_direction(
        &self,
        dir: DVec3,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> DVec3 {
        let k = ((rng.uniform() * lanes.active as f64) as usize).min(lanes.active - 1);
        let mu = if rng.uniform() * c.scattering(k) < c.rayleigh[k] {
            rayleigh::sample_mu(rng.uniform(), lanes.rayleigh_gamma[k])
        } else {
            self.medium.aerosol_phase.sample(|| rng.uniform())
        };
        let (sin_phi, cos_phi) = sin_cos_turns(rng.uniform());
        let sin = (1.0 - mu * mu).max(0.0).sqrt();
        let (t, b) = orthonormal_basis(dir);
        (t * (sin * cos_phi) + b * (sin * sin_phi) + dir * mu).normalize()
    }
}

/// A path segment: from `origin` along `dir` over `span`, after `depth`
/// scatterings.
struct Segment {
    origin: DVec3,
    dir: DVec3,
    span: Span,
    depth: u32,
}

/// Russian roulette after `depth` scatterings: survive with the largest
/// active lane weight times `split` (the weight relative to its value where
/// the path started) over [`ROULETTE_WEIGHT`] (at most 1, and at most 0.9
/// past [`ROULETTE_CAP_DEPTH`], so paths end with probability one), dividing
/// `beta` by that probability on survival.
fn survives_roulette(
    beta: &mut Lanes,
    active: usize,
    depth: u32,
    split: f64,
    rng: &mut Rng,
) -> bool {
    let relative = split * beta[..active].iter().copied().fold(0.0, f64::max);
    let mut survive = (relative / ROULETTE_WEIGHT).min(1.0);
    if depth >= ROULETTE_CAP_DEPTH {
        survive = survive.min(0.9);
    }
    if rng.uniform() >= survive {
        return false;
    }
    for b in beta.iter_mut() {
        *b /= survive;
    }
    true
}

/// The choice at a tentative collision (coefficients `c`, under
/// `majorant`) of [`Integrator::collide`]: whether it is a real scattering,
/// weighting `beta` by 1/(σ̄ P_s) if so (the direction's factor is
/// [`Integrator::scatter`]'s), else by (σ̄ − σ_t)/(σ̄ (1 − P_s)).
fn real_scattering(
    c: &super::medium::Coefficients,
    majorant: f64,
    beta: &mut Lanes,
    lanes: &SpectralLanes,
    rng: &mut Rng,
) -> bool {
    let p_scatter = ((0..lanes.active)
        .map(|j| c.scattering(j) / (majorant - c.absorption[j]).max(1e-300))
        .sum::<f64>()
        / lanes.active as f64)
        .clamp(0.0, 1.0);
    if rng.uniform() < p_scatter {
        for b in beta.iter_mut() {
            *b /= majorant * p_scatter;
        }
        return true;
    }
    for (j, b) in beta.iter_mut().enumerate() {
        *b *= (majorant - c.extinction(j)) / (majorant * (1.0 - p_scatter));
    }
    false
}

/// The ground vertex under unit `normal`, just above the surface.
fn ground_point(medium: &Medium, normal: DVec3) -> DVec3 {
    normal * (medium.planet_radius_m + SURFACE_OFFSET_M)
}

/// Cosine-weighted direction about `normal` (Malley's method).
fn cosine_sample_hemisphere(normal: DVec3, rng: &mut Rng) -> DVec3 {
    let r = rng.uniform().sqrt();
    let (sin_phi, cos_phi) = sin_cos_turns(rng.uniform());
    let z = (1.0 - r * r).max(0.0).sqrt();
    let (t, b) = orthonormal_basis(normal);
    (t * (r * cos_phi) + b * (r * sin_phi) + normal * z).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::IntegratorOptions;

    #[test]
    fn sun_directions_are_unit_and_uniform_over_the_disc() {
        // Not normalised (see `sample_sun_direction`): unit to 1e-14 for
        // suns all over the sky, inside the disc's cone, and uniform in
        // solid angle (half the directions within the cone of half its
        // solid angle, to 4 standard errors).
        let atmosphere =
            crate::atmosphere::Atmosphere::new(crate::atmosphere::AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let plan = TechniquePlan::outside_a_scene(&IntegratorOptions::default());
        let mut rng = Rng::new(3, 4);
        for (az, el) in [
            (0.0, 90.0),
            (123.0, 45.0),
            (270.0, 2.0),
            (10.0, -4.0),
            (200.0, -90.0),
        ] {
            let sun = super::super::direction_from_az_el(az, el);
            let integrator = Integrator::new(&medium, &plan, sun);
            let cos_radius = integrator.cos_sun_radius;
            let cos_half = 1.0 - 0.5 * (1.0 - cos_radius);
            let n = 20_000;
            let mut inner = 0;
            for _ in 0..n {
                let dir = integrator.sample_sun_direction(&mut rng);
                assert!((dir.length() - 1.0).abs() < 1e-14, "{az} {el}: {dir}");
                let cos = dir.dot(sun);
                assert!(cos >= cos_radius - 1e-15, "{az} {el}: {cos}");
                inner += u32::from(cos >= cos_half);
            }
            let share = f64::from(inner) / f64::from(n);
            assert!(
                (share - 0.5).abs() < 4.0 * (0.25 / f64::from(n)).sqrt(),
                "{share}"
            );
        }
    }

    #[test]
    fn the_weight_window_splits_within_its_cap_and_roulettes_dim_paths() {
        use crate::atmosphere::{Atmosphere, AtmosphereParams};
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let sun = super::super::direction_from_az_el(270.0, -4.0);
        let guide = SkyGuide::new(&medium, sun);
        let plan = TechniquePlan::outside_a_scene(&IntegratorOptions {
            splitting: Some(true),
            ..IntegratorOptions::default()
        });
        let integrator = Integrator::new(&medium, &plan, sun).with_sky_guide(&guide);
        let lanes = SpectralLanes::new([450.0, 520.0, 590.0, 660.0], LANES, &medium, false);
        let x = DVec3::new(0.0, 0.0, medium.planet_radius_m + 20_000.0);
        let c = medium.coefficients(x.length(), &lanes);
        let here = integrator
            .importance(x)
            .expect("light reaches 20 km at twilight");
        let sigma = (0..LANES).map(|j| c.scattering(j)).fold(0.0, f64::max);
        let mut rng = Rng::new(1, 2);
        // Weights for a given expected light relative to a reference of 1.
        let beta_for = |expected: f64| [expected / (sigma * here); LANES];
        let start = |reference: f64| Window {
            reference,
            copies: 1,
        };
        let window = |beta: &mut Lanes, window: Window, rng: &mut Rng| {
            let (copies, window) = integrator
                .weight_window(x, &c, beta, (3, 1.0, window), &lanes, rng)
                .unwrap();
            (copies, window.reference, window.copies)
        };
        // Inside the window: one copy, nothing changes.
        let mut beta = beta_for(1.0);
        assert_eq!(window(&mut beta, start(1.0), &mut rng), (1, 1.0, 1));
        assert_eq!(beta, beta_for(1.0));
        // 3× the start's light: three copies, same reference.
        assert_eq!(
            window(&mut beta_for(3.0), start(1.0), &mut rng),
            (3, 1.0, 3)
        );
        // A start with next to no light: the cap holds, and the copies'
        // reference rises to their expected light.
        let (copies, reference, lineage) = window(&mut beta_for(1.0), start(1e-30), &mut rng);
        assert_eq!((copies, lineage), (MAX_SPLIT, MAX_SPLIT));
        let each = 1e30 / MAX_SPLIT as f64;
        assert!((reference / (each * 1e-30) - 1.0).abs() < 1e-9);
        let lifted = Window {
            reference,
            copies: lineage,
        };
        let (again, _, _) = window(&mut beta_for(1.0 / MAX_SPLIT as f64), lifted, &mut rng);
        assert!(again <= 1, "copies split again: {again}");
        // A path already one of MAX_COPIES / 2 copies of its start splits
        // into 2 at most, however bright; one of MAX_COPIES, not at all,
        // and its reference rises to its expected light.
        let many = |copies: usize| Window {
            reference: 1.0,
            copies,
        };
        let (copies, reference, lineage) =
            window(&mut beta_for(100.0), many(MAX_COPIES / 2), &mut rng);
        assert_eq!((copies, lineage), (2, MAX_COPIES));
        assert!((reference - 50.0).abs() < 1e-9);
        let (copies, reference, lineage) = window(&mut beta_for(100.0), many(MAX_COPIES), &mut rng);
        assert_eq!((copies, lineage), (1, MAX_COPIES));
        assert!((reference - 100.0).abs() < 1e-9);
        // A tenth of the start's light: survives 40 % of the time, with
        // its weight divided by 0.4.
        let trials = 20_000;
        let mut survived = 0;
        for _ in 0..trials {
            let mut beta = beta_for(0.1);
            let (copies, _, _) = window(&mut beta, start(1.0), &mut rng);
            if copies == 1 {
                survived += 1;
                assert!((beta[0] / beta_for(0.1)[0] - 2.5).abs() < 1e-9);
            }
        }
        let rate = f64::from(survived) / f64::from(trials);
        let sigma_rate = (0.4 * 0.6 / f64::from(trials)).sqrt();
        assert!((rate - 0.4).abs() < 5.0 * sigma_rate, "survival {rate}");
    }
}
