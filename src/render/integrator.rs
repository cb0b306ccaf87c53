//! The spectral path tracer: one camera path per call, several wavelengths
//! per path.
//!
//! **Estimator.** Along every ray segment a majorant process proposes
//! tentative collisions (delta tracking over shell-wise majorants; see
//! [`super::medium`]). At each tentative collision at distance t the
//! null-collision form of the radiative transfer equation,
//! L(x) = ∫ T̄(t) [σ_s L_s + σ_n L] dt + T̄ L_background (Galtier et al. 2013),
//! is estimated by
//! * next-event estimation toward the solar disc, weighted by σ_s/σ̄, at
//!   *every* tentative collision (the collision estimator for direct light),
//! * then a random choice between a real scattering event (probability P_s)
//!   and a null collision (1 − P_s), each weighted by its coefficient over
//!   σ̄ and its probability.
//!
//! Absorption never terminates a path; it only weights it. Russian roulette
//! ends paths without bias. Optionally, on camera rays the majorant is scaled
//! up so that at least a few collisions (and so next-event estimates) fall
//! along the ray where the air is dense ("forced" in-scattering samples).
//!
//! **Wavelengths.** Lanes carry hero-rotated wavelengths (Wilkie et al. 2014).
//! Every random decision (real vs. null, phase-function component and angle)
//! samples the *average* of the lanes' distributions, and each lane is
//! weighted by its own density over that average (a one-sample mixture / MIS
//! with the balance heuristic per decision), so every lane stays unbiased and
//! weights are bounded by the lane count.

use std::f64::consts::PI;

use glam::DVec3;

use super::medium::{Bounds, Lanes, Medium, SpectralLanes, TransmittanceEstimator, LANES};
use crate::physics::{rayleigh, sun};
use crate::rng::Rng;

/// Switches for the variance-reduction techniques (each defaults to the best;
/// the benchmark's ablation turns them off one at a time).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct IntegratorOptions {
    /// Wavelengths carried per path, 1–4.
    pub wavelengths_per_path: usize,
    /// Shell-wise (tight) majorants; `false` uses one majorant for the whole atmosphere.
    pub tight_majorants: bool,
    /// Transmittance estimator for shadow rays.
    pub shadow_transmittance: TransmittanceEstimator,
    /// Next-event estimation toward the sun.
    pub next_event_estimation: bool,
    /// Minimum expected number of tentative collisions on camera rays (0 = off,
    /// the default: the benchmark's ablation found it costs more time than it
    /// saves variance except at midday; see BENCHMARKS.md).
    pub primary_min_collisions: f64,
    /// Russian roulette after the second scattering event.
    pub russian_roulette: bool,
    /// Keep only scattering orders up to this (for tests of single scattering;
    /// `None` = all orders, the unbiased default).
    pub max_scattering_order: Option<u32>,
}

impl Default for IntegratorOptions {
    fn default() -> Self {
        Self {
            wavelengths_per_path: LANES,
            tight_majorants: true,
            shadow_transmittance: TransmittanceEstimator::ResidualRatioTracking,
            next_event_estimation: true,
            primary_min_collisions: 0.0,
            russian_roulette: true,
            max_scattering_order: None,
        }
    }
}

/// Radiance estimate per lane (W m⁻² sr⁻¹ nm⁻¹, or per unit irradiance).
pub type Radiance = Lanes;

/// Scattering vertices become paths longer than this only through Russian
/// roulette with survival ≤ 0.9, so paths end with probability one.
const ROULETTE_CAP_DEPTH: u32 = 64;
/// Ground vertices sit this far above the surface, m.
const SURFACE_OFFSET_M: f64 = 1e-3;

/// Everything the integrator needs about one scene.
pub struct Integrator<'a> {
    pub medium: &'a Medium,
    pub options: &'a IntegratorOptions,
    pub sun_direction: DVec3,
    cos_sun_radius: f64,
    sun_solid_angle_sr: f64,
    sun_frame: (DVec3, DVec3),
    bounds: Bounds,
}

impl<'a> Integrator<'a> {
    pub fn new(medium: &'a Medium, options: &'a IntegratorOptions, sun_direction: DVec3) -> Self {
        Self {
            medium,
            options,
            sun_direction,
            cos_sun_radius: sun::ANGULAR_RADIUS_DEG.to_radians().cos(),
            sun_solid_angle_sr: sun::solid_angle_sr(),
            sun_frame: orthonormal_basis(sun_direction),
            bounds: if options.tight_majorants {
                Bounds::Tight
            } else {
                Bounds::Global
            },
        }
    }

    /// Uniform direction within the solar disc's cone.
    fn sample_sun_direction(&self, rng: &mut Rng) -> DVec3 {
        let cos_theta = 1.0 - rng.uniform() * (1.0 - self.cos_sun_radius);
        let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
        let phi = 2.0 * PI * rng.uniform();
        let (t, b) = self.sun_frame;
        (t * (sin_theta * phi.cos()) + b * (sin_theta * phi.sin()) + self.sun_direction * cos_theta)
            .normalize()
    }

    /// Solar radiance per lane (uniform disc: E / Ω).
    fn sun_radiance(&self, lanes: &SpectralLanes) -> Lanes {
        lanes.sun_irradiance.map(|e| e / self.sun_solid_angle_sr)
    }

    fn shadow(&self, origin: DVec3, dir: DVec3, lanes: &SpectralLanes, rng: &mut Rng) -> Lanes {
        self.medium.transmittance(
            origin,
            dir,
            lanes,
            self.options.shadow_transmittance,
            self.bounds,
            rng,
        )
    }

    /// Phase function of lane `j` times σ_s (i.e. σ_s,R P_R + σ_s,A P_A), per sr.
    fn scattering_phase(
        &self,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        j: usize,
        mu: f64,
    ) -> f64 {
        c.rayleigh[j] * rayleigh::phase(mu, lanes.rayleigh_gamma[j])
            + c.aerosol_scattering[j] * self.medium.aerosol_phase.eval(mu, self.medium.aerosol_g)
    }

    /// Radiance arriving at `origin` from direction `-dir` (i.e. looking along `dir`).
    pub fn radiance(
        &self,
        origin: DVec3,
        dir: DVec3,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Radiance {
        let active = lanes.active;
        let inv_active = 1.0 / active as f64;
        let opts = self.options;
        let mut beta: Lanes = [1.0; LANES];
        let mut radiance: Lanes = [0.0; LANES];
        let mut origin = origin;
        let mut dir = dir;
        let mut depth: u32 = 0;
        let max_order = opts.max_scattering_order.unwrap_or(u32::MAX);

        loop {
            let mut scattered = false;
            if let Some(span) = self.medium.span(origin, dir) {
                let mut tracker = self
                    .medium
                    .tracker(origin, dir, span, lanes, self.bounds, 0.0);
                if depth == 0 && opts.primary_min_collisions > 0.0 {
                    tracker = tracker.inflate_sunlit(
                        origin,
                        dir,
                        self.sun_direction,
                        opts.primary_min_collisions,
                    );
                }
                while let Some(collision) = tracker.next(rng) {
                    let x = origin + dir * collision.t;
                    let c = self.medium.coefficients(x.length(), lanes);
                    let majorant = collision.majorant;
                    // A next-event estimate at a vertex after `depth` real
                    // scatterings adds scattering order depth + 1.
                    if opts.next_event_estimation && depth < max_order {
                        let to_sun = self.sample_sun_direction(rng);
                        let mu = dir.dot(to_sun);
                        let tr = self.shadow(x, to_sun, lanes, rng);
                        for j in 0..LANES {
                            radiance[j] += beta[j] * self.scattering_phase(&c, lanes, j, mu)
                                / majorant
                                * lanes.sun_irradiance[j]
                                * tr[j];
                        }
                    }
                    if depth + 1 >= max_order {
                        // Only lower orders wanted: continue as if null.
                        for (j, b) in beta.iter_mut().enumerate() {
                            *b *= 1.0 - c.extinction(j) / majorant;
                        }
                        continue;
                    }
                    // Real scattering vs. null collision, sampled from the lane average.
                    let p_scatter = (0..active)
                        .map(|j| c.scattering(j) / (majorant - c.absorption[j]).max(1e-300))
                        .sum::<f64>()
                        * inv_active;
                    let p_scatter = p_scatter.clamp(0.0, 1.0);
                    if rng.uniform() < p_scatter {
                        let new_dir = self.sample_phase_direction(dir, &c, lanes, rng);
                        let mu = dir.dot(new_dir);
                        let pdf = (0..active)
                            .map(|k| self.scattering_phase(&c, lanes, k, mu) / c.scattering(k))
                            .sum::<f64>()
                            * inv_active;
                        for (j, b) in beta.iter_mut().enumerate() {
                            *b *= self.scattering_phase(&c, lanes, j, mu)
                                / (majorant * p_scatter * pdf);
                        }
                        origin = x;
                        dir = new_dir;
                        depth += 1;
                        scattered = true;
                        break;
                    }
                    for (j, b) in beta.iter_mut().enumerate() {
                        *b *= (majorant - c.extinction(j)) / (majorant * (1.0 - p_scatter));
                    }
                }
                if !scattered && span.hits_ground {
                    let normal = (origin + dir * span.t_exit).normalize();
                    let x = normal * (self.medium.planet_radius_m + SURFACE_OFFSET_M);
                    let albedo = self.medium.ground_albedo;
                    if opts.next_event_estimation && depth < max_order {
                        let to_sun = self.sample_sun_direction(rng);
                        let cos = normal.dot(to_sun);
                        if cos > 0.0 {
                            let tr = self.shadow(x, to_sun, lanes, rng);
                            for j in 0..LANES {
                                radiance[j] +=
                                    beta[j] * albedo / PI * cos * lanes.sun_irradiance[j] * tr[j];
                            }
                        }
                    }
                    if depth + 1 >= max_order || albedo <= 0.0 {
                        break;
                    }
                    // Cosine-weighted bounce: the Lambertian BRDF·cos/pdf = albedo.
                    for b in &mut beta {
                        *b *= albedo;
                    }
                    origin = x;
                    dir = cosine_sample_hemisphere(normal, rng);
                    depth += 1;
                    scattered = true;
                }
            }
            if !scattered {
                // Escaped to space. The disc is counted here only where no
                // next-event estimate already accounted for it.
                if (depth == 0 || !opts.next_event_estimation)
                    && dir.dot(self.sun_direction) >= self.cos_sun_radius
                {
                    let l_sun = self.sun_radiance(lanes);
                    for j in 0..LANES {
                        radiance[j] += beta[j] * l_sun[j];
                    }
                }
                break;
            }
            // Russian roulette on the largest lane weight.
            if opts.russian_roulette && depth >= 2 {
                let mut survive = beta[..active].iter().copied().fold(0.0, f64::max).min(1.0);
                if depth >= ROULETTE_CAP_DEPTH {
                    survive = survive.min(0.9);
                }
                if rng.uniform() >= survive {
                    break;
                }
                for b in &mut beta {
                    *b /= survive;
                }
            } else if beta[..active].iter().all(|&b| b == 0.0) {
                break;
            }
        }
        radiance
    }

    /// Sample a new direction from the lane-averaged phase function.
    fn sample_phase_direction(
        &self,
        dir: DVec3,
        c: &super::medium::Coefficients,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> DVec3 {
        let k = ((rng.uniform() * lanes.active as f64) as usize).min(lanes.active - 1);
        let mu = if rng.uniform() * c.scattering(k) < c.rayleigh[k] {
            rayleigh::sample_mu(rng.uniform(), lanes.rayleigh_gamma[k])
        } else {
            self.medium
                .aerosol_phase
                .sample(self.medium.aerosol_g, || rng.uniform())
        };
        let phi = 2.0 * PI * rng.uniform();
        let sin = (1.0 - mu * mu).max(0.0).sqrt();
        let (t, b) = orthonormal_basis(dir);
        (t * (sin * phi.cos()) + b * (sin * phi.sin()) + dir * mu).normalize()
    }
}

/// Two unit vectors completing `n` to a right-handed orthonormal basis
/// (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// Cosine-weighted direction about `normal` (Malley's method).
fn cosine_sample_hemisphere(normal: DVec3, rng: &mut Rng) -> DVec3 {
    let r = rng.uniform().sqrt();
    let phi = 2.0 * PI * rng.uniform();
    let z = (1.0 - r * r).max(0.0).sqrt();
    let (t, b) = orthonormal_basis(normal);
    (t * (r * phi.cos()) + b * (r * phi.sin()) + normal * z).normalize()
}
