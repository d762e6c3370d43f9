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
# The ros2 command finds a package through the ament index under AMENT_PREFIX_PATH: the
# venv's activate script puts the venv prefix there (what sourcing a ROS setup file does).
if ! grep -q AMENT_PREFIX_PATH .venv/bin/activate; then
  cat >> .venv/bin/activate <<'ACTIVATE'
# comems4build_ros: ros2 finds the package's ament index under this prefix
case ":${AMENT_PREFIX_PATH:-}:" in *":$VIRTUAL_ENV:"*) ;; *) export AMENT_PREFIX_PATH="$VIRTUAL_ENV${AMENT_PREFIX_PATH:+:$AMENT_PREFIX_PATH}" ;; esac
ACTIVATE
fi
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
