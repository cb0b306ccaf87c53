//! Compositing layers written beside the beauty image (`render --layers`,
//! the scene's `[output] layers`), one multi-channel EXR named after
//! OpenEXR's layer convention. Both layers here are deterministic
//! functions of the view ray through each pixel's *centre* (no Monte Carlo,
//! no second render):
//!
//! - `transmittance` → `transmittance.R`, `.G`, `.B` and `A`. The spectral
//!   transmittance T(λ) = exp(−∫ σₜ(λ) dt) from the observer along the view
//!   ray to where it leaves the atmosphere or meets the ground, integrated
//!   by Simpson's rule over the same extinction the renderer traces
//!   (`Medium::coefficients`: Rayleigh, aerosols, ozone), at every
//!   [`STEP_NM`] over the observer's colour-matching range. Its colour is
//!   that of a white source seen through it: XYZ = Σ T(λ) x̄(λ), … (a flat
//!   spectrum weighted by the CMFs), to linear Rec.709, each channel divided
//!   by that of T = 1, so a clear ray gives (1, 1, 1). `A` = 1 − Σ T ȳ / Σ ȳ
//!   (1 − the luminance-weighted transmittance), the alpha with which to
//!   composite the sky over a background seen through it; where the ray
//!   meets the ground `A` = 1 (opaque) while `transmittance` still holds the
//!   ray's transmittance to the ground.
//! - `Z` → `Z`: the distance in metres from the observer along the view ray
//!   to the ground (the exact sphere intersection), +∞ where the ray leaves
//!   the atmosphere.
//!
//! Pixels without a view ray (outside a fisheye's circle) have
//! transmittance 0, `A` = 0 and `Z` = +∞.

use glam::DVec3;
use rayon::prelude::*;

use super::medium::{Lanes, SpectralLanes, LANES};
use super::{solar_source, Renderer};
use crate::spectrum::xyz_to_rec709;

/// Wavelength spacing of the transmittance's colour, nm.
pub const STEP_NM: f64 = 5.0;
/// Simpson panels per shell piece at least, their largest rise in
/// altitude and their longest length, m. The profiles fall with scale
/// heights of kilometres (linear between the medium's nodes 50 m apart):
/// 500 m panels keep the zenith's Rayleigh depth within 1e-4 of the exact
/// column (tested).
const MIN_PANELS: usize = 4;
const PANEL_RISE_M: f64 = 500.0;
const PANEL_LENGTH_M: f64 = 20_000.0;

/// The channels of a layer by name (as in [`crate::scene::OUTPUT_LAYERS`]).
pub fn channel_names(layer: &str) -> &'static [&'static str] {
    match layer {
        "sky" => &["sky.R", "sky.G", "sky.B"],
        "sun" => &["sun.R", "sun.G", "sun.B"],
        "ground" => &["ground.R", "ground.G", "ground.B"],
        "variance" => &["variance.Y"],
        "transmittance" => &["transmittance.R", "transmittance.G", "transmittance.B", "A"],
        "Z" => &["Z"],
        _ => &[],
    }
}

/// What one view ray gives the layers.
#[derive(Clone, Copy, Debug)]
struct RaySummary {
    rgb: [f64; 3],
    alpha: f64,
    z: f64,
}

/// Bytes per pixel of the variance layer's sums: the pass and running
/// sums (f64) and the pass's splats (f32).
pub(super) const VARIANCE_SUMS_BYTES: u64 = 5 * 8 + 4;

impl Renderer {
    /// Bytes per pixel the layers of this scene's output add at the end
    /// of a render: their f32 planes and the RGB image's planes beside them.
    pub fn layer_bytes_per_pixel(&self) -> u64 {
        let layers = &self.scene.output.layers;
        if layers.is_empty() {
            return 0;
        }
        let channels: usize = layers.iter().map(|l| channel_names(l).len()).sum();
        // The path layers' sums: the ground's exact XYZ and whether each
        // pixel's centre sees the ground (the sun's few sums are left out).
        let exact = super::exact::ExactPlane::BYTES_PER_PIXEL as u64;
        let sums = if self.path_layers() { exact + 1 } else { 0 }
            + if self.variance_layer() {
                VARIANCE_SUMS_BYTES
            } else {
                0
            };
        4 * (3 + channels as u64) + sums
    }

    /// Whether the films keep the variance layer's sums: the layer is
    /// asked for, or a noise target needs them
    /// ([`super::noise_estimate`]).
    pub fn variance_sums(&self) -> bool {
        self.variance_layer() || self.scene.render.noise_percent.is_some()
    }

    /// Whether the output has any of the layers estimated from the paths
    /// ([`super::film_layers::PATH_LAYERS`]).
    pub fn path_layers(&self) -> bool {
        self.scene
            .output
            .layers
            .iter()
            .any(|l| super::film_layers::PATH_LAYERS.contains(&l.as_str()))
    }

    /// Whether the output has the `variance` layer.
    pub fn variance_layer(&self) -> bool {
        self.scene.output.layers.iter().any(|l| l == "variance")
    }

    /// Whether the view ray along `dir` (unit) meets the ground.
    pub fn meets_ground(&self, dir: DVec3) -> bool {
        self.medium
            .span(self.observer_m, dir)
            .is_some_and(|s| s.hits_ground)
    }

    /// Per pixel (row-major), whether the view ray through its centre
    /// meets the ground; `false` where no ray goes through it.
    pub fn centre_ground(&self) -> Vec<bool> {
        let (width, height) = (self.scene.render.width, self.scene.render.height);
        (0..height)
            .flat_map(|y| (0..width).map(move |x| (x, y)))
            .map(|(x, y)| {
                self.camera
                    .direction(f64::from(x) + 0.5, f64::from(y) + 0.5)
                    .and_then(|dir| self.medium.span(self.observer_m, dir))
                    .is_some_and(|s| s.hits_ground)
            })
            .collect()
    }

    /// Spectral transmittance from the observer along `dir` (unit) to the
    /// top of the atmosphere or the ground, at each of `wavelengths_nm`,
    /// and whether the ray meets the ground and at what distance.
    pub fn view_transmittance(
        &self,
        dir: DVec3,
        wavelengths_nm: &[f64],
    ) -> (Vec<f64>, Option<f64>) {
        let groups = self.lane_groups(wavelengths_nm);
        self.transmittance_groups(dir, &groups, wavelengths_nm.len())
    }

    fn lane_groups(&self, wavelengths_nm: &[f64]) -> Vec<SpectralLanes> {
        let source = solar_source(&self.scene);
        wavelengths_nm
            .chunks(LANES)
            .map(|chunk| {
                let mut w = [chunk[0]; LANES];
                w[..chunk.len()].copy_from_slice(chunk);
                SpectralLanes::with_source(Lanes::from(w), chunk.len(), &self.medium, &source)
            })
            .collect()
    }

    fn transmittance_groups(
        &self,
        dir: DVec3,
        groups: &[SpectralLanes],
        n: usize,
    ) -> (Vec<f64>, Option<f64>) {
        let origin = self.observer_m;
        let mut depth = vec![0.0; groups.len() * LANES];
        let Some(span) = self.medium.span(origin, dir) else {
            return (vec![1.0; n], None);
        };
        for (t0, t1) in self.medium.pieces(origin, dir, span) {
            let (r0, r1) = ((origin + dir * t0).length(), (origin + dir * t1).length());
            let panels = ((r1 - r0).abs() / PANEL_RISE_M)
                .max((t1 - t0) / PANEL_LENGTH_M)
                .ceil() as usize;
            // Even, for Simpson's rule.
            let panels = panels.max(MIN_PANELS).next_multiple_of(2);
            for (t, weight) in crate::physics::quadrature::simpson(t0, t1, panels) {
                let r = (origin + dir * t).length();
                for (g, lanes) in groups.iter().enumerate() {
                    let c = self.medium.coefficients(r, lanes);
                    for j in 0..LANES {
                        depth[g * LANES + j] += weight * c.extinction(j);
                    }
                }
            }
        }
        let ground = span.hits_ground.then_some(span.t_exit);
        (depth[..n].iter().map(|d| (-d).exp()).collect(), ground)
    }

    /// The channels of `layers` (names from [`crate::scene::OUTPUT_LAYERS`],
    /// each once, in their order), each `width`×`height` row-major, named
    /// as in [`channel_names`].
    pub fn layer_channels(&self, layers: &[String]) -> Vec<(String, Vec<f32>)> {
        if !layers.iter().any(|l| l == "transmittance" || l == "Z") {
            return Vec::new();
        }
        let (width, height) = (self.scene.render.width, self.scene.render.height);
        let (from, to) = self.cmf.range_nm();
        let count = ((to - from) / STEP_NM).floor() as usize + 1;
        let wavelengths: Vec<f64> = (0..count).map(|i| from + i as f64 * STEP_NM).collect();
        let bars: Vec<[f64; 3]> = wavelengths.iter().map(|&w| self.cmf.xyz_bar(w)).collect();
        let white_xyz = bars
            .iter()
            .fold([0.0; 3], |a, b| [a[0] + b[0], a[1] + b[1], a[2] + b[2]]);
        let white = xyz_to_rec709(white_xyz);
        let want_t = layers.iter().any(|l| l == "transmittance");
        let groups = if want_t {
            self.lane_groups(&wavelengths)
        } else {
            Vec::new()
        };
        // The atmosphere is spherically symmetric about the observer's
        // vertical: a ray's layers depend on its direction's vertical
        // component alone, so a pixel whose component equals its left
        // neighbour's bit for bit (every pixel of an equirect row) takes its
        // values.
        let up = self.observer_m.normalize();
        let summary = |dir: DVec3| {
            let (ground, rgb, alpha) = if want_t {
                let (t, ground) = self.transmittance_groups(dir, &groups, wavelengths.len());
                let mut xyz = [0.0; 3];
                for (tv, bar) in t.iter().zip(&bars) {
                    for c in 0..3 {
                        xyz[c] += tv * bar[c];
                    }
                }
                let rgb = xyz_to_rec709(xyz);
                let alpha = if ground.is_some() {
                    1.0
                } else {
                    1.0 - xyz[1] / white_xyz[1]
                };
                (ground, [0, 1, 2].map(|c| rgb[c] / white[c]), alpha)
            } else {
                let ground = self
                    .medium
                    .span(self.observer_m, dir)
                    .filter(|s| s.hits_ground)
                    .map(|s| s.t_exit);
                (ground, [0.0; 3], 0.0)
            };
            RaySummary {
                rgb,
                alpha,
                z: ground.unwrap_or(f64::INFINITY),
            }
        };
        let rows: Vec<Vec<RaySummary>> = (0..height)
            .into_par_iter()
            .map(|y| {
                let mut last: Option<(u64, RaySummary)> = None;
                (0..width)
                    .map(|x| {
                        let Some(dir) = self
                            .camera
                            .direction(f64::from(x) + 0.5, f64::from(y) + 0.5)
                        else {
                            return RaySummary {
                                rgb: [0.0; 3],
                                alpha: 0.0,
                                z: f64::INFINITY,
                            };
                        };
                        let dir = dir.normalize();
                        let key = dir.dot(up).to_bits();
                        match last {
                            Some((k, s)) if k == key => s,
                            _ => {
                                let s = summary(dir);
                                last = Some((key, s));
                                s
                            }
                        }
                    })
                    .collect()
            })
            .collect();
        let summaries: Vec<RaySummary> = rows.into_iter().flatten().collect();
        let plane = |f: &dyn Fn(&RaySummary) -> f64| -> Vec<f32> {
            summaries.iter().map(|s| f(s) as f32).collect()
        };
        let mut channels = Vec::new();
        for layer in layers {
            let names = channel_names(layer);
            match layer.as_str() {
                "transmittance" => {
                    for (c, name) in names.iter().take(3).enumerate() {
                        channels.push(((*name).to_owned(), plane(&|s| s.rgb[c])));
                    }
                    channels.push((names[3].to_owned(), plane(&|s| s.alpha)));
                }
                "Z" => channels.push((names[0].to_owned(), plane(&|s| s.z))),
                _ => {}
            }
        }
        channels
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::Atmosphere;
    use crate::render::camera::direction_from_az_el;
    use crate::scene::Scene;

    #[test]
    fn without_aerosols_and_ozone_the_transmittance_is_the_rayleigh_depths() {
        let mut scene = Scene::default();
        scene.atmosphere.aerosols = false;
        scene.atmosphere.ozone = false;
        scene.render.width = 4;
        scene.render.height = 2;
        let renderer = Renderer::new(&scene).unwrap();
        let atmosphere = Atmosphere::new(scene.atmosphere.clone());
        let altitude = scene.observer.altitude_m;
        let wavelengths = [400.0, 550.0, 700.0];
        // Straight up: the vertical Rayleigh depth; 60° from the zenith on
        // a flat-enough path: close to twice it (checked loosely, the
        // sphere's curvature lengthens it by < 1 %).
        let (up, ground) =
            renderer.view_transmittance(direction_from_az_el(0.0, 90.0), &wavelengths);
        assert!(ground.is_none());
        let (slant, _) = renderer.view_transmittance(direction_from_az_el(0.0, 30.0), &wavelengths);
        for (k, &w) in wavelengths.iter().enumerate() {
            let tau = atmosphere.vertical_optical_depth(altitude, w).rayleigh;
            let got = -up[k].ln();
            assert!(
                (got - tau).abs() < 1e-4 * tau,
                "{w} nm: optical depth {got} against {tau}"
            );
            let got = -slant[k].ln();
            assert!(
                (got / tau - 2.0).abs() < 0.01,
                "{w} nm: slant depth {got} against 2 × {tau}"
            );
        }
        // Down: to the ground, at the exact sphere intersection.
        let dir = direction_from_az_el(0.0, -30.0);
        let (_, ground) = renderer.view_transmittance(dir, &wavelengths);
        let o = renderer.observer_m;
        let r = scene.atmosphere.planet_radius_m;
        let b = o.dot(dir);
        let t = -b - (b * b - o.length_squared() + r * r).sqrt();
        let z = ground.expect("meets the ground");
        assert!((z - t).abs() < 1e-6 * t.max(1.0), "{z} against {t}");
    }

    #[test]
    fn the_memory_estimate_counts_the_layers_planes() {
        let mut scene = Scene::default();
        scene.render.width = 40;
        scene.render.height = 20;
        let plain = Renderer::new(&scene).unwrap().memory_needed_bytes();
        scene.output.layers = vec!["transmittance".into(), "Z".into()];
        let layered = Renderer::new(&scene).unwrap().memory_needed_bytes();
        // R, G, B, four transmittance channels and Z: 8 f32 planes.
        assert_eq!(layered - plain, 40 * 20 * 8 * 4);
    }
}
