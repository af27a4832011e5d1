"""skelform against its peers on the same work, in one run on one machine.

Extraction only: every tool reads the same precomputed float32 volume and extracts the
zero level set; we time the extraction call alone (for skelform, the time it reports for its
extraction, after reading the file). Sampling plus extraction: each tool evaluates the field
its fastest way (NumPy for the Python tools, skelform's compiled formulas) and extracts, at
the sizes up to 256³ unless told otherwise (--both-sizes).
Each tool, field and size runs in a fresh process (imports made once, outside the timings),
which also gives its peak memory, and makes all its runs there: the first finds a cold
process, the others a warm one, as in a program that calls the library. skelform and
fast-surface-nets extract in one child process that repeats the extraction (`extract
--repeat`); skelform's sampling + extraction (`mesh`) is a new process per run. Medians of
--runs runs; the first-run (cold) times of skelform's extraction are in a table of their own.
Writes the tables to bench/results/latest.md and prints them.
"""

import argparse
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
SKELFORM = ROOT / "target" / "release" / "skelform"
FSN = ROOT / "target" / "release" / "examples" / "fsn_peer"
CEILING = ROOT / "target" / "release" / "examples" / "machine_ceiling"
CACHE = Path(__file__).resolve().parent / ".cache"

TAU = 6.283185307179586
# From this size on, skelform streams the volume (`extract --stream`; `mesh` does so by itself
# for volumes over 256 MiB) instead of holding it whole.
STREAM_FROM = 512

# name: (domain half-width, NumPy expression, the same in skelform's language). The NumPy
# expressions use broadcasting over the axes (x: [1, 1, n], y: [1, n, 1], z: [n, 1, 1]) instead
# of full coordinate grids, and the blobs are separable (e^(-k|p-c|²) = e^(-k(x-a)²)·e^(-k(y-b)²)
# ·e^(-k(z-c)²)): the fastest plain NumPy we know for each field, evaluated in float32. The
# skelform formulas are written the same way (a blob as e^(-k(x-a)²)·(e^(-k(y-b)²)·e^(-k(z-c)²)),
# whose factors skelform's lattice sampling computes once per column and once per row).
FIELDS = {
    "sphere": (1.0, "np.sqrt(x*x + y*y + z*z) - 0.8", "sqrt(x^2 + y^2 + z^2) - 0.8"),
    "torus": (1.0, "(np.sqrt(x*x + y*y) - 0.6)**2 + z*z - 0.0625", "(sqrt(x^2 + y^2) - 0.6)^2 + z^2 - 0.0625"),
    "gyroid": (TAU, "np.sin(x)*np.cos(y) + np.sin(y)*np.cos(z) + np.sin(z)*np.cos(x)",
               "sin(x)*cos(y) + sin(y)*cos(z) + sin(z)*cos(x)"),
}


def blobs():
    """Twenty Gaussian blobs at fixed pseudo-random places (a simple LCG, reproducible)."""
    seed = 2024
    out = []
    for _ in range(20):
        vals = []
        for _ in range(4):
            seed = (seed * 1103515245 + 12345) % (1 << 31)
            vals.append(seed / float(1 << 31))
        out.append(((vals[0] * 2 - 1) * 0.6, (vals[1] * 2 - 1) * 0.6, (vals[2] * 2 - 1) * 0.6, 12 + 10 * vals[3]))
    return out


BLOBS = blobs()
FIELDS["blobs"] = (
    1.0,
    "blob_sum(x, y, z)",
    "0.5 - (" + " + ".join(f"exp(-{k:.4f}*(x-{a:.4f})^2) * (exp(-{k:.4f}*(y-{b:.4f})^2) * exp(-{k:.4f}*(z-{c:.4f})^2))"
                           for a, b, c, k in BLOBS) + ")",
)


def blob_sum(x, y, z):
    import numpy as np
    total = np.zeros((z.shape[0], y.shape[1], x.shape[2]), dtype=np.float32)
    for a, b, c, k in BLOBS:
        k = np.float32(round(k, 4))
        ex = np.exp(-k * (x - np.float32(round(a, 4))) ** 2)
        ey = np.exp(-k * (y - np.float32(round(b, 4))) ** 2)
        ez = np.exp(-k * (z - np.float32(round(c, 4))) ** 2)
        total += ez * ey * ex
    return np.float32(0.5) - total


def numpy_volume(field, n):
    import numpy as np  # noqa: F401 (used by eval)
    h, expr, _ = FIELDS[field]
    t = np.linspace(-h, h, n, dtype=np.float32)
    x, y, z = t.reshape(1, 1, n), t.reshape(1, n, 1), t.reshape(n, 1, 1)  # x fastest in memory
    v = eval(expr)
    return np.broadcast_to(v, (n, n, n)).astype(np.float32)


def volume_file(field, n):
    CACHE.mkdir(exist_ok=True)
    path = CACHE / f"{field}-{n}-f32.raw"
    if not path.exists():
        numpy_volume(field, n).tofile(path)
    return path


# ---- worker mode: the measurements of one tool, field and size in a fresh process -------

# Rounds behind the speed-up table: in each, one process extracts with one thread and with
# all, in turn (`skelform extract --threads 1,N`), milliseconds apart; the rounds of each
# field and size are spread over the table's whole time, in passes over all of them.
SPEEDUP_ROUNDS = 11
SPEEDUP_PASSES = 3

# Tools that run as child processes and can repeat an extraction in one process themselves.
REPEATING = ("skelform-1", "skelform-all", "fast-surface-nets")


def worker(tool, field, n, mode, runs):
    """`runs` measurements in this process (the Python tools) or in one child process (the
    others, which repeat the extraction themselves): either way every tool's runs after the
    first find a warm process, as a program that calls the library does. Peak memory is the
    largest of any of them."""
    if mode == "extract" and tool in REPEATING:
        return repeated_extraction(tool, field, n, runs)
    results = []
    for _ in range(runs):
        r = one_run(tool, field, n, mode)
        if r is None:
            return None
        results.append(r)
    return results


def repeated_extraction(tool, field, n, runs):
    """`runs` extractions in one child process: skelform `extract --repeat`, or the
    fast-surface-nets peer with a repeat count."""
    with tempfile.TemporaryDirectory() as d:
        if tool == "fast-surface-nets":
            cmd = [str(FSN), str(volume_file(field, n)), str(n), str(n), str(n), str(runs)]
        else:
            threads = "1" if tool == "skelform-1" else str(os.cpu_count())
            cmd = [str(SKELFORM), "extract", str(volume_file(field, n)), "--dims", f"{n},{n},{n}",
                   "-o", f"{d}/m.ply", "--json", "--threads", threads, "--repeat", str(runs)]
            if n >= STREAM_FROM:
                # Read the file slab by slab: the time then includes reading it.
                cmd.append("--stream")
        j = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    seconds = j["seconds"] if tool == "fast-surface-nets" else j["seconds"]["extractions"]
    peak = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
    return [{"seconds": t, "vertices": j["vertices"], "triangles": j["triangles"], "peak_mib": peak}
            for t in seconds]


def paired_scaling(field, n, rounds):
    """skelform's extraction alternately on one thread and on all, `rounds` times in one
    process: each count's times and the rounds' speed-ups."""
    with tempfile.TemporaryDirectory() as d:
        cmd = [str(SKELFORM), "extract", str(volume_file(field, n)), "--dims", f"{n},{n},{n}",
               "-o", f"{d}/m.ply", "--json", "--threads", f"1,{os.cpu_count()}", "--repeat", str(rounds)]
        if n >= STREAM_FROM:
            cmd.append("--stream")
        j = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
    one, every = j["scaling"]
    return {"one": one["extractions"], "all": every["extractions"], "speedups": every["speedups"]}


def machine_ceiling(rounds):
    """`machine_ceiling`'s rounds: speed-ups of all cores over one for arithmetic alone and
    for a read through memory."""
    j = json.loads(subprocess.run([str(CEILING), str(rounds)], check=True, capture_output=True,
                                  text=True).stdout)
    return {"compute": j["compute"]["speedups"], "memory": j["memory"]["speedups"]}


def middle(xs):
    """Median and quartiles."""
    q1, med, q3 = statistics.quantiles(xs, n=4)
    return med, q1, q3


def flying_edges(vol, level=0.0):
    """A vtkFlyingEdges3D set up over `vol` (a C-ordered float32 array, wrapped without a
    copy: numpy_to_vtk keeps a reference to it) for the surface at `level`, with normals,
    gradients and scalars off; its Update() extracts, GetOutput() is the mesh."""
    import vtk
    from vtk.util import numpy_support

    n = vol.shape
    img = vtk.vtkImageData()
    img.SetDimensions(n[2], n[1], n[0])
    img.GetPointData().SetScalars(
        numpy_support.numpy_to_vtk(vol.ravel(), deep=False, array_type=vtk.VTK_FLOAT))
    fe = vtk.vtkFlyingEdges3D()
    fe.SetInputData(img)
    fe.SetValue(0, level)
    fe.ComputeNormalsOff()
    fe.ComputeGradientsOff()
    fe.ComputeScalarsOff()
    return fe


def one_run(tool, field, n, mode):
    result = {}
    # skelform and fast-surface-nets run as child processes: load nothing here, so that the
    # child's peak memory is its own.
    if tool in ("skelform-1", "skelform-all"):
        threads = "1" if tool == "skelform-1" else str(os.cpu_count())
        with tempfile.TemporaryDirectory() as d:
            if mode == "extract":
                cmd = [str(SKELFORM), "extract", str(volume_file(field, n)), "--dims", f"{n},{n},{n}",
                       "-o", f"{d}/m.ply", "--json", "--threads", threads]
                if n >= STREAM_FROM:
                    # Read the file slab by slab: the time then includes reading it.
                    cmd.append("--stream")
                j = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
                result["seconds"] = j["seconds"]["extraction"]
            else:
                h, _, formula = FIELDS[field]
                scene = Path(d) / "s.toml"
                scene.write_text(f'[domain]\nmin = [{-h}, {-h}, {-h}]\nmax = [{h}, {h}, {h}]\n'
                                 f'[mesh]\nresolution = {n}\nrefine = false\n[field]\nformula = "{formula}"\n')
                cmd = [str(SKELFORM), "mesh", str(scene), "-o", f"{d}/m.ply", "--json", "--threads", threads,
                       "--no-normals", "--no-refine"]
                j = json.loads(subprocess.run(cmd, check=True, capture_output=True, text=True).stdout)
                result["seconds"] = j["sampling"] + j["extraction"]
            result["vertices"], result["triangles"] = j["vertices"], j["triangles"]
        result["peak_mib"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        return result
    if tool == "fast-surface-nets":
        if mode != "extract":
            return None
        out = subprocess.run([str(FSN), str(volume_file(field, n)), str(n), str(n), str(n)],
                             check=True, capture_output=True, text=True).stdout
        j = json.loads(out)
        j["peak_mib"] = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024
        return j
    import numpy as np
    if tool == "scikit-image":
        from skimage.measure import marching_cubes
    elif tool == "PyMCubes":
        import mcubes
    if mode == "extract":
        vol = np.fromfile(volume_file(field, n), dtype=np.float32).reshape(n, n, n)
    t0 = time.perf_counter()
    if mode == "both":
        vol = numpy_volume(field, n)
    if tool == "scikit-image":
        t = time.perf_counter()
        verts, faces, _, _ = marching_cubes(vol, level=0.0)
    elif tool == "PyMCubes":
        t = time.perf_counter()
        verts, faces = mcubes.marching_cubes(vol, 0.0)
    elif tool == "VTK FlyingEdges3D":
        fe = flying_edges(vol)
        t = time.perf_counter()
        fe.Update()
        out = fe.GetOutput()
        verts, faces = range(out.GetNumberOfPoints()), range(out.GetNumberOfPolys())
    else:
        raise SystemExit(f"unknown tool {tool}")
    end = time.perf_counter()
    result["seconds"] = end - (t if mode == "extract" else t0)
    result["vertices"], result["triangles"] = len(verts), len(faces)
    result["peak_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    return result


TOOLS = ["skelform-1", "skelform-all", "VTK FlyingEdges3D", "PyMCubes", "scikit-image", "fast-surface-nets"]


def measure(tool, field, n, mode, runs):
    # One fresh process per tool, field and size: its imports are made once, outside the
    # timings, and its peak memory is its own.
    out = subprocess.run([sys.executable, __file__, "--worker", tool, field, str(n), mode, str(runs)],
                         check=True, capture_output=True, text=True).stdout
    samples = json.loads(out)
    if samples is None:
        return None
    med = statistics.median(s["seconds"] for s in samples)
    return {"seconds": med, "first": samples[0]["seconds"], "vertices": samples[0]["vertices"],
            "triangles": samples[0]["triangles"], "peak_mib": max(s["peak_mib"] for s in samples)}


def machine():
    cpu = "unknown CPU"
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return f"{cpu}, {os.cpu_count()} cores, {platform.system()} {platform.release()}, Python {platform.python_version()}"


def make_volumes(fields, sizes):
    """Writes the sample volumes that are not cached yet, each in a child process: a worker's
    peak memory would otherwise include this process's, inherited when it starts the worker."""
    for field in fields:
        for n in sizes:
            subprocess.run([sys.executable, __file__, "--generate", field, str(n)], check=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--worker", nargs=5, metavar=("TOOL", "FIELD", "N", "MODE", "RUNS"), help=argparse.SUPPRESS)
    ap.add_argument("--generate", nargs=2, metavar=("FIELD", "N"), help=argparse.SUPPRESS)
    ap.add_argument("--sizes", default="128,256,384")
    ap.add_argument("--fields", default="sphere,torus,gyroid,blobs")
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "latest.md"))
    ap.add_argument("--both-sizes", default=None,
                    help="sizes of the sampling-plus-extraction table (default: those of --sizes up "
                         "to 256³, or all of them when none is: at 384³ the Python peers' sampling "
                         "alone would take minutes of the run)")
    ap.add_argument("--prepare", action="store_true",
                    help="only write the sample volumes of these sizes and fields, and stop")
    a = ap.parse_args()
    if a.generate:
        volume_file(a.generate[0], int(a.generate[1]))
        return
    if a.worker:
        tool, field, n, mode, runs = a.worker
        print(json.dumps(worker(tool, field, int(n), mode, int(runs))))
        return
    sizes = [int(s) for s in a.sizes.split(",")]
    fields = a.fields.split(",")
    if a.both_sizes:
        both_sizes = [int(s) for s in a.both_sizes.split(",")]
    else:
        both_sizes = [n for n in sizes if n <= 256] or sizes
    if a.prepare:
        make_volumes(fields, sizes)
        return
    lines = [f"# skelform against its peers", "",
             f"One run of `bench/peers/run.sh` on {time.strftime('%Y-%m-%d')}: {machine()}.",
             f"Medians of {a.runs} runs in one fresh process per tool, field and size (the first cold, the others warm);",
             "ratio = peer time / skelform single-threaded time",
             "(above 1: skelform is faster). Peak memory is the process's maximum resident set.", ""]
    started = time.time()
    make_volumes(fields, sizes)
    threads = {}  # (field, n) -> {tool: (first, median)} for skelform's extraction
    for mode, title in [("extract", "Extraction only, from the same float32 volume"),
                        ("both", "Sampling plus extraction, each tool evaluating the field its fastest way")]:
        lines += [f"## {title}", "",
                  "| field | samples | tool | ms | ratio | vertices | triangles | peak MiB |",
                  "|---|---|---|---|---|---|---|---|"]
        for field in fields:
            for n in (sizes if mode == "extract" else both_sizes):
                base = None
                for tool in TOOLS:
                    r = measure(tool, field, n, mode, a.runs)
                    if r is None:
                        continue
                    if tool == "skelform-1":
                        base = r["seconds"]
                    if mode == "extract" and tool.startswith("skelform"):
                        threads.setdefault((field, n), {})[tool] = (r["first"], r["seconds"])
                    ratio = "" if tool.startswith("skelform-1") else f"{r['seconds'] / base:.2f}"
                    lines.append(f"| {field} | {n}³ | {tool} | {r['seconds'] * 1000:.1f} | {ratio} | "
                                 f"{r['vertices']:,} | {r['triangles']:,} | {r['peak_mib']:.0f} |")
                    print(lines[-1], flush=True)
        lines.append("")
        if mode == "extract":
            cores = os.cpu_count()
            rounds = SPEEDUP_ROUNDS * SPEEDUP_PASSES
            pooled = {key: {"one": [], "all": [], "speedups": []} for key in threads}
            ceiling = {"compute": [], "memory": []}
            for _ in range(SPEEDUP_PASSES):
                for key in threads:
                    for k, v in paired_scaling(*key, SPEEDUP_ROUNDS).items():
                        pooled[key][k] += v
                for k, v in machine_ceiling(SPEEDUP_ROUNDS).items():
                    ceiling[k] += v
            (cm, cq1, cq3), (mm, mq1, mq3) = middle(ceiling["compute"]), middle(ceiling["memory"])
            lines += ["## skelform's extraction on all cores against one", "",
                      f"Warm: {rounds} rounds, each extracting once with one thread and once with all {cores} in turn",
                      f"(`skelform extract --threads 1,{cores} --repeat {SPEEDUP_ROUNDS}`, one such process per field and size in",
                      f"each of {SPEEDUP_PASSES} passes over them all); the speed-up is the median of the rounds' ratios, with",
                      "their quartiles beside it, and the times are each thread count's medians. A shared",
                      "machine's speed drifts by up to 2× within minutes: a round's two runs are milliseconds",
                      "apart, so the drift cancels out of their ratio, and the passes spread every field's",
                      "rounds over the same minutes. Cold: the first extraction in a new process (the",
                      "processes of the table above).", "",
                      "What the machine gave to more threads in the same minutes, measured the same way",
                      f"(`machine_ceiling`, an example of skelform-polygonize, once per pass): a loop of arithmetic",
                      f"alone {cm:.2f}× ({cq1:.2f}–{cq3:.2f}); a read through a 256 MiB array (extraction's sign pass alone)",
                      f"{mm:.2f}× ({mq1:.2f}–{mq3:.2f}).", "",
                      "| field | samples | 1 thread, cold | all, cold | speed-up | 1 thread, warm | all, warm | speed-up | quartiles |",
                      "|---|---|---|---|---|---|---|---|---|"]
            for (field, n), t in threads.items():
                (c1, _), (ca, _) = t["skelform-1"], t["skelform-all"]
                w = pooled[(field, n)]
                (one, _, _), (every, _, _) = middle(w["one"]), middle(w["all"])
                up, q1, q3 = middle(w["speedups"])
                lines.append(f"| {field} | {n}³ | {c1 * 1000:.1f} | {ca * 1000:.1f} | {c1 / ca:.2f} | "
                             f"{one * 1000:.1f} | {every * 1000:.1f} | {up:.2f} | {q1:.2f}–{q3:.2f} |")
                print(lines[-1], flush=True)
            lines.append("")
    lines.append(f"Total benchmark time: {time.time() - started:.0f} s.")
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text("\n".join(lines) + "\n")
    print("\n".join(lines))


if __name__ == "__main__":
    main()
