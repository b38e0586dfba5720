#!/usr/bin/env bash
# Traffic simulation throughput, side by side in one run: highway-env (Python, PyPI
# `highway-env`, highway-fast-v0) against `risktwin bench sim`, and the ratio.
# The peer lives in a throwaway virtualenv ($RISKTWIN_PEER_VENV, default /tmp/risktwin-peer-venv).
set -euo pipefail
cd "$(dirname "$0")/../.."
venv=${RISKTWIN_PEER_VENV:-/tmp/risktwin-peer-venv}
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import highway_env' 2>/dev/null; then
  python3 -m venv "$venv"
  "$venv/bin/pip" install -q highway-env
fi
cargo build --release -q -p risktwin
peer=$("$venv/bin/python" tests/peers/highway_env_bench.py --steps "${PEER_STEPS:-300}")
ours_1k=$(target/release/risktwin bench sim --vehicles 1000 --steps 1000 --format json)
ours_10k=$(target/release/risktwin bench sim --vehicles 10000 --steps 300 --format json)
python3 - "$peer" "$ours_1k" "$ours_10k" <<'PY'
import json, sys
peer, a, b = (json.loads(x) for x in sys.argv[1:])
p = peer["vehicle_steps_per_s"]
print(f"highway-env highway-fast-v0: {peer['env_steps_per_s']:.1f} env steps/s x {peer['sim_steps_per_env_step']} sub-steps x {peer['vehicles']:.0f} vehicles = {p:,.0f} vehicle-steps/s")
for r in (a, b):
    print(f"risktwin bench sim {r['vehicles']:>6} vehicles, {r['threads']} threads: {r['vehicle_steps_per_s']:,.0f} vehicle-steps/s  ratio {r['vehicle_steps_per_s'] / p:,.0f}x")
per_1k = 1 / a["vehicle_steps_per_s"]
per_10k = 1 / b["vehicle_steps_per_s"]
print(f"per-vehicle cost at 10,000 vs 1,000 vehicles: {per_10k / per_1k:.2f}x")
PY
