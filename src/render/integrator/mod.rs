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
//! **One path loop** (`path`): every path — a camera branch, a splatted
//! walk, a control cell's projection — alternates a segment estimate, the
//! plan's choice among the estimators below, and one vertex step where
//! the new direction, roulette or splitting (`termination`) and the
//! control variate are applied.
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
//! ends paths without bias. On the delta-tracked segments of the first
//! scatterings (the camera's branches and their next few segments) the
//! first tentative collision is forced into the segment where the ray
//! would otherwise leave the atmosphere
//! ([`crate::plan::IntegratorOptions::forced_collision_depth`]):
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
//! too (`sky_guide_sunlit`). Half the ground's bounces follow the table
//! at every sun elevation (`ground_guide`, `Integrator::bounce_direction`):
//! the sky's light on the ground comes from low toward the sun, where the
//! cosine density is smallest.
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
//! out, it leaves less variance (`BENCHMARKS.md`).
//!
//! **The sky model's light on the ground as a control variate**
//! (`ground_control`, at every sun elevation): a ground bounce adds the
//! exact cosine integral of the approximate model's light arriving there,
//! tabulated on a grid of directions ([`super::ground_sky`]), and its path
//! estimates only L − L̃. By day half a bounce's variance comes from the
//! choice of its direction, which the model's light follows closely.
//!
//! **Multiply scattered light splatted along circles of symmetry**
//! (`circle_splatting`, with the sun low): the camera's
//! paths keep only their next-event points (more per ray than without:
//! single scattering's variance is per point) and ground branches, and the
//! film gets the light scattered again in the air from paths started
//! anywhere in the visible air, each added to the pixels along its point's
//! circle about the sun's axis ([`super::circles`],
//! `Integrator::splat_walk`). With `ground_splatting` (on wherever
//! the observer is in the air, by day without the air's splats) the
//! camera rays that meet the ground keep only its
//! direct sunlight: the skylight it reflects comes from bounces at points
//! anywhere on the visible ground, each added to the pixels along its
//! point's circle ([`super::ground_circles`], `Integrator::ground_light`).
//!
//! **Shadow rays toward the sun** (`sun_transmittance_table`) that climb
//! from their point read T̃ from the table of columns toward the sun over
//! altitude and solar zenith ([`super::sun_columns`]); a random sixteenth
//! of them add the tracked estimate's difference from it, times 16, which
//! keeps every one unbiased ([`super::debias`]). The tracking had been
//! the largest part of a next-event estimate's cost. Rays that descend
//! toward a perigee, where the table can be far off, are tracked.
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

mod camera_ray;
mod control_variate;
mod ground;
mod path;
mod scatter_directions;
mod segments;
mod sun_disc;
mod termination;

use std::f64::consts::PI;

use glam::DVec3;

use super::columns::FixedStart;
use super::control::{Frame, Picked, RadianceTable, L_MAX};
use super::directions::orthonormal_basis;
use super::ground_sky::{GroundSky, GroundSkyAt};
use super::guide::{GuideAt, SkyGuide};
use super::medium::Span;
use super::medium::{Bounds, Lanes, Medium, SpectralLanes, LANES};
use super::sunlight::{CachedRayDensity, CameraDensities, Component, InScatterDistribution};
use super::trig::sin_cos_turns;
use crate::physics::aerosol::MomentsOverWavelength;
use crate::physics::{rayleigh, sun};
use crate::plan::{TechniquePlan, MAX_BRANCHES, MAX_SUNLIGHT_SAMPLES};
use crate::rng::Rng;

/// σ_s,R P_R + σ_s,A P_A of lane `j` at cosine `mu`, given the aerosol's
/// phase function there at the lane's wavelength.
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

/// σ_s p(μ) per lane at one point, for many cosines μ
/// ([`Integrator::scattering_phases_at`]): the Rayleigh part as n (a + b μ²)
/// per lane ([`rayleigh::phase_terms`]) times σ_s,R, the aerosol's
/// phase function once per μ (per lane only where it varies with the
/// wavelength) times σ_s,A; inactive lanes 0.
pub(crate) struct ScatteringPhases<'a> {
    rayleigh: Lanes,
    norm: Lanes,
    constant: Lanes,
    square: Lanes,
    aerosol: Lanes,
    medium: &'a super::medium::Medium,
    lanes: &'a SpectralLanes,
}

impl ScatteringPhases<'_> {
    /// σ_s p(μ) of each lane at cosine `mu` (the same operations as
    /// [`Integrator::scattering_phases`], so the same bits).
    #[inline]
    pub(crate) fn at(&self, mu: f64) -> Lanes {
        let aerosol = self.medium.aerosol_phases(mu, self.lanes);
        Lanes::from_fn(|j| {
            self.rayleigh[j] * (self.norm[j] * (self.constant[j] + self.square[j] * mu * mu))
                + self.aerosol[j] * aerosol[j]
        })
    }
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

/// Where a path starts: position, direction, scatterings so far, and the
/// scale of its weight for roulette (see `termination::survives_roulette`).
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
    /// The medium the paths travel through.
    pub medium: &'a Medium,
    /// The techniques to use.
    pub plan: &'a TechniquePlan,
    /// Unit vector toward the sun's centre.
    pub sun_direction: DVec3,
    cos_sun_radius: f64,
    sun_solid_angle_sr: f64,
    sun_frame: (DVec3, DVec3),
    bounds: Bounds,
    camera: Option<&'a CameraDensities>,
    guide: Option<&'a SkyGuide>,
    control: Option<&'a RadianceTable>,
    /// The model's skylight on the ground, for the ground's control.
    ground_sky: Option<&'a GroundSky>,
    /// Camera rays branch only from the ground: the light scattered more
    /// than once in the air reaches the film through [`super::circles`].
    splatting: bool,
    /// Camera rays do not bounce off the ground they meet: the skylight it
    /// reflects reaches the film through [`super::ground_circles`].
    ground_splatting: bool,
    /// The aerosol phase function's Legendre moments k_0..k_L.
    aerosol_moments: MomentsOverWavelength<{ L_MAX + 1 }>,
    /// The Lambertian kernel's Legendre moments.
    lambert: [f64; L_MAX + 1],
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
        let a = Lanes::from(self.picked.evaluate(&self.frame.basis(dir)));
        *radiance -= *beta * lanes.sun_irradiance * a;
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

    /// The medium's part of [`Self::shares`], medium / (medium + ground):
    /// how a path that may go on from either chooses. `None` where neither
    /// share is known (0/0), which no probability can be drawn from.
    fn air_share(&self, ground_albedo: f64) -> Option<f64> {
        let (medium, ground) = self.shares(ground_albedo);
        Some(medium / (medium + ground)).filter(|s| !s.is_nan())
    }
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
    /// An integrator of `plan` in `medium` for the sun along `sun_direction`
    /// (building the medium's columns toward the sun if the plan reads its
    /// shadow rays from them).
    pub fn new(medium: &'a Medium, plan: &'a TechniquePlan, sun_direction: DVec3) -> Self {
        if plan.sun_transmittance_table {
            // Built now, before any pass: a parallel build on first use
            // inside a pass's workers could deadlock on the medium's lock.
            medium.sun_columns();
        }
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
            ground_sky: None,
            splatting: false,
            ground_splatting: false,
            aerosol_moments: MomentsOverWavelength::new(&medium.aerosol_phase),
            lambert: super::control::lambert_moments(),
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

    /// Whether single estimates may be negative (with a control variate
    /// on, the air's or the ground's, or shadow rays toward the sun read
    /// from its table and corrected, [`super::debias`]: their means are
    /// not); otherwise a negative one is a defect.
    pub fn signed_estimates(&self) -> bool {
        self.control.is_some() || self.ground_sky.is_some() || self.plan.sun_transmittance_table
    }

    /// With `air`, camera rays no longer branch from the air (only from
    /// the ground): the film gets that light from [`super::circles`]
    /// instead; with `ground` (where the renderer splats the ground's
    /// skylight, [`TechniquePlan::ground_splatting`]), nor from the
    /// ground, whose reflected skylight then comes from
    /// [`super::ground_circles`].
    #[must_use]
    pub(crate) fn with_splatting(mut self, air: bool, ground: bool) -> Self {
        self.splatting = air;
        self.ground_splatting = ground;
        self
    }

    /// Uses `guide` for scattering directions (see
    /// [`crate::plan::IntegratorOptions::sky_guide`]), for the distance
    /// densities of segments at low sun (`Self::sunlit_segment`) and for
    /// roulette and splitting by importance.
    #[must_use]
    pub fn with_sky_guide(mut self, guide: &'a SkyGuide) -> Self {
        self.guide = Some(guide);
        self
    }

    /// Uses `sky` as the control variate of ground bounces (see
    /// [`crate::plan::IntegratorOptions::ground_control`]).
    #[must_use]
    pub fn with_ground_sky(mut self, sky: &'a GroundSky) -> Self {
        self.ground_sky = Some(sky);
        self
    }

    /// Uses `camera` for rays that start at its observer (see
    /// [`crate::plan::IntegratorOptions::camera_samples`]).
    #[must_use]
    pub fn with_camera_densities(mut self, camera: &'a CameraDensities) -> Self {
        self.camera = Some(camera);
        self
    }

    /// Phase function of lane `j` times σ_s (i.e. σ_s,R P_R + σ_s,A P_A), per sr.
    pub(crate) fn scattering_phase(
        &self,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        j: usize,
        mu: f64,
    ) -> f64 {
        let aerosol = self.medium.aerosol_phase.eval(mu, lanes.wavelengths_nm[j]);
        lane_scattering_phase(c, lanes, j, mu, aerosol)
    }

    /// [`Self::scattering_phase`] of every lane (the aerosol's phase
    /// function by [`Medium::aerosol_phases`]); inactive lanes 0.
    pub(crate) fn scattering_phases(
        &self,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        mu: f64,
    ) -> Lanes {
        self.scattering_phases_at(c, lanes).at(mu)
    }

    /// [`Self::scattering_phases`] at one point's coefficients `c`, for
    /// many cosines: the per-lane factors found once.
    pub(crate) fn scattering_phases_at<'b>(
        &'b self,
        c: &super::medium::Coefficients,
        lanes: &'b SpectralLanes,
    ) -> ScatteringPhases<'b> {
        let mut phases = ScatteringPhases {
            rayleigh: Lanes::splat(0.0),
            norm: Lanes::splat(0.0),
            constant: Lanes::splat(0.0),
            square: Lanes::splat(0.0),
            aerosol: Lanes::splat(0.0),
            medium: self.medium,
            lanes,
        };
        for j in 0..lanes.active {
            let (norm, constant, square) = rayleigh::phase_terms(lanes.rayleigh_gamma[j]);
            phases.rayleigh[j] = c.rayleigh[j];
            phases.norm[j] = norm;
            phases.constant[j] = constant;
            phases.square[j] = square;
            phases.aerosol[j] = c.aerosol_scattering[j];
        }
        phases
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

    /// The light arriving at `x` from direction `-dir`, estimated by a
    /// path that starts at `x` after one scattering (so the sun's disc
    /// itself is never added: a table's or a splat's view of the light a
    /// scattering point sees).
    pub(crate) fn scattered_light(
        &self,
        x: DVec3,
        dir: DVec3,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Radiance {
        let mut radiance = Light::default();
        self.trace(
            (x, dir, 1, 1.0),
            Lanes::splat(1.0),
            lanes,
            &mut radiance,
            rng,
        );
        radiance.total
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
                    self.trace(from, beta, lanes, &mut radiance, rng);
                }
            }
            _ => self.trace(
                (origin, dir, 0, 1.0),
                Lanes::splat(1.0),
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
    /// direction: the walk serves camera rays along all of them and the
    /// directions between.
    ///
    /// `select`, uniform over [0, 1), picks the mixture's part (the guide's
    /// share first, then the sun lobe's, then each camera direction's) and
    /// is used up by the pick, so that a caller drawing several directions
    /// can stratify it: u ↦ direction maps the uniform density to the
    /// mixture's whatever `select`'s range, so the mean over strata of
    /// f/p is unbiased and the parts' shares no longer vary between walks.
    ///
    /// Returns the direction, its density (sr⁻¹) and the radiance estimate,
    /// or `None` for an empty `camera_dirs`.
    pub(crate) fn splat_walk(
        &self,
        x: DVec3,
        camera_dirs: &[DVec3],
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        select: f64,
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
        // `select` over [0, g) picks the guide; the rest, rescaled to
        // [0, 1), the sun lobe below α and the camera directions' lobes in
        // equal shares above it.
        let dir = match at.as_ref() {
            Some(guide) if select < g => guide.sample(rng).0,
            _ => {
                let u = (select - g) / (1.0 - g);
                if u < alpha {
                    self.sample_phase_direction(self.sun_direction, c, lanes, rng)
                } else {
                    let n = camera_dirs.len();
                    let v = (u - alpha) / (1.0 - alpha);
                    let k = ((v * n as f64) as usize).min(n - 1);
                    self.sample_phase_direction(camera_dirs[k], c, lanes, rng)
                }
            }
        };
        let lobes = camera_dirs
            .iter()
            .map(|d| self.phase_mixture_pdf(c, lanes, d.dot(dir)))
            .sum::<f64>()
            / camera_dirs.len() as f64;
        let pdf = self.direction_mixture_pdf(c, lanes, dir, lobes, at.as_ref().filter(|_| guides));
        Some((dir, pdf, self.scattered_light(x, dir, lanes, rng)))
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
        let mut points = [(t_m.clamp(span.t_enter, span.t_exit), Lanes::splat(0.0))];
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
        *beta *= Lanes::from_fn(|j| self.scattering_phase(c, lanes, j, mu) / pdf);
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
            let seen = *beta * self.sun_radiance(dir, lanes);
            radiance.total += seen;
            if depth == 0 {
                radiance.disc += seen;
            }
        }
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
}

/// A path segment: from `origin` along `dir` over `span`, after `depth`
/// scatterings.
struct Segment {
    origin: DVec3,
    dir: DVec3,
    span: Span,
    depth: u32,
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
        *beta /= majorant * p_scatter;
        return true;
    }
    *beta *= Lanes::from_fn(|j| (majorant - c.extinction(j)) / (majorant * (1.0 - p_scatter)));
    false
}

/// The ground vertex under unit `normal`, just above the surface.
fn ground_point(medium: &Medium, normal: DVec3) -> DVec3 {
    normal * (medium.planet_radius_m + SURFACE_OFFSET_M)
}

/// Cosine-weighted direction about `normal` (Malley's method).
pub(crate) fn cosine_sample_hemisphere(normal: DVec3, rng: &mut Rng) -> DVec3 {
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
}
