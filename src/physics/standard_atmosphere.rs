//! The U.S. Standard Atmosphere 1976 (NOAA-S/T 76-1562, NASA-TM-X-74335).
//!
//! Below 86 km geometric (84.852 km geopotential) the standard defines seven
//! layers with linear molecular-scale temperature in geopotential altitude and
//! hydrostatic pressure (its equations 23, 33a, 33b, 42). Above 86 km we
//! continue it smoothly as an isothermal layer at the 86 km temperature with
//! the same hydrostatic law; the standard's own upper thermosphere differs, but
//! the air there (< 7 × 10⁻⁶ kg m⁻³) scatters nothing visible.
//!
//! Simplification: between 80 and 86 km the standard distinguishes kinetic from
//! molecular-scale temperature by the mean molecular weight ratio M/M₀, which
//! departs from 1 by at most 4.2 × 10⁻⁴ there (its Table 8); we take M = M₀.

/// Sea-level gravity g₀, m s⁻² (standard, eq. 17 context).
pub const G0: f64 = 9.806_65;
/// Effective Earth radius for geopotential altitude r₀, m.
pub const R0_M: f64 = 6_356_766.0;
/// Universal gas constant R*, J mol⁻¹ K⁻¹ (the standard's value).
pub const R_STAR: f64 = 8.314_32;
/// Sea-level mean molecular weight of air M₀, kg mol⁻¹.
pub const M0: f64 = 28.964_4e-3;
/// Avogadro constant used by the standard, mol⁻¹.
pub const AVOGADRO: f64 = 6.022_169e23;

/// Base geopotential altitudes H_b (m) of the seven layers, and the top.
const LAYER_BASE_M: [f64; 8] = [
    0.0, 11_000.0, 20_000.0, 32_000.0, 47_000.0, 51_000.0, 71_000.0, 84_852.0,
];
/// Molecular-scale temperature gradients L_b (K m⁻¹) of the seven layers.
const LAPSE_K_PER_M: [f64; 7] = [-0.0065, 0.0, 0.001, 0.0028, 0.0, -0.0028, -0.002];
/// Sea-level temperature, K, and pressure, Pa.
const T0_K: f64 = 288.15;
const P0_PA: f64 = 101_325.0;

/// The state of the air at one altitude.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AirState {
    /// Temperature, K.
    pub temperature_k: f64,
    /// Pressure, Pa.
    pub pressure_pa: f64,
    /// Mass density, kg m⁻³.
    pub density_kg_m3: f64,
    /// Number density of air molecules, m⁻³.
    pub number_density_m3: f64,
}

/// Geopotential altitude (m′) from geometric altitude (m): H = r₀ z / (r₀ + z).
pub fn geopotential_from_geometric_m(altitude_m: f64) -> f64 {
    R0_M * altitude_m / (R0_M + altitude_m)
}

/// Base temperature and pressure of every layer, derived from the sea-level
/// values by the standard's own recursion (so no rounded table values enter).
fn layer_bases() -> [(f64, f64); 8] {
    let mut bases = [(T0_K, P0_PA); 8];
    for i in 0..7 {
        let (t_b, p_b) = bases[i];
        let dh = LAYER_BASE_M[i + 1] - LAYER_BASE_M[i];
        bases[i + 1] = layer_state(t_b, p_b, LAPSE_K_PER_M[i], dh);
    }
    bases
}

/// Temperature and pressure at `dh_m` above a layer base (eqs. 33a/33b).
fn layer_state(
    base_temperature_k: f64,
    base_pressure_pa: f64,
    lapse: f64,
    dh_m: f64,
) -> (f64, f64) {
    let gmr = G0 * M0 / R_STAR;
    if lapse == 0.0 {
        let p = base_pressure_pa * (-gmr * dh_m / base_temperature_k).exp();
        (base_temperature_k, p)
    } else {
        let t = base_temperature_k + lapse * dh_m;
        let p = base_pressure_pa * (base_temperature_k / t).powf(gmr / lapse);
        (t, p)
    }
}

/// The air at `altitude_m` (geometric, ≥ 0). Above 86 km: isothermal
/// continuation (see module docs).
pub fn air_state(altitude_m: f64) -> AirState {
    let bases = layer_bases();
    let h = geopotential_from_geometric_m(altitude_m.max(0.0));
    let layer = LAYER_BASE_M[..7]
        .partition_point(|&hb| hb <= h)
        .saturating_sub(1);
    let (t_b, p_b) = bases[layer];
    let (temperature_k, pressure_pa) = if h >= LAYER_BASE_M[7] {
        let (t7, p7) = bases[7];
        layer_state(t7, p7, 0.0, h - LAYER_BASE_M[7])
    } else {
        layer_state(t_b, p_b, LAPSE_K_PER_M[layer], h - LAYER_BASE_M[layer])
    };
    AirState {
        temperature_k,
        pressure_pa,
        density_kg_m3: pressure_pa * M0 / (R_STAR * temperature_k),
        number_density_m3: pressure_pa * AVOGADRO / (R_STAR * temperature_k),
    }
}

/// Vertical column number density (molecules m⁻²) above `altitude_m`, by
/// hydrostatic balance with altitude-dependent gravity: N = p / (m g(z)) would
/// hold for constant g; we integrate the number density numerically instead
/// (Simpson's rule on 10 m steps to 200 km), which is exact to < 10⁻⁶.
pub fn column_number_density_m2(altitude_m: f64) -> f64 {
    let top_m = 200_000.0;
    if altitude_m >= top_m {
        return 0.0;
    }
    let n = (((top_m - altitude_m) / 10.0).ceil() as usize).max(2) & !1;
    let step = (top_m - altitude_m) / n as f64;
    let mut sum = 0.0;
    for i in 0..=n {
        let w = if i == 0 || i == n {
            1.0
        } else if i % 2 == 1 {
            4.0
        } else {
            2.0
        };
        sum += w * air_state(altitude_m + i as f64 * step).number_density_m3;
    }
    sum * step / 3.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sea_level_is_the_standard_state() {
        let s = air_state(0.0);
        assert_eq!(s.temperature_k, 288.15);
        assert_eq!(s.pressure_pa, 101_325.0);
        assert!((s.density_kg_m3 - 1.2250).abs() < 1e-4);
        // Loschmidt-like number at 288.15 K: 2.5470e25 m⁻³ (standard Table I).
        assert!((s.number_density_m3 / 2.5470e25 - 1.0).abs() < 1e-4);
    }

    #[test]
    fn layer_base_pressures_match_the_standard() {
        // Standard, Table 4: P_b at 11, 20, 32, 47, 51, 71, 84.852 km'.
        let expected = [
            22_632.06,
            5_474.889,
            868.018_7,
            110.906_3,
            66.938_87,
            3.956_420,
            0.373_384_0,
        ];
        let bases = layer_bases();
        for (i, p) in expected.iter().enumerate() {
            assert!((bases[i + 1].1 / p - 1.0).abs() < 2e-5, "layer {i}");
        }
    }

    #[test]
    fn continuation_above_86_km_is_smooth_and_decreasing() {
        let below = air_state(85_999.0);
        let above = air_state(86_001.0);
        assert!((below.temperature_k - above.temperature_k).abs() < 0.01);
        assert!(above.pressure_pa < below.pressure_pa);
        assert!((above.pressure_pa / below.pressure_pa - 1.0).abs() < 1e-3);
        assert!(air_state(100_000.0).density_kg_m3 < 1e-6);
    }

    #[test]
    fn density_decreases_monotonically() {
        let mut last = f64::INFINITY;
        for i in 0..=2000 {
            let n = air_state(f64::from(i) * 60.0).number_density_m3;
            assert!(n < last);
            last = n;
        }
    }
}
