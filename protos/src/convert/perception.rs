//! Perceived objects, RSU observations and traffic-light phases.

use super::geometry::{footprint_from, footprint_to, header, pose_from, pose_to, vec_from, vec_to};
use super::{ConvertError, enum_value, finite, non_negative, unspecified};
use crate::v1;
use risktwin_common::sensor::ObjectKind;
use risktwin_common::telemetry::{DetectedObject, ObjectList, Phase, RsuObservation, SignalPhase};

impl From<ObjectKind> for v1::ObjectKind {
    fn from(k: ObjectKind) -> Self {
        match k {
            ObjectKind::Vehicle => v1::ObjectKind::Vehicle,
            ObjectKind::Pedestrian => v1::ObjectKind::Pedestrian,
            ObjectKind::Parked => v1::ObjectKind::Parked,
        }
    }
}

impl From<&DetectedObject> for v1::DetectedObject {
    fn from(o: &DetectedObject) -> Self {
        Self {
            id: o.id,
            kind: v1::ObjectKind::from(o.kind) as i32,
            pose: Some(pose_to(&o.pose)),
            footprint: Some(footprint_to(&o.footprint)),
            velocity_mps: Some(vec_to(&o.velocity)),
            accel_mps2: o.accel_mps2,
        }
    }
}

impl TryFrom<v1::DetectedObject> for DetectedObject {
    type Error = ConvertError;
    fn try_from(o: v1::DetectedObject) -> Result<Self, ConvertError> {
        const M: &str = "DetectedObject";
        let kind = match enum_value::<v1::ObjectKind>(M, "kind", o.kind)? {
            v1::ObjectKind::Vehicle => ObjectKind::Vehicle,
            v1::ObjectKind::Pedestrian => ObjectKind::Pedestrian,
            v1::ObjectKind::Parked => ObjectKind::Parked,
            v1::ObjectKind::Unspecified => return Err(unspecified(M, "kind")),
        };
        Ok(Self {
            id: o.id,
            kind,
            pose: pose_from(M, "pose", o.pose)?,
            footprint: footprint_from(M, "footprint", o.footprint)?,
            velocity: vec_from(M, "velocity_mps", o.velocity_mps)?,
            accel_mps2: finite(M, "accel_mps2", o.accel_mps2)?,
        })
    }
}

fn objects(list: Vec<v1::DetectedObject>) -> Result<Vec<DetectedObject>, ConvertError> {
    list.into_iter().map(DetectedObject::try_from).collect()
}

impl From<&ObjectList> for v1::ObjectList {
    fn from(l: &ObjectList) -> Self {
        Self { header: Some((&l.header).into()), objects: l.objects.iter().map(Into::into).collect() }
    }
}

impl TryFrom<v1::ObjectList> for ObjectList {
    type Error = ConvertError;
    fn try_from(l: v1::ObjectList) -> Result<Self, ConvertError> {
        Ok(Self { header: header("ObjectList", l.header)?, objects: objects(l.objects)? })
    }
}

impl From<&RsuObservation> for v1::RsuObservation {
    fn from(r: &RsuObservation) -> Self {
        Self {
            header: Some((&r.header).into()),
            rsu_pose: Some(pose_to(&r.rsu_pose)),
            range_m: r.range_m,
            objects: r.objects.iter().map(Into::into).collect(),
        }
    }
}

impl TryFrom<v1::RsuObservation> for RsuObservation {
    type Error = ConvertError;
    fn try_from(r: v1::RsuObservation) -> Result<Self, ConvertError> {
        const M: &str = "RsuObservation";
        Ok(Self {
            header: header(M, r.header)?,
            rsu_pose: pose_from(M, "rsu_pose", r.rsu_pose)?,
            range_m: non_negative(M, "range_m", r.range_m)?,
            objects: objects(r.objects)?,
        })
    }
}

impl From<&SignalPhase> for v1::SignalPhase {
    fn from(s: &SignalPhase) -> Self {
        let phase = match s.phase {
            Phase::Red => v1::Phase::Red,
            Phase::Amber => v1::Phase::Amber,
            Phase::Green => v1::Phase::Green,
        };
        Self {
            header: Some((&s.header).into()),
            signal_id: s.signal_id,
            phase: phase as i32,
            time_to_change_s: s.time_to_change_s,
        }
    }
}

impl TryFrom<v1::SignalPhase> for SignalPhase {
    type Error = ConvertError;
    fn try_from(s: v1::SignalPhase) -> Result<Self, ConvertError> {
        const M: &str = "SignalPhase";
        let phase = match enum_value::<v1::Phase>(M, "phase", s.phase)? {
            v1::Phase::Red => Phase::Red,
            v1::Phase::Amber => Phase::Amber,
            v1::Phase::Green => Phase::Green,
            v1::Phase::Unspecified => return Err(unspecified(M, "phase")),
        };
        Ok(Self {
            header: header(M, s.header)?,
            signal_id: s.signal_id,
            phase,
            time_to_change_s: non_negative(M, "time_to_change_s", s.time_to_change_s)?,
        })
    }
}
