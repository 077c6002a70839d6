#!/usr/bin/env bash
# Create the repository's Python virtualenv (.venv) holding the pinned SUMO packages that the
# syncroad-sumo crate embeds. Idempotent: a stamp file records the hash of requirements.txt and
# the interpreter version; when both match, nothing is installed again.
#
# Usage: bash python-host/bootstrap.sh        (from anywhere)
# Env:   PYTHON   interpreter to build the venv with (default: python3, must be 3.11)
#        SYNCROAD_VENV  where to put the venv (default: <repo>/.venv)
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/.." && pwd)"
venv="${SYNCROAD_VENV:-$repo/.venv}"
python="${PYTHON:-python3}"
req="$here/requirements.txt"
stamp="$venv/.syncroad-bootstrap.stamp"

if ! command -v "$python" >/dev/null 2>&1; then
    echo "bootstrap: '$python' not found; install CPython 3.11 or set PYTHON=/path/to/python3.11" >&2
    exit 1
fi
pyver="$("$python" -c 'import sys; print("%d.%d" % sys.version_info[:2])')"
if [ "$pyver" != "3.11" ]; then
    echo "bootstrap: $python is Python $pyver, syncroad pins CPython 3.11 (set PYTHON=...)" >&2
    exit 1
fi

want="$(sha256sum "$req" | cut -d' ' -f1) python$pyver"
if [ -f "$stamp" ] && [ "$(cat "$stamp")" = "$want" ] && [ -x "$venv/bin/python" ]; then
    echo "bootstrap: $venv is up to date"
else
    echo "bootstrap: creating $venv with $("$python" -c 'import sys; print(sys.executable)') (Python $pyver)"
    # uv (pinned, installed on first use) where it can be had, else pip.
    bash "$repo/scripts/make-venv.sh" "$venv" "$python" "$req"
    echo "$want" > "$stamp"
fi

sumo_home="$("$venv/bin/python" -c 'import sumo; print(sumo.SUMO_HOME)')"
echo "bootstrap: SUMO_HOME=$sumo_home"
echo "bootstrap: sumo=$sumo_home/bin/sumo netconvert=$sumo_home/bin/netconvert"
echo "bootstrap: python=$("$venv/bin/python" -c 'import sys; print(sys.version.split()[0], sys.base_prefix)')"
echo "bootstrap: pyo3 builds against PYO3_PYTHON, else python3 on PATH: use the interpreter this venv was made from"
