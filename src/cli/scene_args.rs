//! The scene flags every subcommand shares ([`SceneArgs`]: a preset or
//! scene file, then overrides), and the command line's error type.

use std::path::{Path, PathBuf};

use clap::Args;

use crate::output::{self, OutputFormat};
use crate::plan;
use crate::render::OutOfMemory;
use crate::scene::{show_number, CameraKind, Scene, SceneError, MAX_ALTITUDE_M};

/// Scene selection and overrides shared by the subcommands. Every value
/// flag overrides the scene (the preset, default `midday`, or `--scene`);
/// "default" below is what `midday` and a scene file without the key give.
/// Numbers take a leading minus (`--sun-elevation -4`), but a flag never
/// swallows the next flag as its value (`--width -o x.exr` is an error
/// about `--width`).
#[derive(Args, Debug, Default, Clone)]
pub struct SceneArgs {
    /// Built-in preset (see `skyrender presets`) [default: midday].
    #[arg(long, conflicts_with = "scene", value_name = "NAME")]
    pub preset: Option<String>,
    /// Scene description (TOML; see README "Scene files").
    #[arg(long, value_name = "FILE.toml")]
    pub scene: Option<PathBuf>,
    /// Planet: earth or mars. Replaces the scene's atmosphere by the
    /// planet's own (radius, gas, profile, dust) and the Sun's distance;
    /// the other flags apply after it [default: the scene's, earth].
    #[arg(long, value_name = "NAME")]
    pub planet: Option<String>,
    /// Sun elevation above the horizon, degrees, -90 to 90 (negative:
    /// below it, twilight) [default: 45].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub sun_elevation: Option<f64>,
    /// Sun azimuth, degrees clockwise from north, -360 to 720 [default: 180, south].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub sun_azimuth: Option<f64>,
    /// Local date and time with UTC offset (RFC 3339, e.g.
    /// 2013-05-27T11:45:00-04:00): with --lat and --lon, places the Sun
    /// by NREL's SPA (true elevation, no refraction) and sets the Earth–Sun
    /// distance [default: none, the Sun by --sun-elevation/--sun-azimuth].
    #[arg(long, value_name = "DATE_TIME", conflicts_with_all = ["sun_elevation", "sun_azimuth"])]
    pub time: Option<String>,
    /// Observer's latitude, degrees north, -90 to 90 (with --time)
    /// [default: none].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub lat: Option<f64>,
    /// Observer's longitude, degrees east, -180 to 180 (with --time)
    /// [default: none].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub lon: Option<f64>,
    /// The Sun's distance, AU, 0.3 to 50: the solar irradiance scales as
    /// 1/d² [default: the date's with --time, else 1; 1.524 on Mars].
    #[arg(long, allow_negative_numbers = true, value_name = "AU")]
    pub sun_distance: Option<f64>,
    /// Observer altitude above the ground, metres, 0 to 1e8 [default: 2].
    #[arg(long, allow_negative_numbers = true, value_name = "M")]
    pub altitude: Option<f64>,
    /// Projection: equirect (a lat-long panorama), fisheye (looking up) or
    /// perspective [default: equirect].
    #[arg(long, value_name = "KIND")]
    pub camera: Option<String>,
    /// Field of view, degrees: horizontal for perspective (1 to 179), the
    /// circle's for fisheye (up to 360) [default: 90; fisheye 180].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub fov: Option<f64>,
    /// View direction, degrees clockwise from north (perspective and
    /// fisheye; an equirect map stays geographic) [default: 0].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub yaw: Option<f64>,
    /// View elevation, degrees above the horizon, -90 to 90 (perspective)
    /// [default: 0].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub pitch: Option<f64>,
    /// Rotation about the view axis, degrees, clockwise as seen by the
    /// viewer (perspective) [default: 0].
    #[arg(long, allow_negative_numbers = true, value_name = "DEG")]
    pub roll: Option<f64>,
    /// Image width, pixels, 1 to 65536 (at most 16384 × 8192 pixels in all)
    /// [default: 512].
    #[arg(long, allow_negative_numbers = true, value_name = "PIXELS")]
    pub width: Option<i64>,
    /// Image height, pixels, 1 to 65536 [default: 256].
    #[arg(long, allow_negative_numbers = true, value_name = "PIXELS")]
    pub height: Option<i64>,
    /// Samples per pixel: passes over the image; with adaptive sampling, the
    /// least samples a pixel gets (noisy regions get up to 16 per pass)
    /// [default: 64].
    #[arg(long, allow_negative_numbers = true, value_name = "N")]
    pub spp: Option<i64>,
    /// Stop once the image's estimated relative noise is at most PCT
    /// percent, 0.01 to 100 (over the whole image, the sun's 2° cone left
    /// out; estimated from the spread of the passes, after 8 passes at
    /// least); --spp stays the most passes [default: none, --spp passes].
    #[arg(long, allow_negative_numbers = true, value_name = "PCT")]
    pub noise: Option<f64>,
    /// Start no pass that would end (if as long as the last) more than
    /// SECONDS after the first pass began; the first pass always runs
    /// [default: none].
    #[arg(long, allow_negative_numbers = true, value_name = "SECONDS")]
    pub time_limit: Option<f64>,
    /// One sample per pixel per pass everywhere (no adaptive sampling).
    #[arg(long)]
    pub no_adaptive: bool,
    /// Read every pixel on its own, not with its mirror image in the sun's
    /// vertical plane (see `[render] mirror_symmetry`).
    #[arg(long)]
    pub no_mirror: bool,
    /// Render mode: reference (unbiased Monte Carlo at every pixel) or fast
    /// (the approximate sky model at full resolution, corrected by Monte
    /// Carlo at --fast-scale times coarser: consistent, not unbiased; its
    /// bias per preset is in BENCHMARKS.md) [default: reference].
    #[arg(long, value_name = "MODE")]
    pub mode: Option<String>,
    /// Fast mode: the Monte Carlo correction's width and height are the
    /// image's over this factor, 1 to 64 [default: 8].
    #[arg(long, allow_negative_numbers = true, value_name = "N")]
    pub fast_scale: Option<i64>,
    /// Random seed, 0 to 2^63 - 1: the same scene and seed give the same
    /// image at any thread count [default: 1].
    #[arg(long, allow_negative_numbers = true, value_name = "S")]
    pub seed: Option<u64>,
    /// No aerosols (a Rayleigh sky with ozone).
    #[arg(long)]
    pub no_aerosols: bool,
    /// No ozone absorption.
    #[arg(long)]
    pub no_ozone: bool,
    /// Multiplier of Elterman's 1968 aerosol profile, 0 to 100 (1: vertical
    /// optical depth 0.249 at 550 nm, a hazy day) [default: 1].
    #[arg(long, allow_negative_numbers = true, value_name = "X")]
    pub aerosol_amount: Option<f64>,
    /// Vertical aerosol optical depth at 550 nm from sea level, 0 to 25 (a
    /// sun photometer's AOD), in place of --aerosol-amount; the profile
    /// keeps its shape (`[atmosphere.aerosol] optical_depth_550`).
    #[arg(long, allow_negative_numbers = true, value_name = "TAU")]
    pub aod550: Option<f64>,
    /// Ångström exponent, -1 to 4: aerosol optical depth ∝ λ^-A about 550
    /// nm, in place of Elterman's spectrum (`[atmosphere.aerosol]
    /// angstrom_exponent`).
    #[arg(long, allow_negative_numbers = true, value_name = "A")]
    pub angstrom: Option<f64>,
    /// Total ozone column, Dobson units, 0 to 2000 [default: the AFGL
    /// profile's own, about 344].
    #[arg(long, allow_negative_numbers = true, value_name = "DU")]
    pub ozone_du: Option<f64>,
    /// Lambertian ground albedo, 0 to 1 [default: 0.3].
    #[arg(long, allow_negative_numbers = true, value_name = "A")]
    pub ground_albedo: Option<f64>,
    /// The ground's albedo spectrum: grass, snow, sand, ocean (USGS
    /// Spectral Library 7) or a CSV file `wavelength_nm,albedo`; replaces
    /// --ground-albedo [default: none].
    #[arg(long, value_name = "NAME|FILE")]
    pub ground_spectrum: Option<String>,
    /// The Sun's spectral irradiance at 1 AU, a CSV file
    /// `wavelength_nm,irradiance` in W m⁻² nm⁻¹ [default: ASTM E-490].
    #[arg(long, value_name = "FILE")]
    pub sun_spectrum: Option<std::path::PathBuf>,
    /// A limb-darkened solar disc (Neckel & Labs 1994) instead of the
    /// uniform one [default: uniform].
    #[arg(long)]
    pub limb_darkening: bool,
    /// PNG exposure, EV, -50 to 50: a luminance of L cd/m² is shown as
    /// L × 2^EV before the tone curve [default: automatic].
    #[arg(long, allow_negative_numbers = true, value_name = "EV")]
    pub exposure: Option<f64>,
    /// Top-of-atmosphere irradiance of 1 W m⁻² nm⁻¹ at every wavelength
    /// (instead of the measured solar spectrum).
    #[arg(long)]
    pub unit_sun: bool,
    /// Worker threads, 1 to 1024 [default: all cores].
    #[arg(long, allow_negative_numbers = true, value_name = "N")]
    pub threads: Option<i64>,
}

pub(super) fn count(parameter: &str, value: i64, max: i64) -> Result<u32, SceneError> {
    if (1..=max).contains(&value) {
        Ok(value as u32)
    } else {
        Err(SceneError::new(
            parameter,
            format!("{value} is outside the valid range 1 to {max}"),
        ))
    }
}

impl SceneArgs {
    /// The scene: preset or file (default `midday`), then the overrides.
    pub fn build(&self) -> Result<Scene, SceneError> {
        let mut scene = match (&self.preset, &self.scene) {
            (_, Some(path)) => Scene::load(path)?,
            (Some(name), None) => Scene::preset(name)?,
            (None, None) => Scene::preset("midday")?,
        };
        if let Some(name) = &self.planet {
            let planet = crate::physics::planet::Planet::parse(name)
                .map_err(|e| SceneError::new("planet", e))?;
            scene.set_planet(planet);
        }
        if (self.sun_elevation.is_some() || self.sun_azimuth.is_some())
            && scene.sun.date_time.is_some()
            && self.time.is_none()
        {
            return Err(SceneError::new(
                "sun",
                "the scene places the Sun by its date_time: give --time (with --lat/--lon) \
                 or remove date_time from the scene to set --sun-elevation/--sun-azimuth",
            ));
        }
        if let Some(v) = self.sun_elevation {
            scene.sun.elevation_deg = v;
        }
        if let Some(v) = self.sun_azimuth {
            scene.sun.azimuth_deg = v;
        }
        if let Some(t) = &self.time {
            scene.sun.date_time = Some(t.clone());
        }
        if let Some(v) = self.lat {
            scene.sun.latitude_deg = Some(v);
        }
        if let Some(v) = self.lon {
            scene.sun.longitude_deg = Some(v);
        }
        if let Some(v) = self.sun_distance {
            scene.sun.distance_au = Some(v);
        }
        if let Some(v) = self.altitude {
            if !(v.is_finite() && (0.0..=MAX_ALTITUDE_M).contains(&v)) {
                return Err(SceneError::new(
                    "altitude (m)",
                    format!(
                        "{} is outside the valid range 0 (the ground) to 1e8",
                        show_number(v)
                    ),
                ));
            }
            scene.observer.altitude_m = v;
        }
        if let Some(name) = &self.camera {
            let kind = CameraKind::parse(name)?;
            // A fisheye's field of view (180° by default) means nothing to
            // the other projections and vice versa: switching to or from a
            // fisheye without --fov takes the new kind's default.
            let fisheye = [kind, scene.camera.kind].contains(&CameraKind::Fisheye);
            if self.fov.is_none() && kind != scene.camera.kind && fisheye {
                scene.camera.fov_deg = kind.default_fov_deg();
            }
            scene.camera.kind = kind;
        }
        if let Some(v) = self.fov {
            scene.camera.fov_deg = v;
        }
        if let Some(v) = self.yaw {
            scene.camera.yaw_deg = v;
        }
        if let Some(v) = self.pitch {
            scene.camera.pitch_deg = v;
        }
        if let Some(v) = self.roll {
            scene.camera.roll_deg = v;
        }
        if let Some(v) = self.width {
            scene.render.width = count("width", v, 65_536)?;
        }
        if let Some(v) = self.height {
            scene.render.height = count("height", v, 65_536)?;
        }
        if let Some(v) = self.spp {
            scene.render.spp = count("spp", v, i64::from(crate::scene::MAX_SPP))?;
        }
        if let Some(v) = self.noise {
            scene.render.noise_percent = Some(v);
        }
        if let Some(v) = self.time_limit {
            scene.render.time_limit_s = Some(v);
        }
        if let Some(v) = self.seed {
            scene.render.seed = v;
        }
        if let Some(name) = &self.mode {
            scene.render.mode = crate::scene::RenderMode::from_name(name)?;
        }
        if let Some(v) = self.fast_scale {
            scene.render.fast_scale =
                count("fast scale", v, i64::from(crate::scene::MAX_FAST_SCALE))?;
        }
        if self.no_adaptive {
            scene.render.adaptive_sampling = false;
        }
        if self.no_mirror {
            scene.render.mirror_symmetry = false;
        }
        if self.no_aerosols {
            scene.atmosphere.aerosols = false;
        }
        if self.no_ozone {
            scene.atmosphere.ozone = false;
        }
        if self.aerosol_amount.is_some() && self.aod550.is_some() {
            return Err(SceneError::new(
                "aerosol",
                "--aerosol-amount and --aod550 both set the amount of aerosol: give one \
                 (--aerosol-amount multiplies Elterman's profile, --aod550 sets the optical \
                 depth at 550 nm)",
            ));
        }
        // Each flag takes the place of the scene's other way to set the
        // amount, so that a scene's setting never conflicts with a flag.
        if let Some(v) = self.aerosol_amount {
            scene.atmosphere.aerosol_amount = v;
            scene.atmosphere.aerosol.optical_depth_550 = None;
        }
        if let Some(v) = self.aod550 {
            scene.atmosphere.aerosol.optical_depth_550 = Some(v);
            scene.atmosphere.aerosol_amount = 1.0;
        }
        if let Some(v) = self.angstrom {
            scene.atmosphere.aerosol.angstrom_exponent = Some(v);
        }
        if let Some(v) = self.ozone_du {
            scene.atmosphere.ozone_du = Some(v);
        }
        if let Some(v) = self.ground_albedo {
            scene.atmosphere.ground_albedo = v;
            scene.atmosphere.ground_albedo_spectrum = None;
        }
        if let Some(v) = &self.ground_spectrum {
            scene.atmosphere.ground_albedo_spectrum = Some(v.clone());
        }
        if let Some(v) = &self.sun_spectrum {
            scene.sun.spectrum = Some(v.clone());
        }
        if self.limb_darkening {
            scene.sun.limb_darkening = true;
        }
        if let Some(v) = self.exposure {
            scene.render.exposure_ev = Some(v);
        }
        if self.unit_sun {
            scene.render.unit_sun = true;
        }
        // After the altitude: the Sun's topocentric place depends on it.
        scene.place_sun()?;
        scene.validate()?;
        Ok(scene)
    }

    /// The camera flags given that `kind` does not use (see
    /// [`crate::render::camera`]): an equirect map stays geographic (no
    /// yaw, pitch, roll or field of view), a fisheye looks at the zenith
    /// (no pitch or roll).
    pub fn ignored_camera_flags(&self, kind: CameraKind) -> Vec<&'static str> {
        let given = [
            ("--yaw", self.yaw.is_some()),
            ("--pitch", self.pitch.is_some()),
            ("--roll", self.roll.is_some()),
            ("--fov", self.fov.is_some()),
        ];
        let unused: &[&str] = match kind {
            CameraKind::Equirect => &["--yaw", "--pitch", "--roll", "--fov"],
            CameraKind::Fisheye => &["--pitch", "--roll"],
            CameraKind::Perspective => &[],
        };
        given
            .into_iter()
            .filter(|&(flag, given)| given && unused.contains(&flag))
            .map(|(flag, _)| flag)
            .collect()
    }

    /// Notes on flags given that `scene` does not use: camera flags its
    /// projection ignores ([`Self::ignored_camera_flags`]), an aerosol
    /// amount without aerosols, an ozone column without ozone. A note, not
    /// an error: the render is still what was asked for.
    pub fn notes(&self, scene: &Scene) -> Vec<String> {
        let mut notes = Vec::new();
        let ignored = self.ignored_camera_flags(scene.camera.kind);
        if !ignored.is_empty() {
            notes.push(format!(
                "the {} camera does not use {} (README, \"Conventions\")",
                scene.camera.kind.name(),
                ignored.join(", ")
            ));
        }
        for (flag, given) in [
            ("--aerosol-amount", self.aerosol_amount.is_some()),
            ("--aod550", self.aod550.is_some()),
            ("--angstrom", self.angstrom.is_some()),
        ] {
            if given && !scene.atmosphere.aerosols {
                notes.push(format!("{flag} has no effect without aerosols (--no-aerosols, or `aerosols = false` in the scene)"));
            }
        }
        if (self.lat.is_some() || self.lon.is_some()) && scene.sun.date_time.is_none() {
            notes.push("--lat/--lon place the Sun only with a date and time (--time, or --time-start for a timelapse)".into());
        }
        notes.extend(control_variate_note(scene));
        if self.ozone_du.is_some() && !scene.atmosphere.ozone {
            notes.push("--ozone-du has no effect without ozone (--no-ozone, or `ozone = false` in the scene)".into());
        }
        notes
    }

    /// Prints [`Self::notes`] to standard error.
    pub fn print_notes(&self, scene: &Scene) {
        for note in self.notes(scene) {
            eprintln!("skyrender: note: {note}");
        }
    }

    /// The requested number of worker threads (0: all cores), checked.
    pub fn threads(&self) -> Result<usize, SceneError> {
        self.threads
            .map_or(Ok(0), |n| count("threads", n, 1024).map(|n| n as usize))
    }

    /// A rayon pool with the requested number of threads.
    pub fn thread_pool(&self) -> Result<rayon::ThreadPool, SceneError> {
        let threads = self.threads()?;
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| SceneError::new("threads", e.to_string()))
    }
}

/// A one-line user-facing error.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// The scene is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// The output cannot be written.
    #[error(transparent)]
    Output(#[from] output::OutputError),
    /// The render does not fit in memory.
    #[error(transparent)]
    Memory(#[from] OutOfMemory),
    /// The export failed.
    #[error(transparent)]
    Export(#[from] crate::export::ExportError),
    /// Any other failure, as a message.
    #[error("{0}")]
    Other(String),
}

/// Fail early, before rendering, if the output cannot be written.
pub(super) fn check_output_path(path: &Path) -> Result<(), CliError> {
    OutputFormat::from_path(path)?;
    crate::output::check_writable(path).map_err(|e| CliError::Other(format!("invalid output: {e}")))
}

/// A note for a scene that sets the control variate on in haze its table
/// cannot hold ([`crate::plan::control_table_holds`]): the setting is
/// honoured, and the estimate stays unbiased, but there it adds noise (in
/// the thickest haze by orders of magnitude, with negative pixels).
fn control_variate_note(scene: &Scene) -> Option<String> {
    let a = &scene.atmosphere;
    (scene.render.integrator.control_variate == Some(true) && !plan::control_table_holds(a)).then(
        || {
            let (g_min, g_max) = plan::CONTROL_AEROSOL_G;
            format!(
                "control_variate = true in haze its table cannot hold \
                 (aerosol optical depth {:.3} at 550 nm, g {}; left unset it is off past {} \
                 or outside g {g_min} to {g_max}): expect far more noise, and negative pixels",
                a.aerosol_optical_depth(550.0),
                plan::control_aerosol_g(a),
                plan::CONTROL_MAX_AEROSOL_DEPTH,
            )
        },
    )
}
