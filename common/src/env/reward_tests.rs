//! Training-reward tests: the potential difference is exactly k·w_r·(R̄(s) − γ·R̄(s′)) step by
//! step, and the TTC term follows ln(TTC/4 s) below 4 s.

use super::*;
use crate::metrics::RewardWeights;
use crate::scenario::{ScenarioKind, check_feasible, sample};

/// Only the risk weight set: a step's reward is then the risk term alone.
fn risk_only_weights() -> RewardWeights {
    RewardWeights { progress: 0.0, velocity: 0.0, risk: 0.5, lane: 0.0, jerk: 0.0, collision: 0.0, offroad: 0.0 }
}

#[test]
fn the_potential_term_is_the_discounted_difference_of_the_footprint_risk() {
    let spec = (0..20).map(|i| sample(5, ScenarioKind::CutIn, i)).find(|s| check_feasible(s).is_ok()).expect("a spec");
    let w = risk_only_weights();
    let k = 2.0;
    let (mut o1, mut o2) = ([0.0; OBS_DIM], [0.0; OBS_DIM]);
    let mut per_step = DrivingEnv::new(&spec, TrainingReward::eq7(w), &mut o1);
    let potential = TrainingReward { weights: w, risk: RiskShaping::Potential { scale: k }, ttc: 0.0 };
    let mut shaped = DrivingEnv::new(&spec, potential, &mut o2);
    let dt = per_step.world().dt_s;
    let mut risk_before: Option<f64> = None;
    let mut risky_steps = 0;
    for _ in 0..120 {
        // The same action on both: the worlds stay identical; accelerate into the traffic ahead.
        let action = [0.0, 0.6, 0.0];
        let (a, b) = (per_step.step(&action, &mut o1), shaped.step(&action, &mut o2));
        // Per step the reward is −w_r·R̄·dt, so R̄ of the new state is read back from it.
        let risk_after = -a.reward / (w.risk * dt);
        assert!(risk_after >= 0.0, "{risk_after}");
        if let Some(before) = risk_before {
            let expected = k * w.risk * (before - SHAPING_GAMMA * risk_after);
            assert!((b.reward - expected).abs() < 1e-9, "{} vs {expected}", b.reward);
            risky_steps += usize::from(risk_after > 0.05);
        }
        risk_before = Some(risk_after);
        if a.done() {
            assert_eq!(a.done(), b.done());
            break;
        }
    }
    assert!(risky_steps > 5, "the drive met some risk: {risky_steps} steps");
}

#[test]
fn per_step_shaping_adds_no_potential_and_potential_shaping_moves_the_risk_weight_out_of_the_step() {
    let w = RewardWeights::default();
    let eq7 = TrainingReward::eq7(w);
    assert_eq!(eq7.potential_term(1.0, 0.0), 0.0);
    assert_eq!(eq7.step_weights(), w);
    let shaped = TrainingReward { risk: RiskShaping::Potential { scale: 1.0 }, ..eq7 };
    assert_eq!(shaped.step_weights().risk, 0.0);
    assert_eq!(shaped.step_weights().progress, w.progress);
    // Staying at risk R costs only (1 − γ)·k·w_r·R per step; leaving it earns back.
    assert!((shaped.potential_term(1.0, 1.0) - (1.0 - SHAPING_GAMMA) * w.risk).abs() < 1e-12);
    assert!(shaped.potential_term(1.0, 0.0) > 0.0 && shaped.potential_term(0.0, 1.0) < 0.0);
    assert!(RiskShaping::Potential { scale: 0.0 }.validate().is_err());
    assert!(RiskShaping::Potential { scale: f64::NAN }.validate().is_err());
    assert!(RiskShaping::default().validate().is_ok());
}

#[test]
fn the_ttc_term_is_the_log_ratio_to_four_seconds_below_four_seconds() {
    let r = Variant::Ttc.training_reward(RiskShaping::default());
    assert_eq!(r.ttc, TTC_WEIGHT);
    assert_eq!(r.weights.risk, 0.0, "the TTC baseline has no risk-field term");
    let dt = 0.1;
    assert!((r.ttc_term(1.0, dt) - TTC_WEIGHT * 0.25f64.ln() * dt).abs() < 1e-12);
    assert_eq!(r.ttc_term(TTC_THRESHOLD_S, dt), 0.0);
    assert_eq!(r.ttc_term(f64::INFINITY, dt), 0.0);
    assert_eq!(r.ttc_term(f64::NAN, dt), 0.0);
    assert_eq!(r.ttc_term(0.0, dt), r.ttc_term(TTC_FLOOR_S, dt), "a contact is floored, not −∞");
    assert_eq!(Variant::Base.training_reward(RiskShaping::default()).ttc_term(1.0, dt), 0.0);
}

#[test]
fn closing_on_a_braking_lead_costs_the_ttc_variant_and_not_base() {
    let spec = super::tests::spec(
        ScenarioKind::EmergencyBraking,
        &[
            ("ego_speed_mps", 20.0),
            ("initial_headway_m", 25.0),
            ("braking_decel_mps2", 6.0),
            ("brake_time_s", 0.5),
            ("friction_mu", 1.0),
        ],
    );
    let (mut o1, mut o2) = ([0.0; OBS_DIM], [0.0; OBS_DIM]);
    let shaping = RiskShaping::default();
    let mut base = DrivingEnv::new(&spec, Variant::Base.training_reward(shaping), &mut o1);
    let mut ttc = DrivingEnv::new(&spec, Variant::Ttc.training_reward(shaping), &mut o2);
    let (mut gap_sum, mut steps) = (0.0, 0);
    loop {
        let (a, b) = (base.step(&[0.0, 0.3, 0.0], &mut o1), ttc.step(&[0.0, 0.3, 0.0], &mut o2));
        assert!(b.reward <= a.reward + 1e-12, "the TTC term only subtracts");
        gap_sum += a.reward - b.reward;
        steps += 1;
        if a.done() || steps > 400 {
            break;
        }
    }
    assert!(gap_sum > 0.5, "closing under 4 s of TTC was penalised: {gap_sum}");
}
