#!/usr/bin/env bash
# Set-up (idempotent): create .venv/ with the pinned dependencies, install the package
# (non-editable, so the ament index, config files and ros2-run executables are installed
# into the venv prefix), then run the main job unless --no-run is given.
set -euo pipefail
cd "$(dirname "$0")/.."
PY="${PYTHON:-}"
if [ -z "$PY" ]; then
  for cand in python3.11 python3; do
    if command -v "$cand" >/dev/null 2>&1; then PY="$cand"; break; fi
  done
fi
[ -x .venv/bin/python ] || "$PY" -m venv .venv
stamp=.venv/.requirements.sha256
want=$(sha256sum requirements.txt | cut -d' ' -f1)
if [ "$(cat "$stamp" 2>/dev/null || true)" != "$want" ]; then
  .venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip setuptools wheel
  .venv/bin/python -m pip install -q --disable-pip-version-check -r requirements.txt
  echo "$want" > "$stamp"
fi
# Always reinstall the project itself (a few seconds) so installed nodes match the tree.
.venv/bin/python -m pip install -q --disable-pip-version-check --no-deps --no-build-isolation --force-reinstall . >/dev/null
rm -rf build ./*.egg-info
if [ "${1:-}" != "--no-run" ]; then
  echo "== main job: comems4build simulate --ems fuzzy on the default 12-week scenario -> runs/default_fuzzy"
  .venv/bin/comems4build simulate --ems fuzzy --out runs/default_fuzzy
fi
