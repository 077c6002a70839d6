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
# Poppler's pdftotext reads the text back out of the plots' PDFs (--pdf).
if { ! command -v xvfb-run || ! command -v pdftotext; } >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq xvfb xauth libgl1 libxrender1 libxext6 libx11-6 poppler-utils >/dev/null
fi
# Where the suite's time goes, phase by phase (printed at the end).
phases=""
phase() { phases="$phases $1 $((SECONDS - start))s;"; start=$SECONDS; }
start=$SECONDS
# Jobs this script runs beside its phases, stopped if it stops early; `joined PID LOG WHAT`
# waits for one and shows its log, and stops the suite if it failed.
logs="$(mktemp -d)"
side=()
trap 'for p in "${side[@]}"; do kill "$p" 2>/dev/null || true; done' EXIT
joined() {
  local status=0
  wait "$1" || status=$?
  cat "$2"
  if [ "$status" != 0 ]; then
    echo "test.sh: $3 failed (exit $status)" >&2
    exit 1
  fi
}
# The two Python environments (SUMO's and the Python tests') download and unpack while cargo
# builds: neither needs the build, and the build does not need them.
if [ -f python-host/bootstrap.sh ]; then
  bash python-host/bootstrap.sh > "$logs/bootstrap" 2>&1 &
  boot=$!
  side+=("$boot")
fi
bash scripts/python-test.sh --setup > "$logs/venv-py" 2>&1 &
venv_py=$!
side+=("$venv_py")
# The user guide builds (mdBook, pinned and installed on first use).
"$(bash scripts/mdbook.sh)" build docs
phase setup+guide
cargo build --release --workspace --all-targets
if [ -n "${boot:-}" ]; then
  joined "$boot" "$logs/bootstrap" "python-host/bootstrap.sh"
fi
joined "$venv_py" "$logs/venv-py" "the Python tests' environment (scripts/python-test.sh --setup)"
phase build+environments
# The wheel, built once by maturin from the same compiled tree (it only links), before anything
# else runs: no cargo build runs beside it.
bash scripts/python-test.sh --wheel
phase wheel
# The Python package's tests and the Slurm test run beside the cargo tests: they need only what
# the build made (the CLI and the wheel), and they share no files with them (the Python tests
# use .venv-py and their own folders; the Slurm test its own cluster in a temporary folder).
# Run after the cargo tests, the two phases left the cores a fifth idle: the Slurm test mostly
# waits on its daemons, and the last long tests of each runner ran alone.
# A sweep sharded over a private single-node Slurm cluster (skipped, and said so, without Slurm).
bash scripts/slurm-test.sh > "$logs/slurm" 2>&1 &
slurm_pid=$!
side+=("$slurm_pid")
# The Python package: the wheel installed into .venv-py, python/tests run by pytest.
bash scripts/python-test.sh --built > "$logs/python" 2>&1 &
python_pid=$!
side+=("$python_pid")
# Includes the guide's test (crates/syncroad/tests/guide.rs): every command example of
# docs/src and README.md runs as printed. cargo-nextest, where installed, runs the test binaries
# side by side (each test its own process) and the doc tests follow; else cargo's own runner.
# Two tests per core: several wait on a worker's time limit or a stopped process for seconds,
# and the suite passes beside other work (two busy processes per core) anyway.
if cargo nextest --version >/dev/null 2>&1; then
  cargo nextest run --release --workspace --no-fail-fast --test-threads "$((2 * $(nproc)))"
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
joined "$python_pid" "$logs/python" "the Python tests (scripts/python-test.sh)"
phase python-after-cargo
joined "$slurm_pid" "$logs/slurm" "the Slurm test (scripts/slurm-test.sh)"
phase slurm-after-python
echo
echo "summary: guide built; cargo tests passed; baselines passed; Python tests passed; Slurm test: $(tail -1 "$logs/slurm")"
echo "time:$phases total ${SECONDS}s"
