//! Spectra to linear sRGB, as Mitsuba 3's RGB modes convert the spectra of
//! a scene: emission by the CIE 1931 curves, reflectance white-balanced
//! under D65 (a reflectance of one everywhere is white), negative
//! components clamped.

use colorbox::tables::cie_1931_xyz;
use colr_types::illuminant::D65;

use crate::scene::xml::SpectrumValue;

/// XYZ → linear sRGB (ITU-R BT.709 primaries, D65 white), the matrix
/// Mitsuba uses.
const XYZ_TO_RGB: [[f64; 3]; 3] = [
    [3.240479, -1.537150, -0.498535],
    [-0.969256, 1.875991, 0.041556],
    [0.055648, -0.204043, 1.057311],
];

/// The luminance Y of a linear sRGB colour (Rec. 709 weights): the one
/// scalar that light power, environment-map importance and bump heights use.
#[must_use]
pub fn luminance(rgb: [f32; 3]) -> f64 {
    0.2126 * f64::from(rgb[0]) + 0.7152 * f64::from(rgb[1]) + 0.0722 * f64::from(rgb[2])
}

/// The value of a piecewise-linear spectrum at `lambda`; zero outside the
/// wavelengths it names (as Mitsuba's interpolated spectrum).
fn interpolate(samples: &[(f64, f64)], lambda: f64) -> f64 {
    let (Some(first), Some(last)) = (samples.first(), samples.last()) else {
        return 0.0;
    };
    if lambda < first.0 || lambda > last.0 {
        return 0.0;
    }
    let i = samples.partition_point(|s| s.0 < lambda);
    if samples[i].0 == lambda {
        return samples[i].1;
    }
    let (a, b) = (samples[i - 1], samples[i]);
    a.1 + (lambda - a.0) / (b.0 - a.0) * (b.1 - a.1)
}

/// The colour-matching functions at `lambda`, interpolated linearly in
/// the 5 nm tables.
fn cmf(lambda: f64) -> [f64; 3] {
    let (lo, hi) = (
        f64::from(cie_1931_xyz::MIN_WAVELENGTH),
        f64::from(cie_1931_xyz::MAX_WAVELENGTH),
    );
    let n = cie_1931_xyz::Y.len();
    let pos = (lambda - lo) / (hi - lo) * (n - 1) as f64;
    let i = (pos.floor() as usize).min(n - 2);
    let t = pos - i as f64;
    [cie_1931_xyz::X, cie_1931_xyz::Y, cie_1931_xyz::Z]
        .map(|c| f64::from(c[i]) * (1.0 - t) + f64::from(c[i + 1]) * t)
}

/// What a spectrum describes, which decides its white point.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpectrumKind {
    /// Emitted radiance: weighed by the colour-matching functions alone.
    Emission,
    /// A reflectance or other unitless albedo: weighed under D65.
    Reflectance,
}

/// The D65 spectral power at `lambda` (relative, 1 at 560 nm), zero
/// outside the 380–780 nm of the table.
fn d65(lambda: f64) -> f64 {
    let table = D65::<colr_types::observer::Cie1931>::SPD_5NM;
    let pos = (lambda - 380.0) / 5.0;
    if !(0.0..=(table.len() - 1) as f64).contains(&pos) {
        return 0.0;
    }
    let i = (pos.floor() as usize).min(table.len() - 2);
    let t = pos - i as f64;
    f64::from(table[i]) * (1.0 - t) + f64::from(table[i + 1]) * t
}

/// CIE 1931 XYZ of a sampled spectrum, evaluated at every nanometre from
/// 360 to 830 nm and normalised so that a spectrum of one everywhere has
/// Y = 1 (under D65 for reflectances).
#[must_use]
pub fn xyz(samples: &[(f64, f64)], kind: SpectrumKind) -> [f64; 3] {
    let (lo, hi) = (
        cie_1931_xyz::MIN_WAVELENGTH as i32,
        cie_1931_xyz::MAX_WAVELENGTH as i32,
    );
    let (mut sum, mut y_sum) = ([0.0; 3], 0.0);
    for lambda in lo..=hi {
        let l = f64::from(lambda);
        let weight = match kind {
            SpectrumKind::Emission => 1.0,
            SpectrumKind::Reflectance => d65(l),
        };
        let c = cmf(l);
        let v = interpolate(samples, l) * weight;
        for k in 0..3 {
            sum[k] += c[k] * v;
        }
        y_sum += c[1] * weight;
    }
    sum.map(|s| s / y_sum)
}

/// Linear sRGB of a spectrum value: constants and RGB triples as they are,
/// sampled spectra through CIE 1931 XYZ, negative components clamped.
#[must_use]
pub fn to_linear_rgb(value: &SpectrumValue, kind: SpectrumKind) -> [f64; 3] {
    match value {
        SpectrumValue::Constant(c) => [*c; 3],
        SpectrumValue::Rgb(rgb) => *rgb,
        SpectrumValue::Sampled(samples) => {
            let v = xyz(samples, kind);
            XYZ_TO_RGB.map(|row| (row[0] * v[0] + row[1] * v[1] + row[2] * v[2]).max(0.0))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flat_spectrum_has_unit_luminance() {
        let flat = SpectrumValue::Sampled(vec![(360.0, 1.0), (830.0, 1.0)]);
        let [r, g, b] = to_linear_rgb(&flat, SpectrumKind::Emission);
        let luminance = 0.212671 * r + 0.715160 * g + 0.072169 * b;
        assert!((luminance - 1.0).abs() < 1e-4, "{luminance}");
        // Equal-energy white is slightly red against sRGB's D65 white.
        assert!(r > g && r > b, "{r} {g} {b}");
    }

    #[test]
    fn interpolation_is_linear_and_zero_outside() {
        let s = [(400.0, 0.0), (500.0, 8.0), (600.0, 15.6)];
        assert_eq!(interpolate(&s, 450.0), 4.0);
        assert_eq!(interpolate(&s, 500.0), 8.0);
        assert_eq!(interpolate(&s, 399.0), 0.0);
        assert_eq!(interpolate(&s, 601.0), 0.0);
    }

    /// Values that Mitsuba 3.9.1 (`scalar_rgb`) gives for the same spectra
    /// in a version 0.5 scene, measured with its Python module.
    #[test]
    fn agrees_with_mitsuba() {
        let light = SpectrumValue::Sampled(vec![
            (400.0, 0.0),
            (500.0, 8.0),
            (600.0, 15.6),
            (700.0, 18.4),
        ]);
        let red = SpectrumValue::Sampled(vec![
            (400.0, 0.04),
            (500.0, 0.058),
            (600.0, 0.287),
            (700.0, 0.642),
        ]);
        let half = SpectrumValue::Sampled(vec![(360.0, 0.5), (830.0, 0.5)]);
        let cases = [
            (light, SpectrumKind::Emission, [20.7108, 10.8546, 2.77115]),
            (
                red,
                SpectrumKind::Reflectance,
                [0.41467, 0.146241, 0.0317781],
            ),
            (
                half.clone(),
                SpectrumKind::Reflectance,
                [0.499493, 0.499437, 0.499401],
            ),
            (half, SpectrumKind::Emission, [0.602442, 0.474114, 0.454633]),
        ];
        for (value, kind, mitsuba) in cases {
            let rgb = to_linear_rgb(&value, kind);
            for (a, b) in rgb.iter().zip(mitsuba) {
                // Within 0.3 %: the D65 table here spans 380–780 nm, Mitsuba's 360–830 nm.
                assert!(
                    (a - b).abs() <= 3e-3 * b.abs().max(0.01),
                    "{rgb:?} against Mitsuba's {mitsuba:?}"
                );
            }
        }
    }
}
