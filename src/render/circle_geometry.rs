//! The geometry of splatting along circles of symmetry ([`super::circles`]):
//! the frame of the sun's axis, the arcs of a circle the camera sees, and
//! where along an arc a path's splats go.

use std::f64::consts::PI;

use glam::DVec3;

use super::medium::Lanes;

use super::camera::Camera;

/// Positions along a circle per point at the bench's 256×128 equirect
/// map: the phase-drawn positions follow the light the paths found, and
/// the paths cost more than the positions (their transmittance a table's
/// look-up, `super::observer_depths`). More pay the larger the image,
/// whose circles cross more pixels ([`splats_per_walk`]).
pub const SPLATS_PER_WALK: usize = 96;
/// The most positions per point, at 1024×512 and finer.
pub const MAX_SPLATS_PER_WALK: usize = 192;
/// Pixels per radian (√ of the camera's pixels per steradian at its
/// centre) of a 256×128 equirect map, where [`SPLATS_PER_WALK`] pay.
const BASE_PIXELS_PER_RADIAN: f64 = 256.0 / (2.0 * PI);

/// The camera's pixels per steradian at its image's centre (zero where no
/// view passes through it).
fn centre_pixels_per_sr(camera: &Camera) -> f64 {
    let (width, height) = camera.size();
    camera
        .direction(0.5 * width, 0.5 * height)
        .map_or(0.0, |d| camera.pixels_per_sr(d))
}

/// Positions per point for `camera`: [`SPLATS_PER_WALK`] times the square
/// root of its pixels per radian over a 256×128 equirect map's, a multiple
/// of 8 up to [`MAX_SPLATS_PER_WALK`]. A circle crosses pixels in
/// proportion to the resolution, and positions cost a fraction of the
/// path they share: with their transmittance from a table, 128 or 192
/// positions cost more than they save at 256×128 (1.00–1.16× the
/// variance × time, and the rows' noise more correlated), while at
/// 1024×512, twice the 96's square-root law, 192 gave 0.88× and 128
/// 0.91–0.94× (`BENCHMARKS.md`, the circle splatting row).
pub fn splats_per_walk(camera: &Camera) -> usize {
    let per_sr = centre_pixels_per_sr(camera);
    let scale = (per_sr.max(0.0).sqrt() / BASE_PIXELS_PER_RADIAN).sqrt();
    let count = (SPLATS_PER_WALK as f64 * scale / 8.0).round() as usize * 8;
    count.clamp(SPLATS_PER_WALK, MAX_SPLATS_PER_WALK)
}

/// The air's positions per point for `camera` ([`super::circles`]): a
/// third more than [`splats_per_walk`] (the ground's count is half of
/// that), a multiple of 8 up to [`MAX_SPLATS_PER_WALK`]. Most of them take
/// their light from the phase cells' centres (`AtCentres`) and cost less
/// than a position with its own look-ups (`BENCHMARKS.md`, the row on the
/// positions' control).
pub fn air_splats_per_walk(camera: &Camera) -> usize {
    (splats_per_walk(camera) * 4 / 3)
        .div_ceil(8)
        .saturating_mul(8)
        .min(MAX_SPLATS_PER_WALK)
}

/// The phase cells' factor for a position at offset `to` from the
/// observer ([`PixelWeight::at`]): where its view falls on a pixel that
/// takes splats, the camera's pixels per steradian there over those at the
/// image's centre, at most a cap (the circle splatter's, as its point
/// table's importance); elsewhere 1.
///
/// Why: with positions drawn at density q per steradian of view, a pixel
/// of solid angle Ω_p gets about N q_p Ω_p of a walk's N splats, each
/// f_p / (N q_p) (f_p its light per steradian), and the variance its mean
/// takes from them is about f_p² / (N q_p Ω_p). Summed over the pixels at
/// a fixed Σ_p q_p Ω_p = 1, that is least (Lagrange: f_p² / (N q_p² Ω_p)
/// = λ Ω_p) for q_p ∝ f_p / Ω_p, the light times the pixels per
/// steradian. The phase cells follow the light (the Cauchy density's 1/t²,
/// the phase functions); this factor adds the pixels, so that an equirect
/// map's rows near the poles (1/cos el pixels per steradian) get positions
/// in proportion to their pixels, not their solid angle. Off the image the
/// factor stays 1: drawing a perspective view's positions into its frame
/// (a factor of 0 outside) cost more time than it took out
/// (`BENCHMARKS.md`, the row on the positions' pixel density).
#[derive(Clone, Copy, Debug)]
pub(super) struct PixelWeight {
    centre_per_sr: f64,
    max: f64,
}

impl PixelWeight {
    /// For `camera`, capped at `max`.
    pub(super) fn new(camera: &Camera, max: f64) -> Self {
        Self {
            centre_per_sr: centre_pixels_per_sr(camera),
            max,
        }
    }

    /// The factor toward `to` (an offset from the observer).
    pub(super) fn at(&self, camera: &Camera, to: DVec3) -> f64 {
        let dir = to.normalize();
        if camera.splat_position(dir).is_none() {
            return 1.0;
        }
        (camera.pixels_per_sr(dir) / self.centre_per_sr).min(self.max)
    }
}

/// Of them, drawn before the path's direction, whatever it turns out to
/// be (a floor under the positions' density): from the Cauchy density
/// about the observer's nearest point, and uniformly. The rest are drawn
/// after it: from the Cauchy density times the phase function toward the
/// observer at each position ([`PhaseCells`]).
pub(super) const CAUCHY_SPLATS: usize = 4;
pub(super) const UNIFORM_SPLATS: usize = 4;
pub(super) const FIRST_SPLATS: usize = CAUCHY_SPLATS + UNIFORM_SPLATS;
/// Cells of the phase-weighted density, uniform in the Cauchy quantile.
pub(super) const PHASE_CELLS: usize = 32;
/// Share of the phase-weighted density spread evenly over its cells (a
/// floor under the phase function's shape).
pub(super) const PHASE_FLOOR: f64 = 0.1;

/// The frame of the scene's symmetry: the sun's axis through the Earth's
/// centre, and the observer's place about it.
#[derive(Clone, Copy, Debug)]
pub(super) struct SunAxis {
    pub(super) observer_m: DVec3,
    pub(super) sun: DVec3,
    /// Unit vectors normal to the axis; the observer lies at ψ = 0.
    pub(super) e1: DVec3,
    pub(super) e2: DVec3,
    /// The observer's radius and angle from the sun's direction.
    pub(super) r0_m: f64,
    pub(super) theta0: f64,
    pub(super) ground_m: f64,
    pub(super) top_m: f64,
}

impl SunAxis {
    /// `None` with the sun at the observer's zenith or nadir, where every
    /// circle through the observer's neighbourhood degenerates.
    pub(super) fn new(observer_m: DVec3, sun: DVec3, ground_m: f64, top_m: f64) -> Option<Self> {
        let r0_m = observer_m.length();
        let up = observer_m / r0_m;
        let normal = up - up.dot(sun) * sun;
        if normal.length() < 1e-9 {
            return None;
        }
        let e1 = normal.normalize();
        Some(Self {
            observer_m,
            sun,
            e1,
            e2: sun.cross(e1),
            r0_m,
            theta0: up.dot(sun).clamp(-1.0, 1.0).acos(),
            ground_m,
            top_m,
        })
    }

    pub(super) fn point(&self, r_m: f64, theta: f64, psi: f64) -> DVec3 {
        self.circle(r_m, theta).point(psi.sin_cos())
    }

    /// The circle (r, θ) about the axis.
    pub(super) fn circle(&self, r_m: f64, theta: f64) -> Circle<'_> {
        self.circle_at(r_m, (theta.sin(), theta.cos()))
    }

    /// The circle of radius `r_m` at the angle θ of `(sin θ, cos θ)` from
    /// the axis.
    pub(super) fn circle_at(&self, r_m: f64, (sin_theta, cos_theta): (f64, f64)) -> Circle<'_> {
        Circle {
            axis: self,
            r_m,
            sin_theta,
            cos_theta,
        }
    }

    /// `v` turned by `psi` about the axis.
    #[cfg(test)]
    pub(super) fn rotate(&self, v: DVec3, psi: f64) -> DVec3 {
        self.rotate_by(v, psi.sin_cos())
    }

    /// `v` turned about the axis by the angle ψ of `(sin ψ, cos ψ)`.
    fn rotate_by(&self, v: DVec3, (sin_psi, cos_psi): (f64, f64)) -> DVec3 {
        let (a, b) = (v.dot(self.e1), v.dot(self.e2));
        (a * cos_psi - b * sin_psi) * self.e1
            + (a * sin_psi + b * cos_psi) * self.e2
            + v.dot(self.sun) * self.sun
    }

    /// Largest angle at the Earth's centre between the observer and a
    /// point of radius `r_m` that the ground does not hide.
    pub(super) fn horizon_angle(&self, r_m: f64) -> f64 {
        (self.ground_m / self.r0_m).min(1.0).acos() + (self.ground_m / r_m).min(1.0).acos()
    }

    /// Half the visible arc (|ψ| ≤ it) of the circle (r, θ): the points
    /// within [`Self::horizon_angle`] of the observer. 0: none.
    pub(super) fn half_arc(&self, r_m: f64, theta: f64) -> f64 {
        let sines = self.theta0.sin() * theta.sin();
        if sines <= 0.0 {
            return 0.0;
        }
        let cos_min = (self.horizon_angle(r_m).cos() - self.theta0.cos() * theta.cos()) / sines;
        if cos_min >= 1.0 {
            0.0
        } else if cos_min <= -1.0 {
            PI
        } else {
            cos_min.acos()
        }
    }

    /// (r, θ) at polar (ρ, φ) about the observer in the plane
    /// (r − r₀, r₀ (θ − θ₀)); area there is r₀ dr dθ.
    pub(super) fn at_polar(&self, rho_m: f64, phi: f64) -> (f64, f64) {
        let (sin_phi, cos_phi) = phi.sin_cos();
        (
            self.r0_m + rho_m * sin_phi,
            self.theta0 + rho_m * cos_phi / self.r0_m,
        )
    }

    /// The farthest visible circle's ρ.
    pub(super) fn rho_max(&self) -> f64 {
        let dr = (self.top_m - self.r0_m)
            .abs()
            .max((self.r0_m - self.ground_m).abs());
        let dx = self.r0_m * self.horizon_angle(self.top_m);
        dr.hypot(dx)
    }
}

/// One circle (r, θ) about a [`SunAxis`], the sine and cosine of its θ
/// taken once: a walk places a hundred positions on it.
pub(super) struct Circle<'a> {
    axis: &'a SunAxis,
    r_m: f64,
    /// sin θ (the circle's radius over r).
    pub(super) sin_theta: f64,
    cos_theta: f64,
}

impl Circle<'_> {
    /// The point at the angle ψ of `(sin ψ, cos ψ)` about the axis.
    pub(super) fn point(&self, (sin_psi, cos_psi): (f64, f64)) -> DVec3 {
        let (e1, e2, sun) = (self.axis.e1, self.axis.e2, self.axis.sun);
        self.r_m * (self.sin_theta * (cos_psi * e1 + sin_psi * e2) + self.cos_theta * sun)
    }

    /// The offset of position `psi` from the observer, and the direction
    /// from the observer to it turned back by −ψ (into the frame of ψ = 0,
    /// where the walk's directions are drawn): one sine and cosine serve
    /// both, sin(−ψ) = −sin ψ.
    pub(super) fn place(&self, psi: f64) -> (DVec3, DVec3) {
        let (sin_psi, cos_psi) = psi.sin_cos();
        let to = self.point((sin_psi, cos_psi)) - self.axis.observer_m;
        (to, self.axis.rotate_by(to.normalize(), (-sin_psi, cos_psi)))
    }
}

/// Where the circle (r, θ) passes the observer: the scale a of the
/// Cauchy density a / (a² + ψ²) that follows 1/t² along it.
pub(super) fn cauchy_scale(axis: &SunAxis, r_m: f64, theta: f64) -> f64 {
    // Floored far below any pixel's footprint, only to keep the scale
    // positive (a floor near the observer's scale would leave the 1/t²
    // peak of the nearest circles unfollowed: fireflies).
    let nearest = (axis.point(r_m, theta, 0.0) - axis.observer_m)
        .length()
        .max(1e-6);
    // t² = d² + 2 r r₀ sin θ sin θ₀ (1 − cos ψ) ≈ d² + r r₀ sin θ sin θ₀ ψ².
    let curvature = r_m * axis.r0_m * theta.sin() * axis.theta0.sin();
    nearest / curvature.max(1.0).sqrt()
}

/// The visible arc |ψ| ≤ `half` of one circle and the Cauchy density
/// a / (a² + ψ²) on it (normalised to the arc).
#[derive(Clone, Copy, Debug)]
pub(super) struct Arc {
    pub(super) half: f64,
    pub(super) scale: f64,
    pub(super) atan_half: f64,
}

impl Arc {
    pub(super) fn new(half: f64, scale: f64) -> Self {
        Self {
            half,
            scale,
            atan_half: (half / scale).atan(),
        }
    }

    /// ψ at quantile `v` of the Cauchy density.
    pub(super) fn cauchy(&self, v: f64) -> f64 {
        self.scale * (self.atan_half * (2.0 * v - 1.0)).tan()
    }

    /// The Cauchy density's quantile of `psi`.
    pub(super) fn quantile(&self, psi: f64) -> f64 {
        (0.5 * (1.0 + (psi / self.scale).atan() / self.atan_half)).clamp(0.0, 1.0)
    }

    pub(super) fn cauchy_density(&self, psi: f64) -> f64 {
        self.scale / (self.scale * self.scale + psi * psi) / (2.0 * self.atan_half)
    }

    /// The positions drawn before the path's direction, stratified by `u`:
    /// [`CAUCHY_SPLATS`] Cauchy, then [`UNIFORM_SPLATS`] uniform.
    pub(super) fn first_positions(&self, u: f64) -> [f64; FIRST_SPLATS] {
        std::array::from_fn(|k| {
            if k < CAUCHY_SPLATS {
                self.cauchy((k as f64 + u) / CAUCHY_SPLATS as f64)
            } else {
                let v = ((k - CAUCHY_SPLATS) as f64 + u) / UNIFORM_SPLATS as f64;
                self.half * (2.0 * v - 1.0)
            }
        })
    }

    /// The positions' combined density at `psi`, `phase_splats` of them
    /// drawn by `cells` (balance heuristic over the three kinds of draws,
    /// multi-sample MIS: the estimate of a sum over positions divides each
    /// term by it).
    pub(super) fn density(&self, psi: f64, cells: &PhaseCells, phase_splats: usize) -> f64 {
        let cauchy = self.cauchy_density(psi);
        CAUCHY_SPLATS as f64 * cauchy
            + UNIFORM_SPLATS as f64 / (2.0 * self.half)
            + phase_splats as f64 * cells.density(self, psi, cauchy)
    }
}

/// The phase-weighted density on an arc: the Cauchy density times weights
/// constant over [`PHASE_CELLS`] cells uniform in its quantile — the phase
/// function toward the observer at each cell's centre, given the path's
/// direction, with a [`PHASE_FLOOR`]. An aerosol's forward peak seen by one
/// position of many is then drawn where it is: with the direction's density
/// alone (one mixture over all positions) that position's splat carried up
/// to K times the others' weight, and those splats were most of the
/// twilight sky's variance (`BENCHMARKS.md`).
pub(super) struct PhaseCells {
    /// Probability of each cell.
    pub(super) probabilities: [f64; PHASE_CELLS],
}

impl PhaseCells {
    /// From each cell's non-negative weight at its centre (the phase
    /// functions toward the observer, times the camera's pixels per
    /// steradian there: `CircleSplatter`'s walk).
    pub(super) fn new(weights: [f64; PHASE_CELLS]) -> Self {
        let total: f64 = weights.iter().sum();
        let even = 1.0 / PHASE_CELLS as f64;
        let probabilities = if total > 0.0 && total.is_finite() {
            weights.map(|w| (1.0 - PHASE_FLOOR) * w / total + PHASE_FLOOR * even)
        } else {
            [even; PHASE_CELLS]
        };
        Self { probabilities }
    }

    /// The quantile of each cell's centre.
    pub(super) fn centre(m: usize) -> f64 {
        (m as f64 + 0.5) / PHASE_CELLS as f64
    }

    /// Density at `psi` on `arc`, given the Cauchy density `cauchy` there.
    pub(super) fn density(&self, arc: &Arc, psi: f64, cauchy: f64) -> f64 {
        let m = ((arc.quantile(psi) * PHASE_CELLS as f64) as usize).min(PHASE_CELLS - 1);
        self.probabilities[m] * PHASE_CELLS as f64 * cauchy
    }

    /// `count` positions, stratified by `u` over the cells' cumulative
    /// probabilities.
    pub(super) fn positions<'a>(
        &'a self,
        arc: &'a Arc,
        u: f64,
        count: usize,
    ) -> impl Iterator<Item = f64> + 'a {
        let mut m = 0;
        let mut below = 0.0;
        (0..count).map(move |k| {
            let v = (k as f64 + u) / count as f64;
            while m + 1 < PHASE_CELLS && below + self.probabilities[m] <= v {
                below += self.probabilities[m];
                m += 1;
            }
            let within = ((v - below) / self.probabilities[m]).clamp(0.0, 1.0);
            arc.cauchy((m as f64 + within) / PHASE_CELLS as f64)
        })
    }
}

/// A function of the position along an arc known at the phase cells'
/// centres ([`PhaseCells::centre`]), linear in the Cauchy quantile
/// between them; not given beyond the first and the last centre.
#[derive(Clone, Copy, Debug)]
pub(super) struct AtCentres {
    nodes: [Lanes; PHASE_CELLS],
}

impl AtCentres {
    /// Node m (at [`PhaseCells::centre`]`(m)`) is `node(m)`.
    pub(super) fn from_fn(node: impl FnMut(usize) -> Lanes) -> Self {
        Self {
            nodes: std::array::from_fn(node),
        }
    }

    /// The value at quantile `u` of the arc's Cauchy density, between the
    /// first centre and the last.
    #[inline]
    pub(super) fn at(&self, u: f64) -> Option<Lanes> {
        // Node m sits at x = m.
        let x = u * PHASE_CELLS as f64 - 0.5;
        if x.is_nan() || x < 0.0 {
            return None;
        }
        let i = x as usize;
        if i + 1 >= PHASE_CELLS {
            return None;
        }
        let (a, b) = (self.nodes[i], self.nodes[i + 1]);
        let f = x - i as f64;
        Some(Lanes::from_fn(|j| a[j] + f * (b[j] - a[j])))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::direction_from_az_el;
    use crate::scene::{CameraKind, CameraParams};

    #[test]
    fn the_centres_light_is_linear_between_them() {
        let node = |m: usize| Lanes::from_fn(|j| (m * m) as f64 + j as f64);
        let light = AtCentres::from_fn(node);
        for m in 0..PHASE_CELLS {
            let last = m + 1 == PHASE_CELLS;
            assert_eq!(
                light.at(PhaseCells::centre(m)),
                Some(node(m)).filter(|_| !last)
            );
        }
        // Halfway between centres 3 and 4 (lane 1: 10 and 17) their mean;
        // nothing beyond the end centres.
        let halfway = (3.0 + 0.5 + 0.5) / PHASE_CELLS as f64;
        assert!((light.at(halfway).unwrap()[1] - 13.5).abs() < 1e-12);
        assert_eq!(light.at(0.0), None);
        assert_eq!(light.at(0.4 / PHASE_CELLS as f64), None);
        assert_eq!(light.at(1.0), None);
    }

    #[test]
    fn the_pixel_weight_follows_the_pixels_per_steradian_on_the_image() {
        // An equirect map has 1/cos el pixels per steradian: the factor is
        // 1 on the horizon, 2 at 60° and capped near the poles; the rows
        // at the poles take no splats, and there it is 1.
        let params = |kind| CameraParams {
            kind,
            yaw_deg: 90.0,
            ..CameraParams::default()
        };
        let map = Camera::new(&params(CameraKind::Equirect), 256, 128);
        let weight = PixelWeight::new(&map, 20.0);
        let at = |w: &PixelWeight, c: &Camera, az: f64, el: f64| {
            w.at(c, 3e4 * direction_from_az_el(az, el))
        };
        assert!((at(&weight, &map, 10.0, 0.3) - 1.0).abs() < 1e-3);
        assert!((at(&weight, &map, 200.0, -60.0) - 2.0).abs() < 1e-9);
        assert_eq!(at(&weight, &map, 0.0, 88.0), 20.0);
        assert_eq!(at(&weight, &map, 0.0, 89.9), 1.0);
        // A perspective view 90° wide: 1/cos³ of the angle off its axis
        // inside the frame, 1 outside it and behind it.
        let view = Camera::new(&params(CameraKind::Perspective), 200, 100);
        let weight = PixelWeight::new(&view, 20.0);
        assert!((at(&weight, &view, 90.0, 0.0) - 1.0).abs() < 1e-9);
        let off = 40.0_f64.to_radians().cos();
        assert!((at(&weight, &view, 130.0, 0.0) - off.powi(-3)).abs() < 1e-9);
        assert_eq!(at(&weight, &view, 140.0, 0.0), 1.0);
        assert_eq!(at(&weight, &view, 270.0, 0.0), 1.0);
    }
}
