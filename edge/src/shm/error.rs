//! Errors of the shared-memory transport: setting up ports, moving samples, validating payloads.

use iceoryx2::node::NodeCreationFailure;
use iceoryx2::port::listener::{ListenerCreateError, ListenerWaitError};
use iceoryx2::port::notifier::{NotifierCreateError, NotifierNotifyError};
use iceoryx2::port::publisher::PublisherCreateError;
use iceoryx2::port::subscriber::SubscriberCreateError;
use iceoryx2::port::{LoanError, ReceiveError, SendError};
use iceoryx2::service::builder::event::EventOpenOrCreateError;
use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenOrCreateError;
use iceoryx2::service::service_name::ServiceNameError;

use super::stream::ShmStream;

/// Why a payload read from shared memory was rejected.
///
/// Carries the offending value; no variant allocates, so rejecting a flood of bad samples does not
/// touch the heap.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ShmPayloadError {
    /// A float field is NaN or infinite.
    #[error("field {field} is not finite: {value}")]
    NotFinite { field: &'static str, value: f64 },
    /// A finite field lies outside its physical range.
    #[error("field {field} = {value} is outside [{min}, {max}]")]
    OutOfRange { field: &'static str, value: f64, min: f64, max: f64 },
    /// An object list claims more objects than its fixed capacity.
    #[error("object count {count} exceeds the capacity {capacity}")]
    CountOverCapacity { count: u32, capacity: usize },
    /// A float field of one object is NaN or infinite.
    #[error("object {index}: field {field} is not finite: {value}")]
    ObjectNotFinite { index: usize, field: &'static str, value: f64 },
    /// A finite field of one object lies outside its physical range.
    #[error("object {index}: field {field} = {value} is outside [{min}, {max}]")]
    ObjectOutOfRange { index: usize, field: &'static str, value: f64, min: f64, max: f64 },
    /// An object's kind code names no known kind.
    #[error("object {index}: unknown kind code {code}")]
    UnknownObjectKind { index: usize, code: u32 },
    /// A CAN identifier does not fit in 29 bits.
    #[error("CAN id {can_id:#x} exceeds the 29-bit maximum {max:#x}")]
    CanIdOutOfRange { can_id: u32, max: u32 },
    /// A CAN data length code above 8 (classic CAN).
    #[error("CAN data length {dlc} exceeds 8 bytes")]
    DlcOutOfRange { dlc: usize },
}

/// Errors of the shared-memory ports.
#[derive(Debug, thiserror::Error)]
pub enum ShmError {
    /// A vehicle id that cannot name a service.
    #[error("invalid vehicle id {id:?}: {reason}")]
    InvalidVehicleId { id: String, reason: &'static str },
    /// iceoryx2 refused the service name.
    #[error("invalid iceoryx2 service name {service:?}")]
    ServiceName {
        service: String,
        #[source]
        source: ServiceNameError,
    },
    /// The iceoryx2 node could not be created (is /dev/shm writable?).
    #[error("cannot create the iceoryx2 node for {service:?}")]
    Node {
        service: String,
        #[source]
        source: NodeCreationFailure,
    },
    /// The publish–subscribe service could not be opened or created (e.g. the other side uses a
    /// different payload type or incompatible QoS).
    #[error("cannot open or create the publish-subscribe service {service:?}")]
    PubSubService {
        service: String,
        #[source]
        source: PublishSubscribeOpenOrCreateError,
    },
    /// The companion event service could not be opened or created.
    #[error("cannot open or create the event service {service:?}")]
    EventService {
        service: String,
        #[source]
        source: EventOpenOrCreateError,
    },
    /// The publisher port could not be created (too many publishers?).
    #[error("cannot create a publisher on {service:?}")]
    CreatePublisher {
        service: String,
        #[source]
        source: PublisherCreateError,
    },
    /// The subscriber port could not be created (too many subscribers?).
    #[error("cannot create a subscriber on {service:?}")]
    CreateSubscriber {
        service: String,
        #[source]
        source: SubscriberCreateError,
    },
    /// The notifier port could not be created.
    #[error("cannot create a notifier on {service:?}")]
    CreateNotifier {
        service: String,
        #[source]
        source: NotifierCreateError,
    },
    /// The listener port could not be created.
    #[error("cannot create a listener on {service:?}")]
    CreateListener {
        service: String,
        #[source]
        source: ListenerCreateError,
    },
    /// No shared-memory chunk could be loaned (all chunks in flight).
    #[error("cannot loan a {stream} sample")]
    Loan {
        stream: ShmStream,
        #[source]
        source: LoanError,
    },
    /// A sample could not be delivered (in lossless mode: a subscriber stayed full too long).
    #[error("cannot send a {stream} sample")]
    Send {
        stream: ShmStream,
        #[source]
        source: SendError,
    },
    /// In lossless mode, a sample reached fewer subscribers than were registered: one had not
    /// attached yet and its queue was full (or it left during the send).
    #[error("{stream} sample seq {seq} reached {delivered} of {subscribers} subscribers")]
    Undelivered { stream: ShmStream, seq: u64, delivered: usize, subscribers: usize },
    /// Waking the subscribers failed; the sample itself was delivered.
    #[error("cannot notify the subscribers of {stream}")]
    Notify {
        stream: ShmStream,
        #[source]
        source: NotifierNotifyError,
    },
    /// Taking a sample from the subscriber's queue failed.
    #[error("cannot receive a {stream} sample")]
    Receive {
        stream: ShmStream,
        #[source]
        source: ReceiveError,
    },
    /// Waiting for a wake-up failed (e.g. interrupted by a signal).
    #[error("cannot wait for a {stream} sample")]
    Wait {
        stream: ShmStream,
        #[source]
        source: ListenerWaitError,
    },
    /// A received sample failed validation; it was released and the port keeps working.
    #[error("rejected {stream} sample seq {seq}")]
    InvalidSample {
        stream: ShmStream,
        seq: u64,
        #[source]
        source: ShmPayloadError,
    },
    /// A control event (end of stream, drained) could not be signalled.
    #[error("cannot signal {event:?} on {service:?}")]
    ControlNotify {
        service: String,
        event: &'static str,
        #[source]
        source: NotifierNotifyError,
    },
    /// Waiting for a control event failed.
    #[error("cannot wait for control events on {service:?}")]
    ControlWait {
        service: String,
        #[source]
        source: ListenerWaitError,
    },
}
