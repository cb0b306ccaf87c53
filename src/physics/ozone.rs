//! Ozone absorption: temperature-dependent cross-sections of Serdyuchenko,
//! Gorshelev et al. (2014, *Atmos. Meas. Tech.* 7, 609–624 and 625–636) and
//! the AFGL U.S. standard number-density profile (Anderson et al. 1986,
//! AFGL-TR-86-0110). See `data/README.md`.

use std::sync::OnceLock;

use crate::data::{self, Table};
use crate::physics::DOBSON_UNIT_PER_M2;

/// Temperatures of the cross-section table columns, K.
pub const TABLE_TEMPERATURES_K: [f64; 11] = [
    193.0, 203.0, 213.0, 223.0, 233.0, 243.0, 253.0, 263.0, 273.0, 283.0, 293.0,
];

/// The cross-section table on its 1 nm (vacuum) grid, in m².
pub struct CrossSections {
    first_wavelength_nm: f64,
    /// `values[i][k]`: wavelength index i, temperature index k.
    values: Vec<[f64; 11]>,
}

impl CrossSections {
    fn load() -> Self {
        let table = Table::parse(data::OZONE_CROSS_SECTION);
        let wavelengths = table.column_at(0);
        let values = table
            .rows
            .iter()
            .map(|row| {
                // cm² → m²; the few slightly negative values at the noise floor
                // (|σ| ≤ 1.5 × 10⁻²⁴ cm²) are clamped to zero.
                std::array::from_fn(|k| (row[k + 1] * 1e-4).max(0.0))
            })
            .collect();
        Self {
            first_wavelength_nm: wavelengths[0],
            values,
        }
    }

    /// The shared table (parsed once).
    pub fn get() -> &'static Self {
        static TABLE: OnceLock<CrossSections> = OnceLock::new();
        TABLE.get_or_init(Self::load)
    }

    /// Cross-sections at the 11 table temperatures at `wavelength_nm`
    /// (linear in wavelength; zero outside 214–1099 nm, where the visible
    /// and near-infrared absorption of ozone is negligible for our purposes).
    pub fn at_wavelength(&self, wavelength_nm: f64) -> [f64; 11] {
        let x = wavelength_nm - self.first_wavelength_nm;
        let last = self.values.len() - 1;
        if !(0.0..=last as f64).contains(&x) {
            return [0.0; 11];
        }
        let i = (x.floor() as usize).min(last - 1);
        let f = x - i as f64;
        let (a, b) = (&self.values[i], &self.values[i + 1]);
        std::array::from_fn(|k| a[k] + f * (b[k] - a[k]))
    }

    /// Cross-section (m²) at `wavelength_nm` and `temperature_k` (linear in
    /// temperature, clamped to the table's 193–293 K).
    pub fn cross_section_m2(&self, wavelength_nm: f64, temperature_k: f64) -> f64 {
        interpolate_temperature(&self.at_wavelength(wavelength_nm), temperature_k)
    }
}

/// Index and weight for linear interpolation between table temperatures.
pub fn temperature_weight(temperature_k: f64) -> (usize, f64) {
    let x = ((temperature_k - TABLE_TEMPERATURES_K[0]) / 10.0).clamp(0.0, 10.0);
    // x ≥ 0, so truncation is the floor (and no libm call per look-up).
    let i = (x as usize).min(9);
    (i, x - i as f64)
}

/// Interpolate 11 per-temperature values at `temperature_k`.
pub fn interpolate_temperature(values: &[f64; 11], temperature_k: f64) -> f64 {
    let (i, f) = temperature_weight(temperature_k);
    values[i] + f * (values[i + 1] - values[i])
}

/// The AFGL profile: altitude (m) and O₃ number density (m⁻³) at its 50 levels.
pub struct Profile {
    altitudes_m: Vec<f64>,
    ln_density: Vec<f64>,
}

impl Profile {
    fn load() -> Self {
        let table = Table::parse(data::OZONE_PROFILE);
        Self {
            altitudes_m: table.column_at(0).iter().map(|km| km * 1000.0).collect(),
            ln_density: table.column_at(1).iter().map(|n| n.ln()).collect(),
        }
    }

    /// The table, read once.
    pub fn get() -> &'static Self {
        static PROFILE: OnceLock<Profile> = OnceLock::new();
        PROFILE.get_or_init(Self::load)
    }

    /// Number density (m⁻³) at `altitude_m`: exponential between the AFGL
    /// levels (linear in its logarithm), constant below 0 m, and zero above the
    /// profile's top (120 km).
    pub fn number_density_m3(&self, altitude_m: f64) -> f64 {
        if altitude_m > *self.altitudes_m.last().unwrap() {
            return 0.0;
        }
        data::interpolate(&self.altitudes_m, &self.ln_density, altitude_m).exp()
    }

    /// Vertical column (molecules m⁻²) from `altitude_m` to `top_m`, integrated
    /// exactly for the log-linear interpolant.
    pub fn column_m2(&self, altitude_m: f64, top_m: f64) -> f64 {
        let mut total = 0.0;
        for i in 0..self.altitudes_m.len() - 1 {
            let (z0, z1) = (self.altitudes_m[i], self.altitudes_m[i + 1]);
            let lo = z0.max(altitude_m);
            let hi = z1.min(top_m);
            if hi <= lo {
                continue;
            }
            let slope = (self.ln_density[i + 1] - self.ln_density[i]) / (z1 - z0);
            let n_lo = (self.ln_density[i] + slope * (lo - z0)).exp();
            let n_hi = (self.ln_density[i] + slope * (hi - z0)).exp();
            total += if slope.abs() < 1e-12 {
                n_lo * (hi - lo)
            } else {
                (n_hi - n_lo) / slope
            };
        }
        total
    }

    /// Total column of the profile from the ground to `top_m`, Dobson units.
    pub fn column_du(&self, top_m: f64) -> f64 {
        self.column_m2(0.0, top_m) / DOBSON_UNIT_PER_M2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn total_column_is_the_afgl_value() {
        // data/README.md: 344.2 DU for exponential interpolation between levels.
        let du = Profile::get().column_du(120_000.0);
        assert!((du - 344.2).abs() < 0.5, "{du}");
    }

    #[test]
    fn chappuis_band_peaks_near_603_nm() {
        let xs = CrossSections::get();
        let (peak_nm, peak) = (500..700)
            .map(|nm| (nm, xs.cross_section_m2(f64::from(nm), 293.0)))
            .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a });
        assert!((600..=606).contains(&peak_nm), "{peak_nm}");
        // Serdyuchenko et al.: 5.107e-21 cm² at 603 nm, 293 K.
        assert!((peak / 5.107e-25 - 1.0).abs() < 0.01, "{peak}");
        // and 1.125e-17 cm² at the Hartley peak (255 nm, 293 K).
        assert!((xs.cross_section_m2(255.0, 293.0) / 1.125e-21 - 1.0).abs() < 0.01);
    }

    #[test]
    fn temperature_interpolation_hits_table_columns() {
        let xs = CrossSections::get();
        let a = xs.cross_section_m2(603.0, 223.0);
        assert!((a / 5.149e-25 - 1.0).abs() < 0.01, "{a}");
        let mid = xs.cross_section_m2(603.0, 228.0);
        let b = xs.cross_section_m2(603.0, 233.0);
        assert!((mid - 0.5 * (a + b)).abs() < 1e-30);
    }

    #[test]
    fn no_negative_cross_sections() {
        let xs = CrossSections::get();
        for nm in 214..1099 {
            assert!(xs.cross_section_m2(f64::from(nm), 250.0) >= 0.0);
        }
    }
}
