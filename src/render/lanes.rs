//! The wavelengths a path carries: the Sun that lights them
//! ([`SolarSource`]), each lane's constants (cross-sections, the aerosol's
//! and the ground's spectra, the disc's limb darkening), and the table that
//! makes building a path's [`SpectralLanes`] a few interpolations.

use std::sync::Arc;

use super::medium::{Lanes, Medium, SpectralLanes, LANES, SHELL_SLOTS};
use crate::physics::spectrum_file::Tabulated;
use crate::physics::{ozone, sun};

/// The per-wavelength constants of one lane, in the order of
/// [`LaneTable`]'s rows: Rayleigh cross-section (m²), Rayleigh phase γ,
/// aerosol factor, solar irradiance, aerosol single-scattering albedo,
/// ground albedo, the disc's limb-darkening coefficients
/// ([`sun::radiance_over_mean`], linear in them, so interpolating keeps
/// the disc's mean at 1), then the ozone cross-section (m²) at the 11
/// tabulated temperatures.
type LaneConstants = [f64; OZONE_CONSTANTS + 11];
/// Index of the first limb-darkening coefficient in [`LaneConstants`].
const LIMB_CONSTANTS: usize = 6;
/// Index of the first ozone cross-section in [`LaneConstants`].
const OZONE_CONSTANTS: usize = LIMB_CONSTANTS + sun::LIMB_COEFFICIENTS;

/// The Sun the lanes carry: its spectral irradiance at the top of the
/// atmosphere and whether its disc is limb-darkened.
#[derive(Clone, Debug, PartialEq)]
pub struct SolarSource {
    irradiance: SolarIrradiance,
    /// Whether the disc is limb-darkened ([`sun::radiance_over_mean`]).
    pub limb_darkening: bool,
}

/// The solar spectral irradiance of a [`SolarSource`].
#[derive(Clone, Debug, PartialEq)]
enum SolarIrradiance {
    /// 1 W m⁻² nm⁻¹ at every wavelength (`unit_sun`).
    Unit,
    /// A spectrum at 1 AU times `scale`: 1/d² at d AU, since the
    /// irradiance falls with the square of the distance.
    Measured {
        /// Factor on the 1 AU spectrum.
        scale: f64,
        /// The spectrum from a file (`[sun] spectrum`); `None`, the
        /// built-in ASTM E-490 table.
        file: Option<Arc<sun::Spectrum>>,
    },
}

impl SolarSource {
    /// Unit, or the measured spectrum at 1 AU; a uniform disc.
    pub fn from_unit_sun(unit_sun: bool) -> Self {
        Self::at_distance(unit_sun, 1.0)
    }

    /// Unit, or the measured spectrum at `distance_au`; a uniform disc.
    pub fn at_distance(unit_sun: bool, distance_au: f64) -> Self {
        let irradiance = if unit_sun {
            SolarIrradiance::Unit
        } else {
            SolarIrradiance::Measured {
                scale: (distance_au * distance_au).recip(),
                file: None,
            }
        };
        Self {
            irradiance,
            limb_darkening: false,
        }
    }

    /// The same source with the spectrum of `table` (W m⁻² nm⁻¹ at 1 AU)
    /// in place of the built-in one (a unit sun stays unit).
    #[must_use]
    pub fn with_spectrum(mut self, table: Option<&Tabulated>) -> Self {
        if let (SolarIrradiance::Measured { file, .. }, Some(table)) = (&mut self.irradiance, table)
        {
            *file = Some(Arc::new(sun::Spectrum::from_tabulated(table)));
        }
        self
    }

    /// The same source with a limb-darkened (`true`) or uniform disc.
    #[must_use]
    pub fn with_limb_darkening(mut self, darkened: bool) -> Self {
        self.limb_darkening = darkened;
        self
    }

    fn irradiance_w_m2_nm(&self, wavelength_nm: f64) -> f64 {
        match &self.irradiance {
            SolarIrradiance::Unit => 1.0,
            SolarIrradiance::Measured { scale, file } => {
                let spectrum = file.as_deref().unwrap_or_else(|| sun::Spectrum::get());
                let e = spectrum.irradiance_w_m2_nm(wavelength_nm);
                // At 1 AU exactly the table's own value, bit for bit.
                if *scale == 1.0 {
                    e
                } else {
                    scale * e
                }
            }
        }
    }
}

fn lane_constants(wavelength_nm: f64, medium: &Medium, source: &SolarSource) -> LaneConstants {
    let mut c = [0.0; OZONE_CONSTANTS + 11];
    c[0] = medium.gas.cross_section_m2(wavelength_nm);
    c[1] = medium.gas.phase_gamma(wavelength_nm);
    c[2] = medium.aerosol_spectrum.factor(wavelength_nm);
    c[3] = source.irradiance_w_m2_nm(wavelength_nm);
    c[4] = medium.aerosol_albedo.at(wavelength_nm);
    c[5] = medium.ground.at(wavelength_nm);
    c[LIMB_CONSTANTS..OZONE_CONSTANTS].copy_from_slice(&sun::radiance_over_mean(
        wavelength_nm,
        source.limb_darkening,
    ));
    if medium.ozone_on {
        c[OZONE_CONSTANTS..]
            .copy_from_slice(&ozone::CrossSections::get().at_wavelength(wavelength_nm));
    }
    c
}

/// The per-wavelength constants tabulated at a fine step over a wavelength
/// range, so that a path's lanes cost a few interpolations instead of
/// binary-searched table look-ups and the refractive-index formula. The step
/// (0.25 nm) divides the 1 nm of the data, whose tables are piecewise
/// linear, and the table (~220 KB) stays in cache; interpolating it
/// reproduces the direct computation to better than 1e-5 relative (tested;
/// ~1.3e-6, from the Rayleigh formula's curvature); a wavelength outside the range
/// falls back to the direct computation.
pub struct LaneTable {
    first_nm: f64,
    step_nm: f64,
    rows: Vec<LaneConstants>,
    source: SolarSource,
}

impl LaneTable {
    const STEP_NM: f64 = 0.25;

    /// The table over `from_nm`–`to_nm` for the sun `source`.
    pub fn new(medium: &Medium, (from_nm, to_nm): (f64, f64), source: SolarSource) -> Self {
        let count = ((to_nm - from_nm) / Self::STEP_NM).ceil() as usize + 1;
        Self {
            first_nm: from_nm,
            step_nm: Self::STEP_NM,
            rows: (0..count)
                .map(|i| lane_constants(from_nm + i as f64 * Self::STEP_NM, medium, &source))
                .collect(),
            source,
        }
    }

    fn constants(&self, wavelength_nm: f64, medium: &Medium) -> LaneConstants {
        let x = (wavelength_nm - self.first_nm) / self.step_nm;
        if !(x >= 0.0 && x < (self.rows.len() - 1) as f64) {
            return lane_constants(wavelength_nm, medium, &self.source);
        }
        let i = x as usize;
        let f = x - i as f64;
        let (a, b) = (&self.rows[i], &self.rows[i + 1]);
        std::array::from_fn(|k| a[k] + f * (b[k] - a[k]))
    }

    /// The wavelengths the table covers, nm.
    pub fn range_nm(&self) -> (f64, f64) {
        let last = self.rows.len().saturating_sub(1);
        (self.first_nm, self.first_nm + last as f64 * self.step_nm)
    }

    /// The lanes for `wavelengths_nm`, as [`SpectralLanes::new`] would build them.
    pub fn lanes(&self, wavelengths_nm: Lanes, active: usize, medium: &Medium) -> SpectralLanes {
        SpectralLanes::from_constants(
            wavelengths_nm,
            active,
            medium,
            &wavelengths_nm.0.map(|w| self.constants(w, medium)),
        )
    }
}

impl SpectralLanes {
    /// The lanes for `wavelengths_nm`, `active` of them distinct, with the measured sun or (`unit_sun`) unit irradiance.
    pub fn new(
        wavelengths_nm: impl Into<Lanes>,
        active: usize,
        medium: &Medium,
        unit_sun: bool,
    ) -> Self {
        let wavelengths_nm = wavelengths_nm.into();
        Self::with_source(
            wavelengths_nm,
            active,
            medium,
            &SolarSource::from_unit_sun(unit_sun),
        )
    }

    /// [`Self::new`] with the sun's irradiance from `source`.
    pub fn with_source(
        wavelengths_nm: Lanes,
        active: usize,
        medium: &Medium,
        source: &SolarSource,
    ) -> Self {
        Self::from_constants(
            wavelengths_nm,
            active,
            medium,
            &wavelengths_nm.0.map(|w| lane_constants(w, medium, source)),
        )
    }

    pub(super) fn from_constants(
        wavelengths_nm: Lanes,
        active: usize,
        medium: &Medium,
        constants: &[LaneConstants; LANES],
    ) -> Self {
        let mut lanes = Self {
            majorants: [0.0; SHELL_SLOTS],
            residuals: [0.0; SHELL_SLOTS],
            wavelengths_nm,
            active,
            rayleigh_m2: Lanes::splat(0.0),
            rayleigh_gamma: Lanes::splat(0.0),
            ozone_max_m2: Lanes::splat(0.0),
            ozone_min_m2: Lanes::splat(0.0),
            ozone_m2: [[0.0; 11]; LANES],
            aerosol_factor: Lanes::splat(0.0),
            aerosol_albedo: Lanes::splat(0.0),
            sun_irradiance: Lanes::splat(0.0),
            ground_albedo: Lanes::splat(0.0),
            limb: [[0.0; sun::LIMB_COEFFICIENTS]; LANES],
        };
        for (j, c) in constants.iter().enumerate() {
            lanes.rayleigh_m2[j] = c[0];
            lanes.rayleigh_gamma[j] = c[1];
            lanes.aerosol_factor[j] = c[2];
            lanes.sun_irradiance[j] = c[3];
            lanes.aerosol_albedo[j] = c[4];
            lanes.ground_albedo[j] = c[5];
            lanes.limb[j].copy_from_slice(&c[LIMB_CONSTANTS..OZONE_CONSTANTS]);
            let ozone = &c[OZONE_CONSTANTS..];
            lanes.ozone_m2[j].copy_from_slice(ozone);
            lanes.ozone_max_m2[j] = ozone.iter().copied().fold(0.0, f64::max);
            lanes.ozone_min_m2[j] = ozone.iter().copied().fold(f64::INFINITY, f64::min);
        }
        let constants: [[f64; 4]; LANES] = std::array::from_fn(|j| {
            let j = if j < active { j } else { 0 };
            [
                lanes.rayleigh_m2[j],
                lanes.ozone_max_m2[j],
                lanes.ozone_min_m2[j],
                lanes.aerosol_factor[j],
            ]
        });
        (lanes.majorants, lanes.residuals) = medium.shell_terms.extinction(&constants);
        lanes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::rng::Rng;

    #[test]
    fn lane_table_reproduces_the_direct_constants() {
        let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
        let table = LaneTable::new(&medium, (360.0, 830.0), SolarSource::from_unit_sun(false));
        let mut rng = Rng::new(3, 4);
        let mut worst = 0.0_f64;
        for _ in 0..2_000 {
            let w: Lanes = Lanes::from_fn(|_| 360.0 + 470.0 * rng.uniform());
            let a = table.lanes(w, LANES, &medium);
            let b = SpectralLanes::new(w, LANES, &medium, false);
            for j in 0..LANES {
                let pairs = [
                    (a.rayleigh_m2[j], b.rayleigh_m2[j]),
                    (a.rayleigh_gamma[j], b.rayleigh_gamma[j]),
                    (a.aerosol_factor[j], b.aerosol_factor[j]),
                    (a.sun_irradiance[j], b.sun_irradiance[j]),
                    (a.ozone_m2[j][0], b.ozone_m2[j][0]),
                    (a.ozone_m2[j][10], b.ozone_m2[j][10]),
                ];
                for (x, y) in pairs {
                    worst = worst.max((x - y).abs() / y.abs().max(1e-300));
                }
            }
        }
        assert!(worst < 1e-5, "worst relative difference {worst:e}");
        // Outside the table: the direct computation.
        let out = table.lanes(Lanes::splat(1000.0), 1, &medium);
        let direct = SpectralLanes::new(Lanes::splat(1000.0), 1, &medium, false);
        assert_eq!(out.rayleigh_m2, direct.rayleigh_m2);
    }
}
