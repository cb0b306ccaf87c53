//! `skyrender render`: one image, or a timelapse's frames.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::Instant;

use clap::Args;

use super::scene_args::{check_output_path, CliError, SceneArgs};
use crate::export::{self, FramePattern, FrameRange, Timelapse, Written};
use crate::output::stdout::emit;
use crate::output::OutputFormat;
use crate::render::noise_estimate::Stop;
use crate::render::parts::{PassRange, Tile};
use crate::scene::{Scene, SceneError};

/// A timelapse: frames evenly spaced in time, each with its own Sun.
#[derive(Args, Debug, Default, Clone)]
pub struct SequenceArgs {
    /// Timelapse: the first frame's date and time (RFC 3339 with UTC
    /// offset); needs --time-end, --frames, --lat and --lon [default: none,
    /// one image].
    #[arg(long, value_name = "DATE_TIME", conflicts_with = "time", requires_all = ["time_end", "frames"])]
    pub time_start: Option<String>,
    /// Timelapse: the last frame's date and time [default: none].
    #[arg(long, value_name = "DATE_TIME", requires = "time_start")]
    pub time_end: Option<String>,
    /// Timelapse: the number of frames, 1 to 17280, first and last
    /// included [default: none].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "N",
        requires = "time_start"
    )]
    pub frames: Option<i64>,
    /// Timelapse: render only frames FIRST..LAST (1-based, inclusive; e.g.
    /// one per cluster task) [default: every frame].
    #[arg(long, value_name = "FIRST..LAST", requires = "time_start")]
    pub frame_range: Option<String>,
    /// Skip the frames (or the image) whose file already exists, so an
    /// interrupted sequence goes on where it stopped.
    #[arg(long)]
    pub resume: bool,
}

/// A spectral image alongside the RGB one (`[output] spectral_bands`).
#[derive(Args, Debug, Default, Clone)]
pub struct SpectralArgs {
    /// Also write the spectral image, band-averaged spectral radiance in
    /// W m⁻² sr⁻¹ nm⁻¹ over 360–830 nm, as `S0.<nm>` channels of the EXR
    /// (JCGT spectral layout; EXR only) [default: off, or the scene's
    /// `[output] spectral_bands`].
    #[arg(long)]
    pub spectral: bool,
    /// The spectral image's bands over 360–830 nm, 1 to 470 (47: 10 nm
    /// each) [default: 47].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "N",
        requires = "spectral"
    )]
    pub bands: Option<i64>,
}

impl SpectralArgs {
    /// Sets `scene`'s spectral bands from the flags and checks them.
    fn apply(&self, scene: &mut Scene) -> Result<(), SceneError> {
        if self.spectral {
            let bands = self.bands.unwrap_or(i64::from(
                crate::render::film_spectral::DEFAULT_SPECTRAL_BANDS,
            ));
            let bands = u32::try_from(bands).map_err(|_| {
                SceneError::new(
                    "bands",
                    format!(
                        "{bands} is outside the valid range 1 to {}",
                        crate::scene::MAX_SPECTRAL_BANDS
                    ),
                )
            })?;
            scene.output.spectral_bands = Some(bands);
        }
        scene.output.validate_spectral()
    }
}

/// Compositing layers beside the image (see `crate::render::layers`).
#[derive(Args, Debug, Default, Clone)]
pub struct LayerArgs {
    /// Write layers into the EXR beside R,G,B: a comma-separated list of
    /// transmittance, Z; alone, all of them [default: the scene's [output]
    /// layers, none].
    #[arg(long, value_name = "LIST", num_args = 0..=1, default_missing_value = "all")]
    pub layers: Option<String>,
}

impl LayerArgs {
    /// `scene` with the layers asked for (checked by `Scene::validate`).
    fn apply(&self, scene: &mut Scene) -> Result<(), CliError> {
        let Some(list) = &self.layers else {
            return Ok(());
        };
        scene.output.layers = if list == "all" {
            crate::scene::OUTPUT_LAYERS
                .iter()
                .map(|s| (*s).to_owned())
                .collect()
        } else {
            list.split(',').map(|s| s.trim().to_owned()).collect()
        };
        scene.output.check_layers()?;
        Ok(())
    }
}

/// One part of a render split across processes or machines, merged later
/// by `skyrender merge`.
#[derive(Args, Debug, Default, Clone)]
pub struct SplitArgs {
    /// Render only these pixels, X,Y,W,H (a part file, EXR) [default: the
    /// whole image].
    #[arg(long, value_name = "X,Y,W,H", conflicts_with_all = ["tiles", "time_start"])]
    pub tile: Option<String>,
    /// Split the image into K bands of whole rows and render band
    /// --tile-index (a part file, EXR) [default: 1].
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "K",
        requires = "tile_index",
        conflicts_with = "time_start"
    )]
    pub tiles: Option<i64>,
    /// The band to render, 0 to K-1 (with --tiles).
    #[arg(
        long,
        allow_negative_numbers = true,
        value_name = "I",
        requires = "tiles"
    )]
    pub tile_index: Option<i64>,
    /// Render only passes START..END (from 0, END excluded, at most the
    /// scene's spp) into a part file (EXR) [default: 0..spp].
    #[arg(long, value_name = "START..END", conflicts_with = "time_start")]
    pub passes: Option<String>,
}

impl SplitArgs {
    /// The part to render, or `None` for a whole render.
    fn part(&self, scene: &Scene) -> Result<Option<(PassRange, Tile)>, CliError> {
        if self.tile.is_none() && self.tiles.is_none() && self.passes.is_none() {
            return Ok(None);
        }
        if scene.render.mode == crate::scene::RenderMode::Fast {
            return Err(SceneError::new(
                "mode",
                "the fast mode renders a whole image: split renders (--tile, --tiles, --passes) are for the reference mode",
            )
            .into());
        }
        let (width, height) = (scene.render.width, scene.render.height);
        let fail = |parameter: &str, e: String| SceneError::new(parameter, e);
        let tile = match (&self.tile, self.tiles, self.tile_index) {
            (Some(text), _, _) => Tile::parse(text, width, height).map_err(|e| fail("tile", e))?,
            (None, Some(k), Some(i)) => {
                let k = u32::try_from(k)
                    .map_err(|_| fail("tiles", format!("{k} is not a count of tiles")))?;
                let i =
                    u32::try_from(i).map_err(|_| fail("tile index", format!("{i} is negative")))?;
                Tile::band(k, i, width, height).map_err(|e| fail("tiles", e))?
            }
            _ => Tile::whole(width, height),
        };
        let passes = match &self.passes {
            Some(text) => {
                PassRange::parse(text, scene.render.spp).map_err(|e| fail("passes", e))?
            }
            None => PassRange {
                start: 0,
                end: scene.render.spp,
            },
        };
        Ok(Some((passes, tile)))
    }
}

/// One file to render: its scene, its path and its frame label.
struct Job {
    scene: Scene,
    path: PathBuf,
    label: String,
}

/// The files `render` writes, checked before any is rendered: an invalid
/// frame, pattern or range stops the command with nothing written.
fn jobs(base: &Scene, output: &Path, sequence: &SequenceArgs) -> Result<Vec<Job>, CliError> {
    let Some(start) = &sequence.time_start else {
        return Ok(vec![Job {
            scene: base.clone(),
            path: output.to_path_buf(),
            label: String::new(),
        }]);
    };
    let frames = sequence.frames.unwrap_or(0);
    let frames = u32::try_from(frames).map_err(|_| {
        SceneError::new(
            "frames",
            format!(
                "{frames} is outside the valid range 1 to {}",
                export::MAX_FRAMES
            ),
        )
    })?;
    let end = sequence.time_end.as_deref().unwrap_or(start);
    let timelapse = Timelapse::new(start, end, frames)?;
    let range = match &sequence.frame_range {
        Some(text) => FrameRange::parse(text, frames)?,
        None => FrameRange {
            first: 1,
            last: frames,
        },
    };
    let pattern = FramePattern::parse(output);
    if pattern.is_none() && range.first != range.last {
        return Err(SceneError::new(
            "output",
            format!(
                "'{}' has no run of # for the frame number, which a sequence of frames needs \
                 (e.g. sky_####.exr)",
                output.display()
            ),
        )
        .into());
    }
    (range.first..=range.last)
        .map(|frame| {
            let scene = timelapse.scene_for(base, frame)?;
            let path = pattern
                .as_ref()
                .map_or_else(|| output.to_path_buf(), |p| p.path_for(frame));
            let label = format!(
                "frame {frame}/{frames} ({}, sun {:.2}°) ",
                scene.sun.date_time.as_deref().unwrap_or_default(),
                scene.sun.elevation_deg
            );
            Ok(Job { scene, path, label })
        })
        .collect()
}

/// Renders one part of a split render into a part file.
fn run_part(
    args: &SceneArgs,
    scene: &Scene,
    (passes, tile): (PassRange, Tile),
    output: &Path,
    resume: bool,
) -> Result<(), CliError> {
    if !matches!(OutputFormat::from_path(output)?, OutputFormat::Exr) {
        return Err(SceneError::new(
            "output",
            format!(
                "'{}': a part of a split render is an EXR file (merge the parts into a PNG)",
                output.display()
            ),
        )
        .into());
    }
    check_output_path(output)?;
    if resume && output.exists() {
        eprintln!(
            "skyrender: note: --resume: {} exists, skipped",
            output.display()
        );
        return Ok(());
    }
    let pool = args.thread_pool()?;
    args.print_notes(scene);
    let start = Instant::now();
    let cancel = AtomicBool::new(false);
    let paths = pool
        .install(|| export::render_part_to_file(scene, passes, tile, output, &cancel, |_, _| {}))?;
    emit(&format!(
        "part: passes {} of tile {} ({} camera paths) in {:.2} s -> {}\n",
        passes.describe(),
        tile.describe(),
        paths,
        start.elapsed().as_secs_f64(),
        output.display()
    ));
    Ok(())
}

/// `skyrender render`.
pub fn run(
    args: &SceneArgs,
    output: &Path,
    sequence: &SequenceArgs,
    split: &SplitArgs,
    spectral: &SpectralArgs,
    layers: &LayerArgs,
) -> Result<(), CliError> {
    let mut base = args.build()?;
    spectral.apply(&mut base)?;
    layers.apply(&mut base)?;
    if !base.output.layers.is_empty() && base.output.spectral_bands.is_some() {
        return Err(SceneError::new(
            "output",
            "layers and a spectral image do not go into one file yet: render them as two",
        )
        .into());
    }
    if !base.output.layers.is_empty()
        && !matches!(OutputFormat::from_path(output)?, OutputFormat::Exr)
    {
        return Err(SceneError::new(
            "output",
            format!(
                "'{}': layers ({}) need an EXR file, not a PNG",
                output.display(),
                base.output.layers.join(", ")
            ),
        )
        .into());
    }
    if let Some(part) = split.part(&base)? {
        // The view rays' layers are written by the merge; the paths' need
        // the whole render (`export::render_part_to_file` says so).

        return run_part(args, &base, part, output, sequence.resume);
    }
    let mut jobs = jobs(&base, output, sequence)?;
    for job in &jobs {
        check_output_path(&job.path)?;
        export::check_spectral_output(&job.scene, &job.path)?;
    }
    if sequence.resume {
        let before = jobs.len();
        jobs.retain(|job| !job.path.exists());
        if before > jobs.len() {
            eprintln!(
                "skyrender: note: --resume: {} of {before} file(s) exist, skipped",
                before - jobs.len()
            );
        }
    }
    let pool = args.thread_pool()?;
    // A timelapse's frames have their dates (for the notes on --lat/--lon).
    args.print_notes(jobs.first().map_or(&base, |job| &job.scene));
    let spp = u64::from(base.render.spp);
    let total = spp * jobs.len() as u64;
    let bar = if std::io::stderr().is_terminal() && total > 0 {
        let bar = indicatif::ProgressBar::new(total);
        let unit = if jobs.len() > 1 {
            "passes of all frames"
        } else {
            "spp"
        };
        bar.set_style(
            indicatif::ProgressStyle::with_template(&format!(
                "{{elapsed_precise}} [{{bar:40}}] {{pos}}/{{len}} {unit}, eta {{eta}}"
            ))
            .expect("valid template"),
        );
        bar
    } else {
        indicatif::ProgressBar::hidden()
    };
    let cancel = AtomicBool::new(false);
    for (done, job) in jobs.iter().enumerate() {
        let start = Instant::now();
        let offset = done as u64 * spp;
        let written = pool.install(|| {
            export::render_to_file(&job.scene, &job.path, &cancel, |pass, _| {
                bar.set_position(offset + u64::from(pass));
            })
        })?;
        let seconds = start.elapsed().as_secs_f64();
        bar.suspend(|| {
            report(&job.scene, &job.label, &job.path, &written, seconds);
        });
    }
    bar.finish_and_clear();
    Ok(())
}

/// The line `render` prints per file written.
fn report(scene: &Scene, label: &str, path: &Path, written: &Written, seconds: f64) {
    let Written {
        spp,
        paths,
        discarded,
        ..
    } = *written;
    // Adaptive sampling gives noisy pixels more than one sample per
    // pass: say how many paths a pixel got on average.
    let pixels = f64::from(scene.render.width) * f64::from(scene.render.height);
    let mean_spp = paths as f64 / pixels;
    let mut notes = Vec::new();
    if scene.render.adaptive_sampling && mean_spp > f64::from(spp) {
        notes.push(format!("adaptive: {mean_spp:.1} per pixel on average"));
    }
    // Mirror pairs double the samples behind each pixel.
    if crate::render::mirror_pairs(scene).is_some() {
        notes.push("read in mirror pairs".to_owned());
    } else if crate::render::mirror_halves(scene).is_some() {
        notes.push("read in mirror halves".to_owned());
    }
    let adaptive = if notes.is_empty() {
        String::new()
    } else {
        format!(" ({})", notes.join("; "))
    };
    // How it stopped, where a rule other than the passes did, and the
    // noise where it was estimated.
    let mut stop = Vec::new();
    if let Some(noise) = written.noise {
        let target = scene
            .render
            .noise_percent
            .map(|t| format!(", target {t} %"))
            .unwrap_or_default();
        stop.push(format!("estimated noise {:.2} %{target}", 100.0 * noise));
    }
    match written.stop {
        Stop::Passes if scene.render.noise_percent.is_some() => {
            stop.push(format!("the noise target not met in --spp {spp} passes"));
        }
        Stop::Passes => {}
        Stop::NoiseTarget => stop.push("stopped at the noise target".to_owned()),
        Stop::TimeLimit => stop.push("stopped by the time limit".to_owned()),
    }
    let stop = if stop.is_empty() {
        String::new()
    } else {
        format!("; {}", stop.join(", "))
    };
    emit(&format!(
        "{label}{}x{} at {spp} spp{adaptive} in {seconds:.2} s ({:.3} M camera paths/s), {discarded} samples discarded{stop} -> {}\n",
        scene.render.width,
        scene.render.height,
        paths as f64 / seconds / 1e6,
        path.display()
    ));
}
