//! `skyrender`: the command-line and preview-app entry point.

use clap::error::ErrorKind;
use clap::Parser;

fn main() {
    let cli = match skyrender::cli::Cli::try_parse() {
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
        Some(command) => skyrender::cli::run(command).map_err(|e| e.to_string()),
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
