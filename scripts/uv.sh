#!/usr/bin/env bash
# Prints the path of the pinned uv that installs syncroad's Python environments, installing it
# first when absent: a `uv` of the pinned version on PATH, else the one installed before into
# ${XDG_CACHE_HOME:-~/.cache}/syncroad/uv-VERSION, else pip installs it into that folder (a
# virtualenv of the interpreter given as PYTHON, default python3; a few seconds, once).
# Exits non-zero, saying why on stderr, when it cannot (scripts/make-venv.sh then uses pip).
set -euo pipefail
version=0.13.9
if command -v uv >/dev/null 2>&1 && [ "$(uv --version 2>/dev/null | cut -d' ' -f2)" = "$version" ]; then
  command -v uv
  exit 0
fi
root="${XDG_CACHE_HOME:-$HOME/.cache}/syncroad/uv-$version"
if [ ! -x "$root/bin/uv" ]; then
  echo "uv.sh: installing uv $version into $root" >&2
  rm -rf "$root"
  "${PYTHON:-python3}" -m venv "$root" >&2
  "$root/bin/python" -m pip install --disable-pip-version-check -q "uv==$version" >&2
fi
echo "$root/bin/uv"
