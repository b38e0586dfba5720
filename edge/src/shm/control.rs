//! [`ShmControl`]: the per-vehicle event service that orders the end of a producer–gateway run.
//!
//! Samples sent in lossless mode are in the gateway's queues when the send returns, but they live
//! in the producer's data segment: a producer that exits before the gateway read them can take
//! them along. So at the end the producer signals [`ControlEvent::EndOfStream`] after its last
//! send and waits for [`ControlEvent::Drained`], which the gateway signals once every queue was
//! read empty after it saw the end. Both sides own a notifier and a listener on the same service
//! `risktwin/<vehicle_id>/control`; each listener also hears its own side's events, which the
//! bookkeeping here simply records like any other.

use std::cell::Cell;
use std::time::{Duration, Instant};

use iceoryx2::node::Node;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::{EventId, NodeBuilder, ServiceName, SignalHandlingMode, ipc};
use iceoryx2::service::port_factory::event;

use super::error::ShmError;
use super::naming::validate_vehicle_id;

/// The control events of a run.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ControlEvent {
    /// Producer → gateway: every sample of the run has been sent.
    EndOfStream,
    /// Gateway → producer: every sample sent before the end has been taken from shared memory.
    Drained,
}

impl ControlEvent {
    /// The iceoryx2 event id (0 is left to iceoryx2's own notifier events, which are not enabled).
    const fn id(self) -> usize {
        match self {
            ControlEvent::EndOfStream => 1,
            ControlEvent::Drained => 2,
        }
    }

    /// The name used in errors and logs.
    pub const fn as_str(self) -> &'static str {
        match self {
            ControlEvent::EndOfStream => "end-of-stream",
            ControlEvent::Drained => "drained",
        }
    }
}

/// One side's ports on a vehicle's control service, with the events heard so far.
pub struct ShmControl {
    notifier: Notifier<ipc::Service>,
    listener: Listener<ipc::Service>,
    _events: event::PortFactory<ipc::Service>,
    _node: Node<ipc::Service>,
    service: String,
    seen_end: Cell<bool>,
    seen_drained: Cell<bool>,
}

impl ShmControl {
    /// Opens (or creates) `risktwin/<vehicle_id>/control`. Events signalled before this returns
    /// are not heard, so each side opens it before the other can need it: the gateway before
    /// its subscribers, the producer before it publishes.
    pub fn open(vehicle_id: &str) -> Result<Self, ShmError> {
        validate_vehicle_id(vehicle_id)?;
        let service = format!("risktwin/{vehicle_id}/control");
        let node = NodeBuilder::new()
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|source| ShmError::Node { service: service.clone(), source })?;
        let name =
            ServiceName::new(&service).map_err(|source| ShmError::ServiceName { service: service.clone(), source })?;
        let events = node
            .service_builder(&name)
            .event()
            .open_or_create()
            .map_err(|source| ShmError::EventService { service: service.clone(), source })?;
        let notifier = events
            .notifier_builder()
            .create()
            .map_err(|source| ShmError::CreateNotifier { service: service.clone(), source })?;
        let listener = events
            .listener_builder()
            .create()
            .map_err(|source| ShmError::CreateListener { service: service.clone(), source })?;
        Ok(Self {
            notifier,
            listener,
            _events: events,
            _node: node,
            service,
            seen_end: Cell::new(false),
            seen_drained: Cell::new(false),
        })
    }

    /// Signals `event` to every listener of the service.
    pub fn signal(&self, event: ControlEvent) -> Result<(), ShmError> {
        self.notifier
            .notify_with_custom_event_id(EventId::new(event.id()))
            .map(|_| ())
            .map_err(|source| ShmError::ControlNotify { service: self.service.clone(), event: event.as_str(), source })
    }

    /// Whether `event` has been heard, looking at pending events without blocking.
    pub fn heard(&self, event: ControlEvent) -> Result<bool, ShmError> {
        let result = self.listener.try_wait(|activation| self.record(activation.id.as_value()));
        result.map_err(|source| ShmError::ControlWait { service: self.service.clone(), source })?;
        Ok(self.seen(event))
    }

    /// Waits up to `timeout` for `event`; `Ok(false)` when it did not come.
    pub fn wait_for(&self, event: ControlEvent, timeout: Duration) -> Result<bool, ShmError> {
        let deadline = Instant::now() + timeout;
        while !self.heard(event)? {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return Ok(false);
            }
            let result = self.listener.timed_wait(|activation| self.record(activation.id.as_value()), left);
            result.map_err(|source| ShmError::ControlWait { service: self.service.clone(), source })?;
        }
        Ok(true)
    }

    fn record(&self, id: usize) {
        if id == ControlEvent::EndOfStream.id() {
            self.seen_end.set(true);
        } else if id == ControlEvent::Drained.id() {
            self.seen_drained.set(true);
        }
    }

    fn seen(&self, event: ControlEvent) -> bool {
        match event {
            ControlEvent::EndOfStream => self.seen_end.get(),
            ControlEvent::Drained => self.seen_drained.get(),
        }
    }
}
