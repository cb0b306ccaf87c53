//! Cells of directions about a point in the atmosphere, for tables indexed
//! by direction.
//!
//! The atmosphere is spherically symmetric and the sun fixes a mirror plane,
//! so anything seen from a point depends on the direction only through its
//! zenith angle and its azimuth from the sun's vertical plane (0–180°). The
//! zenith bands use square-root spacing away from the local horizon on both
//! sides (fine where ray geometry changes fastest), so no cell straddles the
//! horizon: the rays of one cell all hit the ground or all miss it.

use glam::DVec3;

/// A grid of direction cells: zenith bands × azimuth sectors (0–180°).
#[derive(Clone, Copy, Debug)]
pub struct Grid {
    /// Zenith bands.
    pub zenith: usize,
    /// Azimuth sectors.
    pub azimuth: usize,
}

impl Grid {
    /// Cells in all.
    pub fn cells(self) -> usize {
        self.zenith * self.azimuth
    }
}

/// Band coordinate s ∈ [0, 1] of a cosine `mu` with the horizon at
/// `mu_horizon` (s = ½) and the last direction of interest at `mu_top`
/// (s = 1; below the horizon s runs to 0 at the nadir); `None` above `mu_top`.
pub fn band_coordinate(mu: f64, mu_horizon: f64, mu_top: f64) -> Option<f64> {
    if mu >= mu_horizon {
        if mu > mu_top {
            return None;
        }
        Some(0.5 + 0.5 * ((mu - mu_horizon) / (mu_top - mu_horizon).max(1e-300)).sqrt())
    } else {
        Some(0.5 - 0.5 * ((mu_horizon - mu) / (1.0 + mu_horizon).max(1e-300)).sqrt())
    }
}

/// The cosine at band coordinate `s` (inverse of [`band_coordinate`]).
pub fn band_cosine(s: f64, mu_horizon: f64, mu_top: f64) -> f64 {
    if s >= 0.5 {
        mu_horizon + (2.0 * s - 1.0).powi(2) * (mu_top - mu_horizon)
    } else {
        mu_horizon - (1.0 - 2.0 * s).powi(2) * (1.0 + mu_horizon)
    }
}

/// Cosine of the zenith angle of the geometric horizon at radius `r_m`.
pub fn horizon_cosine(planet_radius_m: f64, r_m: f64) -> f64 {
    -(1.0 - (planet_radius_m / r_m).powi(2)).max(0.0).sqrt()
}

/// The axes of a point's local frame: its zenith, the horizontal direction
/// toward the sun's azimuth (any horizontal direction with the sun at the
/// zenith or nadir) and the one across it.
#[derive(Clone, Copy, Debug)]
pub struct LocalAxes {
    /// The local vertical.
    pub up: DVec3,
    /// Horizontal, toward the sun's azimuth.
    pub toward_sun: DVec3,
    /// Horizontal, across the sun's azimuth.
    pub across_sun: DVec3,
}

impl LocalAxes {
    /// The axes at `x` (m, planet-centred) for the sun along `sun_direction`.
    pub fn new(x: DVec3, sun_direction: DVec3) -> Self {
        let up = x.normalize();
        let horizontal = sun_direction - up * sun_direction.dot(up);
        let toward_sun = if horizontal.length_squared() > 1e-18 {
            horizontal.normalize()
        } else {
            orthonormal_basis(up).0
        };
        Self {
            up,
            toward_sun,
            across_sun: up.cross(toward_sun),
        }
    }

    /// The direction at zenith cosine `mu` and azimuth `phi` (rad) from the
    /// sun's vertical plane.
    pub fn direction(&self, mu: f64, phi: f64) -> DVec3 {
        let sin = (1.0 - mu * mu).max(0.0).sqrt();
        (self.toward_sun * (sin * phi.cos()) + self.across_sun * (sin * phi.sin()) + self.up * mu)
            .normalize()
    }
}

/// The local frame of a point: its axes ([`LocalAxes`]) and the horizon's
/// cosines.
#[derive(Clone, Copy, Debug)]
pub struct ViewFrame {
    axes: LocalAxes,
    /// Cosine of the view zenith angle of the planet's horizon.
    mu_horizon: f64,
    /// Largest view-zenith cosine whose ray meets the atmosphere (1 inside
    /// it; the atmosphere's limb for a point above it).
    mu_top: f64,
}

impl ViewFrame {
    /// The frame at `origin_m` (m, planet-centred) for the sun along
    /// `sun_direction`.
    pub fn new(
        planet_radius_m: f64,
        top_radius_m: f64,
        origin_m: DVec3,
        sun_direction: DVec3,
    ) -> Self {
        let r = origin_m.length();
        Self {
            axes: LocalAxes::new(origin_m, sun_direction),
            mu_horizon: horizon_cosine(planet_radius_m, r),
            mu_top: if r > top_radius_m {
                horizon_cosine(top_radius_m, r)
            } else {
                1.0
            },
        }
    }

    /// Cell of `dir` in `grid`, or `None` above the atmosphere's limb.
    pub fn cell_index(&self, grid: Grid, dir: DVec3) -> Option<usize> {
        let LocalAxes {
            up,
            toward_sun,
            across_sun,
        } = self.axes;
        let mu = dir.dot(up).clamp(-1.0, 1.0);
        let s = band_coordinate(mu, self.mu_horizon, self.mu_top)?;
        let i = ((s * grid.zenith as f64) as usize).min(grid.zenith - 1);
        let phi = dir.dot(across_sun).abs().atan2(dir.dot(toward_sun));
        let k = ((phi / std::f64::consts::PI * grid.azimuth as f64) as usize).min(grid.azimuth - 1);
        Some(i * grid.azimuth + k)
    }

    /// Cosine bounds (low, high) and azimuth bounds (rad, 0–π) of a cell.
    fn cell_bounds(&self, grid: Grid, index: usize) -> ((f64, f64), (f64, f64)) {
        let (i, k) = (index / grid.azimuth, index % grid.azimuth);
        let mu = |s: f64| band_cosine(s, self.mu_horizon, self.mu_top);
        let (s0, s1) = (
            i as f64 / grid.zenith as f64,
            (i + 1) as f64 / grid.zenith as f64,
        );
        let sector = std::f64::consts::PI / grid.azimuth as f64;
        (
            (mu(s0), mu(s1)),
            (k as f64 * sector, (k + 1) as f64 * sector),
        )
    }

    /// The central direction of cell `index` (central in band coordinate).
    pub fn cell_direction(&self, grid: Grid, index: usize) -> DVec3 {
        let (i, k) = (index / grid.azimuth, index % grid.azimuth);
        let s = (i as f64 + 0.5) / grid.zenith as f64;
        let mu = band_cosine(s, self.mu_horizon, self.mu_top);
        let phi = (k as f64 + 0.5) / grid.azimuth as f64 * std::f64::consts::PI;
        self.axes.direction(mu, phi)
    }

    /// Solid angle of cell `index`, sr (both mirror halves).
    pub fn cell_solid_angle(&self, grid: Grid, index: usize) -> f64 {
        let ((mu0, mu1), (phi0, phi1)) = self.cell_bounds(grid, index);
        2.0 * (mu1 - mu0).abs() * (phi1 - phi0)
    }

    /// A direction uniform in solid angle over cell `index` (either mirror
    /// half) for uniform variates `u`.
    pub fn sample_cell(&self, grid: Grid, index: usize, u: [f64; 3]) -> DVec3 {
        let ((mu0, mu1), (phi0, phi1)) = self.cell_bounds(grid, index);
        let mu = mu0 + (mu1 - mu0) * u[0];
        let phi = phi0 + (phi1 - phi0) * u[1];
        self.axes.direction(mu, if u[2] < 0.5 { phi } else { -phi })
    }
}

/// Two unit vectors completing `n` to a right-handed orthonormal basis
/// (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
pub fn orthonormal_basis(n: DVec3) -> (DVec3, DVec3) {
    let sign = 1f64.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        DVec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        DVec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cells_tile_the_sphere_and_round_trip() {
        let planet = 6_371_000.0;
        let grid = Grid {
            zenith: 24,
            azimuth: 8,
        };
        for (altitude_m, top_m) in [
            (2.0, 100_000.0),
            (40_000.0, 100_000.0),
            (400_000.0, 100_000.0),
        ] {
            let origin = DVec3::new(0.3, -0.2, 0.9).normalize() * (planet + altitude_m);
            let sun = DVec3::new(-0.5, 0.4, 0.1).normalize();
            let frame = ViewFrame::new(planet, planet + top_m, origin, sun);
            let total: f64 = (0..grid.cells())
                .map(|i| frame.cell_solid_angle(grid, i))
                .sum();
            // Inside the atmosphere the cells tile the sphere; above it, the
            // part of it that meets the atmosphere.
            let expected = 2.0 * std::f64::consts::PI * (1.0 + frame.mu_top);
            assert!(
                (total - expected).abs() < 1e-9 * expected,
                "{total} vs {expected}"
            );
            for index in 0..grid.cells() {
                let centre = frame.cell_direction(grid, index);
                assert_eq!(frame.cell_index(grid, centre), Some(index));
                let sampled = frame.sample_cell(grid, index, [0.3, 0.7, 0.9]);
                assert_eq!(frame.cell_index(grid, sampled), Some(index));
            }
        }
    }

    #[test]
    fn band_coordinate_inverts_band_cosine() {
        for &(mu_h, mu_top) in &[(-0.1, 1.0), (0.0, 1.0), (-0.3, -0.2)] {
            for k in 0..=20 {
                let s = f64::from(k) / 20.0;
                let mu = band_cosine(s, mu_h, mu_top);
                let back = band_coordinate(mu, mu_h, mu_top).unwrap();
                assert!((back - s).abs() < 1e-9, "s {s} → mu {mu} → {back}");
            }
        }
    }
}

/// Cells of points by where they lie relative to the sun: a spherically
/// symmetric atmosphere makes everything seen from a point depend on its
/// altitude and the sun's zenith angle there only, so tables of what a point
/// sees ([`super::guide`], [`super::control`]) are indexed by those two.
/// Altitude cells use square-root spacing (dense low down, where the air
/// is), solar-zenith cells the band coordinate about the local horizon
/// (dense where the sun grazes and the shadow moves).
#[derive(Clone, Copy, Debug)]
pub struct SunCells {
    planet_radius_m: f64,
    top_radius_m: f64,
    sun_direction: DVec3,
    /// A unit vector across the sun's direction, to place central points.
    across_sun: DVec3,
    /// Cells in altitude and in solar zenith.
    pub altitude: usize,
    /// See `altitude`: cells in solar zenith.
    pub sun_zenith: usize,
}

impl SunCells {
    /// Cells over the atmosphere of a planet of `planet_radius_m`.
    pub fn new(
        planet_radius_m: f64,
        top_radius_m: f64,
        sun_direction: DVec3,
        (altitude, sun_zenith): (usize, usize),
    ) -> Self {
        Self {
            planet_radius_m,
            top_radius_m,
            sun_direction,
            across_sun: orthonormal_basis(sun_direction).0,
            altitude,
            sun_zenith,
        }
    }

    /// Number of cells.
    pub fn count(&self) -> usize {
        self.altitude * self.sun_zenith
    }

    /// Index of cell (altitude `i`, solar zenith `k`).
    pub fn index(&self, i: usize, k: usize) -> usize {
        i * self.sun_zenith + k
    }

    /// The coordinates of `x` (m, planet-centred), each in [0, 1]: altitude
    /// and solar zenith.
    fn coordinates(&self, x: DVec3) -> (f64, f64) {
        let r = x.length();
        let top_m = self.top_radius_m - self.planet_radius_m;
        let a = ((r - self.planet_radius_m) / top_m).clamp(0.0, 1.0).sqrt();
        let mu_sun = (x.dot(self.sun_direction) / r).clamp(-1.0, 1.0);
        let s =
            band_coordinate(mu_sun, horizon_cosine(self.planet_radius_m, r), 1.0).unwrap_or(1.0);
        (a, s)
    }

    /// The cell that holds `x`: (altitude, solar zenith).
    pub fn containing(&self, x: DVec3) -> (usize, usize) {
        let (a, s) = self.coordinates(x);
        (
            ((a * self.altitude as f64) as usize).min(self.altitude - 1),
            ((s * self.sun_zenith as f64) as usize).min(self.sun_zenith - 1),
        )
    }

    /// The lower of the two neighbouring cell centres about `x` in altitude
    /// and in solar zenith, each with the fraction toward the upper one
    /// (for bilinear interpolation between cell centres).
    pub fn about(&self, x: DVec3) -> ((usize, f64), (usize, f64)) {
        let (a, s) = self.coordinates(x);
        (cell_split(a, self.altitude), cell_split(s, self.sun_zenith))
    }

    /// The central point (m, planet-centred) of cell (altitude `i`, solar
    /// zenith `k`).
    pub fn centre(&self, i: usize, k: usize) -> DVec3 {
        let top_m = self.top_radius_m - self.planet_radius_m;
        let altitude_m = top_m * ((i as f64 + 0.5) / self.altitude as f64).powi(2);
        let r = self.planet_radius_m + altitude_m;
        let s = (k as f64 + 0.5) / self.sun_zenith as f64;
        let mu_sun = band_cosine(s, horizon_cosine(self.planet_radius_m, r), 1.0);
        (self.sun_direction * mu_sun + self.across_sun * (1.0 - mu_sun * mu_sun).max(0.0).sqrt())
            * r
    }
}

/// The lower of two neighbouring cell centres about coordinate `u` ∈ [0, 1]
/// over `cells` cells, and the fraction toward the upper one.
fn cell_split(u: f64, cells: usize) -> (usize, f64) {
    let c = (u * cells as f64 - 0.5).clamp(0.0, (cells - 1) as f64);
    let i = (c as usize).min(cells - 2);
    (i, c - i as f64)
}
