//! Exact sums for the film: fixed point with 64 fractional bits in an
//! `i128`.
//!
//! Floating-point addition is not associative, so a film that adds its
//! passes one by one in f32 (or f64) and a merge that adds the sums of two
//! pass ranges give images that differ in their last bits. Integer addition
//! is associative: each sample is rounded once to a multiple of 2⁻⁶⁴ (to
//! nearest, so without bias) and then added exactly, and any grouping of
//! the same samples — one render, or parts of it merged in any order — gives
//! the same sum bit for bit ([`super::parts`]).
//!
//! Range and resolution: |sum| < 2⁶³ ≈ 9.2 × 10¹⁸ (the Sun's disc is about
//! 1.6 × 10⁹ cd m⁻² at noon, so a million samples of it fit 5 000 times
//! over) in steps of 2⁻⁶⁴ ≈ 5.4 × 10⁻²⁰, far below the faintest sky the
//! renderer draws and below an f32's relative step (6 × 10⁻⁸) for any
//! value above 10⁻¹² — the rounding adds less than an f32 sum did.

use std::ops::{Add, AddAssign, Sub};

/// 2⁶⁴: one unit of the sum's integer is 1/`SCALE`.
const SCALE: f64 = 18_446_744_073_709_551_616.0;

/// A sum of real numbers held exactly as an integer multiple of 2⁻⁶⁴.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExactSum(i128);

impl ExactSum {
    /// Zero.
    pub const ZERO: Self = Self(0);

    /// `value` rounded to the nearest multiple of 2⁻⁶⁴ (saturating beyond
    /// the range; `value` must be finite).
    pub fn from_f64(value: f64) -> Self {
        debug_assert!(value.is_finite(), "{value}");
        Self((value * SCALE).round() as i128)
    }

    /// The nearest f64.
    pub fn to_f64(self) -> f64 {
        self.0 as f64 / SCALE
    }

    /// The 128 bits as four 32-bit words, least significant first (for
    /// files whose channels hold 32-bit unsigned integers).
    pub fn to_words(self) -> [u32; 4] {
        let bits = self.0 as u128;
        std::array::from_fn(|k| (bits >> (32 * k)) as u32)
    }

    /// The sum whose [`Self::to_words`] are `words`.
    pub fn from_words(words: [u32; 4]) -> Self {
        let bits = words
            .iter()
            .enumerate()
            .fold(0u128, |acc, (k, &w)| acc | (u128::from(w) << (32 * k)));
        Self(bits as i128)
    }
}

impl AddAssign for ExactSum {
    fn add_assign(&mut self, other: Self) {
        self.0 = self.0.saturating_add(other.0);
    }
}

impl Add for ExactSum {
    type Output = Self;

    fn add(mut self, other: Self) -> Self {
        self += other;
        self
    }
}

impl Sub for ExactSum {
    type Output = Self;

    fn sub(self, other: Self) -> Self {
        Self(self.0.saturating_sub(other.0))
    }
}

impl std::iter::Sum for ExactSum {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::ZERO, Add::add)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sums_do_not_depend_on_their_grouping() {
        // Values spanning 30 decades, where f64 sums depend on the order.
        let values: Vec<f64> = (0..1000)
            .map(|i| {
                let x = f64::from(i);
                (x * 0.618_033_988_75).fract() * 10f64.powf((x % 30.0) - 15.0)
            })
            .collect();
        let whole: ExactSum = values.iter().map(|&v| ExactSum::from_f64(v)).sum();
        for split in [1, 17, 500, 999] {
            let a: ExactSum = values[..split].iter().map(|&v| ExactSum::from_f64(v)).sum();
            let b: ExactSum = values[split..].iter().map(|&v| ExactSum::from_f64(v)).sum();
            assert_eq!(a + b, whole);
            assert_eq!(b + a, whole);
            assert_eq!(whole - a, b);
        }
        let float: f64 = values.iter().sum();
        assert!((whole.to_f64() - float).abs() <= 1e-12 * float);
    }

    #[test]
    fn values_round_to_the_nearest_step_and_words_round_trip() {
        for v in [0.0, 1.0, -2.5, 1.6e9, 3.0e-19, -7.25e12, 1e-25] {
            let s = ExactSum::from_f64(v);
            assert!(
                (s.to_f64() - v).abs() <= 0.5 / SCALE + 1e-16 * v.abs(),
                "{v}"
            );
            assert_eq!(ExactSum::from_words(s.to_words()), s);
        }
        assert_eq!(ExactSum::from_f64(1.0).to_words(), [0, 0, 1, 0]);
        assert_eq!(
            ExactSum::from_f64(-1.0).to_words(),
            [0, 0, u32::MAX, u32::MAX]
        );
    }
}
