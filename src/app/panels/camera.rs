//! The Camera section: the projection (fisheye, equirectangular,
//! perspective) and its field of view and direction.

use super::slider;
use crate::app::state::{AppState, FISHEYE_FOV_RANGE, PERSPECTIVE_FOV_RANGE};
use crate::scene::CameraKind;

/// The camera mode buttons: mode, label, tooltip.
const CAMERA_MODES: [(CameraKind, &str, &str); 3] = [
    (
        CameraKind::Fisheye,
        "Fisheye",
        "All-sky view looking straight up, north at the top",
    ),
    (
        CameraKind::Equirect,
        "Equirect",
        "Whole sphere as a 2:1 latitude–longitude map, north in the middle",
    ),
    (
        CameraKind::Perspective,
        "Perspective",
        "Ordinary camera; drag the view or use the arrow keys to look around",
    ),
];

/// The Camera section.
pub struct CameraPanel<'a> {
    /// The state whose camera it sets.
    pub state: &'a mut AppState,
}

impl CameraPanel<'_> {
    /// Draw the section.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Camera")
            .default_open(true)
            .show(ui, |ui| {
                let camera = self.state.scene().camera.clone();
                ui.horizontal(|ui| {
                    for (kind, label, tip) in CAMERA_MODES {
                        if ui
                            .selectable_label(camera.kind == kind, label)
                            .on_hover_text(tip)
                            .clicked()
                        {
                            self.state.set_camera_kind(kind);
                        }
                    }
                });
                match camera.kind {
                    CameraKind::Perspective => {
                        if let Some(v) = slider(
                            ui,
                            camera.fov_deg,
                            PERSPECTIVE_FOV_RANGE,
                            "Field of view",
                            "°",
                            "Horizontal field of view, degrees",
                        ) {
                            self.state.set_fov(v);
                        }
                        if let Some(v) = slider(
                            ui,
                            camera.yaw_deg,
                            (-180.0, 180.0),
                            "Yaw",
                            "°",
                            "View direction, degrees clockwise from north",
                        ) {
                            self.state.set_view(v, camera.pitch_deg);
                        }
                        if let Some(v) = slider(
                            ui,
                            camera.pitch_deg,
                            (-90.0, 90.0),
                            "Pitch",
                            "°",
                            "View elevation above the horizon, degrees",
                        ) {
                            self.state.set_view(camera.yaw_deg, v);
                        }
                        ui.weak("Drag the view or use the arrow keys to look around.");
                    }
                    CameraKind::Fisheye => {
                        if let Some(v) = slider(
                            ui,
                            camera.fov_deg,
                            FISHEYE_FOV_RANGE,
                            "Field of view",
                            "°",
                            "Full field of view of the fisheye circle, degrees \
                     (180 = down to the horizon)",
                        ) {
                            self.state.set_fov(v);
                        }
                        if let Some(v) = slider(
                            ui,
                            camera.yaw_deg,
                            (-180.0, 180.0),
                            "Rotation",
                            "°",
                            "Turns the all-sky image, degrees",
                        ) {
                            self.state.set_view(v, camera.pitch_deg);
                        }
                    }
                    CameraKind::Equirect => {
                        ui.weak("The map is geographic: north in the middle, east to the right.");
                    }
                }
            });
    }
}
