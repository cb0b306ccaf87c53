//! Scattering directions: the phase functions about the path's and the
//! sun's directions, mixed with the sky guide's table, and the mixture's
//! density.

use super::{
    orthonormal_basis, rayleigh, sin_cos_turns, DVec3, GuideAt, Integrator, Rng, SpectralLanes,
};

impl<'a> Integrator<'a> {
    /// The guide at `x` where it draws scattering directions there
    /// ([`crate::plan::IntegratorOptions::sky_guide`], at sunlit points only with
    /// [`crate::plan::IntegratorOptions::sky_guide_sunlit`]).
    pub(super) fn direction_guide(&self, x: DVec3) -> Option<GuideAt<'a>> {
        let opts = self.plan;
        self.guide
            .filter(|g| {
                opts.directions.sky_guide > 0.0
                    && (opts.directions.sky_guide_sunlit || g.shadowed(x))
            })
            .map(|g| g.at(self.medium, x))
    }

    /// Density (sr⁻¹) of `dir` under the scattering directions' mixture:
    /// `phase` (the phase-function part's density, already evaluated),
    /// mixed with the lobe about the sun ([`crate::plan::IntegratorOptions::sun_lobe`])
    /// and, where `guide` is given, the guide's table
    /// ([`crate::plan::IntegratorOptions::sky_guide`]).
    pub(super) fn direction_mixture_pdf(
        &self,
        c: &crate::render::medium::Coefficients,
        lanes: &SpectralLanes,
        dir: DVec3,
        phase: f64,
        guide: Option<&GuideAt<'_>>,
    ) -> f64 {
        let alpha = self.plan.directions.sun_lobe;
        let pdf = if alpha > 0.0 {
            let lobe = self.phase_mixture_pdf(c, lanes, self.sun_direction.dot(dir));
            (1.0 - alpha) * phase + alpha * lobe
        } else {
            phase
        };
        match guide {
            Some(guide) => {
                let g = self.plan.directions.sky_guide;
                (1.0 - g) * pdf + g * guide.pdf(dir)
            }
            None => pdf,
        }
    }

    /// A scattering direction and its density (per sr): with probability
    /// `sun_lobe`, from the phase function about the *sun's* direction, else
    /// about `dir`; the density is the mixture's (one-sample MIS, balance
    /// heuristic), and the guide at `x` where it was looked up (the segment
    /// from `x` reads its densities). Skylight arriving along ω is mostly sunlight scattered
    /// once somewhere along ω, always through the angle between ω and the
    /// sun, so its angular shape is that phase function P(ω·ω_sun) — the
    /// aureole by day, the glow over the hidden sun at twilight. The phase
    /// function of the point itself stands in for the unknown ones along ω.
    pub(super) fn sample_scatter_direction(
        &self,
        x: DVec3,
        dir: DVec3,
        c: &crate::render::medium::Coefficients,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> (DVec3, f64, Option<GuideAt<'a>>) {
        let mut at = self.direction_guide(x);
        let guides = at.as_ref().is_some_and(GuideAt::guides);
        let g = if guides {
            self.plan.directions.sky_guide
        } else {
            0.0
        };
        let alpha = self.plan.directions.sun_lobe;
        let (new_dir, cell) = match at.as_ref() {
            Some(guide) if guides && rng.uniform() < g => {
                let (new_dir, cell) = guide.sample(rng);
                (new_dir, Some(cell))
            }
            _ if rng.uniform() < alpha => (
                self.sample_phase_direction(self.sun_direction, c, lanes, rng),
                None,
            ),
            _ => (self.sample_phase_direction(dir, c, lanes, rng), None),
        };
        if let Some(at) = at.as_mut() {
            at.choose(new_dir, cell);
        }
        let phase = self.phase_mixture_pdf(c, lanes, dir.dot(new_dir));
        let pdf =
            self.direction_mixture_pdf(c, lanes, new_dir, phase, at.as_ref().filter(|_| guides));
        (new_dir, pdf, at)
    }

    /// Sample a new direction from the lane-averaged phase function.
    pub(super) fn sample_phase_direction(
        &self,
        dir: DVec3,
        c: &crate::render::medium::Coefficients,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> DVec3 {
        let k = ((rng.uniform() * lanes.active as f64) as usize).min(lanes.active - 1);
        let mu = if rng.uniform() * c.scattering(k) < c.rayleigh[k] {
            rayleigh::sample_mu(rng.uniform(), lanes.rayleigh_gamma[k])
        } else {
            self.medium
                .aerosol_phase
                .sample(lanes.wavelengths_nm[k], || rng.uniform())
        };
        let (sin_phi, cos_phi) = sin_cos_turns(rng.uniform());
        let sin = (1.0 - mu * mu).max(0.0).sqrt();
        let (t, b) = orthonormal_basis(dir);
        (t * (sin * cos_phi) + b * (sin * sin_phi) + dir * mu).normalize()
    }
}
