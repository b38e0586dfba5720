//! Overload: how far behind the ingest runs, and which streams it sheds (docs/keyexpr.md,
//! "Overload").
//!
//! The measure is the one CoDel (Nichols & Jacobson, RFC 8289) judges a queue by: the *least*
//! delay seen over an interval. Each live state message's delay is its receive time minus its
//! capture time mapped onto the cloud clock; the mapping is anchored on the smallest delay the
//! source has shown, so what is left is time spent queued (in the network, the router, this
//! process's receive path), whatever the clocks. Jitter makes single delays large, but the
//! least of a second's worth is large only when every message waited: the ingest is behind.
//!
//! Shedding is asked for (`cloud --shed-after-ms MS`, the target); without it the delay is
//! measured and reported only, and nothing is shed: a cloud catching up after a fault would
//! otherwise shed what its recovery is meant to deliver whole. With it, each [`WINDOW`] the level
//! moves one step: up while the least delay exceeds the target, down while it stays under half
//! of it. Level 1 sheds the CAN stream, level 2 every stream but the
//! vehicles' states, which are never shed (the twin is made of them). The streams shed go to the
//! edges in the delivery acknowledgements, so that they stop sending them at the source.

use crate::network::summary::LoadSummary;
use risktwin_transport::EdgeStream;
use std::time::{Duration, Instant};

/// How long a delay is measured before the level moves.
pub const WINDOW: Duration = Duration::from_secs(1);

/// The streams each level sheds, by priority: CAN first (the most messages, the least used),
/// then perception and the roadside streams; states never.
const SHED_BY_LEVEL: [&[EdgeStream]; 3] =
    [&[], &[EdgeStream::Can], &[EdgeStream::Can, EdgeStream::Perception, EdgeStream::Rsu, EdgeStream::Signal]];

/// The highest level.
pub const MAX_LEVEL: u8 = (SHED_BY_LEVEL.len() - 1) as u8;

/// The running measure and the level it sets.
#[derive(Debug, Default)]
pub struct LoadGauge {
    /// The least delay over a window above which the ingest sheds; `None`: it never does.
    target_ns: Option<i64>,
    window_start: Option<Instant>,
    /// Least delay seen in the current window; `None` before the first.
    least_ns: Option<i64>,
    /// Least delay of the last full window.
    last_least_ns: Option<i64>,
    level: u8,
    level_max: u8,
    /// Windows ended at a level above 0.
    windows_shedding: u64,
}

impl LoadGauge {
    /// A gauge that sheds once the least delay of a window exceeds `target` (`None`: never).
    pub fn new(target: Option<Duration>) -> Self {
        let target_ns = target.map(|t| i64::try_from(t.as_nanos()).unwrap_or(i64::MAX));
        LoadGauge { target_ns, ..LoadGauge::default() }
    }

    /// A live message waited `delay_ns`.
    pub fn observe(&mut self, delay_ns: i64) {
        self.least_ns = Some(self.least_ns.map_or(delay_ns, |l| l.min(delay_ns)));
    }

    /// Ends the window if it is over at `now`; the new level when it changed.
    pub fn roll(&mut self, now: Instant) -> Option<u8> {
        let start = *self.window_start.get_or_insert(now);
        if now.duration_since(start) < WINDOW {
            return None;
        }
        self.window_start = Some(now);
        if self.level > 0 {
            self.windows_shedding += 1;
        }
        // A window without a live state says nothing: the level stays.
        let least = self.least_ns.take()?;
        self.last_least_ns = Some(least);
        let target = self.target_ns?;
        let level = if least > target {
            (self.level + 1).min(MAX_LEVEL)
        } else if least < target / 2 {
            self.level.saturating_sub(1)
        } else {
            self.level
        };
        if level == self.level {
            return None;
        }
        self.level = level;
        self.level_max = self.level_max.max(level);
        Some(level)
    }

    /// The streams shed now.
    pub fn shed(&self) -> &'static [EdgeStream] {
        SHED_BY_LEVEL[usize::from(self.level)]
    }

    /// The streams shed now, as the ingest core's bit mask.
    pub fn shed_mask(&self) -> u64 {
        self.shed().iter().fold(0, |mask, s| mask | 1 << s.index())
    }

    /// The level now, the highest reached, the seconds spent above 0 and the last window's
    /// least delay (ms).
    pub fn summary(&self) -> LoadSummary {
        LoadSummary {
            shed_level: self.level,
            shed_level_max: self.level_max,
            shedding_s: self.windows_shedding * WINDOW.as_secs(),
            queue_delay_ms: self.last_least_ns.map(|ns| ns.max(0) as u64 / 1_000_000),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The target the documentation uses: 200 ms.
    const TARGET_NS: i64 = 200_000_000;

    #[test]
    fn the_level_climbs_one_step_a_window_while_behind_and_comes_back_when_the_queue_drains() {
        let mut gauge = LoadGauge::new(Some(Duration::from_nanos(TARGET_NS as u64)));
        let t0 = Instant::now();
        let at = |w: u32| t0 + WINDOW * w;
        assert_eq!(gauge.roll(at(0)), None);
        // One message waiting long among quick ones is jitter, not load.
        gauge.observe(5 * TARGET_NS);
        gauge.observe(1_000_000);
        assert_eq!(gauge.roll(at(1)), None);
        assert!(gauge.shed().is_empty());
        for (w, level) in [(2, 1), (3, 2), (4, 2)] {
            gauge.observe(TARGET_NS + 1);
            let changed = gauge.roll(at(w));
            assert_eq!(gauge.summary().shed_level, level, "window {w}: {changed:?}");
        }
        assert_eq!(gauge.shed_mask(), 0b11110, "all but states (index 0)");
        // Between half the target and the target: hold.
        gauge.observe(TARGET_NS * 3 / 4);
        assert_eq!(gauge.roll(at(5)), None);
        // A window without a live state: hold.
        assert_eq!(gauge.roll(at(6)), None);
        gauge.observe(1_000_000);
        assert_eq!(gauge.roll(at(7)), Some(1));
        assert_eq!(gauge.shed(), &[EdgeStream::Can]);
        gauge.observe(1_000_000);
        assert_eq!(gauge.roll(at(8)), Some(0));
        let summary = gauge.summary();
        assert_eq!((summary.shed_level, summary.shed_level_max), (0, 2));
        assert_eq!(summary.shedding_s, 6, "{summary:?}");
    }

    #[test]
    fn without_a_target_the_delay_is_measured_and_nothing_is_shed() {
        let mut gauge = LoadGauge::new(None);
        let t0 = Instant::now();
        for w in 0..4 {
            gauge.observe(10 * TARGET_NS);
            assert_eq!(gauge.roll(t0 + WINDOW * w), None);
        }
        assert_eq!(gauge.shed_mask(), 0);
        assert_eq!(gauge.summary().queue_delay_ms, Some(2000));
    }
}
