//! The ground's albedo spectrum and the Sun's spectrum file and limb
//! darkening (`[atmosphere] ground_albedo_spectrum`, `[sun] spectrum`,
//! `[sun] limb_darkening`).

mod common;

use common::{render_small, skyrender_ok};

use std::fmt::Write as _;
use std::path::Path;

use skyrender::physics::sun;
use skyrender::render::Renderer;
use skyrender::scene::Scene;

use skyrender::output::channels::read_exr_channels;

/// A scene in folder `dir` from `toml`, loaded as its file would be.
fn scene_in(dir: &Path, toml: &str) -> Scene {
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    Scene::load(&path).unwrap()
}

/// The probe's radiance at `wavelengths` looking at (zenith, azimuth).
fn probe(scene: &Scene, view: (f64, f64), wavelengths: &[f64], samples: u32) -> Vec<(f64, f64)> {
    Renderer::new(scene)
        .unwrap()
        .probe_radiance(view.0, view.1, wavelengths, samples)
        .iter()
        .map(|e| (e.radiance, e.std_error))
        .collect()
}

const SKY: &str = "[sun]\nelevation_deg = 30.0\nazimuth_deg = 180.0\n";

#[test]
fn a_constant_albedo_file_renders_as_the_scalar_albedo() {
    // The lanes carry the file's 0.3 exactly and every density the same
    // scalar: the same seed gives the same estimate, bit for bit.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("grey.csv"),
        "wavelength_nm,albedo\n350,0.3\n900,0.3\n",
    )
    .unwrap();
    let scalar = scene_in(
        dir.path(),
        &format!("{SKY}[atmosphere]\nground_albedo = 0.3\n"),
    );
    let file = scene_in(
        dir.path(),
        &format!("{SKY}[atmosphere]\nground_albedo = 0.9\nground_albedo_spectrum = \"grey.csv\"\n"),
    );
    // Looking down at the ground 40° below the horizon, and up.
    for view in [(130.0, 0.0), (60.0, 90.0)] {
        let w = [450.0, 550.0, 650.0, 750.0];
        let a = probe(&scalar, view, &w, 2_000);
        let b = probe(&file, view, &w, 2_000);
        assert_eq!(a, b, "{view:?}");
    }
}

#[test]
fn each_wavelength_sees_its_own_albedo() {
    // A ramp from 0.1 at 400 nm to 0.9 at 800 nm: the radiance of the
    // ground at each wavelength is that of a grey ground of the ramp's
    // value there (the paths differ: the ramp's densities use its
    // largest albedo), within 4 standard errors.
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(
        dir.path().join("ramp.csv"),
        "# a test ramp\nwavelength_nm,albedo\n360,0.1\n400,0.1\n800,0.9\n830,0.9\n",
    )
    .unwrap();
    let ramp = scene_in(
        dir.path(),
        &format!("{SKY}[atmosphere]\nground_albedo_spectrum = \"ramp.csv\"\n"),
    );
    let view = (120.0, 30.0);
    let wavelengths = [450.0, 600.0, 750.0];
    let got = probe(&ramp, view, &wavelengths, 20_000);
    for (i, &w) in wavelengths.iter().enumerate() {
        let albedo = 0.1 + 0.8 * (w - 400.0) / 400.0;
        let grey = scene_in(
            dir.path(),
            &format!("{SKY}[atmosphere]\nground_albedo = {albedo}\n"),
        );
        let expected = probe(&grey, view, &[w], 20_000)[0];
        let se = got[i].1.hypot(expected.1);
        eprintln!("{w} nm: ramp {:?}, grey {albedo:.3}: {expected:?}", got[i]);
        assert!(
            (got[i].0 - expected.0).abs() < 4.0 * se && se < 0.02 * expected.0,
            "{w} nm: {:?} vs {expected:?}",
            got[i]
        );
    }
    // And snow is brighter than grass in the green, both as their tables.
    let named = |name: &str| {
        let scene = scene_in(
            dir.path(),
            &format!("{SKY}[atmosphere]\nground_albedo_spectrum = \"{name}\"\n"),
        );
        scene.atmosphere.ground().unwrap().at(550.0)
    };
    assert!((named("snow") - 0.83238).abs() < 1e-9);
    assert!((named("grass") - 0.09705).abs() < 1e-9);
}

#[test]
fn a_sun_spectrum_twice_the_table_doubles_the_radiance() {
    let dir = tempfile::tempdir().unwrap();
    let table = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/data/solar_am0.csv"))
        .unwrap();
    let mut doubled = String::from("wavelength_nm,irradiance\n");
    for line in table.lines().skip(1) {
        let (w, e) = line.split_once(',').unwrap();
        writeln!(doubled, "{w},{}", 2.0 * e.parse::<f64>().unwrap()).unwrap();
    }
    std::fs::write(dir.path().join("twice.csv"), doubled).unwrap();
    let plain = scene_in(dir.path(), SKY);
    let twice = scene_in(dir.path(), &format!("{SKY}spectrum = \"twice.csv\"\n"));
    let w = [400.0, 500.0, 600.0, 700.0];
    for view in [(60.0, 150.0), (120.0, 0.0)] {
        let a = probe(&plain, view, &w, 1_000);
        let b = probe(&twice, view, &w, 1_000);
        for (x, y) in a.iter().zip(&b) {
            // Doubling is exact in floating point: the same paths, twice
            // the light (to rounding).
            assert!((y.0 / x.0 - 2.0).abs() < 1e-12, "{view:?}: {x:?} {y:?}");
        }
    }
}

#[test]
fn bad_spectrum_files_are_refused_with_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let cases = [
        ("one.csv", "wavelength_nm,albedo\n500,0.3\n", "line 2"),
        (
            "unsorted.csv",
            "wavelength_nm,albedo\n360,0.3\n830,0.3\n500,0.3\n",
            "line 4",
        ),
        (
            "negative.csv",
            "wavelength_nm,albedo\n360,0.3\n600,-0.2\n830,0.3\n",
            "line 3",
        ),
        (
            "nan.csv",
            "wavelength_nm,albedo\n360,NaN\n830,0.3\n",
            "line 2",
        ),
        (
            "short.csv",
            "wavelength_nm,albedo\n400,0.3\n830,0.3\n",
            "360",
        ),
    ];
    for (file, text, place) in cases {
        std::fs::write(dir.path().join(file), text).unwrap();
        let out_path = dir.path().join("out.png");
        for key in ["ground", "sun"] {
            let scene = if key == "ground" {
                format!("[atmosphere]\nground_albedo_spectrum = \"{file}\"\n")
            } else {
                format!("[sun]\nspectrum = \"{file}\"\n")
            };
            if key == "sun" {
                std::fs::write(dir.path().join(file), text.replace("albedo", "irradiance"))
                    .unwrap();
            }
            let scene_path = dir.path().join("bad.toml");
            std::fs::write(&scene_path, scene).unwrap();
            let out = render_small(&scene_path, &out_path);
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{key} {file}");
            assert!(
                stderr.contains(file) && stderr.contains(place) && stderr.contains("valid:"),
                "{key} {file}: {stderr}"
            );
            assert_eq!(stderr.trim().lines().count(), 1, "{stderr}");
            assert!(!out_path.exists(), "{key} {file}: an image was written");
        }
    }
}

/// The disc's radiance from the probe at the centre and near the limb
/// (r ≈ 0.9, at the same elevation, so through the same air): their ratio
/// at 450 and 650 nm is Neckel & Labs' law, I(μ)/I(1).
#[test]
fn the_disc_near_its_limb_is_darkened_by_the_published_law() {
    use skyrender::render::direction_from_az_el;
    use skyrender::render::probe::ProbeLight;
    let scene = Scene::from_toml(
        "[sun]\nelevation_deg = 60.0\nazimuth_deg = 180.0\nlimb_darkening = true\n",
    )
    .unwrap();
    let renderer = Renderer::new(&scene).unwrap();
    let alpha_deg = sun::ANGULAR_RADIUS_DEG;
    // An azimuth step of 0.9 α / cos(elevation) is 0.9 α across the sky.
    let azimuth = 180.0 + 0.9 * alpha_deg / 60.0_f64.to_radians().cos();
    let cos_theta = direction_from_az_el(180.0, 60.0).dot(direction_from_az_el(azimuth, 60.0));
    let mu = sun::disc_mu(cos_theta, alpha_deg.to_radians().cos());
    assert!((mu - (1.0 - 0.81_f64).sqrt()).abs() < 0.01, "{mu}");
    let wavelengths = [450.0, 650.0];
    let disc = |az: f64| renderer.probe_light(30.0, az, &wavelengths, 2_000, ProbeLight::SunDisc);
    let (centre, limb) = (disc(180.0), disc(azimuth));
    let mut ratios = Vec::new();
    for (i, &nm) in wavelengths.iter().enumerate() {
        let ratio = limb[i].radiance / centre[i].radiance;
        let se = ratio
            * (limb[i].std_error / limb[i].radiance)
                .hypot(centre[i].std_error / centre[i].radiance);
        let law = sun::limb_darkening(nm, mu);
        eprintln!("{nm} nm: limb/centre {ratio:.4} ± {se:.4}, law {law:.4} at μ = {mu:.4}");
        assert!(
            (ratio - law).abs() < 4.0 * se + 1e-3 && se < 0.01,
            "{nm} nm: limb/centre {ratio} ± {se} vs the law's {law}"
        );
        ratios.push(ratio);
    }
    assert!(
        ratios[0] < ratios[1],
        "the blue limb is the darker: {ratios:?}"
    );
}

/// A zoomed render of the sun (1° field, 64 pixels): in the `sun` layer a
/// pixel near the limb over one at the centre is, in blue, Neckel &
/// Labs' law at 450 nm and, in red, at 610 nm (each averaged over the
/// pixels' area; to 0.03: a channel spans many wavelengths), and the blue
/// limb is darker than the red.
#[test]
fn a_zoomed_render_shows_the_limb_darker_and_redder() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sun.exr");
    let (size, fov_deg) = (64usize, 1.0_f64);
    skyrender_ok(&[
        "render",
        "--limb-darkening",
        "--sun-elevation",
        "60",
        "--sun-azimuth",
        "180",
        "--camera",
        "perspective",
        "--fov",
        "1",
        "--yaw",
        "180",
        "--pitch",
        "60",
        "--width",
        "64",
        "--height",
        "64",
        "--spp",
        "64",
        "--no-adaptive",
        "--layers",
        "sun",
        "-o",
        path.to_str().unwrap(),
    ]);
    let file = read_exr_channels(&path).unwrap();
    // Pixel (column, row) spans the tangent plane's square
    // [x0, x0 + h] × [y0, y0 + h], h = 2 tan(fov/2)/size.
    let tan_half = (fov_deg / 2.0).to_radians().tan();
    let h = 2.0 * tan_half / size as f64;
    let cos_radius = sun::ANGULAR_RADIUS_DEG.to_radians().cos();
    let law_mean = |nm: f64, column: usize, row: usize| -> f64 {
        let c = sun::limb_darkening_coefficients(nm);
        let n = 32_u32;
        let mut sum = 0.0;
        for i in 0..n {
            for k in 0..n {
                let x = (column as f64 + (f64::from(i) + 0.5) / f64::from(n)) * h - tan_half;
                let y = (row as f64 + (f64::from(k) + 0.5) / f64::from(n)) * h - tan_half;
                let cos_theta = 1.0 / (1.0 + x * x + y * y).sqrt();
                sum += sun::polynomial(&c, sun::disc_mu(cos_theta, cos_radius));
            }
        }
        sum / f64::from(n * n)
    };
    // Centre: columns and rows 31–32; limb: columns 18 and 45 (15.5 px
    // from the centre, r ≈ 0.91) on rows 31–32.
    let pixels = |columns: [usize; 2]| -> Vec<(usize, usize)> {
        columns
            .iter()
            .flat_map(|&c| [31, 32].map(move |r| (c, r)))
            .collect()
    };
    let (centre, limb) = (pixels([31, 32]), pixels([18, 45]));
    let mut ratios = Vec::new();
    for (channel, nm) in [("sun.B", 450.0), ("sun.R", 610.0)] {
        let values = &file.channels[channel];
        let mean = |ps: &[(usize, usize)]| {
            ps.iter()
                .map(|&(c, r)| f64::from(values[r * size + c]))
                .sum::<f64>()
                / ps.len() as f64
        };
        let law = |ps: &[(usize, usize)]| {
            ps.iter().map(|&(c, r)| law_mean(nm, c, r)).sum::<f64>() / ps.len() as f64
        };
        let image = mean(&limb) / mean(&centre);
        let expected = law(&limb) / law(&centre);
        assert!(
            (image - expected).abs() < 0.03,
            "{channel}: image limb/centre {image:.4} vs the law's {expected:.4} at {nm} nm"
        );
        eprintln!("{channel}: limb/centre {image:.4}, law at {nm} nm {expected:.4}");
        ratios.push(image);
    }
    assert!(ratios[0] < ratios[1] - 0.05, "blue, red: {ratios:?}");
}
