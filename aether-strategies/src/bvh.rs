//! The one BVH over a scene's triangles and spheres: obvhs's compressed
//! wide BVH, built from boxes so that the spheres sit in the same tree as
//! the triangles. A ray then tests only the spheres whose boxes it meets,
//! where a list beside the tree had every ray test every sphere, in double
//! precision: a scene of thousands of spheres would cost thousands of tests
//! per ray.

use glam::{Vec3, Vec3A};
use obvhs::BvhBuildParams;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh;
use obvhs::ploc::PlocBuilder;
use obvhs::splits::split_aabbs_preset;
use obvhs::triangle::Triangle;

use crate::geometry::Sphere;

/// Scenes up to this many primitives get obvhs's slowest, best build.
const BEST_BUILD_LIMIT: usize = 1 << 20;

/// How the BVH of `primitives` primitives is built. The slowest build
/// (large triangles split into several boxes, every node considered for
/// reinsertion) casts the Cornell box's rays with 4.5 % fewer instructions
/// per path-traced sample than obvhs's medium build, whose trees overlap
/// more, but takes about three times as long: 3 s instead of 1 s for a
/// million triangles on two cores. Larger scenes keep the medium build, so
/// that a big scene starts rendering in seconds.
fn build_params(primitives: usize) -> BvhBuildParams {
    if primitives <= BEST_BUILD_LIMIT {
        BvhBuildParams::very_slow_build()
    } else {
        BvhBuildParams::medium_build()
    }
}

/// A box around `s`, padded past the rounding of its corners so that a
/// ray the double-precision sphere test would find never misses the box.
fn sphere_box(s: &Sphere) -> Aabb {
    let center = Vec3A::from(s.center);
    let r = s.radius.abs();
    let pad = r * 1e-4 + 8.0 * f32::EPSILON * (center.abs().max_element() + r);
    let half = Vec3A::splat(r + pad);
    Aabb::new(center - half, center + half)
}

/// The tree over `triangles` followed by `spheres`, as obvhs's compressed
/// wide BVH: its `primitive_indices` index that concatenation (a large
/// triangle split into pieces appears once per piece). None for an empty
/// scene.
#[cfg(test)]
pub(crate) fn build(triangles: &[[Vec3; 3]], spheres: &[Sphere]) -> Option<CwBvh> {
    build_binary(triangles, spheres).map(|b| compress(&b, triangles.len() + spheres.len()))
}

/// The binary tree over `triangles` followed by `spheres`: the steps of
/// obvhs's own triangle builder, with the spheres' boxes added after the
/// split, so that a scene without spheres gets the same tree as from that
/// builder. None for an empty scene.
pub(crate) fn build_binary(triangles: &[[Vec3; 3]], spheres: &[Sphere]) -> Option<Bvh2> {
    let count = triangles.len() + spheres.len();
    if count == 0 {
        return None;
    }
    let config = build_params(count);
    let tris: Vec<Triangle> = triangles
        .iter()
        .map(|[a, b, c]| Triangle {
            v0: Vec3A::from(*a),
            v1: Vec3A::from(*b),
            v2: Vec3A::from(*c),
        })
        .collect();
    let mut boxes: Vec<Aabb> = tris.iter().map(Triangle::aabb).collect();
    let mut indices: Vec<u32> = (0..tris.len() as u32).collect();
    if config.pre_split && !tris.is_empty() {
        let largest = boxes.iter().map(Aabb::half_area).fold(0.0, f32::max);
        let average = boxes.iter().map(Aabb::half_area).sum::<f32>() / tris.len() as f32;
        split_aabbs_preset(&mut boxes, &mut indices, &tris, average, largest);
    }
    for (k, s) in spheres.iter().enumerate() {
        boxes.push(sphere_box(s));
        indices.push((tris.len() + k) as u32);
    }
    let mut bvh2 = PlocBuilder::with_capacity(boxes.len()).build(
        config.ploc_search_distance,
        &boxes,
        indices,
        config.sort_precision,
        config.search_depth_threshold,
    );
    bvh2.uses_spatial_splits = config.pre_split;
    ReinsertionOptimizer::default().run(&mut bvh2, config.reinsertion_batch_ratio, None);
    Some(bvh2)
}

/// obvhs's compressed wide BVH of the binary tree `bvh2` over `count`
/// primitives.
pub(crate) fn compress(bvh2: &Bvh2, count: usize) -> CwBvh {
    let config = build_params(count);
    bvh2_to_cwbvh(bvh2, config.max_prims_per_leaf.clamp(1, 3), true, false)
}

/// `count` random rays for the trees' tests: origin, unit direction and
/// end, from around a box of side 10 about the origin; some directions
/// with a zero component or along an axis, some rays ending at 4.
#[cfg(test)]
pub(crate) fn random_rays(seed: u64, count: usize) -> Vec<(Vec3, Vec3, f32)> {
    let mut rng = aether_core::Pcg32::new(seed, 2);
    let mut u = || aether_core::UniformSource::next_f32(&mut rng);
    (0..count)
        .map(|k| {
            let o = Vec3::new(u(), u(), u()) * 14.0 - 7.0;
            let mut d = (Vec3::new(u(), u(), u()) - 0.5).normalize();
            if k % 7 == 0 {
                d = Vec3::new(d.x, 0.0, d.z).normalize();
            }
            if k % 11 == 0 {
                d = Vec3::NEG_Z;
            }
            let t_max = if k % 3 == 0 { 4.0 } else { f32::INFINITY };
            (o, d, t_max)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sphere_box_holds_the_sphere_far_from_the_origin() {
        let s = Sphere {
            center: Vec3::new(1.0e5, -3.0e4, 7.0),
            radius: 0.25,
        };
        let b = sphere_box(&s);
        for d in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            let p = Vec3A::from(s.center + d * s.radius);
            assert!(p.cmpge(b.min).all() && p.cmple(b.max).all(), "{p} outside");
        }
    }

    #[test]
    fn triangles_alone_get_obvhs_own_tree() {
        // The steps are obvhs's triangle builder's: the same tree for the
        // same triangles, large ones split as there.
        let mut rng = aether_core::Pcg32::new(3, 1);
        let mut u = || aether_core::UniformSource::next_f32(&mut rng);
        let triangles: Vec<[Vec3; 3]> = (0..200)
            .map(|i| {
                let a = Vec3::new(u(), u(), u()) * 4.0;
                let size = if i % 17 == 0 { 6.0 } else { 0.5 };
                [
                    a,
                    a + Vec3::new(u(), u(), u()) * size,
                    a + Vec3::new(u(), u(), u()),
                ]
            })
            .collect();
        let ours = build(&triangles, &[]).expect("a tree");
        let tris: Vec<Triangle> = triangles
            .iter()
            .map(|[a, b, c]| Triangle {
                v0: (*a).into(),
                v1: (*b).into(),
                v2: (*c).into(),
            })
            .collect();
        let theirs = obvhs::cwbvh::builder::build_cwbvh_from_tris(
            &tris,
            build_params(tris.len()),
            &mut std::time::Duration::default(),
        );
        assert!(ours.primitive_indices.len() > triangles.len(), "no split");
        assert_eq!(ours.primitive_indices, theirs.primitive_indices);
        assert_eq!(ours.nodes.len(), theirs.nodes.len());
    }

    #[test]
    fn every_triangle_and_sphere_is_in_the_tree() {
        let triangles = [
            [Vec3::ZERO, Vec3::X, Vec3::Y],
            [Vec3::Z, Vec3::Z + Vec3::X, Vec3::Z + Vec3::Y],
        ];
        let spheres = [Sphere {
            center: Vec3::splat(3.0),
            radius: 1.0,
        }];
        let bvh = build(&triangles, &spheres).expect("a tree");
        let mut seen: Vec<u32> = bvh.primitive_indices.clone();
        seen.sort_unstable();
        seen.dedup();
        assert_eq!(seen, vec![0, 1, 2]);
        assert!(build(&[], &[]).is_none());
    }
}
