//! The spectrum panel under the view: the spectral radiance of the
//! direction the user clicked, from the radiance probe
//! (`Renderer::probe_radiance`), with its standard error.

use crate::render::SpectralEstimate;
use crate::scene::Scene;

/// The spectrum probe's wavelengths: 360–830 nm (the visible range of the
/// CIE colour-matching functions) every 10 nm.
const PROBE_FIRST_NM: f64 = 360.0;
const PROBE_LAST_NM: f64 = 830.0;
const PROBE_STEP_NM: f64 = 10.0;
/// Monte Carlo samples per wavelength of the spectrum probe by default: a
/// standard error of about 0.5% at 550 nm, 45° up at midday, in about a
/// quarter of a second on 2 cores.
pub const DEFAULT_PROBE_SAMPLES: u32 = 2000;
/// Title of the spectrum panel (followed by the direction).
pub const SPECTRUM_TITLE: &str = "Spectrum";

/// The probe's wavelengths, nm.
pub fn probe_wavelengths_nm() -> Vec<f64> {
    let count = ((PROBE_LAST_NM - PROBE_FIRST_NM) / PROBE_STEP_NM).round() as usize + 1;
    (0..count)
        .map(|i| PROBE_FIRST_NM + PROBE_STEP_NM * i as f64)
        .collect()
}

/// The spectral radiance of one direction, asked for by a click on the view.
#[derive(Clone, Debug)]
pub struct SpectrumProbe {
    /// Degrees clockwise from north.
    pub azimuth_deg: f64,
    /// Degrees above the horizon.
    pub elevation_deg: f64,
    /// The scene it was computed for (it is stale once the scene differs).
    pub(crate) scene: Scene,
    /// Which probe this is (a later click's result replaces an earlier one's).
    pub(crate) id: u64,
    /// `None` while it is computed.
    pub result: Option<Result<Vec<SpectralEstimate>, String>>,
}

/// The spectrum panel: the direction in the title, the radiance with its
/// ±1 standard error band.
pub struct SpectrumPanel<'a> {
    /// The probe shown.
    pub probe: &'a SpectrumProbe,
    /// It was computed for another scene than the current one.
    pub stale: bool,
}

impl SpectrumPanel<'_> {
    /// Draw the panel; whether the user closed it.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> bool {
        let (probe, stale) = (self.probe, self.stale);
        let mut close = false;
        ui.horizontal(|ui| {
            ui.heading(format!(
                "{SPECTRUM_TITLE} at azimuth {:.1}°, elevation {:.1}°",
                probe.azimuth_deg, probe.elevation_deg
            ));
            close = ui
                .button("Close")
                .on_hover_text("Hide the spectrum")
                .clicked();
        });
        if stale {
            ui.colored_label(
                super::ERROR_COLOUR,
                "stale: the scene changed since; click the view again",
            );
        }
        let estimates = match &probe.result {
            None => {
                ui.horizontal(|ui| {
                    ui.spinner();
                    ui.label("computing the spectrum…");
                });
                return close;
            }
            Some(Err(e)) => {
                ui.colored_label(super::ERROR_COLOUR, e);
                return close;
            }
            Some(Ok(estimates)) => estimates,
        };
        let xs: Vec<f64> = estimates.iter().map(|e| e.wavelength_nm).collect();
        let lo: Vec<f64> = estimates.iter().map(|e| e.radiance - e.std_error).collect();
        let hi: Vec<f64> = estimates.iter().map(|e| e.radiance + e.std_error).collect();
        let line: Vec<[f64; 2]> = estimates
            .iter()
            .map(|e| [e.wavelength_nm, e.radiance])
            .collect();
        let discarded: u64 = estimates.iter().map(|e| e.discarded).sum();
        let colour = ui.visuals().hyperlink_color;
        egui_plot::Plot::new("spectrum-plot")
            .legend(egui_plot::Legend::default())
            .x_axis_label("wavelength (nm)")
            .y_axis_label(if probe.scene.render.unit_sun {
                // A unit sun (1 W m⁻² nm⁻¹ at the top of the atmosphere) makes
                // the radiance a ratio to that irradiance.
                "radiance per unit TOA irradiance (1/sr)"
            } else {
                "spectral radiance (W/(m²·sr·nm))"
            })
            .height((ui.available_height() - 24.0).max(120.0))
            .show(ui, |plot| {
                plot.add(
                    egui_plot::FilledArea::new("±1 standard error", &xs, &lo, &hi)
                        .fill_color(colour.gamma_multiply(0.3)),
                );
                plot.line(egui_plot::Line::new("radiance", line).color(colour));
            });
        if discarded > 0 {
            ui.label(format!("{discarded} non-finite samples counted as 0"));
        }
        close
    }
}
