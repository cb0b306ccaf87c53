//! Rendering to files: one scene to one EXR or PNG, and a timelapse's
//! frames. The one service behind `skyrender render` and the app's export.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use chrono::{DateTime, Duration, FixedOffset, SecondsFormat};

use crate::output;
use crate::physics::solar_position;
use crate::render::exact::ExactSum;
use crate::render::fast;
use crate::render::noise_estimate::Stop;
use crate::render::parts::{PartData, PassRange, Tile};
use crate::render::service::Rendered;
use crate::render::{service, MirrorAxis, OutOfMemory, Renderer};
use crate::scene::{RenderMode, Scene, SceneError};

/// Why a render to a file did not produce its file.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The scene or a sequence setting is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Writing the file failed.
    #[error(transparent)]
    Output(#[from] output::OutputError),
    /// The render's buffers do not fit in memory.
    #[error(transparent)]
    Memory(#[from] OutOfMemory),
    /// The render was cancelled before its last pass.
    #[error("render cancelled")]
    Cancelled,
}

/// The header metadata written into EXR files: `skyrender:spp` is the passes
/// rendered (the least samples a pixel has), `skyrender:samples_per_pixel`
/// the camera paths per pixel on average (more under adaptive sampling),
/// `skyrender:mirror_pairs` whether pixels were read with their mirror
/// images in the sun's vertical plane (`columns` or `rows`: the image's
/// mirrored axis; `halves`: each pixel's two parts split at the sun's
/// azimuth with their mirror images', [`crate::render::HalfMirror`];
/// `none`), which doubles the samples behind each pixel.
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
                None if crate::render::mirror_halves(scene).is_some() => "halves",
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

/// Everything a rendered image's header carries: [`exr_metadata`], the
/// lighting ([`crate::lighting::metadata`]) and, for an equirect map, the
/// standard `envmap` attribute (`latlong`).
pub fn image_metadata(
    scene: &Scene,
    image: &output::RgbImage,
    spp: u32,
    paths: u64,
    discarded: u64,
) -> Vec<(String, String)> {
    let mut metadata = exr_metadata(scene, spp, paths, discarded);
    metadata.extend(crate::lighting::metadata(scene, image));
    if scene.camera.kind == crate::scene::CameraKind::Equirect {
        metadata.push(("envmap".into(), "latlong".into()));
    }
    metadata
}

/// What a render to a file did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Written {
    /// Passes rendered (the least samples a pixel has; the fast mode's
    /// coarse render's).
    pub spp: u32,
    /// Camera paths traced.
    pub paths: u64,
    /// Samples discarded as not finite.
    pub discarded: u64,
    /// The image's estimated relative noise (0.01: 1 %), where it was
    /// estimated (a noise target or the variance layer;
    /// [`crate::render::noise_estimate`]; the fast mode's coarse render's).
    pub noise: Option<f64>,
    /// Why the render stopped.
    pub stop: Stop,
}

impl Written {
    fn of(rendered: &Rendered) -> Self {
        Self {
            spp: rendered.passes,
            paths: rendered.paths,
            discarded: rendered.film.discarded,
            noise: rendered.noise,
            stop: rendered.stop,
        }
    }

    /// The header's entries of how the render stopped:
    /// `skyrender:stopped_by` ([`Stop::describe`]) and, where it was
    /// estimated, `skyrender:noise_estimate_percent`.
    fn metadata(&self) -> Vec<(String, String)> {
        let mut entries = vec![(
            "skyrender:stopped_by".to_owned(),
            self.stop.describe().to_owned(),
        )];
        if let Some(noise) = self.noise {
            entries.push((
                "skyrender:noise_estimate_percent".to_owned(),
                format!("{:.3}", 100.0 * noise),
            ));
        }
        entries
    }
}

/// Render `scene` and write it to `path` (EXR or PNG), atomically;
/// `progress` receives the passes done and the most there will be.
pub fn render_to_file(
    scene: &Scene,
    path: &Path,
    cancel: &AtomicBool,
    mut progress: impl FnMut(u32, u32),
) -> Result<Written, ExportError> {
    check_spectral_output(scene, path)?;
    if scene.render.mode == RenderMode::Fast {
        return render_fast_to_file(scene, path, cancel, progress);
    }
    let renderer = Renderer::new(scene)?;
    let layers = &scene.output.layers;
    if !layers.is_empty()
        && !matches!(
            output::OutputFormat::from_path(path)?,
            output::OutputFormat::Exr
        )
    {
        return Err(SceneError::new(
            "output",
            format!(
                "'{}': layers ({}) need an EXR file, not a PNG",
                path.display(),
                layers.join(", ")
            ),
        )
        .into());
    }
    if !layers.is_empty() && scene.output.spectral_bands.is_some() {
        return Err(SceneError::new(
            "output",
            "layers and a spectral image do not go into one file yet: render them as two",
        )
        .into());
    }
    if renderer.variance_layer() && scene.render.spp < 3 {
        return Err(SceneError::new(
            "layers",
            format!(
                "variance is estimated from the spread of the passes after the first: it needs spp of 3 or more, not {}",
                scene.render.spp
            ),
        )
        .into());
    }
    let total = scene.render.spp;
    let rendered = service::render_blocking(&renderer, cancel, |pass, _| progress(pass, total))?
        .ok_or(ExportError::Cancelled)?;
    let written = Written::of(&rendered);
    let film = rendered.film;
    let image = film.try_to_rgb().map_err(|_| renderer.out_of_memory())?;
    let mut metadata = image_metadata(scene, &image, written.spp, written.paths, written.discarded);
    metadata.extend(written.metadata());
    let spectral = film
        .try_spectral_planes()
        .map_err(|_| renderer.out_of_memory())?;
    if let Some(planes) = spectral {
        let centres = crate::render::film_spectral::band_centres_nm(planes.len());
        output::spectral::write_spectral_exr(path, &image, &centres, planes, &metadata)?;
    } else if !layers.is_empty() {
        write_layered_exr(scene, &renderer, &film, path, &image, metadata)?;
    } else {
        output::write_image(
            path,
            &image,
            &metadata,
            scene.render.exposure_ev.map(|v| v as f32),
        )?;
    }
    Ok(written)
}

/// A fast-mode image ([`crate::render::fast`]) and the coarse render
/// behind it.
#[derive(Clone, Debug)]
pub struct FastImage {
    /// Linear Rec.709, Y in cd m⁻², at the scene's resolution.
    pub image: output::RgbImage,
    /// What the coarse render did: its passes, paths, discarded samples,
    /// its estimated noise (which the composition's interpolation and
    /// denoising only lower: an upper bound of the image's) and its stop.
    pub coarse: Written,
    /// The coarse render's width and height.
    pub coarse_size: (u32, u32),
}

/// Renders `scene` in the fast mode ([`crate::render::fast`]): its
/// coarse render by Monte Carlo, reporting its passes to `progress`
/// (done, most), then the model corrected by it; `None` if `cancel` was
/// set. The memory of both sizes is checked before any work.
pub fn render_fast(
    scene: &Scene,
    cancel: &AtomicBool,
    mut progress: impl FnMut(u32, u32),
) -> Result<Option<FastImage>, ExportError> {
    scene.validate()?;
    let coarse = Renderer::new(&fast::coarse_scene(scene))?;
    fast::check_memory(scene)?;
    let total = scene.render.spp;
    let Some(rendered) =
        service::render_blocking(&coarse, cancel, |pass, _| progress(pass, total))?
    else {
        return Ok(None);
    };
    let image = fast::compose(scene, &coarse, &rendered.film)?;
    Ok(Some(FastImage {
        image,
        coarse: Written::of(&rendered),
        coarse_size: (coarse.scene.render.width, coarse.scene.render.height),
    }))
}

/// [`render_to_file`] in the fast mode ([`crate::render::fast`]): the
/// header says so (`skyrender:mode` `fast`, `skyrender:fast_scale`,
/// `skyrender:coarse_size`), and its sample counts and noise are the
/// coarse render's.
fn render_fast_to_file(
    scene: &Scene,
    path: &Path,
    cancel: &AtomicBool,
    progress: impl FnMut(u32, u32),
) -> Result<Written, ExportError> {
    output::OutputFormat::from_path(path)?;
    let rendered = render_fast(scene, cancel, progress)?.ok_or(ExportError::Cancelled)?;
    let mut coarse = scene.clone();
    (coarse.render.width, coarse.render.height) = rendered.coarse_size;
    let written = rendered.coarse;
    let mut metadata = image_metadata(
        &coarse,
        &rendered.image,
        written.spp,
        written.paths,
        written.discarded,
    );
    metadata.extend(written.metadata());
    // The scene as asked for, not the coarse one.
    for (key, value) in &mut metadata {
        if key == "skyrender:scene" {
            *value = scene.to_toml();
        }
    }
    let (cw, ch) = rendered.coarse_size;
    metadata.extend([
        ("skyrender:mode".into(), "fast".into()),
        (
            "skyrender:fast_scale".into(),
            scene.render.fast_scale.to_string(),
        ),
        ("skyrender:coarse_size".into(), format!("{cw}x{ch}")),
    ]);
    output::write_image(
        path,
        &rendered.image,
        &metadata,
        scene.render.exposure_ev.map(|v| v as f32),
    )?;
    Ok(written)
}

/// Checks that `scene`'s spectral image, if it asks for one, can be
/// written to `path`: an EXR (a PNG holds no spectra), bands in range.
pub fn check_spectral_output(scene: &Scene, path: &Path) -> Result<(), ExportError> {
    if scene.output.spectral_bands.is_none() {
        return Ok(());
    }
    scene.output.validate_spectral()?;
    if !matches!(
        output::OutputFormat::from_path(path)?,
        output::OutputFormat::Exr
    ) {
        return Err(SceneError::new(
            "output",
            format!(
                "'{}': a spectral image needs an EXR file (a PNG holds only RGB)",
                path.display()
            ),
        )
        .into());
    }
    Ok(())
}

/// Writes `image` (`R`, `G`, `B`) and the channels of the scene's layers
/// (from `film`'s paths, [`crate::render::film_layers`], and from the view
/// rays, [`crate::render::layers`]) into one EXR at `path`, atomically,
/// with the render's `metadata` and the layers' names (`skyrender:layers`).
fn write_layered_exr(
    scene: &Scene,
    renderer: &Renderer,
    film: &crate::render::Film,
    path: &Path,
    image: &output::RgbImage,
    mut metadata: Vec<(String, String)>,
) -> Result<(), ExportError> {
    // Each layer once, in the order asked for.
    let mut layers: Vec<String> = Vec::new();
    for layer in &scene.output.layers {
        if !layers.contains(layer) {
            layers.push(layer.clone());
        }
    }
    let mut channels: Vec<(String, Vec<f32>)> = ["R", "G", "B"]
        .iter()
        .enumerate()
        .map(|(c, name)| {
            (
                (*name).to_owned(),
                image.pixels.iter().map(|p| p[c]).collect(),
            )
        })
        .collect();
    let images = film
        .try_layer_images()
        .map_err(|_| renderer.out_of_memory())?;
    if let Some(images) = images {
        for (layer, image) in crate::render::film_layers::PATH_LAYERS.iter().zip(images) {
            if !layers.iter().any(|l| l == layer) {
                continue;
            }
            let names = crate::render::layers::channel_names(layer);
            for (c, name) in names.iter().enumerate() {
                channels.push(((*name).to_owned(), image.iter().map(|p| p[c]).collect()));
            }
        }
    }
    if layers.iter().any(|l| l == "variance") {
        let plane = film
            .variance_plane()
            .ok_or_else(|| SceneError::new("layers", "variance needs at least 3 passes (spp)"))?;
        channels.push(("variance.Y".to_owned(), plane));
    }
    channels.extend(renderer.layer_channels(&layers));
    metadata.push(("skyrender:layers".into(), layers.join(",")));
    output::channels::write_exr_image_channels(
        path,
        image.width as usize,
        image.height as usize,
        channels,
        &metadata,
    )?;
    Ok(())
}

/// The version of the part files [`render_part_to_file`] writes.
const PART_FORMAT: &str = "3";

/// Renders passes `passes` of the pixels in `tile` of `scene` into a part
/// file at `path` (OpenEXR; see [`crate::render::parts`]): per pixel the
/// camera samples' weighted XYZ sums and their weight, exact (each a
/// 128-bit [`ExactSum`] in four `UINT` channels, least significant word
/// first: `sum.X.0` … `sum.X.3`, …, `weight.0` … `weight.3`; with a
/// half mirror also `left.X.0` … and `left_weight.0` …, those of the
/// samples drawn in the pixels' left parts), the splats'
/// sums (`splat.X`…, f32, where the renderer splats) and the part's own
/// image (`R`, `G`, `B`, for a look), with the
/// scene, the passes, the tile and the counts a merge needs in the header.
/// Returns the camera paths traced.
pub fn render_part_to_file(
    scene: &Scene,
    passes: PassRange,
    tile: Tile,
    path: &Path,
    cancel: &AtomicBool,
    progress: impl FnMut(u32, &crate::render::Film),
) -> Result<u64, ExportError> {
    if scene.output.spectral_bands.is_some() {
        return Err(SceneError::new(
            "output",
            "a part of a split render holds no spectral image (render it whole)",
        )
        .into());
    }
    if scene.render.noise_percent.is_some() || scene.render.time_limit_s.is_some() {
        return Err(SceneError::new(
            "render",
            "a noise target or a time limit stops a whole render: a part renders the passes it is given (--passes)",
        )
        .into());
    }
    let renderer = Renderer::new(scene)?;
    if renderer.path_layers() || renderer.variance_layer() {
        return Err(SceneError::new(
            "output",
            "the sky, sun, ground and variance layers come from a whole render: a part of a split render holds none (render it whole)",
        )
        .into());
    }
    let (film, paths) = service::render_part_blocking(&renderer, passes, tile, cancel, progress)?
        .ok_or(ExportError::Cancelled)?;
    let part = film.part_data(passes);
    let image = film.try_to_rgb().map_err(|_| renderer.out_of_memory())?;
    let plane = |f: &dyn Fn(usize) -> f32| (0..image.pixels.len()).map(f).collect::<Vec<f32>>();
    let mut channels = Vec::new();
    let mut words = Vec::new();
    let mut push_exact = |name: &str, value: &dyn Fn(usize) -> ExactSum| {
        for k in 0..4 {
            let plane = (0..image.pixels.len()).map(|i| value(i).to_words()[k]);
            words.push((format!("{name}.{k}"), plane.collect::<Vec<u32>>()));
        }
    };
    push_exact("weight", &|i| part.weights[i]);
    if !part.left_weights.is_empty() {
        push_exact("left_weight", &|i| part.left_weights[i]);
    }
    for (c, name) in ["X", "Y", "Z"].iter().enumerate() {
        push_exact(&format!("sum.{name}"), &|i| part.sums[i][c]);
        if !part.left_sums.is_empty() {
            push_exact(&format!("left.{name}"), &|i| part.left_sums[i][c]);
        }
        if !part.splat_sums.is_empty() {
            channels.push((format!("splat.{name}"), plane(&|i| part.splat_sums[i][c])));
        }
        if !part.splat_left.is_empty() {
            channels.push((
                format!("splat_left.{name}"),
                plane(&|i| part.splat_left[i][c]),
            ));
        }
    }
    for (c, name) in ["R", "G", "B"].iter().enumerate() {
        channels.push(((*name).to_owned(), plane(&|i| image.pixels[i][c])));
    }
    let metadata = vec![
        ("skyrender:part".to_owned(), PART_FORMAT.to_owned()),
        ("skyrender:version".into(), env!("CARGO_PKG_VERSION").into()),
        ("skyrender:scene".into(), scene.to_toml()),
        ("skyrender:part_passes".into(), passes.describe()),
        ("skyrender:part_tile".into(), tile.describe()),
        ("skyrender:paths".into(), paths.to_string()),
        ("skyrender:splat_paths".into(), part.splat_paths.to_string()),
        (
            "skyrender:camera_discarded".into(),
            part.camera_discarded.to_string(),
        ),
        (
            "skyrender:splat_discarded".into(),
            part.splat_discarded.to_string(),
        ),
    ];
    output::channels::write_exr_channels_with_words(
        path,
        image.width as usize,
        image.height as usize,
        channels,
        words,
        &metadata,
    )?;
    Ok(paths)
}

/// A part file read back.
struct Part {
    scene_toml: String,
    data: PartData,
    paths: u64,
}

fn read_part(path: &Path) -> Result<Part, String> {
    let file = output::channels::read_exr_channels(path)?;
    let name = path.display();
    let text = |key: &str| {
        file.text.get(key).cloned().ok_or_else(|| {
            format!("'{name}' is not a part of a split render (no {key}; render it with --tile/--tiles/--passes)")
        })
    };
    if text("skyrender:part")? != PART_FORMAT {
        return Err(format!("'{name}': a part file of another format version"));
    }
    let scene_toml = text("skyrender:scene")?;
    let scene = Scene::from_toml(&scene_toml).map_err(|e| format!("'{name}': {e}"))?;
    let (width, height) = (scene.render.width, scene.render.height);
    if (file.width, file.height) != (width as usize, height as usize) {
        return Err(format!(
            "'{name}': its size is not its scene's {width}×{height}"
        ));
    }
    let passes = PassRange::parse(&text("skyrender:part_passes")?, scene.render.spp)
        .map_err(|e| format!("'{name}': {e}"))?;
    let tile = Tile::parse(&text("skyrender:part_tile")?, width, height)
        .map_err(|e| format!("'{name}': {e}"))?;
    let count = |key: &str| -> Result<u64, String> {
        text(key)?
            .parse()
            .map_err(|_| format!("'{name}': {key} is not a count"))
    };
    let channel = |key: &str| {
        file.channels
            .get(key)
            .ok_or_else(|| format!("'{name}': no channel {key}"))
    };
    let triple = |prefix: &str| -> Result<Vec<[f32; 3]>, String> {
        let (x, y, z) = (
            channel(&format!("{prefix}.X"))?,
            channel(&format!("{prefix}.Y"))?,
            channel(&format!("{prefix}.Z"))?,
        );
        Ok((0..x.len()).map(|i| [x[i], y[i], z[i]]).collect())
    };
    let exact = |key: &str| -> Result<Vec<ExactSum>, String> {
        let planes = (0..4)
            .map(|k| {
                let channel = format!("{key}.{k}");
                file.words
                    .get(&channel)
                    .filter(|v| v.len() == width as usize * height as usize)
                    .ok_or_else(|| format!("'{name}': no 32-bit integer channel {channel}"))
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok((0..planes[0].len())
            .map(|i| ExactSum::from_words([0, 1, 2, 3].map(|k| planes[k][i])))
            .collect())
    };
    let exact_triple = |prefix: &str| -> Result<Vec<[ExactSum; 3]>, String> {
        let [x, y, z] = ["X", "Y", "Z"].map(|c| exact(&format!("{prefix}.{c}")));
        let (x, y, z) = (x?, y?, z?);
        Ok((0..x.len()).map(|i| [x[i], y[i], z[i]]).collect())
    };
    let sums = exact_triple("sum")?;
    let (left_sums, left_weights) = if file.words.contains_key("left.X.0") {
        (exact_triple("left")?, exact("left_weight")?)
    } else {
        (Vec::new(), Vec::new())
    };
    let splat_sums = if file.channels.contains_key("splat.X") {
        triple("splat")?
    } else {
        Vec::new()
    };
    let splat_left = if file.channels.contains_key("splat_left.X") {
        triple("splat_left")?
    } else {
        Vec::new()
    };
    Ok(Part {
        data: PartData {
            passes,
            tile,
            sums,
            weights: exact("weight")?,
            left_sums,
            left_weights,
            splat_sums,
            splat_left,
            splat_paths: count("skyrender:splat_paths")?,
            camera_discarded: count("skyrender:camera_discarded")?,
            splat_discarded: count("skyrender:splat_discarded")?,
        },
        paths: count("skyrender:paths")?,
        scene_toml,
    })
}

/// Merges the part files at `paths` into the image a single render of
/// their scene gives (see [`crate::render::parts`] for how exactly) and
/// writes it to `output` (EXR or PNG) with the single render's metadata.
/// Parts of different scenes, overlapping pass ranges and missing tiles or
/// passes are refused before anything is written. Returns the scene.
pub fn merge_parts(paths: &[PathBuf], output: &Path) -> Result<Scene, String> {
    if paths.is_empty() {
        return Err("no part files given".into());
    }
    let parts: Vec<Part> = paths
        .iter()
        .map(|p| read_part(p))
        .collect::<Result<_, _>>()?;
    let first = &parts[0];
    if let Some((i, _)) = parts
        .iter()
        .enumerate()
        .find(|(_, p)| p.scene_toml != first.scene_toml)
    {
        return Err(format!(
            "'{}' and '{}' are parts of different scenes",
            paths[0].display(),
            paths[i].display()
        ));
    }
    let scene = Scene::from_toml(&first.scene_toml).map_err(|e| e.to_string())?;
    let (width, height, spp) = (scene.render.width, scene.render.height, scene.render.spp);
    let cover: Vec<(PassRange, Tile)> =
        parts.iter().map(|p| (p.data.passes, p.data.tile)).collect();
    crate::render::parts::check_cover(&cover, spp, width, height)
        .map_err(|e| format!("the parts do not make one render: {e}"))?;
    let splats = parts.iter().any(|p| !p.data.splat_sums.is_empty());
    if splats && parts.iter().any(|p| p.data.splat_sums.is_empty()) {
        return Err("some parts have splats and some do not: parts of different builds".into());
    }
    if crate::render::mirror_halves(&scene).is_some()
        && parts.iter().any(|p| p.data.left_sums.is_empty())
    {
        return Err("some parts lack the sums of their pixels' left parts (the scene's sun is off the pixel grid): parts of different builds".into());
    }
    let data: Vec<PartData> = parts.iter().map(|p| p.data.clone()).collect();
    let film = crate::render::Film::from_parts(
        width,
        height,
        spp,
        (
            crate::render::mirror_pairs(&scene),
            crate::render::mirror_halves(&scene),
        ),
        splats,
        &data,
    )
    .map_err(|_| format!("not enough memory to merge a {width}×{height} image"))?;
    let image = film
        .try_to_rgb()
        .map_err(|_| format!("not enough memory to merge a {width}×{height} image"))?;
    let total_paths = parts.iter().map(|p| p.paths).sum();
    let mut metadata = image_metadata(&scene, &image, spp, total_paths, film.discarded);
    // Every part rendered the passes it was given: the header a whole
    // render of them writes (split renders take no noise target or time
    // limit).
    metadata.push((
        "skyrender:stopped_by".into(),
        Stop::Passes.describe().into(),
    ));
    if scene.output.layers.is_empty() {
        output::write_image(
            output,
            &image,
            &metadata,
            scene.render.exposure_ev.map(|v| v as f32),
        )
        .map_err(|e| e.to_string())?;
    } else {
        // The layers of the view rays (parts hold no path layers).
        let format = output::OutputFormat::from_path(output).map_err(|e| e.to_string())?;
        if !matches!(format, output::OutputFormat::Exr) {
            return Err(format!(
                "'{}': the scene's layers ({}) need an EXR file, not a PNG",
                output.display(),
                scene.output.layers.join(", ")
            ));
        }
        let renderer = Renderer::new(&scene).map_err(|e| e.to_string())?;
        write_layered_exr(&scene, &renderer, &film, output, &image, metadata)
            .map_err(|e| e.to_string())?;
    }
    Ok(scene)
}

/// An output path with a run of `#` standing for the frame number, zero
/// padded to the run's length (`sky_####.exr` → `sky_0007.exr`), as
/// Blender and Nuke name frames.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FramePattern {
    before: String,
    digits: usize,
    after: String,
}

impl FramePattern {
    /// The pattern in `path`, or `None` where its file name has no `#`.
    /// Only the file name's last run of `#` counts.
    pub fn parse(path: &Path) -> Option<Self> {
        let text = path.to_str()?;
        let name_start = text.rfind(std::path::is_separator).map_or(0, |i| i + 1);
        let end = text[name_start..].rfind('#')? + name_start + 1;
        let start = text[..end].trim_end_matches('#').len();
        Some(Self {
            before: text[..start].to_owned(),
            digits: end - start,
            after: text[end..].to_owned(),
        })
    }

    /// The file of frame `frame`.
    pub fn path_for(&self, frame: u32) -> PathBuf {
        PathBuf::from(format!(
            "{}{frame:0width$}{}",
            self.before,
            self.after,
            width = self.digits
        ))
    }
}

/// Frames `first..=last` (1-based, inclusive, as `--frame-range 3..5`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameRange {
    /// First frame.
    pub first: u32,
    /// Last frame, inclusive.
    pub last: u32,
}

impl FrameRange {
    /// Parses `A..B` (inclusive) or a single frame `A`, within `1..=frames`.
    pub fn parse(text: &str, frames: u32) -> Result<Self, SceneError> {
        let fail = |why: String| SceneError::new("frame range", format!("'{text}': {why}"));
        let number = |s: &str| {
            s.trim()
                .parse::<u32>()
                .map_err(|_| fail("expected FIRST..LAST, frame numbers from 1 (e.g. 1..24)".into()))
        };
        let (first, last) = match text.split_once("..") {
            Some((a, b)) => (number(a)?, number(b)?),
            None => (number(text)?, number(text)?),
        };
        if first == 0 || first > last {
            return Err(fail(
                "the range is empty or reversed (frames count from 1)".into(),
            ));
        }
        if last > frames {
            return Err(fail(format!("the sequence has {frames} frames")));
        }
        Ok(Self { first, last })
    }
}

/// Most frames a timelapse may have (a day at one frame every 5 s).
pub const MAX_FRAMES: u32 = 17_280;

/// A timelapse: `frames` instants evenly spaced from `start` to `end`
/// (both included), each a scene with its own Sun.
#[derive(Clone, Debug, PartialEq)]
pub struct Timelapse {
    start: DateTime<FixedOffset>,
    end: DateTime<FixedOffset>,
    frames: u32,
}

impl Timelapse {
    /// From RFC 3339 times (`2013-05-27T05:00:00-04:00`) and a frame count.
    pub fn new(start: &str, end: &str, frames: u32) -> Result<Self, SceneError> {
        let parse = |name: &str, text: &str| {
            solar_position::parse_date_time(text).map_err(|e| SceneError::new(name, e))
        };
        let start = parse("time start", start)?;
        let end = parse("time end", end)?;
        if !(1..=MAX_FRAMES).contains(&frames) {
            return Err(SceneError::new(
                "frames",
                format!("{frames} is outside the valid range 1 to {MAX_FRAMES}"),
            ));
        }
        if end < start {
            return Err(SceneError::new(
                "time end",
                format!("{end} is before the start {start}"),
            ));
        }
        if frames > 1 && end == start {
            return Err(SceneError::new(
                "time end",
                "equals the start: several frames need a span of time",
            ));
        }
        Ok(Self { start, end, frames })
    }

    /// Frames in the sequence.
    pub fn frames(&self) -> u32 {
        self.frames
    }

    /// The instant of frame `frame` (1-based), to the millisecond, in the
    /// start's UTC offset.
    pub fn time_of(&self, frame: u32) -> DateTime<FixedOffset> {
        if self.frames == 1 {
            return self.start;
        }
        let span_ms = (self.end - self.start).num_milliseconds();
        let step = f64::from(frame - 1) / f64::from(self.frames - 1);
        self.start + Duration::milliseconds((span_ms as f64 * step).round() as i64)
    }

    /// `base` at frame `frame`'s instant: its Sun placed for that time.
    pub fn scene_for(&self, base: &Scene, frame: u32) -> Result<Scene, SceneError> {
        let mut scene = base.clone();
        scene.sun.date_time = Some(
            self.time_of(frame)
                .to_rfc3339_opts(SecondsFormat::AutoSi, false),
        );
        scene.place_sun()?;
        scene.validate()?;
        Ok(scene)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_patterns_pad_the_number() {
        let p = FramePattern::parse(Path::new("out/day_####.exr")).unwrap();
        assert_eq!(p.path_for(7), PathBuf::from("out/day_0007.exr"));
        assert_eq!(p.path_for(12345), PathBuf::from("out/day_12345.exr"));
        let p = FramePattern::parse(Path::new("a#b/f#.png")).unwrap();
        assert_eq!(p.path_for(3), PathBuf::from("a#b/f3.png"));
        assert!(FramePattern::parse(Path::new("a#b/sky.exr")).is_none());
    }

    #[test]
    fn frame_ranges_are_checked() {
        assert_eq!(
            FrameRange::parse("3..5", 24).unwrap(),
            FrameRange { first: 3, last: 5 }
        );
        assert_eq!(
            FrameRange::parse("7", 24).unwrap(),
            FrameRange { first: 7, last: 7 }
        );
        for bad in ["5..3", "0..2", "1..25", "a..b", "", "1...3"] {
            assert!(FrameRange::parse(bad, 24).is_err(), "{bad}");
        }
    }

    #[test]
    fn a_timelapse_spans_its_times_evenly() {
        let t =
            Timelapse::new("2013-05-27T00:00:00-04:00", "2013-05-27T23:00:00-04:00", 24).unwrap();
        assert_eq!(t.time_of(1).to_rfc3339(), "2013-05-27T00:00:00-04:00");
        assert_eq!(t.time_of(13).to_rfc3339(), "2013-05-27T12:00:00-04:00");
        assert_eq!(t.time_of(24).to_rfc3339(), "2013-05-27T23:00:00-04:00");
        assert!(Timelapse::new("2013-05-27T10:00:00Z", "2013-05-27T09:00:00Z", 3).is_err());
        assert!(Timelapse::new("2013-05-27T10:00:00Z", "2013-05-27T10:00:00Z", 3).is_err());
        assert!(Timelapse::new("noon", "2013-05-27T10:00:00Z", 3).is_err());
        assert!(Timelapse::new("2013-05-27T10:00:00Z", "2013-05-27T11:00:00Z", 0).is_err());
    }
}
