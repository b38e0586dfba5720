#!/usr/bin/env bash
# The closed loop over a fleet on one host: a router, a cloud with `ingest,twin,loop` on a fresh
# library (KIND scenarios, default 12 emergency brakings and 12 cut-ins of seed 5), and VEHICLES
# (default 2) edge vehicles at their real-time default rate, for DURATION_S (default 60). Prints the
# loop's summary: episodes, failures, twin disagreements, and the iteration time (a result
# handed on by the twin -> scored, stored, ranked -> next push sent; target < 100 ms;
# also from the edge's result, the twin catching up with the episode's end included), then the loop report.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin risktwin
bin=$PWD/target/release/risktwin
tmp=$(mktemp -d)
pids=()
trap 'kill "${pids[@]}" 2>/dev/null || true; wait 2>/dev/null || true; rm -rf "$tmp"' EXIT
for kind in ${KINDS:-emergency-braking cut-in}; do
  "$bin" scenarios generate --kind "$kind" --count "${COUNT:-12}" --seed 5 --db "$tmp/lib.db" --format json >/dev/null
done
"$bin" router --listen tcp/127.0.0.1:0 2>"$tmp/router.err" &
pids+=($!)
until grep -q "listening on" "$tmp/router.err"; do sleep 0.1; done
locator=$(sed -n 's/^listening on //p' "$tmp/router.err" | head -1)
"$bin" cloud --roles ingest,twin,loop --db "$tmp/lib.db" --connect "$locator" --loop-report "$tmp/loop.md" \
  >"$tmp/cloud.json" 2>"$tmp/cloud.err" &
cloud=$!
until grep -qx "ready" "$tmp/cloud.err"; do sleep 0.1; done
for k in $(seq 1 "${VEHICLES:-2}"); do
  "$bin" edge vehicle --id "v$k" --site fleet --connect "$locator" >/dev/null 2>&1 &
  pids+=($!)
done
sleep "${DURATION_S:-60}"
kill -TERM "$cloud"
wait "$cloud"
python3 -c 'import json,sys; print(json.dumps(json.load(open(sys.argv[1]))["loop"], indent=1))' "$tmp/cloud.json"
cat "$tmp/loop.md"
