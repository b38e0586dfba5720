#!/usr/bin/env bash
# Sharded ingest, 1, 2 and 3 workers (issue 20): does the work divide? For each worker count,
# a router, a union (`cloud --roles union`) and N workers (`cloud --roles ingest --shard`) as
# separate processes, and one fleet publisher process (VEHICLES × 50 Hz for SECONDS, each vehicle
# with its liveliness token). Per worker: the vehicles it owned, the messages it accepted, its
# CPU over the run (/proc/PID/stat from before the fleet starts to after it ends) and so its
# µs of CPU per message; the union's the same, and its received count against the fleet's sent.
#
#   benchmarks/shard_scale.sh [RISKTWIN] [SECONDS] [VEHICLES]
#
# Every process shares this machine's cores: the figures are costs, not a speed-up (a worker's
# share of the fleet on its own host is the projection; docs/sharding.md).
set -euo pipefail
bin=${1:-target/release/risktwin}
secs=${2:-20}
n=${3:-2000}
dir=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null || true; done
    rm -rf "$dir"
}
trap cleanup EXIT
tick=$(getconf CLK_TCK)
cpu() { awk '{print $14 + $15}' "/proc/$1/stat"; }
free_port() { python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])'; }
wait_line() { # FILE TEXT: until FILE holds TEXT, at most 60 s
    local deadline=$(($(date +%s) + 60))
    until grep -q "$2" "$1"; do
        if (($(date +%s) > deadline)); then echo "no '$2' in $1:" >&2; cat "$1" >&2; exit 1; fi
        sleep 0.1
    done
}

printf "%-7s  %-8s  %8s  %10s  %9s  %9s  %12s\n" workers process vehicles messages cpu_s cores us_cpu_per_msg
for workers in 1 2 3; do
    loc="tcp/127.0.0.1:$(free_port)"
    "$bin" router --listen "$loc" >"$dir/router.log" 2>&1 &
    pids+=($!)
    sleep 0.5
    "$bin" cloud --roles union --site bench --connect "$loc" >"$dir/union.json" 2>"$dir/union.log" &
    union=$!
    pids+=("$union")
    wait_line "$dir/union.log" '^ready'
    ws=()
    for w in $(seq 1 "$workers"); do
        "$bin" cloud --roles ingest --shard --site bench --connect "$loc" >"$dir/w$w.json" 2>"$dir/w$w.log" &
        ws+=($!)
        pids+=($!)
    done
    for w in $(seq 1 "$workers"); do
        wait_line "$dir/w$w.log" '^ready'
        # Each sees all the others before the fleet starts: no share moves during the run.
        ((workers == 1)) || wait_line "$dir/w$w.log" "($workers alive)"
    done
    declare -A c0=()
    for p in "$union" "${ws[@]}"; do c0[$p]=$(cpu "$p"); done
    t0=$(date +%s.%N)
    "$bin" bench ingest --fleet-connect "$loc" --fleet-tokens --vehicles "$n" --rate-hz 50 --seconds "$secs" \
        >"$dir/fleet.json" 2>"$dir/fleet.log"
    # Let the last samples in before the CPU is read (the workers acknowledge every 500 ms).
    sleep 2
    t1=$(date +%s.%N)
    declare -A c1=()
    for p in "$union" "${ws[@]}"; do c1[$p]=$(cpu "$p"); done
    kill -INT "${ws[@]}"
    for p in "${ws[@]}"; do wait "$p" || true; done
    kill -INT "$union"
    wait "$union" || true
    kill "${pids[0]}" 2>/dev/null || true
    wait "${pids[0]}" 2>/dev/null || true
    pids=()
    python3 - "$dir" "$workers" "$tick" "$t0" "$t1" "$union" "${c0[$union]}" "${c1[$union]}" \
        $(for w in $(seq 1 "$workers"); do p=${ws[$((w - 1))]}; echo "$p" "${c0[$p]}" "${c1[$p]}"; done) <<'EOF'
import json, sys
d, workers, tick, t0, t1 = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), float(sys.argv[5])
rest = sys.argv[6:]
wall = t1 - t0
def row(name, summary, c0, c1):
    cpu_s = (int(c1) - int(c0)) / tick
    msgs = summary["total_received"]
    owned = len(summary["received"])
    print(f"{workers:<7}  {name:<8}  {owned:8d}  {msgs:10d}  {cpu_s:9.2f}  {cpu_s / wall:9.3f}  {cpu_s * 1e6 / max(msgs, 1):12.2f}")
    return msgs
fleet = json.load(open(f"{d}/fleet.json"))
union = json.load(open(f"{d}/union.json"))
row("union", union, rest[1], rest[2])
total = 0
for w in range(workers):
    _, c0, c1 = rest[3 + 3 * w: 6 + 3 * w]
    total += row(f"worker{w + 1}", json.load(open(f"{d}/w{w + 1}.json")), c0, c1)
print(f"{'':7}  fleet sent {fleet['sent']}, workers accepted {total}, union accepted {union['total_received']}, "
      f"union dropped {union['dropped']}, presumed lost {union['total_presumed_lost']}")
EOF
done
