//! Segment estimators: a path segment estimated through next-event points
//! drawn from its expected sunlight (low sun), with roulette and splitting
//! by importance, or by delta tracking with forced collisions.

use super::{
    cosine_sample_hemisphere, ground_point, rayleigh, real_scattering, survives_roulette, Branches,
    Component, ControlAt, DVec3, GuideAt, InScatterDistribution, Integrator, Lanes, Light, Next,
    Rng, Segment, SegmentDensity, Span, SpectralLanes, Start, Vertex, Window, DIRECTION_UNIFORMS,
    MAX_BRANCHES, MAX_COPIES, MAX_SPLIT, MAX_SUNLIGHT_SAMPLES, ROULETTE_CAP_DEPTH, ROULETTE_WEIGHT,
    SPLIT_WEIGHT,
};

impl<'a> Integrator<'a> {
    /// A path whose every segment is estimated through in-scattering points
    /// drawn from [`InScatterDistribution`] (the expected sunlight along the
    /// segment) instead of delta-tracked collisions. For a segment from x
    /// along ω,
    ///
    /// L(x, ω) = ∫ T(0,t) σ_s(t) ∫ p L_in dω' dt + T(0,t_end) L_end.
    ///
    /// Every point gets a next-event estimate toward the sun, weighted by the
    /// point's density and an unbiased transmittance estimate T̂(0,t); one
    /// point, picked uniformly (so its marginal density is the density
    /// itself), may continue the path into the diffuse light. The end of the
    /// segment adds the ground's direct light or, on camera rays, the sun's
    /// disc, weighted by T̂(0,t_end). Where the segment meets the ground the
    /// path continues either from the medium point or from the ground, chosen
    /// by their expected shares (weights divided by the choice's probability).
    /// Every transmittance on the segment comes from one tracking pass.
    pub(super) fn trace_sunlit(
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
        self.walk_sunlit(
            Next::Vertex((origin, dir, beta)),
            (depth, split, window),
            lanes,
            radiance,
            rng,
        );
    }

    /// Expected light a path finds going on from `x`, per unit weight, up
    /// to a constant: the guide's mean once-scattered radiance there.
    pub(super) fn importance(&self, x: DVec3) -> Option<f64> {
        self.guide
            .filter(|_| self.plan.termination.russian_roulette && self.plan.termination.splitting)
            .map(|g| g.skylight(self.medium, x))
            .filter(|&s| s > 0.0 && s.is_finite())
    }

    /// [`Self::trace_sunlit`] from `next` after `depth` scatterings.
    pub(super) fn walk_sunlit(
        &self,
        next: Next<'a>,
        (depth, split, window): (u32, f64, Option<Window>),
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) {
        let mut next = Some(next);
        let mut depth = depth;
        let mut window = window;
        while let Some(n) = next {
            // The guide at the vertex, where choosing its direction looked it up.
            let ((origin, dir, beta), at) = match n {
                Next::Vertex(vertex) => (vertex, None),
                Next::Scatter(x, dir_in, mut beta, control) => {
                    let c = self.medium.coefficients(x.length(), lanes);
                    let copies = window.and_then(|window| {
                        self.weight_window(x, &c, &mut beta, (depth, split, window), lanes, rng)
                    });
                    match copies {
                        Some((0, _)) => break,
                        Some((copies, copies_window)) => {
                            // This path goes on as the last copy.
                            window = Some(copies_window);
                            let from = (x, dir_in, &c, control.as_ref());
                            let walk = (depth, split, window);
                            self.copies(from, beta, copies, walk, lanes, radiance, rng)
                        }
                        None => {
                            // Without the guide's importance: roulette as
                            // for any other vertex.
                            let (new_dir, at) = self.scatter(x, dir_in, &c, &mut beta, lanes, rng);
                            if self.plan.termination.russian_roulette
                                && depth >= 2
                                && !survives_roulette(&mut beta, lanes.active, depth, split, rng)
                            {
                                break;
                            }
                            if let Some(control) = &control {
                                control.subtract(lanes, new_dir, &beta, radiance);
                            }
                            ((x, new_dir, beta), at)
                        }
                    }
                }
            };
            let segment = (origin, dir, depth, at);
            next = self.sunlit_segment(segment, &beta, lanes, radiance, rng);
            depth += 1;
            self.roulette_vertex(&mut next, depth, split, lanes, rng);
        }
    }

    /// `copies` copies of a path scattered at `x` along `dir_in`
    /// (coefficients `c`, weight `beta` before the direction's factor),
    /// sharing its weight, each with its own direction: all but one walk on
    /// here; the last is returned.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn copies(
        &self,
        (x, dir_in, c, control): (
            DVec3,
            DVec3,
            &crate::render::medium::Coefficients,
            Option<&ControlAt<'a>>,
        ),
        beta: Lanes,
        copies: usize,
        walk: (u32, f64, Option<Window>),
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> (Vertex, Option<GuideAt<'a>>) {
        let share = 1.0 / copies as f64;
        let beta = beta.map(|b| b * share);
        for _ in 1..copies {
            let mut copy = beta;
            let (new_dir, _) = self.scatter(x, dir_in, c, &mut copy, lanes, rng);
            if let Some(control) = control {
                control.subtract(lanes, new_dir, &copy, radiance);
            }
            self.walk_sunlit(Next::Vertex((x, new_dir, copy)), walk, lanes, radiance, rng);
        }
        let mut last = beta;
        let (new_dir, at) = self.scatter(x, dir_in, c, &mut last, lanes, rng);
        if let Some(control) = control {
            control.subtract(lanes, new_dir, &last, radiance);
        }
        ((x, new_dir, last), at)
    }

    /// Russian roulette on `next` if it is a vertex with its direction
    /// chosen, after `depth` scatterings (real scatterings play it in
    /// [`Self::walk_sunlit`]); ends the path (`None`) if it loses.
    pub(super) fn roulette_vertex(
        &self,
        next: &mut Option<Next<'a>>,
        depth: u32,
        split: f64,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) {
        if let Some(Next::Vertex((_, _, beta))) = next {
            if self.plan.termination.russian_roulette
                && depth >= 2
                && !survives_roulette(beta, lanes.active, depth, split, rng)
            {
                *next = None;
            }
        }
    }

    /// Adjoint-driven roulette and splitting at a real scattering at `x`
    /// (coefficients `c`, weight `beta` before the direction's factor):
    /// the path's expected light relative to its window's reference (its
    /// start's) picks how many copies go on (0 = ended; survivors' weights
    /// are divided by their chance, copies share the weight), returned with
    /// the copies' window. Where a cap ([`MAX_SPLIT`] per vertex,
    /// [`MAX_COPIES`] per start) leaves each copy at or above the splitting
    /// threshold, their reference rises to their expected light, so a start
    /// with next to no light (where the guide's table fades to zero, or
    /// deep in a thick haze) cannot make every later vertex split again.
    pub(super) fn weight_window(
        &self,
        x: DVec3,
        c: &crate::render::medium::Coefficients,
        beta: &mut Lanes,
        (depth, split, window): (u32, f64, Window),
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> Option<(usize, Window)> {
        let Window { reference, copies } = window;
        let here = self.importance(x)?;
        let weight = (0..lanes.active)
            .map(|j| beta[j] * c.scattering(j))
            .fold(0.0, f64::max);
        let expected = split * weight * here / reference;
        if expected < ROULETTE_WEIGHT || depth >= ROULETTE_CAP_DEPTH {
            let mut survive = (expected / ROULETTE_WEIGHT).min(1.0);
            if depth >= ROULETTE_CAP_DEPTH {
                survive = survive.min(0.9);
            }
            if rng.uniform() >= survive {
                return Some((0, window));
            }
            for b in beta.iter_mut() {
                *b /= survive;
            }
            return Some((1, window));
        }
        if expected >= SPLIT_WEIGHT {
            let room = (MAX_COPIES / copies).max(1);
            let split_into = (expected.floor() as usize).min(MAX_SPLIT).min(room);
            let each = expected / split_into as f64;
            let lifted = if each >= SPLIT_WEIGHT {
                reference * each
            } else {
                reference
            };
            let window = Window {
                reference: lifted,
                copies: copies * split_into,
            };
            return Some((split_into, window));
        }
        Some((1, window))
    }

    /// One segment of [`Self::trace_sunlit`] from `origin` along `dir` after
    /// `depth` scatterings with weight `beta` (`at`: the guide at `origin`,
    /// if already looked up); returns the next vertex (position, direction,
    /// weight).
    pub(super) fn sunlit_segment(
        &self,
        (origin, dir, depth, at): (DVec3, DVec3, u32, Option<GuideAt<'a>>),
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        let segment = self.segment(origin, dir, depth, beta, lanes, radiance)?;
        if let Some(guide) = self.guide {
            let at = at.unwrap_or_else(|| guide.at(self.medium, origin));
            return self.guided_segment(&at, &segment, beta, lanes, radiance, rng);
        }
        let opts = self.plan;
        let max_order = opts.termination.max_scattering_order;
        let span = segment.span;
        let n = (opts.segments.sunlight_samples as usize).min(MAX_SUNLIGHT_SAMPLES);
        if depth >= max_order {
            return self.estimate_segment(&segment, beta, None, (0, 1), lanes, radiance, rng)[0]
                .map(Next::Vertex);
        }
        let mu_sun = dir.dot(self.sun_direction);
        let phase_rayleigh: Lanes =
            Lanes::from_fn(|j| rayleigh::phase(mu_sun, lanes.rayleigh_gamma[j]));
        let phase_aerosol = self.medium.aerosol_phases(mu_sun, lanes);
        let distribution = InScatterDistribution::new(
            self.medium,
            Some(self.medium.sun_columns()),
            lanes,
            origin,
            dir,
            span,
            self.sun_direction,
            &phase_rayleigh,
            &phase_aerosol,
            None,
        );
        let n = if distribution.is_some() { n } else { 0 };
        let distribution = distribution.as_ref().map(|d| d as &dyn SegmentDensity);
        self.estimate_segment(&segment, beta, distribution, (n, 1), lanes, radiance, rng)[0]
            .map(Next::Vertex)
    }

    /// The light along `segment` (reached with weight `beta`) through `n`
    /// in-scattering points drawn from `distribution`, each with a next-event
    /// estimate, plus what lies at the segment's end; returns the vertices
    /// the path goes on from, one per branch of `(n, branches)`, each
    /// weighted 1/branches (see [`Self::trace_sunlit`]).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn estimate_segment(
        &self,
        segment: &Segment,
        beta: &Lanes,
        distribution: Option<&dyn SegmentDensity>,
        (n, branches): (usize, usize),
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Branches {
        let opts = self.plan;
        let max_order = opts.termination.max_scattering_order;
        let &Segment {
            origin,
            dir,
            span,
            depth,
        } = segment;
        let n = if distribution.is_some() && depth < max_order {
            n
        } else {
            0
        };
        // Where the path goes on: from the medium, from the ground, or not.
        let goes_on = depth + 1 < max_order;
        let ground_goes_on = goes_on && span.hits_ground && self.medium.ground_albedo_max > 0.0;
        let p_medium = match (distribution, goes_on) {
            // The camera ray's light scattered again in the air is splatted.
            _ if depth == 0 && self.splatting => 0.0,
            (Some(d), true) if ground_goes_on => {
                // The largest albedo over wavelength: a density, not a value.
                let (medium, ground) = d.shares(self.medium.ground_albedo_max);
                (medium / (medium + ground)).clamp(0.05, 0.95)
            }
            // Without Russian roulette the path must still end: go on with
            // the expected scattered fraction, as an analog path would.
            (Some(d), true) if !opts.termination.russian_roulette => {
                d.shares(0.0).0.clamp(0.05, 1.0)
            }
            (Some(_), true) => 1.0,
            _ => 0.0,
        };
        let mut from_medium = [false; MAX_BRANCHES];
        for f in &mut from_medium[..branches] {
            *f = rng.uniform() < p_medium;
        }
        // n next-event points stratified in the whole density's cumulative
        // probability, and the points the branches go on from, stratified in
        // the skylight part's; sorted for the transmittance pass. A point
        // outside the span (only through rounding) keeps density 0 and is
        // skipped.
        let mut samples = [(0.0, 0.0, None); MAX_SUNLIGHT_SAMPLES + MAX_BRANCHES];
        let mut m = 0;
        if let Some(d) = distribution {
            for k in 0..n {
                let (t, pdf) = d.sample(Component::Mixture, (k as f64 + rng.uniform()) / n as f64);
                samples[m] = (t, pdf, None);
                m += 1;
            }
            for b in (0..branches).filter(|&b| from_medium[b]) {
                let u = (b as f64 + rng.uniform()) / branches as f64;
                let (t, pdf) = d.sample(Component::Skylight, u);
                samples[m] = (t, pdf, Some(b));
                m += 1;
            }
        }
        for sample in &mut samples[..m] {
            if !(span.t_enter..=span.t_exit).contains(&sample.0) {
                *sample = (span.t_exit, 0.0, sample.2);
            }
        }
        // The branches' direction uniforms, drawn before the transmittance
        // pass (whose number of draws varies) so that a pixel sample's
        // first scatterings take them from its low-discrepancy prefix.
        let mut direction_u = [[0.0; DIRECTION_UNIFORMS]; MAX_BRANCHES];
        for u in direction_u[..branches].iter_mut().flatten() {
            *u = rng.uniform();
        }
        samples[..m].sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut points = [(0.0, Lanes::splat(0.0)); MAX_SUNLIGHT_SAMPLES + MAX_BRANCHES];
        for (point, sample) in points.iter_mut().zip(&samples[..m]) {
            point.0 = sample.0;
        }
        // The transmittance to the end is needed at a ground hit and on a
        // camera ray toward the sun's disc; elsewhere the pass stops at the
        // last point.
        let to_end =
            span.hits_ground || (depth == 0 && dir.dot(self.sun_direction) >= self.cos_sun_radius);
        let tr_end = self.medium.transmittance_along(
            origin,
            dir,
            span,
            lanes,
            opts.segments.shadow_transmittance,
            self.bounds,
            &mut points[..m],
            to_end,
            rng,
        );
        let mut next = [None; MAX_BRANCHES];
        let share = 1.0 / branches.max(1) as f64;
        for (&(t, tr_view), &(_, density, branch)) in points.iter().zip(&samples[..m]) {
            if density <= 0.0 {
                continue;
            }
            let x = origin + dir * t;
            let c = self.medium.coefficients(x.length(), lanes);
            if let Some(b) = branch {
                let (new_dir, pdf, _) = rng.replaying(&direction_u[b], |rng| {
                    self.sample_scatter_direction(x, dir, &c, lanes, rng)
                });
                let mu = dir.dot(new_dir);
                let new_beta = Lanes::from_fn(|j| {
                    share * beta[j] * tr_view[j] * self.scattering_phase(&c, lanes, j, mu)
                        / (density * pdf * p_medium)
                });
                if let Some(at) = self.control_at(x, lanes, rng) {
                    let scale: Lanes =
                        Lanes::from_fn(|j| share * beta[j] * tr_view[j] / (density * p_medium));
                    self.control_in(&at, &c, lanes, dir, &scale, radiance);
                    at.subtract(lanes, new_dir, &new_beta, radiance);
                }
                next[b] = Some((x, new_dir, new_beta));
                continue;
            }
            let to_sun = self.sample_sun_direction(rng);
            let mu = dir.dot(to_sun);
            let tr_sun = self.shadow(x, to_sun, lanes, rng);
            let weight = 1.0 / (n as f64 * density);
            let e_sun = self.sun_irradiance_toward(to_sun, lanes);
            let phase = Lanes::from_fn(|j| self.scattering_phase(&c, lanes, j, mu));
            radiance.total += *beta * tr_view * weight * phase * e_sun * tr_sun;
        }
        // What lies at the end (only where the pass went there).
        let Some(tr_end) = tr_end else {
            return next;
        };
        let through: Lanes = Lanes::from_fn(|j| beta[j] * tr_end[j]);
        if span.hits_ground {
            let normal = (origin + dir * span.t_exit).normalize();
            self.ground_direct(normal, depth, &through, lanes, radiance, rng);
            if ground_goes_on {
                // Each ground branch bounces on its own (see `ground_vertex`).
                let x = ground_point(self.medium, normal);
                let weight: Lanes = Lanes::from_fn(|j| {
                    through[j] * lanes.ground_albedo[j] * share / (1.0 - p_medium)
                });
                for ((slot, _), u) in next[..branches]
                    .iter_mut()
                    .zip(&from_medium)
                    .zip(&direction_u)
                    .filter(|((_, &f), _)| !f)
                {
                    let bounce = rng.replaying(u, |rng| cosine_sample_hemisphere(normal, rng));
                    *slot = Some((x, bounce, weight));
                }
            }
        } else if depth == 0 {
            self.add_sun_disc(dir, 0, &through, lanes, radiance);
        }
        next
    }

    /// The segment from `origin` along `dir` after `depth` scatterings, or
    /// `None` where the ray misses the atmosphere (a camera ray, reached with
    /// weight `beta`, then sees the sun's disc if it looks at it).
    pub(super) fn segment(
        &self,
        origin: DVec3,
        dir: DVec3,
        depth: u32,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
    ) -> Option<Segment> {
        let Some(span) = self.medium.span(origin, dir) else {
            if depth == 0 {
                self.add_sun_disc(dir, 0, beta, lanes, radiance);
            }
            return None;
        };
        Some(Segment {
            origin,
            dir,
            span,
            depth,
        })
    }

    /// One path segment reached with weight `beta`: next-event points from
    /// the cached density of the ray of the guide `at` the segment's origin
    /// ([`GuideAt::density`]), the path going on from its first real
    /// scattering ([`Self::track_continuation`]).
    pub(super) fn guided_segment(
        &self,
        at: &GuideAt<'_>,
        segment: &Segment,
        beta: &Lanes,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Option<Next<'a>> {
        let density = at.density(self.medium, segment.dir, segment.span);
        let n = (self
            .plan
            .segments
            .sunlight_samples
            .max(self.plan.segments.shadow_samples) as usize)
            .min(MAX_SUNLIGHT_SAMPLES);
        self.estimate_segment(segment, beta, Some(&density), (n, 0), lanes, radiance, rng);
        self.track_continuation(segment, beta, lanes, radiance, rng)
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
        let max_order = self.plan.termination.max_scattering_order;
        if depth + 1 >= max_order {
            return None;
        }
        let mut beta = *beta;
        let mut tracker = self.medium.tracker(origin, dir, span, lanes, self.bounds);
        while let Some(collision) = tracker.next(rng) {
            let x = origin + dir * collision.t;
            let c = self.medium.coefficients(x.length(), lanes);
            if real_scattering(&c, collision.majorant, &mut beta, lanes, rng) {
                let control = self.control_at(x, lanes, rng);
                if let Some(at) = &control {
                    self.control_in(at, &c, lanes, dir, &beta, radiance);
                }
                return Some(Next::Scatter(x, dir, beta, control));
            }
        }
        if !span.hits_ground || self.medium.ground_albedo_max <= 0.0 {
            return None;
        }
        // Cosine-weighted bounce: the Lambertian BRDF·cos/pdf = albedo.
        let normal = (origin + dir * span.t_exit).normalize();
        Some(Next::Vertex((
            ground_point(self.medium, normal),
            cosine_sample_hemisphere(normal, rng),
            Lanes::from_fn(|j| beta[j] * lanes.ground_albedo[j]),
        )))
    }

    /// `next` with its direction chosen (one copy, no splitting).
    pub(super) fn resolve(
        &self,
        next: Next<'a>,
        lanes: &SpectralLanes,
        rng: &mut Rng,
    ) -> (Vertex, Option<ControlAt<'a>>) {
        match next {
            Next::Vertex(vertex) => (vertex, None),
            Next::Scatter(x, dir, mut beta, control) => {
                let c = self.medium.coefficients(x.length(), lanes);
                let (new_dir, _) = self.scatter(x, dir, &c, &mut beta, lanes, rng);
                ((x, new_dir, beta), control)
            }
        }
    }

    /// Forced collision: on a segment that leaves the atmosphere after
    /// `depth` ≤ [`crate::plan::IntegratorOptions::forced_collision_depth`] scatterings,
    /// conditions `tracker`'s first tentative collision on lying within the
    /// segment and weights `beta` by the chance that it would, 1 − exp(−τ̄).
    /// Unbiased where a path that escapes adds nothing: next-event estimates
    /// have already counted the sun (not on camera rays, depth 0, which may
    /// see its disc), and space is black. An upward ray at midday has τ̄ ≈
    /// 0.1: without forcing, 9 paths in 10 leave with nothing further and
    /// the tenth carries all the higher orders.
    pub(super) fn force_collision(
        &self,
        tracker: &mut crate::render::tracker::Tracker<'_>,
        span: Span,
        depth: u32,
        beta: &mut Lanes,
        rng: &mut Rng,
    ) {
        if depth == 0 || depth > self.plan.segments.forced_collision_depth || span.hits_ground {
            return;
        }
        let p = tracker.force_collision(rng);
        for b in beta {
            *b *= p;
        }
    }
}
