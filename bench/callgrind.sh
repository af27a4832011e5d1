#!/usr/bin/env bash
# Instruction counts (valgrind's callgrind) of two skelform binaries on the same one-thread
# runs, with a check that their meshes are byte-identical. Counts do not depend on what else
# the machine is doing, so they compare builds on a busy machine where times cannot.
#
#   bench/callgrind.sh OLD_BINARY NEW_BINARY > table.md
#
# Build the old binary from a worktree of the earlier commit (`git worktree add ../old REV`,
# `cargo build --release --bin skelform` there).
set -euo pipefail
old=${1:?old binary}; new=${2:?new binary}
here=$(cd "$(dirname "$0")/.." && pwd)
work=$(mktemp -d); trap 'rm -rf "$work"' EXIT
python3 - "$work/gyroid112.raw" <<'PY'
import array, math, sys
n = 112
a = array.array('f')
for k in range(n):
    for j in range(n):
        for i in range(n):
            x, y, z = [(t / (n - 1)) * 6.28 - 3.14 for t in (i, j, k)]
            a.append(math.sin(x) * math.cos(y) + math.sin(y) * math.cos(z) + math.sin(z) * math.cos(x))
open(sys.argv[1], 'wb').write(a.tobytes())
PY
count() { # binary, output mesh, args...
    local bin=$1 out=$2; shift 2
    valgrind --tool=callgrind --callgrind-out-file="$work/cg.out" "$bin" "$@" -o "$out" >/dev/null 2>&1
    awk '/^(summary|totals):/ {print $2; exit}' "$work/cg.out"
}
run() { # name, args...
    local name=$1; shift
    local a b
    a=$(count "$old" "$work/old.ply" "$@")
    b=$(count "$new" "$work/new.ply" "$@")
    local same=different
    cmp -s "$work/old.ply" "$work/new.ply" && same=identical
    python3 -c "print(f'| $name | {$a:,} | {$b:,} | {$b/$a:.4f} | $same |')"
}
echo "| run (1 thread) | old instructions | new instructions | new/old | meshes |"
echo "|---|---:|---:|---:|---|"
run "grid, gyroid, 96 samples" mesh "$here/examples/gyroid.toml" --resolution 96 --threads 1 -q
run "extract, gyroid volume 112³" extract "$work/gyroid112.raw" --dims 112,112,112 --threads 1
run "continuation, torus, 96" mesh "$here/examples/torus.toml" --resolution 96 --method continuation --threads 1 -q
run "healed, Diabolo, 48" mesh "$here/examples/healed/diabolo.toml" --resolution 48 --threads 1 -q
run "nonmanifold, saucer and square" mesh "$here/examples/nonmanifold/saucer-and-square.toml" --threads 1 -q
run "grid, hand, 64" mesh "$here/examples/skeleton/hand.toml" --resolution 64 --threads 1 -q
