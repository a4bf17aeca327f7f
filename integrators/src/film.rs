//! The film: per-pixel accumulation of camera-path estimates, a
//! thread-safe splat buffer for light paths, and a count of the non-finite
//! samples that were dropped. (Pixel filters are sampled by the camera
//! strategy: each camera sample lands in one pixel.)

use std::sync::atomic::{AtomicU64, Ordering};

use aether_strategies::geometry::is_finite;

/// `v` as f32, saturating at the largest finite f32: a mean too bright for
/// f32 (reflectance far above one) stays finite in the image.
#[must_use]
pub fn saturate(v: f64) -> f32 {
    v.clamp(-f64::from(f32::MAX), f64::from(f32::MAX)) as f32
}

/// The image of camera-sample `sums` over their per-pixel `counts` (black
/// where nothing was rendered), plus light paths' splatted sums over their
/// number: a render's image, and a merge's of its parts.
#[must_use]
pub fn camera_image(
    sums: &[[f64; 3]],
    counts: &[u32],
    splats: Option<(&[[f64; 3]], u64)>,
) -> Vec<[f32; 3]> {
    sums.iter()
        .zip(counts)
        .enumerate()
        .map(|(i, (s, &n))| {
            let c = match n {
                0 => [0.0; 3],
                n => s.map(|c| saturate(c / f64::from(n))),
            };
            match splats {
                Some((splat, paths)) if paths > 0 => {
                    let scale = 1.0 / paths as f64;
                    [0, 1, 2].map(|k| saturate(f64::from(c[k]) + splat[i][k] * scale))
                }
                _ => c,
            }
        })
        .collect()
}

/// Accumulated radiance per pixel, and the samples that were dropped.
#[derive(Debug)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    sums: Vec<[f64; 3]>,
    counts: Vec<u32>,
    /// The light paths' splatted sums and the number of light paths.
    splats: Option<(Vec<[f64; 3]>, u64)>,
    dropped: AtomicU64,
}

impl Film {
    /// A black film.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            sums: vec![[0.0; 3]; n],
            counts: vec![0; n],
            splats: None,
            dropped: AtomicU64::new(0),
        }
    }

    /// A film that holds `image` (row by row) at the pixels for which
    /// `rendered` holds, for integrators that make their image themselves.
    #[must_use]
    pub fn from_image(
        width: u32,
        height: u32,
        image: &[[f64; 3]],
        rendered: impl Fn(usize) -> bool,
    ) -> Self {
        let mut film = Film::new(width, height);
        for (i, c) in image.iter().enumerate() {
            if rendered(i) {
                film.add_pixel(i as u32 % width, i as u32 / width, *c, 1, 0);
            }
        }
        film
    }

    /// Counts `dropped` samples more, dropped before they reached the film.
    pub fn count_dropped(&mut self, dropped: u64) {
        self.dropped.fetch_add(dropped, Ordering::Relaxed);
    }

    /// Samples dropped as NaN or infinite.
    #[must_use]
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Adds the light paths splatted into `splats` over `samples` samples of
    /// the whole film: each light path estimates every pixel at once, so
    /// their sum is divided by the number of light paths.
    pub fn add_splats(&mut self, splats: &SplatBuffer, samples: u64) {
        if samples == 0 {
            return;
        }
        self.splats = Some((splats.sums(), samples));
        self.dropped.fetch_add(splats.dropped(), Ordering::Relaxed);
    }

    /// The image: mean radiance per pixel (black where nothing was rendered).
    #[must_use]
    pub fn image(&self) -> Vec<[f32; 3]> {
        let splats = self.splats.as_ref().map(|(s, n)| (s.as_slice(), *n));
        camera_image(&self.sums, &self.counts, splats)
    }

    /// The camera samples' sums per pixel, row by row.
    #[must_use]
    pub fn sums(&self) -> &[[f64; 3]] {
        &self.sums
    }

    /// The light paths' splatted sums and their number, if any were splatted.
    #[must_use]
    pub fn splat_sums(&self) -> Option<(&[[f64; 3]], u64)> {
        self.splats.as_ref().map(|(s, n)| (s.as_slice(), *n))
    }

    /// Adds the sum of `samples` radiance values to pixel (x, y), after
    /// those it already holds (a render in rounds), and counts `dropped`
    /// samples that never reached it (non-finite or negative).
    pub fn add_pixel(&mut self, x: u32, y: u32, sum: [f64; 3], samples: u32, dropped: u64) {
        let i = (y * self.width + x) as usize;
        for (total, s) in self.sums[i].iter_mut().zip(sum) {
            *total += s;
        }
        self.counts[i] += samples;
        self.dropped.fetch_add(dropped, Ordering::Relaxed);
    }

    /// Camera samples taken over all pixels.
    #[must_use]
    pub fn samples(&self) -> u64 {
        self.counts.iter().map(|&n| u64::from(n)).sum()
    }

    /// Each pixel's camera samples, row by row.
    #[must_use]
    pub fn counts(&self) -> &[u32] {
        &self.counts
    }

    /// Pixels rendered with at least one sample.
    #[must_use]
    pub fn rendered_pixels(&self) -> usize {
        self.counts.iter().filter(|&&n| n > 0).count()
    }
}

/// Whether a radiance sample may enter the film.
#[must_use]
pub fn is_valid(c: [f32; 3]) -> bool {
    // The three channels tested together, without a branch each (44
    // instructions per sample as `is_finite() && >= 0` per channel).
    let ok = |x: f32| is_finite(x) & (x >= 0.0);
    ok(c[0]) & ok(c[1]) & ok(c[2])
}

/// A buffer that light paths splat into from any thread (lock-free adds of
/// f64 values). Non-finite splats are dropped and counted.
#[derive(Debug)]
pub struct SplatBuffer {
    width: u32,
    height: u32,
    values: Vec<AtomicU64>,
    dropped: AtomicU64,
}

impl SplatBuffer {
    /// An empty buffer.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        let n = 3 * width as usize * height as usize;
        SplatBuffer {
            width,
            height,
            values: (0..n).map(|_| AtomicU64::new(0f64.to_bits())).collect(),
            dropped: AtomicU64::new(0),
        }
    }

    /// Adds `c` to pixel `pixel` (x, y); pixels off the film are ignored.
    pub fn splat(&self, pixel: [u32; 2], c: [f32; 3]) {
        if !is_valid(c) {
            self.dropped.fetch_add(1, Ordering::Relaxed);
            return;
        }
        let [x, y] = pixel;
        if x >= self.width || y >= self.height {
            return;
        }
        let i = 3 * (y as usize * self.width as usize + x as usize);
        for (k, v) in c.iter().enumerate() {
            let cell = &self.values[i + k];
            let mut old = cell.load(Ordering::Relaxed);
            loop {
                let new = (f64::from_bits(old) + f64::from(*v)).to_bits();
                match cell.compare_exchange_weak(old, new, Ordering::Relaxed, Ordering::Relaxed) {
                    Ok(_) => break,
                    Err(current) => old = current,
                }
            }
        }
    }

    /// The splatted sums, pixel by pixel.
    #[must_use]
    pub fn sums(&self) -> Vec<[f64; 3]> {
        self.values
            .chunks(3)
            .map(|c| [0, 1, 2].map(|k| f64::from_bits(c[k].load(Ordering::Relaxed))))
            .collect()
    }

    /// The splatted sums, scaled by `scale` (one over the number of light paths per pixel).
    #[must_use]
    pub fn image(&self, scale: f64) -> Vec<[f32; 3]> {
        self.values
            .chunks(3)
            .map(|c| {
                [0, 1, 2].map(|k| (f64::from_bits(c[k].load(Ordering::Relaxed)) * scale) as f32)
            })
            .collect()
    }

    /// Splats dropped as NaN or infinite.
    #[must_use]
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splats_add_up_across_threads_and_drop_nan() {
        let b = SplatBuffer::new(4, 4);
        std::thread::scope(|s| {
            for _ in 0..4 {
                s.spawn(|| {
                    for _ in 0..1000 {
                        b.splat([1, 2], [1.0, 2.0, 0.5]);
                    }
                });
            }
        });
        b.splat([0, 0], [f32::NAN, 0.0, 0.0]);
        b.splat([4, 0], [1.0; 3]);
        let img = b.image(1.0);
        assert_eq!(img[2 * 4 + 1], [4000.0, 8000.0, 2000.0]);
        assert_eq!(b.dropped(), 1);
    }

    #[test]
    fn valid_samples_are_finite_and_not_negative_in_every_channel() {
        for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1e-30, -3.0] {
            for k in 0..3 {
                let mut c = [0.5f32; 3];
                c[k] = bad;
                assert!(!is_valid(c), "{c:?}");
            }
        }
        for good in [0.0f32, -0.0, f32::MIN_POSITIVE, 1e-45, 2.0, f32::MAX] {
            assert!(is_valid([good, 1.0, good]), "{good}");
        }
    }
}
