//! Sample numbers and warps. [`Sampler`] gives each pixel its samples' numbers (Owen-scrambled
//! Sobol, keyed by seed and pixel: the same pixel gets the same samples whatever thread renders
//! it, so output is identical for any thread count); [`Rng`] is a plain seeded generator for
//! everything else (generated views, test data). Also the sampling routines of the
//! path tracer: hemisphere and triangle warps, piecewise-constant distributions, the MIS power
//! heuristic.

use glam::Vec3;

mod sobol;

pub use sobol::Sampler;

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

    /// Next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.state = self.state.wrapping_add(INCREMENT);
        mix(self.state)
    }

    /// Uniform in [0, 1).
    pub fn next_f32(&mut self) -> f32 {
        // The top 24 bits fill an f32 mantissa exactly.
        (self.next_u64() >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
    }
}

/// SplitMix64's increment (2⁶⁴ over the golden ratio).
const INCREMENT: u64 = 0x9E37_79B9_7F4A_7C15;

/// SplitMix64's output function: a bijection of 64-bit words that sends neighbouring inputs
/// to unrelated outputs.
fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// An orthonormal basis (t, b, n) around the unit vector `n`, without branches on its sign
/// (Duff et al., "Building an Orthonormal Basis, Revisited", JCGT 2017).
pub fn frame(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// A cosine-weighted direction in the hemisphere around +Z (Malley's method); its pdf is
/// `z / π` per steradian.
pub fn cosine_hemisphere(u1: f32, u2: f32) -> Vec3 {
    let r = u1.sqrt();
    let (sin, cos) = sin_cos_turns(u2);
    Vec3::new(r * cos, r * sin, (1.0 - u1).max(0.0).sqrt())
}

/// A point of the unit disk, uniform by area, from two numbers in [0, 1): Shirley and
/// Chiu's concentric map, which keeps the square's strata as concentric sectors (a polar map
/// squeezes them toward the centre).
pub fn concentric_disk(u1: f32, u2: f32) -> glam::Vec2 {
    let (a, b) = (2.0 * u1 - 1.0, 2.0 * u2 - 1.0);
    if a == 0.0 && b == 0.0 {
        return glam::Vec2::ZERO;
    }
    // The angle in turns: the square's ring at |a| (or |b|) onto the circle of that radius.
    let (r, turns) = if a.abs() > b.abs() {
        (a, 0.125 * (b / a))
    } else {
        (b, 0.25 - 0.125 * (a / b))
    };
    let (sin, cos) = sin_cos_turns(turns);
    glam::Vec2::new(r * cos, r * sin)
}

/// The sine and cosine of the angle `turns`·2π, for sampling an azimuth from a number in
/// [0, 1): within 2e-7 of the exact values (about what `f32::sin_cos` gives after rounding
/// 2π·u to a float), in a dozen inlined instructions where `sin_cos` was a call into libm
/// (4% of a path-traced diffuse box's time, for its cosine-weighted and GGX directions).
///
/// The angle is reduced to the nearest quarter turn exactly (u - q/4 is exact by Sterbenz's
/// lemma for |turns| below 2^21), then Cephes' single-precision minimax polynomials of `sinf`
/// and `cosf` on [-π/4, π/4] give the rest.
#[inline(always)]
pub fn sin_cos_turns(turns: f32) -> (f32, f32) {
    let quarter = (turns * 4.0).round();
    let x = (turns - quarter * 0.25) * std::f32::consts::TAU;
    let z = x * x;
    let sin = ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1) * z * x + x;
    let cos = ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2) * z * z - 0.5 * z + 1.0;
    // Quarter turns q: (sin, cos) of x + q·π/2 is (s, c), (c, -s), (-s, -c), (-c, s). Without
    // branches (q is random in sampling, so a branch on it would mispredict often): swap for
    // odd q, then flip the sine's sign bit for q = 2, 3 and the cosine's for q = 1, 2.
    let q = quarter as i32 as u32;
    let (sin, cos) = if q & 1 == 0 { (sin, cos) } else { (cos, sin) };
    let flip = |v: f32, bit: u32| f32::from_bits(v.to_bits() ^ ((bit & 2) << 30));
    (flip(sin, q), flip(cos, q.wrapping_add(1)))
}

/// Uniform barycentric coordinates on a triangle (the square-root mapping, pbrt-v4 §A.5.5).
pub fn uniform_triangle(u1: f32, u2: f32) -> Vec3 {
    let s = u1.sqrt();
    let (b1, b2) = (1.0 - s, u2 * s);
    Vec3::new(1.0 - b1 - b2, b1, b2)
}

/// The power heuristic with β = 2 (Veach 1997): the MIS weight of a sample drawn with pdf `f`
/// against another strategy with pdf `g`.
pub fn power_heuristic(f: f32, g: f32) -> f32 {
    let (f2, g2) = (f * f, g * g);
    if f2 + g2 > 0.0 && (f2 + g2).is_finite() {
        f2 / (f2 + g2)
    } else if f.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// A piecewise-constant distribution over `n` bins, sampled by inverting its CDF.
#[derive(Clone, Debug, Default)]
pub struct Distribution1D {
    /// Bin weights (non-negative).
    weights: Vec<f32>,
    /// Running sums, normalised: cdf[0] = 0, cdf[n] = 1.
    cdf: Vec<f32>,
    /// Sum of the weights.
    total: f32,
    /// A guide table (the cutpoint method, Chen and Asau 1974): `guide[k]` counts the cdf
    /// entries <= k/G for k = 0..=G, G = `guide.len() - 1` a power of two. A number u in
    /// [k/G, (k+1)/G) has its answer between `guide[k]` and `guide[k + 1]`, so the binary
    /// search runs over a bin or two instead of the whole cdf: the same bin, found sooner (the
    /// environment's two searches were 6% of a path-traced DamagedHelmet).
    guide: Vec<u32>,
}

/// Most cdf entries of one guide slot that [`Distribution1D::sample_index`] steps over one by
/// one; more are binary-searched.
const SCAN_LIMIT: usize = 8;

/// Most entries of a guide table (4 MB): beyond it the search covers a few bins per slot.
const MAX_GUIDE: usize = 1 << 20;

impl Distribution1D {
    /// A distribution proportional to `weights` (negative and non-finite weights count as 0).
    /// With no positive weight it is uniform.
    pub fn new(weights: Vec<f32>) -> Self {
        let weights: Vec<f32> = weights
            .into_iter()
            .map(|w| if w.is_finite() && w > 0.0 { w } else { 0.0 })
            .collect();
        let n = weights.len();
        let mut cdf = Vec::with_capacity(n + 1);
        let mut sum = 0.0f64;
        cdf.push(0.0);
        for w in &weights {
            sum += f64::from(*w);
            cdf.push(sum as f32);
        }
        let total = sum as f32;
        if total > 0.0 {
            for c in &mut cdf {
                *c /= total;
            }
        } else {
            for (i, c) in cdf.iter_mut().enumerate() {
                *c = i as f32 / n.max(1) as f32;
            }
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        // k / G is exact in f32 (G a power of two up to 2^20), as is u·G below.
        let slots = n.next_power_of_two().min(MAX_GUIDE);
        let mut guide = Vec::with_capacity(slots + 1);
        let mut count = 0;
        for k in 0..=slots {
            let at = k as f32 / slots as f32;
            while count < cdf.len() && cdf[count] <= at {
                count += 1;
            }
            guide.push(count as u32);
        }
        Self {
            weights,
            cdf,
            total,
            guide,
        }
    }

    /// Number of bins.
    pub fn len(&self) -> usize {
        self.weights.len()
    }

    /// True with no bins.
    pub fn is_empty(&self) -> bool {
        self.weights.is_empty()
    }

    /// Sum of the weights.
    pub fn total(&self) -> f32 {
        self.total
    }

    /// Probability of bin `i`.
    pub fn probability(&self, i: usize) -> f32 {
        if self.total > 0.0 {
            self.weights.get(i).map_or(0.0, |w| w / self.total)
        } else if self.is_empty() {
            0.0
        } else {
            1.0 / self.len() as f32
        }
    }

    /// A bin drawn with its probability, and the position of `u` within it in [0, 1).
    /// `None` for an empty distribution.
    pub fn sample(&self, u: f32) -> Option<(usize, f32)> {
        let i = self.sample_index(u)?;
        let (lo, hi) = (self.cdf[i], self.cdf[i + 1]);
        let within = if hi > lo { (u - lo) / (hi - lo) } else { 0.5 };
        Some((i, within.clamp(0.0, 1.0 - f32::EPSILON)))
    }

    /// The bin [`Distribution1D::sample`] draws for `u`, without the position within it.
    #[inline(always)]
    pub fn sample_index(&self, u: f32) -> Option<usize> {
        if self.is_empty() {
            return None;
        }
        // The last cdf entry <= u, skipping empty bins (their two cdf entries are equal):
        // the count of entries <= u, searched between the guide's bounds (the cdf does not
        // decrease, so entries before guide[k] are <= k/G <= u, those from guide[k + 1] on
        // are > (k+1)/G > u).
        let below = |c: &f32| *c <= u;
        let count = if (0.0..1.0).contains(&u) {
            let slots = self.guide.len() - 1;
            let k = (u * slots as f32) as usize;
            let (lo, hi) = (self.guide[k] as usize, self.guide[k + 1] as usize);
            if hi - lo <= SCAN_LIMIT {
                // A slot holds (n + 1) / G <= 2 cdf entries on average: stepping over them
                // finds the same count as the binary search, without its mispredicted
                // branches (the environment's two searches were 8% of a path-traced Box).
                let mut count = lo;
                while count < hi && below(&self.cdf[count]) {
                    count += 1;
                }
                count
            } else {
                lo + self.cdf[lo..hi].partition_point(below)
            }
        } else {
            self.cdf.partition_point(below)
        };
        Some(count.saturating_sub(1).min(self.len() - 1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The concentric map fills the unit disk evenly: every point inside, the mean squared
    /// radius of a fine grid 1/2 (uniform by area), each quadrant a quarter, and the corners'
    /// rings on the rim.
    #[test]
    fn concentric_disk_is_uniform_over_the_disk() {
        let n = 256;
        let (mut r2, mut quadrants) = (0.0f64, [0u32; 4]);
        for i in 0..n {
            for j in 0..n {
                let p = concentric_disk((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
                assert!(p.length() <= 1.0 + 1e-6, "{p}");
                r2 += f64::from(p.length_squared());
                quadrants[usize::from(p.x < 0.0) + 2 * usize::from(p.y < 0.0)] += 1;
            }
        }
        assert!(
            (r2 / f64::from(n * n) - 0.5).abs() < 1e-3,
            "{}",
            r2 / f64::from(n * n)
        );
        assert!(quadrants.iter().all(|&q| q == n * n / 4), "{quadrants:?}");
        assert!((concentric_disk(0.0, 0.5).length() - 1.0).abs() < 1e-6);
        assert_eq!(concentric_disk(0.5, 0.5), glam::Vec2::ZERO);
    }

    /// `sin_cos_turns` against f64's sine and cosine of 2π·u for floats u in [0, 1) that the
    /// sampler can give (multiples of 2^-24, in a stride) and for u - 0.5, and at the quarter turns exactly
    /// (where the reduction changes quadrant): within 2e-7, and exactly ±1 and 0 at the
    /// quarters, so a sampled direction stays unit length to rounding.
    #[test]
    fn sin_cos_turns_matches_f64() {
        let mut worst = 0.0f64;
        for k in (0..1u32 << 24)
            .step_by(97)
            .chain([1 << 22, 1 << 23, 3 << 22])
        {
            let u = k as f32 / (1u32 << 24) as f32;
            // Also half a turn back (the environment's azimuth is u - 0.5).
            for turns in [u, u - 0.5] {
                let (sin, cos) = sin_cos_turns(turns);
                let angle = std::f64::consts::TAU * f64::from(turns);
                worst = worst
                    .max((f64::from(sin) - angle.sin()).abs())
                    .max((f64::from(cos) - angle.cos()).abs());
            }
        }
        assert!(worst < 2e-7, "{worst}");
        assert_eq!(sin_cos_turns(0.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(0.25), (1.0, -0.0));
        assert_eq!(sin_cos_turns(0.5), (-0.0, -1.0));
        assert_eq!(sin_cos_turns(0.75), (-1.0, 0.0));
        assert_eq!(sin_cos_turns(1.0), (0.0, 1.0));
        assert_eq!(sin_cos_turns(-0.25), (-1.0, 0.0));
        assert_eq!(sin_cos_turns(-0.5), (0.0, -1.0));
    }

    #[test]
    fn distribution_samples_in_proportion_and_skips_empty_bins() {
        let d = Distribution1D::new(vec![1.0, 0.0, 3.0]);
        assert_eq!(d.probability(0), 0.25);
        assert_eq!(d.probability(1), 0.0);
        let mut rng = Rng::new(3);
        let mut counts = [0usize; 3];
        for _ in 0..40_000 {
            let (i, within) = d.sample(rng.next_f32()).expect("non-empty");
            assert!((0.0..1.0).contains(&within));
            counts[i] += 1;
        }
        assert_eq!(counts[1], 0);
        let share = counts[2] as f32 / 40_000.0;
        assert!((share - 0.75).abs() < 0.01, "{share}");
        assert!(Distribution1D::new(Vec::new()).sample(0.5).is_none());
        let flat = Distribution1D::new(vec![0.0, 0.0]);
        assert_eq!(flat.probability(1), 0.5);
    }

    /// The guided search finds the bin the plain binary search over the whole cdf finds, for
    /// numbers on and around every cdf entry and guide slot, with empty and tiny bins.
    #[test]
    fn guided_search_finds_the_plain_search_bin() {
        let mut rng = Rng::new(11);
        let mut weights: Vec<f32> = (0..1000)
            .map(|i| match i % 7 {
                0 => 0.0,
                1 => 1e-9,
                _ => rng.next_f32() * if i % 50 == 3 { 1000.0 } else { 1.0 },
            })
            .collect();
        weights[0] = 0.0;
        for weights in [weights, vec![1.0], vec![0.0, 2.0, 0.0], vec![3.0; 5]] {
            let d = Distribution1D::new(weights);
            let plain = |u: f32| {
                d.cdf
                    .partition_point(|&c| c <= u)
                    .saturating_sub(1)
                    .min(d.len() - 1)
            };
            let slots = d.guide.len() - 1;
            let mut us: Vec<f32> = d.cdf.to_vec();
            us.extend((0..=slots).map(|k| k as f32 / slots as f32));
            us.extend((0..5000).map(|_| rng.next_f32()));
            for u in us {
                for u in [
                    u,
                    f32::from_bits(u.to_bits().wrapping_sub(1)),
                    f32::from_bits(u.to_bits() + 1),
                ] {
                    if u.is_finite() && u < 1.0 {
                        assert_eq!(d.sample(u).map(|s| s.0), Some(plain(u)), "u = {u}");
                    }
                }
            }
        }
    }

    #[test]
    fn frames_are_orthonormal() {
        for n in [Vec3::Z, Vec3::NEG_Z, Vec3::new(0.3, -0.5, 0.81).normalize()] {
            let (t, b) = frame(n);
            assert!(t.dot(b).abs() < 1e-6 && t.dot(n).abs() < 1e-6 && b.dot(n).abs() < 1e-6);
            assert!((t.length() - 1.0).abs() < 1e-6 && (b.length() - 1.0).abs() < 1e-6);
        }
    }

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
    }
}
