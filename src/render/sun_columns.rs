//! Column amounts toward the sun, tabulated over altitude and solar
//! zenith: a sampling aid for the expected sunlight along rays
//! ([`super::sunlight`]).

use glam::DVec3;
use rayon::prelude::*;

use super::directions::horizon_cosine;

/// Altitude nodes of the column table (square-root spacing: dense low down).
const ALTITUDE_NODES: usize = 64;
/// Solar-zenith nodes (square-root spacing from the horizon: dense where the
/// sun grazes).
const ZENITH_NODES: usize = 64;

/// Column amounts toward the sun: air molecules (m⁻²), ozone molecules (m⁻²)
/// and aerosol optical depth at the reference wavelength (`medium::Node`),
/// from a point at a given altitude for a given solar zenith angle, without
/// refraction.
pub struct SunColumns {
    top_m: f64,
    planet_radius_m: f64,
    /// `[altitude][zenith] → [air, ozone, aerosol]`.
    columns: Vec<[f32; 3]>,
}

impl SunColumns {
    /// The table from `column_along(origin, dir)`, the columns along a
    /// straight ray from `origin` to the top of an atmosphere
    /// `top_radius_m` from the centre of a planet of `planet_radius_m`
    /// (the medium integrates them, [`super::medium::Medium::sun_columns`]).
    pub fn new(
        planet_radius_m: f64,
        top_radius_m: f64,
        column_along: impl Fn(DVec3, DVec3) -> [f32; 3] + Sync,
    ) -> Self {
        let top_m = top_radius_m - planet_radius_m;
        // Each entry on its own (in parallel: the preview's first frame
        // waits for this table).
        let columns = (0..ALTITUDE_NODES * ZENITH_NODES)
            .into_par_iter()
            .map(|entry| {
                let (i, k) = (entry / ZENITH_NODES, entry % ZENITH_NODES);
                let h = top_m * (i as f64 / (ALTITUDE_NODES - 1) as f64).powi(2);
                // Just inside the top, so the ray is in the atmosphere.
                let r = planet_radius_m + h.min(top_m - 1.0);
                let mu_horizon = horizon_cosine(planet_radius_m, r);
                let u = k as f64 / (ZENITH_NODES - 1) as f64;
                // Slightly above the horizon so the grazing ray clears the ground.
                let mu = (mu_horizon + (1.0 - mu_horizon) * u * u + 1e-9).min(1.0);
                let origin = DVec3::new(0.0, 0.0, r);
                let dir = DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
                column_along(origin, dir)
            })
            .collect();
        Self {
            top_m,
            planet_radius_m,
            columns,
        }
    }

    /// Columns toward the sun from `x` (m, planet-centred) for the sun along
    /// `sun_direction`, or `None` where the planet hides the sun's centre.
    pub fn at(&self, x: DVec3, sun_direction: DVec3) -> Option<[f64; 3]> {
        let r = x.length();
        let mu = x.dot(sun_direction) / r;
        let r = r.clamp(self.planet_radius_m, self.planet_radius_m + self.top_m);
        let mu_horizon = horizon_cosine(self.planet_radius_m, r);
        if mu < mu_horizon {
            return None;
        }
        let a =
            ((r - self.planet_radius_m) / self.top_m).max(0.0).sqrt() * (ALTITUDE_NODES - 1) as f64;
        let z = ((mu - mu_horizon) / (1.0 - mu_horizon))
            .clamp(0.0, 1.0)
            .sqrt()
            * (ZENITH_NODES - 1) as f64;
        let (i, fa) = split(a, ALTITUDE_NODES);
        let (k, fz) = split(z, ZENITH_NODES);
        let at = |i: usize, k: usize| &self.columns[i * ZENITH_NODES + k];
        Some(std::array::from_fn(|c| {
            let lo = f64::from(at(i, k)[c]) * (1.0 - fz) + f64::from(at(i, k + 1)[c]) * fz;
            let hi = f64::from(at(i + 1, k)[c]) * (1.0 - fz) + f64::from(at(i + 1, k + 1)[c]) * fz;
            lo * (1.0 - fa) + hi * fa
        }))
    }
}

/// Integer node below `x` and the fraction past it, for linear interpolation.
fn split(x: f64, nodes: usize) -> (usize, f64) {
    let i = (x as usize).min(nodes - 2);
    (i, (x - i as f64).clamp(0.0, 1.0))
}
