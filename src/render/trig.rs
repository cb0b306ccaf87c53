//! Sine and cosine of an angle given in turns, for sampling azimuths.
//!
//! Every sampled direction turns a uniform variate u into an azimuth 2πu
//! and needs its sine and cosine: three calls per scattering vertex, which
//! made libm's `sincos` 4–5 % of a midday render (`perf`, `BENCHMARKS.md`).
//! An angle in turns reduces to a quarter turn *exactly*
//! (4u − round(4u) is exact in binary floating point), so two short
//! polynomials on [−π/4, π/4] serve, with no table and no branch but the
//! quadrant's swap.

use std::f64::consts::FRAC_PI_2;

/// (sin 2πt, cos 2πt) for a finite `turns` = t: within 10⁻¹⁵ of libm's
/// `sin_cos(2πt)` on [0, 1) (which itself rounds 2πt first; tested), with
/// sin² + cos² within 4 × 10⁻¹⁶ of 1.
#[inline]
pub fn sin_cos_turns(turns: f64) -> (f64, f64) {
    // t = q/4 + r/4 with integer q and |r| ≤ 1/2: both steps are exact.
    let quarters = 4.0 * turns;
    let q = quarters.round();
    let theta = (quarters - q) * FRAC_PI_2;
    let (s, c) = sin_cos_octant(theta);
    // Rotate by q quarter turns.
    match (q as i64).rem_euclid(4) {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// Sine and cosine for |θ| ≤ π/4 by their Taylor series: the first omitted
/// terms, θ¹⁷/17! and θ¹⁸/18!, stay below 5 × 10⁻¹⁷ there.
#[inline]
fn sin_cos_octant(theta: f64) -> (f64, f64) {
    // 1/n! for the series, exact to the last bit as f64 literals.
    const S: [f64; 7] = [
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
        -1.0 / 1_307_674_368_000.0,
    ];
    const C: [f64; 8] = [
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
        -1.0 / 87_178_291_200.0,
        1.0 / 20_922_789_888_000.0,
    ];
    let x2 = theta * theta;
    let sin_tail = S.iter().rev().fold(0.0, |acc: f64, &k| acc * x2 + k);
    let cos_tail = C.iter().rev().fold(0.0, |acc: f64, &k| acc * x2 + k);
    (theta + theta * x2 * sin_tail, 1.0 + x2 * cos_tail)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_library_sine_and_cosine() {
        // A fine sweep of [0, 1) (the sampling range), the quadrant
        // boundaries and octant edges, and a few turns outside it.
        let mut worst = 0.0f64;
        let sweep = (0..200_000).map(|i| f64::from(i) / 200_000.0);
        let edges = (0..=16).flat_map(|k| {
            let t = f64::from(k) / 16.0;
            [t, t + 1e-12, t - 1e-12]
        });
        for t in sweep
            .chain(edges)
            .chain([-0.3, 2.7, -5.125, 1.0 - f64::EPSILON])
        {
            let (s, c) = sin_cos_turns(t);
            let (s_ref, c_ref) = (2.0 * std::f64::consts::PI * t).sin_cos();
            worst = worst.max((s - s_ref).abs()).max((c - c_ref).abs());
        }
        // The reference itself rounds 2πt; with |t| ≤ 6 that costs ≤ 2e-15
        // in the argument, so compare at that level beyond [0, 1).
        assert!(worst < 4e-15, "largest difference {worst:e}");
        let mut worst_unit = 0.0f64;
        for i in 0..100_000 {
            let t = f64::from(i) / 100_000.0;
            let (s, c) = sin_cos_turns(t);
            let (s_ref, c_ref) = (2.0 * std::f64::consts::PI * t).sin_cos();
            worst_unit = worst_unit.max((s - s_ref).abs()).max((c - c_ref).abs());
            assert!((s * s + c * c - 1.0).abs() < 4e-16, "t = {t}");
        }
        assert!(
            worst_unit < 1e-15,
            "largest difference on [0, 1): {worst_unit:e}"
        );
    }

    #[test]
    fn quadrants_land_on_the_axes() {
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turns(0.5), (-0.0, -1.0));
        assert_eq!(sin_cos_turns(0.75), (-1.0, 0.0));
    }
}
