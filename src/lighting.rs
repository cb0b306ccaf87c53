//! What a lighting artist needs beside the panorama: where the Sun is in the
//! image, how bright and what colour it is at the observer, and how much
//! light the sky alone sheds on a horizontal plane. Written into every EXR
//! header ([`metadata`]), so the Sun can go into another renderer as a
//! directional light and the sky as an environment map.
//!
//! # The Sun at the observer
//!
//! Its spectral irradiance is the top-of-atmosphere spectrum, scaled by
//! 1/d² for the Earth–Sun distance, times the direct transmittance along
//! the ray from the observer toward the disc's centre,
//! T(λ) = exp(−∫ σₜ(h(s), λ) ds), the extinction of air, ozone and
//! aerosols integrated by Simpson's rule along the straight ray with
//! s = s_top·t² (steps dense near the observer, where the air is dense);
//! zero where the ray meets the ground. Illuminance on a plane normal to the
//! Sun: E_v = K_m ∫ E(λ) T(λ) ȳ(λ) dλ; colour: the XYZ of E·T as linear
//! Rec.709 (scaled to Y = 1) and CIE xy.
//!
//! # The sky on a horizontal plane
//!
//! E_sky = Σ L_v cos θ ΔΩ over the pixels above the horizon, where the
//! camera covers the upper hemisphere (an equirect map; a fisheye of at
//! least 180°). The pixels within the Sun's disc plus one pixel diagonal
//! hold the disc's light, which belongs to the Sun: they take the mean
//! luminance of the ring around them instead.

use glam::DVec3;

use crate::atmosphere::Atmosphere;
use crate::output::RgbImage;
use crate::physics::sun;
use crate::render::Camera;
use crate::scene::{CameraKind, Scene};
use crate::spectrum::{chromaticity, xyz_to_rec709, ColourMatching, K_M};

/// Intervals of the Simpson rule along the ray toward the Sun (even).
const STEPS: usize = 1000;

/// The direct transmittance from `altitude_m` toward elevation
/// `elevation_deg` at `wavelength_nm` (0 where the ray meets the ground).
pub fn direct_transmittance(
    atmosphere: &Atmosphere,
    altitude_m: f64,
    elevation_deg: f64,
    wavelength_nm: f64,
) -> f64 {
    let planet = atmosphere.params.planet_radius_m;
    let top = atmosphere.top_radius_m();
    let r0 = planet + altitude_m;
    let mu = elevation_deg.to_radians().sin();
    // r(s)² = r0² + 2 r0 μ s + s²; the ray meets the ground where that is
    // R² for some s > 0.
    let ground = (r0 * mu).powi(2) - (r0 * r0 - planet * planet);
    if mu < 0.0 && ground >= 0.0 {
        return 0.0;
    }
    if r0 >= top {
        return 1.0;
    }
    let s_top = -r0 * mu + ((r0 * mu).powi(2) + top * top - r0 * r0).sqrt();
    let extinction = |s: f64| {
        let h = (r0 * r0 + 2.0 * r0 * mu * s + s * s).sqrt() - planet;
        atmosphere.rayleigh_scattering_per_m(h, wavelength_nm)
            + atmosphere.ozone_absorption_per_m(h, wavelength_nm)
            + atmosphere.aerosol_extinction_per_m(h, wavelength_nm)
    };
    // s = s_top t², ds = 2 s_top t dt.
    let f = |t: f64| extinction(s_top * t * t) * 2.0 * s_top * t;
    let depth: f64 = crate::physics::quadrature::simpson(0.0, 1.0, STEPS)
        .map(|(t, w)| w * f(t))
        .sum();
    (-depth).exp()
}

/// The Sun as the observer receives it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunLight {
    /// Illuminance on a plane facing the Sun, lux.
    pub illuminance_lux: f64,
    /// Colour as linear Rec.709, scaled to luminance 1.
    pub rec709: [f64; 3],
    /// CIE 1931 chromaticity (the scene's colour-matching functions).
    pub xy: (f64, f64),
}

/// The Sun's light at the scene's observer (point source at the disc's
/// centre; see the module documentation). `None` where it does not reach
/// the observer (below the horizon or behind the planet).
pub fn sun_light(scene: &Scene) -> Option<SunLight> {
    let atmosphere = Atmosphere::new(scene.atmosphere.clone());
    let cmf = ColourMatching::get(scene.render.observer);
    let scale = if scene.render.unit_sun {
        None
    } else {
        Some(scene.sun_distance_au().powi(-2))
    };
    // The scene's spectrum file, if it names one (a validated scene's
    // reads), else the built-in table.
    let file = scene
        .sun_spectrum()
        .ok()
        .flatten()
        .map(|table| sun::Spectrum::from_tabulated(&table));
    let spectrum = file.as_ref().unwrap_or_else(|| sun::Spectrum::get());
    let transmitted = |wavelength_nm: f64| {
        let top = scale.map_or(1.0, |s| s * spectrum.irradiance_w_m2_nm(wavelength_nm));
        top * direct_transmittance(
            &atmosphere,
            scene.observer.altitude_m,
            scene.sun.elevation_deg,
            wavelength_nm,
        )
    };
    let xyz = cmf.integrate(transmitted).map(|v| K_M * v);
    if xyz[1].is_nan() || xyz[1] <= 0.0 {
        return None;
    }
    Some(SunLight {
        illuminance_lux: xyz[1],
        rec709: xyz_to_rec709(xyz.map(|v| v / xyz[1])),
        xy: chromaticity(xyz),
    })
}

/// The sky's illuminance on a horizontal plane at the observer, lux, from
/// the rendered `image` (see the module documentation); `None` where the
/// camera does not cover the upper hemisphere.
pub fn sky_horizontal_illuminance(scene: &Scene, image: &RgbImage) -> Option<f64> {
    let covers = match scene.camera.kind {
        CameraKind::Equirect => true,
        CameraKind::Fisheye => scene.camera.fov_deg >= 180.0,
        CameraKind::Perspective => false,
    };
    if !covers {
        return None;
    }
    let camera = Camera::new(&scene.camera, image.width, image.height);
    let sun = crate::render::direction_from_az_el(scene.sun.azimuth_deg, scene.sun.elevation_deg);
    let (w, h) = (image.width as usize, image.height as usize);
    // One pixel's diagonal, in radians, where it is largest (the equator
    // of an equirect map; the centre of a fisheye).
    let pixel_rad = match scene.camera.kind {
        CameraKind::Equirect => {
            std::f64::consts::PI / h as f64 * 2f64.sqrt().max(2.0 * h as f64 / w as f64)
        }
        _ => scene.camera.fov_deg.to_radians() / w.min(h) as f64 * 2f64.sqrt(),
    };
    let exclusion = sun::ANGULAR_RADIUS_DEG.to_radians() + pixel_rad;
    let (mut sum, mut ring_sum, mut ring_n, mut excluded_weight) = (0.0, 0.0, 0usize, 0.0);
    for y in 0..h {
        for x in 0..w {
            let Some(dir) = camera.direction(x as f64 + 0.5, y as f64 + 0.5) else {
                continue;
            };
            let [r, g, b] = image.pixels[y * w + x].map(f64::from);
            let luminance = crate::spectrum::rec709_luminance([r, g, b]);
            let angle = dir.angle_between(sun);
            if (exclusion..2.0 * exclusion).contains(&angle) && luminance.is_finite() {
                ring_sum += luminance;
                ring_n += 1;
            }
            if dir.z <= 0.0 || !luminance.is_finite() {
                continue;
            }
            let weight = dir.z / camera.pixels_per_sr(dir);
            if angle < exclusion {
                excluded_weight += weight;
            } else {
                sum += luminance * weight;
            }
        }
    }
    let ring_mean = if ring_n > 0 {
        ring_sum / ring_n as f64
    } else {
        0.0
    };
    Some(sum + ring_mean * excluded_weight)
}

/// The lighting attributes of a render's EXR header: the Sun's direction
/// (azimuth, elevation, the pixel it falls on, if in view), its illuminance
/// and colour at the observer, and the sky's horizontal illuminance.
pub fn metadata(scene: &Scene, image: &RgbImage) -> Vec<(String, String)> {
    let mut out = vec![
        (
            "skyrender:sun_azimuth_deg".to_owned(),
            format!("{:.4}", scene.sun.azimuth_deg.rem_euclid(360.0)),
        ),
        (
            "skyrender:sun_elevation_deg".to_owned(),
            format!("{:.4}", scene.sun.elevation_deg),
        ),
    ];
    let camera = Camera::new(&scene.camera, image.width, image.height);
    let dir: DVec3 =
        crate::render::direction_from_az_el(scene.sun.azimuth_deg, scene.sun.elevation_deg);
    if let Some((px, py)) = camera.project(dir) {
        if (0.0..f64::from(image.width)).contains(&px)
            && (0.0..f64::from(image.height)).contains(&py)
        {
            out.push(("skyrender:sun_pixel".to_owned(), format!("{px:.2} {py:.2}")));
        }
    }
    let unit = if scene.render.unit_sun {
        " (per unit top-of-atmosphere irradiance)"
    } else {
        ""
    };
    match sun_light(scene) {
        Some(sun) => {
            out.push((
                "skyrender:sun_illuminance_lux".to_owned(),
                format!("{:.6e}{unit}", sun.illuminance_lux),
            ));
            out.push((
                "skyrender:sun_color_rec709".to_owned(),
                format!(
                    "{:.6} {:.6} {:.6}",
                    sun.rec709[0], sun.rec709[1], sun.rec709[2]
                ),
            ));
            out.push((
                "skyrender:sun_color_xy".to_owned(),
                format!("{:.6} {:.6}", sun.xy.0, sun.xy.1),
            ));
        }
        None => out.push(("skyrender:sun_illuminance_lux".to_owned(), "0".to_owned())),
    }
    if let Some(e) = sky_horizontal_illuminance(scene, image) {
        out.push((
            "skyrender:sky_horizontal_illuminance_lux".to_owned(),
            format!("{e:.6e}{unit}"),
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::AtmosphereParams;

    #[test]
    fn toward_the_zenith_the_transmittance_is_the_vertical_optical_depths() {
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        for wavelength_nm in [400.0, 550.0, 700.0] {
            let depth = atmosphere.vertical_optical_depth(0.0, wavelength_nm);
            let tau = depth.rayleigh + depth.ozone + depth.aerosol;
            let t = direct_transmittance(&atmosphere, 0.0, 90.0, wavelength_nm);
            assert!(
                (t.ln() + tau).abs() < 1e-4 * tau,
                "{wavelength_nm}: {t} vs {tau}"
            );
            // Below the astronomical horizon from the ground: the planet.
            assert_eq!(
                direct_transmittance(&atmosphere, 0.0, -1.0, wavelength_nm),
                0.0
            );
        }
        // At 30° the path is nearly the plane-parallel 1/sin e = 2, a little
        // less: the sphere's curvature shortens a slant path through a layer
        // at height H to about 1/√(sin² e + 2H/R) of the vertical, 0.5 %
        // less for the air's 8 km scale height.
        let depth = atmosphere.vertical_optical_depth(0.0, 550.0);
        let tau = depth.rayleigh + depth.ozone + depth.aerosol;
        let slant = -direct_transmittance(&atmosphere, 0.0, 30.0, 550.0).ln();
        let ratio = slant / tau;
        assert!((1.985..2.0).contains(&ratio), "{ratio}");
    }

    /// Above the air, the Sun's illuminance is the solar illuminance
    /// constant: 133.8 klux (Darula, Kittler & Gueymard, "Reference
    /// luminous solar constant and solar luminance for illuminance
    /// calculations", Solar Energy 79, 559, 2005); the E-490 table we use
    /// is 0.4 % above the modern total (README), within 1.5 % here.
    #[test]
    fn above_the_air_the_sun_gives_the_luminous_solar_constant() {
        let mut scene = Scene::preset("space").unwrap();
        scene.observer.altitude_m = 200_000.0;
        scene.sun.elevation_deg = 30.0;
        let sun = sun_light(&scene).unwrap();
        assert!(
            (sun.illuminance_lux / 133_800.0 - 1.0).abs() < 0.015,
            "{sun:?}"
        );
        // The Sun's colour outside the air: near the blackbody locus at
        // ~5 800 K (x ≈ 0.32–0.33).
        assert!(
            (0.31..0.34).contains(&sun.xy.0) && (0.32..0.35).contains(&sun.xy.1),
            "{sun:?}"
        );
        // From the ground at midday it is dimmer and yellower; at sunset,
        // much dimmer and redder.
        let midday = sun_light(&Scene::preset("midday").unwrap()).unwrap();
        let sunset = sun_light(&Scene::preset("sunset").unwrap()).unwrap();
        assert!(midday.illuminance_lux < sun.illuminance_lux && midday.xy.0 > sun.xy.0);
        assert!(sunset.illuminance_lux < 0.1 * midday.illuminance_lux && sunset.xy.0 > midday.xy.0);
        assert!(sun_light(&Scene::preset("twilight").unwrap()).is_none());
    }

    /// A sky of uniform luminance L sheds π L on a horizontal plane.
    #[test]
    fn a_uniform_sky_sheds_pi_times_its_luminance() {
        for (kind, w, h) in [
            (CameraKind::Equirect, 256, 128),
            (CameraKind::Fisheye, 200, 200),
        ] {
            let mut scene = Scene::preset("midday").unwrap();
            scene.camera.kind = kind;
            scene.camera.fov_deg = 180.0;
            scene.sun.elevation_deg = 40.0;
            let image = RgbImage {
                width: w,
                height: h,
                pixels: vec![[2.0; 3]; (w * h) as usize],
            };
            let e = sky_horizontal_illuminance(&scene, &image).unwrap();
            assert!(
                (e / (std::f64::consts::PI * 2.0) - 1.0).abs() < 0.01,
                "{kind:?}: {e}"
            );
        }
        let mut perspective = Scene::preset("midday").unwrap();
        perspective.camera.kind = CameraKind::Perspective;
        let image = RgbImage {
            width: 4,
            height: 4,
            pixels: vec![[1.0; 3]; 16],
        };
        assert!(sky_horizontal_illuminance(&perspective, &image).is_none());
    }
}
