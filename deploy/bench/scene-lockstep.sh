#!/usr/bin/env bash
# Lockstep over loopback Zenoh against the same scene embedded in one process, and against raw
# Zenoh's floor for a step of as many participants, side by side:
# emergency braking seed 0 with 8 connected vehicles (the ego and all 7 moving traffic cars a
# generated scenario has) + 2 RSUs = 10 participant processes, each answering every 50 ms step.
# Prints both paces, the multiple of real time, the coordination overhead per step (distributed
# minus embedded wall time per step; target >= 20x real time, <= 0.5 ms per step) and the raw
# floor: `risktwin bench fanout`, one put out to 10 echo processes and 10 answers back per round,
# answered from Zenoh callbacks as our participants answer (1 KiB out, 40 B back: about a
# generated scene's truth and a reply), with no physics, sensing, streams or decoding.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin risktwin
bin=target/release/risktwin
connected=${CONNECTED:-8}
rsus=${RSUS:-2}
scene=(--kind "${KIND:-emergency-braking}" --seed "${SEED:-0}" --connected "$connected" --rsus "$rsus")
pace() { grep -o 'scene pace: .*' | tail -1; }
for round in $(seq "${ROUNDS:-3}"); do
  embedded=$("$bin" scene run "${scene[@]}" --embedded 2>&1 >/dev/null | pace)
  distributed=$("$bin" scene run "${scene[@]}" 2>&1 >/dev/null | pace)
  raw=$("$bin" bench fanout --echoes $((connected + rsus)) --rounds 2000 --out-bytes 1024 --reply-bytes 40 --format json |
    sed -nE 's/.*"ms_per_round": ?([0-9]+\.[0-9]{0,3}).*/\1/p')
  ms() { sed -E 's/.* ([0-9.]+) ms per step/\1/' <<<"$1"; }
  x() { sed -E 's/.*: ([0-9.]+)x real time.*/\1/' <<<"$1"; }
  overhead=$(awk -v d="$(ms "$distributed")" -v e="$(ms "$embedded")" 'BEGIN { printf "%.3f", d - e }')
  ratio=$(awk -v o="$overhead" -v r="$raw" 'BEGIN { printf "%.2f", o / r }')
  echo "round $round: embedded $(ms "$embedded") ms/step ($(x "$embedded")x real time); lockstep $(ms "$distributed") ms/step ($(x "$distributed")x real time); coordination overhead $overhead ms/step; raw Zenoh floor $raw ms/round; overhead / raw $ratio"
done
