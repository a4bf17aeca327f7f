//! Bump mapping: the shading normal tilted by the gradient of a height
//! texture over the surface's uv parameterisation.

use glam::{Vec2, Vec3};

use crate::geometry::Primitive;
use crate::scene::{Scene, Texture};
use crate::spectrum::luminance;
use crate::vertex::{SceneVertex, Site};

/// Half a texel in uv, the finite-difference step that resolves a bitmap's
/// bilinear slopes; `None` for textures without variation.
fn half_texel(t: &Texture) -> Option<Vec2> {
    match t {
        Texture::Constant(_) => None,
        Texture::Bitmap {
            image, uv_scale, ..
        } => Some(Vec2::new(
            0.5 / (image.width as f32 * uv_scale[0].abs().max(1e-6)),
            0.5 / (image.height as f32 * uv_scale[1].abs().max(1e-6)),
        )),
        Texture::Scale(_, inner) => half_texel(inner),
    }
}

/// ∂p/∂u and ∂p/∂v of the triangle under `v`, from its texture coordinates
/// (or its barycentric parameterisation when the mesh has none).
pub(super) fn tangents(scene: &Scene, v: &SceneVertex) -> Option<(Vec3, Vec3)> {
    let Site::Surface {
        primitive: Primitive::Triangle { mesh, triangle },
        ..
    } = v.site
    else {
        return None;
    };
    let mesh = &scene.geometry.meshes()[mesh as usize];
    let [p0, p1, p2] = mesh.corners(triangle as usize);
    let [uv0, uv1, uv2] = if mesh.uvs.is_empty() {
        [Vec2::ZERO, Vec2::X, Vec2::Y]
    } else {
        mesh.triangles[triangle as usize].map(|i| mesh.uvs[i as usize])
    };
    let (d1, d2) = (uv1 - uv0, uv2 - uv0);
    let det = d1.x * d2.y - d1.y * d2.x;
    if det.abs() < 1e-12 {
        return None;
    }
    let (e1, e2) = (p1 - p0, p2 - p0);
    Some(((e1 * d2.y - e2 * d1.y) / det, (e2 * d1.x - e1 * d2.x) / det))
}

/// The shading normal of `v` displaced by `height` (Mitsuba's bump map: the
/// tangents gain the height's slope along the normal).
pub(super) fn perturbed_normal(
    scene: &Scene,
    v: &SceneVertex,
    normal: Vec3,
    height: &Texture,
) -> Vec3 {
    let (Some(step), Some((dpdu, dpdv))) = (half_texel(height), tangents(scene, v)) else {
        return normal;
    };
    let h = |du: f32, dv: f32| luminance(height.eval([v.uv.x + du, v.uv.y + dv])) as f32;
    let dhdu = (h(step.x, 0.0) - h(-step.x, 0.0)) / (2.0 * step.x);
    let dhdv = (h(0.0, step.y) - h(0.0, -step.y)) / (2.0 * step.y);
    let n = (dpdu + normal * dhdu).cross(dpdv + normal * dhdv);
    match n.try_normalize() {
        Some(n) if n.dot(normal) < 0.0 => -n,
        Some(n) => n,
        None => normal,
    }
}
