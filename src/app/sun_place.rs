//! The Sun by date, time and place, as the app's controls hold it: a date
//! as typed, a time of day in minutes (the slider), a UTC offset, a
//! latitude and a longitude ([`DatePlace`]). They become the scene's RFC
//! 3339 `sun.date_time`, `latitude_deg` and `longitude_deg`, from which
//! [`Scene::place_sun`] computes the Sun; the inputs are kept apart from
//! the scene so that a half-typed date or an out-of-range latitude can be
//! shown with its error while the scene keeps its last valid Sun.

use chrono::{DateTime, Duration, FixedOffset, NaiveDate, SecondsFormat, Timelike as _};

use crate::scene::{Scene, Sun};

/// Minutes in a day: the time-of-day slider runs from 0 (00:00) to this (24:00).
pub const MINUTES_PER_DAY: u32 = 24 * 60;
/// UTC offsets in use run from −12:00 (Baker Island) to +14:00 (Line Islands), hours.
pub const UTC_OFFSET_RANGE_H: (f64, f64) = (-12.0, 14.0);
/// Latitudes, degrees north.
pub const LATITUDE_RANGE: (f64, f64) = (-90.0, 90.0);
/// Longitudes, degrees east.
pub const LONGITUDE_RANGE: (f64, f64) = (-180.0, 180.0);

/// How the Sun is placed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum SunMode {
    /// By hand: elevation and azimuth.
    #[default]
    Manual,
    /// From a date, a time and a place.
    DatePlace,
}

/// A place the Sun panel offers with one click.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Place {
    /// Name on the button.
    pub name: &'static str,
    /// Degrees north.
    pub latitude_deg: f64,
    /// Degrees east.
    pub longitude_deg: f64,
    /// Standard-time (winter) UTC offset, hours.
    pub utc_offset_h: f64,
    /// Why it is there (the button's tooltip).
    pub note: &'static str,
}

/// The places offered: coordinates of a landmark in each.
pub const PLACES: [Place; 4] = [
    Place {
        name: "Ithaca NY",
        latitude_deg: 42.4434,
        longitude_deg: -76.4816,
        utc_offset_h: -5.0,
        note: "Ithaca, New York (Cornell): mid-latitudes; UTC−5, −4 in summer",
    },
    Place {
        name: "Greenwich",
        latitude_deg: 51.4779,
        longitude_deg: -0.0015,
        utc_offset_h: 0.0,
        note: "The Royal Observatory, Greenwich: the prime meridian; UTC+0, +1 in summer",
    },
    Place {
        name: "Longyearbyen",
        latitude_deg: 78.2232,
        longitude_deg: 15.6267,
        utc_offset_h: 1.0,
        note: "Longyearbyen, Svalbard: midnight sun in summer, polar night in winter; \
               UTC+1, +2 in summer",
    },
    Place {
        name: "Quito",
        latitude_deg: -0.1807,
        longitude_deg: -78.4678,
        utc_offset_h: -5.0,
        note: "Quito, Ecuador: on the equator, the Sun overhead at the equinoxes; UTC−5",
    },
];

/// The date, time and place inputs of the Sun panel.
#[derive(Clone, Debug, PartialEq)]
pub struct DatePlace {
    /// Local date as typed, `YYYY-MM-DD`.
    pub date: String,
    /// Local time of day, minutes after midnight, 0–[`MINUTES_PER_DAY`]
    /// (24:00 is the next day's midnight).
    pub minutes: u32,
    /// UTC offset of the local time, minutes (−240 for UTC−4).
    pub utc_offset_min: i32,
    /// Degrees north (−90 to 90).
    pub latitude_deg: f64,
    /// Degrees east (−180 to 180).
    pub longitude_deg: f64,
}

impl Default for DatePlace {
    /// Today (UTC) at noon at Greenwich.
    fn default() -> Self {
        let today = DateTime::<chrono::Utc>::from(std::time::SystemTime::now()).date_naive();
        let greenwich = PLACES[1];
        Self {
            date: today.format("%Y-%m-%d").to_string(),
            minutes: 12 * 60,
            utc_offset_min: 0,
            latitude_deg: greenwich.latitude_deg,
            longitude_deg: greenwich.longitude_deg,
        }
    }
}

impl DatePlace {
    /// The inputs behind a scene's Sun, if it is placed by date: the time
    /// of day to the minute (seconds are dropped), in its own UTC offset.
    pub fn from_sun(sun: &Sun) -> Option<Self> {
        let date_time =
            crate::physics::solar_position::parse_date_time(sun.date_time.as_ref()?).ok()?;
        Some(Self {
            date: date_time.format("%Y-%m-%d").to_string(),
            minutes: date_time.hour() * 60 + date_time.minute(),
            utc_offset_min: date_time.offset().local_minus_utc().div_euclid(60),
            latitude_deg: sun.latitude_deg?,
            longitude_deg: sun.longitude_deg?,
        })
    }

    /// The local date and time as RFC 3339 (`2013-05-27T11:45:00-04:00`).
    pub fn date_time(&self) -> Result<String, String> {
        self.date_time_after(0)
    }

    /// The local date and time `minutes` later, as RFC 3339 in the same UTC offset.
    pub fn date_time_after(&self, minutes: u32) -> Result<String, String> {
        let date = parse_date(&self.date)?;
        if self.minutes > MINUTES_PER_DAY {
            return Err(format!(
                "invalid time of day: {} is after 24:00",
                format_time_of_day(f64::from(self.minutes))
            ));
        }
        let offset = utc_offset(self.utc_offset_min)?;
        let local = date.and_time(chrono::NaiveTime::MIN)
            + Duration::minutes(i64::from(self.minutes) + i64::from(minutes));
        let date_time = local
            .and_local_timezone(offset)
            .single()
            .ok_or_else(|| format!("invalid date and time: {local} at {offset}"))?;
        Ok(date_time.to_rfc3339_opts(SecondsFormat::Secs, false))
    }

    /// `scene` with its Sun placed by these inputs: `date_time`,
    /// `latitude_deg` and `longitude_deg` set, elevation and azimuth
    /// computed, the whole scene validated. The error says which input is wrong.
    pub fn place(&self, scene: &Scene) -> Result<Scene, String> {
        let mut placed = scene.clone();
        placed.sun.date_time = Some(self.date_time()?);
        placed.sun.latitude_deg = Some(self.latitude_deg);
        placed.sun.longitude_deg = Some(self.longitude_deg);
        placed.place_sun().map_err(|e| e.to_string())?;
        placed.validate().map_err(|e| e.to_string())?;
        Ok(placed)
    }
}

/// A date typed as `YYYY-MM-DD`.
pub fn parse_date(text: &str) -> Result<NaiveDate, String> {
    let text = text.trim();
    NaiveDate::parse_from_str(text, "%Y-%m-%d")
        .map_err(|e| format!("invalid date: '{text}' is not a date like 2013-05-27 ({e})"))
}

/// A UTC offset of `minutes` (within [`UTC_OFFSET_RANGE_H`]).
fn utc_offset(minutes: i32) -> Result<FixedOffset, String> {
    let (lo, hi) = UTC_OFFSET_RANGE_H;
    let hours = f64::from(minutes) / 60.0;
    if !(lo..=hi).contains(&hours) {
        return Err(format!(
            "invalid UTC offset: {} is outside the valid range UTC−12:00 to UTC+14:00",
            format_utc_offset(hours)
        ));
    }
    FixedOffset::east_opt(minutes * 60).ok_or_else(|| format!("invalid UTC offset: {minutes} min"))
}

/// A time of day in minutes as the slider shows it: `11:45`, `24:00`.
pub fn format_time_of_day(minutes: f64) -> String {
    let minutes = minutes.round().max(0.0) as u32;
    format!("{:02}:{:02}", minutes / 60, minutes % 60)
}

/// A time of day typed as `H:MM` or `HH:MM` (or plain hours, `14`), in
/// minutes, up to 24:00.
pub fn parse_time_of_day(text: &str) -> Option<f64> {
    let minutes = parse_hours_minutes(text)?;
    (0..=MINUTES_PER_DAY as i32)
        .contains(&minutes)
        .then_some(f64::from(minutes))
}

/// A UTC offset in hours as the panel shows it: `UTC−04:00`, `UTC+05:45`.
pub fn format_utc_offset(hours: f64) -> String {
    let minutes = (hours * 60.0).round() as i64;
    let sign = if minutes < 0 { '−' } else { '+' };
    let minutes = minutes.abs();
    format!("UTC{sign}{:02}:{:02}", minutes / 60, minutes % 60)
}

/// A UTC offset typed as `-4`, `+5:45`, `UTC−04:00` or `Z`, in hours.
pub fn parse_utc_offset(text: &str) -> Option<f64> {
    let text = text.trim();
    let text = text
        .strip_prefix("UTC")
        .or_else(|| text.strip_prefix("utc"))
        .or_else(|| text.strip_prefix("GMT"))
        .unwrap_or(text)
        .trim();
    if text.is_empty() || text.eq_ignore_ascii_case("z") {
        return Some(0.0);
    }
    parse_hours_minutes(text).map(|m| f64::from(m) / 60.0)
}

/// A duration in minutes as the panel shows it: `12 h`, `1 h 30 min`, `45 min`.
pub fn format_duration(minutes: f64) -> String {
    let minutes = minutes.round().max(0.0) as u32;
    match (minutes / 60, minutes % 60) {
        (0, m) => format!("{m} min"),
        (h, 0) => format!("{h} h"),
        (h, m) => format!("{h} h {m} min"),
    }
}

/// A duration typed as `1:30`, `12 h`, `1 h 30 min`, `90 min` or plain
/// hours (`6`), in minutes.
pub fn parse_duration(text: &str) -> Option<f64> {
    let text = text.trim().to_ascii_lowercase();
    let hours_minutes = || {
        parse_hours_minutes(&text)
            .filter(|m| *m >= 0)
            .map(f64::from)
    };
    let mut minutes = 0.0;
    let mut rest = text.as_str();
    let mut any = false;
    while !rest.is_empty() {
        let end = rest
            .find(|c: char| !(c.is_ascii_digit() || c == '.'))
            .unwrap_or(rest.len());
        if end == 0 {
            return hours_minutes();
        }
        let number: f64 = rest[..end].parse().ok()?;
        rest = rest[end..].trim_start();
        let unit = rest
            .find(|c: char| c.is_ascii_digit() || c == '.')
            .unwrap_or(rest.len());
        let factor = match rest[..unit].trim() {
            "" | "h" | "hours" | "hour" => 60.0,
            "min" | "m" | "minutes" | "minute" => 1.0,
            _ => return hours_minutes(),
        };
        minutes += number * factor;
        rest = rest[unit..].trim_start();
        any = true;
    }
    (any && minutes.is_finite() && minutes >= 0.0).then_some(minutes.round())
}

/// `[+-−]H[:MM]` in minutes (the sign applying to both).
fn parse_hours_minutes(text: &str) -> Option<i32> {
    let text = text.trim();
    let (sign, rest) = match text.chars().next()? {
        '-' | '−' => (-1, &text[text.chars().next()?.len_utf8()..]),
        '+' => (1, &text[1..]),
        _ => (1, text),
    };
    let (hours, minutes) = match rest.split_once(':') {
        Some((h, m)) if m.len() == 2 => (h, m.parse::<i32>().ok()?),
        Some(_) => return None,
        None => (rest, 0),
    };
    let hours: i32 = hours.trim().parse().ok()?;
    if !(0..60).contains(&minutes) || !(0..=48).contains(&hours) {
        return None;
    }
    Some(sign * (hours * 60 + minutes))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ithaca() -> DatePlace {
        DatePlace {
            date: "2013-05-27".into(),
            minutes: 11 * 60 + 45,
            utc_offset_min: -240,
            latitude_deg: 42.4434,
            longitude_deg: -76.4816,
        }
    }

    #[test]
    fn date_time_is_rfc3339_with_the_offset() {
        let place = ithaca();
        assert_eq!(place.date_time().unwrap(), "2013-05-27T11:45:00-04:00");
        assert_eq!(
            place.date_time_after(13 * 60).unwrap(),
            "2013-05-28T00:45:00-04:00"
        );
        let midnight = DatePlace {
            minutes: MINUTES_PER_DAY,
            utc_offset_min: 345,
            ..ithaca()
        };
        assert_eq!(midnight.date_time().unwrap(), "2013-05-28T00:00:00+05:45");
        let utc = DatePlace {
            utc_offset_min: 0,
            ..ithaca()
        };
        assert_eq!(utc.date_time().unwrap(), "2013-05-27T11:45:00+00:00");
        // What it writes, the scene reads back.
        crate::physics::solar_position::parse_date_time(&place.date_time().unwrap()).unwrap();
    }

    #[test]
    fn invalid_inputs_are_errors_not_panics() {
        for (place, expect) in [
            (
                DatePlace {
                    date: "2013-02-30".into(),
                    ..ithaca()
                },
                "invalid date",
            ),
            (
                DatePlace {
                    date: "27/05/2013".into(),
                    ..ithaca()
                },
                "invalid date",
            ),
            (
                DatePlace {
                    utc_offset_min: 15 * 60,
                    ..ithaca()
                },
                "UTC offset",
            ),
            (
                DatePlace {
                    minutes: 2000,
                    ..ithaca()
                },
                "time of day",
            ),
            (
                DatePlace {
                    latitude_deg: 95.0,
                    ..ithaca()
                },
                "latitude",
            ),
            (
                DatePlace {
                    longitude_deg: f64::NAN,
                    ..ithaca()
                },
                "longitude",
            ),
        ] {
            let error = place.place(&Scene::default()).unwrap_err();
            assert!(error.contains(expect), "{error}");
        }
    }

    #[test]
    fn places_the_sun_as_the_scene_does() {
        let scene = ithaca().place(&Scene::default()).unwrap();
        assert!((scene.sun.elevation_deg - 63.35).abs() < 0.01, "{scene:?}");
        assert!((scene.sun.azimuth_deg - 136.08).abs() < 0.01, "{scene:?}");
        assert_eq!(DatePlace::from_sun(&scene.sun), Some(ithaca()));
        assert_eq!(DatePlace::from_sun(&Scene::default().sun), None);
        let mut seconds = scene.sun.clone();
        seconds.date_time = Some("2013-05-27T23:59:59+05:45".into());
        let back = DatePlace::from_sun(&seconds).unwrap();
        assert_eq!((back.minutes, back.utc_offset_min), (23 * 60 + 59, 345));
    }

    #[test]
    fn times_offsets_and_durations_format_and_parse() {
        assert_eq!(format_time_of_day(705.0), "11:45");
        assert_eq!(format_time_of_day(1440.0), "24:00");
        assert_eq!(format_time_of_day(0.0), "00:00");
        assert_eq!(parse_time_of_day("11:45"), Some(705.0));
        assert_eq!(parse_time_of_day("7:05"), Some(425.0));
        assert_eq!(parse_time_of_day("14"), Some(840.0));
        assert_eq!(parse_time_of_day("24:00"), Some(1440.0));
        for bad in ["25:00", "-1:00", "11:5", "11:60", "noon", ""] {
            assert_eq!(parse_time_of_day(bad), None, "{bad}");
        }
        assert_eq!(format_utc_offset(-4.0), "UTC−04:00");
        assert_eq!(format_utc_offset(5.75), "UTC+05:45");
        assert_eq!(format_utc_offset(0.0), "UTC+00:00");
        assert_eq!(format_utc_offset(-9.5), "UTC−09:30");
        for hours in [-12.0, -9.5, -4.0, 0.0, 5.75, 14.0] {
            assert_eq!(parse_utc_offset(&format_utc_offset(hours)), Some(hours));
        }
        assert_eq!(parse_utc_offset("-4"), Some(-4.0));
        assert_eq!(parse_utc_offset("+5:30"), Some(5.5));
        assert_eq!(parse_utc_offset("Z"), Some(0.0));
        assert_eq!(parse_utc_offset("east"), None);
        assert_eq!(format_duration(720.0), "12 h");
        assert_eq!(format_duration(90.0), "1 h 30 min");
        assert_eq!(format_duration(45.0), "45 min");
        for minutes in [0.0, 45.0, 90.0, 720.0, 2880.0] {
            assert_eq!(parse_duration(&format_duration(minutes)), Some(minutes));
        }
        assert_eq!(parse_duration("1:30"), Some(90.0));
        assert_eq!(parse_duration("6"), Some(360.0));
        assert_eq!(parse_duration("1.5 h"), Some(90.0));
        assert_eq!(parse_duration("soon"), None);
        assert_eq!(parse_duration("-1"), None);
        assert_eq!(parse_duration(""), None);
    }
}
