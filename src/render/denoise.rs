//! Denoising the preview's coarse correction (`render::fast`): the
//! difference between a coarse Monte Carlo render and the sky model,
//! smoothed and shrunk by as much as the passes' two independent halves
//! bear out.

use crate::spectrum::rec709_luminance;

/// The largest radius (coarse pixels) of [`denoised`]'s local mean, which
/// takes radii 1 to this: 4 is a 9×9 box (about 40° of an equirect
/// preview).
const MAX_RADIUS: i64 = 4;

/// Strips of columns whose antisymmetric twins [`denoised`] sums apart to
/// estimate its cross products' standard errors.
const BLOCKS: usize = 8;

/// Z of [`denoised`]: a cross product of s standard errors is scaled by
/// 1 − (Z/s)², nothing below Z. Z = 1.5, 2 and 3 gave the same previews
/// at twilight, sunset and midday within a few hundredths of a per cent
/// (seeds 1, 3, 5): the guard is for fields whose halves' noise is large
/// against their correction.
const SIGNIFICANCE: f64 = 1.5;

/// The correction `residual` of a `size` coarse image (its pixels' ground
/// `shares`, `None` for a pixel left out and taken as it is; `wraps` in x
/// for the equirect map) with its noise taken down, from `halves`, the
/// same correction's luminance from each half of the passes alone
/// (`Film::variance_halves`; per coarse pixel, cd m⁻², not finite where
/// the half has no value).
///
/// The preview's correction after a second's coarse passes is several per
/// cent noisy at low sun, while the model it corrects may be off by less
/// than that, and then the correction as it is makes the image worse. Its
/// noise is neither independent from pixel to pixel (a splat walk spreads
/// one path's light along a circle of pixels) nor well measured by a few
/// passes' spread (it is heavy-tailed): weights from the per-pixel
/// variance (Stein's) kept corrections that took twilight's preview 3–7 %
/// off where the model alone is 1.6 %. What this rests on instead is that
/// the halves' noises are independent of each other, whatever their
/// structure. Nearly so: the passes' scrambled Sobol points make
/// successive passes' errors anti-correlated, which biases the cross
/// products below low — toward less correction, never more. (Independent
/// numbers for the coarse passes made each pass noisier: with an earlier
/// form of this estimate the sunset's preview at 2 s 1.2–1.6 % off,
/// against 0.8–1.0 %.)
///
/// For the sky and the ground apart, and each radius ρ, the estimate is
/// β_b b + β_r r: r the correction, b its mean over the part's pixels
/// within ρ. Both are linear in the passes, so each half's r_H and b_H
/// have the same expectations as the whole's; with c the true correction,
/// E⟨b_A, r_B⟩ = ⟨E b, c⟩ and E⟨r_A, r_B⟩ = ⟨E r, c⟩, since the halves'
/// noises are independent. The squared error ‖β_b b + β_r r − c‖² is then
/// estimated without bias up to the constant ‖c‖², and least squares give
/// β = G⁻¹ a, G the Gram matrix of b and r (noise and all), a the halves'
/// cross products above; it lowers the error from that of no correction
/// by aᵀG⁻¹a. Each cross product in a is itself noisy, the more so the
/// fewer the passes; its standard error s comes from a twin with the
/// halves' difference in place of the truth's estimates,
/// ½(⟨b, r_A − r_B⟩ + ⟨b_A − b_B, r⟩) and ⟨r, r_A − r_B⟩ (b and r the
/// whole's), which has expectation zero (for halves of equal weight)
/// and, to leading order, the same noise: summed over [`BLOCKS`] strips
/// of columns, their squares estimate s². (A bright sample in half A
/// where the correction is c adds about E c to both ⟨b_A, r_B⟩ and
/// ⟨b_B, r_A⟩; the twin ½(⟨b_A, r_B⟩ − ⟨b_B, r_A⟩) cancelled it, and
/// twilight's fifth coarse pass was shown 5 % off.) A cross
/// product of a is then scaled by 1 − (Z s / a)², Z = [`SIGNIFICANCE`]
/// (nothing below Z s), so that the largest of several noisy gains is not
/// taken for a real one. Of the radii and of b alone, r alone or both
/// (the weights kept within 0–1), the largest such gain is taken (sums in
/// luminance); where none gains, the halves do not confirm any correction
/// and the model is shown as it is. Only the preview denoises: an
/// approximate frame, never a render or an export.
pub(super) fn denoised(
    residual: &[[f32; 3]],
    halves: &[Vec<f64>; 2],
    shares: &[Option<f64>],
    size: (usize, usize),
    wraps: bool,
) -> Vec<[f32; 3]> {
    let y = |c: [f32; 3]| rec709_luminance(c.map(f64::from));
    // Per pixel: ground (true) or sky; a pixel whose correction (or a
    // half's) is not finite is taken as it is, and so is one whose halves
    // agree exactly: its correction is known (the black of space beyond
    // the limb). Averaged with the limb's, it took a share of the limb's
    // correction, which the model's floor in the dark then made −2 000 %
    // (`render::fast`), and the limb's fine pixels went black.
    let parts: Vec<Option<bool>> = (0..size.0 * size.1)
        .map(|k| {
            let [a, b] = [halves[0][k], halves[1][k]];
            shares[k]
                .filter(|_| {
                    residual[k].iter().all(|v| v.is_finite())
                        && a.is_finite()
                        && b.is_finite()
                        && a != b
                })
                .map(|g| g > 0.5)
        })
        .collect();
    let grid = Grid {
        parts: &parts,
        size,
        wraps,
    };
    let luminance: Vec<f64> = residual.iter().map(|&r| y(r)).collect();
    let mut out = residual.to_vec();
    for ground in [false, true] {
        let members: Vec<usize> = (0..parts.len())
            .filter(|&k| parts[k] == Some(ground))
            .collect();
        let mut best = Fit::NONE;
        for radius in 1..=MAX_RADIUS {
            let mean = |values: &[f64]| -> Vec<f64> {
                members
                    .iter()
                    .map(|&k| grid.mean(values, k, radius))
                    .collect()
            };
            let [b_a, b_b] = [mean(&halves[0]), mean(&halves[1])];
            let b = mean(&luminance);
            let (mut gram, mut along) = ([[0.0; 2]; 2], [0.0; 2]);
            // Per strip of columns, the cross products' twins (next to
            // `along`'s terms): zero in expectation, with the same noise,
            // so their squares sum to the variance of `along` (for strips
            // whose noises are independent).
            let mut twins = [[0.0; 2]; BLOCKS];
            for (j, &k) in members.iter().enumerate() {
                let (r, [r_a, r_b]) = (luminance[k], [halves[0][k], halves[1][k]]);
                gram[0][0] += b[j] * b[j];
                gram[0][1] += b[j] * r;
                gram[1][1] += r * r;
                along[0] += 0.5 * (b_a[j] * r_b + b_b[j] * r_a);
                along[1] += r_a * r_b;
                let twin = &mut twins[(k % size.0) * BLOCKS / size.0];
                twin[0] += 0.5 * (b[j] * (r_a - r_b) + (b_a[j] - b_b[j]) * r);
                twin[1] += 0.5 * (r_a * r_a - r_b * r_b);
            }
            gram[1][0] = gram[0][1];
            let along = [0, 1].map(|i| {
                let error = twins.iter().map(|t| t[i] * t[i]).sum::<f64>().sqrt();
                if along[i] > 0.0 {
                    (along[i] * (1.0 - (SIGNIFICANCE * error / along[i]).powi(2))).max(0.0)
                } else {
                    0.0
                }
            });
            let fit = Fit::best(radius, &gram, &along);
            if fit.gain > best.gain {
                best = fit;
            }
        }
        for &k in &members {
            let b = grid.mean_rgb(residual, k, best.radius);
            let r = residual[k];
            out[k] =
                [0, 1, 2].map(|c| (best.beta[0] * b[c] + best.beta[1] * f64::from(r[c])) as f32);
        }
    }
    out
}

/// The weights of a part's smoothed and raw correction ([`denoised`]).
#[derive(Clone, Copy, Debug)]
struct Fit {
    radius: i64,
    /// β_b and β_r.
    beta: [f64; 2],
    /// The squared error taken out, aᵀG⁻¹a (luminance², summed).
    gain: f64,
}

impl Fit {
    /// No correction.
    const NONE: Self = Self {
        radius: 0,
        beta: [0.0; 2],
        gain: 0.0,
    };

    /// The best of b alone, r alone and both (weights within 0–1) at
    /// `radius`, from the Gram matrix `gram` and cross products `along`.
    fn best(radius: i64, gram: &[[f64; 2]; 2], along: &[f64; 2]) -> Self {
        let mut best = Self::NONE;
        let mut consider = |beta: [f64; 2]| {
            let valid = beta.iter().all(|b| (0.0..=1.0).contains(b));
            // The error's fall: 2 βᵀa − βᵀGβ.
            let quadratic: f64 = (0..2)
                .flat_map(|i| (0..2).map(move |j| (i, j)))
                .map(|(i, j)| beta[i] * gram[i][j] * beta[j])
                .sum();
            let gain = 2.0 * (beta[0] * along[0] + beta[1] * along[1]) - quadratic;
            if valid && gain.is_finite() && gain > best.gain {
                best = Self { radius, beta, gain };
            }
        };
        for i in 0..2 {
            if gram[i][i] > 0.0 {
                let mut beta = [0.0; 2];
                beta[i] = along[i] / gram[i][i];
                consider(beta);
            }
        }
        let det = gram[0][0] * gram[1][1] - gram[0][1] * gram[1][0];
        if det > 0.0 {
            consider([
                (gram[1][1] * along[0] - gram[0][1] * along[1]) / det,
                (gram[0][0] * along[1] - gram[1][0] * along[0]) / det,
            ]);
        }
        best
    }
}

/// Which part each coarse pixel belongs to, for means within a part.
struct Grid<'a> {
    /// Per pixel: ground, sky, or left out ([`denoised`]).
    parts: &'a [Option<bool>],
    size: (usize, usize),
    wraps: bool,
}

impl Grid<'_> {
    /// The pixels of `k`'s part within `radius` of it (itself among them).
    fn neighbours(&self, k: usize, radius: i64) -> impl Iterator<Item = usize> + '_ {
        let (cw, ch) = (self.size.0 as i64, self.size.1 as i64);
        let p = self.parts[k];
        let (x, y) = (k as i64 % cw, k as i64 / cw);
        (-radius..=radius)
            .flat_map(move |dy| (-radius..=radius).map(move |dx| (x + dx, y + dy)))
            .filter_map(move |(nx, ny)| {
                let nx = if self.wraps { nx.rem_euclid(cw) } else { nx };
                ((0..cw).contains(&nx) && (0..ch).contains(&ny))
                    .then(|| (ny * cw + nx) as usize)
                    .filter(|&j| self.parts[j] == p)
            })
    }

    /// The mean of `values` over [`Self::neighbours`].
    fn mean(&self, values: &[f64], k: usize, radius: i64) -> f64 {
        let (mut sum, mut n) = (0.0, 0.0);
        for j in self.neighbours(k, radius) {
            sum += values[j];
            n += 1.0;
        }
        sum / n
    }

    /// [`Self::mean`] of each colour channel of `values`.
    fn mean_rgb(&self, values: &[[f32; 3]], k: usize, radius: i64) -> [f64; 3] {
        let (mut sum, mut n) = ([0.0; 3], 0.0);
        for j in self.neighbours(k, radius) {
            for (s, v) in sum.iter_mut().zip(values[j]) {
                *s += f64::from(v);
            }
            n += 1.0;
        }
        sum.map(|s| s / n)
    }
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;

    /// A correction within its noise is let go, one far above it kept, and
    /// one in between smoothed toward the truth: less error than either —
    /// also where the noise is shared by whole rows of pixels, as a splat
    /// walk's is along its circle.
    #[test]
    fn the_preview_denoises_a_correction_by_its_halves() {
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
        // Each half: the truth plus independent noise of spread √2 per
        // pixel (the whole, their mean, has 1), `rows` of it shared along
        // each row (correlated noise).
        let mut error = |truth: &dyn Fn(usize) -> f64, shared: f64| {
            let mut half = || -> Vec<f64> {
                let rows: Vec<f64> = (0..ch).map(|_| normal()).collect();
                (0..cw * ch)
                    .map(|k| {
                        let own = (1.0 - shared * shared).sqrt() * normal();
                        truth(k) + 2f64.sqrt() * (own + shared * rows[k / cw])
                    })
                    .collect()
            };
            let y = [half(), half()];
            let whole: Vec<[f32; 3]> = (0..cw * ch)
                .map(|k| [(0.5 * (y[0][k] + y[1][k])) as f32; 3])
                .collect();
            let out = denoised(&whole, &y, &shares, (cw, ch), true);
            let rms = |image: &[[f32; 3]]| {
                let sum: f64 = (0..cw * ch)
                    .map(|k| (f64::from(image[k][1]) - truth(k)).powi(2))
                    .sum();
                (sum / (cw * ch) as f64).sqrt()
            };
            (rms(&whole), rms(&out))
        };
        // Pure noise: the output is far nearer zero than the input, with
        // independent pixels; with half the noise's variance shared along
        // each row (16 independent rows a part, so the halves' cross
        // products are themselves noisy) still nearer zero by half.
        for (shared, most) in [(0.0, 0.3), (0.7, 0.6)] {
            let (before, after) = error(&|_| 0.0, shared);
            assert!(
                (before - 1.0).abs() < 0.15 && after < most,
                "shared {shared}: {before} {after}"
            );
        }
        // A strong smooth correction: kept, and its noise averaged.
        let strong = |k: usize| 20.0 + 10.0 * ((k % cw) as f64 / cw as f64 * 2.0 * PI).sin();
        let (before, after) = error(&strong, 0.0);
        assert!(after < 0.6 * before, "{before} {after}");
        // A different correction in the sky and on the ground, each
        // within a few times the noise: neither lost nor left noisy.
        let step = |k: usize| if k / cw < 16 { 2.0 } else { -1.0 };
        let (before, after) = error(&step, 0.0);
        assert!(after < 0.6 * before && after < 0.5, "{before} {after}");
        // A firefly's arc in one half (a splat walk that found a rare
        // bright path: 24 pixels along a row, 200 times the noise) over
        // no correction at all: let go, not spread.
        let arc = |k: usize| k / cw == 8 && (20..44).contains(&(k % cw));
        let mut y = [0, 1].map(|_| {
            (0..cw * ch)
                .map(|_| 2f64.sqrt() * normal())
                .collect::<Vec<_>>()
        });
        for (k, v) in y[1].iter_mut().enumerate() {
            if arc(k) {
                *v += 400.0;
            }
        }
        let whole: Vec<[f32; 3]> = (0..cw * ch)
            .map(|k| [(0.5 * (y[0][k] + y[1][k])) as f32; 3])
            .collect();
        let out = denoised(&whole, &y, &shares, (cw, ch), true);
        let rms = |image: &[[f32; 3]]| {
            (image.iter().map(|p| f64::from(p[1]).powi(2)).sum::<f64>() / (cw * ch) as f64).sqrt()
        };
        let (before, after) = (rms(&whole), rms(&out));
        assert!(after < 0.1 * before && after < 1.0, "{before} {after}");
        // A pixel with no value in a half is taken as it is and spoils
        // nothing.
        let residual = vec![[1.0_f32; 3]; cw * ch];
        let mut y = [vec![1.0; cw * ch], vec![1.0; cw * ch]];
        y[1][100] = f64::NAN;
        let out = denoised(&residual, &y, &shares, (cw, ch), true);
        assert!(out.iter().flatten().all(|v| v.is_finite()));
        assert_eq!(out[100], [1.0; 3]);
        assert!(out.iter().all(|p| (p[1] - 1.0).abs() < 1e-6));
    }
}
