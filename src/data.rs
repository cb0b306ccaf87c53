//! The reference tables of `data/`, embedded in the binary at compile time.
//!
//! Each table is a plain CSV file (one header row, then numbers); its source
//! and any resampling are documented in `data/README.md`.

/// A parsed numeric CSV table.
#[derive(Clone, Debug)]
pub struct Table {
    /// Column names from the header.
    pub columns: Vec<String>,
    /// The rows, one value per column.
    pub rows: Vec<Vec<f64>>,
}

impl Table {
    /// Parse CSV text. The embedded tables are part of the build, so a
    /// malformed one is a programming error caught by the unit tests.
    pub fn parse(text: &str) -> Self {
        let mut lines = text.lines().filter(|l| !l.trim().is_empty());
        let columns = lines
            .next()
            .expect("table has a header")
            .split(',')
            .map(|s| s.trim().to_owned())
            .collect::<Vec<_>>();
        let rows = lines
            .map(|line| {
                line.split(',')
                    .map(|s| s.trim().parse::<f64>().expect("table cell is a number"))
                    .collect::<Vec<_>>()
            })
            .collect::<Vec<_>>();
        Self { columns, rows }
    }

    /// All values of the named column.
    pub fn column(&self, name: &str) -> Vec<f64> {
        let index = self
            .columns
            .iter()
            .position(|c| c == name)
            .unwrap_or_else(|| panic!("table has no column {name}"));
        self.rows.iter().map(|r| r[index]).collect()
    }

    /// Values of column `index`.
    pub fn column_at(&self, index: usize) -> Vec<f64> {
        self.rows.iter().map(|r| r[index]).collect()
    }
}

/// CIE 1931 2° colour-matching functions, Judd (1951)–Vos (1978) modified, 380–825 nm / 5 nm.
pub const CMF_JUDD_VOS: &str = include_str!("../data/cie1931_judd_vos_2deg.csv");
/// CIE 1931 2° standard observer, 360–830 nm / 1 nm.
pub const CMF_CIE1931: &str = include_str!("../data/cie1931_2deg.csv");
/// ASTM E-490-00a extraterrestrial solar spectral irradiance (W m⁻² nm⁻¹).
pub const SOLAR_AM0: &str = include_str!("../data/solar_am0.csv");
/// Serdyuchenko–Gorshelev (2014) ozone cross-sections, 11 temperatures.
pub const OZONE_CROSS_SECTION: &str = include_str!("../data/ozone_cross_section.csv");
/// AFGL U.S. standard ozone number-density profile (Anderson et al. 1986).
pub const OZONE_PROFILE: &str = include_str!("../data/ozone_profile.csv");
/// Elterman (1968) aerosol attenuation at 340 nm.
pub const ELTERMAN_AEROSOL: &str = include_str!("../data/elterman1968_aerosol.csv");
/// Elterman (1968) total attenuation at 22 wavelengths.
pub const ELTERMAN_TOTAL: &str = include_str!("../data/elterman1968_total_attenuation.csv");
/// Mars temperature and pressure against altitude: the Mars-GRAM 2005
/// auxiliary profile of Justus, Duvall & Keller (2005), Table 1.
pub const MARS_PROFILE: &str = include_str!("../data/mars_tes_phoenix_justus2005.csv");
/// Martian dust's refractive index (Wolff et al.), 263–1000 nm.
pub const MARS_DUST_REFRACTIVE_INDEX: &str =
    include_str!("../data/mars_dust_refractive_index_wolff.csv");
/// Martian dust's phase function, 360–840 nm, by Lorenz–Mie theory
/// (`physics::planet::mars_dust::mie_phase`).
pub const MARS_DUST_PHASE: &str = include_str!("../data/mars_dust_phase_mie.csv");

/// Lawn grass GDS91 (green), USGS Spectral Library 7, 360–830 nm / 5 nm.
pub const GROUND_GRASS: &str = include_str!("../data/ground_grass.csv");
/// Melting snow mSnw01a, USGS Spectral Library 7, 360–830 nm / 5 nm.
pub const GROUND_SNOW: &str = include_str!("../data/ground_snow.csv");
/// Sand DWO-3-DEL2ar1 (no oil), USGS Spectral Library 7, 360–830 nm / 5 nm.
pub const GROUND_SAND: &str = include_str!("../data/ground_sand.csv");
/// Seawater, open ocean SW2, USGS Spectral Library 7, 360–830 nm / 5 nm.
pub const GROUND_OCEAN: &str = include_str!("../data/ground_ocean.csv");

/// Piecewise-linear interpolation of `ys(xs)` at `x`, clamped to the ends.
/// `xs` must be ascending.
pub fn interpolate(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    debug_assert_eq!(xs.len(), ys.len());
    if x <= xs[0] {
        return ys[0];
    }
    let last = xs.len() - 1;
    if x >= xs[last] {
        return ys[last];
    }
    let i = xs.partition_point(|&v| v <= x) - 1;
    let f = (x - xs[i]) / (xs[i + 1] - xs[i]);
    ys[i] + f * (ys[i + 1] - ys[i])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_embedded_table_parses_with_sorted_first_column() {
        for text in [
            CMF_JUDD_VOS,
            CMF_CIE1931,
            SOLAR_AM0,
            OZONE_CROSS_SECTION,
            OZONE_PROFILE,
            ELTERMAN_AEROSOL,
            ELTERMAN_TOTAL,
        ] {
            let table = Table::parse(text);
            assert!(table.rows.len() > 10);
            let xs = table.column_at(0);
            assert!(xs.windows(2).all(|w| w[0] < w[1]));
            assert!(table.rows.iter().all(|r| r.len() == table.columns.len()));
        }
    }

    #[test]
    fn interpolation_is_linear_and_clamped() {
        let xs = [0.0, 1.0, 3.0];
        let ys = [0.0, 2.0, 6.0];
        assert_eq!(interpolate(&xs, &ys, 0.5), 1.0);
        assert_eq!(interpolate(&xs, &ys, 2.0), 4.0);
        assert_eq!(interpolate(&xs, &ys, -1.0), 0.0);
        assert_eq!(interpolate(&xs, &ys, 9.0), 6.0);
    }
}
