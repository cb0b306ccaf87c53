//! A vertical profile of the gas read from a CSV file (`[atmosphere]
//! profile`): a radiosonde ascent, a climate model's column, another
//! planet's measured atmosphere, in place of the U.S. Standard Atmosphere.
//!
//! **Form.** A header naming the columns, then one row per level:
//! - `altitude_m`, increasing from the first row (≥ 0);
//! - the gas as `temperature_k` and `pressure_pa` (the number density is
//!   then the ideal gas law's n = p / (k_B T)), or as `number_density_m3`
//!   (with `temperature_k` optional: without it the standard atmosphere's
//!   temperature is taken where a temperature is needed, the ozone
//!   cross-section's);
//! - optionally ozone, as `ozone_m3` (number density) or `ozone_vmr`
//!   (volume mixing ratio, times the air's number density).
//!
//! **Between levels** the number densities are interpolated linearly in
//! their logarithm (exact for an isothermal layer in hydrostatic balance,
//! where the density falls exponentially; a linear interpolation would
//! overestimate the air between levels a scale height apart by 8 %), and
//! the temperature linearly. Where a density is 0 at one end of a layer it
//! is taken linearly in that layer (a logarithm would be −∞). Below the
//! first level the first level's values hold; above the last level there
//! is no gas (the profile ends the atmosphere there, whatever the top).

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

/// Boltzmann constant, J K⁻¹ (exact in the 2019 SI), for n = p / (k_B T).
pub const BOLTZMANN_J_PER_K: f64 = 1.380_649e-23;

/// Most rows a profile may have (a radiosonde at 1 s resolution is a few
/// thousand).
pub const MAX_ROWS: usize = 100_000;

/// The form a profile file must have, as error messages state it.
pub const VALID_FORM: &str = "a CSV with a header naming its columns and at least two rows: \
     altitude_m (≥ 0, increasing), then temperature_k and pressure_pa, or number_density_m3 \
     (temperature_k optional), and optionally ozone_m3 or ozone_vmr; every value finite and ≥ 0, \
     temperatures > 0";

/// A gas profile: number densities and temperatures at levels.
#[derive(Clone, Debug, PartialEq)]
pub struct VerticalProfile {
    /// Altitudes of the levels, m, increasing.
    altitude_m: Vec<f64>,
    /// Number density of the gas, m⁻³.
    number_density_m3: Vec<f64>,
    /// Temperature, K, where the file gives it.
    temperature_k: Option<Vec<f64>>,
    /// Ozone number density, m⁻³, where the file gives it.
    ozone_m3: Option<Vec<f64>>,
}

/// Which quantity a column holds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Column {
    Altitude,
    Temperature,
    Pressure,
    NumberDensity,
    OzoneDensity,
    OzoneMixingRatio,
}

impl Column {
    fn parse(name: &str) -> Option<Self> {
        Some(match name {
            "altitude_m" => Self::Altitude,
            "temperature_k" => Self::Temperature,
            "pressure_pa" => Self::Pressure,
            "number_density_m3" => Self::NumberDensity,
            "ozone_m3" => Self::OzoneDensity,
            "ozone_vmr" => Self::OzoneMixingRatio,
            _ => return None,
        })
    }
}

/// The value at `z` of a quantity tabulated at `xs`, log-linear (or linear
/// where `log` is false or an end is 0), constant below the first level.
fn interpolate(xs: &[f64], ys: &[f64], z: f64, log: bool) -> f64 {
    let k = xs.partition_point(|&x| x <= z);
    if k == 0 {
        return ys[0];
    }
    if k == xs.len() {
        return if z == xs[k - 1] { ys[k - 1] } else { 0.0 };
    }
    let (x0, x1, y0, y1) = (xs[k - 1], xs[k], ys[k - 1], ys[k]);
    let t = (z - x0) / (x1 - x0);
    if log && y0 > 0.0 && y1 > 0.0 {
        y0 * (y1 / y0).powf(t)
    } else {
        y0 + t * (y1 - y0)
    }
}

impl VerticalProfile {
    /// Parses a profile file's text (see [`VALID_FORM`]): blank lines and
    /// lines starting with `#` are skipped. `Err` is (line number, reason);
    /// line 0 stands for the file as a whole.
    pub fn parse(text: &str) -> Result<Self, (usize, String)> {
        let mut header: Option<Vec<Column>> = None;
        let mut rows: Vec<(usize, Vec<f64>)> = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let line_no = i + 1;
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let Some(columns) = &header else {
                let mut columns = Vec::new();
                for name in &fields {
                    let column = Column::parse(name)
                        .ok_or_else(|| (line_no, format!("unknown column '{name}'")))?;
                    if columns.contains(&column) {
                        return Err((line_no, format!("column '{name}' given twice")));
                    }
                    columns.push(column);
                }
                let has = |c| columns.contains(&c);
                let problem = if columns.first() != Some(&Column::Altitude) {
                    Some("the first column must be altitude_m")
                } else if has(Column::NumberDensity) && has(Column::Pressure) {
                    Some("give number_density_m3 or pressure_pa, not both")
                } else if !(has(Column::NumberDensity)
                    || has(Column::Pressure) && has(Column::Temperature))
                {
                    Some("the gas needs temperature_k and pressure_pa, or number_density_m3")
                } else if has(Column::OzoneDensity) && has(Column::OzoneMixingRatio) {
                    Some("give ozone_m3 or ozone_vmr, not both")
                } else {
                    None
                };
                if let Some(problem) = problem {
                    return Err((line_no, format!("header '{line}': {problem}")));
                }
                header = Some(columns);
                continue;
            };
            if rows.len() == MAX_ROWS {
                return Err((line_no, format!("more than {MAX_ROWS} rows")));
            }
            if fields.len() != columns.len() {
                return Err((
                    line_no,
                    format!(
                        "'{line}' has {} values, the header {} columns",
                        fields.len(),
                        columns.len()
                    ),
                ));
            }
            let mut values = Vec::with_capacity(fields.len());
            for (field, column) in fields.iter().zip(columns) {
                let value: f64 = field
                    .parse()
                    .map_err(|_| (line_no, format!("'{field}' is not a number")))?;
                if !value.is_finite() || value < 0.0 {
                    return Err((line_no, format!("{value} is not a finite number ≥ 0")));
                }
                if *column == Column::Temperature && value == 0.0 {
                    return Err((line_no, "a temperature of 0 K".into()));
                }
                values.push(value);
            }
            if let Some((previous_line, previous)) = rows.last() {
                if values[0] <= previous[0] {
                    return Err((
                        line_no,
                        format!(
                            "altitude {} m does not increase from line {previous_line}'s {} m",
                            values[0], previous[0]
                        ),
                    ));
                }
            }
            rows.push((line_no, values));
        }
        let Some(columns) = header else {
            return Err((0, "no header".into()));
        };
        if rows.len() < 2 {
            let last_line = text.lines().count();
            return Err((
                last_line,
                format!("{} row(s): at least two levels are needed", rows.len()),
            ));
        }
        let column = |c: Column| {
            columns
                .iter()
                .position(|&k| k == c)
                .map(|j| rows.iter().map(|(_, r)| r[j]).collect::<Vec<f64>>())
        };
        let altitude_m = column(Column::Altitude).expect("checked with the header");
        let temperature_k = column(Column::Temperature);
        let number_density_m3 = column(Column::NumberDensity).unwrap_or_else(|| {
            let p = column(Column::Pressure).expect("checked with the header");
            let t = temperature_k.as_ref().expect("checked with the header");
            p.iter()
                .zip(t)
                .map(|(p, t)| p / (BOLTZMANN_J_PER_K * t))
                .collect()
        });
        let ozone_m3 = column(Column::OzoneDensity).or_else(|| {
            column(Column::OzoneMixingRatio).map(|vmr| {
                vmr.iter()
                    .zip(&number_density_m3)
                    .map(|(x, n)| x * n)
                    .collect()
            })
        });
        Ok(Self {
            altitude_m,
            number_density_m3,
            temperature_k,
            ozone_m3,
        })
    }

    /// Reads and parses a profile file; the error names the file, the line
    /// and the valid form.
    pub fn load(path: &Path) -> Result<Self, String> {
        super::data_file::load(path, VALID_FORM, Self::parse)
    }

    /// [`Self::load`], once per path for the life of the process
    /// ([`super::data_file::cached`]).
    pub fn cached(path: &Path) -> Result<Arc<Self>, String> {
        static CACHE: super::data_file::Cache<PathBuf, VerticalProfile> = OnceLock::new();
        super::data_file::cached(&CACHE, path.to_owned(), || Self::load(path))
    }

    /// Altitude of the highest level, m: the gas ends there.
    pub fn top_m(&self) -> f64 {
        *self.altitude_m.last().expect("at least two levels")
    }

    /// Number density of the gas at `altitude_m`, m⁻³ (log-linear between
    /// levels; 0 above the last).
    pub fn number_density_m3(&self, altitude_m: f64) -> f64 {
        interpolate(&self.altitude_m, &self.number_density_m3, altitude_m, true)
    }

    /// Temperature at `altitude_m`, K (linear between levels, the last
    /// level's above it), or `None` where the file gives none.
    pub fn temperature_k(&self, altitude_m: f64) -> Option<f64> {
        self.temperature_k
            .as_ref()
            .map(|t| interpolate(&self.altitude_m, t, altitude_m.min(self.top_m()), false))
    }

    /// Ozone number density at `altitude_m`, m⁻³, or `None` where the file
    /// gives no ozone column.
    pub fn ozone_m3(&self, altitude_m: f64) -> Option<f64> {
        self.ozone_m3
            .as_ref()
            .map(|o| interpolate(&self.altitude_m, o, altitude_m, true))
    }

    /// Whether the file gives an ozone column.
    pub fn has_ozone(&self) -> bool {
        self.ozone_m3.is_some()
    }

    /// The levels' altitudes, m.
    pub fn levels_m(&self) -> &[f64] {
        &self.altitude_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn number_density_follows_the_ideal_gas_law_at_a_level() {
        let p = VerticalProfile::parse(
            "altitude_m,temperature_k,pressure_pa\n0,288.15,101325\n1000,281.65,89874.6\n",
        )
        .unwrap();
        let want = 89_874.6 / (BOLTZMANN_J_PER_K * 281.65);
        assert!((p.number_density_m3(1000.0) / want - 1.0).abs() < 1e-12);
        // Log-linear halfway: the geometric mean of the two levels.
        let n0 = 101_325.0 / (BOLTZMANN_J_PER_K * 288.15);
        let mid = (n0 * want).sqrt();
        assert!((p.number_density_m3(500.0) / mid - 1.0).abs() < 1e-12);
        assert!((p.temperature_k(500.0).unwrap() - 284.9).abs() < 1e-9);
        assert_eq!(p.number_density_m3(1000.1), 0.0);
    }

    #[test]
    fn ozone_as_a_mixing_ratio_is_times_the_air() {
        let p = VerticalProfile::parse(
            "# comment\naltitude_m,number_density_m3,ozone_vmr\n0,2e25,1e-8\n5000,1e25,2e-8\n",
        )
        .unwrap();
        assert!((p.ozone_m3(0.0).unwrap() / 2e17 - 1.0).abs() < 1e-12);
        assert!((p.ozone_m3(5000.0).unwrap() / 2e17 - 1.0).abs() < 1e-12);
        assert_eq!(p.temperature_k(100.0), None);
    }

    #[test]
    fn bad_rows_are_named_by_line() {
        let cases = [
            ("altitude_m,number_density_m3\n0,1e25\n", 2, "at least two"),
            (
                "altitude_m,number_density_m3\n0,1e25\n500,1e24\n400,1e23\n",
                4,
                "does not increase",
            ),
            (
                "altitude_m,number_density_m3\n-10,1e25\n500,1e24\n",
                2,
                "≥ 0",
            ),
            (
                "altitude_m,number_density_m3\n0,NaN\n500,1e24\n",
                2,
                "finite",
            ),
            (
                "altitude_m,number_density_m3\n0,1e25\n500,-1e24\n",
                3,
                "≥ 0",
            ),
            ("altitude_m,temperature_k\n0,200\n500,190\n", 1, "needs"),
            ("altitude_m,density\n0,1\n1,1\n", 1, "unknown column"),
            ("altitude_m,number_density_m3\n0,1e25,3\n", 2, "values"),
        ];
        for (text, line, words) in cases {
            let (l, reason) = VerticalProfile::parse(text).unwrap_err();
            assert_eq!(l, line, "{text}: {reason}");
            assert!(reason.contains(words), "{text}: {reason}");
        }
    }
}
