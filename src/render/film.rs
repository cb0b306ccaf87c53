//! The film: per-pixel weighted sums of XYZ samples, filled one pass (one
//! sample per pixel) at a time and readable at any moment. Rows record how
//! many passes they hold and their total weight, so a pass interrupted
//! half-way still reads back coherently. Each pass is an unbiased estimate
//! and its weight is fixed in advance, so the weighted mean is unbiased too.

use crate::output::RgbImage;
use crate::spectrum::xyz_to_rec709;

#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// Weighted sum of XYZ (cd m⁻² for Y) over the row's passes.
    pub(crate) xyz_sum: Vec<[f32; 3]>,
    pub(crate) row_passes: Vec<u32>,
    /// Sum of the weights of the row's passes.
    pub(crate) row_weights: Vec<f64>,
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
            discarded: 0,
        }
    }

    /// Passes completed by every row.
    pub fn complete_passes(&self) -> u32 {
        self.row_passes.iter().copied().min().unwrap_or(0)
    }

    /// 1 / (total weight) of row `y`'s passes (1 before the first).
    fn row_scale(&self, y: usize) -> f64 {
        let w = self.row_weights[y];
        if w > 0.0 {
            1.0 / w
        } else {
            1.0
        }
    }

    /// Mean XYZ of one pixel.
    pub fn xyz(&self, x: u32, y: u32) -> [f64; 3] {
        let scale = self.row_scale(y as usize);
        let s = self.xyz_sum[(y * self.width + x) as usize];
        s.map(|v| f64::from(v) * scale)
    }

    /// The current estimate as linear Rec.709 (Y in cd m⁻²).
    pub fn to_rgb(&self) -> RgbImage {
        let w = self.width as usize;
        let mut pixels = Vec::with_capacity(self.xyz_sum.len());
        for (y, row) in self.xyz_sum.chunks(w).enumerate() {
            let inv = self.row_scale(y);
            pixels.extend(
                row.iter()
                    .map(|s| xyz_to_rec709(s.map(|v| f64::from(v) * inv)).map(|c| c as f32)),
            );
        }
        RgbImage {
            width: self.width,
            height: self.height,
            pixels,
        }
    }
}
