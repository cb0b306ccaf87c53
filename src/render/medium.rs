//! The atmosphere as a participating medium for the path tracer.
//!
//! [`Medium`] caches the altitude profiles of an [`Atmosphere`] on a 50 m
//! grid (linear between nodes: < 10⁻⁵ relative difference from the exact
//! profiles for the 8 km air scale height), and bounds them in concentric
//! altitude *shells*. A ray's altitude is monotone on either side of its
//! perigee, so a ray splits into pieces that each stay in one shell, and the
//! shell's maximum density is a majorant for the piece — the seed paper's
//! idea ("the density at the segment's lowest point bounds a monotone
//! profile") made tight by subdivision. For residual ratio tracking (Novák
//! et al. 2014) the control follows each density profile's chord between the
//! shell's boundaries, linear in r² — along a ray r² = p² + s² (p the perigee
//! distance, s the distance from it), so the control's integral is a
//! polynomial — and the residual is bounded by how far the profiles bend away
//! from their chords inside the shell. Shadow rays, which always run to the
//! top of the atmosphere, take their control from a table of columns instead
//! ([`super::columns`]): one look-up rather than a walk through the shells.
//!
//! Several wavelengths travel together on one path: [`SpectralLanes`] holds
//! their per-molecule cross-sections (built in [`super::lanes`]), and every
//! coefficient is a [`Lanes`] array. The estimators along rays through the
//! medium are in [`super::transmittance`] and [`super::tracker`].

use glam::DVec3;

use super::columns::{ColumnTable, NODE_STEP_M};
use super::sun_columns::SunColumns;

use crate::atmosphere::{AerosolSpectrum, AlbedoSpectrum, Atmosphere, GroundAlbedo};
use crate::physics::rayleigh::Gas;
use crate::physics::{aerosol, ozone, sun};
pub use crate::plan::TransmittanceEstimator;

pub use super::lane_values::Lanes;
pub use crate::spectrum::LANES;

/// Shell boundaries (altitude, m): thin near the ground where the density
/// changes fastest in absolute terms, coarse high up where the whole shell's
/// extinction is tiny. Fewer shells mean fewer pieces per ray; thicker shells
/// mean looser bounds, more null collisions and chords that stray further
/// from the profiles (Elterman's aerosol profile bends at every km): this
/// spacing balances the two for ground and grazing rays (see BENCHMARKS.md).
fn shell_boundaries_m(top_m: f64) -> Vec<f64> {
    const STEPS: [(f64, f64); 6] = [
        (1_000.0, 250.0),
        (4_000.0, 500.0),
        (10_000.0, 1_000.0),
        (30_000.0, 2_000.0),
        (50_000.0, 5_000.0),
        (f64::INFINITY, 25_000.0),
    ];
    let mut b = Vec::new();
    let mut h = 0.0;
    while h < top_m - 1.0 {
        b.push(h);
        let step = STEPS
            .iter()
            .find(|(below, _)| h < *below)
            .map_or(25_000.0, |s| s.1);
        h += step;
    }
    b.push(top_m);
    b
}

/// Density bounds within one shell.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ShellBounds {
    air_max: f64,
    ozone_max: f64,
    aerosol_max: f64,
    pub(super) chord: Chord,
}

/// The chords of the air, aerosol and ozone profiles across one shell, as
/// functions of r² (the control of residual ratio tracking), and how far the
/// profiles stray from them.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Chord {
    /// Air (m⁻³), aerosol extinction at the reference wavelength (m⁻¹) and
    /// ozone (m⁻³) at the shell's lower boundary.
    lower: [f64; 3],
    /// Their change per m² of r².
    slope: [f64; 3],
    /// r² at the lower boundary, m².
    base_radius2_m2: f64,
    /// Largest |profile − chord| in the shell, same units as `lower`.
    deviation: [f64; 3],
}

impl Chord {
    /// The chords' densities where the squared distance from the centre is
    /// `radius2_m2`.
    pub(super) fn at(&self, radius2_m2: f64) -> [f64; 3] {
        let d = radius2_m2 - self.base_radius2_m2;
        std::array::from_fn(|k| self.lower[k] + self.slope[k] * d)
    }

    /// The chords' column amounts along a straight line from `s0` to `s1`
    /// (distances from its perigee, whose squared distance from the centre
    /// is `perigee2`): r² = p² + s², so ∫ (r² − base²) ds is
    /// (s₁ − s₀)·(p² − base² + (s₀² + s₀s₁ + s₁²)/3), free of cancellation.
    pub(super) fn columns(&self, perigee2: f64, s0: f64, s1: f64) -> [f64; 3] {
        let length = s1 - s0;
        let above_base = length
            * (perigee2 - self.base_radius2_m2 + (s0 * s0 + s0 * s1 + s1 * s1) * (1.0 / 3.0));
        std::array::from_fn(|k| self.lower[k] * length + self.slope[k] * above_base)
    }
}

#[derive(Clone, Copy, Debug)]
struct Node {
    air_m3: f64,
    ozone_m3: f64,
    /// Aerosol extinction at the reference wavelength, m⁻¹
    /// ([`Atmosphere::aerosol_reference_extinction_per_m`]: 340 nm × the
    /// amount for Elterman's spectrum, else 550 nm).
    aerosol_reference_per_m: f64,
    temperature_k: f64,
}

/// The medium of one scene, shared read-only by all render threads.
pub struct Medium {
    /// The planet's radius, m.
    pub planet_radius_m: f64,
    /// Radius of the atmosphere's top, m.
    pub top_radius_m: f64,
    nodes: Vec<Node>,
    pub(super) shell_radii_m: Vec<f64>,
    pub(super) shells: Vec<ShellBounds>,
    /// The shells' bounds as rows, and in the last slot the one shell
    /// spanning the whole atmosphere (the "global majorant" variant).
    pub(super) shell_terms: ShellTerms,
    /// The ground's albedo over wavelength (the lanes carry it per
    /// wavelength: [`SpectralLanes::ground_albedo`]).
    pub ground: GroundAlbedo,
    /// The ground's largest albedo at any wavelength: for sampling
    /// densities only.
    pub ground_albedo_max: f64,
    /// The aerosol's single-scattering albedo.
    pub(super) aerosol_albedo: AlbedoSpectrum,
    /// The aerosol's phase function.
    pub aerosol_phase: aerosol::PhaseFunction,
    /// The aerosol extinction's wavelength dependence, relative to the
    /// reference wavelength of the nodes' aerosol profile.
    pub(super) aerosol_spectrum: AerosolSpectrum,
    pub(super) ozone_on: bool,
    /// The scattering gas (its Rayleigh cross-section and depolarisation).
    pub(super) gas: Gas,
    /// Column amounts toward the sun (a sampling aid; built on first use, so
    /// renders that do not sample sunlight do not pay for it).
    sun_columns: std::sync::OnceLock<SunColumns>,
    /// The shadow rays' control, built on first use (sequentially: a
    /// parallel build inside a render pass's workers could deadlock on this
    /// lock).
    column_table: std::sync::OnceLock<ColumnTable>,
    /// The profiles at the nodes in the table's order, to build it.
    profile_nodes: Vec<[f64; 3]>,
}

/// Scattering and absorption coefficients at a point, m⁻¹, per lane.
#[derive(Clone, Copy, Debug, Default)]
pub struct Coefficients {
    /// Rayleigh scattering, m⁻¹.
    pub rayleigh: Lanes,
    /// Aerosol scattering, m⁻¹.
    pub aerosol_scattering: Lanes,
    /// Absorption (ozone and aerosols), m⁻¹.
    pub absorption: Lanes,
}

impl Coefficients {
    /// Scattering coefficient of lane `lane`, m⁻¹.
    pub fn scattering(&self, lane: usize) -> f64 {
        self.rayleigh[lane] + self.aerosol_scattering[lane]
    }
    /// Extinction coefficient of lane `lane`, m⁻¹.
    pub fn extinction(&self, lane: usize) -> f64 {
        self.scattering(lane) + self.absorption[lane]
    }
}

/// Most shells any atmosphere top (≤ 200 km) produces.
const MAX_SHELLS: usize = 40;
/// Slots of [`ShellTerms`]: the shells, then the one global shell.
pub(super) const SHELL_SLOTS: usize = MAX_SHELLS + 1;
/// The global shell's slot.
pub(super) const GLOBAL_SLOT: usize = MAX_SHELLS;

/// Extinction bounds of one shell for the lanes of one path.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct ShellExtinction {
    /// Majorant common to the active lanes.
    pub(super) majorant: f64,
    /// Bound on |extinction − control| common to the active lanes (the
    /// residual majorant; see [`SpectralLanes::control`]).
    pub(super) residual: f64,
}

/// The shells' density bounds as rows over the shells (the global shell in
/// the last slot, unused slots zero), so that a path's bounds for all shells,
/// computed for every path, are one straight loop over the slots (7.5 %
/// fewer instructions per path than a loop over shell structs from orbit,
/// `BENCHMARKS.md`).
#[derive(Clone, Debug)]
pub(super) struct ShellTerms {
    /// Largest air (m⁻³), ozone (m⁻³) and aerosol extinction at the
    /// reference wavelength (m⁻¹) in the shell.
    air_max: [f64; SHELL_SLOTS],
    ozone_max: [f64; SHELL_SLOTS],
    aerosol_max: [f64; SHELL_SLOTS],
    /// The chords' deviations (air, aerosol, ozone; [`Chord::deviation`]).
    deviation: [[f64; SHELL_SLOTS]; 3],
}

impl ShellTerms {
    fn new(shells: &[ShellBounds], global: &ShellBounds) -> Self {
        let mut terms = Self {
            air_max: [0.0; SHELL_SLOTS],
            ozone_max: [0.0; SHELL_SLOTS],
            aerosol_max: [0.0; SHELL_SLOTS],
            deviation: [[0.0; SHELL_SLOTS]; 3],
        };
        let slots = shells.iter().enumerate().chain([(GLOBAL_SLOT, global)]);
        for (i, shell) in slots {
            terms.air_max[i] = shell.air_max;
            terms.ozone_max[i] = shell.ozone_max;
            terms.aerosol_max[i] = shell.aerosol_max;
            for k in 0..3 {
                terms.deviation[k][i] = shell.chord.deviation[k];
            }
        }
        terms
    }

    /// Majorants and residual bounds of every slot for the lanes' constants
    /// (Rayleigh cross-section, ozone cross-section range, aerosol factor),
    /// each the largest over the lanes: `lanes` lists the active lanes'
    /// constants, padded with the first.
    #[allow(clippy::needless_range_loop)]
    pub(super) fn extinction(
        &self,
        lanes: &[[f64; 4]; LANES],
    ) -> ([f64; SHELL_SLOTS], [f64; SHELL_SLOTS]) {
        // `if a > b` rather than f64::max: no NaN can occur here, and the
        // plain comparison needs no NaN handling.
        let larger = |a: f64, b: f64| if a > b { a } else { b };
        let mut majorant = [0.0; SHELL_SLOTS];
        let mut residual = [0.0; SHELL_SLOTS];
        for i in 0..SHELL_SLOTS {
            let mut m = 0.0;
            let mut r = 0.0;
            for &[rayleigh, o_max, o_min, aerosol] in lanes {
                let max = rayleigh * self.air_max[i]
                    + o_max * self.ozone_max[i]
                    + aerosol * self.aerosol_max[i];
                // The chords' deviations, and for ozone the spread of its
                // cross section with temperature about the control's mid value.
                let bound = rayleigh * self.deviation[0][i]
                    + aerosol * self.deviation[1][i]
                    + 0.5 * (o_max + o_min) * self.deviation[2][i]
                    + 0.5 * (o_max - o_min) * self.ozone_max[i];
                m = larger(m, max);
                r = larger(r, bound);
            }
            majorant[i] = m;
            // A relative margin for the rounding of the chord's evaluation.
            residual[i] = r * (1.0 + 1e-9);
        }
        (majorant, residual)
    }
}

/// Per-wavelength constants of one path.
#[derive(Clone, Debug)]
pub struct SpectralLanes {
    /// Each lane's wavelength, nm.
    pub wavelengths_nm: Lanes,
    /// Number of distinct active lanes (1–4); lanes beyond repeat lane 0.
    pub active: usize,
    /// Each lane's Rayleigh cross-section, m².
    pub rayleigh_m2: Lanes,
    /// Each lane's Rayleigh phase-function depolarisation term γ.
    pub rayleigh_gamma: Lanes,
    pub(super) ozone_m2: [[f64; 11]; LANES],
    pub(super) ozone_max_m2: Lanes,
    pub(super) ozone_min_m2: Lanes,
    /// Aerosol extinction relative to the reference wavelength (see [`Node`]).
    pub(super) aerosol_factor: Lanes,
    /// Aerosol single-scattering albedo.
    pub(super) aerosol_albedo: Lanes,
    /// Top-of-atmosphere spectral irradiance, W m⁻² nm⁻¹ (or 1 for a unit sun).
    pub sun_irradiance: Lanes,
    /// The ground's Lambertian albedo.
    pub ground_albedo: Lanes,
    /// The solar disc's radiance relative to its mean, as a polynomial in
    /// the heliocentric μ ([`sun::radiance_over_mean`]; [1, 0, …] for a
    /// uniform disc).
    pub limb: [[f64; sun::LIMB_COEFFICIENTS]; LANES],
    /// Majorants and residual bounds per slot of [`ShellTerms`] for these
    /// wavelengths, computed once per path.
    pub(super) majorants: [f64; SHELL_SLOTS],
    pub(super) residuals: [f64; SHELL_SLOTS],
}

impl SpectralLanes {
    /// The control extinction of residual ratio tracking, m⁻¹, per lane,
    /// from the chords' densities (air, aerosol at the reference
    /// wavelength, ozone): Rayleigh and aerosol as in
    /// [`Medium::coefficients`], ozone with the middle of the lane's
    /// cross-section range over temperature.
    pub(super) fn control(&self, densities: [f64; 3]) -> Lanes {
        Lanes::from_fn(|j| {
            self.rayleigh_m2[j] * densities[0]
                + self.aerosol_factor[j] * densities[1]
                + 0.5 * (self.ozone_max_m2[j] + self.ozone_min_m2[j]) * densities[2]
        })
    }

    /// Bound on |extinction − control| over the active lanes where the
    /// profiles (air, aerosol at the reference wavelength, ozone) lie within
    /// `deviations` of the densities the control was given, and ozone stays below
    /// `ozone_max_m3` (its cross-section's spread over temperature about the
    /// control's mid value), m⁻¹.
    pub(super) fn residual_bound(&self, deviations: [f64; 3], ozone_max_m3: f64) -> f64 {
        (0..self.active)
            .map(|j| {
                let (o_max, o_min) = (self.ozone_max_m2[j], self.ozone_min_m2[j]);
                self.rayleigh_m2[j] * deviations[0]
                    + self.aerosol_factor[j] * deviations[1]
                    + 0.5 * (o_max + o_min) * deviations[2]
                    + 0.5 * (o_max - o_min) * ozone_max_m3
            })
            .fold(0.0, f64::max)
    }

    /// Ozone cross-section of lane `j` at a typical stratospheric
    /// temperature (≈ 223 K), m²: for sampling densities, not for estimates.
    pub fn ozone_reference_m2(&self, j: usize) -> f64 {
        self.ozone_m2[j][3]
    }

    /// Aerosol extinction of lane `j` relative to the reference wavelength.
    pub fn aerosol_extinction_factor(&self, j: usize) -> f64 {
        self.aerosol_factor[j]
    }

    pub(super) fn shell(&self, walk: &ShellWalk, shell: usize) -> ShellExtinction {
        let slot = if walk.global { GLOBAL_SLOT } else { shell };
        ShellExtinction {
            majorant: self.majorants[slot],
            residual: self.residuals[slot],
        }
    }
}

/// Where a ray runs through the atmosphere.
#[derive(Clone, Copy, Debug)]
pub struct Span {
    /// Distance where the ray enters the atmosphere, m.
    pub t_enter: f64,
    /// Distance where it leaves it (or meets the ground), m.
    pub t_exit: f64,
    /// Whether it ends on the ground.
    pub hits_ground: bool,
}

/// Which bounds a tracker uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bounds {
    /// Per-shell maxima.
    Tight,
    /// One bound for the whole atmosphere.
    Global,
}

/// The profiles at altitude `z_m`, interpolated as [`Medium::coefficients`] does.
fn node_at(nodes: &[Node], z_m: f64) -> Node {
    let x = (z_m / NODE_STEP_M).max(0.0);
    let i = (x as usize).min(nodes.len() - 2);
    let f = (x - i as f64).min(1.0);
    let (a, b) = (&nodes[i], &nodes[i + 1]);
    let lerp = |g: fn(&Node) -> f64| g(a) + f * (g(b) - g(a));
    Node {
        air_m3: lerp(|n| n.air_m3),
        ozone_m3: lerp(|n| n.ozone_m3),
        aerosol_reference_per_m: lerp(|n| n.aerosol_reference_per_m),
        temperature_k: lerp(|n| n.temperature_k),
    }
}

impl Medium {
    /// The medium of `atmosphere`, its profiles cached on the node grid.
    pub fn new(atmosphere: &Atmosphere) -> Self {
        let p = &atmosphere.params;
        let ground = p
            .ground()
            .expect("a validated scene's ground albedo (Scene::validate reads it)");
        let top_m = p.top_altitude_m;
        let count = (top_m / NODE_STEP_M).ceil() as usize + 2;
        let nodes: Vec<Node> = (0..count)
            .map(|i| {
                let z = (i as f64 * NODE_STEP_M).min(top_m);
                Node {
                    air_m3: atmosphere.air_number_density_m3(z),
                    ozone_m3: atmosphere.ozone_number_density_m3(z),
                    aerosol_reference_per_m: atmosphere.aerosol_reference_extinction_per_m(z),
                    temperature_k: atmosphere.temperature_k(z),
                }
            })
            .collect();
        let boundaries = shell_boundaries_m(top_m);
        let bounds_between = |lo_m: f64, hi_m: f64| {
            // One node of margin on each side keeps the bound valid under the
            // rounding of shell-crossing distances.
            let first = ((lo_m / NODE_STEP_M).floor() as usize).saturating_sub(1);
            let last = ((hi_m / NODE_STEP_M).ceil() as usize + 1).min(nodes.len() - 1);
            let slice = &nodes[first..=last];
            let max = |f: fn(&Node) -> f64| slice.iter().map(f).fold(0.0, f64::max);
            let (lower, upper) = (node_at(&nodes, lo_m), node_at(&nodes, hi_m));
            let radius2 = |z: f64| (p.planet_radius_m + z).powi(2);
            let (lower2, upper2) = (radius2(lo_m), radius2(hi_m));
            let profiles: [fn(&Node) -> f64; 3] =
                [|n| n.air_m3, |n| n.aerosol_reference_per_m, |n| n.ozone_m3];
            let mut chord = Chord {
                lower: profiles.map(|f| f(&lower)),
                slope: profiles.map(|f| (f(&upper) - f(&lower)) / (upper2 - lower2)),
                base_radius2_m2: lower2,
                deviation: [0.0; 3],
            };
            // The profiles are linear in altitude between nodes and a chord
            // is quadratic, c = A + B·r²: their difference bends by 2B, so
            // between two nodes (or a node and a boundary, where it is 0) it
            // exceeds the larger of its node values by at most |B|·step²/4.
            // Rounding puts points outside the shell by far less than a
            // millimetre: 1e-4 of the profile's range over the neighbouring
            // nodes covers that.
            let inside =
                (lo_m / NODE_STEP_M).ceil() as usize..=(hi_m / NODE_STEP_M).floor() as usize;
            for (k, &f) in profiles.iter().enumerate() {
                let at_nodes = inside
                    .clone()
                    .filter(|&i| i < nodes.len())
                    .map(|i| {
                        let z = (i as f64 * NODE_STEP_M).min(top_m);
                        (f(&nodes[i]) - chord.at(radius2(z))[k]).abs()
                    })
                    .fold(0.0, f64::max);
                let range = max(f) - slice.iter().map(f).fold(f64::INFINITY, f64::min);
                chord.deviation[k] = at_nodes
                    + chord.slope[k].abs() * NODE_STEP_M * NODE_STEP_M / 4.0
                    + 1e-4 * range;
            }
            ShellBounds {
                air_max: max(|n| n.air_m3),
                ozone_max: max(|n| n.ozone_m3),
                aerosol_max: max(|n| n.aerosol_reference_per_m),
                chord,
            }
        };
        assert!(boundaries.len() <= MAX_SHELLS + 1, "too many shells");
        let shells: Vec<ShellBounds> = boundaries
            .windows(2)
            .map(|w| bounds_between(w[0], w[1]))
            .collect();
        let shell_terms = ShellTerms::new(&shells, &bounds_between(0.0, top_m));
        let profile_nodes = nodes
            .iter()
            .map(|n| [n.air_m3, n.aerosol_reference_per_m, n.ozone_m3])
            .collect();
        Self {
            planet_radius_m: p.planet_radius_m,
            top_radius_m: p.planet_radius_m + top_m,
            shell_terms,
            shell_radii_m: boundaries.iter().map(|b| b + p.planet_radius_m).collect(),
            shells,
            nodes,
            ground: ground.clone(),
            ground_albedo_max: ground.max(),
            aerosol_albedo: p.aerosol_albedo_spectrum(),
            aerosol_phase: p
                .aerosol_phase_function()
                .expect("a validated scene's phase function (Scene::validate builds it)"),
            aerosol_spectrum: p.aerosol_column().spectrum,
            ozone_on: p.ozone,
            gas: atmosphere.gas(),
            sun_columns: std::sync::OnceLock::new(),
            column_table: std::sync::OnceLock::new(),
            profile_nodes,
        }
    }

    /// Column amounts toward the sun over altitude × solar zenith.
    pub fn sun_columns(&self) -> &SunColumns {
        self.sun_columns.get_or_init(|| {
            SunColumns::new(self.planet_radius_m, self.top_radius_m, |origin, dir| {
                self.column_along(origin, dir)
            })
        })
    }

    /// Air, ozone and aerosol columns along a straight ray from `origin` to
    /// the top (3-point Gauss–Legendre on every shell piece; a sampling aid
    /// only, so percent-level accuracy is plenty).
    fn column_along(&self, origin: DVec3, dir: DVec3) -> [f32; 3] {
        // Gauss–Legendre nodes and weights on [−1, 1].
        const NODES: [(f64, f64); 3] = [
            (-0.774_596_669_241_483_4, 5.0 / 9.0),
            (0.0, 8.0 / 9.0),
            (0.774_596_669_241_483_4, 5.0 / 9.0),
        ];
        let mut sum = [0.0f64; 3];
        if let Some(span) = self.span(origin, dir) {
            for (t0, t1) in self.pieces(origin, dir, span) {
                let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
                for (x, w) in NODES {
                    let d = self.densities((origin + dir * (mid + half * x)).length());
                    for c in 0..3 {
                        sum[c] += w * half * d[c];
                    }
                }
            }
        }
        sum.map(|v| v as f32)
    }

    /// The column table that serves as the shadow rays' control.
    pub(super) fn column_table(&self) -> &ColumnTable {
        self.column_table.get_or_init(|| {
            let top_m = self.top_radius_m - self.planet_radius_m;
            ColumnTable::new(self.planet_radius_m, top_m, self.profile_nodes.clone())
        })
    }

    /// The aerosol's phase function at cosine `mu` for each lane's
    /// wavelength: evaluated once where it is the same at every
    /// wavelength.
    pub fn aerosol_phases(&self, mu: f64, lanes: &SpectralLanes) -> Lanes {
        if self.aerosol_phase.is_spectral() {
            Lanes::from_fn(|j| self.aerosol_phase.eval(mu, lanes.wavelengths_nm[j]))
        } else {
            Lanes::splat(self.aerosol_phase.eval(mu, lanes.wavelengths_nm[0]))
        }
    }

    /// Coefficients at distance `radius_m` from the planet's centre.
    #[inline]
    pub fn coefficients(&self, radius_m: f64, lanes: &SpectralLanes) -> Coefficients {
        let x = ((radius_m - self.planet_radius_m) / NODE_STEP_M).max(0.0);
        let i = (x as usize).min(self.nodes.len() - 2);
        let f = (x - i as f64).min(1.0);
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        let air = a.air_m3 + f * (b.air_m3 - a.air_m3);
        let o3 = a.ozone_m3 + f * (b.ozone_m3 - a.ozone_m3);
        let aer =
            a.aerosol_reference_per_m + f * (b.aerosol_reference_per_m - a.aerosol_reference_per_m);
        let mut c = Coefficients::default();
        let (k, w) =
            ozone::temperature_weight(a.temperature_k + f * (b.temperature_k - a.temperature_k));
        for j in 0..LANES {
            c.rayleigh[j] = lanes.rayleigh_m2[j] * air;
            let ext = aer * lanes.aerosol_factor[j];
            c.aerosol_scattering[j] = ext * lanes.aerosol_albedo[j];
            let o3_xs =
                lanes.ozone_m2[j][k] + w * (lanes.ozone_m2[j][k + 1] - lanes.ozone_m2[j][k]);
            c.absorption[j] = ext * (1.0 - lanes.aerosol_albedo[j]) + o3 * o3_xs;
        }
        c
    }

    /// Air and ozone number densities (m⁻³) and the aerosol extinction at
    /// the reference wavelength (m⁻¹, as the nodes hold it) at distance `radius_m`
    /// from the planet's centre.
    pub fn densities(&self, radius_m: f64) -> [f64; 3] {
        let x = ((radius_m - self.planet_radius_m) / NODE_STEP_M).max(0.0);
        let i = (x as usize).min(self.nodes.len() - 2);
        let f = (x - i as f64).min(1.0);
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        [
            a.air_m3 + f * (b.air_m3 - a.air_m3),
            a.ozone_m3 + f * (b.ozone_m3 - a.ozone_m3),
            a.aerosol_reference_per_m + f * (b.aerosol_reference_per_m - a.aerosol_reference_per_m),
        ]
    }

    /// The pieces `(t0, t1)` of `span` that each stay within one shell, in
    /// order along the ray.
    pub fn pieces(
        &self,
        origin: DVec3,
        dir: DVec3,
        span: Span,
    ) -> impl Iterator<Item = (f64, f64)> + '_ {
        let mut walk = self.walk(origin, dir, span, Bounds::Tight);
        std::iter::from_fn(move || walk.next_piece(self).map(|p| (p.t0, p.t1)))
    }

    /// The part of the ray `origin + t·dir` (unit `dir`) inside the
    /// atmosphere, or `None` if it misses it.
    pub fn span(&self, origin: DVec3, dir: DVec3) -> Option<Span> {
        let b = origin.dot(dir);
        let r2 = origin.length_squared();
        let perigee2 = (r2 - b * b).max(0.0);
        let top2 = self.top_radius_m * self.top_radius_m;
        if perigee2 >= top2 {
            return None;
        }
        let half_chord_top = (top2 - perigee2).sqrt();
        let t_enter = if r2 > top2 {
            if b >= 0.0 {
                return None;
            }
            -b - half_chord_top
        } else {
            0.0
        };
        let ground2 = self.planet_radius_m * self.planet_radius_m;
        if b < 0.0 && perigee2 < ground2 {
            let t_ground = (-b - (ground2 - perigee2).sqrt()).max(t_enter);
            return Some(Span {
                t_enter,
                t_exit: t_ground,
                hits_ground: true,
            });
        }
        // From the top itself, looking up or across, the ray leaves at once:
        // t_exit = −b + |b| = 0 up to rounding, which may fall below t_enter.
        let t_exit = -b + half_chord_top;
        if t_exit <= t_enter {
            return None;
        }
        Some(Span {
            t_enter,
            t_exit,
            hits_ground: false,
        })
    }

    pub(super) fn shell_index(&self, radius_m: f64) -> usize {
        self.shell_radii_m
            .partition_point(|&r| r <= radius_m)
            .saturating_sub(1)
            .min(self.shells.len() - 1)
    }

    /// Pieces of `span` that each lie in one shell.
    pub(super) fn walk(&self, origin: DVec3, dir: DVec3, span: Span, bounds: Bounds) -> ShellWalk {
        let b = origin.dot(dir);
        let perigee2 = (origin.length_squared() - b * b).max(0.0);
        let t = span.t_enter;
        let radius = (origin + dir * t).length();
        ShellWalk {
            perigee_t: -b,
            perigee2,
            t,
            t_end: span.t_exit,
            shell: if bounds == Bounds::Global {
                0
            } else {
                self.shell_index(radius)
            },
            descending: t < -b,
            global: bounds == Bounds::Global,
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub(super) struct Piece {
    pub(super) t0: f64,
    pub(super) t1: f64,
    pub(super) shell: usize,
}

/// Iterates over the pieces of a ray that stay within one shell.
#[derive(Clone, Debug)]
pub(super) struct ShellWalk {
    pub(super) perigee_t: f64,
    pub(super) perigee2: f64,
    pub(super) t: f64,
    pub(super) t_end: f64,
    pub(super) shell: usize,
    pub(super) descending: bool,
    pub(super) global: bool,
}

impl ShellWalk {
    // Not inlined, the returned `Option<Piece>` went through memory and
    // stalled every caller: inlining made tracker walks 1.7–2.6× faster
    // (`cargo bench --bench hot -- tracker_walk`); `#[inline]` alone did not.
    #[allow(clippy::inline_always)]
    #[inline(always)]
    pub(super) fn next_piece(&mut self, medium: &Medium) -> Option<Piece> {
        if self.t >= self.t_end {
            return None;
        }
        let t0 = self.t;
        if self.global {
            self.t = self.t_end;
            return Some(Piece {
                t0,
                t1: self.t_end,
                shell: 0,
            });
        }
        let shell = self.shell;
        let crossing = |r: f64| (r * r - self.perigee2).max(0.0).sqrt();
        let t1 = if self.descending {
            let r_lo = medium.shell_radii_m[shell];
            if shell > 0 && r_lo * r_lo > self.perigee2 {
                self.shell -= 1;
                self.perigee_t - crossing(r_lo)
            } else if shell == 0 && r_lo * r_lo > self.perigee2 {
                // The ground: the span ends there.
                self.t_end
            } else {
                // Perigee inside this shell: the piece runs to where the ray
                // leaves the shell upwards.
                self.descending = false;
                let t = self.perigee_t + crossing(medium.shell_radii_m[shell + 1]);
                self.shell += 1;
                t
            }
        } else {
            self.shell += 1;
            self.perigee_t + crossing(medium.shell_radii_m[shell + 1])
        };
        let t1 = t1.clamp(t0, self.t_end);
        self.t = t1;
        if self.shell >= medium.shells.len() {
            self.t = self.t_end;
            self.shell = medium.shells.len() - 1;
        }
        Some(Piece { t0, t1, shell })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::AtmosphereParams;
    use crate::rng::Rng;

    fn medium() -> Medium {
        Medium::new(&Atmosphere::new(AtmosphereParams::default()))
    }

    #[test]
    fn cached_profiles_match_the_exact_physics() {
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let lanes =
            SpectralLanes::new(Lanes::from([450.0, 550.0, 650.0, 750.0]), 4, &medium, false);
        for z in [0.0, 123.0, 1_777.0, 9_999.0, 22_345.0, 48_000.0, 77_000.0] {
            let c = medium.coefficients(medium.planet_radius_m + z, &lanes);
            for (j, &w) in lanes.wavelengths_nm.iter().enumerate() {
                let r = atmosphere.rayleigh_scattering_per_m(z, w);
                assert!((c.rayleigh[j] / r - 1.0).abs() < 1e-4, "z={z} {w}");
                let a = atmosphere.aerosol_extinction_per_m(z, w);
                let got = c.aerosol_scattering[j] / atmosphere.params.aerosol_albedo;
                assert!((got - a).abs() <= 1e-3 * a + 1e-12, "z={z}");
                let o = atmosphere.ozone_absorption_per_m(z, w)
                    + a * (1.0 - atmosphere.params.aerosol_albedo);
                assert!(
                    (c.absorption[j] - o).abs() <= 2e-3 * o + 1e-12,
                    "z={z}: {} {o}",
                    c.absorption[j]
                );
            }
        }
    }

    #[test]
    fn shell_majorants_bound_the_medium_along_rays() {
        let medium = medium();
        let lanes =
            SpectralLanes::new(Lanes::from([400.0, 500.0, 600.0, 700.0]), 4, &medium, false);
        let mut rng = Rng::new(1, 1);
        let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + 1_500.0);
        for i in 0..200 {
            let el = -10.0 + 100.0 * f64::from(i) / 200.0;
            let dir = DVec3::new(el.to_radians().cos(), 0.0, el.to_radians().sin());
            let span = medium.span(origin, dir).unwrap();
            let mut tracker = medium.tracker(origin, dir, span, &lanes, Bounds::Tight);
            let mut last = span.t_enter;
            while let Some(c) = tracker.next(&mut rng) {
                assert!(c.t >= last && c.t <= span.t_exit);
                last = c.t;
                let k = medium.coefficients((origin + dir * c.t).length(), &lanes);
                for j in 0..LANES {
                    assert!(
                        k.extinction(j) <= c.majorant * (1.0 + 1e-9),
                        "el={el} t={}",
                        c.t
                    );
                }
            }
        }
    }

    #[test]
    fn span_of_upward_downward_and_space_rays() {
        let medium = medium();
        let ground = DVec3::new(0.0, 0.0, medium.planet_radius_m + 1.0);
        let up = medium.span(ground, DVec3::Z).unwrap();
        assert!(!up.hits_ground && (up.t_exit - 99_999.0).abs() < 1e-3);
        let down = medium.span(ground, -DVec3::Z).unwrap();
        assert!(down.hits_ground && (down.t_exit - 1.0).abs() < 1e-6);
        let space = DVec3::new(0.0, 0.0, medium.planet_radius_m + 400_000.0);
        let s = medium.span(space, -DVec3::Z).unwrap();
        assert!(s.hits_ground && (s.t_enter - 300_000.0).abs() < 1e-3);
        assert!(medium.span(space, DVec3::X).is_none());
        // From the top itself: up and across the ray leaves at once (no
        // span, not one of negative length from rounding); down it enters.
        let top = DVec3::new(0.0, 0.0, medium.top_radius_m);
        for el_deg in [90.0_f64, 30.0, 1.0, 0.01, 0.0] {
            let el = el_deg.to_radians();
            let dir = DVec3::new(el.cos(), 0.0, el.sin());
            assert!(medium.span(top, dir).is_none(), "elevation {el_deg}°");
        }
        let el = (-1.0_f64).to_radians();
        let down = medium
            .span(top, DVec3::new(el.cos(), 0.0, el.sin()))
            .unwrap();
        assert!(down.t_exit > down.t_enter);
    }
}
