//! Cameras map pixel positions to view directions in the observer's local
//! frame: x = east, y = north, z = up. Azimuths are degrees clockwise from
//! north, elevations degrees above the astronomical horizon.
//!
//! * **Equirectangular** (full sphere, 2:1): column u ∈ [0, 1) ↦ azimuth
//!   (u − ½)·360°, so the horizontal centre looks north and azimuth grows to
//!   the right (east); row v ∈ [0, 1) ↦ elevation 90° − v·180°, so the top
//!   row is the zenith. This is the usual lat–long environment-map layout;
//!   yaw, pitch and roll are ignored so the map stays geographic.
//! * **Angular fisheye** (equidistant: angle from the zenith ∝ radius),
//!   looking at the zenith, the circle inscribed in the image spanning
//!   `fov_deg` (180° by default). North is up; seen from below, east is on
//!   the left, as on an all-sky camera. `yaw_deg` turns the image.
//! * **Perspective** (rectilinear): view centre at (`yaw_deg`, `pitch_deg`),
//!   horizontal field of view `fov_deg`, `roll_deg` about the view axis.

use std::f64::consts::PI;

use glam::DVec3;

use crate::scene::{CameraKind, CameraParams};

/// Unit direction for an azimuth (clockwise from north) and elevation, degrees.
pub fn direction_from_az_el(azimuth_deg: f64, elevation_deg: f64) -> DVec3 {
    let (sa, ca) = azimuth_deg.to_radians().sin_cos();
    let (se, ce) = elevation_deg.to_radians().sin_cos();
    DVec3::new(sa * ce, ca * ce, se)
}

/// The largest spread of [`Camera::pixels_per_sr`] over a pixel's square
/// that [`Camera::pixel_density_bounded`] accepts.
pub const MAX_PIXEL_DENSITY_RATIO: f64 = 4.0;

/// A camera of the scene at a given image size: pixels to view rays.
#[derive(Clone, Debug)]
pub struct Camera {
    kind: CameraKind,
    width: f64,
    height: f64,
    tan_half_fov: f64,
    half_fov_rad: f64,
    yaw_deg: f64,
    pitch_deg: f64,
    roll_deg: f64,
    /// Columns: right, up, forward (world from camera).
    right: DVec3,
    up: DVec3,
    forward: DVec3,
}

impl Camera {
    /// The camera of `params` for a `width` × `height` image.
    pub fn new(params: &CameraParams, width: u32, height: u32) -> Self {
        let forward = direction_from_az_el(params.yaw_deg, params.pitch_deg);
        let (sy, cy) = params.yaw_deg.to_radians().sin_cos();
        let right0 = DVec3::new(cy, -sy, 0.0);
        let up0 = right0.cross(forward);
        // Roll: clockwise as seen by the viewer rotates the image content.
        let (sr, cr) = params.roll_deg.to_radians().sin_cos();
        let right = right0 * cr - up0 * sr;
        let up = up0 * cr + right0 * sr;
        let half = params.fov_deg.to_radians() / 2.0;
        Self {
            kind: params.kind,
            width: f64::from(width),
            height: f64::from(height),
            tan_half_fov: half.min(89.5f64.to_radians()).tan(),
            half_fov_rad: half,
            yaw_deg: params.yaw_deg,
            pitch_deg: params.pitch_deg,
            roll_deg: params.roll_deg,
            right,
            up,
            forward,
        }
    }

    /// Image width and height, pixels.
    pub fn size(&self) -> (f64, f64) {
        (self.width, self.height)
    }

    /// View direction through image position (`px`, `py`) in pixels from the
    /// top-left corner, or `None` outside a fisheye's circle.
    pub fn direction(&self, px: f64, py: f64) -> Option<DVec3> {
        let u = px / self.width;
        let v = py / self.height;
        match self.kind {
            CameraKind::Equirect => Some(direction_from_az_el((u - 0.5) * 360.0, 90.0 - v * 180.0)),
            CameraKind::Perspective => {
                let sx = (2.0 * u - 1.0) * self.tan_half_fov;
                let sy = (1.0 - 2.0 * v) * self.tan_half_fov * self.height / self.width;
                Some((self.forward + self.right * sx + self.up * sy).normalize())
            }
            CameraKind::Fisheye => {
                let scale = self.width.min(self.height);
                let nx = (2.0 * px - self.width) / scale;
                let ny = (self.height - 2.0 * py) / scale;
                let r = (nx * nx + ny * ny).sqrt();
                if r > 1.0 {
                    return None;
                }
                let zenith_angle = r * self.half_fov_rad;
                let azimuth = (-nx).atan2(ny) + self.yaw_deg.to_radians();
                Some(direction_from_az_el(
                    azimuth.to_degrees(),
                    90.0 - zenith_angle.to_degrees(),
                ))
            }
        }
    }

    /// The reflection of the image that the reflection of directions in the
    /// vertical plane of azimuth `sun_azimuth_deg` becomes, where it takes
    /// every pixel onto a pixel ([`Mirror`]); `None` where it does not.
    ///
    /// * Equirect: azimuth φ ↦ 2φ☉ − φ is column position u ↦ 2u☉ − u (mod
    ///   1), a pixel map where 2u☉ × width is a whole number (the sun's
    ///   azimuth on a pixel's edge or centre).
    /// * Perspective: with the view centre in the plane (yaw ≡ φ☉ mod 180°)
    ///   the plane holds `forward` and `up` before the roll and flips
    ///   `right`; a roll of 0° or 180° keeps that a flip of columns, 90° or
    ///   270° makes it one of rows. Looking straight up (down), the view
    ///   centre is in every vertical plane: `right` points to azimuth
    ///   yaw + 90° − roll (+ roll) and `up` to yaw + 180° − roll (+ roll),
    ///   so columns flip where yaw ∓ roll − φ☉ ≡ 0 (mod 180°), rows where
    ///   ≡ 90°.
    /// * Fisheye: the image's azimuths θ = φ − yaw map to 2(φ☉ − yaw) − θ, a
    ///   flip of columns where φ☉ − yaw ≡ 0 (mod 180°), of rows where ≡ 90°.
    pub fn mirror(&self, sun_azimuth_deg: f64) -> Option<Mirror> {
        let (width, height) = (self.width as u32, self.height as u32);
        if width == 0 || height == 0 {
            return None;
        }
        // Within 1e-9 of a whole number (of pixels, or of quarter turns): the
        // reflected directions then differ from the reflected pixels' by
        // at most ~1e-8 rad, far below noise.
        let whole = |v: f64| Some(v.round()).filter(|r| (v - r).abs() < 1e-9);
        let quarter_turns = |deg: f64| whole(deg / 90.0).map(|q| q.rem_euclid(4.0) as u32);
        let flip = |axis| Some(Mirror { axis, centre: 0 });
        match self.kind {
            CameraKind::Equirect => {
                let u = (sun_azimuth_deg / 360.0 + 0.5).rem_euclid(1.0);
                let c = whole(2.0 * u * self.width)?;
                Some(Mirror {
                    axis: MirrorAxis::Columns,
                    centre: (c as u32) % width,
                })
            }
            CameraKind::Perspective => {
                let turns = match whole(self.pitch_deg / 90.0).map(|q| q as i32) {
                    Some(1) => quarter_turns(self.yaw_deg - self.roll_deg - sun_azimuth_deg)?,
                    Some(-1) => quarter_turns(self.yaw_deg + self.roll_deg - sun_azimuth_deg)?,
                    _ => {
                        if quarter_turns(self.yaw_deg - sun_azimuth_deg)? % 2 != 0 {
                            return None;
                        }
                        quarter_turns(self.roll_deg)?
                    }
                };
                match turns % 2 {
                    0 => flip(MirrorAxis::Columns),
                    _ => flip(MirrorAxis::Rows),
                }
            }
            CameraKind::Fisheye => match quarter_turns(sun_azimuth_deg - self.yaw_deg)? % 2 {
                0 => flip(MirrorAxis::Columns),
                _ => flip(MirrorAxis::Rows),
            },
        }
    }

    /// The reflection in the vertical plane of azimuth `sun_azimuth_deg`
    /// as a [`HalfMirror`]: an equirect image whose 2u☉ × width is not a
    /// whole number (where it is, [`Self::mirror`]); `None` otherwise.
    pub fn half_mirror(&self, sun_azimuth_deg: f64) -> Option<HalfMirror> {
        if self.kind != CameraKind::Equirect || self.width < 1.0 || self.height < 1.0 {
            return None;
        }
        let u = (sun_azimuth_deg / 360.0 + 0.5).rem_euclid(1.0);
        let t = 2.0 * u * self.width;
        let centre = t.floor();
        let split = t - centre;
        // Within 1e-9 of a whole number [`Self::mirror`] takes it.
        (split > 1e-9 && split < 1.0 - 1e-9 && t.is_finite()).then(|| HalfMirror {
            centre: (centre as u32) % self.width as u32,
            split,
        })
    }

    /// Image area per solid angle at direction `dir` (unit), pixels² sr⁻¹:
    /// a pixel's value is the mean over its square of the radiance seen
    /// through each point, so light arriving from a solid angle dω around
    /// `dir` weighs `pixels_per_sr(dir)` dω in the pixel it falls on. 0 where
    /// the camera does not see `dir`.
    ///
    /// * Equirect: px = W (φ/2π + ½), py = H (½ − el/π) and dω = cos el dφ
    ///   del, so W H / (2π² cos el).
    /// * Perspective: the plane one unit along the axis takes dω to 1/z³ of
    ///   its area (z = cos of the angle off the axis), and one unit of it is
    ///   W / (2 tan ½fov) pixels either way.
    /// * Fisheye: radius r = θ / ½fov in half the smaller side, polar in the
    ///   image (dA = r dr dα) and on the sphere (dω = sin θ dθ dα), so
    ///   (s/2)² θ / (½fov² sin θ).
    pub fn pixels_per_sr(&self, dir: DVec3) -> f64 {
        match self.kind {
            CameraKind::Equirect => {
                let cos_el = (1.0 - dir.z * dir.z).max(0.0).sqrt();
                self.width * self.height / (2.0 * PI * PI * cos_el)
            }
            CameraKind::Perspective => {
                let z = dir.dot(self.forward);
                if z <= 0.0 {
                    return 0.0;
                }
                let unit = self.width / (2.0 * self.tan_half_fov);
                unit * unit / (z * z * z)
            }
            CameraKind::Fisheye => {
                let zenith = dir.z.clamp(-1.0, 1.0).acos();
                if zenith > self.half_fov_rad {
                    return 0.0;
                }
                let half_side = self.width.min(self.height) / 2.0;
                // θ / sin θ → 1 at the zenith.
                let ratio = if zenith > 1e-6 {
                    zenith / zenith.sin()
                } else {
                    1.0
                };
                half_side * half_side * ratio / (self.half_fov_rad * self.half_fov_rad)
            }
        }
    }

    /// Whether [`Self::pixels_per_sr`] (J) stays within
    /// [`MAX_PIXEL_DENSITY_RATIO`] of itself over pixel (`x`, `y`)'s square:
    /// not in an equirect map's first and last rows, which reach its poles
    /// (J ∝ 1/cos el; from the second row on J varies at most 2×), nor where
    /// a fisheye's θ / sin θ climbs toward the nadir of a near-360° circle.
    /// Light splatted into a pixel is weighted by J where it lands, and ∫ J²
    /// dω diverges (logarithmically) at a pole: one splat a hundredth of a
    /// degree from it outweighed the rest of a twilight image's splats. The
    /// renderer leaves such pixels to the camera's own paths.
    pub fn pixel_density_bounded(&self, x: u32, y: u32) -> bool {
        match self.kind {
            CameraKind::Equirect => y > 0 && f64::from(y) + 1.0 < self.height,
            // J ∝ 1/z³ changes little across a pixel at any field of view
            // the scene accepts.
            CameraKind::Perspective => true,
            CameraKind::Fisheye => {
                let half_side = self.width.min(self.height) / 2.0;
                let dx = (f64::from(x) + 0.5 - self.width / 2.0).abs();
                let dy = (f64::from(y) + 0.5 - self.height / 2.0).abs();
                // The square's nearest and farthest points from the centre
                // (J grows with the radius), as zenith angles.
                let zenith = |r: f64| (r / half_side).min(1.0) * self.half_fov_rad;
                let near = zenith((dx - 0.5).max(0.0).hypot((dy - 0.5).max(0.0)));
                let far = zenith((dx + 0.5).hypot(dy + 0.5));
                let ratio = |theta: f64| {
                    if theta > 1e-6 {
                        theta / theta.sin()
                    } else {
                        1.0
                    }
                };
                far < PI && ratio(far) <= MAX_PIXEL_DENSITY_RATIO * ratio(near)
            }
        }
    }

    /// Image position (pixels) where direction `dir` appears, if it lands
    /// inside the image on a pixel that takes splats
    /// ([`Self::pixel_density_bounded`]).
    pub fn splat_position(&self, dir: DVec3) -> Option<(f64, f64)> {
        let (px, py) = self.project(dir)?;
        ((0.0..self.width).contains(&px)
            && (0.0..self.height).contains(&py)
            && self.pixel_density_bounded(px as u32, py as u32))
        .then_some((px, py))
    }

    /// Image position (pixels) where direction `dir` appears, if it does.
    /// Used to check the mappings and to mark the sun in the preview.
    pub fn project(&self, dir: DVec3) -> Option<(f64, f64)> {
        // Only the maps by angle read the azimuth and elevation.
        let az = || dir.x.atan2(dir.y).to_degrees();
        let el = || dir.z.clamp(-1.0, 1.0).asin().to_degrees();
        match self.kind {
            CameraKind::Equirect => {
                let (az, el) = (az(), el());
                let u = (az / 360.0 + 0.5).rem_euclid(1.0);
                Some((u * self.width, (90.0 - el) / 180.0 * self.height))
            }
            CameraKind::Perspective => {
                let z = dir.dot(self.forward);
                if z <= 0.0 {
                    return None;
                }
                let sx = dir.dot(self.right) / z / self.tan_half_fov;
                let sy = dir.dot(self.up) / z / (self.tan_half_fov * self.height / self.width);
                Some((
                    f64::midpoint(sx, 1.0) * self.width,
                    f64::midpoint(1.0, -sy) * self.height,
                ))
            }
            CameraKind::Fisheye => {
                let (az, el) = (az(), el());
                let r = (90.0 - el).to_radians() / self.half_fov_rad;
                if r > 1.0 {
                    return None;
                }
                let a = (az - self.yaw_deg).to_radians();
                let scale = self.width.min(self.height);
                let nx = -r * a.sin();
                let ny = r * a.cos();
                Some((
                    f64::midpoint(nx * scale, self.width),
                    f64::midpoint(self.height, -ny * scale),
                ))
            }
        }
    }
}

/// Which pixel lines a [`Mirror`] reflects.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MirrorAxis {
    /// Column x ↦ (c − 1 − x) mod width, rows unchanged.
    Columns,
    /// Row y ↦ (c − 1 − y) mod height, columns unchanged.
    Rows,
}

/// The reflection of an equirect image in the sun's vertical plane where
/// the sun's azimuth is *not* on a pixel's edge or centre: column position
/// t ↦ K + g − t (mod width), K = `centre` whole, 0 < g = `split` < 1. It
/// takes no pixel onto a pixel, but each pixel's two parts split at g onto
/// parts of two pixels exactly: [x, x + g) onto [x′, x′ + g) of
/// x′ = K − x (its left partner), [x + g, x + 1) onto [x″ + g, x″ + 1) of
/// x″ = K − 1 − x (its right partner). Each sample of a pixel is drawn in
/// one part, chosen by its number alone ([`Self::in_left`]), so each part
/// holds a fixed number of samples, uniform over it; a film that keeps the
/// sums of each pixel's left samples reads each part with its partner's
/// (`super::film`). The counts follow the parts' widths (stratified
/// sampling in proportion); parts drawn by position instead would add the
/// binomial spread of their counts to every pixel, more than the noise
/// the pairing takes out where the sky's estimates are good.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HalfMirror {
    /// K, 0 ≤ K < width.
    pub centre: u32,
    /// g, where each pixel is split, as a fraction of its width from its
    /// left edge.
    pub split: f64,
}

impl HalfMirror {
    /// The column whose left part column `x` of `width`'s left part maps to.
    pub fn left_partner(self, x: usize, width: usize) -> usize {
        (self.centre as usize + width - x % width) % width
    }

    /// The column whose right part column `x` of `width`'s right part maps
    /// to.
    pub fn right_partner(self, x: usize, width: usize) -> usize {
        (self.centre as usize + 2 * width - 1 - x % width) % width
    }

    /// Whether a pixel's sample number `sample` is drawn in its left part:
    /// the draft (0) in the wider part; of the full samples 1, …, n,
    /// [`Self::left_count`]`(n)` in the left part.
    pub fn in_left(self, sample: u64) -> bool {
        if sample == 0 {
            return self.split >= 0.5;
        }
        self.left_count(sample) > self.left_count(sample - 1)
    }

    /// Of full samples 1, …, n, how many are drawn in the left part: the
    /// first in the wider part, then round(n g) kept within 1…n − 1, so
    /// from the second on each part holds at least one. Rises by 0 or 1
    /// with n (a rounded line, clamped between two such).
    pub fn left_count(self, n: u64) -> u64 {
        match n {
            0 => 0,
            1 => u64::from(self.split >= 0.5),
            _ => ((n as f64 * self.split).round() as u64).clamp(1, n - 1),
        }
    }

    /// Sample `sample`'s part (whether the left one) and its number among
    /// its part's full samples (0 for the first; the draft's 0).
    pub fn part(self, sample: u64) -> (bool, u64) {
        let left = self.in_left(sample);
        let index = match (sample, left) {
            (0, _) => 0,
            (_, true) => self.left_count(sample) - 1,
            (_, false) => sample - self.left_count(sample) - 1,
        };
        (left, index)
    }

    /// [`Self::part`] for samples numbered apart (a later part of a split
    /// render numbers a pixel's samples pass × 16 + k): the left part where
    /// frac(n φ + ½) < g, φ the golden ratio's conjugate — in proportion
    /// on any arithmetic run of numbers, where [`Self::in_left`]'s rounded
    /// line can fall on one part only (g = ½ and every 16th number); the
    /// number itself as the index.
    pub fn part_apart(self, sample: u64) -> (bool, u64) {
        const PHI: f64 = 0.618_033_988_749_894_8;
        let left = (sample as f64 * PHI + 0.5).fract() < self.split;
        (left, sample)
    }

    /// Where across its pixel (0–1 from the left edge) a sample drawn in
    /// the left part (`left`) or the right one lies, at `xi` ∈ [0, 1)
    /// within the part.
    pub fn position(self, left: bool, xi: f64) -> f64 {
        if left {
            self.split * xi
        } else {
            self.split + (1.0 - self.split) * xi
        }
    }
}

/// A reflection of the image onto itself that takes every pixel's footprint
/// exactly onto a pixel's (its own on the mirror line): the sun's vertical
/// plane as the camera sees it (see the module documentation).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Mirror {
    /// Which lines the mirror reflects.
    pub axis: MirrorAxis,
    /// c in the line map i ↦ (c − 1 − i) mod n, 0 ≤ c < n (n the lines).
    pub centre: u32,
}

impl Mirror {
    /// The line that line `i` of `n` maps to.
    pub(super) fn line(self, i: usize, n: usize) -> usize {
        (self.centre as usize + 2 * n - 1 - i) % n
    }

    /// Row-major index of the mirror image of pixel (`x`, `y`).
    pub fn partner(self, x: usize, y: usize, width: usize, height: usize) -> usize {
        match self.axis {
            MirrorAxis::Columns => y * width + self.line(x, width),
            MirrorAxis::Rows => self.line(y, height) * width + x,
        }
    }

    /// One line of each mirror pair (or fixed line), consecutive from ⌊c/2⌋
    /// (mod n): neighbours in the image stay neighbours in the folded one.
    pub(super) fn canonical_lines(self, n: usize) -> Vec<usize> {
        let mut taken = vec![false; n];
        let mut lines = Vec::with_capacity(n / 2 + 1);
        for k in 0..n {
            let i = (self.centre as usize / 2 + k) % n;
            if taken[i] {
                break;
            }
            taken[i] = true;
            taken[self.line(i, n)] = true;
            lines.push(i);
        }
        lines
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(kind: CameraKind, w: u32, h: u32) -> Camera {
        Camera::new(
            &CameraParams {
                kind,
                fov_deg: if kind == CameraKind::Fisheye {
                    180.0
                } else {
                    90.0
                },
                ..CameraParams::default()
            },
            w,
            h,
        )
    }

    #[test]
    fn pixels_where_the_density_is_bounded() {
        // Over a 17 × 17 grid on each accepted pixel's square (edges
        // included), J's largest value is within the accepted ratio of its
        // smallest (+5 % for the grid); the pixels left out are an equirect
        // map's pole rows and the rim of a 360° fisheye, and nothing else.
        let fisheye = |fov_deg: f64| {
            Camera::new(
                &CameraParams {
                    kind: CameraKind::Fisheye,
                    fov_deg,
                    ..CameraParams::default()
                },
                48,
                48,
            )
        };
        let cases = [
            ("equirect", camera(CameraKind::Equirect, 64, 32)),
            ("perspective", camera(CameraKind::Perspective, 32, 24)),
            ("fisheye 180°", fisheye(180.0)),
            ("fisheye 360°", fisheye(360.0)),
        ];
        for (name, camera) in cases {
            let (w, h) = camera.size();
            let mut left_out = Vec::new();
            for y in 0..h as u32 {
                for x in 0..w as u32 {
                    if !camera.pixel_density_bounded(x, y) {
                        left_out.push((x, y));
                        continue;
                    }
                    let (mut lo, mut hi) = (f64::INFINITY, 0.0_f64);
                    for (i, j) in (0..17).flat_map(|i| (0..17).map(move |j| (i, j))) {
                        let (px, py) = (
                            f64::from(x) + f64::from(i) / 16.0,
                            f64::from(y) + f64::from(j) / 16.0,
                        );
                        if let Some(dir) = camera.direction(px, py) {
                            let density = camera.pixels_per_sr(dir);
                            if density > 0.0 {
                                (lo, hi) = (lo.min(density), hi.max(density));
                            }
                        }
                    }
                    assert!(
                        hi <= 1.05 * MAX_PIXEL_DENSITY_RATIO * lo,
                        "{name} ({x}, {y}): J from {lo} to {hi}"
                    );
                }
            }
            match name {
                "equirect" => {
                    assert_eq!(left_out.len(), 128);
                    assert!(left_out.iter().all(|&(_, y)| y == 0 || y == 31));
                }
                "fisheye 360°" => {
                    // A ring at the rim: pixels whose squares reach
                    // within about a pixel of the circle's edge.
                    assert!(!left_out.is_empty());
                    for &(x, y) in &left_out {
                        let r = (f64::from(x) + 0.5 - 24.0).hypot(f64::from(y) + 0.5 - 24.0);
                        assert!(r > 20.0, "({x}, {y}) at radius {r}");
                    }
                }
                _ => assert!(left_out.is_empty(), "{name}: {left_out:?}"),
            }
        }
    }

    #[test]
    fn pixel_area_per_solid_angle_matches_the_mappings() {
        // The solid angle of a small square of image around (px, py), from
        // `direction` by finite differences, against 1 / pixels_per_sr.
        let cameras = [
            camera(CameraKind::Equirect, 256, 128),
            Camera::new(
                &CameraParams {
                    kind: CameraKind::Perspective,
                    fov_deg: 70.0,
                    yaw_deg: 30.0,
                    pitch_deg: 20.0,
                    roll_deg: 10.0,
                },
                160,
                90,
            ),
            camera(CameraKind::Fisheye, 120, 100),
        ];
        let h = 1e-4;
        for c in &cameras {
            let mut rng = crate::rng::Rng::new(5, 0);
            let mut checked = 0;
            for _ in 0..200 {
                let (px, py) = (rng.uniform() * c.width, rng.uniform() * c.height);
                let Some(d) = c.direction(px, py) else {
                    continue;
                };
                let (Some(dx), Some(dy)) = (c.direction(px + h, py), c.direction(px, py + h))
                else {
                    continue;
                };
                let solid_angle = (dx - d).cross(dy - d).length() / (h * h);
                let expected = 1.0 / solid_angle;
                let got = c.pixels_per_sr(d);
                assert!(
                    (got / expected - 1.0).abs() < 1e-3,
                    "{:?} at ({px:.2}, {py:.2}): {got} against {expected}",
                    c.kind
                );
                checked += 1;
            }
            assert!(checked > 100, "{:?}", c.kind);
        }
        // Outside the view: nothing.
        let perspective = &cameras[1];
        assert_eq!(perspective.pixels_per_sr(-perspective.forward), 0.0);
        assert_eq!(cameras[2].pixels_per_sr(-DVec3::Z), 0.0);
    }

    #[test]
    fn equirect_layout_is_the_documented_one() {
        let c = camera(CameraKind::Equirect, 360, 180);
        let north = c.direction(180.0, 90.0).unwrap();
        assert!((north - DVec3::Y).length() < 1e-9);
        let east = c.direction(270.0, 90.0).unwrap();
        assert!((east - DVec3::X).length() < 1e-9);
        let zenith = c.direction(180.0, 0.0).unwrap();
        assert!((zenith - DVec3::Z).length() < 1e-9);
    }

    #[test]
    fn fisheye_has_north_up_east_left_and_zenith_centre() {
        let c = camera(CameraKind::Fisheye, 200, 200);
        assert!((c.direction(100.0, 100.0).unwrap() - DVec3::Z).length() < 1e-9);
        let top = c.direction(100.0, 0.0).unwrap();
        assert!((top - DVec3::Y).length() < 1e-9);
        let left = c.direction(0.0, 100.0).unwrap();
        assert!((left - DVec3::X).length() < 1e-9);
        assert!(c.direction(0.0, 0.0).is_none());
    }

    #[test]
    fn projection_inverts_direction() {
        for kind in CameraKind::ALL {
            let mut params = CameraParams {
                kind,
                yaw_deg: 30.0,
                pitch_deg: 10.0,
                roll_deg: 5.0,
                ..CameraParams::default()
            };
            if kind == CameraKind::Fisheye {
                params.fov_deg = 180.0;
            }
            let c = Camera::new(&params, 300, 200);
            for (px, py) in [(150.0, 100.0), (20.5, 40.25), (280.0, 150.0)] {
                if let Some(d) = c.direction(px, py) {
                    let (x, y) = c.project(d).unwrap();
                    assert!((x - px).abs() < 1e-6 && (y - py).abs() < 1e-6, "{kind:?}");
                }
            }
        }
    }

    /// The reflection of `d` in the vertical plane of azimuth `azimuth_deg`.
    fn reflect(d: DVec3, azimuth_deg: f64) -> DVec3 {
        let n = direction_from_az_el(azimuth_deg + 90.0, 0.0);
        d - 2.0 * d.dot(n) * n
    }

    #[test]
    fn the_half_mirror_takes_each_pixel_part_onto_its_reflection() {
        // Suns off the pixel grid (a real date's), at even and odd widths:
        // the direction through any point of a pixel's left (right) part,
        // reflected in the sun's vertical plane, is the direction through
        // the reflected point of its left (right) partner, in the same
        // part.
        let mut checked = 0;
        for (w, h) in [(256u32, 128u32), (15, 9), (64, 32)] {
            for sun_azimuth_deg in [60.0, 240.0, 123.456, 359.9, 0.3] {
                let c = camera(CameraKind::Equirect, w, h);
                assert!(
                    c.mirror(sun_azimuth_deg).is_none() == c.half_mirror(sun_azimuth_deg).is_some()
                );
                let Some(m) = c.half_mirror(sun_azimuth_deg) else {
                    continue;
                };
                for i in 0..499u32 {
                    let (x, y) = ((i * 37) % w, (i * 11) % h);
                    let (fx, fy) = (f64::from(i % 13) / 13.0 + 0.01, f64::from(i % 5) / 5.0);
                    let d = c.direction(f64::from(x) + fx, f64::from(y) + fy).unwrap();
                    let (partner, rx) = if fx < m.split {
                        (m.left_partner(x as usize, w as usize), m.split - fx)
                    } else {
                        (m.right_partner(x as usize, w as usize), 1.0 + m.split - fx)
                    };
                    assert!((0.0..=1.0).contains(&rx), "{rx}");
                    assert_eq!(rx < m.split, fx < m.split, "the same part");
                    let r = c.direction(partner as f64 + rx, f64::from(y) + fy).unwrap();
                    let expected = reflect(d, sun_azimuth_deg);
                    assert!(
                        (r - expected).length() < 1e-8,
                        "{w}×{h} az {sun_azimuth_deg} x {x} + {fx}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 2000, "{checked}");
    }

    #[test]
    fn half_mirror_parts_take_samples_in_proportion_from_the_second() {
        for split in [0.01, 0.3, 0.5, 0.77, 0.999] {
            let m = HalfMirror { centre: 3, split };
            let mut left = 0;
            for n in 1..2000u64 {
                left += u64::from(m.in_left(n));
                assert_eq!(left, m.left_count(n), "g {split}, n {n}");
                if n >= 2 {
                    assert!(left >= 1 && left < n, "g {split}: {left} of {n}");
                }
                if n as f64 >= 1.0 / split.min(1.0 - split) {
                    assert!(
                        (left as f64 - n as f64 * split).abs() <= 1.0,
                        "g {split}, n {n}: {left}"
                    );
                }
            }
            assert_eq!(m.in_left(0), split >= 0.5);
            assert!(m.position(true, 0.999) < split && m.position(false, 0.0) >= split);
            // Each part's samples numbered 0, 1, … in order.
            let (mut l, mut r) = (0, 0);
            for n in 1..500u64 {
                let (left, index) = m.part(n);
                let next = if left { &mut l } else { &mut r };
                assert_eq!(index, *next, "g {split}, n {n}");
                *next += 1;
            }
            // Numbered apart (every 16th number, as a later part of a split
            // render numbers its one sample a pass): still in proportion.
            let apart = (1..=2000u64).filter(|p| m.part_apart(16 * p).0).count();
            assert!(
                (apart as f64 - 2000.0 * split).abs() < 20.0,
                "g {split}: {apart} of 2000"
            );
        }
    }

    #[test]
    fn the_mirror_takes_each_pixel_onto_its_reflection() {
        // For every camera and orientation that has a mirror: the direction
        // through any point of a pixel, reflected in the sun's vertical
        // plane, is the direction through the reflected point of the
        // partner pixel (so the partner's samples are the reflected ones).
        let cases = [
            (CameraKind::Equirect, 0.0, 0.0, 0.0, 180.0),
            (CameraKind::Equirect, 0.0, 0.0, 0.0, 90.0),
            // 256 columns: 1.40625° each, the sun on a column's centre.
            (CameraKind::Equirect, 10.0, 20.0, 30.0, 1.40625 * 3.5),
            (CameraKind::Perspective, 180.0, 10.0, 0.0, 180.0),
            (CameraKind::Perspective, 0.0, -20.0, 180.0, 180.0),
            (CameraKind::Perspective, 45.0, 60.0, 90.0, 225.0),
            (CameraKind::Perspective, 30.0, 90.0, -90.0, 30.0),
            // Straight up or down, yaw and roll both turn the image.
            (CameraKind::Perspective, 0.0, 90.0, 0.0, 90.0),
            (CameraKind::Perspective, 30.0, 90.0, 30.0, 0.0),
            (CameraKind::Perspective, 30.0, -90.0, 30.0, 60.0),
            (CameraKind::Perspective, 10.0, -90.0, 20.0, 120.0),
            (CameraKind::Fisheye, 0.0, 90.0, 0.0, 180.0),
            (CameraKind::Fisheye, 20.0, 90.0, 0.0, 110.0),
        ];
        let mut checked = 0;
        // Odd and one-pixel sizes too; the equirect's mirror depends on the
        // width (2u☉ × width whole), the others' do not.
        for (w, h) in [(256u32, 128u32), (15, 9), (1, 7), (7, 1)] {
            for (kind, yaw_deg, pitch_deg, roll_deg, sun_azimuth_deg) in cases {
                let params = CameraParams {
                    kind,
                    fov_deg: kind.default_fov_deg(),
                    yaw_deg,
                    pitch_deg,
                    roll_deg,
                };
                let c = Camera::new(&params, w, h);
                let Some(mirror) = c.mirror(sun_azimuth_deg) else {
                    assert!(
                        kind == CameraKind::Equirect && (w, h) != (256, 128),
                        "{params:?} at {w}×{h}: no mirror"
                    );
                    continue;
                };
                for i in 0..997u32 {
                    let (x, y) = ((i * 37) % w, (i * 11) % h);
                    let (fx, fy) = (f64::from(i % 7) / 7.0, f64::from(i % 5) / 5.0);
                    let Some(d) = c.direction(f64::from(x) + fx, f64::from(y) + fy) else {
                        continue;
                    };
                    let p = mirror.partner(x as usize, y as usize, w as usize, h as usize);
                    let (px, py) = ((p % w as usize) as f64, (p / w as usize) as f64);
                    // Within its pixel, the reflection flips the mirrored axis.
                    let (rx, ry) = match mirror.axis {
                        MirrorAxis::Columns => (px + 1.0 - fx, py + fy),
                        MirrorAxis::Rows => (px + fx, py + 1.0 - fy),
                    };
                    let r = c.direction(rx, ry).expect("the reflection is in view");
                    let expected = reflect(d, sun_azimuth_deg);
                    assert!(
                        (r - expected).length() < 1e-8,
                        "{params:?} at {w}×{h}, pixel ({x}, {y}) + ({fx}, {fy}): {r} vs {expected}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 20_000, "{checked}");
    }

    #[test]
    fn no_mirror_where_the_reflection_misses_the_pixel_grid() {
        let mirror = |kind, yaw_deg, roll_deg, sun_azimuth_deg| {
            let params = CameraParams {
                kind,
                yaw_deg,
                roll_deg,
                ..CameraParams::default()
            };
            Camera::new(&params, 256, 128).mirror(sun_azimuth_deg)
        };
        // A quarter of a column off the grid.
        assert!(mirror(CameraKind::Equirect, 0.0, 0.0, 1.40625 / 4.0).is_none());
        assert!(mirror(CameraKind::Perspective, 170.0, 0.0, 180.0).is_none());
        assert!(mirror(CameraKind::Perspective, 90.0, 0.0, 180.0).is_none());
        assert!(mirror(CameraKind::Perspective, 180.0, 10.0, 180.0).is_none());
        assert!(mirror(CameraKind::Fisheye, 0.0, 0.0, 45.0).is_none());
        assert!(mirror(CameraKind::Equirect, 0.0, 0.0, 180.0).is_some());
        // Straight up, yaw − roll decides: 45° off the grid.
        let up = CameraParams {
            kind: CameraKind::Perspective,
            yaw_deg: 30.0,
            pitch_deg: 90.0,
            roll_deg: 15.0,
            ..CameraParams::default()
        };
        assert!(Camera::new(&up, 64, 64).mirror(60.0).is_none());
        assert!(Camera::new(&up, 64, 64).mirror(15.0).is_some());
        // No pixels, no mirror (and no panic).
        assert!(Camera::new(&CameraParams::default(), 0, 0)
            .mirror(180.0)
            .is_none());
    }

    #[test]
    fn perspective_looks_at_yaw_and_pitch() {
        let c = Camera::new(
            &CameraParams {
                kind: CameraKind::Perspective,
                yaw_deg: 90.0,
                pitch_deg: 30.0,
                ..CameraParams::default()
            },
            100,
            100,
        );
        let d = c.direction(50.0, 50.0).unwrap();
        assert!((d - direction_from_az_el(90.0, 30.0)).length() < 1e-9);
        // Right of centre is further clockwise (south of east).
        assert!(c.direction(90.0, 50.0).unwrap().y < 0.0);
    }
}
