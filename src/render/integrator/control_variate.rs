//! The once-scattered light as a control variate at a path's scatterings:
//! the table's expansions at a point and the exact phase-function integral
//! they add (the table's cells are filled by [`crate::render::tables`]).

use super::{
    ground_point, rayleigh, ControlAt, DVec3, Integrator, Lanes, Light, Rng, SpectralLanes, LANES,
};
use crate::plan::ControlSource;

impl<'a> Integrator<'a> {
    /// The control variate at a scattering point `x` for `lanes`, if on.
    pub(super) fn control_at(
        &self,
        x: DVec3,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<ControlAt<'a>> {
        let table = self.control?;
        let u = (rng.uniform(), rng.uniform());
        let picked = table.pick(x, &lanes.wavelengths_nm, u, (self.medium, self.guide));
        Some(ControlAt {
            frame: table.frame(x),
            picked,
        })
    }

    /// Adds beta × ∫ σ_s p(dir·ω') A(ω') dω' for a path along `dir` that
    /// scatters at the point of `at` (coefficients `c`) with weight `beta`
    /// before its direction's factor: Σ_l (σ_R k_l^R + σ_A k_l^A) Σ_m a_lm
    /// Y_lm(dir), exact by the Funk–Hecke theorem.
    pub(super) fn control_in(
        &self,
        at: &ControlAt<'_>,
        c: &crate::render::medium::Coefficients,
        lanes: &SpectralLanes,
        dir: DVec3,
        beta: &Lanes,
        radiance: &mut Light,
    ) {
        let y = at.frame.basis(dir);
        let degrees = at.picked.degrees(&y);
        for j in 0..LANES {
            let rayleigh_k2 = rayleigh::phase_legendre_2(lanes.rayleigh_gamma[j]);
            let aerosol: f64 = self
                .aerosol_moments
                .at(lanes.wavelengths_nm[j])
                .iter()
                .zip(&degrees)
                .map(|(k, d)| k * d[j])
                .sum();
            let sum = c.rayleigh[j] * (degrees[0][j] + rayleigh_k2 * degrees[2][j])
                + c.aerosol_scattering[j] * aerosol;
            radiance[j] += beta[j] * lanes.sun_irradiance[j] * sum;
        }
    }

    /// The control variate at a ground bounce under unit `normal` along
    /// `bounce` with weight `beta` (the bounce's, albedo included), where
    /// the control's approximation is the model's light of every order
    /// ([`crate::plan::ControlSource::Model`]): adds beta × ∫ f(n·ω) A(ω) dω
    /// with f the Lambertian kernel max(μ, 0)/π ([`crate::render::control::lambert_moments`], exact
    /// by the Funk–Hecke theorem) and subtracts beta × A(bounce), so the path
    /// going on estimates only L − A. The sky's light on the ground varies
    /// by an order of magnitude over the hemisphere at low sun; the model
    /// follows it, which leaves the bounce's direction little to find.
    pub(super) fn ground_control(
        &self,
        normal: DVec3,
        bounce: DVec3,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        if self.plan.control_source != ControlSource::Model {
            return;
        }
        let Some(at) = self.control_at(ground_point(self.medium, normal), lanes, rng) else {
            return;
        };
        let degrees = at.picked.degrees(&at.frame.basis(normal));
        let reflected = Lanes::from_fn(|j| {
            self.lambert
                .iter()
                .zip(&degrees)
                .map(|(chi, d)| chi * d[j])
                .sum::<f64>()
        });
        radiance.total += *beta * lanes.sun_irradiance * reflected;
        at.subtract(lanes, bounce, beta, radiance);
    }
}
