//! One value per wavelength a path carries ([`Lanes`]), with the
//! arithmetic a path's weights and radiance need: lane by lane, so a
//! product of lanes is written as a product, not as a loop (after
//! Psychopath's spectral sample type).

use std::ops::{Add, AddAssign, Deref, DerefMut, Div, DivAssign, Mul, MulAssign, Sub, SubAssign};

use crate::spectrum::LANES;

/// One value per wavelength lane (radiance, weight, transmittance, a
/// coefficient), with lane-wise arithmetic. Reads and writes as the array
/// of its values.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Lanes(pub [f64; LANES]);

impl Lanes {
    /// Every lane `value`.
    pub const fn splat(value: f64) -> Self {
        Self([value; LANES])
    }

    /// Lane `j` is `f(j)`.
    pub fn from_fn(f: impl FnMut(usize) -> f64) -> Self {
        Self(std::array::from_fn(f))
    }

    /// The lanes' values.
    pub fn iter(&self) -> std::slice::Iter<'_, f64> {
        self.0.iter()
    }

    /// The lanes' values, to change.
    pub fn iter_mut(&mut self) -> std::slice::IterMut<'_, f64> {
        self.0.iter_mut()
    }

    /// `f` of each lane.
    #[must_use]
    pub fn map(self, f: impl FnMut(f64) -> f64) -> Self {
        Self(self.0.map(f))
    }
}

impl From<[f64; LANES]> for Lanes {
    fn from(values: [f64; LANES]) -> Self {
        Self(values)
    }
}

impl Deref for Lanes {
    type Target = [f64; LANES];

    fn deref(&self) -> &[f64; LANES] {
        &self.0
    }
}

impl DerefMut for Lanes {
    fn deref_mut(&mut self) -> &mut [f64; LANES] {
        &mut self.0
    }
}

impl IntoIterator for Lanes {
    type Item = f64;
    type IntoIter = std::array::IntoIter<f64, LANES>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.into_iter()
    }
}

impl<'a> IntoIterator for &'a Lanes {
    type Item = &'a f64;
    type IntoIter = std::slice::Iter<'a, f64>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.iter()
    }
}

impl<'a> IntoIterator for &'a mut Lanes {
    type Item = &'a mut f64;
    type IntoIter = std::slice::IterMut<'a, f64>;

    fn into_iter(self) -> Self::IntoIter {
        self.0.iter_mut()
    }
}

/// Lane-wise operations between two [`Lanes`], and of one with a scalar.
macro_rules! lane_ops {
    ($trait:ident, $method:ident, $assign:ident, $assign_method:ident, $op:tt) => {
        impl $trait for Lanes {
            type Output = Lanes;

            fn $method(self, other: Lanes) -> Lanes {
                Lanes::from_fn(|j| self.0[j] $op other.0[j])
            }
        }

        impl $trait<f64> for Lanes {
            type Output = Lanes;

            fn $method(self, scalar: f64) -> Lanes {
                self.map(|v| v $op scalar)
            }
        }

        impl $assign for Lanes {
            fn $assign_method(&mut self, other: Lanes) {
                for (v, o) in self.0.iter_mut().zip(other.0) {
                    *v = *v $op o;
                }
            }
        }

        impl $assign<f64> for Lanes {
            fn $assign_method(&mut self, scalar: f64) {
                for v in &mut self.0 {
                    *v = *v $op scalar;
                }
            }
        }
    };
}

lane_ops!(Add, add, AddAssign, add_assign, +);
lane_ops!(Sub, sub, SubAssign, sub_assign, -);
lane_ops!(Mul, mul, MulAssign, mul_assign, *);

impl Div<f64> for Lanes {
    type Output = Lanes;

    fn div(self, scalar: f64) -> Lanes {
        self.map(|v| v / scalar)
    }
}

impl DivAssign<f64> for Lanes {
    fn div_assign(&mut self, scalar: f64) {
        for v in &mut self.0 {
            *v /= scalar;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn arithmetic_is_lane_by_lane_and_matches_the_loop() {
        let a = Lanes([1.5, -2.0, 0.25, 3.0]);
        let b = Lanes([2.0, 0.5, -4.0, 1.0 / 3.0]);
        let mut looped = [0.0; LANES];
        for j in 0..LANES {
            looped[j] = a[j] * b[j] + a[j] - b[j] * 2.0;
        }
        assert_eq!((a * b + a - b * 2.0).0, looped);
        let mut c = a;
        c *= b;
        c += 1.0;
        c -= a;
        assert_eq!(c.0, std::array::from_fn(|j| a[j] * b[j] + 1.0 - a[j]));
        assert_eq!((a / 2.0).0, a.0.map(|v| v / 2.0));
        let mut d = a;
        d /= 3.0;
        assert_eq!(d.0, a.0.map(|v| v / 3.0));
        assert_eq!(Lanes::splat(7.0).0, [7.0; LANES]);
    }
}
