#!/usr/bin/env bash
# Every test of the project, as the README's second command: the Rust workspace (unit,
# integration, property and fuzz tests, doc tests), then the files it writes loaded by the
# real libraries other people use (trimesh, meshio, pymeshlab; installed into a virtual
# environment under target/ on first use), the Python package's pytest suite on its wheel in
# a fresh virtual environment, then the browser tests in headless Chromium
# (tests/browser: Debian's chromium and npm packages, installed on first use). Installs what
# is missing; fails on any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v python3 >/dev/null 2>&1; then
    echo "python3 is needed for the interoperability tests (tests/interop)" >&2
    exit 1
fi
if ! python3 -c 'import venv, ensurepip' 2>/dev/null; then
    echo "python3 lacks venv/ensurepip; install python3-venv" >&2
    exit 1
fi
echo "== Rust tests"
cargo test --workspace --locked
echo "== other tools read skelform's files (tests/interop)"
# The test profile's binary, built by the tests above: no second build.
SKELFORM=target/debug/skelform tests/interop/run.sh
echo "== the Python package: its wheel in a fresh virtual environment, pytest (tests/python)"
tests/python/run.sh
echo "== skelform's files in three.js, in headless Chromium (tests/browser)"
SKELFORM=target/debug/skelform tests/browser/run.sh
