//! Adaptive sampling: how many samples each pixel takes per pass, planned
//! from the image so far. A pixel's count follows the spread of its
//! neighbours' luminance (its own value left out, so the plan does not
//! depend on the pixel's own noise and the estimate stays unbiased),
//! relative to the image's median spread.

use rayon::prelude::*;

/// Most samples per pass a planned pixel takes: with mirror pairs a pair
/// reads twice the samples, and a cap of 8 held back the pairs that need
/// the most (the decisions table of `BENCHMARKS.md`).
pub const MAX_SAMPLES_PER_PASS: u8 = 16;
/// Half-width of the neighbourhood whose spread plans a pixel's samples,
/// pixels (a 9×9 window without its centre).
const PLAN_RADIUS: usize = 4;
/// Samples per pass ≈ this × (neighbourhood spread / median spread), clamped
/// to 1–[`MAX_SAMPLES_PER_PASS`]. 1.0 and 1.5 measured alike on the four
/// benchmark scenes (time ratios of uniform sampling 1.15–1.41 and
/// 1.14–1.50, `BENCHMARKS.md`); 1.5 won at midday and twilight.
/// On the folded image of mirror pairs, 1.25 with a cap of 16.
const PLAN_SCALE: f64 = 1.25;
/// Resolution of the spreads' histogram, bins per octave: the median is the
/// geometric centre of the lower median's bin, within 2^(1/16) (4.4 %) of
/// it — plenty for a sample count.
const BINS_PER_OCTAVE: f32 = 8.0;
/// log₂ of the smallest positive f32 is −149: bin = ⌊(log₂ σ + 150) × 8⌋.
const LOG2_OFFSET: f32 = 150.0;
/// Bins: 0 for σ = 0 (not counted), then up to log₂ σ = 128.
const BINS: usize = ((LOG2_OFFSET + 129.0) * BINS_PER_OCTAVE) as usize;

/// Samples per pass for a `width`×`height` image of luminances (row-major):
/// [`PLAN_SCALE`] × σᵢ / σ̃ᵢ, rounded and clamped to
/// 1–[`MAX_SAMPLES_PER_PASS`]. σᵢ is the standard deviation of the values in
/// the window Wᵢ of (2R+1)² pixels about pixel i (clipped at the borders)
/// *without* pixel i. σ̃ᵢ is the median of the positive σⱼ over the pixels j
/// outside Wᵢ — exactly those whose windows miss pixel i — so no part of
/// the plan of pixel i reads pixel i's value. A median, not a mean: the
/// sun's disc or one firefly in a window makes its σⱼ millions of times the
/// rest, and a mean would then give every other pixel one sample.
pub(super) fn plan(luminance: &[f32], width: usize, height: usize) -> Vec<u8> {
    plan_linked(luminance, width, height, &|x| [x, x])
}

/// [`plan`] for an image whose pixel (x, y) is read together with pixels
/// (`linked(x)`[k], y) (a [`super::HalfMirror`]'s partners): σᵢ leaves
/// those out of its window too, and σ̃ᵢ is the median over the pixels
/// whose windows miss pixel i *and* its linked pixels — so the plan of
/// pixel i reads none of the values read with it. (The partners' own
/// plans leave out pixel i in turn: linked both ways.)
pub(super) fn plan_linked(
    luminance: &[f32],
    width: usize,
    height: usize,
    linked: &(dyn Fn(usize) -> [usize; 2] + Sync),
) -> Vec<u8> {
    let spread = spreads(luminance, width, height, linked);
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
        let mut window = [0u16; 3 * (2 * PLAN_RADIUS + 1) * (2 * PLAN_RADIUS + 1)];
        for (x, m) in row.iter_mut().enumerate() {
            // The columns of the windows about pixel x and its linked
            // pixels, as disjoint ranges.
            let mut spans = [x, linked(x)[0], linked(x)[1]]
                .map(|c| c.saturating_sub(r)..(c + r + 1).min(width));
            spans.sort_by_key(|s| s.start);
            let (mut columns, mut count) = ([0..0, 0..0, 0..0], 0);
            for span in spans {
                match columns[..count].last_mut() {
                    Some(last) if span.start <= last.end => last.end = last.end.max(span.end),
                    _ => {
                        columns[count] = span;
                        count += 1;
                    }
                }
            }
            let mut n = 0;
            for yy in rows.clone() {
                for span in &columns[..count] {
                    for &b in &bins[yy * width + span.start..yy * width + span.end] {
                        if b > 0 {
                            window[n] = b;
                            n += 1;
                        }
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
            let samples = PLAN_SCALE * f64::from(spread[y * width + x]) / bin_centre(lo);
            if samples.is_finite() {
                *m = samples.round().clamp(1.0, f64::from(MAX_SAMPLES_PER_PASS)) as u8;
            }
        }
    });
    plan
}

/// The standard deviation σᵢ of the luminance over each pixel's window of
/// (2R+1)² pixels, R = [`PLAN_RADIUS`], clipped at the borders, *without*
/// the pixel itself and the pixels `linked` to it (0 with fewer than two
/// others). Each window is read
/// afresh, its centre skipped: pixel i's value enters no sum of σᵢ, not even
/// through rounding (sliding sums that add and later subtract it would keep
/// a trace of it; so would subtracting it from a total).
fn spreads(
    luminance: &[f32],
    width: usize,
    height: usize,
    linked: &(dyn Fn(usize) -> [usize; 2] + Sync),
) -> Vec<f32> {
    let r = PLAN_RADIUS;
    let mut spread = vec![0.0f32; width * height];
    spread
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, row)| {
            let rows = y.saturating_sub(r)..(y + r + 1).min(height);
            for (x, spread) in row.iter_mut().enumerate() {
                let columns = x.saturating_sub(r)..(x + r + 1).min(width);
                let [a, b] = linked(x);
                let left_out =
                    |(xx, yy): (usize, usize)| yy == y && (xx == x || xx == a || xx == b);
                let others = || {
                    rows.clone()
                        .flat_map(|yy| columns.clone().map(move |xx| (xx, yy)))
                        .filter(|&p| !left_out(p))
                        .map(|(xx, yy)| f64::from(luminance[yy * width + xx]))
                };
                let mut left = [x, a, b];
                left.sort_unstable();
                let dropped = (0..3)
                    .filter(|&k| (k == 0 || left[k] != left[k - 1]) && columns.contains(&left[k]))
                    .count();
                let n = (rows.len() * columns.len() - dropped) as f64;
                if n < 2.0 {
                    continue;
                }
                let mean = others().sum::<f64>() / n;
                let variance = others().map(|v| (v - mean) * (v - mean)).sum::<f64>() / (n - 1.0);
                *spread = variance.sqrt() as f32;
            }
        });
    spread
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

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// A deterministic pseudo-random value in [0, 1) per index.
    pub(crate) fn hash01(i: usize) -> f32 {
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
        // what keeps its mean unbiased): its own spread and those of the
        // pixels outside its window — all the plan reads besides integer
        // counts — stay bit for bit the same whatever its value, and so does
        // its plan; its neighbours' plans may change.
        let (w, h) = (30, 20);
        let image: Vec<f32> = (0..w * h).map(|i| 50.0 + 30.0 * hash01(i)).collect();
        let (spread, m) = (spreads(&image, w, h, &|x| [x, x]), plan(&image, w, h));
        let r = PLAN_RADIUS;
        for i in [0, 7 * w + 11, w * h - 1, 3 * w, 12 * w + 29] {
            for v in [0.0, 1e6, 1e9, f32::MAX] {
                let mut changed = image.clone();
                changed[i] = v;
                let after = spreads(&changed, w, h, &|x| [x, x]);
                let far = |j: usize| (i % w).abs_diff(j % w) > r || (i / w).abs_diff(j / w) > r;
                for j in (0..w * h).filter(|&j| j == i || far(j)) {
                    assert_eq!(
                        after[j].to_bits(),
                        spread[j].to_bits(),
                        "pixel {i} = {v}: σ of {j}"
                    );
                }
                assert_eq!(plan(&changed, w, h)[i], m[i], "pixel {i} set to {v}");
            }
        }
        let mut bright = image.clone();
        bright[7 * w + 11] = 1e6;
        assert_ne!(plan(&bright, w, h)[7 * w + 12], m[7 * w + 12]);
    }

    #[test]
    fn a_pixels_linked_plan_ignores_its_partners_values() {
        // With a half mirror (K = 13 on a 30-wide image) pixel (x, y) is read
        // with pixels (13 − x, y) and (12 − x, y) (mod 30): its plan must not
        // read theirs either, nor theirs its — whatever any of the three
        // holds, near the mirror's line (columns 6, 7), its far side (21,
        // 22) and elsewhere.
        let (w, h) = (30usize, 20usize);
        let linked = |x: usize| [(13 + w - x) % w, (12 + w - x) % w];
        let image: Vec<f32> = (0..w * h).map(|i| 50.0 + 30.0 * hash01(i)).collect();
        let m = plan_linked(&image, w, h, &linked);
        for y in [0, 9, 19] {
            for x in [0, 3, 6, 7, 8, 21, 22, 29] {
                let i = y * w + x;
                let [a, b] = linked(x);
                for j in [i, y * w + a, y * w + b] {
                    for v in [0.0, 1e6, f32::MAX] {
                        let mut changed = image.clone();
                        changed[j] = v;
                        let after = plan_linked(&changed, w, h, &linked);
                        assert_eq!(after[i], m[i], "pixel ({x}, {y}), pixel {j} set to {v}");
                    }
                }
            }
        }
        // Unlinked, the same plan as `plan`.
        assert_eq!(plan_linked(&image, w, h, &|x| [x, x]), plan(&image, w, h));
        // A bright partner changes the plan where it is not left out.
        let mut bright = image.clone();
        bright[9 * w + 13] = 1e6;
        assert_ne!(
            plan(&bright, w, h)[9 * w + 12],
            plan(&image, w, h)[9 * w + 12]
        );
    }

    #[test]
    fn a_black_band_below_a_bright_one_stays_black() {
        // Rows of zeros under noisy bright rows: their spreads must be
        // exactly zero (not the rounding residue of sums that once held the
        // bright rows), so they stay out of the median and the bright band,
        // evenly noisy, does not take the cap everywhere.
        let (w, h) = (30, 30);
        let image: Vec<f32> = (0..w * h)
            .map(|i| {
                // Heavy-tailed (10⁴ to 10⁷): no f64 sum holds their squares exactly.
                if i / w < 10 {
                    1e4 / (hash01(i) + 1e-3)
                } else {
                    0.0
                }
            })
            .collect();
        let spread = spreads(&image, w, h, &|x| [x, x]);
        assert!(spread[(10 + PLAN_RADIUS) * w..].iter().all(|&s| s == 0.0));
        let m = plan(&image, w, h);
        for y in 10 + PLAN_RADIUS..h {
            assert!((0..w).all(|x| m[y * w + x] == 1), "row {y}");
        }
        let band = &m[..(10 - PLAN_RADIUS) * w];
        let capped = band.iter().filter(|&&v| v >= MAX_SAMPLES_PER_PASS).count();
        assert!(
            capped < band.len() / 2,
            "{capped} of {} at the cap",
            band.len()
        );
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
                assert_eq!(
                    f64::from(m[i]),
                    exact.round().clamp(1.0, f64::from(MAX_SAMPLES_PER_PASS)),
                    "pixel {i}"
                );
                checked += 1;
            }
        }
        assert!(checked > w * h * 9 / 10);
        assert!(m.iter().any(|&v| v > 1) && m.contains(&1));
    }
}
