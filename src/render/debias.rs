//! An approximation made unbiased by a randomly applied correction.
//!
//! Where an estimate T̂ of a quantity T is costly and an approximation T̃
//! is cheap (a table look-up), the estimate
//!
//! X = T̃ + 𝟙(u < q) (T̂ − T̃) / q,  E\[X\] = T̃ + E\[T̂\] − T̃ = T,
//!
//! pays for T̂ on a share q of the calls only and stays unbiased whatever
//! T̃ is — Russian roulette on the correction, the debiasing of an
//! approximation as in Misso et al. 2022, "Unbiased and consistent
//! rendering using biased estimators", *ACM Transactions on Graphics*
//! 41(4). Its price is
//!
//! Var X = Var T̂ / q + (1/q − 1)(T − T̃)²:
//!
//! the estimate's own spread and the approximation's error, both times
//! about 1/q. It pays where both are small beside the variance of what X
//! multiplies (a path's light), as for the splats' transmittance from the
//! observer ([`super::observer_depths`]) and the shadow rays toward the sun
//! ([`super::sun_columns`]).

use super::medium::Lanes;
use crate::rng::Rng;

/// `approx` corrected on a share `share` (in (0, 1]) of the calls, chosen
/// by `rng`'s next number, by the unbiased estimate that `exact` draws:
/// unbiased whatever `approx` is (module doc).
pub fn corrected(
    approx: Lanes,
    share: f64,
    rng: &mut Rng,
    exact: impl FnOnce(&mut Rng) -> Lanes,
) -> Lanes {
    if rng.uniform() >= share {
        return approx;
    }
    let exact = exact(rng);
    Lanes::from_fn(|j| approx[j] + (exact[j] - approx[j]) / share)
}

/// Mean and standard error per lane of `n` draws of `f` (the tests'
/// comparisons of a corrected estimate with the one it corrects).
#[cfg(test)]
pub(crate) fn mean_and_error(n: u64, mut f: impl FnMut(u64) -> Lanes) -> (Lanes, Lanes) {
    let (mut sum, mut squares) = (Lanes::splat(0.0), Lanes::splat(0.0));
    for k in 0..n {
        let v = f(k);
        for j in 0..super::medium::LANES {
            sum[j] += v[j];
            squares[j] += v[j] * v[j];
        }
    }
    let mean = Lanes::from_fn(|j| sum[j] / n as f64);
    let error = Lanes::from_fn(|j| {
        ((squares[j] / n as f64 - mean[j] * mean[j]).max(0.0) / (n - 1) as f64).sqrt()
    });
    (mean, error)
}
