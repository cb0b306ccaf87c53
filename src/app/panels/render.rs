//! The Render section: the preview's resolution and target sample count,
//! and pausing.

use egui::Slider;

use crate::app::state::{AppState, MAX_TARGET_SPP, PREVIEW_SCALE_RANGE};

/// The Render section.
pub struct RenderPanel<'a> {
    /// The state whose render settings it sets.
    pub state: &'a mut AppState,
}

impl RenderPanel<'_> {
    /// Draw the section.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Render")
            .default_open(true)
            .show(ui, |ui| {
                let render = self.state.render().clone();
                let mut scale = render.preview_scale;
                let (lo, hi) = PREVIEW_SCALE_RANGE;
                let (w, h) = self.state.preview_size();
                if ui
                    .add(
                        Slider::new(&mut scale, lo..=hi)
                            .text("Preview scale")
                            .suffix("×")
                            .custom_formatter(|v, _| format!("{v:.2}")),
                    )
                    .on_hover_text(format!(
                        "Preview resolution relative to 320×160 (now {w}×{h} px); lower is faster"
                    ))
                    .changed()
                {
                    self.state.set_preview_scale(scale);
                }
                let mut spp = render.target_spp;
                if ui
                    .add(
                        Slider::new(&mut spp, 1..=MAX_TARGET_SPP)
                            .logarithmic(true)
                            .text("Target spp"),
                    )
                    .on_hover_text("Samples per pixel after which the preview stops refining")
                    .changed()
                {
                    self.state.set_target_spp(spp);
                }
                let label = if render.paused { "Resume" } else { "Pause" };
                if ui
                    .button(label)
                    .on_hover_text("Pause or resume refining (the image is kept)")
                    .clicked()
                {
                    self.state.set_paused(!render.paused);
                }
            });
    }
}
