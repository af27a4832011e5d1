"""Formulas, scenes, fields given as Python functions, and the Mesh they give."""

import _thread
import os
import threading
import time

import numpy as np
import pytest
import pyvista
import trimesh

import skelform

CUBE = ((-1.0, -1.0, -1.0), (1.0, 1.0, 1.0))


def component(mesh, i=0):
    return mesh.check()["components"][i]


def test_formula_broadcasts_and_differentiates():
    f = skelform.Formula("sqrt(x^2 + y^2 + z^2) - 0.8")
    x = np.linspace(-1, 1, 5)[:, None]
    y = np.linspace(-1, 1, 4)[None, :]
    v = f.eval(x, y, 0.25)
    assert v.shape == (5, 4)
    np.testing.assert_allclose(v, np.sqrt(x**2 + y**2 + 0.25**2) - 0.8, rtol=1e-12)
    assert f(0.0, 0.0, 0.0).shape == ()
    g = f.gradient(x, y, 0.25)
    assert g.shape == (5, 4, 3)
    r = np.sqrt(x**2 + y**2 + 0.25**2)
    np.testing.assert_allclose(g[..., 0], x / r, atol=1e-6)
    np.testing.assert_allclose(g[..., 2], 0.25 / r, atol=1e-6)


def test_formula_errors_say_where():
    with pytest.raises(ValueError, match="line 1, column 4"):
        skelform.Formula("x +* 2")


def test_scene_file_meshes_to_a_torus(examples):
    scene = skelform.load_scene(examples / "torus.toml")
    mesh = scene.mesh(resolution=48)
    c = component(mesh)
    assert c["closed"] and c["genus"] == 1 and c["outward"]
    assert mesh.vertices.dtype == np.float32 and mesh.vertices.shape[1] == 3
    assert mesh.faces.dtype == np.int32 and mesh.faces.shape[1] == 3
    assert mesh.normals.shape == mesh.vertices.shape
    assert mesh.method == "grid" and mesh.stats["grid_dims"]
    assert trimesh.Trimesh(mesh.vertices, mesh.faces, process=False).is_watertight
    assert mesh.to_trimesh().is_watertight
    poly = mesh.to_pyvista()
    assert isinstance(poly, pyvista.PolyData)
    assert poly.n_points == len(mesh.vertices) and poly.n_cells == len(mesh.faces)
    assert poly.is_manifold
    np.testing.assert_array_equal(poly.regular_faces, mesh.faces)
    np.testing.assert_array_equal(poly.point_data["Normals"], mesh.normals)


def test_scene_from_toml_and_overrides():
    scene = skelform.Scene.from_toml(
        '[domain]\nmin = [-1, -1, -1]\nmax = [1, 1, 1]\n[field]\nformula = "x^2 + y^2 + z^2 - 0.5"\n'
    )
    for method in ("grid", "continuation", "tetra"):
        mesh = scene.mesh(resolution=24, method=method)
        assert component(mesh)["closed"], method
        assert mesh.method == method
    with pytest.raises(ValueError, match="unknown method"):
        scene.mesh(method="marching")
    with pytest.raises(ValueError, match="<string>:2:"):
        skelform.Scene.from_toml("[domain]\nmin = [0, 0]\n")


def test_missing_scene_file():
    with pytest.raises(FileNotFoundError):
        skelform.load_scene("no/such/scene.toml")


def test_nonmanifold_labels_and_curves(examples, tmp_path):
    mesh = skelform.load_scene(examples / "nonmanifold" / "saucer-and-square.toml").mesh()
    assert mesh.labels.shape == (len(mesh.faces), 2)
    assert {tuple(l) for l in mesh.labels} == {(1, 2), (1, 3), (2, 3)}
    assert mesh.curves.shape[1] == 2 and len(mesh.curves) > 0
    assert mesh.curve_labels.shape == (len(mesh.curves), 3)
    # Non-manifold: VTK keeps the faces and their labels as cell data.
    poly = mesh.to_pyvista()
    assert poly.n_cells == len(mesh.faces) and not poly.is_manifold
    np.testing.assert_array_equal(poly.cell_data["labels"], mesh.labels)
    out = tmp_path / "saucer.glb"
    mesh.write(out)
    back = skelform.Mesh.read(out)
    assert len(back.faces) == len(mesh.faces)
    # The .glb holds one primitive per region pair: the same labels, grouped.
    assert sorted(map(tuple, back.labels)) == sorted(map(tuple, mesh.labels))


def test_healed_self_intersection(examples):
    # At 40 samples (32 is checked in Rust: tests/healed.rs,
    # split_sheets_separate_the_plane_and_the_ball_at_32_samples).
    mesh = skelform.load_scene(examples / "healed" / "plane-and-ball.toml").mesh(resolution=40)
    assert mesh.method == "healed"
    assert len(mesh.curves) > 0 and mesh.curves.max() < len(mesh.vertices)
    # Each sheet has its own copies of the curve vertices (its own normals), so unwelded no
    # edge has more than two triangles; welded by position, the sheets cross along edges of
    # four triangles.
    edges = mesh.check()["edge_degrees"]
    assert "4" not in edges and "3" not in edges, edges
    _, weld = np.unique(mesh.vertices, axis=0, return_inverse=True)
    faces = weld.reshape(-1)[mesh.faces]
    pairs = np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1)
    _, degree = np.unique(pairs, axis=0, return_counts=True)
    assert (degree == 4).any(), "the sheets cross along edges of four triangles"


def test_poses_of_the_hand(examples):
    scene = skelform.load_scene(examples / "skeleton" / "hand.toml")
    assert scene.poses
    rest = scene.mesh(resolution=40)
    posed = scene.mesh(resolution=40, pose=scene.poses[-1])
    assert len(rest.faces) > 0 and len(posed.faces) > 0
    assert not np.array_equal(rest.vertices.shape, posed.vertices.shape) or not np.allclose(
        rest.vertices, posed.vertices
    )
    with pytest.raises(ValueError, match="pose"):
        scene.mesh(resolution=24, pose="no-such-pose")


def test_mesh_of_formula_text_and_formula():
    a = skelform.mesh("sqrt(x^2 + y^2 + z^2) - 0.7", CUBE, resolution=32)
    b = skelform.mesh(skelform.Formula("sqrt(x^2 + y^2 + z^2) - 0.7"), CUBE, resolution=32)
    np.testing.assert_array_equal(a.vertices, b.vertices)
    r = np.linalg.norm(a.vertices, axis=1)
    assert np.abs(r - 0.7).max() < 1e-3  # refined onto the surface
    assert component(a)["closed"]


def test_mesh_of_a_python_function_matches_the_formula():
    calls = []

    def ball(p):
        assert p.ndim == 2 and p.shape[1] == 3 and p.dtype == np.float64
        calls.append(len(p))
        return np.sqrt((p**2).sum(1)) - 0.7

    ours = skelform.mesh(ball, CUBE, resolution=32)
    formula = skelform.mesh("sqrt(x^2 + y^2 + z^2) - 0.7", CUBE, resolution=32)
    assert component(ours)["closed"] and component(ours)["genus"] == 0
    assert len(ours.faces) == len(formula.faces)
    np.testing.assert_allclose(ours.vertices, formula.vertices, atol=1e-4)
    assert max(calls) >= 32 * 32, "called a layer at a time, not a point at a time"


def test_python_function_exceptions_propagate():
    def broken(p):
        raise KeyError("no field here")

    with pytest.raises(KeyError, match="no field here"):
        skelform.mesh(broken, CUBE, resolution=16)
    with pytest.raises(ValueError, match="returned 1 values"):
        skelform.mesh(lambda p: np.zeros(1), CUBE, resolution=16)
    with pytest.raises(TypeError):
        skelform.mesh(42, CUBE)


def test_a_python_function_may_mesh_again_while_it_is_called():
    # The field's function runs on one of skelform's worker threads; a call from there
    # runs on that thread (or its own pool's) instead of waiting for a worker of its own.
    inner = []

    def ball(p):
        for threads in (None, 1, 2):
            v, f, _, _ = skelform.marching_cubes(
                np.fromfunction(lambda i, j, k: (i - 3.5) ** 2 + (j - 3.5) ** 2 + (k - 3.5) ** 2,
                                (8, 8, 8)),
                6.0, threads=threads)
            inner.append(len(f))
        return np.sqrt((p**2).sum(1)) - 0.7

    ours = skelform.mesh(ball, CUBE, resolution=12)
    assert component(ours)["closed"]
    assert inner and len(set(inner)) == 1 and inner[0] > 0


def test_calls_from_several_python_threads_at_once_give_their_own_meshes():
    vols = [np.fromfunction(lambda i, j, k: (i - 9.5) ** 2 + (j - 9.5) ** 2 + (k - 9.5) ** 2 - r * r,
                            (20, 20, 20)) for r in (3, 5, 7)]
    alone = [len(skelform.marching_cubes(v, 0.0)[1]) for v in vols]
    got, failed = [], []

    def work(n):
        try:
            for i in range(60):
                k = (n + i) % 3
                faces = skelform.marching_cubes(vols[k], 0.0, threads=1 + i % 2)[1]
                got.append(len(faces) == alone[k])
        except Exception as e:  # noqa: BLE001 - reported below
            failed.append(e)

    placed = hasattr(os, "sched_getaffinity") and os.path.isdir("/proc/self/task")
    allowed = os.sched_getaffinity(0) if placed else None
    threads = [threading.Thread(target=work, args=(n,)) for n in range(3)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not failed and len(got) == 180 and all(got)
    # Workers are pinned apart only while calls run: every thread may run anywhere again.
    for tid in os.listdir("/proc/self/task") if placed else []:
        assert os.sched_getaffinity(int(tid)) == allowed


def test_progress_and_cancellation(examples):
    scene = skelform.load_scene(examples / "gyroid.toml")
    seen = []

    def progress(phase, done, total):
        seen.append((phase, done, total))
        return None

    scene.mesh(resolution=48, progress=progress)
    assert seen and all(isinstance(p, str) for p, _, _ in seen)
    with pytest.raises(skelform.Cancelled):
        scene.mesh(resolution=64, progress=lambda *a: False)


def test_ctrl_c_interrupts_a_long_run(examples):
    scene = skelform.load_scene(examples / "gyroid.toml")
    timer = threading.Timer(0.3, _thread.interrupt_main)
    timer.start()
    started = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        scene.mesh(resolution=1000, max_memory=8 << 30)
    timer.cancel()
    assert time.monotonic() - started < 30


def test_the_gil_is_released(examples):
    scene = skelform.load_scene(examples / "gyroid.toml")
    ticks = 0
    done = threading.Event()

    def work():
        scene.mesh(resolution=96)
        done.set()

    t = threading.Thread(target=work)
    t.start()
    while not done.is_set():
        ticks += 1
        time.sleep(0.001)
    t.join()
    assert ticks > 5


def test_mesh_from_arrays_checks_and_writes(tmp_path):
    v, f, _, _ = skelform.marching_cubes(
        np.fromfunction(lambda i, j, k: (i - 7.5) ** 2 + (j - 7.5) ** 2 + (k - 7.5) ** 2, (16, 16, 16)),
        25.0,
    )
    mesh = skelform.Mesh(v, f)
    report = mesh.check()
    assert report["boundary_edges"] == 0 and report["components"][0]["genus"] == 0
    for ext in ("ply", "obj", "stl", "glb"):
        mesh.write(tmp_path / f"ball.{ext}")
        assert len(skelform.Mesh.read(tmp_path / f"ball.{ext}").faces) == len(f)
    with pytest.raises(ValueError, match="extension"):
        mesh.write(tmp_path / "ball.xyz")
    with pytest.raises(ValueError, match="outside"):
        skelform.Mesh(v, np.array([[0, 1, len(v)]]))
