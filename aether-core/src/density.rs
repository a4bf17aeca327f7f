//! Densities with their measure and Dirac order.
//!
//! A density is not just a number: it is measured against area, solid angle,
//! length or counting measure, and it may carry Dirac factors (a specular
//! lobe, a point light, a pinhole). Two densities of the same path compare
//! first by their Dirac order, then by value; that is what makes specular
//! paths and point lights compose in MIS without special cases.

use std::fmt;

/// True if `x` is finite. `x − x` is zero exactly for finite `x` (NaN for
/// infinities and NaN), so this is one subtraction and one comparison of
/// floats, without branches; `x.is_finite()` followed by a comparison (as
/// in `x.is_finite() && x > 0.0`) compiled to tests of the bits with three
/// branches. Densities are checked at every step: this form took 1.8 % of
/// a path tracer's instructions off `Density::new` alone.
#[inline(always)]
#[allow(clippy::eq_op)]
pub(crate) fn is_finite(x: f64) -> bool {
    x - x == 0.0
}

/// The measure a single density is expressed in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Measure {
    /// Counting measure: a probability mass (light choice, lobe choice, termination).
    Discrete,
    /// Length on an interval.
    Length,
    /// Area on a surface or in the plane (disk, square, triangle).
    Area,
    /// Solid angle on the unit sphere of directions.
    SolidAngle,
    /// The product of two area measures (a two-vertex segment).
    AreaProduct,
}

impl Measure {
    /// The dimension of the measure (0 for counting measure).
    #[must_use]
    pub const fn dimension(self) -> usize {
        match self {
            Measure::Discrete => 0,
            Measure::Length => 1,
            Measure::Area | Measure::SolidAngle => 2,
            Measure::AreaProduct => 4,
        }
    }

    fn product(self, other: Measure) -> Measure {
        match (self, other) {
            (Measure::Discrete, m) | (m, Measure::Discrete) => m,
            (Measure::Area, Measure::Area) => Measure::AreaProduct,
            (a, b) => {
                debug_assert!(false, "product of measures {a:?} and {b:?} is not modelled");
                a
            }
        }
    }
}

/// The density of one sampled value: a non-negative value, its measure, and
/// how many Dirac factors it carries.
///
/// A density with `dirac_order() > 0` is the discrete mass of a Dirac component
/// (times the conversion factors applied to it, such as the solid-angle to
/// area change at a hit point). A zero density means the value cannot be
/// produced at all. Non-finite or negative values are turned into zero.
///
/// ```
/// use aether_core::{Density, Measure};
/// let p = Density::discrete(0.25) * Density::new(2.0, Measure::SolidAngle);
/// assert_eq!(p.value(), 0.5);
/// assert_eq!(p.measure(), Measure::SolidAngle);
/// ```
#[derive(Clone, Copy, PartialEq)]
pub struct Density {
    value: f64,
    /// The Dirac order times eight plus the measure's index: two fields,
    /// not three, so that a density is a pair of scalars that moves in
    /// registers. As three, a density chosen between two (kept or
    /// evaluated, say) went through a stack slot written a field at a
    /// time and read back sixteen bytes at once, which the store buffer
    /// cannot forward (a sixth of BDPT's join weighing, by perf).
    kind: u32,
}

/// The measures by index in [`Density::kind`], which is their order in
/// [`Measure`] (padded to eight, so that a masked index needs no bounds
/// check).
const MEASURES: [Measure; 8] = [
    Measure::Discrete,
    Measure::Length,
    Measure::Area,
    Measure::SolidAngle,
    Measure::AreaProduct,
    Measure::Discrete,
    Measure::Discrete,
    Measure::Discrete,
];

const fn kind(measure: Measure, dirac: u32) -> u32 {
    (dirac << 3) | measure as u32
}

impl fmt::Debug for Density {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Density")
            .field("value", &self.value)
            .field("measure", &self.measure())
            .field("dirac", &self.dirac_order())
            .finish()
    }
}

impl Density {
    /// Zero, in area measure: what cannot be sampled.
    pub(crate) const ZERO: Density = Density {
        value: 0.0,
        kind: kind(Measure::Area, 0),
    };

    /// A continuous density in `measure`.
    #[must_use]
    pub fn new(value: f64, measure: Measure) -> Self {
        let value = if is_finite(value) && value > 0.0 {
            value
        } else {
            0.0
        };
        Density {
            value,
            kind: kind(measure, 0),
        }
    }

    /// A probability mass of a discrete event.
    #[must_use]
    pub fn discrete(mass: f64) -> Self {
        Density::new(mass, Measure::Discrete)
    }

    /// A Dirac component with discrete `mass`, located in a space whose
    /// continuous measure would be `measure`.
    #[must_use]
    pub fn dirac(mass: f64, measure: Measure) -> Self {
        Density {
            kind: kind(measure, 1),
            ..Density::new(mass, measure)
        }
    }

    /// The zero density of a value that cannot be produced.
    #[must_use]
    pub fn zero(measure: Measure) -> Self {
        Density {
            value: 0.0,
            kind: kind(measure, 0),
        }
    }

    /// The numeric value (the mass, for Dirac components).
    #[must_use]
    pub fn value(self) -> f64 {
        self.value
    }

    /// The measure the density is expressed in.
    #[must_use]
    pub fn measure(self) -> Measure {
        MEASURES[(self.kind & 7) as usize]
    }

    /// How many Dirac factors the density carries.
    #[must_use]
    pub fn dirac_order(self) -> u32 {
        self.kind >> 3
    }

    /// True if the value cannot be produced.
    #[must_use]
    pub fn is_zero(self) -> bool {
        self.value == 0.0
    }

    /// True if the density carries at least one Dirac factor.
    #[must_use]
    pub fn is_dirac(self) -> bool {
        self.dirac_order() > 0 && self.value > 0.0
    }

    /// Multiplies by a Jacobian factor, keeping measure and Dirac order.
    #[must_use]
    pub fn scale(self, factor: f64) -> Self {
        // `new` only cleans the value: its measure is replaced by this
        // density's kind.
        Density {
            kind: self.kind,
            ..Density::new(self.value * factor, Measure::Discrete)
        }
    }

    /// The same density re-expressed in another measure after a change of
    /// variables whose Jacobian factor is `factor` (for instance
    /// |cos θ| / r² from solid angle to area).
    #[must_use]
    pub fn convert(self, factor: f64, measure: Measure) -> Self {
        Density {
            kind: kind(measure, self.dirac_order()),
            ..self.scale(factor)
        }
    }
}

/// The sum of two densities of the same value (a mixture). The term of
/// higher Dirac order dominates: a continuous density added to a Dirac one
/// is negligible.
impl std::ops::Add for Density {
    type Output = Density;
    fn add(self, other: Density) -> Density {
        if other.is_zero() {
            return self;
        }
        if self.is_zero() {
            return other;
        }
        match self.dirac_order().cmp(&other.dirac_order()) {
            std::cmp::Ordering::Greater => self,
            std::cmp::Ordering::Less => other,
            std::cmp::Ordering::Equal => Density {
                value: self.value + other.value,
                ..self
            },
        }
    }
}

impl std::ops::Mul for Density {
    type Output = Density;
    fn mul(self, rhs: Density) -> Density {
        let measure = self.measure().product(rhs.measure());
        Density {
            value: self.value * rhs.value,
            kind: kind(measure, self.dirac_order() + rhs.dirac_order()),
        }
    }
}

impl fmt::Display for Density {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6e} ({:?}", self.value, self.measure())?;
        if self.dirac_order() > 0 {
            write!(f, ", Dirac order {}", self.dirac_order())?;
        }
        write!(f, ")")
    }
}

/// The density of a whole path: a product of per-vertex densities.
///
/// Zero factors are counted rather than multiplied in, so that a factor can
/// be divided out again exactly (the ratio recursion of MIS depends on it).
#[derive(Clone, Copy, PartialEq)]
pub struct PathDensity {
    value: f64,
    /// The number of zero factors times 2³² plus the Dirac order: two
    /// fields, so that a path density is a pair of scalars and moves in
    /// registers (as [`Density`] does), and a product adds both counts in
    /// one addition.
    counts: u64,
}

/// One zero factor in [`PathDensity::counts`].
const ZERO_FACTOR: u64 = 1 << 32;

impl fmt::Debug for PathDensity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("PathDensity")
            .field("value", &self.value)
            .field("zeros", &self.zeros())
            .field("dirac", &self.dirac_order())
            .finish()
    }
}

impl Default for PathDensity {
    fn default() -> Self {
        PathDensity::ONE
    }
}

impl PathDensity {
    /// The empty product.
    pub const ONE: PathDensity = PathDensity {
        value: 1.0,
        counts: 0,
    };

    fn zeros(self) -> u32 {
        (self.counts >> 32) as u32
    }

    /// Multiplies a factor in.
    #[must_use]
    pub fn times(self, d: Density) -> PathDensity {
        if d.is_zero() {
            PathDensity {
                counts: self.counts + ZERO_FACTOR,
                ..self
            }
        } else {
            PathDensity {
                value: self.value * d.value,
                counts: self.counts + u64::from(d.dirac_order()),
            }
        }
    }

    /// The product of two path densities (of disjoint sets of vertices).
    #[must_use]
    pub fn times_path(self, other: PathDensity) -> PathDensity {
        PathDensity {
            value: self.value * other.value,
            counts: self.counts + other.counts,
        }
    }

    /// Divides out a factor that was multiplied in before.
    #[must_use]
    pub fn divided_by(self, d: Density) -> PathDensity {
        if d.is_zero() {
            debug_assert!(
                self.zeros() > 0,
                "dividing out a zero factor that was never multiplied in"
            );
            PathDensity {
                counts: match self.zeros() {
                    0 => self.counts,
                    _ => self.counts - ZERO_FACTOR,
                },
                ..self
            }
        } else {
            debug_assert!(
                self.dirac_order() >= d.dirac_order(),
                "dividing out Dirac factors that were never multiplied in"
            );
            PathDensity {
                value: self.value / d.value,
                counts: self.counts - u64::from(d.dirac_order()),
            }
        }
    }

    /// The numeric value: the product of the factors' values (masses for Dirac factors).
    #[must_use]
    pub fn value(self) -> f64 {
        if self.zeros() > 0 { 0.0 } else { self.value }
    }

    /// The number of Dirac factors in the product.
    #[must_use]
    pub fn dirac_order(self) -> u32 {
        self.counts as u32
    }

    /// True if the path cannot be produced.
    #[must_use]
    pub fn is_zero(self) -> bool {
        self.zeros() > 0 || self.value == 0.0 || !is_finite(self.value)
    }

    /// The density of a mixture whose components have densities `self`
    /// and `other` (each already weighted by its probability): a component
    /// with more Dirac factors dominates, equal orders add.
    #[must_use]
    pub fn plus(self, other: PathDensity) -> PathDensity {
        if other.is_zero() {
            return self;
        }
        if self.is_zero() {
            return other;
        }
        match other.dirac_order().cmp(&self.dirac_order()) {
            std::cmp::Ordering::Greater => other,
            std::cmp::Ordering::Less => self,
            std::cmp::Ordering::Equal => PathDensity {
                value: self.value + other.value,
                ..self
            },
        }
    }

    /// `w / self`: a MIS weight over the density of its path, what an
    /// estimate multiplies its integrand by; zero where the density
    /// vanishes or the quotient is not finite (a grazing vertex, whose
    /// contribution vanishes with its density).
    ///
    /// ```
    /// use aether_core::{Density, Measure, PathDensity};
    /// let p = PathDensity::ONE.times(Density::new(4.0, Measure::Area));
    /// assert_eq!(p.weight_over(0.5), 0.125);
    /// assert_eq!(p.times(Density::zero(Measure::Area)).weight_over(0.5), 0.0);
    /// ```
    #[must_use]
    pub fn weight_over(self, w: f64) -> f64 {
        match w / self.value() {
            r if is_finite(r) && !self.is_zero() => r,
            _ => 0.0,
        }
    }

    /// `other / self` in the sense of MIS: infinite if `other` has more Dirac
    /// factors, zero if it has fewer, the ratio of values if they match.
    #[must_use]
    pub fn ratio_to(self, other: PathDensity) -> f64 {
        if other.is_zero() {
            return 0.0;
        }
        if self.is_zero() {
            return f64::INFINITY;
        }
        match other.dirac_order().cmp(&self.dirac_order()) {
            std::cmp::Ordering::Greater => f64::INFINITY,
            std::cmp::Ordering::Less => 0.0,
            std::cmp::Ordering::Equal => other.value / self.value,
        }
    }
}

impl fmt::Display for PathDensity {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:.6e}", self.value())?;
        if self.dirac_order() > 0 {
            write!(f, " (Dirac order {})", self.dirac_order())?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn densities_keep_their_measure_and_dirac_order() {
        let all = [
            Measure::Discrete,
            Measure::Length,
            Measure::Area,
            Measure::SolidAngle,
            Measure::AreaProduct,
        ];
        for m in all {
            let mut d = Density::new(0.5, m);
            for order in 0..40 {
                assert_eq!((d.measure(), d.dirac_order()), (m, order));
                assert_eq!(d.scale(2.0).measure(), m);
                assert_eq!(d.scale(2.0).dirac_order(), order);
                for n in all {
                    let c = d.convert(3.0, n);
                    assert_eq!((c.measure(), c.dirac_order(), c.value()), (n, order, 1.5));
                }
                d = d * Density::dirac(1.0, Measure::Discrete);
            }
        }
        let area = Density::new(2.0, Measure::Area);
        assert_eq!((area * area).measure(), Measure::AreaProduct);
        let sum = Density::dirac(0.5, Measure::Length) + Density::dirac(0.25, Measure::Length);
        assert_eq!(
            (sum.value(), sum.measure(), sum.dirac_order()),
            (0.75, Measure::Length, 1)
        );
        let p = Density::dirac(0.25, Measure::SolidAngle) * Density::new(2.0, Measure::Discrete);
        let shown = format!("{p:?}");
        assert_eq!(
            shown,
            "Density { value: 0.5, measure: SolidAngle, dirac: 1 }"
        );
        assert_eq!(Density::ZERO, Density::zero(Measure::Area));
        assert_ne!(
            Density::zero(Measure::Area),
            Density::zero(Measure::SolidAngle)
        );
    }

    #[test]
    fn path_densities_count_zeros_and_dirac_factors_apart() {
        let dirac = Density::dirac(0.5, Measure::Area);
        let zero = Density::zero(Measure::Area);
        let mut p = PathDensity::ONE;
        for k in 1..=5u32 {
            p = p.times(dirac).times(zero);
            assert_eq!((p.zeros(), p.dirac_order(), p.value()), (k, k, 0.0));
        }
        let q = p.times_path(p);
        assert_eq!((q.zeros(), q.dirac_order()), (10, 10));
        for k in (0..5u32).rev() {
            p = p.divided_by(zero).divided_by(dirac);
            assert_eq!((p.zeros(), p.dirac_order()), (k, k));
        }
        assert_eq!(p, PathDensity::ONE);
        let shown = format!("{:?}", PathDensity::ONE.times(dirac).times(zero));
        assert_eq!(shown, "PathDensity { value: 0.5, zeros: 1, dirac: 1 }");
    }

    #[test]
    fn is_finite_agrees_with_the_standard_test() {
        let values = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f64::MIN_POSITIVE,
            f64::MIN_POSITIVE / 4.0,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
            -f64::NAN,
        ];
        for x in values {
            assert_eq!(is_finite(x), x.is_finite(), "{x}");
        }
        for x in [f64::INFINITY, f64::NAN, -1.0, 0.0] {
            assert_eq!(Density::new(x, Measure::Area).value(), 0.0);
        }
        assert_eq!(
            Density::new(f64::MIN_POSITIVE / 4.0, Measure::Area).value(),
            f64::MIN_POSITIVE / 4.0
        );
    }

    #[test]
    fn zeros_divide_out_exactly() {
        let a = Density::new(3.0, Measure::Area);
        let z = Density::zero(Measure::Area);
        let p = PathDensity::ONE.times(a).times(z);
        assert!(p.is_zero());
        let q = p.divided_by(z);
        assert_eq!(q.value(), 3.0);
    }

    #[test]
    fn dirac_dominates_in_ratios() {
        let cont = PathDensity::ONE.times(Density::new(1e9, Measure::Area));
        let dirac = PathDensity::ONE.times(Density::dirac(0.5, Measure::SolidAngle));
        assert_eq!(cont.ratio_to(dirac), f64::INFINITY);
        assert_eq!(dirac.ratio_to(cont), 0.0);
        let dirac2 = PathDensity::ONE.times(Density::dirac(0.25, Measure::SolidAngle));
        assert_eq!(dirac.ratio_to(dirac2), 0.5);
    }

    #[test]
    fn path_mixtures_keep_the_highest_dirac_order() {
        let a = PathDensity::ONE.times(Density::new(2.0, Measure::Area));
        let b = PathDensity::ONE.times(Density::new(3.0, Measure::Area));
        let d = PathDensity::ONE.times(Density::dirac(0.5, Measure::SolidAngle));
        let zero = PathDensity::ONE.times(Density::zero(Measure::Area));
        assert_eq!(a.plus(b).value(), 5.0);
        assert_eq!(a.plus(d), d);
        assert_eq!(zero.plus(a), a);
        assert_eq!(a.plus(zero), a);
    }

    #[test]
    fn mixture_of_dirac_and_continuous() {
        let d = Density::dirac(0.3, Measure::SolidAngle) + Density::new(5.0, Measure::SolidAngle);
        assert!(d.is_dirac());
        assert_eq!(d.value(), 0.3);
    }

    #[test]
    fn non_finite_becomes_zero() {
        assert!(Density::new(f64::NAN, Measure::Area).is_zero());
        assert!(Density::new(f64::INFINITY, Measure::Area).is_zero());
        assert!(Density::new(-1.0, Measure::Area).is_zero());
    }
}
