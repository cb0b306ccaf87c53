//! The splats' transmittance from the observer, by a table and a
//! randomly corrected share.
//!
//! Every splat ([`super::circles`], [`super::ground_circles`]) needs the
//! transmittance T from the observer O to its point, the largest single
//! cost of a splat (`BENCHMARKS.md`): each is an unbiased residual ratio
//! tracking against the column table ([`super::columns::FixedStart`]),
//! its look-ups (the slant factor's Hermite patch, the vertical column)
//! and its events. Seen from one fixed point, though, the optical depth
//! along a ray depends only on the ray's cosine μ to the observer's
//! zenith and its length t (the atmosphere is spherically symmetric), and
//! its column amounts, one per profile, are smooth in both: this module
//! tabulates them once per observer, and a look-up is one bilinear
//! interpolation, T̃ = exp(−Σ σ_X C̃_X).
//!
//! T̃ is an approximation; the estimate stays unbiased by correcting it
//! on a random share q ([`CORRECTED_SHARE`]) of the rays with the unbiased
//! estimate T̂ ([`super::debias`]): X = T̃ + 𝟙(u < q) (T̂ − T̃) / q. The
//! price, Var T̂ / q + (1/q − 1)(T − T̃)², the tracking's own spread and the
//! table's error, is small beside a splat's path estimate (`BENCHMARKS.md`).
//!
//! **The table.** Rays below the cosine μ_g = −√(1 − (R/r₀)²) meet the
//! ground, the others leave through the top; each set has its own fan of
//! `FAN_NODES` cosines, μ = μ_g ± span·x² for x uniform (dense about the
//! horizon, where the columns change fastest), so no cell straddles the
//! ground's edge. Along each node's ray the columns are kept at
//! `LENGTH_NODES` lengths s = y² of the ray's whole length (dense near
//! the observer, where the air is densest), integrated by Simpson's rule
//! through the profiles.
//!
//! A point the ground hides gives `None`, as the unbiased estimate does —
//! only where it certainly does (beyond the ground by a margin), so the
//! few rays the estimate would call hidden and the table not are left to
//! the correction, which takes them to zero in expectation.

use glam::DVec3;
use rayon::prelude::*;

use super::columns::{ColumnTable, FixedStart, Profiles, PROFILES};
use super::debias::corrected;
use super::integrator::Integrator;
use super::medium::{Lanes, Medium, SpectralLanes};
use crate::rng::Rng;

/// Cosine nodes per fan (the ground's and the sky's).
const FAN_NODES: usize = 129;
/// Length nodes per ray.
const LENGTH_NODES: usize = 65;
/// Simpson intervals between two length nodes (even).
const SIMPSON_STEPS: usize = 8;
/// The share q of the splats' transmittances that also take the unbiased
/// estimate and correct the table's: the correction's variance grows as
/// 1/q, but from a small base (the table within 2 % of T, the tracking's
/// spread a few per cent) beside a splat's path estimate, whose relative
/// spread is of order 1. The corrections' tracking is what costs: at 1/16
/// it took about as long as the table's look-ups, and 1/64 renders faster
/// for no noise measurable over many seeds, while 1/8 bought nothing over
/// 1/16 (`BENCHMARKS.md`).
pub const CORRECTED_SHARE: f64 = 1.0 / 64.0;
/// A point farther than the ground by this relative margin (and
/// [`HIDDEN_MARGIN_M`]) is hidden.
const HIDDEN_MARGIN: f64 = 1e-6;
/// See [`HIDDEN_MARGIN`], m.
const HIDDEN_MARGIN_M: f64 = 1e-3;

/// One fan of rays: cosines μ = `edge` + `span` x², x uniform on [0, 1].
struct Fan {
    edge: f64,
    span: f64,
    /// Columns at (cosine node i, length node j), `[i * LENGTH_NODES + j]`.
    columns: Vec<Profiles>,
}

impl Fan {
    /// The fan's node coordinate of cosine `mu` (clamped to the fan).
    fn coordinate(&self, mu: f64) -> f64 {
        ((mu - self.edge) / self.span).max(0.0).sqrt().min(1.0)
    }

    /// The cosine of node `i`.
    fn cosine(&self, i: usize) -> f64 {
        let x = i as f64 / (FAN_NODES - 1) as f64;
        self.edge + self.span * x * x
    }
}

/// The column amounts along every ray from one observer, tabulated over
/// the ray's cosine and length.
pub struct ObserverDepths {
    position_m: DVec3,
    radius_m: f64,
    planet_radius_m: f64,
    top_radius_m: f64,
    /// μ_g: rays below it meet the ground.
    ground_cosine: f64,
    /// Rays that meet the ground (μ from μ_g down to −1).
    ground: Fan,
    /// Rays that leave through the top (μ from μ_g up to 1).
    sky: Fan,
}

impl ObserverDepths {
    /// The table of `medium` at `position_m` (inside the atmosphere).
    pub fn new(medium: &Medium, position_m: DVec3) -> Self {
        let table = medium.column_table();
        let radius_m = position_m.length();
        let planet_radius_m = medium.planet_radius_m;
        let top_radius_m = medium.top_radius_m;
        let ratio = (planet_radius_m / radius_m).min(1.0);
        let ground_cosine = -(1.0 - ratio * ratio).max(0.0).sqrt();
        let mut depths = Self {
            position_m,
            radius_m,
            planet_radius_m,
            top_radius_m,
            ground_cosine,
            ground: Fan {
                edge: ground_cosine,
                span: -1.0 - ground_cosine,
                columns: Vec::new(),
            },
            sky: Fan {
                edge: ground_cosine,
                span: 1.0 - ground_cosine,
                columns: Vec::new(),
            },
        };
        depths.ground.columns = depths.fan_columns(table, &depths.ground, true);
        depths.sky.columns = depths.fan_columns(table, &depths.sky, false);
        depths
    }

    /// The length of the ray of cosine `mu` to the ground (`to_ground`) or
    /// to the top.
    fn ray_length(&self, mu: f64, to_ground: bool) -> f64 {
        let b = self.radius_m * mu;
        let across2 = self.radius_m * self.radius_m - b * b;
        if to_ground {
            let d2 = self.planet_radius_m * self.planet_radius_m - across2;
            (-b - d2.max(0.0).sqrt()).max(0.0)
        } else {
            let d2 = self.top_radius_m * self.top_radius_m - across2;
            (-b + d2.max(0.0).sqrt()).max(0.0)
        }
    }

    /// The profiles at distance `t_m` along the ray of cosine `mu`.
    fn profiles_at(&self, table: &ColumnTable, mu: f64, t_m: f64) -> Profiles {
        let r2 = self.radius_m * self.radius_m + 2.0 * self.radius_m * mu * t_m + t_m * t_m;
        table.profiles(r2.max(0.0).sqrt() - self.planet_radius_m)
    }

    /// Every node's columns of `fan`.
    fn fan_columns(&self, table: &ColumnTable, fan: &Fan, to_ground: bool) -> Vec<Profiles> {
        (0..FAN_NODES)
            .into_par_iter()
            .flat_map_iter(|i| {
                let mu = fan.cosine(i);
                let length = self.ray_length(mu, to_ground);
                let mut sum = [0.0; PROFILES];
                let mut columns = Vec::with_capacity(LENGTH_NODES);
                columns.push(sum);
                let mut t0 = 0.0;
                for j in 1..LENGTH_NODES {
                    let y = j as f64 / (LENGTH_NODES - 1) as f64;
                    let t1 = length * y * y;
                    let h = (t1 - t0) / SIMPSON_STEPS as f64;
                    for k in 0..=SIMPSON_STEPS {
                        let w = match k {
                            0 | SIMPSON_STEPS => 1.0,
                            k if k % 2 == 1 => 4.0,
                            _ => 2.0,
                        } * h
                            / 3.0;
                        let n = self.profiles_at(table, mu, t0 + h * k as f64);
                        for p in 0..PROFILES {
                            sum[p] += w * n[p];
                        }
                    }
                    columns.push(sum);
                    t0 = t1;
                }
                columns
            })
            .collect()
    }

    /// The table's columns from the observer along the unit direction
    /// `dir` to distance `t_m`; `None` where the ground certainly hides
    /// that point.
    pub fn columns(&self, dir: DVec3, t_m: f64) -> Option<Profiles> {
        let mu = self.position_m.dot(dir) / self.radius_m;
        let to_ground = mu < self.ground_cosine;
        let length = self.ray_length(mu, to_ground);
        if to_ground && t_m > length * (1.0 + HIDDEN_MARGIN) + HIDDEN_MARGIN_M {
            return None;
        }
        let fan = if to_ground { &self.ground } else { &self.sky };
        let s = if length > 0.0 {
            (t_m / length).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let x = fan.coordinate(mu) * (FAN_NODES - 1) as f64;
        let y = s.sqrt() * (LENGTH_NODES - 1) as f64;
        let (i, j) = (
            (x as usize).min(FAN_NODES - 2),
            (y as usize).min(LENGTH_NODES - 2),
        );
        let (fx, fy) = (x - i as f64, y - j as f64);
        let at = |i: usize, j: usize| &fan.columns[i * LENGTH_NODES + j];
        let (a, b, c, d) = (at(i, j), at(i, j + 1), at(i + 1, j), at(i + 1, j + 1));
        Some(std::array::from_fn(|p| {
            let near = a[p] + fy * (b[p] - a[p]);
            let far = c[p] + fy * (d[p] - c[p]);
            near + fx * (far - near)
        }))
    }

    /// T̃: the table's transmittance per lane to distance `t_m` along `dir`
    /// (`None` where the ground hides the point).
    pub fn transmittance(&self, dir: DVec3, t_m: f64, lanes: &SpectralLanes) -> Option<Lanes> {
        let depth = lanes.control(self.columns(dir, t_m)?);
        Some(Lanes::from_fn(|j| (-depth[j]).exp()))
    }
}

/// The observer's two look-ups for its rays: the column table's at the
/// observer (the unbiased estimate's) and the observer's own table.
pub struct ObserverRays {
    start: FixedStart,
    depths: ObserverDepths,
}

impl ObserverRays {
    /// Both tables of `medium` at `position_m` (inside the atmosphere).
    pub fn new(medium: &Medium, position_m: DVec3) -> Self {
        Self {
            start: FixedStart::new(medium.column_table(), position_m),
            depths: ObserverDepths::new(medium, position_m),
        }
    }

    /// The observer's table's transmittance T̃ per lane along the unit
    /// direction `dir` to distance `t_m`, uncorrected (`None` where the
    /// ground hides the point): a deterministic function of the ray.
    pub fn table_transmittance(
        &self,
        dir: DVec3,
        t_m: f64,
        lanes: &SpectralLanes,
    ) -> Option<Lanes> {
        self.depths.transmittance(dir, t_m, lanes)
    }

    /// The column table's look-ups at the observer.
    pub fn start(&self) -> &FixedStart {
        &self.start
    }

    /// The transmittance from the observer along the unit direction `dir`
    /// to distance `t_m`, unbiased: T̃, and on a share [`CORRECTED_SHARE`]
    /// of the calls (`rng`'s next number) its correction by
    /// `integrator`'s estimate (module doc); `None` where the ground hides
    /// the point. Without the plan's `splat_transmittance_table`,
    /// `integrator`'s estimate alone.
    pub fn transmittance(
        &self,
        integrator: &Integrator<'_>,
        dir: DVec3,
        t_m: f64,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<Lanes> {
        if !integrator.plan.splat_transmittance_table {
            return integrator.transmittance_from(&self.start, dir, t_m, lanes, rng);
        }
        let approx = self.depths.transmittance(dir, t_m, lanes)?;
        Some(corrected(approx, CORRECTED_SHARE, rng, |rng| {
            integrator
                .transmittance_from(&self.start, dir, t_m, lanes, rng)
                .unwrap_or(Lanes::splat(0.0))
        }))
    }

    /// What [`Self::transmittance`] adds to the table's T̃ along the same
    /// ray: on a share [`CORRECTED_SHARE`] of the calls (`rng`'s next
    /// number) the unbiased estimate less T̃ (`table`, asked for only
    /// then; `None` where the ground hides the point), over the share;
    /// else `None`. For a caller that holds T̃ × its light as a control of
    /// its own, so that T̃ + this keeps T's expectation.
    pub fn correction(
        &self,
        integrator: &Integrator<'_>,
        dir: DVec3,
        t_m: f64,
        lanes: &SpectralLanes,
        table: impl FnOnce() -> Option<Lanes>,
        rng: &mut Rng,
    ) -> Option<Lanes> {
        if rng.uniform() >= CORRECTED_SHARE {
            return None;
        }
        let table = table()?;
        let exact = integrator
            .transmittance_from(&self.start, dir, t_m, lanes, rng)
            .unwrap_or(Lanes::splat(0.0));
        Some(Lanes::from_fn(|j| (exact[j] - table[j]) / CORRECTED_SHARE))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::plan::{Conditions, IntegratorOptions, TechniquePlan};
    use crate::render::debias::mean_and_error;
    use crate::render::direction_from_az_el;
    use crate::render::medium::LANES;

    /// The sunset's medium, plan and sun.
    fn sunset() -> (Medium, TechniquePlan, DVec3) {
        let medium = Medium::new(&Atmosphere::new(AtmosphereParams::default()));
        let plan = TechniquePlan::new(
            &IntegratorOptions::default(),
            &Conditions::new(2.0, &AtmosphereParams::default(), true),
        );
        (medium, plan, direction_from_az_el(270.0, 2.0))
    }

    /// Rays from `altitude_m` at each elevation (°) to each fraction of
    /// the ray's length inside the atmosphere (at most 300 km).
    fn rays(medium: &Medium, altitude_m: f64) -> (ObserverRays, Vec<(DVec3, f64)>) {
        let observer = DVec3::new(0.0, 0.0, medium.planet_radius_m + altitude_m);
        let rays = ObserverRays::new(medium, observer);
        let mut list = Vec::new();
        for elevation in [-60.0, -5.0, -1.0, -0.1, 0.0, 0.5, 2.0, 10.0, 45.0, 90.0] {
            let dir = direction_from_az_el(30.0, elevation);
            let to_ground = dir.z < rays.depths.ground_cosine;
            let length = rays.depths.ray_length(dir.z, to_ground);
            for fraction in [0.001, 0.01, 0.1, 0.5, 0.999] {
                list.push((dir, (length * fraction).min(300e3)));
            }
        }
        (rays, list)
    }

    /// The unbiased estimate's mean and standard error at a ray.
    fn estimate(
        integrator: &Integrator<'_>,
        rays: &ObserverRays,
        (dir, t): (DVec3, f64),
        lanes: &SpectralLanes,
        n: u64,
    ) -> (Lanes, Lanes) {
        mean_and_error(n, |k| {
            let mut rng = Rng::new(5, k);
            integrator
                .transmittance_from(rays.start(), dir, t, lanes, &mut rng)
                .unwrap_or(Lanes::splat(0.0))
        })
    }

    /// The table is within 2 % of the unbiased estimate's mean wherever
    /// the transmittance is above 10⁻³, from the ground and from 10 km, and
    /// that estimate's own spread is small (≤ 12 % of its mean; ≤ 5 % where
    /// T > 0.1): the correction's variance, (Var T̂ + (T − T̃)²) / q, stays
    /// well below a splat's.
    #[test]
    fn the_table_follows_the_unbiased_estimate() {
        let (medium, plan, sun) = sunset();
        let integrator = Integrator::new(&medium, &plan, sun);
        let lanes = SpectralLanes::new(Lanes::from([400.0, 500.0, 600.0, 700.0]), 4, &medium, true);
        for altitude_m in [2.0, 10_000.0] {
            let (rays, list) = rays(&medium, altitude_m);
            for (dir, t) in list {
                let approx = rays.depths.transmittance(dir, t, &lanes).unwrap();
                let (exact, error) = estimate(&integrator, &rays, (dir, t), &lanes, 2000);
                for j in 0..LANES {
                    let spread = error[j] * 2000f64.sqrt() / exact[j];
                    let at = format!("{altitude_m} m, {dir}, {t} m, lane {j}");
                    if exact[j] > 1e-3 {
                        assert!(
                            (approx[j] / exact[j] - 1.0).abs() < 0.02,
                            "{at}: {approx:?} {exact:?}"
                        );
                    }
                    if exact[j] > 1e-6 {
                        assert!(spread < 0.12, "{at}: {spread}");
                    }
                    if exact[j] > 0.1 {
                        assert!(spread < 0.05, "{at}: {spread}");
                    }
                }
            }
        }
    }

    /// The corrected table's mean agrees with the unbiased estimate's
    /// within four standard errors at every ray — and so does a
    /// correction of an approximation 30 % off, for which leaving out the
    /// correction's 1/q (or the correction itself) would be many standard
    /// errors away.
    #[test]
    fn the_corrected_table_is_unbiased() {
        // The table corrected, a table 0.7 times too dark corrected, and
        // that table plus `ObserverRays::correction`: each within 4
        // standard errors of the unbiased estimate.
        let (medium, plan, sun) = sunset();
        let integrator = Integrator::new(&medium, &plan, sun);
        let lanes = SpectralLanes::new(Lanes::from([420.0, 520.0, 620.0, 720.0]), 4, &medium, true);
        let (rays, list) = rays(&medium, 2.0);
        for ray in list.into_iter().step_by(3) {
            let (dir, t) = ray;
            let (exact, exact_error) = estimate(&integrator, &rays, ray, &lanes, 4000);
            let (table, table_error) = mean_and_error(40_000, |k| {
                let mut rng = Rng::new(9, k);
                rays.transmittance(&integrator, dir, t, &lanes, &mut rng)
                    .unwrap()
            });
            let approx = rays.depths.transmittance(dir, t, &lanes).unwrap();
            let (off, off_error) = mean_and_error(40_000, |k| {
                let mut rng = Rng::new(11, k);
                corrected(
                    Lanes::from_fn(|j| approx[j] * 0.7),
                    CORRECTED_SHARE,
                    &mut rng,
                    |rng| {
                        integrator
                            .transmittance_from(rays.start(), dir, t, &lanes, rng)
                            .unwrap_or(Lanes::splat(0.0))
                    },
                )
            });
            // The correction alone, added by its caller to a T̃ as far off.
            let off_table = Lanes::from_fn(|j| approx[j] * 0.7);
            let (added, added_error) = mean_and_error(40_000, |k| {
                let mut rng = Rng::new(13, k);
                let correction =
                    rays.correction(&integrator, dir, t, &lanes, || Some(off_table), &mut rng);
                off_table + correction.unwrap_or(Lanes::splat(0.0))
            });
            for j in 0..LANES {
                for (mean, error) in [
                    (table[j], table_error[j]),
                    (off[j], off_error[j]),
                    (added[j], added_error[j]),
                ] {
                    let sigma = (error * error + exact_error[j] * exact_error[j]).sqrt();
                    assert!(
                        (mean - exact[j]).abs() <= 4.0 * sigma + 1e-9 * exact[j],
                        "{dir} {t} m lane {j}: {mean} ± {error} against {} ± {}",
                        exact[j],
                        exact_error[j]
                    );
                }
                if exact[j] > 0.01 {
                    assert!((0.3 * approx[j]) > 8.0 * off_error[j], "the test can fail");
                }
            }
        }
    }

    /// A point beyond the ground is hidden for the table as for the
    /// unbiased estimate; one just short of it is not.
    #[test]
    fn the_ground_hides_what_it_hides() {
        let (medium, plan, sun) = sunset();
        let integrator = Integrator::new(&medium, &plan, sun);
        let lanes = SpectralLanes::new(Lanes::from([550.0; LANES]), 1, &medium, true);
        for altitude_m in [2.0, 10_000.0] {
            let observer = DVec3::new(0.0, 0.0, medium.planet_radius_m + altitude_m);
            let rays = ObserverRays::new(&medium, observer);
            for elevation in [-90.0, -30.0, -3.0, -0.5] {
                let dir = direction_from_az_el(10.0, elevation);
                let ground = rays.depths.ray_length(dir.z, true);
                if dir.z >= rays.depths.ground_cosine {
                    continue;
                }
                let mut rng = Rng::new(1, 2);
                for t in [ground * 0.999, ground * 1.001] {
                    let table = rays.transmittance(&integrator, dir, t, &lanes, &mut rng);
                    let exact =
                        integrator.transmittance_from(rays.start(), dir, t, &lanes, &mut rng);
                    assert_eq!(
                        table.is_some(),
                        exact.is_some(),
                        "{altitude_m} m, {elevation}°, {t} m"
                    );
                    assert_eq!(table.is_some(), t < ground, "{altitude_m} m, {elevation}°");
                }
            }
        }
    }
}
