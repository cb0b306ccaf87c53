//! The Sun: a disc of the true mean angular radius with the measured
//! extraterrestrial spectrum (ASTM E-490-00a air-mass-zero table, or a
//! spectrum file), uniform or limb-darkened by Neckel & Labs' (1994)
//! wavelength-dependent law.
//!
//! The table's integral is 1 366.1 W m⁻², the "solar constant" of 2000. The
//! modern total solar irradiance from SORCE/TIM is 1 360.8 ± 0.5 W m⁻²
//! (Kopp & Lean 2011): E-490 is ≈ 0.4 % high in total, which is within the
//! uncertainty of its spectral shape; we use the table unscaled.

use std::f64::consts::PI;
use std::sync::OnceLock;

use crate::data::{self, Table};
use crate::physics::spectrum_file::Tabulated;

/// Mean angular radius of the solar disc at 1 AU: 959.63″ (IAU 2015
/// nominal solar radius 695 700 km seen from 149 597 870.7 km).
pub const ANGULAR_RADIUS_DEG: f64 = 0.266_56;

/// Solid angle of the solar disc, sr: Ω = 2π(1 − cos α).
pub fn solid_angle_sr() -> f64 {
    2.0 * PI * (1.0 - ANGULAR_RADIUS_DEG.to_radians().cos())
}

/// A solar spectral irradiance table at 1 AU (the built-in AM0 one, or a
/// file's).
#[derive(Clone, Debug, PartialEq)]
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

    /// The table, read once.
    pub fn get() -> &'static Self {
        static SPECTRUM: OnceLock<Spectrum> = OnceLock::new();
        SPECTRUM.get_or_init(Self::load)
    }

    /// A spectrum from a file's table ([`Tabulated`], W m⁻² nm⁻¹ at 1 AU).
    pub fn from_tabulated(table: &Tabulated) -> Self {
        Self {
            wavelengths_nm: table.wavelengths_nm.clone(),
            irradiance: table.values.clone(),
        }
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

/// Neckel & Labs (1994), "The solar radiation between 3300 and 12500 Å",
/// *Solar Physics* 153, 91–114: the fifth-order polynomial fits of the
/// centre-to-limb variation of the continuum intensity,
/// I(μ)/I(1) = Σₖ aₖ(λ) μᵏ (μ the cosine of the heliocentric angle), at
/// their 30 wavelengths: (λ nm, [a₀ … a₅], the printed disc-mean-to-centre
/// ratio F/I(1) = 2 Σₖ aₖ/(k + 2)). Transcribed from the Institute for Solar
/// Physics' SST pipeline (github.com/ISP-SST/sstred,
/// `red_neckel_coefficients.pro`, table `table1`). The row at 365.875 nm
/// sums to 0.998, not 1, and its ratio computes to 0.7450 against the
/// printed 0.7445: the law is normalised by the sum here, so I(1) = 1.
pub const NECKEL_LABS_1994: [(f64, [f64; 6], f64); 30] = [
    (
        303.327,
        [0.08011, 0.70695, 0.49910, -0.31080, -0.02177, 0.04642],
        0.6826,
    ),
    (
        310.843,
        [0.08160, 0.71609, 0.69685, -0.87703, 0.47008, -0.08760],
        0.6883,
    ),
    (
        320.468,
        [0.08833, 0.77285, 0.65382, -1.04647, 0.72921, -0.19775],
        0.6985,
    ),
    (
        329.897,
        [0.09188, 0.92459, 0.19604, -0.39546, 0.23599, -0.05303],
        0.7116,
    ),
    (
        349.947,
        [0.11012, 1.02168, -0.10924, -0.00055, -0.08688, 0.06487],
        0.7260,
    ),
    (
        365.875,
        [0.12828, 1.04969, 0.17482, -1.13371, 1.23882, -0.45990],
        0.7445,
    ),
    (
        374.086,
        [0.12579, 0.85402, 0.54601, -1.15048, 0.88928, -0.26462],
        0.7288,
    ),
    (
        390.915,
        [0.12995, 0.91836, -0.07566, 0.19149, -0.28712, 0.12298],
        0.7204,
    ),
    (
        401.970,
        [0.12323, 1.08648, -0.43974, 0.45912, -0.32759, 0.09850],
        0.7303,
    ),
    (
        416.319,
        [0.12814, 1.19947, -0.84407, 1.07201, -0.79537, 0.23982],
        0.7380,
    ),
    (
        427.930,
        [0.14249, 1.28796, -1.19564, 1.68603, -1.36658, 0.44572],
        0.7495,
    ),
    (
        443.885,
        [0.16220, 1.24893, -0.92165, 0.89978, -0.50148, 0.11220],
        0.7588,
    ),
    (
        445.125,
        [0.15248, 1.38517, -1.49615, 1.99886, -1.48155, 0.44119],
        0.7596,
    ),
    (
        457.345,
        [0.16604, 1.38544, -1.52275, 2.00232, -1.45969, 0.42864],
        0.7651,
    ),
    (
        477.427,
        [0.19571, 1.30551, -1.25845, 1.50626, -1.05472, 0.30570],
        0.7751,
    ),
    (
        492.905,
        [0.20924, 1.30798, -1.20411, 1.21505, -0.67196, 0.14381],
        0.7823,
    ),
    (
        519.930,
        [0.23695, 1.29927, -1.28034, 1.37760, -0.85054, 0.21706],
        0.7925,
    ),
    (
        541.760,
        [0.26073, 1.27428, -1.30352, 1.47085, -0.96618, 0.26384],
        0.8002,
    ),
    (
        559.950,
        [0.26892, 1.34319, -1.58427, 1.91271, -1.31350, 0.37295],
        0.8061,
    ),
    (
        579.880,
        [0.28392, 1.36896, -1.75998, 2.22154, -1.56074, 0.44630],
        0.8125,
    ),
    (
        610.975,
        [0.30854, 1.36620, -1.83572, 2.33221, -1.63082, 0.45959],
        0.8221,
    ),
    (
        640.970,
        [0.33644, 1.30590, -1.79238, 2.45040, -1.89979, 0.59943],
        0.8290,
    ),
    (
        669.400,
        [0.34685, 1.37539, -2.04425, 2.70493, -1.94290, 0.55999],
        0.8360,
    ),
    (
        700.875,
        [0.37885, 1.25553, -1.70908, 2.19647, -1.59554, 0.47378],
        0.8434,
    ),
    (
        748.710,
        [0.40627, 1.22842, -1.67877, 2.05535, -1.39972, 0.38845],
        0.8524,
    ),
    (
        811.760,
        [0.42977, 1.25182, -1.85164, 2.31949, -1.59101, 0.44155],
        0.8621,
    ),
    (
        869.600,
        [0.45396, 1.25101, -2.02958, 2.75410, -2.02287, 0.59338],
        0.8701,
    ),
    (
        948.850,
        [0.47855, 1.19813, -1.86296, 2.36939, -1.64367, 0.46056],
        0.8773,
    ),
    (
        1046.60,
        [0.49870, 1.21429, -2.06976, 2.80703, -2.05247, 0.60221],
        0.8841,
    ),
    (
        1098.95,
        [0.51149, 1.19354, -2.00174, 2.66936, -1.94981, 0.57715],
        0.8890,
    ),
];

/// Number of coefficients of the limb-darkening polynomial.
pub const LIMB_COEFFICIENTS: usize = 6;

/// Neckel & Labs' coefficients at `wavelength_nm`, linear in wavelength
/// between their rows (constant beyond 303–1099 nm) and normalised to
/// I(1) = Σ aₖ = 1.
pub fn limb_darkening_coefficients(wavelength_nm: f64) -> [f64; LIMB_COEFFICIENTS] {
    let table = &NECKEL_LABS_1994;
    let k = table.partition_point(|row| row.0 <= wavelength_nm);
    let a: [f64; LIMB_COEFFICIENTS] = match k {
        0 => table[0].1,
        k if k == table.len() => table[k - 1].1,
        k => {
            let (x0, a0, _) = table[k - 1];
            let (x1, a1, _) = table[k];
            let f = (wavelength_nm - x0) / (x1 - x0);
            std::array::from_fn(|i| a0[i] + f * (a1[i] - a0[i]))
        }
    };
    let sum: f64 = a.iter().sum();
    a.map(|c| c / sum)
}

/// The limb darkening I(μ)/I(1) at `wavelength_nm` (Neckel & Labs 1994).
pub fn limb_darkening(wavelength_nm: f64, mu: f64) -> f64 {
    polynomial(&limb_darkening_coefficients(wavelength_nm), mu)
}

/// Σₖ cₖ μᵏ.
pub fn polynomial(c: &[f64; LIMB_COEFFICIENTS], mu: f64) -> f64 {
    c.iter().rev().fold(0.0, |sum, &ck| sum * mu + ck)
}

/// The disc's mean intensity over its centre's, 2 ∫₀¹ I(μ) μ dμ / I(1) =
/// 2 Σₖ aₖ/(k + 2) (exact for the polynomial; the disc's area element is
/// 2r dr = 2μ dμ with r = sin ψ = √(1 − μ²)).
pub fn mean_over_centre(c: &[f64; LIMB_COEFFICIENTS]) -> f64 {
    2.0 * c
        .iter()
        .enumerate()
        .map(|(k, ck)| ck / (k as f64 + 2.0))
        .sum::<f64>()
}

/// The coefficients of the radiance relative to the disc's mean radiance
/// at `wavelength_nm`: L(μ)/L̄ = Σₖ bₖ μᵏ, bₖ = aₖ / (2 Σⱼ aⱼ/(j + 2)), so
/// the disc's mean of L/L̄ is 1 and the irradiance E = L̄ Ω is kept; with
/// `darkened` false, the uniform disc (b = [1, 0, …]).
pub fn radiance_over_mean(wavelength_nm: f64, darkened: bool) -> [f64; LIMB_COEFFICIENTS] {
    if !darkened {
        let mut b = [0.0; LIMB_COEFFICIENTS];
        b[0] = 1.0;
        return b;
    }
    let a = limb_darkening_coefficients(wavelength_nm);
    let mean = mean_over_centre(&a);
    a.map(|c| c / mean)
}

/// μ, the cosine of the heliocentric angle, at a direction whose angle θ
/// from the disc's centre has cosine `cos_from_centre`: the disc's
/// fractional radius r² = (1 − cos θ)/(1 − cos α) (α its angular radius;
/// r = θ/α to 10⁻⁵ at α = 0.27°, and r² is uniform under uniform sampling
/// of the disc's cone, so the cone's mean of L(μ(r)) is the disc's mean
/// exactly), μ = √(1 − r²); 0 outside the disc.
pub fn disc_mu(cos_from_centre: f64, cos_radius: f64) -> f64 {
    let r2 = (1.0 - cos_from_centre) / (1.0 - cos_radius);
    (1.0 - r2).max(0.0).sqrt()
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

    #[test]
    fn neckel_labs_rows_give_their_printed_mean_to_centre_ratio() {
        // The printed F/I(1) checks the transcription of every row (the
        // 365.875 nm row to 6e-4, see `NECKEL_LABS_1994`).
        for (nm, a, printed) in NECKEL_LABS_1994 {
            let sum: f64 = a.iter().sum();
            let ratio = mean_over_centre(&a) / sum;
            let tolerance = if nm == 365.875 { 6e-4 } else { 1.5e-4 };
            assert!(
                (ratio - printed).abs() < tolerance,
                "{nm}: {ratio} vs {printed}"
            );
        }
    }

    #[test]
    fn the_darkened_disc_keeps_the_irradiance() {
        // ∫ L dΩ = 2π ∫₀^α L(μ(θ)) sin θ dθ by Simpson's rule in the angle
        // from the centre (the limb's √ makes it converge as h^1.5: 10⁵
        // panels leave < 1e-6): ∫ L dΩ / (L̄ Ω) = 1 at every wavelength.
        let alpha = ANGULAR_RADIUS_DEG.to_radians();
        let cos_radius = alpha.cos();
        for nm in [360.0, 450.0, 550.0, 700.0, 830.0] {
            let b = radiance_over_mean(nm, true);
            let integral: f64 = crate::physics::quadrature::simpson(0.0, alpha, 100_000)
                .map(|(theta, w)| {
                    w * theta.sin() * polynomial(&b, disc_mu(theta.cos(), cos_radius))
                })
                .sum::<f64>()
                * 2.0
                * PI;
            let relative = integral / solid_angle_sr();
            assert!((relative - 1.0).abs() < 1e-6, "{nm} nm: {relative}");
        }
    }

    #[test]
    fn the_limb_is_darker_in_the_blue() {
        // Neckel & Labs' law at μ = 0.2 (r = 0.98): 0.382 of the centre at
        // 443.885 nm, 0.559 at 669.4 nm (their rows, Σ aₖ 0.2ᵏ / Σ aₖ).
        let at = |nm: f64| {
            let row = NECKEL_LABS_1994.iter().find(|r| r.0 == nm).unwrap();
            polynomial(&row.1, 0.2) / row.1.iter().sum::<f64>()
        };
        let (blue, red) = (limb_darkening(443.885, 0.2), limb_darkening(669.4, 0.2));
        assert!((blue - at(443.885)).abs() < 1e-12 && (red - at(669.4)).abs() < 1e-12);
        assert!((blue - 0.3816).abs() < 1e-4, "{blue}");
        assert!((red - 0.5589).abs() < 1e-4, "{red}");
        assert_eq!(limb_darkening(550.0, 1.0), 1.0);
    }
}
