//! The command line: outputs, their metadata, and every kind of bad input.

mod common;

use common::{skyrender, stderr};

use std::path::Path;
use std::process::{Command, Output, Stdio};

/// The text of header attribute `key` of `image`'s first layer, if any (a
/// non-text attribute as its debug form).
fn exr_text(image: &exr::image::AnyImage, key: &str) -> Option<String> {
    image.layer_data[0]
        .attributes
        .other
        .iter()
        .find(|(k, _)| k.as_slice() == key.as_bytes())
        .map(|(_, v)| match v {
            exr::meta::attribute::AttributeValue::Text(t) => t.to_string(),
            other => format!("{other:?}"),
        })
}

/// A failing run: non-zero exit, a one-line error naming `needle`, and no file.
fn assert_rejected(args: &[&str], needle: &str, output: Option<&Path>) {
    let out = skyrender(args);
    let err = stderr(&out);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert_eq!(
        err.trim().lines().count(),
        1,
        "{args:?}: not one line: {err}"
    );
    assert!(
        err.to_lowercase().contains(&needle.to_lowercase()),
        "{args:?}: '{err}' lacks '{needle}'"
    );
    if let Some(path) = output {
        assert!(!path.exists(), "{args:?} left {}", path.display());
    }
}

#[test]
fn render_writes_an_exr_with_scene_metadata() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.exr");
    let out = skyrender(&[
        "render",
        "--preset",
        "sunset",
        "--width",
        "16",
        "--height",
        "8",
        "--spp",
        "2",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("16x8") && stdout.contains("2 spp") && stdout.contains("paths/s"),
        "{stdout}"
    );
    let image = exr::prelude::read_all_data_from_file(&path).unwrap();
    let text = |key: &str| exr_text(&image, key).unwrap_or_else(|| panic!("{key} missing"));
    let scene = text("skyrender:scene");
    assert!(scene.contains("elevation_deg"), "{scene}");
    assert_eq!(text("skyrender:spp"), "2");
    // The draft and one full pass, both one sample per pixel: 2.00.
    assert_eq!(text("skyrender:samples_per_pixel"), "2.00");
    // The sunset's sun at azimuth 270°: a quarter of the 16 columns from
    // the left edge, on a pixel edge — the image pairs columns.
    assert_eq!(text("skyrender:mirror_pairs"), "columns");
    assert!(stdout.contains("read in mirror pairs"), "{stdout}");
    assert!(image.attributes.chromaticities.is_some());
    // Only the EXR is left in the directory (atomic write, no temp files).
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// `--noise` stops a render at its target, no sooner than the estimate's
/// fewest passes; `--time-limit` before a pass that would end past it (the
/// first pass always runs); each says so on its line and in the header.
#[test]
fn noise_target_and_time_limit_stop_a_render_and_say_so() {
    let dir = tempfile::tempdir().unwrap();
    let run = |flags: &[&str], name: &str| {
        let path = dir.path().join(name);
        let mut args = vec![
            "render", "--preset", "midday", "--width", "32", "--height", "16", "--spp", "40",
        ];
        args.extend_from_slice(flags);
        args.extend_from_slice(&["-o", path.to_str().unwrap()]);
        let out = skyrender(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        let image = exr::prelude::read_all_data_from_file(&path).unwrap();
        let text = |key: &str| exr_text(&image, key).unwrap_or_default();
        let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
        (
            stdout,
            text("skyrender:spp"),
            text("skyrender:stopped_by"),
            text("skyrender:noise_estimate_percent"),
        )
    };
    // Any image meets 100 %: the fewest passes the estimate allows.
    let (stdout, spp, stopped, noise) = run(&["--noise", "100"], "noise.exr");
    let min_passes = skyrender::render::noise_estimate::MIN_PASSES.to_string();
    assert_eq!(
        (spp.as_str(), stopped.as_str()),
        (min_passes.as_str(), "noise target")
    );
    assert!(
        noise.parse::<f64>().is_ok_and(|n| n > 0.0 && n <= 100.0),
        "{noise}"
    );
    assert!(
        stdout.contains("stopped at the noise target") && stdout.contains("target 100 %"),
        "{stdout}"
    );
    let (stdout, spp, stopped, noise) = run(&["--time-limit", "0.001"], "limit.exr");
    assert_eq!(
        (spp.as_str(), stopped.as_str(), noise.as_str()),
        ("1", "time limit", "")
    );
    assert!(stdout.contains("stopped by the time limit"), "{stdout}");
    let (_, spp, stopped, _) = run(&[], "plain.exr");
    assert_eq!((spp.as_str(), stopped.as_str()), ("40", "passes"));
}

#[test]
fn no_mirror_reads_every_pixel_alone_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    for (flags, pairs) in [
        (&["--no-mirror", "--spp", "2"][..], "none"),
        // 1° off the pixel grid (16 columns of 22.5°): each pixel's halves
        // with their mirror images', from three passes on.
        (&["--sun-azimuth", "271", "--spp", "2"][..], "none"),
        (&["--sun-azimuth", "271", "--spp", "3"][..], "halves"),
        (
            &["--sun-azimuth", "271", "--spp", "3", "--no-mirror"][..],
            "none",
        ),
        (&["--spp", "2"][..], "columns"),
    ] {
        let path = dir.path().join("sky.exr");
        let mut args = vec![
            "render", "--preset", "sunset", "--width", "16", "--height", "8",
        ];
        args.extend_from_slice(&["-o", path.to_str().unwrap()]);
        args.extend_from_slice(flags);
        let out = skyrender(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        let stdout = String::from_utf8_lossy(&out.stdout);
        let said = match pairs {
            "columns" => Some("read in mirror pairs"),
            "halves" => Some("read in mirror halves"),
            _ => None,
        };
        assert_eq!(
            stdout.contains("read in mirror"),
            said.is_some(),
            "{flags:?}: {stdout}"
        );
        assert!(
            said.is_none_or(|s| stdout.contains(s)),
            "{flags:?}: {stdout}"
        );
        let image = exr::prelude::read_all_data_from_file(&path).unwrap();
        let value = exr_text(&image, "skyrender:mirror_pairs");
        assert_eq!(value.as_deref(), Some(pairs), "{flags:?}");
    }
}

#[test]
fn render_png_and_fisheye_and_perspective() {
    let dir = tempfile::tempdir().unwrap();
    for camera in ["fisheye", "perspective", "equirect"] {
        let path = dir.path().join(format!("{camera}.png"));
        let out = skyrender(&[
            "render",
            "--camera",
            camera,
            "--width",
            "12",
            "--height",
            "12",
            "--spp",
            "1",
            "-o",
            path.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{}", stderr(&out));
        let png = image::open(&path).unwrap();
        assert_eq!((png.width(), png.height()), (12, 12));
    }
}

#[test]
fn bad_inputs_get_one_line_errors_and_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let o = out.to_str().unwrap();
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["render", "--width", "0", "-o", o], "width"),
        (vec!["render", "--width", "-4", "-o", o], "width"),
        (vec!["render", "--height", "0", "-o", o], "height"),
        (vec!["render", "--spp", "0", "-o", o], "spp"),
        (vec!["render", "--spp", "-1", "-o", o], "spp"),
        (vec!["render", "--altitude", "-1", "-o", o], "altitude"),
        (vec!["render", "--altitude", "2e8", "-o", o], "altitude"),
        (
            vec!["render", "--sun-elevation", "nan", "-o", o],
            "sun elevation",
        ),
        (
            vec!["render", "--fov", "inf", "--camera", "perspective", "-o", o],
            "fov",
        ),
        (vec!["render", "--ground-albedo", "1.5", "-o", o], "albedo"),
        (vec!["render", "--preset", "noon", "-o", o], "preset"),
        (
            vec!["render", "--camera", "orthographic", "-o", o],
            "camera",
        ),
        (
            vec!["render", "--scene", "/nonexistent/scene.toml", "-o", o],
            "scene",
        ),
        (vec!["render", "--threads", "0", "-o", o], "threads"),
        (vec!["render", "--noise", "0", "-o", o], "noise target"),
        (vec!["render", "--noise", "nan", "-o", o], "noise target"),
        (vec!["render", "--noise", "101", "-o", o], "noise target"),
        (vec!["render", "--time-limit", "-1", "-o", o], "time limit"),
        (vec!["render", "--time-limit", "inf", "-o", o], "time limit"),
        // A part renders the passes it is given.
        (
            vec!["render", "--passes", "0..2", "--noise", "5", "-o", o],
            "noise target",
        ),
        // Rejected by the argument parser itself, still on one line.
        (vec!["render", "--width", "nan", "-o", o], "--width"),
        (vec!["render", "--spp", "2.5", "-o", o], "--spp"),
        (vec!["render", "--seed=-1", "-o", o], "--seed"),
        (
            vec!["render", "--preset", "midday", "--scene", "s.toml", "-o", o],
            "--scene",
        ),
        (vec!["render", "--no-such-flag", "-o", o], "--no-such-flag"),
        (vec!["render", "--seed", "-1", "-o", o], "--seed"),
        // A seed the scene embedded in the EXR could not hold.
        (
            vec!["render", "--seed", "18446744073709551615", "-o", o],
            "0 to 9223372036854775807",
        ),
        // Each side in range, the whole too large to allocate.
        (
            vec!["render", "--width", "65536", "--height", "65536", "-o", o],
            "width × height",
        ),
        // The app's options are not the subcommands'.
        (vec!["--preset", "sunset", "render", "-o", o], "--preset"),
        (vec!["bench", "--budget", "-1"], "budget"),
        (vec!["bench", "--seed", "9223372036854775807"], "seed"),
    ];
    for (args, needle) in cases {
        assert_rejected(&args, needle, Some(&out));
    }
    let jpg = dir.path().join("x.jpg");
    assert_rejected(
        &["render", "--spp", "1", "-o", jpg.to_str().unwrap()],
        "extension",
        Some(&jpg),
    );
    let unwritable = dir.path().join("missing-dir").join("x.exr");
    assert_rejected(
        &["render", "--spp", "1", "-o", unwritable.to_str().unwrap()],
        "output",
        Some(&unwritable),
    );
    // Names no file system takes: refused before the render, not after.
    let long = dir.path().join(format!("{}.exr", "a".repeat(300)));
    assert_rejected(
        &["render", "--spp", "1", "-o", long.to_str().unwrap()],
        "at most 255",
        Some(&long),
    );
    let slash = format!("{o}/");
    assert_rejected(
        &["render", "--spp", "1", "-o", &slash],
        "directory",
        Some(&out),
    );
    // The app's screenshot path is checked before any window opens.
    let shot = dir.path().join("missing-dir").join("shot.png");
    assert_rejected(
        &["--screenshot", shot.to_str().unwrap()],
        "screenshot path",
        Some(&shot),
    );
    // A directory in the way of the output: named, and left as it was.
    let in_the_way = dir.path().join("taken.exr");
    std::fs::create_dir(&in_the_way).unwrap();
    assert_rejected(
        &["render", "--spp", "1", "-o", in_the_way.to_str().unwrap()],
        "is a directory",
        None,
    );
    assert!(in_the_way.is_dir());
    std::fs::remove_dir(&in_the_way).unwrap();
    let bad_scene = dir.path().join("bad.toml");
    std::fs::write(&bad_scene, "[sun]\nelevation_deg = \"high\"\n").unwrap();
    assert_rejected(
        &["render", "--scene", bad_scene.to_str().unwrap(), "-o", o],
        "scene",
        Some(&out),
    );
    assert_rejected(
        &[
            "radiance",
            "--view-zenith",
            "0",
            "--view-azimuth",
            "0",
            "--samples",
            "0",
        ],
        "samples",
        None,
    );
    assert_rejected(
        &["radiance", "--view-zenith", "200", "--view-azimuth", "0"],
        "view zenith",
        None,
    );
    assert_rejected(
        &[
            "radiance",
            "--view-zenith",
            "0",
            "--view-azimuth",
            "0",
            "--wavelength",
            "100",
        ],
        "wavelength",
        None,
    );
    assert_rejected(&["atmosphere", "--altitude", "-10"], "altitude", None);
    assert_rejected(&["atmosphere", "--threads", "0"], "threads", None);
    assert_rejected(&["radiance", "--view-azimuth", "0"], "--view-zenith", None);
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "only bad.toml remains"
    );
}

#[test]
fn radiance_json_has_the_documented_keys() {
    let out = skyrender(&[
        "radiance",
        "--view-zenith",
        "30",
        "--view-azimuth",
        "90",
        "--wavelengths",
        "400:700:150",
        "--samples",
        "200",
        "--unit-sun",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["view_zenith_deg"], 30.0);
    assert_eq!(v["view_azimuth_deg"], 90.0);
    assert_eq!(v["samples"], 200);
    let spectrum = v["spectrum"].as_array().unwrap();
    assert_eq!(spectrum.len(), 3);
    for s in spectrum {
        assert!(s["radiance"].as_f64().unwrap() > 0.0);
        assert!(s["std_error"].as_f64().unwrap() >= 0.0);
        assert!(s["wavelength_nm"].as_f64().is_some());
        assert_eq!(s["discarded"], 0);
    }
    // Rayleigh blue: more radiance at 400 than at 700 nm.
    assert!(spectrum[0]["radiance"].as_f64() > spectrum[2]["radiance"].as_f64());
}

#[test]
fn atmosphere_json_reports_the_standard_and_optical_depths() {
    let out = skyrender(&[
        "atmosphere",
        "--altitude",
        "0",
        "--wavelength",
        "550",
        "--json",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for key in [
        "temperature_k",
        "pressure_pa",
        "density_kg_m3",
        "number_density_m3",
        "rayleigh_scattering_m",
        "ozone_absorption_m",
        "aerosol_extinction_m",
    ] {
        assert!(v[key].as_f64().is_some(), "{key}");
    }
    assert_eq!(v["pressure_pa"], 101_325.0);
    let tau = v["optical_depth"]["rayleigh"].as_f64().unwrap();
    assert!((tau - 0.0971).abs() < 0.001, "{tau}");
    assert!(v["optical_depth"]["ozone"].as_f64().unwrap() > 0.0);
    assert!(v["optical_depth"]["aerosol"].as_f64().unwrap() > 0.0);
    let high = skyrender(&[
        "atmosphere",
        "--altitude",
        "20000",
        "--no-aerosols",
        "--json",
    ]);
    let v: serde_json::Value = serde_json::from_slice(&high.stdout).unwrap();
    assert_eq!(v["aerosol_extinction_m"], 0.0);
    assert!((v["temperature_k"].as_f64().unwrap() - 216.65).abs() < 0.01);
}

#[test]
fn presets_are_listed() {
    let out = skyrender(&["presets"]);
    let text = String::from_utf8_lossy(&out.stdout);
    for name in [
        "midday",
        "afternoon",
        "sunset",
        "twilight",
        "space",
        "mars-noon",
        "mars-sunset",
    ] {
        assert!(text.contains(name), "{text}");
    }
}

#[test]
fn no_subcommand_without_display_points_at_the_cli() {
    let out = skyrender(&[]);
    assert!(!out.status.success());
    let err = stderr(&out);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("skyrender render"), "{err}");
}

#[test]
fn a_reader_that_closes_the_pipe_early_ends_the_program_quietly() {
    // `skyrender radiance … | head -n 1`: the reader is gone before the
    // probe prints (it computes first), so the write meets a closed pipe.
    let mut child = Command::new(env!("CARGO_BIN_EXE_skyrender"))
        .args([
            "radiance",
            "--view-zenith",
            "30",
            "--view-azimuth",
            "90",
            "--wavelengths",
            "400:700:10",
            "--samples",
            "2000",
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
}

#[test]
fn an_observer_exactly_at_the_top_of_the_atmosphere_renders() {
    // Rays up and across from the top itself have no span; rounding once
    // gave them one of negative length, and the sampler panicked on it.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("top.exr");
    for preset in ["midday", "twilight"] {
        let out = skyrender(&[
            "render",
            "--preset",
            preset,
            "--altitude",
            "100000",
            "--width",
            "24",
            "--height",
            "12",
            "--spp",
            "2",
            "-o",
            path.to_str().unwrap(),
        ]);
        assert!(out.status.success(), "{preset}: {}", stderr(&out));
    }
    let out = skyrender(&[
        "radiance",
        "--altitude",
        "100000",
        "--view-zenith",
        "89",
        "--view-azimuth",
        "180",
        "--wavelength",
        "550",
        "--samples",
        "500",
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn camera_flags_a_camera_does_not_use_are_noted() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let o = out.to_str().unwrap();
    let small = ["--width", "8", "--height", "4", "--spp", "1", "-o", o];
    let note = |args: &[&str]| {
        let all: Vec<&str> = ["render"]
            .iter()
            .chain(args)
            .chain(&small)
            .copied()
            .collect();
        let run = skyrender(&all);
        assert!(run.status.success(), "{all:?}: {}", stderr(&run));
        stderr(&run)
            .lines()
            .find(|l| l.contains("note:"))
            .map(str::to_owned)
    };
    let fisheye = note(&["--camera", "fisheye", "--pitch", "-90", "--yaw", "30"]).unwrap();
    assert!(
        fisheye.contains("fisheye camera does not use --pitch"),
        "{fisheye}"
    );
    assert!(!fisheye.contains("--yaw"), "{fisheye}");
    let equirect = note(&["--camera", "equirect", "--roll", "5", "--fov", "60"]).unwrap();
    assert!(equirect.contains("--roll, --fov"), "{equirect}");
    assert_eq!(note(&["--camera", "perspective", "--pitch", "10"]), None);
}

#[test]
fn switching_a_fisheye_scene_to_perspective_takes_the_perspective_default() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("fisheye.toml");
    std::fs::write(&scene, "[camera]\nkind = \"fisheye\"\n").unwrap();
    let path = dir.path().join("p.exr");
    let out = skyrender(&[
        "render",
        "--scene",
        scene.to_str().unwrap(),
        "--camera",
        "perspective",
        "--width",
        "8",
        "--height",
        "8",
        "--spp",
        "1",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let image = exr::prelude::read_all_data_from_file(&path).unwrap();
    let scene_text = exr_text(&image, "skyrender:scene").unwrap();
    assert!(scene_text.contains("fov_deg = 90.0"), "{scene_text}");
}

/// The preview app with `args` and `display` as `DISPLAY` (none: unset).
fn skyrender_app(args: &[&str], display: Option<&str>) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_skyrender"));
    command.args(args).env_remove("WAYLAND_DISPLAY");
    match display {
        Some(display) => command.env("DISPLAY", display),
        None => command.env_remove("DISPLAY"),
    };
    command.output().expect("run skyrender")
}

/// A failed start of the app: exit status 2 and one `skyrender: error:` line.
fn app_error(out: &Output) -> String {
    let err = stderr(out);
    assert_eq!(out.status.code(), Some(2), "{:?}: {err}", out.status);
    assert_eq!(err.trim().lines().count(), 1, "not one line: {err}");
    assert!(err.starts_with("skyrender: error: "), "{err}");
    err
}

/// No X server listens on this display.
const MISSING_DISPLAY: &str = ":12345";

#[test]
fn the_app_checks_its_scene_file_before_any_window_opens() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[sun]\nelevation_deg = 95.0\n").unwrap();
    let bad = bad.to_str().unwrap();
    let out = dir.path().join("x.exr");
    let render = skyrender(&["render", "--scene", bad, "-o", out.to_str().unwrap()]);
    let render_err = stderr(&render);
    assert!(render_err.contains("sun elevation"), "{render_err}");
    // The message `skyrender render --scene` gives, with no display and with
    // one that cannot be opened: the file is read before a window is tried.
    for display in [None, Some(MISSING_DISPLAY)] {
        let err = app_error(&skyrender_app(&["--scene", bad], display));
        assert_eq!(err, render_err, "DISPLAY={display:?}");
    }
    let missing = dir.path().join("missing.toml");
    let err = app_error(&skyrender_app(
        &["--scene", missing.to_str().unwrap()],
        Some(MISSING_DISPLAY),
    ));
    assert!(
        err.contains("cannot read") && err.contains("missing.toml"),
        "{err}"
    );
    let garbled = dir.path().join("garbled.toml");
    std::fs::write(&garbled, "[sun\n").unwrap();
    let err = app_error(&skyrender_app(
        &["--scene", garbled.to_str().unwrap()],
        None,
    ));
    assert!(err.contains("line 1"), "{err}");

    let err = app_error(&skyrender_app(
        &["--scene", bad, "--preset", "sunset"],
        Some(MISSING_DISPLAY),
    ));
    assert!(
        err.contains("--preset") && err.contains("--scene") && err.contains("cannot be used with"),
        "{err}"
    );
}

#[test]
fn a_display_that_cannot_be_opened_gets_a_clean_one_line_error() {
    let out = skyrender_app(&["--preset", "sunset"], Some(MISSING_DISPLAY));
    let err = app_error(&out);
    assert!(
        err.contains("cannot open the preview window on display ':12345': "),
        "{err}"
    );
    assert!(err.contains("skyrender render"), "{err}");
    // The windowing library's text can carry its source location.
    for leak in [".cargo/registry", ".rs:", "src/"] {
        assert!(!err.contains(leak), "'{leak}' in {err}");
    }
}

/// A scene file in the app, on the display the tests run under (CI starts
/// Xvfb); `--screenshot-after 0` takes the first frame on screen, before the
/// full-size render has shown one.
#[test]
fn the_app_opens_a_scene_file_and_takes_a_screenshot() {
    let Some(display) = std::env::var("DISPLAY").ok().filter(|d| !d.is_empty()) else {
        eprintln!("skipped: no DISPLAY for the app's window");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("fisheye.toml");
    std::fs::write(
        &scene,
        "[sun]\nelevation_deg = 20.0\n[camera]\nkind = \"fisheye\"\n",
    )
    .unwrap();
    let shot = dir.path().join("shot.png");
    let out = skyrender_app(
        &[
            "--scene",
            scene.to_str().unwrap(),
            "--screenshot",
            shot.to_str().unwrap(),
            "--screenshot-after",
            "0",
        ],
        Some(&display),
    );
    let err = stderr(&out);
    assert!(out.status.success(), "{:?}: {err}", out.status);
    assert!(!err.contains("NaN"), "{err}");
    let report = err
        .lines()
        .find(|l| l.starts_with("skyrender: screenshot at "))
        .unwrap_or_else(|| panic!("no screenshot line: {err}"));
    // The scene file's fisheye: a square image, not the default panorama.
    let size = report
        .split(" at ")
        .nth(2)
        .and_then(|s| s.split([';', ' ']).next())
        .unwrap_or_else(|| panic!("no size in: {report}"));
    let (w, h) = size.split_once('x').unwrap();
    assert_eq!(w, h, "{report}");
    // The window's size in pixels depends on the display's scale (and a
    // window manager's say); the file only has to be a picture of it.
    let png = image::open(&shot).unwrap();
    assert!(png.width() > 0 && png.height() > 0);
}

#[test]
fn the_control_variate_set_on_in_haze_its_table_cannot_hold_is_noted() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x.exr");
    let note = |control: &str| {
        let scene = dir.path().join("haze.toml");
        std::fs::write(
            &scene,
            format!(
                "[sun]\nelevation_deg = 2.0\n[atmosphere]\naerosol_amount = 100.0\n\
                 [render.integrator]\n{control}\n"
            ),
        )
        .unwrap();
        let run = skyrender(&[
            "render",
            "--scene",
            scene.to_str().unwrap(),
            "--width",
            "4",
            "--height",
            "2",
            "--spp",
            "1",
            "-o",
            out.to_str().unwrap(),
        ]);
        assert!(run.status.success(), "{control}: {}", stderr(&run));
        stderr(&run)
            .lines()
            .find(|l| l.contains("note:"))
            .map(str::to_owned)
    };
    let set = note("control_variate = true").unwrap();
    assert!(
        set.contains("control_variate = true") && set.contains("optical depth 24.8"),
        "{set}"
    );
    assert_eq!(note(""), None);
    assert_eq!(note("control_variate = false"), None);
}
