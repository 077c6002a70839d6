#!/usr/bin/env bash
# Sets everything up and runs the main job: the Sugiyama ring (22 vehicles, 230 m) headlessly
# in SUMO, every driver running the delayed-driver law; prints the verdict and metrics.
set -euo pipefail
cd "$(dirname "$0")/.."
bash python-host/bootstrap.sh
cargo build --release -p syncroad
./target/release/syncroad check scenarios/sugiyama-ring.json || true
./target/release/syncroad run scenarios/sugiyama-ring.json --out out/sugiyama-ring
# The same ring with SUMO's own drivers (Krauss σ 0.5 and 0.9, IDM): side-by-side table,
# compare.json and one folder per run with plots.
./target/release/syncroad compare scenarios/sugiyama-ring.json --out out/compare
# Mixed traffic: 0, 1, 2, 4 law-driven vehicles among Krauss σ 0.9 drivers.
./target/release/syncroad compare scenarios/sugiyama-ring.json --mixed 0,1,2,4 --out out/compare-mixed
