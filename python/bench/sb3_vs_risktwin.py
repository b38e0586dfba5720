"""Stable-Baselines3 PPO against `risktwin train --algo ppo`, at the same environment steps,
variant and seed, on the same environment (SB3 at risktwin's PPO settings and at its own
defaults, each on a DummyVecEnv of risktwin/Driving-v0 as an SB3 user builds it): each learner's environment steps per second, and
each policy's held-out figures through risktwin.evaluate (SB3's deterministic actor written as
an ONNX model of the driver interface). Not a test (PyTorch is a ~3 GB install):

    .venv/bin/pip install ./python stable-baselines3==2.9.2 onnx==1.23.2
    .venv/bin/python python/bench/sb3_vs_risktwin.py --risktwin target/release/risktwin \
        --steps 200000 --variant full --seed 1 --out sb3-vs-risktwin

Prints one JSON document (also written to OUT/result.json).
"""

import argparse
import json
import os
import subprocess
import time

import numpy as np
import onnx
from onnx import TensorProto, helper, numpy_helper

import risktwin


# SB3's PPO at risktwin train's PPO settings (learn/src/ppo.rs): 64 environments x 64 steps per
# rollout, 10 epochs of 8 minibatches, the same rates, clip, coefficients and initial log-std, the
# same tanh 64-64 network. What SB3 has no counterpart for: the decaying imitation of the
# reference driver and the critic warm-up of risktwin's learner.
MATCHED = {
    "n_envs": 64,
    "ppo": dict(n_steps=64, batch_size=64 * 64 // 8, n_epochs=10, learning_rate=1e-3, gamma=0.99, gae_lambda=0.95,
                clip_range=0.2, vf_coef=0.5, ent_coef=0.0, max_grad_norm=0.5,
                policy_kwargs=dict(log_std_init=-1.2, net_arch=dict(pi=[64, 64], vf=[64, 64]))),
}
# SB3's own defaults (n_steps 2048, batch 64, lr 3e-4, log-std 0) on 8 environments.
DEFAULTS = {"n_envs": 8, "ppo": {}}


def sb3_train(steps, variant, seed, setting):
    from stable_baselines3 import PPO
    from stable_baselines3.common.env_util import make_vec_env

    envs = make_vec_env("risktwin/Driving-v0", n_envs=setting["n_envs"], seed=seed, env_kwargs={"variant": variant})
    model = PPO("MlpPolicy", envs, seed=seed, device="cpu", verbose=0, **setting["ppo"])
    started = time.perf_counter()
    model.learn(total_timesteps=steps)
    return model, time.perf_counter() - started


def sb3_to_onnx(model, path):
    """The deterministic action of SB3's MlpPolicy (policy_net Linear/Tanh layers, then
    action_net: the Gaussian's mean) as MatMul/Add/Tanh, with the driver interface's metadata."""
    policy = model.policy
    layers = [m for m in policy.mlp_extractor.policy_net if hasattr(m, "weight")] + [policy.action_net]
    nodes, inits, x = [], [], "obs"
    for i, layer in enumerate(layers):
        w = layer.weight.detach().cpu().numpy().astype(np.float32).T
        b = layer.bias.detach().cpu().numpy().astype(np.float32).reshape(1, -1)
        inits += [numpy_helper.from_array(w, f"w{i}"), numpy_helper.from_array(b, f"b{i}")]
        nodes += [helper.make_node("MatMul", [x, f"w{i}"], [f"m{i}"]), helper.make_node("Add", [f"m{i}", f"b{i}"], [f"z{i}"])]
        x = f"z{i}"
        if i < len(layers) - 1:
            nodes.append(helper.make_node("Tanh", [x], [f"h{i}"]))
            x = f"h{i}"
    nodes.append(helper.make_node("Identity", [x], ["action"]))
    graph = helper.make_graph(
        nodes,
        "sb3-ppo",
        [helper.make_tensor_value_info("obs", TensorProto.FLOAT, [1, risktwin.OBS_DIM])],
        [helper.make_tensor_value_info("action", TensorProto.FLOAT, [1, risktwin.ACT_DIM])],
        inits,
    )
    onnx_model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)], ir_version=8)
    for key, value in [("risktwin.observation_version", str(risktwin.OBSERVATION_VERSION)), ("risktwin.decision_rate_hz", "20")]:
        entry = onnx_model.metadata_props.add()
        entry.key, entry.value = key, value
    onnx.checker.check_model(onnx_model)
    onnx.save(onnx_model, path)


def figures(doc):
    overall = doc["overall"]["driver"]
    pick = lambda s: {k: round(s[k], 3) for k in ("share", "low", "high")}
    return {
        "label": doc["driver"],
        "collision": pick(overall["collision"]),
        "success": pick(overall["success"]),
        "route_completion": round(overall["route_completion"]["mean"], 3),
        "avg_speed_mps": round(overall["avg_speed_mps"]["mean"], 2),
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--risktwin", required=True, help="the risktwin binary")
    parser.add_argument("--steps", type=int, default=200_000)
    parser.add_argument("--variant", default="full", choices=risktwin.VARIANTS)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--out", default="sb3-vs-risktwin")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)

    ours = os.path.join(args.out, "risktwin")
    cmd = [args.risktwin, "train", "--algo", "ppo", "--variant", args.variant, "--steps", str(args.steps),
           "--seed", str(args.seed), "--out", ours, "--format", "json"]
    trained = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    ours_doc = risktwin.evaluate(os.path.join(ours, "policy.onnx"), seed=args.seed)
    result = {
        "steps": args.steps,
        "variant": args.variant,
        "seed": args.seed,
        # Its own figures: the training loop's wall time, without the held-out evaluation after it.
        "risktwin": {"envs": 64, "wall_s": round(trained["wall_s"], 1),
                     "env_steps_per_s": round(trained["env_steps_per_s"]), **figures(ours_doc)},
    }
    for name, setting in [("sb3_matched", MATCHED), ("sb3_defaults", DEFAULTS)]:
        model, wall_s = sb3_train(args.steps, args.variant, args.seed, setting)
        path = os.path.join(args.out, f"{name}.onnx")
        sb3_to_onnx(model, path)
        result[name] = {"envs": setting["n_envs"], "wall_s": round(wall_s, 1),
                        "env_steps_per_s": round(args.steps / wall_s), **figures(risktwin.evaluate(path, seed=args.seed))}
    # The reference driver's episodes of the same held-out set.
    result["reference"] = figures({"driver": ours_doc["reference"], "overall": {"driver": ours_doc["overall"]["reference"]}})
    text = json.dumps(result, indent=2)
    with open(os.path.join(args.out, "result.json"), "w") as f:
        f.write(text + "\n")
    print(text)


if __name__ == "__main__":
    main()
