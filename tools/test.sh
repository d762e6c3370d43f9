#!/usr/bin/env bash
# The whole test suite: set-up (idempotent, no main job), lint, then pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh --no-run
# Debian's Mosquitto and Home Assistant in its own Python 3.13 venv for test/test_home_assistant.py
# (idempotent: a cache folder; without a Python 3.13 nothing is installed and that test skips)
bash tools/home_assistant.sh install
export ROS_LOG_DIR="${ROS_LOG_DIR:-$PWD/.ros_log}"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
.venv/bin/ruff check .
.venv/bin/python -m pytest -q -p no:cacheprovider "$@"
