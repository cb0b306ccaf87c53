//! The Lambertian ground: the sunlight it reflects straight to a path and
//! the direction of its bounce (the bounce itself is
//! [`Integrator::ground_bounce`]).

use super::{
    cosine_sample_hemisphere, ground_point, DVec3, GroundSkyAt, GuideAt, Integrator, Lanes, Light,
    Radiance, Rng, SpectralLanes, PI,
};

impl<'a> Integrator<'a> {
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

    /// The skylight the ground under unit `normal` reflects toward any
    /// direction, (a/π) E, estimated by one bounce and its path, as a
    /// camera path's ground branch estimates it (with the ground's control
    /// variate where the plan has one): a ground splat's light
    /// ([`super::super::ground_circles`]). The sun's direct light is not in
    /// it.
    pub(crate) fn ground_light(
        &self,
        normal: DVec3,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Radiance {
        let mut radiance = Light::default();
        let sky = self.ground_sky(normal, lanes);
        Self::ground_sky_in(sky.as_ref(), &lanes.ground_albedo, lanes, &mut radiance);
        let guide = self.bounce_guide(normal);
        let Some((bounce, reflect)) = self.bounce_direction(normal, guide.as_ref(), rng) else {
            return radiance.total;
        };
        let beta = Lanes::from_fn(|j| lanes.ground_albedo[j] * reflect);
        Self::ground_sky_out(sky.as_ref(), bounce, &beta, lanes, &mut radiance);
        self.ground_control(normal, bounce, &beta, lanes, &mut radiance, rng);
        // Roulette plays on the weight relative to the bounce's start, as
        // on a camera path's branch.
        let start = beta[..lanes.active].iter().copied().fold(0.0, f64::max);
        let split = if start > 0.0 { 1.0 / start } else { 1.0 };
        let x = ground_point(self.medium, normal);
        self.trace((x, bounce, 1, split), beta, lanes, &mut radiance, rng);
        radiance.total
    }

    /// The ground's control variate at the ground point under unit
    /// `normal` ([`crate::render::ground_sky`]), where the plan has it.
    pub(super) fn ground_sky(
        &self,
        normal: DVec3,
        lanes: &SpectralLanes,
    ) -> Option<GroundSkyAt<'a>> {
        self.ground_sky?.at(self.medium, normal, lanes)
    }

    /// Adds the control's exact part for a bounce of weight `weight` (the
    /// bounce's, albedo included, before its direction's factor):
    /// weight × ∫ (1/π) L̃ cos dω, whatever direction the bounce then
    /// takes. The bounce's path must then carry L − L̃
    /// ([`Self::ground_sky_out`]).
    pub(super) fn ground_sky_in(
        at: Option<&GroundSkyAt<'_>>,
        weight: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
    ) {
        if let Some(at) = at {
            radiance.total += *weight * at.irradiance() * lanes.sun_irradiance / PI;
        }
    }

    /// Takes L̃ along `bounce` out of a bounce's path of weight `weight`
    /// (the direction's factor included): the path going on estimates
    /// L − L̃.
    pub(super) fn ground_sky_out(
        at: Option<&GroundSkyAt<'_>>,
        bounce: DVec3,
        weight: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
    ) {
        if let Some(at) = at {
            radiance.total -= *weight * at.radiance(bounce) * lanes.sun_irradiance;
        }
    }

    /// The sky guide at the ground point under unit `normal`, where the
    /// plan draws bounce directions from it (`ground_guide`) and it has
    /// light to guide toward.
    pub(super) fn bounce_guide(&self, normal: DVec3) -> Option<GuideAt<'a>> {
        self.guide
            .filter(|_| self.plan.directions.ground_guide > 0.0)
            .map(|g| g.at(self.medium, ground_point(self.medium, normal)))
            .filter(GuideAt::guides)
    }

    /// A bounce direction off the ground under unit `normal` and the
    /// factor cos/(π pdf) it carries (1 for a cosine-weighted one), or
    /// `None` where it points into the ground (the Lambertian kernel is
    /// zero there, so ending the path adds exactly what it would).
    ///
    /// With `ground_guide` = g > 0 the direction comes from the sky
    /// guide's table at the ground point with probability g, else from the
    /// cosine density, and carries the mixture's density (one-sample MIS,
    /// balance heuristic; Veach 1997, §9.2.4): pdf = (1 − g) cos/π +
    /// g p_guide. With the sun low, the light reaching the ground comes
    /// mostly from a band of sky a few degrees high over the sun's azimuth,
    /// where the cosine density is smallest; the guide's table of
    /// once-scattered light holds that band.
    ///
    /// `guide` is [`Self::bounce_guide`] at the same ground point, looked
    /// up once for all the bounces that leave it.
    pub(super) fn bounce_direction(
        &self,
        normal: DVec3,
        guide: Option<&GuideAt<'_>>,
        rng: &mut Rng,
    ) -> Option<(DVec3, f64)> {
        let share = self.plan.directions.ground_guide;
        let Some(at) = guide else {
            return Some((cosine_sample_hemisphere(normal, rng), 1.0));
        };
        let bounce = if rng.uniform() < share {
            at.sample(rng).0
        } else {
            cosine_sample_hemisphere(normal, rng)
        };
        let cos = normal.dot(bounce);
        if cos <= 0.0 {
            return None;
        }
        let pdf = (1.0 - share) * cos / PI + share * at.pdf(bounce);
        Some((bounce, cos / PI / pdf))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Renderer;
    use crate::scene::Scene;

    /// Mean and variance of `n` ground-light estimates (sum over lanes)
    /// under the observer of `preset`, with the ground's control or
    /// without.
    fn ground_light_stats(preset: &str, control: bool, n: usize) -> (f64, f64) {
        let mut scene = Scene::preset(preset).unwrap();
        scene.render.integrator.ground_control = Some(control);
        let renderer = Renderer::new(&scene).unwrap();
        let integrator = renderer.integrator(1);
        assert_eq!(integrator.ground_sky.is_some(), control, "{preset}");
        let (lanes, _) = renderer.sample_lanes(0.37);
        let normal = renderer.observer_m.normalize();
        let mut rng = Rng::new(7, u64::from(control));
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let light = integrator.ground_light(normal, &lanes, &mut rng);
            let v: f64 = light[..lanes.active].iter().sum();
            sum += v;
            sum2 += v * v;
        }
        let mean = sum / n as f64;
        (mean, sum2 / n as f64 - mean * mean)
    }

    #[test]
    fn the_grounds_control_keeps_its_mean_and_cuts_its_variance() {
        // The same ground light estimated with and without the model's
        // skylight as the control: the means agree within their standard
        // errors; by day the control takes out the direction's share of
        // the variance (about half of it at 45°, a third at 20°), with the
        // sun low little (0.91 at 2°).
        for (preset, most) in [("midday", 0.6), ("afternoon", 0.75), ("sunset", 1.0)] {
            let n = 40_000;
            let (plain, plain_var) = ground_light_stats(preset, false, n);
            let (controlled, controlled_var) = ground_light_stats(preset, true, n);
            let se = ((plain_var + controlled_var) / n as f64).sqrt();
            assert!(
                (plain - controlled).abs() < 4.0 * se,
                "{preset}: {controlled} with the control against {plain} ± {se}"
            );
            let ratio = controlled_var / plain_var;
            assert!(ratio < most, "{preset}: variance ratio {ratio}");
        }
    }
}
