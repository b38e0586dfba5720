//! What the cloud's network tests share: a router on a free port, the cloud role started on it,
//! and an edge's state publisher that waits for the cloud's subscriber.

use super::{CloudConfig, CloudError, CloudSummary, run};
use risktwin_transport::router::{RouterConfig, run as run_router};
use risktwin_transport::shutdown::ShutdownTrigger;
use risktwin_transport::zenoh::Session;
use risktwin_transport::zenoh::pubsub::Publisher;
use risktwin_transport::zenoh::qos::CongestionControl;
use risktwin_transport::{Mode, TransportConfig, TransportError, protobuf, shutdown};
use std::time::Duration;
use tokio::sync::oneshot;
use tokio::task::JoinHandle;
use tokio::time::timeout;

/// The bound on every wait of these tests.
pub(super) const STEP: Duration = Duration::from_secs(30);

/// A router listening on a free loopback port, and how a client reaches it.
pub(super) struct Router {
    stop: ShutdownTrigger,
    task: JoinHandle<Result<(), TransportError>>,
    pub(super) client: TransportConfig,
}

impl Router {
    /// Starts one.
    pub(super) async fn start() -> Router {
        let (stop, router_shutdown) = shutdown::channel();
        let (port_tx, port_rx) = oneshot::channel();
        let config = RouterConfig { listen: vec!["tcp/127.0.0.1:0".into()], ..RouterConfig::default() };
        let task = tokio::spawn(async move {
            run_router(&config, router_shutdown, |locators| {
                let _ = port_tx.send(locators.to_vec());
            })
            .await
        });
        let locators = timeout(STEP, port_rx).await.unwrap().unwrap();
        assert!(locators.iter().all(|l| l.starts_with("tcp/127.0.0.1:") && !l.ends_with(":0")), "{locators:?}");
        let client = TransportConfig { mode: Mode::Client, connect: locators, ..TransportConfig::default() };
        Router { stop, task, client }
    }

    /// Stops it and waits until it has.
    pub(super) async fn stop(self) {
        self.stop.fire();
        timeout(STEP, self.task).await.unwrap().unwrap().unwrap();
    }
}

/// The cloud role with `config`, once it is ready; fire the trigger to stop it.
pub(super) async fn start_cloud(
    config: CloudConfig,
) -> (ShutdownTrigger, JoinHandle<Result<CloudSummary, CloudError>>) {
    let (stop, cloud_shutdown) = shutdown::channel();
    let (ready_tx, ready_rx) = oneshot::channel();
    let cloud = tokio::spawn(async move {
        run(&config, cloud_shutdown, |_| {
            let _ = ready_tx.send(());
        })
        .await
    });
    timeout(STEP, ready_rx).await.unwrap().unwrap();
    (stop, cloud)
}

/// A plain publisher of vehicle states on `key`, once a subscriber (the cloud) matches it.
pub(super) async fn state_publisher(session: &Session, key: String) -> Publisher<'static> {
    let publisher = session
        .declare_publisher(key)
        .encoding(protobuf("risktwin.v1.VehicleState"))
        .congestion_control(CongestionControl::Block)
        .await
        .unwrap();
    let matched = async {
        let listener = publisher.matching_listener().await.unwrap();
        if !publisher.matching_status().await.unwrap().matching() {
            while !listener.recv_async().await.unwrap().matching() {}
        }
    };
    timeout(STEP, matched).await.unwrap();
    publisher
}
