//! Aerosols: Elterman's (1968) vertical extinction profile, its wavelength
//! dependence, and the phase functions: Henyey–Greenstein, Cornette–Shanks,
//! double Henyey–Greenstein, or a table ([`PhaseFunction`]).
//!
//! Elterman, L. (1968), *UV, Visible, and IR Attenuation for Altitudes to
//! 50 km*, AFCRL-68-0153. Its aerosol-only column is available to us at
//! 340 nm only; the report's *total* attenuation is tabulated at 22
//! wavelengths. We recover the aerosol part at each of them by subtracting our
//! own Rayleigh (Bucholtz 1995) and ozone (Serdyuchenko–Gorshelev 2014, AFGL
//! profile) coefficients from the totals, summed over 0–5 km where aerosols
//! dominate and ozone is a small correction, and normalise by the same
//! quantity at 340 nm (which then reproduces the 340 nm table's own shape).
//! Between Elterman's wavelengths the ratio is interpolated log–log
//! (piecewise Ångström law), and extrapolated with the end exponents.

use std::f64::consts::PI;
use std::sync::{Arc, OnceLock};

use crate::data::{self, Table};
use crate::physics::spectral_phase::SpectralPhaseTable;
use crate::physics::{ozone, rayleigh, standard_atmosphere};

/// Elterman's sea-level-to-50 km aerosol extinction at 340 nm, per level.
pub struct Profile {
    altitudes_m: Vec<f64>,
    extinction_per_m: Vec<f64>,
}

impl Profile {
    fn load() -> Self {
        let table = Table::parse(data::ELTERMAN_AEROSOL);
        Self {
            altitudes_m: table.column_at(0).iter().map(|km| km * 1000.0).collect(),
            extinction_per_m: table.column_at(1).iter().map(|k| k * 1e-3).collect(),
        }
    }

    /// The table, read once.
    pub fn get() -> &'static Self {
        static PROFILE: OnceLock<Profile> = OnceLock::new();
        PROFILE.get_or_init(Self::load)
    }

    /// Extinction at 340 nm, m⁻¹: linear between Elterman's 1 km levels, zero
    /// above 50 km (where it has fallen to 9 × 10⁻¹⁰ m⁻¹).
    pub fn extinction_340nm_per_m(&self, altitude_m: f64) -> f64 {
        if altitude_m > *self.altitudes_m.last().unwrap() {
            return 0.0;
        }
        data::interpolate(&self.altitudes_m, &self.extinction_per_m, altitude_m)
    }

    /// Vertical optical depth at 340 nm from `altitude_m` to the top (trapezoid
    /// rule: exact for the piecewise-linear profile).
    pub fn optical_depth_340nm(&self, altitude_m: f64) -> f64 {
        let mut tau = 0.0;
        for i in 0..self.altitudes_m.len() - 1 {
            let (z0, z1) = (self.altitudes_m[i], self.altitudes_m[i + 1]);
            let lo = z0.max(altitude_m);
            if z1 <= lo {
                continue;
            }
            let k_lo = self.extinction_340nm_per_m(lo);
            let k_hi = self.extinction_per_m[i + 1];
            tau += 0.5 * (k_lo + k_hi) * (z1 - lo);
        }
        tau
    }
}

/// Aerosol extinction relative to 340 nm at Elterman's wavelengths.
pub struct SpectralFactor {
    ln_wavelength: Vec<f64>,
    ln_factor: Vec<f64>,
}

impl SpectralFactor {
    fn derive() -> Self {
        let total = Table::parse(data::ELTERMAN_TOTAL);
        let altitudes_m: Vec<f64> = total.column_at(0).iter().map(|km| km * 1000.0).collect();
        let o3 = ozone::CrossSections::get();
        let o3_profile = ozone::Profile::get();
        // Aerosol attenuation summed over the 0–5 km levels at one column.
        let aerosol_sum = |column: usize, wavelength_nm: f64| -> f64 {
            let rayleigh_xs = rayleigh::cross_section_m2(wavelength_nm);
            (0..altitudes_m.len())
                .filter(|&i| altitudes_m[i] <= 5_000.0)
                .map(|i| {
                    let z = altitudes_m[i];
                    let air = standard_atmosphere::air_state(z);
                    let rayleigh_per_m = rayleigh_xs * air.number_density_m3;
                    let ozone_per_m = o3.cross_section_m2(wavelength_nm, air.temperature_k)
                        * o3_profile.number_density_m3(z);
                    total.rows[i][column] * 1e-3 - rayleigh_per_m - ozone_per_m
                })
                .sum()
        };
        let mut ln_wavelength = Vec::new();
        let mut ln_factor = Vec::new();
        let reference = aerosol_sum(5, 340.0);
        for (column, name) in total.columns.iter().enumerate().skip(1) {
            let wavelength_nm: f64 = name
                .trim_start_matches("total_attenuation_")
                .trim_end_matches("nm_per_km")
                .parse()
                .expect("column name carries the wavelength");
            // Below 300 nm ozone dominates the totals and the difference is
            // meaningless; we start at 300 nm.
            if wavelength_nm < 300.0 {
                continue;
            }
            ln_wavelength.push(wavelength_nm.ln());
            ln_factor.push((aerosol_sum(column, wavelength_nm) / reference).ln());
        }
        Self {
            ln_wavelength,
            ln_factor,
        }
    }

    /// The table, read once.
    pub fn get() -> &'static Self {
        static FACTOR: OnceLock<SpectralFactor> = OnceLock::new();
        FACTOR.get_or_init(Self::derive)
    }

    /// aerosol(λ) / aerosol(340 nm).
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        let x = wavelength_nm.ln();
        let (xs, ys) = (&self.ln_wavelength, &self.ln_factor);
        let n = xs.len();
        let y = if x < xs[0] {
            ys[0] + (x - xs[0]) * (ys[1] - ys[0]) / (xs[1] - xs[0])
        } else if x > xs[n - 1] {
            ys[n - 1] + (x - xs[n - 1]) * (ys[n - 1] - ys[n - 2]) / (xs[n - 1] - xs[n - 2])
        } else {
            data::interpolate(xs, ys, x)
        };
        y.exp()
    }

    /// The Ångström exponent between two wavelengths: −d ln β / d ln λ.
    pub fn angstrom_exponent(&self, from_nm: f64, to_nm: f64) -> f64 {
        -(self.at(to_nm) / self.at(from_nm)).ln() / (to_nm / from_nm).ln()
    }
}

/// Aerosol phase function model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum PhaseModel {
    /// Henyey & Greenstein (1941).
    HenyeyGreenstein,
    /// Cornette & Shanks (1992), a Mie-like modification of Henyey–Greenstein.
    CornetteShanks,
}

/// Henyey–Greenstein phase function per steradian; `mu` is the cosine between
/// the incident and scattered propagation directions.
pub fn henyey_greenstein(mu: f64, g: f64) -> f64 {
    let denom = 1.0 + g * g - 2.0 * g * mu;
    (1.0 - g * g) / (4.0 * PI * denom * denom.sqrt())
}

/// Cornette–Shanks (1992) phase function per steradian.
pub fn cornette_shanks(mu: f64, g: f64) -> f64 {
    1.5 * (1.0 + mu * mu) / (2.0 + g * g) * henyey_greenstein(mu, g)
}

/// Invert the Henyey–Greenstein CDF analytically.
pub fn sample_henyey_greenstein(u: f64, g: f64) -> f64 {
    if g.abs() < 1e-4 {
        return 1.0 - 2.0 * u;
    }
    let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
    ((1.0 + g * g - s * s) / (2.0 * g)).clamp(-1.0, 1.0)
}

impl PhaseModel {
    /// Legendre moments k_l = 2π ∫ p(μ) P_l(μ) dμ, l = 0..N (k₀ = 1): by
    /// the Funk–Hecke theorem, ∫ p(ω·ω') Y_lm(ω') dω' = k_l Y_lm(ω) for any
    /// spherical harmonic of degree l. Henyey–Greenstein's are g^l (its
    /// generating function); Cornette–Shanks = 3(1+μ²)/(2(2+g²)) × HG, and
    /// μ²'s moments against HG follow from the recurrence
    /// (2l+1) μ P_l = (l+1) P_{l+1} + l P_{l−1}.
    pub fn legendre_moments<const N: usize>(self, g: f64) -> [f64; N] {
        let hg = |l: i64| if l < 0 { 0.0 } else { g.powi(l as i32) };
        std::array::from_fn(|l| match self {
            Self::HenyeyGreenstein => hg(l as i64),
            Self::CornetteShanks => {
                let l = l as i64;
                let lf = l as f64;
                // 2π ∫ μ² HG P_l dμ.
                let mu2 = ((lf + 1.0) * (lf + 2.0) / (2.0 * lf + 3.0) * hg(l + 2)
                    + ((lf + 1.0).powi(2) / (2.0 * lf + 3.0)
                        + if l > 0 {
                            lf * lf / (2.0 * lf - 1.0)
                        } else {
                            0.0
                        })
                        * hg(l)
                    + if l > 1 {
                        lf * (lf - 1.0) / (2.0 * lf - 1.0) * hg(l - 2)
                    } else {
                        0.0
                    })
                    / (2.0 * lf + 1.0);
                1.5 / (2.0 + g * g) * (hg(l) + mu2)
            }
        })
    }

    /// The phase function per steradian at cosine `mu` for parameter `g`.
    pub fn eval(self, mu: f64, g: f64) -> f64 {
        match self {
            Self::HenyeyGreenstein => henyey_greenstein(mu, g),
            Self::CornetteShanks => cornette_shanks(mu, g),
        }
    }

    /// Sample a cosine. Cornette–Shanks is sampled exactly by rejection from
    /// Henyey–Greenstein: CS/HG = 3(1+μ²)/(2(2+g²)) ≤ 3/(2+g²), so accept with
    /// probability (1+μ²)/2 (expected ≤ 2 proposals).
    pub fn sample(self, g: f64, mut uniform: impl FnMut() -> f64) -> f64 {
        match self {
            Self::HenyeyGreenstein => sample_henyey_greenstein(uniform(), g),
            Self::CornetteShanks => loop {
                let mu = sample_henyey_greenstein(uniform(), g);
                if uniform() * 2.0 < 1.0 + mu * mu {
                    return mu;
                }
            },
        }
    }
}

/// The double Henyey–Greenstein phase function per steradian: `weight` ×
/// HG(`g1`) + (1 − `weight`) × HG(`g2`), usually a forward lobe (g1 > 0)
/// and a backward one (g2 < 0). Kattawar, G. W. (1975), *A three-parameter
/// analytic phase function for multiple scattering calculations*, JQSRT 15,
/// 839–849 (his α, g₁, g₂).
pub fn double_henyey_greenstein(mu: f64, g1: f64, g2: f64, weight: f64) -> f64 {
    weight * henyey_greenstein(mu, g1) + (1.0 - weight) * henyey_greenstein(mu, g2)
}

/// The aerosol's phase function with its parameters, as the renderer
/// evaluates, samples and expands it. Every variant's sampling density is
/// exactly its [`Self::eval`], and its [`Self::legendre_moments`] are exact,
/// so the estimators that divide by the one or integrate with the other
/// stay unbiased.
#[derive(Clone, Debug, PartialEq)]
pub enum PhaseFunction {
    /// Henyey & Greenstein (1941).
    HenyeyGreenstein {
        /// Asymmetry parameter (its mean cosine), −1 to 1.
        g: f64,
    },
    /// Cornette & Shanks (1992).
    CornetteShanks {
        /// The parameter g of its Henyey–Greenstein factor.
        g: f64,
    },
    /// [`double_henyey_greenstein`].
    DoubleHenyeyGreenstein {
        /// Asymmetry parameter of the first lobe.
        g1: f64,
        /// Asymmetry parameter of the second lobe.
        g2: f64,
        /// Weight of the first lobe, 0–1.
        weight: f64,
    },
    /// Tabulated against the scattering angle, at one wavelength or at
    /// several ([`SpectralPhaseTable`]).
    Table(Arc<SpectralPhaseTable>),
}

/// The wavelength at which [`PhaseFunction::mean_cosine`] reports a phase
/// function that varies with wavelength, nm (that of aerosol optical
/// depths, `optical_depth_550`).
pub const MEAN_COSINE_REFERENCE_NM: f64 = 550.0;

impl PhaseFunction {
    /// Phase function per steradian at `wavelength_nm`; `mu` is the cosine
    /// between the incident and scattered propagation directions. Only a
    /// table with wavelengths ([`Self::is_spectral`]) reads the wavelength.
    pub fn eval(&self, mu: f64, wavelength_nm: f64) -> f64 {
        match self {
            Self::HenyeyGreenstein { g } => henyey_greenstein(mu, *g),
            Self::CornetteShanks { g } => cornette_shanks(mu, *g),
            Self::DoubleHenyeyGreenstein { g1, g2, weight } => {
                double_henyey_greenstein(mu, *g1, *g2, *weight)
            }
            Self::Table(table) => table.eval(mu, wavelength_nm),
        }
    }

    /// A cosine drawn with density [`Self::eval`] at `wavelength_nm` (× 2π
    /// per unit μ): the double Henyey–Greenstein by choosing its lobe with
    /// probability `weight` (one uniform number), then sampling that lobe;
    /// a table with wavelengths by choosing one of the two nodes it blends
    /// ([`SpectralPhaseTable::sample`]).
    pub fn sample(&self, wavelength_nm: f64, mut uniform: impl FnMut() -> f64) -> f64 {
        match self {
            Self::HenyeyGreenstein { g } => PhaseModel::HenyeyGreenstein.sample(*g, uniform),
            Self::CornetteShanks { g } => PhaseModel::CornetteShanks.sample(*g, uniform),
            Self::DoubleHenyeyGreenstein { g1, g2, weight } => {
                let g = if uniform() < *weight { *g1 } else { *g2 };
                sample_henyey_greenstein(uniform(), g)
            }
            Self::Table(table) => table.sample(wavelength_nm, uniform),
        }
    }

    /// Legendre moments k_l = 2π ∫ p(μ) P_l(μ) dμ, l = 0..N, at
    /// `wavelength_nm` (see [`PhaseModel::legendre_moments`]); the double
    /// Henyey–Greenstein's are weight·g1^l + (1 − weight)·g2^l.
    pub fn legendre_moments<const N: usize>(&self, wavelength_nm: f64) -> [f64; N] {
        match self {
            Self::HenyeyGreenstein { g } => PhaseModel::HenyeyGreenstein.legendre_moments(*g),
            Self::CornetteShanks { g } => PhaseModel::CornetteShanks.legendre_moments(*g),
            Self::DoubleHenyeyGreenstein { g1, g2, weight } => std::array::from_fn(|l| {
                weight * g1.powi(l as i32) + (1.0 - weight) * g2.powi(l as i32)
            }),
            Self::Table(table) => table.legendre_moments(wavelength_nm),
        }
    }

    /// Whether the phase function varies with wavelength.
    pub fn is_spectral(&self) -> bool {
        matches!(self, Self::Table(table) if table.is_spectral())
    }

    /// The wavelengths between which the phase function is linear, nm
    /// (empty where it does not vary with wavelength): what a cache of
    /// its moments over wavelength needs.
    pub fn node_wavelengths_nm(&self) -> &[f64] {
        match self {
            Self::Table(table) => table.node_wavelengths_nm(),
            _ => &[],
        }
    }

    /// The mean cosine of the scattering angle (the asymmetry parameter;
    /// for Cornette–Shanks not its `g`), at [`MEAN_COSINE_REFERENCE_NM`]
    /// where it varies with wavelength.
    pub fn mean_cosine(&self) -> f64 {
        self.legendre_moments::<2>(MEAN_COSINE_REFERENCE_NM)[1]
    }
}

/// A phase function's Legendre moments k_0..k_{N−1} over wavelength,
/// computed once: at its nodes, blended linearly in between (exactly the
/// moments of the blended phase function, [`SpectralPhaseTable`]); one
/// set where it does not vary with wavelength.
#[derive(Clone, Debug, PartialEq)]
pub struct MomentsOverWavelength<const N: usize> {
    /// The nodes' wavelengths, nm (empty: one set for every wavelength).
    wavelengths_nm: Vec<f64>,
    /// The moments at each node (one set where there are no nodes).
    moments: Vec<[f64; N]>,
}

impl<const N: usize> MomentsOverWavelength<N> {
    /// The moments of `phase`.
    pub fn new(phase: &PhaseFunction) -> Self {
        let wavelengths_nm = phase.node_wavelengths_nm().to_vec();
        let moments = if wavelengths_nm.is_empty() {
            vec![phase.legendre_moments(MEAN_COSINE_REFERENCE_NM)]
        } else {
            wavelengths_nm
                .iter()
                .map(|&w| phase.legendre_moments(w))
                .collect()
        };
        Self {
            wavelengths_nm,
            moments,
        }
    }

    /// The moments at `wavelength_nm`.
    pub fn at(&self, wavelength_nm: f64) -> [f64; N] {
        let w = &self.wavelengths_nm;
        let n = w.len();
        if n == 0 || wavelength_nm.is_nan() || wavelength_nm <= w[0] {
            return self.moments[0];
        }
        if wavelength_nm >= w[n - 1] {
            return self.moments[n - 1];
        }
        let i = w.partition_point(|&x| x <= wavelength_nm) - 1;
        let t = (wavelength_nm - w[i]) / (w[i + 1] - w[i]);
        let (a, b) = (&self.moments[i], &self.moments[i + 1]);
        std::array::from_fn(|l| (1.0 - t) * a[l] + t * b[l])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn legendre_moments_match_quadrature() {
        // k_l = 2π ∫ p(μ) P_l(μ) dμ by the midpoint rule on 200 000 points.
        for model in [PhaseModel::HenyeyGreenstein, PhaseModel::CornetteShanks] {
            for g in [0.0, 0.3, 0.7] {
                let k: [f64; 7] = model.legendre_moments(g);
                let q: [f64; 7] = crate::physics::quadrature::legendre_moments_by_midpoints(
                    |mu| model.eval(mu, g),
                    200_000,
                );
                for l in 0..7 {
                    assert!(
                        (k[l] - q[l]).abs() < 1e-6,
                        "{model:?} g {g} l {l}: {} vs {}",
                        k[l],
                        q[l]
                    );
                }
            }
        }
    }

    #[test]
    fn elterman_optical_depth_at_340_nm() {
        // data/README.md: vertical aerosol optical depth 0–50 km at 340 nm = 0.380.
        let tau = Profile::get().optical_depth_340nm(0.0);
        assert!((tau - 0.380).abs() < 0.002, "{tau}");
    }

    #[test]
    fn derived_spectral_factor_matches_the_documented_estimates() {
        // data/README.md estimates 0.84 (400 nm), 0.66 (550), 0.56 (700), 0.47 (1060).
        let f = SpectralFactor::get();
        assert!((f.at(340.0) - 1.0).abs() < 1e-9);
        for (nm, expected) in [(400.0, 0.84), (550.0, 0.66), (700.0, 0.56), (1060.0, 0.47)] {
            let got = f.at(nm);
            assert!((got / expected - 1.0).abs() < 0.06, "{nm} nm: {got}");
        }
        // Elterman's 25 km visual range: 3.912/25 km = 0.156 km⁻¹ at 550 nm.
        let sea_level_550 = Profile::get().extinction_340nm_per_m(0.0) * f.at(550.0) * 1e3;
        assert!((sea_level_550 - 0.156).abs() < 0.01, "{sea_level_550}");
        // The estimates' Ångström exponent, −ln(0.56/0.84)/ln(700/400) = 0.72
        // (ours: 0.71).
        let alpha = f.angstrom_exponent(400.0, 700.0);
        assert!((alpha - 0.72).abs() < 0.1, "{alpha}");
    }

    #[test]
    fn phase_functions_are_normalised() {
        for model in [PhaseModel::HenyeyGreenstein, PhaseModel::CornetteShanks] {
            for g in [0.0, 0.5, 0.7, 0.85] {
                let n = 200_000;
                let integral: f64 = (0..n)
                    .map(|i| {
                        let mu = -1.0 + 2.0 * (f64::from(i) + 0.5) / f64::from(n);
                        2.0 * PI * model.eval(mu, g) * 2.0 / f64::from(n)
                    })
                    .sum();
                assert!((integral - 1.0).abs() < 1e-3, "{model:?} g={g}: {integral}");
            }
        }
    }

    #[test]
    fn double_henyey_greenstein_is_normalised_and_its_moments_exact() {
        // ∫ p dΩ = 2π ∫ p dμ by the midpoint rule on 200 000 points, and
        // the moments w g1^l + (1 − w) g2^l against the same quadrature.
        for (g1, g2, weight) in [(0.8, -0.3, 0.9), (0.95, -0.6, 0.7), (0.5, 0.2, 0.0)] {
            let phase = PhaseFunction::DoubleHenyeyGreenstein { g1, g2, weight };
            let k: [f64; 5] = phase.legendre_moments(550.0);
            let n = 200_000;
            let mut q = [0.0; 5];
            for i in 0..n {
                let mu = -1.0 + 2.0 * (f64::from(i) + 0.5) / f64::from(n);
                let w = 2.0 * PI * phase.eval(mu, 550.0) * 2.0 / f64::from(n);
                let p2 = 0.5 * (3.0 * mu * mu - 1.0);
                let p3 = 0.5 * (5.0 * mu * mu * mu - 3.0 * mu);
                let p4 = (35.0 * mu.powi(4) - 30.0 * mu * mu + 3.0) / 8.0;
                for (l, p) in [1.0, mu, p2, p3, p4].into_iter().enumerate() {
                    q[l] += w * p;
                }
            }
            assert!((q[0] - 1.0).abs() < 1e-3, "{g1} {g2} {weight}: {}", q[0]);
            assert!((k[0] - 1.0).abs() < 1e-15);
            for l in 1..5 {
                assert!((k[l] - q[l]).abs() < 1e-3, "l {l}: {} vs {}", k[l], q[l]);
            }
        }
    }

    #[test]
    fn double_henyey_greenstein_sampling_matches_its_density() {
        // The sampled fractions with μ > 0.9 and μ < −0.5 against the
        // integrals of the density, each within 4 standard errors.
        let phase = PhaseFunction::DoubleHenyeyGreenstein {
            g1: 0.8,
            g2: -0.4,
            weight: 0.85,
        };
        let mut rng = crate::rng::Rng::new(7, 8);
        let n = 200_000;
        let samples: Vec<f64> = (0..n)
            .map(|_| phase.sample(550.0, || rng.uniform()))
            .collect();
        for (lo, hi) in [(0.9, 1.0), (-1.0, -0.5)] {
            let hits =
                samples.iter().filter(|&&mu| mu > lo && mu <= hi).count() as f64 / f64::from(n);
            let m = 20_000;
            let expected: f64 = (0..m)
                .map(|i| {
                    let mu = lo + (hi - lo) * (f64::from(i) + 0.5) / f64::from(m);
                    2.0 * PI * phase.eval(mu, 550.0) * (hi - lo) / f64::from(m)
                })
                .sum();
            let se = (expected * (1.0 - expected) / f64::from(n)).sqrt();
            assert!(
                (hits - expected).abs() < 4.0 * se,
                "{lo}..{hi}: {hits} vs {expected}"
            );
        }
        let mean = samples.iter().sum::<f64>() / f64::from(n);
        let g = phase.mean_cosine();
        assert!((g - (0.85 * 0.8 - 0.15 * 0.4)).abs() < 1e-12);
        assert!((mean - g).abs() < 0.01, "{mean} vs {g}");
    }

    #[test]
    fn sampled_mean_cosine_is_g() {
        // For HG, E[μ] = g and E[μ²] = (1 + 2g²)/3 exactly, so the mean of n
        // samples has the standard error √((1 + 2g²)/3 − g²)/√n (0.41/√n
        // at g = 0.7).
        let mut rng = crate::rng::Rng::new(3, 4);
        let n = 100_000;
        let g = 0.7;
        let mean: f64 = (0..n)
            .map(|_| PhaseModel::HenyeyGreenstein.sample(g, || rng.uniform()))
            .sum::<f64>()
            / f64::from(n);
        let se = ((1.0 + 2.0 * g * g) / 3.0 - g * g).sqrt() / f64::from(n).sqrt();
        assert!((mean - g).abs() < 4.0 * se, "{mean} vs {g} ± {se}");
    }

    #[test]
    fn cornette_shanks_sampling_matches_its_density() {
        // Compare the sampled fraction of μ > 0.9 with the integral of the pdf.
        let g = 0.7;
        let mut rng = crate::rng::Rng::new(5, 6);
        let n = 200_000;
        let hits = (0..n)
            .filter(|_| PhaseModel::CornetteShanks.sample(g, || rng.uniform()) > 0.9)
            .count() as f64
            / f64::from(n);
        let m = 10_000;
        let expected: f64 = (0..m)
            .map(|i| {
                let mu = 0.9 + 0.1 * (f64::from(i) + 0.5) / f64::from(m);
                2.0 * PI * cornette_shanks(mu, g) * 0.1 / f64::from(m)
            })
            .sum();
        let se = (expected * (1.0 - expected) / f64::from(n)).sqrt();
        assert!((hits - expected).abs() < 4.0 * se, "{hits} vs {expected}");
    }
}
