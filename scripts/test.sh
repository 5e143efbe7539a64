#!/usr/bin/env bash
# Set up and run the whole test suite (unit, service and real-Zenoh integration tests).
# Extra arguments go to pytest, e.g. `bash scripts/test.sh -m "not zenoh"`. Installs Chromium
# (scripts/browser.sh) for the browser test when apt-get can; PERCEPTION_NO_BROWSER_INSTALL=1 skips that.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
# Chromium for the page's browser test, from the distribution's packages where possible.
if [ "${PERCEPTION_NO_BROWSER_INSTALL:-0}" != "1" ]; then
  bash scripts/browser.sh || true
fi
exec .venv/bin/python -m pytest "$@"
