//! A control variate for the diffuse light: a table of the once-scattered
//! light arriving at a point, in spherical harmonics, whose phase-function
//! integral is known exactly.
//!
//! At a scattering point x the light a path goes on to estimate is
//! J(x, ω) = ∫ p(ω·ω') L(x, ω') dω', L the diffuse radiance arriving from ω'
//! (all but the sun's direct beam, which next-event estimation counts).
//! With a fixed function A(x, ω'),
//!
//! J = ∫ p A dω' + ∫ p (L − A) dω',
//!
//! the first term exact (below) and the second estimated by the path as
//! before, its continuation now carrying L − A. Whatever A, the estimate
//! stays unbiased; only its variance depends on how well A follows L. With
//! the sun low over the horizon the light a point sees has sharp features —
//! the aureole about the sun, cut by the bright band along the horizon —
//! which the sampled directions find unevenly; they are single scattering's,
//! so A is the once-scattered light (plus the ground's direct reflection):
//! at sunset (2°) it leaves 0.6–0.7× the variance, as much as a table of all
//! orders did (`BENCHMARKS.md`).
//!
//! A is expanded in real spherical harmonics Y_lm about the point's zenith,
//! azimuth measured from the sun's vertical plane (the field is mirror-
//! symmetric about it, so only the cos mφ terms appear), l ≤ [`L_MAX`]. By
//! the Funk–Hecke theorem ∫ p(ω·ω') Y_lm(ω') dω' = k_l Y_lm(ω), with k_l the
//! phase function's Legendre moments (Rayleigh: 1, 0, k₂; Henyey–Greenstein:
//! g^l; see [`crate::physics`]), so ∫ p A dω' costs one evaluation of the
//! basis. The coefficients depend on x only through its altitude and the
//! sun's zenith angle there (spherical symmetry), as in [`super::guide`];
//! each (altitude, solar zenith) cell is projected on first use, per unit
//! irradiance at [`NODES`] wavelengths, from next-event estimates along
//! stratified directions from its central point. A point takes one of the
//! four cells about it and, per lane, one of the two nodes about its
//! wavelength, drawn with their interpolation weights ([`RadianceTable::pick`]).

use std::f64::consts::PI;
use std::sync::OnceLock;

use glam::DVec3;

use super::directions::{LocalAxes, SunCells};
use super::guide::SkyGuide;
use super::medium::Medium;

/// Highest degree of the expansion.
pub const L_MAX: usize = 8;
/// Coefficients per expansion: (l, m) with 0 ≤ m ≤ l ≤ [`L_MAX`].
pub const COEFFICIENTS: usize = (L_MAX + 1) * (L_MAX + 2) / 2;
/// Altitude cells (square-root spacing, as the guide's).
const ALTITUDE_CELLS: usize = 12;
/// Solar-zenith cells (band coordinate about the local horizon).
const SUN_ZENITH_CELLS: usize = 32;
/// Wavelength nodes over the colour-matching range.
pub const NODES: usize = 8;

/// One expansion per wavelength node, per unit solar irradiance (sr⁻¹).
pub type CellCoefficients = [[f64; COEFFICIENTS]; NODES];

/// What fills a [`RadianceTable`]'s cells on first use: the once-scattered
/// light arriving at a cell's central point, projected on the basis. The
/// render's tables supply it ([`crate::render::tables`]); the table itself
/// knows nothing of how light is estimated.
pub trait CellProjection: Send + Sync {
    /// The expansions of `table`'s cell (altitude `i`, solar zenith `k`) in
    /// `medium`, with the sky guide `guide` where the render has one.
    fn project(
        &self,
        medium: &Medium,
        guide: Option<&SkyGuide>,
        table: &RadianceTable,
        i: usize,
        k: usize,
    ) -> CellCoefficients;
}

/// The table of expansions per (altitude, solar zenith) cell.
pub struct RadianceTable {
    sun_direction: DVec3,
    projection: Box<dyn CellProjection>,
    layout: SunCells,
    first_nm: f64,
    step_nm: f64,
    cells: Vec<OnceLock<CellCoefficients>>,
}

/// The local frame of a point ([`LocalAxes`]), in which the basis is laid.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    axes: LocalAxes,
}

impl Frame {
    /// The frame at point `x` for the sun along `sun_direction`.
    pub fn new(x: DVec3, sun_direction: DVec3) -> Self {
        Self {
            axes: LocalAxes::new(x, sun_direction),
        }
    }

    /// The basis at direction `dir` (unit).
    pub fn basis(&self, dir: DVec3) -> [f64; COEFFICIENTS] {
        let LocalAxes { up, toward_sun, .. } = self.axes;
        let cos_theta = dir.dot(up).clamp(-1.0, 1.0);
        let horizontal = dir - up * cos_theta;
        let h = horizontal.length();
        let cos_phi = if h > 1e-12 {
            (horizontal.dot(toward_sun) / h).clamp(-1.0, 1.0)
        } else {
            1.0
        };
        basis(cos_theta, cos_phi)
    }

    /// The direction at zenith cosine `cos_theta` and azimuth `phi` (rad)
    /// from the sun's vertical plane.
    pub fn direction(&self, cos_theta: f64, phi: f64) -> DVec3 {
        self.axes.direction(cos_theta, phi)
    }
}

/// Index of (l, m) in an expansion.
pub const fn index(l: usize, m: usize) -> usize {
    l * (l + 1) / 2 + m
}

/// The orthonormal real spherical harmonics K_lm P_l^m(cos θ) cos mφ
/// (× √2 for m > 0) at zenith cosine `cos_theta` and azimuth cosine
/// `cos_phi`; the sin mφ ones vanish for a field symmetric in φ.
pub fn basis(cos_theta: f64, cos_phi: f64) -> [f64; COEFFICIENTS] {
    let k = Recurrence::get();
    let x = cos_theta;
    let s = (1.0 - x * x).max(0.0).sqrt();
    let mut y = [0.0; COEFFICIENTS];
    // cos mφ by Chebyshev's recurrence.
    let mut cos_m = [1.0; L_MAX + 1];
    cos_m[1] = cos_phi;
    for m in 2..=L_MAX {
        cos_m[m] = 2.0 * cos_phi * cos_m[m - 1] - cos_m[m - 2];
    }
    // Associated Legendre functions (without the Condon–Shortley phase):
    // P_m^m = (2m−1)!! s^m, P_{m+1}^m = x (2m+1) P_m^m,
    // P_l^m = ((2l−1) x P_{l−1}^m − (l+m−1) P_{l−2}^m) / (l−m).
    let mut pmm = 1.0;
    for m in 0..=L_MAX {
        if m > 0 {
            pmm *= (2 * m - 1) as f64 * s;
        }
        let mut p_prev = pmm;
        y[index(m, m)] = k.norm[index(m, m)] * pmm * cos_m[m];
        if m == L_MAX {
            break;
        }
        let mut p = x * (2 * m + 1) as f64 * pmm;
        y[index(m + 1, m)] = k.norm[index(m + 1, m)] * p * cos_m[m];
        for l in m + 2..=L_MAX {
            let i = index(l, m);
            (p_prev, p) = (p, k.a[i] * x * p - k.b[i] * p_prev);
            y[i] = k.norm[i] * p * cos_m[m];
        }
    }
    y
}

/// The basis's constants: K_lm and the recurrence's (2l−1)/(l−m) and
/// (l+m−1)/(l−m).
struct Recurrence {
    norm: [f64; COEFFICIENTS],
    a: [f64; COEFFICIENTS],
    b: [f64; COEFFICIENTS],
}

impl Recurrence {
    fn get() -> &'static Self {
        static CONSTANTS: OnceLock<Recurrence> = OnceLock::new();
        CONSTANTS.get_or_init(|| {
            let mut k = Self {
                norm: [0.0; COEFFICIENTS],
                a: [0.0; COEFFICIENTS],
                b: [0.0; COEFFICIENTS],
            };
            for l in 0..=L_MAX {
                for m in 0..=l {
                    let i = index(l, m);
                    k.norm[i] = normalisation(l, m);
                    if l >= m + 2 {
                        k.a[i] = (2 * l - 1) as f64 / (l - m) as f64;
                        k.b[i] = (l + m - 1) as f64 / (l - m) as f64;
                    }
                }
            }
            k
        })
    }
}

/// K_lm = √((2l+1)/(4π) (l−m)!/(l+m)!), × √2 for m > 0.
fn normalisation(l: usize, m: usize) -> f64 {
    let mut ratio = 1.0;
    for k in (l - m + 1)..=(l + m) {
        ratio /= k as f64;
    }
    let k = ((2 * l + 1) as f64 / (4.0 * PI) * ratio).sqrt();
    if m > 0 {
        k * std::f64::consts::SQRT_2
    } else {
        k
    }
}

/// One expansion: coefficients per unit irradiance at one wavelength node.
pub type Expansion = [f64; COEFFICIENTS];

impl RadianceTable {
    /// An empty table for an atmosphere between `planet_radius_m` and
    /// `top_radius_m`, the sun along `sun_direction`, wavelength nodes over
    /// `range_nm`, its cells filled by `projection` on first use.
    pub fn new(
        planet_radius_m: f64,
        top_radius_m: f64,
        sun_direction: DVec3,
        (from_nm, to_nm): (f64, f64),
        projection: Box<dyn CellProjection>,
    ) -> Self {
        Self {
            sun_direction,
            projection,
            layout: SunCells::new(
                planet_radius_m,
                top_radius_m,
                sun_direction,
                (ALTITUDE_CELLS, SUN_ZENITH_CELLS),
            ),
            first_nm: from_nm,
            step_nm: (to_nm - from_nm) / (NODES - 1) as f64,
            cells: (0..ALTITUDE_CELLS * SUN_ZENITH_CELLS)
                .map(|_| OnceLock::new())
                .collect(),
        }
    }

    /// The wavelength of node `n`, nm.
    pub fn node_nm(&self, n: usize) -> f64 {
        self.first_nm + n as f64 * self.step_nm
    }

    /// The central point (m, planet-centred) of cell (altitude `i`, solar
    /// zenith `k`).
    pub fn cell_point(&self, i: usize, k: usize) -> DVec3 {
        self.layout.centre(i, k)
    }

    /// The frame at `x`.
    pub fn frame(&self, x: DVec3) -> Frame {
        Frame::new(x, self.sun_direction)
    }

    /// The expansions at `x` for the lanes' `wavelengths_nm`: one cell of
    /// the four about `x`, drawn with its bilinear weight by uniform
    /// `u_cell`, and for each lane one of its two neighbouring wavelength
    /// nodes, drawn with its linear weight by uniform `u_node`. A drawn A is
    /// as good a control as any fixed one (the estimate is unbiased for
    /// each draw, and the draws are independent of the path); drawing
    /// saves the interpolation's eight expansions per lane. Missing cells
    /// are projected in `medium` (with `guide`) by the table's
    /// [`CellProjection`].
    pub fn pick<const N: usize>(
        &self,
        x: DVec3,
        wavelengths_nm: &[f64; N],
        (u_cell, u_node): (f64, f64),
        (medium, guide): (&Medium, Option<&SkyGuide>),
    ) -> Picked<'_, N> {
        let ((i, fa), (k, fs)) = self.layout.about(x);
        // Altitude first (u < 1 − fa: lower), then solar zenith, from one
        // uniform.
        let (i, u) = if u_cell < 1.0 - fa {
            (i, u_cell / (1.0 - fa))
        } else {
            (i + 1, (u_cell - (1.0 - fa)) / fa)
        };
        let k = if u < 1.0 - fs { k } else { k + 1 };
        let cell = self.cells[self.layout.index(i, k)]
            .get_or_init(|| self.projection.project(medium, guide, self, i, k));
        let nodes = wavelengths_nm.map(|nm| {
            let u = ((nm - self.first_nm) / self.step_nm).clamp(0.0, (NODES - 1) as f64);
            let n = (u as usize).min(NODES - 2);
            if u_node < u - n as f64 {
                n + 1
            } else {
                n
            }
        });
        Picked { cell, nodes }
    }
}

/// A cell and one wavelength node per lane, drawn by [`RadianceTable::pick`].
#[derive(Clone, Copy, Debug)]
pub struct Picked<'t, const N: usize> {
    cell: &'t CellCoefficients,
    nodes: [usize; N],
}

impl<const N: usize> Picked<'_, N> {
    /// The expansion for lane `lane`, per unit irradiance.
    fn expansion(&self, lane: usize) -> &Expansion {
        &self.cell[self.nodes[lane]]
    }

    /// Σ_m a_lm y_lm per degree l (rows) and lane (columns) for the basis
    /// values `y`. The lanes' sums run side by side: one sum of 45 terms
    /// per lane after another is a chain of dependent additions, which cost
    /// the control a third of its time at sunset.
    pub fn degrees(&self, y: &Expansion) -> [[f64; N]; L_MAX + 1] {
        let expansions: [&Expansion; N] = std::array::from_fn(|j| self.expansion(j));
        let mut degrees = [[0.0; N]; L_MAX + 1];
        for (l, degree) in degrees.iter_mut().enumerate() {
            for i in index(l, 0)..=index(l, l) {
                for (d, a) in degree.iter_mut().zip(&expansions) {
                    *d += a[i] * y[i];
                }
            }
        }
        degrees
    }

    /// Σ_lm a_lm y_lm per lane: the expansions at the basis values `y`.
    pub fn evaluate(&self, y: &Expansion) -> [f64; N] {
        let degrees = self.degrees(y);
        std::array::from_fn(|j| degrees.iter().map(|d| d[j]).sum())
    }
}

/// Legendre moments χ_l = 2π ∫ f(μ) P_l(μ) dμ, l = 0..=[`L_MAX`], of the
/// Lambertian kernel f(μ) = max(μ, 0)/π (the reflected radiance per unit
/// albedo is ∫ f(n·ω) L(ω) dω): by the Funk–Hecke theorem the ground
/// reflects Σ_l χ_l Σ_m a_lm Y_lm(n) of an expansion. Closed form
/// (Ramamoorthi and Hanrahan 2001, eq. 8, their Â_l = π χ_l): χ_0 = 1,
/// χ_1 = 2/3, zero for odd l > 1, and for even l ≥ 2
/// χ_l = 2 (−1)^{l/2−1} / ((l + 2)(l − 1)) · l! / (2^l ((l/2)!)²).
pub fn lambert_moments() -> [f64; L_MAX + 1] {
    std::array::from_fn(|l| match l {
        0 => 1.0,
        1 => 2.0 / 3.0,
        _ if l % 2 == 1 => 0.0,
        _ => {
            let half = l / 2;
            let sign = if half % 2 == 1 { 1.0 } else { -1.0 };
            // l! / (2^l (l/2)!²) = C(l, l/2) / 2^l.
            let central = (1..=half).fold(1.0, |c, k| c * (half + k) as f64 / k as f64);
            2.0 * sign / (((l + 2) * (l - 1)) as f64) * central / 2f64.powi(l as i32)
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_lambert_moments_are_the_clamped_cosine_integrals() {
        // 2 ∫₀¹ μ P_l(μ) dμ by the midpoint rule, P_l by Bonnet's recursion.
        let n = 200_000_u32;
        let moments = lambert_moments();
        for (l, &chi) in moments.iter().enumerate() {
            let mut sum = 0.0;
            for i in 0..n {
                let mu = (f64::from(i) + 0.5) / f64::from(n);
                let (mut p0, mut p1) = (1.0, mu);
                let p = if l == 0 {
                    1.0
                } else {
                    for k in 1..l {
                        let p2 = ((2 * k + 1) as f64 * mu * p1 - k as f64 * p0) / (k + 1) as f64;
                        (p0, p1) = (p1, p2);
                    }
                    p1
                };
                sum += 2.0 * mu * p / f64::from(n);
            }
            assert!((sum - chi).abs() < 1e-9, "l = {l}: {sum} vs {chi}");
        }
        assert!((moments[4] + 1.0 / 24.0).abs() < 1e-15);
    }

    #[test]
    fn the_basis_is_orthonormal_over_the_symmetric_sphere() {
        // ∫ Y_a Y_b dω = δ_ab, by the midpoint rule in cos θ and φ ∈ [0, 2π).
        let (nt, np) = (4000_u32, 64_u32);
        let mut gram = [[0.0; COEFFICIENTS]; COEFFICIENTS];
        for it in 0..nt {
            let x = -1.0 + 2.0 * (f64::from(it) + 0.5) / f64::from(nt);
            for ip in 0..np {
                let phi = 2.0 * PI * (f64::from(ip) + 0.5) / f64::from(np);
                let y = basis(x, phi.cos());
                let w = 2.0 / f64::from(nt) * 2.0 * PI / f64::from(np);
                for (row, ya) in gram.iter_mut().zip(&y) {
                    for (g, yb) in row.iter_mut().zip(&y) {
                        *g += w * ya * yb;
                    }
                }
            }
        }
        for (a, row) in gram.iter().enumerate() {
            for (b, g) in row.iter().enumerate() {
                let expected = if a == b { 1.0 } else { 0.0 };
                assert!((g - expected).abs() < 1e-3, "{a} {b}: {g}");
            }
        }
    }

    #[test]
    fn phase_integrals_of_the_basis_follow_funk_hecke() {
        type Phase = (Box<dyn Fn(f64) -> f64>, [f64; L_MAX + 1]);
        // ∫ p(ω·ω') Y_lm(ω') dω' = k_l Y_lm(ω), by the midpoint rule over ω'
        // (fine in the polar angle about ω, where p peaks), for Rayleigh
        // with depolarisation and both aerosol models at g = 0.7.
        use crate::physics::{aerosol::PhaseModel, rayleigh};
        let gamma = 0.014;
        let mut k_rayleigh = [0.0; L_MAX + 1];
        k_rayleigh[0] = 1.0;
        k_rayleigh[2] = rayleigh::phase_legendre_2(gamma);
        let phases: [Phase; 3] = [
            (Box::new(move |mu| rayleigh::phase(mu, gamma)), k_rayleigh),
            (
                Box::new(|mu| PhaseModel::HenyeyGreenstein.eval(mu, 0.7)),
                PhaseModel::HenyeyGreenstein.legendre_moments(0.7),
            ),
            (
                Box::new(|mu| PhaseModel::CornetteShanks.eval(mu, 0.7)),
                PhaseModel::CornetteShanks.legendre_moments(0.7),
            ),
        ];
        let frame = Frame::new(DVec3::Z, DVec3::new(0.6, 0.0, 0.8));
        for omega in [
            DVec3::new(0.3, -0.5, 0.81).normalize(),
            DVec3::new(-0.9, 0.1, -0.2).normalize(),
        ] {
            let (t, b) = super::super::directions::orthonormal_basis(omega);
            let expected = frame.basis(omega);
            for (phase, k) in &phases {
                let (nt, np) = (4000_u32, 256_u32);
                let mut integral = [0.0; COEFFICIENTS];
                for it in 0..nt {
                    // Polar angle about ω, midpoint in θ (dense near ω).
                    let theta = PI * (f64::from(it) + 0.5) / f64::from(nt);
                    let (sin_t, cos_t) = theta.sin_cos();
                    let w_theta = sin_t * PI / f64::from(nt) * phase(cos_t);
                    for ip in 0..np {
                        let phi = 2.0 * PI * (f64::from(ip) + 0.5) / f64::from(np);
                        let dir = omega * cos_t + (t * phi.cos() + b * phi.sin()) * sin_t;
                        let y = frame.basis(dir);
                        let w = w_theta * 2.0 * PI / f64::from(np);
                        for c in 0..COEFFICIENTS {
                            integral[c] += w * y[c];
                        }
                    }
                }
                for (l, k) in k.iter().enumerate() {
                    for m in 0..=l {
                        let i = index(l, m);
                        assert!(
                            (integral[i] - k * expected[i]).abs() < 2e-4,
                            "l {l} m {m}: {} vs {}",
                            integral[i],
                            k * expected[i]
                        );
                    }
                }
            }
        }
    }
}
