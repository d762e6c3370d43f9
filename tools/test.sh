#!/usr/bin/env bash
# The whole test suite: set-up (idempotent, no main job), lint, then pytest.
#   bash tools/test.sh [PYTEST ARGS]          the full suite (what CI runs via .ci/run)
#   bash tools/test.sh --quick [PYTEST ARGS]  the fast lane: lint, the tests measured under 3 s
#                                             that start no ROS node, and one short ROS run
#                                             (docs/testing.md "The fast lane")
set -euo pipefail
cd "$(dirname "$0")/.."
quick=0
if [[ "${1:-}" == "--quick" ]]; then
    quick=1
    shift
fi
bash tools/setup.sh --no-run
export ROS_LOG_DIR="${ROS_LOG_DIR:-$PWD/.ros_log}"
export ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST
if (( quick )); then
    .venv/bin/ruff check .
    exec .venv/bin/python -m pytest -q -p no:cacheprovider -m "(not ros and not slow) or quick" "$@"
fi
# Debian's Mosquitto and Home Assistant in its own Python 3.13 venv for test/test_home_assistant.py
# (idempotent: a cache folder; without a Python 3.13 nothing is installed and that test skips)
bash tools/home_assistant.sh install
.venv/bin/ruff check .
.venv/bin/python -m pytest -q -p no:cacheprovider "$@"
