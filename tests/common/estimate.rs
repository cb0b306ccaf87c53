//! What the estimator test files share: sample means with their standard
//! errors, and single scattering by quadrature.

use glam::DVec3;
use skyrender::atmosphere::Atmosphere;
use skyrender::render::{Lanes, Medium, SpectralLanes, LANES};
use skyrender::rng::Rng;

/// Mean and standard error of `n` samples of lane 0..LANES, path i drawing
/// from stream (`streams`, i): every call of a comparison passes its own
/// `streams`, so the two sides are independent and their standard errors
/// combine in quadrature (with shared streams the two sides of a comparison
/// are correlated, which `assert_agree`'s combined error does not know).
pub fn estimate(
    streams: u64,
    n: u32,
    mut sample: impl FnMut(&mut Rng) -> Lanes,
) -> ([f64; LANES], [f64; LANES]) {
    let mut sum = [0.0; LANES];
    let mut sum2 = [0.0; LANES];
    for i in 0..n {
        let mut rng = Rng::new(12_345 + streams, u64::from(i));
        let v = sample(&mut rng);
        for j in 0..LANES {
            sum[j] += v[j];
            sum2[j] += v[j] * v[j];
        }
    }
    let nf = f64::from(n);
    let mean = sum.map(|s| s / nf);
    let se = std::array::from_fn(|j| ((sum2[j] / nf - mean[j] * mean[j]).max(0.0) / nf).sqrt());
    (mean, se)
}

/// Lanes at `wavelengths` under a sun of unit irradiance.
pub fn unit_sun_lanes(medium: &Medium, wavelengths: [f64; LANES]) -> SpectralLanes {
    SpectralLanes::new(wavelengths, LANES, medium, true)
}

/// Single scattering by quadrature: L = ∫ T(0,s) σ_s(s) P(Θ) E T_sun(s) ds,
/// with every optical depth integrated by the midpoint rule on fine steps.
pub fn single_scattering_quadrature(
    atmosphere: &Atmosphere,
    origin: DVec3,
    view: DVec3,
    sun_dir: DVec3,
    wavelength_nm: f64,
) -> f64 {
    let medium = Medium::new(atmosphere);
    let extinction = |p: DVec3| {
        let h = p.length() - atmosphere.params.planet_radius_m;
        atmosphere.rayleigh_scattering_per_m(h, wavelength_nm)
            + atmosphere.ozone_absorption_per_m(h, wavelength_nm)
            + atmosphere.aerosol_extinction_per_m(h, wavelength_nm)
    };
    let optical_depth = |from: DVec3, dir: DVec3, length: f64, steps: usize| {
        let ds = length / steps as f64;
        (0..steps)
            .map(|i| extinction(from + dir * ((i as f64 + 0.5) * ds)) * ds)
            .sum::<f64>()
    };
    let span = medium.span(origin, view).unwrap();
    let steps = 4000u32;
    let ds = (span.t_exit - span.t_enter) / f64::from(steps);
    let mu = view.dot(sun_dir);
    let gamma = skyrender::physics::rayleigh::phase_gamma(wavelength_nm);
    let mut tau_view = 0.0;
    let mut radiance = 0.0;
    for i in 0..steps {
        let p = origin + view * (span.t_enter + (f64::from(i) + 0.5) * ds);
        let h = p.length() - atmosphere.params.planet_radius_m;
        let k = extinction(p);
        tau_view += 0.5 * k * ds;
        let sun_span = medium.span(p, sun_dir).unwrap();
        if !sun_span.hits_ground {
            let tau_sun = optical_depth(p, sun_dir, sun_span.t_exit, 400);
            let phase = atmosphere.rayleigh_scattering_per_m(h, wavelength_nm)
                * skyrender::physics::rayleigh::phase(mu, gamma)
                + atmosphere.aerosol_extinction_per_m(h, wavelength_nm)
                    * atmosphere.params.aerosol_albedo
                    * skyrender::physics::aerosol::henyey_greenstein(
                        mu,
                        atmosphere.params.aerosol_g,
                    );
            radiance += (-tau_view).exp() * phase * (-tau_sun).exp() * ds;
        }
        tau_view += 0.5 * k * ds;
    }
    radiance
}
