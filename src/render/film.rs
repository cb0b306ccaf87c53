//! The film: per-pixel weighted sums of XYZ samples, filled one pass at a
//! time and readable at any moment. Rows record how many passes they hold
//! and their total weight, so a pass interrupted half-way still reads back
//! coherently. A pixel's value is Σ wₛ xₛ / Σ wₛ over its samples, each
//! weight set by the sample's pass alone (the draft's by the sun's
//! elevation, `super::draft_weight`; 1 otherwise) and the number of samples
//! by nothing the pixel's own samples influence, so the mean is unbiased.
//! With the renderer splatting along the circles of symmetry
//! (`super::circles`), the film also holds each pixel's sum of splats and
//! the number of paths splatted, and a pixel's value is its samples' mean
//! plus the splats' sum over the paths; a row that holds only the draft
//! pass shows the draft alone, which it drops when its first full pass
//! starts (the draft estimates every order, later samples only what is not
//! splatted).
//!
//! **Adaptive sampling.** After the first full pass the renderer gives the
//! film a plan (`Film::plan_samples`): every later pass takes 1–16 samples
//! per pixel instead of one, more where the image was noisy. The plan of a
//! pixel is read from its *neighbours'* values only (leave-one-out), which
//! are independent of the pixel's own samples (every pixel — with mirror
//! pairs, below, every pair — has its own random streams), so the number
//! of samples a pixel gets carries no information about their values and
//! its mean stays unbiased — unlike adaptive schemes that stop sampling a
//! pixel once its own estimate looks converged.
//!
//! **Mirror pairs.** The sky is mirror-symmetric about the sun's vertical
//! plane: the atmosphere is spherically symmetric (a function of altitude
//! alone), the ground uniform, the sun a disc. Where the camera maps that
//! reflection onto the pixel grid ([`Mirror`], from `Camera::mirror`), a
//! pixel and its mirror image have the same expected value, so the film
//! reads both as the mean of their samples together: twice the samples per
//! pixel at no cost, unbiased because each pixel's samples are. The plan
//! then works on the *folded* image (one value per pair) and gives a pair's
//! pixels the same count, read from other pairs only.

use rayon::prelude::*;

use super::exact::ExactSum;
use crate::output::RgbImage;
use crate::spectrum::xyz_to_rec709;

/// Most samples per pass a planned pixel takes. 16 rather than 8 since the
/// mirror pairs: with a plan scale of 1.25, 0.92× the variance
/// per CPU second at twilight (fixed passes, two seed pairs; 0.91× per path
/// over four), 0.99× at sunset and midday (`BENCHMARKS.md`).
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

/// Which pixel lines a [`Mirror`] reflects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MirrorAxis {
    /// Column x ↦ (c − 1 − x) mod width, rows unchanged.
    Columns,
    /// Row y ↦ (c − 1 − y) mod height, columns unchanged.
    Rows,
}

/// A reflection of the image onto itself that takes every pixel's footprint
/// exactly onto a pixel's (its own on the mirror line): the sun's vertical
/// plane as the camera sees it (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mirror {
    pub axis: MirrorAxis,
    /// c in the line map i ↦ (c − 1 − i) mod n, 0 ≤ c < n (n the lines).
    pub centre: u32,
}

impl Mirror {
    /// The line that line `i` of `n` maps to.
    fn line(self, i: usize, n: usize) -> usize {
        (self.centre as usize + 2 * n - 1 - i) % n
    }

    /// Row-major index of the mirror image of pixel (`x`, `y`).
    pub fn partner(self, x: usize, y: usize, width: usize, height: usize) -> usize {
        match self.axis {
            MirrorAxis::Columns => y * width + self.line(x, width),
            MirrorAxis::Rows => self.line(y, height) * width + x,
        }
    }

    /// One line of each mirror pair (or fixed line), consecutive from ⌊c/2⌋
    /// (mod n): neighbours in the image stay neighbours in the folded one.
    fn canonical_lines(self, n: usize) -> Vec<usize> {
        let mut taken = vec![false; n];
        let mut lines = Vec::with_capacity(n / 2 + 1);
        for k in 0..n {
            let i = (self.centre as usize / 2 + k) % n;
            if taken[i] {
                break;
            }
            taken[i] = true;
            taken[self.line(i, n)] = true;
            lines.push(i);
        }
        lines
    }
}

#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// Weighted sum of XYZ (cd m⁻² for Y) over the row's passes, exact
    /// (so that parts of a render merge bit for bit, [`super::parts`]).
    pub(crate) xyz_sum: Vec<[ExactSum; 3]>,
    pub(crate) row_passes: Vec<u32>,
    /// Sum of the weights of the row's passes (one sample each).
    pub(crate) row_weights: Vec<ExactSum>,
    /// Samples per pass of each pixel under the plan; empty before it.
    pub(crate) plan: Vec<u8>,
    /// Passes the row took under the plan (each of a pixel's m samples has
    /// weight 1, so the pixel's weight is the row's plus (m − 1) per pass).
    pub(crate) row_planned_passes: Vec<u32>,
    /// Samples (and splats) discarded as non-finite (or negative without
    /// the control variate).
    pub discarded: u64,
    /// The splats among `discarded`.
    pub(crate) splat_discarded: u64,
    /// Pixels read together with their mirror images; `None`: each alone.
    pub(crate) mirror: Option<Mirror>,
    /// Sums of the splats of [`super::circles`] (empty unless the renderer
    /// splats): each pixel's light scattered more than once in the air, ×
    /// the number of paths splatted.
    pub(crate) splat_sum: Vec<[f32; 3]>,
    /// Paths splatted so far (the splat sums' divisor).
    pub(crate) splat_paths: u64,
    /// The splats' point density learned from the passes so far.
    pub(crate) learned_points: super::circles::LearnedPoints,
    /// The first pass this film holds: 0, or a later one for a part of a
    /// split render ([`super::parts`]).
    pub(crate) first_pass: u32,
    /// The pixels rendered; `None`: all (see [`super::parts::Tile`]).
    pub(crate) region: Option<super::parts::Tile>,
    /// Each pixel's total weight where it is not a function of its row
    /// (a film merged from parts); empty otherwise.
    pub(crate) pixel_weights: Vec<ExactSum>,
    /// The spectral layer, where a spectral image is asked for
    /// ([`super::film_spectral`]).
    pub(crate) spectral: Option<super::film_spectral::SpectralFilm>,
    /// The sums of the `sky`, `sun` and `ground` layers, where they are
    /// asked for ([`super::film_layers`]).
    pub(crate) layers: Option<super::film_layers::LayerSums>,
    /// The sums of the `variance` layer, where it is asked for.
    pub(crate) variance: Option<super::film_layers::VarianceSums>,
}

/// `n` copies of `value`, or an error where the memory is not there (not
/// an abort, as `vec!` gives).
pub(crate) fn try_filled<T: Clone>(
    n: usize,
    value: T,
) -> Result<Vec<T>, std::collections::TryReserveError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n)?;
    v.resize(n, value);
    Ok(v)
}

impl Film {
    /// An empty film; aborts where memory runs out (see [`Self::try_new`]).
    pub fn new(width: u32, height: u32) -> Self {
        Self::try_new(width, height).expect("memory for the film")
    }

    /// An empty film, or an error where its buffers cannot be allocated.
    pub fn try_new(width: u32, height: u32) -> Result<Self, std::collections::TryReserveError> {
        Ok(Self {
            width,
            height,
            xyz_sum: try_filled(width as usize * height as usize, [ExactSum::ZERO; 3])?,
            row_passes: try_filled(height as usize, 0)?,
            row_weights: try_filled(height as usize, ExactSum::ZERO)?,
            plan: Vec::new(),
            row_planned_passes: try_filled(height as usize, 0)?,
            discarded: 0,
            splat_discarded: 0,
            mirror: None,
            splat_sum: Vec::new(),
            splat_paths: 0,
            learned_points: super::circles::LearnedPoints::default(),
            first_pass: 0,
            region: None,
            pixel_weights: Vec::new(),
            spectral: None,
            layers: None,
            variance: None,
        })
    }

    /// The film with a layer for the splats of [`super::circles`].
    pub(crate) fn try_with_splats(mut self) -> Result<Self, std::collections::TryReserveError> {
        self.splat_sum = try_filled(self.xyz_sum.len(), [0.0; 3])?;
        Ok(self)
    }

    /// Bytes held by the film's buffers.
    pub fn buffer_bytes(&self) -> usize {
        use std::mem::size_of_val;
        size_of_val(self.xyz_sum.as_slice())
            + size_of_val(self.row_passes.as_slice())
            + size_of_val(self.row_weights.as_slice())
            + size_of_val(self.plan.as_slice())
            + size_of_val(self.row_planned_passes.as_slice())
            + size_of_val(self.splat_sum.as_slice())
            + self
                .spectral
                .as_ref()
                .map_or(0, super::film_spectral::SpectralFilm::buffer_bytes)
    }

    /// Whether the film has a splat layer.
    pub(crate) fn splats(&self) -> bool {
        !self.splat_sum.is_empty()
    }

    /// Adds one batch of splats from `paths` paths.
    pub(crate) fn add_splats(&mut self, splats: &[super::circles::Splat], paths: u64) {
        for s in splats {
            let sum = &mut self.splat_sum[s.pixel as usize];
            for (v, x) in sum.iter_mut().zip(s.xyz) {
                *v += x as f32;
            }
        }
        if let Some(variance) = &mut self.variance {
            for s in splats {
                variance.add_splat(s.pixel as usize, s.xyz[1]);
            }
        }
        self.splat_paths += paths;
        if let Some(spectral) = &mut self.spectral {
            spectral.add_splats(splats);
        }
    }

    /// The film reading each pixel together with its image under `mirror`
    /// (see the module documentation), which must be a symmetry of the
    /// scene as the camera sees it; `None` reads each pixel alone.
    #[must_use]
    pub fn with_mirror(mut self, mirror: Option<Mirror>) -> Self {
        self.mirror = mirror;
        self
    }

    /// Passes completed by every row.
    pub fn complete_passes(&self) -> u32 {
        self.row_passes.iter().copied().min().unwrap_or(0)
    }

    /// Whether the film has its adaptive plan (see the module documentation).
    pub fn is_planned(&self) -> bool {
        !self.plan.is_empty()
    }

    /// Samples per pass of pixel `index` (row-major): 1 before the plan.
    pub fn samples_per_pass(&self, index: usize) -> u32 {
        self.plan.get(index).map_or(1, |&m| u32::from(m))
    }

    /// Total weight of the samples of pixel `index` (row-major).
    pub(crate) fn pixel_weight(&self, index: usize) -> f64 {
        self.exact_pixel_weight(index).to_f64()
    }

    /// [`Self::pixel_weight`], exact.
    pub(crate) fn exact_pixel_weight(&self, index: usize) -> ExactSum {
        if let Some(&w) = self.pixel_weights.get(index) {
            return w;
        }
        let y = index / self.width as usize;
        let extra = u64::from(self.samples_per_pass(index) - 1);
        let planned = extra * u64::from(self.row_planned_passes[y]);
        self.row_weights[y] + ExactSum::from_f64(planned as f64)
    }

    /// The image at pixel `index` (row-major). With splats, a row that
    /// holds only the draft pass shows it alone (it estimated every order
    /// along the camera rays); from the first full pass on, the draft is
    /// gone from the row (`Self::drop_draft`) and the image is the camera
    /// samples' mean plus the splats'.
    fn mean(&self, index: usize) -> [f64; 3] {
        self.mean_with(index, &|i| self.xyz_sum[i], &|_| true)
    }

    /// [`Self::mean`] of the camera sums `sums(i)` (a part of the camera
    /// samples' XYZ sums) and of the splats of the pixels `i` where
    /// `splats(i)` holds: the same reading for a layer of the image as for
    /// the whole ([`super::film_layers`]).
    pub(crate) fn mean_with(
        &self,
        index: usize,
        sums: &dyn Fn(usize) -> [ExactSum; 3],
        splats: &dyn Fn(usize) -> bool,
    ) -> [f64; 3] {
        let (w, h) = (self.width as usize, self.height as usize);
        let partner = self
            .mirror
            .map(|m| m.partner(index % w, index / w, w, h))
            .filter(|&p| p != index);
        if !self.splats() {
            return self.pixel_mean(index, partner, sums);
        }
        let full = |i: usize| self.row_passes[i / w] >= 2;
        if !full(index) {
            return self.pixel_mean(index, None, sums);
        }
        // A mirror partner still on the draft would mix the draft's
        // estimate into this pixel's.
        let partner = partner.filter(|&p| full(p));
        let mut mean = self.pixel_mean(index, partner, sums);
        if self.splat_paths > 0 {
            let n = if partner.is_some() { 2.0 } else { 1.0 };
            for p in std::iter::once(index).chain(partner).filter(|&p| splats(p)) {
                for (m, s) in mean.iter_mut().zip(self.splat_sum[p]) {
                    *m += f64::from(s) / (n * self.splat_paths as f64);
                }
            }
        }
        mean
    }

    /// With splats, empties row `y`'s sums of the draft pass before its
    /// first full pass (see [`Self::mean`]).
    pub(crate) fn drop_draft(row: &mut [[ExactSum; 3]], passes: u32, row_weight: &mut ExactSum) {
        if passes == 1 {
            row.fill([ExactSum::ZERO; 3]);
            *row_weight = ExactSum::ZERO;
        }
    }

    /// Mean XYZ of pixel `index`'s camera samples (row-major), with its
    /// mirror image's where the film has a mirror; 0 before the first pass.
    fn camera_mean(&self, index: usize) -> [f64; 3] {
        let (w, h) = (self.width as usize, self.height as usize);
        let partner = self
            .mirror
            .map(|m| m.partner(index % w, index / w, w, h))
            .filter(|&p| p != index);
        self.pixel_mean(index, partner, &|i| self.xyz_sum[i])
    }

    /// Mean XYZ of the camera samples of pixel `index` and of `partner`,
    /// their sums read by `sums`.
    fn pixel_mean(
        &self,
        index: usize,
        partner: Option<usize>,
        sums: &dyn Fn(usize) -> [ExactSum; 3],
    ) -> [f64; 3] {
        let mut sum = sums(index);
        let mut weight = self.exact_pixel_weight(index);
        if let Some(p) = partner {
            for (s, v) in sum.iter_mut().zip(sums(p)) {
                *s += v;
            }
            weight += self.exact_pixel_weight(p);
        }
        let (sum, weight) = (sum.map(ExactSum::to_f64), weight.to_f64());
        if weight > 0.0 {
            sum.map(|s| s / weight)
        } else {
            sum
        }
    }

    /// Mean XYZ of one pixel.
    pub fn xyz(&self, x: u32, y: u32) -> [f64; 3] {
        self.mean((y * self.width + x) as usize)
    }

    /// The current estimate as linear Rec.709 (Y in cd m⁻²).
    pub fn to_rgb(&self) -> RgbImage {
        self.try_to_rgb().expect("memory for the image")
    }

    /// [`Self::to_rgb`], or an error where the image's memory is not there.
    pub fn try_to_rgb(&self) -> Result<RgbImage, std::collections::TryReserveError> {
        let mut pixels = Vec::new();
        pixels.try_reserve_exact(self.xyz_sum.len())?;
        pixels
            .extend((0..self.xyz_sum.len()).map(|i| xyz_to_rec709(self.mean(i)).map(|c| c as f32)));
        Ok(RgbImage {
            width: self.width,
            height: self.height,
            pixels,
        })
    }

    /// Fix every pixel's samples per pass for the passes to come from the
    /// current image (see the module documentation): ∝ the standard
    /// deviation of the luminance over the pixel's neighbourhood without the
    /// pixel itself. Where the image is flat and clean that is small; where it
    /// is noisy or bright and structured (the aureole, a twilight glow), large
    /// — the absolute variance the mean of a pixel carries scales with both.
    /// Once only: a plan changed later would re-weight the passes before it
    /// (does nothing on a planned film). With a mirror, on the folded image:
    /// both pixels of a pair get the count planned for their pair, from the
    /// other pairs' means.
    pub(crate) fn plan_samples(&mut self) {
        if self.is_planned() {
            return;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        // The folded image's pixels as (folded width, folded height, pixel
        // index in the film per folded pixel).
        let (fw, fh, pixels): (usize, usize, Vec<usize>) = match self.mirror {
            None => (w, h, (0..w * h).collect()),
            Some(
                m @ Mirror {
                    axis: MirrorAxis::Columns,
                    ..
                },
            ) => {
                let columns = m.canonical_lines(w);
                let pixels = (0..h)
                    .flat_map(|y| columns.iter().map(move |&x| y * w + x))
                    .collect();
                (columns.len(), h, pixels)
            }
            Some(
                m @ Mirror {
                    axis: MirrorAxis::Rows,
                    ..
                },
            ) => {
                let rows = m.canonical_lines(h);
                let pixels = rows
                    .iter()
                    .flat_map(|&y| (0..w).map(move |x| y * w + x))
                    .collect();
                (w, rows.len(), pixels)
            }
        };
        let luminance: Vec<f32> = pixels
            .iter()
            .map(|&i| self.camera_mean(i)[1] as f32)
            .collect();
        let folded = plan(&luminance, fw, fh);
        let mut plan = vec![1u8; w * h];
        for (&i, &m) in pixels.iter().zip(&folded) {
            plan[i] = m;
            if let Some(mirror) = self.mirror {
                plan[mirror.partner(i % w, i / w, w, h)] = m;
            }
        }
        self.plan = plan;
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
    let spread = spreads(luminance, width, height);
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
/// the pixel itself (0 with fewer than two others). Each window is read
/// afresh, its centre skipped: pixel i's value enters no sum of σᵢ, not even
/// through rounding (sliding sums that add and later subtract it would keep
/// a trace of it; so would subtracting it from a total).
fn spreads(luminance: &[f32], width: usize, height: usize) -> Vec<f32> {
    let r = PLAN_RADIUS;
    let mut spread = vec![0.0f32; width * height];
    spread
        .par_chunks_mut(width)
        .enumerate()
        .for_each(|(y, row)| {
            let rows = y.saturating_sub(r)..(y + r + 1).min(height);
            for (x, spread) in row.iter_mut().enumerate() {
                let columns = x.saturating_sub(r)..(x + r + 1).min(width);
                let others = || {
                    rows.clone()
                        .flat_map(|yy| columns.clone().map(move |xx| (xx, yy)))
                        .filter(|&p| p != (x, y))
                        .map(|(xx, yy)| f64::from(luminance[yy * width + xx]))
                };
                let n = (rows.len() * columns.len() - 1) as f64;
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
mod tests {
    use super::*;

    #[test]
    fn with_splats_a_row_shows_its_draft_until_its_first_full_pass() {
        // 2×2 film; the draft pass gave every pixel XYZ 2 at weight 0.5.
        let mut film = Film::new(2, 2).try_with_splats().unwrap();
        film.xyz_sum.fill([ExactSum::from_f64(1.0); 3]);
        film.row_passes.fill(1);
        film.row_weights.fill(ExactSum::from_f64(0.5));
        // Two splatted paths put XYZ 4 into pixel 0 (mean 2 there).
        film.add_splats(
            &[super::super::circles::Splat {
                pixel: 0,
                xyz: [4.0; 3],
                lanes: super::super::film_spectral::SplatLanes::default(),
            }],
            2,
        );
        // Draft only: the draft's estimate alone, splats not added to it.
        assert_eq!(film.xyz(0, 0), [2.0; 3]);
        // Row 0's first full pass: the draft leaves, a sample of 3 comes in.
        let w = film.width as usize;
        Film::drop_draft(
            &mut film.xyz_sum[..w],
            film.row_passes[0],
            &mut film.row_weights[0],
        );
        film.xyz_sum[..w].fill([ExactSum::from_f64(3.0); 3]);
        film.row_weights[0] = ExactSum::from_f64(1.0);
        film.row_passes[0] = 2;
        assert_eq!(film.xyz(0, 0), [5.0; 3]);
        assert_eq!(film.xyz(1, 0), [3.0; 3]);
        assert_eq!(film.xyz(0, 1), [2.0; 3]);
        // Later passes keep their samples.
        Film::drop_draft(
            &mut film.xyz_sum[..w],
            film.row_passes[0],
            &mut film.row_weights[0],
        );
        assert_eq!(film.xyz(1, 0), [3.0; 3]);
        // Without splats the draft is one sample among the others.
        let mut plain = Film::new(2, 1);
        plain.xyz_sum.fill([ExactSum::from_f64(1.0); 3]);
        plain.row_passes.fill(2);
        plain.row_weights.fill(ExactSum::from_f64(1.5));
        assert_eq!(plain.xyz(0, 0), [1.0 / 1.5; 3]);
    }

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
        // what keeps its mean unbiased): its own spread and those of the
        // pixels outside its window — all the plan reads besides integer
        // counts — stay bit for bit the same whatever its value, and so does
        // its plan; its neighbours' plans may change.
        let (w, h) = (30, 20);
        let image: Vec<f32> = (0..w * h).map(|i| 50.0 + 30.0 * hash01(i)).collect();
        let (spread, m) = (spreads(&image, w, h), plan(&image, w, h));
        let r = PLAN_RADIUS;
        for i in [0, 7 * w + 11, w * h - 1, 3 * w, 12 * w + 29] {
            for v in [0.0, 1e6, 1e9, f32::MAX] {
                let mut changed = image.clone();
                changed[i] = v;
                let after = spreads(&changed, w, h);
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
    fn canonical_lines_take_one_line_of_each_pair() {
        for n in [1, 2, 7, 8, 256] {
            for centre in 0..n as u32 {
                let m = Mirror {
                    axis: MirrorAxis::Columns,
                    centre,
                };
                let lines = m.canonical_lines(n);
                let mut seen = vec![0; n];
                for &i in &lines {
                    seen[i] += 1;
                    seen[m.line(i, n)] += 1;
                    assert_eq!(m.line(m.line(i, n), n), i, "an involution");
                }
                // Every line once, as a canonical line or its partner (a
                // fixed line as both).
                for (i, &count) in seen.iter().enumerate() {
                    let fixed = m.line(i, n) == i;
                    assert_eq!(count, 1 + usize::from(fixed), "n {n}, c {centre}, line {i}");
                }
                // Consecutive (mod n): the folded image keeps neighbours.
                for pair in lines.windows(2) {
                    assert_eq!(pair[1], (pair[0] + 1) % n);
                }
            }
        }
    }

    /// A film of `w`×`h` pixels after one pass of weight 1 with the given
    /// luminances (X = Z = 0).
    fn film_of(luminance: &[f32], w: u32, h: u32, mirror: Option<Mirror>) -> Film {
        let mut film = Film::new(w, h).with_mirror(mirror);
        for (sum, &v) in film.xyz_sum.iter_mut().zip(luminance) {
            *sum = [0.0, f64::from(v), 0.0].map(ExactSum::from_f64);
        }
        film.row_passes.fill(1);
        film.row_weights.fill(ExactSum::from_f64(1.0));
        film
    }

    #[test]
    fn a_mirrored_film_reads_each_pixel_with_its_mirror_image() {
        let (w, h) = (12u32, 6u32);
        let image: Vec<f32> = (0..w * h).map(|i| 10.0 * hash01(i as usize)).collect();
        for (axis, centre) in [
            (MirrorAxis::Columns, 0),
            (MirrorAxis::Columns, 5),
            (MirrorAxis::Rows, 0),
        ] {
            let mirror = Mirror { axis, centre };
            let mut film = film_of(&image, w, h, Some(mirror));
            // A second pass with up to three samples in some pixels (a
            // plan), which the even rows have taken and the odd ones not yet
            // (a pass under way): the pair's mean weighs each sample once.
            film.plan = (0..w * h).map(|i| 1 + (i % 3) as u8).collect();
            for y in (0..h as usize).step_by(2) {
                film.row_passes[y] = 2;
                film.row_weights[y] = ExactSum::from_f64(2.0);
                film.row_planned_passes[y] = 1;
            }
            let rgb = film.to_rgb();
            for y in 0..h {
                for x in 0..w {
                    let i = (y * w + x) as usize;
                    let j = mirror.partner(x as usize, y as usize, w as usize, h as usize);
                    // Samples so far: 1, plus the plan's in even rows.
                    let count = |k: usize| {
                        let planned = (k / w as usize).is_multiple_of(2);
                        1.0 + if planned {
                            f64::from(film.plan[k])
                        } else {
                            0.0
                        }
                    };
                    let (ni, nj) = (count(i), count(j));
                    let expected = if i == j {
                        f64::from(image[i]) / ni
                    } else {
                        (f64::from(image[i]) + f64::from(image[j])) / (ni + nj)
                    };
                    let got = film.xyz(x, y)[1];
                    assert!(
                        (got - expected).abs() < 1e-6 * expected.max(1.0),
                        "{axis:?}"
                    );
                    assert_eq!(rgb.pixels[i], rgb.pixels[j]);
                }
            }
        }
    }

    #[test]
    fn a_mirrored_plan_gives_a_pair_one_count_that_ignores_both_its_pixels() {
        // The mirrored film reads a pixel with its partner, so the count of
        // either must read neither's samples; both get the same count.
        let (w, h) = (30u32, 20u32);
        let image: Vec<f32> = (0..w * h)
            .map(|i| 50.0 + 30.0 * hash01(i as usize))
            .collect();
        for mirror in [
            Mirror {
                axis: MirrorAxis::Columns,
                centre: 11,
            },
            Mirror {
                axis: MirrorAxis::Rows,
                centre: 0,
            },
        ] {
            let planned = |image: &[f32]| {
                let mut film = film_of(image, w, h, Some(mirror));
                film.plan_samples();
                film.plan
            };
            let m = planned(&image);
            let partner = |i: usize| mirror.partner(i % 30, i / 30, 30, 20);
            assert!((0..600).all(|i| m[i] == m[partner(i)]), "{mirror:?}");
            // Pixels on, next to and far from the mirror line.
            for i in [0, 5 * 30 + 5, 7 * 30 + 11, 9 * 30 + 10, 599] {
                for v in [0.0, 1e6, f32::MAX] {
                    let mut changed = image.clone();
                    changed[i] = v;
                    changed[partner(i)] = v;
                    let after = planned(&changed);
                    assert_eq!(after[i], m[i], "{mirror:?}: pixel {i} and partner = {v}");
                }
            }
            let mut bright = image.clone();
            bright[7 * 30 + 15] = 1e6;
            assert_ne!(planned(&bright), m, "the plan reads the other pixels");
        }
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
        let spread = spreads(&image, w, h);
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
