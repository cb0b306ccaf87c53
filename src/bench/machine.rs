//! The machine's side of the benchmark: its CPUs and load, thread pools,
//! parallel scaling, and a render's peak memory.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use serde::Serialize;

use super::noise::render_for;
use crate::render::Renderer;
use crate::scene::Scene;

/// Bytes in a GiB.
pub(super) const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// Parallel scaling from one thread to all.
#[derive(Clone, Debug, Serialize)]
pub struct ScalingResult {
    /// The scene measured.
    pub scene: String,
    /// Threads of the parallel run.
    pub threads: usize,
    /// Camera paths per second with one thread.
    pub paths_per_s_1_thread: f64,
    /// Camera paths per second with every thread.
    pub paths_per_s_all: f64,
    /// `paths_per_s_all` over `paths_per_s_1_thread`.
    pub speedup: f64,
    /// Speedup over the thread count.
    pub efficiency: f64,
    /// CPU time over (wall time × threads) in each configuration.
    pub cpu_share_1_thread: f64,
    /// The same with every thread.
    pub cpu_share_all: f64,
}

/// Peak memory of one render, measured as a child process.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryResult {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Samples per pixel rendered.
    pub spp: u32,
    /// Peak resident set size, bytes.
    pub peak_rss_bytes: u64,
    /// The same, GiB.
    pub peak_rss_gib: f64,
    /// Wall time of the child, s.
    pub seconds: f64,
    /// How the peak was read (GNU time or /proc polling).
    pub method: &'static str,
    /// The command line of the child.
    pub command: String,
}

/// The machine the benchmark ran on.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// Logical CPUs.
    pub cpus: usize,
    /// CPU model name.
    pub model: String,
    /// Load averages before the run (/proc/loadavg).
    pub loadavg_before: String,
    /// Load averages after the run.
    pub loadavg_after: String,
}

pub(super) fn read_trimmed(path: &str) -> String {
    std::fs::read_to_string(path)
        .map(|s| s.trim().to_owned())
        .unwrap_or_default()
}

pub(super) fn cpu_model() -> String {
    read_trimmed("/proc/cpuinfo")
        .lines()
        .find(|l| l.starts_with("model name"))
        .and_then(|l| l.split(':').nth(1))
        .map_or_else(|| "unknown".to_owned(), |s| s.trim().to_owned())
}

pub(super) fn thread_pool(threads: usize) -> Result<rayon::ThreadPool, String> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| format!("bench: threads: {e}"))
}

/// Paths, seconds and CPU seconds of `scene` on `pool`, rendering whole
/// passes for about `seconds`.
fn throughput(
    scene: &Scene,
    pool: &rayon::ThreadPool,
    seconds: f64,
) -> Result<(u64, f64, f64), String> {
    let renderer = Renderer::new(scene).map_err(|e| e.to_string())?;
    Ok(pool.install(|| {
        let r = render_for(&renderer, seconds);
        (r.paths, r.seconds, r.cpu_seconds)
    }))
}

/// Parallel efficiency from 1 to `threads` threads on midday, alternating
/// 1, N, 1, N so that a change of machine load affects both alike.
pub(super) fn measure_scaling(
    scene: &Scene,
    threads: usize,
    budget_s: f64,
) -> Result<ScalingResult, String> {
    let one = thread_pool(1)?;
    let all = thread_pool(threads)?;
    let slot = budget_s / 4.0;
    let (mut p1, mut s1, mut c1, mut pn, mut sn, mut cn) = (0, 0.0, 0.0, 0, 0.0, 0.0);
    for _ in 0..2 {
        let (p, s, c) = throughput(scene, &one, slot)?;
        p1 += p;
        s1 += s;
        c1 += c;
        let (p, s, c) = throughput(scene, &all, slot)?;
        pn += p;
        sn += s;
        cn += c;
    }
    let r1 = p1 as f64 / s1;
    let rn = pn as f64 / sn;
    Ok(ScalingResult {
        scene: "midday".into(),
        threads,
        paths_per_s_1_thread: r1,
        paths_per_s_all: rn,
        speedup: rn / r1,
        efficiency: rn / r1 / threads as f64,
        cpu_share_1_thread: c1 / s1,
        cpu_share_all: cn / (sn * threads as f64),
    })
}

/// Peak resident memory of `skyrender render` writing a `width`×`height`
/// equirect EXR at 1 spp, run as a child process of this executable:
/// GNU time's maximum RSS (from wait4) where `/usr/bin/time` exists, else the
/// child's VmHWM polled from /proc.
pub(super) fn measure_memory(
    threads: usize,
    width: u32,
    height: u32,
) -> Result<MemoryResult, String> {
    let exe = std::env::current_exe().map_err(|e| format!("bench: memory: {e}"))?;
    let dir = tempfile::tempdir().map_err(|e| format!("bench: memory: {e}"))?;
    let output = dir.path().join("export.exr");
    let render_args: Vec<String> = vec![
        "render".into(),
        "--preset".into(),
        "midday".into(),
        "--camera".into(),
        "equirect".into(),
        "--width".into(),
        width.to_string(),
        "--height".into(),
        height.to_string(),
        "--spp".into(),
        "1".into(),
        "--threads".into(),
        threads.to_string(),
        "-o".into(),
        output.display().to_string(),
    ];
    let command = format!("skyrender {}", render_args.join(" "));
    let gnu_time = Path::new("/usr/bin/time");
    let start = Instant::now();
    let (peak_kib, method) = if gnu_time.exists() {
        let report = dir.path().join("time.txt");
        let out = Command::new(gnu_time)
            .arg("-f")
            .arg("%M")
            .arg("-o")
            .arg(&report)
            .arg(&exe)
            .args(&render_args)
            .stdin(Stdio::null())
            .output()
            .map_err(|e| format!("bench: memory: cannot run {}: {e}", gnu_time.display()))?;
        if !out.status.success() {
            return Err(format!(
                "bench: memory: export failed: {}",
                String::from_utf8_lossy(&out.stderr).trim()
            ));
        }
        let text = std::fs::read_to_string(&report).map_err(|e| format!("bench: memory: {e}"))?;
        let kib = text
            .lines()
            .filter_map(|l| l.trim().parse::<u64>().ok())
            .next_back()
            .ok_or_else(|| format!("bench: memory: cannot parse '{}'", text.trim()))?;
        (kib, "max RSS of the child (GNU time, wait4 rusage)")
    } else {
        let mut child = Command::new(&exe)
            .args(&render_args)
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("bench: memory: {e}"))?;
        let status_path = format!("/proc/{}/status", child.id());
        let mut peak = 0u64;
        let status = loop {
            if let Some(kib) = read_trimmed(&status_path)
                .lines()
                .find_map(|l| l.strip_prefix("VmHWM:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<u64>().ok())
            {
                peak = peak.max(kib);
            }
            if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
                break status;
            }
            std::thread::sleep(Duration::from_millis(5));
        };
        if !status.success() {
            return Err(format!("bench: memory: export failed ({status})"));
        }
        (
            peak,
            "VmHWM of the child polled every 5 ms (may miss a final peak)",
        )
    };
    let seconds = start.elapsed().as_secs_f64();
    let bytes = peak_kib * 1024;
    Ok(MemoryResult {
        width,
        height,
        spp: 1,
        peak_rss_bytes: bytes,
        peak_rss_gib: bytes as f64 / GIB,
        seconds,
        method,
        command,
    })
}
