//! The publishing loop shared by every edge role: a role's [`Producer`] is ticked at a fixed
//! wall-clock rate and hands back encoded messages per stream; the loop numbers them per
//! stream, stamps them with the edge clock and publishes them until a count, a duration or the
//! shutdown ends it. Between ticks the producer is handed the cloud's pushes on its own keys
//! (`risktwin/v1/<site>/<id>/{scenario,policy,…}`) and its reports about them are published.

use crate::clock::{CLOCK_STEPS_EVERY, ClockModel, ClockSteps, EdgeClock};
use crate::delivery::{DeliveryWatch, StreamSent};
use crate::error::EdgeError;
use crate::summary::SentSummary;
use risktwin_align::MAX_EDGE_PAYLOAD_BYTES;
use risktwin_common::telemetry::{Frame, Header};
use risktwin_transport::keyexpr::{CloudToEdge, EdgeReport, cloud_to_edge, edge_report};
use risktwin_transport::recovery::DEFAULT_OUTAGE;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::{
    Delivery, EdgeStream, Shutdown, SiteId, SourceId, StreamPublisher, TransportConfig, TransportError, close, connect,
    declare_alive, protobuf, retire,
};
use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// What every edge role is configured with.
#[derive(Debug, Clone)]
pub struct EdgeConfig {
    /// The site the edge belongs to.
    pub site: SiteId,
    /// The edge's id.
    pub id: SourceId,
    /// How to join the Zenoh network.
    pub transport: TransportConfig,
    /// Base rate, Hz of wall time: a vehicle's state messages per second, an RSU's observations
    /// per second. A vehicle's state samples are 20 ms of simulated time apart (interpolated in
    /// the world's 50 ms physics steps, [`crate::cadence`]) and an RSU's 100 ms, so a rate above
    /// 50 Hz (RSU: 10 Hz) runs faster than real time.
    pub rate_hz: f64,
    /// Stop after this many messages on the base stream (vehicle: `state`; RSU: each stream).
    pub count: Option<u64>,
    /// Stop after this long.
    pub duration: Option<Duration>,
    /// How the edge clock differs from true time.
    pub clock: ClockModel,
    /// How long to wait for a subscriber (the cloud) before publishing anyway.
    pub wait_for_cloud: Duration,
    /// The longest outage (router restart, partition) the streams survive: each keeps its last
    /// rate × this many samples for the cloud to fetch (`risktwin_transport::recovery`).
    pub cache_span: Duration,
    /// A file of clock steps the edge clock follows ([`ClockSteps`]).
    pub clock_steps: Option<std::path::PathBuf>,
    /// The scenario the edge's world is sampled from.
    pub kind: risktwin_common::scenario::ScenarioKind,
    /// Run seed of the scenario sample.
    pub scenario_seed: u64,
    /// The key whose signature a vehicle needs on a policy update (`--trust-key`); `None`: it
    /// takes no policy from the network.
    pub trust_key: Option<risktwin_policy::signature::PolicyVerifyingKey>,
    /// The learned driver a vehicle starts with (`--driver`); `None`: the reference driver. A
    /// signed policy update from the cloud replaces it.
    pub driver: Option<crate::scene::ActivePolicy>,
    /// Watch the cloud's delivery acknowledgements and its liveliness, wait for them at the end
    /// and report what was not delivered ([`crate::delivery`]); off (`--no-ack`) for an edge
    /// that publishes without a RiskTwin cloud on purpose.
    pub ack: bool,
}

impl EdgeConfig {
    /// A config with the defaults of docs/cli.md for `id` at `site`.
    pub fn new(site: SiteId, id: SourceId, rate_hz: f64) -> Self {
        EdgeConfig {
            site,
            id,
            transport: TransportConfig::default(),
            rate_hz,
            count: None,
            duration: None,
            clock: ClockModel::default(),
            wait_for_cloud: Duration::from_secs(10),
            cache_span: DEFAULT_OUTAGE,
            clock_steps: None,
            kind: risktwin_common::scenario::ScenarioKind::CutIn,
            scenario_seed: 0,
            trust_key: None,
            driver: None,
            ack: true,
        }
    }
}

/// Hands out headers: per-stream sequence numbers and the edge clock's stamps of this tick.
pub struct Stamper<'a> {
    source: &'a str,
    seq: &'a mut [u64; EdgeStream::ALL.len()],
    /// Streams held back this tick (the cloud sheds them): their messages take no number.
    shed: u64,
    capture_time_ns: i64,
    publish_time_ns: i64,
}

impl Stamper<'_> {
    /// The header of the next message on `stream` (its sequence number is taken).
    pub fn header(&mut self, stream: EdgeStream) -> Header {
        let seq = &mut self.seq[stream.index()];
        let header = Header {
            source: self.source.to_owned(),
            seq: *seq,
            capture_time_ns: self.capture_time_ns,
            publish_time_ns: self.publish_time_ns,
            frame: Frame::World,
        };
        // A message held back is never sent: the next one takes its number, so the stream's
        // numbers stay without gaps and the cloud counts nothing lost.
        if self.shed & (1 << stream.index()) == 0 {
            *seq += 1;
        }
        header
    }

    /// The header of report number `seq` (reports are numbered by the producer).
    pub fn report_header(&self, seq: u64) -> Header {
        Header {
            source: self.source.to_owned(),
            seq,
            capture_time_ns: self.capture_time_ns,
            publish_time_ns: self.publish_time_ns,
            frame: Frame::World,
        }
    }

    /// The edge's id.
    pub fn source(&self) -> &str {
        self.source
    }
}

/// A role's message source, ticked by [`run_producer`].
pub trait Producer {
    /// The streams it publishes; the first is the base stream `count` applies to.
    fn streams(&self) -> &[EdgeStream];
    /// Ticks per base-stream message (a vehicle ticks at 100 Hz for CAN, twice per state).
    fn ticks_per_base(&self) -> u32;
    /// Messages on `stream` per base-stream message (a vehicle: 4 CAN frames per state), which
    /// sizes the stream's recovery cache.
    fn messages_per_base(&self, stream: EdgeStream) -> f64;
    /// Tick number `tick`: append the encoded messages due, in publishing order.
    fn tick(&mut self, tick: u64, stamper: &mut Stamper<'_>, out: &mut Vec<(EdgeStream, Vec<u8>)>);
    /// The cloud pushes it accepts (each subscribed on the edge's own key).
    fn pushes(&self) -> &[CloudToEdge] {
        &[]
    }
    /// One push received, tagged `encoding` (called before a tick, never concurrently with one).
    fn on_push(&mut self, _push: CloudToEdge, _encoding: &str, _payload: &[u8]) {}
    /// Moves the reports due into `out` (called after each tick).
    fn reports(&mut self, _out: &mut Vec<(EdgeReport, Vec<u8>)>) {}
}

/// Declares the reliable publisher of one report key.
async fn report_publisher(
    session: &risktwin_transport::zenoh::Session,
    config: &EdgeConfig,
    report: EdgeReport,
) -> Result<Publisher<'static>, TransportError> {
    let key = edge_report(&config.site, &config.id, report);
    session
        .declare_publisher(key.clone())
        .encoding(protobuf(report.message()))
        .congestion_control(CongestionControl::Block)
        .await
        .map_err(|e| TransportError::Declare { what: "publisher", key, reason: e.to_string() })
}

/// Runs `producer` for `config` until the base stream has sent `count`, `duration` has passed
/// or `shutdown` fires; then undeclares, closes the session and reports what was sent.
pub async fn run_producer(
    config: &EdgeConfig,
    producer: &mut dyn Producer,
    shutdown: Shutdown,
) -> Result<SentSummary, EdgeError> {
    if !(config.rate_hz.is_finite() && config.rate_hz > 0.0 && config.rate_hz <= 1e5) {
        return Err(EdgeError::BadRate { stream: producer.streams()[0].as_str(), rate_hz: config.rate_hz });
    }
    let streams = producer.streams().to_vec();
    let mut stop = shutdown.clone();
    let session = tokio::select! {
        opened = connect(&config.transport) => opened?,
        _ = stop.wait() => return Ok(SentSummary::new(config, streams.iter().map(|s| (*s, 0)), None)),
    };
    let mut publishers = Vec::with_capacity(streams.len());
    for stream in &streams {
        let delivery = Delivery::live(config.rate_hz * producer.messages_per_base(*stream), config.cache_span);
        publishers.push(StreamPublisher::declare(&session, &config.site, &config.id, *stream, delivery)?);
    }
    let mut push_subscribers = Vec::new();
    for push in producer.pushes().to_vec() {
        let key = cloud_to_edge(&config.site, &config.id, push);
        let subscriber = session.declare_subscriber(key.clone()).await.map_err(|e| TransportError::Declare {
            what: "subscriber",
            key,
            reason: e.to_string(),
        })?;
        push_subscribers.push((push, subscriber));
    }
    // The token comes after the push subscribers: a cloud pushing to this edge waits for the
    // token (cloud/src/network/push.rs), and seeing it must mean the subscribers exist. Zenoh
    // 1.10 sends every declaration of a session (subscriber, token) at the same `Control`
    // priority, hence in declaration order over each link, and each node's routing tables apply
    // and forward a face's declarations in arrival order; a link that comes up later (a peer met
    // through gossip) is sent the existing subscribers before the tokens (hat/peer/mod.rs,
    // `new_transport_unicast_face`). So wherever the token is seen, the subscribers reached the
    // same node first.
    let token = declare_alive(&session, &config.site, &config.id).await?;
    // Before the wait for a subscriber, so that the cloud's token is seen from the start.
    let watch = if config.ack { Some(DeliveryWatch::start(&session, &config.site, &config.id).await?) } else { None };
    let mut report_publishers: Vec<(EdgeReport, Publisher<'static>)> = Vec::new();
    let mut reports = Vec::new();
    for publisher in &publishers {
        if !publisher.wait_for_subscriber(config.wait_for_cloud, shutdown.clone()).await? && !shutdown.is_fired() {
            tracing::warn!("edge {}: no subscriber on {} yet, publishing anyway", config.id, publisher.key());
        }
    }

    let tick_period = Duration::from_secs_f64(1.0 / (config.rate_hz * f64::from(producer.ticks_per_base())));
    let start = Instant::now();
    let deadline = config.duration.map(|d| start + d);
    let epoch_ns = unix_ns();
    let mut clock = EdgeClock::new(config.clock, epoch_ns);
    let mut steps = config.clock_steps.as_deref().map(ClockSteps::new);
    let mut steps_read = start;
    let mut seq = [0u64; EdgeStream::ALL.len()];
    let mut sent = [0u64; EdgeStream::ALL.len()];
    // Messages held back because the cloud sheds their stream, per stream.
    let mut shed = [0u64; EdgeStream::ALL.len()];
    let mut shed_mask = 0u64;
    let sent_metrics = crate::live_metrics::sent_counters(config.site.as_str(), config.id.as_str(), &streams);
    // The numbers of messages refused as too large, per stream.
    let mut refused: [Vec<u64>; EdgeStream::ALL.len()] = Default::default();
    let base = streams[0].index();
    let mut out = Vec::new();
    let mut result = Ok(());
    let mut tick = 0u64;
    loop {
        let due = start + tick_period * u32::try_from(tick).unwrap_or(u32::MAX);
        // A base message's ticks are finished before the count stops the loop (a vehicle's
        // second CAN tick after its last state).
        let whole = tick.is_multiple_of(u64::from(producer.ticks_per_base()));
        if (whole && config.count.is_some_and(|n| sent[base] >= n)) || deadline.is_some_and(|d| due > d) {
            break;
        }
        // The first tick goes out before the shutdown is looked at, so that "publishing"
        // (which tests wait for) always means something was sent.
        if tick > 0 {
            tokio::select! {
                _ = tokio::time::sleep_until(due.into()) => {}
                _ = stop.wait() => break,
            }
        }
        let now = Instant::now();
        if let Some(steps) = steps.as_mut()
            && (tick == 0 || now.duration_since(steps_read) >= CLOCK_STEPS_EVERY)
        {
            steps_read = now;
            let by_ns = steps.read_new();
            if by_ns != 0 {
                clock.step(by_ns);
                tracing::info!("edge {}: clock stepped by {} ms", config.id, by_ns as f64 / 1e6);
            }
        }
        let elapsed = now.duration_since(start);
        let mask = watch.as_ref().map_or(0, |w| w.shed_mask(now));
        if mask != shed_mask {
            let held: Vec<&str> = streams.iter().filter(|s| mask & (1 << s.index()) != 0).map(|s| s.as_str()).collect();
            tracing::warn!("edge {}: the cloud is overloaded: holding back {held:?}", config.id);
            shed_mask = mask;
        }
        let mut stamper = Stamper {
            source: config.id.as_str(),
            seq: &mut seq,
            shed: shed_mask,
            capture_time_ns: clock.capture_ns(elapsed),
            publish_time_ns: clock.now_ns(elapsed),
        };
        for (push, subscriber) in &push_subscribers {
            while let Ok(Some(sample)) = subscriber.try_recv() {
                producer.on_push(*push, &sample.encoding().to_string(), &sample.payload().to_bytes());
            }
        }
        out.clear();
        producer.tick(tick, &mut stamper, &mut out);
        producer.reports(&mut reports);
        for (report, payload) in reports.drain(..) {
            let index = match report_publishers.iter().position(|(r, _)| *r == report) {
                Some(i) => i,
                None => {
                    let p = report_publisher(&session, config, report).await?;
                    report_publishers.push((report, p));
                    report_publishers.len() - 1
                }
            };
            let publisher = &report_publishers[index].1;
            if let Err(e) = publisher.put(payload).await {
                result =
                    Err(TransportError::Put { key: publisher.key_expr().to_string(), reason: e.to_string() }.into());
                break;
            }
        }
        for (stream, payload) in out.drain(..) {
            let Some(publisher) = publishers.iter().find(|p| p.stream() == Some(stream)) else { continue };
            let i = stream.index();
            if shed_mask & (1 << i) != 0 {
                shed[i] += 1;
                continue;
            }
            if payload.len() > MAX_EDGE_PAYLOAD_BYTES {
                // Its number is the next one of the stream: every message takes one, in order.
                let seq = sent[i] + refused[i].len() as u64;
                tracing::error!(
                    "edge {}: {} message {seq} is {} bytes, more than {MAX_EDGE_PAYLOAD_BYTES}: not sent",
                    config.id,
                    stream.as_str(),
                    payload.len()
                );
                refused[i].push(seq);
                continue;
            }
            if let Err(e) = publisher.put(payload) {
                result = Err(e.into());
                break;
            }
            sent[i] += 1;
            sent_metrics[i].absolute(sent[i]);
        }
        if result.is_err() {
            break;
        }
        if tick == 0 {
            tracing::info!("edge {}: publishing", config.id);
        }
        tick += 1;
    }

    let numbers: Vec<(EdgeStream, StreamSent)> = streams
        .iter()
        .map(|s| {
            let (sent, refused) = (sent[s.index()], std::mem::take(&mut refused[s.index()]));
            (*s, StreamSent { numbered: sent + refused.len() as u64, sent, refused, skipped: Vec::new() })
        })
        .collect();
    // The publishers (and their caches) stay while the edge waits: the cloud may still fetch.
    let delivery = match watch {
        Some(watch) => Some(watch.settle(&numbers).await?),
        None => None,
    };
    let mut summary = SentSummary::new(config, numbers.iter().map(|(s, n)| (*s, n.sent)), delivery);
    summary.shed =
        streams.iter().filter(|s| shed[s.index()] > 0).map(|s| (s.as_str().to_owned(), shed[s.index()])).collect();
    crate::live_metrics::export_final(&summary.site, &summary.source, &summary.sent, summary.delivery.as_ref());
    if summary.delivery.as_ref().is_some_and(|d| d.total_undelivered() == 0) {
        // All accounted for: nothing left for the cloud to fetch, no need to linger.
        for publisher in publishers {
            publisher.undeclare()?;
        }
    } else {
        retire(publishers).await?;
    }
    for (_, subscriber) in push_subscribers {
        subscriber.undeclare().await.map_err(|e| EdgeError::Shutdown { reason: e.to_string() })?;
    }
    for (_, publisher) in report_publishers {
        publisher.undeclare().await.map_err(|e| EdgeError::Shutdown { reason: e.to_string() })?;
    }
    token.undeclare().await.map_err(|e| EdgeError::Shutdown { reason: e.to_string() })?;
    close(session).await?;
    result.map(|()| summary)
}

impl SentSummary {
    /// The summary of what the edge of `config` sent, per stream, and what became of it when
    /// the edge watched its delivery.
    pub(crate) fn new(
        config: &EdgeConfig,
        sent: impl IntoIterator<Item = (EdgeStream, u64)>,
        delivery: Option<crate::summary::DeliverySummary>,
    ) -> Self {
        SentSummary {
            site: config.site.to_string(),
            source: config.id.to_string(),
            sent: sent.into_iter().map(|(s, n)| (s.as_str().to_owned(), n)).collect(),
            shed: BTreeMap::new(),
            delivery,
        }
    }
}
