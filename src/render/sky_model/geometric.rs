//! Geometric interpolation between the model's table nodes, over a whole
//! spectrum at once.
//!
//! The light past the first scattering falls off about exponentially with
//! the sun's depression at twilight (the shadow rising through the air),
//! and with table nodes a degree or two apart the linear mean there is up
//! to 30 % too bright; so between two solar-zenith nodes whose values
//! differ by more than a quarter the model interpolates geometrically,
//! a (b/a)^f. Where neighbours differ by less than a quarter the two means
//! differ by less than 0.7 %, and the linear one is kept.
//!
//! A march through the tables interpolates two spectra of 16 values per
//! step; one `powf` call per value was a quarter of the preview's first
//! frame at twilight. Here the power is 2^{f log₂(b/a)} by series in short
//! loops over the spectrum, without calls or branches per value, which
//! pipeline (and may vectorise) where 16 calls did not: log₂ from the
//! exponent's bits and 2 atanh((m − 1)/(m + 1)) for the mantissa
//! m ∈ [√½, √2), 2^y from its nearest integer's bits and a Taylor
//! polynomial on the remainder. Both series are cut where their next term
//! is below about 10⁻⁹ of the result, far below the model's own error (per
//! cent); values outside the series' range (zero, subnormal, or a ratio
//! beyond 2^±1000) take the exact path.

use std::f64::consts::{LN_2, LOG2_E};

/// Ratio between neighbours past which the interpolation is geometric.
const GEOMETRIC_PAST: f64 = 1.25;

/// Interpolation between `a` and `b` at fraction `f`: geometric where
/// both are positive and differ by more than a quarter, else linear.
pub(super) fn geometric(a: f64, b: f64, f: f64) -> f64 {
    if a > 0.0 && b > 0.0 && (b > GEOMETRIC_PAST * a || a > GEOMETRIC_PAST * b) {
        a * (b / a).powf(f)
    } else {
        a + f * (b - a)
    }
}

/// [`geometric`] at each wavelength of `a` and `b` (a spectrum at the
/// model's `N` wavelengths), at one fraction `f` (0 ≤ f ≤ 1); within
/// 10⁻⁸ of it relative.
pub(super) fn geometric_spectrum<const N: usize>(a: &[f64; N], b: &[f64; N], f: f64) -> [f64; N] {
    let mut out = [0.0; N];
    let mut any_far = false;
    for n in 0..N {
        out[n] = a[n] + f * (b[n] - a[n]);
        any_far |= b[n] > GEOMETRIC_PAST * a[n] || a[n] > GEOMETRIC_PAST * b[n];
    }
    if !any_far {
        return out;
    }
    // Simple loops, one operation over the spectrum each.
    let mut y = [0.0; N];
    for n in 0..N {
        y[n] = f * log2(b[n] / a[n]);
    }
    let mut power = [0.0; N];
    for n in 0..N {
        power[n] = a[n] * exp2(y[n]);
    }
    let mut exact = false;
    for n in 0..N {
        let (a, b) = (a[n], b[n]);
        let far = b > GEOMETRIC_PAST * a || a > GEOMETRIC_PAST * b;
        let positive = a > 0.0 && b > 0.0;
        let in_range = b / a >= f64::MIN_POSITIVE && y[n].abs() < 1000.0;
        exact |= positive && far && !in_range;
        if positive && far {
            out[n] = power[n];
        }
    }
    if exact {
        for n in 0..N {
            out[n] = geometric(a[n], b[n], f);
        }
    }
    out
}

/// log₂ x for positive normal x (anything for other x: the caller checks).
#[inline(always)]
fn log2(x: f64) -> f64 {
    // x = 2^e m with m ∈ [√½, √2): subtracting √½'s bits leaves e in the
    // exponent field (musl's `log` splits x the same way).
    const SQRT_HALF_BITS: u64 = 0x3fe6_a09e_667f_3bcd;
    // Biased by 1024 so that the shift is a logical one, and the integer
    // turned to a float through 2⁵²'s bits (both as vector instructions).
    const BIAS: u64 = 1024;
    const TWO_52_BITS: u64 = 0x4330_0000_0000_0000;
    let bits = x.to_bits();
    let biased = bits.wrapping_sub(SQRT_HALF_BITS).wrapping_add(BIAS << 52) >> 52;
    let m = f64::from_bits(bits.wrapping_sub(biased << 52).wrapping_add(BIAS << 52));
    let e = f64::from_bits(TWO_52_BITS | biased) - (4_503_599_627_370_496.0 + BIAS as f64);
    // ln m = 2 atanh t, t = (m − 1)/(m + 1), |t| ≤ 0.1716: the series to
    // t⁹ leaves a relative error below t¹⁰/11 ≈ 2·10⁻⁹.
    let t = (m - 1.0) / (m + 1.0);
    let t2 = t * t;
    let series = 1.0 + t2 * (1.0 / 3.0 + t2 * (1.0 / 5.0 + t2 * (1.0 / 7.0 + t2 * (1.0 / 9.0))));
    e + 2.0 * LOG2_E * t * series
}

/// 2^y for |y| < 1000.
#[inline(always)]
fn exp2(y: f64) -> f64 {
    // Adding 1.5·2⁵² rounds y to the nearest integer n, which then lies in
    // the sum's low mantissa bits.
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let s = y + SHIFT;
    let n = s - SHIFT;
    // 2^r = e^{r ln 2}, |r ln 2| ≤ 0.347: Taylor to degree 8 leaves
    // < 0.347⁹/9! ≈ 2·10⁻¹⁰.
    let z = (y - n) * LN_2;
    let mut p = 1.0 / FACTORIALS[8];
    for k in (0..8).rev() {
        p = p * z + 1.0 / FACTORIALS[k];
    }
    // 2^n: the exponent field n + 1023 (the shift's own bits leave by the
    // left shift).
    let scale = f64::from_bits(s.to_bits().wrapping_add(1023) << 52);
    p * scale
}

/// k! for k ≤ 8.
const FACTORIALS: [f64; 9] = [1.0, 1.0, 2.0, 6.0, 24.0, 120.0, 720.0, 5040.0, 40_320.0];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_series_match_the_library_functions() {
        let mut worst: f64 = 0.0;
        for i in 0..200_000 {
            // Spread over 2^±900 and across the mantissa's range.
            let u = (f64::from(i) + 0.5) / 200_000.0;
            let x = 2f64.powf(1800.0 * u - 900.0) * (1.0 + 0.37 * f64::from(i % 7) / 7.0);
            let log = log2(x);
            assert!((log - x.log2()).abs() <= 3e-9, "log2({x})");
            let y = 1800.0 * u - 900.0 + 0.123;
            let exact = y.exp2();
            worst = worst.max((exp2(y) / exact - 1.0).abs());
        }
        assert!(worst < 1e-9, "exp2 off by {worst}");
    }

    #[test]
    fn the_spectrum_matches_the_scalar_interpolation() {
        // The model's 16 wavelengths.
        const N: usize = 16;
        for f in [0.0, 0.13, 0.5, 0.87, 1.0] {
            let a: [f64; N] = std::array::from_fn(|n| match n {
                0 => 0.0,
                1 => 1e-310,
                2 => -1.0,
                3 => 1e-250,
                _ => (n as f64 * 0.37).exp() * 1e-3,
            });
            let b: [f64; N] = std::array::from_fn(|n| match n {
                3 => 1e50,
                4 => a[4] * 1.1,
                _ => (n as f64 * 1.91).exp() * 1e-5 + 1e-9,
            });
            let out = geometric_spectrum(&a, &b, f);
            for n in 0..N {
                let exact = geometric(a[n], b[n], f);
                assert!(
                    (out[n] - exact).abs() <= 1e-8 * exact.abs(),
                    "node {n} at f = {f}: {} against {exact}",
                    out[n]
                );
            }
        }
    }
}
