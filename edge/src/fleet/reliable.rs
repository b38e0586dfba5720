//! The scene plane's publishers: reliable, and blocking on congestion, since lockstep needs
//! every message.

use super::SceneError;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::{CongestionControl, Reliability};
use risktwin_transport::zenoh::{Session, Wait};

/// A transport failure of `what`, as a scene error.
pub(super) fn transport(what: &str) -> impl Fn(Box<dyn std::error::Error + Send + Sync>) -> SceneError + '_ {
    move |e| SceneError::Transport(format!("{what}: {e}"))
}

/// A reliable, blocking publisher on `key`.
pub(super) fn reliable_publisher(session: &Session, key: String) -> Result<Publisher<'static>, SceneError> {
    session
        .declare_publisher(key.clone())
        .congestion_control(CongestionControl::Block)
        .reliability(Reliability::Reliable)
        .wait()
        .map_err(transport(&key))
}
