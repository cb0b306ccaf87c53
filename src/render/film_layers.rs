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
//! splats of [`super::circles`] (light scattered more than once, shared
//! between pixels) go with the ray through their pixel's centre: in the one
//! row of pixels the horizon crosses, the ground and sky layers split that
//! pixel's multiply scattered light by its centre, not sample by sample.
//!
//! The sums are [`ExactSum`]s like the beauty's: the sky's is the beauty's
//! minus the other two, exactly, so it needs no memory of its own. The
//! sun's, non-zero on a few pixels only, are kept per row as a short list.

use super::exact::ExactSum;
use super::film::{try_filled, Film};
use crate::spectrum::xyz_to_rec709;

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
    pub(crate) ground: Vec<[ExactSum; 3]>,
    /// Per row, the columns where the disc was seen and their weighted
    /// XYZ sums of it.
    pub(crate) sun: Vec<Vec<(u32, [ExactSum; 3])>>,
    /// Per pixel, whether the ray through its centre meets the ground
    /// (where its splats go).
    pub(crate) centre_ground: Vec<bool>,
}

/// One row's layer sums, for the thread that renders the row.
pub(crate) struct LayerRow<'a> {
    ground: &'a mut [[ExactSum; 3]],
    sun: &'a mut Vec<(u32, [ExactSum; 3])>,
}

impl LayerRow<'_> {
    /// Adds a camera sample of weight `weight` at column `x`.
    pub(crate) fn add(&mut self, x: usize, weight: f64, xyz: [f64; 3], split: &SampleSplit) {
        if split.ground {
            for (s, v) in self.ground[x].iter_mut().zip(xyz) {
                *s += ExactSum::from_f64(weight * v);
            }
        } else if split.sun_xyz.iter().any(|&v| v != 0.0) {
            let column = x as u32;
            let at = self
                .sun
                .iter()
                .position(|e| e.0 == column)
                .unwrap_or_else(|| {
                    self.sun.push((column, [ExactSum::ZERO; 3]));
                    self.sun.len() - 1
                });
            for (s, v) in self.sun[at].1.iter_mut().zip(split.sun_xyz) {
                *s += ExactSum::from_f64(weight * v);
            }
        }
    }

    /// Empties the row, as [`Film::drop_draft`] empties its XYZ.
    pub(crate) fn clear(&mut self) {
        self.ground.fill([ExactSum::ZERO; 3]);
        self.sun.clear();
    }
}

impl LayerSums {
    /// Per row, the row's layer sums (the `ground` sums are `width` a row).
    pub(crate) fn rows(&mut self, width: usize) -> Vec<LayerRow<'_>> {
        self.ground
            .chunks_mut(width)
            .zip(self.sun.iter_mut())
            .map(|(ground, sun)| LayerRow { ground, sun })
            .collect()
    }

    /// The disc's sums at pixel `index` of a `width`-wide image.
    fn sun_at(&self, index: usize, width: usize) -> [ExactSum; 3] {
        let column = (index % width) as u32;
        self.sun[index / width]
            .iter()
            .find(|e| e.0 == column)
            .map_or([ExactSum::ZERO; 3], |e| e.1)
    }
}

impl Film {
    /// The film with the sums of the `sky`, `sun` and `ground` layers;
    /// `centre_ground[i]`: whether the ray through pixel `i`'s centre
    /// meets the ground.
    pub(crate) fn try_with_layers(
        mut self,
        centre_ground: Vec<bool>,
    ) -> Result<Self, std::collections::TryReserveError> {
        let mut sun = Vec::new();
        sun.try_reserve_exact(self.height as usize)?;
        sun.resize(self.height as usize, Vec::new());
        self.layers = Some(LayerSums {
            ground: try_filled(self.xyz_sum.len(), [ExactSum::ZERO; 3])?,
            sun,
            centre_ground,
        });
        Ok(self)
    }

    /// The `sky`, `sun` and `ground` images (linear Rec.709, cd m⁻² for
    /// Y, read as [`Film::xyz`] reads the beauty), row-major; `None`
    /// without layer sums.
    pub fn try_layer_images(
        &self,
    ) -> Result<Option<[Vec<[f32; 3]>; 3]>, std::collections::TryReserveError> {
        let Some(layers) = &self.layers else {
            return Ok(None);
        };
        let w = self.width as usize;
        let n = self.xyz_sum.len();
        let sun = |i: usize| layers.sun_at(i, w);
        let ground = |i: usize| layers.ground[i];
        let sky = |i: usize| {
            let (s, g, d) = (self.xyz_sum[i], ground(i), sun(i));
            [0, 1, 2].map(|c| s[c] - g[c] - d[c])
        };
        let in_ground = |i: usize| layers.centre_ground[i];
        let in_sky = |i: usize| !layers.centre_ground[i];
        let never = |_: usize| false;
        let mut images = [Vec::new(), Vec::new(), Vec::new()];
        for image in &mut images {
            image.try_reserve_exact(n)?;
        }
        for i in 0..n {
            let rgb = |xyz: [f64; 3]| xyz_to_rec709(xyz).map(|v| v as f32);
            images[0].push(rgb(self.mean_with(i, &sky, &in_sky)));
            images[1].push(rgb(self.mean_with(i, &sun, &never)));
            images[2].push(rgb(self.mean_with(i, &ground, &in_ground)));
        }
        Ok(Some(images))
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
    pass_y: Vec<f64>,
    pass_w: Vec<f64>,
    /// This pass's splats' luminance sums (empty without splats).
    pass_splat_y: Vec<f32>,
    /// Σ Wₚ, Σ Wₚ eₚ and Σ Wₚ eₚ² per pixel.
    sum_w: Vec<f64>,
    sum_we: Vec<f64>,
    sum_wee: Vec<f64>,
    /// Passes counted.
    batches: u32,
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
    /// Per row, the row's pass sums.
    pub(crate) fn rows(&mut self, width: usize) -> Vec<VarianceRow<'_>> {
        self.pass_y
            .chunks_mut(width)
            .zip(self.pass_w.chunks_mut(width))
            .map(|(y, w)| VarianceRow { y, w })
            .collect()
    }

    /// Adds a splat of luminance `y` at `pixel` to this pass's.
    pub(crate) fn add_splat(&mut self, pixel: usize, y: f64) {
        if let Some(s) = self.pass_splat_y.get_mut(pixel) {
            *s += y as f32;
        }
    }
}

impl Film {
    /// The film with the sums of the `variance` layer.
    pub(crate) fn try_with_variance(mut self) -> Result<Self, std::collections::TryReserveError> {
        let n = self.xyz_sum.len();
        self.variance = Some(VarianceSums {
            pass_y: try_filled(n, 0.0)?,
            pass_w: try_filled(n, 0.0)?,
            pass_splat_y: if self.splats() {
                try_filled(n, 0.0)?
            } else {
                Vec::new()
            },
            sum_w: try_filled(n, 0.0)?,
            sum_we: try_filled(n, 0.0)?,
            sum_wee: try_filled(n, 0.0)?,
            batches: 0,
        });
        Ok(self)
    }

    /// Empties the pass sums before pass `pass`.
    pub(crate) fn start_variance_pass(&mut self) {
        if let Some(v) = &mut self.variance {
            v.pass_y.fill(0.0);
            v.pass_w.fill(0.0);
            v.pass_splat_y.fill(0.0);
        }
    }

    /// Counts the pass just rendered by every row (`pass`, with
    /// `splat_paths` splat paths) as one batch; the draft pass is not one.
    pub(crate) fn end_variance_pass(&mut self, pass: u32, splat_paths: u64) {
        let (w, h) = (self.width as usize, self.height as usize);
        let mirror = self.mirror;
        let Some(v) = self.variance.as_mut().filter(|_| pass >= 1) else {
            return;
        };
        for i in 0..w * h {
            let partner = mirror
                .map(|m| m.partner(i % w, i / w, w, h))
                .filter(|&p| p != i);
            let pair = || std::iter::once(i).chain(partner);
            let weight: f64 = pair().map(|p| v.pass_w[p]).sum();
            if weight <= 0.0 {
                continue;
            }
            let mut e = pair().map(|p| v.pass_y[p]).sum::<f64>() / weight;
            if splat_paths > 0 && !v.pass_splat_y.is_empty() {
                let n = pair().count() as f64;
                let splats: f64 = pair().map(|p| f64::from(v.pass_splat_y[p])).sum();
                e += splats / (n * splat_paths as f64);
            }
            v.sum_w[i] += weight;
            v.sum_we[i] += weight * e;
            v.sum_wee[i] += weight * e * e;
        }
        v.batches += 1;
    }

    /// The `variance.Y` plane: per pixel the estimated variance of its mean
    /// luminance, (cd m⁻²)²; `None` without variance sums or before two
    /// full passes.
    pub fn variance_plane(&self) -> Option<Vec<f32>> {
        let v = self.variance.as_ref().filter(|v| v.batches >= 2)?;
        let p = f64::from(v.batches);
        Some(
            (0..self.xyz_sum.len())
                .map(|i| {
                    let (w, we, wee) = (v.sum_w[i], v.sum_we[i], v.sum_wee[i]);
                    if w <= 0.0 {
                        return 0.0;
                    }
                    ((wee - we * we / w).max(0.0) / ((p - 1.0) * w)) as f32
                })
                .collect(),
        )
    }
}
