//! Microfacet normal distributions and Smith shadowing for BSDF values
//! (their sampling lives in the language's primitives).

use std::f32::consts::PI;

use glam::Vec3;

use crate::scene::{MicrofacetKind, Roughness};

/// The distribution of normals D(m) of a rough surface, per unit projected
/// area, for a local microfacet normal `m` (z > 0).
#[must_use]
pub fn normal_density(r: Roughness, m: Vec3) -> f32 {
    if m.z <= 0.0 {
        return 0.0;
    }
    let [ax, ay] = r.alpha;
    let cos2 = m.z * m.z;
    // tan²θ (cos²φ/αx² + sin²φ/αy²), without forming φ.
    let e = (m.x * m.x / (ax * ax) + m.y * m.y / (ay * ay)) / cos2;
    let d = match r.kind {
        MicrofacetKind::Ggx => 1.0 / (PI * ax * ay * cos2 * cos2 * (1.0 + e) * (1.0 + e)),
        MicrofacetKind::Beckmann => (-e).exp() / (PI * ax * ay * cos2 * cos2),
    };
    if d.is_finite() { d } else { 0.0 }
}

/// Smith's masking G₁(w, m): the fraction of facets with normal `m` seen
/// from `w` (separable form, as Mitsuba uses).
#[must_use]
pub fn smith_g1(r: Roughness, w: Vec3, m: Vec3) -> f32 {
    // A facet seen from its back, or a direction on the other side of the
    // macro-surface than of the facet, is masked.
    if w.dot(m) * w.z <= 0.0 {
        return 0.0;
    }
    let xy2 = w.x * w.x + w.y * w.y;
    if xy2 == 0.0 {
        return 1.0;
    }
    let [ax, ay] = r.alpha;
    // α along w's azimuth, times tan θ.
    let alpha_tan2 = (w.x * w.x * ax * ax + w.y * w.y * ay * ay) / (w.z * w.z);
    match r.kind {
        MicrofacetKind::Ggx => 2.0 / (1.0 + (1.0 + alpha_tan2).sqrt()),
        MicrofacetKind::Beckmann => {
            let a = 1.0 / alpha_tan2.sqrt();
            if a >= 1.6 {
                1.0
            } else {
                // Walter et al.'s rational fit of the exact erf expression.
                (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
            }
        }
    }
}

/// The bidirectional shadowing-masking G(wi, wo, m) = G₁(wi) G₁(wo).
#[must_use]
pub fn shadowing(r: Roughness, wi: Vec3, wo: Vec3, m: Vec3) -> f32 {
    smith_g1(r, wi, m) * smith_g1(r, wo, m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// ∫ D(m) cos θ_m dm = 1: the projected facet area is the macro area.
    #[test]
    fn normals_cover_the_surface() {
        for kind in [MicrofacetKind::Ggx, MicrofacetKind::Beckmann] {
            for alpha in [[0.1, 0.1], [0.3, 0.6], [0.8, 0.2]] {
                let rough = Roughness { kind, alpha };
                // z = 1 − s² resolves the narrow peak at the pole.
                let (ns, nphi) = (2000, 96);
                let (ds, dphi) = (1.0 / ns as f64, std::f64::consts::TAU / nphi as f64);
                let mut integral = 0.0f64;
                for i in 0..ns {
                    let s = (i as f64 + 0.5) * ds;
                    let z = 1.0 - s * s;
                    let r = (1.0 - z * z).max(0.0).sqrt();
                    for j in 0..nphi {
                        let phi = (j as f64 + 0.5) * dphi;
                        let m = Vec3::new((r * phi.cos()) as f32, (r * phi.sin()) as f32, z as f32);
                        integral += f64::from(normal_density(rough, m)) * z * 2.0 * s * ds * dphi;
                    }
                }
                assert!(
                    (integral - 1.0).abs() < 5e-3,
                    "{kind:?} {alpha:?}: {integral}"
                );
            }
        }
    }
}
