//! The authority's world: a generated scenario's [`World`] (road, IDM/MOBIL traffic, scripted
//! adversaries, pedestrians), or a recording's [`ResimStepper`] (lanelet road, recorded traffic
//! played back). Either gives the same truth message and the same road-map message.

use super::wire::Truth;
use risktwin_common::road::Road;
use risktwin_common::world::World;
use risktwin_commonroad::LaneletNetwork;
use risktwin_commonroad::twin::ResimStepper;

/// A scene's world.
// One per scene, stepped in place: the variants' sizes cost nothing worth a box.
#[allow(clippy::large_enum_variant)]
pub enum SceneWorld<'a> {
    Generated(World),
    Recorded(ResimStepper<'a>),
}

impl SceneWorld<'_> {
    /// The truth now, for step `step` of scene `scene`.
    pub fn truth(&mut self, scene: u64, step: u64) -> Truth {
        match self {
            SceneWorld::Generated(world) => {
                world.scene_objects();
                Truth::of(world, scene, step)
            }
            SceneWorld::Recorded(run) => Truth::of_recording(run, scene, step),
        }
    }

    /// The road the twin's risk runs on, and the lanelets it was converted from (none for a
    /// generated road), as a road-map message carries them.
    pub fn road_map(&self) -> (Road, LaneletNetwork) {
        match self {
            SceneWorld::Generated(world) => (world.road.clone(), LaneletNetwork::default()),
            SceneWorld::Recorded(run) => (run.road().clone(), run.lanelets().clone()),
        }
    }
}
