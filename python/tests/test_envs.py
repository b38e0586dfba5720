"""The Gymnasium environments: Gymnasium's own checker, seeded resets, the single env as
environment 0 of the vector env, termination and truncation apart, bad input raising."""

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import risktwin
from risktwin.envs import DrivingEnv, DrivingVecEnv


def keep_lane(obs):
    """A deterministic action that depends on the observation (steer against the lane offset)."""
    return np.array([np.clip(-0.5 * obs[2], -1, 1), 0.4, 0.0], dtype=np.float32)


@pytest.mark.parametrize("variant", risktwin.VARIANTS)
def test_gymnasium_env_checker_passes_for_every_variant(variant):
    env = gym.make("risktwin/Driving-v0", variant=variant, seed=3)
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_spaces_are_the_driver_interface():
    env = DrivingEnv()
    assert env.observation_space.shape == (risktwin.OBS_DIM,) == (24,)
    assert env.action_space.shape == (risktwin.ACT_DIM,) == (3,)
    assert env.observation_space.dtype == env.action_space.dtype == np.float32
    assert risktwin.DECISION_RATE_HZ == 20.0 and risktwin.STEP_S == 0.05
    obs, info = env.reset(seed=1)
    assert obs.dtype == np.float32 and obs.shape == (24,) and info == {}


def run_episodes(env, seed, episodes):
    """Observations, rewards and endings of `episodes` episodes after a seeded reset."""
    trace = []
    obs, _ = env.reset(seed=seed)
    for _ in range(episodes):
        while True:
            obs, reward, terminated, truncated, info = env.step(keep_lane(obs))
            trace.append((obs.copy(), reward, terminated, truncated))
            if terminated or truncated:
                trace.append(info["metrics"])
                obs, _ = env.reset()
                break
    return trace


def test_seeded_resets_reproduce_and_other_seeds_differ():
    env = DrivingEnv(kind="cut-in", variant="base")
    first = run_episodes(env, 7, 3)
    again = run_episodes(env, 7, 3)
    assert len(first) == len(again)
    for a, b in zip(first, again):
        if isinstance(a, dict):
            assert a == b
        else:
            np.testing.assert_array_equal(a[0], b[0])
            assert a[1:] == b[1:]
    other = run_episodes(env, 8, 1)
    assert not np.array_equal(first[0][0], other[0][0])


def test_the_single_env_is_environment_0_of_the_vector_env_step_for_step():
    single = DrivingEnv(variant="risk-only", seed=5)
    vec = DrivingVecEnv(num_envs=4, variant="risk-only", seed=5)
    obs, _ = single.reset()
    vobs, _ = vec.reset()
    np.testing.assert_array_equal(obs, vobs[0])
    endings = 0
    for _ in range(700):  # beyond two 15 s episodes
        action = keep_lane(obs)
        actions = np.stack([keep_lane(o) for o in vobs])
        np.testing.assert_array_equal(actions[0], action)
        obs, reward, terminated, truncated, info = single.step(action)
        vobs, vrewards, vterm, vtrunc, vinfo = vec.step(actions)
        assert (terminated, truncated) == (bool(vterm[0]), bool(vtrunc[0]))
        assert reward == vrewards[0]
        if terminated or truncated:
            endings += 1
            assert vinfo["_final_obs"][0] and vinfo["_final_info"][0]
            np.testing.assert_array_equal(obs, vinfo["final_obs"][0])
            assert vinfo["final_info"]["kind"][0] == info["kind"]
            for key, value in info["metrics"].items():
                assert vinfo["final_info"]["metrics"][key][0] == value, key
            assert not (terminated and truncated)
            obs, _ = single.reset()
        np.testing.assert_array_equal(obs, vobs[0])
    assert endings >= 2


def test_the_vector_env_gives_what_the_native_one_gives_step_for_step():
    steps, n = 700, 4  # beyond two 15 s episodes in each environment
    actions = np.random.default_rng(11).uniform(-1, 1, (steps, n, 3)).astype(np.float32)
    native = risktwin._native.native_rollout(actions, variant="full", seed=9)
    vec = DrivingVecEnv(num_envs=n, variant="full", seed=9)
    vec.reset(seed=9)
    endings = 0
    for t in range(steps):
        obs, rewards, terminated, truncated, _ = vec.step(actions[t])
        np.testing.assert_array_equal(obs, native[0][t])
        np.testing.assert_array_equal(rewards, native[1][t].astype(np.float64))
        np.testing.assert_array_equal(terminated, native[2][t])
        np.testing.assert_array_equal(truncated, native[3][t])
        endings += int((terminated | truncated).sum())
    assert endings >= 2 * n


def test_a_crash_terminates_and_the_horizon_truncates():
    env = DrivingEnv(kind="emergency-braking", variant="full", seed=2)
    env.reset(seed=2)
    while True:  # full throttle into the braking lead
        _, _, terminated, truncated, info = env.step(np.array([0.0, 1.0, 0.0], dtype=np.float32))
        if terminated or truncated:
            break
    assert terminated and not truncated and info["metrics"]["collision"]
    assert info["metrics"]["ended"] == "collision" and info["kind"] == "emergency-braking"
    # Only what the training environment measures (no risk score, TTC or closest distance).
    assert "risk_score" not in info["metrics"] and "min_ttc_s" not in info["metrics"]
    with pytest.raises(RuntimeError, match="call reset"):
        env.step(np.zeros(3, dtype=np.float32))
    env.reset()
    steps = 0
    while True:  # standing still: the horizon ends it
        _, _, terminated, truncated, info = env.step(np.array([0.0, 0.0, 1.0], dtype=np.float32))
        steps += 1
        if terminated or truncated:
            break
    assert truncated and not terminated and steps >= 300, steps
    assert not info["metrics"]["collision"] and not info["metrics"]["success"]
    assert info["metrics"]["ended"] == "out-of-time"


def test_make_vec_gives_the_native_vector_env():
    envs = gym.make_vec("risktwin/Driving-v0", num_envs=8, variant="ttc", seed=1)
    assert isinstance(envs.unwrapped, DrivingVecEnv)
    obs, _ = envs.reset(seed=1)
    assert obs.shape == (8, 24) and obs.dtype == np.float32
    obs, rewards, terminated, truncated, _ = envs.step(np.zeros((8, 3), dtype=np.float32))
    assert rewards.shape == terminated.shape == truncated.shape == (8,)
    assert terminated.dtype == truncated.dtype == np.bool_
    envs.close()


def test_bad_input_raises_with_the_message():
    with pytest.raises(ValueError, match="unknown"):
        DrivingEnv(kind="roundabout")
    with pytest.raises(ValueError, match="variant"):
        DrivingEnv(variant="safest")
    with pytest.raises(ValueError, match="out of range"):
        DrivingVecEnv(num_envs=0)
    with pytest.raises(TypeError, match="does not render"):
        gym.make("risktwin/Driving-v0", render_mode="rgb_array")  # what SB3's make_vec_env tries first
    env = DrivingEnv()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        env.step(np.zeros(4, dtype=np.float32))
    with pytest.raises(ValueError, match="integer"):
        env.reset(seed=-1)
    with pytest.raises(ValueError, match="integer"):
        env.reset(seed=2**64)
    for bad in [0, -1, 10**9, 2**70]:  # refused before any space is sized by it
        with pytest.raises(ValueError, match="out of range"):
            DrivingVecEnv(num_envs=bad)
    assert DrivingVecEnv(num_envs=np.int32(2)).num_envs == 2
    assert DrivingEnv(seed=None).reset()[0].shape == (24,)
    vec = DrivingVecEnv(num_envs=2)
    vec.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        vec.step(np.zeros((3, 3), dtype=np.float32))
    with pytest.raises(ValueError, match="shape"):
        vec.step(np.zeros(6, dtype=np.float32))


def test_a_strided_action_array_is_read_as_its_values():
    wide = np.random.default_rng(3).uniform(-1, 1, (2, 6)).astype(np.float32)
    strided, dense = DrivingVecEnv(num_envs=2, seed=4), DrivingVecEnv(num_envs=2, seed=4)
    strided.reset(seed=4), dense.reset(seed=4)
    a = strided._native.step(wide[:, ::2])  # the native side's own copy of a non-contiguous view
    b = dense._native.step(np.ascontiguousarray(wide[:, ::2]))
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)


def test_the_spaces_are_each_environments_own():
    one, two = DrivingEnv(), DrivingEnv()
    assert one.action_space is not two.action_space
    one.action_space.seed(1)
    two.action_space.seed(1)
    first = one.action_space.sample()
    one.action_space.sample()  # advancing one's sampler leaves two's where it was
    np.testing.assert_array_equal(two.action_space.sample(), first)
