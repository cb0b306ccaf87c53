//! Where along a camera ray the light comes from: a sampling density for
//! in-scattering points that follows the *expected sunlight*, not the air.
//!
//! Delta tracking puts collisions where the air is dense. Looking up at
//! twilight, that is in the Earth's shadow, where no sunlight arrives; at
//! midday most camera rays toward the zenith see no collision at all. The
//! single-scattering integrand along a ray is
//!
//! f(t) = T(0, t) · σ_s(t) p(μ) · E_sun T_sun(x(t)),
//!
//! and the multiple-scattering one is close to T(0, t) σ_s(t) times a slowly
//! varying skylight. [`InScatterDistribution`] tabulates an approximation of
//! both on segments of the ray — the view transmittance from the midpoint
//! extinctions, the sun transmittance from [`SunColumns`] (column amounts of
//! air, ozone and aerosol toward the sun, over altitude × solar zenith) — and
//! samples distances from a piecewise-constant mixture of them, one component
//! per lane (balance heuristic over wavelengths). The approximations only
//! shape the density: every estimate uses the exact coefficients and an
//! unbiased transmittance estimate at the sampled point, and the density is
//! positive wherever the air scatters (the skylight component), so the
//! estimator stays unbiased whatever the table's error (Earth's penumbra,
//! refraction-free geometry, interpolation).

use glam::DVec3;

use super::medium::{Lanes, Medium, SpectralLanes, LANES};

/// Altitude nodes of the column table (square-root spacing: dense low down).
const ALTITUDE_NODES: usize = 64;
/// Solar-zenith nodes (square-root spacing from the horizon: dense where the
/// sun grazes).
const ZENITH_NODES: usize = 64;

/// Column amounts toward the sun: air molecules (m⁻²), ozone molecules (m⁻²)
/// and aerosol optical depth at 340 nm (× amount), from a point at a given
/// altitude for a given solar zenith angle, without refraction.
pub struct SunColumns {
    top_m: f64,
    planet_radius_m: f64,
    /// `[altitude][zenith] → [air, ozone, aerosol]`.
    columns: Vec<[f32; 3]>,
}

impl SunColumns {
    /// Integrates the medium's profiles along straight rays to the top
    /// (3-point Gauss–Legendre on every shell piece; a sampling aid only, so
    /// percent-level accuracy is plenty).
    pub fn new(medium: &Medium) -> Self {
        let planet_radius_m = medium.planet_radius_m;
        let top_m = medium.top_radius_m - planet_radius_m;
        let mut columns = Vec::with_capacity(ALTITUDE_NODES * ZENITH_NODES);
        for i in 0..ALTITUDE_NODES {
            let h = top_m * (i as f64 / (ALTITUDE_NODES - 1) as f64).powi(2);
            // Just inside the top, so the ray is in the atmosphere.
            let r = planet_radius_m + h.min(top_m - 1.0);
            let mu_horizon = horizon_cosine(planet_radius_m, r);
            for k in 0..ZENITH_NODES {
                let u = k as f64 / (ZENITH_NODES - 1) as f64;
                // Slightly above the horizon so the grazing ray clears the ground.
                let mu = (mu_horizon + (1.0 - mu_horizon) * u * u + 1e-9).min(1.0);
                let origin = DVec3::new(0.0, 0.0, r);
                let dir = DVec3::new((1.0 - mu * mu).max(0.0).sqrt(), 0.0, mu);
                columns.push(column_along(medium, origin, dir));
            }
        }
        Self {
            top_m,
            planet_radius_m,
            columns,
        }
    }

    /// Columns toward the sun from `x` (m, planet-centred) for the sun along
    /// `sun_direction`, or `None` where the planet hides the sun's centre.
    pub fn at(&self, x: DVec3, sun_direction: DVec3) -> Option<[f64; 3]> {
        let r = x.length();
        let mu = x.dot(sun_direction) / r;
        let r = r.clamp(self.planet_radius_m, self.planet_radius_m + self.top_m);
        let mu_horizon = horizon_cosine(self.planet_radius_m, r);
        if mu < mu_horizon {
            return None;
        }
        let a =
            ((r - self.planet_radius_m) / self.top_m).max(0.0).sqrt() * (ALTITUDE_NODES - 1) as f64;
        let z = ((mu - mu_horizon) / (1.0 - mu_horizon))
            .clamp(0.0, 1.0)
            .sqrt()
            * (ZENITH_NODES - 1) as f64;
        let (i, fa) = split(a, ALTITUDE_NODES);
        let (k, fz) = split(z, ZENITH_NODES);
        let at = |i: usize, k: usize| &self.columns[i * ZENITH_NODES + k];
        Some(std::array::from_fn(|c| {
            let lo = f64::from(at(i, k)[c]) * (1.0 - fz) + f64::from(at(i, k + 1)[c]) * fz;
            let hi = f64::from(at(i + 1, k)[c]) * (1.0 - fz) + f64::from(at(i + 1, k + 1)[c]) * fz;
            lo * (1.0 - fa) + hi * fa
        }))
    }
}

/// Cosine of the zenith angle of the geometric horizon at radius `r_m`.
fn horizon_cosine(planet_radius_m: f64, r_m: f64) -> f64 {
    -(1.0 - (planet_radius_m / r_m).powi(2)).max(0.0).sqrt()
}

/// Integer node below `x` and the fraction past it, for linear interpolation.
fn split(x: f64, nodes: usize) -> (usize, f64) {
    let i = (x as usize).min(nodes - 2);
    (i, (x - i as f64).clamp(0.0, 1.0))
}

fn column_along(medium: &Medium, origin: DVec3, dir: DVec3) -> [f32; 3] {
    // Gauss–Legendre nodes and weights on [−1, 1].
    const NODES: [(f64, f64); 3] = [
        (-0.774_596_669_241_483_4, 5.0 / 9.0),
        (0.0, 8.0 / 9.0),
        (0.774_596_669_241_483_4, 5.0 / 9.0),
    ];
    let mut sum = [0.0f64; 3];
    if let Some(span) = medium.span(origin, dir) {
        for (t0, t1) in medium.pieces(origin, dir, span) {
            let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
            for (x, w) in NODES {
                let d = medium.densities((origin + dir * (mid + half * x)).length());
                for c in 0..3 {
                    sum[c] += w * half * d[c];
                }
            }
        }
    }
    sum.map(|v| v as f32)
}

/// Most segments one camera ray is cut into.
const MAX_SEGMENTS: usize = 96;
/// Segments are cut finer than this optical depth (largest lane), so the
/// view transmittance varies little within one.
const SEGMENT_OPTICAL_DEPTH: f64 = 0.2;
/// Segments are cut shorter than this, m, so the sun's transmittance (which
/// changes across the Earth's shadow) is resolved along long grazing pieces.
const SEGMENT_LENGTH_M: f64 = 40_000.0;
/// Share of the skylight component (∝ σ_s T, positive wherever air scatters):
/// it guarantees unbiasedness and serves the multiple-scattering continuation.
const SKYLIGHT_SHARE: f64 = 0.3;

/// A piecewise-constant density of distances along one camera ray.
pub struct InScatterDistribution {
    /// Segment boundaries, m along the ray.
    t: [f64; MAX_SEGMENTS + 1],
    /// Cumulative probability at each boundary (cdf[0] = 0, cdf[n] = 1).
    cdf: [f64; MAX_SEGMENTS + 1],
    segments: usize,
    /// Approximate lane-averaged ∫ σ_s T dt and T(t_end).
    scattered: f64,
    transmitted: f64,
}

impl InScatterDistribution {
    /// Builds the density for the ray `origin + t·dir` over `span`, for the
    /// sun along `sun_direction`; `phase_rayleigh` and `phase_aerosol` are the
    /// lanes' phase functions at the (fixed) angle between ray and sun.
    /// Returns `None` when nothing along the ray scatters.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        medium: &Medium,
        sun: Option<&SunColumns>,
        lanes: &SpectralLanes,
        origin: DVec3,
        dir: DVec3,
        span: super::medium::Span,
        sun_direction: DVec3,
        phase_rayleigh: &Lanes,
        phase_aerosol: f64,
    ) -> Option<Self> {
        let active = lanes.active;
        let mut t = [0.0; MAX_SEGMENTS + 1];
        // Per segment: sunlight mass per lane, skylight mass per lane.
        let mut sunlit = [[0.0; LANES]; MAX_SEGMENTS];
        let mut skylit = [[0.0; LANES]; MAX_SEGMENTS];
        let mut n = 0;
        let mut view_depth = [0.0; LANES];
        t[0] = span.t_enter;
        'pieces: for (t0, t1) in medium.pieces(origin, dir, span) {
            let length = t1 - t0;
            if length <= 0.0 {
                continue;
            }
            let probe = medium.coefficients((origin + dir * (0.5 * (t0 + t1))).length(), lanes);
            let depth = (0..active)
                .map(|j| probe.extinction(j) * length)
                .fold(0.0, f64::max);
            let cuts = ((depth / SEGMENT_OPTICAL_DEPTH).ceil())
                .max((length / SEGMENT_LENGTH_M).ceil())
                .clamp(1.0, 16.0) as usize;
            let step = length / cuts as f64;
            for s in 0..cuts {
                if n == MAX_SEGMENTS {
                    // Out of room: the last segment runs to the end of the span.
                    t[n] = span.t_exit;
                    break 'pieces;
                }
                let (a, b) = (
                    t0 + step * s as f64,
                    if s + 1 == cuts {
                        t1
                    } else {
                        t0 + step * (s + 1) as f64
                    },
                );
                let x = origin + dir * (0.5 * (a + b));
                let c = medium.coefficients(x.length(), lanes);
                let columns = sun.and_then(|table| table.at(x, sun_direction));
                for j in 0..active {
                    let half = 0.5 * c.extinction(j) * (b - a);
                    let view = view_depth[j] + half;
                    view_depth[j] += 2.0 * half;
                    skylit[n][j] = c.scattering(j) * (-view).exp() * (b - a);
                    if let Some([air, o3, aer]) = columns {
                        let sun_depth = lanes.rayleigh_m2[j] * air
                            + lanes.ozone_reference_m2(j) * o3
                            + lanes.aerosol_extinction_factor(j) * aer;
                        sunlit[n][j] = (c.rayleigh[j] * phase_rayleigh[j]
                            + c.aerosol_scattering[j] * phase_aerosol)
                            * (-(view + sun_depth)).exp()
                            * (b - a);
                    }
                }
                n += 1;
                t[n] = b;
            }
        }
        if n == 0 {
            return None;
        }
        // Normalise each lane's components; mix them with equal lane weights.
        let mut sun_total = [0.0; LANES];
        let mut sky_total = [0.0; LANES];
        for s in 0..n {
            for j in 0..active {
                sun_total[j] += sunlit[s][j];
                sky_total[j] += skylit[s][j];
            }
        }
        let sun_lanes = (0..active).filter(|&j| sun_total[j] > 0.0).count();
        let sky_lanes = (0..active).filter(|&j| sky_total[j] > 0.0).count();
        if sky_lanes == 0 {
            return None;
        }
        let sun_share = if sun_lanes > 0 {
            1.0 - SKYLIGHT_SHARE
        } else {
            0.0
        };
        let mut cdf = [0.0; MAX_SEGMENTS + 1];
        for s in 0..n {
            let mut mass = 0.0;
            for j in 0..active {
                if sun_total[j] > 0.0 {
                    mass += sun_share / sun_lanes as f64 * sunlit[s][j] / sun_total[j];
                }
                if sky_total[j] > 0.0 {
                    mass += (1.0 - sun_share) / sky_lanes as f64 * skylit[s][j] / sky_total[j];
                }
            }
            cdf[s + 1] = cdf[s] + mass;
        }
        let total = cdf[n];
        if total <= 0.0 || !total.is_finite() {
            return None;
        }
        for v in &mut cdf[1..=n] {
            *v /= total;
        }
        cdf[n] = 1.0;
        Some(Self {
            t,
            cdf,
            segments: n,
            scattered: sky_total[..active].iter().sum::<f64>() / active as f64,
            transmitted: view_depth[..active].iter().map(|d| (-d).exp()).sum::<f64>()
                / active as f64,
        })
    }

    /// Expected shares of the light a path finds by going on from the
    /// medium (≈ the scattered fraction) and from a ground of albedo
    /// `ground_albedo` at the segment's end (≈ transmittance × albedo).
    pub fn shares(&self, ground_albedo: f64) -> (f64, f64) {
        (self.scattered, self.transmitted * ground_albedo)
    }

    /// The distance for the uniform variate `u` ∈ [0, 1) and its density, m⁻¹.
    pub fn sample(&self, u: f64) -> (f64, f64) {
        let n = self.segments;
        // First segment whose upper cumulative probability exceeds u.
        let s = self.cdf[1..=n].partition_point(|&c| c <= u).min(n - 1);
        let p = self.cdf[s + 1] - self.cdf[s];
        if p <= 0.0 {
            // Only reachable through rounding at u ≈ 1: take the segment's end.
            return (self.t[s + 1], 0.0);
        }
        let f = ((u - self.cdf[s]) / p).clamp(0.0, 1.0);
        let length = self.t[s + 1] - self.t[s];
        (self.t[s] + f * length, p / length)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};

    #[test]
    fn vertical_column_matches_the_optical_depth_integral() {
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let columns = SunColumns::new(&medium);
        let x = DVec3::new(0.0, 0.0, medium.planet_radius_m);
        let [air, _, _] = columns.at(x, DVec3::Z).unwrap();
        let tau = atmosphere.vertical_optical_depth(0.0, 550.0).rayleigh;
        let sigma = crate::physics::rayleigh::cross_section_m2(550.0);
        assert!(
            (air * sigma / tau - 1.0).abs() < 0.01,
            "{}",
            air * sigma / tau
        );
        // Below the horizon the sun is hidden.
        assert!(columns
            .at(x, DVec3::new(1.0, 0.0, -0.01).normalize())
            .is_none());
        // Toward the horizon the column grows (≈ 38 air masses at sea level).
        let [grazing, _, _] = columns
            .at(x, DVec3::new(1.0, 0.0, 1e-4).normalize())
            .unwrap();
        assert!((20.0..60.0).contains(&(grazing / air)), "{}", grazing / air);
    }

    #[test]
    fn samples_follow_the_density() {
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let columns = SunColumns::new(&medium);
        let lanes = SpectralLanes::new([450.0, 550.0, 650.0, 750.0], 4, &medium, false);
        let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + 10.0);
        let dir = DVec3::new(0.8, 0.0, 0.6);
        let span = medium.span(origin, dir).unwrap();
        let d = InScatterDistribution::new(
            &medium,
            Some(&columns),
            &lanes,
            origin,
            dir,
            span,
            DVec3::new(0.0, 0.6, 0.8),
            &[0.06; LANES],
            0.1,
        )
        .unwrap();
        // Importance-sampling identity E[f(t)/p(t)] = ∫ f dt, for f the
        // scattering coefficient at 550 nm (which the density roughly follows,
        // so f/p stays bounded): the slant scattering optical depth, against
        // a fine midpoint rule.
        let f = |t: f64| {
            medium
                .coefficients((origin + dir * t).length(), &lanes)
                .scattering(1)
        };
        let n = 200_000;
        let mut estimate = 0.0;
        for i in 0..n {
            let (t, p) = d.sample((f64::from(i) + 0.5) / f64::from(n));
            assert!(t >= span.t_enter && t <= span.t_exit && p > 0.0);
            estimate += f(t) / p / f64::from(n);
        }
        let steps = 200_000;
        let h = (span.t_exit - span.t_enter) / f64::from(steps);
        let reference: f64 = (0..steps)
            .map(|i| f(span.t_enter + (f64::from(i) + 0.5) * h) * h)
            .sum();
        let ratio = estimate / reference;
        assert!((ratio - 1.0).abs() < 1e-3, "{estimate} vs {reference}");
    }
}
