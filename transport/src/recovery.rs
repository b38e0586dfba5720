//! How an edge→cloud stream survives a router restart or a network partition: every stream
//! publisher is a zenoh-ext `AdvancedPublisher` that numbers its samples, keeps the last ones in a
//! bounded cache and announces its last number by heartbeat; the cloud's `AdvancedSubscriber`
//! ([`crate::edge_subscriber`]) sees the gap, fetches what the cache still holds, and counts the
//! rest as lost. See docs/keyexpr.md ("Surviving faults").

use std::time::Duration;
use zenoh::qos::{CongestionControl, Priority};
use zenoh::sample::Sample;

/// How often a stream publisher announces its last sequence number, so that a cloud notices
/// samples lost at the end of a burst (nothing published after them) within about this long.
pub const HEARTBEAT_PERIOD: Duration = Duration::from_millis(500);

/// How long an ending edge keeps its stream caches after its last put: one heartbeat for the cloud
/// to notice a gap at the end, and as long again for its query and the answer.
pub const EXIT_LINGER: Duration = Duration::from_millis(2 * HEARTBEAT_PERIOD.as_millis() as u64);

/// The priority live edge-stream samples travel at: above Zenoh's default `Data`, at which
/// answers to recovery queries arrive (every Zenoh runtime forwards an answer at its query's
/// priority, and zenoh-ext's subscriber queries at `Data`). So the cloud tells a recovered
/// sample from a live one ([`is_recovered`]); and zenoh-ext's heartbeats (`Data`, not
/// configurable) trail the live samples they announce: were they ahead, a congested link would
/// make the cloud ask for samples still queued behind them, and get them twice.
pub const LIVE_PRIORITY: Priority = Priority::DataHigh;

/// The priority answers to recovery queries arrive at (see [`LIVE_PRIORITY`]).
pub const RECOVERY_PRIORITY: Priority = Priority::Data;

/// Whether `sample` came from an advanced publisher's cache (an answer to a recovery query)
/// rather than live: numbered (source info) and at [`RECOVERY_PRIORITY`]. A plain publisher's
/// samples (no source info) are never taken for recovered ones; an advanced publisher that does
/// not publish at [`LIVE_PRIORITY`] (not one of ours) has all its samples counted recovered.
pub fn is_recovered(sample: &Sample) -> bool {
    sample.priority() == RECOVERY_PRIORITY && sample.source_info().is_some()
}

/// The longest outage a live edge stream survives by default: a router restart or a partition
/// up to this long loses nothing. 45 s so that a 30 s stall of the cloud is covered with its
/// aftermath: the stall outlasts Zenoh's 10 s lease, the router drops the cloud's session, and
/// the samples published until the cloud is back and queries the caches count too.
pub const DEFAULT_OUTAGE: Duration = Duration::from_secs(45);

/// The most samples one stream's cache may keep (bounds memory whatever rate × outage says).
pub const MAX_CACHE_SAMPLES: usize = 1_000_000;

/// What a stream publisher does under congestion and how much it keeps for recovery.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Delivery {
    /// Samples kept for retransmission (at least 1, at most [`MAX_CACHE_SAMPLES`]).
    pub cache_samples: usize,
    /// `Drop` for a live producer: a put does not wait for a stalled link (the tick loop keeps its
    /// rate) and what the link dropped is fetched from the cache. (A put still waits while its
    /// stream's cache answers a recovery query: zenoh-ext holds the cache's lock while it sends.) `Block` for an unpaced producer
    /// (a replay, a benchmark), which the transport should slow down rather than outrun its cache.
    pub congestion: CongestionControl,
}

impl Delivery {
    /// A live producer of `rate_hz` samples per second on the stream that must survive an outage
    /// of `outage`: a cache of ⌈rate × outage⌉ samples, congestion `Drop`.
    pub fn live(rate_hz: f64, outage: Duration) -> Self {
        Delivery { cache_samples: cache_samples(rate_hz, outage), congestion: CongestionControl::Drop }
    }

    /// An unpaced producer, paced by the transport (`Block`), with a cache of `cache_samples`.
    pub fn paced_by_transport(cache_samples: usize) -> Self {
        Delivery { cache_samples: cache_samples.clamp(1, MAX_CACHE_SAMPLES), congestion: CongestionControl::Block }
    }
}

/// ⌈`rate_hz` × `outage`⌉ samples, within 1..=[`MAX_CACHE_SAMPLES`] (a rate that is not a
/// positive finite number keeps 1).
pub fn cache_samples(rate_hz: f64, outage: Duration) -> usize {
    let samples = (rate_hz * outage.as_secs_f64()).ceil();
    if !(samples.is_finite() && samples >= 1.0) {
        return 1;
    }
    // Compared as f64 first: a huge product must not wrap when cast.
    if samples >= MAX_CACHE_SAMPLES as f64 { MAX_CACHE_SAMPLES } else { samples as usize }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cache_covers_rate_times_outage_within_bounds() {
        assert_eq!(cache_samples(50.0, Duration::from_secs(30)), 1500);
        assert_eq!(cache_samples(200.0, Duration::from_millis(1500)), 300);
        assert_eq!(cache_samples(0.3, Duration::from_secs(1)), 1, "rounded up");
        for bad in [0.0, -5.0, f64::NAN, f64::INFINITY] {
            assert_eq!(cache_samples(bad, DEFAULT_OUTAGE), 1, "{bad}");
        }
        assert_eq!(cache_samples(1e5, Duration::from_secs(3600)), MAX_CACHE_SAMPLES);
        assert_eq!(cache_samples(50.0, Duration::ZERO), 1);
        let live = Delivery::live(50.0, DEFAULT_OUTAGE);
        assert_eq!((live.cache_samples, live.congestion), (2250, CongestionControl::Drop));
        assert_eq!(Delivery::paced_by_transport(0).cache_samples, 1);
        assert_eq!(Delivery::paced_by_transport(usize::MAX).congestion, CongestionControl::Block);
    }
}
