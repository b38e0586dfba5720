#!/usr/bin/env python3
"""Peer benchmark: highway-env `highway-fast-v0` (default config) steps per second.

Times a fixed number of environment steps with a constant IDLE action (the controlled
vehicle's policy is not what is measured; the surrounding IDM/MOBIL traffic is) and prints
one JSON line:
  {"env_steps_per_s": ..., "vehicles": ..., "vehicle_steps_per_s": ...}
`vehicles` is len(env.unwrapped.road.vehicles) (controlled vehicle included), averaged over
the timed steps. Every env step runs `simulation_frequency / policy_frequency` simulation
sub-steps (5 / 1 in highway-fast-v0), each of which moves every vehicle once, so
vehicle_steps_per_s = env_steps_per_s * sim_steps_per_env_step * vehicles: the figure
comparable to a traffic simulator's vehicle-steps/s. Only env.step is timed; resets after a
crash or timeout are excluded (their count is reported).

Needs `pip install highway-env` (use a throwaway venv, e.g. /tmp/hwenv).
Usage: highway_env_bench.py [--steps N] [--seed S]
"""
import argparse
import json
import time

import gymnasium as gym
import highway_env  # noqa: F401  (registers the environments)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--steps", type=int, default=500)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    env = gym.make("highway-fast-v0")
    env.reset(seed=args.seed)
    config = env.unwrapped.config
    sub_steps = int(config["simulation_frequency"] // config["policy_frequency"])
    idle = 1  # DiscreteMetaAction: 1 = IDLE
    steps, vehicle_sum, resets, elapsed = 0, 0, 0, 0.0
    while steps < args.steps:
        start = time.perf_counter()
        _, _, terminated, truncated, _ = env.step(idle)
        elapsed += time.perf_counter() - start
        vehicle_sum += len(env.unwrapped.road.vehicles)
        steps += 1
        if terminated or truncated:
            env.reset(seed=args.seed + resets + 1)
            resets += 1
    env.close()
    env_rate = steps / elapsed
    vehicles = vehicle_sum / steps
    print(json.dumps({
        "env_steps_per_s": round(env_rate, 2),
        "vehicles": round(vehicles, 2),
        "sim_steps_per_env_step": sub_steps,
        "vehicle_steps_per_s": round(env_rate * sub_steps * vehicles, 1),
        "steps": steps,
        "resets": resets,
        "env": "highway-fast-v0",
    }))


if __name__ == "__main__":
    main()
