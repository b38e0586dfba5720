//! Policy files: round trip, every kind of bad file refused with its typed error, and a
//! policy read from a file driving a world through the training environment's mapping.

use super::*;
use crate::random_policy as policy;
use risktwin_common::episode::{self, with_reference_driver};
use risktwin_common::metrics::RewardWeights;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioKind, check_feasible, sample};
use std::sync::Arc;

/// A policy file with one tensor or metadata entry changed (an empty value removes the entry).
fn altered(p: &HostPolicy, meta: &[(&str, &str)], tensor: Option<(&str, Dtype, Vec<usize>, Vec<u8>)>) -> Vec<u8> {
    let bytes = p.to_safetensors().expect("serialised");
    let st = SafeTensors::deserialize(&bytes).expect("parsed");
    let mut tensors: Vec<(String, Dtype, Vec<usize>, Vec<u8>)> =
        st.iter().map(|(n, v)| (n.to_owned(), v.dtype(), v.shape().to_vec(), v.data().to_vec())).collect();
    if let Some((name, dtype, shape, data)) = tensor {
        tensors.retain(|t| t.0 != name);
        if !data.is_empty() {
            tensors.push((name.to_owned(), dtype, shape, data));
        }
    }
    let mut m = metadata(p.kind().algo(), &[8]);
    for (k, v) in meta {
        match *v {
            "" => m.remove(*k),
            _ => m.insert((*k).to_owned(), (*v).to_owned()),
        };
    }
    let views: Vec<(&str, TensorView<'_>)> =
        tensors.iter().map(|(n, d, s, b)| (n.as_str(), TensorView::new(*d, s.clone(), b).expect("a view"))).collect();
    safetensors::serialize(views, Some(m)).expect("serialised")
}

#[test]
fn a_policy_file_round_trips_for_every_kind() {
    for kind in [PolicyKind::Gaussian, PolicyKind::Squashed, PolicyKind::Recurrent] {
        let p = policy(kind, 1, &vec![0.1; kind.out_dim()]);
        let back = HostPolicy::from_safetensors(&p.to_safetensors().expect("bytes")).expect("read back");
        assert_eq!(back, p);
        let meta = read_meta(&p.to_safetensors().expect("bytes")).expect("metadata");
        assert_eq!(meta, PolicyMeta { algo: kind.algo().to_owned(), hidden: vec![8] });
    }
}

#[test]
fn bad_policy_files_are_refused_with_their_reason() {
    let p = policy(PolicyKind::Gaussian, 2, &[0.0; ACT_DIM]);
    let f32s = |v: &[f32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
    let cases: Vec<(Vec<u8>, &str)> = vec![
        (b"\x05\0\0\0\0\0\0\0{}".to_vec(), "not-safetensors"),
        (vec![0xff; 4], "not-safetensors"),
        (altered(&p, &[("obs_dim", "13")], None), "wrong-dims"),
        (altered(&p, &[("act_dim", "2")], None), "wrong-dims"),
        (altered(&p, &[("version", "9")], None), "bad-metadata"),
        (altered(&p, &[("hidden", "8,x")], None), "bad-metadata"),
        (altered(&p, &[("hidden", "16")], None), "bad-tensor"),
        (altered(&p, &[("algo", "dqn")], None), "unsupported-algo"),
        // A feed-forward file said to be recurrent: its first layer is not the GRU state's.
        (altered(&p, &[("algo", "ppo-gru")], None), "bad-tensor"),
        (altered(&p, &[("algo", "sac")], None), "missing-tensor"),
        (altered(&p, &[], Some(("actor.mean.1.bias", Dtype::F32, vec![1, 3], Vec::new()))), "missing-tensor"),
        (altered(&p, &[], Some(("actor.mean.1.bias", Dtype::F32, vec![3], f32s(&[0.0; 3])))), "bad-tensor"),
        (altered(&p, &[], Some(("actor.mean.1.bias", Dtype::F64, vec![1, 3], vec![0; 24]))), "bad-tensor"),
        (
            altered(&p, &[], Some(("actor.mean.1.bias", Dtype::F32, vec![1, 3], f32s(&[0.0, f32::NAN, 0.0])))),
            "non-finite",
        ),
    ];
    for (i, (bytes, reason)) in cases.iter().enumerate() {
        match HostPolicy::from_safetensors(bytes) {
            Ok(_) => panic!("case {i} accepted"),
            Err(e) => assert_eq!(e.reason(), *reason, "case {i}: {e}"),
        }
    }
    let gru = policy(PolicyKind::Recurrent, 2, &[0.0; ACT_DIM]);
    let cases = [
        (altered(&gru, &[], Some(("actor.gru.w_h", Dtype::F32, vec![8, 24], Vec::new()))), "missing-tensor"),
        (altered(&gru, &[], Some(("actor.gru.b_x", Dtype::F32, vec![1, 23], f32s(&[0.0; 23])))), "bad-tensor"),
        (altered(&gru, &[("hidden", "8,4")], None), "bad-tensor"),
    ];
    for (i, (bytes, reason)) in cases.iter().enumerate() {
        match HostPolicy::from_safetensors(bytes) {
            Ok(_) => panic!("recurrent case {i} accepted"),
            Err(e) => assert_eq!(e.reason(), *reason, "recurrent case {i}: {e}"),
        }
    }
    let Err(e) = HostPolicy::from_safetensors(&altered(&p, &[("obs_dim", "13")], None)) else { panic!("accepted") };
    assert_eq!(e, NetError::Dimension { name: "obs_dim", found: "13".into(), expected: OBS_DIM });
}

#[test]
fn the_decision_rate_is_written_checked_and_absent_means_20_hz() {
    let p = policy(PolicyKind::Squashed, 4, &[0.0; 2 * ACT_DIM]);
    let bytes = p.to_safetensors().expect("bytes");
    let (_, header) = SafeTensors::read_metadata(&bytes).expect("a header");
    assert_eq!(header.metadata().as_ref().and_then(|m| m.get("decision_rate_hz")).map(String::as_str), Some("20"));
    for other in ["50", "10", "fast", ""] {
        let file = altered(&p, &[("decision_rate_hz", other)], None);
        match (other, HostPolicy::from_safetensors(&file)) {
            // No field: a file from before it, read as 20 Hz.
            ("", read) => assert_eq!(read.expect("an older file is accepted"), p),
            (_, Ok(_)) => panic!("a {other} Hz file accepted"),
            (_, Err(e)) => {
                assert_eq!(e.reason(), "wrong-decision-rate");
                let text = e.to_string();
                assert!(text.contains(&format!("{other} Hz")) && text.contains("20 Hz"), "{text}");
            }
        }
    }
}

#[test]
fn a_braking_policy_from_a_file_drives_the_world_through_the_env_mapping() {
    let spec = (0..1000).map(|i| sample(3, ScenarioKind::CutIn, i)).find(|s| check_feasible(s).is_ok());
    let spec = spec.expect("a feasible cut-in");
    let weights = RewardWeights::default();
    let (mut world, mut reference) = with_reference_driver(&spec);
    let by_reference = episode::run(&mut world, &mut reference, &weights).metrics;

    // Large output biases dominate the small random weights: full brake (a₂ = 1), no throttle.
    let brake = policy(PolicyKind::Gaussian, 3, &[0.0, -5.0, 5.0]);
    let brake = Arc::new(HostPolicy::from_safetensors(&brake.to_safetensors().expect("bytes")).expect("read"));
    let (mut world, _) = with_reference_driver(&spec);
    let mut driver = crate::model::DriverModel::Native(brake).driver(world.desired_speed_mps, world.dt_s);
    let v0 = world.ego.state.speed_mps;
    let by_policy = episode::run(&mut world, &mut driver, &weights).metrics;
    assert!(world.ego.state.speed_mps < 0.1, "braked to a stop from {v0} m/s: {}", world.ego.state.speed_mps);
    assert!(
        by_policy.avg_speed_mps < 0.5 * by_reference.avg_speed_mps,
        "{} vs reference {}",
        by_policy.avg_speed_mps,
        by_reference.avg_speed_mps
    );
}

/// The recurrent policy remembers: the same observation gives another action after a history,
/// and a fresh memory starts over.
#[test]
fn a_recurrent_policy_acts_on_its_history_and_a_fresh_memory_starts_over() {
    let p = policy(PolicyKind::Recurrent, 5, &[0.0; ACT_DIM]);
    let mut rng = Rng::new(6);
    let obs: Vec<[f32; OBS_DIM]> = (0..20).map(|_| std::array::from_fn(|_| rng.uniform(-1.0, 1.0) as f32)).collect();
    let mut memory = p.memory();
    let first = p.act_deterministic(&obs[0], &mut memory);
    for o in &obs[1..] {
        p.act_deterministic(o, &mut memory);
    }
    let after_history = p.act_deterministic(&obs[0], &mut memory);
    assert_ne!(first, after_history, "the state carried nothing");
    assert_eq!(p.act_deterministic(&obs[0], &mut p.memory()), first);
}
