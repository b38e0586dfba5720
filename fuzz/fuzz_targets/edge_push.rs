//! What a vehicle does with the cloud's pushes (`PushSummary`): scenario pushes decoded,
//! validated and checked feasible; hazard warnings decoded and addressed; policy updates
//! decoded, size-checked, signature-verified against the trusted key and loaded. A sequence
//! per input, so the state a vehicle keeps between pushes (versions accepted) carries over.
#![no_main]

use libfuzzer_sys::fuzz_target;
use risktwin_policy::signature::PolicySigningKey;
use risktwin_edge::vehicle::push::{PolicyTrust, PushSummary};
use risktwin_fuzz::{PUSH_KEY_SEED, PUSH_TARGET, PUSH_VEHICLE_ID, Records, push_tag};
use risktwin_protos::encoding_of;

const MESSAGES: [&str; 3] = ["risktwin.v1.ScenarioPush", "risktwin.v1.HazardWarning", "risktwin.v1.PolicyUpdate"];

fuzz_target!(|data: &[u8]| {
    let trust = PolicyTrust {
        key: Some(PolicySigningKey::from_seed(PUSH_KEY_SEED).verifying_key()),
        target: PUSH_TARGET.into(),
    };
    let mut pushes = PushSummary::default();
    let mut records = Records::new(data);
    while let Some(tag) = records.tag() {
        let payload = records.frame();
        let kind = tag % 3;
        let encoding = match tag / 3 % 3 {
            0 => encoding_of(MESSAGES[usize::from(kind)]),
            1 => encoding_of(MESSAGES[usize::from((kind + 1) % 3)]),
            _ => String::new(),
        };
        match kind {
            push_tag::SCENARIO => drop(pushes.scenario(&encoding, payload)),
            push_tag::WARNING => drop(pushes.warning(PUSH_VEHICLE_ID, &encoding, payload)),
            _ => drop(pushes.policy(&encoding, payload, &trust)),
        }
    }
});
