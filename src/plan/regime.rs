//! The regime table: which techniques are on, and how strongly, for the sun
//! at a given elevation above the observer's horizon.
//!
//! The light a sky path gathers changes character with the sun's height,
//! and each technique pays only where that character suits it:
//!
//! * **Twilight** (sun below the horizon): the observer's air is in the
//!   planet's shadow; the light comes from thin sunlit stretches high up or
//!   toward the sun, found by segment estimates from the expected sunlight,
//!   guided directions, and roulette and splitting by the guide's skylight.
//! * **Sunset** (0–3°): the same long grazing rays, and the aureole cut by
//!   the bright horizon — taken out by the once-scattered light as a
//!   control variate, which leaves the sun lobe nothing to find; splitting
//!   by the guide's skylight as at twilight (the sunlit air is above).
//! * **Day** (3–30°): delta tracking wins again, and for an observer low
//!   in the air multiply scattered light is still best splatted along the
//!   circles about the sun's axis; from high up (an airliner's 10 km) the
//!   splats cost more than they save.
//! * **High sun** (above 30°): plain delta tracking with camera-ray
//!   densities and a narrower lobe.
//!
//! At every elevation half the ground's bounces follow the guide's table
//! of the once-scattered light arriving there: the sky's light on the
//! ground comes from low toward the sun, where the cosine density is
//! small, the more so the lower the sun.
//!
//! Every switch here chooses among unbiased estimators: the expected image
//! is the same on either side of a boundary, only the noise differs. The
//! boundaries were measured on the Earth's scenes (the decisions table of
//! `BENCHMARKS.md` gives the figures); on another planet they still choose
//! among unbiased estimators. This table is the only code that reads a sun
//! elevation threshold.

use serde::Serialize;

/// A band of sun elevations (at the observer) sharing one set of defaults.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Regime {
    /// The sun below the horizon.
    Twilight,
    /// The sun 0–3° above the horizon.
    Sunset,
    /// The sun 3–30° up.
    Day,
    /// The sun more than 30° up.
    HighSun,
}

impl Regime {
    /// The regime of a sun `sun_elevation_deg` above the observer's horizon.
    /// Each band includes its lower bound, but 30° itself is day.
    pub fn at(sun_elevation_deg: f64) -> Self {
        let [horizon, low, zenithal] = BOUNDARIES_DEG;
        if sun_elevation_deg < horizon {
            Self::Twilight
        } else if sun_elevation_deg < low {
            Self::Sunset
        } else if sun_elevation_deg <= zenithal {
            Self::Day
        } else {
            Self::HighSun
        }
    }

    /// The regime's row of [`REGIMES`].
    pub fn defaults(self) -> &'static RegimeDefaults {
        &REGIMES[self as usize].1
    }

    /// The regime's name as the README's table writes it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Twilight => "twilight",
            Self::Sunset => "sunset",
            Self::Day => "day",
            Self::HighSun => "high sun",
        }
    }
}

/// The sun elevations, degrees, where the regimes meet: the horizon
/// (twilight | sunset), where delta tracking overtakes segment estimates
/// (sunset | day), and where a narrower sun lobe starts to pay and
/// splatting along circles stops paying (day | high sun).
pub const BOUNDARIES_DEG: [f64; 3] = [0.0, 3.0, 30.0];

/// Where a regime splats multiply scattered light along circles.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Splatting {
    /// Never by default.
    Off,
    /// For an observer low in the air ([`super::Conditions::observer_low`]).
    Low,
    /// Wherever there are circles.
    On,
}

impl Splatting {
    /// Whether the regime splats for an observer low in the air
    /// (`observer_low`) or not.
    pub fn applies(self, observer_low: bool) -> bool {
        match self {
            Self::Off => false,
            Self::Low => observer_low,
            Self::On => true,
        }
    }
}

/// What a regime turns on when the scene leaves a switch unset.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RegimeDefaults {
    /// Next-event points per path segment from its expected sunlight
    /// (`sunlight_samples`).
    pub sunlight_samples: u32,
    /// Paths a camera ray branches into (`camera_branches`).
    pub camera_branches: u32,
    /// Share of camera branch points drawn by the guide's skylight
    /// (`camera_importance`).
    pub camera_importance: f64,
    /// Share of directions about the sun's (`sun_lobe`) without the control
    /// variate; with it, [`CONTROL_SUN_LOBE`].
    pub sun_lobe: f64,
    /// Share of directions from the sky guide's table (`sky_guide`).
    pub sky_guide: f64,
    /// The guide at sunlit points too (`sky_guide_sunlit`).
    pub sky_guide_sunlit: bool,
    /// Share of the ground's bounce directions from the guide's table
    /// (`ground_guide`).
    pub ground_guide: f64,
    /// Roulette and splitting by importance (`splitting`), where roulette
    /// is on.
    pub splitting: bool,
    /// The once-scattered light as a control variate (`control_variate`),
    /// where the haze lets its table hold the light.
    pub control_variate: bool,
    /// Multiply scattered light splatted along circles
    /// (`circle_splatting`), where the observer is in the air.
    pub circle_splatting: Splatting,
    /// The first (draft) pass's weight in the film's average. Weights ∝
    /// 1/variance minimise the mean's, and the draft's plain delta-tracked
    /// camera paths carry far more variance per path than a full pass's,
    /// the more so the lower the sun (`BENCHMARKS.md`): any fixed positive
    /// weight keeps the mean unbiased and lets the draft alone show a first
    /// image.
    pub draft_weight: f64,
}

/// [`RegimeDefaults::sun_lobe`] where the control variate is on: the
/// control takes out the once-scattered light's aureole, which the lobe
/// samples for, and leaves it nothing to find.
pub const CONTROL_SUN_LOBE: f64 = 0.0;

/// The defaults of each regime, in the order of [`Regime`].
pub const REGIMES: [(Regime, RegimeDefaults); 4] = [
    (
        Regime::Twilight,
        RegimeDefaults {
            sunlight_samples: 1,
            camera_branches: 12,
            camera_importance: 0.5,
            sun_lobe: 0.3,
            sky_guide: 0.35,
            sky_guide_sunlit: true,
            ground_guide: 0.5,
            splitting: true,
            control_variate: false,
            circle_splatting: Splatting::On,
            draft_weight: 1.0 / 128.0,
        },
    ),
    (
        Regime::Sunset,
        RegimeDefaults {
            sunlight_samples: 1,
            camera_branches: 12,
            camera_importance: 0.5,
            sun_lobe: 0.3,
            sky_guide: 0.25,
            sky_guide_sunlit: true,
            ground_guide: 0.5,
            splitting: true,
            control_variate: true,
            circle_splatting: Splatting::On,
            draft_weight: 1.0 / 32.0,
        },
    ),
    (
        Regime::Day,
        RegimeDefaults {
            sunlight_samples: 0,
            camera_branches: 4,
            camera_importance: 0.0,
            sun_lobe: 0.3,
            sky_guide: 0.25,
            sky_guide_sunlit: false,
            ground_guide: 0.5,
            splitting: false,
            control_variate: false,
            circle_splatting: Splatting::Low,
            draft_weight: 1.0 / 8.0,
        },
    ),
    (
        Regime::HighSun,
        RegimeDefaults {
            sunlight_samples: 0,
            camera_branches: 4,
            camera_importance: 0.0,
            sun_lobe: 0.15,
            sky_guide: 0.25,
            sky_guide_sunlit: false,
            ground_guide: 0.5,
            splitting: false,
            control_variate: false,
            circle_splatting: Splatting::Off,
            draft_weight: 1.0 / 8.0,
        },
    ),
];

/// The sun elevations of a regime as the README writes them.
fn band(regime: Regime) -> String {
    let [horizon, low, zenithal] = BOUNDARIES_DEG;
    match regime {
        Regime::Twilight => format!("below {horizon}°"),
        Regime::Sunset => format!("{horizon}–{low}°"),
        Regime::Day => format!("{low}–{zenithal}°"),
        Regime::HighSun => format!("above {zenithal}°"),
    }
}

fn on(b: bool) -> &'static str {
    if b {
        "on"
    } else {
        "off"
    }
}

fn splats(s: Splatting) -> &'static str {
    match s {
        Splatting::Off => "off",
        Splatting::Low => "low observer",
        Splatting::On => "on",
    }
}

fn fraction(w: f64) -> String {
    format!("1/{}", (1.0 / w).round())
}

/// The regime table as Markdown, as the README shows it (a test keeps the
/// README's copy equal to this).
pub fn markdown_table() -> String {
    let mut rows = vec![
        "| regime | sun elevation | `sunlight_samples` | `camera_branches` | `camera_importance` | `sun_lobe` | `sky_guide` | `sky_guide_sunlit` | `ground_guide` | `splitting` | `control_variate` | `circle_splatting` | draft weight |".to_string(),
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|".to_string(),
    ];
    for (regime, d) in REGIMES {
        rows.push(format!(
            "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
            regime.name(),
            band(regime),
            d.sunlight_samples,
            d.camera_branches,
            d.camera_importance,
            d.sun_lobe,
            d.sky_guide,
            on(d.sky_guide_sunlit),
            d.ground_guide,
            on(d.splitting),
            on(d.control_variate),
            splats(d.circle_splatting),
            fraction(d.draft_weight),
        ));
    }
    rows.join("\n") + "\n"
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_table_is_in_the_order_of_its_regimes() {
        for (i, (regime, _)) in REGIMES.iter().enumerate() {
            assert_eq!(*regime as usize, i);
        }
    }

    #[test]
    fn each_band_includes_its_lower_bound_and_thirty_degrees_is_day() {
        assert_eq!(Regime::at(-90.0), Regime::Twilight);
        assert_eq!(Regime::at(-1e-9), Regime::Twilight);
        assert_eq!(Regime::at(0.0), Regime::Sunset);
        assert_eq!(Regime::at(2.999), Regime::Sunset);
        assert_eq!(Regime::at(3.0), Regime::Day);
        assert_eq!(Regime::at(10.0), Regime::Day);
        assert_eq!(Regime::at(30.0), Regime::Day);
        assert_eq!(Regime::at(30.001), Regime::HighSun);
        assert_eq!(Regime::at(90.0), Regime::HighSun);
    }

    #[test]
    fn the_readme_shows_this_table() {
        let readme = include_str!("../../README.md");
        let table = markdown_table();
        assert!(
            readme.contains(&table),
            "README.md's regime table differs from the plan's; it should read:\n{table}"
        );
    }
}
