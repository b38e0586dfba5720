//! The planner's motion primitives: hold a longitudinal acceleration and follow a lane's
//! centreline (the current one or a neighbour), with the reference driver's own pure pursuit and
//! pedal mapping so that the planner drives the same actuators any policy drives.

use crate::driver::{controls_for_accel, pure_pursuit_steer_rad};
use crate::road::{LaneId, Road};
use crate::vehicle::Controls;
use crate::world::World;

/// Which lane a primitive follows, relative to the lane the plan follows so far.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LaneShift {
    Keep,
    Left,
    Right,
}

/// One primitive: an acceleration demand held for a segment, on a lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Primitive {
    pub accel_mps2: f64,
    pub shift: LaneShift,
}

impl Primitive {
    /// The lane this primitive follows when the plan follows `lane`; `None` where the road has
    /// no neighbour on that side (opposing carriageways are not neighbours, see `road`).
    pub fn lane_from(&self, road: &Road, lane: LaneId) -> Option<LaneId> {
        let l = road.lane(lane);
        match self.shift {
            LaneShift::Keep => Some(lane),
            LaneShift::Left => l.left,
            LaneShift::Right => l.right,
        }
    }

    /// Every acceleration combined with every lane shift.
    pub fn lattice(accels_mps2: &[f64]) -> Vec<Primitive> {
        [LaneShift::Keep, LaneShift::Left, LaneShift::Right]
            .into_iter()
            .flat_map(|shift| accels_mps2.iter().map(move |&accel_mps2| Primitive { accel_mps2, shift }))
            .collect()
    }
}

/// The controls that follow `lane` and ask for `accel_mps2`, except that no more speed is asked
/// for at or above `speed_cap_mps` (the pedals then coast).
pub fn controls(world: &World, lane: LaneId, accel_mps2: f64, speed_cap_mps: f64) -> Controls {
    let ego = &world.ego;
    let speed_mps = ego.state.speed_mps.max(0.0);
    let accel_mps2 = if speed_mps >= speed_cap_mps { accel_mps2.min(0.0) } else { accel_mps2 };
    let steer_rad = pure_pursuit_steer_rad(&world.road, lane, ego.pose(), speed_mps, ego.params.wheelbase_m());
    controls_for_accel(&ego.params, speed_mps, steer_rad, accel_mps2)
}
