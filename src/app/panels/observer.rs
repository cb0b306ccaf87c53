//! The Observer section: the eye's altitude, on a logarithmic slider from
//! the ground to orbit (typed values take units, "10 km"), with quick buttons.

use egui::Slider;

use crate::app::state::{AppState, GROUND_ALTITUDE_M, MAX_APP_ALTITUDE_M};

/// The Observer section.
pub struct ObserverPanel<'a> {
    /// The state whose observer it sets.
    pub state: &'a mut AppState,
}

impl ObserverPanel<'_> {
    /// Draw the section.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Observer")
            .default_open(true)
            .show(ui, |ui| {
                let altitude = self.state.scene().observer.altitude_m;
                let mut position = altitude_to_slider(altitude);
                let response = ui
                    .add(
                        Slider::new(&mut position, 0.0..=altitude_to_slider(MAX_APP_ALTITUDE_M))
                            .text("Altitude")
                            .custom_formatter(|p, _| format_altitude(slider_to_altitude(p)))
                            .custom_parser(|s| parse_altitude(s).map(altitude_to_slider)),
                    )
                    .on_hover_text(
                        "Height of the eye above the ground (logarithmic scale, 0 m to 1000 km); \
                 type e.g. \"10 km\"",
                    );
                if response.changed() {
                    self.state.set_altitude_m(slider_to_altitude(position));
                }
                ui.horizontal(|ui| {
                    for (label, m, tip) in [
                        (
                            "Ground",
                            GROUND_ALTITUDE_M,
                            "Standing on the ground (eye height 2 m)",
                        ),
                        (
                            "Airliner 10 km",
                            10_000.0,
                            "Cruising altitude of an airliner",
                        ),
                        ("Orbit 400 km", 400_000.0, "Low Earth orbit, like the ISS"),
                    ] {
                        if ui
                            .selectable_label(altitude == m, label)
                            .on_hover_text(tip)
                            .clicked()
                        {
                            self.state.set_altitude_m(m);
                        }
                    }
                });
            });
    }
}

/// `log10(altitude + 1)`: the altitude slider's position for an altitude in m.
fn altitude_to_slider(altitude_m: f64) -> f64 {
    (altitude_m.max(0.0) + 1.0).log10()
}

/// Inverse of [`altitude_to_slider`], m (rounded to 3 significant digits
/// above 100 m so that dragged values stay readable).
fn slider_to_altitude(position: f64) -> f64 {
    let m = (10f64.powf(position) - 1.0).max(0.0);
    if m < 100.0 {
        (m * 10.0).round() / 10.0
    } else {
        let magnitude = 10f64.powf(m.log10().floor() - 2.0);
        (m / magnitude).round() * magnitude
    }
}

/// An altitude for display: "2 m", "10.0 km", "400 km".
fn format_altitude(m: f64) -> String {
    if m < 1_000.0 {
        format!("{m:.0} m")
    } else if m < 100_000.0 {
        format!("{:.1} km", m / 1_000.0)
    } else {
        format!("{:.0} km", m / 1_000.0)
    }
}

/// Parse an altitude typed by the user: a number in m, or with a unit
/// "m" / "km" ("10 km", "400km", "2500 m").
fn parse_altitude(text: &str) -> Option<f64> {
    let t = text.trim().to_ascii_lowercase();
    let (number, factor) = if let Some(n) = t.strip_suffix("km") {
        (n, 1_000.0)
    } else if let Some(n) = t.strip_suffix('m') {
        (n, 1.0)
    } else {
        (t.as_str(), 1.0)
    };
    let value = number.trim().parse::<f64>().ok()? * factor;
    value.is_finite().then_some(value)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn altitude_slider_mapping() {
        for m in [0.0, 2.0, 10_000.0, 400_000.0, 1.0e6] {
            let back = slider_to_altitude(altitude_to_slider(m));
            assert!((back - m).abs() <= 1e-6 * m.max(1.0), "{m} -> {back}");
        }
        assert_eq!(slider_to_altitude(altitude_to_slider(12_345.0)), 12_300.0);
        assert_eq!(format_altitude(2.0), "2 m");
        assert_eq!(format_altitude(10_000.0), "10.0 km");
        assert_eq!(format_altitude(400_000.0), "400 km");
        assert_eq!(parse_altitude("10 km"), Some(10_000.0));
        assert_eq!(parse_altitude(" 2500m"), Some(2_500.0));
        assert_eq!(parse_altitude("12"), Some(12.0));
        assert_eq!(parse_altitude("high"), None);
        assert_eq!(parse_altitude("inf"), None);
    }
}
