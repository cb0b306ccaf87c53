//! The Display section: exposure, tone curve, the sun marker and false
//! colour (how the image is shown; none of it needs a new render).

use egui::Slider;

use crate::app::state::{AppState, ToneCurve, EXPOSURE_RANGE};

/// The Display section.
pub struct DisplayPanel<'a> {
    /// The state whose display settings it sets.
    pub state: &'a mut AppState,
}

impl DisplayPanel<'_> {
    /// Draw the section (closed at first).
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        // Closed at first: auto exposure and the default tone curve suit
        // most scenes, and the settings above it then fit the default
        // window without scrolling.
        egui::CollapsingHeader::new("Display")
            .default_open(false)
            .show(ui, |ui| {
                let display = &mut self.state.display;
                ui.checkbox(&mut display.auto_exposure, "Auto exposure")
                    .on_hover_text("Map the image's log-average luminance to middle grey");
                let (lo, hi) = EXPOSURE_RANGE;
                ui.add_enabled(
                    !display.auto_exposure,
                    Slider::new(&mut display.exposure_ev, lo..=hi)
                        .text("Exposure")
                        .suffix(" EV")
                        .custom_formatter(|v, _| format!("{v:.1}")),
                )
                .on_hover_text("Display value = luminance (cd/m²) × 2^EV, then the tone curve")
                .on_disabled_hover_text("Set automatically; untick Auto exposure to adjust");
                egui::ComboBox::from_label("Tone curve")
                    .selected_text(display.tone_curve.label())
                    .show_ui(ui, |ui| {
                        for curve in ToneCurve::ALL {
                            ui.selectable_value(&mut display.tone_curve, curve, curve.label());
                        }
                    })
                    .response
                    .on_hover_text("How linear radiance becomes screen brightness");
                ui.checkbox(&mut display.mark_sun, "Mark the sun")
                    .on_hover_text("Draw a ring where the sun is");
                ui.checkbox(&mut display.false_colour, "False colour (log luminance)")
                    .on_hover_text(
                        "Show luminance on a log scale in viridis, with a colour bar in cd/m²",
                    );
            });
    }
}
