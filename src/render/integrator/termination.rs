//! Termination: Russian roulette on a path's weight, and roulette and
//! splitting by importance (Vorba and Křivánek 2016) where the sky guide
//! gives the adjoint.

use super::{ControlAt, DVec3, GuideAt, Integrator, Lanes, Light, Rng, SpectralLanes, Vertex};
use crate::plan::MAX_FORCED_COLLISION_DEPTH;

/// Scattering vertices become paths longer than this only through Russian
/// roulette with survival ≤ 0.9, so paths end with probability one.
pub(super) const ROULETTE_CAP_DEPTH: u32 = MAX_FORCED_COLLISION_DEPTH;
/// Russian roulette leaves a path alone until its weight, relative to where
/// it started, falls below this; survivors carry this weight. At 1
/// (roulette on any loss) a ground bounce of albedo 0.3 killed 70 % of the
/// paths and tripled the weight of the rest, which cost noise in every
/// scene (`BENCHMARKS.md`, Russian roulette).
const ROULETTE_WEIGHT: f64 = 0.25;
/// Paths expected to bring more than this, relative to their start, split.
const SPLIT_WEIGHT: f64 = 2.0;
/// Most copies of one path at one vertex.
pub(super) const MAX_SPLIT: usize = 4;
/// Most copies one path start may become through splitting (the product of
/// the copies made along any copy's line). Without it, a thick haze below
/// the sunlit air, whose importance grows by orders of magnitude from the
/// ground up, split each start into ~20 000 copies (aerosol amount 100 at
/// −4°: up to 60 000 vertices per camera path against 13 in the preset);
/// in the twilight preset it binds for about 1 camera path in 100, and the
/// noise is unchanged (`BENCHMARKS.md`).
pub(super) const MAX_COPIES: usize = 256;

/// Where a path stands in roulette and splitting by importance
/// ([`Integrator::weight_window`]).
#[derive(Clone, Copy, Debug)]
pub(super) struct Window {
    /// Expected light at the path's start (or where a cap last lifted it),
    /// per unit weight.
    pub(super) reference: f64,
    /// The product of the copy counts along this path's line since its
    /// start — the inverse of its share of the start's weight — at most
    /// [`MAX_COPIES`].
    pub(super) copies: usize,
}

/// Where a path stands between vertices: real scatterings so far, the
/// scale of its weight for roulette ([`survives_roulette`]), and its
/// importance window, where roulette and splitting go by importance.
pub(super) type Walk = (u32, f64, Option<Window>);

/// Russian roulette after `depth` scatterings: survive with the largest
/// active lane weight times `split` (the weight relative to its value where
/// the path started) over [`ROULETTE_WEIGHT`] (at most 1, and at most 0.9
/// past [`ROULETTE_CAP_DEPTH`], so paths end with probability one), dividing
/// `beta` by that probability on survival.
pub(super) fn survives_roulette(
    beta: &mut Lanes,
    active: usize,
    depth: u32,
    split: f64,
    rng: &mut Rng,
) -> bool {
    let relative = split * beta[..active].iter().copied().fold(0.0, f64::max);
    let mut survive = (relative / ROULETTE_WEIGHT).min(1.0);
    if depth >= ROULETTE_CAP_DEPTH {
        survive = survive.min(0.9);
    }
    if rng.uniform() >= survive {
        return false;
    }
    *beta /= survive;
    true
}

impl<'a> Integrator<'a> {
    /// Whether a path with weight `beta` after `depth` scatterings (its
    /// roulette scale `split`) ends here: by Russian roulette on the
    /// largest lane weight from the second scattering on (the survivor's
    /// weight divided by its chance), else only where every active lane's
    /// weight is zero.
    pub(super) fn ends(
        &self,
        beta: &mut Lanes,
        depth: u32,
        split: f64,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> bool {
        if self.plan.termination.russian_roulette && depth >= 2 {
            !survives_roulette(beta, lanes.active, depth, split, rng)
        } else {
            beta[..lanes.active].iter().all(|&b| b == 0.0)
        }
    }

    /// Expected light a path finds going on from `x`, per unit weight, up
    /// to a constant: the guide's mean once-scattered radiance there.
    pub(super) fn importance(&self, x: DVec3) -> Option<f64> {
        self.guide
            .filter(|_| self.plan.termination.russian_roulette && self.plan.termination.splitting)
            .map(|g| g.skylight(self.medium, x))
            .filter(|&s| s > 0.0 && s.is_finite())
    }

    /// `copies` copies of a path scattered at `x` along `dir_in`
    /// (coefficients `c`, weight `beta` before the direction's factor),
    /// sharing its weight, each with its own direction: all but one walk on
    /// here; the last is returned.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn copies(
        &self,
        (x, dir_in, c, control): (
            DVec3,
            DVec3,
            &crate::render::medium::Coefficients,
            Option<&ControlAt<'a>>,
        ),
        beta: Lanes,
        copies: usize,
        walk: Walk,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> (Vertex, Option<GuideAt<'a>>) {
        let share = 1.0 / copies as f64;
        let beta = beta.map(|b| b * share);
        for _ in 1..copies {
            let mut copy = beta;
            let (new_dir, _) = self.scatter(x, dir_in, c, &mut copy, lanes, rng);
            if let Some(control) = control {
                control.subtract(lanes, new_dir, &copy, radiance);
            }
            self.walk((x, new_dir, copy), walk, lanes, radiance, rng);
        }
        let mut last = beta;
        let (new_dir, at) = self.scatter(x, dir_in, c, &mut last, lanes, rng);
        if let Some(control) = control {
            control.subtract(lanes, new_dir, &last, radiance);
        }
        ((x, new_dir, last), at)
    }

    /// Adjoint-driven roulette and splitting at a real scattering at `x`
    /// (coefficients `c`, weight `beta` before the direction's factor):
    /// the path's expected light relative to its window's reference (its
    /// start's) picks how many copies go on (0 = ended; survivors' weights
    /// are divided by their chance, copies share the weight), returned with
    /// the copies' window. Where a cap ([`MAX_SPLIT`] per vertex,
    /// [`MAX_COPIES`] per start) leaves each copy at or above the splitting
    /// threshold, their reference rises to their expected light, so a start
    /// with next to no light (where the guide's table fades to zero, or
    /// deep in a thick haze) cannot make every later vertex split again.
    pub(super) fn weight_window(
        &self,
        x: DVec3,
        c: &crate::render::medium::Coefficients,
        beta: &mut Lanes,
        (depth, split, window): (u32, f64, Window),
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<(usize, Window)> {
        let Window { reference, copies } = window;
        let here = self.importance(x)?;
        let weight = (0..lanes.active)
            .map(|j| beta[j] * c.scattering(j))
            .fold(0.0, f64::max);
        let expected = split * weight * here / reference;
        if expected < ROULETTE_WEIGHT || depth >= ROULETTE_CAP_DEPTH {
            let mut survive = (expected / ROULETTE_WEIGHT).min(1.0);
            if depth >= ROULETTE_CAP_DEPTH {
                survive = survive.min(0.9);
            }
            if rng.uniform() >= survive {
                return Some((0, window));
            }
            *beta /= survive;
            return Some((1, window));
        }
        if expected >= SPLIT_WEIGHT {
            let room = (MAX_COPIES / copies).max(1);
            let split_into = (expected.floor() as usize).min(MAX_SPLIT).min(room);
            let each = expected / split_into as f64;
            let lifted = if each >= SPLIT_WEIGHT {
                reference * each
            } else {
                reference
            };
            let window = Window {
                reference: lifted,
                copies: copies * split_into,
            };
            return Some((split_into, window));
        }
        Some((1, window))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::{IntegratorOptions, TechniquePlan};
    use crate::render::guide::SkyGuide;
    use crate::render::medium::{Medium, LANES};

    #[test]
    fn the_weight_window_splits_within_its_cap_and_roulettes_dim_paths() {
        use crate::atmosphere::{Atmosphere, AtmosphereParams};
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let sun = crate::render::direction_from_az_el(270.0, -4.0);
        let guide = SkyGuide::new(&medium, sun);
        let plan = TechniquePlan::outside_a_scene(&IntegratorOptions {
            splitting: Some(true),
            ..IntegratorOptions::default()
        });
        let integrator = Integrator::new(&medium, &plan, sun).with_sky_guide(&guide);
        let lanes = SpectralLanes::new(
            Lanes::from([450.0, 520.0, 590.0, 660.0]),
            LANES,
            &medium,
            false,
        );
        let x = DVec3::new(0.0, 0.0, medium.planet_radius_m + 20_000.0);
        let c = medium.coefficients(x.length(), &lanes);
        let here = integrator
            .importance(x)
            .expect("light reaches 20 km at twilight");
        let sigma = (0..LANES).map(|j| c.scattering(j)).fold(0.0, f64::max);
        let mut rng = Rng::new(1, 2);
        // Weights for a given expected light relative to a reference of 1.
        let beta_for = |expected: f64| Lanes::splat(expected / (sigma * here));
        let start = |reference: f64| Window {
            reference,
            copies: 1,
        };
        let window = |beta: &mut Lanes, window: Window, rng: &mut Rng| {
            let (copies, window) = integrator
                .weight_window(x, &c, beta, (3, 1.0, window), &lanes, rng)
                .unwrap();
            (copies, window.reference, window.copies)
        };
        // Inside the window: one copy, nothing changes.
        let mut beta = beta_for(1.0);
        assert_eq!(window(&mut beta, start(1.0), &mut rng), (1, 1.0, 1));
        assert_eq!(beta, beta_for(1.0));
        // 3× the start's light: three copies, same reference.
        assert_eq!(
            window(&mut beta_for(3.0), start(1.0), &mut rng),
            (3, 1.0, 3)
        );
        // A start with next to no light: the cap holds, and the copies'
        // reference rises to their expected light.
        let (copies, reference, lineage) = window(&mut beta_for(1.0), start(1e-30), &mut rng);
        assert_eq!((copies, lineage), (MAX_SPLIT, MAX_SPLIT));
        let each = 1e30 / MAX_SPLIT as f64;
        assert!((reference / (each * 1e-30) - 1.0).abs() < 1e-9);
        let lifted = Window {
            reference,
            copies: lineage,
        };
        let (again, _, _) = window(&mut beta_for(1.0 / MAX_SPLIT as f64), lifted, &mut rng);
        assert!(again <= 1, "copies split again: {again}");
        // A path already one of MAX_COPIES / 2 copies of its start splits
        // into 2 at most, however bright; one of MAX_COPIES, not at all,
        // and its reference rises to its expected light.
        let many = |copies: usize| Window {
            reference: 1.0,
            copies,
        };
        let (copies, reference, lineage) =
            window(&mut beta_for(100.0), many(MAX_COPIES / 2), &mut rng);
        assert_eq!((copies, lineage), (2, MAX_COPIES));
        assert!((reference - 50.0).abs() < 1e-9);
        let (copies, reference, lineage) = window(&mut beta_for(100.0), many(MAX_COPIES), &mut rng);
        assert_eq!((copies, lineage), (1, MAX_COPIES));
        assert!((reference - 100.0).abs() < 1e-9);
        // A tenth of the start's light: survives 40 % of the time, with
        // its weight divided by 0.4.
        let trials = 20_000;
        let mut survived = 0;
        for _ in 0..trials {
            let mut beta = beta_for(0.1);
            let (copies, _, _) = window(&mut beta, start(1.0), &mut rng);
            if copies == 1 {
                survived += 1;
                assert!((beta[0] / beta_for(0.1)[0] - 2.5).abs() < 1e-9);
            }
        }
        let rate = f64::from(survived) / f64::from(trials);
        let sigma_rate = (0.4 * 0.6 / f64::from(trials)).sqrt();
        assert!((rate - 0.4).abs() < 5.0 * sigma_rate, "survival {rate}");
    }
}
