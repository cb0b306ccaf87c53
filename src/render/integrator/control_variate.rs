//! The once-scattered light as a control variate at a path's scatterings:
//! the table's expansions at a point, the exact phase-function integral
//! they add, and the projection that fills a table cell.

use super::{
    rayleigh, CellCoefficients, ControlAt, DVec3, Integrator, Lanes, Light, RadianceTable, Rng,
    SpectralLanes, COEFFICIENTS, CONTROL_DIRECTIONS, CONTROL_SEED, LANES, NODES, PI,
};

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
        let picked = table.pick(x, &lanes.wavelengths_nm, u, |i, k| {
            self.project_cell(table, i, k)
        });
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

    /// The control's expansions for the table's cell (altitude `i`, solar
    /// zenith `k`): the once-scattered light (and the ground's direct
    /// reflection) arriving at the cell's central point, per unit
    /// irradiance at the table's wavelength nodes, projected on the basis
    /// from next-event estimates along [`CONTROL_DIRECTIONS`] stratified
    /// directions. Single scattering holds the sharp part of the light a
    /// point sees (the aureole, the horizon), which is what the control
    /// takes out of the paths (`BENCHMARKS.md`); the random
    /// numbers are the cell's own, so the table does not depend on the
    /// render's.
    pub(super) fn project_cell(
        &self,
        table: &RadianceTable,
        i: usize,
        k: usize,
    ) -> CellCoefficients {
        let plan = self.plan.for_control_table();
        let mut single = Integrator::new(self.medium, &plan, self.sun_direction);
        single.guide = self.guide;
        let origin = table.cell_point(i, k);
        let frame = table.frame(origin);
        let (nt, np) = CONTROL_DIRECTIONS;
        let weight = 4.0 * PI / (nt * np) as f64;
        let mut rng = Rng::new(CONTROL_SEED, (i * 1000 + k) as u64);
        let sets: Vec<SpectralLanes> = (0..NODES.div_ceil(LANES))
            .map(|set| {
                let nm = std::array::from_fn(|j| table.node_nm((set * LANES + j).min(NODES - 1)));
                SpectralLanes::new(Lanes::from(nm), LANES, self.medium, true)
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
                    let mut radiance = Light::default();
                    let from = (origin, dir, 1, 1.0);
                    if plan.segments.sunlight_samples > 0 && single.guide.is_some() {
                        single.trace_sunlit(
                            from,
                            Lanes::splat(1.0),
                            lanes,
                            &mut radiance,
                            &mut rng,
                        );
                    } else {
                        single.trace(from, Lanes::splat(1.0), lanes, &mut radiance, &mut rng);
                    }
                    for (j, l) in radiance.total.iter().enumerate() {
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
