//! [`ShmPublisher`] and [`ShmSubscriber`]: typed iceoryx2 ports for one vehicle stream.
//!
//! Each port owns its iceoryx2 node, the publish–subscribe service and the companion event
//! service of the same name. The publisher loans a chunk, writes the sample into it, sends it and
//! then signals the event service; signalling is one atomic compare-and-swap unless a listener is
//! asleep, so busy-polling subscribers pay next to nothing for the blocking ones. Fields are
//! declared ports first so that they drop before the services and the node.

use std::ops::Deref;
use std::time::{Duration, Instant};

use iceoryx2::node::Node;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::{BackpressureAction, BackpressureInfo};
use iceoryx2::prelude::{BackpressureStrategy, NodeBuilder, PortFactory, ServiceName, SignalHandlingMode, ipc};
use iceoryx2::sample::Sample;
use iceoryx2::sample_mut::SampleMut;
use iceoryx2::service::port_factory::{event, publish_subscribe};

use super::error::ShmError;
use super::naming::service_name;
use super::payload::ShmPayload;

/// The publish–subscribe service of one stream.
type PubSubFactory<T> = publish_subscribe::PortFactory<ipc::Service, T, ()>;
/// The companion event service of one stream.
type EventFactory = event::PortFactory<ipc::Service>;

/// What a publisher does when a subscriber's queue is full.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    /// The oldest queued sample is overwritten: a slow subscriber sees gaps in `seq`, the producer
    /// never waits (sensor-style, newest wins).
    LatestWins,
    /// The producer waits up to `max_wait` for room, then the send fails with [`ShmError::Send`]:
    /// nothing is lost silently (the gateway must forward every sample).
    ///
    /// iceoryx2 can only hold a producer back for a subscriber that has attached to it, which a
    /// subscriber does on its first poll or wake-up after the publisher appeared; a subscriber
    /// whose queue fills before that misses samples, and the send reports it as
    /// [`ShmError::Undelivered`]. Producers that must not lose the start wait for a first
    /// sample to be acknowledged (see the cross-process tests). A subscriber process that died
    /// with a full queue holds every send for `max_wait` until iceoryx2 cleans up its node, so
    /// keep `max_wait` short next to the producer's period.
    Lossless {
        /// Longest a send may wait for a full subscriber.
        max_wait: Duration,
    },
}

/// Quality of service of a stream; producer and gateway must use the same one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ShmQos {
    /// Samples each subscriber can queue.
    pub subscriber_buffer: usize,
    /// Behaviour on a full subscriber queue.
    pub delivery: Delivery,
}

impl Default for ShmQos {
    /// 128 queued samples (1.3 s of CAN at 100 Hz), lossless with a 50 ms bound on the wait.
    fn default() -> Self {
        Self { subscriber_buffer: 128, delivery: Delivery::Lossless { max_wait: Duration::from_millis(50) } }
    }
}

/// A node that leaves SIGINT/SIGTERM to the application (the roles handle shutdown themselves).
fn create_node(service: &str) -> Result<Node<ipc::Service>, ShmError> {
    NodeBuilder::new()
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<ipc::Service>()
        .map_err(|source| ShmError::Node { service: service.to_owned(), source })
}

/// Opens (or creates) the publish–subscribe service and its event companion.
fn open_services<T: ShmPayload>(
    node: &Node<ipc::Service>,
    service: &str,
    qos: &ShmQos,
) -> Result<(PubSubFactory<T>, EventFactory), ShmError> {
    let name =
        ServiceName::new(service).map_err(|source| ShmError::ServiceName { service: service.to_owned(), source })?;
    let pubsub = node
        .service_builder(&name)
        .publish_subscribe::<T>()
        .subscriber_max_buffer_size(qos.subscriber_buffer)
        .enable_safe_overflow(matches!(qos.delivery, Delivery::LatestWins))
        .open_or_create()
        .map_err(|source| ShmError::PubSubService { service: service.to_owned(), source })?;
    let events = node
        .service_builder(&name)
        .event()
        .open_or_create()
        .map_err(|source| ShmError::EventService { service: service.to_owned(), source })?;
    Ok((pubsub, events))
}

/// Publishes one vehicle stream of `T` into shared memory.
pub struct ShmPublisher<T: ShmPayload> {
    publisher: Publisher<ipc::Service, T, ()>,
    notifier: Notifier<ipc::Service>,
    _events: EventFactory,
    pubsub: PubSubFactory<T>,
    _node: Node<ipc::Service>,
    service: String,
    lossless: bool,
}

impl<T: ShmPayload> ShmPublisher<T> {
    /// Opens `risktwin/<vehicle_id>/<T::STREAM>` for publishing.
    pub fn new(vehicle_id: &str, qos: ShmQos) -> Result<Self, ShmError> {
        let service = service_name(vehicle_id, T::STREAM)?;
        let node = create_node(&service)?;
        let (pubsub, events) = open_services::<T>(&node, &service, &qos)?;
        let builder = pubsub.publisher_builder();
        let builder = match qos.delivery {
            Delivery::LatestWins => builder,
            Delivery::Lossless { max_wait } => builder
                .backpressure_strategy(BackpressureStrategy::RetryUntilDelivered)
                .set_backpressure_handler(move |info: &BackpressureInfo| {
                    if info.elapsed_time < max_wait {
                        BackpressureAction::Retry
                    } else {
                        BackpressureAction::DiscardDataAndFail
                    }
                }),
        };
        let publisher =
            builder.create().map_err(|source| ShmError::CreatePublisher { service: service.clone(), source })?;
        let notifier = events
            .notifier_builder()
            .create()
            .map_err(|source| ShmError::CreateNotifier { service: service.clone(), source })?;
        let lossless = matches!(qos.delivery, Delivery::Lossless { .. });
        Ok(Self { publisher, notifier, _events: events, pubsub, _node: node, service, lossless })
    }

    /// The iceoryx2 service name this publisher writes to.
    pub fn service_name(&self) -> &str {
        &self.service
    }

    /// How many subscribers the service has now (the start-up handshake waits for one).
    pub fn subscriber_count(&self) -> usize {
        self.pubsub.dynamic_config().number_of_subscribers()
    }

    /// Copies `value` into a loaned chunk and sends it. The wrapper allocates nothing; iceoryx2 0.10's
    /// loan itself allocates one small `Rc` (checked by the crate's tests).
    pub fn publish(&self, value: &T) -> Result<(), ShmError> {
        let sample = self.publisher.loan_uninit().map_err(|source| ShmError::Loan { stream: T::STREAM, source })?;
        let sample = sample.write_payload(*value);
        self.send(sample)
    }

    /// Loans a chunk, sets it to [`ShmPayload::EMPTY`], lets `fill` write the sample in place and
    /// sends it. When `fill` fails the chunk goes back unsent and the error names the sample.
    pub fn publish_with<F>(&self, fill: F) -> Result<(), ShmError>
    where
        F: FnOnce(&mut T) -> Result<(), super::error::ShmPayloadError>,
    {
        let sample = self.publisher.loan_uninit().map_err(|source| ShmError::Loan { stream: T::STREAM, source })?;
        let mut sample = sample.write_payload(T::EMPTY);
        if let Err(source) = fill(sample.payload_mut()) {
            return Err(ShmError::InvalidSample { stream: T::STREAM, seq: sample.payload().seq(), source });
        }
        self.send(sample)
    }

    /// Sends, then signals the event service so that subscribers asleep in `receive_timeout` wake.
    fn send(&self, sample: SampleMut<ipc::Service, T, ()>) -> Result<(), ShmError> {
        // Counted before the send: a subscriber that joins during it is not owed this sample.
        let subscribers = if self.lossless { self.pubsub.dynamic_config().number_of_subscribers() } else { 0 };
        let seq = sample.payload().seq();
        let delivered = sample.send().map_err(|source| ShmError::Send { stream: T::STREAM, source })?;
        self.notifier.notify().map_err(|source| ShmError::Notify { stream: T::STREAM, source })?;
        if delivered < subscribers {
            return Err(ShmError::Undelivered { stream: T::STREAM, seq, delivered, subscribers });
        }
        Ok(())
    }
}

/// A received, validated sample, read in place from shared memory; dropping it returns the chunk.
pub struct ShmSample<T: ShmPayload> {
    sample: Sample<ipc::Service, T, ()>,
}

impl<T: ShmPayload> Deref for ShmSample<T> {
    type Target = T;

    fn deref(&self) -> &T {
        self.sample.payload()
    }
}

impl<T: ShmPayload> core::fmt::Debug for ShmSample<T> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_tuple("ShmSample").field(self.sample.payload()).finish()
    }
}

/// Receives one vehicle stream of `T` from shared memory.
pub struct ShmSubscriber<T: ShmPayload> {
    subscriber: Subscriber<ipc::Service, T, ()>,
    listener: Listener<ipc::Service>,
    _events: EventFactory,
    _pubsub: PubSubFactory<T>,
    _node: Node<ipc::Service>,
    service: String,
}

impl<T: ShmPayload> ShmSubscriber<T> {
    /// Opens `risktwin/<vehicle_id>/<T::STREAM>` for receiving. Samples sent before this returns
    /// are not delivered (no history).
    pub fn new(vehicle_id: &str, qos: ShmQos) -> Result<Self, ShmError> {
        let service = service_name(vehicle_id, T::STREAM)?;
        let node = create_node(&service)?;
        let (pubsub, events) = open_services::<T>(&node, &service, &qos)?;
        let subscriber = pubsub
            .subscriber_builder()
            .buffer_size(qos.subscriber_buffer)
            .create()
            .map_err(|source| ShmError::CreateSubscriber { service: service.clone(), source })?;
        let listener = events
            .listener_builder()
            .create()
            .map_err(|source| ShmError::CreateListener { service: service.clone(), source })?;
        Ok(Self { subscriber, listener, _events: events, _pubsub: pubsub, _node: node, service })
    }

    /// The iceoryx2 service name this subscriber reads from.
    pub fn service_name(&self) -> &str {
        &self.service
    }

    /// Takes the next queued sample without blocking (busy-poll); `Ok(None)` when none is queued.
    ///
    /// A sample that fails [`ShmPayload::validate`] is released and reported as
    /// [`ShmError::InvalidSample`]; the next call continues with the following sample.
    pub fn try_receive(&self) -> Result<Option<ShmSample<T>>, ShmError> {
        let Some(sample) =
            self.subscriber.receive().map_err(|source| ShmError::Receive { stream: T::STREAM, source })?
        else {
            return Ok(None);
        };
        let payload = sample.payload();
        match payload.validate() {
            Ok(()) => Ok(Some(ShmSample { sample })),
            Err(source) => Err(ShmError::InvalidSample { stream: T::STREAM, seq: payload.seq(), source }),
        }
    }

    /// Takes the next sample, sleeping until one arrives or `timeout` passes (`Ok(None)`).
    pub fn receive_timeout(&self, timeout: Duration) -> Result<Option<ShmSample<T>>, ShmError> {
        // The clock is read only after a miss, so a queued sample costs no time query.
        if let Some(sample) = self.try_receive()? {
            return Ok(Some(sample));
        }
        let deadline = Instant::now().checked_add(timeout);
        loop {
            // A wake-up may be stale (its sample already taken by a poll) or spurious: the wait
            // drains it and the loop looks at the queue again.
            let wait = match deadline {
                Some(deadline) => {
                    let left = deadline.saturating_duration_since(Instant::now());
                    if left.is_zero() {
                        return Ok(None);
                    }
                    self.listener.timed_wait(|_| {}, left)
                }
                None => self.listener.blocking_wait(|_| {}),
            };
            wait.map_err(|source| ShmError::Wait { stream: T::STREAM, source })?;
            if let Some(sample) = self.try_receive()? {
                return Ok(Some(sample));
            }
        }
    }
}
