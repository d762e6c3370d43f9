#!/usr/bin/env bash
# What the Home Assistant test (test/test_home_assistant.py) needs, installed idempotently:
#   - Debian's Mosquitto broker (apt-get install mosquitto mosquitto-clients);
#   - Home Assistant $HA_VERSION in its own Python 3.13 venv: its MQTT integration pins
#     a paho-mqtt of its own, so it cannot share the project's venv (Python 3.11).
# The venv lives under a cache folder, ${COMEMS4BUILD_CACHE:-$HOME/.cache/comems4build_ros},
# so a second run on the same machine installs nothing. Without a Python 3.13 (on PATH as
# python3.13, or in pyenv's versions) nothing is installed and the test skips, saying so.
#
#   bash tools/home_assistant.sh install     install what is missing (prints what it did)
#   bash tools/home_assistant.sh path        print the venv's python (exit 1 if not installed)
#
# Home Assistant 2025.4.4 is the newest release that installs on Python 3.13.0. The
# requirements of the integrations it sets up (the MQTT integration's paho-mqtt 2.1.0, and
# of those bootstrap always sets up: the frontend, which is critical, and isal; each
# integration's manifest.json, at the versions of Home Assistant's package_constraints.txt)
# are installed here, so Home Assistant runs with --skip-pip and fetches nothing at run time.
set -euo pipefail
HA_VERSION=2025.4.4
CACHE="${COMEMS4BUILD_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/comems4build_ros}"
VENV="$CACHE/home-assistant-$HA_VERSION"
# Requirements of the integrations Home Assistant 2025.4.4 sets up here that its own
# package does not bring (manifest.json of mqtt, frontend and isal).
EXTRA=(paho-mqtt==2.1.0 home-assistant-frontend==20250411.0 isal==1.7.1)

find_python313() {
  if command -v python3.13 >/dev/null 2>&1 && python3.13 -c 'import sys; assert sys.version_info[:2] == (3, 13)' \
      2>/dev/null; then
    command -v python3.13; return 0
  fi
  local root="${PYENV_ROOT:-$HOME/.pyenv}"
  for p in "$root"/versions/3.13*/bin/python3.13; do
    [ -x "$p" ] && { echo "$p"; return 0; }
  done
  return 1
}

install_mosquitto() {
  if command -v mosquitto >/dev/null 2>&1 || [ -x /usr/sbin/mosquitto ]; then
    return 0
  fi
  if ! command -v apt-get >/dev/null 2>&1; then
    echo "home_assistant.sh: no mosquitto and no apt-get: install Mosquitto by hand" >&2
    return 1
  fi
  echo "home_assistant.sh: apt-get install mosquitto mosquitto-clients"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq >/dev/null
  apt-get install -y -qq --no-install-recommends mosquitto mosquitto-clients >/dev/null
  # Debian's package starts its own service where systemd runs; the test starts its own
  # broker on a free port, so a system broker (if any) is left alone.
}

install_ha() {
  local py
  if ! py=$(find_python313); then
    echo "home_assistant.sh: no Python 3.13 (python3.13 on PATH or in pyenv): Home Assistant not installed"
    return 0
  fi
  if [ -x "$VENV/bin/python" ] && [ -f "$VENV/.installed" ] && \
      [ "$(cat "$VENV/.installed")" = "$HA_VERSION ${EXTRA[*]}" ]; then
    return 0
  fi
  echo "home_assistant.sh: Home Assistant $HA_VERSION into $VENV (Python $("$py" -V 2>&1 | cut -d' ' -f2))"
  mkdir -p "$CACHE"
  if ! "$VENV/bin/python" -c "import homeassistant" 2>/dev/null; then  # else only the extras changed
    rm -rf "$VENV"
    "$py" -m venv "$VENV"
    "$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  fi
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check "homeassistant==$HA_VERSION" "${EXTRA[@]}"
  echo "$HA_VERSION ${EXTRA[*]}" > "$VENV/.installed"
}

case "${1:-install}" in
  install)
    install_mosquitto
    install_ha
    ;;
  path)
    if [ -x "$VENV/bin/python" ] && [ -f "$VENV/.installed" ]; then echo "$VENV/bin/python"; else exit 1; fi
    ;;
  *)
    echo "usage: bash tools/home_assistant.sh [install|path]" >&2
    exit 2
    ;;
esac
