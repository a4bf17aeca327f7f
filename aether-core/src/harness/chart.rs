//! Charts: how the chi-square test bins values and integrates densities.

use std::f64::consts::PI;

use glam::{DVec3, Vec2, Vec3};

/// A parameterisation of a value space by the unit interval or square,
/// with its area element. The harness bins samples by their coordinates and
/// integrates densities over the bins through it.
pub trait Parameterization<T> {
    /// 1 or 2.
    fn dims(&self) -> usize;
    /// The value at chart coordinates `s` (only `s[0]` is read in one dimension).
    fn value(&self, s: [f64; 2]) -> Option<T>;
    /// The chart coordinates of `value`, or `None` if it lies off the chart.
    fn coords(&self, value: &T) -> Option<[f64; 2]>;
    /// The value's measure per unit of chart measure at `s`.
    fn jacobian(&self, s: [f64; 2]) -> f64;
}

/// Cells that samples fall in and densities are integrated over.
pub trait Chart<T> {
    /// Number of cells.
    fn cells(&self) -> usize;
    /// The cell of `value`, or `None` if it lies off the chart.
    fn cell_of(&self, value: &T) -> Option<usize>;
    /// ∫ density over the cell, in the value's measure.
    fn integrate(&self, cell: usize, density: &dyn Fn(&T) -> f64) -> f64;
}

/// A regular grid of `n` cells per chart dimension, integrated by composite
/// three-point Gauss–Legendre quadrature (4 panels per cell and dimension).
#[derive(Clone, Copy, Debug)]
pub struct Grid<P> {
    param: P,
    n: usize,
}

impl<P> Grid<P> {
    /// `n` cells per dimension over `param`.
    pub fn new(param: P, n: usize) -> Self {
        Grid { param, n: n.max(1) }
    }
}

const GAUSS: [(f64, f64); 3] = [(-0.774_596_669_241_483_4, 5.0 / 9.0), (0.0, 8.0 / 9.0), (0.774_596_669_241_483_4, 5.0 / 9.0)];
const PANELS: usize = 4;

impl<T, P: Parameterization<T>> Chart<T> for Grid<P> {
    fn cells(&self) -> usize {
        self.n.pow(self.param.dims() as u32)
    }
    fn cell_of(&self, value: &T) -> Option<usize> {
        let s = self.param.coords(value)?;
        let idx = |x: f64| ((0.0..=1.0).contains(&x)).then(|| ((x * self.n as f64) as usize).min(self.n - 1));
        match self.param.dims() {
            1 => idx(s[0]),
            _ => Some(idx(s[1])? * self.n + idx(s[0])?),
        }
    }
    fn integrate(&self, cell: usize, density: &dyn Fn(&T) -> f64) -> f64 {
        let two_d = self.param.dims() == 2;
        let (cx, cy) = if two_d { (cell % self.n, cell / self.n) } else { (cell, 0) };
        let width = 1.0 / (self.n * PANELS) as f64;
        // Nodes and weights along one dimension of the cell.
        let nodes = |c: usize| {
            (0..PANELS).flat_map(move |p| {
                let lo = (c * PANELS + p) as f64 * width;
                GAUSS.iter().map(move |&(x, w)| (lo + (x + 1.0) * 0.5 * width, w * 0.5 * width))
            })
        };
        let mut total = 0.0;
        for (x, wx) in nodes(cx) {
            let ys: Vec<(f64, f64)> = if two_d { nodes(cy).collect() } else { vec![(0.5, 1.0)] };
            for (y, wy) in ys {
                let s = [x, y];
                if let Some(v) = self.param.value(s) {
                    let f = density(&v);
                    if f > 0.0 {
                        total += wx * wy * f * self.param.jacobian(s);
                    }
                }
            }
        }
        total
    }
}

/// Discrete outcomes `0..n`, one cell each.
#[derive(Clone, Copy, Debug)]
pub struct Categories(pub usize);

impl Chart<usize> for Categories {
    fn cells(&self) -> usize {
        self.0
    }
    fn cell_of(&self, value: &usize) -> Option<usize> {
        (*value < self.0).then_some(*value)
    }
    fn integrate(&self, cell: usize, density: &dyn Fn(&usize) -> f64) -> f64 {
        density(&cell)
    }
}

/// The interval `[a, b)`.
#[derive(Clone, Copy, Debug)]
pub struct Interval(pub f32, pub f32);

impl Parameterization<f32> for Interval {
    fn dims(&self) -> usize {
        1
    }
    fn value(&self, s: [f64; 2]) -> Option<f32> {
        Some((f64::from(self.0) + s[0] * f64::from(self.1 - self.0)) as f32)
    }
    fn coords(&self, v: &f32) -> Option<[f64; 2]> {
        Some([f64::from((v - self.0) / (self.1 - self.0)), 0.0])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        f64::from(self.1 - self.0)
    }
}

/// The unit square.
#[derive(Clone, Copy, Debug)]
pub struct Square;

impl Parameterization<Vec2> for Square {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec2> {
        Some(Vec2::new(s[0] as f32, s[1] as f32))
    }
    fn coords(&self, v: &Vec2) -> Option<[f64; 2]> {
        Some([f64::from(v.x), f64::from(v.y)])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        1.0
    }
}

/// The disk of radius `r`, by (ρ²/r², φ/2π): an equal-area chart.
#[derive(Clone, Copy, Debug)]
pub struct Disk(pub f32);

impl Parameterization<Vec2> for Disk {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec2> {
        let rho = s[0].sqrt() * f64::from(self.0);
        let phi = 2.0 * PI * s[1];
        Some(Vec2::new((rho * phi.cos()) as f32, (rho * phi.sin()) as f32))
    }
    fn coords(&self, v: &Vec2) -> Option<[f64; 2]> {
        let r = f64::from(self.0);
        Some([f64::from(v.length_squared()) / (r * r), turn(f64::from(v.y), f64::from(v.x))])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        PI * f64::from(self.0).powi(2)
    }
}

/// Unit directions by ((1 − cos θ)/2, φ/2π) about +z: an equal-area chart
/// of the sphere, in solid angle.
#[derive(Clone, Copy, Debug)]
pub struct SphereDirections;

impl Parameterization<Vec3> for SphereDirections {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec3> {
        let z = 1.0 - 2.0 * s[0];
        let r = (1.0 - z * z).max(0.0).sqrt();
        let phi = 2.0 * PI * s[1];
        Some(DVec3::new(r * phi.cos(), r * phi.sin(), z).as_vec3())
    }
    fn coords(&self, w: &Vec3) -> Option<[f64; 2]> {
        let w = w.as_dvec3().normalize();
        Some([(1.0 - w.z) / 2.0, turn(w.y, w.x)])
    }
    fn jacobian(&self, _s: [f64; 2]) -> f64 {
        4.0 * PI
    }
}

/// The chart of a triangle: p₀ + s₀ e₁ + s₁ (1 − s₀) e₂ (a map unrelated
/// to the sampler's, so that the test is independent of it).
#[derive(Clone, Copy, Debug)]
pub struct Triangle(pub Vec3, pub Vec3, pub Vec3);

impl Parameterization<Vec3> for Triangle {
    fn dims(&self) -> usize {
        2
    }
    fn value(&self, s: [f64; 2]) -> Option<Vec3> {
        let (p0, e1, e2) = (self.0.as_dvec3(), (self.1 - self.0).as_dvec3(), (self.2 - self.0).as_dvec3());
        Some((p0 + s[0] * e1 + s[1] * (1.0 - s[0]) * e2).as_vec3())
    }
    fn coords(&self, x: &Vec3) -> Option<[f64; 2]> {
        let (b0, b1) = crate::primitives::UniformTriangle::new(self.0, self.1, self.2).barycentrics(*x)?;
        // x = p0 + β e1 + γ e2 with β = b1, γ = 1 − b0 − b1.
        let s0 = b1;
        let s1 = if s0 < 1.0 { (1.0 - b0 - b1) / (1.0 - s0) } else { 0.0 };
        Some([s0, s1])
    }
    fn jacobian(&self, s: [f64; 2]) -> f64 {
        let n = (self.1 - self.0).as_dvec3().cross((self.2 - self.0).as_dvec3());
        n.length() * (1.0 - s[0])
    }
}

fn turn(y: f64, x: f64) -> f64 {
    let phi = y.atan2(x);
    if phi < 0.0 { phi / (2.0 * PI) + 1.0 } else { phi / (2.0 * PI) }
}
