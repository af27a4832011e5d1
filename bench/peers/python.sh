#!/usr/bin/env bash
# skelform.marching_cubes from Python against scikit-image, PyMCubes and VTK on the same
# arrays (python_api.py). Uses the peers' environment (bench/peers/.venv, made here when
# missing), installs skelform's wheel into it (a release build), and writes
# bench/results/python.md. Options go to python_api.py (--sizes 256 --fields torus --runs 9).
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../.." && pwd)
if [ ! -x "$here/.venv/bin/python" ]; then
    python3 -m venv "$here/.venv"
fi
"$here/.venv/bin/pip" install --quiet --disable-pip-version-check numpy scikit-image PyMCubes vtk
"$here/.venv/bin/pip" install --quiet --disable-pip-version-check --force-reinstall --no-deps "$root/crates/skelform-python"
cd "$here"
exec "$here/.venv/bin/python" "$here/python_api.py" "$@"
