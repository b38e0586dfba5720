"""RiskTwin's driving twin from Python (docs/python.md).

- ``risktwin.envs.DrivingEnv`` / ``DrivingVecEnv``: the training environment as Gymnasium
  environments, registered as ``risktwin/Driving-v0`` (``gymnasium.make`` and
  ``gymnasium.make_vec`` after ``import risktwin``).
- ``risktwin.evaluate(driver, ...)``: any driver SPEC or a Python callable ``obs -> action``
  over the held-out set or a library: the document of ``risktwin evaluate --format json``.
- ``risktwin.Library(path)``: a scenario library's ranking, specs and stored outcomes.
"""

import json as _json
import operator as _operator
import os as _os

import gymnasium as _gym

from . import _native
from ._native import (
    ACT_DIM,
    DECISION_RATE_HZ,
    KINDS,
    OBS_DIM,
    OBSERVATION_VERSION,
    STEP_S,
    VARIANTS,
    RiskTwinError,
)

__all__ = [
    "ACT_DIM",
    "DECISION_RATE_HZ",
    "KINDS",
    "OBS_DIM",
    "OBSERVATION_VERSION",
    "STEP_S",
    "VARIANTS",
    "Library",
    "RiskTwinError",
    "evaluate",
]


def _count(name, value):
    """An optional non-negative integer argument, checked before it crosses to Rust."""
    if value is None:
        return None
    try:
        number = None if isinstance(value, bool) else _operator.index(value)  # int, numpy integers
    except TypeError:
        number = None
    if number is None or not 0 <= number < 2**64:
        raise ValueError(f"{name} = {value!r} must be an integer in [0, 2**64)")
    return number


def evaluate(driver, *, seed=None, per_kind=None, library=None, floor=False, threads=None, label=None):
    """Drives ``driver`` over the held-out set of run seed ``seed`` (``per_kind`` scenarios of
    each kind; 1 and 12 when not given) or, with ``library`` (which takes neither), every generated scenario of that library file (whose
    outcomes then gain the driver's), beside the reference driver; with ``floor`` also the
    achievable floor. ``driver`` is a SPEC (``"idm"``, ``"PATH.safetensors"``, ``"PATH.onnx"``)
    or a callable taking the observation (float32, shape (24,)) and returning three numbers
    (steering, throttle, brake in [-1, 1]); a callable is called once per 50 ms decision and
    is labelled ``python:<qualname>`` unless ``label`` says otherwise (required with
    ``library``). Returns the document ``risktwin evaluate --format json`` prints, as a dict."""
    if isinstance(driver, _os.PathLike):
        driver = _os.fspath(driver)
    text = _native.evaluate(
        driver,
        seed=_count("seed", seed),
        per_kind=_count("per_kind", per_kind),
        library=None if library is None else _os.fspath(library),
        floor=floor,
        threads=_count("threads", threads),
        label=label,
    )
    return _json.loads(text)


class Library:
    """A scenario library file (``risktwin scenarios generate --db FILE`` makes one)."""

    def __init__(self, path):
        self._native = _native.Library(str(path))

    def rank(self, top=None, *, kind=None, label="idm"):
        """The ``top`` riskiest scenarios (all when None), of one kind or all, by the latest
        outcome of the driver ``label``: the items of ``risktwin scenarios rank --format json``."""
        return _json.loads(self._native.rank(top, kind=kind, label=label))

    def scenario(self, scenario_id):
        """One scenario: ``id``, ``spec`` (a ``--spec`` file's content), ``origin``,
        ``parent_id``, ``generation`` and ``outcomes`` (each ``label``, ``metrics``, ``risk``)."""
        return _json.loads(self._native.scenario(scenario_id))


_gym.register(
    id="risktwin/Driving-v0",
    entry_point="risktwin.envs:DrivingEnv",
    vector_entry_point="risktwin.envs:DrivingVecEnv",
)
