//! Columns of the medium's profiles from a point to the top of the
//! atmosphere, tabulated over (altitude, direction cosine): the control of
//! the shadow rays' residual ratio tracking, found with one or two table
//! look-ups instead of a walk through the shells.
//!
//! Residual ratio tracking (Novák et al. 2014) estimates a transmittance as
//!
//! T = exp(−τ_c) · E[∏ᵢ (1 − (σ(xᵢ) − σ_c(xᵢ)) / σ̄)],
//!
//! the product over the points of a Poisson process of rate σ̄ along the ray.
//! It is unbiased whatever the control σ_c, provided τ_c is *exactly* the
//! control's integral along the ray; σ̄ ≥ |σ − σ_c| keeps each factor in
//! [0, 2]. So the control is defined from the table rather than the other
//! way round: with C̃(r, μ) a continuous approximation of the column from
//! radius r along direction cosine μ to the top, the control at a point is
//! C̃'s rate of decrease along the ray, σ_c = −dC̃/ds, with dr/ds = μ and
//! dμ/ds = (1 − μ²)/r on a straight ray. Its integral from a point to the
//! top is C̃ there (C̃ = 0 at the top) — exact by the fundamental theorem of
//! calculus whatever the table's error, which only enters the residual.
//!
//! C̃ = V(r) / g̃(r, μ): V is the exact vertical column of the medium's
//! piecewise-linear profiles (so −dV/dr is the profile itself: a vertical
//! ray's residual is zero but for ozone's temperature dependence), and g̃
//! interpolates the slant factor g = V/C (μ in a flat atmosphere; smooth) on
//! nodes uniform in √(h + 500 m) and μ/(μ + 0.2) — dense low down and about
//! the horizontal, where the columns change fastest — linearly across
//! altitude and by cubic Hermite splines along μ. A horizontal ray's control
//! is g̃'s slope in μ alone, which a piecewise-linear g̃ gets wrong to first
//! order in the node spacing (3 % residuals here); the spline's slope is
//! right to second order (0.5 %). A ray that starts downward (μ < 0) climbs
//! out symmetrically from its perigee p: C(r, μ) = 2 C(p, 0) − C(r, −μ), and
//! its control at (r, μ) is the one at (r, |μ|). The residual bound of each
//! table cell is the largest residual found on a 6 × 6 grid of points in it,
//! with a 50 % margin.
//!
//! Measured (`BENCHMARKS.md`): a shadow ray toward a 45° sun costs a third
//! of the walk through the shells, with 1/3–1/20 of its relative standard
//! deviation; grazing rays cost about the same as before.

use glam::DVec3;

use super::medium::{Lanes, Medium, SpectralLanes, LANES, NODE_STEP_M};
use crate::rng::Rng;

/// Altitude nodes of the slant-factor table.
const ALTITUDE_NODES: usize = 64;
/// Direction-cosine nodes (μ from 0 to 1).
const COSINE_NODES: usize = 64;
/// Altitude offset of the node spacing, m: nodes uniform in √(h + offset)
/// (dense low down, with a finite derivative at the ground).
const ALTITUDE_OFFSET_M: f64 = 500.0;
/// Cosine scale of the node spacing: nodes uniform in μ/(μ + scale), dense
/// about the horizontal, where the columns change fastest, and nearly linear
/// there, so that the interpolant's slope follows the columns' (the control
/// of a horizontal ray is that slope).
const COSINE_SCALE: f64 = 0.2;
/// Points per cell side at which the residual is evaluated for its bound.
const BOUND_POINTS: usize = 6;
/// Margin on the largest residual found, for what lies between the points.
const BOUND_MARGIN: f64 = 1.5;
/// Rays whose residual bound expects more events than this go through the
/// shells instead: an event (a coefficient and a control evaluation) costs
/// about a third of the walk, and such rays are grazing ones low down, which
/// the walk's per-shell residuals follow more closely.
const MAX_EXPECTED_EVENTS: f64 = 2.0;
/// Longest piece of a ray in the slant columns' quadrature, m.
const SLANT_PIECE_M: f64 = 5_000.0;
/// Number of profiles: air (m⁻³), aerosol extinction at 340 nm (m⁻¹),
/// ozone (m⁻³) — the order of [`SpectralLanes::control`].
const PROFILES: usize = 3;

pub type Profiles = [f64; PROFILES];
/// A table node: g per profile, then its slope along the cosine nodes
/// (second-order differences, one-sided at the ends).
type Node = [f64; 2 * PROFILES];

/// The table of one medium (built once; independent of the sun and the
/// wavelengths).
pub struct ColumnTable {
    planet_radius_m: f64,
    top_m: f64,
    /// Profiles at the medium's nodes, every [`NODE_STEP_M`] from the ground.
    nodes: Vec<Profiles>,
    /// Vertical column above each node, to the top.
    above_node: Vec<Profiles>,
    /// Slant factor g = V/C at (altitude node i, cosine node k) and its
    /// slope along the cosine nodes, `[i * COSINE_NODES + k]`.
    table: Vec<Node>,
    /// Largest |profile − control| over the cells at or above altitude node
    /// i and at or above cosine node k (same layout).
    bound: Vec<Profiles>,
    /// Largest ozone density anywhere, m⁻³ (for the temperature term).
    ozone_max_m3: f64,
    /// Node coordinates per unit of √(h + offset) (h in m) and of μ/(μ + scale).
    altitude_per_root: f64,
    cosine_coordinate_scale: f64,
}

/// Where a point lies in the table and how its coordinates change along a ray.
struct Cell {
    i: usize,
    k: usize,
    fa: f64,
    fz: f64,
    /// d(altitude coordinate)/dr, 1/m, and d(cosine coordinate)/dμ.
    da_dr: f64,
    dz_dmu: f64,
}

impl ColumnTable {
    /// Builds the table for a planet of radius `planet_radius_m` with an
    /// atmosphere `top_m` deep whose profiles (in the order of [`Profiles`])
    /// are `nodes`, linear between nodes [`NODE_STEP_M`] apart from the
    /// ground ([`Medium`]'s cache); ~25 ms.
    pub fn new(planet_radius_m: f64, top_m: f64, nodes: Vec<Profiles>) -> Self {
        let mut table = Self {
            planet_radius_m,
            top_m,
            above_node: Vec::new(),
            table: Vec::new(),
            bound: Vec::new(),
            ozone_max_m3: nodes.iter().map(|n| n[2]).fold(0.0, f64::max),
            altitude_per_root: (ALTITUDE_NODES - 1) as f64
                / ((top_m + ALTITUDE_OFFSET_M).sqrt() - ALTITUDE_OFFSET_M.sqrt()),
            cosine_coordinate_scale: (COSINE_NODES - 1) as f64 * (1.0 + COSINE_SCALE),
            nodes,
        };
        table.above_node = table.vertical_columns();
        let slant: Vec<Profiles> = (0..ALTITUDE_NODES * COSINE_NODES)
            .map(|n| {
                let (i, k) = (n / COSINE_NODES, n % COSINE_NODES);
                // Just below the top, where V and C both vanish but not their ratio.
                let h = table.node_altitude_m(i).min(top_m - 1.0);
                let vertical = table.vertical(h);
                let slant = table.slant_column(h, table.node_cosine(k));
                std::array::from_fn(|p| {
                    if vertical[p] > 0.0 && slant[p] > 0.0 {
                        vertical[p] / slant[p]
                    } else {
                        // A profile that is zero above here (no ozone, no aerosol):
                        // any positive factor gives the exact zero column.
                        1.0
                    }
                })
            })
            .collect();
        table.table = (0..ALTITUDE_NODES * COSINE_NODES)
            .map(|n| {
                let k = n % COSINE_NODES;
                let g = |k: usize| &slant[n - n % COSINE_NODES + k];
                let last = COSINE_NODES - 1;
                // Second-order differences, one-sided at the ends.
                std::array::from_fn(|q| {
                    let p = q % PROFILES;
                    match (q < PROFILES, k) {
                        (true, _) => g(k)[p],
                        (false, 0) => 0.5 * (-3.0 * g(0)[p] + 4.0 * g(1)[p] - g(2)[p]),
                        (false, k) if k == last => {
                            0.5 * (3.0 * g(last)[p] - 4.0 * g(last - 1)[p] + g(last - 2)[p])
                        }
                        (false, k) => 0.5 * (g(k + 1)[p] - g(k - 1)[p]),
                    }
                })
            })
            .collect();
        table.bound = table.residual_bounds();
        table
    }

    /// Altitude of node `i`, m.
    fn node_altitude_m(&self, i: usize) -> f64 {
        ((i as f64 / self.altitude_per_root + ALTITUDE_OFFSET_M.sqrt()).powi(2) - ALTITUDE_OFFSET_M)
            .clamp(0.0, self.top_m)
    }

    /// Direction cosine of node `k`.
    fn node_cosine(&self, k: usize) -> f64 {
        let z = k as f64 / self.cosine_coordinate_scale;
        (COSINE_SCALE * z / (1.0 - z)).clamp(0.0, 1.0)
    }

    /// The profiles at altitude `h_m`, interpolated exactly as
    /// [`Medium::densities`] does.
    fn profiles(&self, h_m: f64) -> Profiles {
        let x = (h_m / NODE_STEP_M).max(0.0);
        let i = (x as usize).min(self.nodes.len() - 2);
        let f = (x - i as f64).min(1.0);
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        std::array::from_fn(|p| a[p] + f * (b[p] - a[p]))
    }

    /// Column above each node: the trapezoid rule is exact for the linear
    /// pieces (up to the top, inside the last node interval).
    fn vertical_columns(&self) -> Vec<Profiles> {
        let n = self.nodes.len();
        let mut above = vec![[0.0; PROFILES]; n];
        let last = ((self.top_m / NODE_STEP_M) as usize).min(n - 2);
        let (z_last, at_top) = (last as f64 * NODE_STEP_M, self.profiles(self.top_m));
        above[last] = std::array::from_fn(|p| {
            0.5 * (self.top_m - z_last) * (self.nodes[last][p] + at_top[p])
        });
        for i in (0..last).rev() {
            above[i] = std::array::from_fn(|p| {
                above[i + 1][p] + 0.5 * NODE_STEP_M * (self.nodes[i][p] + self.nodes[i + 1][p])
            });
        }
        above
    }

    /// Exact vertical column from altitude `h_m` to the top.
    fn vertical(&self, h_m: f64) -> Profiles {
        self.vertical_and_density(h_m).0
    }

    /// The vertical column from altitude `h_m` to the top and the profiles
    /// there.
    fn vertical_and_density(&self, h_m: f64) -> (Profiles, Profiles) {
        let h = h_m.clamp(0.0, self.top_m);
        let i = ((h / NODE_STEP_M) as usize).min(self.nodes.len() - 2);
        let below = h - i as f64 * NODE_STEP_M;
        let here = self.profiles(h);
        (
            std::array::from_fn(|p| {
                (self.above_node[i][p] - 0.5 * below * (self.nodes[i][p] + here[p])).max(0.0)
            }),
            here,
        )
    }

    /// Column from altitude `h_m` along cosine `mu` ≥ 0 to the top, by
    /// 6-point Gauss–Legendre between the table's altitude nodes (smooth
    /// there but for the profiles' 50 m kinks: ~1e-6 relative).
    fn slant_column(&self, h_m: f64, mu: f64) -> Profiles {
        const GAUSS: [(f64, f64); 6] = [
            (-0.932_469_514_203_152, 0.171_324_492_379_170),
            (-0.661_209_386_466_265, 0.360_761_573_048_139),
            (-0.238_619_186_083_197, 0.467_913_934_572_691),
            (0.238_619_186_083_197, 0.467_913_934_572_691),
            (0.661_209_386_466_265, 0.360_761_573_048_139),
            (0.932_469_514_203_152, 0.171_324_492_379_170),
        ];
        let r0 = self.planet_radius_m + h_m;
        let perigee2 = r0 * r0 * (1.0 - mu * mu);
        let s_at = |h: f64| {
            ((self.planet_radius_m + h).powi(2) - perigee2)
                .max(0.0)
                .sqrt()
        };
        let mut sum = [0.0; PROFILES];
        let mut s0 = r0 * mu;
        // Finer than the table near the start, where the ray may graze.
        let mut boundaries: Vec<f64> = (0..ALTITUDE_NODES)
            .map(|i| self.node_altitude_m(i))
            .filter(|&h| h > h_m)
            .collect();
        boundaries.push(self.top_m);
        for h1 in boundaries {
            let s1 = s_at(h1).max(s0);
            // Pieces at most 5 km long: near the horizontal one altitude
            // interval spans tens of km and many of the profiles' kinks.
            let pieces = ((s1 - s0) / SLANT_PIECE_M).ceil().max(1.0);
            let half = 0.5 * (s1 - s0) / pieces;
            for piece in 0..pieces as usize {
                let mid = s0 + half * (2.0 * piece as f64 + 1.0);
                for (x, w) in GAUSS {
                    let s = mid + half * x;
                    let h = (perigee2 + s * s).sqrt() - self.planet_radius_m;
                    let n = self.profiles(h);
                    for p in 0..PROFILES {
                        sum[p] += w * half * n[p];
                    }
                }
            }
            s0 = s1;
        }
        sum
    }

    /// The cell of the point at radius `radius_m` on a ray with cosine `mu`.
    fn cell(&self, radius_m: f64, mu: f64) -> Cell {
        let h = (radius_m - self.planet_radius_m).clamp(0.0, self.top_m);
        let root_h = (h + ALTITUDE_OFFSET_M).sqrt();
        let a = self.altitude_per_root * (root_h - ALTITUDE_OFFSET_M.sqrt());
        let mu = mu.clamp(0.0, 1.0);
        let inv = 1.0 / (mu + COSINE_SCALE);
        let z = self.cosine_coordinate_scale * mu * inv;
        let i = (a as usize).min(ALTITUDE_NODES - 2);
        let k = (z as usize).min(COSINE_NODES - 2);
        Cell {
            i,
            k,
            fa: (a - i as f64).clamp(0.0, 1.0),
            fz: (z - k as f64).clamp(0.0, 1.0),
            da_dr: 0.5 * self.altitude_per_root / root_h,
            dz_dmu: self.cosine_coordinate_scale * COSINE_SCALE * inv * inv,
        }
    }

    /// The four table nodes around `cell`: (i, k), (i, k+1), (i+1, k), (i+1, k+1).
    fn corners(&self, cell: &Cell) -> [&Node; 4] {
        let n = cell.i * COSINE_NODES + cell.k;
        [
            &self.table[n],
            &self.table[n + 1],
            &self.table[n + COSINE_NODES],
            &self.table[n + COSINE_NODES + 1],
        ]
    }

    /// g̃ at `cell`: cubic Hermite along the cosine nodes (C¹, so its slope —
    /// the control of a horizontal ray — is accurate to second order),
    /// linear across the altitude nodes.
    fn slant_factor(&self, cell: &Cell) -> Profiles {
        let [n00, n01, n10, n11] = self.corners(cell);
        let t = cell.fz;
        let (t2, t3) = (t * t, t * t * t);
        let h = [
            2.0 * t3 - 3.0 * t2 + 1.0,
            t3 - 2.0 * t2 + t,
            3.0 * t2 - 2.0 * t3,
            t3 - t2,
        ];
        let fa = cell.fa;
        std::array::from_fn(|p| {
            let q = p + PROFILES;
            let lower = h[0] * n00[p] + h[1] * n00[q] + h[2] * n01[p] + h[3] * n01[q];
            let upper = h[0] * n10[p] + h[1] * n10[q] + h[2] * n11[p] + h[3] * n11[q];
            (1.0 - fa) * lower + fa * upper
        })
    }

    /// g̃ and its partial derivatives in the node coordinates (a, z) at `cell`.
    fn slant_factor_derivatives(&self, cell: &Cell) -> [(f64, f64, f64); PROFILES] {
        let [n00, n01, n10, n11] = self.corners(cell);
        let t = cell.fz;
        let (t2, t3) = (t * t, t * t * t);
        let h = [
            2.0 * t3 - 3.0 * t2 + 1.0,
            t3 - 2.0 * t2 + t,
            3.0 * t2 - 2.0 * t3,
            t3 - t2,
        ];
        let d = [
            6.0 * t2 - 6.0 * t,
            3.0 * t2 - 4.0 * t + 1.0,
            6.0 * t - 6.0 * t2,
            3.0 * t2 - 2.0 * t,
        ];
        let fa = cell.fa;
        std::array::from_fn(|p| {
            let q = p + PROFILES;
            let hermite = |w: &[f64; 4], lo: &Node, hi: &Node| {
                w[0] * lo[p] + w[1] * lo[q] + w[2] * hi[p] + w[3] * hi[q]
            };
            let (lower, upper) = (hermite(&h, n00, n01), hermite(&h, n10, n11));
            let (lower_dz, upper_dz) = (hermite(&d, n00, n01), hermite(&d, n10, n11));
            (
                (1.0 - fa) * lower + fa * upper,
                upper - lower,
                (1.0 - fa) * lower_dz + fa * upper_dz,
            )
        })
    }

    /// C̃ from radius `radius_m` along cosine `mu` ≥ 0 to the top, and the
    /// index of its cell's bound.
    fn columns_up(&self, radius_m: f64, mu: f64) -> (Profiles, usize) {
        let vertical = self.vertical(radius_m - self.planet_radius_m);
        let cell = self.cell(radius_m, mu);
        let slant = self.slant_factor(&cell);
        (
            std::array::from_fn(|p| vertical[p] / slant[p]),
            cell.i * COSINE_NODES + cell.k,
        )
    }

    /// C̃ for any cosine — a ray that starts downward is the whole chord of
    /// its perigee less the part behind its start — and the bound on
    /// |profile − control| along the ray (from the perigee on, if it starts
    /// downward).
    fn columns_and_bound(&self, radius_m: f64, mu: f64) -> (Profiles, Profiles) {
        if mu >= 0.0 {
            let (columns, cell) = self.columns_up(radius_m, mu);
            return (columns, self.bound[cell]);
        }
        let perigee_m = radius_m * (1.0 - mu * mu).max(0.0).sqrt();
        let (chord, cell) = self.columns_up(perigee_m, 0.0);
        let (behind, _) = self.columns_up(radius_m, -mu);
        (
            std::array::from_fn(|p| 2.0 * chord[p] - behind[p]),
            self.bound[cell],
        )
    }

    /// The control σ_c = −dC̃/ds per profile at radius `radius_m`, cosine
    /// `mu` (the same for −μ), by the chain rule through the node coordinates.
    fn control(&self, radius_m: f64, mu: f64) -> Profiles {
        let mu = mu.abs();
        let (vertical, density) = self.vertical_and_density(radius_m - self.planet_radius_m);
        let cell = self.cell(radius_m, mu);
        let slant = self.slant_factor_derivatives(&cell);
        let dmu_ds = (1.0 - mu * mu) / radius_m;
        std::array::from_fn(|p| {
            let (g, dg_da, dg_dz) = slant[p];
            let dg_ds = dg_da * cell.da_dr * mu + dg_dz * cell.dz_dmu * dmu_ds;
            // −d(V/g)/ds with dV/ds = −n μ.
            density[p] * mu / g + vertical[p] * dg_ds / (g * g)
        })
    }

    /// Bounds on |profile − control| per cell, then the largest over all
    /// cells at or above each cell in both coordinates (a ray that starts
    /// upward only climbs in both).
    fn residual_bounds(&self) -> Vec<Profiles> {
        let cell_bound = |n: usize| {
            let (i, k) = (n / COSINE_NODES, n % COSINE_NODES);
            if i + 1 == ALTITUDE_NODES || k + 1 == COSINE_NODES {
                return [0.0; PROFILES];
            }
            let (a0, a1) = (self.node_altitude_m(i), self.node_altitude_m(i + 1));
            let (m0, m1) = (self.node_cosine(k), self.node_cosine(k + 1));
            let mut worst = [0.0_f64; PROFILES];
            for u in 0..BOUND_POINTS {
                let h = a0 + (a1 - a0) * u as f64 / (BOUND_POINTS - 1) as f64;
                let r = self.planet_radius_m + h.min(self.top_m - 1e-3);
                let n = self.profiles(r - self.planet_radius_m);
                for v in 0..BOUND_POINTS {
                    let mu = m0 + (m1 - m0) * v as f64 / (BOUND_POINTS - 1) as f64;
                    let c = self.control(r, mu);
                    for p in 0..PROFILES {
                        worst[p] = worst[p].max((n[p] - c[p]).abs());
                    }
                }
            }
            worst.map(|w| BOUND_MARGIN * w)
        };
        let mut bound: Vec<Profiles> = (0..ALTITUDE_NODES * COSINE_NODES).map(cell_bound).collect();
        for i in (0..ALTITUDE_NODES).rev() {
            for k in (0..COSINE_NODES).rev() {
                let mut b = bound[i * COSINE_NODES + k];
                for (di, dk) in [(1, 0), (0, 1)] {
                    if i + di < ALTITUDE_NODES && k + dk < COSINE_NODES {
                        let next = bound[(i + di) * COSINE_NODES + k + dk];
                        b = std::array::from_fn(|p| b[p].max(next[p]));
                    }
                }
                bound[i * COSINE_NODES + k] = b;
            }
        }
        bound
    }

    /// Unbiased transmittance estimate, per lane, along `dir` from `origin`
    /// (m, planet-centred) over `[t_enter, t_exit]`, the ray's whole
    /// remaining span to the top (it must not meet the ground); `None` where
    /// the residual bound expects more than [`MAX_EXPECTED_EVENTS`] on the
    /// ray, which the walk through the shells then estimates faster.
    pub fn transmittance(
        &self,
        medium: &Medium,
        origin: DVec3,
        dir: DVec3,
        (t_enter, t_exit): (f64, f64),
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<Lanes> {
        let start = origin + dir * t_enter;
        let r0 = start.length();
        // The end is at the top, where C̃ = 0 (V vanishes there, up to rounding).
        let (columns, bound) = self.columns_and_bound(r0, start.dot(dir) / r0);
        let depth = lanes.control(columns);
        let rate = lanes.residual_bound(bound, self.ozone_max_m3);
        if rate * (t_exit - t_enter) > MAX_EXPECTED_EVENTS {
            return None;
        }
        let mut factors = [1.0; LANES];
        if rate > 0.0 {
            let mut t = t_enter;
            loop {
                t -= rng.uniform_open0().ln() / rate;
                if t >= t_exit {
                    break;
                }
                let x = origin + dir * t;
                let r = x.length();
                let c = medium.coefficients(r, lanes);
                let control = lanes.control(self.control(r, x.dot(dir) / r));
                for (j, f) in factors.iter_mut().enumerate() {
                    *f *= 1.0 - (c.extinction(j) - control[j]) / rate;
                }
            }
        }
        Some(std::array::from_fn(|j| factors[j] * (-depth[j]).exp()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::render::medium::Span;

    fn medium() -> Medium {
        Medium::new(&Atmosphere::new(AtmosphereParams::default()))
    }

    fn table(medium: &Medium) -> &ColumnTable {
        medium.column_table()
    }

    /// Rays that leave the atmosphere without meeting the ground: from the
    /// ground at several elevations down to the horizontal, from altitude
    /// through a perigee, from the mesosphere and from space.
    fn rays(medium: &Medium) -> Vec<(DVec3, DVec3, Span)> {
        let mut rays = Vec::new();
        for (altitude_m, elevations) in [
            (2.0, vec![90.0, 45.0, 10.0, 2.0, 0.3, 0.0]),
            (3_000.0, vec![30.0, 0.0, -1.0]),
            (12_345.0, vec![-2.0, -3.5]),
            (60_000.0, vec![-7.0, 5.0]),
            (400_000.0, vec![-19.7]),
        ] {
            for el in elevations {
                let el: f64 = el;
                let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + altitude_m);
                let dir = DVec3::new(el.to_radians().cos(), 0.0, el.to_radians().sin());
                let span = medium.span(origin, dir).unwrap();
                assert!(!span.hits_ground, "altitude {altitude_m} elevation {el}");
                rays.push((origin, dir, span));
            }
        }
        rays
    }

    /// The columns and the residual bound where the ray enters `span`.
    fn at_start(
        table: &ColumnTable,
        origin: DVec3,
        dir: DVec3,
        span: Span,
    ) -> (Profiles, Profiles) {
        let start = origin + dir * span.t_enter;
        table.columns_and_bound(start.length(), start.dot(dir) / start.length())
    }

    /// Where `origin + t·dir` crosses radius `radius_m`, inside `span`.
    fn crossings(origin: DVec3, dir: DVec3, span: Span, radius_m: f64) -> Vec<f64> {
        let b = origin.dot(dir);
        let disc = b * b - origin.length_squared() + radius_m * radius_m;
        if disc <= 0.0 {
            return Vec::new();
        }
        [-b - disc.sqrt(), -b + disc.sqrt()]
            .into_iter()
            .filter(|t| (span.t_enter..span.t_exit).contains(t))
            .collect()
    }

    #[test]
    fn controls_integrate_to_the_tabulated_columns() {
        // What makes the estimator unbiased: the control's integral from a
        // point to the top is the column the estimate is given. Gauss–Legendre
        // (4 points) on 500 pieces between the altitude nodes (the control
        // jumps there, the interpolant being linear across them; no point
        // falls on a jump), 1e-8 relative.
        const GAUSS: [(f64, f64); 4] = [
            (-0.861_136_311_594_053, 0.347_854_845_137_454),
            (-0.339_981_043_584_856, 0.652_145_154_862_546),
            (0.339_981_043_584_856, 0.652_145_154_862_546),
            (0.861_136_311_594_053, 0.347_854_845_137_454),
        ];
        let medium = medium();
        let table = table(&medium);
        for (origin, dir, span) in rays(&medium) {
            let mut breaks = vec![span.t_enter, span.t_exit];
            for i in 1..ALTITUDE_NODES - 1 {
                let radius_m = table.planet_radius_m + table.node_altitude_m(i);
                breaks.extend(crossings(origin, dir, span, radius_m));
            }
            breaks.sort_by(f64::total_cmp);
            let mut integral = [0.0; PROFILES];
            for w in breaks.windows(2) {
                let pieces = 500;
                let half = 0.5 * (w[1] - w[0]) / f64::from(pieces);
                for piece in 0..pieces {
                    let mid = w[0] + half * (2.0 * f64::from(piece) + 1.0);
                    for (u, weight) in GAUSS {
                        let x = origin + dir * (mid + half * u);
                        let r = x.length();
                        let control = table.control(r, x.dot(dir) / r);
                        for p in 0..PROFILES {
                            integral[p] += weight * half * control[p];
                        }
                    }
                }
            }
            let (columns, _) = at_start(table, origin, dir, span);
            for p in 0..PROFILES {
                assert!(
                    (integral[p] - columns[p]).abs() <= 1e-8 * columns[p],
                    "{dir:?} from {:.0} m, profile {p}: ∫ control {} vs column {}",
                    origin.length() - table.planet_radius_m,
                    integral[p],
                    columns[p]
                );
            }
        }
    }

    #[test]
    fn tabulated_columns_are_close_to_the_profiles_columns() {
        // Not needed for unbiasedness, but a table far off would make the
        // residual, and the noise, large: within 1 % of midpoint quadrature
        // (the worst: 0.7 % for aerosol on the horizontal ray from 3 km,
        // where its profile bends between two altitude nodes; < 0.1 %
        // elsewhere).
        let medium = medium();
        let table = table(&medium);
        for (origin, dir, span) in rays(&medium) {
            let n = 200_000;
            let dt = (span.t_exit - span.t_enter) / f64::from(n);
            let mut exact = [0.0; PROFILES];
            for i in 0..n {
                let x = origin + dir * (span.t_enter + dt * (f64::from(i) + 0.5));
                let d = table.profiles(x.length() - table.planet_radius_m);
                for p in 0..PROFILES {
                    exact[p] += d[p] * dt;
                }
            }
            let (columns, _) = at_start(table, origin, dir, span);
            for p in 0..PROFILES {
                assert!(
                    (columns[p] - exact[p]).abs() <= 1e-2 * exact[p],
                    "{dir:?} profile {p}: {} vs {}",
                    columns[p],
                    exact[p]
                );
            }
        }
    }

    #[test]
    fn controls_stay_within_their_residual_bound() {
        // 2000 points along each ray: |profile − control| ≤ the ray's bound.
        let medium = medium();
        let table = table(&medium);
        for (origin, dir, span) in rays(&medium) {
            let (_, bound) = at_start(table, origin, dir, span);
            for i in 0..=2000 {
                let t = span.t_enter + (span.t_exit - span.t_enter) * f64::from(i) / 2000.0;
                let x = origin + dir * t;
                let r = x.length();
                let profiles = table.profiles(r - table.planet_radius_m);
                let control = table.control(r, x.dot(dir) / r);
                for p in 0..PROFILES {
                    assert!(
                        (profiles[p] - control[p]).abs() <= bound[p],
                        "{dir:?} at {:.0} m, profile {p}: residual {} > bound {}",
                        r - table.planet_radius_m,
                        profiles[p] - control[p],
                        bound[p]
                    );
                }
            }
        }
    }
}
