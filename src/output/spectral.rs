//! Spectral OpenEXR files in the emissive layout of A. Fichet, R. Pacanowski
//! and A. Wilkie, "An OpenEXR Layout for Spectral Images", Journal of
//! Computer Graphics Techniques 10(3), 2021 (<https://jcgt.org/published/0010/03/01/>),
//! as their reference implementation (github.com/afichet/spectral-exr,
//! `lib/EXRSpectralImage.cpp`) writes and reads it:
//!
//! - one f32 channel per wavelength, `S0.<wavelength>nm`: `S0` the first
//!   Stokes component (unpolarised radiance), the wavelength in nm as C++'s
//!   `std::to_string(double)` prints it (`%f`, six decimals) with the decimal
//!   point written as a comma, since `.` separates layers in EXR channel
//!   names: `S0.555,000000nm`;
//! - the RGB image alongside, as `R`, `G`, `B`, for viewers that read no
//!   spectra;
//! - the string attributes `spectralLayoutVersion` = `1.0` and
//!   `emissiveUnits` = `W.m^-2.sr^-1` (the only unit the reference reader
//!   accepts; per nm of wavelength, as the channels sample a spectral
//!   density).
//!
//! Here each channel holds its band's mean spectral radiance, W m⁻² sr⁻¹
//! nm⁻¹, named by the band's centre ([`crate::render::film_spectral`]).

use std::path::Path;

use super::channels::write_exr_channels;
use super::{OutputError, RgbImage};

/// The layout's version attribute and value.
pub const LAYOUT_VERSION: (&str, &str) = ("spectralLayoutVersion", "1.0");
/// The layout's unit attribute and its value for spectral radiance.
pub const EMISSIVE_UNITS: (&str, &str) = ("emissiveUnits", "W.m^-2.sr^-1");

/// The layout's channel name for unpolarised emission at `wavelength_nm`:
/// `S0.555,000000nm`.
pub fn emissive_channel_name(wavelength_nm: f64) -> String {
    let number = format!("{wavelength_nm:.6}").replace('.', ",");
    format!("S0.{number}nm")
}

/// Writes `image` (`R`, `G`, `B`) and one channel per band of `planes`
/// (row-major, W m⁻² sr⁻¹ nm⁻¹) centred on `centres_nm`, with the text
/// `metadata` and the layout's attributes, as one EXR layer, atomically.
pub fn write_spectral_exr(
    path: &Path,
    image: &RgbImage,
    centres_nm: &[f64],
    planes: Vec<Vec<f32>>,
    metadata: &[(String, String)],
) -> Result<(), OutputError> {
    let mut channels = Vec::with_capacity(3 + planes.len());
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        channels.push((name.to_owned(), image.pixels.iter().map(|p| p[c]).collect()));
    }
    channels.extend(
        centres_nm
            .iter()
            .map(|&nm| emissive_channel_name(nm))
            .zip(planes),
    );
    let mut metadata = metadata.to_vec();
    for (key, value) in [LAYOUT_VERSION, EMISSIVE_UNITS] {
        metadata.push((key.to_owned(), value.to_owned()));
    }
    write_exr_channels(
        path,
        image.width as usize,
        image.height as usize,
        channels,
        &metadata,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channel_names_follow_the_reference_implementation() {
        assert_eq!(emissive_channel_name(555.0), "S0.555,000000nm");
        assert_eq!(emissive_channel_name(365.0), "S0.365,000000nm");
        assert_eq!(emissive_channel_name(827.5), "S0.827,500000nm");
    }
}
