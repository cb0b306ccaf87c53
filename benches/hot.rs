//! Criterion micro-benchmarks of the renderer's hot functions:
//! `cargo bench --bench hot` (quick settings: 20 samples, ~1 s each).
//!
//! Medium look-ups, the majorant (tracker) walk along a ray, shadow-ray
//! transmittance, phase-function sampling, per-path spectral set-up, one
//! camera path (`Integrator::radiance` and `Renderer::sample_pixel`) and the
//! standard-atmosphere state.

use std::hint::black_box;
use std::time::Duration;

use criterion::{criterion_group, criterion_main, Criterion};
use glam::DVec3;
use skyrender::atmosphere::{Atmosphere, AtmosphereParams};
use skyrender::physics::{aerosol, rayleigh, standard_atmosphere};
use skyrender::render::medium::{Bounds, Medium, SpectralLanes, TransmittanceEstimator};
use skyrender::render::{
    direction_from_az_el, Integrator, IntegratorOptions, Renderer, TechniquePlan,
};
use skyrender::rng::Rng;
use skyrender::spectrum::{ColourMatching, Observer};
use skyrender::Scene;

struct Fixture {
    medium: Medium,
    lanes: SpectralLanes,
    ground: DVec3,
}

fn fixture() -> Fixture {
    let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
    let lanes = SpectralLanes::new([450.0, 520.0, 590.0, 660.0], 4, &medium, false);
    let ground = DVec3::new(0.0, 0.0, medium.planet_radius_m + 2.0);
    Fixture {
        medium,
        lanes,
        ground,
    }
}

fn medium_lookups(c: &mut Criterion) {
    let f = fixture();
    let radii: Vec<f64> = (0..64)
        .map(|i| f.medium.planet_radius_m + f64::from(i) * 1_537.0)
        .collect();
    let mut i = 0;
    c.bench_function("medium/coefficients", |b| {
        b.iter(|| {
            i = (i + 1) & 63;
            black_box(f.medium.coefficients(black_box(radii[i]), &f.lanes))
        });
    });
    let mut rng = Rng::new(1, 1);
    for (label, elevation) in [("zenith", 90.0), ("elevation_5deg", 5.0)] {
        let dir = direction_from_az_el(0.0, elevation);
        let span = f.medium.span(f.ground, dir).expect("inside");
        for (bounds_label, bounds) in [("tight", Bounds::Tight), ("global", Bounds::Global)] {
            c.bench_function(
                &format!("medium/tracker_walk/{label}/{bounds_label}"),
                |b| {
                    b.iter(|| {
                        let mut tracker = f.medium.tracker(f.ground, dir, span, &f.lanes, bounds);
                        let mut n = 0u32;
                        while let Some(c) = tracker.next(&mut rng) {
                            n += 1;
                            black_box(c);
                        }
                        n
                    });
                },
            );
        }
    }
    for (label, elevation) in [("sun_45deg", 45.0), ("sun_2deg", 2.0)] {
        let dir = direction_from_az_el(180.0, elevation);
        let origin = DVec3::new(0.0, 0.0, f.medium.planet_radius_m + 1_000.0);
        for (est_label, estimator) in [
            (
                "residual_ratio",
                TransmittanceEstimator::ResidualRatioTracking,
            ),
            ("ratio", TransmittanceEstimator::RatioTracking),
            ("delta", TransmittanceEstimator::DeltaTracking),
        ] {
            c.bench_function(
                &format!("medium/shadow_transmittance/{label}/{est_label}"),
                |b| {
                    b.iter(|| {
                        f.medium.transmittance(
                            black_box(origin),
                            dir,
                            &f.lanes,
                            estimator,
                            Bounds::Tight,
                            &mut rng,
                        )
                    });
                },
            );
        }
    }
}

fn phase_sampling(c: &mut Criterion) {
    let mut rng = Rng::new(2, 2);
    let gamma = rayleigh::phase_gamma(550.0);
    c.bench_function("phase/rayleigh_sample_mu", |b| {
        b.iter(|| rayleigh::sample_mu(rng.uniform(), black_box(gamma)));
    });
    c.bench_function("phase/henyey_greenstein_sample", |b| {
        b.iter(|| aerosol::sample_henyey_greenstein(rng.uniform(), black_box(0.7)));
    });
    c.bench_function("phase/cornette_shanks_sample", |b| {
        b.iter(|| aerosol::PhaseModel::CornetteShanks.sample(black_box(0.7), || rng.uniform()));
    });
}

fn paths(c: &mut Criterion) {
    let f = fixture();
    let plan = TechniquePlan::outside_a_scene(&IntegratorOptions::default());
    let sun = direction_from_az_el(180.0, 45.0);
    let integrator = Integrator::new(&f.medium, &plan, sun);
    let mut rng = Rng::new(3, 3);
    for (label, elevation) in [("zenith", 90.0), ("elevation_5deg", 5.0), ("ground", -30.0)] {
        let dir = direction_from_az_el(90.0, elevation);
        c.bench_function(&format!("path/radiance/{label}"), |b| {
            b.iter(|| integrator.radiance(black_box(f.ground), dir, &f.lanes, &mut rng));
        });
    }
    let cmf = ColourMatching::get(Observer::JuddVos);
    c.bench_function("path/spectral_lanes_new", |b| {
        b.iter(|| {
            let u = rng.uniform();
            let w = std::array::from_fn(|k| cmf.sample_wavelength((u + k as f64 / 4.0).fract()).0);
            SpectralLanes::new(black_box(w), 4, &f.medium, false)
        });
    });
    let mut scene = Scene::preset("midday").expect("preset");
    scene.render.width = 256;
    scene.render.height = 128;
    let renderer = Renderer::new(&scene).expect("scene");
    let pixel_integrator = Integrator::new(&f.medium, renderer.plan(), renderer.sun_direction());
    let mut sample = 0u64;
    c.bench_function("path/sample_pixel/midday_256x128_row_40", |b| {
        b.iter(|| {
            sample = sample.wrapping_add(1);
            renderer.sample_pixel(&pixel_integrator, black_box(100), 40, sample)
        });
    });
}

fn physics(c: &mut Criterion) {
    let mut h = 0.0;
    c.bench_function("physics/air_state", |b| {
        b.iter(|| {
            h = (h + 777.0) % 86_000.0;
            standard_atmosphere::air_state(black_box(h))
        });
    });
}

criterion_group! {
    name = hot;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    targets = medium_lookups, phase_sampling, paths, physics
}
criterion_main!(hot);
