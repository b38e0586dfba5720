//! The cloud roles of RiskTwin: what the cloud does with the edges' messages, and how it sits on
//! the Zenoh network.
//!
//! - [`ingest`]: decode, validate, de-duplicate and align edge messages into snapshots
//!   ([`ingest::IngestWorker`], transport-free), and record what was accepted;
//! - [`twin`]: the live twin built from those snapshots, and its per-tick outputs (scene boxes,
//!   the risk field and report of every vehicle) — transport-free too;
//! - [`warning`]: the event-driven warning path: each accepted state re-assesses the pairs it
//!   touches and warns both vehicles of a critical one at once, beside the aligned snapshots;
//! - [`network`]: the `risktwin cloud` roles on Zenoh (subscriptions, queryables, the
//!   publisher of the twin's outputs, liveliness) and the cloud→edge pushes;
//! - [`viz`]: the live twin served to the Foxglove app over its WebSocket protocol (the same
//!   topics and schemas as a recording);
//! - [`fleet_loop`]: the closed loop over the fleet (what the `loop` role decides), on the
//!   library's state (the SQLite stores are `risktwin-store`'s);
//! - [`criticality`]: CommonRoad criticality of a replayed scenario; [`trainer`], [`generate`],
//!   [`episode_recording`]: the offline side.
//!
//! The ingest and the twin need no network: feed a worker encoded messages, and the twin
//! follows its snapshots.
//!
//! ```
//! use risktwin_cloud::ingest::IngestWorker;
//! use risktwin_cloud::twin::Twin;
//! use risktwin_align::IngestConfig;
//! use risktwin_common::geometry::{Footprint, Pose, Vec2};
//! use risktwin_common::telemetry::{Frame, Header, VehicleStateSample};
//! use risktwin_transport::EdgeStream;
//! use std::io::Cursor;
//!
//! let mut worker: IngestWorker<Cursor<Vec<u8>>> = IngestWorker::new(IngestConfig::default(), None);
//! let mut twin = Twin::new();
//! twin.name_source(0, "veh-1", "site"); // the first source the worker numbers
//! for seq in 0..50u64 {
//!     let t_ns = 1_000_000_000 + seq as i64 * 20_000_000; // 50 Hz, 20 m/s along x
//!     let header = Header { source: "veh-1".into(), seq, capture_time_ns: t_ns, publish_time_ns: t_ns, frame: Frame::World };
//!     let state = VehicleStateSample {
//!         header,
//!         pose: Pose::new(20.0 * t_ns as f64 * 1e-9, 0.0, 0.0),
//!         velocity: Vec2::new(20.0, 0.0),
//!         speed_mps: 20.0,
//!         accel_mps2: 0.0,
//!         yaw_rate_radps: 0.0,
//!         steer_rad: 0.0,
//!         footprint: Footprint::new(4.5, 1.8),
//!     };
//!     let payload = risktwin_protos::encode(&state);
//!     let key = "risktwin/v1/site/veh-1/state";
//!     let received_ns = t_ns + 2_000_000;
//!     worker.handle("veh-1", EdgeStream::State, key, &payload, received_ns, |s| twin.update(s))?;
//! }
//! assert_eq!(worker.stats().accepted, 50);
//! assert_eq!(twin.site("site").map(|s| s.vehicles.len()), Some(1));
//! # Ok::<(), risktwin_protos::recording::RecordingError>(())
//! ```

pub mod commonroad_recording;
pub mod criticality;
pub mod episode_recording;
pub mod fleet_loop;
pub mod generate;
pub mod ingest;
pub mod network;
#[cfg(test)]
mod test_fixtures;
pub mod trainer;
pub mod twin;
pub mod viz;
pub mod warning;
