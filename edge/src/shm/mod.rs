//! Zero-copy exchange between the processes of one host over iceoryx2 shared memory.
//!
//! On a vehicle, the sensor producer and the edge gateway are separate processes. The producer
//! publishes plain-old-data samples ([`ShmVehicleState`], [`ShmCanFrame`], [`ShmObjectList`]) into
//! shared memory with a [`ShmPublisher`]; the gateway takes them with a [`ShmSubscriber`] and
//! forwards them to Zenoh. A sample is written once, in place, into a loaned shared-memory chunk
//! and read in place by the subscriber: no serialisation and no copy between the processes.
//!
//! Each (vehicle, stream) pair is one iceoryx2 publish–subscribe service named
//! `risktwin/<vehicle_id>/<stream>` (see [`service_name`]) plus an event service of the same name
//! that the publisher signals after each send, so that a subscriber can either busy-poll
//! ([`ShmSubscriber::try_receive`]) or sleep until a sample arrives
//! ([`ShmSubscriber::receive_timeout`]).
//!
//! Shared memory is input like any wire: the subscriber validates every sample
//! ([`ShmPayload::validate`]: finite floats, ranges, object count within capacity) before handing
//! it out, and rejects a bad one with [`ShmError::InvalidSample`] without stopping.
//!
//! A third service per vehicle, the event service `risktwin/<vehicle_id>/control`
//! ([`ShmControl`]), orders the end of a run: the producer signals
//! [`ControlEvent::EndOfStream`] after its last send and keeps its publishers until the gateway
//! answers [`ControlEvent::Drained`], because a publisher that leaves can take unread samples
//! along.

mod control;
mod convert;
mod error;
mod naming;
mod payload;
mod port;
mod stream;

pub use control::{ControlEvent, ShmControl};
pub use error::{ShmError, ShmPayloadError};
pub use naming::{MAX_VEHICLE_ID_LEN, service_name, validate_vehicle_id};
pub use payload::{
    MAX_CAN_ID, OBJECT_LIST_CAPACITY, ShmCanFrame, ShmObject, ShmObjectList, ShmPayload, ShmVehicleState,
    object_kind_code,
};
pub use port::{Delivery, ShmPublisher, ShmQos, ShmSample, ShmSubscriber};
pub use stream::ShmStream;
