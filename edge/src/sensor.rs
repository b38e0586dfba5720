//! The vehicle's sensor producer (`risktwin edge sensor`): the world of `edge vehicle`, stepped
//! and stamped the same way (per-stream sequence numbers, capture time from the edge clock), but
//! published zero-copy into iceoryx2 for the vehicle's gateway ([`crate::gateway`]) instead of
//! over Zenoh.
//!
//! What is due at each tick (the interpolated state at 50 Hz, CAN frames every 10 ms, perception
//! every 2nd physics step) is decided by [`crate::cadence`], the same code that ticks
//! [`crate::vehicle`].
//!
//! Nothing is lost at either end of the run: the producer publishes only once every service has
//! a subscriber, and at the end (count, duration or SIGINT/SIGTERM) it signals the end of the
//! stream and keeps its publishers until the gateway has drained them
//! ([`crate::shm::ShmControl`]). A gateway that leaves mid-run stops the producer with an error.

use crate::cadence::{Segment, TICKS_PER_STATE, VehicleOutlet, vehicle_tick};
use crate::clock::EdgeClock;
use crate::error::EdgeError;
use crate::gateway::ShmRoleError;
use crate::publish::EdgeConfig;
use crate::scene::{Scene, feasible_spec};
use crate::shm::{
    ControlEvent, OBJECT_LIST_CAPACITY, ShmCanFrame, ShmControl, ShmError, ShmObjectList, ShmPublisher, ShmQos,
    ShmStream, ShmVehicleState,
};
use crate::summary::SentSummary;
use risktwin_common::telemetry::CAN_DLC;
use risktwin_common::vehicle::Vehicle;
use risktwin_transport::wall_clock::unix_ns;
use risktwin_transport::{EdgeStream, Shutdown};
use std::time::{Duration, Instant};

/// How often the start-up handshake looks at the subscriber counts.
const HANDSHAKE_POLL: Duration = Duration::from_millis(5);

/// The three publishers of one vehicle.
struct Publishers {
    state: ShmPublisher<ShmVehicleState>,
    can: ShmPublisher<ShmCanFrame>,
    objects: ShmPublisher<ShmObjectList>,
}

impl Publishers {
    fn open(id: &str, qos: ShmQos) -> Result<Self, ShmRoleError> {
        Ok(Publishers {
            state: ShmPublisher::new(id, qos)?,
            can: ShmPublisher::new(id, qos)?,
            objects: ShmPublisher::new(id, qos)?,
        })
    }

    /// The service that has no subscriber yet, if any.
    fn without_subscriber(&self) -> Option<&str> {
        [
            (self.state.subscriber_count(), self.state.service_name()),
            (self.can.subscriber_count(), self.can.service_name()),
            (self.objects.subscriber_count(), self.objects.service_name()),
        ]
        .into_iter()
        .find(|(n, _)| *n == 0)
        .map(|(_, name)| name)
    }
}

/// Per-stream sequence numbers and sent counts, indexed by [`EdgeStream::index`].
#[derive(Default)]
struct Counters {
    seq: [u64; EdgeStream::ALL.len()],
}

impl Counters {
    /// Takes the next sequence number of `stream`.
    fn next(&mut self, stream: EdgeStream) -> u64 {
        let seq = &mut self.seq[stream.index()];
        let taken = *seq;
        *seq += 1;
        taken
    }

    /// Messages sent on `stream` so far (every taken number was sent or the run failed).
    fn sent(&self, stream: EdgeStream) -> u64 {
        self.seq[stream.index()]
    }
}

/// The vehicle world and its publishers.
struct Sensor {
    scene: Scene,
    /// The ego over the last step, which the ticks sample.
    segment: Segment,
    publishers: Publishers,
    counters: Counters,
    /// The capture time of the tick being published, ns of the edge clock.
    capture_ns: i64,
}

/// The ticks of [`crate::vehicle::Vehicle`], published as shared-memory samples.
impl VehicleOutlet for Sensor {
    type Error = ShmRoleError;

    fn step(&mut self) -> Result<(), ShmRoleError> {
        self.segment = self.scene.step();
        Ok(())
    }

    fn segment(&self) -> &Segment {
        &self.segment
    }

    fn publish_state(&mut self, ego: &Vehicle) -> Result<(), ShmRoleError> {
        let seq = self.counters.next(EdgeStream::State);
        let state = ShmVehicleState::from_common(seq, self.capture_ns, &ego.state, &ego.params.footprint());
        Ok(self.publishers.state.publish(&state)?)
    }

    fn publish_perception(&mut self) -> Result<(), ShmRoleError> {
        let seq = self.counters.next(EdgeStream::Perception);
        // The list has a fixed capacity; the sensor model yields far fewer in practice.
        let perceived = self.scene.world.perceived();
        let objects = &perceived[..perceived.len().min(OBJECT_LIST_CAPACITY)];
        let capture_ns = self.capture_ns;
        Ok(self.publishers.objects.publish_with(|list| list.fill_from_perceived(seq, capture_ns, objects))?)
    }

    fn publish_can(&mut self, can_id: u32, data: [u8; 8]) -> Result<(), ShmRoleError> {
        let seq = self.counters.next(EdgeStream::Can);
        let frame = ShmCanFrame::new(seq, self.capture_ns, can_id, &data[..usize::from(CAN_DLC)])
            .map_err(|source| ShmError::InvalidSample { stream: ShmStream::Can, seq, source })?;
        Ok(self.publishers.can.publish(&frame)?)
    }
}

/// Runs the sensor producer of `config.id` until its count or duration is reached or `shutdown`
/// fires. Waits up to `config.wait_for_cloud` for the gateway's subscribers before publishing
/// and for its drain confirmation at the end; either missing is an error.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<SentSummary, ShmRoleError> {
    if !(config.rate_hz.is_finite() && config.rate_hz > 0.0 && config.rate_hz <= 1e5) {
        return Err(EdgeError::BadRate { stream: EdgeStream::State.as_str(), rate_hz: config.rate_hz }.into());
    }
    let id = config.id.as_str();
    // Opened first: the gateway's drain confirmation must find this listener.
    let control = ShmControl::open(id)?;
    let publishers = Publishers::open(id, ShmQos::default())?;
    let scene = Scene::new(feasible_spec(config.scenario_seed, config.kind)?);
    let segment = Segment::at_rest(scene.world.ego.clone());
    let mut sensor = Sensor { scene, segment, publishers, counters: Counters::default(), capture_ns: 0 };

    // Start-up handshake: iceoryx2 keeps no history, so nothing goes out before every stream
    // has the gateway's subscriber.
    let mut stop = shutdown.clone();
    let waited = Instant::now();
    if sensor.publishers.without_subscriber().is_some() {
        tracing::info!("sensor {id}: waiting for the gateway");
    }
    while let Some(service) = sensor.publishers.without_subscriber() {
        if waited.elapsed() >= config.wait_for_cloud {
            return Err(ShmRoleError::NoGateway {
                service: service.to_owned(),
                waited_s: config.wait_for_cloud.as_secs_f64(),
            });
        }
        tokio::select! {
            _ = tokio::time::sleep(HANDSHAKE_POLL) => {}
            _ = stop.wait() => return Ok(summary(config, &sensor.counters)),
        }
    }

    let result = publish_loop(config, &mut sensor, stop).await;
    // Whatever stopped the loop, everything sent so far must reach the gateway before the
    // publishers (and their data segments) go away.
    control.signal(ControlEvent::EndOfStream)?;
    // A gateway that already left can confirm nothing more: no waiting for it then.
    let drained = control.heard(ControlEvent::Drained)?
        || (sensor.publishers.without_subscriber().is_none()
            && tokio::task::block_in_place(|| control.wait_for(ControlEvent::Drained, config.wait_for_cloud))?);
    result?;
    if !drained {
        return Err(ShmRoleError::NotDrained { waited_s: config.wait_for_cloud.as_secs_f64() });
    }
    Ok(summary(config, &sensor.counters))
}

/// Ticks the sensor at the CAN rate (twice the state rate) until the count, the duration or the shutdown.
async fn publish_loop(config: &EdgeConfig, sensor: &mut Sensor, mut stop: Shutdown) -> Result<(), ShmRoleError> {
    let tick_period = Duration::from_secs_f64(1.0 / (config.rate_hz * f64::from(TICKS_PER_STATE)));
    let start = Instant::now();
    let deadline = config.duration.map(|d| start + d);
    let epoch_ns = unix_ns();
    let mut clock = EdgeClock::new(config.clock, epoch_ns);
    let mut tick = 0u64;
    loop {
        let due = start + tick_period * u32::try_from(tick).unwrap_or(u32::MAX);
        // The count applies to whole state periods (the second CAN tick after a state still goes out).
        let whole = tick.is_multiple_of(u64::from(TICKS_PER_STATE));
        if (whole && config.count.is_some_and(|n| sensor.counters.sent(EdgeStream::State) >= n))
            || deadline.is_some_and(|d| due > d)
        {
            return Ok(());
        }
        if tick > 0 {
            tokio::select! {
                _ = tokio::time::sleep_until(due.into()) => {}
                _ = stop.wait() => return Ok(()),
            }
        }
        sensor.capture_ns = clock.capture_ns(Instant::now().duration_since(start));
        vehicle_tick(tick, sensor)?;
        // iceoryx2 delivers to the subscribers present at the send: a gateway gone means loss.
        if let Some(service) = sensor.publishers.without_subscriber() {
            return Err(ShmRoleError::GatewayLeft { service: service.to_owned() });
        }
        if tick == 0 {
            tracing::info!("sensor {}: publishing", config.id);
        }
        tick += 1;
    }
}

fn summary(config: &EdgeConfig, counters: &Counters) -> SentSummary {
    let streams = [EdgeStream::State, EdgeStream::Can, EdgeStream::Perception];
    SentSummary::new(config, streams.map(|s| (s, counters.sent(s))), None)
}
