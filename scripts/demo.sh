#!/usr/bin/env bash
# Set up and run the live demo on embedded defaults: a local router, the four services and
# the simulated apartment as separate processes, a live view, then the tracking metrics.
# Extra arguments go to `perception demo`, e.g. `bash scripts/demo.sh --scenario chairs`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/perception demo "$@"
