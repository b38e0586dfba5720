#!/usr/bin/env bash
# Risk-field throughput on one core at the issue's size (64 agents, 256 x 256 cells).
# No published peer computes this field; the bar is an absolute one (1,000 fields/s).
set -euo pipefail
cd "$(dirname "$0")/../.."
cargo build --release -q -p risktwin
target/release/risktwin bench risk-field --agents 64 --cols 256 --rows 256 --seconds "${SECONDS_PER_RUN:-3}"
