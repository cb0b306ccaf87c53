//! The planet under the atmosphere, as data: its radius, the top of its
//! atmosphere, the gas that scatters, the gas's vertical profile and the
//! Sun's distance.
//!
//! **Earth** is the renderer's original model: radius 6 371 km, the U.S.
//! Standard Atmosphere 1976 of air to 100 km.
//!
//! **Mars** (sources beside each constant):
//! - radius 3 389.5 km, the volumetric mean radius of NASA's Mars Fact
//!   Sheet (Williams, NSSDCA);
//! - the gas: CO₂, whose Rayleigh cross-section and depolarisation are
//!   Sneep & Ubachs (2005) ([`super::rayleigh::co2`]); Mars's air is
//!   95 % CO₂ (Fact Sheet), and the rest (N₂, Ar) is counted as CO₂;
//! - the temperature and pressure profile: the Mars-GRAM 2005 auxiliary
//!   profile of Justus, Duvall & Keller (2005), Table 1 (the average of 17
//!   MGS TES limb profiles at the Phoenix landing conditions), from its
//!   first level (2.172 km) to its last (57.546 km) in `data/`; its
//!   altitudes are taken from its first level as the ground, and its
//!   pressures scaled by 610 Pa over the first level's 475.13 Pa: 610 Pa is
//!   the reference surface pressure of the Mars Climate Database (its dust
//!   columns are "normalized at reference pressure of 610 Pa"). Scaling
//!   every pressure by one factor keeps the profile in hydrostatic balance
//!   (it moves the ground down by H ln(610/475) ≈ 2.8 km at H ≈ 11 km);
//! - the atmosphere's top is the profile's last level, 55.374 km above the
//!   ground, where the pressure is 0.92 Pa (0.15 % of the ground's): the
//!   CO₂ above it scatters 2 × 10⁻⁵ of the vertical light at 400 nm, and the
//!   dust at an 11 km scale height holds 0.6 % of its column above it;
//! - no ozone (Mars's column is ~1 µm-atm, about 0.1 DU, Fact Sheet trace
//!   gases; its Hartley band lies below the renderer's 360 nm);
//! - the Sun at Mars's mean distance, 1.524 AU (semi-major axis
//!   227.956 × 10⁶ km, Fact Sheet).
//!
//! The dust is the aerosol of a Mars scene ([`mars_dust`]).

use std::fmt::Write as _;
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};

use super::profile::VerticalProfile;
use super::rayleigh::Gas;
use super::{DEFAULT_ATMOSPHERE_TOP_M, EARTH_RADIUS_M};

/// Mars's volumetric mean radius, m (NASA Mars Fact Sheet: 3 389.5 km).
pub const MARS_RADIUS_M: f64 = 3_389_500.0;
/// Mars's semi-major axis, AU (Fact Sheet: 227.956 × 10⁶ km / 149.598 ×
/// 10⁶ km).
pub const MARS_DISTANCE_AU: f64 = 1.524;
/// Ground pressure the Mars profile is scaled to, Pa (the Mars Climate
/// Database's reference pressure of its dust columns).
pub const MARS_SURFACE_PRESSURE_PA: f64 = 610.0;
/// Mars's Bond albedo (Fact Sheet: 0.250), the default ground albedo of a
/// Mars scene.
pub const MARS_GROUND_ALBEDO: f64 = 0.25;

/// Mars's suspended dust, by its optical properties (the keys of
/// `[atmosphere.aerosol]` a Mars scene gets where it does not set them).
pub mod mars_dust {
    use std::sync::{Arc, OnceLock};

    use num_complex::Complex64;

    use crate::physics::mie::{population, GammaSizes, PopulationOptics};
    use crate::physics::spectral_phase::SpectralPhaseTable;

    /// Visible vertical optical depth: 0.5, typical by day outside the
    /// dust-storm season (the Mars Climate Database's annual global mean
    /// is 0.375, its seasonal range 0.20–0.76; Montabone et al. 2015,
    /// 2020).
    pub const OPTICAL_DEPTH_550: f64 = 0.5;
    /// Ångström exponent: 0, grey. The dust's extinction efficiency varies
    /// by ±3 % over 600–880 nm for its 1.5 µm particles (Wolff et al.
    /// 2009, as tabulated for the Mars Climate Database).
    pub const ANGSTROM_EXPONENT: f64 = 0.0;
    /// Scale height of the dust, m: mixed with the gas (11.1 km, Fact
    /// Sheet); Vincendon & Langevin (2010, Icarus 207, 923) find 6–12 km
    /// depending on season.
    pub const SCALE_HEIGHT_M: f64 = 11_100.0;
    /// Single-scattering albedo, `[wavelength_nm, albedo]`: Wolff et al.
    /// (2009, J. Geophys. Res. 114, E00D04) dust for r_eff = 1.5 µm as the
    /// Mars Climate Database tabulates it (LMD `optprop_dustvis_TM.dat`):
    /// 0.73 at 388 nm, 0.967 at 650 nm, 0.975 at 700 nm — absorbing in the
    /// blue. Constant beyond the end pairs.
    pub const SINGLE_SCATTERING_ALBEDO: [[f64; 2]; 3] =
        [[388.0, 0.73], [650.0, 0.967], [700.0, 0.975]];
    /// Double Henyey–Greenstein fitted to sky radiance in the solar
    /// almucantar by the Curiosity rover's cameras at 650 nm (Chen-Chen,
    /// Pérez-Hoyos & Sánchez-Lavega 2019, Icarus 330, 16): g₁ = 0.889,
    /// g₂ = 0.094, weight 0.743, mean cosine 0.685 (their §4: 0.687 ±
    /// 0.081). The measured reference the dust's phase table is checked
    /// against; it is one wavelength's, so the table is what renders.
    pub const G1: f64 = 0.889;
    /// See [`G1`].
    pub const G2: f64 = 0.094;
    /// See [`G1`].
    pub const WEIGHT: f64 = 0.743;
    /// The measured mean cosine's standard error at 650 nm (Chen-Chen et
    /// al. 2019, §4).
    pub const MEAN_COSINE_ERROR: f64 = 0.081;

    /// Effective radius of the dust's size distribution, µm, and its
    /// effective variance: Wolff et al. (2009), the Mars Climate
    /// Database's dust (r_eff = 1.5 µm, v_eff = 0.3, a gamma
    /// distribution).
    pub const SIZES: GammaSizes = GammaSizes {
        effective_radius_um: 1.5,
        effective_variance: 0.3,
    };

    /// Wavelengths of the phase table's blocks, nm: 360 to 840 every 20.
    pub fn table_wavelengths_nm() -> impl Iterator<Item = f64> {
        (0..25).map(|i| 360.0 + 20.0 * f64::from(i))
    }

    /// Scattering angles of the phase table's rows, degrees: every 0.25°
    /// to 10° (the forward peak, about λ/(2r) ≈ 7° wide in the red and
    /// 4° in the blue), every 0.5° to 30°, every degree to 180°.
    pub fn table_angles_deg() -> Vec<f64> {
        let mut angles: Vec<f64> = (0..40).map(|i| 0.25 * f64::from(i)).collect();
        angles.extend((0..40).map(|i| 10.0 + 0.5 * f64::from(i)));
        angles.extend((0..=150).map(|i| 30.0 + f64::from(i)));
        angles
    }

    /// The dust's refractive index at `wavelength_nm`: Wolff's
    /// (`data/mars_dust_refractive_index_wolff.csv`), linear in wavelength
    /// between rows, the end rows beyond them.
    pub fn refractive_index(wavelength_nm: f64) -> Complex64 {
        let table = crate::data::Table::parse(crate::data::MARS_DUST_REFRACTIVE_INDEX);
        let (w, n, k) = (
            table.column("wavelength_nm"),
            table.column("n"),
            table.column("k"),
        );
        let last = w.len() - 1;
        let x = wavelength_nm.clamp(w[0], w[last]);
        let i = w.partition_point(|&v| v <= x).clamp(1, last) - 1;
        let t = (x - w[i]) / (w[i + 1] - w[i]);
        Complex64::new(n[i] + t * (n[i + 1] - n[i]), k[i] + t * (k[i + 1] - k[i]))
    }

    /// The dust's phase function at `wavelength_nm` at `angles_deg`, by
    /// Lorenz–Mie theory for spheres of [`SIZES`] and
    /// [`refractive_index`] ([`crate::physics::mie::population`], size
    /// step 0.1 in size parameter): how `data/mars_dust_phase_mie.csv`
    /// is made (`cargo run --release --example mars_dust_phase`).
    pub fn mie_phase(wavelength_nm: f64, angles_deg: &[f64]) -> PopulationOptics {
        let mu: Vec<f64> = angles_deg.iter().map(|a| a.to_radians().cos()).collect();
        population(
            &SIZES,
            refractive_index(wavelength_nm),
            wavelength_nm,
            &mu,
            0.1,
        )
    }

    /// The dust's phase function over wavelength: the embedded
    /// `data/mars_dust_phase_mie.csv` (`phase = "mars-dust"`).
    pub fn phase_table() -> Arc<SpectralPhaseTable> {
        static TABLE: OnceLock<Arc<SpectralPhaseTable>> = OnceLock::new();
        TABLE
            .get_or_init(|| {
                Arc::new(
                    SpectralPhaseTable::parse(crate::data::MARS_DUST_PHASE)
                        .expect("the embedded Mars dust phase table parses"),
                )
            })
            .clone()
    }
}

/// Planets by name (`[planet] preset`, `--planet`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum Planet {
    /// The Earth: air, the U.S. Standard Atmosphere.
    #[default]
    Earth,
    /// Mars: CO₂, a TES temperature profile, dust.
    Mars,
}

impl Planet {
    /// Every planet, in the order the app lists them.
    pub const ALL: [Planet; 2] = [Self::Earth, Self::Mars];

    /// The planet's name as scenes and the command line spell it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Earth => "earth",
            Self::Mars => "mars",
        }
    }

    /// The planet named `name` (any case); `Err` lists the valid names.
    pub fn parse(name: &str) -> Result<Self, String> {
        Self::ALL
            .into_iter()
            .find(|p| p.name().eq_ignore_ascii_case(name))
            .ok_or_else(|| format!("unknown planet '{name}' (valid: earth, mars)"))
    }

    /// The scattering gas.
    pub fn gas(self) -> Gas {
        match self {
            Self::Earth => Gas::Air,
            Self::Mars => Gas::CarbonDioxide,
        }
    }

    /// Radius, m.
    pub fn radius_m(self) -> f64 {
        match self {
            Self::Earth => EARTH_RADIUS_M,
            Self::Mars => MARS_RADIUS_M,
        }
    }

    /// Top of the atmosphere above the ground, m.
    pub fn atmosphere_top_m(self) -> f64 {
        match self {
            Self::Earth => DEFAULT_ATMOSPHERE_TOP_M,
            Self::Mars => mars_profile().top_m(),
        }
    }

    /// The Sun's distance, AU, where it is not 1.
    pub fn sun_distance_au(self) -> Option<f64> {
        match self {
            Self::Earth => None,
            Self::Mars => Some(MARS_DISTANCE_AU),
        }
    }

    /// The planet's own gas profile; `None`: the U.S. Standard Atmosphere.
    pub fn profile(self) -> Option<&'static VerticalProfile> {
        match self {
            Self::Earth => None,
            Self::Mars => Some(mars_profile()),
        }
    }
}

/// The Mars profile of `data/mars_tes_phoenix_justus2005.csv`, rebased and
/// scaled as the module docs say.
pub fn mars_profile() -> &'static VerticalProfile {
    static PROFILE: OnceLock<VerticalProfile> = OnceLock::new();
    PROFILE.get_or_init(|| {
        let table = crate::data::Table::parse(crate::data::MARS_PROFILE);
        let altitude_km = table.column("altitude_km");
        let temperature_k = table.column("temperature_K");
        let pressure_pa = table.column("pressure_Pa");
        let scale = MARS_SURFACE_PRESSURE_PA / pressure_pa[0];
        let mut text = String::from("altitude_m,temperature_k,pressure_pa\n");
        for ((z, t), p) in altitude_km.iter().zip(&temperature_k).zip(&pressure_pa) {
            let z_m = ((z - altitude_km[0]) * 1000.0).max(0.0);
            writeln!(text, "{z_m},{t},{}", p * scale).expect("writing to a String");
        }
        VerticalProfile::parse(&text).expect("the embedded Mars profile parses")
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The embedded dust table is what [`mars_dust::mie_phase`] computes
    /// (every fifth row of three wavelengths, to the 8 digits printed), so
    /// the data file cannot drift from the code and its sources; and its
    /// asymmetry parameter at 650 nm lies within the standard error of the
    /// one measured from Curiosity (0.687 ± 0.081, Chen-Chen et al. 2019).
    #[test]
    fn the_dust_table_is_the_mie_computation() {
        let text = crate::data::MARS_DUST_PHASE;
        let angles = mars_dust::table_angles_deg();
        let some: Vec<f64> = angles.iter().step_by(5).copied().collect();
        for wavelength in [360.0, 560.0, 840.0] {
            let optics = mars_dust::mie_phase(wavelength, &some);
            for (angle, phase) in some.iter().zip(&optics.phase) {
                let row = text
                    .lines()
                    .find(|l| {
                        l.starts_with(&format!("{angle},"))
                            && l.ends_with(&format!(",{wavelength}"))
                    })
                    .unwrap_or_else(|| panic!("no row {angle}° at {wavelength} nm"));
                let stored: f64 = row.split(',').nth(1).unwrap().parse().unwrap();
                assert!(
                    (stored / phase - 1.0).abs() < 1e-7,
                    "{angle}° at {wavelength} nm: stored {stored}, computed {phase}"
                );
            }
        }
        let table = mars_dust::phase_table();
        assert_eq!(table.node_wavelengths_nm().len(), 25);
        let g_650: f64 = table.legendre_moments::<2>(650.0)[1];
        let measured =
            mars_dust::WEIGHT * mars_dust::G1 + (1.0 - mars_dust::WEIGHT) * mars_dust::G2;
        assert!(
            (g_650 - measured).abs() < mars_dust::MEAN_COSINE_ERROR,
            "g at 650 nm: table {g_650}, measured {measured}"
        );
        // The forward peak narrows toward the blue: more of the light
        // within 3° at 440 nm than at 700 nm, less at 10°.
        let forward = |w: f64, deg: f64| table.eval(deg.to_radians().cos(), w);
        assert!(forward(440.0, 2.0) > 2.0 * forward(700.0, 2.0));
        assert!(forward(440.0, 10.0) < forward(700.0, 10.0));
    }

    #[test]
    fn the_mars_profile_starts_at_610_pa() {
        let p = mars_profile();
        let n0 = MARS_SURFACE_PRESSURE_PA / (super::super::profile::BOLTZMANN_J_PER_K * 209.39);
        assert!((p.number_density_m3(0.0) / n0 - 1.0).abs() < 1e-12);
        assert!((p.top_m() - 55_374.0).abs() < 1e-6, "{}", p.top_m());
        // Column ≈ p / (m g): 610 Pa / (43.34 u × 3.71 m s⁻²) within the
        // few per cent that gravity's fall with altitude and the cut top make.
        let column: f64 = (0..55_374)
            .map(|z| p.number_density_m3(f64::from(z) + 0.5))
            .sum();
        let hydrostatic = 610.0 / (43.34e-3 / 6.022_140_76e23 * 3.71);
        assert!(
            (column / hydrostatic - 1.0).abs() < 0.05,
            "{column} {hydrostatic}"
        );
    }
}
