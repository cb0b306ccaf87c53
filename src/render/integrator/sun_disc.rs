//! The Sun as a light: directions within its disc, its irradiance and
//! radiance per lane, and the transmittance of shadow rays toward it.

use super::{sin_cos_turns, sun, DVec3, Integrator, Lanes, Rng, SpectralLanes};

impl Integrator<'_> {
    /// Uniform direction within the solar disc's cone. Unit without
    /// normalising: the frame is orthonormal and sin² + cos² = 1 to within
    /// 1e-15 (a square root and a division saved on every next-event
    /// estimate).
    pub(super) fn sample_sun_direction(&self, rng: &mut Rng) -> DVec3 {
        let cos_theta = 1.0 - rng.uniform() * (1.0 - self.cos_sun_radius);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let (sin_phi, cos_phi) = sin_cos_turns(rng.uniform());
        let (t, b) = self.sun_frame;
        t * (sin_theta * cos_phi) + b * (sin_theta * sin_phi) + self.sun_direction * cos_theta
    }

    /// The solar irradiance per lane that a next-event estimate along
    /// `to_sun`, drawn uniformly in the disc's cone
    /// ([`Self::sample_sun_direction`]), carries: E × L(μ)/L̄, the disc's
    /// radiance there over its mean ([`sun::radiance_over_mean`]). Its mean
    /// over the cone is E, so the estimate of a limb-darkened disc stays
    /// unbiased; for a uniform disc the factor is exactly 1.
    pub(super) fn sun_irradiance_toward(&self, to_sun: DVec3, lanes: &SpectralLanes) -> Lanes {
        let mu = sun::disc_mu(to_sun.dot(self.sun_direction), self.cos_sun_radius);
        Lanes::from_fn(|j| lanes.sun_irradiance[j] * sun::polynomial(&lanes.limb[j], mu))
    }

    /// Solar radiance per lane along `dir`, a direction within the disc:
    /// E / Ω × L(μ)/L̄ (E / Ω for a uniform disc).
    pub(super) fn sun_radiance(&self, dir: DVec3, lanes: &SpectralLanes) -> Lanes {
        self.sun_irradiance_toward(dir, lanes)
            .map(|e| e / self.sun_solid_angle_sr)
    }

    pub(super) fn shadow(
        &self,
        origin: DVec3,
        dir: DVec3,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Lanes {
        self.medium.transmittance(
            origin,
            dir,
            lanes,
            self.plan.segments.shadow_transmittance,
            self.bounds,
            rng,
        )
    }
}
