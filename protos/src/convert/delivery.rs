//! The cloud's delivery acknowledgement to one edge.

use super::geometry::header;
use super::{ConvertError, non_empty};
use crate::v1;
use risktwin_common::delivery::{DeliveryAck, StreamAck};

impl From<&DeliveryAck> for v1::DeliveryAck {
    fn from(a: &DeliveryAck) -> Self {
        Self {
            header: Some((&a.header).into()),
            edge_source: a.edge_source.clone(),
            edge_session: a.edge_session.clone(),
            cloud_session: a.cloud_session.clone(),
            streams: a
                .streams
                .iter()
                .map(|s| v1::StreamAck {
                    stream: s.stream.clone(),
                    next_seq: s.next_seq,
                    received: s.received,
                    lost: s.lost,
                })
                .collect(),
            shed: a.shed.clone(),
        }
    }
}

impl TryFrom<v1::DeliveryAck> for DeliveryAck {
    type Error = ConvertError;
    fn try_from(a: v1::DeliveryAck) -> Result<Self, ConvertError> {
        const M: &str = "DeliveryAck";
        let mut streams = Vec::with_capacity(a.streams.len());
        for s in a.streams {
            // More received than numbers accounted for cannot be true.
            if s.received > s.next_seq {
                return Err(ConvertError::InvalidField {
                    message: "StreamAck",
                    field: "received",
                    reason: format!("{} above next_seq {}", s.received, s.next_seq),
                });
            }
            streams.push(StreamAck {
                stream: non_empty("StreamAck", "stream", s.stream)?,
                next_seq: s.next_seq,
                received: s.received,
                lost: s.lost,
            });
        }
        Ok(Self {
            header: header(M, a.header)?,
            edge_source: non_empty(M, "edge_source", a.edge_source)?,
            edge_session: non_empty(M, "edge_session", a.edge_session)?,
            cloud_session: non_empty(M, "cloud_session", a.cloud_session)?,
            streams,
            shed: a.shed.into_iter().map(|name| non_empty(M, "shed", name)).collect::<Result<_, _>>()?,
        })
    }
}
