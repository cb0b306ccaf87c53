//! A small, fast, seedable random number generator (PCG, O'Neill 2014),
//! with an optional low-discrepancy prefix for pixel samples.
//!
//! Every pixel sample owns a generator seeded from (scene seed, the pixel's
//! sample number, pixel), so images do not depend on how rayon schedules the
//! work.
//!
//! **Low-discrepancy prefix** ([`Rng::with_sobol_prefix`]): the first
//! [`SOBOL_DIMENSIONS`] uniforms of a pixel sample are the coordinates of
//! one point per sample of an Owen-scrambled Sobol sequence (Burley 2020,
//! "Practical Hash-based Owen Scrambling", JCGT 9(4); the `sobol_burley`
//! crate), scrambled per pixel. One scrambled point is uniform over the unit cube (Owen 1995),
//! so every sample, and the pixel mean, stays unbiased; across the samples of
//! a pixel the points are stratified, so the first decisions of a path (the
//! pixel position, the camera ray's scattering points and the first
//! scattering directions) cover their domain evenly and the noise they cause
//! falls faster than 1/√N. Later uniforms, and all of them past the
//! sequence's 2¹⁶ points, come from PCG. A per-sample variance estimate
//! assumes independent samples: the spectral-radiance probe keeps
//! [`Rng::for_sample`].

/// Uniforms of a pixel sample drawn from the Sobol point ([`Rng::with_sobol_prefix`]).
pub const SOBOL_DIMENSIONS: usize = 32;
/// Most values [`Rng::replaying`] serves.
const MAX_REPLAY: usize = 8;
/// Points of the Sobol sequence (`sobol_burley`'s limit).
pub const SOBOL_POINTS: u64 = 1 << 16;

/// A 64-bit PCG state (O'Neill 2014, "PCG: A Family of Simple Fast
/// Space-Efficient Statistically Good Algorithms for Random Number
/// Generation") read through XSH-RR 64/32 for 32-bit values and RXS-M-XS
/// 64/64 for uniforms (one step each: two 32-bit steps per uniform made
/// the generator 6 % of a midday render, callgrind), with the
/// optional Sobol prefix and a replay buffer.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
    /// The Sobol point's coordinates not yet served (multiples of 2⁻²³).
    prefix: [f32; SOBOL_DIMENSIONS],
    prefix_next: u8,
    prefix_len: u8,
    /// Values [`Rng::replaying`] serves before anything else.
    replay: [f64; MAX_REPLAY],
    replay_next: u8,
    replay_len: u8,
}

const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

/// SplitMix64 finaliser (Steele et al. 2014): a good 64-bit mixing function.
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The Owen scramble of `pixel`'s Sobol sequences under `seed`: one per
/// pixel, so the pixels' sequences are independent.
fn sobol_scramble(seed: u64, pixel: u64) -> u32 {
    mix64(seed ^ mix64(pixel ^ 0x50b0_1000)) as u32
}

impl Rng {
    /// A generator for one stream, identified by any number of keys.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Self {
            state: 0,
            inc: (mix64(stream) << 1) | 1,
            prefix: [0.0; SOBOL_DIMENSIONS],
            prefix_next: 0,
            prefix_len: 0,
            replay: [0.0; MAX_REPLAY],
            replay_next: 0,
            replay_len: 0,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(mix64(seed));
        rng.next_u32();
        rng
    }

    /// Generator for sample number `sample` of pixel `pixel` under `seed`.
    pub fn for_sample(seed: u64, sample: u64, pixel: u64) -> Self {
        Self::new(mix64(seed ^ mix64(sample)), pixel)
    }

    /// This generator with a low-discrepancy prefix: its next
    /// [`SOBOL_DIMENSIONS`] uniforms are the coordinates of point `index`
    /// (< 2¹⁶; see [`SOBOL_POINTS`]) of the Sobol sequence Owen-scrambled for
    /// `pixel` under `seed` (see the module's docs).
    #[must_use]
    pub fn with_sobol_prefix(mut self, seed: u64, pixel: u64, index: u32) -> Self {
        debug_assert!(u64::from(index) < SOBOL_POINTS);
        let scramble = sobol_scramble(seed, pixel);
        for (set, chunk) in self.prefix.chunks_exact_mut(4).enumerate() {
            chunk.copy_from_slice(&sobol_burley::sample_4d(index, set as u32, scramble));
        }
        self.prefix_next = 0;
        self.prefix_len = SOBOL_DIMENSIONS as u8;
        self
    }

    /// Sobol coordinate `v` made uniform on [0, 1) at full precision: the
    /// Sobol values are multiples of 2⁻²³, and 30 random bits below that
    /// fill the rest (the sum is exact and at most 1 − 2⁻⁵³).
    fn sobol_uniform(&mut self, v: f32) -> f64 {
        f64::from(v) + f64::from(self.next_u32() >> 2) * (1.0 / (1u64 << 53) as f64)
    }

    /// Runs `f` with `values` (each in [0, 1)) served as its first uniforms,
    /// then the stream as before. A decision that needs the low-discrepancy
    /// prefix but comes after a variable number of draws takes its uniforms
    /// early and replays them here (at most 8 are kept).
    pub fn replaying<T>(&mut self, values: &[f64], f: impl FnOnce(&mut Self) -> T) -> T {
        let n = values.len().min(MAX_REPLAY);
        self.replay[..n].copy_from_slice(&values[..n]);
        (self.replay_next, self.replay_len) = (0, n as u8);
        let result = f(self);
        (self.replay_next, self.replay_len) = (0, 0);
        result
    }

    /// 64 random bits from one step of the same generator, with PCG's
    /// RXS-M-XS 64/64 output function (O'Neill 2014, section 6.3.4): a
    /// uniform takes one step instead of two 32-bit outputs.
    pub fn next_u64(&mut self) -> u64 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let word = ((old >> ((old >> 59) + 5)) ^ old).wrapping_mul(12_605_985_483_714_917_081);
        (word >> 43) ^ word
    }

    /// The next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }

    /// Uniform in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        if self.replay_next < self.replay_len {
            self.replay_next += 1;
            return self.replay[usize::from(self.replay_next - 1)];
        }
        if self.prefix_next < self.prefix_len {
            let v = self.prefix[usize::from(self.prefix_next)];
            self.prefix_next += 1;
            return self.sobol_uniform(v);
        }
        ((self.next_u64() >> 11) as f64) * (1.0 / (1u64 << 53) as f64)
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
    fn pixel_samples_are_uniform_in_every_dimension() {
        // Over 64 passes of 64 pixels, every prefix dimension and the
        // stream after it have mean 1/2 (4096 values each; standard error
        // 1/sqrt(12·4096) ≈ 0.0045 if independent, smaller if stratified).
        let dims = SOBOL_DIMENSIONS + 4;
        let mut sum = vec![0.0; dims];
        for pixel in 0..64 {
            for pass in 0..64 {
                let mut rng =
                    Rng::for_sample(3, pass, pixel).with_sobol_prefix(3, pixel, pass as u32);
                for s in &mut sum {
                    let u = rng.uniform();
                    assert!((0.0..1.0).contains(&u));
                    *s += u;
                }
            }
        }
        let se = (1.0 / (12.0 * 4096.0_f64)).sqrt();
        for (d, s) in sum.iter().enumerate() {
            assert!((s / 4096.0 - 0.5).abs() < 5.0 * se, "dimension {d}: {s}");
        }
    }

    #[test]
    fn dimensions_of_a_sample_are_uncorrelated() {
        // One scrambled point is uniform over the cube, so its coordinates
        // are independent: the correlation of neighbouring dimensions over
        // 4096 samples stays within 5/√4096 ≈ 0.08 of 0.
        let n = 4096.0;
        let mut values = vec![Vec::new(); SOBOL_DIMENSIONS + 1];
        for pixel in 0..64 {
            for pass in 0..64 {
                let mut rng =
                    Rng::for_sample(11, pass, pixel).with_sobol_prefix(11, pixel, pass as u32);
                for v in &mut values {
                    v.push(rng.uniform());
                }
            }
        }
        for d in 0..SOBOL_DIMENSIONS {
            let (a, b) = (&values[d], &values[d + 1]);
            let cov = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - 0.5) * (y - 0.5))
                .sum::<f64>()
                / n;
            let corr = cov * 12.0;
            assert!(
                corr.abs() < 5.0 / n.sqrt(),
                "dimensions {d}, {}: {corr}",
                d + 1
            );
        }
    }

    #[test]
    fn a_pixels_passes_are_stratified() {
        // The first 64 Sobol points: every 1-D projection puts one point in
        // each 1/64 interval, and dimensions (0, 1) one in each cell of an
        // 8 × 8 grid (a (0, 2)-sequence); Owen scrambling keeps both. An
        // independent generator fails this with near certainty.
        for pixel in [0, 17, 1234] {
            let points: Vec<Vec<f64>> = (0..64)
                .map(|pass| {
                    let mut rng =
                        Rng::for_sample(5, pass, pixel).with_sobol_prefix(5, pixel, pass as u32);
                    (0..SOBOL_DIMENSIONS).map(|_| rng.uniform()).collect()
                })
                .collect();
            for d in 0..SOBOL_DIMENSIONS {
                let mut cells = [0; 64];
                for p in &points {
                    cells[(p[d] * 64.0) as usize] += 1;
                }
                assert!(
                    cells.iter().all(|&c| c == 1),
                    "pixel {pixel}, dimension {d}"
                );
            }
            let mut cells = [0; 64];
            for p in &points {
                cells[(p[0] * 8.0) as usize * 8 + (p[1] * 8.0) as usize] += 1;
            }
            assert!(
                cells.iter().all(|&c| c == 1),
                "pixel {pixel}, dimensions 0 and 1"
            );
        }
        let independent: Vec<f64> = (0..64)
            .map(|pass| Rng::for_sample(5, pass, 0).uniform())
            .collect();
        let mut cells = [0; 64];
        for u in independent {
            cells[(u * 64.0) as usize] += 1;
        }
        assert!(cells.iter().any(|&c| c != 1));
    }

    #[test]
    fn pixels_get_different_scrambles_and_samples_repeat() {
        let first = |pixel| {
            Rng::for_sample(9, 3, pixel)
                .with_sobol_prefix(9, pixel, 3)
                .uniform()
        };
        assert_ne!(first(0), first(1));
        assert_eq!(first(7), first(7));
    }

    #[test]
    fn replaying_serves_the_values_then_the_stream() {
        let mut plain = Rng::for_sample(1, 2, 3).with_sobol_prefix(1, 3, 2);
        let mut replayed = plain.clone();
        let values = [0.25, 0.5, 0.75];
        let (served, next) = replayed.replaying(&values, |rng| {
            let served: Vec<f64> = (0..3).map(|_| rng.uniform()).collect();
            (served, rng.uniform())
        });
        assert_eq!(served, values);
        assert_eq!(next, plain.uniform());
        // After the closure the replay is gone: both continue alike.
        assert_eq!(replayed.uniform(), plain.uniform());
        // Values the closure leaves unused are dropped too.
        replayed.replaying(&values, Rng::uniform);
        assert_eq!(replayed.uniform(), plain.uniform());
    }

    #[test]
    fn neighbouring_streams_are_uncorrelated_and_every_bit_is_fair() {
        // Tests and pixels take streams 0, 1, 2, … under one seed: the k-th
        // uniforms of streams i and i + 1 must be uncorrelated (standard
        // error of a correlation ≈ 1/√n), and each of the 53 bits a uniform
        // uses must be set half the time (binomial, 5 standard errors).
        let (streams, draws) = (4000u64, 16);
        let values: Vec<Vec<f64>> = (0..streams)
            .map(|i| {
                let mut rng = Rng::new(12_345, i);
                (0..draws).map(|_| rng.uniform()).collect()
            })
            .collect();
        let n = ((streams - 1) * draws as u64) as f64;
        let (mut sxy, mut sx, mut sy, mut sxx, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for pair in values.windows(2) {
            for (x, y) in pair[0].iter().zip(&pair[1]) {
                (sx, sy, sxy, sxx, syy) = (sx + x, sy + y, sxy + x * y, sxx + x * x, syy + y * y);
            }
        }
        let cov = sxy / n - sx / n * (sy / n);
        let rho = cov / ((sxx / n - (sx / n).powi(2)) * (syy / n - (sy / n).powi(2))).sqrt();
        assert!(rho.abs() < 5.0 / n.sqrt(), "correlation {rho}");
        let mut rng = Rng::new(3, 9);
        let m = 100_000u32;
        let mut ones = [0u32; 53];
        for _ in 0..m {
            let bits = rng.next_u64() >> 11;
            for (b, count) in ones.iter_mut().enumerate() {
                *count += u32::from((bits >> b) & 1 == 1);
            }
        }
        let sigma = (f64::from(m) * 0.25).sqrt();
        for (b, &count) in ones.iter().enumerate() {
            let off = (f64::from(count) - 0.5 * f64::from(m)).abs();
            assert!(off < 5.0 * sigma, "bit {b}: {count} of {m}");
        }
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
