//! `skyrender`: the command-line and preview-app entry point.

use clap::Parser;

fn main() {
    let cli = skyrender::cli::Cli::parse();
    let result = match cli.command {
        Some(command) => skyrender::cli::run(command).map_err(|e| e.to_string()),
        None => skyrender::app::run_app(
            cli.preset.as_deref(),
            cli.screenshot.as_deref(),
            cli.screenshot_after,
        ),
    };
    if let Err(message) = result {
        eprintln!("skyrender: error: {message}");
        std::process::exit(2);
    }
}
