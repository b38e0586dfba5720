//! An episode as the twin saw it: one vehicle's pushed scenario, scored tick by tick from what
//! the twin reconstructed of its site (the vehicle's reported states, the objects it and the
//! roadside units perceived) on the scenario's own road and route, with the code `simulate`
//! scores the world's own steps with ([`EpisodeScorer`]). Set beside the vehicle's own
//! `ScenarioResult`, it shows what the fleet's streams let the cloud know of the episode.

use super::SiteTwin;
use super::risk::{Surroundings, TwinStep};
use risktwin_common::episode::{EpisodeResult, EpisodeScorer};
use risktwin_common::metrics::RewardWeights;
use risktwin_common::road::{Lane, Road};
use risktwin_common::scenario::{ScenarioSpec, build};
use risktwin_common::world::STEP_S;

/// One vehicle's episode, scored as the twin's ticks come.
#[derive(Debug, Clone)]
pub struct TwinEpisode {
    source: String,
    road: Road,
    around: Surroundings,
    scorer: EpisodeScorer,
    route: Lane,
    route_start_s_m: f64,
    route_length_m: f64,
    desired_speed_mps: f64,
    last_tick_ns: Option<i64>,
    progress_m: f64,
}

impl TwinEpisode {
    /// The episode of `spec` driven by vehicle `source`, before its first tick.
    pub fn new(spec: &ScenarioSpec, source: &str) -> Self {
        let world = build(spec);
        let route = world.road.lane(world.route.lane).clone();
        let progress_m = world.progress_m();
        TwinEpisode {
            source: source.to_owned(),
            scorer: EpisodeScorer::new(RewardWeights::default(), progress_m),
            route,
            route_start_s_m: world.route.start_s_m,
            route_length_m: world.route.length_m,
            desired_speed_mps: world.desired_speed_mps,
            road: world.road,
            around: Surroundings::default(),
            last_tick_ns: None,
            progress_m,
        }
    }

    /// Scores the tick `tick_ns` of the vehicle's site; a tick without the vehicle (its state
    /// stale or missing) is skipped, and the next one covers the time since its last.
    pub fn tick(&mut self, site: &SiteTwin, tick_ns: i64) {
        let Some(ego) = site.vehicles.iter().position(|v| *v.source == *self.source) else { return };
        let dt_s = self.last_tick_ns.map_or(STEP_S, |last| (tick_ns - last) as f64 * 1e-9);
        if dt_s <= 0.0 {
            return;
        }
        let position = site.vehicles[ego].kinematics.pose.position();
        self.progress_m = self.route.project(position).s_m - self.route_start_s_m;
        let step = TwinStep { dt_s, progress_m: self.progress_m, desired_speed_mps: self.desired_speed_mps };
        self.around.score(&self.road, site, ego, step, &mut self.scorer);
        self.last_tick_ns = Some(tick_ns);
    }

    /// The episode so far.
    pub fn finish(&self) -> EpisodeResult {
        self.scorer.finish(self.progress_m / self.route_length_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ingest::ObservedKinematics;
    use crate::twin::{TwinObject, TwinVehicle};
    use risktwin_common::episode::{EpisodeResult, evaluate_observed};
    use risktwin_common::geometry::{Footprint, Pose};
    use risktwin_common::scenario::{ScenarioKind, sample};
    use risktwin_common::telemetry::DetectedObject;
    use std::sync::Arc;

    /// The twin of a site that received every step of `spec`'s reference episode exactly as it
    /// happened (no noise, no loss, no latency), scored; beside the library's own episode.
    fn perfectly_observed(spec: &ScenarioSpec) -> (EpisodeResult, EpisodeResult) {
        let mut twin = TwinEpisode::new(spec, "veh-1");
        let mut tick_ns = 0;
        let library = evaluate_observed(spec, &mut |world, _| {
            tick_ns += (world.dt_s * 1e9).round() as i64;
            let e = &world.ego;
            let kinematics = ObservedKinematics {
                pose: e.pose(),
                velocity: e.velocity(),
                speed_mps: e.state.speed_mps,
                accel_mps2: e.state.accel_mps2,
                footprint: e.params.footprint(),
                seqs: (0, 0),
            };
            let vehicle =
                TwinVehicle { source: Arc::from("veh-1"), kinematics, jerk_mps3: 0.0, lateral_accel_mps2: 0.0 };
            let objects = world.scene().iter().map(|o| {
                let object = DetectedObject {
                    id: o.id,
                    kind: o.kind,
                    pose: Pose::new(o.obb.centre.x, o.obb.centre.y, o.obb.axis.y.atan2(o.obb.axis.x)),
                    footprint: Footprint::new(2.0 * o.obb.half_length_m, 2.0 * o.obb.half_width_m),
                    velocity: o.velocity,
                    // Traffic (ids below the traffic count) reports its acceleration, as a
                    // connected vehicle's state does; pedestrians have none.
                    accel_mps2: if (o.id as usize) < world.traffic.len() {
                        world.traffic.accel_mps2(o.id as usize)
                    } else {
                        0.0
                    },
                };
                TwinObject { observer: Arc::from("veh-1"), object }
            });
            let site = SiteTwin { vehicles: vec![vehicle], objects: objects.collect() };
            twin.tick(&site, tick_ns);
        });
        (twin.finish(), library)
    }

    #[test]
    fn a_perfectly_observed_episode_scores_as_the_library_scored_it() {
        for kind in ScenarioKind::ALL {
            let spec =
                (0..).map(|i| sample(11, kind, i)).find(|s| risktwin_common::scenario::check_feasible(s).is_ok());
            let spec = spec.expect("a feasible spec");
            let (twin, library) = perfectly_observed(&spec);
            let (t, l) = (&twin.metrics, &library.metrics);
            assert_eq!(
                (t.collision, t.offroad, t.success, t.steps),
                (l.collision, l.offroad, l.success, l.steps),
                "{kind:?}"
            );
            assert!((t.route_completion - l.route_completion).abs() < 1e-9, "{kind:?}");
            assert!((t.avg_speed_mps - l.avg_speed_mps).abs() < 1e-9, "{kind:?}");
            assert_eq!((t.min_ttc_s, t.min_distance_m), (l.min_ttc_s, l.min_distance_m), "{kind:?}");
            assert!(
                (twin.risk.score - library.risk.score).abs() < 1e-9,
                "{kind:?}: {:?} vs {:?}",
                twin.risk,
                library.risk
            );
        }
    }
}
