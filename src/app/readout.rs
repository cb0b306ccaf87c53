//! What the app reads off the displayed frame: a pixel's direction,
//! luminance and colour under the cursor, and the log-luminance false-colour
//! map with its scale. Plain functions, testable without a window.

use glam::DVec3;

use crate::output::RgbImage;
use crate::render::Camera;
use crate::scene::Scene;

/// Linear Rec.709 (sRGB primaries, D65 white) → CIE 1931 XYZ, the inverse
/// of [`crate::spectrum::XYZ_TO_REC709`] as given in IEC 61966-2-1:1999
/// (sRGB), equation (F.7). Its middle row is the luminance weights.
pub const REC709_TO_XYZ: [[f64; 3]; 3] = [
    [0.4124, 0.3576, 0.1805],
    [0.2126, 0.7152, 0.0722],
    [0.0193, 0.1192, 0.9505],
];

/// Azimuth (degrees clockwise from north, 0–360) and elevation (degrees)
/// of a world direction: the inverse of
/// [`crate::render::direction_from_az_el`] (x east, y north, z up).
pub fn az_el_from_direction(dir: DVec3) -> (f64, f64) {
    let dir = dir.normalize();
    let azimuth = dir.x.atan2(dir.y).to_degrees().rem_euclid(360.0);
    let elevation = dir.z.clamp(-1.0, 1.0).asin().to_degrees();
    (azimuth, elevation)
}

/// CIE XYZ of a linear Rec.709 colour ([`REC709_TO_XYZ`]).
pub fn rec709_to_xyz(rgb: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|c| REC709_TO_XYZ[r][c] * rgb[c]).sum())
}

/// Luminance of a linear Rec.709 colour (Y, in the colour's units; the
/// renderer's RGB is scaled so that Y is in cd/m²).
pub fn luminance(rgb: [f64; 3]) -> f64 {
    rec709_to_xyz(rgb)[1]
}

/// CIE 1931 chromaticity (x, y) of a linear Rec.709 colour; `None` for black
/// or a colour whose XYZ sum is not positive (no chromaticity to speak of).
pub fn chromaticity_xy(rgb: [f64; 3]) -> Option<(f64, f64)> {
    let xyz = rec709_to_xyz(rgb);
    let sum = xyz[0] + xyz[1] + xyz[2];
    (sum.is_finite() && sum > 0.0).then(|| (xyz[0] / sum, xyz[1] / sum))
}

/// What the cursor is over in the sky view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelReadout {
    /// Degrees clockwise from north, 0–360.
    pub azimuth_deg: f64,
    /// Degrees above the horizon.
    pub elevation_deg: f64,
    /// Linear Rec.709 RGB of the displayed frame's pixel.
    pub rgb: [f64; 3],
    /// Luminance, cd/m².
    pub luminance: f64,
    /// CIE 1931 chromaticity, where it has one.
    pub xy: Option<(f64, f64)>,
}

/// The readout at (`u`, `v`), 0–1 across and down `image`, which `scene`'s
/// camera rendered; `None` off the image or where no ray leaves (outside a
/// fisheye's circle).
pub fn pixel_readout(image: &RgbImage, scene: &Scene, u: f64, v: f64) -> Option<PixelReadout> {
    if !(0.0..=1.0).contains(&u) || !(0.0..=1.0).contains(&v) || image.pixels.is_empty() {
        return None;
    }
    let (w, h) = (image.width, image.height);
    let camera = Camera::new(&scene.camera, w, h);
    let (px, py) = (u * f64::from(w), v * f64::from(h));
    // The pixel the cursor is in, and the direction through its centre, so
    // the direction and the colour describe the same sample.
    let (ix, iy) = (
        (px as u32).min(w.saturating_sub(1)),
        (py as u32).min(h.saturating_sub(1)),
    );
    let dir = camera.direction(f64::from(ix) + 0.5, f64::from(iy) + 0.5)?;
    let (azimuth_deg, elevation_deg) = az_el_from_direction(dir);
    let rgb = image.pixels[(iy * w + ix) as usize].map(f64::from);
    Some(PixelReadout {
        azimuth_deg,
        elevation_deg,
        rgb,
        luminance: luminance(rgb),
        xy: chromaticity_xy(rgb),
    })
}

/// Matplotlib's viridis colormap (van der Walt & Smith, 2015) at nine evenly
/// spaced points, 8-bit sRGB (#440154 … #fde725): perceptually uniform and
/// ordered in lightness, so a brighter sky reads as a lighter colour.
const VIRIDIS: [[u8; 3]; 9] = [
    [0x44, 0x01, 0x54],
    [0x47, 0x2d, 0x7b],
    [0x3b, 0x52, 0x8b],
    [0x2c, 0x72, 0x8e],
    [0x21, 0x91, 0x8c],
    [0x28, 0xae, 0x80],
    [0x5e, 0xc9, 0x62],
    [0xad, 0xdc, 0x30],
    [0xfd, 0xe7, 0x25],
];

/// The viridis colour at `t` (0–1, clamped; NaN counts as 0), interpolated
/// between the table's points.
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let i = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - i as f64;
    std::array::from_fn(|k| {
        let (a, b) = (f64::from(VIRIDIS[i][k]), f64::from(VIRIDIS[i + 1][k]));
        (a + f * (b - a)).round() as u8
    })
}

/// The luminance range a false-colour image spans: whole decades, log10 of
/// cd/m².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FalseColourScale {
    /// log10 of the luminance at the bottom of the colormap.
    pub log_lo: f64,
    /// log10 of the luminance at the top (always above `log_lo`).
    pub log_hi: f64,
}

impl FalseColourScale {
    /// The scale for `image`: from its 1st to its 99.5th percentile of
    /// positive luminance, widened to whole decades. The percentiles keep
    /// the sun's disc (a few pixels, orders of magnitude brighter) and
    /// near-black pixels from squeezing the sky into a few colours.
    pub fn of(image: &RgbImage) -> Self {
        let mut logs: Vec<f64> = image
            .pixels
            .iter()
            .map(|p| luminance(p.map(f64::from)))
            .filter(|y| y.is_finite() && *y > 0.0)
            .map(f64::log10)
            .collect();
        if logs.is_empty() {
            return Self {
                log_lo: 0.0,
                log_hi: 1.0,
            };
        }
        logs.sort_by(f64::total_cmp);
        let at = |q: f64| logs[((logs.len() - 1) as f64 * q).round() as usize];
        let log_lo = at(0.01).floor();
        let log_hi = at(0.995).ceil().max(log_lo + 1.0);
        Self { log_lo, log_hi }
    }

    /// Where luminance `y` (cd/m²) falls on the scale, 0–1 (clamped; black
    /// is at 0).
    pub fn position(&self, y: f64) -> f64 {
        // NaN, zero and negative luminances are black.
        if y.is_nan() || y <= 0.0 {
            return 0.0;
        }
        ((y.log10() - self.log_lo) / (self.log_hi - self.log_lo)).clamp(0.0, 1.0)
    }

    /// `image` as 8-bit sRGB, row-major, 3 bytes a pixel: each pixel's
    /// luminance in viridis on this scale.
    pub fn map(&self, image: &RgbImage) -> Vec<u8> {
        image
            .pixels
            .iter()
            .flat_map(|p| viridis(self.position(luminance(p.map(f64::from)))))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::direction_from_az_el;

    #[test]
    fn az_el_inverts_direction_from_az_el() {
        for (az, el) in [
            (0.0, 0.0),
            (90.0, 10.0),
            (180.0, -30.0),
            (271.5, 45.0),
            (359.0, 89.0),
        ] {
            let (a, e) = az_el_from_direction(direction_from_az_el(az, el));
            assert!((a - az).abs() < 1e-9, "azimuth {az} -> {a}");
            assert!((e - el).abs() < 1e-9, "elevation {el} -> {e}");
        }
        // East is +x: azimuth 90° clockwise from north.
        let (a, e) = az_el_from_direction(DVec3::X);
        assert!((a - 90.0).abs() < 1e-12 && e.abs() < 1e-12);
        let (_, e) = az_el_from_direction(DVec3::Z);
        assert!((e - 90.0).abs() < 1e-12);
    }

    #[test]
    fn white_is_d65_and_has_unit_luminance() {
        let (x, y) = chromaticity_xy([1.0, 1.0, 1.0]).unwrap();
        assert!((x - 0.3127).abs() < 1e-4, "x = {x}");
        assert!((y - 0.3290).abs() < 1e-4, "y = {y}");
        assert!((luminance([1.0, 1.0, 1.0]) - 1.0).abs() < 1e-12);
        assert_eq!(chromaticity_xy([0.0; 3]), None);
        // The matrix inverts the renderer's XYZ → Rec.709 one.
        let back = crate::spectrum::xyz_to_rec709(rec709_to_xyz([0.2, 0.5, 0.9]));
        for (b, c) in back.iter().zip([0.2, 0.5, 0.9]) {
            assert!((b - c).abs() < 1e-3, "{back:?}");
        }
    }

    #[test]
    fn readout_follows_the_camera_and_skips_outside_a_fisheye() {
        let mut scene = Scene::preset("midday").unwrap();
        scene.camera.kind = crate::scene::CameraKind::Equirect;
        let image = RgbImage {
            width: 4,
            height: 2,
            pixels: vec![[1.0, 1.0, 1.0]; 8],
        };
        // Top row, right of centre: above the horizon, east of north.
        let r = pixel_readout(&image, &scene, 0.6, 0.25).unwrap();
        assert!(r.elevation_deg > 0.0 && r.azimuth_deg < 180.0, "{r:?}");
        assert!((r.luminance - 1.0).abs() < 1e-9);
        assert_eq!(pixel_readout(&image, &scene, 1.5, 0.5), None);
        scene.camera.kind = crate::scene::CameraKind::Fisheye;
        let square = RgbImage {
            width: 4,
            height: 4,
            pixels: vec![[1.0; 3]; 16],
        };
        assert_eq!(pixel_readout(&square, &scene, 0.0, 0.0), None);
        let zenith = pixel_readout(&square, &scene, 0.5, 0.5).unwrap();
        assert!(zenith.elevation_deg > 45.0, "{zenith:?}");
    }

    #[test]
    fn false_colour_scale_spans_whole_decades_and_is_ordered() {
        let image = RgbImage {
            width: 3,
            height: 1,
            pixels: vec![[20.0; 3], [300.0; 3], [4000.0; 3]],
        };
        let scale = FalseColourScale::of(&image);
        assert_eq!((scale.log_lo, scale.log_hi), (1.0, 4.0));
        let bytes = scale.map(&image);
        // Viridis grows lighter with luminance.
        let light = |i: usize| {
            bytes[3 * i..3 * i + 3]
                .iter()
                .map(|&b| u32::from(b))
                .sum::<u32>()
        };
        assert!(light(0) < light(1) && light(1) < light(2));
        assert_eq!(viridis(0.0), VIRIDIS[0]);
        assert_eq!(viridis(1.0), VIRIDIS[8]);
        assert_eq!(scale.position(0.0), 0.0);
    }
}
