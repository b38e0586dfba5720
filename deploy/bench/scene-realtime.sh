#!/usr/bin/env bash
# Real-time scenes on one host: emergency braking with 8 connected vehicles (the ego and all 7
# moving traffic cars a generated scenario has) + 2 RSUs = 10 participant processes and the
# authority, stepping on the wall clock (50 ms). Episodes of consecutive seeds run back to back
# until at least SECONDS_MIN (default 60) s of scene have run. Prints per episode and in total
# the answers due, the deadlines missed (late answers are counted, not waited for) and the CPU
# the scene's processes used (user + system, from /usr/bin/time, in cores). Target: misses
# <= 0.1 % of answers. COMMONROAD=FILE plays that recording instead, again and again
# (CONNECTED=10: DEU_Flensburg-10_1_T-1 has 24 vehicles beside its ego, 10 s).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin risktwin
bin=$PWD/target/release/risktwin
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
kind=${KIND:-emergency-braking} connected=${CONNECTED:-8} rsus=${RSUS:-2}
total_s=0 due=0 missed=0 cpu_s=0 wall_s=0 seed=${SEED:-0}
while awk -v t="$total_s" -v m="${SECONDS_MIN:-60}" 'BEGIN { exit !(t < m) }'; do
  if [ -n "${COMMONROAD:-}" ]; then scenario=(--commonroad "$COMMONROAD"); else scenario=(--kind "$kind" --seed "$seed"); fi
  /usr/bin/time -f '%U %S %e' -o "$tmp/time" "$bin" scene run "${scenario[@]}" \
    --connected "$connected" --rsus "$rsus" --clock realtime >"$tmp/out.json" 2>"$tmp/err"
  read -r user sys wall <"$tmp/time"
  read -r steps step_s d m <<<"$(python3 -c 'import json,sys; o=json.load(open(sys.argv[1])); print(o["steps"], o["step_s"], o["deadlines"]["due"], o["deadlines"]["missed"])' "$tmp/out.json")"
  scene_s=$(awk -v n="$steps" -v s="$step_s" 'BEGIN { printf "%.2f", n * s }')
  echo "run $seed: $scene_s s of scene in $wall s, answers due $d, missed $m, CPU $(awk -v u="$user" -v s="$sys" -v w="$wall" 'BEGIN { printf "%.2f", (u + s) / w }') cores"
  total_s=$(awk -v a="$total_s" -v b="$scene_s" 'BEGIN { print a + b }')
  due=$((due + d)) missed=$((missed + m))
  cpu_s=$(awk -v a="$cpu_s" -v u="$user" -v s="$sys" 'BEGIN { print a + u + s }')
  wall_s=$(awk -v a="$wall_s" -v w="$wall" 'BEGIN { print a + w }')
  seed=$((seed + 1))
done
awk -v t="$total_s" -v d="$due" -v m="$missed" -v c="$cpu_s" -v w="$wall_s" -v n="$((connected + rsus))" 'BEGIN {
  printf "total: %.1f s of scene, %d participants, answers due %d, missed %d (%.3f %%), CPU %.2f cores (%.1f s in %.1f s)\n", t, n, d, m, 100 * m / d, c / w, c, w }'
