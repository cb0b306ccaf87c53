//! The tables a render reads, built in one place from its technique plan:
//! the camera rays' expected-sunlight densities, the sky guide, the
//! control variate's table of once-scattered light (with the projection
//! that fills its cells), and the splatter's circles. Every table is a
//! cache of a function of the scene alone, filled on first use with its
//! own random numbers, so what a render computes does not depend on the
//! order in which the tables fill; the integrator only reads them.

use std::f64::consts::PI;
use std::sync::{Arc, OnceLock};

use glam::DVec3;

use super::camera::Camera;
use super::circles::CircleSplatter;
use super::control::{CellCoefficients, CellProjection, RadianceTable, COEFFICIENTS, NODES};
use super::ground_circles::GroundSplatter;
use super::ground_sky::GroundSky;
use super::guide::SkyGuide;
use super::integrator::Integrator;
use super::lanes::LaneTable;
use super::medium::{Lanes, Medium, SpectralLanes, LANES};
use super::sky_model::{ModelField, ModelTables};
use super::sunlight::CameraDensities;
use crate::plan::{ControlSource, TechniquePlan};
use crate::rng::Rng;

/// Zenith × azimuth strata of the directions a control cell is projected
/// from.
const CONTROL_DIRECTIONS: (usize, usize) = (32, 16);
/// Seed of the control cells' own random numbers.
const CONTROL_SEED: u64 = 0xc047_a01e;

/// The tables of one render.
pub struct Tables {
    /// Expected-sunlight densities of camera rays, built per view
    /// direction on first use.
    pub camera_densities: CameraDensities,
    /// Incoming once-scattered light by direction at scattering points,
    /// built per (altitude, solar zenith) cell on first use; only for the
    /// plans that read it ([`TechniquePlan::needs_sky_guide`]); shared with
    /// the camera densities, which read its skylight as their importance.
    pub sky_guide: Option<Arc<SkyGuide>>,
    /// The once-scattered light's table for the control variate, where the
    /// plan turns it on.
    pub control: Option<RadianceTable>,
    /// The model's skylight on the ground for the ground's control
    /// variate, where the plan turns it on and the ground reflects.
    pub ground_sky: Option<GroundSky>,
    /// The splatter, built on first use (after the draft pass).
    splatter: OnceLock<Option<CircleSplatter>>,
    /// The ground's splatter, likewise.
    ground_splatter: OnceLock<Option<GroundSplatter>>,
}

impl Tables {
    /// The tables `plan` reads in `medium` for an observer at `observer_m`
    /// and the sun along `sun_direction`, the control's wavelength nodes
    /// over `lane_table`'s range. Empty until first used.
    pub fn new(
        medium: &Medium,
        plan: &TechniquePlan,
        lane_table: &LaneTable,
        observer_m: DVec3,
        sun_direction: DVec3,
    ) -> Self {
        let sky_guide = plan
            .needs_sky_guide()
            .then(|| Arc::new(SkyGuide::new(medium, sun_direction)));
        let camera_densities = CameraDensities::new(medium, observer_m, sun_direction);
        let camera_importance = Some(plan.camera.importance).filter(|&share| share > 0.0);
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
        let control = plan.control_variate.then(|| {
            let projection: Box<dyn CellProjection> = match plan.control_source {
                ControlSource::OnceScattered => Box::new(SingleScattering {
                    plan: plan.for_control_table(),
                    sun_direction,
                }),
                ControlSource::Model => Box::new(ModelRadiance {
                    field: ModelField::from_tables(
                        ModelTables::shared(medium, lane_table),
                        sun_direction,
                    ),
                }),
            };
            RadianceTable::new(
                medium.planet_radius_m,
                medium.top_radius_m,
                sun_direction,
                lane_table.range_nm(),
                projection,
            )
        });
        let ground_sky = (plan.ground_control && medium.ground_albedo_max > 0.0)
            .then(|| GroundSky::new(ModelTables::shared(medium, lane_table), sun_direction));
        Self {
            camera_densities,
            sky_guide,
            control,
            ground_sky,
            splatter: OnceLock::new(),
            ground_splatter: OnceLock::new(),
        }
    }

    /// The integrator of `plan` in `medium` for the sun along
    /// `sun_direction`, reading these tables.
    pub fn integrator<'a>(
        &'a self,
        medium: &'a Medium,
        plan: &'a TechniquePlan,
        sun_direction: DVec3,
    ) -> Integrator<'a> {
        let integrator = Integrator::new(medium, plan, sun_direction)
            .with_camera_densities(&self.camera_densities);
        let integrator = match &self.sky_guide {
            Some(guide) => integrator.with_sky_guide(guide),
            None => integrator,
        };
        let integrator = match &self.control {
            Some(table) => integrator.with_control(table),
            None => integrator,
        };
        match &self.ground_sky {
            Some(sky) if plan.ground_control => integrator.with_ground_sky(sky),
            _ => integrator,
        }
    }

    /// The splatter along the circles about the sun's axis for `camera`
    /// at `observer_m`, learned on first use with the integrator that
    /// `integrator` makes (only then); `None` where there are no circles
    /// to splat along.
    pub(crate) fn splatter<'i>(
        &self,
        medium: &Medium,
        integrator: impl FnOnce() -> Integrator<'i>,
        camera: &Camera,
        observer_m: DVec3,
    ) -> Option<&CircleSplatter> {
        self.splatter
            .get_or_init(|| {
                CircleSplatter::new(
                    medium,
                    &integrator(),
                    self.sky_guide.as_deref(),
                    camera,
                    observer_m,
                )
            })
            .as_ref()
    }

    /// The splatter of the ground's skylight along the same circles
    /// ([`GroundSplatter`]), built on first use with the integrator that
    /// `integrator` makes (only then); `None` where there is nothing to
    /// splat.
    pub(crate) fn ground_splatter<'i>(
        &self,
        medium: &Medium,
        integrator: impl FnOnce() -> Integrator<'i>,
        camera: &Camera,
        observer_m: DVec3,
    ) -> Option<&GroundSplatter> {
        self.ground_splatter
            .get_or_init(|| {
                GroundSplatter::new(
                    medium,
                    &integrator(),
                    self.sky_guide.as_deref(),
                    camera,
                    observer_m,
                )
            })
            .as_ref()
    }
}

/// The control table's cells: the once-scattered light (and the ground's
/// direct reflection) arriving at a cell's central point, per unit
/// irradiance at the table's wavelength nodes, projected on the basis from
/// next-event estimates along [`CONTROL_DIRECTIONS`] stratified directions,
/// by paths of the render's plan cut after one scattering
/// ([`TechniquePlan::for_control_table`]). Single scattering holds the
/// sharp part of the light a point sees (the aureole, the horizon), which
/// is what the control takes out of the paths (`BENCHMARKS.md`); the
/// random numbers are the cell's own, so the table does not depend on the
/// render's.
struct SingleScattering {
    plan: TechniquePlan,
    sun_direction: DVec3,
}

impl CellProjection for SingleScattering {
    fn project(
        &self,
        medium: &Medium,
        guide: Option<&SkyGuide>,
        table: &RadianceTable,
        i: usize,
        k: usize,
    ) -> CellCoefficients {
        let single = Integrator::new(medium, &self.plan, self.sun_direction);
        let single = match guide {
            Some(guide) => single.with_sky_guide(guide),
            None => single,
        };
        let origin = table.cell_point(i, k);
        let frame = table.frame(origin);
        let (nt, np) = CONTROL_DIRECTIONS;
        let weight = 4.0 * PI / (nt * np) as f64;
        let mut rng = Rng::new(CONTROL_SEED, (i * 1000 + k) as u64);
        let sets: Vec<SpectralLanes> = (0..NODES.div_ceil(LANES))
            .map(|set| {
                let nm = std::array::from_fn(|j| table.node_nm((set * LANES + j).min(NODES - 1)));
                SpectralLanes::new(Lanes::from(nm), LANES, medium, true)
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
                    let radiance = single.scattered_light(origin, dir, lanes, &mut rng);
                    for (j, l) in radiance.iter().enumerate() {
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
}

/// The control table's cells from the approximate sky model
/// ([`ModelField`]): the light of *every* order arriving at a cell's
/// central point (and the lit ground's), per unit irradiance, projected on
/// the basis by the midpoint rule over [`CONTROL_DIRECTIONS`] directions,
/// each the model's march through its tables, linear in wavelength between
/// the model's nodes. The paths then estimate only what the model misses,
/// L − L̃ (the "whole path" control variate); it holds no random numbers.
struct ModelRadiance {
    field: ModelField,
}

impl CellProjection for ModelRadiance {
    fn project(
        &self,
        medium: &Medium,
        _guide: Option<&SkyGuide>,
        table: &RadianceTable,
        i: usize,
        k: usize,
    ) -> CellCoefficients {
        let origin = table.cell_point(i, k);
        let frame = table.frame(origin);
        let (nt, np) = CONTROL_DIRECTIONS;
        let weight = 4.0 * PI / (nt * np) as f64;
        // Each table node as a blend of two model nodes.
        let blend: [(usize, f64); NODES] =
            std::array::from_fn(|n| ModelField::node_blend(table.node_nm(n)));
        let mut coefficients = [[0.0; COEFFICIENTS]; NODES];
        for it in 0..nt {
            for ip in 0..np {
                let cos_theta = -1.0 + 2.0 * (it as f64 + 0.5) / nt as f64;
                let phi = PI * (ip as f64 + 0.5) / np as f64;
                let dir = frame.direction(cos_theta, phi);
                let y = frame.basis(dir);
                let model = self.field.radiance(medium, origin, dir);
                for (c, &(m, f)) in coefficients.iter_mut().zip(&blend) {
                    let l = model[m] * (1.0 - f) + model[m + 1] * f;
                    for (c, y) in c.iter_mut().zip(&y) {
                        *c += weight * l * y;
                    }
                }
            }
        }
        coefficients
    }
}
