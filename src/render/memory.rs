//! How much memory a render needs, checked before any work, and the film
//! allocated without aborting where it is not there.

use super::exact::ExactPlane;
use super::{film_spectral, Film, Renderer};

/// A render's buffers could not be allocated.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "not enough memory for a {width}×{height} render: it needs about {:.2} GiB; \
     choose a smaller size (--width/--height) or free memory",
    *bytes as f64 / f64::from(1u32 << 30)
)]
pub struct OutOfMemory {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// [`Renderer::memory_needed_bytes`].
    pub bytes: u64,
}

impl Renderer {
    /// A film for this render (aborts if memory runs out; see `try_new_film`).
    pub fn new_film(&self) -> Film {
        self.try_new_film().unwrap_or_else(|e| panic!("{e}"))
    }

    /// [`Self::new_film`], or an error saying how much memory the image
    /// needs where its buffers cannot be allocated.
    pub fn try_new_film(&self) -> Result<Film, OutOfMemory> {
        let film = Film::try_new(self.scene.render.width, self.scene.render.height)
            .map_err(|_| self.out_of_memory())?
            .with_mirror(self.mirror)
            .try_with_halves(self.halves)
            .map_err(|_| self.out_of_memory())?;
        let film = if self.plan.splats() {
            film.try_with_splats().map_err(|_| self.out_of_memory())?
        } else {
            film
        };
        let film = if self.variance_sums() {
            film.try_with_variance().map_err(|_| self.out_of_memory())?
        } else {
            film
        };
        let film = if self.path_layers() {
            film.try_with_layers(self.centre_ground())
                .map_err(|_| self.out_of_memory())?
        } else {
            film
        };
        match self.scene.output.spectral_bands {
            Some(bands) => film
                .try_with_spectral(bands)
                .map_err(|_| self.out_of_memory()),
            None => Ok(film),
        }
    }

    /// About the most memory a render of this scene holds at once, bytes:
    /// the film (exact XYZ sums, 24 bytes a pixel, [`super::exact`], and
    /// with a [`super::HalfMirror`] its left parts' sums and weight, 32; the
    /// splat layer's f32 sums, 12, where the renderer splats (24 with a
    /// half mirror); the adaptive
    /// plan's byte) and, on top, the
    /// larger of the adaptive plan's working arrays (a pixel index, the
    /// luminance, its spread, a bin and the plan: 19 bytes) and the output
    /// (the RGB image, 12 bytes, and a PNG's 8-bit copy, 3), plus the
    /// layers' planes where the output has layers
    /// ([`Self::layer_bytes_per_pixel`]), a spectral image's sums and
    /// planes ([`film_spectral::spectral_bytes_per_pixel`]) and a noise
    /// target's variance sums, 44 ([`super::noise_estimate`]). The tables the
    /// integrator reads do not grow with the image and are left out.
    pub fn memory_needed_bytes(&self) -> u64 {
        let pixels = u64::from(self.scene.render.width) * u64::from(self.scene.render.height);
        let exact = ExactPlane::BYTES_PER_PIXEL as u64;
        let film = exact
            + if self.halves.is_some() { exact + 8 } else { 0 }
            + match (self.plan.splats(), self.halves.is_some()) {
                (true, true) => 24,
                (true, false) => 12,
                (false, _) => 0,
            }
            + 1;
        let planning = 8 + 4 + 4 + 2 + 1;
        let output = 12 + 3;
        let spectral = self.scene.output.spectral_bands.map_or(0, |bands| {
            film_spectral::spectral_bytes_per_pixel(bands, self.plan.splats())
        });
        // A noise target's variance sums, where no layer counted them.
        let variance = if self.variance_sums() && !self.variance_layer() {
            super::layers::VARIANCE_SUMS_BYTES
        } else {
            0
        };
        pixels * (film + planning.max(output) + spectral + variance + self.layer_bytes_per_pixel())
    }

    /// Checks, before any work, that [`Self::memory_needed_bytes`] can be
    /// allocated (and frees it again), so a render too large for the
    /// machine or its limits (`ulimit -v`) stops at once with a message
    /// rather than aborting when a buffer fails to allocate hours later.
    pub fn check_memory(&self) -> Result<(), OutOfMemory> {
        if super::alloc::can_reserve(self.memory_needed_bytes()) {
            Ok(())
        } else {
            Err(self.out_of_memory())
        }
    }

    /// The error for this scene's render not fitting in memory.
    pub fn out_of_memory(&self) -> OutOfMemory {
        OutOfMemory {
            width: self.scene.render.width,
            height: self.scene.render.height,
            bytes: self.memory_needed_bytes(),
        }
    }
}
