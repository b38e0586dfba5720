//! An ONNX driver against the native policy path, side by side in one run: the cost of one
//! decision (observation → action) and whole episodes per second, for a policy file given on
//! the command line or, without one, a PPO policy of `risktwin train`'s shape (24 → 64 → 64 →
//! 3) with random weights. The ONNX model is the policy's own export (`HostPolicy::to_onnx`), so
//! both sides compute the same function.
//!
//! ```sh
//! cargo bench -p risktwin-policy --bench onnx_driver -- [POLICY.safetensors] [--episodes N]
//! ```
//!
//! Prints `decision_us native=… onnx=… ratio=…` (median over rounds of 10,000 decisions) and
//! `episodes_per_s native=… onnx=… ratio=…` (N episodes of every scenario kind, one thread).

use risktwin_common::env::OBS_DIM;
use risktwin_common::episode;
use risktwin_common::metrics::RewardWeights;
use risktwin_common::rng::Rng;
use risktwin_common::scenario::{ScenarioKind, build, check_feasible, sample};
use risktwin_policy::model::DriverModel;
use risktwin_policy::onnx::OnnxPolicy;
use risktwin_policy::{Dense, HostMlp, HostPolicy, PolicyKind};
use std::hint::black_box;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

const DECISIONS_PER_ROUND: usize = 10_000;
const ROUNDS: usize = 7;

fn main() -> ExitCode {
    let mut args: Vec<String> = std::env::args().skip(1).filter(|a| a != "--bench").collect();
    let mut episodes = 4;
    if let Some(k) = args.iter().position(|a| a == "--episodes") {
        match args.get(k + 1).and_then(|n| n.parse().ok()) {
            Some(n) if n > 0 => episodes = n,
            _ => return fail("--episodes needs a positive count"),
        }
        args.drain(k..k + 2);
    }
    let host = match args.first() {
        Some(path) => match std::fs::read(path)
            .map_err(|e| e.to_string())
            .and_then(|b| HostPolicy::from_safetensors(&b).map_err(|e| e.to_string()))
        {
            Ok(p) => p,
            Err(e) => return fail(&format!("{path}: {e}")),
        },
        None => random_ppo(),
    };
    let onnx = match OnnxPolicy::from_bytes(&host.to_onnx()) {
        Ok(m) => m,
        Err(e) => return fail(&format!("the exported model does not load: {e}")),
    };
    let native = DriverModel::Native(Arc::new(host));
    let onnx = DriverModel::Onnx(Arc::new(onnx));

    let mut rng = Rng::new(1);
    let observations: Vec<[f32; OBS_DIM]> =
        (0..DECISIONS_PER_ROUND).map(|_| std::array::from_fn(|_| rng.uniform(-1.0, 1.0) as f32)).collect();
    let decision_us = |model: &DriverModel| {
        let mut rounds: Vec<f64> = (0..ROUNDS)
            .map(|_| {
                let mut actor = model.actor();
                let start = Instant::now();
                for obs in &observations {
                    black_box(actor(black_box(obs)));
                }
                start.elapsed().as_secs_f64() * 1e6 / DECISIONS_PER_ROUND as f64
            })
            .collect();
        rounds.sort_by(f64::total_cmp);
        rounds[ROUNDS / 2]
    };
    let (a, b) = (decision_us(&native), decision_us(&onnx));
    println!("decision_us native={a:.3} onnx={b:.3} ratio={:.2}", b / a);

    let specs: Vec<_> = ScenarioKind::ALL
        .iter()
        .flat_map(|&kind| (0..).map(move |i| sample(11, kind, i)).filter(|s| check_feasible(s).is_ok()).take(episodes))
        .collect();
    let episodes_per_s = |model: &DriverModel| {
        let start = Instant::now();
        let mut steps = 0u64;
        for spec in &specs {
            let mut world = build(spec);
            let mut driver = model.driver(world.desired_speed_mps, world.dt_s);
            steps += episode::run(&mut world, &mut driver, &RewardWeights::default()).metrics.steps;
        }
        (specs.len() as f64 / start.elapsed().as_secs_f64(), steps)
    };
    let ((a, steps_a), (b, steps_b)) = (episodes_per_s(&native), episodes_per_s(&onnx));
    println!(
        "episodes_per_s native={a:.1} onnx={b:.1} ratio={:.2} episodes={} steps native={steps_a} onnx={steps_b}",
        b / a,
        specs.len()
    );
    ExitCode::SUCCESS
}

/// A PPO actor of the trained shape with random weights.
fn random_ppo() -> HostPolicy {
    let mut rng = Rng::new(3);
    let mut layer = |name: &str, n_in: usize, n_out: usize| {
        let w = (0..n_in * n_out).map(|_| rng.uniform(-0.3, 0.3) as f32).collect();
        Dense::new(name, w, vec![0.0; n_out], n_in, n_out).expect("a layer")
    };
    let layers = vec![layer("0", OBS_DIM, 64), layer("1", 64, 64), layer("2", 64, 3)];
    HostPolicy::new(PolicyKind::Gaussian, HostMlp::from_layers(layers).expect("a chain")).expect("a policy")
}

fn fail(why: &str) -> ExitCode {
    eprintln!("error: {why}");
    ExitCode::from(2)
}
