#!/usr/bin/env bash
# Recovery after a stalled cloud (issue 17: "recovery after a 30 s stall completes within 5 s for
# 100 vehicles"), measured with the delivery acknowledgements (docs/keyexpr.md).
#
#   benchmarks/stall_recovery.sh [RISKTWIN] [VEHICLES] [STALL_S] [CACHE_S]
#
# A router, a cloud (ingest) and VEHICLES `edge vehicle` processes (50 Hz state, clients of the
# router). Once all publish, the cloud is stopped (SIGSTOP) for STALL_S and continued (SIGCONT);
# a stall longer than Zenoh's 10 s lease makes the router drop the cloud's session, which comes
# back by itself. Once every vehicle that saw it go has seen it back, all are stopped (SIGTERM) at once:
# each waits for acknowledgements covering everything it sent (at most 3 s) and prints its
# summary. Printed: when the cloud's count of samples recovered from the caches stopped growing
# (its Prometheus counter, scraped every 0.1 s from SIGCONT: the recovery itself); per vehicle the seconds from SIGCONT until it exited with everything
# accounted for (recovery of the stall's samples, plus the acknowledgement period), and the
# counts of the edges and the cloud. Needs the release binary (cargo build --release).
# KEEP_LOGS=1 keeps every process's output in the temporary folder it names (the cloud's stderr
# with the Unix time of each line; RUST_LOG=info,zenoh=debug there shows Zenoh's reconnection).
set -euo pipefail
bin=${1:-target/release/risktwin}
n=${2:-100}
stall_s=${3:-30}
cache_s=${4:-45}
dir=$(mktemp -d)
pids=()
cleanup() {
    for p in "${pids[@]}" $(cat "$dir"/veh-*.pid 2>/dev/null); do kill -9 "$p" 2>/dev/null || true; done
    if [ -n "${KEEP_LOGS:-}" ]; then echo "logs kept in $dir" >&2; else rm -rf "$dir"; fi
}
trap cleanup EXIT
now() { date +%s.%N; }
# Prefixes each line with the Unix time it was read at (the roles print none of their own).
stamp() { perl -MTime::HiRes=time -ne '$| = 1; printf "%.6f %s", time, $_'; }
# Waits up to $2 s until file $1 holds a line matching $3.
wait_for() {
    local deadline=$(($(date +%s) + $2))
    until grep -q -- "$3" "$1" 2>/dev/null; do
        if (($(date +%s) > deadline)); then echo "timeout: $3 not in $1" >&2; cat "$1" >&2; exit 1; fi
        sleep 0.1
    done
}

"$bin" router --listen tcp/127.0.0.1:0 2>"$dir/router.err" &
pids+=($!)
wait_for "$dir/router.err" 30 "listening on tcp/127.0.0.1:"
locator=$(grep -m1 -o 'listening on tcp/127.0.0.1:[0-9]*' "$dir/router.err" | cut -d' ' -f3)
net=(--mode client --connect "$locator")

"$bin" cloud --roles ingest "${net[@]}" --metrics-listen 127.0.0.1:0 >"$dir/cloud.json" 2> >(stamp >"$dir/cloud.err") &
cloud=$!
pids+=("$cloud")
wait_for "$dir/cloud.err" 30 " ready$"
metrics=$(grep -m1 -o 'http://[^ ]*/metrics' "$dir/cloud.err")
# Samples the cloud recovered from the edges' caches so far (its Prometheus counter, summed).
recovered() { curl -sf --max-time 5 "$metrics" | awk '/^risktwin_ingest_messages_recovered_total/ {s += $2} END {print s + 0}'; }

for i in $(seq 1 "$n"); do
    (
        "$bin" edge vehicle --id "veh-$i" --site bench "${net[@]}" --cache-s "$cache_s" \
            >"$dir/veh-$i.json" 2>"$dir/veh-$i.err" &
        echo $! >"$dir/veh-$i.pid"
        wait $! || echo "exit $?" >>"$dir/veh-$i.err"
        now >"$dir/veh-$i.end"
    ) &
    pids+=($!)
done
for i in $(seq 1 "$n"); do wait_for "$dir/veh-$i.err" 120 "edge veh-$i: publishing"; done
sleep 2

echo "SIGSTOP at $(now)" >"$dir/marks"
kill -STOP "$cloud"
sleep "$stall_s"
cont=$(now)
echo "SIGCONT at $cont" >>"$dir/marks"
kill -CONT "$cloud"
# The recovered count every 100 ms until the cloud exits (it waits for a last scrape).
(while kill -0 "$cloud" 2>/dev/null; do echo "$(now) $(recovered)"; sleep 0.1; done >"$dir/recovered") &
poller=$!
pids+=("$poller")
# A stall past the lease took the cloud's session (and token) away: wait until it is back.
for i in $(seq 1 "$n"); do
    if grep -q "cloud gone" "$dir/veh-$i.err"; then wait_for "$dir/veh-$i.err" 60 "cloud back after"; fi
done
back=$(now)
vehicles=()
for i in $(seq 1 "$n"); do vehicles+=("$(cat "$dir/veh-$i.pid")"); done
kill -TERM "${vehicles[@]}" || true
for i in $(seq 1 "$n"); do wait_for "$dir/veh-$i.end" 60 "."; done
kill -TERM "$cloud"
wait "$cloud" || true
wait "$poller" || true

python3 - "$dir" "$n" "$cont" "$back" "$stall_s" "$cache_s" <<'EOF'
import json, statistics, sys
d, n, cont, back, stall, cache = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5], sys.argv[6]
cloud = json.load(open(f"{d}/cloud.json"))
secs, tot = [], {k: 0 for k in ("sent", "acknowledged", "lost", "undelivered")}
failed = 0
for i in range(1, n + 1):
    end = float(open(f"{d}/veh-{i}.end").read())
    try:
        s = json.load(open(f"{d}/veh-{i}.json"))
    except ValueError:
        failed += 1
        continue
    for k in tot:
        tot[k] += sum(s[k].values())
    if sum(s["undelivered"].values()) == 0:
        secs.append(end - cont)
    else:
        failed += 1
print(f"vehicles {n}, stall {stall} s, --cache-s {cache}: cloud back at all edges {back - cont:.2f} s after SIGCONT")
if secs:
    q = statistics.quantiles(secs, n=20) if len(secs) > 1 else secs * 19
    print(f"SIGCONT -> edge exited, all acknowledged: median {statistics.median(secs):.2f} s, p95 {q[18]:.2f} s, max {max(secs):.2f} s ({len(secs)} edges)")
print(f"edges with undelivered messages (or no summary): {failed}")
print("edges:", tot)
# When the recovered count reached its final value: the stall's samples are all in the twin.
series = [tuple(map(float, l.split())) for l in open(f"{d}/recovered") if len(l.split()) == 2]
final = max((v for _, v in series), default=0)
done = next((t for t, v in series if v >= final), cont)
print(f"recovered {final:.0f} samples from the edges' caches, the last {done - cont:.2f} s after SIGCONT (scraped every 0.1 s)")
print("cloud: received", cloud["total_received"], "recovered", cloud["total_recovered"], "lost", cloud["total_lost"],
      "presumed_lost", cloud["total_presumed_lost"], "dropped", cloud["dropped"])
EOF
