#!/usr/bin/env bash
# The browser tests: skelform's outputs (and, later, its studio) in real headless Chromium,
# driven by playwright-core with Debian's system browser; no browser is downloaded.
#
#   tests/browser/run.sh            # builds skelform (dev profile) unless SKELFORM names a binary
#   SKELFORM=target/debug/skelform tests/browser/run.sh
#
# Installs what is missing: Debian's chromium (with apt-get, as root) unless
# SKELFORM_CHROMIUM names a browser, and the npm packages of package-lock.json (npm ci, into
# tests/browser/node_modules). Writes meshes and screenshots to target/browser.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
for tool in node npm; do
    if ! command -v "$tool" >/dev/null 2>&1; then
        echo "the browser tests need Node.js and npm ($tool is missing; Debian: apt-get install nodejs npm)" >&2
        exit 1
    fi
done
chromium=${SKELFORM_CHROMIUM:-/usr/bin/chromium}
if [[ ! -x $chromium ]]; then
    if [[ $(id -u) -ne 0 ]] || ! command -v apt-get >/dev/null 2>&1; then
        echo "no Chromium at $chromium: install Debian's chromium package or set SKELFORM_CHROMIUM" >&2
        exit 1
    fi
    echo "installing Debian's chromium (once)"
    export DEBIAN_FRONTEND=noninteractive
    apt-get install -y -q chromium >/dev/null 2>&1 || {
        apt-get update -q >/dev/null
        apt-get install -y -q chromium >/dev/null
    }
fi
if [[ -z "${SKELFORM:-}" ]]; then
    cargo build -q -p skelform-cli
    SKELFORM=target/debug/skelform
fi
export SKELFORM
cd tests/browser
if [[ ! -d node_modules/playwright-core || ! -d node_modules/three ]] \
    || [[ package-lock.json -nt node_modules/.package-lock.json ]]; then
    npm ci --no-audit --no-fund --loglevel=error
fi
npm test
