//! The workspace's one source of randomness: SplitMix64 (Steele, Lea, Flood 2014), as a
//! stateful generator ([`Rng`]) and as a stateless hash ([`mix`], [`hash`]).
//!
//! Hand-written on purpose: synthetic scenes, test inputs and randomised searches must give the
//! same bytes for the same seed forever, independent of a crate's version or of thread order.

/// SplitMix64's increment (the golden ratio in 64 bits).
pub const GOLDEN: u64 = 0x9E37_79B9_7F4A_7C15;

/// One SplitMix64 step as a stateless hash: the output function applied to `z + GOLDEN`.
#[inline]
pub fn mix(z: u64) -> u64 {
    let mut z = z.wrapping_add(GOLDEN);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The `i`-th output of a SplitMix64 stream started at `seed`, without walking the stream: lets
/// parallel code draw the value for pixel `i` independently of thread order.
#[inline]
pub fn mix_at(seed: u64, i: u64) -> u64 {
    mix(seed.wrapping_add(i.wrapping_mul(GOLDEN)))
}

/// A hash of several words (order matters), for lattice noise and per-item seeds.
pub fn hash(parts: &[u64]) -> u64 {
    parts
        .iter()
        .fold(0x51_7CC1_B727_220A, |acc, &p| mix(acc ^ mix(p)))
}

/// The top 53 bits of `h` as a float uniform in `[0, 1)`.
#[inline]
pub fn unit(h: u64) -> f64 {
    (h >> 11) as f64 / (1u64 << 53) as f64
}

/// SplitMix64 as a stateful generator.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self(seed ^ GOLDEN)
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        let out = mix(self.0);
        self.0 = self.0.wrapping_add(GOLDEN);
        out
    }

    /// Uniform in `[0, 1)`.
    #[inline]
    pub fn f64(&mut self) -> f64 {
        unit(self.next_u64())
    }

    /// Uniform integer in `[lo, hi]` (inclusive); `lo` when `hi <= lo`.
    #[inline]
    pub fn range(&mut self, lo: i64, hi: i64) -> i64 {
        if hi <= lo {
            return lo;
        }
        let span = (hi as i128 - lo as i128 + 1) as u128;
        (lo as i128 + ((self.next_u64() >> 1) as u128 % span) as i128) as i64
    }

    /// A standard normal sample (Box-Muller; one draw of two uniforms per sample).
    pub fn normal(&mut self) -> f64 {
        // 1 - u lies in (0, 1], so the logarithm is finite.
        let u = 1.0 - self.f64();
        let v = self.f64();
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matches_the_published_splitmix64_stream() {
        // Reference values of SplitMix64 seeded with 1234567 (state before the first step), from
        // the reference C implementation by Vigna (http://prng.di.unimi.it/splitmix64.c).
        let mut r = Rng(1234567);
        let want = [
            6457827717110365317u64,
            3203168211198807973,
            9817491932198370423,
            4593380528125082431,
            16408922859458223821,
        ];
        for w in want {
            assert_eq!(r.next_u64(), w);
        }
    }

    #[test]
    fn stateless_and_stateful_views_agree() {
        let mut r = Rng::new(42);
        for i in 0..10 {
            assert_eq!(r.next_u64(), mix_at(42 ^ GOLDEN, i));
        }
    }

    #[test]
    fn range_covers_its_bounds_and_stays_inside() {
        let mut r = Rng::new(7);
        let mut seen = [false; 5];
        for _ in 0..1000 {
            let v = r.range(-2, 2);
            assert!((-2..=2).contains(&v));
            seen[(v + 2) as usize] = true;
        }
        assert!(seen.iter().all(|&s| s));
        // The full i64 span must not overflow.
        let _ = r.range(i64::MIN, i64::MAX);
        assert_eq!(r.range(5, 5), 5);
    }

    #[test]
    fn normal_has_unit_moments() {
        let mut r = Rng::new(3);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let mean = xs.iter().sum::<f64>() / n as f64;
        let var = xs.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n as f64;
        assert!(mean.abs() < 0.01, "mean {mean}");
        assert!((var - 1.0).abs() < 0.02, "variance {var}");
    }
}
