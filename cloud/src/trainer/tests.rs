//! The trainer's orchestration on small, real libraries (SQLite files) and untrained or briefly
//! trained policies: held-out disjointness, failures entering the library, refreshed sets.

use super::curriculum::Curriculum;
use super::*;
use crate::generate::{generate, store};
use risktwin_common::env::{RiskShaping, Variant};
use risktwin_common::rng::Rng;
use risktwin_common::scenario::ScenarioKind;
use risktwin_learn::{Algo, PolicyNet};
use risktwin_store::library::{Origin, ScenarioLibrary, content_id};
use std::collections::BTreeSet;

fn plan() -> TrainingPlan {
    TrainingPlan {
        algo: Algo::Ppo,
        steps: 2 * 64 * 8,
        n_envs: 8,
        phases: 2,
        curve_points: 2,
        replay_top: 12,
        background: 6,
        replay_share: 0.5,
        mutations: 10,
        mutation_radius: 0.1,
        risk_shaping: RiskShaping::default(),
        warm_start: false,
        cost_limit: None,
        replay_rule: ReplayRule::default(),
        threads: 2,
    }
}

fn library(seed: u64) -> (tempfile::TempDir, ScenarioLibrary) {
    let dir = tempfile::tempdir().expect("temp dir");
    let mut lib = ScenarioLibrary::open(dir.path().join("library.db")).expect("library");
    let batch = generate(&ScenarioKind::ALL, 8, seed, 2);
    store(&mut lib, &ScenarioKind::ALL, &batch).expect("store");
    (dir, lib)
}

#[test]
fn held_out_covers_every_kind_and_is_disjoint_from_the_library() {
    let (_dir, lib) = library(3);
    let held = HeldOut::new(3, 4);
    assert_eq!(held.specs.len(), 20);
    for kind in ScenarioKind::ALL {
        assert_eq!(held.specs.iter().filter(|s| s.kind == kind).count(), 4, "{kind}");
    }
    let stored: Vec<_> =
        lib.rank(None, None).unwrap().iter().map(|r| lib.get(&r.id).unwrap().expect("stored").spec).collect();
    assert!(!stored.is_empty());
    held.check_disjoint(&stored).expect("the library shares no spec with the held-out set");
    // The check is real: a held-out spec offered for training is refused by id.
    let leak = held.specs[7].clone();
    let err = held.check_disjoint([&stored[0], &leak]).unwrap_err();
    assert!(matches!(err, TrainerError::HeldOutLeak(ref id) if *id == content_id(&leak)), "{err}");
    // Same seed, same set; another seed, another set.
    assert_eq!(HeldOut::new(3, 4), held);
    assert_ne!(HeldOut::new(4, 4).specs, held.specs);
}

#[test]
fn refresh_stores_failures_and_their_children_and_changes_the_training_set() {
    let (_dir, mut lib) = library(5);
    let held = HeldOut::new(5, 2);
    let plan = plan();
    let mut curriculum = Curriculum::new(11);
    let first = curriculum.initial(&lib, &plan, &held).unwrap();
    assert!(!first.is_empty() && first.len() <= plan.replay_top + plan.background);
    // An untrained policy: it fails on risky scenarios, which is what the refresh feeds on.
    let policy = PolicyNet::new(Algo::Ppo, &[16, 16], &mut Rng::new(1)).unwrap();
    let before = lib.count_by_kind().unwrap().values().map(|c| c.stored).sum::<u64>();
    let (next, refresh) = curriculum.refresh(&mut lib, &policy, "test-phase0", 0, &plan, &held, 2).unwrap();

    assert_eq!(refresh.evaluated, plan.replay_top);
    assert!(refresh.failures > 0, "an untrained policy failed nowhere: {refresh:?}");
    let driven = lib.rank_for_policy("test-phase0", None, None).unwrap();
    assert!(driven.len() >= refresh.evaluated, "the policy's outcomes were not stored");

    assert!(refresh.children > 0);
    let after = lib.count_by_kind().unwrap().values().map(|c| c.stored).sum::<u64>();
    assert!(after > before, "no child was stored ({before} → {after})");
    let child = driven
        .iter()
        .map(|r| lib.get(&r.id).unwrap().expect("stored"))
        .find(|s| s.origin == Origin::Mutated)
        .expect("a mutated child driven by the policy");
    let parent = child.parent_id.clone().expect("children keep their parent");
    assert_eq!(lib.lineage(&child.id).unwrap().get(1), Some(&parent));
    assert!(child.latest_outcome("idm").is_some(), "children are also scored by the reference driver");

    let ids = |v: &[risktwin_common::scenario::ScenarioSpec]| v.iter().map(content_id).collect::<BTreeSet<_>>();
    assert_ne!(ids(&first), ids(&next), "the refresh left the training set unchanged");
    assert!(next.iter().any(|s| lib.get(&content_id(s)).unwrap().is_some_and(|s| s.origin == Origin::Mutated)));
    held.check_disjoint(&next).unwrap();
}

#[test]
fn full_trains_in_phases_and_base_does_not_touch_the_library() {
    let (_dir, mut lib) = library(9);
    let held = HeldOut::new(9, 1);
    let plan = plan();
    let before = lib.count_by_kind().unwrap();
    let base = train_variant(&plan, Variant::Base, 1, &mut lib, &held, &mut |_, _| {}).unwrap();
    assert!(base.refreshes.is_empty());
    assert_eq!(lib.count_by_kind().unwrap(), before, "base changed the library");
    assert!(base.env_steps >= plan.steps);

    let mut calls = 0;
    let full = train_variant(&plan, Variant::Full, 1, &mut lib, &held, &mut |d, t| {
        calls += 1;
        assert!(d <= t);
    })
    .unwrap();
    assert!(calls >= 2);
    assert_eq!(full.refreshes.len(), plan.phases as usize - 1);
    assert_eq!(full.refreshes[0].policy, "ppo-full-seed1-phase0");
    assert!(!lib.rank_for_policy("ppo-full-seed1-phase0", None, None).unwrap().is_empty());
}

#[test]
fn a_warm_start_counts_its_demonstration_steps_and_needs_ppo() {
    let (_dir, mut lib) = library(9);
    let held = HeldOut::new(9, 1);
    let demo_steps = 8 * risktwin_learn::warm::DEMO_STEPS_PER_ENV as u64;
    let plan = TrainingPlan { warm_start: true, steps: demo_steps + 512, ..plan() };
    let warm = train_variant(&plan, Variant::Base, 1, &mut lib, &held, &mut |_, _| {}).unwrap();
    assert_eq!(warm.env_steps, plan.steps, "the demonstrations and one 512-step rollout");
    assert!(warm.curve.iter().all(|p| p.env_steps > demo_steps), "{:?}", warm.curve);
    let sac = TrainingPlan { algo: Algo::Sac, ..plan };
    let err = train_variant(&sac, Variant::Base, 1, &mut lib, &held, &mut |_, _| {}).unwrap_err();
    assert!(err.to_string().contains("warm start needs PPO"), "{err}");
}

#[test]
fn a_cost_limit_trains_with_a_multiplier_and_needs_ppo() {
    let (_dir, mut lib) = library(10);
    let held = HeldOut::new(10, 1);
    let plan = TrainingPlan { cost_limit: Some(0.0), ..plan() };
    let run = train_variant(&plan, Variant::Base, 1, &mut lib, &held, &mut |_, _| {}).unwrap();
    assert_eq!(run.env_steps, plan.steps);
    let sac = TrainingPlan { algo: Algo::Sac, ..plan.clone() };
    let err = train_variant(&sac, Variant::Base, 1, &mut lib, &held, &mut |_, _| {}).unwrap_err();
    assert!(err.to_string().contains("cost limit needs PPO"), "{err}");
    let wide = TrainingPlan { cost_limit: Some(-0.5), ..plan };
    let err = train_variant(&wide, Variant::Base, 1, &mut lib, &held, &mut |_, _| {}).unwrap_err();
    assert!(err.to_string().contains("cost_limit -0.5"), "{err}");
}

#[test]
fn the_frontier_is_what_the_policy_sometimes_completes_most_uncertain_first() {
    let shares = [0.0, 0.75, 1.0, 0.5, 0.25, 0.25];
    let risks = [9.0, 0.1, 9.0, 0.2, 0.3, 0.3];
    let ids: Vec<String> = ["f", "e", "d", "c", "b", "a"].map(String::from).into();
    assert_eq!(curriculum::frontier_order(&shares, &risks, &ids, 10), vec![3, 5, 4, 1]);
    assert_eq!(curriculum::frontier_order(&shares, &risks, &ids, 2), vec![3, 5]);
}

#[test]
fn noisy_success_shares_are_reproducible_whatever_the_thread_count() {
    let specs: Vec<_> = generate(&ScenarioKind::ALL, 1, 12, 2).evaluated.into_iter().map(|e| e.spec).collect();
    let policy = PolicyNet::new(Algo::Ppo, &[8], &mut Rng::new(3)).unwrap();
    let one = drive::success_shares(&policy, &specs, 2, 5, 1).expect("PPO has a σ");
    assert_eq!(one.len(), specs.len());
    assert_eq!(drive::success_shares(&policy, &specs, 2, 5, 2), Some(one));
    let sac = PolicyNet::new(Algo::Sac, &[8], &mut Rng::new(3)).unwrap();
    assert_eq!(drive::success_shares(&sac, &specs, 2, 5, 2), None);
}

#[test]
fn full_trains_with_the_frontier_rule_and_sac_is_refused_it() {
    let (_dir, mut lib) = library(11);
    let held = HeldOut::new(11, 1);
    let plan = TrainingPlan { replay_rule: ReplayRule::Frontier, ..plan() };
    let full = train_variant(&plan, Variant::Full, 1, &mut lib, &held, &mut |_, _| {}).unwrap();
    assert_eq!(full.refreshes.len(), plan.phases as usize - 1);
    assert!(full.refreshes.iter().all(|r| r.frontier.is_some()), "{:?}", full.refreshes);
    let sac = TrainingPlan { algo: Algo::Sac, ..plan };
    let err = train_variant(&sac, Variant::Full, 1, &mut lib, &held, &mut |_, _| {}).unwrap_err();
    assert!(err.to_string().contains("frontier replay rule needs PPO"), "{err}");
}
