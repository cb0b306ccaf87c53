//! The artists' guide (`docs/artists.md`) holds: loaded into Blender as
//! that guide says — World → Environment Texture through a Mapping node
//! rotated −90° about Z, north along +Y — the Sun's direction lands on the
//! pixel where skyrender put the Sun. Blender's equirect lookup, from
//! Cycles (`intern/cycles/kernel/geom/...`, `direction_to_equirectangular`
//! with range (−2π, π, −π, π)): u = (atan2(y, x) − π)/(−2π),
//! v = (acos z − π)/(−π), v = 1 at the top row.

mod common;

use std::f64::consts::PI;
use std::process::Command;

/// Where Blender samples the map for the world direction of azimuth
/// `azimuth_deg` (clockwise from north = +Y; east = +X) and elevation
/// `elevation_deg`, through the guide's Mapping node: image pixel (x from
/// the left, y from the top) of a `width`×`height` map.
fn blender_pixel(azimuth_deg: f64, elevation_deg: f64, width: f64, height: f64) -> (f64, f64) {
    let (a, e) = (azimuth_deg.to_radians(), elevation_deg.to_radians());
    let world = [a.sin() * e.cos(), a.cos() * e.cos(), e.sin()];
    // Mapping node, type Point, rotation Z = −90°: the vector looked up is
    // R_z(−90°) · world.
    let (s, c) = (-PI / 2.0).sin_cos();
    let lookup = [
        c * world[0] - s * world[1],
        s * world[0] + c * world[1],
        world[2],
    ];
    let u = (lookup[1].atan2(lookup[0]) - PI) / (-2.0 * PI);
    let v = (lookup[2].acos() - PI) / (-PI);
    (u.rem_euclid(1.0) * width, (1.0 - v) * height)
}

#[test]
fn the_sun_is_where_blender_looks_for_it() {
    let dir = tempfile::tempdir().unwrap();
    for (azimuth, elevation) in [(100.0, 30.0), (250.0, 12.0), (10.0, 55.0)] {
        let path = dir.path().join(format!("az{azimuth}.exr"));
        let out = Command::new(env!("CARGO_BIN_EXE_skyrender"))
            .args([
                "render", "--camera", "equirect", "--width", "128", "--height", "64",
            ])
            .args(["--spp", "8", "--sun-azimuth", &format!("{azimuth}")])
            .args(["--sun-elevation", &format!("{elevation}"), "-o"])
            .arg(&path)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let (width, pixels) = common::exr_luminance(&path);
        // The brightest pixel: the solar disc, or the aureole around it.
        let brightest = (0..pixels.len())
            .max_by(|&i, &j| pixels[i].total_cmp(&pixels[j]))
            .unwrap();
        let (x, y) = (
            (brightest % width) as f64 + 0.5,
            (brightest / width) as f64 + 0.5,
        );
        let (bx, by) = blender_pixel(azimuth, elevation, 128.0, 64.0);
        let dx = (x - bx + 64.0).rem_euclid(128.0) - 64.0;
        assert!(
            dx.abs() <= 1.5 && (y - by).abs() <= 1.5,
            "sun at {azimuth}°/{elevation}°: brightest pixel ({x}, {y}), Blender looks at ({bx:.1}, {by:.1})"
        );
        // The header's sun pixel says the same.
        let header = exr::meta::MetaData::read_from_file(&path, false).unwrap();
        let attribute = &header.headers[0].own_attributes.other
            [&exr::meta::attribute::Text::from("skyrender:sun_pixel")];
        let exr::meta::attribute::AttributeValue::Text(text) = attribute else {
            panic!("{attribute:?}")
        };
        let numbers: Vec<f64> = text
            .to_string()
            .split(' ')
            .map(|n| n.parse().unwrap())
            .collect();
        let dx = (numbers[0] - bx + 64.0).rem_euclid(128.0) - 64.0;
        assert!(
            dx.abs() < 0.01 && (numbers[1] - by).abs() < 0.01,
            "{text:?}"
        );
    }
}
