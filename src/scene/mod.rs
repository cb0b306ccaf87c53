//! The scene description: sun, observer, camera, atmosphere and render
//! settings, serialisable as TOML, with validation that names the parameter
//! and its valid range.

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::atmosphere::AtmosphereParams;
use crate::error::{check_count, check_range};
pub use crate::error::{show_number, SceneError};
use crate::physics::planet::Planet;
use crate::physics::solar_position::{self, SunPlacement};
use crate::plan::IntegratorOptions;
use crate::spectrum::Observer;

mod mode;
mod output;
mod planet;

pub use mode::{RenderMode, DEFAULT_FAST_SCALE, MAX_FAST_SCALE};
pub use output::{OutputParams, MAX_SPECTRAL_BANDS, OUTPUT_LAYERS};
use planet::with_planet_defaults;
pub use planet::PlanetParams;

/// Highest observer altitude accepted, m.
pub const MAX_ALTITUDE_M: f64 = 1e8;

/// Where the Sun is and how far: by hand (elevation and azimuth), or from a
/// date, a time and a place ([`crate::physics::solar_position`]), which then
/// sets the elevation and azimuth ([`Scene::place_sun`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Sun {
    /// Elevation above the observer's astronomical horizon, degrees (true,
    /// unrefracted: the renderer has no refraction).
    pub elevation_deg: f64,
    /// Azimuth, degrees clockwise from north.
    pub azimuth_deg: f64,
    /// Local date and time with its UTC offset (RFC 3339,
    /// `2013-05-27T11:45:00-04:00`); with `latitude_deg` and
    /// `longitude_deg`, places the Sun by NREL's SPA.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub date_time: Option<String>,
    /// Observer's latitude, degrees north (−90 to 90).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub latitude_deg: Option<f64>,
    /// Observer's longitude, degrees east (−180 to 180).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub longitude_deg: Option<f64>,
    /// The Sun's distance from the planet, AU, scaling the solar
    /// irradiance by 1/d²; unset: the date's distance where `date_time` is
    /// given, else 1 AU (the solar spectrum's own distance; a planet other
    /// than the Earth sets its own, [`Scene::set_planet`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub distance_au: Option<f64>,
    /// The Sun's spectral irradiance at 1 AU, a CSV file
    /// `wavelength_nm,irradiance` in W m⁻² nm⁻¹ (relative to the scene
    /// file's folder), in place of the built-in ASTM E-490 table; scaled by
    /// 1/`distance_au`² as the table is.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spectrum: Option<std::path::PathBuf>,
    /// Whether the disc is limb-darkened (Neckel & Labs 1994,
    /// [`crate::physics::sun::NECKEL_LABS_1994`]) rather than uniform; the
    /// disc's irradiance is the same either way. Off by default: the
    /// sun's next-event samples are weighted by the darkened radiance, which
    /// raised the sunset sky's noise 1.18× (`BENCHMARKS.md`).
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub limb_darkening: bool,
}

impl Default for Sun {
    fn default() -> Self {
        Self {
            elevation_deg: 45.0,
            azimuth_deg: 180.0,
            date_time: None,
            latitude_deg: None,
            longitude_deg: None,
            distance_au: None,
            spectrum: None,
            limb_darkening: false,
        }
    }
}

/// Where the observer stands.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ObserverPosition {
    /// Height of the eye above the ground, m.
    pub altitude_m: f64,
}

impl Default for ObserverPosition {
    fn default() -> Self {
        Self { altitude_m: 2.0 }
    }
}

/// Camera projections.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum CameraKind {
    /// Rectilinear, horizontal field of view `fov_deg`.
    Perspective,
    /// Full-sphere latitude–longitude map, 2:1.
    #[default]
    Equirect,
    /// Equidistant angular fisheye looking at the zenith.
    Fisheye,
}

impl CameraKind {
    /// Every camera kind, in the app's order.
    pub const ALL: [CameraKind; 3] = [Self::Perspective, Self::Equirect, Self::Fisheye];

    /// The kind's name as the CLI and TOML write it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Perspective => "perspective",
            Self::Equirect => "equirect",
            Self::Fisheye => "fisheye",
        }
    }

    /// The field of view a camera of this kind gets when none is given:
    /// 180° for a fisheye (the whole sky), 90° otherwise.
    pub fn default_fov_deg(self) -> f64 {
        match self {
            Self::Fisheye => 180.0,
            Self::Perspective | Self::Equirect => 90.0,
        }
    }

    /// The kind named `name`, or an error naming the valid ones.
    pub fn parse(name: &str) -> Result<Self, SceneError> {
        Self::ALL
            .into_iter()
            .find(|k| k.name().eq_ignore_ascii_case(name))
            .ok_or_else(|| {
                SceneError::new(
                    "camera",
                    format!("unknown camera '{name}' (valid: perspective, equirect, fisheye)"),
                )
            })
    }
}

/// The camera: its kind, orientation and field of view.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CameraParams {
    /// Perspective, equirectangular or fisheye.
    pub kind: CameraKind,
    /// Perspective: horizontal field of view; fisheye: full field of view; degrees.
    pub fov_deg: f64,
    /// Azimuth of the view centre, degrees clockwise from north.
    pub yaw_deg: f64,
    /// Elevation of the view centre, degrees.
    pub pitch_deg: f64,
    /// Rotation about the view axis, degrees (clockwise as seen by the viewer).
    pub roll_deg: f64,
}

impl Default for CameraParams {
    fn default() -> Self {
        Self {
            kind: CameraKind::Equirect,
            fov_deg: 90.0,
            yaw_deg: 0.0,
            pitch_deg: 0.0,
            roll_deg: 0.0,
        }
    }
}

/// Most samples per pixel (passes) a scene may ask for, 2²⁰: with up to 16
/// samples per pass (adaptive sampling) that is 2²⁴ samples, about where an
/// f32 sum (24-bit significand) stops registering one more — as the splat
/// layer's sums are (the camera samples' are exact, `render::exact`). The
/// splat layer, with the sun below 10°, takes ~100 splats per pixel and
/// pass, so it reaches that after ~10⁵ passes: further passes refine the
/// camera's part only.
pub const MAX_SPP: u32 = 1 << 20;
/// Most pixels a render may have: 16384 × 8192, the largest panoramas in
/// common use. Memory grows with the pixels (68 bytes a pixel, 80 with the
/// sun below 10° and its splat layer, `Renderer::memory_needed_bytes`), so
/// this is about 8.5 GiB, 10 GiB at sunset; `render` checks before the
/// first pass that it can have it (`Renderer::check_memory`).
pub const MAX_PIXELS: u64 = 16_384 * 8_192;
/// The least noise target, percent (a target of 0 is never met).
pub const MIN_NOISE_PERCENT: f64 = 0.01;
/// The shortest time limit, seconds.
pub const MIN_TIME_LIMIT_S: f64 = 0.001;
/// The longest time limit, seconds (a year).
pub const MAX_TIME_LIMIT_S: f64 = 365.0 * 86_400.0;
/// Largest seed: TOML's integers are signed 64-bit, so a larger one could
/// not be read back from the scene a render embeds in its EXR.
pub const MAX_SEED: u64 = i64::MAX as u64;

/// How the image is rendered.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RenderParams {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Samples (camera paths) per pixel: the passes over the image, or,
    /// with a noise target or a time limit, the most passes.
    pub spp: u32,
    /// Stop once the image's estimated relative noise is at most this many
    /// percent (after at least [`crate::render::noise_estimate::MIN_PASSES`]
    /// passes; see [`crate::render::noise_estimate`]); `None`: `spp` passes.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub noise_percent: Option<f64>,
    /// Start no pass expected (as long as the last) to end later than this
    /// many seconds after the first pass began (the atmosphere's tables,
    /// made before it, not counted); the first pass always runs (the first
    /// three with the `variance` layer, whose spread needs them). `None`:
    /// no limit.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_limit_s: Option<f64>,
    /// Seed of the random numbers (same seed, same image).
    pub seed: u64,
    /// Top-of-atmosphere irradiance of 1 W m⁻² nm⁻¹ at every wavelength.
    pub unit_sun: bool,
    /// Colour-matching functions.
    pub observer: Observer,
    /// PNG exposure in EV; `None` = automatic.
    pub exposure_ev: Option<f64>,
    /// After the first full pass, give each pixel 1–16 samples per pass, more
    /// where its neighbourhood is noisy (unbiased: see
    /// [`crate::render::film`]); `spp` then counts passes, the least samples
    /// a pixel gets.
    pub adaptive_sampling: bool,
    /// Read each pixel together with its mirror image in the sun's vertical
    /// plane where the camera maps that reflection onto the pixel grid, and
    /// each half of a pixel with its mirror image's where an equirect
    /// image's columns split it (unbiased: the sky is symmetric about that
    /// plane; see [`crate::render::film`]): about half the variance at no
    /// cost.
    pub mirror_symmetry: bool,
    /// The technique switches (`[render.integrator]`).
    pub integrator: IntegratorOptions,
    /// The reference (unbiased, the default) or the explicit fast mode.
    #[serde(skip_serializing_if = "RenderMode::is_reference")]
    pub mode: RenderMode,
    /// The fast mode's Monte Carlo correction runs at the image's width and
    /// height over this factor ([`crate::render::fast`]).
    #[serde(skip_serializing_if = "mode::is_default_fast_scale")]
    pub fast_scale: u32,
}

impl Default for RenderParams {
    fn default() -> Self {
        Self {
            width: 512,
            height: 256,
            spp: 64,
            noise_percent: None,
            time_limit_s: None,
            seed: 1,
            unit_sun: false,
            observer: Observer::JuddVos,
            exposure_ev: None,
            adaptive_sampling: true,
            mirror_symmetry: true,
            integrator: IntegratorOptions::default(),
            mode: RenderMode::Reference,
            fast_scale: DEFAULT_FAST_SCALE,
        }
    }
}

/// A complete scene.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct Scene {
    /// The sun's position.
    pub sun: Sun,
    /// The observer's position.
    pub observer: ObserverPosition,
    /// The camera.
    pub camera: CameraParams,
    /// The atmosphere and the planet.
    pub atmosphere: AtmosphereParams,
    /// How the image is rendered.
    pub render: RenderParams,
    /// What an EXR holds besides the RGB image (`[output]`).
    #[serde(skip_serializing_if = "OutputParams::is_plain")]
    pub output: OutputParams,
    /// The planet (`[planet]`); unset: the Earth.
    #[serde(skip_serializing_if = "PlanetParams::is_earth")]
    pub planet: PlanetParams,
}

/// A TOML error as one line: where (line and column) and what, e.g.
/// "line 2, column 8: unknown variant `ortho`, expected one of `perspective`,
/// `equirect`, `fisheye`" (the toml crate's own display spans several lines).
fn toml_error(text: &str, error: &toml::de::Error) -> SceneError {
    let place = error.span().map(|span| {
        let before = text.get(..span.start).unwrap_or(text);
        let line = before.matches('\n').count() + 1;
        let column = before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1;
        let key = key_at(text, span.start)
            .filter(|key| !error.message().contains(&format!("`{key}`")))
            .map(|key| format!("`{key}`: "))
            .unwrap_or_default();
        // `[[sun]]` makes an array of tables where a table belongs.
        let line_text = text[before.rfind('\n').map_or(0, |i| i + 1)..]
            .lines()
            .next()
            .unwrap_or_default()
            .trim();
        let hint = line_text
            .strip_prefix("[[")
            .and_then(|l| l.strip_suffix("]]"))
            .map(|name| format!(" (`[[{name}]]` is an array of tables: write `[{name}]`)"))
            .unwrap_or_default();
        (format!("line {line}, column {column}: {key}"), hint)
    });
    let (place, hint) = place.unwrap_or_default();
    SceneError::new("scene", format!("{place}{}{hint}", error.message().trim()))
}

/// The dotted key (`sun.elevation_deg`) that the TOML text defines at byte
/// `offset`: the table header above it (or the header itself, when the
/// offset falls on one) and the key left of the `=` on its line. Only for
/// the plain layout scene files have; `None` where that does not fit, so a
/// message never names a wrong key.
fn key_at(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    let start = text.get(..offset)?.rfind('\n').map_or(0, |i| i + 1);
    let end = text[start..].find('\n').map_or(text.len(), |i| start + i);
    let header = |line: &str| {
        let line = line.trim();
        let inner = line
            .strip_prefix("[[")
            .and_then(|l| l.split("]]").next())
            .or_else(|| line.strip_prefix('[').and_then(|l| l.split(']').next()))?;
        Some(inner.trim().replace([' ', '"'], ""))
    };
    let line = &text[start..end];
    if let Some(name) = header(line) {
        return Some(name);
    }
    let (key, _) = line.split_once('=')?;
    let key = key.trim().trim_matches('"');
    if key.is_empty() || key.contains(char::is_whitespace) {
        return None;
    }
    let table = text[..start].lines().rev().find_map(header);
    Some(match table {
        Some(table) if !table.is_empty() => format!("{table}.{key}"),
        _ => key.to_owned(),
    })
}

/// Largest scene file read: a scene is a few hundred bytes of TOML; a
/// larger file is not one (`--scene /dev/urandom` would read for ever).
pub const MAX_SCENE_FILE_BYTES: u64 = 1 << 20;

/// Built-in presets, shipped as TOML in `assets/presets/`.
pub const PRESETS: [(&str, &str); 8] = [
    ("midday", include_str!("../../assets/presets/midday.toml")),
    (
        "afternoon",
        include_str!("../../assets/presets/afternoon.toml"),
    ),
    ("sunset", include_str!("../../assets/presets/sunset.toml")),
    (
        "twilight",
        include_str!("../../assets/presets/twilight.toml"),
    ),
    ("space", include_str!("../../assets/presets/space.toml")),
    (
        "airliner",
        include_str!("../../assets/presets/airliner.toml"),
    ),
    (
        "mars-noon",
        include_str!("../../assets/presets/mars-noon.toml"),
    ),
    (
        "mars-sunset",
        include_str!("../../assets/presets/mars-sunset.toml"),
    ),
];

impl Scene {
    /// A built-in preset by name.
    pub fn preset(name: &str) -> Result<Self, SceneError> {
        let (_, text) = PRESETS
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .ok_or_else(|| {
                let names: Vec<_> = PRESETS.iter().map(|(n, _)| *n).collect();
                SceneError::new(
                    "preset",
                    format!("unknown preset '{name}' (valid: {})", names.join(", ")),
                )
            })?;
        Self::from_toml(text)
    }

    /// A scene from its TOML text; a relative `phase_file` is taken from
    /// the working directory.
    pub fn from_toml(text: &str) -> Result<Self, SceneError> {
        Self::from_toml_in(text, None)
    }

    /// [`Self::from_toml`] for a file in folder `base`, from which a
    /// relative `phase_file` is then taken.
    pub fn from_toml_in(text: &str, base: Option<&Path>) -> Result<Self, SceneError> {
        let table: toml::Table = toml::from_str(text).map_err(|e| toml_error(text, &e))?;
        // A fisheye's field of view defaults to 180° (the whole sky), a
        // perspective camera's to 90°: the shared field's default is the
        // perspective one, so fill in the fisheye's where the file is silent.
        let camera = table.get("camera").and_then(toml::Value::as_table);
        let fisheye_without_fov = camera.is_some_and(|c| {
            c.get("kind").and_then(toml::Value::as_str) == Some("fisheye")
                && !c.contains_key("fov_deg")
        });
        // From the text again, not from `table`: only then do serde's errors
        // (unknown fields, wrong types) keep their line and column.
        let mut scene: Self = toml::from_str(text).map_err(|e| toml_error(text, &e))?;
        if scene.planet.preset != Planet::Earth {
            // The planet's defaults where the file is silent (the file's
            // own keys have passed the check above, with their lines).
            scene = toml::Value::Table(with_planet_defaults(table, scene.planet.preset))
                .try_into()
                .map_err(|e: toml::de::Error| SceneError::new("planet", e.message()))?;
        }
        scene.atmosphere.planet = scene.planet.preset;
        if fisheye_without_fov {
            scene.camera.fov_deg = CameraKind::Fisheye.default_fov_deg();
        }
        if let Some(base) = base {
            let files = [
                scene.atmosphere.aerosol.phase_file.as_mut(),
                scene.atmosphere.profile.as_mut(),
            ];
            for file in files.into_iter().flatten() {
                if file.is_relative() {
                    *file = base.join(&*file);
                }
            }
        }
        if let Some(base) = base {
            scene.atmosphere.resolve_ground_file(base);
            if let Some(file) = &mut scene.sun.spectrum {
                if file.is_relative() {
                    *file = base.join(&*file);
                }
            }
        }
        scene.place_sun()?;
        scene.validate()?;
        Ok(scene)
    }

    /// Puts the scene on `planet`: its atmosphere becomes the planet's own
    /// ([`AtmosphereParams::for_planet`]) and the Sun its distance (a date
    /// and time, which place the Sun from the Earth, are dropped for
    /// another planet). Everything else stays.
    pub fn set_planet(&mut self, planet: Planet) {
        self.planet.preset = planet;
        self.atmosphere = AtmosphereParams::for_planet(planet);
        self.sun.distance_au = planet.sun_distance_au();
        if planet != Planet::Earth {
            self.sun.date_time = None;
        }
    }

    /// The Sun for the scene's date, time and place, if it has them.
    pub fn sun_from_date(&self) -> Result<Option<SunPlacement>, SceneError> {
        let Some(text) = &self.sun.date_time else {
            return Ok(None);
        };
        let fail = |parameter: &str, message: String| SceneError::new(parameter, message);
        let date_time =
            solar_position::parse_date_time(text).map_err(|e| fail("sun date_time", e))?;
        let (Some(latitude_deg), Some(longitude_deg)) =
            (self.sun.latitude_deg, self.sun.longitude_deg)
        else {
            return Err(fail(
                "sun date_time",
                "a date and time place the Sun only with latitude_deg and longitude_deg \
                 (--lat and --lon)"
                    .into(),
            ));
        };
        check_range("latitude (deg)", latitude_deg, -90.0, 90.0)?;
        check_range("longitude (deg)", longitude_deg, -180.0, 180.0)?;
        let delta_t_s = solar_position::estimated_delta_t_s(&date_time)
            .map_err(|e| fail("sun date_time", e))?;
        solar_position::sun_at(
            &date_time,
            latitude_deg,
            longitude_deg,
            self.observer.altitude_m,
            delta_t_s,
        )
        .map(Some)
        .map_err(|e| fail("sun date_time", e))
    }

    /// Sets the Sun's elevation and azimuth from the scene's date, time and
    /// place (if it has them; otherwise leaves them as given).
    pub fn place_sun(&mut self) -> Result<(), SceneError> {
        if let Some(sun) = self.sun_from_date()? {
            self.sun.elevation_deg = sun.elevation_deg;
            self.sun.azimuth_deg = sun.azimuth_deg;
        }
        Ok(())
    }

    /// The Earth–Sun distance the render uses, AU: `distance_au`, else the
    /// date's, else 1.
    pub fn sun_distance_au(&self) -> f64 {
        self.sun.distance_au.unwrap_or_else(|| {
            self.sun_from_date()
                .ok()
                .flatten()
                .map_or(1.0, |sun| sun.distance_au)
        })
    }

    /// The Sun's spectrum file's table, if `[sun] spectrum` names one.
    pub fn sun_spectrum(
        &self,
    ) -> Result<Option<std::sync::Arc<crate::physics::spectrum_file::Tabulated>>, SceneError> {
        use crate::physics::spectrum_file::{Quantity, Tabulated};
        self.sun
            .spectrum
            .as_deref()
            .map(|path| {
                Tabulated::cached(path, Quantity::Irradiance)
                    .map_err(|e| SceneError::new("sun.spectrum", e))
            })
            .transpose()
    }

    /// Reads a scene file: at most [`MAX_SCENE_FILE_BYTES`] of UTF-8 TOML.
    pub fn load(path: &Path) -> Result<Self, SceneError> {
        use std::io::Read as _;
        let fail = |reason: String| {
            SceneError::new(
                "scene file",
                format!("cannot read '{}': {reason}", path.display()),
            )
        };
        if path.is_dir() {
            return Err(fail("it is a directory".into()));
        }
        let file = std::fs::File::open(path).map_err(|e| fail(e.to_string()))?;
        let mut bytes = Vec::new();
        file.take(MAX_SCENE_FILE_BYTES + 1)
            .read_to_end(&mut bytes)
            .map_err(|e| fail(e.to_string()))?;
        if bytes.len() as u64 > MAX_SCENE_FILE_BYTES {
            return Err(fail(format!(
                "it is larger than {} KiB, so not a scene (a scene is a short TOML file)",
                MAX_SCENE_FILE_BYTES / 1024
            )));
        }
        let text = String::from_utf8(bytes).map_err(|e| {
            fail(format!(
                "it is not UTF-8 text (byte {})",
                e.utf8_error().valid_up_to()
            ))
        })?;
        Self::from_toml_in(&text, path.parent()).map_err(|e| SceneError {
            parameter: e.parameter,
            message: format!("{} (in '{}')", e.message, path.display()),
        })
    }

    /// The scene as TOML (the form `--scene` reads).
    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).expect("a scene always serialises")
    }

    /// Check every parameter; the error names the first invalid one and its range.
    pub fn validate(&self) -> Result<(), SceneError> {
        self.output.validate_spectral()?;
        check_range("sun elevation (deg)", self.sun.elevation_deg, -90.0, 90.0)?;
        check_range("sun azimuth (deg)", self.sun.azimuth_deg, -360.0, 720.0)?;
        if let Some(d) = self.sun.distance_au {
            // Mercury's perihelion (0.307 AU) to beyond Pluto's aphelion.
            check_range("sun distance (AU)", d, 0.3, 50.0)?;
        }
        if self.sun.date_time.is_some() && self.planet.preset != Planet::Earth {
            return Err(SceneError::new(
                "sun date_time",
                format!(
                    "places the Sun by the Earth's ephemeris (NREL's SPA), not from {}: \
                     give elevation_deg and azimuth_deg",
                    self.planet.preset.name()
                ),
            ));
        }
        if self.atmosphere.planet != self.planet.preset {
            return Err(SceneError::new(
                "planet",
                "the atmosphere belongs to another planet (set the planet with Scene::set_planet)",
            ));
        }
        if let Some(v) = self.sun.latitude_deg {
            check_range("latitude (deg)", v, -90.0, 90.0)?;
        }
        if let Some(v) = self.sun.longitude_deg {
            check_range("longitude (deg)", v, -180.0, 180.0)?;
        }
        self.sun_from_date()?;
        check_range(
            "altitude (m)",
            self.observer.altitude_m,
            0.0,
            MAX_ALTITUDE_M,
        )?;
        let fov_max = if self.camera.kind == CameraKind::Perspective {
            179.0
        } else {
            360.0
        };
        check_range("fov (deg)", self.camera.fov_deg, 1.0, fov_max)?;
        check_range("yaw (deg)", self.camera.yaw_deg, -3600.0, 3600.0)?;
        check_range("pitch (deg)", self.camera.pitch_deg, -90.0, 90.0)?;
        check_range("roll (deg)", self.camera.roll_deg, -360.0, 360.0)?;
        let a = &self.atmosphere;
        check_range("planet radius (m)", a.planet_radius_m, 1e5, 1e8)?;
        check_range("atmosphere top (m)", a.top_altitude_m, 1_000.0, 200_000.0)?;
        check_range("ground albedo", a.ground_albedo, 0.0, 1.0)?;
        a.ground()?;
        self.sun_spectrum()?;
        if let Some(du) = a.ozone_du {
            check_range("ozone column (DU)", du, 0.0, 2_000.0)?;
        }
        a.validate_aerosol()?;
        a.validate_profile()?;
        let r = &self.render;
        if r.width == 0 || r.width > 65_536 {
            return Err(SceneError::new(
                "width",
                format!("{} is outside the valid range 1 to 65536", r.width),
            ));
        }
        if r.height == 0 || r.height > 65_536 {
            return Err(SceneError::new(
                "height",
                format!("{} is outside the valid range 1 to 65536", r.height),
            ));
        }
        let pixels = u64::from(r.width) * u64::from(r.height);
        if pixels > MAX_PIXELS {
            return Err(SceneError::new(
                "width × height",
                format!(
                    "{} × {} = {pixels} pixels is more than the {MAX_PIXELS} (16384 × 8192) a render may have",
                    r.width, r.height
                ),
            ));
        }
        check_count("spp", r.spp as usize, 1, MAX_SPP as usize)?;
        if let Some(percent) = r.noise_percent {
            check_range("noise target (%)", percent, MIN_NOISE_PERCENT, 100.0)?;
        }
        if let Some(seconds) = r.time_limit_s {
            check_range(
                "time limit (s)",
                seconds,
                MIN_TIME_LIMIT_S,
                MAX_TIME_LIMIT_S,
            )?;
        }
        mode::validate(r.mode, r.fast_scale, &self.output)?;
        if r.seed > MAX_SEED {
            return Err(SceneError::new(
                "seed",
                format!("{} is outside the valid range 0 to {MAX_SEED}", r.seed),
            ));
        }
        if let Some(ev) = r.exposure_ev {
            check_range("exposure (EV)", ev, -50.0, 50.0)?;
        }
        let i = &r.integrator;
        let samples = crate::plan::MAX_SUNLIGHT_SAMPLES;
        let branches = crate::plan::MAX_BRANCHES;
        check_count(
            "wavelengths per path",
            i.wavelengths_per_path,
            1,
            crate::spectrum::LANES,
        )?;
        if let Some(n) = i.sunlight_samples {
            check_count("sunlight samples", n as usize, 0, samples)?;
        }
        check_count("shadow samples", i.shadow_samples as usize, 0, samples)?;
        if let Some(n) = i.camera_samples {
            check_count("camera samples", n as usize, 0, samples)?;
        }
        if let Some(n) = i.camera_branches {
            check_count("camera branches", n as usize, 1, branches)?;
        }
        if let Some(share) = i.sun_lobe {
            check_range("sun lobe", share, 0.0, 1.0)?;
        }
        if let Some(share) = i.sky_guide {
            check_range("sky guide", share, 0.0, 1.0)?;
        }
        if let Some(share) = i.ground_guide {
            check_range("ground guide", share, 0.0, 1.0)?;
        }
        if let Some(share) = i.camera_importance {
            check_range("camera importance", share, 0.0, 1.0)?;
        }
        check_count(
            "forced collision depth",
            i.forced_collision_depth as usize,
            0,
            crate::plan::MAX_FORCED_COLLISION_DEPTH as usize,
        )?;
        // The first splatting switch the scene turns on, whose needs follow.
        let splatting_asked = [
            ("circle_splatting", i.circle_splatting),
            ("ground_splatting", i.ground_splatting),
        ]
        .into_iter()
        .find_map(|(name, asked)| (asked == Some(true)).then_some(name));
        if let Some(parameter) =
            splatting_asked.filter(|_| self.observer.altitude_m >= self.atmosphere.top_altitude_m)
        {
            // From above the air the splats' densities follow the light
            // poorly: 70 % noise after 40 s on the `space` bench scene
            // against 2 % without (`BENCHMARKS.md`).
            return Err(SceneError::new(
                parameter,
                "needs the observer inside the atmosphere (altitude below its top)",
            ));
        }
        if let Some(parameter) =
            splatting_asked.filter(|_| i.camera_samples == Some(0) || !i.next_event_estimation)
        {
            // The camera paths' share of the light is what their
            // next-event points estimate; without them nothing would.
            return Err(SceneError::new(
                parameter,
                "needs camera_samples ≥ 1 and next_event_estimation = true",
            ));
        }
        if i.splitting == Some(true) && !i.russian_roulette {
            // Splitting's other half is roulette (dim paths end); without
            // it the option would silently do nothing.
            return Err(SceneError::new(
                "splitting",
                "needs russian_roulette = true (roulette and splitting by importance go together)",
            ));
        }
        self.output.check_layers()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_preset_loads_and_round_trips() {
        for (name, _) in PRESETS {
            let scene = Scene::preset(name).unwrap();
            let again = Scene::from_toml(&scene.to_toml()).unwrap();
            assert_eq!(scene, again, "{name}");
        }
    }

    #[test]
    fn a_planet_sets_the_defaults_the_scene_overrides() {
        use crate::atmosphere::AerosolPhaseKind;
        use crate::physics::planet::{MARS_DISTANCE_AU, MARS_RADIUS_M};
        let mars = Scene::from_toml("[planet]\npreset = \"mars\"\n").unwrap();
        assert_eq!(mars.atmosphere, AtmosphereParams::for_planet(Planet::Mars));
        assert_eq!(mars.atmosphere.planet_radius_m, MARS_RADIUS_M);
        assert_eq!(mars.sun.distance_au, Some(MARS_DISTANCE_AU));
        // The scene's keys win; the dust's other keys stay.
        let own = Scene::from_toml(
            "[planet]\npreset = \"mars\"\n[sun]\ndistance_au = 1.38\n\
             [atmosphere]\nplanet_radius_m = 3396200.0\n\
             [atmosphere.aerosol]\noptical_depth_550 = 2.0\n",
        )
        .unwrap();
        assert_eq!(own.sun.distance_au, Some(1.38));
        assert_eq!(own.atmosphere.planet_radius_m, 3_396_200.0);
        assert_eq!(own.atmosphere.aerosol.optical_depth_550, Some(2.0));
        assert_eq!(
            own.atmosphere.aerosol.phase,
            Some(AerosolPhaseKind::MarsDust)
        );
        // A phase of the scene's own takes none of the dust's parameters.
        let hg = Scene::from_toml(
            "[planet]\npreset = \"mars\"\n[atmosphere.aerosol]\n\
             phase = \"henyey-greenstein\"\nasymmetry = 0.6\n",
        )
        .unwrap();
        assert_eq!(
            hg.atmosphere.aerosol.phase,
            Some(AerosolPhaseKind::HenyeyGreenstein)
        );
        assert_eq!(hg.atmosphere.aerosol.asymmetry, Some(0.6));
        // Round trip, and the Earth's scenes write no [planet].
        assert_eq!(Scene::from_toml(&own.to_toml()).unwrap(), own);
        assert!(!Scene::default().to_toml().contains("[planet]"));
        // The Earth's ephemeris does not place the Sun on Mars.
        let dated = Scene::from_toml(
            "[planet]\npreset = \"mars\"\n[sun]\ndate_time = \"2013-05-27T11:45:00-04:00\"\n\
             latitude_deg = 42.0\nlongitude_deg = -76.0\n",
        )
        .unwrap_err();
        assert!(dated.message.contains("Earth's ephemeris"), "{dated:?}");
        let mut scene = Scene::default();
        scene.set_planet(Planet::Mars);
        assert_eq!(scene, mars);
    }

    #[test]
    fn an_aerosol_table_round_trips_and_is_left_out_when_unset() {
        let toml = "[atmosphere.aerosol]\noptical_depth_550 = 0.2\nangstrom_exponent = 0.8\n\
                    single_scattering_albedo = 0.95\nprofile = \"exponential\"\n\
                    scale_height_m = 2000.0\nphase = \"double-henyey-greenstein\"\n\
                    g1 = 0.8\ng2 = -0.2\nweight = 0.9\n";
        let scene = Scene::from_toml(toml).unwrap();
        let text = scene.to_toml();
        assert!(text.contains("[atmosphere.aerosol]"), "{text}");
        assert_eq!(Scene::from_toml(&text).unwrap(), scene);
        assert!(!Scene::default().to_toml().contains("aerosol]"));
    }

    #[test]
    fn splatting_needs_the_camera_rays_next_event_points() {
        for splatting in ["circle_splatting", "ground_splatting"] {
            for toml in [
                format!("[render.integrator]\n{splatting} = true\ncamera_samples = 0"),
                format!("[render.integrator]\n{splatting} = true\nnext_event_estimation = false"),
            ] {
                let e = Scene::from_toml(&toml).unwrap_err();
                assert_eq!(e.parameter, splatting, "{toml}");
                assert!(e.to_string().contains("camera_samples"), "{e}");
            }
        }
        // The ground's splats go without the air's.
        assert!(Scene::from_toml(
            "[render.integrator]\ncircle_splatting = false\nground_splatting = true",
        )
        .is_ok());
        // Off, or unset, either is fine.
        let ok = "[render.integrator]\ncircle_splatting = false\ncamera_samples = 0";
        assert!(Scene::from_toml(ok).is_ok());
        assert!(Scene::from_toml("[render.integrator]\ncamera_samples = 0").is_ok());
        // From above the air: refused when asked for, left off when unset.
        let mut space = Scene::preset("space").unwrap();
        space.render.integrator.circle_splatting = Some(true);
        let e = space.validate().unwrap_err();
        assert_eq!(e.parameter, "circle_splatting");
        assert!(e.to_string().contains("inside the atmosphere"), "{e}");
        space.render.integrator.circle_splatting = None;
        space.render.integrator.ground_splatting = Some(true);
        assert_eq!(space.validate().unwrap_err().parameter, "ground_splatting");
    }

    #[test]
    fn errors_name_the_parameter_and_range() {
        let mut scene = Scene::default();
        scene.observer.altitude_m = -5.0;
        let e = scene.validate().unwrap_err();
        assert_eq!(e.parameter, "altitude (m)");
        assert!(e.to_string().contains("0 to 100000000"), "{e}");
        scene.observer.altitude_m = f64::NAN;
        assert!(scene.validate().is_err());
        let e = Scene::preset("noon").unwrap_err();
        assert!(e.to_string().contains("midday"), "{e}");
        assert!(Scene::from_toml("[sun]\nelevation = 3").is_err());
        let e = Scene::from_toml("[render]\nspp = 1048577").unwrap_err();
        assert!(e.to_string().contains("1 to 1048576"), "{e}");
        // Each side in range, but too many pixels to allocate.
        let e = Scene::from_toml("[render]\nwidth = 65536\nheight = 65536").unwrap_err();
        assert_eq!(e.parameter, "width × height");
        assert!(e.to_string().contains("134217728 (16384 × 8192)"), "{e}");
        assert!(Scene::from_toml("[render]\nwidth = 16384\nheight = 8192").is_ok());
        // A seed a scene file can hold, so an EXR's embedded scene reloads.
        scene = Scene::default();
        scene.render.seed = u64::MAX;
        let e = scene.validate().unwrap_err();
        assert!(e.to_string().contains("0 to 9223372036854775807"), "{e}");
        scene.render.seed = MAX_SEED;
        assert_eq!(Scene::from_toml(&scene.to_toml()).unwrap(), scene);
        let e = Scene::from_toml("[render.integrator]\nsplitting = true\nrussian_roulette = false")
            .unwrap_err();
        assert_eq!(e.parameter, "splitting");
        assert!(e.to_string().contains("russian_roulette = true"), "{e}");
    }

    #[test]
    fn toml_errors_say_where_and_what_on_one_line() {
        for (toml, want) in [
            (
                "[camera]\nkind = \"ortho\"",
                "line 2, column 8: `camera.kind`: unknown variant `ortho`, expected one of `perspective`, `equirect`, `fisheye`",
            ),
            (
                "[sun]\nelevatoin_deg = 3",
                "line 2, column 1: `sun.elevatoin_deg`: unknown field `elevatoin_deg`",
            ),
            ("[render]\nspp = -3", "line 2, column 7: `render.spp`:"),
            ("[sun]\nelevation_deg = \"x\"", "line 2, column 17: `sun.elevation_deg`:"),
        ] {
            let e = Scene::from_toml(toml).unwrap_err();
            assert_eq!(e.parameter, "scene");
            let text = e.to_string();
            assert!(text.contains(want) && !text.contains('\n'), "{toml}: {text}");
        }
    }

    #[test]
    fn a_fisheye_sees_the_whole_sky_unless_told_otherwise() {
        let fov = |toml: &str| Scene::from_toml(toml).unwrap().camera.fov_deg;
        assert_eq!(fov("[camera]\nkind = \"fisheye\""), 180.0);
        assert_eq!(fov("[camera]\nkind = \"fisheye\"\nfov_deg = 120.0"), 120.0);
        assert_eq!(fov("[camera]\nkind = \"perspective\""), 90.0);
        assert_eq!(fov(""), 90.0);
    }

    #[test]
    fn integrator_options_are_range_checked() {
        for (toml, parameter, range) in [
            ("wavelengths_per_path = 0", "wavelengths per path", "1 to 4"),
            ("camera_samples = 9", "camera samples", "0 to 8"),
            ("camera_branches = 0", "camera branches", "1 to 16"),
            ("sunlight_samples = 9", "sunlight samples", "0 to 8"),
            ("shadow_samples = 9", "shadow samples", "0 to 8"),
            ("sun_lobe = 1.5", "sun lobe", "0 to 1"),
            ("sky_guide = -0.1", "sky guide", "0 to 1"),
            ("ground_guide = 1.5", "ground guide", "0 to 1"),
            ("camera_importance = 1.5", "camera importance", "0 to 1"),
            (
                "forced_collision_depth = 65",
                "forced collision depth",
                "0 to 64",
            ),
        ] {
            let e = Scene::from_toml(&format!("[render.integrator]\n{toml}")).unwrap_err();
            assert_eq!(e.parameter, parameter);
            assert!(e.to_string().contains(range), "{e}");
        }
    }

    #[test]
    fn the_control_variate_is_a_scene_option_on_at_sunset() {
        use crate::plan::{Conditions, TechniquePlan};
        let scene = Scene::from_toml("[render.integrator]\ncontrol_variate = false\n").unwrap();
        assert_eq!(scene.render.integrator.control_variate, Some(false));
        let control = |scene: &Scene| {
            let at = Conditions::new(scene.sun.elevation_deg, &scene.atmosphere, true);
            TechniquePlan::new(&scene.render.integrator, &at).control_variate
        };
        let sunset = Scene::preset("sunset").unwrap();
        assert!(control(&sunset));
        assert!(!control(&Scene::preset("midday").unwrap()));
        // Nor in haze its table cannot hold, unless asked for.
        let mut haze = sunset.clone();
        haze.atmosphere.aerosol_amount = 100.0;
        assert!(!control(&haze));
        haze.render.integrator.control_variate = Some(true);
        assert!(control(&haze));
    }
}
