//! What the ingest needs to know of each edge→cloud stream beyond its key: the protobuf type it
//! carries and how the aligner treats it. The streams themselves are
//! [`risktwin_transport::EdgeStream`], defined once with the key scheme.

use risktwin_align::{StreamIndex, StreamMode, StreamSpec};
use risktwin_common::telemetry::{CanFrame, ObjectList, RsuObservation, SignalPhase, VehicleStateSample};
use risktwin_protos::WireMessage;
use risktwin_transport::EdgeStream;

/// The protobuf message type `stream` carries (its schema name in a recording).
pub fn proto_name(stream: EdgeStream) -> &'static str {
    match stream {
        EdgeStream::State => VehicleStateSample::PROTO_NAME,
        EdgeStream::Can => CanFrame::PROTO_NAME,
        EdgeStream::Perception => ObjectList::PROTO_NAME,
        EdgeStream::Rsu => RsuObservation::PROTO_NAME,
        EdgeStream::Signal => SignalPhase::PROTO_NAME,
    }
}

/// Position of `stream` in the aligner's stream table (its [`EdgeStream::index`]).
pub fn aligner_index(stream: EdgeStream) -> StreamIndex {
    StreamIndex(stream.index() as u16)
}

/// Nominal period of `stream`, used for staleness: state 50 Hz, CAN 100 Hz, perception and RSU
/// 10 Hz, signal phases 1 Hz.
pub fn period_ns(stream: EdgeStream) -> i64 {
    match stream {
        EdgeStream::State => 20_000_000,
        EdgeStream::Can => 10_000_000,
        EdgeStream::Perception | EdgeStream::Rsu => 100_000_000,
        EdgeStream::Signal => 1_000_000_000,
    }
}

/// The aligner specification of every stream, in index order: state interpolated, the rest
/// as-of.
pub fn aligner_specs() -> Vec<StreamSpec> {
    EdgeStream::ALL
        .into_iter()
        .map(|s| StreamSpec {
            mode: if s == EdgeStream::State { StreamMode::Interpolated } else { StreamMode::AsOf },
            period_ns: period_ns(s),
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indices_follow_the_table() {
        for (i, s) in EdgeStream::ALL.into_iter().enumerate() {
            assert_eq!(aligner_index(s), StreamIndex(i as u16));
            assert_eq!(aligner_specs()[i].period_ns, period_ns(s));
        }
        assert_eq!(aligner_specs().len(), EdgeStream::ALL.len());
        // The key scheme's schema tags name the types the ingest decodes.
        for s in EdgeStream::ALL {
            assert_eq!(s.message(), proto_name(s));
            let tag = risktwin_transport::protobuf(s.message()).to_string();
            assert_eq!(tag, risktwin_protos::encoding_of(proto_name(s)), "what a receiver checks is what is sent");
        }
        assert_eq!(aligner_specs()[0].mode, StreamMode::Interpolated);
    }
}
