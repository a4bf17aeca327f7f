//! Reading and writing images: EXR (f32 linear RGB, with spp and render time in the
//! header) and a PNG preview (sRGB, with an exposure).

use std::path::Path;

use exr::prelude::*;

/// Writes linear RGB to an EXR file.
pub fn write_exr(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    spp: u32,
    seconds: f64,
) -> std::result::Result<(), String> {
    let w = width as usize;
    let channels = SpecificChannels::rgb(|Vec2(x, y)| {
        let c: [f32; 3] = rgb[y * w + x];
        (c[0], c[1], c[2])
    });
    let mut image = Image::from_channels((w, height as usize), channels);
    image
        .attributes
        .other
        .insert(Text::new_or_panic("spp"), AttributeValue::I32(spp as i32));
    image.attributes.other.insert(
        Text::new_or_panic("renderTimeSeconds"),
        AttributeValue::F64(seconds),
    );
    image
        .write()
        .to_file(path)
        .map_err(|e| format!("{}: cannot write the EXR image: {e}", path.display()))
}

fn to_srgb(c: f32) -> u8 {
    let c = c.clamp(0.0, 1.0);
    let s = if c <= 0.003_130_8 {
        12.92 * c
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// Writes an sRGB PNG preview, scaled by 2^`exposure`.
pub fn write_png(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    exposure: f32,
) -> std::result::Result<(), String> {
    let scale = exposure.exp2();
    let bytes: Vec<u8> = rgb
        .iter()
        .flat_map(|c| c.map(|x| to_srgb(x * scale)))
        .collect();
    image::save_buffer(path, &bytes, width, height, image::ColorType::Rgb8)
        .map_err(|e| format!("{}: cannot write the PNG preview: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trip_keeps_values_and_header() {
        let dir = std::env::temp_dir().join(format!("aether-out-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("t.exr");
        let rgb: Vec<[f32; 3]> = (0..6).map(|i| [i as f32, 0.5, 2.0]).collect();
        write_exr(&path, 3, 2, &rgb, 16, 1.5).unwrap();
        let image = read_first_rgba_layer_from_file(
            &path,
            |r, _| vec![[0f32; 3]; r.width() * r.height()],
            |v: &mut Vec<[f32; 3]>, p: Vec2<usize>, (r, g, b, _a): (f32, f32, f32, f32)| {
                v[p.y() * 3 + p.x()] = [r, g, b]
            },
        )
        .unwrap();
        assert_eq!(image.layer_data.channel_data.pixels, rgb);
        let header = &image.layer_data.attributes.other;
        assert_eq!(
            header.get(&Text::new_or_panic("spp")),
            Some(&AttributeValue::I32(16))
        );
        assert_eq!(
            header.get(&Text::new_or_panic("renderTimeSeconds")),
            Some(&AttributeValue::F64(1.5))
        );
        write_png(&dir.join("t.png"), 3, 2, &rgb, 0.0).unwrap();
        assert!(std::fs::metadata(dir.join("t.png")).unwrap().len() > 0);
    }
}

/// Reads the RGB channels of an EXR file: width, height and pixels in rows.
///
/// # Errors
/// If the file cannot be read or has no RGB layer.
pub fn read_exr(path: &Path) -> std::result::Result<(u32, u32, Vec<[f32; 3]>), String> {
    let image = read_first_rgba_layer_from_file(
        path,
        |size, _| (size.width(), vec![[0.0f32; 3]; size.area()]),
        |(w, pixels), Vec2(x, y), (r, g, b, _a): (f32, f32, f32, f32)| {
            pixels[y * *w + x] = [r, g, b];
        },
    )
    .map_err(|e| format!("{}: cannot read the EXR image: {e}", path.display()))?;
    let size = image.layer_data.size;
    let (_, pixels) = image.layer_data.channel_data.pixels;
    Ok((size.width() as u32, size.height() as u32, pixels))
}

/// The comparison of an image with a reference of the same size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Comparison {
    /// Mean of the image over pixels and channels.
    pub mean: f64,
    /// Mean of the reference.
    pub reference_mean: f64,
    /// Root-mean-square difference over pixels and channels.
    pub rmse: f64,
    /// Relative mean squared error: the mean of (x − r)² / (r² + 0.01) over
    /// pixels and channels, which bright pixels do not dominate.
    pub rel_mse: f64,
}

impl Comparison {
    /// Compares `image` with `reference`; `None` if their sizes differ.
    #[must_use]
    pub fn of(image: &[[f32; 3]], reference: &[[f32; 3]]) -> Option<Comparison> {
        if image.len() != reference.len() || image.is_empty() {
            return None;
        }
        let n = 3.0 * image.len() as f64;
        let (mut a, mut b, mut d2, mut rel) = (0.0, 0.0, 0.0, 0.0);
        for (p, q) in image.iter().zip(reference) {
            for k in 0..3 {
                let (x, y) = (f64::from(p[k]), f64::from(q[k]));
                a += x;
                b += y;
                d2 += (x - y) * (x - y);
                rel += (x - y) * (x - y) / (y * y + 0.01);
            }
        }
        Some(Comparison {
            mean: a / n,
            reference_mean: b / n,
            rmse: (d2 / n).sqrt(),
            rel_mse: rel / n,
        })
    }

    /// (mean − reference mean) / reference mean.
    #[must_use]
    pub fn relative_difference(&self) -> f64 {
        (self.mean - self.reference_mean) / self.reference_mean
    }
}
