//! The Sun: a uniform disc of the true mean angular radius with the measured
//! extraterrestrial spectrum (ASTM E-490-00a air-mass-zero table).
//!
//! The table's integral is 1 366.1 W m⁻², the "solar constant" of 2000. The
//! modern total solar irradiance from SORCE/TIM is 1 360.8 ± 0.5 W m⁻²
//! (Kopp & Lean 2011): E-490 is ≈ 0.4 % high in total, which is within the
//! uncertainty of its spectral shape; we use the table unscaled.

use std::f64::consts::PI;
use std::sync::OnceLock;

use crate::data::{self, Table};

/// Mean angular radius of the solar disc at 1 AU: 959.63″ (IAU 2015
/// nominal solar radius 695 700 km seen from 149 597 870.7 km).
pub const ANGULAR_RADIUS_DEG: f64 = 0.266_56;

/// Solid angle of the solar disc, sr: Ω = 2π(1 − cos α).
pub fn solid_angle_sr() -> f64 {
    2.0 * PI * (1.0 - ANGULAR_RADIUS_DEG.to_radians().cos())
}

/// The AM0 spectral irradiance table.
pub struct Spectrum {
    wavelengths_nm: Vec<f64>,
    irradiance: Vec<f64>,
}

impl Spectrum {
    fn load() -> Self {
        let table = Table::parse(data::SOLAR_AM0);
        Self {
            wavelengths_nm: table.column_at(0),
            irradiance: table.column_at(1),
        }
    }

    pub fn get() -> &'static Self {
        static SPECTRUM: OnceLock<Spectrum> = OnceLock::new();
        SPECTRUM.get_or_init(Self::load)
    }

    /// Spectral irradiance at the top of the atmosphere, W m⁻² nm⁻¹ (linear
    /// between the table's points).
    pub fn irradiance_w_m2_nm(&self, wavelength_nm: f64) -> f64 {
        data::interpolate(&self.wavelengths_nm, &self.irradiance, wavelength_nm)
    }

    /// Trapezoid integral of the table between two wavelengths, W m⁻².
    pub fn integral_w_m2(&self, from_nm: f64, to_nm: f64) -> f64 {
        self.wavelengths_nm
            .windows(2)
            .zip(self.irradiance.windows(2))
            .filter(|(w, _)| w[0] >= from_nm && w[1] <= to_nm)
            .map(|(w, e)| 0.5 * (e[0] + e[1]) * (w[1] - w[0]))
            .sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn am0_integral_is_the_e490_solar_constant() {
        let total = Spectrum::get().integral_w_m2(0.0, 1e7);
        assert!((total - 1366.1).abs() < 0.5, "{total}");
    }

    #[test]
    fn disc_solid_angle() {
        // α = 4.652 mrad → Ω ≈ πα² = 6.80 × 10⁻⁵ sr.
        assert!((solid_angle_sr() / 6.80e-5 - 1.0).abs() < 0.005);
    }

    #[test]
    fn green_irradiance_interpolates_the_e490_table() {
        // ASTM E490-00a prints 1.970 and 1.857 W m⁻² nm⁻¹ at 499.5 and
        // 500.5 nm (the visible peak region): linear between them, 1.9135
        // at 500 nm; a printed node is returned as printed.
        let spectrum = Spectrum::get();
        let e = spectrum.irradiance_w_m2_nm(500.0);
        assert!((e - 1.9135).abs() < 1e-9, "{e}");
        assert!((spectrum.irradiance_w_m2_nm(499.5) - 1.970).abs() < 1e-12);
    }
}
