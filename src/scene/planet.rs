//! The scene's `[planet]` table and how a planet's defaults fill the keys
//! a scene leaves unset.

use serde::{Deserialize, Serialize};

use crate::atmosphere::AtmosphereParams;
use crate::physics::planet::Planet;

/// The planet under the scene (`[planet]`): its radius, the top of its
/// atmosphere, its gas and profile, its aerosol and the Sun's distance
/// ([`crate::physics::planet`]) are the defaults of the scene's keys that
/// set them (`[atmosphere]`, `[atmosphere.aerosol]`, `[sun] distance_au`),
/// which override them.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(default, deny_unknown_fields)]
pub struct PlanetParams {
    /// Which planet: `earth` or `mars`.
    pub preset: Planet,
}

impl PlanetParams {
    /// Whether the planet is the Earth (the table is then left out of a
    /// written scene).
    pub fn is_earth(&self) -> bool {
        self.preset == Planet::Earth
    }
}

/// The keys of `[atmosphere.aerosol]` in groups set together: a planet's
/// default for one of them is not used where the scene sets any key of its
/// group (or a flat `[atmosphere]` key that the group replaces).
const AEROSOL_KEY_GROUPS: [(&[&str], &[&str]); 5] = [
    (
        &["phase", "asymmetry", "g1", "g2", "weight", "phase_file"],
        &["aerosol_phase", "aerosol_g"],
    ),
    (&["profile", "scale_height_m"], &[]),
    (&["optical_depth_550"], &["aerosol_amount"]),
    (&["single_scattering_albedo"], &["aerosol_albedo"]),
    (&["angstrom_exponent"], &[]),
];

/// `table` (a scene's TOML) with the defaults of `planet` filled in where
/// it leaves them unset: the atmosphere's keys (with the aerosol's in their
/// groups, [`AEROSOL_KEY_GROUPS`]) and the Sun's distance.
pub(super) fn with_planet_defaults(mut table: toml::Table, planet: Planet) -> toml::Table {
    let defaults = toml::Table::try_from(AtmosphereParams::for_planet(planet))
        .expect("an atmosphere serialises");
    let atmosphere = table
        .entry("atmosphere")
        .or_insert_with(|| toml::Value::Table(toml::Table::new()));
    if let toml::Value::Table(atmosphere) = atmosphere {
        // The scene's own flat keys, before the defaults join them.
        let flat: Vec<String> = atmosphere.keys().cloned().collect();
        for (key, value) in &defaults {
            if key == "aerosol" {
                continue;
            }
            atmosphere
                .entry(key.clone())
                .or_insert_with(|| value.clone());
        }
        if let Some(toml::Value::Table(dust)) = defaults.get("aerosol") {
            let aerosol = atmosphere
                .entry("aerosol")
                .or_insert_with(|| toml::Value::Table(toml::Table::new()));
            if let toml::Value::Table(aerosol) = aerosol {
                for (keys, flat_keys) in AEROSOL_KEY_GROUPS {
                    let set = keys.iter().any(|k| aerosol.contains_key(*k))
                        || flat_keys.iter().any(|k| flat.iter().any(|f| f == k));
                    if set {
                        continue;
                    }
                    for key in keys {
                        if let Some(value) = dust.get(*key) {
                            aerosol.insert((*key).to_owned(), value.clone());
                        }
                    }
                }
            }
        }
    }
    if let Some(distance_au) = planet.sun_distance_au() {
        let sun = table
            .entry("sun")
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        if let toml::Value::Table(sun) = sun {
            if !sun.contains_key("date_time") {
                sun.entry("distance_au")
                    .or_insert(toml::Value::Float(distance_au));
            }
        }
    }
    table
}
