#!/usr/bin/env bash
# Regenerates the vendored three.js files the studio page embeds, from the npm package that
# tests/browser/package-lock.json pins (three 0.187.0), and checks them against SHA256SUMS.
#
#   crates/skelform-studio/assets/vendor/update.sh          # copy and check
#   crates/skelform-studio/assets/vendor/update.sh --bless  # copy and rewrite SHA256SUMS
#
# Nothing is fetched but the npm package (npm ci in tests/browser when it is missing).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../../.." && pwd)
three="$root/tests/browser/node_modules/three"
if [[ ! -f $three/package.json ]]; then
    (cd "$root/tests/browser" && npm ci --no-audit --no-fund --loglevel=error)
fi
version=$(node -p "require('$three/package.json').version")
if [[ $version != 0.187.0 ]]; then
    echo "expected three 0.187.0 in tests/browser/node_modules, found $version" >&2
    exit 1
fi
cp "$three/build/three.module.js" "$three/build/three.core.js" "$here/"
cp "$three/examples/jsm/controls/OrbitControls.js" "$three/examples/jsm/controls/TransformControls.js" "$here/"
cp "$three/LICENSE" "$here/three-LICENSE"
cd "$here"
files=(three.module.js three.core.js OrbitControls.js TransformControls.js three-LICENSE)
if [[ ${1:-} == --bless ]]; then
    sha256sum "${files[@]}" > SHA256SUMS
fi
sha256sum -c --quiet SHA256SUMS
echo "three $version vendored"
