"""skelform: implicit surfaces and volumes to meshes with correct topology.

- ``marching_cubes(volume, level, ...)``: a drop-in for ``skimage.measure.marching_cubes``
  (same arguments, return values, axis order, winding, dtypes and errors), with the
  topology of the trilinear interpolant in ambiguous cubes and no holes where samples equal
  the level.
- ``Formula(text)``: skelform's formula language on NumPy arrays (``.eval``, ``.gradient``).
- ``load_scene(path)``, ``Scene.from_toml(text)``: scene files (formulas, skeletons,
  regions), meshed by ``.mesh(**overrides)``.
- ``mesh(field, domain, ...)``: a formula, a scene or a Python callable to a ``Mesh``.
- ``Mesh``: vertices, faces, normals, labels, curves as arrays; ``write``, ``check``,
  ``to_trimesh``, ``to_pyvista``.

Long calls release the GIL, stop on Ctrl-C, and take ``progress(phase, done, total)``
callbacks that may return ``False`` to cancel (raising ``Cancelled``).
"""

from __future__ import annotations

from typing import Any, Callable, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

from ._skelform import (
    Cancelled,
    Formula,
    Mesh,
    Scene,
    __version__,
    load_scene,
    marching_cubes_core as _marching_cubes_core,
    mesh,
)

__all__ = [
    "Cancelled",
    "Formula",
    "Mesh",
    "Scene",
    "__version__",
    "load_scene",
    "marching_cubes",
    "mesh",
]

# Element types the native half reads straight from the array; others are converted.
_NATIVE = {np.dtype(t) for t in (np.float32, np.float64, np.int8, np.int16, np.int32,
                                 np.int64, np.uint8, np.uint16, np.uint32, np.uint64)}


def marching_cubes(
    volume: npt.ArrayLike,
    level: Optional[float] = None,
    spacing: Sequence[float] = (1.0, 1.0, 1.0),
    *,
    gradient_direction: str = "descent",
    step_size: int = 1,
    allow_degenerate: bool = True,
    mask: Optional[npt.ArrayLike] = None,
    threads: Optional[int] = None,
    progress: Optional[Callable[[str, int, Optional[int]], Optional[bool]]] = None,
) -> Tuple[npt.NDArray[Any], npt.NDArray[np.int32], npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """Isosurface of a 3-D volume, as ``skimage.measure.marching_cubes`` returns it.

    Parameters are scikit-image's: ``level`` (default: the middle of the data range),
    ``spacing`` (voxel size along each axis), ``gradient_direction`` (``"descent"``: faces
    wound so that their normals, by the right-hand rule, point towards higher values;
    ``"ascent"``: the other way),
    ``step_size`` (every n-th sample), ``allow_degenerate`` (``False`` merges coincident
    vertices and drops the faces that then have zero area), ``mask`` (a boolean array of
    the volume's shape: only the cubes whose last corner is ``True``, as in scikit-image). skelform adds
    ``threads`` (default: every core; the mesh is the same on any count; with a count, the
    call's worker threads are pinned to CPUs of their own while it runs, and only then) and
    ``progress``.

    Returns ``(verts, faces, normals, values)``: vertex coordinates (V×3, in the order of
    the array's axes, times the spacing), faces (F×3 int32), unit vertex normals pointing
    down the gradient (V×3 float32), and the gradient's size at each vertex (V float32).

    Unlike scikit-image, ambiguous cubes take the topology of the trilinear interpolant
    and samples equal to ``level`` leave no holes: a surface that stays inside the volume
    comes out closed.
    """
    volume = np.asarray(volume)
    if volume.ndim != 3:
        raise ValueError("Input volume should be a 3D numpy array.")
    if volume.shape[0] < 2 or volume.shape[1] < 2 or volume.shape[2] < 2:
        raise ValueError("Input array must be at least 2x2x2.")
    if volume.dtype not in _NATIVE:
        volume = volume.astype(np.float64)
    # The default level (the middle of the data range) and the check that a given one lies
    # in the range are made in the native half, in the passes it makes anyway.
    if level is not None:
        level = float(level)
    if len(spacing) != 3:
        raise ValueError("`spacing` must consist of three floats.")
    step_size = int(step_size)
    if step_size < 1:
        raise ValueError("step_size must be at least one.")
    if gradient_direction not in ("descent", "ascent"):
        raise ValueError(
            f"Incorrect input {gradient_direction} in `gradient_direction`, see docstring."
        )
    if mask is not None:
        mask = np.asarray(mask)
        if mask.shape != volume.shape:
            raise ValueError("volume and mask must have the same shape.")
        mask = mask.astype(bool, copy=False)
    verts, faces, normals, values = _marching_cubes_core(
        volume,
        level,
        step_size,
        gradient_direction == "ascent",
        bool(allow_degenerate),
        mask,
        None if threads is None else int(threads),
        progress,
    )
    if not len(verts):
        raise RuntimeError("No surface found at the given iso value.")
    if not np.array_equal(spacing, (1, 1, 1)):
        verts = verts * np.r_[spacing]
    return verts, faces, normals, values
