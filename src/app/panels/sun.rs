//! The Sun section: the Sun placed by hand (elevation and azimuth) or by a
//! date, a time of day and a place, whose time slider scrubs through the day.

use egui::{DragValue, Slider};

use super::{slider, ERROR_COLOUR};
use crate::app::state::{AppState, SUN_ELEVATION_RANGE};
use crate::app::sun_place::{
    format_time_of_day, format_utc_offset, parse_time_of_day, parse_utc_offset, DatePlace, SunMode,
    LATITUDE_RANGE, LONGITUDE_RANGE, MINUTES_PER_DAY, PLACES, UTC_OFFSET_RANGE_H,
};

/// The Sun section.
pub struct SunPanel<'a> {
    /// The state whose Sun it places.
    pub state: &'a mut AppState,
}

impl SunPanel<'_> {
    /// Draw the section. The mode toggle sits in the header row, so that
    /// the settings below it still fit the default window unscrolled.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        let id = ui.make_persistent_id("sun-section");
        egui::collapsing_header::CollapsingState::load_with_default_open(ui.ctx(), id, true)
            .show_header(ui, |ui| {
                // In the colour of the other sections' titles.
                let colour = ui.visuals().widgets.inactive.text_color();
                ui.label(egui::RichText::new("Sun").color(colour));
                let mode = self.state.sun_mode();
                for (choice, label, tip) in [
                    (
                        SunMode::Manual,
                        "Elevation/azimuth",
                        "Place the Sun by hand",
                    ),
                    (
                        SunMode::DatePlace,
                        "Date, time, place",
                        "Place the Sun where it is at a date and time of day seen from \
                         a latitude and longitude (NREL's Solar Position Algorithm)",
                    ),
                ] {
                    if ui
                        .selectable_label(mode == choice, label)
                        .on_hover_text(tip)
                        .clicked()
                    {
                        self.state.set_sun_mode(choice);
                    }
                }
            })
            .body(|ui| match self.state.sun_mode() {
                SunMode::Manual => self.manual(ui),
                SunMode::DatePlace => self.date_place(ui),
            });
    }

    /// Elevation and azimuth sliders.
    fn manual(&mut self, ui: &mut egui::Ui) {
        let sun = self.state.scene().sun.clone();
        if let Some(v) = slider(
            ui,
            sun.elevation_deg,
            SUN_ELEVATION_RANGE,
            "Elevation",
            "°",
            "Sun elevation above the astronomical horizon, degrees (negative: below it)",
        ) {
            self.state.set_sun_elevation(v);
        }
        if let Some(v) = slider(
            ui,
            sun.azimuth_deg,
            (0.0, 360.0),
            "Azimuth",
            "°",
            "Sun azimuth, degrees clockwise from north (90 east, 180 south, 270 west)",
        ) {
            self.state.set_sun_azimuth(v);
        }
    }

    /// The date, time and place inputs, the places, and the Sun they give.
    fn date_place(&mut self, ui: &mut egui::Ui) {
        let before = self.state.date_place().clone();
        let mut place = before.clone();
        ui.horizontal(|ui| {
            let label = ui.label("Date");
            ui.add(
                egui::TextEdit::singleline(&mut place.date)
                    .hint_text("YYYY-MM-DD")
                    .desired_width(84.0),
            )
            .labelled_by(label.id)
            .on_hover_text("Local date, YYYY-MM-DD (e.g. 2013-05-27)");
            let label = ui.label("UTC offset");
            let mut hours = f64::from(place.utc_offset_min) / 60.0;
            let (lo, hi) = UTC_OFFSET_RANGE_H;
            let response = ui
                .add(
                    DragValue::new(&mut hours)
                        .range(lo..=hi)
                        // Dragging and typing clamp; a value set from
                        // elsewhere is checked (and refused) by the state.
                        .clamp_existing_to_range(false)
                        .speed(0.05)
                        .custom_formatter(|h, _| format_utc_offset(h))
                        .custom_parser(parse_utc_offset),
                )
                .labelled_by(label.id)
                .on_hover_text(
                    "The local time's offset from UTC, in quarter hours \
                     (e.g. −4 for US Eastern summer time); type −4 or +5:45",
                );
            if response.changed() {
                // Zones are whole quarter hours (Nepal, UTC+05:45).
                place.utc_offset_min = ((hours * 4.0).round() * 15.0) as i32;
            }
        });
        let mut minutes = place.minutes;
        ui.add(
            Slider::new(&mut minutes, 0..=MINUTES_PER_DAY)
                .text("Time")
                .custom_formatter(|m, _| format_time_of_day(m))
                .custom_parser(parse_time_of_day),
        )
        .on_hover_text(
            "Local time of day, 00:00 to 24:00, at the UTC offset above; drag to scrub \
             through the day, or type e.g. 11:45",
        );
        place.minutes = minutes;
        ui.horizontal(|ui| {
            for (value, text, range, tip) in [
                (
                    &mut place.latitude_deg,
                    "Latitude",
                    LATITUDE_RANGE,
                    "Degrees north of the equator (negative: south), −90 to 90",
                ),
                (
                    &mut place.longitude_deg,
                    "Longitude",
                    LONGITUDE_RANGE,
                    "Degrees east of Greenwich (negative: west), −180 to 180",
                ),
            ] {
                let label = ui.label(text);
                let (lo, hi) = range;
                ui.add(
                    DragValue::new(value)
                        .range(lo..=hi)
                        .clamp_existing_to_range(false)
                        .speed(0.1)
                        .suffix("°")
                        .custom_formatter(|v, _| format!("{v:.4}")),
                )
                .labelled_by(label.id)
                .on_hover_text(tip);
            }
        });
        ui.horizontal_wrapped(|ui| {
            for p in PLACES {
                let here =
                    place.latitude_deg == p.latitude_deg && place.longitude_deg == p.longitude_deg;
                if ui
                    .selectable_label(here, p.name)
                    .on_hover_text(p.note)
                    .clicked()
                {
                    place = DatePlace {
                        latitude_deg: p.latitude_deg,
                        longitude_deg: p.longitude_deg,
                        utc_offset_min: (p.utc_offset_h * 60.0).round() as i32,
                        ..place.clone()
                    };
                }
            }
        });
        if place != before {
            self.state.set_date_place(place);
        }
        let scene = self.state.scene();
        let error = self.state.date_place_error().map(str::to_owned);
        let shown = if error.is_some() { " (last valid)" } else { "" };
        ui.label(format!(
            "Elevation {:.2}°, azimuth {:.2}°{shown}",
            scene.sun.elevation_deg, scene.sun.azimuth_deg
        ))
        .on_hover_text(
            "Where the Sun is at this date, time and place: the true elevation above the \
             astronomical horizon (no refraction, as the renderer has none), and the \
             azimuth clockwise from north",
        );
        ui.label(format!(
            "Earth–Sun distance {:.4} AU",
            scene.sun_distance_au()
        ))
        .on_hover_text("The date's Earth–Sun distance; sunlight scales by 1/distance²");
        if let Some(error) = error {
            ui.colored_label(ERROR_COLOUR, error);
        }
    }
}
