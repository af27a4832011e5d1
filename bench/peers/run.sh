#!/usr/bin/env bash
# skelform against scikit-image, PyMCubes, VTK (Flying Edges) and fast-surface-nets, on the
# same volumes, in one run. Creates its own Python virtual environment (bench/peers/.venv),
# installs the peers from PyPI, builds skelform in release mode, and writes
# bench/results/latest.md. Options go to peers.py (--sizes 128,256 --fields torus --runs 3).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
started=$(date +%s)
# The build runs while the Python side installs the peers and writes the sample volumes.
(cd "$root" && cargo build --release --quiet --bin skelform \
    && cargo build --release --quiet -p skelform-polygonize --example fsn_peer --example machine_ceiling) &
build=$!
if [ ! -x "$here/.venv/bin/python" ]; then
    python3 -m venv "$here/.venv"
fi
"$here/.venv/bin/pip" install --quiet --disable-pip-version-check numpy scikit-image PyMCubes vtk
"$here/.venv/bin/python" "$here/peers.py" --prepare "$@"
if ! wait "$build"; then
    echo "run.sh: building skelform failed" >&2
    exit 1
fi
echo "run.sh: set up in $(( $(date +%s) - started )) s (environment, peers, build, volumes)" >&2
exec "$here/.venv/bin/python" "$here/peers.py" "$@"
