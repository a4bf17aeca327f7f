use glam::Vec2;
use smallvec::smallvec;

use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one};

/// The uniform distribution on `[a, b)`.
///
/// Density: 1 / (b − a) in length measure.
///
/// ```
/// use aether_core::{Distribution, primitives::UniformInterval};
/// let d = UniformInterval::new(2.0, 4.0);
/// assert_eq!(d.sample(&[0.5]).unwrap().value, 3.0);
/// assert_eq!(d.density(&3.0).value(), 0.5);
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UniformInterval {
    a: f32,
    b: f32,
}

impl UniformInterval {
    /// The interval `[a, b)`; `a < b`.
    #[must_use]
    pub fn new(a: f32, b: f32) -> Self {
        debug_assert!(a < b, "empty interval [{a}, {b})");
        UniformInterval { a, b }
    }

    fn pdf(&self) -> Density {
        Density::new(1.0 / f64::from(self.b - self.a), Measure::Length)
    }
}

impl Distribution for UniformInterval {
    type Value = f32;
    fn dims(&self) -> usize {
        1
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<f32>> {
        Some(Sample::new(self.a + u[0] * (self.b - self.a), self.pdf()))
    }
    fn density(&self, x: &f32) -> Density {
        if (self.a..self.b).contains(x) {
            self.pdf()
        } else {
            Density::zero(Measure::Length)
        }
    }
    fn invert(&self, x: &f32) -> Option<Uniforms> {
        (self.a..self.b)
            .contains(x)
            .then(|| smallvec![below_one((x - self.a) / (self.b - self.a))])
    }
}

/// The uniform distribution on the unit square: the identity map.
///
/// Density: 1 in area measure.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UniformSquare;

impl Distribution for UniformSquare {
    type Value = Vec2;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec2>> {
        Some(Sample::new(
            Vec2::new(u[0], u[1]),
            Density::new(1.0, Measure::Area),
        ))
    }
    fn density(&self, p: &Vec2) -> Density {
        let inside = (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y);
        Density::new(if inside { 1.0 } else { 0.0 }, Measure::Area)
    }
    fn invert(&self, p: &Vec2) -> Option<Uniforms> {
        let inside = (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y);
        inside.then(|| smallvec![p.x, p.y])
    }
}

/// The cells of a `columns` × `rows` grid, each equally likely: the pixel
/// a primary-sample-space sampler picks, or one of several techniques
/// (`rows` = 1, read from one uniform). The first uniform picks the
/// column and the second the row, so that a small change of the uniforms
/// moves to a nearby cell.
/// Values are row-major indices; [`cell`](Self::cell) gives the column
/// and row.
///
/// Density: 1 / (columns · rows), discrete.
///
/// ```
/// use aether_core::{Distribution, primitives::UniformCells};
/// let pixels = UniformCells::new(4, 2);
/// let s = pixels.sample(&[0.3, 0.9]).unwrap();
/// assert_eq!(pixels.cell(s.value), [1, 1]);
/// assert_eq!(s.density.value(), 1.0 / 8.0);
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct UniformCells {
    columns: u32,
    rows: u32,
}

impl UniformCells {
    /// A grid of `columns` × `rows` cells (each at least one).
    #[must_use]
    pub fn new(columns: u32, rows: u32) -> Self {
        UniformCells {
            columns: columns.max(1),
            rows: rows.max(1),
        }
    }

    /// The number of cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.columns as usize * self.rows as usize
    }

    /// Never true: a grid has at least one cell.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The column and row of cell `index`.
    #[must_use]
    pub fn cell(&self, index: usize) -> [u32; 2] {
        let c = self.columns as usize;
        [(index % c) as u32, (index / c) as u32]
    }

    fn pdf(&self) -> Density {
        Density::discrete(1.0 / self.len() as f64)
    }
}

impl Distribution for UniformCells {
    type Value = usize;
    fn dims(&self) -> usize {
        if self.rows == 1 { 1 } else { 2 }
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<usize>> {
        // In f64: a film of a million columns still picks every one.
        let pick = |u: f32, n: u32| ((f64::from(u) * f64::from(n)) as u32).min(n - 1);
        let y = if self.rows == 1 {
            0
        } else {
            pick(u[1], self.rows)
        };
        let x = pick(u[0], self.columns);
        Some(Sample::new(
            y as usize * self.columns as usize + x as usize,
            self.pdf(),
        ))
    }
    fn density(&self, i: &usize) -> Density {
        if *i < self.len() {
            self.pdf()
        } else {
            Density::zero(Measure::Discrete)
        }
    }
    fn invert(&self, i: &usize) -> Option<Uniforms> {
        let [x, y] = (*i < self.len()).then(|| self.cell(*i))?;
        let middle = |k: u32, n: u32| below_one(((f64::from(k) + 0.5) / f64::from(n)) as f32);
        let mut u = smallvec![middle(x, self.columns)];
        if self.rows > 1 {
            u.push(middle(y, self.rows));
        }
        Some(u)
    }
}
