#!/usr/bin/env bash
# The Python package's tests, on what a user gets: the wheel of crates/skelform-python,
# built by pip (maturin, release profile) and installed into a fresh virtual environment
# with numpy, pytest, scikit-image, trimesh and pyvista (with VTK) from PyPI; then pytest on
# crates/skelform-python/tests.
#
#   tests/python/run.sh                 # a new environment in target/python-venv each run
#   SKELFORM_PY_KEEP_VENV=1 tests/python/run.sh   # reuse it (faster when iterating)
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
if ! python3 -c 'import venv, ensurepip' 2>/dev/null; then
    echo "python3 with venv and ensurepip is needed (Debian: apt-get install python3-venv)" >&2
    exit 1
fi
venv=$root/target/python-venv
if [[ -z "${SKELFORM_PY_KEEP_VENV:-}" || ! -x $venv/bin/python ]]; then
    rm -rf "$venv"
    python3 -m venv "$venv"
    "$venv/bin/pip" install -q --upgrade pip
    "$venv/bin/pip" install -q numpy pytest scikit-image trimesh pyvista
fi
echo "building and installing the wheel (pip install crates/skelform-python)"
"$venv/bin/pip" install -q --force-reinstall --no-deps crates/skelform-python
"$venv/bin/python" -c 'import skelform, sys; print("skelform", skelform.__version__, "on Python", sys.version.split()[0])'
# From outside the source tree, so that the installed package is what is imported.
cd "$root/target"
"$venv/bin/python" -m pytest -q -p no:cacheprovider "$root/crates/skelform-python/tests"
