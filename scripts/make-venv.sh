#!/usr/bin/env bash
# Makes (or completes) the virtualenv VENV of PYTHON and installs the requirement files into it:
#   bash scripts/make-venv.sh VENV PYTHON REQUIREMENTS...
# With the pinned uv (scripts/uv.sh: installed with pip on first use) where it can be had and
# works, else with pip: uv takes about half of pip's CPU time (it unpacks each wheel once into
# its cache, links the files into every environment and byte-compiles them in parallel).
# Used by python-host/bootstrap.sh (SUMO's .venv) and scripts/python-test.sh (.venv-py).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
venv="${1:?usage: make-venv.sh VENV PYTHON REQUIREMENTS...}"
python="${2:?usage: make-venv.sh VENV PYTHON REQUIREMENTS...}"
shift 2
reqs=()
for r in "$@"; do
  reqs+=(-r "$r")
done
# The platform's certificates as well as uv's own (pip reads the system's bundle too).
if uv="$(PYTHON="$python" bash "$here/uv.sh")" \
  && "$uv" venv --quiet --seed --allow-existing --python "$python" "$venv" \
  && "$uv" pip install --quiet --system-certs --python "$venv/bin/python" --compile-bytecode "${reqs[@]}"; then
  exit 0
fi
echo "make-venv.sh: uv unavailable or failed; installing $venv with pip" >&2
"$python" -m venv "$venv"
"$venv/bin/python" -m pip install --disable-pip-version-check -q "${reqs[@]}"
