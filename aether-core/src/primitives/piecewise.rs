use glam::Vec2;
use smallvec::smallvec;

use super::{DiscreteDistribution, DiscreteError};
use crate::density::{Density, Measure};
use crate::distribution::{Distribution, Sample, Uniforms, below_one};

/// A piecewise-constant density on `[0, 1)` with `n` equal cells.
///
/// Density: n · w_i / Σ w in length measure on cell i.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseConstant1D {
    cells: DiscreteDistribution,
}

impl PiecewiseConstant1D {
    /// Cells with the given non-negative weights.
    pub fn new(weights: &[f64]) -> Result<Self, DiscreteError> {
        Ok(PiecewiseConstant1D {
            cells: DiscreteDistribution::new(weights)?,
        })
    }

    fn cell_density(&self, i: usize) -> f64 {
        self.cells.probability(i) * self.cells.len() as f64
    }

    fn cell_of(&self, x: f32) -> Option<usize> {
        let n = self.cells.len();
        (0.0..1.0)
            .contains(&x)
            .then(|| ((f64::from(x) * n as f64) as usize).min(n - 1))
    }
}

impl Distribution for PiecewiseConstant1D {
    type Value = f32;
    fn dims(&self) -> usize {
        1
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<f32>> {
        let (i, rest) = self.cells.select(u[0]);
        if self.cells.len() == 1 {
            // One cell (a box filter's table): the uniform itself, with no
            // rescaling to round.
            let density = Density::new(self.cell_density(0), Measure::Length);
            return Some(Sample::new(below_one(rest), density));
        }
        let n = self.cells.len() as f64;
        let mut x = below_one(((i as f64 + f64::from(rest)) / n) as f32);
        // Rounding may carry a point at the top of cell i into cell i + 1.
        while self.cell_of(x).is_some_and(|c| c > i) {
            x = f32::from_bits(x.to_bits() - 1);
        }
        Some(Sample::new(
            x,
            Density::new(self.cell_density(i), Measure::Length),
        ))
    }
    fn density(&self, x: &f32) -> Density {
        Density::new(
            self.cell_of(*x).map_or(0.0, |i| self.cell_density(i)),
            Measure::Length,
        )
    }
    fn invert(&self, x: &f32) -> Option<Uniforms> {
        let i = self.cell_of(*x)?;
        if self.cells.probability(i) == 0.0 {
            return None;
        }
        let rest = (x * self.cells.len() as f32 - i as f32).clamp(0.0, 1.0);
        Some(smallvec![self.cells.unselect(i, rest)])
    }
}

/// A piecewise-constant density on the unit square (an environment map's
/// luminance), sampled by the marginal over rows and the conditional within
/// the row.
///
/// Density: f(u, v) / ∫f in area measure on the unit square.
#[derive(Clone, Debug, PartialEq)]
pub struct PiecewiseConstant2D {
    rows: PiecewiseConstant1D,
    columns: Vec<Option<PiecewiseConstant1D>>,
    width: usize,
}

impl PiecewiseConstant2D {
    /// A `width` × `height` table in row-major order (row = v).
    pub fn new(values: &[f64], width: usize, height: usize) -> Result<Self, DiscreteError> {
        if width == 0 || height == 0 || values.len() != width * height {
            return Err(DiscreteError::Empty);
        }
        let row_sums: Vec<f64> = values.chunks(width).map(|r| r.iter().sum()).collect();
        let rows = PiecewiseConstant1D::new(&row_sums)?;
        let columns = values
            .chunks(width)
            .zip(&row_sums)
            .map(|(r, &s)| {
                if s > 0.0 {
                    PiecewiseConstant1D::new(r).map(Some)
                } else {
                    Ok(None)
                }
            })
            .collect::<Result<_, _>>()?;
        Ok(PiecewiseConstant2D {
            rows,
            columns,
            width,
        })
    }

    /// Table width (cells along u).
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// True for a table of one cell: the uniform density on the square.
    fn is_one_cell(&self) -> bool {
        self.width == 1 && self.columns.len() == 1
    }
}

impl Distribution for PiecewiseConstant2D {
    type Value = Vec2;
    fn dims(&self) -> usize {
        2
    }
    fn sample(&self, u: &[f32]) -> Option<Sample<Vec2>> {
        if self.is_one_cell() {
            // A box filter's table, at every camera sample: what the general
            // path computes, without its row lookups.
            let p = Vec2::new(below_one(u[0].max(0.0)), below_one(u[1].max(0.0)));
            return Some(Sample::new(p, Density::new(1.0, Measure::Area)));
        }
        let v = self.rows.sample(&u[1..2])?;
        let row = self.rows.cell_of(v.value)?;
        let x = self.columns[row].as_ref()?.sample(&u[0..1])?;
        let p = Density::new(v.density.value() * x.density.value(), Measure::Area);
        Some(Sample::new(Vec2::new(x.value, v.value), p))
    }
    fn density(&self, p: &Vec2) -> Density {
        if self.is_one_cell() {
            let inside = (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y);
            return Density::new(if inside { 1.0 } else { 0.0 }, Measure::Area);
        }
        let pv = self.rows.density(&p.y);
        let pu = self
            .rows
            .cell_of(p.y)
            .and_then(|r| self.columns[r].as_ref())
            .map_or(0.0, |c| c.density(&p.x).value());
        Density::new(pv.value() * pu, Measure::Area)
    }
    fn invert(&self, p: &Vec2) -> Option<Uniforms> {
        let uv = self.rows.invert(&p.y)?;
        let uu = self.columns[self.rows.cell_of(p.y)?]
            .as_ref()?
            .invert(&p.x)?;
        Some(smallvec![uu[0], uv[0]])
    }
}
