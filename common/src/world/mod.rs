//! The twin's world: road, ego vehicle, surrounding traffic, pedestrians and the ego's sensor,
//! advanced together at a fixed step.
//!
//! Order within a step (all from the state at the start of the step, so it is reproducible):
//! perceive → policy acts → ego dynamics → traffic (seeing the ego and pedestrians) → contacts.

mod contact;
mod roadside;
mod samples;
#[cfg(test)]
mod step_study;

pub use contact::Contacts;
pub use roadside::EGO_OBJECT_ID;

use crate::driver::{DriverView, Policy};
use crate::geometry::{Footprint, Obb, Pose, Vec2};
use crate::rng::Rng;
use crate::road::{LaneId, Road};
use crate::scenario::cast;
use crate::sensor::{ObjectKind, PerceivedObject, SceneObject, Sensor};
use crate::traffic::{ExternalAgent, PedestrianWalk, Traffic};
use crate::vehicle::{Controls, Vehicle};

/// The twin's fixed step, s (20 Hz: the ego dynamics sub-step inside it).
pub const STEP_S: f64 = 0.05;

/// Decisions per second of the reference driver and of policies: one per physics step, Hz.
pub const DECISION_RATE_HZ: f64 = 1.0 / STEP_S;

/// The stretch of lane the ego is asked to drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Route {
    pub lane: LaneId,
    pub start_s_m: f64,
    pub length_m: f64,
}

/// A complete twin state.
#[derive(Debug, Clone)]
pub struct World {
    pub road: Road,
    pub ego: Vehicle,
    pub traffic: Traffic,
    pub pedestrians: Vec<PedestrianWalk>,
    pub sensor: Sensor,
    pub route: Route,
    pub desired_speed_mps: f64,
    /// The time gap the ego's driver keeps when the scenario prescribes one (how closely it
    /// follows), s; `None` for the driver's own default.
    pub driver_time_headway_s: Option<f64>,
    pub time_s: f64,
    pub dt_s: f64,
    pub horizon_s: f64,
    /// Noise and dropout of the sensor: a stream of its own so traffic stays reproducible.
    pub sensor_rng: Rng,
    objects: Vec<SceneObject>,
    perceived: Vec<PerceivedObject>,
    external: Vec<ExternalAgent>,
}

/// What one step produced.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepReport {
    pub controls: Controls,
    pub contacts: Contacts,
}

impl World {
    /// A world at t = 0 (scenario builders fill it).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        road: Road,
        ego: Vehicle,
        traffic: Traffic,
        pedestrians: Vec<PedestrianWalk>,
        sensor: Sensor,
        route: Route,
        desired_speed_mps: f64,
        horizon_s: f64,
        seed: u64,
    ) -> Self {
        let mut traffic = traffic;
        // Poses exist only after a step or `prepare`; the first perception needs them.
        traffic.prepare(&road);
        Self {
            road,
            ego,
            traffic,
            pedestrians,
            sensor,
            route,
            desired_speed_mps,
            driver_time_headway_s: None,
            time_s: 0.0,
            dt_s: STEP_S,
            horizon_s,
            sensor_rng: Rng::derive(seed, 0x5E45),
            objects: Vec::new(),
            perceived: Vec::new(),
            external: Vec::new(),
        }
    }

    /// Takes traffic vehicle `i` out of this world before it runs (see [`Traffic::withdraw`]).
    pub fn withdraw_traffic(&mut self, i: usize) {
        self.traffic.withdraw(i);
        self.traffic.prepare(&self.road);
    }

    /// Pedestrian footprint: a square around the body circle, for contact and perception.
    pub fn pedestrian_obb(position: Vec2, velocity: Vec2) -> Obb {
        let heading = if velocity.norm_squared() > 1e-12 { velocity.y.atan2(velocity.x) } else { 0.0 };
        let d = 2.0 * cast::PEDESTRIAN_RADIUS_M;
        Obb::new(Pose::new(position.x, position.y, heading), Footprint::new(d, d))
    }

    /// True state of every object other than the ego, refreshed into the scratch buffer.
    pub fn scene_objects(&mut self) -> &[SceneObject] {
        self.objects.clear();
        for i in (0..self.traffic.len()).filter(|&i| self.traffic.is_active(i)) {
            let kind = if self.traffic.is_parked(i) { ObjectKind::Parked } else { ObjectKind::Vehicle };
            self.objects.push(SceneObject {
                id: i as u32,
                obb: self.traffic.obb(i),
                velocity: self.traffic.velocity(i),
                kind,
            });
        }
        let base = self.traffic.len() as u32;
        for (k, p) in self.pedestrians.iter().enumerate() {
            if let Some(pos) = p.position_at(self.time_s) {
                let vel = p.velocity_at(self.time_s);
                self.objects.push(SceneObject {
                    id: base + k as u32,
                    obb: Self::pedestrian_obb(pos, vel),
                    velocity: vel,
                    kind: ObjectKind::Pedestrian,
                });
            }
        }
        &self.objects
    }

    /// The scene as of the last [`World::step`] or [`World::scene_objects`] refresh.
    pub fn scene(&self) -> &[SceneObject] {
        &self.objects
    }

    /// Progress along the route, m.
    pub fn progress_m(&self) -> f64 {
        self.road.lane(self.route.lane).project(self.ego.pose().position()).s_m - self.route.start_s_m
    }

    /// True when the horizon has passed or the route is done.
    pub fn finished(&self) -> bool {
        self.time_s >= self.horizon_s - 1e-9 || self.progress_m() >= self.route.length_m
    }

    /// Objects the ego perceived in the last step.
    pub fn perceived(&self) -> &[PerceivedObject] {
        &self.perceived
    }

    /// Advances the world by one step with `policy` driving the ego: [`World::perceive`], the
    /// policy acts on [`World::view`], then [`World::advance`].
    pub fn step(&mut self, policy: &mut dyn Policy) -> StepReport {
        self.perceive();
        let controls = policy.act(&self.view());
        self.advance(controls)
    }

    /// The first part of a step: refreshes the scene and lets the ego's sensor perceive it.
    /// A learned policy's environment calls this, observes [`World::view`], and later
    /// [`World::advance`]s with its action, consuming the sensor noise exactly as `step` does.
    pub fn perceive(&mut self) {
        self.scene_objects();
        let ego_pose = self.ego.pose();
        self.sensor.perceive(ego_pose, &self.objects, &mut self.sensor_rng, &mut self.perceived);
    }

    /// What a policy sees after the last [`World::perceive`].
    pub fn view(&self) -> DriverView<'_> {
        DriverView {
            road: &self.road,
            time_s: self.time_s,
            ego_pose: self.ego.pose(),
            ego_speed_mps: self.ego.state.speed_mps,
            ego_accel_mps2: self.ego.state.accel_mps2,
            ego_footprint: self.ego.params.footprint(),
            perceived: &self.perceived,
            warned: &[],
        }
    }

    /// The rest of a step after [`World::perceive`]: the ego applies `controls`, traffic and
    /// pedestrians move, time advances and contacts are detected.
    pub fn advance(&mut self, controls: Controls) -> StepReport {
        let ego_pose = self.ego.pose();
        let mu = self.road.friction_at(ego_pose.position());
        let ego_velocity = self.ego.velocity();
        self.ego.step(controls, mu, self.dt_s);

        self.external.clear();
        self.external.push(ExternalAgent {
            pose: ego_pose,
            velocity: ego_velocity,
            footprint: self.ego.params.footprint(),
        });
        for p in &self.pedestrians {
            if let Some(pos) = p.position_at(self.time_s) {
                let d = 2.0 * cast::PEDESTRIAN_RADIUS_M;
                let vel = p.velocity_at(self.time_s);
                let heading = Self::pedestrian_obb(pos, vel).axis;
                self.external.push(ExternalAgent {
                    pose: Pose::new(pos.x, pos.y, heading.y.atan2(heading.x)),
                    velocity: vel,
                    footprint: Footprint::new(d, d),
                });
            }
        }
        self.traffic.step(&self.road, self.time_s, self.dt_s, &self.external);
        self.time_s += self.dt_s;

        self.scene_objects();
        let contacts = Contacts::detect(&self.ego.obb(), &self.objects, &self.road);
        StepReport { controls, contacts }
    }
}
