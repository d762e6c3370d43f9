#!/usr/bin/env bash
# The whole test suite: set-up (idempotent, no main job), lint, then pytest.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh --no-run
export ROS_LOG_DIR="${ROS_LOG_DIR:-$PWD/.ros_log}"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
.venv/bin/ruff check .
.venv/bin/python -m pytest -q -p no:cacheprovider "$@"
