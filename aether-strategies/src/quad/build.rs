//! The four-wide tree collapsed from a binary one: each node takes the
//! largest boxes below it until it has four children, and every subtree of
//! up to four triangles becomes one leaf, tested in one pass.

use glam::{Vec3, Vec3A, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;

use super::{DEEP, LEAF, Leaf, Node, QuadBvh, SHALLOW};

/// Triangles a leaf holds side by side.
const LANES: usize = 4;

/// Binary trees deeper than this keep obvhs's wide nodes: the collapse
/// recurses once per level.
const DEEPEST: usize = 256;

/// What a child of a node covers: a subtree of the binary tree, or a run
/// of the primitive list (part of a binary leaf of more than four).
#[derive(Clone, Copy)]
enum Part {
    Subtree(usize),
    Run(usize, usize),
}

struct Collapse<'a> {
    bvh: &'a Bvh2,
    triangles: &'a [[Vec3; 3]],
    /// Primitives below each binary node.
    counts: Vec<usize>,
    nodes: Vec<Node>,
    leaves: Vec<Leaf>,
    order: Vec<u32>,
}

impl QuadBvh {
    /// The four-wide tree of `bvh`, whose primitives are `triangles`, if no
    /// ray through it can need more pending children than a traversal
    /// holds; None too for a tree that is empty, deeper than [`DEEPEST`]
    /// or names a node or primitive it does not have. With the tree, the
    /// primitives (the binary tree's indices) in the order its leaves number
    /// them: a triangle the tree splits into pieces appears once per leaf
    /// that holds a piece of it.
    pub(crate) fn of(bvh: &Bvh2, triangles: &[[Vec3; 3]]) -> Option<(Self, Vec<u32>)> {
        let counts = counts(bvh)?;
        if bvh
            .primitive_indices
            .iter()
            .any(|&p| p as usize >= triangles.len())
        {
            return None;
        }
        let mut c = Collapse {
            bvh,
            triangles,
            counts,
            nodes: Vec::new(),
            leaves: Vec::new(),
            order: Vec::new(),
        };
        let (root, pending) = c.collapse(Part::Subtree(0));
        let tree = QuadBvh {
            nodes: c.nodes,
            leaves: c.leaves,
            root,
            deep: pending > SHALLOW,
        };
        (pending <= DEEP).then_some((tree, c.order))
    }
}

/// The number of primitives below each node of `bvh`, or None if it is
/// empty, deeper than [`DEEPEST`] or names a child it does not have.
fn counts(bvh: &Bvh2) -> Option<Vec<usize>> {
    let mut counts = vec![0; bvh.nodes.len()];
    // Parents come before their children in a walk from the root: counted
    // in reverse, every child is counted before its parent.
    let mut walk = vec![(0usize, 1usize)];
    let mut seen = Vec::with_capacity(bvh.nodes.len());
    while let Some((i, depth)) = walk.pop() {
        let node = bvh.nodes.get(i)?;
        if depth > DEEPEST {
            return None;
        }
        seen.push(i);
        if !node.is_leaf() {
            let first = node.first_index as usize;
            walk.extend([(first, depth + 1), (first + 1, depth + 1)]);
        }
    }
    for &i in seen.iter().rev() {
        let node = &bvh.nodes[i];
        counts[i] = if node.is_leaf() {
            node.prim_count as usize
        } else {
            let first = node.first_index as usize;
            counts.get(first)? + counts.get(first + 1)?
        };
    }
    Some(counts)
}

impl Collapse<'_> {
    fn count(&self, part: Part) -> usize {
        match part {
            Part::Subtree(i) => self.counts[i],
            Part::Run(_, len) => len,
        }
    }

    /// The box of `part`, padded by a few units in the last place of its
    /// coordinates: the planes of a split triangle's pieces are rounded
    /// points of the triangle, which may fall short of it by that much
    /// (obvhs's compressed nodes rounded every box outwards).
    fn bounds(&self, part: Part) -> Aabb {
        let b = self.exact_bounds(part);
        let pad = |p: Vec3A| p.abs() * (4.0 * f32::EPSILON);
        Aabb::new(b.min - pad(b.min), b.max + pad(b.max))
    }

    fn exact_bounds(&self, part: Part) -> Aabb {
        match part {
            Part::Subtree(i) => self.bvh.nodes[i].aabb,
            Part::Run(start, len) => {
                let mut b = Aabb::empty();
                for &p in &self.bvh.primitive_indices[start..start + len] {
                    for c in self.triangles[p as usize] {
                        b.extend(Vec3A::from(c));
                    }
                }
                b
            }
        }
    }

    /// The two halves of a part of more than four primitives.
    fn open(&self, part: Part) -> [Part; 2] {
        let halves = |start: usize, len: usize| {
            [
                Part::Run(start, len / 2),
                Part::Run(start + len / 2, len - len / 2),
            ]
        };
        match part {
            Part::Subtree(i) => {
                let node = &self.bvh.nodes[i];
                let first = node.first_index as usize;
                if node.is_leaf() {
                    halves(first, node.prim_count as usize)
                } else {
                    [Part::Subtree(first), Part::Subtree(first + 1)]
                }
            }
            Part::Run(start, len) => halves(start, len),
        }
    }

    /// The child reference of `part` collapsed, and the most children a
    /// ray can leave pending below it.
    fn collapse(&mut self, part: Part) -> (u32, usize) {
        if self.count(part) <= LANES {
            return (self.leaf(part), 0);
        }
        let mut kids = self.open(part).to_vec();
        while kids.len() < 4 {
            // Open the largest child that is not to be a leaf.
            let widest = (0..kids.len())
                .filter(|&k| self.count(kids[k]) > LANES)
                .max_by(|&a, &b| {
                    let area = |k: usize| self.bounds(kids[k]).half_area();
                    area(a).total_cmp(&area(b))
                });
            let Some(k) = widest else { break };
            let opened = self.open(kids.swap_remove(k));
            kids.extend(opened);
        }
        let slot = self.nodes.len();
        self.nodes.push(Node {
            planes: [
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
                Vec4::INFINITY,
                Vec4::NEG_INFINITY,
            ],
            children: [LEAF; 4],
        });
        let mut most_pending = 0;
        for (k, &kid) in kids.iter().enumerate() {
            let b = self.bounds(kid);
            let (child, pending) = self.collapse(kid);
            most_pending = most_pending.max(pending);
            let node = &mut self.nodes[slot];
            node.children[k] = child;
            for a in 0..3 {
                node.planes[2 * a][k] = b.min[a];
                node.planes[2 * a + 1][k] = b.max[a];
            }
        }
        (slot as u32, most_pending + kids.len() - 1)
    }

    /// A leaf of the primitives of `part` (at most four).
    fn leaf(&mut self, part: Part) -> u32 {
        let mut prims = Vec::with_capacity(LANES);
        let mut walk = vec![part];
        while let Some(p) = walk.pop() {
            match p {
                Part::Subtree(i) if !self.bvh.nodes[i].is_leaf() => {
                    walk.extend(self.open(p).into_iter().rev());
                }
                Part::Subtree(i) => {
                    let node = &self.bvh.nodes[i];
                    let first = node.first_index as usize;
                    prims.extend_from_slice(
                        &self.bvh.primitive_indices[first..first + node.prim_count as usize],
                    );
                }
                Part::Run(start, len) => {
                    prims.extend_from_slice(&self.bvh.primitive_indices[start..start + len]);
                }
            }
        }
        // Pieces of one large triangle: tested once. A triangle with two
        // equal corners is never hit (its edge functions cancel exactly),
        // and its zero edge function would send every ray through the leaf
        // to the scalar test.
        prims.sort_unstable();
        prims.dedup();
        prims.retain(|&p| {
            let [a, b, c] = self.triangles[p as usize];
            a != b && b != c && c != a
        });
        let mut corners = [[Vec4::NAN; 3]; 3];
        for (lane, &p) in prims.iter().enumerate() {
            for (v, corner) in self.triangles[p as usize].iter().enumerate() {
                for a in 0..3 {
                    corners[v][a][lane] = corner[a];
                }
            }
        }
        self.leaves.push(Leaf {
            corners,
            first: self.order.len() as u32,
            count: prims.len() as u32,
        });
        self.order.extend_from_slice(&prims);
        (self.leaves.len() - 1) as u32 | LEAF
    }
}
