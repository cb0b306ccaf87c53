//! The Lambertian ground: the sunlight it reflects straight to a path (its
//! bounce is [`Integrator::ground_bounce`]).

use super::{ground_point, DVec3, Integrator, Lanes, Light, Rng, SpectralLanes, PI};

impl Integrator<'_> {
    /// The sun's direct light reflected at a ground vertex with normal
    /// `normal`, reached after `depth` scatterings with weight `beta`.
    pub(super) fn ground_direct(
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
            let e_sun = self.sun_irradiance_toward(to_sun, lanes);
            let cos = normal.dot(to_sun);
            if cos > 0.0 {
                let tr = self.shadow(x, to_sun, lanes, rng);
                radiance.total += *beta * lanes.ground_albedo / PI * cos * e_sun * tr;
            }
        }
    }
}
