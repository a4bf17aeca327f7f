//! Checks (a), inversion and (b): pointwise, at uniforms chosen by proptest.

use std::cell::RefCell;
use std::fmt;

use proptest::test_runner::{Config, RngAlgorithm, TestCaseError, TestError, TestRng, TestRunner};

use super::{Check, Failure, Report};
use crate::distribution::{Coords, Distribution, Embed};

/// Uniforms closer than this to 0 or 1 are not generated: warps are
/// singular at the boundary of the square (poles, cone rims).
const MARGIN: f32 = 0.02;
/// Finite-difference step in uniform space.
const STEP: f32 = 4e-3;
/// Relative disagreement of the two step sizes beyond which a case counts
/// as singular.
const SINGULAR: f64 = 2e-3;

fn embed<T: Embed>(v: &T) -> (Coords, usize) {
    let mut c = Coords::new();
    let m = v.embed(&mut c);
    (c, m)
}

/// The pseudo-determinant of JᵀJ restricted to rank `m`: the sum of its
/// principal minors of order m (columns of discrete choices are zero).
fn gram_pseudo_determinant(columns: &[Coords], m: usize) -> f64 {
    let d = columns.len();
    let gram = |i: usize, j: usize| {
        columns[i]
            .iter()
            .zip(&columns[j])
            .map(|(a, b)| a * b)
            .sum::<f64>()
    };
    let mut total = 0.0;
    for mask in 0u32..(1 << d) {
        if mask.count_ones() as usize != m {
            continue;
        }
        let idx: Vec<usize> = (0..d).filter(|k| mask & (1 << k) != 0).collect();
        let mut a: Vec<Vec<f64>> = idx
            .iter()
            .map(|&i| idx.iter().map(|&j| gram(i, j)).collect())
            .collect();
        total += determinant(&mut a);
    }
    total
}

fn determinant(a: &mut [Vec<f64>]) -> f64 {
    let n = a.len();
    let mut det = 1.0;
    for c in 0..n {
        let p = (c..n)
            .max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs()))
            .unwrap_or(c);
        if a[p][c] == 0.0 {
            return 0.0;
        }
        if p != c {
            a.swap(p, c);
            det = -det;
        }
        det *= a[c][c];
        let (top, bottom) = a.split_at_mut(c + 1);
        let pivot = &top[c];
        for row in bottom {
            let f = row[c] / pivot[c];
            for (x, p) in row[c..].iter_mut().zip(&pivot[c..]) {
                *x -= f * p;
            }
        }
    }
    det
}

/// 1/√pdet(JᵀJ) by central differences of step `h` and of step `h/2`, or
/// `None` where the map is undefined nearby, changes manifold, or has a
/// kink (one-sided differences that do not converge as the step halves).
fn finite_difference_densities<D>(d: &D, u: &[f32], h: f32) -> Option<(f64, f64)>
where
    D: Distribution,
    D::Value: Embed,
{
    let (c0, m) = embed(&d.sample(u)?.value);
    if m == 0 {
        return None;
    }
    let at = |k: usize, delta: f32| -> Option<(Coords, f64)> {
        let mut v = u.to_vec();
        v[k] = (u[k] + delta).clamp(0.0, 1.0 - f32::EPSILON);
        let (c, mv) = embed(&d.sample(&v)?.value);
        (mv == m && c.len() == c0.len()).then_some((c, f64::from(v[k]) - f64::from(u[k])))
    };
    let diff = |a: &Coords, b: &Coords, step: f64| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y) / step)
            .collect::<Coords>()
    };
    let norm = |c: &Coords| c.iter().map(|x| x * x).sum::<f64>().sqrt();
    let (mut coarse, mut fine) = (Vec::with_capacity(u.len()), Vec::with_capacity(u.len()));
    for k in 0..u.len() {
        let (p2, s_p2) = at(k, h)?;
        let (m2, s_m2) = at(k, -h)?;
        let (p1, s_p1) = at(k, h / 2.0)?;
        let (m1, s_m1) = at(k, -h / 2.0)?;
        // One-sided slopes disagree by O(h) on smooth maps, by O(1) at a kink.
        let kink = |plus: &Coords, sp: f64, minus: &Coords, sm: f64| {
            let forward = diff(plus, &c0, sp);
            let backward = diff(&c0, minus, -sm);
            norm(&diff(&forward, &backward, 1.0))
        };
        let (k2, k1) = (kink(&p2, s_p2, &m2, s_m2), kink(&p1, s_p1, &m1, s_m1));
        let central = diff(&p1, &m1, s_p1 - s_m1);
        // Smooth maps give k2 ≈ 2 k1. A kink within h/2 keeps k1 ≈ k2; one
        // between h/2 and h makes k2 much larger than 2 k1.
        let noise = 1e-3 * norm(&central).max(1e-12);
        if (k1 > noise && k1 > 0.7 * k2) || (k2 > noise && k2 > 3.0 * k1) {
            return None;
        }
        coarse.push(diff(&p2, &m2, s_p2 - s_m2));
        fine.push(central);
    }
    let density = |columns: &[Coords]| {
        let det = gram_pseudo_determinant(columns, m);
        (det > 0.0).then(|| 1.0 / det.sqrt())
    };
    Some((density(&coarse)?, density(&fine)?))
}

fn distance(a: &Coords, b: &Coords) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).powi(2))
        .sum::<f64>()
        .sqrt()
}

#[derive(Default)]
struct Tally {
    checked: u32,
    skipped: u32,
    max_error: f64,
    failure: Option<Failure>,
}

pub(super) fn check_pointwise<D>(d: &D, config: &Check) -> Result<Report, Failure>
where
    D: Distribution,
    D::Value: Embed + fmt::Debug,
{
    let dims = d.dims();
    let tally = RefCell::new(Tally::default());
    let mut runner = TestRunner::new_with_rng(
        Config {
            cases: config.cases,
            failure_persistence: None,
            ..Config::default()
        },
        TestRng::from_seed(RngAlgorithm::ChaCha, &seed_bytes(config.seed)),
    );
    let strategy = proptest::collection::vec(MARGIN..1.0 - MARGIN, dims);
    let result = runner.run(&strategy, |u| {
        let failure = check_case(d, &u, config, &mut tally.borrow_mut());
        match failure {
            Some(f) => {
                let message = f.to_string();
                tally.borrow_mut().failure = Some(f);
                Err(TestCaseError::fail(message))
            }
            None => Ok(()),
        }
    });
    let tally = tally.into_inner();
    if let Err(TestError::Fail(..)) = result {
        // The last failure recorded is proptest's shrunk, minimal case.
        return Err(tally.failure.expect("a failing case records its failure"));
    }
    let continuous = tally.checked + tally.skipped;
    if continuous > 0 && f64::from(tally.checked) < config.min_checked * f64::from(continuous) {
        return Err(Failure::TooFewJacobianCases {
            checked: tally.checked,
            skipped: tally.skipped,
        });
    }
    Ok(Report {
        cases: config.cases,
        jacobian_checked: tally.checked,
        jacobian_skipped: tally.skipped,
        jacobian_max_error: tally.max_error,
        ..Report::default()
    })
}

fn seed_bytes(seed: u64) -> [u8; 32] {
    let mut bytes = [0u8; 32];
    for (i, chunk) in bytes.chunks_mut(8).enumerate() {
        chunk.copy_from_slice(
            &(seed
                .wrapping_mul(0x9e37_79b9_7f4a_7c15)
                .wrapping_add(i as u64))
            .to_le_bytes(),
        );
    }
    bytes
}

fn check_case<D>(d: &D, u: &[f32], config: &Check, tally: &mut Tally) -> Option<Failure>
where
    D: Distribution,
    D::Value: Embed + fmt::Debug,
{
    let s = d.sample(u)?;
    // (a) density mode against the recorded density.
    let evaluated = d.density(&s.value);
    let (r, e) = (s.density.value(), evaluated.value());
    let agree = s.density.dirac_order() == evaluated.dirac_order()
        && (r - e).abs() <= config.agreement_tolerance * r.max(e)
        && (r == 0.0) == (e == 0.0);
    if !agree {
        return Some(Failure::Agreement {
            u: u.to_vec(),
            recorded: s.density.to_string(),
            evaluated: evaluated.to_string(),
        });
    }
    if s.density.is_zero() {
        // A value that was produced has positive probability; only events
        // without a density (a miss) may record zero.
        let (_, m) = embed(&s.value);
        let is_event = m == 0 && embed(&s.value).0.is_empty();
        return (!is_event).then(|| Failure::ZeroDensitySample {
            u: u.to_vec(),
            value: format!("{:?}", s.value),
        });
    }
    // Inversion: sampling the inverted uniforms gives the value back.
    let (c0, _) = embed(&s.value);
    let scale = c0.iter().fold(1.0f64, |a, x| a.max(x.abs()));
    let inverted = d.invert(&s.value);
    let back = inverted
        .as_ref()
        .and_then(|v| d.sample(v))
        .map(|t| embed(&t.value).0);
    match back {
        Some(c1) if distance(&c0, &c1) <= 1e-3 * scale => {}
        other => {
            return Some(Failure::Inversion {
                u: u.to_vec(),
                inverted: inverted.map(|v| v.to_vec()),
                distance: other.map_or(f64::INFINITY, |c1| distance(&c0, &c1)),
            });
        }
    }
    // (b) the Jacobian, where the value is continuous and a single branch made it.
    if s.density.is_dirac() || d.has_overlapping_branches() || embed(&s.value).1 == 0 {
        return None;
    }
    let Some((coarse, fine)) = finite_difference_densities(d, u, STEP) else {
        tally.skipped += 1;
        return None;
    };
    // Central differences err by O(h²): Richardson's combination of the two
    // steps removes that term. Where the steps disagree by more than
    // `SINGULAR`, the map is too curved for either to be trusted.
    if (coarse - fine).abs() > SINGULAR * fine {
        tally.skipped += 1;
        return None;
    }
    let expected = (4.0 * fine - coarse) / 3.0;
    tally.checked += 1;
    let error = (r - expected).abs() / expected;
    tally.max_error = tally.max_error.max(error);
    (error > config.jacobian_tolerance).then(|| Failure::Jacobian {
        u: u.to_vec(),
        expected,
        got: r,
    })
}
