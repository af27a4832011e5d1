"""skelform.marching_cubes against scikit-image's: same conventions, better topology."""

import numpy as np
import pytest
import trimesh
from skimage.measure import marching_cubes as sk_marching_cubes

import skelform


def topology(verts, faces):
    """(boundary edges, non-manifold edges, consistently oriented) from skelform's checker."""
    r = skelform.Mesh(np.asarray(verts, np.float32), faces).check()
    return r["boundary_edges"], r["non_manifold_edges"], r["consistently_oriented"]


def closed(verts, faces):
    return topology(verts, faces) == (0, 0, True)


def sorted_rows(a):
    a = np.asarray(a, np.float64)
    return a[np.lexsort(a.T[::-1])]


def sphere(n=40, centre=(17.3, 19.6, 18.8), radius=11.0):
    g = np.mgrid[0:n, 0:n, 0:n].astype(np.float64)
    c = np.array(centre).reshape(3, 1, 1, 1)
    return np.sqrt(((g - c) ** 2).sum(0)) - radius


def torus(n=48):
    z, y, x = np.mgrid[-1:1:n * 1j, -1.1:1.1:n * 1j, -1.2:1.2:n * 1j]
    return np.sqrt((np.sqrt(x**2 + y**2) - 0.61) ** 2 + z**2) - 0.27


@pytest.mark.parametrize("field", [sphere, torus])
@pytest.mark.parametrize("spacing", [(1.0, 1.0, 1.0), (0.5, 1.0, 2.0)])
def test_same_mesh_as_scikit_image_without_ambiguity(field, spacing):
    vol = field()
    theirs = sk_marching_cubes(vol, 0.0, spacing=spacing)
    ours = skelform.marching_cubes(vol, 0.0, spacing=spacing)
    assert [a.dtype for a in ours] == [a.dtype for a in theirs]
    assert ours[0].shape == theirs[0].shape and ours[1].shape == theirs[1].shape
    np.testing.assert_allclose(sorted_rows(ours[0]), sorted_rows(theirs[0]), atol=1e-5)
    # Winding: the faces' normals point the same way as scikit-image's (towards higher
    # values with the default gradient direction).
    def face_normals_up(v, f):
        n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        centre = v.mean(0)
        return np.mean((n * (v[f].mean(1) - centre)).sum(1) > 0)
    assert face_normals_up(*ours[:2]) == pytest.approx(face_normals_up(*theirs[:2]), abs=0.02)
    # Vertex normals point down the gradient, as scikit-image's do.
    order_o, order_t = np.lexsort(ours[0].T[::-1]), np.lexsort(theirs[0].T[::-1])
    dots = (ours[2][order_o] * theirs[2][order_t]).sum(1)
    assert np.percentile(dots, 5) > 0.98
    assert closed(ours[0], ours[1])


def test_ascent_reverses_the_faces():
    vol = sphere()
    down = skelform.marching_cubes(vol, 0.0)
    up = skelform.marching_cubes(vol, 0.0, gradient_direction="ascent")
    np.testing.assert_array_equal(down[1][:, [0, 2, 1]], up[1])
    np.testing.assert_array_equal(down[2], up[2])


def test_closed_where_scikit_image_leaves_holes():
    # Integer volumes put samples exactly on the level: scikit-image's meshes of these have
    # holes (every one of these, when this test was written); skelform's are closed.
    rng = np.random.default_rng(3)
    holes_theirs = 0
    for _ in range(60):
        vol = rng.integers(-1, 2, (8, 8, 8)).astype(np.float64)
        vol[[0, -1]] = vol[:, [0, -1]] = vol[:, :, [0, -1]] = 1
        if vol.min() >= 0:
            continue
        v, f, _, _ = skelform.marching_cubes(vol, 0.0)
        assert closed(v, f)
        assert trimesh.Trimesh(v, f, process=False).is_watertight
        holes_theirs += not closed(*sk_marching_cubes(vol, 0.0)[:2])
    assert holes_theirs > 0, "the comparison no longer shows scikit-image's holes"


def test_ambiguous_noise_is_closed_and_watertight():
    rng = np.random.default_rng(1)
    vol = rng.standard_normal((24, 24, 24))
    vol[[0, -1]] = vol[:, [0, -1]] = vol[:, :, [0, -1]] = 5
    v, f, n, values = skelform.marching_cubes(vol, 0.0)
    assert closed(v, f)
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight and mesh.is_winding_consistent
    assert np.all(np.isfinite(values)) and np.all(values >= 0)


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("direction", ["descent", "ascent"])
@pytest.mark.parametrize("threads", [1, 2])
def test_winding_is_scikit_images_in_every_memory_order(order, direction, threads):
    """The faces come wound from the extractor (its axes are the array's reversed in C
    order, not in Fortran order): every face's normal, by the right-hand rule, points the
    way scikit-image's do, out of a sphere (towards higher values) for "descent"."""
    vol = np.asarray(sphere(), order=order)
    verts, faces = skelform.marching_cubes(vol, 0.0, gradient_direction=direction,
                                           threads=threads)[:2]
    theirs = sk_marching_cubes(np.ascontiguousarray(vol), 0.0, gradient_direction=direction)
    def outward(v, f):
        n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        return (n * (v[f].mean(1) - np.array([17.3, 19.6, 18.8]))).sum(1) > 0
    ours = outward(verts, faces)
    assert ours.all() if direction == "descent" else not ours.any()
    assert outward(*theirs[:2]).mean() == pytest.approx(ours.mean(), abs=0.02)
    assert faces.dtype == np.int32 and faces.flags.c_contiguous and faces.min() >= 0
    assert closed(verts, faces)


def test_dtypes_and_memory_orders_give_the_same_mesh():
    vol = np.round(sphere(24, (11.3, 12.1, 10.7), 7.0) * 100)
    ref = skelform.marching_cubes(vol.astype(np.float64), 0.5)
    for a in (vol.astype(np.float32), vol.astype(np.int16), vol.astype(np.int64),
              np.asfortranarray(vol), vol[::-1][::-1]):
        got = skelform.marching_cubes(a, 0.5)
        assert len(got[0]) == len(ref[0]) and len(got[1]) == len(ref[1])
        np.testing.assert_allclose(sorted_rows(got[0]), sorted_rows(ref[0]), atol=1e-5)
        assert closed(got[0], got[1])
    u8 = (vol - vol.min()).clip(0, 255).astype(np.uint8)
    assert closed(*skelform.marching_cubes(u8, 100.5)[:2])


def test_same_mesh_on_any_thread_count():
    vol = torus(64)
    one = skelform.marching_cubes(vol, 0.0, threads=1)
    two = skelform.marching_cubes(vol, 0.0, threads=2)
    for a, b in zip(one, two):
        np.testing.assert_array_equal(a, b)


def test_step_size_matches_scikit_image():
    vol = sphere()
    ours = skelform.marching_cubes(vol, 0.0, step_size=2)
    theirs = sk_marching_cubes(vol, 0.0, step_size=2)
    assert len(ours[0]) == len(theirs[0]) and len(ours[1]) == len(theirs[1])
    np.testing.assert_allclose(sorted_rows(ours[0]), sorted_rows(theirs[0]), atol=1e-4)


def test_mask_keeps_the_cubes_it_names():
    vol = sphere()
    mask = np.zeros(vol.shape, bool)
    mask[:20] = True
    v, f, _, _ = skelform.marching_cubes(vol, 0.0, mask=mask)
    full = skelform.marching_cubes(vol, 0.0)
    assert 0 < len(f) < len(full[1])
    assert v[:, 0].max() <= 19.0 + 1e-6
    # scikit-image computes a cube when the mask holds at its last corner; so does skelform.
    theirs = sk_marching_cubes(vol, 0.0, mask=mask)
    assert len(f) == len(theirs[1])
    np.testing.assert_allclose(sorted_rows(v), sorted_rows(theirs[0]), atol=1e-5)


def test_allow_degenerate_false_drops_zero_area_faces():
    i, j, k = np.mgrid[-8:9, -8:9, -8:9].astype(np.float64)
    vol = np.maximum(np.maximum(abs(i), abs(j)), abs(k)) - 5  # faces on sample planes
    v, f, _, _ = skelform.marching_cubes(vol, 0.0, allow_degenerate=False)
    area = np.linalg.norm(np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), axis=1)
    assert np.all(area > 0)
    assert closed(v, f)


@pytest.mark.parametrize(
    "call, error, message",
    [
        (lambda: skelform.marching_cubes(np.zeros((4, 4))), ValueError, "3D"),
        (lambda: skelform.marching_cubes(np.zeros((1, 4, 4))), ValueError, "2x2x2"),
        (lambda: skelform.marching_cubes(sphere(8, (4, 4, 4), 2), 99.0), ValueError, "range"),
        (lambda: skelform.marching_cubes(sphere(8, (4, 4, 4), 2), 0, (1, 1)), ValueError,
         "three floats"),
        (lambda: skelform.marching_cubes(sphere(8, (4, 4, 4), 2), 0, step_size=0), ValueError,
         "step_size"),
        (lambda: skelform.marching_cubes(sphere(8, (4, 4, 4), 2), 0, gradient_direction="up"),
         ValueError, "gradient_direction"),
        (lambda: skelform.marching_cubes(sphere(8, (4, 4, 4), 2), 0, mask=np.ones((2, 2, 2))),
         ValueError, "same shape"),
        (lambda: skelform.marching_cubes(np.ones((4, 4, 4)), 1.0), RuntimeError,
         "No surface"),
        (lambda: skelform.marching_cubes(sphere(8, (4, 4, 4), 2), 0, threads=0), ValueError,
         "threads"),
    ],
)
def test_errors_are_scikit_images(call, error, message):
    with pytest.raises(error, match=message):
        call()


def test_cancelled_by_the_progress_callback():
    seen = []

    def progress(phase, done, total):
        seen.append((phase, done, total))
        return False

    with pytest.raises(skelform.Cancelled):
        skelform.marching_cubes(torus(160), 0.0, progress=progress)
    assert seen and isinstance(seen[0][0], str)


def reference_normals(vol, level, verts):
    """The normals and values the conventions promise, computed in NumPy: the gradient of
    the samples (each ``float32(x - level)``) by central differences inside and one-sided
    ones at the border, per axis, interpolated linearly along each vertex's lattice edge."""
    s = (np.asarray(vol, np.float64) - level).astype(np.float32).astype(np.float64)
    nodes = np.stack(np.gradient(s), axis=-1)
    p = verts.astype(np.float64)
    top = np.array(vol.shape) - 2
    base = np.clip(np.floor(p), 0, top).astype(np.int64)
    t = np.clip(p - base, 0.0, 1.0)
    at_end = t == 1.0
    base[at_end] += 1
    t[at_end] = 0.0
    assert np.all((t > 0).sum(1) <= 1), "a vertex off the lattice's edges"
    axis = np.argmax(t, axis=1)
    tip = base.copy()
    tip[np.arange(len(p)), axis] += (t.max(1) > 0)
    w = t.max(1)[:, None]
    g = (1 - w) * nodes[tuple(base.T)] + w * nodes[tuple(tip.T)]
    length = np.sqrt((g * g).sum(1))[:, None]
    return (-g / length).astype(np.float32), np.abs(g).sum(1).astype(np.float32)


@pytest.mark.parametrize("order", ["C", "F"])
@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_normals_and_values_are_the_sample_gradient(order, dtype):
    # A sphere the volume's faces cut, with noise: vertices inside the lattice and on its
    # border, whose normals come from different code.
    rng = np.random.default_rng(5)
    vol = sphere(30, (12.4, 15.2, 17.9), 14.0) + 0.3 * rng.standard_normal((30, 30, 30))
    vol = np.asarray(vol.astype(dtype), order=order)
    level = 0.25
    for threads in (1, 2):
        v, f, n, values = skelform.marching_cubes(vol, level, threads=threads)
        border = np.any((v < 1) | (v > np.array(vol.shape) - 2), axis=1)
        assert border.sum() > 100 and (~border).sum() > 1000
        normals, sizes = reference_normals(vol, level, v)
        np.testing.assert_allclose(n, normals, rtol=1e-6, atol=1e-7)
        np.testing.assert_allclose(values, sizes, rtol=1e-6, atol=1e-7)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_non_finite_samples_are_the_largest_finite_ones(dtype):
    # At level 0 a float32 volume is read in place, and the normals read its values raw
    # where they are finite: infinities and NaN must still read as the largest finite
    # samples of their sign (NaN as positive), in the normals and values too, on vertices
    # whose neighbours they are.
    rng = np.random.default_rng(11)
    vol = sphere(30, (14.2, 15.1, 13.7), 10.0) + 0.3 * rng.standard_normal((30, 30, 30))
    vol = vol.astype(dtype)
    flat = vol.reshape(-1)
    flat[::97], flat[13::89], flat[5::101] = np.inf, -np.inf, np.nan
    big = np.finfo(np.float32).max
    replaced = np.nan_to_num(vol, nan=big, posinf=big, neginf=-big)
    for threads in (1, 2):
        ours = skelform.marching_cubes(vol, 0.0, threads=threads)
        theirs = skelform.marching_cubes(replaced, 0.0, threads=threads)
        assert len(ours[1]) > 1000
        # (Values, the gradient's size, may overflow float32 next to those samples.)
        assert np.isfinite(ours[0]).all() and np.isfinite(ours[2]).all()
        assert not np.isnan(ours[3]).any()
        for a, b in zip(ours, theirs):
            assert np.array_equal(a, b)


def test_arrays_outlive_later_calls():
    """The arrays are over memory that goes back to a pool when NumPy drops them: arrays and
    views a caller keeps are never written by later calls, and dropped ones are reused."""
    vol = sphere(48).astype(np.float32)
    first = skelform.marching_cubes(vol, 0.0, threads=1)
    kept = [a.copy() for a in first]
    view = first[0][5:, 1]
    view_copy = view.copy()
    for a in first:
        assert a.flags.c_contiguous and a.flags.writeable and a.flags.aligned
    for level in (1.0, -2.0, 0.0, 0.5):
        for threads in (1, 2):
            skelform.marching_cubes(vol, level, threads=threads)
            other = skelform.marching_cubes(vol + 3.0, level, threads=threads)
            del other
    for a, b in zip(first, kept):
        assert np.array_equal(a, b)
    del first
    for level in (1.0, 0.0):
        again = skelform.marching_cubes(vol, level, threads=1)
        assert again[0].shape[1] == 3
    assert np.array_equal(view, view_copy)
    # Writing into returned arrays (as NumPy allows) does not reach later results.
    a = skelform.marching_cubes(vol, 0.0, threads=1)
    for x in a:
        x[...] = 7
    del a
    b = skelform.marching_cubes(vol, 0.0, threads=1)
    for x, y in zip(b, kept):
        assert np.array_equal(x, y)
