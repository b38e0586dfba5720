//! The roadside-unit role: object lists and signal phases, both at the base rate (10 Hz, the
//! usual rate of SPaT messages).

use crate::publish::{EdgeConfig, StreamPlan, run_streams};
use crate::{EdgeError, SentSummary};
use risktwin_transport::{EdgeStream, Shutdown};

/// The rate of an RSU unless told otherwise, Hz.
pub const DEFAULT_RATE_HZ: f64 = 10.0;

/// The streams of an RSU publishing at `rate_hz`.
pub fn plans(rate_hz: f64) -> [StreamPlan; 2] {
    [StreamPlan { stream: EdgeStream::Rsu, rate_hz }, StreamPlan { stream: EdgeStream::Signal, rate_hz }]
}

/// Runs an RSU until its count or duration is reached or `shutdown` fires.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<SentSummary, EdgeError> {
    run_streams(config, &plans(config.rate_hz), shutdown).await
}
