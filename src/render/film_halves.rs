//! The film's reading under a [`HalfMirror`] (see the module documentation
//! of [`super::film`], "Mirror halves"): each pixel's two parts with their
//! mirror images', the camera samples' and the splats'.

use super::alloc::try_filled;
use super::camera::HalfMirror;
use super::exact::ExactPlane;
use super::Film;

impl Film {
    /// The film reading each pixel's two parts split by `halves` together
    /// with their mirror images' (see the module documentation), which
    /// must be a symmetry of the scene as the camera sees it; `None`: none.
    pub(crate) fn try_with_halves(
        mut self,
        halves: Option<HalfMirror>,
    ) -> Result<Self, std::collections::TryReserveError> {
        let (w, h) = (self.width as usize, self.height as usize);
        (self.left_sum, self.left_weight) = match halves {
            Some(_) => (ExactPlane::try_new(w, h)?, try_filled(w * h, 0.0)?),
            None => (ExactPlane::default(), Vec::new()),
        };
        self.halves = halves;
        Ok(self)
    }

    /// [`Self::mean`] with `halves`: each part of the pixel with its
    /// partner's where their rows are at the same stage (as
    /// [`Self::mean_with`] reads pairs), plus past the draft the pixel's
    /// own splats.
    pub(super) fn halves_mean(&self, index: usize) -> [f64; 3] {
        let past = self.past_draft(index);
        let usable = |i: usize| self.past_draft(i) == past;
        let mut mean = self.halves_camera_mean(index, &usable);
        if self.splat_paths > 0 && past {
            for (m, s) in mean.iter_mut().zip(self.halves_splats(index, &usable)) {
                *m += s / self.splat_paths as f64;
            }
        }
        mean
    }

    /// The sum of the splats of pixel `index` read with `halves`: those
    /// that landed in each part, averaged with those in its partner's
    /// (where `usable`). Each part's sum over the splatted paths estimates
    /// its share of the pixel's splatted light, as the partner's does its
    /// reflection's.
    fn halves_splats(&self, index: usize, usable: &dyn Fn(usize) -> bool) -> [f64; 3] {
        let own = self.splat_sum[index].map(f64::from);
        let Some(halves) = self.halves.filter(|_| !self.splat_left.is_empty()) else {
            return own;
        };
        let w = self.width as usize;
        let (x, row) = (index % w, index - index % w);
        let part = |i: usize, left: bool| {
            let (all, l) = (self.splat_sum[i], self.splat_left[i]);
            [0, 1, 2].map(|c| f64::from(if left { l[c] } else { all[c] - l[c] }))
        };
        let paired = |left: bool, partner: usize| {
            let mine = part(index, left);
            if partner != index && usable(partner) {
                let theirs = part(partner, left);
                [0, 1, 2].map(|c| 0.5 * (mine[c] + theirs[c]))
            } else {
                mine
            }
        };
        let l = paired(true, row + halves.left_partner(x, w));
        let r = paired(false, row + halves.right_partner(x, w));
        [0, 1, 2].map(|c| l[c] + r[c])
    }

    /// Mean XYZ of pixel `index`'s camera samples read with `halves`: the
    /// integral over each part, g × the mean of the samples drawn in the
    /// left part with its left partner's, (1 − g) × that of the right
    /// part's with its right partner's (partners where `usable`). The
    /// samples of a part (its partner's reflected) are uniform over it and
    /// their number and weights fixed in advance ([`HalfMirror::in_left`],
    /// the plan of [`super::adaptive::plan_linked`]), so each term is
    /// unbiased. Before both parts hold samples, the pixel's own mean.
    pub(super) fn halves_camera_mean(
        &self,
        index: usize,
        usable: &dyn Fn(usize) -> bool,
    ) -> [f64; 3] {
        let own = |i: usize| self.pixel_mean(i, None, &|i| self.xyz_sum.get(i));
        let Some(halves) = self.halves else {
            return own(index);
        };
        let w = self.width as usize;
        let (x, row) = (index % w, index - index % w);
        // (sums, weight) of a pixel's left and right parts.
        let parts = |i: usize| {
            let (all, l) = (self.xyz_sum.get(i), self.left_sum.get(i));
            let lw = self.left_weight[i];
            let r = [0, 1, 2].map(|c| all[c] - l[c]);
            [(l, lw), (r, self.pixel_weight(i) - lw)]
        };
        let mine = parts(index);
        let mean = |left: bool, partner: usize| {
            let side = usize::from(!left);
            let (mut sum, mut weight) = mine[side];
            if partner != index && usable(partner) {
                let (s, pw) = parts(partner)[side];
                for (a, b) in sum.iter_mut().zip(s) {
                    *a += b;
                }
                weight += pw;
            }
            (weight > 0.0).then(|| sum.map(|s| s.to_f64() / weight))
        };
        let g = halves.split;
        match (
            mean(true, row + halves.left_partner(x, w)),
            mean(false, row + halves.right_partner(x, w)),
        ) {
            (Some(l), Some(r)) => [0, 1, 2].map(|c| g * l[c] + (1.0 - g) * r[c]),
            _ => own(index),
        }
    }
}
