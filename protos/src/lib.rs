//! RiskTwin's wire schema: the protobuf messages of package `risktwin.v1` (`proto/risktwin/v1/`),
//! the Foxglove visualisation messages of package `foxglove`, and the conversions between the
//! generated types and the `common` domain types.
//!
//! Code outside the transport layer should never see a generated type: it calls
//! [`encode`]/[`decode`] on `risktwin_common::telemetry` types. The generated modules are public
//! for the transport and recording code (`FILE_DESCRIPTOR_SET` feeds MCAP schema records);
//! [`convert::foxglove`] builds the Foxglove visualisation messages from domain types.

pub mod convert;
pub mod recording;

/// Generated types of package `risktwin.v1`.
#[allow(clippy::all, missing_docs)]
pub mod v1 {
    include!(concat!(env!("OUT_DIR"), "/risktwin.v1.rs"));
}

/// Generated types of package `foxglove` (wire-compatible with Foxglove's schemas).
#[allow(clippy::all, missing_docs)]
pub mod foxglove {
    include!(concat!(env!("OUT_DIR"), "/foxglove.rs"));
}

/// Encoded `google.protobuf.FileDescriptorSet` of every `.proto` file of this crate and its imports
/// (well-known types included), without source info. MCAP stores it as the schema data of every
/// protobuf channel: a reader finds the channel's message by its full name in the set.
pub const FILE_DESCRIPTOR_SET: &[u8] = include_bytes!(concat!(env!("OUT_DIR"), "/file_descriptor_set.bin"));

pub use convert::{
    ConvertError, DecodeError, PROTOBUF_MEDIA_TYPE, WireMessage, check_encoding, decode, decode_tagged, encode,
    encode_into, encoding_of, header_seq,
};
