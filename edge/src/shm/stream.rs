//! The streams of the shared-memory exchange, named by the last segment of their service name.

use std::fmt;

/// The streams a vehicle's sensor producer publishes to its gateway.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ShmStream {
    /// Ego vehicle state ([`super::ShmVehicleState`]).
    State,
    /// CAN-like signal frames ([`super::ShmCanFrame`]).
    Can,
    /// Perceived object lists ([`super::ShmObjectList`]).
    Objects,
}

impl ShmStream {
    /// The last segment of the service name.
    pub const fn as_str(self) -> &'static str {
        match self {
            ShmStream::State => "state",
            ShmStream::Can => "can",
            ShmStream::Objects => "objects",
        }
    }
}

impl fmt::Display for ShmStream {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}
