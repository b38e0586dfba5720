//! The vehicle role: state at the base rate (50 Hz), CAN-like frames at twice it (100 Hz) and
//! perception at a fifth of it (10 Hz).

use crate::publish::{EdgeConfig, StreamPlan, run_streams};
use crate::{EdgeError, SentSummary};
use risktwin_transport::{EdgeStream, Shutdown};

/// The state rate of a vehicle unless told otherwise, Hz.
pub const DEFAULT_STATE_RATE_HZ: f64 = 50.0;

/// The streams of a vehicle whose state rate is `state_rate_hz`.
pub fn plans(state_rate_hz: f64) -> [StreamPlan; 3] {
    [
        StreamPlan { stream: EdgeStream::State, rate_hz: state_rate_hz },
        StreamPlan { stream: EdgeStream::Can, rate_hz: 2.0 * state_rate_hz },
        StreamPlan { stream: EdgeStream::Perception, rate_hz: state_rate_hz / 5.0 },
    ]
}

/// Runs a vehicle until its count or duration is reached or `shutdown` fires.
pub async fn run(config: &EdgeConfig, shutdown: Shutdown) -> Result<SentSummary, EdgeError> {
    run_streams(config, &plans(config.rate_hz), shutdown).await
}
