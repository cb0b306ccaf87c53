//! The scene's `[output]` table: compositing layers and a spectral image
//! beside the RGB image.

use serde::{Deserialize, Serialize};

use super::SceneError;

/// What a render's EXR holds besides its RGB image: compositing layers and
/// a spectral image. Unset, a plain RGB file, as before.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct OutputParams {
    /// Extra layers by name (see `crate::render::layers`).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub layers: Vec<String>,
    /// A spectral image in this many bands over 360–830 nm; unset: none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub spectral_bands: Option<u32>,
}

/// The most bands of a spectral image: 1 nm each over 360–830 nm. Finer
/// bands than the colour-matching tables' 1–5 nm steps resolve nothing
/// and would each catch too few wavelength samples to be more than noise.
pub const MAX_SPECTRAL_BANDS: u32 = 470;

impl OutputParams {
    /// Whether the output is the RGB image alone.
    pub fn is_plain(&self) -> bool {
        self.layers.is_empty() && self.spectral_bands.is_none()
    }

    /// Checks `spectral_bands`: 1 to [`MAX_SPECTRAL_BANDS`].
    pub fn validate_spectral(&self) -> Result<(), SceneError> {
        match self.spectral_bands {
            Some(n) if !(1..=MAX_SPECTRAL_BANDS).contains(&n) => Err(SceneError::new(
                "output.spectral_bands",
                format!(
                    "{n} bands: must be 1 to {MAX_SPECTRAL_BANDS} (360–830 nm in bands \
                     of at least 1 nm)"
                ),
            )),
            _ => Ok(()),
        }
    }

    /// Checks the layer names: each one of [`OUTPUT_LAYERS`].
    pub fn check_layers(&self) -> Result<(), SceneError> {
        match self
            .layers
            .iter()
            .find(|name| !OUTPUT_LAYERS.contains(&name.as_str()))
        {
            Some(name) => Err(SceneError::new(
                "layers",
                format!(
                    "unknown layer '{name}' (valid layers: {})",
                    OUTPUT_LAYERS.join(", ")
                ),
            )),
            None => Ok(()),
        }
    }
}

/// The layers a render can write beside its RGB image: `sky`, `sun`,
/// `ground` and `variance` from the render's own paths
/// (`crate::render::film_layers`),
/// `transmittance` and `Z` from each pixel's view ray
/// (`crate::render::layers`).
pub const OUTPUT_LAYERS: &[&str] = &["sky", "sun", "ground", "variance", "transmittance", "Z"];
