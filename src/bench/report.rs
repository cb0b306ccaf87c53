//! `skyrender bench`'s report as Markdown tables.

use serde::Serialize;

use super::machine::{Machine, MemoryResult, ScalingResult};
use super::noise::{NoiseRun, SkyMask};

/// The preview's first frame, ms: the target the report judges.
pub(super) const FIRST_FRAME_TARGET_MS: f64 = 100.0;
/// Parallel efficiency from one thread to all: the target.
pub(super) const EFFICIENCY_TARGET: f64 = 0.85;
/// Time to 1 % over a 4096×2048 sunset export (`--export-noise`), s: the
/// issue's target.
const EXPORT_TARGET_S: f64 = 15.0 * 60.0;
/// Peak memory of the measured render (`--memory`), GiB: the target.
pub(super) const MEMORY_TARGET_GIB: f64 = 1.5;

/// One row of the per-scene table; exactly the keys of the issue.
#[derive(Clone, Debug, Serialize)]
pub struct SceneResult {
    /// The scene's name.
    pub scene: String,
    /// Camera paths per second.
    pub paths_per_s: f64,
    /// Relative noise over the sky at the budget.
    pub noise_at_budget: f64,
    /// The time budget, s.
    pub budget_s: f64,
    /// Time to 2 % noise over the sky, extrapolated, s.
    pub time_to_2pct_s: f64,
    /// Time to 1 % noise over the sky, extrapolated, s.
    pub time_to_1pct_s: f64,
    /// Time to the preview's first frame, ms.
    pub first_frame_ms: f64,
    /// Render threads.
    pub threads: usize,
    /// Relative noise over the ground, and over the whole image (sun cone
    /// excluded), at the budget.
    pub noise_ground_at_budget: f64,
    /// See `noise_ground_at_budget`: over the whole image.
    pub noise_whole_at_budget: f64,
    /// Time to 1 % noise over the whole image of a 4096×2048 render,
    /// extrapolated: noise ∝ 1/√time, time ∝ pixels.
    pub time_to_1pct_4k_s: f64,
    /// The neighbour or circle correlation of the noise largest in
    /// magnitude, with its sign.
    pub noise_neighbour_correlation: f64,
    /// RMS error of the preview's first frame, the sky model, against the
    /// reference (see [`NoiseRun::model_error`]).
    pub first_frame_error: f64,
    /// RMS error of the first Monte Carlo pass against the reference (see
    /// [`NoiseRun::first_pass_error`]).
    pub first_pass_error: f64,
    /// RMS error of what the preview shows 2 s after a change (see
    /// [`NoiseRun::preview_error_2s`]).
    pub preview_error_2s: f64,
}

/// Everything else measured per scene.
#[derive(Clone, Debug, Serialize)]
pub struct SceneDetail {
    /// The scene's name.
    pub scene: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Camera kind.
    pub camera: &'static str,
    /// Sun elevation at the observer, degrees.
    pub sun_elevation_deg: f64,
    /// Observer altitude, m.
    pub observer_altitude_m: f64,
    /// Which pixels the sky noise covers.
    pub sky_mask: SkyMask,
    /// Wavelengths carried per path.
    pub wavelengths_per_path: usize,
    /// Spectral samples (paths × lanes) per second.
    pub spectral_samples_per_s: f64,
    /// The two-image noise measurement.
    pub run: NoiseRun,
    /// Width of the first-frame scene, pixels.
    pub first_frame_width: u32,
    /// Height of the first-frame scene, pixels.
    pub first_frame_height: u32,
    /// Time to set the renderer up before the first frame, ms.
    pub first_frame_setup_ms: f64,
    /// Time to the first frame with the sky model's tables made anew (the
    /// app's start, or a change of atmosphere), ms; `first_frame_ms` is
    /// with them kept (a change of sun, camera or size).
    pub first_frame_cold_ms: f64,
    /// Time to the first frame with the tables read from disk (the app's
    /// start at an atmosphere seen before), ms.
    pub first_frame_disk_ms: f64,
    /// The noise target at the budget, if the scene has one.
    pub noise_target: Option<f64>,
    /// Extrapolated time to the noise target, s.
    pub time_to_target_s: Option<f64>,
    /// Whether the target is reached within 10 s (extrapolated if the budget differs).
    pub target_met: Option<bool>,
}

/// One ablation variant of one scene.
#[derive(Clone, Debug, Serialize)]
pub struct AblationRow {
    /// The scene's name.
    pub scene: String,
    /// The variant (`key=value` of `[render.integrator]` or `[render]`).
    pub variant: String,
    /// Relative sky noise of the variant at the budget.
    pub noise_at_budget: f64,
    /// Render time the variant actually took (more than the budget where one
    /// pass each overran it), s.
    pub seconds: f64,
    /// Noise of the variant over noise of the full renderer at equal time:
    /// sqrt(noise_v² t_v / (noise_full² t_full)), which is the plain ratio
    /// of the noise at budget unless the variant overran the budget.
    pub noise_ratio: f64,
    /// Time the variant needs for the full renderer's noise, relative (= ratio²).
    pub time_ratio: f64,
    /// Relative noise of the variant over the ground's pixels at the budget.
    pub noise_ground_at_budget: f64,
    /// [`Self::noise_ratio`] over the ground's pixels.
    pub ground_noise_ratio: f64,
    /// Relative noise of the variant over the whole image (ground
    /// included, the sun's cone left out) at the budget.
    pub noise_whole_at_budget: f64,
    /// [`Self::noise_ratio`] over the whole image.
    pub whole_noise_ratio: f64,
    /// The variant's structure: its noise's correlation between
    /// neighbours or splat partners largest in magnitude (as the scene's
    /// `noise_neighbour_correlation`), so that a technique that trades
    /// structure for variance shows both.
    pub noise_neighbour_correlation: f64,
    /// Camera paths per second of the variant.
    pub paths_per_s: f64,
    /// Mean sky luminance of the variant over the full renderer's (≈ 1: unbiased).
    pub mean_ratio: f64,
    /// CPU time over (wall time × threads) while the variant ran.
    pub cpu_share: f64,
}

/// The sunset at a larger size and the 4096×2048 export's time
/// extrapolated from it (`--export-noise`).
#[derive(Clone, Debug, Serialize)]
pub struct ExportNoise {
    /// The scene (a preset as an equirect map).
    pub scene: String,
    /// Width rendered, pixels.
    pub width: u32,
    /// Height rendered, pixels.
    pub height: u32,
    /// Time the two renders took, s.
    pub seconds: f64,
    /// Passes of render A and of render B.
    pub passes: [u32; 2],
    /// Relative noise over the whole image (ground included, the sun's
    /// cone left out).
    pub noise_whole: f64,
    /// The same over the sky.
    pub noise_sky: f64,
    /// The same over the ground.
    pub noise_ground: f64,
    /// Time to 1 % over the whole image of a 4096×2048 export,
    /// extrapolated from this size (noise ∝ 1/√time, time ∝ pixels), s.
    pub time_to_1pct_4k_s: f64,
    /// The same extrapolated from the 256×128 scene of the same run, s
    /// (null where the run left the scene out).
    pub time_to_1pct_4k_s_from_bench: Option<f64>,
    /// CPU time over (wall time × threads) while it rendered.
    pub cpu_share: f64,
}

/// The whole report (`--json` prints it).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The command line that produced the report.
    pub command: String,
    /// A smoke run (`--quick`): budgets too small for the targets, so
    /// none is judged (shown as "n/a", `target_met` null).
    pub smoke: bool,
    /// The machine.
    pub machine: Machine,
    /// The time budget per scene, s.
    pub budget_s: f64,
    /// Render threads.
    pub threads: usize,
    /// One row per scene.
    pub scenes: Vec<SceneResult>,
    /// The measurement behind each row.
    pub details: Vec<SceneDetail>,
    /// Ablation rows (`--ablation`).
    pub ablation: Vec<AblationRow>,
    /// The fast mode against the reference, per scene and scale.
    pub fast: Vec<super::FastResult>,
    /// Parallel scaling (`--scaling`).
    pub scaling: Option<ScalingResult>,
    /// Peak memory (`--memory`).
    pub memory: Option<MemoryResult>,
    /// The sunset measured at 1024×512 (`--export-noise`).
    pub export_noise: Option<ExportNoise>,
    /// Remarks on the run (load, smoke budgets).
    pub notes: Vec<String>,
}

fn pct(v: f64) -> String {
    if v.is_finite() {
        format!("{:.2} %", v * 100.0)
    } else {
        "n/a".into()
    }
}

fn secs(v: f64) -> String {
    if !v.is_finite() {
        "n/a".into()
    } else if v < 100.0 {
        format!("{v:.2} s")
    } else {
        format!("{v:.0} s")
    }
}

fn minutes(v: f64) -> String {
    if v.is_finite() {
        format!("{:.0} min", v / 60.0)
    } else {
        "n/a".into()
    }
}

fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "n/a".into()
    }
}

fn yes_no(ok: bool) -> &'static str {
    if ok {
        "yes"
    } else {
        "NO"
    }
}

/// The report as Markdown tables (what `BENCHMARKS.md` records).
pub fn format_report(report: &Report) -> String {
    use std::fmt::Write as _;
    let mut out = String::new();
    let m = &report.machine;
    // A smoke run's budgets are far below the targets': judging them would
    // read as failures that say nothing.
    let yes_no = |ok: bool| if report.smoke { "n/a" } else { yes_no(ok) };
    let _ = writeln!(out, "command: {}", report.command);
    if report.smoke {
        let _ = writeln!(
            out,
            "smoke run (--quick): small budgets, targets not judged (n/a)"
        );
    }
    let _ = writeln!(
        out,
        "machine: {} CPU(s), {}; load average before: {}, after: {}",
        m.cpus, m.model, m.loadavg_before, m.loadavg_after
    );
    let _ = writeln!(
        out,
        "budget {} s per scene (two renders of {} s), {} thread(s)\n",
        report.budget_s,
        report.budget_s / 2.0,
        report.threads
    );
    let _ = writeln!(
        out,
        "| scene | size | M paths/s | M spectral samples/s | spp A+B | noise at budget | time to 2 % | time to 1 % | target (10 s) | met | first frame | ≤ 100 ms |"
    );
    let _ = writeln!(
        out,
        "|---|---|---:|---:|---:|---:|---:|---:|---:|:-:|---:|:-:|"
    );
    for (r, d) in report.scenes.iter().zip(&report.details) {
        let _ = writeln!(
            out,
            "| {} | {}×{} | {:.3} | {:.3} | {}+{} | {} | {} | {} | {} | {} | {:.1} ms | {} |",
            r.scene,
            d.width,
            d.height,
            r.paths_per_s / 1e6,
            d.spectral_samples_per_s / 1e6,
            d.run.passes[0],
            d.run.passes[1],
            pct(r.noise_at_budget),
            secs(r.time_to_2pct_s),
            secs(r.time_to_1pct_s),
            d.noise_target.map_or_else(|| "—".into(), pct),
            d.target_met.map_or("—", yes_no),
            r.first_frame_ms,
            yes_no(r.first_frame_ms <= FIRST_FRAME_TARGET_MS),
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "What the user sees (sun cone excluded): noise over the ground and the whole image (and the latter as the renders estimate it from their own passes, what render --noise reads), the whole image's time to 1 % at 4096×2048 (extrapolated), the noise's correlation between neighbours (rows, columns) and along the splats' circles, and the error of the preview's first frame (the sky model) and of the first Monte Carlo pass against the reference.\n"
    );
    let _ = writeln!(
        out,
        "| scene | noise sky | noise ground | noise whole | its estimate | 4K to 1 % | corr. rows | corr. columns | corr. circles | first-frame (model) error | first-pass error | preview error at 2 s |"
    );
    let _ = writeln!(
        out,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for (r, d) in report.scenes.iter().zip(&report.details) {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            r.scene,
            pct(r.noise_at_budget),
            pct(r.noise_ground_at_budget),
            pct(r.noise_whole_at_budget),
            pct(d.run.noise_whole_estimate),
            minutes(r.time_to_1pct_4k_s),
            num(d.run.row_correlation, 3),
            num(d.run.column_correlation, 3),
            num(d.run.circle_correlation, 3),
            pct(r.first_frame_error),
            pct(r.first_pass_error),
            pct(r.preview_error_2s),
        );
    }
    let _ = writeln!(out);
    let _ = writeln!(
        out,
        "| scene | sky mask | sky pixels | mean sky Y (cd/m²) | render s | CPU share | discarded | first-frame set-up | first frame, tables made | first frame, tables read |"
    );
    let _ = writeln!(out, "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|");
    for d in &report.details {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.4e} | {:.2} | {} | {} | {:.1} ms | {:.1} ms | {:.1} ms |",
            d.scene,
            d.sky_mask.describe(),
            d.run.sky_pixels,
            d.run.mean_luminance_cd_m2,
            d.run.seconds,
            pct(d.run.cpu_share),
            d.run.discarded,
            d.first_frame_setup_ms,
            d.first_frame_cold_ms,
            d.first_frame_disk_ms,
        );
    }
    if !report.fast.is_empty() {
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "Fast mode (render --mode fast; bias: RMS relative error against the reference, noise removed; 4K: 4096x2048 at scale 8 to 1 % whole-image noise, extrapolated)\n"
        );
        let _ = writeln!(
            out,
            "| scene | scale | coarse | bias | whole-image noise | mean ratio | render s | compose s | 4K to 1 %, s |"
        );
        let _ = writeln!(out, "|---|---:|---|---:|---:|---:|---:|---:|---:|");
        for f in &report.fast {
            let _ = writeln!(
                out,
                "| {} | {} | {}x{} | {} | {} | {} | {:.1} | {:.3} | {:.0} |",
                f.scene,
                f.fast_scale,
                f.coarse_size.0,
                f.coarse_size.1,
                pct(f.bias),
                pct(f.noise_whole),
                num(f.mean_ratio, 3),
                f.seconds,
                f.compose_s,
                f.time_to_1pct_4k_s
            );
        }
    }
    if !report.ablation.is_empty() {
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "Ablation (same budget; noise ratio > 1: the technique helps; time ratio = ratio²; mean ratio ≈ 1: unbiased; † = one pass each overran the budget, ratio normalised to equal time by the 1/√t law)\n"
        );
        let _ = writeln!(
            out,
            "| scene | switched off | noise at budget | render s | noise ratio | time ratio | ground noise | ground ratio | whole-image noise | whole-image ratio | correlation | M paths/s | CPU share | mean ratio |"
        );
        let _ = writeln!(
            out,
            "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
        );
        for a in &report.ablation {
            let overran = if a.seconds > 1.1 * report.budget_s {
                " †"
            } else {
                ""
            };
            let _ = writeln!(
                out,
                "| {} | {} | {} | {:.1}{overran} | {} | {} | {} | {} | {} | {} | {} | {:.3} | {} | {} |",
                a.scene,
                a.variant,
                pct(a.noise_at_budget),
                a.seconds,
                num(a.noise_ratio, 2),
                num(a.time_ratio, 2),
                pct(a.noise_ground_at_budget),
                num(a.ground_noise_ratio, 2),
                pct(a.noise_whole_at_budget),
                num(a.whole_noise_ratio, 2),
                num(a.noise_neighbour_correlation, 3),
                a.paths_per_s / 1e6,
                pct(a.cpu_share),
                num(a.mean_ratio, 3)
            );
        }
    }
    if let Some(s) = &report.scaling {
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "Scaling ({}, 1 vs {} threads, alternated 1/N/1/N): {:.3} → {:.3} M paths/s, speedup {:.2}, efficiency {:.1} % (target ≥ 85 %: {}); CPU share {} (1 thread), {} ({} threads)",
            s.scene,
            s.threads,
            s.paths_per_s_1_thread / 1e6,
            s.paths_per_s_all / 1e6,
            s.speedup,
            s.efficiency * 100.0,
            yes_no(s.efficiency >= EFFICIENCY_TARGET),
            pct(s.cpu_share_1_thread),
            pct(s.cpu_share_all),
            s.threads
        );
    }
    if let Some(mem) = &report.memory {
        let _ = writeln!(out);
        let _ = writeln!(
            out,
            "Memory: {}×{} equirect export at {} spp: peak RSS {:.3} GiB ({} bytes) in {:.1} s (target ≤ 1.5 GiB: {}); {}; `{}`",
            mem.width,
            mem.height,
            mem.spp,
            mem.peak_rss_gib,
            mem.peak_rss_bytes,
            mem.seconds,
            yes_no(mem.peak_rss_gib <= MEMORY_TARGET_GIB),
            mem.method,
            mem.command
        );
    }
    if let Some(e) = &report.export_noise {
        let _ = writeln!(out);
        let from_bench = e
            .time_to_1pct_4k_s_from_bench
            .map_or("n/a".into(), |s| format!("{:.0} min", s / 60.0));
        let _ = writeln!(
            out,
            "Export noise: {} at {}×{}, {}+{} passes in {:.1} s: whole image {}, sky {}, ground {}; a 4096×2048 export to 1 % extrapolated from it: {:.0} min (from the 256×128 scene: {from_bench}; target ≤ 15 min: {}); CPU share {}",
            e.scene,
            e.width,
            e.height,
            e.passes[0],
            e.passes[1],
            e.seconds,
            pct(e.noise_whole),
            pct(e.noise_sky),
            pct(e.noise_ground),
            e.time_to_1pct_4k_s / 60.0,
            yes_no(e.time_to_1pct_4k_s <= EXPORT_TARGET_S),
            pct(e.cpu_share)
        );
    }
    let _ = writeln!(out);
    for n in &report.notes {
        let _ = writeln!(out, "- {n}");
    }
    out
}
