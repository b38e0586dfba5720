//! Per-source clock offset and drift, estimated from one-way messages.
//!
//! Each message carries the source's capture time `c` (its own clock: offset, drift, jitter)
//! and the cloud's receive time `r`. With the source clock mapped onto the cloud clock as
//! `cloud(c) = c + θ(c)`, `r − c = θ(c) + d` where the network delay `d ≥ 0`. So the lower
//! envelope of `r − c` over time traces `θ(c) + d_min`, and its slope is the relative drift.
//! This is the minimum-filter approach of Paxson ("On calibrating measurements of packet transit
//! times", SIGMETRICS 1998) and Moon, Skelly & Towsley ("Estimation and removal of clock skew
//! from network delay measurements", INFOCOM 1999), in the latter's linear-programming form:
//! 1. receive time is cut into buckets (default 1 s); each bucket keeps its minimum `r − c` and
//!    the capture time where it occurred;
//! 2. over the last K closed buckets (default 32), the line under every minimum with the least
//!    total distance to them (Moon et al.'s linear program; it touches their lower convex hull
//!    at their mean capture time) gives drift and offset. It supports the points from below, and
//!    minima raised by congestion or by a backlog delivered late (a cloud catching up after a
//!    stall) lie above it without moving it — a least-squares line through them would tilt and
//!    map live samples into the future. The drift is bounded (500 ppm, NTP's tolerance): when
//!    late minima are all there is on one side (a long catch-up), the bound keeps the line near
//!    the last good ones.
//!
//! With one-way messages only, the offset and the minimum delay `d_min` cannot be told apart
//! (NTP needs round trips for that): the estimate maps a capture onto the earliest cloud time it
//! could have been received, i.e. true time + `d_min`. For alignment this is a constant per
//! source of the size of the fastest network path (≈ 0.1–2 ms on a LAN).
//!
//! Determinism: the mapping only uses messages received strictly earlier (closed buckets, or the
//! running minimum of earlier receive times while warming up), so messages that share a receive
//! time map the same whatever their order.

/// How the estimator is set up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClockConfig {
    /// Width of one minimum-filter bucket, in receive time.
    pub bucket_ns: i64,
    /// How many closed buckets the fit spans (the sliding window).
    pub buckets: usize,
    /// Closed buckets needed before the drift is fitted; before that the offset is the minimum.
    pub min_fit_buckets: usize,
    /// The largest rate error a source clock is believed to have: the fit's drift is clamped to
    /// it. 500 ppm is the frequency tolerance NTP's reference implementation assumes of any
    /// clock (its `MAXFREQ`); quartz clocks stay within ±100 ppm.
    pub max_drift_ppm: u32,
}

impl Default for ClockConfig {
    fn default() -> Self {
        Self { bucket_ns: 1_000_000_000, buckets: 32, min_fit_buckets: 4, max_drift_ppm: 500 }
    }
}

#[derive(Debug, Clone, Copy)]
struct Bucket {
    min_delta_ns: i64,
    at_capture_ns: i64,
}

/// `θ(c) = offset_ns + slope · (c − ref_ns)`.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Line {
    ref_ns: i64,
    offset_ns: f64,
    slope: f64,
}

/// One source's clock estimate; fixed memory after construction.
#[derive(Debug, Clone)]
pub struct ClockEstimator {
    cfg: ClockConfig,
    ring: Vec<Bucket>,
    ring_next: usize,
    /// Scratch for the fit: the ring's points, then their lower hull.
    hull: Vec<(f64, f64)>,
    open: Option<(i64, Bucket)>,
    last_receive_ns: Option<i64>,
    /// Minimum `r − c` over messages received before `last_receive_ns`.
    committed_min_ns: Option<i64>,
    /// Minimum `r − c` over messages received at `last_receive_ns`.
    tie_min_ns: Option<i64>,
    line: Option<Line>,
    latest_capture_ns: Option<i64>,
    samples: u64,
}

impl ClockEstimator {
    /// An estimator that knows nothing yet.
    pub fn new(cfg: ClockConfig) -> Self {
        let cfg = ClockConfig {
            bucket_ns: cfg.bucket_ns.max(1),
            buckets: cfg.buckets.max(2),
            min_fit_buckets: cfg.min_fit_buckets.max(2),
            max_drift_ppm: cfg.max_drift_ppm,
        };
        Self {
            cfg,
            ring: Vec::with_capacity(cfg.buckets),
            ring_next: 0,
            hull: Vec::with_capacity(cfg.buckets),
            open: None,
            last_receive_ns: None,
            committed_min_ns: None,
            tie_min_ns: None,
            line: None,
            latest_capture_ns: None,
            samples: 0,
        }
    }

    /// Forgets everything (e.g. after the source's clock stepped), keeping the memory.
    pub fn reset(&mut self) {
        self.ring.clear();
        self.ring_next = 0;
        self.open = None;
        self.last_receive_ns = None;
        self.committed_min_ns = None;
        self.tie_min_ns = None;
        self.line = None;
        self.latest_capture_ns = None;
        self.samples = 0;
    }

    /// Takes in one message: [`roll_to`](Self::roll_to) its receive time, then records it.
    pub fn observe(&mut self, capture_ns: i64, receive_ns: i64) {
        self.roll_to(receive_ns);
        self.record(capture_ns, receive_ns);
    }

    /// Moves the estimator's notion of "now" to `receive_ns`, closing buckets that ended and
    /// refitting; idempotent. Call it before [`to_cloud_ns`](Self::to_cloud_ns) for a message so
    /// that messages sharing a receive time map alike.
    pub fn roll_to(&mut self, receive_ns: i64) {
        if self.last_receive_ns.is_some_and(|last| receive_ns <= last) {
            return;
        }
        self.last_receive_ns = Some(receive_ns);
        self.committed_min_ns = min_opt(self.committed_min_ns, self.tie_min_ns.take());
        let id = receive_ns.div_euclid(self.cfg.bucket_ns);
        match self.open {
            Some((open_id, bucket)) if id > open_id => {
                self.push_closed(bucket);
                self.open = None;
                self.refit();
            }
            _ => {}
        }
    }

    /// Records one message at the current receive time without rolling.
    fn record(&mut self, capture_ns: i64, receive_ns: i64) {
        let delta_ns = receive_ns.saturating_sub(capture_ns);
        self.samples += 1;
        self.latest_capture_ns = Some(self.latest_capture_ns.map_or(capture_ns, |l| l.max(capture_ns)));
        self.tie_min_ns = Some(self.tie_min_ns.map_or(delta_ns, |m| m.min(delta_ns)));
        let id = receive_ns.div_euclid(self.cfg.bucket_ns);
        match &mut self.open {
            Some((_, b)) => {
                // A receive time that went backwards is folded into the open bucket.
                if delta_ns < b.min_delta_ns {
                    *b = Bucket { min_delta_ns: delta_ns, at_capture_ns: capture_ns };
                }
            }
            None => self.open = Some((id, Bucket { min_delta_ns: delta_ns, at_capture_ns: capture_ns })),
        }
    }

    fn push_closed(&mut self, b: Bucket) {
        if self.ring.len() < self.cfg.buckets {
            self.ring.push(b);
        } else {
            self.ring[self.ring_next] = b;
        }
        self.ring_next = (self.ring_next + 1) % self.cfg.buckets;
    }

    fn refit(&mut self) {
        if self.ring.len() < self.cfg.min_fit_buckets {
            self.line = None;
            return;
        }
        let ref_ns = self.ring.iter().map(|b| b.at_capture_ns).min().unwrap_or(0);
        // Saturating, like every difference of a source's stamps here: they may span more than
        // i64 (a hostile or broken clock), which a fit may get wrong but not overflow.
        self.hull.clear();
        self.hull
            .extend(self.ring.iter().map(|b| (b.at_capture_ns.saturating_sub(ref_ns) as f64, b.min_delta_ns as f64)));
        let mean_x = self.hull.iter().map(|p| p.0).sum::<f64>() / self.hull.len() as f64;
        let (offset_ns, slope) = lower_support_at(&mut self.hull, mean_x, f64::from(self.cfg.max_drift_ppm) * 1e-6);
        self.line = Some(Line { ref_ns, offset_ns, slope });
    }

    /// `θ(c)`: what to add to a capture time to get cloud time; `None` before any message was
    /// received strictly earlier than the current receive time.
    pub fn offset_at_ns(&self, capture_ns: i64) -> Option<i64> {
        match self.line {
            Some(l) => {
                let dx = capture_ns.saturating_sub(l.ref_ns) as f64;
                Some((l.offset_ns + l.slope * dx).round() as i64)
            }
            None => self.committed_min_ns,
        }
    }

    /// A capture time of this source on the cloud clock; `None` while nothing is known.
    pub fn to_cloud_ns(&self, capture_ns: i64) -> Option<i64> {
        self.offset_at_ns(capture_ns).map(|o| capture_ns.saturating_add(o))
    }

    /// The current offset (cloud − source) at the latest capture time seen, in ns.
    pub fn offset_ns(&self) -> Option<i64> {
        self.latest_capture_ns.and_then(|c| self.offset_at_ns(c))
    }

    /// The source clock's rate error against the cloud clock, in parts per million
    /// (positive: the source clock runs fast); 0 until the drift is fitted.
    pub fn drift_ppm(&self) -> f64 {
        // cloud = c + θ(c), dcloud/dc = 1 + slope, so the source runs at 1/(1 + slope).
        self.line.map_or(0.0, |l| (1.0 / (1.0 + l.slope) - 1.0) * 1e6)
    }

    /// Whether the drift has been fitted (enough closed buckets).
    pub fn is_fitted(&self) -> bool {
        self.line.is_some()
    }

    /// Messages observed since construction or the last reset.
    pub fn samples(&self) -> u64 {
        self.samples
    }
}

/// The line under every point of `points`, of slope within ±`max_slope`, that lies highest at
/// `x` — of all such lines, the one with the least total distance to the points when `x` is
/// their mean: `(offset at x = 0, slope)`. Sorts `points` and leaves their lower convex hull in
/// it (no allocation).
///
/// The supporting line at `x` touches the lower hull along the edge that spans `x` (or, at `x`
/// beyond the hull, the end vertex, slope 0 there); a steeper edge gives way to the bound,
/// through the vertex that keeps the line under all points (the objective is concave in the
/// slope). Points above the hull — minima raised by congestion — do not move it, which a
/// least-squares fit through them would. The bound matters when raised minima make the hull
/// itself: after a stall, the late backlog's minima lie a stall's length to the right of the
/// last good ones, and once their mean crosses into that gap the edge spanning it climbs to them.
fn lower_support_at(points: &mut Vec<(f64, f64)>, x: f64, max_slope: f64) -> (f64, f64) {
    points.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
    // Andrew's monotone chain, lower half, in place: the hull never outruns the input.
    let mut k = 0;
    for i in 0..points.len() {
        let p = points[i];
        // A point at the same x as the hull's last is higher (sorted): not on the lower hull.
        if k > 0 && points[k - 1].0 == p.0 {
            continue;
        }
        while k >= 2 && cross(points[k - 2], points[k - 1], p) <= 0.0 {
            k -= 1;
        }
        points[k] = p;
        k += 1;
    }
    points.truncate(k);
    let edge = points.windows(2).find(|e| e[0].0 <= x && x <= e[1].0);
    // One distinct x (a stalled source clock), or `x` outside: flat.
    let slope = edge.map_or(0.0, |e| (e[1].1 - e[0].1) / (e[1].0 - e[0].0)).clamp(-max_slope, max_slope);
    // Through the hull vertex the line touches: the lowest `y − slope·x` (the edge's own ends
    // when the slope was not clamped).
    let offset = points.iter().map(|p| p.1 - slope * p.0).fold(f64::INFINITY, f64::min);
    (offset, slope)
}

/// Positive when `a → b → c` turns counter-clockwise.
fn cross(a: (f64, f64), b: (f64, f64), c: (f64, f64)) -> f64 {
    (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0)
}

fn min_opt(a: Option<i64>, b: Option<i64>) -> Option<i64> {
    match (a, b) {
        (Some(x), Some(y)) => Some(x.min(y)),
        (x, None) => x,
        (None, y) => y,
    }
}

#[cfg(test)]
#[path = "clock_tests.rs"]
mod tests;
