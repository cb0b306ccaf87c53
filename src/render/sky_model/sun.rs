//! The sun's light at a point as the model takes it: through the
//! sun-column table, over the sun's disc where it is setting.

use glam::DVec3;

use super::optics::{Optics, Spectrum, NODES};
use crate::render::medium::LANES;

/// The sun's angular radius, rad (`crate::physics::sun`).
const SUN_RADIUS_RAD: f64 = crate::physics::sun::ANGULAR_RADIUS_DEG * std::f64::consts::PI / 180.0;
/// Where the sun's centre stands less than its radius above a point's
/// astronomical horizon (this is the sine of 0.26656°), its light there is
/// averaged over the disc, not taken at its centre: the path tracer's sun
/// is a disc, and there the planet may hide part of it, or the rays to its
/// upper and lower limbs graze the air at heights kilometres apart. At
/// twilight, where that sunlit air is all the sky's light, a point sun
/// left the model's sky and ground 1–4 % dark (first frame 2.7 → 1.6 %
/// off the path tracer's, BENCHMARKS.md); averaging wherever the sun is
/// below 1°, 2°, 3° or 5° changed nothing more, and cost more.
const DISC_BELOW_SIN_ELEVATION: f64 = 0.004_652_3;

impl Optics<'_> {
    /// Transmittance toward the sun from `x` at each wavelength (0 in the
    /// planet's shadow), over the sun's disc where it stands less than its
    /// radius above `x`'s horizon ([`DISC_BELOW_SIN_ELEVATION`]), else at
    /// its centre.
    pub(super) fn sun_transmittance(&self, x: DVec3) -> Spectrum {
        let up = x / x.length();
        let sin_elevation = up.dot(self.sun_direction);
        let across = up - self.sun_direction * sin_elevation;
        let length = across.length();
        if sin_elevation > DISC_BELOW_SIN_ELEVATION || length < 1e-9 {
            return self
                .sun_transmittance_along(x, self.sun_direction)
                .unwrap_or([0.0; NODES]);
        }
        // The disc's vertical diameter, its points s ∈ [−1, 1] weighted by
        // the chord √(1 − s²): Gauss–Chebyshev (second kind) with three
        // nodes, s = ±1/√2 and 0, weights ¼, ½, ¼.
        let offset = across * (SUN_RADIUS_RAD * std::f64::consts::FRAC_1_SQRT_2 / length);
        // Below the upper node the planet hides the rest of the disc too.
        let Some(upper) =
            self.sun_transmittance_along(x, (self.sun_direction + offset).normalize())
        else {
            return [0.0; NODES];
        };
        let centre = self
            .sun_transmittance_along(x, self.sun_direction)
            .unwrap_or([0.0; NODES]);
        let lower = self
            .sun_transmittance_along(x, (self.sun_direction - offset).normalize())
            .unwrap_or([0.0; NODES]);
        std::array::from_fn(|n| 0.25 * (upper[n] + lower[n]) + 0.5 * centre[n])
    }

    /// Transmittance from `x` along the unit `sun` at each wavelength;
    /// `None` where the planet hides that direction.
    fn sun_transmittance_along(&self, x: DVec3, sun: DVec3) -> Option<Spectrum> {
        let columns = self.medium.sun_columns().at(x, sun)?;
        let mut t = [0.0; NODES];
        for (g, lanes) in self.groups.iter().enumerate() {
            for j in 0..LANES {
                t[g * LANES + j] =
                    (-crate::render::sunlight::sun_optical_depth(lanes, j, columns)).exp();
            }
        }
        Some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::sky_model::optics::{node_groups, Phases};
    use crate::render::Renderer;
    use crate::Scene;

    /// The sun's light at a point is its disc's: where the sun stands
    /// high, the centre's alone; where its centre has just set for a point
    /// on the ground, the part of the disc still above the horizon (the
    /// centre's transmittance is zero there), less than a disc wholly up.
    #[test]
    fn sunlight_near_the_horizon_is_the_discs() {
        let renderer = Renderer::new(&Scene::preset("midday").unwrap()).unwrap();
        let medium = &renderer.medium;
        let groups = node_groups(medium, &renderer.lane_table);
        let phases = Phases::new(medium, &groups);
        let optics = |elevation_deg: f64| Optics {
            medium,
            groups: &groups,
            phases: &phases,
            sun_direction: crate::render::direction_from_az_el(0.0, elevation_deg),
        };
        let ground = DVec3::new(0.0, 0.0, medium.planet_radius_m + 1.0);
        let high = optics(30.0);
        assert_eq!(
            high.sun_transmittance(ground),
            high.sun_transmittance_along(ground, high.sun_direction)
                .unwrap()
        );
        let setting = optics(-0.1);
        assert!(setting
            .sun_transmittance_along(ground, setting.sun_direction)
            .is_none());
        let part = setting.sun_transmittance(ground);
        let up = optics(0.5).sun_transmittance(ground);
        for n in 0..NODES {
            assert!(
                part[n] > 0.0 && part[n] < up[n],
                "node {n}: {} {}",
                part[n],
                up[n]
            );
        }
    }
}
