//! The aerosols' optical properties as a scene gives them (optical depth,
//! Ångström exponent, single-scattering albedo, vertical profile, phase
//! function) and the ground's albedo over wavelength.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use crate::error::{check_range, SceneError};
use crate::physics::aerosol;
use crate::physics::spectrum_file::Tabulated;

/// Vertical shape of the aerosol extinction (`[atmosphere.aerosol] profile`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum AerosolProfileKind {
    /// Elterman (1968), tabulated at 1 km steps to 50 km.
    #[default]
    Elterman,
    /// exp(−altitude / `scale_height_m`).
    Exponential,
}

/// Aerosol phase functions by name (`[atmosphere.aerosol] phase`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum AerosolPhaseKind {
    /// Henyey–Greenstein with `asymmetry`.
    HenyeyGreenstein,
    /// Cornette–Shanks with `asymmetry`.
    CornetteShanks,
    /// Double Henyey–Greenstein with `g1`, `g2` and `weight`
    /// ([`aerosol::double_henyey_greenstein`]).
    DoubleHenyeyGreenstein,
    /// Tabulated in `phase_file`, at one wavelength or several
    /// ([`crate::physics::spectral_phase::SpectralPhaseTable`]).
    Table,
    /// The Martian dust's, over wavelength, by Lorenz–Mie theory
    /// ([`crate::physics::planet::mars_dust::phase_table`]).
    MarsDust,
}

/// Valid range of the Ångström exponent. Particles much smaller than the
/// wavelength scatter as λ⁻⁴ (Rayleigh's limit, the steepest any particle
/// gives); the finest smoke measures about 2–2.5, and coarse dust and sea
/// salt down to about −0.5 (Eck et al. 1999, *J. Geophys. Res.* 104,
/// 31 333). Beyond −1 to 4 a value is a typing or unit error.
pub const ANGSTROM_EXPONENT_RANGE: (f64, f64) = (-1.0, 4.0);
/// Largest vertical aerosol optical depth at 550 nm: 25, as the thickest
/// haze `aerosol_amount` allows (100 × Elterman's 0.249).
pub const MAX_AEROSOL_OPTICAL_DEPTH: f64 = 25.0;
/// Valid range of the exponential profile's scale height, m. Below 500 m
/// the renderer's 50 m nodes (`render::medium`), linear in between, would
/// stray from the exponential by more than (50/500)²/8 = 0.13 %; above 100 km it is no longer a profile but a
/// constant over the atmosphere's height (typical hazes: 1–2 km).
pub const SCALE_HEIGHT_RANGE_M: (f64, f64) = (500.0, 100_000.0);
/// Reference wavelength of `optical_depth_550` and of the Ångström law, nm.
pub const AEROSOL_REFERENCE_NM: f64 = 550.0;

/// The aerosol by its optical properties: the `[atmosphere.aerosol]`
/// table of a scene, every key optional. Unset, the aerosol is Elterman's
/// with the flat keys of `[atmosphere]`, as before the table existed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct AerosolOptics {
    /// Vertical aerosol optical depth at 550 nm from sea level to the top
    /// of the atmosphere (a sun photometer's AOD); replaces
    /// `aerosol_amount`: the profile is scaled to give this column.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub optical_depth_550: Option<f64>,
    /// Ångström exponent α: τ(λ) = τ₅₅₀ (λ / 550 nm)^−α, in place of
    /// Elterman's spectral dependence.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub angstrom_exponent: Option<f64>,
    /// Single-scattering albedo, 0–1: one number, or a spectrum of
    /// `[wavelength_nm, albedo]` pairs; replaces `aerosol_albedo`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub single_scattering_albedo: Option<AlbedoSpectrum>,
    /// Vertical shape of the extinction; unset: Elterman's.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub profile: Option<AerosolProfileKind>,
    /// Scale height of the exponential profile, m.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub scale_height_m: Option<f64>,
    /// Phase function; replaces `aerosol_phase`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase: Option<AerosolPhaseKind>,
    /// Asymmetry parameter of Henyey–Greenstein or Cornette–Shanks;
    /// replaces `aerosol_g`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub asymmetry: Option<f64>,
    /// Double Henyey–Greenstein: asymmetry of the first lobe.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub g1: Option<f64>,
    /// Double Henyey–Greenstein: asymmetry of the second lobe.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub g2: Option<f64>,
    /// Double Henyey–Greenstein: weight of the first lobe, 0–1.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub weight: Option<f64>,
    /// Tabulated phase function: a CSV file `angle_deg,phase`
    /// ([`crate::physics::phase_table`]); a relative path is taken from
    /// the scene file's folder.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub phase_file: Option<PathBuf>,
}

/// A single-scattering albedo: one number for every wavelength, or
/// `[wavelength_nm, albedo]` pairs (a sun photometer's retrieval, e.g.
/// AERONET's at 440, 675, 870 and 1020 nm), linear in wavelength between
/// them and constant beyond the first and the last.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum AlbedoSpectrum {
    /// The same albedo at every wavelength.
    Constant(f64),
    /// `[wavelength_nm, albedo]` pairs, wavelengths increasing.
    Spectrum(Vec<[f64; 2]>),
}

impl AlbedoSpectrum {
    /// The albedo at `wavelength_nm`.
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        match self {
            Self::Constant(albedo) => *albedo,
            Self::Spectrum(pairs) => {
                let k = pairs.partition_point(|p| p[0] <= wavelength_nm);
                match k {
                    0 => pairs[0][1],
                    k if k == pairs.len() => pairs[k - 1][1],
                    k => {
                        let ([x0, y0], [x1, y1]) = (pairs[k - 1], pairs[k]);
                        y0 + (wavelength_nm - x0) / (x1 - x0) * (y1 - y0)
                    }
                }
            }
        }
    }

    /// Checks the albedos (0–1) and the wavelengths (220–4000 nm,
    /// increasing, at least one pair).
    pub(super) fn validate(&self, parameter: &str) -> Result<(), SceneError> {
        match self {
            Self::Constant(albedo) => check_range(parameter, *albedo, 0.0, 1.0),
            Self::Spectrum(pairs) => {
                if pairs.is_empty() {
                    return Err(SceneError::new(
                        parameter,
                        "an empty spectrum: give a number, or [wavelength_nm, albedo] pairs",
                    ));
                }
                for (i, &[nm, albedo]) in pairs.iter().enumerate() {
                    check_range(&format!("{parameter} wavelength (nm)"), nm, 220.0, 4000.0)?;
                    check_range(parameter, albedo, 0.0, 1.0)?;
                    if i > 0 && nm <= pairs[i - 1][0] {
                        return Err(SceneError::new(
                            parameter,
                            format!(
                                "wavelength {nm} nm does not increase from the pair before's {} nm",
                                pairs[i - 1][0]
                            ),
                        ));
                    }
                }
                Ok(())
            }
        }
    }
}

/// The ground's albedo over wavelength ([`super::AtmosphereParams::ground_albedo`]
/// or [`super::AtmosphereParams::ground_albedo_spectrum`]).
#[derive(Clone, Debug, PartialEq)]
pub enum GroundAlbedo {
    /// The same albedo at every wavelength.
    Constant(f64),
    /// A tabulated spectrum.
    Spectrum(std::sync::Arc<Tabulated>),
}

impl GroundAlbedo {
    /// The albedo at `wavelength_nm`.
    pub fn at(&self, wavelength_nm: f64) -> f64 {
        match self {
            Self::Constant(albedo) => *albedo,
            Self::Spectrum(table) => table.at(wavelength_nm),
        }
    }

    /// The largest albedo at any wavelength: for sampling densities that
    /// need one number for all lanes, never for an estimate's value.
    pub fn max(&self) -> f64 {
        match self {
            Self::Constant(albedo) => *albedo,
            Self::Spectrum(table) => table.max(),
        }
    }
}

impl AerosolOptics {
    /// Whether no key is set (the table is left out of a written scene).
    pub fn is_unset(&self) -> bool {
        *self == Self::default()
    }
}

/// How the aerosol extinction depends on wavelength.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AerosolSpectrum {
    /// Elterman's, relative to 340 nm ([`aerosol::SpectralFactor`]).
    Elterman340,
    /// Elterman's, relative to 550 nm.
    Elterman550,
    /// (λ / 550 nm)^−α.
    Angstrom {
        /// The Ångström exponent α.
        exponent: f64,
    },
}

impl AerosolSpectrum {
    /// Extinction at `wavelength_nm` relative to the reference wavelength
    /// (340 nm for [`Self::Elterman340`], else 550 nm).
    pub fn factor(self, wavelength_nm: f64) -> f64 {
        match self {
            Self::Elterman340 => aerosol::SpectralFactor::get().at(wavelength_nm),
            Self::Elterman550 => {
                let f = aerosol::SpectralFactor::get();
                f.at(wavelength_nm) / f.at(AEROSOL_REFERENCE_NM)
            }
            Self::Angstrom { exponent } => (wavelength_nm / AEROSOL_REFERENCE_NM).powf(-exponent),
        }
    }
}

/// The aerosol extinction as a vertical profile at a reference wavelength
/// times a spectral factor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AerosolColumn {
    /// Exponential scale height, m; `None`: Elterman's profile.
    pub(super) scale_height_m: Option<f64>,
    /// Factor on the profile's shape (Elterman's extinction at 340 nm,
    /// m⁻¹, or the exponential's value 1 at the ground) giving the
    /// extinction at the reference wavelength, m⁻¹.
    pub(super) scale: f64,
    /// The spectral factor.
    pub spectrum: AerosolSpectrum,
}

impl AerosolColumn {
    /// The profile's shape at `altitude_m`.
    fn shape(&self, altitude_m: f64) -> f64 {
        match self.scale_height_m {
            None => aerosol::Profile::get().extinction_340nm_per_m(altitude_m),
            Some(h) => (-altitude_m / h).exp(),
        }
    }

    /// Extinction at the reference wavelength, m⁻¹.
    pub fn reference_extinction_per_m(&self, altitude_m: f64) -> f64 {
        self.scale * self.shape(altitude_m)
    }
}

/// Elterman's column from the ground to `top_m` at 340 nm.
pub(super) fn elterman_column_340nm(top_m: f64) -> f64 {
    let profile = aerosol::Profile::get();
    profile.optical_depth_340nm(0.0) - profile.optical_depth_340nm(top_m)
}
