//! Denoising the preview's coarse correction (`render::fast`): the
//! difference between a coarse Monte Carlo render and the sky model, shrunk
//! by its noise as each pixel's variance over the passes measures it.

use crate::spectrum::rec709_luminance;

/// The correction `residual` of a `size` coarse image (its pixels' ground
/// `shares`, `None` for a pixel left out of the statistics and taken as it
/// is; `wraps` in x for the equirect map) with its noise shrunk, from
/// `variance`, each pixel's luminance variance: the preview's correction
/// after a second's coarse passes is 3–5 % noisy at low sun, while the
/// model it corrects may be off by less than that, and then the
/// correction as it is makes the image worse.
///
/// For the sky and the ground apart ([`Shrunk`]), the correction is the
/// mean b of its neighbours of the same part within a radius of 1, 2 or 3
/// pixels plus λ times its detail r − b, all of it then shrunk toward zero
/// by μ; λ and μ take the weights least squares choose for independent
/// noise of known variance (as in Stein's estimator), and the radius is
/// the one of least estimated error (Stein's unbiased risk estimate). A
/// correction far above its noise (a model off by tens of per cent) is
/// kept whole; one within its noise is let go, and the model shown as it
/// is. Only the preview denoises: an approximate frame, never a render or
/// an export.
pub(super) fn denoised(
    residual: &[[f32; 3]],
    variance: &[f32],
    shares: &[Option<f64>],
    size: (usize, usize),
    wraps: bool,
) -> Vec<[f32; 3]> {
    // Per pixel: ground (true) or sky; a pixel with no finite variance
    // (or correction) is taken as it is, and so is one with none: its
    // passes agree exactly (the black of space beyond the limb), and its
    // correction is known. Averaged with the limb's, it took a share of
    // the limb's correction, which the model's floor in the dark then
    // made −2 000 % (`render::fast`), and the limb's fine pixels went
    // black.
    let parts: Vec<Option<bool>> = (0..size.0 * size.1)
        .map(|k| {
            shares[k]
                .filter(|_| {
                    variance[k].is_finite()
                        && variance[k] > 0.0
                        && residual[k].iter().all(|v| v.is_finite())
                })
                .map(|g| g > 0.5)
        })
        .collect();
    let grid = Grid {
        residual,
        variance,
        parts: &parts,
        size,
        wraps,
    };
    let mut out = residual.to_vec();
    for ground in [false, true] {
        let members: Vec<usize> = (0..parts.len())
            .filter(|&k| parts[k] == Some(ground))
            .collect();
        let best = (1..=3)
            .map(|radius| grid.shrunk(&members, radius))
            .min_by(|a, b| a.risk.total_cmp(&b.risk));
        if let Some(best) = best {
            for (&k, v) in members.iter().zip(best.values) {
                out[k] = v.map(|x| x as f32);
            }
        }
    }
    out
}

/// The coarse correction and its variance, for [`denoised`].
struct Grid<'a> {
    residual: &'a [[f32; 3]],
    variance: &'a [f32],
    /// Per pixel: ground, sky, or left out ([`denoised`]).
    parts: &'a [Option<bool>],
    size: (usize, usize),
    wraps: bool,
}

/// One part's correction shrunk at one radius ([`Grid::shrunk`]).
struct Shrunk {
    /// Per member pixel, in order.
    values: Vec<[f64; 3]>,
    /// Stein's unbiased estimate of the summed squared error (luminance).
    risk: f64,
}

impl Grid<'_> {
    /// `members`' neighbours' mean within `radius` (those of the same
    /// part), their count and their summed variance.
    fn neighbours(&self, k: usize, radius: i64) -> ([f64; 3], f64, f64) {
        let (cw, ch) = (self.size.0 as i64, self.size.1 as i64);
        let p = self.parts[k];
        let (x, y) = (k as i64 % cw, k as i64 / cw);
        let (mut sum, mut n, mut v) = ([0.0; 3], 0.0, 0.0);
        for dy in -radius..=radius {
            for dx in -radius..=radius {
                let (nx, ny) = (x + dx, y + dy);
                let nx = if self.wraps { nx.rem_euclid(cw) } else { nx };
                if !(0..cw).contains(&nx) || !(0..ch).contains(&ny) {
                    continue;
                }
                let j = (ny * cw + nx) as usize;
                if self.parts[j] == p {
                    for (s, r) in sum.iter_mut().zip(self.residual[j]) {
                        *s += f64::from(r);
                    }
                    n += 1.0;
                    v += f64::from(self.variance[j]);
                }
            }
        }
        (sum.map(|s| s / n), n, v)
    }

    /// `members` shrunk with neighbours within `radius`: r̂ = b + λ (r − b),
    /// then μ r̂. With v_k pixel k's variance and n its neighbours (itself
    /// among them), the detail r − b carries of the noise
    /// v_k (1 − 1/n)² + (Σ v − v_k)/n², so λ = 1 − Σ that / Σ (r − b)²;
    /// r̂'s variance is (1 − λ)² Σ v/n² + λ² v_k + 2λ(1 − λ) v_k/n, so
    /// μ = 1 − Σ that / Σ r̂². The estimate's own weight on r_k is
    /// S = μ((1 − λ)/n + λ), and its risk Σ (μ r̂ − r)² + Σ v_k (2S − 1).
    fn shrunk(&self, members: &[usize], radius: i64) -> Shrunk {
        let y = |c: [f64; 3]| rec709_luminance(c);
        let raw = |k: usize| self.residual[k].map(f64::from);
        let blurred: Vec<([f64; 3], f64, f64)> = members
            .iter()
            .map(|&k| self.neighbours(k, radius))
            .collect();
        let (mut detail2, mut detail_noise) = (0.0, 0.0);
        for (&k, &(b, n, v)) in members.iter().zip(&blurred) {
            let vk = f64::from(self.variance[k]);
            let d = y(raw(k)) - y(b);
            detail2 += d * d;
            detail_noise += vk * (1.0 - 1.0 / n).powi(2) + (v - vk) / (n * n);
        }
        let lambda = if detail2 > 0.0 && detail2.is_finite() {
            (1.0 - detail_noise / detail2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (mut sum2, mut noise) = (0.0, 0.0);
        let smoothed: Vec<[f64; 3]> = members
            .iter()
            .zip(&blurred)
            .map(|(&k, &(b, n, v))| {
                let (vk, r) = (f64::from(self.variance[k]), raw(k));
                let out: [f64; 3] = std::array::from_fn(|c| b[c] + lambda * (r[c] - b[c]));
                sum2 += y(out).powi(2);
                noise += (1.0 - lambda).powi(2) * v / (n * n)
                    + lambda * lambda * vk
                    + 2.0 * lambda * (1.0 - lambda) * vk / n;
                out
            })
            .collect();
        let mu = if sum2 > 0.0 && sum2.is_finite() {
            (1.0 - noise / sum2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let mut risk = 0.0;
        let values = members
            .iter()
            .zip(&blurred)
            .zip(smoothed)
            .map(|((&k, &(_, n, _)), out)| {
                let value = out.map(|c| mu * c);
                let vk = f64::from(self.variance[k]);
                let own = mu * ((1.0 - lambda) / n + lambda);
                risk += (y(value) - y(raw(k))).powi(2) + vk * (2.0 * own - 1.0);
                value
            })
            .collect();
        Shrunk { values, risk }
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    /// A correction within its noise is let go, one far above it kept, and
    /// one in between shrunk toward the truth: less error than either.
    #[test]
    fn the_preview_denoises_a_correction_by_its_variance() {
        let (cw, ch) = (64, 32);
        let mut rng = crate::rng::Rng::new(7, 0);
        // Gaussian noise of standard deviation 1 (Box–Muller).
        let mut normal = move || {
            let (u, v) = (rng.uniform_open0(), rng.uniform());
            (-2.0 * u.ln()).sqrt() * (2.0 * PI * v).cos()
        };
        // Sky above row 16, ground below; the truth smooth in each.
        let shares: Vec<Option<f64>> = (0..cw * ch)
            .map(|k| Some(if k / cw < 16 { 0.0 } else { 1.0 }))
            .collect();
        let variance = vec![1.0_f32; cw * ch];
        let mut error = |truth: &dyn Fn(usize) -> f64| {
            let noisy: Vec<[f32; 3]> = (0..cw * ch)
                .map(|k| [(truth(k) + normal()) as f32; 3])
                .collect();
            let out = denoised(&noisy, &variance, &shares, (cw, ch), true);
            let rms = |image: &[[f32; 3]]| {
                let sum: f64 = (0..cw * ch)
                    .map(|k| (f64::from(image[k][1]) - truth(k)).powi(2))
                    .sum();
                (sum / (cw * ch) as f64).sqrt()
            };
            (rms(&noisy), rms(&out))
        };
        // Pure noise: the output is far nearer zero than the input.
        let (before, after) = error(&|_| 0.0);
        assert!(
            (before - 1.0).abs() < 0.05 && after < 0.2,
            "{before} {after}"
        );
        // A strong smooth correction: kept, and its noise averaged.
        let strong = |k: usize| 20.0 + 10.0 * ((k % cw) as f64 / cw as f64 * 2.0 * PI).sin();
        let (before, after) = error(&strong);
        assert!(after < 0.6 * before, "{before} {after}");
        // A different correction in the sky and on the ground, each
        // within a few times the noise: neither lost nor left noisy.
        let step = |k: usize| if k / cw < 16 { 2.0 } else { -1.0 };
        let (before, after) = error(&step);
        assert!(after < 0.6 * before && after < 0.5, "{before} {after}");
        // A pixel of infinite variance (a firefly's) is taken as it is and
        // spoils nothing.
        let mut wild = variance.clone();
        wild[100] = f32::INFINITY;
        let residual = vec![[1.0_f32; 3]; cw * ch];
        let out = denoised(&residual, &wild, &shares, (cw, ch), true);
        assert!(out.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(out[100], [1.0; 3]);
    }
}
