//! The model's optics: the atmosphere at the model's wavelengths, its
//! phase functions, the tables of light scattered twice or more as they
//! are looked up, and the march along a ray that gathers the light.

use std::f64::consts::PI;

use glam::DVec3;

use super::geometric::geometric_spectrum;
use crate::physics::rayleigh;
use crate::render::medium::{Medium, SpectralLanes, LANES};

/// Wavelength groups of [`LANES`] wavelengths each.
pub(super) const GROUPS: usize = 4;
/// Wavelengths at which the model is computed.
pub(super) const NODES: usize = GROUPS * LANES;
/// The nodes' range, nm (the colour-matching functions').
pub(super) const RANGE_NM: (f64, f64) = (360.0, 830.0);

/// A quantity at the model's wavelengths.
pub(super) type Spectrum = [f64; NODES];

/// Steps of a march inside the multiple-scattering and irradiance tables
/// (at 12, the second order's light just above the horizon at sunset read
/// 9–20 % over the path tracer's, at 24 6–14 %; at 48 rather than 24 the
/// first frame at 128×64 came 3.03 → 2.70 % off at sunset and 1.08 →
/// 0.93 % at midday, the rest unchanged).
pub(super) const TABLE_STEPS: usize = 48;
/// Steps of a march through the table of an order past the first.
pub(super) const TABLE_STEPS_HIGHER: usize = 8;
/// Directions over which Ψ's integrals are summed: outside the cap about
/// the sun, as dense as an even set of this many.
pub(super) const MS_DIRECTIONS: usize = 128;
/// ... and inside it, as dense as an even set of this many
/// ([`Quadrature::about_the_sun`]).
pub(super) const MS_DIRECTIONS_NEAR_SUN: usize = 768;
/// The cosine of the cap's half-angle about the sun (40°: wide enough for
/// the Martian dust's aureole and twilight's arch about the set sun).
pub(super) const SUN_CAP_COSINE: f64 = 0.766;
/// ... and within the inner cap about the sun, of cosine
/// [`SUN_INNER_CAP_COSINE`], as dense as an even set of this many, for
/// the once-scattered light ([`Quadrature::rings`]): cells of about 2°,
/// as narrow as the Martian dust's forward peak (half its height 3° from
/// the sun at 500 nm). The light scattered twice toward a view near the
/// sun is the product of two such peaks, the once-scattered light's
/// about the sun and the phase function's about the view; averaged over
/// cells of 4° (768's) the product read a fifth too faint 2–8° from the
/// sun at Mars sunset.
pub(super) const MS_DIRECTIONS_AT_SUN: usize = 3072;
/// The cosine of the inner cap's half-angle (20°).
pub(super) const SUN_INNER_CAP_COSINE: f64 = 0.94;
/// ... and within the innermost cap, of cosine [`SUN_CORE_CAP_COSINE`]
/// (10°), as dense as an even set of this many: cells of about 1°. With
/// 2° cells there, the product of the two peaks was still blurred: Mars
/// sunset's sky read 5–7 % too faint 2–5° above the sun and up to 10 %
/// too bright on the aureole's skirt (first frame at 128×64 11.6 % off
/// the path tracer's, 10.1 % with these cells).
pub(super) const MS_DIRECTIONS_AT_CORE: usize = 12288;
/// The cosine of the innermost cap's half-angle (10°).
pub(super) const SUN_CORE_CAP_COSINE: f64 = 0.985;
/// Directions over which the ground's irradiance from the orders past the
/// first is summed (their light is smooth, and no phase function is read).
pub(super) const GROUND_DIRECTIONS_HIGHER: usize = 64;
/// Altitudes and solar-zenith cosines of the multiple-scattering table.
/// Along a view near the horizon J changes fastest in the lowest
/// kilometres, where the ground hides more of the phase function's peak
/// the lower the point: at 9 rows (the second at 550 m on the Earth) the
/// first frame at Mars sunset read 4.9 % off the path tracer's and the
/// Earth's sunset 2.7 % (twilight 2.0 %), at 13 (the second at 200 m)
/// 4.3 % and 1.9 % (twilight 2.7 %), at 17 4.3 % and 1.6 % for a third
/// more time than 13 (256×128, against 2 × 24–40 passes; twilight's
/// figures with the sun taken as a point, 1.6 % at 13 rows over its disc,
/// `super::sun`).
pub(super) const MS_ALTITUDES: usize = 13;
/// See [`MS_ALTITUDES`].
pub(super) const MS_ZENITHS: usize = 33;
/// Solar-zenith nodes of the sky's irradiance on the ground
/// ([`SkyIrradiance`]), spaced as [`MS_ZENITHS`]' and four times as dense:
/// every fourth is one of theirs. Below the horizon the irradiance falls
/// by an order of magnitude from node to node of [`MS_ZENITHS`] (−5.6°,
/// −3.6°), its logarithm curving, and the geometric mean between them
/// left twilight's ground (sun −4°) 0.97× its own sky's irradiance — the
/// cosine-weighted integral of the model's image, 0.998× the path
/// tracer's. The table is cheap beside Ψ's: a march per upward direction
/// and node, at the ground only.
pub(super) const E_ZENITHS: usize = 4 * (MS_ZENITHS - 1) + 1;

/// The medium seen through one group of lanes per node group.
pub(super) struct Optics<'a> {
    pub(super) medium: &'a Medium,
    pub(super) groups: &'a [SpectralLanes],
    pub(super) phases: &'a Phases,
    pub(super) sun_direction: DVec3,
}

/// What a march gathers along a ray, per wavelength.
#[derive(Default)]
pub(super) struct Gathered {
    /// ∫ T σ_R T_sun dt.
    pub(super) rayleigh: Spectrum,
    /// ∫ T σ_A T_sun dt.
    pub(super) aerosol: Spectrum,
    /// ∫ T σ_s Ψ dt plus the ground's reflected light.
    pub(super) isotropic: Spectrum,
    /// ∫ T σ_s dt.
    pub(super) scattering: Spectrum,
}

impl Optics<'_> {
    /// Marches from `origin` along `dir` in about `steps` steps, short
    /// where the ray is lowest ([`step_ends`]), gathering the sunlight
    /// scattered toward `origin`, the multiple scattering and the ground's
    /// light where the ray ends on it, as `sources` says.
    pub(super) fn march(
        &self,
        origin: DVec3,
        dir: DVec3,
        steps: usize,
        sources: Sources<'_>,
    ) -> Gathered {
        let mut out = [Gathered::default()];
        self.march_fan(origin, &[dir], steps, sources, &mut out);
        let [g] = out;
        g
    }

    /// [`Self::march`] along each of `dirs` into `out`, the directions all
    /// at one angle to `origin`'s zenith (a row of the observer's view
    /// table). Over a spherical planet such rays pass through the same
    /// altitudes at the same distances, so their steps, the air's
    /// coefficients and its transmittance along them are computed once;
    /// only the sunlight and the multiple scattering, which depend on the
    /// angle to the sun, are computed per direction.
    pub(super) fn march_fan(
        &self,
        origin: DVec3,
        dirs: &[DVec3],
        steps: usize,
        sources: Sources<'_>,
        out: &mut [Gathered],
    ) {
        debug_assert_eq!(dirs.len(), out.len());
        let Some(&first) = dirs.first() else {
            return;
        };
        debug_assert!(dirs
            .iter()
            .all(|d| (d.dot(origin) - first.dot(origin)).abs() <= 1e-9 * origin.length().max(1.0)));
        let Some(span) = self.medium.span(origin, first) else {
            return;
        };
        let mut transmittance = [1.0; NODES];
        let mut t0 = span.t_enter;
        for t1 in step_ends(span.t_enter, span.t_exit, -origin.dot(first), steps) {
            let dt = t1 - t0;
            let tm = 0.5 * (t0 + t1);
            let x0 = origin + first * tm;
            let r = x0.length();
            let mu_v = x0.dot(first) / r;
            // Per wavelength: the step's weight ∫ T dt (σ_t constant over
            // the step: T₀ (1 − e^{−σΔt})/σ) and its coefficients.
            let mut weight = [0.0; NODES];
            let mut rayleigh = [0.0; NODES];
            let mut aerosol = [0.0; NODES];
            let mut scattering = [0.0; NODES];
            for (g, lanes) in self.groups.iter().enumerate() {
                let c = self.medium.coefficients(r, lanes);
                for j in 0..LANES {
                    let k = g * LANES + j;
                    let extinction = c.extinction(j);
                    let step_t = (-extinction * dt).exp();
                    weight[k] = if extinction > 0.0 {
                        transmittance[k] * (1.0 - step_t) / extinction
                    } else {
                        transmittance[k] * dt
                    };
                    rayleigh[k] = c.rayleigh[j];
                    aerosol[k] = c.aerosol_scattering[j];
                    scattering[k] = c.scattering(j);
                    transmittance[k] *= step_t;
                }
            }
            for (dir, o) in dirs.iter().zip(out.iter_mut()) {
                let x = origin + *dir * tm;
                let nu = dir.dot(self.sun_direction);
                let sun = if sources.sunlight {
                    self.sun_transmittance(x)
                } else {
                    [0.0; NODES]
                };
                let psi = sources
                    .ms
                    .map(|m| m.at(r, x.dot(self.sun_direction) / r, nu, mu_v));
                for k in 0..NODES {
                    let w = weight[k];
                    o.rayleigh[k] += w * rayleigh[k] * sun[k];
                    o.aerosol[k] += w * aerosol[k] * sun[k];
                    o.scattering[k] += w * scattering[k];
                    if let Some([psi_r, psi_a]) = &psi {
                        o.isotropic[k] += w * (rayleigh[k] * psi_r[k] + aerosol[k] * psi_a[k]);
                    }
                }
            }
            t0 = t1;
        }
        if span.hits_ground {
            for (dir, o) in dirs.iter().zip(out.iter_mut()) {
                let g = origin + *dir * span.t_exit;
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
                        o.isotropic[k] += transmittance[k] * lanes.ground_albedo[j] / PI * e;
                    }
                }
            }
        }
    }

    /// These optics with the sun at solar-zenith cosine `mu_s` above a
    /// point on the z axis (in the x–z plane), and that sun's direction.
    pub(super) fn with_sun_at(&self, mu_s: f64) -> (DVec3, Self) {
        let sun = DVec3::new((1.0 - mu_s * mu_s).max(0.0).sqrt(), 0.0, mu_s);
        let optics = Optics {
            sun_direction: sun,
            ..*self
        };
        (sun, optics)
    }
}

/// The far ends of about `steps` steps over [t_enter, t_exit], in order,
/// lengths growing as the square away from the ray's lowest point
/// (`t_perigee`, the parameter nearest the planet's centre, clamped into
/// the span): the air is densest there, and its density falls with
/// scale heights (8 km for the air, about 1 km for haze) far shorter than
/// a ray from orbit to the ground. Each side of that point gets steps in
/// proportion to its length, at least one; a ray from an observer looking
/// up starts at its lowest point and keeps one side.
///
/// Steps uniform in length, or short at the start only, put a few coarse
/// steps through the lowest kilometres of a ray from above: their
/// midpoints there miss most of the haze (the sum of a convex exponential
/// at midpoints falls short of its integral), and the ground seen from
/// orbit read 0.8–0.9× the path tracer's.
fn step_ends(t_enter: f64, t_exit: f64, t_perigee: f64, steps: usize) -> impl Iterator<Item = f64> {
    let t_low = t_perigee.clamp(t_enter, t_exit);
    let (before, after) = (t_low - t_enter, t_exit - t_low);
    let length = before + after;
    let share = |side: f64| {
        if side > 0.0 {
            ((steps as f64 * side / length).round() as usize).max(1)
        } else {
            0
        }
    };
    let (n_before, n_after) = (share(before), share(after));
    // Toward the lowest point: the steps' far ends from the entry on.
    let toward = (1..=n_before).map(move |s| {
        if s == n_before {
            t_low
        } else {
            let u = (n_before - s) as f64 / n_before as f64;
            t_low - before * u * u
        }
    });
    let away = (1..=n_after).map(move |s| t_low + after * (s as f64 / n_after as f64).powi(2));
    toward.chain(away)
}

/// Samples of [`Phases`].
pub(super) const PHASE_SAMPLES: usize = 2048;

/// The Rayleigh and aerosol phase functions at each wavelength, tabulated
/// at μ = 1 − 2u², u uniform (0.11° apart at the forward peak), linear in
/// between: the model evaluates them about a million times, and a
/// tabulated phase function over wavelength costs two searches each.
pub(super) struct Phases {
    pub(super) values: Vec<(Spectrum, Spectrum)>,
}

impl Phases {
    pub(super) fn new(medium: &Medium, groups: &[SpectralLanes]) -> Self {
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

    /// These phase functions averaged over a cap of `directions`'
    /// cell's area (4π/n, angular radius α with cos α = 1 − 2/n) about
    /// each angle: the weight of one of `directions` evenly spread
    /// directions in a sum Σ L(ω) P(ω·v) 4π/n that stands for ∫ L P dω.
    /// A forward peak narrower than the directions' spacing makes the sum
    /// with P itself hit or miss it from one view to the next (the
    /// Martian dust's low sky came out twice too bright away from the
    /// sun and a fifth too dark toward it); averaged over the cell, every
    /// view gets its share, and the average keeps P's normalisation.
    ///
    /// For the cap about the direction at angle θ from the peak, the
    /// circle at angle γ from the peak lies inside it over the azimuths
    /// |φ| ≤ Φ(γ), cos Φ = (cos α − cos θ cos γ)/(sin θ sin γ) (all of
    /// it where γ ≤ α − θ), so P̄(θ) = ∫ 2Φ(γ) P(cos γ) d(−cos γ) / Ω,
    /// Ω = 2π(1 − cos α); the integral runs over the table's own
    /// coordinate u (μ = 1 − 2u², dμ = −4u du), dense at the peak.
    pub(super) fn averaged_over_cells(&self, directions: usize) -> Self {
        const STEPS: usize = 96;
        let cos_alpha = 1.0 - 2.0 / directions as f64;
        let alpha = cos_alpha.acos();
        let solid_angle = 2.0 * PI * (1.0 - cos_alpha);
        let values = (0..PHASE_SAMPLES)
            .map(|i| {
                let u = i as f64 / (PHASE_SAMPLES - 1) as f64;
                let mu = 1.0 - 2.0 * u * u;
                let theta = mu.clamp(-1.0, 1.0).acos();
                let (sin_theta, cos_theta) = theta.sin_cos();
                let u_of = |gamma: f64| (0.5 * (1.0 - gamma.cos())).max(0.0).sqrt();
                let (u_lo, u_hi) = (
                    u_of((theta - alpha).max(0.0)),
                    u_of((theta + alpha).min(PI)),
                );
                let du = (u_hi - u_lo) / STEPS as f64;
                let (mut r, mut a) = ([0.0; NODES], [0.0; NODES]);
                for k in 0..STEPS {
                    let uk = u_lo + (k as f64 + 0.5) * du;
                    let cos_gamma = 1.0 - 2.0 * uk * uk;
                    let sin_gamma = (1.0 - cos_gamma * cos_gamma).max(0.0).sqrt();
                    let across = sin_theta * sin_gamma;
                    let half_arc = if across < 1e-12 {
                        if cos_gamma * cos_theta >= cos_alpha {
                            PI
                        } else {
                            0.0
                        }
                    } else {
                        ((cos_alpha - cos_theta * cos_gamma) / across)
                            .clamp(-1.0, 1.0)
                            .acos()
                    };
                    let w = 2.0 * half_arc * 4.0 * uk * du / solid_angle;
                    let (pr, pa) = self.at(cos_gamma);
                    for n in 0..NODES {
                        r[n] += w * pr[n];
                        a[n] += w * pa[n];
                    }
                }
                (r, a)
            })
            .collect();
        Self { values }
    }

    pub(super) fn at(&self, mu: f64) -> (Spectrum, Spectrum) {
        let x = (0.5 * (1.0 - mu.clamp(-1.0, 1.0))).sqrt() * (PHASE_SAMPLES - 1) as f64;
        let (i, f) = split(x, PHASE_SAMPLES);
        let ((ra, aa), (rb, ab)) = (&self.values[i], &self.values[i + 1]);
        (
            std::array::from_fn(|n| ra[n] + f * (rb[n] - ra[n])),
            std::array::from_fn(|n| aa[n] + f * (ab[n] - aa[n])),
        )
    }
}

/// The light a march gathers.
#[derive(Clone, Copy)]
pub(super) struct Sources<'a> {
    /// Sunlight scattered once along the ray.
    pub(super) sunlight: bool,
    /// Light scattered twice or more along the ray, per unit scattering
    /// coefficient.
    pub(super) ms: Option<&'a MsTable>,
    /// The sun on the ground where the ray ends on it.
    pub(super) ground_sun: bool,
    /// The sky's irradiance on the ground where the ray ends on it.
    pub(super) ground_sky: Option<&'a SkyIrradiance>,
}

impl<'a> Sources<'a> {
    /// Everything: what an observer sees.
    pub(super) fn all(ms: &'a MsTable, sky: &'a SkyIrradiance) -> Self {
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
/// azimuths about it), times a factor over the view's zenith and azimuth:
/// Bruneton & Neyret's (2008) iteration over scattering orders. The
/// model's Ψ is the sum over orders (`orders::scattering_orders`).
#[derive(Clone)]
pub(super) struct MsTable {
    pub(super) planet_radius_m: f64,
    pub(super) top_m: f64,
    /// Per (altitude, zenith, ν): (J_R, J_A).
    pub(super) values: Vec<[Spectrum; 2]>,
    /// Per (altitude, zenith, view zenith, view azimuth): J at that view,
    /// for each of R and A; summed over orders.
    pub(super) zenith_sums: Vec<[Spectrum; 2]>,
    /// Per (altitude, zenith, view zenith, view azimuth): the ratio of the
    /// two, by which the ν table's J is scaled at that view.
    pub(super) zenith_factors: Vec<[Factor; 2]>,
}

/// A zenith factor at the model's wavelengths, in single precision: a
/// ratio near one, needed to a few parts in ten thousand, read sixteen
/// at a time by every look-up of the table ([`MsTable::at`]), which is
/// the largest of the model's tables: half the bytes to fetch, and twice
/// the numbers per vector instruction.
pub(super) type Factor = [f32; NODES];

/// View-zenith cosines of [`MsTable`]'s zenith factors: μ_v = u|u|,
/// dense about the horizon.
pub(super) const MS_VIEW_ZENITHS: usize = 13;
/// View azimuths from the sun's (0–180°) of the zenith factors, square
/// spacing from the sun's ([`view_azimuth_of`]).
pub(super) const MS_VIEW_AZIMUTHS: usize = 12;

/// The azimuth from the sun's (radians, 0–π) of column `b` of the zenith
/// factors: φ = π ((b + ½)/n)², dense toward the sun (0.3°, 2.8°, 7.8° …
/// 166°). Beside a low sun the views sweep the aureole within a few
/// degrees of azimuth, where the share of the phase function's peak that
/// reaches below the horizon changes fastest; at 30° spacing (6 even
/// columns) the second order at Mars sunset read 1.05–1.10× the path
/// tracer's 6–15° beside the sun at the horizon.
pub(super) fn view_azimuth_of(b: usize) -> f64 {
    let u = (b as f64 + 0.5) / MS_VIEW_AZIMUTHS as f64;
    PI * u * u
}

/// [`view_azimuth_of`]'s inverse, as a fractional column.
pub(super) fn view_azimuth_index(phi: f64) -> f64 {
    (phi / PI).clamp(0.0, 1.0).sqrt() * MS_VIEW_AZIMUTHS as f64 - 0.5
}

pub(super) fn view_zenith_cosine_of(i: usize) -> f64 {
    let u = 2.0 * i as f64 / (MS_VIEW_ZENITHS - 1) as f64 - 1.0;
    u * u.abs()
}

pub(super) fn view_zenith_index(mu_v: f64) -> f64 {
    let mu = mu_v.clamp(-1.0, 1.0);
    0.5 * (mu.signum() * mu.abs().sqrt() + 1.0) * (MS_VIEW_ZENITHS - 1) as f64
}

/// View–sun cosines of [`MsTable`]: ν = 1 − 2u², dense about the sun
/// (1.8° apart there: the light scattered two and more times about the
/// sun at Mars sunset is an aureole a few degrees wide; at 16 entries,
/// 7.6° apart, it fell between two, and at 32, 3.7° apart, the first
/// frame at 128×64 read 11.6 % off, not 10.1 %).
pub(super) const MS_VIEW_ANGLES: usize = 64;

pub(super) fn view_cosine_of(i: usize) -> f64 {
    let u = i as f64 / (MS_VIEW_ANGLES - 1) as f64;
    1.0 - 2.0 * u * u
}

pub(super) fn view_cosine_index(nu: f64) -> f64 {
    (0.5 * (1.0 - nu.clamp(-1.0, 1.0))).sqrt() * (MS_VIEW_ANGLES - 1) as f64
}

/// The entry below fractional index `x` of a table of `n` entries and the
/// weight of the one above it, `x` clamped to the table: every linear
/// look-up of the model's tables.
pub(super) fn split(x: f64, n: usize) -> (usize, f64) {
    let x = x.clamp(0.0, (n - 1) as f64);
    let i = (x as usize).min(n - 2);
    (i, x - i as f64)
}

impl MsTable {
    /// The altitude row and the solar-zenith slice below distance `r`
    /// from the centre and solar-zenith cosine `mu_s`, each with the
    /// weight of the next ([`split`]).
    fn altitude_and_zenith(&self, r: f64, mu_s: f64) -> ((usize, f64), (usize, f64)) {
        (
            split(
                altitude_index(r - self.planet_radius_m, MS_ALTITUDES, self.top_m),
                MS_ALTITUDES,
            ),
            split(zenith_index(mu_s), MS_ZENITHS),
        )
    }

    /// (J_R, J_A) of the ν table at its `angle`-th view–sun cosine
    /// ([`view_cosine_of`]), distance `r` from the centre and solar-zenith
    /// cosine `mu_s`, without the view's zenith factor: the shape of the
    /// light scattered more than once about the sun.
    pub(super) fn about_sun(&self, r: f64, mu_s: f64, angle: usize) -> [Spectrum; 2] {
        let ((i, fi), (k, fk)) = self.altitude_and_zenith(r, mu_s);
        let slice = |k: usize| {
            let at = |i: usize| &self.values[(i * MS_ZENITHS + k) * MS_VIEW_ANGLES + angle];
            let (low, high) = (at(i), at(i + 1));
            [0, 1].map(|x| std::array::from_fn(|n| low[x][n] + fi * (high[x][n] - low[x][n])))
        };
        let (low, high): ([Spectrum; 2], [Spectrum; 2]) = (slice(k), slice(k + 1));
        [0, 1].map(|x| geometric_spectrum(&low[x], &high[x], fk))
    }

    /// (J_R, J_A) at distance `r` from the centre, solar-zenith cosine
    /// `mu_s`, view–sun cosine `nu` and view-zenith cosine `mu_v`.
    pub(super) fn at(&self, r: f64, mu_s: f64, nu: f64, mu_v: f64) -> [Spectrum; 2] {
        let ((i, fi), (k, fk)) = self.altitude_and_zenith(r, mu_s);
        let (a, fa) = split(view_cosine_index(nu), MS_VIEW_ANGLES);
        let (z, fz) = split(view_zenith_index(mu_v), MS_VIEW_ZENITHS);
        // The view's azimuth from the sun's, φ ∈ [0, π], from
        // ν = μ_s μ_v + √(1 − μ_s²) √(1 − μ_v²) cos φ.
        let across = ((1.0 - mu_s * mu_s) * (1.0 - mu_v * mu_v)).max(0.0).sqrt();
        let cos_phi = if across > 1e-9 {
            ((nu - mu_s * mu_v) / across).clamp(-1.0, 1.0)
        } else {
            1.0
        };
        let (b, fb) = split(view_azimuth_index(cos_phi.acos()), MS_VIEW_AZIMUTHS);
        // The two azimuth columns about φ lie side by side: each of the
        // eight (altitude, zenith, view zenith) corners reads one pair.
        let mut factor = [[0.0_f32; NODES]; 2];
        for (di, wi) in [(0, 1.0 - fi), (1, fi)] {
            for (dk, wk) in [(0, 1.0 - fk), (1, fk)] {
                for (dz, wz) in [(0, 1.0 - fz), (1, fz)] {
                    let w = wi * wk * wz;
                    if w == 0.0 {
                        continue;
                    }
                    let cell = (((i + di) * MS_ZENITHS + k + dk) * MS_VIEW_ZENITHS + z + dz)
                        * MS_VIEW_AZIMUTHS
                        + b;
                    let [low, high] = [&self.zenith_factors[cell], &self.zenith_factors[cell + 1]];
                    let (w_low, w_high) = ((w * (1.0 - fb)) as f32, (w * fb) as f32);
                    for x in 0..2 {
                        add_scaled(&mut factor[x], w_low, &low[x]);
                        add_scaled(&mut factor[x], w_high, &high[x]);
                    }
                }
            }
        }
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
                    for x in 0..2 {
                        add_scaled(&mut out[x], w, &v[x]);
                    }
                }
            }
            out
        };
        let (low, high) = (slice(k), slice(k + 1));
        [0, 1].map(|x| {
            let mut j = geometric_spectrum(&low[x], &high[x], fk);
            for (v, f) in j.iter_mut().zip(factor[x]) {
                *v *= f64::from(f);
            }
            j
        })
    }
}

/// `sum` += `w` `v`, element by element (written so as to compile to
/// vector instructions).
#[inline]
pub(super) fn add_scaled<T, const N: usize>(sum: &mut [T; N], w: T, v: &[T; N])
where
    T: Copy + std::ops::Mul<Output = T> + std::ops::AddAssign,
{
    for (s, v) in sum.iter_mut().zip(v) {
        *s += w * *v;
    }
}

/// `sum` += `a` `b`, element by element (written so as to compile to
/// vector instructions: the sums over the sphere are most of a table's
/// making).
#[inline]
pub(super) fn add_product(sum: &mut Spectrum, a: &Spectrum, b: &Spectrum) {
    for ((s, a), b) in sum.iter_mut().zip(a).zip(b) {
        *s += a * b;
    }
}

/// The sky's irradiance on the ground by solar-zenith cosine (the sun's
/// own left out), of one scattering order or the sum of several.
#[derive(Clone)]
pub(super) struct SkyIrradiance {
    pub(super) values: Vec<Spectrum>,
}

impl SkyIrradiance {
    /// The irradiance at solar-zenith cosine `mu_s`, geometric between
    /// its [`E_ZENITHS`] nodes.
    pub(super) fn at(&self, mu_s: f64) -> Spectrum {
        let (k, f) = split(zenith_index_of(mu_s, E_ZENITHS), E_ZENITHS);
        let (low, high) = (&self.values[k], &self.values[k + 1]);
        geometric_spectrum(low, high, f)
    }
}

/// Solar-zenith cosine of fractional node `k` of [`MS_ZENITHS`]: square
/// spacing about the horizon (μ = ±u², u from −1 to 1), where the light
/// changes fastest with the sun's height (twilight, sunset).
pub(super) fn zenith_cosine_of(k: f64) -> f64 {
    zenith_cosine_of_node(k, MS_ZENITHS)
}

/// [`zenith_cosine_of`]'s inverse.
pub(super) fn zenith_index(mu_s: f64) -> f64 {
    zenith_index_of(mu_s, MS_ZENITHS)
}

/// Solar-zenith cosine of fractional node `k` of `nodes` spaced as
/// [`zenith_cosine_of`]'s.
pub(super) fn zenith_cosine_of_node(k: f64, nodes: usize) -> f64 {
    let u = 2.0 * k / (nodes - 1) as f64 - 1.0;
    u * u.abs()
}

/// [`zenith_cosine_of_node`]'s inverse.
pub(super) fn zenith_index_of(mu_s: f64, nodes: usize) -> f64 {
    let mu = mu_s.clamp(-1.0, 1.0);
    let u = mu.signum() * mu.abs().sqrt();
    0.5 * (u + 1.0) * (nodes - 1) as f64
}

/// Altitude of row `i` of `n` over an atmosphere `top_m` high: spacing
/// as the power 2.5, dense low down (the Earth's 13 rows at 0, 0.2, 1.1,
/// 3.1, 6.4 … km), where the haze lies (scale height about a kilometre)
/// and the light at sunset changes fastest with height (square spacing
/// put the second row at 2 km; see BENCHMARKS.md).
pub(super) fn altitude_of(i: usize, n: usize, top_m: f64) -> f64 {
    (top_m * (i as f64 / (n - 1) as f64).powf(2.5)).clamp(1.0, top_m - 1.0)
}

/// Fractional row of `altitude_m` ([`altitude_of`]'s inverse).
pub(super) fn altitude_index(altitude_m: f64, n: usize, top_m: f64) -> f64 {
    (altitude_m / top_m).clamp(0.0, 1.0).powf(0.4) * (n - 1) as f64
}

/// Node `k`'s wavelength, nm.
pub(super) fn node_wavelength(k: usize) -> f64 {
    RANGE_NM.0 + (RANGE_NM.1 - RANGE_NM.0) * k as f64 / (NODES - 1) as f64
}

/// The model's wavelength nodes as [`GROUPS`] groups of [`LANES`] lanes,
/// each with `medium`'s coefficients from `lane_table`.
pub(super) fn node_groups(
    medium: &Medium,
    lane_table: &crate::render::lanes::LaneTable,
) -> Vec<SpectralLanes> {
    (0..GROUPS)
        .map(|g| {
            let w = crate::render::medium::Lanes::from_fn(|j| node_wavelength(g * LANES + j));
            lane_table.lanes(w, LANES, medium)
        })
        .collect()
}

/// Directions to sum an integral over the sphere by, each with its
/// cell's solid angle and the phase functions averaged over a cell of
/// that size ([`Phases::averaged_over_cells`], made once by the caller:
/// several sets share them). Either spread evenly, or
/// denser within a cap about the sun: the once-scattered light arriving
/// at a point holds the aureole, as narrow as the aerosol's forward peak,
/// and the light scattered again toward a view near the sun is its
/// product with that same peak, which cells as wide as an even set's
/// smooth twice over (the Martian dust's aureole read too faint at its
/// centre and too bright on its skirt).
pub(super) struct Quadrature<'a> {
    /// Per direction (the sun at +z where `about_the_sun`): the
    /// direction, its solid angle (sr) and its cells' index.
    points: Vec<(DVec3, f64, usize)>,
    /// Phase functions averaged over each size of cell.
    cells: Vec<&'a Phases>,
    /// Whether the directions turn with the sun.
    about_the_sun: bool,
}

impl<'a> Quadrature<'a> {
    /// `count` directions spread evenly, with `cells` (the phase functions
    /// averaged over cells of 4π/`count`).
    pub(super) fn even(count: usize, cells: &'a Phases) -> Self {
        let weight = 4.0 * PI / count as f64;
        Self {
            points: fibonacci_sphere(count)
                .into_iter()
                .map(|d| (d, weight, 0))
                .collect(),
            cells: vec![cells],
            about_the_sun: false,
        }
    }

    /// The directions of an even set of `near` within the cap of cosine
    /// `cap_cosine` about the sun, and of an even set of `far` outside
    /// it, with `cells` for each (as [`Self::even`]'s); each part's solid
    /// angles sum to its area.
    pub(super) fn about_the_sun(
        (near, far): (usize, usize),
        cap_cosine: f64,
        cells: [&'a Phases; 2],
    ) -> Self {
        Self::rings(&[(near, cap_cosine), (far, -1.0)], &cells)
    }

    /// Rings about the sun, from it outward: ring k holds the directions
    /// of an even set of `rings[k].0` whose cosine to the sun lies between
    /// `rings[k].1` and the ring before's (1 for the first), with
    /// `cells[k]` (the phase functions averaged over cells of
    /// 4π/`rings[k].0`); each ring's solid angles sum to its area.
    pub(super) fn rings(rings: &[(usize, f64)], cells: &[&'a Phases]) -> Self {
        let mut points = Vec::new();
        let mut inner_cosine = 1.0;
        for (index, &(count, outer_cosine)) in rings.iter().enumerate() {
            let area = 2.0 * PI * (inner_cosine - outer_cosine);
            let part: Vec<DVec3> = fibonacci_sphere(count)
                .into_iter()
                .filter(|d| d.z > outer_cosine && d.z <= inner_cosine)
                .collect();
            let weight = area / part.len().max(1) as f64;
            points.extend(part.into_iter().map(|d| (d, weight, index)));
            inner_cosine = outer_cosine;
        }
        Self {
            points,
            cells: cells.to_vec(),
            about_the_sun: true,
        }
    }

    /// Per direction, for the sun at `sun` (in the x–z plane, as
    /// [`Optics::with_sun_at`] places it): the direction, its solid angle
    /// and its cells' phase functions.
    pub(super) fn points(&self, sun: DVec3) -> impl Iterator<Item = (DVec3, f64, &Phases)> + '_ {
        // The rotation about y taking +z to the sun.
        let (sin, cos) = (sun.x, sun.z);
        let turn = self.about_the_sun;
        self.points.iter().map(move |&(d, weight, cells)| {
            let d = if turn {
                DVec3::new(d.x * cos + d.z * sin, d.y, d.z * cos - d.x * sin)
            } else {
                d
            };
            (d, weight, self.cells[cells])
        })
    }
}

/// `n` directions spread evenly over the sphere (a Fibonacci lattice).
pub(super) fn fibonacci_sphere(n: usize) -> Vec<DVec3> {
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::Renderer;
    use crate::Scene;

    /// ∫ P dω over the sphere from the table's coordinate u
    /// (μ = 1 − 2u², dω = 2π · 4u du), at a fine midpoint rule.
    fn integral(phases: &Phases, pick: impl Fn((Spectrum, Spectrum)) -> f64) -> f64 {
        let steps: u32 = 200_000;
        (0..steps)
            .map(|k| {
                let u = (f64::from(k) + 0.5) / f64::from(steps);
                pick(phases.at(1.0 - 2.0 * u * u)) * 2.0 * PI * 4.0 * u / f64::from(steps)
            })
            .sum()
    }

    /// Averaged over cells, the phase functions keep their normalisation
    /// (the Earth's haze and the Martian dust, whose forward peak is
    /// narrower than a cell), lose their peak, and a cell's average of a
    /// constant is the constant (to the midpoint rule's half per cent at
    /// the kink where the cap first holds the peak).
    #[test]
    fn cell_averaged_phases_keep_their_integral_and_lose_the_peak() {
        for name in ["midday", "mars-noon"] {
            let renderer = Renderer::new(&Scene::preset(name).unwrap()).unwrap();
            let medium = &renderer.medium;
            let groups = node_groups(medium, &renderer.lane_table);
            let phases = Phases::new(medium, &groups);
            for directions in [32, 128] {
                let cells = phases.averaged_over_cells(directions);
                for n in [0, NODES / 2, NODES - 1] {
                    for pick in [0, 1] {
                        let value =
                            |p: (Spectrum, Spectrum)| if pick == 0 { p.0[n] } else { p.1[n] };
                        let (before, after) = (integral(&phases, value), integral(&cells, value));
                        assert!((before - 1.0).abs() < 2e-3, "{name} {pick} {n}: {before}");
                        assert!((after - 1.0).abs() < 5e-3, "{name} {pick} {n}: {after}");
                    }
                    let peak = phases.at(1.0).1[n];
                    assert!(cells.at(1.0).1[n] < peak, "{name}: the peak is kept");
                }
            }
        }
        let constant = Phases {
            values: vec![([1.0 / (4.0 * PI); NODES], [2.0; NODES]); PHASE_SAMPLES],
        };
        let cells = constant.averaged_over_cells(32);
        for i in 0..PHASE_SAMPLES {
            let (r, a) = cells.values[i];
            assert!(
                (r[0] * 4.0 * PI - 1.0).abs() < 5e-3 && (a[0] - 2.0).abs() < 1e-2,
                "{i}: {} {}",
                r[0] * 4.0 * PI,
                a[0]
            );
        }
    }

    /// A quadrature's solid angles sum to the sphere's, its cosines over
    /// the upper half to π; about the sun, its dense cap turns with the
    /// sun and it sums the Martian dust's phase function (a forward peak
    /// far narrower than the even set's cells) to 1 with the sun anywhere.
    #[test]
    fn quadratures_sum_the_sphere_and_turn_with_the_sun() {
        let renderer = Renderer::new(&Scene::preset("mars-noon").unwrap()).unwrap();
        let medium = &renderer.medium;
        let groups = node_groups(medium, &renderer.lane_table);
        let phases = Phases::new(medium, &groups);
        let (near_cells, far_cells) = (
            phases.averaged_over_cells(MS_DIRECTIONS_NEAR_SUN),
            phases.averaged_over_cells(MS_DIRECTIONS),
        );
        let even = Quadrature::even(MS_DIRECTIONS, &far_cells);
        let near = Quadrature::about_the_sun(
            (MS_DIRECTIONS_NEAR_SUN, MS_DIRECTIONS),
            SUN_CAP_COSINE,
            [&near_cells, &far_cells],
        );
        let at_sun_cells = phases.averaged_over_cells(MS_DIRECTIONS_AT_SUN);
        let rings = Quadrature::rings(
            &[
                (MS_DIRECTIONS_AT_SUN, SUN_INNER_CAP_COSINE),
                (MS_DIRECTIONS_NEAR_SUN, SUN_CAP_COSINE),
                (MS_DIRECTIONS, -1.0),
            ],
            &[&at_sun_cells, &near_cells, &far_cells],
        );
        for mu_s in [1.0_f64, 0.5, 0.0, -0.3] {
            let sun = DVec3::new((1.0 - mu_s * mu_s).sqrt(), 0.0, mu_s);
            // The inner cap holds its share of the densest set.
            let inner = rings
                .points(sun)
                .filter(|p| p.0.dot(sun) > SUN_INNER_CAP_COSINE)
                .count();
            let expected = MS_DIRECTIONS_AT_SUN as f64 * (1.0 - SUN_INNER_CAP_COSINE) / 2.0;
            assert!((inner as f64 - expected).abs() <= 1.0, "{inner} inside");
            for (name, q) in [("even", &even), ("about the sun", &near), ("rings", &rings)] {
                let total: f64 = q.points(sun).map(|p| p.1).sum();
                assert!((total / (4.0 * PI) - 1.0).abs() < 1e-9, "{name}: {total}");
                let up: f64 = q.points(sun).map(|(d, w, _)| w * d.z.max(0.0)).sum();
                assert!((up / PI - 1.0).abs() < 0.02, "{name} at {mu_s}: {up}");
                assert!(q.points(sun).all(|p| (p.0.length() - 1.0).abs() < 1e-12));
            }
            let in_cap = near
                .points(sun)
                .filter(|p| p.0.dot(sun) > SUN_CAP_COSINE)
                .count();
            let expected = MS_DIRECTIONS_NEAR_SUN as f64 * (1.0 - SUN_CAP_COSINE) / 2.0;
            assert!(
                (in_cap as f64 - expected).abs() <= 1.0,
                "{in_cap} in the cap"
            );
            // Σ P̄(ω·sun) Δω for the dust's phase at its most peaked node.
            let dust: f64 = near
                .points(sun)
                .map(|(d, w, cells)| w * cells.at(d.dot(sun)).1[0])
                .sum();
            assert!((dust - 1.0).abs() < 0.01, "dust's phase sums to {dust}");
        }
    }

    /// A march's steps end in order at the span's end, about as many as
    /// asked, shortest where the ray is lowest: from orbit down to the
    /// ground at the ground, along the limb at the tangent point, and from
    /// the ground up at the start.
    #[test]
    fn steps_are_shortest_where_the_ray_is_lowest() {
        for (t_enter, t_exit, t_perigee) in [
            (300_000.0, 400_000.0, 500_000.0), // orbit to the ground
            (0.0, 2_000_000.0, 1_000_000.0),   // the limb, tangent midway
            (0.0, 100_000.0, -5.0),            // the ground looking up
        ] {
            let ends: Vec<f64> = step_ends(t_enter, t_exit, t_perigee, 32).collect();
            assert!((31..=33).contains(&ends.len()));
            assert_eq!(*ends.last().unwrap(), t_exit);
            let mut starts = vec![t_enter];
            starts.extend(&ends[..ends.len() - 1]);
            let lengths: Vec<f64> = starts.iter().zip(&ends).map(|(a, b)| b - a).collect();
            assert!(lengths.iter().all(|&l| l > 0.0));
            let low = t_perigee.clamp(t_enter, t_exit);
            let shortest = starts
                .iter()
                .zip(&lengths)
                .min_by(|a, b| a.1.total_cmp(b.1))
                .map(|(s, l)| s + 0.5 * l)
                .unwrap();
            let longest = lengths.iter().copied().fold(0.0, f64::max);
            assert!(
                (shortest - low).abs() <= longest,
                "{t_enter} {t_exit}: shortest step at {shortest}, lowest point {low}"
            );
        }
    }
}
