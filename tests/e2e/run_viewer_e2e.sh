#!/bin/sh
# ctest entry of the viewer's end-to-end test (tests/e2e/viewer_e2e.mjs): checks that node,
# Debian's chromium and playwright-core (npm ci in tests/e2e, done by toolchain/install-deps.sh)
# are there, else says what is missing and exits 77 (ctest: skipped).
# Usage: run_viewer_e2e.sh RDSLAM_BINARY OUT_DIR
set -eu
here=$(cd "$(dirname "$0")" && pwd)
chromium=${RDSLAM_CHROMIUM:-/usr/bin/chromium}
if ! command -v node >/dev/null 2>&1; then
  echo "SKIPPED: node not found (toolchain/install-deps.sh installs nodejs)"; exit 77
fi
if [ ! -x "$chromium" ]; then
  echo "SKIPPED: $chromium not found (toolchain/install-deps.sh installs Debian's chromium)"; exit 77
fi
if [ ! -f "$here/node_modules/playwright-core/package.json" ]; then
  echo "SKIPPED: playwright-core not installed (run: npm ci --prefix $here; install-deps.sh does)"
  exit 77
fi
exec node "$here/viewer_e2e.mjs" "$1" "$2" "$chromium"
