#!/usr/bin/env bash
# Install Chromium from the distribution's packages for the browser test of `perception view`
# (tests/integration/test_viewer_browser.py), when it is missing and apt-get can be used (root, or sudo
# without a password). Never fails: without Chromium that test is skipped, saying why.
set -uo pipefail
for name in chromium chromium-browser google-chrome; do
  if command -v "$name" >/dev/null 2>&1; then exit 0; fi
done
if ! command -v apt-get >/dev/null 2>&1; then
  echo "note: no apt-get here; the browser test will be skipped (install Chromium to run it)" >&2
  exit 0
fi
if [ "$(id -u)" -eq 0 ]; then
  SUDO=""
elif command -v sudo >/dev/null 2>&1 && sudo -n true 2>/dev/null; then
  SUDO="sudo -n"
else
  echo "note: cannot run apt-get as root; the browser test will be skipped (apt-get install chromium to run it)" >&2
  exit 0
fi
echo "installing chromium for the browser test (apt-get) ..." >&2
if ! { $SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium; } >/dev/null 2>&1; then
  echo "note: apt-get could not install chromium; the browser test will be skipped" >&2
fi
exit 0
