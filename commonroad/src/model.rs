//! The typed CommonRoad scenario: what [`super::parse_scenario`] returns.
//!
//! Field names follow the CommonRoad 2020a format documentation (Althoff et al., "CommonRoad:
//! Composable benchmarks for motion planning on roads", and `documentation/XML_commonRoad_2020a.pdf`
//! of commonroad-io) with SI units in the names. Time is an integer step; `dt_s` converts it.

use crate::LaneletNetwork;
use risktwin_common::geometry::Vec2;
use std::collections::HashMap;

/// One CommonRoad scenario: road network, obstacles and planning problems.
#[derive(Debug, Clone, PartialEq)]
pub struct Scenario {
    /// `benchmarkID` (e.g. `OSC_CutIn-1_2_T-1`); empty when absent.
    pub benchmark_id: String,
    /// `commonRoadVersion` (`2020a`, or `2018b` for the older obstacle layout).
    pub version: String,
    /// Time-step size, s.
    pub dt_s: f64,
    /// `<scenarioTags>` children, as written (`interstate`, `intersection`, ...).
    pub tags: Vec<String>,
    pub lanelets: LaneletNetwork,
    /// Dynamic obstacles in file order.
    pub dynamic_obstacles: Vec<DynamicObstacle>,
    /// Static obstacles in file order.
    pub static_obstacles: Vec<StaticObstacle>,
    pub planning_problems: Vec<PlanningProblem>,
    pub intersections: Vec<Intersection>,
    /// Dynamic obstacle id → index into `dynamic_obstacles`.
    pub(crate) dynamic_index: HashMap<u64, usize>,
}

impl Scenario {
    /// A scenario from its parts (e.g. rebuilt from a recording), with no tags, planning
    /// problems or intersections; a dynamic obstacle id may appear once only.
    pub fn from_parts(
        benchmark_id: String,
        dt_s: f64,
        lanelets: LaneletNetwork,
        dynamic_obstacles: Vec<DynamicObstacle>,
        static_obstacles: Vec<StaticObstacle>,
    ) -> Result<Self, super::CommonRoadError> {
        let mut dynamic_index = HashMap::with_capacity(dynamic_obstacles.len());
        for (i, o) in dynamic_obstacles.iter().enumerate() {
            if dynamic_index.insert(o.id, i).is_some() {
                return Err(super::CommonRoadError::DuplicateObstacle { id: o.id });
            }
        }
        Ok(Self {
            benchmark_id,
            version: "2020a".to_string(),
            dt_s,
            tags: Vec::new(),
            lanelets,
            dynamic_obstacles,
            static_obstacles,
            planning_problems: Vec::new(),
            intersections: Vec::new(),
            dynamic_index,
        })
    }

    /// The dynamic obstacle with this id.
    pub fn dynamic_obstacle(&self, id: u64) -> Option<&DynamicObstacle> {
        self.dynamic_index.get(&id).map(|&i| &self.dynamic_obstacles[i])
    }

    /// True when `<scenarioTags>` holds `tag` (case-insensitive).
    pub fn has_tag(&self, tag: &str) -> bool {
        self.tags.iter().any(|t| t.eq_ignore_ascii_case(tag))
    }

    /// The ego by docs/cli.md's default: the dynamic obstacle whose id is a planning problem's id,
    /// else the first dynamic obstacle in the file; `None` when there is no dynamic obstacle.
    pub fn default_ego_id(&self) -> Option<u64> {
        self.planning_problems
            .iter()
            .map(|p| p.id)
            .find(|id| self.dynamic_index.contains_key(id))
            .or_else(|| self.dynamic_obstacles.first().map(|o| o.id))
    }
}

/// A state of an obstacle at one time step. Velocity and acceleration are scalar and along the
/// orientation, as CommonRoad stores them; absent when the file does not give them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObstacleState {
    pub time_step: i64,
    /// Centre of the shape, world frame, m.
    pub position: Vec2,
    pub orientation_rad: f64,
    pub velocity_mps: Option<f64>,
    pub acceleration_mps2: Option<f64>,
}

/// An obstacle's outline, centred on its state position and turned by its orientation.
#[derive(Debug, Clone, PartialEq)]
pub enum Shape {
    /// `length_m` along the orientation.
    Rectangle {
        length_m: f64,
        width_m: f64,
    },
    Circle {
        radius_m: f64,
    },
    /// Vertices in the obstacle's frame (for static obstacles, usually the world frame).
    Polygon {
        vertices: Vec<Vec2>,
    },
}

impl Shape {
    /// Half of the extent along the heading: ℓ/2 for a rectangle, r for a circle, the largest
    /// |x| for a polygon.
    pub fn half_length_m(&self) -> f64 {
        match self {
            Shape::Rectangle { length_m, .. } => 0.5 * length_m,
            Shape::Circle { radius_m } => *radius_m,
            Shape::Polygon { vertices } => vertices.iter().map(|v| v.x.abs()).fold(0.0, f64::max),
        }
    }
}

/// Obstacle role as in the `<type>` element (`car`, `truck`, `pedestrian`, `parkedVehicle`, ...).
pub type ObstacleType = String;

/// One occupancy of a set-based prediction: the region covered during `[time_start, time_end]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Occupancy {
    pub time_start: i64,
    pub time_end: i64,
    /// The covered region, world frame (polygons as written; rectangles and circles with their
    /// centre and orientation).
    pub shapes: Vec<PlacedShape>,
}

/// A shape at a place: what occupancies and goal regions are made of.
#[derive(Debug, Clone, PartialEq)]
pub struct PlacedShape {
    pub shape: Shape,
    pub centre: Vec2,
    pub orientation_rad: f64,
}

/// A moving obstacle with its recorded trajectory (or a set-based prediction).
#[derive(Debug, Clone, PartialEq)]
pub struct DynamicObstacle {
    pub id: u64,
    pub obstacle_type: ObstacleType,
    pub shape: Shape,
    pub initial_state: ObstacleState,
    /// Trajectory states after the initial one, one per consecutive time step.
    pub trajectory: Vec<ObstacleState>,
    /// Set-based prediction (`<occupancySet>`), when the file gives one instead of a trajectory.
    pub occupancy_set: Vec<Occupancy>,
}

impl DynamicObstacle {
    /// First time step with a state.
    pub fn first_time_step(&self) -> i64 {
        self.initial_state.time_step
    }

    /// Last time step with a state.
    pub fn last_time_step(&self) -> i64 {
        self.trajectory.last().map_or(self.initial_state.time_step, |s| s.time_step)
    }

    /// The state at `time_step`, if the obstacle has one (states are consecutive, checked on
    /// import).
    pub fn state_at(&self, time_step: i64) -> Option<&ObstacleState> {
        let k = time_step.checked_sub(self.initial_state.time_step)?;
        match k {
            0 => Some(&self.initial_state),
            k if k > 0 => self.trajectory.get(usize::try_from(k - 1).ok()?),
            _ => None,
        }
    }

    /// All states, initial first.
    pub fn states(&self) -> impl Iterator<Item = &ObstacleState> {
        std::iter::once(&self.initial_state).chain(self.trajectory.iter())
    }
}

/// An obstacle that does not move.
#[derive(Debug, Clone, PartialEq)]
pub struct StaticObstacle {
    pub id: u64,
    pub obstacle_type: ObstacleType,
    pub shape: Shape,
    pub initial_state: ObstacleState,
}

/// A planning problem: where the planned vehicle starts. Goal regions are counted, not typed
/// (no measure here needs them).
#[derive(Debug, Clone, PartialEq)]
pub struct PlanningProblem {
    pub id: u64,
    pub initial_state: ObstacleState,
    pub goal_state_count: usize,
}

/// An intersection: its incomings and where each leads.
#[derive(Debug, Clone, PartialEq)]
pub struct Intersection {
    pub id: u64,
    pub incomings: Vec<Incoming>,
}

/// One incoming of an intersection.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Incoming {
    pub id: u64,
    pub incoming_lanelets: Vec<u64>,
    pub successors_right: Vec<u64>,
    pub successors_straight: Vec<u64>,
    pub successors_left: Vec<u64>,
}
