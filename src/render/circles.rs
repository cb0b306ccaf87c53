//! Multiply scattered light splatted along the scene's circles of symmetry.
//!
//! The scene — a spherically symmetric atmosphere over a uniform ground, lit
//! by a sun at infinity — is unchanged by any rotation about the axis
//! through the Earth's centre along the sun's direction. So is its light
//! field: the radiance arriving at a point y from direction d equals that
//! arriving at R y from R d for every such rotation R. In spherical
//! coordinates about that axis — radius r, angle θ from the sun's
//! direction, angle ψ about the axis, dV = r² sin θ dr dθ dψ — the light
//! field depends on (r, θ) and the direction in y's frame, not on ψ.
//!
//! A pixel's multiply scattered light is an integral over the visible air:
//! the light that arrives at y, has scattered at least once and scatters
//! at y toward the observer O,
//!
//! V = ∫ J(ω) T(O, y) / t² ∫ σ_s P(ω·d) L(y, d) dd dV,
//!
//! ω = (y − O)/t the camera direction, J = [`Camera::pixels_per_sr`] (only
//! where ω falls in the pixel). The camera's own paths estimate it by a
//! point on each camera ray and a path from there: every such path serves
//! one pixel (two with mirror pairs). Here one path serves many: a point y₀
//! is drawn in (r, θ), K positions ψ_k along its circle, a direction d₀
//! at y₀ and a path estimating L(y₀, d₀) — which is also an unbiased
//! estimate of L(R_k y₀, R_k d₀) — and each y_k = R_k y₀ adds its
//! J T σ_s P / t² term to the pixel its camera direction falls in (two
//! directions, each with its path, averaged: the positions' cost, their
//! transmittances above all, is shared). Each
//! term carries the densities it was drawn with, so every pixel's expected
//! sum is V exactly; the paths' noise, which at twilight is most of the
//! image's, is spread over K pixels (`BENCHMARKS.md`).
//!
//! * **Points** (r, θ) are drawn in polar coordinates (ρ, φ) about the
//!   observer's own (r₀, θ₀) in the plane (r − r₀, r₀ (θ − θ₀)): a circle
//!   passing at distance ≈ ρ from the observer brings ∫ dψ / t² ∝ 1/ρ,
//!   which the polar area element ρ dρ dφ cancels. A table over (log ρ, φ)
//!   of that integral (with the transmittance to the observer, the air's
//!   scattering and the guide's mean once-scattered light at the point,
//!   [`SkyGuide::skylight`]) holds most of the density; an analytic
//!   density in ρ, positive wherever a circle can be seen, the rest, a
//!   tenth of it in the thin wedge between the ground and the observer's
//!   height, which the table's bins miss ([`super::circle_points`]).
//!   From the second splatting pass on, most points come from a density
//!   learned from the earlier passes' splats ([`LearnedPoints`]): the
//!   prior's times a factor per cell of the table, where the splats' own
//!   variance says points are missing.
//! * **Positions** ψ on the visible arc, in two rounds. Before the
//!   directions: a few from a Cauchy density about the point nearest the
//!   observer (t² ≈ d² + c ψ² there) and a few uniform. After them, most:
//!   from the Cauchy density times the phase functions toward the observer
//!   at each position given the d₀ and the camera's pixels per steradian
//!   there (`PhaseCells`), so that an aerosol's forward peak is drawn where
//!   it points at the observer and each pixel gets its share of positions
//!   whatever its solid angle. All combined by the balance heuristic
//!   (multi-sample MIS), all stratified. A position's light toward the
//!   observer, T × the in-scattered light, is a control interpolated
//!   between the cells' centres (T̃ the table's there); one position in
//!   six, at a random offset, adds its own unbiased light less the
//!   control's, times six, so each position's expectation is its own
//!   light, and the rest skip their look-ups (beyond the end centres
//!   each position takes its own). T's own correction (the table's T̃
//!   against the tracked estimate) stays on its share of all positions
//!   at its own weight: times six as well, it made single splats
//!   strongly negative on the rays that graze the ground.
//! * **Direction** d₀: the scene's usual mixture (the guide's table, the
//!   sun lobe), with the phase function about each of the camera's
//!   directions at the phase cells' 32 centres in equal shares
//!   (`Integrator::splat_walk`). Those centres fall along the arc as the
//!   positions do, so wherever d₀ meets a position's forward peak its
//!   density has a lobe near it; with the first round's eight directions
//!   as anchors, a d₀ aligned with a position between them carried a
//!   phase function many times its density, and such walks were among
//!   the heaviest splats (`BENCHMARKS.md`, the direction anchors' row).

use std::f64::consts::PI;

use glam::DVec3;
use rayon::prelude::*;

use super::camera::Camera;
use super::guide::SkyGuide;
use super::integrator::Integrator;
use super::medium::{Lanes, Medium, SpectralLanes, LANES};
use super::observer_depths::ObserverRays;
use crate::rng::Rng;

pub use super::circle_geometry::SPLATS_PER_WALK;
use super::circle_geometry::{air_splats_per_walk, AtCentres, PixelWeight, MAX_SPLATS_PER_WALK};
use super::circle_geometry::{cauchy_scale, Arc, PhaseCells, SunAxis, FIRST_SPLATS, PHASE_CELLS};
use super::circle_points::{analytic_rho_cdf, analytic_rho_density, sample_analytic_rho, Wedge};

/// Directions (each with its path) per point, shared by its positions:
/// most of a low sun's walk's variance is its paths', and a walk's
/// positions cost several of its paths, so a third direction pays for
/// itself where a fourth no longer does (`BENCHMARKS.md`, the decisions
/// table's row on the air splat walks' directions).
const DIRECTIONS_PER_WALK: usize = 3;
/// One position in this many evaluates its own transmittance and phase
/// functions; the others take the light the cells' centres give
/// ([`AtCentres`]), and the one corrects them all. Fewer exact positions
/// cost less, and their correction, times this, adds more variance; one
/// in six and one in 12 measured alike (`BENCHMARKS.md`, the row on the
/// positions' control).
const EXACT_EVERY: usize = 6;
/// Share of the points drawn from the table (the rest: analytic in ρ).
const TABLE_SHARE: f64 = 0.8;
/// Share of the analytic part drawn in the wedge between the ground and
/// the observer's height ([`Wedge`]), which the table misses; 0.03 and 0.1
/// measured alike on the horizon's row (`BENCHMARKS.md`, the wedge's
/// decisions row).
const WEDGE_SHARE: f64 = 0.1;
/// Share of the points drawn from the density learned from the pass's
/// predecessors' splats ([`LearnedPoints`]), once there are any; the rest
/// from the prior (table and analytic parts), which keeps the density
/// positive wherever the prior is (chosen by cross-validating the splats
/// of one twilight render against another's, `BENCHMARKS.md`).
const LEARNED_SHARE: f64 = 0.75;
/// Table bins per learned cell along each axis: the learned density is the
/// prior's times one factor per cell of 4 × 4 bins (16 × 16 cells; 8 × 8
/// and 32 × 32 cells did no better offline).
const CELL_BINS: usize = 4;
const CELLS_PHI: usize = TABLE_PHI_BINS / CELL_BINS;
const CELLS: usize = (TABLE_RHO_BINS / CELL_BINS) * CELLS_PHI;
/// The table's bins: ρ log-spaced from [`TABLE_RHO_MIN_M`] (one bin below
/// it), φ uniform; positions along the arc per bin for its integral.
const TABLE_RHO_BINS: usize = 64;
const TABLE_PHI_BINS: usize = 64;
const TABLE_NODES: usize = 32;
const TABLE_RHO_MIN_M: f64 = 10.0;
/// Seed of the table's transmittance estimates.
const TABLE_SEED: u64 = 0x00c1_4c1e;
/// The table's wavelength, nm.
const TABLE_WAVELENGTH_NM: f64 = 550.0;
/// Cosine of the elevation below which the table stops following 1/cos el
/// (the equirect map's pixels per steradian near its poles, whose rows are
/// tiny; their splats follow it: only the table's importance is capped; the
/// rows that reach the poles take no splats, see
/// [`Camera::pixel_density_bounded`]); the positions' factor for the
/// pixels ([`PixelWeight`]) is capped at its reciprocal alike.
const TABLE_MIN_COS: f64 = 0.05;

pub use super::film_spectral::Splat;

/// Whether the scene has circles to splat along: not with the sun at the
/// observer's zenith or nadir (see `SunAxis::new`).
pub fn has_circles(observer_m: DVec3, sun_direction: DVec3) -> bool {
    SunAxis::new(observer_m, sun_direction, 0.0, 0.0).is_some()
}

/// Splats the multiply scattered light of one scene for one camera.
pub struct CircleSplatter {
    axis: SunAxis,
    rho_max_m: f64,
    /// The wedge below the observer's height; `None` on the ground.
    wedge: Option<Wedge>,
    /// Bin edges in ρ (m).
    rho_edges: Vec<f64>,
    /// Probability of each (ρ, φ) bin, row-major in ρ; empty if nothing in
    /// view had weight (then the analytic density alone).
    bins: Vec<f64>,
    cdf: Vec<f64>,
    /// The prior's (table and analytic parts') probability of each bin,
    /// and of each learned cell.
    prior_bins: Vec<f64>,
    prior_cells: Vec<f64>,
    /// The look-ups of the rays from the observer, where every splat's
    /// ray to the camera starts.
    observer: ObserverRays,
    /// Positions per point ([`splats_per_walk`]).
    splats: usize,
    /// The phase cells' factor for the camera's pixels.
    pixels: PixelWeight,
    /// One position in this many evaluates its own light
    /// ([`EXACT_EVERY`]); the control's light is scaled by
    /// `control_scale` (1; a test's way to make it wrong).
    exact_every: usize,
    control_scale: f64,
}

/// The points' density learned from the splats of a render's passes so
/// far (one per film): the prior's ([`CircleSplatter`]'s table and
/// analytic parts) times one factor per cell of (ρ, φ) bins, chosen to
/// minimise the splats' variance summed over the image.
///
/// A walk from point x adds s(x) = Σ_k Y_k² (its splats' luminances) to
/// that sum (over N² for N walks); s scales as 1/p(x)² with the density
/// p that drew x. Drawn from the prior p₀ times c_b on cell b (Σ_b c_b P_b
/// = 1, P_b the prior's mass there), the sum is Σ_b S_b / c_b, S_b the
/// cell's share of it under p₀ — least for c_b ∝ √(S_b / P_b). S_b is
/// estimated from the walks drawn so far, whatever density q drew them:
/// each adds s q/p₀ (q/p₀ squared brings s to p₀'s scale, p₀/q weighs the
/// walk back). At twilight the prior's guess — the light that scatters
/// once on the way, from the guide — missed both the brightness of the
/// paths found low in the shadow and the weight of the splats near the
/// zenith and on the horizon (`BENCHMARKS.md`).
///
/// A pass draws 3/4 of its points (`LEARNED_SHARE`) from the learned density
/// and the rest from the prior, so the density is positive wherever the
/// prior's is, and fixed before the pass starts: every pass stays
/// unbiased.
#[derive(Clone, Debug, Default)]
pub struct LearnedPoints {
    /// Σ s q/p₀ per cell over the walks so far.
    moments: Vec<f64>,
    /// The learned density's probability of each table bin, and their
    /// running sum; empty until a walk has found light.
    bins: Vec<f64>,
    cdf: Vec<f64>,
}

impl LearnedPoints {
    /// Whether points are drawn from a learned density yet.
    pub fn is_learned(&self) -> bool {
        !self.cdf.is_empty()
    }

    /// Adds walks' terms of their cells' moments (in walk order: the sums,
    /// and so the image, do not depend on the thread count); the density
    /// changes only with [`CircleSplatter::learn`].
    pub fn add_moments(&mut self, moments: impl IntoIterator<Item = (usize, f64)>) {
        if self.moments.is_empty() {
            self.moments = vec![0.0; CELLS];
        }
        for (cell, m) in moments {
            self.moments[cell] += m;
        }
    }
}

/// [`CircleSplatter::polar_densities`] at one point.
struct PolarDensities {
    drawn: f64,
    prior: f64,
    bin: Option<usize>,
}

/// What one walk did: its splats discarded as not finite, and its term of
/// its cell's moment ([`LearnedPoints`]; `None` where it splatted nothing).
#[derive(Clone, Copy, Debug)]
pub struct Walked {
    /// Splats discarded as not finite.
    pub discarded: u64,
    /// The walk's term of its cell's moment.
    pub moment: Option<(usize, f64)>,
}

impl CircleSplatter {
    /// The splatter for `camera` at `observer_m`, its point table built
    /// with `integrator`'s transmittance estimates and `guide`'s light;
    /// `None` where the scene has no circles to splat along (the sun at the
    /// zenith or nadir).
    pub fn new(
        medium: &Medium,
        integrator: &Integrator<'_>,
        guide: Option<&SkyGuide>,
        camera: &Camera,
        observer_m: DVec3,
    ) -> Option<Self> {
        let axis = SunAxis::new(
            observer_m,
            integrator.sun_direction,
            medium.planet_radius_m,
            medium.top_radius_m,
        )?;
        let rho_max = axis.rho_max();
        let rho_edges: Vec<f64> = std::iter::once(0.0)
            .chain((0..TABLE_RHO_BINS).map(|i| {
                TABLE_RHO_MIN_M
                    * (rho_max / TABLE_RHO_MIN_M).powf(i as f64 / (TABLE_RHO_BINS - 1) as f64)
            }))
            .collect();
        let lanes = SpectralLanes::new(Lanes::from([TABLE_WAVELENGTH_NM; LANES]), 1, medium, true);
        let observer = ObserverRays::new(medium, observer_m);
        let up = observer_m.normalize();
        let mass: Vec<f64> = (0..TABLE_RHO_BINS * TABLE_PHI_BINS)
            .into_par_iter()
            .map(|bin| {
                let (i, j) = (bin / TABLE_PHI_BINS, bin % TABLE_PHI_BINS);
                let rho = 0.5 * (rho_edges[i] + rho_edges[i + 1]);
                let phi = (j as f64 + 0.5) / TABLE_PHI_BINS as f64 * 2.0 * PI;
                let (r, theta) = axis.at_polar(rho, phi);
                if !(axis.ground_m..=axis.top_m).contains(&r) || !(0.0..=PI).contains(&theta) {
                    return 0.0;
                }
                let half = axis.half_arc(r, theta);
                if half <= 0.0 {
                    return 0.0;
                }
                let mut rng = Rng::new(TABLE_SEED, bin as u64);
                let y0 = axis.point(r, theta, 0.0);
                let c = medium.coefficients(r, &lanes);
                let light = guide.map_or(1.0, |g| g.skylight(medium, y0)) * c.scattering(0);
                let arc = Arc::new(half, cauchy_scale(&axis, r, theta));
                let circle = axis.circle(r, theta);
                // ∫ dψ T / (t² cos el) by the Cauchy draws at stratum centres.
                let mut integral = 0.0;
                for k in 0..TABLE_NODES {
                    let psi = arc.cauchy((k as f64 + 0.5) / TABLE_NODES as f64);
                    let density = arc.cauchy_density(psi);
                    let to = circle.point(psi.sin_cos()) - observer_m;
                    let t = to.length();
                    let dir = to / t;
                    if camera.pixels_per_sr(dir) <= 0.0 {
                        continue;
                    }
                    let Some(tr) =
                        integrator.transmittance_from(observer.start(), dir, t, &lanes, &mut rng)
                    else {
                        continue;
                    };
                    let cos_el = (1.0 - dir.dot(up).powi(2)).max(0.0).sqrt();
                    integral += tr[0]
                        / (t * t * cos_el.max(TABLE_MIN_COS))
                        / (TABLE_NODES as f64 * density);
                }
                // Density per r₀ dr dθ, times the bin's area ρ Δρ Δφ.
                r * r
                    * circle.sin_theta
                    * light
                    * integral
                    * rho
                    * (rho_edges[i + 1] - rho_edges[i])
                    * (2.0 * PI / TABLE_PHI_BINS as f64)
                    / axis.r0_m
            })
            .collect();
        let total: f64 = mass.iter().sum();
        let (bins, cdf) = if total > 0.0 && total.is_finite() {
            let bins: Vec<f64> = mass.iter().map(|m| m / total).collect();
            let mut sum = 0.0;
            let cdf = bins
                .iter()
                .map(|p| {
                    sum += p;
                    sum
                })
                .collect();
            (bins, cdf)
        } else {
            (Vec::new(), Vec::new())
        };
        // The analytic part's mass per bin: its mass in the ρ interval,
        // spread evenly in φ, and the wedge's.
        let wedge = Wedge::new(axis.r0_m - axis.ground_m, rho_max);
        let prior_bins = (0..TABLE_RHO_BINS * TABLE_PHI_BINS)
            .map(|bin| {
                let i = bin / TABLE_PHI_BINS;
                let j = bin % TABLE_PHI_BINS;
                let even = (analytic_rho_cdf(rho_edges[i + 1], rho_max)
                    - analytic_rho_cdf(rho_edges[i], rho_max))
                    / TABLE_PHI_BINS as f64;
                let analytic = wedge.map_or(even, |wedge| {
                    let phi = |j: usize| j as f64 / TABLE_PHI_BINS as f64 * 2.0 * PI;
                    let mass = wedge.mass((rho_edges[i], rho_edges[i + 1]), (phi(j), phi(j + 1)));
                    (1.0 - WEDGE_SHARE) * even + WEDGE_SHARE * mass
                });
                if bins.is_empty() {
                    analytic
                } else {
                    TABLE_SHARE * bins[bin] + (1.0 - TABLE_SHARE) * analytic
                }
            })
            .collect::<Vec<f64>>();
        let mut prior_cells = vec![0.0; CELLS];
        for (bin, p) in prior_bins.iter().enumerate() {
            prior_cells[Self::cell(bin)] += p;
        }
        Some(Self {
            axis,
            rho_max_m: rho_max,
            wedge,
            rho_edges,
            bins,
            cdf,
            prior_bins,
            prior_cells,
            observer,
            splats: air_splats_per_walk(camera),
            pixels: PixelWeight::new(camera, 1.0 / TABLE_MIN_COS),
            exact_every: EXACT_EVERY,
            control_scale: 1.0,
        })
    }

    /// The same splatter with one position in `every` exact and the
    /// control's light times `scale`.
    #[cfg(test)]
    fn with_control(mut self, every: usize, scale: f64) -> Self {
        self.exact_every = every.max(1);
        self.control_scale = scale;
        self
    }

    /// The table bin holding (ρ, φ), if any (ρ beyond the farthest circle
    /// has none).
    fn bin(&self, rho: f64, phi: f64) -> Option<usize> {
        let i = self.rho_edges.partition_point(|&e| e <= rho);
        (1..self.rho_edges.len()).contains(&i).then(|| {
            let j = ((phi / (2.0 * PI) * TABLE_PHI_BINS as f64) as usize).min(TABLE_PHI_BINS - 1);
            (i - 1) * TABLE_PHI_BINS + j
        })
    }

    /// The area of table bin `bin` in (ρ, φ).
    fn bin_area(&self, bin: usize) -> f64 {
        let i = bin / TABLE_PHI_BINS;
        (self.rho_edges[i + 1] - self.rho_edges[i]) * 2.0 * PI / TABLE_PHI_BINS as f64
    }

    /// A point uniform in table bin `bin`, by `v` (ρ) and `w` (φ).
    fn in_bin(&self, bin: usize, v: f64, w: f64) -> (f64, f64) {
        let (i, j) = (bin / TABLE_PHI_BINS, bin % TABLE_PHI_BINS);
        let rho = self.rho_edges[i] + v * (self.rho_edges[i + 1] - self.rho_edges[i]);
        (rho, (j as f64 + w) / TABLE_PHI_BINS as f64 * 2.0 * PI)
    }

    /// The learned cell of table bin `bin`.
    fn cell(bin: usize) -> usize {
        let (i, j) = (bin / TABLE_PHI_BINS, bin % TABLE_PHI_BINS);
        (i / CELL_BINS) * CELLS_PHI + j / CELL_BINS
    }

    /// Draws `learned`'s density anew from its moments (between passes).
    pub fn learn(&self, learned: &mut LearnedPoints) {
        if learned.moments.is_empty() {
            return;
        }
        let prior = &self.prior_cells;
        // Each cell's mass ∝ √(S_b P_b).
        let mass: Vec<f64> = learned
            .moments
            .iter()
            .zip(prior)
            .map(|(s, p)| (s * p).sqrt())
            .collect();
        let total: f64 = mass.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return;
        }
        learned.bins = self
            .prior_bins
            .iter()
            .enumerate()
            .map(|(bin, p)| {
                let cell = Self::cell(bin);
                if prior[cell] > 0.0 {
                    mass[cell] / total * p / prior[cell]
                } else {
                    0.0
                }
            })
            .collect();
        let mut sum = 0.0;
        learned.cdf = learned
            .bins
            .iter()
            .map(|p| {
                sum += p;
                sum
            })
            .collect();
    }

    /// Densities of (ρ, φ) per dρ dφ: the one points are drawn from (the
    /// prior's, or with `learned`'s part) and the prior's (table and
    /// analytic parts), with the table bin holding (ρ, φ).
    fn polar_densities(&self, learned: &LearnedPoints, rho: f64, phi: f64) -> PolarDensities {
        let bin = self.bin(rho, phi);
        let per_area = |bins: &[f64]| bin.map_or(0.0, |bin| bins[bin] / self.bin_area(bin));
        let even = analytic_rho_density(rho, self.rho_max_m) / (2.0 * PI);
        let analytic = self.wedge.map_or(even, |wedge| {
            (1.0 - WEDGE_SHARE) * even + WEDGE_SHARE * wedge.density(rho, phi)
        });
        let prior = if self.bins.is_empty() {
            analytic
        } else {
            TABLE_SHARE * per_area(&self.bins) + (1.0 - TABLE_SHARE) * analytic
        };
        let drawn = if learned.is_learned() {
            LEARNED_SHARE * per_area(&learned.bins) + (1.0 - LEARNED_SHARE) * prior
        } else {
            prior
        };
        PolarDensities { drawn, prior, bin }
    }

    fn sample_polar(&self, learned: &LearnedPoints, rng: &mut Rng) -> (f64, f64) {
        let draw = |cdf: &[f64], u: f64| cdf.partition_point(|&c| c <= u).min(cdf.len() - 1);
        let (u, v, w) = (rng.uniform(), rng.uniform(), rng.uniform());
        // The component's uniform.
        let mut x = rng.uniform();
        if learned.is_learned() {
            if x < LEARNED_SHARE {
                return self.in_bin(draw(&learned.cdf, u), v, w);
            }
            x = (x - LEARNED_SHARE) / (1.0 - LEARNED_SHARE);
        }
        if !self.bins.is_empty() {
            if x < TABLE_SHARE {
                return self.in_bin(draw(&self.cdf, u), v, w);
            }
            x = (x - TABLE_SHARE) / (1.0 - TABLE_SHARE);
        }
        match self.wedge {
            Some(wedge) if x < WEDGE_SHARE => wedge.sample(u, v, w),
            _ => (sample_analytic_rho(u, v, self.rho_max_m), w * 2.0 * PI),
        }
    }

    /// Positions per point: splats a walk makes at most.
    pub fn splats_per_walk(&self) -> usize {
        self.splats
    }

    /// One path and its splats (at most [`Self::splats_per_walk`]) into `out`;
    /// each splat's XYZ is the path's estimate for its pixel (the film
    /// divides by the number of paths). `wavelength_weights[j]` turns lane
    /// j's radiance into XYZ (K_m x̄ȳz̄(λ) / (its density × the lanes)).
    /// The point is drawn with `learned`'s density; returns the splats
    /// discarded and the walk's term of its cell's moment ([`Walked`]).
    #[allow(clippy::too_many_arguments)]
    pub fn walk(
        &self,
        integrator: &Integrator<'_>,
        camera: &Camera,
        lanes: &SpectralLanes,
        wavelength_weights: &[[f64; 3]; LANES],
        learned: &LearnedPoints,
        rng: &mut Rng,
        out: &mut Vec<Splat>,
    ) -> Walked {
        let nothing = Walked {
            discarded: 0,
            moment: None,
        };
        let axis = &self.axis;
        let (rho, phi) = self.sample_polar(learned, rng);
        let (r, theta) = axis.at_polar(rho, phi);
        if rho <= 0.0 || !(axis.ground_m..=axis.top_m).contains(&r) || !(0.0..=PI).contains(&theta)
        {
            return nothing;
        }
        let half = axis.half_arc(r, theta);
        if half <= 0.0 {
            return nothing;
        }
        let densities = self.polar_densities(learned, rho, phi);
        // Density per dr dθ: per dρ dφ × r₀ / ρ.
        let point_density = densities.drawn * axis.r0_m / rho;
        let arc = Arc::new(half, cauchy_scale(axis, r, theta));
        let y0 = axis.point(r, theta, 0.0);
        // A position's offset from the observer, and its camera direction
        // turned back into y₀'s frame.
        let circle = axis.circle(r, theta);
        let place = |psi: f64| circle.place(psi);
        let mut positions = [(0.0, DVec3::ZERO, DVec3::ZERO); MAX_SPLATS_PER_WALK];
        let positions = &mut positions[..self.splats];
        let phase_splats = self.splats - FIRST_SPLATS;
        for (slot, psi) in positions.iter_mut().zip(arc.first_positions(rng.uniform())) {
            let (to, camera_dir) = place(psi);
            *slot = (psi, to, camera_dir);
        }
        // The phase cells' centres, evenly spaced in the Cauchy quantile (so
        // about as the positions fall): their camera directions are the
        // directions' anchors, then, with their views, the cells' weights.
        let placed: [(DVec3, DVec3); PHASE_CELLS] =
            std::array::from_fn(|m| place(arc.cauchy(PhaseCells::centre(m))));
        let centres = placed.map(|(_, camera_dir)| camera_dir);
        let c = integrator.medium.coefficients(r, lanes);
        // Each direction's path estimate over its density, averaged over
        // all DIRECTIONS_PER_WALK draws (those that found nothing count).
        let mut directions = [(DVec3::ZERO, Lanes::splat(0.0)); DIRECTIONS_PER_WALK];
        let mut found = 0;
        for k in 0..DIRECTIONS_PER_WALK {
            // Each draw picks the mixture's part from its own equal share
            // of the unit interval (stratified: `Integrator::splat_walk`).
            let select = (k as f64 + rng.uniform()) / DIRECTIONS_PER_WALK as f64;
            let Some((d, pdf, radiance)) =
                integrator.splat_walk(y0, &centres, &c, lanes, select, rng)
            else {
                continue;
            };
            if pdf > 0.0 && radiance[..lanes.active].iter().any(|&l| l != 0.0) {
                let scale = 1.0 / (pdf * DIRECTIONS_PER_WALK as f64);
                directions[found] = (d, radiance.map(|l| l * scale));
                found += 1;
            }
        }
        let directions = &directions[..found];
        if directions.is_empty() {
            return nothing;
        }
        let cells = PhaseCells::new(std::array::from_fn(|m| {
            self.pixels.at(camera, placed[m].0)
                * directions
                    .iter()
                    .map(|(d, _)| integrator.phase_mixture_pdf(&c, lanes, centres[m].dot(*d)))
                    .sum::<f64>()
        }));
        for (slot, psi) in positions[FIRST_SPLATS..].iter_mut().zip(cells.positions(
            &arc,
            rng.uniform(),
            phase_splats,
        )) {
            let (to, camera_dir) = place(psi);
            *slot = (psi, to, camera_dir);
        }
        let (width, _) = camera.size();
        let scattering = integrator.scattering_phases_at(&c, lanes);
        let in_scattered = |cam_dir: DVec3| {
            let mut sum = Lanes::splat(0.0);
            for (d, radiance) in directions {
                sum += scattering.at(cam_dir.dot(*d)) * *radiance;
            }
            sum
        };
        // The light each position sends the observer, T × the in-scattered
        // light, as a control: T̃ (the table's) × it at the cells' centres,
        // interpolated between them; one position in `every` (which, by a
        // random offset) adds its own unbiased light less the control's,
        // times `every`, so each position's expectation is its own light.
        // Beyond the end centres (`AtCentres::at`) each position takes its
        // own.
        // Without the table every ray's transmittance is tracked, and each
        // position takes its own light.
        let tabled = integrator.plan.splat_transmittance_table;
        let every = if tabled { self.exact_every } else { 1 };
        let control = tabled.then(|| {
            AtCentres::from_fn(|m| {
                let (to, cam_dir) = placed[m];
                let t = to.length();
                self.observer
                    .table_transmittance(to / t, t, lanes)
                    .map_or(Lanes::splat(0.0), |tr| {
                        tr * in_scattered(cam_dir) * Lanes::splat(self.control_scale)
                    })
            })
        });
        let offset = ((rng.uniform() * every as f64) as usize).min(every - 1);
        let mut discarded = 0;
        let first = out.len();
        for (i, &(psi, to, cam_dir)) in positions.iter().enumerate() {
            let position_density = arc.density(psi, &cells, phase_splats);
            let t = to.length();
            let dir = to / t;
            let per_sr = camera.pixels_per_sr(dir);
            if per_sr <= 0.0 {
                continue;
            }
            let Some((px, py)) = camera.splat_position(dir) else {
                continue;
            };
            let light = if let Some(control) = &control {
                // T̃ × the in-scattered light (0 where the ground hides the
                // position), whose expectation the control's term keeps;
                // then T's own correction (as `ObserverRays::transmittance`
                // adds it), so that each position's expectation is T × it.
                let table = || self.observer.table_transmittance(dir, t, lanes);
                let mut looked_up = None;
                let mut light = match control.at(arc.quantile(psi)) {
                    Some(approx) if i % every != offset => approx,
                    // The exact one, or beyond the end centres each its own.
                    approx => {
                        let tr = *looked_up.insert(table());
                        let own = tr.map_or(Lanes::splat(0.0), |tr| tr * in_scattered(cam_dir));
                        approx.map_or(own, |approx| {
                            Lanes::from_fn(|j| approx[j] + every as f64 * (own[j] - approx[j]))
                        })
                    }
                };
                let tr = || looked_up.unwrap_or_else(table);
                if let Some(correction) =
                    self.observer.correction(integrator, dir, t, lanes, tr, rng)
                {
                    light += correction * in_scattered(cam_dir);
                }
                light
            } else {
                self.observer
                    .transmittance(integrator, dir, t, lanes, rng)
                    .map_or(Lanes::splat(0.0), |tr| tr * in_scattered(cam_dir))
            };
            let weight =
                r * r * circle.sin_theta * per_sr / (t * t * point_density * position_density);
            let mut xyz = [0.0; 3];
            let mut spectral = super::film_spectral::SplatLanes::default();
            for j in 0..lanes.active {
                let l = light[j] * weight;
                for (v, bar) in xyz.iter_mut().zip(wavelength_weights[j]) {
                    *v += l * bar;
                }
                spectral.wavelengths_nm[j] = lanes.wavelengths_nm[j] as f32;
                spectral.values[j] = l as f32;
            }
            if xyz.iter().all(|v| v.is_finite()) {
                out.push(Splat {
                    pixel: (py as u32) * width as u32 + px as u32,
                    column_offset: px.fract() as f32,
                    xyz,
                    lanes: spectral,
                });
            } else {
                discarded += 1;
            }
        }
        let squares: f64 = out[first..].iter().map(|s| s.xyz[1] * s.xyz[1]).sum();
        let moment = densities
            .bin
            .filter(|_| squares > 0.0 && densities.prior > 0.0)
            .map(|bin| (Self::cell(bin), squares * densities.drawn / densities.prior));
        Walked { discarded, moment }
    }
}

#[cfg(test)]
mod tests;
