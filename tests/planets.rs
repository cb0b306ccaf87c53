//! Custom vertical profiles (`[atmosphere] profile`) and planets
//! (`[planet]`, `--planet`): a profile that reproduces the standard
//! atmosphere renders as it, the ideal gas law at a level, bad profile
//! files, and the colours of the Mars presets.

mod common;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use common::{assert_one_line_error, render_small, skyrender};
use skyrender::physics::standard_atmosphere;
use skyrender::render::Renderer;
use skyrender::Scene;

/// The U.S. Standard Atmosphere's temperature and pressure every 1 km from
/// 0 to 100 km, as a profile file.
fn standard_atmosphere_csv() -> String {
    let mut text = String::from("altitude_m,temperature_k,pressure_pa\n");
    for km in 0..=100 {
        let z = f64::from(km) * 1000.0;
        let air = standard_atmosphere::air_state(z);
        writeln!(text, "{z},{},{}", air.temperature_k, air.pressure_pa).unwrap();
    }
    text
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path
}

#[test]
fn a_profile_of_the_standard_atmosphere_renders_as_the_default() {
    // The scene file names the profile relative to its own folder.
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "ussa.csv", &standard_atmosphere_csv());
    let body = "[sun]\nelevation_deg = 30.0\n";
    let with = write(
        dir.path(),
        "with.toml",
        &format!("{body}[atmosphere]\nprofile = \"ussa.csv\"\n"),
    );
    let without = write(dir.path(), "without.toml", body);
    let probe = |path: &Path, zenith_deg: f64, azimuth_deg: f64| {
        let scene = Scene::load(path).unwrap();
        Renderer::new(&scene).unwrap().probe_radiance(
            zenith_deg,
            azimuth_deg,
            &[420.0, 550.0, 680.0],
            20_000,
        )
    };
    for (zenith_deg, azimuth_deg) in [(0.0, 0.0), (70.0, 0.0), (85.0, 180.0)] {
        let (a, b) = (
            probe(&without, zenith_deg, azimuth_deg),
            probe(&with, zenith_deg, azimuth_deg),
        );
        for (a, b) in a.iter().zip(&b) {
            let se = a.std_error.hypot(b.std_error);
            assert!(a.std_error < 0.02 * a.radiance, "too noisy: {a:?}");
            assert!(
                (a.radiance - b.radiance).abs() < 3.5 * se,
                "view ({zenith_deg}°, {azimuth_deg}°), {} nm: default {} ± {} vs profile {} ± {}",
                a.wavelength_nm,
                a.radiance,
                a.std_error,
                b.radiance,
                b.std_error
            );
        }
    }
}

#[test]
fn the_number_density_is_the_ideal_gas_law_at_a_level() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "p.csv",
        "altitude_m,temperature_k,pressure_pa\n0,250,70000\n1500,240,58000\n4000,230,40000\n",
    );
    let scene = write(
        dir.path(),
        "s.toml",
        "[atmosphere]\nprofile = \"p.csv\"\nozone = false\n",
    );
    let out = skyrender(&[
        "atmosphere",
        "--json",
        "--scene",
        scene.to_str().unwrap(),
        "--altitude",
        "1500",
    ]);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let n = v["number_density_m3"].as_f64().unwrap();
    let want = 58_000.0 / (1.380_649e-23 * 240.0);
    assert!((n / want - 1.0).abs() < 1e-12, "{n} vs {want}");
    assert_eq!(v["temperature_k"].as_f64().unwrap(), 240.0);
    assert!((v["pressure_pa"].as_f64().unwrap() / 58_000.0 - 1.0).abs() < 1e-12);
}

#[test]
fn a_bad_profile_is_one_error_naming_file_line_and_form() {
    let dir = tempfile::tempdir().unwrap();
    let header = "altitude_m,temperature_k,pressure_pa\n";
    let cases = [
        ("one_row.csv", format!("{header}0,288,101325\n"), "line 2"),
        (
            "unsorted.csv",
            format!("{header}0,288,101325\n2000,275,79000\n1000,281,89000\n"),
            "line 4",
        ),
        (
            "negative_altitude.csv",
            format!("{header}-100,288,101325\n1000,281,89000\n"),
            "line 2",
        ),
        (
            "nan.csv",
            format!("{header}0,288,101325\n1000,NaN,89000\n"),
            "line 3",
        ),
        (
            "negative_value.csv",
            format!("{header}0,288,101325\n1000,281,-89000\n"),
            "line 3",
        ),
    ];
    for (name, text, line) in cases {
        write(dir.path(), name, &text);
        let scene = write(
            dir.path(),
            "bad.toml",
            &format!("[atmosphere]\nprofile = \"{name}\"\n"),
        );
        let image = dir.path().join(format!("{name}.exr"));
        let out = render_small(&scene, &image);
        assert_one_line_error(&out, &[name, line, "altitude_m", "temperature_k"]);
        assert!(!image.exists(), "{name}: an image was written");
    }
}

/// Linear RGB of an EXR, row-major, and its width.
fn exr_rgb(path: &Path) -> (usize, Vec<[f64; 3]>) {
    let image = exr::prelude::read_first_rgba_layer_from_file(
        path,
        |size, _| {
            (
                size.width(),
                vec![[f64::NAN; 3]; size.width() * size.height()],
            )
        },
        |(width, pixels): &mut (usize, Vec<[f64; 3]>),
         position: exr::prelude::Vec2<usize>,
         (r, g, b, _): (f32, f32, f32, f32)| {
            pixels[position.y() * *width + position.x()] =
                [f64::from(r), f64::from(g), f64::from(b)];
        },
    )
    .expect("read the EXR");
    image.layer_data.channel_data.pixels
}

/// Renders `args` to a 64×32 equirect EXR and returns its pixels.
fn render(dir: &Path, name: &str, args: &[&str]) -> (usize, Vec<[f64; 3]>) {
    let image = dir.join(format!("{name}.exr"));
    let mut all = vec![
        "render", "--camera", "equirect", "--width", "64", "--height", "32", "--spp", "32",
        "--seed", "7", "-o",
    ];
    all.push(image.to_str().unwrap());
    all.extend_from_slice(args);
    let out = skyrender(&all);
    assert!(out.status.success(), "{}", common::stderr(&out));
    exr_rgb(&image)
}

/// The summed RGB of the equirect pixels whose centres lie within
/// `radius_deg` of (azimuth, elevation) — the map's centre looks north.
fn around(
    (width, pixels): &(usize, Vec<[f64; 3]>),
    azimuth_deg: f64,
    elevation_deg: f64,
    radius_deg: f64,
) -> [f64; 3] {
    let height = pixels.len() / width;
    let dir = |az: f64, el: f64| {
        let (az, el) = (az.to_radians(), el.to_radians());
        [el.cos() * az.sin(), el.cos() * az.cos(), el.sin()]
    };
    let target = dir(azimuth_deg, elevation_deg);
    let mut sum = [0.0; 3];
    let mut count = 0;
    for y in 0..height {
        let el = 90.0 - (y as f64 + 0.5) / height as f64 * 180.0;
        for x in 0..*width {
            let az = ((x as f64 + 0.5) / *width as f64 - 0.5) * 360.0;
            let d = dir(az, el);
            let cos = d[0] * target[0] + d[1] * target[1] + d[2] * target[2];
            if cos.clamp(-1.0, 1.0).acos().to_degrees() <= radius_deg {
                let p = pixels[y * width + x];
                for k in 0..3 {
                    sum[k] += p[k];
                }
                count += 1;
            }
        }
    }
    assert!(
        count > 0,
        "no pixel within {radius_deg}° of ({azimuth_deg}°, {elevation_deg}°)"
    );
    sum
}

#[test]
fn mars_at_noon_has_a_butterscotch_sky() {
    let dir = tempfile::tempdir().unwrap();
    let image = render(dir.path(), "noon", &["--preset", "mars-noon"]);
    // The sun is in the south at 60°: the northern sky at 30° and the
    // east and west at 20°, away from it, are red over blue.
    for (azimuth_deg, elevation_deg) in [(0.0, 30.0), (90.0, 20.0), (270.0, 20.0)] {
        let [r, _, b] = around(&image, azimuth_deg, elevation_deg, 8.0);
        eprintln!("noon ({azimuth_deg}°, {elevation_deg}°): R/B = {}", r / b);
        assert!(
            r > 1.0 * b,
            "({azimuth_deg}°, {elevation_deg}°): R {r}, B {b}"
        );
    }
    // --planet mars turns the default (Earth) midday into Mars's.
    let planet = render(dir.path(), "planet", &["--planet", "mars"]);
    let [r, _, b] = around(&planet, 0.0, 30.0, 8.0);
    eprintln!("--planet mars midday (0°, 30°): R/B = {}", r / b);
    assert!(r > b, "R {r}, B {b}");
}

#[test]
fn mars_at_sunset_is_red_far_from_the_sun_and_bluer_about_it() {
    let dir = tempfile::tempdir().unwrap();
    let image = render(dir.path(), "sunset", &["--preset", "mars-sunset"]);
    // The sun is in the west (270°) at 2°: far from it (the east, the
    // zenith) red over blue, and about it less red than there (more of the
    // light there is scattered once, and less often absorbed in the blue).
    let ratio = |[r, _, b]: [f64; 3]| b / r;
    let near = ratio(around(&image, 270.0, 8.0, 7.0));
    eprintln!("sunset near the sun: B/R = {near}");
    for (azimuth_deg, elevation_deg) in [(90.0, 15.0), (0.0, 80.0)] {
        let far = ratio(around(&image, azimuth_deg, elevation_deg, 8.0));
        eprintln!("sunset ({azimuth_deg}°, {elevation_deg}°): B/R = {far}");
        assert!(far < 1.0, "({azimuth_deg}°, {elevation_deg}°): B/R {far}");
        assert!(
            near > far,
            "near the sun B/R {near}, at ({azimuth_deg}°, {elevation_deg}°) {far}"
        );
    }
}

/// The landers' blue sunset: within a few degrees of the sun the sky is
/// blue over red. The dust's forward peak narrows toward the blue (Mie
/// theory for its 1.5 µm particles: about λ/(2r) wide), so close to the
/// sun blue light is scattered up to three times more strongly than red;
/// farther out the red wins again. Measured in a 24° view toward the sun,
/// in the ring 1°–4° from its centre (the disc, 0.35° across, left out).
/// With one phase function at every wavelength (the double
/// Henyey–Greenstein measured at 650 nm) the same ring is red over blue:
/// the test fails for a renderer that evaluates one phase for all lanes.
#[test]
fn mars_at_sunset_has_a_blue_aureole() {
    let dir = tempfile::tempdir().unwrap();
    let spectral = aureole_blue_over_red(dir.path(), "mars-dust", &["--preset", "mars-sunset"]);
    assert!(spectral > 1.0, "1°–4° from the sun: B/R {spectral}");
    // The same sunset with the dust's phase function at 650 nm for every
    // wavelength (Chen-Chen et al.'s double Henyey–Greenstein).
    let grey = dir.path().join("grey.toml");
    std::fs::write(
        &grey,
        "[planet]\npreset = \"mars\"\n[sun]\nelevation_deg = 2.0\nazimuth_deg = 270.0\n\
         [observer]\naltitude_m = 2.0\n[atmosphere.aerosol]\n\
         phase = \"double-henyey-greenstein\"\ng1 = 0.889\ng2 = 0.094\nweight = 0.743\n",
    )
    .unwrap();
    let grey = aureole_blue_over_red(dir.path(), "grey", &["--scene", grey.to_str().unwrap()]);
    assert!(grey < 1.0, "one phase function: B/R {grey}");
}

/// B/R summed over the ring 1°–4° from the sun (the sun 2° up in the west)
/// in a 24° perspective view toward it, 48×24 at 32 spp.
fn aureole_blue_over_red(dir: &Path, name: &str, args: &[&str]) -> f64 {
    let image = dir.join(format!("{name}.exr"));
    let (width, height, fov_deg, yaw_deg, pitch_deg) = (48_usize, 24_usize, 24.0_f64, 270.0, 6.0);
    let mut all = vec![
        "render",
        "--camera",
        "perspective",
        "--fov",
        "24",
        "--yaw",
        "270",
        "--pitch",
        "6",
        "--width",
        "48",
        "--height",
        "24",
        "--spp",
        "32",
        "--seed",
        "7",
        "-o",
    ];
    all.push(image.to_str().unwrap());
    all.extend_from_slice(args);
    let out = skyrender(&all);
    assert!(out.status.success(), "{}", common::stderr(&out));
    let (_, pixels) = exr_rgb(&image);
    // The pinhole's ray through each pixel centre (x east, y north, z up).
    let dir = |az: f64, el: f64| {
        let (az, el) = (az.to_radians(), el.to_radians());
        [el.cos() * az.sin(), el.cos() * az.cos(), el.sin()]
    };
    let forward = dir(yaw_deg, pitch_deg);
    let right = {
        let r = [forward[1], -forward[0], 0.0];
        let n = (r[0] * r[0] + r[1] * r[1]).sqrt();
        [r[0] / n, r[1] / n, 0.0]
    };
    let up = [
        right[1] * forward[2] - right[2] * forward[1],
        right[2] * forward[0] - right[0] * forward[2],
        right[0] * forward[1] - right[1] * forward[0],
    ];
    let sun = dir(270.0, 2.0);
    let tan_half = (0.5 * fov_deg).to_radians().tan();
    let mut sum = [0.0; 3];
    let mut count = 0;
    for y in 0..height {
        for x in 0..width {
            let sx = (2.0 * (x as f64 + 0.5) / width as f64 - 1.0) * tan_half;
            let sy = (1.0 - 2.0 * (y as f64 + 0.5) / height as f64) * tan_half * height as f64
                / width as f64;
            let ray: Vec<f64> = (0..3)
                .map(|k| forward[k] + sx * right[k] + sy * up[k])
                .collect();
            let norm = ray.iter().map(|v| v * v).sum::<f64>().sqrt();
            let cos = (0..3).map(|k| ray[k] / norm * sun[k]).sum::<f64>();
            let angle_deg = cos.clamp(-1.0, 1.0).acos().to_degrees();
            if (1.0..=4.0).contains(&angle_deg) {
                for k in 0..3 {
                    sum[k] += pixels[y * width + x][k];
                }
                count += 1;
            }
        }
    }
    assert!(count > 20, "{count} pixels in the ring");
    let ratio = sum[2] / sum[0];
    eprintln!("{name}: aureole 1°–4° from the sun ({count} pixels): B/R = {ratio}");
    ratio
}
