//! Seeded, position-keyed random numbers: the same pixel gets the same samples whatever thread
//! renders it, so output is identical for any thread count.

/// A small, fast generator (SplitMix64). Not for cryptography; statistically fine for jitter.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
}

impl Rng {
    /// A generator from a seed.
    pub fn new(seed: u64) -> Self {
        Self { state: seed }
    }

    /// A generator for one pixel of one render: independent streams per (seed, x, y).
    pub fn for_pixel(seed: u64, x: u32, y: u32) -> Self {
        let key = (u64::from(x) << 32) | u64::from(y);
        let mut rng = Self::new(seed ^ key.wrapping_mul(0x9E37_79B9_7F4A_7C15));
        rng.next_u64();
        rng
    }

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        // The top 24 bits fill an f32 mantissa exactly.
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_in_unit_interval_and_reproducible() {
        let mut a = Rng::new(1);
        let mut b = Rng::new(1);
        let mut sum = 0.0;
        for _ in 0..10_000 {
            let x = a.next_f32();
            assert_eq!(x, b.next_f32());
            assert!((0.0..1.0).contains(&x));
            sum += x;
        }
        assert!((sum / 10_000.0 - 0.5).abs() < 0.02);
        assert_ne!(
            Rng::for_pixel(0, 1, 2).next_u64(),
            Rng::for_pixel(0, 2, 1).next_u64()
        );
    }
}
