#!/usr/bin/env bash
# The Python package's tests (run by scripts/test.sh): builds the wheel once with maturin,
# installs it into .venv-py (made here, with the tools of python/tests/requirements.txt, and
# kept between runs: a stamp records the requirements' hash), and runs python/tests with
# pytest. The wheel's build reuses what cargo built for the CLI (one set of features and one
# pyo3 configuration for both: crates/syncroad-hack, .cargo/config.toml), so it only links.
# Needs the cargo-built CLI (target/release/syncroad) the tests compare with.
# `--setup` only makes .venv-py (scripts/test.sh does that while cargo builds); `--wheel` only
# builds the wheel into target/wheels, and `--built` runs the tests on the wheel built there
# (scripts/test.sh builds it before the cargo tests start, and tests it beside them).
# Env: PYTHON (default python3), SYNCROAD_PY_VENV (default .venv-py).
set -euo pipefail
cd "$(dirname "$0")/.."
python="${PYTHON:-python3}"
venv="${SYNCROAD_PY_VENV:-.venv-py}"
req=python/tests/requirements.txt
# The SUMO family and the rest of the wheel's dependencies at the project's pins, installed
# with the tools, so that installing the wheel later adds only the package.
deps=python-host/requirements.txt
stamp="$venv/.syncroad-py.stamp"
want="$(cat "$req" "$deps" | sha256sum | cut -d' ' -f1)"
if [ ! -x "$venv/bin/python" ] || [ "$(cat "$stamp" 2>/dev/null)" != "$want" ]; then
  echo "python-test: creating $venv"
  # uv (pinned, installed on first use) where it can be had, else pip.
  bash scripts/make-venv.sh "$venv" "$python" "$req" "$deps"
  echo "$want" > "$stamp"
fi
mode="${1:-}"
case "$mode" in
  --setup) exit 0 ;;
  --wheel | --built) shift ;;
esac
if [ "$mode" != --built ]; then
  rm -f target/wheels/syncroad-*.whl
  # The interpreter the CLI was built against (scripts/test.sh exports it): maturin passes it
  # to pyo3 as PYO3_PYTHON, so the two builds share what they have in common.
  interp=()
  if [ -n "${PYO3_PYTHON:-}" ]; then
    interp=(-i "$PYO3_PYTHON")
  fi
  nice -n 5 "$venv/bin/maturin" build --release --quiet "${interp[@]}" -o target/wheels
fi
if [ "$mode" = --wheel ]; then
  exit 0
fi
wheel="$(ls target/wheels/syncroad-*.whl)"
# Dependencies once; the freshly built package every time (its version does not change).
"$venv/bin/python" -m pip install --disable-pip-version-check -q "$wheel"
"$venv/bin/python" -m pip install --disable-pip-version-check -q --force-reinstall --no-deps "$wheel"
# Side by side on every core (pytest-xdist; each test has its own folders), at most four.
SYNCROAD_WHEEL="$PWD/$wheel" "$venv/bin/python" -m pytest -q -p no:cacheprovider \
  --numprocesses=auto --maxprocesses=4 python/tests "$@"
