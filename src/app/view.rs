//! The central sky image: the latest frame scaled to fit, a ring where the
//! Sun is, and dragging or the arrow keys to turn the view.

use egui::{Color32, Sense};

use super::state::AppState;
use crate::render::service::Frame;
use crate::render::{direction_from_az_el, Camera};
use crate::scene::{CameraKind, Scene};

/// Radius of the ring marking the sun, points.
const SUN_RING_RADIUS: f32 = 12.0;
/// Arrow-key step of the view direction, degrees (shift: a fifth of it).
const ARROW_STEP_DEG: f64 = 5.0;

/// The sky view: what it shows and the state its input turns.
pub struct SkyView<'a> {
    /// Turned by dragging and the arrow keys; its display settings say
    /// whether to mark the sun.
    pub state: &'a mut AppState,
    /// The frame on screen and its texture; `None` before the first.
    pub image: Option<(&'a egui::TextureHandle, &'a Frame)>,
    /// The preview scene `image` was rendered from (where its sun is).
    pub frame_scene: &'a Scene,
}

impl SkyView<'_> {
    /// Draw the view into `ui` (all of its space) and apply its input.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        let available = ui.available_rect_before_wrap();
        let Some((texture, frame)) = self.image else {
            ui.centered_and_justified(|ui| {
                ui.horizontal_centered(|ui| {
                    ui.spinner();
                    ui.label("rendering the first pass…");
                });
            });
            return;
        };
        let (w, h) = (frame.image.width as f32, frame.image.height as f32);
        let scale = (available.width() / w).min(available.height() / h).max(0.0);
        let rect =
            egui::Rect::from_center_size(available.center(), egui::vec2(w * scale, h * scale));
        let response = ui.allocate_rect(rect, Sense::click_and_drag());
        response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, "Sky view"));
        let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        ui.painter().image(texture.id(), rect, uv, Color32::WHITE);

        if self.state.display.mark_sun {
            let scene = self.frame_scene;
            let camera = Camera::new(&scene.camera, scene.render.width, scene.render.height);
            let sun = direction_from_az_el(scene.sun.azimuth_deg, scene.sun.elevation_deg);
            if let Some((px, py)) = camera.project(sun) {
                let centre = rect.min
                    + egui::vec2(px as f32 / w * rect.width(), py as f32 / h * rect.height());
                // The equirectangular map wraps around: a sun on its edge
                // shows on both sides.
                let copies: &[f32] = if scene.camera.kind == CameraKind::Equirect {
                    &[-1.0, 0.0, 1.0]
                } else {
                    &[0.0]
                };
                let painter = ui.painter().with_clip_rect(rect);
                for shift in copies {
                    let c = centre + egui::vec2(shift * rect.width(), 0.0);
                    if rect.expand(SUN_RING_RADIUS).contains(c) {
                        // A dark ring around a light one reads on any background.
                        let dark = egui::Stroke::new(3.0, Color32::from_black_alpha(160));
                        let light = egui::Stroke::new(1.5, Color32::from_rgb(255, 220, 90));
                        painter.circle_stroke(c, SUN_RING_RADIUS, dark);
                        painter.circle_stroke(c, SUN_RING_RADIUS, light);
                    }
                }
            }
        }

        let kind = self.state.scene().camera.kind;
        if response.dragged() && kind != CameraKind::Equirect {
            let delta = response.drag_delta();
            let fov = self.state.scene().camera.fov_deg;
            let per_point = fov / f64::from(rect.width().max(1.0));
            match kind {
                CameraKind::Perspective => {
                    self.state.rotate_view(
                        -f64::from(delta.x) * per_point,
                        f64::from(delta.y) * per_point,
                    );
                }
                _ => self.state.rotate_view(f64::from(delta.x) * per_point, 0.0),
            }
        }
        let nothing_focused = ui.memory(|m| m.focused().is_none());
        if nothing_focused && kind != CameraKind::Equirect {
            let (d_yaw, d_pitch) = ui.input(|i| {
                let step = if i.modifiers.shift {
                    ARROW_STEP_DEG / 5.0
                } else {
                    ARROW_STEP_DEG
                };
                let key = |k| if i.key_pressed(k) { step } else { 0.0 };
                (
                    key(egui::Key::ArrowRight) - key(egui::Key::ArrowLeft),
                    key(egui::Key::ArrowUp) - key(egui::Key::ArrowDown),
                )
            });
            if d_yaw != 0.0 || d_pitch != 0.0 {
                let d_pitch = if kind == CameraKind::Perspective {
                    d_pitch
                } else {
                    0.0
                };
                self.state.rotate_view(d_yaw, d_pitch);
            }
        }
    }
}
