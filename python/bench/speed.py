"""Environment steps per second, side by side in one process: the native vector of
environments alone (no Python in the loop), the same environments through
risktwin.envs.DrivingVecEnv (Gymnasium's vector API, numpy in and out), the single
DrivingEnv, and highway-env's highway-fast-v0 (the Gymnasium driving environment RL work uses)
if it is installed. Zero actions everywhere (the same work for every path). Not a test:

    .venv/bin/pip install ./python highway-env==1.12.1
    .venv/bin/python python/bench/speed.py [--envs 64] [--steps 200] [--rounds 5]
"""

import argparse
import json
import time

import numpy as np

import risktwin
from risktwin import _native
from risktwin.envs import DrivingEnv, DrivingVecEnv


def per_s(steps, started):
    return steps / (time.perf_counter() - started)


def vector(n, steps):
    env = DrivingVecEnv(num_envs=n, seed=0)
    env.reset(seed=0)
    actions = np.zeros((n, risktwin.ACT_DIM), dtype=np.float32)
    started = time.perf_counter()
    for _ in range(steps):
        env.step(actions)
    return per_s(n * steps, started)


def single(steps):
    env = DrivingEnv(seed=0)
    env.reset(seed=0)
    action = np.zeros(risktwin.ACT_DIM, dtype=np.float32)
    started = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return per_s(steps, started)


def highway(steps):
    try:
        import gymnasium as gym
        import highway_env  # noqa: F401  (registers its environments)
    except ImportError:
        return None
    env = gym.make("highway-fast-v0")
    env.reset(seed=0)
    started = time.perf_counter()
    for _ in range(steps):
        _, _, terminated, truncated, _ = env.step(env.action_space.sample())
        if terminated or truncated:
            env.reset()
    return per_s(steps, started)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--envs", type=int, default=64)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    # Native and Python-side rounds interleaved, the median of each: drift of the machine's load
    # falls on both paths alike.
    native, through_python = [], []
    for _ in range(args.rounds):
        native.append(_native.native_steps_per_s(args.envs, args.steps, seed=0))
        through_python.append(vector(args.envs, args.steps))
    native, through_python = float(np.median(native)), float(np.median(through_python))
    one = single(args.steps * 10)
    peer = highway(min(args.steps, 200))
    result = {
        "envs": args.envs,
        "rounds": args.rounds,
        "native_vec_steps_per_s": round(native),
        "python_vec_steps_per_s": round(through_python),
        "python_vec_over_native": round(through_python / native, 3),
        "python_single_steps_per_s": round(one),
        "highway_fast_v0_steps_per_s": None if peer is None else round(peer, 1),
        "python_vec_over_highway": None if peer is None else round(through_python / peer, 1),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()
