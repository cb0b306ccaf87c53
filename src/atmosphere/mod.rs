//! The model atmosphere: which constituents are present and how much of each,
//! and the resulting optical coefficients as pure functions of altitude and
//! wavelength.

use std::path::PathBuf;
use std::sync::Arc;

use serde::{Deserialize, Serialize};

mod optics;

use optics::elterman_column_340nm;
pub use optics::{
    AerosolColumn, AerosolOptics, AerosolPhaseKind, AerosolProfileKind, AerosolSpectrum,
    AlbedoSpectrum, GroundAlbedo, AEROSOL_REFERENCE_NM, ANGSTROM_EXPONENT_RANGE,
    MAX_AEROSOL_OPTICAL_DEPTH, SCALE_HEIGHT_RANGE_M,
};

use crate::error::{check_range, SceneError};
use crate::physics::planet::Planet;
use crate::physics::profile::VerticalProfile;
use crate::physics::rayleigh::Gas;
use crate::physics::spectral_phase::SpectralPhaseTable;
use crate::physics::spectrum_file::{self, Quantity, Tabulated};
use crate::physics::{
    aerosol, ozone, standard_atmosphere, DEFAULT_ATMOSPHERE_TOP_M, DOBSON_UNIT_PER_M2,
    EARTH_RADIUS_M,
};

/// Everything that defines the atmosphere and the planet under it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AtmosphereParams {
    /// Radius of the spherical planet, m.
    pub planet_radius_m: f64,
    /// Top of the atmosphere above the ground, m.
    pub top_altitude_m: f64,
    /// Lambertian ground albedo, 0–1, at every wavelength (unless
    /// `ground_albedo_spectrum` is given).
    pub ground_albedo: f64,
    /// The ground's albedo as a spectrum, in place of `ground_albedo`: a
    /// named one of [`spectrum_file::GROUND_SPECTRA`] (`grass`, `snow`,
    /// `sand`, `ocean`), or a CSV file `wavelength_nm,albedo` (relative to
    /// the scene file's folder).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub ground_albedo_spectrum: Option<String>,
    /// Ozone absorption (Chappuis and Huggins bands).
    pub ozone: bool,
    /// Total ozone column, Dobson units; `None` keeps the AFGL profile's own
    /// column (≈ 344 DU).
    pub ozone_du: Option<f64>,
    /// Aerosols (haze; Mars: dust).
    pub aerosols: bool,
    /// Multiplier of Elterman's aerosol profile (0 = none, 1 = standard).
    pub aerosol_amount: f64,
    /// Asymmetry parameter g of the aerosol phase function.
    pub aerosol_g: f64,
    /// Aerosol single-scattering albedo.
    pub aerosol_albedo: f64,
    /// The aerosols' phase-function model, with `aerosol_g`.
    pub aerosol_phase: aerosol::PhaseModel,
    /// The aerosol by its optical properties (`[atmosphere.aerosol]`); each
    /// key given takes the place of the flat key above it stands for.
    #[serde(skip_serializing_if = "AerosolOptics::is_unset")]
    pub aerosol: AerosolOptics,
    /// The gas's vertical profile from a CSV file
    /// ([`crate::physics::profile`]) in place of the planet's own (the
    /// U.S. Standard Atmosphere on Earth); a relative path is taken from
    /// the scene file's folder.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub profile: Option<PathBuf>,
    /// The planet (the scene's `[planet] preset`, copied here by
    /// [`crate::scene::Scene`]): its gas and its own profile.
    #[serde(skip)]
    pub planet: Planet,
}

impl Default for AtmosphereParams {
    fn default() -> Self {
        Self {
            planet_radius_m: EARTH_RADIUS_M,
            top_altitude_m: DEFAULT_ATMOSPHERE_TOP_M,
            ground_albedo: 0.3,
            ground_albedo_spectrum: None,
            ozone: true,
            ozone_du: None,
            aerosols: true,
            aerosol_amount: 1.0,
            aerosol_g: 0.7,
            aerosol_albedo: 0.9,
            aerosol_phase: aerosol::PhaseModel::HenyeyGreenstein,
            aerosol: AerosolOptics::default(),
            profile: None,
            planet: Planet::Earth,
        }
    }
}

impl AtmosphereParams {
    /// The atmosphere of `planet` with its own defaults: Earth's are
    /// [`Self::default`]; Mars's its radius, its top, CO₂ without ozone,
    /// its ground albedo and its dust ([`crate::physics::planet`]).
    pub fn for_planet(planet: Planet) -> Self {
        use crate::physics::planet::{mars_dust, MARS_GROUND_ALBEDO};
        match planet {
            Planet::Earth => Self::default(),
            Planet::Mars => Self {
                planet_radius_m: planet.radius_m(),
                top_altitude_m: planet.atmosphere_top_m(),
                ground_albedo: MARS_GROUND_ALBEDO,
                ozone: false,
                aerosol: AerosolOptics {
                    optical_depth_550: Some(mars_dust::OPTICAL_DEPTH_550),
                    angstrom_exponent: Some(mars_dust::ANGSTROM_EXPONENT),
                    single_scattering_albedo: Some(AlbedoSpectrum::Spectrum(
                        mars_dust::SINGLE_SCATTERING_ALBEDO.to_vec(),
                    )),
                    profile: Some(AerosolProfileKind::Exponential),
                    scale_height_m: Some(mars_dust::SCALE_HEIGHT_M),
                    phase: Some(AerosolPhaseKind::MarsDust),
                    ..AerosolOptics::default()
                },
                planet,
                ..Self::default()
            },
        }
    }

    /// The gas profile this atmosphere uses: the `profile` file's (read
    /// once per process), else the planet's own; `None`: the U.S. Standard
    /// Atmosphere. The error names the file, the line and the valid form.
    pub fn gas_profile(&self) -> Result<Option<Arc<VerticalProfile>>, SceneError> {
        match &self.profile {
            Some(path) => VerticalProfile::cached(path)
                .map(Some)
                .map_err(|e| SceneError::new("atmosphere.profile", e)),
            None => Ok(self.planet.profile().map(|p| Arc::new(p.clone()))),
        }
    }

    /// Checks the profile file, if any, and that `ozone_du` has an ozone
    /// profile to scale.
    pub fn validate_profile(&self) -> Result<(), SceneError> {
        let profile = self.gas_profile()?;
        if self.ozone {
            if let Some(p) = &profile {
                if !p.has_ozone() && self.planet != Planet::Earth {
                    return Err(SceneError::new(
                        "ozone",
                        format!(
                            "{} has no ozone profile: set ozone = false, or give a profile \
                             file with an ozone_m3 or ozone_vmr column",
                            self.planet.name()
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}

impl AtmosphereParams {
    /// The ground's albedo: the spectrum `ground_albedo_spectrum` names
    /// (built in, or read from its file), else `ground_albedo`.
    pub fn ground(&self) -> Result<GroundAlbedo, SceneError> {
        let Some(name) = &self.ground_albedo_spectrum else {
            return Ok(GroundAlbedo::Constant(self.ground_albedo));
        };
        if let Some(table) = spectrum_file::named_ground(name) {
            return Ok(GroundAlbedo::Spectrum(table));
        }
        let names: Vec<&str> = spectrum_file::GROUND_SPECTRA.iter().map(|s| s.0).collect();
        if !name.to_ascii_lowercase().ends_with(".csv") {
            return Err(SceneError::new(
                "atmosphere.ground_albedo_spectrum",
                format!(
                    "'{name}' is neither a named spectrum ({}) nor a .csv file",
                    names.join(", ")
                ),
            ));
        }
        Tabulated::cached(std::path::Path::new(name), Quantity::Albedo)
            .map(GroundAlbedo::Spectrum)
            .map_err(|e| SceneError::new("atmosphere.ground_albedo_spectrum", e))
    }

    /// `ground_albedo_spectrum` taken from folder `base` where it is a
    /// relative file path (not a named spectrum).
    pub fn resolve_ground_file(&mut self, base: &std::path::Path) {
        if let Some(name) = &mut self.ground_albedo_spectrum {
            let path = std::path::Path::new(name.as_str());
            if spectrum_file::named_ground(name).is_none() && path.is_relative() {
                *name = base.join(path).to_string_lossy().into_owned();
            }
        }
    }
}

impl AtmosphereParams {
    /// Whether the aerosol's amount, profile and spectrum are Elterman's
    /// with `aerosol_amount` (no key of `[atmosphere.aerosol]` changes them).
    fn aerosol_is_elterman(&self) -> bool {
        let a = &self.aerosol;
        a.optical_depth_550.is_none()
            && a.angstrom_exponent.is_none()
            && a.profile.unwrap_or_default() == AerosolProfileKind::Elterman
    }

    /// The aerosol extinction's profile and spectrum. Without the keys of
    /// `[atmosphere.aerosol]` that change them, Elterman's profile at 340 nm
    /// times `aerosol_amount`, as before they existed (to the bit). Else the
    /// profile's shape scaled so that its column from the ground to the top
    /// of the atmosphere at 550 nm is `optical_depth_550` (unset:
    /// `aerosol_amount` times Elterman's column there), times the Ångström
    /// law (unset: Elterman's spectrum relative to 550 nm).
    pub fn aerosol_column(&self) -> AerosolColumn {
        if self.aerosol_is_elterman() {
            return AerosolColumn {
                scale_height_m: None,
                scale: self.aerosol_amount,
                spectrum: AerosolSpectrum::Elterman340,
            };
        }
        let a = &self.aerosol;
        let top = self.top_altitude_m;
        let depth_550 = a.optical_depth_550.unwrap_or_else(|| {
            self.aerosol_amount
                * elterman_column_340nm(top)
                * aerosol::SpectralFactor::get().at(AEROSOL_REFERENCE_NM)
        });
        let spectrum = match a.angstrom_exponent {
            Some(exponent) => AerosolSpectrum::Angstrom { exponent },
            None => AerosolSpectrum::Elterman550,
        };
        let scale_height_m = match a.profile.unwrap_or_default() {
            AerosolProfileKind::Elterman => None,
            AerosolProfileKind::Exponential => Some(a.scale_height_m.unwrap_or(f64::NAN)),
        };
        // The shape's column from the ground to the top, in closed form.
        let shape_column = match scale_height_m {
            None => elterman_column_340nm(top),
            Some(h) => h * -(-top / h).exp_m1(),
        };
        AerosolColumn {
            scale_height_m,
            scale: depth_550 / shape_column,
            spectrum,
        }
    }

    /// Vertical aerosol optical depth from the ground to the top of the
    /// atmosphere at `wavelength_nm` (0 without aerosols): the column of
    /// [`Atmosphere::aerosol_extinction_per_m`], in closed form (Elterman's
    /// profile is piecewise linear, the other an exponential), without
    /// building an [`Atmosphere`].
    pub fn aerosol_optical_depth(&self, wavelength_nm: f64) -> f64 {
        if !self.aerosols {
            return 0.0;
        }
        if self.aerosol_is_elterman() {
            let column_340nm = elterman_column_340nm(self.top_altitude_m);
            return self.aerosol_amount
                * column_340nm
                * aerosol::SpectralFactor::get().at(wavelength_nm);
        }
        let column = self.aerosol_column();
        let depth_550 = match column.scale_height_m {
            None => column.scale * elterman_column_340nm(self.top_altitude_m),
            Some(h) => column.scale * h * -(-self.top_altitude_m / h).exp_m1(),
        };
        depth_550 * column.spectrum.factor(wavelength_nm)
    }

    /// The aerosol's single-scattering albedo: `[atmosphere.aerosol]
    /// single_scattering_albedo`, else `aerosol_albedo`.
    pub fn aerosol_albedo_spectrum(&self) -> AlbedoSpectrum {
        self.aerosol
            .single_scattering_albedo
            .clone()
            .unwrap_or(AlbedoSpectrum::Constant(self.aerosol_albedo))
    }

    /// [`Self::aerosol_albedo_spectrum`] at `wavelength_nm`.
    pub fn aerosol_single_scattering_albedo(&self, wavelength_nm: f64) -> f64 {
        self.aerosol_albedo_spectrum().at(wavelength_nm)
    }

    /// The aerosol's phase function: `[atmosphere.aerosol] phase` with its
    /// parameters, else `aerosol_phase` with `aerosol_g`. A table is read
    /// once per process ([`SpectralPhaseTable::cached`]); the error names the file,
    /// the line and the valid form.
    pub fn aerosol_phase_function(&self) -> Result<aerosol::PhaseFunction, SceneError> {
        use aerosol::PhaseFunction as F;
        let a = &self.aerosol;
        let g = a.asymmetry.unwrap_or(self.aerosol_g);
        let kind = a.phase.unwrap_or(match self.aerosol_phase {
            aerosol::PhaseModel::HenyeyGreenstein => AerosolPhaseKind::HenyeyGreenstein,
            aerosol::PhaseModel::CornetteShanks => AerosolPhaseKind::CornetteShanks,
        });
        let missing = |key: &str, what: &str| {
            SceneError::new(
                &format!("atmosphere.aerosol.{key}"),
                format!("phase = \"{what}\" needs {key}"),
            )
        };
        Ok(match kind {
            AerosolPhaseKind::HenyeyGreenstein => F::HenyeyGreenstein { g },
            AerosolPhaseKind::CornetteShanks => F::CornetteShanks { g },
            AerosolPhaseKind::DoubleHenyeyGreenstein => {
                let dhg = "double-henyey-greenstein";
                F::DoubleHenyeyGreenstein {
                    g1: a.g1.ok_or_else(|| missing("g1", dhg))?,
                    g2: a.g2.ok_or_else(|| missing("g2", dhg))?,
                    weight: a.weight.ok_or_else(|| missing("weight", dhg))?,
                }
            }
            AerosolPhaseKind::MarsDust => {
                F::Table(crate::physics::planet::mars_dust::phase_table())
            }
            AerosolPhaseKind::Table => {
                let path = a
                    .phase_file
                    .as_deref()
                    .ok_or_else(|| missing("phase_file", "table"))?;
                F::Table(
                    SpectralPhaseTable::cached(path)
                        .map_err(|e| SceneError::new("atmosphere.aerosol.phase_file", e))?,
                )
            }
        })
    }

    /// The aerosol phase function's mean cosine (asymmetry parameter); NaN
    /// where the phase function cannot be built (a scene not validated).
    pub fn aerosol_mean_cosine(&self) -> f64 {
        self.aerosol_phase_function()
            .map_or(f64::NAN, |p| p.mean_cosine())
    }

    /// Checks the aerosol's parameters, flat and `[atmosphere.aerosol]`:
    /// ranges, keys that belong together, a flat key and the table key
    /// that replaces it not both set, and the phase function file.
    pub fn validate_aerosol(&self) -> Result<(), SceneError> {
        check_range("aerosol amount", self.aerosol_amount, 0.0, 100.0)?;
        check_range("aerosol g", self.aerosol_g, -0.99, 0.99)?;
        check_range("aerosol albedo", self.aerosol_albedo, 0.0, 1.0)?;
        let a = &self.aerosol;
        let default = Self::default();
        // (table key given, flat key differs from its default, names).
        let replaced = [
            (
                a.optical_depth_550.is_some(),
                self.aerosol_amount != default.aerosol_amount,
                "optical_depth_550",
                "aerosol_amount",
            ),
            (
                a.single_scattering_albedo.is_some(),
                self.aerosol_albedo != default.aerosol_albedo,
                "single_scattering_albedo",
                "aerosol_albedo",
            ),
            (
                a.asymmetry.is_some(),
                self.aerosol_g != default.aerosol_g,
                "asymmetry",
                "aerosol_g",
            ),
            (
                a.phase.is_some(),
                self.aerosol_phase != default.aerosol_phase,
                "phase",
                "aerosol_phase",
            ),
        ];
        for (given, flat_set, key, flat) in replaced {
            if given && flat_set {
                return Err(SceneError::new(
                    &format!("atmosphere.aerosol.{key}"),
                    format!("replaces [atmosphere] {flat}: set one of them, not both"),
                ));
            }
        }
        if let Some(tau) = a.optical_depth_550 {
            check_range(
                "atmosphere.aerosol.optical_depth_550",
                tau,
                0.0,
                MAX_AEROSOL_OPTICAL_DEPTH,
            )?;
        }
        if let Some(alpha) = a.angstrom_exponent {
            let (lo, hi) = ANGSTROM_EXPONENT_RANGE;
            check_range("atmosphere.aerosol.angstrom_exponent", alpha, lo, hi).map_err(|e| {
                SceneError::new(
                    &e.parameter,
                    format!(
                        "{} (4 is Rayleigh's λ⁻⁴, the steepest any particle gives; \
                         coarse dust reaches about −0.5)",
                        e.message
                    ),
                )
            })?;
        }
        if let Some(albedo) = &a.single_scattering_albedo {
            albedo.validate("atmosphere.aerosol.single_scattering_albedo")?;
        }
        let exponential = a.profile == Some(AerosolProfileKind::Exponential);
        match (exponential, a.scale_height_m) {
            (true, None) => {
                return Err(SceneError::new(
                    "atmosphere.aerosol.scale_height_m",
                    "profile = \"exponential\" needs scale_height_m",
                ))
            }
            (false, Some(_)) => {
                return Err(SceneError::new(
                    "atmosphere.aerosol.scale_height_m",
                    "belongs to profile = \"exponential\" (valid profiles: elterman, exponential)",
                ))
            }
            (true, Some(h)) => {
                let (lo, hi) = SCALE_HEIGHT_RANGE_M;
                check_range("atmosphere.aerosol.scale_height_m", h, lo, hi)?;
            }
            (false, None) => {}
        }
        let kind = a.phase.unwrap_or(AerosolPhaseKind::HenyeyGreenstein);
        let belongs = [
            (
                "asymmetry",
                a.asymmetry,
                matches!(
                    kind,
                    AerosolPhaseKind::HenyeyGreenstein | AerosolPhaseKind::CornetteShanks
                ),
                "henyey-greenstein or cornette-shanks",
            ),
            (
                "g1",
                a.g1,
                kind == AerosolPhaseKind::DoubleHenyeyGreenstein,
                "double-henyey-greenstein",
            ),
            (
                "g2",
                a.g2,
                kind == AerosolPhaseKind::DoubleHenyeyGreenstein,
                "double-henyey-greenstein",
            ),
            (
                "weight",
                a.weight,
                kind == AerosolPhaseKind::DoubleHenyeyGreenstein,
                "double-henyey-greenstein",
            ),
        ];
        for (key, value, fits, phases) in belongs {
            let Some(value) = value else { continue };
            let parameter = format!("atmosphere.aerosol.{key}");
            if !fits {
                return Err(SceneError::new(
                    &parameter,
                    format!("belongs to phase = {phases}"),
                ));
            }
            if key == "weight" {
                check_range(&parameter, value, 0.0, 1.0)?;
            } else {
                check_range(&parameter, value, -0.99, 0.99)?;
            }
        }
        if a.phase_file.is_some() && kind != AerosolPhaseKind::Table {
            return Err(SceneError::new(
                "atmosphere.aerosol.phase_file",
                "belongs to phase = \"table\"",
            ));
        }
        self.aerosol_phase_function()?;
        Ok(())
    }
}

/// Optical properties of the atmosphere described by [`AtmosphereParams`].
#[derive(Clone, Debug)]
pub struct Atmosphere {
    /// The parameters the atmosphere was built from.
    pub params: AtmosphereParams,
    /// Factor applied to the AFGL ozone profile (target column / own column).
    ozone_scale: f64,
    /// The aerosol extinction's profile and spectrum.
    aerosol: AerosolColumn,
    /// The gas profile; `None`: the U.S. Standard Atmosphere.
    profile: Option<Arc<VerticalProfile>>,
}

/// Vertical optical depths from some altitude to the top of the atmosphere.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct OpticalDepth {
    /// Rayleigh scattering by the air.
    pub rayleigh: f64,
    /// Ozone absorption.
    pub ozone: f64,
    /// Aerosol extinction.
    pub aerosol: f64,
}

impl Atmosphere {
    /// The atmosphere of validated `params` (a profile file that cannot be
    /// read is a programming error here: [`crate::scene::Scene::validate`]
    /// reads it first, and it is read once per process).
    pub fn new(params: AtmosphereParams) -> Self {
        let profile = params
            .gas_profile()
            .expect("a validated scene's profile (Scene::validate reads it)");
        let mut atmosphere = Self {
            aerosol: params.aerosol_column(),
            params,
            ozone_scale: 1.0,
            profile,
        };
        atmosphere.ozone_scale = match (atmosphere.params.ozone, atmosphere.params.ozone_du) {
            (false, _) => 0.0,
            (true, None) => 1.0,
            (true, Some(du)) => du / atmosphere.base_ozone_column_du(),
        };
        atmosphere
    }

    /// Whether the gas comes from a profile (a file's or the planet's)
    /// rather than the U.S. Standard Atmosphere.
    pub fn has_gas_profile(&self) -> bool {
        self.profile.is_some()
    }

    /// The scattering gas.
    pub fn gas(&self) -> Gas {
        self.params.planet.gas()
    }

    /// The unscaled ozone profile: the profile file's ozone column if it has
    /// one, else the AFGL profile, m⁻³.
    fn base_ozone_m3(&self, altitude_m: f64) -> f64 {
        match self.profile.as_ref().and_then(|p| p.ozone_m3(altitude_m)) {
            Some(n) => n,
            None => ozone::Profile::get().number_density_m3(altitude_m),
        }
    }

    /// Column of [`Self::base_ozone_m3`] from the ground to the top, DU.
    fn base_ozone_column_du(&self) -> f64 {
        let top = self.params.top_altitude_m;
        match &self.profile {
            Some(p) if p.has_ozone() => {
                let mut column = 0.0;
                let mut lo = 0.0;
                while lo < top {
                    let hi = (lo + 500.0).min(top);
                    for (z, w) in crate::physics::quadrature::simpson(lo, hi, 50) {
                        column += w * self.base_ozone_m3(z);
                    }
                    lo = hi;
                }
                column / DOBSON_UNIT_PER_M2
            }
            _ => ozone::Profile::get().column_du(top),
        }
    }

    /// Temperature at `altitude_m`, K: the profile's where it gives one,
    /// else the U.S. Standard Atmosphere's.
    pub fn temperature_k(&self, altitude_m: f64) -> f64 {
        self.profile
            .as_ref()
            .and_then(|p| p.temperature_k(altitude_m))
            .unwrap_or_else(|| standard_atmosphere::air_state(altitude_m).temperature_k)
    }

    /// Radius of the top of the atmosphere, m.
    pub fn top_radius_m(&self) -> f64 {
        self.params.planet_radius_m + self.params.top_altitude_m
    }

    fn inside(&self, altitude_m: f64) -> bool {
        altitude_m <= self.params.top_altitude_m
    }

    /// Number density of the gas, m⁻³: the profile's, else the U.S.
    /// Standard Atmosphere 1976's; zero above the top of the model
    /// atmosphere.
    pub fn air_number_density_m3(&self, altitude_m: f64) -> f64 {
        if !self.inside(altitude_m) {
            return 0.0;
        }
        match &self.profile {
            Some(p) => p.number_density_m3(altitude_m),
            None => standard_atmosphere::air_state(altitude_m).number_density_m3,
        }
    }

    /// Ozone number density, m⁻³, scaled to the requested column.
    pub fn ozone_number_density_m3(&self, altitude_m: f64) -> f64 {
        if self.inside(altitude_m) && self.ozone_scale != 0.0 {
            self.ozone_scale * self.base_ozone_m3(altitude_m)
        } else {
            0.0
        }
    }

    /// Aerosol extinction at the reference wavelength, m⁻¹: 340 nm (times
    /// the aerosol amount) for Elterman's spectrum, else 550 nm
    /// ([`AtmosphereParams::aerosol_column`]).
    pub fn aerosol_reference_extinction_per_m(&self, altitude_m: f64) -> f64 {
        if self.params.aerosols && self.inside(altitude_m) {
            self.aerosol.reference_extinction_per_m(altitude_m)
        } else {
            0.0
        }
    }

    /// Aerosol extinction at `wavelength_nm` relative to the reference
    /// wavelength of [`Self::aerosol_reference_extinction_per_m`].
    pub fn aerosol_spectral_factor(&self, wavelength_nm: f64) -> f64 {
        self.aerosol.spectrum.factor(wavelength_nm)
    }

    /// Rayleigh scattering coefficient, m⁻¹.
    pub fn rayleigh_scattering_per_m(&self, altitude_m: f64, wavelength_nm: f64) -> f64 {
        self.gas().cross_section_m2(wavelength_nm) * self.air_number_density_m3(altitude_m)
    }

    /// Ozone absorption coefficient, m⁻¹, with the cross-section taken at the
    /// local temperature ([`Self::temperature_k`]).
    pub fn ozone_absorption_per_m(&self, altitude_m: f64, wavelength_nm: f64) -> f64 {
        let n = self.ozone_number_density_m3(altitude_m);
        if n == 0.0 {
            return 0.0;
        }
        let t = self.temperature_k(altitude_m);
        n * ozone::CrossSections::get().cross_section_m2(wavelength_nm, t)
    }

    /// Aerosol extinction coefficient, m⁻¹.
    pub fn aerosol_extinction_per_m(&self, altitude_m: f64, wavelength_nm: f64) -> f64 {
        self.aerosol_reference_extinction_per_m(altitude_m)
            * self.aerosol_spectral_factor(wavelength_nm)
    }

    /// Total ozone column of this atmosphere, Dobson units.
    pub fn ozone_column_du(&self) -> f64 {
        self.ozone_scale * self.base_ozone_column_du()
    }

    /// Vertical optical depths from `altitude_m` to the top, by Simpson's rule
    /// on a grid fine enough (≤ 10 m, and nodes at every table level) for
    /// < 10⁻⁵ relative error.
    pub fn vertical_optical_depth(&self, altitude_m: f64, wavelength_nm: f64) -> OpticalDepth {
        let top = self.params.top_altitude_m;
        let mut depth = OpticalDepth {
            rayleigh: 0.0,
            ozone: 0.0,
            aerosol: 0.0,
        };
        if altitude_m >= top {
            return depth;
        }
        // Integrate per 1 km slab so kinks of the tabulated profiles (at whole
        // kilometres and at the AFGL levels, all multiples of 500 m) fall on
        // slab edges.
        let mut lo = altitude_m;
        while lo < top {
            let hi = ((lo / 500.0).floor() * 500.0 + 500.0).min(top);
            for (z, w) in crate::physics::quadrature::simpson(lo, hi, 50) {
                depth.rayleigh += w * self.rayleigh_scattering_per_m(z, wavelength_nm);
                depth.ozone += w * self.ozone_absorption_per_m(z, wavelength_nm);
                depth.aerosol += w * self.aerosol_extinction_per_m(z, wavelength_nm);
            }
            lo = hi;
        }
        depth
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ozone_column_scales_to_the_requested_dobson_units() {
        let atmosphere = Atmosphere::new(AtmosphereParams {
            ozone_du: Some(300.0),
            ..AtmosphereParams::default()
        });
        assert!((atmosphere.ozone_column_du() - 300.0).abs() < 1e-6);
        let off = Atmosphere::new(AtmosphereParams {
            ozone: false,
            ..AtmosphereParams::default()
        });
        assert_eq!(off.ozone_absorption_per_m(25_000.0, 600.0), 0.0);
    }

    #[test]
    fn the_aerosol_column_in_closed_form_matches_the_numerical_one() {
        for params in [
            AtmosphereParams::default(),
            AtmosphereParams {
                aerosol_amount: 100.0,
                top_altitude_m: 20_000.0,
                ..AtmosphereParams::default()
            },
        ] {
            let numerical = Atmosphere::new(params.clone())
                .vertical_optical_depth(0.0, 550.0)
                .aerosol;
            let closed = params.aerosol_optical_depth(550.0);
            assert!(
                (closed / numerical - 1.0).abs() < 1e-5,
                "{closed} {numerical}"
            );
        }
        let none = AtmosphereParams {
            aerosols: false,
            ..AtmosphereParams::default()
        };
        assert_eq!(none.aerosol_optical_depth(550.0), 0.0);
    }

    #[test]
    fn the_aerosol_by_its_optical_depth_gives_that_column() {
        // τ₅₅₀ and the Ångström law over the column from the ground, by
        // either profile, against the numerical column of the coefficients.
        for (profile, scale_height_m) in [
            (None, None),
            (Some(AerosolProfileKind::Exponential), Some(1_500.0)),
        ] {
            let params = AtmosphereParams {
                aerosol: AerosolOptics {
                    optical_depth_550: Some(0.3),
                    angstrom_exponent: Some(1.1),
                    profile,
                    scale_height_m,
                    ..AerosolOptics::default()
                },
                ..AtmosphereParams::default()
            };
            params.validate_aerosol().unwrap();
            let atmosphere = Atmosphere::new(params.clone());
            for nm in [350.0, 550.0, 870.0] {
                let want = 0.3 * (nm / 550.0_f64).powf(-1.1);
                let closed = params.aerosol_optical_depth(nm);
                let numerical = atmosphere.vertical_optical_depth(0.0, nm).aerosol;
                assert!((closed / want - 1.0).abs() < 1e-12, "{closed} {want}");
                assert!((numerical / want - 1.0).abs() < 1e-5, "{numerical} {want}");
            }
        }
        // Only the spectrum changed: Elterman's profile with amount 2 keeps
        // its column at 550 nm.
        let elterman = AtmosphereParams {
            aerosol_amount: 2.0,
            ..AtmosphereParams::default()
        };
        let angstrom = AtmosphereParams {
            aerosol: AerosolOptics {
                angstrom_exponent: Some(0.0),
                ..AerosolOptics::default()
            },
            ..elterman.clone()
        };
        let (a, b) = (
            elterman.aerosol_optical_depth(550.0),
            angstrom.aerosol_optical_depth(550.0),
        );
        assert!((a / b - 1.0).abs() < 1e-12, "{a} {b}");
        assert_eq!(angstrom.aerosol_optical_depth(400.0), b);
    }

    #[test]
    fn without_the_new_keys_the_aerosol_is_computed_as_before() {
        // Bit for bit: amount × Elterman at 340 nm × the spectral factor.
        let params = AtmosphereParams {
            aerosol_amount: 3.0,
            ..AtmosphereParams::default()
        };
        let atmosphere = Atmosphere::new(params.clone());
        for z in [0.0, 750.0, 12_345.0] {
            let old = 3.0
                * aerosol::Profile::get().extinction_340nm_per_m(z)
                * aerosol::SpectralFactor::get().at(500.0);
            assert_eq!(atmosphere.aerosol_extinction_per_m(z, 500.0), old);
        }
        assert_eq!(
            params.aerosol_phase_function().unwrap(),
            aerosol::PhaseFunction::HenyeyGreenstein { g: 0.7 }
        );
        assert_eq!(params.aerosol_single_scattering_albedo(500.0), 0.9);
    }

    #[test]
    fn numerical_ozone_depth_matches_the_analytic_column() {
        // With a temperature-independent wavelength (where σ(T) varies little)
        // the optical depth ≈ column × σ; use the exact column at 1 nm steps.
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let column_m2 = atmosphere.ozone_column_du() * DOBSON_UNIT_PER_M2;
        let tau = atmosphere.vertical_optical_depth(0.0, 603.0).ozone;
        let xs = ozone::CrossSections::get();
        let (lo, hi) = (
            xs.cross_section_m2(603.0, 293.0),
            xs.cross_section_m2(603.0, 193.0),
        );
        let (lo, hi) = (lo.min(hi), lo.max(hi));
        assert!(
            tau >= column_m2 * lo * 0.999 && tau <= column_m2 * hi * 1.001,
            "{tau}"
        );
    }
}
