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
//!
//! **Mirror halves.** Where the sun's azimuth falls between an equirect
//! image's columns (a real date's sun, most often), the reflection takes no
//! pixel onto a pixel, but it takes each pixel's two parts, split at the
//! same fraction g of every pixel, onto parts of two pixels exactly
//! ([`HalfMirror`]). Each sample is drawn in one part chosen by its number
//! alone, in proportion to the parts' widths, so each part's samples are
//! uniform over it and their count fixed in advance; the film keeps each
//! pixel's sums and weight of its left part's samples (and the splats that
//! landed there) and reads the pixel as g × the left part's mean with its
//! left partner's plus (1 − g) × the right part's with its right partner's.
//! Each term is unbiased; the plan reads each pixel's own samples and
//! leaves a pixel's partners out of its plan as it leaves out the pixel.

use super::adaptive::plan;
pub use super::adaptive::MAX_SAMPLES_PER_PASS;
use super::alloc::{try_filled, try_zeroed};
use super::camera::{HalfMirror, Mirror, MirrorAxis};
use super::exact::{ExactPlane, ExactRow, ExactSum};
use super::film_layers::{LayerSums, VarianceSums};
use super::film_spectral::SpectralFilm;
use super::parts::{pick, PartData, PassRange, Tile};
use crate::output::RgbImage;
use crate::spectrum::xyz_to_rec709;

/// The image being accumulated: exact sums per pixel, the adaptive plan, and the optional layers, spectral bands and splats.
#[derive(Clone, Debug)]
pub struct Film {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Weighted sum of XYZ (cd m⁻² for Y) over the row's passes, exact
    /// (so that parts of a render merge bit for bit, [`super::parts`]).
    pub(crate) xyz_sum: ExactPlane,
    pub(crate) row_passes: Vec<u32>,
    /// Sum of the weights of the row's passes (one sample each).
    pub(crate) row_weights: Vec<ExactSum>,
    /// Samples per pass of each pixel under the plan; empty before it.
    pub(crate) plan: Vec<u8>,
    /// Passes the row took under the plan (each of a pixel's m samples has
    /// weight 1, so the pixel's weight is the row's plus (m − 1) per pass).
    pub(crate) row_planned_passes: Vec<u32>,
    /// Samples (and splats) discarded as non-finite (or negative where
    /// no estimate may be, `Integrator::signed_estimates`).
    pub discarded: u64,
    /// The splats among `discarded`.
    pub(crate) splat_discarded: u64,
    /// Pixels read together with their mirror images; `None`: each alone.
    pub(crate) mirror: Option<Mirror>,
    /// Pixel parts read together with their mirror images, where the
    /// mirror takes parts of pixels onto parts ([`HalfMirror`]); `None`:
    /// none.
    pub(crate) halves: Option<HalfMirror>,
    /// With `halves`, the weighted XYZ sums of the samples drawn in each
    /// pixel's left part; empty without.
    pub(crate) left_sum: ExactPlane,
    /// With `halves`, the total weight of those samples (sums of the
    /// passes' weights, 1 and powers of ½: exact in an f64); empty without.
    pub(crate) left_weight: Vec<f64>,
    /// Sums of the splats of [`super::circles`] (empty unless the renderer
    /// splats): each pixel's light scattered more than once in the air, ×
    /// the number of paths splatted.
    pub(crate) splat_sum: Vec<[f32; 3]>,
    /// With `halves` and splats, the part of `splat_sum` that landed in
    /// each pixel's left part; empty otherwise.
    pub(crate) splat_left: Vec<[f32; 3]>,
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
            xyz_sum: ExactPlane::try_new(width as usize, height as usize)?,
            row_passes: try_filled(height as usize, 0)?,
            row_weights: try_filled(height as usize, ExactSum::ZERO)?,
            plan: Vec::new(),
            row_planned_passes: try_filled(height as usize, 0)?,
            discarded: 0,
            splat_discarded: 0,
            mirror: None,
            halves: None,
            left_sum: ExactPlane::default(),
            left_weight: Vec::new(),
            splat_sum: Vec::new(),
            splat_left: Vec::new(),
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
        self.splat_sum = try_zeroed(self.xyz_sum.len())?;
        if self.halves.is_some() {
            self.splat_left = try_zeroed(self.xyz_sum.len())?;
        }
        Ok(self)
    }

    /// Bytes held by the film's buffers.
    pub fn buffer_bytes(&self) -> usize {
        use std::mem::size_of_val;
        self.xyz_sum.bytes()
            + self.left_sum.bytes()
            + size_of_val(self.left_weight.as_slice())
            + size_of_val(self.row_passes.as_slice())
            + size_of_val(self.row_weights.as_slice())
            + size_of_val(self.plan.as_slice())
            + size_of_val(self.row_planned_passes.as_slice())
            + size_of_val(self.splat_sum.as_slice())
            + size_of_val(self.splat_left.as_slice())
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
    pub(crate) fn add_splats(&mut self, splats: &[super::film_spectral::Splat], paths: u64) {
        for s in splats {
            let sum = &mut self.splat_sum[s.pixel as usize];
            for (v, x) in sum.iter_mut().zip(s.xyz) {
                *v += x as f32;
            }
        }
        if let Some(halves) = self.halves.filter(|_| !self.splat_left.is_empty()) {
            for s in splats
                .iter()
                .filter(|s| f64::from(s.column_offset) < halves.split)
            {
                let sum = &mut self.splat_left[s.pixel as usize];
                for (v, x) in sum.iter_mut().zip(s.xyz) {
                    *v += x as f32;
                }
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
    /// holds only the draft pass shows the draft without the splats
    /// ([`Self::past_draft`]); from the first full pass on, the draft is
    /// gone from the row (`Self::drop_draft`) and the image is the camera
    /// samples' mean plus the splats'. Mirror partners are read together
    /// where their rows are at the same stage ([`Self::read_partner`]).
    fn mean(&self, index: usize) -> [f64; 3] {
        if self.halves.is_some() {
            return self.halves_mean(index);
        }
        self.mean_with(index, &|i| self.xyz_sum.get(i), &|_| true)
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
        let partner = self.read_partner(index);
        let mut mean = self.pixel_mean(index, partner, sums);
        if self.splat_paths > 0 && self.past_draft(index) {
            let n = if partner.is_some() { 2.0 } else { 1.0 };
            for p in std::iter::once(index).chain(partner).filter(|&p| splats(p)) {
                for (m, s) in mean.iter_mut().zip(self.splat_sum[p]) {
                    *m += f64::from(s) / (n * self.splat_paths as f64);
                }
            }
        }
        mean
    }

    /// Whether pixel `index`'s row is past its draft: without splats every
    /// row is (the draft is one weighted pass among the others); with them
    /// a row on its draft shows the draft without the splats, which it
    /// drops at its first full pass (it estimated every order along the
    /// camera rays, later passes only what the splats do not).
    pub(super) fn past_draft(&self, index: usize) -> bool {
        !self.splats() || self.row_passes[index / self.width as usize] >= 2
    }

    /// The mirror partner pixel `index` is read with: where the film has a
    /// mirror and both rows are at the same stage, so that no draft is
    /// mixed into a pixel past its own, nor full passes into a draft.
    fn read_partner(&self, index: usize) -> Option<usize> {
        let (w, h) = (self.width as usize, self.height as usize);
        self.mirror
            .map(|m| m.partner(index % w, index / w, w, h))
            .filter(|&p| p != index && self.past_draft(p) == self.past_draft(index))
    }

    /// With splats, empties row `y`'s sums of the draft pass before its
    /// first full pass (see [`Self::mean`]).
    pub(crate) fn drop_draft(row: &mut ExactRow<'_>, passes: u32, row_weight: &mut ExactSum) {
        if passes == 1 {
            row.clear();
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
        self.pixel_mean(index, partner, &|i| self.xyz_sum.get(i))
    }

    /// Mean XYZ of the camera samples of pixel `index` and of `partner`,
    /// their sums read by `sums`.
    pub(super) fn pixel_mean(
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
    /// other pairs' means. With halves, from each pixel's own mean, each
    /// pixel's plan leaving out its partners too
    /// ([`super::adaptive::plan_linked`]).
    pub(crate) fn plan_samples(&mut self) {
        if self.is_planned() {
            return;
        }
        let (w, h) = (self.width as usize, self.height as usize);
        if let Some(halves) = self.halves {
            // Each pixel's own samples alone: read with its partners, its
            // value would carry theirs into the plans about it.
            let luminance: Vec<f32> = (0..w * h)
                .map(|i| self.halves_camera_mean(i, &|p| p == i)[1] as f32)
                .collect();
            self.plan = super::adaptive::plan_linked(&luminance, w, h, &|x| {
                [halves.left_partner(x, w), halves.right_partner(x, w)]
            });
            return;
        }
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
            ground: ExactPlane::try_new(self.width as usize, self.height as usize)?,
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
        let ground = |i: usize| layers.ground.get(i);
        let sky = |i: usize| {
            let (s, g, d) = (self.xyz_sum.get(i), ground(i), sun(i));
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

impl Film {
    /// The film with the sums of the `variance` layer.
    pub(crate) fn try_with_variance(mut self) -> Result<Self, std::collections::TryReserveError> {
        self.variance = Some(VarianceSums::try_new(self.xyz_sum.len(), self.splats())?);
        Ok(self)
    }

    /// Keeps the `variance` layer's two halves too; nothing without it.
    pub(crate) fn try_keep_variance_halves(
        &mut self,
    ) -> Result<(), std::collections::TryReserveError> {
        self.variance
            .as_mut()
            .map_or(Ok(()), VarianceSums::try_keep_halves)
    }

    /// The luminance of the odd- and the even-numbered full passes apart,
    /// once each has one, where the film keeps them.
    pub fn variance_halves(&self) -> Option<super::film_layers::VarianceHalves> {
        self.variance.as_ref()?.halves()
    }

    /// Empties the pass sums before pass `pass`.
    pub(crate) fn start_variance_pass(&mut self) {
        if let Some(v) = &mut self.variance {
            v.start_pass();
        }
    }

    /// Counts the pass just rendered by every row (`pass`, with
    /// `splat_paths` splat paths) as one batch; the draft pass is not one.
    pub(crate) fn end_variance_pass(&mut self, pass: u32, splat_paths: u64) {
        let size = (self.width as usize, self.height as usize);
        if let Some(v) = self.variance.as_mut().filter(|_| pass >= 1) {
            v.end_pass(size, self.mirror, splat_paths);
        }
    }

    /// The `variance.Y` plane: per pixel the estimated variance of its mean
    /// luminance, (cd m⁻²)²; `None` without variance sums or before two
    /// full passes.
    pub fn variance_plane(&self) -> Option<Vec<f32>> {
        self.variance
            .as_ref()?
            .plane(self.width as usize, self.halves)
    }
}

impl Film {
    /// The film with a spectral layer of `bands` bands.
    pub(crate) fn try_with_spectral(
        mut self,
        bands: u32,
    ) -> Result<Self, std::collections::TryReserveError> {
        self.spectral = Some(SpectralFilm::try_new(
            self.width,
            self.height,
            bands,
            self.splats(),
        )?);
        Ok(self)
    }

    /// The spectral image, one row-major plane per band (W m⁻² sr⁻¹ nm⁻¹,
    /// band-averaged), normalised as [`Film::xyz`] normalises the XYZ sums;
    /// `None` without a spectral layer.
    pub fn try_spectral_planes(
        &self,
    ) -> Result<Option<Vec<Vec<f32>>>, std::collections::TryReserveError> {
        let Some(spectral) = &self.spectral else {
            return Ok(None);
        };
        let (w, h, bands) = (self.width as usize, self.height as usize, spectral.bands);
        let mut planes = Vec::new();
        planes.try_reserve_exact(bands)?;
        for _ in 0..bands {
            planes.push(try_filled(w * h, 0.0f32)?);
        }
        let camera = |i: usize| &spectral.rows[i / w][(i % w) * bands..(i % w + 1) * bands];
        let mut mean = vec![0.0f64; bands];
        for i in 0..w * h {
            // The same reading as `Film::mean`: a pixel with its mirror
            // partner; with splats, a row still on its draft without the
            // splats (with its partner where that is on the draft too),
            // later rows the camera mean plus the splats'.
            let partner = self.read_partner(i);
            let splats = self.splat_paths > 0 && self.past_draft(i);
            let mut weight = self.pixel_weight(i);
            for (m, &v) in mean.iter_mut().zip(camera(i)) {
                *m = f64::from(v);
            }
            if let Some(p) = partner {
                weight += self.pixel_weight(p);
                for (m, &v) in mean.iter_mut().zip(camera(p)) {
                    *m += f64::from(v);
                }
            }
            if weight > 0.0 {
                for m in &mut mean {
                    *m /= weight;
                }
            }
            if splats {
                let n = if partner.is_some() { 2.0 } else { 1.0 };
                let scale = 1.0 / (n * self.splat_paths as f64);
                for p in std::iter::once(i).chain(partner) {
                    let s = &spectral.splat_sum[p * bands..(p + 1) * bands];
                    for (m, &v) in mean.iter_mut().zip(s) {
                        *m += f64::from(v) * scale;
                    }
                }
            }
            for (plane, m) in planes.iter_mut().zip(&mean) {
                plane[i] = *m as f32;
            }
        }
        Ok(Some(planes))
    }
}

impl Film {
    /// Sets up an empty film to hold only `passes` of the pixels in
    /// `tile` (see the module documentation).
    #[must_use]
    pub fn for_part(mut self, passes: PassRange, tile: Tile) -> Self {
        self.first_pass = passes.start;
        self.row_passes.fill(passes.start);
        let whole = Tile::whole(self.width, self.height);
        self.region = (tile != whole).then_some(tile);
        self
    }

    /// The film's state inside its tile, to be merged later.
    pub fn part_data(&self, passes: PassRange) -> PartData {
        let w = self.width as usize;
        let tile = self
            .region
            .unwrap_or_else(|| Tile::whole(self.width, self.height));
        let inside = |i: usize| tile.contains((i % w) as u32, (i / w) as u32);
        let n = self.xyz_sum.len();
        let picked = |plane: &ExactPlane| -> Vec<[ExactSum; 3]> {
            (0..n)
                .map(|i| {
                    if inside(i) {
                        plane.get(i)
                    } else {
                        [ExactSum::ZERO; 3]
                    }
                })
                .collect()
        };
        PartData {
            passes,
            tile,
            sums: picked(&self.xyz_sum),
            left_sums: if self.halves.is_some() {
                picked(&self.left_sum)
            } else {
                Vec::new()
            },
            left_weights: (0..self.left_weight.len())
                .map(|i| {
                    if inside(i) {
                        ExactSum::from_f64(self.left_weight[i])
                    } else {
                        ExactSum::ZERO
                    }
                })
                .collect(),
            weights: (0..n)
                .map(|i| {
                    if inside(i) {
                        self.exact_pixel_weight(i)
                    } else {
                        ExactSum::ZERO
                    }
                })
                .collect(),
            splat_sums: pick(&self.splat_sum, inside),
            splat_left: pick(&self.splat_left, inside),
            splat_paths: self.splat_paths,
            camera_discarded: self.discarded - self.splat_discarded,
            splat_discarded: self.splat_discarded,
        }
    }

    /// The film of the whole render from its parts: per pixel the sums and
    /// weights of the parts that hold it, the splat sums likewise, and the
    /// splat paths of one tile per pass range (each tile of a range ran
    /// them all). With splats, a part of the first pass alone (the draft)
    /// is left out when the render has more passes: the draft estimates
    /// every order along the camera rays, which the splats add again.
    /// `parts` must tile the image and the passes `0..spp` exactly
    /// (`check_cover`).
    pub fn from_parts(
        width: u32,
        height: u32,
        spp: u32,
        (mirror, halves): (Option<Mirror>, Option<HalfMirror>),
        splats: bool,
        parts: &[PartData],
    ) -> Result<Self, std::collections::TryReserveError> {
        let mut film = Self::try_new(width, height)?
            .with_mirror(mirror)
            .try_with_halves(halves)?;
        if splats {
            film = film.try_with_splats()?;
        }
        film.row_passes.fill(spp);
        let mut weights = try_filled(film.xyz_sum.len(), ExactSum::ZERO)?;
        let mut counted_ranges = Vec::new();
        let w = width as usize;
        for part in parts {
            let draft_only = splats && part.passes == PassRange { start: 0, end: 1 } && spp > 1;
            for (i, weight) in weights.iter_mut().enumerate() {
                if !part.tile.contains((i % w) as u32, (i / w) as u32) {
                    continue;
                }
                if !draft_only {
                    film.xyz_sum.add(i, part.sums[i]);
                    if let (Some(_), Some(&left), Some(&weight)) =
                        (halves, part.left_sums.get(i), part.left_weights.get(i))
                    {
                        film.left_sum.add(i, left);
                        film.left_weight[i] += weight.to_f64();
                    }
                    *weight += part.weights[i];
                }
                if splats {
                    for c in 0..3 {
                        film.splat_sum[i][c] += part.splat_sums[i][c];
                    }
                    if let (false, Some(left)) =
                        (film.splat_left.is_empty(), part.splat_left.get(i))
                    {
                        for (s, l) in film.splat_left[i].iter_mut().zip(left) {
                            *s += l;
                        }
                    }
                }
            }
            film.discarded += part.camera_discarded;
            if !counted_ranges.contains(&part.passes) {
                counted_ranges.push(part.passes);
                film.splat_paths += part.splat_paths;
                film.discarded += part.splat_discarded;
            }
        }
        film.pixel_weights = weights;
        Ok(film)
    }
}

#[cfg(test)]
mod tests {
    use super::super::adaptive::tests::hash01;
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
            &[super::super::film_spectral::Splat {
                pixel: 0,
                column_offset: 0.5,
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
            &mut film.xyz_sum.row_mut(0),
            film.row_passes[0],
            &mut film.row_weights[0],
        );
        for x in 0..w {
            film.xyz_sum.row_mut(0).add(x, [ExactSum::from_f64(3.0); 3]);
        }
        film.row_weights[0] = ExactSum::from_f64(1.0);
        film.row_passes[0] = 2;
        assert_eq!(film.xyz(0, 0), [5.0; 3]);
        assert_eq!(film.xyz(1, 0), [3.0; 3]);
        assert_eq!(film.xyz(0, 1), [2.0; 3]);
        // Later passes keep their samples.
        Film::drop_draft(
            &mut film.xyz_sum.row_mut(0),
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
        for (i, &v) in luminance.iter().enumerate() {
            film.xyz_sum
                .add(i, [0.0, f64::from(v), 0.0].map(ExactSum::from_f64));
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
}
