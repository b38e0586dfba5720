//! Header, frame and the planar geometry messages.

use super::{ConvertError, enum_value, finite, non_empty, positive, required, unspecified};
use crate::v1;
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::telemetry::{Frame, Header};

impl From<Frame> for v1::Frame {
    fn from(f: Frame) -> Self {
        match f {
            Frame::World => v1::Frame::World,
            Frame::Vehicle => v1::Frame::Vehicle,
        }
    }
}

impl From<&Header> for v1::Header {
    fn from(h: &Header) -> Self {
        Self {
            source: h.source.clone(),
            seq: h.seq,
            capture_time_ns: h.capture_time_ns,
            publish_time_ns: h.publish_time_ns,
            frame: v1::Frame::from(h.frame) as i32,
        }
    }
}

impl TryFrom<v1::Header> for Header {
    type Error = ConvertError;
    fn try_from(h: v1::Header) -> Result<Self, ConvertError> {
        let frame = match enum_value::<v1::Frame>("Header", "frame", h.frame)? {
            v1::Frame::World => Frame::World,
            v1::Frame::Vehicle => Frame::Vehicle,
            v1::Frame::Unspecified => return Err(unspecified("Header", "frame")),
        };
        Ok(Self {
            source: non_empty("Header", "source", h.source)?,
            seq: h.seq,
            capture_time_ns: h.capture_time_ns,
            publish_time_ns: h.publish_time_ns,
            frame,
        })
    }
}

/// The required header of `message`.
pub(crate) fn header(message: &'static str, h: Option<v1::Header>) -> Result<Header, ConvertError> {
    required(message, "header", h)?.try_into()
}

pub(crate) fn pose_to(p: &Pose) -> v1::Pose2 {
    v1::Pose2 { x_m: p.x_m, y_m: p.y_m, heading_rad: p.heading_rad }
}

/// The required, finite pose `field` of `message`.
pub(crate) fn pose_from(
    message: &'static str,
    field: &'static str,
    p: Option<v1::Pose2>,
) -> Result<Pose, ConvertError> {
    let p = required(message, field, p)?;
    Ok(Pose::new(
        finite(message, field, p.x_m)?,
        finite(message, field, p.y_m)?,
        finite(message, field, p.heading_rad)?,
    ))
}

pub(crate) fn vec_to(v: &Vec2) -> v1::Vector2 {
    v1::Vector2 { x: v.x, y: v.y }
}

/// The required, finite vector `field` of `message`.
pub(crate) fn vec_from(
    message: &'static str,
    field: &'static str,
    v: Option<v1::Vector2>,
) -> Result<Vec2, ConvertError> {
    let v = required(message, field, v)?;
    Ok(Vec2::new(finite(message, field, v.x)?, finite(message, field, v.y)?))
}

pub(crate) fn footprint_to(f: &Footprint) -> v1::Footprint {
    v1::Footprint { length_m: f.length_m, width_m: f.width_m }
}

/// The required footprint `field` of `message`, both sides finite and > 0.
pub(crate) fn footprint_from(
    message: &'static str,
    field: &'static str,
    f: Option<v1::Footprint>,
) -> Result<Footprint, ConvertError> {
    let f = required(message, field, f)?;
    Ok(Footprint::new(positive(message, field, f.length_m)?, positive(message, field, f.width_m)?))
}
