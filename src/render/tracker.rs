//! The majorant process along a ray: the tentative collisions of delta
//! tracking over the shells' majorants, which every free-flight sampler of
//! the integrator draws from (one iterator serving every tracker).

use glam::DVec3;

use super::medium::{Bounds, Medium, ShellWalk, Span, SpectralLanes, GLOBAL_SLOT};
use crate::rng::Rng;

impl Medium {
    /// Distances to the sample points of a majorant (free-flight) process
    /// along `span`, one [`Collision`] at a time.
    pub fn tracker<'a>(
        &'a self,
        origin: DVec3,
        dir: DVec3,
        span: Span,
        lanes: &'a SpectralLanes,
        bounds: Bounds,
    ) -> Tracker<'a> {
        Tracker {
            medium: self,
            lanes,
            walk: self.walk(origin, dir, span, bounds),
            t: span.t_enter,
            piece_end: span.t_enter,
            majorant: 0.0,
            budget: -1.0,
        }
    }
}

/// A tentative collision of the majorant process.
#[derive(Clone, Copy, Debug)]
pub struct Collision {
    /// Distance along the ray, m.
    pub t: f64,
    /// The (common) majorant at the collision, m⁻¹.
    pub majorant: f64,
}

/// Samples the majorant process along a ray, piece by piece.
pub struct Tracker<'a> {
    medium: &'a Medium,
    lanes: &'a SpectralLanes,
    pub(super) walk: ShellWalk,
    t: f64,
    piece_end: f64,
    majorant: f64,
    /// Optical depth left to the next collision (negative: draw a new one).
    budget: f64,
}

impl Tracker<'_> {
    /// Conditions the first tentative collision on lying within the span
    /// (call before [`Self::next`]) and returns the probability that it
    /// would have, 1 − exp(−τ̄), τ̄ being the majorant's optical depth over
    /// the span: the path's weight is multiplied by it. The optical depth to
    /// the collision is then exponential truncated at τ̄.
    pub fn force_collision(&mut self, rng: &mut Rng) -> f64 {
        let depth = self.majorant * (self.piece_end - self.t) + self.remaining_majorant_depth();
        // −expm1(−τ̄) keeps its precision for thin rays.
        let p = -(-depth).exp_m1();
        if p <= 0.0 {
            return 0.0;
        }
        // A truncated exponential: −ln(1 − u p), u ∈ (0, 1].
        self.budget = -(-rng.uniform_open0() * p).ln_1p();
        p
    }

    /// The majorant's optical depth over the pieces the walk has not
    /// reached, in closed form rather than piece by piece (a walk costs a
    /// square root and a branch per piece, and forcing then walked every
    /// segment twice: 6 % of a midday render, callgrind).
    /// Measured from the perigee, the ray's points at distance u lie at
    /// radius √(p² + u²), so shell s, between radii a and b, holds the u
    /// with c(a) ≤ |u| < c(b), c(r) = √(max(r² − p², 0)): the span's part
    /// beyond the perigee, u ∈ [max(u₀, 0), max(u₁, 0)], and its part
    /// before it, |u| ∈ [max(−u₁, 0), max(−u₀, 0)], each overlap a
    /// difference of two such values.
    pub(super) fn remaining_majorant_depth(&self) -> f64 {
        let walk = &self.walk;
        if walk.t >= walk.t_end {
            return 0.0;
        }
        let majorants = &self.lanes.majorants;
        if walk.global {
            return majorants[GLOBAL_SLOT] * (walk.t_end - walk.t);
        }
        // Plain comparisons: no NaN can occur, and `f64::min`/`max` cost
        // their NaN handling in this loop.
        let (min, max) = (
            |a: f64, b: f64| if a < b { a } else { b },
            |a: f64, b: f64| if a > b { a } else { b },
        );
        let radii = &self.medium.shell_radii_m;
        let crossing = |r: f64| {
            let d = r * r - walk.perigee2;
            if d > 0.0 {
                d.sqrt()
            } else {
                0.0
            }
        };
        let (u0, u1) = (walk.t - walk.perigee_t, walk.t_end - walk.perigee_t);
        let mut depth = 0.0;
        if u0 >= 0.0 {
            // Past the perigee (most forced segments: upward): the walk's
            // shell and those above it, each from crossing to crossing.
            let mut lo = u0;
            for (s, &r) in radii.iter().enumerate().skip(walk.shell + 1) {
                let hi = min(crossing(r), u1);
                depth += majorants[s - 1] * max(hi - lo, 0.0);
                if hi >= u1 {
                    break;
                }
                lo = hi;
            }
            return depth;
        }
        let (after_lo, after_hi) = (0.0, max(u1, 0.0));
        let (before_lo, before_hi) = (max(-u1, 0.0), -u0);
        let mut c_lo = crossing(radii[0]);
        for (s, &r) in radii[1..].iter().enumerate() {
            let c_hi = crossing(r);
            let after = max(min(c_hi, after_hi) - max(c_lo, after_lo), 0.0);
            let before = max(min(c_hi, before_hi) - max(c_lo, before_lo), 0.0);
            depth += majorants[s] * (after + before);
            c_lo = c_hi;
        }
        depth
    }

    /// The next tentative collision, or `None` at the end of the span.
    pub fn next(&mut self, rng: &mut Rng) -> Option<Collision> {
        if self.budget < 0.0 {
            self.budget = -rng.uniform_open0().ln();
        }
        loop {
            // The exponential optical-depth budget carries over piece
            // boundaries (memorylessness), so crossing a piece costs no
            // random number.
            let available = self.majorant * (self.piece_end - self.t);
            if self.budget < available {
                self.t += self.budget / self.majorant;
                self.budget = -1.0;
                return Some(Collision {
                    t: self.t,
                    majorant: self.majorant,
                });
            }
            self.budget -= available;
            let piece = self.walk.next_piece(self.medium)?;
            self.majorant = self.lanes.shell(&self.walk, piece.shell).majorant;
            self.t = piece.t0;
            self.piece_end = piece.t1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::atmosphere::{Atmosphere, AtmosphereParams};
    use crate::render::medium::Lanes;
    use crate::render::transmittance::tests::test_rays;

    fn medium() -> Medium {
        Medium::new(&Atmosphere::new(AtmosphereParams::default()))
    }

    #[test]
    fn a_forced_collision_is_the_first_collision_given_one_in_the_span() {
        // `force_collision` returns the chance that an unforced tracker meets
        // a tentative collision before the span ends, and then draws the
        // first collision from its distribution given that it does: both
        // checked against unforced trackers within 4 standard errors.
        let medium = medium();
        let lanes =
            SpectralLanes::new(Lanes::from([400.0, 500.0, 600.0, 700.0]), 4, &medium, false);
        let origin = DVec3::new(0.0, 0.0, medium.planet_radius_m + 2_000.0);
        let n = 40_000;
        for el in [90.0_f64, 20.0, 3.0] {
            let dir = DVec3::new(el.to_radians().cos(), 0.0, el.to_radians().sin());
            let span = medium.span(origin, dir).unwrap();
            let tracker = || medium.tracker(origin, dir, span, &lanes, Bounds::Tight);
            let p = tracker().force_collision(&mut Rng::new(0, 0));
            let (mut hits, mut hit_t, mut forced_t, mut forced_t2) = (0.0, 0.0, 0.0, 0.0);
            for i in 0..n {
                let mut rng = Rng::new(7, i);
                if let Some(c) = tracker().next(&mut rng) {
                    hits += 1.0;
                    hit_t += c.t;
                }
                let mut forced = tracker();
                assert_eq!(forced.force_collision(&mut rng), p);
                let c = forced.next(&mut rng).expect("a forced collision");
                assert!((span.t_enter..=span.t_exit).contains(&c.t), "el {el}");
                forced_t += c.t;
                forced_t2 += c.t * c.t;
            }
            let nf = n as f64;
            let p_se = (p * (1.0 - p) / nf).sqrt();
            assert!(p > 0.0 && p < 1.0, "el {el}: p {p}");
            assert!(
                (hits / nf - p).abs() < 4.0 * p_se,
                "el {el}: {} vs {p}",
                hits / nf
            );
            // Mean distance of the first collision given one: unforced
            // (hits) vs forced (all n).
            let mean = forced_t / nf;
            let sd = (forced_t2 / nf - mean * mean).sqrt();
            let se = sd * (1.0 / nf + 1.0 / hits).sqrt();
            assert!(
                (hit_t / hits - mean).abs() < 4.0 * se,
                "el {el}: {} vs {mean} ± {se}",
                hit_t / hits
            );
        }
    }

    #[test]
    fn the_closed_form_majorant_depth_matches_the_walk() {
        // The majorant's optical depth of a whole span, in closed form,
        // against the sum over the pieces of a walk, for rays up, across,
        // grazing, into the ground and from orbit, with tight and global
        // bounds, from the span's start and from part-way along it.
        let medium = medium();
        let lanes =
            SpectralLanes::new(Lanes::from([400.0, 500.0, 600.0, 700.0]), 4, &medium, false);
        for (origin, dir) in test_rays(&medium) {
            let span = medium.span(origin, dir).unwrap();
            for bounds in [Bounds::Tight, Bounds::Global] {
                let mut tracker = medium.tracker(origin, dir, span, &lanes, bounds);
                for _ in 0..4 {
                    let mut walk = tracker.walk.clone();
                    let mut walked = 0.0;
                    while let Some(piece) = walk.next_piece(&medium) {
                        walked += lanes.shell(&walk, piece.shell).majorant * (piece.t1 - piece.t0);
                    }
                    let closed = tracker.remaining_majorant_depth();
                    assert!(
                        (closed - walked).abs() <= 1e-9 * walked + 1e-12,
                        "{dir:?} {bounds:?}: {closed} vs {walked}"
                    );
                    // On to the next piece.
                    if tracker.walk.next_piece(&medium).is_none() {
                        break;
                    }
                }
            }
        }
    }
}
