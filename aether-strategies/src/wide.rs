//! The BVH as rays read it: obvhs's compressed wide nodes with their
//! children's quantized planes turned into floats once, when the tree is
//! built, rather than at every node a ray visits; traversed by obvhs's own
//! `traverse!` loop.
//!
//! A node stores each child's box as bytes on a grid of the node's box.
//! obvhs's node test converts those 48 bytes to floats at every visit,
//! about a sixth of a ray's instructions on the Cornell box, and decodes
//! where each child's hit goes in the traversal's mask for the ray's
//! octant. The floats here are those conversions' exact results, used in
//! the same arithmetic in the same order, and the masks are decoded once
//! per octant, so the tree finds the same children in the same order as
//! obvhs's test (this file's tests check it, node by node and ray by ray),
//! and images stay the same to the bit. The price is memory: 496 bytes a
//! node instead of 80, so only trees of up to [`WIDE_NODES`] nodes
//! are kept this way; larger ones keep obvhs's nodes (on grids of 200 000
//! and a million triangles, decoded nodes rendered no faster), and so do
//! trees of more than [`STACK`] levels, deeper than the short traversal
//! stack of decoded trees ([`crate::traversal`]).

// `UVec2` is named by obvhs's `traverse!` loop.
use glam::{UVec2, Vec3, Vec3A, Vec4};
use obvhs::bvh2::Bvh2;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::ray::{Ray, RayHit};

use crate::quad::QuadBvh;
use crate::traversal::{STACK, Walk, octant_inv4};

/// Trees of up to this many nodes (tens of thousands of triangles) are
/// decoded: about 8 MB.
pub(crate) const WIDE_NODES: usize = 1 << 14;

/// The smallest entry distance obvhs's node test accepts, which this test
/// must share to find the same children.
const NEAREST: f32 = 0.0001;

/// The fields of a compressed node that obvhs's `traverse!` loop reads (the
/// first three, by these names), with the node's grid, its children's
/// planes as floats and their hit-mask bits per octant.
#[derive(Clone, Copy, Debug)]
pub(crate) struct WideNode {
    child_base_idx: u32,
    primitive_base_idx: u32,
    imask: u8,
    /// The origin of the node's grid, as obvhs's test finds it at every visit.
    origin: Vec3A,
    /// The grid's cell size per axis (powers of two), as obvhs's test
    /// decodes it from the node's exponents at every visit.
    extent: Vec3A,
    /// Per axis, the children's lower then upper planes, children 0–3 in
    /// the first vector and 4–7 in the second.
    planes: [[[Vec4; 2]; 2]; 3],
    /// Per ray octant (its direction's signs, [`octant`]), what each child
    /// adds to the hit mask when the ray enters it: obvhs's
    /// `get_child_and_index_bits` decoded once per node rather than at
    /// every visit.
    bits: [[u32; 8]; 8],
}

impl WideNode {
    fn new(node: &CwBvhNode) -> Self {
        let floats = |q: &[u8; 8]| {
            let f = q.map(f32::from);
            [
                Vec4::new(f[0], f[1], f[2], f[3]),
                Vec4::new(f[4], f[5], f[6], f[7]),
            ]
        };
        let bits = std::array::from_fn(|o| {
            let (child, index) = node.get_child_and_index_bits(octant_of(o));
            std::array::from_fn(|j| {
                let shift = 8 * j;
                (((child >> shift) & 0xff) as u32) << (((index >> shift) & 0xff) as u32)
            })
        });
        WideNode {
            child_base_idx: node.child_base_idx,
            primitive_base_idx: node.primitive_base_idx,
            imask: node.imask,
            origin: Vec3A::from(node.p),
            extent: node.compute_extent(),
            planes: [
                [floats(&node.child_min_x), floats(&node.child_max_x)],
                [floats(&node.child_min_y), floats(&node.child_max_y)],
                [floats(&node.child_min_z), floats(&node.child_max_z)],
            ],
            bits,
        }
    }

    /// The hit mask of obvhs's node test (`CwBvhNode::intersect_ray`): the
    /// children the ray enters before `ray.tmax`, in the traversal order
    /// that `oct_inv4` (the ray's octant) gives them.
    #[inline(always)]
    fn hits(&self, ray: &Ray, oct_inv4: u32) -> u32 {
        let scale = self.extent * ray.inv_direction;
        let start = (self.origin - ray.origin) * ray.inv_direction;
        let negative = [
            ray.direction.x < 0.0,
            ray.direction.y < 0.0,
            ray.direction.z < 0.0,
        ];
        let bits = &self.bits[octant(oct_inv4)];
        let mut mask = 0;
        for half in 0..2 {
            // Entry and exit distances of the four children's slabs on one axis.
            let slab = |axis: usize| {
                let [lo, hi] = self.planes[axis].map(|p| p[half]);
                let (near, far) = if negative[axis] { (hi, lo) } else { (lo, hi) };
                let (a, b) = (Vec4::splat(scale[axis]), Vec4::splat(start[axis]));
                (near * a + b, far * a + b)
            };
            let (x, y, z) = (slab(0), slab(1), slab(2));
            let near = x.0.max(y.0.max(z.0)).max(Vec4::splat(NEAREST));
            let far = x.1.min(y.1.min(z.1)).min(Vec4::splat(ray.tmax));
            let entered = near.cmple(far).bitmask();
            for j in 0..4 {
                if entered & (1 << j) != 0 {
                    mask |= bits[4 * half + j];
                }
            }
        }
        mask
    }
}

/// The octant of index `o` as obvhs's traversal encodes it: that of a
/// direction whose x, y and z are not negative where bits 2, 1 and 0 of
/// `o` are set ([`crate::traversal::octant_inv4`]).
fn octant_of(o: usize) -> u32 {
    let sign = |bit: usize| if o & bit != 0 { 1.0 } else { -1.0 };
    octant_inv4(Vec3A::new(sign(4), sign(2), sign(1)))
}

/// The index `o` of an octant, [`octant_of`]'s inverse: the encoding
/// repeats one byte, whose low three bits are those of `o`.
#[inline(always)]
fn octant(oct_inv4: u32) -> usize {
    (oct_inv4 & 7) as usize
}

/// A tree of [`WideNode`]s: obvhs's traversal over decoded nodes.
#[derive(Debug)]
pub(crate) struct WideBvh {
    nodes: Vec<WideNode>,
}

impl WideBvh {
    /// The decoded nodes of `bvh`, if it is small and shallow enough to
    /// keep them.
    pub(crate) fn of(bvh: &CwBvh) -> Option<Self> {
        (bvh.nodes.len() <= WIDE_NODES && levels(bvh) <= STACK).then(|| WideBvh {
            nodes: bvh.nodes.iter().map(WideNode::new).collect(),
        })
    }

    /// As `CwBvh::ray_traverse`: the closest primitive for which
    /// `intersect` returns a distance below the ray's end, into `hit`.
    #[inline(always)]
    pub(crate) fn ray_traverse(
        &self,
        ray: Ray,
        hit: &mut RayHit,
        mut intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> bool {
        let mut shortened = ray;
        let mut state = Walk::new(ray.direction);
        let mut node;
        obvhs::traverse!(self, node, state, node.hits(&shortened, state.oct_inv4), {
            let t = intersect(&shortened, state.primitive_id as usize);
            if t < shortened.tmax {
                hit.primitive_id = state.primitive_id;
                hit.t = t;
                shortened.tmax = t;
            }
        });
        hit.t < ray.tmax
    }

    /// As `CwBvh::ray_traverse_miss`: true if `intersect` finds no
    /// primitive before the ray's end; stops at the first it finds.
    #[inline(always)]
    pub(crate) fn ray_traverse_miss(
        &self,
        ray: Ray,
        mut intersect: impl FnMut(&Ray, usize) -> f32,
    ) -> bool {
        let mut state = Walk::new(ray.direction);
        let mut node;
        let mut miss = true;
        'found: {
            obvhs::traverse!(self, node, state, node.hits(&ray, state.oct_inv4), {
                if intersect(&ray, state.primitive_id as usize) < ray.tmax {
                    miss = false;
                    break 'found;
                }
            });
        }
        miss
    }
}

/// The number of levels of nodes in `bvh` (its root alone: one).
fn levels(bvh: &CwBvh) -> usize {
    let mut deepest = 0;
    let mut pending = vec![(0usize, 1usize)];
    while let Some((i, level)) = pending.pop() {
        let Some(node) = bvh.nodes.get(i) else {
            continue;
        };
        deepest = deepest.max(level);
        let first = node.child_base_idx as usize;
        let children = node.imask.count_ones() as usize;
        pending.extend((first..first + children).map(|c| (c, level + 1)));
    }
    deepest
}

/// A scene's tree: four-wide where it holds triangles alone; else obvhs's
/// wide nodes, decoded where the tree is small.
#[derive(Debug)]
pub(crate) enum Tree {
    /// Triangles alone, in a tree that no ray overflows
    /// ([`QuadBvh`]).
    Quad(QuadBvh),
    /// Up to [`WIDE_NODES`] nodes and [`STACK`] levels.
    Wide(WideBvh),
    /// Larger or deeper trees.
    Compressed(CwBvh),
}

impl Tree {
    /// The decoded tree of `bvh` if it is small and shallow enough, else
    /// `bvh` itself.
    pub(crate) fn of(bvh: CwBvh) -> Self {
        WideBvh::of(&bvh).map_or(Tree::Compressed(bvh), Tree::Wide)
    }

    /// The tree for rays of the binary tree `bvh` over `triangles`
    /// followed by `spheres` spheres, and its order of the primitives (the
    /// concatenation's indices; a large triangle split into pieces once per
    /// piece, or in a four-wide tree once per leaf holding a piece), by
    /// which rays number what they hit.
    pub(crate) fn build(bvh: &Bvh2, triangles: &[[Vec3; 3]], spheres: usize) -> (Self, Vec<u32>) {
        if spheres == 0
            && let Some((quad, order)) = QuadBvh::of(bvh, triangles)
        {
            return (Tree::Quad(quad), order);
        }
        let wide = crate::bvh::compress(bvh, triangles.len() + spheres);
        let order = wide.primitive_indices.clone();
        (Tree::of(wide), order)
    }
}

/// `$body` with `$t` bound to the tree `$tree` (a `&Tree`) if it has
/// obvhs's wide nodes, `$other` with `$quad` bound to it if it is
/// four-wide. The body is written once but compiled per kind, so that a
/// primitive test written in it as a closure is a closure per traversal
/// and inlines into it: one closure handed to both (through a method of
/// `Tree`) stayed a call per candidate, which cost more than decoding the
/// nodes saved.
macro_rules! with_tree {
    ($tree:expr, $t:ident => $body:expr, $quad:ident => $other:expr) => {
        match $tree {
            $crate::wide::Tree::Quad($quad) => $other,
            $crate::wide::Tree::Wide($t) => $body,
            $crate::wide::Tree::Compressed($t) => $body,
        }
    };
}
pub(crate) use with_tree;

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn random_tree(seed: u64) -> (CwBvh, Vec<[Vec3; 3]>) {
        let mut rng = aether_core::Pcg32::new(seed, 1);
        let mut u = || aether_core::UniformSource::next_f32(&mut rng);
        let triangles: Vec<[Vec3; 3]> = (0..400)
            .map(|_| {
                let a = Vec3::new(u(), u(), u()) * 10.0 - 5.0;
                [
                    a,
                    a + Vec3::new(u(), u(), u()),
                    a + Vec3::new(u(), u(), u()),
                ]
            })
            .collect();
        let bvh = crate::bvh::build(&triangles, &[]).expect("a tree");
        let ordered = bvh
            .primitive_indices
            .iter()
            .map(|&i| triangles[i as usize])
            .collect();
        (bvh, ordered)
    }

    /// Random rays as obvhs takes them (a negative zero in the direction
    /// made positive, as `Geometry` does).
    fn rays(seed: u64) -> Vec<Ray> {
        crate::bvh::random_rays(seed, 2000)
            .into_iter()
            .map(|(o, d, t_max)| Ray::new(o.into(), (d + Vec3::ZERO).into(), 0.0, t_max))
            .collect()
    }

    #[test]
    fn octant_indices_invert_their_encoding() {
        for o in 0..8 {
            assert_eq!(octant(octant_of(o)), o);
        }
    }

    #[test]
    fn every_node_finds_the_children_obvhs_finds() {
        let (bvh, _) = random_tree(5);
        let wide = WideBvh::of(&bvh).expect("a small tree");
        assert!(bvh.nodes.len() > 8);
        for ray in rays(6) {
            let oct = bvh.new_traversal(ray.direction).oct_inv4;
            assert_eq!(octant_inv4(ray.direction), oct);
            for (node, w) in bvh.nodes.iter().zip(&wide.nodes) {
                assert_eq!(w.hits(&ray, oct), node.intersect_ray(&ray, oct));
            }
        }
    }

    #[test]
    fn rays_find_what_obvhs_finds() {
        let (bvh, triangles) = random_tree(7);
        let wide = WideBvh::of(&bvh).expect("a small tree");
        let test = |r: &Ray, id: usize| {
            let [a, b, c] = triangles[id];
            let tri = obvhs::triangle::Triangle {
                v0: a.into(),
                v1: b.into(),
                v2: c.into(),
            };
            tri.intersect(r)
        };
        let mut hits = 0;
        for ray in rays(8) {
            let (mut ours, mut theirs) = (RayHit::none(), RayHit::none());
            let found = wide.ray_traverse(ray, &mut ours, test);
            assert_eq!(found, bvh.ray_traverse(ray, &mut theirs, test));
            assert_eq!((ours.primitive_id, ours.t), (theirs.primitive_id, theirs.t));
            assert_eq!(
                wide.ray_traverse_miss(ray, test),
                bvh.ray_traverse_miss(ray, test)
            );
            hits += usize::from(found);
        }
        assert!(hits > 100 && hits < 1900, "{hits} hits");
    }

    #[test]
    fn large_trees_keep_obvhs_nodes() {
        let (bvh, _) = random_tree(9);
        assert!(matches!(Tree::of(bvh), Tree::Wide(_)));
        let big = CwBvh {
            nodes: vec![CwBvhNode::default(); WIDE_NODES + 1],
            ..random_tree(9).0
        };
        assert!(matches!(Tree::of(big), Tree::Compressed(_)));
    }

    #[test]
    fn deep_trees_keep_obvhs_nodes() {
        let (bvh, _) = random_tree(9);
        assert!((2..=STACK).contains(&levels(&bvh)));
        // A chain of single children, one level more than the short stack allows.
        let chain = |len: u32| CwBvh {
            nodes: (0..len)
                .map(|i| CwBvhNode {
                    child_base_idx: i + 1,
                    imask: u8::from(i + 1 < len),
                    ..CwBvhNode::default()
                })
                .collect(),
            ..random_tree(9).0
        };
        assert_eq!(levels(&chain(STACK as u32)), STACK);
        assert!(matches!(Tree::of(chain(STACK as u32)), Tree::Wide(_)));
        assert!(matches!(
            Tree::of(chain(STACK as u32 + 1)),
            Tree::Compressed(_)
        ));
    }
}
