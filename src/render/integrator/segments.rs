//! Segment estimators at low sun: a path segment estimated through
//! next-event points drawn from its expected sunlight, built per segment
//! or read from the sky guide's cached densities, and the forced first
//! collision of delta tracking.

use super::{
    ground_point, rayleigh, Branches, Component, DVec3, GuideAt, InScatterDistribution, Integrator,
    Lanes, Light, Next, Rng, Segment, SegmentDensity, Span, SpectralLanes, DIRECTION_UNIFORMS,
    MAX_BRANCHES, MAX_SUNLIGHT_SAMPLES,
};

/// The air's expected share of the light beyond a camera ray that meets a
/// splatted ground (the segment density's scattered light over it plus the
/// ground's transmitted light times the largest albedo) at and above which
/// the ray's branches into that air always go on; below it they go on with
/// probability share / this (at least 1/20). From near the ground the share
/// is a few per cent and a branch is a whole path of multiple scattering;
/// from orbit it is about a third and they all go on.
const CAMERA_BRANCH_SHARE: f64 = 0.25;

impl<'a> Integrator<'a> {
    /// The segment from `origin` along `dir` after `depth` scatterings,
    /// reached with weight `beta` (`at`: the guide at `origin`, if already
    /// looked up), estimated through in-scattering points drawn from its
    /// expected sunlight instead of delta-tracked collisions: from the
    /// guide's cached density of rays from points of the same altitude and
    /// solar zenith where there is a guide, else from an
    /// [`InScatterDistribution`] built for the segment. For a segment from
    /// x along ω,
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
    /// Returns where the path goes on.
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
    /// weighted 1/branches (see [`Self::sunlit_segment`]).
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
        // The camera ray's ground reflects skylight through its splats.
        let ground_goes_on = goes_on
            && span.hits_ground
            && self.medium.ground_albedo_max > 0.0
            && !(depth == 0 && self.ground_splatting);
        let p_medium = match (distribution, goes_on) {
            // The camera ray's light scattered again in the air is splatted.
            _ if depth == 0 && self.splatting => 0.0,
            (Some(d), true) if ground_goes_on => {
                // The largest albedo over wavelength: a density, not a value.
                // Neither share known: both ways even.
                d.air_share(self.medium.ground_albedo_max)
                    .map_or(0.5, |share| share.clamp(0.05, 0.95))
            }
            // Without Russian roulette the path must still end: go on with
            // the expected scattered fraction, as an analog path would.
            (Some(d), true) if !opts.termination.russian_roulette => {
                d.shares(0.0).0.clamp(0.05, 1.0)
            }
            // A camera ray whose ground's skylight is splatted: its branches
            // carry only the air in front of the ground, a small share of
            // the pixel from near the ground, so they are rouletted by that
            // share (`BENCHMARKS.md`, the camera's branches over the ground).
            (Some(d), true)
                if depth == 0 && span.hits_ground && opts.termination.russian_roulette =>
            {
                // Neither share known: every branch goes on. (Dividing by a
                // power of two is exact: the same bits as the share's
                // denominator scaled.)
                d.air_share(self.medium.ground_albedo_max)
                    .map_or(1.0, |share| (share / CAMERA_BRANCH_SHARE).clamp(0.05, 1.0))
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
            let e_sun = self.sun_irradiance_toward(to_sun, lanes);
            let mu = dir.dot(to_sun);
            let tr_sun = self.shadow(x, to_sun, lanes, rng);
            let weight = 1.0 / (n as f64 * density);
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
                // Each ground branch bounces on its own (see `Integrator::ground_bounce`).
                let x = ground_point(self.medium, normal);
                let guide = self.bounce_guide(normal);
                let sky = self.ground_sky(normal, lanes);
                let weight: Lanes = Lanes::from_fn(|j| {
                    through[j] * lanes.ground_albedo[j] * share / (1.0 - p_medium)
                });
                for ((slot, _), u) in next[..branches]
                    .iter_mut()
                    .zip(&from_medium)
                    .zip(&direction_u)
                    .filter(|((_, &f), _)| !f)
                {
                    Self::ground_sky_in(sky.as_ref(), &weight, lanes, radiance);
                    let Some((bounce, reflect)) =
                        rng.replaying(u, |rng| self.bounce_direction(normal, guide.as_ref(), rng))
                    else {
                        continue;
                    };
                    let weight = weight * reflect;
                    Self::ground_sky_out(sky.as_ref(), bounce, &weight, lanes, radiance);
                    self.ground_control(normal, bounce, &weight, lanes, radiance, rng);
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
        *beta *= tracker.force_collision(rng);
    }
}
