#!/usr/bin/env bash
# How long a deployment of HOSTS (default 20) emulated hosts takes to come up and to be torn
# down (targets: ≤ 10 s up, ≤ 5 s down). Two edge sites of vehicles and RSUs, a cloud site; every
# site has its router (its own namespace), the edge sites reach the cloud over 10 ms links.
# "Up" is `risktwin deploy up` returning: every namespace, veth and relay made, the routers
# listening, the cloud ready and every edge process started. Needs root for the namespaces.
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release --bin risktwin
bin=$PWD/target/release/risktwin
tmp=$(mktemp -d)
file=$tmp/fleet.toml
trap '"$bin" deploy down "$file" >/dev/null 2>&1 || true; rm -rf "$tmp"' EXIT
hosts=${HOSTS:-20}
{
  printf '[[site]]\nname = "cloud"\n\n[[site]]\nname = "north"\n\n[[site]]\nname = "south"\n\n'
  printf '[[host]]\nname = "cloud-0"\nsite = "cloud"\nrun = [{ role = "cloud", args = ["--roles", "ingest,twin"] }]\n\n'
  for k in $(seq 1 $((hosts - 1))); do
    site=north; [ $((k % 2)) -eq 0 ] && site=south
    role=vehicle; [ $((k % 5)) -eq 0 ] && role=rsu
    printf '[[host]]\nname = "h%d"\nsite = "%s"\nrun = [{ role = "%s" }]\n\n' "$k" "$site" "$role"
  done
  for site in north south; do
    printf '[[link]]\nbetween = ["%s", "cloud"]\nlatency_ms = 10\n\n' "$site"
  done
} >"$file"
t0=$(date +%s.%N)
"$bin" deploy up "$file" --out "$tmp/out" >"$tmp/up.json"
t1=$(date +%s.%N)
machines=$(grep -o '"machines": "[^"]*"' "$tmp/up.json")
"$bin" deploy down "$file" >/dev/null
t2=$(date +%s.%N)
left=$(ip netns list | grep -c '^rt-' || true)
echo "hosts $hosts ($machines): up $(awk "BEGIN{print $t1 - $t0}") s, down $(awk "BEGIN{print $t2 - $t1}") s; namespaces left: $left"
