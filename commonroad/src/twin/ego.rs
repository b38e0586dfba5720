//! The recorded ego as the twin drives it closed-loop: its vehicle, driver, sensor and route.
//! One definition, used by [`super::resimulate`] and by a scene's onboard stack (edge::fleet),
//! so that both drive the same ego.

use super::scene::TwinScene;
use risktwin_common::driver::ReferenceDriver;
use risktwin_common::geometry::Vec2;
use risktwin_common::rng::Rng;
use risktwin_common::road::Lane;
use risktwin_common::sensor::{Sensor, SensorParams};
use risktwin_common::vehicle::{ModelKind, Vehicle, VehicleParams};

/// Seed of the recorded ego's sensor noise stream (a recording has no scenario seed).
pub const RECORDING_SEED: u64 = 0;
/// The ego's sensor noise stream, as a generated world's (`World::new`).
const EGO_SENSOR_STREAM: u64 = 0x5E45;

impl TwinScene {
    /// The ego's vehicle parameters: the twin's car with the recorded footprint.
    pub fn ego_params(&self) -> VehicleParams {
        let mut params = VehicleParams::bmw_320i();
        params.length_m = self.ego.footprint.length_m;
        params.width_m = self.ego.footprint.width_m;
        params
    }

    /// The speed the ego's driver wants: the fastest the recorded ego drove (at least 1 m/s).
    pub fn ego_desired_speed_mps(&self) -> f64 {
        self.ego.recorded().iter().map(|s| s.speed_mps).fold(1.0, f64::max)
    }

    /// The ego's single-track vehicle in its recorded initial state.
    pub fn ego_vehicle(&self) -> Vehicle {
        let first = self.ego.recorded()[0];
        Vehicle::new(self.ego_params(), ModelKind::SingleTrack, first.pose, first.speed_mps)
    }

    /// The reference driver that drives the ego.
    pub fn ego_driver(&self) -> ReferenceDriver {
        ReferenceDriver::new(self.ego_desired_speed_mps(), self.ego_params())
    }

    /// The recorded ego path as a lane (the route whose completion is measured, and along which
    /// a scene places its roadside units); a standing ego gets a 1 m stub along its heading.
    pub fn ego_route(&self) -> Lane {
        let mut pts: Vec<Vec2> = Vec::new();
        for s in self.ego.recorded() {
            let p = s.pose.position();
            if pts.last().is_none_or(|q| (p - q).norm() > 0.05) {
                pts.push(p);
            }
        }
        if pts.len() < 2 {
            let s = self.ego.recorded()[0].pose;
            pts = vec![s.position(), s.position() + s.forward()];
        }
        Lane::new(pts, 3.5, 36.0)
    }
}

/// The ego's forward sensor and its noise stream.
pub fn ego_sensor() -> (Sensor, Rng) {
    let sensor =
        Sensor::new(SensorParams::default()).expect("the default sensor parameters are valid (sensor module tests)");
    (sensor, Rng::derive(RECORDING_SEED, EGO_SENSOR_STREAM))
}
