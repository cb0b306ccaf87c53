//! The fast mode (`[render] mode = "fast"`, `render --mode fast`): the
//! approximate sky at the image's resolution, corrected by the Monte Carlo
//! image at a coarser one. Explicit, never the default: consistent, not
//! unbiased.
//!
//! The approximate sky ([`super::sky_model`]) is sharp where the sky is:
//! each pixel evaluates the phase functions at its own angle to the sun
//! (the aureole) and marches its own ray (the horizon, the limb from
//! orbit); its tables hold the light's smooth parts, and what it gets
//! wrong is smooth too. So the fast mode renders the model at the image's
//! resolution, M, the Monte Carlo image P_c at the image's width and
//! height over `fast_scale`, the model there too, M_c, and shows
//!
//!   I = M + Y(M) up((P_c − M_c) / Y(M_c)),
//!
//! `up` the bilinear interpolation of the coarse image at each pixel's
//! centre, placed through the coarse camera's own projection (so every
//! camera maps; the equirect map wraps in azimuth), Y the model's
//! luminance (at least a thousandth of its mean): the model is off by a
//! share of the light, and where the light changes fast (the twilight
//! glow over the horizon) an interpolated difference would smear the
//! coarse pixels' light over the fine ones. P_c is the reference
//! renderer's, pixel for pixel, so I converges as its passes do — to the
//! reference up to the interpolation of the model's error, which vanishes
//! as the coarse resolution reaches the image's. The work per pixel is the
//! model's (a few microseconds); the Monte Carlo's is `fast_scale`² times
//! less than the reference's at the same passes. The bias per preset is
//! measured against the reference (`skyrender bench`, `BENCHMARKS.md`).
//!
//! The correction jumps where the model's error does, at the horizon (and
//! the limb seen from orbit): the sky's pixels interpolate it from the
//! coarse pixels that see mostly sky, the ground's from those that see
//! mostly ground, and the pixels the horizon crosses take each by their
//! share.
//!
//! The sun's disc is the one feature neither smooth nor in the model: the
//! coarse render's `sun` layer (the disc through the air,
//! [`super::film_layers`]) is taken out of P_c, and its light is spread
//! evenly over the disc at the image's resolution, each pixel taking its
//! share of the disc: sharp, its light and colour the coarse render's (a
//! limb-darkened disc, or one reddened from below at sunset, comes out
//! uniform).

use glam::DVec3;
use rayon::prelude::*;

use super::camera::Camera;
use super::film_layers::VarianceHalves;
use super::{Film, OutOfMemory, Renderer};
use crate::output::RgbImage;
use crate::physics::sun;
use crate::scene::{CameraKind, RenderMode, Scene};
use crate::spectrum::rec709_luminance;

/// Positions per axis at which a pixel's share of the solar disc, or of
/// the ground, is counted.
const SHARE_GRID: usize = 16;

/// Width and height of the coarse render of a `width` × `height` image at
/// `scale`: each divided by the scale, rounded up.
pub fn coarse_size(width: u32, height: u32, scale: u32) -> (u32, u32) {
    let scale = scale.max(1);
    (width.div_ceil(scale), height.div_ceil(scale))
}

/// The reference-mode scene the fast mode renders by Monte Carlo: `scene`
/// at its coarse size, with the `sun` layer (the disc, taken out before
/// the correction is interpolated).
pub fn coarse_scene(scene: &Scene) -> Scene {
    let mut coarse = scene.clone();
    let r = &mut coarse.render;
    (r.width, r.height) = coarse_size(r.width, r.height, r.fast_scale);
    r.mode = RenderMode::Reference;
    coarse.output.layers = vec!["sun".into()];
    coarse
}

/// Bytes a pixel of the image takes while composing: the model's image
/// (12) and a pixel's ground shares and directions on the way (a few
/// more, per row).
const BYTES_PER_PIXEL: u64 = 16;

/// Checks, before any work, that the full-size image's memory can be had
/// (16 bytes a pixel; the coarse render checks its own film).
pub fn check_memory(scene: &Scene) -> Result<(), OutOfMemory> {
    let (width, height) = (scene.render.width, scene.render.height);
    let bytes = u64::from(width) * u64::from(height) * BYTES_PER_PIXEL;
    if super::alloc::can_reserve(bytes) {
        Ok(())
    } else {
        Err(OutOfMemory {
            width,
            height,
            bytes,
        })
    }
}

/// The fast-mode image of `scene` from its coarse renderer `coarse`
/// ([`coarse_scene`]) and the passes on its `film` so far.
pub fn compose(scene: &Scene, coarse: &Renderer, film: &Film) -> Result<RgbImage, OutOfMemory> {
    let (width, height) = (scene.render.width, scene.render.height);
    let camera = Camera::new(&scene.camera, width, height);
    // One model of the sky, imaged at both sizes.
    let sky = coarse.sky_model();
    let r = &coarse.scene.render;
    let coarse_model = sky.image(coarse.camera(), r.width, r.height);
    let model = sky.image(&camera, width, height);
    correct(scene, &camera, model, coarse, &coarse_model, film, None)
}

/// [`compose`] with the models made: `model`, the model's image of
/// `scene` through `camera` (its own size), corrected by the passes on
/// `film` of the coarse renderer `coarse`, whose own model image is
/// `coarse_model`; `places`, where given, is [`places`] of `camera` in
/// the coarse one (kept by a caller that composes again and again). Where
/// the coarse film keeps the `variance` layer's halves (the preview's), the
/// correction is denoised ([`Coarse::halves`]).
pub fn correct(
    scene: &Scene,
    camera: &Camera,
    model: RgbImage,
    coarse: &Renderer,
    coarse_model: &RgbImage,
    film: &Film,
    places: Option<&[Option<Place>]>,
) -> Result<RgbImage, OutOfMemory> {
    let passes = film.try_to_rgb().map_err(|_| coarse.out_of_memory())?;
    let disc = film
        .try_layer_images()
        .map_err(|_| coarse.out_of_memory())?
        .map(|[_, sun, _]| sun);
    let halves = film.variance_halves();
    let correction = Coarse {
        camera: coarse.camera(),
        passes: &passes.pixels,
        model: &coarse_model.pixels,
        disc: disc.as_deref(),
        halves: halves.as_ref(),
        wraps: scene.camera.kind == CameraKind::Equirect,
        meets_ground: &|dir| coarse.meets_ground(dir),
    };
    let sun = coarse.sun_direction();
    Ok(match places {
        Some(places) => correction.apply_at(model, camera, sun, |i| places[i]),
        None => correction.apply(model, camera, sun),
    })
}

/// Where a pixel of the image takes its correction: its centre's position
/// in the coarse image (pixel centres at whole numbers) and the share of
/// its rays that meet the ground.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    gx: f64,
    gy: f64,
    ground: f64,
}

/// [`Place`] of pixel (`x`, `y`) of `camera` in `coarse`; `None` where it
/// has no ray or the coarse camera does not see its centre.
fn place(
    camera: &Camera,
    coarse: &Camera,
    x: usize,
    y: usize,
    meets_ground: &dyn Fn(DVec3) -> bool,
) -> Option<Place> {
    let dir = camera.direction(x as f64 + 0.5, y as f64 + 0.5)?;
    let (u, v) = coarse.project(dir)?;
    let ground = ground_share(camera, x, y, meets_ground)?;
    Some(Place {
        gx: u - 0.5,
        gy: v - 0.5,
        ground,
    })
}

/// Every pixel's [`Place`] (row-major) of `camera` in the coarse
/// renderer's camera: the geometry of a composition, the same for every
/// one of a render's.
pub fn places(camera: &Camera, coarse: &Renderer) -> Vec<Option<Place>> {
    let width = camera.size().0 as usize;
    let pixels = width * camera.size().1 as usize;
    (0..pixels)
        .into_par_iter()
        .map(|i| {
            place(camera, coarse.camera(), i % width, i / width, &|dir| {
                coarse.meets_ground(dir)
            })
        })
        .collect()
}

/// The coarse images behind a fast-mode image.
pub struct Coarse<'a> {
    /// The coarse render's camera.
    pub camera: &'a Camera,
    /// The Monte Carlo image (row-major, linear Rec.709).
    pub passes: &'a [[f32; 3]],
    /// The model's image at the coarse resolution.
    pub model: &'a [[f32; 3]],
    /// The sun's disc in `passes` (its `sun` layer), if the render kept it.
    pub disc: Option<&'a [[f32; 3]]>,
    /// The passes' luminance from each half of them apart (the `variance`
    /// layer's halves, [`Film::variance_halves`]), where the correction is
    /// to be denoised (the preview's, `render::denoise`); `None`: taken as
    /// it is (the fast mode's export, whose bias is measured without it).
    pub halves: Option<&'a VarianceHalves>,
    /// Whether the image wraps around in x (the equirect map).
    pub wraps: bool,
    /// Whether the view ray along a direction meets the ground
    /// ([`Renderer::meets_ground`]).
    pub meets_ground: &'a (dyn Fn(DVec3) -> bool + Sync),
}

/// Sky or ground: which part of the correction a pixel takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Part {
    /// Sky (or space).
    Sky,
    /// Ground.
    Ground,
}

/// Ground share past which a coarse pixel's correction counts as the
/// ground's (below one minus it, as the sky's): the horizon seen from
/// near the ground lies a fraction of a degree above the edge of a row,
/// and that sliver of sky would otherwise leave the ground's first row
/// without a neighbour.
const MOSTLY: f64 = 0.9;

impl Part {
    /// Whether a coarse pixel with ground share `g` stands for this part.
    fn mostly(self, g: f64) -> bool {
        match self {
            Self::Sky => g <= 1.0 - MOSTLY,
            Self::Ground => g >= MOSTLY,
        }
    }
}

/// Share of pixel (`x`, `y`)'s rays that meet the ground, of those it has
/// (`None`: none, outside a fisheye's circle): its centre's and corners'
/// rays, and where they differ, a [`SHARE_GRID`]² grid.
fn ground_share(
    camera: &Camera,
    x: usize,
    y: usize,
    meets_ground: &dyn Fn(DVec3) -> bool,
) -> Option<f64> {
    let share = |points: &mut dyn Iterator<Item = (f64, f64)>| {
        let (mut rays, mut ground) = (0, 0);
        for (fx, fy) in points {
            if let Some(dir) = camera.direction(x as f64 + fx, y as f64 + fy) {
                rays += 1;
                if meets_ground(dir) {
                    ground += 1;
                }
            }
        }
        (rays > 0).then(|| f64::from(ground) / f64::from(rays))
    };
    let corners = [(0.5, 0.5), (0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)];
    match share(&mut corners.into_iter()) {
        Some(g) if g > 0.0 && g < 1.0 => share(&mut (0..SHARE_GRID * SHARE_GRID).map(|k| {
            (
                ((k % SHARE_GRID) as f64 + 0.5) / SHARE_GRID as f64,
                ((k / SHARE_GRID) as f64 + 0.5) / SHARE_GRID as f64,
            )
        })),
        g => g,
    }
}

impl Coarse<'_> {
    /// `model` (the model's image through `camera`) plus the interpolated
    /// correction (P_c − M_c, relative to M_c's luminance, times the
    /// pixel's), plus the disc of the sun at `sun_direction`.
    ///
    /// The correction jumps at the horizon (and the limb from orbit): the
    /// model's error over the ground is not its error in the sky. So the
    /// sky's pixels interpolate it from the coarse pixels that see mostly
    /// sky, the ground's from those that see mostly ground, and a pixel the
    /// horizon crosses takes each in proportion to its share of sky and
    /// ground.
    pub fn apply(&self, model: RgbImage, camera: &Camera, sun_direction: DVec3) -> RgbImage {
        let width = camera.size().0 as usize;
        self.apply_at(model, camera, sun_direction, |i| {
            place(camera, self.camera, i % width, i / width, self.meets_ground)
        })
    }

    /// [`Self::apply`] with each pixel's [`Place`] (by row-major index)
    /// from `place_of`.
    fn apply_at(
        &self,
        mut model: RgbImage,
        camera: &Camera,
        sun_direction: DVec3,
        place_of: impl Fn(usize) -> Option<Place> + Sync,
    ) -> RgbImage {
        let (cw, ch) = self.camera.size();
        let (cw, ch) = (cw as usize, ch as usize);
        // The correction, the disc taken out, and what each coarse pixel sees.
        let residual: Vec<[f32; 3]> = (0..cw * ch)
            .map(|k| {
                let d = self.disc.map_or([0.0; 3], |d| d[k]);
                [0, 1, 2].map(|c| self.passes[k][c] - d[c] - self.model[k][c])
            })
            .collect();
        // The coarse pixels that hold the sun's disc are left out as if
        // they saw nothing: their correction is the disc's sampling and
        // the aureole's, which rises tenfold across such a pixel, while
        // the model images the aureole at each fine pixel's own angle.
        // Interpolated, the bright pixels about the sun took a correction
        // of −100 % or more from them, one coarse pass in two.
        let shares: Vec<Option<f64>> = (0..cw * ch)
            .into_par_iter()
            .map(|k| {
                ground_share(self.camera, k % cw, k / cw, self.meets_ground)
                    .filter(|_| self.disc.is_none_or(|d| d[k][1] <= 0.0))
            })
            .collect();
        let luminance = |p: [f32; 3]| rec709_luminance(p.map(f64::from));
        let residual = match self.halves {
            Some(halves) => {
                // Each half's correction in luminance, as the residual's.
                let halves = halves.mean_y.each_ref().map(|mean_y| {
                    (0..cw * ch)
                        .map(|k| {
                            let disc = self.disc.map_or(0.0, |d| luminance(d[k]));
                            f64::from(mean_y[k]) - disc - luminance(self.model[k])
                        })
                        .collect()
                });
                super::denoise::denoised(&residual, &halves, &shares, (cw, ch), self.wraps)
            }
            None => residual,
        };
        // The correction relative to the model's luminance, interpolated,
        // then times the fine pixel's: where the model is off by a share
        // of the light (its usual error) and the light changes fast (the
        // twilight glow over the horizon, the limb), an interpolated
        // difference smears the coarse pixels' light over the fine ones,
        // a share does not. Where the model is dark the scale stops at a
        // thousandth of its mean, and the correction is a difference as
        // before; with no model light at all it is one everywhere.
        let mean = self
            .model
            .iter()
            .map(|&p| luminance(p).max(0.0))
            .sum::<f64>()
            / (cw * ch) as f64;
        let floor = 1e-3 * mean;
        let scale = |p: [f32; 3]| {
            if floor > 0.0 {
                luminance(p).max(floor)
            } else {
                1.0
            }
        };
        let relative: Vec<[f32; 3]> = residual
            .iter()
            .zip(self.model)
            .map(|(r, &m)| {
                let s = scale(m);
                r.map(|v| (f64::from(v) / s) as f32)
            })
            .collect();
        let width = model.width as usize;
        model
            .pixels
            .par_chunks_mut(width)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, pixel) in row.iter_mut().enumerate() {
                    let Some(p) = place_of(y * width + x) else {
                        continue;
                    };
                    let s = scale(*pixel) as f32;
                    let at = |only: Part| {
                        self.interpolate(&relative, &shares, only, p.gx, p.gy)
                            .map(|v| v * s)
                    };
                    let r = match p.ground {
                        g if g <= 0.0 => at(Part::Sky),
                        g if g >= 1.0 => at(Part::Ground),
                        g => {
                            let (sky, ground) = (at(Part::Sky), at(Part::Ground));
                            let g = g as f32;
                            [0, 1, 2].map(|c| (1.0 - g) * sky[c] + g * ground[c])
                        }
                    };
                    for c in 0..3 {
                        pixel[c] += r[c];
                    }
                }
            });
        if let Some(disc) = self.disc {
            self.add_disc(disc, &mut model, camera, sun_direction);
        }
        model
    }

    /// Bilinear interpolation of `values` at coarse position (`gx`, `gy`)
    /// (pixel centres at whole numbers) over the neighbours that see
    /// mostly `only` ([`Part::mostly`], by their ground `shares`); where
    /// none of the four does, a tent of radius two over the sixteen about
    /// it; where none of those does either, over the four that see
    /// anything.
    fn interpolate(
        &self,
        values: &[[f32; 3]],
        shares: &[Option<f64>],
        only: Part,
        gx: f64,
        gy: f64,
    ) -> [f32; 3] {
        let (cw, ch) = self.camera.size();
        let (cw, ch) = (cw as i64, ch as i64);
        let (x0, y0) = (gx.floor() as i64, gy.floor() as i64);
        let column = |x: i64| {
            if self.wraps {
                x.rem_euclid(cw)
            } else {
                x.clamp(0, cw - 1)
            }
        };
        let mean = |reach: i64, take: &dyn Fn(Option<f64>) -> bool| {
            let mut sum = [0.0_f64; 3];
            let mut weight = 0.0;
            for dy in 1 - reach..=reach {
                for dx in 1 - reach..=reach {
                    let (x, y) = (x0 + dx, y0 + dy);
                    let tent = |d: f64| (reach as f64 - d.abs()).max(0.0);
                    let w = tent(x as f64 - gx) * tent(y as f64 - gy);
                    let k = (y.clamp(0, ch - 1) * cw + column(x)) as usize;
                    if w > 0.0 && take(shares[k]) {
                        weight += w;
                        for c in 0..3 {
                            sum[c] += w * f64::from(values[k][c]);
                        }
                    }
                }
            }
            (weight > 0.0).then(|| sum.map(|s| (s / weight) as f32))
        };
        let wanted = |share: Option<f64>| share.is_some_and(|g| only.mostly(g));
        mean(1, &wanted)
            .or_else(|| mean(2, &wanted))
            .or_else(|| mean(1, &|share| share.is_some()))
            .unwrap_or([0.0; 3])
    }

    /// Adds the sun's disc to `image` (through `camera`): the disc's light
    /// in the coarse render (its `disc` layer times each pixel's solid
    /// angle, summed) spread evenly over the disc at the image's
    /// resolution, each pixel taking its share of the disc.
    fn add_disc(
        &self,
        disc: &[[f32; 3]],
        image: &mut RgbImage,
        camera: &Camera,
        sun_direction: DVec3,
    ) {
        let pixel_sr = |camera: &Camera, i: usize| {
            let (w, _) = camera.size();
            let w = w as usize;
            camera
                .direction((i % w) as f64 + 0.5, (i / w) as f64 + 0.5)
                .map_or(0.0, |dir| 1.0 / camera.pixels_per_sr(dir))
        };
        let mut flux = [0.0_f64; 3];
        for (k, _) in disc_shares(self.camera, sun_direction, self.wraps) {
            let sr = pixel_sr(self.camera, k);
            for c in 0..3 {
                flux[c] += f64::from(disc[k][c]) * sr;
            }
        }
        let fine = disc_shares(camera, sun_direction, self.wraps);
        let covered: f64 = fine
            .iter()
            .map(|&(i, share)| share * pixel_sr(camera, i))
            .sum();
        if covered <= 0.0 {
            return;
        }
        for (i, share) in fine {
            for (v, f) in image.pixels[i].iter_mut().zip(flux) {
                *v += (f / covered * share) as f32;
            }
        }
    }
}

/// The pixels of `camera`'s image that the solar disc about
/// `sun_direction` covers, with the share of each one's area it covers
/// (counted on a 16 × 16 grid of positions); `wraps`: the image
/// wraps around in x (the equirect map).
pub fn disc_shares(camera: &Camera, sun_direction: DVec3, wraps: bool) -> Vec<(usize, f64)> {
    let Some((u, v)) = camera.project(sun_direction) else {
        return Vec::new();
    };
    let (w, h) = camera.size();
    let radius = sun::ANGULAR_RADIUS_DEG.to_radians();
    let cos_radius = radius.cos();
    // The window about the sun's pixel: the disc's radius over the angle a
    // pixel spans there, each way, and a pixel to spare.
    let angle = |du: f64, dv: f64| {
        let a = camera.direction(u, v);
        let b = camera.direction(u + du, v + dv);
        a.zip(b).map_or(0.0, |(a, b)| a.angle_between(b))
    };
    let reach = |pixel_angle: f64| {
        if pixel_angle > 0.0 {
            ((radius / pixel_angle).ceil() + 2.0).min(4096.0) as i64
        } else {
            2
        }
    };
    let (rx, ry) = (reach(angle(0.5, 0.0) * 2.0), reach(angle(0.0, 0.5) * 2.0));
    let (cx, cy) = (u.floor() as i64, v.floor() as i64);
    let (wi, hi) = (w as i64, h as i64);
    let mut shares = Vec::new();
    for y in (cy - ry).max(0)..=(cy + ry).min(hi - 1) {
        for x in cx - rx..=cx + rx {
            let x = if wraps { x.rem_euclid(wi) } else { x };
            if !(0..wi).contains(&x) {
                continue;
            }
            let mut inside = 0;
            for k in 0..SHARE_GRID * SHARE_GRID {
                let fx = ((k % SHARE_GRID) as f64 + 0.5) / SHARE_GRID as f64;
                let fy = ((k / SHARE_GRID) as f64 + 0.5) / SHARE_GRID as f64;
                if camera
                    .direction(x as f64 + fx, y as f64 + fy)
                    .is_some_and(|d| d.dot(sun_direction) >= cos_radius)
                {
                    inside += 1;
                }
            }
            if inside > 0 {
                let share = f64::from(inside) / (SHARE_GRID * SHARE_GRID) as f64;
                shares.push(((y * wi + x) as usize, share));
            }
        }
    }
    shares
}

#[cfg(test)]
mod tests {
    use std::f64::consts::PI;

    use super::*;
    use crate::scene::CameraParams;

    fn equirect(width: u32, height: u32) -> Camera {
        Camera::new(&CameraParams::default(), width, height)
    }

    /// Ground below the astronomical horizon.
    fn below(dir: DVec3) -> bool {
        dir.z < 0.0
    }

    /// `apply` with no disc onto a zero model: the interpolated correction
    /// alone.
    fn correction_of(
        coarse: &Camera,
        passes: &[[f32; 3]],
        fine: &Camera,
        meets_ground: &(dyn Fn(DVec3) -> bool + Sync),
    ) -> RgbImage {
        let (w, h) = fine.size();
        let zeros = vec![[0.0; 3]; passes.len()];
        let c = Coarse {
            camera: coarse,
            passes,
            model: &zeros,
            disc: None,
            halves: None,
            wraps: true,
            meets_ground,
        };
        let model = RgbImage {
            width: w as u32,
            height: h as u32,
            pixels: vec![[0.0; 3]; (w * h) as usize],
        };
        c.apply(model, fine, DVec3::Z)
    }

    #[test]
    fn a_correction_linear_in_the_image_is_reproduced_exactly() {
        // A correction linear in the coarse pixel position (and periodic in
        // x through the seam: none in x) is what bilinear interpolation
        // reproduces everywhere between the outer rows' centres.
        let (coarse, fine) = (equirect(16, 8), equirect(64, 32));
        let passes: Vec<[f32; 3]> = (0..16 * 8)
            .map(|k| {
                let y = (k / 16) as f32 + 0.5;
                [y, 2.0 * y, -y]
            })
            .collect();
        let image = correction_of(&coarse, &passes, &fine, &|_| false);
        for y in 2..30 {
            let expected = (y as f32 + 0.5) / 4.0;
            for x in 0..64 {
                let p = image.pixels[y * 64 + x];
                assert!(
                    (p[0] - expected).abs() < 1e-4,
                    "({x}, {y}): {p:?} vs {expected}"
                );
                assert!((p[1] - 2.0 * expected).abs() < 2e-4);
                assert!((p[2] + expected).abs() < 1e-4);
            }
        }
    }

    #[test]
    fn the_map_wraps_around_at_its_seam() {
        // A correction of cos(azimuth) is continuous through the seam: the
        // first and last columns agree with the coarse values' own
        // interpolation there.
        let (coarse, fine) = (equirect(16, 8), equirect(64, 32));
        let passes: Vec<[f32; 3]> = (0..16 * 8)
            .map(|k| {
                let u = (f64::from(k % 16) + 0.5) / 16.0;
                [(2.0 * PI * u).cos() as f32; 3]
            })
            .collect();
        let image = correction_of(&coarse, &passes, &fine, &|_| false);
        let (first, last) = (image.pixels[16 * 64][0], image.pixels[16 * 64 + 63][0]);
        // Both lie an eighth of a coarse pixel from the seam, halfway
        // between the two coarse centres beside it: the same value.
        assert!((first - last).abs() < 1e-6, "{first} vs {last}");
        assert!(first > 0.9, "{first}");
    }

    #[test]
    fn sky_and_ground_take_their_own_corrections() {
        // +1 in the sky, −1 over the ground: no pixel away from the horizon
        // mixes them, and the rows it crosses take each by their share.
        let (coarse, fine) = (equirect(16, 8), equirect(64, 32));
        let passes: Vec<[f32; 3]> = (0..16 * 8)
            .map(|k| [if k / 16 < 4 { 1.0 } else { -1.0 }; 3])
            .collect();
        let image = correction_of(&coarse, &passes, &fine, &below);
        for y in 0..32 {
            let p = image.pixels[y * 64 + 5][0];
            let expected = if y < 16 { 1.0 } else { -1.0 };
            assert!((p - expected).abs() < 1e-6, "row {y}: {p}");
        }
        // A horizon crossing the middle of a row: half and half.
        let tilted = |dir: DVec3| dir.z < -(0.5 * PI / 32.0).sin();
        let image = correction_of(&coarse, &passes, &fine, &tilted);
        let p = image.pixels[16 * 64 + 5][0];
        assert!(p.abs() < 0.07, "row 16 under a horizon at its middle: {p}");
    }

    /// The limb seen from orbit: black space above, bright air below,
    /// the coarse passes 3 % under the model with noise of that size.
    /// Denoised, the correction stays a few per cent at the limb's fine
    /// pixels and nothing in space (a difference averaged from the limb
    /// into space, then divided by the dark model's floor there, once
    /// turned the limb black).
    #[test]
    fn a_denoised_correction_does_not_spill_from_the_limb_into_space() {
        let (coarse, fine) = (equirect(16, 8), equirect(64, 32));
        let bright = |row: usize| if row >= 3 { 1000.0_f32 } else { 0.0 };
        let model: Vec<[f32; 3]> = (0..16 * 8).map(|k| [bright(k / 16); 3]).collect();
        let passes: Vec<[f32; 3]> = (0..16 * 8)
            .map(|k| {
                let wobble = if (k * 7) % 3 == 0 { 1.0 } else { -0.5 };
                [bright(k / 16) * (0.97 + 0.03 * wobble); 3]
            })
            .collect();
        // Two halves whose noise is each other's opposite about the
        // passes' mean.
        let halves = VarianceHalves {
            mean_y: [1.0_f32, -1.0].map(|sign| {
                (0..16 * 8)
                    .map(|k| {
                        let mean = passes[k][1];
                        mean + sign * 0.02 * bright(k / 16) * if k % 2 == 0 { 1.0 } else { -1.0 }
                    })
                    .collect()
            }),
        };
        let c = Coarse {
            camera: &coarse,
            passes: &passes,
            model: &model,
            disc: None,
            halves: Some(&halves),
            wraps: true,
            meets_ground: &|_| false,
        };
        let fine_model = RgbImage {
            width: 64,
            height: 32,
            pixels: (0..64 * 32).map(|i| [bright(i / 64 / 4); 3]).collect(),
        };
        let image = c.apply(fine_model.clone(), &fine, DVec3::Z);
        for (i, (p, m)) in image.pixels.iter().zip(&fine_model.pixels).enumerate() {
            let (row, ratio) = (i / 64, p[1] / m[1].max(1e-30));
            if m[1] > 0.0 {
                assert!((0.9..=1.05).contains(&ratio), "row {row}: {ratio}");
            } else {
                assert!(p[1].abs() < 0.05, "space at row {row}: {}", p[1]);
            }
        }
    }

    #[test]
    fn the_disc_covers_the_suns_solid_angle_at_any_resolution() {
        let sun = direction_from(30.0, 100.0);
        let solid_angle = sun::solid_angle_sr();
        // The count on a 16 × 16 grid per pixel: coarser where the disc
        // spans fewer pixels.
        for (w, h, tolerance) in [(256, 128, 0.1), (1024, 512, 0.03), (4096, 2048, 0.01)] {
            let camera = equirect(w, h);
            let covered: f64 = disc_shares(&camera, sun, true)
                .iter()
                .map(|&(i, share)| {
                    let y = (i / w as usize) as f64 + 0.5;
                    let elevation = (90.0 - y / f64::from(h) * 180.0).to_radians();
                    let pixel_sr =
                        (2.0 * PI / f64::from(w)) * (PI / f64::from(h)) * elevation.cos();
                    share * pixel_sr
                })
                .sum();
            assert!(
                (covered / solid_angle - 1.0).abs() < tolerance,
                "{w}×{h}: {covered:e} sr vs {solid_angle:e}"
            );
        }
        // At the seam of the map (azimuth 180°) too.
        let seam = direction_from(10.0, 180.0);
        let shares = disc_shares(&equirect(4096, 2048), seam, true);
        let columns: Vec<usize> = shares.iter().map(|&(i, _)| i % 4096).collect();
        assert!(
            columns.contains(&0) && columns.contains(&4095),
            "{columns:?}"
        );
    }

    fn direction_from(elevation_deg: f64, azimuth_deg: f64) -> DVec3 {
        crate::render::direction_from_az_el(azimuth_deg, elevation_deg)
    }

    #[test]
    fn the_disc_keeps_the_coarse_renders_light() {
        // The disc's light in a coarse image, spread over a finer one by
        // each pixel's share, comes back whole.
        let sun = direction_from(20.0, 90.0);
        let (coarse, fine) = (equirect(64, 32), equirect(512, 256));
        let pixel_sr = |camera: &Camera, i: usize| {
            let (w, h) = camera.size();
            let y = (i / w as usize) as f64 + 0.5;
            let elevation = (90.0 - y / h * 180.0).to_radians();
            (2.0 * PI / w) * (PI / h) * elevation.cos()
        };
        let mut disc = vec![[0.0_f32; 3]; 64 * 32];
        let mut coarse_flux = 0.0;
        for (k, share) in disc_shares(&coarse, sun, true) {
            disc[k] = [(1000.0 * share) as f32; 3];
            coarse_flux += 1000.0 * share * pixel_sr(&coarse, k);
        }
        let zeros = vec![[0.0; 3]; 64 * 32];
        let c = Coarse {
            camera: &coarse,
            passes: &disc,
            model: &zeros,
            disc: Some(&disc),
            halves: None,
            wraps: true,
            meets_ground: &below,
        };
        let model = RgbImage {
            width: 512,
            height: 256,
            pixels: vec![[0.0; 3]; 512 * 256],
        };
        let image = c.apply(model, &fine, sun);
        let fine_flux: f64 = image
            .pixels
            .iter()
            .enumerate()
            .map(|(i, p)| f64::from(p[1]) * pixel_sr(&fine, i))
            .sum();
        assert!(
            (fine_flux / coarse_flux - 1.0).abs() < 0.03,
            "{fine_flux:e} vs {coarse_flux:e}"
        );
    }

    #[test]
    fn coarse_sizes_round_up() {
        assert_eq!(coarse_size(4096, 2048, 8), (512, 256));
        assert_eq!(coarse_size(1000, 333, 8), (125, 42));
        assert_eq!(coarse_size(7, 3, 64), (1, 1));
        assert_eq!(coarse_size(7, 3, 0), (7, 3));
    }
}
