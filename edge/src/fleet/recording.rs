//! A CommonRoad recording as a scene: the lanelet map is the road, the recorded ego (`v0`) is
//! driven closed-loop by the reference driver on its own onboard stack from its recorded
//! initial state, and every other recorded obstacle is played back by the authority (a
//! recording does not react). The episode is `resimulate(.., EgoMode::ReferenceDriver, ..)`'s,
//! stepped by [`ResimStepper`] with the controls of the ego's process.

use super::SceneError;
use risktwin_common::digest::fnv1a64;
use risktwin_commonroad::twin::{EgoMode, ResimStepper, TwinScene};
use risktwin_commonroad::{Scenario, parse_scenario};
use std::sync::Arc;

/// A parsed CommonRoad file, its ego, and the digest of its bytes (the scene's identity).
#[derive(Clone)]
pub struct Recording {
    scenario: Arc<Scenario>,
    /// The scene as the twin sees it (road, ego, playback), with no vehicle taken out.
    scene: Arc<TwinScene>,
    /// The ego's dynamic-obstacle id.
    pub ego_id: u64,
    /// FNV-1a 64 of the file's bytes.
    pub file_digest: u64,
}

impl std::fmt::Debug for Recording {
    /// Names the recording; its parsed contents would run to megabytes.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Recording")
            .field("benchmark_id", &self.scenario.benchmark_id)
            .field("ego_id", &self.ego_id)
            .field("file_digest", &format_args!("{:016x}", self.file_digest))
            .finish()
    }
}

impl PartialEq for Recording {
    /// Same bytes and ego: the same recording (the parsed values follow from the bytes).
    fn eq(&self, other: &Self) -> bool {
        self.file_digest == other.file_digest && self.ego_id == other.ego_id
    }
}

impl Recording {
    /// Parses CommonRoad XML `xml` with ego `ego` (default: the scenario's, as everywhere in the
    /// CLI: the dynamic obstacle that is a planning problem's, else the first). Errors name
    /// what is wrong (the element and line, an unknown ego and the ones there are).
    pub fn parse(xml: &str, ego: Option<u64>) -> Result<Recording, SceneError> {
        let refused = |reason: String| SceneError::Recording { reason };
        let scenario = parse_scenario(xml).map_err(|e| refused(e.to_string()))?;
        let scene = TwinScene::new(&scenario, ego).map_err(|e| refused(e.to_string()))?;
        let ego_id = scene.ego.id;
        let file_digest = fnv1a64(xml.bytes());
        Ok(Recording { scenario: Arc::new(scenario), scene: Arc::new(scene), ego_id, file_digest })
    }

    /// The scenario's benchmark id (`USA_Lanker-1_3_T-1`).
    pub fn benchmark_id(&self) -> &str {
        &self.scenario.benchmark_id
    }

    pub fn scenario(&self) -> &Scenario {
        &self.scenario
    }

    /// The scene as the twin sees it, every recorded obstacle present.
    pub fn twin_scene(&self) -> &TwinScene {
        &self.scene
    }

    /// Candidates for `v1, v2, …`: the recorded vehicles other than the ego in file order (no
    /// pedestrians, cyclists or parked vehicles), as their index among the other obstacles,
    /// which is their id in the truth.
    pub fn vehicles(&self) -> Vec<usize> {
        self.scene.vehicles()
    }

    /// The authority's world at the ego's first recorded state, with `withdrawn` (indices among
    /// the other obstacles) taken out.
    pub fn stepper(&self, withdrawn: impl IntoIterator<Item = usize>) -> Result<ResimStepper<'_>, SceneError> {
        let mut scene = TwinScene::clone(&self.scene);
        for index in withdrawn {
            scene.withdraw(index);
        }
        let step_s = risktwin_common::world::STEP_S;
        ResimStepper::new(&self.scenario.lanelets, scene, EgoMode::ReferenceDriver, step_s)
            .map_err(|e| SceneError::Failed { reason: e.to_string() })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fleet::authority::{Embedded, run_scene};
    use crate::fleet::{Role, SceneSetup, SceneSource};
    use risktwin_commonroad::twin::resimulate;

    fn xml(name: &str) -> String {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../data/commonroad/{name}.xml"));
        std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
    }

    fn scene(name: &str, ego: Option<u64>, connected: u32, rsus: u32) -> SceneSetup {
        let recording = Recording::parse(&xml(name), ego).expect("the file parses");
        SceneSetup::commonroad(recording, connected, rsus).expect("a scene")
    }

    /// The embedded scene's ego outcome is `risktwin simulate --commonroad F --policy idm`'s:
    /// `resimulate` with the reference driver at the twin's step.
    #[test]
    fn an_embedded_recording_scene_is_the_resimulated_episode() {
        for (name, connected) in [("OSC_CutIn-1_2_T-1", 2), ("BEL_Putte-8_2_T-1", 4), ("ZAM_Tjunction-1_97_T-1", 3)] {
            let setup = scene(name, None, connected, 1);
            let outcome = run_scene(&setup, &mut Embedded::new(&setup).expect("stacks")).expect("runs");
            let SceneSource::CommonRoad(recording) = &setup.source else { unreachable!("a recording") };
            let step_s = risktwin_common::world::STEP_S;
            let resim = resimulate(recording.scenario(), None, EgoMode::ReferenceDriver, step_s).expect("resim");
            assert_eq!(outcome.metrics, resim.metrics, "{name}: the ego's episode");
            assert_eq!(outcome.risk, resim.risk, "{name}");
            assert_eq!(outcome.steps, resim.metrics.steps, "{name}");
            assert!(outcome.steps > 50, "{name}: {} steps", outcome.steps);
            assert_eq!(outcome.kind, "commonroad");
        }
    }

    #[test]
    fn connected_vehicles_are_the_recorded_vehicles_in_file_order() {
        // HRV_Pula-27_3_T-1: the ego is the first obstacle (a motorcycle, 34), then a bicycle
        // (39) and cars; bicycles are no connected vehicles.
        let setup = scene("HRV_Pula-27_3_T-1", None, 3, 1);
        let SceneSource::CommonRoad(recording) = &setup.source else { unreachable!("a recording") };
        assert_eq!(recording.ego_id, 34);
        let others = &recording.twin_scene().others;
        let ids: Vec<u64> = [1, 2]
            .iter()
            .map(|k| match setup.role_of(&format!("v{k}")) {
                Ok(Role::Agent { traffic_index }) => others[traffic_index].id,
                other => panic!("v{k}: {other:?}"),
            })
            .collect();
        assert_eq!(ids, [323, 329], "the cars after the bicycle");
        let too_many = Recording::parse(&xml("HRV_Pula-27_3_T-1"), None).and_then(|r| SceneSetup::commonroad(r, 40, 0));
        assert!(
            matches!(too_many, Err(SceneError::TooManyConnected { asked: 40, available: 7, what: "recording", .. })),
            "{too_many:?}"
        );
    }

    #[test]
    fn the_digest_covers_the_file_the_ego_and_the_roles() {
        let a = scene("BEL_Putte-8_2_T-1", None, 3, 1);
        assert_eq!(a.digest(), scene("BEL_Putte-8_2_T-1", None, 3, 1).digest());
        assert_eq!(a.digest(), scene("BEL_Putte-8_2_T-1", Some(33), 3, 1).digest(), "33 is the default ego");
        assert_ne!(a.digest(), scene("BEL_Putte-8_2_T-1", Some(35), 3, 1).digest(), "another ego");
        assert_ne!(a.digest(), scene("BEL_Putte-8_2_T-1", None, 2, 1).digest(), "other roles");
        assert_ne!(a.digest(), scene("HRV_Pula-27_3_T-1", None, 3, 1).digest(), "another file");
        // One byte more (a trailing newline) is another file.
        let edited = Recording::parse(&format!("{}\n", xml("BEL_Putte-8_2_T-1")), None).expect("parses");
        assert_ne!(a.digest(), SceneSetup::commonroad(edited, 3, 1).expect("scene").digest());
        assert!(a.describe().starts_with("CommonRoad BEL_Putte-8_2_T-1 (file "), "{}", a.describe());
    }

    #[test]
    fn a_bad_file_or_ego_is_refused_by_name() {
        let unknown = Recording::parse(&xml("BEL_Putte-8_2_T-1"), Some(999_999));
        let Err(SceneError::Recording { reason }) = unknown else { panic!("{unknown:?}") };
        assert!(reason.contains("ego id 999999 is not a dynamic obstacle") && reason.contains("33, 35"), "{reason}");
        assert!(matches!(Recording::parse("<commonRoad", None), Err(SceneError::Recording { .. })));
    }

    #[test]
    fn a_recorded_vehicle_taken_out_is_absent_and_the_others_keep_their_ids() {
        let full = scene("BEL_Putte-8_2_T-1", None, 3, 0);
        let without = full.clone().without(&["v1".into()]).expect("v1 can be taken out");
        let ids = |setup: &SceneSetup| {
            let truth = setup.world().expect("a world").truth(0, 0);
            truth.objects.iter().map(|o| o.id).collect::<Vec<_>>()
        };
        let (all, less) = (ids(&full), ids(&without));
        assert_eq!(all.len(), less.len() + 1);
        assert!(all.contains(&0) && !less.contains(&0), "v1 is the first other obstacle: {all:?} / {less:?}");
        let outcome = run_scene(&without, &mut Embedded::new(&without).expect("stacks")).expect("runs");
        assert_eq!(outcome.participants, ["v0", "v2"]);
    }
}
