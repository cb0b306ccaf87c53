//! The Presets section: the built-in scenes, and saving and loading scene files.

use super::{Dialog, Request};
use crate::app::state::AppState;
use crate::scene::PRESETS;

/// The Presets section.
pub struct PresetsPanel<'a> {
    /// The state a preset replaces the scene of.
    pub state: &'a mut AppState,
    /// Whether a file dialog may be opened (none is open yet).
    pub dialogs_enabled: bool,
}

impl PresetsPanel<'_> {
    /// Draw the section; a click on "Save scene…" or "Load scene…" asks
    /// for its dialog.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<Request> {
        let mut request = None;
        egui::CollapsingHeader::new("Presets")
            .default_open(true)
            .show(ui, |ui| {
                ui.horizontal_wrapped(|ui| {
                    for (name, text) in PRESETS {
                        let summary = text
                            .lines()
                            .next()
                            .unwrap_or("")
                            .trim_start_matches('#')
                            .trim();
                        if ui.button(name).on_hover_text(summary).clicked() {
                            self.state.load_preset(name);
                        }
                    }
                });
                ui.horizontal(|ui| {
                    let enabled = self.dialogs_enabled;
                    if ui
                        .add_enabled(enabled, egui::Button::new("Save scene…"))
                        .on_hover_text(
                            "Save the scene as TOML (usable with `skyrender render --scene`)",
                        )
                        .clicked()
                    {
                        request = Some(Request::Open(Dialog::SaveScene));
                    }
                    if ui
                        .add_enabled(enabled, egui::Button::new("Load scene…"))
                        .on_hover_text("Load a scene TOML")
                        .clicked()
                    {
                        request = Some(Request::Open(Dialog::LoadScene));
                    }
                });
            });
        request
    }
}
