#!/usr/bin/env bash
# Whole-scenario criticality, side by side in one run: CommonRoad-CriMe 0.4.5 (PyPI
# `commonroad-crime`, CriMeInterface.evaluate_scenario with HW, THW, TTC, ALongReq over every
# ego time step) against `risktwin criticality --format csv` (every pair, every step), and the
# ratio. Both times are wall-clock and include reading the XML file; ours is the median of
# $REPEAT process runs.
# Usage: deploy/bench/criticality-vs-crime.sh [SCENARIO.xml EGO_ID]...
#   (default: the three scenarios of tests/fixtures/crime/)
# The peer lives in a throwaway virtualenv ($RISKTWIN_CRIME_VENV, default /tmp/crime-venv).
set -euo pipefail
cd "$(dirname "$0")/../.."
venv=${RISKTWIN_CRIME_VENV:-/tmp/crime-venv}
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import commonroad_crime' 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q commonroad-crime==0.4.5
fi
cargo build --release -q -p risktwin
if [ $# -eq 0 ]; then
  set -- tests/fixtures/crime/OSC_CutIn-1_2_T-1.xml 3 tests/fixtures/crime/BEL_Putte-8_2_T-1.xml 33 \
    tests/fixtures/crime/HRV_Pula-27_3_T-1.xml 34
fi
while [ $# -ge 2 ]; do
  xml=$1 ego=$2; shift 2
  crime=$("$venv/bin/python" tests/peers/crime_reference.py "$xml" "$ego" --time | sed -n 's/^crime_seconds=//p')
  python3 - "$xml" "$ego" "$crime" "${REPEAT:-21}" <<'PY'
import statistics, subprocess, sys, time
xml, ego, crime, repeat = sys.argv[1], sys.argv[2], float(sys.argv[3]), int(sys.argv[4])
cmd = ["target/release/risktwin", "criticality", "--commonroad", xml, "--ego", ego, "--format", "csv"]
times, rows = [], 0
for _ in range(repeat):
    t0 = time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    times.append(time.perf_counter() - t0)
    rows = out.count("\n") - 1
ours = statistics.median(times)
name = xml.rsplit("/", 1)[-1]
print(f"{name}: CriMe {crime:.2f} s, risktwin {ours * 1000:.1f} ms ({rows} cells), ratio {crime / ours:,.0f}x")
PY
done
