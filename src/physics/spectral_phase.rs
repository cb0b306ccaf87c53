//! A phase function tabulated against the scattering angle at one or more
//! wavelengths: the file form `angle_deg,phase[,wavelength_nm]`.
//!
//! Particles comparable to the wavelength scatter with a forward peak
//! whose width is about λ/(2r): the Martian dust's is narrower in the blue
//! than in the red, which is what makes the blue aureole about the setting
//! Sun. A table with a wavelength column holds one [`PhaseTable`] per
//! tabulated wavelength (its rows in a block, the blocks in increasing
//! wavelength).
//!
//! **Model.** Between two tabulated wavelengths λ_i < λ_{i+1} the phase
//! function is the linear blend p_λ = (1 − w) p_i + w p_{i+1}, w = (λ −
//! λ_i)/(λ_{i+1} − λ_i), and constant beyond the ends. A blend of two
//! normalised densities is a normalised density and a mixture, so it is
//! sampled exactly by choosing p_{i+1} with probability w and sampling it;
//! its Legendre moments are the same blend of the nodes' moments. A table
//! without the wavelength column is one node: the same at every
//! wavelength.

use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};

use super::phase_table::{PhaseTable, MAX_ROWS};
use super::spectrum_file::RENDERED_RANGE_NM;

/// The form a phase function file must have, as error messages state it.
pub const VALID_FORM: &str = "a CSV with the header `angle_deg,phase` (one phase function) or \
     `angle_deg,phase,wavelength_nm` (one per wavelength, in blocks of rows of \
     increasing wavelength covering 360–830 nm); each block at least two rows, \
     scattering angles in degrees increasing from 0 to 180, phase values finite \
     and ≥ 0, not all 0";

/// Phase functions tabulated against angle at increasing wavelengths,
/// linear in wavelength between them.
#[derive(Clone, Debug, PartialEq)]
pub struct SpectralPhaseTable {
    /// The nodes' wavelengths, nm, increasing (one entry, NaN, for a
    /// table without wavelengths).
    wavelengths_nm: Vec<f64>,
    /// The phase function at each node.
    tables: Vec<PhaseTable>,
}

impl SpectralPhaseTable {
    /// Whether the phase function varies with wavelength (more than one
    /// node).
    pub fn is_spectral(&self) -> bool {
        self.tables.len() > 1
    }

    /// The nodes' wavelengths, nm (empty for a grey table).
    pub fn node_wavelengths_nm(&self) -> &[f64] {
        if self.is_spectral() {
            &self.wavelengths_nm
        } else {
            &[]
        }
    }

    /// The node at `index` (in the order of [`Self::node_wavelengths_nm`];
    /// 0 for a grey table).
    pub fn node(&self, index: usize) -> &PhaseTable {
        &self.tables[index]
    }

    /// The blend at `wavelength_nm`: node `i` with weight 1 − `w` and node
    /// `i + 1` with weight `w` (w = 0 beyond the ends and for a grey
    /// table).
    pub fn bracket(&self, wavelength_nm: f64) -> (usize, f64) {
        let n = self.wavelengths_nm.len();
        if n == 1 || wavelength_nm.is_nan() || wavelength_nm <= self.wavelengths_nm[0] {
            return (0, 0.0);
        }
        if wavelength_nm >= self.wavelengths_nm[n - 1] {
            return (n - 1, 0.0);
        }
        let i = self.wavelengths_nm.partition_point(|&w| w <= wavelength_nm) - 1;
        let (l0, l1) = (self.wavelengths_nm[i], self.wavelengths_nm[i + 1]);
        (i, (wavelength_nm - l0) / (l1 - l0))
    }

    /// The phase function at cosine `mu` and `wavelength_nm`, sr⁻¹.
    pub fn eval(&self, mu: f64, wavelength_nm: f64) -> f64 {
        match self.bracket(wavelength_nm) {
            (i, 0.0) => self.tables[i].eval(mu),
            (i, w) => (1.0 - w) * self.tables[i].eval(mu) + w * self.tables[i + 1].eval(mu),
        }
    }

    /// A cosine drawn with density [`Self::eval`] at `wavelength_nm`: the
    /// node by its weight in the blend (one uniform number, none where
    /// there is one node), then the node's inverse CDF.
    pub fn sample(&self, wavelength_nm: f64, mut uniform: impl FnMut() -> f64) -> f64 {
        let (i, w) = self.bracket(wavelength_nm);
        let node = if w > 0.0 && uniform() < w { i + 1 } else { i };
        self.tables[node].sample(uniform())
    }

    /// Legendre moments 2π ∫ p_λ P_l dμ, l = 0..N, at `wavelength_nm`.
    pub fn legendre_moments<const N: usize>(&self, wavelength_nm: f64) -> [f64; N] {
        match self.bracket(wavelength_nm) {
            (i, 0.0) => self.tables[i].legendre_moments(),
            (i, w) => {
                let (a, b): ([f64; N], [f64; N]) = (
                    self.tables[i].legendre_moments(),
                    self.tables[i + 1].legendre_moments(),
                );
                std::array::from_fn(|l| (1.0 - w) * a[l] + w * b[l])
            }
        }
    }

    /// Parses a phase function file (see [`VALID_FORM`]): blank lines and
    /// lines starting with `#` are skipped; the first other line is the
    /// header. `Err` is (line number, reason).
    pub fn parse(text: &str) -> Result<Self, (usize, String)> {
        let mut header = None;
        let mut blocks: Vec<Block> = Vec::new();
        let mut rows = 0;
        let last_line = text.lines().count();
        for (i, line) in text.lines().enumerate() {
            let line_no = i + 1;
            let line = line.trim();
            if line.is_empty() || line.starts_with('#') {
                continue;
            }
            let fields: Vec<&str> = line.split(',').map(str::trim).collect();
            let Some(columns) = header else {
                header = Some(match fields[..] {
                    ["angle_deg", "phase"] => 2,
                    ["angle_deg", "phase", "wavelength_nm"] => 3,
                    _ => {
                        return Err((
                            line_no,
                            format!(
                                "header '{line}' is neither `angle_deg,phase` nor \
                                 `angle_deg,phase,wavelength_nm`"
                            ),
                        ))
                    }
                });
                continue;
            };
            rows += 1;
            if rows > MAX_ROWS {
                return Err((line_no, format!("more than {MAX_ROWS} rows")));
            }
            let numbers: Option<Vec<f64>> = (fields.len() == columns)
                .then(|| fields.iter().map(|f| f.parse::<f64>().ok()).collect())
                .flatten();
            let Some(numbers) = numbers else {
                let form = if columns == 2 {
                    "two numbers `angle_deg,phase`"
                } else {
                    "three numbers `angle_deg,phase,wavelength_nm`"
                };
                return Err((line_no, format!("'{line}' is not {form}")));
            };
            let wavelength = if columns == 3 { numbers[2] } else { f64::NAN };
            if columns == 3 && !(wavelength.is_finite() && wavelength > 0.0) {
                return Err((
                    line_no,
                    format!("wavelength {wavelength} nm is not a positive number"),
                ));
            }
            let same = blocks.last().is_some_and(|b| {
                b.wavelength_nm == wavelength || (b.wavelength_nm.is_nan() && wavelength.is_nan())
            });
            if !same {
                if let Some(previous) = blocks.last() {
                    if wavelength <= previous.wavelength_nm {
                        return Err((
                            line_no,
                            format!(
                                "wavelength {wavelength} nm does not increase from the \
                                 previous block's {} nm",
                                previous.wavelength_nm
                            ),
                        ));
                    }
                }
                blocks.push(Block {
                    wavelength_nm: wavelength,
                    ..Block::default()
                });
            }
            let block = blocks.last_mut().expect("a block was pushed");
            block.angles_deg.push(numbers[0]);
            block.values.push(numbers[1]);
            block.lines.push(line_no);
        }
        if header.is_none() {
            return Err((0, "no header `angle_deg,phase[,wavelength_nm]`".into()));
        }
        if blocks.is_empty() {
            return Err((last_line, "no rows".into()));
        }
        let mut wavelengths_nm = Vec::with_capacity(blocks.len());
        let mut tables = Vec::with_capacity(blocks.len());
        for block in &blocks {
            let (wavelength, lines) = (&block.wavelength_nm, &block.lines);
            let table =
                PhaseTable::new(&block.angles_deg, &block.values).map_err(|(row, reason)| {
                    // A row of the block, or (0, a count past the rows) the
                    // block's last line.
                    let line = match row {
                        0 => *lines.last().expect("a block has a row"),
                        r => lines
                            .get(r - 1)
                            .copied()
                            .unwrap_or(*lines.last().expect("a block has a row")),
                    };
                    let at = if wavelength.is_nan() {
                        String::new()
                    } else {
                        format!(" (the block at {wavelength} nm)")
                    };
                    (line, format!("{reason}{at}"))
                })?;
            wavelengths_nm.push(*wavelength);
            tables.push(table);
        }
        let n = wavelengths_nm.len();
        if header == Some(3) {
            let (from, to) = RENDERED_RANGE_NM;
            if wavelengths_nm[0] > from || wavelengths_nm[n - 1] < to {
                return Err((
                    0,
                    format!(
                        "the blocks cover {}–{} nm, not the rendered {from}–{to} nm",
                        wavelengths_nm[0],
                        wavelengths_nm[n - 1]
                    ),
                ));
            }
        }
        Ok(Self {
            wavelengths_nm,
            tables,
        })
    }

    /// Reads and parses a phase function file; the error names the file,
    /// the line and the valid form.
    pub fn load(path: &Path) -> Result<Self, String> {
        super::data_file::load(path, VALID_FORM, Self::parse)
    }

    /// [`Self::load`], once per path for the life of the process
    /// ([`super::data_file::cached`]).
    pub fn cached(path: &Path) -> Result<Arc<Self>, String> {
        static CACHE: super::data_file::Cache<PathBuf, SpectralPhaseTable> = OnceLock::new();
        super::data_file::cached(&CACHE, path.to_owned(), || Self::load(path))
    }
}

/// The rows of one wavelength as a file is read.
#[derive(Default)]
struct Block {
    /// The block's wavelength, nm (NaN in a file without wavelengths).
    wavelength_nm: f64,
    angles_deg: Vec<f64>,
    values: Vec<f64>,
    /// The file's line of each row.
    lines: Vec<usize>,
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;
    use std::fmt::Write as _;

    use super::*;
    use crate::physics::aerosol::henyey_greenstein;

    /// Henyey–Greenstein tables of g = 0.3 at 400 nm and 0.8 at 700 nm,
    /// 1° apart, and the file's text.
    fn two_nodes() -> (SpectralPhaseTable, String) {
        let mut text = String::from("angle_deg,phase,wavelength_nm\n");
        for (g, wavelength) in [(0.3, 360.0), (0.8, 830.0)] {
            for a in 0..=180 {
                let mu = f64::from(a).to_radians().cos();
                writeln!(text, "{a},{},{wavelength}", henyey_greenstein(mu, g)).unwrap();
            }
        }
        (SpectralPhaseTable::parse(&text).unwrap(), text)
    }

    #[test]
    fn between_nodes_the_phase_function_is_the_blend() {
        let (table, _) = two_nodes();
        assert!(table.is_spectral());
        assert_eq!(table.node_wavelengths_nm(), &[360.0, 830.0]);
        let w = (500.0 - 360.0) / (830.0 - 360.0);
        for mu in [-1.0, -0.2, 0.4, 0.95, 1.0] {
            let blend = (1.0 - w) * table.node(0).eval(mu) + w * table.node(1).eval(mu);
            assert!((table.eval(mu, 500.0) - blend).abs() < 1e-12);
        }
        // Beyond the ends, the end nodes.
        assert_eq!(table.eval(0.5, 300.0), table.node(0).eval(0.5));
        assert_eq!(table.eval(0.5, 900.0), table.node(1).eval(0.5));
        // Normalised, and the moments are the blend's.
        let k: [f64; 6] = table.legendre_moments(500.0);
        let q: [f64; 6] = crate::physics::quadrature::legendre_moments_by_midpoints(
            |mu| table.eval(mu, 500.0),
            400_000,
        );
        assert!((k[0] - 1.0).abs() < 1e-12, "{}", k[0]);
        for l in 0..6 {
            assert!((k[l] - q[l]).abs() < 1e-6, "l {l}: {} vs {}", k[l], q[l]);
        }
        assert!(
            (k[1] - ((1.0 - w) * 0.3 + w * 0.8)).abs() < 2e-3,
            "{}",
            k[1]
        );
    }

    /// Sampled cosines at a wavelength between the nodes against the
    /// blend integrated over bins in μ: Pearson's χ² over 40 bins (39
    /// degrees of freedom: mean 39, standard deviation 8.8; the bound 80 is
    /// exceeded with probability < 10⁻⁴).
    #[test]
    fn sampling_follows_the_blend() {
        let (table, _) = two_nodes();
        for wavelength in [360.0, 550.0, 700.0] {
            let bins = 40;
            let n = 400_000_u32;
            let mut counts = vec![0.0; bins];
            let mut rng = crate::rng::Rng::new(21, 22);
            for _ in 0..n {
                let mu = table.sample(wavelength, || rng.uniform());
                let b = ((0.5 * (mu + 1.0) * bins as f64) as usize).min(bins - 1);
                counts[b] += 1.0;
            }
            let mut chi2 = 0.0;
            for (b, &count) in counts.iter().enumerate() {
                let lo = -1.0 + 2.0 * b as f64 / bins as f64;
                let hi = lo + 2.0 / bins as f64;
                let m = 2000;
                let p: f64 = (0..m)
                    .map(|i| {
                        let mu = lo + (hi - lo) * (f64::from(i) + 0.5) / f64::from(m);
                        2.0 * PI * table.eval(mu, wavelength) * (hi - lo) / f64::from(m)
                    })
                    .sum();
                let expected = p * f64::from(n);
                chi2 += (count - expected).powi(2) / expected;
            }
            assert!(chi2 < 80.0, "{wavelength} nm: χ² {chi2}");
        }
    }

    #[test]
    fn a_table_without_wavelengths_is_grey() {
        let table = SpectralPhaseTable::parse("angle_deg,phase\n0,2\n90,1\n180,2\n").unwrap();
        assert!(!table.is_spectral());
        assert!(table.node_wavelengths_nm().is_empty());
        assert_eq!(table.eval(0.3, 400.0), table.eval(0.3, 800.0));
    }

    #[test]
    fn bad_tables_say_which_line_and_why() {
        let (_, good) = two_nodes();
        let block = "0,1,500\n180,1,500\n";
        for (text, line, needle) in [
            (
                "angle_deg,phase,wavelength_nm\n0,1,500\n",
                2,
                "at least two rows",
            ),
            ("angle,phase,nm\n0,1,500\n180,1,500\n", 1, "header"),
            (
                "angle_deg,phase,wavelength_nm\n0,1,830\n180,1,830\n0,1,360\n180,1,360\n",
                4,
                "does not increase",
            ),
            (
                "angle_deg,phase,wavelength_nm\n0,1,-5\n180,1,-5\n",
                2,
                "positive",
            ),
            ("angle_deg,phase,wavelength_nm\n0,1,NaN\n", 2, "positive"),
            (
                "angle_deg,phase,wavelength_nm\n0,1\n180,1,500\n",
                2,
                "three numbers",
            ),
            (
                "angle_deg,phase,wavelength_nm\n0,1,500\n170,1,500\n",
                3,
                "end at 180° (the block at 500 nm)",
            ),
            (
                "angle_deg,phase,wavelength_nm\n0,1,500\n90,-1,500\n180,1,500\n",
                3,
                "≥ 0",
            ),
            ("angle_deg,phase,wavelength_nm\n", 1, "no rows"),
            ("# only a comment\n", 0, "no header"),
        ] {
            let (got_line, reason) = SpectralPhaseTable::parse(text).unwrap_err();
            assert_eq!(got_line, line, "{text:?}: {reason}");
            assert!(reason.contains(needle), "{text:?}: {reason}");
        }
        // Blocks that do not cover the rendered range.
        let narrow = format!("angle_deg,phase,wavelength_nm\n{block}");
        let (line, reason) = SpectralPhaseTable::parse(&narrow).unwrap_err();
        assert_eq!(line, 0);
        assert!(reason.contains("360–830"), "{reason}");
        assert!(SpectralPhaseTable::parse(&good).is_ok());
    }
}
