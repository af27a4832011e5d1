#!/usr/bin/env bash
# Instructions per steady-state call of skelform.marching_cubes (one thread), scikit-image's
# marching_cubes and VTK's vtkFlyingEdges3D on the same 256³ float32 array: a measure the
# load of a shared machine does not move (valgrind's callgrind; each tool: 4 calls less 1
# call, over 3, so that imports, the volume and first-call set-up drop out). Uses the
# environment bench/peers/python.sh makes (run that first). Slow: about a minute a tool.
#
#   bench/peers/python_icount.sh [FIELD [N]]     # default: sphere 256
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
py=$here/.venv/bin/python
field=${1:-sphere}
n=${2:-256}
command -v valgrind >/dev/null || { echo "valgrind is needed (apt-get install valgrind)" >&2; exit 1; }
[ -x "$py" ] || { echo "run bench/peers/python.sh first (it makes $here/.venv)" >&2; exit 1; }
script='
import sys
sys.path.insert(0, sys.argv[1])
import numpy as np
from peers import flying_edges, numpy_volume
tool, field, n, calls = sys.argv[2], sys.argv[3], int(sys.argv[4]), int(sys.argv[5])
vol = np.ascontiguousarray(numpy_volume(field, n))
if tool == "skelform":
    import skelform
    f = lambda: skelform.marching_cubes(vol, 0.0, threads=1)
elif tool == "scikit-image":
    from skimage.measure import marching_cubes
    f = lambda: marching_cubes(vol, 0.0)
else:
    f = lambda: flying_edges(vol).Update()
for _ in range(calls):
    f()
'
count() {
    valgrind --tool=callgrind --callgrind-out-file=/dev/null "$py" -c "$script" "$here" "$1" "$field" "$n" "$2" 2>&1 |
        sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
for tool in skelform VTK scikit-image; do
    one=$(count "$tool" 1)
    four=$(count "$tool" 4)
    echo "$tool, $field $n³: $(( (four - one) / 3 / 1000000 )) M instructions per call"
done
