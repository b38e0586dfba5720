//! Plain-old-data payloads that live in shared memory, and their validation.
//!
//! Every type is `#[repr(C)]`, fixed size and pointer free, so both processes read the same bytes
//! the same way; padding is spelled out as zeroed `_reserved` fields so that no byte of a sample
//! is left uninitialised. iceoryx2 refuses to connect two sides whose payload type name, size or
//! alignment differ; the type names are fixed (`risktwin.shm.*`) so that a renamed Rust module
//! does not break a deployed producer. Bump the name's version when a layout changes.

use iceoryx2::prelude::ZeroCopySend;
use risktwin_common::sensor::ObjectKind;

use super::error::ShmPayloadError;
use super::stream::ShmStream;

/// How many objects one [`ShmObjectList`] holds at most.
///
/// 64 covers the sensor model's 150 m, 120° field of view in dense traffic with margin; a producer
/// that sees more must drop the farthest ones (the list stays a fixed 4 120-byte chunk).
pub const OBJECT_LIST_CAPACITY: usize = 64;

/// Largest CAN identifier: 29 bits (extended frame format, ISO 11898-1).
pub const MAX_CAN_ID: u32 = 0x1FFF_FFFF;

/// Highest plausible vehicle speed accepted from a producer, m/s (540 km/h).
const MAX_SPEED_MPS: f64 = 150.0;
/// Smallest and largest plausible vehicle or object extent, m.
const MIN_EXTENT_M: f64 = 1e-3;
const MAX_EXTENT_M: f64 = 50.0;

/// The wire code of an object kind (0 is reserved as invalid).
pub const fn object_kind_code(kind: ObjectKind) -> u32 {
    match kind {
        ObjectKind::Vehicle => 1,
        ObjectKind::Pedestrian => 2,
        ObjectKind::Parked => 3,
    }
}

/// The object kind of a wire code, `None` for an unknown code.
pub(super) const fn object_kind_from_code(code: u32) -> Option<ObjectKind> {
    match code {
        1 => Some(ObjectKind::Vehicle),
        2 => Some(ObjectKind::Pedestrian),
        3 => Some(ObjectKind::Parked),
        _ => None,
    }
}

/// A payload that can travel through a [`super::ShmPublisher`]: plain old data with a sequence
/// number and a validation that the receiving side runs before trusting it.
pub trait ShmPayload: ZeroCopySend + Copy + core::fmt::Debug + Send + Sync + 'static {
    /// The stream this payload type travels on.
    const STREAM: ShmStream;
    /// An all-zero value, written into a loaned chunk before it is filled in place.
    const EMPTY: Self;
    /// The producer's sequence number of this sample.
    fn seq(&self) -> u64;
    /// Checks that every field is finite and within its physical range.
    fn validate(&self) -> Result<(), ShmPayloadError>;
}

/// The ego vehicle's state at one instant (88 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("risktwin.shm.VehicleState.v1")]
pub struct ShmVehicleState {
    /// Producer's sequence number, +1 per sample.
    pub seq: u64,
    /// Capture time on the vehicle's own clock, ns.
    pub capture_time_ns: i64,
    /// Centre-of-gravity x in the world frame, m.
    pub x_m: f64,
    /// Centre-of-gravity y in the world frame, m.
    pub y_m: f64,
    /// Yaw angle, rad (not wrapped).
    pub heading_rad: f64,
    /// Speed of the centre of gravity, m/s (never negative).
    pub speed_mps: f64,
    /// Longitudinal acceleration, m/s².
    pub accel_mps2: f64,
    /// Yaw rate, rad/s.
    pub yaw_rate_radps: f64,
    /// Front-wheel steering angle, rad.
    pub steer_rad: f64,
    /// Body slip angle, rad.
    pub slip_angle_rad: f64,
    /// Footprint length, m (f32: millimetre precision is plenty for a box).
    pub length_m: f32,
    /// Footprint width, m.
    pub width_m: f32,
}

/// One CAN-like signal frame (classic CAN, up to 8 data bytes; 32 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("risktwin.shm.CanFrame.v1")]
pub struct ShmCanFrame {
    /// Producer's sequence number, +1 per sample.
    pub seq: u64,
    /// Capture time on the vehicle's own clock, ns.
    pub capture_time_ns: i64,
    /// CAN identifier, at most [`MAX_CAN_ID`].
    pub can_id: u32,
    /// Number of valid bytes in `data`, at most 8.
    pub dlc: u8,
    /// Data bytes; those past `dlc` are zero.
    pub data: [u8; 8],
    _reserved: [u8; 3],
}

/// One perceived object (64 bytes), the shared-memory form of `common::sensor::PerceivedObject`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("risktwin.shm.Object.v1")]
pub struct ShmObject {
    /// Identity of the tracked object.
    pub id: u32,
    /// Kind code, see [`super::object_kind_code`]; 0 is invalid (u32 keeps the layout padding free).
    pub kind: u32,
    /// Footprint centre x in the world frame, m.
    pub x_m: f64,
    /// Footprint centre y in the world frame, m.
    pub y_m: f64,
    /// Heading of the footprint's length axis, rad.
    pub heading_rad: f64,
    /// Velocity x in the world frame, m/s.
    pub vx_mps: f64,
    /// Velocity y in the world frame, m/s.
    pub vy_mps: f64,
    /// Share of the footprint that was visible, in [0, 1].
    pub visible_fraction: f64,
    /// Footprint length, m.
    pub length_m: f32,
    /// Footprint width, m.
    pub width_m: f32,
}

/// A perceived object list with a fixed capacity of [`OBJECT_LIST_CAPACITY`] (4 120 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, ZeroCopySend)]
#[type_name("risktwin.shm.ObjectList.v1")]
pub struct ShmObjectList {
    /// Producer's sequence number, +1 per sample.
    pub seq: u64,
    /// Capture time on the vehicle's own clock, ns.
    pub capture_time_ns: i64,
    /// Number of valid entries at the front of `objects`.
    pub count: u32,
    _reserved: u32,
    /// The objects; entries past `count` are ignored.
    pub objects: [ShmObject; OBJECT_LIST_CAPACITY],
}

impl ShmObject {
    /// An all-zero object (kind 0, so invalid until filled).
    pub const EMPTY: Self = Self {
        id: 0,
        kind: 0,
        x_m: 0.0,
        y_m: 0.0,
        heading_rad: 0.0,
        vx_mps: 0.0,
        vy_mps: 0.0,
        visible_fraction: 0.0,
        length_m: 0.0,
        width_m: 0.0,
    };

    /// Checks the object found at `index` of its list.
    pub fn validate_at(&self, index: usize) -> Result<(), ShmPayloadError> {
        if object_kind_from_code(self.kind).is_none() {
            return Err(ShmPayloadError::UnknownObjectKind { index, code: self.kind });
        }
        let fields = [
            ("x_m", self.x_m),
            ("y_m", self.y_m),
            ("heading_rad", self.heading_rad),
            ("vx_mps", self.vx_mps),
            ("vy_mps", self.vy_mps),
            ("visible_fraction", self.visible_fraction),
            ("length_m", f64::from(self.length_m)),
            ("width_m", f64::from(self.width_m)),
        ];
        for (field, value) in fields {
            if !value.is_finite() {
                return Err(ShmPayloadError::ObjectNotFinite { index, field, value });
            }
        }
        let ranges = [
            ("visible_fraction", self.visible_fraction, 0.0, 1.0),
            ("length_m", f64::from(self.length_m), MIN_EXTENT_M, MAX_EXTENT_M),
            ("width_m", f64::from(self.width_m), MIN_EXTENT_M, MAX_EXTENT_M),
        ];
        for (field, value, min, max) in ranges {
            if !(min..=max).contains(&value) {
                return Err(ShmPayloadError::ObjectOutOfRange { index, field, value, min, max });
            }
        }
        Ok(())
    }
}

impl ShmCanFrame {
    /// A frame with `data` copied in (at most 8 bytes) and the rest zeroed; no range check on the
    /// id (the receiver validates).
    pub fn new(seq: u64, capture_time_ns: i64, can_id: u32, data: &[u8]) -> Result<Self, ShmPayloadError> {
        let mut frame = Self { seq, capture_time_ns, can_id, ..Self::EMPTY };
        frame.set_data(data)?;
        Ok(frame)
    }

    /// Replaces the data bytes (at most 8) and the length code, zeroing the unused tail.
    pub fn set_data(&mut self, data: &[u8]) -> Result<(), ShmPayloadError> {
        let dlc = u8::try_from(data.len())
            .ok()
            .filter(|&dlc| dlc <= 8)
            .ok_or(ShmPayloadError::DlcOutOfRange { dlc: data.len() })?;
        self.data = [0; 8];
        self.data[..data.len()].copy_from_slice(data);
        self.dlc = dlc;
        Ok(())
    }

    /// The valid data bytes (the first `dlc`, clamped to 8).
    pub fn payload(&self) -> &[u8] {
        &self.data[..usize::from(self.dlc).min(8)]
    }
}

impl ShmObjectList {
    /// An empty list with the given header.
    pub const fn new(seq: u64, capture_time_ns: i64) -> Self {
        Self { seq, capture_time_ns, ..Self::EMPTY }
    }

    /// The valid objects (the first `count`, clamped to the capacity).
    pub fn objects(&self) -> &[ShmObject] {
        let count = usize::try_from(self.count).map_or(OBJECT_LIST_CAPACITY, |c| c.min(OBJECT_LIST_CAPACITY));
        &self.objects[..count]
    }

    /// Appends one object; fails when the list is full.
    pub fn push(&mut self, object: ShmObject) -> Result<(), ShmPayloadError> {
        let index = self.objects().len();
        if index >= OBJECT_LIST_CAPACITY {
            return Err(ShmPayloadError::CountOverCapacity {
                count: self.count.saturating_add(1),
                capacity: OBJECT_LIST_CAPACITY,
            });
        }
        self.objects[index] = object;
        self.count = index as u32 + 1;
        Ok(())
    }
}

/// Checks `fields` for NaN/inf.
fn check_finite(fields: &[(&'static str, f64)]) -> Result<(), ShmPayloadError> {
    match fields.iter().find(|(_, value)| !value.is_finite()) {
        Some(&(field, value)) => Err(ShmPayloadError::NotFinite { field, value }),
        None => Ok(()),
    }
}

/// Checks that `value` of `field` lies in `[min, max]`.
fn check_range(field: &'static str, value: f64, min: f64, max: f64) -> Result<(), ShmPayloadError> {
    if (min..=max).contains(&value) { Ok(()) } else { Err(ShmPayloadError::OutOfRange { field, value, min, max }) }
}

impl ShmPayload for ShmVehicleState {
    const STREAM: ShmStream = ShmStream::State;
    const EMPTY: Self = Self {
        seq: 0,
        capture_time_ns: 0,
        x_m: 0.0,
        y_m: 0.0,
        heading_rad: 0.0,
        speed_mps: 0.0,
        accel_mps2: 0.0,
        yaw_rate_radps: 0.0,
        steer_rad: 0.0,
        slip_angle_rad: 0.0,
        length_m: 0.0,
        width_m: 0.0,
    };

    fn seq(&self) -> u64 {
        self.seq
    }

    fn validate(&self) -> Result<(), ShmPayloadError> {
        check_finite(&[
            ("x_m", self.x_m),
            ("y_m", self.y_m),
            ("heading_rad", self.heading_rad),
            ("speed_mps", self.speed_mps),
            ("accel_mps2", self.accel_mps2),
            ("yaw_rate_radps", self.yaw_rate_radps),
            ("steer_rad", self.steer_rad),
            ("slip_angle_rad", self.slip_angle_rad),
            ("length_m", f64::from(self.length_m)),
            ("width_m", f64::from(self.width_m)),
        ])?;
        check_range("speed_mps", self.speed_mps, 0.0, MAX_SPEED_MPS)?;
        check_range("length_m", f64::from(self.length_m), MIN_EXTENT_M, MAX_EXTENT_M)?;
        check_range("width_m", f64::from(self.width_m), MIN_EXTENT_M, MAX_EXTENT_M)
    }
}

impl ShmPayload for ShmCanFrame {
    const STREAM: ShmStream = ShmStream::Can;
    const EMPTY: Self = Self { seq: 0, capture_time_ns: 0, can_id: 0, dlc: 0, data: [0; 8], _reserved: [0; 3] };

    fn seq(&self) -> u64 {
        self.seq
    }

    fn validate(&self) -> Result<(), ShmPayloadError> {
        if self.can_id > MAX_CAN_ID {
            return Err(ShmPayloadError::CanIdOutOfRange { can_id: self.can_id, max: MAX_CAN_ID });
        }
        if self.dlc > 8 {
            return Err(ShmPayloadError::DlcOutOfRange { dlc: usize::from(self.dlc) });
        }
        Ok(())
    }
}

impl ShmPayload for ShmObjectList {
    const STREAM: ShmStream = ShmStream::Objects;
    const EMPTY: Self =
        Self { seq: 0, capture_time_ns: 0, count: 0, _reserved: 0, objects: [ShmObject::EMPTY; OBJECT_LIST_CAPACITY] };

    fn seq(&self) -> u64 {
        self.seq
    }

    fn validate(&self) -> Result<(), ShmPayloadError> {
        if self.count as usize > OBJECT_LIST_CAPACITY {
            return Err(ShmPayloadError::CountOverCapacity { count: self.count, capacity: OBJECT_LIST_CAPACITY });
        }
        self.objects().iter().enumerate().try_for_each(|(index, object)| object.validate_at(index))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_are_fixed_and_padding_free() {
        assert_eq!(size_of::<ShmVehicleState>(), 88);
        assert_eq!(size_of::<ShmCanFrame>(), 32);
        assert_eq!(size_of::<ShmObject>(), 64);
        assert_eq!(size_of::<ShmObjectList>(), 24 + 64 * OBJECT_LIST_CAPACITY);
        assert_eq!(align_of::<ShmObjectList>(), 8);
    }

    #[test]
    fn can_frame_keeps_its_bytes_and_refuses_long_data() {
        let frame = ShmCanFrame::new(3, -5, 0x18FE_F100, &[1, 2, 3]).unwrap();
        assert_eq!(frame.payload(), &[1, 2, 3]);
        assert_eq!(frame.data, [1, 2, 3, 0, 0, 0, 0, 0]);
        assert_eq!(frame.validate(), Ok(()));
        assert_eq!(ShmCanFrame::new(0, 0, 1, &[0; 9]), Err(ShmPayloadError::DlcOutOfRange { dlc: 9 }));
        let mut bad = frame;
        bad.can_id = MAX_CAN_ID + 1;
        assert!(
            matches!(bad.validate(), Err(ShmPayloadError::CanIdOutOfRange { can_id, .. }) if can_id == MAX_CAN_ID + 1)
        );
        bad = frame;
        bad.dlc = 9;
        assert_eq!(bad.validate(), Err(ShmPayloadError::DlcOutOfRange { dlc: 9 }));
    }

    #[test]
    fn state_validation_names_the_bad_field() {
        let mut state = ShmVehicleState { length_m: 4.5, width_m: 1.8, speed_mps: 10.0, ..ShmVehicleState::EMPTY };
        assert_eq!(state.validate(), Ok(()));
        state.yaw_rate_radps = f64::INFINITY;
        assert!(matches!(state.validate(), Err(ShmPayloadError::NotFinite { field: "yaw_rate_radps", .. })));
        state.yaw_rate_radps = 0.0;
        state.speed_mps = -1.0;
        assert!(matches!(state.validate(), Err(ShmPayloadError::OutOfRange { field: "speed_mps", .. })));
        state.speed_mps = 1.0;
        state.width_m = 0.0;
        assert!(matches!(state.validate(), Err(ShmPayloadError::OutOfRange { field: "width_m", .. })));
    }

    #[test]
    fn object_list_checks_count_and_each_valid_object() {
        let object = ShmObject { kind: 1, length_m: 4.0, width_m: 2.0, visible_fraction: 0.4, ..ShmObject::EMPTY };
        let mut list = ShmObjectList::EMPTY;
        for _ in 0..OBJECT_LIST_CAPACITY {
            list.push(object).unwrap();
        }
        assert!(matches!(list.push(object), Err(ShmPayloadError::CountOverCapacity { .. })));
        assert_eq!(list.validate(), Ok(()));
        list.objects[5].vx_mps = f64::NAN;
        assert!(matches!(list.validate(), Err(ShmPayloadError::ObjectNotFinite { index: 5, field: "vx_mps", .. })));
        // Entries past `count` are not data: garbage there is ignored.
        list.count = 5;
        assert_eq!(list.validate(), Ok(()));
        list.objects[2].kind = 9;
        assert_eq!(list.validate(), Err(ShmPayloadError::UnknownObjectKind { index: 2, code: 9 }));
        list.count = 65;
        assert_eq!(list.validate(), Err(ShmPayloadError::CountOverCapacity { count: 65, capacity: 64 }));
        assert_eq!(list.objects().len(), OBJECT_LIST_CAPACITY);
    }
}
