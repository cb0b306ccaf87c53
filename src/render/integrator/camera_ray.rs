//! The camera ray's estimator: next-event points from the tabulated
//! expected sunlight along the view ray, and the branches the camera path
//! goes on as.

use super::{
    Branches, CameraDensities, DVec3, Integrator, Lanes, Light, Rng, Segment, SpectralLanes,
    MAX_BRANCHES, MAX_SUNLIGHT_SAMPLES,
};

impl Integrator<'_> {
    /// The camera ray's segment, estimated through in-scattering points from
    /// the cached expected-sunlight density ([`CameraDensities`]) like one
    /// segment of [`Self::sunlit_segment`]; returns the vertices the path
    /// branches into.
    pub(super) fn camera_segment(
        &self,
        camera: &CameraDensities,
        dir: DVec3,
        lanes: &SpectralLanes,
        radiance: &mut Light,
        rng: &mut Rng,
    ) -> Branches {
        let origin = camera.origin_m();
        let beta = Lanes::splat(1.0);
        let Some(span) = self.medium.span(origin, dir) else {
            self.add_sun_disc(dir, 0, &beta, lanes, radiance);
            return [None; MAX_BRANCHES];
        };
        let density = camera.density(self.medium, dir, span);
        let n = (self.plan.camera.samples as usize).min(MAX_SUNLIGHT_SAMPLES);
        let segment = Segment {
            origin,
            dir,
            span,
            depth: 0,
        };
        let branches = (self.plan.camera.branches as usize).clamp(1, MAX_BRANCHES);
        self.estimate_segment(
            &segment,
            &beta,
            Some(&density),
            (n, branches),
            lanes,
            radiance,
            rng,
        )
    }
}
