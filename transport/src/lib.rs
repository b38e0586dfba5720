//! Zenoh glue shared by the edge and cloud roles (and the benchmarks): the key-expression
//! scheme, sessions built from a typed config, typed publishers and subscribers on the scheme,
//! liveliness, and the shutdown signal every role obeys.
//!
//! Boundary: this crate moves opaque payload bytes on typed keys, each tagged with the name of
//! the message its key carries (`stream::protobuf`). It knows nothing of what a vehicle or the
//! twin is; message encoding belongs to `risktwin-protos`. The edge and cloud
//! crates depend on it; `common` never does (it stays free of async and network code).
//!
//! Two host helpers every role shares live here too: [`sync::LockExt`] (one rule for a poisoned
//! lock) and [`wall_clock::unix_ns`].

pub mod edge_subscriber;
pub mod keyexpr;
pub mod metrics;
pub mod recovery;
pub mod router;
pub mod session;
pub mod shutdown;
pub mod stream;
pub mod sync;
pub mod tls;
pub mod wall_clock;

pub use edge_subscriber::{
    EdgeStreamSubscriber, Missed, StreamLoss, fetch_cached, requery, subscribe_edge_streams, subscribe_shard_group,
};
pub use keyexpr::{EdgeStream, KeyError, SiteId, SourceId};
pub use recovery::Delivery;
pub use session::{DEFAULT_ROUTER_PORT, Mode, TransportConfig, TransportError, close, connect, listening_locators};
pub use shutdown::{Shutdown, ShutdownTrigger};
pub use stream::{
    Liveness, StreamPublisher, declare_alive, declare_alive_within, linger, protobuf, retire, watch_liveliness,
};
pub use tls::{Identity, Security, TlsError, TlsFiles};
/// Re-exported so that roles name zenoh types without their own dependency line.
pub use zenoh;
