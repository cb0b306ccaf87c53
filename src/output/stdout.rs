//! Text for standard output, written so that a closed pipe ends the
//! program quietly, as other command-line tools do.

/// Writes `text` to standard output. A reader that closed the pipe early
/// (`skyrender radiance … | head -n 3`) ends the program quietly with
/// success, as other command-line tools do, where `print!` would panic; any
/// other write error ends it with a one-line error.
pub fn emit(text: &str) {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(0);
        }
        eprintln!("skyrender: error: cannot write to standard output: {e}");
        std::process::exit(2);
    }
}
