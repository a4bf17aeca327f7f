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

/// A regular grid of `n` cells per chart dimension, integrated by adaptive
/// three-point Gauss–Legendre quadrature (panels are halved where the
/// density jumps or peaks, such as at the rim of a cone).
#[derive(Clone, Copy, Debug)]
pub struct Grid<P> {
    param: P,
    n: usize,
    tolerance: f64,
}

impl<P> Grid<P> {
    /// `n` cells per dimension over `param`.
    pub fn new(param: P, n: usize) -> Self {
        Grid {
            param,
            n: n.max(1),
            tolerance: TOLERANCE,
        }
    }

    /// Refines panels until halving changes their integral by less than
    /// `tolerance` times their chart area (1e-5 by default). A density
    /// that is noisy at that level (evaluated through f32 ray casts over
    /// tiny angles, say) would otherwise refine every panel to the
    /// deepest level; the chi-square test at 10⁶ samples only needs
    /// each cell's integral to about 1e-3.
    pub fn with_tolerance(self, tolerance: f64) -> Self {
        Grid { tolerance, ..self }
    }
}

const GAUSS: [(f64, f64); 3] = [
    (-0.774_596_669_241_483_4, 5.0 / 9.0),
    (0.0, 8.0 / 9.0),
    (0.774_596_669_241_483_4, 5.0 / 9.0),
];
const PANELS: usize = 4;

impl<T, P: Parameterization<T>> Chart<T> for Grid<P> {
    fn cells(&self) -> usize {
        self.n.pow(self.param.dims() as u32)
    }
    fn cell_of(&self, value: &T) -> Option<usize> {
        let s = self.param.coords(value)?;
        let idx = |x: f64| {
            ((0.0..=1.0).contains(&x)).then(|| ((x * self.n as f64) as usize).min(self.n - 1))
        };
        match self.param.dims() {
            1 => idx(s[0]),
            _ => Some(idx(s[1])? * self.n + idx(s[0])?),
        }
    }
    fn integrate(&self, cell: usize, density: &dyn Fn(&T) -> f64) -> f64 {
        let h = 1.0 / self.n as f64;
        let f = |s: [f64; 2]| match self.param.value(s) {
            Some(v) => {
                let p = density(&v);
                if p > 0.0 {
                    p * self.param.jacobian(s)
                } else {
                    0.0
                }
            }
            None => 0.0,
        };
        let panel = h / PANELS as f64;
        let mut total = 0.0;
        if self.param.dims() == 2 {
            let (cx, cy) = (cell % self.n, cell / self.n);
            for i in 0..PANELS {
                for j in 0..PANELS {
                    let x0 = cx as f64 * h + i as f64 * panel;
                    let y0 = cy as f64 * h + j as f64 * panel;
                    let coarse = gauss_2d(&f, [x0, y0], panel);
                    total += adaptive_2d(&f, [x0, y0], panel, coarse, self.tolerance, 0);
                }
            }
        } else {
            for i in 0..PANELS {
                let x0 = cell as f64 * h + i as f64 * panel;
                let coarse = gauss_1d(&f, x0, panel);
                total += adaptive_1d(&f, x0, panel, coarse, self.tolerance, 0);
            }
        }
        total
    }
}

/// Refinement stops at this depth, or where halving changes a panel's
/// integral by less than the grid's tolerance times its chart area.
const MAX_DEPTH: u32 = 8;
/// Panels are always halved this often, so that a coarse and a fine rule
/// agreeing by chance across a jump do not stop refinement.
const MIN_DEPTH: u32 = 1;
/// The default tolerance.
const TOLERANCE: f64 = 1e-5;

fn gauss_1d(f: &dyn Fn([f64; 2]) -> f64, x0: f64, w: f64) -> f64 {
    GAUSS
        .iter()
        .map(|&(x, wx)| wx * 0.5 * w * f([x0 + (x + 1.0) * 0.5 * w, 0.5]))
        .sum()
}

fn adaptive_1d(
    f: &dyn Fn([f64; 2]) -> f64,
    x0: f64,
    w: f64,
    coarse: f64,
    tol: f64,
    depth: u32,
) -> f64 {
    let (a, b) = (gauss_1d(f, x0, w / 2.0), gauss_1d(f, x0 + w / 2.0, w / 2.0));
    if depth >= MAX_DEPTH || (depth >= MIN_DEPTH && (a + b - coarse).abs() <= tol * w) {
        return a + b;
    }
    let half = w / 2.0;
    adaptive_1d(f, x0, half, a, tol, depth + 1) + adaptive_1d(f, x0 + half, half, b, tol, depth + 1)
}

fn gauss_2d(f: &dyn Fn([f64; 2]) -> f64, o: [f64; 2], w: f64) -> f64 {
    let mut total = 0.0;
    for &(x, wx) in &GAUSS {
        for &(y, wy) in &GAUSS {
            total += wx
                * wy
                * 0.25
                * w
                * w
                * f([o[0] + (x + 1.0) * 0.5 * w, o[1] + (y + 1.0) * 0.5 * w]);
        }
    }
    total
}

fn adaptive_2d(
    f: &dyn Fn([f64; 2]) -> f64,
    o: [f64; 2],
    w: f64,
    coarse: f64,
    tol: f64,
    depth: u32,
) -> f64 {
    let half = w / 2.0;
    let corners = [
        [o[0], o[1]],
        [o[0] + half, o[1]],
        [o[0], o[1] + half],
        [o[0] + half, o[1] + half],
    ];
    let parts = corners.map(|c| gauss_2d(f, c, half));
    let fine: f64 = parts.iter().sum();
    if depth >= MAX_DEPTH || (depth >= MIN_DEPTH && (fine - coarse).abs() <= tol * w * w) {
        return fine;
    }
    corners
        .iter()
        .zip(parts)
        .map(|(c, p)| adaptive_2d(f, *c, half, p, tol, depth + 1))
        .sum()
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
        Some(Vec2::new(
            (rho * phi.cos()) as f32,
            (rho * phi.sin()) as f32,
        ))
    }
    fn coords(&self, v: &Vec2) -> Option<[f64; 2]> {
        let r = f64::from(self.0);
        Some([
            f64::from(v.length_squared()) / (r * r),
            turn(f64::from(v.y), f64::from(v.x)),
        ])
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
        let (p0, e1, e2) = (
            self.0.as_dvec3(),
            (self.1 - self.0).as_dvec3(),
            (self.2 - self.0).as_dvec3(),
        );
        Some((p0 + s[0] * e1 + s[1] * (1.0 - s[0]) * e2).as_vec3())
    }
    fn coords(&self, x: &Vec3) -> Option<[f64; 2]> {
        let (b0, b1) =
            crate::primitives::UniformTriangle::new(self.0, self.1, self.2).barycentrics(*x)?;
        // x = p0 + β e1 + γ e2 with β = b1, γ = 1 − b0 − b1.
        let s0 = b1;
        let s1 = if s0 < 1.0 {
            (1.0 - b0 - b1) / (1.0 - s0)
        } else {
            0.0
        };
        Some([s0, s1])
    }
    fn jacobian(&self, s: [f64; 2]) -> f64 {
        let n = (self.1 - self.0)
            .as_dvec3()
            .cross((self.2 - self.0).as_dvec3());
        n.length() * (1.0 - s[0])
    }
}

fn turn(y: f64, x: f64) -> f64 {
    let phi = y.atan2(x);
    if phi < 0.0 {
        phi / (2.0 * PI) + 1.0
    } else {
        phi / (2.0 * PI)
    }
}
