//! Fresnel reflectance of dielectric and conductor interfaces.

use glam::{DVec3, Vec3};

/// Unpolarised Fresnel reflectance of a dielectric interface; `cos_i` on
/// the side `eta` = η_other / η_this is relative to. Total internal
/// reflection gives 1.
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(-1.0, 1.0).abs();
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Fresnel reflectance of a conductor with complex index η + ik, per channel.
#[must_use]
pub fn fresnel_conductor(cos_i: f32, eta: Vec3, k: Vec3) -> Vec3 {
    let c = f64::from(cos_i.clamp(0.0, 1.0));
    let (eta, k) = (eta.as_dvec3(), k.as_dvec3());
    let c2 = c * c;
    let s2 = 1.0 - c2;
    let t0 = eta * eta - k * k - DVec3::splat(s2);
    let a2b2 = (t0 * t0 + 4.0 * eta * eta * k * k).map(f64::sqrt);
    let a = (0.5 * (a2b2 + t0)).map(|x| x.max(0.0).sqrt());
    let t1 = a2b2 + DVec3::splat(c2);
    let t2 = 2.0 * c * a;
    let rs = (t1 - t2) / (t1 + t2);
    let t3 = c2 * a2b2 + DVec3::splat(s2 * s2);
    let t4 = t2 * s2;
    let rp = rs * (t3 - t4) / (t3 + t4);
    (0.5 * (rp + rs)).as_vec3()
}

/// Hemispherical average of the dielectric Fresnel reflectance,
/// 2 ∫₀¹ F(μ, η) μ dμ: the fraction of diffuse light an interface of
/// relative index `eta` reflects (Mitsuba's `fresnelDiffuseReflectance`).
///
/// Beyond the critical angle F = 1 and the integral is exact; the rest is
/// integrated by the midpoint rule, which converges fast on that smooth part.
#[must_use]
pub fn fresnel_diffuse_reflectance(eta: f32) -> f32 {
    let eta = f64::from(eta);
    // Below μ_c (internal reflection, η < 1) every direction reflects.
    let mu_c = if eta < 1.0 {
        (1.0 - eta * eta).sqrt()
    } else {
        0.0
    };
    const N: usize = 512;
    let h = (1.0 - mu_c) / N as f64;
    let smooth: f64 = (0..N)
        .map(|i| {
            let mu = mu_c + (i as f64 + 0.5) * h;
            f64::from(fresnel_dielectric(mu as f32, eta as f32)) * mu * h
        })
        .sum();
    (mu_c * mu_c + 2.0 * smooth) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn diffuse_reflectance_of_glass() {
        // The external average of glass is about 0.092, the internal one
        // 1 − (1 − 0.092) / η² ≈ 0.596 (energy balance across the interface).
        let ext = fresnel_diffuse_reflectance(1.5);
        let int = fresnel_diffuse_reflectance(1.0 / 1.5);
        assert!((ext - 0.092).abs() < 2e-3, "{ext}");
        assert!((int - (1.0 - (1.0 - ext) / 2.25)).abs() < 2e-3, "{int}");
    }

    #[test]
    fn fresnel_limits() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-4);
        assert_eq!(fresnel_dielectric(0.1, 1.0 / 1.5), 1.0);
        assert!(fresnel_dielectric(0.0, 1.5) > 0.99);
        // A conductor with k = 0 is a dielectric.
        let c = fresnel_conductor(0.7, Vec3::splat(1.5), Vec3::ZERO);
        assert!((c.x - fresnel_dielectric(0.7, 1.5)).abs() < 1e-5);
        // Aluminium reflects most light at normal incidence.
        let al = fresnel_conductor(
            1.0,
            Vec3::new(1.6575, 0.880405, 0.521244),
            Vec3::new(9.22381, 6.2695, 4.837),
        );
        assert!(al.min_element() > 0.85, "{al}");
    }
}
