//! Scenes written on the fly and a chi-square chart over every surface of
//! a scene, for the strategy tests.
#![allow(dead_code)]

use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};

use aether_core::Step;
use aether_core::harness::{Chart, Grid, Parameterization, SphereDirections, Triangle};
use aether_strategies::geometry::Primitive;
use aether_strategies::integrand::visible;
use aether_strategies::scene::Scene;
use aether_strategies::vertex::{SceneVertex, Site};
use glam::Vec3;

/// A folder of this test process for scene files and their images.
pub fn folder() -> PathBuf {
    let dir = std::env::temp_dir().join(format!("aether-strategies-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Loads a scene from the body of a `<scene>` element (with a default
/// camera if it has none).
pub fn scene(body: &str) -> Scene {
    let body = if body.contains("<sensor") {
        body.to_string()
    } else {
        format!("{body}<sensor type=\"perspective\"/>")
    };
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let path = folder().join(format!("scene{}.xml", NEXT.fetch_add(1, Ordering::Relaxed)));
    std::fs::write(&path, format!("<scene version=\"0.5.0\">{body}</scene>")).unwrap();
    Scene::load(&path, &HashMap::new()).unwrap_or_else(|e| panic!("{e}"))
}

/// The inside of the cube [−1, 1]³, diffuse, with a small lamp under its
/// ceiling facing down, and `extra` shapes and emitters.
pub fn room(extra: &str) -> Scene {
    scene(&format!(
        "<shape type=\"cube\"><boolean name=\"flipNormals\" value=\"true\"/>
            <bsdf type=\"diffuse\"><rgb name=\"reflectance\" value=\"0.5\"/></bsdf></shape>
        <shape type=\"rectangle\"><transform name=\"toWorld\"><scale value=\"0.3\"/>
            <rotate x=\"1\" angle=\"180\"/><translate z=\"0.95\"/></transform>
            <emitter type=\"area\"><rgb name=\"radiance\" value=\"5\"/></emitter></shape>
        {extra}"
    ))
}

/// The room with a 0.4 × 0.2 portal rectangle tilted by 30° in its middle.
pub fn portal_room() -> Scene {
    room(
        "<shape type=\"rectangle\"><transform name=\"toWorld\"><scale x=\"0.2\" y=\"0.1\"/>
            <rotate x=\"1\" angle=\"30\"/><translate x=\"0.1\"/></transform>
            <boolean name=\"portal\" value=\"true\"/></shape>",
    )
}

/// A grey 8×8 checkerboard PNG for textures and bump maps, written once
/// per test process (rewritten by each test, it could be read half-written
/// by another running beside it).
pub fn checkerboard() -> PathBuf {
    static WRITTEN: std::sync::OnceLock<PathBuf> = std::sync::OnceLock::new();
    WRITTEN
        .get_or_init(|| {
            let path = folder().join("checker.png");
            let img = image::RgbImage::from_fn(8, 8, |x, y| {
                let v = if (x + y) % 2 == 0 { 200 } else { 60 };
                image::Rgb([v, v, v])
            });
            img.save(&path).unwrap();
            path
        })
        .clone()
}

/// A chart of every triangle and sphere of a scene (`n` × `n` cells each,
/// by equal-area parameterisations unrelated to the samplers') and, if
/// `sky`, of directions at infinity.
pub struct SceneChart<'s> {
    scene: &'s Scene,
    viewpoint: Option<SceneVertex>,
    n: usize,
    parts: Vec<Part>,
    index: HashMap<(u32, u32), usize>,
}

#[derive(Clone, Copy)]
enum Part {
    Triangle { mesh: u32, triangle: u32 },
    Sphere(u32),
    Sky,
}

impl<'s> SceneChart<'s> {
    /// The chart of `scene`.
    pub fn new(scene: &'s Scene, n: usize, sky: bool) -> Self {
        let mut parts = Vec::new();
        let mut index = HashMap::new();
        for (m, mesh) in scene.geometry.meshes().iter().enumerate() {
            for t in 0..mesh.triangles.len() {
                index.insert((m as u32, t as u32), parts.len());
                parts.push(Part::Triangle {
                    mesh: m as u32,
                    triangle: t as u32,
                });
            }
        }
        for s in 0..scene.geometry.spheres().len() {
            index.insert((u32::MAX, s as u32), parts.len());
            parts.push(Part::Sphere(s as u32));
        }
        if sky {
            index.insert((u32::MAX, u32::MAX), parts.len());
            parts.push(Part::Sky);
        }
        SceneChart {
            scene,
            viewpoint: None,
            n,
            parts,
            index,
        }
    }

    /// The chart restricted to surface points that `viewpoint` sees (the
    /// first hits of rays from it): densities ignore occlusion, samples of
    /// ray-casting strategies do not.
    pub fn seen_from(mut self, viewpoint: SceneVertex) -> Self {
        self.viewpoint = Some(viewpoint);
        self
    }

    fn param(&self, part: Part) -> PartParam<'s> {
        PartParam {
            scene: self.scene,
            viewpoint: self.viewpoint,
            part,
        }
    }
}

struct PartParam<'s> {
    scene: &'s Scene,
    viewpoint: Option<SceneVertex>,
    part: Part,
}

impl PartParam<'_> {
    fn triangle(&self) -> Option<(u32, u32, Triangle)> {
        let Part::Triangle { mesh, triangle } = self.part else {
            return None;
        };
        let [a, b, c] = self.scene.geometry.meshes()[mesh as usize].corners(triangle as usize);
        Some((mesh, triangle, Triangle(a, b, c)))
    }
}

impl Parameterization<Step<SceneVertex>> for PartParam<'_> {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Step<SceneVertex>> {
        let v = match self.part {
            Part::Triangle { .. } => {
                let (mesh, triangle, chart) = self.triangle()?;
                SceneVertex::on_triangle(self.scene, mesh, triangle, chart.value(s)?)
            }
            Part::Sphere(i) => {
                let sphere = self.scene.geometry.spheres()[i as usize];
                let d = SphereDirections.value(s)?;
                SceneVertex::on_sphere(self.scene, i, sphere.center + sphere.radius * d)
            }
            Part::Sky => SceneVertex::environment(SphereDirections.value(s)?),
        };
        let seen = match (&self.viewpoint, self.part) {
            (Some(from), Part::Triangle { .. } | Part::Sphere(_)) => visible(self.scene, from, &v),
            _ => true,
        };
        seen.then_some(Step::Vertex(v))
    }
    fn coords(&self, v: &Step<SceneVertex>) -> Option<[f64; 2]> {
        let Step::Vertex(v) = v else { return None };
        match self.part {
            Part::Triangle { .. } => self.triangle()?.2.coords(&v.position),
            Part::Sphere(i) => {
                let sphere = self.scene.geometry.spheres()[i as usize];
                SphereDirections.coords(&(v.position - sphere.center).normalize())
            }
            Part::Sky => match v.site {
                Site::Environment { direction } => SphereDirections.coords(&direction),
                _ => None,
            },
        }
    }
    fn jacobian(&self, s: [f64; 2]) -> f64 {
        match self.part {
            Part::Triangle { .. } => self.triangle().map_or(0.0, |t| t.2.jacobian(s)),
            Part::Sphere(i) => {
                let r = f64::from(self.scene.geometry.spheres()[i as usize].radius);
                4.0 * std::f64::consts::PI * r * r
            }
            Part::Sky => 4.0 * std::f64::consts::PI,
        }
    }
}

impl Chart<Step<SceneVertex>> for SceneChart<'_> {
    fn cells(&self) -> usize {
        self.parts.len() * self.n * self.n
    }
    fn cell_of(&self, v: &Step<SceneVertex>) -> Option<usize> {
        let Step::Vertex(x) = v else { return None };
        let key = match x.site {
            Site::Surface {
                primitive: Primitive::Triangle { mesh, triangle },
                ..
            } => (mesh, triangle),
            Site::Surface {
                primitive: Primitive::Sphere(s),
                ..
            } => (u32::MAX, s),
            Site::Environment { .. } => (u32::MAX, u32::MAX),
            _ => return None,
        };
        let p = *self.index.get(&key)?;
        let cell = Grid::new(self.param(self.parts[p]), self.n).cell_of(v)?;
        Some(p * self.n * self.n + cell)
    }
    fn integrate(&self, cell: usize, density: &dyn Fn(&Step<SceneVertex>) -> f64) -> f64 {
        let per = self.n * self.n;
        Grid::new(self.param(self.parts[cell / per]), self.n).integrate(cell % per, density)
    }
}

/// A vertex on the first surface a ray from `origin` along `dir` hits.
pub fn hit(scene: &Scene, origin: Vec3, dir: Vec3) -> SceneVertex {
    let h = scene
        .geometry
        .intersect(origin, dir.normalize(), f32::INFINITY)
        .expect("a hit");
    SceneVertex::from_hit(&h, scene.shape_of(h.primitive))
}
