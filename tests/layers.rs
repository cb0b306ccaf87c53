//! `render --layers`: the transmittance and Z layers in one EXR beside the
//! image, read back by the `exr` crate and OpenEXR's `exrheader`; bad
//! layer names and layers to a PNG refused with nothing written.

use std::path::Path;
use std::process::{Command, Output};

use skyrender::output::channels::read_exr_channels;
use skyrender::render::Renderer;
use skyrender::scene::Scene;
use skyrender::spectrum::{xyz_to_rec709, ColourMatching};

fn skyrender(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_skyrender"))
        .args(args)
        .env_remove("DISPLAY")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run skyrender")
}

const SIZE: [&str; 6] = ["--width", "32", "--height", "16", "--spp", "2"];

fn render_layers(path: &Path, extra: &[&str]) {
    let out = skyrender(
        &[
            &["render", "--preset", "sunset", "--camera", "equirect"],
            &SIZE[..],
            extra,
            &["-o", path.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

const ALL: [&str; 8] = [
    "A",
    "B",
    "G",
    "R",
    "Z",
    "transmittance.B",
    "transmittance.G",
    "transmittance.R",
];

#[test]
fn all_layers_are_written_beside_the_image() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("layers.exr");
    render_layers(&path, &["--layers"]);
    let file = read_exr_channels(&path).unwrap();
    let mut names: Vec<&str> = file.channels.keys().map(String::as_str).collect();
    names.sort_unstable();
    assert_eq!(names, ALL);
    assert_eq!(file.text["skyrender:layers"], "transmittance,Z");
    // OpenEXR's own reader lists the same channels.
    let header = Command::new("exrheader").arg(&path).output().unwrap();
    assert!(header.status.success());
    let text = String::from_utf8_lossy(&header.stdout);
    assert!(text.contains("chromaticities"), "{text}");
    for name in ALL {
        assert!(
            text.lines()
                .any(|l| l.trim_start().starts_with(&format!("{name},"))),
            "exrheader does not list {name}:\n{text}"
        );
    }

    // Z: finite exactly on the rows below the horizon (the observer 2 m
    // up: every pixel centre below it meets the ground), about 2 m / sin(dip)
    // there.
    let (w, h) = (32, 16);
    let z = &file.channels["Z"];
    let alpha = &file.channels["A"];
    for y in 0..h {
        let elevation = 90.0 - (y as f64 + 0.5) * 180.0 / h as f64;
        for x in 0..w {
            let v = f64::from(z[y * w + x]);
            if elevation < 0.0 {
                let flat = 2.0 / (-elevation).to_radians().sin();
                assert!(
                    (v / flat - 1.0).abs() < 1e-3,
                    "row {y}: Z {v} against {flat}"
                );
                assert_eq!(alpha[y * w + x], 1.0, "opaque ground, row {y}");
            } else {
                assert_eq!(v, f64::INFINITY, "row {y}");
                assert!((0.0..1.0).contains(&alpha[y * w + x]), "row {y}");
            }
        }
    }

    // The transmittance's colour and A from the spectral transmittance
    // along each pixel centre's ray: a white source seen through it,
    // normalised to (1, 1, 1) for T = 1; A = 1 − Σ T ȳ / Σ ȳ in the sky.
    let scene = Scene::preset("sunset").unwrap();
    let mut scene = scene;
    scene.render.width = w as u32;
    scene.render.height = h as u32;
    let renderer = Renderer::new(&scene).unwrap();
    let cmf = ColourMatching::get(scene.render.observer);
    let (from, to) = cmf.range_nm();
    let step = skyrender::render::layers::STEP_NM;
    let wavelengths: Vec<f64> = (0..=((to - from) / step) as usize)
        .map(|i| from + i as f64 * step)
        .collect();
    let weigh = |t: &dyn Fn(usize) -> f64| {
        let mut xyz = [0.0; 3];
        for (i, &l) in wavelengths.iter().enumerate() {
            let bar = cmf.xyz_bar(l);
            for c in 0..3 {
                xyz[c] += t(i) * bar[c];
            }
        }
        xyz
    };
    let white_xyz = weigh(&|_| 1.0);
    let white = xyz_to_rec709(white_xyz);
    for (x, y) in [(0, 0), (5, 3), (24, 7), (12, 8), (31, 15)] {
        let dir = renderer
            .camera()
            .direction(x as f64 + 0.5, y as f64 + 0.5)
            .unwrap()
            .normalize();
        let (t, ground) = renderer.view_transmittance(dir, &wavelengths);
        let xyz = weigh(&|i| t[i]);
        let rgb = xyz_to_rec709(xyz);
        let i = y * w + x;
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let got = f64::from(file.channels[&format!("transmittance.{name}")][i]);
            let want = rgb[c] / white[c];
            assert!(
                (got - want).abs() < 1e-5,
                "({x}, {y}) {name}: {got} against {want}"
            );
        }
        let want_a = if ground.is_some() {
            1.0
        } else {
            1.0 - xyz[1] / white_xyz[1]
        };
        assert!((f64::from(alpha[i]) - want_a).abs() < 1e-6, "({x}, {y}) A");
    }
    // Overhead the air is nearly clear; along the horizon nearly opaque.
    assert!(alpha[w / 2] < 0.5 && alpha[7 * w + w / 2] > 0.5);
    // The beauty image is the plain render's.
    let plain = dir.path().join("plain.exr");
    render_layers(&plain, &[]);
    let plain = read_exr_channels(&plain).unwrap();
    for c in ["R", "G", "B"] {
        assert_eq!(plain.channels[c], file.channels[c], "{c}");
    }
}

#[test]
fn a_list_picks_layers_and_the_scene_file_may_name_them() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("z.exr");
    render_layers(&path, &["--layers", "Z"]);
    let file = read_exr_channels(&path).unwrap();
    let mut names: Vec<&str> = file.channels.keys().map(String::as_str).collect();
    names.sort_unstable();
    assert_eq!(names, ["B", "G", "R", "Z"]);
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        "[camera]\nkind = \"equirect\"\n[output]\nlayers = [\"transmittance\"]\n",
    )
    .unwrap();
    let path = dir.path().join("t.exr");
    let out = skyrender(
        &[
            &["render", "--scene", scene.to_str().unwrap()],
            &SIZE[..],
            &["-o", path.to_str().unwrap()],
        ]
        .concat(),
    );
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let file = read_exr_channels(&path).unwrap();
    assert!(file.channels.contains_key("transmittance.G") && !file.channels.contains_key("Z"));
}

#[test]
fn bad_layers_are_refused_with_nothing_written() {
    let dir = tempfile::tempdir().unwrap();
    let bad_scene = dir.path().join("bad.toml");
    std::fs::write(&bad_scene, "[output]\nlayers = [\"Z\", \"depth\"]\n").unwrap();
    for (args, name, expect) in [
        (
            vec!["--layers", "Z,bogus"],
            "a.exr",
            "unknown layer 'bogus'",
        ),
        (vec!["--layers"], "b.png", "need an EXR"),
        (vec!["--layers", "Z"], "c.png", "need an EXR"),
        (
            vec!["--scene", bad_scene.to_str().unwrap()],
            "d.exr",
            "unknown layer 'depth'",
        ),
    ] {
        let path = dir.path().join(name);
        let out = skyrender(
            &[
                &["render"],
                &SIZE[..],
                &args[..],
                &["-o", path.to_str().unwrap()],
            ]
            .concat(),
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        if expect.starts_with("unknown") {
            assert!(err.contains("valid layers: transmittance, Z"), "{err}");
        }
        assert!(!path.exists(), "{args:?}: {name} written");
    }
}
