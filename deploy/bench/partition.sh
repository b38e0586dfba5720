#!/usr/bin/env bash
# The edge site of a 3-host deployment (a vehicle and an RSU, a cloud over a 20 ms link) is
# partitioned for PARTITION_S seconds (default 30: longer than Zenoh's 10 s lease, so the
# sessions across it close and reconnect after the heal) while the edges keep publishing into
# their caches (--cache-s CACHE_S, default 45: sized for the outage). Prints, per edge stream,
# sent / received / recovered (of received, from the edge's cache) / lost / missing from the report, and the links that reconnected. Target:
# received = sent, lost = 0. Needs root for the namespaces.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin risktwin
bin=$PWD/target/release/risktwin
tmp=$(mktemp -d)
file=$tmp/partition.toml
trap '"$bin" deploy down "$file" >/dev/null 2>&1 || true; rm -rf "$tmp"' EXIT
part=${PARTITION_S:-30}
cache=${CACHE_S:-45}
run_s=$((part + 20))
cat >"$file" <<TOML
[[site]]
name = "cloud"

[[site]]
name = "edge"

[[host]]
name = "cloud-0"
site = "cloud"
run = [{ role = "cloud", args = ["--roles", "ingest"] }]

[[host]]
name = "car-1"
site = "edge"
run = [{ role = "vehicle", args = ["--count", "$((run_s * 50))", "--rate-hz", "50", "--cache-s", "$cache"] }]

[[host]]
name = "rsu-1"
site = "edge"
run = [{ role = "rsu", args = ["--count", "$((run_s * 10))", "--cache-s", "$cache"] }]

[[link]]
between = ["edge", "cloud"]
latency_ms = 20
jitter = { dist = "normal", sd_ms = 2 }

[[event]]
at_s = 5
partition = "edge"
for_s = $part
TOML
"$bin" deploy run "$file" --for "$((run_s + 60))s" --out "$tmp/out" >/dev/null
python3 - "$tmp/out/report.json" "$part" "$cache" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"partition {sys.argv[2]} s of the edge site, --cache-s {sys.argv[3]}, ran {r['ran_s']:.1f} s")
for s in r["streams"]:
    print(f"  {s['source']}/{s['stream']}: sent {s['sent']}, received {s['received']}, "
          f"recovered {s['recovered']}, lost {s['lost']}, missing {s['missing']}")
for l in r["links"]:
    if len(l["connected_at_s"]) > 1:
        print(f"  {l['name']}: connected at {[round(t, 2) for t in l['connected_at_s']]} s")
print("  timeline:", [(round(e["at_s"], 2), e["what"]) for e in r["timeline"] if "partition" in e["what"] or "heal" in e["what"]])
PY
