//! The film: per-pixel sums of XYZ samples, filled one pass (one sample per
//! pixel) at a time and readable at any moment. Rows record how many passes
//! they hold, so a pass interrupted half-way still reads back coherently.

use crate::output::RgbImage;
use crate::spectrum::xyz_to_rec709;

#[derive(Clone, Debug)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// Sum of XYZ (cd m⁻² for Y) over the row's passes.
    pub(crate) xyz_sum: Vec<[f32; 3]>,
    pub(crate) row_passes: Vec<u32>,
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
            discarded: 0,
        }
    }

    /// Passes completed by every row.
    pub fn complete_passes(&self) -> u32 {
        self.row_passes.iter().copied().min().unwrap_or(0)
    }

    /// Mean XYZ of one pixel.
    pub fn xyz(&self, x: u32, y: u32) -> [f64; 3] {
        let n = self.row_passes[y as usize].max(1);
        let s = self.xyz_sum[(y * self.width + x) as usize];
        s.map(|v| f64::from(v) / f64::from(n))
    }

    /// The current estimate as linear Rec.709 (Y in cd m⁻²).
    pub fn to_rgb(&self) -> RgbImage {
        let w = self.width as usize;
        let mut pixels = Vec::with_capacity(self.xyz_sum.len());
        for (y, row) in self.xyz_sum.chunks(w).enumerate() {
            let inv = 1.0 / f64::from(self.row_passes[y].max(1));
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
