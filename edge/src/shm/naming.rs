//! Service names: one iceoryx2 service per vehicle and stream, `risktwin/<vehicle_id>/<stream>`.

use super::error::ShmError;
use super::stream::ShmStream;

/// Longest accepted vehicle id, in bytes (keeps service names far below iceoryx2's limit).
pub const MAX_VEHICLE_ID_LEN: usize = 64;

/// Checks that `id` is 1..=[`MAX_VEHICLE_ID_LEN`] bytes of `[A-Za-z0-9_-]`.
///
/// The same id becomes a Zenoh key segment in the gateway, so separators and wildcards
/// (`/`, `*`, `$`, `?`, `#`) are refused here rather than misrouted later.
pub fn validate_vehicle_id(id: &str) -> Result<(), ShmError> {
    let reason = if id.is_empty() {
        Some("empty")
    } else if id.len() > MAX_VEHICLE_ID_LEN {
        Some("longer than 64 bytes")
    } else if !id.bytes().all(|b| b.is_ascii_alphanumeric() || b == b'_' || b == b'-') {
        Some("only ASCII letters, digits, '_' and '-' are allowed")
    } else {
        None
    };
    match reason {
        Some(reason) => Err(ShmError::InvalidVehicleId { id: id.to_owned(), reason }),
        None => Ok(()),
    }
}

/// The iceoryx2 service name of `stream` for `vehicle_id`: `risktwin/<vehicle_id>/<stream>`.
pub fn service_name(vehicle_id: &str, stream: ShmStream) -> Result<String, ShmError> {
    validate_vehicle_id(vehicle_id)?;
    Ok(format!("risktwin/{vehicle_id}/{stream}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_follow_the_scheme() {
        assert_eq!(service_name("car-7", ShmStream::State).unwrap(), "risktwin/car-7/state");
        assert_eq!(service_name("car_7", ShmStream::Can).unwrap(), "risktwin/car_7/can");
        assert_eq!(service_name("A1", ShmStream::Objects).unwrap(), "risktwin/A1/objects");
    }

    #[test]
    fn bad_ids_are_refused_with_the_id() {
        for bad in ["", "a/b", "car*", "car 1", "é", "$x", "a?b", "a#b"] {
            let err = validate_vehicle_id(bad).unwrap_err();
            assert!(matches!(err, ShmError::InvalidVehicleId { ref id, .. } if id == bad), "{bad:?}: {err}");
        }
        let long = "x".repeat(MAX_VEHICLE_ID_LEN + 1);
        assert!(validate_vehicle_id(&long).is_err());
        assert!(validate_vehicle_id(&long[..MAX_VEHICLE_ID_LEN]).is_ok());
    }
}
