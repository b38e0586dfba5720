//! Conversions between the generated wire types and the `common::telemetry` domain types, and the
//! [`encode`]/[`decode`] entry points that keep prost out of every caller.
//!
//! `From<&domain>` builds the wire message (infallible); `TryFrom<wire>` validates it and is where
//! the cloud's ingest rejects bad input: missing required sub-messages, NaN/±inf numbers (except
//! where `+inf` has a documented meaning), negative sizes, out-of-range values and enum values that
//! are unknown or `*_UNSPECIFIED`. One file per message family.
//!
//! Numbers survive a round trip bit for bit, with one exception: `-0.0` arrives as `+0.0`, since
//! proto3 does not send a field equal to its default and prost compares floats with `== 0.0`.

mod delivery;
pub mod foxglove;
mod geometry;
mod map;
mod perception;
mod risk;
mod scenario;
mod vehicle;
mod warning;

#[cfg(test)]
pub(crate) mod tests;

use prost::Message;
use risktwin_align::DropReason;
use risktwin_common::telemetry;

/// Why a wire message is not a valid domain value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConvertError {
    #[error("{message}.{field} is missing")]
    MissingField { message: &'static str, field: &'static str },
    #[error("{message}.{field} is invalid: {reason}")]
    InvalidField { message: &'static str, field: &'static str, reason: String },
}

/// Why bytes did not decode to a domain value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DecodeError {
    #[error("malformed protobuf: {0}")]
    Malformed(#[from] prost::DecodeError),
    #[error(transparent)]
    Invalid(#[from] ConvertError),
    /// The bytes are tagged with another encoding than the type's (another message, another
    /// schema version, or none): they are not read.
    #[error("encoding {found}, expected application/protobuf;{expected}")]
    WrongSchema { found: String, expected: &'static str },
}

impl DecodeError {
    /// Why the ingest drops such a message.
    pub fn drop_reason(&self) -> DropReason {
        match self {
            DecodeError::Malformed(_) => DropReason::Malformed,
            DecodeError::Invalid(ConvertError::MissingField { .. }) => DropReason::MissingField,
            DecodeError::Invalid(ConvertError::InvalidField { .. }) => DropReason::InvalidField,
            DecodeError::WrongSchema { .. } => DropReason::WrongSchema,
        }
    }

    /// A short, stable label for counting rejections by reason: the [`DropReason`] code
    /// (`malformed`, `missing-field`, `invalid-field`, `wrong-schema`).
    pub fn reason(&self) -> &'static str {
        self.drop_reason().code()
    }
}

/// A domain type with a wire form.
pub trait WireMessage: Sized {
    /// The generated message type.
    type Proto: Message + Default;
    /// Full protobuf name of the wire message (the MCAP schema name), e.g. `risktwin.v1.VehicleState`.
    const PROTO_NAME: &'static str;
    /// The wire form.
    fn to_proto(&self) -> Self::Proto;
    /// The validated domain value.
    fn from_proto(proto: Self::Proto) -> Result<Self, ConvertError>;
}

/// Encodes a domain value to protobuf bytes.
pub fn encode<T: WireMessage>(msg: &T) -> Vec<u8> {
    msg.to_proto().encode_to_vec()
}

/// Encodes a domain value, appending to `buf` (reuse one buffer to avoid an allocation per message).
pub fn encode_into<T: WireMessage>(msg: &T, buf: &mut Vec<u8>) {
    let proto = msg.to_proto();
    buf.reserve(proto.encoded_len());
    // Encoding into a Vec cannot run out of space: it grows.
    proto.encode(buf).expect("a Vec<u8> grows to fit any message");
}

/// Decodes and validates protobuf bytes as a domain value.
pub fn decode<T: WireMessage>(bytes: &[u8]) -> Result<T, DecodeError> {
    let proto = T::Proto::decode(bytes)?;
    Ok(T::from_proto(proto)?)
}

/// The header's sequence number of an encoded message of the schema (each carries its
/// `Header` as field 1), read without decoding the rest: `None` when the bytes do not parse
/// or have no header.
pub fn header_seq(bytes: &[u8]) -> Option<u64> {
    /// Field 1 of every message, and field 2 (`seq`) of its header; the rest is skipped.
    #[derive(Clone, PartialEq, prost::Message)]
    struct Headed {
        #[prost(message, optional, tag = "1")]
        header: Option<SeqOnly>,
    }
    #[derive(Clone, PartialEq, prost::Message)]
    struct SeqOnly {
        #[prost(uint64, tag = "2")]
        seq: u64,
    }
    Headed::decode(bytes).ok()?.header.map(|h| h.seq)
}

/// The media type of every protobuf payload.
pub const PROTOBUF_MEDIA_TYPE: &str = "application/protobuf";

/// The encoding that tags a payload of message `name` on the wire (a Zenoh sample's encoding):
/// `application/protobuf;risktwin.v1.VehicleState`. The package carries the schema version.
pub fn encoding_of(name: &str) -> String {
    format!("{PROTOBUF_MEDIA_TYPE};{name}")
}

/// Decodes bytes tagged with `encoding` (as [`encoding_of`] writes it): refused unless it names
/// `T`, so a message of another type or schema version, or an untagged one, is never misread.
pub fn decode_tagged<T: WireMessage>(encoding: &str, bytes: &[u8]) -> Result<T, DecodeError> {
    check_encoding(encoding, T::PROTO_NAME)?;
    decode(bytes)
}

/// `Ok` when `encoding` tags a protobuf message `name`; else the error naming what came.
pub fn check_encoding(encoding: &str, name: &'static str) -> Result<(), DecodeError> {
    let tagged = encoding.strip_prefix(PROTOBUF_MEDIA_TYPE).and_then(|rest| rest.strip_prefix(';'));
    if tagged == Some(name) {
        Ok(())
    } else {
        Err(DecodeError::WrongSchema { found: encoding.to_owned(), expected: name })
    }
}

/// Implements [`WireMessage`] from a `From<&Domain> for Proto` and a `TryFrom<Proto> for Domain`.
macro_rules! wire_message {
    ($domain:ty, $proto:ty, $name:literal) => {
        impl $crate::convert::WireMessage for $domain {
            type Proto = $proto;
            const PROTO_NAME: &'static str = $name;
            fn to_proto(&self) -> Self::Proto {
                self.into()
            }
            fn from_proto(proto: Self::Proto) -> Result<Self, $crate::convert::ConvertError> {
                proto.try_into()
            }
        }
    };
}

wire_message!(telemetry::VehicleStateSample, crate::v1::VehicleState, "risktwin.v1.VehicleState");
wire_message!(telemetry::CanFrame, crate::v1::CanFrame, "risktwin.v1.CanFrame");
wire_message!(telemetry::ObjectList, crate::v1::ObjectList, "risktwin.v1.ObjectList");
wire_message!(telemetry::RsuObservation, crate::v1::RsuObservation, "risktwin.v1.RsuObservation");
wire_message!(telemetry::SignalPhase, crate::v1::SignalPhase, "risktwin.v1.SignalPhase");
wire_message!(telemetry::RoadMap, crate::v1::RoadMap, "risktwin.v1.RoadMap");
wire_message!(telemetry::RiskField, crate::v1::RiskGrid, "risktwin.v1.RiskGrid");
wire_message!(telemetry::RiskReport, crate::v1::RiskReport, "risktwin.v1.RiskReport");
wire_message!(telemetry::ControlCommand, crate::v1::ControlCommand, "risktwin.v1.ControlCommand");
wire_message!(telemetry::PolicyUpdate, crate::v1::PolicyUpdate, "risktwin.v1.PolicyUpdate");
wire_message!(telemetry::ScenarioPush, crate::v1::ScenarioPush, "risktwin.v1.ScenarioPush");
wire_message!(telemetry::ScenarioResult, crate::v1::ScenarioResult, "risktwin.v1.ScenarioResult");
wire_message!(telemetry::HazardWarning, crate::v1::HazardWarning, "risktwin.v1.HazardWarning");
wire_message!(risktwin_common::delivery::DeliveryAck, crate::v1::DeliveryAck, "risktwin.v1.DeliveryAck");

// Validation helpers shared by the per-family files.

/// A required sub-message.
pub(crate) fn required<T>(message: &'static str, field: &'static str, v: Option<T>) -> Result<T, ConvertError> {
    v.ok_or(ConvertError::MissingField { message, field })
}

pub(crate) fn invalid(message: &'static str, field: &'static str, reason: impl Into<String>) -> ConvertError {
    ConvertError::InvalidField { message, field, reason: reason.into() }
}

/// A finite number.
pub(crate) fn finite(message: &'static str, field: &'static str, v: f64) -> Result<f64, ConvertError> {
    if v.is_finite() { Ok(v) } else { Err(invalid(message, field, format!("{v} is not finite"))) }
}

/// A finite number within `[lo, hi]`.
pub(crate) fn in_range(
    message: &'static str,
    field: &'static str,
    v: f64,
    lo: f64,
    hi: f64,
) -> Result<f64, ConvertError> {
    if v >= lo && v <= hi { Ok(v) } else { Err(invalid(message, field, format!("{v} is outside [{lo}, {hi}]"))) }
}

/// A finite number ≥ 0.
pub(crate) fn non_negative(message: &'static str, field: &'static str, v: f64) -> Result<f64, ConvertError> {
    if v >= 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(invalid(message, field, format!("{v} is not a finite number ≥ 0")))
    }
}

/// A finite number > 0.
pub(crate) fn positive(message: &'static str, field: &'static str, v: f64) -> Result<f64, ConvertError> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(invalid(message, field, format!("{v} is not a finite number > 0")))
    }
}

/// A distance that may be `+inf` (nothing there) but not NaN or negative.
pub(crate) fn distance_or_inf(message: &'static str, field: &'static str, v: f64) -> Result<f64, ConvertError> {
    if v >= 0.0 { Ok(v) } else { Err(invalid(message, field, format!("{v} is not ≥ 0 or +inf"))) }
}

/// A non-empty string.
pub(crate) fn non_empty(message: &'static str, field: &'static str, v: String) -> Result<String, ConvertError> {
    if v.is_empty() { Err(ConvertError::MissingField { message, field }) } else { Ok(v) }
}

/// A known enum value (callers reject `*_UNSPECIFIED` with [`unspecified`]).
pub(crate) fn enum_value<E: TryFrom<i32>>(
    message: &'static str,
    field: &'static str,
    v: i32,
) -> Result<E, ConvertError> {
    E::try_from(v).map_err(|_| invalid(message, field, format!("unknown enum value {v}")))
}

/// The error for a required enum left at `*_UNSPECIFIED` (wire value 0).
pub(crate) fn unspecified(message: &'static str, field: &'static str) -> ConvertError {
    invalid(message, field, "value is UNSPECIFIED (0)")
}
