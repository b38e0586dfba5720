//! Edge roles (vehicle, RSU, replay) land with the edge–cloud pipeline.
//! - [`shm`]: zero-copy iceoryx2 exchange between a vehicle's sensor producer and its gateway.

pub mod shm;
