//! The Export section, pinned under the others: the HDR panorama's size
//! and samples, the timelapse settings (where the Sun is placed by date),
//! the export button and its progress, and saving the view.

use egui::{DragValue, Slider};

use super::{Dialog, Request, ERROR_COLOUR};
use crate::app::state::{
    AppState, ExportStatus, SequenceStatus, DEFAULT_EXPORT_NOISE_PERCENT, EXPORT_WIDTHS,
    MAX_EXPORT_SPP, MAX_TIMELAPSE_MINUTES,
};
use crate::app::sun_place::{format_duration, parse_duration, SunMode};
use crate::export::MAX_FRAMES;

/// The Export section.
pub struct ExportPanel<'a> {
    /// The state whose export settings it sets and whose status it shows.
    pub state: &'a mut AppState,
    /// An export is running (no second one may start).
    pub exporting: bool,
    /// Whether a file dialog may be opened (none is open yet).
    pub dialogs_enabled: bool,
    /// Whether there is a frame on screen to save.
    pub can_save_view: bool,
}

impl ExportPanel<'_> {
    /// Draw the section; the export and save buttons ask for their dialogs,
    /// Cancel for the export to stop.
    pub fn ui(&mut self, ui: &mut egui::Ui) -> Option<Request> {
        egui::CollapsingHeader::new("Export")
            .default_open(true)
            .show(ui, |ui| self.contents(ui))
            .body_returned
            .flatten()
    }

    /// "noise ≤ x %": the export's noise target (`render --noise`), beside
    /// its spp.
    fn noise_target(&mut self, ui: &mut egui::Ui, noise_percent: Option<f64>) {
        let tip = "Stop the export once its estimated noise (the whole image's, from the \
                   spread of its passes, read from the eighth on) is at most this; the spp \
                   stays the most passes";
        let mut on = noise_percent.is_some();
        if ui.checkbox(&mut on, "noise ≤").on_hover_text(tip).changed() {
            self.state
                .set_export_noise(on.then_some(DEFAULT_EXPORT_NOISE_PERCENT));
        }
        if let Some(mut percent) = noise_percent {
            let field = DragValue::new(&mut percent)
                .range(crate::scene::MIN_NOISE_PERCENT..=100.0)
                .speed(0.05)
                .suffix(" %");
            if ui.add(field).on_hover_text(tip).changed() {
                self.state.set_export_noise(Some(percent));
            }
        }
    }

    fn contents(&mut self, ui: &mut egui::Ui) -> Option<Request> {
        let mut request = None;
        let export = self.state.export.clone();
        egui::ComboBox::from_label("Panorama size")
            .selected_text(format!("{} × {}", export.width, export.height()))
            .show_ui(ui, |ui| {
                for width in EXPORT_WIDTHS {
                    let text = format!("{width} × {}", width / 2);
                    if ui.selectable_label(export.width == width, text).clicked() {
                        self.state.set_export_width(width);
                    }
                }
            })
            .response
            .on_hover_text("Size of the equirectangular EXR panorama");
        ui.horizontal(|ui| {
            let mut spp = export.spp;
            let spp_slider = Slider::new(&mut spp, 1..=MAX_EXPORT_SPP)
                .logarithmic(true)
                .text("spp");
            if ui
                .add(spp_slider)
                .on_hover_text(
                    "Samples per pixel of the exported panorama (the most, with a noise target)",
                )
                .changed()
            {
                self.state.set_export_spp(spp);
            }
            self.noise_target(ui, export.noise_percent);
        });
        if self.state.sun_mode() == SunMode::DatePlace {
            self.timelapse_settings(ui);
        }
        let can_export = !self.exporting && self.dialogs_enabled;
        ui.horizontal(|ui| self.export_buttons(ui, can_export, &mut request));
        match self.state.export_status.clone() {
            ExportStatus::Running {
                done,
                total,
                sequence,
                ..
            } => {
                ui.horizontal(|ui| {
                    let fraction = done as f32 / total.max(1) as f32;
                    let text = match sequence {
                        Some(s) => {
                            format!("frame {} / {}: {done} / {total} spp", s.frame, s.frames)
                        }
                        None => format!("{done} / {total} spp"),
                    };
                    let bar = egui::ProgressBar::new(fraction)
                        .text(text)
                        .desired_width(if sequence.is_some() { 200.0 } else { 160.0 });
                    ui.add(bar);
                    let tip = if sequence.is_some() {
                        "Stop the export; the frames finished so far are kept, no partial one"
                    } else {
                        "Stop the export; nothing is written"
                    };
                    if ui.button("Cancel").on_hover_text(tip).clicked() {
                        request = Some(Request::CancelExport);
                    }
                });
            }
            ExportStatus::Finished {
                path,
                elapsed,
                sequence,
            } => {
                let seconds = elapsed.as_secs_f64();
                match sequence {
                    Some(s) => ui.weak(format!(
                        "Exported {} in {seconds:.1} s{}",
                        path.display(),
                        frame_counts(s)
                    )),
                    None => ui.weak(format!("Exported {} in {seconds:.1} s", path.display())),
                };
            }
            ExportStatus::Cancelled { sequence: None } => {
                ui.weak("Export cancelled; nothing written.");
            }
            ExportStatus::Cancelled { sequence: Some(s) } => {
                ui.weak(format!(
                    "Timelapse cancelled at frame {} of {}{}; no partial frame written.",
                    s.frame,
                    s.frames,
                    frame_counts(s)
                ));
            }
            ExportStatus::Failed(e) => {
                ui.colored_label(ERROR_COLOUR, format!("Export failed: {e}"));
            }
            ExportStatus::Idle => {}
        }
        if ui
            .add_enabled(
                self.can_save_view && self.dialogs_enabled,
                egui::Button::new("Save view as PNG/EXR…"),
            )
            .on_hover_text("Save the image on screen: PNG as shown, EXR as linear HDR")
            .clicked()
        {
            request = Some(Request::Open(Dialog::SaveView));
        }
        request
    }

    /// The export button (a panorama, or the timelapse's frames) and the
    /// Layers option beside it.
    fn export_buttons(
        &mut self,
        ui: &mut egui::Ui,
        can_export: bool,
        request: &mut Option<Request>,
    ) {
        if self.state.timelapse_enabled() {
            let plan = self.state.timelapse();
            if ui
                .add_enabled(
                    can_export && plan.is_ok(),
                    egui::Button::new("Export timelapse…"),
                )
                .on_hover_text(
                    "Render the frames one after another in the background into a \
                     folder you choose, named by the file name above",
                )
                .clicked()
            {
                *request = Some(Request::Open(Dialog::TimelapseFolder));
            }
        } else if ui
            .add_enabled(can_export, egui::Button::new("Export HDR panorama…"))
            .on_hover_text(
                "Render the scene as an equirectangular OpenEXR in the background: \
                 the same file as `skyrender render --camera equirect` writes",
            )
            .clicked()
        {
            *request = Some(Request::Open(Dialog::Export));
        }
        let fast = self.state.export.fast;
        ui.add_enabled(
            !fast,
            egui::Checkbox::new(&mut self.state.export.layers, "Layers"),
        )
        .on_hover_text(
            "Write the compositing layers beside the image: sky, sun and ground \
             (the image split by light path), variance, transmittance and alpha, Z \
             (as `skyrender render --layers`)",
        )
        .on_disabled_hover_text("The fast mode writes the image alone");
        ui.checkbox(&mut self.state.export.fast, "Fast")
            .on_hover_text(
                "Approximate, not the reference: the sky model at full size, corrected by \
             a Monte Carlo render at an eighth of the width and height (as `skyrender \
             render --mode fast`): a 4096 × 2048 panorama in minutes instead of hours, \
             about 1–3 % off the reference (BENCHMARKS.md)",
            );
    }

    /// The Timelapse checkbox and, when ticked, its duration, frames, file
    /// names and resume option, with the times it spans or why it cannot run.
    fn timelapse_settings(&mut self, ui: &mut egui::Ui) {
        let settings = &mut self.state.export.timelapse;
        ui.checkbox(&mut settings.enabled, "Timelapse")
            .on_hover_text(
                "Export a sequence of panoramas from the Sun panel's date and time on, \
             the Sun moving with the time",
            );
        if !settings.enabled {
            return;
        }
        let mut duration = settings.duration_min;
        let mut frames = settings.frames;
        ui.horizontal(|ui| {
            let label = ui.label("Duration");
            ui.add(
                DragValue::new(&mut duration)
                    .range(0..=MAX_TIMELAPSE_MINUTES)
                    .speed(5.0)
                    .custom_formatter(|m, _| format_duration(m))
                    .custom_parser(parse_duration),
            )
            .labelled_by(label.id)
            .on_hover_text(
                "Time from the first frame to the last (type e.g. 12 h, 1:30 or 90 min)",
            );
            let label = ui.label("Frames");
            ui.add(DragValue::new(&mut frames).range(1..=MAX_FRAMES).speed(0.5))
                .labelled_by(label.id)
                .on_hover_text("Frames in the sequence, the first and the last included");
        });
        ui.horizontal(|ui| {
            let label = ui.label("File names");
            ui.add(egui::TextEdit::singleline(&mut settings.file_name).desired_width(140.0))
                .labelled_by(label.id)
                .on_hover_text(
                    "Each frame's file name; a run of # is its number, zero padded \
                     (sky_####.exr: sky_0001.exr, sky_0002.exr, …)",
                );
        });
        ui.checkbox(&mut settings.skip_existing, "Skip frames whose file exists")
            .on_hover_text("Resume an interrupted sequence: frames already on disk are left alone");
        self.state.set_timelapse_duration(duration);
        self.state.set_timelapse_frames(frames);
        match self.state.timelapse() {
            Ok(timelapse) => {
                let n = timelapse.frames();
                let time = |frame| timelapse.time_of(frame).format("%Y-%m-%d %H:%M");
                let step = if n > 1 {
                    let seconds = f64::from(duration) * 60.0 / f64::from(n - 1);
                    if seconds < 60.0 {
                        format!(", one every {seconds:.0} s")
                    } else {
                        format!(", one every {}", format_duration(seconds / 60.0))
                    }
                } else {
                    String::new()
                };
                ui.weak(format!("{} to {}{step}", time(1), time(n)));
            }
            Err(e) => {
                ui.colored_label(ERROR_COLOUR, e);
            }
        }
    }
}

/// ", 3 frames written, 1 skipped" for a timelapse's status line.
fn frame_counts(s: SequenceStatus) -> String {
    let skipped = if s.skipped > 0 {
        format!(", {} skipped (their files existed)", s.skipped)
    } else {
        String::new()
    };
    let plural = if s.written == 1 { "" } else { "s" };
    format!(", {} frame{plural} written{skipped}", s.written)
}
