//! Sources of uniforms.

/// Something that yields independent uniforms in `[0, 1)`.
pub trait UniformSource {
    /// The next uniform.
    fn next_f32(&mut self) -> f32;
    /// The next `out.len()` uniforms, in order: the same values as as many
    /// calls of [`next_f32`](Self::next_f32), drawn through one call, since
    /// a step's uniforms come through a `dyn` source.
    fn fill(&mut self, out: &mut [f32]) {
        for x in out {
            *x = self.next_f32();
        }
    }
}

impl<U: UniformSource + ?Sized> UniformSource for &mut U {
    fn next_f32(&mut self) -> f32 {
        (**self).next_f32()
    }
    fn fill(&mut self, out: &mut [f32]) {
        (**self).fill(out);
    }
}

/// O'Neill's PCG32 (XSH-RR): small, fast and seekable by stream, so that
/// each pixel can own a stream that depends on the seed and the pixel only.
///
/// Written here rather than taken from rand_pcg to keep the sampling
/// language free of the rand_core version that each dependency pins.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

impl Pcg32 {
    const MULTIPLIER: u64 = 6_364_136_223_846_793_005;

    /// The generator for `seed` on stream `stream`.
    #[must_use]
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut rng = Pcg32 {
            state: 0,
            inc: (stream << 1) | 1,
        };
        rng.next_u32();
        rng.state = rng.state.wrapping_add(seed);
        rng.next_u32();
        rng
    }

    /// The next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MULTIPLIER).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }
}

impl UniformSource for Pcg32 {
    fn next_f32(&mut self) -> f32 {
        // 24 random bits: every value is exactly representable and below one.
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_draws_what_single_draws_draw() {
        let (mut a, mut b) = (Pcg32::new(3, 9), Pcg32::new(3, 9));
        let mut filled = [0.0f32; 5];
        (&mut a as &mut dyn UniformSource).fill(&mut filled);
        let single: Vec<f32> = (0..5).map(|_| b.next_f32()).collect();
        assert_eq!(filled.as_slice(), single.as_slice());
        assert_eq!(a.next_u32(), b.next_u32());
    }

    #[test]
    fn streams_differ_and_repeat() {
        let a: Vec<u32> = (0..4)
            .map({
                let mut r = Pcg32::new(7, 1);
                move |_| r.next_u32()
            })
            .collect();
        let mut b = Pcg32::new(7, 1);
        let mut c = Pcg32::new(7, 2);
        assert_eq!(a, (0..4).map(|_| b.next_u32()).collect::<Vec<_>>());
        assert_ne!(a, (0..4).map(|_| c.next_u32()).collect::<Vec<_>>());
        let mut r = Pcg32::new(1, 0);
        let mean: f64 = (0..100_000).map(|_| f64::from(r.next_f32())).sum::<f64>() / 100_000.0;
        assert!((mean - 0.5).abs() < 0.005);
    }
}
