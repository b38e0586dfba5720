//! ONNX models: a host policy of every kind exported and run by tract acts as the host does,
//! and every kind of model that does not fit is refused at load with its reason.

use super::export::{Graph, model, value};
use super::*;
use crate::{HostPolicy, PolicyKind, random_policy};
use risktwin_common::rng::Rng;

const KINDS: [PolicyKind; 3] = [PolicyKind::Gaussian, PolicyKind::Squashed, PolicyKind::Recurrent];

/// Largest action difference between the host and tract over an episode-like sequence: the
/// operators round differently (tract's tanh and sigmoid against the host's), by a few ULP.
const ACTION_TOLERANCE: f32 = 1e-4;

fn observations(seed: u64, n: usize) -> Vec<[f32; OBS_DIM]> {
    let mut rng = Rng::new(seed);
    (0..n).map(|_| std::array::from_fn(|_| rng.uniform(-1.5, 1.5) as f32)).collect()
}

#[test]
fn an_exported_policy_acts_as_the_host_policy_for_every_kind() {
    for kind in KINDS {
        // Output biases large enough that some actions clip.
        let host = random_policy(kind, 3, &vec![0.9; kind.out_dim()]);
        let bytes = host.to_onnx();
        assert_eq!(bytes, host.to_onnx(), "{kind:?}: the same bytes twice");
        let onnx = Arc::new(OnnxPolicy::from_bytes(&bytes).expect("an exported model loads"));
        assert!(onnx.warnings().is_empty(), "{:?}", onnx.warnings());
        assert_eq!(onnx.recurrent(), kind == PolicyKind::Recurrent);
        let (mut ours, mut memory) = (onnx.actor(), host.memory());
        let mut worst = 0.0f32;
        for obs in observations(4, 200) {
            let (a, b) = (ours(&obs), host.act_deterministic(&obs, &mut memory));
            worst = a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(worst, f32::max);
            assert!(a.iter().all(|v| (-1.0..=1.0).contains(v)), "{kind:?}: {a:?}");
        }
        assert!(worst < ACTION_TOLERANCE, "{kind:?}: actions differ by up to {worst}");
        assert_eq!(onnx.faults(), 0);
    }
}

#[test]
fn a_new_actor_starts_from_a_zero_state() {
    let host = random_policy(PolicyKind::Recurrent, 5, &[0.0; 3]);
    let onnx = Arc::new(OnnxPolicy::from_bytes(&host.to_onnx()).expect("loads"));
    let obs = observations(6, 20);
    let run = || {
        let mut actor = onnx.actor();
        obs.iter().map(&mut actor).collect::<Vec<_>>()
    };
    assert_eq!(run(), run(), "a new actor starts over");
    // The same observation twice: a different action the second time, as the state moved on.
    let mut actor = onnx.actor();
    let (once, twice) = (actor(&obs[0]), actor(&obs[0]));
    assert_ne!(once, twice, "the state carries from step to step");
}

/// The exported model of a PPO policy, changed by `edit`.
fn edited(edit: impl FnOnce(&mut pb::ModelProto)) -> Vec<u8> {
    let bytes = random_policy(PolicyKind::Gaussian, 7, &[0.0; 3]).to_onnx();
    let mut proto = pb::ModelProto::decode(bytes.as_slice()).expect("decodes");
    edit(&mut proto);
    proto.encode_to_vec()
}

fn refusal(bytes: &[u8]) -> String {
    OnnxPolicy::from_bytes(bytes).expect_err("refused").to_string()
}

#[test]
fn models_that_do_not_fit_are_refused_with_the_reason() {
    let good = random_policy(PolicyKind::Gaussian, 7, &[0.0; 3]).to_onnx();
    assert!(refusal(&good[..good.len() / 2]).starts_with("not an ONNX model"), "truncated");
    assert_eq!(refusal(b""), "not an ONNX model: no graph");
    assert!(refusal(b"\xff\xff\xff\xff").starts_with("not an ONNX model"));

    let meta = |key: &'static str, v: &str| {
        let v = v.to_owned();
        edited(move |p| p.metadata_props.iter_mut().filter(|m| m.key == key).for_each(|m| m.value = v.clone()))
    };
    assert_eq!(
        refusal(&meta(OBSERVATION_VERSION_KEY, "2")),
        "model metadata has risktwin.observation_version = '2', this build's drivers use 1"
    );
    assert_eq!(
        refusal(&meta(DECISION_RATE_KEY, "10")),
        "model metadata has risktwin.decision_rate_hz = '10', this build's drivers use 20 Hz"
    );

    let nan_weight = edited(|p| {
        let w = &mut p.graph.as_mut().expect("graph").initializer[0];
        w.raw_data[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    });
    assert_eq!(refusal(&nan_weight), "weight 'actor.0.weight' has a non-finite value at index 1");

    let narrow = edited(|p| {
        let g = p.graph.as_mut().expect("graph");
        g.input[0] = value("obs", 10);
    });
    assert_eq!(refusal(&narrow), "observation input 'obs' is [batch, 10], the observation is [batch, 24]");

    let unknown_op = edited(|p| p.graph.as_mut().expect("graph").node[0].op_type = "NoSuchOp".into());
    assert!(refusal(&unknown_op).starts_with("tract cannot run the model"), "{}", refusal(&unknown_op));

    let too_wide = edited(|p| {
        let g = p.graph.as_mut().expect("graph");
        g.input.push(value("state", MAX_STATE_WIDTH + 1));
        g.output.push(value("state_out", MAX_STATE_WIDTH + 1));
    });
    assert!(
        refusal(&too_wide).contains(&format!("its width must be fixed, from 1 to {MAX_STATE_WIDTH}")),
        "{}",
        refusal(&too_wide)
    );
    // An output no node gives: tract panics on it, and the panic is the model's fault.
    let dangling = edited(|p| p.graph.as_mut().expect("graph").output[0].name = "nowhere".into());
    let why = refusal(&dangling);
    assert!(why.starts_with("tract cannot run the model: tract failed on the graph (it panicked: "), "{why}");
    let nan_constant = edited(|p| {
        let g = p.graph.as_mut().expect("graph");
        let t = pb::TensorProto {
            data_type: 11,
            dims: vec![2],
            double_data: vec![1.0, f64::INFINITY],
            name: "k".into(),
            ..Default::default()
        };
        let attribute = vec![pb::AttributeProto { name: "value".into(), t: Some(t), r#type: 4, ..Default::default() }];
        g.node.push(pb::NodeProto {
            op_type: "Constant".into(),
            output: vec!["k".into()],
            attribute,
            ..Default::default()
        });
    });
    assert_eq!(refusal(&nan_constant), "weight 'k' has a non-finite value at index 1");

    let two_outputs = edited(|p| {
        let g = p.graph.as_mut().expect("graph");
        g.output.push(value("extra", 3));
    });
    assert_eq!(
        refusal(&two_outputs),
        "the model has 1 inputs and 2 outputs: a driver has one of each (observation → action), or two (and its state)"
    );
}

/// A model `observation → observation·W` with W all `w` and `out` outputs, then `head`: an op
/// of the product (and of a constant, when given: e.g. `Div` by zero).
fn linear(out: usize, w: f32, head: Option<(&str, Option<f32>)>, meta: &[(&str, String)]) -> Vec<u8> {
    let mut g = Graph::default();
    let w = g.constant("w".into(), &[OBS_DIM, out], &vec![w; OBS_DIM * out]);
    let last = if head.is_some() { "product" } else { "action" };
    let y = g.op("MatMul", &["observation", &w], last.into());
    if let Some((op, c)) = head {
        let mut inputs = vec![y];
        inputs.extend(c.map(|c| g.constant("c".into(), &[], &[c])));
        g.op(op, &inputs.iter().map(String::as_str).collect::<Vec<_>>(), "action".into());
    }
    model(g, vec![value("observation", OBS_DIM)], vec![value("action", out)], meta).encode_to_vec()
}

#[test]
fn wrong_action_width_nan_outputs_and_missing_metadata_are_found_at_load() {
    let current =
        [(OBSERVATION_VERSION_KEY, OBSERVATION_VERSION.to_string()), (DECISION_RATE_KEY, DECISION_RATE_HZ.to_string())];
    assert!(OnnxPolicy::from_bytes(&linear(3, 0.01, None, &current)).expect("fits").warnings().is_empty());
    let wide = refusal(&linear(5, 0.01, None, &current));
    assert!(wide.starts_with("output 0 (action) is") && wide.ends_with("expected float32 [1, 3]"), "{wide}");
    // 0 / 0 at the zero observation: finite weights, NaN out.
    assert_eq!(
        refusal(&linear(3, 0.01, Some(("Div", Some(0.0))), &current)),
        format!("the model's action is not finite at the load-time probe (observation 1 of {PROBE_STEPS})")
    );
    // √ of the product: 0 at the zero observation, NaN at the first with a negative sum.
    let later = refusal(&linear(3, 0.01, Some(("Sqrt", None)), &current));
    assert!(later.starts_with("the model's action is not finite") && !later.contains("observation 1 of"), "{later}");
    let bare = OnnxPolicy::from_bytes(&linear(3, 0.01, None, &[])).expect("loads without metadata");
    assert_eq!(bare.warnings().len(), 2, "{:?}", bare.warnings());
    assert!(bare.warnings()[0].contains("taken as 1") && bare.warnings()[1].contains("taken as 20 Hz"));
}

#[test]
fn a_host_policy_from_a_file_exports_the_same_model() {
    // The ONNX model does not depend on whether the policy came from training or its file.
    let host = random_policy(PolicyKind::Squashed, 9, &[0.2; 6]);
    let back = HostPolicy::from_safetensors(&host.to_safetensors().expect("bytes")).expect("read");
    assert_eq!(back.to_onnx(), host.to_onnx());
}

#[test]
fn a_decision_that_is_not_finite_at_run_time_drives_as_the_zero_action_and_is_counted() {
    // √(observation·W + ½): finite over the probe's range (|Σ| ≤ 0.36), NaN far outside it.
    let mut g = Graph::default();
    let w = g.constant("w".into(), &[OBS_DIM, 3], &[0.01; OBS_DIM * 3]);
    let half = g.constant("half".into(), &[], &[0.5]);
    let product = g.op("MatMul", &["observation", &w], "product".into());
    let shifted = g.op("Add", &[&product, &half], "shifted".into());
    g.op("Sqrt", &[&shifted], "action".into());
    let meta =
        [(OBSERVATION_VERSION_KEY, OBSERVATION_VERSION.to_string()), (DECISION_RATE_KEY, DECISION_RATE_HZ.to_string())];
    let bytes = model(g, vec![value("observation", OBS_DIM)], vec![value("action", 3)], &meta).encode_to_vec();
    let onnx = Arc::new(OnnxPolicy::from_bytes(&bytes).expect("passes its probe"));
    let mut actor = onnx.actor();
    assert!(actor(&[0.0; OBS_DIM]).iter().all(|&a| (a - 0.5f32.sqrt()).abs() < 1e-6));
    assert_eq!(onnx.faults(), 0);
    assert_eq!(actor(&[-10.0; OBS_DIM]), [0.0; 3], "a NaN decision drives as the zero action");
    assert_eq!(actor(&[-10.0; OBS_DIM]), [0.0; 3]);
    assert_eq!(onnx.faults(), 2, "each counted");
    assert!(actor(&[0.0; OBS_DIM])[0] > 0.0, "the next finite decision drives");
}
