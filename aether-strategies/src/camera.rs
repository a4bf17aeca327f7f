//! The camera as strategies: its position (a pinhole, or a point on a thin
//! lens) and the direction of a primary ray for a pixel, with the film's
//! pixel filter; and the way back, from a world point to the film, with
//! the camera's importance there (for light paths splatted on the film).
//!
//! Conventions are Mitsuba's: the camera looks along its local +z, with x
//! to the left, and raster coordinates grow rightwards and downwards.

use aether_core::primitives::{
    Affine2, ExponentialDisk, Gnomonic, PiecewiseConstant2D, Planar, UniformDisk, UniformSquare,
};
use aether_core::{
    DiracPoint, Distribution, Either, Frame, InFrame, Intersect, OnSurface, Prefix, Step, Strategy,
};
use glam::{Mat4, Vec2, Vec3};

use crate::geometry::is_finite;
use crate::scene::Scene;
use crate::vertex::{SceneVertex, Site};

/// A frame from the rotation part of an object-to-world matrix (scale and
/// mirroring removed by normalising the axes).
pub(crate) fn frame_of(m: Mat4) -> Frame {
    Frame {
        s: m.x_axis.truncate().normalize(),
        t: m.y_axis.truncate().normalize(),
        n: m.z_axis.truncate().normalize(),
    }
}

/// The pixel filter, tabulated: a sample's offset from the pixel centre is
/// drawn from the filter itself, so each sample belongs to one pixel with
/// weight one. The filter *is* the table (a piecewise-constant version of
/// Mitsuba's box, tent or Gaussian), so that sampling and importance agree
/// exactly.
#[derive(Clone, Debug)]
pub struct PixelFilter {
    table: PiecewiseConstant2D,
    radius: f32,
}

impl PixelFilter {
    /// The filter named `box`, `tent` or `gaussian` (standard deviation 0.5
    /// pixel, truncated at 2 pixels, as in Mitsuba).
    #[must_use]
    pub fn named(name: &str) -> Option<PixelFilter> {
        let (radius, cells, profile): (f32, usize, fn(f64) -> f64) = match name {
            "box" => (0.5, 1, |_| 1.0),
            "tent" => (1.0, 32, |x| 1.0 - x.abs()),
            "gaussian" => (2.0, 32, |x| {
                ((-x * x / (2.0 * 0.25)).exp() - (-4.0f64 / 0.5).exp()).max(0.0)
            }),
            _ => return None,
        };
        // Each cell holds the profile's mean over it (Simpson's rule).
        let r = f64::from(radius);
        let cell = |i: usize| {
            let (a, b) = (
                -r + 2.0 * r * i as f64 / cells as f64,
                -r + 2.0 * r * (i + 1) as f64 / cells as f64,
            );
            (profile(a) + 4.0 * profile(0.5 * (a + b)) + profile(b)) / 6.0
        };
        let axis: Vec<f64> = (0..cells).map(cell).collect();
        let values: Vec<f64> = (0..cells * cells)
            .map(|k| axis[k % cells] * axis[k / cells])
            .collect();
        let table = PiecewiseConstant2D::new(&values, cells, cells).ok()?;
        Some(PixelFilter { table, radius })
    }

    /// Half the width of the filter's support, in pixels.
    #[must_use]
    pub fn radius(&self) -> f32 {
        self.radius
    }
}

/// Half the film's extent on the plane z = 1 in front of the camera, along
/// x and y: the tangents of half the field of view, with Mitsuba's rules for
/// the axis the scene's `fov` is measured along.
#[must_use]
pub fn film_tangents(scene: &Scene) -> Vec2 {
    let (w, h) = (scene.film.width as f32, scene.film.height as f32);
    let t = (scene.camera.fov.to_radians() * 0.5).tan();
    let aspect = w / h;
    match scene.camera.fov_axis.as_str() {
        "y" => Vec2::new(t * aspect, t),
        "diagonal" => {
            let d = t / (1.0 + 1.0 / (aspect * aspect)).sqrt();
            Vec2::new(d, d / aspect)
        }
        "smaller" if aspect > 1.0 => Vec2::new(t * aspect, t),
        "larger" if aspect < 1.0 => Vec2::new(t * aspect, t),
        _ => Vec2::new(t, t / aspect),
    }
}

/// The scene's camera: a pinhole or a thin lens, with its film.
#[derive(Clone, Debug)]
pub struct Camera {
    frame: Frame,
    origin: Vec3,
    /// Film plane at z = 1 from raster coordinates: scale and offset.
    plane: (Vec2, Vec2),
    size: [u32; 2],
    lens_radius: f32,
    focus_distance: f32,
    filter: PixelFilter,
}

impl Camera {
    /// The camera of `scene` with the scene's film and pixel filter.
    ///
    /// # Errors
    /// If the film names a filter other than box, tent or gaussian.
    pub fn new(scene: &Scene) -> Result<Camera, String> {
        let filter = PixelFilter::named(&scene.film.filter)
            .ok_or_else(|| format!("unknown pixel filter '{}'", scene.film.filter))?;
        let c = &scene.camera;
        let (w, h) = (scene.film.width as f32, scene.film.height as f32);
        let tan = film_tangents(scene);
        Ok(Camera {
            frame: frame_of(c.to_world),
            origin: c.to_world.transform_point3(Vec3::ZERO),
            plane: (Vec2::new(-2.0 * tan.x / w, -2.0 * tan.y / h), tan),
            size: [scene.film.width, scene.film.height],
            lens_radius: c.aperture_radius,
            focus_distance: c.focus_distance,
            filter,
        })
    }

    /// Film width and height in pixels.
    #[must_use]
    pub fn size(&self) -> [u32; 2] {
        self.size
    }

    /// The pixel filter.
    #[must_use]
    pub fn filter(&self) -> &PixelFilter {
        &self.filter
    }

    /// The strategy that samples the camera vertex.
    #[must_use]
    pub fn position(&self) -> CameraPosition<'_> {
        CameraPosition(self)
    }

    /// The strategy that samples the first hit of pixel `pixel`'s rays.
    #[must_use]
    pub fn direction<'a>(&'a self, scene: &'a Scene, pixel: [u32; 2]) -> CameraDirection<'a> {
        CameraDirection {
            camera: self,
            scene,
            pixel,
        }
    }

    /// The film-plane shift of rays leaving lens point `lens`: thin-lens rays
    /// aim at the plane in focus, so seen from `lens` the film moves by
    /// −lens / focus distance.
    fn shift(&self, lens: &SceneVertex) -> Vec2 {
        match lens.site {
            Site::Lens => {
                -self.frame.to_local(lens.position - self.origin).truncate() / self.focus_distance
            }
            _ => Vec2::ZERO,
        }
    }

    /// The directions of rays leaving `lens` for pixel `pixel`: a film
    /// position from the filter around the pixel, projected through the lens
    /// point (the film → direction Jacobian is the projection's cos³θ).
    pub fn directions(
        &self,
        pixel: [u32; 2],
        lens: &SceneVertex,
    ) -> impl Distribution<Value = Vec3> + '_ {
        let r = self.filter.radius;
        let corner = Vec2::new(pixel[0] as f32, pixel[1] as f32) + Vec2::splat(0.5 - r);
        let (scale, offset) = self.plane;
        let film = Affine2::new(&self.filter.table, scale * 2.0 * r, offset + scale * corner);
        InFrame::new(self.frame, Gnomonic::new(film, self.shift(lens)))
    }

    /// The directions of rays leaving `lens` toward the whole film,
    /// uniformly on it: the first edge of a path whose pixel is not chosen.
    pub fn film_directions(&self, lens: &SceneVertex) -> impl Distribution<Value = Vec3> + '_ {
        let (scale, offset) = self.plane;
        let size = Vec2::new(self.size[0] as f32, self.size[1] as f32);
        let film = Affine2::new(UniformSquare, scale * size, offset);
        InFrame::new(self.frame, Gnomonic::new(film, self.shift(lens)))
    }

    /// The directions of rays leaving `lens` toward film points offset from
    /// raster position `center` by `offsets` (in pixels): Veach's lens
    /// perturbation.
    pub fn perturbed_directions(
        &self,
        lens: &SceneVertex,
        center: Vec2,
        offsets: ExponentialDisk,
    ) -> impl Distribution<Value = Vec3> + '_ {
        let (scale, offset) = self.plane;
        let film = Affine2::new(offsets, scale, offset + scale * center);
        InFrame::new(self.frame, Gnomonic::new(film, self.shift(lens)))
    }

    /// The angle one pixel subtends at the film's centre, in radians.
    #[must_use]
    pub fn pixel_angle(&self) -> f32 {
        self.plane.0.x.abs()
    }

    /// True if the camera has a lens of positive radius (its vertex is
    /// sampled by area, not a Dirac point).
    #[must_use]
    pub fn has_lens(&self) -> bool {
        self.lens_radius > 0.0
    }

    /// The raster position (pixels, y down) where a ray from `lens` in
    /// world direction `toward` meets the film, if it is in front.
    #[must_use]
    pub fn raster(&self, lens: &SceneVertex, toward: Vec3) -> Option<Vec2> {
        let local = self.frame.to_local(toward);
        if local.z <= 0.0 {
            return None;
        }
        let q = local.truncate() / local.z - self.shift(lens);
        let (scale, offset) = self.plane;
        Some((q - offset) / scale).filter(|r| is_finite(r.x) && is_finite(r.y))
    }

    /// The pixels whose filter support contains raster position `raster`.
    pub fn pixels_around(&self, raster: Vec2) -> impl Iterator<Item = [u32; 2]> {
        let r = self.filter.radius;
        // A non-finite position covers no pixel (max and min would drop NaN).
        let raster = if is_finite(raster.x) && is_finite(raster.y) {
            raster
        } else {
            Vec2::splat(-1e9)
        };
        let lo = (raster - Vec2::splat(r + 0.5)).ceil().max(Vec2::ZERO);
        let hi = (raster + Vec2::splat(r - 0.5)).floor().min(Vec2::new(
            self.size[0] as f32 - 1.0,
            self.size[1] as f32 - 1.0,
        ));
        let (x0, y0, x1, y1) = (lo.x as i64, lo.y as i64, hi.x as i64, hi.y as i64);
        (y0..=y1).flat_map(move |y| (x0..=x1).map(move |x| [x as u32, y as u32]))
    }

    /// The pixels whose filter covers the film position a ray from `lens`
    /// in world direction `toward` meets: those a light path connected to
    /// the camera along that ray contributes to.
    pub fn pixels_toward(
        &self,
        lens: &SceneVertex,
        toward: Vec3,
    ) -> impl Iterator<Item = [u32; 2]> {
        self.raster(lens, toward)
            .into_iter()
            .flat_map(|r| self.pixels_around(r))
    }

    /// The importance W(x₀ → x₁) of pixel `pixel` for a ray leaving camera
    /// vertex `lens` in direction `toward`: the density of the camera's own
    /// sampling of that ray (position times direction), over |cos| at the
    /// lens, so that camera paths estimate with weight one and light paths
    /// splat exactly what a camera path would have found.
    #[must_use]
    pub fn importance(&self, pixel: [u32; 2], lens: &SceneVertex, toward: Vec3) -> f64 {
        let strategy = self.position();
        let position = strategy.distribution(Prefix::forward(&[]));
        let p_lens = position.density(&Step::Vertex(*lens)).value();
        let p_direction = self.directions(pixel, lens).density(&toward).value();
        let cos = match lens.site {
            Site::Lens => f64::from(lens.geometric_normal.dot(toward).abs()),
            _ => 1.0,
        };
        if cos == 0.0 {
            return 0.0;
        }
        p_lens * p_direction / cos
    }
}

/// The camera vertex: a pinhole (a Dirac point) or a point on the lens
/// aperture by area.
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene) {
/// use aether_core::RandomSequence;
/// use aether_strategies::camera::Camera;
/// let camera = Camera::new(scene).unwrap();
/// let (position, direction) = (camera.position(), camera.direction(scene, [10, 20]));
/// let mut path = RandomSequence::new();
/// path.append(&position).append(&direction);
/// # }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct CameraPosition<'c>(&'c Camera);

impl Strategy<SceneVertex> for CameraPosition<'_> {
    fn distribution<'a>(
        &'a self,
        _prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let c = self.0;
        if c.lens_radius > 0.0 {
            let aperture = Planar::new(
                UniformDisk::new(c.lens_radius),
                c.origin,
                c.frame.s,
                c.frame.t,
            );
            Either::Right(OnSurface::new(aperture, move |p| {
                Some(SceneVertex::lens(p, c.frame.n))
            }))
        } else {
            Either::Left(DiracPoint::new(SceneVertex::point(c.origin, None), 1.0))
        }
    }
    fn memory(&self) -> usize {
        0
    }
    fn depth_class(&self, _prefix_len: usize) -> usize {
        0
    }
}

/// The first hit of a primary ray toward any point of the film, uniformly:
/// the camera edge of a Metropolis mutation that resamples it.
#[derive(Clone, Copy, Debug)]
pub struct FilmDirection<'a> {
    camera: &'a Camera,
    scene: &'a Scene,
}

impl<'a> FilmDirection<'a> {
    /// Primary rays of `camera` into `scene`.
    #[must_use]
    pub fn new(camera: &'a Camera, scene: &'a Scene) -> Self {
        FilmDirection { camera, scene }
    }
}

impl Strategy<SceneVertex> for FilmDirection<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let lens = prefix.last().expect("the camera vertex comes first");
        Intersect::new(lens, self.camera.film_directions(lens), self.scene)
    }
    fn memory(&self) -> usize {
        1
    }
}

/// The first hit of a primary ray toward a film point near `center`
/// (raster coordinates): Veach's lens perturbation of a path's first edge.
#[derive(Clone, Copy, Debug)]
pub struct PerturbedFilm<'a> {
    camera: &'a Camera,
    scene: &'a Scene,
    center: Vec2,
    offsets: ExponentialDisk,
}

impl<'a> PerturbedFilm<'a> {
    /// Rays toward `center` moved by `offsets` (pixels).
    #[must_use]
    pub fn new(
        camera: &'a Camera,
        scene: &'a Scene,
        center: Vec2,
        offsets: ExponentialDisk,
    ) -> Self {
        PerturbedFilm {
            camera,
            scene,
            center,
            offsets,
        }
    }
}

impl Strategy<SceneVertex> for PerturbedFilm<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let lens = prefix.last().expect("the camera vertex comes first");
        let directions = self
            .camera
            .perturbed_directions(lens, self.center, self.offsets);
        Intersect::new(lens, directions, self.scene)
    }
    fn memory(&self) -> usize {
        1
    }
}

/// The first hit of a primary ray of one pixel, from the camera vertex.
///
/// Its density, in area measure at the hit, is the filter's density on the
/// film, times the film → direction Jacobian, times |cos θ| / r².
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene) {
/// use aether_core::{Pcg32, RandomSequence};
/// use aether_strategies::camera::Camera;
/// let camera = Camera::new(scene).unwrap();
/// let (lens, pixel) = (camera.position(), camera.direction(scene, [0, 0]));
/// let mut rng = Pcg32::new(7, 0);
/// let mut path = RandomSequence::new();
/// if path.append_sample(&lens, &mut rng) && path.append_sample(&pixel, &mut rng) {
///     let first_hit = path.vertices()[1];
/// }
/// # }
/// ```
#[derive(Clone, Copy, Debug)]
pub struct CameraDirection<'a> {
    camera: &'a Camera,
    scene: &'a Scene,
    pixel: [u32; 2],
}

impl Strategy<SceneVertex> for CameraDirection<'_> {
    fn distribution<'a>(
        &'a self,
        prefix: Prefix<'a, SceneVertex>,
    ) -> impl Distribution<Value = Step<SceneVertex>> + 'a {
        let lens = prefix.last().expect("the camera vertex comes first");
        Intersect::new(lens, self.camera.directions(self.pixel, lens), self.scene)
    }
    fn memory(&self) -> usize {
        1
    }
    fn instance(&self) -> u64 {
        (u64::from(self.pixel[1]) << 32) | u64::from(self.pixel[0])
    }
    fn depth_class(&self, _prefix_len: usize) -> usize {
        0
    }
}
