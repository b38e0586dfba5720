//! V2X: the radio channel between vehicles and road-side units (sidelink), applied per message
//! and per receiver from the distance between them in the ground truth — never to physics.

pub mod awareness;
pub mod bler;
pub mod cam;
pub mod channel;
pub mod cpm;
pub mod experiment;
pub mod latency;
pub mod link;
pub mod loss;
pub mod messages;
pub mod sps;
pub mod sps_reference;
mod sps_sensing;
pub mod sweep;
pub mod twin;
pub mod warning;
