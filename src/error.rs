//! The error every bad input becomes: which parameter, and what is wrong
//! with it, in one line. Below the scene and the physics alike, so that
//! either can refuse input without importing the other.

/// An invalid parameter: its name as the user wrote it (a TOML key, a
/// flag, a file) and the reason, naming the valid range or form.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("invalid {parameter}: {message}")]
pub struct SceneError {
    /// The parameter as the user wrote it (a TOML key, a flag, a file).
    pub parameter: String,
    /// What is wrong, naming the valid range or form.
    pub message: String,
}

impl SceneError {
    /// An error for `parameter`.
    pub fn new(parameter: &str, message: impl Into<String>) -> Self {
        Self {
            parameter: parameter.to_owned(),
            message: message.into(),
        }
    }
}

/// A number as a message shows it: plainly where that is short, in
/// scientific notation where plain digits would run long (`1e308`, not 309
/// digits; `1.5e-9`, not a row of zeros).
pub fn show_number(value: f64) -> String {
    let magnitude = value.abs();
    if value == 0.0 || !value.is_finite() || (1e-4..1e7).contains(&magnitude) {
        format!("{value}")
    } else {
        format!("{value:e}")
    }
}

/// A count within `lo..=hi`, or an error naming `parameter` and the range.
pub fn check_count(parameter: &str, value: usize, lo: usize, hi: usize) -> Result<(), SceneError> {
    if (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(SceneError::new(
            parameter,
            format!("{value} is outside the valid range {lo} to {hi}"),
        ))
    }
}

/// A value within `lo..=hi` (and finite), or an error naming `parameter`
/// and the range.
pub fn check_range(parameter: &str, value: f64, lo: f64, hi: f64) -> Result<(), SceneError> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(())
    } else {
        Err(SceneError::new(
            parameter,
            format!(
                "{} is outside the valid range {lo} to {hi}",
                show_number(value)
            ),
        ))
    }
}
