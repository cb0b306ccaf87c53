//! The Atmosphere section: the planet, aerosols, ozone and the ground's
//! albedo.

use super::slider;
use crate::app::state::{AppState, AEROSOL_AMOUNT_RANGE, OZONE_DU_RANGE};
use crate::physics::planet::Planet;
use crate::physics::spectrum_file::GROUND_SPECTRA;

/// The ground spectrum menu's entry for the albedo slider's one number.
const UNIFORM_GROUND: &str = "uniform";

/// The Atmosphere section.
pub struct AtmospherePanel<'a> {
    /// The state whose atmosphere it sets.
    pub state: &'a mut AppState,
}

impl AtmospherePanel<'_> {
    /// Draw the section.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Atmosphere")
            .default_open(true)
            .show(ui, |ui| {
                // The amount slider multiplies Elterman's Earth profile, and
                // the ozone profile is the Earth's: both belong to the Earth.
                let earth = self.state.planet() == Planet::Earth;
                let a = self.state.atmosphere().clone();
                let mut aerosols = a.aerosols;
                // The planet shares the aerosols' row: the side panel's
                // height is spoken for (the export buttons stay in view at
                // the default window size).
                ui.horizontal(|ui| {
                    if ui
                        .checkbox(&mut aerosols, "Aerosols")
                        .on_hover_text(
                            "Haze particles (Elterman's profile; Mars: dust): whiter sky \
                             near the horizon, glow around the sun",
                        )
                        .changed()
                    {
                        self.state.set_aerosols(aerosols);
                    }
                    let planet = self.state.planet();
                    egui::ComboBox::from_label("Planet")
                        .selected_text(planet.name())
                        .show_ui(ui, |ui| {
                            for p in Planet::ALL {
                                if ui.selectable_label(p == planet, p.name()).clicked() {
                                    self.state.set_planet(p);
                                }
                            }
                        })
                        .response
                        .on_hover_text(
                            "The planet's own atmosphere: Mars has CO₂ air, dust and no ozone, \
                             and the Sun at 1.52 AU (choosing one replaces the atmosphere)",
                        );
                });
                ui.add_enabled_ui(aerosols && earth, |ui| {
                    if let Some(v) = slider(
                        ui,
                        a.aerosol_amount,
                        AEROSOL_AMOUNT_RANGE,
                        "Aerosol amount",
                        "×",
                        "Multiple of the standard aerosol profile (1 = clear standard day)",
                    ) {
                        self.state.set_aerosol_amount(v);
                    }
                });
                let mut ozone = a.ozone;
                if ui
                    .add_enabled(earth, egui::Checkbox::new(&mut ozone, "Ozone"))
                    .on_hover_text(
                        "Ozone absorption (Chappuis band): keeps the twilight zenith blue",
                    )
                    .changed()
                {
                    self.state.set_ozone(ozone);
                }
                ui.add_enabled_ui(ozone && earth, |ui| {
                    ui.horizontal(|ui| {
                        if let Some(v) = slider(
                            ui,
                            self.state.ozone_column_du(),
                            OZONE_DU_RANGE,
                            "Ozone column",
                            " DU",
                            "Total ozone column in Dobson units (about 300 is typical)",
                        ) {
                            self.state.set_ozone_du(Some(v));
                        }
                        if ui
                            .add_enabled(a.ozone_du.is_some(), egui::Button::new("Profile").small())
                            .on_hover_text("Use the model profile's own column")
                            .clicked()
                        {
                            self.state.set_ozone_du(None);
                        }
                    });
                });
                // The spectrum menu shares the albedo's row (the panel's
                // height is spoken for, as above).
                ui.horizontal(|ui| {
                    if let Some(v) = slider(
                        ui,
                        a.ground_albedo,
                        (0.0, 1.0),
                        "Ground albedo",
                        "",
                        "Fraction of light the (Lambertian) ground reflects: \
                         0.1 forest or sea, 0.3 average, 0.8 snow",
                    ) {
                        self.state.set_ground_albedo(v);
                    }
                    self.ground_spectrum(ui);
                });
            });
    }

    /// The ground's albedo spectrum: the slider's one number at every
    /// wavelength, or a measured spectrum (moving the slider returns to
    /// the one number).
    fn ground_spectrum(&mut self, ui: &mut egui::Ui) {
        let current = self.state.scene().atmosphere.ground_albedo_spectrum.clone();
        let shown = current.as_deref().unwrap_or(UNIFORM_GROUND);
        egui::ComboBox::from_id_salt("ground spectrum")
            .width(64.0)
            .selected_text(shown)
            .show_ui(ui, |ui| {
                if ui
                    .selectable_label(current.is_none(), UNIFORM_GROUND)
                    .clicked()
                {
                    self.state.set_ground_spectrum(None);
                }
                for (name, _) in GROUND_SPECTRA {
                    if ui
                        .selectable_label(current.as_deref() == Some(name), name)
                        .clicked()
                    {
                        self.state.set_ground_spectrum(Some(name));
                    }
                }
            })
            .response
            .on_hover_text(
                "The ground's reflectance over wavelength: the albedo above at every \
                 wavelength, or a measured spectrum (USGS Spectral Library 7: green grass, \
                 fine snow, beach sand, sea water; data/README.md)",
            );
    }
}
