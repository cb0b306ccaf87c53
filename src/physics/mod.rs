//! Physics of the clear atmosphere: pure functions of altitude and
//! wavelength, in SI units (metres, kelvin, pascals, m⁻¹), except that
//! wavelengths are in nanometres, as in every table we read.
//!
//! Nothing here knows about rendering.

pub mod aerosol;
pub mod data_file;
pub mod mie;
pub mod ozone;
pub mod phase_table;
pub mod planet;
pub mod profile;
pub mod quadrature;
pub mod rayleigh;
pub mod solar_position;
pub mod spectral_phase;
pub mod spectrum_file;
pub mod standard_atmosphere;
pub mod sun;

/// Mean radius of the Earth, m (IUGG mean radius R₁ = 6 371.0088 km, rounded
/// as the scene's planet radius).
pub const EARTH_RADIUS_M: f64 = 6_371_000.0;

/// Default top of the model atmosphere, m.
pub const DEFAULT_ATMOSPHERE_TOP_M: f64 = 100_000.0;

/// Boltzmann constant, J K⁻¹, as used by the U.S. Standard Atmosphere 1976
/// (k = R*/N_A = 1.380 622 × 10⁻²³).
pub const BOLTZMANN_USSA76: f64 = 1.380_622e-23;

/// One Dobson unit in molecules m⁻²: 2.686 763 × 10²⁰ (0.01 mm of gas at STP).
pub const DOBSON_UNIT_PER_M2: f64 = 2.686_763e20;
