//! Subpaths with the integrand's running products, so that joining a camera
//! subpath to a light subpath costs one connection's factors, not a pass
//! over the whole path.

use aether_core::{INLINE_VERTICES, Pooled, Recycle};
use glam::{DVec3, Vec3};

use crate::bsdf::Bsdf;
use crate::integrand::{Integrand, geometry_term_along};
use crate::vertex::SceneVertex;

/// The end of the path a subpath starts from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum End {
    /// The camera: the first vertex is on the lens.
    Camera,
    /// A light: the first vertex is on an emitter.
    Light,
}

/// The vertices of a subpath, their BSDFs, and for each prefix the factors
/// of f(x̄) that the prefix alone fixes: the geometry terms of its edges and
/// the BSDF values at its vertices but the last (for a light subpath, the
/// emission of its first vertex too). The camera's importance is left out,
/// since it depends on the pixel.
///
/// ```
/// # fn f(scene: &aether_strategies::scene::Scene, camera: &aether_strategies::camera::Camera,
/// #      lights: &aether_strategies::lights::Lights, eye: &[aether_strategies::vertex::SceneVertex],
/// #      lamp: aether_strategies::vertex::SceneVertex) {
/// use aether_strategies::integrand::Integrand;
/// use aether_strategies::subpath::{End, Subpath};
/// let f = Integrand::new(scene, camera, lights);
/// let camera_side = Subpath::of(f, End::Camera, eye);
/// // f(x̄) of the eye's vertices followed by the lamp, without importance.
/// let throughput = camera_side.connect_lamp(eye.len(), &lamp);
/// # }
/// ```
#[derive(Clone, Debug)]
pub struct Subpath<'a> {
    f: Integrand<'a>,
    end: End,
    /// One list, not one per field: each list checks where its items live
    /// (inline or on the heap) at every access.
    nodes: Pooled<[Node<'a>; INLINE_VERTICES]>,
}

/// A vertex of a subpath with what the subpath keeps for it.
#[derive(Clone, Copy, Debug)]
struct Node<'a> {
    vertex: SceneVertex,
    bsdf: Option<Bsdf<'a>>,
    /// The unit direction to the vertex before (none for the first): every
    /// BSDF value at the vertex needs it, and the emission toward the
    /// camera of a camera subpath's vertex on a light.
    back: Option<Vec3>,
    /// The factors of f that the subpath up to this vertex fixes.
    product: DVec3,
}

impl Recycle for Node<'_> {
    type Static = Node<'static>;
}

impl<'a> Subpath<'a> {
    /// The empty subpath from `end`.
    #[must_use]
    pub fn new(f: Integrand<'a>, end: End) -> Self {
        Subpath {
            f,
            end,
            nodes: Pooled::new(),
        }
    }

    /// The subpath from `end` through `vertices`. It is returned by value
    /// (about 2.5 KB, copied): [`new`](Self::new) and [`extend`](Self::extend)
    /// build it in place (a path tracer's 1 % of instructions).
    #[must_use]
    pub fn of(f: Integrand<'a>, end: End, vertices: &[SceneVertex]) -> Self {
        let mut s = Subpath::new(f, end);
        s.extend(vertices);
        s
    }

    /// Appends vertices, each sampled from the one before.
    pub fn extend(&mut self, vertices: &[SceneVertex]) {
        for v in vertices {
            self.push(*v);
        }
    }

    /// Number of vertices.
    #[must_use]
    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    /// True if there are no vertices.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// Vertex `i`, counted from the subpath's end.
    ///
    /// # Panics
    /// If there are not `i + 1` vertices.
    #[must_use]
    pub fn vertex(&self, i: usize) -> &SceneVertex {
        &self.nodes[i].vertex
    }

    /// The BSDF at vertex `i`, if it lies on a surface.
    #[must_use]
    pub fn bsdf(&self, i: usize) -> Option<&Bsdf<'a>> {
        self.nodes[i].bsdf.as_ref()
    }

    /// The factors of f that the first `i + 1` vertices fix (see [`Subpath`]).
    #[must_use]
    pub fn product(&self, i: usize) -> DVec3 {
        self.nodes[i].product
    }

    /// True if a connection can end at vertex `i`: it is not on a purely
    /// specular surface.
    #[must_use]
    pub fn connectible(&self, i: usize) -> bool {
        self.nodes[i].bsdf.is_none_or(|b| !b.is_dirac())
    }

    /// Keeps the first `len` vertices.
    pub fn truncate(&mut self, len: usize) {
        self.nodes.truncate(len);
    }

    /// Appends a vertex sampled from the last one (its edge needs no
    /// visibility test).
    pub fn push(&mut self, v: SceneVertex) {
        let (product, back) = match self.nodes.last() {
            None => (DVec3::ONE, None),
            // The edge's direction, which the factor at the last vertex,
            // the geometry term and the new vertex's BSDF values all need,
            // found once (each was a square root and a division).
            Some(last) => match last.vertex.directions_between(&v) {
                Some((out, back)) => (self.product_along(self.len() - 1, &v, out), Some(back)),
                None => (DVec3::ZERO, None),
            },
        };
        let bsdf = Bsdf::at(self.f.scene(), &v);
        self.nodes.push(Node {
            vertex: v,
            bsdf,
            back,
            product,
        });
    }

    /// The factors of f that the first `i + 1` vertices fix, followed by a
    /// vertex `next` in unit direction `out` from vertex `i`: their
    /// product, times the factor at `i` ([`factor_toward`](Self::factor_toward)),
    /// times the edge's geometry term.
    #[inline(always)]
    fn product_along(&self, i: usize, next: &SceneVertex, out: Vec3) -> DVec3 {
        let node = &self.nodes[i];
        let g = geometry_term_along(&node.vertex, next, out);
        node.product * self.factor_toward(i, out) * f64::from(g)
    }

    /// The factor of f at vertex `i` when the vertex after it on the way
    /// away from this subpath's end lies in unit direction `out`: the BSDF
    /// value, or at a light's first vertex its emission along `out`.
    fn factor_toward(&self, i: usize, out: Vec3) -> DVec3 {
        let node = &self.nodes[i];
        if i == 0 {
            return match self.end {
                End::Camera => DVec3::ONE,
                End::Light => self.f.emitted(&node.vertex, out).as_dvec3(),
            };
        }
        let (Some(bsdf), Some(back)) = (&node.bsdf, node.back) else {
            return DVec3::ZERO;
        };
        let value = match self.end {
            End::Camera => bsdf.eval(out, back),
            End::Light => bsdf.eval(back, out),
        };
        value.as_dvec3()
    }

    /// f(x̄) without importance for the camera subpath's first `s` vertices
    /// when the last of them is on a light: zero otherwise.
    #[must_use]
    pub fn emitted(&self, s: usize) -> DVec3 {
        // Most vertices are on no light: asked first, before the direction.
        if s < 2 || self.end != End::Camera {
            return DVec3::ZERO;
        }
        let node = &self.nodes[s - 1];
        if !self.f.on_light(&node.vertex) {
            return DVec3::ZERO;
        }
        let Some(out) = node.back else {
            return DVec3::ZERO;
        };
        let radiance: Vec3 = self.f.emitted(&node.vertex, out);
        node.product * radiance.as_dvec3()
    }

    /// f(x̄) without importance for this camera subpath's first `s`
    /// vertices joined to `light`'s first `t` (s, t ≥ 1), the connecting
    /// edge tested for visibility.
    #[must_use]
    pub fn connect(&self, s: usize, light: &Subpath<'_>, t: usize) -> DVec3 {
        if s == 0 || t == 0 || light.end != End::Light {
            return DVec3::ZERO;
        }
        let (c, l) = (&self.nodes[s - 1].vertex, &light.nodes[t - 1].vertex);
        let Some((out, back)) = c.directions_between(l) else {
            return DVec3::ZERO;
        };
        let beyond = light.factor_toward(t - 1, back) * light.nodes[t - 1].product;
        self.join(s, l, out, beyond)
    }

    /// f(x̄) without importance for this camera subpath's first `s`
    /// vertices followed by `lamp`, a point on a light (as sampled by direct
    /// emitter sampling), the edge to it tested for visibility.
    #[must_use]
    pub fn connect_lamp(&self, s: usize, lamp: &SceneVertex) -> DVec3 {
        self.toward_lamp(s, lamp)
            .map_or(DVec3::ZERO, |(out, beyond)| self.join(s, lamp, out, beyond))
    }

    /// As [`connect_lamp`](Self::connect_lamp) for an edge whose visibility
    /// the caller already knows (a path shifted from another that shares
    /// it): no shadow ray is cast.
    #[must_use]
    pub fn connect_lamp_unoccluded(&self, s: usize, lamp: &SceneVertex) -> DVec3 {
        self.toward_lamp(s, lamp)
            .map_or(DVec3::ZERO, |(out, beyond)| {
                self.unoccluded(s, lamp, out, beyond)
            })
    }

    /// The direction from this subpath's vertex `s − 1` to `lamp` (s ≥ 1),
    /// and what `lamp` emits back along it.
    fn toward_lamp(&self, s: usize, lamp: &SceneVertex) -> Option<(Vec3, DVec3)> {
        let c = &self.nodes[s.checked_sub(1)?].vertex;
        let (out, back) = c.directions_between(lamp)?;
        Some((out, self.f.emitted(lamp, back).as_dvec3()))
    }

    /// f(x̄) for the first `s` vertices joined to a light-side vertex `l`
    /// in direction `out` from the last of them, whose factors of f beyond
    /// the edge multiply to `beyond`.
    fn join(&self, s: usize, l: &SceneVertex, out: Vec3, beyond: DVec3) -> DVec3 {
        let f = self.unoccluded(s, l, out, beyond);
        if f == DVec3::ZERO || !self.f.visible(&self.nodes[s - 1].vertex, l) {
            return DVec3::ZERO;
        }
        f
    }

    /// As [`join`](Self::join), without the visibility test.
    fn unoccluded(&self, s: usize, l: &SceneVertex, out: Vec3, beyond: DVec3) -> DVec3 {
        if s == 0 || self.end != End::Camera || beyond == DVec3::ZERO {
            return DVec3::ZERO;
        }
        self.product_along(s - 1, l, out) * beyond
    }
}
