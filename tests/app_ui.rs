//! UI tests of the preview app, headless, with `egui_kittest` driving
//! [`SkyApp::show`]: controls change the scene and restart accumulation,
//! the export writes the same EXR as the CLI, errors are shown and leave no
//! file behind. Tiny preview sizes and sample counts keep them fast.

mod common;

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use egui::accesskit::Role;
use egui_kittest::kittest::{NodeT as _, Queryable as _};
use egui_kittest::Harness;
use exr::prelude::{AttributeValue, Text};
use skyrender::app::{AppState, ExportStatus, SequenceStatus, SkyApp, SunMode};
use skyrender::scene::{CameraKind, Scene};

/// An app on `preset` with an 80×40 preview refining to 2 spp and a 64×32, 2 spp export.
fn tiny_app(preset: &str) -> SkyApp {
    let mut state = AppState::new(Scene::preset(preset).unwrap());
    state.set_preview_scale(0.25);
    state.set_target_spp(2);
    state.set_export_width(64);
    state.set_export_spp(2);
    SkyApp::with_state(state)
}

fn harness(app: SkyApp) -> Harness<'static, SkyApp> {
    Harness::builder()
        .with_size(egui::vec2(1000.0, 1100.0))
        .build_ui_state(|ui, app: &mut SkyApp| app.show(ui), app)
}

/// Step the UI until `done` holds (rendering and saving run on other threads).
fn step_until(harness: &mut Harness<'_, SkyApp>, what: &str, done: impl Fn(&SkyApp) -> bool) {
    let start = Instant::now();
    while !done(harness.state()) {
        assert!(
            start.elapsed() < Duration::from_mins(2),
            "timed out waiting for {what}"
        );
        harness.step();
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Wait for a frame of the service's current epoch to be on screen.
fn wait_for_current_frame(harness: &mut Harness<'_, SkyApp>) {
    step_until(harness, "a frame of the current scene", |app| {
        !app.state().is_dirty() && app.frame().is_some_and(|f| f.epoch == app.service_epoch())
    });
}

/// Assert that `change` restarts accumulation: the epoch grows at once and
/// the next frame on screen belongs to it, starting again from few samples.
fn assert_restarts(
    harness: &mut Harness<'_, SkyApp>,
    what: &str,
    change: impl FnOnce(&mut Harness<'_, SkyApp>),
) {
    wait_for_current_frame(harness);
    let before = harness.state().service_epoch();
    change(harness);
    harness.run_steps(2);
    let after = harness.state().service_epoch();
    assert!(after > before, "{what}: epoch {before} -> {after}");
    wait_for_current_frame(harness);
    let frame = harness.state().frame().unwrap();
    assert!(
        frame.epoch >= after,
        "{what}: frame of epoch {} shown",
        frame.epoch
    );
}

#[test]
fn sun_slider_changes_the_scene_and_restarts_accumulation() {
    let mut harness = harness(tiny_app("midday"));
    assert_restarts(&mut harness, "sun elevation", |h| {
        h.get_by_role_and_label(Role::Slider, "Elevation")
            .set_value_accesskit(10.0);
    });
    assert_eq!(harness.state().state().scene().sun.elevation_deg, 10.0);
    assert_restarts(&mut harness, "sun azimuth", |h| {
        h.get_by_role_and_label(Role::Slider, "Azimuth")
            .set_value_accesskit(90.0);
    });
    assert_eq!(harness.state().state().scene().sun.azimuth_deg, 90.0);
    // The frame on screen was rendered for the new sun.
    let frame = harness.state().frame().unwrap();
    assert_eq!(frame.image.width, 80);
    assert!(frame.spp <= 2);
}

#[test]
fn toggling_aerosols_and_ozone_restarts_accumulation() {
    let mut harness = harness(tiny_app("midday"));
    assert_restarts(&mut harness, "aerosols off", |h| {
        h.get_by_label("Aerosols").click_accesskit();
    });
    assert!(!harness.state().state().scene().atmosphere.aerosols);
    assert_restarts(&mut harness, "ozone off", |h| {
        h.get_by_label("Ozone").click_accesskit();
    });
    assert!(!harness.state().state().scene().atmosphere.ozone);
    assert_restarts(&mut harness, "ozone on", |h| {
        h.get_by_label("Ozone").click_accesskit();
    });
    assert!(harness.state().state().scene().atmosphere.ozone);
    assert_restarts(&mut harness, "altitude quick button", |h| {
        h.get_by_label("Orbit 400 km").click_accesskit();
    });
    assert_eq!(
        harness.state().state().scene().observer.altitude_m,
        400_000.0
    );
}

#[test]
fn choosing_a_ground_spectrum_restarts_accumulation() {
    let mut harness = harness(tiny_app("midday"));
    assert_restarts(&mut harness, "snow ground", |h| {
        // The ground's menu: the combo box whose value is the albedo's.
        h.get_by(|node| {
            node.role() == Role::ComboBox && node.value().as_deref() == Some("uniform")
        })
        .click_accesskit();
        h.run_steps(2);
        h.get_by_label("snow").click_accesskit();
    });
    let atmosphere = &harness.state().state().scene().atmosphere;
    assert_eq!(atmosphere.ground_albedo_spectrum.as_deref(), Some("snow"));
    // The slider returns to one albedo at every wavelength.
    assert_restarts(&mut harness, "albedo slider", |h| {
        h.get_by_role_and_label(Role::Slider, "Ground albedo")
            .set_value_accesskit(0.5);
    });
    let atmosphere = &harness.state().state().scene().atmosphere;
    assert_eq!(atmosphere.ground_albedo_spectrum, None);
    assert_eq!(atmosphere.ground_albedo, 0.5);
}

#[test]
fn switching_camera_mode_restarts_and_arrow_keys_turn_the_view() {
    let mut harness = harness(tiny_app("midday"));
    assert_restarts(&mut harness, "fisheye", |h| {
        h.get_by_label("Fisheye").click_accesskit();
    });
    let frame = harness.state().frame().unwrap();
    assert_eq!(
        frame.image.width, frame.image.height,
        "the fisheye preview is square"
    );
    assert_restarts(&mut harness, "perspective", |h| {
        h.get_by_label("Perspective").click_accesskit();
    });
    let scene = harness.state().state().scene().clone();
    assert_eq!(scene.camera.kind, CameraKind::Perspective);
    assert_restarts(&mut harness, "arrow key", |h| {
        h.key_press(egui::Key::ArrowRight);
    });
    let camera = &harness.state().state().scene().camera;
    assert_eq!(camera.yaw_deg, scene.camera.yaw_deg + 5.0);
    assert_restarts(&mut harness, "preset button", |h| {
        h.get_by_label("sunset").click_accesskit();
    });
    assert_eq!(
        harness.state().state().scene(),
        &Scene::preset("sunset").unwrap()
    );
}

#[test]
fn export_writes_the_same_exr_as_the_cli() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pano.exr");
    let mut harness = harness(tiny_app("sunset"));
    harness.state_mut().start_export(path.clone());
    step_until(&mut harness, "the export", |app| {
        !app.state().export_status.is_running()
    });
    let status = harness.state().state().export_status.clone();
    assert!(
        matches!(&status, ExportStatus::Finished { path: p, .. } if *p == path),
        "{status:?}"
    );
    assert_eq!(harness.state().state().last_error, None);

    let meta = exr::meta::MetaData::read_from_file(&path, false).unwrap();
    let header = &meta.headers[0];
    assert_eq!((header.layer_size.0, header.layer_size.1), (64, 32));
    assert_eq!(scene_in(&path), harness.state().state().export_scene());

    // `skyrender render --preset sunset --camera equirect --width 64 --height 32 --spp 2`.
    let args = skyrender::cli::SceneArgs {
        preset: Some("sunset".into()),
        camera: Some("equirect".into()),
        width: Some(64),
        height: Some(32),
        spp: Some(2),
        ..Default::default()
    };
    let cli_path = dir.path().join("cli.exr");
    skyrender::export::render_to_file(
        &args.build().unwrap(),
        &cli_path,
        &AtomicBool::new(false),
        |_, _| {},
    )
    .unwrap();
    // Same header attributes (in any order: they are a hash map) and pixels.
    let app_exr = exr::prelude::read_all_flat_layers_from_file(&path).unwrap();
    let cli_exr = exr::prelude::read_all_flat_layers_from_file(&cli_path).unwrap();
    assert!(app_exr == cli_exr, "app and CLI files differ");
}

/// The scene an EXR was rendered from (its `skyrender:scene` header).
fn scene_in(path: &Path) -> Scene {
    let meta = exr::meta::MetaData::read_from_file(path, false).unwrap();
    let header = &meta.headers[0];
    let attribute = header
        .own_attributes
        .other
        .get(&Text::from("skyrender:scene"))
        .or_else(|| {
            header
                .shared_attributes
                .other
                .get(&Text::from("skyrender:scene"))
        })
        .expect("skyrender:scene attribute");
    let AttributeValue::Text(text) = attribute else {
        panic!("not text: {attribute:?}")
    };
    Scene::from_toml(std::str::from_utf8(text.bytes()).unwrap()).unwrap()
}

/// Files in `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn invalid_export_paths_show_an_error_and_leave_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(tiny_app("midday"));
    for (path, expect) in [
        (dir.path().join("missing").join("pano.exr"), "cannot write"),
        (dir.path().join("pano.png"), ".exr"),
        (dir.path().join("pano"), "extension"),
        (dir.path().to_path_buf(), ""),
    ] {
        harness.state_mut().state_mut().last_error = None;
        harness.state_mut().start_export(path.clone());
        step_until(&mut harness, "the export to fail", |app| {
            !app.state().export_status.is_running()
        });
        let state = harness.state().state();
        let ExportStatus::Failed(message) = &state.export_status else {
            panic!("{}: {:?}", path.display(), state.export_status)
        };
        assert!(message.contains(expect), "{message}");
        assert_eq!(state.last_error.as_deref(), Some(message.as_str()));
        // The error is on screen.
        harness.run_steps(2);
        let _ = harness.get_by_label_contains("Export failed");
    }
    assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
}

#[test]
fn cancelled_export_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("pano.exr");
    let mut app = tiny_app("midday");
    app.state_mut().set_export_width(512);
    app.state_mut().set_export_spp(4096);
    let mut harness = harness(app);
    harness.state_mut().start_export(path.clone());
    harness.run_steps(2);
    harness.get_by_label("Cancel").click_accesskit();
    step_until(&mut harness, "the export to stop", |app| {
        !app.state().export_status.is_running()
    });
    assert_eq!(
        harness.state().state().export_status,
        ExportStatus::Cancelled { sequence: None }
    );
    assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));
}

#[test]
fn view_and_scene_files_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(tiny_app("twilight"));
    wait_for_current_frame(&mut harness);
    for name in ["view.png", "view.exr", "scene.toml"] {
        let path = dir.path().join(name);
        if name.ends_with("toml") {
            harness.state_mut().save_scene_to(path);
        } else {
            harness.state_mut().save_view_to(path);
        }
    }
    step_until(&mut harness, "the saves", |app| !app.busy());
    assert_eq!(harness.state().state().last_error, None);
    assert_eq!(entries(dir.path()), ["scene.toml", "view.exr", "view.png"]);
    let png = image::open(dir.path().join("view.png")).unwrap();
    assert_eq!((png.width(), png.height()), (80, 40));
    exr::meta::MetaData::read_from_file(dir.path().join("view.exr"), false).unwrap();

    harness.state_mut().state_mut().load_preset("midday");
    wait_for_current_frame(&mut harness);
    harness
        .state_mut()
        .load_scene_from(dir.path().join("scene.toml"));
    step_until(&mut harness, "the load", |app| !app.busy());
    assert_eq!(
        harness.state().state().scene(),
        &Scene::preset("twilight").unwrap()
    );
    harness
        .state_mut()
        .load_scene_from(dir.path().join("nothing.toml"));
    step_until(&mut harness, "the failed load", |app| !app.busy());
    assert!(harness.state().state().last_error.is_some());
    assert_eq!(
        harness.state().state().scene(),
        &Scene::preset("twilight").unwrap()
    );
}

/// Time from a slider change to the first frame of the new scene on screen
/// at the default preview size (320×160), as the app measures it. Run alone
/// for a clean figure: `cargo test --release --test app_ui latency -- --nocapture`.
#[test]
fn slider_change_latency_at_the_default_preview_size() {
    let mut harness = harness(SkyApp::new(Scene::preset("midday").unwrap()));
    wait_for_current_frame(&mut harness);
    let (mut first, mut full) = (Vec::new(), Vec::new());
    for i in 0..8 {
        harness
            .state_mut()
            .state_mut()
            .set_sun_elevation(20.0 + f64::from(i));
        harness.step();
        let measured = harness.state().full_latency().count;
        step_until(&mut harness, "the new full-size frame", |app| {
            app.full_latency().count > measured
        });
        first.push(harness.state().latency().last.unwrap());
        full.push(harness.state().full_latency().last.unwrap());
    }
    let ms = |d: Duration| d.as_secs_f64() * 1e3;
    for (what, latencies) in [("first frame", &mut first), ("full-size frame", &mut full)] {
        latencies.sort();
        eprintln!(
            "slider change -> {what} at 320x160: median {:.0} ms, min {:.0} ms, max {:.0} ms",
            ms(latencies[latencies.len() / 2]),
            ms(latencies[0]),
            ms(latencies[latencies.len() - 1]),
        );
    }
    // A regression guard, not the benchmark (`skyrender bench` measures the
    // first frame: 37–58 ms in release): run alone in the test profile the
    // medians read 45 ms (first frame) and 114 ms (full size); the bounds
    // leave room for the other tests sharing CI's two cores.
    assert!(first[first.len() / 2] < Duration::from_secs(1));
    assert!(full[full.len() / 2] < Duration::from_secs(2));
}

#[test]
fn showing_the_controls_leaves_the_scene_alone() {
    let mut scene = Scene::preset("midday").unwrap();
    scene.sun.elevation_deg = 12.345_678;
    scene.sun.azimuth_deg = 123.456_789;
    scene.observer.altitude_m = 1_234.5;
    scene.atmosphere.ground_albedo = 0.123_456;
    let mut state = AppState::new(scene.clone());
    state.set_preview_scale(0.25);
    state.set_target_spp(2);
    let mut harness = harness(SkyApp::with_state(state));
    wait_for_current_frame(&mut harness);
    let epoch = harness.state().service_epoch();
    harness.run_steps(10);
    assert_eq!(harness.state().state().scene(), &scene);
    assert_eq!(
        harness.state().service_epoch(),
        epoch,
        "no restart without input"
    );
}

#[test]
fn run_app_explains_itself_without_a_display() {
    let err = skyrender::app::run_app(Some("noon"), None, None, 5.0).unwrap_err();
    assert!(err.contains("midday"), "{err}");
    let no_display = ["DISPLAY", "WAYLAND_DISPLAY"]
        .iter()
        .all(|v| std::env::var_os(v).is_none_or(|s| s.is_empty()));
    if no_display {
        let err = skyrender::app::run_app(None, None, None, 5.0).unwrap_err();
        assert_eq!(err, skyrender::app::NO_DISPLAY_MESSAGE);
        assert!(!err.contains('\n') && err.contains("skyrender render"));
    }
}

/// The whole window, rendered by wgpu (lavapipe where there is no GPU):
/// every control group with its units (Display, closed at first, opened).
/// The sky image (whose noise changes with any change to the renderer) and
/// the status bar (timings) are masked; the exposure is fixed so no value on
/// screen depends on the render.
#[test]
fn window_snapshot() {
    let mut app = tiny_app("sunset");
    app.state_mut().display.auto_exposure = false;
    app.state_mut().display.exposure_ev = -10.0;
    let mut harness = Harness::builder()
        .with_size(egui::vec2(960.0, 1000.0))
        .build_ui_state(|ui, app: &mut SkyApp| app.show(ui), app);
    step_until(&mut harness, "the finished frame", |app| {
        app.frame()
            .is_some_and(|f| f.finished && f.epoch == app.service_epoch())
    });
    harness.get_by_label("Display").click_accesskit();
    harness.run_steps(3);
    let view = harness.get_by_label("Sky view").rect();
    harness.mask(view);
    let status = harness.get_by_label_contains(" / 2 spp").rect();
    harness.mask(egui::Rect::from_x_y_ranges(
        0.0..=960.0,
        (status.top() - 4.0)..=1000.0,
    ));
    harness.snapshot("app_window");
}

/// The export and save buttons are in view at the window's default size,
/// without scrolling, even with the camera mode that has the most controls.
#[test]
fn export_buttons_are_in_view_at_the_default_window_size() {
    let [width, height] = skyrender::app::WINDOW_SIZE;
    for kind in [CameraKind::Equirect, CameraKind::Perspective] {
        let mut app = tiny_app("midday");
        app.state_mut().set_camera_kind(kind);
        let mut harness = Harness::builder()
            .with_size(egui::vec2(width, height))
            .build_ui_state(|ui, app: &mut SkyApp| app.show(ui), app);
        wait_for_current_frame(&mut harness);
        harness.run_steps(2);
        // The status bar holds the preview size; the side panel ends above it.
        let (w, h) = harness.state().state().preview_size();
        let status_top = harness.get_by_label(&format!("{w}×{h} px")).rect().top();
        let heading = harness.get_by_label("skyrender").rect();
        for label in ["Export HDR panorama…", "Save view as PNG/EXR…"] {
            let rect = harness.get_by_label(label).rect();
            assert!(
                rect.top() >= heading.bottom()
                    && rect.bottom() <= status_top
                    && rect.right() <= width,
                "{kind:?}: '{label}' at {rect:?}, panel from {} to {status_top}",
                heading.bottom()
            );
        }
        if kind == CameraKind::Equirect {
            // The default view shows every open section whole, the settings
            // scrolling above the pinned Export section.
            let pause = harness.get_by_label("Pause").rect();
            let export = harness.get_by_label("Export").rect();
            assert!(pause.bottom() <= export.top(), "{pause:?} under {export:?}");
        }
    }
}

/// The status bar's time counts from the scene change, the draft included,
/// and stops with the last pass (the service's own clock starts again at
/// the full-size render).
#[test]
fn render_time_counts_from_the_change_and_stops_when_done() {
    let mut app = tiny_app("midday");
    app.state_mut().set_preview_scale(1.0);
    let mut harness = harness(app);
    step_until(&mut harness, "the finished frame", |app| {
        app.frame()
            .is_some_and(|f| f.finished && f.epoch == app.service_epoch())
    });
    harness.run_steps(2);
    let app = harness.state();
    let time = app.render_time();
    let frame = app.frame().unwrap();
    assert!(time >= frame.elapsed, "{time:?} < {:?}", frame.elapsed);
    let shown = format!("{:.1} s", time.as_secs_f64());
    let _ = harness.get_by_label(&shown);
    std::thread::sleep(Duration::from_millis(200));
    harness.run_steps(2);
    assert_eq!(harness.state().render_time(), time, "the clock stopped");
}

/// Switch the Sun panel to date mode and pick Ithaca, NY (UTC−5 at first).
fn date_mode_at_ithaca(harness: &mut Harness<'_, SkyApp>) {
    assert_restarts(harness, "date mode", |h| {
        h.get_by_label("Date, time, place").click_accesskit();
    });
    assert_eq!(harness.state().state().sun_mode(), SunMode::DatePlace);
    harness.get_by_label("Ithaca NY").click_accesskit();
    harness.run_steps(2);
}

/// Ithaca, NY, 2013-05-27 11:45 at UTC−4: SPA puts the Sun at 63.35°
/// elevation, 136.08° azimuth (true, unrefracted).
#[test]
fn date_mode_places_the_sun_and_the_time_slider_scrubs_it() {
    let dir = tempfile::tempdir().unwrap();
    let mut harness = harness(tiny_app("midday"));
    date_mode_at_ithaca(&mut harness);
    harness
        .get_by_role_and_label(Role::TextInput, "Date")
        .set_text_value_accesskit("2013-05-27");
    harness.run_steps(2);
    harness
        .get_by_role_and_label(Role::SpinButton, "UTC offset")
        .set_value_accesskit(-4.0);
    harness.run_steps(2);
    assert_restarts(&mut harness, "time slider", |h| {
        h.get_by_role_and_label(Role::Slider, "Time")
            .set_value_accesskit(11.0 * 60.0 + 45.0);
    });
    let state = harness.state().state();
    assert_eq!(state.date_place_error(), None);
    let sun = state.scene().sun.clone();
    assert_eq!(sun.date_time.as_deref(), Some("2013-05-27T11:45:00-04:00"));
    assert_eq!(
        (sun.latitude_deg, sun.longitude_deg),
        (Some(42.4434), Some(-76.4816))
    );
    assert!((sun.elevation_deg - 63.35).abs() < 0.01, "{sun:?}");
    assert!((sun.azimuth_deg - 136.08).abs() < 0.01, "{sun:?}");
    // The result is on screen, read-only.
    let _ = harness.get_by_label_contains(&format!("Elevation {:.2}°", sun.elevation_deg));
    let _ = harness.get_by_label_contains("Earth–Sun distance 1.01");
    // The frame on screen was rendered for that Sun.
    assert_eq!(
        harness.state().frame().unwrap().epoch,
        harness.state().service_epoch()
    );

    // Scrubbing the time moves the Sun and renders again.
    assert_restarts(&mut harness, "scrubbing the time", |h| {
        h.get_by_role_and_label(Role::Slider, "Time")
            .set_value_accesskit(17.0 * 60.0);
    });
    let later = harness.state().state().scene().sun.clone();
    assert!(
        later.elevation_deg < sun.elevation_deg - 20.0 && later.azimuth_deg > 250.0,
        "{later:?}"
    );
    assert_eq!(
        later.date_time.as_deref(),
        Some("2013-05-27T17:00:00-04:00")
    );

    // "Save scene…" writes the date and place; loading it back restores them.
    let toml = dir.path().join("ithaca.toml");
    harness.state_mut().save_scene_to(toml.clone());
    step_until(&mut harness, "the save", |app| !app.busy());
    let saved = Scene::load(&toml).unwrap();
    assert_eq!(&saved, harness.state().state().scene());

    // Back to manual: the Sun stays where it is, the date and place go.
    assert_restarts(&mut harness, "manual mode", |h| {
        h.get_by_label("Elevation/azimuth").click_accesskit();
    });
    let manual = harness.state().state().scene().sun.clone();
    assert_eq!(
        (manual.elevation_deg, manual.azimuth_deg),
        (later.elevation_deg, later.azimuth_deg)
    );
    assert_eq!(
        (manual.date_time, manual.latitude_deg, manual.longitude_deg),
        (None, None, None)
    );
    let _ = harness.get_by_role_and_label(Role::Slider, "Elevation");

    // Loading the saved scene brings date mode back with its inputs.
    harness.state_mut().load_scene_from(toml);
    step_until(&mut harness, "the load", |app| !app.busy());
    assert_eq!(harness.state().state().sun_mode(), SunMode::DatePlace);
    assert_eq!(harness.state().state().date_place().minutes, 17 * 60);
    // Showing the date controls changes nothing by itself.
    wait_for_current_frame(&mut harness);
    let epoch = harness.state().service_epoch();
    harness.run_steps(10);
    assert_eq!(harness.state().state().scene(), &saved);
    assert_eq!(harness.state().service_epoch(), epoch, "no restart");
}

#[test]
fn invalid_date_and_place_are_refused_with_a_message() {
    let mut harness = harness(tiny_app("midday"));
    date_mode_at_ithaca(&mut harness);
    harness
        .get_by_role_and_label(Role::TextInput, "Date")
        .set_text_value_accesskit("2013-06-21");
    harness.run_steps(2);
    wait_for_current_frame(&mut harness);
    let scene = harness.state().state().scene().clone();
    let epoch = harness.state().service_epoch();

    harness
        .get_by_role_and_label(Role::SpinButton, "Latitude")
        .set_value_accesskit(95.0);
    harness.run_steps(3);
    let error = harness
        .state()
        .state()
        .date_place_error()
        .unwrap()
        .to_owned();
    assert!(
        error.contains("latitude") && error.contains("95"),
        "{error}"
    );
    let _ = harness.get_by_label(&error);
    let _ = harness.get_by_label_contains("(last valid)");
    assert_eq!(
        harness.state().state().scene(),
        &scene,
        "the last valid scene"
    );
    assert_eq!(harness.state().service_epoch(), epoch, "no restart");
    assert!(harness.state().state().date_place().latitude_deg == 95.0);

    // A fixed latitude and a date that does not exist.
    harness
        .get_by_role_and_label(Role::SpinButton, "Latitude")
        .set_value_accesskit(42.4434);
    harness
        .get_by_role_and_label(Role::TextInput, "Date")
        .set_text_value_accesskit("2013-02-30");
    harness.run_steps(3);
    let error = harness
        .state()
        .state()
        .date_place_error()
        .unwrap()
        .to_owned();
    assert!(error.contains("invalid date"), "{error}");
    let _ = harness.get_by_label(&error);
    assert_eq!(harness.state().state().scene(), &scene);

    // Valid again: the error goes and the Sun moves to the new date.
    harness
        .get_by_role_and_label(Role::TextInput, "Date")
        .set_text_value_accesskit("2013-12-21");
    harness.run_steps(3);
    assert_eq!(harness.state().state().date_place_error(), None);
    let sun = &harness.state().state().scene().sun;
    assert!(
        sun.elevation_deg < scene.sun.elevation_deg - 10.0,
        "{sun:?}"
    );
    assert!(harness.query_by_label_contains("invalid").is_none());
}

#[test]
fn timelapse_export_writes_numbered_frames_and_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let mut app = tiny_app("midday");
    app.state_mut().set_export_width(16);
    app.state_mut().set_export_spp(1);
    let mut harness = harness(app);
    harness.run_steps(2);
    assert!(
        harness.query_by_label("Timelapse").is_none(),
        "a timelapse needs a date"
    );
    date_mode_at_ithaca(&mut harness);
    harness.get_by_label("Timelapse").click_accesskit();
    harness.run_steps(2);
    harness
        .get_by_role_and_label(Role::SpinButton, "Frames")
        .set_value_accesskit(3.0);
    harness
        .get_by_role_and_label(Role::SpinButton, "Duration")
        .set_value_accesskit(120.0);
    harness.run_steps(2);
    let _ = harness.get_by_label("Export timelapse…");
    let settings = harness.state().state().export.timelapse.clone();
    assert_eq!((settings.frames, settings.duration_min), (3, 120));
    let start = harness.state().state().date_place().date_time().unwrap();

    let pattern = dir.path().join(&settings.file_name);
    harness.state_mut().start_timelapse(pattern.clone());
    let ExportStatus::Running { total, .. } = harness.state().state().export_status else {
        panic!("{:?}", harness.state().state().export_status)
    };
    assert_eq!(total, 3, "one progress bar for frames × spp");
    step_until(&mut harness, "the timelapse", |app| {
        !app.state().export_status.is_running()
    });
    let status = harness.state().state().export_status.clone();
    let done = SequenceStatus {
        frame: 3,
        frames: 3,
        written: 3,
        skipped: 0,
    };
    assert!(
        matches!(&status, ExportStatus::Finished { path, sequence: Some(s), .. }
            if *path == pattern && *s == done),
        "{status:?}"
    );
    let frames = ["sky_0001.exr", "sky_0002.exr", "sky_0003.exr"];
    assert_eq!(entries(dir.path()), frames);
    // Each frame has its own time, an hour apart, and its own Sun.
    let scenes: Vec<_> = frames
        .iter()
        .map(|f| scene_in(&dir.path().join(f)))
        .collect();
    assert_eq!(scenes[0].sun.date_time.as_deref(), Some(start.as_str()));
    let two_hours_on = harness.state().state().date_place().date_time_after(120);
    assert_eq!(scenes[2].sun.date_time, Some(two_hours_on.unwrap()));
    assert!(scenes[0].sun.elevation_deg != scenes[1].sun.elevation_deg);
    assert_eq!(
        (
            scenes[0].render.width,
            scenes[0].render.height,
            scenes[0].render.spp
        ),
        (16, 8, 1)
    );

    // Resume: only the missing frame is rendered; the others are left alone.
    std::fs::remove_file(dir.path().join(frames[1])).unwrap();
    let modified = |f: &str| {
        std::fs::metadata(dir.path().join(f))
            .unwrap()
            .modified()
            .unwrap()
    };
    let (first, third) = (modified(frames[0]), modified(frames[2]));
    harness
        .get_by_label("Skip frames whose file exists")
        .click_accesskit();
    harness.run_steps(2);
    harness.state_mut().start_timelapse(pattern.clone());
    step_until(&mut harness, "the resumed timelapse", |app| {
        !app.state().export_status.is_running()
    });
    let status = harness.state().state().export_status.clone();
    assert!(
        matches!(&status, ExportStatus::Finished { sequence: Some(s), .. }
            if s.written == 1 && s.skipped == 2),
        "{status:?}"
    );
    assert_eq!(entries(dir.path()), frames);
    assert_eq!((modified(frames[0]), modified(frames[2])), (first, third));
    assert_eq!(scene_in(&dir.path().join(frames[1])), scenes[1]);
    harness.run_steps(2);
    let _ = harness.get_by_label_contains("1 frame written, 2 skipped");

    // A name without # is refused before anything is rendered.
    harness.state_mut().state_mut().export.timelapse.file_name = "sky.exr".into();
    harness
        .state_mut()
        .start_timelapse(dir.path().join("sky.exr"));
    let ExportStatus::Failed(message) = &harness.state().state().export_status else {
        panic!("{:?}", harness.state().state().export_status)
    };
    assert!(message.contains('#'), "{message}");
    assert_eq!(entries(dir.path()), frames);
}

/// The middle of the sky view, a quarter of the way down: 45° up in the
/// equirectangular view.
fn sky_point(harness: &Harness<'_, SkyApp>) -> egui::Pos2 {
    let view = harness.get_by_label("Sky view").rect();
    egui::pos2(view.center().x, view.top() + 0.25 * view.height())
}

/// The text a label shows.
fn text_of(node: &egui_kittest::Node<'_>) -> String {
    node.accesskit_node()
        .label()
        .or_else(|| node.value())
        .unwrap_or_default()
}

#[test]
fn hovering_the_view_reads_out_direction_luminance_and_colour() {
    let mut harness = harness(tiny_app("midday"));
    wait_for_current_frame(&mut harness);
    harness.run_steps(2);
    assert!(harness.query_by_label_contains("cd/m²").is_none());
    let at = sky_point(&harness);
    harness.hover_at(at);
    harness.run_steps(2);
    let luminance = text_of(&harness.get_by_label_contains("cd/m²"));
    assert!(luminance.starts_with("luminance "), "{luminance}");
    let direction = text_of(&harness.get_by_label_contains("°, elevation"));
    // "azimuth A°, elevation E°"
    let numbers: Vec<f64> = direction
        .split(|c: char| !(c.is_ascii_digit() || c == '.' || c == '-'))
        .filter_map(|t| t.parse().ok())
        .collect();
    assert_eq!(numbers.len(), 2, "{direction}");
    assert!(
        (numbers[1] - 45.0).abs() < 3.0,
        "{direction}: a quarter down the panorama is 45° up"
    );
    harness.get_by_label_contains("CIE 1931 x 0.");
    harness.get_by_label_contains("RGB (linear Rec.709)");

    // Outside a fisheye's circle there is no sky, and no readout.
    harness
        .state_mut()
        .state_mut()
        .set_camera_kind(CameraKind::Fisheye);
    wait_for_current_frame(&mut harness);
    harness.run_steps(2);
    let view = harness.get_by_label("Sky view").rect();
    harness.hover_at(view.left_top() + egui::vec2(2.0, 2.0));
    harness.run_steps(2);
    assert!(harness.query_by_label_contains("cd/m²").is_none());
    harness.hover_at(view.center());
    harness.run_steps(2);
    harness.get_by_label_contains("cd/m²");
}

#[test]
fn clicking_the_view_plots_the_spectrum_in_the_background() {
    let mut app = tiny_app("midday");
    app.set_probe_samples(8);
    let mut harness = harness(app);
    wait_for_current_frame(&mut harness);
    harness.run_steps(2);
    let at = sky_point(&harness);
    harness.hover_at(at);
    for pressed in [true, false] {
        harness.event(egui::Event::PointerButton {
            pos: at,
            button: egui::PointerButton::Primary,
            pressed,
            modifiers: egui::Modifiers::NONE,
        });
    }
    harness.run_steps(2);
    let probe = harness
        .state()
        .spectrum()
        .expect("the click starts a probe");
    assert!((probe.elevation_deg - 45.0).abs() < 3.0, "{probe:?}");
    step_until(&mut harness, "the spectrum", |app| {
        app.spectrum().is_some_and(|p| p.result.is_some())
    });
    harness.run_steps(2);
    let estimates = harness
        .state()
        .spectrum()
        .unwrap()
        .result
        .clone()
        .unwrap()
        .unwrap();
    assert_eq!(estimates.len(), 48, "360–830 nm every 10 nm");
    assert!(estimates
        .iter()
        .all(|e| e.radiance.is_finite() && e.std_error >= 0.0));
    let title = format!("{} at azimuth", skyrender::app::SPECTRUM_TITLE);
    harness.get_by_label_contains(&title);
    assert!(harness.query_by_label_contains("stale").is_none());

    // A scene change leaves it up, marked stale.
    harness.state_mut().state_mut().set_sun_elevation(20.0);
    harness.run_steps(2);
    harness.get_by_label_contains("stale");
    harness.get_by_label("Close").click_accesskit();
    harness.run_steps(2);
    assert!(harness.query_by_label_contains(&title).is_none());
}

/// Mean absolute difference per channel between two renders inside `rect`.
fn mean_difference(a: &image::RgbaImage, b: &image::RgbaImage, rect: egui::Rect) -> f64 {
    let (mut sum, mut n) = (0.0, 0.0);
    for y in rect.top() as u32..rect.bottom() as u32 {
        for x in rect.left() as u32..rect.right() as u32 {
            let (p, q) = (a.get_pixel(x, y).0, b.get_pixel(x, y).0);
            for k in 0..3 {
                sum += (f64::from(p[k]) - f64::from(q[k])).abs();
                n += 1.0;
            }
        }
    }
    sum / n
}

#[test]
fn false_colour_shows_log_luminance_with_a_colour_bar() {
    let mut harness = harness(tiny_app("midday"));
    step_until(&mut harness, "the finished frame", |app| {
        app.frame()
            .is_some_and(|f| f.finished && f.epoch == app.service_epoch())
    });
    harness.run_steps(2);
    let label = skyrender::app::COLOUR_BAR_LABEL;
    assert!(harness.query_by_label(label).is_none());
    let before = harness.render().unwrap();
    harness.get_by_label("Display").click_accesskit();
    harness.run_steps(2);
    harness
        .get_by_label("False colour (log luminance)")
        .click_accesskit();
    harness.run_steps(3);
    assert!(harness.state().state().display.false_colour);
    harness.get_by_label(label);
    let view = harness.get_by_label("Sky view").rect().shrink(2.0);
    let after = harness.render().unwrap();
    let diff = mean_difference(&before, &after, view);
    assert!(diff > 20.0, "the view barely changed: {diff}");
}

/// A new atmosphere's first frame waits seconds on its sky-model tables;
/// the status bar says so meanwhile, and not once the frame is there.
#[test]
fn a_new_atmosphere_says_it_is_making_its_tables() {
    let notice = "making the sky model's tables for this atmosphere…";
    let mut harness = harness(tiny_app("midday"));
    wait_for_current_frame(&mut harness);
    assert!(harness.query_by_label(notice).is_none());
    let amount = common::fresh_haze(harness.state().state().scene().atmosphere.aerosol_amount);
    harness.state_mut().state_mut().set_aerosol_amount(amount);
    step_until(&mut harness, "the tables' notice", |app| {
        app.making_tables()
    });
    harness.run_steps(2);
    assert!(harness.query_by_label(notice).is_some());
    wait_for_current_frame(&mut harness);
    harness.run_steps(2);
    assert!(harness.query_by_label(notice).is_none());
}
