#!/usr/bin/env bash
# Sets everything up and runs the main job: the example ring-road scenario.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ -f python-host/bootstrap.sh ]; then
  bash python-host/bootstrap.sh
fi
cargo build --release -p syncroad
./target/release/syncroad check scenarios/ring-theorem1.json || true
./target/release/syncroad simulate scenarios/ring-theorem1.json --out out/ring-theorem1
