//! Where the skylight at a point comes from: a table of the once-scattered
//! light arriving there by direction, to guide scattering directions, and the
//! distance densities of rays leaving such points.
//!
//! At twilight the multiply scattered light carries most of the radiance and
//! nearly all the variance: a point in the Earth's shadow is lit by a small
//! patch of sky — within some 30° of the hidden sun's azimuth, just above its
//! horizon — which the phase function finds rarely (single paths then weigh
//! 250–1000× the mean; `BENCHMARKS.md`). The light arriving at a point x from
//! direction ω is mostly sunlight scattered once along ω,
//!
//! L₁(x, ω) = ∫ T(x, y) σ_s(y) p(ω·ω_sun) E_sun T_sun(y) dt, y = x + tω
//! (plus, for rays that meet the ground, its direct reflection),
//!
//! and depends on x only through its altitude and the sun's zenith angle
//! there (spherical symmetry), and on ω only through its cell of
//! [`super::directions`]. [`SkyGuide`] tabulates it on first use per
//! (altitude, solar zenith) cell, from one representative point, and the
//! integrator draws directions from it (mixed with the phase function, one-
//! sample MIS) and distances along the following segment from the same
//! representative rays' [`InScatterDistribution`]s. Like every density of the
//! renderer it only shapes the sampling: the estimator stays unbiased
//! whatever the table's error.
//!
//! Its total over directions, [`SkyGuide::skylight`], is the importance of
//! the integrator's roulette and splitting (`splitting`).
//!
//! Used through the options `sky_guide`, `shadow_samples`,
//! `sunlight_samples` and `splitting` of [`super::IntegratorOptions`].
//! `sunlight_samples` is on by default with the sun low (the regime table, [`crate::plan::regime`]),
//! where its segment estimates, through this guide's cached densities, win
//! at equal time (`BENCHMARKS.md`); `sky_guide` draws a quarter
//! of the directions in the shadow from the table by default, 0.35 with the
//! sun below the horizon (second-order light at twilight ~25× cheaper per
//! path; the heavier tails of higher orders stay, so the whole image gains
//! 1.1–1.35× at equal time, `BENCHMARKS.md`); `shadow_samples` is off.

use std::sync::OnceLock;

use glam::DVec3;

use super::directions::{Grid, SunCells, ViewFrame};
use super::medium::{Medium, Span};
use super::sunlight::{CachedRayDensity, DensityBuilder, DensitySlots, InScatterDistribution};
use crate::rng::Rng;

/// Altitude cells (square-root spacing: dense low down, where the air is).
const ALTITUDE_CELLS: usize = 12;
/// Solar-zenith cells, in the band coordinate of [`super::directions`] about
/// the local horizon (dense where the sun grazes and the shadow moves).
const SUN_ZENITH_CELLS: usize = 32;
/// Direction cells of one point's table.
const DIRECTION_GRID: Grid = Grid {
    zenith: 24,
    azimuth: 8,
};

/// Incoming once-scattered light by direction, per (altitude, solar zenith)
/// cell, built on first use.
pub struct SkyGuide {
    planet_radius_m: f64,
    top_radius_m: f64,
    sun_direction: DVec3,
    layout: SunCells,
    builder: DensityBuilder,
    cells: Vec<OnceLock<PointCell>>,
}

/// The table of one (altitude, solar zenith) cell.
struct PointCell {
    /// The representative point, m, planet-centred, and its frame.
    origin_m: DVec3,
    frame: ViewFrame,
    /// Cumulative probability over the direction cells (∝ L₁ × solid angle);
    /// empty where no sunlight reaches any direction.
    cdf: Vec<f64>,
    /// ∫ L₁ dω over the sphere per unit irradiance (the table's total;
    /// dimensionless, sr⁻¹ × sr).
    fluence: f64,
    /// Distance densities of the representative rays, built on first use.
    rays: DensitySlots,
}

impl SkyGuide {
    /// An empty guide for `medium` with the sun along `sun_direction`.
    pub fn new(medium: &Medium, sun_direction: DVec3) -> Self {
        Self {
            planet_radius_m: medium.planet_radius_m,
            top_radius_m: medium.top_radius_m,
            sun_direction,
            layout: SunCells::new(
                medium.planet_radius_m,
                medium.top_radius_m,
                sun_direction,
                (ALTITUDE_CELLS, SUN_ZENITH_CELLS),
            ),
            builder: DensityBuilder::new(medium, sun_direction),
            cells: (0..ALTITUDE_CELLS * SUN_ZENITH_CELLS)
                .map(|_| OnceLock::new())
                .collect(),
        }
    }

    /// Whether the planet hides the sun's centre from `x` (m, planet-centred).
    /// By day only there does the table guide directions: at sunlit points
    /// the phase function about the sun (the integrator's sun lobe) follows
    /// the once-scattered light's sharp aureole better than the table's
    /// cells can (`BENCHMARKS.md`: guiding everywhere loses 1.2–1.6× by
    /// day), while in the shadow the light comes from the sunlit air above
    /// the horizon, which no phase function about a fixed axis finds. With
    /// the sun low, sunlit points see that glow too and are guided as well
    /// (`sky_guide_sunlit` of [`super::IntegratorOptions`]).
    pub fn shadowed(&self, x: DVec3) -> bool {
        // cos θ_sun < cos θ_horizon = −√(1 − R²/r²), squared: with d = x·ŝ,
        // d < 0 and d² > r² − R² (no root or division on this per-vertex test).
        let d = x.dot(self.sun_direction);
        d < 0.0 && d * d > x.length_squared() - self.planet_radius_m * self.planet_radius_m
    }

    /// The guide at point `x` (m, planet-centred, inside the atmosphere).
    pub fn at(&self, medium: &Medium, x: DVec3) -> GuideAt<'_> {
        let (i, k) = self.layout.containing(x);
        let cell = self.cell(medium, i, k);
        GuideAt {
            guide: self,
            cell,
            frame: ViewFrame::new(
                self.planet_radius_m,
                self.top_radius_m,
                x,
                self.sun_direction,
            ),
            chosen: None,
        }
    }

    /// The table of cell (altitude `i`, solar zenith `k`), from its central point.
    fn build(&self, medium: &Medium, i: usize, k: usize) -> PointCell {
        let origin_m = self.layout.centre(i, k);
        let frame = ViewFrame::new(
            self.planet_radius_m,
            self.top_radius_m,
            origin_m,
            self.sun_direction,
        );
        let rays = DensitySlots::new(DIRECTION_GRID.cells());
        let mut cdf = Vec::with_capacity(DIRECTION_GRID.cells() + 1);
        cdf.push(0.0);
        for d in 0..DIRECTION_GRID.cells() {
            let dir = frame.cell_direction(DIRECTION_GRID, d);
            let light = self.incoming_light(
                medium,
                origin_m,
                dir,
                rays.get(d, || self.builder.build(medium, origin_m, dir, None)),
            );
            let mass = light * frame.cell_solid_angle(DIRECTION_GRID, d);
            cdf.push(cdf[d] + if mass.is_finite() { mass } else { 0.0 });
        }
        let fluence = cdf[DIRECTION_GRID.cells()];
        if fluence > 0.0 {
            for c in &mut cdf {
                *c /= fluence;
            }
        } else {
            cdf.clear();
        }
        PointCell {
            origin_m,
            frame,
            cdf,
            fluence,
            rays,
        }
    }

    /// The cell of (altitude `i`, solar zenith `k`), built on first use.
    fn cell(&self, medium: &Medium, i: usize, k: usize) -> &PointCell {
        self.cells[self.layout.index(i, k)].get_or_init(|| self.build(medium, i, k))
    }

    /// Approximate mean once-scattered radiance arriving at `x` per unit
    /// irradiance, sr⁻¹ (the tables' fluence over 4π, interpolated bilinearly
    /// between cell centres).
    pub fn skylight(&self, medium: &Medium, x: DVec3) -> f64 {
        let ((i, fa), (k, fs)) = self.layout.about(x);
        let f = |i: usize, k: usize| self.cell(medium, i, k).fluence;
        let lo = f(i, k) * (1.0 - fs) + f(i, k + 1) * fs;
        let hi = f(i + 1, k) * (1.0 - fs) + f(i + 1, k + 1) * fs;
        (lo * (1.0 - fa) + hi * fa) / (4.0 * std::f64::consts::PI)
    }

    /// Approximate once-scattered light per unit irradiance arriving at
    /// `origin_m` from `dir` (whose density is `ray`), sr⁻¹: the sky's, plus
    /// the ground's direct reflection where the ray meets it.
    fn incoming_light(
        &self,
        medium: &Medium,
        origin_m: DVec3,
        dir: DVec3,
        ray: Option<&InScatterDistribution>,
    ) -> f64 {
        let Some(ray) = ray else {
            return 0.0;
        };
        let mut light = ray.sunlit();
        if let Some(span) = medium.span(origin_m, dir).filter(|s| s.hits_ground) {
            let ground = origin_m + dir * span.t_exit;
            let cos = ground.normalize().dot(self.sun_direction);
            if cos > 0.0 {
                // The largest albedo over wavelength: the guide is a density.
                light += ray.transmitted() * medium.ground_albedo_max / std::f64::consts::PI
                    * cos
                    * self.builder.sun_transmittance(medium, ground);
            }
        }
        light
    }
}

/// The guide at one point: its cell's table seen in the point's own frame.
pub struct GuideAt<'a> {
    guide: &'a SkyGuide,
    cell: &'a PointCell,
    frame: ViewFrame,
    /// The direction the path left along and its cell ([`Self::choose`]):
    /// its density and its segment's both need the cell.
    chosen: Option<(DVec3, Option<usize>)>,
}

impl GuideAt<'_> {
    /// Record `dir` as the direction the path leaves along, with its cell
    /// where [`Self::sample`] drew it (`cell`), else looked up here once.
    pub fn choose(&mut self, dir: DVec3, cell: Option<usize>) {
        let cell = cell.or_else(|| self.frame.cell_index(DIRECTION_GRID, dir));
        self.chosen = Some((dir, cell));
    }

    /// The direction cell of `dir`, or `None` above the atmosphere's limb.
    fn cell_of(&self, dir: DVec3) -> Option<usize> {
        match self.chosen {
            Some((chosen, cell)) if chosen == dir => cell,
            _ => self.frame.cell_index(DIRECTION_GRID, dir),
        }
    }

    /// Whether the table has any light to guide toward.
    pub fn guides(&self) -> bool {
        !self.cell.cdf.is_empty()
    }

    /// A direction ∝ the tabulated light (piecewise constant per cell,
    /// uniform in solid angle within one); only where [`Self::guides`].
    /// Returns the direction and its cell.
    pub fn sample(&self, rng: &mut Rng) -> (DVec3, usize) {
        let u = rng.uniform();
        let cells = DIRECTION_GRID.cells();
        let d = self.cell.cdf[1..]
            .partition_point(|&c| c <= u)
            .min(cells - 1);
        let dir = self.frame.sample_cell(
            DIRECTION_GRID,
            d,
            [rng.uniform(), rng.uniform(), rng.uniform()],
        );
        (dir, d)
    }

    /// The density of [`Self::sample`] at `dir`, per sr.
    pub fn pdf(&self, dir: DVec3) -> f64 {
        let Some(d) = self.cell_of(dir) else {
            return 0.0;
        };
        if self.cell.cdf.is_empty() {
            return 0.0;
        }
        let p = self.cell.cdf[d + 1] - self.cell.cdf[d];
        let omega = self.frame.cell_solid_angle(DIRECTION_GRID, d);
        if omega > 0.0 {
            p / omega
        } else {
            0.0
        }
    }

    /// The distance density for the ray from this point along `dir` over
    /// `span`: its direction cell's representative ray, mapped onto it.
    pub fn density(&self, medium: &Medium, dir: DVec3, span: Span) -> CachedRayDensity<'_> {
        let cell = self.cell;
        let ray = self.cell_of(dir).and_then(|d| {
            cell.rays.get(d, || {
                let central = cell.frame.cell_direction(DIRECTION_GRID, d);
                self.guide
                    .builder
                    .build(medium, cell.origin_m, central, None)
            })
        });
        CachedRayDensity::new(ray, span)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::render::direction_from_az_el;

    /// ∫ f(ω) dω over the sphere by a midpoint rule in (cos θ, φ).
    fn sphere_quadrature(f: impl Fn(DVec3) -> f64) -> f64 {
        let (n_mu, n_phi) = (2000, 400);
        let d_mu = 2.0 / f64::from(n_mu);
        let d_phi = 2.0 * std::f64::consts::PI / f64::from(n_phi);
        let mut sum = 0.0;
        for i in 0..n_mu {
            let mu = -1.0 + (f64::from(i) + 0.5) * d_mu;
            let sin = (1.0 - mu * mu).sqrt();
            for k in 0..n_phi {
                let phi = (f64::from(k) + 0.5) * d_phi;
                sum += f(DVec3::new(sin * phi.cos(), sin * phi.sin(), mu)) * d_mu * d_phi;
            }
        }
        sum
    }

    #[test]
    fn guided_directions_follow_their_density() {
        // At a sunlit point by day, a shadowed one at twilight and one high
        // up: the density integrates to one over the sphere, and each
        // direction cell receives its share of samples (within 5 binomial
        // standard deviations), at the density the sampler reports.
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let radius = medium.planet_radius_m;
        for (sun, x) in [
            (
                direction_from_az_el(180.0, 30.0),
                DVec3::new(0.1, 0.2, 1.0).normalize() * (radius + 800.0),
            ),
            (
                direction_from_az_el(270.0, -4.0),
                DVec3::new(0.0, 0.0, radius + 3_000.0),
            ),
            (
                direction_from_az_el(60.0, 10.0),
                DVec3::new(0.3, 0.0, 1.0).normalize() * (radius + 45_000.0),
            ),
        ] {
            let guide = SkyGuide::new(&medium, sun);
            let at = guide.at(&medium, x);
            assert!(at.guides());
            let total = sphere_quadrature(|w| at.pdf(w));
            assert!((total - 1.0).abs() < 2e-3, "∫ p dω = {total}");
            let cells = DIRECTION_GRID.cells();
            let mut counts = vec![0u32; cells];
            let n = 200_000;
            let mut rng = Rng::new(3, 1);
            let mut memo = guide.at(&medium, x);
            for _ in 0..n {
                let (w, drawn) = at.sample(&mut rng);
                let d = at.frame.cell_index(DIRECTION_GRID, w).unwrap();
                assert_eq!(
                    d, drawn,
                    "a sampled direction lies in the cell it was drawn from"
                );
                let p = at.cell.cdf[d + 1] - at.cell.cdf[d];
                let density = p / at.frame.cell_solid_angle(DIRECTION_GRID, d);
                assert!((at.pdf(w) / density - 1.0).abs() < 1e-12);
                // The chosen direction's cell, remembered, reads the same.
                memo.choose(w, Some(drawn));
                assert_eq!(memo.pdf(w).to_bits(), at.pdf(w).to_bits());
                counts[d] += 1;
            }
            for (d, &count) in counts.iter().enumerate() {
                let p = at.cell.cdf[d + 1] - at.cell.cdf[d];
                let expected = p * f64::from(n);
                let sigma = (expected * (1.0 - p)).sqrt();
                assert!(
                    (f64::from(count) - expected).abs() <= 5.0 * sigma + 1.0,
                    "cell {d}: {count} samples, expected {expected:.1}"
                );
            }
        }
    }

    #[test]
    fn skylight_interpolates_the_cells_and_rises_out_of_the_shadow() {
        // Twilight, sun 4° below the horizon toward −x.
        let atmosphere = Atmosphere::new(AtmosphereParams::default());
        let medium = Medium::new(&atmosphere);
        let radius = medium.planet_radius_m;
        let top_m = medium.top_radius_m - radius;
        let sun = direction_from_az_el(270.0, -4.0);
        let guide = SkyGuide::new(&medium, sun);
        let above = |altitude_m: f64| DVec3::Z * (radius + altitude_m);
        // At a cell's centre point the value is that cell's fluence / 4π.
        for (i, k) in [(3, 28), (6, 20), (9, 30)] {
            let cell = guide.cell(&medium, i, k);
            let expected = cell.fluence / (4.0 * std::f64::consts::PI);
            assert!(expected > 0.0, "cell ({i}, {k}) sees no light");
            let got = guide.skylight(&medium, cell.origin_m);
            assert!(
                (got / expected - 1.0).abs() < 1e-9,
                "cell ({i}, {k}): {got} vs {expected}"
            );
        }
        // Continuous across a boundary between altitude cells (a = 4/12).
        let boundary_m = top_m * (4.0 / ALTITUDE_CELLS as f64).powi(2);
        let (below, over) = (
            guide.skylight(&medium, above(boundary_m - 1.0)),
            guide.skylight(&medium, above(boundary_m + 1.0)),
        );
        assert!((over / below - 1.0).abs() < 1e-3, "{below} vs {over}");
        // Above the observer the shadow thins with height: the light grows
        // several-fold from 0.5 to 40 km, and at 20 km the sun's side
        // (nearer the sunlit air) sees more than the opposite side.
        let low = guide.skylight(&medium, above(500.0));
        let high = guide.skylight(&medium, above(40_000.0));
        assert!(low > 0.0 && high > 5.0 * low, "{low} → {high}");
        let tilt = |x: f64| DVec3::new(x, 0.0, 1.0).normalize() * (radius + 20_000.0);
        let (sun_side, far_side) = (
            guide.skylight(&medium, tilt(-0.02)),
            guide.skylight(&medium, tilt(0.02)),
        );
        assert!(sun_side > 1.5 * far_side, "{sun_side} vs {far_side}");
    }
}
