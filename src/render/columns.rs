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
//! the horizontal, where the columns change fastest — by a bicubic Hermite
//! patch (C¹). A near-horizontal ray's control is mostly g̃'s slope in μ,
//! which a piecewise-linear g̃ gets wrong to first order in the node spacing
//! (3 % residuals); the spline's slopes are right to second order. A ray
//! that starts downward (μ < 0) climbs out symmetrically from its perigee p:
//! C(r, μ) = 2 C(p, 0) − C(r, −μ), and its control at (r, μ) is the one at
//! (r, |μ|). The residual bound of each table cell is the largest residual
//! found on a 4 × 4 grid of points in it and at the profiles' kinks (where
//! the tabulated data change slope) inside it, with a 50 % margin. Residuals
//! (bound / sea-level density): air 0.03 % (0.1 % on grazing rays), aerosol
//! 0.1 % (up to 3 % on grazing rays low down), ozone 0.05–2 % of its peak.
//! A ray whose bound expects more than two residual
//! events (grazing rays low down) goes through the shells' chords instead.
//!
//! Measured (`BENCHMARKS.md`): relative std of one shadow-ray
//! estimate 0.003–0.011 on steep rays (chords: 0.013–0.042), 0.015–0.05 on
//! grazing ones and from orbit (0.06–0.15); instructions per camera path
//! (callgrind) 27 % fewer at midday, 18 % at sunset, 23 % from orbit, 2 % at
//! twilight (most of its shadow rays end on the planet); the table takes
//! ~20 ms to build, on first use.

use glam::DVec3;

/// Spacing of the medium's cached profile nodes, m (the table's nodes are
/// the medium's).
pub const NODE_STEP_M: f64 = 50.0;

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
/// Points per cell side at which the residual is evaluated for its bound
/// (plus the profiles' kinks).
const BOUND_POINTS: usize = 4;
/// A node where a profile's second difference exceeds this fraction of its
/// value is a kink of the tabulated data (the exponential air profile's
/// curvature over 50 m is 4e-5).
const KINK: f64 = 1e-3;
/// Margin on the largest residual found, for what lies between the points.
const BOUND_MARGIN: f64 = 1.5;
/// Rays whose residual bound expects more events than this go through the
/// shells instead: an event (a coefficient and a control evaluation) costs
/// about a third of the walk, and such rays are grazing ones low down, which
/// the walk's per-shell residuals follow more closely.
pub(super) const MAX_EXPECTED_EVENTS: f64 = 2.0;
/// Longest piece of a ray in the slant columns' quadrature, m.
const SLANT_PIECE_M: f64 = 10_000.0;
/// Number of profiles: air (m⁻³), aerosol extinction at the reference
/// wavelength (m⁻¹), ozone (m⁻³) — the order of [`SpectralLanes::control`].
pub(super) const PROFILES: usize = 3;

/// One value per profile: air (m⁻³), aerosol extinction at the reference
/// wavelength (m⁻¹), ozone (m⁻³).
pub type Profiles = [f64; PROFILES];
/// Entries of a table node: per profile g, then its slopes in node units
/// along the cosine nodes, along the altitude nodes, and across both.
const NODE_LEN: usize = 4 * PROFILES;
/// A table node.
type Node = [f64; NODE_LEN];

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
    /// slopes (see [`Node`]), `[i * COSINE_NODES + k]`.
    table: Vec<Node>,
    /// Largest |profile − control| over the cells at or above altitude node
    /// i and at or above cosine node k (same layout).
    pub(super) bound: Vec<Profiles>,
    /// Largest ozone density anywhere, m⁻³ (for the temperature term).
    pub(super) ozone_max_m3: f64,
    /// Node coordinates per unit of √(h + offset) (h in m) and of μ/(μ + scale).
    altitude_per_root: f64,
    cosine_coordinate_scale: f64,
}

/// Cubic Hermite basis on [0, 1] at `t` and its derivatives, ordered
/// (value at 0, slope at 0, value at 1, slope at 1).
fn hermite(t: f64) -> ([f64; 4], [f64; 4]) {
    let (t2, t3) = (t * t, t * t * t);
    (
        [
            2.0 * t3 - 3.0 * t2 + 1.0,
            t3 - 2.0 * t2 + t,
            3.0 * t2 - 2.0 * t3,
            t3 - t2,
        ],
        [
            6.0 * t2 - 6.0 * t,
            3.0 * t2 - 4.0 * t + 1.0,
            6.0 * t - 6.0 * t2,
            3.0 * t2 - 2.0 * t,
        ],
    )
}

/// The slope at node `k` of `f` over `nodes` unit-spaced nodes: central
/// differences, second-order one-sided ones at the ends.
fn slope(f: &dyn Fn(usize) -> f64, k: usize, nodes: usize) -> f64 {
    match k {
        0 => 0.5 * (-3.0 * f(0) + 4.0 * f(1) - f(2)),
        k if k + 1 == nodes => 0.5 * (3.0 * f(k) - 4.0 * f(k - 1) + f(k - 2)),
        k => 0.5 * (f(k + 1) - f(k - 1)),
    }
}

/// The perigee radius of the ray from radius `radius_m` with cosine `mu`.
fn perigee_m(radius_m: f64, mu: f64) -> f64 {
    radius_m * (1.0 - mu * mu).max(0.0).sqrt()
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
    /// are `nodes`, linear between nodes 50 m apart from the
    /// ground ([`super::medium::Medium`]'s cache); ~20 ms.
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
        let mut slant: Vec<Profiles> = (0..ALTITUDE_NODES * COSINE_NODES)
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
                        f64::NAN
                    }
                })
            })
            .collect();
        // Where a profile is zero from some altitude up (aerosol above 50 km,
        // or a profile switched off), any positive factor gives the exact
        // zero column: carry the last one up, so the spline stays smooth.
        for n in 0..slant.len() {
            let below = (n >= COSINE_NODES).then(|| slant[n - COSINE_NODES]);
            for (p, g) in slant[n].iter_mut().enumerate() {
                if g.is_nan() {
                    *g = below.map_or(1.0, |b| b[p]);
                }
            }
        }
        // Slopes in node units by second-order differences (one-sided at
        // the ends), along z, along a, and the cross slope.
        let along_z = |f: &dyn Fn(usize) -> f64, n: usize| {
            let k = n % COSINE_NODES;
            slope(&|k2| f(n - k + k2), k, COSINE_NODES)
        };
        let along_a = |f: &dyn Fn(usize) -> f64, n: usize| {
            let (i, k) = (n / COSINE_NODES, n % COSINE_NODES);
            slope(&|i2| f(i2 * COSINE_NODES + k), i, ALTITUDE_NODES)
        };
        table.table = (0..ALTITUDE_NODES * COSINE_NODES)
            .map(|n| {
                let mut node = [0.0; NODE_LEN];
                for p in 0..PROFILES {
                    let g = |m: usize| slant[m][p];
                    node[p] = slant[n][p];
                    node[PROFILES + p] = along_z(&g, n);
                    node[2 * PROFILES + p] = along_a(&g, n);
                    node[3 * PROFILES + p] = along_a(&|m| along_z(&g, m), n);
                }
                node
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
    pub(super) fn profiles(&self, h_m: f64) -> Profiles {
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
    /// 4-point Gauss–Legendre between the table's altitude nodes (smooth
    /// there but for the profiles' 50 m kinks; far below the table's own
    /// interpolation error).
    fn slant_column(&self, h_m: f64, mu: f64) -> Profiles {
        const GAUSS: [(f64, f64); 4] = [
            (-0.861_136_311_594_053, 0.347_854_845_137_454),
            (-0.339_981_043_584_856, 0.652_145_154_862_546),
            (0.339_981_043_584_856, 0.652_145_154_862_546),
            (0.861_136_311_594_053, 0.347_854_845_137_454),
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
        // Between the table's altitude nodes above the start.
        let mut boundaries: Vec<f64> = (0..ALTITUDE_NODES)
            .map(|i| self.node_altitude_m(i))
            .filter(|&h| h > h_m)
            .collect();
        boundaries.push(self.top_m);
        for h1 in boundaries {
            let s1 = s_at(h1).max(s0);
            // Pieces at most 10 km long: near the horizontal one altitude
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
        let (k, fz) = self.cosine_cell(mu);
        let i = (a as usize).min(ALTITUDE_NODES - 2);
        Cell {
            i,
            k,
            fa: (a - i as f64).clamp(0.0, 1.0),
            fz,
            da_dr: 0.5 * self.altitude_per_root / root_h,
            dz_dmu: self.cosine_coordinate_scale * COSINE_SCALE * inv * inv,
        }
    }

    /// The cosine cell of `mu` and the fraction across it.
    pub(super) fn cosine_cell(&self, mu: f64) -> (usize, f64) {
        let mu = mu.clamp(0.0, 1.0);
        let inv = 1.0 / (mu + COSINE_SCALE);
        let z = self.cosine_coordinate_scale * mu * inv;
        let k = (z as usize).min(COSINE_NODES - 2);
        (k, (z - k as f64).clamp(0.0, 1.0))
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

    /// g̃ and its partial derivatives in the node coordinates (a, z) at
    /// `cell`: a bicubic Hermite patch on the corners' values and slopes, so
    /// g̃ is C¹ and its slopes — the control of a near-horizontal ray is
    /// mostly g̃'s slope in μ — are right to second order in the spacing.
    fn slant_factor_derivatives(&self, cell: &Cell) -> [(f64, f64, f64); PROFILES] {
        let corners = self.corners(cell);
        let (ha, da) = hermite(cell.fa);
        let (hz, dz) = hermite(cell.fz);
        std::array::from_fn(|p| {
            let (mut g, mut g_a, mut g_z) = (0.0, 0.0, 0.0);
            // Corner (u, v): u across altitude, v along the cosine.
            for (c, node) in corners.iter().enumerate() {
                let (u, v) = (c / 2, c % 2);
                let values = [
                    node[p],
                    node[PROFILES + p],
                    node[2 * PROFILES + p],
                    node[3 * PROFILES + p],
                ];
                // Weights of value, z-slope, a-slope and cross slope.
                let term = |wa: &[f64; 4], wz: &[f64; 4]| {
                    wa[2 * u] * wz[2 * v] * values[0]
                        + wa[2 * u] * wz[2 * v + 1] * values[1]
                        + wa[2 * u + 1] * wz[2 * v] * values[2]
                        + wa[2 * u + 1] * wz[2 * v + 1] * values[3]
                };
                g += term(&ha, &hz);
                g_a += term(&da, &hz);
                g_z += term(&ha, &dz);
            }
            (g, g_a, g_z)
        })
    }

    /// g̃ at `cell` (see [`Self::slant_factor_derivatives`]; the same
    /// weights without the derivatives, for the look-ups at a ray's start).
    fn slant_factor(&self, cell: &Cell) -> Profiles {
        let corners = self.corners(cell);
        let (ha, _) = hermite(cell.fa);
        let (hz, _) = hermite(cell.fz);
        let mut g = [0.0; PROFILES];
        for (c, node) in corners.iter().enumerate() {
            let (u, v) = (c / 2, c % 2);
            let w = [
                ha[2 * u] * hz[2 * v],
                ha[2 * u] * hz[2 * v + 1],
                ha[2 * u + 1] * hz[2 * v],
                ha[2 * u + 1] * hz[2 * v + 1],
            ];
            for (p, g) in g.iter_mut().enumerate() {
                *g += w[0] * node[p]
                    + w[1] * node[PROFILES + p]
                    + w[2] * node[2 * PROFILES + p]
                    + w[3] * node[3 * PROFILES + p];
            }
        }
        g
    }

    /// C̃ from radius `radius_m` along cosine `mu` ≥ 0 to the top.
    pub(super) fn columns_up(&self, radius_m: f64, mu: f64) -> Profiles {
        let vertical = self.vertical(radius_m - self.planet_radius_m);
        let slant = self.slant_factor(&self.cell(radius_m, mu));
        std::array::from_fn(|p| vertical[p] / slant[p])
    }

    /// The bound on |profile − control| over the stretch of a ray from
    /// (radius, cosine) `start` to `end`: the bound of its lowest point's
    /// cell — its perigee if it passes one, else its lower end — as every
    /// point of the stretch lies at or above that in altitude and |μ|, and
    /// the table holds the largest over the cells at or above each.
    pub(super) fn stretch_bound(&self, (r0, mu0): (f64, f64), (r1, mu1): (f64, f64)) -> Profiles {
        let (radius_m, mu) = if mu0 < 0.0 && mu1 > 0.0 {
            (perigee_m(r0, mu0), 0.0)
        } else if r1 < r0 {
            (r1, mu1.abs())
        } else {
            (r0, mu0.abs())
        };
        let cell = self.cell(radius_m, mu);
        self.bound[cell.i * COSINE_NODES + cell.k]
    }

    /// The control σ_c = −dC̃/ds per profile at radius `radius_m`, cosine
    /// `mu` (the same for −μ), by the chain rule through the node coordinates.
    pub(super) fn control(&self, radius_m: f64, mu: f64) -> Profiles {
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
        // The profiles' kinks (where the tabulated data change slope), at
        // which the residual peaks between the grid points.
        let kinks: Vec<f64> = (1..self.nodes.len() - 1)
            .filter(|&i| {
                let (a, b, c) = (&self.nodes[i - 1], &self.nodes[i], &self.nodes[i + 1]);
                (0..PROFILES).any(|p| (a[p] - 2.0 * b[p] + c[p]).abs() > KINK * b[p].abs())
            })
            .map(|i| i as f64 * NODE_STEP_M)
            .collect();
        let cell_bound = |n: usize| {
            let (i, k) = (n / COSINE_NODES, n % COSINE_NODES);
            if i + 1 == ALTITUDE_NODES || k + 1 == COSINE_NODES {
                return [0.0; PROFILES];
            }
            let (a0, a1) = (self.node_altitude_m(i), self.node_altitude_m(i + 1));
            let (m0, m1) = (self.node_cosine(k), self.node_cosine(k + 1));
            let grid =
                (0..BOUND_POINTS).map(|u| a0 + (a1 - a0) * u as f64 / (BOUND_POINTS - 1) as f64);
            let first = kinks.partition_point(|&h| h < a0);
            let last = kinks.partition_point(|&h| h <= a1);
            let mut worst = [0.0_f64; PROFILES];
            for h in grid.chain(kinks[first..last].iter().copied()) {
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
}

/// The table's look-ups at one fixed start point — the observer, from which
/// every splat's ray to the camera starts ([`super::circles`]): C̃ there
/// and the residual bound of its cell as functions of the direction cosine
/// alone. At a fixed altitude the bicubic patch of g̃ is a cubic Hermite
/// spline in the cosine coordinate whose node values and slopes are
/// collapsed across altitude once, here: a look-up reads two nodes, not
/// four, and computes no altitude coordinate. It is the same polynomial
/// as `ColumnTable::columns_up` at the start (to rounding), so C̃'s
/// difference along a ray stays the control's integral.
pub struct FixedStart {
    pub(super) position_m: DVec3,
    pub(super) radius_m: f64,
    /// The exact vertical column above the start.
    vertical: Profiles,
    /// Per cosine node: g̃ and its slope along the cosine nodes at the
    /// start's altitude.
    nodes: Vec<[Profiles; 2]>,
    /// Per cosine node: the residual bound of the start's cell.
    pub(super) bound: Vec<Profiles>,
}

impl FixedStart {
    /// The look-ups of `table` at `position_m` (inside the atmosphere).
    pub fn new(table: &ColumnTable, position_m: DVec3) -> Self {
        let radius_m = position_m.length();
        let cell = table.cell(radius_m, 0.0);
        let (ha, _) = hermite(cell.fa);
        let nodes = (0..COSINE_NODES)
            .map(|k| {
                let (below, above) = (
                    &table.table[cell.i * COSINE_NODES + k],
                    &table.table[(cell.i + 1) * COSINE_NODES + k],
                );
                // The altitude weights of slant_factor's corners (u = 0, 1):
                // value and cosine slope each take value + altitude slope,
                // and cosine slope + cross slope, of the two altitude nodes.
                let collapse = |offset: usize| {
                    std::array::from_fn(|p| {
                        ha[0] * below[offset + p]
                            + ha[1] * below[offset + 2 * PROFILES + p]
                            + ha[2] * above[offset + p]
                            + ha[3] * above[offset + 2 * PROFILES + p]
                    })
                };
                [collapse(0), collapse(PROFILES)]
            })
            .collect();
        Self {
            position_m,
            radius_m,
            vertical: table.vertical(radius_m - table.planet_radius_m),
            nodes,
            bound: (0..COSINE_NODES)
                .map(|k| table.bound[cell.i * COSINE_NODES + k])
                .collect(),
        }
    }

    /// The start.
    pub fn position_m(&self) -> DVec3 {
        self.position_m
    }

    /// C̃ from the start along a direction in cosine cell `k` at fraction `fz`.
    pub(super) fn columns(&self, k: usize, fz: f64) -> Profiles {
        let (hz, _) = hermite(fz);
        let (lo, hi) = (&self.nodes[k], &self.nodes[k + 1]);
        std::array::from_fn(|p| {
            let g = hz[0] * lo[0][p] + hz[1] * lo[1][p] + hz[2] * hi[0][p] + hz[3] * hi[1][p];
            self.vertical[p] / g
        })
    }
}

/// C̃ at the points of one ray, whose perigee term (for a ray that starts
/// downward) is computed once, so that it cancels exactly between two points.
pub(super) struct RayColumns<'a> {
    table: &'a ColumnTable,
    /// C̃ from the perigee along the horizontal, if the ray starts downward.
    chord: Option<Profiles>,
}

impl<'a> RayColumns<'a> {
    /// The ray through radius `radius_m` with cosine `mu` there.
    pub(super) fn new(table: &'a ColumnTable, radius_m: f64, mu: f64) -> Self {
        let chord = (mu < 0.0).then(|| table.columns_up(perigee_m(radius_m, mu), 0.0));
        Self { table, chord }
    }

    /// C̃ at the ray's point at radius `radius_m`, cosine `mu`.
    pub(super) fn at(&self, radius_m: f64, mu: f64) -> Profiles {
        match self.chord {
            Some(chord) if mu < 0.0 => {
                let behind = self.table.columns_up(radius_m, -mu);
                std::array::from_fn(|p| 2.0 * chord[p] - behind[p])
            }
            _ => self.table.columns_up(radius_m, mu.max(0.0)),
        }
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::render::medium::{Medium, Span};
    use crate::rng::Rng;

    fn medium() -> Medium {
        Medium::new(&Atmosphere::new(AtmosphereParams::default()))
    }

    pub(crate) fn table(medium: &Medium) -> &ColumnTable {
        medium.column_table()
    }

    /// Rays that leave the atmosphere without meeting the ground: from the
    /// ground at several elevations down to the horizontal, from altitude
    /// through a perigee, from the mesosphere and from space.
    pub(crate) fn rays(medium: &Medium) -> Vec<(DVec3, DVec3, Span)> {
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
    pub(crate) fn at_start(
        table: &ColumnTable,
        origin: DVec3,
        dir: DVec3,
        span: Span,
    ) -> (Profiles, Profiles) {
        let at = |t: f64| {
            let x = origin + dir * t;
            (x.length(), x.dot(dir) / x.length())
        };
        let (start, end) = (at(span.t_enter), at(span.t_exit));
        (
            RayColumns::new(table, start.0, start.1).at(start.0, start.1),
            table.stretch_bound(start, end),
        )
    }

    /// Where `origin + t·dir` crosses radius `radius_m`, inside `span`.
    pub(crate) fn crossings(origin: DVec3, dir: DVec3, span: Span, radius_m: f64) -> Vec<f64> {
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

    /// ∫ control ds along `origin + t·dir` over `[t0, t1]`: Gauss–Legendre
    /// (4 points) on 500 pieces between the altitude nodes' crossings, where
    /// the control is smooth (1e-8 relative).
    pub(crate) fn control_integral(
        table: &ColumnTable,
        origin: DVec3,
        dir: DVec3,
        t0: f64,
        t1: f64,
    ) -> Profiles {
        const GAUSS: [(f64, f64); 4] = [
            (-0.861_136_311_594_053, 0.347_854_845_137_454),
            (-0.339_981_043_584_856, 0.652_145_154_862_546),
            (0.339_981_043_584_856, 0.652_145_154_862_546),
            (0.861_136_311_594_053, 0.347_854_845_137_454),
        ];
        let stretch = Span {
            t_enter: t0,
            t_exit: t1,
            hits_ground: false,
        };
        let mut breaks = vec![t0, t1];
        for i in 1..ALTITUDE_NODES - 1 {
            let radius_m = table.planet_radius_m + table.node_altitude_m(i);
            breaks.extend(crossings(origin, dir, stretch, radius_m));
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
        integral
    }

    #[test]
    fn controls_integrate_to_the_tabulated_columns() {
        // What makes the estimator unbiased: the control's integral from a
        // point to the top is the column the estimate is given.
        let medium = medium();
        let table = table(&medium);
        for (origin, dir, span) in rays(&medium) {
            let integral = control_integral(table, origin, dir, span.t_enter, span.t_exit);
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
    fn controls_integrate_to_column_differences_on_any_stretch() {
        // The segments' case: over a stretch [t0, t1] of a ray the control
        // integrates to C̃(t0) − C̃(t1) with one perigee term per ray — on
        // stretches that end in the air, pass their perigee or end on the
        // ground (1e-7 of the larger column: the quadrature breaks at the
        // altitude nodes only, and a slanted ray crosses cosine nodes too,
        // where the control's slope jumps; a table error would show at
        // 1e-3).
        let medium = medium();
        let table = table(&medium);
        let mut cases = 0;
        for (altitude_m, el_deg) in [
            (2.0, 3.0),
            (2.0, -0.5),
            (2.0, -10.0),
            (3_000.0, -1.0),
            (12_345.0, -2.0),
            (12_345.0, -3.5),
            (60_000.0, -7.0),
            (400_000.0, -19.7),
        ] {
            let el = f64::to_radians(el_deg);
            let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + altitude_m);
            let dir = DVec3::new(el.cos(), 0.0, el.sin());
            let span = medium.span(origin, dir).unwrap();
            let start = origin + dir * span.t_enter;
            let ray = RayColumns::new(table, start.length(), start.dot(dir) / start.length());
            let at = |t: f64| {
                let x = origin + dir * t;
                ray.at(x.length(), x.dot(dir) / x.length())
            };
            let length = span.t_exit - span.t_enter;
            for (f0, f1) in [(0.0, 1.0), (0.0, 0.3), (0.2, 0.7), (0.6, 1.0)] {
                let (t0, t1) = (span.t_enter + f0 * length, span.t_enter + f1 * length);
                let integral = control_integral(table, origin, dir, t0, t1);
                let (c0, c1) = (at(t0), at(t1));
                for p in 0..PROFILES {
                    let scale = c0[p].abs().max(c1[p].abs());
                    assert!(
                        (integral[p] - (c0[p] - c1[p])).abs() <= 1e-7 * scale,
                        "{el_deg}° from {altitude_m} m over {f0}–{f1}, profile {p}: \
                         ∫ control {} vs C̃ difference {}",
                        integral[p],
                        c0[p] - c1[p]
                    );
                }
                cases += 1;
            }
        }
        assert_eq!(cases, 32);
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
        // 2000 points along each ray: |profile − control| ≤ the ray's bound,
        // on the rays above and 600 more from random altitudes (0–90 km) and
        // elevations (−10° to 90°).
        let medium = medium();
        let table = table(&medium);
        let mut rng = Rng::new(4, 4);
        let random = (0..600).filter_map(|_| {
            let altitude_m = 90_000.0 * rng.uniform().powi(2);
            let el = (-10.0 + 100.0 * rng.uniform()).to_radians();
            let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + altitude_m);
            let dir = DVec3::new(el.cos(), 0.0, el.sin());
            let span = medium.span(origin, dir)?;
            (!span.hits_ground).then_some((origin, dir, span))
        });
        let all: Vec<_> = rays(&medium).into_iter().chain(random).collect();
        for (origin, dir, span) in all {
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
