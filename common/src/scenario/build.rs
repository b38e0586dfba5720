//! Builds a [`World`] from a validated, feasible spec: the road, the ego, the cast and their
//! manoeuvres, the ego's sensor. Layout constants live in [`super::cast`].

use super::cast::{self, CAR, EGO, EGO_START_S_M, LANE_WIDTH_M, TRUCK};
use super::{ScenarioKind, ScenarioSpec};
use crate::geometry::Footprint;
use crate::road::{LaneId, Road};
use crate::sensor::{Sensor, SensorParams};
use crate::traffic::{IdmParams, Manoeuvre, PedestrianWalk, Traffic, VehicleInit};
use crate::vehicle::{GRAVITY_MPS2, ModelKind, Vehicle, VehicleParams};
use crate::world::{Route, World};

/// Episodes last this long unless their kind needs longer (emergency braking: until the lead
/// has stopped), s.
pub const HORIZON_S: f64 = 15.0;
/// Time the ego may lose against its desired speed and still complete the route, s.
const ROUTE_SLACK_S: f64 = 5.0;

fn car(lane: LaneId, s_m: f64, speed_mps: f64, footprint: Footprint, manoeuvre: Manoeuvre) -> VehicleInit {
    VehicleInit {
        lane,
        s_m,
        d_m: 0.0,
        speed_mps,
        footprint,
        idm: IdmParams { desired_speed_mps: speed_mps.max(1.0), ..IdmParams::default() },
        lane_changes: false,
        manoeuvre,
    }
}

/// Centre position of a vehicle whose rear bumper is `gap_m` ahead of the ego's front bumper.
fn ahead_of_ego(gap_m: f64, footprint: Footprint) -> f64 {
    EGO_START_S_M + 0.5 * EGO.length_m + gap_m + 0.5 * footprint.length_m
}

/// The world a spec describes. The spec must have passed [`super::check_feasible`].
pub fn build(spec: &ScenarioSpec) -> World {
    let p = |n: &str| spec.get(n);
    let mut traffic = Traffic::new();
    let mut pedestrians = Vec::new();
    // An automated vehicle perceives all around (lidar + surround radar); only the occlusion
    // kind degrades range and field of view.
    let mut sensor_params = SensorParams { fov_rad: std::f64::consts::TAU, ..SensorParams::default() };
    let mut horizon_s = HORIZON_S;
    let mut driver_time_headway_s = None;
    let mut route_end_s: Option<f64> = None;
    let (road, ego_lane, ego_speed) = match spec.kind {
        ScenarioKind::CutIn => {
            let v = p("ego_speed_mps");
            let v_cut = v + p("relative_speed_mps");
            let t_cut = p("cut_in_time_s");
            // Gap at t = 0 such that constant speeds give `longitudinal_gap_m` at the cut-in.
            let gap0 = p("longitudinal_gap_m") - p("relative_speed_mps") * t_cut;
            let road = Road::straight(3, LANE_WIDTH_M, EGO_START_S_M + 40.0 * HORIZON_S + 300.0, 36.0);
            let mut cutter = car(
                2,
                ahead_of_ego(gap0, CAR),
                v_cut,
                CAR,
                Manoeuvre::CutIn { start_time_s: t_cut, duration_s: p("cut_in_duration_s"), target_lane: 1 },
            );
            cutter.d_m = p("lateral_gap_m") - LANE_WIDTH_M;
            traffic.add(cutter);
            traffic.add(car(0, ahead_of_ego(30.0, CAR), 0.9 * v, CAR, Manoeuvre::None));
            (road, 1, v)
        }
        ScenarioKind::EmergencyBraking => {
            let (v, mu, t_brake) = (p("ego_speed_mps"), p("friction_mu"), p("brake_time_s"));
            let mut road = Road::straight(2, LANE_WIDTH_M, EGO_START_S_M + 40.0 * 30.0 + 300.0, 36.0);
            road.friction_default = mu;
            let s_lead = ahead_of_ego(p("initial_headway_m"), CAR);
            let decel = p("braking_decel_mps2");
            traffic.add(car(0, s_lead, v, CAR, Manoeuvre::Brake { start_time_s: t_brake, decel_mps2: decel }));
            // A steady column in the other lane: the ego cannot escape sideways, it must brake.
            for k in 0..6 {
                traffic.add(car(1, EGO_START_S_M - 50.0 + 22.0 * k as f64, v, CAR, Manoeuvre::None));
            }
            // The route ends where a safe stop behind the stopped lead lies, and the episode
            // lasts until well after the lead has stopped.
            let a_lead = decel.min(mu * GRAVITY_MPS2);
            let s_stop = s_lead + v * t_brake + v * v / (2.0 * a_lead);
            route_end_s = Some(s_stop - 0.5 * CAR.length_m - 0.5 * EGO.length_m - 4.0);
            horizon_s = t_brake + v / a_lead + 8.0;
            // The initial headway is how closely this ego follows: its driver keeps it as its
            // IDM equilibrium gap, s0 + v·T (T clamped to 0.3–1.6 s), instead of braking away.
            let s0 = IdmParams::default().min_gap_m;
            driver_time_headway_s = Some(((p("initial_headway_m") - s0) / v).clamp(0.3, 1.6));
            (road, 0, v)
        }
        ScenarioKind::PedestrianCrossing => {
            let v = p("ego_speed_mps");
            let crosswalk_x = EGO_START_S_M + 0.5 * EGO.length_m + p("crossing_distance_m");
            let road = Road::crossing(LANE_WIDTH_M, crosswalk_x + 250.0, crosswalk_x + 80.0, crosswalk_x, 13.9);
            let cw = road.crosswalks[0];
            // Parked cars line the right lane up to 1 m before the crosswalk strip.
            for k in 0..cast::parked_count(p("occlusion_level")) {
                let s = crosswalk_x - 0.5 * cw.width_m - 1.0 - 0.5 * CAR.length_m - k as f64 * cast::PARKED_SPACING_M;
                traffic.add(car(0, s, 0.0, CAR, Manoeuvre::Parked));
            }
            pedestrians.push(PedestrianWalk {
                start: cw.start,
                heading_rad: cw.heading_rad,
                speed_mps: p("pedestrian_speed_mps"),
                start_time_s: p("pedestrian_delay_s"),
                path_length_m: cw.length_m,
                radius_m: cast::PEDESTRIAN_RADIUS_M,
            });
            (road, 1, v)
        }
        ScenarioKind::SensorOcclusion => {
            let v = p("ego_speed_mps");
            let road = Road::straight(2, LANE_WIDTH_M, EGO_START_S_M + 40.0 * HORIZON_S + 300.0, 36.0);
            // The truck swerves late, holding its speed: 1.6 s before it would reach the stopped
            // car, the half-cosine move over 2 s has carried it clear of the car (≥ 2.2 m
            // lateral) when its front gets there.
            let swerve = Manoeuvre::Swerve { trigger_gap_m: 1.6 * v + 5.0, duration_s: 2.0, target_lane: 1 };
            traffic.add(car(0, ahead_of_ego(p("occluder_gap_m"), TRUCK), v, TRUCK, swerve));
            traffic.add(car(0, EGO_START_S_M + p("hidden_obstacle_distance_m"), 0.0, CAR, Manoeuvre::Parked));
            sensor_params.range_m = p("sensor_range_m");
            sensor_params.fov_rad = p("sensor_fov_deg").to_radians();
            sensor_params.dropout_rate = p("dropout_rate");
            (road, 0, v)
        }
        ScenarioKind::LowFriction => {
            let v = p("entry_speed_mps");
            let (kappa, mu) = (p("curvature_1pm"), p("friction_mu"));
            let lead_in_m = 80.0;
            let road = if kappa < 1e-4 {
                Road::straight(2, LANE_WIDTH_M, 600.0, 36.0)
            } else {
                let angle = (150.0 * kappa).min(std::f64::consts::FRAC_PI_2);
                Road::curved(2, LANE_WIDTH_M, lead_in_m, 1.0 / kappa, angle, 300.0, 36.0)
            }
            .with_friction_patch(60.0, 1e6, mu);
            // The lead drives the bend at a speed the slippery road allows (half of μ·g).
            let v_lead = if kappa < 1e-4 { v } else { v.min((0.5 * mu * GRAVITY_MPS2 / kappa).sqrt()) };
            let s_lead = ahead_of_ego(p("lead_gap_m"), CAR);
            let manoeuvre = if p("lead_decel_mps2") < 0.1 {
                Manoeuvre::None
            } else {
                let t = ((lead_in_m - s_lead) / v_lead.max(1.0)).max(0.5);
                Manoeuvre::Brake { start_time_s: t, decel_mps2: p("lead_decel_mps2") }
            };
            traffic.add(car(0, s_lead, v_lead, CAR, manoeuvre));
            (road, 0, v)
        }
    };
    let start = road.lane(ego_lane).pose_at(EGO_START_S_M, 0.0);
    let ego = Vehicle::new(VehicleParams::bmw_320i(), ModelKind::SingleTrack, start, ego_speed);
    let length_m = match route_end_s {
        Some(end) => (end - EGO_START_S_M).max(1.0),
        None => ego_speed.max(5.0) * (horizon_s - ROUTE_SLACK_S),
    };
    let route = Route { lane: ego_lane, start_s_m: EGO_START_S_M, length_m };
    let mut world = World::new(
        road,
        ego,
        traffic,
        pedestrians,
        Sensor::new(sensor_params).expect("scenario parameter ranges lie inside the sensor model's valid ranges"),
        route,
        ego_speed,
        horizon_s,
        spec.seed,
    );
    world.driver_time_headway_s = driver_time_headway_s;
    world
}
