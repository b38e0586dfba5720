//! Where a trained policy fails on the benign set: each benign scenario's outcome with its kind
//! and parameters, and a per-kind tally. `POLICY=path/policy.safetensors SEED=1 BENIGN=40
//! cargo run --release -p risktwin-learn --example benign_diag`
use risktwin_common::env::benign_specs;
use risktwin_learn::PolicyNet;
use risktwin_learn::train::evaluate_policy;
use std::collections::BTreeMap;
use std::path::PathBuf;

fn main() {
    let path = PathBuf::from(std::env::var("POLICY").expect("POLICY"));
    let seed: u64 = std::env::var("SEED").ok().and_then(|s| s.parse().ok()).unwrap_or(1);
    let n: usize = std::env::var("BENIGN").ok().and_then(|s| s.parse().ok()).unwrap_or(40);
    let policy = PolicyNet::load(&path).expect("policy");
    let specs = benign_specs(seed ^ 0xBE91_6000, n);
    let metrics = evaluate_policy(&policy, &specs);
    let mut tally: BTreeMap<String, [u32; 5]> = BTreeMap::new();
    for (s, m) in specs.iter().zip(&metrics) {
        let outcome = if m.success {
            0
        } else if m.collision {
            1
        } else if m.offroad {
            2
        } else {
            3
        };
        let t = tally.entry(format!("{:?}", s.kind)).or_default();
        t[outcome] += 1;
        t[4] += 1;
        let params: Vec<String> = s.params.iter().map(|(k, v)| format!("{k}={v:.2}")).collect();
        println!(
            "{:?} {} compl {:.2} v {:.1} steps {} | {}",
            s.kind,
            ["ok", "COLLISION", "OFFROAD", "timeout"][outcome],
            m.route_completion,
            m.avg_speed_mps,
            m.steps,
            params.join(" ")
        );
    }
    for (k, t) in tally {
        println!("{k}: ok {} collision {} offroad {} timeout {} of {}", t[0], t[1], t[2], t[3], t[4]);
    }
}
