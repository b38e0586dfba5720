use super::*;
use crate::channel::{LinkBudget, PathLoss};
use crate::latency::Latency;
use risktwin_common::episode::{EpisodeResult, evaluate, run_stepped, with_reference_driver};
use risktwin_common::metrics::RewardWeights;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, sample};

/// Warnings from a mast `offset_m` beside the lane, each copy taking exactly `latency_ms`.
fn setup(latency_ms: f64, offset_m: f64) -> WarningSetup {
    WarningSetup {
        channel: V2xChannel {
            model: PathLoss::UrbanLos,
            budget: LinkBudget::default(),
            latency: Latency::Sidelink { t1_ms: latency_ms, t2_ms: latency_ms },
            bursts: None,
        },
        rsu_offset_m: offset_m,
        repeat_hz: 10.0,
    }
}

/// The reference driver's episode of `spec`, warned through `setup`.
fn warned(spec: &ScenarioSpec, setup: WarningSetup) -> (EpisodeResult, WarningCounts) {
    let (mut world, mut driver) = with_reference_driver(spec);
    let mut warnings = Warnings::new(&world, setup, spec.seed);
    let result = run_stepped(&mut world, &RewardWeights::default(), &mut |_, _| {}, &mut |w| {
        Ok::<_, std::convert::Infallible>(warnings.step(w, &mut driver))
    })
    .unwrap_or_else(|e| match e {});
    (result, warnings.counts())
}

#[test]
fn a_warning_in_time_prevents_a_crash_and_the_same_warning_late_does_not() {
    // A pedestrian steps out from behind parked cars; the reference driver, seeing it late,
    // hits it.
    let spec = sample(7, ScenarioKind::PedestrianCrossing, 49);
    assert!(evaluate(&spec).metrics.collision, "the unwarned driver crashes");
    let (in_time, counts) = warned(&spec, setup(20.0, 10.0));
    assert!(!in_time.metrics.collision, "warned within 20 ms, it stops: {counts:?}");
    assert!(counts.arrived > 0 && counts.first_heard_s > counts.first_hazard_s, "{counts:?}");
    let (late, counts) = warned(&spec, setup(700.0, 10.0));
    assert!(counts.arrived > 0, "the late warnings are heard: {counts:?}");
    assert!(late.metrics.collision, "warned 0.7 s late, it does not: {counts:?}");
}

#[test]
fn warnings_that_never_arrive_leave_the_episode_as_it_was() {
    // The mast 1,000 km away: every copy is lost, and the world's randomness is untouched by the
    // RSU's sensor and the channel.
    for (kind, index) in [(ScenarioKind::PedestrianCrossing, 49), (ScenarioKind::SensorOcclusion, 5)] {
        let spec = sample(7, kind, index);
        let (result, counts) = warned(&spec, setup(20.0, 1e6));
        assert_eq!(counts.arrived, 0);
        assert_eq!(result, evaluate(&spec), "{kind}");
    }
}

#[test]
fn the_seed_decides_which_warnings_arrive() {
    let spec = sample(7, ScenarioKind::SensorOcclusion, 26);
    // Far enough in urban NLOS that about half the copies are lost.
    let nlos = |offset_m| WarningSetup {
        channel: V2xChannel { model: PathLoss::UrbanNlos, latency: Latency::SIDELINK, ..setup(0.0, offset_m).channel },
        ..setup(0.0, offset_m)
    };
    let (a, ca) = warned(&spec, nlos(330.0));
    assert!(ca.arrived > 0 && ca.arrived < ca.made, "{ca:?}");
    assert_eq!((a, ca), warned(&spec, nlos(330.0)));
    let other = ScenarioSpec { seed: spec.seed + 1, ..spec.clone() };
    assert_ne!(warned(&other, nlos(330.0)).1.arrived, ca.arrived);
}
