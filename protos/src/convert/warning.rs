//! The cloud's hazard warning to one vehicle.

use super::geometry::{footprint_from, footprint_to, header, pose_from, pose_to, vec_from, vec_to};
use super::{ConvertError, enum_value, non_empty, non_negative, unspecified};
use crate::v1;
use risktwin_common::telemetry::{HazardKind, HazardWarning};

impl From<HazardKind> for v1::HazardKind {
    fn from(k: HazardKind) -> Self {
        match k {
            HazardKind::Contact => v1::HazardKind::Contact,
            HazardKind::LaneTtc => v1::HazardKind::LaneTtc,
            HazardKind::PredictedContact => v1::HazardKind::PredictedContact,
        }
    }
}

impl From<&HazardWarning> for v1::HazardWarning {
    fn from(w: &HazardWarning) -> Self {
        Self {
            header: Some((&w.header).into()),
            warned_source: w.warned_source.clone(),
            hazard_source: w.hazard_source.clone(),
            hazard_pose: Some(pose_to(&w.hazard_pose)),
            hazard_velocity_mps: Some(vec_to(&w.hazard_velocity)),
            hazard_footprint: Some(footprint_to(&w.hazard_footprint)),
            kind: v1::HazardKind::from(w.kind) as i32,
            ttc_s: w.ttc_s,
            distance_m: w.distance_m,
            trigger_source: w.trigger_source.clone(),
            trigger_seq: w.trigger_seq,
            trigger_capture_time_ns: w.trigger_capture_time_ns,
        }
    }
}

impl TryFrom<v1::HazardWarning> for HazardWarning {
    type Error = ConvertError;
    fn try_from(w: v1::HazardWarning) -> Result<Self, ConvertError> {
        const M: &str = "HazardWarning";
        let kind = match enum_value::<v1::HazardKind>(M, "kind", w.kind)? {
            v1::HazardKind::Contact => HazardKind::Contact,
            v1::HazardKind::LaneTtc => HazardKind::LaneTtc,
            v1::HazardKind::PredictedContact => HazardKind::PredictedContact,
            v1::HazardKind::Unspecified => return Err(unspecified(M, "kind")),
        };
        Ok(Self {
            header: header(M, w.header)?,
            warned_source: non_empty(M, "warned_source", w.warned_source)?,
            hazard_source: non_empty(M, "hazard_source", w.hazard_source)?,
            hazard_pose: pose_from(M, "hazard_pose", w.hazard_pose)?,
            hazard_velocity: vec_from(M, "hazard_velocity_mps", w.hazard_velocity_mps)?,
            hazard_footprint: footprint_from(M, "hazard_footprint", w.hazard_footprint)?,
            kind,
            ttc_s: non_negative(M, "ttc_s", w.ttc_s)?,
            distance_m: non_negative(M, "distance_m", w.distance_m)?,
            trigger_source: non_empty(M, "trigger_source", w.trigger_source)?,
            trigger_seq: w.trigger_seq,
            trigger_capture_time_ns: w.trigger_capture_time_ns,
        })
    }
}
