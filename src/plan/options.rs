//! The user's technique switches: the scene's `[render.integrator]` table.
//!
//! Every field is either a fixed default or `None`, "let the plan choose";
//! [`super::TechniquePlan::new`] makes every choice, by the regime table
//! ([`super::regime`]). Nothing else reads these unset.

/// Default `forced_collision_depth`: delta-tracked segments after one to
/// eight scatterings that would leave the atmosphere force their first
/// collision into it. By day a path leaving upward (majorant optical depth
/// ≈ 0.1 at midday, more in haze or the Martian dust) otherwise carries
/// the orders past the second in rare large estimates, and those orders
/// hold most of the sky's variance; forced, every path brings a small
/// share of them and roulette bounds their length. It pays most in thick
/// air (Mars at noon, a hazy day); below 3° the segments are estimated
/// through next-event points, not tracked, and it changes nothing there
/// (`BENCHMARKS.md`, forced collisions).
pub const FORCED_COLLISION_DEPTH: u32 = 8;

/// Switches for the variance-reduction techniques (each defaults to the
/// best; the benchmark's ablation turns them off one at a time). `None`
/// means the regime table's choice for the scene's sun
/// ([`super::regime::REGIMES`]).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IntegratorOptions {
    /// Wavelengths carried per path, 1–4.
    pub wavelengths_per_path: usize,
    /// Shell-wise (tight) majorants; `false` uses one majorant for the whole atmosphere.
    pub tight_majorants: bool,
    /// Transmittance estimator for shadow rays.
    pub shadow_transmittance: TransmittanceEstimator,
    /// Next-event estimation toward the sun.
    pub next_event_estimation: bool,
    /// Next-event points on each camera ray, drawn from the expected
    /// sunlight along it (tabulated per view direction; stratified), 0–8;
    /// 0 = delta tracking on camera rays too. Unset: [`super::CAMERA_SAMPLES`],
    /// or [`super::SPLAT_CAMERA_SAMPLES`] where the renderer splats along
    /// circles.
    pub camera_samples: Option<u32>,
    /// Paths the camera ray branches into at its segment (each from its own
    /// point, drawn from the skylight part of the density, or ground
    /// bounce, weighted 1/N), 1–16, with `camera_samples` > 0: the camera
    /// segment's cost is shared by several estimates of the multiply
    /// scattered light, which carries most of the variance. Unset: the
    /// regime table's (where light scattered again in the air is splatted
    /// along circles, a ray's branches all bounce off the ground it meets).
    pub camera_branches: Option<u32>,
    /// Share of the points camera paths branch from drawn ∝ σ_s T × the sky
    /// guide's mean once-scattered radiance at the point (the light a
    /// branch can expect to find there) instead of σ_s T, 0–1. Unset: the
    /// regime table's.
    pub camera_importance: Option<f64>,
    /// Next-event points per path segment drawn from the expected-sunlight
    /// density (stratified; the path goes on from a further point drawn
    /// from its skylight part), 0–8; 0 = delta tracking with a next-event
    /// estimate at every tentative collision. Unset: the regime table's.
    pub sunlight_samples: Option<u32>,
    /// Share of scattering directions drawn from the phase function about
    /// the sun's direction instead of the path's, 0–1. Unset: the regime
    /// table's, or [`super::regime::CONTROL_SUN_LOBE`] with the control
    /// variate on.
    pub sun_lobe: Option<f64>,
    /// Share of scattering directions drawn, at points in the planet's
    /// shadow, from the table of incoming once-scattered light there (the
    /// sky guide) instead of the phase functions, 0–1. Unset: the regime
    /// table's. By day no vertex lies in the shadow and nothing changes.
    pub sky_guide: Option<f64>,
    /// Whether `sky_guide` also guides directions at sunlit points (with
    /// the sun low, the glow over the sun's azimuth holds much of the light
    /// even a sunlit vertex sees). Unset: the regime table's.
    pub sky_guide_sunlit: Option<bool>,
    /// Share of the ground's bounce directions drawn from the sky guide's
    /// table at the ground point instead of the cosine density, 0–1 (a
    /// direction below the horizon ends the path: the cosine weights it
    /// zero). At low sun the sky's light on the ground comes mostly from
    /// a band of bright sky low over the sun's azimuth, where the cosine
    /// density is small. Unset: the regime table's.
    pub ground_guide: Option<f64>,
    /// Next-event points on each path segment that starts in the planet's
    /// shadow, drawn from the expected sunlight along it as the sky guide
    /// tabulates it (the path goes on from its first real scattering),
    /// 0–8; 0 (the default) = delta tracking there too: the pass over the
    /// whole, often grazing, ray costs more than the variance it saves.
    pub shadow_samples: u32,
    /// Delta-tracked path segments that start after 1 to this many
    /// scatterings and would leave the atmosphere force their first
    /// tentative collision into the segment (weighted by its probability),
    /// 0–64; 0 = off. Default [`FORCED_COLLISION_DEPTH`] (1: the
    /// branches of camera paths only).
    pub forced_collision_depth: u32,
    /// Russian roulette after the second scattering event.
    pub russian_roulette: bool,
    /// Adjoint-driven roulette and splitting (after Vorba and Křivánek
    /// 2016) at the real scatterings of paths whose segments are estimated
    /// through the guide's densities (`sunlight_samples` > 0), the guide's
    /// mean once-scattered radiance as the adjoint. Needs
    /// `russian_roulette`. Unset: the regime table's where roulette is on,
    /// else off.
    pub splitting: Option<bool>,
    /// The once-scattered light as a control variate: every real
    /// scattering adds the exact phase-function integral of a tabulated
    /// approximation A of the once-scattered light arriving there, and the
    /// path going on estimates only L − A. Unset: the regime table's,
    /// where the haze lets the table hold the light
    /// ([`super::control_table_holds`]). Set, it is honoured.
    pub control_variate: Option<bool>,
    /// What the control variate's approximation A is, where the control is
    /// on. Unset: [`ControlSource::OnceScattered`].
    pub control_source: Option<ControlSource>,
    /// Multiply scattered light splatted along the scene's circles of
    /// symmetry: the camera's own paths keep single scattering and the
    /// ground's light, and paths started anywhere in the visible air carry
    /// the rest to the pixels of 96 points on their start's circle about
    /// the sun's axis (up to 192 in finer images). Needs
    /// `camera_samples` > 0, `next_event_estimation` and the observer
    /// inside the atmosphere. Unset: the regime table's.
    pub circle_splatting: Option<bool>,
    /// The skylight the ground reflects splatted along the same circles:
    /// the camera's rays that meet the ground keep its direct sunlight, and
    /// bounces from points anywhere on the visible ground carry the rest to
    /// the pixels of half as many points on their circle: one bounce per
    /// path splatted in the air, or, without `circle_splatting`, bounces of
    /// their own. Needs what `circle_splatting` needs. Unset: on wherever
    /// the observer is inside the atmosphere and above the ground.
    pub ground_splatting: Option<bool>,
    /// Where the ground's skylight is splatted, each bounce less its twin:
    /// the same bounce (the same random numbers and wavelengths) from the
    /// observer's foot. The twin's mean, the foot's reflected skylight, is
    /// estimated once per pass by a pool of bounces of its own, and the
    /// camera's samples add it where their rays meet the ground
    /// ([`crate::render::ground_circles`]). The reflected skylight changes
    /// little over the ground seen from near it, so a bounce and its twin
    /// nearly cancel (most pairs are left out by Russian roulette), and
    /// the pool's noise, shared by every pixel, replaces the bounces'.
    /// Not with a spectral image (the pool's light is XYZ). Unset: on
    /// wherever the ground's skylight is splatted.
    pub ground_pool: Option<bool>,
    /// The approximate sky model's light on the ground as a control
    /// variate at every ground bounce: the bounce adds the exact cosine
    /// integral of the model's light on a grid of directions, and its path
    /// estimates only what the model misses
    /// ([`crate::render::ground_sky`]). Needs a ground that reflects; not
    /// with `control_source = "model"`, which controls the ground itself.
    /// Unset: on for an observer inside the atmosphere (from above it the
    /// ground's pixels hold mostly the air's light in front of them, and
    /// the look-ups cost more than they save) in haze the model holds
    /// ([`super::GROUND_CONTROL_MAX_AEROSOL_DEPTH`]).
    pub ground_control: Option<bool>,
    /// The splats' transmittance from the observer (`circle_splatting`,
    /// `ground_splatting`) read from a table of the observer's rays over
    /// their direction and length, a random share of them
    /// ([`crate::render::observer_depths::CORRECTED_SHARE`]) corrected by
    /// the unbiased estimate, which keeps the sum unbiased; `false`: every
    /// splat takes the unbiased estimate itself.
    pub splat_transmittance_table: bool,
    /// The shadow rays toward the sun read their transmittance from the
    /// table of columns toward it over altitude and solar zenith
    /// ([`crate::render::sun_columns`]), a random sixteenth of them
    /// corrected by the unbiased estimate, which keeps the sum unbiased
    /// ([`crate::render::debias`]); rays that descend from their point
    /// (toward a perigee, where the table can be many times off) take the
    /// unbiased estimate itself, as every ray does with `false` or with a
    /// `shadow_transmittance` or majorant other than the default (those are
    /// there to be compared).
    pub sun_transmittance_table: bool,
    /// How a pixel sample draws its first random numbers.
    pub sampler: Sampler,
    /// Keep only scattering orders up to this (for tests of single scattering;
    /// `None` = all orders, the unbiased default).
    pub max_scattering_order: Option<u32>,
}

impl Default for IntegratorOptions {
    fn default() -> Self {
        Self {
            wavelengths_per_path: crate::spectrum::LANES,
            tight_majorants: true,
            shadow_transmittance: TransmittanceEstimator::ResidualRatioTracking,
            next_event_estimation: true,
            camera_samples: None,
            camera_branches: None,
            camera_importance: None,
            sunlight_samples: None,
            sun_lobe: None,
            sky_guide: None,
            sky_guide_sunlit: None,
            ground_guide: None,
            shadow_samples: 0,
            forced_collision_depth: FORCED_COLLISION_DEPTH,
            russian_roulette: true,
            splitting: None,
            control_variate: None,
            control_source: None,
            circle_splatting: None,
            ground_splatting: None,
            ground_pool: None,
            ground_control: None,
            splat_transmittance_table: true,
            sun_transmittance_table: true,
            sampler: Sampler::Sobol,
            max_scattering_order: None,
        }
    }
}

/// The control variate's approximation of the light arriving at a
/// scattering point.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ControlSource {
    /// The once-scattered light (and the ground's direct reflection),
    /// projected from the render's own estimates with paths cut after one
    /// scattering.
    #[default]
    OnceScattered,
    /// The approximate sky model's light of every order and its lit
    /// ground ([`crate::render::sky_model::ModelField`]): the paths
    /// estimate only what the model misses; the ground's bounces are
    /// controlled too.
    Model,
}

/// How a pixel sample draws its random numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Sampler {
    /// The first 32 uniforms of each pass from an Owen-scrambled Sobol
    /// point, per pixel: the pixel position, the camera ray's scattering
    /// points and the first scattering directions are stratified across
    /// passes; the points splatted along circles take a pass's Sobol
    /// points in turn.
    #[default]
    Sobol,
    /// Every uniform independent (PCG).
    Independent,
}

/// Estimators of transmittance along shadow rays.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum TransmittanceEstimator {
    /// Residual ratio tracking (Novák et al. 2014) with a table of columns
    /// as control, on shadow rays and segments alike; where the table's
    /// residual bound expects more than two events (grazing rays low down),
    /// each shell's chord of the extinction.
    #[default]
    ResidualRatioTracking,
    /// Residual ratio tracking with the shells' chords as control everywhere
    /// (a walk through every shell the ray crosses).
    ChordResidualRatioTracking,
    /// Ratio tracking (Cramer 1978; Novák et al. 2014).
    RatioTracking,
    /// Delta tracking: a binary estimate (Woodcock et al. 1965).
    DeltaTracking,
}
