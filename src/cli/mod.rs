//! The `skyrender` command line: a thin shell over the library.

use std::path::PathBuf;

use std::time::Instant;

use clap::Subcommand;

mod render;
mod scene_args;

use crate::atmosphere::Atmosphere;
use crate::physics::standard_atmosphere;
use crate::render::Renderer;
use crate::scene::{show_number, SceneError};

pub use crate::output::stdout::emit;
use scene_args::{check_output_path, count};
pub use scene_args::{CliError, SceneArgs};

/// `println!` through [`emit`].
macro_rules! outln {
    ($($arg:tt)*) => {
        emit(&format!("{}\n", format_args!($($arg)*)))
    };
}

/// The command line's subcommands (the benchmark is the binary's own).
#[derive(Subcommand, Debug)]
pub enum Command {
    /// Render an image (EXR: linear HDR, Y in cd/m²; PNG: tone-mapped sRGB).
    Render {
        /// The scene and its overrides.
        #[command(flatten)]
        scene: SceneArgs,
        /// An animation over time.
        #[command(flatten)]
        sequence: render::SequenceArgs,
        /// A part of a split render (tiles, passes).
        #[command(flatten)]
        split: render::SplitArgs,
        /// Spectral EXR output.
        #[command(flatten)]
        spectral: render::SpectralArgs,
        /// Compositing layers.
        #[command(flatten)]
        layers: render::LayerArgs,
        /// Output file, .exr or .png; for a timelapse, a name with a run of
        /// `#` for the frame number (sky_####.exr).
        #[arg(short, long, value_name = "OUT.exr|OUT.png")]
        output: PathBuf,
    },
    /// Merge the parts of a split render (render --tile/--tiles/--passes)
    /// into the image one render gives.
    Merge {
        /// The part files (EXR), in any order.
        #[arg(required = true, value_name = "PART.exr")]
        parts: Vec<PathBuf>,
        /// Output file, .exr or .png.
        #[arg(short, long, value_name = "OUT.exr|OUT.png")]
        output: PathBuf,
    },
    /// Spectral radiance seen by the observer in one direction.
    Radiance {
        /// The scene and its overrides.
        #[command(flatten)]
        scene: SceneArgs,
        /// View zenith angle, degrees, 0 (straight up) to 180.
        #[arg(long, allow_negative_numbers = true)]
        view_zenith: f64,
        /// View azimuth, degrees clockwise from north, -360 to 720.
        #[arg(long, allow_negative_numbers = true)]
        view_azimuth: f64,
        /// One wavelength, nm, 220 to 4000 [default: 550].
        #[arg(long, allow_negative_numbers = true, conflicts_with = "wavelengths")]
        wavelength: Option<f64>,
        /// Wavelength range FROM:TO:STEP, nm.
        #[arg(long, value_name = "FROM:TO:STEP")]
        wavelengths: Option<String>,
        /// Paths per wavelength, 1 to 2^30.
        #[arg(
            long,
            allow_negative_numbers = true,
            default_value_t = 10_000,
            value_name = "N"
        )]
        samples: i64,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// Properties of the model atmosphere at one altitude.
    Atmosphere {
        /// The scene and its overrides.
        #[command(flatten)]
        scene: SceneArgs,
        /// Wavelength for the optical coefficients, nm.
        #[arg(long, allow_negative_numbers = true, default_value_t = 550.0)]
        wavelength: f64,
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// List the built-in presets.
    Presets,
}

fn parse_wavelengths(single: Option<f64>, range: Option<&str>) -> Result<Vec<f64>, SceneError> {
    let check = |w: f64| {
        if w.is_finite() && (220.0..=4000.0).contains(&w) {
            Ok(w)
        } else {
            Err(SceneError::new(
                "wavelength (nm)",
                format!("{} is outside the valid range 220 to 4000", show_number(w)),
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

/// The first sentence of a preset's leading comment, which may span lines.
fn preset_summary(text: &str) -> String {
    let comment: Vec<&str> = text
        .lines()
        .map_while(|line| line.strip_prefix('#'))
        .map(str::trim)
        .collect();
    let joined = comment.join(" ");
    // A sentence ends at a full stop followed by a space or the end (not at
    // a decimal point, and not inside parentheses).
    let mut depth = 0i32;
    let chars: Vec<(usize, char)> = joined.char_indices().collect();
    for (k, &(i, c)) in chars.iter().enumerate() {
        match c {
            '(' => depth += 1,
            ')' => depth -= 1,
            '.' if depth == 0 && chars.get(k + 1).is_none_or(|&(_, n)| n == ' ') => {
                return joined[..=i].to_owned();
            }
            _ => {}
        }
    }
    joined
}

/// Run a subcommand; returns the process exit code.
pub fn run(command: Command) -> Result<(), CliError> {
    match command {
        Command::Presets => {
            for (name, text) in crate::scene::PRESETS {
                outln!("{name:<10} {}", preset_summary(text));
            }
            Ok(())
        }
        Command::Render {
            scene: args,
            output,
            sequence,
            split,
            spectral,
            layers,
        } => render::run(&args, &output, &sequence, &split, &spectral, &layers),
        Command::Merge { parts, output } => {
            check_output_path(&output)?;
            let start = Instant::now();
            let scene = crate::export::merge_parts(&parts, &output).map_err(CliError::Other)?;
            outln!(
                "merged {} part(s): {}x{} at {} spp in {:.2} s -> {}",
                parts.len(),
                scene.render.width,
                scene.render.height,
                scene.render.spp,
                start.elapsed().as_secs_f64(),
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
                    format!(
                        "{} is outside the valid range 0 to 180",
                        show_number(view_zenith)
                    ),
                )
                .into());
            }
            if !(view_azimuth.is_finite() && (-360.0..=720.0).contains(&view_azimuth)) {
                return Err(SceneError::new(
                    "view azimuth (deg)",
                    format!(
                        "{} is outside the valid range -360 to 720",
                        show_number(view_azimuth)
                    ),
                )
                .into());
            }
            args.print_notes(&scene);
            let samples = count("samples", samples, 1 << 30)?;
            let list = parse_wavelengths(wavelength, wavelengths.as_deref())?;
            let pool = args.thread_pool()?;
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
                outln!("# {discarded} samples discarded (not finite, or negative where no estimate may be)");
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
            args.print_notes(&scene);
            let altitude_m = scene.observer.altitude_m;
            parse_wavelengths(Some(wavelength), None)?;
            let atmosphere = Atmosphere::new(scene.atmosphere.clone());
            let mut air = standard_atmosphere::air_state(altitude_m);
            if atmosphere.has_gas_profile() {
                // The profile's gas: n and T as the renderer takes them,
                // p and ρ from them by the ideal gas law.
                let n = atmosphere.air_number_density_m3(altitude_m);
                let t = atmosphere.temperature_k(altitude_m);
                air = standard_atmosphere::AirState {
                    temperature_k: t,
                    pressure_pa: n * crate::physics::profile::BOLTZMANN_J_PER_K * t,
                    density_kg_m3: n * atmosphere.gas().molar_mass_kg_per_mol()
                        / standard_atmosphere::AVOGADRO,
                    number_density_m3: n,
                };
            }
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
                "aerosol_albedo": scene.atmosphere.aerosol_single_scattering_albedo(wavelength),
                "aerosol_asymmetry": scene.atmosphere.aerosol_mean_cosine(),
                "ground_albedo": scene.atmosphere.ground()?.at(wavelength),
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
    }
}
