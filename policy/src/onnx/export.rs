//! A host policy written as an ONNX model (what `risktwin train` puts beside the policy file):
//! the same network in standard operators, its output already the action in [−1, 1].
//!
//! - Input `observation`, float32 [batch, OBS_DIM] (batch a named, dynamic dimension).
//! - Feed-forward: `MatMul`, `Add` and `Tanh` per layer; the head is `Clip(−1, 1)` of the mean
//!   (PPO) or `Tanh` of the mean (SAC: only the mean half of the last layer is written, the
//!   log σ half is not an action).
//! - Recurrent (`ppo-gru`): a second input `state` [batch, h] and a second output `state_out`,
//!   the GRU step in `MatMul`/`Add`/`Sigmoid`/`Tanh`/`Mul`/`Sub` (gate order r, z, n; the
//!   candidate's state term gated after its bias, as the host cell), the mean network after it.
//! - Output `action`, float32 [batch, ACT_DIM].
//! - `metadata_props`: [`super::OBSERVATION_VERSION_KEY`], [`super::DECISION_RATE_KEY`],
//!   `risktwin.algo` and `risktwin.hidden`.
//!
//! The graph is built in a fixed order, so the same policy gives the same bytes.

use super::{DECISION_RATE_KEY, OBSERVATION_VERSION_KEY};
use crate::{Dense, HostGru, HostPolicy, PolicyKind};
use prost::Message;
use risktwin_common::env::{ACT_DIM, OBS_DIM, OBSERVATION_VERSION};
use risktwin_common::world::DECISION_RATE_HZ;
use tract_onnx::pb;

/// ONNX IR version and default-domain opset the models are written in (IR 8 is opset 17's).
const IR_VERSION: i64 = 8;
const OPSET: i64 = 17;

/// A graph under construction: nodes and initializers in the order they are added.
#[derive(Default)]
pub(super) struct Graph {
    nodes: Vec<pb::NodeProto>,
    initializers: Vec<pb::TensorProto>,
}

impl Graph {
    /// Adds `op(inputs)` and returns its output's name.
    pub(super) fn op(&mut self, op: &str, inputs: &[&str], output: String) -> String {
        self.nodes.push(pb::NodeProto {
            input: inputs.iter().map(|s| (*s).to_owned()).collect(),
            output: vec![output.clone()],
            name: output.clone(),
            op_type: op.to_owned(),
            ..Default::default()
        });
        output
    }

    /// Adds a float32 constant of `dims` and returns its name.
    pub(super) fn constant(&mut self, name: String, dims: &[usize], values: &[f32]) -> String {
        self.initializers.push(pb::TensorProto {
            dims: dims.iter().map(|&d| d as i64).collect(),
            data_type: pb::tensor_proto::DataType::Float as i32,
            name: name.clone(),
            raw_data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
            ..Default::default()
        });
        name
    }

    /// `x`·W + b for the columns `cols` of a dense layer.
    fn affine(&mut self, x: &str, layer: &Dense, cols: std::ops::Range<usize>, name: &str) -> String {
        let n_out = layer.n_out();
        let w: Vec<f32> = layer.weight().chunks_exact(n_out).flat_map(|row| &row[cols.clone()]).copied().collect();
        let w = self.constant(format!("{name}.weight"), &[layer.n_in(), cols.len()], &w);
        let b = self.constant(format!("{name}.bias"), &[cols.len()], &layer.bias()[cols]);
        let xw = self.op("MatMul", &[x, &w], format!("{name}.matmul"));
        self.op("Add", &[&xw, &b], format!("{name}.out"))
    }

    /// The GRU step from `obs` and `state`; returns the new state's name.
    fn gru(&mut self, cell: &HostGru, obs: &str, state: &str) -> String {
        let (x, h) = cell.maps();
        let n = cell.hidden();
        let gate = |g: &mut Self, i: usize, name: &str| {
            let gx = g.affine(obs, x, i * n..(i + 1) * n, &format!("gru.{name}.x"));
            let gh = g.affine(state, h, i * n..(i + 1) * n, &format!("gru.{name}.h"));
            (gx, gh)
        };
        let (rx, rh) = gate(self, 0, "r");
        let r_sum = self.op("Add", &[&rx, &rh], "gru.r.sum".into());
        let r = self.op("Sigmoid", &[&r_sum], "gru.r".into());
        let (zx, zh) = gate(self, 1, "z");
        let z_sum = self.op("Add", &[&zx, &zh], "gru.z.sum".into());
        let z = self.op("Sigmoid", &[&z_sum], "gru.z".into());
        let (nx, nh) = gate(self, 2, "n");
        let gated = self.op("Mul", &[&r, &nh], "gru.n.gated".into());
        let n_sum = self.op("Add", &[&nx, &gated], "gru.n.sum".into());
        let cand = self.op("Tanh", &[&n_sum], "gru.n".into());
        // h′ = n + z⊙(h − n)
        let diff = self.op("Sub", &[state, &cand], "gru.diff".into());
        let keep = self.op("Mul", &[&z, &diff], "gru.keep".into());
        self.op("Add", &[&cand, &keep], STATE_OUT.into())
    }
}

/// Names of the model's inputs and outputs.
pub(super) const OBSERVATION: &str = "observation";
pub(super) const STATE: &str = "state";
pub(super) const ACTION: &str = "action";
pub(super) const STATE_OUT: &str = "state_out";

/// A float32 [batch, width] value.
pub(super) fn value(name: &str, width: usize) -> pb::ValueInfoProto {
    use pb::tensor_shape_proto::{Dimension, dimension::Value};
    let dim = |value| Dimension { value: Some(value), ..Default::default() };
    let shape =
        pb::TensorShapeProto { dim: vec![dim(Value::DimParam("batch".into())), dim(Value::DimValue(width as i64))] };
    let tensor = pb::type_proto::Tensor { elem_type: pb::tensor_proto::DataType::Float as i32, shape: Some(shape) };
    pb::ValueInfoProto {
        name: name.to_owned(),
        r#type: Some(pb::TypeProto { value: Some(pb::type_proto::Value::TensorType(tensor)), ..Default::default() }),
        ..Default::default()
    }
}

/// The model of graph `g` with these interface values and metadata.
pub(super) fn model(
    g: Graph,
    input: Vec<pb::ValueInfoProto>,
    output: Vec<pb::ValueInfoProto>,
    meta: &[(&str, String)],
) -> pb::ModelProto {
    pb::ModelProto {
        ir_version: IR_VERSION,
        opset_import: vec![pb::OperatorSetIdProto { domain: String::new(), version: OPSET }],
        producer_name: "risktwin".into(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        graph: Some(pb::GraphProto {
            node: g.nodes,
            name: "risktwin-driver".into(),
            initializer: g.initializers,
            input,
            output,
            ..Default::default()
        }),
        metadata_props: meta
            .iter()
            .map(|(key, value)| pb::StringStringEntryProto { key: (*key).to_owned(), value: value.clone() })
            .collect(),
        ..Default::default()
    }
}

impl HostPolicy {
    /// The policy as an ONNX model (module docs), the same function as
    /// [`HostPolicy::act_deterministic`] up to the operators' float rounding.
    pub fn to_onnx(&self) -> Vec<u8> {
        let mut g = Graph::default();
        let mut inputs = vec![value(OBSERVATION, OBS_DIM)];
        let mut outputs = vec![value(ACTION, ACT_DIM)];
        let mut x = OBSERVATION.to_owned();
        if let Some(cell) = self.gru() {
            inputs.push(value(STATE, cell.hidden()));
            outputs.push(value(STATE_OUT, cell.hidden()));
            x = g.gru(cell, OBSERVATION, STATE);
        }
        let layers = self.net().layers();
        for (i, layer) in layers.iter().enumerate() {
            let name = format!("actor.{i}");
            if i + 1 < layers.len() {
                let y = g.affine(&x, layer, 0..layer.n_out(), &name);
                x = g.op("Tanh", &[&y], format!("{name}.tanh"));
            } else {
                // SAC's last layer gives mean then log σ: the action is tanh of the mean.
                let mean = g.affine(&x, layer, 0..ACT_DIM, &name);
                x = match self.kind() {
                    PolicyKind::Squashed => g.op("Tanh", &[&mean], ACTION.into()),
                    PolicyKind::Gaussian | PolicyKind::Recurrent => {
                        let lo = g.constant("clip.min".into(), &[], &[-1.0]);
                        let hi = g.constant("clip.max".into(), &[], &[1.0]);
                        g.op("Clip", &[&mean, &lo, &hi], ACTION.into())
                    }
                };
            }
        }
        let mut hidden: Vec<String> = self.gru().map(|c| c.hidden().to_string()).into_iter().collect();
        hidden.extend(layers.iter().take(layers.len() - 1).map(|l| l.n_out().to_string()));
        let meta = [
            (OBSERVATION_VERSION_KEY, OBSERVATION_VERSION.to_string()),
            (DECISION_RATE_KEY, DECISION_RATE_HZ.to_string()),
            ("risktwin.algo", self.kind().algo().to_owned()),
            ("risktwin.hidden", hidden.join(",")),
        ];
        model(g, inputs, outputs, &meta).encode_to_vec()
    }
}
