#!/usr/bin/env bash
# Lockstep over loopback Zenoh against the same scene embedded in one process, side by side:
# emergency braking seed 0 with 8 connected vehicles (the ego and all 7 moving traffic cars a
# generated scenario has) + 2 RSUs = 10 participant processes, each answering every 50 ms step.
# Prints both paces, the multiple of real time and the coordination overhead per step
# (distributed minus embedded wall time per step). Target: >= 20x real time, <= 0.5 ms per step.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin risktwin
bin=target/release/risktwin
scene=(--kind "${KIND:-emergency-braking}" --seed "${SEED:-0}" --connected "${CONNECTED:-8}" --rsus "${RSUS:-2}")
pace() { grep -o 'scene pace: .*' | tail -1; }
for round in $(seq "${ROUNDS:-3}"); do
  embedded=$("$bin" scene run "${scene[@]}" --embedded 2>&1 >/dev/null | pace)
  distributed=$("$bin" scene run "${scene[@]}" 2>&1 >/dev/null | pace)
  ms() { sed -E 's/.* ([0-9.]+) ms per step/\1/' <<<"$1"; }
  x() { sed -E 's/.*: ([0-9.]+)x real time.*/\1/' <<<"$1"; }
  overhead=$(awk -v d="$(ms "$distributed")" -v e="$(ms "$embedded")" 'BEGIN { printf "%.3f", d - e }')
  echo "round $round: embedded $(ms "$embedded") ms/step ($(x "$embedded")x real time); lockstep $(ms "$distributed") ms/step ($(x "$distributed")x real time); coordination overhead $overhead ms/step"
done
