//! Writing rendered images to disk: scene-referred OpenEXR and display-referred PNG.
//!
//! # Pixel convention
//!
//! An [`RgbImage`] holds *linear* RGB with Rec.709 / sRGB primaries and a D65 white point,
//! scaled so that the Rec.709 luminance `Y = 0.2126 R + 0.7152 G + 0.0722 B` is in cd/m².
//!
//! # EXR conventions
//!
//! [`write_exr`] stores the pixels unchanged (no exposure, no tone curve):
//!
//! - three 32-bit float channels `R`, `G`, `B` (no alpha), scanlines, lossless ZIP compression;
//! - the standard `chromaticities` attribute: Rec.709 primaries (0.64, 0.33), (0.30, 0.60),
//!   (0.15, 0.06) and D65 white (0.3127, 0.3290);
//! - the standard `whiteLuminance` attribute set to 1.0, i.e. the RGB value (1, 1, 1) has a
//!   luminance of 1 cd/m², so pixel values are absolute photometric quantities;
//! - `software` = `skyrender <version>`;
//! - the pair `("envmap", "latlong")` (or `"cube"`) as the standard `envmap` attribute, which
//!   tells other tools the image is an environment map;
//! - every other metadata pair `(key, value)` as a custom `string` attribute named `key`
//!   (e.g. `skyrender:scene` holding the scene TOML, `skyrender:spp` holding `"64"`). EXR
//!   strings are byte strings; values are stored as their UTF-8 bytes. (The `exr` crate's
//!   `Text: Display` decodes bytes as Latin-1, so decode `Text::bytes()` as UTF-8 when reading.)
//! - the header's attributes in byte order of their names, so equal images with equal
//!   metadata are equal files.
//!
//! # Tone curve (PNG output and the preview)
//!
//! Display values are computed per pixel as
//!
//! ```text
//! peak  = max(r, g, b)                                       (negative channels as 0)
//! srgb8 = quantise(oetf(aces(peak * 2^exposure_ev) * rgb / peak))   (per channel)
//! ```
//!
//! - **Exposure.** `exposure_ev` is a plain base-2 scale exponent with no reference constant:
//!   a luminance of `L` cd/m² is shown as a linear display value of `L * 2^exposure_ev` before
//!   the curve. `exposure_ev = 0` therefore maps 1 cd/m² to display value 1.0 (which the curve
//!   then compresses), and each +1 doubles the brightness. [`auto_exposure_ev`] chooses the EV
//!   that maps the log-average (geometric mean) luminance to middle grey 0.18, the "key value"
//!   of Reinhard et al., "Photographic Tone Reproduction for Digital Images", SIGGRAPH 2002.
//! - **Curve.** The ACES filmic fit by K. Narkowicz, "ACES Filmic Tone Mapping Curve"
//!   (<https://knarkowicz.wordpress.com/2016/01/06/aces-filmic-tone-mapping-curve/>):
//!   `aces(x) = clamp(x (2.51 x + 0.03) / (x (2.43 x + 0.59) + 0.14), 0, 1)`. It has a toe,
//!   maps middle grey 0.18 to about 0.27 and reaches white at x ≈ 7.2, i.e. about 5.3 stops
//!   above middle grey. It is applied to the pixel's largest channel and the others keep their
//!   ratios to it, so the curve compresses brightness but keeps hue and saturation: applied per
//!   channel it would turn every bright colour toward white-yellow — a sunset's orange sun and
//!   glow, whose linear Rec.709 ratios are about 1 : 0.3 : 0.02, would show pale yellow.
//! - **Encoding.** The sRGB OETF of IEC 61966-2-1 (`12.92 v` below 0.0031308, otherwise
//!   `1.055 v^(1/2.4) − 0.055`), then rounding to 8 bits.
//! - Pixels with a NaN or infinite channel are shown black; negative channels are clipped to 0.
//!
//! # Atomic writes
//!
//! Files are first written to a temporary file in the target's directory (unnamed on Linux),
//! flushed and synced, then put in the target's place in one step ([`atomic`]). A failed or
//! interrupted write leaves the target untouched (absent, or the previous file) and no
//! temporary file.

pub mod atomic;
pub mod channels;
pub mod spectral;
pub mod stdout;

use std::collections::HashSet;
use std::fs::File;
use std::io::{self, BufRead, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use exr::meta::attribute::{Chromaticities, EnvironmentMap};
use exr::prelude::{
    AttributeValue, Encoding, Image as ExrImage, Layer, LayerAttributes, SpecificChannels, Text,
    Vec2, WritableImage,
};
use rayon::prelude::*;

/// Linear Rec.709 RGB image, row-major, top row first; values scaled so that
/// Y = luminance in cd/m².
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// `width * height` pixels, row-major, top row first.
    pub pixels: Vec<[f32; 3]>,
}

/// Why writing an output image failed. Every message names the target path.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The path's extension is not one of the supported formats.
    #[error("unsupported output extension '.{extension}' for '{}' (valid: .exr, .png)", .path.display())]
    UnsupportedExtension {
        /// Target path.
        path: PathBuf,
        /// The extension found, without the dot.
        extension: String,
    },
    /// The path has no extension, so the format cannot be chosen.
    #[error("output path '{}' has no file extension (valid: .exr, .png)", .path.display())]
    MissingExtension {
        /// Target path.
        path: PathBuf,
    },
    /// The image's pixel buffer does not match its dimensions, or it is empty.
    #[error("cannot write output '{}': {reason}", .path.display())]
    InvalidImage {
        /// Target path.
        path: PathBuf,
        /// What is wrong with the image.
        reason: String,
    },
    /// A metadata key cannot be stored as an EXR attribute name.
    #[error("cannot write output '{}': invalid metadata key {key:?}: {reason}", .path.display())]
    InvalidMetadata {
        /// Target path.
        path: PathBuf,
        /// The offending key.
        key: String,
        /// Why it is invalid.
        reason: &'static str,
    },
    /// Creating, writing, syncing or renaming the file failed.
    #[error("cannot write output '{}': {source}", .path.display())]
    Io {
        /// Target path.
        path: PathBuf,
        /// Underlying I/O error.
        source: io::Error,
    },
    /// The EXR encoder failed (this includes I/O errors raised while encoding).
    #[error("cannot write EXR output '{}': {source}", .path.display())]
    Exr {
        /// Target path.
        path: PathBuf,
        /// Underlying encoder error.
        source: exr::error::Error,
    },
    /// The PNG encoder failed (this includes I/O errors raised while encoding).
    #[error("cannot write PNG output '{}': {source}", .path.display())]
    Png {
        /// Target path.
        path: PathBuf,
        /// Underlying encoder error.
        source: png::EncodingError,
    },
}

/// Output file format, chosen from the file extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    /// Scene-referred 32-bit float OpenEXR.
    Exr,
    /// Tone-mapped 8-bit sRGB PNG.
    Png,
}

impl OutputFormat {
    /// Format for `path`'s extension (`.exr` or `.png`, case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self, OutputError> {
        let Some(extension) = path.extension() else {
            return Err(OutputError::MissingExtension {
                path: path.to_path_buf(),
            });
        };
        let extension = extension.to_string_lossy();
        if extension.eq_ignore_ascii_case("exr") {
            Ok(Self::Exr)
        } else if extension.eq_ignore_ascii_case("png") {
            Ok(Self::Png)
        } else {
            Err(OutputError::UnsupportedExtension {
                path: path.to_path_buf(),
                extension: extension.into_owned(),
            })
        }
    }
}

/// Writes `image` to `path`, choosing the format from the extension (see [`OutputFormat`]).
///
/// `metadata` goes into the EXR header or the PNG's text chunks; `exposure_ev` is used by PNG
/// only (`None` = [`auto_exposure_ev`]).
/// The extension is checked before anything is written.
pub fn write_image(
    path: &Path,
    image: &RgbImage,
    metadata: &[(String, String)],
    exposure_ev: Option<f32>,
) -> Result<(), OutputError> {
    match OutputFormat::from_path(path)? {
        OutputFormat::Exr => write_exr(path, image, metadata),
        OutputFormat::Png => write_png(path, image, exposure_ev, metadata),
    }
}

/// Rec.709 / sRGB primaries with a D65 white point.
const REC709_CHROMATICITIES: Chromaticities = Chromaticities {
    red: Vec2(0.64, 0.33),
    green: Vec2(0.30, 0.60),
    blue: Vec2(0.15, 0.06),
    white: Vec2(0.3127, 0.3290),
};

/// Writes `image` unchanged as a 32-bit float RGB OpenEXR file, atomically.
///
/// See the module documentation for the header attributes written. Metadata keys must be
/// non-empty, unique, free of NUL bytes and not names of standard EXR attributes.
/// The extension of `path` is not checked.
pub fn write_exr(
    path: &Path,
    image: &RgbImage,
    metadata: &[(String, String)],
) -> Result<(), OutputError> {
    let (width, height) = checked_size(path, image)?;
    let layer_attributes = exr_layer_attributes(path, metadata)?;

    let pixels = &image.pixels;
    let channels = SpecificChannels::rgb(|position: Vec2<usize>| {
        let [r, g, b] = pixels[position.y() * width + position.x()];
        (r, g, b)
    });
    let layer = Layer::new(
        (width, height),
        layer_attributes,
        Encoding::SMALL_LOSSLESS,
        channels,
    );
    let mut exr_image = ExrImage::from_layer(layer);
    exr_image.attributes.chromaticities = Some(REC709_CHROMATICITIES);

    write_atomically(path, |writer| {
        exr_image
            .write()
            .to_buffered(&mut *writer)
            .map_err(|source| OutputError::Exr {
                path: path.to_path_buf(),
                source,
            })?;
        finish_exr(path, writer)
    })
}

/// The header attributes of every EXR layer written here: `whiteLuminance`
/// 1, `software`, and each metadata pair as a text attribute (keys
/// non-empty, unique, free of NUL bytes).
fn exr_layer_attributes(
    path: &Path,
    metadata: &[(String, String)],
) -> Result<LayerAttributes, OutputError> {
    let mut layer_attributes = LayerAttributes {
        white_luminance: Some(1.0),
        software_name: Some(Text::from(concat!("skyrender ", env!("CARGO_PKG_VERSION")))),
        ..LayerAttributes::default()
    };
    let mut seen = HashSet::with_capacity(metadata.len());
    for (key, value) in metadata {
        let reason = if key.is_empty() {
            Some("empty")
        } else if key.contains('\0') {
            Some("contains a NUL byte")
        } else if !seen.insert(key.as_str()) {
            Some("duplicate")
        } else {
            None
        };
        if let Some(reason) = reason {
            return Err(OutputError::InvalidMetadata {
                path: path.to_path_buf(),
                key: key.clone(),
                reason,
            });
        }
        // The standard `envmap` attribute is an enum, not text: a
        // lat-long map is how other tools know an equirect panorama.
        match (key.as_str(), value.as_str()) {
            ("envmap", "latlong") => {
                layer_attributes.environment_map = Some(EnvironmentMap::LatitudeLongitude);
            }
            ("envmap", "cube") => layer_attributes.environment_map = Some(EnvironmentMap::Cube),
            _ => {
                layer_attributes.other.insert(
                    Text::from_slice_unchecked(key.as_bytes()),
                    AttributeValue::Text(Text::from_slice_unchecked(value.as_bytes())),
                );
            }
        }
    }
    Ok(layer_attributes)
}

/// Flushes an EXR just encoded into `writer` and sorts its header
/// ([`sort_header_attributes`]).
fn finish_exr(path: &Path, writer: &mut BufWriter<&mut File>) -> Result<(), OutputError> {
    writer.flush().map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    sort_header_attributes(writer.get_mut()).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Rewrites the header of the single-part EXR file in `file` with its
/// attributes sorted by name. The `exr` crate writes custom attributes in
/// the order of a `HashMap` with random keys, so the same image came out as
/// different bytes on every run; sorted, the same scene and seed give the
/// same file. The header keeps its length, so the offset table after it
/// stays valid. Multi-part files (not written here) are left alone.
fn sort_header_attributes(file: &mut File) -> io::Result<()> {
    /// The version field's multi-part flag (OpenEXR file layout, "Version Field").
    const MULTI_PART: u32 = 0x1000;
    let invalid =
        |what: &str| io::Error::new(io::ErrorKind::InvalidData, format!("EXR header: {what}"));
    file.seek(SeekFrom::Start(0))?;
    let mut reader = io::BufReader::new(&mut *file);
    let mut start = [0u8; 8];
    reader.read_exact(&mut start)?;
    if start[..4] != [0x76, 0x2f, 0x31, 0x01] {
        return Err(invalid("not an OpenEXR file"));
    }
    if u32::from_le_bytes([start[4], start[5], start[6], start[7]]) & MULTI_PART != 0 {
        return Ok(());
    }
    // Each attribute: name NUL, type NUL, size (i32, little-endian), value.
    let mut attributes: Vec<(Vec<u8>, Vec<u8>)> = Vec::new();
    loop {
        let mut name = Vec::new();
        reader.read_until(0, &mut name)?;
        if name.last() != Some(&0) {
            return Err(invalid("ends inside an attribute name"));
        }
        if name.len() == 1 {
            break; // the header's terminating NUL
        }
        let mut record = name.clone();
        reader.read_until(0, &mut record)?;
        let mut size = [0u8; 4];
        reader.read_exact(&mut size)?;
        record.extend_from_slice(&size);
        let size =
            usize::try_from(i32::from_le_bytes(size)).map_err(|_| invalid("negative size"))?;
        let value_start = record.len();
        record.resize(value_start + size, 0);
        reader.read_exact(&mut record[value_start..])?;
        attributes.push((name, record));
    }
    drop(reader);
    attributes.sort_by(|a, b| a.0.cmp(&b.0));
    let mut header = start.to_vec();
    for (_, record) in attributes {
        header.extend_from_slice(&record);
    }
    header.push(0);
    file.seek(SeekFrom::Start(0))?;
    file.write_all(&header)
}

/// Writes `image` tone-mapped to 8-bit sRGB PNG, atomically.
///
/// `exposure_ev` as described in the module documentation; `None` uses [`auto_exposure_ev`].
/// The file says it is sRGB (an `sRGB` chunk) and carries `metadata` and the exposure used
/// (`skyrender:exposure_ev`) as text chunks ([`encode_png`]).
/// The extension of `path` is not checked.
pub fn write_png(
    path: &Path,
    image: &RgbImage,
    exposure_ev: Option<f32>,
    metadata: &[(String, String)],
) -> Result<(), OutputError> {
    checked_size(path, image)?;
    let exposure_ev = exposure_ev.unwrap_or_else(|| auto_exposure_ev(image));
    let srgb = tonemap_to_srgb8(image, exposure_ev);
    let mut text = metadata.to_vec();
    text.push(("skyrender:exposure_ev".into(), format!("{exposure_ev:.4}")));
    write_atomically(path, |writer| {
        encode_png(
            writer,
            image.width,
            image.height,
            srgb.as_flattened(),
            png::ColorType::Rgb,
            &text,
        )
        .map_err(|source| OutputError::Png {
            path: path.to_path_buf(),
            source,
        })
    })
}

/// Encodes 8-bit sRGB pixels (`Rgb` or `Rgba`, row-major) as a PNG with an
/// `sRGB` chunk (perceptual intent, so viewers need no gamma guess),
/// `Software`, and each `(key, value)` of `text` as an international text
/// chunk (`iTXt`, UTF-8: a scene's TOML may hold any text).
pub fn encode_png(
    writer: impl Write,
    width: u32,
    height: u32,
    pixels: &[u8],
    color: png::ColorType,
    text: &[(String, String)],
) -> Result<(), png::EncodingError> {
    let mut encoder = png::Encoder::new(writer, width, height);
    encoder.set_color(color);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    encoder.add_text_chunk(
        "Software".into(),
        concat!("skyrender ", env!("CARGO_PKG_VERSION")).into(),
    )?;
    for (key, value) in text {
        encoder.add_itxt_chunk(key.clone(), value.clone())?;
    }
    let mut writer = encoder.write_header()?;
    writer.write_image_data(pixels)?;
    writer.finish()
}

/// Checks that the image is non-empty and its buffer matches its size; returns (width, height).
fn checked_size(path: &Path, image: &RgbImage) -> Result<(usize, usize), OutputError> {
    let width = image.width as usize;
    let height = image.height as usize;
    let reason = if width == 0 || height == 0 {
        format!("image is empty ({width}x{height})")
    } else if width.checked_mul(height) != Some(image.pixels.len()) {
        format!(
            "image is {width}x{height} but has {} pixels instead of {}",
            image.pixels.len(),
            width.saturating_mul(height)
        )
    } else {
        return Ok((width, height));
    };
    Err(OutputError::InvalidImage {
        path: path.to_path_buf(),
        reason,
    })
}

/// Writes via `write` into a temporary file beside `path`, then renames it over `path`
/// ([`replace_file`]).
fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), OutputError>,
) -> Result<(), OutputError> {
    let io_error = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    replace_file(path, io_error, write)
}

/// Replaces the file at `path` with what `write` writes, atomically: into a
/// temporary file beside it ([`atomic::PendingFile`]: unnamed on Linux),
/// synced, then put in place in one step. On error the temporary file is
/// gone and `path` is left as it was; `io_error` turns I/O errors into the
/// caller's. A regular file replaced keeps its permissions (Unix); a
/// symbolic link at `path` is replaced by the new file, as `sed -i` and
/// most atomic writers do, and what it pointed to is left alone.
pub fn replace_file<E>(
    path: &Path,
    io_error: impl Fn(io::Error) -> E,
    write: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), E>,
) -> Result<(), E> {
    let directory = parent_dir(path);
    // Report a missing directory plainly, rather than via the temp file's name.
    std::fs::metadata(directory).map_err(&io_error)?;
    let mut temp = atomic::PendingFile::create_in(directory).map_err(&io_error)?;
    {
        let mut writer = BufWriter::new(temp.file_mut());
        write(&mut writer)?;
        writer.flush().map_err(&io_error)?;
    }
    // Unix only: an open file's mode does not stop its writes there, but a
    // read-only file on Windows could not be renamed over its target.
    #[cfg(unix)]
    if let Ok(existing) = std::fs::symlink_metadata(path) {
        if existing.is_file() {
            temp.file()
                .set_permissions(existing.permissions())
                .map_err(&io_error)?;
        }
    }
    temp.file().sync_all().map_err(&io_error)?;
    temp.commit(path).map_err(&io_error)
}

/// Middle grey: the display value the log-average luminance is mapped to (Reinhard's key).
const MIDDLE_GREY: f64 = 0.18;
/// The directory a file at `path` goes into (`.` for a bare file name).
pub fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(parent) if !parent.as_os_str().is_empty() => parent,
        _ => Path::new("."),
    }
}

/// Longest file name most file systems take (`NAME_MAX`: bytes on Linux
/// and macOS; UTF-16 units on Windows' NTFS).
const MAX_FILE_NAME: usize = 255;

/// The unit of [`MAX_FILE_NAME`].
const FILE_NAME_UNIT: &str = if cfg!(windows) {
    "UTF-16 units"
} else {
    "bytes"
};

/// Length of a file name in the units [`MAX_FILE_NAME`] counts.
fn file_name_length(name: &std::ffi::OsStr) -> usize {
    #[cfg(windows)]
    return std::os::windows::ffi::OsStrExt::encode_wide(name).count();
    #[cfg(not(windows))]
    name.len()
}

/// Checks, before any work, that a file can be written atomically at
/// `path`: it names a file (not a directory, no trailing separator, a name
/// of at most 255 bytes, or UTF-16 units on Windows) and a temporary file can be created beside it.
/// The error names the path and the reason.
pub fn check_writable(path: &Path) -> Result<(), String> {
    let fail = |reason: String| Err(format!("cannot write '{}': {reason}", path.display()));
    if path.is_dir() {
        return fail("it is a directory".into());
    }
    if path
        .as_os_str()
        .to_string_lossy()
        .ends_with(std::path::is_separator)
    {
        return fail("it ends with a separator, so it names a directory".into());
    }
    let Some(name) = path.file_name() else {
        return fail("it names no file".into());
    };
    let length = file_name_length(name);
    if length > MAX_FILE_NAME {
        return fail(format!(
            "the file name is {length} {FILE_NAME_UNIT} long (at most {MAX_FILE_NAME})"
        ));
    }
    let directory = parent_dir(path);
    if let Err(e) = std::fs::metadata(directory) {
        return fail(format!("directory '{}': {e}", directory.display()));
    }
    atomic::PendingFile::create_in(directory)
        .map(drop)
        .map_err(|e| {
            format!(
                "cannot write '{}': cannot create a file in '{}' ({})",
                path.display(),
                directory.display(),
                e.kind()
            )
        })
}

/// Fraction of the brightest valid pixels ignored by [`auto_exposure_ev`] (e.g. the sun).
const AUTO_EXPOSURE_OUTLIER_FRACTION: f64 = 0.001;
/// Luminances more than 16 stops below the median are raised to that level before averaging
/// logs, so a few nearly black pixels cannot drag the average down without limit.
const AUTO_EXPOSURE_FLOOR_BELOW_MEDIAN: f32 = 1.0 / 65_536.0;

/// Rec.709 luminance of a linear RGB triple.
fn luminance(rgb: [f32; 3]) -> f32 {
    0.2126 * rgb[0] + 0.7152 * rgb[1] + 0.0722 * rgb[2]
}

/// Exposure (EV, see the module documentation) that maps the log-average luminance to 0.18.
///
/// Pixels with a non-finite channel and pixels with luminance ≤ 0 (e.g. black ground) are
/// ignored, as are the brightest 0.1 % of the rest (e.g. the solar disc); luminances more than
/// 16 stops below the median of the remainder count as 16 stops below it. Returns 0 when no
/// pixel is usable.
pub fn auto_exposure_ev(image: &RgbImage) -> f32 {
    let mut luminances: Vec<f32> = image
        .pixels
        .iter()
        .filter(|rgb| rgb.iter().all(|channel| channel.is_finite()))
        .map(|&rgb| luminance(rgb))
        .filter(|&y| y > 0.0 && y.is_finite())
        .collect();

    let outliers = (luminances.len() as f64 * AUTO_EXPOSURE_OUTLIER_FRACTION) as usize;
    if outliers > 0 {
        let kept = luminances.len() - outliers;
        luminances.select_nth_unstable_by(kept, f32::total_cmp);
        luminances.truncate(kept);
    }
    if luminances.is_empty() {
        return 0.0;
    }

    let middle = luminances.len() / 2;
    let (_, &mut median, _) = luminances.select_nth_unstable_by(middle, f32::total_cmp);
    let floor = median * AUTO_EXPOSURE_FLOOR_BELOW_MEDIAN;
    let sum_log2: f64 = luminances
        .iter()
        .map(|&y| f64::from(y.max(floor)).log2())
        .sum();
    let log2_average = sum_log2 / luminances.len() as f64;
    (MIDDLE_GREY.log2() - log2_average) as f32
}

/// Tone-maps the whole image to 8-bit sRGB (same layout as `image.pixels`); see
/// [`tonemap_pixel`].
pub fn tonemap_to_srgb8(image: &RgbImage, exposure_ev: f32) -> Vec<[u8; 3]> {
    let exposure_scale = exposure_ev.exp2();
    image
        .pixels
        .par_iter()
        .map(|&rgb| tonemap_pixel(rgb, exposure_scale))
        .collect()
}

/// Tone-maps one linear RGB pixel to 8-bit sRGB.
///
/// `exposure_scale` is the linear multiplier `2^exposure_ev`. A pixel with any NaN or
/// infinite channel becomes black; negative channels are clipped to 0.
pub fn tonemap_pixel(rgb: [f32; 3], exposure_scale: f32) -> [u8; 3] {
    if !rgb.iter().all(|channel| channel.is_finite()) {
        return [0; 3];
    }
    let rgb = rgb.map(|channel| channel.max(0.0));
    let peak = rgb[0].max(rgb[1]).max(rgb[2]);
    if peak <= 0.0 {
        return [0; 3];
    }
    // The curve on the largest channel; the ratios (hue, saturation) stay.
    let display_peak = aces_filmic(peak * exposure_scale);
    rgb.map(|channel| quantize_u8(srgb_oetf(display_peak * (channel / peak))))
}

/// Narkowicz's ACES filmic fit, clamped to [0, 1]; NaN and negative inputs give 0.
fn aces_filmic(x: f32) -> f32 {
    // The curve exceeds 1 from x ≈ 7.24 on; capping the input keeps +∞ from giving ∞/∞.
    let x = if x > 0.0 { x.min(1.0e4) } else { 0.0 };
    let mapped = (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14);
    mapped.clamp(0.0, 1.0)
}

/// sRGB opto-electronic transfer function (IEC 61966-2-1), linear → encoded, for v in [0, 1].
pub fn srgb_oetf(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

/// Rounds an encoded value in [0, 1] to 8 bits (clamping; NaN gives 0).
pub fn quantize_u8(encoded: f32) -> u8 {
    // `as` saturates and maps NaN to 0.
    (encoded.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    fn uniform(width: u32, height: u32, rgb: [f32; 3]) -> RgbImage {
        RgbImage {
            width,
            height,
            pixels: vec![rgb; (width * height) as usize],
        }
    }

    #[test]
    fn srgb_oetf_known_values() {
        assert_eq!(quantize_u8(srgb_oetf(0.0)), 0);
        assert_eq!(quantize_u8(srgb_oetf(1.0)), 255);
        assert!((srgb_oetf(1.0) - 1.0).abs() < 1e-6);
        // 18 % grey encodes to ≈ 0.4614 (118/255).
        assert!((srgb_oetf(0.18) - 0.461_356).abs() < 1e-4);
        assert_eq!(quantize_u8(srgb_oetf(0.18)), 118);
    }

    #[test]
    fn srgb_oetf_is_continuous_at_breakpoint() {
        let below = srgb_oetf(0.003_130_8);
        let above = srgb_oetf(0.003_130_8_f32.next_up());
        assert!((below - 0.040_449_936).abs() < 1e-6, "{below}");
        assert!((above - below).abs() < 1e-5, "{below} vs {above}");
    }

    #[test]
    fn tone_curve_is_monotone_and_bounded() {
        let mut previous = aces_filmic(0.0);
        assert_eq!(previous, 0.0);
        for i in 1..=20_000 {
            let x = i as f32 * 0.001;
            let y = aces_filmic(x);
            assert!(y >= previous, "not monotone at {x}: {previous} > {y}");
            assert!((0.0..=1.0).contains(&y));
            previous = y;
        }
        assert_eq!(previous, 1.0);
        // Middle grey lands at about 0.267.
        assert!((aces_filmic(0.18) - 0.266_9).abs() < 1e-3);
    }

    #[test]
    fn tonemap_keeps_the_hue_of_bright_colours() {
        // A sunset sun's linear ratios, far above white: the largest channel
        // saturates, the others keep their ratios (orange, not yellow-white).
        let [r, g, b] = tonemap_pixel([1.0, 0.33, 0.02], 1.0e4);
        assert_eq!(r, 255);
        assert_eq!(g, quantize_u8(srgb_oetf(0.33)));
        assert_eq!(b, quantize_u8(srgb_oetf(0.02)));
        // Grey stays grey at any exposure.
        for scale in [0.01, 1.0, 100.0] {
            let [r, g, b] = tonemap_pixel([0.5; 3], scale);
            assert!(r == g && g == b);
        }
    }

    #[test]
    fn tonemap_pixel_handles_non_finite_and_negative_input() {
        assert_eq!(tonemap_pixel([f32::NAN, 1.0, 1.0], 1.0), [0, 0, 0]);
        assert_eq!(tonemap_pixel([f32::INFINITY, 1.0, 1.0], 1.0), [0, 0, 0]);
        assert_eq!(tonemap_pixel([1.0, f32::NEG_INFINITY, 1.0], 1.0), [0, 0, 0]);
        assert_eq!(tonemap_pixel([-1.0, 0.0, 1.0e30], 1.0e30), [0, 0, 255]);
        assert_eq!(tonemap_pixel([1.0, 1.0, 1.0], f32::NAN), [0, 0, 0]);
        assert_eq!(tonemap_pixel([1.0e6, 1.0e6, 1.0e6], 1.0), [255, 255, 255]);
    }

    #[test]
    fn auto_exposure_maps_uniform_luminance_to_middle_grey() {
        for luminance_cd_m2 in [1.0e-4_f32, 0.18, 1.0, 5_000.0, 1.6e9] {
            let image = uniform(50, 40, [luminance_cd_m2; 3]);
            let exposure_ev = auto_exposure_ev(&image);
            let mapped = luminance_cd_m2 * exposure_ev.exp2();
            assert!(
                (mapped - 0.18).abs() < 1e-4,
                "L = {luminance_cd_m2}: {mapped}"
            );
        }
    }

    #[test]
    fn auto_exposure_ignores_invalid_pixels_and_outliers() {
        let mut image = uniform(100, 100, [2.0; 3]);
        image.pixels[0] = [f32::NAN; 3];
        image.pixels[1] = [f32::INFINITY, 0.0, 0.0];
        image.pixels[2] = [0.0; 3];
        image.pixels[3] = [-5.0; 3];
        // 9 of the 9 996 valid pixels (≤ 0.1 %): a sun-like outlier.
        for pixel in &mut image.pixels[10..19] {
            *pixel = [1.0e9; 3];
        }
        let mapped = 2.0 * auto_exposure_ev(&image).exp2();
        assert!((mapped - 0.18).abs() < 1e-4, "{mapped}");
    }

    #[test]
    fn auto_exposure_limits_the_pull_of_nearly_black_pixels() {
        // A quarter of the pixels at 1e-30 cd/m² count as 16 stops below the median:
        // the log-average drops by exactly 4 stops.
        // (Fewer than 1 000 pixels, so no outliers are dropped.)
        let mut image = uniform(20, 20, [1.0; 3]);
        for pixel in &mut image.pixels[..100] {
            *pixel = [1.0e-30; 3];
        }
        let expected_ev = 0.18_f32.log2() + 4.0;
        let exposure_ev = auto_exposure_ev(&image);
        assert!(
            (exposure_ev - expected_ev).abs() < 1e-4,
            "{exposure_ev} vs {expected_ev}"
        );
    }

    #[test]
    fn auto_exposure_of_unusable_image_is_zero() {
        assert_eq!(auto_exposure_ev(&uniform(3, 3, [0.0; 3])), 0.0);
        assert_eq!(auto_exposure_ev(&uniform(3, 3, [f32::NAN; 3])), 0.0);
        assert_eq!(
            auto_exposure_ev(&RgbImage {
                width: 0,
                height: 0,
                pixels: vec![]
            }),
            0.0
        );
    }

    #[test]
    fn extension_parsing() {
        assert_eq!(
            OutputFormat::from_path(Path::new("a/sky.exr")).unwrap(),
            OutputFormat::Exr
        );
        assert_eq!(
            OutputFormat::from_path(Path::new("SKY.EXR")).unwrap(),
            OutputFormat::Exr
        );
        assert_eq!(
            OutputFormat::from_path(Path::new("sky.Png")).unwrap(),
            OutputFormat::Png
        );

        let error = OutputFormat::from_path(Path::new("out/sky.jpg")).unwrap_err();
        assert!(matches!(error, OutputError::UnsupportedExtension { .. }));
        assert_eq!(
            error.to_string(),
            "unsupported output extension '.jpg' for 'out/sky.jpg' (valid: .exr, .png)"
        );

        let error = OutputFormat::from_path(Path::new("out/sky")).unwrap_err();
        assert!(matches!(error, OutputError::MissingExtension { .. }));
        assert!(error.to_string().contains("extension"));
        assert!(error.to_string().contains("out/sky"));

        assert!(OutputFormat::from_path(Path::new("sky.exr.tmp")).is_err());
    }

    #[test]
    fn equal_images_with_equal_metadata_are_equal_files() {
        // The exr crate orders custom attributes by a randomly keyed HashMap:
        // with six of them, unsorted headers differ in most writes.
        let dir = tempfile::tempdir().unwrap();
        let image = uniform(5, 3, [0.25, 0.5, 1.0]);
        let metadata: Vec<(String, String)> = ["f", "b", "e", "a", "d", "c"]
            .iter()
            .map(|k| (format!("skyrender:{k}"), format!("value of {k}")))
            .collect();
        let paths: Vec<_> = (0..4)
            .map(|i| dir.path().join(format!("{i}.exr")))
            .collect();
        for path in &paths {
            write_exr(path, &image, &metadata).unwrap();
        }
        let first = std::fs::read(&paths[0]).unwrap();
        for path in &paths[1..] {
            assert!(std::fs::read(path).unwrap() == first, "{}", path.display());
        }
        // Still a valid file with every attribute, now in name order.
        let read = exr::prelude::read_first_rgba_layer_from_file(
            &paths[0],
            |_, _| (),
            |(), _, (_, _, _, _): (f32, f32, f32, f32)| (),
        )
        .unwrap();
        for (key, value) in &metadata {
            let found = &read.layer_data.attributes.other[&Text::from(key.as_str())];
            assert!(matches!(found, AttributeValue::Text(t) if t.to_string() == *value));
        }
        let names: Vec<usize> = metadata
            .iter()
            .map(|(k, _)| {
                first
                    .windows(k.len())
                    .position(|w| w == k.as_bytes())
                    .unwrap()
            })
            .collect();
        let mut sorted_keys: Vec<&String> = metadata.iter().map(|(k, _)| k).collect();
        sorted_keys.sort();
        let mut by_position: Vec<(usize, &String)> = names
            .into_iter()
            .zip(metadata.iter().map(|(k, _)| k))
            .collect();
        by_position.sort();
        assert_eq!(
            by_position.into_iter().map(|(_, k)| k).collect::<Vec<_>>(),
            sorted_keys
        );
    }

    #[test]
    fn invalid_images_are_rejected_before_writing() {
        let path = Path::new("never-written.exr");
        let image = RgbImage {
            width: 2,
            height: 2,
            pixels: vec![[0.0; 3]; 3],
        };
        let error = write_exr(path, &image, &[]).unwrap_err();
        assert!(matches!(error, OutputError::InvalidImage { .. }), "{error}");
        let empty = RgbImage {
            width: 0,
            height: 5,
            pixels: vec![],
        };
        assert!(matches!(
            write_png(path, &empty, None, &[]),
            Err(OutputError::InvalidImage { .. })
        ));
        assert!(!path.exists());
    }

    #[test]
    fn bad_metadata_keys_are_rejected() {
        let path = Path::new("never-written.exr");
        let image = uniform(1, 1, [1.0; 3]);
        for metadata in [
            vec![(String::new(), "x".to_owned())],
            vec![("a\0b".to_owned(), "x".to_owned())],
            vec![
                ("k".to_owned(), "1".to_owned()),
                ("k".to_owned(), "2".to_owned()),
            ],
        ] {
            let error = write_exr(path, &image, &metadata).unwrap_err();
            assert!(
                matches!(error, OutputError::InvalidMetadata { .. }),
                "{error}"
            );
        }
        assert!(!path.exists());
    }
}
