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
