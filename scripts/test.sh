#!/usr/bin/env bash
# Sets everything up and runs every test of syncroad (this is what CI runs).
set -euo pipefail
cd "$(dirname "$0")/.."
# One interpreter for every build: the CLI's (cargo) and the wheel's (maturin) builds of the
# SUMO crate then agree on PYO3_PYTHON, and neither rebuilds what the other built.
PYO3_PYTHON="${PYO3_PYTHON:-$("${PYTHON:-python3}" -c 'import sys; print(sys.executable)')}"
export PYO3_PYTHON
# Xvfb and the X and OpenGL libraries sumo-gui links: the replay test starts sumo-gui under a
# virtual display (it says it is skipped where they cannot be installed).
if ! command -v xvfb-run >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq xvfb xauth libgl1 libxrender1 libxext6 libx11-6 >/dev/null
fi
if [ -f python-host/bootstrap.sh ]; then
  bash python-host/bootstrap.sh
fi
# Where the suite's time goes, phase by phase (printed at the end).
phases=""
phase() { phases="$phases $1 $((SECONDS - start))s;"; start=$SECONDS; }
start=$SECONDS
# The user guide builds (mdBook, pinned and installed on first use).
"$(bash scripts/mdbook.sh)" build docs
phase setup+guide
cargo build --release --workspace --all-targets
phase build
# Includes the guide's test (crates/syncroad/tests/guide.rs): every command example of
# docs/src and README.md runs as printed. cargo-nextest, where installed, runs the test binaries
# side by side (each test its own process) and the doc tests follow; else cargo's own runner.
if cargo nextest --version >/dev/null 2>&1; then
  cargo nextest run --release --workspace --no-fail-fast
  cargo test --release --workspace --doc
else
  cargo test --release --workspace --no-fail-fast
fi
phase cargo-tests
# The congestion/synchronization regression check on every committed baseline.
for b in tests/baselines/*.json; do
  ./target/release/syncroad regress "$b"
done
phase baselines
# The Python package: the wheel built once, installed into .venv-py, python/tests run by pytest.
bash scripts/python-test.sh
phase python
# A sweep sharded over a private single-node Slurm cluster (skipped, and said so, without Slurm).
slurm="$(bash scripts/slurm-test.sh)"
phase slurm
echo
echo "summary: guide built; cargo tests passed; baselines passed; Python tests passed; Slurm test: $(echo "$slurm" | tail -1)"
echo "time:$phases total ${SECONDS}s"
