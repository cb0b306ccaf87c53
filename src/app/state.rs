//! The preview app's state: the scene being previewed and the display,
//! render and export settings, as a plain struct with no widgets, so that it
//! can be tested without a window.
//!
//! Every method that changes what the renderer sees marks the state *dirty*;
//! the app restarts the render service when [`AppState::take_dirty`] says so.
//! Setters never panic: out-of-range values are clamped and non-finite ones
//! ignored, so any user input is safe.

use super::sun_place::{DatePlace, SunMode};
use crate::atmosphere::{Atmosphere, AtmosphereParams};
use crate::export::{Timelapse, MAX_FRAMES};
use crate::scene::{CameraKind, Scene};

pub use super::export_state::*;

pub use crate::render::service::PREVIEW_BASE_PIXELS;
/// Range of the preview resolution scale (a linear factor on width and height).
pub const PREVIEW_SCALE_RANGE: (f64, f64) = (0.25, 3.0);
/// Range of the sun elevation slider, degrees.
pub const SUN_ELEVATION_RANGE: (f64, f64) = (-20.0, 90.0);
/// Highest observer altitude offered by the app, m.
pub const MAX_APP_ALTITUDE_M: f64 = 1.0e6;
/// Altitude of the "ground" quick button: eye height, m.
pub const GROUND_ALTITUDE_M: f64 = 2.0;
/// Range of the perspective field of view, degrees.
pub const PERSPECTIVE_FOV_RANGE: (f64, f64) = (10.0, 150.0);
/// Range of the fisheye field of view, degrees.
pub const FISHEYE_FOV_RANGE: (f64, f64) = (60.0, 360.0);
/// Range of the ozone column slider, Dobson units.
pub const OZONE_DU_RANGE: (f64, f64) = (0.0, 800.0);
/// Range of the aerosol amount slider (multiple of Elterman's profile).
pub const AEROSOL_AMOUNT_RANGE: (f64, f64) = (0.0, 10.0);
/// Range of the display exposure, EV.
pub const EXPOSURE_RANGE: (f32, f32) = (-25.0, 10.0);
/// Largest target sample count of the preview.
pub const MAX_TARGET_SPP: u32 = 1 << 16;
/// How linear radiance becomes display values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum ToneCurve {
    /// Narkowicz's ACES filmic fit ([`crate::output::tonemap_pixel`]), as the
    /// CLI's PNG output.
    #[default]
    Filmic,
    /// Linear, clipped at display white: shows the true ratios, burns out highlights.
    Clip,
}

impl ToneCurve {
    /// Every curve, in menu order.
    pub const ALL: [ToneCurve; 2] = [Self::Filmic, Self::Clip];

    /// Name shown in the UI.
    pub fn label(self) -> &'static str {
        match self {
            Self::Filmic => "Filmic (ACES)",
            Self::Clip => "Linear (clip)",
        }
    }

    /// Tone-map one linear Rec.709 pixel (Y in cd/m²) to 8-bit sRGB;
    /// `exposure_scale` is `2^EV`. Non-finite pixels become black.
    pub fn map(self, rgb: [f32; 3], exposure_scale: f32) -> [u8; 3] {
        match self {
            Self::Filmic => crate::output::tonemap_pixel(rgb, exposure_scale),
            Self::Clip => {
                if !rgb.iter().all(|c| c.is_finite()) {
                    return [0; 3];
                }
                rgb.map(|c| {
                    let v = (c * exposure_scale).clamp(0.0, 1.0);
                    crate::output::quantize_u8(crate::output::srgb_oetf(v))
                })
            }
        }
    }
}

/// How the preview image is shown.
#[derive(Clone, Debug, PartialEq)]
pub struct DisplaySettings {
    /// Exposure in EV (display value = luminance · 2^EV before the tone curve);
    /// updated from each new frame while `auto_exposure` is on.
    pub exposure_ev: f32,
    /// Follow [`crate::output::auto_exposure_ev`] of the latest frame.
    pub auto_exposure: bool,
    /// The tone curve.
    pub tone_curve: ToneCurve,
    /// Draw a ring around the sun's position.
    pub mark_sun: bool,
    /// Show log luminance in false colour (with a colour bar) instead of
    /// the tone-mapped image.
    pub false_colour: bool,
}

impl Default for DisplaySettings {
    fn default() -> Self {
        Self {
            exposure_ev: -13.0,
            auto_exposure: true,
            tone_curve: ToneCurve::Filmic,
            mark_sun: true,
            false_colour: false,
        }
    }
}

/// How the preview is rendered.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Linear factor on the preview's width and height (1 = 320 × 160 equirect).
    pub preview_scale: f64,
    /// Rendering is paused (the accumulated image is kept).
    pub paused: bool,
    /// Samples per pixel after which the preview stops refining.
    pub target_spp: u32,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            preview_scale: 1.0,
            paused: false,
            target_spp: crate::render::service::PREVIEW_TARGET_SPP,
        }
    }
}

/// The app's state, independent of any widget.
#[derive(Clone, Debug)]
pub struct AppState {
    scene: Scene,
    /// How the image is shown (changing it needs no new render).
    pub display: DisplaySettings,
    render: RenderSettings,
    /// Size and samples of the HDR export.
    pub export: ExportSettings,
    /// Where the export stands.
    pub export_status: ExportStatus,
    /// The latest error to show the user (cleared by the user or on success).
    pub last_error: Option<String>,
    /// The latest informational message (e.g. "saved …").
    pub message: Option<String>,
    /// Ozone column of the model's own profile, DU (what `ozone_du = None` means).
    profile_ozone_du: f64,
    /// How the Sun is placed.
    sun_mode: SunMode,
    /// The date, time and place inputs (kept in manual mode too, for the
    /// next switch to date mode).
    date_place: DatePlace,
    /// Why the date, time and place inputs do not place the Sun, if they don't.
    date_place_error: Option<String>,
    dirty: bool,
}

impl Default for AppState {
    fn default() -> Self {
        Self::new(Scene::preset("midday").unwrap_or_default())
    }
}

impl AppState {
    /// State previewing `scene`; marked dirty so the first frame renders it.
    pub fn new(scene: Scene) -> Self {
        let mut state = Self {
            scene: Scene::default(),
            display: DisplaySettings::default(),
            render: RenderSettings::default(),
            export: ExportSettings::default(),
            export_status: ExportStatus::Idle,
            last_error: None,
            message: None,
            profile_ozone_du: 0.0,
            sun_mode: SunMode::Manual,
            date_place: DatePlace::default(),
            date_place_error: None,
            dirty: true,
        };
        state.set_scene(scene);
        state
    }

    /// The scene as the user set it up (its own render size and spp are what
    /// a saved TOML keeps; the preview uses [`Self::preview_scene`]).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// The render settings.
    pub fn render(&self) -> &RenderSettings {
        &self.render
    }

    /// Whether the scene changed since the last [`Self::take_dirty`].
    pub fn is_dirty(&self) -> bool {
        self.dirty
    }

    /// Report and clear the dirty flag.
    pub fn take_dirty(&mut self) -> bool {
        std::mem::take(&mut self.dirty)
    }

    /// Mark the scene as changed (forces a restart of the preview).
    pub fn mark_dirty(&mut self) {
        self.dirty = true;
    }

    /// Replace the whole scene (a preset or a loaded file). A scene that
    /// fails validation is rejected with its error and the old one kept. A
    /// scene with a date and a place puts the Sun panel in date mode with
    /// its inputs; one without, in manual mode.
    pub fn set_scene(&mut self, scene: Scene) -> bool {
        if let Err(e) = scene.validate() {
            self.last_error = Some(e.to_string());
            return false;
        }
        match DatePlace::from_sun(&scene.sun) {
            Some(place) => {
                self.sun_mode = SunMode::DatePlace;
                self.date_place = place;
            }
            None => self.sun_mode = SunMode::Manual,
        }
        self.date_place_error = None;
        self.adopt(scene);
        true
    }

    /// Makes `scene` the current one: its atmosphere profile's own ozone
    /// column (what the ozone slider's "Profile" returns to) and a restart.
    fn adopt(&mut self, scene: Scene) {
        let mut params = scene.atmosphere.clone();
        params.ozone = true;
        params.ozone_du = None;
        self.profile_ozone_du = Atmosphere::new(params).ozone_column_du();
        self.scene = scene;
        self.dirty = true;
    }

    /// The scene's planet.
    pub fn planet(&self) -> crate::physics::planet::Planet {
        self.scene.planet.preset
    }

    /// Put the scene on `planet` ([`Scene::set_planet`]: its atmosphere
    /// becomes the planet's own, the Sun its distance; a date and place
    /// give way to manual mode off the Earth).
    pub fn set_planet(&mut self, planet: crate::physics::planet::Planet) {
        if self.scene.planet.preset == planet {
            return;
        }
        let mut scene = self.scene.clone();
        scene.set_planet(planet);
        if scene.sun.date_time.is_none() {
            self.sun_mode = SunMode::Manual;
        }
        self.adopt(scene);
    }

    /// Load a built-in preset by name.
    pub fn load_preset(&mut self, name: &str) -> bool {
        match Scene::preset(name) {
            Ok(scene) => {
                let ok = self.set_scene(scene);
                if ok {
                    self.message = Some(format!("preset '{name}'"));
                }
                ok
            }
            Err(e) => {
                self.last_error = Some(e.to_string());
                false
            }
        }
    }

    /// Assign `value`, clamped to `lo..=hi`, to the field `f` selects;
    /// non-finite values are ignored. Marks the state dirty when it changes.
    fn update(&mut self, value: f64, (lo, hi): (f64, f64), f: impl FnOnce(&mut Scene) -> &mut f64) {
        if !value.is_finite() {
            return;
        }
        let value = value.clamp(lo, hi);
        let field = f(&mut self.scene);
        if *field != value {
            *field = value;
            self.dirty = true;
        }
    }

    /// Sun elevation, degrees, clamped to [`SUN_ELEVATION_RANGE`]. Places
    /// the Sun by hand (leaves date mode).
    pub fn set_sun_elevation(&mut self, deg: f64) {
        self.set_sun_mode(SunMode::Manual);
        self.update(deg, SUN_ELEVATION_RANGE, |s| &mut s.sun.elevation_deg);
    }

    /// Sun azimuth, degrees clockwise from north, wrapped to 0–360. Places
    /// the Sun by hand (leaves date mode).
    pub fn set_sun_azimuth(&mut self, deg: f64) {
        self.set_sun_mode(SunMode::Manual);
        let wrapped = if deg == 360.0 {
            deg
        } else {
            deg.rem_euclid(360.0)
        };
        self.update(wrapped, (0.0, 360.0), |s| &mut s.sun.azimuth_deg);
    }

    /// How the Sun is placed.
    pub fn sun_mode(&self) -> SunMode {
        self.sun_mode
    }

    /// The date, time and place inputs (what the Sun panel shows in date mode).
    pub fn date_place(&self) -> &DatePlace {
        &self.date_place
    }

    /// Why the date, time and place inputs do not place the Sun (the scene
    /// then keeps its last valid Sun); `None` when they do, or in manual mode.
    pub fn date_place_error(&self) -> Option<&str> {
        self.date_place_error.as_deref()
    }

    /// Place the Sun by hand or by date. Switching to date mode places it
    /// from the inputs (if they are valid); switching to manual keeps its
    /// elevation and azimuth and clears the scene's date, time and place.
    pub fn set_sun_mode(&mut self, mode: SunMode) {
        if self.sun_mode == mode {
            return;
        }
        self.sun_mode = mode;
        match mode {
            SunMode::Manual => {
                self.date_place_error = None;
                let sun = &mut self.scene.sun;
                if sun.date_time.is_some() || sun.latitude_deg.is_some() {
                    sun.date_time = None;
                    sun.latitude_deg = None;
                    sun.longitude_deg = None;
                    // The Earth–Sun distance was the date's; now 1 AU.
                    self.dirty = true;
                }
            }
            SunMode::DatePlace => self.apply_date_place(),
        }
    }

    /// Set the date, time and place inputs; in date mode the Sun moves to
    /// them if they are valid, and otherwise keeps its place while
    /// [`Self::date_place_error`] says what is wrong.
    pub fn set_date_place(&mut self, place: DatePlace) {
        if self.date_place == place {
            return;
        }
        self.date_place = place;
        if self.sun_mode == SunMode::DatePlace {
            self.apply_date_place();
        }
    }

    /// Place the Sun from the inputs, or record why they cannot.
    fn apply_date_place(&mut self) {
        match self.date_place.place(&self.scene) {
            Ok(scene) => {
                self.date_place_error = None;
                if scene != self.scene {
                    self.scene = scene;
                    self.dirty = true;
                }
            }
            Err(e) => self.date_place_error = Some(e),
        }
    }

    /// Observer altitude, m, clamped to 0–[`MAX_APP_ALTITUDE_M`] (in date
    /// mode the Sun is placed again: its position is the observer's).
    pub fn set_altitude_m(&mut self, m: f64) {
        let before = self.scene.observer.altitude_m;
        self.update(m, (0.0, MAX_APP_ALTITUDE_M), |s| &mut s.observer.altitude_m);
        if self.sun_mode == SunMode::DatePlace && self.scene.observer.altitude_m != before {
            self.apply_date_place();
        }
    }

    /// Switch the camera projection. The field of view is brought into the
    /// new mode's range (a fisheye starts as a hemisphere, 180°).
    pub fn set_camera_kind(&mut self, kind: CameraKind) {
        if self.scene.camera.kind == kind {
            return;
        }
        let camera = &mut self.scene.camera;
        let previous = camera.kind;
        camera.kind = kind;
        match kind {
            CameraKind::Fisheye => camera.fov_deg = 180.0,
            CameraKind::Perspective => {
                let (lo, hi) = PERSPECTIVE_FOV_RANGE;
                if previous == CameraKind::Fisheye || !(lo..=hi).contains(&camera.fov_deg) {
                    camera.fov_deg = 90.0;
                }
            }
            CameraKind::Equirect => {}
        }
        self.dirty = true;
    }

    /// Field of view, degrees, clamped to the current mode's range (the
    /// equirectangular map has none and ignores it).
    pub fn set_fov(&mut self, deg: f64) {
        let range = match self.scene.camera.kind {
            CameraKind::Fisheye => FISHEYE_FOV_RANGE,
            CameraKind::Perspective | CameraKind::Equirect => PERSPECTIVE_FOV_RANGE,
        };
        self.update(deg, range, |s| &mut s.camera.fov_deg);
    }

    /// View direction: yaw (degrees clockwise from north, wrapped to
    /// −180–180) and pitch (clamped to ±90).
    pub fn set_view(&mut self, yaw_deg: f64, pitch_deg: f64) {
        let yaw = (yaw_deg + 180.0).rem_euclid(360.0) - 180.0;
        self.update(yaw, (-180.0, 180.0), |s| &mut s.camera.yaw_deg);
        self.update(pitch_deg, (-90.0, 90.0), |s| &mut s.camera.pitch_deg);
    }

    /// Turn the view by the given angles, degrees.
    pub fn rotate_view(&mut self, d_yaw_deg: f64, d_pitch_deg: f64) {
        let camera = &self.scene.camera;
        self.set_view(camera.yaw_deg + d_yaw_deg, camera.pitch_deg + d_pitch_deg);
    }

    /// Aerosols on or off.
    pub fn set_aerosols(&mut self, on: bool) {
        if self.scene.atmosphere.aerosols != on {
            self.scene.atmosphere.aerosols = on;
            self.dirty = true;
        }
    }

    /// Aerosol amount (multiple of the standard profile), clamped to
    /// [`AEROSOL_AMOUNT_RANGE`]. A changed amount takes the place of the
    /// scene's `[atmosphere.aerosol] optical_depth_550`, as
    /// `--aerosol-amount` does.
    pub fn set_aerosol_amount(&mut self, amount: f64) {
        let before = self.scene.atmosphere.aerosol_amount;
        self.update(amount, AEROSOL_AMOUNT_RANGE, |s| {
            &mut s.atmosphere.aerosol_amount
        });
        if self.scene.atmosphere.aerosol_amount != before {
            self.scene.atmosphere.aerosol.optical_depth_550 = None;
        }
    }

    /// Ozone on or off.
    pub fn set_ozone(&mut self, on: bool) {
        if self.scene.atmosphere.ozone != on {
            self.scene.atmosphere.ozone = on;
            self.dirty = true;
        }
    }

    /// Ozone column in DU (clamped to [`OZONE_DU_RANGE`]), or `None` for the
    /// model profile's own column.
    pub fn set_ozone_du(&mut self, du: Option<f64>) {
        let (lo, hi) = OZONE_DU_RANGE;
        let du = match du {
            Some(v) if !v.is_finite() => return,
            other => other.map(|v| v.clamp(lo, hi)),
        };
        if self.scene.atmosphere.ozone_du != du {
            self.scene.atmosphere.ozone_du = du;
            self.dirty = true;
        }
    }

    /// The ozone column the renderer uses, DU (the profile's own when unset).
    pub fn ozone_column_du(&self) -> f64 {
        self.scene
            .atmosphere
            .ozone_du
            .unwrap_or(self.profile_ozone_du)
    }

    /// Lambertian ground albedo, clamped to 0–1, at every wavelength (it
    /// takes the place of an albedo spectrum).
    pub fn set_ground_albedo(&mut self, albedo: f64) {
        if albedo.is_finite() && self.scene.atmosphere.ground_albedo_spectrum.is_some() {
            self.scene.atmosphere.ground_albedo_spectrum = None;
            self.dirty = true;
        }
        self.update(albedo, (0.0, 1.0), |s| &mut s.atmosphere.ground_albedo);
    }

    /// The ground's albedo spectrum: one of the named spectra
    /// ([`crate::physics::spectrum_file::GROUND_SPECTRA`]), or `None` for
    /// the albedo slider's one number. Another name is ignored.
    pub fn set_ground_spectrum(&mut self, name: Option<&str>) {
        if name.is_some_and(|n| crate::physics::spectrum_file::named_ground(n).is_none()) {
            return;
        }
        let value = name.map(str::to_owned);
        if self.scene.atmosphere.ground_albedo_spectrum != value {
            self.scene.atmosphere.ground_albedo_spectrum = value;
            self.dirty = true;
        }
    }

    /// Preview resolution scale, clamped to [`PREVIEW_SCALE_RANGE`].
    pub fn set_preview_scale(&mut self, scale: f64) {
        if !scale.is_finite() {
            return;
        }
        let (lo, hi) = PREVIEW_SCALE_RANGE;
        let scale = scale.clamp(lo, hi);
        if self.render.preview_scale != scale {
            self.render.preview_scale = scale;
            self.dirty = true;
        }
    }

    /// Samples per pixel after which the preview stops, 1–[`MAX_TARGET_SPP`].
    pub fn set_target_spp(&mut self, spp: u32) {
        let spp = spp.clamp(1, MAX_TARGET_SPP);
        if self.render.target_spp != spp {
            self.render.target_spp = spp;
            self.dirty = true;
        }
    }

    /// Pause or resume rendering (keeps the accumulated image; not a scene change).
    pub fn set_paused(&mut self, paused: bool) {
        self.render.paused = paused;
    }

    /// Width and height of the preview for the current camera mode and
    /// scale ([`crate::render::service::preview_size`]).
    pub fn preview_size(&self) -> (u32, u32) {
        crate::render::service::preview_size(&self.scene, self.render.preview_scale)
    }

    /// The scene the preview renders: the user's scene at the preview size,
    /// with the target sample count.
    pub fn preview_scene(&self) -> Scene {
        crate::render::service::preview_scene(
            &self.scene,
            self.render.preview_scale,
            self.render.target_spp,
        )
    }

    /// The scene an HDR panorama export renders: the user's scene with an
    /// equirectangular camera at the export size and sample count — what
    /// `skyrender render --camera equirect --width W --height H --spp N`
    /// renders for it. When it stops is the Export panel's alone (its spp
    /// and noise target): a loaded scene file's `[render] time_limit_s`,
    /// which the panel does not show, does not cut the export short.
    pub fn export_scene(&self) -> Scene {
        let mut scene = self.scene.clone();
        scene.camera.kind = CameraKind::Equirect;
        let width = self.export.width.clamp(2, MAX_EXPORT_WIDTH);
        scene.render.width = width;
        scene.render.height = width / 2;
        scene.render.spp = self.export.spp.clamp(1, MAX_EXPORT_SPP);
        scene.render.noise_percent = self.export.noise_percent;
        scene.render.time_limit_s = None;
        // The fast mode writes the image alone.
        if self.export.fast {
            scene.render.mode = crate::scene::RenderMode::Fast;
        }
        // Every layer; the variance needs three passes.
        scene.output.layers = if self.export.layers && !self.export.fast {
            crate::scene::OUTPUT_LAYERS
                .iter()
                .filter(|&&l| l != "variance" || scene.render.spp >= 3)
                .map(|&l| l.to_owned())
                .collect()
        } else {
            Vec::new()
        };
        scene
    }

    /// Set the exported panorama's width (height = width / 2), 2–16384.
    pub fn set_export_width(&mut self, width: u32) {
        self.export.width = width.clamp(2, MAX_EXPORT_WIDTH);
    }

    /// Set the export sample count, 1–[`MAX_EXPORT_SPP`].
    pub fn set_export_spp(&mut self, spp: u32) {
        self.export.spp = spp.clamp(1, MAX_EXPORT_SPP);
    }

    /// Set the export's noise target, percent (clamped to the scene's
    /// range), or none.
    pub fn set_export_noise(&mut self, percent: Option<f64>) {
        self.export.noise_percent = percent
            .filter(|p| p.is_finite())
            .map(|p| p.clamp(crate::scene::MIN_NOISE_PERCENT, 100.0));
    }

    /// Set the timelapse's frame count, 1–[`MAX_FRAMES`].
    pub fn set_timelapse_frames(&mut self, frames: u32) {
        self.export.timelapse.frames = frames.clamp(1, MAX_FRAMES);
    }

    /// Set the timelapse's duration, minutes, 0–[`MAX_TIMELAPSE_MINUTES`].
    pub fn set_timelapse_duration(&mut self, minutes: u32) {
        self.export.timelapse.duration_min = minutes.min(MAX_TIMELAPSE_MINUTES);
    }

    /// Whether the export is a timelapse: asked for, and the Sun placed by date.
    pub fn timelapse_enabled(&self) -> bool {
        self.export.timelapse.enabled && self.sun_mode == SunMode::DatePlace
    }

    /// The timelapse the export settings describe: from the Sun panel's
    /// date and time over the set duration. An error says why there is
    /// none (manual Sun, invalid inputs, no `#` in the file name).
    pub fn timelapse(&self) -> Result<Timelapse, String> {
        if self.sun_mode != SunMode::DatePlace {
            return Err("a timelapse needs the Sun placed by date, time and place".into());
        }
        if let Some(e) = &self.date_place_error {
            return Err(e.clone());
        }
        let settings = &self.export.timelapse;
        let name = settings.file_name.trim();
        if name.contains(std::path::is_separator) {
            return Err(format!(
                "invalid file name '{name}': a name only (the folder is asked for next)"
            ));
        }
        if !name.contains('#') {
            return Err(format!(
                "invalid file name '{name}': it needs a run of # for the frame number \
                 (sky_####.exr)"
            ));
        }
        let start = self.date_place.date_time()?;
        let end = self.date_place.date_time_after(settings.duration_min)?;
        Timelapse::new(&start, &end, settings.frames).map_err(|e| e.to_string())
    }

    /// The parameters of the atmosphere as set (for display).
    pub fn atmosphere(&self) -> &AtmosphereParams {
        &self.scene.atmosphere
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_first_preview_is_the_benchmarks_preview_scene() {
        // `skyrender bench`'s `preview` scene is the app's first preview.
        let state = AppState::default();
        assert_eq!(
            state.preview_scene(),
            crate::render::service::default_preview_scene()
        );
        assert_eq!(state.preview_size(), (320, 160));
    }

    #[test]
    fn the_export_writes_every_layer_when_asked() {
        let mut state = AppState::default();
        assert!(state.export_scene().output.layers.is_empty());
        state.export.layers = true;
        let layers = state.export_scene().output.layers;
        assert_eq!(layers.len(), crate::scene::OUTPUT_LAYERS.len());
        state.set_export_spp(2);
        let layers = state.export_scene().output.layers;
        assert!(layers.contains(&"sky".to_owned()) && !layers.contains(&"variance".to_owned()));
    }

    #[test]
    fn the_fast_export_is_the_fast_mode_without_layers() {
        let mut state = AppState::default();
        assert_eq!(
            state.export_scene().render.mode,
            crate::scene::RenderMode::Reference
        );
        state.export.layers = true;
        state.export.fast = true;
        let scene = state.export_scene();
        assert_eq!(scene.render.mode, crate::scene::RenderMode::Fast);
        assert!(scene.output.layers.is_empty());
        scene.validate().unwrap();
    }

    #[test]
    fn setters_mark_dirty_only_on_change() {
        let mut state = AppState::default();
        assert!(state.take_dirty(), "a new state renders its scene");
        assert!(!state.take_dirty());
        state.set_sun_elevation(state.scene().sun.elevation_deg);
        assert!(!state.is_dirty(), "same value: no restart");
        state.set_sun_elevation(10.0);
        assert!(state.take_dirty());
        assert_eq!(state.scene().sun.elevation_deg, 10.0);
        state.set_aerosols(false);
        assert!(state.take_dirty());
        state.set_ozone(false);
        assert!(state.take_dirty());
        state.set_camera_kind(CameraKind::Fisheye);
        assert!(state.take_dirty());
        state.set_paused(true);
        assert!(!state.is_dirty(), "pausing keeps the accumulation");
        state.display.exposure_ev = 3.0;
        assert!(!state.is_dirty(), "display settings need no new render");
    }

    #[test]
    fn the_amount_slider_replaces_a_scenes_optical_depth() {
        let scene = Scene::from_toml("[atmosphere.aerosol]\noptical_depth_550 = 0.1").unwrap();
        let mut state = AppState::new(scene);
        state.set_aerosol_amount(1.0);
        assert_eq!(state.atmosphere().aerosol.optical_depth_550, Some(0.1));
        state.set_aerosol_amount(2.0);
        assert_eq!(state.atmosphere().aerosol.optical_depth_550, None);
        assert!(state.scene().validate().is_ok());
    }

    #[test]
    fn user_input_is_clamped_and_non_finite_ignored() {
        let mut state = AppState::default();
        state.set_sun_elevation(-70.0);
        assert_eq!(state.scene().sun.elevation_deg, -20.0);
        state.set_sun_elevation(f64::NAN);
        assert_eq!(state.scene().sun.elevation_deg, -20.0);
        state.set_sun_azimuth(-90.0);
        assert_eq!(state.scene().sun.azimuth_deg, 270.0);
        state.set_altitude_m(-1.0);
        assert_eq!(state.scene().observer.altitude_m, 0.0);
        state.set_altitude_m(f64::INFINITY);
        assert_eq!(state.scene().observer.altitude_m, 0.0);
        state.set_altitude_m(5e9);
        assert_eq!(state.scene().observer.altitude_m, MAX_APP_ALTITUDE_M);
        state.set_ground_albedo(2.0);
        assert_eq!(state.scene().atmosphere.ground_albedo, 1.0);
        state.set_ground_spectrum(Some("snow"));
        assert_eq!(
            state.scene().atmosphere.ground_albedo_spectrum.as_deref(),
            Some("snow")
        );
        state.set_ground_spectrum(Some("moss"));
        assert_eq!(
            state.scene().atmosphere.ground_albedo_spectrum.as_deref(),
            Some("snow")
        );
        state.set_ground_albedo(0.5);
        assert_eq!(state.scene().atmosphere.ground_albedo_spectrum, None);
        state.set_ozone_du(Some(f64::NAN));
        assert_eq!(state.scene().atmosphere.ozone_du, None);
        state.set_ozone_du(Some(5_000.0));
        assert_eq!(state.scene().atmosphere.ozone_du, Some(OZONE_DU_RANGE.1));
        state.set_target_spp(0);
        assert_eq!(state.render().target_spp, 1);
        state.set_preview_scale(f64::NAN);
        assert_eq!(state.render().preview_scale, 1.0);
        state.set_camera_kind(CameraKind::Perspective);
        state.set_view(200.0, 120.0);
        assert_eq!(state.scene().camera.yaw_deg, -160.0);
        assert_eq!(state.scene().camera.pitch_deg, 90.0);
        state.set_fov(500.0);
        assert_eq!(state.scene().camera.fov_deg, PERSPECTIVE_FOV_RANGE.1);
        state.preview_scene().validate().unwrap();
        state.export_scene().validate().unwrap();
    }

    #[test]
    fn camera_switch_keeps_a_valid_fov() {
        let mut state = AppState::default();
        state.set_camera_kind(CameraKind::Fisheye);
        assert_eq!(state.scene().camera.fov_deg, 180.0);
        state.preview_scene().validate().unwrap();
        state.set_camera_kind(CameraKind::Perspective);
        assert_eq!(state.scene().camera.fov_deg, 90.0);
        state.preview_scene().validate().unwrap();
    }

    #[test]
    fn preview_and_export_scenes() {
        let mut state = AppState::default();
        assert_eq!(state.preview_size(), (320, 160));
        state.set_camera_kind(CameraKind::Fisheye);
        let (w, h) = state.preview_size();
        assert_eq!(w, h);
        assert!((f64::from(w * h) / PREVIEW_BASE_PIXELS - 1.0).abs() < 0.02);
        state.set_preview_scale(0.5);
        let scene = state.preview_scene();
        assert_eq!((scene.render.width, scene.render.height), (113, 113));
        assert_eq!(scene.render.spp, state.render().target_spp);
        state.set_export_width(1024);
        state.set_export_spp(3);
        let export = state.export_scene();
        assert_eq!(export.camera.kind, CameraKind::Equirect);
        assert_eq!(
            (export.render.width, export.render.height, export.render.spp),
            (1024, 512, 3)
        );
        assert_eq!(export.sun, state.scene().sun);
        assert_eq!(export.render.noise_percent, None);
        state.set_export_noise(Some(0.0));
        assert_eq!(
            state.export_scene().render.noise_percent,
            Some(crate::scene::MIN_NOISE_PERCENT)
        );
        state.set_export_noise(Some(1.5));
        state.export_scene().validate().unwrap();
        assert_eq!(state.export_scene().render.noise_percent, Some(1.5));
        // A scene file's time limit and noise target: the panel's rule.
        let mut file = state.scene().clone();
        file.render.time_limit_s = Some(30.0);
        file.render.noise_percent = Some(4.0);
        assert!(state.set_scene(file));
        assert_eq!(state.scene().render.time_limit_s, Some(30.0));
        let export = state.export_scene();
        assert_eq!(export.render.time_limit_s, None);
        assert_eq!(export.render.noise_percent, Some(1.5));
    }

    #[test]
    fn presets_and_invalid_scenes() {
        let mut state = AppState::default();
        for (name, _) in crate::scene::PRESETS {
            assert!(state.load_preset(name), "{name}");
            assert!(state.take_dirty());
        }
        assert!(state.load_preset("airliner"));
        assert_eq!(state.scene().observer.altitude_m, 10_000.0);
        assert!(!state.load_preset("nowhere"));
        assert!(state.last_error.as_deref().unwrap_or("").contains("midday"));
        let mut bad = Scene::default();
        bad.render.spp = 0;
        assert!(!state.set_scene(bad));
        assert_eq!(state.scene().observer.altitude_m, 10_000.0);
    }

    #[test]
    fn ozone_column_defaults_to_the_profile() {
        let mut state = AppState::default();
        let own = state.ozone_column_du();
        assert!((250.0..450.0).contains(&own), "{own}");
        state.set_ozone_du(Some(300.0));
        assert_eq!(state.ozone_column_du(), 300.0);
    }

    fn ithaca() -> DatePlace {
        DatePlace {
            date: "2013-05-27".into(),
            minutes: 11 * 60 + 45,
            utc_offset_min: -240,
            latitude_deg: 42.4434,
            longitude_deg: -76.4816,
        }
    }

    #[test]
    fn date_mode_places_the_sun_and_manual_mode_keeps_it() {
        let mut state = AppState::default();
        state.set_date_place(ithaca());
        assert_eq!(state.sun_mode(), SunMode::Manual);
        assert!(state.take_dirty() && !state.take_dirty());
        assert_eq!(
            state.scene().sun.date_time,
            None,
            "inputs alone move nothing"
        );
        state.set_sun_mode(SunMode::DatePlace);
        assert!(state.take_dirty());
        let sun = state.scene().sun.clone();
        assert_eq!(sun.date_time.as_deref(), Some("2013-05-27T11:45:00-04:00"));
        assert!((sun.elevation_deg - 63.35).abs() < 0.01, "{sun:?}");
        state.export_scene().validate().unwrap();
        // The observer's height is part of where the Sun is seen from.
        state.set_altitude_m(400_000.0);
        assert_eq!(state.scene().sun.date_time, sun.date_time);

        let placed = state.scene().sun.clone();
        state.set_sun_mode(SunMode::Manual);
        assert!(state.take_dirty());
        let manual = &state.scene().sun;
        assert_eq!(
            (manual.elevation_deg, manual.azimuth_deg),
            (placed.elevation_deg, placed.azimuth_deg)
        );
        assert!((manual.elevation_deg - sun.elevation_deg).abs() < 0.01);
        assert_eq!(
            (manual.date_time.as_ref(), manual.latitude_deg),
            (None, None)
        );
        assert!(state.timelapse().is_err(), "a timelapse needs date mode");

        // Setting the Sun by hand leaves date mode.
        state.set_sun_mode(SunMode::DatePlace);
        state.set_sun_elevation(10.0);
        assert_eq!(state.sun_mode(), SunMode::Manual);
        assert_eq!(state.scene().sun.date_time, None);
    }

    #[test]
    fn invalid_date_places_keep_the_last_valid_scene() {
        let mut state = AppState::default();
        state.set_date_place(ithaca());
        state.set_sun_mode(SunMode::DatePlace);
        let valid = state.scene().clone();
        state.take_dirty();
        for bad in [
            DatePlace {
                latitude_deg: 91.0,
                ..ithaca()
            },
            DatePlace {
                date: "2013-5-".into(),
                ..ithaca()
            },
            DatePlace {
                utc_offset_min: -13 * 60,
                ..ithaca()
            },
        ] {
            state.set_date_place(bad.clone());
            assert!(state.date_place_error().is_some(), "{bad:?}");
            assert_eq!(state.scene(), &valid);
            assert!(!state.is_dirty());
            assert_eq!(state.date_place(), &bad, "the input is kept to be fixed");
            assert!(state.timelapse().is_err());
        }
        state.set_date_place(ithaca());
        assert_eq!(state.date_place_error(), None);
        // A loaded scene with a date brings its inputs; one without, manual mode.
        let mut dated = Scene::default();
        dated.sun.date_time = Some("2013-12-21T12:00:00+01:00".into());
        dated.sun.latitude_deg = Some(78.2232);
        dated.sun.longitude_deg = Some(15.6267);
        dated.place_sun().unwrap();
        assert!(state.set_scene(dated));
        assert_eq!(state.sun_mode(), SunMode::DatePlace);
        assert_eq!(state.date_place().utc_offset_min, 60);
        assert!(state.scene().sun.elevation_deg < 0.0, "polar night");
        assert!(state.load_preset("midday"));
        assert_eq!(state.sun_mode(), SunMode::Manual);
    }

    #[test]
    fn timelapse_settings_are_checked() {
        let mut state = AppState::default();
        state.set_date_place(ithaca());
        state.set_sun_mode(SunMode::DatePlace);
        state.set_timelapse_frames(3);
        state.set_timelapse_duration(120);
        let timelapse = state.timelapse().unwrap();
        assert_eq!(timelapse.frames(), 3);
        assert_eq!(
            timelapse.time_of(3).to_rfc3339(),
            "2013-05-27T13:45:00-04:00"
        );
        state.set_timelapse_frames(0);
        assert_eq!(state.export.timelapse.frames, 1);
        state.set_timelapse_frames(3);
        state.set_timelapse_duration(0);
        assert!(state.timelapse().unwrap_err().contains("span"));
        state.set_timelapse_duration(u32::MAX);
        assert_eq!(state.export.timelapse.duration_min, MAX_TIMELAPSE_MINUTES);
        for name in ["sky.exr", "out/sky_##.exr"] {
            state.export.timelapse.file_name = name.into();
            assert!(state.timelapse().is_err(), "{name}");
        }
        assert!(!state.timelapse_enabled());
        state.export.timelapse.enabled = true;
        assert!(state.timelapse_enabled());
        state.set_sun_mode(SunMode::Manual);
        assert!(!state.timelapse_enabled());
    }

    #[test]
    fn tone_curves() {
        for curve in ToneCurve::ALL {
            assert_eq!(curve.map([f32::NAN, 1.0, 1.0], 1.0), [0; 3]);
            assert_eq!(curve.map([0.0; 3], 1.0), [0; 3]);
            let bright = curve.map([100.0; 3], 1.0);
            assert!(bright.iter().all(|&c| c >= 250), "{curve:?} {bright:?}");
        }
        assert_eq!(ToneCurve::Clip.map([0.5; 3], 1.0), [188; 3]);
    }
}
