//! Charts of four coordinates: values that are pairs of surface points (a
//! line through a portal) or paths with two free vertices (a perturbation
//! of the film point and of a direction), binned on a grid of the unit
//! 4-cube.

use super::Chart;

/// A parameterisation of a value space by the unit 4-cube.
pub trait Parameterization4<T> {
    /// The value at chart coordinates `s` and its measure per unit of chart
    /// volume there (one evaluation, since the value may take ray casts).
    fn value(&self, s: [f64; 4]) -> Option<(T, f64)>;
    /// The chart coordinates of `value`, or `None` if it lies off the chart.
    fn coords(&self, value: &T) -> Option<[f64; 4]>;
}

/// A regular grid of `n` cells per coordinate over `param`, integrated by a
/// product rule of three Gauss–Legendre points per coordinate on each of a
/// cell's 16 half-cells (1,296 evaluations a cell, no adaptivity: in four
/// dimensions refinement costs too much, so the coordinates should make
/// the density nearly constant, as a strategy's own distributions do).
#[derive(Clone, Copy, Debug)]
pub struct Grid4<P> {
    param: P,
    n: usize,
}

impl<P> Grid4<P> {
    /// `n` cells per coordinate over `param`.
    pub fn new(param: P, n: usize) -> Self {
        Grid4 { param, n: n.max(1) }
    }
}

/// Three-point Gauss–Legendre nodes and weights on [0, 1].
const GAUSS: [(f64, f64); 3] = [
    (0.112_701_665_379_258_3, 5.0 / 18.0),
    (0.5, 8.0 / 18.0),
    (0.887_298_334_620_741_7, 5.0 / 18.0),
];

impl<T, P: Parameterization4<T>> Chart<T> for Grid4<P> {
    fn cells(&self) -> usize {
        self.n.pow(4)
    }
    fn cell_of(&self, value: &T) -> Option<usize> {
        let s = self.param.coords(value)?;
        let n = self.n;
        s.iter().try_fold(0, |cell, &x| {
            (0.0..=1.0)
                .contains(&x)
                .then(|| cell * n + ((x * n as f64) as usize).min(n - 1))
        })
    }
    fn integrate(&self, cell: usize, density: &dyn Fn(&T) -> f64) -> f64 {
        let n = self.n;
        let mut lo = [0.0; 4];
        let mut rest = cell;
        for k in (0..4).rev() {
            lo[k] = (rest % n) as f64 / n as f64;
            rest /= n;
        }
        let h = 0.5 / n as f64;
        let mut total = 0.0;
        for half in 0..16usize {
            for node in 0..81usize {
                let mut s = [0.0; 4];
                let mut weight = 1.0;
                for (k, x) in s.iter_mut().enumerate() {
                    let (g, w) = GAUSS[(node / 3usize.pow(k as u32)) % 3];
                    *x = lo[k] + (((half >> k) & 1) as f64 + g) * h;
                    weight *= w * h;
                }
                if let Some((v, jacobian)) = self.param.value(s) {
                    let p = density(&v);
                    if p > 0.0 {
                        total += weight * p * jacobian;
                    }
                }
            }
        }
        total
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The point of the 4-cube, with density 2 s₀ (uniform in the rest).
    struct Cube;
    impl Parameterization4<[f64; 4]> for Cube {
        fn value(&self, s: [f64; 4]) -> Option<([f64; 4], f64)> {
            Some((s, 1.0))
        }
        fn coords(&self, v: &[f64; 4]) -> Option<[f64; 4]> {
            Some(*v)
        }
    }

    #[test]
    fn cells_integrate_a_linear_density_exactly() {
        let grid = Grid4::new(Cube, 3);
        let density = |v: &[f64; 4]| 2.0 * v[0];
        let total: f64 = (0..grid.cells()).map(|c| grid.integrate(c, &density)).sum();
        assert!((total - 1.0).abs() < 1e-12, "{total}");
        // The last cell of the first coordinate holds 5/9 of the mass, over
        // the 27 cells of the others.
        let last = grid.integrate(grid.cell_of(&[0.9, 0.1, 0.1, 0.1]).unwrap(), &density);
        assert!((last - 5.0 / 9.0 / 27.0).abs() < 1e-12, "{last}");
    }
}
