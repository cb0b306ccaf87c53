//! Spectral to colour: colour-matching functions, wavelength sampling and the
//! XYZ → linear Rec.709 conversion.

use std::sync::OnceLock;

use crate::data::{self, Table};

/// Wavelengths carried by one path (hero wavelength and its rotations,
/// Wilkie et al. 2014).
pub const LANES: usize = 4;

/// Maximum luminous efficacy for photopic vision, lm W⁻¹ (CIE; BIPM SI
/// brochure: K_cd = 683 lm W⁻¹ at 540 THz).
pub const K_M: f64 = 683.0;

/// Which colour-matching functions turn spectra into XYZ.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Observer {
    /// CIE 1931 2° as modified by Judd (1951) and Vos (1978), 380–825 nm.
    #[default]
    JuddVos,
    /// CIE 1931 2° standard observer, 360–830 nm.
    Cie1931,
}

/// Colour-matching functions on a regular grid, with a wavelength sampler.
pub struct ColourMatching {
    first_nm: f64,
    step_nm: f64,
    xyz: Vec<[f64; 3]>,
    /// Cumulative distribution of the sampling density over grid intervals.
    cdf: Vec<f64>,
    /// Sampling density per interval (per nm).
    pdf: Vec<f64>,
}

impl ColourMatching {
    fn load(text: &str) -> Self {
        let table = Table::parse(text);
        let wavelengths = table.column_at(0);
        let xyz: Vec<[f64; 3]> = table.rows.iter().map(|r| [r[1], r[2], r[3]]).collect();
        let step_nm = wavelengths[1] - wavelengths[0];
        // Importance density ∝ x̄ + ȳ + z̄ (averaged over each interval), mixed
        // with 10 % uniform so the tails are never starved.
        let weights: Vec<f64> = xyz
            .windows(2)
            .map(|w| 0.5 * (w[0].iter().sum::<f64>() + w[1].iter().sum::<f64>()))
            .collect();
        let total: f64 = weights.iter().sum();
        let n = weights.len() as f64;
        let probabilities: Vec<f64> = weights.iter().map(|w| 0.9 * w / total + 0.1 / n).collect();
        let mut cdf = vec![0.0];
        for p in &probabilities {
            cdf.push(cdf.last().unwrap() + p);
        }
        let last = *cdf.last().unwrap();
        for c in &mut cdf {
            *c /= last;
        }
        let pdf = probabilities.iter().map(|p| p / last / step_nm).collect();
        Self {
            first_nm: wavelengths[0],
            step_nm,
            xyz,
            cdf,
            pdf,
        }
    }

    /// The colour-matching functions of `observer`, read once.
    pub fn get(observer: Observer) -> &'static Self {
        static JV: OnceLock<ColourMatching> = OnceLock::new();
        static CIE: OnceLock<ColourMatching> = OnceLock::new();
        match observer {
            Observer::JuddVos => JV.get_or_init(|| Self::load(data::CMF_JUDD_VOS)),
            Observer::Cie1931 => CIE.get_or_init(|| Self::load(data::CMF_CIE1931)),
        }
    }

    /// The wavelength range covered, nm.
    pub fn range_nm(&self) -> (f64, f64) {
        (
            self.first_nm,
            self.first_nm + self.step_nm * (self.xyz.len() - 1) as f64,
        )
    }

    /// The table's wavelengths, nm: the grid [`Self::integrate`] samples.
    pub fn grid_nm(&self) -> impl Iterator<Item = f64> + '_ {
        (0..self.xyz.len()).map(|i| self.first_nm + i as f64 * self.step_nm)
    }

    /// x̄, ȳ, z̄ at `wavelength_nm` (linear; zero outside the table).
    pub fn xyz_bar(&self, wavelength_nm: f64) -> [f64; 3] {
        let x = (wavelength_nm - self.first_nm) / self.step_nm;
        let last = self.xyz.len() - 1;
        if !(0.0..=last as f64).contains(&x) {
            return [0.0; 3];
        }
        let i = (x.floor() as usize).min(last - 1);
        let f = x - i as f64;
        std::array::from_fn(|k| self.xyz[i][k] + f * (self.xyz[i + 1][k] - self.xyz[i][k]))
    }

    /// Map a uniform number to a wavelength; returns (wavelength_nm, pdf per nm).
    pub fn sample_wavelength(&self, u: f64) -> (f64, f64) {
        let i = (self.cdf.partition_point(|&c| c <= u).max(1) - 1).min(self.pdf.len() - 1);
        let within = (u - self.cdf[i]) / (self.cdf[i + 1] - self.cdf[i]);
        let wavelength = self.first_nm + (i as f64 + within.clamp(0.0, 1.0)) * self.step_nm;
        (wavelength, self.pdf[i])
    }

    /// The sampling density (per nm) at `wavelength_nm`.
    pub fn pdf(&self, wavelength_nm: f64) -> f64 {
        let x = (wavelength_nm - self.first_nm) / self.step_nm;
        if x < 0.0 || x > self.pdf.len() as f64 {
            return 0.0;
        }
        self.pdf[(x as usize).min(self.pdf.len() - 1)]
    }

    /// Integrate a spectrum (per nm) against the CMFs with the trapezoid rule
    /// on the table's grid; returns unnormalised XYZ.
    pub fn integrate(&self, spectrum: impl Fn(f64) -> f64) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (i, bar) in self.xyz.iter().enumerate() {
            let w = if i == 0 || i == self.xyz.len() - 1 {
                0.5
            } else {
                1.0
            };
            let s = spectrum(self.first_nm + i as f64 * self.step_nm) * w * self.step_nm;
            for k in 0..3 {
                out[k] += bar[k] * s;
            }
        }
        out
    }
}

/// XYZ → linear Rec.709 (sRGB primaries, D65 white), IEC 61966-2-1.
pub const XYZ_TO_REC709: [[f64; 3]; 3] = [
    [3.240_454_2, -1.537_138_5, -0.498_531_4],
    [-0.969_266_0, 1.876_010_8, 0.041_556_0],
    [0.055_643_4, -0.204_025_9, 1.057_225_2],
];

/// Convert CIE XYZ to linear Rec.709 RGB.
pub fn xyz_to_rec709(xyz: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|c| XYZ_TO_REC709[r][c] * xyz[c]).sum())
}

/// The luminance Y of a linear Rec.709 triple (the Y row of the inverse of
/// [`XYZ_TO_REC709`], IEC 61966-2-1).
pub fn rec709_luminance(rgb: [f64; 3]) -> f64 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Chromaticity (x, y) of an XYZ triple.
pub fn chromaticity(xyz: [f64; 3]) -> (f64, f64) {
    let s = xyz[0] + xyz[1] + xyz[2];
    (xyz[0] / s, xyz[1] / s)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equal_energy_spectrum_is_illuminant_e() {
        // By construction of the CIE 1931 CMFs, E has x = y = 1/3.
        let (x, y) = chromaticity(ColourMatching::get(Observer::Cie1931).integrate(|_| 1.0));
        assert!(
            (x - 1.0 / 3.0).abs() < 2e-4 && (y - 1.0 / 3.0).abs() < 2e-4,
            "{x} {y}"
        );
        // Judd–Vos moves E only slightly.
        let (x, y) = chromaticity(ColourMatching::get(Observer::JuddVos).integrate(|_| 1.0));
        assert!(
            (x - 1.0 / 3.0).abs() < 0.01 && (y - 1.0 / 3.0).abs() < 0.01,
            "{x} {y}"
        );
    }

    #[test]
    fn d65_white_maps_to_equal_rgb() {
        // D65 white point x = 0.3127, y = 0.3290 (CIE 15).
        let (x, y) = (0.3127, 0.3290);
        let xyz = [x / y, 1.0, (1.0 - x - y) / y];
        let rgb = xyz_to_rec709(xyz);
        for c in rgb {
            assert!((c - 1.0).abs() < 1e-3, "{rgb:?}");
        }
    }

    #[test]
    fn wavelength_sampler_is_a_normalised_density() {
        let cmf = ColourMatching::get(Observer::JuddVos);
        let (lo, hi) = cmf.range_nm();
        let n = 10_000;
        let integral: f64 = (0..n)
            .map(|i| {
                cmf.pdf(lo + (hi - lo) * (f64::from(i) + 0.5) / f64::from(n)) * (hi - lo)
                    / f64::from(n)
            })
            .sum();
        assert!((integral - 1.0).abs() < 1e-3, "{integral}");
        for i in 0..100 {
            let (w, p) = cmf.sample_wavelength(f64::from(i) / 100.0);
            assert!((lo..=hi).contains(&w));
            assert!((p - cmf.pdf(w)).abs() < 1e-12 || (w - lo).abs() < 1e-9);
        }
    }

    #[test]
    fn y_bar_peaks_at_555_nm() {
        let cmf = ColourMatching::get(Observer::Cie1931);
        assert!((cmf.xyz_bar(555.0)[1] - 1.0).abs() < 1e-3);
    }
}
