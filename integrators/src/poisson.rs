//! Screened Poisson reconstruction: the image that best agrees with a
//! noisy primal estimate P and with estimated gradients Gx, Gy,
//!
//!   min over I of  Σ ‖α(I − P)‖ + Σ ‖∂x I − Gx‖ + Σ ‖∂y I − Gy‖,
//!
//! with ∂x I = I(x + 1, y) − I(x, y) (likewise ∂y), in the L2 norm (squared;
//! a linear system solved by preconditioned conjugate gradients) or the L1
//! norm (iteratively reweighted least squares, started from the L2
//! solution). Each colour channel is solved on its own, in f64.

use rayon::prelude::*;

/// The norm the reconstruction minimises.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Norm {
    /// Least absolute deviations: robust to outliers in the gradients, as
    /// Kettunen et al. recommend for gradient-domain path tracing.
    L1,
    /// Least squares: unbiased, noisier.
    L2,
}

/// At most this many iteratively reweighted least-squares rounds of an L1
/// reconstruction, each at most this many conjugate-gradient iterations.
const L1_ROUNDS: usize = 30;
const L1_ITERATIONS: usize = 200;

/// The image (row by row, `width` × `height`) that best fits `primal` and
/// the gradients `dx` (at (x, y): I(x + 1, y) − I(x, y); the last column is
/// ignored) and `dy` (likewise down; the last row is ignored), with weight
/// `alpha` on the primal, in the norm `norm`.
///
/// ```
/// use integrators::poisson::{Norm, reconstruct};
/// // A 2 × 1 image: the primal says 1 and 1, the gradient says +2.
/// let (primal, dx, dy) = ([[1.0; 3], [1.0; 3]], [[2.0; 3], [0.0; 3]], [[0.0; 3]; 2]);
/// let image = reconstruct(2, 1, &primal, &dx, &dy, 0.5, Norm::L2);
/// // 0.25·((a − 1)² + (b − 1)²) + (b − a − 2)² is least at b − a = 16/9.
/// assert!((image[1][0] - image[0][0] - 16.0 / 9.0).abs() < 1e-4);
/// ```
///
/// # Panics
/// If the images do not have `width` × `height` pixels.
#[must_use]
pub fn reconstruct(
    width: u32,
    height: u32,
    primal: &[[f32; 3]],
    dx: &[[f32; 3]],
    dy: &[[f32; 3]],
    alpha: f32,
    norm: Norm,
) -> Vec<[f32; 3]> {
    let n = width as usize * height as usize;
    assert!(
        primal.len() == n && dx.len() == n && dy.len() == n,
        "every image must have {width} × {height} pixels"
    );
    let channels: Vec<Vec<f64>> = (0..3)
        .into_par_iter()
        .map(|c| {
            let take = |image: &[[f32; 3]]| image.iter().map(|p| f64::from(p[c])).collect();
            let problem = Problem::new(
                width as usize,
                height as usize,
                f64::from(alpha),
                take(primal),
                take(dx),
                take(dy),
            );
            problem.solve(norm)
        })
        .collect();
    (0..n)
        .map(|i| [0, 1, 2].map(|c| channels[c][i] as f32))
        .collect()
}

/// The gradients of an image as [`reconstruct`] reads them: at (x, y),
/// I(x + 1, y) − I(x, y) and I(x, y + 1) − I(x, y), zero in the last column
/// and row.
///
/// ```
/// use integrators::poisson::differences;
/// let (dx, dy) = differences(&[[1.0; 3], [3.0; 3], [2.0; 3], [2.0; 3]], 2);
/// assert_eq!((dx[0], dx[1], dy[0], dy[1]), ([2.0; 3], [0.0; 3], [1.0; 3], [-1.0; 3]));
/// ```
#[must_use]
pub fn differences(image: &[[f32; 3]], width: u32) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    let (n, w) = (image.len(), width as usize);
    let diff = |i: usize, j: usize| [0, 1, 2].map(|c| image[j][c] - image[i][c]);
    let dx = (0..n)
        .map(|i| {
            if i % w + 1 < w {
                diff(i, i + 1)
            } else {
                [0.0; 3]
            }
        })
        .collect();
    let dy = (0..n)
        .map(|i| if i + w < n { diff(i, i + w) } else { [0.0; 3] })
        .collect();
    (dx, dy)
}

/// One channel's least-squares problem with per-term weights (all one for
/// L2; reweighted for L1). Edges that leave the image have weight zero, so
/// that the operator runs without a test per pixel.
struct Problem {
    width: usize,
    alpha2: f64,
    primal: Vec<f64>,
    dx: Vec<f64>,
    dy: Vec<f64>,
    /// Weights of the primal, horizontal and vertical terms.
    wp: Vec<f64>,
    wx: Vec<f64>,
    wy: Vec<f64>,
}

impl Problem {
    fn new(
        width: usize,
        height: usize,
        alpha: f64,
        primal: Vec<f64>,
        dx: Vec<f64>,
        dy: Vec<f64>,
    ) -> Self {
        let n = width * height;
        let mut p = Problem {
            width,
            alpha2: alpha * alpha,
            primal,
            dx,
            dy,
            wp: vec![1.0; n],
            wx: vec![1.0; n],
            wy: vec![1.0; n],
        };
        p.clear_outer_edges();
        p
    }

    /// Zero weight for the edges past the last column and row.
    fn clear_outer_edges(&mut self) {
        let (w, n) = (self.width, self.wx.len());
        for i in (w - 1..n).step_by(w) {
            self.wx[i] = 0.0;
        }
        for wy in &mut self.wy[n - w..] {
            *wy = 0.0;
        }
    }

    /// Solves in `norm`, starting from the primal.
    fn solve(mut self, norm: Norm) -> Vec<f64> {
        let mut image = self.primal.clone();
        self.conjugate_gradients(&mut image, 3000, 1e-12);
        // The constant image is A's slowest eigenvector (eigenvalue α²):
        // set its component exactly, as the solution keeps the primal's sum.
        let n = image.len() as f64;
        let shift = self
            .primal
            .iter()
            .zip(&image)
            .map(|(p, v)| p - v)
            .sum::<f64>()
            / n;
        for v in &mut image {
            *v += shift;
        }
        if norm == Norm::L1 {
            // Residuals below this count as this large, so that no weight
            // is infinite: a small fraction of the image's mean.
            let (n, w) = (image.len(), self.width);
            let scale = self.primal.iter().map(|v| v.abs()).sum::<f64>() / n as f64;
            let floor = 1e-4 * scale.max(1e-12);
            let alpha = self.alpha2.sqrt();
            let weight = |r: f64| 1.0 / r.abs().max(floor);
            for _ in 0..L1_ROUNDS {
                let before = image.clone();
                for ((wp, v), p) in self.wp.iter_mut().zip(&image).zip(&self.primal) {
                    *wp = weight(alpha * (v - p));
                }
                for i in 0..n - 1 {
                    self.wx[i] = weight(image[i + 1] - image[i] - self.dx[i]);
                }
                for i in 0..n - w {
                    self.wy[i] = weight(image[i + w] - image[i] - self.dy[i]);
                }
                self.clear_outer_edges();
                // A few iterations per round: each round's weights are
                // provisional, and the image barely changes past this.
                // Each round's weights are provisional: solve to a modest
                // residual, and stop once a round barely moves the image.
                self.conjugate_gradients(&mut image, L1_ITERATIONS, 1e-6);
                let change = image
                    .iter()
                    .zip(&before)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                if change < 1e-3 * scale {
                    break;
                }
            }
        }
        image
    }

    /// A v, for the normal equations A = α²Wp + ∂xᵀWx∂x + ∂yᵀWy∂y.
    fn apply(&self, v: &[f64], out: &mut [f64]) {
        let (n, w) = (v.len(), self.width);
        for i in 0..n {
            out[i] = self.alpha2 * self.wp[i] * v[i];
        }
        for i in 0..n - 1 {
            let t = self.wx[i] * (v[i + 1] - v[i]);
            out[i] -= t;
            out[i + 1] += t;
        }
        for i in 0..n - w {
            let t = self.wy[i] * (v[i + w] - v[i]);
            out[i] -= t;
            out[i + w] += t;
        }
    }

    /// The right-hand side α²Wp P + ∂xᵀWx Gx + ∂yᵀWy Gy and the diagonal of A.
    fn rhs_and_diagonal(&self) -> (Vec<f64>, Vec<f64>) {
        let (n, w) = (self.primal.len(), self.width);
        let mut b: Vec<f64> = (0..n)
            .map(|i| self.alpha2 * self.wp[i] * self.primal[i])
            .collect();
        let mut diagonal: Vec<f64> = (0..n).map(|i| self.alpha2 * self.wp[i]).collect();
        let edges = [(1, &self.wx, &self.dx), (w, &self.wy, &self.dy)];
        for (step, weights, gradient) in edges {
            for i in 0..n - step {
                let t = weights[i] * gradient[i];
                b[i] -= t;
                b[i + step] += t;
                diagonal[i] += weights[i];
                diagonal[i + step] += weights[i];
            }
        }
        (b, diagonal)
    }

    /// Jacobi-preconditioned conjugate gradients on A x = b from `x`, until
    /// ‖r‖² is `tolerance` ‖b‖² or after `iterations`.
    fn conjugate_gradients(&self, x: &mut [f64], iterations: usize, tolerance: f64) {
        let n = x.len();
        let (b, diagonal) = self.rhs_and_diagonal();
        let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| a * b).sum::<f64>();
        let mut ax = vec![0.0; n];
        self.apply(x, &mut ax);
        let mut r: Vec<f64> = b.iter().zip(&ax).map(|(b, a)| b - a).collect();
        let mut z: Vec<f64> = r.iter().zip(&diagonal).map(|(r, d)| r / d).collect();
        let mut p = z.clone();
        let mut rz = dot(&r, &z);
        let mut ap = ax;
        let mut rr = dot(&r, &r);
        let target = tolerance * dot(&b, &b).max(1e-300);
        for _ in 0..iterations {
            if rr <= target {
                break;
            }
            self.apply(&p, &mut ap);
            let pap = dot(&p, &ap);
            if pap <= 0.0 || !pap.is_finite() {
                break;
            }
            let step = rz / pap;
            let (mut rz_next, mut rr_next) = (0.0, 0.0);
            for i in 0..n {
                x[i] += step * p[i];
                r[i] -= step * ap[i];
                z[i] = r[i] / diagonal[i];
                rz_next += r[i] * z[i];
                rr_next += r[i] * r[i];
            }
            let beta = rz_next / rz;
            (rz, rr) = (rz_next, rr_next);
            for i in 0..n {
                p[i] = z[i] + beta * p[i];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use aether_core::{Pcg32, UniformSource};

    /// A test image: a ramp, a bright square and a colour per channel.
    fn image(w: usize, h: usize) -> Vec<[f32; 3]> {
        (0..w * h)
            .map(|i| {
                let (x, y) = ((i % w) as f32, (i / w) as f32);
                let square = if (4.0..9.0).contains(&x) && (3.0..7.0).contains(&y) {
                    5.0
                } else {
                    0.0
                };
                [0.1 * x + square, 0.05 * y + 1.0, square * 0.5]
            })
            .collect()
    }

    fn rmse(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
        let sum: f64 = a
            .iter()
            .zip(b)
            .flat_map(|(a, b)| (0..3).map(move |c| f64::from(a[c] - b[c]).powi(2)))
            .sum();
        (sum / (3 * a.len()) as f64).sqrt()
    }

    #[test]
    fn exact_gradients_and_primal_give_the_image_back() {
        let (w, h) = (17, 13);
        let truth = image(w, h);
        let (dx, dy) = differences(&truth, w as u32);
        for norm in [Norm::L2, Norm::L1] {
            let got = reconstruct(w as u32, h as u32, &truth, &dx, &dy, 0.04, norm);
            assert!(
                rmse(&got, &truth) < 1e-5,
                "{norm:?}: {}",
                rmse(&got, &truth)
            );
        }
    }

    #[test]
    fn exact_gradients_remove_the_primal_noise() {
        let (w, h) = (24, 20);
        let truth = image(w, h);
        let (dx, dy) = differences(&truth, w as u32);
        let mut rng = Pcg32::new(3, 1);
        let noisy: Vec<[f32; 3]> = truth
            .iter()
            .map(|p| p.map(|v| v + 2.0 * (rng.next_f32() - 0.5)))
            .collect();
        for norm in [Norm::L2, Norm::L1] {
            let got = reconstruct(w as u32, h as u32, &noisy, &dx, &dy, 0.04, norm);
            let (before, after) = (rmse(&noisy, &truth), rmse(&got, &truth));
            assert!(after < 0.15 * before, "{norm:?}: {before} → {after}");
        }
    }

    #[test]
    fn l1_shrugs_off_gradient_outliers_that_l2_spreads() {
        let (w, h) = (24, 20);
        let truth = image(w, h);
        let (mut dx, dy) = differences(&truth, w as u32);
        // A few fireflies in the gradients.
        for i in [30, 170, 301] {
            dx[i] = dx[i].map(|v| v + 40.0);
        }
        let l2 = reconstruct(w as u32, h as u32, &truth, &dx, &dy, 0.04, Norm::L2);
        let l1 = reconstruct(w as u32, h as u32, &truth, &dx, &dy, 0.04, Norm::L1);
        let (e2, e1) = (rmse(&l2, &truth), rmse(&l1, &truth));
        assert!(e1 < 0.1 * e2, "L1 {e1}, L2 {e2}");
    }
}
