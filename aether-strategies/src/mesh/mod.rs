//! Triangle meshes and their loaders: Wavefront OBJ and Mitsuba's
//! `.serialized` format.

mod obj;
mod plane;
mod serialized;

use std::fmt;
use std::path::{Path, PathBuf};

use glam::{Mat4, Vec2, Vec3};

pub use obj::{ObjMaterial, load_obj, load_obj_with_materials};
pub use plane::{TrianglePlane, triangle_normal};
pub use serialized::{load_serialized, serialized_mesh_count};

/// A triangle mesh in world or object space.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriangleMesh {
    /// Name, from the file (an OBJ object, a `.serialized` mesh name).
    pub name: String,
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals, or empty.
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates, or empty.
    pub uvs: Vec<Vec2>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
}

/// The largest coordinate a mesh vertex or a sphere may have, in world
/// space: the BVH builder and the f32 ray arithmetic square extents, which
/// must stay finite (1e12² = 1e24, far below f32's 3.4e38).
pub const MAX_COORDINATE: f32 = 1e12;

/// Why a mesh could not be loaded. Every variant names the file.
#[derive(Debug)]
pub enum MeshError {
    /// The file could not be opened or read, or is not a regular file of a
    /// mesh's size.
    File(crate::files::FileError),
    /// The file is not a valid mesh of its format.
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong, and where.
        message: String,
    },
    /// A vertex position is NaN or infinite.
    NonFinite {
        /// The file.
        path: PathBuf,
        /// The mesh in the file.
        mesh: String,
        /// The vertex.
        vertex: usize,
    },
    /// A vertex position is beyond [`MAX_COORDINATE`] (after the shape's
    /// transform, where there is one).
    OutOfBounds {
        /// The file.
        path: PathBuf,
        /// The mesh in the file.
        mesh: String,
        /// The vertex.
        vertex: usize,
        /// Its position.
        position: [f32; 3],
    },
    /// A triangle refers to a vertex that does not exist.
    IndexOutOfRange {
        /// The file.
        path: PathBuf,
        /// The mesh in the file.
        mesh: String,
        /// The triangle.
        triangle: usize,
        /// The index it holds.
        index: u32,
        /// The number of vertices.
        vertices: usize,
    },
}

impl fmt::Display for MeshError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            MeshError::File(e) => write!(f, "cannot read the mesh: {e}"),
            MeshError::OutOfBounds {
                path,
                mesh,
                vertex,
                position,
            } => write!(
                f,
                "{}: mesh '{mesh}': vertex {vertex} at {position:?} is beyond ±{MAX_COORDINATE:e}, the largest coordinate the ray tracer handles",
                path.display()
            ),
            MeshError::Format { path, message } => write!(f, "{}: {message}", path.display()),
            MeshError::NonFinite { path, mesh, vertex } => {
                write!(
                    f,
                    "{}: mesh '{mesh}': vertex {vertex} has a NaN or infinite coordinate",
                    path.display()
                )
            }
            MeshError::IndexOutOfRange {
                path,
                mesh,
                triangle,
                index,
                vertices,
            } => write!(
                f,
                "{}: mesh '{mesh}': triangle {triangle} refers to vertex {index}, but the mesh has {vertices} vertices",
                path.display()
            ),
        }
    }
}

impl std::error::Error for MeshError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            MeshError::File(e) => Some(e),
            _ => None,
        }
    }
}

impl TriangleMesh {
    /// The square [−1, 1]² in the z = 0 plane, facing +z (Mitsuba's `rectangle`).
    #[must_use]
    pub fn rectangle() -> Self {
        TriangleMesh {
            name: "rectangle".into(),
            positions: vec![
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(-1.0, 1.0, 0.0),
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3]],
            ..TriangleMesh::default()
        }
    }

    /// Checks that positions are finite and within [`MAX_COORDINATE`] and
    /// indices in range; `path` names the file in the error.
    pub fn validate(&self, path: &Path) -> Result<(), MeshError> {
        if let Some(vertex) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(MeshError::NonFinite {
                path: path.to_owned(),
                mesh: self.name.clone(),
                vertex,
            });
        }
        let beyond = |p: &Vec3| p.abs().max_element() > MAX_COORDINATE;
        if let Some(vertex) = self.positions.iter().position(beyond) {
            return Err(MeshError::OutOfBounds {
                path: path.to_owned(),
                mesh: self.name.clone(),
                vertex,
                position: self.positions[vertex].to_array(),
            });
        }
        let n = self.positions.len();
        for (triangle, t) in self.triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::IndexOutOfRange {
                    path: path.to_owned(),
                    mesh: self.name.clone(),
                    triangle,
                    index,
                    vertices: n,
                });
            }
        }
        let consistent = |len: usize| len == 0 || len == n;
        if !consistent(self.normals.len()) || !consistent(self.uvs.len()) {
            return Err(MeshError::Format {
                path: path.to_owned(),
                message: format!(
                    "mesh '{}': {n} positions but {} normals and {} uvs",
                    self.name,
                    self.normals.len(),
                    self.uvs.len()
                ),
            });
        }
        Ok(())
    }

    /// Applies an object-to-world transform: positions by `m`, normals by
    /// its inverse transpose (flipping nothing: orientation follows the
    /// winding, as in Mitsuba).
    pub fn transform(&mut self, m: Mat4) {
        let normal_matrix = m.inverse().transpose();
        for p in &mut self.positions {
            *p = m.transform_point3(*p);
        }
        for n in &mut self.normals {
            *n = normal_matrix.transform_vector3(*n).normalize_or_zero();
        }
    }

    /// The corners of triangle `i`.
    #[must_use]
    pub fn corners(&self, i: usize) -> [Vec3; 3] {
        self.triangles[i].map(|k| self.positions[k as usize])
    }

    /// The area of triangle `i`.
    #[must_use]
    pub fn triangle_area(&self, i: usize) -> f64 {
        let [a, b, c] = self.corners(i).map(|p| p.as_dvec3());
        0.5 * (b - a).cross(c - a).length()
    }

    /// The total surface area.
    #[must_use]
    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|i| self.triangle_area(i))
            .sum()
    }
}
