//! `skyrender bench --ablation`: the variants that switch one technique
//! of the integrator off, or swap in the alternative its default was chosen
//! against, and the ones a user names (`--variants key=value`).

use crate::render::TransmittanceEstimator;
use crate::scene::Scene;

/// An ablation variant: its name and how it changes the scene.
pub type Variant = (&'static str, fn(&mut Scene));

/// The ablation variants: each switches one technique off, or swaps in an
/// alternative the defaults were chosen against.
pub fn ablation_variants() -> Vec<Variant> {
    vec![
        ("wavelengths_per_path=1", |s| {
            s.render.integrator.wavelengths_per_path = 1;
        }),
        ("tight_majorants=false", |s| {
            s.render.integrator.tight_majorants = false;
        }),
        ("shadow_transmittance=chord-residual-ratio-tracking", |s| {
            s.render.integrator.shadow_transmittance =
                TransmittanceEstimator::ChordResidualRatioTracking;
        }),
        ("shadow_transmittance=ratio-tracking", |s| {
            s.render.integrator.shadow_transmittance = TransmittanceEstimator::RatioTracking;
        }),
        ("shadow_transmittance=delta-tracking", |s| {
            s.render.integrator.shadow_transmittance = TransmittanceEstimator::DeltaTracking;
        }),
        ("next_event_estimation=false", |s| {
            s.render.integrator.next_event_estimation = false;
        }),
        ("camera_samples=0", |s| {
            s.render.integrator.camera_samples = Some(0);
        }),
        ("camera_samples=1", |s| {
            s.render.integrator.camera_samples = Some(1);
        }),
        ("camera_samples=2", |s| {
            s.render.integrator.camera_samples = Some(2);
        }),
        ("camera_branches=1", |s| {
            s.render.integrator.camera_branches = Some(1);
        }),
        ("camera_branches=4", |s| {
            s.render.integrator.camera_branches = Some(4);
        }),
        ("camera_importance=0", |s| {
            s.render.integrator.camera_importance = Some(0.0);
        }),
        ("sunlight_samples=0", |s| {
            s.render.integrator.sunlight_samples = Some(0);
        }),
        ("sunlight_samples=1", |s| {
            s.render.integrator.sunlight_samples = Some(1);
        }),
        ("sky_guide=0", |s| {
            s.render.integrator.sky_guide = Some(0.0);
        }),
        ("sky_guide_sunlit=false", |s| {
            s.render.integrator.sky_guide_sunlit = Some(false);
        }),
        ("sky_guide_sunlit=true", |s| {
            s.render.integrator.sky_guide_sunlit = Some(true);
        }),
        ("ground_guide=0", |s| {
            s.render.integrator.ground_guide = Some(0.0);
        }),
        ("sky_guide=0.5", |s| {
            s.render.integrator.sky_guide = Some(0.5);
        }),
        ("shadow_samples=1", |s| {
            s.render.integrator.shadow_samples = 1;
        }),
        ("sun_lobe=0", |s| {
            s.render.integrator.sun_lobe = Some(0.0);
        }),
        ("sun_lobe=0.3", |s| {
            s.render.integrator.sun_lobe = Some(0.3);
        }),
        ("sun_lobe=0.5", |s| {
            s.render.integrator.sun_lobe = Some(0.5);
        }),
        ("forced_collision_depth=0", |s| {
            s.render.integrator.forced_collision_depth = 0;
        }),
        ("forced_collision_depth=1", |s| {
            s.render.integrator.forced_collision_depth = 1;
        }),
        ("russian_roulette=false", |s| {
            s.render.integrator.russian_roulette = false;
        }),
        ("splitting=false", |s| {
            s.render.integrator.splitting = Some(false);
        }),
        ("splitting=true", |s| {
            s.render.integrator.splitting = Some(true);
        }),
        ("control_variate=false", |s| {
            s.render.integrator.control_variate = Some(false);
        }),
        ("control_variate=true", |s| {
            s.render.integrator.control_variate = Some(true);
        }),
        ("circle_splatting=false", |s| {
            s.render.integrator.circle_splatting = Some(false);
        }),
        ("circle_splatting=true", |s| {
            s.render.integrator.circle_splatting = Some(true);
        }),
        ("ground_splatting=false", |s| {
            s.render.integrator.ground_splatting = Some(false);
        }),
        ("ground_pool=false", |s| {
            s.render.integrator.ground_pool = Some(false);
        }),
        ("ground_control=false", |s| {
            s.render.integrator.ground_control = Some(false);
        }),
        ("splat_transmittance_table=false", |s| {
            s.render.integrator.splat_transmittance_table = false;
        }),
        ("sun_transmittance_table=false", |s| {
            s.render.integrator.sun_transmittance_table = false;
        }),
        ("sampler=independent", |s| {
            s.render.integrator.sampler = crate::render::Sampler::Independent;
        }),
        ("adaptive_sampling=false", |s| {
            s.render.adaptive_sampling = false;
        }),
        ("mirror_symmetry=false", |s| {
            s.render.mirror_symmetry = false;
        }),
    ]
}

/// A variant to run: one of [`ablation_variants`], or integrator options
/// set by name (`key=value`, as in a scene file's `[render.integrator]`
/// table; several joined by `+`).
pub(super) enum Selected {
    Listed(Variant),
    Option {
        name: String,
        settings: Vec<(String, toml::Value)>,
    },
}

impl Selected {
    pub(super) fn name(&self) -> &str {
        match self {
            Self::Listed((name, _)) => name,
            Self::Option { name, .. } => name,
        }
    }

    /// `scene` with the variant's change, checked as a scene file is.
    pub(super) fn apply(&self, scene: &Scene) -> Result<Scene, String> {
        let mut scene = scene.clone();
        match self {
            Self::Listed((_, change)) => change(&mut scene),
            Self::Option { name, settings } => {
                // toml's messages run over lines ("…\nin `key`"): one line here.
                let fail = |e: &dyn std::fmt::Display| {
                    let message = e.to_string();
                    let message: Vec<&str> = message.lines().map(str::trim).collect();
                    format!("--variants: '{name}': {}", message.join(" "))
                };
                let mut options =
                    toml::Table::try_from(&scene.render.integrator).map_err(|e| fail(&e))?;
                for (key, value) in settings {
                    options.insert(key.clone(), value.clone());
                }
                scene.render.integrator = options.try_into().map_err(|e| fail(&e))?;
                scene.validate().map_err(|e| fail(&e))?;
            }
        }
        Ok(scene)
    }
}

/// The ablation variants named in `names` (all of them for `None`): listed
/// ones by name, others as `key=value` integrator options (the value a TOML
/// value, or else a string: `shadow_transmittance=ratio-tracking`; several
/// options at once joined by `+`); an
/// error names a variant that is neither, or whose option is unknown or
/// invalid, with the valid names — before any measurement.
pub(super) fn selected_variants(names: Option<&[String]>) -> Result<Vec<Selected>, String> {
    let all = ablation_variants();
    let Some(names) = names else {
        return Ok(all.into_iter().map(Selected::Listed).collect());
    };
    names
        .iter()
        .map(|n| {
            if let Some(&listed) = all.iter().find(|(v, _)| v == n) {
                return Ok(Selected::Listed(listed));
            }
            let valid: Vec<&str> = all.iter().map(|(v, _)| *v).collect();
            let unknown = || {
                format!(
                    "--variants: unknown variant '{n}' (valid: {}, or an integrator option as key=value)",
                    valid.join(", ")
                )
            };
            let settings = n
                .split('+')
                .map(|setting| {
                    let (key, text) = setting.split_once('=').ok_or_else(unknown)?;
                    if key.trim().is_empty() {
                        return Err(format!("--variants: '{n}' names no option (key=value)"));
                    }
                    let value = toml::from_str::<toml::Table>(&format!("v = {text}"))
                        .ok()
                        .and_then(|mut t| t.remove("v"))
                        .unwrap_or_else(|| toml::Value::String(text.to_owned()));
                    Ok((key.trim().to_owned(), value))
                })
                .collect::<Result<Vec<_>, String>>()?;
            let selected = Selected::Option {
                name: n.clone(),
                settings,
            };
            selected.apply(&Scene::default())?;
            Ok(selected)
        })
        .collect()
}
