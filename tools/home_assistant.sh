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
#   bash tools/home_assistant.sh frontend    also the frontend package (for a dashboard screenshot)
#
# Home Assistant 2025.4.4 is the newest release that installs on Python 3.13.0; the MQTT
# integration's requirement (paho-mqtt 2.1.0, its manifest.json) and those of the
# integrations the test's configuration loads are installed here, so Home Assistant runs
# with --skip-pip and fetches nothing at run time.
set -euo pipefail
HA_VERSION=2025.4.4
FRONTEND_VERSION=20250411.0   # the frontend that Home Assistant 2025.4.4 pins (its package_constraints)
CACHE="${COMEMS4BUILD_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/comems4build_ros}"
VENV="$CACHE/home-assistant-$HA_VERSION"
# Requirements of the integrations the test's configuration loads (manifest.json of each
# in Home Assistant 2025.4.4): mqtt, and the ones bootstrap always sets up.
EXTRA=(paho-mqtt==2.1.0)

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
  rm -rf "$VENV"
  "$py" -m venv "$VENV"
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check --upgrade pip
  "$VENV/bin/python" -m pip install -q --disable-pip-version-check "homeassistant==$HA_VERSION" "${EXTRA[@]}"
  echo "$HA_VERSION ${EXTRA[*]}" > "$VENV/.installed"
}

case "${1:-install}" in
  install)
    install_mosquitto
    install_ha
    ;;
  frontend)
    install_mosquitto
    install_ha
    [ -x "$VENV/bin/python" ] || { echo "home_assistant.sh: no Home Assistant venv" >&2; exit 1; }
    "$VENV/bin/python" -c "import hass_frontend" 2>/dev/null || \
      "$VENV/bin/python" -m pip install -q --disable-pip-version-check "home-assistant-frontend==$FRONTEND_VERSION"
    ;;
  path)
    if [ -x "$VENV/bin/python" ] && [ -f "$VENV/.installed" ]; then echo "$VENV/bin/python"; else exit 1; fi
    ;;
  *)
    echo "usage: bash tools/home_assistant.sh [install|frontend|path]" >&2
    exit 2
    ;;
esac
