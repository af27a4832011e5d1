#!/usr/bin/env bash
# Issue 20's interactive-speed goals, from scratch (scene parsed, field built, mesh written):
#   the chapter-6 hand (109 elements) at a 128-samples cell (continuation, the issue's case, and grid), and
#   1000 random segments and points (bench/scenes/random-1000.toml) at a 256-samples cell.
# Prints a table: medians over R rounds of the tool's own wall time (`seconds.total`) and of
# the process's CPU time (user + system, all threads), field evaluations per output vertex,
# and, given an older binary, its medians from the same rounds (the two binaries take turns,
# so a busy machine slows both alike), the old/new ratios and whether the meshes are
# byte-identical.
#
#   bench/interactive.sh [OLD_BINARY] [ROUNDS]      (default: no old binary, 5 rounds)
#
# Then the edits, re-meshed by `skelform::Live` (crates/skelform/examples/live_edit.rs) against
# a fresh run of the edited scene in the same rounds: the hand with the middle finger's
# second knuckle bent by 10 degrees, and random-1000 with one segment moved by 0.01 (grid
# method; medians of wall time, mean CPU time per call, whether the meshes are identical).
#
# Build the old binary from a worktree of the earlier commit (`git worktree add ../old REV`,
# `cargo build --release --bin skelform` there). The old binary visits every element's box
# at every point: on the random scene it takes tens of seconds a run, so give it few rounds.
set -euo pipefail
old=${1:-}
rounds=${2:-5}
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin skelform
cargo build --release --quiet -p skelform --example live_edit
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

joint = 'name = "middle2"\nparent = "middle1"\nat = [0.9, 0, 0]\naxes = ["y"]\nangles = 30'
segment = "a = [0.8113, 0.3725, 0.5330]\nb = [0.9327, 0.3005, 0.5737]"
edits = [
    ("hand, a finger joint bent 10°", "examples/skeleton/hand.toml", 128, joint,
     joint.replace("angles = 30", "angles = 40")),
    ("random-1000, one element moved", "bench/scenes/random-1000.toml", 256, segment,
     segment.replace("0.8113", "0.8213").replace("0.9327", "0.9427")),
]
print()
print("| edit | samples | vertices | fresh: wall s | incremental: wall s | incr./fresh wall | "
      "fresh: CPU s | incremental: CPU s | incr./fresh CPU | re-sampled | reused vertices | same mesh |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for name, scene, res, old_text, new_text in edits:
    doc = json.loads(subprocess.run(
        ["./target/release/examples/live_edit", scene, str(res), str(max(rounds, 2)), old_text, new_text],
        check=True, capture_output=True, text=True).stdout)
    print(f"| {name} | {res} | {doc['vertices']:,} | {doc['fresh_s']:.3f} | {doc['incremental_s']:.4f} | "
          f"{doc['ratio']:.3f} | {doc['fresh_cpu_s']:.3f} | {doc['incremental_cpu_s']:.4f} | "
          f"{doc['incremental_cpu_s'] / doc['fresh_cpu_s']:.3f} | {doc['resampled']:,} | "
          f"{doc['reused_vertices']:,} | {'yes' if doc['same_mesh'] else 'no'} |", flush=True)
PY
