//! A small, seeded pseudo-random generator (SplitMix64) for the fuzz generators: fast,
//! reproducible from one `u64`, and without dependencies.

/// SplitMix64 (Steele, Lea and Flood 2014): every seed gives a full-period sequence.
#[derive(Debug, Clone)]
pub struct Rng(u64);

impl Rng {
    /// A generator started from `seed`.
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        mix(self.0)
    }

    /// Uniform in `0..n` (`0` when `n` is 0).
    pub fn below(&mut self, n: usize) -> usize {
        if n == 0 {
            return 0;
        }
        ((self.next_u64() as u128 * n as u128) >> 64) as usize
    }

    /// Uniform in `lo..=hi`.
    pub fn range(&mut self, lo: usize, hi: usize) -> usize {
        lo + self.below(hi.saturating_sub(lo) + 1)
    }

    /// `true` with probability `1 / n`.
    pub fn one_in(&mut self, n: usize) -> bool {
        self.below(n) == 0
    }

    /// `true` with probability `p`.
    pub fn chance(&mut self, p: f64) -> bool {
        self.unit() < p
    }

    /// Uniform in `[0, 1)`.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// One element of a non-empty slice.
    pub fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }

    /// `len` random bytes.
    pub fn bytes(&mut self, len: usize) -> Vec<u8> {
        (0..len).map(|_| self.next_u64() as u8).collect()
    }

    /// A float of any kind: ordinary, tiny, huge, zero of either sign, subnormal, NaN or
    /// infinite.
    pub fn any_f64(&mut self) -> f64 {
        match self.below(12) {
            0 => f64::NAN,
            1 => *self.pick(&[f64::INFINITY, f64::NEG_INFINITY]),
            2 => *self.pick(&[0.0, -0.0, f64::MIN_POSITIVE, 5e-324, f64::MAX, f64::MIN]),
            3 => f64::from_bits(self.next_u64()),
            _ => self.plain_f64(),
        }
    }

    /// A finite float of a plausible magnitude (1e-9 to 1e9, either sign, sometimes an
    /// integer).
    pub fn plain_f64(&mut self) -> f64 {
        let magnitude = 10f64.powi(self.range(0, 18) as i32 - 9);
        let v = self.uniform(-1.0, 1.0) * magnitude;
        if self.one_in(4) {
            v.round()
        } else {
            v
        }
    }
}

/// SplitMix64's output function; also used to derive one input's seed.
pub fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seed of input `index` of the parser named `parser` in a campaign of seed `seed`:
/// every input is reproducible on its own (`fuzz-parsers --parser P --seed S --index I`).
pub fn input_seed(seed: u64, parser: &str, index: u64) -> u64 {
    // FNV-1a of the name, so parsers draw different inputs from one campaign seed.
    let name = parser.bytes().fold(0xCBF2_9CE4_8422_2325_u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01B3)
    });
    mix(mix(seed ^ name).wrapping_add(index))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_reproducible_and_spread() {
        let a: Vec<u64> = (0..4).map(|_| Rng::new(7).next_u64()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        let mut r = Rng::new(1);
        let mut hist = [0usize; 4];
        for _ in 0..4000 {
            hist[r.below(4)] += 1;
        }
        assert!(hist.iter().all(|&h| (800..1200).contains(&h)), "{hist:?}");
        assert_ne!(input_seed(1, "csv", 0), input_seed(1, "csv", 1));
        assert_ne!(input_seed(1, "csv", 0), input_seed(1, "utfsm", 0));
    }
}
