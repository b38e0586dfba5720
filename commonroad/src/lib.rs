//! CommonRoad scenarios (https://commonroad.in.tum.de): import of the XML format (2020a, and the
//! 2018b obstacle layout) into typed values and export back to XML, and the criticality measures
//! of a recorded ego against the other traffic.
//!
//! - [`parse_scenario`]: XML text → [`Scenario`] (pure, no I/O; errors name the element, its id,
//!   its line and the reason — [`CommonRoadError`]).
//! - [`limits`]: the size, nesting depth and node count a document may have (a hostile file is
//!   an error, not a stack overflow).
//! - [`to_xml`]: [`Scenario`] → XML text that [`parse_scenario`] reads back equal.
//! - [`LaneletNetwork`] (defined in `risktwin_common::road::lanelet`, as the twin's road map carries
//!   it): bounds → centrelines, widths, adjacency, links, polygons.
//! - [`model`]: obstacles (type, shape, initial state, trajectory or occupancy set), planning
//!   problems, intersections.
//! - [`criticality`]: HW, THW, TTC, a_long,req per (time step, other), PET and minimum
//!   distance per pair, agreeing with CommonRoad-CriMe where its quirks do not apply.
//!
//! ```no_run
//! # fn demo(text: &str) -> Result<(), Box<dyn std::error::Error>> {
//! use risktwin_commonroad::{criticality::scenario_criticality, parse_scenario};
//! let scenario = parse_scenario(text)?;
//! let ego = scenario.default_ego_id();
//! let measures = scenario_criticality(&scenario, ego)?;
//! println!("{} cells", measures.cells.len());
//! # Ok(()) }
//! ```

pub mod criticality;
mod error;
pub mod limits;
pub mod model;
mod parse;
pub mod twin;
mod write;
mod xml;

pub use error::CommonRoadError;
pub use model::{
    DynamicObstacle, Incoming, Intersection, ObstacleState, Occupancy, PlacedShape, PlanningProblem, Scenario, Shape,
    StaticObstacle,
};
pub use parse::parse_scenario;
pub use risktwin_common::road::lanelet::{Adjacency, Lanelet, LaneletNetwork};
pub use write::to_xml;
