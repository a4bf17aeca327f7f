//! Check (c): chi-square goodness of fit of a histogram of samples.

use std::fmt;

use super::{Chart, Check, Failure, Report, chi_square_p_value};
use crate::density::Measure;
use crate::distribution::{Coords, Distribution, Embed};
use crate::rng::{Pcg32, UniformSource};

/// Samples this close (relative to their scale) to an atom with the same
/// mass belong to it: a Dirac lobe matches directions within
/// [`DiracDirection::TOLERANCE`](crate::primitives::DiracDirection::TOLERANCE)
/// (an angle of about 1.4e-3), so a continuous sample that lands that
/// close records the Dirac's density.
const ATOM_TOLERANCE: f64 = 2e-3;

/// Cells are pooled until their expected count reaches this.
const MIN_EXPECTED: f64 = 5.0;

/// A sample that is not a point of a continuous density: a Dirac atom, a
/// discrete event (termination), a miss or a void sample. Atoms with the
/// same value and mass share a cell whose expected count is mass × N.
#[derive(Debug)]
struct Atom {
    coords: Coords,
    mass: f64,
    count: f64,
}

pub(super) fn check_histogram<D>(
    d: &D,
    chart: &impl Chart<D::Value>,
    config: &Check,
    report: &mut Report,
) -> Result<(), Failure>
where
    D: Distribution,
    D::Value: Embed + fmt::Debug,
{
    let n = config.samples as f64;
    let mut observed = vec![0.0; chart.cells()];
    let mut atoms: Vec<Atom> = Vec::new();
    let mut void = 0.0;
    let mut off_chart = 0.0;
    let mut rng = Pcg32::new(config.seed, 0xc41);
    let mut u = vec![0.0f32; d.dims()];
    for _ in 0..config.samples {
        u.iter_mut().for_each(|x| *x = rng.next_f32());
        let Some(s) = d.sample(&u) else {
            void += 1.0;
            continue;
        };
        let continuous = !s.density.is_dirac() && s.density.measure() != Measure::Discrete;
        match chart.cell_of(&s.value) {
            Some(c) if continuous || s.density.measure() == Measure::Discrete => observed[c] += 1.0,
            // A continuous value off the chart counts as "elsewhere" (no atom
            // search: there may be as many of them as samples).
            None if continuous => off_chart += 1.0,
            _ => {
                let mut coords = Coords::new();
                s.value.embed(&mut coords);
                let mass = if continuous { 0.0 } else { s.density.value() };
                let found = atoms.iter_mut().find(|a| {
                    let close = a.coords.len() == coords.len()
                        && a.coords
                            .iter()
                            .zip(&coords)
                            .all(|(x, y)| (x - y).abs() <= ATOM_TOLERANCE * x.abs().max(1.0));
                    close && (a.mass - mass).abs() <= 1e-9 * mass.max(1e-300)
                });
                match found {
                    Some(a) => a.count += 1.0,
                    None => atoms.push(Atom {
                        coords,
                        mass,
                        count: 1.0,
                    }),
                }
            }
        }
    }

    // Expected counts: the density integrated over each cell, then the atoms.
    let density = |v: &D::Value| {
        let p = d.density(v);
        if p.is_dirac() { 0.0 } else { p.value() }
    };
    let mut cells: Vec<(String, f64, f64)> = (0..chart.cells())
        .map(|c| {
            (
                format!("#{c}"),
                observed[c],
                n * chart.integrate(c, &density),
            )
        })
        .collect();
    let mut integral = cells.iter().map(|c| c.2).sum::<f64>() / n;
    // Samples off the chart with a continuous density count as "elsewhere".
    let mut elsewhere = void + off_chart;
    for a in &atoms {
        if a.mass > 0.0 {
            cells.push((
                format!("atom at {:?} of mass {:.4}", a.coords.as_slice(), a.mass),
                a.count,
                n * a.mass,
            ));
            integral += a.mass;
        } else {
            elsewhere += a.count;
        }
    }
    report.integral = integral;
    // Quadrature of densities with jumps leaves an error of order 1e-4.
    if integral > 1.0 + 2e-3 {
        return Err(Failure::IntegralAboveOne { integral });
    }
    cells.push((
        "elsewhere (void, off the chart)".to_string(),
        elsewhere,
        (n * (1.0 - integral)).max(0.0),
    ));

    // Pool the cells of smallest expected count until the pool reaches
    // MIN_EXPECTED. Cells whose support the quadrature misses (a sliver
    // between nodes) land there instead of failing the test; a density that
    // is zero where samples land is caught by the agreement check instead.
    cells.sort_by(|a, b| a.2.total_cmp(&b.2));
    let (mut pooled_o, mut pooled_e, mut first) = (0.0, 0.0, 0);
    while first < cells.len() && pooled_e < MIN_EXPECTED {
        pooled_o += cells[first].1;
        pooled_e += cells[first].2;
        first += 1;
    }
    let mut terms: Vec<(String, f64, f64)> = cells.split_off(first);
    if pooled_e > 0.0 {
        terms.push(("pooled small cells".to_string(), pooled_o, pooled_e));
    }
    let statistic: f64 = terms.iter().map(|(_, o, e)| (o - e) * (o - e) / e).sum();
    let dof = terms.len().saturating_sub(1).max(1);
    let p_value = chi_square_p_value(statistic, dof);
    report.chi_square = statistic;
    report.dof = dof;
    report.p_value = p_value;
    if p_value < config.significance {
        terms.sort_by(|a, b| {
            let score = |t: &(String, f64, f64)| (t.1 - t.2).powi(2) / t.2;
            score(b).total_cmp(&score(a))
        });
        terms.truncate(5);
        return Err(Failure::ChiSquare {
            statistic,
            dof,
            p_value,
            worst: terms,
        });
    }
    Ok(())
}
