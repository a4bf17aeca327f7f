//! The (s, t) technique images of BDPT, weighted by MIS and unweighted, as
//! in Veach's pyramid: row s + t − 1 holds the paths of that many edges.

use std::path::Path;

use glam::DVec3;

use crate::film::SplatBuffer;
use crate::output::write_exr;

/// One weighted and one unweighted image per (s, t) technique with
/// s + t ≤ `max_vertices` (s = 0, light paths that reach a thin lens,
/// included). Costs 48 bytes a pixel a technique: meant for small films.
#[derive(Debug)]
pub struct TechniqueImages {
    width: u32,
    height: u32,
    max_vertices: usize,
    weighted: Vec<SplatBuffer>,
    unweighted: Vec<SplatBuffer>,
}

impl TechniqueImages {
    /// Black images for paths of 2 to `max_vertices` vertices.
    #[must_use]
    pub fn new(width: u32, height: u32, max_vertices: usize) -> Self {
        let count = ((max_vertices + 1) * (max_vertices + 2) / 2).saturating_sub(3);
        let buffers = || {
            (0..count)
                .map(|_| SplatBuffer::new(width, height))
                .collect()
        };
        TechniqueImages {
            width,
            height,
            max_vertices,
            weighted: buffers(),
            unweighted: buffers(),
        }
    }

    /// Position of (s, t) in the pyramid: rows by length n = s + t ≥ 2,
    /// each row holding s = 0 ..= n.
    fn index(s: usize, t: usize) -> usize {
        let n = s + t;
        n * (n + 1) / 2 - 3 + s
    }

    /// Records a contribution of technique (s, t) to `pixel`. Camera-path
    /// contributions (`splatted` false) count once per pixel sample, light
    /// paths once per sample of the whole film; both are stored so that
    /// one division by the film's sample count gives the image.
    pub fn add(
        &self,
        s: usize,
        t: usize,
        pixel: [u32; 2],
        weighted: DVec3,
        unweighted: DVec3,
        splatted: bool,
    ) {
        if s + t < 2 || s + t > self.max_vertices {
            return;
        }
        let scale = if splatted {
            1.0
        } else {
            f64::from(self.width) * f64::from(self.height)
        };
        let i = Self::index(s, t);
        self.weighted[i].splat(pixel, (weighted * scale).as_vec3().to_array());
        self.unweighted[i].splat(pixel, (unweighted * scale).as_vec3().to_array());
    }

    /// The weighted and unweighted image of (s, t) after `samples` samples
    /// of the whole film (pixels × samples per pixel).
    #[must_use]
    pub fn images(&self, s: usize, t: usize, samples: u64) -> Option<[Vec<[f32; 3]>; 2]> {
        if s + t < 2 || s + t > self.max_vertices || samples == 0 {
            return None;
        }
        let i = Self::index(s, t);
        let scale = 1.0 / samples as f64;
        Some([
            self.weighted[i].image(scale),
            self.unweighted[i].image(scale),
        ])
    }

    /// Writes `s{s}_t{t}.exr` and `s{s}_t{t}_unweighted.exr` into `dir`
    /// (s = 0 only for a thin lens, which light paths can reach).
    ///
    /// # Errors
    /// If the folder or a file cannot be written.
    pub fn write(&self, dir: &Path, samples: u64, spp: u32, lens: bool) -> Result<(), String> {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        for n in 2..=self.max_vertices {
            for s in usize::from(!lens)..=n {
                let [w, u] = self.images(s, n - s, samples).expect("in the pyramid");
                let name = format!("s{s}_t{}", n - s);
                let (wf, uf) = (
                    dir.join(format!("{name}.exr")),
                    dir.join(format!("{name}_unweighted.exr")),
                );
                write_exr(&wf, self.width, self.height, &w, spp, 0.0)?;
                write_exr(&uf, self.width, self.height, &u, spp, 0.0)?;
            }
        }
        Ok(())
    }
}
