//! The circle splatter's tests: its frame and arcs, the positions' and
//! points' densities, the positions' control and counts.

use super::*;
use crate::atmosphere::{Atmosphere, AtmosphereParams};
use crate::render::circle_geometry::{splats_per_walk, PHASE_CELLS, PHASE_FLOOR};
use crate::render::direction_from_az_el;
use crate::render::guide::SkyGuide;

/// Phase-drawn positions at the base count.
const PHASE_SPLATS: usize = SPLATS_PER_WALK - FIRST_SPLATS;

fn axis_for(sun_elevation_deg: f64) -> SunAxis {
    let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
    let observer = DVec3::new(0.0, 0.0, medium.planet_radius_m + 2.0);
    SunAxis::new(
        observer,
        direction_from_az_el(30.0, sun_elevation_deg),
        medium.planet_radius_m,
        medium.top_radius_m,
    )
    .unwrap()
}

#[test]
fn the_axis_frame_places_the_observer_and_turns_about_the_sun() {
    let axis = axis_for(-4.0);
    let at_observer = axis.point(axis.r0_m, axis.theta0, 0.0);
    assert!((at_observer - axis.observer_m).length() < 1e-6);
    let v = DVec3::new(0.3, -0.5, 0.8).normalize();
    let turned = axis.rotate(v, 0.7);
    assert!((turned.dot(axis.sun) - v.dot(axis.sun)).abs() < 1e-12);
    assert!((turned.length() - 1.0).abs() < 1e-12);
    assert!((axis.rotate(turned, -0.7) - v).length() < 1e-12);
    // point(r, θ, ψ) is point(r, θ, 0) turned by ψ.
    let p = axis.point(axis.r0_m + 3e3, 1.5, 0.0);
    assert!((axis.rotate(p, 0.2) - axis.point(axis.r0_m + 3e3, 1.5, 0.2)).length() < 1e-6);
    // A circle's positions, one sine and cosine each, are the point and
    // the turn back to the bit (sin(−ψ) = −sin ψ): the splats, and so
    // the pinned images, do not depend on which form places them.
    let circle = axis.circle(axis.r0_m + 3e3, 1.5);
    for psi in [-2.9, -0.7, -1e-3, 0.0, 2e-4, 0.2, 1.1, 3.1] {
        let to = axis.point(axis.r0_m + 3e3, 1.5, psi) - axis.observer_m;
        let (placed, back) = circle.place(psi);
        assert_eq!(placed, to, "ψ {psi}");
        assert_eq!(back, axis.rotate(to.normalize(), -psi), "ψ {psi}");
    }
}

#[test]
fn the_visible_arc_is_where_the_ground_does_not_hide_the_circle() {
    // Brute force over ψ: a point is visible iff the segment from the
    // observer misses the planet.
    let axis = axis_for(-4.0);
    let hidden = |y: DVec3| {
        let o = axis.observer_m;
        let d = y - o;
        let s = (-o.dot(d) / d.length_squared()).clamp(0.0, 1.0);
        (o + d * s).length() < axis.ground_m - 1e-3
    };
    let mut rng = Rng::new(3, 0);
    for _ in 0..300 {
        let r = axis.ground_m + rng.uniform() * (axis.top_m - axis.ground_m);
        let theta = axis.theta0 + (rng.uniform() - 0.5) * 0.4;
        let half = axis.half_arc(r, theta);
        for k in 0..200 {
            let psi = -PI + (f64::from(k) + 0.5) / 200.0 * 2.0 * PI;
            let visible = !hidden(axis.point(r, theta, psi));
            // Away from the arc's ends (the brute force's own rounding).
            if (psi.abs() - half).abs() > 1e-6 {
                assert_eq!(
                    visible,
                    psi.abs() < half,
                    "r {r} θ {theta} ψ {psi} half {half}"
                );
            }
        }
    }
}

#[test]
fn arc_positions_integrate_by_their_density() {
    // Σ f(ψ_k)/density(ψ_k) over both rounds of positions is an unbiased
    // estimate of ∫ f over the arc for any f: with f = 1, the 1/t² shape
    // and a smooth one, averaged over both rounds' stratification
    // offsets, for even cell weights, a peaked set (one cell 1000×
    // the rest) and a zero one (all floor), at the fewest and the most
    // positions a walk takes.
    let (half, scale) = (0.3, 2e-4);
    let arc = Arc::new(half, scale);
    let mut peaked = [1.0; PHASE_CELLS];
    peaked[PHASE_CELLS / 3] = 1000.0;
    let cell_sets = [[1.0; PHASE_CELLS], peaked, [0.0; PHASE_CELLS]];
    for f in [
        (|_: f64| 1.0) as fn(f64) -> f64,
        |psi: f64| 2e-4 / (4e-8 + psi * psi),
        |psi: f64| psi.cos() * (1.0 + psi),
    ] {
        let exact = {
            let n = 2_000_000u32;
            (0..n)
                .map(|i| {
                    let psi = -half + (f64::from(i) + 0.5) / f64::from(n) * 2.0 * half;
                    f(psi)
                })
                .sum::<f64>()
                * 2.0
                * half
                / f64::from(n)
        };
        for (weights, phase_splats) in cell_sets
            .into_iter()
            .flat_map(|w| [(w, PHASE_SPLATS), (w, MAX_SPLATS_PER_WALK - FIRST_SPLATS)])
        {
            let cells = PhaseCells::new(weights);
            let trials = 400u32;
            let mut sum = 0.0;
            for i in 0..trials {
                for j in 0..trials {
                    let u = (f64::from(i) + 0.5) / f64::from(trials);
                    let v = (f64::from(j) + 0.5) / f64::from(trials);
                    let first = arc.first_positions(u);
                    sum += first
                        .iter()
                        .copied()
                        .chain(cells.positions(&arc, v, phase_splats))
                        .map(|psi| f(psi) / arc.density(psi, &cells, phase_splats))
                        .sum::<f64>();
                }
            }
            let estimate = sum / f64::from(trials * trials);
            assert!(
                (estimate / exact - 1.0).abs() < 2e-3,
                "{estimate} against {exact} (cells {:?}, {phase_splats})",
                &weights[..4]
            );
        }
    }
}

#[test]
fn the_positions_control_keeps_each_walks_expectation() {
    // The splats of many sunset walks summed (luminance-like: lane
    // weights 1): one position in six exact and the rest from the
    // cells' control reads as every position exact, and so does a
    // control 2.5 times too bright, which the exact positions must
    // correct (with the correction's weight 1 instead of 6 its mean
    // would read about 2.25 times the truth). Within 4 standard errors.
    let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
    let sun = direction_from_az_el(30.0, 2.0);
    let plan = crate::plan::TechniquePlan::new(
        &crate::plan::IntegratorOptions::default(),
        &crate::plan::Conditions::new(2.0, &AtmosphereParams::default(), true),
    );
    let guide = SkyGuide::new(&medium, sun);
    let integrator = Integrator::new(&medium, &plan, sun).with_sky_guide(&guide);
    let camera = Camera::new(&crate::scene::CameraParams::default(), 64, 32);
    let observer = DVec3::new(0.0, 0.0, medium.planet_radius_m + 2.0);
    let lanes = SpectralLanes::new(Lanes::from([450.0, 520.0, 590.0, 660.0]), 4, &medium, true);
    let weights = [[1.0; 3]; LANES];
    let learned = LearnedPoints::default();
    let totals = |every: usize, scale: f64, seed: u64| {
        let splatter = CircleSplatter::new(&medium, &integrator, Some(&guide), &camera, observer)
            .unwrap()
            .with_control(every, scale);
        let mut out = Vec::new();
        let values: Vec<f64> = (0..20_000u64)
            .map(|walk| {
                let mut rng = Rng::new(seed, walk);
                out.clear();
                splatter.walk(
                    &integrator,
                    &camera,
                    &lanes,
                    &weights,
                    &learned,
                    &mut rng,
                    &mut out,
                );
                out.iter().map(|s| s.xyz[1]).sum()
            })
            .collect();
        let n = values.len() as f64;
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0);
        (mean, (var / n).sqrt())
    };
    let (exact, exact_se) = totals(1, 1.0, 3);
    assert!(exact > 0.0);
    for (every, scale, seed) in [(6, 1.0, 5), (6, 2.5, 7)] {
        let (mean, se) = totals(every, scale, seed);
        let z = (mean - exact) / exact_se.hypot(se);
        assert!(
            z.abs() < 4.0,
            "every {every}, control × {scale}: {mean} ± {se} against {exact} ± {exact_se}"
        );
    }
}

#[test]
fn the_airs_positions_are_a_third_more_up_to_the_most() {
    let equirect = crate::scene::CameraParams::default();
    let count = |w: u32, h: u32| air_splats_per_walk(&Camera::new(&equirect, w, h));
    assert_eq!(count(256, 128), 128);
    assert_eq!(count(512, 256), 184);
    assert_eq!(count(1024, 512), MAX_SPLATS_PER_WALK);
}

#[test]
fn positions_grow_with_the_images_resolution() {
    // 96 at the bench's 256×128 map, × √2 per doubling of the pixels
    // per radian, up to 192 from 1024×512; a 90° perspective view 160
    // pixels wide has 80 per radian at its centre (an equirect map 503
    // wide), 1024 wide 512 (the most).
    let equirect = crate::scene::CameraParams::default();
    let count = |params: &crate::scene::CameraParams, w: u32, h: u32| {
        splats_per_walk(&Camera::new(params, w, h))
    };
    assert_eq!(count(&equirect, 256, 128), SPLATS_PER_WALK);
    assert_eq!(count(&equirect, 128, 64), SPLATS_PER_WALK);
    assert_eq!(count(&equirect, 512, 256), 136);
    assert_eq!(count(&equirect, 1024, 512), MAX_SPLATS_PER_WALK);
    assert_eq!(count(&equirect, 4096, 2048), MAX_SPLATS_PER_WALK);
    let perspective = crate::scene::CameraParams {
        kind: crate::scene::CameraKind::Perspective,
        ..equirect
    };
    assert_eq!(count(&perspective, 1024, 576), MAX_SPLATS_PER_WALK);
    assert_eq!(count(&perspective, 160, 90), 136);
}

#[test]
fn phase_cells_draw_by_their_weights() {
    // The second round's positions fall in each cell in proportion to
    // its probability: over offsets u on a grid of 1000, within two
    // per stratum (the grid's rounding at the cell's edges).
    let arc = Arc::new(0.5, 1e-3);
    let mut weights = [0.0; PHASE_CELLS];
    for (m, w) in weights.iter_mut().enumerate() {
        *w = (m as f64 * 0.7).sin().abs();
    }
    let cells = PhaseCells::new(weights);
    assert!((cells.probabilities.iter().sum::<f64>() - 1.0).abs() < 1e-12);
    let trials = 1000;
    let mut counts = [0usize; PHASE_CELLS];
    for i in 0..trials {
        let u = (f64::from(i) + 0.5) / f64::from(trials);
        for psi in cells.positions(&arc, u, PHASE_SPLATS) {
            let m = (arc.quantile(psi) * PHASE_CELLS as f64) as usize;
            counts[m.min(PHASE_CELLS - 1)] += 1;
        }
    }
    for (m, (&count, p)) in counts.iter().zip(cells.probabilities).enumerate() {
        let expected = p * (PHASE_SPLATS * trials as usize) as f64;
        assert!(
            (count as f64 - expected).abs() <= 2.0 * PHASE_SPLATS as f64,
            "cell {m}: {count} against {expected}"
        );
    }
    // The floor: no cell below PHASE_FLOOR / PHASE_CELLS.
    assert!(cells
        .probabilities
        .iter()
        .all(|&p| p >= PHASE_FLOOR / PHASE_CELLS as f64 - 1e-15));
}

#[test]
fn points_follow_their_density() {
    // E[g/p] = ∫ g over the (ρ, φ) plane for the points a twilight
    // splatter draws (table and analytic parts), with g smooth and
    // lopsided in φ, before and after learning (three lopsided
    // cells' moments, one of them far out); and for the analytic
    // sampler alone.
    let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
    let sun = direction_from_az_el(30.0, -4.0);
    let plan = crate::plan::TechniquePlan::new(
        &crate::plan::IntegratorOptions::default(),
        &crate::plan::Conditions::new(-4.0, &AtmosphereParams::default(), true),
    );
    let guide = SkyGuide::new(&medium, sun);
    let integrator = Integrator::new(&medium, &plan, sun).with_sky_guide(&guide);
    let camera = Camera::new(&crate::scene::CameraParams::default(), 64, 32);
    let observer = DVec3::new(0.0, 0.0, medium.planet_radius_m + 2.0);
    let splatter =
        CircleSplatter::new(&medium, &integrator, Some(&guide), &camera, observer).unwrap();
    assert!(!splatter.bins.is_empty());
    let rho_max = splatter.rho_max_m;
    let scale = 50e3;
    let g = |rho: f64, phi: f64| {
        if rho < rho_max {
            (-rho / scale).exp() * (1.5 + phi.cos())
        } else {
            0.0
        }
    };
    let exact = 2.0 * PI * 1.5 * scale * (1.0 - (-rho_max / scale).exp());
    let prior = LearnedPoints::default();
    let mut learned = LearnedPoints::default();
    learned.add_moments([(5, 1.0), (100, 50.0), (CELLS - 3, 3.0)]);
    splatter.learn(&mut learned);
    assert!(learned.is_learned() && !prior.is_learned());
    // The learned part holds its cells' bins only, with √(S P) mass.
    let total: f64 = learned.bins.iter().sum();
    assert!((total - 1.0).abs() < 1e-12, "{total}");
    let mass = |cell: usize| -> f64 {
        (0..learned.bins.len())
            .filter(|&b| CircleSplatter::cell(b) == cell)
            .map(|b| learned.bins[b])
            .sum()
    };
    assert_eq!(mass(6), 0.0);
    let prior_mass = |cell: usize| -> f64 {
        (0..splatter.prior_bins.len())
            .filter(|&b| CircleSplatter::cell(b) == cell)
            .map(|b| splatter.prior_bins[b])
            .sum()
    };
    let ratio = mass(100) / mass(5);
    let expected = (50.0 * prior_mass(100) / prior_mass(5)).sqrt();
    assert!(
        (ratio / expected - 1.0).abs() < 1e-9,
        "{ratio} vs {expected}"
    );
    let mut rng = Rng::new(17, 0);
    let n = 400_000u32;
    // And a g that lives only in the wedge below the observer's height
    // (2 m), where the table's bins hold nothing: the air in front of
    // the ground and along the horizon's grazing rays.
    let height = splatter.axis.r0_m - splatter.axis.ground_m;
    let in_wedge = |rho: f64, phi: f64| {
        let dr = rho * phi.sin();
        (-height..=0.0).contains(&dr)
    };
    let g_wedge = |rho: f64, phi: f64| {
        if (50.0..20e3).contains(&rho) && in_wedge(rho, phi) {
            1.0 + 0.5 * phi.cos()
        } else {
            0.0
        }
    };
    // ∫ over both wedges of (1 + ½ cos φ) dφ dρ, 50 m < ρ < 20 km, by
    // quadrature: the cosine's integrals over [π, π + β] and
    // [2π − β, 2π] are −sin β and +sin β and cancel, leaving ∫ 2β dρ.
    let steps = 200_000u32;
    let exact_wedge: f64 = (0..steps)
        .map(|k| {
            let rho = 50.0 + (f64::from(k) + 0.5) / f64::from(steps) * (20e3 - 50.0);
            2.0 * (height / rho).min(1.0).asin()
        })
        .sum::<f64>()
        * (20e3 - 50.0)
        / f64::from(steps);
    // E[g/p] over `count` points of `density`, and its standard error.
    let mut estimate = |density: &LearnedPoints, g: &dyn Fn(f64, f64) -> f64, count: u32| {
        let (mut sum, mut sum2) = (0.0, 0.0);
        for _ in 0..count {
            let (rho, phi) = splatter.sample_polar(density, &mut rng);
            let v = g(rho, phi) / splatter.polar_densities(density, rho, phi).drawn;
            sum += v;
            sum2 += v * v;
        }
        let mean = sum / f64::from(count);
        (
            mean,
            ((sum2 / f64::from(count) - mean * mean) / f64::from(count)).sqrt(),
        )
    };
    for density in [&prior, &learned] {
        // Few points fall in the wedge (under 1 % of the learned
        // density's): ten times as many.
        let (mean, se) = estimate(density, &g_wedge, 10 * n);
        assert!(
            (mean - exact_wedge).abs() < 4.0 * se,
            "wedge: {mean} against {exact_wedge} (SE {se})"
        );
        assert!(se < 0.04 * exact_wedge, "wedge: SE {se}");
        let (mean, se) = estimate(density, &g, n);
        assert!(
            (mean - exact).abs() < 4.0 * se,
            "{mean} against {exact} (SE {se})"
        );
        assert!(se < 0.02 * exact, "SE {se}");
    }
    // The analytic part alone: ∫ 1 dρ over [0, ρ_max].
    let mut sum = 0.0;
    for _ in 0..n {
        let rho = sample_analytic_rho(rng.uniform(), rng.uniform(), rho_max);
        if rho < rho_max {
            sum += 1.0 / analytic_rho_density(rho, rho_max);
        }
    }
    let mean = sum / f64::from(n);
    assert!(
        (mean / rho_max - 1.0).abs() < 0.02,
        "{mean} against {rho_max}"
    );
}
