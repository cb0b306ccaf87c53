//! The film's spectral layer: band-averaged spectral radiance per pixel,
//! estimated from the same paths as the XYZ image (no second render).
//!
//! Each camera sample's wavelength lanes carry a wavelength λⱼ drawn with
//! density p(λⱼ) and the radiance L(λⱼ) found along the path; the XYZ film
//! adds K_m L(λⱼ) x̄(λⱼ) / (p(λⱼ) n) over the n lanes. The spectral layer adds
//! L(λⱼ) / (p(λⱼ) n Δ) to the band of width Δ holding λⱼ: a histogram
//! estimator, whose expectation is ∫_band L dλ / Δ, the band's mean spectral
//! radiance (W m⁻² sr⁻¹ nm⁻¹). The sums are weighted and normalised exactly
//! as the XYZ sums are (the draft pass's weight, mirror pairs, the adaptive
//! plan, the circle splats), so the spectral image integrated with the
//! colour-matching functions gives the RGB image up to the CMFs' variation
//! within a band.
//!
//! Bands split 360–830 nm (the CIE 1931 tables' range) evenly. The default,
//! [`DEFAULT_SPECTRAL_BANDS`] = 47 bands of 10 nm: twice the Judd–Vos
//! table's 5 nm step, fine enough for the sky's smooth spectra (Rayleigh's
//! λ⁻⁴, ozone's broad Chappuis band), and half the memory, file size and
//! per-band noise variance of 5 nm bands (each band catches twice the
//! wavelength samples). A 2048×1024 image in 47 bands holds 394 MB of f32
//! sums per layer ([`spectral_bytes_per_pixel`]).

use super::alloc::try_filled;
use super::medium::LANES;

/// The spectral image's first wavelength, nm.
pub const SPECTRAL_FIRST_NM: f64 = 360.0;
/// The spectral image's last wavelength, nm.
pub const SPECTRAL_LAST_NM: f64 = 830.0;
/// Bands when none are given: 10 nm each (see the module documentation).
pub const DEFAULT_SPECTRAL_BANDS: u32 = 47;

/// Width of each of `bands` bands, nm.
pub fn band_width_nm(bands: usize) -> f64 {
    (SPECTRAL_LAST_NM - SPECTRAL_FIRST_NM) / bands as f64
}

/// The centre wavelengths of `bands` bands, nm.
pub fn band_centres_nm(bands: usize) -> Vec<f64> {
    let width = band_width_nm(bands);
    (0..bands)
        .map(|b| SPECTRAL_FIRST_NM + (b as f64 + 0.5) * width)
        .collect()
}

/// The band holding `wavelength_nm` (830 nm in the last), or `None` outside
/// 360–830 nm.
pub fn band_of(bands: usize, wavelength_nm: f64) -> Option<usize> {
    if !(SPECTRAL_FIRST_NM..=SPECTRAL_LAST_NM).contains(&wavelength_nm) {
        return None;
    }
    let b = ((wavelength_nm - SPECTRAL_FIRST_NM) / band_width_nm(bands)) as usize;
    Some(b.min(bands - 1))
}

/// Bytes a spectral render of `bands` bands holds per pixel: the camera
/// sums, the splats' sums where the renderer splats, and the band planes
/// written out (f32 each).
pub fn spectral_bytes_per_pixel(bands: u32, splatting: bool) -> u64 {
    u64::from(bands) * 4 * if splatting { 3 } else { 2 }
}

/// One sample's (or splat's) lanes: wavelength and radiance over its
/// density and the lane count, L(λ) / (p(λ) n), W m⁻² sr⁻¹.
#[derive(Clone, Copy, Debug, Default)]
pub struct SampleLanes {
    /// Lanes in use.
    pub active: usize,
    /// Each lane's wavelength, nm.
    pub wavelengths_nm: [f64; LANES],
    /// Each lane's L(λ) / (p(λ) n).
    pub values: [f64; LANES],
}

impl SampleLanes {
    /// Adds the lanes × `weight` to `pixel`'s bands (one slot per band).
    pub fn add_to(&self, pixel: &mut [f32], weight: f64) {
        let width = band_width_nm(pixel.len());
        for j in 0..self.active {
            if let Some(b) = band_of(pixel.len(), self.wavelengths_nm[j]) {
                pixel[b] += (weight * self.values[j] / width) as f32;
            }
        }
    }
}

/// A splat's lanes, compactly (splats are many): wavelength and
/// L(λ) / (p(λ) n) × the splat's weight; inactive lanes hold 0.
#[derive(Clone, Copy, Debug, Default)]
pub struct SplatLanes {
    /// Each lane's wavelength, nm.
    pub wavelengths_nm: [f32; LANES],
    /// Each lane's weighted L(λ) / (p(λ) n).
    pub values: [f32; LANES],
}

impl SplatLanes {
    /// Adds the lanes to `pixel`'s bands (one slot per band).
    fn add_to(&self, pixel: &mut [f32]) {
        let width = band_width_nm(pixel.len());
        for (&l, &v) in self.wavelengths_nm.iter().zip(&self.values) {
            if let Some(b) = band_of(pixel.len(), f64::from(l)) {
                pixel[b] += (f64::from(v) / width) as f32;
            }
        }
    }
}

/// The spectral sums of a film.
#[derive(Clone, Debug)]
pub struct SpectralFilm {
    /// Bands over 360–830 nm.
    pub bands: usize,
    /// Per row, `width` × `bands` weighted sums of the camera samples, like
    /// [`Film`]'s XYZ sums.
    pub(crate) rows: Vec<Vec<f32>>,
    /// Per pixel × band, the splats' sums (empty unless the film splats).
    pub(crate) splat_sum: Vec<f32>,
}

impl SpectralFilm {
    /// Empty sums of `bands` bands for a `width`×`height` film, with a
    /// splat layer where `splats`.
    pub(crate) fn try_new(
        width: u32,
        height: u32,
        bands: u32,
        splats: bool,
    ) -> Result<Self, std::collections::TryReserveError> {
        let (w, h, bands) = (width as usize, height as usize, bands as usize);
        let mut rows = Vec::new();
        rows.try_reserve_exact(h)?;
        for _ in 0..h {
            rows.push(try_filled(w * bands, 0.0f32)?);
        }
        let splat_sum = if splats {
            try_filled(w * h * bands, 0.0f32)?
        } else {
            Vec::new()
        };
        Ok(Self {
            bands,
            rows,
            splat_sum,
        })
    }

    /// Bytes held by the sums.
    pub fn buffer_bytes(&self) -> usize {
        4 * (self.rows.iter().map(Vec::len).sum::<usize>() + self.splat_sum.len())
    }

    /// Adds one batch of splats.
    pub(crate) fn add_splats(&mut self, splats: &[Splat]) {
        if self.splat_sum.is_empty() {
            return;
        }
        let bands = self.bands;
        for s in splats {
            let i = s.pixel as usize * bands;
            s.lanes.add_to(&mut self.splat_sum[i..i + bands]);
        }
    }
}

/// One path's contribution to one pixel.
#[derive(Clone, Copy, Debug)]
pub struct Splat {
    /// Row-major pixel index.
    pub pixel: u32,
    /// Where it lands across the pixel's columns, 0–1 from its left edge
    /// (which part a [`super::HalfMirror`] reads it in).
    pub column_offset: f32,
    /// XYZ (Y in cd m⁻²) times the number of paths it is averaged over.
    pub xyz: [f64; 3],
    /// The same light by wavelength lane, for a spectral film: the lanes'
    /// radiance (W m⁻² sr⁻¹ nm⁻¹) times the splat's weight; the renderer
    /// divides by the lanes' densities (the renderer's splat pass).
    pub lanes: SplatLanes,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bands_cover_360_to_830_nm() {
        assert_eq!(band_width_nm(47), 10.0);
        assert_eq!(band_centres_nm(47)[0], 365.0);
        assert_eq!(band_of(47, 360.0), Some(0));
        assert_eq!(band_of(47, 829.9), Some(46));
        assert_eq!(band_of(47, 830.0), Some(46));
        assert_eq!(band_of(47, 359.9), None);
        let mut pixel = [0.0f32; 47];
        let mut lanes = SampleLanes {
            active: 1,
            ..SampleLanes::default()
        };
        lanes.wavelengths_nm[0] = 551.0;
        lanes.values[0] = 20.0;
        lanes.add_to(&mut pixel, 0.5);
        assert_eq!(pixel[19], 1.0);
    }
}
