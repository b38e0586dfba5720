//! ONNX drivers against the reference tools: a model built with the official `onnx` package
//! drives `simulate` and `evaluate`; malformed ones exit 2 with the fault named; the model
//! `risktwin train` writes passes `onnx.checker` and runs in `onnxruntime`, which gives the
//! actions the twin gives from the policy file and from the model.

use crate::peer_python;
use risktwin_policy::HostPolicy;
use risktwin_policy::onnx::OnnxPolicy;
use std::path::Path;
use std::process::{Command, Output};
use std::sync::Arc;

const PACKAGES: [&str; 3] = ["onnx==1.23.2", "onnxruntime==1.31.1", "numpy==2.4.6"];

/// Writes driver models with the `onnx` helpers: `good.onnx` (24 → 16 tanh → 3, tanh head,
/// with the metadata), `bare.onnx` (the same without metadata), `nan.onnx` (its action divided
/// by zero), `narrow.onnx` (an observation of 10), `rate.onnx` (trained at 10 Hz).
const MAKE_MODELS: &str = r#"
import sys, numpy as np, onnx
from onnx import helper, TensorProto, numpy_helper
rng = np.random.default_rng(7)
def model(path, obs=24, head="Tanh", meta={"risktwin.observation_version": "1", "risktwin.decision_rate_hz": "20"}, divide=False):
    w0 = numpy_helper.from_array((rng.standard_normal((obs, 16)) * 0.3).astype(np.float32), "w0")
    b0 = numpy_helper.from_array(np.zeros(16, np.float32), "b0")
    w1 = numpy_helper.from_array((rng.standard_normal((16, 3)) * 0.3).astype(np.float32), "w1")
    zero = numpy_helper.from_array(np.zeros((), np.float32), "zero")
    nodes = [helper.make_node("MatMul", ["obs", "w0"], ["h0"]), helper.make_node("Add", ["h0", "b0"], ["h1"]),
             helper.make_node("Tanh", ["h1"], ["h2"]), helper.make_node("MatMul", ["h2", "w1"], ["m"]),
             helper.make_node(head, ["m"], ["a" if divide else "act"])]
    if divide:
        nodes.append(helper.make_node("Div", ["a", "zero"], ["act"]))
    graph = helper.make_graph(nodes, "driver",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, ["batch", obs])],
        [helper.make_tensor_value_info("act", TensorProto.FLOAT, ["batch", 3])], [w0, b0, w1, zero])
    m = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], producer_name="onnx-helper")
    m.ir_version = 8
    onnx.helper.set_model_props(m, meta)
    onnx.checker.check_model(m, full_check=True)
    onnx.save(m, path)
out = sys.argv[1]
model(out + "/good.onnx")
model(out + "/bare.onnx", meta={})
model(out + "/nan.onnx", divide=True)
model(out + "/narrow.onnx", obs=10)
model(out + "/rate.onnx", meta={"risktwin.observation_version": "1", "risktwin.decision_rate_hz": "10"})
"#;

/// Checks `risktwin train`'s model with `onnx.checker` and prints onnxruntime's actions for
/// the observations in argv[2] (JSON rows), the state carried for a recurrent model.
const RUN_ORT: &str = r#"
import json, sys, numpy as np, onnx, onnxruntime as ort
m = onnx.load(sys.argv[1])
onnx.checker.check_model(m, full_check=True)
meta = {p.key: p.value for p in m.metadata_props}
s = ort.InferenceSession(sys.argv[1], providers=["CPUExecutionProvider"])
names = [i.name for i in s.get_inputs()]
state = None if len(names) == 1 else np.zeros((1, s.get_inputs()[1].shape[1]), np.float32)
actions = []
for row in json.loads(sys.argv[2]):
    feed = {names[0]: np.array([row], np.float32)}
    if state is not None:
        feed[names[1]] = state
    outs = s.run(None, feed)
    if state is not None:
        state = outs[1]
    actions.append([float(v) for v in outs[0][0]])
print(json.dumps({"meta": meta, "actions": actions}))
"#;

fn risktwin(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_risktwin")).args(args).current_dir(dir).output().expect("risktwin runs")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

#[test]
fn models_from_the_onnx_package_drive_and_malformed_ones_exit_2_by_name() {
    let dir = tempfile::tempdir().expect("temp dir");
    let python = peer_python::python(&PACKAGES);
    let made = Command::new(&python).arg("-c").arg(MAKE_MODELS).arg(dir.path()).output().expect("python runs");
    assert!(made.status.success(), "the onnx helpers failed: {}", stderr(&made));

    let spec = r#"{"kind": "emergency-braking", "seed": 4, "params": {"ego_speed_mps": 20, "initial_headway_m": 30,
        "braking_decel_mps2": 5, "brake_time_s": 1, "friction_mu": 0.9}}"#;
    std::fs::write(dir.path().join("spec.json"), spec).expect("spec written");
    let sim =
        |model: &str| risktwin(dir.path(), &["simulate", "--spec", "spec.json", "--driver", model, "--format", "json"]);
    let good = sim("good.onnx");
    assert_eq!(good.status.code(), Some(0), "{}", stderr(&good));
    let metrics: serde_json::Value = serde_json::from_slice(&good.stdout).expect("one JSON document");
    assert!(metrics["steps"].as_u64().is_some_and(|s| s > 0), "{metrics}");
    assert!(stderr(&good).is_empty(), "no warning for a model with its metadata: {}", stderr(&good));
    let eval = risktwin(dir.path(), &["evaluate", "--driver", "good.onnx", "--per-kind", "2", "--format", "json"]);
    assert_eq!(eval.status.code(), Some(0), "{}", stderr(&eval));
    let doc: serde_json::Value = serde_json::from_slice(&eval.stdout).expect("one JSON document");
    assert_eq!(doc["overall"]["driver"]["episodes"], 10);
    assert_eq!(doc["model_faults"], 0);

    let bare = sim("bare.onnx");
    assert_eq!(bare.status.code(), Some(0), "{}", stderr(&bare));
    assert!(stderr(&bare).contains("warning: driver bare.onnx: the model does not say its observation version"));

    for (model, needle) in [
        ("nan.onnx", "the model's action is not finite at the load-time probe"),
        ("narrow.onnx", "observation input 'obs' is [batch, 10], the observation is [batch, 24]"),
        ("rate.onnx", "risktwin.decision_rate_hz = '10'"),
    ] {
        let out = sim(model);
        assert_eq!(out.status.code(), Some(2), "{model}: {}", stderr(&out));
        let line = stderr(&out);
        assert!(line.starts_with(&format!("error: driver {model}: ")) && line.contains(needle), "{model}: {line}");
    }
}

#[test]
fn trains_model_passes_the_checker_and_onnxruntime_gives_the_twins_actions() {
    let dir = tempfile::tempdir().expect("temp dir");
    let python = peer_python::python(&PACKAGES);
    for algo in ["ppo", "ppo-gru", "sac"] {
        let out =
            risktwin(dir.path(), &["train", "--algo", algo, "--steps", "2048", "--out", algo, "--format", "json"]);
        assert_eq!(out.status.code(), Some(0), "{}", stderr(&out));
        let model = dir.path().join(algo).join("policy.onnx");
        // Observations over the features' usual range, the state carried from row to row.
        let rows: Vec<[f32; 24]> =
            (0..20).map(|i| std::array::from_fn(|j| (((i * 24 + j) * 37 % 200) as f32 / 100.0) - 1.0)).collect();
        let rows_json = serde_json::to_string(&rows.iter().map(|r| r.to_vec()).collect::<Vec<_>>()).expect("JSON");
        let ran = Command::new(&python).arg("-c").arg(RUN_ORT).arg(&model).arg(&rows_json).output().expect("python");
        assert!(ran.status.success(), "{algo}: onnx/onnxruntime refused the model: {}", stderr(&ran));
        let doc: serde_json::Value = serde_json::from_slice(&ran.stdout).expect("one JSON line");
        assert_eq!(doc["meta"]["risktwin.observation_version"], "1");
        assert_eq!(doc["meta"]["risktwin.algo"], algo);
        let theirs: Vec<Vec<f64>> = serde_json::from_value(doc["actions"].clone()).expect("actions");
        // The twin's two readings of the same policy: the file by the host arithmetic, the
        // model by tract.
        let file = std::fs::read(dir.path().join(algo).join("policy.safetensors")).expect("the policy file");
        let host = Arc::new(HostPolicy::from_safetensors(&file).expect("the policy file loads"));
        let tract = Arc::new(OnnxPolicy::from_bytes(&std::fs::read(&model).expect("the model")).expect("it loads"));
        let (mut by_file, mut by_tract) = (host.actor(), tract.actor());
        let mut worst = 0.0f64;
        for (row, ort) in rows.iter().zip(&theirs) {
            for actions in [by_file(row), by_tract(row)] {
                worst = actions.iter().zip(ort).map(|(a, b)| (f64::from(*a) - b).abs()).fold(worst, f64::max);
            }
        }
        assert!(worst < 1e-4, "{algo}: onnxruntime and the twin's readings differ by {worst}");
    }
}
