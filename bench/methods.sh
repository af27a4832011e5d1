#!/usr/bin/env bash
# Field evaluations and time of each polygonizer on the same scenes, from one run.
# Usage: bench/methods.sh [scene.toml ...]   (default: the continuation benchmark scenes, the
# chapter-6 hand, whose 85 skeletal elements seed the continuation methods, and every
# non-manifold example of chapter 4 and the leaves)
# Evaluation counts are exact and repeatable; times are from this run on this machine.
# The ratio column is evaluations / the tetra polygonizer's evaluations on the same scene. A
# region scene (`[regions]` or `[leaf]`) has no field for the tetra polygonizer, so its one row
# (method nonmanifold) divides the region function's evaluations by the count the library
# reports for a conventional tetrahedral polygonizer on the same cubes
# (`conventional_evaluations`: every corner once, eight bisections per segment whose ends
# differ): issue 18 asks for at most 2.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin skelform
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(examples/continuation/blobs-50.toml examples/continuation/torus.toml examples/continuation/jacks.toml examples/skeleton/hand.toml examples/nonmanifold/*.toml)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printf '| scene | method | evaluations | evaluations / tetra evaluations | triangles | components | seconds (median of 3) |\n|---|---|---|---|---|---|---|\n'
for s in "${scenes[@]}"; do
    methods=(tetra grid continuation)
    grep -Eq '^\[(regions|leaf)\]' "$s" && methods=(nonmanifold)
    tetra=0
    for m in "${methods[@]}"; do
        times=()
        for _ in 1 2 3; do
            j=$(./target/release/skelform mesh "$s" -o "$out/m.ply" --method "$m" --json -q)
            times+=("$(python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"]["total"])' <<<"$j")")
        done
        if [ "$m" = tetra ]; then tetra=$(python3 -c 'import json,sys; print(json.load(sys.stdin)["evaluations"])' <<<"$j"); fi
        python3 - "$s" "$m" "$j" "$tetra" "${times[@]}" <<'PY'
import json, sys
scene, method, doc, tetra, *times = sys.argv[1:]
j = json.loads(doc)
t = sorted(float(x) for x in times)[1]
comps = len(j["components"]) if "components" in j else "-"
base = j.get("conventional_evaluations") or int(tetra)
ratio = f"{j['evaluations'] / base:.2f}"
print(f"| {scene} | {method} | {j['evaluations']:,} | {ratio} | {j['triangles']:,} | {comps} | {t:.3f} |")
PY
    done
done
