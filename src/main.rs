//! `skyrender`: the command-line and preview-app entry point.

use clap::error::ErrorKind;
use std::path::PathBuf;

use clap::{Parser, Subcommand};

/// Physically based spectral sky renderer. Without a subcommand, opens the
/// interactive preview.
#[derive(Parser, Debug)]
#[command(
    name = "skyrender",
    version,
    about,
    args_conflicts_with_subcommands = true
)]
struct Cli {
    #[command(subcommand)]
    command: Option<Shell>,
    /// Preview app: save a screenshot of the window to this PNG and exit.
    #[arg(long, value_name = "OUT.png")]
    screenshot: Option<PathBuf>,
    /// Preview app: seconds to let the image refine before the screenshot.
    #[arg(
        long,
        allow_hyphen_values = true,
        value_name = "SECONDS",
        default_value_t = 5.0
    )]
    screenshot_after: f64,
    /// Preview app: start from this preset.
    #[arg(long, value_name = "NAME", conflicts_with = "scene")]
    preset: Option<String>,
    /// Preview app: start from this scene description (TOML).
    #[arg(long, value_name = "FILE.toml")]
    scene: Option<PathBuf>,
}

/// The shells: the command line's subcommands, and the benchmark.
#[derive(Subcommand, Debug)]
enum Shell {
    #[command(flatten)]
    Cli(Box<skyrender::cli::Command>),
    /// Measure speed and noise (see BENCHMARKS.md).
    Bench(skyrender::bench::BenchArgs),
}

fn main() {
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => {
            e.exit()
        }
        Err(e) => {
            // clap's own message spans several lines (tips, usage); keep its
            // first paragraph on one line, like every other error here.
            let text = e.to_string();
            let first: Vec<&str> = text
                .lines()
                .take_while(|line| !line.trim().is_empty())
                .map(str::trim)
                .collect();
            let message = first.join(" ");
            let message = message.strip_prefix("error: ").unwrap_or(&message);
            eprintln!("skyrender: error: {message} (see --help)");
            std::process::exit(2);
        }
    };
    // Ctrl-C or a `kill` while a file is being written must not leave its
    // temporary file behind; where the handler cannot be installed the
    // writes stay atomic, only that clean-up is lost.
    let _ = skyrender::output::atomic::remove_on_signals();
    let result = match cli.command {
        Some(Shell::Cli(command)) => skyrender::cli::run(*command).map_err(|e| e.to_string()),
        Some(Shell::Bench(args)) => skyrender::bench::run(&args),
        None => skyrender::app::run_app(
            cli.preset.as_deref(),
            cli.scene.as_deref(),
            cli.screenshot.as_deref(),
            cli.screenshot_after,
        ),
    };
    // The app's window may close while an export is still writing.
    skyrender::output::atomic::remove_pending_files();
    if let Err(message) = result {
        eprintln!("skyrender: error: {message}");
        std::process::exit(2);
    }
}
