//! The technique plan: the one place where a scene's conditions (the sun's
//! elevation, where the observer stands, the haze) and the user's switches
//! ([`IntegratorOptions`]) become a fully resolved choice of estimators.
//!
//! ```text
//! IntegratorOptions (user, Option = "choose") ─┐
//! Conditions (sun elevation, observer, haze) ──┴─► TechniquePlan ─► integrator
//!                                                       └─► first_pass() (the draft)
//! ```
//!
//! The plan has no unset field: the integrator, the renderer and the table
//! builders read its sub-plans as they are. The regime table
//! ([`regime::REGIMES`]) holds every default that depends on the sun; the
//! README shows the same table (a test keeps them equal).

pub mod options;
pub mod regime;

pub use options::{
    ControlSource, IntegratorOptions, Sampler, TransmittanceEstimator, FORCED_COLLISION_DEPTH,
};
pub use regime::{Regime, RegimeDefaults, REGIMES};

use crate::atmosphere::AtmosphereParams;

/// Next-event points per camera ray where the renderer does not splat the
/// air's light:
/// against 1, less variance at midday for little more time.
pub const CAMERA_SAMPLES: u32 = 2;

/// Next-event points per camera ray where the renderer splats along
/// circles: the camera's paths then carry single scattering (and the
/// ground's light) only, whose variance is per point, while the points cost
/// little beside the splats.
pub const SPLAT_CAMERA_SAMPLES: u32 = 8;

/// Most next-event points on one segment or camera ray (`camera_samples`,
/// `sunlight_samples`, `shadow_samples`).
pub const MAX_SUNLIGHT_SAMPLES: usize = 8;

/// Most branches of a camera path (`camera_branches`).
pub const MAX_BRANCHES: usize = 16;

/// Largest `forced_collision_depth` accepted: the depth past which the
/// integrator's roulette caps survival at 0.9, so paths end with
/// probability one.
pub const MAX_FORCED_COLLISION_DEPTH: u32 = 64;

/// Largest vertical aerosol optical depth at 550 nm with the control
/// variate on by default. The table holds the once-scattered light at 12
/// altitudes and 8 wavelengths and a point takes a neighbour's; half the
/// aerosol column lies between the two lowest altitudes, so in thick haze
/// the light it holds changes by orders of magnitude from one cell to the
/// next, and deep in it the light is mostly scattered many times, which the
/// table does not hold: beyond this depth the control adds noise (the
/// decisions table of `BENCHMARKS.md`).
pub const CONTROL_MAX_AEROSOL_DEPTH: f64 = 4.0;

/// Largest vertical aerosol optical depth at 550 nm with the ground's
/// control on by default ([`IntegratorOptions::ground_control`]). The sky
/// model follows the light order by order up to the fifth and sums the rest
/// as a tail; in haze this deep most of the light is of higher orders, and
/// where the model misses it the control's own spread swamps the image (at
/// 25, four 2-pass renders of a 16×8 sunset averaged a negative luminance;
/// the estimate stays unbiased either way).
pub const GROUND_CONTROL_MAX_AEROSOL_DEPTH: f64 = 4.0;

/// Aerosol asymmetry parameters g (from, to) with the control variate on by
/// default where there are aerosols. The expansion stops at degree
/// [`crate::render::control::L_MAX`] = 8, and a Henyey–Greenstein aureole
/// keeps Σ_{l>8} (2l+1) g^{2l} of its squared norm beyond it: 1.2 % at
/// g = 0.7, 9 % at 0.8, 43 % at 0.9. The expansion then rings about the sun
/// and misses the peak, which the paths must find without the sun lobe.
pub const CONTROL_AEROSOL_G: (f64, f64) = (-0.5, 0.8);

/// Whether the control variate's table holds the once-scattered light well
/// enough in `atmosphere`'s haze to pay for itself: an aerosol column no
/// deeper than [`CONTROL_MAX_AEROSOL_DEPTH`] at 550 nm, and g within
/// [`CONTROL_AEROSOL_G`] (or no aerosols). Either way the estimate stays
/// unbiased (the phase function's Legendre moments are exact): only the
/// noise is at stake.
pub fn control_table_holds(atmosphere: &AtmosphereParams) -> bool {
    let depth = atmosphere.aerosol_optical_depth(550.0);
    depth == 0.0
        || (depth <= CONTROL_MAX_AEROSOL_DEPTH
            && (CONTROL_AEROSOL_G.0..=CONTROL_AEROSOL_G.1).contains(&control_aerosol_g(atmosphere)))
}

/// The g that [`control_table_holds`] compares with [`CONTROL_AEROSOL_G`]:
/// Henyey–Greenstein's and Cornette–Shanks' parameter, the other phase
/// functions' mean cosine (the forward peak whose share beyond the
/// expansion's degree is at stake; NaN where the phase function cannot be
/// built); for a phase function over wavelength the largest of its
/// tabulated wavelengths' (the sharpest peak the expansion must hold: the
/// Martian dust's is 0.84 at 360 nm, 0.73 at 650 nm).
pub fn control_aerosol_g(atmosphere: &AtmosphereParams) -> f64 {
    use crate::physics::aerosol::PhaseFunction;
    match atmosphere.aerosol_phase_function() {
        Ok(PhaseFunction::HenyeyGreenstein { g } | PhaseFunction::CornetteShanks { g }) => g,
        Ok(phase) if phase.is_spectral() => phase
            .node_wavelengths_nm()
            .iter()
            .map(|&w| phase.legendre_moments::<2>(w)[1])
            .fold(f64::NEG_INFINITY, f64::max),
        Ok(phase) => phase.mean_cosine(),
        Err(_) => f64::NAN,
    }
}

/// What the plan needs to know of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Conditions {
    /// The sun's elevation above the observer's horizon, degrees.
    pub sun_elevation_deg: f64,
    /// Whether the haze lets the control variate's table hold the light
    /// ([`control_table_holds`]).
    pub haze_fits_control: bool,
    /// Whether multiply scattered light can be splatted along circles: the
    /// observer inside the atmosphere and the sun off the zenith and nadir.
    pub circles: bool,
    /// Whether the observer is low in the air: where the air is at least
    /// [`LOW_OBSERVER_DENSITY`] times as dense as at the ground. By day the
    /// regime table splats only there ([`regime::Splatting::Low`]).
    pub observer_low: bool,
    /// Whether the observer is inside the atmosphere (below its top).
    pub observer_in_air: bool,
    /// Whether the haze is thin enough for the sky model to stand in for
    /// the ground's light ([`GROUND_CONTROL_MAX_AEROSOL_DEPTH`]).
    pub haze_fits_model: bool,
    /// Whether the render keeps a spectral image, whose lanes need each
    /// ground bounce's own estimate (no `ground_pool`: its light is XYZ).
    pub spectral_image: bool,
}

/// The air's density at the observer, over the ground's, above which the
/// observer is low in the air ([`Conditions::observer_low`]): by day the
/// splats paid from 2 m and from 2 km (0.8 of the ground's density) and
/// lost from 10 km (0.34; `BENCHMARKS.md`, circle splatting); a half lies
/// between, about 6.7 km up on Earth, and was not measured itself.
pub const LOW_OBSERVER_DENSITY: f64 = 0.5;

impl Conditions {
    /// Conditions of a scene whose sun stands `sun_elevation_deg` up in
    /// `atmosphere`; `circles` as [`Self::circles`]; an observer low in
    /// the air (see [`Self::with_observer_density`]).
    pub fn new(sun_elevation_deg: f64, atmosphere: &AtmosphereParams, circles: bool) -> Self {
        Self {
            sun_elevation_deg,
            haze_fits_control: control_table_holds(atmosphere),
            circles,
            observer_low: true,
            observer_in_air: true,
            haze_fits_model: atmosphere.aerosol_optical_depth(550.0)
                <= GROUND_CONTROL_MAX_AEROSOL_DEPTH,
            spectral_image: false,
        }
    }

    /// The same conditions for a render that keeps a spectral image or not.
    #[must_use]
    pub fn with_spectral_image(self, spectral_image: bool) -> Self {
        Self {
            spectral_image,
            ..self
        }
    }

    /// The same conditions for an observer inside the atmosphere or not.
    #[must_use]
    pub fn with_observer_in_air(self, in_air: bool) -> Self {
        Self {
            observer_in_air: in_air,
            ..self
        }
    }

    /// The same conditions for an observer where the air is
    /// `density_over_ground` times as dense as at the ground.
    #[must_use]
    pub fn with_observer_density(self, density_over_ground: f64) -> Self {
        Self {
            observer_low: density_over_ground >= LOW_OBSERVER_DENSITY,
            ..self
        }
    }

    /// A day sky (the [`Regime::Day`] row) without circles to splat along:
    /// the plan of an integrator built outside a scene, such as in tests
    /// of single estimators, where every technique that depends on the
    /// sun's height is off unless set (the ground guide, on at every
    /// height, is on).
    pub const DAY: Self = Self {
        sun_elevation_deg: 20.0,
        haze_fits_control: true,
        circles: false,
        observer_low: true,
        observer_in_air: true,
        haze_fits_model: true,
        spectral_image: false,
    };
}

/// How camera rays are estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPlan {
    /// Next-event points per camera ray from its tabulated expected
    /// sunlight; 0 = delta tracking.
    pub samples: u32,
    /// Continuations of each camera path (1–8).
    pub branches: u32,
    /// Share of branch points drawn by the sky guide's skylight (0 where
    /// camera rays are delta-tracked).
    pub importance: f64,
}

/// How path segments are estimated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SegmentPlan {
    /// Shell-wise majorants (else one for the whole atmosphere).
    pub tight_majorants: bool,
    /// The transmittance estimator of shadow rays.
    pub shadow_transmittance: TransmittanceEstimator,
    /// Next-event estimation toward the sun.
    pub next_event_estimation: bool,
    /// Next-event points per segment from its expected sunlight; 0 = delta
    /// tracking.
    pub sunlight_samples: u32,
    /// Such points on segments that start in the planet's shadow.
    pub shadow_samples: u32,
    /// Segments after 1 to this many scatterings force their first
    /// collision into the air; 0 = off.
    pub forced_collision_depth: u32,
}

/// The estimator of one path segment ([`SegmentPlan::estimator`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SegmentEstimator {
    /// Delta tracking over the majorants, with a next-event estimate at
    /// every tentative collision where next-event estimation is on.
    DeltaTracking,
    /// `sunlight_samples` next-event points drawn from the segment's
    /// expected sunlight (the sky guide's cached density where the render
    /// has one), the path going on from one of them or the ground.
    SunlightPoints,
    /// `shadow_samples` next-event points from the sky guide's cached
    /// density, the path going on from its first delta-tracked real
    /// scattering.
    ShadowPoints,
}

impl SegmentPlan {
    /// The estimator of a segment after `depth` scatterings whose start
    /// lies in the planet's shadow (`in_shadow`) or not, where the render
    /// has a sky guide (`guide`). Points from the expected sunlight need
    /// next-event estimation (they are its points).
    pub fn estimator(&self, depth: u32, in_shadow: bool, guide: bool) -> SegmentEstimator {
        if !self.next_event_estimation {
            SegmentEstimator::DeltaTracking
        } else if self.sunlight_samples > 0 {
            SegmentEstimator::SunlightPoints
        } else if self.shadow_samples > 0 && depth > 0 && in_shadow && guide {
            SegmentEstimator::ShadowPoints
        } else {
            SegmentEstimator::DeltaTracking
        }
    }
}

/// How scattering directions are drawn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionPlan {
    /// Share from the phase function about the sun's direction.
    pub sun_lobe: f64,
    /// Share from the sky guide's table at shadowed points.
    pub sky_guide: f64,
    /// The guide at sunlit points too.
    pub sky_guide_sunlit: bool,
    /// Share of the ground's bounce directions from the guide's table.
    pub ground_guide: f64,
}

/// How paths end.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TerminationPlan {
    /// Russian roulette after the second scattering.
    pub russian_roulette: bool,
    /// Roulette and splitting by the guide's skylight (needs roulette).
    pub splitting: bool,
    /// Scattering orders kept; `u32::MAX` = all (the unbiased default).
    pub max_scattering_order: u32,
}

/// A fully resolved choice of techniques for one scene: no unset field.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TechniquePlan {
    /// The sun's regime, whose row supplied the unset choices.
    pub regime: Regime,
    /// Wavelengths per path (1–[`crate::spectrum::LANES`]).
    pub wavelengths_per_path: usize,
    /// Camera rays.
    pub camera: CameraPlan,
    /// Path segments.
    pub segments: SegmentPlan,
    /// Scattering directions.
    pub directions: DirectionPlan,
    /// Roulette, splitting and the orders kept.
    pub termination: TerminationPlan,
    /// The once-scattered light as a control variate (never with a limit
    /// on the orders, which it would mix).
    pub control_variate: bool,
    /// The control variate's approximation, where it is on.
    pub control_source: ControlSource,
    /// Multiply scattered light splatted along circles.
    pub circle_splatting: bool,
    /// The skylight the ground reflects splatted along circles: with
    /// `circle_splatting` one bounce per path splatted in the air, without
    /// it bounces of their own (`render::splatting`).
    pub ground_splatting: bool,
    /// Each splatted ground bounce less its twin at the observer's foot,
    /// the camera's samples adding the twin's mean from a pool of bounces
    /// per pass (only with `ground_splatting`, never with a spectral
    /// image).
    pub ground_pool: bool,
    /// The model's skylight as a control variate at ground bounces (never
    /// with a limit on the orders, which it would mix, nor with the
    /// model's own cells as the control, which hold the ground's).
    pub ground_control: bool,
    /// The splats' transmittance from the observer by its table, a random
    /// share corrected ([`crate::render::observer_depths`]).
    pub splat_transmittance_table: bool,
    /// The sun's shadow rays by its column table, a random share corrected
    /// ([`crate::render::debias`]).
    pub sun_transmittance_table: bool,
    /// How pixel samples draw their first random numbers.
    pub sampler: Sampler,
    /// The first pass's weight in the film's average (1 for later ones).
    pub draft_weight: f64,
}

impl TechniquePlan {
    /// The plan for `options` under `conditions`: every unset switch from
    /// the regime table's row for the sun, then the gates between
    /// techniques (splitting needs roulette; splatting needs camera-ray
    /// densities, next-event estimation and circles; the sun lobe yields to
    /// the control variate).
    pub fn new(options: &IntegratorOptions, conditions: &Conditions) -> Self {
        let regime = Regime::at(conditions.sun_elevation_deg);
        let row = regime.defaults();
        let control_variate = options
            .control_variate
            .unwrap_or(row.control_variate && conditions.haze_fits_control);
        let camera_samples_asked = options.camera_samples.unwrap_or(CAMERA_SAMPLES);
        // What the splats need: camera paths that estimate their own share
        // by next-event points, and circles.
        let can_splat =
            camera_samples_asked > 0 && options.next_event_estimation && conditions.circles;
        let circle_splatting = options
            .circle_splatting
            .unwrap_or(row.circle_splatting.applies(conditions.observer_low))
            && can_splat;
        let ground_splatting = can_splat && options.ground_splatting.unwrap_or(true);
        let camera_samples = options.camera_samples.unwrap_or(if circle_splatting {
            SPLAT_CAMERA_SAMPLES
        } else {
            CAMERA_SAMPLES
        });
        let importance = options.camera_importance.unwrap_or(row.camera_importance);
        Self {
            regime,
            wavelengths_per_path: options.wavelengths_per_path,
            camera: CameraPlan {
                samples: camera_samples,
                branches: options.camera_branches.unwrap_or(row.camera_branches),
                importance: if camera_samples > 0 { importance } else { 0.0 },
            },
            segments: SegmentPlan {
                tight_majorants: options.tight_majorants,
                shadow_transmittance: options.shadow_transmittance,
                next_event_estimation: options.next_event_estimation,
                sunlight_samples: options.sunlight_samples.unwrap_or(row.sunlight_samples),
                shadow_samples: options.shadow_samples,
                forced_collision_depth: options.forced_collision_depth,
            },
            directions: DirectionPlan {
                sun_lobe: options.sun_lobe.unwrap_or(if control_variate {
                    regime::CONTROL_SUN_LOBE
                } else {
                    row.sun_lobe
                }),
                sky_guide: options.sky_guide.unwrap_or(row.sky_guide),
                sky_guide_sunlit: options.sky_guide_sunlit.unwrap_or(row.sky_guide_sunlit),
                ground_guide: options.ground_guide.unwrap_or(row.ground_guide),
            },
            termination: TerminationPlan {
                russian_roulette: options.russian_roulette,
                // Splitting needs roulette (the scene refuses one without
                // the other); unset, it follows it.
                splitting: options
                    .splitting
                    .unwrap_or(options.russian_roulette && row.splitting),
                max_scattering_order: options.max_scattering_order.unwrap_or(u32::MAX),
            },
            control_variate: control_variate && options.max_scattering_order.is_none(),
            control_source: options.control_source.unwrap_or_default(),
            circle_splatting,
            ground_splatting,
            ground_pool: ground_splatting
                && options.ground_pool.unwrap_or(true)
                && !conditions.spectral_image,
            ground_control: options
                .ground_control
                .unwrap_or(conditions.observer_in_air && conditions.haze_fits_model)
                && options.max_scattering_order.is_none()
                && !(control_variate && options.control_source == Some(ControlSource::Model)),
            splat_transmittance_table: options.splat_transmittance_table,
            // The other shadow estimators are there to be compared: they
            // take every ray themselves.
            sun_transmittance_table: options.sun_transmittance_table
                && options.tight_majorants
                && options.shadow_transmittance == TransmittanceEstimator::ResidualRatioTracking,
            sampler: options.sampler,
            draft_weight: row.draft_weight,
        }
    }

    /// The plan for `options` outside a scene ([`Conditions::DAY`]).
    pub fn outside_a_scene(options: &IntegratorOptions) -> Self {
        Self::new(options, &Conditions::DAY)
    }

    /// Whether a pass splats anything along circles (the air's light or
    /// the ground's), and the film keeps a splat layer.
    pub fn splats(&self) -> bool {
        self.circle_splatting || self.ground_splatting
    }

    /// The first (draft) pass's plan: plain delta-tracked camera paths and
    /// segments, no control variate, no guided directions, no splitting, independent
    /// random numbers (the Sobol prefix costs ~4 % of a path and one pass
    /// gains nothing from stratification across passes), and shadow rays
    /// through the shells' chords, not the tables (the column table takes
    /// ~20 ms to build: not in the first frame). Every pass is an unbiased
    /// estimate, so the film's weighted average of them stays unbiased.
    #[must_use]
    pub fn first_pass(&self) -> Self {
        Self {
            camera: CameraPlan {
                samples: 0,
                ..self.camera
            },
            segments: SegmentPlan {
                sunlight_samples: 0,
                shadow_samples: 0,
                shadow_transmittance: match self.segments.shadow_transmittance {
                    TransmittanceEstimator::ResidualRatioTracking => {
                        TransmittanceEstimator::ChordResidualRatioTracking
                    }
                    other => other,
                },
                ..self.segments
            },
            directions: DirectionPlan {
                sky_guide: 0.0,
                ..self.directions
            },
            // Splitting pays for its bookkeeping where the segments find
            // the sunlit air; the draft's delta-tracked paths go without.
            termination: TerminationPlan {
                splitting: false,
                ..self.termination
            },
            control_variate: false,
            ground_control: false,
            sun_transmittance_table: false,
            sampler: Sampler::Independent,
            ..*self
        }
    }

    /// The plan that fills the control variate's table: this plan's
    /// techniques, once-scattered light only (orders ≤ 2 from the table's
    /// point, which starts at order 1), no control of its own (nor the
    /// ground's, which holds every order).
    #[must_use]
    pub fn for_control_table(&self) -> Self {
        Self {
            control_variate: false,
            ground_control: false,
            termination: TerminationPlan {
                max_scattering_order: 2,
                ..self.termination
            },
            ..*self
        }
    }

    /// Whether the renderer needs the sky guide's table: for guided
    /// directions, segment estimates, or camera branch points by
    /// importance.
    pub fn needs_sky_guide(&self) -> bool {
        self.directions.sky_guide > 0.0
            || self.directions.ground_guide > 0.0
            || self.segments.shadow_samples > 0
            || self.segments.sunlight_samples > 0
            || self.camera.importance > 0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn haze() -> AtmosphereParams {
        AtmosphereParams::default()
    }

    #[test]
    fn unset_choices_follow_the_regime_table() {
        let options = IntegratorOptions::default();
        for (regime, row) in REGIMES {
            let elevation = match regime {
                Regime::Twilight => -4.0,
                Regime::Sunset => 2.0,
                Regime::Day => 20.0,
                Regime::HighSun => 45.0,
            };
            let plan = TechniquePlan::new(&options, &Conditions::new(elevation, &haze(), true));
            assert_eq!(plan.regime, regime);
            assert_eq!(plan.segments.sunlight_samples, row.sunlight_samples);
            assert_eq!(plan.camera.branches, row.camera_branches);
            assert_eq!(plan.camera.importance, row.camera_importance);
            assert_eq!(plan.directions.sky_guide, row.sky_guide);
            assert_eq!(plan.directions.sky_guide_sunlit, row.sky_guide_sunlit);
            assert_eq!(plan.directions.ground_guide, row.ground_guide);
            assert_eq!(plan.termination.splitting, row.splitting);
            assert_eq!(plan.control_variate, row.control_variate);
            let splats = row.circle_splatting.applies(true);
            assert_eq!(plan.circle_splatting, splats);
            // The ground's splats wherever there are circles, with the
            // air's or without.
            assert!(plan.ground_splatting && plan.splats());
            let lobe = if row.control_variate {
                regime::CONTROL_SUN_LOBE
            } else {
                row.sun_lobe
            };
            assert_eq!(plan.directions.sun_lobe, lobe);
            let points = if splats {
                SPLAT_CAMERA_SAMPLES
            } else {
                CAMERA_SAMPLES
            };
            assert_eq!(plan.camera.samples, points);
            assert_eq!(plan.draft_weight, row.draft_weight);
        }
    }

    #[test]
    fn set_choices_stay_whatever_the_sun() {
        let options = IntegratorOptions {
            camera_samples: Some(3),
            camera_branches: Some(5),
            camera_importance: Some(0.2),
            sunlight_samples: Some(2),
            sun_lobe: Some(0.4),
            sky_guide: Some(0.1),
            sky_guide_sunlit: Some(false),
            ground_guide: Some(0.7),
            splitting: Some(false),
            control_variate: Some(false),
            circle_splatting: Some(false),
            ..IntegratorOptions::default()
        };
        let plans: Vec<TechniquePlan> = [-4.0, 2.0, 45.0]
            .iter()
            .map(|&e| TechniquePlan::new(&options, &Conditions::new(e, &haze(), true)))
            .collect();
        for plan in &plans {
            assert_eq!(plan.camera.samples, 3);
            assert_eq!(plan.camera.branches, 5);
            assert_eq!(plan.camera.importance, 0.2);
            assert_eq!(plan.segments.sunlight_samples, 2);
            assert_eq!(plan.directions.sun_lobe, 0.4);
            assert_eq!(plan.directions.sky_guide, 0.1);
            assert!(!plan.directions.sky_guide_sunlit);
            assert_eq!(plan.directions.ground_guide, 0.7);
            assert!(!plan.termination.splitting && !plan.control_variate);
            assert!(!plan.circle_splatting);
        }
    }

    #[test]
    fn the_grounds_control_keeps_out_of_drafts_tables_and_order_limits() {
        let at = |e| Conditions::new(e, &haze(), true);
        let default = IntegratorOptions::default();
        for e in [-4.0, 2.0, 20.0, 45.0] {
            let plan = TechniquePlan::new(&default, &at(e));
            assert!(plan.ground_control, "{e}°");
            // Not in the draft, nor in the control table's paths (their
            // orders are limited), nor under a limit on the orders.
            assert!(!plan.first_pass().ground_control);
            assert!(!plan.for_control_table().ground_control);
            let limited = IntegratorOptions {
                max_scattering_order: Some(2),
                ..IntegratorOptions::default()
            };
            assert!(!TechniquePlan::new(&limited, &at(e)).ground_control);
            let off = IntegratorOptions {
                ground_control: Some(false),
                ..IntegratorOptions::default()
            };
            assert!(!TechniquePlan::new(&off, &at(e)).ground_control);
            // From above the air, or in thick haze, it is off unless asked
            // for.
            let above = at(e).with_observer_in_air(false);
            assert!(!TechniquePlan::new(&default, &above).ground_control);
            let thick = Conditions {
                haze_fits_model: false,
                ..at(e)
            };
            assert!(!TechniquePlan::new(&default, &thick).ground_control);
            let on = IntegratorOptions {
                ground_control: Some(true),
                ..IntegratorOptions::default()
            };
            assert!(TechniquePlan::new(&on, &above).ground_control);
        }
        // The model's own cells control the ground where they are on.
        let model = IntegratorOptions {
            control_source: Some(ControlSource::Model),
            ..IntegratorOptions::default()
        };
        assert!(!TechniquePlan::new(&model, &at(2.0)).ground_control);
        assert!(TechniquePlan::new(&model, &at(45.0)).ground_control);
    }

    #[test]
    fn the_gates_between_techniques_hold() {
        let at = |e| Conditions::new(e, &haze(), true);
        // Splitting follows roulette.
        let no_roulette = IntegratorOptions {
            russian_roulette: false,
            ..IntegratorOptions::default()
        };
        assert!(
            !TechniquePlan::new(&no_roulette, &at(-4.0))
                .termination
                .splitting
        );
        // Splatting needs circles, camera-ray densities and next-event
        // estimation.
        let default = IntegratorOptions::default();
        let no_circles = Conditions {
            circles: false,
            ..at(-4.0)
        };
        let plan = TechniquePlan::new(&default, &no_circles);
        assert!(!plan.circle_splatting && !plan.ground_splatting);
        assert_eq!(plan.camera.samples, CAMERA_SAMPLES);
        let no_ground = IntegratorOptions {
            ground_splatting: Some(false),
            ..IntegratorOptions::default()
        };
        let plan = TechniquePlan::new(&no_ground, &at(-4.0));
        assert!(plan.circle_splatting && !plan.ground_splatting);
        let delta_camera = IntegratorOptions {
            camera_samples: Some(0),
            ..IntegratorOptions::default()
        };
        let plan = TechniquePlan::new(&delta_camera, &at(-4.0));
        assert!(!plan.circle_splatting);
        assert_eq!(plan.camera.importance, 0.0);
        // By day only an observer low in the air splats unless asked; at
        // sunset and twilight every observer in the air does; never with
        // a high sun.
        let splats = |e: f64, density: f64| {
            TechniquePlan::new(&default, &at(e).with_observer_density(density)).circle_splatting
        };
        assert!(splats(6.0, 1.0) && splats(20.0, 0.8) && splats(29.0, 0.5));
        assert!(!splats(6.0, 0.34) && !splats(20.0, 0.49));
        assert!(splats(2.0, 0.34) && splats(-4.0, 0.1));
        assert!(!splats(45.0, 1.0));
        let asked = IntegratorOptions {
            circle_splatting: Some(true),
            ..IntegratorOptions::default()
        };
        let high_day = at(20.0).with_observer_density(0.34);
        assert!(TechniquePlan::new(&asked, &high_day).circle_splatting);
        // The control variate: set on, the lobe yields; in haze its table
        // cannot hold, it stays off unless set; never with an order limit.
        let control = IntegratorOptions {
            control_variate: Some(true),
            ..IntegratorOptions::default()
        };
        let plan = TechniquePlan::new(&control, &at(45.0));
        assert!(plan.control_variate);
        assert_eq!(plan.directions.sun_lobe, regime::CONTROL_SUN_LOBE);
        let thick = Conditions {
            haze_fits_control: false,
            ..at(2.0)
        };
        assert!(!TechniquePlan::new(&default, &thick).control_variate);
        assert!(TechniquePlan::new(&control, &thick).control_variate);
        let single = IntegratorOptions {
            max_scattering_order: Some(1),
            ..control
        };
        assert!(!TechniquePlan::new(&single, &at(2.0)).control_variate);
    }

    #[test]
    fn the_first_pass_is_plain_delta_tracking() {
        let plan = TechniquePlan::new(
            &IntegratorOptions::default(),
            &Conditions::new(2.0, &haze(), true),
        );
        let draft = plan.first_pass();
        assert_eq!(draft.camera.samples, 0);
        assert_eq!(draft.segments.sunlight_samples, 0);
        assert_eq!(draft.directions.sky_guide, 0.0);
        assert!(!draft.control_variate);
        assert_eq!(draft.sampler, Sampler::Independent);
        assert_eq!(
            draft.segments.shadow_transmittance,
            TransmittanceEstimator::ChordResidualRatioTracking
        );
        assert_eq!(draft.draft_weight, plan.draft_weight);
        // Twilight splits; its draft does not.
        let twilight = TechniquePlan::new(
            &IntegratorOptions::default(),
            &Conditions::new(-4.0, &haze(), true),
        );
        assert!(twilight.termination.splitting);
        assert!(!twilight.first_pass().termination.splitting);
        for depth in [0, 1, 5] {
            assert_eq!(
                draft.segments.estimator(depth, true, true),
                SegmentEstimator::DeltaTracking
            );
        }
    }

    #[test]
    fn each_segment_gets_the_estimator_its_plan_names() {
        use SegmentEstimator::*;
        let plan = |sun_el: f64, options: IntegratorOptions| {
            TechniquePlan::new(&options, &Conditions::new(sun_el, &haze(), true)).segments
        };
        // Low sun: every segment through points of its expected sunlight.
        let sunset = plan(2.0, IntegratorOptions::default());
        for (depth, shadow) in [(0, false), (1, true), (4, false)] {
            assert_eq!(sunset.estimator(depth, shadow, true), SunlightPoints);
        }
        // High sun: delta tracking, unless shadow points are asked for,
        // and then only after a scattering, in the shadow, with a guide.
        let midday = plan(60.0, IntegratorOptions::default());
        assert_eq!(midday.estimator(2, true, true), DeltaTracking);
        let shadow = plan(
            60.0,
            IntegratorOptions {
                shadow_samples: 2,
                ..IntegratorOptions::default()
            },
        );
        assert_eq!(shadow.estimator(1, true, true), ShadowPoints);
        assert_eq!(shadow.estimator(0, true, true), DeltaTracking);
        assert_eq!(shadow.estimator(1, false, true), DeltaTracking);
        assert_eq!(shadow.estimator(1, true, false), DeltaTracking);
        // Without next-event estimation there are no points to draw.
        let analog = plan(
            2.0,
            IntegratorOptions {
                next_event_estimation: false,
                ..IntegratorOptions::default()
            },
        );
        assert_eq!(analog.estimator(1, true, true), DeltaTracking);
    }

    #[test]
    fn a_phase_function_over_wavelength_is_judged_by_its_sharpest_peak() {
        // The Martian dust: mean cosine 0.757 at 550 nm, within the
        // control's range, but 0.84 at 360 nm, beyond it: off at sunset.
        use crate::physics::planet::Planet;
        let mars = AtmosphereParams::for_planet(Planet::Mars);
        let phase = mars.aerosol_phase_function().unwrap();
        assert!(phase.mean_cosine() < CONTROL_AEROSOL_G.1);
        let g = control_aerosol_g(&mars);
        assert!((g - 0.8436).abs() < 1e-3, "{g}");
        assert!(!control_table_holds(&mars));
        let plan = TechniquePlan::new(
            &IntegratorOptions::default(),
            &Conditions::new(2.0, &mars, true),
        );
        assert!(!plan.control_variate);
    }

    #[test]
    fn the_control_variate_stays_off_where_its_table_cannot_hold_the_haze() {
        // At sunset, unset: on in the default haze and at the limits, off
        // past them (with the sun lobe of no control), on again without
        // aerosols whatever their g; set, honoured.
        let haze = |amount: f64, g: f64| AtmosphereParams {
            aerosol_amount: amount,
            aerosol_g: g,
            ..AtmosphereParams::default()
        };
        let per_amount = AtmosphereParams::default().aerosol_optical_depth(550.0);
        let deepest = CONTROL_MAX_AEROSOL_DEPTH / per_amount;
        let (g_min, g_max) = CONTROL_AEROSOL_G;
        for (atmosphere, on) in [
            (haze(1.0, 0.7), true),
            (haze(deepest * 0.999, 0.7), true),
            (haze(deepest * 1.001, 0.7), false),
            (haze(100.0, 0.7), false),
            (haze(100.0, 0.99), false),
            (haze(1.0, g_max), true),
            (haze(1.0, g_max + 0.01), false),
            (haze(1.0, 0.99), false),
            (haze(1.0, g_min), true),
            (haze(1.0, g_min - 0.01), false),
            (haze(1.0, -0.99), false),
            (haze(0.0, 0.99), true),
            (
                AtmosphereParams {
                    aerosols: false,
                    ..haze(100.0, 0.99)
                },
                true,
            ),
        ] {
            let what = format!("{} {}", atmosphere.aerosol_amount, atmosphere.aerosol_g);
            assert_eq!(control_table_holds(&atmosphere), on, "{what}");
            let at = Conditions::new(2.0, &atmosphere, true);
            let plan = TechniquePlan::new(&IntegratorOptions::default(), &at);
            assert_eq!(plan.control_variate, on, "{what}");
            let lobe = if on {
                regime::CONTROL_SUN_LOBE
            } else {
                Regime::Sunset.defaults().sun_lobe
            };
            assert_eq!(plan.directions.sun_lobe, lobe, "{what}");
            for set in [false, true] {
                let options = IntegratorOptions {
                    control_variate: Some(set),
                    ..IntegratorOptions::default()
                };
                let plan = TechniquePlan::new(&options, &at);
                assert_eq!(plan.control_variate, set, "{what}");
            }
        }
        // The default haze: aerosol optical depth 0.249 at 550 nm, g 0.7.
        assert!((per_amount - 0.249).abs() < 0.001, "{per_amount}");
    }
}
