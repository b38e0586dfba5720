#!/usr/bin/env python3
"""CriMe 0.4.5's intermediate quantities behind its THW, to explain where `risktwin criticality`
and CriMe disagree (docs/criticality.md, DEU_AAH1-2_7900).

Usage: crime_thw_probe.py SCENARIO.xml EGO_ID [--lanelet ID] [T:OTHER ...]

Prints, with CriMe's own objects (commonroad-io scenario, CriMe's ego curvilinear frame):

1. The choice of L0 (CriMe's §2): the lanelets containing the ego's centre at its initial step
   in the order CriMe iterates them (it takes the first), commonroad-io's
   `find_most_likely_lanelet_by_state` (the containing lanelet whose direction is closest to the
   ego's heading, which is what risktwin takes), each candidate's direction at the ego and its
   successors, and the lanelets the ego's centre is in at its last step.
2. For every cell T:OTHER (default: none): CriMe's THW, the same-lanelet test and both
   expanded lanelet sets, the arc lengths of the other's rear and the ego's front at T, and the
   ego's walk over its future steps (front s, lateral offset, first step past the other's rear)
   in CriMe's frame on L0 and, with `--lanelet ID`, in a frame CriMe builds on lanelet ID.
3. Over all cells, why CriMe's THW is inf where it is: not the same lanelet, the other's point
   outside the projection domain, the ego already past, or the ego's recorded future never
   reaching the other's rear (with the largest front s it reaches), for L0 and for `--lanelet`.

Needs the venv of crime_reference.py (commonroad-crime==0.4.5).
"""

import logging
import math
import sys

import crime_reference as ref
import commonroad_crime.utility.general as crime_general
from commonroad_crime.measure.time.thw import THW


def project(clcs, point):
    try:
        return clcs.convert_to_curvilinear_coords(point[0], point[1])
    except ValueError:
        return None


def frame(path, ego_id, lanelet):
    scenario, config = ref.configure(path, ego_id, lanelet)
    return scenario, THW(config)


def initial_lanelet(scenario, ego_id):
    ego = scenario.obstacle_by_id(ego_id)
    t0 = ego.initial_state.time_step
    net = scenario.lanelet_network
    candidates = list(ego.prediction.center_lanelet_assignment[t0])
    likely = net.find_most_likely_lanelet_by_state([ego.initial_state])
    print(f"ego {ego_id} at step {t0}: centre {ego.initial_state.position}, heading {ego.initial_state.orientation:.4f} rad")
    print(f"  containing lanelets in CriMe's order: {candidates} -> CriMe's L0 = {candidates[0]}")
    print(f"  commonroad-io find_most_likely_lanelet_by_state: {likely}")
    for lid in candidates:
        lanelet = net.find_lanelet_by_id(lid)
        direction = lanelet.orientation_by_position(ego.initial_state.position)
        print(f"  lanelet {lid}: direction at the ego {direction:.4f} rad, successors {lanelet.successor}")
    last = ego.prediction.final_time_step
    print(f"  ego centre at its last step {last}: lanelets {sorted(ego.prediction.center_lanelet_assignment[last])}")


def probe_cell(scenario, thw, t, other_id):
    ego = thw.ego_vehicle
    other = scenario.obstacle_by_id(other_id)
    value = thw.compute(other_id, t, verbose=False)
    net = scenario.lanelet_network

    def expanded(vehicle):
        hit = set(net.find_lanelet_by_shape(vehicle.occupancy_at_time(t).shape))
        return sorted(hit | {n for lid in hit for n in (net.find_lanelet_by_id(lid).predecessor or [])}
                      | {n for lid in hit for n in (net.find_lanelet_by_id(lid).successor or [])})

    same = crime_general.check_in_same_lanelet(net, ego, other, t)
    print(f"  t={t} other={other_id}: CriMe THW {value!r}; same lanelet {same} "
          f"(ego {expanded(ego)}, other {expanded(other)})")
    so = project(thw.clcs, other.state_at_time(t).position)
    se = project(thw.clcs, ego.state_at_time(t).position)
    if so is None or se is None:
        print(f"    projection failed: other {so}, ego {se}")
        return
    rear = so[0] - thw._compute_vehicle_add_on(other)
    half = thw._compute_vehicle_add_on(ego)
    print(f"    other rear s = {rear:.3f} (lateral {so[1]:.2f}); ego front s = {se[0] + half:.3f} (lateral {se[1]:.2f})")
    for k in range(t + 1, ego.prediction.final_time_step + 1):
        p = project(thw.clcs, ego.state_at_time(k).position)
        if p is None:
            print(f"    step {k}: ego outside the projection domain")
            return
        passed = p[0] + half > rear
        if passed or (k - t) % 25 == 0 or k == ego.prediction.final_time_step:
            print(f"    step {k}: ego front s = {p[0] + half:.3f}, lateral {p[1]:.2f}" + (" -> passes" if passed else ""))
        if passed:
            return


def inf_causes(scenario, thw):
    """Counts CriMe's inf THW cells by cause."""
    ego = thw.ego_vehicle
    net = scenario.lanelet_network
    causes = {}
    last = ego.prediction.final_time_step
    half = thw._compute_vehicle_add_on(ego)
    ego_s = {k: project(thw.clcs, ego.state_at_time(k).position) for k in range(ego.initial_state.time_step, last + 1)}
    for t in range(ego.initial_state.time_step, last + 1):
        for other in scenario.dynamic_obstacles:
            if other.obstacle_id == ego.obstacle_id or other.state_at_time(t) is None:
                continue
            if not crime_general.check_in_same_lanelet(net, ego, other, t):
                cause = "not the same lanelet"
            else:
                so = project(thw.clcs, other.state_at_time(t).position)
                if so is None:
                    cause = "other outside the projection domain"
                elif ego_s[t] is None:
                    continue  # NaN, not inf
                else:
                    rear = so[0] - thw._compute_vehicle_add_on(other)
                    if ego_s[t][0] + half > rear:
                        cause = "ego already past"
                    else:
                        future = [ego_s[k] for k in range(t + 1, last + 1)]
                        if any(p is None for p in future):
                            continue  # NaN
                        if any(p[0] + half > rear for p in future):
                            continue  # finite
                        cause = "ego's recorded future never reaches the other's rear"
            causes[cause] = causes.get(cause, 0) + 1
    for cause, n in sorted(causes.items(), key=lambda kv: -kv[1]):
        print(f"  {n:5d} cells: {cause}")


def main():
    logging.disable(logging.CRITICAL)
    if len(sys.argv) < 3:
        sys.exit(__doc__)
    path, ego_id = sys.argv[1], int(sys.argv[2])
    rest = sys.argv[3:]
    lanelet = int(rest[rest.index("--lanelet") + 1]) if "--lanelet" in rest else None
    cells = [tuple(int(x) for x in a.split(":")) for a in rest if ":" in a]
    scenario, thw = frame(path, ego_id, None)
    initial_lanelet(scenario, ego_id)
    frames = [("CriMe's L0", scenario, thw)]
    if lanelet is not None:
        frames.append((f"L0 = lanelet {lanelet}",) + frame(path, ego_id, lanelet))
    for name, sce, m in frames:
        print(f"\n== CriMe, reference path on {name} ==")
        for t, other_id in cells:
            probe_cell(sce, m, t, other_id)
        print("  inf THW cells by cause:")
        inf_causes(sce, m)


if __name__ == "__main__":
    main()
