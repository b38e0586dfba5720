#!/usr/bin/env python3
"""Agreement of `risktwin criticality` with CommonRoad-CriMe reference CSVs (issue 4, part 4).

Usage: crime_compare.py RISKTWIN_BINARY REFERENCE_DIR SCENARIO_DIR [--examples N]

REFERENCE_DIR holds one `<scenario>.csv` per scenario as written by crime_reference.py
(columns time_step,other_id,hw,thw,ttc,a_long_req,other_a). For each, this runs
`risktwin criticality --commonroad SCENARIO_DIR/<scenario>.xml --ego ID --format json` with the
ego id of `<scenario>.yaml`, joins the cells on (time_step, other_id) and counts a cell as
agreeing when both values are finite and |ours − crime| ≤ max(5 % of |crime|, abs_tol), or both
are inf of the same sign, or both NaN. abs_tol: 0.5 m for HW, 0.1 s for THW and TTC,
0.1 m/s² for a_long_req. A cell present on one side only disagrees.

Criteria (issue 4): THW ≥ 95 % of cells over all scenarios; HW and TTC ≥ 95 % of cells over the
scenarios whose ego lane heads along +x (|heading| ≤ 0.1 rad at the ego's start), TTC counting
only cells where the other is not braking (CriMe's other_a ≥ 0; CriMe drops the sign of the
other's acceleration). Prints one line per scenario and measure, the pooled figures, and the
first N disagreeing cells of each measure and scenario (both values) for the divergence notes.
Only the Python standard library is needed.
"""

import csv
import json
import math
import os
import subprocess
import sys

MEASURES = [("hw", 0.5), ("thw", 0.1), ("ttc", 0.1), ("a_long_req", 0.1)]
OURS_KEY = {"hw": "hw", "thw": "thw", "ttc": "ttc", "a_long_req": "a_long_req"}
PLUS_X_RAD = 0.1


def num(x):
    return math.nan if x is None else float(x)  # float() reads "inf" and "nan" too


def agree(ours, ref, tol):
    if math.isnan(ref) or math.isnan(ours):
        return math.isnan(ref) and math.isnan(ours)
    if math.isinf(ref) or math.isinf(ours):
        return ref == ours
    return abs(ours - ref) <= max(0.05 * abs(ref), tol)


def ego_id(yaml_path):
    with open(yaml_path) as f:
        for line in f:
            if line.strip().startswith("ego_id:"):
                return int(line.split(":")[1])
    return None


def main():
    if len(sys.argv) < 4:
        sys.exit(__doc__)
    binary, ref_dir, sce_dir = sys.argv[1:4]
    n_examples = int(sys.argv[sys.argv.index("--examples") + 1]) if "--examples" in sys.argv else 3
    pooled = {}  # (class, measure) -> [agree, total]
    summary = []
    for name in sorted(f[:-4] for f in os.listdir(ref_dir) if f.endswith(".csv")):
        ego = ego_id(os.path.join(sce_dir, name + ".yaml"))
        if ego is None:
            continue
        xml = os.path.join(sce_dir, name + ".xml")
        run = subprocess.run(
            [binary, "criticality", "--commonroad", xml, "--ego", str(ego), "--format", "json"],
            capture_output=True, text=True,
        )
        if run.returncode != 0:
            print(f"{name}: risktwin failed: {run.stderr.strip()}")
            continue
        doc = json.loads(run.stdout)
        heading = num(doc["ego_lane_heading_rad"])
        plus_x = not math.isnan(heading) and abs(math.atan2(math.sin(heading), math.cos(heading))) <= PLUS_X_RAD
        # JSON writes inf and NaN alike as null: the values come from the CSV.
        run = subprocess.run(
            [binary, "criticality", "--commonroad", xml, "--ego", str(ego), "--format", "csv"],
            capture_output=True, text=True, check=True,
        )
        ours = {(int(r["time_step"]), int(r["other_id"])): r for r in csv.DictReader(run.stdout.splitlines())}
        with open(os.path.join(ref_dir, name + ".csv")) as f:
            ref = {(int(r["time_step"]), int(r["other_id"])): r for r in csv.DictReader(f)}
        keys = sorted(set(ours) | set(ref))
        line = [f"{name:40s} {'+x' if plus_x else '  '} heading={heading:+.3f} cells={len(ref)}"]
        for m, tol in MEASURES:
            ok = total = 0
            ok_nb = total_nb = 0
            examples = []
            for k in keys:
                r, o = ref.get(k), ours.get(k)
                if r is None or o is None:
                    good = False
                    rv = float(r[m]) if r else math.nan
                    ov = num(o[OURS_KEY[m]]) if o else math.nan
                    braking = r is not None and float(r["other_a"]) < 0
                else:
                    rv, ov = float(r[m]), num(o[OURS_KEY[m]])
                    good = agree(ov, rv, tol)
                    braking = float(r["other_a"]) < 0
                total += 1
                ok += good
                if not braking:
                    total_nb += 1
                    ok_nb += good
                if not good and len(examples) < n_examples:
                    examples.append(f"t={k[0]} other={k[1]} ours={ov!r} crime={rv!r}" + (" (braking)" if braking else ""))
            for cls in ["all"] + (["+x"] if plus_x else []):
                acc = pooled.setdefault((cls, m), [0, 0])
                acc[0] += ok
                acc[1] += total
                if m == "ttc":
                    acc = pooled.setdefault((cls, "ttc_not_braking"), [0, 0])
                    acc[0] += ok_nb
                    acc[1] += total_nb
            pct = 100.0 * ok / total if total else float("nan")
            line.append(f"{m}={pct:5.1f}%")
            summary.append((name, m, examples))
        print(" ".join(line))
    print("\npooled agreement:")
    for (cls, m), (ok, total) in sorted(pooled.items()):
        print(f"  {cls:4s} {m:16s} {ok:6d}/{total:6d} = {100.0 * ok / max(total, 1):5.1f}%")
    thw = pooled.get(("all", "thw"), [0, 1])
    hw = pooled.get(("+x", "hw"), [0, 1])
    ttc = pooled.get(("+x", "ttc_not_braking"), [0, 1])
    verdict = all(a / max(b, 1) >= 0.95 for a, b in (thw, hw, ttc))
    print(f"\ncriteria (THW all, HW +x, TTC +x not braking >= 95%): {'MET' if verdict else 'NOT MET'}")
    print("\nfirst disagreeing cells:")
    for name, m, examples in summary:
        for e in examples:
            print(f"  {name} {m}: {e}")


if __name__ == "__main__":
    main()
