//! The spectral EXR (`render --spectral`): the JCGT layout's channels and
//! attributes, read back by OpenEXR's own `exrheader`; the spectral image
//! agreeing with the RGB one through the colour-matching functions; its
//! memory; and bad input.

mod common;

use common::{skyrender, skyrender_ok};

use std::path::Path;
use std::process::Command;
use std::sync::atomic::AtomicBool;

use skyrender::output::channels::read_exr_channels;
use skyrender::output::spectral::emissive_channel_name;
use skyrender::render::film_spectral::{band_centres_nm, band_width_nm, DEFAULT_SPECTRAL_BANDS};
use skyrender::render::Renderer;
use skyrender::scene::Scene;
use skyrender::spectrum::{xyz_to_rec709, ColourMatching, K_M};

/// A tiny sunset: circle splats, mirror pairs and the adaptive plan on,
/// so every path into the film is in the test.
fn tiny_sunset(bands: u32) -> Scene {
    let mut scene = Scene::preset("sunset").unwrap();
    scene.render.width = 16;
    scene.render.height = 8;
    scene.render.spp = 6;
    scene.output.spectral_bands = Some(bands);
    scene
}

#[test]
fn the_spectral_image_integrates_to_the_rgb_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.exr");
    // Four times the tiny sunset's pixels: the bands' and the colour
    // matching functions' readings of the same samples differ by a noise
    // (a sample near a band's edge weighs the band's mean, not its own
    // wavelength's), which a handful of heavy splats in 128 pixels took
    // past 1 %.
    let mut scene = tiny_sunset(DEFAULT_SPECTRAL_BANDS);
    scene.render.width = 32;
    scene.render.height = 16;
    skyrender::export::render_to_file(&scene, &path, &AtomicBool::new(false), |_, _| {}).unwrap();
    let file = read_exr_channels(&path).unwrap();
    let bands = DEFAULT_SPECTRAL_BANDS as usize;
    assert_eq!(file.channels.len(), 3 + bands);
    // The same paths: the RGB image is the one a plain render gives
    // (without the ground's pool, whose light is XYZ alone: a spectral
    // image goes without it).
    let plain_path = dir.path().join("plain.exr");
    let mut plain = scene.clone();
    plain.output.spectral_bands = None;
    plain.render.integrator.ground_pool = Some(false);
    skyrender::export::render_to_file(&plain, &plain_path, &AtomicBool::new(false), |_, _| {})
        .unwrap();
    let plain_file = read_exr_channels(&plain_path).unwrap();
    for name in ["R", "G", "B"] {
        assert_eq!(file.channels[name], plain_file.channels[name], "{name}");
    }
    // Each band's CMF integral on a 0.1 nm grid: the band means times these
    // are the XYZ of the band-averaged spectrum.
    let cmf = ColourMatching::get(scene.render.observer);
    let width = band_width_nm(bands);
    let weights: Vec<[f64; 3]> = band_centres_nm(bands)
        .iter()
        .map(|&c| {
            let steps = (width * 10.0).round() as usize;
            let mut w = [0.0; 3];
            for k in 0..steps {
                let l = c - width / 2.0 + (k as f64 + 0.5) * width / steps as f64;
                for (v, b) in w.iter_mut().zip(cmf.xyz_bar(l)) {
                    *v += b * width / steps as f64;
                }
            }
            w
        })
        .collect();
    let pixels = 32 * 16;
    let (mut from_spectra, mut rgb) = ([0.0f64; 3], [0.0f64; 3]);
    for i in 0..pixels {
        let mut xyz = [0.0; 3];
        for (b, &centre) in band_centres_nm(bands).iter().enumerate() {
            let s = f64::from(file.channels[&emissive_channel_name(centre)][i]);
            // Finite; not always ≥ 0: under the control variate single
            // estimates may be negative (and stay unbiased).
            assert!(s.is_finite(), "band {centre} nm: {s}");
            for c in 0..3 {
                xyz[c] += K_M * s * weights[b][c];
            }
        }
        for (c, v) in xyz_to_rec709(xyz).iter().enumerate() {
            from_spectra[c] += v;
        }
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            rgb[c] += f64::from(file.channels[*name][i]);
        }
    }
    for c in 0..3 {
        let error = (from_spectra[c] / rgb[c] - 1.0).abs();
        eprintln!(
            "channel {c}: spectra {:.4} rgb {:.4}, {:.3} %",
            from_spectra[c],
            rgb[c],
            100.0 * error
        );
        assert!(error < 0.01, "channel {c}: {:.3} % off", 100.0 * error);
    }
}

#[test]
fn the_file_has_the_jcgt_layout_for_exrheader() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.exr");
    skyrender_ok(&[
        "render",
        "--preset",
        "midday",
        "--width",
        "4",
        "--height",
        "2",
        "--spp",
        "1",
        "--spectral",
        "--bands",
        "94",
        "-o",
        path.to_str().unwrap(),
    ]);
    // 94 bands of 5 nm: centres 362.5 … 827.5 nm.
    let file = read_exr_channels(&path).unwrap();
    assert!(file.channels.contains_key("S0.362,500000nm"));
    assert!(file.channels.contains_key("S0.827,500000nm"));
    assert_eq!(file.text["spectralLayoutVersion"], "1.0");
    assert_eq!(file.text["emissiveUnits"], "W.m^-2.sr^-1");
    let header = match Command::new("exrheader").arg(&path).output() {
        Ok(o) => String::from_utf8_lossy(&o.stdout).into_owned(),
        Err(e) => {
            eprintln!("note: exrheader not run ({e}); the layout was checked by the exr crate");
            return;
        }
    };
    let channels: Vec<&str> = header
        .lines()
        .filter_map(|l| l.trim().strip_prefix("S0."))
        .collect();
    assert_eq!(channels.len(), 94, "{header}");
    assert!(channels
        .iter()
        .all(|c| c.contains("0000nm, 32-bit floating-point")));
    for channel in ["R", "G", "B"] {
        assert!(header.contains(&format!("\n    {channel}, 32-bit floating-point")));
    }
    assert!(header.contains("spectralLayoutVersion (type string): \"1.0\""));
    assert!(header.contains("emissiveUnits (type string): \"W.m^-2.sr^-1\""));
}

/// One failing run: exit 2, one line naming `needle`, no file.
fn assert_rejected(args: &[&str], needle: &str, output: &Path) {
    let out = skyrender(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
    assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
    assert!(!output.exists(), "{args:?} wrote {}", output.display());
}

#[test]
fn bad_spectral_requests_fail_with_one_line_and_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("s.exr");
    let png = dir.path().join("s.png");
    let tiny = ["render", "--width", "4", "--height", "2", "--spp", "1"];
    let with = |extra: &[&str], out: &Path| {
        let mut args: Vec<String> = tiny.iter().map(ToString::to_string).collect();
        args.extend(extra.iter().map(ToString::to_string));
        args.extend(["-o".to_owned(), out.to_str().unwrap().to_owned()]);
        args
    };
    for (extra, needle, out) in [
        (&["--spectral", "--bands", "0"][..], "1 to 470", &exr),
        (&["--spectral", "--bands", "471"][..], "1 to 470", &exr),
        (&["--spectral", "--bands", "-3"][..], "1 to 470", &exr),
        (&["--spectral"][..], "EXR", &png),
    ] {
        let args = with(extra, out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_rejected(&args, needle, out);
    }
    // The scene file's `[output] spectral_bands`, likewise.
    let scene = dir.path().join("scene.toml");
    let mut text = Scene::preset("midday").unwrap().to_toml();
    text.push_str("\n[output]\nspectral_bands = 0\n");
    std::fs::write(&scene, text).unwrap();
    let args = with(&["--scene", scene.to_str().unwrap()], &exr);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    assert_rejected(&args, "spectral_bands", &exr);
}

#[test]
fn a_2048_by_1024_spectral_export_counts_its_bands_in_the_memory_budget() {
    let mut scene = Scene::preset("sunset").unwrap();
    scene.render.width = 2048;
    scene.render.height = 1024;
    let plain = Renderer::new(&scene).unwrap().memory_needed_bytes();
    scene.output.spectral_bands = Some(DEFAULT_SPECTRAL_BANDS);
    let spectral = Renderer::new(&scene).unwrap().memory_needed_bytes();
    let per_layer = 2048 * 1024 * u64::from(DEFAULT_SPECTRAL_BANDS) * 4;
    // Camera sums and the written planes, and the splats' sums where the
    // renderer splats (it does at sunset).
    assert_eq!(spectral - plain, 3 * per_layer);
    eprintln!(
        "2048x1024, {DEFAULT_SPECTRAL_BANDS} bands: {} MB, {} MB without the spectral image",
        spectral / 1_000_000,
        plain / 1_000_000
    );
}
