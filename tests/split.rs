//! Renders split by pixel tiles and pass ranges, merged back by
//! `skyrender merge`: the single render's image where the technique allows
//! it, statistically the same image otherwise; bad sets of parts refused.

mod common;

use common::{skyrender, skyrender_ok};

use std::path::{Path, PathBuf};

/// The luminance (cd/m²) of every pixel of an RGB EXR, row-major.
fn luminance(path: &Path) -> Vec<f64> {
    common::exr_luminance(path).1
}

fn render(dir: &Path, name: &str, scene: &[&str], extra: &[&str]) -> PathBuf {
    let path = dir.join(name);
    skyrender_ok(&[&["render"], scene, extra, &["-o", path.to_str().unwrap()]].concat());
    path
}

fn merge(dir: &Path, parts: &[PathBuf], name: &str) -> PathBuf {
    let path = dir.join(name);
    let mut args = vec!["merge".to_owned()];
    args.extend(parts.iter().map(|p| p.to_str().unwrap().to_owned()));
    args.extend(["-o".to_owned(), path.to_str().unwrap().to_owned()]);
    skyrender_ok(&args.iter().map(String::as_str).collect::<Vec<_>>());
    path
}

/// The arguments of a 64×32 render of `preset` with the sun at `azimuth`
/// degrees, `spp` passes, adaptive sampling off.
fn small_scene<'a>(preset: &'a str, azimuth: &'a str, spp: &'a str) -> [&'a str; 11] {
    let mut args = [""; 11];
    args[..10].copy_from_slice(&adaptive_scene(preset, azimuth, spp));
    args[10] = "--no-adaptive";
    args
}

/// [`small_scene`] with adaptive sampling on.
fn adaptive_scene<'a>(preset: &'a str, azimuth: &'a str, spp: &'a str) -> [&'a str; 10] {
    [
        "--preset",
        preset,
        "--sun-azimuth",
        azimuth,
        "--width",
        "64",
        "--height",
        "32",
        "--spp",
        spp,
    ]
}

/// Tiles, adaptive sampling off: the merged file is the single render's,
/// byte for byte — midday (the ground's splats alone) in 4 bands, and
/// sunset (the air's and the ground's splats along the circles of
/// symmetry) in two explicit tiles and a band mix; the sun
/// at 250° too, off the columns' grid (mirror halves, their sums in the
/// parts).
#[test]
fn tiles_merge_into_the_single_render_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    for (preset, azimuth, tiles) in [
        (
            "midday",
            "180",
            vec![
                "--tiles 4 --tile-index 0",
                "--tiles 4 --tile-index 1",
                "--tiles 4 --tile-index 2",
                "--tiles 4 --tile-index 3",
            ],
        ),
        (
            "sunset",
            "270",
            vec!["--tile 0,0,48,16", "--tile 48,0,16,16", "--tile 0,16,64,16"],
        ),
        (
            "sunset",
            "250",
            vec!["--tile 0,0,48,16", "--tile 48,0,16,16", "--tile 0,16,64,16"],
        ),
        (
            "midday",
            "250",
            vec!["--tiles 2 --tile-index 0", "--tiles 2 --tile-index 1"],
        ),
    ] {
        let scene = small_scene(preset, azimuth, "4");
        let preset = format!("{preset}{azimuth}");
        let single = render(dir.path(), &format!("{preset}.exr"), &scene, &[]);
        let parts: Vec<PathBuf> = tiles
            .iter()
            .enumerate()
            .map(|(i, t)| {
                let extra: Vec<&str> = t.split(' ').collect();
                render(dir.path(), &format!("{preset}_part{i}.exr"), &scene, &extra)
            })
            .collect();
        // In any order.
        let reversed: Vec<PathBuf> = parts.iter().rev().cloned().collect();
        let merged = merge(dir.path(), &reversed, &format!("{preset}_merged.exr"));
        assert!(
            std::fs::read(&single).unwrap() == std::fs::read(&merged).unwrap(),
            "{preset}: the merged tiles differ from the single render"
        );
    }
}

/// Pass ranges without adaptive sampling and without splats: the same
/// samples, their sums exact — the merged file is the single render's, byte
/// for byte, whichever way the passes are cut. (Splats, the ground's by
/// day too, are summed in f32 per part: their merge is the single
/// render's to rounding, so the scene turns them off.)
#[test]
fn pass_ranges_merge_into_the_single_render_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let midday = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/presets/midday.toml"),
    )
    .unwrap();
    let file = dir.path().join("midday_no_splats.toml");
    std::fs::write(
        &file,
        format!("{midday}\n[render.integrator]\nground_splatting = false\n"),
    )
    .unwrap();
    let file = file.to_str().unwrap();
    // The sun at 180° (mirror pairs) and at 250° (mirror halves: the
    // parts' samples keep their numbers, so their parts too).
    for azimuth in ["180", "250"] {
        let mut scene = small_scene("midday", azimuth, "6");
        scene[..2].copy_from_slice(&["--scene", file]);
        let single = std::fs::read(render(dir.path(), "single.exr", &scene, &[])).unwrap();
        for cuts in [
            &["0..1", "1..4", "4..6"][..],
            &["0..5", "5..6"],
            &["0..3", "3..6"],
        ] {
            let parts: Vec<PathBuf> = cuts
                .iter()
                .map(|r| {
                    let name = format!("p{}.exr", r.replace("..", "_"));
                    render(dir.path(), &name, &scene, &["--passes", r])
                })
                .collect();
            let merged = merge(dir.path(), &parts, "merged.exr");
            assert!(
                std::fs::read(&merged).unwrap() == single,
                "{azimuth}°, {cuts:?}: the merged passes differ from the single render"
            );
        }
    }
}

/// Pass ranges and tiles with adaptive sampling on, at sunset (splats): each
/// part plans and learns from its own image, so the merge is another
/// unbiased estimate of the same image. Its difference from the single
/// render is no larger than that between two independent single renders
/// (seeds 1 and 2), and its mean luminance agrees with theirs within four
/// standard errors of a pixel-mean difference.
#[test]
fn adaptive_parts_merge_to_a_statistically_equal_image() {
    // The sun at 270° (mirror pairs) and at 250° (mirror halves; the later
    // parts number their samples apart and draw their parts by
    // `HalfMirror::part_apart`), its disc at column 16 or 12.4.
    for (azimuth, sun_x) in [("270", 16.0), ("250", 12.44)] {
        adaptive_parts_at(azimuth, sun_x);
    }
}

fn adaptive_parts_at(azimuth: &str, sun_x: f64) {
    let dir = tempfile::tempdir().unwrap();
    let scene = adaptive_scene("sunset", azimuth, "6");
    let a = luminance(&render(dir.path(), "a.exr", &scene, &["--seed", "1"]));
    let b = luminance(&render(dir.path(), "b.exr", &scene, &["--seed", "2"]));
    let parts = vec![
        render(
            dir.path(),
            "p0.exr",
            &scene,
            &["--seed", "1", "--passes", "0..3"],
        ),
        render(
            dir.path(),
            "p1t0.exr",
            &scene,
            &[
                "--seed",
                "1",
                "--passes",
                "3..6",
                "--tiles",
                "2",
                "--tile-index",
                "0",
            ],
        ),
        render(
            dir.path(),
            "p1t1.exr",
            &scene,
            &[
                "--seed",
                "1",
                "--passes",
                "3..6",
                "--tiles",
                "2",
                "--tile-index",
                "1",
            ],
        ),
    ];
    let merged = luminance(&merge(dir.path(), &parts, "merged.exr"));
    // The sun's disc (0.27° across, at 2° elevation and azimuth 270°: pixel
    // (16, 15.6) of this map) fills a hundredth of its pixel: a sample that
    // hits it outweighs the rest a thousandfold, so pixels within 11° of it
    // (two pixels) are left out, as the bench leaves out the sun's cone.
    // With halves a pixel is read with its partners across the mirror's
    // line (the sun's column): only one side of it counts, so the pixels
    // kept stay independent (as the standard error below assumes).
    let halves = azimuth != "270";
    let far = |i: usize| {
        let (x, y) = ((i % 64) as f64 + 0.5, (i / 64) as f64 + 0.5);
        let side = (x - sun_x).rem_euclid(64.0);
        (x - sun_x).hypot(y - 15.6) > 2.0 && (!halves || (side > 1.0 && side < 31.0))
    };
    let keep = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .enumerate()
            .filter(|(i, _)| far(*i))
            .map(|(_, y)| *y)
            .collect()
    };
    let (a, b, merged) = (keep(&a), keep(&b), keep(&merged));
    let rms = |x: &[f64], y: &[f64]| {
        (x.iter().zip(y).map(|(p, q)| (p - q).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let independent = rms(&a, &b);
    let split = rms(&a, &merged);
    assert!(
        split < 1.5 * independent,
        "{azimuth}°: split {split} vs independent {independent}"
    );
    let mean = |x: &[f64]| x.iter().sum::<f64>() / x.len() as f64;
    // A pixel difference has standard deviation ≈ `independent`; the mean
    // of n of them, ≈ independent/√n (pixels nearly independent).
    let standard_error = independent / (a.len() as f64).sqrt();
    let difference = mean(&merged) - mean(&a);
    assert!(
        difference.abs() < 4.0 * standard_error,
        "{azimuth}°: mean {} vs {}: {difference} > 4 × {standard_error}",
        mean(&merged),
        mean(&a)
    );
    assert!(merged.iter().all(|y| y.is_finite() && *y >= 0.0));
}

/// Sets of parts that do not make one render are refused with one line,
/// and nothing is written.
#[test]
fn parts_that_do_not_fit_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = [
        "--preset",
        "midday",
        "--width",
        "16",
        "--height",
        "8",
        "--spp",
        "4",
        "--no-adaptive",
    ];
    let p01 = render(dir.path(), "p01.exr", &scene, &["--passes", "0..1"]);
    let p14 = render(dir.path(), "p14.exr", &scene, &["--passes", "1..4"]);
    let p24 = render(dir.path(), "p24.exr", &scene, &["--passes", "2..4"]);
    let top = render(
        dir.path(),
        "top.exr",
        &scene,
        &["--tiles", "2", "--tile-index", "0"],
    );
    let other = render(
        dir.path(),
        "other.exr",
        &[
            "--preset",
            "midday",
            "--width",
            "16",
            "--height",
            "8",
            "--spp",
            "4",
            "--no-adaptive",
            "--seed",
            "9",
        ],
        &["--passes", "1..4"],
    );
    let plain = render(dir.path(), "plain.exr", &scene, &[]);
    let out = dir.path().join("out.exr");
    let cases: Vec<(Vec<&PathBuf>, &str)> = vec![
        (vec![&p01, &p14, &p24], "overlap"),
        (vec![&p01, &p24], "passes 1..2 are missing"),
        (vec![&p14], "passes 0..1 are missing"),
        (vec![&top], "a tile is missing"),
        (vec![&p01, &other], "different scenes"),
        (vec![&plain], "not a part"),
    ];
    for (parts, needle) in cases {
        let mut args = vec!["merge"];
        args.extend(parts.iter().map(|p| p.to_str().unwrap()));
        args.extend(["-o", out.to_str().unwrap()]);
        let result = skyrender(&args);
        let err = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!out.exists());
    }
    // Bad parts to render: a tile outside the image, passes past spp, a PNG.
    for (extra, needle) in [
        (vec!["--tile", "0,0,17,8"], "not inside"),
        (vec!["--passes", "2..5"], "go past"),
        (vec!["--passes", "3..3"], "empty"),
        (vec!["--tiles", "9", "--tile-index", "0"], "8 rows"),
    ] {
        let result = skyrender(
            &[
                &["render"],
                &scene[..],
                &extra[..],
                &["-o", out.to_str().unwrap()],
            ]
            .concat(),
        );
        let err = String::from_utf8_lossy(&result.stderr);
        assert_eq!(result.status.code(), Some(2), "{extra:?}: {err}");
        assert!(err.contains(needle), "{extra:?}: {err}");
        assert!(!out.exists());
    }
    let png = dir.path().join("part.png");
    let result = skyrender(
        &[
            &["render"],
            &scene[..],
            &["--passes", "0..2", "-o", png.to_str().unwrap()],
        ]
        .concat(),
    );
    assert_eq!(result.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&result.stderr).contains("EXR"));
}

/// The view rays' layers (transmittance, Z) of a split render come out of
/// the merge as out of a single render, byte for byte; the layers of the
/// paths (sky, sun, ground, variance) need the whole render, and a part
/// that asks for them is refused with nothing written.
#[test]
fn merges_write_the_view_ray_layers_and_parts_refuse_the_path_layers() {
    let dir = tempfile::tempdir().unwrap();
    let scene = [
        "--preset",
        "midday",
        "--camera",
        "equirect",
        "--width",
        "32",
        "--height",
        "16",
        "--spp",
        "3",
        "--no-adaptive",
        "--layers",
        "transmittance,Z",
    ];
    let single = render(dir.path(), "single.exr", &scene, &[]);
    let parts: Vec<PathBuf> = (0..2)
        .map(|i| {
            let index = i.to_string();
            let extra = ["--tiles", "2", "--tile-index", index.as_str()];
            render(dir.path(), &format!("part{i}.exr"), &scene, &extra)
        })
        .collect();
    let merged = merge(dir.path(), &parts, "merged.exr");
    assert!(
        std::fs::read(&single).unwrap() == std::fs::read(&merged).unwrap(),
        "the merged layered file differs from the single render's"
    );
    let refused = dir.path().join("sky_part.exr");
    let out = skyrender(&[
        "render",
        "--preset",
        "midday",
        "--width",
        "16",
        "--height",
        "8",
        "--spp",
        "3",
        "--passes",
        "0..1",
        "--layers",
        "sky",
        "-o",
        refused.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("come from a whole render"), "{err}");
    assert!(!refused.exists());
}
