//! The `skyrender` command line: a thin shell over the library.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::{Args, Parser, Subcommand};

use crate::atmosphere::Atmosphere;
use crate::output::{self, OutputFormat};
use crate::physics::standard_atmosphere;
use crate::render::{integrator, service, MirrorAxis, Renderer};
use crate::scene::{CameraKind, Scene, SceneError, MAX_ALTITUDE_M};

/// Writes `text` to standard output. A reader that closed the pipe early
/// (`skyrender radiance … | head -n 3`) ends the program quietly with
/// success, as other command-line tools do, where `print!` would panic; any
/// other write error ends it with a one-line error.
pub fn emit(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("skyrender: error: cannot write to standard output: {e}");
        std::process::exit(2);
    }
}

/// `println!` through [`emit`].
macro_rules! outln {
    ($($arg:tt)*) => {
        emit(&format!("{}\n", format_args!($($arg)*)))
    };
}

/// A note for a scene that sets the control variate on in haze its table
/// cannot hold ([`integrator::control_table_holds`]): the setting is
/// honoured, and the estimate stays unbiased, but there it adds noise (in
/// the thickest haze by orders of magnitude, with negative pixels).
fn control_variate_note(scene: &Scene) -> Option<String> {
    let a = &scene.atmosphere;
    (scene.render.integrator.control_variate == Some(true) && !integrator::control_table_holds(a))
        .then(|| {
            let (g_min, g_max) = integrator::CONTROL_AEROSOL_G;
            format!(
                "skyrender: note: control_variate = true in haze its table cannot hold \
                 (aerosol optical depth {:.3} at 550 nm, g {}; left unset it is off past {} \
                 or outside g {g_min} to {g_max}): expect far more noise, and negative pixels",
                a.aerosol_optical_depth(550.0),
                a.aerosol_g,
                integrator::CONTROL_MAX_AEROSOL_DEPTH,
            )
        })
}

/// Physically based spectral sky renderer. Without a subcommand, opens the
/// interactive preview.
#[derive(Parser, Debug)]
#[command(
    name = "skyrender",
    version,
    about,
    args_conflicts_with_subcommands = true
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Option<Command>,
    /// Preview app: save a screenshot of the window to this PNG and exit.
    #[arg(long, value_name = "OUT.png")]
    pub screenshot: Option<PathBuf>,
    /// Preview app: seconds to let the image refine before the screenshot.
    #[arg(
        long,
        allow_hyphen_values = true,
        value_name = "SECONDS",
        default_value_t = 5.0
    )]
    pub screenshot_after: f64,
    /// Preview app: start from this preset.
    #[arg(long, value_name = "NAME")]
    pub preset: Option<String>,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render an image (EXR: linear HDR, Y in cd/m²; PNG: tone-mapped sRGB).
    Render {
        #[command(flatten)]
        scene: SceneArgs,
        /// Output file, .exr or .png.
        #[arg(short, long, value_name = "OUT.exr|OUT.png")]
        output: PathBuf,
    },
    /// Spectral radiance seen by the observer in one direction.
    Radiance {
        #[command(flatten)]
        scene: SceneArgs,
        /// View zenith angle, degrees (0 = straight up).
        #[arg(long, allow_hyphen_values = true)]
        view_zenith: f64,
        /// View azimuth, degrees clockwise from north.
        #[arg(long, allow_hyphen_values = true)]
        view_azimuth: f64,
        /// One wavelength, nm.
        #[arg(long, allow_hyphen_values = true, conflicts_with = "wavelengths")]
        wavelength: Option<f64>,
        /// Wavelength range FROM:TO:STEP, nm.
        #[arg(long, value_name = "FROM:TO:STEP")]
        wavelengths: Option<String>,
        /// Paths per wavelength.
        #[arg(long, allow_hyphen_values = true, default_value_t = 10_000)]
        samples: i64,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Properties of the model atmosphere at one altitude.
    Atmosphere {
        #[command(flatten)]
        scene: SceneArgs,
        /// Wavelength for the optical coefficients, nm.
        #[arg(long, allow_hyphen_values = true, default_value_t = 550.0)]
        wavelength: f64,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// List the built-in presets.
    Presets,
    /// Measure speed and noise (see BENCHMARKS.md).
    Bench(crate::bench::BenchArgs),
}

/// Scene selection and overrides shared by the subcommands.
#[derive(Args, Debug, Default, Clone)]
pub struct SceneArgs {
    /// Built-in preset (see `skyrender presets`).
    #[arg(long, conflicts_with = "scene")]
    pub preset: Option<String>,
    /// Scene description (TOML).
    #[arg(long, value_name = "FILE.toml")]
    pub scene: Option<PathBuf>,
    #[arg(long, allow_hyphen_values = true, value_name = "DEG")]
    pub sun_elevation: Option<f64>,
    #[arg(long, allow_hyphen_values = true, value_name = "DEG")]
    pub sun_azimuth: Option<f64>,
    /// Observer altitude above the ground, m.
    #[arg(long, allow_hyphen_values = true, value_name = "M")]
    pub altitude: Option<f64>,
    /// perspective | equirect | fisheye
    #[arg(long)]
    pub camera: Option<String>,
    #[arg(long, allow_hyphen_values = true, value_name = "DEG")]
    pub fov: Option<f64>,
    #[arg(long, allow_hyphen_values = true, value_name = "DEG")]
    pub yaw: Option<f64>,
    #[arg(long, allow_hyphen_values = true, value_name = "DEG")]
    pub pitch: Option<f64>,
    #[arg(long, allow_hyphen_values = true, value_name = "DEG")]
    pub roll: Option<f64>,
    #[arg(long, allow_hyphen_values = true, value_name = "W")]
    pub width: Option<i64>,
    #[arg(long, allow_hyphen_values = true, value_name = "H")]
    pub height: Option<i64>,
    /// Samples per pixel: passes over the image; with adaptive sampling, the
    /// least samples a pixel gets (noisy regions get up to 16 per pass).
    #[arg(long, allow_hyphen_values = true, value_name = "N")]
    pub spp: Option<i64>,
    /// One sample per pixel per pass everywhere (no adaptive sampling).
    #[arg(long)]
    pub no_adaptive: bool,
    /// Read every pixel on its own, not with its mirror image in the sun's
    /// vertical plane (see `[render] mirror_symmetry`).
    #[arg(long)]
    pub no_mirror: bool,
    #[arg(long, allow_negative_numbers = true, value_name = "S")]
    pub seed: Option<u64>,
    #[arg(long)]
    pub no_aerosols: bool,
    #[arg(long)]
    pub no_ozone: bool,
    #[arg(long, allow_hyphen_values = true, value_name = "X")]
    pub aerosol_amount: Option<f64>,
    #[arg(long, allow_hyphen_values = true, value_name = "DU")]
    pub ozone_du: Option<f64>,
    #[arg(long, allow_hyphen_values = true, value_name = "A")]
    pub ground_albedo: Option<f64>,
    /// PNG exposure, EV (default: automatic).
    #[arg(long, allow_hyphen_values = true, value_name = "EV")]
    pub exposure: Option<f64>,
    /// Top-of-atmosphere irradiance of 1 W m⁻² nm⁻¹ at every wavelength.
    #[arg(long)]
    pub unit_sun: bool,
    /// Worker threads (default: all cores).
    #[arg(long, allow_hyphen_values = true, value_name = "N")]
    pub threads: Option<i64>,
}

fn count(parameter: &str, value: i64, max: i64) -> Result<u32, SceneError> {
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
        if let Some(v) = self.sun_elevation {
            scene.sun.elevation_deg = v;
        }
        if let Some(v) = self.sun_azimuth {
            scene.sun.azimuth_deg = v;
        }
        if let Some(v) = self.altitude {
            if !(v.is_finite() && (0.0..=MAX_ALTITUDE_M).contains(&v)) {
                return Err(SceneError::new(
                    "altitude (m)",
                    format!("{v} is outside the valid range 0 (the ground) to 1e8"),
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
        if let Some(v) = self.seed {
            scene.render.seed = v;
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
        if let Some(v) = self.aerosol_amount {
            scene.atmosphere.aerosol_amount = v;
        }
        if let Some(v) = self.ozone_du {
            scene.atmosphere.ozone_du = Some(v);
        }
        if let Some(v) = self.ground_albedo {
            scene.atmosphere.ground_albedo = v;
        }
        if let Some(v) = self.exposure {
            scene.render.exposure_ev = Some(v);
        }
        if self.unit_sun {
            scene.render.unit_sun = true;
        }
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
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error(transparent)]
    Output(#[from] output::OutputError),
    #[error("{0}")]
    Other(String),
}

/// Fail early, before rendering, if the output cannot be written.
fn check_output_path(path: &Path) -> Result<(), CliError> {
    OutputFormat::from_path(path)?;
    crate::output::check_writable(path).map_err(|e| CliError::Other(format!("invalid output: {e}")))
}

/// The header metadata written into EXR files: `skyrender:spp` is the passes
/// rendered (the least samples a pixel has), `skyrender:samples_per_pixel`
/// the camera paths per pixel on average (more under adaptive sampling),
/// `skyrender:mirror_pairs` whether pixels were read with their mirror
/// images in the sun's vertical plane (`columns` or `rows`: the image's
/// mirrored axis; `none`), which doubles the samples behind each pixel.
pub fn exr_metadata(scene: &Scene, spp: u32, paths: u64, discarded: u64) -> Vec<(String, String)> {
    let pixels = f64::from(scene.render.width) * f64::from(scene.render.height);
    vec![
        ("skyrender:version".into(), env!("CARGO_PKG_VERSION").into()),
        ("skyrender:scene".into(), scene.to_toml()),
        ("skyrender:spp".into(), spp.to_string()),
        (
            "skyrender:samples_per_pixel".into(),
            format!("{:.2}", paths as f64 / pixels),
        ),
        ("skyrender:discarded_samples".into(), discarded.to_string()),
        (
            "skyrender:mirror_pairs".into(),
            match crate::render::mirror_pairs(scene).map(|m| m.axis) {
                Some(MirrorAxis::Columns) => "columns",
                Some(MirrorAxis::Rows) => "rows",
                None => "none",
            }
            .into(),
        ),
        (
            "skyrender:units".into(),
            "linear Rec.709, Y = luminance in cd/m^2".into(),
        ),
    ]
}

/// Render `scene` and write it to `path` (EXR or PNG), atomically.
pub fn render_to_file(
    scene: &Scene,
    path: &Path,
    cancel: &AtomicBool,
    mut progress: impl FnMut(u32, u32),
) -> Result<(u32, u64, u64), CliError> {
    let renderer = Renderer::new(scene)?;
    let total = scene.render.spp;
    let (film, paths) =
        service::render_blocking(&renderer, cancel, |pass, _| progress(pass, total))
            .ok_or_else(|| CliError::Other("render cancelled".into()))?;
    let image = film.to_rgb();
    output::write_image(
        path,
        &image,
        &exr_metadata(scene, total, paths, film.discarded),
        scene.render.exposure_ev.map(|v| v as f32),
    )?;
    Ok((total, paths, film.discarded))
}

fn parse_wavelengths(single: Option<f64>, range: Option<&str>) -> Result<Vec<f64>, SceneError> {
    let check = |w: f64| {
        if w.is_finite() && (220.0..=4000.0).contains(&w) {
            Ok(w)
        } else {
            Err(SceneError::new(
                "wavelength (nm)",
                format!("{w} is outside the valid range 220 to 4000"),
            ))
        }
    };
    match (single, range) {
        (Some(w), _) => Ok(vec![check(w)?]),
        (None, Some(text)) => {
            let parts: Vec<f64> = text
                .split(':')
                .map(|p| p.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| {
                    SceneError::new("wavelengths", format!("'{text}' is not FROM:TO:STEP in nm"))
                })?;
            let [from, to, step] = parts[..] else {
                return Err(SceneError::new(
                    "wavelengths",
                    format!("'{text}' is not FROM:TO:STEP in nm"),
                ));
            };
            check(from)?;
            check(to)?;
            if !(step.is_finite() && step > 0.0 && to >= from && (to - from) / step <= 10_000.0) {
                return Err(SceneError::new(
                    "wavelengths",
                    format!(
                        "'{text}': need FROM ≤ TO and a STEP > 0 giving at most 10000 wavelengths"
                    ),
                ));
            }
            let n = ((to - from) / step + 1e-9).floor() as usize;
            Ok((0..=n).map(|i| from + i as f64 * step).collect())
        }
        (None, None) => Ok(vec![550.0]),
    }
}

/// Run a subcommand; returns the process exit code.
pub fn run(command: Command) -> Result<(), CliError> {
    match command {
        Command::Presets => {
            for (name, text) in crate::scene::PRESETS {
                let summary = text
                    .lines()
                    .next()
                    .unwrap_or("")
                    .trim_start_matches('#')
                    .trim();
                outln!("{name:<10} {summary}");
            }
            Ok(())
        }
        Command::Render {
            scene: args,
            output,
        } => {
            let scene = args.build()?;
            check_output_path(&output)?;
            let pool = args.thread_pool()?;
            if let Some(note) = control_variate_note(&scene) {
                eprintln!("{note}");
            }
            let ignored = args.ignored_camera_flags(scene.camera.kind);
            if !ignored.is_empty() {
                eprintln!(
                    "skyrender: note: the {} camera does not use {} (README, \"Conventions\")",
                    scene.camera.kind.name(),
                    ignored.join(", ")
                );
            }
            let bar = if std::io::stderr().is_terminal() {
                let bar = indicatif::ProgressBar::new(u64::from(scene.render.spp));
                bar.set_style(
                    indicatif::ProgressStyle::with_template(
                        "{elapsed_precise} [{bar:40}] {pos}/{len} spp, eta {eta}",
                    )
                    .expect("valid template"),
                );
                bar
            } else {
                indicatif::ProgressBar::hidden()
            };
            let start = Instant::now();
            let cancel = AtomicBool::new(false);
            let (spp, paths, discarded) = pool.install(|| {
                render_to_file(&scene, &output, &cancel, |pass, _| {
                    bar.set_position(u64::from(pass));
                })
            })?;
            bar.finish_and_clear();
            let seconds = start.elapsed().as_secs_f64();
            // Adaptive sampling gives noisy pixels more than one sample per
            // pass: say how many paths a pixel got on average.
            let pixels = f64::from(scene.render.width) * f64::from(scene.render.height);
            let mean_spp = paths as f64 / pixels;
            let mut notes = Vec::new();
            if scene.render.adaptive_sampling && mean_spp > f64::from(spp) {
                notes.push(format!("adaptive: {mean_spp:.1} per pixel on average"));
            }
            // Mirror pairs double the samples behind each pixel.
            if crate::render::mirror_pairs(&scene).is_some() {
                notes.push("read in mirror pairs".to_owned());
            }
            let adaptive = if notes.is_empty() {
                String::new()
            } else {
                format!(" ({})", notes.join("; "))
            };
            outln!(
                "{}x{} at {spp} spp{adaptive} in {seconds:.2} s ({:.3} M camera paths/s), {discarded} samples discarded -> {}",
                scene.render.width,
                scene.render.height,
                paths as f64 / seconds / 1e6,
                output.display()
            );
            Ok(())
        }
        Command::Radiance {
            scene: args,
            view_zenith,
            view_azimuth,
            wavelength,
            wavelengths,
            samples,
            json,
        } => {
            let scene = args.build()?;
            if !(view_zenith.is_finite() && (0.0..=180.0).contains(&view_zenith)) {
                return Err(SceneError::new(
                    "view zenith (deg)",
                    format!("{view_zenith} is outside the valid range 0 to 180"),
                )
                .into());
            }
            if !(view_azimuth.is_finite() && (-360.0..=720.0).contains(&view_azimuth)) {
                return Err(SceneError::new(
                    "view azimuth (deg)",
                    format!("{view_azimuth} is outside the valid range -360 to 720"),
                )
                .into());
            }
            let samples = count("samples", samples, 1 << 30)?;
            let list = parse_wavelengths(wavelength, wavelengths.as_deref())?;
            let pool = args.thread_pool()?;
            if let Some(note) = control_variate_note(&scene) {
                eprintln!("{note}");
            }
            let renderer = Renderer::new(&scene)?;
            let spectrum =
                pool.install(|| renderer.probe_radiance(view_zenith, view_azimuth, &list, samples));
            if json {
                let value = serde_json::json!({
                    "view_zenith_deg": view_zenith,
                    "view_azimuth_deg": view_azimuth,
                    "samples": samples,
                    "unit_sun": scene.render.unit_sun,
                    "spectrum": spectrum,
                });
                outln!("{}", serde_json::to_string_pretty(&value).expect("json"));
            } else {
                let unit = if scene.render.unit_sun {
                    "per unit TOA irradiance, sr^-1"
                } else {
                    "W m^-2 sr^-1 nm^-1"
                };
                outln!("# view zenith {view_zenith} deg, azimuth {view_azimuth} deg, {samples} paths per wavelength");
                outln!("# wavelength_nm  radiance ({unit})  std_error");
                for s in &spectrum {
                    outln!(
                        "{:>8.2}  {:.6e}  {:.3e}",
                        s.wavelength_nm,
                        s.radiance,
                        s.std_error
                    );
                }
                let discarded: u64 = spectrum.iter().map(|s| s.discarded).sum();
                outln!("# {discarded} samples discarded (not finite, or negative without the control variate)");
            }
            Ok(())
        }
        Command::Atmosphere {
            scene: args,
            wavelength,
            json,
        } => {
            let scene = args.build()?;
            // Nothing here runs in parallel, but a bad --threads is still bad.
            args.threads()?;
            let altitude_m = scene.observer.altitude_m;
            parse_wavelengths(Some(wavelength), None)?;
            let atmosphere = Atmosphere::new(scene.atmosphere.clone());
            let air = standard_atmosphere::air_state(altitude_m);
            let depth = atmosphere.vertical_optical_depth(altitude_m, wavelength);
            let value = serde_json::json!({
                "altitude_m": altitude_m,
                "wavelength_nm": wavelength,
                "temperature_k": air.temperature_k,
                "pressure_pa": air.pressure_pa,
                "density_kg_m3": air.density_kg_m3,
                "number_density_m3": air.number_density_m3,
                "rayleigh_scattering_m": atmosphere.rayleigh_scattering_per_m(altitude_m, wavelength),
                "ozone_absorption_m": atmosphere.ozone_absorption_per_m(altitude_m, wavelength),
                "aerosol_extinction_m": atmosphere.aerosol_extinction_per_m(altitude_m, wavelength),
                "optical_depth": depth,
            });
            if json {
                outln!("{}", serde_json::to_string_pretty(&value).expect("json"));
            } else {
                for (k, v) in value.as_object().expect("object") {
                    outln!("{k:<22} {v}");
                }
            }
            Ok(())
        }
        Command::Bench(args) => crate::bench::run(&args).map_err(CliError::Other),
    }
}
