//! The central sky image: the latest frame scaled to fit, a ring where the
//! Sun is, dragging or the arrow keys to turn the view, a readout of the
//! pixel under the cursor, a click to ask for its spectrum, and the colour
//! bar of the false-colour view.

use egui::{Color32, Sense};

use super::readout::{pixel_readout, viridis, FalseColourScale, PixelReadout};
use super::state::AppState;
use crate::render::service::Frame;
use crate::render::{direction_from_az_el, Camera};
use crate::scene::{CameraKind, Scene};

/// Radius of the ring marking the sun, points.
const SUN_RING_RADIUS: f32 = 12.0;
/// Arrow-key step of the view direction, degrees (shift: a fifth of it).
const ARROW_STEP_DEG: f64 = 5.0;
/// Width kept right of the image for the false-colour bar and its labels, points.
const COLOUR_BAR_SPACE: f32 = 96.0;
/// Width of the false-colour bar itself, points.
const COLOUR_BAR_WIDTH: f32 = 18.0;
/// Quads the false-colour bar is drawn with.
const COLOUR_BAR_STEPS: usize = 64;
/// Accessible name of the false-colour bar.
pub const COLOUR_BAR_LABEL: &str = "Colour bar: luminance, cd/m²";

/// The sky view: what it shows and the state its input turns.
pub struct SkyView<'a> {
    /// Turned by dragging and the arrow keys; its display settings say
    /// whether to mark the sun.
    pub state: &'a mut AppState,
    /// The frame on screen and its texture; `None` before the first.
    pub image: Option<(&'a egui::TextureHandle, &'a Frame)>,
    /// The preview scene `image` was rendered from (where its sun is).
    pub frame_scene: &'a Scene,
    /// The scale of the false-colour image on screen, if it is one.
    pub false_colour: Option<FalseColourScale>,
}

impl SkyView<'_> {
    /// Draw the view into `ui` (all of its space) and apply its input; the
    /// direction clicked (azimuth, elevation, degrees), whose spectrum the
    /// user asks for.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<(f64, f64)> {
        let mut available = ui.available_rect_before_wrap();
        if self.false_colour.is_some() {
            available.max.x = (available.max.x - COLOUR_BAR_SPACE).max(available.min.x);
        }
        let Some((texture, frame)) = self.image else {
            ui.centered_and_justified(|ui| {
                ui.horizontal_centered(|ui| {
                    ui.spinner();
                    ui.label("rendering the first pass…");
                });
            });
            return None;
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

        if let Some(scale) = self.false_colour {
            colour_bar(ui, rect, scale);
        }
        let readout_at = |pos: egui::Pos2| {
            let u = f64::from((pos.x - rect.min.x) / rect.width().max(1.0));
            let v = f64::from((pos.y - rect.min.y) / rect.height().max(1.0));
            pixel_readout(&frame.image, self.frame_scene, u, v)
        };
        if let Some(readout) = response.hover_pos().and_then(readout_at) {
            show_readout(ui, rect, &readout);
        }
        let clicked = response
            .clicked()
            .then(|| response.interact_pointer_pos())
            .flatten()
            .and_then(readout_at)
            .map(|r| (r.azimuth_deg, r.elevation_deg));

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
        clicked
    }
}

/// The readout of the pixel under the cursor, in the view's top-left
/// corner: in a layer of its own that takes no input, so that it never
/// steals the hover it reports.
fn show_readout(ui: &egui::Ui, image: egui::Rect, r: &PixelReadout) {
    let [red, green, blue] = r.rgb;
    let xy = match r.xy {
        Some((x, y)) => format!("x {x:.4}, y {y:.4}"),
        None => "x n/a, y n/a".to_owned(),
    };
    egui::Area::new(egui::Id::unique("sky-view-readout"))
        .order(egui::Order::Foreground)
        .fixed_pos(image.min + egui::vec2(6.0, 6.0))
        .interactable(false)
        .show(ui.ctx(), |ui| {
            egui::Frame::popup(ui.style()).show(ui, |ui| {
                let line = |ui: &mut egui::Ui, text: String| {
                    ui.add(egui::Label::new(text).selectable(false).extend());
                };
                line(
                    ui,
                    format!(
                        "azimuth {:.1}°, elevation {:.1}°",
                        r.azimuth_deg, r.elevation_deg
                    ),
                );
                line(ui, format!("luminance {} cd/m²", sig(r.luminance)));
                line(
                    ui,
                    format!(
                        "RGB (linear Rec.709) {}, {}, {}",
                        sig(red),
                        sig(green),
                        sig(blue)
                    ),
                );
                line(ui, format!("CIE 1931 {xy}"));
            });
        });
}

/// `v` with four significant digits, in scientific notation when large or small.
fn sig(v: f64) -> String {
    if v == 0.0 {
        "0".to_owned()
    } else if (1e-2..1e5).contains(&v.abs()) {
        let decimals = (3 - v.abs().log10().floor() as i32).clamp(0, 5) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.3e}")
    }
}

/// A power of ten as text: plain from 0.001 to 1000, else `1e<k>` (the
/// default fonts have no superscript digits).
fn decade(k: i32) -> String {
    if (-3..=3).contains(&k) {
        let v = 10f64.powi(k);
        let decimals = (-k).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("1e{k}")
    }
}

/// The false-colour bar right of `image`: the colormap bottom (dim) to top
/// (bright), a tick and label at each decade of luminance, the unit on top.
fn colour_bar(ui: &egui::Ui, image: egui::Rect, scale: FalseColourScale) {
    let top = image.min.y + 20.0;
    let bottom = image.max.y - 8.0;
    if bottom - top < 20.0 {
        return;
    }
    let left = image.max.x + 12.0;
    let bar = egui::Rect::from_min_max(
        egui::pos2(left, top),
        egui::pos2(left + COLOUR_BAR_WIDTH, bottom),
    );
    let response = ui.interact(bar, egui::Id::unique("false-colour-bar"), Sense::hover());
    response.widget_info(|| egui::WidgetInfo::labeled(egui::Role::Image, true, COLOUR_BAR_LABEL));
    let painter = ui.painter();
    // One quad per step, shaded top to bottom: the colormap is piecewise
    // linear, so a few dozen steps show it exactly enough.
    let mut mesh = egui::Mesh::default();
    for i in 0..=COLOUR_BAR_STEPS {
        let t = i as f32 / COLOUR_BAR_STEPS as f32;
        let [r, g, b] = viridis(f64::from(t));
        let c = Color32::from_rgb(r, g, b);
        let y = bottom - t * (bottom - top);
        mesh.colored_vertex(egui::pos2(bar.min.x, y), c);
        mesh.colored_vertex(egui::pos2(bar.max.x, y), c);
        if i > 0 {
            let k = 2 * i as u32;
            mesh.add_triangle(k - 2, k - 1, k);
            mesh.add_triangle(k - 1, k + 1, k);
        }
    }
    painter.add(mesh);
    let text = ui.visuals().text_color();
    painter.rect_stroke(
        bar,
        0.0,
        egui::Stroke::new(1.0, text),
        egui::StrokeKind::Outside,
    );
    let font = egui::FontId::proportional(12.0);
    painter.text(
        egui::pos2(bar.min.x, top - 4.0),
        egui::Align2::LEFT_BOTTOM,
        "cd/m²",
        font.clone(),
        text,
    );
    let (lo, hi) = (scale.log_lo as i32, scale.log_hi as i32);
    // At most about one label per 18 points.
    let every = ((hi - lo) as f32 * 18.0 / (bottom - top)).ceil().max(1.0) as i32;
    for k in (lo..=hi).filter(|k| (k - lo) % every == 0) {
        let t = ((f64::from(k) - scale.log_lo) / (scale.log_hi - scale.log_lo)) as f32;
        let y = bottom - t * (bottom - top);
        painter.line_segment(
            [egui::pos2(bar.max.x, y), egui::pos2(bar.max.x + 4.0, y)],
            egui::Stroke::new(1.0, text),
        );
        painter.text(
            egui::pos2(bar.max.x + 7.0, y),
            egui::Align2::LEFT_CENTER,
            decade(k),
            font.clone(),
            text,
        );
    }
}
