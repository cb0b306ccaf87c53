//! A quantity tabulated against wavelength, read from a two-column CSV file
//! (`wavelength_nm,<quantity>`): a ground's albedo, the Sun's spectral
//! irradiance. Linear in wavelength between rows; every row is checked, and
//! an error names the file, the line and the valid form (as
//! [`super::phase_table`]'s do).

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use crate::data;

/// The wavelengths a render may ask for, nm: the colour-matching tables'
/// range (CIE 1931, 360–830 nm). A spectrum file must cover it.
pub const RENDERED_RANGE_NM: (f64, f64) = (360.0, 830.0);

/// Most rows a spectrum file may have (0.01 nm steps over 300–1100 nm are
/// 80 001).
pub const MAX_ROWS: usize = 200_000;

/// What a spectrum file holds, for its header and its checks.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Quantity {
    /// A Lambertian albedo, 0–1 (header `wavelength_nm,albedo`).
    Albedo,
    /// A spectral irradiance at 1 AU, W m⁻² nm⁻¹, ≥ 0 (header
    /// `wavelength_nm,irradiance`, or `irradiance_<unit>`).
    Irradiance,
}

impl Quantity {
    /// The second column's name.
    pub fn column(self) -> &'static str {
        match self {
            Self::Albedo => "albedo",
            Self::Irradiance => "irradiance",
        }
    }

    /// Largest valid value.
    fn max(self) -> f64 {
        match self {
            Self::Albedo => 1.0,
            Self::Irradiance => f64::INFINITY,
        }
    }

    /// The form a file must have, as error messages state it.
    pub fn valid_form(self) -> String {
        let (column, values) = match self {
            Self::Albedo => ("albedo", "albedos from 0 to 1"),
            Self::Irradiance => (
                "irradiance",
                "irradiances in W m⁻² nm⁻¹ at 1 AU, finite and ≥ 0",
            ),
        };
        format!(
            "a CSV with the header `wavelength_nm,{column}` and at least two rows \
             `wavelength_nm,{column}`: wavelengths in nm increasing and covering {}–{} nm, \
             {values}",
            RENDERED_RANGE_NM.0, RENDERED_RANGE_NM.1
        )
    }
}

/// A spectrum: values at increasing wavelengths, linear in between and
/// constant beyond the ends.
#[derive(Clone, Debug, PartialEq)]
pub struct Tabulated {
    /// Wavelengths, nm, increasing.
    pub wavelengths_nm: Vec<f64>,
    /// The quantity at `wavelengths_nm`.
    pub values: Vec<f64>,
}

impl Tabulated {
    /// The value at `wavelength_nm`.
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        data::interpolate(&self.wavelengths_nm, &self.values, wavelength_nm)
    }

    /// Largest value.
    pub fn max(&self) -> f64 {
        self.values.iter().copied().fold(0.0, f64::max)
    }

    /// Parses the text of a spectrum file: blank lines and lines starting
    /// with `#` are skipped; the first other line is the header. `Err` is
    /// (line number, reason); line 0 is the file as a whole.
    pub fn parse(text: &str, quantity: Quantity) -> Result<Self, (usize, String)> {
        let column = quantity.column();
        let mut wavelengths_nm: Vec<f64> = Vec::new();
        let mut values: Vec<f64> = Vec::new();
        let mut header_seen = false;
        let mut last_line = 0;
        for (i, line) in text.lines().enumerate() {
            let line_no = i + 1;
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            last_line = line_no;
            if !header_seen {
                let columns: Vec<&str> = line.split(',').map(str::trim).collect();
                let fits = matches!(columns[..], ["wavelength_nm", c]
                    if c == column || c.starts_with(&format!("{column}_")));
                if !fits {
                    return Err((
                        line_no,
                        format!("header '{line}' is not `wavelength_nm,{column}`"),
                    ));
                }
                header_seen = true;
                continue;
            }
            if wavelengths_nm.len() == MAX_ROWS {
                return Err((line_no, format!("more than {MAX_ROWS} rows")));
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let parsed = match fields[..] {
                [w, v] => w.parse::<f64>().ok().zip(v.parse::<f64>().ok()),
                _ => None,
            };
            let Some((wavelength, value)) = parsed else {
                return Err((
                    line_no,
                    format!("'{line}' is not two numbers `wavelength_nm,{column}`"),
                ));
            };
            if !wavelength.is_finite() || wavelength <= 0.0 {
                return Err((
                    line_no,
                    format!("wavelength {wavelength} nm is not a finite number > 0"),
                ));
            }
            if let Some(&previous) = wavelengths_nm.last() {
                if wavelength <= previous {
                    return Err((
                        line_no,
                        format!(
                            "wavelength {wavelength} nm does not increase from the previous \
                             row's {previous} nm"
                        ),
                    ));
                }
            }
            if !value.is_finite() || value < 0.0 || value > quantity.max() {
                let range = match quantity {
                    Quantity::Albedo => "from 0 to 1",
                    Quantity::Irradiance => "finite and ≥ 0",
                };
                return Err((line_no, format!("{column} {value} is not {range}")));
            }
            wavelengths_nm.push(wavelength);
            values.push(value);
        }
        if !header_seen {
            return Err((0, format!("no header `wavelength_nm,{column}`")));
        }
        let n = wavelengths_nm.len();
        if n < 2 {
            return Err((
                last_line,
                format!("{n} row(s): at least two rows are needed"),
            ));
        }
        let (from, to) = RENDERED_RANGE_NM;
        if wavelengths_nm[0] > from || wavelengths_nm[n - 1] < to {
            return Err((
                0,
                format!(
                    "the rows cover {}–{} nm, not the rendered {from}–{to} nm",
                    wavelengths_nm[0],
                    wavelengths_nm[n - 1]
                ),
            ));
        }
        Ok(Self {
            wavelengths_nm,
            values,
        })
    }

    /// Reads and parses a spectrum file; the error names the file, the
    /// line and the valid form.
    pub fn load(path: &Path, quantity: Quantity) -> Result<Self, String> {
        super::data_file::load(path, &quantity.valid_form(), |text| {
            Self::parse(text, quantity)
        })
    }

    /// [`Self::load`], once per path and quantity for the life of the
    /// process ([`super::data_file::cached`]).
    pub fn cached(path: &Path, quantity: Quantity) -> Result<Arc<Self>, String> {
        static CACHE: super::data_file::Cache<(PathBuf, Quantity), Tabulated> = OnceLock::new();
        super::data_file::cached(&CACHE, (path.to_owned(), quantity), || {
            Self::load(path, quantity)
        })
    }
}

/// The named ground spectra of `data/` (USGS Spectral Library Version 7,
/// Kokaly et al. 2017, doi:10.5066/F7RR1WDJ; sample ids and resampling in
/// `data/README.md`).
pub const GROUND_SPECTRA: [(&str, &str); 4] = [
    ("grass", data::GROUND_GRASS),
    ("snow", data::GROUND_SNOW),
    ("sand", data::GROUND_SAND),
    ("ocean", data::GROUND_OCEAN),
];

/// A named ground spectrum ([`GROUND_SPECTRA`]), or `None` for another name.
pub fn named_ground(name: &str) -> Option<Arc<Tabulated>> {
    static PARSED: OnceLock<Vec<Arc<Tabulated>>> = OnceLock::new();
    let parsed = PARSED.get_or_init(|| {
        GROUND_SPECTRA
            .iter()
            .map(|(_, text)| {
                Arc::new(Tabulated::parse(text, Quantity::Albedo).expect("an embedded table"))
            })
            .collect()
    });
    GROUND_SPECTRA
        .iter()
        .position(|(n, _)| *n == name)
        .map(|i| Arc::clone(&parsed[i]))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn error(text: &str) -> (usize, String) {
        Tabulated::parse(text, Quantity::Albedo).unwrap_err()
    }

    #[test]
    fn bad_rows_are_named_by_line() {
        let (line, reason) = error("wavelength_nm,albedo\n360,0.3\n");
        assert_eq!(line, 2, "{reason}");
        assert!(reason.contains("at least two rows"), "{reason}");
        let (line, reason) = error("wavelength_nm,albedo\n360,0.3\n830,0.3\n600,0.3\n");
        assert_eq!(line, 4, "{reason}");
        assert!(reason.contains("does not increase"), "{reason}");
        let (line, reason) = error("wavelength_nm,albedo\n360,0.3\n500,-0.1\n830,0.3\n");
        assert_eq!(line, 3, "{reason}");
        assert!(reason.contains("-0.1"), "{reason}");
        let (line, reason) = error("wavelength_nm,albedo\n360,NaN\n830,0.3\n");
        assert_eq!(line, 2, "{reason}");
        let (line, reason) = error("wavelength_nm,albedo\n400,0.3\n830,0.3\n");
        assert_eq!(line, 0, "{reason}");
        assert!(reason.contains("360"), "{reason}");
        let (line, reason) = error("wavelength_nm,albedo\n360,1.5\n830,0.3\n");
        assert_eq!(line, 2, "{reason}");
        let (line, reason) = error("angle_deg,phase\n360,0.3\n830,0.3\n");
        assert_eq!(line, 1, "{reason}");
    }

    #[test]
    fn an_irradiance_file_may_name_its_unit() {
        let text = "# E-490\nwavelength_nm,irradiance_W_m-2_nm-1\n300,1\n900,3\n";
        let t = Tabulated::parse(text, Quantity::Irradiance).unwrap();
        assert_eq!(t.at(600.0), 2.0);
        let (_, reason) = Tabulated::parse("wavelength_nm,irradiance\n300,1e400\n900,3\n", {
            Quantity::Irradiance
        })
        .unwrap_err();
        assert!(reason.contains("finite"), "{reason}");
    }

    /// USGS splib07 source points (the records' own wavelength, µm → nm,
    /// and reflectance, as the library prints them) and the tables' 5 nm
    /// nodes between or at them: the tables are the source's straight
    /// line between its valid samples.
    #[test]
    fn named_spectra_are_the_usgs_records() {
        // (name, node nm, [(source nm, source reflectance); 2]).
        let cases = [
            // Lawn_Grass_GDS91_green_BECKa_AREF, Beckman channels.
            (
                "grass",
                550.0,
                [(549.300_01, 0.096_918_613), (551.299_99, 0.097_290_933)],
            ),
            (
                "grass",
                450.0,
                [(448.8, 0.035_457_607), (451.3, 0.035_585_754)],
            ),
            // Seawater_Open_Ocean_SW2_lwch_BECKa_AREF.
            (
                "ocean",
                450.0,
                [(448.8, 0.043_949_541), (451.3, 0.043_623_023)],
            ),
            // Melting_snow_mSnw01a_ASDFRa_AREF, ASD 1 nm channels: a node
            // is a source sample.
            ("snow", 550.0, [(550.0, 0.832_376_54); 2]),
            ("snow", 750.0, [(750.0, 0.805_099_61); 2]),
            // Sand_DWO-3-DEL2ar1_no_oil_ASDFRa_AREF.
            ("sand", 650.0, [(650.0, 0.254_109_41); 2]),
            ("sand", 450.0, [(450.0, 0.156_504_59); 2]),
        ];
        for (name, node, [(x0, y0), (x1, y1)]) in cases {
            let table = named_ground(name).unwrap();
            let source = if x1 > x0 {
                y0 + (y1 - y0) * (node - x0) / (x1 - x0)
            } else {
                y0
            };
            // The tables print 5 decimals.
            let value = table.at(node);
            assert!(
                (value - source).abs() <= 5e-6,
                "{name} {node}: {value} vs {source}"
            );
            assert_eq!(table.wavelengths_nm.len(), 95);
            assert_eq!(table.wavelengths_nm[0], 360.0);
            assert_eq!(table.wavelengths_nm[94], 830.0);
        }
        assert!(named_ground("moss").is_none());
    }
}
