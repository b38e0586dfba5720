//! The publishing loop shared by every edge role: a few streams at fixed rates, numbered per
//! stream, stamped by the edge clock, until a count, a duration or the shutdown ends it.

use crate::clock::{ClockModel, EdgeClock};
use crate::{EdgeError, SentSummary};
use risktwin_transport::standin::StandIn;
use risktwin_transport::{
    EdgeStream, Shutdown, SiteId, SourceId, StreamPublisher, TransportConfig, close, connect, declare_alive,
};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

/// One stream and its rate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StreamPlan {
    /// Which stream.
    pub stream: EdgeStream,
    /// Messages per second.
    pub rate_hz: f64,
}

/// What every edge role is configured with.
#[derive(Debug, Clone)]
pub struct EdgeConfig {
    /// The site the edge belongs to.
    pub site: SiteId,
    /// The edge's id.
    pub id: SourceId,
    /// How to join the Zenoh network.
    pub transport: TransportConfig,
    /// Base rate, Hz (a vehicle's state rate; an RSU's object-list rate).
    pub rate_hz: f64,
    /// Stop each stream after this many messages.
    pub count: Option<u64>,
    /// Stop after this long.
    pub duration: Option<Duration>,
    /// How the edge clock differs from true time.
    pub clock: ClockModel,
    /// Payload size, bytes (the stand-in record is padded up to it).
    pub payload_bytes: usize,
    /// How long to wait for a subscriber (the cloud) before publishing anyway.
    pub wait_for_cloud: Duration,
}

impl EdgeConfig {
    /// A config with the defaults of cli.md for `id` at `site`.
    pub fn new(site: SiteId, id: SourceId, rate_hz: f64) -> Self {
        EdgeConfig {
            site,
            id,
            transport: TransportConfig::default(),
            rate_hz,
            count: None,
            duration: None,
            clock: ClockModel::default(),
            payload_bytes: 64,
            wait_for_cloud: Duration::from_secs(10),
        }
    }

    fn check(&self, plans: &[StreamPlan]) -> Result<(), EdgeError> {
        for plan in plans {
            if !(plan.rate_hz.is_finite() && plan.rate_hz > 0.0 && plan.rate_hz <= 1e6) {
                return Err(EdgeError::BadRate { stream: plan.stream.as_str(), rate_hz: plan.rate_hz });
            }
        }
        Ok(())
    }
}

/// Per-stream progress of the loop.
struct Lane {
    publisher: StreamPublisher,
    period: Duration,
    next_due: Instant,
    sent: u64,
}

/// Runs `plans` for `config` until every stream has sent `count`, `duration` has passed or
/// `shutdown` fires; then undeclares, closes the session and reports what was sent.
pub async fn run_streams(
    config: &EdgeConfig,
    plans: &[StreamPlan],
    shutdown: Shutdown,
) -> Result<SentSummary, EdgeError> {
    config.check(plans)?;
    let mut stop = shutdown.clone();
    let session = tokio::select! {
        opened = connect(&config.transport) => opened?,
        _ = stop.wait() => return Ok(SentSummary::new(config, plans.iter().map(|p| (p.stream, 0)))),
    };
    let token = declare_alive(&session, &config.site, &config.id).await?;
    let mut publishers = Vec::with_capacity(plans.len());
    for plan in plans {
        publishers.push(StreamPublisher::declare(&session, &config.site, &config.id, plan.stream).await?);
    }
    for publisher in &publishers {
        if !publisher.wait_for_subscriber(config.wait_for_cloud, shutdown.clone()).await? && !shutdown.is_fired() {
            eprintln!("edge {}: no subscriber on {} yet, publishing anyway", config.id, publisher.key());
        }
    }

    let start = Instant::now();
    let deadline = config.duration.map(|d| start + d);
    let epoch_ns = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as i64);
    let mut clock = EdgeClock::new(config.clock, epoch_ns);
    let mut lanes: Vec<Lane> = publishers
        .into_iter()
        .zip(plans)
        .map(|(publisher, plan)| Lane {
            publisher,
            period: Duration::from_secs_f64(1.0 / plan.rate_hz),
            next_due: start,
            sent: 0,
        })
        .collect();
    let done =
        |lane: &Lane| config.count.is_some_and(|n| lane.sent >= n) || deadline.is_some_and(|d| lane.next_due > d);

    // The first round goes out before the shutdown is looked at, so that "publishing" (which
    // tests wait for) always means something was sent.
    let mut result = publish_due(config, &mut lanes, &mut clock, start, start, &done).await;
    if result.is_ok() {
        eprintln!("edge {}: publishing", config.id);
    }
    while result.is_ok() {
        let Some(next) = lanes.iter().filter(|l| !done(l)).map(|l| l.next_due).min() else { break };
        tokio::select! {
            _ = tokio::time::sleep_until(next.into()) => {}
            _ = stop.wait() => break,
        }
        result = publish_due(config, &mut lanes, &mut clock, start, Instant::now(), &done).await;
    }

    let summary = SentSummary::new(config, lanes.iter().map(|l| (l.publisher.stream(), l.sent)));
    for lane in lanes {
        lane.publisher.undeclare().await?;
    }
    token.undeclare().await.map_err(|e| EdgeError::Shutdown { reason: e.to_string() })?;
    close(session).await?;
    result.map(|()| summary)
}

/// Publishes one message on every lane that is due at `now`.
async fn publish_due(
    config: &EdgeConfig,
    lanes: &mut [Lane],
    clock: &mut EdgeClock,
    start: Instant,
    now: Instant,
    done: &impl Fn(&Lane) -> bool,
) -> Result<(), EdgeError> {
    for lane in lanes.iter_mut() {
        if done(lane) || lane.next_due > now {
            continue;
        }
        let elapsed = now.duration_since(start);
        let record = StandIn {
            source: config.id.as_str(),
            seq: lane.sent,
            capture_time_ns: clock.capture_ns(elapsed),
            publish_time_ns: clock.now_ns(elapsed),
        };
        let payload = record.encode(config.payload_bytes)?;
        lane.publisher.put(payload).await?;
        lane.sent += 1;
        lane.next_due += lane.period;
    }
    Ok(())
}
