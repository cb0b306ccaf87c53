//! Aerosols by their optical properties (`[atmosphere.aerosol]`, `--aod550`,
//! `--angstrom`): the optical depths they give, a tabulated phase function
//! against the analytic one it tabulates, and bad input.

mod common;

use std::f64::consts::PI;
use std::path::{Path, PathBuf};

use common::{assert_one_line_error, render_small, skyrender};
use skyrender::physics::aerosol::henyey_greenstein;
use skyrender::render::Renderer;
use skyrender::Scene;

/// The `atmosphere --json` report for `args`.
fn atmosphere_json(args: &[&str]) -> serde_json::Value {
    let mut all = vec!["atmosphere", "--json"];
    all.extend_from_slice(args);
    let out = skyrender(&all);
    assert!(out.status.success(), "{}", common::stderr(&out));
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn aod_and_angstrom_exponent_give_the_optical_depths_of_the_power_law() {
    // τ(λ) = τ₅₅₀ (λ/550)^−α over the whole column from sea level.
    let (tau_550, alpha) = (0.12, 1.3);
    for (nm, expected) in [
        ("550", tau_550),
        ("440", tau_550 * (440.0_f64 / 550.0).powf(-alpha)),
        ("1020", tau_550 * (1020.0_f64 / 550.0).powf(-alpha)),
    ] {
        let v = atmosphere_json(&[
            "--altitude",
            "0",
            "--wavelength",
            nm,
            "--aod550",
            "0.12",
            "--angstrom",
            "1.3",
        ]);
        let tau = v["optical_depth"]["aerosol"].as_f64().unwrap();
        // The report integrates the profile numerically (Simpson, < 1e-5).
        assert!(
            (tau / expected - 1.0).abs() < 1e-5,
            "{nm} nm: {tau} vs {expected}"
        );
    }
    // The same by an exponential profile, in a scene file.
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("haze.toml");
    std::fs::write(
        &scene,
        "[atmosphere.aerosol]\noptical_depth_550 = 0.12\nangstrom_exponent = 1.3\n\
         profile = \"exponential\"\nscale_height_m = 1200.0\n",
    )
    .unwrap();
    let scene = scene.to_str().unwrap();
    let v = atmosphere_json(&["--scene", scene, "--altitude", "0", "--wavelength", "440"]);
    let tau = v["optical_depth"]["aerosol"].as_f64().unwrap();
    let expected = tau_550 * (440.0_f64 / 550.0).powf(-alpha);
    assert!((tau / expected - 1.0).abs() < 1e-5, "{tau} vs {expected}");
    // At one scale height, e⁻¹ of the column lies above.
    let v = atmosphere_json(&[
        "--scene",
        scene,
        "--altitude",
        "1200",
        "--wavelength",
        "550",
    ]);
    let tau = v["optical_depth"]["aerosol"].as_f64().unwrap();
    assert!(
        (tau / (tau_550 / std::f64::consts::E) - 1.0).abs() < 1e-4,
        "{tau}"
    );
    // --aerosol-amount keeps its meaning: amount 1 is Elterman's 0.249.
    let v = atmosphere_json(&["--altitude", "0", "--aerosol-amount", "1"]);
    let tau = v["optical_depth"]["aerosol"].as_f64().unwrap();
    assert!((tau - 0.249).abs() < 0.001, "{tau}");
}

#[test]
fn the_two_ways_to_set_the_amount_are_not_both_given() {
    let out = skyrender(&["atmosphere", "--aerosol-amount", "2", "--aod550", "0.1"]);
    assert_one_line_error(&out, &["--aerosol-amount", "--aod550", "give one"]);
    let out = skyrender(&["atmosphere", "--aod550", "-0.1"]);
    assert_one_line_error(&out, &["optical_depth_550", "0 to 25"]);
    let out = skyrender(&["atmosphere", "--angstrom", "4.5"]);
    assert_one_line_error(&out, &["angstrom_exponent", "-1 to 4", "Rayleigh"]);
    let out = skyrender(&["atmosphere", "--angstrom", "NaN"]);
    assert_one_line_error(&out, &["angstrom_exponent"]);
    // In a scene, the flat key and the one replacing it are not both set.
    let e = Scene::from_toml(
        "[atmosphere]\naerosol_amount = 2.0\n[atmosphere.aerosol]\noptical_depth_550 = 0.1",
    )
    .unwrap_err();
    assert!(e.to_string().contains("aerosol_amount"), "{e}");
}

/// Writes `rows` as a phase function file `name` in `dir`.
fn write_table(dir: &Path, name: &str, rows: &[(f64, f64)]) -> PathBuf {
    use std::fmt::Write as _;
    let mut text = String::from("angle_deg,phase\n");
    for (angle, phase) in rows {
        writeln!(text, "{angle},{phase}").unwrap();
    }
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

/// Henyey–Greenstein `g` tabulated every `step_deg` degrees, scaled by 4π
/// (the program normalises whatever the scale).
fn hg_rows(g: f64, step_deg: f64) -> Vec<(f64, f64)> {
    let n = (180.0 / step_deg).round() as usize;
    (0..=n)
        .map(|i| {
            let angle = (i as f64 * step_deg).min(180.0);
            (
                angle,
                4.0 * PI * henyey_greenstein(angle.to_radians().cos(), g),
            )
        })
        .collect()
}

/// A bad phase file: its name, rows, the line and the reason the error gives.
type BadTable<'a> = (&'a str, Vec<(f64, f64)>, &'a str, &'a str);

#[test]
fn bad_phase_files_are_refused_naming_the_file_the_line_and_the_form() {
    let dir = tempfile::tempdir().unwrap();
    let cases: [BadTable; 5] = [
        (
            "one_row.csv",
            vec![(0.0, 1.0)],
            "line 2",
            "at least two rows",
        ),
        (
            "unsorted.csv",
            vec![(0.0, 1.0), (90.0, 1.0), (45.0, 1.0), (180.0, 1.0)],
            "line 4",
            "does not increase",
        ),
        (
            "short.csv",
            vec![(0.0, 1.0), (170.0, 1.0)],
            "line 3",
            "end at 180",
        ),
        (
            "negative.csv",
            vec![(0.0, 1.0), (90.0, -2.0), (180.0, 1.0)],
            "line 3",
            "≥ 0",
        ),
        (
            "nan.csv",
            vec![(0.0, 1.0), (90.0, f64::NAN), (180.0, 1.0)],
            "line 3",
            "≥ 0",
        ),
    ];
    for (name, rows, line, reason) in cases {
        let table = write_table(dir.path(), name, &rows);
        let scene = dir.path().join("scene.toml");
        // A relative path: from the scene file's folder.
        std::fs::write(
            &scene,
            format!("[atmosphere.aerosol]\nphase = \"table\"\nphase_file = \"{name}\"\n"),
        )
        .unwrap();
        let image = dir.path().join("sky.exr");
        let out = render_small(&scene, &image);
        assert_one_line_error(
            &out,
            &[
                table.to_str().unwrap(),
                line,
                reason,
                "angle_deg,phase",
                "0 to 180",
            ],
        );
        assert!(!image.exists(), "{name}: rendered");
    }
    let out = skyrender(&["atmosphere", "--scene", "/nonexistent/scene.toml"]);
    assert_eq!(out.status.code(), Some(2));
    // Keys that belong to another phase function, or are missing.
    for (toml, needle) in [
        ("phase = \"table\"", "needs phase_file"),
        (
            "phase = \"double-henyey-greenstein\"\ng1 = 0.8\ng2 = -0.3",
            "needs weight",
        ),
        ("g1 = 0.8", "belongs to phase = double-henyey-greenstein"),
        (
            "phase = \"table\"\nphase_file = \"x.csv\"\nasymmetry = 0.5",
            "belongs to",
        ),
        ("profile = \"exponential\"", "needs scale_height_m"),
        ("scale_height_m = 1000.0", "belongs to profile"),
    ] {
        let e = Scene::from_toml(&format!("[atmosphere.aerosol]\n{toml}")).unwrap_err();
        assert!(e.to_string().contains(needle), "{toml}: {e}");
    }
    let e = Scene::from_toml("[atmosphere.aerosol]\nasymetry = 0.5").unwrap_err();
    assert!(e.to_string().contains("unknown field `asymetry`"), "{e}");
}

/// A scene with the sun at `elevation_deg` and the aerosol phase function
/// given by the `[atmosphere.aerosol]` lines `phase`, thick enough haze
/// (optical depth 0.5 at 550 nm) that many paths scatter off it more than once.
fn hazy(elevation_deg: f64, phase: &str) -> Scene {
    Scene::from_toml(&format!(
        "[sun]\nelevation_deg = {elevation_deg}\nazimuth_deg = 180.0\n\
         [atmosphere.aerosol]\noptical_depth_550 = 0.5\n{phase}\n"
    ))
    .unwrap()
}

#[test]
fn a_tabulated_henyey_greenstein_renders_as_henyey_greenstein() {
    // The default g = 0.7 at 0.5° steps (the table's own model error,
    // linear in cos θ between rows, is < 0.1 % of the phase function).
    let dir = tempfile::tempdir().unwrap();
    let file = write_table(dir.path(), "hg.csv", &hg_rows(0.7, 0.5));
    let table = format!("phase = \"table\"\nphase_file = \"{}\"", file.display());
    let analytic = "phase = \"henyey-greenstein\"\nasymmetry = 0.7";
    // Sun at 30°: in the aureole (10° from the sun), away from it, and the
    // zenith; at sunset (2°, the control variate on, with the table's
    // Legendre moments) toward the sun and the east.
    let probes: [(f64, f64, f64, u32); 5] = [
        (30.0, 70.0, 180.0, 20_000),
        (30.0, 50.0, 0.0, 20_000),
        (30.0, 0.0, 0.0, 20_000),
        (2.0, 80.0, 180.0, 20_000),
        (2.0, 70.0, 0.0, 20_000),
    ];
    for (elevation_deg, zenith_deg, azimuth_deg, samples) in probes {
        let probe = |phase: &str| {
            let scene = hazy(elevation_deg, phase);
            let renderer = Renderer::new(&scene).unwrap();
            renderer.probe_radiance(zenith_deg, azimuth_deg, &[450.0, 650.0], samples)
        };
        let (a, b) = (probe(analytic), probe(&table));
        for (a, b) in a.iter().zip(&b) {
            let se = a.std_error.hypot(b.std_error);
            assert!(a.std_error < 0.02 * a.radiance, "too noisy to test: {a:?}");
            assert!(
                (a.radiance - b.radiance).abs() < 3.5 * se,
                "sun {elevation_deg}°, view ({zenith_deg}°, {azimuth_deg}°), {} nm: \
                 HG {} ± {} vs table {} ± {}",
                a.wavelength_nm,
                a.radiance,
                a.std_error,
                b.radiance,
                b.std_error
            );
        }
    }
    // At sunset the control variate is on with the table as with HG.
    let sunset = hazy(2.0, &table);
    assert!(Renderer::new(&sunset).unwrap().plan().control_variate);
}

#[test]
fn an_albedo_spectrum_is_the_constant_albedo_at_each_wavelength() {
    // Linear between [440 nm, 0.8] and [675 nm, 1.0], constant beyond:
    // at 440 nm the haze scatters as with albedo 0.8, at 675 nm as with 1.
    let scene = |albedo: &str| {
        Scene::from_toml(&format!(
            "[sun]\nelevation_deg = 20.0\n[atmosphere.aerosol]\noptical_depth_550 = 0.6\n\
             single_scattering_albedo = {albedo}\n"
        ))
        .unwrap()
    };
    let spectrum = scene("[[440.0, 0.8], [675.0, 1.0]]");
    let probe = |scene: &Scene, nm: f64| {
        Renderer::new(scene)
            .unwrap()
            .probe_radiance(60.0, 0.0, &[nm], 20_000)[0]
    };
    for (nm, constant) in [(440.0, "0.8"), (675.0, "1.0"), (900.0, "1.0")] {
        let (a, b) = (probe(&spectrum, nm), probe(&scene(constant), nm));
        let se = a.std_error.hypot(b.std_error);
        assert!(
            (a.radiance - b.radiance).abs() < 3.5 * se,
            "{nm} nm: {a:?} vs {b:?}"
        );
    }
    // A lower albedo darkens the haze: the two ends differ.
    let (dark, bright) = (probe(&scene("0.8"), 550.0), probe(&scene("1.0"), 550.0));
    assert!(bright.radiance - dark.radiance > 5.0 * bright.std_error.hypot(dark.std_error));
    // The atmosphere command reports the albedo at its wavelength.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("albedo.toml");
    std::fs::write(&path, spectrum.to_toml()).unwrap();
    let v = atmosphere_json(&["--scene", path.to_str().unwrap(), "--wavelength", "550"]);
    let albedo = v["aerosol_albedo"].as_f64().unwrap();
    assert!(
        (albedo - (0.8 + 0.2 * 110.0 / 235.0)).abs() < 1e-12,
        "{albedo}"
    );
    for (bad, needle) in [
        ("[[675.0, 0.9], [440.0, 0.9]]", "does not increase"),
        ("[[440.0, 1.2]]", "0 to 1"),
        ("[]", "empty"),
        ("1.5", "0 to 1"),
    ] {
        let e = Scene::from_toml(&format!(
            "[atmosphere.aerosol]\nsingle_scattering_albedo = {bad}"
        ))
        .unwrap_err();
        assert!(e.to_string().contains(needle), "{bad}: {e}");
    }
}

#[test]
fn a_double_henyey_greenstein_renders_as_its_table() {
    // At sunset the control variate integrates the phase function by its
    // Legendre moments: w g1^l + (1 − w) g2^l for the analytic form, the
    // exact moments of the linear pieces for the table; and directions
    // are drawn by choosing a lobe, or by the table's CDF. Both must give
    // the same light. The table at 0.25° steps (model error < 0.02 %).
    let (g1, g2, weight) = (0.8, -0.3, 0.9);
    let rows: Vec<(f64, f64)> = (0..=720)
        .map(|i| {
            let angle = f64::from(i) * 0.25;
            let mu = angle.to_radians().cos();
            let p = weight * henyey_greenstein(mu, g1) + (1.0 - weight) * henyey_greenstein(mu, g2);
            (angle, p)
        })
        .collect();
    let dir = tempfile::tempdir().unwrap();
    let file = write_table(dir.path(), "dhg.csv", &rows);
    let analytic =
        format!("phase = \"double-henyey-greenstein\"\ng1 = {g1}\ng2 = {g2}\nweight = {weight}");
    let table = format!("phase = \"table\"\nphase_file = \"{}\"", file.display());
    for (zenith_deg, azimuth_deg) in [(85.0, 180.0), (60.0, 0.0)] {
        let probe = |phase: &str| {
            let scene = hazy(2.0, phase);
            let renderer = Renderer::new(&scene).unwrap();
            assert!(renderer.plan().control_variate, "{phase}");
            renderer.probe_radiance(zenith_deg, azimuth_deg, &[450.0, 650.0], 20_000)
        };
        let (a, b) = (probe(&analytic), probe(&table));
        for (a, b) in a.iter().zip(&b) {
            let se = a.std_error.hypot(b.std_error);
            assert!(a.std_error < 0.02 * a.radiance, "too noisy to test: {a:?}");
            assert!(
                (a.radiance - b.radiance).abs() < 3.5 * se,
                "view ({zenith_deg}°, {azimuth_deg}°): {a:?} vs {b:?}"
            );
        }
    }
}

#[test]
fn a_phase_table_over_wavelength_renders_each_wavelength_with_its_blend() {
    // Henyey–Greenstein g = 0.5 at 360 nm, 0.7 at 550 nm and 0.78 at
    // 830 nm in one file: a path carries 450 and 650 nm in its lanes, which
    // draw directions from the lanes' average and weigh each lane by its
    // own phase function (and, at sunset, integrate the control variate
    // with each lane's moments). Each wavelength must come out as a scene
    // whose one phase function is that wavelength's blend: at 450 nm
    // (1 − w) HG(0.5) + w HG(0.7), w = 90/190; at 650 nm the blend of
    // 0.7 and 0.78 with w = 100/280.
    use std::fmt::Write as _;
    let dir = tempfile::tempdir().unwrap();
    let nodes = [(360.0, 0.5), (550.0, 0.7), (830.0, 0.78)];
    let mut text = String::from("angle_deg,phase,wavelength_nm\n");
    for (wavelength, g) in nodes {
        for (angle, phase) in hg_rows(g, 0.5) {
            writeln!(text, "{angle},{phase},{wavelength}").unwrap();
        }
    }
    let spectral = dir.path().join("spectral.csv");
    std::fs::write(&spectral, text).unwrap();
    let blend = |(w0, g0): (f64, f64), (w1, g1): (f64, f64), at: f64, name: &str| {
        let w = (at - w0) / (w1 - w0);
        let rows: Vec<(f64, f64)> = hg_rows(g0, 0.5)
            .into_iter()
            .zip(hg_rows(g1, 0.5))
            .map(|((angle, a), (_, b))| (angle, (1.0 - w) * a + w * b))
            .collect();
        write_table(dir.path(), name, &rows)
    };
    let at_450 = blend(nodes[0], nodes[1], 450.0, "blend450.csv");
    let at_650 = blend(nodes[1], nodes[2], 650.0, "blend650.csv");
    let phase = |file: &Path| format!("phase = \"table\"\nphase_file = \"{}\"", file.display());
    for (elevation_deg, zenith_deg, azimuth_deg) in
        [(30.0, 70.0, 180.0), (2.0, 80.0, 180.0), (2.0, 60.0, 0.0)]
    {
        let probe = |phase: &str, wavelengths: &[f64]| {
            let renderer = Renderer::new(&hazy(elevation_deg, phase)).unwrap();
            assert_eq!(renderer.plan().control_variate, elevation_deg < 3.0);
            renderer.probe_radiance(zenith_deg, azimuth_deg, wavelengths, 20_000)
        };
        let both = probe(&phase(&spectral), &[450.0, 650.0]);
        let one = [
            probe(&phase(&at_450), &[450.0])[0],
            probe(&phase(&at_650), &[650.0])[0],
        ];
        for (a, b) in both.iter().zip(&one) {
            let se = a.std_error.hypot(b.std_error);
            assert!(a.std_error < 0.02 * a.radiance, "too noisy to test: {a:?}");
            assert!(
                (a.radiance - b.radiance).abs() < 3.5 * se,
                "sun {elevation_deg}°, view ({zenith_deg}°, {azimuth_deg}°), {} nm: \
                 over wavelength {} ± {} vs its blend {} ± {}",
                a.wavelength_nm,
                a.radiance,
                a.std_error,
                b.radiance,
                b.std_error
            );
        }
    }
}
