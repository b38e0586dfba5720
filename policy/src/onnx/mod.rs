//! ONNX models as drivers, run natively with tract (pure Rust: nothing to install beside the
//! binary). tract picks its kernels by CPU feature at run time, so results are the same run
//! after run on one machine, and may differ in the last bits between machines.
//!
//! A driver model maps the observation (float32 [batch, OBS_DIM], batch 1 or dynamic) to the
//! three actions (float32 [batch, ACT_DIM], in [−1, 1]; outside is clamped, as for every
//! driver). A recurrent model has a second input, its state [batch, h], and a second output,
//! the next state, of the same shape: the state starts at zero each episode and is carried from
//! step to step. Inputs and outputs are taken by position, their names are free.
//!
//! `metadata_props` may carry [`OBSERVATION_VERSION_KEY`] and [`DECISION_RATE_KEY`]; a model
//! of another observation version or rate is refused, one without them is taken as the current
//! version and rate with a warning. At load the whole model is checked — it decodes, its
//! interface fits, its weights are finite, tract can run it, and a probe of
//! [`PROBE_STEPS`] observations gives finite outputs — so a model that does not fit is refused
//! before any episode, never mid-way.

mod export;

use export::{ACTION, STATE_OUT};
use prost::Message;
use risktwin_common::env::{ACT_DIM, OBS_DIM, OBSERVATION_VERSION};
use risktwin_common::world::DECISION_RATE_HZ;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use tract_onnx::pb;
use tract_onnx::prelude::*;
use tract_onnx::tract_hir::internal::{bail, format_err};

/// `metadata_props` key of the observation contract's version the model was trained on.
pub const OBSERVATION_VERSION_KEY: &str = "risktwin.observation_version";
/// `metadata_props` key of the decisions per second the model was trained at.
pub const DECISION_RATE_KEY: &str = "risktwin.decision_rate_hz";
/// Observations the load-time probe feeds the model (state carried): zeros, then a fixed
/// pseudo-random sequence over [−1.5, 1.5] per feature.
pub const PROBE_STEPS: usize = 32;
/// The widest recurrent state a driver model may declare (a GRU or LSTM of a driving policy is
/// tens to hundreds wide); a wider one is refused before any of it is allocated.
pub const MAX_STATE_WIDTH: usize = 1 << 16;

/// Why an ONNX model was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OnnxError {
    #[error("not an ONNX model: {0}")]
    Decode(String),
    #[error("model metadata has {key} = '{found}', this build's drivers use {expected}")]
    Metadata { key: &'static str, found: String, expected: String },
    #[error("{0}")]
    Interface(String),
    #[error("weight '{name}' has a non-finite value at index {index}")]
    NonFiniteWeight { name: String, index: usize },
    #[error("tract cannot run the model: {0}")]
    Unsupported(String),
    #[error("the model's {output} is not finite at the load-time probe (observation {step} of {PROBE_STEPS})")]
    Probe { output: &'static str, step: usize },
}

/// A checked ONNX driver model, ready to act.
#[derive(Debug)]
pub struct OnnxPolicy {
    plan: Arc<TypedRunnableModel>,
    /// Width of the recurrent state (`None` for a feed-forward model).
    state_width: Option<usize>,
    /// What the load found worth saying (missing metadata).
    warnings: Vec<String>,
    /// Steps whose inference failed or gave a non-finite action (taken as 0 then).
    faults: AtomicU64,
}

/// A float32 [batch, width] interface value's declared width, if the model declares one.
fn declared(value: &pb::ValueInfoProto) -> Result<(Option<usize>, Vec<String>), OnnxError> {
    use pb::tensor_shape_proto::dimension::Value;
    let Some(pb::type_proto::Value::TensorType(t)) = value.r#type.as_ref().and_then(|t| t.value.as_ref()) else {
        return Err(OnnxError::Interface(format!("'{}' is not a tensor", value.name)));
    };
    if t.elem_type != pb::tensor_proto::DataType::Float as i32 {
        return Err(OnnxError::Interface(format!("'{}' is not float32 (ONNX type {})", value.name, t.elem_type)));
    }
    let Some(shape) = &t.shape else { return Ok((None, Vec::new())) };
    let dims: Vec<String> = shape
        .dim
        .iter()
        .map(|d| match &d.value {
            Some(Value::DimValue(v)) => v.to_string(),
            Some(Value::DimParam(p)) => p.clone(),
            None => "?".to_owned(),
        })
        .collect();
    let width = match shape.dim.as_slice() {
        [batch, width] => {
            if matches!(batch.value, Some(Value::DimValue(b)) if b != 1) {
                return Err(OnnxError::Interface(format!(
                    "'{}' has batch {}, a driver steps one at a time",
                    value.name, dims[0]
                )));
            }
            match width.value {
                Some(Value::DimValue(w)) => usize::try_from(w).ok(),
                _ => None,
            }
        }
        _ => {
            return Err(OnnxError::Interface(format!(
                "'{}' is [{}], a driver's values are [batch, width]",
                value.name,
                dims.join(", ")
            )));
        }
    };
    Ok((width, dims))
}

/// The index of a float32 or float64 tensor's first non-finite value (raw little-endian bytes
/// or the typed field); other types hold no weights a driver computes with.
fn first_non_finite(t: &pb::TensorProto) -> Option<usize> {
    use pb::tensor_proto::DataType;
    let raw = !t.raw_data.is_empty();
    if t.data_type == DataType::Float as i32 {
        if raw {
            return t.raw_data.chunks_exact(4).position(|b| !f32::from_le_bytes([b[0], b[1], b[2], b[3]]).is_finite());
        }
        return t.float_data.iter().position(|v| !v.is_finite());
    }
    if t.data_type == DataType::Double as i32 {
        if raw {
            return t
                .raw_data
                .chunks_exact(8)
                .position(|b| !f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]).is_finite());
        }
        return t.double_data.iter().position(|v| !v.is_finite());
    }
    None
}

/// Refuses a model of another observation version or decision rate; names what is absent.
fn check_metadata(proto: &pb::ModelProto) -> Result<Vec<String>, OnnxError> {
    let get = |key: &str| proto.metadata_props.iter().find(|p| p.key == key).map(|p| p.value.clone());
    let mut warnings = Vec::new();
    match get(OBSERVATION_VERSION_KEY) {
        Some(v) if v.trim() != OBSERVATION_VERSION.to_string() => {
            return Err(OnnxError::Metadata {
                key: OBSERVATION_VERSION_KEY,
                found: v,
                expected: OBSERVATION_VERSION.to_string(),
            });
        }
        Some(_) => {}
        None => warnings.push(format!(
            "the model does not say its observation version ({OBSERVATION_VERSION_KEY}): taken as {OBSERVATION_VERSION}"
        )),
    }
    match get(DECISION_RATE_KEY) {
        Some(v) if !v.trim().parse::<f64>().is_ok_and(|hz| (hz - DECISION_RATE_HZ).abs() < 1e-9) => {
            return Err(OnnxError::Metadata {
                key: DECISION_RATE_KEY,
                found: v,
                expected: format!("{DECISION_RATE_HZ} Hz"),
            });
        }
        Some(_) => {}
        None => warnings.push(format!(
            "the model does not say its decision rate ({DECISION_RATE_KEY}): taken as {DECISION_RATE_HZ} Hz"
        )),
    }
    Ok(warnings)
}

impl OnnxPolicy {
    /// Loads and checks a model (module docs).
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, OnnxError> {
        let proto = pb::ModelProto::decode(bytes).map_err(|e| OnnxError::Decode(e.to_string()))?;
        let graph = proto.graph.as_ref().ok_or_else(|| OnnxError::Decode("no graph".into()))?;
        let warnings = check_metadata(&proto)?;
        // Initializers and `Constant` nodes' tensors (what exporters write weights as).
        let constants = graph.node.iter().filter(|n| n.op_type == "Constant").flat_map(|n| &n.attribute);
        let tensors = graph.initializer.iter().chain(constants.filter_map(|a| a.t.as_ref()));
        for t in tensors {
            if let Some(index) = first_non_finite(t) {
                return Err(OnnxError::NonFiniteWeight { name: t.name.clone(), index });
            }
        }
        // Old exporters list initializers among the inputs too.
        let weights: std::collections::BTreeSet<&str> = graph.initializer.iter().map(|t| t.name.as_str()).collect();
        let inputs: Vec<&pb::ValueInfoProto> =
            graph.input.iter().filter(|i| !weights.contains(i.name.as_str())).collect();
        let expected = |what: &str| {
            OnnxError::Interface(format!(
                "the model has {} inputs and {} outputs: {what}",
                inputs.len(),
                graph.output.len()
            ))
        };
        let state_width = match (inputs.len(), graph.output.len()) {
            (1, 1) => None,
            (2, 2) => {
                let (width, dims) = declared(inputs[1])?;
                let width = width.filter(|w| (1..=MAX_STATE_WIDTH).contains(w)).ok_or_else(|| {
                    OnnxError::Interface(format!(
                        "state input '{}' is [{}]: its width must be fixed, from 1 to {MAX_STATE_WIDTH}",
                        inputs[1].name,
                        dims.join(", ")
                    ))
                })?;
                Some(width)
            }
            _ => return Err(expected("a driver has one of each (observation → action), or two (and its state)")),
        };
        let (obs_width, dims) = declared(inputs[0])?;
        if obs_width.is_some_and(|w| w != OBS_DIM) {
            return Err(OnnxError::Interface(format!(
                "observation input '{}' is [{}], the observation is [batch, {OBS_DIM}]",
                inputs[0].name,
                dims.join(", ")
            )));
        }
        let typed = optimised(&proto, state_width)?;
        let unsupported = |e: TractError| OnnxError::Unsupported(format!("{e:#}"));
        let check_output = |i: usize, what: &str, width: usize| -> Result<(), OnnxError> {
            let fact = typed.output_fact(i).map_err(unsupported)?;
            if fact.datum_type != f32::datum_type() || fact.shape.as_concrete() != Some(&[1, width][..]) {
                return Err(OnnxError::Interface(format!(
                    "output {i} ({what}) is {fact:?} for one observation, expected float32 [1, {width}]"
                )));
            }
            Ok(())
        };
        check_output(0, ACTION, ACT_DIM)?;
        if let Some(h) = state_width {
            check_output(1, STATE_OUT, h)?;
        }
        let plan = typed.into_runnable().map_err(unsupported)?;
        let policy = Self { plan, state_width, warnings, faults: AtomicU64::new(0) };
        guarded("running the probe", || policy.probe())?;
        Ok(policy)
    }

    /// Runs the probe sequence; every output must be finite.
    fn probe(&self) -> Result<(), OnnxError> {
        let mut actor = self.session().map_err(|e| OnnxError::Unsupported(format!("{e:#}")))?;
        let mut x = 0x9E37_79B9_7F4A_7C15u64;
        for step in 0..PROBE_STEPS {
            let mut obs = [0.0f32; OBS_DIM];
            if step > 0 {
                for o in &mut obs {
                    // splitmix64: a fixed sequence, no dependency for it.
                    x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
                    let mut z = x;
                    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
                    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
                    z ^= z >> 31;
                    *o = ((z >> 40) as f32 / (1u64 << 24) as f32 - 0.5) * 3.0;
                }
            }
            let (action, state) = actor.step(&obs).map_err(|e| OnnxError::Unsupported(format!("{e:#}")))?;
            if !action.iter().all(|v| v.is_finite()) {
                return Err(OnnxError::Probe { output: "action", step: step + 1 });
            }
            if !state.iter().all(|v| v.is_finite()) {
                return Err(OnnxError::Probe { output: "state", step: step + 1 });
            }
        }
        Ok(())
    }

    /// A fresh episode's session: tract state and a zero recurrent state.
    fn session(&self) -> TractResult<Session> {
        Ok(Session {
            state: self.plan.spawn()?,
            memory: vec![0.0; self.state_width.unwrap_or(0)],
            recurrent: self.state_width.is_some(),
        })
    }

    /// What the load found worth a warning (missing metadata).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Whether the model carries a recurrent state.
    pub fn recurrent(&self) -> bool {
        self.state_width.is_some()
    }

    /// Steps so far, over every actor, whose inference failed or gave a non-finite action
    /// (driven as the zero action).
    pub fn faults(&self) -> u64 {
        self.faults.load(Ordering::Relaxed)
    }

    /// An actor for one episode: state from zero, one inference per decision.
    pub fn actor(self: &Arc<Self>) -> crate::BoxedActor {
        let policy = Arc::clone(self);
        let mut session = self.session().ok();
        Box::new(move |obs| {
            let step = |s: &mut Session| {
                std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| s.step(obs).map(|(a, _)| a)))
            };
            let action = match session.as_mut().map(step) {
                Some(Ok(Ok(a))) => Some(a),
                Some(Ok(Err(_))) | None => None,
                // A session that panicked mid-run is not trusted again this episode.
                Some(Err(_)) => {
                    session = None;
                    None
                }
            };
            match action {
                Some(a) if a.iter().all(|v| v.is_finite()) => a,
                _ => {
                    policy.faults.fetch_add(1, Ordering::Relaxed);
                    [0.0; ACT_DIM]
                }
            }
        })
    }
}

/// tract's reading of `proto` for one observation at a time, optimised. tract answers most
/// faults with an error, but it may panic on a graph it did not expect: that is the model's
/// fault too, refused as such.
fn optimised(proto: &pb::ModelProto, state_width: Option<usize>) -> Result<TypedModel, OnnxError> {
    let unsupported = |e: TractError| OnnxError::Unsupported(format!("{e:#}"));
    let build = || -> Result<TypedModel, OnnxError> {
        let mut model = tract_onnx::onnx().model_for_proto_model(proto).map_err(unsupported)?;
        model = model.with_input_fact(0, f32::fact([1, OBS_DIM]).into()).map_err(unsupported)?;
        if let Some(h) = state_width {
            model = model.with_input_fact(1, f32::fact([1, h]).into()).map_err(unsupported)?;
        }
        model.into_optimized().map_err(unsupported)
    };
    guarded("on the graph", build)
}

/// `f`, a panic in it answered as the model's fault, its message in the error rather than on
/// stderr: the panic hook is silenced meanwhile (a load happens once, at start-up).
fn guarded<T>(what: &str, f: impl FnOnce() -> Result<T, OnnxError>) -> Result<T, OnnxError> {
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
    std::panic::set_hook(previous);
    result.unwrap_or_else(|payload| {
        let why = payload
            .downcast_ref::<String>()
            .cloned()
            .or_else(|| payload.downcast_ref::<&str>().map(|s| (*s).to_owned()))
            .unwrap_or_else(|| "no message".to_owned());
        Err(OnnxError::Unsupported(format!("tract failed {what} (it panicked: {why})")))
    })
}

/// One episode's inference state.
struct Session {
    state: TypedSimpleState,
    memory: Vec<f32>,
    recurrent: bool,
}

impl Session {
    /// The action for `obs`, advancing the recurrent state; also returns that state.
    fn step(&mut self, obs: &[f32; OBS_DIM]) -> TractResult<([f32; ACT_DIM], &[f32])> {
        let mut inputs: TVec<TValue> = tvec![Tensor::from_shape(&[1, OBS_DIM], obs)?.into()];
        if self.recurrent {
            inputs.push(Tensor::from_shape(&[1, self.memory.len()], &self.memory)?.into());
        }
        let outputs = self.state.run(inputs)?;
        let action = outputs[0].try_as_plain_ram()?.as_slice::<f32>()?;
        let action: [f32; ACT_DIM] = action.try_into().map_err(|_| format_err!("action of {} values", action.len()))?;
        if self.recurrent {
            let next = outputs[1].try_as_plain_ram()?.as_slice::<f32>()?;
            if next.len() != self.memory.len() {
                bail!("state of {} values, expected {}", next.len(), self.memory.len());
            }
            self.memory.copy_from_slice(next);
        }
        Ok((action, &self.memory))
    }
}

#[cfg(test)]
mod tests;
