//! The edge→cloud streams the ingest role understands, and what each carries.

use risktwin_common::align::{StreamIndex, StreamMode, StreamSpec};
use risktwin_common::telemetry::{CanFrame, ObjectList, RsuObservation, SignalPhase, VehicleStateSample};
use risktwin_protos::WireMessage;

/// One edge→cloud stream; its name is the last segment of its key expression.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Stream {
    /// `VehicleState`, 50 Hz, interpolated.
    State,
    /// `CanFrame`, 100 Hz, as-of.
    Can,
    /// `ObjectList` from a vehicle's perception, 10 Hz, as-of.
    Perception,
    /// `RsuObservation`, 10 Hz, as-of.
    Rsu,
    /// `SignalPhase`, as-of.
    Signal,
}

impl Stream {
    pub const ALL: [Stream; 5] = [Stream::State, Stream::Can, Stream::Perception, Stream::Rsu, Stream::Signal];

    /// The key-expression segment (`risktwin/v1/<site>/<source>/<name>`).
    pub fn name(self) -> &'static str {
        match self {
            Stream::State => "state",
            Stream::Can => "can",
            Stream::Perception => "perception",
            Stream::Rsu => "rsu",
            Stream::Signal => "signal",
        }
    }

    /// The stream named by a key-expression segment.
    pub fn from_name(name: &str) -> Option<Stream> {
        Stream::ALL.into_iter().find(|s| s.name() == name)
    }

    /// The protobuf message type the stream carries (its schema name in a recording).
    pub fn proto_name(self) -> &'static str {
        match self {
            Stream::State => VehicleStateSample::PROTO_NAME,
            Stream::Can => CanFrame::PROTO_NAME,
            Stream::Perception => ObjectList::PROTO_NAME,
            Stream::Rsu => RsuObservation::PROTO_NAME,
            Stream::Signal => SignalPhase::PROTO_NAME,
        }
    }

    /// Position in the aligner's stream table.
    pub fn index(self) -> StreamIndex {
        StreamIndex(self as u16)
    }

    /// Nominal period, used for staleness.
    pub fn period_ns(self) -> i64 {
        match self {
            Stream::State => 20_000_000,
            Stream::Can => 10_000_000,
            Stream::Perception | Stream::Rsu => 100_000_000,
            Stream::Signal => 1_000_000_000,
        }
    }

    /// The aligner specification of every stream, in index order.
    pub fn specs() -> Vec<StreamSpec> {
        Stream::ALL
            .into_iter()
            .map(|s| StreamSpec {
                mode: if s == Stream::State { StreamMode::Interpolated } else { StreamMode::AsOf },
                period_ns: s.period_ns(),
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_indices_follow_the_table() {
        for (i, s) in Stream::ALL.into_iter().enumerate() {
            assert_eq!(Stream::from_name(s.name()), Some(s));
            assert_eq!(s.index(), StreamIndex(i as u16));
        }
        assert_eq!(Stream::from_name("bogus"), None);
        assert_eq!(Stream::specs().len(), Stream::ALL.len());
    }
}
