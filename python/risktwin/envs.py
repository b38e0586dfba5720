"""The training environment of ``risktwin train`` as Gymnasium environments.

Both wrap the native vector of environments (``risktwin._native.VecEnv``): the observation,
action, 20 Hz decision rate, reward of each variant, termination (collision, leaving the road)
and truncation (the horizon or the route's end: the environment truncates itself, so
``gymnasium.make`` adds no time limit) are exactly the trainer's (docs/python.md)."""

import json

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _native
from ._native import ACT_DIM, DECISION_RATE_HZ, MAX_ENVS, OBS_DIM

def _spaces():
    """Fresh spaces for each environment (a space carries its own sampling state): every
    observation feature is clamped to [-10, 10]; actions beyond [-1, 1] are clamped."""
    return spaces.Box(-10.0, 10.0, (OBS_DIM,), np.float32), spaces.Box(-1.0, 1.0, (ACT_DIM,), np.float32)


def _seed(seed):
    """A seed as the native side takes it: an integer in [0, 2**64); None stays None."""
    if seed is None:
        return None
    if isinstance(seed, (bool, float)) or not isinstance(seed, (int, np.integer)) or not 0 <= seed < 2**64:
        raise ValueError(f"seed {seed!r} must be an integer in [0, 2**64) (one for all environments)")
    return int(seed)


def _stream(seed):
    """The scenario stream a constructor starts: `seed`, or stream 0 for None."""
    seed = _seed(seed)
    return 0 if seed is None else seed


def _no_render(render_mode):
    # TypeError, as for an argument the environment does not take: Stable-Baselines3's
    # make_vec_env asks for rgb_array and on TypeError builds the environment without it.
    if render_mode is not None:
        raise TypeError(f"render_mode {render_mode!r}: the environment does not render (record with risktwin simulate --record)")


def _restart(native, seed, options, fresh):
    """The observations a reset starts from: seed `seed`'s first episodes, the untouched current
    ones (`fresh`: built or just auto-reset), or every environment's next episode."""
    if options:
        raise ValueError(f"reset options {sorted(options)} are not supported")
    if seed is not None:
        return native.reset(seed)
    return native.obs() if fresh else native.reset()


def _finished(native):
    """The episodes the last step finished: {index: {"kind": ..., "metrics": {...}}}."""
    return {i: {"kind": kind, "metrics": json.loads(metrics)} for i, kind, metrics in native.finished()}


class DrivingEnv(gym.Env):
    """One driving environment: ``kind`` (one of ``risktwin.KINDS``; None: all five, as the
    trainer samples them), ``variant`` (``risktwin.VARIANTS``: its training reward; ``full``
    with ``kind=None`` also replays the trainer's risk-ranked scenarios), ``seed`` (the scenario
    stream; ``reset(seed=...)`` restarts it). Episode k after a seeded reset is episode k of
    environment 0 of ``DrivingVecEnv`` with that seed."""

    metadata = {"render_modes": [], "render_fps": DECISION_RATE_HZ}

    def __init__(self, kind=None, variant="full", seed=0, render_mode=None):
        _no_render(render_mode)
        self.render_mode = None
        self.observation_space, self.action_space = _spaces()
        self._native = _native.VecEnv(1, kind=kind, variant=variant, seed=_stream(seed))
        # True while the current episode is untouched (built, or just auto-reset): the next
        # reset() without a seed starts it rather than skipping it.
        self._fresh = True
        self._over = False

    def reset(self, *, seed=None, options=None):
        seed = _seed(seed)
        super().reset(seed=seed)
        obs = _restart(self._native, seed, options, self._fresh)
        self._fresh, self._over = False, False
        return obs[0], {}

    def step(self, action):
        if self._over:
            raise RuntimeError("the episode is over: call reset()")
        action = np.asarray(action, dtype=np.float32)
        if action.shape != (ACT_DIM,):
            raise ValueError(f"action has shape {action.shape}, not ({ACT_DIM},)")
        obs, rewards, terminated, truncated, final_obs = self._native.step(action.reshape(1, ACT_DIM))
        info = {}
        terminated, truncated = bool(terminated[0]), bool(truncated[0])
        if terminated or truncated:
            info = _finished(self._native)[0]
            self._fresh, self._over = True, True
            return final_obs[0], float(rewards[0]), terminated, truncated, info
        self._fresh = False
        return obs[0], float(rewards[0]), terminated, truncated, info


class DrivingVecEnv(VectorEnv):
    """``num_envs`` environments stepped together natively (in parallel, the GIL released),
    as ``risktwin train`` steps them: ``gymnasium.make_vec("risktwin/Driving-v0", num_envs=n)``.
    A finished episode resets in the same step (``AutoresetMode.SAME_STEP``): ``infos`` then
    holds ``final_obs`` (and mask ``_final_obs``) and ``final_info`` (kind and metrics of the
    finished episodes, mask ``_final_info``), laid out as Gymnasium's ``SyncVectorEnv`` lays
    them out: ``infos["final_info"]["metrics"]["collision"][i]``. ``reset(seed=s)`` restarts every environment on
    seed s's stream; ``reset()`` starts each one's next episode."""

    metadata = {"render_modes": [], "render_fps": DECISION_RATE_HZ, "autoreset_mode": AutoresetMode.SAME_STEP}

    def __init__(self, num_envs=1, kind=None, variant="full", seed=0, render_mode=None):
        _no_render(render_mode)
        self.render_mode = None
        # Checked before any space is sized by it.
        if isinstance(num_envs, bool) or not isinstance(num_envs, (int, np.integer)) or not 1 <= num_envs <= MAX_ENVS:
            raise ValueError(f"num_envs = {num_envs!r} is out of range [1, {MAX_ENVS}]")
        self._native = _native.VecEnv(int(num_envs), kind=kind, variant=variant, seed=_stream(seed))
        self.num_envs = self._native.num_envs
        self.single_observation_space, self.single_action_space = _spaces()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self._fresh = True

    def reset(self, *, seed=None, options=None):
        seed = _seed(seed)
        super().reset(seed=seed)
        obs = _restart(self._native, seed, options, self._fresh)
        self._fresh = False
        return obs, {}

    def step(self, actions):
        actions = np.ascontiguousarray(actions, dtype=np.float32)
        if actions.shape != (self.num_envs, ACT_DIM):
            raise ValueError(f"actions have shape {actions.shape}, not ({self.num_envs}, {ACT_DIM})")
        obs, rewards, terminated, truncated, final_obs = self._native.step(actions)
        self._fresh = False
        infos = {}
        done = terminated | truncated
        if done.any():
            # Laid out as Gymnasium's own vector environments lay it out (one entry per
            # finished environment; arrays with masks, nested for final_info's dicts).
            finished = _finished(self._native)
            for i in np.flatnonzero(done):
                i = int(i)
                infos = self._add_info(infos, {"final_obs": final_obs[i], "final_info": finished[i]}, i)
        return obs, rewards.astype(np.float64), terminated, truncated, infos
