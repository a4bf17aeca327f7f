//! A part of a render as an EXR file: its own image in R, G, B (to look
//! at), each additive plane as two f32 channels (`name.hi`, the value
//! rounded to f32, and `name.lo`, the rest), and in the header the part
//! (`aether.shard`), the totals (`aether.total.NAME`, f64) and what the
//! parts share (`aether.same.NAME`, text).

use std::collections::BTreeMap;
use std::path::Path;

use exr::prelude::*;
use smallvec::SmallVec;

use crate::shard::{Partial, Shard};

const SHARD: &str = "aether.shard";
const TOTAL: &str = "aether.total.";
const SAME: &str = "aether.same.";

fn text(s: &str) -> std::result::Result<Text, String> {
    Text::new_or_none(s).ok_or_else(|| format!("'{s}' cannot be written in an EXR header"))
}

/// Writes `partial`, part `shard` of a render, with `image` as its RGB.
///
/// # Errors
/// If the file cannot be written.
pub fn write_part(
    path: &Path,
    shard: Shard,
    partial: &Partial,
    image: &[[f32; 3]],
) -> std::result::Result<(), String> {
    let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    for (k, c) in ["R", "G", "B"].iter().enumerate() {
        let v = image.iter().map(|p| p[k]).collect();
        channels.push(AnyChannel::new(*c, FlatSamples::F32(v)));
    }
    for (name, plane) in &partial.planes {
        let hi: Vec<f32> = plane.iter().map(|&v| v as f32).collect();
        let lo = plane
            .iter()
            .zip(&hi)
            .map(|(&v, &h)| (v - f64::from(h)) as f32)
            .collect();
        channels.push(AnyChannel::new(
            text(&format!("{name}.hi"))?,
            FlatSamples::F32(hi),
        ));
        channels.push(AnyChannel::new(
            text(&format!("{name}.lo"))?,
            FlatSamples::F32(lo),
        ));
    }
    let mut attributes = LayerAttributes::default();
    let other = &mut attributes.other;
    other.insert(
        text(SHARD)?,
        AttributeValue::Text(text(&shard.to_string())?),
    );
    for (name, total) in &partial.totals {
        other.insert(
            text(&format!("{TOTAL}{name}"))?,
            AttributeValue::F64(*total),
        );
    }
    for (name, value) in &partial.same {
        other.insert(
            text(&format!("{SAME}{name}"))?,
            AttributeValue::Text(text(value)?),
        );
    }
    let size = (partial.width as usize, partial.height as usize);
    let layer = Layer::new(
        size,
        attributes,
        Encoding::FAST_LOSSLESS,
        AnyChannels::sort(channels),
    );
    Image::from_layer(layer)
        .write()
        .to_file(path)
        .map_err(|e| format!("{}: cannot write the part: {e}", path.display()))
}

/// Reads a part written by [`write_part`].
///
/// # Errors
/// If the file is not an EXR image, or not a part of a render (no part in
/// its header, a plane without its other half, a truncated file).
pub fn read_part(path: &Path) -> std::result::Result<(Shard, Partial), String> {
    let image =
        crate::output::read_channels(path).map_err(|e| format!("not a readable EXR image: {e}"))?;
    let layer = &image.layer_data;
    let header: BTreeMap<String, &AttributeValue> = layer
        .attributes
        .other
        .iter()
        .chain(&image.attributes.other)
        .map(|(k, v)| (k.to_string(), v))
        .collect();
    let shard = match header.get(SHARD) {
        Some(AttributeValue::Text(t)) => t
            .to_string()
            .parse::<Shard>()
            .map_err(|e| format!("{SHARD}: {e}"))?,
        _ => {
            return Err(format!(
                "no {SHARD} in its header: an image, not a part of a render"
            ));
        }
    };
    let (w, h) = (layer.size.width(), layer.size.height());
    let mut partial = Partial::new(w as u32, h as u32);
    for (key, value) in &header {
        if let (Some(name), AttributeValue::F64(v)) = (key.strip_prefix(TOTAL), value) {
            partial.totals.insert(name.to_string(), *v);
        }
        if let (Some(name), AttributeValue::Text(t)) = (key.strip_prefix(SAME), value) {
            partial.same.insert(name.to_string(), t.to_string());
        }
    }
    let mut halves: BTreeMap<String, [Option<Vec<f32>>; 2]> = BTreeMap::new();
    for c in &layer.channel_data.list {
        let name = c.name.to_string();
        let (base, half) = match (name.strip_suffix(".hi"), name.strip_suffix(".lo")) {
            (Some(b), _) => (b.to_string(), 0),
            (_, Some(b)) => (b.to_string(), 1),
            _ => continue,
        };
        let FlatSamples::F32(v) = &c.sample_data else {
            return Err(format!("channel {name} is not 32-bit float"));
        };
        halves.entry(base).or_default()[half] = Some(v.clone());
    }
    for (name, [hi, lo]) in halves {
        let (Some(hi), Some(lo)) = (hi, lo) else {
            return Err(format!("the plane {name} has one of its two channels only"));
        };
        let plane = hi
            .iter()
            .zip(&lo)
            .map(|(&a, &b)| f64::from(a) + f64::from(b))
            .collect();
        partial.planes.insert(name, plane);
    }
    Ok((shard, partial))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_part_reads_back_with_its_sums_to_48_bits() {
        let mut p = Partial::new(3, 2);
        let sums: Vec<[f64; 3]> = (0..6)
            .map(|i| [1.0 / 3.0 + f64::from(i), 1e9 + 0.1, 0.0])
            .collect();
        p.put_rgb("sum", &sums);
        p.planes.insert("samples".into(), vec![4_000_000_001.0; 6]);
        p.totals.insert("light_paths".into(), 123_456_789_012.0);
        p.same.insert("seed".into(), "7".into());
        let dir = std::env::temp_dir().join(format!("aether-part-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("p.exr");
        let shard = Shard { index: 1, count: 3 };
        write_part(&file, shard, &p, &[[0.5; 3]; 6]).unwrap();
        let (s, q) = read_part(&file).unwrap();
        assert_eq!(s, shard);
        assert_eq!(
            (q.totals.clone(), q.same.clone()),
            (p.totals.clone(), p.same.clone())
        );
        for (name, plane) in &p.planes {
            for (a, b) in plane.iter().zip(&q.planes[name]) {
                assert!((a - b).abs() <= a.abs() * 2f64.powi(-46), "{name}: {a} {b}");
            }
        }
        // An image that is not a part, and a truncated part, are refused.
        crate::output::write_exr(&dir.join("i.exr"), 3, 2, &[[0.5; 3]; 6], 1, 0.0).unwrap();
        assert!(
            read_part(&dir.join("i.exr"))
                .unwrap_err()
                .contains("not a part")
        );
        let bytes = std::fs::read(&file).unwrap();
        std::fs::write(dir.join("t.exr"), &bytes[..bytes.len() / 2]).unwrap();
        assert!(read_part(&dir.join("t.exr")).is_err());
    }
}

/// What [`merge_files`] wrote.
#[derive(Debug)]
pub struct MergeReport {
    /// Files written.
    pub written: Vec<std::path::PathBuf>,
    /// The fraction of the render's parts merged.
    pub fraction: f64,
    /// Camera samples (or mutations) the merge holds.
    pub samples: f64,
}

/// Merges the parts in `inputs` into the image `out` (an EXR, with its PNG
/// preview and, for gradient-domain tracing, the primal and gradient images
/// beside it), refusing an existing `out` unless `force`.
///
/// # Errors
/// A part that cannot be read, parts that do not belong together or are
/// missing (unless `partial`), or an output that exists or cannot be written.
pub fn merge_files(
    out: &Path,
    inputs: &[std::path::PathBuf],
    partial: bool,
    force: bool,
    exposure: f32,
) -> std::result::Result<MergeReport, String> {
    let files = crate::output::OutputFiles::for_name(out).map_err(|e| e.to_string())?;
    for f in [&files.exr, &files.png] {
        if f.exists() && !force {
            return Err(format!("{}: exists (--force overwrites it)", f.display()));
        }
    }
    files.check_writable()?;
    let mut merger: Option<crate::shard::Merger> = None;
    for path in inputs {
        let (shard, p) = read_part(path).map_err(|e| format!("{}: {e}", path.display()))?;
        match &mut merger {
            None => merger = Some(crate::shard::Merger::new(path.clone(), shard, p)),
            Some(m) => m.add(path, shard, &p).map_err(|e| e.to_string())?,
        }
    }
    let merger = merger.ok_or_else(|| crate::shard::MergeError::Nothing.to_string())?;
    let merged = merger.finish(partial).map_err(|e| e.to_string())?;
    let finished = crate::parts::finish(&merged.partial)?;
    let p = &merged.partial;
    let (w, h) = (p.width, p.height);
    let mut written = vec![files.exr.clone(), files.png.clone()];
    match p.plane("samples") {
        Some(counts) if p.same.get("integrator").is_some_and(|i| i != "gpt") => {
            let counts: Vec<u32> = counts.iter().map(|&n| n as u32).collect();
            crate::output::write_exr_with_counts(&files.exr, w, h, &finished.image, &counts, 0.0)?;
        }
        _ => crate::output::write_exr(&files.exr, w, h, &finished.image, 0, 0.0)?,
    }
    crate::output::write_png(&files.png, w, h, &finished.image, exposure)?;
    for (suffix, image) in &finished.beside {
        let stem = files
            .exr
            .file_stem()
            .map_or("out".into(), |s| s.to_string_lossy());
        let path = files.exr.with_file_name(format!("{stem}-{suffix}.exr"));
        crate::output::write_exr(&path, w, h, image, 0, 0.0)?;
        written.push(path);
    }
    let samples = p
        .plane("samples")
        .map_or(p.total("mutations"), |c| c.iter().sum());
    Ok(MergeReport {
        written,
        fraction: merged.fraction,
        samples,
    })
}
