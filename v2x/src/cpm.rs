//! What a roadside unit's Collective Perception Message carries: the object inclusion rules of
//! ETSI TR 103 562 (the analysis of the Collective Perception Service, taken into TS 103 324),
//! as Thandavarayan, Sepulcre and Gozalvez evaluate them ("Generation of Cooperative Perception
//! Messages for Connected and Automated Vehicles", IEEE TVT 2020). Checked every
//! [`T_GEN_CPM_S`]; a perceived object is included when
//!
//! - it is new (never included), or
//! - it moved more than 4 m, its speed changed by more than 0.5 m/s or its heading by more than
//!   4° since it was last included, or
//! - it was last included [`T_GEN_CPM_MAX_S`] ago or more; a pedestrian (a person, a "type B"
//!   object) [`PERSON_INTERVAL_S`] ago or more.
//!
//! A CPM goes out when at least one object is included. The free-space and sensor-information
//! containers, object redundancy mitigation and the look-ahead variant are not modelled.

use super::cam::{HEADING_CHANGE_RAD, POSITION_CHANGE_M, SPEED_CHANGE_MPS, TIME_SLACK_S};
use risktwin_common::sensor::{ObjectKind, PerceivedObject};

/// How often the inclusion is checked, s (T_GenCpm; 10 Hz).
pub const T_GEN_CPM_S: f64 = 0.1;
/// The longest an object goes without being included, s.
pub const T_GEN_CPM_MAX_S: f64 = 1.0;
/// The longest a pedestrian goes without being included, s.
pub const PERSON_INTERVAL_S: f64 = 0.5;

/// What was last sent of an object: when, where, how fast, which way.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Included {
    id: u32,
    time_s: f64,
    x_m: f64,
    y_m: f64,
    speed_mps: f64,
    heading_rad: f64,
}

impl Included {
    fn of(o: &PerceivedObject, time_s: f64) -> Included {
        let (centre, axis) = (o.obb.centre, o.obb.axis);
        let (x_m, y_m, speed_mps) = (centre.x, centre.y, o.velocity.norm());
        Included { id: o.id, time_s, x_m, y_m, speed_mps, heading_rad: axis.y.atan2(axis.x) }
    }

    /// Whether `now` is due for inclusion against this record.
    fn due(&self, now: &Included, kind: ObjectKind) -> bool {
        let interval_s = if kind == ObjectKind::Pedestrian { PERSON_INTERVAL_S } else { T_GEN_CPM_MAX_S };
        let turn = (now.heading_rad - self.heading_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        now.time_s - self.time_s + TIME_SLACK_S >= interval_s
            || (now.x_m - self.x_m).hypot(now.y_m - self.y_m) > POSITION_CHANGE_M
            || (now.speed_mps - self.speed_mps).abs() > SPEED_CHANGE_MPS
            || turn.abs() > HEADING_CHANGE_RAD
    }
}

/// One RSU's CPM generation: what it last included of each object, and when it last checked.
#[derive(Debug, Clone, Default)]
pub struct CpmGenerator {
    included: Vec<Included>,
    next_check_s: f64,
}

impl CpmGenerator {
    /// The objects of `perceived` a CPM made at `now_s` includes, into `out` (cleared first):
    /// none between checks. Objects no longer perceived are forgotten (new when seen again).
    pub fn select(&mut self, now_s: f64, perceived: &[PerceivedObject], out: &mut Vec<PerceivedObject>) {
        out.clear();
        if now_s + TIME_SLACK_S < self.next_check_s {
            return;
        }
        while now_s + TIME_SLACK_S >= self.next_check_s {
            self.next_check_s += T_GEN_CPM_S;
        }
        self.included.retain(|i| perceived.iter().any(|o| o.id == i.id));
        for o in perceived {
            let now = Included::of(o, now_s);
            match self.included.iter_mut().find(|i| i.id == o.id) {
                Some(last) if !last.due(&now, o.kind) => {}
                Some(last) => {
                    *last = now;
                    out.push(*o);
                }
                None => {
                    self.included.push(now);
                    out.push(*o);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::geometry::{Footprint, Obb, Pose, Vec2};

    fn object(id: u32, kind: ObjectKind, x_m: f64, speed_mps: f64, heading_rad: f64) -> PerceivedObject {
        let obb = Obb::new(Pose::new(x_m, 0.0, heading_rad), Footprint::new(4.5, 1.8));
        let velocity = Vec2::new(heading_rad.cos(), heading_rad.sin()) * speed_mps;
        PerceivedObject { id, kind, obb, velocity, visible_fraction: 1.0 }
    }

    /// The ids a generator includes at each 0.05 s step for `world(step)`.
    fn included(steps: u32, world: impl Fn(u32) -> Vec<PerceivedObject>) -> Vec<Vec<u32>> {
        let (mut cpm, mut out) = (CpmGenerator::default(), Vec::new());
        (0..steps)
            .map(|k| {
                cpm.select(f64::from(k) * 0.05, &world(k), &mut out);
                out.iter().map(|o| o.id).collect()
            })
            .collect()
    }

    #[test]
    fn a_standing_car_is_included_new_then_each_second_and_a_pedestrian_each_half_second() {
        let ids = included(41, |_| {
            vec![object(1, ObjectKind::Parked, 0.0, 0.0, 0.0), object(2, ObjectKind::Pedestrian, 5.0, 0.0, 0.0)]
        });
        let when = |id| ids.iter().enumerate().filter(|(_, s)| s.contains(&id)).map(|(k, _)| k).collect::<Vec<_>>();
        assert_eq!(when(1), [0, 20, 40], "new, then every 1 s");
        assert_eq!(when(2), [0, 10, 20, 30, 40], "a person every 0.5 s");
        assert!(ids.iter().skip(1).step_by(2).all(Vec::is_empty), "checked every 0.1 s only");
    }

    #[test]
    fn a_moving_car_is_included_when_it_moved_4_m_or_changed_speed_or_heading() {
        // 30 m/s: 3 m per check, so every second check (6 m > 4 m).
        let fast = included(21, |k| vec![object(1, ObjectKind::Vehicle, 1.5 * f64::from(k), 30.0, 0.0)]);
        let when: Vec<usize> = fast.iter().enumerate().filter(|(_, s)| !s.is_empty()).map(|(k, _)| k).collect();
        assert_eq!(when, [0, 4, 8, 12, 16, 20]);
        // Standing but braking hard: 0.3 m/s per check, included at the second (0.6 > 0.5).
        let braking = included(5, |k| vec![object(1, ObjectKind::Vehicle, 0.0, 10.0 - 3.0 * 0.05 * f64::from(k), 0.0)]);
        assert_eq!(braking[4], [1]);
        assert!(braking[2].is_empty());
        // Turning 3° per check: the second check (6°) includes it, through ±π too.
        let deg = std::f64::consts::PI / 180.0;
        let turning =
            included(5, |k| vec![object(1, ObjectKind::Vehicle, 0.0, 0.0, 179.0 * deg + 1.5 * deg * f64::from(k))]);
        assert!(turning[2].is_empty());
        assert_eq!(turning[4], [1]);
    }

    #[test]
    fn an_object_seen_again_after_it_was_lost_is_new() {
        let ids = included(6, |k| match k {
            2 => vec![],
            _ => vec![object(1, ObjectKind::Parked, 0.0, 0.0, 0.0)],
        });
        assert_eq!(ids, [vec![1], vec![], vec![], vec![], vec![1], vec![]]);
    }
}
