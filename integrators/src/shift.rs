//! The shift of gradient-domain path tracing: a base path moved into a
//! neighbouring pixel by replaying its uniforms there (the camera ray
//! moves by one pixel, then every step samples again from the same
//! uniforms) until the first pair of rough vertices, where the offset
//! reconnects to the base path and copies it from there. Its Jacobian is a
//! ratio of the language's conditional densities of the replayed steps
//! ([`replay_jacobian`]); no density is written here.

use std::cell::{Cell, OnceCell};

use aether_core::{Pcg32, RandomSequence, replay_jacobian};
use aether_strategies::camera::{CameraDirection, CameraPosition};
use aether_strategies::integrand::{Integrand, visible};
use aether_strategies::lights::DirectEmitter;
use aether_strategies::scattering::BsdfSampling;
use aether_strategies::scene::Scene;
use aether_strategies::subpath::{End, Subpath};
use aether_strategies::vertex::SceneVertex;
use glam::DVec3;

/// The shift of the base path into one neighbour, as far as it has got.
pub(crate) struct Offset<'a> {
    /// The offset path.
    pub(crate) path: RandomSequence<'a, SceneVertex>,
    sub: Subpath<'a>,
    importance: f64,
    /// |∂ȳ/∂x̄| of the vertices replayed so far.
    jacobian: f64,
    /// Where the offset reconnected to the base path, which it copies from
    /// there on.
    pub(crate) joined_at: Option<usize>,
    /// Its density over the base's under the same technique, once the
    /// vertices that differ no longer condition the last ones.
    pub(crate) ratio: Cell<Option<f64>>,
}

/// An offset of the base path's length, its value and its Jacobian.
pub(crate) type Shifted<'o, 'a> = Option<(&'o Offset<'a>, DVec3, f64)>;

/// The shift of a scene: where it reconnects.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Shift<'s> {
    scene: &'s Scene,
    /// Vertices at most this rough count as specular.
    threshold: f32,
}

/// The shifts of one base path into the four neighbours.
pub(crate) struct Offsets<'a> {
    shift: Shift<'a>,
    /// By neighbour; `None` outside the crop window or once the shift failed.
    all: [Option<Offset<'a>>; 4],
}

impl<'s> Shift<'s> {
    /// The shift of `scene`, which reconnects at vertices rougher than
    /// `threshold`.
    pub(crate) fn new(scene: &'s Scene, threshold: f32) -> Self {
        Shift { scene, threshold }
    }

    /// The base's camera ray, drawn from `start`, replayed toward each
    /// neighbour `j` through `looks[d]` and `lens`.
    pub(crate) fn start<'a>(
        self,
        f: Integrand<'a>,
        lens: &'a CameraPosition<'a>,
        looks: &'a [CameraDirection<'a>],
        neighbours: &[Option<[u32; 2]>; 4],
        base: &RandomSequence<'a, SceneVertex>,
        start: &Pcg32,
    ) -> Offsets<'a>
    where
        's: 'a,
    {
        // Built in place: an offset is kilobytes of inline vertices, and
        // moving four of them per sample showed up as memcpy in profiles.
        let mut all: [Option<Offset<'a>>; 4] = [None, None, None, None];
        for (d, slot) in all.iter_mut().enumerate() {
            let Some(j) = neighbours[d] else { continue };
            let o = slot.insert(Offset {
                path: RandomSequence::new(),
                sub: Subpath::new(f, End::Camera),
                importance: 0.0,
                jacobian: 0.0,
                joined_at: None,
                ratio: Cell::new(None),
            });
            if !o
                .path
                .append(lens)
                .append_sample(&looks[d], &mut start.clone())
            {
                *slot = None;
                continue;
            }
            o.sub.extend(o.path.vertices());
            o.importance = f.importance(j, o.path.vertices());
            o.jacobian = replay_jacobian(base, &o.path, 0..2);
        }
        Offsets { shift: self, all }
    }
}

impl<'a> Offsets<'a> {
    /// The offsets of `n` vertices, with what their last vertex emits
    /// toward the camera.
    pub(crate) fn emitted(&self, n: usize) -> [Shifted<'_, 'a>; 4] {
        self.all.each_ref().map(|o| {
            let o = o.as_ref().filter(|o| o.path.len() == n)?;
            Some((o, o.sub.emitted(n) * o.importance, o.jacobian))
        })
    }

    /// Extends every offset by the base's direct-lighting vertex `lamp`
    /// (vertex `n`): copied where the offset has reconnected (`clear` tells
    /// whether the shared edge to it is unoccluded), replayed from `replay`
    /// otherwise; returns their connections' values.
    pub(crate) fn connect_lamp(
        &mut self,
        base: &RandomSequence<'a, SceneVertex>,
        direct: &'a DirectEmitter<'a, 'a>,
        replay: &Pcg32,
        clear: &dyn Fn() -> bool,
    ) -> [Shifted<'_, 'a>; 4] {
        let n = base.len() - 1;
        let lamp = base.vertices()[n];
        let mut jacobians = [0.0; 4];
        for (o, jacobian) in self.all.iter_mut().zip(&mut jacobians) {
            let Some(o) = o else { continue };
            *jacobian = if o.joined_at.is_some() {
                o.path.extend_from(base, n..n + 1, false);
                o.jacobian
            } else if o.sub.connectible(n - 1) && o.path.append_sample(direct, &mut replay.clone())
            {
                o.jacobian * replay_jacobian(base, &o.path, n..n + 1)
            } else {
                0.0
            };
        }
        std::array::from_fn(|d| {
            let o = self.all[d].as_ref().filter(|o| o.path.len() == n + 1)?;
            let fy = if o.joined_at.is_none() {
                o.sub.connect_lamp(n, &o.path.vertices()[n])
            } else {
                let fy = o.sub.connect_lamp_unoccluded(n, &lamp);
                if fy != DVec3::ZERO && clear() {
                    fy
                } else {
                    DVec3::ZERO
                }
            };
            Some((o, fy * o.importance, jacobians[d]))
        })
    }

    /// Takes every offset back to `n` vertices.
    pub(crate) fn truncate(&mut self, n: usize) {
        for o in self.all.iter_mut().flatten() {
            o.path.truncate(n);
        }
    }

    /// Moves every offset on to the base path's new last vertex (sampled
    /// by `bsdf` from `replay`'s uniforms), dropping those whose shift fails.
    pub(crate) fn advance(
        &mut self,
        base: &RandomSequence<'a, SceneVertex>,
        eye: &Subpath<'_>,
        bsdf: &'a BsdfSampling<'a>,
        replay: &Pcg32,
    ) {
        let Shift { scene, threshold } = self.shift;
        for slot in &mut self.all {
            if slot
                .as_mut()
                .is_some_and(|o| !advance(scene, threshold, o, base, eye, bsdf, replay))
            {
                *slot = None;
            }
        }
    }
}

/// A shared edge's visibility, tested once for every offset that copies it.
pub(crate) fn once(test: impl Fn() -> bool) -> impl Fn() -> bool {
    let known = OnceCell::new();
    move || *known.get_or_init(&test)
}

/// Moves `offset` on to the base path's new last vertex x: copied if the
/// offset has reconnected; reconnected (if the edge to x is clear) when x
/// and the last vertices of both paths are rough; replayed from `replay`'s
/// uniforms otherwise. False if the shift fails.
///
/// The shift must be its own inverse, so every decision is symmetric in the
/// two paths: where both last vertices are rough, x is specular and the
/// replayed vertex rough, the shift back would reconnect to that vertex,
/// and this one fails instead.
fn advance<'a>(
    scene: &Scene,
    threshold: f32,
    offset: &mut Offset<'a>,
    base: &RandomSequence<'a, SceneVertex>,
    eye: &Subpath<'_>,
    bsdf: &'a BsdfSampling<'a>,
    replay: &Pcg32,
) -> bool {
    let n = base.len() - 1;
    let x = base.vertices()[n];
    let rough = |s: &Subpath<'_>, i: usize| s.bsdf(i).is_some_and(|b| b.is_rougher_than(threshold));
    let both_rough = rough(eye, n - 1) && rough(&offset.sub, n - 1);
    if offset.joined_at.is_some() || (both_rough && rough(eye, n)) {
        if offset.joined_at.is_none() && !visible(scene, offset.sub.vertex(n - 1), &x) {
            return false;
        }
        offset.path.extend_from(base, n..n + 1, false);
        offset.sub.push(x);
        offset.joined_at.get_or_insert(n);
        return true;
    }
    if !offset.path.append_sample(bsdf, &mut replay.clone()) {
        return false;
    }
    offset.jacobian *= replay_jacobian(base, &offset.path, n..n + 1);
    offset.sub.push(offset.path.vertices()[n]);
    !(both_rough && rough(&offset.sub, n)) && offset.jacobian.is_finite() && offset.jacobian > 0.0
}
