//! Conversions between the shared-memory payloads and the `common` domain types.
//!
//! Into shared memory never fails except for capacity; out of it always validates first, so a
//! `common` value built here is finite and in range. Two conversions are lossy by design and
//! documented where they happen: extents travel as f32 (sub-micrometre loss at vehicle sizes) and
//! an object's orientation travels as a heading angle, so its unit axis is recomputed (≤ 1 ulp).

use risktwin_common::geometry::{Footprint, Obb, Pose, Vec2};
use risktwin_common::sensor::PerceivedObject;
use risktwin_common::vehicle::VehicleState;

use super::error::ShmPayloadError;
use super::payload::{
    OBJECT_LIST_CAPACITY, ShmObject, ShmObjectList, ShmPayload, ShmVehicleState, object_kind_code,
    object_kind_from_code,
};

impl ShmVehicleState {
    /// The shared-memory form of a vehicle's state and footprint (extents narrowed to f32).
    pub fn from_common(seq: u64, capture_time_ns: i64, state: &VehicleState, footprint: &Footprint) -> Self {
        Self {
            seq,
            capture_time_ns,
            x_m: state.x_m,
            y_m: state.y_m,
            heading_rad: state.heading_rad,
            speed_mps: state.speed_mps,
            accel_mps2: state.accel_mps2,
            yaw_rate_radps: state.yaw_rate_radps,
            steer_rad: state.steer_rad,
            slip_angle_rad: state.slip_angle_rad,
            length_m: footprint.length_m as f32,
            width_m: footprint.width_m as f32,
        }
    }

    /// The validated `common` state and footprint.
    pub fn to_common(&self) -> Result<(VehicleState, Footprint), ShmPayloadError> {
        self.validate()?;
        let state = VehicleState {
            x_m: self.x_m,
            y_m: self.y_m,
            heading_rad: self.heading_rad,
            speed_mps: self.speed_mps,
            yaw_rate_radps: self.yaw_rate_radps,
            slip_angle_rad: self.slip_angle_rad,
            steer_rad: self.steer_rad,
            accel_mps2: self.accel_mps2,
        };
        Ok((state, Footprint::new(f64::from(self.length_m), f64::from(self.width_m))))
    }

    /// The pose (centre of gravity and heading); meaningful once validated.
    pub fn pose(&self) -> Pose {
        Pose::new(self.x_m, self.y_m, self.heading_rad)
    }
}

impl ShmObject {
    /// The shared-memory form of a perceived object (heading from its axis, extents as f32).
    pub fn from_perceived(object: &PerceivedObject) -> Self {
        let obb = &object.obb;
        Self {
            id: object.id,
            kind: object_kind_code(object.kind),
            x_m: obb.centre.x,
            y_m: obb.centre.y,
            heading_rad: obb.axis.y.atan2(obb.axis.x),
            vx_mps: object.velocity.x,
            vy_mps: object.velocity.y,
            visible_fraction: object.visible_fraction,
            length_m: (2.0 * obb.half_length_m) as f32,
            width_m: (2.0 * obb.half_width_m) as f32,
        }
    }

    /// The validated `common` object; `index` only labels errors.
    pub fn to_perceived(&self, index: usize) -> Result<PerceivedObject, ShmPayloadError> {
        self.validate_at(index)?;
        let kind =
            object_kind_from_code(self.kind).ok_or(ShmPayloadError::UnknownObjectKind { index, code: self.kind })?;
        let pose = Pose::new(self.x_m, self.y_m, self.heading_rad);
        let footprint = Footprint::new(f64::from(self.length_m), f64::from(self.width_m));
        Ok(PerceivedObject {
            id: self.id,
            kind,
            obb: Obb::new(pose, footprint),
            velocity: Vec2::new(self.vx_mps, self.vy_mps),
            visible_fraction: self.visible_fraction,
        })
    }
}

impl ShmObjectList {
    /// Overwrites the header and the objects in place (for [`super::ShmPublisher::publish_with`]);
    /// fails without writing when `objects` exceeds [`OBJECT_LIST_CAPACITY`].
    pub fn fill_from_perceived(
        &mut self,
        seq: u64,
        capture_time_ns: i64,
        objects: &[PerceivedObject],
    ) -> Result<(), ShmPayloadError> {
        if objects.len() > OBJECT_LIST_CAPACITY {
            return Err(ShmPayloadError::CountOverCapacity {
                count: u32::try_from(objects.len()).unwrap_or(u32::MAX),
                capacity: OBJECT_LIST_CAPACITY,
            });
        }
        self.seq = seq;
        self.capture_time_ns = capture_time_ns;
        for (slot, object) in self.objects.iter_mut().zip(objects) {
            *slot = ShmObject::from_perceived(object);
        }
        self.count = objects.len() as u32;
        Ok(())
    }

    /// Validates the list and appends its objects to `out` (cleared first).
    pub fn to_perceived(&self, out: &mut Vec<PerceivedObject>) -> Result<(), ShmPayloadError> {
        self.validate()?;
        out.clear();
        for (index, object) in self.objects().iter().enumerate() {
            out.push(object.to_perceived(index)?);
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::sensor::ObjectKind;

    fn state() -> VehicleState {
        VehicleState {
            x_m: 12.5,
            y_m: -3.25,
            heading_rad: 0.3,
            speed_mps: 13.9,
            yaw_rate_radps: 0.05,
            slip_angle_rad: 0.01,
            steer_rad: -0.02,
            accel_mps2: -1.5,
        }
    }

    fn object(kind: ObjectKind) -> PerceivedObject {
        PerceivedObject {
            id: 42,
            kind,
            obb: Obb::new(Pose::new(30.0, 1.5, 2.0), Footprint::new(4.5, 1.8)),
            velocity: Vec2::new(-8.0, 0.5),
            visible_fraction: 0.6,
        }
    }

    #[test]
    fn vehicle_state_round_trips() {
        let footprint = Footprint::new(4.5, 1.75);
        let shm = ShmVehicleState::from_common(9, 1_000, &state(), &footprint);
        let (back, back_footprint) = shm.to_common().unwrap();
        assert_eq!(back, state());
        // 4.5 and 1.75 are exact in f32.
        assert_eq!(back_footprint, footprint);
        assert_eq!(shm.pose(), Pose::new(12.5, -3.25, 0.3));
    }

    #[test]
    fn nan_state_is_refused_on_the_way_out() {
        let mut shm = ShmVehicleState::from_common(1, 0, &state(), &Footprint::new(4.5, 1.8));
        shm.x_m = f64::NAN;
        assert!(matches!(shm.to_common(), Err(ShmPayloadError::NotFinite { field: "x_m", .. })));
    }

    #[test]
    fn objects_round_trip_every_kind() {
        let objects = [object(ObjectKind::Vehicle), object(ObjectKind::Pedestrian), object(ObjectKind::Parked)];
        let mut list = ShmObjectList::EMPTY;
        list.fill_from_perceived(4, 77, &objects).unwrap();
        assert_eq!((list.seq, list.capture_time_ns, list.count), (4, 77, 3));
        let mut back = Vec::new();
        list.to_perceived(&mut back).unwrap();
        assert_eq!(back.len(), 3);
        for (got, want) in back.iter().zip(&objects) {
            assert_eq!(
                (got.id, got.kind, got.velocity, got.visible_fraction),
                (want.id, want.kind, want.velocity, want.visible_fraction)
            );
            assert_eq!(got.obb.centre, want.obb.centre);
            assert!((got.obb.axis - want.obb.axis).norm() < 1e-15, "{:?} vs {:?}", got.obb.axis, want.obb.axis);
            assert!((got.obb.half_length_m - want.obb.half_length_m).abs() < 1e-6);
            assert!((got.obb.half_width_m - want.obb.half_width_m).abs() < 1e-6);
        }
    }

    #[test]
    fn too_many_objects_are_refused_without_writing() {
        let objects = vec![object(ObjectKind::Vehicle); OBJECT_LIST_CAPACITY + 1];
        let mut list = ShmObjectList::EMPTY;
        assert_eq!(
            list.fill_from_perceived(1, 0, &objects),
            Err(ShmPayloadError::CountOverCapacity { count: 65, capacity: 64 })
        );
        assert_eq!(list, ShmObjectList::EMPTY);
    }
}
