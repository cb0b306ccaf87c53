//! The two-image noise measurement of `skyrender bench` (see the module
//! above for the method): the masks of sky, ground and whole image, the
//! relative noise of the mean image over each, and how the noise is
//! correlated between pixels.

use std::time::Instant;

use glam::DVec3;
use serde::Serialize;

use crate::render::noise_estimate::{outside_sun_cone, relative_noise_of};
use crate::render::preview::Preview;
use crate::render::{Camera, Film, Renderer};
use crate::scene::Scene;

pub use crate::render::noise_estimate::SUN_CONE_DEG;

/// Which pixels count as sky.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SkyMask {
    /// Pixel centre above the astronomical horizon (observer in the atmosphere).
    AboveHorizon,
    /// Non-zero mean luminance (observer above the atmosphere).
    Lit,
}

impl SkyMask {
    /// The mask for `scene`: lit pixels from above the air, else the sky above the horizon.
    pub fn for_scene(scene: &Scene) -> Self {
        if scene.observer.altitude_m >= scene.atmosphere.top_altitude_m {
            Self::Lit
        } else {
            Self::AboveHorizon
        }
    }

    /// The mask in words, for the report.
    pub fn describe(self) -> &'static str {
        match self {
            Self::AboveHorizon => "pixel centres above the horizon",
            Self::Lit => "pixels with non-zero mean luminance",
        }
    }
}

/// The sky pixels of a `width`×`height` image (row-major): see [`SkyMask`];
/// pixels whose centre is within [`SUN_CONE_DEG`] of `sun` are excluded.
/// `mean_y` (the mean luminance per pixel) is used by [`SkyMask::Lit`] only.
pub fn sky_mask(
    camera: &Camera,
    width: u32,
    height: u32,
    sun: DVec3,
    kind: SkyMask,
    mean_y: &[f64],
) -> Vec<bool> {
    outside_sun_cone(camera, width, height, sun, |i, dir| match kind {
        SkyMask::AboveHorizon => dir.z > 0.0,
        SkyMask::Lit => mean_y.get(i).is_some_and(|&v| v > 0.0),
    })
}

/// Relative RMS noise of the mean of two independent images,
/// sqrt(mean((A − B)²) / 4) / mean((A + B) / 2), over the masked pixels.
/// NaN when no pixel is selected or the mean is not positive.
pub fn relative_noise(a: &[f64], b: &[f64], mask: &[bool]) -> f64 {
    let (mut n, mut diff2, mut sum) = (0usize, 0.0, 0.0);
    for ((&a, &b), &m) in a.iter().zip(b).zip(mask) {
        if m {
            n += 1;
            diff2 += (a - b) * (a - b);
            sum += 0.5 * (a + b);
        }
    }
    if n == 0 || sum <= 0.0 {
        return f64::NAN;
    }
    let n = n as f64;
    (diff2 / n / 4.0).sqrt() / (sum / n)
}

/// Time to reach `target` relative noise, from `noise` measured after
/// `seconds`, assuming noise ∝ 1/√time.
pub fn time_to_noise(noise: f64, seconds: f64, target: f64) -> f64 {
    if noise.is_finite() && noise > 0.0 {
        seconds * (noise / target).powi(2)
    } else {
        f64::NAN
    }
}

fn luminance(film: &Film) -> Vec<f64> {
    let mut y = Vec::with_capacity(film.width as usize * film.height as usize);
    for row in 0..film.height {
        for x in 0..film.width {
            y.push(film.xyz(x, row)[1]);
        }
    }
    y
}

/// Seconds after a change at which the bench reads what the preview shows
/// (issue 33's "≤ 2 % after 2 s").
pub const PREVIEW_SECONDS: f64 = 2.0;

/// Result of one two-image noise measurement.
#[derive(Clone, Debug, Serialize)]
pub struct NoiseRun {
    /// Relative RMS noise of the mean image over the sky pixels.
    pub noise: f64,
    /// Mean luminance over the sky pixels, cd m⁻².
    pub mean_luminance_cd_m2: f64,
    /// Render time of A and B together, s.
    pub seconds: f64,
    /// CPU time this process got meanwhile over (wall time × threads): below
    /// 1 when other processes competed for the cores.
    pub cpu_share: f64,
    /// Camera paths traced in A and B.
    pub paths: u64,
    /// Passes of A and of B.
    pub passes: [u32; 2],
    /// Pixels in the sky mask.
    pub sky_pixels: usize,
    /// Samples discarded as not finite.
    pub discarded: u64,
    /// Relative noise over the ground: the pixels whose centre's ray meets
    /// it (sun cone excluded; NaN where none does).
    pub noise_ground: f64,
    /// Pixels below the horizon (the ground).
    pub ground_pixels: usize,
    /// Relative noise over the whole image: every pixel with a ray (lit,
    /// for an observer above the air), the sun's cone excluded.
    pub noise_whole: f64,
    /// Pixels of the whole image, the sun's cone left out.
    pub whole_pixels: usize,
    /// `noise_whole` as A and B estimate it each from its own passes
    /// ([`crate::render::noise_estimate`], what `render --noise` reads),
    /// for their mean: √(e_A² + e_B²)/2. A check of that estimate.
    pub noise_whole_estimate: f64,
    /// Correlation of the relative A − B differences of horizontal
    /// neighbours, of vertical ones, and of pixels at the same angle from
    /// the sun (on one circle of [`crate::render::circles`], neither
    /// neighbours nor mirror partners) over the whole image: structured
    /// noise. Mirror partners are left out of every pair (their symmetry
    /// is by construction).
    pub row_correlation: f64,
    /// See `row_correlation`: vertical neighbours.
    pub column_correlation: f64,
    /// See `row_correlation`: pixels on one circle about the sun's axis.
    pub circle_correlation: f64,
    /// The reference's own relative noise over the whole image: the mean
    /// of A and B (`noise_whole`), or, with a reference budget, the mean
    /// of two longer renders of their own (seeds + 3 and + 4).
    pub reference_noise: f64,
    /// Passes of the reference's two renders (A's and B's where the
    /// reference is their mean).
    pub reference_passes: [u32; 2],
    /// RMS error of one first pass (the draft, another seed) against the
    /// reference over the whole image, relative to its mean luminance,
    /// with the reference's own noise (`reference_noise`) taken out in
    /// quadrature.
    pub first_pass_error: f64,
    /// The same error for the approximate sky model
    /// ([`crate::render::sky_model`]): the preview's first frame.
    pub model_error: f64,
    /// The same error for what the preview shows `PREVIEW_SECONDS` (2 s) after
    /// a change: the last image [`crate::render::preview::Preview`]
    /// completed by then (the model, corrected by coarse passes, then the
    /// full passes blended with it).
    pub preview_error_2s: f64,
    /// The reference other images are compared with (luminance,
    /// row-major): see `reference_noise`.
    #[serde(skip)]
    pub reference: Vec<f64>,
    /// The whole-image mask (see `noise_whole`).
    #[serde(skip)]
    pub whole_mask: Vec<bool>,
}

impl NoiseRun {
    /// Camera paths per second of wall time.
    pub fn paths_per_s(&self) -> f64 {
        self.paths as f64 / self.seconds.max(1e-9)
    }
}

/// CPU time (user + system, all threads) of this process so far, s, from
/// `/proc/self/stat` (Linux, USER_HZ = 100); `None` where unavailable.
pub fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    // Fields 14 and 15 of proc(5), counted from `state` (field 3) here.
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    Some((utime + stime) / 100.0)
}

/// `scene` with seed `seed + offset`, or an error naming `what` render's
/// seed where that overflows.
pub(super) fn with_seed(
    scene: &Scene,
    seed: u64,
    offset: u64,
    what: &str,
) -> Result<Scene, String> {
    let mut s = scene.clone();
    s.render.seed = seed
        .checked_add(offset)
        .ok_or_else(|| format!("seed {seed}: {what}'s seed (seed + {offset}) overflows"))?;
    Ok(s)
}

/// What [`render_for`] did.
pub(super) struct Rendered {
    pub(super) film: Film,
    pub(super) paths: u64,
    pub(super) passes: u32,
    pub(super) seconds: f64,
    /// CPU seconds of this process meanwhile (NaN if unknown).
    pub(super) cpu_seconds: f64,
}

/// Render whole passes of `renderer` for about `seconds`: another pass is
/// started only while it is expected (as long as the last one) to end less
/// than half a pass past `seconds` (so the time spent is the nearest pass
/// boundary; at least one pass). The last pass, not the mean: the draft and
/// first passes are cheaper than the adaptive ones after them.
pub(super) fn render_for(renderer: &Renderer, seconds: f64) -> Rendered {
    let mut film = renderer.new_film();
    let mut paths = 0;
    let mut pass = 0u32;
    let cpu_start = process_cpu_seconds();
    let start = Instant::now();
    let mut last_end = 0.0;
    loop {
        // Camera paths and splatted ones: both are paths traced.
        let stats = renderer.render_pass(&mut film, pass, &|| false);
        paths += stats.paths + stats.splat_paths;
        pass += 1;
        let elapsed = start.elapsed().as_secs_f64();
        let last_pass = elapsed - last_end;
        last_end = elapsed;
        if elapsed + 0.5 * last_pass > seconds {
            let cpu_seconds = match (cpu_start, process_cpu_seconds()) {
                (Some(a), Some(b)) => b - a,
                _ => f64::NAN,
            };
            return Rendered {
                film,
                paths,
                passes: pass,
                seconds: elapsed,
                cpu_seconds,
            };
        }
    }
}

/// Render `scene` twice, with seeds `seed` and `seed + 1`, `budget_s / 2` each, and
/// measure the relative noise of the mean image over the sky, the ground
/// and the whole image, and its structure; the mean is the run's
/// reference until [`measure_preview`] replaces it. The preview's errors
/// stay NaN until [`measure_preview`] measures them.
pub fn measure_noise(scene: &Scene, budget_s: f64, seed: u64) -> Result<NoiseRun, String> {
    let mut images = Vec::with_capacity(2);
    let mut run = NoiseRun {
        noise: f64::NAN,
        mean_luminance_cd_m2: f64::NAN,
        seconds: 0.0,
        cpu_share: 0.0,
        paths: 0,
        passes: [0; 2],
        sky_pixels: 0,
        discarded: 0,
        noise_ground: f64::NAN,
        ground_pixels: 0,
        noise_whole: f64::NAN,
        whole_pixels: 0,
        noise_whole_estimate: f64::NAN,
        row_correlation: f64::NAN,
        column_correlation: f64::NAN,
        circle_correlation: f64::NAN,
        first_pass_error: f64::NAN,
        model_error: f64::NAN,
        preview_error_2s: f64::NAN,
        reference_noise: f64::NAN,
        reference_passes: [0; 2],
        reference: Vec::new(),
        whole_mask: Vec::new(),
    };
    let mut geometry = None;
    let mut cpu_seconds = 0.0;
    let mut variances = Vec::with_capacity(2);
    for (k, what) in ["A", "B"].into_iter().enumerate() {
        let mut s = with_seed(scene, seed, k as u64, what)?;
        // The variance layer's sums, for the noise each estimates alone.
        s.output.layers.push("variance".into());
        let renderer = Renderer::new(&s).map_err(|e| e.to_string())?;
        let r = render_for(&renderer, budget_s / 2.0);
        run.seconds += r.seconds;
        cpu_seconds += r.cpu_seconds;
        run.paths += r.paths;
        run.passes[k] = r.passes;
        run.discarded += r.film.discarded;
        images.push(luminance(&r.film));
        variances.push(r.film.variance_plane());
        geometry = Some((
            renderer.camera().clone(),
            renderer.sun_direction(),
            renderer.centre_ground(),
        ));
    }
    let (camera, sun, ground) = geometry.expect("two renders");
    run.cpu_share = cpu_seconds / (run.seconds * rayon::current_num_threads() as f64);
    let mean: Vec<f64> = images[0]
        .iter()
        .zip(&images[1])
        .map(|(a, b)| 0.5 * (a + b))
        .collect();
    let mask = sky_mask(
        &camera,
        scene.render.width,
        scene.render.height,
        sun,
        SkyMask::for_scene(scene),
        &mean,
    );
    run.sky_pixels = mask.iter().filter(|&&m| m).count();
    run.mean_luminance_cd_m2 = mean
        .iter()
        .zip(&mask)
        .filter(|(_, &m)| m)
        .map(|(v, _)| v)
        .sum::<f64>()
        / run.sky_pixels.max(1) as f64;
    run.noise = relative_noise(&images[0], &images[1], &mask);
    let (w, h) = (scene.render.width, scene.render.height);
    let whole = whole_mask(&camera, w, h, sun, SkyMask::for_scene(scene), &mean);
    let ground: Vec<bool> = ground.iter().zip(&whole).map(|(&g, &m)| g && m).collect();
    (run.whole_pixels, run.ground_pixels) = (count(&whole), count(&ground));
    run.noise_whole = relative_noise(&images[0], &images[1], &whole);
    run.noise_ground = relative_noise(&images[0], &images[1], &ground);
    let estimates: Vec<f64> = variances
        .iter()
        .zip(&images)
        .map(|(v, y)| {
            v.as_ref()
                .and_then(|v| relative_noise_of(v, y, &whole))
                .unwrap_or(f64::NAN)
        })
        .collect();
    run.noise_whole_estimate = estimates.iter().map(|e| e * e).sum::<f64>().sqrt() / 2.0;
    let (wu, hu) = (w as usize, h as usize);
    let pairs = crate::render::mirror_pairs(scene);
    let halves = crate::render::mirror_halves(scene);
    let partners = |x: u32, y: u32| {
        let (x, y) = (x as usize, y as usize);
        match (pairs, halves) {
            (Some(m), _) => [m.partner(x, y, wu, hu); 2],
            (None, Some(m)) => [m.left_partner(x, wu), m.right_partner(x, wu)].map(|p| y * wu + p),
            (None, None) => [y * wu + x; 2],
        }
    };
    let c = correlations(&images, &whole, (w, h), &camera, sun, &partners);
    (
        run.row_correlation,
        run.column_correlation,
        run.circle_correlation,
    ) = c;
    run.reference_noise = run.noise_whole;
    run.reference_passes = run.passes;
    run.reference = mean;
    run.whole_mask = whole;
    Ok(run)
}

/// The preview's errors of `scene` against `run`'s reference (the mean of
/// its A and B, or with `reference_s` two further renders of that many
/// seconds each, seeds + 3 and + 4, which then become `run`'s reference):
/// one draft pass's (seed + 2), the sky model's and what `render::preview`
/// shows 2 s after a change, each with the reference's noise taken out.
pub fn measure_preview(
    run: &mut NoiseRun,
    scene: &Scene,
    seed: u64,
    reference_s: Option<f64>,
) -> Result<(), String> {
    let whole = &run.whole_mask;
    // The reference: A and B's mean, or two longer renders' (a converged
    // reference for the errors below, where A and B are still noisy).
    if let Some(seconds) = reference_s {
        let mut long = Vec::with_capacity(2);
        for (offset, passes) in [3, 4].into_iter().zip(&mut run.reference_passes) {
            let s = with_seed(scene, seed, offset, "the reference")?;
            let renderer = Renderer::new(&s).map_err(|e| e.to_string())?;
            let rendered = render_for(&renderer, seconds);
            *passes = rendered.passes;
            long.push(luminance(&rendered.film));
        }
        run.reference_noise = relative_noise(&long[0], &long[1], whole);
        run.reference = long[0]
            .iter()
            .zip(&long[1])
            .map(|(a, b)| 0.5 * (a + b))
            .collect();
    }
    let mean = &run.reference;
    // The first pass of a third, independent render against the reference.
    let s = with_seed(scene, seed, 2, "the first pass")?;
    let renderer = Renderer::new(&s).map_err(|e| e.to_string())?;
    let mut film = renderer.new_film();
    renderer.render_pass(&mut film, 0, &|| false);
    let first = luminance(&film);
    let error = relative_noise(&first, mean, whole) * 2.0;
    run.first_pass_error = without_noise(error, &[run.reference_noise]);
    let model_image = renderer.sky_model_image();
    let y = |image: &crate::output::RgbImage| -> Vec<f64> {
        image
            .pixels
            .iter()
            .map(|p| crate::spectrum::rec709_luminance(p.map(f64::from)))
            .collect()
    };
    let model = y(&model_image);
    let error = relative_noise(&model, mean, whole) * 2.0;
    run.model_error = without_noise(error, &[run.reference_noise]);
    // What the preview shows PREVIEW_SECONDS after a change: the last image
    // its steps (render::preview, as the app's service takes them)
    // completed by then, from a renderer made anew.
    let since_change = std::time::Instant::now();
    let renderer = Renderer::new(&s).map_err(|e| e.to_string())?;
    let mut preview = Preview::new(&renderer);
    let mut last = preview.model().clone();
    while let Some(step) = preview.step(&|| false) {
        if since_change.elapsed().as_secs_f64() > PREVIEW_SECONDS {
            break;
        }
        last = step.image;
    }
    let shown = y(&last);
    let error = relative_noise(&shown, mean, whole) * 2.0;
    run.preview_error_2s = without_noise(error, &[run.reference_noise]);
    Ok(())
}

/// An RMS difference `error` with the independent noises `noises` (all
/// relative RMS) taken out in quadrature, at least zero.
pub(super) fn without_noise(error: f64, noises: &[f64]) -> f64 {
    (error * error - noises.iter().map(|n| n * n).sum::<f64>())
        .max(0.0)
        .sqrt()
}

fn count(mask: &[bool]) -> usize {
    mask.iter().filter(|&&m| m).count()
}

/// Every pixel with a ray (with non-zero mean luminance for an observer
/// above the air, [`SkyMask::Lit`]), those within [`SUN_CONE_DEG`] of the
/// sun left out.
pub fn whole_mask(
    camera: &Camera,
    width: u32,
    height: u32,
    sun: DVec3,
    kind: SkyMask,
    mean_y: &[f64],
) -> Vec<bool> {
    outside_sun_cone(camera, width, height, sun, |i, _| {
        kind == SkyMask::AboveHorizon || mean_y[i] > 0.0
    })
}

/// (rows, columns, circles): the correlations of u = (A − B)/(A + B)
/// between horizontal neighbours, vertical neighbours and pixels at the
/// same angle from `sun` (binned by the image's pixel height in angle,
/// each paired with the next of its bin that is neither a neighbour nor
/// its mirror partner), over `mask`; pairs of mirror partners (pixels
/// `partners(x, y)` of pixel (x, y); itself where it has none) are left
/// out. r = Σ uᵢuⱼ / √(Σ uᵢ² Σ uⱼ²): 0 for independent noise.
pub fn correlations(
    images: &[Vec<f64>],
    mask: &[bool],
    (width, height): (u32, u32),
    camera: &Camera,
    sun: DVec3,
    partners: &dyn Fn(u32, u32) -> [usize; 2],
) -> (f64, f64, f64) {
    let (w, h) = (width as usize, height as usize);
    let u: Vec<Option<f64>> = (0..w * h)
        .map(|i| {
            let (a, b) = (images[0][i], images[1][i]);
            (mask[i] && a + b > 0.0).then(|| (a - b) / (a + b))
        })
        .collect();
    let partner_of = |i: usize, j: usize| partners((i % w) as u32, (i / w) as u32).contains(&j);
    let correlation = |pairs: &mut dyn Iterator<Item = (usize, usize)>| {
        let (mut uv, mut uu, mut vv) = (0.0, 0.0, 0.0);
        for (i, j) in pairs {
            if partner_of(i, j) {
                continue;
            }
            if let (Some(a), Some(b)) = (u[i], u[j]) {
                uv += a * b;
                uu += a * a;
                vv += b * b;
            }
        }
        if uu > 0.0 && vv > 0.0 {
            uv / (uu * vv).sqrt()
        } else {
            f64::NAN
        }
    };
    let rows = correlation(&mut (0..w * h).filter(|i| i % w + 1 < w).map(|i| (i, i + 1)));
    let columns = correlation(&mut (0..w * h.saturating_sub(1)).map(|i| (i, i + w)));
    // Bins of angle from the sun, one pixel height wide.
    let bin_rad = std::f64::consts::PI / h.max(1) as f64;
    let mut bins = std::collections::BTreeMap::<u64, Vec<usize>>::new();
    for (i, _) in u.iter().enumerate().filter(|(_, v)| v.is_some()) {
        let (x, y) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
        if let Some(dir) = camera.direction(x, y) {
            let theta = dir.normalize().dot(sun).clamp(-1.0, 1.0).acos();
            bins.entry((theta / bin_rad) as u64).or_default().push(i);
        }
    }
    let near = |i: usize, j: usize| {
        let (dx, dy) = ((i % w).abs_diff(j % w), (i / w).abs_diff(j / w));
        dx <= 1 && dy <= 1
    };
    let mut pairs = Vec::new();
    for pixels in bins.values() {
        for (k, &i) in pixels.iter().enumerate() {
            if let Some(&j) = pixels[k + 1..]
                .iter()
                .find(|&&j| !near(i, j) && !partner_of(i, j))
            {
                pairs.push((i, j));
            }
        }
    }
    let circles = correlation(&mut pairs.into_iter());
    (rows, columns, circles)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::CameraKind;

    /// A deterministic pseudo-random value in (−1, 1) per index.
    fn noise(i: usize) -> f64 {
        let mut z = (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ 0x5eed;
        z = (z ^ (z >> 31)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 29)).wrapping_mul(0x94d0_49bb_1331_11eb);
        2.0 * ((z >> 11) as f64 / (1u64 << 53) as f64) - 1.0
    }

    #[test]
    fn correlations_find_structure_and_not_white_noise() {
        let mut scene = Scene::preset("sunset").unwrap();
        scene.camera.kind = CameraKind::Equirect;
        scene.render.width = 128;
        scene.render.height = 64;
        let renderer = Renderer::new(&scene).unwrap();
        let (camera, sun) = (renderer.camera().clone(), renderer.sun_direction());
        let (w, h) = (128usize, 64usize);
        let mask = vec![true; w * h];
        let alone = |x: u32, y: u32| [y as usize * w + x as usize; 2];
        let pair = |e: &dyn Fn(usize) -> f64| -> Vec<Vec<f64>> {
            vec![
                (0..w * h).map(|i| 1.0 + 0.1 * e(i)).collect(),
                (0..w * h).map(|i| 1.0 - 0.1 * e(i)).collect(),
            ]
        };
        // White noise: every correlation within a few 1/√pairs of 0.
        let white = pair(&noise);
        let (r, c, k) = correlations(&white, &mask, (128, 64), &camera, sun, &alone);
        for v in [r, c, k] {
            assert!(v.abs() < 0.05, "{r} {c} {k}");
        }
        // Pairs of columns share their noise: the rows' correlation is about
        // a half (every other horizontal pair shares it), the columns' none.
        let doubled = pair(&|i: usize| noise(i - i % 2));
        let (r, c, _) = correlations(&doubled, &mask, (128, 64), &camera, sun, &alone);
        assert!((r - 0.5).abs() < 0.1 && c.abs() < 0.05, "{r} {c}");
        // Noise that depends on the angle from the sun alone: the circles'.
        let theta = |i: usize| {
            let dir = camera
                .direction((i % w) as f64 + 0.5, (i / w) as f64 + 0.5)
                .unwrap()
                .normalize();
            let bin =
                (dir.dot(sun).clamp(-1.0, 1.0).acos() / (std::f64::consts::PI / h as f64)) as usize;
            noise(bin + 7)
        };
        let circular = pair(&theta);
        let (_, _, k) = correlations(&circular, &mask, (128, 64), &camera, sun, &alone);
        assert!(k > 0.9, "{k}");
    }
}
