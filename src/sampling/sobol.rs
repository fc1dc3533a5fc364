//! The path tracer's sample sequence: Owen-scrambled Sobol points, padded dimension by
//! dimension with shuffled indices (Burley, "Practical Hash-based Owen Scrambling", JCGT 2020;
//! the sampler pbrt-v4 calls `PaddedSobolSampler` and Cycles uses as "Sobol-Burley").
//!
//! Each sample of a pixel asks for its numbers in order, one or two at a time. Every request
//! (a *dimension*) gets the first two dimensions of the Sobol sequence, a (0, 2)-sequence,
//! with its own random shuffle of the sample indices and its own Owen scrambling, both keyed
//! by a hash of (seed, pixel, dimension). So:
//!
//! - within one dimension, the first 2^m samples of a pixel are stratified: every pair of them
//!   falls in its own elementary interval of area 2^-m (the shuffle keeps this, see
//!   [`shuffled_index`]), where independent random numbers clump and leave holes;
//! - different dimensions, and different pixels, are independent of one another;
//! - every point is uniformly distributed over [0, 1)², so estimators stay unbiased whatever
//!   order the numbers are used in.
//!
//! Numbers are a pure function of (seed, pixel, sample index, dimension): the same image for
//! any thread count, and a pixel can stop after any number of samples (adaptive sampling).

/// The sample numbers of one pixel: seeded, keyed by the pixel, stepped through samples.
#[derive(Clone, Debug)]
pub struct Sampler {
    /// The (seed, pixel) key every dimension's hash starts from.
    key: u64,
    /// The current sample's index within the pixel, bit-reversed (as `owen_scramble` takes
    /// it: reversed once a sample instead of once a dimension).
    index_reversed: u32,
    /// The next dimension to hand out.
    dimension: u32,
}

impl Sampler {
    /// The sampler of pixel (`x`, `y`) for `seed`, at sample 0. The pixel's key goes through
    /// SplitMix64's output mix before it meets the seed, so neighbouring pixels get unrelated
    /// keys (an unmixed key once made pixel (x, y + 1) repeat (x, y)'s numbers shifted by one,
    /// and path-traced noise showed vertical streaks).
    pub fn for_pixel(seed: u64, x: u32, y: u32) -> Self {
        let pixel = (u64::from(x) << 32) | u64::from(y);
        Self {
            key: super::mix(seed ^ super::mix(pixel.wrapping_mul(super::INCREMENT))),
            index_reversed: 0,
            dimension: 0,
        }
    }

    /// Moves to sample `index` of the pixel, from its first dimension.
    pub fn start_sample(&mut self, index: u32) {
        self.index_reversed = index.reverse_bits();
        self.dimension = 0;
    }

    /// The next number of the current sample, in [0, 1): Owen-scrambled van der Corput (the
    /// Sobol sequence's first dimension) at a shuffled index.
    pub fn next_f32(&mut self) -> f32 {
        let (seed_index, seed_x, _) = self.dimension_seeds();
        let i = shuffled_index(self.index_reversed, seed_index);
        // owen_scramble(i.reverse_bits(), seed_x), without reversing twice.
        to_unit(owen_hash(i, seed_x).reverse_bits())
    }

    /// Passes over `dimensions` dimensions (one `next_f32` or `next_2d` each) without drawing
    /// them: a number a sample does not need costs nothing, and the ones after it keep their
    /// dimensions.
    pub fn skip(&mut self, dimensions: u32) {
        self.dimension += dimensions;
    }

    /// The next two numbers of the current sample, in [0, 1)²: a point of the Sobol
    /// sequence's first two dimensions (a (0, 2)-sequence), Owen-scrambled, at a shuffled
    /// index. Use it for the two coordinates of one 2D warp (a pixel position, a direction,
    /// a point on a light) so they are stratified together.
    pub fn next_2d(&mut self) -> (f32, f32) {
        let (seed_index, seed_x, seed_y) = self.dimension_seeds();
        let i = shuffled_index(self.index_reversed, seed_index);
        (
            to_unit(owen_hash(i, seed_x).reverse_bits()),
            // owen_scramble(sobol_second(i), seed_y), without reversing twice.
            to_unit(owen_hash(sobol_second_reversed(i), seed_y).reverse_bits()),
        )
    }

    /// Three independent 32-bit seeds for the current dimension (index shuffle, first and
    /// second coordinate), and a step to the next dimension.
    fn dimension_seeds(&mut self) -> (u32, u32, u32) {
        let h = super::mix(self.key ^ u64::from(self.dimension).wrapping_mul(super::INCREMENT));
        let h2 = super::mix(h);
        self.dimension += 1;
        (h as u32, (h >> 32) as u32, h2 as u32)
    }
}

/// `index` shuffled by a random permutation keyed by `seed`: nested uniform (Owen) scrambling
/// of its bits, as Burley shuffles. Bit k of the result is bit k of `index` flipped or not by
/// the bits above it, so the first 2^m indices (all higher bits zero) map to one aligned block
/// c·2^m + (a permutation of 0..2^m). The Sobol points of an aligned block are a (0, m, 2)-net
/// (the high index bits XOR every point by the same constant), so the first 2^m shuffled
/// samples stay stratified; so does every aligned block of 2^m.
///
/// Takes the index bit-reversed (`index.reverse_bits()`): `owen_scramble` without its first
/// reversal, which the sampler does once a sample instead of once a dimension.
#[inline(always)]
fn shuffled_index(index_reversed: u32, seed: u32) -> u32 {
    owen_hash(index_reversed, seed).reverse_bits()
}

/// Nested uniform (Owen) scrambling of a 32-bit fixed-point fraction: each bit is flipped or
/// not by a hash of `seed` and the bits above it, which permutes the elementary intervals at
/// every level and keeps a net a net. Burley's construction (reverse, a Laine-Karras style
/// hash that propagates only upward, reverse back) with Vegdahl's stronger hash (the one
/// Cycles uses in `reversed_bit_owen`).
#[cfg(test)]
fn owen_scramble(x: u32, seed: u32) -> u32 {
    owen_hash(x.reverse_bits(), seed).reverse_bits()
}

/// The hash of `owen_scramble` (the tests' reference) on bit-reversed input: each bit of the result is the same bit
/// of `n` flipped by a function of `seed` and the bits below it (multiplications by even
/// constants, additions and odd multiplications only carry upward), a bijection.
fn owen_hash(mut n: u32, seed: u32) -> u32 {
    n ^= n.wrapping_mul(0x3d20_adea);
    n = n.wrapping_add(seed);
    n = n.wrapping_mul((seed >> 16) | 1);
    n ^= n.wrapping_mul(0x0552_6c56);
    n ^= n.wrapping_mul(0x53a2_2864);
    n
}

/// The second dimension of the Sobol sequence at `index`, as a 32-bit fraction with its bits
/// reversed (what [`owen_hash`] takes): the XOR of the direction numbers of the index's set
/// bits. Its primitive polynomial is x + 1, so `v[0] = 1/2` and `v[k] = v[k-1] ^ (v[k-1] >> 1)`;
/// the table holds them reversed.
///
/// XOR is associative, so the sum is taken a byte of the index at a time from
/// [`SOBOL_SECOND_BYTES`]: four loads. The shuffled indices have random high bits, about 16
/// set, and the loop over them one by one was 3-4% of a path-traced Box.
#[inline(always)]
fn sobol_second_reversed(index: u32) -> u32 {
    let [b0, b1, b2, b3] = index.to_le_bytes();
    SOBOL_SECOND_BYTES[0][b0 as usize]
        ^ SOBOL_SECOND_BYTES[1][b1 as usize]
        ^ SOBOL_SECOND_BYTES[2][b2 as usize]
        ^ SOBOL_SECOND_BYTES[3][b3 as usize]
}

/// The second Sobol dimension's direction numbers, bit-reversed: entry k for index bit k.
const SOBOL_SECOND_DIRECTIONS: [u32; 32] = {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    let mut k = 0;
    while k < 32 {
        v[k] = v[k].reverse_bits();
        k += 1;
    }
    v
};

/// `SOBOL_SECOND_BYTES[b][x]`: the XOR of the (reversed) direction numbers of the set bits of
/// `x` placed as byte `b` of an index (4 KB).
static SOBOL_SECOND_BYTES: [[u32; 256]; 4] = {
    let mut table = [[0u32; 256]; 4];
    let mut b = 0;
    while b < 4 {
        let mut x = 0;
        while x < 256 {
            let mut sum = 0;
            let mut bit = 0;
            while bit < 8 {
                if x & (1 << bit) != 0 {
                    sum ^= SOBOL_SECOND_DIRECTIONS[8 * b + bit];
                }
                bit += 1;
            }
            table[b][x] = sum;
            x += 1;
        }
        b += 1;
    }
    table
};

/// A 32-bit fraction as an f32 in [0, 1): its top 24 bits, which an f32 mantissa holds exactly.
fn to_unit(x: u32) -> f32 {
    (x >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The second Sobol dimension at `index` as a 32-bit fraction.
    fn sobol_second(index: u32) -> u32 {
        sobol_second_reversed(index).reverse_bits()
    }

    /// The first 2^m points (as 32-bit fractions) each fall in their own cell of every
    /// elementary-interval shape of area 2^-m: 2^a × 2^(m-a) cells for a = 0..=m.
    fn is_net(points: &[(u32, u32)], m: u32) -> bool {
        (0..=m).all(|a| {
            let mut seen = vec![false; 1 << m];
            points.iter().all(|&(x, y)| {
                let cx = if a == 0 { 0 } else { x >> (32 - a) };
                let cy = if a == m { 0 } else { y >> (32 - (m - a)) };
                let cell = ((cx << (m - a)) | cy) as usize;
                !std::mem::replace(&mut seen[cell], true)
            })
        })
    }

    /// The byte tables give the XOR over the index's bits one by one, for indices with bits
    /// in every byte.
    #[test]
    fn the_byte_tables_sum_the_direction_numbers() {
        let mut rng = crate::sampling::Rng::new(5);
        let mut indices: Vec<u32> = (0..2000).map(|_| rng.next_u64() as u32).collect();
        indices.extend([0, 1, 255, 256, u32::MAX, 1 << 31, 0x00ff_ff00]);
        for index in indices {
            let mut bitwise = 0;
            for (k, direction) in SOBOL_SECOND_DIRECTIONS.iter().enumerate() {
                if index & (1 << k) != 0 {
                    bitwise ^= direction;
                }
            }
            assert_eq!(sobol_second_reversed(index), bitwise, "index {index:#x}");
        }
    }

    #[test]
    fn the_unscrambled_sequence_is_sobol() {
        // The Sobol sequence's first two dimensions, as published (Joe and Kuo).
        let expected = [
            (0.0, 0.0),
            (0.5, 0.5),
            (0.25, 0.75),
            (0.75, 0.25),
            (0.125, 0.625),
            (0.625, 0.125),
            (0.375, 0.375),
            (0.875, 0.875),
        ];
        for (i, (ex, ey)) in expected.into_iter().enumerate() {
            let i = i as u32;
            assert_eq!(to_unit(i.reverse_bits()), ex, "x of point {i}");
            assert_eq!(to_unit(sobol_second(i)), ey, "y of point {i}");
        }
    }

    #[test]
    fn shuffled_and_scrambled_prefixes_of_power_of_two_length_are_nets() {
        for seed in [0u32, 1, 0xdead_beef, 0x1234_5678] {
            for m in 0..=8 {
                let points: Vec<(u32, u32)> = (0..1u32 << m)
                    .map(|i| {
                        let j = shuffled_index(i.reverse_bits(), seed);
                        (
                            owen_scramble(j.reverse_bits(), seed ^ 0x55),
                            owen_scramble(sobol_second(j), seed ^ 0xaa),
                        )
                    })
                    .collect();
                assert!(is_net(&points, m), "seed {seed:#x}, 2^{m} points");
            }
        }
    }

    #[test]
    fn the_shuffle_is_a_permutation_of_each_aligned_block() {
        let mut seen = [false; 256];
        for i in 0..256u32 {
            let j = shuffled_index(i.reverse_bits(), 0x9e37_79b9) & 255;
            assert!(
                !std::mem::replace(&mut seen[j as usize], true),
                "{i} -> {j}"
            );
        }
    }

    #[test]
    fn a_pixel_sample_is_stratified_in_every_dimension_and_unbiased() {
        // Every dimension of a pixel's first 64 samples is a (0, 6)-net in 2D and fills the 64
        // 1D strata once each; across many pixels the numbers average 1/2 and their squares 1/3.
        let (mut sum, mut squares, mut n) = (0.0f64, 0.0f64, 0.0f64);
        for pixel in 0..50u32 {
            let mut sampler = Sampler::for_pixel(7, pixel, 3 * pixel);
            let mut dims: Vec<Vec<(f32, f32)>> = vec![Vec::new(); 6];
            for s in 0..64 {
                sampler.start_sample(s);
                for (d, dim) in dims.iter_mut().enumerate() {
                    dim.push(if d % 2 == 0 {
                        sampler.next_2d()
                    } else {
                        (sampler.next_f32(), 0.5)
                    });
                }
            }
            for dim in &dims {
                let mut strata = [false; 64];
                for &(x, y) in dim {
                    assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                    assert!(!std::mem::replace(&mut strata[(x * 64.0) as usize], true));
                    sum += f64::from(x);
                    squares += f64::from(x * x);
                    n += 1.0;
                }
            }
        }
        assert!((sum / n - 0.5).abs() < 0.005, "mean {}", sum / n);
        assert!(
            (squares / n - 1.0 / 3.0).abs() < 0.005,
            "second moment {}",
            squares / n
        );
    }

    #[test]
    fn dimensions_and_pixels_are_not_correlated() {
        // The correlation of two dimensions of one pixel, and of one dimension in two
        // vertically neighbouring pixels, over 64 pixels × 64 samples is that of independent
        // numbers (|r| well below 0.05; its standard deviation is 1/64 here).
        let mut a = Vec::new();
        let mut b = Vec::new();
        let mut c = Vec::new();
        for pixel in 0..64u32 {
            let mut first = Sampler::for_pixel(1, pixel, 0);
            let mut second = Sampler::for_pixel(1, pixel, 1);
            for s in 0..64 {
                first.start_sample(s);
                second.start_sample(s);
                a.push(f64::from(first.next_f32()));
                b.push(f64::from(first.next_f32()));
                c.push(f64::from(second.next_f32()));
            }
        }
        let r = |p: &[f64], q: &[f64]| {
            let n = p.len() as f64;
            let (mp, mq) = (p.iter().sum::<f64>() / n, q.iter().sum::<f64>() / n);
            let cov: f64 = p.iter().zip(q).map(|(x, y)| (x - mp) * (y - mq)).sum();
            let vp: f64 = p.iter().map(|x| (x - mp).powi(2)).sum();
            let vq: f64 = q.iter().map(|y| (y - mq).powi(2)).sum();
            cov / (vp * vq).sqrt()
        };
        assert!(r(&a, &b).abs() < 0.05, "dimensions: r = {}", r(&a, &b));
        assert!(r(&a, &c).abs() < 0.05, "pixels: r = {}", r(&a, &c));
    }

    #[test]
    fn the_same_pixel_and_seed_give_the_same_numbers() {
        let draw = |seed| {
            let mut s = Sampler::for_pixel(seed, 5, 9);
            s.start_sample(3);
            (s.next_f32(), s.next_2d())
        };
        assert_eq!(draw(4), draw(4));
        assert_ne!(draw(4), draw(5));
    }
}
