#!/usr/bin/env bash
# Issue 20's interactive-speed goals, from scratch (scene parsed, field built, mesh written):
#   the 85-element hand at a 128-samples cell (continuation, the issue's case, and grid), and
#   1000 random segments and points (bench/scenes/random-1000.toml) at a 256-samples cell.
# Prints a table: medians over R rounds of the tool's own wall time (`seconds.total`) and of
# the process's CPU time (user + system, all threads), field evaluations per output vertex,
# and, given an older binary, its medians from the same rounds (the two binaries take turns,
# so a busy machine slows both alike), the old/new ratios and whether the meshes are
# byte-identical.
#
#   bench/interactive.sh [OLD_BINARY] [ROUNDS]      (default: no old binary, 5 rounds)
#
# Build the old binary from a worktree of the earlier commit (`git worktree add ../old REV`,
# `cargo build --release --bin skelform` there). The old binary visits every element's box
# at every point: on the random scene it takes tens of seconds a run, so give it few rounds.
set -euo pipefail
old=${1:-}
rounds=${2:-5}
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin skelform
[ -f bench/scenes/random-1000.toml ] || python3 bench/scenes/random-1000.py
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
python3 - "$out" "$rounds" "$old" <<'PY'
import json, os, resource, statistics, subprocess, sys

out, rounds, old = sys.argv[1], int(sys.argv[2]), sys.argv[3]
new = "./target/release/skelform"
cases = [
    ("examples/skeleton/hand.toml", "continuation", 128),
    ("examples/skeleton/hand.toml", "grid", 128),
    ("bench/scenes/random-1000.toml", "grid", 256),
    ("bench/scenes/random-1000.toml", "continuation", 256),
]

def run(binary, scene, method, res, ply):
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    doc = subprocess.run(
        [binary, "mesh", scene, "-o", ply, "--method", method, "--resolution", str(res), "--json", "-q"],
        check=True, capture_output=True, text=True).stdout
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return json.loads(doc), cpu

head = "| scene | method | samples | vertices | evaluations per vertex | new: wall s | new: CPU s |"
rule = "|---|---|---|---|---|---|---|"
if old:
    head += " old: wall s | old: CPU s | old/new wall | old/new CPU | same mesh |"
    rule += "---|---|---|---|---|"
print(head)
print(rule)
for scene, method, res in cases:
    times = {"new": [], "old": []}
    for _ in range(rounds):
        for tag, binary in (("new", new), ("old", old)):
            if not binary:
                continue
            j, cpu = run(binary, scene, method, res, os.path.join(out, tag + ".ply"))
            times[tag].append((j["seconds"]["total"], cpu))
            if tag == "new":
                doc = j
    med = {k: (statistics.median(t for t, _ in v), statistics.median(c for _, c in v))
           for k, v in times.items() if v}
    name = os.path.splitext(os.path.basename(scene))[0]
    row = (f"| {name} | {method} | {res} | {doc['vertices']:,} | "
           f"{doc['evaluations'] / max(doc['vertices'], 1):.2f} | {med['new'][0]:.3f} | {med['new'][1]:.3f} |")
    if old:
        with open(os.path.join(out, "new.ply"), "rb") as a, open(os.path.join(out, "old.ply"), "rb") as b:
            same = "yes" if a.read() == b.read() else "no"
        row += (f" {med['old'][0]:.3f} | {med['old'][1]:.3f} | {med['old'][0] / med['new'][0]:.2f} | "
                f"{med['old'][1] / med['new'][1]:.2f} | {same} |")
    print(row, flush=True)
PY
