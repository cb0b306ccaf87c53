//! The approximate model's skylight on the ground, as a control variate
//! for the ground's bounces.
//!
//! A Lambertian ground of albedo a under unit normal n reflects (a/π) E
//! toward every direction, E = ∫ L(ω) max(n·ω, 0) dω the sky's irradiance
//! (the sun's disc apart: next-event estimation counts it). A bounce
//! estimates E by one direction ω drawn from a density p and the path going
//! on: L̂(ω) cos/p. With a fixed function L̃,
//!
//! E = ∫ L̃ cos dω + ∫ (L − L̃) cos dω,
//!
//! the first term exact and the second estimated by the bounce as before,
//! its path now carrying L − L̃. Whatever L̃, the estimate stays unbiased;
//! its variance loses the part that came from the direction's choice as
//! far as L̃ follows L (the part from the path's own estimate of L along
//! ω stays). By day that part is about half a bounce's variance, with the
//! sun low a tenth (`BENCHMARKS.md`, ground control).
//!
//! L̃ is the approximate sky model's light of every order
//! ([`ModelField`]), constant over the cells of a grid of directions about
//! the point's zenith (cells uniform in the zenith cosine μ and in the
//! azimuth φ from the sun's vertical plane, which the light is
//! mirror-symmetric about), so its cosine integral is an exact sum:
//! (μ₁² − μ₀²)/2 · Δφ per cell and mirror half. Over a spherical ground the
//! light arriving at a point depends only on the sun's zenith angle there:
//! one grid per node of the sun's zenith cosine, made on first use, a
//! point's two nodes blended linearly with weights fixed by the point (so
//! the blend's integral is the blend of the grids'), and in wavelength
//! linear between the model's nodes. It holds no random numbers. A bounce
//! looks it up in a few tens of nanoseconds, a grid takes a few
//! milliseconds to make.

use std::f64::consts::PI;
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use glam::DVec3;

use super::directions::LocalAxes;
use super::medium::{Lanes, Medium, SpectralLanes, LANES};
use super::sky_model::{ModelField, ModelTables, MODEL_NODES};

/// Zenith-cosine cells of a grid, uniform over 0–1 (narrow in angle at the
/// horizon, where the low sun's light lies). Finer grids and longer
/// marches take out no more of the variance (`BENCHMARKS.md`): what the
/// control leaves is the path's own estimate's.
const ZENITH_CELLS: usize = 16;
/// Azimuth cells, uniform over 0–180° from the sun's vertical plane.
const AZIMUTH_CELLS: usize = 16;
/// Steps of the model's march per direction.
const MARCH_STEPS: usize = 16;
/// The lowest node's sun: 18° below the horizon (the end of astronomical
/// twilight), beyond which the ground's skylight is not worth a grid.
const SUN_COSINE_MIN: f64 = -0.309_016_994_374_947_4;
/// Nodes of the sun's zenith cosine, uniform from [`SUN_COSINE_MIN`] to 1
/// (1.4° apart at the horizon).
const SUN_NODES: usize = 53;

/// The model's light on one grid, per unit solar irradiance.
struct Grid {
    /// Per cell (zenith-major), at the model's nodes.
    radiance: Vec<[f32; MODEL_NODES]>,
    /// ∫ L̃ cos dω over the hemisphere of these cell values, at each node.
    irradiance: [f64; MODEL_NODES],
}

/// The grids of one atmosphere's model, one per node of the sun's zenith
/// cosine, each made on first use. They do not depend on the sun's
/// direction (only on its zenith angle at the ground point, the node's),
/// so renderers of the same optics share them ([`GroundSky::new`]); each
/// is made in one canonical frame, so its values do not depend on which
/// renderer made it.
struct Grids {
    /// The model lit from the canonical sun, +z.
    field: ModelField,
    by_node: Vec<OnceLock<Grid>>,
}

/// The model's skylight on the ground of one scene.
pub struct GroundSky {
    grids: Arc<Grids>,
    sun_direction: DVec3,
}

/// The control at one ground point for one path's wavelengths.
pub struct GroundSkyAt<'a> {
    /// The two nodes about the point's sun.
    grids: [&'a Grid; 2],
    /// Per lane, the model node below its wavelength and the weights of
    /// the four values it blends: (grid, node) = (0, m), (0, m + 1),
    /// (1, m), (1, m + 1).
    blend: [(usize, [f32; 4]); LANES],
    /// The point's zenith and horizontal axes about the sun's azimuth.
    axes: LocalAxes,
}

impl GroundSky {
    /// The skylight of the atmosphere of the model's `tables` lit along
    /// unit `sun_direction`, its grids those of the last renderer of the
    /// same tables where there was one.
    pub fn new(tables: Arc<ModelTables>, sun_direction: DVec3) -> Self {
        /// The grids made last, kept for the next renderer of the same
        /// tables (the app makes one per change of sun).
        static LAST: Mutex<Option<Arc<Grids>>> = Mutex::new(None);
        let mut last = LAST.lock().unwrap_or_else(PoisonError::into_inner);
        let grids = match last.as_ref() {
            Some(grids) if Arc::ptr_eq(grids.field.tables(), &tables) => Arc::clone(grids),
            _ => {
                let grids = Arc::new(Grids {
                    field: ModelField::from_tables(tables, DVec3::Z),
                    by_node: (0..SUN_NODES).map(|_| OnceLock::new()).collect(),
                });
                *last = Some(Arc::clone(&grids));
                grids
            }
        };
        Self {
            grids,
            sun_direction,
        }
    }

    /// The control at the ground point under unit `normal` in `medium`
    /// (the field's) for `lanes`, or `None` where the sun stands more than
    /// 18° below the point's horizon.
    pub fn at(
        &self,
        medium: &Medium,
        normal: DVec3,
        lanes: &SpectralLanes,
    ) -> Option<GroundSkyAt<'_>> {
        let cos_sun = normal.dot(self.sun_direction).min(1.0);
        let u = (cos_sun - SUN_COSINE_MIN) / sun_step();
        if u < 0.0 {
            return None;
        }
        let k = (u as usize).min(SUN_NODES - 2);
        let w = (u - k as f64) as f32;
        let grids = &self.grids;
        let grid = |k: usize| grids.by_node[k].get_or_init(|| grids.grid(medium, k));
        let blend = std::array::from_fn(|j| {
            let (m, f) = ModelField::node_blend(lanes.wavelengths_nm[j]);
            let f = f as f32;
            (
                m,
                [(1.0 - w) * (1.0 - f), (1.0 - w) * f, w * (1.0 - f), w * f],
            )
        });
        Some(GroundSkyAt {
            grids: [grid(k), grid(k + 1)],
            blend,
            axes: LocalAxes::new(normal, self.sun_direction),
        })
    }
}

impl Grids {
    /// The grid of node `k`: the model's light at each cell's central
    /// direction, seen from a ground point with the sun at the node's
    /// zenith cosine.
    fn grid(&self, medium: &Medium, k: usize) -> Grid {
        let cos_sun = SUN_COSINE_MIN + k as f64 * sun_step();
        let normal = DVec3::new((1.0 - cos_sun * cos_sun).max(0.0).sqrt(), 0.0, cos_sun);
        let x = normal * medium.planet_radius_m;
        let axes = LocalAxes::new(normal, DVec3::Z);
        let d_mu = 1.0 / ZENITH_CELLS as f64;
        let d_phi = PI / AZIMUTH_CELLS as f64;
        let mut radiance = Vec::with_capacity(ZENITH_CELLS * AZIMUTH_CELLS);
        let mut irradiance = [0.0; MODEL_NODES];
        for i in 0..ZENITH_CELLS {
            let mu = (i as f64 + 0.5) * d_mu;
            // ∫ μ dμ dφ over the cell, twice for the mirror half.
            let (mu0, mu1) = (i as f64 * d_mu, (i + 1) as f64 * d_mu);
            let weight = (mu1 * mu1 - mu0 * mu0) * d_phi;
            for l in 0..AZIMUTH_CELLS {
                let phi = (l as f64 + 0.5) * d_phi;
                let dir = axes.direction(mu, phi);
                let model = self.field.radiance_marched(medium, x, dir, MARCH_STEPS);
                let cell: [f32; MODEL_NODES] = std::array::from_fn(|n| model[n] as f32);
                for (e, &l) in irradiance.iter_mut().zip(&cell) {
                    *e += f64::from(l) * weight;
                }
                radiance.push(cell);
            }
        }
        Grid {
            radiance,
            irradiance,
        }
    }
}

impl GroundSkyAt<'_> {
    /// ∫ L̃ cos dω per lane, per unit solar irradiance.
    pub fn irradiance(&self) -> Lanes {
        let [a, b] = self.grids;
        Lanes::from_fn(|j| {
            let (m, w) = self.blend[j];
            let v = [
                a.irradiance[m],
                a.irradiance[m + 1],
                b.irradiance[m],
                b.irradiance[m + 1],
            ];
            v.iter().zip(w).map(|(v, w)| v * f64::from(w)).sum()
        })
    }

    /// L̃ along unit `dir` per lane, per unit solar irradiance (0 below the
    /// horizon).
    pub fn radiance(&self, dir: DVec3) -> Lanes {
        let mu = dir.dot(self.axes.up);
        if mu <= 0.0 {
            return Lanes::splat(0.0);
        }
        let phi = dir
            .dot(self.axes.across_sun)
            .atan2(dir.dot(self.axes.toward_sun))
            .abs();
        let i = ((mu * ZENITH_CELLS as f64) as usize).min(ZENITH_CELLS - 1);
        let l = ((phi * (AZIMUTH_CELLS as f64 / PI)) as usize).min(AZIMUTH_CELLS - 1);
        let cell = i * AZIMUTH_CELLS + l;
        let [a, b] = self.grids;
        let (a, b) = (&a.radiance[cell], &b.radiance[cell]);
        Lanes::from_fn(|j| {
            let (m, w) = self.blend[j];
            let v = [a[m], a[m + 1], b[m], b[m + 1]];
            v.iter()
                .zip(w)
                .map(|(&v, w)| f64::from(v) * f64::from(w))
                .sum()
        })
    }
}

/// Spacing of the nodes of the sun's zenith cosine.
fn sun_step() -> f64 {
    (1.0 - SUN_COSINE_MIN) / (SUN_NODES - 1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::render::integrator::cosine_sample_hemisphere;
    use crate::render::lanes::{LaneTable, SolarSource};
    use crate::rng::Rng;

    #[test]
    fn the_exact_irradiance_is_the_cosine_integral_of_the_looked_up_light() {
        // The control is unbiased only if the irradiance it adds is the
        // integral of the very function it subtracts: a cosine-weighted
        // Monte Carlo average of π L̃ over the hemisphere must agree with
        // it, at points between the nodes of solar zenith.
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let lane_table = LaneTable::new(&medium, (360.0, 830.0), SolarSource::from_unit_sun(false));
        let sun = DVec3::new(0.3, -0.2, 0.93).normalize();
        let sky = GroundSky::new(ModelTables::shared(&medium, &lane_table), sun);
        let lanes = lane_table.lanes(Lanes::from([420.0, 515.3, 601.0, 777.7]), LANES, &medium);
        let mut rng = Rng::new(3, 4);
        for sun_zenith_deg in [31.3, 87.9, 93.1] {
            let angle = f64::to_radians(sun_zenith_deg);
            let aside = sun.any_orthonormal_vector();
            let normal = sun * angle.cos() + aside * angle.sin();
            let at = sky
                .at(&medium, normal, &lanes)
                .expect("sun within 18° of the horizon");
            let exact = at.irradiance();
            let n = 200_000_u32;
            let (mut sum, mut sum2) = (Lanes::splat(0.0), Lanes::splat(0.0));
            for _ in 0..n {
                let dir = cosine_sample_hemisphere(normal, &mut rng);
                let v = at.radiance(dir) * PI;
                sum += v;
                sum2 += v * v;
            }
            for j in 0..LANES {
                let mean = sum[j] / f64::from(n);
                let se = ((sum2[j] / f64::from(n) - mean * mean) / f64::from(n)).sqrt();
                assert!(exact[j] > 0.0, "{sun_zenith_deg}°: no light");
                assert!(
                    (mean - exact[j]).abs() < 4.0 * se,
                    "{sun_zenith_deg}°, lane {j}: {mean} ± {se} against {}",
                    exact[j]
                );
            }
        }
        // Beyond 18° below the horizon there is no control.
        let normal = -sun;
        assert!(sky.at(&medium, normal, &lanes).is_none());
    }
}
