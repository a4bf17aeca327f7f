//! BSDF sampling written in the language's blocks passes the harness for
//! every material of the scene layer (smooth lobes as atoms with their
//! probabilities, rough lobes against the histogram).

use aether_core::harness::{Check, Grid, SphereDirections, check};
use aether_strategies::bsdf::{Lobes, Transport};
use aether_strategies::scene::{Material, MicrofacetKind, Roughness, Texture};
use glam::Vec3;

fn rough(kind: MicrofacetKind, alpha: f32) -> Option<Roughness> {
    Some(Roughness {
        kind,
        alpha: [alpha, alpha],
    })
}

#[test]
fn every_material_samples_as_its_density_says() {
    let grey = Texture::Constant([0.5; 3]);
    let ior = Some(([0.2, 0.9, 1.1], [3.9, 2.5, 2.1]));
    let materials = [
        (
            "diffuse",
            Material::Diffuse {
                reflectance: grey.clone(),
            },
            1.5,
        ),
        (
            "mirror",
            Material::Conductor {
                ior,
                specular_reflectance: [1.0; 3],
                roughness: None,
            },
            1.5,
        ),
        (
            "rough metal, GGX",
            Material::Conductor {
                ior,
                specular_reflectance: [1.0; 3],
                roughness: rough(MicrofacetKind::Ggx, 0.3),
            },
            1.5,
        ),
        (
            "rough metal, Beckmann",
            Material::Conductor {
                ior,
                specular_reflectance: [1.0; 3],
                roughness: rough(MicrofacetKind::Beckmann, 0.2),
            },
            1.5,
        ),
        (
            "glass, entering",
            Material::Dielectric {
                int_ior: 1.5,
                ext_ior: 1.0,
                roughness: None,
            },
            1.5,
        ),
        (
            "glass, leaving",
            Material::Dielectric {
                int_ior: 1.5,
                ext_ior: 1.0,
                roughness: None,
            },
            1.0 / 1.5,
        ),
        (
            "rough glass, entering",
            Material::Dielectric {
                int_ior: 1.5,
                ext_ior: 1.0,
                roughness: rough(MicrofacetKind::Ggx, 0.3),
            },
            1.5,
        ),
        (
            "rough glass, leaving",
            Material::Dielectric {
                int_ior: 1.5,
                ext_ior: 1.0,
                roughness: rough(MicrofacetKind::Beckmann, 0.25),
            },
            1.0 / 1.5,
        ),
        (
            "plastic",
            Material::Plastic {
                diffuse_reflectance: grey.clone(),
                specular_reflectance: [1.0; 3],
                int_ior: 1.5,
                ext_ior: 1.0,
                roughness: None,
            },
            1.5,
        ),
        (
            "rough plastic",
            Material::Plastic {
                diffuse_reflectance: grey,
                specular_reflectance: [1.0; 3],
                int_ior: 1.5,
                ext_ior: 1.0,
                roughness: rough(MicrofacetKind::Ggx, 0.2),
            },
            1.5,
        ),
    ];
    // Twenty chi-square tests: each at 0.01 / 20 (Bonferroni), so that the
    // whole test fails a correct sampler with probability 0.01.
    let seed = std::env::var("AETHER_TEST_SEED")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(0x5eed);
    let config = Check {
        samples: 100_000,
        significance: 0.01 / 20.0,
        seed,
        ..Check::default()
    };
    for wi in [
        Vec3::new(0.3, 0.1, 0.95).normalize(),
        Vec3::new(-0.8, 0.2, 0.35).normalize(),
    ] {
        for (name, material, eta) in &materials {
            let lobes = Lobes::of(material, wi, *eta, Transport::Radiance);
            let report = check(&lobes, &Grid::new(SphereDirections, 16), &config)
                .unwrap_or_else(|f| panic!("{name} at wi = {wi}: {f}"));
            println!("{name:>24} wi = {wi}: {report}");
            assert!(report.integral > 0.5, "{name}: {report}");
        }
    }
}
