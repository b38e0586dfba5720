//! The five scenario kinds and their parameter spaces (docs/method.md §2).
//!
//! Ranges are chosen so each space holds both benign corners (the reference driver copes) and
//! critical ones (it collides); the feasibility filter removes physically impossible points.

use serde::{Deserialize, Serialize};
use std::fmt;
use std::str::FromStr;

/// One kind of risky scenario; spelled as in docs/cli.md.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ScenarioKind {
    CutIn,
    EmergencyBraking,
    PedestrianCrossing,
    SensorOcclusion,
    LowFriction,
}

/// A named, bounded scenario parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamDef {
    pub name: &'static str,
    pub min: f64,
    pub max: f64,
    /// What it means, with its unit.
    pub doc: &'static str,
}

const fn p(name: &'static str, min: f64, max: f64, doc: &'static str) -> ParamDef {
    ParamDef { name, min, max, doc }
}

const CUT_IN: &[ParamDef] = &[
    p("ego_speed_mps", 10.0, 35.0, "ego initial and desired speed, m/s"),
    p("relative_speed_mps", -12.0, 4.0, "cutting vehicle speed minus ego speed, m/s"),
    p("longitudinal_gap_m", 2.0, 40.0, "gap from ego front bumper to cutter rear bumper when the cut-in starts, m"),
    p("lateral_gap_m", 2.5, 4.5, "lateral distance between the cutter's and the ego's centre lines at the start, m"),
    p("cut_in_time_s", 0.5, 5.0, "time at which the cutter starts to change lane, s"),
    p("cut_in_duration_s", 1.0, 4.0, "duration of the lateral move, s"),
];

const EMERGENCY_BRAKING: &[ParamDef] = &[
    p("ego_speed_mps", 10.0, 35.0, "ego and lead vehicle initial speed, m/s"),
    p("initial_headway_m", 5.0, 60.0, "gap from ego front bumper to lead rear bumper, m"),
    p("braking_decel_mps2", 2.0, 10.0, "lead vehicle braking deceleration, m/s²"),
    p("brake_time_s", 0.5, 5.0, "time at which the lead vehicle starts braking, s"),
    p("friction_mu", 0.2, 1.0, "road friction coefficient"),
];

const PEDESTRIAN_CROSSING: &[ParamDef] = &[
    p("ego_speed_mps", 5.0, 17.0, "ego initial and desired speed, m/s"),
    p("crossing_distance_m", 15.0, 80.0, "distance from the ego front bumper to the crosswalk at t = 0, m"),
    p("pedestrian_speed_mps", 0.5, 3.0, "walking speed, m/s"),
    p("pedestrian_delay_s", 0.0, 4.0, "time at which the pedestrian steps onto the road, s"),
    p(
        "occlusion_level",
        0.0,
        1.0,
        "share of the kerb before the crosswalk lined with parked vehicles (0 none, 1 three cars)",
    ),
];

const SENSOR_OCCLUSION: &[ParamDef] = &[
    p("ego_speed_mps", 10.0, 30.0, "ego initial and desired speed, m/s"),
    p("occluder_gap_m", 8.0, 30.0, "gap to the lead truck that hides the road ahead, m"),
    p(
        "hidden_obstacle_distance_m",
        30.0,
        150.0,
        "distance from the ego to the stopped vehicle the truck swerves around, m",
    ),
    p("sensor_range_m", 20.0, 150.0, "degraded sensor range, m"),
    p("sensor_fov_deg", 20.0, 120.0, "degraded horizontal field of view, degrees"),
    p("dropout_rate", 0.0, 0.9, "probability that a detection is lost in a frame"),
];

const LOW_FRICTION: &[ParamDef] = &[
    p("friction_mu", 0.1, 1.0, "friction coefficient on the bend and after it"),
    p("curvature_1pm", 0.0, 0.04, "bend curvature (1 / radius), 1/m"),
    p("entry_speed_mps", 5.0, 35.0, "ego speed when entering, m/s"),
    p("lead_gap_m", 10.0, 80.0, "gap to a lead vehicle that brakes on the slippery patch, m"),
    p("lead_decel_mps2", 0.0, 8.0, "lead vehicle braking deceleration, m/s²"),
];

impl ScenarioKind {
    pub const ALL: [ScenarioKind; 5] = [
        ScenarioKind::CutIn,
        ScenarioKind::EmergencyBraking,
        ScenarioKind::PedestrianCrossing,
        ScenarioKind::SensorOcclusion,
        ScenarioKind::LowFriction,
    ];

    /// The kebab-case name used on the command line and in files.
    pub fn name(self) -> &'static str {
        match self {
            ScenarioKind::CutIn => "cut-in",
            ScenarioKind::EmergencyBraking => "emergency-braking",
            ScenarioKind::PedestrianCrossing => "pedestrian-crossing",
            ScenarioKind::SensorOcclusion => "sensor-occlusion",
            ScenarioKind::LowFriction => "low-friction",
        }
    }

    /// The parameter space of this kind, in a fixed order.
    pub fn params(self) -> &'static [ParamDef] {
        match self {
            ScenarioKind::CutIn => CUT_IN,
            ScenarioKind::EmergencyBraking => EMERGENCY_BRAKING,
            ScenarioKind::PedestrianCrossing => PEDESTRIAN_CROSSING,
            ScenarioKind::SensorOcclusion => SENSOR_OCCLUSION,
            ScenarioKind::LowFriction => LOW_FRICTION,
        }
    }

    pub fn param(self, name: &str) -> Option<&'static ParamDef> {
        self.params().iter().find(|d| d.name == name)
    }
}

impl fmt::Display for ScenarioKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown scenario kind name.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "unknown scenario kind '{0}' (expected one of cut-in, emergency-braking, pedestrian-crossing, sensor-occlusion, low-friction)"
)]
pub struct UnknownKind(pub String);

impl FromStr for ScenarioKind {
    type Err = UnknownKind;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        ScenarioKind::ALL.into_iter().find(|k| k.name() == s).ok_or_else(|| UnknownKind(s.to_string()))
    }
}
