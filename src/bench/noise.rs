//! The two-image noise measurement of `skyrender bench` (see the module
//! above for the method): the masks of sky, ground and whole image, the
//! relative noise of the mean image over each, and how the noise is
//! correlated between pixels.

use std::time::Instant;

use glam::DVec3;
use serde::Serialize;

use super::SUN_CONE_DEG;
use crate::render::{Camera, Film, Renderer};
use crate::scene::Scene;

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
    pub fn for_scene(scene: &Scene) -> Self {
        if scene.observer.altitude_m >= scene.atmosphere.top_altitude_m {
            Self::Lit
        } else {
            Self::AboveHorizon
        }
    }

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
    let cos_cone = SUN_CONE_DEG.to_radians().cos();
    let mut mask = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height {
        for x in 0..width {
            let i = mask.len();
            let keep = camera
                .direction(f64::from(x) + 0.5, f64::from(y) + 0.5)
                .is_some_and(|dir| {
                    dir.dot(sun) < cos_cone
                        && match kind {
                            SkyMask::AboveHorizon => dir.z > 0.0,
                            SkyMask::Lit => mean_y.get(i).is_some_and(|&v| v > 0.0),
                        }
                });
            mask.push(keep);
        }
    }
    mask
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

/// Result of one two-image noise measurement.
#[derive(Clone, Debug, Serialize)]
pub struct NoiseRun {
    pub noise: f64,
    /// Mean luminance over the sky pixels, cd m⁻².
    pub mean_luminance_cd_m2: f64,
    /// Render time of A and B together, s.
    pub seconds: f64,
    /// CPU time this process got meanwhile over (wall time × threads): below
    /// 1 when other processes competed for the cores.
    pub cpu_share: f64,
    pub paths: u64,
    pub passes: [u32; 2],
    pub sky_pixels: usize,
    pub discarded: u64,
}

impl NoiseRun {
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
/// measure the relative noise of the mean image over the sky.
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
    };
    let mut geometry = None;
    let mut cpu_seconds = 0.0;
    let second = seed
        .checked_add(1)
        .ok_or_else(|| format!("seed {seed}: B's seed (seed + 1) overflows"))?;
    for (k, seed) in [seed, second].into_iter().enumerate() {
        let mut s = scene.clone();
        s.render.seed = seed;
        let renderer = Renderer::new(&s).map_err(|e| e.to_string())?;
        let r = render_for(&renderer, budget_s / 2.0);
        run.seconds += r.seconds;
        cpu_seconds += r.cpu_seconds;
        run.paths += r.paths;
        run.passes[k] = r.passes;
        run.discarded += r.film.discarded;
        images.push(luminance(&r.film));
        geometry = Some((renderer.camera().clone(), renderer.sun_direction()));
    }
    let (camera, sun) = geometry.expect("two renders");
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
    Ok(run)
}
