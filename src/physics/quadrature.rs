//! Numerical integration shared by the physics and the renderer's exact
//! (deterministic) quantities.

/// The nodes and weights of the composite Simpson rule on [`a`, `b`] with
/// `panels` intervals (even): ∫ f ≈ Σ wᵢ f(xᵢ), wᵢ = (h/3)·(1, 4, 2, 4, …,
/// 2, 4, 1), h = (b − a)/panels; exact for cubics, error O(h⁴).
pub fn simpson(a: f64, b: f64, panels: usize) -> impl Iterator<Item = (f64, f64)> {
    debug_assert!(panels >= 2 && panels.is_multiple_of(2), "{panels} panels");
    let h = (b - a) / panels as f64;
    (0..=panels).map(move |i| {
        let c = if i == 0 || i == panels {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        (a + i as f64 * h, c * h / 3.0)
    })
}

/// The Legendre moments k_l = 2π ∫ p(μ) P_l(μ) dμ, l = 0…N − 1, of the
/// phase function `p` by the midpoint rule on `points` cosines (the
/// Legendre polynomials by Bonnet's recursion): the reference the phase
/// functions' closed-form moments are tested against.
#[cfg(test)]
pub(crate) fn legendre_moments_by_midpoints<const N: usize>(
    p: impl Fn(f64) -> f64,
    points: u32,
) -> [f64; N] {
    let mut q = [0.0; N];
    for i in 0..points {
        let mu = -1.0 + 2.0 * (f64::from(i) + 0.5) / f64::from(points);
        let w = 2.0 * std::f64::consts::PI * p(mu) * 2.0 / f64::from(points);
        let (mut p0, mut p1) = (1.0, mu);
        q[0] += w;
        q[1] += w * mu;
        for (l, ql) in q.iter_mut().enumerate().skip(2) {
            let lf = l as f64;
            let p2 = ((2.0 * lf - 1.0) * mu * p1 - (lf - 1.0) * p0) / lf;
            *ql += w * p2;
            (p0, p1) = (p1, p2);
        }
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simpson_is_exact_for_cubics() {
        let integral: f64 = simpson(-1.0, 2.0, 6)
            .map(|(x, w)| w * (x * x * x - 2.0 * x + 1.0))
            .sum();
        // ∫₋₁² x³ − 2x + 1 dx = [x⁴/4 − x² + x] = (4 − 4 + 2) − (1/4 − 1 − 1) = 3.75.
        assert!((integral - 3.75).abs() < 1e-12, "{integral}");
    }
}
