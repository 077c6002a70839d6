#!/usr/bin/env bash
# Sets everything up and runs the main job: the Sugiyama ring (22 vehicles, 230 m) headlessly
# in SUMO, every driver running the delayed-driver law; prints the verdict and metrics.
set -euo pipefail
cd "$(dirname "$0")/.."
bash python-host/bootstrap.sh
cargo build --release -p syncroad
./target/release/syncroad check scenarios/sugiyama-ring.json || true
./target/release/syncroad run scenarios/sugiyama-ring.json --out out/sugiyama-ring
