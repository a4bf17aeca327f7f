//! The built-in scene: a Cornell box in its classic dimensions (in
//! millimetres: a room about 555 on a side, a square light under the
//! ceiling, a short and a tall block), written here from its published
//! measurements, with a portal just under the light for tridirectional
//! path tracing.

use aether_strategies::geometry::Geometry;
use aether_strategies::mesh::TriangleMesh;
use aether_strategies::scene::xml::look_at;
use aether_strategies::scene::{
    Camera, Emitter, Film, IntegratorSettings, Material, Scene, Shape, Texture,
};
use glam::{DVec3, Vec3};

/// A mesh of quads, each given by four corners in order.
fn quads(name: &str, corners: &[[[f32; 3]; 4]]) -> TriangleMesh {
    let mut mesh = TriangleMesh {
        name: name.to_string(),
        ..TriangleMesh::default()
    };
    for q in corners {
        let base = mesh.positions.len() as u32;
        mesh.positions
            .extend(q.iter().map(|p| Vec3::from_array(*p)));
        mesh.triangles
            .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    }
    mesh
}

/// The sides and top of a block standing on the floor, from its top corners.
fn block(name: &str, top: [[f32; 2]; 4], height: f32) -> TriangleMesh {
    let up = |i: usize| [top[i][0], height, top[i][1]];
    let down = |i: usize| [top[i][0], 0.0, top[i][1]];
    let mut faces = vec![[up(0), up(1), up(2), up(3)]];
    for i in 0..4 {
        let j = (i + 1) % 4;
        faces.push([down(i), down(j), up(j), up(i)]);
    }
    let mut mesh = quads(name, &faces);
    // Orient every face outwards (the corners above are not all wound alike).
    let centre = mesh.positions.iter().copied().sum::<Vec3>() / mesh.positions.len() as f32;
    for t in &mut mesh.triangles {
        let [a, b, c] = t.map(|k| mesh.positions[k as usize]);
        if (b - a).cross(c - a).dot((a + b + c) / 3.0 - centre) < 0.0 {
            t.swap(1, 2);
        }
    }
    mesh
}

/// The built-in Cornell box at `width` × `height` and `spp` samples per pixel.
#[must_use]
pub fn cornell_box(width: u32, height: u32, spp: u32) -> Scene {
    let white = Material::Diffuse {
        reflectance: Texture::Constant([0.725, 0.71, 0.68]),
    };
    let red = Material::Diffuse {
        reflectance: Texture::Constant([0.63, 0.065, 0.05]),
    };
    let green = Material::Diffuse {
        reflectance: Texture::Constant([0.14, 0.45, 0.091]),
    };
    let lamp = Material::Diffuse {
        reflectance: Texture::Constant([0.78; 3]),
    };
    let meshes = vec![
        quads(
            "floor",
            &[[
                [552.8, 0.0, 0.0],
                [0.0, 0.0, 0.0],
                [0.0, 0.0, 559.2],
                [549.6, 0.0, 559.2],
            ]],
        ),
        quads(
            "ceiling",
            &[[
                [556.0, 548.8, 0.0],
                [556.0, 548.8, 559.2],
                [0.0, 548.8, 559.2],
                [0.0, 548.8, 0.0],
            ]],
        ),
        quads(
            "back",
            &[[
                [549.6, 0.0, 559.2],
                [0.0, 0.0, 559.2],
                [0.0, 548.8, 559.2],
                [556.0, 548.8, 559.2],
            ]],
        ),
        quads(
            "green wall",
            &[[
                [0.0, 0.0, 559.2],
                [0.0, 0.0, 0.0],
                [0.0, 548.8, 0.0],
                [0.0, 548.8, 559.2],
            ]],
        ),
        quads(
            "red wall",
            &[[
                [552.8, 0.0, 0.0],
                [549.6, 0.0, 559.2],
                [556.0, 548.8, 559.2],
                [556.0, 548.8, 0.0],
            ]],
        ),
        block(
            "short block",
            [[130.0, 65.0], [82.0, 225.0], [240.0, 272.0], [290.0, 114.0]],
            165.0,
        ),
        block(
            "tall block",
            [
                [423.0, 247.0],
                [265.0, 296.0],
                [314.0, 456.0],
                [472.0, 406.0],
            ],
            330.0,
        ),
        quads(
            "light",
            &[[
                [343.0, 548.7, 227.0],
                [343.0, 548.7, 332.0],
                [213.0, 548.7, 332.0],
                [213.0, 548.7, 227.0],
            ]],
        ),
    ];
    let material_of = [0, 0, 0, 2, 1, 0, 0, 3];
    let mut shapes: Vec<Shape> = material_of
        .iter()
        .enumerate()
        .map(|(i, &m)| Shape {
            material: m,
            emitter: None,
            declared: format!("built-in Cornell box: {}", meshes[i].name),
        })
        .collect();
    shapes[7].emitter = Some(0);
    let camera = Camera {
        to_world: look_at(
            DVec3::new(278.0, 273.0, -800.0),
            DVec3::new(278.0, 273.0, -799.0),
            DVec3::Y,
        )
        .expect("a valid frame")
        .as_mat4(),
        fov: 39.3077,
        fov_axis: "x".to_string(),
        near_clip: 10.0,
        far_clip: 2800.0,
        aperture_radius: 0.0,
        focus_distance: 1000.0,
    };
    Scene {
        geometry: Geometry::new(meshes, vec![]),
        shapes,
        materials: vec![white, red, green, lamp],
        emitters: vec![Emitter::Area {
            radiance: [17.0, 12.0, 4.0],
            shape: 7,
        }],
        camera,
        film: Film {
            width,
            height,
            crop: [0, 0, width, height],
            filter: "gaussian".to_string(),
            spp,
        },
        integrator: IntegratorSettings::default(),
        // The opening under the lamp, a little wider than it: light reaches
        // the box through it, so tridirectional tracing has a portal here.
        portals: vec![quads(
            "portal under the light",
            &[[
                [363.0, 540.0, 207.0],
                [363.0, 540.0, 352.0],
                [193.0, 540.0, 352.0],
                [193.0, 540.0, 207.0],
            ]],
        )],
        warnings: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_camera_looks_into_the_box_and_the_light_faces_down() {
        let scene = cornell_box(64, 64, 1);
        let eye = scene.camera.to_world.transform_point3(Vec3::ZERO);
        let forward = scene.camera.to_world.transform_vector3(Vec3::Z);
        let left = scene.camera.to_world.transform_vector3(Vec3::X);
        assert!((eye - Vec3::new(278.0, 273.0, -800.0)).length() < 1e-3);
        assert!((forward - Vec3::Z).length() < 1e-5);
        // Mitsuba's camera x axis points left: towards the red wall at x ≈ 550,
        // which the classic image shows on the left.
        assert!((left - Vec3::X).length() < 1e-5, "{left}");
        let light = &scene.geometry.meshes()[7];
        let [a, b, c] = light.corners(0);
        assert!((b - a).cross(c - a).normalize().y < -0.99);
        // Block faces point away from the block.
        let hit = scene
            .geometry
            .intersect(Vec3::new(185.0, 300.0, 170.0), -Vec3::Y, f32::INFINITY)
            .unwrap();
        assert!(
            (hit.position.y - 165.0).abs() < 1e-3 && hit.geometric_normal.y > 0.99,
            "{hit:?}"
        );
    }
}
