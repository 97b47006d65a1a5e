#!/usr/bin/env bash
# Browser test of the dashboard. Installs what it needs (Debian's chromium when missing, the
# npm packages from package-lock.json), builds the debug binary, and runs the test.
# Usage: tests/dashboard/run.sh   (AVSEP_BIN=path to test another binary)
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "$here/../.." && pwd)"

if [ ! -x "${CHROMIUM:-/usr/bin/chromium}" ]; then
  echo "installing chromium (apt)"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null
fi
if ! command -v node >/dev/null; then
  echo "installing node (apt)"
  apt-get update -qq
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq nodejs npm >/dev/null
fi
(cd "$here" && npm ci --no-audit --no-fund --loglevel=error)
if [ -z "${AVSEP_BIN:-}" ]; then
  (cd "$root" && cargo build --bin avsep)
fi
cd "$here"
exec node --test --test-reporter=spec dashboard.test.mjs
