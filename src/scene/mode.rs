//! The render mode (`[render] mode`): the unbiased reference, or the
//! explicit fast mode ([`crate::render::fast`]).

use serde::{Deserialize, Serialize};

use super::output::OutputParams;
use crate::error::{check_count, SceneError};

/// Default of `[render] fast_scale`: the fast mode's Monte Carlo runs at an
/// eighth of the image's width and height (a 4096 × 2048 panorama's
/// correction at 512 × 256, 0.7° a pixel).
pub const DEFAULT_FAST_SCALE: u32 = 8;
/// Largest `fast_scale` accepted.
pub const MAX_FAST_SCALE: u32 = 64;

/// How an image is rendered.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum RenderMode {
    /// Unbiased spectral Monte Carlo at every pixel: the reference.
    #[default]
    Reference,
    /// The approximate sky model at the image's resolution, corrected by
    /// the Monte Carlo image at `fast_scale` times coarser: consistent
    /// (the correction's resolution reaching the image's, the bias goes),
    /// not unbiased; its bias is measured per preset (`skyrender bench`,
    /// `BENCHMARKS.md`).
    Fast,
}

impl RenderMode {
    /// Every mode, as the command line names them.
    pub const ALL: [RenderMode; 2] = [Self::Reference, Self::Fast];

    /// The mode's name in scene files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Self::Reference => "reference",
            Self::Fast => "fast",
        }
    }

    /// The mode of `name`, or an error listing the modes.
    pub fn from_name(name: &str) -> Result<Self, SceneError> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == name)
            .ok_or_else(|| {
                SceneError::new(
                    "mode",
                    format!("'{name}' is not a render mode: reference or fast"),
                )
            })
    }

    /// Whether this is the reference mode (left out of saved scenes).
    pub fn is_reference(&self) -> bool {
        *self == Self::Reference
    }
}

/// Whether `scale` is [`DEFAULT_FAST_SCALE`] (left out of saved scenes).
// serde's `skip_serializing_if` hands the field by reference.
#[allow(clippy::trivially_copy_pass_by_ref)]
pub(super) fn is_default_fast_scale(scale: &u32) -> bool {
    *scale == DEFAULT_FAST_SCALE
}

/// Checks `mode` and `fast_scale` against the scene's `output`: the fast
/// mode writes one RGB image (no spectral image, no layers: each would
/// need its own correction).
pub(super) fn validate(
    mode: RenderMode,
    fast_scale: u32,
    output: &OutputParams,
) -> Result<(), SceneError> {
    check_count(
        "fast_scale",
        fast_scale as usize,
        1,
        MAX_FAST_SCALE as usize,
    )?;
    if mode != RenderMode::Fast {
        return Ok(());
    }
    if output.spectral_bands.is_some() {
        return Err(SceneError::new(
            "mode",
            "the fast mode writes an RGB image only: render the spectral image in the reference mode",
        ));
    }
    if !output.layers.is_empty() {
        return Err(SceneError::new(
            "mode",
            format!(
                "the fast mode writes an RGB image only: render the layers ({}) in the reference mode",
                output.layers.join(", ")
            ),
        ));
    }
    Ok(())
}
