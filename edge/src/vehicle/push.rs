//! What a vehicle does with the cloud's pushes: scenario pushes are validated (decodable,
//! complete, in range, feasible) before the vehicle runs them; policy updates are validated
//! (decodable, a known algorithm, weights of sane size that load as a policy of this build's
//! observation and action sizes and decision rate — `policy::HostPolicy`; a file without
//! a decision rate predates the field and is taken as 20 Hz — and whose file names the same
//! algorithm, a version above every one accepted of its policy id while this process runs, also
//! after another policy drove since) and then drive the vehicle. Before any of that, a policy
//! update must carry the cloud's ed25519 signature over its weights and metadata, addressed to
//! this vehicle ([`PolicyTrust`], `policy::signature`): without a trusted key every
//! update is refused (`unverifiable`), an unsigned one is `unsigned`, one that does not verify
//! `bad-signature`, one signed for another vehicle `wrong-vehicle`; refused weights are never
//! loaded. A refused push is counted by reason and logged; the vehicle keeps running what it was
//! running. A hazard warning addressed to the vehicle is handed on to its driver (see
//! [`super`]); one that does not decode, or that names another vehicle (`wrong-vehicle`), is
//! refused by reason.

use crate::scene::ActivePolicy;
use risktwin_common::scenario::check_feasible;
use risktwin_common::telemetry::{HazardWarning, PolicyRef, PolicyUpdate, ScenarioPush};
use risktwin_policy::HostPolicy;
use risktwin_policy::model::DriverModel;
use risktwin_policy::signature::{PolicyVerifyingKey, SignatureError};
use risktwin_protos::decode_tagged;
use serde::Serialize;
use std::collections::BTreeMap;
use std::sync::Arc;

/// Algorithms whose network layouts an edge knows.
pub const KNOWN_ALGOS: [&str; 3] = ["ppo", "ppo-gru", "sac"];
/// Largest accepted weights file, bytes.
pub const MAX_WEIGHTS_BYTES: usize = 64 << 20;
/// Refusals of one reason logged as warnings before they thin out to one in [`LOG_EVERY`]: a
/// peer flooding refused pushes must not flood the log too.
const LOGGED_IN_FULL: u64 = 10;
/// After the first [`LOGGED_IN_FULL`], one refusal of a reason in this many is logged.
const LOG_EVERY: u64 = 1000;

/// Whose policy updates a vehicle takes: signed by the holder of `key`'s secret half for this
/// vehicle (`target`, `SITE/ID`).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PolicyTrust {
    /// The key the vehicle trusts (`--trust-key`); `None`: it takes no policy from the network.
    pub key: Option<PolicyVerifyingKey>,
    /// `SITE/ID` of this vehicle, as the signed update must name it.
    pub target: String,
}

impl PolicyTrust {
    /// Why `update` is refused before its weights are looked at, if it is.
    fn refusal(&self, update: &PolicyUpdate) -> Option<(&'static str, String)> {
        let Some(key) = &self.key else {
            return Some(("unverifiable", "no trusted key (--trust-key): no policy from the network is taken".into()));
        };
        match key.verify(update) {
            Err(SignatureError::Unsigned) => Some(("unsigned", "the update carries no signature".into())),
            Err(e) => Some(("bad-signature", e.to_string())),
            // Verified: the target is the signer's, so a mismatch is a copy sent to the wrong car.
            Ok(()) if update.target != self.target => {
                Some(("wrong-vehicle", format!("signed for {:?}, this is {:?}", update.target, self.target)))
            }
            Ok(()) => None,
        }
    }
}

/// Whether the `count`-th refusal of a reason past the first [`LOGGED_IN_FULL`] is logged.
fn thinned_out_logged(count: u64) -> bool {
    count.is_multiple_of(LOG_EVERY)
}

/// A pushed scenario's outcome, as the vehicle reports it in its summary.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResultLine {
    pub spec_id: String,
    pub collision: bool,
    pub min_ttc_s: Option<f64>,
    pub risk_score: f64,
    pub steps: u64,
    /// The received policy that drove; `None`: the reference driver.
    pub policy: Option<PolicyRef>,
    /// Sequence numbers of the first and last `state` message of the played episode, so its
    /// streams can be found in what the cloud received.
    pub state_seqs: Option<(u64, u64)>,
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
    /// The latest accepted policy, which drives the vehicle.
    pub policy: Option<PolicyLine>,
    /// Hazard warnings received from the cloud's warning role, addressed to this vehicle.
    pub warnings_received: u64,
    /// Of those, received while a pushed episode played (recorded ahead of time: its driver
    /// cannot react; the own scene's driver does not hear them either).
    pub warnings_on_tape: u64,
    /// Warnings refused, by reason.
    pub warnings_refused: BTreeMap<String, u64>,
    /// The highest version accepted of each policy id, kept when another policy takes over, so
    /// a recorded older update cannot roll the vehicle back. Held for the process's life only.
    #[serde(skip)]
    highest_versions: BTreeMap<String, u32>,
}

impl PushSummary {
    /// Counts a refusal by reason and logs it: the first [`LOGGED_IN_FULL`] of each reason,
    /// then one in [`LOG_EVERY`] with the count so far (every one at debug level).
    fn refuse(map: &mut BTreeMap<String, u64>, what: &str, reason: &str, detail: &str) {
        let count = map.entry(reason.to_owned()).or_default();
        *count += 1;
        if *count <= LOGGED_IN_FULL {
            tracing::warn!("edge: refused {what}: {reason}: {detail}");
        } else if thinned_out_logged(*count) {
            tracing::warn!("edge: refused {what}: {reason}: {detail} ({count} so far, one in {LOG_EVERY} logged)");
        } else {
            tracing::debug!("edge: refused {what}: {reason}: {detail}");
        }
    }

    /// A valid, feasible scenario push (`payload` tagged `encoding`), or `None` (counted and
    /// logged).
    pub fn scenario(&mut self, encoding: &str, payload: &[u8]) -> Option<ScenarioPush> {
        let push = match decode_tagged::<ScenarioPush>(encoding, payload) {
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

    /// A valid hazard warning addressed to vehicle `me` (`payload` tagged `encoding`), or
    /// `None` (counted by reason and logged).
    pub fn warning(&mut self, me: &str, encoding: &str, payload: &[u8]) -> Option<HazardWarning> {
        let w = match decode_tagged::<HazardWarning>(encoding, payload) {
            Ok(w) => w,
            Err(e) => {
                Self::refuse(&mut self.warnings_refused, "hazard warning", e.reason(), &e.to_string());
                return None;
            }
        };
        if w.warned_source != me {
            let detail = format!("addressed to {:?}, this is {me:?}", w.warned_source);
            Self::refuse(&mut self.warnings_refused, "hazard warning", "wrong-vehicle", &detail);
            return None;
        }
        tracing::debug!("edge: warned about {} ({:?}, TTC {:.2} s)", w.hazard_source, w.kind, w.ttc_s);
        self.warnings_received += 1;
        Some(w)
    }

    /// Validates a policy update (`payload` tagged `encoding`): its signature against `trust`,
    /// then its weights, which it loads; the policy to drive with when valid and newer than the
    /// one held.
    pub fn policy(&mut self, encoding: &str, payload: &[u8], trust: &PolicyTrust) -> Option<ActivePolicy> {
        let update = match decode_tagged::<PolicyUpdate>(encoding, payload) {
            Ok(u) => u,
            Err(e) => {
                Self::refuse(&mut self.policies_refused, "policy update", e.reason(), &e.to_string());
                return None;
            }
        };
        // Before the signature is checked, whose message hashes all of the weights.
        if update.weights.len() > MAX_WEIGHTS_BYTES {
            let detail = format!("{} bytes > {MAX_WEIGHTS_BYTES}", update.weights.len());
            Self::refuse(&mut self.policies_refused, "policy update", "too-large", &detail);
            return None;
        }
        if let Some((reason, detail)) = trust.refusal(&update) {
            Self::refuse(&mut self.policies_refused, "policy update", reason, &detail);
            return None;
        }
        match self.check_policy(&update) {
            Ok(net) => {
                self.highest_versions.insert(update.policy_id.clone(), update.version);
                self.policy = Some(PolicyLine {
                    policy_id: update.policy_id.clone(),
                    version: update.version,
                    algo: update.algo.clone(),
                    weights_bytes: update.weights.len(),
                });
                let id = PolicyRef { policy_id: update.policy_id, version: update.version };
                Some(ActivePolicy { id, model: DriverModel::Native(Arc::new(net)) })
            }
            Err((reason, detail)) => {
                Self::refuse(&mut self.policies_refused, "policy update", reason, &detail);
                None
            }
        }
    }

    /// The loaded policy of a decoded update, or why it is refused.
    fn check_policy(&self, update: &PolicyUpdate) -> Result<HostPolicy, (&'static str, String)> {
        if !KNOWN_ALGOS.contains(&update.algo.as_str()) {
            return Err(("unknown-algo", format!("algo {:?}, known {KNOWN_ALGOS:?}", update.algo)));
        }
        // Against every version accepted so far, not only the one driving now: replaying an
        // older signed update of another id first must not open the way back to this one's.
        if let Some(&highest) = self.highest_versions.get(&update.policy_id)
            && update.version <= highest
        {
            let detail = format!("{:?} version {} ≤ {highest} accepted before", update.policy_id, update.version);
            return Err(("stale-version", detail));
        }
        let net = HostPolicy::from_safetensors(&update.weights).map_err(|e| (e.reason(), e.to_string()))?;
        if net.kind().algo() != update.algo {
            let detail = format!("update says {:?}, its weights are a {} policy", update.algo, net.kind().algo());
            return Err(("algo-mismatch", detail));
        }
        Ok(net)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use risktwin_common::env::OBS_DIM;
    use risktwin_common::scenario::ScenarioKind;
    use risktwin_common::telemetry::{Frame, Header};
    use risktwin_policy::PolicyKind;
    use risktwin_policy::signature::PolicySigningKey;
    use risktwin_protos::{encode, encoding_of};

    const SCENARIO: &str = "application/protobuf;risktwin.v1.ScenarioPush";
    const POLICY: &str = "application/protobuf;risktwin.v1.PolicyUpdate";

    fn header() -> Header {
        Header { source: "cloud".into(), seq: 0, capture_time_ns: 1, publish_time_ns: 1, frame: Frame::World }
    }

    fn weights() -> Vec<u8> {
        crate::scene::tests::policy_file(PolicyKind::Gaussian, &[0.0; 3])
    }

    const ME: &str = "site0/veh-1";

    fn cloud_key() -> PolicySigningKey {
        PolicySigningKey::from_seed([7; 32])
    }

    fn trusting() -> PolicyTrust {
        PolicyTrust { key: Some(cloud_key().verifying_key()), target: ME.into() }
    }

    fn unsigned(version: u32, algo: &str, weights: Vec<u8>) -> PolicyUpdate {
        unsigned_id("p", version, algo, weights)
    }

    fn unsigned_id(policy_id: &str, version: u32, algo: &str, weights: Vec<u8>) -> PolicyUpdate {
        PolicyUpdate {
            header: header(),
            policy_id: policy_id.into(),
            version,
            algo: algo.into(),
            weights,
            target: ME.into(),
            signature: Vec::new(),
        }
    }

    /// An update signed by the cloud's key for this vehicle.
    fn policy(version: u32, algo: &str, weights: Vec<u8>) -> Vec<u8> {
        let mut u = unsigned(version, algo, weights);
        cloud_key().sign(&mut u);
        encode(&u)
    }

    #[test]
    fn only_updates_signed_for_this_vehicle_by_the_trusted_key_are_loaded() {
        let mut log = PushSummary::default();
        let nobody = PolicyTrust { key: None, target: ME.into() };
        assert!(log.policy(POLICY, &policy(1, "ppo", weights()), &nobody).is_none(), "no trusted key");
        assert!(log.policy(POLICY, &encode(&unsigned(1, "ppo", weights())), &trusting()).is_none());
        let mut flipped = unsigned(1, "ppo", weights());
        cloud_key().sign(&mut flipped);
        let last = flipped.weights.len() - 1;
        flipped.weights[last] ^= 1;
        assert!(log.policy(POLICY, &encode(&flipped), &trusting()).is_none(), "a flipped weights byte");
        let mut renamed = unsigned(1, "ppo", weights());
        cloud_key().sign(&mut renamed);
        renamed.version = 9;
        assert!(log.policy(POLICY, &encode(&renamed), &trusting()).is_none(), "metadata changed");
        let mut stranger = unsigned(1, "ppo", weights());
        PolicySigningKey::from_seed([8; 32]).sign(&mut stranger);
        assert!(log.policy(POLICY, &encode(&stranger), &trusting()).is_none(), "another key");
        let mut elsewhere = unsigned(1, "ppo", weights());
        elsewhere.target = "site0/veh-2".into();
        cloud_key().sign(&mut elsewhere);
        assert!(log.policy(POLICY, &encode(&elsewhere), &trusting()).is_none(), "for another vehicle");
        let mut huge = unsigned(1, "ppo", vec![0; MAX_WEIGHTS_BYTES + 1]);
        huge.signature = vec![0; 64];
        assert!(log.policy(POLICY, &encode(&huge), &trusting()).is_none(), "too large to hash");
        assert_eq!(log.policy, None, "nothing refused was loaded");
        assert!(log.policy(POLICY, &policy(1, "ppo", weights()), &trusting()).is_some());
        let reasons: Vec<(&str, u64)> = log.policies_refused.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        assert_eq!(
            reasons,
            [("bad-signature", 3), ("too-large", 1), ("unsigned", 1), ("unverifiable", 1), ("wrong-vehicle", 1)]
        );
    }

    #[test]
    fn a_recorded_older_update_cannot_roll_the_vehicle_back_through_another_policy() {
        let signed = |id: &str, version: u32| {
            let mut u = unsigned_id(id, version, "ppo", weights());
            cloud_key().sign(&mut u);
            encode(&u)
        };
        let mut log = PushSummary::default();
        assert!(log.policy(POLICY, &signed("p", 2), &trusting()).is_some());
        assert!(log.policy(POLICY, &signed("q", 1), &trusting()).is_some(), "another policy takes over");
        assert!(log.policy(POLICY, &signed("p", 1), &trusting()).is_none(), "p v1 replayed after p v2");
        assert!(log.policy(POLICY, &signed("p", 2), &trusting()).is_none(), "p v2 replayed");
        assert_eq!(log.policy.as_ref().map(|p| (p.policy_id.as_str(), p.version)), Some(("q", 1)));
        assert!(log.policy(POLICY, &signed("p", 3), &trusting()).is_some(), "a newer p is taken");
        assert!(log.policy(POLICY, &signed("q", 1), &trusting()).is_none(), "q v1 replayed");
        let reasons: Vec<(&str, u64)> = log.policies_refused.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        assert_eq!(reasons, [("stale-version", 3)]);
    }

    #[test]
    fn a_flood_of_refusals_is_counted_in_full_and_logged_thinned_out() {
        let mut log = PushSummary::default();
        for _ in 0..2500 {
            assert!(log.scenario(SCENARIO, b"\xff\xff garbage").is_none());
        }
        assert_eq!(log.scenarios_refused.get("malformed"), Some(&2500));
        let logged = (1..=2500).filter(|&n| n <= LOGGED_IN_FULL || thinned_out_logged(n)).count();
        assert_eq!(logged, 12, "the first ten, the 1000th and the 2000th");
    }

    #[test]
    fn warnings_to_the_vehicle_are_taken_and_others_refused_by_reason() {
        use risktwin_common::geometry::{Footprint, Pose, Vec2};
        use risktwin_common::telemetry::HazardKind;
        let warning = HazardWarning {
            header: header(),
            warned_source: "veh-1".into(),
            hazard_source: "veh-2".into(),
            hazard_pose: Pose::new(10.0, 0.0, 0.0),
            hazard_velocity: Vec2::zeros(),
            hazard_footprint: Footprint::new(4.5, 1.8),
            kind: HazardKind::PredictedContact,
            ttc_s: 1.2,
            distance_m: 5.5,
            trigger_source: "veh-1".into(),
            trigger_seq: 7,
            trigger_capture_time_ns: 1,
        };
        let mut log = PushSummary::default();
        let tag = encoding_of("risktwin.v1.HazardWarning");
        assert_eq!(log.warning("veh-1", &tag, &encode(&warning)), Some(warning.clone()));
        assert_eq!(log.warning("veh-1", &tag, b"\xff\xff garbage"), None);
        assert_eq!(log.warning("veh-1", POLICY, &encode(&warning)), None);
        assert_eq!(log.warning("veh-2", &tag, &encode(&warning)), None, "addressed to veh-1");
        assert_eq!(log.warnings_received, 1);
        let reasons: Vec<(&str, u64)> = log.warnings_refused.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        assert_eq!(reasons, [("malformed", 1), ("wrong-schema", 1), ("wrong-vehicle", 1)]);
    }

    #[test]
    fn scenario_pushes_are_refused_by_reason() {
        let mut log = PushSummary::default();
        assert!(log.scenario(SCENARIO, b"\xff\xff garbage").is_none());
        let spec = crate::scene::feasible_spec(1, ScenarioKind::CutIn).expect("feasible");
        let good = ScenarioPush { header: header(), spec_id: "abc".into(), spec };
        assert_eq!(log.scenario(SCENARIO, &encode(&good)).map(|p| p.spec_id), Some("abc".into()));
        // The same bytes under another schema version, or untagged: never read.
        assert!(log.scenario(&encoding_of("risktwin.v2.ScenarioPush"), &encode(&good)).is_none());
        assert!(log.scenario("zenoh/bytes", &encode(&good)).is_none());
        let mut no_id = encode(&good);
        no_id.clear();
        assert!(log.scenario(SCENARIO, &no_id).is_none(), "an empty message has no header");
        assert_eq!(log.scenarios_accepted, 1);
        let reasons: Vec<(&str, u64)> = log.scenarios_refused.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        assert_eq!(reasons, [("malformed", 1), ("missing-field", 1), ("wrong-schema", 2)]);
    }

    #[test]
    fn policies_must_be_known_loadable_and_newer() {
        let mut log = PushSummary::default();
        let first = log.policy(POLICY, &policy(1, "ppo", weights()), &trusting()).expect("accepted");
        assert_eq!(first.id, PolicyRef { policy_id: "p".into(), version: 1 });
        assert!(log.policy(POLICY, &policy(1, "ppo", weights()), &trusting()).is_none(), "same version again");
        assert!(log.policy(POLICY, &policy(0, "ppo", weights()), &trusting()).is_none(), "older");
        assert!(log.policy(POLICY, &policy(2, "dqn", weights()), &trusting()).is_none());
        assert!(log.policy(POLICY, &policy(2, "sac", vec![9; 12]), &trusting()).is_none(), "not safetensors");
        assert!(log.policy(POLICY, &policy(2, "sac", weights()), &trusting()).is_none(), "a ppo file pushed as sac");
        // A file whose observation width is not this build's: refused, never a panic.
        let mut wide = weights();
        let key = format!(r#""obs_dim":"{OBS_DIM}""#).into_bytes();
        let at = wide.windows(key.len()).position(|w| w == key).expect("the metadata holds obs_dim");
        // Same length, another width: the last digit changed.
        wide[at + key.len() - 2] ^= 1;
        assert!(log.policy(POLICY, &policy(2, "ppo", wide), &trusting()).is_none(), "wrong observation width");
        // Trained at another decision rate: refused; from before the field: taken as 20 Hz.
        let rate = br#""decision_rate_hz":"20""#;
        // The metadata's order varies between files: each is searched.
        let rate_at = |file: &[u8]| {
            let at = file.windows(rate.len()).position(|w| w == rate).expect("the metadata holds the decision rate");
            at + rate.len()
        };
        let mut fast = weights();
        let end = rate_at(&fast);
        fast[end - 3] = b'5';
        assert!(log.policy(POLICY, &policy(2, "ppo", fast), &trusting()).is_none(), "a 50 Hz policy");
        let mut older = weights();
        let end = rate_at(&older);
        older[end - 8..end - 6].copy_from_slice(b"xx");
        assert!(log.policy(POLICY, &policy(2, "ppo", older), &trusting()).is_some(), "a file without the rate");
        let sac = crate::scene::tests::policy_file(PolicyKind::Squashed, &[0.0; 6]);
        assert!(log.policy(POLICY, &policy(3, "sac", sac), &trusting()).is_some());
        assert_eq!(log.policy.as_ref().map(|p| (p.version, p.algo.as_str())), Some((3, "sac")));
        assert!(
            log.policy("application/protobuf;risktwin.v1.ScenarioPush", &policy(4, "ppo", weights()), &trusting())
                .is_none()
        );
        let reasons: Vec<(&str, u64)> = log.policies_refused.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        assert_eq!(
            reasons,
            [
                ("algo-mismatch", 1),
                ("not-safetensors", 1),
                ("stale-version", 2),
                ("unknown-algo", 1),
                ("wrong-decision-rate", 1),
                ("wrong-dims", 1),
                ("wrong-schema", 1)
            ]
        );
    }
}
