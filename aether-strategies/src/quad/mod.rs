//! A four-wide BVH for processors rather than graphics cards: each node
//! holds its four children's boxes as floats, each leaf up to four
//! triangles side by side, so that one pass of four-lane arithmetic tests
//! four boxes or four triangles ([`Shear4::intersect`]).
//!
//! obvhs's compressed wide tree (eight children, boxes as bytes, leaves of
//! up to three triangles tested one by one) is laid out for a graphics
//! card's memory; on the Cornell box a ray spent more instructions on its
//! bookkeeping (the hit mask, the octant order, the quantized planes) than
//! on its triangles. This tree is collapsed from the same binary tree
//! (obvhs's PLOC build with reinsertion), so it bounds the same pieces; a
//! ray finds the same closest hit, and the same distance, up to which of
//! two triangles it keeps when both are hit at exactly the same distance.

use glam::{Vec3, Vec4};
use obvhs::ray::safe_inverse;

use crate::watertight::{Edges, Shear4};

mod build;

/// Pending children a ray through a tree of few levels holds: a tree is
/// kept in this form only if no ray can need more than [`DEEP`] (each node
/// adds at most three). Two sizes, because every ray clears its list: 64
/// entries for the Cornell box's rays cost path tracing 1.4 % more
/// instructions than 32 (a call to `memset` per ray).
const SHALLOW: usize = 32;

/// Pending children a ray through a deeper tree holds.
pub(super) const DEEP: usize = 64;

/// The bit of a child reference that marks a leaf.
const LEAF: u32 = 1 << 31;

/// Slack on a box's exit distance (pbrt's 1 + 2γ₃) for the rounding of the
/// slab distances; the boxes themselves are padded where they are built.
/// (A direction component below f32's ε is taken as ±ε, obvhs's
/// convention, as the old walk did: a ray almost parallel to a slab that
/// starts a hair outside it sees the slab end sooner than it does.)
const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// Four children's boxes: per axis, their lower then upper planes
/// (`planes[2 * axis + side]`), and what each child is. An empty slot has
/// an empty box (lower +∞, upper −∞), which no ray enters.
#[derive(Clone, Copy, Debug)]
struct Node {
    planes: [Vec4; 6],
    children: [u32; 4],
}

/// Up to four triangles side by side: `corners[vertex][axis]` holds the
/// triangles' coordinates in its lanes (NaN in unused lanes, which no ray
/// hits), the first triangle's position in the tree's order, and how many.
#[derive(Clone, Copy, Debug)]
struct Leaf {
    corners: [[Vec4; 3]; 3],
    first: u32,
    count: u32,
}

/// The four-wide tree: nodes, leaves and the child reference of the root.
#[derive(Debug)]
pub(crate) struct QuadBvh {
    nodes: Vec<Node>,
    leaves: Vec<Leaf>,
    root: u32,
    /// Whether a ray can need more than [`SHALLOW`] pending children.
    deep: bool,
}

/// A ray as the node test reads it: origin and inverse direction spread
/// over four lanes, and per axis which planes it enters and leaves by.
struct Slabs {
    origin: [Vec4; 3],
    inverse: [Vec4; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl Slabs {
    #[inline(always)]
    fn new(origin: Vec3, dir: Vec3) -> Self {
        // obvhs's inverse, whose tiny components stay finite, so that a
        // plane through the origin gives 0, never NaN.
        let inv = [dir.x, dir.y, dir.z].map(safe_inverse);
        let near = std::array::from_fn(|a| 2 * a + usize::from(inv[a] < 0.0));
        Slabs {
            origin: origin.to_array().map(Vec4::splat),
            inverse: inv.map(Vec4::splat),
            near,
            far: near.map(|n| n ^ 1),
        }
    }

    /// The children of `node` that the ray enters before `t_max`, as bits
    /// 0–3, and their entry distances.
    #[inline(always)]
    fn enter(&self, node: &Node, t_max: f32) -> (u32, Vec4) {
        let t = |plane: usize, a: usize| (node.planes[plane] - self.origin[a]) * self.inverse[a];
        let near = t(self.near[0], 0)
            .max(t(self.near[1], 1))
            .max(t(self.near[2], 2));
        let far = t(self.far[0], 0)
            .min(t(self.far[1], 1))
            .min(t(self.far[2], 2));
        // In this order a NaN distance (a ray with a NaN coordinate)
        // survives the clamps and enters nothing: SSE's max and min return
        // their second operand when one is NaN.
        let near = Vec4::ZERO.max(near);
        let far = Vec4::splat(t_max).min(far) * ROBUST;
        (near.cmple(far).bitmask(), near)
    }
}

impl QuadBvh {
    /// The closest triangle the ray from `origin` along `dir` (with
    /// `shear` set up for it) meets in (0, `t_max`), farther than the
    /// hit's rounding error: its distance, its position in the tree's order
    /// and its edge functions. `exact` is the scalar test of the triangle
    /// at a position, for the rare leaf where an edge function of a lane is
    /// exactly zero (an edge through the ray).
    #[inline(always)]
    pub(crate) fn closest(
        &self,
        shear: &Shear4,
        ray: (Vec3, Vec3),
        t_max: f32,
        exact: impl Fn(usize, f32) -> Option<(f32, Edges)>,
    ) -> Option<(f32, usize, Edges)> {
        if self.deep {
            self.closest_with::<DEEP>(shear, ray, t_max, &exact)
        } else {
            self.closest_with::<SHALLOW>(shear, ray, t_max, &exact)
        }
    }

    /// [`closest`](Self::closest) with room for `N` pending children.
    #[inline(always)]
    fn closest_with<const N: usize>(
        &self,
        shear: &Shear4,
        (origin, dir): (Vec3, Vec3),
        t_max: f32,
        exact: &impl Fn(usize, f32) -> Option<(f32, Edges)>,
    ) -> Option<(f32, usize, Edges)> {
        let slabs = Slabs::new(origin, dir);
        let mut best: Option<(f32, usize, Edges)> = None;
        let mut limit = t_max;
        let mut pending = [(0u32, 0f32); N];
        let mut len = 0;
        let mut at = self.root;
        loop {
            if at & LEAF == 0 {
                let node = &self.nodes[at as usize];
                let (mask, near) = slabs.enter(node, limit);
                if mask != 0 {
                    let near = near.to_array();
                    let first = (mask.trailing_zeros() & 3) as usize;
                    let rest = mask & (mask - 1);
                    if rest == 0 {
                        at = node.children[first];
                        continue;
                    }
                    let second = (rest.trailing_zeros() & 3) as usize;
                    if rest & (rest - 1) == 0 {
                        // Two: the nearer next, the other pending.
                        let (a, b) = if near[second] < near[first] {
                            (second, first)
                        } else {
                            (first, second)
                        };
                        debug_assert!(len < N, "more pending children than the build bounds");
                        if let Some(slot) = pending.get_mut(len) {
                            *slot = (node.children[b], near[b]);
                            len += 1;
                        }
                        at = node.children[a];
                        continue;
                    }
                    // More: the nearest next, the others pending far to near.
                    let mut entered = [(0u32, 0f32); 4];
                    let mut n = 0;
                    for (k, (&child, &t)) in node.children.iter().zip(&near).enumerate() {
                        if mask & (1 << k) != 0 {
                            entered[n] = (child, t);
                            n += 1;
                        }
                    }
                    sort_far_to_near(&mut entered[..n]);
                    for &e in &entered[..n - 1] {
                        debug_assert!(len < N, "more pending children than the build bounds");
                        if let Some(slot) = pending.get_mut(len) {
                            *slot = e;
                            len += 1;
                        }
                    }
                    at = entered[n - 1].0;
                    continue;
                }
            } else {
                let leaf = &self.leaves[(at & !LEAF) as usize];
                let found = match shear.intersect(&leaf.corners, limit) {
                    Some(hits) => hits.nearest().map(|k| {
                        let (t, edges) = hits.lane(k);
                        (t, k, edges)
                    }),
                    None => (0..leaf.count as usize)
                        .filter_map(|k| {
                            exact(leaf.first as usize + k, limit).map(|(t, e)| (t, k, e))
                        })
                        .fold(None, nearer),
                };
                if let Some((t, k, edges)) = found {
                    limit = t;
                    best = Some((t, leaf.first as usize + k, edges));
                }
            }
            // The next pending child the ray may still meet before its hit.
            loop {
                if len == 0 {
                    return best;
                }
                len -= 1;
                let (child, near) = pending[len];
                // As the node test's slack: a box entered where the hit
                // was found, give or take rounding, may hold a nearer hit.
                if near <= limit * ROBUST {
                    at = child;
                    break;
                }
            }
        }
    }

    /// True if the ray from `origin` along `dir` (with `shear` set up for
    /// it) meets a triangle in (0, `t_max`); `exact` as for
    /// [`closest`](Self::closest). Stops at the first it finds.
    #[inline(always)]
    pub(crate) fn blocked(
        &self,
        shear: &Shear4,
        ray: (Vec3, Vec3),
        t_max: f32,
        exact: impl Fn(usize, f32) -> bool,
    ) -> bool {
        if self.deep {
            self.blocked_with::<DEEP>(shear, ray, t_max, &exact)
        } else {
            self.blocked_with::<SHALLOW>(shear, ray, t_max, &exact)
        }
    }

    /// [`blocked`](Self::blocked) with room for `N` pending children.
    #[inline(always)]
    fn blocked_with<const N: usize>(
        &self,
        shear: &Shear4,
        (origin, dir): (Vec3, Vec3),
        t_max: f32,
        exact: &impl Fn(usize, f32) -> bool,
    ) -> bool {
        let slabs = Slabs::new(origin, dir);
        let mut pending = [0u32; N];
        let mut len = 0;
        let mut at = self.root;
        loop {
            if at & LEAF == 0 {
                let node = &self.nodes[at as usize];
                let (mut mask, _) = slabs.enter(node, t_max);
                if mask != 0 {
                    at = node.children[mask.trailing_zeros() as usize];
                    mask &= mask - 1;
                    while mask != 0 {
                        debug_assert!(len < N, "more pending children than the build bounds");
                        if let Some(slot) = pending.get_mut(len) {
                            *slot = node.children[mask.trailing_zeros() as usize];
                            len += 1;
                        }
                        mask &= mask - 1;
                    }
                    continue;
                }
            } else {
                let leaf = &self.leaves[(at & !LEAF) as usize];
                let hit = match shear.intersect(&leaf.corners, t_max) {
                    Some(hits) => hits.mask != 0,
                    None => (0..leaf.count as usize).any(|k| exact(leaf.first as usize + k, t_max)),
                };
                if hit {
                    return true;
                }
            }
            if len == 0 {
                return false;
            }
            len -= 1;
            at = pending[len];
        }
    }
}

/// The nearer of a hit found so far and another.
fn nearer<T>(best: Option<(f32, usize, T)>, hit: (f32, usize, T)) -> Option<(f32, usize, T)> {
    match best {
        Some(b) if b.0 <= hit.0 => Some(b),
        _ => Some(hit),
    }
}

/// Sorts up to four entered children by decreasing entry distance.
#[inline(always)]
fn sort_far_to_near(e: &mut [(u32, f32)]) {
    for i in 1..e.len() {
        let mut j = i;
        while j > 0 && e[j - 1].1 < e[j].1 {
            e.swap(j - 1, j);
            j -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::watertight::Shear;
    use aether_core::{Pcg32, UniformSource};

    /// Random triangles, some large (split into pieces by the build) and
    /// some axis-aligned (flat boxes), and rays through and around them.
    fn scene(seed: u64, count: usize) -> Vec<[Vec3; 3]> {
        let mut rng = Pcg32::new(seed, 1);
        let mut u = || rng.next_f32();
        (0..count)
            .map(|i| {
                let a = Vec3::new(u(), u(), u()) * 10.0 - 5.0;
                let size = if i % 13 == 0 { 8.0 } else { 1.0 };
                let (b, c) = (
                    a + Vec3::new(u(), u(), u()) * size,
                    a + Vec3::new(u(), u(), u()) * size,
                );
                if i % 5 == 0 {
                    [a, Vec3::new(b.x, b.y, a.z), Vec3::new(c.x, c.y, a.z)]
                } else {
                    [a, b, c]
                }
            })
            .collect()
    }

    /// The closest hit by testing every triangle: distance and triangle.
    fn brute(tris: &[[Vec3; 3]], (o, d, t_max): (Vec3, Vec3, f32)) -> Option<(f32, usize)> {
        let shear = Shear::new(o, d);
        let mut best: Option<(f32, usize)> = None;
        for (i, t) in tris.iter().enumerate() {
            if let Some((t, _)) = shear.intersect(t, 0.0, best.map_or(t_max, |b| b.0)) {
                best = Some((t, i));
            }
        }
        best
    }

    /// The four-wide tree of `tris`, its order of them, and the triangles
    /// in that order (as `Geometry` keeps them, for the scalar test).
    fn tree(tris: &[[Vec3; 3]]) -> (QuadBvh, Vec<u32>, Vec<[Vec3; 3]>) {
        let b = crate::bvh::build_binary(tris, &[]).expect("a tree");
        let (quad, order) = QuadBvh::of(&b, tris).expect("a four-wide tree");
        let ordered = order.iter().map(|&i| tris[i as usize]).collect();
        (quad, order, ordered)
    }

    #[test]
    fn rays_find_the_closest_triangle_and_any_triangle() {
        let mut deep = 0;
        for (seed, count) in [(3, 1), (4, 3), (5, 40), (6, 500), (7, 20000)] {
            let tris = scene(seed, count);
            let (quad, order, ordered) = tree(&tris);
            deep += usize::from(quad.deep);
            let mut hits = 0;
            // Fewer rays through the large scene: each is tested against
            // every triangle.
            for ray in crate::bvh::random_rays(seed, if count > 1000 { 400 } else { 3000 }) {
                let (o, d, t_max) = ray;
                let shear = Shear::new(o, d);
                let exact = |id: usize, t: f32| shear.intersect(&ordered[id], 0.0, t);
                let found = quad.closest(&Shear4::new(o, d), (o, d), t_max, exact);
                let expected = brute(&tris, ray);
                assert_eq!(found.map(|f| f.0), expected.map(|e| e.0), "{ray:?}");
                if let (Some(f), Some(e)) = (found, expected) {
                    assert_eq!(tris[order[f.1] as usize], tris[e.1]);
                }
                let blocked = quad.blocked(&Shear4::new(o, d), (o, d), t_max, |id, t| {
                    exact(id, t).is_some()
                });
                assert_eq!(blocked, expected.is_some());
                hits += usize::from(blocked);
            }
            if (10..1000).contains(&count) {
                assert!(hits > 100, "{hits} hits");
            }
        }
        // Both sizes of the pending list.
        assert!((1..5).contains(&deep), "{deep} deep trees");
    }

    /// A floor of unit squares at z = 0, two triangles each, corners on
    /// integers: rays through its shared edges and corners meet edge
    /// functions that are exactly zero.
    fn floor() -> Vec<[Vec3; 3]> {
        let mut tris = Vec::new();
        for i in -4..4 {
            for j in -4..4 {
                let p = |x: i32, y: i32| Vec3::new(x as f32, y as f32, 0.0);
                tris.push([p(i, j), p(i + 1, j), p(i + 1, j + 1)]);
                tris.push([p(i, j), p(i + 1, j + 1), p(i, j + 1)]);
            }
        }
        tris
    }

    #[test]
    fn rays_through_shared_edges_and_corners_hit_the_floor() {
        let tris = floor();
        let (quad, _, ordered) = tree(&tris);
        for x in -6..=6 {
            for y in -6..=6 {
                // Through a corner, an edge or a diagonal at (x/2, y/2, 0):
                // straight down, and slanted.
                let target = Vec3::new(x as f32 * 0.5, y as f32 * 0.5, 0.0);
                for d in [Vec3::NEG_Z, Vec3::new(0.5, 0.0, -1.0).normalize()] {
                    let o = target - d * (2.0 / -d.z);
                    let shear = Shear::new(o, d);
                    let exact = |id: usize, t: f32| shear.intersect(&ordered[id], 0.0, t);
                    let found = quad.closest(&Shear4::new(o, d), (o, d), f32::INFINITY, exact);
                    let expected = brute(&tris, (o, d, f32::INFINITY));
                    assert_eq!(found.map(|f| f.0), expected.map(|e| e.0), "{o} {d}");
                    let blocked =
                        quad.blocked(&Shear4::new(o, d), (o, d), f32::INFINITY, |id, t| {
                            exact(id, t).is_some()
                        });
                    assert_eq!(blocked, expected.is_some());
                    // Inside the floor nothing slips through an edge.
                    if target.x.abs() < 4.0 && target.y.abs() < 4.0 {
                        assert!(found.is_some(), "{o} {d} fell through");
                    }
                }
            }
        }
    }

    #[test]
    fn a_ray_leaving_the_floor_does_not_hit_it() {
        let tris = floor();
        let (quad, _, ordered) = tree(&tris);
        let mut rng = Pcg32::new(11, 3);
        let mut u = || rng.next_f32();
        for _ in 0..2000 {
            // A point exactly on the plane, no offset, leaving upwards at
            // any angle: its own triangle is a rounding error away.
            let o = Vec3::new(u() * 7.0 - 3.5, u() * 7.0 - 3.5, 0.0);
            let d = Vec3::new(u() - 0.5, u() - 0.5, u() * 0.5 + 1e-3).normalize();
            let shear = Shear::new(o, d);
            let exact = |id: usize, t: f32| shear.intersect(&ordered[id], 0.0, t);
            let found = quad.closest(&Shear4::new(o, d), (o, d), f32::INFINITY, exact);
            assert!(
                found.is_none(),
                "{o} {d} hit its own floor at {found:?}",
                found = found.map(|f| f.0)
            );
            assert!(brute(&tris, (o, d, f32::INFINITY)).is_none());
        }
    }
}
