#!/usr/bin/env bash
# Sets everything up and runs every test of syncroad (this is what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -f python-host/bootstrap.sh ]; then
  bash python-host/bootstrap.sh
fi
cargo build --release --workspace --all-targets
cargo test --release --workspace
# The congestion/synchronization regression check on every committed baseline.
for b in tests/baselines/*.json; do
  ./target/release/syncroad regress "$b"
done
