#!/usr/bin/env bash
# Whole-scenario criticality, side by side per scenario in one run, like for like:
# - CriMe: CommonRoad-CriMe 0.4.5 (PyPI `commonroad-crime`) evaluating the scenario itself,
#   CriMeInterface.evaluate_scenario([HW, THW, TTC, ALongReq]) over every ego time step, timed
#   inside Python after the imports and the file reading (tests/peers/crime_reference.py --time;
#   best of $CRIME_REPEAT evaluations);
# - ours per process: `risktwin criticality --format csv` (every pair, every step), wall time of
#   the whole process (start-up and file reading included), best and median of $REPEAT runs;
# - ours in process: reading, parsing and all measures without the process
#   (`cargo bench -p risktwin-commonroad --bench criticality`), median of $REPEAT runs;
# and the ratios CriMe / ours (on the medians). Prints a Markdown table (docs/results.md).
# Usage: deploy/bench/criticality-vs-crime.sh [SCENARIO.xml EGO_ID]...
#   (default: every data/commonroad/*.xml whose .yaml names an ego, `ego_id:`)
# The peer lives in a throwaway virtualenv ($RISKTWIN_CRIME_VENV, default /tmp/crime-venv).
set -euo pipefail
cd "$(dirname "$0")/../.."
venv=${RISKTWIN_CRIME_VENV:-/tmp/crime-venv}
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import commonroad_crime' 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q commonroad-crime==0.4.5
fi
cargo build --release -q -p risktwin
cargo bench -q -p risktwin-commonroad --bench criticality --no-run
if [ $# -eq 0 ]; then
  for yaml in data/commonroad/*.yaml; do
    ego=$(sed -n 's/^ *ego_id: *\([0-9][0-9]*\).*/\1/p' "$yaml" | head -1)
    xml=${yaml%.yaml}.xml
    if [ -n "$ego" ] && [ -f "$xml" ]; then set -- "$@" "$xml" "$ego"; fi
  done
fi
repeat=${REPEAT:-21}
echo "| scenario | cells | CriMe evaluation (s) | ours per process, best / median (ms) | CriMe / per process | ours in process, median (ms) | CriMe / in process |"
echo "|---|---:|---:|---:|---:|---:|---:|"
while [ $# -ge 2 ]; do
  xml=$1 ego=$2
  shift 2
  crime=$("$venv/bin/python" tests/peers/crime_reference.py "$xml" "$ego" --time --repeat "${CRIME_REPEAT:-1}" |
    sed -n 's/^crime_seconds=//p')
  in_process=$(cargo bench -q -p risktwin-commonroad --bench criticality -- --repeat "$repeat" "$PWD/$xml" "$ego" |
    sed -n 's/.* median=\([0-9.]*\) .*/\1/p')
  python3 - "$xml" "$ego" "$crime" "$in_process" "$repeat" <<'PY'
import statistics, subprocess, sys, time
xml, ego, crime, in_process, repeat = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
cmd = ["target/release/risktwin", "criticality", "--commonroad", xml, "--ego", ego, "--format", "csv"]
times, rows = [], 0
for _ in range(repeat):
    t0 = time.perf_counter()
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    times.append(time.perf_counter() - t0)
    rows = out.count("\n") - 1
best, median = min(times) * 1e3, statistics.median(times) * 1e3
name = xml.rsplit("/", 1)[-1].removesuffix(".xml")
print(f"| {name} | {rows:,} | {crime:.2f} | {best:.1f} / {median:.1f} | {crime * 1e3 / median:,.0f}× "
      f"| {in_process:.2f} | {crime * 1e3 / in_process:,.0f}× |", flush=True)
PY
done
