//! A phase function tabulated against the scattering angle: measured or
//! computed elsewhere (a Mie code, an aerosol climatology such as OPAC) and
//! handed to the renderer as numbers. Files are read, one table per
//! wavelength, by [`super::spectral_phase`].
//!
//! **Model.** Between two rows the phase function is linear in μ = cos θ,
//! so the table defines one density on the sphere, which is evaluated,
//! integrated and sampled exactly:
//! - the normalisation 2π ∫ p dμ = 1 is the trapezoid rule in μ, exact for
//!   the piecewise-linear model (the file's values are rescaled by it, so
//!   any positive scale is accepted: a phase function normalised to 4π, or
//!   to 1 over the sphere, or a bare scattering cross-section);
//! - sampling picks a segment by its mass (its share of the integral), then
//!   inverts the segment's CDF, a quadratic in μ, in closed form: the
//!   density of the sampled directions is the evaluated phase function
//!   itself, so an estimator that divides by it stays unbiased;
//! - the Legendre moments 2π ∫ p P_l dμ (for the control variate's
//!   Funk–Hecke integrals, `render::control`) are exact integrals of the
//!   linear pieces against the polynomials.

use std::f64::consts::PI;

/// Most rows a table may have: a phase function at 0.01° steps is 18 001
/// rows; a file much larger than that is not a phase function table.
pub const MAX_ROWS: usize = 100_000;

/// A phase function linear in cos θ between tabulated scattering angles,
/// normalised to 2π ∫ p dμ = 1 (per steradian).
#[derive(Clone, Debug, PartialEq)]
pub struct PhaseTable {
    /// μ = cos θ of the rows, ascending (−1 first, 1 last).
    mu: Vec<f64>,
    /// The normalised phase function at `mu`, sr⁻¹.
    phase: Vec<f64>,
    /// Cumulative probability at the start of each segment `mu[k]..mu[k+1]`,
    /// and 1 at the end (`mu.len()` values, first 0).
    cdf: Vec<f64>,
}

impl PhaseTable {
    /// A table from scattering angles (degrees, increasing from exactly 0
    /// to exactly 180) and non-negative phase values in any units, not all
    /// zero. `Err` says which row is wrong and why (rows counted from 1).
    pub fn new(angles_deg: &[f64], values: &[f64]) -> Result<Self, (usize, String)> {
        if angles_deg.len() != values.len() {
            return Err((0, "as many angles as values are needed".into()));
        }
        let n = angles_deg.len();
        if n < 2 {
            return Err((
                n,
                format!("{n} row(s): at least two rows (0° and 180°) are needed"),
            ));
        }
        if n > MAX_ROWS {
            return Err((MAX_ROWS + 1, format!("more than {MAX_ROWS} rows")));
        }
        for (i, (&angle, &value)) in angles_deg.iter().zip(values).enumerate() {
            let row = i + 1;
            if !angle.is_finite() || !(0.0..=180.0).contains(&angle) {
                return Err((row, format!("angle {angle}° is outside 0 to 180")));
            }
            if !value.is_finite() || value < 0.0 {
                return Err((row, format!("phase {value} is not a finite number ≥ 0")));
            }
            if i > 0 && angle <= angles_deg[i - 1] {
                return Err((
                    row,
                    format!(
                        "angle {angle}° does not increase from the previous row's {}°",
                        angles_deg[i - 1]
                    ),
                ));
            }
        }
        if angles_deg[0] != 0.0 {
            return Err((
                1,
                format!(
                    "the first angle is {}°: the table must start at 0°",
                    angles_deg[0]
                ),
            ));
        }
        if angles_deg[n - 1] != 180.0 {
            return Err((
                n,
                format!(
                    "the last angle is {}°: the table must end at 180°",
                    angles_deg[n - 1]
                ),
            ));
        }
        // Ascending in μ: the rows reversed. cos(0) = 1 and cos(π) = −1
        // exactly, so the table spans [−1, 1] exactly.
        let mu: Vec<f64> = angles_deg
            .iter()
            .rev()
            .map(|&a| match a {
                0.0 => 1.0,
                180.0 => -1.0,
                _ => a.to_radians().cos(),
            })
            .collect();
        let raw: Vec<f64> = values.iter().rev().copied().collect();
        let masses: Vec<f64> = (0..n - 1)
            .map(|k| 0.5 * (raw[k] + raw[k + 1]) * (mu[k + 1] - mu[k]).max(0.0))
            .collect();
        let total: f64 = masses.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return Err((
                0,
                "the phase function integrates to zero (or overflows) over the sphere".into(),
            ));
        }
        let scale = 1.0 / (2.0 * PI * total);
        let mut cdf = Vec::with_capacity(n);
        let mut sum = 0.0;
        cdf.push(0.0);
        for m in &masses {
            sum += m;
            cdf.push(sum / total);
        }
        *cdf.last_mut().expect("n ≥ 2") = 1.0;
        Ok(Self {
            mu,
            phase: raw.iter().map(|v| v * scale).collect(),
            cdf,
        })
    }

    /// Index `k` of the segment `mu[k]..=mu[k+1]` that holds `mu`.
    fn segment(&self, mu: f64) -> usize {
        let n = self.mu.len();
        self.mu.partition_point(|&m| m <= mu).clamp(1, n - 1) - 1
    }

    /// The phase function at cosine `mu` of the scattering angle, sr⁻¹.
    pub fn eval(&self, mu: f64) -> f64 {
        let mu = mu.clamp(-1.0, 1.0);
        let k = self.segment(mu);
        let (m0, m1) = (self.mu[k], self.mu[k + 1]);
        let (p0, p1) = (self.phase[k], self.phase[k + 1]);
        let width = m1 - m0;
        if width <= 0.0 {
            return p0.max(p1);
        }
        let t = ((mu - m0) / width).clamp(0.0, 1.0);
        p0 + t * (p1 - p0)
    }

    /// A cosine drawn with density [`Self::eval`] (per unit μ, times 2π)
    /// from one uniform number in [0, 1): the segment by the CDF, then
    /// within it the inverse of F(t) = (a t + (b − a) t²/2)/((a + b)/2),
    /// a and b the phase at its ends, written
    /// t = (a + b) v / (a + √((1 − v) a² + v b²)) so that neither a
    /// constant segment (b = a) nor a zero end cancels.
    pub fn sample(&self, u: f64) -> f64 {
        let n = self.mu.len();
        // The segment whose CDF interval holds u; empty segments (zero
        // mass) are never chosen: their interval has no width.
        let k = (self.cdf.partition_point(|&c| c <= u).clamp(1, n - 1)) - 1;
        let (c0, c1) = (self.cdf[k], self.cdf[k + 1]);
        let v = if c1 > c0 {
            ((u - c0) / (c1 - c0)).clamp(0.0, 1.0)
        } else {
            0.5
        };
        let (a, b) = (self.phase[k], self.phase[k + 1]);
        let denominator = a + ((1.0 - v) * a * a + v * b * b).sqrt();
        let t = if denominator > 0.0 {
            ((a + b) * v / denominator).clamp(0.0, 1.0)
        } else {
            v
        };
        let (m0, m1) = (self.mu[k], self.mu[k + 1]);
        (m0 + t * (m1 - m0)).clamp(-1.0, 1.0)
    }

    /// The Legendre moments k_l = 2π ∫ p(μ) P_l(μ) dμ, l = 0..N, exact for
    /// the linear pieces: with p = α + βμ on a segment, ∫ P_l = (P_{l+1} −
    /// P_{l−1})/(2l + 1) and μ P_l = ((l + 1) P_{l+1} + l P_{l−1})/(2l + 1)
    /// (Bonnet's recurrence) give both parts from the antiderivatives of the
    /// P_m at the segment's ends.
    pub fn legendre_moments<const N: usize>(&self) -> [f64; N] {
        // Antiderivative of P_m at x, m = 0..=N+1: Q_0 = x,
        // Q_m = (P_{m+1} − P_{m−1})/(2m + 1).
        let antiderivatives = |x: f64| -> Vec<f64> {
            let mut p = vec![0.0; N + 3];
            p[0] = 1.0;
            p[1] = x;
            for m in 1..N + 2 {
                let mf = m as f64;
                p[m + 1] = ((2.0 * mf + 1.0) * x * p[m] - mf * p[m - 1]) / (mf + 1.0);
            }
            (0..N + 2)
                .map(|m| {
                    if m == 0 {
                        x
                    } else {
                        (p[m + 1] - p[m - 1]) / (2.0 * m as f64 + 1.0)
                    }
                })
                .collect()
        };
        let mut moments = [0.0; N];
        let mut lower = antiderivatives(self.mu[0]);
        for k in 0..self.mu.len() - 1 {
            let upper = antiderivatives(self.mu[k + 1]);
            let (m0, m1) = (self.mu[k], self.mu[k + 1]);
            if m1 > m0 {
                let beta = (self.phase[k + 1] - self.phase[k]) / (m1 - m0);
                let alpha = self.phase[k] - beta * m0;
                let integral = |m: usize| upper[m] - lower[m];
                for (l, moment) in moments.iter_mut().enumerate() {
                    let lf = l as f64;
                    // ∫ μ P_l = ((l + 1) ∫ P_{l+1} + l ∫ P_{l−1})/(2l + 1).
                    let mu_pl = ((lf + 1.0) * integral(l + 1)
                        + if l > 0 { lf * integral(l - 1) } else { 0.0 })
                        / (2.0 * lf + 1.0);
                    *moment += 2.0 * PI * (alpha * integral(l) + beta * mu_pl);
                }
            }
            lower = upper;
        }
        moments
    }

    /// The mean cosine of the scattering angle (the asymmetry parameter g).
    pub fn mean_cosine(&self) -> f64 {
        self.legendre_moments::<2>()[1]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::physics::aerosol::henyey_greenstein;
    use crate::physics::spectral_phase::SpectralPhaseTable;

    /// Henyey–Greenstein g at whole degrees 0..=180.
    fn hg_table(g: f64, step_deg: f64) -> PhaseTable {
        let n = (180.0 / step_deg).round() as usize;
        let angles: Vec<f64> = (0..=n).map(|i| i as f64 * step_deg).collect();
        let angles: Vec<f64> = angles.into_iter().map(|a: f64| a.min(180.0)).collect();
        let values: Vec<f64> = angles
            .iter()
            .map(|a| henyey_greenstein(a.to_radians().cos(), g))
            .collect();
        PhaseTable::new(&angles, &values).unwrap()
    }

    #[test]
    fn a_table_of_henyey_greenstein_at_one_degree_is_henyey_greenstein() {
        let table = hg_table(0.7, 1.0);
        for i in 0..=1800 {
            let mu = (f64::from(i) * 0.1).to_radians().cos();
            let (got, want) = (table.eval(mu), henyey_greenstein(mu, 0.7));
            assert!((got / want - 1.0).abs() < 0.01, "{mu}: {got} vs {want}");
        }
        let g = table.mean_cosine();
        assert!((g - 0.7).abs() < 1e-3, "{g}");
    }

    #[test]
    fn moments_match_quadrature() {
        let table = hg_table(0.5, 5.0);
        let k: [f64; 10] = table.legendre_moments();
        let q: [f64; 10] =
            crate::physics::quadrature::legendre_moments_by_midpoints(|mu| table.eval(mu), 400_000);
        assert!((k[0] - 1.0).abs() < 1e-12, "{}", k[0]);
        for l in 0..10 {
            assert!((k[l] - q[l]).abs() < 1e-6, "l {l}: {} vs {}", k[l], q[l]);
        }
    }

    /// Sampled cosines against the density integrated over bins in μ:
    /// Pearson's χ² over 40 bins (39 degrees of freedom: mean 39, standard
    /// deviation 8.8; the bound 80 is exceeded with probability < 10⁻⁴).
    #[test]
    fn sampling_follows_the_evaluated_density() {
        let angles = [0.0, 2.0, 10.0, 30.0, 60.0, 90.0, 120.0, 150.0, 179.0, 180.0];
        let values = [50.0, 30.0, 8.0, 2.0, 0.5, 0.0, 0.3, 0.6, 1.5, 1.5];
        for table in [
            PhaseTable::new(&angles, &values).unwrap(),
            hg_table(0.7, 1.0),
        ] {
            let bins = 40;
            let n = 400_000_u32;
            let mut counts = vec![0.0; bins];
            let mut rng = crate::rng::Rng::new(11, 12);
            for _ in 0..n {
                let mu = table.sample(rng.uniform());
                let b = ((0.5 * (mu + 1.0) * bins as f64) as usize).min(bins - 1);
                counts[b] += 1.0;
            }
            let mut chi2 = 0.0;
            for (b, &count) in counts.iter().enumerate() {
                let (lo, hi) = (
                    -1.0 + 2.0 * b as f64 / bins as f64,
                    -1.0 + 2.0 * (b + 1) as f64 / bins as f64,
                );
                let m = 2000;
                let p: f64 = (0..m)
                    .map(|i| {
                        let mu = lo + (hi - lo) * (f64::from(i) + 0.5) / f64::from(m);
                        2.0 * PI * table.eval(mu) * (hi - lo) / f64::from(m)
                    })
                    .sum();
                let expected = p * f64::from(n);
                if expected > 0.0 {
                    chi2 += (count - expected).powi(2) / expected;
                } else {
                    assert_eq!(count, 0.0, "bin {b}");
                }
            }
            assert!(chi2 < 80.0, "χ² {chi2}");
        }
    }

    #[test]
    fn sampling_near_the_ends_and_empty_segments_stays_inside() {
        let table = PhaseTable::new(&[0.0, 90.0, 180.0], &[1.0, 0.0, 0.0]).unwrap();
        for u in [0.0, 1e-300, 0.5, 1.0 - 1e-16] {
            let mu = table.sample(u);
            assert!((0.0..=1.0).contains(&mu), "{u}: {mu}");
        }
        assert_eq!(table.eval(-0.5), 0.0);
        // Linear in μ from 0 at μ = 0 to 2a at μ = 1: 2π a = 1.
        assert!((table.eval(1.0) - 1.0 / PI).abs() < 1e-12);
    }

    #[test]
    fn bad_tables_say_which_line_and_why() {
        for (text, line, needle) in [
            ("angle_deg,phase\n0,1\n", 2, "at least two rows"),
            (
                "angle_deg,phase\n0,1\n90,1\n45,1\n180,1\n",
                4,
                "does not increase",
            ),
            ("angle_deg,phase\n0,1\n170,1\n", 3, "end at 180"),
            ("angle_deg,phase\n5,1\n180,1\n", 2, "start at 0"),
            ("angle_deg,phase\n0,1\n90,-1\n180,1\n", 3, "≥ 0"),
            ("angle_deg,phase\n0,1\n90,NaN\n180,1\n", 3, "≥ 0"),
            ("angle_deg,phase\n0,1\n90,x\n180,1\n", 3, "two numbers"),
            ("theta,p\n0,1\n180,1\n", 1, "header"),
            ("angle_deg,phase\n0,0\n180,0\n", 3, "zero"),
        ] {
            let (got_line, reason) = SpectralPhaseTable::parse(text).unwrap_err();
            assert_eq!(got_line, line, "{text:?}: {reason}");
            assert!(reason.contains(needle), "{text:?}: {reason}");
        }
        let table =
            SpectralPhaseTable::parse("# comment\nangle_deg, phase\n\n0, 2\n180, 2\n").unwrap();
        assert!((table.eval(0.3, 550.0) - 1.0 / (4.0 * PI)).abs() < 1e-15);
    }
}
