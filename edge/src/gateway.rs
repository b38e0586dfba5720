//! The vehicle's edge gateway (`risktwin edge gateway`): takes the sensor producer's samples from
//! iceoryx2 shared memory ([`crate::sensor`]), validates them, converts them to the protobuf
//! messages of `edge vehicle` and publishes each on the vehicle's Zenoh key of its stream.
//!
//! A reader thread owns the iceoryx2 ports (they are not `Send`) and hands encoded messages to
//! the Zenoh side through a bounded channel, so a slow network holds the producer back (lossless
//! delivery) instead of dropping. The sample's sequence number and capture time travel
//! unchanged; the publish time is the gateway's reading of the same edge clock model at
//! forwarding. The run ends when the producer signals the end of its stream (the gateway drains
//! every queue, then confirms with [`ControlEvent::Drained`]) or on SIGINT/SIGTERM: the gateway
//! keeps forwarding for up to [`STOP_GRACE`] waiting for that end (a signal to the process group
//! stops the producer too, which then ends its stream), then forwards what is queued and stops;
//! a producer still running learns that its gateway left.
//!
//! Like `edge vehicle`, the gateway watches the cloud's delivery acknowledgements of its
//! vehicle's streams ([`crate::delivery`]) and reports what no cloud accounted for; a sequence
//! number the producer used but the gateway did not forward (a rejected sample) is reported as
//! never sent, not as undelivered.

use crate::cadence::messages_per_state;
use crate::clock::EdgeClock;
use crate::delivery::{DeliveryWatch, Numbering, StreamSent};
use crate::error::EdgeError;
use crate::publish::EdgeConfig;
use crate::scene::{Scene, detected, feasible_spec};
use crate::shm::{
    ControlEvent, ShmCanFrame, ShmControl, ShmError, ShmObjectList, ShmPayload, ShmPayloadError, ShmQos, ShmSample,
    ShmSubscriber, ShmVehicleState,
};
use crate::summary::DeliverySummary;
use risktwin_common::sensor::PerceivedObject;
use risktwin_common::telemetry::{CanFrame, Frame, Header, ObjectList, VehicleStateSample};
use risktwin_common::vehicle::Vehicle;
use risktwin_protos::encode;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::{
    Delivery, EdgeStream, Shutdown, StreamPublisher, TransportError, close, connect, declare_alive, retire,
};
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};
use thiserror::Error;
use tokio::sync::{mpsc, oneshot};

/// Longest sleep of an idle reader between looks at the stop flag and the control events.
const IDLE_WAIT: Duration = Duration::from_millis(10);
/// How long a signalled gateway keeps forwarding while waiting for the producer's end.
const STOP_GRACE: Duration = Duration::from_millis(500);
/// Encoded messages in flight between the reader thread and the Zenoh publishers.
const FORWARD_QUEUE: usize = 1024;
/// Rejected samples logged per stream; the rest are only counted.
const LOGGED_REJECTS: u64 = 10;

/// The streams a gateway forwards, in [`GatewaySummary`] order.
const STREAMS: [EdgeStream; 3] = [EdgeStream::State, EdgeStream::Can, EdgeStream::Perception];

/// Why the sensor producer or the gateway stopped with an error.
#[derive(Debug, Error)]
pub enum ShmRoleError {
    #[error(transparent)]
    Edge(#[from] EdgeError),
    #[error(transparent)]
    Shm(#[from] ShmError),
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error("no gateway subscribed to {service} within {waited_s} s (start `risktwin edge gateway` first)")]
    NoGateway { service: String, waited_s: f64 },
    #[error("the gateway left {service} while the sensor was publishing; samples since are lost")]
    GatewayLeft { service: String },
    #[error("the gateway did not confirm draining the stream within {waited_s} s; samples may be lost")]
    NotDrained { waited_s: f64 },
    #[error("the shared-memory reader thread panicked")]
    ReaderPanicked,
    #[error("the Zenoh side of the gateway stopped before the shared-memory reader")]
    ForwarderStopped,
}

/// What a gateway forwarded and rejected per stream, printed as JSON on exit.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GatewaySummary {
    /// The vehicle's site.
    pub site: String,
    /// The vehicle's id.
    pub source: String,
    /// Messages published on Zenoh per stream name.
    pub forwarded: BTreeMap<String, u64>,
    /// Samples that failed validation per stream name (counted, logged, dropped).
    pub rejected: BTreeMap<String, u64>,
    /// Whether the producer signalled the end of its stream (else a signal stopped the gateway).
    pub end_of_stream: bool,
    /// What became of the forwarded messages, when the gateway watched the cloud's
    /// acknowledgements.
    #[serde(flatten)]
    pub delivery: Option<DeliverySummary>,
}

impl GatewaySummary {
    /// Why this run cannot count as a success, if it cannot (see [`DeliverySummary::failure`]).
    pub fn failure(&self) -> Option<String> {
        self.delivery.as_ref()?.failure(&self.source, self.forwarded.values().sum())
    }
}

/// The Zenoh stream of a shared-memory payload and its conversion to the wire message.
trait Forward: ShmPayload {
    /// The Zenoh stream it is published on.
    const EDGE: EdgeStream;
    /// The encoded protobuf message of this (validated) sample.
    fn encode(&self, reader: &mut Reader) -> Result<Vec<u8>, ShmPayloadError>;
}

impl Forward for ShmVehicleState {
    const EDGE: EdgeStream = EdgeStream::State;

    fn encode(&self, reader: &mut Reader) -> Result<Vec<u8>, ShmPayloadError> {
        let (state, footprint) = self.to_common()?;
        // Pose and velocity are those of the footprint centre, which sits ahead of the centre of
        // gravity by the vehicle's own geometry: the gateway knows its vehicle's model.
        reader.model.state = state;
        let sample = VehicleStateSample {
            header: reader.header(self.seq, self.capture_time_ns),
            pose: reader.model.pose(),
            velocity: reader.model.velocity(),
            speed_mps: state.speed_mps,
            accel_mps2: state.accel_mps2,
            yaw_rate_radps: state.yaw_rate_radps,
            steer_rad: state.steer_rad,
            footprint,
        };
        Ok(encode(&sample))
    }
}

impl Forward for ShmCanFrame {
    const EDGE: EdgeStream = EdgeStream::Can;

    fn encode(&self, reader: &mut Reader) -> Result<Vec<u8>, ShmPayloadError> {
        let frame = CanFrame {
            header: reader.header(self.seq, self.capture_time_ns),
            can_id: self.can_id,
            data: self.data,
            dlc: self.dlc,
        };
        Ok(encode(&frame))
    }
}

impl Forward for ShmObjectList {
    const EDGE: EdgeStream = EdgeStream::Perception;

    fn encode(&self, reader: &mut Reader) -> Result<Vec<u8>, ShmPayloadError> {
        let mut perceived = std::mem::take(&mut reader.objects);
        let converted = self.to_perceived(&mut perceived);
        let list = converted.map(|()| ObjectList {
            header: reader.header(self.seq, self.capture_time_ns),
            objects: perceived.iter().map(detected).collect(),
        });
        reader.objects = perceived;
        Ok(encode(&list?))
    }
}

/// The reader thread's state: conversion context, counters and the hand-over to Zenoh.
struct Reader {
    source: String,
    clock: EdgeClock,
    start: Instant,
    model: Vehicle,
    objects: Vec<PerceivedObject>,
    rejected: [u64; STREAMS.len()],
    tx: mpsc::Sender<(EdgeStream, u64, Vec<u8>)>,
}

/// What the reader thread ends with.
struct ReaderEnd {
    rejected: [u64; STREAMS.len()],
    end_of_stream: bool,
}

impl Reader {
    fn header(&self, seq: u64, capture_time_ns: i64) -> Header {
        Header {
            source: self.source.clone(),
            seq,
            capture_time_ns,
            publish_time_ns: self.clock.now_ns(self.start.elapsed()),
            frame: Frame::World,
        }
    }

    fn slot(stream: EdgeStream) -> usize {
        STREAMS.iter().position(|s| *s == stream).expect("the gateway forwards only its own streams")
    }

    fn reject(&mut self, stream: EdgeStream, error: &dyn std::error::Error) {
        let count = &mut self.rejected[Self::slot(stream)];
        *count += 1;
        if *count <= LOGGED_REJECTS {
            let source = error.source().map(|s| format!(": {s}")).unwrap_or_default();
            tracing::warn!("gateway {}: rejected {} sample: {error}{source}", self.source, stream.as_str());
        }
    }

    /// Forwards one receive result; `Ok(true)` when a sample was taken (forwarded or rejected),
    /// `Ok(false)` when the queue was empty. Fails on port errors and when Zenoh's side is gone.
    fn handle<T: Forward>(&mut self, received: Result<Option<ShmSample<T>>, ShmError>) -> Result<bool, ShmRoleError> {
        let sample = match received {
            Ok(Some(sample)) => sample,
            Ok(None) => return Ok(false),
            Err(e @ ShmError::InvalidSample { .. }) => {
                self.reject(T::EDGE, &e);
                return Ok(true);
            }
            Err(e) => return Err(e.into()),
        };
        match sample.encode(self) {
            Ok(bytes) => {
                let seq = sample.seq();
                // Released before the (possibly waiting) hand-over so that the producer gets its
                // chunk back as early as possible.
                drop(sample);
                if self.tx.blocking_send((T::EDGE, seq, bytes)).is_err() {
                    return Err(ShmRoleError::ForwarderStopped);
                }
            }
            Err(source) => {
                let e = ShmError::InvalidSample { stream: T::STREAM, seq: sample.seq(), source };
                self.reject(T::EDGE, &e);
            }
        }
        Ok(true)
    }

    /// Takes every queued sample of `subscriber`; how many.
    fn drain<T: Forward>(&mut self, subscriber: &ShmSubscriber<T>) -> Result<u64, ShmRoleError> {
        let mut taken = 0;
        while self.handle(subscriber.try_receive())? {
            taken += 1;
        }
        Ok(taken)
    }
}

/// The gateway's three subscribers.
struct Subscribers {
    state: ShmSubscriber<ShmVehicleState>,
    can: ShmSubscriber<ShmCanFrame>,
    objects: ShmSubscriber<ShmObjectList>,
}

/// The reader thread: opens the control service and the subscribers, reports readiness, then
/// forwards until the producer's end (drained, confirmed) or the stop flag (drained once).
fn read_loop(
    id: &str,
    mut reader: Reader,
    stop: &AtomicBool,
    ready: oneshot::Sender<Result<(), ShmError>>,
) -> Result<ReaderEnd, ShmRoleError> {
    let opened = (|| -> Result<_, ShmError> {
        // The control listener exists before any subscriber, so the producer's end is heard.
        let control = ShmControl::open(id)?;
        let qos = ShmQos::default();
        let subscribers = Subscribers {
            state: ShmSubscriber::new(id, qos)?,
            can: ShmSubscriber::new(id, qos)?,
            objects: ShmSubscriber::new(id, qos)?,
        };
        Ok((control, subscribers))
    })();
    let (control, subs) = match opened {
        Ok(opened) => {
            let _ = ready.send(Ok(()));
            opened
        }
        Err(e) => {
            // The caller reports the error it was handed and does not wait for this thread.
            let _ = ready.send(Err(e));
            return Ok(ReaderEnd { rejected: [0; STREAMS.len()], end_of_stream: false });
        }
    };
    let mut give_up_at = None;
    let end_of_stream = loop {
        let stopping = stop.load(Ordering::Acquire);
        // Looked at before the drain: every sample sent before the end is queued by then.
        let ended = control.heard(ControlEvent::EndOfStream)?;
        let taken = reader.drain(&subs.state)? + reader.drain(&subs.objects)? + reader.drain(&subs.can)?;
        if ended {
            break true;
        }
        if stopping {
            // A terminal's Ctrl-C reaches the producer too, which then ends its stream: waiting
            // a moment for that end lets both exit cleanly with nothing lost.
            let deadline = *give_up_at.get_or_insert_with(|| Instant::now() + STOP_GRACE);
            if Instant::now() >= deadline {
                break false;
            }
        }
        if taken == 0 {
            // CAN goes out every tick, so its wake-up also covers the other two streams.
            reader.handle(subs.can.receive_timeout(IDLE_WAIT))?;
        }
    };
    if end_of_stream {
        control.signal(ControlEvent::Drained)?;
    }
    Ok(ReaderEnd { rejected: reader.rejected, end_of_stream })
}

/// Runs the gateway of vehicle `config.id` until its producer ends the stream or `shutdown`
/// fires. Needs a multi-threaded Tokio runtime.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<GatewaySummary, ShmRoleError> {
    crate::shm::validate_vehicle_id(config.id.as_str())?;
    // The vehicle's geometry (the offset of its footprint centre from its centre of gravity).
    let model = Scene::new(feasible_spec(config.scenario_seed, config.kind)?).world.ego;
    let mut stop = shutdown.clone();
    let session = tokio::select! {
        opened = connect(&config.transport) => opened?,
        _ = stop.wait() => return Ok(summary(config, [0; 3], [0; 3], false, None)),
    };
    let token = declare_alive(&session, &config.site, &config.id).await?;
    let watch = if config.ack { Some(DeliveryWatch::start(&session, &config.site, &config.id).await?) } else { None };
    let mut publishers = Vec::with_capacity(STREAMS.len());
    for stream in STREAMS {
        // The sensor's cadence, at the gateway's rate (the sensor's, unless told otherwise).
        let delivery = Delivery::live(config.rate_hz * messages_per_state(stream), config.cache_span);
        publishers.push(StreamPublisher::declare(&session, &config.site, &config.id, stream, delivery)?);
    }
    for publisher in &publishers {
        if !publisher.wait_for_subscriber(config.wait_for_cloud, shutdown.clone()).await? && !shutdown.is_fired() {
            tracing::warn!("gateway {}: no subscriber on {} yet, forwarding anyway", config.id, publisher.key());
        }
    }

    let (tx, mut rx) = mpsc::channel(FORWARD_QUEUE);
    let (ready_tx, ready_rx) = oneshot::channel();
    let stop_flag = Arc::new(AtomicBool::new(shutdown.is_fired()));
    let epoch_ns = unix_ns();
    let reader = Reader {
        source: config.id.to_string(),
        clock: EdgeClock::new(config.clock, epoch_ns),
        start: Instant::now(),
        model,
        objects: Vec::new(),
        rejected: [0; STREAMS.len()],
        tx,
    };
    let id = config.id.to_string();
    let flag = Arc::clone(&stop_flag);
    let thread = std::thread::Builder::new()
        .name("shm-reader".into())
        .spawn(move || read_loop(&id, reader, &flag, ready_tx))
        .map_err(|e| EdgeError::Shutdown { reason: format!("cannot start the shared-memory reader: {e}") })?;
    match ready_rx.await {
        Ok(Ok(())) => tracing::info!("gateway {}: ready", config.id),
        Ok(Err(e)) => return Err(e.into()),
        Err(_) => return Err(ShmRoleError::ReaderPanicked),
    }

    let mut numbering: [Numbering; STREAMS.len()] = Default::default();
    let mut result: Result<(), TransportError> = Ok(());
    loop {
        tokio::select! {
            message = rx.recv() => {
                let Some((stream, seq, bytes)) = message else { break };
                let slot = Reader::slot(stream);
                if let Err(e) = publishers[slot].put(bytes) {
                    result = Err(e);
                    break;
                }
                numbering[slot].sent(seq);
            }
            _ = stop.wait(), if !stop_flag.load(Ordering::Acquire) => stop_flag.store(true, Ordering::Release),
        }
    }
    stop_flag.store(true, Ordering::Release);
    drop(rx);
    let end = tokio::task::spawn_blocking(move || thread.join())
        .await
        .map_err(|_| ShmRoleError::ReaderPanicked)?
        .map_err(|_| ShmRoleError::ReaderPanicked)?;

    let sent: Vec<(EdgeStream, StreamSent)> =
        STREAMS.iter().zip(&numbering).map(|(s, n)| (*s, n.stream_sent())).collect();
    // The publishers (and their caches) stay while the gateway waits: the cloud may still fetch.
    let delivery = match watch {
        Some(watch) if result.is_ok() => Some(watch.settle(&sent).await?),
        _ => None,
    };
    retire(publishers).await?;
    token.undeclare().await.map_err(|e| EdgeError::Shutdown { reason: e.to_string() })?;
    close(session).await?;
    result?;
    let end = end?;
    let forwarded = numbering.map(|n| n.count());
    Ok(summary(config, forwarded, end.rejected, end.end_of_stream, delivery))
}

fn summary(
    config: &EdgeConfig,
    forwarded: [u64; 3],
    rejected: [u64; 3],
    end_of_stream: bool,
    delivery: Option<DeliverySummary>,
) -> GatewaySummary {
    let named = |counts: [u64; 3]| STREAMS.iter().zip(counts).map(|(s, n)| (s.as_str().to_owned(), n)).collect();
    let summary = GatewaySummary {
        site: config.site.to_string(),
        source: config.id.to_string(),
        forwarded: named(forwarded),
        rejected: named(rejected),
        end_of_stream,
        delivery,
    };
    crate::live_metrics::export_final(&summary.site, &summary.source, &summary.forwarded, summary.delivery.as_ref());
    summary
}
