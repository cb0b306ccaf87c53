//! The status bar under the view: whether the preview is refining, its
//! samples, speed, render and pass times, size and latency, and the latest
//! error or message.

use std::time::Duration;

use egui::RichText;

use super::ERROR_COLOUR;
use crate::app::state::AppState;
use crate::render::service::Frame;

/// The status bar.
pub struct StatusBar<'a> {
    /// The state (its latest error is dismissed here).
    pub state: &'a mut AppState,
    /// The frame on screen, if any.
    pub frame: Option<&'a Frame>,
    /// Whether that frame is a quick low-resolution draft.
    pub frame_is_draft: bool,
    /// Whether the preview is still refining.
    pub rendering: bool,
    /// Whether the current scene's first frame waits on a new
    /// atmosphere's sky-model tables.
    pub making_tables: bool,
    /// Render time of the image on screen.
    pub render_time: Duration,
    /// How long the latest full-size pass took.
    pub pass_time: Option<Duration>,
    /// The latest times from a change to its first frame and to its first
    /// full-size frame.
    pub latency: (Option<Duration>, Option<Duration>),
}

impl StatusBar<'_> {
    /// Draw the bar.
    pub fn ui(&mut self, ui: &mut egui::Ui) {
        ui.horizontal_wrapped(|ui| {
            let (w, h) = self.state.preview_size();
            let state = if self.state.render().paused {
                "paused"
            } else if self.rendering {
                "rendering"
            } else {
                "done"
            };
            ui.label(RichText::new(state).strong());
            if self.making_tables {
                ui.label("making the sky model's tables for this atmosphere…")
                    .on_hover_text(
                        "A new atmosphere's tables take a few seconds on two cores; \
                         they are then kept while only the sun, the observer, the \
                         camera or the size change, and on disk for the next start",
                    );
            }
            match self.frame {
                Some(f) => {
                    let spp = if self.frame_is_draft {
                        format!("draft {}×{}", f.image.width, f.image.height)
                    } else {
                        format!("{} / {} spp", f.spp, self.state.render().target_spp)
                    };
                    ui.label(spp).on_hover_text(
                        "Samples per pixel accumulated / target (a draft is a quick \
                         low-resolution first look after a change)",
                    );
                    if let Some(noise) = f.noise {
                        ui.label(format!("noise {:.2} %", 100.0 * noise))
                            .on_hover_text(
                                "The passes' estimated noise: the RMS of each pixel's standard \
                             error, from the spread of its passes, over the mean luminance \
                             (the sun's 2° cone left out; shown from the eighth pass on) — \
                             what an export of this many passes would have",
                            );
                    }
                    if f.model_weight > 0.0 {
                        let corrected = if f.coarse_passes > 0 {
                            format!(" (corrected by {} coarse passes)", f.coarse_passes)
                        } else {
                            String::new()
                        };
                        ui.label(format!("model {:.0} %{corrected}", f.model_weight * 100.0))
                            .on_hover_text(
                                "Share of the approximate sky model in the image: the first \
                                 frame is the model alone, then the model corrected by a \
                                 quarter-size Monte Carlo render, and it fades as the passes' \
                                 noise falls below its error (exports never contain it)",
                            );
                    }
                    ui.label(format!(
                        "{:.2} M camera paths/s",
                        f.paths_per_second() / 1e6
                    ))
                    .on_hover_text("Camera paths traced per second");
                    ui.label(format!("{:.1} s", self.render_time.as_secs_f64()))
                        .on_hover_text(
                            "Render time since the latest change (draft included, \
                             pauses not counted)",
                        );
                    if let Some(pass) = self.pass_time {
                        let seconds = pass.as_secs_f64();
                        let text = if seconds < 1.0 {
                            format!("{:.0} ms/pass", seconds * 1e3)
                        } else {
                            format!("{seconds:.1} s/pass")
                        };
                        ui.label(text)
                            .on_hover_text("How long the latest sample pass took");
                    }
                    ui.label(format!("{} discarded", f.discarded))
                        .on_hover_text("Samples dropped as non-finite or negative");
                }
                None => {
                    ui.label("no frame yet");
                }
            }
            ui.label(format!("{w}×{h} px"))
                .on_hover_text("Preview resolution");
            if let (Some(first), Some(full)) = self.latency {
                ui.label(format!(
                    "first frame {:.0} ms, full size {:.0} ms",
                    first.as_secs_f64() * 1e3,
                    full.as_secs_f64() * 1e3
                ))
                .on_hover_text(
                    "Time from the latest change to its first frame on screen \
                     (draft, then full size)",
                );
            }
            if let Some(error) = self.state.last_error.clone() {
                ui.separator();
                ui.colored_label(ERROR_COLOUR, format!("Error: {error}"));
                if ui
                    .small_button("Dismiss")
                    .on_hover_text("Clear this error")
                    .clicked()
                {
                    self.state.last_error = None;
                }
            } else if let Some(message) = &self.state.message {
                ui.separator();
                ui.weak(message);
            }
        });
    }
}
