//! Kinematic playback of a recorded obstacle: its state at any time of its recording.

use super::super::{DynamicObstacle, ObstacleState, Shape};
use risktwin_common::geometry::{Footprint, Obb, Pose, Vec2, wrap_angle};
use risktwin_common::sensor::ObjectKind;

/// An obstacle's state at one moment of playback.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaybackState {
    /// Shape centre and orientation.
    pub pose: Pose,
    /// Speed along the orientation, m/s (CommonRoad's scalar velocity).
    pub speed_mps: f64,
    /// Acceleration along the orientation, m/s².
    pub accel_mps2: f64,
}

impl PlaybackState {
    /// Velocity in the world frame.
    pub fn velocity(&self) -> Vec2 {
        self.pose.forward() * self.speed_mps
    }
}

/// The twin's rectangle for a CommonRoad shape: the rectangle itself, the square around a
/// circle, the axis-aligned box (in the obstacle frame) around a polygon.
pub fn footprint_of(shape: &Shape) -> Footprint {
    match shape {
        Shape::Rectangle { length_m, width_m } => Footprint::new(*length_m, *width_m),
        Shape::Circle { radius_m } => Footprint::new(2.0 * radius_m, 2.0 * radius_m),
        Shape::Polygon { vertices } => {
            let x = vertices.iter().map(|v| v.x.abs()).fold(0.0, f64::max);
            let y = vertices.iter().map(|v| v.y.abs()).fold(0.0, f64::max);
            Footprint::new(2.0 * x, 2.0 * y)
        }
    }
}

/// What the twin's sensor and drivers take an obstacle type for.
pub fn kind_of(obstacle_type: &str) -> ObjectKind {
    match obstacle_type {
        "pedestrian" | "bicycle" => ObjectKind::Pedestrian,
        "parkedVehicle" | "constructionZone" | "roadBoundary" | "building" | "pillar" | "median_strip" => {
            ObjectKind::Parked
        }
        _ => ObjectKind::Vehicle,
    }
}

/// One obstacle's recording, played back at any time in `[start_s, end_s]`.
#[derive(Debug, Clone)]
pub struct Playback {
    pub id: u64,
    pub kind: ObjectKind,
    pub footprint: Footprint,
    dt_s: f64,
    first_step: i64,
    /// Per recorded step: centre, heading, speed, acceleration (missing values filled from
    /// finite differences of the positions and speeds).
    states: Vec<PlaybackState>,
}

impl Playback {
    /// The playback of `obstacle` in a scenario with step `dt_s` (> 0).
    pub fn new(obstacle: &DynamicObstacle, dt_s: f64) -> Self {
        let recorded: Vec<&ObstacleState> = obstacle.states().collect();
        let n = recorded.len();
        let pos = |k: usize| recorded[k.min(n - 1)].position;
        let mut states: Vec<PlaybackState> = recorded
            .iter()
            .enumerate()
            .map(|(k, s)| {
                // Central differences inside, one-sided at the ends (np.gradient, as CriMe).
                let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                let span = (b - a) as f64 * dt_s;
                let fd_speed = if span > 0.0 { (pos(b) - pos(a)).norm() / span } else { 0.0 };
                PlaybackState {
                    pose: Pose::new(s.position.x, s.position.y, s.orientation_rad),
                    speed_mps: s.velocity_mps.unwrap_or(fd_speed),
                    accel_mps2: s.acceleration_mps2.unwrap_or(f64::NAN),
                }
            })
            .collect();
        for k in 0..n {
            if states[k].accel_mps2.is_nan() {
                let (a, b) = (k.saturating_sub(1), (k + 1).min(n - 1));
                let span = (b - a) as f64 * dt_s;
                states[k].accel_mps2 =
                    if span > 0.0 { (states[b].speed_mps - states[a].speed_mps) / span } else { 0.0 };
            }
        }
        Self {
            id: obstacle.id,
            kind: kind_of(&obstacle.obstacle_type),
            footprint: footprint_of(&obstacle.shape),
            dt_s,
            first_step: obstacle.first_time_step(),
            states,
        }
    }

    /// Time of the first recorded state, s.
    pub fn start_s(&self) -> f64 {
        self.first_step as f64 * self.dt_s
    }

    /// Time of the last recorded state, s.
    pub fn end_s(&self) -> f64 {
        (self.first_step + self.states.len() as i64 - 1) as f64 * self.dt_s
    }

    /// The recorded states, one per step from [`Playback::start_s`].
    pub fn recorded(&self) -> &[PlaybackState] {
        &self.states
    }

    /// The state at `time_s`, interpolated between the two recorded steps around it; `None`
    /// outside the recording (1 µs of slack for float round-off at the ends).
    pub fn at(&self, time_s: f64) -> Option<PlaybackState> {
        let u = (time_s - self.start_s()) / self.dt_s;
        let last = (self.states.len() - 1) as f64;
        let slack = 1e-6 / self.dt_s;
        if !(u >= -slack && u <= last + slack) {
            return None;
        }
        let u = u.clamp(0.0, last);
        let k = (u.floor() as usize).min(self.states.len() - 1);
        let f = u - k as f64;
        let a = &self.states[k];
        let Some(b) = self.states.get(k + 1).filter(|_| f > 1e-12) else {
            return Some(*a);
        };
        let lerp = |x: f64, y: f64| x + f * (y - x);
        let heading = wrap_angle(a.pose.heading_rad + f * wrap_angle(b.pose.heading_rad - a.pose.heading_rad));
        Some(PlaybackState {
            pose: Pose::new(lerp(a.pose.x_m, b.pose.x_m), lerp(a.pose.y_m, b.pose.y_m), heading),
            speed_mps: lerp(a.speed_mps, b.speed_mps),
            accel_mps2: lerp(a.accel_mps2, b.accel_mps2),
        })
    }

    /// The footprint at a playback state.
    pub fn obb(&self, state: &PlaybackState) -> Obb {
        Obb::new(state.pose, self.footprint)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn obstacle() -> DynamicObstacle {
        let st = |t: i64, x: f64, h: f64| ObstacleState {
            time_step: t,
            position: Vec2::new(x, 0.0),
            orientation_rad: h,
            velocity_mps: None,
            acceleration_mps2: None,
        };
        DynamicObstacle {
            id: 7,
            obstacle_type: "car".into(),
            shape: Shape::Rectangle { length_m: 4.0, width_m: 2.0 },
            initial_state: st(2, 0.0, 3.1),
            trajectory: vec![st(3, 1.0, -3.1), st(4, 3.0, -3.1)],
            occupancy_set: Vec::new(),
        }
    }

    #[test]
    fn interpolates_between_steps_and_fills_speeds() {
        let p = Playback::new(&obstacle(), 0.1);
        assert!((p.start_s() - 0.2).abs() < 1e-12 && (p.end_s() - 0.4).abs() < 1e-12);
        assert!(p.at(0.19).is_none() && p.at(0.41).is_none());
        let s = p.at(0.25).expect("inside");
        assert!((s.pose.x_m - 0.5).abs() < 1e-9);
        // Heading across ±π takes the short way: halfway between 3.1 and −3.1 is π.
        assert!((s.pose.heading_rad.abs() - std::f64::consts::PI).abs() < 1e-9);
        // Speeds from positions: 10 m/s forward at the start, central 15, 20 at the end.
        let v: Vec<f64> = p.recorded().iter().map(|s| s.speed_mps).collect();
        assert!((v[0] - 10.0).abs() < 1e-9 && (v[1] - 15.0).abs() < 1e-9 && (v[2] - 20.0).abs() < 1e-9);
        assert!((p.recorded()[1].accel_mps2 - 50.0).abs() < 1e-9);
        assert_eq!(p.at(0.4).map(|s| s.pose.x_m), Some(3.0));
    }
}
