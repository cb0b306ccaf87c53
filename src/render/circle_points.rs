//! The analytic parts of the density that draws the splat walks' points
//! (r, θ) ([`super::circles`]), in polar coordinates (ρ, φ) about the
//! observer's own (r₀, θ₀) in the plane (r − r₀, r₀ (θ − θ₀)):
//! r = r₀ + ρ sin φ, θ = θ₀ + ρ cos φ / r₀.
//!
//! * **In ρ**, two exponentials and a uniform part up to the farthest
//!   visible circle, φ uniform: positive wherever a circle can be seen.
//! * **The wedge below the observer's height** h = r₀ − r_ground: the
//!   points between the ground and the observer's height, sin φ ∈
//!   [−h/ρ, 0], two wedges of half-width β(ρ) = asin(min(h/ρ, 1)) at
//!   φ = π and φ = 2π (the sides toward and away from the sun). For an
//!   observer 2 m up this is the air in front of the ground and along the
//!   rays that graze it at the horizon — the light of the ground's pixels'
//!   air and of the horizon's row. At 5 km it is 4 × 10⁻⁴ rad wide, so
//!   neither the uniform φ above nor the table (each bin read at its
//!   centre, which lies under the ground) draws points there, and the few
//!   drawn carried weights that made the horizon's row the noisiest of a
//!   twilight panorama (`BENCHMARKS.md`, the wedge's decisions row). Here ρ
//!   follows the same analytic density and φ is uniform across the two
//!   wedges.

use std::f64::consts::PI;

/// The analytic density in ρ: shares and scales (m) of two exponentials,
/// then uniform up to the farthest visible circle.
const RHO_SHARES: [f64; 2] = [0.5, 0.3];
const RHO_SCALES_M: [f64; 2] = [5e3, 30e3];

/// Density (per ρ, per φ-turn) of the analytic part.
pub(super) fn analytic_rho_density(rho_m: f64, rho_max: f64) -> f64 {
    let exponentials: f64 = RHO_SHARES
        .iter()
        .zip(RHO_SCALES_M)
        .map(|(share, scale)| share * (-rho_m / scale).exp() / scale)
        .sum();
    let uniform = 1.0 - RHO_SHARES.iter().sum::<f64>();
    exponentials
        + if rho_m < rho_max {
            uniform / rho_max
        } else {
            0.0
        }
}

/// ρ drawn from [`analytic_rho_density`] by the uniforms `u` (the part)
/// and `v` (within it).
pub(super) fn sample_analytic_rho(u: f64, v: f64, rho_max: f64) -> f64 {
    let (a, b) = (RHO_SHARES[0], RHO_SHARES[0] + RHO_SHARES[1]);
    if u < a {
        -RHO_SCALES_M[0] * (1.0 - v).ln()
    } else if u < b {
        -RHO_SCALES_M[1] * (1.0 - v).ln()
    } else {
        v * rho_max
    }
}

/// Probability of ρ ≤ `rho_m` under [`analytic_rho_density`].
pub(super) fn analytic_rho_cdf(rho_m: f64, rho_max: f64) -> f64 {
    let exponentials: f64 = RHO_SHARES
        .iter()
        .zip(RHO_SCALES_M)
        .map(|(share, scale)| share * -(-rho_m / scale).exp_m1())
        .sum();
    let uniform = 1.0 - RHO_SHARES.iter().sum::<f64>();
    exponentials + uniform * (rho_m / rho_max).min(1.0)
}

/// The wedge below an observer `height_m` above the ground: ρ from the
/// analytic density, φ uniform across the two wedges.
#[derive(Clone, Copy, Debug)]
pub(super) struct Wedge {
    height_m: f64,
    rho_max: f64,
}

impl Wedge {
    /// The wedge of an observer `height_m` above the ground (none at or
    /// below it) with the farthest visible circle at `rho_max`.
    pub(super) fn new(height_m: f64, rho_max: f64) -> Option<Self> {
        (height_m > 0.0 && rho_max > 0.0).then_some(Self { height_m, rho_max })
    }

    /// Each wedge's half-width in φ at `rho_m`, β = asin(min(h/ρ, 1)).
    fn half_width(&self, rho_m: f64) -> f64 {
        if rho_m > 0.0 {
            (self.height_m / rho_m).min(1.0).asin()
        } else {
            0.0
        }
    }

    /// Density per dρ dφ at (`rho_m`, `phi`), φ in [0, 2π]: the analytic
    /// density in ρ over the two wedges' width 2β.
    pub(super) fn density(&self, rho_m: f64, phi: f64) -> f64 {
        let beta = self.half_width(rho_m);
        let inside = (PI..=PI + beta).contains(&phi) || (2.0 * PI - beta..=2.0 * PI).contains(&phi);
        if beta > 0.0 && inside {
            analytic_rho_density(rho_m, self.rho_max) / (2.0 * beta)
        } else {
            0.0
        }
    }

    /// A point drawn by the uniforms `u`, `v` (ρ, as
    /// [`sample_analytic_rho`]) and `w` (the side, then φ across it).
    pub(super) fn sample(&self, u: f64, v: f64, w: f64) -> (f64, f64) {
        let rho = sample_analytic_rho(u, v, self.rho_max);
        let beta = self.half_width(rho);
        let phi = if w < 0.5 {
            PI + beta * 2.0 * w
        } else {
            2.0 * PI - beta * (2.0 * w - 1.0)
        };
        (rho, phi)
    }

    /// The probability of ρ in `rho` and φ in `phi` (a table bin): the
    /// wedges' overlap with the bin's φ range over their width, integrated
    /// over ρ by the midpoint rule (64 steps: within the bins the overlap
    /// changes as 1/ρ, smoothly).
    pub(super) fn mass(&self, rho: (f64, f64), phi: (f64, f64)) -> f64 {
        const STEPS: usize = 64;
        if phi.1 < PI {
            return 0.0;
        }
        let overlap = |a: f64, b: f64| (phi.1.min(b) - phi.0.max(a)).max(0.0);
        let step = (rho.1 - rho.0) / STEPS as f64;
        (0..STEPS)
            .map(|k| {
                let r = rho.0 + (k as f64 + 0.5) * step;
                let beta = self.half_width(r);
                if beta <= 0.0 {
                    return 0.0;
                }
                let share =
                    (overlap(PI, PI + beta) + overlap(2.0 * PI - beta, 2.0 * PI)) / (2.0 * beta);
                analytic_rho_density(r, self.rho_max) * share
            })
            .sum::<f64>()
            * step
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    #[test]
    fn the_analytic_density_integrates_to_one() {
        let rho_max = 1.2e6;
        let n = 400_000u32;
        let sum: f64 = (0..n)
            .map(|i| {
                let rho = (f64::from(i) + 0.5) / f64::from(n) * 4.0 * rho_max;
                analytic_rho_density(rho, rho_max)
            })
            .sum::<f64>()
            * 4.0
            * rho_max
            / f64::from(n);
        assert!((sum - 1.0).abs() < 2e-3, "{sum}");
        // Its distribution function is its integral (midpoint rule, up to
        // a few ρ; the learned density reads the prior's mass per bin off it).
        for upper in [3e3, 40e3, 0.5 * rho_max, rho_max, 2.0 * rho_max] {
            let integral: f64 = (0..n)
                .map(|i| analytic_rho_density((f64::from(i) + 0.5) / f64::from(n) * upper, rho_max))
                .sum::<f64>()
                * upper
                / f64::from(n);
            let cdf = analytic_rho_cdf(upper, rho_max);
            assert!(
                (cdf - integral).abs() < 2e-3,
                "ρ {upper}: {cdf} vs {integral}"
            );
        }
    }

    #[test]
    fn the_wedge_lies_below_the_observer_and_follows_its_density() {
        let (r0, height, rho_max) = (6.371e6 + 2.0, 2.0, 1.2e6);
        let wedge = Wedge::new(height, rho_max).unwrap();
        assert!(Wedge::new(0.0, rho_max).is_none());
        let mut rng = Rng::new(5, 0);
        // g: a weight over the wedge (lopsided in φ and ρ); E[g/p] = ∫ g
        // over both wedges, computed by quadrature in ρ (the φ integral of
        // g is exact: g is linear in φ across each wedge).
        // (Beyond 50 m: within a few metres the wedges are a quarter turn
        // wide each, and g/p would be heavy there.)
        let g = |rho: f64, phi: f64| {
            if rho > 50.0 {
                (-rho / 20e3).exp() * (2.0 + (phi - PI).sin())
            } else {
                0.0
            }
        };
        let n = 200_000u32;
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..n {
            let (rho, phi) = wedge.sample(rng.uniform(), rng.uniform(), rng.uniform());
            // Every point lies between the ground and the observer.
            let r = r0 + rho * phi.sin();
            assert!((r0 - height - 1e-6..=r0 + 1e-9).contains(&r), "r {r}");
            let v = g(rho, phi) / wedge.density(rho, phi);
            sum += v;
            sum2 += v * v;
        }
        let mean = sum / f64::from(n);
        let se = ((sum2 / f64::from(n) - mean * mean) / f64::from(n)).sqrt();
        let steps = 200_000u32;
        let exact: f64 = (0..steps)
            .map(|k| {
                let rho = 50.0 + (f64::from(k) + 0.5) / f64::from(steps) * 400e3;
                let beta = wedge.half_width(rho);
                // ∫ (2 + sin(φ − π)) dφ over [π, π + β], and the same over
                // [2π − β, 2π].
                (-rho / 20e3).exp() * 2.0 * (2.0 * beta + 1.0 - beta.cos())
            })
            .sum::<f64>()
            * 400e3
            / f64::from(steps);
        assert!(
            (mean - exact).abs() < 4.0 * se,
            "{mean} against {exact} (SE {se})"
        );
        assert!(se < 0.01 * exact, "SE {se}");
        // The bins' masses add up to one and match the density.
        let edges: Vec<f64> = (0..=64)
            .map(|i| rho_max * (f64::from(i) / 64.0).powi(3))
            .collect();
        let mut total = 0.0;
        for pair in edges.windows(2) {
            for j in 0..64 {
                let phi = (
                    f64::from(j) / 64.0 * 2.0 * PI,
                    f64::from(j + 1) / 64.0 * 2.0 * PI,
                );
                total += wedge.mass((pair[0], pair[1]), phi);
            }
        }
        let beyond = 1.0 - analytic_rho_cdf(rho_max, rho_max);
        assert!((total + beyond - 1.0).abs() < 2e-3, "{total} + {beyond}");
    }
}
