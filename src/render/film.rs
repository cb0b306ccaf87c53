//! The film: per-pixel weighted sums of XYZ samples, filled one pass at a
//! time and readable at any moment. Rows record how many passes they hold
//! and their total weight, so a pass interrupted half-way still reads back
//! coherently. Each sample's weight is fixed before it is drawn (by its
//! pass and, from the adaptive plan on, by nothing else), so the weighted
//! mean is unbiased.
//!
//! **Adaptive sampling.** After the first full pass the film can be given a
//! plan ([`Film::plan_samples`]): every later pass takes 1–8 samples per
//! pixel instead of one, more where the image was noisy. The plan of a pixel
//! is read from its *neighbours'* values only (leave-one-out), which are
//! independent of the pixel's own samples, so the number of samples a pixel
//! gets carries no information about their values and its mean stays
//! unbiased — unlike adaptive schemes that stop sampling a pixel once its
//! own estimate looks converged.

use rayon::prelude::*;

use crate::output::RgbImage;
use crate::spectrum::xyz_to_rec709;

/// Most samples per pass a planned pixel takes.
pub const MAX_SAMPLES_PER_PASS: u8 = 8;
/// Half-width of the neighbourhood whose spread plans a pixel's samples,
/// pixels (a 9×9 window without its centre).
const PLAN_RADIUS: usize = 4;
/// Samples per pass ≈ this × (neighbourhood spread / median spread), clamped
/// to 1–[`MAX_SAMPLES_PER_PASS`]. 1.0 and 1.5 measured alike on the four
/// benchmark scenes (time ratios of uniform sampling 1.15–1.41 and
/// 1.14–1.50, `BENCHMARKS.md`, session 9); 1.5 won at midday and twilight.
const PLAN_SCALE: f64 = 1.5;
/// Resolution of the spreads' histogram, bins per octave (the median is
/// taken to within 2^(1/8), 9 %: plenty for a sample count).
const BINS_PER_OCTAVE: f32 = 8.0;
/// log₂ of the smallest positive f32 is −149: bin = ⌊(log₂ σ + 150) × 8⌋.
const LOG2_OFFSET: f32 = 150.0;
/// Bins: 0 for σ = 0 (not counted), then up to log₂ σ = 128.
const BINS: usize = ((LOG2_OFFSET + 129.0) * BINS_PER_OCTAVE) as usize;

#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// Weighted sum of XYZ (cd m⁻² for Y) over the row's passes.
    pub(crate) xyz_sum: Vec<[f32; 3]>,
    pub(crate) row_passes: Vec<u32>,
    /// Sum of the weights of the row's passes (one sample each).
    pub(crate) row_weights: Vec<f64>,
    /// Samples per pass of each pixel under the plan; empty before it.
    pub(crate) plan: Vec<u8>,
    /// Passes the row took under the plan (each of a pixel's m samples has
    /// weight 1, so the pixel's weight is the row's plus (m − 1) per pass).
    pub(crate) row_planned_passes: Vec<u32>,
    /// Samples discarded as non-finite or negative.
    pub discarded: u64,
}

impl Film {
    pub fn new(width: u32, height: u32) -> Self {
        Self {
            width,
            height,
            xyz_sum: vec![[0.0; 3]; width as usize * height as usize],
            row_passes: vec![0; height as usize],
            row_weights: vec![0.0; height as usize],
            plan: Vec::new(),
            row_planned_passes: vec![0; height as usize],
            discarded: 0,
        }
    }

    /// Passes completed by every row.
    pub fn complete_passes(&self) -> u32 {
        self.row_passes.iter().copied().min().unwrap_or(0)
    }

    /// Whether [`Self::plan_samples`] has run.
    pub fn is_planned(&self) -> bool {
        !self.plan.is_empty()
    }

    /// Samples per pass of pixel `index` (row-major): 1 before the plan.
    pub fn samples_per_pass(&self, index: usize) -> u32 {
        self.plan.get(index).map_or(1, |&m| u32::from(m))
    }

    /// 1 / (total weight) of pixel `index` in row `y` (1 before the first pass).
    fn pixel_scale(&self, y: usize, index: usize) -> f64 {
        let extra = f64::from(self.samples_per_pass(index) - 1);
        let w = self.row_weights[y] + extra * f64::from(self.row_planned_passes[y]);
        if w > 0.0 {
            1.0 / w
        } else {
            1.0
        }
    }

    /// Mean XYZ of one pixel.
    pub fn xyz(&self, x: u32, y: u32) -> [f64; 3] {
        let index = (y * self.width + x) as usize;
        let scale = self.pixel_scale(y as usize, index);
        self.xyz_sum[index].map(|v| f64::from(v) * scale)
    }

    /// The current estimate as linear Rec.709 (Y in cd m⁻²).
    pub fn to_rgb(&self) -> RgbImage {
        let w = self.width as usize;
        let pixels = self
            .xyz_sum
            .iter()
            .enumerate()
            .map(|(i, s)| {
                let scale = self.pixel_scale(i / w, i);
                xyz_to_rec709(s.map(|v| f64::from(v) * scale)).map(|c| c as f32)
            })
            .collect();
        RgbImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// Fix every pixel's samples per pass for the passes to come from the
    /// current image (see the module documentation): ∝ the standard
    /// deviation of the luminance over the pixel's neighbourhood without the
    /// pixel itself. Where the image is flat and clean that is small; where it
    /// is noisy or bright and structured (the aureole, a twilight glow), large
    /// — the absolute variance the mean of a pixel carries scales with both.
    pub fn plan_samples(&mut self) {
        let luminance: Vec<f32> = (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .map(|(x, y)| self.xyz(x, y)[1] as f32)
            .collect();
        self.plan = plan(&luminance, self.width as usize, self.height as usize);
    }
}

/// Samples per pass for a `width`×`height` image of luminances (row-major):
/// [`PLAN_SCALE`] × σᵢ / σ̃ᵢ, rounded and clamped to
/// 1–[`MAX_SAMPLES_PER_PASS`]. σᵢ is the standard deviation of the values in
/// the window Wᵢ of (2R+1)² pixels about pixel i (clipped at the borders)
/// *without* pixel i. σ̃ᵢ is the median of the positive σⱼ over the pixels j
/// outside Wᵢ — exactly those whose windows miss pixel i — so no part of
/// the plan of pixel i reads pixel i's value. A median, not a mean: the
/// sun's disc or one firefly in a window makes its σⱼ millions of times the
/// rest, and a mean would then give every other pixel one sample.
fn plan(luminance: &[f32], width: usize, height: usize) -> Vec<u8> {
    let mut spread = vec![0.0f32; width * height];
    for_each_window(luminance, width, height, |i, sum, sum_sq, n| {
        let own = f64::from(luminance[i]);
        let (s, s2, n) = (sum - own, sum_sq - own * own, (n - 1) as f64);
        if n >= 2.0 {
            let mean = s / n;
            spread[i] = ((s2 / n - mean * mean).max(0.0) * n / (n - 1.0)).sqrt() as f32;
        }
    });
    let bins: Vec<u16> = spread.iter().map(|&s| spread_bin(s)).collect();
    // cumulative[b] = positive spreads in bins ≤ b.
    let mut cumulative = vec![0u32; BINS];
    for &b in &bins {
        cumulative[usize::from(b)] += u32::from(b > 0);
    }
    for b in 1..BINS {
        cumulative[b] += cumulative[b - 1];
    }
    let positive = cumulative[BINS - 1];
    let r = PLAN_RADIUS;
    let mut plan = vec![1u8; width * height];
    plan.par_chunks_mut(width).enumerate().for_each(|(y, row)| {
        let rows = y.saturating_sub(r)..(y + r + 1).min(height);
        let mut window = [0u16; (2 * PLAN_RADIUS + 1) * (2 * PLAN_RADIUS + 1)];
        for (x, m) in row.iter_mut().enumerate() {
            let columns = x.saturating_sub(r)..(x + r + 1).min(width);
            let mut n = 0;
            for yy in rows.clone() {
                for &b in &bins[yy * width + columns.start..yy * width + columns.end] {
                    if b > 0 {
                        window[n] = b;
                        n += 1;
                    }
                }
            }
            let far = positive - n as u32;
            if far == 0 {
                continue;
            }
            // The far set's lower median: the first bin b whose far count
            // (cumulative − the window's) passes rank k. That count grows
            // with b, so bisect between the bins where the whole image's
            // count passes k and k + n.
            let k = (far - 1) / 2;
            let far_below = |b: usize| {
                cumulative[b] - window[..n].iter().filter(|&&w| usize::from(w) <= b).count() as u32
            };
            let mut lo = cumulative.partition_point(|&c| c <= k);
            let mut hi = cumulative.partition_point(|&c| c <= k + n as u32);
            while lo < hi {
                let mid = usize::midpoint(lo, hi);
                if far_below(mid) > k {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            let median = bin_centre(lo);
            let samples = PLAN_SCALE * f64::from(spread[y * width + x]) / median;
            *m = samples.round().clamp(1.0, f64::from(MAX_SAMPLES_PER_PASS)) as u8;
        }
    });
    plan
}

/// Histogram bin of a spread: 0 for zero (or non-finite), else its log₂
/// scaled by [`BINS_PER_OCTAVE`].
fn spread_bin(spread: f32) -> u16 {
    if spread > 0.0 && spread.is_finite() {
        ((spread.log2() + LOG2_OFFSET) * BINS_PER_OCTAVE).clamp(1.0, (BINS - 1) as f32) as u16
    } else {
        0
    }
}

/// The geometric centre of bin `b`'s spreads.
fn bin_centre(b: usize) -> f64 {
    ((b as f64 + 0.5) / f64::from(BINS_PER_OCTAVE) - f64::from(LOG2_OFFSET)).exp2()
}

/// Calls `f(i, Σ v, Σ v², n)` for every pixel i of a `width`×`height` image
/// (row-major) over the n values in its window of (2R+1)² pixels, R =
/// [`PLAN_RADIUS`], clipped at the borders. Runs a sliding window over
/// per-column sums (f64), so memory stays O(width) however large the image.
fn for_each_window(
    values: &[f32],
    width: usize,
    height: usize,
    mut f: impl FnMut(usize, f64, f64, usize),
) {
    let r = PLAN_RADIUS;
    let mut col_sum = vec![0.0f64; width];
    let mut col_sq = vec![0.0f64; width];
    let (mut top, mut bottom) = (0usize, 0usize); // window rows [top, bottom)
    let update = |row: usize, sign: f64, col_sum: &mut [f64], col_sq: &mut [f64]| {
        for (x, &v) in values[row * width..(row + 1) * width].iter().enumerate() {
            let v = f64::from(v);
            col_sum[x] += sign * v;
            col_sq[x] += sign * v * v;
        }
    };
    for y in 0..height {
        while bottom < (y + r + 1).min(height) {
            update(bottom, 1.0, &mut col_sum, &mut col_sq);
            bottom += 1;
        }
        while top < y.saturating_sub(r) {
            update(top, -1.0, &mut col_sum, &mut col_sq);
            top += 1;
        }
        for x in 0..width {
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(width));
            let sum = col_sum[x0..x1].iter().sum();
            let sum_sq = col_sq[x0..x1].iter().sum();
            f(y * width + x, sum, sum_sq, (bottom - top) * (x1 - x0));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A deterministic pseudo-random value in [0, 1) per index.
    fn hash01(i: usize) -> f32 {
        let mut z = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0xdead_beef;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        (z >> 40) as f32 / (1u64 << 24) as f32
    }

    #[test]
    fn a_flat_image_takes_one_sample_everywhere() {
        assert!(plan(&[5.0; 12 * 10], 12, 10).iter().all(|&m| m == 1));
        assert!(plan(&[0.0; 12 * 10], 12, 10).iter().all(|&m| m == 1));
    }

    #[test]
    fn noisy_regions_get_more_samples_within_the_cap() {
        // Three quarters faintly noisy (σ ≈ 0.3 about 100), the last quarter
        // noisy (σ ≈ 29): the median spread is the faint one.
        let (w, h) = (40, 20);
        let image: Vec<f32> = (0..w * h)
            .map(|i| {
                let amplitude = if i % w < 3 * w / 4 { 1.0 } else { 100.0 };
                100.0 + amplitude * (hash01(i) - 0.5)
            })
            .collect();
        let m = plan(&image, w, h);
        assert!(m.iter().all(|&v| (1..=MAX_SAMPLES_PER_PASS).contains(&v)));
        let mean = |range: std::ops::Range<usize>| {
            let px: Vec<f64> = (0..h)
                .flat_map(|y| range.clone().map(move |x| y * w + x))
                .map(|i| f64::from(m[i]))
                .collect();
            px.iter().sum::<f64>() / px.len() as f64
        };
        let (clean, noisy) = (
            mean(0..3 * w / 4 - PLAN_RADIUS),
            mean(3 * w / 4 + PLAN_RADIUS..w),
        );
        // About the median: PLAN_SCALE samples, rounded either way.
        assert!(
            (1.0..=PLAN_SCALE.ceil()).contains(&clean),
            "faint part: {clean}"
        );
        assert!(
            (noisy - f64::from(MAX_SAMPLES_PER_PASS)).abs() < 1e-12,
            "noisy part: {noisy} samples per pass"
        );
    }

    #[test]
    fn a_pixels_plan_ignores_its_own_value() {
        // The plan of pixel i must not depend on pixel i's samples (that is
        // what keeps its mean unbiased); its neighbours' plans may.
        let (w, h) = (30, 20);
        let image: Vec<f32> = (0..w * h).map(|i| 50.0 + 30.0 * hash01(i)).collect();
        let before = plan(&image, w, h);
        for i in [0, 7 * w + 11, w * h - 1, 3 * w, 12 * w + 29] {
            for v in [0.0, 1e6] {
                let mut changed = image.clone();
                changed[i] = v;
                let after = plan(&changed, w, h);
                assert_eq!(after[i], before[i], "pixel {i} set to {v}");
            }
        }
        let mut bright = image.clone();
        bright[7 * w + 11] = 1e6;
        assert_ne!(plan(&bright, w, h)[7 * w + 12], before[7 * w + 12]);
    }

    #[test]
    fn window_sums_match_a_direct_computation() {
        let (w, h) = (23, 17);
        // Noise growing fourfold from left to right.
        let image: Vec<f32> = (0..w * h)
            .map(|i| 10.0 * (1.0 + 3.0 * (i % w) as f32 / w as f32) * hash01(i).powi(3))
            .collect();
        let r = PLAN_RADIUS as i64;
        let window = |i: usize| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            (-r..=r)
                .flat_map(move |dy| (-r..=r).map(move |dx| (x + dx, y + dy)))
                .filter(|&(xx, yy)| (0..w as i64).contains(&xx) && (0..h as i64).contains(&yy))
                .map(|(xx, yy)| yy as usize * w + xx as usize)
                .collect::<Vec<_>>()
        };
        let spread: Vec<f64> = (0..w * h)
            .map(|i| {
                let v: Vec<f64> = window(i)
                    .into_iter()
                    .filter(|&j| j != i)
                    .map(|j| f64::from(image[j]))
                    .collect();
                let n = v.len() as f64;
                let mean = v.iter().sum::<f64>() / n;
                (v.iter().map(|a| (a - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
            })
            .collect();
        let m = plan(&image, w, h);
        let mut checked = 0;
        for i in 0..w * h {
            let near = window(i);
            let mut far: Vec<u16> = (0..w * h)
                .filter(|j| !near.contains(j))
                .map(|j| spread_bin(spread[j] as f32))
                .filter(|&b| b > 0)
                .collect();
            far.sort_unstable();
            let median = bin_centre(usize::from(far[(far.len() - 1) / 2]));
            let exact = PLAN_SCALE * spread[i] / median;
            // Rounding ties may fall either way by floating-point error.
            if (exact.fract() - 0.5).abs() > 1e-4 {
                assert_eq!(f64::from(m[i]), exact.round().clamp(1.0, 8.0), "pixel {i}");
                checked += 1;
            }
        }
        assert!(checked > w * h * 9 / 10);
        assert!(m.iter().any(|&v| v > 1) && m.contains(&1));
    }
}
