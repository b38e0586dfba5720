//! A synthetic fleet for the ingest benchmarks: many vehicles' real protobuf edge messages
//! (`VehicleState` at 50 Hz, optionally CAN at 100 Hz and perception at 10 Hz), each numbered
//! per stream and stamped by the vehicle's own clock (a per-vehicle offset of up to ±100 ms and
//! a drift of up to ±10 ppm), and a nominal cloud receive time 1–3 ms later. Deterministic: the
//! same configuration yields the same bytes.
//!
//! Messages come out tick by tick (10 ms), vehicles in index order, receive times
//! non-decreasing, which is the order a recording holds them in and a publisher sends them.

use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::sensor::ObjectKind;
use risktwin_common::telemetry::{CanFrame, DetectedObject, Frame, Header, ObjectList, VehicleStateSample};
use risktwin_protos::encode_into;
use risktwin_transport::EdgeStream;

/// The base period of the fleet: every stream's period is a multiple of it.
pub const FLEET_TICK_NS: i64 = 10_000_000;

/// Which streams each synthetic vehicle sends, and how many.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FleetConfig {
    pub vehicles: usize,
    /// CAN frames at 100 Hz next to the 50 Hz state.
    pub can: bool,
    /// A perceived object list (4 objects) at 10 Hz.
    pub perception: bool,
    /// State every this many 10 ms ticks (2: 50 Hz).
    pub state_every_ticks: u64,
    /// Index of the first vehicle (names `veh-<index>`), so that several fleets do not overlap.
    pub first_vehicle: usize,
    /// Cloud time of tick 0, ns since the Unix epoch.
    pub start_ns: i64,
}

impl FleetConfig {
    /// `vehicles` sending state only.
    pub fn states_only(vehicles: usize) -> Self {
        FleetConfig {
            vehicles,
            can: false,
            perception: false,
            state_every_ticks: 2,
            first_vehicle: 0,
            start_ns: 1_700_000_000_000_000_000,
        }
    }

    /// Messages per second of the whole fleet.
    pub fn messages_per_s(&self) -> u64 {
        let per_vehicle =
            100 / self.state_every_ticks.max(1) + if self.can { 100 } else { 0 } + if self.perception { 10 } else { 0 };
        self.vehicles as u64 * per_vehicle
    }
}

/// One vehicle's running state: its prebuilt messages, updated in place each tick.
struct SynthVehicle {
    key_prefix: String,
    offset_ns: i64,
    drift_ppm: i64,
    delay_ns: i64,
    lane_y_m: f64,
    speed_mps: f64,
    state: VehicleStateSample,
    can: CanFrame,
    perception: ObjectList,
}

/// One message of the fleet, lent to the caller's callback.
#[derive(Debug, Clone, Copy)]
pub struct FleetMessage<'a> {
    /// Index of the sending vehicle.
    pub vehicle: usize,
    pub stream: EdgeStream,
    /// `risktwin/v1/<site>/<source>/<stream>`.
    pub key: &'a str,
    /// The encoded protobuf message.
    pub payload: &'a [u8],
    /// When the cloud nominally receives it, ns (cloud clock).
    pub receive_ns: i64,
}

/// A deterministic synthetic fleet; see the module docs.
pub struct SyntheticFleet {
    config: FleetConfig,
    vehicles: Vec<SynthVehicle>,
    key: String,
    buf: Vec<u8>,
}

fn header(source: &str) -> Header {
    Header { source: source.to_owned(), seq: 0, capture_time_ns: 0, publish_time_ns: 0, frame: Frame::World }
}

impl SyntheticFleet {
    /// A fleet of `config.vehicles` named `veh-00000`… at `site`.
    pub fn new(config: FleetConfig, site: &str) -> Self {
        let vehicles = (0..config.vehicles)
            .map(|i| {
                let source = format!("veh-{:05}", config.first_vehicle + i);
                let spread = |m: usize, k: usize| ((i * k) % m) as i64 - (m / 2) as i64;
                SynthVehicle {
                    key_prefix: format!("risktwin/v1/{site}/{source}/"),
                    offset_ns: spread(201, 7_919) * 1_000_000,
                    drift_ppm: spread(21, 13),
                    // Spread over 1–3 ms in vehicle order so receive times stay sorted in a tick.
                    delay_ns: 1_000_000 + (2_000_000 * i as i64) / config.vehicles.max(1) as i64,
                    lane_y_m: 3.5 * (i % 4) as f64,
                    speed_mps: 15.0 + (i % 10) as f64,
                    state: VehicleStateSample {
                        header: header(&source),
                        pose: Pose::new(0.0, 0.0, 0.0),
                        velocity: Vec2::new(0.0, 0.0),
                        speed_mps: 0.0,
                        accel_mps2: 0.0,
                        yaw_rate_radps: 0.0,
                        steer_rad: 0.0,
                        footprint: Footprint::new(4.5, 1.8),
                    },
                    can: CanFrame { header: header(&source), can_id: 0x123, data: [0; 8], dlc: 8 },
                    perception: ObjectList {
                        header: header(&source),
                        objects: (0..4)
                            .map(|k| DetectedObject {
                                id: k,
                                kind: ObjectKind::Vehicle,
                                pose: Pose::new(0.0, 0.0, 0.0),
                                footprint: Footprint::new(4.5, 1.8),
                                velocity: Vec2::new(20.0, 0.0),
                                accel_mps2: 0.0,
                            })
                            .collect(),
                    },
                }
            })
            .collect();
        SyntheticFleet { config, vehicles, key: String::new(), buf: Vec::with_capacity(512) }
    }

    pub fn config(&self) -> &FleetConfig {
        &self.config
    }

    /// Emits every message of tick `tick` (at `start_ns + tick × 10 ms`), vehicle by vehicle.
    pub fn tick(&mut self, tick: u64, mut emit: impl FnMut(FleetMessage<'_>)) {
        let t_ns = self.config.start_ns + tick as i64 * FLEET_TICK_NS;
        let elapsed_s = tick as f64 * FLEET_TICK_NS as f64 * 1e-9;
        let (buf, key) = (&mut self.buf, &mut self.key);
        for (index, v) in self.vehicles.iter_mut().enumerate() {
            // The vehicle's clock: offset plus drift since tick 0.
            let capture_ns = t_ns + v.offset_ns + (t_ns - self.config.start_ns) / 1_000_000 * v.drift_ppm;
            let receive_ns = t_ns + v.delay_ns;
            let x_m = v.speed_mps * elapsed_s;
            let mut send = |stream: EdgeStream, payload: &[u8]| {
                key.clear();
                key.push_str(&v.key_prefix);
                key.push_str(stream.as_str());
                emit(FleetMessage { vehicle: index, stream, key, payload, receive_ns });
            };
            if tick.is_multiple_of(self.config.state_every_ticks.max(1)) {
                let s = &mut v.state;
                stamp(&mut s.header, capture_ns);
                s.pose = Pose::new(x_m, v.lane_y_m, 0.0);
                s.velocity = Vec2::new(v.speed_mps, 0.0);
                s.speed_mps = v.speed_mps;
                buf.clear();
                encode_into(&*s, buf);
                s.header.seq += 1;
                send(EdgeStream::State, buf);
            }
            if self.config.can {
                let f = &mut v.can;
                stamp(&mut f.header, capture_ns);
                let bits = (x_m as f32).to_le_bytes();
                f.data = [bits[0], bits[1], bits[2], bits[3], 0, 0, 0, 1];
                buf.clear();
                encode_into(&*f, buf);
                f.header.seq += 1;
                send(EdgeStream::Can, buf);
            }
            if self.config.perception && tick.is_multiple_of(10) {
                let l = &mut v.perception;
                stamp(&mut l.header, capture_ns);
                for (k, o) in l.objects.iter_mut().enumerate() {
                    o.pose = Pose::new(x_m + 10.0 * (k + 1) as f64, v.lane_y_m, 0.0);
                }
                buf.clear();
                encode_into(&*l, buf);
                l.header.seq += 1;
                send(EdgeStream::Perception, buf);
            }
        }
    }
}

fn stamp(header: &mut Header, capture_ns: i64) {
    header.capture_time_ns = capture_ns;
    header.publish_time_ns = capture_ns + 200_000;
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_align::IngestConfig;
    use risktwin_cloud::ingest::IngestWorker;
    use std::io::Cursor;

    #[test]
    fn the_fleet_is_accepted_whole_and_numbered_per_stream() {
        let config = FleetConfig { vehicles: 20, can: true, perception: true, ..FleetConfig::states_only(0) };
        let mut fleet = SyntheticFleet::new(config, "bench");
        let mut worker: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
        let mut sent = 0u64;
        let mut last_receive_ns = i64::MIN;
        for tick in 0..200 {
            fleet.tick(tick, |m| {
                assert!(m.receive_ns >= last_receive_ns, "receive times never go back");
                last_receive_ns = m.receive_ns;
                let source = m.key.rsplit('/').nth(1).expect("a source segment");
                worker.handle(source, m.stream, m.key, m.payload, m.receive_ns, |_| {}).expect("no recorder");
                sent += 1;
            });
        }
        // 2 s: 100 states, 200 CAN frames and 20 object lists per vehicle.
        assert_eq!(sent, 20 * (100 + 200 + 20));
        assert_eq!(sent, config.messages_per_s() * 2);
        let stats = worker.stats();
        assert_eq!(stats.accepted, sent, "{stats:?}");
        assert!(stats.snapshots >= 30, "{stats:?}");
    }
}
