//! The radiance probe: the spectral radiance reaching the observer from
//! one direction, wavelength by wavelength, with its Monte Carlo standard
//! error — the reference the images are checked against, and the app's
//! spectrum readout.

use rayon::prelude::*;

use super::{direction_from_az_el, solar_source, Lanes, Renderer, SpectralLanes, LANES};
use crate::rng::Rng;

/// One spectral radiance estimate with its Monte Carlo standard error.
#[derive(Clone, Copy, Debug, serde::Serialize)]
pub struct SpectralEstimate {
    /// The wavelength, nm.
    pub wavelength_nm: f64,
    /// Spectral radiance, W m⁻² sr⁻¹ nm⁻¹ (or per unit irradiance).
    pub radiance: f64,
    /// Its Monte Carlo standard error.
    pub std_error: f64,
    /// Paths whose estimate was not finite (or negative where no estimate
    /// may be, `Integrator::signed_estimates`): counted as 0,
    /// like a discarded pixel sample.
    pub discarded: u64,
}

/// Which light a probe estimates, as the image's layers split it
/// ([`super::film_layers`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ProbeLight {
    /// All the light (the beauty image).
    All,
    /// The sun's disc seen straight along the ray (the `sun` layer).
    SunDisc,
    /// All but the disc (the `sky` layer, or the `ground` layer where the
    /// ray meets the ground).
    WithoutSunDisc,
}

impl Renderer {
    /// Spectral radiance reaching the observer from (`view_zenith_deg`,
    /// `view_azimuth_deg`) at each wavelength, W m⁻² sr⁻¹ nm⁻¹ (or per unit
    /// irradiance with a unit sun), from `samples` paths each.
    pub fn probe_radiance(
        &self,
        view_zenith_deg: f64,
        view_azimuth_deg: f64,
        wavelengths_nm: &[f64],
        samples: u32,
    ) -> Vec<SpectralEstimate> {
        self.probe_light(
            view_zenith_deg,
            view_azimuth_deg,
            wavelengths_nm,
            samples,
            ProbeLight::All,
        )
    }

    /// [`Self::probe_radiance`] of the part `light` of the light, from the
    /// same paths as the whole.
    pub fn probe_light(
        &self,
        view_zenith_deg: f64,
        view_azimuth_deg: f64,
        wavelengths_nm: &[f64],
        samples: u32,
        light: ProbeLight,
    ) -> Vec<SpectralEstimate> {
        let dir = direction_from_az_el(view_azimuth_deg, 90.0 - view_zenith_deg);
        // Any pass but the first: the scene's own options.
        let integrator = self.integrator(1);
        let signed = integrator.signed_estimates();
        // Once per probe: with a date it runs the solar position algorithm.
        let source = solar_source(&self.scene);
        wavelengths_nm
            .par_chunks(LANES)
            .enumerate()
            .flat_map_iter(|(chunk_index, chunk)| {
                let mut lane_wavelengths = [chunk[0]; LANES];
                lane_wavelengths[..chunk.len()].copy_from_slice(chunk);
                let lanes = SpectralLanes::with_source(
                    Lanes::from(lane_wavelengths),
                    chunk.len(),
                    &self.medium,
                    &source,
                );
                let mut sum = Lanes::splat(0.0);
                let mut sum2 = Lanes::splat(0.0);
                let mut discarded = [0u64; LANES];
                for s in 0..samples {
                    let mut rng =
                        Rng::for_sample(self.scene.render.seed, u64::from(s), chunk_index as u64);
                    let path = integrator.light(self.observer_m, dir, &lanes, &mut rng);
                    let l: Lanes = match light {
                        ProbeLight::All => path.total,
                        ProbeLight::SunDisc => path.disc,
                        ProbeLight::WithoutSunDisc => path.total - path.disc,
                    };
                    for j in 0..LANES {
                        let v = if l[j].is_finite() && (signed || l[j] >= 0.0) {
                            l[j]
                        } else {
                            discarded[j] += 1;
                            0.0
                        };
                        sum[j] += v;
                        sum2[j] += v * v;
                    }
                }
                let n = f64::from(samples);
                chunk
                    .iter()
                    .enumerate()
                    .map(|(j, &w)| {
                        let mean = sum[j] / n;
                        let var = (sum2[j] / n - mean * mean).max(0.0) * n / (n - 1.0).max(1.0);
                        SpectralEstimate {
                            wavelength_nm: w,
                            radiance: mean,
                            std_error: (var / n).sqrt(),
                            discarded: discarded[j],
                        }
                    })
                    .collect::<Vec<_>>()
            })
            .collect()
    }
}
