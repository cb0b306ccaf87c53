//! Lorenz–Mie scattering by homogeneous spheres, and its average over a
//! size distribution: the phase function of a particle population from its
//! refractive index and sizes, at any wavelength.
//!
//! **One sphere** (Bohren & Huffman 1983, *Absorption and Scattering of
//! Light by Small Particles*, §4.4 and Appendix A): with size parameter
//! x = 2πr/λ and relative refractive index m, the scattered field is the
//! series of coefficients
//!
//! a_n = [(D_n(mx)/m + n/x) ψ_n(x) − ψ_{n−1}(x)] / [(D_n(mx)/m + n/x) ξ_n(x) − ξ_{n−1}(x)],
//! b_n = [(m D_n(mx) + n/x) ψ_n(x) − ψ_{n−1}(x)] / [(m D_n(mx) + n/x) ξ_n(x) − ξ_{n−1}(x)],
//!
//! ψ_n and ξ_n = ψ_n − iχ_n the Riccati–Bessel functions (upward
//! recurrence, stable for them), D_n = ψ_n′/ψ_n of the complex argument mx
//! by *downward* recurrence D_{n−1} = n/(mx) − 1/(D_n + n/(mx)) (upward it
//! is unstable wherever Im(mx) is not small). The series stops after
//! n = x + 4x^{1/3} + 2 terms (Wiscombe 1980). From the coefficients:
//!
//! - Q_ext = (2/x²) Σ (2n+1) Re(a_n + b_n), Q_sca = (2/x²) Σ (2n+1)(|a_n|² + |b_n|²);
//! - g Q_sca = (4/x²) [Σ n(n+2)/(n+1) Re(a_n a*_{n+1} + b_n b*_{n+1}) + Σ (2n+1)/(n(n+1)) Re(a_n b*_n)];
//! - the amplitudes S₁(μ) = Σ (2n+1)/(n(n+1)) (a_n π_n + b_n τ_n) and S₂
//!   with π_n and τ_n exchanged, π_n and τ_n the angular functions of
//!   μ = cos θ (π_n = [(2n−1) μ π_{n−1} − n π_{n−2}]/(n−1), τ_n = nμπ_n −
//!   (n+1)π_{n−1}); for unpolarised light the phase function is
//!   p(μ) = (|S₁|² + |S₂|²) / (x² Q_sca) / (2π)… per steradian
//!   normalised to 1 over the sphere (the factor is 1/(k² C_sca)).
//!
//! **A population** with number density n(r) dr scatters with the
//! cross-section-weighted average: p(μ) = ∫ n(r) (|S₁|² + |S₂|²)/(2k²) dr
//! / ∫ n(r) C_sca(r) dr, and its single-scattering albedo is ∫ n C_sca /
//! ∫ n C_ext. The size distribution here is the two-parameter gamma
//! distribution of Hansen & Travis (1974, *Space Sci. Rev.* 16, 527, eq.
//! 2.56), n(r) ∝ r^{(1−3b)/b} e^{−r/(ab)}, whose effective radius (the
//! area-weighted mean radius) is a and effective variance b: the form in
//! which Martian dust is described (Wolff et al. 2009: r_eff = 1.5 µm,
//! v_eff = 0.3).
//!
//! The code is checked against Wiscombe's (1980, NCAR/TN-140+STR,
//! Appendix) and Bohren & Huffman's (1983, Appendix A) published test
//! cases, and against the Rayleigh limit.

use std::f64::consts::PI;

use num_complex::Complex64;

/// The scattering of a plane wave by one homogeneous sphere: the series'
/// coefficients a_n, b_n (n = 1…) and the efficiencies they give.
#[derive(Clone, Debug)]
pub struct Sphere {
    /// Size parameter x = 2πr/λ.
    size_parameter: f64,
    /// a_n, n = 1..=N (index n − 1).
    a: Vec<Complex64>,
    /// b_n, n = 1..=N (index n − 1).
    b: Vec<Complex64>,
}

impl Sphere {
    /// The sphere of size parameter `size_parameter` (2πr/λ, > 0) and
    /// relative refractive index `refractive_index` (n + ik, k ≥ 0 for an
    /// absorbing sphere).
    pub fn new(size_parameter: f64, refractive_index: Complex64) -> Self {
        let x = size_parameter;
        let m = refractive_index;
        let terms = (x + 4.05 * x.cbrt() + 2.0) as usize + 1;
        let mx = m * x;
        // D_n(mx) downward from well above both N and |mx|, with D = 0
        // there. The error of that start decays only where n > |mx|, over a
        // width that grows as |mx|^{1/3}: Bohren & Huffman's max(N, |mx|) +
        // 15 loses 4 × 10⁻⁴ of Q_ext at x = 1000, m = 1.5; this start
        // reproduces Wiscombe's figures to 10⁻⁶.
        let norm = mx.norm();
        let start = terms.max((norm + 15.0 * norm.cbrt()).ceil() as usize) + 15;
        let mut d = vec![Complex64::new(0.0, 0.0); start + 1];
        for n in (1..=start).rev() {
            let n_over = Complex64::new(n as f64, 0.0) / mx;
            d[n - 1] = n_over - Complex64::new(1.0, 0.0) / (d[n] + n_over);
        }
        // ψ_{−1} = cos x, ψ_0 = sin x; χ_{−1} = −sin x, χ_0 = cos x.
        let (mut psi_prev2, mut psi_prev) = (x.cos(), x.sin());
        let (mut chi_prev2, mut chi_prev) = (-x.sin(), x.cos());
        let mut a = Vec::with_capacity(terms);
        let mut b = Vec::with_capacity(terms);
        for (n, &d_n) in d.iter().enumerate().take(terms + 1).skip(1) {
            let nf = n as f64;
            let psi = (2.0 * nf - 1.0) / x * psi_prev - psi_prev2;
            let chi = (2.0 * nf - 1.0) / x * chi_prev - chi_prev2;
            let xi = Complex64::new(psi, -chi);
            let xi_prev = Complex64::new(psi_prev, -chi_prev);
            let da = d_n / m + nf / x;
            let db = d_n * m + nf / x;
            a.push((da * psi - psi_prev) / (da * xi - xi_prev));
            b.push((db * psi - psi_prev) / (db * xi - xi_prev));
            (psi_prev2, psi_prev) = (psi_prev, psi);
            (chi_prev2, chi_prev) = (chi_prev, chi);
        }
        Self {
            size_parameter: x,
            a,
            b,
        }
    }

    /// Extinction efficiency Q_ext = C_ext/(πr²).
    pub fn q_ext(&self) -> f64 {
        let sum: f64 = self
            .orders()
            .map(|(n, a, b)| (2.0 * n + 1.0) * (a + b).re)
            .sum();
        2.0 * sum / self.x2()
    }

    /// Scattering efficiency Q_sca = C_sca/(πr²).
    pub fn q_sca(&self) -> f64 {
        let sum: f64 = self
            .orders()
            .map(|(n, a, b)| (2.0 * n + 1.0) * (a.norm_sqr() + b.norm_sqr()))
            .sum();
        2.0 * sum / self.x2()
    }

    /// Backscattering efficiency, 4|S₁(π)|²/x² (Bohren & Huffman's Q_back).
    pub fn q_back(&self) -> f64 {
        let (s1, _) = self.amplitudes(-1.0);
        4.0 * s1.norm_sqr() / self.x2()
    }

    /// The asymmetry parameter g = ⟨cos θ⟩ of the scattered light.
    pub fn asymmetry(&self) -> f64 {
        let n_max = self.a.len();
        let mut sum = 0.0;
        for i in 0..n_max {
            let n = (i + 1) as f64;
            if i + 1 < n_max {
                let next = self.a[i] * self.a[i + 1].conj() + self.b[i] * self.b[i + 1].conj();
                sum += n * (n + 2.0) / (n + 1.0) * next.re;
            }
            sum += (2.0 * n + 1.0) / (n * (n + 1.0)) * (self.a[i] * self.b[i].conj()).re;
        }
        4.0 * sum / (self.x2() * self.q_sca())
    }

    /// The scattering amplitudes (S₁, S₂) at μ = cos θ, θ the scattering
    /// angle (Bohren & Huffman eq. 4.74).
    pub fn amplitudes(&self, mu: f64) -> (Complex64, Complex64) {
        let (mut pi_prev, mut pi) = (0.0, 1.0);
        let mut s1 = Complex64::new(0.0, 0.0);
        let mut s2 = Complex64::new(0.0, 0.0);
        for (n, a, b) in self.orders() {
            let tau = n * mu * pi - (n + 1.0) * pi_prev;
            let f = (2.0 * n + 1.0) / (n * (n + 1.0));
            s1 += f * (a * pi + b * tau);
            s2 += f * (a * tau + b * pi);
            let next = ((2.0 * n + 1.0) * mu * pi - (n + 1.0) * pi_prev) / n;
            (pi_prev, pi) = (pi, next);
        }
        (s1, s2)
    }

    /// S₁₁ = (|S₁|² + |S₂|²)/2 at μ: the unpolarised scattered intensity
    /// (Wiscombe's and Bohren & Huffman's tabulated quantity).
    pub fn s11(&self, mu: f64) -> f64 {
        let (s1, s2) = self.amplitudes(mu);
        0.5 * (s1.norm_sqr() + s2.norm_sqr())
    }

    /// (n, a_n, b_n) for n = 1..=N.
    fn orders(&self) -> impl Iterator<Item = (f64, Complex64, Complex64)> + '_ {
        self.a
            .iter()
            .zip(&self.b)
            .enumerate()
            .map(|(i, (&a, &b))| ((i + 1) as f64, a, b))
    }

    fn x2(&self) -> f64 {
        self.size_parameter * self.size_parameter
    }
}

/// Hansen & Travis's (1974) gamma distribution of radii: effective radius
/// (µm) and effective variance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GammaSizes {
    /// Effective radius r_eff = ∫ r πr² n dr / ∫ πr² n dr, µm.
    pub effective_radius_um: f64,
    /// Effective variance v_eff (dimensionless), 0 < v_eff < 1/2.
    pub effective_variance: f64,
}

impl GammaSizes {
    /// The number density n(r) ∝ r^{(1−3b)/b} e^{−r/(ab)}, scaled to 1 at
    /// its mode r = a(1 − 3b) (in logarithms, so that a narrow
    /// distribution's large power does not overflow).
    pub fn density(&self, radius_um: f64) -> f64 {
        let (a, b) = (self.effective_radius_um, self.effective_variance);
        let power = (1.0 - 3.0 * b) / b;
        let mode = a * (1.0 - 3.0 * b);
        if radius_um <= 0.0 {
            return 0.0;
        }
        (power * (radius_um / mode).ln() - (radius_um - mode) / (a * b)).exp()
    }

    /// The radius beyond which the distribution's geometric cross-section
    /// πr² n(r) is below 10⁻¹² of its peak, µm: where its integrals stop.
    pub fn upper_radius_um(&self) -> f64 {
        let peak_um = self.effective_radius_um * (1.0 - self.effective_variance);
        let area = |r: f64| r * r * self.density(r);
        let peak = area(peak_um);
        let mut r = peak_um.max(1e-3);
        while area(r) > 1e-12 * peak {
            r *= 1.05;
        }
        r
    }
}

/// The single-scattering properties of a population of spheres at one
/// wavelength.
#[derive(Clone, Debug)]
pub struct PopulationOptics {
    /// Cross-section-weighted extinction efficiency ⟨C_ext⟩/⟨πr²⟩.
    pub q_ext: f64,
    /// Single-scattering albedo ⟨C_sca⟩/⟨C_ext⟩.
    pub single_scattering_albedo: f64,
    /// Asymmetry parameter ⟨g C_sca⟩/⟨C_sca⟩.
    pub asymmetry: f64,
    /// The phase function at the requested cosines, per steradian,
    /// normalised to 1 over the sphere.
    pub phase: Vec<f64>,
}

/// The scattering of the population `sizes` of spheres of refractive index
/// `refractive_index` at `wavelength_nm`, its phase function at the
/// cosines `mu`: the integrals over radius by the trapezoid rule on a
/// grid of `size_step` in size parameter (fine enough to resolve the
/// ripple of the efficiencies, period ≈ π/(n − 1) in x, when 0.1 or less).
pub fn population(
    sizes: &GammaSizes,
    refractive_index: Complex64,
    wavelength_nm: f64,
    mu: &[f64],
    size_step: f64,
) -> PopulationOptics {
    let k_per_um = 2.0 * PI / (wavelength_nm * 1e-3);
    let x_max = k_per_um * sizes.upper_radius_um();
    let steps = (x_max / size_step).ceil() as usize;
    let dx = x_max / steps as f64;
    let (mut ext, mut sca, mut g_sca, mut area) = (0.0, 0.0, 0.0, 0.0);
    let mut intensity = vec![0.0; mu.len()];
    // The trapezoid's end points weigh ½; the integrand vanishes at x = 0.
    for i in 1..=steps {
        let x = i as f64 * dx;
        let weight = if i == steps { 0.5 } else { 1.0 };
        let r_um = x / k_per_um;
        let number = weight * sizes.density(r_um);
        if number == 0.0 {
            continue;
        }
        let sphere = Sphere::new(x, refractive_index);
        let geometric = PI * r_um * r_um * number;
        let q_sca = sphere.q_sca();
        area += geometric;
        ext += geometric * sphere.q_ext();
        sca += geometric * q_sca;
        g_sca += geometric * q_sca * sphere.asymmetry();
        // (|S₁|² + |S₂|²)/(2k²) is the differential cross-section per sr,
        // µm²; per unit number of particles, summed with their numbers.
        for (value, &m) in intensity.iter_mut().zip(mu) {
            *value += number * sphere.s11(m) / (k_per_um * k_per_um);
        }
    }
    PopulationOptics {
        q_ext: ext / area,
        single_scattering_albedo: sca / ext,
        asymmetry: g_sca / sca,
        phase: intensity.iter().map(|v| v / sca).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn assert_close(actual: f64, expected: f64, tolerance: f64, what: &str) {
        assert!(
            (actual - expected).abs() <= tolerance,
            "{what}: {actual} vs {expected} (±{tolerance})"
        );
    }

    /// Wiscombe (1980), NCAR/TN-140+STR, Appendix, test cases of m = 1.5
    /// (non-absorbing) and 1.5 + 0.1i: x, Q_ext, Q_sca, g, and S₁₁ at 0°,
    /// 30° and 180°.
    #[test]
    fn wiscombe_test_cases() {
        #[rustfmt::skip]
        let cases = [
            // (k, x, Q_ext, Q_sca, g, S11(0°), S11(30°), S11(180°))
            (0.0, 10.0, 2.881999, 2.881999, 0.742913, 0.520856e4, 0.768071e2, 0.423766e2),
            (0.0, 100.0, 2.094388, 2.094388, 0.818246, 0.275508e8, 0.159327e5, 0.434048e4),
            (0.0, 1000.0, 2.013945, 2.013945, 0.827882, 0.253568e12, 0.103882e7, 0.257577e7),
            (0.1, 10.0, 2.459791, 1.235144, 0.922350, 0.379171e4, 0.273164e2, 0.231818e1),
            (0.1, 100.0, 2.089822, 1.132134, 0.950392, 0.273645e8, 0.801673e3, 0.103837e3),
            (0.1, 1000.0, 2.019703, 1.106932, 0.950880, 0.255002e12, 0.646676e5, 0.103834e5),
        ];
        for (k, x, q_ext, q_sca, g, s0, s30, s180) in cases {
            let sphere = Sphere::new(x, Complex64::new(1.5, k));
            let what = format!("m = 1.5 + {k}i, x = {x}");
            assert_close(sphere.q_ext(), q_ext, 2e-6, &format!("{what}: Q_ext"));
            assert_close(sphere.q_sca(), q_sca, 2e-6, &format!("{what}: Q_sca"));
            assert_close(sphere.asymmetry(), g, 2e-6, &format!("{what}: g"));
            for (deg, expected) in [(0.0_f64, s0), (30.0, s30), (180.0, s180)] {
                let s11 = sphere.s11(deg.to_radians().cos());
                assert_close(s11 / expected, 1.0, 1e-5, &format!("{what}: S11({deg}°)"));
            }
        }
    }

    /// Bohren & Huffman (1983), Appendix A: m = 1.55, r = 0.525 µm, λ =
    /// 0.6328 µm: Q_ext = Q_sca = 3.10543, Q_back = 2.92534, and S₁₁
    /// relative to 0° at 45° and 90°.
    #[test]
    fn bohren_and_huffman_test_case() {
        let x = 2.0 * PI * 0.525 / 0.6328;
        let sphere = Sphere::new(x, Complex64::new(1.55, 0.0));
        assert_close(sphere.q_ext(), 3.10543, 1e-5, "Q_ext");
        assert_close(sphere.q_sca(), 3.10543, 1e-5, "Q_sca");
        assert_close(sphere.q_back(), 2.92534, 1e-5, "Q_back");
        let s0 = sphere.s11(1.0);
        for (deg, expected) in [(45.0_f64, 0.701845e-1), (90.0, 0.124601e-1)] {
            let relative = sphere.s11(deg.to_radians().cos()) / s0;
            assert_close(relative, expected, 2e-6, &format!("S11({deg}°)/S11(0°)"));
        }
    }

    /// Small spheres scatter as dipoles: Q_sca → (8/3) x⁴ |(m² − 1)/(m² +
    /// 2)|², g → 0, and the phase function → (3/16π)(1 + μ²).
    #[test]
    fn small_spheres_are_rayleigh_scatterers() {
        let m = Complex64::new(1.5, 0.0);
        let x = 0.01;
        let sphere = Sphere::new(x, m);
        let m2 = m * m;
        let polarisability = ((m2 - 1.0) / (m2 + 2.0)).norm_sqr();
        let rayleigh = 8.0 / 3.0 * x.powi(4) * polarisability;
        assert_close(sphere.q_sca() / rayleigh, 1.0, 1e-4, "Q_sca / Rayleigh");
        assert!(sphere.asymmetry().abs() < 1e-4, "g {}", sphere.asymmetry());
        for mu in [-1.0, -0.3, 0.0, 0.5, 1.0] {
            // p = S11 / (x² Q_sca π) per sr for a single sphere.
            let p = sphere.s11(mu) / (x * x * sphere.q_sca() * PI);
            let dipole = 3.0 / (16.0 * PI) * (1.0 + mu * mu);
            assert_close(p / dipole, 1.0, 1e-3, &format!("phase at μ = {mu}"));
        }
    }

    /// A population's phase function is normalised, its g is the mean
    /// cosine of that phase function, and a narrow distribution scatters as
    /// one sphere of its effective radius.
    #[test]
    fn a_population_phase_function_is_normalised() {
        let n = 4001;
        let mu: Vec<f64> = (0..n)
            .map(|i| (PI * i as f64 / (n - 1) as f64).cos())
            .collect();
        let sizes = GammaSizes {
            effective_radius_um: 0.5,
            effective_variance: 0.3,
        };
        let optics = population(&sizes, Complex64::new(1.5, 0.005), 550.0, &mu, 0.1);
        // 2π ∫ p dμ and 2π ∫ p μ dμ by the trapezoid rule in θ (dμ = sin θ dθ).
        let dtheta = PI / (n - 1) as f64;
        let (mut norm, mut mean) = (0.0, 0.0);
        for (i, (&p, &m)) in optics.phase.iter().zip(&mu).enumerate() {
            let theta = i as f64 * dtheta;
            let w = if i == 0 || i == n - 1 { 0.5 } else { 1.0 };
            norm += w * p * theta.sin() * dtheta * 2.0 * PI;
            mean += w * p * m * theta.sin() * dtheta * 2.0 * PI;
        }
        assert_close(norm, 1.0, 1e-3, "2π ∫ p dμ");
        assert_close(mean, optics.asymmetry, 1e-3, "mean cosine vs g");
        assert!(optics.single_scattering_albedo < 1.0);
        assert!(optics.single_scattering_albedo > 0.9);

        let narrow = GammaSizes {
            effective_radius_um: 0.5,
            effective_variance: 1e-4,
        };
        let one = Sphere::new(2.0 * PI * 0.5 / 0.55, Complex64::new(1.5, 0.0));
        let optics = population(&narrow, Complex64::new(1.5, 0.0), 550.0, &[1.0], 0.002);
        assert_close(optics.q_ext, one.q_ext(), 0.02, "narrow population Q_ext");
        assert_close(
            optics.asymmetry,
            one.asymmetry(),
            0.01,
            "narrow population g",
        );
    }
}
