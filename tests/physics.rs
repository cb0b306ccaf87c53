//! Physics against published figures and analytic limits.

use skyrender::atmosphere::{Atmosphere, AtmosphereParams};
use skyrender::data::Table;
use skyrender::physics::{ozone, rayleigh, standard_atmosphere, sun};

#[test]
fn us_standard_atmosphere_matches_the_printed_tables() {
    // data/ussa76_reference.csv: U.S. Standard Atmosphere 1976, Table I.
    let table = Table::parse(include_str!("../data/ussa76_reference.csv"));
    for row in &table.rows {
        let altitude_m = row[0] * 1000.0;
        let s = standard_atmosphere::air_state(altitude_m);
        let checks = [
            ("temperature", s.temperature_k, row[1]),
            ("pressure", s.pressure_pa, row[2]),
            ("density", s.density_kg_m3, row[3]),
        ];
        for (name, got, expected) in checks {
            let rel = (got / expected - 1.0).abs();
            assert!(
                rel < 1e-3,
                "{name} at {altitude_m} m: {got} vs {expected} ({rel:.2e})"
            );
        }
    }
    assert_eq!(table.rows.len(), 10);
}

#[test]
fn rayleigh_optical_depth_at_550_nm_is_bucholtz() {
    // Bucholtz (1995), Table 3 (U.S. standard atmosphere): τ(0.55 µm) ≈ 0.0971.
    let atmosphere = Atmosphere::new(AtmosphereParams::default());
    let tau = atmosphere.vertical_optical_depth(0.0, 550.0).rayleigh;
    assert!((tau / 0.0971 - 1.0).abs() < 0.01, "τ = {tau}");
}

#[test]
fn rayleigh_slope_is_close_to_lambda_minus_four() {
    let atmosphere = Atmosphere::new(AtmosphereParams::default());
    let t400 = atmosphere.vertical_optical_depth(0.0, 400.0).rayleigh;
    let t700 = atmosphere.vertical_optical_depth(0.0, 700.0).rayleigh;
    let exponent = (t400 / t700).ln() / (700.0f64 / 400.0).ln();
    // Dispersion of n and of the King factor steepen λ⁻⁴ to ≈ λ⁻⁴·¹ in the visible.
    assert!((4.0..4.2).contains(&exponent), "exponent {exponent}");
}

#[test]
fn rayleigh_cross_sections_agree_with_bodhaine_1999() {
    // An independent formulation (data/rayleigh_bodhaine1999_colour.csv, 300 ppm
    // CO₂, different n_s): agreement within 1.5 % from 300 to 1000 nm.
    let table = Table::parse(include_str!("../data/rayleigh_bodhaine1999_colour.csv"));
    for row in &table.rows {
        let ours = rayleigh::cross_section_m2(row[0]);
        assert!(
            (ours / row[2] - 1.0).abs() < 0.015,
            "{} nm: {ours} vs {}",
            row[0],
            row[2]
        );
    }
}

#[test]
fn ozone_column_defaults_to_the_afgl_profile_and_scales() {
    let default = Atmosphere::new(AtmosphereParams::default());
    let du = default.ozone_column_du();
    // AFGL U.S. standard: 344–346 DU depending on interpolation (data/README.md).
    assert!((340.0..350.0).contains(&du), "{du}");
    let scaled = Atmosphere::new(AtmosphereParams {
        ozone_du: Some(250.0),
        ..AtmosphereParams::default()
    });
    let ratio = scaled.vertical_optical_depth(0.0, 600.0).ozone
        / default.vertical_optical_depth(0.0, 600.0).ozone;
    assert!((ratio - 250.0 / du).abs() < 1e-6);
    // Chappuis band: the 600 nm vertical ozone depth of ~345 DU is ≈ 0.04.
    let tau = default.vertical_optical_depth(0.0, 603.0).ozone;
    assert!((0.035..0.05).contains(&tau), "{tau}");
    assert!(
        ozone::Profile::get().number_density_m3(22_000.0)
            > ozone::Profile::get().number_density_m3(5_000.0) * 5.0
    );
}

#[test]
fn solar_constant_of_the_am0_table() {
    // ASTM E-490: 1366.1 W m⁻² (the modern TSI is 1360.8 ± 0.5, Kopp & Lean 2011).
    let total = sun::Spectrum::get().integral_w_m2(0.0, 1e7);
    assert!((total - 1366.1).abs() < 0.5, "{total}");
}

#[test]
fn aerosol_optical_depth_at_550_nm_is_plausible_for_25_km_visibility() {
    let atmosphere = Atmosphere::new(AtmosphereParams::default());
    let tau = atmosphere.vertical_optical_depth(0.0, 550.0).aerosol;
    // Elterman's clear standard atmosphere: τ_aer(550) ≈ 0.25 (0.380 at 340 nm × 0.66).
    assert!((0.2..0.3).contains(&tau), "{tau}");
}

/// NREL's SPA against pvlib's independent implementation of it
/// (`data/sun_positions_pvlib.csv`: 24 dates and places, polar day and
/// night among them): true elevation and azimuth within 0.01°, the
/// Earth–Sun distance within 1e-6 AU.
#[test]
fn the_sun_is_where_pvlib_puts_it() {
    use skyrender::physics::solar_position::{parse_date_time, sun_at};
    let text = include_str!("../data/sun_positions_pvlib.csv");
    let mut rows = 0;
    let (mut polar_day, mut polar_night) = (false, false);
    for line in text.lines().skip(1) {
        let f: Vec<&str> = line.split(',').collect();
        let number = |i: usize| f[i].parse::<f64>().unwrap();
        let t = parse_date_time(f[0]).unwrap();
        let sun = sun_at(&t, number(1), number(2), number(3), number(4)).unwrap();
        let (elevation, azimuth, distance) = (number(5), number(6), number(7));
        let azimuth_error = ((sun.azimuth_deg - azimuth + 540.0) % 360.0 - 180.0).abs();
        assert!(
            (sun.elevation_deg - elevation).abs() < 0.01,
            "{line}: {sun:?}"
        );
        assert!(azimuth_error < 0.01, "{line}: {sun:?}");
        assert!((sun.distance_au - distance).abs() < 1e-6, "{line}: {sun:?}");
        polar_day |= f[8].contains("polar day") && elevation > 0.0;
        polar_night |= f[8].contains("polar night") && elevation < 0.0;
        rows += 1;
    }
    assert!(rows >= 20 && polar_day && polar_night);
}
