//! Rayleigh scattering by air molecules after Bucholtz (1995), "Rayleigh-
//! scattering calculations for the terrestrial atmosphere", *Appl. Opt.* 34,
//! 2765–2773.
//!
//! Cross-section per molecule (Bucholtz eq. 2):
//! σ(λ) = 24π³ (n_s² − 1)² / (λ⁴ N_s² (n_s² + 2)²) · F_K(λ),
//! with n_s the refractive index of standard air (15 °C, 101 325 Pa,
//! 300 ppm CO₂) from Peck & Reeder (1972) (Bucholtz eqs. 4–5), N_s its
//! number density, and F_K = (6 + 3ρ)/(6 − 7ρ) the King correction factor.
//! Bucholtz takes the depolarisation ratio ρ(λ) from Bates (1984); we compute
//! it from Bates' King factors of N₂ and O₂ (as tabulated by Bodhaine et al.
//! 1999, eqs. 5–6, 22–23) for air with 300 ppm CO₂, and ρ = 6(F−1)/(3+7F).
//!
//! The phase function with depolarisation (Chandrasekhar 1950; Bucholtz eq. 12):
//! P(Θ) = 3/(4(1+2γ)) · [(1+3γ) + (1−γ) cos²Θ],  γ = ρ/(2−ρ),
//! normalised so that ∫ P dΩ = 4π.

use std::f64::consts::PI;

/// Number density of standard air (288.15 K, 101 325 Pa), m⁻³ (Bucholtz:
/// 2.547 43 × 10¹⁹ cm⁻³).
pub const STANDARD_AIR_NUMBER_DENSITY_M3: f64 = 2.547_43e25;

/// CO₂ volume mixing ratio of Peck & Reeder's standard air, in percent.
const CO2_PERCENT: f64 = 0.03;

/// Refractive index of standard air minus one (Peck & Reeder 1972, as quoted by
/// Bucholtz 1995 eqs. 4 and 5; wavenumber in µm⁻¹).
pub fn refractive_index_minus_one(wavelength_nm: f64) -> f64 {
    let inv_um2 = (1000.0 / wavelength_nm).powi(2);
    let scaled = if wavelength_nm > 230.0 {
        5_791_817.0 / (238.018_5 - inv_um2) + 167_909.0 / (57.362 - inv_um2)
    } else {
        8_060.51 + 2_480_990.0 / (132.274 - inv_um2) + 17_455.7 / (39.329_57 - inv_um2)
    };
    scaled * 1e-8
}

/// King correction factor F_K of air (Bates 1984 via Bodhaine et al. 1999).
pub fn king_factor(wavelength_nm: f64) -> f64 {
    let inv_um2 = (1000.0 / wavelength_nm).powi(2);
    let f_n2 = 1.034 + 3.17e-4 * inv_um2;
    let f_o2 = 1.096 + 1.385e-3 * inv_um2 + 1.448e-4 * inv_um2 * inv_um2;
    let (f_ar, f_co2) = (1.0, 1.15);
    // Volume percentages of dry air (Bodhaine et al. 1999, eq. 23).
    let (n2, o2, ar) = (78.084, 20.946, 0.934);
    (n2 * f_n2 + o2 * f_o2 + ar * f_ar + CO2_PERCENT * f_co2) / (n2 + o2 + ar + CO2_PERCENT)
}

/// Depolarisation ratio ρ from the King factor: F = (6+3ρ)/(6−7ρ).
pub fn depolarisation_ratio(wavelength_nm: f64) -> f64 {
    let f = king_factor(wavelength_nm);
    6.0 * (f - 1.0) / (3.0 + 7.0 * f)
}

/// Rayleigh cross-section per molecule, m² (Bucholtz eq. 2).
pub fn cross_section_m2(wavelength_nm: f64) -> f64 {
    let n = 1.0 + refractive_index_minus_one(wavelength_nm);
    let n2 = n * n;
    let wavelength_m = wavelength_nm * 1e-9;
    let ns = STANDARD_AIR_NUMBER_DENSITY_M3;
    24.0 * PI.powi(3) * (n2 - 1.0).powi(2) / (wavelength_m.powi(4) * ns * ns * (n2 + 2.0).powi(2))
        * king_factor(wavelength_nm)
}

/// The anisotropy γ = ρ/(2−ρ) of the depolarised phase function.
pub fn phase_gamma(wavelength_nm: f64) -> f64 {
    let rho = depolarisation_ratio(wavelength_nm);
    rho / (2.0 - rho)
}

/// Phase function per steradian (integrates to 1 over the sphere) at
/// scattering-angle cosine `mu`, for anisotropy `gamma`.
pub fn phase(mu: f64, gamma: f64) -> f64 {
    3.0 / (16.0 * PI * (1.0 + 2.0 * gamma)) * ((1.0 + 3.0 * gamma) + (1.0 - gamma) * mu * mu)
}

/// The second Legendre moment k₂ = 2π ∫ p(μ) P₂(μ) dμ of [`phase`] (k₀ = 1,
/// every other moment 0): with p ∝ A + Bμ² and ∫ μ² P₂ dμ = 4/15,
/// k₂ = (1 − γ)/(10 (1 + 2γ)).
pub fn phase_legendre_2(gamma: f64) -> f64 {
    (1.0 - gamma) / (10.0 * (1.0 + 2.0 * gamma))
}

/// Sample the scattering-angle cosine exactly by inverting the CDF.
///
/// With p(μ) = c (A + B μ²) on [−1, 1], c = 3/(8(1+2γ)), A = 1+3γ, B = 1−γ,
/// the CDF equation c(A(μ+1) + B(μ³+1)/3) = u is the depressed cubic
/// μ³ + pμ + q = 0 with p = 3A/B > 0, so Cardano's formula has one real root.
pub fn sample_mu(u: f64, gamma: f64) -> f64 {
    let a = 1.0 + 3.0 * gamma;
    let b = 1.0 - gamma;
    let c = 3.0 / (8.0 * (1.0 + 2.0 * gamma));
    let p = 3.0 * a / b;
    let q = 3.0 * (a + b / 3.0 - u / c) / b;
    let disc = (q * q / 4.0 + p * p * p / 27.0).sqrt();
    let mu = (-q / 2.0 + disc).cbrt() + (-q / 2.0 - disc).cbrt();
    mu.clamp(-1.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refractive_index_of_standard_air_at_550_nm() {
        // Peck & Reeder (1972): (n−1)·10⁸ ≈ 27 784 at 550 nm (Edlén's value is 27 785).
        let n = refractive_index_minus_one(550.0) * 1e8;
        assert!((n - 27_784.0).abs() < 5.0, "{n}");
    }

    #[test]
    fn depolarisation_is_close_to_published_values() {
        // Bucholtz (1995) Table 1 (from Bates 1984): ρ ≈ 0.0284 near 500 nm
        // and ≈ 0.0273 near 1 µm: we require agreement to a few per cent.
        let rho500 = depolarisation_ratio(500.0);
        assert!((rho500 - 0.0284).abs() < 0.0015, "{rho500}");
        assert!(depolarisation_ratio(400.0) > depolarisation_ratio(800.0));
    }

    #[test]
    fn phase_function_integrates_to_one() {
        for gamma in [0.0, 0.014, 0.1] {
            let n = 10_000;
            let integral: f64 = (0..n)
                .map(|i| {
                    let mu = -1.0 + 2.0 * (f64::from(i) + 0.5) / f64::from(n);
                    2.0 * PI * phase(mu, gamma) * 2.0 / f64::from(n)
                })
                .sum();
            assert!((integral - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn sampling_inverts_the_cdf() {
        let gamma = phase_gamma(450.0);
        for i in 1..100 {
            let u = f64::from(i) / 100.0;
            let mu = sample_mu(u, gamma);
            let a = 1.0 + 3.0 * gamma;
            let b = 1.0 - gamma;
            let c = 3.0 / (8.0 * (1.0 + 2.0 * gamma));
            let cdf = c * (a * (mu + 1.0) + b * (mu.powi(3) + 1.0) / 3.0);
            assert!((cdf - u).abs() < 1e-9, "u={u} cdf={cdf}");
        }
        assert!((sample_mu(0.0, gamma) + 1.0).abs() < 1e-6);
        assert!((sample_mu(1.0, gamma) - 1.0).abs() < 1e-6);
    }
}
