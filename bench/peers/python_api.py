"""skelform.marching_cubes from Python against scikit-image, PyMCubes and VTK's Flying Edges,
on the same NumPy arrays in one process and one run.

Every tool gets the same C-ordered float32 volume (the fields of peers.py) and extracts its
zero level set; the timed call is the library call alone (for VTK, `Update()` of a
`vtkFlyingEdges3D` over an image that wraps the array without a copy, normals off).
skelform and scikit-image also return vertex normals and values, which PyMCubes and VTK (as
set here) do not. The tools take turns within each round, so that a shared machine's drift
falls on all of them alike; medians of --runs rounds; ratio = peer time / skelform time on one
thread (above 1: skelform is faster), of the medians and, paired, the median of the rounds'
ratios. Writes bench/results/python.md and prints it.
"""

import argparse
import os
import statistics
import time
from pathlib import Path

# The BLAS that NumPy and SciPy (imported by scikit-image) load starts a pool of threads that
# spin for a while after each call that uses it; on a 2-core machine they took the second
# core from the two-thread skelform call that followed (4.6% of a profile of that call:
# `blas_thread_server`). No tool timed here uses more than one BLAS thread, so the pool is
# kept to one, before NumPy is first imported (a value already set is kept).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from peers import FIELDS, ROOT, flying_edges, machine, numpy_volume  # noqa: E402


def tools():
    import mcubes
    from skimage.measure import marching_cubes as sk

    import skelform

    def vtk_flying_edges(vol):
        fe = flying_edges(vol)
        t = time.perf_counter()
        fe.Update()
        return time.perf_counter() - t, fe.GetOutput().GetNumberOfPolys()

    def timed(f):
        def run(vol):
            t = time.perf_counter()
            faces = f(vol)[1]
            return time.perf_counter() - t, len(faces)
        return run

    cores = os.cpu_count()
    return {
        "skelform, 1 thread": timed(lambda v: skelform.marching_cubes(v, 0.0, threads=1)),
        f"skelform, {cores} threads": timed(lambda v: skelform.marching_cubes(v, 0.0, threads=cores)),
        "VTK FlyingEdges3D": vtk_flying_edges,
        "PyMCubes": timed(lambda v: mcubes.marching_cubes(v, 0.0)),
        "scikit-image": timed(lambda v: sk(v, 0.0)),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="128,256")
    ap.add_argument("--fields", default="sphere,torus,gyroid")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "python.md"))
    a = ap.parse_args()
    every = tools()
    lines = ["# skelform.marching_cubes from Python against its peers", "",
             f"One run of `bench/peers/python.sh` on {time.strftime('%Y-%m-%d')}: {machine()}.",
             f"Medians of {a.runs} rounds in one process, the tools taking turns in each round;",
             "ratio = tool time / skelform's single-threaded time is shown as the peer's slowdown",
             "(above 1: skelform is faster): of the medians, and the median of each round's ratio.", "",
             "| field | samples | tool | ms | ratio | ratio by round | triangles |",
             "|---|---|---|---|---|---|---|"]
    started = time.time()
    load_before = os.getloadavg()
    for field in a.fields.split(","):
        for n in map(int, a.sizes.split(",")):
            vol = np.ascontiguousarray(numpy_volume(field, n))
            times = {name: [] for name in every}
            faces = {}
            for name, f in every.items():
                f(vol)  # warm: imports, tables, first-touch of the pools
            for _ in range(a.runs):
                for name, f in every.items():
                    t, faces[name] = f(vol)
                    times[name].append(t)
            one = times["skelform, 1 thread"]
            base = statistics.median(one)
            for name in every:
                med = statistics.median(times[name])
                # The ratio in each round, between calls made a moment apart, and their
                # median: a slow stretch of the machine that lasts a few rounds moves both
                # calls of a round alike, where it moves one tool's median and not the other's.
                paired = statistics.median(t / b for t, b in zip(times[name], one))
                ratio = "" if name == "skelform, 1 thread" else f"{med / base:.2f}"
                per_round = "" if name == "skelform, 1 thread" else f"{paired:.2f}"
                lines.append(f"| {field} | {n}³ | {name} | {med * 1000:.1f} | {ratio} | {per_round} | {faces[name]:,} |")
                print(lines[-1], flush=True)
    load_after = os.getloadavg()
    # The machine's load, which on a shared machine moves every time here by tens of percent.
    load = lambda l: "/".join(f"{x:.1f}" for x in l)
    lines += ["", f"Total benchmark time: {time.time() - started:.0f} s. Load average (1/5/15 min) "
              f"before: {load(load_before)}, after: {load(load_after)} on {os.cpu_count()} cores."]
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
