//! Loading the Aether example meshes from ../shared, and bad mesh files.

mod common;
use common::scenes;

use std::path::{Path, PathBuf};

use aether_strategies::geometry::{Geometry, Primitive};
use aether_strategies::mesh::{MeshError, load_obj, load_serialized, serialized_mesh_count};

#[test]
fn cornell_box_objs() {
    let Some(dir) = scenes() else { return };
    let mut meshes = Vec::new();
    for name in [
        "back",
        "ceiling",
        "floor",
        "greenwall",
        "largebox",
        "luminaire",
        "redwall",
        "smallbox",
    ] {
        meshes.push(load_obj(&dir.join(format!("cbox/meshes/cbox_{name}.obj"))).unwrap());
    }
    let counts: Vec<usize> = meshes.iter().map(|m| m.triangles.len()).collect();
    // Quads for the walls and the luminaire, two for the ceiling, six for each box.
    assert_eq!(counts, [2, 4, 2, 2, 12, 2, 2, 12]);
    let g = Geometry::new(meshes, vec![]);
    // From the camera, the tall box stands in the middle; above it, the back wall.
    let eye = glam::Vec3::new(278.0, 273.0, -800.0);
    let hit = g.intersect(eye, glam::Vec3::Z, f32::INFINITY).unwrap();
    assert!(
        matches!(hit.primitive, Primitive::Triangle { mesh: 4, .. }),
        "{hit:?}"
    );
    let up = (glam::Vec3::new(150.0, 480.0, 559.2) - eye).normalize();
    let hit = g.intersect(eye, up, f32::INFINITY).unwrap();
    assert!(
        matches!(hit.primitive, Primitive::Triangle { mesh: 0, .. })
            && (hit.position.z - 559.2).abs() < 0.01,
        "{hit:?}"
    );
}

#[test]
fn serialized_versions_3_and_4() {
    let Some(dir) = scenes() else { return };
    let sphere = dir.join("cbox-sphere/cbox-sphere.serialized");
    assert_eq!(serialized_mesh_count(&sphere).unwrap(), 8);
    assert_eq!(load_serialized(&sphere, 0).unwrap().triangles.len(), 1088);
    assert_eq!(load_serialized(&sphere, 2).unwrap().triangles.len(), 2);
    let bidir = dir.join("veach_bidir/bidir.serialized");
    assert_eq!(serialized_mesh_count(&bidir).unwrap(), 11);
    for i in 0..11 {
        assert!(!load_serialized(&bidir, i).unwrap().triangles.is_empty());
    }
    let hole = load_serialized(&dir.join("cbox/cornell_box_keyhole.serialized"), 0).unwrap();
    assert!(hole.area() > 0.0);
}

fn temp(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aether-mesh-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

#[test]
fn bad_meshes_name_the_file_and_the_problem() {
    let missing = load_obj(Path::new("/nonexistent/mesh.obj")).unwrap_err();
    assert!(
        missing.to_string().contains("/nonexistent/mesh.obj"),
        "{missing}"
    );
    let nan = temp("nan.obj", b"v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n");
    let e = load_obj(&nan).unwrap_err();
    assert!(
        matches!(e, MeshError::NonFinite { vertex: 1, .. }) && e.to_string().contains("nan.obj"),
        "{e}"
    );
    let empty = temp("empty.obj", b"# nothing\n");
    assert!(
        load_obj(&empty)
            .unwrap_err()
            .to_string()
            .contains("no faces")
    );
    let junk = temp("junk.serialized", b"not a mesh at all");
    let e = load_serialized(&junk, 0).unwrap_err();
    assert!(
        e.to_string().contains("junk.serialized") && e.to_string().contains("magic"),
        "{e}"
    );
    let Some(dir) = scenes() else { return };
    let e = load_serialized(&dir.join("cbox-sphere/cbox-sphere.serialized"), 9).unwrap_err();
    assert!(
        e.to_string()
            .contains("shapeIndex 9 is out of range: the file holds 8 meshes"),
        "{e}"
    );
    let mut truncated = std::fs::read(dir.join("cbox-sphere/cbox-sphere.serialized")).unwrap();
    truncated.truncate(truncated.len() / 2);
    let e = load_serialized(&temp("cut.serialized", &truncated), 0).unwrap_err();
    assert!(e.to_string().contains("cut.serialized"), "{e}");
}

#[test]
fn obj_materials_come_from_the_mtl_library() {
    let dir = std::env::temp_dir().join(format!("aether-mtl-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("m.mtl"), "newmtl paint\nKd 0.8 0.2 0.1\n").unwrap();
    std::fs::write(
        dir.join("m.obj"),
        "mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl paint\nf 1 2 3\n",
    )
    .unwrap();
    let (mesh, materials) =
        aether_strategies::mesh::load_obj_with_materials(&dir.join("m.obj")).unwrap();
    assert_eq!(mesh.triangles.len(), 1);
    assert_eq!(materials[0].name, "paint");
    assert_eq!(materials[0].diffuse, [0.8, 0.2, 0.1]);
    // A scene shape without a <bsdf> takes the MTL colour.
    std::fs::write(dir.join("s.xml"), "<scene><sensor type=\"perspective\"/><shape type=\"obj\"><string name=\"filename\" value=\"m.obj\"/></shape></scene>").unwrap();
    let scene = aether_strategies::scene::Scene::load(
        &dir.join("s.xml"),
        &std::collections::HashMap::new(),
    )
    .unwrap();
    assert_eq!(
        scene.materials[0],
        aether_strategies::scene::Material::Diffuse {
            reflectance: aether_strategies::scene::Texture::Constant([0.8, 0.2, 0.1])
        }
    );
}

#[test]
fn out_of_range_indices_name_the_triangle() {
    let mut mesh = aether_strategies::mesh::TriangleMesh::rectangle();
    mesh.triangles[1] = [0, 2, 7];
    let e = mesh
        .validate(Path::new("scenes/broken.serialized"))
        .unwrap_err();
    assert_eq!(
        e.to_string(),
        "scenes/broken.serialized: mesh 'rectangle': triangle 1 refers to vertex 7, but the mesh has 4 vertices"
    );
    let bad_obj = temp("range.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    let e = load_obj(&bad_obj).unwrap_err();
    assert!(e.to_string().contains("range.obj"), "{e}");
}
