//! A small, fast, seedable random number generator (PCG32, O'Neill 2014).
//!
//! Every pixel sample owns a generator seeded from (scene seed, pass, pixel),
//! so images do not depend on how rayon schedules the work.

/// PCG-XSH-RR 64/32 (O'Neill 2014, "PCG: A Family of Simple Fast
/// Space-Efficient Statistically Good Algorithms for Random Number Generation").
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

/// SplitMix64 finaliser (Steele et al. 2014): a good 64-bit mixing function.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Rng {
    /// A generator for one stream, identified by any number of keys.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Self {
            state: 0,
            inc: (mix64(stream) << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(mix64(seed));
        rng.next_u32();
        rng
    }

    /// Generator for sample `pass` of pixel `pixel` under `seed`.
    pub fn for_sample(seed: u64, pass: u64, pixel: u64) -> Self {
        Self::new(mix64(seed ^ mix64(pass)), pixel)
    }

    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        let hi = u64::from(self.next_u32()) << 21;
        let lo = u64::from(self.next_u32()) >> 11;
        ((hi | lo) as f64) * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform in (0, 1]: safe for `-ln(u)`.
    pub fn uniform_open0(&mut self) -> f64 {
        1.0 - self.uniform()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_is_in_range_and_has_right_mean() {
        let mut rng = Rng::new(1, 2);
        let n = 200_000;
        let mut sum = 0.0;
        for _ in 0..n {
            let u = rng.uniform();
            assert!((0.0..1.0).contains(&u));
            sum += u;
        }
        // Mean of U(0,1) is 1/2 with standard error 1/sqrt(12 n).
        let se = (1.0 / (12.0 * f64::from(n))).sqrt();
        assert!((sum / f64::from(n) - 0.5).abs() < 5.0 * se);
    }

    #[test]
    fn streams_differ() {
        let a: Vec<u32> = (0..4).map(|_| Rng::new(7, 1).next_u32()).collect();
        let mut r1 = Rng::new(7, 1);
        let mut r2 = Rng::new(7, 2);
        assert_ne!(r1.next_u32(), r2.next_u32());
        assert_eq!(a[0], a[1]);
    }
}
