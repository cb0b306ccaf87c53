//! Round trips through `skyrender::output`: EXR and PNG files written, read back and checked,
//! plus the atomic-write and error behaviour.

use std::fs;
use std::path::Path;

use exr::prelude::{AttributeValue, ReadChannels as _, ReadLayers as _, SampleType, Text, Vec2};
use skyrender::output::{write_exr, write_image, write_png, OutputError, RgbImage};

/// A small image with distinctive, non-trivial float values in every pixel.
fn test_image(width: u32, height: u32) -> RgbImage {
    let pixels = (0..width * height)
        .map(|i| {
            let i = i as f32;
            [
                i * 0.173 + 1.0e-3,
                (i * 1.7).sin().abs() * 3.0e4,
                1.0 / (i + 3.0),
            ]
        })
        .collect();
    RgbImage {
        width,
        height,
        pixels,
    }
}

fn metadata() -> Vec<(String, String)> {
    vec![
        (
            "skyrender:scene".to_owned(),
            "[sun]\nelevation_deg = 30.0 # 30°\n".to_owned(),
        ),
        ("skyrender:spp".to_owned(), "64".to_owned()),
    ]
}

/// Names of the entries in `dir`, sorted.
fn dir_entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|entry| entry.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// The 7×5 test image with the test metadata, written as `sky.exr` in `dir`.
fn write_test_exr(dir: &Path) -> (std::path::PathBuf, RgbImage) {
    let path = dir.join("sky.exr");
    let image = test_image(7, 5);
    write_exr(&path, &image, &metadata()).unwrap();
    (path, image)
}

#[test]
fn exr_round_trip_preserves_pixels_and_attributes() {
    let dir = tempfile::tempdir().unwrap();
    let (path, image) = write_test_exr(dir.path());

    let read = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _| vec![[f32::NAN; 3]; resolution.width() * resolution.height()],
            |pixels: &mut Vec<[f32; 3]>, position, (r, g, b, _): (f32, f32, f32, f32)| {
                pixels[position.y() * 7 + position.x()] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(&path)
        .unwrap();

    let layer = &read.layer_data;
    assert_eq!((layer.size.width(), layer.size.height()), (7, 5));
    // Stored as 32-bit floats, so values survive bit for bit.
    assert_eq!(layer.channel_data.pixels, image.pixels);
    let (r, g, b, alpha) = &layer.channel_data.channels;
    for channel in [r, g, b] {
        assert_eq!(channel.sample_type, SampleType::F32, "{channel:?}");
    }
    assert!(alpha.is_none(), "no alpha channel expected");

    let chromaticities = read
        .attributes
        .chromaticities
        .expect("chromaticities attribute");
    assert_eq!(chromaticities.red, Vec2(0.64, 0.33));
    assert_eq!(chromaticities.green, Vec2(0.30, 0.60));
    assert_eq!(chromaticities.blue, Vec2(0.15, 0.06));
    assert_eq!(chromaticities.white, Vec2(0.3127, 0.3290));
    assert_eq!(layer.attributes.white_luminance, Some(1.0));

    for (key, value) in metadata() {
        let attribute = layer
            .attributes
            .other
            .get(&Text::from(key.as_str()))
            .or_else(|| read.attributes.other.get(&Text::from(key.as_str())))
            .unwrap_or_else(|| panic!("metadata attribute {key} missing"));
        let AttributeValue::Text(text) = attribute else {
            panic!("metadata attribute {key} is not text: {attribute:?}");
        };
        assert_eq!(std::str::from_utf8(text.bytes()).unwrap(), value);
    }
}

/// Runs one of the OpenEXR reference library's tools (Debian's `openexr`
/// package, which `.ci/run` installs); its stdout.
fn openexr_tool(tool: &str, args: &[&Path]) -> String {
    let out = std::process::Command::new(tool)
        .args(args)
        .output()
        .unwrap_or_else(|e| {
            panic!("{tool} not runnable ({e}): install Debian's openexr tools (apt-get install openexr)")
        });
    assert!(
        out.status.success(),
        "{tool} {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

#[test]
fn the_reference_openexr_library_reads_our_files() {
    // Another reader than the `exr` crate that wrote the file: the OpenEXR
    // library itself. `exrheader` reads the header; `exrmaketiled` decodes
    // every pixel and writes them out again as a tiled file, which must hold
    // the same values.
    let dir = tempfile::tempdir().unwrap();
    let (path, image) = write_test_exr(dir.path());

    let header = openexr_tool("exrheader", &[&path]);
    for line in [
        "R, 32-bit floating-point",
        "G, 32-bit floating-point",
        "B, 32-bit floating-point",
        "red   (0.64 0.33)",
        "white (0.3127 0.329)",
        "whiteLuminance (type float): 1",
    ] {
        assert!(header.contains(line), "exrheader lacks '{line}':\n{header}");
    }
    for (key, value) in metadata() {
        let attribute = format!("{key} (type string): \"{value}\"");
        assert!(
            header.contains(&attribute),
            "exrheader lacks {attribute}:\n{header}"
        );
    }

    let tiled = dir.path().join("tiled.exr");
    openexr_tool("exrmaketiled", &[&path, &tiled]);
    assert!(openexr_tool("exrheader", &[&tiled]).contains("tiles (type tiledesc)"));
    let read = exr::prelude::read_first_rgba_layer_from_file(
        &tiled,
        |resolution, _| vec![[f32::NAN; 3]; resolution.width() * resolution.height()],
        |pixels: &mut Vec<[f32; 3]>, position, (r, g, b, _): (f32, f32, f32, f32)| {
            pixels[position.y() * 7 + position.x()] = [r, g, b];
        },
    )
    .unwrap();
    assert_eq!(read.layer_data.channel_data.pixels, image.pixels);
}

#[test]
fn png_round_trip_has_right_size_and_tone_mapping() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.PNG");
    let image = RgbImage {
        width: 6,
        height: 4,
        pixels: vec![[100.0; 3]; 24],
    };
    write_image(&path, &image, &metadata(), None).unwrap();

    let decoded = image::open(&path).unwrap();
    assert_eq!((decoded.width(), decoded.height()), (6, 4));
    let rgb = decoded.to_rgb8();
    // Auto exposure puts the uniform image at middle grey: aces(0.18) ≈ 0.267 → sRGB ≈ 141.
    let expected = skyrender::output::tonemap_pixel([0.18; 3], 1.0);
    assert!(
        rgb.pixels().all(|pixel| pixel.0 == expected),
        "{:?}",
        rgb.get_pixel(0, 0)
    );
    assert!((138..=144).contains(&expected[0]), "{expected:?}");

    // An explicit exposure is honoured: +30 EV over 100 cd/m² is white.
    write_png(&path, &image, Some(30.0), &[]).unwrap();
    let rgb = image::open(&path).unwrap().to_rgb8();
    assert!(rgb.pixels().all(|pixel| pixel.0 == [255; 3]));
}

#[test]
fn missing_directory_is_an_error_and_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("does-not-exist").join("sky.exr");
    let error = write_image(&path, &test_image(2, 2), &[], None).unwrap_err();
    assert!(matches!(error, OutputError::Io { .. }), "{error}");
    let message = error.to_string();
    assert!(message.contains(&path.display().to_string()), "{message}");
    assert!(!message.contains('\n'), "{message}");
    assert!(!path.exists());
    assert!(dir_entries(dir.path()).is_empty());

    let png = dir.path().join("does-not-exist").join("sky.png");
    assert!(write_image(&png, &test_image(2, 2), &[], None).is_err());
    assert!(dir_entries(dir.path()).is_empty());
}

#[test]
fn unsupported_extension_is_rejected_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.jpg");
    let error = write_image(&path, &test_image(2, 2), &[], None).unwrap_err();
    assert!(matches!(error, OutputError::UnsupportedExtension { .. }));
    let message = error.to_string();
    assert!(message.contains("extension"), "{message}");
    assert!(message.contains(".jpg"), "{message}");
    assert!(message.contains(&path.display().to_string()), "{message}");
    assert!(dir_entries(dir.path()).is_empty());

    // Checked even when the directory does not exist.
    let nowhere = dir.path().join("missing").join("sky.tiff");
    let error = write_image(&nowhere, &test_image(2, 2), &[], None).unwrap_err();
    assert!(matches!(error, OutputError::UnsupportedExtension { .. }));
}

#[test]
fn overwriting_replaces_file_and_leaves_no_temp_files() {
    let dir = tempfile::tempdir().unwrap();
    let exr_path = dir.path().join("sky.exr");
    let png_path = dir.path().join("sky.png");
    fs::write(&exr_path, b"old content").unwrap();
    fs::write(&png_path, b"old content").unwrap();

    write_image(&exr_path, &test_image(3, 2), &metadata(), None).unwrap();
    write_image(&png_path, &test_image(3, 2), &[], Some(-10.0)).unwrap();

    let exr_bytes = fs::read(&exr_path).unwrap();
    assert_eq!(
        &exr_bytes[..4],
        &[0x76, 0x2f, 0x31, 0x01],
        "EXR magic number"
    );
    let png_bytes = fs::read(&png_path).unwrap();
    assert_eq!(&png_bytes[..8], b"\x89PNG\r\n\x1a\n");
    assert_eq!(dir_entries(dir.path()), ["sky.exr", "sky.png"]);

    // A failing write keeps the previous file intact and cleans up.
    let bad = RgbImage {
        width: 3,
        height: 2,
        pixels: vec![[0.0; 3]; 5],
    };
    assert!(write_image(&exr_path, &bad, &[], None).is_err());
    assert_eq!(fs::read(&exr_path).unwrap(), exr_bytes);
    let reserved = vec![("chromaticities".to_owned(), "x".to_owned())];
    let error = write_exr(&exr_path, &test_image(3, 2), &reserved).unwrap_err();
    assert!(matches!(error, OutputError::Exr { .. }), "{error}");
    assert_eq!(fs::read(&exr_path).unwrap(), exr_bytes);
    assert_eq!(dir_entries(dir.path()), ["sky.exr", "sky.png"]);
}

#[cfg(unix)]
#[test]
fn written_files_get_default_permissions() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("sky.exr");
    write_exr(&path, &test_image(2, 2), &[]).unwrap();
    let reference = dir.path().join("reference");
    fs::File::create(&reference).unwrap();
    // Like File::create (0o666 minus umask), not tempfile's owner-only 0o600.
    let mode = |path: &Path| fs::metadata(path).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&path), mode(&reference));
}

#[cfg(unix)]
#[test]
fn overwriting_keeps_the_files_permissions_and_replaces_links() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = tempfile::tempdir().unwrap();
    let mode = |path: &Path| fs::metadata(path).unwrap().permissions().mode() & 0o777;
    // A replaced file keeps its mode (an execute bit never comes from the
    // default 0o666 minus the umask).
    let path = dir.path().join("sky.exr");
    fs::write(&path, b"old").unwrap();
    fs::set_permissions(&path, fs::Permissions::from_mode(0o744)).unwrap();
    write_exr(&path, &test_image(2, 2), &[]).unwrap();
    assert_eq!(mode(&path), 0o744);
    assert_ne!(fs::read(&path).unwrap(), b"old");
    // A link is replaced by the new file, as `sed -i` does; the file it
    // pointed to is left as it was.
    let real = dir.path().join("real.png");
    fs::write(&real, b"old").unwrap();
    let link = dir.path().join("latest.png");
    std::os::unix::fs::symlink("real.png", &link).unwrap();
    write_png(&link, &test_image(2, 2), None, &[]).unwrap();
    assert!(fs::symlink_metadata(&link).unwrap().is_file());
    assert_eq!(&fs::read(&link).unwrap()[..4], b"\x89PNG");
    assert_eq!(fs::read(&real).unwrap(), b"old");
    assert_eq!(
        dir_entries(dir.path()),
        ["latest.png", "real.png", "sky.exr"]
    );
}

#[test]
fn paths_that_cannot_name_the_output_are_refused_before_any_work() {
    use skyrender::output::check_writable;
    let dir = tempfile::tempdir().unwrap();
    let refused = |path: &Path, reason: &str| {
        let message = check_writable(path).unwrap_err();
        assert!(message.contains(reason), "{message}");
        assert!(
            !message.contains(".skyrender-"),
            "temp file named: {message}"
        );
    };
    refused(&dir.path().join("sky.exr/"), "names a directory");
    refused(dir.path(), "is a directory");
    let long = dir.path().join(format!("{}.exr", "a".repeat(300)));
    refused(&long, "the file name is 304 ");
    refused(&long, "long (at most 255)");
    refused(
        &dir.path().join("missing").join("sky.exr"),
        &format!("directory '{}'", dir.path().join("missing").display()),
    );
    assert!(check_writable(&dir.path().join(format!("{}.exr", "a".repeat(251)))).is_ok());
    assert!(dir_entries(dir.path()).is_empty());
}
