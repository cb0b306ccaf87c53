//! The `sky`, `sun` and `ground` layers of a render (`render --layers`),
//! estimated from the beauty image's own camera samples and splats — no
//! second render — so that `sky + sun + ground` is the beauty image to
//! float precision and each layer is an unbiased estimate of its own light:
//!
//! - `sun`: the sun's disc seen straight along the camera ray, through the
//!   air's transmittance (`Light::disc` of the integrator): the attenuated
//!   solar disc alone, zero off the disc.
//! - `ground`: everything a camera ray that meets the ground brings back —
//!   the light the ground reflects toward the camera *and* the light
//!   scattered into the ray in the air in front of it (aerial
//!   perspective), so that the layer is the ground as it is seen and a
//!   matte over it replaces exactly what it shows.
//! - `sky`: the rest, the light scattered into the camera rays that leave
//!   the atmosphere (or go to space), without the disc.
//!
//! A camera sample goes to one layer by its own ray (`SampleSplit`). The
//! splats of [`super::circles`] and [`super::ground_circles`] (light
//! scattered more than once, and the skylight the ground reflects, shared
//! between pixels) go with the ray through their pixel's centre: in the one
//! row of pixels the horizon crosses, the ground and sky layers split that
//! pixel's splatted light by its centre, not sample by sample.
//!
//! The sums are [`ExactSum`]s like the beauty's: the sky's is the beauty's
//! minus the other two, exactly, so it needs no memory of its own. The
//! sun's, non-zero on a few pixels only, are kept per row as a short list.

use super::alloc::try_filled;
use super::camera::{HalfMirror, Mirror};
use super::exact::{column_entry, ExactPlane, ExactRow, ExactSum};

/// The layers the film estimates from its paths, as named in
/// [`crate::scene::OUTPUT_LAYERS`].
pub const PATH_LAYERS: [&str; 3] = ["sky", "sun", "ground"];

/// What one camera sample gives the layers beside its XYZ.
#[derive(Clone, Copy, Debug, Default)]
pub struct SampleSplit {
    /// XYZ of the sun's disc seen straight along the sample's ray (a part
    /// of the sample's XYZ).
    pub sun_xyz: [f64; 3],
    /// Whether the sample's ray meets the ground.
    pub ground: bool,
}

/// The layer sums of a film.
#[derive(Clone, Debug)]
pub(crate) struct LayerSums {
    /// Per pixel, the weighted XYZ sums of the camera samples whose ray
    /// meets the ground.
    pub(crate) ground: ExactPlane,
    /// Per row, the columns where the disc was seen and their weighted
    /// XYZ sums of it.
    pub(crate) sun: Vec<Vec<(u32, [ExactSum; 3])>>,
    /// Per pixel, whether the ray through its centre meets the ground
    /// (where its splats go).
    pub(crate) centre_ground: Vec<bool>,
}

/// One row's layer sums, for the thread that renders the row.
pub(crate) struct LayerRow<'a> {
    ground: ExactRow<'a>,
    sun: &'a mut Vec<(u32, [ExactSum; 3])>,
}

impl LayerRow<'_> {
    /// Adds a camera sample of weight `weight` at column `x`.
    pub(crate) fn add(&mut self, x: usize, weight: f64, xyz: [f64; 3], split: &SampleSplit) {
        if split.ground {
            self.ground
                .add(x, xyz.map(|v| ExactSum::from_f64(weight * v)));
        } else if split.sun_xyz.iter().any(|&v| v != 0.0) {
            for (s, v) in column_entry(self.sun, x).iter_mut().zip(split.sun_xyz) {
                *s += ExactSum::from_f64(weight * v);
            }
        }
    }

    /// Empties the row, as [`Film::drop_draft`] empties its XYZ.
    pub(crate) fn clear(&mut self) {
        self.ground.clear();
        self.sun.clear();
    }
}

impl LayerSums {
    /// Per row, the row's layer sums .
    pub(crate) fn rows(&mut self) -> Vec<LayerRow<'_>> {
        self.ground
            .rows_mut()
            .into_iter()
            .zip(self.sun.iter_mut())
            .map(|(ground, sun)| LayerRow { ground, sun })
            .collect()
    }

    /// The disc's sums at pixel `index` of a `width`-wide image.
    pub(super) fn sun_at(&self, index: usize, width: usize) -> [ExactSum; 3] {
        let column = (index % width) as u32;
        self.sun[index / width]
            .iter()
            .find(|e| e.0 == column)
            .map_or([ExactSum::ZERO; 3], |e| e.1)
    }
}

/// The sums behind the `variance` layer: the spread of each pixel's
/// per-pass estimates (batch means).
///
/// Each full pass p ≥ 1 gives pixel i an estimate eₚ of its luminance of
/// weight Wₚ (its camera samples' weight in the pass, with its mirror
/// partner's; plus the pass's splats into the pair over the pass's splat
/// paths). Modelling Var(eₚ) = σ²/Wₚ, σ̂² = Σ Wₚ (eₚ − ē)² / (P − 1) is
/// unbiased for σ² and Var(ē) ≈ σ̂² / Σ Wₚ: the variance of the pixel's
/// mean luminance, (cd m⁻²)². The draft pass (another estimator) is left
/// out. The renderer's low-discrepancy sequences make successive passes'
/// errors anti-correlated, which this treats as independent: the estimate
/// errs high, never low, on average (measured in `tests/layers.rs`).
#[derive(Clone, Debug)]
pub(crate) struct VarianceSums {
    /// This pass's weighted camera luminance sums and weights.
    pub(super) pass_y: Vec<f64>,
    pub(super) pass_w: Vec<f64>,
    /// This pass's splats' luminance sums (empty without splats).
    pub(super) pass_splat_y: Vec<f32>,
    /// Σ Wₚ, Σ Wₚ eₚ and Σ Wₚ eₚ² per pixel.
    pub(super) sum_w: Vec<f64>,
    pub(super) sum_we: Vec<f64>,
    pub(super) sum_wee: Vec<f64>,
    /// Passes counted.
    pub(super) batches: u32,
    /// Σ Wₚ and Σ Wₚ eₚ over the odd-numbered batches alone, where the film
    /// keeps its two halves ([`VarianceHalves`]).
    pub(super) odd: Option<[Vec<f64>; 2]>,
}

/// A pixel's luminance from the odd-numbered and the even-numbered
/// batches apart (`Film::variance_halves`): two estimates whose
/// noises are independent of each other (nearly: successive passes' Sobol
/// points are stratified against each other), by which the preview's
/// denoising tells its correction from noise (`render::denoise`).
#[derive(Clone, Debug)]
pub struct VarianceHalves {
    /// Per pixel, each half's mean luminance, cd m⁻² (NaN where the half
    /// has no weight there).
    pub mean_y: [Vec<f32>; 2],
}

/// One row's share of a pass's luminance sums, for the thread that
/// renders the row.
pub(crate) struct VarianceRow<'a> {
    y: &'a mut [f64],
    w: &'a mut [f64],
}

impl VarianceRow<'_> {
    /// Adds a camera sample of luminance `y` (cd m⁻²) and weight `weight`
    /// at column `x`.
    pub(crate) fn add(&mut self, x: usize, weight: f64, y: f64) {
        self.y[x] += weight * y;
        self.w[x] += weight;
    }
}

impl VarianceSums {
    /// Zero sums for `pixels` pixels (and their splats' pass sums, where
    /// the film `splats`).
    pub(super) fn try_new(
        pixels: usize,
        splats: bool,
    ) -> Result<Self, std::collections::TryReserveError> {
        Ok(Self {
            pass_y: try_filled(pixels, 0.0)?,
            pass_w: try_filled(pixels, 0.0)?,
            pass_splat_y: if splats {
                try_filled(pixels, 0.0)?
            } else {
                Vec::new()
            },
            sum_w: try_filled(pixels, 0.0)?,
            sum_we: try_filled(pixels, 0.0)?,
            sum_wee: try_filled(pixels, 0.0)?,
            batches: 0,
            odd: None,
        })
    }

    /// Empties the pass sums before a pass.
    pub(super) fn start_pass(&mut self) {
        self.pass_y.fill(0.0);
        self.pass_w.fill(0.0);
        self.pass_splat_y.fill(0.0);
    }

    /// Counts the pass just rendered into a film of `size` (width, height;
    /// its pixels read with their `mirror` partners), with `splat_paths`
    /// splat paths, as one batch.
    pub(super) fn end_pass(
        &mut self,
        size: (usize, usize),
        mirror: Option<Mirror>,
        splat_paths: u64,
    ) {
        let (w, h) = size;
        for i in 0..w * h {
            let partner = mirror
                .map(|m| m.partner(i % w, i / w, w, h))
                .filter(|&p| p != i);
            let pair = || std::iter::once(i).chain(partner);
            let weight: f64 = pair().map(|p| self.pass_w[p]).sum();
            if weight <= 0.0 {
                continue;
            }
            let mut e = pair().map(|p| self.pass_y[p]).sum::<f64>() / weight;
            if splat_paths > 0 && !self.pass_splat_y.is_empty() {
                let n = pair().count() as f64;
                let splats: f64 = pair().map(|p| f64::from(self.pass_splat_y[p])).sum();
                e += splats / (n * splat_paths as f64);
            }
            self.add_batch(i, weight, e);
        }
        self.batches += 1;
    }

    /// Per pixel the estimated variance of its mean luminance, of a film
    /// `width` pixels wide read with `halves` where it has them; `None`
    /// before two batches.
    ///
    /// A batch is a pixel's own samples (and splats) of one pass, so the
    /// batches' spread gives v, the variance of the pixel's own mean. With
    /// halves the film reads each part of a pixel with its partner's
    /// ([`super::film`], "Mirror halves"): a part of share s (g or 1 − g)
    /// holds s of the pixel's samples, uniform over it, so where the
    /// variance per sample is about even across the pixel the part's own
    /// mean has variance v / s; pooled with its partner p's part (as many
    /// samples) it has (v + v_p) / (4 s), and weighted by s² in the image
    /// it adds s (v + v_p) / 4 (s v alone where the part is its own
    /// partner). Together ¼ (v + g v_left + (1 − g) v_right): half the
    /// pixel's own variance where its partners' match it.
    pub(super) fn plane(&self, width: usize, halves: Option<HalfMirror>) -> Option<Vec<f32>> {
        let p = f64::from(self.batches);
        if self.batches < 2 {
            return None;
        }
        let own: Vec<f64> = (0..self.sum_w.len())
            .map(|i| {
                let (w, we, wee) = (self.sum_w[i], self.sum_we[i], self.sum_wee[i]);
                if w <= 0.0 {
                    return 0.0;
                }
                (wee - we * we / w).max(0.0) / ((p - 1.0) * w)
            })
            .collect();
        let Some(halves) = halves else {
            return Some(own.iter().map(|&v| v as f32).collect());
        };
        let g = halves.split;
        Some(
            (0..own.len())
                .map(|i| {
                    let (x, row) = (i % width, i - i % width);
                    let part = |share: f64, partner: usize| {
                        if partner == i {
                            share * own[i]
                        } else {
                            0.25 * share * (own[i] + own[partner])
                        }
                    };
                    let left = part(g, row + halves.left_partner(x, width));
                    let right = part(1.0 - g, row + halves.right_partner(x, width));
                    (left + right) as f32
                })
                .collect(),
        )
    }

    /// Per row, the row's pass sums.
    pub(crate) fn rows(&mut self, width: usize) -> Vec<VarianceRow<'_>> {
        self.pass_y
            .chunks_mut(width)
            .zip(self.pass_w.chunks_mut(width))
            .map(|(y, w)| VarianceRow { y, w })
            .collect()
    }

    /// Counts pixel `i`'s estimate `e` of weight `weight` in the batch
    /// being ended (number [`Self::batches`], counted from 0).
    fn add_batch(&mut self, i: usize, weight: f64, e: f64) {
        self.sum_w[i] += weight;
        self.sum_we[i] += weight * e;
        self.sum_wee[i] += weight * e * e;
        if let Some([w, we]) = self.odd.as_mut().filter(|_| self.batches % 2 == 1) {
            w[i] += weight;
            we[i] += weight * e;
        }
    }

    /// Keeps the two halves' sums too ([`VarianceHalves`]).
    pub(super) fn try_keep_halves(&mut self) -> Result<(), std::collections::TryReserveError> {
        let n = self.sum_w.len();
        self.odd = Some([try_filled(n, 0.0)?, try_filled(n, 0.0)?]);
        Ok(())
    }

    /// The two halves' means, once each has a batch; `None` where the film
    /// does not keep them.
    pub(super) fn halves(&self) -> Option<VarianceHalves> {
        let [odd_w, odd_we] = self.odd.as_ref().filter(|_| self.batches >= 2)?;
        let mean = |we: f64, w: f64| if w > 0.0 { (we / w) as f32 } else { f32::NAN };
        Some(VarianceHalves {
            mean_y: [
                odd_we
                    .iter()
                    .zip(odd_w)
                    .map(|(&we, &w)| mean(we, w))
                    .collect(),
                (0..self.sum_w.len())
                    .map(|i| mean(self.sum_we[i] - odd_we[i], self.sum_w[i] - odd_w[i]))
                    .collect(),
            ],
        })
    }

    /// Adds a splat of luminance `y` at `pixel` to this pass's.
    pub(crate) fn add_splat(&mut self, pixel: usize, y: f64) {
        if let Some(s) = self.pass_splat_y.get_mut(pixel) {
            *s += y as f32;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The odd-numbered batches make one half and the rest the other, each
    /// its weighted mean; none before each half has a batch, or where the
    /// film keeps no halves.
    #[test]
    fn the_halves_split_the_batches_by_their_parity() {
        let batches = |keep: bool, count: usize| {
            let mut v = VarianceSums::try_new(1, false).unwrap();
            if keep {
                v.try_keep_halves().unwrap();
            }
            for (b, e) in [1.0, 2.0, 4.0, 8.0, 16.0]
                .into_iter()
                .take(count)
                .enumerate()
            {
                v.add_batch(0, 1.0 + b as f64, e);
                v.batches += 1;
            }
            v
        };
        let halves = batches(true, 5).halves().unwrap();
        // Odd: batches 1 and 3 (weights 2 and 4); even: 0, 2 and 4.
        let odd = (2.0 * 2.0 + 4.0 * 8.0) / 6.0;
        let even = (1.0 + 3.0 * 4.0 + 5.0 * 16.0) / 9.0;
        assert!((f64::from(halves.mean_y[0][0]) - odd).abs() < 1e-5);
        assert!((f64::from(halves.mean_y[1][0]) - even).abs() < 1e-5);
        assert!(batches(true, 1).halves().is_none());
        assert!(batches(true, 2).halves().is_some());
        assert!(batches(false, 5).halves().is_none());
    }
}
