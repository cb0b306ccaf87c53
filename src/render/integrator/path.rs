//! The path loop: one loop for every path, whatever estimates its
//! segments.
//!
//! A path alternates two steps. At a vertex, what happens to the path is
//! decided in one place ([`Integrator::go_on`]): a real scattering picks
//! its new direction (or, with importance splitting, the copies' new
//! directions), the path is rouletted, and the control variate's
//! expansion along the new direction is taken out of it. Along the segment
//! from the vertex, the plan's segment estimator
//! ([`Integrator::estimate_next`]) adds the light it finds — by
//! next-event estimates at delta-tracked collisions, at points drawn from
//! the segment's expected sunlight, or from the sky guide's cached
//! densities — and says where the path goes on: a real scattering
//! ([`Next::Scatter`]), a vertex with its direction already chosen (a
//! ground bounce, a segment estimator's own branch, [`Next::Vertex`]), or
//! nowhere.

use super::termination::{Walk, Window};
use super::{
    ground_point, real_scattering, DVec3, GuideAt, Integrator, Lanes, Light, Next, Rng, Segment,
    SpectralLanes, Start, Vertex,
};
use crate::plan::SegmentEstimator;
use crate::render::guide::SkyGuide;

impl<'a> Integrator<'a> {
    /// Continues a path from `origin` along `dir` after `depth` scatterings
    /// (its weight's roulette scale `split`) with weight `beta`, adding what
    /// it finds to `radiance`.
    pub(super) fn trace(
        &self,
        (origin, dir, depth, split): Start,
        beta: Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        let window = self.importance(origin).map(|reference| Window {
            reference,
            copies: 1,
        });
        self.walk(
            (origin, dir, beta),
            (depth, split, window),
            lanes,
            radiance,
            rng,
        );
    }

    /// The path loop from `vertex`, whose direction is chosen: segment,
    /// vertex, segment, … until the path ends.
    pub(super) fn walk(
        &self,
        vertex: Vertex,
        (depth, split, window): Walk,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        let mut depth = depth;
        let mut window = window;
        let mut vertex = (vertex, None);
        loop {
            let ((origin, dir, beta), at) = vertex;
            let segment = (origin, dir, depth, at);
            let Some(next) = self.estimate_next(segment, &beta, lanes, radiance, rng) else {
                break;
            };
            depth += 1;
            let walk = (depth, split, &mut window);
            let Some(resolved) = self.go_on(next, walk, lanes, radiance, rng) else {
                break;
            };
            vertex = resolved;
        }
    }

    /// The vertex `next` after `depth` scatterings, with its direction,
    /// rouletted (or split) and the control variate taken out: the vertex
    /// the path goes on from (with the guide at it, where choosing its
    /// direction looked it up), or `None` if the path ends there. Copies
    /// beyond the first walk on here.
    fn go_on(
        &self,
        next: Next<'a>,
        (depth, split, window): (u32, f64, &mut Option<Window>),
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<(Vertex, Option<GuideAt<'a>>)> {
        match next {
            Next::Vertex(mut vertex) => {
                let ended = self.ends(&mut vertex.2, depth, split, lanes, rng);
                (!ended).then_some((vertex, None))
            }
            Next::Scatter(x, dir_in, mut beta, control) => {
                let c = self.medium.coefficients(x.length(), lanes);
                let copies = window.and_then(|w| {
                    self.weight_window(x, &c, &mut beta, (depth, split, w), lanes, rng)
                });
                match copies {
                    Some((0, _)) => None,
                    Some((copies, copies_window)) => {
                        // This path goes on as the last copy.
                        *window = Some(copies_window);
                        let from = (x, dir_in, &c, control.as_ref());
                        let walk = (depth, split, *window);
                        Some(self.copies(from, beta, copies, walk, lanes, radiance, rng))
                    }
                    None => {
                        let (new_dir, at) = self.scatter(x, dir_in, &c, &mut beta, lanes, rng);
                        if self.ends(&mut beta, depth, split, lanes, rng) {
                            return None;
                        }
                        if let Some(control) = &control {
                            control.subtract(lanes, new_dir, &beta, radiance);
                        }
                        Some(((x, new_dir, beta), at))
                    }
                }
            }
        }
    }

    /// The plan's estimate of the segment from `origin` along `dir` after
    /// `depth` scatterings, reached with weight `beta` (`at`: the guide at
    /// `origin`, if already looked up): adds the light found along it and
    /// returns where the path goes on, by the plan's estimator
    /// ([`crate::plan::SegmentPlan::estimator`]).
    fn estimate_next(
        &self,
        (origin, dir, depth, at): (DVec3, DVec3, u32, Option<GuideAt<'a>>),
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        // Whether the segment starts in the planet's shadow matters only
        // to `shadow_samples`; the test is skipped otherwise.
        let in_shadow =
            |guide: &SkyGuide| self.plan.segments.shadow_samples > 0 && guide.shadowed(origin);
        let guide = self.guide.filter(|&g| in_shadow(g));
        match self
            .plan
            .segments
            .estimator(depth, guide.is_some(), self.guide.is_some())
        {
            SegmentEstimator::SunlightPoints => {
                self.sunlit_segment((origin, dir, depth, at), beta, lanes, radiance, rng)
            }
            SegmentEstimator::ShadowPoints => {
                // Its sunlit stretch is found by the guide's density, not
                // by chance collisions.
                let guide = guide?;
                let segment = self.segment(origin, dir, depth, beta, lanes, radiance)?;
                let at = at.unwrap_or_else(|| guide.at(self.medium, origin));
                self.guided_segment(&at, &segment, beta, lanes, radiance, rng)
            }
            SegmentEstimator::DeltaTracking => {
                self.tracked_segment(origin, dir, depth, beta, lanes, radiance, rng)
            }
        }
    }

    /// The segment from `origin` along `dir` after `depth` scatterings,
    /// delta-tracked, with a next-event estimate toward the sun at every
    /// tentative collision (see the module's estimator), the sun's direct
    /// light at the ground, and the sun's disc where the path escapes
    /// straight from the camera (or without next-event estimation).
    #[allow(clippy::too_many_arguments)]
    fn tracked_segment(
        &self,
        origin: DVec3,
        dir: DVec3,
        depth: u32,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        let opts = self.plan;
        let nee = opts.segments.next_event_estimation;
        let max_order = opts.termination.max_scattering_order;
        let mut beta = *beta;
        if let Some(span) = self.medium.span(origin, dir) {
            let mut tracker = self.medium.tracker(origin, dir, span, lanes, self.bounds);
            if nee {
                self.force_collision(&mut tracker, span, depth, &mut beta, rng);
            }
            while let Some(collision) = tracker.next(rng) {
                let x = origin + dir * collision.t;
                let c = self.medium.coefficients(x.length(), lanes);
                let majorant = collision.majorant;
                // A next-event estimate at a vertex after `depth` real
                // scatterings adds scattering order depth + 1.
                if nee && depth < max_order {
                    let to_sun = self.sample_sun_direction(rng);
                    let e_sun = self.sun_irradiance_toward(to_sun, lanes);
                    let mu = dir.dot(to_sun);
                    let tr = self.shadow(x, to_sun, lanes, rng);
                    let phase = Lanes::from_fn(|j| self.scattering_phase(&c, lanes, j, mu));
                    radiance.total += beta * phase / majorant * e_sun * tr;
                }
                if depth + 1 >= max_order {
                    // Only lower orders wanted: continue as if null.
                    beta *= Lanes::from_fn(|j| 1.0 - c.extinction(j) / majorant);
                    continue;
                }
                if real_scattering(&c, majorant, &mut beta, lanes, rng) {
                    return Some(self.real_scattering_at(x, dir, &c, beta, lanes, radiance, rng));
                }
            }
            if span.hits_ground {
                let normal = (origin + dir * span.t_exit).normalize();
                self.ground_direct(normal, depth, &beta, lanes, radiance, rng);
                return self.ground_bounce(normal, depth, &beta, lanes, radiance, rng);
            }
        }
        // Escaped to space. The disc is counted here only where no
        // next-event estimate already accounted for it.
        if depth == 0 || !nee {
            self.add_sun_disc(dir, depth, &beta, lanes, radiance);
        }
        None
    }

    /// Where a path goes on from `segment`, whose light a segment estimate
    /// already counted: its first real scattering by delta tracking (so the
    /// weight changes by about the single-scattering albedo, whatever the
    /// ray), or else the ground's bounce; `None` if the path ends.
    pub(super) fn track_continuation(
        &self,
        segment: &Segment,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        let &Segment {
            origin,
            dir,
            span,
            depth,
        } = segment;
        if depth + 1 >= self.plan.termination.max_scattering_order {
            return None;
        }
        let mut beta = *beta;
        let mut tracker = self.medium.tracker(origin, dir, span, lanes, self.bounds);
        while let Some(collision) = tracker.next(rng) {
            let x = origin + dir * collision.t;
            let c = self.medium.coefficients(x.length(), lanes);
            if real_scattering(&c, collision.majorant, &mut beta, lanes, rng) {
                return Some(self.real_scattering_at(x, dir, &c, beta, lanes, radiance, rng));
            }
        }
        if !span.hits_ground {
            return None;
        }
        let normal = (origin + dir * span.t_exit).normalize();
        self.ground_bounce(normal, depth, &beta, lanes, radiance, rng)
    }

    /// A real scattering at `x` of a path along `dir` with weight `beta`
    /// (coefficients `c`), its direction still to choose: with the control
    /// variate on, the exact integral of its expansion there is added
    /// now, and the path going on will estimate the rest.
    #[allow(clippy::too_many_arguments)]
    fn real_scattering_at(
        &self,
        x: DVec3,
        dir: DVec3,
        c: &crate::render::medium::Coefficients,
        beta: Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Next<'a> {
        let control = self.control_at(x, lanes, rng);
        if let Some(at) = &control {
            self.control_in(at, c, lanes, dir, &beta, radiance);
        }
        Next::Scatter(x, dir, beta, control)
    }

    /// The Lambertian ground's bounce under unit `normal`, reached after
    /// `depth` scatterings with weight `beta`: a direction from
    /// [`Integrator::bounce_direction`] (BRDF · cos / pdf = albedo for a
    /// cosine-weighted one), with the control variate's share taken
    /// out where the plan controls the ground
    /// ([`Integrator::ground_control`]); `None` where no order beyond it is
    /// wanted or the ground is black.
    pub(super) fn ground_bounce(
        &self,
        normal: DVec3,
        depth: u32,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        if depth + 1 >= self.plan.termination.max_scattering_order
            || self.medium.ground_albedo_max <= 0.0
        {
            return None;
        }
        let weight = *beta * lanes.ground_albedo;
        let sky = self.ground_sky(normal, lanes);
        Self::ground_sky_in(sky.as_ref(), &weight, lanes, radiance);
        let guide = self.bounce_guide(normal);
        let (bounce, reflect) = self.bounce_direction(normal, guide.as_ref(), rng)?;
        let beta = weight * reflect;
        Self::ground_sky_out(sky.as_ref(), bounce, &beta, lanes, radiance);
        self.ground_control(normal, bounce, &beta, lanes, radiance, rng);
        Some(Next::Vertex((
            ground_point(self.medium, normal),
            bounce,
            beta,
        )))
    }
}
