#!/usr/bin/env bash
# Edge→cloud Zenoh throughput, ours against raw Zenoh (exact-key and wildcard subscribers), in
# one process over TCP loopback, peer mode, reliable, 1 KiB payloads. Prints the ratios.
#
# Build optimised: in the plain dev profile only dependencies are at opt-level 2 and our own
# crates at 0, which would handicap our side. `--release` is the reference; on a busy 2-core
# machine `CARGO_PROFILE_DEV_OPT_LEVEL=2 cargo build` is a quicker equivalent (used for the
# figures reported on the branch).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -p risktwin
exec target/release/risktwin bench zenoh --messages "${MESSAGES:-200000}" --payload-bytes 1024 --rounds "${ROUNDS:-5}" "$@"
