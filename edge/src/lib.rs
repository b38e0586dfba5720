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
pub mod gateway;
pub mod publish;
pub mod replay;
pub mod rsu;
pub mod scene;
pub mod sensor;
pub mod shm;
pub mod vehicle;

pub use clock::{ClockModel, EdgeClock};
pub use publish::{EdgeConfig, Producer, Stamper};

use risktwin_transport::{EdgeStream, TransportError};
use serde::Serialize;
use std::collections::BTreeMap;
use thiserror::Error;

/// Why an edge role stopped with an error.
#[derive(Debug, Error)]
pub enum EdgeError {
    #[error("rate of stream {stream} is {rate_hz} Hz; it must be finite, positive and at most 100 kHz")]
    BadRate { stream: &'static str, rate_hz: f64 },
    #[error(transparent)]
    Transport(#[from] TransportError),
    #[error("no feasible {kind} scenario for seed {seed} among the first {tried} candidates")]
    NoFeasibleScenario { kind: &'static str, seed: u64, tried: u64 },
    #[error("roadside sensor: {reason}")]
    Sensor { reason: String },
    #[error("shutting down: {reason}")]
    Shutdown { reason: String },
    #[error("recording: {reason}")]
    Recording { reason: String },
}

/// What an edge sent, per stream: printed as JSON on exit so that tests can check
/// sent = received + counted drops.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct SentSummary {
    /// The edge's site.
    pub site: String,
    /// The edge's id.
    pub source: String,
    /// Messages sent per stream name.
    pub sent: BTreeMap<String, u64>,
}

impl SentSummary {
    fn new(config: &EdgeConfig, sent: impl IntoIterator<Item = (EdgeStream, u64)>) -> Self {
        SentSummary {
            site: config.site.to_string(),
            source: config.id.to_string(),
            sent: sent.into_iter().map(|(s, n)| (s.as_str().to_owned(), n)).collect(),
        }
    }
}
