//! The physics authority: steps the scene's world at the world's own step, hands each step's
//! truth to every participant through a [`Plane`] and advances with the ego's controls.
//! The episode is measured exactly as `risktwin simulate` measures it (`common::episode`; a
//! recording's as `simulate --commonroad` does, `commonroad::twin::ResimStepper`).

use super::onboard::Onboard;
use super::physics::SceneWorld;
use super::v2x::cam_state;
use super::wire::{SceneEnd, Truth};
use super::{SceneError, SceneSetup, SceneSource};
use risktwin_common::digest::{FNV_OFFSET, fnv1a64_step};
use risktwin_common::episode::run_stepped;
use risktwin_common::metrics::{EpisodeMetrics, RewardWeights};
use risktwin_common::risk::RiskTerms;
use risktwin_common::vehicle::Controls;
use risktwin_v2x::cam::CamState;
use risktwin_v2x::messages::{V2xSummary, VirtualScene};
use serde::Serialize;
use std::collections::BTreeMap;

/// How the truth reaches the participants and their answers come back.
pub trait Plane {
    /// Hands `truth` to every participant; once all have answered, the ego's controls.
    fn exchange(&mut self, truth: &Truth) -> Result<Controls, SceneError>;
    /// Tells every participant the scene is over (`last.end` is set).
    fn finish(&mut self, last: &Truth) -> Result<(), SceneError>;
}

/// Every participant's stack in this process: the embedded run of a scene.
pub struct Embedded {
    stacks: Vec<Onboard>,
    /// Every participant's V2X layer in virtual time, if the scene has V2X.
    v2x: Option<(VirtualScene, Vec<Option<CamState>>)>,
}

impl Embedded {
    /// The stacks of every participant of `setup`; with the scene's V2X, if it has V2X, in
    /// virtual time: vehicles send CAMs, everyone receives, decided as a deployed scene's
    /// participants decide them (`super::v2x`).
    pub fn new(setup: &SceneSetup) -> Result<Embedded, SceneError> {
        let ids = setup.participants();
        let stacks: Vec<Onboard> = ids.iter().map(|id| Onboard::new(setup, id)).collect::<Result<_, _>>()?;
        let v2x = setup.v2x().map(|&channel| {
            let members: Vec<(String, Option<u32>)> =
                ids.into_iter().zip(&stacks).map(|(id, s)| (id, s.role().object_id())).collect();
            (VirtualScene::new(channel, &members).warning(setup.warnings()).cpm(setup.cpm()), Vec::new())
        });
        Ok(Embedded { stacks, v2x })
    }

    /// Each participant's V2X counts, if the scene has V2X.
    pub fn v2x_summaries(&self) -> Option<BTreeMap<String, V2xSummary>> {
        self.v2x.as_ref().map(|(scene, _)| scene.summaries())
    }
}

impl Plane for Embedded {
    fn exchange(&mut self, truth: &Truth) -> Result<Controls, SceneError> {
        let mut ego = None;
        for (member, stack) in self.stacks.iter_mut().enumerate() {
            let Some(pose) = stack.perceive(truth) else { continue };
            // The warnings heard by this step (made + latency ≤ now) reach the driver's view.
            let warned = match &mut self.v2x {
                Some((scene, _)) => scene.warned(member, truth.time_s, stack.perceived()),
                None => &[],
            };
            if let Some(controls) = stack.act(truth, pose, warned) {
                ego = Some(controls);
            }
        }
        if let Some((scene, states)) = &mut self.v2x {
            states.clear();
            states.extend(self.stacks.iter().map(|stack| cam_state(truth, stack)));
            let seen: Vec<&[_]> = self.stacks.iter().map(Onboard::perceived).collect();
            scene.warn(truth.time_s, states, &seen);
            scene.step(truth.time_s, states);
        }
        ego.ok_or_else(|| SceneError::Failed { reason: "the ego's stack gave no controls".into() })
    }

    fn finish(&mut self, _last: &Truth) -> Result<(), SceneError> {
        Ok(())
    }
}

/// A plane paced against the wall clock: step k is handed out no earlier than k·step/speed
/// after the first (lockstep still waits for every answer; a late step is counted).
pub struct Paced<P> {
    pub inner: P,
    /// Scene seconds per wall second; 1 is real time.
    pub speed: f64,
    pub step_s: f64,
    start: Option<std::time::Instant>,
    /// Steps handed out after their wall-clock time.
    pub late_steps: u64,
}

impl<P: Plane> Paced<P> {
    pub fn new(inner: P, speed: f64, step_s: f64) -> Self {
        Paced { inner, speed, step_s, start: None, late_steps: 0 }
    }
}

impl<P: Plane> Plane for Paced<P> {
    fn exchange(&mut self, truth: &Truth) -> Result<Controls, SceneError> {
        let start = *self.start.get_or_insert_with(std::time::Instant::now);
        let due = start + std::time::Duration::from_secs_f64(truth.step as f64 * self.step_s / self.speed);
        match due.checked_duration_since(std::time::Instant::now()) {
            Some(wait) => std::thread::sleep(wait),
            None => self.late_steps += u64::from(truth.step > 0),
        }
        self.inner.exchange(truth)
    }

    fn finish(&mut self, last: &Truth) -> Result<(), SceneError> {
        self.inner.finish(last)
    }
}

/// What a scene produced: the ego's episode and a digest of every step's truth.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneOutcome {
    /// The scene digest, hex.
    pub scene: String,
    pub kind: &'static str,
    /// A generated scenario's seed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// A recording's benchmark id and ego.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub recording: Option<RecordingOutcome>,
    pub participants: Vec<String>,
    /// Physics steps taken.
    pub steps: u64,
    pub step_s: f64,
    /// FNV-1a over the encoded truth of every step, hex: equal digests, equal trajectories.
    pub truth_digest: String,
    pub metrics: EpisodeMetrics,
    pub risk: RiskTerms,
}

/// Which recording a scene played.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecordingOutcome {
    pub benchmark_id: String,
    pub ego_id: u64,
    /// FNV-1a 64 of the file's bytes, hex.
    pub file: String,
}

/// Hands each step's truth to the participants through a plane, digesting what it sends.
struct Handout<'p> {
    plane: &'p mut dyn Plane,
    /// Steps handed out and answered.
    step: u64,
    digest: u64,
    bytes: Vec<u8>,
}

impl Handout<'_> {
    fn exchange(&mut self, truth: &Truth) -> Result<Controls, SceneError> {
        truth.encode_into(&mut self.bytes);
        self.digest = self.bytes.iter().fold(self.digest, |h, &b| fnv1a64_step(h, b));
        let controls = self.plane.exchange(truth)?;
        self.step += 1;
        Ok(controls)
    }
}

/// Runs `setup`'s episode to its end, the participants reached through `plane`. A failing
/// participant ends the scene: the participants are told why, and the error is returned.
pub fn run_scene(setup: &SceneSetup, plane: &mut dyn Plane) -> Result<SceneOutcome, SceneError> {
    let scene = setup.digest();
    let mut out = Handout { plane, step: 0, digest: FNV_OFFSET, bytes: Vec::new() };
    let (result, mut last, step_s) = match setup.world()? {
        SceneWorld::Generated(mut world) => {
            let result =
                run_stepped(&mut world, &RewardWeights::default(), &mut |_, _| {}, &mut |w| -> Result<_, SceneError> {
                    w.scene_objects();
                    let controls = out.exchange(&Truth::of(w, scene, out.step))?;
                    Ok(w.advance(controls))
                });
            world.scene_objects();
            let last = Truth::of(&world, scene, out.step);
            (result.map(|r| (r.metrics, r.risk)), last, world.dt_s)
        }
        // The recording's episode, measured as `resimulate` measures it.
        SceneWorld::Recorded(mut run) => {
            let mut result = Ok(());
            while result.is_ok() && !run.finished() {
                result = out.exchange(&Truth::of_recording(&run, scene, out.step)).map(|c| run.advance(c));
            }
            let last = Truth::of_recording(&run, scene, out.step);
            (result.map(|()| run.finish()).map(|r| (r.metrics, r.risk)), last, setup.step_s())
        }
    };
    last.end = Some(match &result {
        Ok((metrics, risk)) => SceneEnd::Done { metrics: metrics.clone(), risk: *risk },
        Err(e) => SceneEnd::Failed(e.to_string()),
    });
    let finished = out.plane.finish(&last);
    let (metrics, risk) = result?;
    finished?;
    let (seed, recording) = match &setup.source {
        SceneSource::Generated(spec) => (Some(spec.seed), None),
        SceneSource::CommonRoad(r) => {
            let file = format!("{:016x}", r.file_digest);
            (None, Some(RecordingOutcome { benchmark_id: r.benchmark_id().to_owned(), ego_id: r.ego_id, file }))
        }
    };
    Ok(SceneOutcome {
        scene: format!("{scene:016x}"),
        kind: setup.kind_name(),
        seed,
        recording,
        participants: setup.participants(),
        steps: out.step,
        step_s,
        truth_digest: format!("{:016x}", out.digest),
        metrics,
        risk,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::feasible_spec;
    use risktwin_common::episode::evaluate;
    use risktwin_common::scenario::{ScenarioKind, ScenarioSpec};

    #[test]
    fn an_embedded_scene_is_the_library_episode() {
        for kind in [ScenarioKind::CutIn, ScenarioKind::EmergencyBraking, ScenarioKind::PedestrianCrossing] {
            let spec = feasible_spec(5, kind).expect("feasible");
            let setup = SceneSetup::new(spec.clone(), 1, 1).expect("scene");
            let outcome = run_scene(&setup, &mut Embedded::new(&setup).expect("stacks")).expect("runs");
            let library = evaluate(&spec);
            assert_eq!(outcome.metrics, library.metrics, "{kind:?}: same trajectory as `simulate`");
            assert_eq!(outcome.risk, library.risk);
            assert_eq!(outcome.steps, library.metrics.steps);
        }
    }

    #[test]
    fn the_connected_cutter_is_seen_by_the_ego_and_the_rsu() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("feasible");
        let setup = SceneSetup::new(spec, 2, 1).expect("scene");
        let mut plane = Embedded::new(&setup).expect("stacks");
        let (mut seen_by_ego, mut seen_by_rsu) = (0, 0);
        struct Watch<'a>(&'a mut Embedded, &'a mut u32, &'a mut u32);
        impl Plane for Watch<'_> {
            fn exchange(&mut self, truth: &Truth) -> Result<Controls, SceneError> {
                let controls = self.0.exchange(truth)?;
                let sees_cutter = |s: &Onboard| s.perceived().iter().any(|o| o.id == 0);
                *self.1 += u32::from(sees_cutter(&self.0.stacks[0]));
                *self.2 += u32::from(sees_cutter(&self.0.stacks[2]));
                Ok(controls)
            }
            fn finish(&mut self, last: &Truth) -> Result<(), SceneError> {
                self.0.finish(last)
            }
        }
        run_scene(&setup, &mut Watch(&mut plane, &mut seen_by_ego, &mut seen_by_rsu)).expect("runs");
        assert!(seen_by_ego > 10 && seen_by_rsu > 10, "ego {seen_by_ego}, rsu {seen_by_rsu} steps");
    }

    #[test]
    fn a_vehicle_taken_out_is_absent_from_the_truth_and_the_others_keep_their_ids() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("feasible");
        let full = SceneSetup::new(spec.clone(), 2, 1).expect("scene");
        let without = SceneSetup::new(spec.clone(), 2, 1).and_then(|s| s.without(&["v1".into()])).expect("scene");
        assert_eq!(without.participants(), ["v0", "rsu0"]);
        assert!(matches!(without.role_of("v1"), Err(SceneError::Withdrawn { .. })));
        assert_ne!(without.digest(), full.digest());
        for bad in ["v0", "rsu0"] {
            let refused = SceneSetup::new(spec.clone(), 2, 1).and_then(|s| s.without(&[bad.into()]));
            assert_eq!(refused, Err(SceneError::CannotWithdraw { id: bad.into() }));
        }
        let ids = |setup: &SceneSetup| {
            let truth = setup.world().expect("a world").truth(0, 0);
            truth.objects.iter().map(|o| o.id).collect::<Vec<_>>()
        };
        assert_eq!(ids(&full), [0, 1], "the cutter (0) and the slow lead (1)");
        assert_eq!(ids(&without), [1], "the lead keeps its id");
        let outcome = run_scene(&without, &mut Embedded::new(&without).expect("stacks")).expect("runs");
        assert!(outcome.metrics.success, "alone with the lead, the ego drives through: {:?}", outcome.metrics);
    }

    #[test]
    fn the_ego_reacts_to_the_connected_cutter_it_perceives() {
        let spec = feasible_spec(3, ScenarioKind::CutIn).expect("feasible");
        let mut calm = spec.clone();
        // The same cutter, driving on in its own lane instead of cutting in.
        calm.params.insert("cut_in_time_s".into(), 1e9);
        let run = |spec: ScenarioSpec| {
            let setup = SceneSetup::new(spec, 2, 0).expect("scene");
            let mut plane = Embedded::new(&setup).expect("stacks");
            let mut closest_lateral_m = f64::INFINITY;
            struct Watch<'a>(&'a mut Embedded, &'a mut f64);
            impl Plane for Watch<'_> {
                fn exchange(&mut self, truth: &Truth) -> Result<Controls, SceneError> {
                    let controls = self.0.exchange(truth)?;
                    let ego = truth.ego_pose();
                    let (s, c) = ego.heading_rad.sin_cos();
                    for o in self.0.stacks[0].perceived().iter().filter(|o| o.id == 0) {
                        let (dx, dy) = (o.obb.centre.x - ego.x_m, o.obb.centre.y - ego.y_m);
                        if dx * c + dy * s > 0.0 {
                            *self.1 = self.1.min((-dx * s + dy * c).abs());
                        }
                    }
                    Ok(controls)
                }
                fn finish(&mut self, last: &Truth) -> Result<(), SceneError> {
                    self.0.finish(last)
                }
            }
            let outcome = run_scene(&setup, &mut Watch(&mut plane, &mut closest_lateral_m)).expect("runs");
            (outcome, closest_lateral_m)
        };
        let (cut, cut_lateral_m) = run(spec);
        let (calm, calm_lateral_m) = run(calm);
        assert!(cut_lateral_m < 1.0, "the ego saw the cutter in its lane ahead: {cut_lateral_m} m");
        assert!(calm_lateral_m > 2.5, "without the cut-in it stays a lane away: {calm_lateral_m} m");
        assert_ne!(cut.truth_digest, calm.truth_digest);
        assert!(
            cut.metrics.avg_speed_mps < calm.metrics.avg_speed_mps,
            "the ego slows for the cutter: {} vs {} m/s",
            cut.metrics.avg_speed_mps,
            calm.metrics.avg_speed_mps
        );
    }
}
