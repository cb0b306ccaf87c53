//! Time and place: the Sun from a date, and timelapses of a whole day.

mod common;

use common::{skyrender, stderr};

use std::path::Path;

/// The scene an EXR embeds, and its mean luminance (cd/m²).
fn read_exr(path: &Path) -> (skyrender::Scene, f64) {
    let (_, luminance) = common::exr_luminance(path);
    let meta = exr::meta::MetaData::read_from_file(path, false).unwrap();
    let attributes = &meta.headers[0].own_attributes;
    let scene = attributes
        .other
        .iter()
        .find(|(k, _)| k.as_slice() == b"skyrender:scene")
        .map(|(_, v)| match v {
            exr::meta::attribute::AttributeValue::Text(t) => {
                String::from_utf8(t.as_slice().to_vec()).unwrap()
            }
            other => panic!("{other:?}"),
        })
        .unwrap();
    let mean = luminance.iter().sum::<f64>() / luminance.len() as f64;
    (skyrender::Scene::from_toml(&scene).unwrap(), mean)
}

/// The README's example: Ithaca, 27 May 2013, 11:45 EDT. The EXR records
/// the date, the place and the Sun SPA gives (pvlib: elevation 63.349°,
/// azimuth 136.078°, `data/sun_positions_pvlib.csv`).
#[test]
fn a_date_and_place_put_the_sun_where_spa_does() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("ithaca.exr");
    let out = skyrender(&[
        "render",
        "--lat",
        "42.4434",
        "--lon",
        "-76.4816",
        "--time",
        "2013-05-27T11:45:00-04:00",
        "--width",
        "16",
        "--height",
        "8",
        "--spp",
        "1",
        "-o",
        path.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", stderr(&out));
    let (scene, _) = read_exr(&path);
    assert_eq!(
        scene.sun.date_time.as_deref(),
        Some("2013-05-27T11:45:00-04:00")
    );
    assert_eq!(scene.sun.latitude_deg, Some(42.4434));
    // ΔT from the date's estimate (≈ 67 s) instead of pvlib's 67.0: far
    // below 0.01°.
    assert!(
        (scene.sun.elevation_deg - 63.348963).abs() < 0.01,
        "{scene:?}"
    );
    assert!(
        (scene.sun.azimuth_deg - 136.077537).abs() < 0.01,
        "{scene:?}"
    );
    // Late May: the Earth is 1.0133 AU from the Sun.
    assert!((scene.sun_distance_au() - 1.0132715).abs() < 1e-5);
}

/// A day at one frame an hour (24 frames at 128×64): every frame's Sun from
/// its own time, night darker than day, and `--resume` redoing only what
/// is missing.
#[test]
fn a_day_timelapse_writes_every_frame_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = dir.path().join("day_####.exr");
    let args = [
        "render",
        "--lat",
        "42.4434",
        "--lon",
        "-76.4816",
        "--time-start",
        "2013-05-27T00:00:00-04:00",
        "--time-end",
        "2013-05-27T23:00:00-04:00",
        "--frames",
        "24",
        "--width",
        "128",
        "--height",
        "64",
        "--spp",
        "1",
        "-o",
        pattern.to_str().unwrap(),
    ];
    let out = skyrender(&args);
    assert!(out.status.success(), "{}", stderr(&out));
    let mut means = Vec::new();
    for frame in 1..=24 {
        let path = dir.path().join(format!("day_{frame:04}.exr"));
        let (scene, mean) = read_exr(&path);
        assert_eq!(
            scene.sun.date_time.unwrap(),
            format!("2013-05-27T{:02}:00:00-04:00", frame - 1)
        );
        means.push((scene.sun.elevation_deg, mean));
    }
    // Solar noon in Ithaca (76.5° W, EDT) is near 13:00: the highest Sun
    // (≈ 68.6° at 42.4° N in late May: 90° − 42.4° + 21.3° declination)
    // and the brightest frame.
    let (noon_elevation, noon_mean) = means[13];
    assert!((noon_elevation - 68.6).abs() < 0.5, "{means:?}");
    let midnight = means[0];
    assert!(midnight.0 < -18.0, "{means:?}");
    assert!(noon_mean > 1e3 * midnight.1.max(1e-9), "{means:?}");
    // Daylight frames grow brighter with the Sun from 07:00 to 11:00.
    for pair in means[7..=11].windows(2) {
        assert!(pair[0].0 < pair[1].0 && pair[0].1 < pair[1].1, "{means:?}");
    }

    // Resume: only the missing frame is rendered again.
    let gone = dir.path().join("day_0007.exr");
    let kept = dir.path().join("day_0008.exr");
    std::fs::remove_file(&gone).unwrap();
    let kept_before = std::fs::metadata(&kept).unwrap().modified().unwrap();
    let out = skyrender(&[&args[..], &["--resume"]].concat());
    assert!(out.status.success(), "{}", stderr(&out));
    assert!(gone.exists());
    assert_eq!(
        std::fs::metadata(&kept).unwrap().modified().unwrap(),
        kept_before
    );
    assert!(stderr(&out).contains("23 of 24"), "{}", stderr(&out));
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(stdout.lines().count(), 1, "{stdout}");
    assert!(stdout.contains("frame 7/24"), "{stdout}");
}

/// Bad sequences: one line each, exit code 2, nothing written.
#[test]
fn bad_times_places_and_ranges_write_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = dir.path().join("f_##.exr");
    let single = dir.path().join("f.exr");
    let p = pattern.to_str().unwrap();
    let s = single.to_str().unwrap();
    let day = [
        "--time-start",
        "2013-05-27T00:00:00-04:00",
        "--time-end",
        "2013-05-27T23:00:00-04:00",
    ];
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (
            vec!["--time", "noon", "--lat", "1", "--lon", "1", "-o", s],
            "utc offset",
        ),
        (
            vec![
                "--time",
                "2013-05-27T11:45:00",
                "--lat",
                "1",
                "--lon",
                "1",
                "-o",
                s,
            ],
            "utc offset",
        ),
        (
            vec![
                "--time",
                "2013-05-27T11:45:00Z",
                "--lat",
                "91",
                "--lon",
                "1",
                "-o",
                s,
            ],
            "latitude",
        ),
        (
            vec![
                "--time",
                "2013-05-27T11:45:00Z",
                "--lat",
                "1",
                "--lon",
                "181",
                "-o",
                s,
            ],
            "longitude",
        ),
        (
            vec!["--time", "2013-05-27T11:45:00Z", "-o", s],
            "--lat and --lon",
        ),
        (
            [
                &day[..],
                &["--frames", "3", "--lat", "1", "--lon", "1", "-o", s],
            ]
            .concat(),
            "run of #",
        ),
        (
            [
                &day[..],
                &["--frames", "0", "--lat", "1", "--lon", "1", "-o", p],
            ]
            .concat(),
            "frames",
        ),
        (
            [
                &day[..],
                &[
                    "--frames",
                    "3",
                    "--frame-range",
                    "3..2",
                    "--lat",
                    "1",
                    "--lon",
                    "1",
                    "-o",
                    p,
                ],
            ]
            .concat(),
            "reversed",
        ),
        (
            [
                &day[..],
                &[
                    "--frames",
                    "3",
                    "--frame-range",
                    "2..4",
                    "--lat",
                    "1",
                    "--lon",
                    "1",
                    "-o",
                    p,
                ],
            ]
            .concat(),
            "3 frames",
        ),
        (
            vec![
                "--time-start",
                "2013-05-27T10:00:00Z",
                "--time-end",
                "2013-05-27T09:00:00Z",
                "--frames",
                "2",
                "--lat",
                "1",
                "--lon",
                "1",
                "-o",
                p,
            ],
            "before the start",
        ),
    ];
    for (args, needle) in cases {
        let out = skyrender(&[&["render"], &args[..]].concat());
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(
            err.to_lowercase().contains(&needle.to_lowercase()),
            "{args:?}: {err}"
        );
        assert!(
            std::fs::read_dir(dir.path()).unwrap().next().is_none(),
            "{args:?} wrote a file"
        );
    }
}
