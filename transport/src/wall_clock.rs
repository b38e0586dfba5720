//! The host's wall clock, in the nanoseconds the wire's headers carry.

use std::time::{SystemTime, UNIX_EPOCH};

/// Nanoseconds since the Unix epoch, now; 0 on a clock set before 1970.
///
/// Only the roles read it: the domain core takes its time as an argument.
pub fn unix_ns() -> i64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_nanos() as i64)
}
