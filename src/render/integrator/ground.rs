//! The Lambertian ground: its vertices, the sunlight it reflects straight
//! to a path, and cosine-weighted bounce directions.

use super::{
    cosine_sample_hemisphere, ground_point, DVec3, Integrator, Lanes, Light, Rng, SpectralLanes,
    Vertex, PI,
};

impl Integrator<'_> {
    /// A Lambertian ground vertex with normal `normal`, reached after `depth`
    /// scatterings with weight `beta`: adds the sun's direct light and
    /// returns the bounce (vertex, direction, weight) if the path goes on.
    pub(super) fn ground_vertex(
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
            Lanes::from_fn(|j| beta[j] * lanes.ground_albedo[j]),
        ))
    }

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
            let cos = normal.dot(to_sun);
            if cos > 0.0 {
                let tr = self.shadow(x, to_sun, lanes, rng);
                let e_sun = self.sun_irradiance_toward(to_sun, lanes);
                radiance.total += *beta * lanes.ground_albedo / PI * cos * e_sun * tr;
            }
        }
    }
}
