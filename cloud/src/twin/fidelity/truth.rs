//! A site's ground truth as its scene's authority publishes it, and the truth twin: the same
//! [`SiteTwin`] the cloud builds from the edges' streams, built instead from the truth at the
//! tick's time, so that one risk code runs on both and every difference is the twin's.

use super::super::{SiteTwin, TwinObject, TwinVehicle};
use crate::ingest::ObservedKinematics;
use crate::twin::risk::SELF_RADIUS_M;
use risktwin_align::{Interpolate, lerp_angle};
use risktwin_common::geometry::Pose;
use risktwin_common::telemetry::{DetectedObject, VehicleStateSample};
use std::collections::{BTreeMap, VecDeque};
use std::sync::Arc;

/// Truth samples kept per vehicle and object lists kept per site: 10 s at 20 Hz, far more than
/// a tick lags behind the truth.
const KEPT_SAMPLES: usize = 200;

/// The truth of one site: connected vehicles' states and every other object, oldest first.
#[derive(Debug, Default)]
pub(super) struct SiteTruth {
    vehicles: BTreeMap<Arc<str>, VecDeque<(i64, VehicleStateSample)>>,
    objects: VecDeque<(i64, Vec<DetectedObject>)>,
    observer: Option<Arc<str>>,
}

/// Appends `(t, value)` if it is newer than the last sample (out-of-order truth cannot be
/// interpolated against; the authority sends in order), dropping the oldest beyond the cap.
fn push_in_order<T>(samples: &mut VecDeque<(i64, T)>, t: i64, value: T) {
    if samples.back().is_some_and(|&(last, _)| last >= t) {
        return;
    }
    if samples.len() == KEPT_SAMPLES {
        samples.pop_front();
    }
    samples.push_back((t, value));
}

/// A sample stamped with its time, ns.
type Stamped<T> = (i64, T);

/// The samples around `t`: `(earlier, later, fraction)`, or the one sample at exactly `t`;
/// `None` outside them (no extrapolation).
fn bracket<T>(samples: &VecDeque<Stamped<T>>, t: i64) -> Option<(&Stamped<T>, &Stamped<T>, f64)> {
    let after = samples.iter().position(|&(ts, _)| ts >= t)?;
    let later = &samples[after];
    if later.0 == t {
        return Some((later, later, 0.0));
    }
    let earlier = samples.get(after.checked_sub(1)?)?;
    Some((earlier, later, (t - earlier.0) as f64 / (later.0 - earlier.0) as f64))
}

impl SiteTruth {
    pub(super) fn push_vehicle(&mut self, source: &str, sample: &VehicleStateSample) {
        let samples = match self.vehicles.get_mut(source) {
            Some(s) => s,
            None => self.vehicles.entry(Arc::from(source)).or_default(),
        };
        push_in_order(samples, sample.header.capture_time_ns, sample.clone());
    }

    pub(super) fn push_objects(&mut self, time_ns: i64, objects: Vec<DetectedObject>) {
        push_in_order(&mut self.objects, time_ns, objects);
    }

    /// Vehicle `source` at `t_ns`. Jerk is the acceleration's change between the two samples
    /// and lateral acceleration the yaw rate times the speed (what the twin derives from its
    /// ticks, here from the truth's own states).
    fn vehicle_at(&self, source: &str, t_ns: i64) -> Option<TwinVehicle> {
        let (source, samples) = self.vehicles.get_key_value(source)?;
        let ((t0, a), (t1, b), f) = bracket(samples, t_ns)?;
        let (ka, kb) = (ObservedKinematics::from(a), ObservedKinematics::from(b));
        let kinematics = ObservedKinematics::lerp(&ka, &kb, f);
        let jerk_mps3 = if t1 > t0 { (kb.accel_mps2 - ka.accel_mps2) / ((t1 - t0) as f64 * 1e-9) } else { 0.0 };
        let yaw_rate = a.yaw_rate_radps + (b.yaw_rate_radps - a.yaw_rate_radps) * f;
        Some(TwinVehicle {
            source: Arc::clone(source),
            kinematics,
            jerk_mps3,
            lateral_accel_mps2: yaw_rate * kinematics.speed_mps,
        })
    }

    /// Fills `out` with the truth at `t_ns`: every connected vehicle whose truth brackets the
    /// tick, and every other object (by truth id, interpolated between the two lists around
    /// the tick; connected vehicles, which the object list also holds, only once). `false`
    /// when no vehicle's truth brackets the tick.
    pub(super) fn twin_at(&mut self, t_ns: i64, out: &mut SiteTwin) -> bool {
        out.vehicles.clear();
        out.objects.clear();
        for source in self.vehicles.keys() {
            if let Some(v) = self.vehicle_at(source, t_ns) {
                out.vehicles.push(v);
            }
        }
        if out.vehicles.is_empty() {
            return false;
        }
        let observer = Arc::clone(self.observer.get_or_insert_with(|| Arc::from("truth")));
        let Some(((_, before), (_, after), f)) = bracket(&self.objects, t_ns) else { return true };
        for o in after {
            let object = match before.iter().find(|p| p.id == o.id) {
                Some(p) => lerp_object(p, o, f),
                None => *o,
            };
            let centre = object.pose.position();
            let connected = out.vehicles.iter().any(|v| (v.kinematics.pose.position() - centre).norm() < SELF_RADIUS_M);
            if !connected {
                out.objects.push(TwinObject { observer: Arc::clone(&observer), object });
            }
        }
        true
    }
}

fn lerp_object(a: &DetectedObject, b: &DetectedObject, f: f64) -> DetectedObject {
    let l = |x: f64, y: f64| x + (y - x) * f;
    DetectedObject {
        pose: Pose::new(
            l(a.pose.x_m, b.pose.x_m),
            l(a.pose.y_m, b.pose.y_m),
            lerp_angle(a.pose.heading_rad, b.pose.heading_rad, f),
        ),
        velocity: a.velocity + (b.velocity - a.velocity) * f,
        accel_mps2: l(a.accel_mps2, b.accel_mps2),
        ..*b
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::geometry::{Footprint, Vec2};
    use risktwin_common::sensor::ObjectKind;
    use risktwin_common::telemetry::{Frame, Header};

    fn state(t_ns: i64, x: f64, accel: f64) -> VehicleStateSample {
        let header =
            Header { source: "v0".into(), seq: 0, capture_time_ns: t_ns, publish_time_ns: t_ns, frame: Frame::World };
        VehicleStateSample {
            header,
            pose: Pose::new(x, 0.0, 0.0),
            velocity: Vec2::new(10.0, 0.0),
            speed_mps: 10.0,
            accel_mps2: accel,
            yaw_rate_radps: 0.1,
            steer_rad: 0.0,
            footprint: Footprint::new(4.5, 1.8),
        }
    }

    fn object(id: u32, x: f64) -> DetectedObject {
        DetectedObject {
            id,
            kind: ObjectKind::Vehicle,
            pose: Pose::new(x, 3.5, 0.0),
            footprint: Footprint::new(4.5, 1.8),
            velocity: Vec2::new(5.0, 0.0),
            accel_mps2: 0.0,
        }
    }

    #[test]
    fn the_truth_twin_interpolates_vehicles_and_objects_at_the_tick() {
        let mut truth = SiteTruth::default();
        truth.push_vehicle("v0", &state(0, 0.0, 0.0));
        truth.push_vehicle("v0", &state(100, 10.0, 1.0));
        truth.push_vehicle("v0", &state(50, 99.0, 0.0)); // out of order: ignored
        truth.push_objects(0, vec![object(7, 20.0), object(8, 40.0)]);
        truth.push_objects(100, vec![object(7, 30.0), object(9, 60.0)]);
        let mut twin = SiteTwin::default();
        assert!(truth.twin_at(25, &mut twin));
        assert_eq!(twin.vehicles[0].kinematics.pose.position(), Vec2::new(2.5, 0.0));
        assert!(!truth.twin_at(101, &mut twin), "no extrapolation");
        assert!(truth.twin_at(50, &mut twin));
        assert_eq!(twin.vehicles.len(), 1);
        let v = &twin.vehicles[0];
        assert!((v.kinematics.pose.x_m - 5.0).abs() < 1e-12);
        assert!((v.jerk_mps3 - 1.0 / 100e-9).abs() < 1e-3, "accel change over the samples: {}", v.jerk_mps3);
        assert!((v.lateral_accel_mps2 - 1.0).abs() < 1e-12);
        let xs: Vec<(u32, f64)> = twin.objects.iter().map(|o| (o.object.id, o.object.pose.x_m)).collect();
        assert_eq!(xs, [(7, 25.0), (9, 60.0)], "7 interpolated, 9 only in the later list, 8 gone");
        assert!(!truth.twin_at(200, &mut twin), "no truth after the last sample");
    }

    #[test]
    fn a_connected_vehicle_in_the_object_list_is_not_counted_twice() {
        let mut truth = SiteTruth::default();
        truth.push_vehicle("v1", &state(0, 20.0, 0.0));
        let mut cutter = object(3, 20.0);
        cutter.pose = Pose::new(20.0, 0.0, 0.0);
        truth.push_objects(0, vec![cutter, object(4, 50.0)]);
        let mut twin = SiteTwin::default();
        assert!(truth.twin_at(0, &mut twin));
        assert_eq!(twin.objects.iter().map(|o| o.object.id).collect::<Vec<_>>(), [4]);
    }
}
