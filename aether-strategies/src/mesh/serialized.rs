//! Mitsuba's `.serialized` meshes: a concatenation of zlib-compressed
//! meshes followed by a table of their offsets.

use std::io::Read;
use std::path::Path;

use flate2::read::ZlibDecoder;
use glam::{Vec2, Vec3};

use super::{MeshError, TriangleMesh};
use crate::files::{MAX_MESH_BYTES, read_regular};

const MAGIC: u16 = 0x041C;
const HAS_NORMALS: u32 = 0x0001;
const HAS_UVS: u32 = 0x0002;
const HAS_COLORS: u32 = 0x0008;
const SINGLE_PRECISION: u32 = 0x1000;
const DOUBLE_PRECISION: u32 = 0x2000;

fn format_error(path: &Path, message: impl Into<String>) -> MeshError {
    MeshError::Format {
        path: path.to_owned(),
        message: message.into(),
    }
}

/// The file's bytes and the offsets of its meshes.
fn table(path: &Path) -> Result<(Vec<u8>, u16, Vec<usize>), MeshError> {
    let bytes = read_regular(path, MAX_MESH_BYTES).map_err(MeshError::File)?;
    let u16_at = |o: usize| {
        bytes
            .get(o..o + 2)
            .map(|b| u16::from_le_bytes([b[0], b[1]]))
    };
    if u16_at(0) != Some(MAGIC) {
        return Err(format_error(
            path,
            "not a Mitsuba .serialized file (bad magic number)",
        ));
    }
    let version = u16_at(2).unwrap_or(0);
    if version != 3 && version != 4 {
        return Err(format_error(
            path,
            format!("unsupported .serialized version {version} (3 and 4 are read)"),
        ));
    }
    let n = bytes.len();
    let count = bytes
        .get(n.saturating_sub(4)..)
        .filter(|b| b.len() == 4)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
        .ok_or_else(|| format_error(path, "truncated file: no mesh count"))?;
    let width = if version == 4 { 8 } else { 4 };
    let start = n.checked_sub(4 + width * count).ok_or_else(|| {
        format_error(
            path,
            format!("truncated file: the offset table of {count} meshes does not fit"),
        )
    })?;
    let offsets = bytes[start..n - 4]
        .chunks_exact(width)
        .map(|c| {
            if width == 8 {
                u64::from_le_bytes(c.try_into().expect("8 bytes")) as usize
            } else {
                u32::from_le_bytes(c.try_into().expect("4 bytes")) as usize
            }
        })
        .collect::<Vec<_>>();
    if let Some(bad) = offsets.iter().find(|&&o| o + 4 > start) {
        return Err(format_error(
            path,
            format!("mesh offset {bad} lies outside the file"),
        ));
    }
    Ok((bytes, version, offsets))
}

/// The number of meshes in a `.serialized` file.
pub fn serialized_mesh_count(path: &Path) -> Result<usize, MeshError> {
    Ok(table(path)?.2.len())
}

/// A little-endian reader over a decompressed mesh that reports truncation.
struct Cursor<'a> {
    data: &'a [u8],
    at: usize,
}

impl Cursor<'_> {
    fn take(&mut self, n: usize) -> Option<&[u8]> {
        let s = self.data.get(self.at..self.at.checked_add(n)?)?;
        self.at += n;
        Some(s)
    }
    fn u32(&mut self) -> Option<u32> {
        self.take(4)
            .map(|b| u32::from_le_bytes(b.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> Option<u64> {
        self.take(8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8 bytes")))
    }
    fn real(&mut self, double: bool) -> Option<f32> {
        if double {
            self.take(8)
                .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
        } else {
            self.take(4)
                .map(|b| f32::from_le_bytes(b.try_into().expect("4 bytes")))
        }
    }
    fn vec3(&mut self, double: bool) -> Option<Vec3> {
        Some(Vec3::new(
            self.real(double)?,
            self.real(double)?,
            self.real(double)?,
        ))
    }
}

/// Loads mesh `shape_index` of a Mitsuba `.serialized` file (versions 3 and 4).
pub fn load_serialized(path: &Path, shape_index: usize) -> Result<TriangleMesh, MeshError> {
    let (bytes, version, offsets) = table(path)?;
    let Some(&offset) = offsets.get(shape_index) else {
        return Err(format_error(
            path,
            format!(
                "shapeIndex {shape_index} is out of range: the file holds {} meshes",
                offsets.len()
            ),
        ));
    };
    let header = u16::from_le_bytes([bytes[offset], bytes[offset + 1]]);
    if header != MAGIC {
        return Err(format_error(
            path,
            format!("mesh {shape_index}: bad magic number at offset {offset}"),
        ));
    }
    let mut data = Vec::new();
    ZlibDecoder::new(&bytes[offset + 4..])
        .read_to_end(&mut data)
        .map_err(|e| {
            format_error(
                path,
                format!("mesh {shape_index}: the compressed stream is corrupt: {e}"),
            )
        })?;
    let truncated = || {
        format_error(
            path,
            format!("mesh {shape_index}: the decompressed data ends early"),
        )
    };
    let mut c = Cursor { data: &data, at: 0 };
    let flags = c.u32().ok_or_else(truncated)?;
    let double = match (flags & SINGLE_PRECISION != 0, flags & DOUBLE_PRECISION != 0) {
        (true, false) => false,
        (false, true) => true,
        _ => {
            return Err(format_error(
                path,
                format!(
                    "mesh {shape_index}: flags {flags:#x} name neither single nor double precision"
                ),
            ));
        }
    };
    let mut name = String::new();
    if version == 4 {
        let end = data[c.at..]
            .iter()
            .position(|&b| b == 0)
            .ok_or_else(truncated)?;
        name = String::from_utf8_lossy(&data[c.at..c.at + end]).into_owned();
        c.at += end + 1;
    }
    let vertices = c.u64().ok_or_else(truncated)? as usize;
    let triangles = c.u64().ok_or_else(truncated)? as usize;
    // A size larger than the data could hold is corrupt, not a reason to allocate.
    if vertices.saturating_mul(12) > data.len() || triangles.saturating_mul(12) > data.len() {
        return Err(format_error(
            path,
            format!(
                "mesh {shape_index}: {vertices} vertices and {triangles} triangles do not fit in the data"
            ),
        ));
    }
    let mut mesh = TriangleMesh {
        name: if name.is_empty() {
            format!("mesh {shape_index}")
        } else {
            name
        },
        ..TriangleMesh::default()
    };
    mesh.positions = (0..vertices)
        .map(|_| c.vec3(double))
        .collect::<Option<_>>()
        .ok_or_else(truncated)?;
    if flags & HAS_NORMALS != 0 {
        mesh.normals = (0..vertices)
            .map(|_| c.vec3(double).map(|n| n.normalize_or_zero()))
            .collect::<Option<_>>()
            .ok_or_else(truncated)?;
    }
    if flags & HAS_UVS != 0 {
        mesh.uvs = (0..vertices)
            .map(|_| Some(Vec2::new(c.real(double)?, c.real(double)?)))
            .collect::<Option<_>>()
            .ok_or_else(truncated)?;
    }
    if flags & HAS_COLORS != 0 {
        c.take(vertices * 3 * if double { 8 } else { 4 })
            .ok_or_else(truncated)?;
    }
    mesh.triangles = (0..triangles)
        .map(|_| Some([c.u32()?, c.u32()?, c.u32()?]))
        .collect::<Option<_>>()
        .ok_or_else(truncated)?;
    mesh.validate(path)?;
    Ok(mesh)
}
