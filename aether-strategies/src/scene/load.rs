//! From the XML tree to a scene: meshes in world space, material and
//! emitter descriptions, the camera, the film and the integrator settings.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{Mat4, Vec3};

use super::xml::{Category, Object, SceneError, Value, Warning, read_scene, read_scene_str};
use crate::bitmap::Bitmap;
use crate::files::{MAX_IMAGE_BYTES, check_regular};
use crate::geometry::{Geometry, Sphere};
use crate::mesh::{
    MAX_COORDINATE, ObjMaterial, TriangleMesh, load_obj_with_materials, load_serialized,
};
use crate::spectrum::{SpectrumKind, to_linear_rgb};

/// A spatially varying or constant colour parameter.
#[derive(Clone, Debug, PartialEq)]
pub enum Texture {
    /// A linear RGB constant.
    Constant([f32; 3]),
    /// An image, addressed by uv × `uv_scale` + offset.
    Bitmap {
        /// The image file.
        path: PathBuf,
        /// Its texels.
        image: Arc<Bitmap>,
        /// Scale of uv.
        uv_scale: [f32; 2],
        /// Offset of uv.
        uv_offset: [f32; 2],
    },
    /// Another texture times a factor.
    Scale(f32, Box<Texture>),
}

impl Texture {
    /// True unless the texture is the same everywhere (it reads uv).
    #[must_use]
    pub fn varies(&self) -> bool {
        match self {
            Texture::Constant(_) => false,
            Texture::Bitmap { .. } => true,
            Texture::Scale(_, inner) => inner.varies(),
        }
    }

    /// The colour at texture coordinates `uv`.
    #[must_use]
    #[inline]
    pub fn eval(&self, uv: [f32; 2]) -> [f32; 3] {
        // A constant is read in place; only an image or a scaled texture
        // is a call (the recursion kept every evaluation out of line).
        match self {
            Texture::Constant(c) => *c,
            varying => varying.eval_varying(uv),
        }
    }

    /// [`eval`](Self::eval) out of line, for images and scaled textures
    /// (`eval` reads a constant itself, at any depth of scaling).
    #[inline(never)]
    fn eval_varying(&self, uv: [f32; 2]) -> [f32; 3] {
        match self {
            Texture::Constant(c) => *c,
            Texture::Bitmap {
                image,
                uv_scale,
                uv_offset,
                ..
            } => image.lookup(
                uv[0] * uv_scale[0] + uv_offset[0],
                uv[1] * uv_scale[1] + uv_offset[1],
            ),
            Texture::Scale(s, inner) => inner.eval(uv).map(|c| c * s),
        }
    }
}

/// Microfacet distribution names of Mitsuba.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MicrofacetKind {
    /// Beckmann.
    Beckmann,
    /// GGX.
    Ggx,
}

/// Microfacet roughness.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Roughness {
    /// Distribution.
    pub kind: MicrofacetKind,
    /// α along u and v.
    pub alpha: [f32; 2],
}

/// A BSDF as declared.
#[derive(Clone, Debug, PartialEq)]
pub enum Material {
    /// Lambertian.
    Diffuse {
        /// Albedo.
        reflectance: Texture,
    },
    /// Smooth or rough glass.
    Dielectric {
        /// Interior index.
        int_ior: f32,
        /// Exterior index.
        ext_ior: f32,
        /// `None` for a smooth (Dirac) interface.
        roughness: Option<Roughness>,
    },
    /// Smooth or rough metal.
    Conductor {
        /// Complex index of refraction (η, k) per channel, or `None` for a
        /// perfect mirror (Mitsuba's `material="none"`).
        ior: Option<([f32; 3], [f32; 3])>,
        /// Tint.
        specular_reflectance: [f32; 3],
        /// `None` for a smooth (Dirac) interface.
        roughness: Option<Roughness>,
    },
    /// A diffuse base under a dielectric coat.
    Plastic {
        /// Base albedo.
        diffuse_reflectance: Texture,
        /// Specular tint.
        specular_reflectance: [f32; 3],
        /// Interior index.
        int_ior: f32,
        /// Exterior index.
        ext_ior: f32,
        /// `None` for a smooth coat.
        roughness: Option<Roughness>,
    },
    /// A bump-mapped material.
    BumpMap {
        /// The height texture.
        height: Texture,
        /// The material it perturbs.
        inner: Box<Material>,
    },
    /// The same material on both sides.
    TwoSided(Box<Material>),
}

/// A light source as declared.
#[derive(Clone, Debug, PartialEq)]
pub enum Emitter {
    /// Emission from shape `shape` (an index into [`Scene::shapes`]).
    Area {
        /// Radiance.
        radiance: [f32; 3],
        /// The shape.
        shape: usize,
    },
    /// A point light.
    Point {
        /// Position.
        position: Vec3,
        /// Intensity.
        intensity: [f32; 3],
    },
    /// A spot light.
    Spot {
        /// Object to world (the light looks along +z).
        to_world: Mat4,
        /// Intensity.
        intensity: [f32; 3],
        /// Cut-off angle in degrees.
        cutoff_angle: f32,
        /// Beam width in degrees.
        beam_width: f32,
    },
    /// A distant light.
    Directional {
        /// Direction of travel of the light.
        direction: Vec3,
        /// Irradiance.
        irradiance: [f32; 3],
    },
    /// Uniform radiance from every direction.
    Constant {
        /// Radiance.
        radiance: [f32; 3],
    },
    /// An environment map.
    EnvMap {
        /// The EXR file.
        path: PathBuf,
        /// Its texels (latitude-longitude).
        image: Arc<Bitmap>,
        /// Scale.
        scale: f32,
        /// Object to world.
        to_world: Mat4,
    },
}

/// A shape of the scene: a mesh or a sphere of [`Scene::geometry`].
#[derive(Clone, Debug, PartialEq)]
pub struct Shape {
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// Index into [`Scene::emitters`], for area lights.
    pub emitter: Option<usize>,
    /// Where it was declared.
    pub declared: String,
}

/// The camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    /// Camera to world (Mitsuba's: looks along +z, x to the left).
    pub to_world: Mat4,
    /// Field of view in degrees, along `fov_axis`.
    pub fov: f32,
    /// `x`, `y`, `diagonal`, `smaller` or `larger`.
    pub fov_axis: String,
    /// Near clip distance.
    pub near_clip: f32,
    /// Far clip distance.
    pub far_clip: f32,
    /// Lens radius (0 for a pinhole) and focus distance.
    pub aperture_radius: f32,
    /// Focus distance (thin lens).
    pub focus_distance: f32,
}

/// Film and sampling settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Crop window: offset and size.
    pub crop: [u32; 4],
    /// Reconstruction filter: `box`, `gaussian` or `tent`.
    pub filter: String,
    /// Samples per pixel.
    pub spp: u32,
}

/// A film over [`Film::MAX_PIXELS`] pixels: the render would not fit in
/// memory, or take longer than anyone would wait.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FilmTooLarge {
    /// The width asked for.
    pub width: u64,
    /// The height asked for.
    pub height: u64,
}

impl std::fmt::Display for FilmTooLarge {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let pixels = self.width as f64 * self.height as f64;
        write!(
            f,
            "a {}×{} film ({pixels:.3e} pixels) is over the limit of {} pixels (8192²): its buffers would need {:.1} GiB",
            self.width,
            self.height,
            Film::MAX_PIXELS,
            pixels * Film::BYTES_PER_PIXEL as f64 / f64::from(1u32 << 30)
        )
    }
}

impl std::error::Error for FilmTooLarge {}

impl Film {
    /// The most pixels a film may have: 8192², whose buffers take about
    /// 3.5 GiB.
    pub const MAX_PIXELS: u64 = 1 << 26;

    /// Bytes a render holds per pixel: the sums (f64 RGB) and count of the
    /// camera samples, the splat buffer (f64 RGB), the image (f32 RGB) and
    /// its preview.
    pub const BYTES_PER_PIXEL: u64 = 24 + 4 + 24 + 12 + 3;

    /// Checks that a `width` × `height` film is within
    /// [`Film::MAX_PIXELS`].
    ///
    /// # Errors
    /// If it is not.
    pub fn check_size(width: u64, height: u64) -> Result<(), FilmTooLarge> {
        match width.checked_mul(height) {
            Some(n) if n <= Self::MAX_PIXELS => Ok(()),
            _ => Err(FilmTooLarge { width, height }),
        }
    }

    /// Resizes the film to `width` pixels (at least one), the height
    /// keeping the aspect ratio; the crop window becomes the whole film.
    ///
    /// # Errors
    /// If the film would be over [`Film::MAX_PIXELS`]; it is then unchanged.
    pub fn scale_to_width(&mut self, width: u32) -> Result<(), FilmTooLarge> {
        let aspect = f64::from(self.height) / f64::from(self.width);
        let width = width.max(1);
        let height = (f64::from(width) * aspect).round().max(1.0);
        if height > f64::from(u32::MAX) {
            return Err(FilmTooLarge {
                width: u64::from(width),
                height: height as u64,
            });
        }
        let height = height as u32;
        Film::check_size(u64::from(width), u64::from(height))?;
        (self.width, self.height) = (width, height);
        self.crop = [0, 0, width, height];
        Ok(())
    }
}

/// The integrator the scene asks for, with its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct IntegratorSettings {
    /// Our name: `path`, `direct`, `bdpt`, `tridir`, `mlt`, `gpt`, `light`.
    pub name: String,
    /// Mitsuba's maxDepth (−1: unlimited).
    pub max_depth: i64,
    /// Depth at which Russian roulette starts.
    pub rr_depth: i64,
    /// Gradient-domain path tracing's parameters.
    pub gradient: GradientSettings,
    /// Metropolis light transport's parameters.
    pub metropolis: MetropolisSettings,
}

/// Parameters of Metropolis light transport (Aether's `mymlt`, Mitsuba's
/// `mlt` and `pssmlt`). The specular roughness threshold is shared with
/// [`GradientSettings::roughness_threshold`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MetropolisSettings {
    /// Independent samples that estimate the normalisation and seed the
    /// chains (`luminanceSamples`; 100 000).
    pub luminance_samples: u32,
    /// Probability of a large step in primary sample space (`pLarge`; 0.3).
    pub large_step: f64,
    /// Number of chains (`chains`, or Mitsuba's `workUnits` if positive; 16).
    pub chains: u32,
    /// Samples per pixel of a separate direct-lighting pass, whose paths
    /// the chains then leave out (`directSamples`; −1 or 0: none).
    pub direct_samples: u32,
    /// Relative frequencies of Veach's mutations: bidirectional, lens,
    /// caustic and multi-chain (`bidirectionalMutation`,
    /// `lensPerturbation`, `causticPerturbation`, `multiChainPerturbation`:
    /// true for 1, false for 0).
    pub mutations: [f64; 4],
}

impl Default for MetropolisSettings {
    fn default() -> Self {
        MetropolisSettings {
            luminance_samples: 100_000,
            large_step: 0.3,
            chains: 16,
            direct_samples: 0,
            mutations: [1.0; 4],
        }
    }
}

impl Default for IntegratorSettings {
    /// Path tracing without a depth limit, roulette from depth 5.
    fn default() -> Self {
        IntegratorSettings {
            name: "path".into(),
            max_depth: -1,
            rr_depth: 5,
            gradient: GradientSettings::default(),
            metropolis: MetropolisSettings::default(),
        }
    }
}

/// Parameters of gradient-domain path tracing (Aether's `mygpt`, Kettunen
/// et al.'s `gpt`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GradientSettings {
    /// Surfaces with a lobe at most this rough (microfacet α) count as
    /// specular: shifts replay through them instead of reconnecting
    /// (`specularRoughnessThreshold`, or `shiftThreshold`; 0.02).
    pub roughness_threshold: f32,
    /// Reconstruct in the L1 norm (iteratively reweighted) rather than L2
    /// (`doL1Reconstruction`, or `reconstructL1`; true).
    pub l1: bool,
    /// Weight α of the primal image against the gradients in the screened
    /// Poisson reconstruction (`reconstructAlpha`; 0.04).
    pub alpha: f32,
}

impl Default for GradientSettings {
    fn default() -> Self {
        GradientSettings {
            roughness_threshold: 0.02,
            l1: true,
            alpha: 0.04,
        }
    }
}

/// A loaded scene.
#[derive(Debug)]
pub struct Scene {
    /// Ray casting over every shape.
    pub geometry: Geometry,
    /// Per mesh then per sphere of `geometry`: material and emitter.
    pub shapes: Vec<Shape>,
    /// Materials.
    pub materials: Vec<Material>,
    /// Emitters.
    pub emitters: Vec<Emitter>,
    /// The camera.
    pub camera: Camera,
    /// Film and sampling.
    pub film: Film,
    /// Integrator settings.
    pub integrator: IntegratorSettings,
    /// Portal (keyhole) openings, in world space: shapes declared with
    /// `<boolean name="portal" value="true"/>`. They are not rendered; the
    /// tridirectional integrator samples segments through them.
    pub portals: Vec<TriangleMesh>,
    /// What was skipped or adjusted while loading.
    pub warnings: Vec<Warning>,
}

impl Scene {
    /// Loads a Mitsuba scene file.
    ///
    /// # Errors
    /// Anything that keeps the file from being read or rendered, with the
    /// file, line and element it is about.
    pub fn load(path: &Path, params: &HashMap<String, String>) -> Result<Scene, SceneError> {
        Self::from_file(read_scene(path, params)?)
    }

    /// Loads a scene from `text`, as if it were the file `path` (relative
    /// paths inside resolve against its folder).
    ///
    /// # Errors
    /// As [`Scene::load`].
    pub fn load_str(
        text: &str,
        path: &Path,
        params: &HashMap<String, String>,
    ) -> Result<Scene, SceneError> {
        Self::from_file(read_scene_str(text, path, params)?)
    }

    fn from_file(file: super::xml::SceneFile) -> Result<Scene, SceneError> {
        let mut loader = Loader {
            portals: Vec::new(),
            meshes: Vec::new(),
            spheres: Vec::new(),
            mesh_shapes: Vec::new(),
            sphere_shapes: Vec::new(),
            materials: Vec::new(),
            material_ids: HashMap::new(),
            emitters: Vec::new(),
            warnings: file.warnings,
        };
        let root = &file.root;
        for child in &root.children {
            match child.category {
                Category::Shape => loader.shape(child)?,
                Category::Emitter => {
                    let e = loader.emitter(child, None)?;
                    loader.emitters.push(e);
                }
                Category::Bsdf | Category::Texture | Category::Sensor | Category::Integrator => {}
                Category::Medium | Category::Phase => loader.warnings.push(Warning {
                    location: child.location.clone(),
                    message: format!(
                        "{} is not referenced by any shape and is ignored",
                        child.describe()
                    ),
                }),
                _ => loader.warnings.push(Warning {
                    location: child.location.clone(),
                    message: format!("{} is ignored at the top level", child.describe()),
                }),
            }
        }
        let sensor = root
            .children_of(Category::Sensor)
            .next()
            .ok_or_else(|| root.error("the scene has no <sensor>"))?;
        let (camera, film) = camera_and_film(sensor)?;
        let integrator = match root.children_of(Category::Integrator).next() {
            Some(i) => integrator(i)?,
            None => IntegratorSettings::default(),
        };
        // Mitsuba reads one of each; later ones (often from an include)
        // would otherwise pass unnoticed.
        for (category, name) in [
            (Category::Sensor, "sensor"),
            (Category::Integrator, "integrator"),
        ] {
            let mut all = root.children_of(category);
            let Some(first) = all.next() else { continue };
            for extra in all {
                loader.warnings.push(Warning {
                    location: extra.location.clone(),
                    message: format!(
                        "{} is ignored: the scene's first <{name}> ({}) is used",
                        extra.describe(),
                        first.location
                    ),
                });
            }
        }
        // Only the objects the scene uses: declared-but-unreferenced BSDFs
        // and textures are not reported.
        for child in root.children.iter().filter(|c| {
            matches!(
                c.category,
                Category::Shape | Category::Emitter | Category::Sensor | Category::Integrator
            )
        }) {
            loader.warnings.extend(child.unread());
        }
        if !loader.emitters.is_empty() && loader.emitters.iter().all(is_black) {
            loader.warnings.push(Warning {
                location: root.location.clone(),
                message: "every emitter of the scene emits nothing (zero radiance, intensity or scale): the image will be black".to_string(),
            });
        }
        let Loader {
            meshes,
            spheres,
            mut mesh_shapes,
            sphere_shapes,
            materials,
            mut emitters,
            warnings,
            portals,
            ..
        } = loader;
        for e in &mut emitters {
            if let Emitter::Area { shape, .. } = e {
                if *shape >= SPHERE_BASE {
                    *shape = *shape - SPHERE_BASE + meshes.len();
                }
            }
        }
        mesh_shapes.extend(sphere_shapes);
        let mut geometry = Geometry::new(meshes, spheres);
        let first_sphere = geometry.meshes().len();
        geometry.set_sphere_uvs_used(|i| {
            mesh_shapes
                .get(first_sphere + i)
                .and_then(|shape| materials.get(shape.material))
                .is_none_or(Material::reads_uv)
        });
        Ok(Scene {
            geometry,
            shapes: mesh_shapes,
            materials,
            emitters,
            camera,
            film,
            integrator,
            portals,
            warnings,
        })
    }
}

/// Provisional shape indices of spheres, while meshes are still being read.
const SPHERE_BASE: usize = usize::MAX / 2;

struct Loader {
    portals: Vec<TriangleMesh>,
    meshes: Vec<TriangleMesh>,
    spheres: Vec<Sphere>,
    mesh_shapes: Vec<Shape>,
    sphere_shapes: Vec<Shape>,
    materials: Vec<Material>,
    material_ids: HashMap<*const Object, usize>,
    emitters: Vec<Emitter>,
    warnings: Vec<Warning>,
}

fn rgb(v: [f64; 3]) -> [f32; 3] {
    v.map(|x| x as f32)
}

/// A colour property: spectrum, rgb or float, converted for its use.
fn color(
    o: &Object,
    name: &str,
    default: [f32; 3],
    kind: SpectrumKind,
) -> Result<[f32; 3], SceneError> {
    let Some(p) = o.property(name) else {
        return Ok(default);
    };
    Ok(match &p.value {
        Value::Spectrum(s) => rgb(to_linear_rgb(s, kind)),
        Value::Rgb(c) => rgb(*c),
        Value::Float(x) => [*x as f32; 3],
        Value::Integer(i) => [*i as f32; 3],
        other => {
            return Err(o.error(format!(
                "'{name}' must be a spectrum or a colour, not {other:?}"
            )));
        }
    })
}

/// An emitter's colour `name` (1 by default) times `scale`: each channel
/// finite and ≥ 0, as negative emission has no meaning and renders black.
fn emission(o: &Object, name: &str, scale: f32) -> Result<[f32; 3], SceneError> {
    let c = color(o, name, [1.0; 3], SpectrumKind::Emission)?;
    if c.iter().any(|&x| x < 0.0) {
        return Err(o.error(format!(
            "'{name}' {c:?} has a negative channel: emission must be ≥ 0 (negative emission renders black)"
        )));
    }
    let scaled = c.map(|x| x * scale);
    if scaled.iter().any(|x| !x.is_finite()) {
        return Err(o.error(format!(
            "'{name}' {c:?} times 'scale' {scale} is beyond the largest number a radiance may have"
        )));
    }
    Ok(scaled)
}

/// Whether an emitter emits nothing at all.
fn is_black(e: &Emitter) -> bool {
    let zero = |c: &[f32; 3]| c.iter().all(|&x| x == 0.0);
    match e {
        Emitter::Area { radiance, .. } | Emitter::Constant { radiance } => zero(radiance),
        Emitter::Point { intensity, .. } | Emitter::Spot { intensity, .. } => zero(intensity),
        Emitter::Directional { irradiance, .. } => zero(irradiance),
        Emitter::EnvMap { scale, image, .. } => *scale == 0.0 || image.texels.iter().all(zero),
    }
}

fn positive(o: &Object, name: &str, default: f64) -> Result<f32, SceneError> {
    let v = o.float(name, default)?;
    // Positive in f32 too: 1e308 is a finite f64 but an infinite f32.
    if v.is_finite() && v > 0.0 && (v as f32).is_finite() && v as f32 > 0.0 {
        Ok(v as f32)
    } else {
        Err(o.error(format!("'{name}' must be positive, not {v}")))
    }
}

/// Index of refraction: a number or a named material.
fn ior(o: &Object, name: &str, default: f64) -> Result<f32, SceneError> {
    if let Some(s) = o.string(name).ok().flatten() {
        let n = match s {
            "vacuum" => 1.0,
            "air" => 1.000_277,
            "water" => 1.333,
            "bk7" => 1.5046,
            "glass" => 1.5,
            "acrylic glass" => 1.49,
            "polypropylene" => 1.49,
            "diamond" => 2.419,
            other => return Err(o.error(format!("unknown index of refraction '{other}'"))),
        };
        return Ok(n);
    }
    let n = positive(o, name, default)?;
    // No material is near 100 or 0.01; beyond, the ratio of two indices
    // and Fresnel's squares leave f32.
    if !(0.01..=100.0).contains(&n) {
        return Err(o.error(format!(
            "'{name}' {n} is not an index of refraction (from 0.01 to 100)"
        )));
    }
    Ok(n)
}

fn roughness(o: &Object) -> Result<Option<Roughness>, SceneError> {
    if !o.kind.starts_with("rough") {
        return Ok(None);
    }
    let kind = match o.string("distribution")?.unwrap_or("beckmann") {
        "beckmann" => MicrofacetKind::Beckmann,
        "ggx" => MicrofacetKind::Ggx,
        other => {
            return Err(o.error(format!(
                "the microfacet distribution '{other}' is not supported (beckmann, ggx)"
            )));
        }
    };
    let alpha = positive(o, "alpha", 0.1)?;
    let au = if o.property("alphaU").is_some() {
        positive(o, "alphaU", 0.1)?
    } else {
        alpha
    };
    let av = if o.property("alphaV").is_some() {
        positive(o, "alphaV", 0.1)?
    } else {
        alpha
    };
    Ok(Some(Roughness {
        kind,
        alpha: [au, av],
    }))
}

fn texture(o: &Object, name: &str, default: [f32; 3]) -> Result<Texture, SceneError> {
    if let Some(t) = o
        .children_of(Category::Texture)
        .find(|t| t.name.as_deref() == Some(name))
    {
        return texture_object(t);
    }
    Ok(Texture::Constant(color(
        o,
        name,
        default,
        SpectrumKind::Reflectance,
    )?))
}

fn texture_object(t: &Object) -> Result<Texture, SceneError> {
    match t.kind.as_str() {
        "bitmap" => {
            let file = t
                .string("filename")?
                .ok_or_else(|| t.error("the bitmap has no 'filename'"))?;
            let path = t
                .location
                .file
                .parent()
                .unwrap_or(Path::new("."))
                .join(file);
            check_regular(&path, MAX_IMAGE_BYTES)
                .map_err(|e| t.error(format!("the image: {e}")))?;
            let s = t.float("uvscale", 1.0)? as f32;
            let uv_scale = [
                t.float("uscale", f64::from(s))? as f32,
                t.float("vscale", f64::from(s))? as f32,
            ];
            let uv_offset = [
                t.float("uoffset", 0.0)? as f32,
                t.float("voffset", 0.0)? as f32,
            ];
            let image = Arc::new(Bitmap::load(&path).map_err(|e| t.error(e))?);
            Ok(Texture::Bitmap {
                path,
                image,
                uv_scale,
                uv_offset,
            })
        }
        "scale" => {
            let inner = t
                .children_of(Category::Texture)
                .next()
                .ok_or_else(|| t.error("a scale texture needs a nested texture"))?;
            Ok(Texture::Scale(
                t.float("scale", 1.0)? as f32,
                Box::new(texture_object(inner)?),
            ))
        }
        other => Err(t.error(format!(
            "the texture type '{other}' is not supported (bitmap, scale)"
        ))),
    }
}

/// Complex indices of refraction (η, k) of Mitsuba's named metals in linear
/// sRGB, as Mitsuba 3.9.1 (`scalar_rgb`) converts its measured spectra;
/// read with its Python module.
fn metal(name: &str) -> Option<([f32; 3], [f32; 3])> {
    Some(match name {
        "Al" => ([1.6575, 0.880405, 0.521244], [9.22381, 6.2695, 4.837]),
        "Cu" => ([0.201005, 0.92375, 1.10222], [3.91326, 2.45305, 2.14209]),
        "Au" => ([0.143036, 0.375307, 1.44205], [3.983, 2.38556, 1.60336]),
        "Ag" => ([0.155276, 0.116728, 0.138388], [4.82835, 3.12222, 2.1469]),
        "Cr" => ([4.36967, 2.91651, 1.6549], [5.20655, 4.23131, 3.7547]),
        _ => return None,
    })
}

fn material(o: &Object) -> Result<Material, SceneError> {
    let nested = || {
        o.children_of(Category::Bsdf)
            .next()
            .ok_or_else(|| o.error("needs a nested <bsdf>"))
    };
    Ok(match o.kind.as_str() {
        "diffuse" => Material::Diffuse {
            reflectance: texture(o, "reflectance", [0.5; 3])?,
        },
        "dielectric" | "roughdielectric" => Material::Dielectric {
            int_ior: ior(o, "intIOR", 1.5046)?,
            ext_ior: ior(o, "extIOR", 1.000_277)?,
            roughness: roughness(o)?,
        },
        "conductor" | "roughconductor" => {
            let ior = if o.property("eta").is_some() || o.property("k").is_some() {
                Some((
                    color(o, "eta", [0.0; 3], SpectrumKind::Reflectance)?,
                    color(o, "k", [1.0; 3], SpectrumKind::Reflectance)?,
                ))
            } else {
                match o.string("material")?.unwrap_or("Cu") {
                    "none" => None,
                    name => Some(metal(name).ok_or_else(|| {
                        o.error(format!(
                            "the metal '{name}' is not known (Al, Cu, Au, Ag, Cr, none)"
                        ))
                    })?),
                }
            };
            Material::Conductor {
                ior,
                specular_reflectance: color(
                    o,
                    "specularReflectance",
                    [1.0; 3],
                    SpectrumKind::Reflectance,
                )?,
                roughness: roughness(o)?,
            }
        }
        "plastic" | "roughplastic" => Material::Plastic {
            diffuse_reflectance: texture(o, "diffuseReflectance", [0.5; 3])?,
            specular_reflectance: color(
                o,
                "specularReflectance",
                [1.0; 3],
                SpectrumKind::Reflectance,
            )?,
            int_ior: ior(o, "intIOR", 1.49)?,
            ext_ior: ior(o, "extIOR", 1.000_277)?,
            roughness: roughness(o)?,
        },
        "bumpmap" => {
            let height = o
                .children_of(Category::Texture)
                .next()
                .ok_or_else(|| o.error("a bump map needs a <texture>"))?;
            Material::BumpMap {
                height: texture_object(height)?,
                inner: Box::new(material(nested()?)?),
            }
        }
        "twosided" => Material::TwoSided(Box::new(material(nested()?)?)),
        other => return Err(o.error(format!("the BSDF type '{other}' is not supported"))),
    })
}

impl Loader {
    fn material_index(&mut self, o: &Arc<Object>) -> Result<usize, SceneError> {
        let key = Arc::as_ptr(o);
        if let Some(&i) = self.material_ids.get(&key) {
            return Ok(i);
        }
        let m = material(o)?;
        self.materials.push(m);
        self.material_ids.insert(key, self.materials.len() - 1);
        Ok(self.materials.len() - 1)
    }

    fn shape(&mut self, o: &Object) -> Result<(), SceneError> {
        let to_world = o.transform("toWorld")?;
        let base = o
            .location
            .file
            .parent()
            .unwrap_or(Path::new("."))
            .to_path_buf();
        let file = |o: &Object| -> Result<PathBuf, SceneError> {
            let name = o
                .string("filename")?
                .ok_or_else(|| o.error("the 'filename' property is missing"))?;
            Ok(base.join(name))
        };
        let mesh_error = |e: crate::mesh::MeshError| o.error(e.to_string());
        let mut mtl = None;
        let geometry: Result<TriangleMesh, Sphere> = match o.kind.as_str() {
            "obj" => {
                let (mesh, materials) = load_obj_with_materials(&file(o)?).map_err(mesh_error)?;
                mtl = materials.into_iter().next();
                Ok(mesh)
            }
            "serialized" => {
                let index = o.integer("shapeIndex", 0)?;
                let index = usize::try_from(index).map_err(|_| o.error(format!("shapeIndex {index} is negative")))?;
                Ok(load_serialized(&file(o)?, index).map_err(mesh_error)?)
            }
            "rectangle" => Ok(TriangleMesh::rectangle()),
            "cube" => Ok(cube_mesh()),
            "sphere" => {
                let center = o.point("center", Vec3::ZERO)?;
                let radius = positive(o, "radius", 1.0)?;
                let c = to_world.transform_point3(center);
                let scale = to_world.transform_vector3(Vec3::X).length();
                let radius = radius * scale;
                if !(c.is_finite() && radius.is_finite()) || c.abs().max_element() + radius > MAX_COORDINATE {
                    return Err(o.error(format!("the sphere at {c} of radius {radius} reaches beyond ±{MAX_COORDINATE:e}, the largest coordinate the ray tracer handles")));
                }
                Err(Sphere { center: c, radius })
            }
            other => return Err(o.error(format!("the shape type '{other}' is not supported (obj, serialized, sphere, rectangle, cube)"))),
        };
        let geometry = match geometry {
            Ok(mut mesh) => {
                if o.boolean("faceNormals", false)? {
                    mesh.normals.clear();
                }
                if o.boolean("flipNormals", false)? {
                    mesh.triangles.iter_mut().for_each(|t| t.swap(1, 2));
                    mesh.normals.iter_mut().for_each(|n| *n = -*n);
                }
                Ok(mesh)
            }
            sphere => {
                if o.boolean("flipNormals", false)? {
                    return Err(o.error(
                        "flipNormals on a sphere is not supported: it would change the image",
                    ));
                }
                sphere
            }
        };
        if o.boolean("portal", false)? {
            let Ok(mut mesh) = geometry else {
                return Err(o.error("a portal must be a mesh, not a sphere"));
            };
            if o.children_of(Category::Emitter).next().is_some() {
                return Err(o.error("a portal cannot emit light"));
            }
            mesh.transform(to_world);
            mesh.validate(&o.location.file)
                .map_err(|e| o.error(e.to_string()))?;
            self.portals.push(mesh);
            return Ok(());
        }
        for p in ["interior", "exterior"] {
            if o.children_of(Category::Medium)
                .any(|m| m.name.as_deref() == Some(p))
            {
                return Err(
                    o.error("participating media are not supported: they would change the image")
                );
            }
        }
        let material = match o.children_of(Category::Bsdf).next() {
            Some(b) => self.material_index(b)?,
            None => {
                // Without a <bsdf>, an OBJ's own MTL material gives its diffuse colour or map.
                let reflectance = match mtl {
                    Some(ObjMaterial {
                        diffuse_map: Some(map),
                        ..
                    }) => {
                        let image = Arc::new(Bitmap::load(&map).map_err(|e| o.error(e))?);
                        Texture::Bitmap {
                            path: map,
                            image,
                            uv_scale: [1.0; 2],
                            uv_offset: [0.0; 2],
                        }
                    }
                    Some(ObjMaterial { diffuse, .. }) => Texture::Constant(diffuse),
                    None => Texture::Constant([0.5; 3]),
                };
                self.materials.push(Material::Diffuse { reflectance });
                self.materials.len() - 1
            }
        };
        // Spheres follow the meshes in `Scene::shapes`: their index is
        // settled once every mesh is known (see `Scene::load`).
        let shape_index = match &geometry {
            Ok(_) => self.mesh_shapes.len(),
            Err(_) => SPHERE_BASE + self.spheres.len(),
        };
        let emitter = match o.children_of(Category::Emitter).next() {
            Some(e) => {
                let e = self.emitter(e, Some(shape_index))?;
                self.emitters.push(e);
                Some(self.emitters.len() - 1)
            }
            None => None,
        };
        let shape = Shape {
            material,
            emitter,
            declared: format!("{}: {}", o.location, o.describe()),
        };
        match geometry {
            Ok(mut mesh) => {
                mesh.transform(to_world);
                mesh.validate(&o.location.file)
                    .map_err(|e| o.error(e.to_string()))?;
                self.meshes.push(mesh);
                self.mesh_shapes.push(shape);
            }
            Err(sphere) => {
                self.spheres.push(sphere);
                self.sphere_shapes.push(shape);
            }
        }
        Ok(())
    }

    fn emitter(&mut self, o: &Object, shape: Option<usize>) -> Result<Emitter, SceneError> {
        let scale = o.float("scale", 1.0)?;
        if scale < 0.0 {
            return Err(o.error(format!(
                "'scale' must be ≥ 0, not {scale}: negative emission renders black"
            )));
        }
        let scale = scale as f32;
        let scaled = |name: &str| emission(o, name, scale);
        Ok(match o.kind.as_str() {
            "area" => {
                let shape =
                    shape.ok_or_else(|| o.error("an area emitter must be nested in a <shape>"))?;
                Emitter::Area {
                    radiance: scaled("radiance")?,
                    shape,
                }
            }
            "point" => Emitter::Point {
                position: o
                    .transform("toWorld")?
                    .transform_point3(o.point("position", Vec3::ZERO)?),
                intensity: scaled("intensity")?,
            },
            "spot" => Emitter::Spot {
                to_world: o.transform("toWorld")?,
                intensity: scaled("intensity")?,
                cutoff_angle: o.float("cutoffAngle", 20.0)? as f32,
                beam_width: o.float("beamWidth", o.float("cutoffAngle", 20.0)? * 0.75)? as f32,
            },
            "directional" => Emitter::Directional {
                direction: o
                    .transform("toWorld")?
                    .transform_vector3(o.point("direction", Vec3::Z)?)
                    .normalize_or_zero(),
                irradiance: scaled("irradiance")?,
            },
            "constant" => Emitter::Constant {
                radiance: scaled("radiance")?,
            },
            "envmap" => {
                let name = o
                    .string("filename")?
                    .ok_or_else(|| o.error("the 'filename' property is missing"))?;
                let path = o
                    .location
                    .file
                    .parent()
                    .unwrap_or(Path::new("."))
                    .join(name);
                check_regular(&path, MAX_IMAGE_BYTES)
                    .map_err(|e| o.error(format!("the environment map: {e}")))?;
                let image = Arc::new(Bitmap::load(&path).map_err(|e| o.error(e))?);
                Emitter::EnvMap {
                    path,
                    image,
                    scale,
                    to_world: o.transform("toWorld")?,
                }
            }
            other => return Err(o.error(format!("the emitter type '{other}' is not supported"))),
        })
    }
}

/// The cube [−1, 1]³ with outward faces.
fn cube_mesh() -> TriangleMesh {
    let mut mesh = TriangleMesh {
        name: "cube".into(),
        ..TriangleMesh::default()
    };
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let n = Vec3::from_array(std::array::from_fn(|k| if k == axis { sign } else { 0.0 }));
            let (u, v) = (n.any_orthonormal_pair().0, n.any_orthonormal_pair().1);
            let base = mesh.positions.len() as u32;
            for (a, b) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                mesh.positions.push(n + a * u + b * v);
            }
            // Wind so that the geometric normal points outwards.
            let outward = (u).cross(v).dot(n) > 0.0;
            if outward {
                mesh.triangles
                    .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
            } else {
                mesh.triangles
                    .extend([[base, base + 2, base + 1], [base, base + 3, base + 2]]);
            }
        }
    }
    mesh
}

fn camera_and_film(sensor: &Object) -> Result<(Camera, Film), SceneError> {
    let aperture_radius = match sensor.kind.as_str() {
        "perspective" => 0.0,
        "thinlens" => positive(sensor, "apertureRadius", 0.03)?,
        other => {
            return Err(sensor.error(format!(
                "the sensor type '{other}' is not supported (perspective, thinlens)"
            )));
        }
    };
    let camera = Camera {
        to_world: sensor.transform("toWorld")?,
        fov: positive(sensor, "fov", 30.0)?,
        fov_axis: sensor.string("fovAxis")?.unwrap_or("x").to_string(),
        near_clip: positive(sensor, "nearClip", 1e-2)?,
        far_clip: positive(sensor, "farClip", 1e4)?,
        aperture_radius,
        focus_distance: positive(sensor, "focusDistance", 1.0)?,
    };
    if !["x", "y", "diagonal", "smaller", "larger"].contains(&camera.fov_axis.as_str()) {
        return Err(sensor.error(format!(
            "fovAxis '{}' is not x, y, diagonal, smaller or larger",
            camera.fov_axis
        )));
    }
    let film = sensor.children_of(Category::Film).next();
    let size = |name: &str, default: i64| -> Result<u32, SceneError> {
        let v = film.map_or(Ok(default), |f| f.integer(name, default))?;
        u32::try_from(v).ok().filter(|&v| v > 0).ok_or_else(|| {
            film.map_or_else(
                || sensor.error("bad film size"),
                |f| f.error(format!("'{name}' must be a positive integer, not {v}")),
            )
        })
    };
    let (width, height) = (size("width", 768)?, size("height", 576)?);
    Film::check_size(u64::from(width), u64::from(height)).map_err(|e| match film {
        Some(f) => f.error(e.to_string()),
        None => sensor.error(e.to_string()),
    })?;
    let crop = match film {
        Some(f) => [
            f.integer("cropOffsetX", 0)?,
            f.integer("cropOffsetY", 0)?,
            f.integer("cropWidth", i64::from(width))?,
            f.integer("cropHeight", i64::from(height))?,
        ],
        None => [0, 0, i64::from(width), i64::from(height)],
    };
    if crop.iter().any(|&c| c < 0)
        || crop[0] + crop[2] > i64::from(width)
        || crop[1] + crop[3] > i64::from(height)
    {
        return Err(film.map_or_else(
            || sensor.error("bad crop window"),
            |f| {
                f.error(format!(
                    "the crop window {crop:?} does not fit in {width}×{height}"
                ))
            },
        ));
    }
    let filter = film
        .and_then(|f| f.children_of(Category::Rfilter).next())
        .map_or("box".to_string(), |r| r.kind.clone());
    if !["box", "gaussian", "tent"].contains(&filter.as_str()) {
        return Err(film.map_or_else(
            || sensor.error("bad filter"),
            |f| {
                f.error(format!(
                    "the reconstruction filter '{filter}' is not supported (box, gaussian, tent)"
                ))
            },
        ));
    }
    let spp = match sensor.children_of(Category::Sampler).next() {
        Some(s) => {
            let n = s.integer("sampleCount", 4)?;
            u32::try_from(n)
                .ok()
                .filter(|&n| n > 0)
                .ok_or_else(|| s.error(format!("sampleCount must be positive, not {n}")))?
        }
        None => 4,
    };
    Ok((
        camera,
        Film {
            width,
            height,
            crop: crop.map(|c| c as u32),
            filter,
            spp,
        },
    ))
}

fn integrator(o: &Object) -> Result<IntegratorSettings, SceneError> {
    let name = match o.kind.as_str() {
        "path" | "mypath" => "path",
        "direct" | "mydirect" => "direct",
        "bdpt" | "bidir" | "mybidir" => "bdpt",
        "mytridir" => "tridir",
        "mlt" | "mymlt" => "mlt",
        "pssmlt" => "pssmlt",
        "mmlt" => "mmlt",
        "mygpt" | "gpt" => "gpt",
        "ptracer" | "myptracer" => "light",
        other => return Err(o.error(format!("the integrator '{other}' is not known"))),
    };
    let defaults = GradientSettings::default();
    let either = |a: &str, b: &str| {
        if o.property(a).is_some() {
            a.to_string()
        } else {
            b.to_string()
        }
    };
    let threshold = o.float(
        &either("specularRoughnessThreshold", "shiftThreshold"),
        f64::from(defaults.roughness_threshold),
    )?;
    let alpha = o.float("reconstructAlpha", f64::from(defaults.alpha))?;
    if !(threshold >= 0.0 && threshold.is_finite()) {
        return Err(o.error(format!(
            "the roughness threshold must be a number ≥ 0, not {threshold}"
        )));
    }
    if !(alpha > 0.0 && alpha.is_finite()) {
        return Err(o.error(format!("reconstructAlpha must be positive, not {alpha}")));
    }
    let metropolis = metropolis(o)?;
    Ok(IntegratorSettings {
        name: name.to_string(),
        metropolis,
        max_depth: o.integer("maxDepth", -1)?,
        rr_depth: o.integer("rrDepth", 5)?,
        gradient: GradientSettings {
            roughness_threshold: threshold as f32,
            l1: o.boolean(&either("doL1Reconstruction", "reconstructL1"), defaults.l1)?,
            alpha: alpha as f32,
        },
    })
}

fn metropolis(o: &Object) -> Result<MetropolisSettings, SceneError> {
    let d = MetropolisSettings::default();
    let positive = |name: &str, default: u32| -> Result<u32, SceneError> {
        let n = o.integer(name, i64::from(default))?;
        u32::try_from(n)
            .ok()
            .filter(|&n| n > 0)
            .ok_or_else(|| o.error(format!("{name} must be a positive integer, not {n}")))
    };
    let large_step = o.float("pLarge", d.large_step)?;
    if !(0.0..=1.0).contains(&large_step) {
        return Err(o.error(format!("pLarge must lie in [0, 1], not {large_step}")));
    }
    let work_units = o.integer("workUnits", -1)?;
    let chains = if o.property("chains").is_some() || work_units <= 0 {
        positive("chains", d.chains)?
    } else {
        positive("workUnits", d.chains)?
    };
    let direct = o.integer("directSamples", -1)?;
    let direct_samples = u32::try_from(direct.max(0))
        .map_err(|_| o.error(format!("directSamples is too large: {direct}")))?;
    let mut mutations = d.mutations;
    for (w, name) in mutations.iter_mut().zip([
        "bidirectionalMutation",
        "lensPerturbation",
        "causticPerturbation",
        "multiChainPerturbation",
    ]) {
        *w = if o.boolean(name, true)? { 1.0 } else { 0.0 };
    }
    if mutations[0] == 0.0 {
        return Err(o.error(
            "bidirectionalMutation cannot be off: the perturbations alone keep a path's length and light vertex, so the chain would not reach every path".to_string(),
        ));
    }
    Ok(MetropolisSettings {
        luminance_samples: positive("luminanceSamples", d.luminance_samples)?,
        large_step,
        chains,
        direct_samples,
        mutations,
    })
}
