#!/usr/bin/env bash
# Checks that trimesh, meshio and pymeshlab read skelform's outputs (tests/interop/check_readers.py).
#
#   tests/interop/run.sh            # builds skelform (dev profile) unless SKELFORM names a binary
#   SKELFORM=target/release/skelform tests/interop/run.sh
#   SKELFORM=target/debug/skelform tests/interop/run.sh   # after `cargo test -p skelform-cli`
#                                                         # (no second build of the binary)
#
# Makes a virtual environment in target/interop-venv (once; PyPI must be reachable the first
# time) and writes the meshes to target/interop-out.
set -euo pipefail
root=$(cd "$(dirname "$0")/../.." && pwd)
cd "$root"
if [[ -z "${SKELFORM:-}" ]]; then
    cargo build -q -p skelform-cli
    SKELFORM=target/debug/skelform
fi
venv=target/interop-venv
if [[ ! -x $venv/bin/python ]] || ! $venv/bin/python -c 'import trimesh, meshio, pymeshlab, numpy, scipy, networkx' 2>/dev/null; then
    python3 -m venv "$venv"
    # scipy and networkx: trimesh needs them to load a PLY of edges as a path.
    "$venv/bin/pip" install -q trimesh meshio pymeshlab numpy scipy networkx
fi
out=target/interop-out
rm -rf "$out"
mkdir -p "$out"
mesh() { "$SKELFORM" mesh "$@" --quiet; }
# Closed surfaces (grid and continuation), a labelled non-manifold scene, a healed scene with curves.
for ext in ply obj stl glb; do
    mesh examples/sphere.toml -o "$out/sphere.$ext" --resolution 24
    mesh examples/torus.toml -o "$out/torus.$ext" --resolution 32
    mesh examples/nonmanifold/saucer-and-square.toml -o "$out/saucer.$ext"
done
mesh examples/nonmanifold/saucer-and-square.toml -o "$out/saucer-nocurves.glb" --no-curves
mesh examples/nonmanifold/sphere-and-square.toml -o "$out/sphere-and-square.ply"
mesh examples/healed/double-cone.toml -o "$out/double-cone.ply" --resolution 24
mesh examples/torus.toml -o "$out/torus-ascii.ply" --resolution 16 --ascii
mesh examples/nonmanifold/saucer-and-square.toml -o "$out/saucer-ascii.ply" --ascii
"$venv/bin/python" tests/interop/check_readers.py "$out" "$SKELFORM"
