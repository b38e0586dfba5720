#!/usr/bin/env python3
"""CommonRoad-CriMe 0.4.5 as the peer of `risktwin criticality`.

Reference mode (default): for one CommonRoad scenario, CriMe's HW, THW, TTC and ALongReq of the
ego against every other dynamic obstacle at every time step where both have a state, as CSV on
stdout with the header of `risktwin criticality --format csv` plus one diagnostic column:

    time_step,other_id,hw,thw,ttc,a_long_req,other_a

`other_a` is the other's longitudinal acceleration as CriMe preprocesses it
(numpy.gradient of the recorded speeds over time, docs/criticality.md, "How CriMe 0.4.5
computes" §1); the agreement check uses it to tell braking others (< 0) apart for TTC. Values
are printed with repr(), so `inf`/`nan` are spelled as in our CSV.

Timing mode (`--time [--repeat N]`): after the imports, reads the scenario once
(`crime_load_seconds=`, CommonRoadFileReader + configuration), then runs CriMe's own
whole-scenario evaluation, CriMeInterface.evaluate_scenario([HW, THW, TTC, ALongReq], first,
last) for the ego over all its time steps, N times (default 1) on a fresh CriMeInterface, and
prints `crime_seconds=<best wall seconds of one evaluation>` and `crime_cpu_seconds=` (its CPU
time, steadier on a loaded machine; interpreter start-up, imports and file reading excluded). Each measure's `compute` is wrapped so that a cell CriMe crashes on
gives NaN instead of aborting the whole evaluation, as in reference mode.

`--initial-lanelet ID` builds CriMe's reference path (its §2 L0) around lanelet ID instead of
the first lanelet of the ego's initial `center_lanelet_assignment` (a Python set, whose order
decides when the ego starts on overlapping lanelets); used to show what the choice of L0 does
(docs/criticality.md, DEU_AAH1-2_7900).

Version issue (docs/criticality.md, "How CriMe 0.4.5 computes" §8): with commonroad-clcs 2025.x
the CLCS raises CartesianProjectionDomainError where CriMe 0.4.5 catches ValueError; the ego
CLCS is wrapped so that its projection errors become the ValueError CriMe's source intends.  Any other exception
from a measure gives NaN for that cell, as CriMe's crash would.

Usage: crime_reference.py SCENARIO.xml EGO_ID [--time [--repeat N]] [--initial-lanelet ID]
"""

import logging
import math
import sys
import time

import numpy as np
import commonroad_crime.data_structure.base as crime_base
from commonroad.common.file_reader import CommonRoadFileReader
from commonroad_crime.data_structure.configuration import CriMeConfiguration
from commonroad_crime.data_structure.crime_interface import CriMeInterface
from commonroad_crime.measure.acceleration.a_long_req import ALongReq
from commonroad_crime.measure.distance.hw import HW
from commonroad_crime.measure.time.thw import THW
from commonroad_crime.measure.time.ttc import TTC

_CLCS = crime_base.CurvilinearCoordinateSystem


class _ValueErrorClcs:
    """The ego CLCS, raising ValueError on projection-domain errors as CriMe expects."""

    def __init__(self, *args, **kwargs):
        self._inner = _CLCS(*args, **kwargs)

    def convert_to_curvilinear_coords(self, x, y):
        try:
            return self._inner.convert_to_curvilinear_coords(x, y)
        except ValueError:
            raise
        except Exception as e:  # CartesianProjectionDomainError
            raise ValueError(str(e)) from e

    def __getattr__(self, name):
        return getattr(self._inner, name)


crime_base.CurvilinearCoordinateSystem = _ValueErrorClcs


def configure(path, ego_id, initial_lanelet=None):
    scenario, _ = CommonRoadFileReader(path).open(lanelet_assignment=True)
    if initial_lanelet is not None:
        ego = scenario.obstacle_by_id(ego_id)
        ego.prediction.center_lanelet_assignment[ego.initial_state.time_step] = {initial_lanelet}
    config = CriMeConfiguration()
    config.update(ego_id=ego_id, sce=scenario)
    return scenario, config


def gradient_accel(obstacle, dt):
    states = [obstacle.initial_state] + list(obstacle.prediction.trajectory.state_list)
    v = np.array([s.velocity for s in states], dtype=float)
    t = np.array([s.time_step * dt for s in states], dtype=float)
    if len(v) < 2:
        return {states[0].time_step: math.nan}
    a = np.gradient(v, t)
    return {s.time_step: float(x) for s, x in zip(states, a)}


def safe(measure, other_id, t):
    try:
        value = measure.compute(other_id, t, verbose=False)
        return math.nan if value is None else float(value)
    except Exception:  # CriMe crashes on this cell: NaN, as in the reference data
        return math.nan


def reference(path, ego_id, initial_lanelet=None):
    scenario, config = configure(path, ego_id, initial_lanelet)
    ego = scenario.obstacle_by_id(ego_id)
    measures = [HW(config), THW(config), TTC(config), ALongReq(config)]
    others = [o for o in scenario.dynamic_obstacles if o.obstacle_id != ego_id]
    accel = {}
    for o in others:
        try:
            accel[o.obstacle_id] = gradient_accel(o, scenario.dt)
        except Exception:
            accel[o.obstacle_id] = {}
    first, last = ego.initial_state.time_step, ego.prediction.final_time_step
    print("time_step,other_id,hw,thw,ttc,a_long_req,other_a")
    for t in range(first, last + 1):
        for o in sorted(others, key=lambda o: o.obstacle_id):
            if o.state_at_time(t) is None:
                continue
            values = [safe(m, o.obstacle_id, t) for m in measures]
            a = accel[o.obstacle_id].get(t, math.nan)
            print(",".join([str(t), str(o.obstacle_id)] + [repr(x) for x in values] + [repr(a)]))


def tolerant(measure):
    """`measure` whose per-cell `compute` returns NaN where CriMe raises."""

    class Tolerant(measure):
        def compute(self, *args, **kwargs):
            try:
                return super().compute(*args, **kwargs)
            except Exception:
                return math.nan

    return Tolerant


def timing(path, ego_id, repeat):
    t0 = time.perf_counter()
    scenario, config = configure(path, ego_id)
    ego = scenario.obstacle_by_id(ego_id)
    print(f"crime_load_seconds={time.perf_counter() - t0:.3f}")
    best = best_cpu = math.inf
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        CriMeInterface(config).evaluate_scenario(
            [tolerant(m) for m in (HW, THW, TTC, ALongReq)], ego.initial_state.time_step, ego.prediction.final_time_step, verbose=False
        )
        best = min(best, time.perf_counter() - t0)
        best_cpu = min(best_cpu, time.process_time() - c0)
    print(f"crime_seconds={best:.3f}")
    print(f"crime_cpu_seconds={best_cpu:.3f}")


def main():
    logging.disable(logging.CRITICAL)
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    path, ego_id, flags = sys.argv[1], int(sys.argv[2]), sys.argv[3:]

    def option(name, default):
        return int(flags[flags.index(name) + 1]) if name in flags else default

    if "--time" in flags:
        timing(path, ego_id, option("--repeat", 1))
    else:
        reference(path, ego_id, option("--initial-lanelet", None))


if __name__ == "__main__":
    main()
