//! A participant's onboard stack: its own sensor (own noise stream) over the truth of each
//! step, and for the ego the driver acting on what it perceived.
//!
//! The ego's stack is built from the same scenario as the authority's world, so its road,
//! vehicle parameters, sensor and sensor noise stream are the world's own: perceiving the
//! truth here consumes the noise exactly as `World::step` would in one process (for a
//! recording, as `resimulate`'s driver does).

use super::wire::Truth;
use super::{Role, SceneError, SceneSetup, SceneSource};
use risktwin_common::driver::{DriverView, Policy};
use risktwin_common::episode::with_reference_driver;
use risktwin_common::geometry::{Footprint, Pose, Vec2};
use risktwin_common::rng::Rng;
use risktwin_common::road::{Lane, Road};
use risktwin_common::sensor::{PerceivedObject, SceneObject, Sensor, SensorParams};
use risktwin_common::telemetry::{DetectedObject, Header, VehicleStateSample};
use risktwin_common::vehicle::Controls;
use risktwin_common::world::EGO_OBJECT_ID;
use risktwin_commonroad::twin::ego_sensor;

/// Noise stream of connected traffic vehicle k's sensor (k = its traffic index).
const AGENT_SENSOR_STREAM: u64 = 0xA6E0_0000;
/// Noise stream of roadside unit k's sensor.
const RSU_SENSOR_STREAM: u64 = 0x25F0_0000;
/// Spacing of roadside units along the ego's route, m, and their mast's offset to its right.
const RSU_SPACING_M: f64 = 150.0;
const RSU_OFFSET_M: f64 = -12.0;

/// What a participant runs onboard.
pub struct Onboard {
    role: Role,
    /// The ego's road and footprint, as its driver sees them.
    road: Road,
    ego_footprint: Footprint,
    driver: Option<Box<dyn Policy + Send>>,
    sensor: Sensor,
    rng: Rng,
    /// A roadside unit's mast.
    mast: Pose,
    objects: Vec<SceneObject>,
    perceived: Vec<PerceivedObject>,
}

/// What every stack of a scene is built from: the ego's road, footprint, driver, sensor and
/// noise stream (the authority's world's own, so that perceiving the truth here consumes the
/// noise as the world would in one process), and the route the roadside units stand along.
struct Basis {
    road: Road,
    ego_footprint: Footprint,
    driver: Box<dyn Policy + Send>,
    sensor: Sensor,
    rng: Rng,
    route: Lane,
    route_start_s_m: f64,
}

impl Basis {
    /// The basis of `setup`'s scenario; the ego's driver is the setup's learned one (acting
    /// through the training environment's mapping at the world's step) or the reference driver.
    fn of(setup: &SceneSetup) -> Basis {
        let learned = |desired_speed_mps: f64, dt_s: f64| {
            setup.ego_driver().map(|d| Box::new(d.model.driver(desired_speed_mps, dt_s)) as Box<dyn Policy + Send>)
        };
        match &setup.source {
            SceneSource::Generated(spec) => {
                let (world, reference) = with_reference_driver(spec);
                Basis {
                    ego_footprint: world.ego.params.footprint(),
                    driver: learned(world.desired_speed_mps, world.dt_s).unwrap_or_else(|| Box::new(reference)),
                    route: world.road.lane(world.route.lane).clone(),
                    route_start_s_m: world.route.start_s_m,
                    road: world.road,
                    sensor: world.sensor,
                    rng: world.sensor_rng,
                }
            }
            // The ego `resimulate` drives: the same driver, sensor and noise stream.
            SceneSource::CommonRoad(recording) => {
                let scene = recording.twin_scene();
                let (sensor, rng) = ego_sensor();
                Basis {
                    road: scene.road.clone(),
                    ego_footprint: scene.ego.footprint,
                    driver: learned(scene.ego_desired_speed_mps(), setup.step_s())
                        .unwrap_or_else(|| Box::new(scene.ego_driver())),
                    sensor,
                    rng,
                    route: scene.ego_route(),
                    route_start_s_m: 0.0,
                }
            }
        }
    }
}

impl Onboard {
    /// The stack of participant `id` of `setup`.
    pub fn new(setup: &SceneSetup, id: &str) -> Result<Onboard, SceneError> {
        let role = setup.role_of(id)?;
        let Basis { road, ego_footprint, driver, sensor, rng, route, route_start_s_m } = Basis::of(setup);
        let seed = setup.seed();
        let around = SensorParams { fov_rad: std::f64::consts::TAU, occlusion: false, ..SensorParams::default() };
        let sensor_of = |params| Sensor::new(params).map_err(|e| SceneError::Failed { reason: e.to_string() });
        let (driver, sensor, rng, mast) = match role {
            Role::Ego => (Some(driver), sensor, rng, Pose::default()),
            Role::Agent { traffic_index } => (
                None,
                sensor_of(SensorParams::default())?,
                Rng::derive(seed, AGENT_SENSOR_STREAM + traffic_index as u64),
                Pose::default(),
            ),
            Role::Rsu { index } => {
                let along = route.pose_at(route_start_s_m + RSU_SPACING_M * f64::from(index), 0.0);
                let (s, c) = along.heading_rad.sin_cos();
                let mast = Pose::new(along.x_m - RSU_OFFSET_M * s, along.y_m + RSU_OFFSET_M * c, along.heading_rad);
                (None, sensor_of(around)?, Rng::derive(seed, RSU_SENSOR_STREAM + u64::from(index)), mast)
            }
        };
        let (objects, perceived) = (Vec::new(), Vec::new());
        Ok(Onboard { role, road, ego_footprint, driver, sensor, rng, mast, objects, perceived })
    }

    /// The participant's role.
    pub fn role(&self) -> Role {
        self.role
    }

    /// Perceives `truth`: where the participant is (`None`: a vehicle that left the world, which
    /// perceives nothing).
    pub fn perceive(&mut self, truth: &Truth) -> Option<Pose> {
        self.objects.clear();
        let pose = match self.role {
            Role::Ego => {
                self.objects.extend(truth.objects.iter().map(SceneObject::from));
                truth.ego_pose()
            }
            Role::Agent { traffic_index } => {
                let id = traffic_index as u32;
                let me = truth.objects.iter().find(|o| o.id == id).map(SceneObject::from);
                self.objects.extend(truth.objects.iter().filter(|o| o.id != id).map(SceneObject::from));
                self.objects.push(truth.ego_object(EGO_OBJECT_ID));
                // A vehicle that left the world (off its lane's end) perceives nothing.
                let Some(me) = me else {
                    self.perceived.clear();
                    return None;
                };
                Pose::new(me.obb.centre.x, me.obb.centre.y, me.obb.axis.y.atan2(me.obb.axis.x))
            }
            Role::Rsu { .. } => {
                self.objects.extend(truth.objects.iter().map(SceneObject::from));
                self.objects.push(truth.ego_object(EGO_OBJECT_ID));
                self.mast
            }
        };
        self.sensor.perceive(pose, &self.objects, &mut self.rng, &mut self.perceived);
        Some(pose)
    }

    /// The ego's driver acts at `pose` (from [`Self::perceive`]) on what it perceived and the
    /// objects it was `warned` of over V2X; `None` from participants that do not drive.
    pub fn act(&mut self, truth: &Truth, pose: Pose, warned: &[PerceivedObject]) -> Option<Controls> {
        let driver = self.driver.as_mut()?;
        let view = DriverView {
            road: &self.road,
            time_s: truth.time_s,
            ego_pose: pose,
            ego_speed_mps: truth.ego.speed_mps,
            ego_accel_mps2: truth.ego.accel_mps2,
            ego_footprint: self.ego_footprint,
            perceived: &self.perceived,
            warned,
        };
        Some(driver.act(&view))
    }

    /// What the sensor perceived in the last step.
    pub fn perceived(&self) -> &[PerceivedObject] {
        &self.perceived
    }

    /// A connected vehicle's own state in `truth`, under `header`; `None` for an RSU, or a
    /// vehicle no longer in the world.
    pub fn own_state(&self, truth: &Truth, header: Header) -> Option<VehicleStateSample> {
        vehicle_state(truth, self.role, header)
    }

    /// A roadside unit's mast pose and sensor range, m.
    pub fn mast(&self) -> (Pose, f64) {
        (self.mast, self.sensor.params().range_m)
    }
}

/// The state of the connected vehicle of `role` in `truth`, under `header`; `None` for an RSU,
/// or a vehicle no longer in the world.
pub fn vehicle_state(truth: &Truth, role: Role, header: Header) -> Option<VehicleStateSample> {
    match role {
        Role::Ego => {
            let e = &truth.ego;
            Some(VehicleStateSample {
                header,
                pose: truth.ego_pose(),
                velocity: Vec2::new(e.velocity[0], e.velocity[1]),
                speed_mps: e.speed_mps,
                accel_mps2: e.accel_mps2,
                yaw_rate_radps: e.yaw_rate_radps,
                steer_rad: e.steer_rad,
                footprint: Footprint::new(e.footprint[0], e.footprint[1]),
            })
        }
        Role::Agent { traffic_index } => {
            let o = DetectedObject::from(truth.objects.iter().find(|o| o.id == traffic_index as u32)?);
            Some(VehicleStateSample {
                header,
                pose: o.pose,
                velocity: o.velocity,
                speed_mps: o.velocity.dot(&o.pose.forward()),
                accel_mps2: o.accel_mps2,
                yaw_rate_radps: 0.0,
                steer_rad: 0.0,
                footprint: o.footprint,
            })
        }
        Role::Rsu { .. } => None,
    }
}
