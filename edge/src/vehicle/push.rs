//! What a vehicle does with the cloud's pushes: scenario pushes are validated (decodable,
//! complete, in range, feasible) before the vehicle runs them; policy updates are validated
//! (decodable, a known algorithm, a monotonic version per policy id, safetensors-shaped weights
//! of sane size) and kept, for the `learn` crate's controller to load once it exists. A refused
//! push is counted by reason and logged; the vehicle keeps running what it was running.

use risktwin_common::scenario::check_feasible;
use risktwin_common::telemetry::{PolicyUpdate, ScenarioPush};
use risktwin_protos::decode;
use serde::Serialize;
use std::collections::BTreeMap;

/// Algorithms whose network layouts an edge knows.
pub const KNOWN_ALGOS: [&str; 2] = ["ppo", "sac"];
/// Largest accepted weights file, bytes.
pub const MAX_WEIGHTS_BYTES: usize = 64 << 20;

/// A pushed scenario's outcome, as the vehicle reports it in its summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResultLine {
    pub spec_id: String,
    pub collision: bool,
    pub min_ttc_s: Option<f64>,
    pub risk_score: f64,
    pub steps: u64,
}

/// The policy a vehicle holds.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct PolicyLine {
    pub policy_id: String,
    pub version: u32,
    pub algo: String,
    pub weights_bytes: usize,
}

/// Pushes a vehicle received, for its summary.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct PushSummary {
    /// Scenario pushes accepted and run.
    pub scenarios_accepted: u64,
    /// Scenario pushes refused, by reason.
    pub scenarios_refused: BTreeMap<String, u64>,
    /// Outcomes of the pushed scenarios played to their end, in order.
    pub results: Vec<ResultLine>,
    /// Policy updates refused, by reason.
    pub policies_refused: BTreeMap<String, u64>,
    /// The latest accepted policy (not driving yet: see `scene::EgoController`).
    pub policy: Option<PolicyLine>,
}

impl PushSummary {
    fn refuse(map: &mut BTreeMap<String, u64>, what: &str, reason: &str, detail: &str) {
        eprintln!("edge: refused {what}: {reason}: {detail}");
        *map.entry(reason.to_owned()).or_default() += 1;
    }

    /// A valid, feasible scenario push, or `None` (counted and logged).
    pub fn scenario(&mut self, payload: &[u8]) -> Option<ScenarioPush> {
        let push = match decode::<ScenarioPush>(payload) {
            Ok(p) => p,
            Err(e) => {
                Self::refuse(&mut self.scenarios_refused, "scenario push", e.reason(), &e.to_string());
                return None;
            }
        };
        if let Err(infeasible) = check_feasible(&push.spec) {
            Self::refuse(&mut self.scenarios_refused, "scenario push", "infeasible", &format!("{infeasible:?}"));
            return None;
        }
        self.scenarios_accepted += 1;
        Some(push)
    }

    /// Validates a policy update and keeps it when it is newer than the one held.
    pub fn policy(&mut self, payload: &[u8]) -> Option<PolicyUpdate> {
        let update = match decode::<PolicyUpdate>(payload) {
            Ok(u) => u,
            Err(e) => {
                Self::refuse(&mut self.policies_refused, "policy update", e.reason(), &e.to_string());
                return None;
            }
        };
        let reason = if !KNOWN_ALGOS.contains(&update.algo.as_str()) {
            Some(("unknown_algo", format!("algo {:?}, known {KNOWN_ALGOS:?}", update.algo)))
        } else if update.weights.len() > MAX_WEIGHTS_BYTES {
            Some(("too_large", format!("{} bytes > {MAX_WEIGHTS_BYTES}", update.weights.len())))
        } else if let Err(e) = check_safetensors(&update.weights) {
            Some(("bad_weights", e))
        } else if let Some(held) = self.policy.as_ref().filter(|p| p.policy_id == update.policy_id)
            && update.version <= held.version
        {
            Some(("stale_version", format!("version {} ≤ held {}", update.version, held.version)))
        } else {
            None
        };
        if let Some((reason, detail)) = reason {
            Self::refuse(&mut self.policies_refused, "policy update", reason, &detail);
            return None;
        }
        self.policy = Some(PolicyLine {
            policy_id: update.policy_id.clone(),
            version: update.version,
            algo: update.algo.clone(),
            weights_bytes: update.weights.len(),
        });
        Some(update)
    }
}

/// The safetensors framing: an 8-byte little-endian header length, then that many bytes of a
/// JSON object, then the tensor data (which the header's offsets must not overrun: checked by
/// the loader of the `learn` crate, which parses the header).
pub fn check_safetensors(bytes: &[u8]) -> Result<(), String> {
    let len_bytes: [u8; 8] = bytes.get(..8).and_then(|b| b.try_into().ok()).ok_or("shorter than 8 bytes")?;
    let header_len = u64::from_le_bytes(len_bytes);
    let end = usize::try_from(header_len).ok().and_then(|n| n.checked_add(8)).filter(|end| *end <= bytes.len());
    let end = end.ok_or_else(|| format!("header length {header_len} overruns the {} bytes", bytes.len()))?;
    let header = std::str::from_utf8(&bytes[8..end]).map_err(|_| "header is not UTF-8".to_owned())?;
    let header = header.trim_end();
    if !(header.starts_with('{') && header.ends_with('}')) {
        return Err("header is not a JSON object".to_owned());
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::scenario::ScenarioKind;
    use risktwin_common::telemetry::{Frame, Header};
    use risktwin_protos::encode;

    fn header() -> Header {
        Header { source: "cloud".into(), seq: 0, capture_time_ns: 1, publish_time_ns: 1, frame: Frame::World }
    }

    /// A minimal safetensors file: one f32 tensor of shape [2].
    pub(crate) fn weights() -> Vec<u8> {
        let json = br#"{"w":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}}"#;
        let mut bytes = (json.len() as u64).to_le_bytes().to_vec();
        bytes.extend_from_slice(json);
        bytes.extend_from_slice(&[0; 8]);
        bytes
    }

    fn policy(version: u32, algo: &str, weights: Vec<u8>) -> Vec<u8> {
        encode(&PolicyUpdate { header: header(), policy_id: "p".into(), version, algo: algo.into(), weights })
    }

    #[test]
    fn scenario_pushes_are_refused_by_reason() {
        let mut log = PushSummary::default();
        assert!(log.scenario(b"\xff\xff garbage").is_none());
        let spec = crate::scene::feasible_spec(1, ScenarioKind::CutIn).expect("feasible");
        let good = ScenarioPush { header: header(), spec_id: "abc".into(), spec };
        assert_eq!(log.scenario(&encode(&good)).map(|p| p.spec_id), Some("abc".into()));
        let mut no_id = encode(&good);
        no_id.clear();
        assert!(log.scenario(&no_id).is_none(), "an empty message has no header");
        assert_eq!(log.scenarios_accepted, 1);
        assert_eq!(log.scenarios_refused.values().sum::<u64>(), 2, "{:?}", log.scenarios_refused);
    }

    #[test]
    fn policies_must_be_known_sane_and_newer() {
        let mut log = PushSummary::default();
        assert!(log.policy(&policy(1, "ppo", weights())).is_some());
        assert!(log.policy(&policy(1, "ppo", weights())).is_none(), "same version again");
        assert!(log.policy(&policy(0, "ppo", weights())).is_none(), "older");
        assert!(log.policy(&policy(2, "dqn", weights())).is_none());
        assert!(log.policy(&policy(2, "sac", vec![9; 12])).is_none(), "not safetensors");
        assert!(log.policy(&policy(3, "sac", weights())).is_some());
        assert_eq!(log.policy.as_ref().map(|p| (p.version, p.algo.as_str())), Some((3, "sac")));
        let reasons: Vec<&str> = log.policies_refused.keys().map(String::as_str).collect();
        assert_eq!(reasons, ["bad_weights", "stale_version", "unknown_algo"]);
        assert_eq!(log.policies_refused["stale_version"], 2);
    }
}
