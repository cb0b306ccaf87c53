//! The model atmosphere: which constituents are present and how much of each,
//! and the resulting optical coefficients as pure functions of altitude and
//! wavelength.

use serde::{Deserialize, Serialize};

use crate::physics::{
    aerosol, ozone, rayleigh, standard_atmosphere, DEFAULT_ATMOSPHERE_TOP_M, DOBSON_UNIT_PER_M2,
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
    /// Lambertian ground albedo, 0–1.
    pub ground_albedo: f64,
    pub ozone: bool,
    /// Total ozone column, Dobson units; `None` keeps the AFGL profile's own
    /// column (≈ 344 DU).
    pub ozone_du: Option<f64>,
    pub aerosols: bool,
    /// Multiplier of Elterman's aerosol profile (0 = none, 1 = standard).
    pub aerosol_amount: f64,
    /// Asymmetry parameter g of the aerosol phase function.
    pub aerosol_g: f64,
    /// Aerosol single-scattering albedo.
    pub aerosol_albedo: f64,
    pub aerosol_phase: aerosol::PhaseModel,
}

impl Default for AtmosphereParams {
    fn default() -> Self {
        Self {
            planet_radius_m: EARTH_RADIUS_M,
            top_altitude_m: DEFAULT_ATMOSPHERE_TOP_M,
            ground_albedo: 0.3,
            ozone: true,
            ozone_du: None,
            aerosols: true,
            aerosol_amount: 1.0,
            aerosol_g: 0.7,
            aerosol_albedo: 0.9,
            aerosol_phase: aerosol::PhaseModel::HenyeyGreenstein,
        }
    }
}

impl AtmosphereParams {
    /// Vertical aerosol optical depth from the ground to the top of the
    /// atmosphere at `wavelength_nm` (0 without aerosols): the column of
    /// [`Atmosphere::aerosol_extinction_per_m`], in closed form (Elterman's
    /// profile is piecewise linear), without building an [`Atmosphere`].
    pub fn aerosol_optical_depth(&self, wavelength_nm: f64) -> f64 {
        if !self.aerosols {
            return 0.0;
        }
        let profile = aerosol::Profile::get();
        let column_340nm =
            profile.optical_depth_340nm(0.0) - profile.optical_depth_340nm(self.top_altitude_m);
        self.aerosol_amount * column_340nm * aerosol::SpectralFactor::get().at(wavelength_nm)
    }
}

/// Optical properties of the atmosphere described by [`AtmosphereParams`].
#[derive(Clone, Debug)]
pub struct Atmosphere {
    pub params: AtmosphereParams,
    /// Factor applied to the AFGL ozone profile (target column / own column).
    ozone_scale: f64,
}

/// Vertical optical depths from some altitude to the top of the atmosphere.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct OpticalDepth {
    pub rayleigh: f64,
    pub ozone: f64,
    pub aerosol: f64,
}

impl Atmosphere {
    pub fn new(params: AtmosphereParams) -> Self {
        let own_du = ozone::Profile::get().column_du(params.top_altitude_m);
        let ozone_scale = match (params.ozone, params.ozone_du) {
            (false, _) => 0.0,
            (true, None) => 1.0,
            (true, Some(du)) => du / own_du,
        };
        Self {
            params,
            ozone_scale,
        }
    }

    /// Radius of the top of the atmosphere, m.
    pub fn top_radius_m(&self) -> f64 {
        self.params.planet_radius_m + self.params.top_altitude_m
    }

    fn inside(&self, altitude_m: f64) -> bool {
        altitude_m <= self.params.top_altitude_m
    }

    /// Number density of air, m⁻³ (U.S. Standard Atmosphere 1976; zero above
    /// the top of the model atmosphere).
    pub fn air_number_density_m3(&self, altitude_m: f64) -> f64 {
        if self.inside(altitude_m) {
            standard_atmosphere::air_state(altitude_m).number_density_m3
        } else {
            0.0
        }
    }

    /// Ozone number density, m⁻³, scaled to the requested column.
    pub fn ozone_number_density_m3(&self, altitude_m: f64) -> f64 {
        if self.inside(altitude_m) {
            self.ozone_scale * ozone::Profile::get().number_density_m3(altitude_m)
        } else {
            0.0
        }
    }

    /// Aerosol extinction at 340 nm, m⁻¹, scaled by the aerosol amount.
    pub fn aerosol_extinction_340nm_per_m(&self, altitude_m: f64) -> f64 {
        if self.params.aerosols && self.inside(altitude_m) {
            self.params.aerosol_amount * aerosol::Profile::get().extinction_340nm_per_m(altitude_m)
        } else {
            0.0
        }
    }

    /// Rayleigh scattering coefficient, m⁻¹.
    pub fn rayleigh_scattering_per_m(&self, altitude_m: f64, wavelength_nm: f64) -> f64 {
        rayleigh::cross_section_m2(wavelength_nm) * self.air_number_density_m3(altitude_m)
    }

    /// Ozone absorption coefficient, m⁻¹, with the cross-section taken at the
    /// local temperature of the standard atmosphere.
    pub fn ozone_absorption_per_m(&self, altitude_m: f64, wavelength_nm: f64) -> f64 {
        let n = self.ozone_number_density_m3(altitude_m);
        if n == 0.0 {
            return 0.0;
        }
        let t = standard_atmosphere::air_state(altitude_m).temperature_k;
        n * ozone::CrossSections::get().cross_section_m2(wavelength_nm, t)
    }

    /// Aerosol extinction coefficient, m⁻¹.
    pub fn aerosol_extinction_per_m(&self, altitude_m: f64, wavelength_nm: f64) -> f64 {
        self.aerosol_extinction_340nm_per_m(altitude_m)
            * aerosol::SpectralFactor::get().at(wavelength_nm)
    }

    /// Total ozone column of this atmosphere, Dobson units.
    pub fn ozone_column_du(&self) -> f64 {
        self.ozone_scale * ozone::Profile::get().column_m2(0.0, self.params.top_altitude_m)
            / DOBSON_UNIT_PER_M2
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
