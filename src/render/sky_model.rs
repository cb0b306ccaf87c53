//! An approximate sky, computed in a few tens of milliseconds from the
//! same atmosphere the path tracer renders: the preview's first frame,
//! shown before the first Monte Carlo pass is in.
//!
//! **Method** (Hillaire 2020, "A Scalable and Production Ready Sky and
//! Atmosphere Rendering Technique", *Computer Graphics Forum* 39(4)): the
//! same coefficients, phase functions and sun ([`Medium`], [`SpectralLanes`])
//! at 16 wavelengths, with three approximations, each a table (the second
//! computed as Bruneton & Neyret do):
//!
//! 1. *Sunlight* reaching a point is the straight-line transmittance from
//!    its column amounts toward the sun ([`Medium::sun_columns`]); zero in
//!    the planet's shadow.
//! 2. *Light scattered twice or more* at a point depends on its altitude,
//!    the solar zenith and the angle between the view and the sun, order
//!    by order (Bruneton & Neyret 2008, "Precomputed Atmospheric
//!    Scattering", *Computer Graphics Forum* 27(4)): the table of order
//!    n + 1 is J_X(r, μ_s, ν) = Σ_ω L_n(ω) P_X(ω·v) Δω for the Rayleigh
//!    and aerosol phase functions P_X, L_n the light of order n arriving
//!    from ω (the air's, marched through the table of order n, and the
//!    ground's, lit by the sky of order n − 1). Orders 2–4 are computed;
//!    the rest are each entry's geometric tail. Hillaire's isotropic
//!    factor for the orders past the second takes their light as made at
//!    the point itself and isotropic; at the horizon and at twilight it
//!    arrives from far away and that factor leaves out a fifth of it.
//!    The phase functions are kept in every order: at low sun most of the
//!    light is haze's forward scattering about the sun.
//! 3. *The sky seen from the observer* is smooth in direction once the
//!    phase functions are taken out: along a view ray the angle to the sun
//!    is fixed, so the single scattering is P_R(θ) A_R + P_A(θ) A_A with
//!    A = ∫ T σ T_sun dt, and the rest (Ψ, the ground) is a third term B.
//!    A, B are tabulated over elevation (dense at the horizon) and azimuth
//!    from the sun; each pixel then evaluates the phase functions at its
//!    own angle, so the aureole is as sharp as the phase function.
//!
//! The ground is Lambertian, lit by the sun and by the model's own sky
//! (its irradiance tabulated over the solar zenith). The spectrum is the
//! atmosphere's response at 16 wavelengths (360–830 nm), linear between
//! them, times the sun's spectrum at the colour-matching functions' 1 nm
//! grid. The sun's disc is left out.
//!
//! It is an approximation, never a reference: its error against the
//! converged path tracer is measured per preset (`skyrender bench`,
//! `first_frame_error`; `BENCHMARKS.md`).

use std::f64::consts::PI;

use glam::DVec3;
use rayon::prelude::*;

use super::camera::Camera;
use super::directions::horizon_cosine;
use super::lanes::LaneTable;
use super::medium::{Lanes, Medium, SpectralLanes, LANES};
use crate::output::RgbImage;
use crate::physics::rayleigh;
use crate::spectrum::{xyz_to_rec709, ColourMatching, K_M};

/// Wavelength groups of [`LANES`] wavelengths each.
const GROUPS: usize = 4;
/// Wavelengths at which the model is computed.
const NODES: usize = GROUPS * LANES;
/// The nodes' range, nm (the colour-matching functions').
const RANGE_NM: (f64, f64) = (360.0, 830.0);

/// Steps of a view ray's march.
const VIEW_STEPS: usize = 32;
/// Steps of a march inside the multiple-scattering and irradiance tables.
const TABLE_STEPS: usize = 12;
/// Directions over which Ψ's integrals are summed.
const MS_DIRECTIONS: usize = 32;
/// Altitudes and solar-zenith cosines of the multiple-scattering table.
const MS_ALTITUDES: usize = 8;
/// See [`MS_ALTITUDES`].
const MS_ZENITHS: usize = 33;
/// Rows (elevation) and columns (azimuth from the sun, 0–180°) of the
/// observer's sky table.
const VIEW_ROWS: usize = 64;
/// See [`VIEW_ROWS`].
const VIEW_COLUMNS: usize = 32;

/// A quantity at the model's wavelengths.
type Spectrum = [f64; NODES];

/// The approximate sky of one scene.
pub struct SkyModel {
    /// The observer's sky: per texel, A_R, A_A and B at each wavelength.
    view: Vec<[Spectrum; 3]>,
    /// Zenith, the horizontal toward the sun, and across, at the observer.
    frame: [DVec3; 3],
    /// The elevations of the view table's rows.
    rows: Rows,
    sun_direction: DVec3,
    /// The phase functions at each wavelength.
    phases: Phases,
    /// XYZ per unit response at each node: K_M ∫ E_sun h_k x̄ dλ.
    xyz_weights: [[f64; 3]; NODES],
}

/// The medium seen through one group of lanes per node group.
struct Optics<'a> {
    medium: &'a Medium,
    groups: &'a [SpectralLanes],
    phases: &'a Phases,
    sun_direction: DVec3,
}

/// What a march gathers along a ray, per wavelength.
#[derive(Default)]
struct Gathered {
    /// ∫ T σ_R T_sun dt.
    rayleigh: Spectrum,
    /// ∫ T σ_A T_sun dt.
    aerosol: Spectrum,
    /// ∫ T σ_s Ψ dt plus the ground's reflected light.
    isotropic: Spectrum,
    /// ∫ T σ_s dt.
    scattering: Spectrum,
}

impl Optics<'_> {
    /// Transmittance toward the sun from `x` at each wavelength (0 in the
    /// planet's shadow).
    fn sun_transmittance(&self, x: DVec3) -> Spectrum {
        let mut t = [0.0; NODES];
        if let Some(columns) = self.medium.sun_columns().at(x, self.sun_direction) {
            for (g, lanes) in self.groups.iter().enumerate() {
                for j in 0..LANES {
                    t[g * LANES + j] =
                        (-super::sunlight::sun_optical_depth(lanes, j, columns)).exp();
                }
            }
        }
        t
    }

    /// Marches from `origin` along `dir` in `steps` (lengths growing as
    /// the square, short where the ray starts), gathering the sunlight
    /// scattered toward `origin`, the multiple scattering and the ground's
    /// light where the ray ends on it, as `sources` says.
    fn march(&self, origin: DVec3, dir: DVec3, steps: usize, sources: Sources<'_>) -> Gathered {
        let mut out = Gathered::default();
        let Some(span) = self.medium.span(origin, dir) else {
            return out;
        };
        let length = span.t_exit - span.t_enter;
        let nu = dir.dot(self.sun_direction);
        let mut transmittance = [1.0; NODES];
        let mut t0 = span.t_enter;
        for s in 0..steps {
            let t1 = span.t_enter + length * ((s + 1) as f64 / steps as f64).powi(2);
            let dt = t1 - t0;
            let x = origin + dir * (0.5 * (t0 + t1));
            let r = x.length();
            let sun = if sources.sunlight {
                self.sun_transmittance(x)
            } else {
                [0.0; NODES]
            };
            let psi = sources
                .ms
                .map(|m| m.at(r, x.dot(self.sun_direction) / r, nu));
            for (g, lanes) in self.groups.iter().enumerate() {
                let c = self.medium.coefficients(r, lanes);
                for j in 0..LANES {
                    let k = g * LANES + j;
                    let extinction = c.extinction(j);
                    // ∫ over the step of T(t) with σ_t constant: T₀ (1 − e^{−σΔt})/σ.
                    let step_t = (-extinction * dt).exp();
                    let weight = if extinction > 0.0 {
                        transmittance[k] * (1.0 - step_t) / extinction
                    } else {
                        transmittance[k] * dt
                    };
                    out.rayleigh[k] += weight * c.rayleigh[j] * sun[k];
                    out.aerosol[k] += weight * c.aerosol_scattering[j] * sun[k];
                    out.scattering[k] += weight * c.scattering(j);
                    if let Some([psi_r, psi_a]) = &psi {
                        out.isotropic[k] += weight
                            * (c.rayleigh[j] * psi_r[k] + c.aerosol_scattering[j] * psi_a[k]);
                    }
                    transmittance[k] *= step_t;
                }
            }
            t0 = t1;
        }
        if span.hits_ground {
            let g = origin + dir * span.t_exit;
            let (mu_sun, sun) = if sources.ground_sun {
                let mu = (g.dot(self.sun_direction) / g.length()).max(0.0);
                (mu, self.sun_transmittance(g))
            } else {
                (0.0, [0.0; NODES])
            };
            let irradiance = sources
                .ground_sky
                .map(|s| s.at(g.dot(self.sun_direction) / g.length()));
            for (group, lanes) in self.groups.iter().enumerate() {
                for j in 0..LANES {
                    let k = group * LANES + j;
                    let e = mu_sun * sun[k] + irradiance.map_or(0.0, |e| e[k]);
                    out.isotropic[k] += transmittance[k] * lanes.ground_albedo[j] / PI * e;
                }
            }
        }
        out
    }

    /// These optics with the sun at solar-zenith cosine `mu_s` above a
    /// point on the z axis (in the x–z plane), and that sun's direction.
    fn with_sun_at(&self, mu_s: f64) -> (DVec3, Self) {
        let sun = DVec3::new((1.0 - mu_s * mu_s).max(0.0).sqrt(), 0.0, mu_s);
        let optics = Optics {
            sun_direction: sun,
            ..*self
        };
        (sun, optics)
    }

    /// The phase functions (P_R, P_A) at each wavelength at cosine `mu`
    /// between the ray and the sun ([`Phases`]).
    fn phases(&self, mu: f64) -> (Spectrum, Spectrum) {
        self.phases.at(mu)
    }
}

/// Samples of [`Phases`].
const PHASE_SAMPLES: usize = 2048;

/// The Rayleigh and aerosol phase functions at each wavelength, tabulated
/// at μ = 1 − 2u², u uniform (0.11° apart at the forward peak), linear in
/// between: the model evaluates them about a million times, and a
/// tabulated phase function over wavelength costs two searches each.
struct Phases {
    values: Vec<(Spectrum, Spectrum)>,
}

impl Phases {
    fn new(medium: &Medium, groups: &[SpectralLanes]) -> Self {
        let values = (0..PHASE_SAMPLES)
            .map(|i| {
                let u = i as f64 / (PHASE_SAMPLES - 1) as f64;
                let mu = 1.0 - 2.0 * u * u;
                let (mut rayleigh_phase, mut aerosol_phase) = ([0.0; NODES], [0.0; NODES]);
                for (g, lanes) in groups.iter().enumerate() {
                    let aerosol = medium.aerosol_phases(mu, lanes);
                    for j in 0..LANES {
                        rayleigh_phase[g * LANES + j] =
                            rayleigh::phase(mu, lanes.rayleigh_gamma[j]);
                        aerosol_phase[g * LANES + j] = aerosol[j];
                    }
                }
                (rayleigh_phase, aerosol_phase)
            })
            .collect();
        Self { values }
    }

    fn at(&self, mu: f64) -> (Spectrum, Spectrum) {
        let x = (0.5 * (1.0 - mu.clamp(-1.0, 1.0))).sqrt() * (PHASE_SAMPLES - 1) as f64;
        let i = (x as usize).min(PHASE_SAMPLES - 2);
        let f = x - i as f64;
        let ((ra, aa), (rb, ab)) = (&self.values[i], &self.values[i + 1]);
        (
            std::array::from_fn(|n| ra[n] + f * (rb[n] - ra[n])),
            std::array::from_fn(|n| aa[n] + f * (ab[n] - aa[n])),
        )
    }
}

/// The light a march gathers.
#[derive(Clone, Copy)]
struct Sources<'a> {
    /// Sunlight scattered once along the ray.
    sunlight: bool,
    /// Light scattered twice or more along the ray, per unit scattering
    /// coefficient.
    ms: Option<&'a MsTable>,
    /// The sun on the ground where the ray ends on it.
    ground_sun: bool,
    /// The sky's irradiance on the ground where the ray ends on it.
    ground_sky: Option<&'a SkyIrradiance>,
}

impl<'a> Sources<'a> {
    /// Everything: what an observer sees.
    fn all(ms: &'a MsTable, sky: &'a SkyIrradiance) -> Self {
        Self {
            sunlight: true,
            ms: Some(ms),
            ground_sun: true,
            ground_sky: Some(sky),
        }
    }
}

/// Light scattered twice or more toward a point's viewer, per unit
/// Rayleigh and aerosol scattering coefficient, by the point's altitude,
/// solar zenith and the cosine ν between the view and the sun. One
/// order's table is J_{n+1,X}(ν) = Σ_ω L_n(ω) P_X(ω·v) Δω for the
/// phase functions P_X, L_n the light of order n arriving from ω (the
/// air's and the ground's), v at ν from the sun (averaged over two
/// azimuths about it): Bruneton & Neyret's (2008) iteration over
/// scattering orders, with the view's zenith folded into ν. The model's
/// Ψ is the sum over orders ([`scattering_orders`]).
#[derive(Clone)]
struct MsTable {
    planet_radius_m: f64,
    top_m: f64,
    /// Per (altitude, zenith, ν): (J_R, J_A).
    values: Vec<[Spectrum; 2]>,
}

/// View–sun cosines of [`MsTable`]: ν = 1 − 2u², dense about the sun.
const MS_VIEW_ANGLES: usize = 16;

fn view_cosine_of(i: usize) -> f64 {
    let u = i as f64 / (MS_VIEW_ANGLES - 1) as f64;
    1.0 - 2.0 * u * u
}

fn view_cosine_index(nu: f64) -> f64 {
    (0.5 * (1.0 - nu.clamp(-1.0, 1.0))).sqrt() * (MS_VIEW_ANGLES - 1) as f64
}

impl MsTable {
    /// The light scattered once more than `previous`'s: from the sunlight
    /// scattered once (and the sunlit ground) without it, else from the
    /// light of the previous order (its table J_n, and the ground lit by
    /// the sky of the order before, E_{n−1}).
    fn scattered(optics: &Optics<'_>, previous: Option<(&MsTable, &SkyIrradiance)>) -> Self {
        let medium = optics.medium;
        let (planet_radius_m, top_m) = (
            medium.planet_radius_m,
            medium.top_radius_m - medium.planet_radius_m,
        );
        let directions = fibonacci_sphere(MS_DIRECTIONS);
        let weight = 4.0 * PI / MS_DIRECTIONS as f64;
        // Per solar zenith (the sun's direction, and so every phase
        // function value, is the same at each altitude): the altitudes' rows.
        let per_zenith: Vec<Vec<[Spectrum; 2]>> = (0..MS_ZENITHS)
            .into_par_iter()
            .map(|k| {
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
                let to_sun: Vec<_> = directions
                    .iter()
                    .map(|d| optics.phases(d.dot(sun)))
                    .collect();
                let to_view: Vec<Vec<_>> = views
                    .iter()
                    .map(|v| {
                        directions
                            .iter()
                            .map(|d| optics.phases(d.dot(*v)))
                            .collect()
                    })
                    .collect();
                (0..MS_ALTITUDES)
                    .flat_map(|i| {
                        let r = planet_radius_m + altitude_of(i, MS_ALTITUDES, top_m);
                        let origin = DVec3::new(0.0, 0.0, r);
                        let arriving: Vec<Spectrum> = directions
                            .iter()
                            .zip(&to_sun)
                            .map(|(&dir, (pr, pa))| match previous {
                                None => {
                                    let once = Sources {
                                        sunlight: true,
                                        ms: None,
                                        ground_sun: true,
                                        ground_sky: None,
                                    };
                                    let g = cell_optics.march(origin, dir, TABLE_STEPS, once);
                                    std::array::from_fn(|n| {
                                        pr[n] * g.rayleigh[n]
                                            + pa[n] * g.aerosol[n]
                                            + g.isotropic[n]
                                    })
                                }
                                Some((table, sky)) => {
                                    let order = Sources {
                                        sunlight: false,
                                        ms: Some(table),
                                        ground_sun: false,
                                        ground_sky: Some(sky),
                                    };
                                    cell_optics.march(origin, dir, TABLE_STEPS, order).isotropic
                                }
                            })
                            .collect();
                        to_view
                            .chunks(2)
                            .map(|pair| {
                                let mut out = [[0.0; NODES]; 2];
                                for phases in pair {
                                    for (l, (pr, pa)) in arriving.iter().zip(phases) {
                                        for n in 0..NODES {
                                            out[0][n] += l[n] * pr[n];
                                            out[1][n] += l[n] * pa[n];
                                        }
                                    }
                                }
                                out.map(|o| std::array::from_fn(|n| o[n] * 0.5 * weight))
                            })
                            .collect::<Vec<_>>()
                    })
                    .collect()
            })
            .collect();
        // Reordered to (altitude, zenith, ν).
        let rows = MS_VIEW_ANGLES;
        let values = (0..MS_ALTITUDES * MS_ZENITHS * rows)
            .map(|index| {
                let (cell, a) = (index / rows, index % rows);
                let (i, k) = (cell / MS_ZENITHS, cell % MS_ZENITHS);
                per_zenith[k][i * rows + a]
            })
            .collect();
        Self {
            planet_radius_m,
            top_m,
            values,
        }
    }

    /// (Ψ_R, Ψ_A) at distance `r` from the centre, solar-zenith cosine
    /// `mu_s` and view–sun cosine `nu`.
    fn at(&self, r: f64, mu_s: f64, nu: f64) -> [Spectrum; 2] {
        let split = |x: f64, n: usize| {
            let x = x.clamp(0.0, (n - 1) as f64);
            let i = (x as usize).min(n - 2);
            (i, x - i as f64)
        };
        let (i, fi) = split(
            altitude_index(r - self.planet_radius_m, MS_ALTITUDES, self.top_m),
            MS_ALTITUDES,
        );
        let (k, fk) = split(zenith_index(mu_s), MS_ZENITHS);
        let (a, fa) = split(view_cosine_index(nu), MS_VIEW_ANGLES);
        // Linear in altitude and ν within each of the two solar-zenith
        // slices, then geometric between them.
        let slice = |k: usize| {
            let mut out = [[0.0; NODES]; 2];
            for (di, wi) in [(0, 1.0 - fi), (1, fi)] {
                for (da, wa) in [(0, 1.0 - fa), (1, fa)] {
                    let w = wi * wa;
                    if w == 0.0 {
                        continue;
                    }
                    let cell = ((i + di) * MS_ZENITHS + k) * MS_VIEW_ANGLES + a + da;
                    let v = &self.values[cell];
                    for n in 0..NODES {
                        out[0][n] += w * v[0][n];
                        out[1][n] += w * v[1][n];
                    }
                }
            }
            out
        };
        let (low, high) = (slice(k), slice(k + 1));
        [0, 1].map(|x| std::array::from_fn(|n| geometric(low[x][n], high[x][n], fk)))
    }
}

/// Interpolation between `a` and `b` at fraction `f`: geometric where
/// both are positive and differ by more than a quarter, else linear. The
/// light past the first scattering falls off about exponentially with the
/// sun's depression at twilight (the shadow rising through the air), and
/// with table nodes a degree or two apart the linear mean there is up to
/// 30 % too bright; where neighbours differ by less than a quarter the
/// two means differ by less than 0.7 % (and the power is not paid for).
fn geometric(a: f64, b: f64, f: f64) -> f64 {
    let linear = a + f * (b - a);
    if a > 0.0 && b > 0.0 && (b > 1.25 * a || a > 1.25 * b) {
        a * (b / a).powf(f)
    } else {
        linear
    }
}

/// The sky's irradiance on the ground by solar-zenith cosine (the sun's
/// own left out), of one scattering order or the sum of several.
#[derive(Clone)]
struct SkyIrradiance {
    values: Vec<Spectrum>,
}

impl SkyIrradiance {
    /// The irradiance of the sunlight scattered once (without `ms`) or of
    /// the light that `ms` scatters toward the ground.
    fn scattered(optics: &Optics<'_>, ms: Option<&MsTable>) -> Self {
        let medium = optics.medium;
        let up: Vec<DVec3> = fibonacci_sphere(2 * MS_DIRECTIONS)
            .into_iter()
            .filter(|d| d.z > 0.0)
            .collect();
        let weight = 4.0 * PI / (2 * MS_DIRECTIONS) as f64;
        // Looking up from the ground, no view ray ends on it.
        let sources = Sources {
            sunlight: ms.is_none(),
            ms,
            ground_sun: false,
            ground_sky: None,
        };
        let values = (0..MS_ZENITHS)
            .into_par_iter()
            .map(|k| {
                let (sun, cell_optics) = optics.with_sun_at(zenith_cosine_of(k as f64));
                let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + 1.0);
                let mut e = [0.0; NODES];
                for &dir in &up {
                    let g = cell_optics.march(origin, dir, TABLE_STEPS, sources);
                    let radiance: Spectrum = if ms.is_some() {
                        g.isotropic
                    } else {
                        let (pr, pa) = cell_optics.phases(dir.dot(sun));
                        std::array::from_fn(|n| pr[n] * g.rayleigh[n] + pa[n] * g.aerosol[n])
                    };
                    for n in 0..NODES {
                        e[n] += radiance[n] * dir.z * weight;
                    }
                }
                e
            })
            .collect();
        Self { values }
    }

    fn at(&self, mu_s: f64) -> Spectrum {
        let x = zenith_index(mu_s).clamp(0.0, (MS_ZENITHS - 1) as f64);
        let k = (x as usize).min(MS_ZENITHS - 2);
        let (low, high) = (&self.values[k], &self.values[k + 1]);
        std::array::from_fn(|n| geometric(low[n], high[n], x - k as f64))
    }
}

/// Scattering orders computed one by one ([`MsTable::scattered`]) past
/// the first.
const ORDERS: usize = 4;

/// The share of an order's light that the next one keeps, at most: past
/// it the tail's sum ρ/(1 − ρ) is taken as this.
const MAX_ORDER_RATIO: f64 = 0.9;

/// The light scattered twice or more (Ψ, the sum of the orders' tables)
/// and the sky's irradiance on the ground (E, the sum of its orders).
///
/// Orders 2 to [`ORDERS`] of Ψ (and 1 to [`ORDERS`] − 1 of E) are
/// computed in turn; the rest are a geometric tail, each entry's last
/// order times ρ/(1 − ρ) with ρ the ratio of its last two orders. This
/// replaces Hillaire's isotropic factor F_ms = 1/(1 − f_ms), which takes
/// the higher orders' light as isotropic and as made at the point itself:
/// at the horizon and at twilight most of it arrives from far away
/// (low, long paths; the still sunlit air high up), and F_ms leaves out
/// a fifth of it there.
fn scattering_orders(optics: &Optics<'_>) -> (MsTable, SkyIrradiance) {
    // J₂ from the once-scattered light; E₁ of the once-scattered sky.
    let mut table = MsTable::scattered(optics, None);
    let mut sky = SkyIrradiance::scattered(optics, None);
    let (mut psi, mut irradiance) = (table.clone(), sky.clone());
    let (mut last_table, mut last_sky) = (table.clone(), sky.clone());
    for _ in 2..ORDERS {
        // E_n from J_n, then J_{n+1} from L_n (J_n and the ground lit by
        // E_{n−1}).
        let next_sky = SkyIrradiance::scattered(optics, Some(&table));
        let next_table = MsTable::scattered(optics, Some((&table, &sky)));
        for (sum, v) in psi.values.iter_mut().zip(&next_table.values) {
            for x in 0..2 {
                for n in 0..NODES {
                    sum[x][n] += v[x][n];
                }
            }
        }
        for (sum, v) in irradiance.values.iter_mut().zip(&next_sky.values) {
            for n in 0..NODES {
                sum[n] += v[n];
            }
        }
        (last_table, last_sky) = (table, sky);
        (table, sky) = (next_table, next_sky);
    }
    let tail = |last: f64, before: f64| {
        if before > 0.0 && last > 0.0 {
            let ratio = (last / before).min(MAX_ORDER_RATIO);
            last * ratio / (1.0 - ratio)
        } else {
            0.0
        }
    };
    for ((sum, last), before) in psi
        .values
        .iter_mut()
        .zip(&table.values)
        .zip(&last_table.values)
    {
        for x in 0..2 {
            for n in 0..NODES {
                sum[x][n] += tail(last[x][n], before[x][n]);
            }
        }
    }
    for ((sum, last), before) in irradiance
        .values
        .iter_mut()
        .zip(&sky.values)
        .zip(&last_sky.values)
    {
        for n in 0..NODES {
            sum[n] += tail(last[n], before[n]);
        }
    }
    (psi, irradiance)
}

/// The model's light field: the radiance arriving at any point of the
/// atmosphere from any direction, per unit solar irradiance, at the
/// model's wavelengths — the model's tables without the observer's view
/// table. A view ray's march through the tables costs about as much as a
/// few path vertices, so the field serves as a control variate's
/// approximation of the light at a point (`crate::render::tables`).
pub struct ModelField {
    groups: Vec<SpectralLanes>,
    phases: Phases,
    ms: MsTable,
    sky: SkyIrradiance,
    sun_direction: DVec3,
}

impl ModelField {
    /// The field of `medium` lit along `sun_direction`, at the wavelengths
    /// of `lane_table`'s constants.
    pub fn new(medium: &Medium, lane_table: &LaneTable, sun_direction: DVec3) -> Self {
        let nodes: Vec<f64> = (0..NODES).map(node_wavelength).collect();
        let groups: Vec<SpectralLanes> = nodes
            .chunks(LANES)
            .map(|w| lane_table.lanes(Lanes::from_fn(|j| w[j]), LANES, medium))
            .collect();
        let phases = Phases::new(medium, &groups);
        let optics = Optics {
            medium,
            groups: &groups,
            phases: &phases,
            sun_direction,
        };
        let (ms, sky) = scattering_orders(&optics);
        Self {
            groups,
            phases,
            ms,
            sky,
            sun_direction,
        }
    }

    fn optics<'a>(&'a self, medium: &'a Medium) -> Optics<'a> {
        Optics {
            medium,
            groups: &self.groups,
            phases: &self.phases,
            sun_direction: self.sun_direction,
        }
    }

    /// The radiance arriving at `x` looking along unit `dir` in `medium`
    /// (the one the field was built for), per unit solar irradiance, at
    /// each of the model's wavelengths ([`Self::node_nm`]); the sun's disc
    /// left out.
    pub fn radiance(&self, medium: &Medium, x: DVec3, dir: DVec3) -> [f64; NODES] {
        let optics = self.optics(medium);
        let g = optics.march(x, dir, VIEW_STEPS, Sources::all(&self.ms, &self.sky));
        let (pr, pa) = self.phases.at(dir.dot(self.sun_direction));
        std::array::from_fn(|n| pr[n] * g.rayleigh[n] + pa[n] * g.aerosol[n] + g.isotropic[n])
    }

    /// The wavelength of the model's node `k` < [`MODEL_NODES`], nm.
    pub fn node_nm(k: usize) -> f64 {
        node_wavelength(k)
    }
}

/// Wavelengths at which the model is computed ([`ModelField::node_nm`]).
pub const MODEL_NODES: usize = NODES;

impl SkyModel {
    /// The model of `medium` lit along `sun_direction`, seen from
    /// `observer_m`, in the sun and colours of `lane_table` and `cmf`.
    pub fn new(
        medium: &Medium,
        lane_table: &LaneTable,
        cmf: &ColourMatching,
        sun_direction: DVec3,
        observer_m: DVec3,
    ) -> Self {
        let field = ModelField::new(medium, lane_table, sun_direction);
        let nodes: Vec<f64> = (0..NODES).map(node_wavelength).collect();
        let optics = field.optics(medium);
        let (ms, sky) = (&field.ms, &field.sky);
        let zenith = observer_m.normalize();
        let toward_sun = sun_direction - zenith * sun_direction.dot(zenith);
        let x = if toward_sun.length() > 1e-9 {
            toward_sun.normalize()
        } else {
            zenith.any_orthonormal_vector()
        };
        let frame = [zenith, x, zenith.cross(x)];
        let r = observer_m.length();
        let rows = Rows::new(medium.planet_radius_m, medium.top_radius_m, r);
        let view = (0..VIEW_ROWS * VIEW_COLUMNS)
            .into_par_iter()
            .map(|texel| {
                let (row, column) = (texel / VIEW_COLUMNS, texel % VIEW_COLUMNS);
                let elevation = rows.elevation(row as f64);
                let azimuth = PI * column as f64 / (VIEW_COLUMNS - 1) as f64;
                let dir = direction(&frame, elevation, azimuth);
                let g = optics.march(observer_m, dir, VIEW_STEPS, Sources::all(ms, sky));
                [g.rayleigh, g.aerosol, g.isotropic]
            })
            .collect();
        Self {
            view,
            frame,
            rows,
            sun_direction,
            xyz_weights: xyz_weights(medium, lane_table, cmf, &nodes),
            phases: field.phases,
        }
    }

    /// The model's radiance along `dir` from the observer as CIE XYZ (Y, the
    /// luminance, in cd m⁻²), the sun's disc left out.
    pub fn xyz(&self, dir: DVec3) -> [f64; 3] {
        let [zenith, x, y] = self.frame;
        let elevation = dir.dot(zenith).clamp(-1.0, 1.0).asin();
        let azimuth = dir.dot(y).atan2(dir.dot(x)).abs();
        let row = self.rows.row(elevation);
        let column = azimuth / PI * (VIEW_COLUMNS - 1) as f64;
        let pick = |n: usize| {
            let at = |texel: &[Spectrum; 3]| texel[n];
            bilinear_with(
                &self.view,
                VIEW_COLUMNS,
                (row, VIEW_ROWS),
                (column, VIEW_COLUMNS),
                at,
            )
        };
        let [ar, aa, b] = [pick(0), pick(1), pick(2)];
        let (pr, pa) = self.phases.at(dir.dot(self.sun_direction));
        let mut xyz = [0.0; 3];
        for n in 0..NODES {
            let response = pr[n] * ar[n] + pa[n] * aa[n] + b[n];
            for (v, w) in xyz.iter_mut().zip(self.xyz_weights[n]) {
                *v += response * w;
            }
        }
        xyz
    }

    /// The model seen through `camera`: linear Rec.709, Y in cd m⁻²,
    /// each pixel the average over its area (the path tracer's box
    /// filter; a sub-pixel position with no ray counts as black).
    ///
    /// Four stratified positions per pixel; where their luminances differ
    /// by more than [`EDGE_CONTRAST`] of the largest (the horizon, the limb
    /// seen from orbit, the edge of a fisheye's circle) the pixel is
    /// averaged over an [`EDGE_SAMPLES`]² grid instead: there the light
    /// drops by orders of magnitude within a pixel, and one value at its
    /// centre is off by as much.
    pub fn image(&self, camera: &Camera, width: u32, height: u32) -> RgbImage {
        let pixels = (0..width as usize * height as usize)
            .into_par_iter()
            .map(|i| {
                let (px, py) = ((i % width as usize) as f64, (i / width as usize) as f64);
                let at = |fx: f64, fy: f64| {
                    camera
                        .direction(px + fx, py + fy)
                        .map_or([0.0; 3], |dir| self.xyz(dir))
                };
                let mean = |grid: usize| {
                    let mut sum = [0.0; 3];
                    for k in 0..grid * grid {
                        let step = 1.0 / grid as f64;
                        let xyz = at(
                            ((k % grid) as f64 + 0.5) * step,
                            ((k / grid) as f64 + 0.5) * step,
                        );
                        for (s, v) in sum.iter_mut().zip(xyz) {
                            *s += v;
                        }
                    }
                    sum.map(|s| s / (grid * grid) as f64)
                };
                let four = [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)]
                    .map(|(fx, fy)| at(fx, fy));
                let luminance = four.map(|xyz| xyz[1]);
                let (low, high) = luminance
                    .iter()
                    .fold((f64::INFINITY, 0.0_f64), |(l, h), &y| (l.min(y), h.max(y)));
                let xyz = if high - low > EDGE_CONTRAST * high {
                    mean(EDGE_SAMPLES)
                } else {
                    std::array::from_fn(|c| four.iter().map(|v| v[c]).sum::<f64>() / 4.0)
                };
                xyz_to_rec709(xyz).map(|v| v as f32)
            })
            .collect();
        RgbImage {
            width,
            height,
            pixels,
        }
    }
}

/// The spread of a pixel's four first luminances, relative to the
/// largest, past which [`SkyModel::image`] averages it over a finer grid.
const EDGE_CONTRAST: f64 = 0.1;
/// Positions per axis of [`SkyModel::image`]'s finer grid.
const EDGE_SAMPLES: usize = 8;

/// Node `k`'s wavelength, nm.
fn node_wavelength(k: usize) -> f64 {
    RANGE_NM.0 + (RANGE_NM.1 - RANGE_NM.0) * k as f64 / (NODES - 1) as f64
}

/// K_M ∫ E_sun(λ) h_k(λ) x̄(λ) dλ for the hat function h_k of each node,
/// on the colour-matching table's own grid.
fn xyz_weights(
    medium: &Medium,
    lane_table: &LaneTable,
    cmf: &ColourMatching,
    nodes: &[f64],
) -> [[f64; 3]; NODES] {
    // The sun at the grid's wavelengths, four at a time.
    let grid: Vec<f64> = cmf.grid_nm().collect();
    let sun: Vec<f64> = grid
        .chunks(LANES)
        .flat_map(|w| {
            let lanes = lane_table.lanes(Lanes::from_fn(|j| w[j.min(w.len() - 1)]), LANES, medium);
            (0..w.len()).map(move |j| lanes.sun_irradiance[j])
        })
        .collect();
    let step = nodes[1] - nodes[0];
    std::array::from_fn(|k| {
        let xyz = cmf.integrate(|w| {
            let i = grid.partition_point(|&g| g < w);
            let hat = (1.0 - (w - nodes[k]).abs() / step).max(0.0);
            // Beyond the end nodes the end node holds the response.
            let hat = if (k == 0 && w < nodes[0]) || (k == NODES - 1 && w > nodes[NODES - 1]) {
                1.0
            } else {
                hat
            };
            sun.get(i).copied().unwrap_or(0.0) * hat
        });
        xyz.map(|v| K_M * v)
    })
}

/// Solar-zenith cosine of fractional node `k` of [`MS_ZENITHS`]: square
/// spacing about the horizon (μ = ±u², u from −1 to 1), where the light
/// changes fastest with the sun's height (twilight, sunset).
fn zenith_cosine_of(k: f64) -> f64 {
    let u = 2.0 * k / (MS_ZENITHS - 1) as f64 - 1.0;
    u * u.abs()
}

/// [`zenith_cosine_of`]'s inverse.
fn zenith_index(mu_s: f64) -> f64 {
    let mu = mu_s.clamp(-1.0, 1.0);
    let u = mu.signum() * mu.abs().sqrt();
    0.5 * (u + 1.0) * (MS_ZENITHS - 1) as f64
}

/// Altitude of row `i` of `n` over an atmosphere `top_m` high: square
/// spacing, dense low down.
fn altitude_of(i: usize, n: usize, top_m: f64) -> f64 {
    (top_m * (i as f64 / (n - 1) as f64).powi(2)).clamp(1.0, top_m - 1.0)
}

/// Fractional row of `altitude_m` ([`altitude_of`]'s inverse).
fn altitude_index(altitude_m: f64, n: usize, top_m: f64) -> f64 {
    (altitude_m / top_m).clamp(0.0, 1.0).sqrt() * (n - 1) as f64
}

/// The observer's sky table's rows: elevations crowding about the horizon
/// (at `horizon_rad`), where the sky changes fastest (Hillaire's mapping),
/// the upper half ending at `top_rad`, the highest elevation at which a
/// view ray still meets the air (π/2 inside the atmosphere; the grazing
/// ray of its top from outside, where the bright limb is a few tenths of
/// a degree high and would otherwise fall between two rows).
#[derive(Clone, Copy)]
struct Rows {
    horizon_rad: f64,
    top_rad: f64,
}

impl Rows {
    /// The rows of an observer `r_m` from the centre of a planet of
    /// radius `planet_radius_m` with an atmosphere up to `top_radius_m`.
    fn new(planet_radius_m: f64, top_radius_m: f64, r_m: f64) -> Self {
        // The horizon dips by acos(R/r) below the horizontal: its elevation
        // is the arcsine of its zenith cosine, −√(1 − (R/r)²).
        let below = |radius_m: f64| {
            horizon_cosine(radius_m, r_m.max(radius_m))
                .clamp(-1.0, 0.0)
                .asin()
        };
        let horizon_rad = below(planet_radius_m);
        let top_rad = if r_m > top_radius_m {
            below(top_radius_m)
        } else {
            PI / 2.0
        };
        Self {
            horizon_rad,
            top_rad,
        }
    }

    /// Elevation of fractional `row`.
    fn elevation(&self, row: f64) -> f64 {
        let v = row / (VIEW_ROWS - 1) as f64;
        if v >= 0.5 {
            let u = 2.0 * v - 1.0;
            self.horizon_rad + u * u * (self.top_rad - self.horizon_rad)
        } else {
            let u = 1.0 - 2.0 * v;
            self.horizon_rad - u * u * (PI / 2.0 + self.horizon_rad)
        }
    }

    /// Fractional row of `elevation` ([`Self::elevation`]'s inverse; the
    /// last row above `top_rad`).
    fn row(&self, elevation: f64) -> f64 {
        let h = self.horizon_rad;
        let v = if elevation >= h {
            0.5 + 0.5 * ((elevation - h) / (self.top_rad - h)).min(1.0).sqrt()
        } else {
            0.5 - 0.5 * ((h - elevation) / (PI / 2.0 + h)).sqrt()
        };
        v.clamp(0.0, 1.0) * (VIEW_ROWS - 1) as f64
    }
}

/// The direction at `elevation` and `azimuth` from the sun in `frame`.
fn direction(frame: &[DVec3; 3], elevation: f64, azimuth: f64) -> DVec3 {
    let [zenith, x, y] = *frame;
    (zenith * elevation.sin() + (x * azimuth.cos() + y * azimuth.sin()) * elevation.cos())
        .normalize()
}

/// `n` directions spread evenly over the sphere (a Fibonacci lattice).
fn fibonacci_sphere(n: usize) -> Vec<DVec3> {
    let golden = PI * (3.0 - 5.0_f64.sqrt());
    (0..n)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / n as f64;
            let r = (1.0 - z * z).max(0.0).sqrt();
            let phi = golden * i as f64;
            DVec3::new(r * phi.cos(), r * phi.sin(), z)
        })
        .collect()
}

/// Bilinear interpolation in a row-major table, `columns` wide, of the
/// spectra `pick` takes from its entries, at fractional (row, column),
/// each clamped to its count.
fn bilinear_with<T>(
    values: &[T],
    columns: usize,
    (row, rows): (f64, usize),
    (column, column_count): (f64, usize),
    pick: impl Fn(&T) -> Spectrum,
) -> Spectrum {
    let split = |x: f64, n: usize| {
        let x = x.clamp(0.0, (n - 1) as f64);
        let i = (x as usize).min(n.saturating_sub(2));
        (i, (x - i as f64).min(1.0))
    };
    let (i, fi) = split(row, rows);
    let (k, fk) = split(column, column_count);
    let at =
        |i: usize, k: usize| pick(&values[(i.min(rows - 1)) * columns + k.min(column_count - 1)]);
    let (a, b, c, d) = (at(i, k), at(i, k + 1), at(i + 1, k), at(i + 1, k + 1));
    std::array::from_fn(|n| {
        let lo = a[n] + fk * (b[n] - a[n]);
        let hi = c[n] + fk * (d[n] - c[n]);
        lo + fi * (hi - lo)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Renderer;
    use crate::Scene;

    /// The observer's table against the march it tabulates, at elevations
    /// about the horizon (where the sky's light drops by two orders of
    /// magnitude to the ground's), for an observer on the ground and one
    /// in orbit (horizon 20° below the horizontal).
    #[test]
    fn the_view_table_matches_its_march_about_the_horizon() {
        for name in ["sunset", "space"] {
            let renderer = Renderer::new(&Scene::preset(name).unwrap()).unwrap();
            let (medium, sun) = (&renderer.medium, renderer.sun_direction);
            let model = SkyModel::new(
                medium,
                &renderer.lane_table,
                renderer.cmf,
                sun,
                renderer.observer_m,
            );
            let field = ModelField::new(medium, &renderer.lane_table, sun);
            let [zenith, x, y] = model.frame;
            // (exact, table) luminance per view.
            let mut pairs = Vec::new();
            for step in -20..=20 {
                // Half-degree steps about the horizon (its dip is
                // acos(R/r)), between the table's rows.
                let dip = (medium.planet_radius_m / renderer.observer_m.length()).acos();
                let elevation = -dip + (f64::from(step) + 0.25) * 0.5_f64.to_radians();
                for azimuth_deg in [30.0_f64, 90.0, 150.0] {
                    let dir = direction(&[zenith, x, y], elevation, azimuth_deg.to_radians());
                    let response = field.radiance(medium, renderer.observer_m, dir);
                    let exact: f64 = (0..NODES)
                        .map(|n| response[n] * model.xyz_weights[n][1])
                        .sum();
                    pairs.push((exact, model.xyz(dir)[1]));
                }
            }
            // Off by the view's own light, or by a thousandth of the
            // brightest where the light is far below it (the limb's top
            // from orbit, the sky's drop to the ground).
            let peak = pairs.iter().map(|p| p.0).fold(0.0, f64::max);
            let worst = pairs
                .iter()
                .map(|&(exact, table)| (table - exact).abs() / exact.max(1e-3 * peak))
                .fold(0.0, f64::max);
            // Bilinear interpolation between rows a fraction of a degree
            // apart at the horizon: a few per cent where the light changes
            // fastest.
            assert!(worst < 0.05, "{name}: table off its march by {worst}");
        }
    }
}
