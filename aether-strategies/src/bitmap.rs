//! Images for textures and environment maps, in linear RGB.

use std::path::Path;

/// A linear-RGB image.
#[derive(Clone, Debug, PartialEq)]
pub struct Bitmap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Texels, row by row from the top.
    pub texels: Vec<[f32; 3]>,
}

fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

impl Bitmap {
    /// Loads a PNG or JPEG (8-bit sRGB, made linear) or an EXR (linear).
    pub fn load(path: &Path) -> Result<Bitmap, String> {
        let is_exr = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("exr"));
        if is_exr {
            return Self::load_exr(path);
        }
        let img = image::open(path)
            .map_err(|e| format!("{}: cannot read the image: {e}", path.display()))?
            .into_rgb8();
        let (width, height) = img.dimensions();
        let texels = img
            .pixels()
            .map(|p| p.0.map(|c| srgb_to_linear(f32::from(c) / 255.0)))
            .collect();
        Ok(Bitmap {
            width,
            height,
            texels,
        })
    }

    fn load_exr(path: &Path) -> Result<Bitmap, String> {
        use exr::prelude::*;
        let image = read_first_rgba_layer_from_file(
            path,
            |r, _| (r.width(), vec![[0f32; 3]; r.width() * r.height()]),
            |(w, v): &mut (usize, Vec<[f32; 3]>),
             p: Vec2<usize>,
             (r, g, b, _a): (f32, f32, f32, f32)| v[p.y() * *w + p.x()] = [r, g, b],
        )
        .map_err(|e| format!("{}: cannot read the EXR image: {e}", path.display()))?;
        let size = image.layer_data.size;
        let texels = image.layer_data.channel_data.pixels.1;
        if texels.iter().flatten().any(|x| !x.is_finite()) {
            return Err(format!(
                "{}: the image holds NaN or infinite values",
                path.display()
            ));
        }
        Ok(Bitmap {
            width: size.0 as u32,
            height: size.1 as u32,
            texels,
        })
    }

    /// Bilinear lookup at texture coordinates (u, v), wrapping around, with
    /// v = 0 at the bottom row (as Mitsuba's bitmaps).
    #[must_use]
    pub fn lookup(&self, u: f32, v: f32) -> [f32; 3] {
        let (w, h) = (self.width as f32, self.height as f32);
        let x = u.rem_euclid(1.0) * w - 0.5;
        let y = (1.0 - v.rem_euclid(1.0)) * h - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let at = |xi: f32, yi: f32| {
            let xi = (xi as i64).rem_euclid(i64::from(self.width)) as usize;
            let yi = (yi as i64).rem_euclid(i64::from(self.height)) as usize;
            self.texels[yi * self.width as usize + xi]
        };
        let (a, b, c, d) = (
            at(x0, y0),
            at(x0 + 1.0, y0),
            at(x0, y0 + 1.0),
            at(x0 + 1.0, y0 + 1.0),
        );
        std::array::from_fn(|k| {
            (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy
        })
    }
}
