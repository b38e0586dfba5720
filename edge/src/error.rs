//! Why an edge role stopped.

use risktwin_transport::TransportError;
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
