//! The sky model's tables of the light scattered twice or more: one
//! scattering order at a time from the one before (Bruneton & Neyret
//! 2008), the sky's irradiance on the ground by order, and the tables of
//! one atmosphere kept for the next renderer of the same optics.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex, OnceLock};
use std::thread::JoinHandle;

use glam::DVec3;
use rayon::prelude::*;

use super::optics::{
    add_product, add_scaled, altitude_of, node_groups, node_wavelength, split, view_azimuth_of,
    view_cosine_index, view_cosine_of, view_zenith_cosine_of, zenith_cosine_of,
    zenith_cosine_of_node, MsTable, Optics, Phases, Quadrature, SkyIrradiance, Sources, Spectrum,
    E_ZENITHS, GROUND_DIRECTIONS_HIGHER, GROUPS, MS_ALTITUDES, MS_DIRECTIONS,
    MS_DIRECTIONS_AT_CORE, MS_DIRECTIONS_AT_SUN, MS_DIRECTIONS_NEAR_SUN, MS_VIEW_ANGLES,
    MS_VIEW_AZIMUTHS, MS_VIEW_ZENITHS, MS_ZENITHS, NODES, SUN_CAP_COSINE, SUN_CORE_CAP_COSINE,
    SUN_INNER_CAP_COSINE, TABLE_STEPS, TABLE_STEPS_HIGHER,
};
use super::stored;
use crate::render::lanes::LaneTable;
use crate::render::medium::{Lanes, Medium, SpectralLanes, LANES};

/// One solar zenith's entries of an [`MsTable`]: the ν table's and the
/// view sums'.
type ZenithEntries = (Vec<[Spectrum; 2]>, Vec<[Spectrum; 2]>);

/// Whether a build of the tables is to be given up: asked once per table
/// and solar zenith (a few tens of milliseconds of work apart).
type Cancelled<'a> = &'a (dyn Fn() -> bool + Sync);

impl MsTable {
    /// The light scattered once more than `previous`'s: from the sunlight
    /// scattered once (and the sunlit ground) without it, else from the
    /// light of the previous order (its table J_n, and the ground lit by
    /// the sky of the order before, E_{n−1}), summed over `quadrature`'s
    /// directions with the phase functions averaged over their cells: the
    /// sums below stand for integrals over the sphere, and a forward peak
    /// narrower than the directions' spacing would be hit or missed from
    /// one view to the next. That holds for the once-scattered light
    /// arriving from each direction too (the aureole about the sun).
    fn scattered(
        optics: &Optics<'_>,
        previous: Option<(&MsTable, &SkyIrradiance)>,
        quadrature: &Quadrature,
        cancelled: Cancelled<'_>,
    ) -> Option<Self> {
        let medium = optics.medium;
        let (planet_radius_m, top_m) = (
            medium.planet_radius_m,
            medium.top_radius_m - medium.planet_radius_m,
        );
        // Per solar zenith (the sun's direction, and so every phase
        // function value, is the same at each altitude): the altitudes' rows.
        let per_zenith: Vec<ZenithEntries> = (0..MS_ZENITHS)
            .into_par_iter()
            .map(|k| {
                if cancelled() {
                    return None;
                }
                let (sun, cell_optics) = optics.with_sun_at(zenith_cosine_of(k as f64));
                // Views at ν from the sun, in the plane of the sun and the
                // zenith and across it, each weighted ½.
                let (toward, across) = (DVec3::new(-sun.z, 0.0, sun.x), DVec3::Y);
                let views: Vec<DVec3> = (0..MS_VIEW_ANGLES)
                    .flat_map(|a| {
                        let nu = view_cosine_of(a);
                        let sin = (1.0 - nu * nu).max(0.0).sqrt();
                        [sun * nu + toward * sin, sun * nu + across * sin]
                    })
                    .collect();
                let points: Vec<(DVec3, f64, &Phases)> = quadrature.points(sun).collect();
                let phases_toward = |v: DVec3| -> Vec<(Spectrum, Spectrum)> {
                    points
                        .iter()
                        .map(|(d, _, cells)| cells.at(d.dot(v)))
                        .collect()
                };
                // The phase functions toward a view, each scaled so that
                // the quadrature sums it to one, as its integral over the
                // sphere is: a forward peak a few cells wide is summed
                // over a lattice whose points fall differently about each
                // view, and its sum strayed by ±15 % from view to view
                // (the Martian dust's sky at sunset in rings 60° from the
                // sun). The light arriving is smooth there, so the
                // normalised sum is the light about the peak.
                let normalised_toward = |v: DVec3| -> Vec<(Spectrum, Spectrum)> {
                    let mut phases = phases_toward(v);
                    let (mut sum_r, mut sum_a) = ([0.0; NODES], [0.0; NODES]);
                    for ((_, weight, _), (pr, pa)) in points.iter().zip(&phases) {
                        for n in 0..NODES {
                            sum_r[n] += weight * pr[n];
                            sum_a[n] += weight * pa[n];
                        }
                    }
                    let scale = |sum: f64| if sum > 0.0 { 1.0 / sum } else { 1.0 };
                    for (pr, pa) in &mut phases {
                        for n in 0..NODES {
                            pr[n] *= scale(sum_r[n]);
                            pa[n] *= scale(sum_a[n]);
                        }
                    }
                    phases
                };
                let to_sun = phases_toward(sun);
                // Per altitude, each direction's light times its solid angle.
                let arriving: Vec<Vec<Spectrum>> = (0..MS_ALTITUDES)
                    .map(|i| {
                        let r = planet_radius_m + altitude_of(i, MS_ALTITUDES, top_m);
                        let origin = DVec3::new(0.0, 0.0, r);
                        points
                            .iter()
                            .zip(&to_sun)
                            .map(|(&(dir, weight, _), (pr, pa))| match previous {
                                None => {
                                    let once = Sources {
                                        sunlight: true,
                                        ms: None,
                                        ground_sun: true,
                                        ground_sky: None,
                                    };
                                    let g = cell_optics.march(origin, dir, TABLE_STEPS, once);
                                    std::array::from_fn(|n| {
                                        weight
                                            * (pr[n] * g.rayleigh[n]
                                                + pa[n] * g.aerosol[n]
                                                + g.isotropic[n])
                                    })
                                }
                                Some((table, sky)) => {
                                    let order = Sources {
                                        sunlight: false,
                                        ms: Some(table),
                                        ground_sun: false,
                                        ground_sky: Some(sky),
                                    };
                                    let g =
                                        cell_optics.march(origin, dir, TABLE_STEPS_HIGHER, order);
                                    g.isotropic.map(|v| weight * v)
                                }
                            })
                            .collect()
                    })
                    .collect();
                // Per altitude, Σ_ω L(ω) P(ω·v) Δω summed over `views` (R
                // and A): one view's phase functions at a time, read by
                // every altitude's light.
                let sums = |views: &[DVec3]| -> Vec<[Spectrum; 2]> {
                    let mut out = vec![[[0.0; NODES]; 2]; MS_ALTITUDES];
                    for &v in views {
                        let phases = normalised_toward(v);
                        for (o, light) in out.iter_mut().zip(&arriving) {
                            let (mut r, mut a) = ([0.0; NODES], [0.0; NODES]);
                            for (l, (pr, pa)) in light.iter().zip(&phases) {
                                add_product(&mut r, l, pr);
                                add_product(&mut a, l, pa);
                            }
                            add_scaled(&mut o[0], 1.0, &r);
                            add_scaled(&mut o[1], 1.0, &a);
                        }
                    }
                    out
                };
                // The ν table's views in pairs (each weighted ½), then the
                // views at each tabulated zenith, at azimuths from the sun
                // spread over a half turn (the other half mirrors them): J
                // there (the ν table's at its angle to the sun is read
                // when the factors are made).
                let nu_sums: Vec<Vec<[Spectrum; 2]>> = views
                    .chunks(2)
                    .map(|pair| {
                        let mut out = sums(pair);
                        for o in &mut out {
                            *o = o.map(|x| x.map(|v| 0.5 * v));
                        }
                        out
                    })
                    .collect();
                let zenith_sums: Vec<Vec<[Spectrum; 2]>> = (0..MS_VIEW_ZENITHS * MS_VIEW_AZIMUTHS)
                    .map(|view| {
                        sums(&[zenith_view(
                            view / MS_VIEW_AZIMUTHS,
                            view % MS_VIEW_AZIMUTHS,
                        )])
                    })
                    .collect();
                // Altitude by altitude: its ν row, then its views' sums.
                let values = (0..MS_ALTITUDES)
                    .flat_map(|i| nu_sums.iter().map(move |at| at[i]))
                    .collect();
                let sums = (0..MS_ALTITUDES)
                    .flat_map(|i| zenith_sums.iter().map(move |at| at[i]))
                    .collect();
                Some((values, sums))
            })
            .collect::<Option<_>>()?;
        // Reordered to (altitude, zenith, ν) and (altitude, zenith, μ_v).
        let cell = |index: usize, rows: usize| {
            let (cell, a) = (index / rows, index % rows);
            let (i, k) = (cell / MS_ZENITHS, cell % MS_ZENITHS);
            (k, i * rows + a)
        };
        let values = (0..MS_ALTITUDES * MS_ZENITHS * MS_VIEW_ANGLES)
            .map(|index| {
                let (k, at) = cell(index, MS_VIEW_ANGLES);
                per_zenith[k].0[at]
            })
            .collect();
        let zenith_sums = (0..MS_ALTITUDES * MS_ZENITHS * MS_VIEW_ZENITHS * MS_VIEW_AZIMUTHS)
            .map(|index| {
                let (k, at) = cell(index, MS_VIEW_ZENITHS * MS_VIEW_AZIMUTHS);
                per_zenith[k].1[at]
            })
            .collect();
        let mut table = Self {
            planet_radius_m,
            top_m,
            values,
            zenith_sums,
            zenith_factors: Vec::new(),
        };
        table.update_factors();
        Some(table)
    }

    /// Every number the orders add up: the ν table's, then the zenith
    /// sums' (the factors follow from them).
    fn numbers(&self) -> impl Iterator<Item = &f64> {
        let sums = self.zenith_sums.iter().flatten().flatten();
        self.values.iter().flatten().flatten().chain(sums)
    }

    /// [`Self::numbers`], to change.
    fn numbers_mut(&mut self) -> impl Iterator<Item = &mut f64> {
        let sums = self.zenith_sums.iter_mut().flatten().flatten();
        self.values.iter_mut().flatten().flatten().chain(sums)
    }

    /// The zenith factors from the zenith sums: each the sum at its view
    /// over the ν table's at the view's angle to the sun (linear in the
    /// table's index, as its look-ups are).
    fn update_factors(&mut self) {
        let views = MS_VIEW_ZENITHS * MS_VIEW_AZIMUTHS;
        let indices: Vec<Vec<f64>> = (0..MS_ZENITHS)
            .map(|k| {
                let mu_s = zenith_cosine_of(k as f64);
                let sun = DVec3::new((1.0 - mu_s * mu_s).max(0.0).sqrt(), 0.0, mu_s);
                (0..views)
                    .map(|view| {
                        let v = zenith_view(view / MS_VIEW_AZIMUTHS, view % MS_VIEW_AZIMUTHS);
                        view_cosine_index(v.dot(sun))
                    })
                    .collect()
            })
            .collect();
        self.zenith_factors = self
            .zenith_sums
            .iter()
            .enumerate()
            .map(|(cell, direct)| {
                let (slice, view) = (cell / views, cell % views);
                let k = slice % MS_ZENITHS;
                let (a, f) = split(indices[k][view], MS_VIEW_ANGLES);
                let (lo, hi) = (
                    &self.values[slice * MS_VIEW_ANGLES + a],
                    &self.values[slice * MS_VIEW_ANGLES + a + 1],
                );
                std::array::from_fn(|x| {
                    std::array::from_fn(|n| {
                        let table = lo[x][n] + f * (hi[x][n] - lo[x][n]);
                        if table > 0.0 {
                            (direct[x][n] / table) as f32
                        } else {
                            1.0
                        }
                    })
                })
            })
            .collect();
    }
}

/// The view of the zenith factors' view zenith `z` and azimuth column `b`
/// ([`view_zenith_cosine_of`], [`view_azimuth_of`]), the sun in the x–z
/// plane ([`Optics::with_sun_at`]).
fn zenith_view(z: usize, b: usize) -> DVec3 {
    let mu = view_zenith_cosine_of(z);
    let sin = (1.0 - mu * mu).max(0.0).sqrt();
    let phi = view_azimuth_of(b);
    DVec3::new(sin * phi.cos(), sin * phi.sin(), mu)
}

impl SkyIrradiance {
    /// The irradiance of the sunlight scattered once (without `ms`) or of
    /// the light that `ms` scatters toward the ground, summed over the
    /// upward directions of `quadrature` (the once-scattered light with
    /// its cells' phase functions: the aureole is as narrow as there).
    fn scattered(
        optics: &Optics<'_>,
        ms: Option<&MsTable>,
        quadrature: &Quadrature,
        cancelled: Cancelled<'_>,
    ) -> Option<Self> {
        let medium = optics.medium;
        // Looking up from the ground, no view ray ends on it.
        let sources = Sources {
            sunlight: ms.is_none(),
            ms,
            ground_sun: false,
            ground_sky: None,
        };
        let steps = if ms.is_some() {
            TABLE_STEPS_HIGHER
        } else {
            TABLE_STEPS
        };
        let values = (0..E_ZENITHS)
            .into_par_iter()
            .map(|k| {
                if cancelled() {
                    return None;
                }
                let (sun, cell_optics) =
                    optics.with_sun_at(zenith_cosine_of_node(k as f64, E_ZENITHS));
                let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + 1.0);
                let mut e = [0.0; NODES];
                for (dir, weight, cells) in quadrature.points(sun).filter(|p| p.0.z > 0.0) {
                    let g = cell_optics.march(origin, dir, steps, sources);
                    let radiance: Spectrum = if ms.is_some() {
                        g.isotropic
                    } else {
                        let (pr, pa) = cells.at(dir.dot(sun));
                        std::array::from_fn(|n| pr[n] * g.rayleigh[n] + pa[n] * g.aerosol[n])
                    };
                    for n in 0..NODES {
                        e[n] += radiance[n] * dir.z * weight;
                    }
                }
                Some(e)
            })
            .collect::<Option<_>>()?;
        Some(Self { values })
    }
}

/// Scattering orders computed one by one ([`MsTable::scattered`]) past
/// the first.
const ORDERS: usize = 5;

/// The share of an order's light that the next one keeps, at most: past
/// it the tail's sum is taken as if it were this.
const MAX_ORDER_RATIO: f64 = 0.9;

/// Orders past which [`tail_after`] stops following a falling ratio and
/// sums the rest as a geometric series.
const TAIL_TERMS: usize = 64;

/// The light of the orders past the last computed, J_{n+1} + J_{n+2} + …,
/// at one entry from its last three orders `older`, `before`, `last`
/// (J_{n−2}, J_{n−1}, J_n), and `floor`, the whole field's ratio of its
/// last two orders.
///
/// An entry's ratio ρ_k = J_k / J_{k−1} tends, order by order, to the
/// field's own (the largest eigenvalue of the scattering operator: the
/// light of high orders is one diffuse shape whatever its source), and
/// the field's ratio of sums is near that. An entry whose ratio is
/// falling toward it (q = ρ_n / ρ_{n−1} < 1: the sky just above the
/// horizon, where the low orders' long, grazing paths give way to the
/// diffuse light) goes on falling by q per order down to `floor`; one
/// whose ratio is steady, rising or already below `floor` keeps ρ_n (the
/// geometric tail ρ_n/(1 − ρ_n) J_n). The geometric tail from ρ₅ alone
/// left Mars's sky 0–4° above its horizon at sunset 1.3–1.6× the path
/// tracer's; an entry's ratio falling on to zero left twilight's sky too
/// faint; with this tail every preset's first frame is as far from the
/// path tracer's image as with twelve orders computed (within 0.1
/// percentage point).
fn tail_after(older: f64, before: f64, last: f64, floor: f64) -> f64 {
    if !(before > 0.0 && last > 0.0) {
        return 0.0;
    }
    let rho = (last / before).min(MAX_ORDER_RATIO);
    let geometric = |ratio: f64| ratio / (1.0 - ratio);
    let q = if older > 0.0 {
        (last / before) / (before / older)
    } else {
        1.0
    };
    let floor = floor.min(rho);
    if q >= 1.0 || rho <= floor {
        return last * geometric(rho);
    }
    // J_{n+k} = J_n Π_{j ≤ k} max(ρ q^j, floor).
    let (mut sum, mut term, mut ratio) = (0.0, 1.0, rho);
    for _ in 0..TAIL_TERMS {
        ratio = (ratio * q).max(floor);
        term *= ratio;
        sum += term;
        if ratio <= floor {
            break;
        }
    }
    // Past the loop the ratio holds (at `floor`, or where it stopped).
    last * (sum + term * geometric(ratio))
}

fn scattering_orders(
    optics: &Optics<'_>,
    cancelled: Cancelled<'_>,
) -> Option<(MsTable, SkyIrradiance)> {
    // J₂ from the once-scattered light; E₁ of the once-scattered sky.
    let cells = |count: usize| optics.phases.averaged_over_cells(count);
    let (core_cells, at_sun_cells, near_cells, far_cells) = (
        cells(MS_DIRECTIONS_AT_CORE),
        cells(MS_DIRECTIONS_AT_SUN),
        cells(MS_DIRECTIONS_NEAR_SUN),
        cells(MS_DIRECTIONS),
    );
    let first = Quadrature::rings(
        &[
            (MS_DIRECTIONS_AT_CORE, SUN_CORE_CAP_COSINE),
            (MS_DIRECTIONS_AT_SUN, SUN_INNER_CAP_COSINE),
            (MS_DIRECTIONS_NEAR_SUN, SUN_CAP_COSINE),
            (MS_DIRECTIONS, -1.0),
        ],
        &[&core_cells, &at_sun_cells, &near_cells, &far_cells],
    );
    // The third order is summed over the same rings: in a dust or haze
    // thick enough, the light scattered twice is still an aureole, and the
    // third order's is the product of three peaks (with the rings of 4°
    // cells alone inside 40°, the first frame at Mars sunset read 0.95×
    // the path tracer's within 5° of the sun). The orders past it, blurred
    // by every scattering, are summed about the sun more coarsely (over
    // 32 even directions, cells of 20°, the third order near the sun at
    // Mars sunset had added a sixth of the path tracer's; outside the cap
    // as dense as the second order's: with 32 there, turning with the
    // sun, the low sky at twilight read 8 % off, not 3 %).
    let later = Quadrature::about_the_sun(
        (MS_DIRECTIONS_NEAR_SUN, MS_DIRECTIONS),
        SUN_CAP_COSINE,
        [&near_cells, &far_cells],
    );
    // Only the upward half of each set counts from the ground: twice as
    // many directions over the sphere keep the sky as finely summed, but
    // for the cap about the sun, where the table's density already holds
    // the aureole's share of the irradiance (a finer cap changed nothing).
    let far_up_cells = cells(2 * MS_DIRECTIONS);
    let first_up = Quadrature::about_the_sun(
        (MS_DIRECTIONS_NEAR_SUN, 2 * MS_DIRECTIONS),
        SUN_CAP_COSINE,
        [&near_cells, &far_up_cells],
    );
    // The orders past the first reach the ground as their tables' light,
    // already scattered: no phase function is read there.
    let higher_up = Quadrature::even(GROUND_DIRECTIONS_HIGHER, optics.phases);
    let mut table = MsTable::scattered(optics, None, &first, cancelled)?;
    let mut sky = SkyIrradiance::scattered(optics, None, &first_up, cancelled)?;
    // Only the order being marched needs its factors; the sum and the
    // two orders before it keep their numbers alone (the factors are
    // about a third of a table).
    let numbers_of = |t: &MsTable| MsTable {
        zenith_factors: Vec::new(),
        ..t.clone()
    };
    let (mut psi, mut irradiance) = (numbers_of(&table), sky.clone());
    let (mut last_table, mut last_sky) = (numbers_of(&table), sky.clone());
    let (mut older_table, mut older_sky) = (numbers_of(&table), sky.clone());
    for next in 3..=ORDERS {
        let quadrature = if next == 3 { &first } else { &later };
        // E_n from J_n, then J_{n+1} from L_n (J_n and the ground lit by
        // E_{n−1}).
        let next_sky = SkyIrradiance::scattered(optics, Some(&table), &higher_up, cancelled)?;
        let next_table = MsTable::scattered(optics, Some((&table, &sky)), quadrature, cancelled)?;
        for (sum, v) in psi.numbers_mut().zip(next_table.numbers()) {
            *sum += v;
        }
        for (sum, v) in irradiance
            .values
            .iter_mut()
            .flatten()
            .zip(next_sky.values.iter().flatten())
        {
            *sum += v;
        }
        (older_table, older_sky) = (last_table, last_sky);
        (last_table, last_sky) = (numbers_of(&table), sky);
        (table, sky) = (next_table, next_sky);
    }
    // The field's ratio of its last two orders, over the ν table; the
    // ground's irradiance tends to the same ratio (one operator's largest
    // eigenvalue), so its tail shares the floor.
    let sum = |t: &MsTable| t.values.iter().flatten().flatten().sum::<f64>();
    let floor = sum(&table) / sum(&last_table);
    let tables = older_table
        .numbers()
        .zip(last_table.numbers())
        .zip(table.numbers());
    for (sum, ((&older, &before), &last)) in psi.numbers_mut().zip(tables) {
        *sum += tail_after(older, before, last, floor);
    }
    psi.update_factors();
    let skies = older_sky
        .values
        .iter()
        .flatten()
        .zip(last_sky.values.iter().flatten())
        .zip(sky.values.iter().flatten());
    for (sum, ((&older, &before), &last)) in irradiance.values.iter_mut().flatten().zip(skies) {
        *sum += tail_after(older, before, last, floor);
    }
    // The sums only made the factors; the tables read from disk have
    // none either.
    psi.zenith_sums = Vec::new();
    Some((psi, irradiance))
}

/// The model's tables for one atmosphere: its phase functions at the
/// model's wavelengths, the light scattered twice or more (Ψ) and the
/// sky's irradiance on the ground. Every solar zenith is tabulated, so
/// they hold for any place of the sun and the observer: a renderer may
/// keep them while only those change (the app's sun and camera).
pub struct ModelTables {
    pub(super) groups: Vec<SpectralLanes>,
    pub(super) phases: Phases,
    pub(super) ms: MsTable,
    pub(super) sky: SkyIrradiance,
    /// What the tables were made of ([`fingerprint`]).
    fingerprint: Vec<f64>,
}

impl ModelTables {
    /// The tables of `medium` at the wavelengths of `lane_table`'s
    /// constants.
    pub fn new(medium: &Medium, lane_table: &LaneTable) -> Self {
        let key = fingerprint(medium, lane_table);
        Self::made(medium, lane_table, key, None, &|| false)
            .expect("tables never cancelled are made")
    }

    /// [`Self::new`], its fingerprint already taken; Ψ and the sky's
    /// irradiance `stored` where they were read back ([`stored::load`]).
    /// `None` once `cancelled()` returns true while they are being made
    /// (it is asked once per table and solar zenith).
    fn made(
        medium: &Medium,
        lane_table: &LaneTable,
        fingerprint: Vec<f64>,
        stored: Option<(MsTable, SkyIrradiance)>,
        cancelled: Cancelled<'_>,
    ) -> Option<Self> {
        let groups = node_groups(medium, lane_table);
        let phases = Phases::new(medium, &groups);
        let (ms, sky) = if let Some(read) = stored {
            read
        } else {
            let optics = Optics {
                medium,
                groups: &groups,
                phases: &phases,
                // Each table sets its own sun per solar zenith.
                sun_direction: DVec3::Z,
            };
            scattering_orders(&optics, cancelled)?
        };
        Some(Self {
            groups,
            phases,
            ms,
            sky,
            fingerprint,
        })
    }

    /// The tables of `medium` at `lane_table`'s wavelengths, made anew or,
    /// where the last ones made this way were of the same optics (the
    /// same coefficients at the tables' altitudes, phase functions and
    /// ground albedo at every node), those.
    pub fn shared(medium: &Medium, lane_table: &LaneTable) -> Arc<Self> {
        SHARED
            .get(medium, lane_table, &|| false)
            .expect("tables never cancelled are made")
    }

    /// [`Self::shared`], given up (`None`, nothing kept) once `cancelled()`
    /// returns true while the tables are being made: a new atmosphere's
    /// take seconds, and the app's scene may have changed again meanwhile.
    /// Tables kept in memory or on disk are returned whatever `cancelled`
    /// says.
    pub fn shared_unless(
        medium: &Medium,
        lane_table: &LaneTable,
        cancelled: &(dyn Fn() -> bool + Sync),
    ) -> Option<Arc<Self>> {
        SHARED.get(medium, lane_table, cancelled)
    }
}

/// The last tables made, kept for the next renderer of the same optics,
/// and every table made kept on disk ([`stored`]) for the next process.
struct TableCache {
    last: Mutex<Option<Arc<ModelTables>>>,
    /// The folder of the files, resolved on first use; `None`: none kept.
    folder: OnceLock<Option<PathBuf>>,
    /// Whether files are read and written.
    on_disk: AtomicBool,
    /// The write of the last tables made, done beside the render.
    writing: Mutex<Option<JoinHandle<()>>>,
}

impl TableCache {
    /// A cache keeping its files where [`stored::default_folder`] says.
    const fn new() -> Self {
        Self {
            last: Mutex::new(None),
            folder: OnceLock::new(),
            on_disk: AtomicBool::new(true),
            writing: Mutex::new(None),
        }
    }

    /// A cache keeping its files in `folder` (`None`: none).
    #[cfg(test)]
    fn in_folder(folder: Option<PathBuf>) -> Self {
        let cache = Self::new();
        let _ = cache.folder.set(folder);
        cache
    }

    /// The folder of the files, if they are kept.
    fn folder(&self) -> Option<&PathBuf> {
        if !self.on_disk.load(Ordering::Relaxed) {
            return None;
        }
        self.folder.get_or_init(stored::default_folder).as_ref()
    }

    /// See [`ModelTables::shared_unless`].
    fn get(
        &self,
        medium: &Medium,
        lane_table: &LaneTable,
        cancelled: Cancelled<'_>,
    ) -> Option<Arc<ModelTables>> {
        let key = fingerprint(medium, lane_table);
        let mut last = lock(&self.last);
        if let Some(tables) = last.as_ref().filter(|t| t.fingerprint == key) {
            return Some(Arc::clone(tables));
        }
        let folder = self.folder().cloned();
        let radii = (
            medium.planet_radius_m,
            medium.top_radius_m - medium.planet_radius_m,
        );
        let read = folder.as_ref().and_then(|f| stored::load(f, &key, radii));
        let made_here = read.is_none();
        let tables = Arc::new(ModelTables::made(medium, lane_table, key, read, cancelled)?);
        *last = Some(Arc::clone(&tables));
        if let Some(folder) = folder.filter(|_| made_here) {
            // Beside the render: its first frame does not wait on the disk.
            let kept = Arc::clone(&tables);
            let write = std::thread::spawn(move || {
                // Best effort: without the file the next process makes
                // the tables anew.
                let _ = stored::store(&folder, &kept.fingerprint, &kept.ms, &kept.sky);
            });
            if let Some(previous) = lock(&self.writing).replace(write) {
                let _ = previous.join();
            }
        }
        Some(tables)
    }

    /// Waits for the last tables' write to disk, if one is under way.
    fn wait_for_writes(&self) {
        if let Some(write) = lock(&self.writing).take() {
            let _ = write.join();
        }
    }
}

/// A cache's lock. A poisoned lock only means another thread panicked
/// while holding it; the values are swapped whole.
fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex
        .lock()
        .unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The tables [`ModelTables::shared`] made last.
static SHARED: TableCache = TableCache::new();

/// Drops the tables [`ModelTables::shared`] keeps in memory, so that the
/// next call reads them from disk or makes them anew (the bench's cold
/// first frame), after waiting for their write to disk.
pub fn forget_shared_tables() {
    SHARED.wait_for_writes();
    *lock(&SHARED.last) = None;
}

/// Whether [`ModelTables::shared`] reads and writes its tables on disk
/// (on by default; the bench turns it off to time the tables' making).
pub fn keep_shared_tables_on_disk(on: bool) {
    SHARED.on_disk.store(on, Ordering::Relaxed);
}

/// The optics the tables are made of, sampled: each node's coefficients
/// at the tables' altitudes, its ground albedo and its phase functions
/// at a few angles.
fn fingerprint(medium: &Medium, lane_table: &LaneTable) -> Vec<f64> {
    let top_m = medium.top_radius_m - medium.planet_radius_m;
    let mut key = vec![medium.planet_radius_m, medium.top_radius_m];
    for k in 0..GROUPS {
        let lanes = lane_table.lanes(
            Lanes::from_fn(|j| node_wavelength(k * LANES + j)),
            LANES,
            medium,
        );
        key.extend(lanes.ground_albedo);
        key.extend(lanes.rayleigh_gamma);
        for i in 0..MS_ALTITUDES {
            let r = medium.planet_radius_m + altitude_of(i, MS_ALTITUDES, top_m);
            let c = medium.coefficients(r, &lanes);
            key.extend(c.rayleigh);
            key.extend(c.aerosol_scattering);
            key.extend((0..LANES).map(|j| c.extinction(j)));
        }
        for mu in [-1.0, 0.0, 0.9, 1.0] {
            key.extend(medium.aerosol_phases(mu, &lanes));
        }
    }
    key
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Renderer;
    use crate::Scene;

    /// The tail of a series whose ratio falls by a fixed factor per order
    /// down to a floor is its sum; a geometric series keeps its own.
    #[test]
    fn the_tail_sums_the_orders_it_stands_for() {
        // J_k with ratio ρ_k = max(ρ₀ qᵏ, floor), summed far past the tail.
        let series = |rho0: f64, q: f64, floor: f64| -> Vec<f64> {
            let mut j = vec![1.0];
            for k in 1..4000 {
                let ratio = (rho0 * q.powi(k as i32)).max(floor);
                j.push(j[k - 1] * ratio);
            }
            j
        };
        for (rho0, q, floor) in [
            (0.6, 1.0, 0.3),
            (0.95, 0.97, 0.4),
            (0.9, 0.8, 0.2),
            (0.8, 0.99, 0.5),
            (0.5, 0.9, 0.6),
        ] {
            let j = series(rho0, q, floor);
            for n in [3, 5, 9] {
                let exact: f64 = j[n + 1..].iter().sum();
                let tail = tail_after(j[n - 2], j[n - 1], j[n], floor);
                assert!(
                    (tail - exact).abs() <= 1e-9 * exact.max(1e-300),
                    "ρ₀ {rho0} q {q} floor {floor} n {n}: tail {tail} against {exact}"
                );
            }
        }
        // Nothing left where an order is dark; a ratio past the cap is capped.
        assert_eq!(tail_after(1.0, 0.0, 0.0, 0.5), 0.0);
        assert!((tail_after(1.0, 1.0, 1.0, 0.5) - 9.0).abs() < 1e-12);
    }

    /// The numbers of two sets of tables, bit for bit.
    fn same_numbers(a: &ModelTables, b: &ModelTables) -> bool {
        stored::body(&a.ms, &a.sky) == stored::body(&b.ms, &b.sky)
    }

    /// Tables written to disk come back bit for bit in the next process
    /// (a cache of its own over the same folder); a damaged or truncated
    /// file, or one of other optics, is never read, and the tables are
    /// made anew; a folder that cannot be made costs nothing but the file.
    #[test]
    fn tables_kept_on_disk_come_back_whole_or_not_at_all() {
        let folder = tempfile::tempdir().unwrap();
        let renderer = Renderer::new(&Scene::preset("midday").unwrap()).unwrap();
        let (medium, lanes) = (&renderer.medium, &renderer.lane_table);
        let radii = (
            medium.planet_radius_m,
            medium.top_radius_m - medium.planet_radius_m,
        );
        let key = fingerprint(medium, lanes);
        let first_cache = TableCache::in_folder(Some(folder.path().to_path_buf()));
        let made = first_cache.get(medium, lanes, &|| false).unwrap();
        first_cache.wait_for_writes();
        let files: Vec<_> = std::fs::read_dir(folder.path())
            .unwrap()
            .map(|e| e.unwrap().path())
            .collect();
        assert_eq!(files.len(), 1, "one file per atmosphere: {files:?}");
        // Read back, as the next process would.
        let read = TableCache::in_folder(Some(folder.path().to_path_buf()))
            .get(medium, lanes, &|| false)
            .unwrap();
        assert!(!Arc::ptr_eq(&made, &read));
        assert!(same_numbers(&made, &read));
        assert!(stored::load(folder.path(), &key, radii).is_some());
        // Another atmosphere's fingerprint finds nothing.
        let mut other = key.clone();
        other[0] += 1.0;
        assert!(stored::load(folder.path(), &other, radii).is_none());
        // One bit changed anywhere, or the file cut short: not read.
        let bytes = std::fs::read(&files[0]).unwrap();
        for at in [9, bytes.len() / 2, bytes.len() - 1] {
            let mut damaged = bytes.clone();
            damaged[at] ^= 0x10;
            std::fs::write(&files[0], &damaged).unwrap();
            assert!(
                stored::load(folder.path(), &key, radii).is_none(),
                "byte {at}"
            );
        }
        std::fs::write(&files[0], &bytes[..bytes.len() - 8]).unwrap();
        assert!(stored::load(folder.path(), &key, radii).is_none());
        // Damaged, the tables are made anew (the same numbers) and the
        // file written again.
        let cache = TableCache::in_folder(Some(folder.path().to_path_buf()));
        assert!(same_numbers(
            &made,
            &cache.get(medium, lanes, &|| false).unwrap()
        ));
        cache.wait_for_writes();
        assert!(stored::load(folder.path(), &key, radii).is_some());
        // A "folder" that is a file: no file kept, the tables all the same.
        let blocked = folder.path().join("blocked");
        std::fs::write(&blocked, b"").unwrap();
        let cache = TableCache::in_folder(Some(blocked.join("sky-model")));
        assert!(same_numbers(
            &made,
            &cache.get(medium, lanes, &|| false).unwrap()
        ));
        cache.wait_for_writes();
        assert_eq!(std::fs::read_dir(folder.path()).unwrap().count(), 2);
    }

    /// The tables are kept for renderers of the same atmosphere, whatever
    /// the sun, observer and camera, and made anew for another.
    #[test]
    fn tables_are_shared_by_atmosphere() {
        // A cache of its own (and no files): other tests use the shared
        // one meanwhile.
        let cache = TableCache::in_folder(None);
        let tables = |scene: &Scene| {
            let renderer = Renderer::new(scene).unwrap();
            cache
                .get(&renderer.medium, &renderer.lane_table, &|| false)
                .unwrap()
        };
        let sunset = Scene::preset("sunset").unwrap();
        let first = tables(&sunset);
        let mut moved = sunset.clone();
        moved.sun.elevation_deg = 40.0;
        moved.observer.altitude_m = 10_000.0;
        assert!(Arc::ptr_eq(&first, &tables(&moved)));
        let mut hazier = sunset.clone();
        hazier.atmosphere.aerosol_amount *= 2.0;
        let other = tables(&hazier);
        assert!(!Arc::ptr_eq(&first, &other));
        assert!(other.fingerprint != first.fingerprint);
        // And back: made anew (one set is kept), equal to the first.
        let again = tables(&sunset);
        assert!(!Arc::ptr_eq(&other, &again));
        assert!(again.fingerprint == first.fingerprint);

        // A build given up keeps nothing and leaves the last tables kept;
        // it stops within the table it was building when asked.
        let hazier_renderer = Renderer::new(&hazier).unwrap();
        let unless = |cancelled: Cancelled<'_>| {
            cache.get(
                &hazier_renderer.medium,
                &hazier_renderer.lane_table,
                cancelled,
            )
        };
        assert!(unless(&|| true).is_none());
        let asked = std::sync::atomic::AtomicUsize::new(0);
        let after_forty = || asked.fetch_add(1, Ordering::SeqCst) >= 40;
        assert!(unless(&after_forty).is_none());
        let asked = asked.load(Ordering::SeqCst);
        assert!((41..=40 + MS_ZENITHS).contains(&asked), "{asked}");
        let kept = lock(&cache.last).clone().unwrap();
        assert!(Arc::ptr_eq(&kept, &again));
        // Tables already kept are returned, cancelled or not.
        let renderer = Renderer::new(&sunset).unwrap();
        let kept = cache.get(&renderer.medium, &renderer.lane_table, &|| true);
        assert!(Arc::ptr_eq(&kept.unwrap(), &again));
    }
}
