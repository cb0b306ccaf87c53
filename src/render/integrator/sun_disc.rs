//! The Sun as a light: directions within its disc, its irradiance and
//! radiance per lane, and the transmittance of shadow rays toward it.

use super::{sin_cos_turns, sun, DVec3, Integrator, Lanes, Rng, SpectralLanes};
use crate::render::debias;
use crate::render::sunlight::sun_optical_depth;

/// The share q of the sun's shadow rays that also take the tracked
/// estimate and correct the table's T̃ ([`debias`]). On the rays that
/// climb from their point the table is within 3 % of T and the tracking's
/// own spread is ≤ 8 % where T > 10⁻⁴ (the tests below), so the
/// correction adds a relative variance of at most (0.08² + 0.03²)/q ≈ 0.12
/// to an estimate that multiplies a path's light; 1/8 and 1/32 measured no
/// better at sunset and midday (`BENCHMARKS.md`).
const SUN_CORRECTED_SHARE: f64 = 0.0625;

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

    /// The transmittance from `origin` along `dir` (within the sun's disc)
    /// to the top of the atmosphere, unbiased. With the plan's
    /// `sun_transmittance_table`, on a ray that climbs from `origin`, the
    /// table of columns toward the sun gives T̃, and a share
    /// [`SUN_CORRECTED_SHARE`] of the calls (`rng`'s next number) corrects it
    /// by the tracked estimate ([`debias`]); otherwise the tracked estimate
    /// alone.
    pub(super) fn shadow(
        &self,
        origin: DVec3,
        dir: DVec3,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Lanes {
        let exact = |rng: &mut Rng| {
            self.medium.transmittance(
                origin,
                dir,
                lanes,
                self.plan.segments.shadow_transmittance,
                self.bounds,
                rng,
            )
        };
        // Rays that descend from their point pass lower down, toward a
        // perigee the table's coordinates (the point's altitude and the
        // ray's cosine) place steeply: there its columns can be a few per
        // cent off where the optical depth is tens, and T̃ many times T.
        if !self.plan.sun_transmittance_table || origin.dot(dir) < 0.0 {
            return exact(rng);
        }
        let approx = self
            .medium
            .sun_columns()
            .at(origin, dir)
            .map_or(Lanes::splat(0.0), |columns| {
                Lanes::from_fn(|j| (-sun_optical_depth(lanes, j, columns)).exp())
            });
        debias::corrected(approx, SUN_CORRECTED_SHARE, rng, exact)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::plan::{Conditions, IntegratorOptions, TechniquePlan, TransmittanceEstimator};
    use crate::render::debias::mean_and_error;
    use crate::render::direction_from_az_el;
    use crate::render::medium::{Bounds, Medium, LANES};

    /// The plan for the sun `elevation_deg` up, with `table` for the
    /// shadow rays toward it.
    fn plan(elevation_deg: f64, table: bool) -> TechniquePlan {
        let options = IntegratorOptions {
            sun_transmittance_table: table,
            ..IntegratorOptions::default()
        };
        TechniquePlan::new(
            &options,
            &Conditions::new(elevation_deg, &AtmosphereParams::default(), true),
        )
    }

    /// Points at several altitudes, each in four directions from the
    /// observer's vertical and at five distances, brought back to their
    /// altitude: near the sun, across it and away from it, some of them
    /// in the planet's shadow at low sun.
    fn points(medium: &Medium) -> Vec<DVec3> {
        let mut list = Vec::new();
        for altitude_m in [10.0, 500.0, 2_000.0, 5_000.0, 20_000.0, 40_000.0] {
            let r = medium.planet_radius_m + altitude_m;
            for azimuth_deg in [270.0, 240.0, 180.0, 90.0] {
                let dir = direction_from_az_el(azimuth_deg, 0.0);
                for distance_m in [1e3, 30e3, 100e3, 300e3, 600e3] {
                    let x = DVec3::new(0.0, 0.0, r) + dir * distance_m;
                    list.push(x.normalize() * r);
                }
            }
        }
        list
    }

    /// On the rays that climb from their point (the ones that read it) the
    /// table's T̃ is within 3 % of the
    /// tracked estimate's mean wherever T > 10⁻³, and that estimate's own
    /// spread is ≤ 8 % wherever T > 10⁻⁴ (10 % where T > 10⁻⁵): the
    /// correction's variance, (Var T̂ + (T − T̃)²)/q, stays about 0.1 T² at
    /// q = 1/16 ([`SUN_CORRECTED_SHARE`]'s argument).
    #[test]
    fn the_sun_table_follows_the_tracked_estimate() {
        let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
        let lanes = SpectralLanes::new(Lanes::from([400.0, 500.0, 600.0, 700.0]), 4, &medium, true);
        for elevation_deg in [-4.0, 2.0, 45.0] {
            let plan = plan(elevation_deg, true);
            let sun = direction_from_az_el(270.0, elevation_deg);
            for x in points(&medium).into_iter().filter(|x| x.dot(sun) >= 0.0) {
                let Some(columns) = medium.sun_columns().at(x, sun) else {
                    continue;
                };
                let (exact, error) = mean_and_error(2000, |k| {
                    medium.transmittance(
                        x,
                        sun,
                        &lanes,
                        plan.segments.shadow_transmittance,
                        Bounds::Tight,
                        &mut Rng::new(3, k),
                    )
                });
                for j in 0..LANES {
                    let approx = (-sun_optical_depth(&lanes, j, columns)).exp();
                    let at = format!("{elevation_deg}°, {x}, lane {j}: {approx} {}", exact[j]);
                    if exact[j] > 1e-3 {
                        assert!((approx / exact[j] - 1.0).abs() < 0.03, "{at}");
                    }
                    if exact[j] > 1e-5 {
                        let spread = error[j] * 2000f64.sqrt() / exact[j];
                        let most = if exact[j] > 1e-4 { 0.08 } else { 0.1 };
                        assert!(spread < most, "{at}: spread {spread}");
                    }
                }
            }
        }
    }

    /// The corrected shadow rays' mean agrees with the tracked estimate's
    /// within four standard errors at every point, in and out of the
    /// planet's shadow, with directions anywhere in the sun's disc.
    #[test]
    fn the_corrected_shadow_rays_are_unbiased() {
        let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
        let lanes = SpectralLanes::new(Lanes::from([420.0, 510.0, 590.0, 680.0]), 4, &medium, true);
        for elevation_deg in [-4.0, 0.5, 2.0, 45.0] {
            let (with, without) = (plan(elevation_deg, true), plan(elevation_deg, false));
            assert!(with.sun_transmittance_table && !without.sun_transmittance_table);
            let sun = direction_from_az_el(270.0, elevation_deg);
            let table = Integrator::new(&medium, &with, sun);
            let tracked = Integrator::new(&medium, &without, sun);
            let n = 40_000;
            for x in points(&medium) {
                let draw = |integrator: &Integrator<'_>, seed: u64| {
                    mean_and_error(n, |k| {
                        let mut rng = Rng::new(seed, k);
                        let to_sun = integrator.sample_sun_direction(&mut rng);
                        integrator.shadow(x, to_sun, &lanes, &mut rng)
                    })
                };
                let (a, ea) = draw(&table, 11);
                let (b, eb) = draw(&tracked, 12);
                for j in 0..LANES {
                    let se = ea[j].hypot(eb[j]);
                    assert!(
                        (a[j] - b[j]).abs() <= 4.0 * se + 1e-300,
                        "{elevation_deg}°, {x}, lane {j}: {} against {} (SE {se})",
                        a[j],
                        b[j]
                    );
                }
            }
        }
    }

    /// A corrected shadow ray is negative where the tracked T̂ falls below
    /// (1 − q) T̃ on a corrected call (T̃ + (T̂ − T̃)/q < 0), so an
    /// integrator reading the sun's table calls its estimates signed and
    /// the film keeps them: dropping the negative ones would raise the
    /// mean (from orbit, where no control variate makes them signed
    /// otherwise, one sample in about a million).
    #[test]
    fn corrected_shadow_rays_can_be_negative_so_the_estimates_are_signed() {
        let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
        let lanes = SpectralLanes::new(Lanes::from([420.0, 510.0, 590.0, 680.0]), 4, &medium, true);
        let sun = direction_from_az_el(270.0, 2.0);
        let (with, without) = (plan(2.0, true), plan(2.0, false));
        let table = Integrator::new(&medium, &with, sun);
        let mut negative = 0;
        for x in points(&medium) {
            for k in 0..2000 {
                let mut rng = Rng::new(5, k);
                let to_sun = table.sample_sun_direction(&mut rng);
                let t = table.shadow(x, to_sun, &lanes, &mut rng);
                negative += usize::from((0..LANES).any(|j| t[j] < 0.0));
            }
        }
        assert!(negative > 0);
        assert!(table.signed_estimates());
        assert!(!Integrator::new(&medium, &without, sun).signed_estimates());
    }

    /// On by default at every sun elevation, off in the draft pass, off
    /// where the options say so or choose another shadow estimator.
    #[test]
    fn the_plan_reads_the_sun_table_unless_told_not_to() {
        for elevation_deg in [-12.0, -4.0, 0.0, 2.0, 45.0, 90.0] {
            let default = TechniquePlan::new(
                &IntegratorOptions::default(),
                &Conditions::new(elevation_deg, &AtmosphereParams::default(), true),
            );
            assert!(default.sun_transmittance_table, "{elevation_deg}°");
            assert!(!default.first_pass().sun_transmittance_table);
            assert!(!plan(elevation_deg, false).sun_transmittance_table);
            for options in [
                IntegratorOptions {
                    shadow_transmittance: TransmittanceEstimator::RatioTracking,
                    ..IntegratorOptions::default()
                },
                IntegratorOptions {
                    tight_majorants: false,
                    ..IntegratorOptions::default()
                },
            ] {
                let conditions = Conditions::new(elevation_deg, &AtmosphereParams::default(), true);
                assert!(!TechniquePlan::new(&options, &conditions).sun_transmittance_table);
            }
        }
    }
}
