//! Scenario pushes and results, episode metrics and policy updates (the cloud↔edge control plane).

use super::geometry::header;
use super::risk::terms;
use super::{
    ConvertError, distance_or_inf, enum_value, finite, in_range, invalid, non_empty, non_negative, required,
    unspecified,
};
use crate::v1;
use risktwin_common::metrics::EpisodeMetrics;
use risktwin_common::scenario::{ScenarioKind, ScenarioSpec, content_id};
use risktwin_common::telemetry::{PolicyRef, PolicyUpdate, ScenarioPush, ScenarioResult, SceneRef};

impl From<ScenarioKind> for v1::ScenarioKind {
    fn from(k: ScenarioKind) -> Self {
        match k {
            ScenarioKind::CutIn => v1::ScenarioKind::CutIn,
            ScenarioKind::EmergencyBraking => v1::ScenarioKind::EmergencyBraking,
            ScenarioKind::PedestrianCrossing => v1::ScenarioKind::PedestrianCrossing,
            ScenarioKind::SensorOcclusion => v1::ScenarioKind::SensorOcclusion,
            ScenarioKind::LowFriction => v1::ScenarioKind::LowFriction,
        }
    }
}

impl From<&ScenarioSpec> for v1::ScenarioSpec {
    fn from(s: &ScenarioSpec) -> Self {
        Self { kind: v1::ScenarioKind::from(s.kind) as i32, seed: s.seed, params: s.params.clone() }
    }
}

impl TryFrom<v1::ScenarioSpec> for ScenarioSpec {
    type Error = ConvertError;
    fn try_from(s: v1::ScenarioSpec) -> Result<Self, ConvertError> {
        const M: &str = "ScenarioSpec";
        let kind = match enum_value::<v1::ScenarioKind>(M, "kind", s.kind)? {
            v1::ScenarioKind::CutIn => ScenarioKind::CutIn,
            v1::ScenarioKind::EmergencyBraking => ScenarioKind::EmergencyBraking,
            v1::ScenarioKind::PedestrianCrossing => ScenarioKind::PedestrianCrossing,
            v1::ScenarioKind::SensorOcclusion => ScenarioKind::SensorOcclusion,
            v1::ScenarioKind::LowFriction => ScenarioKind::LowFriction,
            v1::ScenarioKind::Unspecified => return Err(unspecified(M, "kind")),
        };
        // The spec's own validation: known names, every parameter present, finite and in range.
        ScenarioSpec::new(kind, s.seed, s.params).map_err(|e| invalid(M, "params", e.to_string()))
    }
}

impl From<&ScenarioPush> for v1::ScenarioPush {
    fn from(p: &ScenarioPush) -> Self {
        Self { header: Some((&p.header).into()), spec_id: p.spec_id.clone(), spec: Some((&p.spec).into()) }
    }
}

impl TryFrom<v1::ScenarioPush> for ScenarioPush {
    type Error = ConvertError;
    fn try_from(p: v1::ScenarioPush) -> Result<Self, ConvertError> {
        const M: &str = "ScenarioPush";
        Ok(Self {
            header: header(M, p.header)?,
            spec_id: non_empty(M, "spec_id", p.spec_id)?,
            spec: required(M, "spec", p.spec)?.try_into()?,
        })
    }
}

impl From<&EpisodeMetrics> for v1::EpisodeMetrics {
    fn from(m: &EpisodeMetrics) -> Self {
        Self {
            collision: m.collision,
            offroad: m.offroad,
            success: m.success,
            route_completion: m.route_completion,
            avg_speed_mps: m.avg_speed_mps,
            steering_smoothness: m.steering_smoothness,
            longitudinal_smoothness: m.longitudinal_smoothness,
            min_ttc_s: m.min_ttc_s,
            min_distance_m: m.min_distance_m,
            risk_score: m.risk_score,
            reward: m.reward,
            steps: m.steps,
        }
    }
}

impl TryFrom<v1::EpisodeMetrics> for EpisodeMetrics {
    type Error = ConvertError;
    fn try_from(m: v1::EpisodeMetrics) -> Result<Self, ConvertError> {
        const M: &str = "EpisodeMetrics";
        Ok(Self {
            collision: m.collision,
            offroad: m.offroad,
            success: m.success,
            route_completion: in_range(M, "route_completion", m.route_completion, 0.0, 1.0)?,
            avg_speed_mps: finite(M, "avg_speed_mps", m.avg_speed_mps)?,
            steering_smoothness: non_negative(M, "steering_smoothness", m.steering_smoothness)?,
            longitudinal_smoothness: non_negative(M, "longitudinal_smoothness", m.longitudinal_smoothness)?,
            min_ttc_s: m.min_ttc_s.map(|t| non_negative(M, "min_ttc_s", t)).transpose()?,
            min_distance_m: distance_or_inf(M, "min_distance_m", m.min_distance_m)?,
            risk_score: in_range(M, "risk_score", m.risk_score, 0.0, 1.0)?,
            reward: finite(M, "reward", m.reward)?,
            steps: m.steps,
        })
    }
}

impl From<&ScenarioResult> for v1::ScenarioResult {
    fn from(r: &ScenarioResult) -> Self {
        Self {
            header: Some((&r.header).into()),
            spec_id: r.spec_id.clone(),
            metrics: Some((&r.metrics).into()),
            risk: Some((&r.risk).into()),
            policy: r.policy.as_ref().map(|p| v1::PolicyRef { policy_id: p.policy_id.clone(), version: p.version }),
            state_seqs: r.state_seqs.map(|(first, last)| v1::SeqRange { first, last }),
            scene: r.scene.as_ref().map(|s| v1::SceneRef { digest: s.digest.clone(), spec: Some((&s.spec).into()) }),
        }
    }
}

impl TryFrom<v1::ScenarioResult> for ScenarioResult {
    type Error = ConvertError;
    fn try_from(r: v1::ScenarioResult) -> Result<Self, ConvertError> {
        const M: &str = "ScenarioResult";
        let spec_id = non_empty(M, "spec_id", r.spec_id)?;
        let scene = r.scene.map(|s| scene_ref(s, &spec_id)).transpose()?;
        Ok(Self {
            header: header(M, r.header)?,
            spec_id,
            metrics: required(M, "metrics", r.metrics)?.try_into()?,
            risk: terms(M, "risk", r.risk)?,
            policy: r
                .policy
                .map(|p| {
                    non_empty("PolicyRef", "policy_id", p.policy_id)
                        .map(|id| PolicyRef { policy_id: id, version: p.version })
                })
                .transpose()?,
            state_seqs: match r.state_seqs {
                Some(v1::SeqRange { first, last }) if first > last => {
                    return Err(invalid(M, "state_seqs", format!("first {first} > last {last}")));
                }
                range => range.map(|s| (s.first, s.last)),
            },
            scene,
        })
    }
}

/// A scene reference: a 16-hex-digit digest and the spec whose content id is `spec_id`.
fn scene_ref(s: v1::SceneRef, spec_id: &str) -> Result<SceneRef, ConvertError> {
    const M: &str = "SceneRef";
    if s.digest.len() != 16 || !s.digest.bytes().all(|b| matches!(b, b'0'..=b'9' | b'a'..=b'f')) {
        return Err(invalid(M, "digest", format!("{:?} is not 16 lower-case hex digits", s.digest)));
    }
    let spec: ScenarioSpec = required(M, "spec", s.spec)?.try_into()?;
    let id = content_id(&spec);
    if id != spec_id {
        return Err(invalid(M, "spec", format!("its content id {id} is not the result's spec_id {spec_id}")));
    }
    Ok(SceneRef { digest: s.digest, spec })
}

impl From<&PolicyUpdate> for v1::PolicyUpdate {
    fn from(p: &PolicyUpdate) -> Self {
        Self {
            header: Some((&p.header).into()),
            policy_id: p.policy_id.clone(),
            version: p.version,
            algo: p.algo.clone(),
            weights_safetensors: p.weights.clone(),
            target: p.target.clone(),
            signature: p.signature.clone(),
        }
    }
}

impl TryFrom<v1::PolicyUpdate> for PolicyUpdate {
    type Error = ConvertError;
    fn try_from(p: v1::PolicyUpdate) -> Result<Self, ConvertError> {
        const M: &str = "PolicyUpdate";
        if p.weights_safetensors.is_empty() {
            return Err(ConvertError::MissingField { message: M, field: "weights_safetensors" });
        }
        Ok(Self {
            header: header(M, p.header)?,
            policy_id: non_empty(M, "policy_id", p.policy_id)?,
            version: p.version,
            algo: non_empty(M, "algo", p.algo)?,
            weights: p.weights_safetensors,
            target: p.target,
            signature: p.signature,
        })
    }
}
