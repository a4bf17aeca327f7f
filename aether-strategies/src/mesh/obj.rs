use std::path::{Path, PathBuf};

use glam::{Vec2, Vec3};

use super::{MeshError, TriangleMesh};
use crate::files::{MAX_IMAGE_BYTES, MAX_MESH_BYTES, open_regular};

/// A material from an OBJ file's MTL library: its diffuse colour and map.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjMaterial {
    /// Its name in the library.
    pub name: String,
    /// `Kd`, or 0.5 grey.
    pub diffuse: [f32; 3],
    /// `map_Kd`, relative to the OBJ file's folder.
    pub diffuse_map: Option<PathBuf>,
}

/// Loads every object of a Wavefront OBJ file into one mesh (as Mitsuba's
/// `obj` shape does), triangulating polygons. Texture coordinates keep the
/// OBJ convention (v up).
pub fn load_obj(path: &Path) -> Result<TriangleMesh, MeshError> {
    load_obj_with_materials(path).map(|(mesh, _)| mesh)
}

/// As [`load_obj`], with the materials of the file's MTL library (none if
/// it names no library or the library cannot be read).
pub fn load_obj_with_materials(path: &Path) -> Result<(TriangleMesh, Vec<ObjMaterial>), MeshError> {
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ..tobj::LoadOptions::default()
    };
    let mut reader = open_regular(path, MAX_MESH_BYTES).map_err(MeshError::File)?;
    let folder = path.parent().unwrap_or(Path::new("."));
    // The library is read as the mesh is: a device named by `mtllib` is
    // refused like one named as the mesh (and then no material is used).
    let library = |name: &Path| {
        let mut reader = open_regular(&folder.join(name), MAX_IMAGE_BYTES)
            .map_err(|_| tobj::LoadError::OpenFileFailed)?;
        tobj::load_mtl_buf(&mut reader)
    };
    let (models, materials) =
        tobj::load_obj_buf(&mut reader, &options, library).map_err(|e| MeshError::Format {
            path: path.to_owned(),
            message: format!("not a valid OBJ file: {e}"),
        })?;
    let mut mesh = TriangleMesh {
        name: path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default(),
        ..TriangleMesh::default()
    };
    let all_normals = models.iter().all(|m| !m.mesh.normals.is_empty());
    let all_uvs = models.iter().all(|m| !m.mesh.texcoords.is_empty());
    for model in &models {
        let m = &model.mesh;
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(
            m.positions
                .chunks_exact(3)
                .map(|p| Vec3::new(p[0], p[1], p[2])),
        );
        if all_normals {
            mesh.normals.extend(
                m.normals
                    .chunks_exact(3)
                    .map(|n| Vec3::new(n[0], n[1], n[2]).normalize_or_zero()),
            );
        }
        if all_uvs {
            mesh.uvs
                .extend(m.texcoords.chunks_exact(2).map(|t| Vec2::new(t[0], t[1])));
        }
        mesh.triangles.extend(
            m.indices
                .chunks_exact(3)
                .map(|t| [base + t[0], base + t[1], base + t[2]]),
        );
    }
    if mesh.triangles.is_empty() {
        return Err(MeshError::Format {
            path: path.to_owned(),
            message: "the OBJ file holds no faces".to_string(),
        });
    }
    mesh.validate(path)?;
    let materials = materials
        .unwrap_or_default()
        .into_iter()
        .map(|m| ObjMaterial {
            name: m.name,
            diffuse: m.diffuse.unwrap_or([0.5; 3]),
            diffuse_map: m.diffuse_texture.map(|t| folder.join(t)),
        })
        .collect();
    Ok((mesh, materials))
}
