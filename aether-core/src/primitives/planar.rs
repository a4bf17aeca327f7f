use std::f32::consts::FRAC_PI_4;
use std::f64::consts::PI;

use glam::{Vec2, Vec3};
use smallvec::smallvec;

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one, in_unit_cube};

/// The uniform distribution on a disk of radius `r` centred at the origin,
/// by Shirley and Chiu's concentric map (low distortion, invertible).
///
/// Density: 1 / (π r²) in area measure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UniformDisk {
    radius: f32,
}

impl UniformDisk {
    /// The unit disk.
    pub const UNIT: UniformDisk = UniformDisk { radius: 1.0 };

    /// A disk of the given positive radius.
    #[must_use]
    pub fn new(radius: f32) -> Self {
        debug_assert!(radius > 0.0);
        UniformDisk { radius }
    }

    /// The concentric map of the unit square onto the unit disk.
    #[must_use]
    pub fn concentric(u: [f32; 2]) -> Vec2 {
        let a = 2.0 * u[0] - 1.0;
        let b = 2.0 * u[1] - 1.0;
        if a == 0.0 && b == 0.0 {
            return Vec2::ZERO;
        }
        // φ = x in the wedges about ±x, π/2 − x in those about ±y, with
        // |x| ≤ π/4: one polynomial pair, its two results swapped for the
        // second case, where libm's `sincosf` reduced an argument that
        // never needs reducing (1.6 % of a path tracer's time).
        if a.abs() > b.abs() {
            let (sin, cos) = sin_cos_quarter(FRAC_PI_4 * (b / a));
            a * Vec2::new(cos, sin)
        } else {
            let (sin, cos) = sin_cos_quarter(FRAC_PI_4 * (a / b));
            b * Vec2::new(sin, cos)
        }
    }

    /// The inverse of [`concentric`](Self::concentric) on the closed unit disk.
    #[must_use]
    pub fn concentric_inverse(p: Vec2) -> Option<[f32; 2]> {
        let r = f64::from(p.length());
        if r > 1.0 + 1e-6 {
            return None;
        }
        let theta = f64::from(p.y).atan2(f64::from(p.x));
        let quarter = PI / 4.0;
        // Which wedge of the square the point came from, and its signed radius.
        let (a, b) = if theta.abs() <= quarter {
            (r, r * theta / quarter)
        } else if theta.abs() >= 3.0 * quarter {
            let t = if theta > 0.0 { theta - PI } else { theta + PI };
            (-r, -r * t / quarter)
        } else if theta > 0.0 {
            (r * (2.0 - theta / quarter), r)
        } else {
            let t = theta + PI;
            (-r * (2.0 - t / quarter), -r)
        };
        let u = [
            below_one(((a + 1.0) / 2.0) as f32),
            below_one(((b + 1.0) / 2.0) as f32),
        ];
        in_unit_cube(&u).then_some(u)
    }

    fn pdf(&self) -> Density {
        let r = f64::from(self.radius);
        Density::new(1.0 / (PI * r * r), Measure::Area)
    }
}

impl Distribution for UniformDisk {
    type Value = Vec2;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec2>> {
        Some(Sample::new(
            self.radius * Self::concentric([u[0], u[1]]),
            self.pdf(),
        ))
    }
    fn density(&self, p: &Vec2) -> Density {
        if p.length() <= self.radius {
            self.pdf()
        } else {
            Density::zero(Measure::Area)
        }
    }
    fn invert(&self, p: &Vec2) -> Option<Uniforms> {
        Self::concentric_inverse(*p / self.radius).map(|u| smallvec![u[0], u[1]])
    }
}

/// sin x and cos x for |x| ≤ π/4, within two units in the last place of
/// the exact values: the minimax polynomials of Moshier's Cephes library
/// (`sinf`, `cosf`) for that range, where they need no argument reduction.
fn sin_cos_quarter(x: f32) -> (f32, f32) {
    let z = x * x;
    let sin = x + x * z * (-1.666_665_5e-1 + z * (8.332_161e-3 + z * -1.951_529_6e-4));
    // Smallest terms first, 1 last (one rounding fewer than 1 − z/2 first).
    let cos = z * z * (4.166_664_6e-2 + z * (-1.388_731_6e-3 + z * 2.443_315_7e-5)) - 0.5 * z + 1.0;
    (sin, cos)
}

/// The uniform distribution on a triangle, by area.
///
/// The map is b₀ = 1 − √u₀, b₁ = u₁ √u₀ on barycentrics. Its inverse checks
/// that a point lies in the triangle's plane, with a tolerance relative to
/// the triangle's size (no absolute epsilon).
///
/// Density: 1 / A in area measure.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UniformTriangle {
    p: [Vec3; 3],
    /// The reciprocal of the area, found once: a light's triangles are
    /// built once and sampled at every vertex of every path, and the
    /// square root and division cost more than the sampling itself.
    inverse_area: f64,
}

impl UniformTriangle {
    /// The triangle with these corners.
    #[must_use]
    pub fn new(p0: Vec3, p1: Vec3, p2: Vec3) -> Self {
        let p = [p0, p1, p2];
        UniformTriangle {
            p,
            inverse_area: 1.0 / area_of(&p),
        }
    }

    /// Its corners, in the order given to [`new`](Self::new).
    #[must_use]
    pub fn corners(&self) -> [Vec3; 3] {
        self.p
    }

    /// Its area.
    #[must_use]
    pub fn area(&self) -> f64 {
        area_of(&self.p)
    }

    /// Barycentrics (b₀, b₁) of a point in the triangle's plane, or `None`
    /// if it lies off the plane or outside the triangle.
    #[must_use]
    pub fn barycentrics(&self, x: Vec3) -> Option<(f64, f64)> {
        let [p0, p1, p2] = self.p.map(|p| p.as_dvec3());
        let x = x.as_dvec3();
        let (e1, e2, d) = (p1 - p0, p2 - p0, x - p0);
        let n = e1.cross(e2);
        let n2 = n.length_squared();
        if n2 == 0.0 {
            return None;
        }
        let size = n2.sqrt().sqrt();
        if d.dot(n).abs() / n2.sqrt() > 1e-4 * size {
            return None;
        }
        // x = p0 + β e1 + γ e2; b₀ weighs p0, b₁ weighs p1.
        let beta = d.cross(e2).dot(n) / n2;
        let gamma = e1.cross(d).dot(n) / n2;
        let b0 = 1.0 - beta - gamma;
        let tol = -1e-6;
        (b0 >= tol && beta >= tol && gamma >= tol).then_some((b0, beta))
    }

    /// The point the uniforms `u` map to, as [`sample`](Distribution::sample)
    /// gives it, with its barycentrics (b₀, b₁, b₂): the weights of the
    /// corners in the order given to [`new`](Self::new), for whoever
    /// interpolates the triangle's attributes there.
    #[must_use]
    pub fn sample_point(&self, u: &[f32]) -> Sample<(Vec3, [f64; 3])> {
        let su = f64::from(u[0]).sqrt();
        let b0 = 1.0 - su;
        let b1 = f64::from(u[1]) * su;
        let b2 = 1.0 - b0 - b1;
        let [p0, p1, p2] = self.p.map(|p| p.as_dvec3());
        let x = b0 * p0 + b1 * p1 + b2 * p2;
        Sample::new((x.as_vec3(), [b0, b1, b2]), self.pdf())
    }

    fn pdf(&self) -> Density {
        Density::new(self.inverse_area, Measure::Area)
    }
}

/// The area of the triangle with corners `p`, in double precision.
fn area_of(p: &[Vec3; 3]) -> f64 {
    let e1 = (p[1] - p[0]).as_dvec3();
    let e2 = (p[2] - p[0]).as_dvec3();
    0.5 * e1.cross(e2).length()
}

impl Distribution for UniformTriangle {
    type Value = Vec3;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec3>> {
        let s = self.sample_point(u);
        Some(Sample::new(s.value.0, s.density))
    }
    fn density(&self, x: &Vec3) -> Density {
        match self.barycentrics(*x) {
            Some(_) => self.pdf(),
            None => Density::zero(Measure::Area),
        }
    }
    fn invert(&self, x: &Vec3) -> Option<Uniforms> {
        let (b0, b1) = self.barycentrics(*x)?;
        let su = (1.0 - b0).clamp(0.0, 1.0);
        let u1 = if su > 0.0 { b1 / su } else { 0.5 };
        Some(smallvec![
            below_one((su * su) as f32),
            below_one(u1.clamp(0.0, 1.0) as f32)
        ])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quarter_sine_and_cosine_are_within_two_units_in_the_last_place() {
        // The spacing of f32 values at |v| (for v ≠ 0).
        let ulp = |v: f32| f64::from(f32::from_bits(v.abs().to_bits() + 1) - v.abs());
        for i in -10_000..=10_000 {
            let x = FRAC_PI_4 * i as f32 / 10_000.0;
            let (sin, cos) = sin_cos_quarter(x);
            let exact = f64::from(x);
            let (es, ec) = (exact.sin(), exact.cos());
            if i != 0 {
                assert!(
                    (f64::from(sin) - es).abs() <= 2.0 * ulp(es as f32),
                    "sin {x}: {sin}"
                );
            }
            assert!(
                (f64::from(cos) - ec).abs() <= 2.0 * ulp(ec as f32),
                "cos {x}: {cos}"
            );
        }
        assert_eq!(sin_cos_quarter(0.0), (0.0, 1.0));
    }

    #[test]
    fn concentric_round_trip() {
        for i in 1..20 {
            for j in 1..20 {
                let u = [i as f32 / 20.0, j as f32 / 20.0];
                let p = UniformDisk::concentric(u);
                let v = UniformDisk::concentric_inverse(p).unwrap();
                assert!(
                    (v[0] - u[0]).abs() < 1e-5 && (v[1] - u[1]).abs() < 1e-5,
                    "{u:?} -> {p} -> {v:?}"
                );
            }
        }
    }
}
