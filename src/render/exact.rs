//! Exact sums for the film: fixed point with 32 fractional bits, held in
//! an `i64` per channel where it fits and an `i128` where it does not.
//!
//! Floating-point addition is not associative, so a film that adds its
//! passes one by one in f32 (or f64) and a merge that adds the sums of two
//! pass ranges give images that differ in their last bits. Integer addition
//! is associative: each sample is rounded once to a multiple of 2⁻³² (to
//! nearest, so without bias) and then added exactly, and any grouping of
//! the same samples — one render, or parts of it merged in any order — gives
//! the same sum bit for bit ([`super::parts`]).
//!
//! Resolution: steps of 2⁻³² ≈ 2.3 × 10⁻¹⁰ (cd m⁻² for the luminance), so
//! each sample is off by at most 1.2 × 10⁻¹⁰, evenly either way (unbiased).
//! A sum of f32s is off by up to 6 × 10⁻⁸ of the running sum at each
//! addition: more than that once the sum passes 2 × 10⁻³.
//!
//! Range: a film holds its sums in an [`ExactPlane`], 8 bytes a channel,
//! |sum| < 2³¹ ≈ 2.1 × 10⁹ — a clear sky's pixel (≤ 10⁵ cd m⁻² but for
//! the aureole) for more than 20 000 samples; a pixel whose sum outgrows it
//! (the Sun's disc, 1.6 × 10⁹ cd m⁻² at noon, at its second sample) moves
//! its excess to a short per-row list of [`ExactSum`]s, whose `i128` holds
//! |sum| < 2⁹⁵. Which pixels moved depends on the order of the additions;
//! the values never do.

use std::ops::{Add, AddAssign, Sub};

/// 2³²: one unit of the sum's integer is 1/`SCALE`.
const SCALE: f64 = 4_294_967_296.0;

/// A sum of real numbers held exactly as an integer multiple of 2⁻³².
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ExactSum(i128);

impl ExactSum {
    /// Zero.
    pub const ZERO: Self = Self(0);

    /// `value` rounded to the nearest multiple of 2⁻³² (saturating beyond
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

/// A plane of exact XYZ sums, one per pixel, held compactly: each channel
/// an `i64` while the sum fits, its excess in a short per-row list where it
/// does not (see the module's notes on range). Planes compare by their
/// values, whichever pixels spilled.
#[derive(Clone, Debug, Default)]
pub struct ExactPlane {
    width: usize,
    compact: Vec<[i64; 3]>,
    /// Per row, the columns whose sums outgrew `compact`, with the excess.
    excess: Vec<Vec<(u32, [ExactSum; 3])>>,
}

impl ExactPlane {
    /// Bytes a pixel holds (the excess lists aside).
    pub const BYTES_PER_PIXEL: usize = 24;

    /// A plane of zeros, or an error where it cannot be allocated.
    pub fn try_new(width: usize, height: usize) -> Result<Self, std::collections::TryReserveError> {
        Ok(Self {
            width,
            compact: super::alloc::try_filled(width * height, [0; 3])?,
            excess: super::alloc::try_filled(height, Vec::new())?,
        })
    }

    /// Pixels in the plane.
    pub fn len(&self) -> usize {
        self.compact.len()
    }

    /// Whether the plane has no pixels.
    pub fn is_empty(&self) -> bool {
        self.compact.is_empty()
    }

    /// The bytes the plane holds.
    pub fn bytes(&self) -> usize {
        std::mem::size_of_val(self.compact.as_slice())
            + self
                .excess
                .iter()
                .map(|r| std::mem::size_of_val(r.as_slice()))
                .sum::<usize>()
    }

    /// The sums at pixel `index` (row-major).
    pub fn get(&self, index: usize) -> [ExactSum; 3] {
        let (y, x) = (index / self.width, index % self.width);
        with_excess(self.compact[index], &self.excess[y], x)
    }

    /// Adds `value` to the sums at pixel `index`.
    pub fn add(&mut self, index: usize, value: [ExactSum; 3]) {
        let (y, x) = (index / self.width, index % self.width);
        self.row_mut(y).add(x, value);
    }

    /// Sets every sum to `value`.
    pub fn fill(&mut self, value: [ExactSum; 3]) {
        for y in 0..self.excess.len() {
            let mut row = self.row_mut(y);
            row.clear();
            for x in 0..row.compact.len() {
                row.add(x, value);
            }
        }
    }

    /// Row `y`, to add to.
    pub fn row_mut(&mut self, y: usize) -> ExactRow<'_> {
        ExactRow {
            compact: &mut self.compact[y * self.width..(y + 1) * self.width],
            excess: &mut self.excess[y],
        }
    }

    /// Every row, in order, to add to (each from its own thread).
    pub fn rows_mut(&mut self) -> Vec<ExactRow<'_>> {
        self.compact
            .chunks_mut(self.width.max(1))
            .zip(self.excess.iter_mut())
            .map(|(compact, excess)| ExactRow { compact, excess })
            .collect()
    }
}

impl PartialEq for ExactPlane {
    fn eq(&self, other: &Self) -> bool {
        self.width == other.width
            && self.len() == other.len()
            && (0..self.len()).all(|i| self.get(i) == other.get(i))
    }
}

impl Eq for ExactPlane {}

/// One row of an [`ExactPlane`], for the thread that renders it.
#[derive(Debug)]
pub struct ExactRow<'a> {
    compact: &'a mut [[i64; 3]],
    excess: &'a mut Vec<(u32, [ExactSum; 3])>,
}

impl ExactRow<'_> {
    /// Adds `value` to the sums at column `x`: to the `i64`s where each
    /// channel's sum still fits, to the row's excess list where not.
    pub fn add(&mut self, x: usize, value: [ExactSum; 3]) {
        let mut spill = [ExactSum::ZERO; 3];
        for ((sum, v), s) in self.compact[x].iter_mut().zip(value).zip(&mut spill) {
            match i64::try_from(v.0).ok().and_then(|v| sum.checked_add(v)) {
                Some(added) => *sum = added,
                None => *s = v,
            }
        }
        if spill != [ExactSum::ZERO; 3] {
            for (e, s) in column_entry(self.excess, x).iter_mut().zip(spill) {
                *e += s;
            }
        }
    }

    /// The sums at column `x`.
    pub fn get(&self, x: usize) -> [ExactSum; 3] {
        with_excess(self.compact[x], &self.excess[..], x)
    }

    /// Sets the row's sums to zero.
    pub fn clear(&mut self) {
        self.compact.fill([0; 3]);
        self.excess.clear();
    }
}

/// The sums of column `x` in a row's short list of columns, added (as
/// zeros) where it is not listed yet.
pub(crate) fn column_entry(list: &mut Vec<(u32, [ExactSum; 3])>, x: usize) -> &mut [ExactSum; 3] {
    let column = x as u32;
    let at = list.iter().position(|e| e.0 == column).unwrap_or_else(|| {
        list.push((column, [ExactSum::ZERO; 3]));
        list.len() - 1
    });
    &mut list[at].1
}

/// A pixel's compact sums plus its excess in `excess`, if listed.
fn with_excess(compact: [i64; 3], excess: &[(u32, [ExactSum; 3])], x: usize) -> [ExactSum; 3] {
    let mut sum = compact.map(|c| ExactSum(i128::from(c)));
    if let Some((_, e)) = excess.iter().find(|e| e.0 as usize == x) {
        for (s, &e) in sum.iter_mut().zip(e) {
            *s += e;
        }
    }
    sum
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
        assert_eq!(ExactSum::from_f64(1.0).to_words(), [0, 1, 0, 0]);
        assert_eq!(
            ExactSum::from_f64(-1.0).to_words(),
            [0, u32::MAX, u32::MAX, u32::MAX]
        );
    }

    #[test]
    fn a_plane_spills_what_outgrows_its_compact_sums_and_keeps_the_value() {
        // Two rows of three; values up to the Sun's disc (1.6e9 cd m⁻²),
        // so the compact i64s (|sum| < 2.1e9) overflow in any order.
        let values: Vec<(usize, [f64; 3])> = (0..300usize)
            .map(|k| {
                let x = k as f64;
                let v = (x * 0.618_033_988_75).fract();
                let big = if k % 7 == 0 { 1.6e9 } else { 1e-3 };
                (k % 6, [v * big, -v * big, v])
            })
            .collect();
        let add_all = |order: &mut dyn Iterator<Item = &(usize, [f64; 3])>| {
            let mut plane = ExactPlane::try_new(3, 2).unwrap();
            for (i, v) in order {
                plane.add(*i, v.map(ExactSum::from_f64));
            }
            plane
        };
        let forward = add_all(&mut values.iter());
        let backward = add_all(&mut values.iter().rev());
        assert_eq!(forward, backward);
        assert!(forward.excess.iter().any(|r| !r.is_empty()), "spilled");
        for i in 0..6 {
            let exact: [ExactSum; 3] = std::array::from_fn(|c| {
                values
                    .iter()
                    .filter(|(j, _)| *j == i)
                    .map(|(_, v)| ExactSum::from_f64(v[c]))
                    .sum()
            });
            assert_eq!(forward.get(i), exact, "pixel {i}");
        }
        // A row cleared holds zeros, spilled columns included.
        let mut cleared = forward.clone();
        cleared.row_mut(0).clear();
        assert_eq!(cleared.get(0), [ExactSum::ZERO; 3]);
        assert_eq!(cleared.get(3), forward.get(3));
    }
}
