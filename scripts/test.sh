#!/usr/bin/env bash
# Set up and run the whole test suite (unit, service and real-Zenoh integration tests).
# Extra arguments go to pytest, e.g. `bash scripts/test.sh -m "not zenoh"`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/python -m pytest "$@"
