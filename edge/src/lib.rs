//! Edge roles: processes that mimic vehicles and roadside units and publish their streams to
//! the cloud over Zenoh (key scheme in `risktwin_transport::keyexpr`).
//!
//! Each role has a `run(config, shutdown)` function; the `risktwin` binary only parses
//! arguments. Each role simulates its own scenario world ([`scene`]) and publishes real
//! `common::telemetry` messages encoded by `risktwin-protos`.
//! [`shm`] is the zero-copy iceoryx2 exchange between a vehicle's sensor producer and its
//! gateway on one host; [`sensor`] (the producer, `edge sensor`) and [`gateway`] (`edge gateway`,
//! forwarding to Zenoh) are the two processes around it.

pub mod cadence;
pub mod clock;
pub mod delivery;
mod error;
pub mod fleet;
pub mod gateway;
mod live_metrics;
pub mod publish;
pub mod replay;
pub mod rsu;
pub mod scene;
pub mod sensor;
pub mod shm;
pub mod summary;
pub mod vehicle;

pub use clock::{ClockModel, EdgeClock};
pub use error::EdgeError;
pub use publish::{EdgeConfig, Producer, Stamper};
pub use summary::SentSummary;
