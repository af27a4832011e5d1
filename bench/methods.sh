#!/usr/bin/env bash
# Field evaluations and time of each polygonizer on the same scenes, from one run.
# Usage: bench/methods.sh [scene.toml ...]   (default: the continuation benchmark scenes and
# the chapter-6 hand, whose 85 skeletal elements seed the continuation methods)
# Evaluation counts are exact and repeatable; times are from this run on this machine.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin skelform
scenes=("$@")
[ ${#scenes[@]} -gt 0 ] || scenes=(examples/continuation/blobs-50.toml examples/continuation/torus.toml examples/continuation/jacks.toml examples/skeleton/hand.toml)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
printf '| scene | method | evaluations | triangles | components | seconds (median of 3) |\n|---|---|---|---|---|---|\n'
for s in "${scenes[@]}"; do
    for m in grid continuation tetra; do
        times=()
        for _ in 1 2 3; do
            j=$(./target/release/skelform mesh "$s" -o "$out/m.ply" --method "$m" --json -q)
            times+=("$(python3 -c 'import json,sys; print(json.load(sys.stdin)["seconds"]["total"])' <<<"$j")")
        done
        python3 - "$s" "$m" "$j" "${times[@]}" <<'PY'
import json, sys
scene, method, doc, *times = sys.argv[1:]
j = json.loads(doc)
t = sorted(float(x) for x in times)[1]
comps = len(j["components"]) if "components" in j else "-"
print(f"| {scene} | {method} | {j['evaluations']:,} | {j['triangles']:,} | {comps} | {t:.3f} |")
PY
    done
done
