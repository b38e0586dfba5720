#!/usr/bin/env bash
# The ingestion soak (issue 20): a fleet (2,000 vehicles × 50 Hz by default) into the cloud
# ingest for a long time with a rotating recording (a segment a minute), sampled every SAMPLE_S
# seconds: the cloud's resident memory, its CPU per recorded message over the interval, the
# segments closed so far. At the end the bench's own figures (sent, received, lost, dropped) and
# the catalogue's message count against the recorded count.
#
#   benchmarks/soak.sh [RISKTWIN] [SECONDS] [VEHICLES] [SAMPLE_S]
#
# The cloud side is `risktwin bench ingest` itself (the real cloud role in that process; the
# fleet is its child processes), so its /proc entry is the cloud's. Needs the release binary
# and about 4 MB of disk per second of soak (deleted at the end unless KEEP=1).
set -euo pipefail
bin=${1:-target/release/risktwin}
secs=${2:-1800}
n=${3:-2000}
every=${4:-30}
dir=$(mktemp -d)
pid=
cleanup() {
    [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null || true
    if [ -n "${KEEP:-}" ]; then echo "kept in $dir" >&2; else rm -rf "$dir"; fi
}
trap cleanup EXIT

"$bin" bench ingest --vehicles "$n" --rate-hz 50 --seconds "$secs" --record-dir "$dir/rec" --segment-s 60 \
    --metrics-listen 127.0.0.1:0 --format json >"$dir/report.json" 2>"$dir/err" &
pid=$!
deadline=$(($(date +%s) + 60))
until grep -q "metrics on http" "$dir/err"; do
    if (($(date +%s) > deadline)) || ! kill -0 "$pid" 2>/dev/null; then cat "$dir/err" >&2; exit 1; fi
    sleep 0.2
done
url=$(grep -m1 -o 'http://[^ ]*/metrics' "$dir/err")
tick=$(getconf CLK_TCK)
# One sample: seconds, resident KiB, CPU ticks, messages recorded, segments closed.
sample() {
    local m
    m=$(curl -sf --max-time 10 "$url" || true)
    echo "$(date +%s.%N) $(awk '/^VmRSS/ {print $2}' "/proc/$pid/status") $(awk '{print $14 + $15}' "/proc/$pid/stat")" \
        "$(awk '/^risktwin_recording_messages_total/ {print $2 + 0}' <<<"$m")" \
        "$(awk '/^risktwin_recording_segments_total\{state="closed"\}/ {print $2 + 0}' <<<"$m")"
}
echo "t_s  rss_mib  cpu_cores  us_cpu_per_msg  msgs_per_s  recorded  segments_closed"
read -r t0 _ c0 m0 _ < <(sample)
pt=$t0 pc=$c0 pm=${m0:-0}
while sleep "$every" && kill -0 "$pid" 2>/dev/null; do
    read -r t rss c m segs < <(sample) || break
    [ -n "${m:-}" ] || continue
    awk -v t="$t" -v t0="$t0" -v pt="$pt" -v rss="$rss" -v c="$c" -v pc="$pc" -v m="$m" -v pm="$pm" -v s="${segs:-0}" -v k="$tick" \
        'BEGIN { dt = t - pt; dc = (c - pc) / k; dm = m - pm;
                 printf "%5.0f  %7.1f  %9.3f  %14.2f  %10.0f  %8d  %15d\n",
                 t - t0, rss / 1024, dc / dt, (dm > 0 ? dc * 1e6 / dm : 0), dm / dt, m, s }'
    pt=$t pc=$c pm=$m
done
wait "$pid"
python3 - "$dir" "$bin" <<'EOF'
import json, subprocess, sys
d, bin = sys.argv[1], sys.argv[2]
r = json.load(open(f"{d}/report.json"))
print(f"sent {r['sent']} received {r['received']} lost {r['lost']} dropped {r['dropped']}",
      f"cloud {r['cloud_cpu_us_per_msg']:.2f} µs CPU/msg over the run")
cat = json.loads(subprocess.run([bin, "recordings", "list", f"{d}/rec", "--format", "json"],
                                capture_output=True, check=True, text=True).stdout)
segs = cat["segments"]
print(f"catalogue: {len(segs)} segments ({sum(s['status'] == 'finished' for s in segs)} finished),",
      f"{sum(s.get('messages') or 0 for s in segs)} messages; recorded by the cloud {r['received']}")
print("made by:", json.dumps({k: cat["recordings"][0][k] for k in ("risktwin_version", "git_commit")}))
EOF
