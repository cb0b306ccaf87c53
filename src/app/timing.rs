//! How long the preview takes: the latency from a scene change to its first
//! frames ([`LatencyStats`]) and the render time the status bar shows
//! ([`RenderClock`]).

use std::time::{Duration, Instant};

/// Time from a scene change to its first frame on screen.
#[derive(Clone, Copy, Debug, Default)]
pub struct LatencyStats {
    /// The latest measurement.
    pub last: Option<Duration>,
    /// Number of measurements.
    pub count: u32,
    /// Sum of all measurements.
    pub total: Duration,
    /// Largest measurement.
    pub max: Duration,
}

impl LatencyStats {
    /// Add one measurement.
    pub(crate) fn record(&mut self, latency: Duration) {
        self.last = Some(latency);
        self.count += 1;
        self.total += latency;
        self.max = self.max.max(latency);
    }

    /// Mean of all measurements.
    pub fn mean(&self) -> Option<Duration> {
        (self.count > 0).then(|| self.total / self.count)
    }
}

/// Render time of the image on screen: wall time since the latest scene
/// change, draft included, pauses not counted, stopped when the target is
/// reached (or the render failed). The service's own `Frame::elapsed` starts
/// again at the full-size render after a draft and counts pauses, so it
/// understates a fresh render and overstates a paused one.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct RenderClock {
    /// Time counted before `running_since`.
    banked: Duration,
    /// Counting since then; `None` while paused or stopped.
    running_since: Option<Instant>,
    /// The render is over; only a scene change starts the clock again.
    stopped: bool,
}

impl RenderClock {
    /// A scene change at `now`: count from zero (from the resume if paused).
    pub(crate) fn restart(&mut self, now: Instant, paused: bool) {
        *self = Self {
            banked: Duration::ZERO,
            running_since: (!paused).then_some(now),
            stopped: false,
        };
    }

    /// Stop counting until [`Self::resume`].
    pub(crate) fn pause(&mut self, now: Instant) {
        if let Some(since) = self.running_since.take() {
            self.banked += now.saturating_duration_since(since);
        }
    }

    /// Count again after a pause (not after [`Self::stop`]).
    pub(crate) fn resume(&mut self, now: Instant) {
        if !self.stopped && self.running_since.is_none() {
            self.running_since = Some(now);
        }
    }

    /// The render finished (or failed) at `now`.
    pub(crate) fn stop(&mut self, now: Instant) {
        self.pause(now);
        self.stopped = true;
    }

    /// The time counted up to `now`.
    pub(crate) fn read(&self, now: Instant) -> Duration {
        self.banked
            + self
                .running_since
                .map_or(Duration::ZERO, |since| now.saturating_duration_since(since))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn render_clock_counts_from_the_change_without_pauses_and_stops_when_done() {
        let t0 = Instant::now();
        let mut clock = RenderClock::default();
        assert_eq!(clock.read(t0), Duration::ZERO);
        clock.restart(t0, false);
        assert_eq!(clock.read(t0 + 300 * MS), 300 * MS);
        clock.pause(t0 + 500 * MS);
        assert_eq!(clock.read(t0 + 9000 * MS), 500 * MS);
        clock.resume(t0 + 10_000 * MS);
        assert_eq!(clock.read(t0 + 10_250 * MS), 750 * MS);
        clock.stop(t0 + 11_000 * MS);
        assert_eq!(clock.read(t0 + 60_000 * MS), 1500 * MS);
        // Pausing and resuming a finished render leaves it finished.
        clock.pause(t0 + 61_000 * MS);
        clock.resume(t0 + 62_000 * MS);
        assert_eq!(clock.read(t0 + 63_000 * MS), 1500 * MS);
        // A change made while paused starts counting at the resume.
        clock.restart(t0 + 70_000 * MS, true);
        assert_eq!(clock.read(t0 + 71_000 * MS), Duration::ZERO);
        clock.resume(t0 + 72_000 * MS);
        assert_eq!(clock.read(t0 + 72_100 * MS), 100 * MS);
    }
}
