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
    insert_header(&mut image.attributes.other, f64::from(spp), seconds);
    image
        .write()
        .to_file(path)
        .map_err(|e| format!("{}: cannot write the EXR image: {e}", path.display()))
}

/// Writes linear RGB to an EXR file with each pixel's sample count in a
/// `samples` channel (u32) and their mean as the `spp` attribute (and, as
/// a float, `sppMean`): the true counts of a render that was stopped.
pub fn write_exr_with_counts(
    path: &Path,
    width: u32,
    height: u32,
    rgb: &[[f32; 3]],
    counts: &[u32],
    seconds: f64,
) -> std::result::Result<(), String> {
    let w = width as usize;
    let channels = SpecificChannels::build()
        .with_channel("B")
        .with_channel("G")
        .with_channel("R")
        .with_channel("samples")
        .with_pixel_fn(|Vec2(x, y)| {
            let (c, n): ([f32; 3], u32) = (rgb[y * w + x], counts[y * w + x]);
            (c[2], c[1], c[0], n)
        });
    let mut image = Image::from_channels((w, height as usize), channels);
    let total: u64 = counts.iter().map(|&n| u64::from(n)).sum();
    let mean = total as f64 / counts.len().max(1) as f64;
    insert_header(&mut image.attributes.other, mean, seconds);
    image
        .write()
        .to_file(path)
        .map_err(|e| format!("{}: cannot write the EXR image: {e}", path.display()))
}

fn insert_header(
    other: &mut std::collections::HashMap<Text, AttributeValue>,
    spp: f64,
    seconds: f64,
) {
    let rounded = spp.round().clamp(0.0, f64::from(i32::MAX)) as i32;
    other.insert(Text::new_or_panic("spp"), AttributeValue::I32(rounded));
    other.insert(Text::new_or_panic("sppMean"), AttributeValue::F64(spp));
    other.insert(
        Text::new_or_panic("renderTimeSeconds"),
        AttributeValue::F64(seconds),
    );
}

/// Where a render's images go: the EXR (linear, HDR) and its sRGB PNG
/// preview, one named by `-o` and the other beside it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputFiles {
    /// The EXR image.
    pub exr: std::path::PathBuf,
    /// The PNG preview.
    pub png: std::path::PathBuf,
}

/// An output name whose extension is neither `.exr` nor `.png`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownFormat(pub std::path::PathBuf);

impl std::fmt::Display for UnknownFormat {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: the output is written as EXR (name it .exr; the PNG preview goes beside it) or as a PNG preview (name it .png; the EXR goes beside it); no other format is written",
            self.0.display()
        )
    }
}

impl std::error::Error for UnknownFormat {}

impl OutputFiles {
    /// The files for the output name `path`: `x.exr` gives `x.exr` and
    /// `x.png`, and so does `x.png`, so that the HDR image is never lost.
    ///
    /// # Errors
    /// For any other extension.
    pub fn for_name(path: &Path) -> std::result::Result<Self, UnknownFormat> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_lowercase());
        match ext.as_deref() {
            Some("exr" | "png") => Ok(OutputFiles {
                exr: path.with_extension("exr"),
                png: path.with_extension("png"),
            }),
            _ => Err(UnknownFormat(path.to_owned())),
        }
    }

    /// Checks, before a render, that both files can be written: each is
    /// opened for appending (created if missing, then removed again), so
    /// that a bad path is found before hours of rendering, not after.
    ///
    /// # Errors
    /// The first file that cannot be written, and why.
    pub fn check_writable(&self) -> std::result::Result<(), String> {
        for path in [&self.exr, &self.png] {
            if path.is_dir() {
                return Err(format!("{}: is a directory, not a file", path.display()));
            }
            let existed = path.exists();
            std::fs::OpenOptions::new()
                .append(true)
                .create(true)
                .open(path)
                .map_err(|e| format!("{}: cannot be written: {e}", path.display()))?;
            if !existed {
                // The file was only a probe; a failure to remove it is harmless.
                let _ = std::fs::remove_file(path);
            }
        }
        Ok(())
    }
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
        // With counts, the colours read back the same and the mean is kept.
        let counted = dir.join("c.exr");
        write_exr_with_counts(&counted, 3, 2, &rgb, &[1, 2, 3, 4, 5, 6], 0.5).unwrap();
        assert_eq!(read_exr(&counted).unwrap(), (3, 2, rgb.clone()));
        assert_eq!(read_counts(&counted).unwrap(), Some(vec![1, 2, 3, 4, 5, 6]));
        assert_eq!(read_counts(&path).unwrap(), None);
        let meta = exr::meta::MetaData::read_from_file(&counted, false).unwrap();
        let header = &meta.headers[0];
        assert_eq!(header.channels.list.len(), 4);
        let key = Text::new_or_panic("sppMean");
        let mean = header.own_attributes.other.get(&key);
        let mean = mean.or_else(|| header.shared_attributes.other.get(&key));
        assert_eq!(mean, Some(&AttributeValue::F64(3.5)));
    }

    #[test]
    fn outputs_are_named_by_extension_and_checked_first() {
        let f = OutputFiles::for_name(Path::new("a/p.png")).unwrap();
        assert_eq!(
            (f.exr.to_str(), f.png.to_str()),
            (Some("a/p.exr"), Some("a/p.png"))
        );
        assert!(OutputFiles::for_name(Path::new("x.EXR")).is_ok());
        let e = OutputFiles::for_name(Path::new("a.jpg")).unwrap_err();
        assert!(e.to_string().contains("a.jpg"), "{e}");
        assert!(OutputFiles::for_name(Path::new("noext")).is_err());
        let missing = OutputFiles::for_name(Path::new("/nonexistent-dir/x.exr")).unwrap();
        let e = missing.check_writable().unwrap_err();
        assert!(e.contains("/nonexistent-dir/x.exr"), "{e}");
        let dir = std::env::temp_dir().join(format!("aether-check-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let ok = OutputFiles::for_name(&dir.join("o.exr")).unwrap();
        ok.check_writable().unwrap();
        assert!(!ok.exr.exists(), "the probe leaves no file behind");
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

/// Reads the `samples` channel of an EXR file written by
/// [`write_exr_with_counts`]: each pixel's sample count, row by row, or
/// `None` if the file has no such channel.
///
/// # Errors
/// If the file cannot be read as an EXR image.
pub fn read_counts(path: &Path) -> std::result::Result<Option<Vec<u32>>, String> {
    let image = read_channels(path)
        .map_err(|e| format!("{}: cannot read the EXR image: {e}", path.display()))?;
    let channels = &image.layer_data.channel_data.list;
    Ok(channels
        .iter()
        .find(|c| c.name == Text::new_or_panic("samples"))
        .and_then(|c| match &c.sample_data {
            FlatSamples::U32(v) => Some(v.clone()),
            _ => None,
        }))
}

/// Every channel of the first layer of an EXR file, with its attributes.
pub(crate) fn read_channels(
    path: &Path,
) -> std::result::Result<Image<Layer<AnyChannels<FlatSamples>>>, exr::error::Error> {
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
}
